//! The output grid a run would make, without rendering a pixel: what a
//! caller needs to split the run into windows (`window`) on many workers.

use super::RunPlan;
use crate::options::RectifyOptions;
use crate::progress::Progress;
use crate::Result;
use serde::Serialize;

/// The whole output of a run, in pixels and tiles.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct OutputPlan {
    pub width: u32,
    pub height: u32,
    /// The tile size; a `window` is counted in tiles.
    pub tile: u32,
    pub tiles_across: u32,
    pub tiles_down: u32,
    /// GDAL's geotransform: `[x0, pixel width, 0, y0, 0, −pixel height]`.
    pub transform: [f64; 6],
    /// The output CRS as the run names it.
    pub crs: String,
    pub bands: u32,
}

/// The grid `opts` make, the whole of it (any `window` aside).
pub fn plan(opts: &RectifyOptions, progress: &dyn Progress) -> Result<OutputPlan> {
    let mut whole = opts.clone();
    whole.grid.window = None;
    let plan = RunPlan::new(&whole, progress)?;
    let g = plan.grid;
    let t = whole.file.tile;
    Ok(OutputPlan {
        width: g.width,
        height: g.height,
        tile: t,
        tiles_across: g.width.div_ceil(t),
        tiles_down: g.height.div_ceil(t),
        transform: [g.x0, g.gsd.x, 0.0, g.y0, 0.0, -g.gsd.y],
        crs: plan.camera.crs.to_string(),
        bands: plan.src.info.bands,
    })
}
