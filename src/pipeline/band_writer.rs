//! An output made a band (a row of tiles) at a time by the caller, through
//! `rectify`'s own encoder and writer: tiles and mask tiles compressed in
//! parallel, overviews and statistics made as they stream, the
//! Cloud-Optimized layout; a temporary file beside the output, verified,
//! then renamed. For outputs with no one scan behind them (a mosaic).

use super::context::{Output, Stop, Walk};
use super::stages::encode::tiles;
use super::stages::resample::{Made, Raw};
use super::stages::write::write;
use crate::error::{Error, Result};
use crate::geom::OutputGrid;
use crate::io::tiff_out::{verify, OutputSpec, PendingFile};
use crate::overview::{OverviewResampling, Pyramid, ValidBy};
use crate::progress::{Cancel, Progress};
use std::collections::VecDeque;
use std::path::Path;
use std::sync::Mutex;
use std::time::Duration;

/// How the output is written.
pub struct BandWriting<'a> {
    pub spec: &'a OutputSpec,
    pub path: &'a Path,
    pub threads: usize,
    pub overview_resampling: OverviewResampling,
    /// Written where no pixel has a value.
    pub fill: f64,
    pub sync: bool,
    pub progress: &'a dyn Progress,
    pub cancel: &'a Cancel,
    /// What the output is made from, the same for every piece of it.
    pub source: Option<&'a str>,
}

/// What writing `spec` in strips `across` tile columns wide holds at most,
/// bytes: a strip's band in flight three times (made, being encoded, being
/// written) and the overview tiles not yet finished: a band of them, and
/// in strips those waiting at a strip's edge for the next strip (a column
/// a level, down the whole height, from the level where the strip is a
/// tile wide).
pub fn held_bytes(spec: &OutputSpec, across: u32) -> u64 {
    let edge = if across < spec.tiles_across() { Pyramid::held_bytes(spec, spec.tiles_down().div_ceil(across)) } else { 0 };
    3 * across as u64 * spec.tile_bytes() as u64 + Pyramid::held_bytes(spec, across) + edge
}

/// Writes `w.path` from the bands `make_band(s, b)` makes: strip after strip
/// of `strips` (tile columns `[c0, c1)`, from left to right, together the
/// whole width), in each band after band from the top. A strip's band is
/// its tiles one after the other, padded to whole tiles, and (under a
/// mask) a byte a pixel saying which have a value. The file's bytes do not
/// depend on the strips. Returns the encoder's busy time and the full
/// level's statistics.
pub fn write_bands(
    w: &BandWriting,
    pending: PendingFile,
    strips: &[(u32, u32)],
    mut make_band: impl FnMut(usize, u32) -> Result<(Raw, Option<Vec<u8>>)>,
) -> Result<(Duration, crate::overview::Statistics)> {
    let spec = w.spec;
    let tile = spec.chunk().0;
    let (tx, ty) = (spec.tiles_across(), spec.tiles_down());
    let geo = spec.geo.as_ref().ok_or_else(|| Error::Geometry("a band-written output needs its grid".into()))?;
    let grid = OutputGrid { x0: geo.x0, y0: geo.y0, gsd: geo.gsd, width: spec.width, height: spec.height };
    let walk = Walk { grid, tile, bands: (0, ty), cols: (0, tx), columns: false, piece: (0, 0, tx) };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(w.threads)
        .build()
        .map_err(|e| Error::setting("threads", format!("cannot start {} threads: {e}", w.threads)))?;
    let stop = Stop::new(w.cancel);
    let valid_by = ValidBy::of(spec);
    let pyramid = Pyramid::new(spec, w.overview_resampling, valid_by, w.fill).map(Mutex::new);
    let statistics = Mutex::default();
    let spare_masks = crossbeam_channel::bounded(1);
    let out = Output {
        spec,
        path: w.path,
        sync: w.sync,
        walk,
        pool: &pool,
        stop: &stop,
        progress: w.progress,
        spare_masks: &spare_masks.0,
        pyramid: pyramid.as_ref(),
        valid_by,
        statistics: &statistics,
        source: w.source,
        in_strips: strips.len() > 1,
    };
    let out_file = pending.file()?;
    let flush_file = out_file.try_clone().map_err(|e| Error::io(pending.path(), e))?;
    let (free, _freed) = crossbeam_channel::bounded::<Raw>(1);
    let mut busy = Duration::ZERO;
    let mut ready = VecDeque::new();
    let mut bands = strips.iter().enumerate().flat_map(|(s, &(c0, _))| (0..ty).map(move |b| (s, c0, b)));
    write(&out, out_file, flush_file, || loop {
        if let Some(t) = ready.pop_front() {
            return Ok(Some(t));
        }
        if stop.now() {
            return Err(Error::Cancelled);
        }
        let Some((s, c0, b)) = bands.next() else { return Ok(None) };
        let (raw, valid) = make_band(s, b).map_err(|e| stop.fail(e))?;
        for t in tiles(&out, Made { band: b, first_col: c0, raw, valid }, &free, &mut busy) {
            ready.push_back(t?);
        }
    })?;
    if pyramid.as_ref().is_some_and(|p| !p.lock().is_ok_and(|p| p.is_complete())) {
        return Err(Error::Internal("an overview tile was left unfinished".into()));
    }
    verify(pending.path(), spec)?;
    pending.publish_synced(w.sync)?;
    let statistics = statistics.lock().map(|s| s.total()).unwrap_or_default();
    Ok((busy, statistics))
}
