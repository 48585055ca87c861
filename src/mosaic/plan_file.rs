//! The mosaic's plan on disk (`--plan-out`, `--plan`): what the shards of
//! one mosaic must share so that their pieces join into the single run's
//! mosaic — the grid, each cell's image (run-length coded) and each image's
//! radiometric correction. The images, cameras and DEMs are the manifest's:
//! a shard plans them again (deterministically) and checks it made the same
//! grid for the same images before it takes the file's seams and gains.

use super::balance::Correction;
use super::plan::Plan;
use crate::error::{Error, Result};
use crate::geom::OutputGrid;
use serde::{Deserialize, Serialize};
use std::path::Path;

#[derive(Serialize, Deserialize)]
struct PlanFile {
    format: String,
    grid: OutputGrid,
    crs: String,
    cell: u32,
    cw: usize,
    ch: usize,
    images: Vec<String>,
    /// `[image, count]` runs over the cells, row by row (65535: none).
    labels: Vec<[u32; 2]>,
    corrections: Vec<Correction>,
    /// What it was planned from: the images, cameras and DEMs by their
    /// contents, and the settings every piece shares (none in plans of
    /// earlier versions).
    #[serde(default)]
    source: Option<String>,
    /// FNV-1a of the file's JSON written without this field: a plan edited
    /// or damaged by hand is refused, not taken as planned.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    checksum: Option<String>,
}

const FORMAT: &str = "gcm-ortho mosaic plan 1";

/// The bounds a plan's corrections are taken within: a balance solved on
/// real overlaps stays far inside them (a gain of 1e308 saturates every
/// pixel of its image).
const GAINS: std::ops::RangeInclusive<f64> = (1.0 / 64.0)..=64.0;
const MAX_OFFSET: f64 = 1e9;
const MAX_RADIAL: f64 = 16.0;

/// The plan's checksum: FNV-1a (64 bits) of its JSON without one (`file`'s
/// own is left out: `None` is not written).
fn checksum(file: &PlanFile) -> Result<String> {
    debug_assert!(file.checksum.is_none());
    let text = serde_json::to_vec(file).map_err(|e| Error::Internal(format!("a mosaic plan as JSON: {e}")))?;
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    crate::identity::fnv(&mut hash, &text);
    Ok(format!("{hash:016x}"))
}

/// Refuses a correction out of [`GAINS`], [`MAX_OFFSET`] or [`MAX_RADIAL`],
/// naming the image and band.
fn check_corrections(path: &Path, file: &PlanFile) -> Result<()> {
    for (c, image) in file.corrections.iter().zip(&file.images) {
        for (band, &g) in c.gain.iter().enumerate() {
            if !GAINS.contains(&g) {
                return Err(Error::format(path, format!("the gain of {image}, band {}, is {g}: a plan's gains lie within 1/64 to 64", band + 1)));
            }
        }
        for (band, &o) in c.offset.iter().enumerate() {
            if !(o.abs() <= MAX_OFFSET) {
                return Err(Error::format(path, format!("the offset of {image}, band {}, is {o}: a plan's offsets lie within ±{MAX_OFFSET:e}", band + 1)));
            }
        }
        for (band, r) in c.radial.iter().enumerate() {
            if !r.iter().all(|v| v.abs() <= MAX_RADIAL) {
                return Err(Error::format(path, format!("the vignetting terms of {image}, band {}, are {r:?}: they lie within ±{MAX_RADIAL}", band + 1)));
            }
        }
    }
    Ok(())
}

/// Writes `plan`'s seams and `corrections`, planned from `source`, for
/// `path` under a temporary name beside it, for the caller to publish
/// when its run is done.
pub fn write(plan: &Plan, corrections: &[Correction], source: &str, path: &Path) -> Result<Option<crate::io::publish::PendingFile>> {
    let mut labels: Vec<[u32; 2]> = Vec::new();
    for &l in &plan.label {
        match labels.last_mut() {
            Some(run) if run[0] == u32::from(l) => run[1] += 1,
            _ => labels.push([u32::from(l), 1]),
        }
    }
    let file = PlanFile {
        format: FORMAT.into(),
        grid: plan.grid,
        crs: plan.crs.to_string(),
        cell: plan.cell,
        cw: plan.cw,
        ch: plan.ch,
        images: plan.images.iter().map(|i| i.name.clone()).collect(),
        labels,
        corrections: corrections.to_vec(),
        source: Some(source.to_string()),
        checksum: None,
    };
    let file = PlanFile { checksum: Some(checksum(&file)?), ..file };
    let text = serde_json::to_string(&file).map_err(|e| Error::Internal(format!("a mosaic plan as JSON: {e}")))?;
    crate::io::publish::write_pending(path, text.as_bytes())
}

fn load(path: &Path) -> Result<PlanFile> {
    let text = crate::io::bounded_read::read_text_bounded(path, "a mosaic plan", crate::io::bounded_read::LIST)?;
    let mut file: PlanFile = serde_json::from_str(&text).map_err(|e| Error::format(path, format!("is not a mosaic plan: {e}")))?;
    match file.checksum.take() {
        Some(sum) if sum == checksum(&file)? => {}
        Some(_) => return Err(Error::format(path, "its content does not match its checksum (edited or damaged): plan again")),
        None => return Err(Error::format(path, "has no checksum (a plan of an earlier version, or written by hand): plan again")),
    }
    check_corrections(path, &file)?;
    Ok(file)
}

/// The grid of the plan file at `path`.
pub fn grid_of(path: &Path) -> Result<OutputGrid> {
    load(path).map(|f| f.grid)
}

/// The cell side of the plan file at `path` (a shard plans on the plan's
/// cells whatever its own memory budget).
pub fn cell_of(path: &Path) -> Result<u32> {
    load(path).map(|f| f.cell)
}

/// Takes the seams of the plan file at `path` into `plan` (made again from
/// the same manifest and settings, `source`) and returns its corrections.
pub fn read(plan: &mut Plan, source: &str, path: &Path) -> Result<Vec<Correction>> {
    let file = load(path)?;
    if file.format != FORMAT {
        return Err(Error::format(path, format!("'{}' is not a plan this version reads ({FORMAT})", file.format)));
    }
    let names: Vec<String> = plan.images.iter().map(|i| i.name.clone()).collect();
    if file.images != names {
        return Err(Error::format(path, "was planned for other images: plan again from this manifest"));
    }
    if file.grid != plan.grid || (file.cell, file.cw, file.ch) != (plan.cell, plan.cw, plan.ch) || file.crs != plan.crs.to_string() {
        return Err(Error::format(
            path,
            "was planned on another grid (other ‹gsd›, ‹bounds›, ‹crs› or DEMs): give the settings it was made with, or plan again",
        ));
    }
    // Pieces of other inputs would not join: refused before the render.
    if file.source.as_deref().is_some_and(|s| s != source) {
        return Err(Error::format(
            path,
            "was planned from other images, cameras or DEMs (their contents), or other ‹blend›, ‹occlusion›, ‹gsd›, ‹bounds› or ‹crs›: give what it was made from, or plan again",
        ));
    }
    let cells = plan.cw * plan.ch;
    let damaged = || Error::format(path, "is cut short or damaged");
    let mut label = Vec::with_capacity(cells);
    for &[l, n] in &file.labels {
        if l != u32::from(super::plan::NONE) && l as usize >= names.len() {
            return Err(Error::format(path, format!("names image {l} of {}", names.len())));
        }
        if label.len() + n as usize > cells {
            return Err(damaged());
        }
        label.extend(std::iter::repeat_n(l as u16, n as usize));
    }
    let bands_ok = file.corrections.iter().zip(&plan.images).all(|(c, im)| {
        let nb = im.bands as usize;
        c.gain.len() == nb && c.offset.len() == nb && (c.radial.is_empty() || c.radial.len() == nb)
    });
    if label.len() != cells || file.corrections.len() != names.len() || !bands_ok {
        return Err(damaged());
    }
    plan.label = label;
    Ok(file.corrections)
}
