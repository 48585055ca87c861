//! Terrain heights: a regular height grid looked up bilinearly (textbook eq.
//! 9.35), a constant "flat" DEM, and the policy for holes and for points
//! outside the grid. The rest of the program sees only `Dem::height`.
//! A grid is read from its file in `read.rs`; the run's `Dem` (its
//! policies, windows of posts, summaries) is `terrain.rs`.

use crate::error::Result;
use crate::geodesy::{Crs, Reprojection};
use crate::geom::floor_split;
use crate::io::cached_raster::CachedRaster;
use std::path::PathBuf;

mod collar;
mod mosaic;
mod read;
mod terrain;
pub use collar::Collar;
pub use mosaic::{is_vrt, vrt_grid};

/// What a raw lookup found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lookup {
    Height(f64),
    /// Inside the grid, but a sample needed for the interpolation is nodata.
    Hole,
    Outside,
}

/// What to do when a lookup finds no height.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Miss {
    /// Stop the run with an error naming the point.
    Error,
    /// Leave the output pixel as nodata.
    Nodata,
    /// Use this height instead.
    Height(f64),
}

/// Heights of a grid: in memory, or read a chunk at a time from the file
/// into a bounded cache (large DEMs: a 1 m DEM of 20×20 km is 1.6 GB).
enum Samples {
    Memory(Vec<f32>),
    Chunked(Box<CachedRaster>),
    /// A window of posts in memory, `at` = [i0, j0, width, height] (what
    /// a mosaic looks up: its ground, not the whole file), the rest
    /// through a small cache.
    Window {
        at: [usize; 4],
        data: Vec<f32>,
        rest: Box<CachedRaster>,
    },
    /// Tiles of a VRT or a folder, each read as a DEM of its own.
    Mosaic(mosaic::Mosaic),
    /// An SRTM `.hgt` tile: big-endian Int16 in the mapped file, so that
    /// a folder of them holds only the pages lookups touch.
    Hgt(std::sync::Arc<crate::io::mapped_file::MappedFile>),
}

/// Sample `k` of a mapped `.hgt` tile.
#[inline]
fn hgt_at(m: &[u8], k: usize) -> f32 {
    i16::from_be_bytes([m[2 * k], m[2 * k + 1]]) as f32
}

/// DEMs larger than this are read a chunk at a time.
pub const IN_MEMORY_LIMIT: u64 = 64 << 20;

/// A height grid, north-up, heights at pixel centres.
pub struct GridDem {
    pub width: usize,
    pub height: usize,
    data: Samples,
    /// GDAL geotransform (north-up: gt2 = gt4 = 0).
    pub transform: [f64; 6],
    pub nodata: Option<f64>,
    /// The CRS its keys name; `None`: taken to be the ground CRS.
    pub crs: Option<Crs>,
    /// 1/gt1 and 1/gt5: lookups multiply instead of dividing.
    inv_step: (f64, f64),
    /// Nodata joined to the grid's edge: outside the DEM, not a hole.
    collar: Option<std::sync::Arc<Collar>>,
}

impl GridDem {
    /// An error naming a mapped file (an `.hgt` tile) truncated while it
    /// was read: checked before an output made of its heights is published.
    pub fn check_intact(&self) -> Result<()> {
        match &self.data {
            Samples::Hgt(m) => m.check_intact(),
            Samples::Mosaic(m) => m.check_intact(),
            _ => Ok(()),
        }
    }

    pub fn new(width: usize, height: usize, data: Vec<f32>, transform: [f64; 6], nodata: Option<f64>, crs: Option<Crs>) -> GridDem {
        assert_eq!(data.len(), width * height);
        GridDem { width, height, data: Samples::Memory(data), transform, nodata, crs, inv_step: (1.0 / transform[1], 1.0 / transform[5]), collar: None }
    }

    #[cfg(any(test, feature = "internals"))]
    /// Is the grid read a chunk at a time?
    pub fn is_chunked(&self) -> bool {
        matches!(self.data, Samples::Chunked(_))
    }

    /// The most its samples hold in memory, bytes (a mapped `.hgt`: none,
    /// its pages are the kernel's to drop).
    pub fn held_bytes(&self) -> u64 {
        match &self.data {
            Samples::Memory(v) => v.len() as u64 * 4,
            Samples::Chunked(c) => c.cache_bytes() as u64,
            Samples::Window { data, rest, .. } => data.len() as u64 * 4 + rest.cache_bytes() as u64,
            Samples::Mosaic(m) => m.held_bytes(),
            Samples::Hgt(_) => 0,
        }
    }

    /// Sample (i, j) (column, row).
    #[inline]
    pub fn sample(&self, i: usize, j: usize) -> f32 {
        match &self.data {
            Samples::Memory(v) => v[j * self.width + i],
            Samples::Chunked(c) => c.get(i, j),
            &Samples::Window { at: [wi, wj, ww, wh], ref data, ref rest } => match (i.wrapping_sub(wi), j.wrapping_sub(wj)) {
                (a, b) if a < ww && b < wh => data[b * ww + a],
                _ => rest.get(i, j),
            },
            Samples::Mosaic(m) => m.get(i, j),
            Samples::Hgt(m) => hgt_at(m, j * self.width + i),
        }
    }

    /// Samples (i0, j0), (i1, j0), (i0, j1), (i1, j1): a bilinear cell.
    #[inline]
    fn corners(&self, i0: usize, j0: usize, i1: usize, j1: usize) -> [f32; 4] {
        match &self.data {
            Samples::Memory(v) => [v[j0 * self.width + i0], v[j0 * self.width + i1], v[j1 * self.width + i0], v[j1 * self.width + i1]],
            Samples::Chunked(c) => c.corners(i0, j0, i1, j1),
            &Samples::Window { at: [wi, wj, ww, wh], ref data, ref rest } => {
                if i0 >= wi && j0 >= wj && i1 < wi + ww && j1 < wj + wh {
                    let (a0, a1, b0, b1) = (i0 - wi, i1 - wi, (j0 - wj) * ww, (j1 - wj) * ww);
                    [data[b0 + a0], data[b0 + a1], data[b1 + a0], data[b1 + a1]]
                } else {
                    rest.corners(i0, j0, i1, j1)
                }
            }
            Samples::Mosaic(m) => [m.get(i0, j0), m.get(i1, j0), m.get(i0, j1), m.get(i1, j1)],
            Samples::Hgt(m) => {
                let w = self.width;
                [hgt_at(m, j0 * w + i0), hgt_at(m, j0 * w + i1), hgt_at(m, j1 * w + i0), hgt_at(m, j1 * w + i1)]
            }
        }
    }

    /// Every `step`-th sample, row-major (for summaries: mean height).
    pub fn samples(&self, step: usize) -> Vec<f32> {
        match &self.data {
            Samples::Memory(v) => return v.iter().step_by(step.max(1)).copied().collect(),
            // (A window's rest is the same file's samples.)
            Samples::Chunked(c) | Samples::Window { rest: c, .. } => return c.samples(step),
            Samples::Mosaic(_) | Samples::Hgt(_) => {}
        }
        let n = self.width * self.height;
        (0..n).step_by(step.max(1)).map(|k| self.sample(k % self.width, k / self.width)).collect()
    }

    #[inline]
    pub fn is_nodata(&self, v: f32) -> bool {
        v.is_nan() || self.nodata.is_some_and(|nd| v as f64 == nd)
    }

    /// Continuous sample coordinates of (X, Y) in the grid's CRS: sample
    /// (i, j) at (i, j).
    #[inline]
    pub fn sample_coords(&self, x: f64, y: f64) -> (f64, f64) {
        let gt = &self.transform;
        ((x - gt[0]) * self.inv_step.0 - 0.5, (y - gt[3]) * self.inv_step.1 - 0.5)
    }

    /// The height at continuous sample coordinates (c, r), bilinear; NaN
    /// outside the grid or where a sample it needs is nodata.
    pub fn height_at_sample(&self, c: f64, r: f64) -> f64 {
        let gt = &self.transform;
        let (x, y) = (gt[0] + (c + 0.5) * gt[1], gt[3] + (r + 0.5) * gt[5]);
        match self.lookup(x, y) {
            Lookup::Height(z) => z,
            _ => f64::NAN,
        }
    }

    /// Sample (i, j) as a height; NaN outside or nodata.
    pub fn post(&self, i: i64, j: i64) -> f64 {
        if i < 0 || j < 0 || i as usize >= self.width || j as usize >= self.height {
            return f64::NAN;
        }
        let v = self.sample(i as usize, j as usize);
        if self.is_nodata(v) {
            f64::NAN
        } else {
            v as f64
        }
    }

    /// Bilinear height at ground (X, Y) (textbook 9.35).
    #[inline]
    pub fn lookup(&self, x: f64, y: f64) -> Lookup {
        let gt = &self.transform;
        // Continuous pixel-centre coordinates: sample (i, j) at (i, j).
        let c = (x - gt[0]) * self.inv_step.0 - 0.5;
        let r = (y - gt[3]) * self.inv_step.1 - 0.5;
        let (w, h) = (self.width as f64, self.height as f64);
        // The grid covers its pixels' whole area: accept the outer half pixel.
        if !(c >= -0.5 && c <= w - 0.5 && r >= -0.5 && r <= h - 0.5) {
            return Lookup::Outside;
        }
        let c = c.clamp(0.0, w - 1.0);
        let r = r.clamp(0.0, h - 1.0);
        let i0 = (floor_split(c).0 as usize).min(self.width.saturating_sub(2));
        let j0 = (floor_split(r).0 as usize).min(self.height.saturating_sub(2));
        let i1 = (i0 + 1).min(self.width - 1);
        let j1 = (j0 + 1).min(self.height - 1);
        let (fx, fy) = (c - i0 as f64, r - j0 as f64);
        let [z00, z10, z01, z11] = self.corners(i0, j0, i1, j1);
        let need = |z: f32, wgt: f64| wgt > 0.0 && self.is_nodata(z);
        if need(z00, (1.0 - fx) * (1.0 - fy)) || need(z10, fx * (1.0 - fy)) || need(z01, (1.0 - fx) * fy) || need(z11, fx * fy) {
            // Every missing post in the collar: past the DEM's edge.
            let needed = [need(z00, (1.0 - fx) * (1.0 - fy)), need(z10, fx * (1.0 - fy)), need(z01, (1.0 - fx) * fy), need(z11, fx * fy)];
            let at = [(i0, j0), (i1, j0), (i0, j1), (i1, j1)];
            if let Some(c) = &self.collar {
                if needed.iter().zip(at).all(|(&n, (i, j))| !n || c.contains(i, j)) {
                    return Lookup::Outside;
                }
            }
            return Lookup::Hole;
        }
        let z = |z: f32, wgt: f64| if wgt > 0.0 { z as f64 * wgt } else { 0.0 };
        Lookup::Height(z(z00, (1.0 - fx) * (1.0 - fy)) + z(z10, fx * (1.0 - fy)) + z(z01, (1.0 - fx) * fy) + z(z11, fx * fy))
    }

    /// Height and its gradient (dZ/dX, dZ/dY) at ground (X, Y), from the
    /// bilinear cell; `None` outside or in a hole.
    #[inline]
    pub fn lookup_gradient(&self, x: f64, y: f64) -> Option<(f64, f64, f64)> {
        let gt = &self.transform;
        let c = (x - gt[0]) * self.inv_step.0 - 0.5;
        let r = (y - gt[3]) * self.inv_step.1 - 0.5;
        let (w, h) = (self.width as f64, self.height as f64);
        if !(c >= -0.5 && c <= w - 0.5 && r >= -0.5 && r <= h - 0.5) || self.width < 2 || self.height < 2 {
            return None;
        }
        let c = c.clamp(0.0, w - 1.0);
        let r = r.clamp(0.0, h - 1.0);
        // ⌊c⌋, ⌊r⌋ (both ≥ 0) without saturating conversions: this runs
        // for every pixel of a synthetic scan.
        let i0 = (floor_split(c).0 as usize).min(self.width - 2);
        let j0 = (floor_split(r).0 as usize).min(self.height - 2);
        let (fx, fy) = (c - i0 as f64, r - j0 as f64);
        let (z00, z10, z01, z11) = match &self.data {
            // The common case, with one bounds check for the four samples.
            Samples::Memory(v) => {
                let k = j0 * self.width + i0;
                let (top, bottom) = (&v[k..k + 2], &v[k + self.width..k + self.width + 2]);
                (top[0], top[1], bottom[0], bottom[1])
            }
            Samples::Chunked(_) | Samples::Window { .. } | Samples::Mosaic(_) | Samples::Hgt(_) => {
                let [z00, z10, z01, z11] = self.corners(i0, j0, i0 + 1, j0 + 1);
                (z00, z10, z01, z11)
            }
        };
        let holes = match self.nodata {
            // A NaN anywhere makes the sum NaN.
            None => (z00 + z10 + z01 + z11).is_nan(),
            Some(_) => [z00, z10, z01, z11].iter().any(|&z| self.is_nodata(z)),
        };
        if holes {
            return None;
        }
        Some(self.height_and_slopes([z00, z10, z01, z11], fx, fy))
    }

    /// Height and slopes (dZ/dX, dZ/dY) in a cell with corner samples
    /// `[z00, z10, z01, z11]` at (fx, fy) within it: along the top and
    /// bottom edges first, then between them, from the same few
    /// differences. A NaN corner makes the height NaN.
    #[inline(always)]
    fn height_and_slopes(&self, z: [f32; 4], fx: f64, fy: f64) -> (f64, f64, f64) {
        let [z00, z10, z01, z11] = z.map(f64::from);
        let (dtop, dbottom) = (z10 - z00, z11 - z01);
        let (top, bottom) = (z00 + fx * dtop, z01 + fx * dbottom);
        let height = top + fy * (bottom - top);
        let dzdc = dtop + fy * (dbottom - dtop);
        let dzdr = bottom - top;
        (height, dzdc * self.inv_step.0, dzdr * self.inv_step.1)
    }

    /// `lookup_gradient` for many points: `out[k]` is (Z, dZ/dX, dZ/dY) at
    /// `(x[k], y[k])`, with Z NaN where that gives `None`. The same numbers;
    /// in one loop without a branch per point for a grid in memory without
    /// a nodata value (the scene generator's), point by point otherwise.
    pub fn lookup_gradient_many(&self, x: &[f64], y: &[f64], out: &mut [(f64, f64, f64)]) {
        let n = out.len().min(x.len()).min(y.len());
        let miss = |p: Option<(f64, f64, f64)>| p.unwrap_or((f64::NAN, 0.0, 0.0));
        // The posts in memory and where they lie: all of them, or a window.
        let (v, [wi, wj, ww, wh]) = match &self.data {
            Samples::Memory(v) if self.nodata.is_none() && self.width >= 2 && self.height >= 2 => (v, [0, 0, self.width, self.height]),
            Samples::Window { at, data, .. } if self.nodata.is_none() && at[2] >= 2 && at[3] >= 2 => (data, *at),
            _ => {
                for k in 0..n {
                    out[k] = miss(self.lookup_gradient(x[k], y[k]));
                }
                return;
            }
        };
        let gt = &self.transform;
        let (w, h) = (self.width as f64, self.height as f64);
        for k in 0..n {
            let c = (x[k] - gt[0]) * self.inv_step.0 - 0.5;
            let r = (y[k] - gt[3]) * self.inv_step.1 - 0.5;
            let inside = c >= -0.5 && c <= w - 0.5 && r >= -0.5 && r <= h - 0.5;
            // Outside (or NaN), look at cell (0, 0) and answer NaN.
            let (c, r) = if inside { (c.clamp(0.0, w - 1.0), r.clamp(0.0, h - 1.0)) } else { (0.0, 0.0) };
            let i0 = (floor_split(c).0 as usize).min(self.width - 2);
            let j0 = (floor_split(r).0 as usize).min(self.height - 2);
            if !(i0 >= wi && j0 >= wj && i0 + 1 < wi + ww && j0 + 1 < wj + wh) {
                // Past the window: through the cache.
                out[k] = if inside { miss(self.lookup_gradient(x[k], y[k])) } else { (f64::NAN, 0.0, 0.0) };
                continue;
            }
            let (fx, fy) = (c - i0 as f64, r - j0 as f64);
            let at = (j0 - wj) * ww + i0 - wi;
            let corners = [v[at], v[at + 1], v[at + ww], v[at + ww + 1]];
            // A hole (NaN) makes the height NaN by itself.
            let found = self.height_and_slopes(corners, fx, fy);
            out[k] = if inside && !found.0.is_nan() { found } else { (f64::NAN, 0.0, 0.0) };
        }
    }

    /// Ground bounds `[minx, miny, maxx, maxy]`.
    pub fn bounds(&self) -> [f64; 4] {
        let gt = &self.transform;
        let (x1, y1) = (gt[0] + gt[1] * self.width as f64, gt[3] + gt[5] * self.height as f64);
        [gt[0].min(x1), gt[3].min(y1), gt[0].max(x1), gt[3].max(y1)]
    }
}

/// Where heights come from.
#[allow(clippy::large_enum_variant)] // one a run
pub enum HeightModel {
    Flat(f64),
    Grid(GridDem),
}

/// A height model with its hole/outside policy.
pub struct Dem {
    pub model: HeightModel,
    pub on_hole: Miss,
    pub on_outside: Miss,
    /// For error messages.
    pub path: PathBuf,
    /// Ground (orthophoto CRS) → the grid's own CRS, when they differ.
    pub to_dem: Option<Reprojection>,
    /// What reading it found doubtful (for the run's warnings).
    pub warnings: Vec<String>,
    /// [`Dem::mean_height`], worked out once: it samples the whole grid,
    /// which a DEM larger than its cache reads whole again each time.
    mean: std::sync::OnceLock<Option<f64>>,
    /// [`Dem::height_range`], worked out once.
    range: std::sync::OnceLock<Option<(f64, f64)>>,
}

/// The height at a ground point after the policy, or why there is none.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Height {
    Value(f64),
    /// No height; the pixel becomes nodata.
    Nodata,
    /// No height and the policy says the run must stop.
    Missing(Lookup),
}


/// A GeoTransform that places pixels: six finite numbers whose pixel
/// axes span an area (not NaN, nor a pixel of no size).
fn check_transform(gt: &[f64; 6]) -> std::result::Result<(), String> {
    if let Some(v) = gt.iter().find(|v| !v.is_finite()) {
        return Err(format!("{v} is not a finite number"));
    }
    if gt[1] * gt[5] - gt[2] * gt[4] == 0.0 {
        return Err(format!("pixels of no area ({}, {}, {}, {})", gt[1], gt[2], gt[4], gt[5]));
    }
    Ok(())
}

/// Refuses a DEM whose grid is not north-up (rows along the easting, the
/// first row the northernmost): its tiles and lookups assume it.
fn check_north_up(geo: &crate::io::geotiff::GeoRef, path: &std::path::Path) -> Result<()> {
    let gt = geo.transform;
    if gt[2] != 0.0 || gt[4] != 0.0 || !(gt[1] > 0.0) || !(gt[5] < 0.0) {
        return Err(crate::error::Error::unsupported(path, format!("only north-up DEMs are supported (geotransform {gt:?})")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn ramp() -> GridDem {
        // 4×3 samples, 10 m posting, origin (1000, 2000): z = 100 + col + 10·row.
        let data = (0..12).map(|k| 100.0 + (k % 4) as f32 + 10.0 * (k / 4) as f32).collect();
        GridDem::new(4, 3, data, [1000.0, 10.0, 0.0, 2000.0, 0.0, -10.0], Some(-9999.0), None)
    }

    #[test]
    fn height_and_slopes_of_a_twisted_cell() {
        // 2×2 samples, 10 m posting, sample centres at X = 1005, 1015 and
        // Y = 1995, 1985: z00 = 100, z10 = 104, z01 = 120, z11 = 132.
        // At fx = 0.25, fy = 0.5 (X = 1007.5, Y = 1990):
        //   top = 101, bottom = 123 → z = 112;
        //   dz/dcol = 4·0.5 + 12·0.5 = 8 → dZ/dX = 0.8 m/m;
        //   dz/drow = 123 − 101 = 22 → dZ/dY = −2.2 (rows run south).
        let g = GridDem::new(2, 2, vec![100.0, 104.0, 120.0, 132.0], [1000.0, 10.0, 0.0, 2000.0, 0.0, -10.0], None, None);
        let (z, gx, gy) = g.lookup_gradient(1007.5, 1990.0).unwrap();
        assert!((z - 112.0).abs() < 1e-12 && (gx - 0.8).abs() < 1e-12 && (gy + 2.2).abs() < 1e-12, "{z} {gx} {gy}");
        assert_eq!(g.lookup(1007.5, 1990.0), Lookup::Height(z));
        // The slopes are the height's differences.
        let h = 1e-4;
        let dzx = (g.lookup_gradient(1007.5 + h, 1990.0).unwrap().0 - g.lookup_gradient(1007.5 - h, 1990.0).unwrap().0) / (2.0 * h);
        assert!((dzx - gx).abs() < 1e-6, "{dzx}");
        // A hole among the four samples, and outside the grid: nothing.
        let holed = GridDem::new(2, 2, vec![100.0, f32::NAN, 120.0, 132.0], [1000.0, 10.0, 0.0, 2000.0, 0.0, -10.0], None, None);
        assert!(holed.lookup_gradient(1007.5, 1990.0).is_none());
        assert!(g.lookup_gradient(1030.0, 1990.0).is_none());
    }

    /// Heights of the test DEMs: ridges, a slope and a little noise.
    fn test_z(i: usize, j: usize) -> f32 {
        200.0 + (i as f32 * 0.37).sin() * 20.0 + j as f32 * 0.5 + ((i * 7 + j * 3) % 5) as f32
    }

    /// A DEM of 100×70 samples of `test_z` plus `lift`, 10 m posts from
    /// (1000, 2000) in UTM 31N, deflated in `chunking`.
    fn write_test_dem(path: &Path, chunking: crate::io::tiff_out::Chunking, lift: f32) {
        write_test_grid(path, chunking, true, |i, j| test_z(i, j) + lift);
    }

    /// 100×70 samples `z(column, row)`, deflated in `chunking`, with the
    /// test DEMs' georeferencing in GeoTIFF tags where `tagged`.
    fn write_test_grid(path: &Path, chunking: crate::io::tiff_out::Chunking, tagged: bool, z: impl Fn(usize, usize) -> f32 + Sync) {
        use crate::io::tiff_out::{write_raster, Compression, GeoTags, OutputSpec};
        let (w, h) = (100usize, 70usize);
        let spec = OutputSpec {
            overviews: 0,
            cog: false,
            width: w as u32,
            height: h as u32,
            bands: 1,
            sample: crate::io::source::SampleType::F32,
            chunking,
            compression: Compression::Deflate,
            level: None,
            overview_level: None,
            bigtiff: false,
            photometric: 1,
            alpha: false,
            mask: false,
            geo: tagged.then(|| GeoTags {
                x0: 1000.0,
                y0: 2000.0,
                gsd: crate::geom::Gsd::square(10.0),
                keys: crate::geodesy::geokeys::keys_of(&Crs::from_epsg(32631).unwrap()).unwrap(),
                nodata: None,
            }),
        };
        write_raster(path, &spec, |y0, y1, buf| {
            let out: &mut [f32] = bytemuck::cast_slice_mut(buf);
            for j in y0 as usize..y1 as usize {
                for i in 0..w {
                    out[(j - y0 as usize) * w + i] = z(i, j);
                }
            }
        })
        .unwrap()
    }

    #[test]
    fn a_dem_read_in_chunks_finds_the_collar_one_read_whole_does() {
        // NaN cut around the data (a corner's triangle and the right-hand
        // columns, as a DSM warped to another CRS has) and a hole inside:
        // the collar is the same read whole or a chunk at a time (tiles and
        // strips), and the hole stays a hole.
        use crate::io::tiff_out::Chunking;
        let dir = tempfile::tempdir().unwrap();
        let void = |i: usize, j: usize| i + j < 30 || i >= 90 || ((40..43).contains(&i) && (30..33).contains(&j));
        let collar_posts = (0..70).flat_map(|j| (0..100).map(move |i| (i, j))).filter(|&(i, j)| i + j < 30 || i >= 90).count() as u64;
        for (k, chunking) in [Chunking::Tiles(16), Chunking::Strips(3)].into_iter().enumerate() {
            let path = dir.path().join(format!("dsm{k}.tif"));
            write_test_grid(&path, chunking, true, |i, j| if void(i, j) { f32::NAN } else { test_z(i, j) });
            let whole = GridDem::read(&path).unwrap();
            let chunked = GridDem::read_within(&path, 4 * 16 * 16 * 4).unwrap();
            assert!(chunked.is_chunked(), "{chunking:?}");
            assert_eq!((whole.collar_posts(), chunked.collar_posts()), (collar_posts, collar_posts), "{chunking:?}");
            let collar = chunked.collar.as_ref().unwrap();
            assert!(collar.contains(0, 0) && collar.contains(95, 40) && !collar.contains(41, 31) && !collar.contains(50, 50), "{chunking:?}");
        }
    }

    #[test]
    fn a_dem_read_in_chunks_gives_the_heights_of_one_read_whole() {
        // 100×70 samples in 16×16 tiles (7×5 chunks, partial at the right
        // and bottom), read whole and through a cache of a few chunks:
        // every lookup, on chunk edges and across them, the same.
        use crate::io::tiff_out::Chunking;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("dem.tif");
        let (w, h) = (100usize, 70usize);
        let z = test_z;
        let write = |path: &Path, lift: f32| write_test_dem(path, Chunking::Tiles(16), lift);
        write(&path, 0.0);
        let whole = GridDem::read(&path).unwrap();
        let chunked = GridDem::read_within(&path, 4 * 16 * 16 * 4).unwrap();
        // Another chunked DEM, 500 m higher, looked up in turn with the
        // first: a thread's last chunk is its own raster's.
        let other = dir.path().join("other.tif");
        write(&other, 500.0);
        let lifted = GridDem::read_within(&other, 4 * 16 * 16 * 4).unwrap();
        for (i, j) in [(3, 4), (3, 5), (40, 33), (41, 33), (99, 69)] {
            assert_eq!((chunked.sample(i, j), lifted.sample(i, j), chunked.sample(i, j)), (z(i, j), z(i, j) + 500.0, z(i, j)));
        }
        assert!(!whole.is_chunked() && chunked.is_chunked());
        let mut n = 0;
        for jj in 0..(h * 4) {
            for ii in 0..(w * 4) {
                // Quarter-sample steps: every cell, chunk edges included.
                let (x, y) = (1000.0 + (ii as f64 + 0.3) * 2.5, 2000.0 - (jj as f64 + 0.6) * 2.5);
                assert_eq!(format!("{:?}", whole.lookup(x, y)), format!("{:?}", chunked.lookup(x, y)), "at ({x}, {y})");
                assert_eq!(whole.lookup_gradient(x, y), chunked.lookup_gradient(x, y), "at ({x}, {y})");
                n += 1;
            }
        }
        assert_eq!(n, 400 * 280);
        assert_eq!(whole.sample(99, 69), z(99, 69));
    }

    #[test]
    fn a_dem_held_in_a_window_gives_the_heights_of_one_read_whole() {
        // Tiles of 16 and strips of 3 rows: a window of posts in memory
        // (a mosaic's ground), the rest through the cache; every lookup,
        // inside it, on its edge and past it, as the DEM read whole.
        use crate::io::tiff_out::Chunking;
        let dir = tempfile::tempdir().unwrap();
        let crs = Crs::from_epsg(32631).unwrap();
        for chunking in [Chunking::Tiles(16), Chunking::Strips(3)] {
            let path = dir.path().join("dem.tif");
            write_test_dem(&path, chunking, 0.0);
            let whole = Dem::open(&path, &crs).unwrap();
            let mut held = Dem::open_within(&path, &crs, 1024).unwrap();
            // The same window of a DEM read whole (it fit its budget).
            let mut cropped = Dem::open(&path, &crs).unwrap();
            let grid = |d: &Dem| match &d.model {
                HeightModel::Grid(g) => matches!(g.data, Samples::Window { .. }),
                HeightModel::Flat(_) => false,
            };
            let b = [1000.0 + 300.0, 2000.0 - 400.0, 1000.0 + 600.0, 2000.0 - 200.0];
            assert!(!held.hold_window(b, 2, 10 * 10 * 4).unwrap(), "{chunking:?}: 100 posts do not hold the window");
            assert!(!grid(&held));
            assert!(held.hold_window(b, 2, 64 << 10).unwrap(), "{chunking:?}");
            assert!(cropped.hold_window(b, 2, 64 << 10).unwrap(), "{chunking:?}");
            assert!(grid(&held) && grid(&cropped));
            assert_eq!(cropped.held_bytes(), held.held_bytes());
            // Beside the window, a cache of the least chunks for the rest
            // (four tiles, two strips).
            let chunk = match chunking {
                Chunking::Tiles(t) => 4 * t * t,
                Chunking::Strips(rows) => 2 * rows * 100,
            } as u64;
            let window = held.held_bytes() - chunk * 4;
            // The box's edges lie halfway between posts: posts 29..=60
            // across and 19..=40 down for its bilinear cells, 2 more around.
            assert_eq!((window, held.bytes_under(b, 2)), (36 * 26 * 4, 36 * 26 * 4), "{chunking:?}");
            // A strip of a mosaic's own posts, read again from the file; the
            // DEM read whole, once it lets go of its posts, through its cache.
            let strip = whole.posts_for(b, 2, 64 << 10, 0).unwrap().expect("one grid file");
            assert_eq!((strip.held_bytes() - chunk * 4, whole.bytes_under(b, 2)), (36 * 26 * 4, 36 * 26 * 4), "{chunking:?}");
            let cached = whole.posts_for(b, 2, 36 * 26 * 4 - 1, 0).unwrap().expect("one grid file");
            assert!(grid(&strip) && !grid(&cached), "{chunking:?}: a window past its budget is read through a cache");
            // Read whole, a window past the budget: read through the cache.
            let mut past = Dem::open(&path, &crs).unwrap();
            assert!(!past.hold_window(b, 2, 10 * 10 * 4).unwrap(), "{chunking:?}");
            assert_eq!(past.held_bytes(), chunk * 4, "{chunking:?}: read whole, it keeps only the least cache");
            let mut gone = Dem::open(&path, &crs).unwrap();
            gone.let_go_of_posts().unwrap();
            assert_eq!(gone.held_bytes(), chunk * 4, "{chunking:?}");
            let (mut xs, mut ys) = (Vec::new(), Vec::new());
            for jj in 0..(70 * 4) {
                for ii in 0..(100 * 4) {
                    let (x, y) = (1000.0 + (ii as f64 + 0.3) * 2.5, 2000.0 - (jj as f64 + 0.6) * 2.5);
                    assert_eq!(format!("{:?}", whole.lookup(x, y)), format!("{:?}", held.lookup(x, y)), "{chunking:?} at ({x}, {y})");
                    assert_eq!(whole.height_gradient(x, y), held.height_gradient(x, y), "{chunking:?} at ({x}, {y})");
                    assert_eq!(format!("{:?}", whole.lookup(x, y)), format!("{:?}", cropped.lookup(x, y)), "{chunking:?} at ({x}, {y})");
                    assert_eq!(format!("{:?}", whole.lookup(x, y)), format!("{:?}", strip.lookup(x, y)), "{chunking:?} at ({x}, {y})");
                    assert_eq!(format!("{:?}", whole.lookup(x, y)), format!("{:?}", gone.lookup(x, y)), "{chunking:?} at ({x}, {y})");
                    assert_eq!(format!("{:?}", whole.lookup(x, y)), format!("{:?}", cached.lookup(x, y)), "{chunking:?} at ({x}, {y})");
                    assert_eq!(format!("{:?}", whole.lookup(x, y)), format!("{:?}", past.lookup(x, y)), "{chunking:?} at ({x}, {y})");
                    xs.push(x);
                    ys.push(y);
                }
            }
            let (mut a, mut c) = (vec![(0.0, 0.0, 0.0); xs.len()], vec![(0.0, 0.0, 0.0); xs.len()]);
            whole.height_gradient_many(&xs, &ys, &mut a);
            held.height_gradient_many(&xs, &ys, &mut c);
            assert!(a.iter().zip(&c).all(|(p, q)| format!("{p:?}") == format!("{q:?}")), "{chunking:?}");
            cropped.height_gradient_many(&xs, &ys, &mut c);
            assert!(a.iter().zip(&c).all(|(p, q)| format!("{p:?}") == format!("{q:?}")), "{chunking:?}");
            // A window over the whole DEM is the DEM read whole.
            let mut all = Dem::open_within(&path, &crs, 1024).unwrap();
            assert!(all.hold_window([0.0, 0.0, 1e5, 1e5], 2, 1 << 20).unwrap());
            assert!(matches!(&all.model, HeightModel::Grid(g) if matches!(g.data, Samples::Memory(_))));
            assert_eq!(all.held_bytes(), 100 * 70 * 4);
        }
    }

    #[test]
    fn a_summary_of_a_dem_in_tiles_decodes_each_tile_once() {
        // 7×5 tiles of 16: the mean height's and the voids check's samples
        // spread row by row over the file; through the cache each sampled
        // row decoded its row of tiles again.
        use crate::io::tiff_out::Chunking;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("dem.tif");
        write_test_dem(&path, Chunking::Tiles(16), 0.0);
        let whole = GridDem::read(&path).unwrap();
        for step in [1, 3, 7, 100, 6999, 7000, 9999] {
            let chunked = GridDem::read_within(&path, 4 * 16 * 16 * 4).unwrap();
            let Samples::Chunked(c) = &chunked.data else { panic!("read in chunks") };
            let before = c.raster().chunks_decoded();
            let got = chunked.samples(step);
            assert_eq!(got, whole.samples(step), "step {step}");
            assert!(c.raster().chunks_decoded() - before <= 35, "step {step}: {} chunks decoded", c.raster().chunks_decoded() - before);
        }
    }

    #[test]
    fn georeferencing_in_gdals_aux_xml_is_read() {
        // The test DEM without its GeoTIFF tags, its grid, CRS and nodata in
        // FILE.aux.xml (as GDAL's baseline profile writes them): the same
        // heights where the tagged one has them.
        use crate::io::tiff_out::Chunking;
        let dir = tempfile::tempdir().unwrap();
        let (tagged, bare) = (dir.path().join("tagged.tif"), dir.path().join("bare.tif"));
        write_test_dem(&tagged, Chunking::Strips(8), 0.0);
        write_test_grid(&bare, Chunking::Strips(8), false, |i, j| if (i, j) == (50, 30) { -9999.0 } else { test_z(i, j) });
        let crs = Crs::from_epsg(32631).unwrap();
        let refused = Dem::open(&bare, &crs).err().map(|e| e.to_string()).unwrap_or_default();
        assert!(refused.contains("no georeferencing") && refused.contains(".aux.xml"), "{refused}");
        let wkt = r#"PROJCS["WGS 84 / UTM zone 31N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AUTHORITY["EPSG","4326"]],PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",0],PARAMETER["central_meridian",3],PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",500000],PARAMETER["false_northing",0],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AXIS["Northing",NORTH],AUTHORITY["EPSG","32631"]]"#;
        let aux = format!(
            "<PAMDataset>\n  <SRS dataAxisToSRSAxisMapping=\"1,2\">{}</SRS>\n  <GeoTransform>  1.0000000000000000e+03,  1.0e+01,  0.0,  2.0e+03,  0.0, -1.0e+01</GeoTransform>\n  <PAMRasterBand band=\"1\">\n    <NoDataValue>-9999</NoDataValue>\n  </PAMRasterBand>\n</PAMDataset>\n",
            wkt.replace('"', "&quot;")
        );
        std::fs::write(dir.path().join("bare.tif.aux.xml"), aux).unwrap();
        let (whole, bare) = (Dem::open(&tagged, &crs).unwrap(), Dem::open(&bare, &crs).unwrap());
        assert!(bare.warnings.is_empty(), "its CRS is read: {:?}", bare.warnings);
        for (x, y) in [(1005.0, 1995.0), (1333.3, 1777.7), (1994.0, 1306.0), (1505.0, 1695.0)] {
            let (a, b) = (whole.lookup(x, y), bare.lookup(x, y));
            if (x, y) == (1505.0, 1695.0) {
                // Post (50, 30) is the aux's nodata.
                assert_eq!(b, Lookup::Hole);
            } else {
                assert_eq!(format!("{a:?}"), format!("{b:?}"), "at ({x}, {y})");
            }
        }
    }

    #[test]
    fn many_lookups_give_what_single_lookups_give() {
        // 5×4 samples with a hole, 10 m posting, and points inside, on the
        // outer half pixel, outside, next to the hole and NaN.
        let mut data: Vec<f32> = (0..20).map(|k| 100.0 + (k * 37 % 11) as f32 * 1.7).collect();
        data[13] = f32::NAN;
        let g = GridDem::new(5, 4, data, [1000.0, 10.0, 0.0, 2000.0, 0.0, -10.0], None, None);
        let mut x = vec![f64::NAN, 1000.0, 999.9, 1050.0, 1050.1, 1024.9, 1033.0, 1012.5];
        let mut y = vec![1990.0, 1960.0, 1985.0, 1960.0, 1999.0, 1975.1, 1975.0, 2000.0];
        for k in 0..60 {
            x.push(1000.0 + (k * 7 % 51) as f64 * 1.03);
            y.push(2000.0 - (k * 13 % 41) as f64 * 0.99);
        }
        let mut out = vec![(0.0, 0.0, 0.0); x.len()];
        g.lookup_gradient_many(&x, &y, &mut out);
        let (mut some, mut none) = (0, 0);
        for k in 0..x.len() {
            match g.lookup_gradient(x[k], y[k]) {
                Some(p) => {
                    some += 1;
                    assert_eq!((p.0.to_bits(), p.1.to_bits(), p.2.to_bits()), (out[k].0.to_bits(), out[k].1.to_bits(), out[k].2.to_bits()), "{k}");
                }
                None => {
                    none += 1;
                    assert!(out[k].0.is_nan(), "{k}: {:?}", out[k]);
                }
            }
        }
        assert!(some > 30 && none > 5, "{some} {none}");
    }

    #[test]
    fn bilinear_at_centres_and_between() {
        let g = ramp();
        // Centre of sample (0, 0) is (1005, 1995).
        assert_eq!(g.lookup(1005.0, 1995.0), Lookup::Height(100.0));
        // Halfway between columns 1 and 2 and rows 0 and 1: 100 + 1.5 + 5.
        assert_eq!(g.lookup(1020.0, 1990.0), Lookup::Height(106.5));
        // The outer half pixel clamps to the edge sample.
        assert_eq!(g.lookup(1001.0, 1999.0), Lookup::Height(100.0));
        assert_eq!(g.lookup(999.0, 1995.0), Lookup::Outside);
    }

    #[test]
    fn holes_and_policies() {
        let mut g = ramp();
        if let Samples::Memory(v) = &mut g.data {
            v[5] = -9999.0; // (1, 1)
        }
        assert_eq!(g.lookup(1020.0, 1990.0), Lookup::Hole);
        // Exactly on sample (2, 0) the hole at (1, 1) has zero weight.
        assert_eq!(g.lookup(1025.0, 1995.0), Lookup::Height(102.0));
        let mut dem = Dem::grid(g, Path::new("dem.tif"));
        assert_eq!(dem.height(1020.0, 1990.0), Height::Missing(Lookup::Hole));
        dem.on_hole = Miss::Height(55.0);
        dem.on_outside = Miss::Nodata;
        assert_eq!(dem.height(1020.0, 1990.0), Height::Value(55.0));
        assert_eq!(dem.height(0.0, 0.0), Height::Nodata);
    }

    #[test]
    fn trend_plane_of_a_ramp_is_the_ramp() {
        let dem = Dem::grid(ramp(), Path::new("dem.tif"));
        let p = dem.trend_plane([1005.0, 1975.0, 1035.0, 1995.0]).unwrap();
        // z = 100 + (X − 1005)/10 + 10·(1995 − Y)/10
        assert!((p.b - 0.1).abs() < 1e-9 && (p.c + 1.0).abs() < 1e-9);
        assert!((p.height(1015.0, 1985.0) - 111.0).abs() < 1e-9);
    }
}
