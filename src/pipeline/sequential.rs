//! The sequential runner (`--threads 1`): every step one after the other,
//! never two at once, pulled by the writer: when it wants a tile and none
//! is made, the next chunk is read, resampled and encoded, and the next
//! band's nodes worked out when its chunks run out. A job given one CPU
//! (a batch scheduler's one-core allocation, or one job a core) then uses
//! one, and holds one scan window and one chunk at a time.

use super::context::Run;
use super::stages::dem::node_heights;
use super::stages::encode::{tiles, Tile};
use super::stages::gcm::band_gcm;
use super::stages::read::{plan, read, release_outside, Chunk, Reader};
use super::stages::resample::{made, resample, Raw};
use super::stages::write::write;
use super::stages::{timed, Busy, SharedRows};
use crate::error::Result;
use crate::gcm::BandGcm;
use crate::io::source::Window;
use std::collections::VecDeque;
use std::sync::Arc;

/// Runs every step of `run` one after the other, writing `out_file`:
/// resampling and encoding on the pool (of one worker), the rest on this
/// thread, which waits meanwhile.
pub fn run_sequential(run: &Run, out_file: std::fs::File, flush_file: std::fs::File) -> Result<Busy> {
    let mut busy = Busy::default();
    let (mut heights, mut node_rows) = (SharedRows::default(), SharedRows::default());
    let mut reader = Reader::default();
    let mut bands = run.walk.bands.0..run.walk.bands.1;
    // The band being made and its chunks still to make.
    let mut band: Option<(u32, Arc<BandGcm>)> = None;
    let mut chunks: VecDeque<Chunk> = VecDeque::new();
    let mut ready: VecDeque<(usize, Tile)> = VecDeque::new();
    // Buffers used again, chunk after chunk; a chunk's buffer comes back
    // through `free` once its last tile is written.
    let (free, freed) = crossbeam_channel::bounded::<Raw>(1);
    let mut win = Window::default();
    // The scan rows the chunk before read in place.
    let mut mapped: Option<(u32, u32)> = None;
    let written = write(&run.output(), out_file, flush_file, || loop {
        if let Some(tile) = ready.pop_front() {
            return Ok(Some(tile));
        }
        if run.stop.now() {
            return Err(crate::error::Error::Cancelled);
        }
        let Some(chunk) = chunks.pop_front() else {
            let Some(b) = bands.next() else {
                return Ok(None);
            };
            let msg = timed(&mut busy.dem, || node_heights(run, b, &mut heights));
            let gcm = Arc::new(timed(&mut busy.gcm, || band_gcm(run, msg, &mut node_rows))?);
            chunks.extend(plan(run, b, &gcm, &mut reader));
            band = Some((b, gcm));
            continue;
        };
        let (b, gcm) = band.clone().expect("a band for its chunks");
        let msg = read(run, b, gcm, chunk, &mut reader, std::mem::take(&mut win))?;
        let rows_now = msg.in_place.map(|_| (msg.win.y0, msg.win.y0 + msg.win.h));
        if let Some(rows) = mapped.take() {
            release_outside(run.inputs.src, rows, rows_now);
        }
        mapped = rows_now;
        let raw = timed(&mut busy.resample, || run.pool.install(|| resample(run, &msg, freed.try_recv().ok())));
        let made = made(run, b, msg.chunk.x0, raw)?;
        win = msg.win;
        for tile in tiles(&run.output(), made, &free, &mut busy.encode) {
            ready.push_back(tile?);
        }
    });
    if let Some(rows) = mapped {
        release_outside(run.inputs.src, rows, None);
    }
    written?;
    busy.read = reader.busy;
    Ok(busy)
}
