//! `gcm-ortho synth`: synthetic scenes whose truth is known. A procedural
//! ground texture, a relief posted as a real DEM raster, a film or digital
//! frame camera; the scan is rendered the *other* way from `rectify` — each
//! scan pixel's ray is cast onto the DEM and the texture sampled there — so
//! the two check each other from opposite directions. Deterministic for a
//! seed; written a band of rows at a time, in parallel, in bounded memory.

pub mod block;
pub mod film_marks;
pub mod leftovers;
pub mod noise;
pub mod panoramic;
pub mod points;
mod render;
pub mod satellite;
pub mod texture;

use crate::camera::atmosphere::Refraction;
use crate::camera::distortion::Brown;
use crate::camera::file::{CameraFile, CameraSection, CorrectionsSection, DistortionSection, ExteriorSection, InteriorSection, PixelSize};
use crate::camera::rotation::AngleConvention;
use crate::camera::SensorModel;
use crate::dem::{Dem, GridDem, Height};
use crate::error::{Error, Result};
use crate::io::source::SampleType;
use crate::io::tiff_out::{write_raster, Chunking, Compression, GeoTags, OutputSpec};
use crate::progress::Progress;
use crate::transform::footprint::{auto_grid, centre_gsd, footprint_gsd};
use rayon::prelude::*;
use render::render_scan;
use std::path::PathBuf;
use texture::Texture;

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Relief {
    Flat,
    Hilly,
    Mountain,
    /// A town on gentle terrain: flat-roofed buildings with vertical walls,
    /// trees, streets — what a drone's photogrammetric DSM holds.
    Urban,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CameraKind {
    Film,
    Digital,
    /// A pushbroom satellite described by a fitted RPC.
    Rpc,
    /// A KH-4B-like panoramic (optical-bar) film camera.
    Panoramic,
    /// A drone's small-format frame looking obliquely (`off_nadir_deg`),
    /// with strong Brown distortion.
    Drone,
}

impl crate::options::Choice for Relief {
    const NAMES: &'static [&'static str] = &["flat", "hilly", "mountain", "urban"];
    fn from_name(name: &str) -> Option<Self> {
        [Relief::Flat, Relief::Hilly, Relief::Mountain, Relief::Urban].into_iter().zip(Self::NAMES).find(|(_, n)| **n == name).map(|(r, _)| r)
    }
}

impl crate::options::Choice for CameraKind {
    const NAMES: &'static [&'static str] = &["film", "digital", "rpc", "drone", "panoramic"];
    fn from_name(name: &str) -> Option<Self> {
        [CameraKind::Film, CameraKind::Digital, CameraKind::Rpc, CameraKind::Drone, CameraKind::Panoramic]
            .into_iter()
            .zip(Self::NAMES)
            .find(|(_, n)| **n == name)
            .map(|(c, _)| c)
    }
}

/// What `synth` is asked to make (serde: the same object read back).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub struct SynthOptions {
    pub out: PathBuf,
    pub width: u32,
    pub height: u32,
    pub bands: u32,
    pub bits: u32,
    pub relief: Relief,
    pub camera: CameraKind,
    pub kappa_deg: f64,
    pub tiled: bool,
    pub compress: Compression,
    pub dem_posting: f64,
    /// Photo scale denominator (1:scale).
    pub scale: f64,
    /// Number of fiducial marks on film (4 or 8).
    pub fiducials: u32,
    /// Film image frame, mm: 230 (the common 23 × 23 cm) or 180 (18 × 18 cm).
    pub frame_mm: f64,
    /// Off-nadir angle of a satellite scene, degrees (2 to 35).
    pub off_nadir_deg: f64,
    pub seed: u64,
    /// Write only the geometry (camera, DEM, checkpoints): for accuracy
    /// studies of scans too large to render.
    pub no_scan: bool,
    /// A film's marks and margin.
    pub marks: film_marks::FilmMarks,
}

impl Default for SynthOptions {
    fn default() -> Self {
        SynthOptions {
            out: PathBuf::from("scene"),
            width: 4000,
            height: 4000,
            bands: 3,
            bits: 8,
            relief: Relief::Hilly,
            camera: CameraKind::Film,
            kappa_deg: 0.0,
            tiled: false,
            compress: Compression::None,
            dem_posting: 5.0,
            scale: 10000.0,
            fiducials: 4,
            frame_mm: 230.0,
            off_nadir_deg: 25.0,
            seed: 1,
            no_scan: false,
            marks: film_marks::FilmMarks::default(),
        }
    }
}

/// What `synth` wrote.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SynthReport {
    pub scan: PathBuf,
    pub camera: PathBuf,
    pub dem: PathBuf,
    pub truth: Option<PathBuf>,
    pub checkpoints: PathBuf,
    pub gsd: f64,
    pub flying_height: f64,
    pub relief_range: [f64; 2],
    pub max_slope_deg: f64,
}

/// Film: the image frame (230 or 180 mm) and 5 mm of film base with the
/// fiducial marks on each side scanned; 152 mm lens.
const FILM_BORDER_MM: f64 = 5.0;
const FILM_FOCAL: f64 = 152.0;

impl SynthOptions {
    /// Half the image frame, mm.
    fn frame_half(&self) -> f64 {
        self.frame_mm / 2.0
    }
    /// The scanned film's side, mm.
    fn film_mm(&self) -> f64 {
        self.frame_mm + 2.0 * FILM_BORDER_MM
    }
}
const DIGITAL_FOCAL: f64 = 100.0;
/// A drone camera: 8.8 mm lens on a 13.2 mm-wide sensor (a 1" sensor).
const DRONE_FOCAL: f64 = 8.8;
const DRONE_SENSOR_MM: f64 = 13.2;
const BASE_HEIGHT: f64 = 300.0;
/// Scene origin: UTM zone 31N, southern France.
const EPSG: u32 = 32631;
const ORIGIN: (f64, f64) = (650_000.0, 4_890_000.0);

/// The most samples a scene's DEM may have (held in memory as it is made:
/// 12 bytes a sample).
const MAX_DEM_SAMPLES: u128 = 200_000_000;

/// The most pixels a scan may have, and the longest side.
const MAX_SCAN_PIXELS: u64 = 20_000_000_000;
const MAX_SCAN_SIDE: u32 = 1_000_000;

/// Settings that make no scene, refused by their flag.
pub fn check(o: &SynthOptions) -> Result<()> {
    let bad = |setting: &'static str, m: String| Err(Error::setting(setting, m));
    if o.width < 64 || o.height < 64 {
        return bad("size", format!("{}x{} is too small (64×64 at least)", o.width, o.height));
    }
    if o.width.max(o.height) > MAX_SCAN_SIDE || o.width as u64 * o.height as u64 > MAX_SCAN_PIXELS {
        return bad("size", format!("{}x{} is past what a scene is made for ({MAX_SCAN_SIDE} px a side, {MAX_SCAN_PIXELS} px)", o.width, o.height));
    }
    if o.marks.dust > 100_000 {
        return bad("dust", format!("{} specks: 100000 at most", o.marks.dust));
    }
    if !(1..=4).contains(&o.bands) {
        return bad("bands", format!("{} is not 1 to 4", o.bands));
    }
    if o.bits != 8 && o.bits != 16 {
        return bad("bits", format!("{} is not 8 or 16", o.bits));
    }
    if !(o.dem_posting > 0.0) || !(o.scale > 0.0) {
        return bad(if o.dem_posting > 0.0 { "scale" } else { "dem_posting" }, "must be positive".into());
    }
    // Higher, no camera flies; lower, no DEM posting resolves the ground
    // (the relief is checked against the camera once it is made).
    let focal = match o.camera {
        CameraKind::Film => Some(FILM_FOCAL),
        CameraKind::Digital => Some(DIGITAL_FOCAL),
        CameraKind::Drone => Some(DRONE_FOCAL),
        CameraKind::Rpc | CameraKind::Panoramic => None,
    };
    if let Some(f) = focal {
        let flying = f * o.scale / 1000.0;
        if !(20.0..=100_000.0).contains(&flying) {
            let height = if flying < 1e6 { format!("{flying:.1}") } else { format!("{flying:.2e}") };
            return bad("scale", format!("1:{} flies a {f} mm camera {height} m above the ground: 20 m to 100 km", o.scale));
        }
    }
    if o.frame_mm != 230.0 && o.frame_mm != 180.0 {
        return bad("frame", format!("{} mm is not 230 or 180", o.frame_mm));
    }
    if o.fiducials != 4 && o.fiducials != 8 {
        return bad("fiducials", format!("{} is not 4 or 8", o.fiducials));
    }
    if matches!(o.camera, CameraKind::Rpc | CameraKind::Drone) && !(2.0..=35.0).contains(&o.off_nadir_deg) {
        return bad("off_nadir", format!("{}° is not 2° to 35°", o.off_nadir_deg));
    }
    if o.compress == Compression::Zstd {
        return bad("compress", "zstd is not written for scans (none, deflate, lzw)".into());
    }
    Ok(())
}

/// The marks' shapes as the camera file says them.
fn mark_shapes(o: &SynthOptions, marks: usize) -> crate::camera::file::OneOrMany {
    use crate::camera::file::OneOrMany;
    match film_marks::shape_names(&o.marks.shape, marks) {
        Ok(v) if v.iter().all(|n| *n == v[0]) => OneOrMany::One(v[0].clone()),
        Ok(v) => OneOrMany::Many(v),
        Err(_) => OneOrMany::One(o.marks.shape.clone()),
    }
}

/// The camera file of the scene.
fn camera_file(o: &SynthOptions, ground_h: f64) -> CameraFile {
    let u = |k: i64| noise::unit(k, 3, o.seed);
    let (omega, tilt2) = ((u(1) - 0.5) * 2.4, (u(2) - 0.5) * 2.4);
    let centre_x = ORIGIN.0 + (u(3) * 1000.0).round();
    let centre_y = ORIGIN.1 + (u(4) * 1000.0).round();
    match o.camera {
        CameraKind::Film => {
            // A film turned more than the usual fraction of a degree needs
            // a wider scan to keep its corners.
            let g = o.marks.scan_turn_deg.to_radians();
            let wider = if g.abs() > 0.5f64.to_radians() { g.cos() + g.abs().sin() } else { 1.0 };
            let px = o.film_mm() * wider / o.width.max(o.height) as f64;
            let flying = FILM_FOCAL * o.scale / 1000.0;
            // A flatbed scanner: turned 0.3° (or as asked, and by quarter
            // turns, mirrored), y pixels 0.08 % longer, film centre a
            // little off the scan centre.
            let (sx, sy) = (1.0 / px, 1.0 / (px * 1.0008));
            let (cx, cy) = (o.width as f64 / 2.0 + 12.3, o.height as f64 / 2.0 - 7.8);
            let (sg, cg) = (g.sin(), g.cos());
            let quarter = crate::fiducials::Turn { quarters: o.marks.quarters % 4, mirrored: o.marks.mirrored }.matrix();
            let to_px = |x: f64, y: f64| {
                let v = quarter * nalgebra::Vector2::new(sx * x, sy * y);
                [cx + v.x * cg + v.y * sg, cy - v.x * sg + v.y * cg]
            };
            let marks = film_marks::mark_places(o);
            let pp = [0.004, -0.009];
            let px_marks = marks.iter().map(|m| to_px(m[0], m[1])).collect();
            CameraFile {
                crs: format!("EPSG:{EPSG}"),
                camera: CameraSection { model: "frame".into(), focal_length_mm: Some(FILM_FOCAL) },
                interior: Some(InteriorSection {
                    fiducial_mark: Some(crate::camera::file::MarkSetting { shape: Some(mark_shapes(o, marks.len())), ..Default::default() }),
                    fiducials_mm: Some(marks),
                    fiducials_px: Some(px_marks),
                    principal_point_mm: Some(pp),
                    ..Default::default()
                }),
                distortion: Some(DistortionSection { radial_mm: Some([0.0, 1.5e-7, -2.0e-9]), ..Default::default() }),
                exterior: Some(ExteriorSection {
                    position: [centre_x, centre_y, ground_h + flying],
                    angles_deg: [tilt2, omega, o.kappa_deg],
                    convention: AngleConvention::AlphaOmegaKappa,
                }),
                corrections: CorrectionsSection { refraction: Refraction::Auto, earth_curvature: true },
                rpc: None,
                panoramic: None,
            }
        }
        CameraKind::Drone => {
            let px = DRONE_SENSOR_MM / o.width.max(o.height) as f64;
            let flying = DRONE_FOCAL * o.scale / 1000.0;
            CameraFile {
                crs: format!("EPSG:{EPSG}"),
                camera: CameraSection { model: "frame".into(), focal_length_mm: Some(DRONE_FOCAL) },
                interior: Some(InteriorSection {
                    pixel_size_mm: Some(PixelSize::Square(px)),
                    principal_point_px: Some([o.width as f64 / 2.0 - 11.3, o.height as f64 / 2.0 + 6.1]),
                    ..Default::default()
                }),
                // Strong barrel distortion, monotonic over the whole image.
                distortion: Some(DistortionSection { brown: Some(Brown { k1: -0.11, k2: 0.035, k3: 0.0, p1: 4.0e-4, p2: -2.5e-4 }), ..Default::default() }),
                exterior: Some(ExteriorSection {
                    position: [centre_x, centre_y, ground_h + flying],
                    // Tilted forward by the off-nadir angle, then swung.
                    angles_deg: [omega, o.off_nadir_deg, o.kappa_deg],
                    convention: AngleConvention::OmegaPhiKappa,
                }),
                corrections: CorrectionsSection { refraction: Refraction::None, earth_curvature: false },
                rpc: None,
                panoramic: None,
            }
        }
        CameraKind::Digital | CameraKind::Rpc | CameraKind::Panoramic => {
            let px = 0.006 * 8000.0 / o.width.max(o.height) as f64;
            let flying = DIGITAL_FOCAL * o.scale / 1000.0;
            CameraFile {
                crs: format!("EPSG:{EPSG}"),
                camera: CameraSection { model: "frame".into(), focal_length_mm: Some(DIGITAL_FOCAL) },
                interior: Some(InteriorSection {
                    pixel_size_mm: Some(PixelSize::Square(px)),
                    principal_point_px: Some([o.width as f64 / 2.0 + 3.7, o.height as f64 / 2.0 - 2.9]),
                    ..Default::default()
                }),
                distortion: Some(DistortionSection { brown: Some(Brown { k1: -0.02, k2: 0.004, k3: 0.0, p1: 1.0e-5, p2: -2.0e-5 }), ..Default::default() }),
                exterior: Some(ExteriorSection {
                    position: [centre_x, centre_y, ground_h + flying],
                    angles_deg: [omega, tilt2, o.kappa_deg],
                    convention: AngleConvention::OmegaPhiKappa,
                }),
                corrections: CorrectionsSection { refraction: Refraction::Auto, earth_curvature: true },
                rpc: None,
                panoramic: None,
            }
        }
    }
}

/// The relief raster around (cx, cy), `half` metres each way.
fn relief(o: &SynthOptions, cx: f64, cy: f64, half: f64, flying: f64) -> Result<GridDem> {
    let p = o.dem_posting;
    let n = ((2.0 * half / p).ceil() as usize).max(4);
    let x0 = ((cx - half) / p).floor() * p;
    let y0 = ((cy + half) / p).ceil() * p;
    relief_grid(o, (n, n), [x0, p, 0.0, y0, 0.0, -p], &|x, y| (x, y), (p, p), 0.35 * flying, EPSG)
}

/// A relief raster of `size` samples on the geotransform `gt` in EPSG:`epsg`:
/// the noise is evaluated at `metres(X, Y)` (a local metric position), its
/// samples are `posting_m` metres apart. Hilly reliefs are scaled to a
/// steepest slope of 20°, mountains to a height range of `mountain_range`.
fn relief_grid(
    o: &SynthOptions,
    (nx, ny): (usize, usize),
    gt: [f64; 6],
    metres: &(dyn Fn(f64, f64) -> (f64, f64) + Sync),
    posting_m: (f64, f64),
    mountain_range: f64,
    epsg: u32,
) -> Result<GridDem> {
    if nx as u128 * ny as u128 > MAX_DEM_SAMPLES {
        let side = |n: usize| if n == usize::MAX { "more than 10^19".to_string() } else { n.to_string() };
        return Err(Error::setting("dem_posting", format!("makes a DEM of {} × {} samples over the scene: more than {MAX_DEM_SAMPLES}", side(nx), side(ny))));
    }
    let seed = o.seed ^ 0xde_0de;
    let raw: Vec<f64> = (0..nx * ny)
        .into_par_iter()
        .map(|k| {
            let (x, y) = metres(gt[0] + ((k % nx) as f64 + 0.5) * gt[1], gt[3] + ((k / nx) as f64 + 0.5) * gt[5]);
            match o.relief {
                Relief::Flat => 0.0,
                Relief::Hilly => noise::fbm(x / 700.0, y / 700.0, 3, seed),
                Relief::Mountain => noise::ridged(x / 900.0, y / 900.0, 4, seed),
                Relief::Urban => noise::fbm(x / 900.0, y / 900.0, 2, seed),
            }
        })
        .collect();
    let (lo, hi) = raw.iter().fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    let amp = match o.relief {
        Relief::Flat => 0.0,
        Relief::Hilly => 20f64.to_radians().tan() / max_slope(&raw, (nx, ny), posting_m).max(1e-12),
        Relief::Mountain => mountain_range / (hi - lo).max(1e-12),
        // Gentle ground under the town: 4° at the steepest.
        Relief::Urban => 4f64.to_radians().tan() / max_slope(&raw, (nx, ny), posting_m).max(1e-12),
    };
    let data = raw
        .iter()
        .enumerate()
        .map(|(k, v)| {
            let ground = BASE_HEIGHT + amp * (v - lo);
            let above = if o.relief == Relief::Urban {
                let (x, y) = metres(gt[0] + ((k % nx) as f64 + 0.5) * gt[1], gt[3] + ((k / nx) as f64 + 0.5) * gt[5]);
                town(x, y, seed)
            } else {
                0.0
            };
            (ground + above) as f32
        })
        .collect();
    Ok(GridDem::new(nx, ny, data, gt, None, Some(crate::geodesy::Crs::from_epsg(epsg).expect("synthetic scenes use known codes"))))
}

/// Height above the ground of the town at (x, y), metres: lots of 32 m
/// along streets 8 m wide; most hold one flat-roofed building of 8 to 22 m
/// a side and 4 to 30 m high (vertical walls), the others trees, domes of
/// 2 to 4 m radius and 5 to 12 m high.
fn town(x: f64, y: f64, seed: u64) -> f64 {
    const LOT: f64 = 32.0;
    let (i, j) = ((x / LOT).floor(), (y / LOT).floor());
    let (lx, ly) = (x - i * LOT, y - j * LOT);
    let (i, j) = (i as i64, j as i64);
    let u = |k: u64| noise::unit(i, j, seed.wrapping_add(k));
    if u(1) < 0.75 {
        // A building within the lot's 24 m, leaving the street.
        let (w, d) = (8.0 + 14.0 * u(2), 8.0 + 14.0 * u(3));
        let (x0, y0) = ((24.0 - w) * u(4), (24.0 - d) * u(5));
        if lx >= x0 && lx < x0 + w && ly >= y0 && ly < y0 + d {
            return 4.0 + 26.0 * u(6) * u(6);
        }
        return 0.0;
    }
    // Trees: up to three in the lot.
    let mut h = 0.0f64;
    for t in 0..3 {
        let k = 10 + 4 * t;
        let (cx, cy, r, top) = (3.0 + 18.0 * u(k), 3.0 + 18.0 * u(k + 1), 2.0 + 2.0 * u(k + 2), 5.0 + 7.0 * u(k + 3));
        let d2 = ((lx - cx).powi(2) + (ly - cy).powi(2)) / (r * r);
        if d2 < 1.0 {
            h = h.max(top * (1.0 - d2).sqrt());
        }
    }
    h
}

/// Writes a relief raster as a Float32 GeoTIFF (square postings).
fn write_dem(path: &std::path::Path, g: &GridDem) -> Result<()> {
    let spec = OutputSpec {
        overviews: 0,
        cog: false,
        width: g.width as u32,
        height: g.height as u32,
        bands: 1,
        sample: SampleType::F32,
        chunking: Chunking::Strips(16),
        compression: Compression::None,
        level: None,
        overview_level: None,
        bigtiff: false,
        photometric: 1,
        alpha: false,
        mask: false,
        geo: Some(GeoTags {
            x0: g.transform[0],
            y0: g.transform[3],
            gsd: crate::geom::Gsd::square(g.transform[1]),
            keys: crate::geodesy::geokeys::keys_of(&g.crs.clone().unwrap_or_else(|| crate::geodesy::Crs::from_epsg(EPSG).expect("known")))
                .map_err(Error::Geometry)?,
            nodata: None,
        }),
    };
    write_raster(path, &spec, |y0, y1, buf| {
        let w = g.width;
        let src: Vec<f32> = (y0 as usize * w..y1 as usize * w).map(|k| g.sample(k % w, k / w)).collect();
        buf.copy_from_slice(bytemuck::cast_slice(&src));
    })
}

/// Steepest slope (tan) of a raster with samples `posting` metres apart,
/// by central differences.
fn max_slope(z: &[f64], (nx, ny): (usize, usize), (px, py): (f64, f64)) -> f64 {
    let mut m = 0.0f64;
    for j in 1..ny - 1 {
        for i in 1..nx - 1 {
            let gx = (z[j * nx + i + 1] - z[j * nx + i - 1]) / (2.0 * px);
            let gy = (z[(j + 1) * nx + i] - z[(j - 1) * nx + i]) / (2.0 * py);
            m = m.max(gx.hypot(gy));
        }
    }
    m
}

/// Is the photo point inside the image area (not the film margin)?
fn in_image(o: &SynthOptions, cam: &crate::camera::FrameCamera, c: f64, r: f64) -> bool {
    match o.camera {
        CameraKind::Film => {
            let (x, y) = cam.interior.px_to_mm(c, r);
            x.abs() <= o.frame_half() && y.abs() <= o.frame_half()
        }
        CameraKind::Digital | CameraKind::Rpc | CameraKind::Drone | CameraKind::Panoramic => c >= 0.0 && r >= 0.0 && c < o.width as f64 && r < o.height as f64,
    }
}

fn quantise(v: f32, bits: u32, out: &mut [u8]) {
    if bits == 8 {
        out[0] = quantise8(v);
    } else {
        out[..2].copy_from_slice(&(((v * 65535.0).clamp(0.0, 65535.0) + 0.5) as u16).to_ne_bytes());
    }
}

/// A pixel's samples from its colour: `bands` samples of `bits` each.
#[inline]
fn write_pixel(rgb: [f32; 3], bands: u32, bits: u32, px: &mut [u8]) {
    if bands == 3 && bits == 8 {
        // The common scan, without the per-band dispatch.
        if let [r, g, b, ..] = px {
            (*r, *g, *b) = (quantise8(rgb[0]), quantise8(rgb[1]), quantise8(rgb[2]));
        }
        return;
    }
    let sb = bits as usize / 8;
    for k in 0..bands {
        quantise(pixel_value(rgb, bands, k), bits, &mut px[k as usize * sb..]);
    }
}

#[inline]
fn quantise8(v: f32) -> u8 {
    ((v * 255.0).clamp(0.0, 255.0) + 0.5) as u8
}

fn pixel_value(rgb: [f32; 3], bands: u32, k: u32) -> f32 {
    match (bands, k) {
        (1, _) | (2, 0) => 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2],
        (_, 0..=2) => rgb[k as usize],
        // A near-infrared-like fourth band.
        _ => (1.2 * rgb[1] - 0.3 * rgb[0]).clamp(0.0, 1.0),
    }
}

/// Generates the scene. See the module doc.
pub fn synth(o: &SynthOptions, progress: &dyn Progress) -> Result<SynthReport> {
    check(o)?;
    std::fs::create_dir_all(&o.out).map_err(|e| Error::io(&o.out, e))?;
    if o.camera == CameraKind::Rpc {
        return satellite::synth_rpc(o, progress);
    }
    if o.camera == CameraKind::Panoramic {
        return panoramic::synth_panoramic(o, progress);
    }
    let cam_path = o.out.join("camera.toml");
    let dem_path = o.out.join("dem.tif");
    let scan_path = o.out.join("scan.tif");

    // Camera first (needs the terrain's base height only), then a DEM
    // generously covering its footprint.
    let file = camera_file(o, BASE_HEIGHT);
    let text = file.to_toml();
    crate::io::publish::write_file(&cam_path, text.as_bytes())?;
    let camera = crate::camera::file::Camera::read(&cam_path)?;
    let cam = camera.frame(&cam_path)?;
    let flying = file.exterior.as_ref().expect("synth writes exterior").position[2] - BASE_HEIGHT;
    let (focal, film_half) = match o.camera {
        CameraKind::Film => (FILM_FOCAL, o.film_mm() / 2.0),
        CameraKind::Digital | CameraKind::Rpc | CameraKind::Panoramic => (DIGITAL_FOCAL, cam.interior.pixel_size_mm() * o.width.max(o.height) as f64 / 2.0),
        CameraKind::Drone => (DRONE_FOCAL, cam.interior.pixel_size_mm() * o.width.max(o.height) as f64 / 2.0),
    };
    // Far enough to hold the footprint, an oblique one's far side too.
    let tilt = if o.camera == CameraKind::Drone { o.off_nadir_deg.to_radians() } else { 0.0 };
    let half = 1.8 * (tilt + (film_half / focal).atan()).min(1.3).tan() * flying + 200.0;
    let grid_dem = relief(o, cam.centre.x, cam.centre.y, half, flying)?;
    let zs: Vec<f64> = grid_dem.samples(1).iter().map(|&v| v as f64).collect();
    let (zlo, zhi) = zs.iter().fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    let slope = max_slope(&zs, (grid_dem.width, grid_dem.height), (o.dem_posting, o.dem_posting)).atan().to_degrees();
    if zhi >= cam.centre.z {
        return Err(Error::setting("scale", format!("1:{} puts the camera at {:.1} m, under the relief's top at {zhi:.1} m", o.scale, cam.centre.z)));
    }
    write_dem(&dem_path, &grid_dem)?;
    let dem = Dem::grid(grid_dem, &dem_path);
    let mid_z = (zlo + zhi) / 2.0;

    // The scan.
    let tex = Texture::new(o.seed, centre_gsd(cam, &dem, o.width, o.height, mid_z)?, cam.centre.x, cam.centre.y, 2.0 * half);
    let inside = |c: f64, r: f64| in_image(o, cam, c, r);
    let colour = |x: f64, y: f64| tex.rgb(x, y);
    let film = (o.camera == CameraKind::Film).then(|| film_marks::Margin::new(o, &file, &cam.interior)).transpose()?;
    let margin = |c: f64, r: f64| -> [f32; 3] { film.as_ref().map_or([0.0; 3], |m| [m.tone(c, r); 3]) };
    let scene = Scene { model: cam, dem: &dem, colour: &colour, inside: &inside, margin: &margin, shade: &|_, _, c| c, mid_z };
    let scan_spec = scan_spec(o);
    if !o.no_scan {
        render_scan(o, &scene, &scan_spec, &scan_path, progress)?;
    }
    // The truth orthophoto on the grid rectify chooses by default.
    let gsd = footprint_gsd(cam, &dem, o.width, o.height, mid_z)?;
    let (grid, _) = auto_grid(cam, &dem, o.width, o.height, mid_z, crate::geom::Gsd::square(gsd))?;
    let measures = Measures { gsd, flying_height: flying, relief_range: [zlo, zhi], max_slope_deg: slope };
    finish(o, &scene.as_dyn(), &scan_spec, &grid, measures)
}

/// What a scene measures, for its report.
struct Measures {
    gsd: f64,
    flying_height: f64,
    relief_range: [f64; 2],
    max_slope_deg: f64,
}

/// The truth orthophoto (when under ~100 Mpx and a scan was rendered), the
/// checkpoints, and the report of what was written.
fn finish(o: &SynthOptions, sc: &Scene<'_>, spec: &OutputSpec, grid: &crate::geom::OutputGrid, m: Measures) -> Result<SynthReport> {
    let truth_path = o.out.join("truth.tif");
    let truth = if grid.pixel_count() <= 100_000_000 && !o.no_scan {
        render_truth(o, sc, spec, grid, &truth_path)?;
        Some(truth_path)
    } else {
        None
    };
    let checkpoints = o.out.join("checkpoints.csv");
    write_checkpoints(o, sc, grid, &checkpoints)?;
    Ok(SynthReport {
        scan: if o.no_scan { PathBuf::new() } else { o.out.join("scan.tif") },
        camera: o.out.join("camera.toml"),
        dem: o.out.join("dem.tif"),
        truth,
        checkpoints,
        gsd: m.gsd,
        flying_height: m.flying_height,
        relief_range: m.relief_range,
        max_slope_deg: m.max_slope_deg,
    })
}

/// What rendering needs of a scene: the sensor and the terrain in one
/// ground CRS, the ground's colour there, which scan pixels see the ground
/// and what the others show.
///
/// Generic over the model and the two per-pixel functions, so that the
/// scan, which calls them once or more per pixel, is rendered with them
/// inlined; the rest takes the `dyn` scene (`as_dyn`).
struct Scene<
    'a,
    M: SensorModel + ?Sized = dyn SensorModel + 'a,
    C: Fn(f64, f64) -> [f32; 3] + Sync + ?Sized = dyn Fn(f64, f64) -> [f32; 3] + Sync + 'a,
    I: Fn(f64, f64) -> bool + Sync + ?Sized = dyn Fn(f64, f64) -> bool + Sync + 'a,
> {
    model: &'a M,
    dem: &'a Dem,
    colour: &'a C,
    inside: &'a I,
    margin: &'a (dyn Fn(f64, f64) -> [f32; 3] + Sync),
    /// The camera's own exposure of a colour seen at scan pixel (c, r):
    /// a block's frames differ in gain, offset and vignetting.
    shade: &'a (dyn Fn(f64, f64, [f32; 3]) -> [f32; 3] + Sync),
    mid_z: f64,
}

impl<'a, M, C, I> Scene<'a, M, C, I>
where
    M: SensorModel,
    C: Fn(f64, f64) -> [f32; 3] + Sync,
    I: Fn(f64, f64) -> bool + Sync,
{
    fn as_dyn(&self) -> Scene<'_> {
        Scene { model: self.model, dem: self.dem, colour: self.colour, inside: self.inside, margin: self.margin, shade: self.shade, mid_z: self.mid_z }
    }
}

/// The layout of the scan file.
fn scan_spec(o: &SynthOptions) -> OutputSpec {
    let sample = if o.bits == 8 { SampleType::U8 } else { SampleType::U16 };
    let spec = OutputSpec {
        overviews: 0,
        cog: false,
        width: o.width,
        height: o.height,
        bands: o.bands,
        sample,
        chunking: if o.tiled { Chunking::Tiles(256) } else { Chunking::Strips(16) },
        compression: o.compress,
        level: None,
        overview_level: None,
        bigtiff: false,
        photometric: if o.bands >= 3 { 2 } else { 1 },
        alpha: false,
        mask: false,
        geo: None,
    };
    OutputSpec { bigtiff: spec.needs_bigtiff(), ..spec }
}

/// The layout of a true orthophoto on `grid` (in the scene's UTM zone):
/// the scan's samples, deflated tiles, 0 for no data.
fn truth_spec(scan: &OutputSpec, grid: &crate::geom::OutputGrid) -> Result<OutputSpec> {
    Ok(OutputSpec {
        width: grid.width,
        height: grid.height,
        chunking: Chunking::Tiles(256),
        compression: Compression::Deflate,
        level: None,
        overview_level: None,
        geo: Some(GeoTags {
            x0: grid.x0,
            y0: grid.y0,
            gsd: grid.gsd,
            keys: crate::geodesy::geokeys::keys_of(&crate::geodesy::Crs::from_epsg(EPSG).expect("known")).map_err(Error::Geometry)?,
            nodata: Some(0.0),
        }),
        bigtiff: false,
        ..scan.clone()
    })
}

/// The true orthophoto on `grid` (in the scene's UTM zone):
/// the ground's colour wherever the scan sees the ground, 0 elsewhere.
fn render_truth(o: &SynthOptions, sc: &Scene<'_>, scan: &OutputSpec, grid: &crate::geom::OutputGrid, path: &std::path::Path) -> Result<()> {
    let pb = o.bands as usize * scan.sample.bytes();
    let spec = truth_spec(scan, grid)?;
    write_raster(path, &spec, |y0, _y1, buf| {
        let row_bytes = grid.width as usize * pb;
        buf.par_chunks_mut(row_bytes).enumerate().for_each(|(k, row)| {
            let v = (y0 as usize + k) as f64 + 0.5;
            for i in 0..grid.width as usize {
                let (x, y) = grid.ground(i as f64 + 0.5, v);
                let px = &mut row[i * pb..(i + 1) * pb];
                let seen = match sc.dem.height(x, y) {
                    Height::Value(z) => sc.model.project(x, y, z).filter(|&(c, r)| (sc.inside)(c, r)).is_some(),
                    _ => false,
                };
                if !seen {
                    px.fill(0);
                    continue;
                }
                let rgb = (sc.colour)(x, y);
                write_pixel(rgb, o.bands, o.bits, px);
            }
        });
    })
}

/// 50 checkpoints: ground points inside the image, with their exact scan positions.
fn write_checkpoints(o: &SynthOptions, sc: &Scene<'_>, grid: &crate::geom::OutputGrid, path: &std::path::Path) -> Result<()> {
    let mut csv = String::from("id,X,Y,Z,col,row\n");
    let mut id = 0;
    for k in 0..2000 {
        if id == 50 {
            break;
        }
        let x = grid.x0 + grid.gsd.x * grid.width as f64 * (0.1 + 0.8 * noise::unit(k, 1, o.seed ^ 0xc4));
        let y = grid.y0 - grid.gsd.y * grid.height as f64 * (0.1 + 0.8 * noise::unit(k, 2, o.seed ^ 0xc4));
        let Height::Value(z) = sc.dem.height(x, y) else { continue };
        let Some((c, r)) = sc.model.project(x, y, z) else { continue };
        if !(sc.inside)(c, r) {
            continue;
        }
        id += 1;
        csv.push_str(&format!("{id},{x:.4},{y:.4},{z:.4},{c:.4},{r:.4}\n"));
    }
    crate::io::publish::write_file(path, csv.as_bytes())
}
