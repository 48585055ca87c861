//! Stage 3, read: plan a band's chunks (which groups of output tiles to
//! resample together, and which window of the scan each needs), then read
//! each chunk's window — in place from the mapped scan where it can, copied
//! or decoded where not. Like GDAL's chunk list: the source window of a
//! chunk is found from a lattice of samples of `A + c`, and tiles are
//! grouped left to right while the window stays under the memory budget.

use super::timed;
use crate::error::Result;
use crate::gcm::{BandGcm, Gcm};
use crate::geom::Span;
use crate::io::source::{SourceImage, Window};
use crate::pipeline::context::Run;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

/// A chunk's scan window on its way to the resampler.
pub struct ReadMsg<'a> {
    pub band: u32,
    pub gcm: Arc<BandGcm>,
    pub chunk: Chunk,
    pub win: Window,
    /// The window's rows in place in the mapped scan (then `win` only
    /// carries the position), and their stride in bytes.
    pub in_place: Option<(&'a [u8], usize)>,
}

/// What the read stage carries from one band to the next.
#[derive(Default)]
pub struct Reader {
    /// Scan windows are copied from here on (see [`read`]).
    copying: bool,
    /// The scan rows of the band before (for the read-ahead).
    rows_before: Option<(u32, u32)>,
    pub busy: Duration,
}

/// The chunks of band `b` and their scan windows. The band's scan rows,
/// and as many again the way the bands move through the scan, are asked
/// for at once where they will be read in place: a scan that is not in
/// memory yet then comes in large reads ahead of the workers, instead of
/// small ones that each hold up a worker's fault. Nothing is read where
/// the rows are in memory.
pub fn plan(run: &Run, b: u32, band: &BandGcm, reader: &mut Reader) -> Vec<Chunk> {
    let (src, walk) = (run.inputs.src, &run.walk);
    let (y0, y1) = walk.band_rows(b);
    let (sw, sh) = (src.info.width, src.info.height);
    let margin = run.inputs.pixels.kernel.radius() + run.inputs.pixels.footprint + 2;
    let (budget_px, max_tiles) = (run.budget.window_pixels(src.info.pixel_bytes()), run.budget.chunk_tiles(run.inputs.chunk_tile_bytes()));
    let chunks = timed(&mut reader.busy, || plan_band(run.inputs.gcm, band, y0, y1, walk.tile, (sw, sh), margin, budget_px, max_tiles, walk.cols));
    let rows = band_scan_rows(&chunks);
    if let Some(rows) = rows.filter(|&(r0, r1)| !reader.copying && (r1 - r0) as u64 * sw as u64 * src.info.pixel_bytes() as u64 <= run.budget.mapped_rows()) {
        let (a, b) = read_ahead_rows(rows, reader.rows_before, sh);
        src.will_need_rows(a, b - a);
    }
    reader.rows_before = rows;
    chunks
}

/// The scan window of `chunk` (of band `b`), into `win` or in place.
pub fn read<'a>(run: &Run<'a>, b: u32, band: Arc<BandGcm>, chunk: Chunk, reader: &mut Reader, mut win: Window) -> Result<ReadMsg<'a>> {
    let src = run.inputs.src;
    let [c0, r0, c1, r1] = chunk.win;
    // In place when the rows it spans fit the budget's in-place share: no
    // window is copied and the only scan pages resident are the rows of the
    // chunks being resampled (at most whole rows: the kernel maps pages
    // around each fault). A tall, narrow window of a turned scan would map
    // far more pages than it uses: copy those. Once one chunk is copied,
    // the rest of the run is copied too: mapped rows on top of the copies'
    // buffers would go past the budget.
    if !chunk.strips.is_empty() {
        // Made strip by strip: the resampler reads each strip's window.
        (win.x0, win.y0, win.w, win.h) = (c0, r0, 0, 0);
        return Ok(ReadMsg { band: b, gcm: band, chunk, win, in_place: None });
    }
    let span = (r1 - r0) as u64 * src.info.width as u64 * src.info.pixel_bytes() as u64;
    let in_place =
        if span <= run.budget.in_place_rows() && !reader.copying { src.mapped_rows(c0, r0, c1 - c0, r1 - r0).map_err(|e| run.stop.fail(e))? } else { None };
    match in_place {
        Some(_) => {
            (win.x0, win.y0, win.w, win.h) = (c0, r0, c1 - c0, r1 - r0);
            run.counters.chunks_in_place.fetch_add(1, Ordering::Relaxed);
        }
        None => {
            // A chunk that sees no pixel of the scan decides nothing.
            reader.copying |= c1 > c0 && r1 > r0;
            timed(&mut reader.busy, || src.read_window_on(run.pool, c0, r0, c1 - c0, r1 - r0, &mut win)).map_err(|e| run.stop.fail(e))?
        }
    }
    Ok(ReadMsg { band: b, gcm: band, chunk, win, in_place })
}

/// Gives back the mapped scan rows `rows` except those inside `keep`.
pub fn release_outside(src: &SourceImage, rows: (u32, u32), keep: Option<(u32, u32)>) {
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

/// A run of output tiles of one band and the scan window it reads.
#[derive(Clone, Debug, PartialEq)]
pub struct Chunk {
    /// Output columns `[x0, x1)`.
    pub x0: u32,
    pub x1: u32,
    /// Scan window `[c0, c1) × [r0, r1)`, clipped to the scan; empty when no
    /// pixel of the chunk sees the scan.
    pub win: [u32; 4],
    /// A single tile whose window would pass the budget (its pixels cover
    /// many scan pixels each) is made piece by piece, each piece (a strip
    /// of its rows, cut across too where needed) reading its own window:
    /// these, in order; none for other chunks.
    pub strips: Vec<Strip>,
}

/// Rows `[rows.0, rows.1)` of a chunk's band (counted from its first),
/// its columns `[cols.0, cols.1)` (from the chunk's first), and the scan
/// window they read.
#[derive(Clone, Debug, PartialEq)]
pub struct Strip {
    pub rows: (u32, u32),
    pub cols: (u32, u32),
    pub win: [u32; 4],
}

/// Source bounding boxes of the tiles of output rows `[y0, y1)`, from a
/// lattice of samples: every 16th row and column, the band's first and last
/// rows and every tile's first and last columns. `A + c` is smooth between
/// samples; a pixel that still falls outside its window is read on its own
/// by the resampler, so a box can never be wrong, only too small.
fn tile_bboxes(gcm: &Gcm<'_>, band: &BandGcm, y0: u32, y1: u32, tile: u32, (t0, t1): (u32, u32)) -> Vec<Option<[f64; 4]>> {
    let width = gcm.t.grid.width;
    let tiles = (t1 - t0) as usize;
    // Output columns [x_lo, x_lo + w) of the tiles t0..t1.
    let x_lo = (t0 * tile) as usize;
    let w = (t1 * tile).min(width) as usize - x_lo;
    let mut cols = vec![0.0; w];
    let mut rows = vec![0.0; w];
    let mut miss = None;
    let mut boxes: Vec<Option<[f64; 4]>> = vec![None; tiles];
    let mut ys: Vec<u32> = (y0..y1).step_by(16).collect();
    ys.push(y1 - 1);
    let grow = |b: &mut Option<[f64; 4]>, (c, r): (f64, f64)| {
        if c.is_finite() && r.is_finite() {
            *b = Some(match *b {
                None => [c, r, c, r],
                Some(o) => [o[0].min(c), o[1].min(r), o[2].max(c), o[3].max(r)],
            });
        }
    };
    let tile = tile as usize;
    let mut spans = Vec::new();
    for &y in &ys {
        if gcm.row_spans(band, y, x_lo as u32, w, &mut spans) && spans.iter().all(|s| s.stepped) {
            // Stepped spans: their bounds (cut at tile edges) hold them.
            for (t, piece) in Span::by_tile(&spans, x_lo, tile) {
                let b = piece.bounds();
                grow(&mut boxes[t], (b[0], b[1]));
                grow(&mut boxes[t], (b[2], b[3]));
            }
            continue;
        }
        gcm.fill_row(band, y, x_lo as u32, &mut cols, &mut rows, &mut miss);
        for (t, b) in boxes.iter_mut().enumerate() {
            let (x0, x1) = (t * tile, ((t + 1) * tile).min(w));
            for x in (x0..x1).step_by(16).chain(std::iter::once(x1 - 1)) {
                grow(b, (cols[x], rows[x]));
            }
        }
    }
    boxes
}

/// Splits band rows `[y0, y1)`, tile columns `[t0, t1)`, into chunks of
/// whole tiles whose scan windows
/// hold at most `budget_px` pixels and that count at most `max_tiles`
/// tiles (a single tile may exceed the budget).
#[allow(clippy::too_many_arguments)] // the band, the scan and the budget, each a plain number
pub fn plan_band(
    gcm: &Gcm<'_>,
    band: &BandGcm,
    y0: u32,
    y1: u32,
    tile: u32,
    scan: (u32, u32),
    margin: u32,
    budget_px: u64,
    max_tiles: u32,
    (t0, t1): (u32, u32),
) -> Vec<Chunk> {
    let width = gcm.t.grid.width;
    let clip = |b: [f64; 4]| -> [u32; 4] {
        let m = margin as f64;
        let c0 = (b[0] - m).floor().clamp(0.0, scan.0 as f64) as u32;
        let r0 = (b[1] - m).floor().clamp(0.0, scan.1 as f64) as u32;
        let c1 = (b[2] + m).ceil().clamp(0.0, scan.0 as f64) as u32;
        let r1 = (b[3] + m).ceil().clamp(0.0, scan.1 as f64) as u32;
        [c0, r0, c1.max(c0), r1.max(r0)]
    };
    let area = |w: &[u32; 4]| (w[2] - w[0]) as u64 * (w[3] - w[1]) as u64;
    let union = |a: Option<[f64; 4]>, b: Option<[f64; 4]>| match (a, b) {
        (Some(a), Some(b)) => Some([a[0].min(b[0]), a[1].min(b[1]), a[2].max(b[2]), a[3].max(b[3])]),
        (a, None) => a,
        (None, b) => b,
    };
    let boxes = tile_bboxes(gcm, band, y0, y1, tile, (t0, t1));
    let mut chunks = Vec::new();
    let mut start = t0;
    let mut acc: Option<[f64; 4]> = None;
    for t in t0..t1 {
        let x0 = t * tile;
        let bb = boxes[(t - t0) as usize];
        let merged = union(acc, bb);
        let fits = merged.map(|m| area(&clip(m)) <= budget_px).unwrap_or(true);
        if t > start && (!fits || t - start >= max_tiles) {
            chunks.push(Chunk { x0: start * tile, x1: x0, win: acc.map(clip).unwrap_or([0; 4]), strips: Vec::new() });
            start = t;
            acc = bb;
        } else {
            acc = merged;
        }
    }
    chunks.push(Chunk { x0: start * tile, x1: (t1 * tile).min(width), win: acc.map(clip).unwrap_or([0; 4]), strips: Vec::new() });
    // A single tile past the budget: strips of rows whose windows fit,
    // fewer rows a strip where one does not, down to one row; then strips
    // cut across (a scan turned against the output, where a row's window
    // crosses much of the scan), down to 16 columns.
    for c in chunks.iter_mut().filter(|c| c.x1 - c.x0 <= tile && area(&c.win) > budget_px) {
        let (chunk_w, band_rows) = (c.x1 - c.x0, y1 - y0);
        let mut per = ((band_rows as u64 * budget_px / area(&c.win).max(1)) as u32).clamp(1, band_rows);
        // In whole groups of 16 rows where a strip holds more (the
        // resampler then makes a transposed chunk's rows 16 a task, not
        // one: a piece of every pixel of a large tile is tens of MB).
        if per >= 16 {
            per -= per % 16;
        }
        let mut across = tile;
        c.strips = loop {
            let mut strips = Vec::new();
            for a in (y0..y1).step_by(per as usize) {
                let b = (a + per).min(y1);
                let first = c.x0 / across;
                let boxes = tile_bboxes(gcm, band, a, b, across, (first, first + chunk_w.div_ceil(across)));
                for (k, bb) in boxes.into_iter().enumerate() {
                    let xa = k as u32 * across;
                    strips.push(Strip { rows: (a - y0, b - y0), cols: (xa, (xa + across).min(chunk_w)), win: bb.map(clip).unwrap_or([0; 4]) });
                }
            }
            let narrowest = per == 1 && (across <= 16 || across % 2 == 1);
            if narrowest || strips.iter().all(|s| area(&s.win) <= budget_px) {
                break strips;
            }
            if per > 1 {
                per = per.div_ceil(2);
            } else {
                across /= 2;
            }
        };
    }
    chunks
}

/// The scan rows `[r0, r1)` that a band's chunks read (their windows'
/// rows, hull of those that see the scan), if any.
pub fn band_scan_rows(chunks: &[Chunk]) -> Option<(u32, u32)> {
    chunks
        .iter()
        .filter(|c| c.win[2] > c.win[0] && c.win[3] > c.win[1])
        .fold(None, |acc, c| Some(acc.map_or((c.win[1], c.win[3]), |(a, b): (u32, u32)| (a.min(c.win[1]), b.max(c.win[3])))))
}

/// The scan rows to ask for ahead when a band reads `rows`: those, and as
/// many again the way the bands move through the scan (down unless this
/// band starts above the one `before`), within the scan's `height` rows.
pub fn read_ahead_rows(rows: (u32, u32), before: Option<(u32, u32)>, height: u32) -> (u32, u32) {
    let (r0, r1) = rows;
    let ext = r1 - r0;
    if before.is_none_or(|(p0, _)| p0 <= r0) {
        (r0, r1.saturating_add(ext).min(height))
    } else {
        (r0.saturating_sub(ext), r1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_band_reads_ahead_the_way_the_bands_move() {
        let chunk = |win: [u32; 4]| Chunk { x0: 0, x1: 256, win, strips: Vec::new() };
        // A chunk that sees no scan (empty window) does not count.
        let chunks = [chunk([0, 120, 50, 400]), chunk([40, 100, 90, 380]), chunk([0, 0, 0, 0]), chunk([5, 900, 5, 990])];
        assert_eq!(band_scan_rows(&chunks), Some((100, 400)));
        assert_eq!(band_scan_rows(&chunks[2..]), None);
        // First band, and bands moving down: the rows and as many below.
        assert_eq!(read_ahead_rows((100, 400), None, 10_000), (100, 700));
        assert_eq!(read_ahead_rows((100, 400), Some((0, 130)), 10_000), (100, 700));
        // Moving up (a scan turned 180°): as many above.
        assert_eq!(read_ahead_rows((100, 400), Some((350, 650)), 10_000), (0, 400));
        assert_eq!(read_ahead_rows((500, 800), Some((750, 1000)), 10_000), (200, 800));
        // Never past the scan's last row.
        assert_eq!(read_ahead_rows((9_800, 9_990), Some((9_500, 9_810)), 10_000), (9_800, 10_000));
    }
}
