//! The steps of one `rectify` run, band by band and chunk by chunk: node
//! heights, GCM rows, the plan and scan windows, resampling, tile encoding
//! and writing. The threaded runner (`threaded.rs`) gives each step a thread
//! joined to the next by a bounded channel; the sequential one
//! (`sequential.rs`) runs them one after the other.

use super::chunk::{resample_chunk, Raw, ReadMsg};
use super::config::RectifyConfig;
use super::plan::{band_scan_rows, plan_band, read_ahead_rows, Chunk};
use crate::dem::{Dem, Lookup};
use crate::error::{Error, Result};
use crate::gcm::{BandGcm, Gcm, GcmStats, NodeHeights};
use crate::geom::OutputGrid;
use crate::io::source::{SampleType, SourceImage, Window};
use crate::io::tiff_out::{encode_tile, tiff_write_error, write_placed, Compression, OutputSpec, WriteError};
use indicatif::ProgressBar;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// An encoded tile on its way to the writer: compressed bytes of its own, or
/// (uncompressed output) a piece of the resampled chunk, written from there;
/// the chunk's buffer goes back to the resampler when its last tile is
/// written.
pub(super) enum Tile {
    Owned(Vec<u8>),
    Shared { chunk: Option<Arc<Raw>>, range: std::ops::Range<usize>, free: crossbeam_channel::Sender<Raw> },
}

impl AsRef<[u8]> for Tile {
    fn as_ref(&self) -> &[u8] {
        match self {
            Tile::Owned(v) => v,
            Tile::Shared { chunk, range, .. } => &chunk.as_ref().expect("held until dropped").bytes()[range.clone()],
        }
    }
}

impl Drop for Tile {
    fn drop(&mut self) {
        if let Tile::Shared { chunk, free, .. } = self {
            if let Some(Ok(raw)) = chunk.take().map(Arc::try_unwrap) {
                let _ = free.try_send(raw);
            }
        }
    }
}

/// The heights (and ground coordinates) at the GCM nodes of one band.
pub(super) struct DemMsg {
    first_j: i64,
    heights: Vec<NodeHeights>,
}

/// The node rows of the band before, kept for the next: neighbouring bands
/// share the node rows at their edge (two of 18 a band of 256 rows at
/// k = 16, two of 23 at k = 12), which need not be worked out again.
pub(super) struct SharedRows<T> {
    first_j: i64,
    rows: Vec<T>,
}

impl<T> Default for SharedRows<T> {
    fn default() -> Self {
        SharedRows { first_j: 0, rows: Vec::new() }
    }
}

impl<T: Clone> SharedRows<T> {
    /// Rows `j0..=j1`: those of the band before as they were, the others
    /// from `make`; and how many were the band before's.
    fn rows(&mut self, j0: i64, j1: i64, mut make: impl FnMut(i64) -> T) -> (Vec<T>, usize) {
        let mut reused = 0;
        let rows: Vec<T> = (j0..=j1)
            .map(|j| match usize::try_from(j - self.first_j).ok().and_then(|k| self.rows.get(k)) {
                Some(row) => {
                    reused += 1;
                    row.clone()
                }
                None => make(j),
            })
            .collect();
        self.first_j = j0;
        self.rows.clone_from(&rows);
        (rows, reused)
    }
}

/// A chunk's tiles on their way to the encoder: band `band`, walked tile
/// columns from `first_col`.
pub(super) struct Made {
    pub band: u32,
    pub first_col: u32,
    pub raw: Raw,
}

/// What the read step carries from one band to the next.
#[derive(Default)]
pub(super) struct Reader {
    /// Scan windows are copied from here on (see `Run::read`).
    copying: bool,
    /// The scan rows of the band before (for the read-ahead).
    rows_before: Option<(u32, u32)>,
    pub busy: Duration,
}

/// Bytes of output between two background syncs.
const FLUSH_EVERY: usize = 64 << 20;

/// Everything the steps of one run share: its inputs, the grid as walked
/// (transposed for bands of tile columns), where tiles go, the memory
/// shares, the worker pool, and what the run counts.
pub(super) struct Run<'a> {
    pub cfg: &'a RectifyConfig,
    pub gcm: &'a Gcm<'a>,
    pub src: &'a SourceImage,
    pub dem: &'a Dem,
    pub spec: &'a OutputSpec,
    pub walked: OutputGrid,
    /// Bands `bands.0..bands.1` of walked tile columns `cols.0..cols.1`.
    pub bands: (u32, u32),
    pub cols: (u32, u32),
    /// Bands of the output's tile columns.
    pub columns: bool,
    /// The piece's first tile (column, row) and its width in tiles.
    pub piece: (u32, u32, u32),
    pub bands_out: u32,
    /// A 24th of the memory budget, in bytes; in scan pixels; in output tiles.
    pub share: u64,
    pub budget_px: u64,
    pub max_tiles: u32,
    pub pool: rayon::ThreadPool,
    pub progress: ProgressBar,
    pub cancel: &'a AtomicBool,
    pub failed: AtomicBool,
    pub chunks_done: AtomicU64,
    pub chunks_in_place: AtomicU64,
    pub stats: Mutex<GcmStats>,
}

impl<'a> Run<'a> {
    /// Cancelled from outside, or failed in another step.
    pub fn stop(&self) -> bool {
        self.cancel.load(Ordering::Relaxed) || self.failed.load(Ordering::Relaxed)
    }

    /// Records `e` as the run's failure (the other steps stop).
    pub fn fail(&self, e: Error) -> Error {
        self.failed.store(true, Ordering::Relaxed);
        e
    }

    /// Walked rows of band `b`: a band is a row of tiles of the walked grid.
    pub fn band_rows(&self, b: u32) -> (u32, u32) {
        let tile = self.cfg.tile;
        (b * tile, ((b + 1) * tile).min(self.walked.height))
    }

    /// Where the tile of band `band` and walked tile column `col` goes in
    /// the file, row-major.
    fn tile_index(&self, band: u32, col: u32) -> usize {
        let (tc0, tr0, tcw) = self.piece;
        let (row, col) = if self.columns { (col, band) } else { (band, col) };
        ((row - tr0) * tcw + (col - tc0)) as usize
    }

    /// DEM lookup: the heights at the nodes of band `b`.
    pub fn node_heights(&self, b: u32, before: &mut SharedRows<NodeHeights>) -> DemMsg {
        let (y0, y1) = self.band_rows(b);
        let (j0, _, _) = self.gcm.rows_for(y0);
        let (_, j1, _) = self.gcm.rows_for(y1 - 1);
        DemMsg { first_j: j0, heights: before.rows(j0, j1, |j| self.gcm.node_heights(j)).0 }
    }

    /// GCM rows: exact `T` at the band's nodes; a DEM miss under the
    /// `error` policy fails the run.
    pub fn band_gcm(&self, msg: DemMsg, before: &mut SharedRows<crate::gcm::NodeRow>) -> Result<BandGcm> {
        let gcm = self.gcm;
        let mut miss = None;
        let last_j = msg.first_j + msg.heights.len() as i64 - 1;
        let (rows, reused) = before.rows(msg.first_j, last_j, |j| gcm.node_row(j, &msg.heights[(j - msg.first_j) as usize], &mut miss));
        let mut band = gcm.finish_band(msg.first_j, rows, miss);
        // Nodes worked out for this band, not those it shares with the one before.
        band.stats.nodes -= (reused * gcm.nodes_per_row()) as u64;
        if let Some(m) = band.miss {
            return Err(self.fail(dem_miss_error(self.dem, m)));
        }
        self.stats.lock().expect("stats").add(&band.stats);
        Ok(band)
    }

    /// The chunks of band `b` and their scan windows. The band's scan rows,
    /// and as many again the way the bands move through the scan, are asked
    /// for at once where they will be read in place: a scan that is not in
    /// memory yet then comes in large reads ahead of the workers, instead of
    /// small ones that each hold up a worker's fault. Nothing is read where
    /// the rows are in memory.
    pub fn plan(&self, b: u32, band: &BandGcm, reader: &mut Reader) -> Vec<Chunk> {
        let (y0, y1) = self.band_rows(b);
        let (sw, sh) = (self.src.info.width, self.src.info.height);
        let margin = self.cfg.kernel.radius() + 2;
        let chunks = timed(&mut reader.busy, || plan_band(self.gcm, band, y0, y1, self.cfg.tile, (sw, sh), margin, self.budget_px, self.max_tiles, self.cols));
        let rows = band_scan_rows(&chunks);
        if let Some(rows) = rows.filter(|&(r0, r1)| !reader.copying && (r1 - r0) as u64 * sw as u64 * self.src.info.pixel_bytes() as u64 <= 8 * self.share) {
            let (a, b) = read_ahead_rows(rows, reader.rows_before, sh);
            self.src.will_need_rows(a, b - a);
        }
        reader.rows_before = rows;
        chunks
    }

    /// The scan window of `chunk` (of band `b`), into `win` or in place.
    pub fn read(&self, b: u32, band: Arc<BandGcm>, chunk: Chunk, reader: &mut Reader, mut win: Window) -> Result<ReadMsg<'a>> {
        let [c0, r0, c1, r1] = chunk.win;
        // In place when the rows it spans fit six shares (a quarter of the
        // budget): no window is copied (the windows' four shares are free)
        // and the only scan pages resident are the rows of the chunks being
        // resampled (at most whole rows: the kernel maps pages around each
        // fault); the other two shares come from the budget's slack. A tall,
        // narrow window of a turned scan would map far more pages than it
        // uses: copy those. Once one chunk is copied, the rest of the run is
        // copied too: mapped rows on top of the copies' buffers went past
        // the budget (a 4 GiB scan whose bands' rows lie about at the bound
        // peaked at 115–150 MiB; copied throughout, 76–82).
        let span = (r1 - r0) as u64 * self.src.info.width as u64 * self.src.info.pixel_bytes() as u64;
        let in_place = if span <= 6 * self.share && !reader.copying { self.src.mapped_rows(c0, r0, c1 - c0, r1 - r0).map_err(|e| self.fail(e))? } else { None };
        match in_place {
            Some(_) => {
                (win.x0, win.y0, win.w, win.h) = (c0, r0, c1 - c0, r1 - r0);
                self.chunks_in_place.fetch_add(1, Ordering::Relaxed);
            }
            None => {
                // A chunk that sees no pixel of the scan decides nothing.
                reader.copying |= c1 > c0 && r1 > r0;
                timed(&mut reader.busy, || self.src.read_window_on(&self.pool, c0, r0, c1 - c0, r1 - r0, &mut win)).map_err(|e| self.fail(e))?
            }
        }
        Ok(ReadMsg { band: b, gcm: band, chunk, win, in_place })
    }

    /// The chunk's pixels, tile by tile, in the buffer `spare` if given;
    /// or the ground point where the DEM had no height.
    pub fn resample(&self, msg: &ReadMsg, spare: Option<Raw>) -> std::result::Result<Raw, (f64, f64, Lookup)> {
        let (y0, y1) = self.band_rows(msg.band);
        let (gcm, src, cfg, bo) = (self.gcm, self.src, self.cfg, self.bands_out);
        match src.info.sample {
            SampleType::U8 => resample_chunk::<u8>(gcm, src, msg, y0, y1, cfg, bo, spare).map(Raw::U8),
            SampleType::U16 => resample_chunk::<u16>(gcm, src, msg, y0, y1, cfg, bo, spare).map(Raw::U16),
            SampleType::F32 => resample_chunk::<f32>(gcm, src, msg, y0, y1, cfg, bo, spare).map(Raw::F32),
        }
    }

    /// The resampled chunk of band `band` from output column `x0`, counted,
    /// on its way to the encoder; where the DEM had no height (under the
    /// `error` policy), the run's failure.
    pub fn made(&self, band: u32, x0: u32, raw: std::result::Result<Raw, (f64, f64, Lookup)>) -> Result<Made> {
        let raw = raw.map_err(|m| self.fail(dem_miss_error(self.dem, m)))?;
        self.chunks_done.fetch_add(1, Ordering::Relaxed);
        Ok(Made { band, first_col: x0 / self.cfg.tile, raw })
    }

    /// A resampled chunk, passed on as its tiles with their places in the
    /// file: compressed in parallel; uncompressed, pieces of the chunk,
    /// which goes back through `free` when the last is written.
    pub fn tiles(&self, made: Made, free: &crossbeam_channel::Sender<Raw>, busy: &mut Duration) -> Vec<Result<(usize, Tile)>> {
        let Made { band, first_col, raw } = made;
        let tb = self.spec.tile_bytes();
        // The chunk holds whole tiles, one after the other (padded).
        let n = raw.bytes().len() / tb;
        let tiles: Vec<Result<Tile>> = if self.spec.compression == Compression::None {
            let shared = Arc::new(raw);
            (0..n).map(|k| Ok(Tile::Shared { chunk: Some(shared.clone()), range: k * tb..(k + 1) * tb, free: free.clone() })).collect()
        } else {
            let tiles = timed(busy, || {
                let bytes = raw.bytes();
                self.pool.install(|| (0..n).into_par_iter().map(|k| encode_tile(self.spec, bytes[k * tb..(k + 1) * tb].to_vec()).map(Tile::Owned)).collect())
            });
            let _ = free.try_send(raw);
            tiles
        };
        tiles.into_iter().enumerate().map(|(k, tile)| Ok((self.tile_index(band, first_col + k as u32), tile.map_err(|e| self.fail(e))?))).collect()
    }

    /// Writes the tiles `next` gives, in any order, into `out_file`, while
    /// a thread of its own starts the write-back of what is written (under
    /// `--sync`) through `flush_file`, a second handle to the output: the
    /// sync before the rename then has little left to wait for (0.6 s at
    /// the end of a 1 GiB output without it).
    pub fn write(&self, out_file: std::fs::File, flush_file: std::fs::File, mut next: impl FnMut() -> Result<Option<(usize, Tile)>>) -> Result<()> {
        let (tx_flush, rx_flush) = crossbeam_channel::bounded::<()>(1);
        std::thread::scope(|s| {
            if self.cfg.sync {
                s.spawn(move || {
                    // Errors show again, and are reported, at the final sync.
                    for () in rx_flush.iter() {
                        let _ = flush_file.sync_data();
                    }
                });
            }
            let mut unsynced = 0usize;
            let r = write_placed(out_file, self.spec, || -> Result<Option<(usize, Tile)>> {
                if self.cancel.load(Ordering::Relaxed) {
                    return Err(Error::Cancelled);
                }
                let next = next()?;
                if let Some((_, tile)) = &next {
                    self.progress.inc(1);
                    unsynced += tile.as_ref().len();
                    if self.cfg.sync && unsynced >= FLUSH_EVERY {
                        // Never waits: a sync still running takes this one too.
                        let _ = tx_flush.try_send(());
                        unsynced = 0;
                    }
                }
                Ok(next)
            });
            drop(tx_flush);
            match r {
                Ok(()) => Ok(()),
                Err(WriteError::Source(e)) => Err(self.fail(e)),
                Err(WriteError::Tiff(e)) => Err(self.fail(tiff_write_error(&self.cfg.output, e))),
            }
        })
    }
}

fn dem_miss_error(dem: &Dem, (x, y, l): (f64, f64, Lookup)) -> Error {
    let what = match l {
        Lookup::Hole => "a hole (nodata) in the DEM",
        _ => "outside the DEM",
    };
    Error::format(&dem.path, format!("no height at ground point ({x:.2}, {y:.2}), {what}; choose --dem-hole / --dem-outside nodata or a height"))
}

/// Runs `f`, adding its wall time to `acc`.
pub(super) fn timed<R>(acc: &mut Duration, f: impl FnOnce() -> R) -> R {
    let t = Instant::now();
    let r = f();
    *acc += t.elapsed();
    r
}

/// Gives back the mapped scan rows `rows` except those inside `keep`.
pub(super) fn release_outside(src: &SourceImage, rows: (u32, u32), keep: Option<(u32, u32)>) {
    let (a, b) = rows;
    match keep {
        Some((ka, kb)) if ka < b && kb > a => {
            if ka > a {
                src.release_rows(a, ka - a);
            }
            if kb < b {
                src.release_rows(kb, b - kb);
            }
        }
        _ => src.release_rows(a, b - a),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bands_take_the_rows_they_share_with_the_band_before() {
        let mut made = Vec::new();
        let mut before = SharedRows::default();
        let mut rows = |j0, j1, made: &mut Vec<i64>| {
            before.rows(j0, j1, |j| {
                made.push(j);
                j * 10
            })
        };
        assert_eq!(rows(-1, 3, &mut made), (vec![-10, 0, 10, 20, 30], 0));
        // Two rows shared at the edge.
        assert_eq!(rows(2, 6, &mut made), (vec![20, 30, 40, 50, 60], 2));
        // None shared (a jump), then one.
        assert_eq!(rows(9, 10, &mut made), (vec![90, 100], 0));
        assert_eq!(rows(10, 11, &mut made), (vec![100, 110], 1));
        assert_eq!(made, [-1, 0, 1, 2, 3, 4, 5, 6, 9, 10, 11]);
    }
}
