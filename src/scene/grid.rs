//! A run's output grid: its CRS, GSD and bounds (given, taken from a
//! reference raster, or the scan's own footprint over the DEM), the limits
//! that refuse a typo's output of days, and the terrain plane `A` is fitted
//! to.

use crate::camera::file::Camera;
use crate::dem::Dem;
use crate::error::{Error, Result};
use crate::geodesy::Crs;
use crate::geom::{Gsd, OutputGrid, Plane};
use crate::io::source::SourceImage;
use crate::options::RectifyOptions;
use crate::progress::Progress;
use crate::transform::footprint::{auto_grid, centre_gsd, footprint_gsd};
use crate::transform::Trend;

/// The orthophoto's CRS: as given, else the reference grid's (`like`),
/// else the camera's; a datum without a shift to WGS84 warned of.
pub fn output_crs(opts: &RectifyOptions, like: Option<&Crs>, camera: &Camera, progress: &dyn Progress) -> Result<Crs> {
    let ground = match (&opts.grid.crs, like) {
        (Some(c), Some(l)) if c != l => {
            let path = opts.grid.like.as_deref().unwrap_or(std::path::Path::new("")).display();
            return Err(Error::setting("crs", format!("{c}, but the reference grid {path} is in {l}: give one of the two")));
        }
        (Some(c), _) => c.clone(),
        (None, Some(l)) => l.clone(),
        (None, None) => camera.crs.clone(),
    };
    if ground != camera.crs {
        if let Some(d) = ground.unknown_datum().or(camera.crs.unknown_datum()) {
            progress.warn(&format!(
                "{}: the datum '{d}' has no shift to WGS84 this build knows; it is taken as WGS84 between the camera's CRS ({}) and the orthophoto's ({ground}), which may place the orthophoto up to hundreds of metres off",
                opts.inputs.camera.display(),
                camera.crs
            ));
        }
    }
    Ok(ground)
}

/// The output grid: the reference grid where given, else the GSD (given,
/// or the scan's own over the DEM) on the bounds (given, or the scan's
/// footprint); refused past the limits.
pub fn output_grid(
    opts: &RectifyOptions,
    like: Option<OutputGrid>,
    camera: &Camera,
    dem: &Dem,
    (sw, sh): (u32, u32),
    z_guess: f64,
    progress: &dyn Progress,
) -> Result<OutputGrid> {
    let model = camera.model();
    // Where the scan and the DEM do not meet, the DEM is the file to name.
    let on_dem = |e: Error| match e {
        Error::Geometry(m) => Error::format(&dem.path, m),
        e => e,
    };
    let grid = match like {
        Some(grid) => grid,
        None => {
            let gsd = match opts.grid.gsd {
                Some(g) => {
                    // A pixel wider than the scan's whole ground makes
                    // an orthophoto of less than a pixel: said as the
                    // GSD's fault, not the DEM's it then fails to meet.
                    if let Ok(own) = centre_gsd(model, dem, sw, sh, z_guess) {
                        let across = own * f64::from(sw.max(sh));
                        // (Metres given in a CRS of degrees are said so below.)
                        let metres_in_degrees = camera.crs.is_geographic() && g.max() > MAX_GSD_DEGREES;
                        if g.max() > across && !metres_in_degrees {
                            return Err(Error::setting(
                                "gsd",
                                format!("{g} makes the orthophoto less than one pixel a side: the scan spans about {across:.1} on the ground (its own GSD {own:.4})"),
                            ));
                        }
                    }
                    g
                }
                None => Gsd::square(footprint_gsd(model, dem, sw, sh, z_guess).map_err(on_dem)?),
            };
            match opts.grid.bounds {
                Some(b) => OutputGrid::from_bounds(b, gsd, opts.grid.snap)
                    .ok_or_else(|| Error::setting("bounds", format!("{b:?} at GSD {gsd} {}", OutputGrid::no_grid_because(b, gsd))))?,
                None => {
                    let (grid, fp) = auto_grid(model, dem, sw, sh, z_guess, gsd).map_err(on_dem)?;
                    fp.check_covered(&opts.inputs.image, dem)?;
                    if let Some(w) = fp.partial_warning(&opts.inputs.image, dem) {
                        progress.warn(&w);
                    }
                    grid
                }
            }
        }
    };
    let gsd = grid.gsd;
    // Metres given for a CRS in degrees: pixels tens of kilometres wide.
    if let (Some(g), true) = (opts.grid.gsd, camera.crs.is_geographic()) {
        if g.max() > MAX_GSD_DEGREES {
            return Err(Error::setting(
                "gsd",
                format!(
                    "{g} is in degrees in {} (pixels of about {:.0} km); give the GSD in degrees (about {:.1e} for 0.5 m)",
                    camera.crs,
                    g.max() * 111.32,
                    0.5 / 111_320.0
                ),
            ));
        }
    }
    if grid.width > MAX_SIDE || grid.height > MAX_SIDE {
        return Err(Error::setting("gsd", format!("an output of {}×{} pixels is beyond 2M pixels a side; check the GSD and bounds", grid.width, grid.height)));
    }
    // A GSD or bounds typo makes an output of days; refused before any work.
    let pixels = grid.width as u64 * grid.height as u64;
    let limit = opts.grid.max_output_pixels.unwrap_or_else(|| (16 * sw as u64 * sh as u64).max(1 << 28));
    if pixels > limit {
        return Err(Error::setting(
            "max_output_pixels",
            format!(
                "an output of {}×{} pixels ({:.2} Gpx at GSD {gsd}) is more than the {:.2} Gpx allowed; check the GSD and bounds, or raise this limit",
                grid.width,
                grid.height,
                pixels as f64 / 1e9,
                limit as f64 / 1e9
            ),
        ));
    }
    Ok(grid)
}

/// The plane `A` is fitted to: the DEM's trend (or mean) over the grid;
/// none there is said as the bounds' fault where they were given.
pub fn terrain_plane(opts: &RectifyOptions, crs: &Crs, dem: &Dem, grid: &OutputGrid) -> Result<Plane> {
    match opts.geometry.trend {
        Trend::Plane => dem.trend_plane(grid.bounds()),
        Trend::Mean => dem.mean_plane(grid.bounds()),
    }
    .ok_or_else(|| {
        // Bounds in degrees under a CRS in metres land near its origin.
        let degrees = opts
            .grid.bounds
            .is_some_and(|[x0, y0, x1, y1]| !crs.is_geographic() && [x0, x1].iter().all(|x| x.abs() <= 180.0) && [y0, y1].iter().all(|y| y.abs() <= 90.0));
        // Northing first: the box given with X and Y swapped lies on the DEM.
        let swapped = match (opts.grid.bounds, &dem.model) {
            (Some([x0, y0, x1, y1]), crate::dem::HeightModel::Grid(g)) if dem.to_dem.is_none() => {
                let [a0, b0, a1, b1] = g.bounds();
                y0 < a1 && y1 > a0 && x0 < b1 && x1 > b0
            }
            _ => false,
        };
        match (degrees, swapped, opts.grid.bounds.is_some()) {
            (true, _, _) => Error::setting(
                "bounds",
                format!("no height of {} anywhere inside them: they look like degrees; the output's CRS, {}, is in its own units", dem.path.display(), crs),
            ),
            (_, true, _) => Error::setting(
                "bounds",
                format!(
                    "no height of {} anywhere inside them, but there is with X and Y swapped: they are xmin,ymin,xmax,ymax (easting first)",
                    dem.path.display()
                ),
            ),
            (_, _, true) => Error::setting("bounds", format!("no height of {} anywhere inside them", dem.path.display())),
            _ => Error::format(&dem.path, "no height anywhere inside the output area"),
        }
    })
}

/// The grid of a reference raster (north-up) and its CRS.
pub fn reference_grid(path: &std::path::Path) -> Result<(OutputGrid, Crs)> {
    let (width, height, t, crs) = if crate::dem::is_vrt(path) {
        let (w, h, t, crs) = crate::dem::vrt_grid(path)?;
        let side = |n: usize| u32::try_from(n).map_err(|_| Error::format(path, format!("VRT: {n} pixels a side")));
        (side(w)?, side(h)?, t, crs)
    } else {
        let info = SourceImage::info_of(path)?;
        let g = info.georef.ok_or_else(|| Error::format(path, "has no georeferencing to take the grid from"))?;
        let crs = crate::geodesy::geokeys::crs_of(&g.keys).map_err(|m| Error::format(path, format!("its GeoTIFF keys: {m}")))?;
        (info.width, info.height, g.transform, crs)
    };
    let crs = crs.ok_or_else(|| Error::format(path, "names no CRS to take the grid from"))?;
    if t[2] != 0.0 || t[4] != 0.0 {
        return Err(Error::unsupported(path, "a turned grid (the orthophoto is north-up)"));
    }
    if !(t[1] > 0.0 && t[5] < 0.0 && t[1].is_finite() && t[5].is_finite()) {
        return Err(Error::unsupported(path, format!("pixels of {} × {} (only north-up grids, rows going south)", t[1], -t[5])));
    }
    // Square within a writer's rounding stays square.
    let gsd = if (t[1] + t[5]).abs() <= 1e-9 * t[1] { Gsd::square(t[1]) } else { Gsd { x: t[1], y: -t[5] } };
    Ok((OutputGrid { x0: t[0], y0: t[3], gsd, width, height }, crs))
}

/// The coarsest GSD taken in a CRS in degrees (about 1 km).
const MAX_GSD_DEGREES: f64 = 0.01;

/// Outputs beyond this many pixels a side are refused.
const MAX_SIDE: u32 = 1 << 21;
