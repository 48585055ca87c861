//! `rectify`: set up the run, give its stages to a runner, verify and
//! publish the output, report.

use super::context::{Counters, Inputs, Run, Stop, Walk};
use super::report::{Hidden, Report, ScanInfo, StageTimes, UNBOUNDED_WARNING_PX};
use super::sequential::run_sequential;
use super::setup::RunPlan;
use super::threaded::run_threaded;
use crate::error::{Error, Result};
use crate::gcm::self_check;
use crate::gcm::{Gcm, GcmStats};
use crate::io::tiff_out::{page_padding, reserve, verify, Compression, PendingFile};
use crate::options::{Occlusion, RectifyOptions};
use crate::overview::{Pyramid, ValidBy};
use crate::progress::{Cancel, Progress, Task};
use crate::transform::visibility::Visibility;
use crate::transform::Transform;
use std::sync::atomic::Ordering;
use std::time::Instant;

/// Orthorectifies `opts.image` into `opts.output`, telling `progress` how
/// far it has come. `cancel` may be set from another thread (a signal
/// handler) to stop the run; the output is then not created.
pub fn rectify(opts: &RectifyOptions, progress: &dyn Progress, cancel: &Cancel) -> Result<Report> {
    let wall = Instant::now();
    let recording = crate::progress::Recording::new(progress);
    let progress: &dyn Progress = &recording;
    // Every output is a GeoTIFF: a name that says another format misleads
    // whoever opens it by its name.
    if let Some(w) = crate::io::tiff_out::named_as_other_format(&opts.file.path) {
        progress.warn(&w);
    }
    if let Some(w) = crate::processor::unknown_choice() {
        progress.warn(&w);
    }
    opts.validate()?;
    opts.check_outputs(&[])?;
    // The output folder must take a file before any work starts.
    let pending = PendingFile::create(&opts.file.path)?;
    if cancel.is_cancelled() {
        return Err(Error::Cancelled);
    }
    // One thread: the steps one after the other (resampling and encoding
    // on the pool's one worker, while this thread waits), so that one
    // thread keeps one processor busy, not one and a half.
    let sequential = opts.resources.threads == 1;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(opts.resources.threads)
        .build()
        .map_err(|e| Error::setting("threads", format!("cannot start {} threads: {e}", opts.resources.threads)))?;
    // The set-up's parallel parts (reading the DEM) on the run's own workers too.
    let plan = pool.install(|| RunPlan::new(opts, progress))?;
    if cancel.is_cancelled() {
        return Err(Error::Cancelled);
    }
    let (src, dem, spec) = (&plan.src, &plan.dem, &plan.spec);
    let model = plan.camera.model();
    let columns = plan.columns();
    // Bands of tile columns walk the transposed grid: its rows are the
    // output's columns.
    let (t, approx) =
        if columns { (Transform::transposed(model, dem, plan.grid), plan.approx.transposed()) } else { (Transform::new(model, dem, plan.grid), plan.approx) };
    let t = t.with_scan((src.info.width, src.info.height));
    let gcm = Gcm::new(&t, approx, plan.gcm);
    let visibility = (opts.pixels.occlusion != Occlusion::None).then(|| Visibility::new(&t, plan.occlusion_tolerance()));

    // The piece as walked: bands `wr0..wr1` of tile columns `wc0..wc1`
    // (transposed, bands of the output's tile columns).
    let [tc0, tr0, tcw, trh] = plan.piece;
    let (tc1, tr1) = (tc0 + tcw, tr0 + trh);
    let (wc0, wc1, wr0, wr1) = if columns { (tr0, tr1, tc0, tc1) } else { (tc0, tc1, tr0, tr1) };
    let walk = Walk { grid: t.grid, tile: opts.file.tile, bands: (wr0, wr1), cols: (wc0, wc1), columns, piece: (tc0, tr0, tcw) };

    let mut times = StageTimes { setup: wall.elapsed().as_secs_f64(), ..Default::default() };
    let (lines, line_name) = if columns { (spec.width, "columns") } else { (spec.height, "rows") };
    let units = spec.tiles_across() as u64 * spec.tiles_down() as u64;
    progress.start(&Task { name: "rectify", units, lines: lines as u64, line_name, input_bytes: src.info.data_bytes() });
    let out_file = pending.file()?;
    // A second handle to the output, to start its write-back while tiles
    // are still being made.
    let flush_file = out_file.try_clone().map_err(|e| Error::io(pending.path(), e))?;
    if opts.file.compress == Compression::None && !spec.cog {
        // The padding before the tiles and the tiles' bytes (all levels'),
        // all of which the file will hold.
        let pad = page_padding(spec).unwrap_or(0) as u64;
        let tiles: u64 = (0..=spec.overviews).map(|l| spec.level_tile_count(l) as u64).sum();
        reserve(&out_file, pad + spec.tile_bytes() as u64 * tiles);
    }

    let run = Run {
        inputs: Inputs { gcm: &gcm, src, dem, spec, pixels: plan.pixels, output: &opts.file.path, sync: opts.file.sync, visibility: visibility.as_ref() },
        walk,
        budget: plan.budget,
        counters: Counters { sampled: Some(Default::default()), ..Default::default() },
        stop: Stop::new(cancel),
        pool: &pool,
        progress,
        spare_masks: crossbeam_channel::bounded(4),
        pyramid: Pyramid::new(spec, opts.file.overview_resampling, ValidBy::of(spec), plan.pixels.fill).map(std::sync::Mutex::new),
        valid_by: ValidBy::of(spec),
        statistics: Default::default(),
        // A piece also names the whole it is a piece of.
        source: Some(match (opts.grid.window, crate::scene::made_from::source_key(opts)) {
            (Some(_), key) => {
                crate::io::geotiff::piece_source(&key, &plan.grid, &crate::assemble::layout_record(opts.file.overviews, opts.file.overview_resampling, opts.file.cog))
            }
            (None, key) => key,
        }),
    };
    let result = if sequential { run_sequential(&run, out_file, flush_file) } else { run_threaded(&run, out_file, flush_file) };
    progress.finish();
    if cancel.is_cancelled() {
        return Err(Error::Cancelled);
    }
    let busy = result?;
    // Zeros read past the end of a file truncated under its map make no
    // output.
    src.check_intact()?;
    plan.dem.check_intact()?;
    plan.camera.check_intact()?;
    say_what_the_pixels_hold(opts, &run, progress);
    if run.pyramid.as_ref().is_some_and(|p| !p.lock().is_ok_and(|p| p.is_complete())) {
        return Err(Error::Internal("an overview tile was left unfinished".into()));
    }
    times.dem = busy.dem.as_secs_f64();
    times.gcm = busy.gcm.as_secs_f64();
    times.read = busy.read.as_secs_f64();
    times.resample = busy.resample.as_secs_f64();
    times.encode = busy.encode.as_secs_f64();
    verify(pending.path(), spec)?;
    let output_bytes = std::fs::metadata(pending.path()).map(|m| m.len()).unwrap_or(0);
    pending.publish_synced(opts.file.sync)?;
    let wall_s = wall.elapsed().as_secs_f64();
    times.write = (wall_s - times.setup).max(0.0);
    let error_bound = plan.gcm.max_error;
    let (estimate, error_within) = checked_error(&run, &t.grid, columns, error_bound, progress);
    let gcm_stats = GcmStats { exact_pixels: run.counters.exact_pixels.load(Ordering::Relaxed), ..*run.counters.gcm.lock().expect("stats") };
    // Everything the run warned of, the DEM's doubts among them.
    let warnings = recording.said();
    Ok(Report {
        config: {
            let mut c = opts.clone();
            (c.geometry.gcm, c.geometry.auto_sparsity, c.resources.band_order) = (plan.gcm, false, plan.band_order);
            c
        },
        grid: plan.grid,
        crs: plan.camera.crs.to_string(),
        geographic: plan.camera.crs.is_geographic(),
        scan: ScanInfo::of(src),
        bands: wr1 - wr0,
        chunks: run.counters.chunks_done.load(Ordering::Relaxed),
        chunks_in_place: run.counters.chunks_in_place.load(Ordering::Relaxed),
        stage_seconds: times,
        wall_seconds: wall_s,
        input_mb_per_s: src.info.data_bytes() as f64 / 1e6 / wall_s,
        output_mpx_per_s: spec.width as f64 * spec.height as f64 / 1e6 / wall_s,
        peak_rss_mib: progress.peak_memory_mib(),
        kernels: crate::processor::chosen().name(),
        gcm: gcm_stats,
        accuracy_estimate: estimate,
        error_bound,
        error_within,
        output_bytes,
        warnings,
        gcps: plan.gcp_fit.clone(),
        occlusion: visibility.is_some().then(|| Hidden::new(run.counters.imaged.load(Ordering::Relaxed), run.counters.hidden.load(Ordering::Relaxed))),
    })
}

/// What the run's pixels hold that its user should hear of: samples moved
/// off the nodata value, or no pixel with a value at all.
fn say_what_the_pixels_hold(opts: &RectifyOptions, run: &Run, progress: &dyn Progress) {
    let src = run.inputs.src;
    let nudged = run.counters.nudged.load(Ordering::Relaxed);
    if nudged > 0 {
        let v = run.inputs.pixels.fill;
        progress.warn(&format!(
            "{nudged} samples of pixels with a value held the nodata value {v} and were made {} (as GDAL's warper does), so that they do not read as holes; the default internal mask (‹nodata› auto) keeps every value",
            super::stages::resample::off_nodata(v, src.info.sample)
        ));
    }
    // An orthophoto without one pixel of image is a mistake to say (a
    // piece of a window may be empty beside the footprint).
    let stats = run.statistics.lock().map(|s| s.total()).unwrap_or_default();
    if opts.grid.window.is_none() && stats.pixels > 0 && !stats.bands.is_empty() && stats.bands.iter().all(|b| b.count == 0) {
        progress.warn(&format!(
            "{}: no pixel of it has a value: the scan's ground lies outside the grid, in the DEM's holes or off it (‹dem_hole›, ‹dem_outside›), or the scan holds no image there",
            opts.file.path.display()
        ));
    }
}

/// The GCM's error against the exact model on the run's sample, with
/// whether it is within the bound (or, unbounded, within what passes
/// unsaid); said when it is not.
fn checked_error(
    run: &Run,
    grid: &crate::geom::OutputGrid,
    columns: bool,
    error_bound: Option<f64>,
    progress: &dyn Progress,
) -> (self_check::ErrorStats, bool) {
    let sampled = run.counters.sampled.as_ref().map(|s| *s.lock().expect("sample")).unwrap_or_default();
    let mut estimate = self_check::ErrorStats::of(&sampled, self_check::run_sample_steps(grid).1);
    if columns {
        // Where the largest error is, on the output grid.
        estimate.argmax.swap(0, 1);
    }
    // The bound holds by construction at every pixel; the sample checks it.
    let error_within = estimate.max <= error_bound.map_or(UNBOUNDED_WARNING_PX, |b| b * 1.000_001);
    if !error_within {
        let w = match error_bound {
            Some(b) => format!("the GCM missed its bound of {b} px: {:.3} px at output pixel {:?} (please report it)", estimate.max, estimate.argmax),
            None => format!(
                "the GCM is up to {:.2} px off the exact model (sampled, at output pixel {:?}); ‹max_error› 0.1 holds it within 0.1 px",
                estimate.max, estimate.argmax
            ),
        };
        progress.warn(&w);
    }
    (estimate, error_within)
}

impl ScanInfo {
    fn of(src: &crate::io::source::SourceImage) -> ScanInfo {
        ScanInfo {
            width: src.info.width,
            height: src.info.height,
            bands: src.info.bands,
            sample: src.info.sample,
            tiled: src.info.tiled,
            compression: src.info.compression,
            memory_mapped: src.is_mapped(),
            bytes: src.info.data_bytes(),
        }
    }
}
