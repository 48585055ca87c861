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
}

const FORMAT: &str = "gcm-ortho mosaic plan 1";

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
    };
    let text = serde_json::to_string(&file).map_err(|e| Error::Geometry(e.to_string()))?;
    crate::io::publish::write_pending(path, text.as_bytes())
}

fn load(path: &Path) -> Result<PlanFile> {
    let text = crate::io::bounded_read::read_text_bounded(path, "a mosaic plan", crate::io::bounded_read::LIST)?;
    serde_json::from_str(&text).map_err(|e| Error::format(path, format!("is not a mosaic plan: {e}")))
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
            "was planned on another grid (other --gsd, --bounds, --crs or DEMs): give the settings it was made with, or plan again",
        ));
    }
    // Pieces of other inputs would not join: refused before the render.
    if file.source.as_deref().is_some_and(|s| s != source) {
        return Err(Error::format(
            path,
            "was planned from other images, cameras or DEMs (their contents), or other --blend, --occlusion, --gsd, --bounds or --crs: give what it was made from, or plan again",
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
