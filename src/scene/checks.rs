//! Whether a run's inputs belong together, before any pixel: an RPC that
//! folds, a camera made for another image, a crop's offset forgotten, a
//! frame that sees no ground, a drone's height on another datum. Refused
//! where the output would be wrong, warned of where it may be.

use crate::camera::file::{Camera, Sensor};
use crate::dem::{Dem, HeightModel};
use crate::error::{Error, Result};
use crate::geom::OutputGrid;
use crate::io::source::SourceInfo;
use crate::options::RectifyOptions;
use crate::progress::Progress;

/// The camera checked against the scan (`info`) and the ground under it
/// (`dem`, its mean height `z_guess`).
pub fn camera_meets_scan(opts: &RectifyOptions, camera: &Camera, info: &SourceInfo, dem: &Dem, z_guess: f64, progress: &dyn Progress) -> Result<()> {
    let (sw, sh) = (info.width, info.height);
    if let Sensor::Rpc(r) = &camera.sensor {
        super::terrain::check_geoid_covers(r, sw, sh, z_guess)?;
    }
    let frame = match &camera.sensor {
        Sensor::Frame(f) => Some((f, Some((f.centre.x, f.centre.y)))),
        Sensor::ReprojectedFrame(r) => Some((&r.inner, r.to_ground(r.inner.centre.x, r.inner.centre.y))),
        Sensor::Rpc(_) | Sensor::Panoramic(_) => None,
    };
    if let Some((f, _)) = frame {
        if let Some(w) = crate::camera::file::narrow_view(&opts.inputs.camera, &camera.file, (sw, sh), f.centre.z - z_guess) {
            progress.warn(&w);
        }
    }
    let sized = match &camera.sensor {
        Sensor::Panoramic(p) => Some(("panoramic.size_px", p.bar.size)),
        _ => camera.file.interior.as_ref().and_then(|i| i.image_size_px).map(|s| ("interior.image_size_px", s)),
    };
    if let Some((field, [w, h])) = sized {
        if [w, h] != [sw, sh] {
            return Err(Error::config(&opts.inputs.camera, field, format!("the camera is for {w}×{h} images, but {} is {sw}×{sh}", opts.inputs.image.display())));
        }
    }
    if let Some(r) = match &camera.sensor {
        Sensor::Rpc(r) => Some(&r.rpc),
        _ => None,
    } {
        // A crop of a scene whose tool kept the crop's place as a
        // "geotransform" of pixels (origin at its offset, pixels of 1,
        // no CRS: as the CNES and other crops are): its RPC is the whole
        // scene's, and without the offset the orthophoto lands a crop's
        // offset away (kilometres), without another sign.
        let given = camera.file.rpc.as_ref().and_then(|r| r.offset_px).is_some();
        if let Some(g) = info.georef.as_ref().filter(|_| !given) {
            let t = g.transform;
            let whole = |v: f64| v == v.round() && v.abs() < 1e7;
            // (And the image at that offset inside the RPC's scene: an
            // RPC already shifted to the crop puts it outside.)
            let inside = ((t[0] + sw as f64 / 2.0 - r.samp_off) / r.samp_scale).abs() <= 1.0
                && ((t[3].abs() + sh as f64 / 2.0 - r.line_off) / r.line_scale).abs() <= 1.0;
            if inside
                && g.keys.0.is_empty()
                && t[1].abs() == 1.0
                && t[5].abs() == 1.0
                && t[2] == 0.0
                && t[4] == 0.0
                && whole(t[0])
                && whole(t[3])
                && (t[0], t[3]) != (0.0, 0.0)
            {
                progress.warn(&format!(
                    "{}: its GeoTIFF origin ({}, {}) in pixels of 1 without a CRS looks like a crop's offset in the scene its RPC was fitted over: if it is, give ‹rpc_offset› {},{} (in a camera file rpc.offset_px), or the orthophoto lands that far off (an RPC already shifted to the crop: ‹rpc_offset› 0,0 says so)",
                    opts.inputs.image.display(),
                    t[0],
                    t[3],
                    t[0],
                    t[3].abs()
                ));
            }
        }
        // The image within the scene the RPC was fitted over (an RPC
        // extrapolated beyond it bends fast): its corners at most a
        // tenth of the scene beyond.
        let norm = |v: f64, off: f64, scale: f64| ((v - off) / scale).abs();
        let out = [0.0, sw as f64]
            .iter()
            .map(|&c| norm(c, r.samp_off, r.samp_scale))
            .chain([0.0, sh as f64].iter().map(|&l| norm(l, r.line_off, r.line_scale)))
            .fold(0.0, f64::max);
        if !(out <= 1.1) {
            progress.warn(&format!(
                "{}: the image ({sw}×{sh}) reaches {:.1} times the half-size of the scene its RPC was fitted over: beyond it the RPC is extrapolated; check the crop's offset (‹rpc_offset›, rpc.offset_px)",
                opts.inputs.image.display(),
                out
            ));
        }
        // The ground's heights within the range the RPC was fitted over
        // (HEIGHT_OFF ± HEIGHT_SCALE; twice that, and a geoid's
        // undulation, before it is doubted): far beyond, it is
        // extrapolated as fast as beyond the scene.
        if !((z_guess - r.height_off).abs() <= 2.0 * r.height_scale.abs() + 200.0) {
            progress.warn(&format!(
                "{}: the ground is at {z_guess:.0} m, but its RPC was fitted over heights {:.0} ± {:.0} m: far beyond them the RPC is extrapolated; check the DEM (or ‹height›) and that the RPC is this scene's",
                opts.inputs.image.display(),
                r.height_off,
                r.height_scale.abs()
            ));
        }
    }
    if let Some((f, centre)) = frame {
        // The ground under the camera where the DEM has it, else its mean.
        let below = match centre.map(|(x, y)| dem.height(x, y)) {
            Some(crate::dem::Height::Value(z)) => z,
            _ => z_guess,
        };
        // Past any terrain on Earth the heights are the DEM's fault (a
        // unit or a scale slipped), not the camera's being under them.
        if !(-12_000.0..=12_000.0).contains(&below) {
            let source = match &opts.inputs.dem {
                crate::options::DemSource::File(p) => p.display().to_string(),
                _ => "‹height›".into(),
            };
            return Err(Error::Named(format!(
                "{source}: a height of {} m under the camera is past any terrain on Earth (−12 to 12 km): heights in another unit, or scaled?",
                crate::error::short_number(below)
            )));
        }
        f.check_sees_ground(sw, sh, below, &opts.inputs.camera)?;
        // A camera made for another image (another size, another scan)
        // puts its principal point far from this one's centre.
        let (pc, pr) = f.interior.mm_to_px(0.0, 0.0);
        let off = (pc / sw as f64 - 0.5).abs().max((pr / sh as f64 - 0.5).abs());
        if !(off <= PRINCIPAL_POINT_OFF_CENTRE) {
            progress.warn(&format!(
                "{}: the camera puts the principal point at ({pc:.0}, {pr:.0}) px, {:.0} % of the image off the centre of {} ({sw}×{sh}): is it this image's camera?",
                opts.inputs.camera.display(),
                off * 100.0,
                opts.inputs.image.display()
            ));
        }
        // A drone that says how high it flew over its take-off point:
        // a camera placed far from that over the DEM is on another
        // height datum (geoid vs ellipsoid) or mistagged.
        if let (Some(rel), Some(_)) = (camera.relative_altitude, centre) {
            let above = f.centre.z - below;
            if (above - rel).abs() > (0.3 * rel.abs()).max(20.0) {
                progress.warn(&format!(
                    "{}: the camera is {above:.1} m above the DEM below it, but the drone's tags say it flew {rel:.1} m above its take-off point: its absolute height may be on another datum (ellipsoid vs geoid) or wrong; fix it with a camera file (gcm-ortho cameras --camera exif … --out-dir)",
                    opts.inputs.image.display()
                ));
            }
        }
    }
    Ok(())
}

/// Farther off the image's centre than this share of its size, a frame
/// camera's principal point is warned about: real lenses' lie within a few
/// per cent, a film frame within its scan's margins.
const PRINCIPAL_POINT_OFF_CENTRE: f64 = 0.15;

/// Which of an RPC's denominators takes both signs over `places` (lon,
/// lat, height): where one passes through zero the image goes to infinity
/// and folds.
fn denominator_changing_sign(r: &crate::camera::rpc::Rpc, places: impl Iterator<Item = (f64, f64, f64)>) -> Option<&'static str> {
    let (mut line, mut samp) = ([false; 2], [false; 2]);
    for (lon, lat, h) in places {
        let (ld, sd) = r.denominators(lon, lat, h);
        line[usize::from(ld > 0.0)] |= ld != 0.0;
        samp[usize::from(sd > 0.0)] |= sd != 0.0;
    }
    [("LINE_DEN_COEFF", line), ("SAMP_DEN_COEFF", samp)].into_iter().find(|(_, seen)| *seen == [true, true]).map(|(name, _)| name)
}

/// Refuses an RPC whose denominator changes sign within its own validity
/// box (offsets ± scales, 9×9 places at its lowest, middle and highest
/// heights), before anything is located with it: a fold throws the
/// footprint off the scene it cuts, and the error would blame the DEM.
pub fn check_denominators_in_box(r: &crate::camera::RpcCamera, path: &std::path::Path) -> Result<()> {
    let p = &r.rpc;
    let at = |i: usize, off: f64, scale: f64| off + scale * (i as f64 / 4.0 - 1.0);
    let places =
        (0..9 * 9 * 3).map(|n| (at(n / 27, p.long_off, p.long_scale), at(n / 3 % 9, p.lat_off, p.lat_scale), at(n % 3 * 4, p.height_off, p.height_scale)));
    match denominator_changing_sign(p, places) {
        Some(name) => Err(Error::format(
            path,
            format!("RPC: {name} changes sign within the RPC's validity box (offsets ± scales): the image would fold where it passes zero"),
        )),
        None => Ok(()),
    }
}

/// Refuses an RPC whose denominator changes sign over the scene (the output
/// grid, from the DEM's lowest to its highest height, on a 9×9 lattice).
pub fn check_denominators(r: &crate::camera::RpcCamera, grid: &OutputGrid, dem: &Dem, path: &std::path::Path) -> Result<()> {
    let heights: Vec<f64> = match &dem.model {
        HeightModel::Flat(z) => vec![*z],
        HeightModel::Grid(g) => {
            let zs: Vec<f64> = g.samples((g.width * g.height / 10_000).max(1)).into_iter().filter(|v| !g.is_nodata(*v)).map(f64::from).collect();
            let (lo, hi) = zs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &z| (a.min(z), b.max(z)));
            if lo.is_finite() {
                vec![lo, hi]
            } else {
                vec![r.rpc.height_off]
            }
        }
    };
    // Ellipsoidal heights: the geoid moves them by tens of metres at most.
    let places = (0..81)
        .filter_map(|n| {
            let (x, y) = grid.ground(grid.width as f64 * (n / 9) as f64 / 8.0, grid.height as f64 * (n % 9) as f64 / 8.0);
            r.crs.to_lonlat(x, y)
        })
        .flat_map(|(lon, lat)| heights.iter().map(move |&h| (lon, lat, h)));
    match denominator_changing_sign(&r.rpc, places) {
        Some(name) => Err(Error::format(path, format!("RPC: {name} changes sign over the scene: the image would fold where it passes zero"))),
        None => Ok(()),
    }
}
