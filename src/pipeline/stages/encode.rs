//! Stage 5, encode: a resampled chunk's tiles, compressed in parallel on
//! the pool; uncompressed output passes pieces of the chunk itself.

use super::resample::{Made, Raw};
use super::timed;
use crate::error::Result;
use crate::io::tiff_out::{encode_mask, encode_tile, Compression};
use crate::overview::{Pyramid, Quarter, Ready, Statistics};
use crate::pipeline::context::Output;
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Duration;

/// An encoded tile on its way to the writer: compressed bytes of its own, or
/// (uncompressed output) a piece of the resampled chunk, written from there;
/// the chunk's buffer goes back to the resampler when its last tile is
/// written.
pub enum Tile {
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

/// A resampled chunk, passed on as its tiles with their places in the
/// file: compressed in parallel; uncompressed, pieces of the chunk, which
/// goes back through `free` when the last is written. Under a mask, each
/// image tile is followed by its mask's tile. With overviews, each tile is
/// also reduced in the same pass, and the overview tiles it finishes
/// follow.
pub fn tiles(run: &Output, made: Made, free: &crossbeam_channel::Sender<Raw>, busy: &mut Duration) -> Vec<Result<(usize, Tile)>> {
    let Made { band, first_col, raw, valid } = made;
    let spec = run.spec;
    let tb = spec.tile_bytes();
    // The chunk holds whole tiles, one after the other (padded).
    let n = raw.bytes().len() / tb;
    let at = |k: usize| run.walk.tile_index(band, first_col + k as u32);
    // A tile's mask (where there is one) and, compressed, the tile itself,
    // and its quarter for the overview: one parallel pass.
    let px = valid.as_ref().map_or(0, |v| v.len() / n.max(1));
    let valid_of = |k: usize| valid.as_ref().map(|v| &v[k * px..(k + 1) * px]);
    // (A mosaic says which pixels have a value also where a nodata value
    // marks the others.)
    let mask = |k: usize| valid_of(k).filter(|_| spec.mask).map(|v| encode_mask(spec, v).map(Tile::Owned));
    let pyramid = run.pyramid.map(|p| p.lock().expect("the encoder's alone"));
    // The tile's quarter for the overview, and its statistics.
    // Without a mask, a pixel has a value as GDAL reads it: by the nodata
    // value (an image's own pixel of that value is a hole to GDAL too).
    let read_as = |k: usize| valid_of(k).filter(|_| spec.mask);
    let summary = |k: usize, bytes: &[u8]| {
        let tile = &bytes[k * tb..(k + 1) * tb];
        let stats = Statistics::of_output_tile(spec, run.valid_by, tile, read_as(k), spec.tile_extent(0, at(k)));
        (pyramid.as_ref().map(|p| p.reduce(0, at(k), tile, read_as(k))), stats)
    };
    // A tile's quarter for the overview and its statistics.
    type Summary = (Option<Quarter>, Statistics);
    type Done = (Result<Tile>, Option<Result<Tile>>, Summary);
    let done: Vec<Done> = if spec.compression == Compression::None {
        let side: Vec<(Option<Result<Tile>>, Summary)> =
            timed(busy, || run.pool.install(|| (0..n).into_par_iter().map(|k| (mask(k), summary(k, raw.bytes()))).collect()));
        let shared = Arc::new(raw);
        side.into_iter()
            .enumerate()
            .map(|(k, (m, q))| (Ok(Tile::Shared { chunk: Some(shared.clone()), range: k * tb..(k + 1) * tb, free: free.clone() }), m, q))
            .collect()
    } else {
        let done = timed(busy, || {
            let bytes = raw.bytes();
            run.pool.install(|| {
                (0..n)
                    .into_par_iter()
                    .map(|k| (encode_tile(spec, 0, bytes[k * tb..(k + 1) * tb].to_vec(), valid_of(k)).map(Tile::Owned), mask(k), summary(k, bytes)))
                    .collect()
            })
        });
        let _ = free.try_send(raw);
        done
    };
    if let Some(v) = valid {
        let _ = run.spare_masks.try_send(v);
    }
    let mut out = Vec::with_capacity(n * if spec.mask { 2 } else { 1 });
    let mut finished = Vec::new();
    let mut pyramid = pyramid;
    let mut statistics = run.statistics.lock().expect("the encoder's alone");
    for (k, (tile, mask, (q, stats))) in done.into_iter().enumerate() {
        statistics.add(at(k) / spec.tiles_across() as usize, &stats);
        out.push(tile.map(|t| (at(k), t)).map_err(|e| run.stop.fail(e)));
        if let Some(mask) = mask {
            out.push(mask.map(|m| (spec.mask_tile(at(k)), m)).map_err(|e| run.stop.fail(e)));
        }
        if let (Some(p), Some(q)) = (pyramid.as_mut(), q) {
            finished.extend(p.place(0, at(k), q));
        }
    }
    if let Some(p) = pyramid.as_mut() {
        overview_tiles(run, p, finished, &mut out, busy);
    }
    out
}

/// The overview tiles `finished` (and those they finish in turn, level
/// after level): each compressed and its mask's tile made, in parallel.
fn overview_tiles(run: &Output, pyramid: &mut Pyramid, finished: Vec<Ready>, out: &mut Vec<Result<(usize, Tile)>>, busy: &mut Duration) {
    let spec = run.spec;
    timed(busy, || {
        run.pool.install(|| {
            pyramid.cascade(
                finished,
                |t| {
                    let mask = spec.mask.then(|| encode_mask(spec, &t.valid));
                    (encode_tile(spec, t.level, t.pixels, Some(&t.valid)), mask)
                },
                |l, k, (tile, mask)| {
                    out.push(tile.map(|t| (spec.chunk_index(l, k, false), Tile::Owned(t))).map_err(|e| run.stop.fail(e)));
                    if let Some(m) = mask {
                        out.push(m.map(|m| (spec.chunk_index(l, k, true), Tile::Owned(m))).map_err(|e| run.stop.fail(e)));
                    }
                },
            )
        })
    });
}
