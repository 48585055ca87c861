//! `mosaic`: one seamless orthomosaic of a whole block, straight from the
//! scans (the digital photoplan of the photogrammetry textbook's §9.10.5,
//! made by rectifying all overlapping scans directly): the plan on coarse cells (`plan.rs`), radiometric balancing
//! (`balance.rs`), seamlines on least-cost paths (`seams.rs`), the blend
//! across them (`weights.rs`), and the render, streamed band by band from
//! the scans through `rectify`'s own stages (`render.rs`). The seamlines
//! can be written as GeoJSON polygons (`seamlines.rs`).

pub mod agreement;
pub mod balance;
pub mod box_store;
pub mod label_runs;
pub mod normal;
pub mod plan;
pub mod plan_file;
pub mod render;
pub mod resume;
pub mod seamlines;
pub mod seams;
pub mod strip_heights;
pub mod turns;
pub mod weights;

use crate::assemble::AssembleOptions;
use crate::error::{Error, Result};
use crate::geodesy::Crs;
use crate::geom::Gsd;
use crate::io::overwrite::{check_outputs, check_writable, Role};
use crate::io::tiff_out::{Chunking, Compression, GeoTags, OutputSpec, PendingFile};
use crate::options::{BigTiff, Nodata, Occlusion, Overviews, RectifyOptions};
use crate::pipeline::band_writer::{write_bands, BandWriting};
use crate::progress::{Cancel, Progress, Task};
use balance::{Balance, Correction};
use plan::{Plan, PlanSettings, NONE};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;
use strip_heights::StripHeights;

/// What `mosaic` is asked to do (serde: the same object read back).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub struct MosaicOptions {
    pub manifest: PathBuf,
    /// The mosaic, or a piece of it (`window`); `None`: the plan only.
    pub output: Option<PathBuf>,
    /// Write the plan (seams, gains) for shards here.
    pub plan_out: Option<PathBuf>,
    /// Take the seams and gains from this plan instead of finding them.
    pub plan_in: Option<PathBuf>,
    /// Render only these tiles of the mosaic: first column, first row,
    /// width, height (a piece for `assemble`).
    pub window: Option<[u32; 4]>,
    pub gsd: Option<Gsd>,
    pub bounds: Option<[f64; 4]>,
    #[serde(with = "crate::geodesy::optional_crs_definition")]
    pub crs: Option<Crs>,
    /// The grid (CRS, origin, pixel size, size) of this raster, instead of
    /// `gsd` and `bounds`.
    pub like: Option<PathBuf>,
    pub balance: Balance,
    /// Move the first partition's seams onto least-cost paths.
    pub least_cost: bool,
    /// Width of the ramp across a seam, output pixels (0: a sharp cut).
    pub blend: f64,
    pub seamlines_out: Option<PathBuf>,
    /// Edited seamlines to honour instead of finding them.
    pub seamlines_in: Option<PathBuf>,
    /// Memory budget, bytes.
    pub memory: u64,
    pub threads: usize,
    /// Write the Cloud-Optimized layout (else as the manifest says).
    pub cog: Option<bool>,
    /// Overviews (else as the manifest says).
    pub overviews: Option<crate::options::Overviews>,
    /// The tiles' codec (else as the manifest says): `--resume-dir`'s
    /// pieces of a lossy mosaic are coded losslessly, then coded once in
    /// the end.
    pub compress: Option<crate::io::tiff_out::Compression>,
    /// Remake an output whose record says it is current.
    pub force: bool,
    /// Occluded ground (a true orthomosaic), for every image (else as
    /// each job says).
    pub occlusion: Option<crate::options::Occlusion>,
    pub sync: bool,
    /// Where the caller writes the run's report: checked with the outputs
    /// (never one of the inputs), not written here.
    pub report: Option<PathBuf>,
}

/// One image's part in the mosaic.
#[derive(Clone, Debug, Serialize)]
pub struct ImageReport {
    pub name: String,
    pub image: PathBuf,
    /// Share of the mosaic's covered area taken from it.
    pub share: f64,
    pub correction: Correction,
    /// The grid it was rectified on (tiles of the mosaic's), where any.
    pub grid: Option<crate::geom::OutputGrid>,
    /// Under occlusion: of the pixels it was made over, the share it does
    /// not see.
    pub hidden_share: Option<f64>,
}

/// Under occlusion: the mosaic's ground that no image sees.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Unseen {
    /// Pixels some image images.
    pub covered_px: u64,
    /// Of them, pixels every image that images them has hidden.
    pub unseen_px: u64,
    /// `unseen_px / covered_px`.
    pub share: f64,
    /// Their ground area, ground units squared.
    pub area: f64,
}

impl Unseen {
    fn new(covered_px: u64, unseen_px: u64, gsd: Gsd) -> Unseen {
        Unseen { covered_px, unseen_px, share: unseen_px as f64 / covered_px.max(1) as f64, area: unseen_px as f64 * gsd.area() }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct PhaseSeconds {
    pub plan: f64,
    pub balance: f64,
    pub seams: f64,
    pub render: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct MosaicReport {
    /// The file written, where one was.
    pub output: Option<PathBuf>,
    /// The output was current (made for these inputs and settings): left as it was.
    pub skipped: bool,
    /// The tiles rendered (all, or the window).
    pub window: [u32; 4],
    /// The tiles' side, pixels (windows count in tiles).
    pub tile: u32,
    pub width: u32,
    pub height: u32,
    pub gsd: Gsd,
    pub crs: String,
    /// The plan's cell side, output pixels.
    pub cell_px: u32,
    /// Share of the mosaic's area some image sees (of the plan's cells).
    pub coverage: f64,
    /// Of the pixels written, how many have a value (GDAL's
    /// `STATISTICS_VALID_PERCENT`), and of how many; none where nothing
    /// was rendered (or pieces were taken as they were).
    pub pixels_with_value: Option<[u64; 2]>,
    pub balance: Balance,
    pub blend_px: f64,
    pub seams: seams::SeamStats,
    /// Total length of the seamlines, ground units (of the CRS: degrees
    /// in a geographic one).
    pub seam_length: f64,
    /// The same in output pixels, whatever the CRS.
    pub seam_length_px: u64,
    /// What honouring edited seamlines (`--seamlines`) changed, where given.
    pub edited_seams: Option<seamlines::EditedSeams>,
    pub images: Vec<ImageReport>,
    /// Under occlusion: what no image sees.
    pub unseen: Option<Unseen>,
    pub seconds: PhaseSeconds,
    pub wall_seconds: f64,
    pub peak_rss_mib: Option<f64>,
    pub output_bytes: u64,
    /// With `--resume-dir`: the pieces a stopped run had finished, taken as
    /// they were, and the pieces in all.
    pub pieces_reused: Option<[usize; 2]>,
    /// Strips of tile columns the render was made in, then assembled: 1
    /// where the memory held the mosaic's width at once; 0 where nothing
    /// was rendered (the plan only, or a current output left as it was);
    /// under `--resume-dir`, the most any one piece took.
    pub strips: usize,
}

/// `o` with the grid the manifest gives (`gsd`, `bounds`, `crs`, `like`)
/// where the command line gives none: one grid for all the images, so
/// jobs that differ are refused. An alpha band is refused (a mosaic
/// marks its empty pixels with a mask, or `nodata = V`).
pub(crate) fn with_manifest_settings(o: &MosaicOptions, jobs: &[crate::batch::manifest::Job]) -> Result<MosaicOptions> {
    // (Compared as written: a NaN nodata is one value.)
    fn one<T: std::fmt::Debug>(o: &MosaicOptions, key: &str, mut each: impl Iterator<Item = T>) -> Result<T> {
        let first = each.next().ok_or_else(|| Error::format(&o.manifest, "no image"))?;
        match each.all(|v| format!("{v:?}") == format!("{first:?}")) {
            true => Ok(first),
            false => Err(Error::config(&o.manifest, key, format!("differs between images; a mosaic has one {key}: give it once, in [defaults]"))),
        }
    }
    let alpha: Vec<&str> = jobs.iter().filter(|j| j.config.pixels.alpha).map(|j| j.name.as_str()).collect();
    if !alpha.is_empty() {
        let whose = if alpha.len() == jobs.len() { "every job (in [defaults]?)".to_string() } else { format!("job {}", alpha.join(", ")) };
        return Err(Error::config(
            &o.manifest,
            "alpha",
            format!("{whose}: a mosaic marks pixels without a value with an internal mask (or nodata = V); drop alpha"),
        ));
    }
    one(o, "nodata", jobs.iter().map(|j| j.config.pixels.nodata))?;
    let mut o = o.clone();
    if o.gsd.is_none() && o.like.is_none() {
        o.gsd = one(&o, "gsd", jobs.iter().map(|j| j.config.grid.gsd))?;
    }
    if o.bounds.is_none() && o.like.is_none() {
        o.bounds = one(&o, "bounds", jobs.iter().map(|j| j.config.grid.bounds))?;
    }
    if o.crs.is_none() {
        o.crs = one(&o, "crs", jobs.iter().map(|j| j.config.grid.crs.clone()))?;
    }
    if o.like.is_none() && o.gsd.is_none() && o.bounds.is_none() {
        o.like = one(&o, "like", jobs.iter().map(|j| j.config.grid.like.clone()))?;
    }
    Ok(o)
}

/// Refuses a run that would write over anything it reads, or write two of
/// its files (records of finished outputs included) to one path.
pub(crate) fn check_mosaic_outputs(o: &MosaicOptions, jobs: &[crate::batch::manifest::Job]) -> Result<()> {
    let (inputs, _) = crate::batch::manifest::files(jobs);
    let mut ins: Vec<Role> = vec![Role::new("manifest", &o.manifest)];
    if let Some(s) = &o.seamlines_in {
        ins.push(Role::new("seamlines", s));
    }
    ins.extend(inputs.iter().map(|(w, p)| Role::new(w, p)));
    if let Some(p) = &o.plan_in {
        ins.push(Role::new("plan", p));
    }
    if let Some(p) = &o.like {
        ins.push(Role::new("reference grid", p));
    }
    // A finished output and a plan each get a record beside them.
    let records: Vec<std::path::PathBuf> = o.output.iter().chain(&o.plan_out).map(|p| crate::batch::sidecar(p)).collect();
    let mut outs: Vec<Role> = o.output.iter().map(|p| Role::new("output", p)).collect();
    for (what, path) in [("seamlines", &o.seamlines_out), ("plan", &o.plan_out), ("report", &o.report)] {
        if let Some(p) = path {
            outs.push(Role::new(what, p));
        }
    }
    for out in &outs {
        check_writable(*out)?;
    }
    outs.extend(records.iter().map(|p| Role::new("record of a finished output", p)));
    check_outputs(&ins, &outs)
}

/// Blends wider than this, pixels, are doubted (the default is 8).
const MOST_BLEND_PX: f64 = 256.0;

/// Makes the mosaic of the manifest's images (see the module doc).
pub fn mosaic(o: &MosaicOptions, progress: &dyn Progress, cancel: &Cancel) -> Result<MosaicReport> {
    // The plan and each image's set-up (per strip, too) meet the same
    // cameras and DEMs: each warning said once.
    let once = crate::progress::Recording::once(progress);
    let progress: &dyn Progress = &once;
    let wall = Instant::now();
    if !(o.blend >= 0.0 && o.blend.is_finite()) {
        return Err(Error::setting("blend", format!("{} is not a width in pixels (0 or more)", o.blend)));
    }
    if o.threads > RectifyOptions::MAX_THREADS {
        return Err(Error::setting("threads", format!("{} is more than {} (0 takes every core)", o.threads, RectifyOptions::MAX_THREADS)));
    }
    if o.blend > MOST_BLEND_PX {
        progress.warn(&format!(
            "‹blend› {} px: a ramp that wide mixes two images over their whole overlap (anything that moved or stands up shows twice); a few pixels hide a seam",
            o.blend
        ));
    }
    let jobs = crate::batch::manifest::load(&o.manifest).map_err(|e| e.into_error())?;
    if let Some(bad) = jobs.iter().find_map(|j| j.problem.clone()) {
        // It names the manifest and line already.
        return Err(Error::Named(bad));
    }
    if o.output.is_none() && o.plan_out.is_none() {
        return Err(Error::Usage("mosaic: give ‹output› (the mosaic or a piece) or ‹plan_out› (the plan)".into()));
    }
    let given = o;
    let o = &with_manifest_settings(o, &jobs)?;
    // Errors of a setting the manifest gave name it there, not as a flag.
    let from_manifest = |e: Error| match e {
        Error::Setting { setting, msg } if manifest_gave(given, o, setting) => Error::config(&o.manifest, setting, msg),
        e => e,
    };
    (|| -> Result<MosaicReport> {
        check_mosaic_outputs(o, &jobs)?;
        // Said once the output is known to be no input (else refused alone).
        if let Some(w) = o.output.as_deref().and_then(crate::io::tiff_out::named_as_other_format) {
            progress.warn(&w);
        }
        // A rerun (a restarted shard) leaves a current output as it is.
        let key = run_key(o, &jobs);
        let source = source_key(o, &jobs);
        // (Not where a plan or seamlines are asked for: they are made anew.)
        if let (Some(out), None, None, false) = (&o.output, &o.plan_out, &o.seamlines_out, o.force) {
            if crate::batch::output_is_current(out, &key) {
                return Ok(MosaicReport::skipped(out));
            }
        }
        let pending = o.output.as_deref().map(PendingFile::create).transpose()?;
        let first = jobs.first().map(|j| j.config.clone()).ok_or_else(|| Error::format(&o.manifest, "no image"))?;

        // A shard that takes a plan needs only where each image sees.
        let like = o.like.as_deref().map(crate::scene::grid::reference_grid).transpose()?;
        let crs = match (&o.crs, &like) {
            (Some(c), Some((_, l))) if c != l => {
                let path = o.like.as_deref().unwrap_or(Path::new("")).display();
                return Err(Error::setting("crs", format!("{c}, but the reference grid {path} is in {l}: give one of the two")));
            }
            (Some(c), _) => Some(c.clone()),
            (None, l) => l.as_ref().map(|(_, c)| c.clone()),
        };
        let cell = o.plan_in.as_deref().map(plan_file::cell_of).transpose()?;
        let settings = PlanSettings { gsd: o.gsd, bounds: o.bounds, crs, grid: like.map(|(g, _)| g), memory: o.memory, cell, thumbnails: o.plan_in.is_none() };
        let mut plan = Plan::make(jobs.into_iter().map(|j| (j.name, j.config)).collect(), &settings, progress)?;
        let t_plan = wall.elapsed().as_secs_f64();
        progress.memory_freed();
        if cancel.is_cancelled() {
            return Err(Error::Cancelled);
        }
        let t = Instant::now();
        let from_plan = o.plan_in.as_deref().map(|p| plan_file::read(&mut plan, &source, p)).transpose()?;
        let pairs = balance::overlaps(&plan)?;
        for doubt in agreement::doubted(&plan, &pairs) {
            progress.warn(&doubt);
        }
        let corrections = match &from_plan {
            Some(c) => c.clone(),
            None => balance::solve(&plan, o.balance, &pairs)?,
        };
        // Sums over every pair of images: not for the render to hold.
        drop(pairs);
        let t_balance = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let edges = seams::height_edges(&plan);
        // The corridor: a sixth of the images' median footprint side.
        let corridor = {
            let mut sides: Vec<usize> = plan.images.iter().map(|i| (i.cells[2] - i.cells[0]).min(i.cells[3] - i.cells[1])).collect();
            sides.sort_unstable();
            (sides[sides.len() / 2] / 6).clamp(4, 256)
        };
        // The plan's seams are taken as they are; else least-cost ones, and
        // over them an edited file's (the cells no feature takes keep
        // their cut, as --seamlines-out wrote it).
        let seam_stats = match from_plan.is_none() && o.least_cost {
            true => seams::refine(&mut plan, &corrections, corridor, &edges)?,
            false => seams::SeamStats::default(),
        };
        let edited_seams = match (&o.seamlines_in, &from_plan) {
            (Some(path), None) => {
                let edited = seamlines::read(&mut plan, path)?;
                for doubt in &edited.doubts {
                    progress.warn(&format!("{}: {doubt}", path.display()));
                }
                if edited.cells_kept > 0 || edited.cells_overlapping > 0 {
                    progress.warn(&format!(
                        "{}: {} cells kept their planned image (given to an image that does not see them, or to none), {} lay in two features (the first one's)",
                        path.display(),
                        edited.cells_kept,
                        edited.cells_overlapping
                    ));
                }
                Some(edited)
            }
            _ => None,
        };
        let t_seams = t.elapsed().as_secs_f64();
        // Written now (the render lets the cells' labels go), published
        // with the mosaic: a run stopped or failed leaves none of them.
        let mut side_outputs = Vec::new();
        if let Some(path) = &o.seamlines_out {
            side_outputs.extend(seamlines::write(&plan, path)?);
        }
        if let Some(path) = &o.plan_out {
            side_outputs.extend(plan_file::write(&plan, &corrections, &source, path)?);
        }
        // Pieces join only where their seams and balance are one: made with
        // another --balance, seam method, edited seams or plan, their
        // images would meet in a step at the join.
        let source = plan_source(&source, &plan, &corrections);
        let weights = weights::Weights::new(&plan, o.blend, &edges);
        drop(edges);
        let grid = plan.grid;
        let (tx_all, ty_all) = (grid.width.div_ceil(first.file.tile), grid.height.div_ceil(first.file.tile));
        let window = crate::geom::cut_window(o.window.unwrap_or([0, 0, tx_all, ty_all]), (tx_all, ty_all))
            .map_err(|w| Error::setting("window", format!("{w} does not start inside the mosaic's {tx_all}×{ty_all} tiles")))?;

        // The output: the first job's format settings, the plan's grid.
        let tile = first.file.tile;
        let layout = (o.overviews.unwrap_or(first.file.overviews), o.cog.unwrap_or(first.file.cog));
        let spec = piece_spec(&plan, &first, window, layout, o.compress)?;

        // The report's counts, while the plan has its labels cell by cell.
        let cells = CellCounts::of(&plan);
        let covered = cells.of_image.iter().sum::<usize>();
        // The render (none when only the plan is asked for).
        let mut works: Vec<render::ImageWork> = Vec::new();
        let mut t_render = 0.0;
        let mut strips_made = 0;
        let mut pixels_with_value = None;
        // Under occlusion: each image's pixels imaged and hidden, and the
        // mosaic's pixels no image sees.
        let mut hidden = vec![(0u64, 0u64); plan.images.len()];
        let mut unseen = None;
        if let (Some(out), Some(pending)) = (o.output.as_deref(), pending) {
            let threads = match o.threads {
                0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
                n => n,
            };
            let true_ortho = plan.images.iter().any(|im| o.occlusion.unwrap_or(im.opts.pixels.occlusion) != Occlusion::None);
            // Where an image may not see the ground, every image that sees the
            // cell is made there, so that another can fill what it hides.
            let prone = true_ortho.then(|| render::occlusion_prone(&plan));
            plan.forget_for_render()?;
            let opts_of = |i: usize| {
                let own = &plan.images[i].opts;
                let mut opts = own.clone();
                (opts.resources.threads, opts.file.sync) = (threads, false);
                opts.pixels.occlusion = o.occlusion.unwrap_or(own.pixels.occlusion);
                opts
            };
            works = within(&render::work(&plan, &weights, tile, prone.as_deref(), opts_of), window);
            progress.memory_freed();

            let t = Instant::now();
            let (fill, _) = fill_of(plan.images[0].sample, first.pixels.nodata)?;
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| Error::setting("threads", e.to_string()))?;
            let compose = render::Compose {
                plan: &plan,
                weights: &weights,
                corrections: &corrections,
                tile,
                bands: plan.images[0].bands as usize,
                fill,
                unseen: Default::default(),
                covered: Default::default(),
            };
            // A piece also names the whole it is a piece of.
            let piece_source = match o.window {
                Some(_) => {
                    crate::io::geotiff::piece_source(&source, &plan.grid, &crate::assemble::layout_record(layout.0, first.file.overview_resampling, layout.1))
                }
                None => source.clone(),
            };
            let pieces = PieceRender {
                plan: &plan,
                compose: &compose,
                works: &works,
                threads,
                pool: &pool,
                fill,
                first: &first,
                progress,
                cancel,
                source: &piece_source,
                memory: o.memory,
            };
            // Strips of tile columns, as wide as the memory holds (one, the
            // whole width, where it holds that), each band of each made in turn
            // into the one file, laid out as a band-by-band run's.
            let strips = column_strips(&plan, weights.bytes(), &works, &spec, window, o.memory)?;
            strips_made = strips.len();
            let stats = pieces.render(window, &strips, &spec, (out, pending, o.sync), &mut hidden)?;
            pixels_with_value = stats.bands.first().map(|b| [b.count, stats.pixels]);
            crate::batch::write_sidecar(out, &key)?;
            if true_ortho {
                use std::sync::atomic::Ordering;
                unseen = Some(Unseen::new(compose.covered.load(Ordering::Relaxed), compose.unseen.load(Ordering::Relaxed), grid.gsd));
            }
            t_render = t.elapsed().as_secs_f64();
        }
        for side in side_outputs {
            side.publish()?;
        }
        for note in &plan.coarse_notes {
            progress.warn(note);
        }
        if let Some(coarse) = coarse_plan(&plan, o) {
            progress.warn(&coarse);
        }
        // The report.
        let images = plan
            .images
            .iter()
            .enumerate()
            .map(|(k, im)| ImageReport {
                name: im.name.clone(),
                image: im.opts.inputs.image.clone(),
                share: cells.of_image[k] as f64 / covered.max(1) as f64,
                correction: corrections[k].clone(),
                grid: works.iter().find(|w| w.image == k).map(|w| w.grid),
                hidden_share: unseen.is_some().then(|| hidden[k].1 as f64 / hidden[k].0.max(1) as f64),
            })
            .collect();
        Ok(MosaicReport {
            output: o.output.clone(),
            skipped: false,
            window,
            tile,
            width: grid.width,
            height: grid.height,
            gsd: grid.gsd,
            crs: plan.crs.to_string(),
            cell_px: plan.cell,
            coverage: covered as f64 / (plan.cw * plan.ch) as f64,
            pixels_with_value,
            balance: o.balance,
            blend_px: o.blend,
            seams: seam_stats,
            seam_length: cells.seams as f64 * plan.cell_metres(),
            seam_length_px: cells.seams as u64 * plan.cell as u64,
            edited_seams,
            images,
            unseen,
            seconds: PhaseSeconds { plan: t_plan, balance: t_balance, seams: t_seams, render: t_render },
            wall_seconds: wall.elapsed().as_secs_f64(),
            peak_rss_mib: progress.peak_memory_mib(),
            output_bytes: o.output.as_deref().and_then(|p| std::fs::metadata(p).ok()).map_or(0, |m| m.len()),
            pieces_reused: None,
            strips: strips_made,
        })
    })()
    .map_err(from_manifest)
}

/// Where `--memory` made the plan's cells coarser than a larger budget
/// would (seams and balance then follow the ground less closely): what it
/// says of that. (A plan file fixes the cells.)
fn coarse_plan(plan: &Plan, o: &MosaicOptions) -> Option<String> {
    let px = plan.grid.width as u64 * plan.grid.height as u64;
    let finest = plan::cell_side(px, u64::MAX);
    if o.plan_in.is_some() || plan.cell <= finest {
        return None;
    }
    let cells = px.div_ceil(finest as u64 * finest as u64);
    let more = (cells * plan::BUDGET_PER_CELL).next_multiple_of(1 << 20) >> 20;
    Some(format!(
        "‹memory› {} MiB: the plan's cells are {} px, {} px from ‹memory› {more}M: the seams and the balance follow the ground more coarsely",
        o.memory >> 20,
        plan.cell,
        finest
    ))
}

/// Whether the manifest gave `setting` (the command line did not).
fn manifest_gave(given: &MosaicOptions, taken: &MosaicOptions, setting: &str) -> bool {
    match setting {
        "gsd" => given.gsd.is_none() && taken.gsd.is_some(),
        "bounds" => given.bounds.is_none() && taken.bounds.is_some(),
        "crs" => given.crs.is_none() && taken.crs.is_some(),
        "like" => given.like.is_none() && taken.like.is_some(),
        _ => false,
    }
}

/// The output file of the mosaic's tiles `window` (first column, first
/// row, columns, rows): the first job's format settings, the plan's grid
/// clipped to those tiles, with `layout`'s overviews and Cloud-Optimized
/// layout.
fn piece_spec(plan: &Plan, first: &RectifyOptions, window: [u32; 4], layout: (Overviews, bool), compress: Option<Compression>) -> Result<OutputSpec> {
    let [tc0, tr0, tcw, trh] = window;
    let (grid, tile, im0) = (plan.grid, first.file.tile, &plan.images[0]);
    let (fill, mask) = fill_of(im0.sample, first.pixels.nodata)?;
    let (x0, y0) = grid.ground((tc0 * tile) as f64, (tr0 * tile) as f64);
    let (width, height) = (((tc0 + tcw) * tile).min(grid.width) - tc0 * tile, ((tr0 + trh) * tile).min(grid.height) - tr0 * tile);
    let mut spec = OutputSpec {
        overviews: 0,
        cog: false,
        width,
        height,
        bands: im0.bands,
        sample: im0.sample,
        chunking: Chunking::Tiles(tile),
        compression: compress.unwrap_or(first.file.compress),
        level: match compress {
            Some(c) if c != first.file.compress => crate::options::codec_level(c, None, None)?,
            _ => first.codec_level()?,
        },
        overview_level: first.overview_codec_level()?,
        bigtiff: false,
        photometric: if im0.photometric == 2 && im0.bands >= 3 { 2 } else { 1 },
        alpha: false,
        mask,
        geo: Some(GeoTags {
            x0,
            y0,
            gsd: grid.gsd,
            keys: crate::geodesy::geokeys::keys_of(&plan.crs).map_err(|m| Error::setting("crs", m))?,
            nodata: (!mask).then_some(fill),
        }),
    };
    spec.check_codec().map_err(|m| Error::setting("compress", m))?;
    spec.overviews = layout.0.levels(width, height, tile);
    spec.cog = layout.1;
    spec.bigtiff = bigtiff(first.file.bigtiff).unwrap_or_else(|| spec.needs_bigtiff());
    Ok(spec)
}

/// A BigTIFF setting as said (`None`: as the size needs).
fn bigtiff(b: BigTiff) -> Option<bool> {
    match b {
        BigTiff::Yes => Some(true),
        BigTiff::No => Some(false),
        BigTiff::Auto => None,
    }
}

/// What a mosaic's pixels without a value hold, and whether a mask says
/// which they are: as `rectify` writes them (NaN for floating point, else
/// a mask over zeros), or the value the manifest's `nodata` gives.
fn fill_of(sample: crate::io::source::SampleType, nodata: Nodata) -> Result<(f64, bool)> {
    match nodata.resolved(sample) {
        Nodata::Value(v) => Nodata::check_value(v, sample).map(|()| (v, false)),
        _ => Ok((0.0, true)),
    }
}

/// How strips (or pieces) of the mosaic are put together into the file a
/// single run writes: its layout, its codec levels, its `fill`.
fn assembly(layout: (Overviews, bool), first: &RectifyOptions, fill: f64, sync: bool) -> AssembleOptions {
    AssembleOptions {
        compress: Some(first.file.compress),
        partial: false,
        fill: Some(fill),
        sync,
        overviews: Some(layout.0),
        overview_resampling: Some(first.file.overview_resampling),
        cog: Some(layout.1),
        level: first.file.level,
        overview_level: first.file.overview_level,
        quality: first.file.quality,
        bigtiff: bigtiff(first.file.bigtiff),
    }
}

/// Each image's bands and columns within `window` (the images with none
/// left out); its grid stays the whole run's, so that its pixels are the
/// same.
fn within(works: &[render::ImageWork], window: [u32; 4]) -> Vec<render::ImageWork> {
    let [tc0, tr0, tcw, trh] = window;
    works
        .iter()
        .map(|w| render::ImageWork {
            bands: w
                .bands
                .iter()
                .filter(|(b, _)| (tr0..tr0 + trh).contains(*b))
                .filter_map(|(&b, &(c0, c1))| {
                    let (c0, c1) = (c0.max(tc0), c1.min(tc0 + tcw));
                    (c0 < c1).then_some((b, (c0, c1)))
                })
                .collect(),
            ..(*w).clone()
        })
        .filter(|w| !w.bands.is_empty())
        .collect()
}

/// Tiles of the mosaic: first column, first row, columns, rows.
type Strip = [u32; 4];

/// A strip and how its render fits the memory.
type StripPlan = (Strip, render::Fit);

/// Strips are at most this wide, output pixels, or the images' median
/// footprint where that is wider (in a power of two of tiles): the images'
/// bands in hand and the mosaic's band then do not grow with the block's
/// width (about three images across at work in a band of a 60/30 %
/// block), and an image is made in two strips at most.
const STRIP_PX: u32 = 2048;

/// The most tile columns a strip of the plan's mosaic takes.
fn widest_strip(plan: &Plan, tile: u32) -> u32 {
    strip_columns(plan.images.iter().map(|i| (i.cells[2] - i.cells[0]) as u32 * plan.cell).collect(), tile)
}

/// The most tile columns a strip takes where the images' footprints are
/// `widths` output pixels wide (0: none): a power of two (see
/// [`STRIP_PX`]).
fn strip_columns(mut widths: Vec<u32>, tile: u32) -> u32 {
    widths.retain(|&w| w > 0);
    widths.sort_unstable();
    let median = widths.get(widths.len() / 2).copied().unwrap_or(0);
    STRIP_PX.max(median).div_ceil(tile.max(1)).max(1).next_power_of_two()
}

/// `window` cut into strips of tile columns whose renders each fit
/// `memory`: the whole where it is no wider than twice [`widest_strip`] and fits, else the widest power of two that
/// does (strips start at multiples of it, the last what is left; overview
/// tiles then rarely wait for the next strip). When strips a tile column wide
/// do not fit either, the refusal of the one that needs the most (its
/// figure is the least that runs).
fn column_strips(plan: &Plan, weights: u64, works: &[render::ImageWork], spec: &OutputSpec, window: Strip, memory: u64) -> Result<Vec<StripPlan>> {
    let [tc0, tr0, tcw, trh] = window;
    // Strips `wide` columns wide (the last what is left), or the most
    // that one of them lacks.
    let cut = |wide: u32| -> std::result::Result<Vec<StripPlan>, render::Short> {
        let (mut fits, mut worst) = (Vec::new(), None::<render::Short>);
        for c0 in (tc0..tc0 + tcw).step_by(wide as usize) {
            let strip = [c0, tr0, wide.min(tc0 + tcw - c0), trh];
            match render::budget(plan, weights, &within(works, strip), spec, strip, memory) {
                Ok(fit) => fits.push((strip, fit)),
                Err(short) => worst = Some(worst.filter(|w| w.enough >= short.enough).unwrap_or(short)),
            }
        }
        worst.map_or(Ok(fits), Err)
    };
    let most = widest_strip(plan, spec.chunk().0);
    // A mosaic up to two strips wide is made whole where it fits: cut in
    // two it would hold little less, and make its images twice.
    if tcw <= 2 * most {
        match cut(tcw) {
            Ok(whole) => return Ok(whole),
            Err(short) if tcw == 1 => return Err(short.into()),
            Err(_) => {}
        }
    }
    // The widest power of two under the whole width (and no wider than
    // the most).
    let mut wide = most.min(1 << (31 - (tcw - 1).leading_zeros()));
    loop {
        match cut(wide) {
            Ok(fits) => return Ok(fits),
            Err(short) if wide == 1 => return Err(short.into()),
            Err(_) => wide /= 2,
        }
    }
}

/// What renders any window of the mosaic: the plan, the compositor, every
/// image's work, the threads.
struct PieceRender<'a> {
    plan: &'a Plan,
    compose: &'a render::Compose<'a>,
    works: &'a [render::ImageWork],
    threads: usize,
    pool: &'a rayon::ThreadPool,
    fill: f64,
    first: &'a RectifyOptions,
    progress: &'a dyn Progress,
    cancel: &'a Cancel,
    /// What the mosaic is made from ([`source_key`]).
    source: &'a str,
    /// The run's budget, bytes (each strip's DEM posts take a share).
    memory: u64,
}

impl PieceRender<'_> {
    /// The mosaic's tiles `window` into `path` (through `pending`, synced
    /// or not) as `spec` says, strip after strip of `strips`, each with its
    /// fit's renders at once and memory each; each image's pixels imaged
    /// and hidden added to `hidden`. Returns the statistics of its pixels.
    fn render(
        &self,
        window: Strip,
        strips: &[StripPlan],
        spec: &OutputSpec,
        (path, pending, sync): (&Path, PendingFile, bool),
        hidden: &mut [(u64, u64)],
    ) -> Result<crate::overview::Statistics> {
        let [tc0, tr0, tx, ty] = window;
        // Each strip's works, made as it starts and let go when it ends;
        // the DEMs' posts its images look up, a cohort of them at a time.
        let tile = spec.chunk().0;
        let works_of = |&(strip, (_, share)): &StripPlan| -> (Vec<render::ImageWork>, StripHeights) {
            let mut works = within(self.works, strip);
            for w in &mut works {
                w.opts.resources.memory = share;
                w.opts.resources.geometry_memory = Some(render::least_share(spec));
            }
            let mut heights = StripHeights::new(&works);
            heights.settle(self.plan, tile, self.memory);
            (works, heights)
        };
        let columns: Vec<(u32, u32)> = strips.iter().map(|(s, _)| (s[0] - tc0, s[0] - tc0 + s[2])).collect();
        let (cancel, progress) = (self.cancel, self.progress);
        progress.start(&Task {
            name: "mosaic",
            units: tx as u64 * ty as u64,
            lines: spec.height as u64 * strips.len() as u64,
            line_name: "rows",
            input_bytes: 0,
        });
        let writing = BandWriting {
            spec,
            path,
            threads: self.threads,
            overview_resampling: self.first.file.overview_resampling,
            fill: self.fill,
            sync,
            progress,
            cancel,
            source: Some(self.source),
        };
        let sample = self.plan.images[0].sample;
        let written = std::thread::scope(|s| {
            let mut feeds: Option<(usize, Vec<render::ImageWork>, StripHeights, render::Feeds)> = None;
            write_bands(&writing, pending, &columns, |k, b| {
                if feeds.as_ref().is_none_or(|(j, _, _, _)| *j != k) {
                    // The strip before is done: its images' threads have ended.
                    feeds = None;
                    progress.memory_freed();
                    let (works, heights) = works_of(&strips[k]);
                    let n = works.len();
                    // No more images make a band at once than there are
                    // threads (two at least, so that one's serial stages
                    // overlap another's): more only hold more in flight.
                    let at_once = strips[k].1 .0.min(self.threads.max(2));
                    feeds = Some((k, works, heights, render::Feeds::new(s, n, at_once, self.pool)));
                }
                let (_, works, heights, feeds) = feeds.as_mut().expect("just made");
                // The piece's band b is the mosaic's tr0 + b.
                let given = heights.give(self.plan, works, tr0 + b, tile)?;
                let got = feeds.band(works, tr0 + b, cancel, progress)?;
                // The images started hold their DEMs themselves.
                for j in given {
                    works[j].dem = None;
                }
                let works = &*works;
                for (j, band) in &got {
                    if let Some(s) = &band.seen {
                        hidden[works[*j].image].0 += s.imaged;
                        hidden[works[*j].image].1 += s.hidden;
                    }
                }
                let got: Vec<_> = got.iter().map(|(j, band)| (&works[*j], band)).collect();
                let strip = strips[k].0;
                self.compose.make_band(tr0 + b, (strip[0], strip[0] + strip[2]), &got, self.pool, sample)
            })
        });
        progress.finish();
        if cancel.is_cancelled() {
            return Err(Error::Cancelled);
        }
        written.map(|(_, stats)| stats)
    }
}

/// The plan's cells each image is given, and the cell sides its seams run
/// along (between two images).
struct CellCounts {
    of_image: Vec<usize>,
    seams: usize,
}

impl CellCounts {
    fn of(plan: &Plan) -> CellCounts {
        let mut of_image = vec![0; plan.images.len()];
        for &l in plan.label.iter().filter(|&&l| l != NONE) {
            of_image[l as usize] += 1;
        }
        let seams = (0..plan.cw * plan.ch)
            .map(|k| {
                let (x, y) = (k % plan.cw, k / plan.cw);
                let l = plan.label[k];
                let right = x + 1 < plan.cw && l != NONE && plan.label[k + 1] != NONE && plan.label[k + 1] != l;
                let down = y + 1 < plan.ch && l != NONE && plan.label[k + plan.cw] != NONE && plan.label[k + plan.cw] != l;
                usize::from(right) + usize::from(down)
            })
            .sum::<usize>();
        CellCounts { of_image, seams }
    }
}

/// What a mosaic is made from, the same for each of its pieces and strips
/// and whatever layout they are put together in: its images and their
/// settings (by their contents), blend and occlusion: not the piece, the
/// layout, nor what a plan fixes — grid, seams, balance — which shards
/// read from the plan file a single run makes for itself.
fn source_key(o: &MosaicOptions, jobs: &[crate::batch::manifest::Job]) -> String {
    // What the pixels depend on beyond the plan the pieces share: the
    // blend, the occlusion, each image by its contents (see
    // `scene::made_from::source_key`).
    // The grid is the mosaic's, whether the manifest or the flags give it.
    let settings = format!("{} {:?} {:?} {:?} {:?}", o.blend, o.occlusion, o.gsd, o.bounds, o.crs.as_ref().map(ToString::to_string));
    let job_keys: Vec<String> = jobs
        .iter()
        .map(|j| {
            let mut config = j.config.clone();
            (config.grid.gsd, config.grid.bounds, config.grid.crs, config.grid.like) = (None, None, None, None);
            format!("{}={}", j.name, crate::scene::made_from::source_key(&config))
        })
        .collect();
    let like: Vec<&std::path::Path> = o.like.iter().map(PathBuf::as_path).collect();
    crate::identity::content_key_of(&[settings.as_bytes(), job_keys.join(";").as_bytes()], &like)
}

/// `source` with what the plan gives every pixel: its cells' labels (the
/// seams) and each image's correction (the balance).
fn plan_source(source: &str, plan: &Plan, corrections: &[balance::Correction]) -> String {
    let gains = serde_json::to_vec(corrections).unwrap_or_default();
    let cells = format!("{} {}x{}", plan.cell, plan.cw, plan.ch);
    crate::identity::content_key_of(&[source.as_bytes(), cells.as_bytes(), bytemuck::cast_slice(&plan.label), &gains], &[])
}

/// The key of a run: the manifest's jobs (their inputs and settings), the
/// files it takes (plan, seamlines) and every setting that changes the
/// output.
fn run_key(o: &MosaicOptions, jobs: &[crate::batch::manifest::Job]) -> String {
    let settings = format!(
        "{:?} {:?} {:?} {:?} {} {} {:?} {:?} {:?} {:?} {:?}",
        o.gsd,
        o.bounds,
        o.crs.as_ref().map(ToString::to_string),
        o.balance,
        o.least_cost,
        o.blend,
        o.window,
        o.cog,
        o.occlusion,
        o.overviews,
        o.compress
    );
    let job_keys: Vec<String> = jobs.iter().map(|j| format!("{}={}", j.name, crate::batch::job_key(&j.config))).collect();
    let joined = job_keys.join(";");
    let files: Vec<&std::path::Path> =
        [Some(&o.manifest), o.plan_in.as_ref(), o.seamlines_in.as_ref(), o.like.as_ref()].into_iter().flatten().map(PathBuf::as_path).collect();
    crate::identity::key_of(&[settings.as_bytes(), joined.as_bytes()], &files)
}

impl MosaicReport {
    /// The report of a run that found its output current.
    fn skipped(out: &std::path::Path) -> MosaicReport {
        MosaicReport {
            output: Some(out.to_path_buf()),
            skipped: true,
            window: [0; 4],
            tile: 0,
            width: 0,
            height: 0,
            gsd: Gsd::square(0.0),
            crs: String::new(),
            cell_px: 0,
            coverage: 0.0,
            pixels_with_value: None,
            balance: Balance::None,
            blend_px: 0.0,
            seams: seams::SeamStats::default(),
            seam_length: 0.0,
            seam_length_px: 0,
            edited_seams: None,
            images: Vec::new(),
            unseen: None,
            seconds: PhaseSeconds { plan: 0.0, balance: 0.0, seams: 0.0, render: 0.0 },
            wall_seconds: 0.0,
            peak_rss_mib: None,
            output_bytes: std::fs::metadata(out).map_or(0, |m| m.len()),
            pieces_reused: None,
            strips: 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Strips of 2048 px under frames of 2000 px; a frame wide under
    /// wider frames (a frame then lies in two strips at most); in whole
    /// powers of two of tiles.
    #[test]
    fn strips_are_about_a_frame_wide_whatever_the_block() {
        assert_eq!(strip_columns(vec![2000, 2010, 0, 1990], 256), 8);
        assert_eq!(strip_columns(vec![2000; 400], 512), 4);
        assert_eq!(strip_columns(vec![18918; 4], 512), 64, "18918 px = 37 tiles");
        assert_eq!(strip_columns(vec![3000, 30000, 3100], 256), 16, "the median frame's 3100 px");
        assert_eq!(strip_columns(Vec::new(), 256), 8);
    }
}
