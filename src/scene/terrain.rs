//! A run's terrain: the DEM (a file, a constant height, the model's own
//! height) with its policies for holes and for ground off it, and the
//! geoid its heights are above where the camera (an RPC, a panoramic
//! film) locates ellipsoidal heights.

use crate::camera::file::{Camera, Sensor};
use crate::dem::{Dem, HeightModel};
use crate::error::{Error, Result};
use crate::geodesy::Crs;
use crate::options::{DemSource, RectifyOptions};
use crate::progress::Progress;
use std::sync::Arc;

/// The DEM the options name, in the camera's CRS, read within `max_bytes`
/// (its doubts said): `shared` where a caller holds that one already.
pub fn dem_of_run(opts: &RectifyOptions, camera: &Camera, shared: Option<Arc<Dem>>, max_bytes: u64, progress: &dyn Progress) -> Result<Arc<Dem>> {
    if let Some(d) = shared {
        return Ok(d);
    }
    let mut dem = match &opts.inputs.dem {
        DemSource::File(p) => Dem::open_within(p, &camera.crs, max_bytes)?,
        DemSource::Height(h) => Dem::flat(*h),
        DemSource::ModelHeight => match &camera.sensor {
            Sensor::Rpc(r) => Dem::flat(r.height_hint()),
            Sensor::Panoramic(p) => Dem::flat(p.height_hint()),
            Sensor::Frame(_) | Sensor::ReprojectedFrame(_) => return Err(Error::setting("dem", "a frame camera needs a DEM file or a constant height")),
        },
    };
    for w in &dem.warnings {
        progress.warn(w);
    }
    dem.on_hole = opts.inputs.dem_hole;
    dem.on_outside = opts.inputs.dem_outside;
    Ok(Arc::new(dem))
}

/// Whether `dem`, opened in `crs`, is the one `opts` name, with their
/// policies: a caller's DEM taken instead of opening it again.
pub fn is_dem_of(opts: &RectifyOptions, dem: &Dem, crs: &Crs, camera: &Camera) -> bool {
    matches!(&opts.inputs.dem, DemSource::File(p) if *p == dem.path) && dem.on_hole == opts.inputs.dem_hole && dem.on_outside == opts.inputs.dem_outside && camera.crs == *crs
}

/// Gives the camera the geoid the DEM's heights are above, where it
/// locates ellipsoidal heights and has none of its own.
pub fn geoid_for_camera(camera: &mut Camera, dem: &Dem, crs: Option<&Crs>, progress: &dyn Progress) -> Result<()> {
    if let Sensor::Rpc(r) = &mut camera.sensor {
        if r.geoid.is_none() {
            r.geoid = geoid_of_heights(dem, crs, progress)?;
        }
    }
    if let Sensor::Panoramic(p) = &mut camera.sensor {
        if p.geoid.is_none() {
            p.geoid = geoid_of_heights(dem, crs, progress)?;
        }
    }
    Ok(())
}

/// The geoid an RPC camera needs when the DEM's CRS (else the given
/// `crs`) says its heights are above one: the grid PROJ uses for that
/// height, found where PROJ keeps its grids. Named but not found is an
/// error (the heights would be off by the undulation, tens of metres); a
/// geoid height without a known grid, a warning.
fn geoid_of_heights(dem: &Dem, crs: Option<&Crs>, progress: &dyn Progress) -> Result<Option<crate::geodesy::Geoid>> {
    let from_dem = match &dem.model {
        HeightModel::Grid(g) => g.crs.as_ref().and_then(|c| c.vertical()),
        HeightModel::Flat(_) => None,
    };
    let (vertical, whose) = match (from_dem, crs.and_then(|c| c.vertical())) {
        (Some(v), _) => (v, format!("the DEM {}", dem.path.display())),
        (None, Some(v)) => (v, "‹crs›".to_string()),
        (None, None) => {
            // SRTM's tiles hold heights above EGM96 and say nothing of it.
            let hgt = |p: &std::path::Path| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("hgt"));
            if hgt(&dem.path) || Dem::tile_files(&dem.path).iter().any(|t| hgt(t)) {
                progress.warn(&format!(
                    "{}: SRTM .hgt heights are above the EGM96 geoid, an RPC's above the ellipsoid: without ‹geoid› (EGM96's grid, e.g. egm96_15.gtx) they are taken as ellipsoidal, the geoid's undulation (tens of metres) off",
                    dem.path.display()
                ));
            }
            return Ok(None);
        }
    };
    if vertical.is_ellipsoidal() {
        return Ok(None);
    }
    if vertical.grids.is_empty() {
        progress.warn(&format!(
            "{whose} says its heights are {vertical}, a height system without a geoid grid this build knows; the RPC's ellipsoidal heights are taken as they are unless ‹geoid› gives the grid"
        ));
        return Ok(None);
    }
    match vertical.find_grid() {
        Some(path) => crate::geodesy::Geoid::read(&path).map(Some),
        None => Err(Error::setting(
            "geoid",
            format!(
                "{whose} says its heights are {vertical}: give that geoid's grid with ‹geoid› (PROJ names it {}; none was found in PROJ_DATA, PROJ_LIB or the proj folders)",
                vertical.grids.join(" or ")
            ),
        )),
    }
}

/// Refuses a geoid grid that leaves part of the image's ground uncovered
/// (it would be that much of the scene as nodata): the image's corners,
/// edges' middles and centre located at height `z` without the geoid (tens
/// of metres of height move them by far less than a grid cell); names the
/// grid, what it covers and what the image spans.
pub fn check_geoid_covers(r: &crate::camera::RpcCamera, w: u32, h: u32, z: f64) -> Result<()> {
    let Some(geoid) = &r.geoid else { return Ok(()) };
    let plain = crate::camera::RpcCamera::new(r.rpc.clone(), crate::geodesy::GroundCrs::from_epsg(4326).map_err(Error::Geometry)?, None);
    let (mut span, mut uncovered) = ([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], false);
    for (fc, fr) in [(0.0, 0.0), (0.5, 0.0), (1.0, 0.0), (0.0, 0.5), (0.5, 0.5), (1.0, 0.5), (0.0, 1.0), (0.5, 1.0), (1.0, 1.0)] {
        let Some((lon, lat)) = crate::camera::locate(&plain, fc * w as f64, fr * h as f64, z, 0.01) else { continue };
        span = [span[0].min(lon), span[1].min(lat), span[2].max(lon), span[3].max(lat)];
        uncovered |= geoid.undulation(lon, lat).is_none();
    }
    if uncovered {
        let e = geoid.extent();
        return Err(Error::format(
            &geoid.path,
            format!(
                "the geoid grid covers longitudes {:.3}..{:.3}, latitudes {:.3}..{:.3}; the image spans {:.3}..{:.3}, {:.3}..{:.3}",
                e[0], e[2], e[1], e[3], span[0], span[2], span[1], span[3]
            ),
        ));
    }
    Ok(())
}
