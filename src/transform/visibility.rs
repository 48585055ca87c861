//! True orthophotos: which output pixels the sensor sees on the DSM.
//!
//! A Z-buffer in scan space, one tile of output pixels at a time. The DSM's
//! cells under the tile, and toward the sensor as far as the highest surface
//! there could hide the tile, are projected into the scan and rasterised;
//! each Z-buffer sample keeps the highest surface point seen there (along
//! one line of sight from above, the highest point is the one nearest the
//! sensor). An output pixel is seen when its own height reaches what the
//! Z-buffer holds around its scan position, which the GCM already gives.
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

use super::Transform;
use crate::dem::{Height, HeightModel};

/// Where the surface is sampled: nodes `(ox + i dx, oy + j dy)` — the DSM's
/// own posts where they are lines of the ground CRS (a bilinear DSM bends
/// only along them), else a lattice of the output grid.
#[derive(Clone, Copy, Debug)]
struct Lattice {
    ox: f64,
    oy: f64,
    dx: f64,
    dy: f64,
}

impl Lattice {
    /// Node indices covering ground `[xa, xb] × [ya, yb]`.
    fn cover(&self, [xa, ya, xb, yb]: [f64; 4]) -> (i64, i64, i64, i64) {
        let (i0, i1) = ((xa - self.ox) / self.dx, (xb - self.ox) / self.dx);
        let (j0, j1) = ((ya - self.oy) / self.dy, (yb - self.oy) / self.dy);
        (i0.min(i1).floor() as i64, j0.min(j1).floor() as i64, i0.max(i1).ceil() as i64, j0.max(j1).ceil() as i64)
    }

    fn node(&self, i: i64, j: i64) -> (f64, f64) {
        (self.ox + i as f64 * self.dx, self.oy + j as f64 * self.dy)
    }

    /// The cell (its first node's indices) holding ground (x, y).
    fn cell(&self, x: f64, y: f64) -> (i32, i32) {
        (((x - self.ox) / self.dx).floor() as i32, ((y - self.oy) / self.dy).floor() as i32)
    }
}

/// Which pixels of one band the sensor sees, tile by tile.
#[derive(Clone, Debug, Default)]
pub struct Seen {
    /// The band's first walked row and the first tile's first column.
    y0: u32,
    x0: u32,
    tile: u32,
    /// Per tile, `tile × tile` bytes row-major: 1 seen, 0 hidden.
    tiles: Vec<Vec<u8>>,
    /// Pixels the sensor images (a position inside the scan) and of them hidden.
    pub imaged: u64,
    pub hidden: u64,
}

impl Seen {
    pub fn new(y0: u32, x0: u32, tile: u32, tiles: Vec<(Vec<u8>, u64, u64)>) -> Seen {
        let (imaged, hidden) = tiles.iter().fold((0, 0), |(a, b), t| (a + t.1, b + t.2));
        Seen { y0, x0, tile, tiles: tiles.into_iter().map(|t| t.0).collect(), imaged, hidden }
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
        tile.get((cy * t + cx) as usize).is_none_or(|&v| v != 0)
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
    /// The scan's size (columns, rows): pixels imaged outside it are not counted.
    scan: (f64, f64),
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
    max: Vec<std::sync::OnceLock<f32>>,
}

/// Lattice cells a side of a block of [`BlockMax`].
const BLOCK: i64 = 32;

/// A surface point projected: scan column, row, and its height.
type Projected = (f64, f64, f64);

/// DSM cells that bend more than this (|z00 + z11 − z01 − z10|, in
/// tolerances) are split into bilinear pieces rather than two triangles.
const SPLIT_BEND: f64 = 4.0;
/// A cell that bends is split into this many pieces a side.
const SPLIT: usize = 4;
/// The reach toward the sensor is cut at this many tile sides (a line of
/// sight within a few degrees of the horizon would reach out of the scene).
const MAX_REACH_TILES: f64 = 16.0;

impl<'a> Visibility<'a> {
    /// Visibility for `t` (its model, DSM and walked grid) of a scan of
    /// `scan` (columns, rows); heights within `tolerance` of the surface
    /// seen count as seen.
    pub fn new(t: &'a Transform<'a>, scan: (u32, u32), tolerance: f64) -> Visibility<'a> {
        let grid = t.grid;
        let aligned = match &t.dem.model {
            HeightModel::Grid(g) if t.dem.to_dem.is_none() && g.transform[2] == 0.0 && g.transform[4] == 0.0 => Some(g.transform),
            _ => None,
        };
        let lattice = match aligned {
            Some(gt) => {
                // Posts much finer than the output are taken a few at a
                // time, half a pixel apart at most (a roof's edge moves
                // with the lattice).
                let n = (0.5 * grid.gsd / gt[1].abs()).floor().max(1.0);
                Lattice { ox: gt[0] + 0.5 * gt[1], oy: gt[3] + 0.5 * gt[5], dx: gt[1] * n, dy: gt[5] * n }
            }
            None => Lattice { ox: grid.x0 + 0.5 * grid.gsd, oy: grid.y0 - 0.5 * grid.gsd, dx: grid.gsd, dy: -grid.gsd },
        };
        // The output's ground, and as far again around it as the reach can go.
        let (xa, ya) = t.ground(0.0, 0.0);
        let (xb, yb) = t.ground(grid.width as f64, grid.height as f64);
        let reach = MAX_REACH_TILES * 256.0 * grid.gsd;
        let region = [xa.min(xb) - reach, ya.min(yb) - reach, xa.max(xb) + reach, ya.max(yb) + reach];
        let (i0, j0, i1, j1) = lattice.cover(region);
        let (across, down) = (((i1 - i0) / BLOCK + 1) as usize, ((j1 - j0) / BLOCK + 1) as usize);
        let blocks = BlockMax { i0, j0, across, down, max: (0..across * down).map(|_| std::sync::OnceLock::new()).collect() };
        Visibility { t, lattice, tolerance, scan: (scan.0 as f64, scan.1 as f64), blocks }
    }

    /// The highest height in block (bi, bj) (its nodes and its far edge's),
    /// −∞ where it has none or lies outside the region.
    fn block_max(&self, bi: i64, bj: i64) -> f64 {
        let b = &self.blocks;
        if bi < 0 || bj < 0 || bi >= b.across as i64 || bj >= b.down as i64 {
            return f64::NEG_INFINITY;
        }
        *b.max[bj as usize * b.across + bi as usize].get_or_init(|| {
            let (i0, j0) = (b.i0 + bi * BLOCK, b.j0 + bj * BLOCK);
            let mut hi = f64::NEG_INFINITY;
            for j in j0..=j0 + BLOCK {
                for i in i0..=i0 + BLOCK {
                    let (x, y) = self.lattice.node(i, j);
                    let z = self.z(x, y);
                    if z > hi {
                        hi = z;
                    }
                }
            }
            hi as f32
        }) as f64
    }

    /// How high above `zlo` the tile `rect` must look for occluders: the
    /// highest block within the capped reach that stands high enough to
    /// reach the tile along lines of sight sloping `slope` (horizontal per
    /// unit of height, the steepest at the tile), at least `zhi − zlo`.
    fn occluder_rise(&self, rect: [f64; 4], window: [f64; 4], zlo: f64, zhi: f64, slope: f64) -> f64 {
        let mut rise = zhi - zlo;
        let (i0, j0, i1, j1) = self.lattice.cover(window);
        let b = &self.blocks;
        let (bi0, bj0) = ((i0 - b.i0).div_euclid(BLOCK), (j0 - b.j0).div_euclid(BLOCK));
        let (bi1, bj1) = ((i1 - b.i0).div_euclid(BLOCK), (j1 - b.j0).div_euclid(BLOCK));
        for bj in bj0..=bj1 {
            for bi in bi0..=bi1 {
                let top = self.block_max(bi, bj) - zlo;
                if !(top > rise) {
                    continue;
                }
                // The block's ground, and its distance from the tile.
                let (xa, ya) = self.lattice.node(b.i0 + bi * BLOCK, b.j0 + bj * BLOCK);
                let (xb, yb) = self.lattice.node(b.i0 + (bi + 1) * BLOCK, b.j0 + (bj + 1) * BLOCK);
                let dx = (xa.min(xb) - rect[2]).max(rect[0] - xa.max(xb)).max(0.0);
                let dy = (ya.min(yb) - rect[3]).max(rect[1] - ya.max(yb)).max(0.0);
                if dx.hypot(dy) <= top * slope {
                    rise = top;
                }
            }
        }
        rise
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

    /// Which pixels of walked tile `[x0, y0, x1, y1]` are seen, given their
    /// scan positions (row-major, NaN where none): 1 seen, 0 hidden, into
    /// `seen` (`t × t`, row-major); and how many pixels are imaged and hidden.
    pub fn tile(&self, [x0, y0, x1, y1]: [u32; 4], t: u32, cols: &[f64], rows: &[f64], seen: &mut [u8]) -> (u64, u64) {
        let (w, h) = ((x1 - x0) as usize, (y1 - y0) as usize);
        seen.fill(1);
        // The tile's ground (pixel centres) and its heights.
        let corners =
            [(x0 as f64 + 0.5, y0 as f64 + 0.5), (x1 as f64 - 0.5, y0 as f64 + 0.5), (x0 as f64 + 0.5, y1 as f64 - 0.5), (x1 as f64 - 0.5, y1 as f64 - 0.5)];
        let ground: Vec<(f64, f64)> = corners.iter().map(|&(u, v)| self.t.ground(u, v)).collect();
        let rect = ground
            .iter()
            .fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |b, &(x, y)| [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)]);
        let (zlo, zhi) = self.height_range(rect);
        if !zlo.is_finite() {
            return (0, 0);
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
            return (0, 0);
        }
        let cap = MAX_REACH_TILES * (rect[2] - rect[0]).max(rect[3] - rect[1]).max(self.lattice.dx.abs());
        let window = |dz: f64| {
            let m = |v: f64| if v == 0.0 { 0.0 } else { (dz * v).clamp(-cap, cap) };
            [rect[0] + m(g[0]).min(0.0), rect[1] + m(g[1]).min(0.0), rect[2] + m(g[2]).max(0.0), rect[3] + m(g[3]).max(0.0)]
        };
        // As far toward the sensor as the highest surface that could hide
        // the tile stands (within the cap).
        let slope = g[0].abs().max(g[2].abs()).hypot(g[1].abs().max(g[3].abs()));
        let rise = self.occluder_rise(rect, window(f64::INFINITY), zlo, zhi, slope);
        let lattice = self.project_lattice(window(rise));

        // The Z-buffer over the tile's scan positions, samples about a
        // pixel's footprint apart.
        let mut bb = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
        for (&c, &r) in cols.iter().zip(rows) {
            if c.is_finite() && r.is_finite() {
                bb = [bb[0].min(c), bb[1].min(r), bb[2].max(c), bb[3].max(r)];
            }
        }
        if !bb[0].is_finite() {
            return (0, 0);
        }
        let step = 0.5 * footprint(cols, rows, w, h).max(1e-3);
        let n = (w * h) as f64;
        // Never more than 4 samples a pixel (a tile turned 45° fills half its box).
        let step = step.max(((bb[2] - bb[0]) * (bb[3] - bb[1]) / (16.0 * n)).sqrt());
        let zb = ZBuffer::new(bb, step);
        let mut zb = zb;
        lattice.rasterise(self, &mut zb);

        let (src_w, src_h) = self.scan;
        let (mut imaged, mut hidden) = (0, 0);
        for y in 0..h {
            for x in 0..w {
                let k = y * w + x;
                let (c, r) = (cols[k], rows[k]);
                if !(c >= 0.0 && r >= 0.0 && c <= src_w && r <= src_h) {
                    continue;
                }
                imaged += 1;
                let (gx, gy) = self.t.ground(x0 as f64 + x as f64 + 0.5, y0 as f64 + y as f64 + 0.5);
                let z = self.z(gx, gy);
                if !z.is_finite() {
                    continue;
                }
                let (above, cell) = zb.seen_height(c, r);
                // Hidden: a surface above the pixel's is seen where it
                // would be, and not its own or its cell's neighbours' (a
                // bilinear wall between two posts seen edge-on is no cover).
                let own = self.lattice.cell(gx, gy);
                if z + self.tolerance < above && ((cell.0 - own.0).abs() > 1 || (cell.1 - own.1).abs() > 1) {
                    seen[y * t as usize + x] = 0;
                    hidden += 1;
                }
            }
        }
        (imaged, hidden)
    }

    /// The lowest and highest height at the lattice nodes over ground `rect`
    /// (NaN, NaN where none).
    fn height_range(&self, rect: [f64; 4]) -> (f64, f64) {
        let (i0, j0, i1, j1) = self.lattice.cover(rect);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let (x, y) = self.lattice.node(i, j);
                let z = self.z(x, y);
                if z.is_finite() {
                    lo = lo.min(z);
                    hi = hi.max(z);
                }
            }
        }
        if lo.is_finite() {
            (lo, hi)
        } else {
            (f64::NAN, f64::NAN)
        }
    }

    /// The lattice nodes over ground `rect`, projected into the scan.
    fn project_lattice(&self, rect: [f64; 4]) -> ProjectedLattice {
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
                zs.push(self.z(x, y));
            }
        }
        let mut cs = vec![0.0; xs.len()];
        let mut rs = vec![0.0; xs.len()];
        self.t.model.project_many(&xs, &ys, &zs, &mut cs, &mut rs);
        ProjectedLattice { i0: i0 as i32, j0: j0 as i32, ni, nj, xs, ys, zs, cs, rs }
    }
}

/// Lattice nodes with their ground position, height and scan position.
struct ProjectedLattice {
    /// The first node's lattice indices.
    i0: i32,
    j0: i32,
    ni: usize,
    nj: usize,
    xs: Vec<f64>,
    ys: Vec<f64>,
    zs: Vec<f64>,
    cs: Vec<f64>,
    rs: Vec<f64>,
}

impl ProjectedLattice {
    /// Every cell with heights at its four nodes into `zb`: two triangles,
    /// or bilinear pieces where it bends (a building's corner).
    fn rasterise(&self, vis: &Visibility, zb: &mut ZBuffer) {
        let p = |k: usize| -> Projected { (self.cs[k], self.rs[k], self.zs[k]) };
        for j in 0..self.nj.saturating_sub(1) {
            for i in 0..self.ni.saturating_sub(1) {
                let k = j * self.ni + i;
                let q = [p(k), p(k + 1), p(k + self.ni), p(k + self.ni + 1)];
                if q.iter().any(|v| !(v.0.is_finite() && v.1.is_finite() && v.2.is_finite())) {
                    continue;
                }
                if !zb.touches(&q) {
                    continue;
                }
                let bend = (q[0].2 + q[3].2 - q[1].2 - q[2].2).abs();
                let cell = (self.i0 + i as i32, self.j0 + j as i32);
                if bend > SPLIT_BEND * vis.tolerance {
                    self.split(vis, k, cell, zb);
                } else {
                    zb.quad(q, cell);
                }
            }
        }
    }

    /// Cell `k` (its first node) as `SPLIT²` bilinear pieces, each projected.
    fn split(&self, vis: &Visibility, k: usize, cell: (i32, i32), zb: &mut ZBuffer) {
        let (x0, y0) = (self.xs[k], self.ys[k]);
        let (dx, dy) = (self.xs[k + 1] - x0, self.ys[k + self.ni] - y0);
        let z = [self.zs[k], self.zs[k + 1], self.zs[k + self.ni], self.zs[k + self.ni + 1]];
        let n = SPLIT;
        let mut pts = Vec::with_capacity((n + 1) * (n + 1));
        for b in 0..=n {
            for a in 0..=n {
                let (fa, fb) = (a as f64 / n as f64, b as f64 / n as f64);
                let zz = z[0] * (1.0 - fa) * (1.0 - fb) + z[1] * fa * (1.0 - fb) + z[2] * (1.0 - fa) * fb + z[3] * fa * fb;
                let (x, y) = (x0 + fa * dx, y0 + fb * dy);
                let (c, r) = vis.t.model.project(x, y, zz).unwrap_or((f64::NAN, f64::NAN));
                pts.push((c, r, zz));
            }
        }
        for b in 0..n {
            for a in 0..n {
                let k = b * (n + 1) + a;
                let q = [pts[k], pts[k + 1], pts[k + n + 1], pts[k + n + 2]];
                if q.iter().all(|v| v.0.is_finite() && v.1.is_finite()) {
                    zb.quad(q, cell);
                }
            }
        }
    }
}

/// The highest surface seen at each sample of a scan window, with the
/// slope of the triangle that put it there: the surface seen at any scan
/// position is then its nearest sample's plane, not the sample's value.
struct ZBuffer {
    c0: f64,
    r0: f64,
    inv: f64,
    w: usize,
    h: usize,
    z: Vec<f32>,
    /// d z / d (buffer column, row) of the triangle seen at each sample.
    slope: Vec<[f32; 2]>,
    /// The lattice cell it belongs to.
    cell: Vec<(i32, i32)>,
}

impl ZBuffer {
    /// Samples `step` scan pixels apart over `[c0, r0, c1, r1]` and a
    /// sample beyond.
    fn new([c0, r0, c1, r1]: [f64; 4], step: f64) -> ZBuffer {
        let (c0, r0) = (c0 - 2.0 * step, r0 - 2.0 * step);
        let w = ((c1 - c0) / step).ceil() as usize + 3;
        let h = ((r1 - r0) / step).ceil() as usize + 3;
        ZBuffer { c0, r0, inv: 1.0 / step, w, h, z: vec![f32::NEG_INFINITY; w * h], slope: vec![[0.0; 2]; w * h], cell: vec![(i32::MIN, i32::MIN); w * h] }
    }

    /// Buffer coordinates of scan (c, r): sample centres at integers.
    #[inline]
    fn at(&self, c: f64, r: f64) -> (f64, f64) {
        ((c - self.c0) * self.inv - 0.5, (r - self.r0) * self.inv - 0.5)
    }

    /// Does the quad's box meet the buffer?
    fn touches(&self, q: &[Projected; 4]) -> bool {
        let (mut a, mut b) = (f64::INFINITY, f64::INFINITY);
        let (mut c, mut d) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        for p in q {
            let (x, y) = self.at(p.0, p.1);
            (a, b, c, d) = (a.min(x), b.min(y), c.max(x), d.max(y));
        }
        c >= 0.0 && d >= 0.0 && a <= (self.w - 1) as f64 && b <= (self.h - 1) as f64
    }

    /// Quad `[p00, p10, p01, p11]` as two triangles.
    fn quad(&mut self, q: [Projected; 4], cell: (i32, i32)) {
        self.triangle(q[0], q[1], q[3], cell);
        self.triangle(q[0], q[3], q[2], cell);
    }

    /// Every sample inside the triangle keeps the higher of its height and
    /// the triangle's there (linear in the scan), with the slope of its own.
    fn triangle(&mut self, a: Projected, b: Projected, c: Projected, cell: (i32, i32)) {
        let (ax, ay) = self.at(a.0, a.1);
        let (bx, by) = self.at(b.0, b.1);
        let (cx, cy) = self.at(c.0, c.1);
        let area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
        if area.abs() < 1e-12 {
            return;
        }
        let xa = ax.min(bx).min(cx).ceil().max(0.0) as i64;
        let xb = ax.max(bx).max(cx).floor().min((self.w - 1) as f64) as i64;
        let ya = ay.min(by).min(cy).ceil().max(0.0) as i64;
        let yb = ay.max(by).max(cy).floor().min((self.h - 1) as f64) as i64;
        if xa > xb || ya > yb {
            return;
        }
        let inv = 1.0 / area;
        let (db, dc) = (b.2 - a.2, c.2 - a.2);
        let gx = (db * (cy - ay) - dc * (by - ay)) * inv;
        let gy = (dc * (bx - ax) - db * (cx - ax)) * inv;
        let slope = [gx as f32, gy as f32];
        // Barycentric weights of b and c, linear in the sample position;
        // a sample on an edge counts (a max never double-counts).
        let eps = -1e-9;
        for y in ya..=yb {
            let fy = y as f64;
            for x in xa..=xb {
                let fx = x as f64;
                let wb = ((fx - ax) * (cy - ay) - (fy - ay) * (cx - ax)) * inv;
                let wc = ((bx - ax) * (fy - ay) - (by - ay) * (fx - ax)) * inv;
                if wb < eps || wc < eps || 1.0 - wb - wc < eps {
                    continue;
                }
                let z = (a.2 + wb * db + wc * dc) as f32;
                let k = y as usize * self.w + x as usize;
                if z > self.z[k] {
                    self.z[k] = z;
                    self.slope[k] = slope;
                    self.cell[k] = cell;
                }
            }
        }
    }

    /// The height of the surface seen at scan (c, r): its nearest sample's
    /// plane there, within the heights of the four samples around (a
    /// wall seen edge-on is steep enough to reach anywhere), and its
    /// lattice cell; −∞ where nothing is seen.
    fn seen_height(&self, c: f64, r: f64) -> (f64, (i32, i32)) {
        let none = (f64::NEG_INFINITY, (i32::MIN, i32::MIN));
        let (x, y) = self.at(c, r);
        let (i, j) = (x.floor() as i64, y.floor() as i64);
        if i < 0 || j < 0 || i + 1 >= self.w as i64 || j + 1 >= self.h as i64 {
            return none;
        }
        let (i, j) = (i as usize, j as usize);
        let k = [j * self.w + i, j * self.w + i + 1, (j + 1) * self.w + i, (j + 1) * self.w + i + 1];
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for &q in &k {
            lo = lo.min(self.z[q]);
            hi = hi.max(self.z[q]);
        }
        let (fx, fy) = (x - i as f64, y - j as f64);
        let near = k[usize::from(fx >= 0.5) + 2 * usize::from(fy >= 0.5)];
        let z = self.z[near];
        if z == f32::NEG_INFINITY {
            return none;
        }
        let (sx, sy) = ((near % self.w) as f64, (near / self.w) as f64);
        let [gx, gy] = self.slope[near];
        let plane = z as f64 + gx as f64 * (x - sx) + gy as f64 * (y - sy);
        let cell = self.cell[near];
        if lo == f32::NEG_INFINITY {
            return (plane.min(hi as f64), cell);
        }
        (plane.clamp(lo as f64, hi as f64), cell)
    }
}

/// About one output pixel's footprint in the scan (scan pixels): the
/// shorter of the steps between neighbouring pixels at the tile's middle.
fn footprint(cols: &[f64], rows: &[f64], w: usize, h: usize) -> f64 {
    let mut best = f64::INFINITY;
    for (y, x) in [(h / 2, w / 2), (h / 4, w / 4), (3 * h / 4, 3 * w / 4)] {
        let k = y * w + x;
        if x + 1 < w {
            let d = (cols[k + 1] - cols[k]).hypot(rows[k + 1] - rows[k]);
            if d.is_finite() {
                best = best.min(d);
            }
        }
        if y + 1 < h {
            let d = (cols[k + w] - cols[k]).hypot(rows[k + w] - rows[k]);
            if d.is_finite() {
                best = best.min(d);
            }
        }
    }
    if best.is_finite() {
        best
    } else {
        1.0
    }
}
