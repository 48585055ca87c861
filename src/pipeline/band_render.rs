//! One image's orthophoto a band at a time into memory, for a mosaic: the
//! stages of `rectify` up to the resampler (DEM, GCM, read, resample) on
//! the image's own grid, for the bands and tile columns asked for, in
//! order. Nothing is written: each band's chunks go to the caller, which
//! composes them with other images' before its own encoder and writer.
//!
//! The run's set-up holds the scan, the DEM and the GCM, which borrow from
//! one another; a caller that needs several images at once runs each on a
//! thread of its own (see `mosaic::render`), all resampling on one pool.

use super::budget::MemoryBudget;
use super::context::{Counters, Inputs, Run, Stop, Walk};
use super::setup::RunPlan;
use super::stages::dem::node_heights;
use super::stages::gcm::band_gcm;
use super::stages::read::{plan, read, release_outside, Reader};
use super::stages::resample::{made, resample, Made};
use super::stages::SharedRows;
use crate::error::{Error, Result};
use crate::gcm::Gcm;
use crate::io::source::Window;
use crate::options::{BandOrder, Nodata, Occlusion, Overviews, RectifyOptions};
use crate::overview::ValidBy;
use crate::progress::{Cancel, NoProgress, Progress, Task};
use crate::transform::visibility::Visibility;
use crate::transform::Transform;
use std::sync::Arc;

/// A band of the image's grid as made: its chunks, each a run of whole
/// tiles from tile column `first_col`, with which pixels have a value.
pub struct BandPixels {
    pub band: u32,
    pub chunks: Vec<Made>,
    /// Under `--occlusion`: which of the band's pixels the sensor sees.
    pub seen: Option<std::sync::Arc<crate::transform::visibility::Seen>>,
}

/// What the caller asks of one band: the band (a row of the image grid's
/// tiles) and its tile columns `cols.0..cols.1`.
pub type BandRequest = (u32, (u32, u32));

/// A DEM already open, and the ground CRS it was opened for: taken where
/// the image asks for that file in that CRS with the same policies.
pub type SharedDem = Option<(Arc<crate::dem::Dem>, crate::geodesy::Crs)>;

/// The options an image is made with inside a mosaic: rows of tiles (the
/// mosaic's bands), every pixel's validity (a mask), nothing of the output
/// file's own (no overviews: the mosaic's writer makes its own).
pub fn in_memory(opts: &RectifyOptions) -> RectifyOptions {
    let mut o = opts.clone();
    o.resources.band_order = BandOrder::Rows;
    o.pixels.nodata = Nodata::Mask;
    o.pixels.alpha = false;
    o.grid.window = None;
    o.file.cog = false;
    o.file.overviews = Overviews::None;
    o
}

/// An image's set-up warnings (aliasing, a datum, the camera), said to
/// `to` with the image named where they name no file of it: nobody
/// watches an image's own progress.
struct ImageWarnings<'a> {
    to: &'a dyn Progress,
    image: &'a std::path::Path,
    camera: &'a std::path::Path,
}

impl Progress for ImageWarnings<'_> {
    fn start(&self, _: &Task) {}
    fn advance(&self, _: u64) {}
    fn finish(&self) {}
    fn warn(&self, message: &str) {
        let name = self.image.display().to_string();
        if message.contains(&name) || message.contains(&self.camera.display().to_string()) {
            self.to.warn(message);
        } else {
            self.to.warn(&format!("{name}: {message}"));
        }
    }
    fn peak_memory_mib(&self) -> Option<f64> {
        self.to.peak_memory_mib()
    }
    fn memory_freed(&self) {
        self.to.memory_freed();
    }
}

/// What the images of a mosaic share: the workers they resample on (so
/// that an image waiting for its turn holds no threads of its own), the
/// run's cancel, where their set-up warnings go.
pub struct Shared<'a> {
    pub pool: &'a rayon::ThreadPool,
    pub cancel: &'a Cancel,
    pub warn: &'a dyn Progress,
}

/// Makes the bands `requests` names (in increasing order) of the image of
/// `opts` (see [`in_memory`]), handing each to `sink`. Each band waits for
/// `turn`, whose answer is held while the band is made; stops early when
/// `turn` gives none, `sink` says so (its reader went away) or the run is
/// cancelled.
pub fn render_bands<T>(
    opts: &RectifyOptions,
    dem: SharedDem,
    requests: &[BandRequest],
    with: &Shared,
    mut turn: impl FnMut(&BandRequest) -> Option<T>,
    mut sink: impl FnMut(Result<BandPixels>) -> bool,
) -> Result<()> {
    let Shared { pool, cancel, warn } = *with;
    let opts = in_memory(opts);
    let setup = match RunPlan::with_dem(&opts, &ImageWarnings { to: warn, image: &opts.inputs.image, camera: &opts.inputs.camera }, dem) {
        Ok(p) => p,
        Err(e) => {
            sink(Err(e));
            return Ok(());
        }
    };
    let t = Transform::new(setup.camera.model(), &setup.dem, setup.grid).with_scan((setup.src.info.width, setup.src.info.height));
    let gcm = Gcm::new(&t, setup.approx, setup.gcm);
    let visibility = (opts.pixels.occlusion != Occlusion::None).then(|| Visibility::new(&t, setup.occlusion_tolerance()));
    let (tx, ty) = (setup.grid.width.div_ceil(opts.file.tile), setup.grid.height.div_ceil(opts.file.tile));
    let walk = Walk { grid: t.grid, tile: opts.file.tile, bands: (0, ty), cols: (0, tx), columns: false, piece: (0, 0, tx) };
    let mut run = Run {
        // Into memory, not a file: nothing to name.
        source: None,
        inputs: Inputs {
            gcm: &gcm,
            src: &setup.src,
            dem: &setup.dem,
            spec: &setup.spec,
            pixels: setup.pixels,
            output: &opts.file.path,
            sync: false,
            visibility: visibility.as_ref(),
        },
        walk,
        budget: MemoryBudget::new(setup.budget.total()),
        counters: Counters::default(),
        stop: Stop::new(cancel),
        pool,
        progress: &NoProgress,
        spare_masks: crossbeam_channel::bounded(4),
        pyramid: None,
        valid_by: ValidBy::of(&setup.spec),
        statistics: Default::default(),
    };
    let (mut heights, mut node_rows) = (SharedRows::default(), SharedRows::default());
    let mut reader = Reader::default();
    let mut win = Window::default();
    let mut mapped: Option<(u32, u32)> = None;
    for &(b, cols) in requests {
        let Some(turn) = turn(&(b, cols)) else { break };
        if cancel.is_cancelled() {
            return Err(Error::Cancelled);
        }
        run.walk.cols = (cols.0.min(tx), cols.1.min(tx));
        let band = (|| -> Result<BandPixels> {
            let msg = node_heights(&run, b, &mut heights);
            let gcm = Arc::new(band_gcm(&run, msg, &mut node_rows)?);
            let mut chunks = Vec::new();
            for chunk in plan(&run, b, &gcm, &mut reader) {
                let msg = read(&run, b, gcm.clone(), chunk, &mut reader, std::mem::take(&mut win))?;
                let rows_now = msg.in_place.map(|_| (msg.win.y0, msg.win.y0 + msg.win.h));
                if let Some(rows) = mapped.take() {
                    release_outside(run.inputs.src, rows, rows_now);
                }
                mapped = rows_now;
                let raw = run.pool.install(|| resample(&run, &msg, None));
                chunks.push(made(&run, b, msg.chunk.x0, raw)?);
                win = msg.win;
            }
            // (Zeros read past a truncated scan's end make no band.)
            run.inputs.src.check_intact()?;
            run.inputs.dem.check_intact()?;
            Ok(BandPixels { band: b, chunks, seen: gcm.seen.clone() })
        })();
        // Until its next turn the image holds no scan rows, no window and
        // no DEM chunk.
        if let Some(rows) = mapped.take() {
            release_outside(run.inputs.src, rows, None);
        }
        win = Window::default();
        crate::io::cached_raster::let_go_of_last_look();
        drop(turn);
        let failed = band.is_err();
        if !sink(band) || failed {
            break;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An image inside a mosaic makes no overviews of its own (the
    /// mosaic's writer does): asking for them would hold a band of their
    /// tiles against the image's small share and refuse wide frames.
    #[test]
    fn an_image_in_a_mosaic_makes_no_file_of_its_own() {
        let base = RectifyOptions::new("s.tif".into(), "s.toml".into(), crate::options::DemSource::Height(0.0), "o.tif".into());
        let mut opts = base;
        (opts.file.overviews, opts.file.cog, opts.pixels.alpha) = (Overviews::Auto, true, true);
        let m = in_memory(&opts);
        assert_eq!(
            (m.file.overviews, m.file.cog, m.pixels.alpha, m.resources.band_order, m.pixels.nodata),
            (Overviews::None, false, false, BandOrder::Rows, Nodata::Mask)
        );
    }
}
