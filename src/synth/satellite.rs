//! Satellite scenes (`synth --camera rpc`): a pushbroom sensor 650 km up,
//! rolled `--off-nadir` degrees across track (and pitched 3° along it) on a
//! track 10° + `--kappa` off north, looking at a relief posted in EPSG:4326
//! like SRTM. As image providers do, the RPC is *fitted* to the physical
//! sensor over the scene's height range; the fitted RPC is then the truth:
//! the scan is rendered through it, and `rectify` inverts it.
//!
//! Written: `scan.tif`, `scan_RPC.TXT` (GDAL's sidecar name, so gdalwarp
//! `-rpc` finds it), `camera.toml` (`model = "rpc"`, orthophoto in UTM
//! 31N), `dem.tif` (EPSG:4326), `truth.tif` (UTM, when small enough) and
//! `checkpoints.csv` (UTM).

use super::{finish, noise, relief_grid, render_scan, scan_spec, write_dem, Measures, Scene, SynthOptions, SynthReport};
use super::{texture::Texture, BASE_HEIGHT, EPSG, ORIGIN};
use crate::camera::file::{CameraFile, CameraSection, CorrectionsSection, RpcSection};
use crate::camera::rpc::fit::fit_rpc;
use crate::camera::rpc::Rpc;
use crate::camera::RpcCamera;
use crate::dem::Dem;
use crate::error::{Error, Result};
use crate::geodesy::GroundCrs;
use crate::transform::footprint::{auto_grid, footprint_gsd};

/// Metres per degree of latitude on the sphere of the scene's local frame.
const METRES_PER_DEGREE: f64 = 111_194.93;
const ALTITUDE: f64 = 650_000.0;
const PITCH_DEG: f64 = 3.0;
/// Ground sample distance at the scene centre, metres.
const GSD: f64 = 0.5;

/// The physical sensor: continuous scan (column, row) at height z →
/// longitude, latitude. Flat-earth local frame around (lon0, lat0).
struct Pushbroom {
    lon0: f64,
    lat0: f64,
    roll: f64,
    pitch: f64,
    /// Unit vectors (east, north) along and across the track.
    along: (f64, f64),
    across: (f64, f64),
    ifov: f64,
    width: f64,
    height: f64,
}

impl Pushbroom {
    fn new(o: &SynthOptions, lon0: f64, lat0: f64) -> Pushbroom {
        Self::pitched(o, lon0, lat0, PITCH_DEG)
    }

    /// A sensor looking `pitch_deg` forward along its track (negative:
    /// back): the two views of an in-track stereo pair.
    fn pitched(o: &SynthOptions, lon0: f64, lat0: f64, pitch_deg: f64) -> Pushbroom {
        let roll = o.off_nadir_deg.to_radians();
        let psi = (10.0 + o.kappa_deg).to_radians();
        Pushbroom {
            lon0,
            lat0,
            roll,
            pitch: pitch_deg.to_radians(),
            // A descending pass: rows run south-ish, columns east-ish.
            along: (psi.sin(), -psi.cos()),
            across: (psi.cos(), psi.sin()),
            ifov: GSD * roll.cos().powi(2) / ALTITUDE,
            width: o.width as f64,
            height: o.height as f64,
        }
    }

    /// Local metres (east, north) of longitude/latitude, and back.
    fn metres(&self, lon: f64, lat: f64) -> (f64, f64) {
        ((lon - self.lon0) * METRES_PER_DEGREE * self.lat0.to_radians().cos(), (lat - self.lat0) * METRES_PER_DEGREE)
    }

    fn lonlat(&self, x: f64, y: f64) -> (f64, f64) {
        (self.lon0 + x / (METRES_PER_DEGREE * self.lat0.to_radians().cos()), self.lat0 + y / METRES_PER_DEGREE)
    }

    /// Where the ray of scan pixel (c, r) meets height z.
    fn ground(&self, c: f64, r: f64, z: f64) -> (f64, f64) {
        let dz = BASE_HEIGHT + ALTITUDE - z;
        let phi = self.roll + (c - self.width / 2.0) * self.ifov;
        let across = -ALTITUDE * self.roll.tan() + dz * phi.tan();
        let along = (r - self.height / 2.0) * GSD - (z - BASE_HEIGHT) * self.pitch.tan();
        self.lonlat(across * self.across.0 + along * self.along.0, across * self.across.1 + along * self.along.1)
    }
}

/// The relief under `sensors` (the first's local metres): a posting of
/// `dem_posting` metres in latitude, square in degrees like SRTM, covering
/// every footprint at every height with room; its heights' range and
/// steepest slope, degrees.
fn relief_under(o: &SynthOptions, sensors: &[&Pushbroom], lat0: f64) -> Result<(crate::dem::GridDem, (f64, f64), f64)> {
    let mountain_range = 2000.0;
    let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
    for sensor in sensors {
        for (c, r) in [(0.0, 0.0), (sensor.width, 0.0), (0.0, sensor.height), (sensor.width, sensor.height)] {
            for z in [BASE_HEIGHT, BASE_HEIGHT + mountain_range] {
                let (lon, lat) = sensor.ground(c, r, z);
                lo = (lo.0.min(lon), lo.1.min(lat));
                hi = (hi.0.max(lon), hi.1.max(lat));
            }
        }
    }
    let p = o.dem_posting / METRES_PER_DEGREE;
    let margin = 300.0 / METRES_PER_DEGREE;
    let x0 = ((lo.0 - 2.0 * margin) / p).floor() * p;
    let y0 = ((hi.1 + margin) / p).ceil() * p;
    let nx = ((hi.0 + 2.0 * margin - x0) / p).ceil() as usize;
    let ny = ((y0 - lo.1 + margin) / p).ceil() as usize;
    let posting_m = (p * METRES_PER_DEGREE * lat0.to_radians().cos(), o.dem_posting);
    let s0 = sensors[0];
    let grid_dem = relief_grid(o, (nx, ny), [x0, p, 0.0, y0, 0.0, -p], &|x, y| s0.metres(x, y), posting_m, mountain_range, 4326)?;
    let zs: Vec<f64> = grid_dem.samples(1).iter().map(|&v| f64::from(v)).collect();
    let (zlo, zhi) = zs.iter().fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    let slope = super::max_slope(&zs, (nx, ny), posting_m).atan().to_degrees();
    Ok((grid_dem, (zlo, zhi), slope))
}

/// The RPC of `sensor`, fitted on a 21×21×7 grid over the heights
/// `zlo..zhi` (50 m more each side), as image providers fit theirs.
fn fitted_rpc(sensor: &Pushbroom, zlo: f64, zhi: f64) -> Result<Rpc> {
    let mut pts = Vec::with_capacity(21 * 21 * 7);
    for j in 0..=20 {
        for i in 0..=20 {
            for k in 0..=6 {
                let (c, r) = (sensor.width * i as f64 / 20.0, sensor.height * j as f64 / 20.0);
                let z = zlo - 50.0 + (zhi - zlo + 100.0) * k as f64 / 6.0;
                let (lon, lat) = sensor.ground(c, r, z);
                pts.push(((lon, lat, z), (c, r)));
            }
        }
    }
    let fitted = fit_rpc(&pts).ok_or_else(|| Error::Geometry("the RPC fit is singular".into()))?;
    if fitted.max_residual_px > 0.01 {
        return Err(Error::Geometry(format!("the RPC fits the sensor only to {:.3} px", fitted.max_residual_px)));
    }
    Ok(fitted.rpc)
}

pub(super) fn synth_rpc(o: &SynthOptions, progress: &dyn crate::progress::Progress) -> Result<SynthReport> {
    let out = |name: &str| o.out.join(name);
    let (cam_path, dem_path, scan_path, rpc_path) = (out("camera.toml"), out("dem.tif"), out("scan.tif"), out("scan_RPC.TXT"));
    let utm = GroundCrs::from_epsg(EPSG).map_err(Error::Geometry)?;
    let u = |k: i64| noise::unit(k, 3, o.seed);
    let centre = (ORIGIN.0 + (u(3) * 1000.0).round(), ORIGIN.1 + (u(4) * 1000.0).round());
    let (lon0, lat0) = utm.to_lonlat(centre.0, centre.1).ok_or_else(|| Error::Geometry("scene centre".into()))?;
    let sensor = Pushbroom::new(o, lon0, lat0);

    let (grid_dem, (zlo, zhi), slope) = relief_under(o, &[&sensor], lat0)?;
    write_dem(&dem_path, &grid_dem)?;
    let rpc: Rpc = fitted_rpc(&sensor, zlo, zhi)?;
    crate::io::publish::write_file(&rpc_path, rpc.to_gdal_text().as_bytes())?;
    let file = CameraFile {
        crs: format!("EPSG:{EPSG}"),
        camera: CameraSection { model: "rpc".into(), focal_length_mm: None },
        interior: None,
        distortion: None,
        exterior: None,
        corrections: CorrectionsSection::default(),
        rpc: Some(RpcSection { file: Some("scan_RPC.TXT".into()), offset_px: None, geoid: None, image: None, inline: Default::default() }),
        panoramic: None,
    };
    crate::io::publish::write_file(&cam_path, file.to_toml().as_bytes())?;

    // Render through the RPC in the DEM's own CRS (no reprojection per pixel).
    let geo = RpcCamera::new(rpc.clone(), GroundCrs::from_epsg(4326).map_err(Error::Geometry)?, None);
    let dem_geo = Dem::grid(grid_dem, &dem_path);
    let mid_z = (zlo + zhi) / 2.0;
    let tex = Texture::new(o.seed, GSD, 0.0, 0.0, o.width.max(o.height) as f64 * GSD);
    let (w, h) = (o.width as f64, o.height as f64);
    let inside = |c: f64, r: f64| c >= 0.0 && r >= 0.0 && c < w && r < h;
    let colour_geo = |lon: f64, lat: f64| {
        let (x, y) = sensor.metres(lon, lat);
        tex.rgb(x, y)
    };
    let spec = scan_spec(o);
    if !o.no_scan {
        let scene = Scene { model: &geo, dem: &dem_geo, colour: &colour_geo, inside: &inside, margin: &|_, _| [0.0; 3], shade: &|_, _, c| c, mid_z };
        render_scan(o, &scene, &spec, &scan_path, progress)?;
    }

    // Truth and checkpoints in UTM, on the grid rectify chooses by default.
    let model = RpcCamera::new(rpc, utm, None);
    let dem = Dem::open(&dem_path, &crate::geodesy::Crs::from_epsg(EPSG).map_err(Error::Geometry)?)?;
    let gsd = footprint_gsd(&model, &dem, o.width, o.height, mid_z)?;
    let (grid, _) = auto_grid(&model, &dem, o.width, o.height, mid_z, crate::geom::Gsd::square(gsd))?;
    let colour = |x: f64, y: f64| match model.crs.to_lonlat(x, y) {
        Some((lon, lat)) => colour_geo(lon, lat),
        None => [0.0; 3],
    };
    let scene = Scene { model: &model, dem: &dem, colour: &colour, inside: &inside, margin: &|_, _| [0.0; 3], shade: &|_, _, c| c, mid_z };
    finish(o, &scene.as_dyn(), &spec, &grid, Measures { gsd, flying_height: ALTITUDE, relief_range: [zlo, zhi], max_slope_deg: slope })
}

/// What `synth --camera rpc --stereo B/H` wrote.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PairReport {
    pub left: std::path::PathBuf,
    pub right: std::path::PathBuf,
    /// Each view's model: its RPC file, or its camera file.
    pub left_model: std::path::PathBuf,
    pub right_model: std::path::PathBuf,
    /// The ground's true heights (EPSG:4326, ellipsoidal).
    pub dem: std::path::PathBuf,
    pub base_to_height: f64,
    pub relief_range: [f64; 2],
}

/// An in-track stereo pair of one relief and texture: two pushbroom views
/// pitched forward and back so that the base-to-height ratio is
/// `base_to_height`, each with its RPC fitted as `synth_rpc`'s; a small
/// lake of flat colour in the scene. Written: `left.tif`, `right.tif`,
/// `left_RPC.TXT`, `right_RPC.TXT`, `dem.tif`, `lake.csv` (its centre and
/// radius in UTM 31N).
pub fn synth_rpc_pair(o: &SynthOptions, base_to_height: f64, progress: &dyn crate::progress::Progress) -> Result<PairReport> {
    if !(0.01..=1.2).contains(&base_to_height) {
        return Err(Error::setting("stereo", format!("a base-to-height ratio of {base_to_height} is not 0.01 to 1.2")));
    }
    std::fs::create_dir_all(&o.out).map_err(|e| Error::io(&o.out, e))?;
    let out = |name: &str| o.out.join(name);
    let utm = GroundCrs::from_epsg(EPSG).map_err(Error::Geometry)?;
    let u = |k: i64| noise::unit(k, 3, o.seed);
    let centre = (ORIGIN.0 + (u(3) * 1000.0).round(), ORIGIN.1 + (u(4) * 1000.0).round());
    let (lon0, lat0) = utm.to_lonlat(centre.0, centre.1).ok_or_else(|| Error::Geometry("scene centre".into()))?;
    let pitch = (base_to_height / 2.0).atan().to_degrees();
    let sensors = [Pushbroom::pitched(o, lon0, lat0, pitch), Pushbroom::pitched(o, lon0, lat0, -pitch)];
    let s0 = &sensors[0];
    let (grid_dem, (zlo, zhi), _) = relief_under(o, &[&sensors[0], &sensors[1]], lat0)?;
    let dem_path = out("dem.tif");
    write_dem(&dem_path, &grid_dem)?;
    let dem_geo = Dem::grid(grid_dem, &dem_path);
    let tex = Texture::new(o.seed, GSD, 0.0, 0.0, o.width.max(o.height) as f64 * GSD);
    // A lake: flat water, no texture to match (a hole in the DSM is the
    // right answer there). Written as its centre and radius in UTM.
    let side = o.width.min(o.height) as f64 * GSD;
    let lake = (0.2 * side, 0.15 * side, 0.05 * side);
    let colour_geo = |lon: f64, lat: f64| {
        let (x, y) = s0.metres(lon, lat);
        if (x - lake.0).hypot(y - lake.1) < lake.2 {
            return [0.32, 0.38, 0.42];
        }
        tex.rgb(x, y)
    };
    let (lake_lon, lake_lat) = s0.lonlat(lake.0, lake.1);
    let (lx, ly) = utm.lonlat_to_ground(lake_lon, lake_lat).ok_or_else(|| Error::Geometry("the lake's centre".into()))?;
    let lake_path = out("lake.csv");
    crate::io::publish::write_file(&lake_path, format!("x,y,radius\n{lx:.3},{ly:.3},{:.3}\n", lake.2).as_bytes())?;
    let (w, h) = (o.width as f64, o.height as f64);
    let inside = |c: f64, r: f64| c >= 0.0 && r >= 0.0 && c < w && r < h;
    let spec = scan_spec(o);
    for (sensor, name) in sensors.iter().zip(["left", "right"]) {
        let rpc = fitted_rpc(sensor, zlo, zhi)?;
        let rpc_path = out(&format!("{name}_RPC.TXT"));
        crate::io::publish::write_file(&rpc_path, rpc.to_gdal_text().as_bytes())?;
        let geo = RpcCamera::new(rpc, GroundCrs::from_epsg(4326).map_err(Error::Geometry)?, None);
        let scene =
            Scene { model: &geo, dem: &dem_geo, colour: &colour_geo, inside: &inside, margin: &|_, _| [0.0; 3], shade: &|_, _, c| c, mid_z: (zlo + zhi) / 2.0 };
        render_scan(o, &scene, &spec, &out(&format!("{name}.tif")), progress)?;
    }
    Ok(PairReport {
        left: out("left.tif"),
        right: out("right.tif"),
        left_model: out("left_RPC.TXT"),
        right_model: out("right_RPC.TXT"),
        dem: dem_path,
        base_to_height,
        relief_range: [zlo, zhi],
    })
}
