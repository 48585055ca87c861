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
use crate::geom::OutputGrid;
use crate::io::source::{SourceImage, SourceInfo};
use crate::io::tiff_out::{Chunking, GeoTags, OutputSpec};
use crate::options::{BandOrder, BigTiff, Nodata, Occlusion, RectifyOptions};
use crate::overview::Pyramid;
use crate::progress::Progress;
use crate::scene::{checks, grid, terrain};
use crate::transform::Approx;

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
        let mut budget = MemoryBudget::new(opts.resources.memory);
        let like = opts.grid.like.as_deref().map(grid::reference_grid).transpose()?;
        // GCPs refine a frame camera's pose in its own CRS, before anything
        // else uses it (an RPC's bias once its heights' geoid is known, below).
        let (camera, gcps, mut gcp_fit) = crate::scene::camera::of_run(opts, opts.grid.crs.as_ref(), progress)?;
        let ground = grid::output_crs(opts, like.as_ref().map(|(_, crs)| crs), &camera, progress)?;
        let camera = camera.in_crs(&ground).map_err(|m| Error::setting("crs", m))?;
        let src = SourceImage::open_within(&opts.inputs.image, budget.scan_cache() as usize, budget.total())?;
        let decoding = reserve_decoders(opts, &src, &mut budget)?;
        let shared = shared.filter(|(d, crs)| terrain::is_dem_of(opts, d, crs, &camera)).map(|(d, _)| d);
        let dem = terrain::dem_of_run(opts, &camera, shared, budget.dem(), progress)?;
        let mut camera = camera;
        if let Sensor::Rpc(r) = &camera.sensor {
            checks::check_denominators_in_box(r, &opts.inputs.camera)?;
        }
        terrain::geoid_for_camera(&mut camera, &dem, opts.grid.crs.as_ref(), progress)?;
        if let (Some((g, points)), Sensor::Rpc(_)) = (&gcps, &camera.sensor) {
            gcp_fit = Some(crate::camera::gcp::refine(&mut camera, points, g.model, g.max_residual, &g.file)?);
        }
        let model = camera.model();
        let (sw, sh) = (src.info.width, src.info.height);
        let z_guess = dem.mean_height().unwrap_or_else(|| camera.height_hint());
        checks::camera_meets_scan(opts, &camera, &src.info, &dem, z_guess, progress)?;
        let grid = grid::output_grid(opts, like.map(|(g, _)| g), &camera, &dem, (sw, sh), z_guess, progress)?;
        if let Sensor::Rpc(r) = &camera.sensor {
            checks::check_denominators(r, &grid, &dem, &opts.inputs.camera)?;
        }
        let plane = grid::terrain_plane(opts, &camera.crs, &dem, &grid)?;
        let approx = Approx::new(model, &grid, plane).ok_or_else(|| Error::Geometry("the terrain plane is not in front of the camera".into()))?;
        let band_order = match opts.resources.band_order {
            BandOrder::Auto => fewer_scan_rows(&approx, &grid, opts.file.tile),
            order => order,
        };
        let gcm = node_spacing(opts, &dem, &grid, &camera.crs, budget, decoding)?;

        // The piece of the grid to make, in tiles (everything by default).
        // All geometry stays that of the whole grid, so pieces equal the whole.
        let tile = opts.file.tile;
        let (tx_all, ty_all) = (grid.width.div_ceil(tile), grid.height.div_ceil(tile));
        let [tc0, tr0, tcw, trh] = crate::geom::cut_window(opts.grid.window.unwrap_or([0, 0, tx_all, ty_all]), (tx_all, ty_all))
            .map_err(|w| Error::setting("window", format!("{w} does not start inside the output's {tx_all}×{ty_all} tiles")))?;
        let mut spec = output_spec(opts, &src.info, &grid, &camera.crs, [tc0, tr0, tcw, trh], progress)?;
        let band_tiles = if band_order == BandOrder::Columns { trh } else { tcw };
        check_output_memory(&spec, tile, band_tiles, tcw as u64 * trh as u64, budget, decoding)?;
        spec.bigtiff = match opts.file.bigtiff {
            BigTiff::Yes => true,
            BigTiff::No => false,
            BigTiff::Auto => spec.needs_bigtiff(),
        };
        let pixels = pixel_options(opts, &src, &camera, &approx, &grid, &spec, progress)?;
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

/// The output file's layout for the piece `[column, row, width, height]`
/// (in tiles) of `grid`: bands, sample, tiles, codec, overviews, and a
/// nodata value or the internal mask (hidden pixels that keep their values
/// need the mask to say so).
fn output_spec(
    opts: &RectifyOptions,
    info: &SourceInfo,
    grid: &OutputGrid,
    crs: &Crs,
    [tc0, tr0, tcw, trh]: [u32; 4],
    progress: &dyn Progress,
) -> Result<OutputSpec> {
    let tile = opts.file.tile;
    let (tc1, tr1) = (tc0 + tcw, tr0 + trh);
    let piece_w = (tc1 * tile).min(grid.width) - tc0 * tile;
    let piece_h = (tr1 * tile).min(grid.height) - tr0 * tile;
    // A nodata value, or the mask: then the resampler says which pixels
    // have a value, and the encoder makes the mask's tiles of it.
    // Hidden pixels that keep their values need the mask to say so.
    let asked = if opts.pixels.occlusion == Occlusion::Mask && opts.pixels.nodata == Nodata::Auto { Nodata::Mask } else { opts.pixels.nodata };
    if opts.pixels.alpha && info.sample == crate::io::source::SampleType::F32 {
        // GDAL takes an alpha band for a mask only of 8 or 16 bits: of
        // floats its 0s would read as values.
        return Err(Error::setting(
            "alpha",
            "a Float32 orthophoto marks pixels without a value with NaN, its nodata (GDAL reads an alpha band as a mask only of 8 or 16 bits): leave out ‹alpha›, or give ‹nodata› mask for an internal mask",
        ));
    }
    let (nodata, mask) = match (opts.pixels.alpha, asked.resolved(info.sample)) {
        (true, _) => (None, false),
        (false, Nodata::Value(v)) => {
            Nodata::check_value(v, info.sample)?;
            (Some(v), false)
        }
        (false, _) => (None, true),
    };
    let bands_in = info.bands;
    let bands_out = bands_in + u32::from(opts.pixels.alpha);
    let photometric = if info.photometric == 2 && bands_in >= 3 { 2 } else { 1 };
    let mut spec = OutputSpec {
        overviews: 0,
        cog: false,
        width: piece_w,
        height: piece_h,
        bands: bands_out,
        sample: info.sample,
        chunking: Chunking::Tiles(tile),
        compression: opts.file.compress,
        level: opts.codec_level()?,
        overview_level: opts.overview_codec_level()?,
        bigtiff: false,
        photometric,
        alpha: opts.pixels.alpha || info.has_alpha,
        mask,
        geo: Some(GeoTags {
            x0: grid.x0 + (tc0 * tile) as f64 * grid.gsd.x,
            y0: grid.y0 - (tr0 * tile) as f64 * grid.gsd.y,
            gsd: grid.gsd,
            keys: crate::geodesy::geokeys::keys_of(crs).map_err(|m| Error::setting("crs", m))?,
            nodata,
        }),
    };
    spec.check_codec().map_err(|m| Error::setting("compress", m))?;
    spec.overviews = opts.file.overviews.levels(piece_w, piece_h, tile);
    spec.cog = opts.file.cog;
    if opts.file.cog && opts.file.overviews == crate::options::Overviews::None && opts.grid.window.is_none() {
        progress.warn("‹cog› with ‹overviews› none: a Cloud-Optimized GeoTIFF without overviews is read whole to be seen whole (GDAL's validator warns of it); leave out ‹overviews› none");
    }
    Ok(spec)
}

/// Refuses an output (of `tiles` tiles `tile` px a side, in bands
/// `band_tiles` wide) whose tiles in flight, or overview quarters, pass the
/// memory budget: said by the setting at fault with the figure that holds
/// every check (`decoding`: what the scan's decoders took off the top).
fn check_output_memory(spec: &OutputSpec, tile: u32, band_tiles: u32, tiles: u64, budget: MemoryBudget, decoding: u64) -> Result<()> {
    // The quarters of unfinished overview tiles: a band of them at each
    // level, within four shares of the budget.
    let held = Pyramid::held_bytes(spec, band_tiles);
    // The chunks in flight hold a tile each at least: a tile too large
    // for its share passes the budget, whatever else is planned.
    let tile_bytes = tile as u64 * tile as u64 * (spec.bands as u64 * spec.sample.bytes() as u64 + u64::from(spec.mask));
    let tiles_need = tiles_memory(tile_bytes, tiles);
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
        return Err(Error::setting(setting, format!("{what}: give ‹memory› {}M or more, or {instead}", need.div_ceil(1 << 20))));
    }
    Ok(())
}

/// What the per-pixel code sees: the kernel, the fill, the mask, the
/// scan's image area and holes, how far a footprint reaches; a point
/// kernel on output pixels several scan pixels wide is warned of.
fn pixel_options(
    opts: &RectifyOptions,
    src: &SourceImage,
    camera: &Camera,
    approx: &Approx,
    grid: &OutputGrid,
    spec: &OutputSpec,
    progress: &dyn Progress,
) -> Result<PixelOptions> {
    let nodata = spec.geo.as_ref().and_then(|g| g.nodata);
    let area = camera.model().image_area();
    let footprint = if opts.pixels.kernel.area().is_some() { footprint_reach(approx, grid) } else { 0 };
    // A point kernel on output pixels several scan pixels wide reads a
    // few of the pixels under each: the texture aliases.
    if let (None, Some(e)) = (opts.pixels.kernel.area(), pixel_extent(approx, grid.width as f64 / 2.0, grid.height as f64 / 2.0, 1.0 / 64.0)) {
        if e >= ALIASING_EXTENT {
            progress.warn(&format!(
                "output pixels span about {e:.0} scan pixels: ‹resample› {} reads a few of them under each, so fine texture aliases; ‹resample› average takes them all",
                format!("{:?}", opts.pixels.kernel).to_lowercase()
            ));
        }
    }
    let pixels = PixelOptions {
        kernel: opts.pixels.kernel,
        tile: opts.file.tile,
        fill: nodata.unwrap_or(0.0),
        bands_out: spec.bands,
        area,
        mask: spec.mask,
        occlusion: opts.pixels.occlusion,
        footprint,
        holes: src.hole_mark()?,
        nudge: nodata.is_some_and(f64::is_finite),
    };
    Ok(pixels)
}

/// Reserves what decoding the scan's chunks holds (JPEG 2000) off the top
/// of `budget` (the shares are then of what is left): as many decoders as
/// threads, within half the budget, one at least. What they hold, bytes.
fn reserve_decoders(opts: &RectifyOptions, src: &SourceImage, budget: &mut MemoryBudget) -> Result<u64> {
    let threads = match opts.resources.threads {
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
                    opts.inputs.image.display(),
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
        *budget = MemoryBudget::new(budget.total() - decoding);
    }
    Ok(decoding)
}

/// The GCM's node spacing: as given, or the default (the DEM's posting,
/// within the memory the node rows in flight may take); a spacing given so
/// fine that its node rows pass the budget is refused, with what it takes.
fn node_spacing(opts: &RectifyOptions, dem: &Dem, grid: &OutputGrid, ground: &Crs, budget: MemoryBudget, decoding: u64) -> Result<GcmSpec> {
    let mut gcm = opts.geometry.gcm;
    if opts.geometry.auto_sparsity {
        gcm.k = auto_sparsity(dem, grid, ground);
        // Fine node spacing on a wide output: the node rows of the bands
        // in flight would outgrow what the plan can give them; the error
        // bound's refinement then does the DEM lines' work instead. Up
        // to the slack a chosen spacing may take, the DEM's spacing is
        // kept: the refinement it spares holds more (a 31,000 px wide
        // film scan on a DEM 13 px apart, at 128M: k = 16 refined a
        // third of its cells, 178 MiB, 11 s; k = 13 none, 127 MiB, 9 s).
        let geometry = opts.resources.geometry_memory.map_or(budget, MemoryBudget::new);
        if geometry.node_rows(gcm.k, opts.file.tile, grid.width.max(grid.height), 100) > geometry.node_limit() {
            gcm.k = 16;
        }
    }
    // A spacing the user chose so fine that its node rows would pass
    // what the plan can give them (`--sparsity 1` on a wide output):
    // refused, with what it would take.
    let nodes = budget.node_rows(gcm.k, opts.file.tile, grid.width.max(grid.height), 60);
    if !opts.geometry.auto_sparsity && nodes > budget.node_limit() {
        return Err(Error::setting(
            "sparsity",
            format!(
                "{} keeps about {} MB of GCM nodes in flight at this output's {} px, more than the memory budget allows them: give ‹memory› {}M or more, or a larger sparsity",
                gcm.k,
                nodes >> 20,
                grid.width.max(grid.height),
                ((nodes * budget.total()).div_ceil(budget.node_limit().max(1)) + decoding).div_ceil(1 << 20)
            ),
        ));
    }
    Ok(gcm)
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

/// Output pixels this many scan pixels across are warned about under a
/// point kernel (bilinear reads 4 of the 9 pixels under one at 3×).
const ALIASING_EXTENT: f64 = 3.0;

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
