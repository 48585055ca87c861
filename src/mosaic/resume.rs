//! A mosaic that a stop does not cost its finished work (`--resume-dir
//! DIR`): the plan made once into DIR, the mosaic rendered as bands of
//! tile rows, each a piece finished in DIR with its record (as shards
//! are), then the pieces assembled into the output — byte for byte what a
//! single run writes. Run again after a stop, it takes the plan and every
//! finished piece as they are and renders the rest. DIR holds about one
//! mosaic's worth of pieces until the output is made, then is emptied.

use super::{mosaic, plan_file, run_key, MosaicOptions, MosaicReport, Unseen};
use crate::assemble::assemble;
use crate::error::{Error, Result};
use crate::io::tiff_out::Compression;
use crate::options::Overviews;
use crate::progress::{Cancel, Progress};
use std::path::{Path, PathBuf};

/// Pieces a mosaic is cut into: what a stop can lose at most, against
/// planning its images again for each piece.
const PIECES: u32 = 16;

/// The mosaic `o` asks for (the whole of it, into `o.output`), by pieces
/// in `dir`; see the module doc.
pub fn resumable(o: &MosaicOptions, dir: &Path, progress: &dyn Progress, cancel: &Cancel) -> Result<MosaicReport> {
    let out = o.output.clone().ok_or_else(|| Error::Usage("‹resume_dir›: give ‹output›, the mosaic".into()))?;
    if o.window.is_some() || o.plan_in.is_some() || o.plan_out.is_some() {
        return Err(Error::setting("resume_dir", "renders the whole mosaic from a plan of its own: drop ‹window›, ‹plan› and ‹plan_out›"));
    }
    let jobs = crate::batch::manifest::load(&o.manifest).map_err(|e| e.into_error())?;
    let first = jobs.first().map(|j| j.config.clone()).ok_or_else(|| Error::format(&o.manifest, "no image"))?;
    // (The plan and the pieces take the manifest's settings themselves,
    // and name them as the manifest's.)
    let filled = super::with_manifest_settings(o, &jobs)?;
    super::check_mosaic_outputs(&filled, &jobs)?;
    let key = run_key(&filled, &jobs);
    if !o.force && crate::batch::output_is_current(&out, &key) {
        return Ok(MosaicReport::skipped(&out));
    }
    let absolute = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    if absolute(dir) == absolute(&out) {
        return Err(Error::setting("resume_dir", format!("{} is the output itself: give a folder of its own", dir.display())));
    }
    if dir.exists() && !dir.is_dir() {
        return Err(Error::setting("resume_dir", format!("{} is a file, not a folder", dir.display())));
    }
    let made_here = !dir.exists();
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    // What a killed run left half-made (its pieces' temporaries).
    crate::io::publish::remove_dead_temporaries(dir);

    // The plan, once: kept while its record says it was made for these
    // images and settings (remaking it would change the pieces' inputs).
    // Names of our own, beside whatever else the folder holds.
    let plan = dir.join("gcm-ortho-mosaic-plan.json");
    let planning = MosaicOptions { output: None, plan_out: Some(plan.clone()), ..o.clone() };
    // The layout and the blend are the render's and the assembly's: a
    // rerun that changes them keeps the plan (and the pieces, --cog).
    let plan_key = run_key(&MosaicOptions { cog: None, blend: 0.0, ..planning.clone() }, &jobs);
    if o.force || !crate::batch::output_is_current(&plan, &plan_key) {
        if let Err(e) = mosaic(&planning, progress, cancel) {
            // A folder of nothing yet (a plan refused): not left behind.
            if made_here {
                let _ = std::fs::remove_dir(dir);
            }
            return Err(e);
        }
        crate::batch::write_sidecar(&plan, &plan_key)?;
    }
    let grid = plan_file::grid_of(&plan)?;
    let (across, down) = (grid.width.div_ceil(first.file.tile), grid.height.div_ceil(first.file.tile));
    let rows = down.div_ceil(PIECES);

    // The pieces: bands of tile rows, without overviews (the whole's are
    // made by assembling); a finished one is left as it is.
    let mut pieces: Vec<PathBuf> = Vec::new();
    let mut reports: Vec<MosaicReport> = Vec::new();
    for r0 in (0..down).step_by(rows as usize) {
        if cancel.is_cancelled() {
            return Err(Error::Cancelled);
        }
        let piece = dir.join(format!("gcm-ortho-mosaic-piece-{r0:06}.tif"));
        let po = MosaicOptions {
            output: Some(piece.clone()),
            plan_in: Some(plan.clone()),
            window: Some([0, r0, across, rows.min(down - r0)]),
            seamlines_in: None,
            seamlines_out: None,
            cog: Some(false),
            overviews: Some(Overviews::None),
            // A lossy mosaic's pieces losslessly: coded once, at the
            // assembly, from the pixels a single run codes.
            compress: first.file.compress.is_lossy().then_some(Compression::Deflate),
            force: false,
            ..o.clone()
        };
        reports.push(mosaic(&po, progress, cancel)?);
        pieces.push(piece);
    }

    let (fill, _) = super::fill_of(crate::io::source::SourceImage::open(&pieces[0], 1 << 20)?.info.sample, first.pixels.nodata)?;
    let layout = super::assembly((o.overviews.unwrap_or(first.file.overviews), o.cog.unwrap_or(first.file.cog)), &first, fill, o.sync);
    assemble(&pieces, &out, &layout, cancel)?;
    crate::batch::write_sidecar(&out, &key)?;
    for p in pieces.iter().chain([&plan]) {
        let _ = std::fs::remove_file(crate::batch::sidecar(p));
        let _ = std::fs::remove_file(p);
    }
    crate::io::publish::remove_dead_temporaries(dir);
    let _ = std::fs::remove_dir(dir);
    Ok(joined(reports, &out, [0, 0, across, down], grid))
}

/// One report of the pieces': the plan's findings (the same in each), the
/// pieces' times and counts added up.
fn joined(reports: Vec<MosaicReport>, out: &Path, window: [u32; 4], grid: crate::geom::OutputGrid) -> MosaicReport {
    let rendered: Vec<&MosaicReport> = reports.iter().filter(|r| !r.skipped).collect();
    let reused = [reports.len() - rendered.len(), reports.len()];
    let mut whole = rendered.first().map(|r| (*r).clone()).unwrap_or_else(|| MosaicReport::skipped(out));
    whole.output = Some(out.to_path_buf());
    whole.skipped = false;
    whole.window = window;
    (whole.width, whole.height) = (grid.width, grid.height);
    whole.seconds.render = rendered.iter().map(|r| r.seconds.render).sum();
    whole.wall_seconds = rendered.iter().map(|r| r.wall_seconds).sum();
    whole.peak_rss_mib = rendered.iter().filter_map(|r| r.peak_rss_mib).reduce(f64::max);
    whole.output_bytes = std::fs::metadata(out).map_or(0, |m| m.len());
    whole.pieces_reused = Some(reused);
    whole.strips = rendered.iter().map(|r| r.strips).max().unwrap_or(0);
    // (Known where every piece was made now.)
    whole.pixels_with_value = match reused[0] {
        0 => rendered.iter().map(|r| r.pixels_with_value).try_fold([0, 0], |[v, n], p| p.map(|[pv, pn]| [v + pv, n + pn])),
        _ => None,
    };
    let unseen: Vec<Unseen> = rendered.iter().filter_map(|r| r.unseen).collect();
    whole.unseen = (!unseen.is_empty()).then(|| {
        let (c, u) = unseen.iter().fold((0, 0), |(c, u), s| (c + s.covered_px, u + s.unseen_px));
        Unseen::new(c, u, grid.gsd)
    });
    // Per image, what each piece hid is a share of that piece: not added up.
    for im in &mut whole.images {
        im.hidden_share = None;
        im.grid = None;
    }
    whole
}
