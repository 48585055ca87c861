//! The threaded runner: a thread for each step, joined by bounded channels
//! so that a few bands at most are in flight; resampling on the worker
//! pool, two chunks at once.

use super::band_bytes::BandBytes;
use super::context::Run;
use super::stages::dem::{node_heights, DemMsg};
use super::stages::encode::{tiles, Tile};
use super::stages::gcm::band_gcm;
use super::stages::read::{plan, read, release_outside, ReadMsg, Reader};
use super::stages::resample::{made, resample, Made, Raw};
use super::stages::write::write;
use super::stages::{timed, Busy, SharedRows};
use crate::error::{Error, Result};
use crate::gcm::BandGcm;
use crate::io::source::{SourceImage, Window};
use crossbeam_channel::{bounded, Receiver, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Runs every step of `run` on threads of its own, writing `out_file`.
/// The error is the root cause: the first that is not a consequence of
/// another's cancelling the run.
pub fn run_threaded(run: &Run, out_file: std::fs::File, flush_file: std::fs::File) -> Result<Busy> {
    let (tx_dem, rx_dem) = bounded::<DemMsg>(2);
    let (tx_gcm, rx_gcm) = bounded::<Arc<BandGcm>>(2);
    let (tx_read, rx_read) = bounded::<ReadMsg>(1);
    let (tx_raw, rx_raw) = bounded::<Made>(1);
    // Buffers going back up the pipeline to be used again.
    let (tx_free_win, rx_free_win) = bounded::<Window>(4);
    let (tx_free_raw, rx_free_raw) = bounded::<Raw>(4);
    let (tx_enc, rx_enc) = bounded::<(usize, Tile)>(run.budget.chunk_tiles(run.inputs.chunk_tile_bytes()).max(4) as usize);

    let results: Vec<Result<Duration>> = std::thread::scope(|s| {
        let h_dem = s.spawn(|| {
            let mut busy = Duration::ZERO;
            let mut before = SharedRows::default();
            for b in run.walk.bands.0..run.walk.bands.1 {
                if run.stop.now() {
                    return Err(Error::Cancelled);
                }
                let msg = timed(&mut busy, || node_heights(run, b, &mut before));
                if tx_dem.send(msg).is_err() {
                    return Err(Error::Cancelled);
                }
            }
            drop(tx_dem);
            Ok(busy)
        });
        let h_gcm = s.spawn(|| {
            // Owned, so that it is dropped (and the stage before it stops)
            // as soon as this stage returns, by success or by error.
            let rx_dem = rx_dem;
            let mut busy = Duration::ZERO;
            let mut before = SharedRows::default();
            let mut in_flight = BandBytes::new(run.budget.bands_in_flight());
            for msg in rx_dem.iter() {
                if run.stop.now() {
                    return Err(Error::Cancelled);
                }
                in_flight.wait_for_room(&run.stop)?;
                let band = Arc::new(timed(&mut busy, || band_gcm(run, msg, &mut before))?);
                in_flight.send(&band, band.heap_bytes());
                if tx_gcm.send(band).is_err() {
                    return Err(Error::Cancelled);
                }
            }
            drop(tx_gcm);
            Ok(busy)
        });
        let h_read = s.spawn(|| {
            let rx_gcm = rx_gcm;
            let mut reader = Reader::default();
            for (b, band) in rx_gcm.iter().enumerate() {
                let b = run.walk.bands.0 + b as u32;
                for chunk in plan(run, b, &band, &mut reader) {
                    if run.stop.now() {
                        return Err(Error::Cancelled);
                    }
                    let win = rx_free_win.try_recv().unwrap_or_default();
                    let msg = read(run, b, band.clone(), chunk, &mut reader, win)?;
                    if tx_read.send(msg).is_err() {
                        return Err(Error::Cancelled);
                    }
                }
            }
            drop(tx_read);
            Ok(reader.busy)
        });
        let h_resample = s.spawn(|| resample_stage(run, rx_read, tx_raw, tx_free_win, rx_free_raw));
        let h_encode = s.spawn(|| {
            let rx_raw = rx_raw;
            let mut busy = Duration::ZERO;
            for made in rx_raw.iter() {
                if run.stop.now() {
                    return Err(Error::Cancelled);
                }
                for tile in tiles(&run.output(), made, &tx_free_raw, &mut busy) {
                    if tx_enc.send(tile?).is_err() {
                        return Err(Error::Cancelled);
                    }
                }
            }
            drop(tx_enc);
            Ok(busy)
        });
        let h_write = s.spawn(|| {
            let rx_enc = rx_enc;
            write(&run.output(), out_file, flush_file, || Ok(rx_enc.recv().ok())).map(|()| Duration::ZERO)
        });
        [h_dem, h_gcm, h_read, h_resample, h_encode, h_write]
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|p| Err(panicked("a pipeline stage", p.as_ref()))))
            .collect()
    });
    busy_of(results)
}

/// Stage 4 on the pool: each chunk's pixels, two or three chunks at once,
/// passed on in order; the mapped scan rows of chunks done let go.
fn resample_stage(run: &Run, rx_read: Receiver<ReadMsg>, tx_raw: Sender<Made>, tx_free_win: Sender<Window>, rx_free_raw: Receiver<Raw>) -> Result<Duration> {
    let src = run.inputs.src;
    // Two chunks are resampled at once: when a worker runs out of
    // rows of the older one it starts on the newer one instead of
    // waiting for the other worker to finish (and for the pool to be
    // woken again). Three in bands of tile columns, where a chunk is
    // only two tasks: a worker done with both of the newer chunk's
    // while the older one's slower task runs has something to take.
    let in_flight: usize = if run.walk.columns { 3 } else { 2 };
    let row_bytes = src.info.width as u64 * src.info.pixel_bytes() as u64;
    let (tx_done, rx_done) = crossbeam_channel::unbounded::<Resampled>();
    let mut chunks = InFlight::default();
    let result = run.pool.in_place_scope(|scope| -> Result<()> {
        // Waits for the oldest chunk in flight and passes it on.
        let forward_oldest = |chunks: &mut InFlight| -> Result<()> {
            let done = chunks.finish_oldest(&rx_done)?;
            let _ = tx_free_win.try_send(done.win);
            let made = made(run, done.band, done.x0, done.raw)?;
            tx_raw.send(made).map_err(|_| Error::Cancelled)
        };
        for (seq, msg) in rx_read.iter().enumerate() {
            let seq = seq as u64;
            if run.stop.now() {
                return Err(Error::Cancelled);
            }
            let rows_now = msg.in_place.map(|_| (msg.win.y0, msg.win.y0 + msg.win.h));
            // Mapped rows stay within eight shares (the windows' four,
            // unused when chunks are read in place, and four of the
            // budget's slack): where the chunks in flight and this
            // one would map more together (the first chunk of a band
            // beside the last of the one before), the older ones are
            // finished first, and the workers idle through the
            // older one's last rows (eight shares, not the six of
            // one chunk, so that this is rare at band edges).
            while !chunks.is_empty() && chunks.rows_hull(rows_now).is_some_and(|(a, b)| (b - a) as u64 * row_bytes > run.budget.mapped_rows()) {
                forward_oldest(&mut chunks)?;
            }
            chunks.release_finished_rows(src, rows_now);
            let spare = rx_free_raw.try_recv().ok();
            let tx_done = tx_done.clone();
            chunks.start(seq, rows_now);
            scope.spawn(move |_| {
                // A panic (a bug) must still report the chunk: the
                // stage waits for it, and the run would hang.
                let raw = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| resample(run, &msg, spare)))
                    .unwrap_or_else(|p| Err(super::stages::resample::Failed::Read(panicked("resampling", p.as_ref()))));
                let _ = tx_done.send(Resampled { seq, raw, win: msg.win, band: msg.band, x0: msg.chunk.x0 });
            });
            while chunks.len() >= in_flight {
                forward_oldest(&mut chunks)?;
            }
        }
        while !chunks.is_empty() {
            forward_oldest(&mut chunks)?;
        }
        Ok(())
    });
    chunks.release_finished_rows(src, None);
    result?;
    drop(tx_raw);
    Ok(chunks.busy)
}

/// The stages' busy times; or the first error that was not a stop (a
/// stage that saw the others stop says Cancelled, not why).
fn busy_of(results: Vec<Result<Duration>>) -> Result<Busy> {
    let mut times = Vec::with_capacity(results.len());
    let mut cancelled = false;
    let mut root = None;
    for r in results {
        match r {
            Ok(d) => times.push(d),
            Err(Error::Cancelled) => cancelled = true,
            Err(e) => {
                root.get_or_insert(e);
            }
        }
    }
    if let Some(e) = root {
        return Err(e);
    }
    if cancelled {
        return Err(Error::Cancelled);
    }
    Ok(Busy { dem: times[0], gcm: times[1], read: times[2], resample: times[3], encode: times[4] })
}

/// A panic of `what` as the run's error: a bug, said as one, with the
/// panic's message (the hook has printed where).
fn panicked(what: &str, payload: &(dyn std::any::Any + Send)) -> Error {
    let msg = payload.downcast_ref::<String>().map(String::as_str).or_else(|| payload.downcast_ref::<&str>().copied()).unwrap_or("no message");
    Error::Internal(format!("{what}: {msg}"))
}

/// A chunk resampled by a pool worker, with its number in the band order
/// and the window buffer to use again.
struct Resampled {
    seq: u64,
    raw: std::result::Result<super::stages::resample::Pixels, super::stages::resample::Failed>,
    win: Window,
    band: u32,
    /// The chunk's first output column.
    x0: u32,
}

/// The chunks being resampled, oldest first, with the scan rows each reads
/// in place; the scan rows of finished chunks not yet given back; and the
/// stage's busy time (while any chunk is in flight).
#[derive(Default)]
struct InFlight {
    chunks: std::collections::VecDeque<(u64, Option<(u32, u32)>)>,
    /// Chunks finished before an older one.
    early: std::collections::BTreeMap<u64, Resampled>,
    finished_rows: Vec<(u32, u32)>,
    busy_since: Option<Instant>,
    busy: Duration,
}

impl InFlight {
    fn len(&self) -> usize {
        self.chunks.len()
    }

    fn is_empty(&self) -> bool {
        self.chunks.is_empty()
    }

    fn start(&mut self, seq: u64, rows: Option<(u32, u32)>) {
        self.busy_since.get_or_insert_with(Instant::now);
        self.chunks.push_back((seq, rows));
    }

    /// Waits for the oldest chunk (the others may finish first).
    fn finish_oldest(&mut self, done: &crossbeam_channel::Receiver<Resampled>) -> Result<Resampled> {
        let (seq, rows) = self.chunks.pop_front().expect("a chunk in flight");
        let chunk = loop {
            if let Some(d) = self.early.remove(&seq) {
                break d;
            }
            let d = done.recv().map_err(|_| Error::Cancelled)?;
            self.early.insert(d.seq, d);
        };
        if self.chunks.is_empty() {
            if let Some(t) = self.busy_since.take() {
                self.busy += t.elapsed();
            }
        }
        self.finished_rows.extend(rows);
        Ok(chunk)
    }

    /// The scan rows from the first to the last mapped by the chunks in
    /// flight and `extra`.
    fn rows_hull(&self, extra: Option<(u32, u32)>) -> Option<(u32, u32)> {
        self.chunks.iter().filter_map(|c| c.1).chain(extra).reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
    }

    /// Gives back the rows of finished chunks that neither a chunk in
    /// flight nor `next` reads.
    fn release_finished_rows(&mut self, src: &SourceImage, next: Option<(u32, u32)>) {
        let keep = self.rows_hull(next);
        for rows in self.finished_rows.drain(..) {
            release_outside(src, rows, keep);
        }
    }
}
