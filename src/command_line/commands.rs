//! What each subcommand does with its validated options: call the library,
//! print a summary.

/// `println!` that never panics: where stdout is gone (a closed pipe, as
/// under `| head`) the line is dropped, and the command's work stands.
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($t)*);
    }};
}

use super::cli::{AccuracyArgs, BatchArgs, Cli, Command, DemoArgs, MosaicArgs, RectifyArgs, SynthArgs};
use super::progress_bar::Bar;
use crate::camera::file::Camera;
use crate::dem::Dem;
use crate::gcm::{CorrectionMode, Gcm, GcmSpec};
use crate::io::overwrite::{check_outputs, check_writable, Role};
use crate::io::publish::write_file;
use crate::io::source::SourceImage;
use crate::options::{parse_bytes, parse_size, DemSource, RectifyOptions};
use crate::study::accuracy::evaluate_where;
use crate::study::compare::compare_files;
use crate::synth::{synth, SynthOptions};
use crate::transform::footprint::{auto_grid, footprint_gsd};
use crate::transform::{Approx, Transform, Trend};
use crate::{rectify, Cancel, Report};
use anyhow::{anyhow, Context, Result};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// SIGINT / SIGTERM turn into the cancel flag the library polls; SIGBUS on
/// a scan truncated under its memory map into one line and exit code 1.
pub struct Signals {
    pub cancel: Cancel,
    int: Arc<AtomicBool>,
    term: Arc<AtomicBool>,
    /// Who says the run was interrupted and ends it: the command, or the
    /// watchdog (once).
    ending: Arc<AtomicBool>,
}

/// How long a command that polls the cancel flag has to wind down after a
/// signal before the watchdog ends it: parsing and planning poll less
/// often than rendering does, and a signal is honoured within a second
/// in every phase.
const GRACE: Duration = Duration::from_millis(700);

impl Signals {
    /// `polls`: the command stops at the cancel flag (rectify, batch, demo),
    /// cleaning up as it goes, within [`GRACE`]; a command that does not
    /// poll, and one still busy after it, is ended by the watchdog, its
    /// temporary outputs removed. A second signal ends it at once.
    pub fn install(polls: bool) -> std::io::Result<Signals> {
        let s = Signals { cancel: Cancel::new(), int: Arc::default(), term: Arc::default(), ending: Arc::default() };
        for (sig, flag, code) in [(signal_hook::consts::SIGINT, &s.int, 130), (signal_hook::consts::SIGTERM, &s.term, 143)] {
            // Before the flags are set: it sees whether one already was.
            signal_hook::flag::register_conditional_shutdown(sig, code, s.cancel.flag())?;
            signal_hook::flag::register(sig, flag.clone())?;
            signal_hook::flag::register(sig, s.cancel.flag())?;
        }
        crate::io::mmap_guard::install_sigbus_handler();
        let watched = Signals { cancel: s.cancel.clone(), int: s.int.clone(), term: s.term.clone(), ending: s.ending.clone() };
        let grace = if polls { GRACE } else { Duration::ZERO };
        std::thread::Builder::new().name("signal watchdog".into()).spawn(move || watched.watch(grace))?;
        Ok(s)
    }

    /// Waits for a signal; `grace` after it, ends a command still running:
    /// its registered temporary outputs removed, one line, exit 130 or 143.
    fn watch(&self, grace: Duration) {
        let code = loop {
            if let Some(code) = self.exit_code() {
                break code;
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        std::thread::sleep(grace);
        if self.claim_end() {
            crate::io::mmap_guard::remove_registered_temporaries();
            eprintln!("gcm-ortho: interrupted; no unfinished output was left behind");
            std::process::exit(i32::from(code));
        }
    }

    /// Whether the caller is the one to say the run was interrupted (the
    /// command and the watchdog may both come to it).
    pub fn claim_end(&self) -> bool {
        self.ending.compare_exchange(false, true, Ordering::AcqRel, Ordering::Acquire).is_ok()
    }

    pub fn exit_code(&self) -> Option<u8> {
        if self.int.load(Ordering::Relaxed) {
            Some(130)
        } else if self.term.load(Ordering::Relaxed) {
            Some(143)
        } else {
            None
        }
    }
}

/// Runs a command; `Ok(code)` is the exit code of a run that completed
/// (3: a batch in which some jobs failed).
pub fn run(cli: Cli, signals: &Signals) -> Result<u8> {
    match cli.command {
        Command::Synth(a) => run_synth(&a).map(|()| 0),
        Command::Rectify(a) => run_rectify(&a, signals).map(|()| 0),
        Command::Accuracy(a) => run_accuracy(&a).map(|()| 0),
        Command::Demo(a) => run_demo(&a, signals).map(|()| 0),
        Command::Batch(a) => run_batch(&a, signals),
        Command::RpcGrid(a) => run_rpc_grid(&a).map(|()| 0),
        Command::Mosaic(a) => run_mosaic(&a, signals).map(|()| 0),
        Command::Cameras(a) => run_cameras(&a).map(|()| 0),
        Command::Fiducials(a) => run_fiducials(&a).map(|()| 0),
        Command::Grid(a) => run_grid(&a, signals).map(|()| 0),
        Command::Dem(a) => run_dem(&a, signals).map(|()| 0),
        Command::Assemble(a) => {
            warn_if_not_tiff(&a.output);
            inputs_exist(&a.pieces.iter().map(|p| ("piece", Some(p.as_path()))).collect::<Vec<_>>())?;
            let opts = crate::command_keys::assemble_options(super::cli::keys_of(&a)?)?;
            crate::assemble::assemble(&a.pieces, &a.output, &opts, &signals.cancel)?;
            Ok(0)
        }
    }
}

/// `--threads`: 0 is every core.
fn worker_threads(asked: usize) -> usize {
    match asked {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        t => threads_within_cores(t, 1).0,
    }
}

fn run_dem(a: &super::cli::DemArgs, signals: &Signals) -> Result<()> {
    let mut o = crate::command_keys::dem_options(super::cli::keys_of(a)?)?;
    o.threads = worker_threads(a.threads);
    let run = || crate::stereo::dem(&o, &Bar::new(a.quiet), &signals.cancel);
    run_reported(
        a.json.as_deref(),
        (&a.memory, o.memory),
        a.quiet,
        run,
        |r| &mut r.warnings,
        |r| {
            let made = match (&r.dsm, &r.then) {
                (Some(d), _) => format!("{} × {} cells", d.width, d.height),
                (None, then) => format!("{} points of this shard (the DSM: {})", r.points_written, then.as_deref().unwrap_or("")),
            };
            format!(
                "{}: {made}; {:.1} % of the overlap matched, residual parallax {:.3} px (median), B/H {:.2}, height precision {:.2} m; {:.1} s",
                r.output.display(),
                100.0 * r.matched_share,
                r.residual_parallax_px.median,
                r.epipolar.base_to_height,
                r.height_precision_m,
                r.seconds
            )
        },
    )
}

fn run_grid(a: &super::cli::GridArgs, signals: &Signals) -> Result<()> {
    inputs_exist(&a.points.iter().map(|p| ("points", Some(p.as_path()))).collect::<Vec<_>>())?;
    let mut o = crate::command_keys::grid_options(super::cli::keys_of(a)?)?;
    o.threads = worker_threads(a.threads);
    let run = || crate::gridding::grid(&o, &Bar::new(a.quiet), &signals.cancel);
    run_reported(
        a.json.as_deref(),
        (&a.memory, o.memory),
        a.quiet,
        run,
        |r| &mut r.warnings,
        |r| {
            format!(
                "{}: {}×{} cells at {} from {} points ({} blunders dropped); {:.1} % with a height; typical spacing {:.3}, longest side {:.3}; {:.1} s",
                r.output.display(),
                r.width,
                r.height,
                r.gsd[0],
                r.points_used,
                r.blunders,
                100.0 * r.cells_with_height as f64 / (r.cells_with_height + r.cells_without).max(1) as f64,
                r.spacing,
                r.max_edge,
                r.seconds
            )
        },
    )
}

/// What `grid` and `dem` do once their options are read: the report's
/// path checked before the run, the run, the memory warning (said, and
/// kept in the report's `warnings`), the report written, the summary line.
fn run_reported<R: serde::Serialize>(
    json: Option<&Path>,
    (memory_given, memory): (&str, u64),
    quiet: bool,
    run: impl FnOnce() -> crate::Result<R>,
    warnings: impl Fn(&mut R) -> &mut Vec<String>,
    summary: impl Fn(&R) -> String,
) -> Result<()> {
    if let Some(j) = json {
        check_writable(Role::new("report", j))?;
    }
    let mut report = run()?;
    if let Some(w) = past_budget(memory_given, memory) {
        super::flag_names::warn(&w);
        warnings(&mut report).push(w);
    }
    if let Some(j) = json {
        write_report(j, &serde_json::to_string_pretty(&report)?)?;
    }
    if !quiet {
        eprintln!("{}", summary(&report));
    }
    Ok(())
}

/// The run's JSON report, its last output: a report that cannot be written
/// fails the run, and the run's other outputs are taken back with it
/// (published before, as the report describes them).
fn write_report(path: &Path, json: &str) -> Result<()> {
    write_file(path, super::flag_names::with_flags(json).as_bytes()).map_err(|e| {
        let kept = crate::io::publish::withdraw_publications();
        match kept.is_empty() {
            true => anyhow!("report: {e}; this run's outputs are removed"),
            false => {
                anyhow!("report: {e}; this run's outputs are removed but for {}", kept.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", "))
            }
        }
    })
}

fn run_fiducials(a: &super::cli::FiducialsArgs) -> Result<()> {
    use crate::fiducials::{self, camera::Overrides, Turn};
    use crate::io::overwrite::{check_outputs, Role};
    let turn = match a.turn.as_deref() {
        None => None,
        Some(t) => {
            let (deg, mirrored) = t.strip_suffix('m').map_or((t, false), |d| (d, true));
            let quarters = match deg {
                "0" => 0,
                "90" => 1,
                "180" => 2,
                "270" => 3,
                _ => return Err(crate::Error::setting("turn", format!("'{t}' is not 0, 90, 180 or 270 (with m after it for a mirrored scan)")).into()),
            };
            Some(Turn { quarters, mirrored })
        }
    };
    let mut outputs = Vec::new();
    if let Some(w) = &a.write {
        outputs.push(Role::new("--write", w));
    }
    if let Some(s) = &a.sheet {
        outputs.push(Role::new("--sheet", s));
    }
    check_outputs(&[Role::new("--image", &a.image), Role::new("--camera", &a.camera)], &outputs)?;
    let text = crate::io::bounded_read::read_text_bounded(&a.camera, "a camera file", crate::io::bounded_read::SMALL)?;
    let file = crate::camera::file::CameraFile::parse(&text, &a.camera)?;
    let src = crate::io::source::SourceImage::open(&a.image, 16 << 20)?;
    let over = Overrides { shape: a.shape.clone(), size_mm: a.size_mm, polarity: a.polarity, turn, pixel_mm: a.scan_pixel_mm, limit_px: a.max_residual_px };
    let det = fiducials::camera::detect_for(&file, &a.camera, &src, &over)?;
    if let Some(w) = &a.write {
        let measured = fiducials::camera::with_marks(file.clone(), &det)?;
        // The file must still make a camera.
        measured.clone().build(&a.camera)?;
        let edited = fiducials::camera::edit_toml(&text, &measured, &a.camera)?;
        crate::io::publish::write_file(w, edited.as_bytes())?;
    }
    if let Some(s) = &a.sheet {
        fiducials::sheet::write(s, fiducials::sheet::render(&src, &det)?)?;
    }
    for w in &det.warnings {
        super::flag_names::warn(&format!("{}: {w}", a.image.display()));
    }
    if det.turn_ambiguous && turn.is_none() {
        eprintln!("gcm-ortho: note: the marks look the same turned; the scan is taken as it lies (--turn if the film was turned)");
    }
    if a.json {
        say!("{}", super::flag_names::with_flags(&serde_json::to_string_pretty(&det)?));
        return Ok(());
    }
    say!("{:>4} {:>10} {:>10} {:>11} {:>11} {:>6} {:>6} {:>8} {:>8}  used", "mark", "x mm", "y mm", "column", "row", "score", "centre", "res px", "res µm");
    for m in &det.marks {
        let (c, r) = m.px.map_or((f64::NAN, f64::NAN), |p| (p[0], p[1]));
        let rp = m.residual_px.map_or(f64::NAN, |v| v[0].hypot(v[1]));
        let ru = m.residual_um.map_or(f64::NAN, |v| v[0].hypot(v[1]));
        let used = if m.used { "yes".to_string() } else { format!("no: {}", m.why.clone().unwrap_or_default()) };
        say!(
            "{:>4} {:>10.3} {:>10.3} {:>11.2} {:>11.2} {:>6.2} {:>6.2} {:>8.2} {:>8.1}  {used}",
            m.mark,
            m.mm[0],
            m.mm[1],
            c,
            r,
            m.score,
            m.centre_score,
            rp,
            ru
        );
    }
    say!(
        "film {}, {:+.3}°; {} marks; scan pixel {:.2} × {:.2} µm; residuals RMS {:.2} px, max {:.2} px ({:.1} µm)",
        det.turn_text,
        det.rotation_deg,
        match det.polarity {
            fiducials::Polarity::Dark => "dark",
            _ => "light",
        },
        det.pixel_mm[0] * 1e3,
        det.pixel_mm[1] * 1e3,
        det.rms_px,
        det.max_px,
        det.max_um
    );
    Ok(())
}

fn run_cameras(a: &super::cli::CamerasArgs) -> Result<()> {
    let done = crate::camera::formats::convert::convert(&a.options()?)?;
    for w in &done.warnings {
        super::flag_names::warn(w);
    }
    if a.quiet {
        return Ok(());
    }
    say!("{}", crate::camera::formats::convert::table(&done.entries).trim_end_matches('\n'));
    for p in &done.written {
        say!("wrote {}", p.display());
    }
    Ok(())
}

fn run_mosaic(a: &MosaicArgs, signals: &Signals) -> Result<()> {
    use crate::mosaic::mosaic;
    inputs_exist(&[
        ("manifest", Some(a.manifest.as_path())),
        ("--seamlines", a.seamlines.as_deref()),
        ("--plan", a.plan.as_deref()),
        ("--like", a.like.as_deref()),
    ])?;
    if let Some(j) = &a.json {
        check_writable(Role::new("report", j))?;
    }
    let mut o = crate::command_keys::mosaic_options(super::cli::keys_of(a)?)?;
    o.threads = threads_within_cores(a.threads, 1).0;
    let memory = o.memory;
    let report = match &a.resume_dir {
        Some(dir) => crate::mosaic::resume::resumable(&o, dir, &Bar::new(a.quiet), &signals.cancel)?,
        None => mosaic(&o, &Bar::new(a.quiet), &signals.cancel)?,
    };
    if let Some(w) = past_budget(&a.memory, memory) {
        super::flag_names::warn(&w);
    }
    if let Some(j) = &a.json {
        // A rerun that finds its output current made nothing: it says so,
        // not a mosaic's figures it never measured.
        let text = match report.skipped {
            true => serde_json::to_string_pretty(&serde_json::json!({ "output": report.output, "skipped": true, "output_bytes": report.output_bytes }))?,
            false => serde_json::to_string_pretty(&report)?,
        };
        write_report(j, &text)?;
    }
    if report.skipped {
        if !a.quiet {
            eprintln!("{}: current (made from these inputs and settings); --force remakes it", report.output.as_deref().unwrap_or(Path::new("")).display());
        }
        return Ok(());
    }
    if !a.quiet {
        eprintln!(
            "{}: {}×{} px at {} from {}; {}; seams {} px long; plan {:.1} s, balance {:.1} s, seams {:.1} s{}",
            report.output.as_deref().or(a.plan_out.as_deref()).unwrap_or(Path::new("")).display(),
            report.width,
            report.height,
            report.gsd,
            taken_of(&report.images),
            // What GDAL's VALID_PERCENT says, where the pixels were made.
            match report.pixels_with_value {
                Some([v, n]) => format!("{:.1} % of its pixels have a value", 100.0 * v as f64 / n.max(1) as f64),
                None => format!("{:.0} % of it seen by some image", report.coverage * 100.0),
            },
            report.seam_length_px,
            report.seconds.plan,
            report.seconds.balance,
            report.seconds.seams,
            // (The plan alone renders nothing.)
            if report.output.is_some() { format!(", render {:.1} s", report.seconds.render) } else { String::new() }
        );
        if let Some(u) = &report.unseen {
            eprintln!(
                "  occlusion: {} px ({:.2} % of the covered ground, {:.1} m²) seen by no image, left without a value",
                u.unseen_px,
                100.0 * u.share,
                u.area
            );
        }
    }
    Ok(())
}

fn run_batch(a: &BatchArgs, signals: &Signals) -> Result<u8> {
    use crate::batch::{self, BatchOptions, ReportWriter, Status};
    let shard = batch::shard::resolve(a.shard.as_deref(), a.shard_count, &|k| std::env::var(k).ok())?;
    let memory = parse_bytes("memory", &a.memory)?;
    if memory < RectifyOptions::MIN_MEMORY {
        return Err(crate::Error::setting("memory", "must be at least 16M").into());
    }
    let jobs = batch::manifest::load(&a.manifest).map_err(|e| e.into_error())?;
    if let Some(report) = &a.report {
        let (mut ins, outs) = batch::manifest::files(&jobs);
        ins.push(("manifest".into(), a.manifest.clone()));
        let ins: Vec<Role> = ins.iter().map(|(w, p)| Role::new(w, p)).collect();
        let mut outs: Vec<Role> = outs.iter().map(|(w, p)| Role::new(w, p)).collect();
        outs.push(Role::new("report", report));
        check_writable(Role::new("report", report))?;
        check_outputs(&ins, &outs)?;
    }
    let at_once = batch::jobs_within(memory, a.jobs);
    if at_once < a.jobs {
        eprintln!(
            "gcm-ortho: warning: --memory {} gives {} jobs at once at least {} MiB each: running {at_once} at a time, not {}",
            a.memory,
            a.jobs,
            RectifyOptions::MIN_MEMORY >> 20,
            a.jobs
        );
    }
    let threads = threads_within_cores(a.threads, at_once).0;
    let o = BatchOptions { jobs: at_once, memory, force: a.force, shard, threads };
    if a.dry_run {
        let mine: Vec<_> = jobs.iter().enumerate().filter(|(i, _)| i % shard.1 == shard.0).collect();
        for (i, j) in &mine {
            say!("{i:>5}  {}  {} -> {}", j.name, j.config.inputs.image.display(), j.config.file.path.display());
        }
        // A job that would fail is said now, and the check fails (exit 3):
        // its files as the manifest names them, each image's header (a
        // truncated or foreign file), and the run's whole set-up — the
        // camera, the DEM under the footprint, the grid — short of making
        // pixels; its warnings as the run would give them.
        let mut failing = 0;
        for (_, j) in &mine {
            let recording = crate::progress::Recording::new(&crate::progress::NoProgress);
            let problem = j.problem.clone().or_else(|| {
                crate::io::source::SourceImage::info_of(&j.config.inputs.image)
                    .and_then(|_| j.config.validate())
                    .and_then(|()| crate::pipeline::RunPlan::new(&j.config, &recording))
                    .and_then(|plan| plan.check_node_heights())
                    .err()
                    .map(|e| e.to_string())
            });
            for w in recording.said() {
                super::flag_names::warn(&format!("job {}: {w}", j.name));
            }
            if let Some(p) = problem {
                eprintln!("gcm-ortho: job {} will fail: {p}", j.name);
                failing += 1;
            }
        }
        return Ok(if failing == 0 { 0 } else { 3 });
    }
    for j in jobs.iter().filter(|j| j.problem.is_some()) {
        eprintln!("gcm-ortho: job {} will fail: {}", j.name, j.problem.as_deref().unwrap_or_default());
    }
    let report = ReportWriter::create(a.report.as_deref()).with_context(|| format!("{:?}", a.report))?;
    let quiet = a.quiet;
    let results = batch::run_jobs(&jobs, &o, &Bar::new(true), &signals.cancel, &|r| {
        report.push(r);
        for w in &r.warnings {
            super::flag_names::warn(&format!("job {}: {w}", r.job));
        }
        // A failed job's error, and a job left to another run, are shown
        // even when quiet: quiet hides progress, not what was not made.
        if !quiet || matches!(r.status, Status::Failed | Status::Busy) {
            eprintln!("{:<24} {:?}{}", r.job, r.status, r.error.as_ref().map(|e| format!(": {e}")).unwrap_or_default());
        }
    });
    if !a.quiet {
        say!("{:<24} {:>9} {:>8} {:>8} {:>9}  output", "job", "status", "time s", "MB/s", "max px");
        for r in &results {
            say!(
                "{:<24} {:>9} {:>8.2} {:>8} {:>9}  {}",
                r.job,
                format!("{:?}", r.status).to_lowercase(),
                r.seconds,
                r.input_mb_per_s.map(|v| format!("{v:.1}")).unwrap_or_else(|| "-".into()),
                r.gcm_max_px.map(|v| format!("{v:.3}")).unwrap_or_else(|| "-".into()),
                r.output.display()
            );
        }
        let count = |s: Status| results.iter().filter(|r| r.status == s).count();
        say!(
            "shard {}/{}: {} jobs, {} done, {} skipped (current), {} busy (another run's), {} failed, {} cancelled",
            shard.0 + 1,
            shard.1,
            results.len(),
            count(Status::Done),
            count(Status::Skipped),
            count(Status::Busy),
            count(Status::Failed),
            count(Status::Cancelled)
        );
    }
    if let Some(w) = past_budget(&a.memory, memory) {
        super::flag_names::warn(&w);
    }
    if signals.exit_code().is_some() {
        return Err(anyhow::Error::new(crate::Error::Cancelled));
    }
    Ok(if results.iter().any(|r| r.status == Status::Failed) { 3 } else { 0 })
}

fn usage(msg: String) -> anyhow::Error {
    anyhow::Error::new(crate::Error::Usage(msg))
}

fn run_synth(a: &SynthArgs) -> Result<()> {
    let before = crate::synth::leftovers::Leftovers::before(&a.out);
    let made = make_synth(a);
    if made.is_err() {
        before.remove();
    }
    made
}

fn make_synth(a: &SynthArgs) -> Result<()> {
    let t = std::time::Instant::now();
    if let Some(n) = a.points {
        std::fs::create_dir_all(&a.out).with_context(|| format!("{}: cannot make the folder", a.out.display()))?;
        let path = a.out.join(if a.laz {
            "points.laz"
        } else if a.csv {
            "points.csv"
        } else {
            "points.las"
        });
        let side = crate::synth::points::write_points(&path, n, a.points_density, a.seed, &Bar::new(a.quiet))?;
        if !a.quiet {
            say!("synth: {n} points on {side:.0} m × {side:.0} m from (500000, 4000000), EPSG:32631, {:.1} s\n  {}", t.elapsed().as_secs_f64(), path.display());
        }
        return Ok(());
    }
    let o = a.options()?;
    if let Some(bh) = a.stereo {
        let r = match o.camera {
            crate::synth::CameraKind::Rpc => crate::synth::satellite::synth_rpc_pair(&o, bh, &Bar::new(a.quiet))?,
            crate::synth::CameraKind::Panoramic => crate::synth::panoramic::synth_panoramic_pair(&o, bh, &Bar::new(a.quiet))?,
            _ => return Err(usage("--stereo: only for --camera rpc or panoramic (a frame pair: --block 2x1)".into())),
        };
        if !a.quiet {
            say!(
                "synth: a{} stereo pair of {}x{} at B/H {}, relief {:.0} to {:.0} m, {:.1} s\n  {}\n  {}\n  {}",
                if o.camera == crate::synth::CameraKind::Rpc { "n RPC" } else { " panoramic" },
                o.width,
                o.height,
                r.base_to_height,
                r.relief_range[0],
                r.relief_range[1],
                t.elapsed().as_secs_f64(),
                r.left.display(),
                r.right.display(),
                r.dem.display()
            );
        }
        return Ok(());
    }
    if let Some(b) = &a.block {
        let (cols, rows) = parse_size("block", b)?;
        let r = crate::synth::block::synth_block(&o, cols, rows, &Bar::new(a.quiet))?;
        if !a.quiet {
            say!(
                "synth: a block of {} frames of {}x{}, mosaic grid {}x{} at {} m, {:.1} s",
                r.frames,
                o.width,
                o.height,
                r.grid.width,
                r.grid.height,
                r.grid.gsd,
                t.elapsed().as_secs_f64()
            );
            say!("  {}\n  {}\n  {}", r.manifest.display(), r.dem.display(), r.truth.display());
        }
        return Ok(());
    }
    if a.marks_only {
        if o.camera != crate::synth::CameraKind::Film {
            return Err(anyhow!("--marks-only: only for --camera film"));
        }
        let (scan, camera) = crate::synth::film_marks::marks_only(&o)?;
        if !a.quiet {
            say!(
                "synth: {}x{} film scan of {} marks, {:.1} s\n  {}\n  {}",
                o.width,
                o.height,
                o.marks.shape,
                t.elapsed().as_secs_f64(),
                scan.display(),
                camera.display()
            );
        }
        return Ok(());
    }
    let r = synth(&o, &Bar::new(a.quiet))?;
    if !a.quiet {
        say!(
            "synth: {}x{} {} scan, GSD {} m, flying height {:.0} m, relief {:.0}–{:.0} m (steepest {:.0}°), {:.1} s",
            o.width,
            o.height,
            format!("{:?}", o.relief).to_lowercase(),
            r.gsd,
            r.flying_height,
            r.relief_range[0],
            r.relief_range[1],
            r.max_slope_deg,
            t.elapsed().as_secs_f64()
        );
        for p in [Some(&r.scan), Some(&r.camera), Some(&r.dem), r.truth.as_ref(), Some(&r.checkpoints)].into_iter().flatten() {
            say!("  {}", p.display());
        }
    }
    Ok(())
}

fn print_report(r: &Report) {
    let s = &r.stage_seconds;
    say!(
        "rectify: {}x{} px at {} {} ({}), {:.2} s wall, {:.1} MB/s in, {:.1} Mpx/s out, peak RSS {} MiB",
        r.grid.width,
        r.grid.height,
        r.grid.gsd,
        // Ground units: degrees in a geographic CRS.
        if r.geographic { "°" } else { "m" },
        r.crs,
        r.wall_seconds,
        r.input_mb_per_s,
        r.output_mpx_per_s,
        r.peak_rss_mib.map(|m| format!("{m:.0}")).unwrap_or_else(|| "?".into())
    );
    say!("  stages (busy s): setup {:.2}, dem {:.2}, gcm {:.2}, read {:.2}, resample {:.2}, encode {:.2}", s.setup, s.dem, s.gcm, s.read, s.resample, s.encode);
    let e = &r.accuracy_estimate;
    let bound = r.error_bound.map(|b| format!(", bound {b} px {}", if r.error_within { "held" } else { "MISSED" })).unwrap_or_default();
    say!(
        "  GCM (node spacing {} px) vs exact model (sampled): RMS {:.4} px, max {:.4} px over {} pixels{bound}",
        r.config.geometry.gcm.k,
        e.rms,
        e.max,
        e.count
    );
    if let Some(h) = &r.occlusion {
        say!("  occlusion: {} of {} imaged pixels hidden from the sensor ({:.2} %)", h.hidden_px, h.imaged_px, 100.0 * h.share);
    }
    if let Some(g) = &r.gcps {
        say!("  GCPs ({}): RMS {:.3} px before, {:.3} px after; {}", g.method, g.rms_before, g.rms_after, g.correction);
        for p in &g.points {
            say!("    {:<12} before ({:+.3}, {:+.3})  after ({:+.3}, {:+.3}) px", p.id, p.before[0], p.before[1], p.after[0], p.after[1]);
        }
    }
}

/// Where this process's peak resident memory passed `--memory` (`given`,
/// `budget` bytes): what to say. A job limit set from `--memory` (Slurm's
/// `--mem`, a pod's limit) may have had to take pages from the run; the
/// budget holds what the run allocates, not the program's code nor the
/// input pages it maps (resident too, 10–25 MiB on a drone frame).
fn past_budget(given: &str, budget: u64) -> Option<String> {
    let peak = super::os_memory::peak_rss_mib()?;
    let mib = budget as f64 / f64::from(1 << 20);
    (peak > mib).then(|| {
        format!(
            "the peak memory, {peak:.0} MiB, passed --memory {given} ({mib:.0} MiB): a job limit for such runs needs about {}M; a larger --memory lets the run plan for it",
            (peak * 1.1).ceil()
        )
    })
}

/// Every output is a GeoTIFF: a name that says another format (`.png`,
/// `.jpg`, `.vrt`) would mislead whoever opens it by its name. Said on
/// stderr, even with --quiet.
fn warn_if_not_tiff(output: &Path) {
    if let Some(w) = crate::io::tiff_out::named_as_other_format(output) {
        super::flag_names::warn(&w);
    }
}

/// `--threads` within this machine's cores (`at_once` jobs sharing them):
/// more threads than cores only cut the memory budget into slivers and
/// slow every step. Said on stderr, even with --quiet; 0 (every core) stays.
fn threads_within_cores(asked: usize, at_once: usize) -> (usize, Option<String>) {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    // Past the most taken it is refused by name when the options are checked.
    if asked * at_once <= cores || asked > RectifyOptions::MAX_THREADS {
        return (asked, None);
    }
    let fit = (cores / at_once).max(1);
    let jobs = if at_once > 1 { format!(" for each of {at_once} jobs at once") } else { String::new() };
    let w = format!("--threads {asked}{jobs} is more than the {cores} cores here: running {fit} a job");
    super::flag_names::warn(&w);
    (fit, Some(w))
}

fn run_rectify(a: &RectifyArgs, signals: &Signals) -> Result<()> {
    let mut opts = a.options()?;
    let dem = match &opts.inputs.dem {
        DemSource::File(p) => Some(p.as_path()),
        _ => None,
    };
    inputs_exist(&[
        ("--image", Some(opts.inputs.image.as_path())),
        (if a.sensor.rpc.is_some() { "--rpc" } else { "--camera" }, Some(opts.inputs.camera.as_path()).filter(|c| *c != Path::new("exif"))),
        ("--exterior", a.sensor.exterior.as_deref()),
        ("--dem", dem),
        ("--like", opts.grid.like.as_deref()),
        ("--gcps", opts.inputs.gcps.as_ref().map(|g| g.file.as_path())),
    ])?;
    let json: Vec<Role> = a.json.iter().map(|j| Role::new("report", j)).collect();
    opts.check_outputs(&json)?;
    for j in &json {
        check_writable(*j)?;
    }
    let too_many;
    (opts.resources.threads, too_many) = threads_within_cores(opts.resources.threads, 1);
    let mut report = rectify(&opts, &Bar::new(a.quiet), &signals.cancel)?;
    report.warnings.extend(too_many);
    if let Some(w) = past_budget(&a.memory, opts.resources.memory) {
        super::flag_names::warn(&w);
        report.warnings.push(w);
    }
    if let Some(j) = &a.json {
        write_report(j, &serde_json::to_string_pretty(&report)?)?;
    }
    if !a.quiet {
        print_report(&report);
    }
    Ok(())
}

/// An input that is not there, named with the option that gives it
/// (reading it would name the file alone).
fn inputs_exist(inputs: &[(&str, Option<&Path>)]) -> Result<()> {
    for (flag, path) in inputs {
        if let Some(p) = path.filter(|p| std::fs::symlink_metadata(p).is_err()) {
            // Tiles listed on the command line are a common first guess.
            let tiles = if *flag == "--dem" && p.to_string_lossy().contains(',') {
                " (several tiles are one --dem: a GDAL VRT of them, a folder, or a text file naming one a line)"
            } else {
                ""
            };
            return Err(crate::Error::Named(format!("{flag} {}: no such file or folder{tiles}", p.display())).into());
        }
    }
    Ok(())
}

/// The scene's inputs from --scene or the individual flags.
fn scene_inputs(a: &AccuracyArgs) -> Result<(PathBuf, PathBuf, PathBuf)> {
    match &a.scene {
        Some(d) => Ok((d.join("scan.tif"), d.join("camera.toml"), d.join("dem.tif"))),
        None => Ok((
            a.image.clone().ok_or_else(|| usage("give --scene DIR or --image, --camera, --dem".into()))?,
            a.camera.clone().ok_or_else(|| usage("--camera missing".into()))?,
            a.dem.clone().ok_or_else(|| usage("--dem missing".into()))?,
        )),
    }
}

fn run_accuracy(a: &AccuracyArgs) -> Result<()> {
    use crate::Error;
    let max_k = RectifyOptions::MAX_SPARSITY;
    if let Some(k) = a.sparsity.iter().find(|&&k| k == 0 || k > max_k) {
        return Err(Error::setting("sparsity", format!("{k} is not 1 to {max_k}")).into());
    }
    if a.map_sparsity == 0 || a.map_sparsity > max_k {
        return Err(Error::setting("map_sparsity", format!("{} is not 1 to {max_k}", a.map_sparsity)).into());
    }
    if a.step == 0 {
        return Err(Error::setting("step", "0 is not a step: 1 evaluates every pixel").into());
    }
    if let Some(e) = a.max_error.iter().find(|e| !(**e > 0.0 && e.is_finite())) {
        return Err(Error::setting("max_error", format!("{e} must be a positive number")).into());
    }
    if let Some(m) = a.max_slope.filter(|m| !(0.0..=90.0).contains(m)) {
        return Err(Error::setting("max_slope", format!("{m} is not a slope from 0 to 90°")).into());
    }
    let (image, camera, dem_path) = scene_inputs(a)?;
    {
        let checkpoints = a.scene.as_ref().map(|d| d.join("checkpoints.csv"));
        let mut ins = vec![Role::new("image", &image), Role::new("camera file", &camera), Role::new("DEM", &dem_path)];
        ins.extend(checkpoints.as_deref().map(|c| Role::new("checkpoints", c)));
        let outs: Vec<Role> = [("error map", &a.error_map), ("error picture", &a.png), ("GCM picture", &a.gcm_png), ("table", &a.json)]
            .into_iter()
            .filter_map(|(what, p)| p.as_deref().map(|p| Role::new(what, p)))
            .collect();
        for o in &outs {
            check_writable(*o)?;
        }
        check_outputs(&ins, &outs)?;
    }
    let cam = Camera::read(&camera)?;
    let (w, h) = match &a.size {
        Some(sz) => parse_size("size", sz)?,
        None => {
            let info = SourceImage::info_of(&image)?;
            (info.width, info.height)
        }
    };
    let dem = Dem::open(&dem_path, &cam.crs)?;
    let z0 = dem.mean_height().unwrap_or_else(|| cam.height_hint());
    let gsd = footprint_gsd(cam.model(), &dem, w, h, z0)?;
    let (grid, _) = auto_grid(cam.model(), &dem, w, h, z0, crate::geom::Gsd::square(gsd))?;
    let area = grid.bounds();
    let plane =
        if a.trend == Trend::Mean { dem.mean_plane(area) } else { dem.trend_plane(area) }.ok_or_else(|| anyhow!("no DEM heights in the output area"))?;
    let approx = Approx::new(cam.model(), &grid, plane).ok_or_else(|| anyhow!("plane behind the camera"))?;
    let t = Transform::new(cam.model(), &dem, grid).with_scan((w, h));
    say!(
        "accuracy of A + GCM against the exact model: {}x{} output at {} m, every {} row/column, trend {}{}",
        grid.width,
        grid.height,
        gsd,
        a.step,
        format!("{:?}", a.trend).to_lowercase(),
        a.max_slope.map(|m| format!(", only where the slope is at most {m}°")).unwrap_or_default()
    );
    say!(
        "{:>4} {:>9} {:>9} | {:>9} {:>9} {:>9} | {:>6} {:>6} {:>6} {:>6} | {:>8} {:>8} {:>9}",
        "k",
        "mode",
        "bound",
        "mean px",
        "RMS px",
        "max px",
        "<0.1",
        "<0.25",
        "<0.5",
        "<1",
        "prep s",
        "fill s",
        "refined%"
    );
    let mut rows = Vec::new();
    let mut cases: Vec<(u32, CorrectionMode, Option<f64>)> = Vec::new();
    for &k in &a.sparsity {
        cases.push((k, CorrectionMode::Cell, None));
        cases.push((k, CorrectionMode::Bilinear, None));
    }
    let kmax = a.sparsity.iter().copied().max().unwrap_or(16);
    for &e in &a.max_error {
        cases.push((kmax, CorrectionMode::Bilinear, Some(e)));
    }
    for (k, mode, bound) in cases {
        let gcm = Gcm::new(&t, approx, GcmSpec { k, mode, max_error: bound });
        let ev = evaluate_where(&gcm, a.step, a.max_slope, Some((w, h)), None);
        let e = &ev.errors;
        let refined = 100.0 * ev.gcm.refined_cells as f64 / ev.gcm.cells.max(1) as f64;
        say!(
            "{:>4} {:>9} {:>9} | {:>9.4} {:>9.4} {:>9.4} | {:>6.1} {:>6.1} {:>6.1} {:>6.1} | {:>8.3} {:>8.3} {:>9.1}",
            k,
            format!("{mode:?}").to_lowercase(),
            bound.map(|b| format!("{b}")).unwrap_or_else(|| "-".into()),
            e.mean_abs,
            e.rms,
            e.max,
            e.pct_under[0],
            e.pct_under[1],
            e.pct_under[2],
            e.pct_under[3],
            ev.prepare.as_secs_f64(),
            ev.fill.as_secs_f64(),
            refined
        );
        // Cells the GCM cannot span (a spacing past the grid, A behind the
        // camera) are worked out exactly: there the table compares the
        // exact model with itself, which it must say.
        if ev.gcm.exact_pixels > 0 {
            let share = 100.0 * ev.gcm.exact_pixels as f64 / (grid.width as f64 * grid.height as f64);
            say!(
                "     k = {k} {}: {} pixels ({share:.1} % of the grid) by the exact model itself, counted as no error",
                format!("{mode:?}").to_lowercase(),
                ev.gcm.exact_pixels
            );
        }
        rows.push(serde_json::json!({"k": k, "mode": mode, "max_error": bound, "errors": e, "gcm": ev.gcm,
            "prepare_s": ev.prepare.as_secs_f64(), "fill_s": ev.fill.as_secs_f64()}));
    }
    let cp_path = a.scene.as_ref().map(|d| d.join("checkpoints.csv")).filter(|p| p.exists());
    if let Some(cp_path) = cp_path {
        let cps = crate::study::accuracy::read_checkpoints(&cp_path)?;
        let gcm = Gcm::new(&t, approx, GcmSpec { k: a.map_sparsity, mode: CorrectionMode::Bilinear, max_error: None });
        let offs = crate::study::accuracy::checkpoint_offsets(&gcm, &cps);
        let n = offs.len().max(1) as f64;
        let rms = (offs.iter().map(|(_, d)| d[0] * d[0] + d[1] * d[1]).sum::<f64>() / n).sqrt();
        let max = offs.iter().map(|(_, d)| d[0].hypot(d[1])).fold(0.0, f64::max);
        say!(
            "checkpoints (as Beloshapkin's Table 2), k = {} bilinear: {} points, RMS {:.4} px = {:.4} m, max {:.4} px",
            a.map_sparsity,
            offs.len(),
            rms,
            rms * grid.gsd.x,
            max
        );
        rows.push(serde_json::json!({"checkpoints": offs.len(), "k": a.map_sparsity, "rms_px": rms, "rms_m": rms * grid.gsd.x, "max_px": max}));
    }
    if a.error_map.is_some() || a.png.is_some() {
        let gcm = Gcm::new(&t, approx, GcmSpec { k: a.map_sparsity, mode: CorrectionMode::Bilinear, max_error: None });
        let mut map = Vec::new();
        // Only where the scan is (NaN, the map's nodata, elsewhere).
        evaluate_where(&gcm, a.step, None, Some((w, h)), Some(&mut map));
        let (mw, mh) = (grid.width.div_ceil(a.step), grid.height.div_ceil(a.step));
        if let Some(p) = &a.error_map {
            crate::study::maps::write_error_map(p, &map, mw, mh, &grid, a.step, &cam.crs)?;
        }
        if let Some(p) = &a.png {
            crate::study::maps::write_error_png(p, &map, mw, mh)?;
        }
    }
    if let Some(p) = &a.gcm_png {
        let gcm = Gcm::new(&t, approx, GcmSpec { k: a.map_sparsity, mode: CorrectionMode::Cell, max_error: None });
        crate::study::maps::write_gcm_png(p, &gcm)?;
    }
    if let Some(j) = &a.json {
        write_file(j, super::flag_names::with_flags(&serde_json::to_string_pretty(&serde_json::json!({"grid": grid, "rows": rows}))?).as_bytes())?;
    }
    Ok(())
}

fn run_rpc_grid(a: &super::cli::RpcGridArgs) -> Result<()> {
    use crate::camera::file::Sensor;
    use crate::camera::RpcCamera;
    use crate::geodesy::GroundCrs;
    use crate::rpcgrid;
    let (origin, model) = a.sensor.model()?;
    let vrt_path = a.output.with_extension("vrt");
    {
        let mut ins = vec![Role::new("image", &a.sensor.image), Role::new("sensor model", &origin)];
        ins.extend(a.dem.as_deref().map(|d| Role::new("DEM", d)));
        ins.extend(a.sensor.geoid.as_deref().map(|g| Role::new("geoid grid", g)));
        let mut outs = vec![Role::new("grid", &a.output), Role::new("VRT", &vrt_path)];
        outs.extend(a.json.as_deref().map(|j| Role::new("table", j)));
        for o in &outs {
            check_writable(*o)?;
        }
        check_outputs(&ins, &outs)?;
    }
    let cam = crate::scene::camera::load(&model, &a.sensor.image, &origin, None)?;
    let Sensor::Rpc(r) = &cam.sensor else {
        return Err(crate::error::Error::unsupported(&origin, "rpc-grid needs an RPC model (camera.model = \"rpc\")").into());
    };
    // The grid is in longitude/latitude: the model and the DEM in EPSG:4326.
    let model = RpcCamera::new(r.rpc.clone(), GroundCrs::from_epsg(4326).map_err(|m| anyhow!(m))?, r.geoid.clone());
    let dem = match (&a.dem, a.height) {
        (Some(p), _) => Dem::open(p, &crate::geodesy::Crs::wgs84())?,
        (None, Some(h)) if h.is_finite() => Dem::flat(h),
        _ => return Err(usage("give --dem or a finite --height".to_string())),
    };
    let info = SourceImage::info_of(&a.sensor.image)?;
    let (w, h) = (info.width, info.height);
    let z0 = dem.mean_height().unwrap_or_else(|| model.height_hint());
    let on_dem = |e: crate::error::Error| match (e, &a.dem) {
        (crate::error::Error::Geometry(m), Some(d)) => crate::error::Error::format(d, m),
        (e, _) => e,
    };
    let grid = rpcgrid::build(&model, &dem, w, h, a.step, z0).map_err(on_dem)?;
    grid.write(&a.output)?;
    let data_type = match info.sample {
        crate::io::source::SampleType::U8 => "Byte",
        crate::io::source::SampleType::U16 => "UInt16",
        crate::io::source::SampleType::F32 => "Float32",
    };
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let vrt = rpcgrid::geolocation_vrt(&abs(&a.sensor.image), &abs(&a.output), w, h, info.bands, data_type, a.step);
    write_file(&vrt_path, vrt.as_bytes())?;
    say!(
        "rpc-grid: {}x{} nodes every {} px for {w}x{h} px; {} nodes failed the {} px back-check, {} corrected",
        grid.cols,
        grid.rows,
        a.step,
        grid.bad,
        rpcgrid::BACK_CHECK_PX,
        grid.corrected
    );
    say!("  {}\n  {} (gdalwarp -geoloc {} …)", a.output.display(), vrt_path.display(), vrt_path.display());
    if let Some(steps) = &a.accuracy {
        let steps: Vec<u32> = steps
            .split(',')
            .map(|s| s.trim().parse::<u32>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| usage(format!("--accuracy '{steps}' is not a list of steps")))?;
        say!("accuracy of the grid against the exact solve, every {} px:", a.sample);
        say!("{:>5} | {:>9} {:>9} {:>9} | {:>6} {:>6} {:>6} {:>6} | {:>9}", "step", "mean m", "RMS m", "max m", "<0.5", "<1", "<2.5", "<5", "corrected");
        let mut rows = Vec::new();
        for s in steps {
            let g = rpcgrid::build(&model, &dem, w, h, s, z0).map_err(on_dem)?;
            let acc = crate::study::rpc_grid::accuracy(&g, &model, &dem, w, h, a.sample, z0);
            say!(
                "{:>5} | {:>9.4} {:>9.4} {:>9.4} | {:>6.1} {:>6.1} {:>6.1} {:>6.1} | {:>9}",
                s,
                acc.mean_abs_m,
                acc.rms_m,
                acc.max_m,
                acc.pct_under[0],
                acc.pct_under[1],
                acc.pct_under[2],
                acc.pct_under[3],
                acc.corrected_nodes
            );
            rows.push(acc);
        }
        if let Some(j) = &a.json {
            write_file(j, super::flag_names::with_flags(&serde_json::to_string_pretty(&rows)?).as_bytes())?;
        }
    }
    Ok(())
}

fn run_demo(a: &DemoArgs, signals: &Signals) -> Result<()> {
    let tmp;
    let dir: &Path = match &a.keep {
        Some(d) => d,
        None => {
            tmp = tempfile::tempdir()?;
            tmp.path()
        }
    };
    let (width, height) = parse_size("size", &a.size)?;
    let opts = SynthOptions { out: dir.join("scene"), width, height, kappa_deg: 30.0, ..Default::default() };
    // Refused before the work is announced.
    crate::synth::check(&opts)?;
    say!("demo: generating a {width}x{height} hilly film scene (swing 30°) in {}", opts.out.display());
    let t = std::time::Instant::now();
    let scene = synth(&opts, &Bar::new(a.quiet))?;
    say!("  synth: {:.1} s, GSD {} m, flying height {:.0} m", t.elapsed().as_secs_f64(), scene.gsd, scene.flying_height);
    let out = dir.join("ortho.tif");
    let opts = RectifyOptions::new(scene.scan.clone(), scene.camera.clone(), DemSource::File(scene.dem.clone()), out.clone());
    let report = rectify(&opts, &Bar::new(a.quiet), &signals.cancel)?;
    print_report(&report);
    let truth = scene.truth.ok_or_else(|| anyhow!("the demo scene has no truth image"))?;
    let c = compare_files(&out, &truth, 0.0, 48)?;
    say!(
        "  vs truth: mean |difference| {:.2} grey levels over {} pixels; offset by correlation in {} windows: mean {:.3} px, 95% under {:.3} px",
        c.mean_abs_diff,
        c.pixels,
        c.windows,
        c.mean_shift,
        c.p95_shift
    );
    say!("  files: {}", if a.keep.is_some() { dir.display().to_string() } else { "(temporary, removed; use --keep DIR)".into() });
    Ok(())
}

/// "N images", or "N of M images" where the mosaic takes nothing of some.
fn taken_of(images: &[crate::mosaic::ImageReport]) -> String {
    let taken = images.iter().filter(|i| i.share > 0.0).count();
    if taken == images.len() {
        format!("{taken} images")
    } else {
        format!("{taken} of {} images", images.len())
    }
}
