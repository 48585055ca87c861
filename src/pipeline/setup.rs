//! A run's set-up: the options resolved into what the stages need — the
//! camera, the scan, the DEM, the output grid and its piece, `A`, the GCM's
//! spacing, the band order and the output file's layout: a [`RunPlan`].

use super::budget::MemoryBudget;
use super::context::PixelOptions;
use crate::camera::file::{Camera, Sensor};
use crate::dem::{Dem, HeightModel};
use crate::error::{Error, Result};
use crate::gcm::GcmSpec;
use crate::geodesy::{Crs, GroundCrs};
use crate::geom::{Gsd, OutputGrid};
use crate::io::source::SourceImage;
use crate::io::tiff_out::{Chunking, GeoTags, OutputSpec};
use crate::options::{BandOrder, BigTiff, DemSource, Nodata, Occlusion, RectifyOptions};
use crate::overview::Pyramid;
use crate::progress::Progress;
use crate::transform::footprint::{auto_grid, mean_gsd};
use crate::transform::{Approx, Trend};

/// Output tiles a run holds at a time, at most (chunks of one tile being
/// made, queued, encoded, their overview quarters, and the buffers handed
/// back; of an output of fewer tiles, one more than it has), measured:
/// the peak with 1024² RGB tiles is the same at any budget.
const TILES_HELD: u64 = 10;

/// The memory a run needs for output tiles of `tile_bytes` (their mask
/// included) on an output of `tiles`: those it holds at a time take at
/// most half of it.
pub fn tiles_memory(tile_bytes: u64, tiles: u64) -> u64 {
    2 * TILES_HELD.min(tiles.saturating_add(1)) * tile_bytes
}

/// Outputs beyond this many pixels a side are refused.
const MAX_SIDE: u32 = 1 << 21;

/// Everything a run needs, worked out from its options before any pixel.
pub struct RunPlan {
    pub camera: Camera,
    pub src: SourceImage,
    pub dem: std::sync::Arc<Dem>,
    /// The whole output grid (a piece keeps its geometry).
    pub grid: OutputGrid,
    /// `A` on the whole grid, not transposed.
    pub approx: Approx,
    /// Rows or columns, never auto.
    pub band_order: BandOrder,
    /// The GCM as run (the spacing chosen from the DEM unless given).
    pub gcm: GcmSpec,
    /// The piece made, in tiles: first column, first row, width, height.
    pub piece: [u32; 4],
    pub spec: OutputSpec,
    pub pixels: PixelOptions,
    pub budget: MemoryBudget,
    /// What the ground control points did to the model.
    pub gcp_fit: Option<crate::camera::gcp::GcpFit>,
}

impl RunPlan {
    pub fn new(opts: &RectifyOptions, progress: &dyn Progress) -> Result<RunPlan> {
        Self::with_dem(opts, progress, None)
    }

    /// [`RunPlan::new`] taking `shared` for the DEM where it is the one the
    /// options name, opened in the camera's CRS with the same policies.
    pub fn with_dem(opts: &RectifyOptions, progress: &dyn Progress, shared: super::band_render::SharedDem) -> Result<RunPlan> {
        let mut budget = MemoryBudget::new(opts.memory);
        let like = opts.like.as_deref().map(reference_grid).transpose()?;
        // GCPs refine a frame camera's pose in its own CRS, before anything
        // else uses it (an RPC's bias once its heights' geoid is known, below).
        let (camera, gcps, mut gcp_fit) = crate::scene::camera::of_run(opts, opts.crs.as_ref(), progress)?;
        // The orthophoto's CRS: as given, else the reference grid's, else
        // the camera's.
        let ground = match (&opts.crs, &like) {
            (Some(c), Some((_, l))) if c != l => {
                let path = opts.like.as_deref().unwrap_or(std::path::Path::new("")).display();
                return Err(Error::setting("crs", format!("{c}, but the reference grid {path} is in {l}: give one of the two")));
            }
            (Some(c), _) => c.clone(),
            (None, Some((_, l))) => l.clone(),
            (None, None) => camera.crs.clone(),
        };
        if ground != camera.crs {
            if let Some(d) = ground.unknown_datum().or(camera.crs.unknown_datum()) {
                progress.warn(&format!(
                    "{}: the datum '{d}' has no shift to WGS84 this build knows; it is taken as WGS84 between the camera's CRS ({}) and the orthophoto's ({ground}), which may place the orthophoto up to hundreds of metres off",
                    opts.camera.display(),
                    camera.crs
                ));
            }
        }
        let camera = camera.in_crs(&ground).map_err(|m| Error::setting("crs", m))?;
        let src = SourceImage::open_within(&opts.image, budget.scan_cache() as usize, budget.total())?;
        // What decoding the scan's chunks holds (JPEG 2000) comes off the
        // top; the shares are of what is left.
        let threads = match opts.threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            n => n,
        };
        // Chunks are decoded on as many threads as half the budget holds
        // (the reads wait their turn), and on one at least.
        let one = src.decoding_bytes();
        let mut decoding = 0;
        if one > 0 {
            if 2 * one > budget.total() {
                return Err(Error::setting(
                    "memory",
                    format!(
                        "{}: decoding one of its {}×{} chunks holds about {} MiB, more than half the memory budget: give {}M or more",
                        opts.image.display(),
                        src.info.chunk.0,
                        src.info.chunk.1,
                        one.div_ceil(1 << 20),
                        (4 * one).div_ceil(1 << 20)
                    ),
                ));
            }
            let decoders = (threads as u64).min(budget.total() / 2 / one).max(1);
            src.limit_decoders(decoders as usize);
            decoding = decoders * one;
            budget = MemoryBudget::new(budget.total() - decoding);
        }
        let shared = shared.filter(|(d, ground)| {
            matches!(&opts.dem, DemSource::File(p) if *p == d.path) && d.on_hole == opts.dem_hole && d.on_outside == opts.dem_outside && camera.crs == *ground
        });
        let dem = match shared {
            Some((d, _)) => d,
            None => {
                let mut dem = match &opts.dem {
                    DemSource::File(p) => Dem::open_within(p, &camera.crs, budget.dem())?,
                    DemSource::Height(h) => Dem::flat(*h),
                    DemSource::ModelHeight => match &camera.sensor {
                        Sensor::Rpc(r) => Dem::flat(r.height_hint()),
                        Sensor::Panoramic(p) => Dem::flat(p.height_hint()),
                        Sensor::Frame(_) | Sensor::ReprojectedFrame(_) => {
                            return Err(Error::setting("dem", "a frame camera needs a DEM file or a constant height"))
                        }
                    },
                };
                for w in &dem.warnings {
                    progress.warn(w);
                }
                dem.on_hole = opts.dem_hole;
                dem.on_outside = opts.dem_outside;
                std::sync::Arc::new(dem)
            }
        };
        let mut camera = camera;
        if let Sensor::Rpc(r) = &camera.sensor {
            check_denominators_in_box(r, &opts.camera)?;
        }
        if let Sensor::Rpc(r) = &mut camera.sensor {
            if r.geoid.is_none() {
                r.geoid = geoid_of_heights(&dem, opts.crs.as_ref(), progress)?;
            }
        }
        if let Sensor::Panoramic(p) = &mut camera.sensor {
            if p.geoid.is_none() {
                p.geoid = geoid_of_heights(&dem, opts.crs.as_ref(), progress)?;
            }
        }
        if let (Some((g, points)), Sensor::Rpc(_)) = (&gcps, &camera.sensor) {
            gcp_fit = Some(crate::camera::gcp::refine(&mut camera, points, g.model, g.max_residual, &g.file)?);
        }
        let model = camera.model();
        let (sw, sh) = (src.info.width, src.info.height);
        let z_guess = dem.mean_height().unwrap_or_else(|| camera.height_hint());
        if let Sensor::Rpc(r) = &camera.sensor {
            check_geoid_covers(r, sw, sh, z_guess)?;
        }
        let frame = match &camera.sensor {
            Sensor::Frame(f) => Some((f, Some((f.centre.x, f.centre.y)))),
            Sensor::ReprojectedFrame(r) => Some((&r.inner, r.to_ground(r.inner.centre.x, r.inner.centre.y))),
            Sensor::Rpc(_) | Sensor::Panoramic(_) => None,
        };
        if let Some((f, _)) = frame {
            if let Some(w) = crate::camera::file::narrow_view(&opts.camera, &camera.file, (sw, sh), f.centre.z - z_guess) {
                progress.warn(&w);
            }
        }
        let sized = match &camera.sensor {
            Sensor::Panoramic(p) => Some(("panoramic.size_px", p.bar.size)),
            _ => camera.file.interior.as_ref().and_then(|i| i.image_size_px).map(|s| ("interior.image_size_px", s)),
        };
        if let Some((field, [w, h])) = sized {
            if [w, h] != [sw, sh] {
                return Err(Error::config(&opts.camera, field, format!("the camera is for {w}×{h} images, but {} is {sw}×{sh}", opts.image.display())));
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
            if let Some(g) = src.info.georef.as_ref().filter(|_| !given) {
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
                        "{}: its GeoTIFF origin ({}, {}) in pixels of 1 without a CRS looks like a crop's offset in the scene its RPC was fitted over: if it is, give --rpc-offset {},{} (in a camera file rpc.offset_px), or the orthophoto lands that far off (an RPC already shifted to the crop: --rpc-offset 0,0 says so)",
                        opts.image.display(),
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
                    "{}: the image ({sw}×{sh}) reaches {:.1} times the half-size of the scene its RPC was fitted over: beyond it the RPC is extrapolated; check the crop's offset (--rpc-offset, rpc.offset_px)",
                    opts.image.display(),
                    out
                ));
            }
            // The ground's heights within the range the RPC was fitted over
            // (HEIGHT_OFF ± HEIGHT_SCALE; twice that, and a geoid's
            // undulation, before it is doubted): far beyond, it is
            // extrapolated as fast as beyond the scene.
            if !((z_guess - r.height_off).abs() <= 2.0 * r.height_scale.abs() + 200.0) {
                progress.warn(&format!(
                    "{}: the ground is at {z_guess:.0} m, but its RPC was fitted over heights {:.0} ± {:.0} m: far beyond them the RPC is extrapolated; check the DEM (or --height) and that the RPC is this scene's",
                    opts.image.display(),
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
            f.check_sees_ground(sw, sh, below, &opts.camera)?;
            // A camera made for another image (another size, another scan)
            // puts its principal point far from this one's centre.
            let (pc, pr) = f.interior.mm_to_px(0.0, 0.0);
            let off = (pc / sw as f64 - 0.5).abs().max((pr / sh as f64 - 0.5).abs());
            if !(off <= PRINCIPAL_POINT_OFF_CENTRE) {
                progress.warn(&format!(
                    "{}: the camera puts the principal point at ({pc:.0}, {pr:.0}) px, {:.0} % of the image off the centre of {} ({sw}×{sh}): is it this image's camera?",
                    opts.camera.display(),
                    off * 100.0,
                    opts.image.display()
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
                        opts.image.display()
                    ));
                }
            }
        }
        // Where the scan and the DEM do not meet, the DEM is the file to name.
        let on_dem = |e: Error| match e {
            Error::Geometry(m) => Error::format(&dem.path, m),
            e => e,
        };
        let grid = match like {
            Some((grid, _)) => grid,
            None => {
                let gsd = match opts.gsd {
                    Some(g) => {
                        // A pixel wider than the scan's whole ground makes
                        // an orthophoto of less than a pixel: said as the
                        // GSD's fault, not the DEM's it then fails to meet.
                        if let Ok(own) = mean_gsd(model, &dem, sw, sh, z_guess) {
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
                    None => Gsd::square(mean_gsd(model, &dem, sw, sh, z_guess).map_err(on_dem)?),
                };
                match opts.bounds {
                    Some(b) => OutputGrid::from_bounds(b, gsd, opts.snap)
                        .ok_or_else(|| Error::setting("bounds", format!("{b:?} at GSD {gsd} {}", OutputGrid::no_grid_because(b, gsd))))?,
                    None => {
                        let (grid, fp) = auto_grid(model, &dem, sw, sh, z_guess, gsd).map_err(on_dem)?;
                        fp.check_covered(&opts.image, &dem)?;
                        if let Some(w) = fp.partial_warning(&opts.image, &dem) {
                            progress.warn(&w);
                        }
                        grid
                    }
                }
            }
        };
        let gsd = grid.gsd;
        // Metres given for a CRS in degrees: pixels tens of kilometres wide.
        if let (Some(g), true) = (opts.gsd, camera.crs.is_geographic()) {
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
            return Err(Error::setting(
                "gsd",
                format!("an output of {}×{} pixels is beyond 2M pixels a side; check the GSD and bounds", grid.width, grid.height),
            ));
        }
        // A GSD or bounds typo makes an output of days; refused before any work.
        let pixels = grid.width as u64 * grid.height as u64;
        let limit = opts.max_output_pixels.unwrap_or_else(|| (16 * sw as u64 * sh as u64).max(1 << 28));
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
        let area = grid.bounds();
        if let Sensor::Rpc(r) = &camera.sensor {
            check_denominators(r, &grid, &dem, &opts.camera)?;
        }
        let plane = match opts.trend {
            Trend::Plane => dem.trend_plane(area),
            Trend::Mean => dem.mean_plane(area),
        }
        .ok_or_else(|| {
            // Bounds in degrees under a CRS in metres land near its origin.
            let degrees = opts.bounds.is_some_and(|[x0, y0, x1, y1]| {
                !camera.crs.is_geographic() && [x0, x1].iter().all(|x| x.abs() <= 180.0) && [y0, y1].iter().all(|y| y.abs() <= 90.0)
            });
            // Northing first: the box given with X and Y swapped lies on the DEM.
            let swapped = match (opts.bounds, &dem.model) {
                (Some([x0, y0, x1, y1]), crate::dem::HeightModel::Grid(g)) if dem.to_dem.is_none() => {
                    let [a0, b0, a1, b1] = g.bounds();
                    y0 < a1 && y1 > a0 && x0 < b1 && x1 > b0
                }
                _ => false,
            };
            match (degrees, swapped, opts.bounds.is_some()) {
                (true, _, _) => Error::setting(
                    "bounds",
                    format!(
                        "no height of {} anywhere inside them: they look like degrees; the output's CRS, {}, is in its own units",
                        dem.path.display(),
                        camera.crs
                    ),
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
        })?;
        let approx = Approx::new(model, &grid, plane).ok_or_else(|| Error::Geometry("the terrain plane is not in front of the camera".into()))?;
        let band_order = match opts.band_order {
            BandOrder::Auto => fewer_scan_rows(&approx, &grid, opts.tile),
            order => order,
        };
        let mut gcm = opts.gcm;
        if opts.auto_sparsity {
            gcm.k = auto_sparsity(&dem, &grid, &camera.crs);
            // Fine node spacing on a wide output: the node rows of the bands
            // in flight would outgrow what the plan can give them; the error
            // bound's refinement then does the DEM lines' work instead. Up
            // to the slack a chosen spacing may take, the DEM's spacing is
            // kept: the refinement it spares holds more (a 31,000 px wide
            // film scan on a DEM 13 px apart, at 128M: k = 16 refined a
            // third of its cells, 178 MiB, 11 s; k = 13 none, 127 MiB, 9 s).
            let geometry = opts.geometry_memory.map_or(budget, MemoryBudget::new);
            if geometry.node_rows(gcm.k, opts.tile, grid.width.max(grid.height), 100) > geometry.node_limit() {
                gcm.k = 16;
            }
        }
        // A spacing the user chose so fine that its node rows would pass
        // what the plan can give them (`--sparsity 1` on a wide output):
        // refused, with what it would take.
        let nodes = budget.node_rows(gcm.k, opts.tile, grid.width.max(grid.height), 60);
        if !opts.auto_sparsity && nodes > budget.node_limit() {
            return Err(Error::setting(
                "sparsity",
                format!(
                    "{} keeps about {} MB of GCM nodes in flight at this output's {} px, more than the memory budget allows them: give --memory {}M or more, or a larger sparsity",
                    gcm.k,
                    nodes >> 20,
                    grid.width.max(grid.height),
                    ((nodes * budget.total()).div_ceil(budget.node_limit().max(1)) + decoding).div_ceil(1 << 20)
                ),
            ));
        }

        // The piece of the grid to make, in tiles (everything by default).
        // All geometry stays that of the whole grid, so pieces equal the whole.
        let tile = opts.tile;
        let (tx_all, ty_all) = (grid.width.div_ceil(tile), grid.height.div_ceil(tile));
        let [tc0, tr0, tcw, trh] = crate::geom::cut_window(opts.window.unwrap_or([0, 0, tx_all, ty_all]), (tx_all, ty_all))
            .map_err(|w| Error::setting("window", format!("{w} does not start inside the output's {tx_all}×{ty_all} tiles")))?;
        let (tc1, tr1) = (tc0 + tcw, tr0 + trh);
        let piece_w = (tc1 * tile).min(grid.width) - tc0 * tile;
        let piece_h = (tr1 * tile).min(grid.height) - tr0 * tile;
        // A nodata value, or the mask: then the resampler says which pixels
        // have a value, and the encoder makes the mask's tiles of it.
        // Hidden pixels that keep their values need the mask to say so.
        let asked = if opts.occlusion == Occlusion::Mask && opts.nodata == Nodata::Auto { Nodata::Mask } else { opts.nodata };
        if opts.alpha && src.info.sample == crate::io::source::SampleType::F32 {
            // GDAL takes an alpha band for a mask only of 8 or 16 bits: of
            // floats its 0s would read as values.
            return Err(Error::setting(
                "alpha",
                "a Float32 orthophoto marks pixels without a value with NaN, its nodata (GDAL reads an alpha band as a mask only of 8 or 16 bits): leave out --alpha, or give --nodata mask for an internal mask",
            ));
        }
        let (nodata, mask) = match (opts.alpha, asked.resolved(src.info.sample)) {
            (true, _) => (None, false),
            (false, Nodata::Value(v)) => {
                Nodata::check_value(v, src.info.sample)?;
                (Some(v), false)
            }
            (false, _) => (None, true),
        };
        let bands_in = src.info.bands;
        let bands_out = bands_in + u32::from(opts.alpha);
        let photometric = if src.info.photometric == 2 && bands_in >= 3 { 2 } else { 1 };
        let mut spec = OutputSpec {
            overviews: 0,
            cog: false,
            width: piece_w,
            height: piece_h,
            bands: bands_out,
            sample: src.info.sample,
            chunking: Chunking::Tiles(tile),
            compression: opts.compress,
            level: opts.codec_level()?,
            overview_level: opts.overview_codec_level()?,
            bigtiff: false,
            photometric,
            alpha: opts.alpha || src.info.has_alpha,
            mask,
            geo: Some(GeoTags {
                x0: grid.x0 + (tc0 * tile) as f64 * grid.gsd.x,
                y0: grid.y0 - (tr0 * tile) as f64 * grid.gsd.y,
                gsd: grid.gsd,
                keys: crate::geodesy::geokeys::keys_of(&camera.crs).map_err(|m| Error::setting("crs", m))?,
                nodata,
            }),
        };
        spec.check_codec().map_err(|m| Error::setting("compress", m))?;
        spec.overviews = opts.overviews.levels(piece_w, piece_h, tile);
        spec.cog = opts.cog;
        if opts.cog && opts.overviews == crate::options::Overviews::None && opts.window.is_none() {
            progress.warn("--cog with --overviews none: a Cloud-Optimized GeoTIFF without overviews is read whole to be seen whole (GDAL's validator warns of it); leave out --overviews none");
        }
        // The quarters of unfinished overview tiles: a band of them at each
        // level, within four shares of the budget.
        let band_tiles = if band_order == BandOrder::Columns { trh } else { tcw };
        let held = Pyramid::held_bytes(&spec, band_tiles);
        // The chunks in flight hold a tile each at least: a tile too large
        // for its share passes the budget, whatever else is planned.
        let tile_bytes = tile as u64 * tile as u64 * (spec.bands as u64 * spec.sample.bytes() as u64 + u64::from(spec.mask));
        let tiles_need = tiles_memory(tile_bytes, tcw as u64 * trh as u64);
        // Each check short of memory, with the figure that holds it; the
        // refusal gives the largest, so that the figure given runs.
        let mut short: Vec<(&'static str, String, u64)> = Vec::new();
        if held > 4 * budget.share() {
            short.push((
                "overviews",
                format!(
                    "made while the tiles stream, they hold about {} MB of a {band_tiles}-tile-wide output at a time, more than the memory budget allows them",
                    held >> 20
                ),
                held * 6,
            ));
        }
        if tiles_need > budget.total() {
            short.push((
                "tile",
                format!(
                    "{tile} makes tiles of {} MiB, and a run holds about {} of them at a time, more than half the memory budget",
                    tile_bytes.div_ceil(1 << 20),
                    tiles_need / (2 * tile_bytes)
                ),
                tiles_need,
            ));
        }
        if let Some((setting, what, _)) = short.first() {
            let need = short.iter().map(|s| s.2).max().unwrap_or(0) + decoding;
            let instead = if *setting == "tile" { "a smaller tile" } else { "no overviews" };
            return Err(Error::setting(setting, format!("{what}: give --memory {}M or more, or {instead}", need.div_ceil(1 << 20))));
        }
        spec.bigtiff = match opts.bigtiff {
            BigTiff::Yes => true,
            BigTiff::No => false,
            BigTiff::Auto => spec.needs_bigtiff(),
        };
        let area = camera.model().image_area();
        let footprint = if opts.kernel.area().is_some() { footprint_reach(&approx, &grid) } else { 0 };
        // A point kernel on output pixels several scan pixels wide reads a
        // few of the pixels under each: the texture aliases.
        if let (None, Some(e)) = (opts.kernel.area(), pixel_extent(&approx, grid.width as f64 / 2.0, grid.height as f64 / 2.0, 1.0 / 64.0)) {
            if e >= ALIASING_EXTENT {
                progress.warn(&format!(
                    "output pixels span about {e:.0} scan pixels: --resample {} reads a few of them under each, so fine texture aliases; --resample average (in a manifest, resample = \"average\") takes them all",
                    format!("{:?}", opts.kernel).to_lowercase()
                ));
            }
        }
        let pixels = PixelOptions {
            kernel: opts.kernel,
            tile,
            fill: nodata.unwrap_or(0.0),
            alpha: opts.alpha,
            bands_out,
            area,
            mask,
            occlusion: opts.occlusion,
            footprint,
            holes: src.hole_mark()?,
            nudge: nodata.is_some_and(f64::is_finite),
        };
        Ok(RunPlan { camera, src, dem, grid, approx, band_order, gcm, piece: [tc0, tr0, tcw, trh], spec, pixels, budget, gcp_fit })
    }

    /// Heights within this of the surface seen count as seen (a quarter of
    /// an output pixel, in metres, within 2 cm and 1 m): covers the
    /// positions' error and a surface's curvature within a pixel.
    pub fn occlusion_tolerance(&self) -> f64 {
        let metres = if self.camera.crs.is_geographic() { 111_320.0 } else { 1.0 };
        (0.25 * self.grid.gsd.min() * metres).clamp(0.02, 1.0)
    }

    /// Bands of tile columns: the stages walk the transposed grid.
    pub fn columns(&self) -> bool {
        self.band_order == BandOrder::Columns
    }

    /// The heights the run will look up for its GCM, every one, as the run
    /// walks them (the nodes, and the refined cells' own), short of making
    /// pixels: the miss the DEM's policies make an error, as the run would
    /// fail with it (a batch's dry run: the set-up alone passed jobs whose
    /// DEM had a hole under the footprint).
    pub fn check_node_heights(&self) -> Result<()> {
        use crate::transform::Transform;
        let model = self.camera.model();
        let (t, approx) = match self.columns() {
            true => (Transform::transposed(model, &self.dem, self.grid), self.approx.transposed()),
            false => (Transform::new(model, &self.dem, self.grid), self.approx),
        };
        let t = t.with_scan((self.src.info.width, self.src.info.height));
        let gcm = crate::gcm::Gcm::new(&t, approx, self.gcm);
        // Bands of rows as the run's (its tiles'), one at a time.
        let band = self.spec.chunk().1.max(1);
        for y0 in (0..t.grid.height).step_by(band as usize) {
            if let Some(m) = gcm.prepare(y0, (y0 + band).min(t.grid.height)).miss {
                return Err(super::stages::gcm::dem_miss_error(&self.dem, m));
            }
        }
        Ok(())
    }
}

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
fn check_denominators_in_box(r: &crate::camera::RpcCamera, path: &std::path::Path) -> Result<()> {
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
fn check_denominators(r: &crate::camera::RpcCamera, grid: &OutputGrid, dem: &Dem, path: &std::path::Path) -> Result<()> {
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

/// Farther off the image's centre than this share of its size, a frame
/// camera's principal point is warned about: real lenses' lie within a few
/// per cent, a film frame within its scan's margins.
const PRINCIPAL_POINT_OFF_CENTRE: f64 = 0.15;

/// The geoid an RPC camera needs when the DEM's CRS (else the given
/// `--crs`) says its heights are above one: the grid PROJ uses for that
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
        (None, Some(v)) => (v, "--crs".to_string()),
        (None, None) => {
            // SRTM's tiles hold heights above EGM96 and say nothing of it.
            let hgt = |p: &std::path::Path| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("hgt"));
            if hgt(&dem.path) || Dem::tile_files(&dem.path).iter().any(|t| hgt(t)) {
                progress.warn(&format!(
                    "{}: SRTM .hgt heights are above the EGM96 geoid, an RPC's above the ellipsoid: without --geoid (EGM96's grid, e.g. egm96_15.gtx) they are taken as ellipsoidal, the geoid's undulation (tens of metres) off",
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
            "{whose} says its heights are {vertical}, a height system without a geoid grid this build knows; the RPC's ellipsoidal heights are taken as they are unless --geoid gives the grid"
        ));
        return Ok(None);
    }
    match vertical.find_grid() {
        Some(path) => crate::geodesy::Geoid::read(&path).map(Some),
        None => Err(Error::setting(
            "geoid",
            format!(
                "{whose} says its heights are {vertical}: give that geoid's grid with --geoid (PROJ names it {}; none was found in PROJ_DATA, PROJ_LIB or the proj folders)",
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
fn check_geoid_covers(r: &crate::camera::RpcCamera, w: u32, h: u32, z: f64) -> Result<()> {
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

/// How far, scan pixels, an output pixel's footprint reaches from its
/// centre: half its extent along the scan's axes, by `A` at a 9×9 lattice
/// of the grid, a quarter again for the terrain `A` leaves out (a footprint
/// that reaches further is read on its own).
fn footprint_reach(a: &Approx, g: &OutputGrid) -> u32 {
    let mut most = 0f64;
    for i in 0..=8 {
        for j in 0..=8 {
            if let Some(e) = pixel_extent(a, g.width as f64 * i as f64 / 8.0, g.height as f64 * j as f64 / 8.0, 1.0) {
                most = most.max(e);
            }
        }
    }
    (0.5 * most * 1.25).ceil().min(4096.0) as u32
}

/// The extent in scan pixels, along the scan's wider axis, of the output
/// pixel at (u, v), by `A` over a step of `d` px scaled up (a whole pixel
/// on from the centre of a coarse grid may lie past the horizon).
fn pixel_extent(a: &Approx, u: f64, v: f64, d: f64) -> Option<f64> {
    let (p, pu, pv) = (a.at(u, v)?, a.at(u + d, v)?, a.at(u, v + d)?);
    let extent = ((pu.0 - p.0).abs() + (pv.0 - p.0).abs()).max((pu.1 - p.1).abs() + (pv.1 - p.1).abs()) / d;
    extent.is_finite().then_some(extent)
}

/// The coarsest GSD taken in a CRS in degrees (about 1 km).
const MAX_GSD_DEGREES: f64 = 0.01;

/// Output pixels this many scan pixels across are warned about under a
/// point kernel (bilinear reads 4 of the 9 pixels under one at 3×).
const ALIASING_EXTENT: f64 = 3.0;

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
/// The band order that crosses fewer scan rows a band (rows on a tie): a
/// band of tile rows crosses the scan rows that `A` meets along the grid's
/// width and down a tile; a band of tile columns, down the grid's height and
/// across a tile. Measured with `A`'s rates at the grid's centre.
fn fewer_scan_rows(approx: &Approx, grid: &OutputGrid, tile: u32) -> BandOrder {
    let (u, v) = (grid.width as f64 / 2.0, grid.height as f64 / 2.0);
    let (Some((_, r)), Some((_, ru)), Some((_, rv))) = (approx.at(u, v), approx.at(u + 1.0, v), approx.at(u, v + 1.0)) else {
        return BandOrder::Rows;
    };
    let (along_u, along_v) = ((ru - r).abs(), (rv - r).abs());
    let rows = along_u * grid.width as f64 + along_v * tile as f64;
    let columns = along_v * grid.height as f64 + along_u * tile as f64;
    if columns < rows {
        BandOrder::Columns
    } else {
        BandOrder::Rows
    }
}

/// The default node spacing: 16 output pixels, or the DEM's posting in
/// output pixels where that is finer, but not under 4: the DEM's post lines
/// are then node lines too, so no cell holds a bend of the DEM and the
/// corrections are smooth between nodes (Chibunichev and Sonyushkin likewise
/// ask for grid nodes no sparser than the DEM). A DEM posted finer still (a
/// drone's DSM) is left to the refinement under the error bound.
fn auto_sparsity(dem: &Dem, grid: &OutputGrid, ground: &Crs) -> u32 {
    let HeightModel::Grid(g) = &dem.model else { return 16 };
    let metres = |crs: Option<&Crs>, v: f64, lat_scale: f64| {
        if crs.is_some_and(|c| c.is_geographic()) {
            v * 111_320.0 * lat_scale
        } else {
            v
        }
    };
    let lat_mid = {
        let (x, y) = grid.ground(grid.width as f64 / 2.0, grid.height as f64 / 2.0);
        match GroundCrs::new(ground).ok().and_then(|c| c.to_lonlat(x, y)) {
            Some((_, lat)) => lat,
            None => 0.0,
        }
    };
    let cos = lat_mid.to_radians().cos();
    let post = metres(g.crs.as_ref(), g.transform[1].abs(), cos).min(metres(g.crs.as_ref(), g.transform[5].abs(), 1.0));
    let gsd = metres(Some(ground), grid.gsd.max(), 1.0);
    if !(post > 0.0 && gsd > 0.0) {
        return 16;
    }
    let posts = post / gsd;
    if posts < 4.0 {
        return 16;
    }
    (posts.floor() as u32).clamp(4, 16)
}
