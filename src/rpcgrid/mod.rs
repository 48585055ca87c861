//! The inverse regular grid of Chibunichev and Sonyushkin (`gcm-ortho rpc-grid`): for image
//! nodes every `step` pixels, the ground point (longitude, latitude, height
//! on the DEM) each sees — the linearised solve of 004 eq. (1) (RPC partials
//! and the DEM's slope), iterated to convergence from the neighbouring
//! node. Every node is checked back through the forward RPC (0.025 px);
//! nodes that fail (dead zones, no convergence) are replaced by 004's
//! "topology correction": a linear model of longitude, latitude and height
//! in image coordinates plus a multilevel B-spline of its residuals, both
//! fitted on the good nodes.
//!
//! Written as GDAL geolocation arrays: a Float64 GeoTIFF with bands
//! longitude, latitude, height (node (i, j) at the centre of image pixel
//! (i·step, j·step)), and a VRT of the image carrying the GEOLOCATION
//! metadata that makes `gdalwarp -geoloc` use it.

pub mod mba;

use crate::camera::{RpcCamera, SensorModel};
use crate::dem::{Dem, Height};
use crate::error::{Error, Result};
use crate::transform::inverse::RayCaster;
use mba::Mba;
use rayon::prelude::*;
use std::path::Path;

/// Chibunichev and Sonyushkin's back-check threshold, pixels.
pub const BACK_CHECK_PX: f64 = 0.025;
pub const METRES_PER_DEGREE: f64 = 111_320.0;

/// The grid of one step.
pub struct RpcGrid {
    pub step: u32,
    /// Nodes across and down.
    pub cols: usize,
    pub rows: usize,
    pub lon: Vec<f64>,
    pub lat: Vec<f64>,
    pub h: Vec<f64>,
    /// Nodes that failed the back-check (before correction).
    pub bad: usize,
    /// Bad nodes replaced by the linear model + B-spline.
    pub corrected: usize,
}

/// Builds the grid for an image of `w × h` pixels. `model` must work in
/// EPSG:4326 (X longitude, Y latitude) and `dem` be looked up in it.
pub fn build(model: &RpcCamera, dem: &Dem, w: u32, h: u32, step: u32, z_guess: f64) -> Result<RpcGrid> {
    if step == 0 {
        return Err(Error::setting("step", "must be at least 1"));
    }
    let cols = ((w - 1) / step + 1 + u32::from(!(w - 1).is_multiple_of(step))) as usize;
    let rows = ((h - 1) / step + 1 + u32::from(!(h - 1).is_multiple_of(step))) as usize;
    let at = |i: usize| (i as u32 * step) as f64 + 0.5;
    // Solve each row from its left neighbour.
    let solved: Vec<Vec<Option<[f64; 3]>>> = (0..rows)
        .into_par_iter()
        .map(|j| {
            let mut caster = RayCaster::new(model, dem);
            let mut prev = None;
            (0..cols)
                .map(|i| {
                    let (c, r) = (at(i), at(j));
                    let p = caster.cast(c, r, prev, z_guess, 1e-4);
                    prev = p.map(|p| (p[0], p[1]));
                    // The back-check through the forward RPC at the DEM's height.
                    p.filter(|p| match dem.height(p[0], p[1]) {
                        Height::Value(z) => model.project(p[0], p[1], z).is_some_and(|(pc, pr)| (pc - c).hypot(pr - r) <= BACK_CHECK_PX),
                        _ => false,
                    })
                })
                .collect()
        })
        .collect();
    let n = cols * rows;
    let (mut lon, mut lat, mut hh) = (vec![f64::NAN; n], vec![f64::NAN; n], vec![f64::NAN; n]);
    let mut good_uv = Vec::new();
    let mut good = [Vec::new(), Vec::new(), Vec::new()];
    for (j, row) in solved.iter().enumerate() {
        for (i, p) in row.iter().enumerate() {
            if let Some(p) = p {
                let k = j * cols + i;
                (lon[k], lat[k], hh[k]) = (p[0], p[1], p[2]);
                good_uv.push(((i as f64) / (cols - 1).max(1) as f64, (j as f64) / (rows - 1).max(1) as f64));
                good[0].push(p[0]);
                good[1].push(p[1]);
                good[2].push(p[2]);
            }
        }
    }
    let bad = n - good_uv.len();
    if good_uv.len() < 3 {
        return Err(Error::Geometry(format!("only {} of {n} grid nodes meet the DEM: does the DEM cover the image?", good_uv.len())));
    }
    let mut corrected = 0;
    if bad > 0 {
        let finest = cols.max(rows).next_power_of_two();
        let fits: Vec<([f64; 3], Mba)> = good
            .iter()
            .map(|vals| {
                let plane = fit_plane(&good_uv, vals);
                let res: Vec<f64> = good_uv.iter().zip(vals).map(|(&(u, v), z)| z - (plane[0] + plane[1] * u + plane[2] * v)).collect();
                (plane, Mba::fit(&good_uv, &res, finest))
            })
            .collect();
        for j in 0..rows {
            for i in 0..cols {
                let k = j * cols + i;
                if !lon[k].is_nan() {
                    continue;
                }
                let (u, v) = (i as f64 / (cols - 1).max(1) as f64, j as f64 / (rows - 1).max(1) as f64);
                let val = |f: &([f64; 3], Mba)| f.0[0] + f.0[1] * u + f.0[2] * v + f.1.eval(u, v);
                (lon[k], lat[k], hh[k]) = (val(&fits[0]), val(&fits[1]), val(&fits[2]));
                corrected += 1;
            }
        }
    }
    Ok(RpcGrid { step, cols, rows, lon, lat, h: hh, bad, corrected })
}

/// Least-squares plane z = a + b·u + c·v.
fn fit_plane(uv: &[(f64, f64)], z: &[f64]) -> [f64; 3] {
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atz = nalgebra::Vector3::<f64>::zeros();
    for (&(u, v), &z) in uv.iter().zip(z) {
        let r = nalgebra::Vector3::new(1.0, u, v);
        ata += r * r.transpose();
        atz += r * z;
    }
    match ata.try_inverse() {
        Some(inv) => {
            let s = inv * atz;
            [s[0], s[1], s[2]]
        }
        None => [z.iter().sum::<f64>() / z.len().max(1) as f64, 0.0, 0.0],
    }
}

impl RpcGrid {
    /// Longitude and latitude at continuous image (column, row), bilinear
    /// between nodes.
    pub fn interpolate(&self, c: f64, r: f64) -> (f64, f64) {
        let s = self.step as f64;
        let x = ((c - 0.5) / s).clamp(0.0, (self.cols - 1) as f64);
        let y = ((r - 0.5) / s).clamp(0.0, (self.rows - 1) as f64);
        let (i, j) = ((x as usize).min(self.cols.saturating_sub(2)), (y as usize).min(self.rows.saturating_sub(2)));
        let (fx, fy) = (x - i as f64, y - j as f64);
        let i1 = (i + 1).min(self.cols - 1);
        let j1 = (j + 1).min(self.rows - 1);
        let bl = |v: &[f64]| {
            let a = v[j * self.cols + i] * (1.0 - fx) + v[j * self.cols + i1] * fx;
            let b = v[j1 * self.cols + i] * (1.0 - fx) + v[j1 * self.cols + i1] * fx;
            a * (1.0 - fy) + b * fy
        };
        (bl(&self.lon), bl(&self.lat))
    }

    /// Writes the grid as a 3-band Float64 TIFF (longitude, latitude,
    /// height), under a temporary name renamed into place when complete.
    pub fn write(&self, path: &Path) -> Result<()> {
        let pending = crate::io::tiff_out::PendingFile::create(path)?;
        let data: Vec<f64> = (0..self.cols * self.rows).flat_map(|k| [self.lon[k], self.lat[k], self.h[k]]).collect();
        let err = |e| crate::io::tiff_out::tiff_write_error(path, e);
        let mut enc = tiff::encoder::TiffEncoder::new(pending.file()?).map_err(err)?;
        let mut image = enc.new_image::<ThreeValues>(self.cols as u32, self.rows as u32).map_err(err)?;
        // Bands 2 and 3 are values too, not colours.
        image.encoder().write_tag(tiff::tags::Tag::ExtraSamples, &[0u16, 0][..]).map_err(err)?;
        image.write_data(&data).map_err(err)?;
        pending.publish()
    }
}

/// Three f64 samples a pixel that are values (longitude, latitude,
/// height), not a colour: grey with two unspecified extra samples, so that
/// GDAL and QGIS read three bands of data, not an RGB picture.
struct ThreeValues;

impl tiff::encoder::colortype::ColorType for ThreeValues {
    type Inner = f64;
    const TIFF_VALUE: tiff::tags::PhotometricInterpretation = tiff::tags::PhotometricInterpretation::BlackIsZero;
    const BITS_PER_SAMPLE: &'static [u16] = &[64, 64, 64];
    const SAMPLE_FORMAT: &'static [tiff::tags::SampleFormat] = &[tiff::tags::SampleFormat::IEEEFP; 3];
    fn horizontal_predict(_: &[f64], _: &mut Vec<f64>) {
        unreachable!("written without a predictor")
    }
}

/// A VRT of `image` carrying GDAL's GEOLOCATION metadata pointing at the
/// grid file: `gdalwarp -geoloc` on it orthorectifies through the grid.
pub fn geolocation_vrt(image: &Path, grid_file: &Path, w: u32, h: u32, bands: u32, data_type: &str, step: u32) -> String {
    let esc = |p: &Path| p.display().to_string().replace('&', "&amp;").replace('<', "&lt;").replace('"', "&quot;");
    let mut s = format!("<VRTDataset rasterXSize=\"{w}\" rasterYSize=\"{h}\">\n  <Metadata domain=\"GEOLOCATION\">\n");
    let wgs84 = "GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563]],PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433],AXIS[\"Longitude\",EAST],AXIS[\"Latitude\",NORTH]]";
    for (k, v) in [
        ("SRS", wgs84.replace('"', "&quot;")),
        ("X_DATASET", esc(grid_file)),
        ("X_BAND", "1".into()),
        ("Y_DATASET", esc(grid_file)),
        ("Y_BAND", "2".into()),
        // Node i is at image coordinate 0.5 + i·step (the centre of pixel
        // i·step) in GDAL's top-left-corner pixel coordinates.
        ("PIXEL_OFFSET", "0.5".into()),
        ("LINE_OFFSET", "0.5".into()),
        ("PIXEL_STEP", step.to_string()),
        ("LINE_STEP", step.to_string()),
        ("GEOREFERENCING_CONVENTION", "TOP_LEFT_CORNER".into()),
    ] {
        s += &format!("    <MDI key=\"{k}\">{v}</MDI>\n");
    }
    s += "  </Metadata>\n";
    for b in 1..=bands {
        s += &format!(
            "  <VRTRasterBand dataType=\"{data_type}\" band=\"{b}\">\n    <SimpleSource>\n      <SourceFilename relativeToVRT=\"0\">{}</SourceFilename>\n      <SourceBand>{b}</SourceBand>\n    </SimpleSource>\n  </VRTRasterBand>\n",
            esc(image)
        );
    }
    s + "</VRTDataset>\n"
}
