//! `rectify`: the run's set-up (camera, DEM, output grid, `A` and the GCM,
//! band order, the output file) and its report; the steps themselves are in
//! `steps.rs`, run by `threaded.rs` or (one thread) `sequential.rs`.

use super::config::{BandOrder, BigTiff, DemSource, RectifyConfig};
use super::report::{peak_rss_mib, Report, ScanInfo, StageTimes};
use super::sequential::run_sequential;
use super::steps::Run;
use super::threaded::run_threaded;
use crate::accuracy;
use crate::camera::file::Camera;
use crate::dem::Dem;
use crate::error::{Error, Result};
use crate::gcm::Gcm;
use crate::geom::OutputGrid;
use crate::io::source::SourceImage;
use crate::io::tiff_out::{reserve, verify, Chunking, Compression, GeoTags, OutputSpec, PendingFile};
use crate::transform::footprint::{auto_grid, mean_gsd};
use crate::transform::{Approx, Transform, Trend};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

/// Orthorectifies `cfg.image` into `cfg.output`. `cancel` may be set from
/// another thread (a signal handler) to stop the run; the output is then
/// not created.
pub fn rectify(cfg: &RectifyConfig, cancel: &AtomicBool) -> Result<Report> {
    let wall = Instant::now();
    if cfg.tile == 0 || cfg.tile % 16 != 0 || cfg.tile > 4096 {
        return Err(Error::Usage(format!("--tile {} must be a multiple of 16 up to 4096", cfg.tile)));
    }
    if cfg.gcm.k == 0 {
        return Err(Error::Usage("--sparsity must be at least 1".into()));
    }
    if cfg.memory < 16 << 20 {
        return Err(Error::Usage("--memory must be at least 16M".into()));
    }
    // The output folder must take a file before any work starts.
    let pending = PendingFile::create(&cfg.output)?;

    let camera = match &cfg.camera_file {
        Some(f) => f.clone().build(&cfg.camera)?,
        None => Camera::read(&cfg.camera)?,
    };
    let model = camera.model();
    let src = SourceImage::open(&cfg.image, (cfg.memory / 12) as usize)?;
    let mut dem = match &cfg.dem {
        // The DEM's share of the budget (see the memory plan below).
        DemSource::File(p) => Dem::open_within(p, camera.crs.epsg, cfg.memory / 8)?,
        DemSource::Height(h) => Dem::flat(*h),
        DemSource::ModelHeight => match &camera.sensor {
            crate::camera::file::Sensor::Rpc(r) => Dem::flat(r.height_hint()),
            crate::camera::file::Sensor::Frame(_) => return Err(Error::Usage("give --dem FILE or --height METRES".into())),
        },
    };
    dem.on_hole = cfg.dem_hole;
    dem.on_outside = cfg.dem_outside;
    let (sw, sh) = (src.info.width, src.info.height);
    let z_guess = dem.mean_height().unwrap_or_else(|| camera.height_hint());
    // Where the scan and the DEM do not meet, the DEM is the file to name.
    let on_dem = |e: Error| match e {
        Error::Geometry(m) => Error::format(&dem.path, m),
        e => e,
    };
    let gsd = match cfg.gsd {
        Some(g) if g > 0.0 && g.is_finite() => g,
        Some(g) => return Err(Error::Usage(format!("--gsd {g} must be positive"))),
        None => mean_gsd(model, &dem, sw, sh, z_guess).map_err(on_dem)?,
    };
    let grid = match cfg.bounds {
        Some(b) => OutputGrid::snapped(b[0], b[1], b[2], b[3], gsd).ok_or_else(|| Error::Usage(format!("--bounds {b:?} at GSD {gsd} is empty")))?,
        None => auto_grid(model, &dem, sw, sh, z_guess, gsd).map_err(on_dem)?,
    };
    if grid.width > 1 << 21 || grid.height > 1 << 21 {
        return Err(Error::Usage(format!("output of {}×{} pixels is beyond 2M pixels a side", grid.width, grid.height)));
    }
    let area = [grid.x0, grid.y0 - grid.gsd * grid.height as f64, grid.x0 + grid.gsd * grid.width as f64, grid.y0];
    let plane = match cfg.trend {
        Trend::Plane => dem.trend_plane(area),
        Trend::Mean => dem.mean_plane(area),
    }
    .ok_or_else(|| Error::format(&dem.path, "no height anywhere inside the output area"))?;
    let approx = Approx::new(model, &grid, plane).ok_or_else(|| Error::Geometry("the terrain plane is not in front of the camera".into()))?;
    let band_order = match cfg.band_order {
        BandOrder::Auto => fewer_scan_rows(&approx, &grid, cfg.tile),
        order => order,
    };
    // Bands of tile columns walk the transposed grid: its rows are the
    // output's columns.
    let columns = band_order == BandOrder::Columns;
    let (t, approx) = if columns { (Transform::transposed(model, &dem, grid), approx.transposed()) } else { (Transform::new(model, &dem, grid), approx) };
    let mut spec_gcm = cfg.gcm;
    if cfg.auto_sparsity {
        spec_gcm.k = auto_sparsity(&dem, &grid, camera.crs.epsg);
    }
    let gcm = Gcm::new(&t, approx, spec_gcm);

    // The piece of the grid to make, in tiles (everything by default). All
    // geometry stays that of the whole grid, so pieces equal the whole.
    let (tx_all, ty_all) = (grid.width.div_ceil(cfg.tile), grid.height.div_ceil(cfg.tile));
    let [tc0, tr0, tcw, trh] = cfg.window.unwrap_or([0, 0, tx_all, ty_all]);
    if tcw == 0 || trh == 0 || tc0 + tcw > tx_all || tr0 + trh > ty_all {
        return Err(Error::Usage(format!("--window {tc0},{tr0},{tcw},{trh} is not inside the output's {tx_all}×{ty_all} tiles")));
    }
    let (tc1, tr1) = (tc0 + tcw, tr0 + trh);
    // The piece as walked: bands `wr0..wr1` of tile columns `wc0..wc1`
    // (transposed, bands of the output's tile columns).
    let (wc0, wc1, wr0, wr1) = if columns { (tr0, tr1, tc0, tc1) } else { (tc0, tc1, tr0, tr1) };
    let piece_w = (tc1 * cfg.tile).min(grid.width) - tc0 * cfg.tile;
    let piece_h = (tr1 * cfg.tile).min(grid.height) - tr0 * cfg.tile;
    let bands_in = src.info.bands;
    let bands_out = bands_in + u32::from(cfg.alpha);
    let photometric = if src.info.photometric == 2 && bands_in >= 3 { 2 } else { 1 };
    let mut spec = OutputSpec {
        width: piece_w,
        height: piece_h,
        bands: bands_out,
        sample: src.info.sample,
        chunking: Chunking::Tiles(cfg.tile),
        compression: cfg.compress,
        bigtiff: false,
        photometric,
        alpha: cfg.alpha || src.info.has_alpha,
        geo: Some(GeoTags {
            x0: grid.x0 + (tc0 * cfg.tile) as f64 * grid.gsd,
            y0: grid.y0 - (tr0 * cfg.tile) as f64 * grid.gsd,
            gsd: grid.gsd,
            epsg: camera.crs.epsg,
            nodata: (!cfg.alpha).then_some(cfg.nodata),
        }),
    };
    spec.bigtiff = match cfg.bigtiff {
        BigTiff::Yes => true,
        BigTiff::No => false,
        BigTiff::Auto => spec.needs_bigtiff(),
    };

    // One thread: the steps one after the other (resampling and encoding
    // on the pool's one worker, while this thread waits), so that
    // `--threads 1` keeps one processor busy, not one and a half.
    let sequential = cfg.threads == 1;
    let pool =
        rayon::ThreadPoolBuilder::new().num_threads(cfg.threads).build().map_err(|e| Error::Usage(format!("cannot start {} threads: {e}", cfg.threads)))?;
    let mut times = StageTimes { setup: wall.elapsed().as_secs_f64(), ..Default::default() };
    let n_bands = wr1 - wr0;
    let (lines, what) = if columns { (piece_w, "columns") } else { (piece_h, "rows") };
    let progress = crate::progress::rows_bar(spec.tiles_across() as u64 * spec.tiles_down() as u64, lines as u64, what, src.info.data_bytes(), cfg.quiet);
    let out_file = pending.file()?;
    // A second handle to the output, to start its write-back while tiles
    // are still being made.
    let flush_file = out_file.try_clone().map_err(|e| Error::io(pending.path(), e))?;
    if cfg.compress == Compression::None {
        // The padding before the tiles and the tiles' bytes, all of which the
        // file will hold.
        let pad = crate::io::tiff_out::page_padding(&spec).unwrap_or(0) as u64;
        reserve(&out_file, pad + spec.tile_bytes() as u64 * spec.tiles_across() as u64 * spec.tiles_down() as u64);
    }

    // The memory plan: four scan windows in flight (being read, queued, two
    // being resampled; read in place instead, up to eight shares of mapped
    // scan rows, see the threaded runner), four output chunks (two being
    // made, queued, being encoded; three being made in bands of tile
    // columns, whose windows are read in place) and the encoded tiles (in
    // hand and queued), each a 24th of the budget; the DEM an eighth (larger ones
    // are read a chunk at a time). What is left (~45 %) covers the GCM rows,
    // the threads, the program and the allocator's per-thread arenas
    // (20–30 MB measured on 1 GiB scans), so that the peak resident size
    // stays under the budget (measured at 128 MiB: 76–85 MiB on a 1 GiB
    // scan, 66 MiB with the scan turned 90°, where every window is copied,
    // 76–81 MiB on a 4 GiB scan). The sequential runner holds one window
    // and one chunk at a time.
    let share = cfg.memory / 24;
    let run = Run {
        cfg,
        gcm: &gcm,
        src: &src,
        dem: &dem,
        spec: &spec,
        walked: t.grid,
        bands: (wr0, wr1),
        cols: (wc0, wc1),
        columns,
        piece: (tc0, tr0, tcw),
        bands_out,
        share,
        budget_px: share / src.info.pixel_bytes().max(1) as u64,
        max_tiles: (share / spec.tile_bytes() as u64).max(1) as u32,
        pool,
        progress,
        cancel,
        failed: AtomicBool::new(false),
        chunks_done: AtomicU64::new(0),
        chunks_in_place: AtomicU64::new(0),
        stats: std::sync::Mutex::new(crate::gcm::GcmStats::default()),
    };
    let result = if sequential { run_sequential(&run, out_file, flush_file) } else { run_threaded(&run, out_file, flush_file) };
    run.progress.finish_and_clear();
    if cancel.load(Ordering::Relaxed) {
        return Err(Error::Cancelled);
    }
    let busy = result?;
    times.dem = busy.dem.as_secs_f64();
    times.gcm = busy.gcm.as_secs_f64();
    times.read = busy.read.as_secs_f64();
    times.resample = busy.resample.as_secs_f64();
    times.encode = busy.encode.as_secs_f64();
    verify(pending.path(), &spec)?;
    let output_bytes = std::fs::metadata(pending.path()).map(|m| m.len()).unwrap_or(0);
    pending.publish_synced(cfg.sync)?;
    let wall_s = wall.elapsed().as_secs_f64();
    times.write = (wall_s - times.setup).max(0.0);
    // On the run's own workers: `--threads 1` stays one thread to the end.
    let mut estimate = run.pool.install(|| accuracy::sample_errors(&gcm, (t.grid.height / 64).max(1), 7));
    if columns {
        // Where the largest error is, on the output grid.
        estimate.argmax.swap(0, 1);
    }
    let gcm_stats = *run.stats.lock().expect("stats");
    Ok(Report {
        config: RectifyConfig { gcm: spec_gcm, auto_sparsity: false, band_order, ..cfg.clone() },
        grid,
        crs: camera.crs.to_string(),
        scan: ScanInfo {
            width: sw,
            height: sh,
            bands: bands_in,
            sample: src.info.sample,
            tiled: src.info.tiled,
            compression: src.info.compression,
            memory_mapped: src.is_mapped(),
            bytes: src.info.data_bytes(),
        },
        bands: n_bands,
        chunks: run.chunks_done.load(Ordering::Relaxed),
        chunks_in_place: run.chunks_in_place.load(Ordering::Relaxed),
        stage_seconds: times,
        wall_seconds: wall_s,
        input_mb_per_s: src.info.data_bytes() as f64 / 1e6 / wall_s,
        output_mpx_per_s: piece_w as f64 * piece_h as f64 / 1e6 / wall_s,
        peak_rss_mib: peak_rss_mib(),
        gcm: gcm_stats,
        accuracy_estimate: estimate,
        output_bytes,
    })
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
/// output pixels where that is finer, but not under 12. Between nodes the
/// corrections are interpolated bilinearly while the DEM bends at its own
/// posts; seed 004 likewise asks for grid nodes no sparser than the DEM.
fn auto_sparsity(dem: &Dem, grid: &OutputGrid, ground_epsg: u32) -> u32 {
    let crate::dem::HeightModel::Grid(g) = &dem.model else { return 16 };
    let metres = |epsg: Option<u32>, v: f64, lat_scale: f64| {
        if epsg.and_then(crate::io::geotiff::is_geographic).unwrap_or(false) {
            v * 111_320.0 * lat_scale
        } else {
            v
        }
    };
    let (lat_mid, _) = {
        let (x, y) = grid.ground(grid.width as f64 / 2.0, grid.height as f64 / 2.0);
        match crate::geodesy::GroundCrs::from_epsg(ground_epsg).ok().and_then(|c| c.to_lonlat(x, y)) {
            Some((lon, lat)) => (lat, lon),
            None => (0.0, 0.0),
        }
    };
    let cos = lat_mid.to_radians().cos();
    let post = metres(g.epsg, g.transform[1].abs(), cos).min(metres(g.epsg, g.transform[5].abs(), 1.0));
    let gsd = metres(Some(ground_epsg), grid.gsd, 1.0);
    if !(post > 0.0 && gsd > 0.0) {
        return 16;
    }
    ((post / gsd).floor() as u32).clamp(12, 16)
}
