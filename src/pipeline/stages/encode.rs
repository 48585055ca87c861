//! Stage 5, encode: a resampled chunk's tiles, compressed in parallel on
//! the pool; uncompressed output passes pieces of the chunk itself.

use super::resample::{Made, Raw};
use super::timed;
use crate::error::Result;
use crate::io::tiff_out::{encode_mask, encode_tile, Compression};
use crate::pipeline::context::Run;
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
/// image tile is followed by its mask's tile.
pub fn tiles(run: &Run, made: Made, free: &crossbeam_channel::Sender<Raw>, busy: &mut Duration) -> Vec<Result<(usize, Tile)>> {
    let Made { band, first_col, raw, valid } = made;
    let spec = run.inputs.spec;
    let tb = spec.tile_bytes();
    // The chunk holds whole tiles, one after the other (padded).
    let n = raw.bytes().len() / tb;
    // A tile's mask (where there is one) and, compressed, the tile itself:
    // one parallel pass.
    let px = valid.as_ref().map_or(0, |v| v.len() / n.max(1));
    let mask = |k: usize| valid.as_ref().map(|v| encode_mask(spec, &v[k * px..(k + 1) * px]).map(Tile::Owned));
    let (tiles, masks): (Vec<Result<Tile>>, Vec<Option<Result<Tile>>>) = if spec.compression == Compression::None {
        let masks = timed(busy, || run.pool.install(|| (0..n).into_par_iter().map(mask).collect()));
        let shared = Arc::new(raw);
        ((0..n).map(|k| Ok(Tile::Shared { chunk: Some(shared.clone()), range: k * tb..(k + 1) * tb, free: free.clone() })).collect(), masks)
    } else {
        let pairs = timed(busy, || {
            let bytes = raw.bytes();
            run.pool.install(|| (0..n).into_par_iter().map(|k| (encode_tile(spec, bytes[k * tb..(k + 1) * tb].to_vec()).map(Tile::Owned), mask(k))).collect())
        });
        let _ = free.try_send(raw);
        pairs
    };
    if let Some(v) = valid {
        let _ = run.spare_masks.0.try_send(v);
    }
    let mut masks = masks.into_iter().flatten();
    let mut out = Vec::with_capacity(n * if spec.mask { 2 } else { 1 });
    for (k, tile) in tiles.into_iter().enumerate() {
        let at = run.walk.tile_index(band, first_col + k as u32);
        out.push(tile.map(|t| (at, t)).map_err(|e| run.stop.fail(e)));
        if let Some(mask) = masks.next() {
            out.push(mask.map(|m| (spec.mask_tile(at), m)).map_err(|e| run.stop.fail(e)));
        }
    }
    out
}
