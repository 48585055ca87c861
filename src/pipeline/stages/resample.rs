//! Stage 4, resample: a chunk's output pixels, row by row across the
//! chunk, written tile by tile into one buffer (in parallel on the pool).

use super::holes::ScanHoles;
use super::read::ReadMsg;
pub use super::resample_row::{off_nodata, Miss};
use super::resample_row::{RowMaker, RowScratch};
use crate::error::Result;
use crate::gcm::Gcm;
use crate::io::source::{SampleType, SourceImage, SourceInfo, Window};
use crate::pipeline::context::{PixelOptions, Run};
use crate::resample::{Sample, View};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// A resampled chunk's tiles on their way to the encoder: band `band`,
/// walked tile columns from `first_col`.
pub struct Made {
    pub band: u32,
    pub first_col: u32,
    pub raw: Raw,
    /// Under a mask: 1 where a pixel has a value, laid out as `raw`'s pixels.
    pub valid: Option<Vec<u8>>,
}

/// A chunk's pixels, and under a mask which of them have a value.
pub type Pixels = (Raw, Option<Vec<u8>>);

/// Why a chunk could not be made: a DEM miss under the `error` policy, or
/// a strip's window that could not be read.
#[derive(Debug)]
pub enum Failed {
    Miss(Miss),
    Read(crate::error::Error),
}

/// The chunk's pixels, tile by tile, in the buffer `spare` if given (and
/// under a mask, which have a value); or the ground point where the DEM
/// had no height.
pub fn resample(run: &Run, msg: &ReadMsg, spare: Option<Raw>) -> std::result::Result<Pixels, Failed> {
    let (y0, y1) = run.walk.band_rows(msg.band);
    let (gcm, src, opts) = (run.inputs.gcm, run.inputs.src, run.inputs.pixels);
    let spare = (spare, run.spare_masks.1.try_recv().ok());
    let counts = (&run.counters.exact_pixels, &run.counters.nudged);
    match src.info.sample {
        SampleType::U8 => resample_chunk::<u8>(gcm, src, msg, y0, y1, opts, spare, counts).map(|(p, v)| (Raw::U8(p), v)),
        SampleType::U16 => resample_chunk::<u16>(gcm, src, msg, y0, y1, opts, spare, counts).map(|(p, v)| (Raw::U16(p), v)),
        SampleType::F32 => resample_chunk::<f32>(gcm, src, msg, y0, y1, opts, spare, counts).map(|(p, mut v)| {
            // A float scan's NaN (its holes) has no value under the mask
            // either, as it has none under NaN as nodata.
            if let Some(v) = v.as_mut() {
                let b = src.info.bands as usize;
                for (ok, px) in v.iter_mut().zip(p.chunks_exact(b)) {
                    if px.iter().any(|s| s.is_nan()) {
                        *ok = 0;
                    }
                }
            }
            (Raw::F32(p), v)
        }),
    }
}

/// The resampled chunk of band `band` from output column `x0`, counted,
/// on its way to the encoder; where the DEM had no height (under the
/// `error` policy), the run's failure.
pub fn made(run: &Run, band: u32, x0: u32, pixels: std::result::Result<Pixels, Failed>) -> Result<Made> {
    let (raw, valid) = pixels.map_err(|f| {
        run.stop.fail(match f {
            Failed::Miss(m) => super::gcm::dem_miss_error(run.inputs.dem, m),
            Failed::Read(e) => e,
        })
    })?;
    run.counters.chunks_done.fetch_add(1, Ordering::Relaxed);
    Ok(Made { band, first_col: x0 / run.walk.tile, raw, valid })
}

/// The output pixels of one chunk, tile by tile, in the output sample type.
pub enum Raw {
    U8(Vec<u8>),
    U16(Vec<u16>),
    F32(Vec<f32>),
}

/// Output buffers handed back by the encoder for the next chunk: allocating
/// and freeing multi-MB buffers on different threads leaves the allocator's
/// per-thread arenas holding tens of MB nobody uses.
pub trait Recycle: Sized {
    fn take(raw: Option<Raw>) -> Vec<Self>;
}

macro_rules! recycle {
    ($t:ty, $v:ident) => {
        impl Recycle for $t {
            fn take(raw: Option<Raw>) -> Vec<$t> {
                match raw {
                    Some(Raw::$v(v)) => v,
                    _ => Vec::new(),
                }
            }
        }
    };
}
recycle!(u8, U8);
recycle!(u16, U16);
recycle!(f32, F32);

impl Raw {
    pub fn bytes(&self) -> &[u8] {
        match self {
            Raw::U8(v) => v,
            Raw::U16(v) => bytemuck::cast_slice(v),
            Raw::F32(v) => bytemuck::cast_slice(v),
        }
    }
}

/// The chunk's scan window as samples of type `T`.
fn view<'v, T: Sample>(msg: &'v ReadMsg, info: &SourceInfo) -> View<'v, T> {
    let w = &msg.win;
    match msg.in_place {
        Some((bytes, stride)) => {
            let data = bytemuck::try_cast_slice(bytes).expect("mapped_rows checks alignment");
            View::in_place(data, w.x0, w.y0, w.w, w.h, stride / info.pixel_bytes(), info.bands, info.width, info.height)
        }
        None => View::new(w, info.bands, info.width, info.height),
    }
}

/// Rows of a transposed chunk made by one task: the most of 128, 64, 32
/// and 16 (a tile is a multiple of 16) that divides the tile. Each task
/// writes its rows across the whole chunk, so fewer, larger tasks sweep it
/// fewer times; one task a chunk would leave the second worker idle.
fn column_group(tile: usize) -> usize {
    [128, 64, 32, 16].into_iter().find(|g| tile.is_multiple_of(*g)).unwrap_or(1)
}
/// Resamples the rows of one chunk (and under a mask, says which pixels
/// have a value, 1 a byte, laid out as the pixels); returns a DEM miss
/// under the `error` policy.
#[allow(clippy::type_complexity)] // the pixels and their validity
#[allow(clippy::too_many_arguments)] // the chunk, its options and buffers, and the count of exact pixels
pub fn resample_chunk<T: Sample + Recycle>(
    gcm: &Gcm<'_>,
    src: &SourceImage,
    msg: &ReadMsg,
    y0: u32,
    y1: u32,
    opts: PixelOptions,
    (spare, spare_mask): (Option<Raw>, Option<Vec<u8>>),
    (exact, nudged): (&AtomicU64, &AtomicU64),
) -> std::result::Result<(Vec<T>, Option<Vec<u8>>), Failed> {
    let info = &src.info;
    let bands_in = info.bands as usize;
    let bo = opts.bands_out as usize;
    let (x0, x1) = (msg.chunk.x0, msg.chunk.x1);
    let w = (x1 - x0) as usize;
    let fill = T::from_f32(opts.fill as f32);
    let opaque = T::from_f32(match T::TYPE {
        SampleType::U8 => 255.0,
        SampleType::U16 => 65535.0,
        SampleType::F32 => 1.0,
    });
    // Every sample is written below: keep what the buffer holds.
    let mut out = T::take(spare);
    // Tile-major: the chunk's tiles one after the other, each `tile` rows
    // of `tile` pixels; what lies beyond the grid's right or bottom edge is
    // zero (the writer sends tiles as they are).
    let t = opts.tile as usize;
    let rows = (y1 - y0) as usize;
    let n_tiles = w.div_ceil(t);
    // Exactly: grown by doubling, the buffers of chunks in flight held up
    // to twice their share (the panoramic strip's peak 8 MB over).
    out.reserve_exact((n_tiles * t * t * bo).saturating_sub(out.len()));
    out.resize(n_tiles * t * t * bo, T::default());
    // Made row by row across the whole chunk, so that the kernel walks the
    // scan's rows in long runs (~10 % faster than tile by tile on a 1 GiB
    // scan). In bands of tile rows each task makes one row, and its pieces
    // are that row of each tile. Walked transposed (bands of tile columns),
    // the rows made are the tiles' columns: each task makes `column_group`
    // of them, and its pieces are their stretch of every tile row, one
    // piece for each pixel of the rows made, which goes into it at the
    // row's place.
    let transposed = gcm.t.is_transposed();
    // A chunk made strip by strip (its window would pass the budget) takes
    // its rows one a task, so that a strip's rows are its tasks'.
    let by_strips = !msg.chunk.strips.is_empty();
    let group = match (transposed, by_strips) {
        (false, _) => 1,
        (true, false) => column_group(t),
        // As many as every strip's rows are a whole number of.
        (true, true) => {
            let mut g = column_group(t);
            while g > 1
                && msg
                    .chunk
                    .strips
                    .iter()
                    .any(|s| !(s.rows.0 as usize).is_multiple_of(g) || (!(s.rows.1 as usize).is_multiple_of(g) && s.rows.1 as usize != rows))
            {
                g /= 2;
            }
            g
        }
    };
    let piece_len = if transposed { group * bo } else { t * bo };
    let groups = t / group;
    // A task's rows (of `w` pixels) lie `stride` pixels apart.
    let stride = if transposed { super::transpose::block_stride(w, bands_in * std::mem::size_of::<T>()) } else { w };
    let mut pieces: Vec<Vec<&mut [T]>> = (0..groups).map(|_| Vec::with_capacity(out.len() / piece_len / groups)).collect();
    for (k, piece) in out.chunks_exact_mut(piece_len).enumerate() {
        pieces[k % groups].push(piece);
    }
    // The mask's bytes, cut into the pixels' pieces (none without a mask).
    // (Every byte is written below, as every sample is.)
    let mut mask = if opts.mask { spare_mask.unwrap_or_default() } else { Vec::new() };
    let mask_len = if opts.mask { n_tiles * t * t } else { 0 };
    mask.reserve_exact(mask_len.saturating_sub(mask.len()));
    mask.resize(mask_len, 0);
    let mut mask_pieces: Vec<Vec<&mut [u8]>> = (0..groups).map(|_| Vec::new()).collect();
    for (k, piece) in mask.chunks_exact_mut(piece_len / bo).enumerate() {
        mask_pieces[k % groups].push(piece);
    }
    let direct = bo == bands_in;
    let holes = ScanHoles::of(src, opts.holes, opts.kernel);
    // The scan windows the rows are made from: the chunk's own, read by the
    // read stage; or, for a chunk whose window would pass the budget (an
    // output pixel far larger than a scan pixel), one a strip of its rows,
    // read here in turn.
    #[allow(clippy::type_complexity)] // rows, columns, window
    let strips: Vec<(std::ops::Range<usize>, std::ops::Range<usize>, [u32; 4])> = if by_strips {
        msg.chunk.strips.iter().map(|s| (s.rows.0 as usize..s.rows.1 as usize, s.cols.0 as usize..s.cols.1 as usize, s.win)).collect()
    } else {
        vec![(0..rows, 0..w, msg.chunk.win)]
    };
    let mut own = Window::default();
    let mut first_miss = None;
    for (range, cx, [c0, r0, c1, r1]) in strips {
        let view = if by_strips {
            src.read_window(c0, r0, c1 - c0, r1 - r0, &mut own).map_err(Failed::Read)?;
            View::new(&own, info.bands, info.width, info.height)
        } else {
            view::<T>(msg, info)
        }
        .with_area(opts.area);
        // Where the kernel stays inside the window (or the window reaches the
        // scan's edge, where clamping is the intended behaviour).
        let r = opts.kernel.radius() as f64 + 1.0;
        let safe = [
            if c0 == 0 { f64::NEG_INFINITY } else { c0 as f64 + r },
            if r0 == 0 { f64::NEG_INFINITY } else { r0 as f64 + r },
            if c1 == info.width { f64::INFINITY } else { c1 as f64 - r },
            if r1 == info.height { f64::INFINITY } else { r1 as f64 - r },
        ];
        let placing = Placing { group, rows, stride, w, t, bo, bands_in, direct, opaque };
        let maker = RowMaker { gcm, band: &msg.gcm, src, view, opts: &opts, holes: holes.as_ref(), safe, fill, bands_in, direct, x0, y0, exact, nudged };
        let misses: Vec<Option<Miss>> = pieces
            .par_iter_mut()
            .zip(mask_pieces.par_iter_mut())
            .with_min_len((8 / group).max(1))
            .enumerate()
            .map_init(
                // The rows of a task, one after the other.
                || (RowScratch::default(), super::task_block::TaskBlock::<T>::zeroed(group * stride * bands_in), vec![false; group * w]),
                |(scratch, block, valid_block), (g, (row_pieces, mask_pieces))| {
                    let block = block.as_mut_slice();
                    // (Rows of other strips are theirs; one a task then.)
                    if g * group < rows && !range.contains(&(g * group)) {
                        return None;
                    }
                    let task = Task { g, cx: cx.clone(), scratch, block, valid_block, row_pieces, mask_pieces };
                    if transposed {
                        placing.transposed(&maker, task)
                    } else {
                        placing.rows(&maker, task)
                    }
                },
            )
            .collect();
        first_miss = first_miss.or(misses.into_iter().flatten().next());
    }
    match first_miss {
        Some(m) => Err(Failed::Miss(m)),
        None => Ok((out, opts.mask.then_some(mask))),
    }
}
/// How a chunk's rows go into its tiles: what every task of it shares.
struct Placing<T> {
    /// Rows a task makes.
    group: usize,
    /// The chunk's rows and width, the tile's side.
    rows: usize,
    w: usize,
    t: usize,
    /// Pixels apart, the rows a transposed task makes.
    stride: usize,
    bands_in: usize,
    bo: usize,
    direct: bool,
    /// The alpha band's value of a pixel with a value.
    opaque: T,
}

/// One task of a chunk: its index, the columns it makes, its buffers, and
/// the pieces of the tiles it fills.
struct Task<'t, 'p, T> {
    g: usize,
    cx: std::ops::Range<usize>,
    scratch: &'t mut RowScratch,
    block: &'t mut [T],
    valid_block: &'t mut [bool],
    row_pieces: &'t mut [&'p mut [T]],
    mask_pieces: &'t mut [&'p mut [u8]],
}

impl<T: Sample> Placing<T> {
    /// Task `g` of a chunk walked transposed (bands of tile columns): its
    /// rows are the tiles' columns, made into `block` and gathered, pixel
    /// by pixel, into the pieces of every tile row.
    fn transposed(&self, maker: &RowMaker<'_, T>, task: Task<'_, '_, T>) -> Option<Miss> {
        let Task { g, cx, scratch, block, valid_block, row_pieces, mask_pieces } = task;
        let Placing { group, rows, w, stride, bands_in, bo, direct, opaque, .. } = *self;
        let mut miss = None;
        for j in 0..group {
            let at = j * stride * bands_in;
            let (px, valid) = (&mut block[at..at + w * bands_in], &mut valid_block[j * w..(j + 1) * w]);
            if g * group + j < rows {
                maker.make(g * group + j, cx.clone(), scratch, px, valid, &mut miss);
            } else {
                // Beyond the grid's edge: zero.
                px.fill(T::default());
                valid.fill(false);
            }
        }
        // Piece x takes pixel x of each row made (those of
        // columns `cx`; the pieces past the grid's edge zero).
        // Where every pixel of the block has a value (nearly
        // every block), whole pieces at once: byte by byte,
        // this took 0.28 s of a 1 GiB scan's 4.6 s.
        let all_valid = !mask_pieces.is_empty()
            && (0..group).all(|j| {
                let row: &[u8] = bytemuck::cast_slice(&valid_block[j * w + cx.start..j * w + cx.end]);
                !row.contains(&0)
            });
        for (x, piece) in mask_pieces.iter_mut().enumerate().filter(|(x, _)| cx.contains(x) || *x >= w) {
            if x >= w || all_valid {
                piece.fill(u8::from(x < w));
                continue;
            }
            for (j, to) in piece.iter_mut().enumerate() {
                *to = u8::from(valid_block[j * w + x]);
            }
        }
        let (seen, pad) = row_pieces.split_at_mut(w);
        let seen = &mut seen[cx.clone()];
        if direct {
            let px_bytes = bands_in * std::mem::size_of::<T>();
            let from: &[u8] = bytemuck::cast_slice(block);
            super::transpose::gather(&from[cx.start * px_bytes..], group, stride, px_bytes, seen);
        } else {
            for (x, piece) in seen.iter_mut().enumerate().map(|(i, p)| (i + cx.start, p)) {
                for (j, to) in piece.chunks_exact_mut(bo).enumerate() {
                    let at = (j * stride + x) * bands_in;
                    to[..bands_in].copy_from_slice(&block[at..at + bands_in]);
                    to[bands_in] = if valid_block[j * w + x] { opaque } else { T::default() };
                }
            }
        }
        pad.iter_mut().for_each(|p| p.fill(T::default()));
        miss
    }

    /// Task `g` of a chunk walked in bands of tile rows: each row made,
    /// then its stretch in each tile copied into that tile's piece.
    fn rows(&self, maker: &RowMaker<'_, T>, task: Task<'_, '_, T>) -> Option<Miss> {
        let Task { g, cx, scratch, block, valid_block, row_pieces, mask_pieces } = task;
        let Placing { group, rows, w, t, bands_in, bo, direct, opaque, .. } = *self;
        let mut miss = None;
        let (px, valid) = (block, valid_block);
        for j in 0..group {
            let r = g * group + j;
            if r >= rows {
                // Below the grid's edge.
                row_pieces.iter_mut().for_each(|p| p.fill(T::default()));
                mask_pieces.iter_mut().for_each(|p| p.fill(0));
                continue;
            }
            maker.make(r, cx.clone(), scratch, px, valid, &mut miss);
            // Each tile's stretch of the row: of it, the columns `cx`.
            let part = |tx: usize| {
                let (xs, n) = (tx * t, t.min(w - tx * t));
                (xs, n, cx.start.clamp(xs, xs + n) - xs..cx.end.clamp(xs, xs + n) - xs)
            };
            for (tx, piece) in mask_pieces.iter_mut().enumerate() {
                let (xs, n, own) = part(tx);
                piece[own.clone()].copy_from_slice(bytemuck::cast_slice(&valid[xs + own.start..xs + own.end]));
                piece[n..].fill(0);
            }
            for (tx, piece) in row_pieces.iter_mut().enumerate() {
                let (xs, n, own) = part(tx);
                let (seg_out, pad) = piece.split_at_mut(n * bo);
                pad.fill(T::default());
                if direct {
                    seg_out[own.start * bo..own.end * bo].copy_from_slice(&px[(xs + own.start) * bands_in..(xs + own.end) * bands_in]);
                } else {
                    for i in own {
                        let s = (xs + i) * bands_in;
                        seg_out[i * bo..i * bo + bands_in].copy_from_slice(&px[s..s + bands_in]);
                        seg_out[i * bo + bands_in] = if valid[xs + i] { opaque } else { T::default() };
                    }
                }
            }
        }
        miss
    }
}
