//! True orthophotos: which output pixels the sensor sees on the DSM.
//!
//! A Z-buffer in scan space, one tile of output pixels at a time. The DSM's
//! cells under the tile, and toward the sensor as far as the highest surface
//! there could hide the tile, are projected into the scan and rasterised;
//! each Z-buffer sample keeps the highest surface point seen there (along
//! one line of sight from above, the highest point is the one nearest the
//! sensor). An output pixel is seen when its own height reaches what the
//! Z-buffer holds around its scan position: interpolated between the
//! projected posts of its own DSM cell (the GCM's would repeat the exact
//! model at every wall), or the GCM's where the lattice is not the DSM's.
//! Only cells higher than a block's lowest pixel are drawn (no other can
//! hide one), on samples half a pixel apart along the output's axes.
//!
//! Why this method: ray tracing along the DSM from every output pixel costs
//! a walk of the occluders' reach per pixel (tens of DSM cells behind a
//! building), and Habib's angle sweep runs along radial lines from the
//! nadir, which do not follow bands of output rows; the Z-buffer costs one
//! projection per DSM post around the tile and a raster fill, its memory is
//! a tile's, and it needs no line of sight at all — the same code serves
//! frame cameras, RPCs and any other model. The Z-buffer's samples are about
//! an output pixel's footprint in the scan, so the occlusion boundary lands
//! within a pixel of where the DSM puts it.

mod lattice;
mod zbuffer;

use super::Transform;
use crate::dem::{Height, HeightModel};
use lattice::{Corridor, Lattice, ProjectedLattice};
use zbuffer::{jacobian, SampleFrame, ZBuffer};

/// Which pixels of one band the sensor sees, tile by tile.
#[derive(Clone, Debug, Default)]
pub struct Seen {
    /// The band's first walked row and the first tile's first column.
    y0: u32,
    x0: u32,
    tile: u32,
    /// Per tile, a bit a pixel row-major, set where hidden; empty where
    /// the whole tile is seen (most tiles over terrain).
    tiles: Vec<Vec<u64>>,
    /// Pixels the sensor images (a position inside the scan) and of them hidden.
    pub imaged: u64,
    pub hidden: u64,
}

impl Seen {
    /// From each tile's bytes (`tile × tile`, 0 where hidden), and the
    /// band's pixels imaged and hidden.
    pub fn new(y0: u32, x0: u32, tile: u32, tiles: Vec<Vec<u8>>, imaged: u64, hidden: u64) -> Seen {
        let pack = |bytes: Vec<u8>| -> Vec<u64> {
            if bytes.iter().all(|&v| v != 0) {
                return Vec::new();
            }
            let mut bits = vec![0u64; bytes.len().div_ceil(64)];
            for (k, _) in bytes.iter().enumerate().filter(|(_, &v)| v == 0) {
                bits[k / 64] |= 1 << (k % 64);
            }
            bits
        };
        Seen { y0, x0, tile, tiles: tiles.into_iter().map(pack).collect(), imaged, hidden }
    }

    /// Is walked pixel (x, y) of the band seen? (Pixels outside the tiles
    /// made are.)
    #[inline]
    pub fn at(&self, x: u32, y: u32) -> bool {
        let t = self.tile;
        let Some(tile) = x.checked_sub(self.x0).and_then(|dx| self.tiles.get((dx / t) as usize)) else {
            return true;
        };
        let (cx, cy) = ((x - self.x0) % t, y.wrapping_sub(self.y0));
        let k = (cy * t + cx) as usize;
        tile.get(k / 64).is_none_or(|&w| w & (1 << (k % 64)) == 0)
    }
}

/// Visibility on the DSM of one run's walked grid.
pub struct Visibility<'a> {
    t: &'a Transform<'a>,
    lattice: Lattice,
    /// Heights closer than this to the Z-buffer's count as seen (ground units
    /// of height): covers the positions' error and the surface's curvature
    /// within a Z-buffer sample.
    tolerance: f64,
    /// The DSM's posts where the lattice is them (every `n`th).
    posts: Option<(&'a crate::dem::GridDem, i64)>,
    /// The highest surface in blocks of the lattice, found on first need:
    /// how far toward the sensor a tile's occluders may stand.
    blocks: BlockMax,
}

/// The highest lattice height in blocks of `BLOCK × BLOCK` cells over the
/// ground the occluders of any output pixel may stand on, each worked out
/// once, when a tile first asks.
struct BlockMax {
    /// Lattice index of the first block's first node.
    i0: i64,
    j0: i64,
    across: usize,
    down: usize,
    max: Vec<std::sync::OnceLock<(f32, f32)>>,
}

/// Lattice cells a side of a block of [`BlockMax`].
const BLOCK: i64 = 32;

/// Pixels a side of the blocks of a tile that get a Z-buffer each.
const SUB: usize = 64;
/// The reach toward the sensor is cut at this many tile sides (a line of
/// sight within a few degrees of the horizon would reach out of the scene).
const MAX_REACH_TILES: f64 = 16.0;

impl<'a> Visibility<'a> {
    /// Visibility for `t` (its model, DSM, walked grid and scan: positions
    /// outside the scan are not imaged; all are where `t` does not know
    /// it); heights within `tolerance` of the surface seen count as seen.
    pub fn new(t: &'a Transform<'a>, tolerance: f64) -> Visibility<'a> {
        let grid = t.grid;
        let aligned = match &t.dem.model {
            HeightModel::Grid(g) if t.dem.to_dem.is_none() && g.transform[2] == 0.0 && g.transform[4] == 0.0 => Some(g.transform),
            _ => None,
        };
        // Non-square pixels: lattices as fine as the finer side.
        let gsd = grid.gsd.min();
        let posts = match (&t.dem.model, aligned) {
            (HeightModel::Grid(g), Some(gt)) => Some((g, (0.5 * gsd / gt[1].abs()).floor().max(1.0) as i64)),
            _ => None,
        };
        let lattice = match aligned {
            Some(gt) => {
                // Posts much finer than the output are taken a few at a
                // time, half a pixel apart at most (a roof's edge moves
                // with the lattice).
                let n = (0.5 * gsd / gt[1].abs()).floor().max(1.0);
                Lattice { ox: gt[0] + 0.5 * gt[1], oy: gt[3] + 0.5 * gt[5], dx: gt[1] * n, dy: gt[5] * n }
            }
            None => {
                // A DSM in another CRS (or flat): a lattice of the output
                // grid, half a DSM post apart (it bends nowhere finer),
                // whole pixels, half a pixel at the finest.
                let (cx, cy) = t.ground(grid.width as f64 / 2.0, grid.height as f64 / 2.0);
                let post = match (t.dem.sample_coords(cx, cy), t.dem.sample_coords(cx + gsd, cy), t.dem.sample_coords(cx, cy + gsd)) {
                    (Some(a), Some(b), Some(c)) => gsd / (b.0 - a.0).hypot(b.1 - a.1).max((c.0 - a.0).hypot(c.1 - a.1)),
                    _ => f64::INFINITY,
                };
                let step = if post.is_finite() { (0.5 * post / gsd).floor().max(1.0) * gsd } else { 64.0 * gsd };
                let step = if post.is_finite() && 0.5 * post < gsd { 0.5 * gsd } else { step };
                Lattice { ox: grid.x0 + 0.5 * gsd, oy: grid.y0 - 0.5 * gsd, dx: step, dy: -step }
            }
        };
        // The output's ground, and as far again around it as the reach can go.
        let (xa, ya) = t.ground(0.0, 0.0);
        let (xb, yb) = t.ground(grid.width as f64, grid.height as f64);
        let reach = MAX_REACH_TILES * 256.0 * grid.gsd.max();
        let region = [xa.min(xb) - reach, ya.min(yb) - reach, xa.max(xb) + reach, ya.max(yb) + reach];
        let (i0, j0, i1, j1) = lattice.cover(region);
        let (across, down) = (((i1 - i0) / BLOCK + 1) as usize, ((j1 - j0) / BLOCK + 1) as usize);
        let blocks = BlockMax { i0, j0, across, down, max: (0..across * down).map(|_| std::sync::OnceLock::new()).collect() };
        Visibility { t, lattice, tolerance, posts, blocks }
    }

    /// The highest height in block (bi, bj) (its nodes and its far edge's)
    /// and the steepest the surface gets in it (an upper bound of the
    /// bilinear gradient's length, height per ground unit): −∞, 0 where it
    /// has none or lies outside the region.
    fn block(&self, bi: i64, bj: i64) -> (f64, f64) {
        let b = &self.blocks;
        if bi < 0 || bj < 0 || bi >= b.across as i64 || bj >= b.down as i64 {
            return (f64::NEG_INFINITY, 0.0);
        }
        let (hi, steep) = *b.max[bj as usize * b.across + bi as usize].get_or_init(|| {
            let (i0, j0) = (b.i0 + bi * BLOCK, b.j0 + bj * BLOCK);
            let n = (BLOCK + 1) as usize;
            let z: Vec<f64> = (j0..=j0 + BLOCK).flat_map(|j| (i0..=i0 + BLOCK).map(move |i| (i, j))).map(|(i, j)| self.node_z(i, j)).collect();
            let hi = z.iter().copied().filter(|v| v.is_finite()).fold(f64::NEG_INFINITY, f64::max);
            // Within a bilinear cell each partial derivative lies between
            // its two edges' differences.
            let (mut gx, mut gy) = (0.0f64, 0.0f64);
            for r in 0..n {
                for c in 0..n {
                    let k = r * n + c;
                    if c + 1 < n {
                        let d = (z[k + 1] - z[k]).abs();
                        gx = if d.is_nan() { gx } else { gx.max(d) };
                    }
                    if r + 1 < n {
                        let d = (z[k + n] - z[k]).abs();
                        gy = if d.is_nan() { gy } else { gy.max(d) };
                    }
                }
            }
            (hi as f32, (gx / self.lattice.dx.abs()).hypot(gy / self.lattice.dy.abs()) as f32)
        });
        (hi as f64, steep as f64)
    }

    /// How high above `zlo` the ground `rect` must look for occluders:
    /// the highest block toward the sensor (lines of sight within `g`,
    /// horizontal per unit of height, extremes [min x, min y, max x, max
    /// y]) that stands high enough to reach `rect`, within `cap` of it; at
    /// least `zhi − zlo`.
    fn occluder_rise(&self, rect: [f64; 4], g: [f64; 4], zlo: f64, zhi: f64, cap: f64) -> (f64, f64) {
        let mut rise = zhi - zlo;
        let reach = |v: f64| if v == 0.0 { 0.0 } else { cap.copysign(v) };
        let window = [rect[0] + reach(g[0]).min(0.0), rect[1] + reach(g[1]).min(0.0), rect[2] + reach(g[2]).max(0.0), rect[3] + reach(g[3]).max(0.0)];
        let (i0, j0, i1, j1) = self.lattice.cover(window);
        let b = &self.blocks;
        let (bi0, bj0) = ((i0 - b.i0).div_euclid(BLOCK), (j0 - b.j0).div_euclid(BLOCK));
        let (bi1, bj1) = ((i1 - b.i0).div_euclid(BLOCK), (j1 - b.j0).div_euclid(BLOCK));
        let half = 0.5 * BLOCK as f64 * self.lattice.dx.abs().hypot(self.lattice.dy.abs());
        let centre = |bi: i64, bj: i64| {
            let (xa, ya) = self.lattice.node(b.i0 + bi * BLOCK, b.j0 + bj * BLOCK);
            let (xb, yb) = self.lattice.node(b.i0 + (bi + 1) * BLOCK, b.j0 + (bj + 1) * BLOCK);
            (0.5 * (xa + xb), 0.5 * (ya + yb))
        };
        for bj in bj0..=bj1 {
            for bi in bi0..=bi1 {
                let top = self.block(bi, bj).0 - zlo;
                // Does the block meet the ground swept from `rect` toward
                // the sensor as high as it stands?
                let (x, y) = centre(bi, bj);
                if top > rise && Corridor::toward(rect, g, top).holds(x, y, half) {
                    rise = top;
                }
            }
        }
        // The steepest surface in that corridor.
        let corridor = Corridor::toward(rect, g, rise);
        let mut steep = 0.0f64;
        for bj in bj0..=bj1 {
            for bi in bi0..=bi1 {
                let (x, y) = centre(bi, bj);
                if corridor.holds(x, y, half) {
                    steep = steep.max(self.block(bi, bj).1);
                }
            }
        }
        (rise, steep)
    }

    /// Height at lattice node (i, j): the DSM's post where the lattice is
    /// its posts, NaN where it has none (after the hole policy).
    fn node_z(&self, i: i64, j: i64) -> f64 {
        if let Some((g, n)) = self.posts {
            let z = g.post(i * n, j * n);
            if z.is_finite() {
                return z;
            }
        }
        let (x, y) = self.lattice.node(i, j);
        self.z(x, y)
    }

    /// Height of ground (x, y), NaN where the DSM has none.
    fn z(&self, x: f64, y: f64) -> f64 {
        match self.t.dem.height(x, y) {
            Height::Value(z) => z,
            _ => f64::NAN,
        }
    }

    /// The line of sight at ground (x, y, z): the horizontal move per unit
    /// of height along it (toward the sensor as height grows).
    fn sight(&self, x: f64, y: f64, z: f64) -> Option<(f64, f64)> {
        let m = self.t.model;
        let h = 5.0 * m.ground_step();
        let (c, r) = m.project(x, y, z)?;
        let (cx, rx) = m.project(x + h, y, z)?;
        let (cy, ry) = m.project(x, y + h, z)?;
        let zh = h.max(0.5);
        let (cz, rz) = m.project(x, y, z + zh)?;
        let (a, b, e) = ((cx - c) / h, (cy - c) / h, (cz - c) / zh);
        let (cc, d, f) = ((rx - r) / h, (ry - r) / h, (rz - r) / zh);
        // [a b; cc d]·(gx, gy) = −(e, f)
        let det = a * d - b * cc;
        if det.abs() < 1e-300 {
            return None;
        }
        let (gx, gy) = ((-e * d + b * f) / det, (-a * f + cc * e) / det);
        (gx.is_finite() && gy.is_finite()).then_some((gx, gy))
    }

    /// Which pixels of walked block `[x0, y0, x1, y1]` (a tile) are seen:
    /// 1 seen, 0 hidden, into `seen` (rows `t` apart); and how many pixels
    /// are imaged and hidden. `positions(y, x, cols,
    /// rows)` fills scan positions (NaN where none) from the GCM along
    /// walked row `y` from column `x`; where the lattice is the DSM's
    /// posts, a block that needs its Z-buffer takes them from the lattice
    /// instead (see [`ProjectedLattice::position`]).
    pub fn tile(&self, [x0, y0, x1, y1]: [u32; 4], t: u32, positions: impl Fn(u32, u32, &mut [f64], &mut [f64]), seen: &mut [u8]) -> (u64, u64) {
        let (w, h) = ((x1 - x0) as usize, (y1 - y0) as usize);
        let all_positions = || {
            let (mut cols, mut rows) = (vec![f64::NAN; w * h], vec![f64::NAN; w * h]);
            for y in 0..h {
                positions(y0 + y as u32, x0, &mut cols[y * w..(y + 1) * w], &mut rows[y * w..(y + 1) * w]);
            }
            (cols, rows)
        };
        // Nothing hidden: how many pixels are imaged. Over a DSM without a
        // hole there, the whole block is when its border is (the ground
        // seen unhidden maps one to one into the scan, a rectangle): 4/w
        // of the positions.
        let all_seen = |complete: bool| {
            if complete && self.border_imaged([x0, y0, x1, y1], &positions) {
                return ((w * h) as u64, 0);
            }
            let (cols, rows) = all_positions();
            self.count_imaged(&cols, &rows)
        };
        seen.fill(1);
        // The tile's ground (pixel centres) and its heights.
        let corners =
            [(x0 as f64 + 0.5, y0 as f64 + 0.5), (x1 as f64 - 0.5, y0 as f64 + 0.5), (x0 as f64 + 0.5, y1 as f64 - 0.5), (x1 as f64 - 0.5, y1 as f64 - 0.5)];
        let ground: Vec<(f64, f64)> = corners.iter().map(|&(u, v)| self.t.ground(u, v)).collect();
        let rect = ground
            .iter()
            .fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |b, &(x, y)| [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)]);
        let (zlo, zhi, complete) = self.height_range(rect);
        if !zlo.is_finite() {
            return all_seen(false);
        }
        // Lines of sight at the corners, at the tile's lowest height: where
        // the occluders of the tile can stand.
        let mut g = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
        for &(x, y) in &ground {
            if let Some((gx, gy)) = self.sight(x, y, zlo) {
                g = [g[0].min(gx), g[1].min(gy), g[2].max(gx), g[3].max(gy)];
            }
        }
        if !g[0].is_finite() {
            return all_seen(false);
        }
        let cap = MAX_REACH_TILES * (rect[2] - rect[0]).max(rect[3] - rect[1]).max(self.lattice.dx.abs());
        let window = |dz: f64| {
            let m = |v: f64| if v == 0.0 { 0.0 } else { (dz * v).clamp(-cap, cap) };
            [rect[0] + m(g[0]).min(0.0), rect[1] + m(g[1]).min(0.0), rect[2] + m(g[2]).max(0.0), rect[3] + m(g[3]).max(0.0)]
        };
        // As far toward the sensor as the highest surface that could hide
        // the tile stands (within the cap); only the nodes in that corridor.
        let slope = g[0].abs().max(g[2].abs()).hypot(g[1].abs().max(g[3].abs()));
        let (rise, steep) = self.occluder_rise(rect, g, zlo, zhi, cap);
        // Nothing in reach stands high enough to hide half a pixel, or no
        // surface there rises as steeply as the lines of sight (terrain
        // under a camera looking down): all seen.
        if rise * slope < 0.5 * self.t.grid.gsd.min() || steep * slope < 0.9 {
            return all_seen(complete);
        }
        let lattice = self.project_lattice(window(rise), &Corridor::toward(rect, g, rise));
        let (cols, rows) = if self.posts.is_some() {
            let (mut cols, mut rows) = (vec![f64::NAN; w * h], vec![f64::NAN; w * h]);
            for y in 0..h {
                for x in 0..w {
                    let (gx, gy) = self.t.ground((x0 as usize + x) as f64 + 0.5, (y0 as usize + y) as f64 + 0.5);
                    (cols[y * w + x], rows[y * w + x]) = lattice.position(self.lattice, gx, gy, self.lattice.cell(gx, gy));
                }
            }
            (cols, rows)
        } else {
            all_positions()
        };
        let (cols, rows) = (&cols[..], &rows[..]);

        // A Z-buffer for each block of the tile's pixels: the box of a
        // block's scan positions hugs them (a whole tile's, turned, seen in
        // perspective, its roofs displaced, holds four times its area).
        let boxes = lattice.cell_boxes();
        let (mut imaged, mut hidden) = (0, 0);
        for by in (0..h).step_by(SUB) {
            for bx in (0..w).step_by(SUB) {
                let (bw, bh) = (SUB.min(w - bx), SUB.min(h - by));
                let at = |x: usize, y: usize| (by + y) * w + bx + x;
                // The block's imaged pixels with a height: where, how
                // high, their cell.
                let mut pixels = Vec::with_capacity(bw * bh);
                let mut lowest = f64::INFINITY;
                for y in 0..bh {
                    for x in 0..bw {
                        let (c, r) = (cols[at(x, y)], rows[at(x, y)]);
                        if !self.in_scan(c, r) {
                            continue;
                        }
                        imaged += 1;
                        let (gx, gy) = self.t.ground((x0 as usize + bx + x) as f64 + 0.5, (y0 as usize + by + y) as f64 + 0.5);
                        let own = self.lattice.cell(gx, gy);
                        let z = lattice.height(self.lattice, gx, gy, own);
                        if z.is_finite() {
                            lowest = lowest.min(z);
                            pixels.push((x, y, z, own));
                        }
                    }
                }
                if pixels.is_empty() {
                    continue;
                }
                let frame = self.sample_frame([x0 as usize + bx, y0 as usize + by, bw, bh], zlo, cols, rows, w, [bx, by]);
                let mut frame = match frame {
                    Some(f) => f,
                    None => continue,
                };
                let bb = |f: &SampleFrame| {
                    let mut bb = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
                    for y in 0..bh {
                        for x in 0..bw {
                            let (c, r) = (cols[at(x, y)], rows[at(x, y)]);
                            if c.is_finite() && r.is_finite() {
                                let (u, v) = f.apply(c, r);
                                bb = [bb[0].min(u), bb[1].min(v), bb[2].max(u), bb[3].max(v)];
                            }
                        }
                    }
                    bb
                };
                let mut samples = bb(&frame);
                if !samples[0].is_finite() {
                    continue;
                }
                // Never more than 16 samples a pixel.
                let most = 16.0 * (bw * bh) as f64;
                let many = (samples[2] - samples[0] + 4.0) * (samples[3] - samples[1] + 4.0);
                if many > most {
                    frame = frame.scaled((most / many).sqrt());
                    samples = bb(&frame);
                }
                let mut zb = ZBuffer::new(frame, samples);
                // A cell no higher than the lowest pixel (and the
                // tolerance) hides none of them: only roofs, walls and
                // rising ground are drawn.
                if !lattice.rasterise(self.tolerance, &boxes, &mut zb, lowest + self.tolerance) {
                    continue;
                }
                for (x, y, z, own) in pixels {
                    let (above, cell) = zb.seen_height(cols[at(x, y)], rows[at(x, y)]);
                    // Hidden: a surface above the pixel's is seen where it
                    // would be, and not its own or its cell's neighbours'
                    // (a bilinear wall between two posts seen edge-on is
                    // no cover).
                    if z + self.tolerance < above && ((cell.0 - own.0).abs() > 1 || (cell.1 - own.1).abs() > 1) {
                        seen[(by + y) * t as usize + bx + x] = 0;
                        hidden += 1;
                    }
                }
            }
        }
        (imaged, hidden)
    }

    /// Of these scan positions, how many are in the scan (and none hidden).
    fn count_imaged(&self, cols: &[f64], rows: &[f64]) -> (u64, u64) {
        (cols.iter().zip(rows).filter(|&(&c, &r)| self.in_scan(c, r)).count() as u64, 0)
    }

    /// Is scan position (c, r) imaged: in the scan (anywhere, where the
    /// transform does not know the scan's size)?
    #[inline]
    fn in_scan(&self, c: f64, r: f64) -> bool {
        c >= 0.0 && r >= 0.0 && self.t.scan.is_none_or(|(w, h)| c <= w && r <= h)
    }

    /// Are the border pixels of walked block `[x0, y0, x1, y1]` all in the
    /// scan (`positions` as for [`Visibility::tile`])?
    fn border_imaged(&self, [x0, y0, x1, y1]: [u32; 4], positions: &impl Fn(u32, u32, &mut [f64], &mut [f64])) -> bool {
        let w = (x1 - x0) as usize;
        let (mut cols, mut rows) = (vec![f64::NAN; w], vec![f64::NAN; w]);
        for y in [y0, y1 - 1] {
            positions(y, x0, &mut cols, &mut rows);
            if !cols.iter().zip(&rows).all(|(&c, &r)| self.in_scan(c, r)) {
                return false;
            }
        }
        (y0 + 1..y1.saturating_sub(1)).all(|y| {
            [x0, x1 - 1].into_iter().all(|x| {
                positions(y, x, &mut cols[..1], &mut rows[..1]);
                self.in_scan(cols[0], rows[0])
            })
        })
    }

    /// The lowest and highest height at the lattice nodes over ground `rect`
    /// (NaN, NaN where none), and whether they are the DSM's every post
    /// there and all have a height (no hole, all inside).
    fn height_range(&self, rect: [f64; 4]) -> (f64, f64, bool) {
        let (i0, j0, i1, j1) = self.lattice.cover(rect);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut complete = matches!(self.posts, Some((_, 1)));
        for j in j0..=j1 {
            for i in i0..=i1 {
                let z = self.node_z(i, j);
                if z.is_finite() {
                    lo = lo.min(z);
                    hi = hi.max(z);
                } else {
                    complete = false;
                }
            }
        }
        if lo.is_finite() {
            (lo, hi, complete)
        } else {
            (f64::NAN, f64::NAN, false)
        }
    }

    /// The lattice nodes over ground `rect`, projected into the scan.
    fn project_lattice(&self, rect: [f64; 4], corridor: &Corridor) -> ProjectedLattice {
        let (i0, j0, i1, j1) = self.lattice.cover(rect);
        let (ni, nj) = ((i1 - i0 + 1) as usize, (j1 - j0 + 1) as usize);
        let mut xs = Vec::with_capacity(ni * nj);
        let mut ys = Vec::with_capacity(ni * nj);
        let mut zs = Vec::with_capacity(ni * nj);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let (x, y) = self.lattice.node(i, j);
                xs.push(x);
                ys.push(y);
                // (A NaN height: not projected, no cell of it drawn.)
                zs.push(if corridor.holds(x, y, self.lattice.dx.abs().max(self.lattice.dy.abs())) { self.node_z(i, j) } else { f64::NAN });
            }
        }
        // Only the nodes with a height are projected.
        let keep: Vec<usize> = (0..zs.len()).filter(|&k| zs[k].is_finite()).collect();
        let pick = |v: &[f64]| keep.iter().map(|&k| v[k]).collect::<Vec<f64>>();
        let (mut c, mut r) = (vec![0.0; keep.len()], vec![0.0; keep.len()]);
        self.t.model.project_many(&pick(&xs), &pick(&ys), &pick(&zs), &mut c, &mut r);
        let mut cs = vec![f64::NAN; xs.len()];
        let mut rs = vec![f64::NAN; xs.len()];
        for (n, &k) in keep.iter().enumerate() {
            (cs[k], rs[k]) = (c[n], r[n]);
        }
        ProjectedLattice { i0: i0 as i32, j0: j0 as i32, ni, nj, xs, ys, zs, cs, rs }
    }
}

impl Visibility<'_> {
    /// The sampling of the Z-buffer for walked pixels `[x, y, w, h]`: from
    /// the model on the plane of the tile's lowest height `z` (a roof's
    /// pixels are larger in the scan: sampled more finely), at the block's
    /// centre, made finer until samples are half a pixel apart at its
    /// corners too (perspective). Where the model gives no position there,
    /// from the block's own positions (`cols`, `rows`, rows `w` apart,
    /// the block at `at`).
    fn sample_frame(&self, [x, y, bw, bh]: [usize; 4], z: f64, cols: &[f64], rows: &[f64], w: usize, at: [usize; 2]) -> Option<SampleFrame> {
        let project = |u: f64, v: f64| {
            let (gx, gy) = self.t.ground(u, v);
            self.t.model.project(gx, gy, z)
        };
        let model_j = |u: f64, v: f64| Some(jacobian(project(u, v)?, project(u + 1.0, v)?, project(u, v + 1.0)?));
        let (cu, cv) = (x as f64 + 0.5 * bw as f64, y as f64 + 0.5 * bh as f64);
        let frame = match model_j(cu, cv) {
            Some(j) => SampleFrame::of_jacobian(j, 2.0),
            None => {
                // The first point of the block with positions a step on.
                let (bx, by) = (at[0], at[1]);
                [(bh / 2, bw / 2), (0, 0), (bh - 1, bw - 1), (0, bw - 1), (bh - 1, 0)].into_iter().find_map(|(yy, xx)| {
                    let (xx, yy) = ((bx + xx).min(bx + bw.saturating_sub(2)), (by + yy).min(by + bh.saturating_sub(2)));
                    let k = yy * w + xx;
                    if k + w + 1 >= cols.len() {
                        return None;
                    }
                    SampleFrame::of_jacobian(jacobian((cols[k], rows[k]), (cols[k + 1], rows[k + 1]), (cols[k + w], rows[k + w])), 2.0)
                })
            }
        }?;
        // A sample step along either axis of the frame, as output pixels
        // at each corner: half a pixel at the most.
        let mut k = 1.0f64;
        for (u, v) in [(x as f64, y as f64), ((x + bw) as f64, y as f64), (x as f64, (y + bh) as f64), ((x + bw) as f64, (y + bh) as f64)] {
            let Some(j) = model_j(u, v) else { continue };
            let Some(back) = SampleFrame::of_jacobian(j, 1.0) else { continue };
            for e in [(1.0, 0.0), (0.0, 1.0)] {
                let (c, r) = frame.invert(e.0, e.1);
                let (du, dv) = back.apply(c, r);
                k = k.max(2.0 * du.hypot(dv));
            }
        }
        Some(frame.scaled(k))
    }
}
