//! What a viewer reads to show an image fast, made while the tiles stream:
//! band statistics ([`Statistics`]) and internal overviews.
//!
//! Overviews: every tile of a level,
//! as it is made, is reduced to a quarter ([`reduce`]) and put into its
//! place in the tile above it; a tile of the level above is finished when
//! its (up to four) quarters are in, and goes on the same way. Only the
//! quarters of unfinished tiles are held: in bands of tile rows, about half
//! a band of tiles over all levels.

mod reduce;
mod statistics;

pub use reduce::{fill_pixel, reduce, OverviewResampling, Quarter, TileLayout, ValidBy};
pub use statistics::{ByTileRow, Statistics};

use crate::io::tiff_out::OutputSpec;
use std::collections::HashMap;

/// A finished tile of an overview level: its pixels (a whole tile, padded
/// with the fill value) and their 0/1 validity.
pub struct LevelTile {
    pub level: u32,
    /// Row-major in the level.
    pub k: usize,
    pub pixels: Vec<u8>,
    pub valid: Vec<u8>,
}

/// A tile of an overview level whose quarters are all in, to be joined
/// ([`Pyramid::join`]; on any thread).
pub struct Ready {
    level: u32,
    k: usize,
    slots: [Option<Quarter>; 4],
}

/// The overview levels being made.
pub struct Pyramid {
    pub kernel: OverviewResampling,
    pub lay: TileLayout,
    pub by: ValidBy,
    pub fill: f64,
    spec: OutputSpec,
    /// For each level above the full one, its unfinished tiles' quarters.
    pending: Vec<HashMap<usize, [Option<Quarter>; 4]>>,
}

impl Pyramid {
    /// The levels `spec` asks for (none: `None`), made with `kernel`; a
    /// pixel without a value holds `fill` and is known `by`.
    pub fn new(spec: &OutputSpec, kernel: OverviewResampling, by: ValidBy, fill: f64) -> Option<Pyramid> {
        if spec.overviews == 0 {
            return None;
        }
        Some(Pyramid {
            kernel,
            lay: TileLayout { tile: spec.chunk().0 as usize, bands: spec.bands as usize, sample: spec.sample },
            by,
            fill,
            spec: spec.clone(),
            pending: (0..=spec.overviews).map(|_| HashMap::new()).collect(),
        })
    }

    /// The last level.
    pub fn top(&self) -> u32 {
        self.spec.overviews
    }

    /// Tile `k` of level `l` reduced for the level above (pure: run many at
    /// once). `valid` under a mask.
    pub fn reduce(&self, l: u32, k: usize, pixels: &[u8], valid: Option<&[u8]>) -> Quarter {
        reduce(self.kernel, self.lay, self.by, self.fill, pixels, valid, self.spec.tile_extent(l, k))
    }

    /// Puts tile `k` of level `l`, reduced, into its tile of level `l + 1`:
    /// that tile's quarters, when this was its last.
    pub fn place(&mut self, l: u32, k: usize, q: Quarter) -> Option<Ready> {
        let (a, d) = self.spec.level_tiles(l);
        let (a, d) = (a as usize, d as usize);
        let (cx, cy) = (k % a, k / a);
        let up = l as usize + 1;
        let pa = self.spec.level_tiles(l + 1).0 as usize;
        let parent = cy / 2 * pa + cx / 2;
        // The tiles below it that exist: two or one across, two or one down.
        let need = (a.min(cx / 2 * 2 + 2) - cx / 2 * 2) * (d.min(cy / 2 * 2 + 2) - cy / 2 * 2);
        let slots = self.pending[up].entry(parent).or_default();
        slots[(cy % 2) * 2 + cx % 2] = Some(q);
        if slots.iter().flatten().count() < need {
            return None;
        }
        let slots = self.pending[up].remove(&parent).expect("just filled");
        Some(Ready { level: up as u32, k: parent, slots })
    }

    /// A tile from its quarters (those missing, beyond the level below's
    /// edge, left empty).
    pub fn join(&self, Ready { level: l, k, slots }: Ready) -> LevelTile {
        let (t, b) = (self.lay.tile, self.lay.bands);
        let px = b * self.lay.sample.bytes();
        let half = t / 2;
        // Row by row, each byte written once: the halves of a row from
        // their quarters, or the fill where a quarter is missing.
        let fill_row: Vec<u8> = fill_pixel(self.lay, self.fill).repeat(half);
        let no_value = vec![0u8; half];
        let mut pixels = Vec::with_capacity(t * t * px);
        let mut valid = Vec::with_capacity(t * t);
        for y in 0..t {
            for q in &slots[y / half * 2..][..2] {
                match q {
                    Some(q) => {
                        let r = y % half;
                        pixels.extend_from_slice(&q.pixels[r * half * px..(r + 1) * half * px]);
                        valid.extend_from_slice(&q.valid[r * half..(r + 1) * half]);
                    }
                    None => {
                        pixels.extend_from_slice(&fill_row);
                        valid.extend_from_slice(&no_value);
                    }
                }
            }
        }
        LevelTile { level: l, k, pixels, valid }
    }

    /// The overview tiles `finished`, and those they finish in turn, level
    /// after level: each joined from its quarters, reduced for the level
    /// above (below the top) and then given to `make`, many at once on the
    /// current rayon pool; what `make` returns goes to `take` with the
    /// tile's level and number.
    pub fn cascade<R: Send>(&mut self, mut finished: Vec<Ready>, make: impl Fn(LevelTile) -> R + Sync, mut take: impl FnMut(u32, usize, R)) {
        use rayon::prelude::*;
        let top = self.top();
        while !finished.is_empty() {
            let p = &*self;
            let made: Vec<(u32, usize, R, Option<Quarter>)> = finished
                .into_par_iter()
                .map(|r| {
                    let t = p.join(r);
                    let q = (t.level < top).then(|| p.reduce(t.level, t.k, &t.pixels, Some(&t.valid)));
                    (t.level, t.k, make(t), q)
                })
                .collect();
            finished = Vec::new();
            for (l, k, r, q) in made {
                take(l, k, r);
                if let Some(q) = q {
                    finished.extend(self.place(l, k, q));
                }
            }
        }
    }

    /// The order a file of `spec` written a band (a row of full-resolution
    /// tiles) at a time gets its chunks in: each band's tiles (each with its
    /// mask's), then the overview tiles that band finishes, as
    /// [`Pyramid::place`] and [`Pyramid::cascade`] finish them. A run that
    /// makes its tiles in another order lays them out in this one, so that
    /// its file is a band-by-band run's, byte for byte.
    pub fn band_order(spec: &OutputSpec) -> Vec<usize> {
        let mut order = Vec::with_capacity(spec.chunk_count());
        let mut put = |l: u32, k: usize| {
            order.push(spec.chunk_index(l, k, false));
            if spec.mask {
                order.push(spec.chunk_index(l, k, true));
            }
        };
        let mut pyramid = Pyramid::new(spec, OverviewResampling::Nearest, ValidBy::Mask, 0.0);
        let quarter = || Quarter { pixels: Vec::new(), valid: Vec::new() };
        let across = spec.tiles_across() as usize;
        for b in 0..spec.tiles_down() as usize {
            let mut finished = Vec::new();
            for k in b * across..(b + 1) * across {
                put(0, k);
                if let Some(p) = pyramid.as_mut() {
                    finished.extend(p.place(0, k, quarter()));
                }
            }
            let Some(p) = pyramid.as_mut() else { continue };
            while !finished.is_empty() {
                let mut next = Vec::new();
                for r in finished {
                    put(r.level, r.k);
                    if r.level < p.top() {
                        next.extend(p.place(r.level, r.k, quarter()));
                    }
                }
                finished = next;
            }
        }
        order
    }

    /// Have all tiles been finished? (Every tile below came.)
    pub fn is_complete(&self) -> bool {
        self.pending.iter().all(HashMap::is_empty)
    }

    /// The most the unfinished quarters can hold, bytes, when the tiles of
    /// the full level come in bands of `band_tiles` (tiles across, or down
    /// in bands of columns): at each level, a band of quarters waiting for
    /// the band below them.
    pub fn held_bytes(spec: &OutputSpec, band_tiles: u32) -> u64 {
        let t = spec.chunk().0 as u64;
        let quarter = (t / 2) * (t / 2) * (spec.bands as u64 * spec.sample.bytes() as u64 + 1);
        (0..spec.overviews).map(|l| (band_tiles as u64).div_ceil(1 << l) * quarter).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::format::SampleType;
    use crate::io::tiff_out::{Chunking, Compression};

    fn spec(width: u32, height: u32) -> OutputSpec {
        OutputSpec {
            width,
            height,
            bands: 1,
            sample: SampleType::U8,
            chunking: Chunking::Tiles(4),
            compression: Compression::Deflate,
            level: None,
            overview_level: None,
            bigtiff: false,
            photometric: 1,
            alpha: false,
            mask: true,
            geo: None,
            overviews: OutputSpec::auto_overviews(width, height, 4),
            cog: false,
        }
    }

    /// A band-by-band run's order: every chunk once; each band's tiles,
    /// each followed by its mask's, before the overview tiles it finishes,
    /// and every overview tile after the four below it.
    #[test]
    fn the_band_order_has_every_chunk_once_each_after_what_it_is_made_of() {
        let s = spec(17, 9);
        let order = Pyramid::band_order(&s);
        let mut seen = vec![usize::MAX; s.chunk_count()];
        for (i, &k) in order.iter().enumerate() {
            assert_eq!(seen[k], usize::MAX, "chunk {k} twice");
            seen[k] = i;
        }
        assert!(seen.iter().all(|&i| i != usize::MAX), "a chunk left out");
        assert_eq!(&order[..4], &[s.chunk_index(0, 0, false), s.chunk_index(0, 0, true), s.chunk_index(0, 1, false), s.chunk_index(0, 1, true)]);
        for l in 1..=s.overviews {
            let (a, d) = s.level_tiles(l);
            let below = s.level_tiles(l - 1).0 as usize;
            for k in 0..(a * d) as usize {
                let (x, y) = (k % a as usize, k / a as usize);
                let at = seen[s.chunk_index(l, k, false)];
                assert_eq!(seen[s.chunk_index(l, k, true)], at + 1, "its mask right after it");
                let under = seen[s.chunk_index(l - 1, 2 * y * below + 2 * x, false)];
                assert!(under < at, "level {l} tile {k} before the tiles it is made of");
            }
        }
    }

    #[test]
    fn every_level_equals_the_average_of_the_level_below_in_any_tile_order() {
        // 17×9 grey in 4-px tiles: levels 9×5, 5×3, 3×2 (three overviews).
        // The full level's pixel (x, y) = 3x + 5y, without a value where
        // x + y is a multiple of 7. Each level is checked against the
        // average of the level below made here directly, and tiles given
        // in row order and in column order make the same levels.
        let s = spec(17, 9);
        assert_eq!(s.overviews, 3);
        let (w, h) = (17usize, 9usize);
        let full: Vec<(u8, u8)> = (0..w * h).map(|i| ((3 * (i % w) + 5 * (i / w)) as u8, u8::from((i % w + i / w) % 7 != 0))).collect();
        let run = |columns: bool| {
            let mut p = Pyramid::new(&s, OverviewResampling::Average, ValidBy::Mask, 0.0).unwrap();
            let mut levels: Vec<Vec<(u8, u8)>> = (1..=3).map(|l| vec![(0, 0); s.level_size(l).0 as usize * s.level_size(l).1 as usize]).collect();
            let (a, d) = s.level_tiles(0);
            let mut order: Vec<usize> = (0..(a * d) as usize).collect();
            if columns {
                order.sort_by_key(|&k| (k % a as usize, k / a as usize));
            }
            let mut queue: Vec<(u32, usize, Vec<u8>, Vec<u8>)> = order
                .into_iter()
                .map(|k| {
                    let (x0, y0) = (k % a as usize * 4, k / a as usize * 4);
                    let mut px = vec![0u8; 16];
                    let mut ok = vec![0u8; 16];
                    for j in 0..16 {
                        let (x, y) = (x0 + j % 4, y0 + j / 4);
                        if x < w && y < h {
                            (px[j], ok[j]) = full[y * w + x];
                        }
                    }
                    (0, k, px, ok)
                })
                .collect();
            queue.reverse();
            while let Some((l, k, px, ok)) = queue.pop() {
                if l > 0 {
                    let (lw, lh) = s.level_size(l);
                    let la = s.level_tiles(l).0 as usize;
                    for j in 0..16 {
                        let (x, y) = (k % la * 4 + j % 4, k / la * 4 + j / 4);
                        if x < lw as usize && y < lh as usize {
                            levels[l as usize - 1][y * lw as usize + x] = (px[j], ok[j]);
                        }
                    }
                }
                if l < p.top() {
                    let q = p.reduce(l, k, &px, Some(&ok));
                    if let Some(r) = p.place(l, k, q) {
                        let t = p.join(r);
                        queue.push((t.level, t.k, t.pixels, t.valid));
                    }
                }
            }
            assert!(p.is_complete());
            levels
        };
        let rows = run(false);
        assert_eq!(run(true), rows);
        let mut below = full;
        for l in 1..=3u32 {
            let (bw, bh) = s.level_size(l - 1);
            let (lw, lh) = s.level_size(l);
            for y in 0..lh as usize {
                for x in 0..lw as usize {
                    let mut vals = Vec::new();
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (bx, by) = (2 * x + dx, 2 * y + dy);
                        if bx < bw as usize && by < bh as usize {
                            let (v, ok) = below[by * bw as usize + bx];
                            if ok == 1 {
                                vals.push(v as u32);
                            }
                        }
                    }
                    let want = if vals.is_empty() { (0, 0) } else { (((vals.iter().sum::<u32>() * 2 + vals.len() as u32) / (2 * vals.len() as u32)) as u8, 1) };
                    assert_eq!(rows[l as usize - 1][y * lw as usize + x], want, "level {l} pixel {x},{y}");
                }
            }
            below = rows[l as usize - 1].clone();
        }
    }

    #[test]
    fn held_quarters_are_bounded_by_a_band() {
        let s = OutputSpec { bands: 3, mask: false, ..spec(40000, 40000) };
        let b = Pyramid::held_bytes(&s, 10000);
        // 10000 tiles across, quarters of 2×2 pixels of 3 bytes and validity.
        assert!(b <= (2 * 10000 + s.overviews as u64) * 16, "{b}");
    }
}
