//! Panoramic scenes (`synth --camera panoramic`): a KH-4B-like optical bar
//! (609.6 mm lens, a 70° scan across the track, 15° forward tilt, 170 km
//! up at 7,700 m/s, full image motion compensation) over a relief posted
//! in EPSG:4326. The scan's columns span the whole 70° whatever `--size`,
//! so the film's pixel grows as the scan shrinks: the geometry of the
//! cylinder, at any size.
//!
//! The scan time is 0.36 s, spymicmac's for KH-4 (after the results of
//! Sohn et al. and Ghuffar et al. on real frames); Ames Stereo Pipeline's
//! sample camera has 0.5 s, a placeholder its documentation says to
//! adjust. It is among what a GCP resection fits (`--gcp-refine interior`).
//!
//! Written: `scan.tif`, `camera.toml` (`model = "panoramic"`, orthophoto in
//! UTM 31N), `scan.tsai` (the same camera as ASP's `OPTICAL_BAR` file),
//! `dem.tif` (EPSG:4326), `truth.tif` (UTM, when small enough) and
//! `checkpoints.csv` (UTM).

use super::{finish, noise, relief_grid, render_scan, scan_spec, write_dem, Measures, Scene, SynthOptions, SynthReport};
use super::{texture::Texture, BASE_HEIGHT, EPSG, ORIGIN};
use crate::camera::file::CameraFile;
use crate::camera::panoramic::{rot_x, OpticalBar, PanoramicCamera};
use crate::dem::Dem;
use crate::error::{Error, Result};
use crate::geodesy::ecef::{enu_axes, to_ecef};
use crate::geodesy::GroundCrs;
use crate::transform::footprint::{auto_grid, footprint_gsd};
use nalgebra::{Matrix3, Vector3};

const METRES_PER_DEGREE: f64 = 111_194.93;
const ALTITUDE: f64 = 170_000.0;
const FOCAL: f64 = 0.6096;
const SCAN_DEG: f64 = 70.0;
const TILT_DEG: f64 = 15.0;
const SPEED: f64 = 7_700.0;
const SCAN_TIME: f64 = 0.36;
const MOUNTAIN_RANGE: f64 = 2000.0;

/// A camera of the scene: its scan's middle looks at the scene centre
/// (lon0, lat0) at the base height, flying `10° + kappa` east of north,
/// `tilt_deg` forward (negative: back), sweeping its columns left to right
/// or back.
pub(super) fn camera(o: &SynthOptions, lon0: f64, lat0: f64, tilt_deg: f64, left_to_right: bool) -> OpticalBar {
    let enu = enu_axes(lon0, lat0);
    let psi = (10.0 + o.kappa_deg).to_radians();
    let along = enu * Vector3::new(psi.sin(), psi.cos(), 0.0);
    let down = -(enu * Vector3::z());
    // x along the scan, y along the flight, z down (before the tilt).
    let level = Matrix3::from_columns(&[along.cross(&down), along, down]);
    let tilt = tilt_deg.to_radians();
    let rotation = level * rot_x(-tilt);
    let target = to_ecef(lon0, lat0, BASE_HEIGHT);
    let middle = target - ALTITUDE * down - ALTITUDE * tilt.tan() * along;
    let pitch = FOCAL * SCAN_DEG.to_radians() / f64::from(o.width - 1);
    let travel = SPEED * SCAN_TIME * along;
    OpticalBar {
        size: [o.width, o.height],
        centre_px: [f64::from(o.width) / 2.0, f64::from(o.height) / 2.0],
        pitch,
        focal: FOCAL,
        scan_time: SCAN_TIME,
        left_to_right,
        forward_tilt: tilt,
        position: middle - 0.5 * travel,
        rotation,
        speed: SPEED,
        motion: None,
        motion_compensation: 1.0,
        earth_radius: 6_371_000.0,
        surface_elevation: BASE_HEIGHT,
        mirror_offset: 0.0,
    }
}

/// The scene's centre (longitude, latitude) and its local metres.
struct Local {
    lon0: f64,
    lat0: f64,
    cos0: f64,
}

impl Local {
    fn new(o: &SynthOptions) -> Result<Local> {
        let utm = GroundCrs::from_epsg(EPSG).map_err(Error::Geometry)?;
        let u = |k: i64| noise::unit(k, 3, o.seed);
        let centre = (ORIGIN.0 + (u(3) * 1000.0).round(), ORIGIN.1 + (u(4) * 1000.0).round());
        let (lon0, lat0) = utm.to_lonlat(centre.0, centre.1).ok_or_else(|| Error::Geometry("scene centre".into()))?;
        Ok(Local { lon0, lat0, cos0: lat0.to_radians().cos() })
    }

    fn metres(&self, lon: f64, lat: f64) -> (f64, f64) {
        ((lon - self.lon0) * METRES_PER_DEGREE * self.cos0, (lat - self.lat0) * METRES_PER_DEGREE)
    }
}

/// The relief under every camera's footprint (the film's edges, a bow-tie
/// on the ground, sampled along every side at the relief's lowest and
/// highest heights), posted in EPSG:4326; its heights' range and steepest
/// slope, degrees.
fn relief_under(o: &SynthOptions, bars: &[&OpticalBar], local: &Local) -> Result<(crate::dem::GridDem, (f64, f64), f64)> {
    let geo = GroundCrs::from_epsg(4326).map_err(Error::Geometry)?;
    let (w, h) = (f64::from(o.width), f64::from(o.height));
    let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
    for bar in bars {
        let flat = PanoramicCamera::new((*bar).clone(), geo.clone(), None);
        for k in 0..=32 {
            let t = f64::from(k) / 32.0;
            for (c, r) in [(t * w, 0.0), (t * w, h), (0.0, t * h), (w, t * h)] {
                for z in [BASE_HEIGHT - 100.0, BASE_HEIGHT + MOUNTAIN_RANGE + 100.0] {
                    let (lon, lat) = crate::camera::SensorModel::locate_approx(&flat, c, r, z)
                        .ok_or_else(|| Error::Geometry("synth's panoramic footprint misses the earth".into()))?;
                    lo = (lo.0.min(lon), lo.1.min(lat));
                    hi = (hi.0.max(lon), hi.1.max(lat));
                }
            }
        }
    }
    let gsd_nadir = ALTITUDE * bars[0].pitch / bars[0].focal;
    let posting = o.dem_posting.max(gsd_nadir);
    let p = posting / METRES_PER_DEGREE;
    let margin = 5.0 * posting / METRES_PER_DEGREE;
    let x0 = ((lo.0 - 2.0 * margin) / p).floor() * p;
    let y0 = ((hi.1 + margin) / p).ceil() * p;
    let nx = ((hi.0 + 2.0 * margin - x0) / p).ceil() as usize;
    let ny = ((y0 - lo.1 + margin) / p).ceil() as usize;
    let posting_m = (p * METRES_PER_DEGREE * local.cos0, posting);
    let grid_dem = relief_grid(o, (nx, ny), [x0, p, 0.0, y0, 0.0, -p], &|x, y| local.metres(x, y), posting_m, MOUNTAIN_RANGE, 4326)?;
    let zs: Vec<f64> = grid_dem.samples(1).iter().map(|&v| f64::from(v)).collect();
    let (zlo, zhi) = zs.iter().fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    let slope = super::max_slope(&zs, (nx, ny), posting_m).atan().to_degrees();
    Ok((grid_dem, (zlo, zhi), slope))
}

/// Renders `bar`'s scan over `dem` (EPSG:4326) into `path`.
fn render(
    o: &SynthOptions,
    bar: &OpticalBar,
    dem: &Dem,
    mid_z: f64,
    local: &Local,
    path: &std::path::Path,
    progress: &dyn crate::progress::Progress,
) -> Result<()> {
    let geo = GroundCrs::from_epsg(4326).map_err(Error::Geometry)?;
    let model = PanoramicCamera::new(bar.clone(), geo, None);
    let gsd_nadir = ALTITUDE * bar.pitch / bar.focal;
    let (w, h) = (f64::from(o.width), f64::from(o.height));
    // (The texture's features around the scene centre, local metres (0, 0).)
    let tex = Texture::new(o.seed, gsd_nadir, 0.0, 0.0, w * gsd_nadir * 1.5);
    let inside = |c: f64, r: f64| c >= 0.0 && r >= 0.0 && c < w && r < h;
    let colour = |lon: f64, lat: f64| {
        let (x, y) = local.metres(lon, lat);
        tex.rgb(x, y)
    };
    let scene = Scene { model: &model, dem, colour: &colour, inside: &inside, margin: &|_, _| [0.0; 3], shade: &|_, _, c| c, mid_z };
    render_scan(o, &scene, &scan_spec(o), path, progress)
}

pub(super) fn synth_panoramic(o: &SynthOptions, progress: &dyn crate::progress::Progress) -> Result<SynthReport> {
    let out = |name: &str| o.out.join(name);
    let local = Local::new(o)?;
    let bar = camera(o, local.lon0, local.lat0, TILT_DEG, true);
    bar.check().map_err(|(field, m)| Error::Geometry(format!("synth's panoramic camera: {field}: {m}")))?;
    let (grid_dem, (zlo, zhi), slope) = relief_under(o, &[&bar], &local)?;
    let dem_path = out("dem.tif");
    write_dem(&dem_path, &grid_dem)?;
    let cam_path = out("camera.toml");
    crate::io::publish::write_file(&cam_path, CameraFile::panoramic(&bar, &format!("EPSG:{EPSG}")).to_toml().as_bytes())?;
    let tsai = out("scan.tsai");
    crate::io::publish::write_file(&tsai, crate::camera::panoramic_file::asp_text(&bar).as_bytes())?;
    let dem_geo = Dem::grid(grid_dem, &dem_path);
    let mid_z = (zlo + zhi) / 2.0;
    if !o.no_scan {
        render(o, &bar, &dem_geo, mid_z, &local, &out("scan.tif"), progress)?;
    }

    // Truth and checkpoints in UTM, on the grid rectify chooses by default.
    let utm = GroundCrs::from_epsg(EPSG).map_err(Error::Geometry)?;
    let model = PanoramicCamera::new(bar, utm, None);
    let dem = Dem::open(&dem_path, &crate::geodesy::Crs::from_epsg(EPSG).map_err(Error::Geometry)?)?;
    let gsd = footprint_gsd(&model, &dem, o.width, o.height, mid_z)?;
    let (grid, _) = auto_grid(&model, &dem, o.width, o.height, mid_z, crate::geom::Gsd::square(gsd))?;
    let gsd_nadir = ALTITUDE * model.bar.pitch / model.bar.focal;
    let tex = Texture::new(o.seed, gsd_nadir, 0.0, 0.0, f64::from(o.width) * gsd_nadir * 1.5);
    let colour = |x: f64, y: f64| match model.crs.to_lonlat(x, y) {
        Some((lon, lat)) => {
            let (mx, my) = local.metres(lon, lat);
            tex.rgb(mx, my)
        }
        None => [0.0; 3],
    };
    let (w, h) = (f64::from(o.width), f64::from(o.height));
    let inside = |c: f64, r: f64| c >= 0.0 && r >= 0.0 && c < w && r < h;
    let scene = Scene { model: &model, dem: &dem, colour: &colour, inside: &inside, margin: &|_, _| [0.0; 3], shade: &|_, _, c| c, mid_z };
    finish(o, &scene.as_dyn(), &scan_spec(o), &grid, Measures { gsd, flying_height: ALTITUDE, relief_range: [zlo, zhi], max_slope_deg: slope })
}

/// A fore/aft pair as KH-4B's two cameras took them: the fore camera
/// tilted forward and sweeping left to right, the aft one tilted back and
/// sweeping back, both looking at the scene centre, the tilts set by
/// `base_to_height` (KH-4B's ±15°: 0.54). Written: `left.tif`,
/// `right.tif`, `left.toml`, `right.toml` (and ASP's `left.tsai`,
/// `right.tsai`), `dem.tif` (the true heights, EPSG:4326).
pub fn synth_panoramic_pair(o: &SynthOptions, base_to_height: f64, progress: &dyn crate::progress::Progress) -> Result<super::satellite::PairReport> {
    if !(0.05..=1.2).contains(&base_to_height) {
        return Err(Error::setting("stereo", format!("a base-to-height ratio of {base_to_height} is not 0.05 to 1.2")));
    }
    std::fs::create_dir_all(&o.out).map_err(|e| Error::io(&o.out, e))?;
    let out = |name: &str| o.out.join(name);
    let local = Local::new(o)?;
    let tilt = (base_to_height / 2.0).atan().to_degrees();
    let bars = [camera(o, local.lon0, local.lat0, tilt, true), camera(o, local.lon0, local.lat0, -tilt, false)];
    for b in &bars {
        b.check().map_err(|(field, m)| Error::Geometry(format!("synth's panoramic camera: {field}: {m}")))?;
    }
    let (grid_dem, (zlo, zhi), _) = relief_under(o, &[&bars[0], &bars[1]], &local)?;
    let dem_path = out("dem.tif");
    write_dem(&dem_path, &grid_dem)?;
    let dem_geo = Dem::grid(grid_dem, &dem_path);
    for (bar, name) in bars.iter().zip(["left", "right"]) {
        let cam = out(&format!("{name}.toml"));
        crate::io::publish::write_file(&cam, CameraFile::panoramic(bar, &format!("EPSG:{EPSG}")).to_toml().as_bytes())?;
        let tsai = out(&format!("{name}.tsai"));
        crate::io::publish::write_file(&tsai, crate::camera::panoramic_file::asp_text(bar).as_bytes())?;
        render(o, bar, &dem_geo, (zlo + zhi) / 2.0, &local, &out(&format!("{name}.tif")), progress)?;
    }
    Ok(super::satellite::PairReport {
        left: out("left.tif"),
        right: out("right.tif"),
        left_model: out("left.toml"),
        right_model: out("right.toml"),
        dem: dem_path,
        base_to_height,
        relief_range: [zlo, zhi],
    })
}
