//! The DSM's nodes around a tile, projected into the scan, and the ground
//! their occluders can stand on: the lattice of nodes, the nodes
//! projected, and their cells drawn into the Z-buffer.

use super::zbuffer::{Projected, ZBuffer};

/// DSM cells that bend more than this (|z00 + z11 − z01 − z10|, in
/// tolerances) are split into bilinear pieces rather than two triangles.
const SPLIT_BEND: f64 = 4.0;
/// A cell that bends is split into this many pieces a side.
const SPLIT: usize = 4;

/// Where the surface is sampled: nodes `(ox + i dx, oy + j dy)` — the DSM's
/// own posts where they are lines of the ground CRS (a bilinear DSM bends
/// only along them), else a lattice of the output grid.
#[derive(Clone, Copy, Debug)]
pub(super) struct Lattice {
    pub(super) ox: f64,
    pub(super) oy: f64,
    pub(super) dx: f64,
    pub(super) dy: f64,
}

impl Lattice {
    /// Node indices covering ground `[xa, xb] × [ya, yb]`.
    pub(super) fn cover(&self, [xa, ya, xb, yb]: [f64; 4]) -> (i64, i64, i64, i64) {
        let (i0, i1) = ((xa - self.ox) / self.dx, (xb - self.ox) / self.dx);
        let (j0, j1) = ((ya - self.oy) / self.dy, (yb - self.oy) / self.dy);
        (i0.min(i1).floor() as i64, j0.min(j1).floor() as i64, i0.max(i1).ceil() as i64, j0.max(j1).ceil() as i64)
    }

    pub(super) fn node(&self, i: i64, j: i64) -> (f64, f64) {
        (self.ox + i as f64 * self.dx, self.oy + j as f64 * self.dy)
    }

    /// The cell (its first node's indices) holding ground (x, y).
    pub(super) fn cell(&self, x: f64, y: f64) -> (i32, i32) {
        (((x - self.ox) / self.dx).floor() as i32, ((y - self.oy) / self.dy).floor() as i32)
    }
}


/// The ground a tile's occluders can stand on: the tile swept toward the
/// sensor along `g` (horizontal per unit of height) up to `rise`.
pub(super) struct Corridor {
    pub(super) rect: [f64; 4],
    pub(super) g: (f64, f64),
    pub(super) rise: f64,
}

impl Corridor {
    /// `rect` swept along the mean of lines of sight `g` (extremes [min x,
    /// min y, max x, max y]) up to `rise`, widened by how much they turn.
    pub(super) fn toward(rect: [f64; 4], g: [f64; 4], rise: f64) -> Corridor {
        let mean = (0.5 * (g[0] + g[2]), 0.5 * (g[1] + g[3]));
        let turn = (0.5 * rise * (g[2] - g[0]), 0.5 * rise * (g[3] - g[1]));
        Corridor { rect: [rect[0] - turn.0, rect[1] - turn.1, rect[2] + turn.0, rect[3] + turn.1], g: mean, rise }
    }

    /// Is ground (x, y) within `margin` of the corridor? (Some t in
    /// [0, rise] puts (x, y) − t g in the rectangle.)
    pub(super) fn holds(&self, x: f64, y: f64, margin: f64) -> bool {
        let (mut lo, mut hi) = (0.0f64, self.rise.max(0.0));
        for (p, g, a, b) in [(x, self.g.0, self.rect[0] - margin, self.rect[2] + margin), (y, self.g.1, self.rect[1] - margin, self.rect[3] + margin)] {
            if g.abs() < 1e-12 {
                if p < a || p > b {
                    return false;
                }
            } else {
                let (t1, t2) = ((p - b) / g, (p - a) / g);
                lo = lo.max(t1.min(t2));
                hi = hi.min(t1.max(t2));
            }
        }
        lo <= hi
    }
}

/// Lattice nodes with their ground position, height and scan position.
pub(super) struct ProjectedLattice {
    /// The first node's lattice indices.
    pub(super) i0: i32,
    pub(super) j0: i32,
    pub(super) ni: usize,
    pub(super) nj: usize,
    pub(super) xs: Vec<f64>,
    pub(super) ys: Vec<f64>,
    pub(super) zs: Vec<f64>,
    pub(super) cs: Vec<f64>,
    pub(super) rs: Vec<f64>,
}

impl ProjectedLattice {
    /// Each cell's box in the scan (its four nodes'), empty where a node
    /// has no height or no image.
    pub(super) fn cell_boxes(&self) -> Vec<[f32; 4]> {
        let (ni, nj) = (self.ni.saturating_sub(1), self.nj.saturating_sub(1));
        let mut out = Vec::with_capacity(ni * nj);
        for j in 0..nj {
            for i in 0..ni {
                let k = j * self.ni + i;
                let ks = [k, k + 1, k + self.ni, k + self.ni + 1];
                if ks.iter().any(|&q| !(self.cs[q].is_finite() && self.rs[q].is_finite() && self.zs[q].is_finite())) {
                    out.push([f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY]);
                    continue;
                }
                let (mut b0, mut b1, mut b2, mut b3) = (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
                for q in ks {
                    (b0, b1, b2, b3) = (b0.min(self.cs[q]), b1.min(self.rs[q]), b2.max(self.cs[q]), b3.max(self.rs[q]));
                }
                out.push([b0 as f32, b1 as f32, b2 as f32, b3 as f32]);
            }
        }
        out
    }

    /// The bilinear height at ground (x, y) in cell `cell` (global
    /// indices), from the cell's nodes; NaN where it has none.
    pub(super) fn height(&self, l: Lattice, x: f64, y: f64, cell: (i32, i32)) -> f64 {
        let (i, j) = ((cell.0 - self.i0) as i64, (cell.1 - self.j0) as i64);
        if i < 0 || j < 0 || i + 1 >= self.ni as i64 || j + 1 >= self.nj as i64 {
            return f64::NAN;
        }
        let k = j as usize * self.ni + i as usize;
        let fx = (x - l.ox) / l.dx - cell.0 as f64;
        let fy = (y - l.oy) / l.dy - cell.1 as f64;
        let z = [self.zs[k], self.zs[k + 1], self.zs[k + self.ni], self.zs[k + self.ni + 1]];
        (z[0] * (1.0 - fx) + z[1] * fx) * (1.0 - fy) + (z[2] * (1.0 - fx) + z[3] * fx) * fy
    }

    /// The scan position of ground (x, y) in cell `cell`: its four nodes'
    /// positions interpolated bilinearly (NaN where one has none). Over a
    /// DSM cell the bilinear surface projects bilinearly but for the
    /// camera's curvature, hundredths of a scan pixel, and so does a pixel
    /// on it; the GCM would repeat the exact model at every wall.
    pub(super) fn position(&self, l: Lattice, x: f64, y: f64, cell: (i32, i32)) -> (f64, f64) {
        let (i, j) = ((cell.0 - self.i0) as i64, (cell.1 - self.j0) as i64);
        if i < 0 || j < 0 || i + 1 >= self.ni as i64 || j + 1 >= self.nj as i64 {
            return (f64::NAN, f64::NAN);
        }
        let k = j as usize * self.ni + i as usize;
        let fx = (x - l.ox) / l.dx - cell.0 as f64;
        let fy = (y - l.oy) / l.dy - cell.1 as f64;
        let ks = [k, k + 1, k + self.ni, k + self.ni + 1];
        let bilerp = |v: &[f64]| (v[ks[0]] * (1.0 - fx) + v[ks[1]] * fx) * (1.0 - fy) + (v[ks[2]] * (1.0 - fx) + v[ks[3]] * fx) * fy;
        (bilerp(&self.cs), bilerp(&self.rs))
    }

    /// Every cell with heights at its four nodes, one of them above
    /// `floor`, into `zb`: two triangles, or bilinear pieces where it bends
    /// (a building's corner). Whether any was drawn.
    pub(super) fn rasterise(&self, tolerance: f64, boxes: &[[f32; 4]], zb: &mut ZBuffer, floor: f64) -> bool {
        let mut drawn = false;
        let p = |k: usize| -> Projected { (self.cs[k], self.rs[k], self.zs[k]) };
        let [c0, r0, c1, r1] = zb.extent();
        for j in 0..self.nj.saturating_sub(1) {
            for i in 0..self.ni.saturating_sub(1) {
                // (A cell without four projected heights has an empty box.)
                let b = boxes[j * (self.ni - 1) + i];
                if b[2] < c0 || b[0] > c1 || b[3] < r0 || b[1] > r1 {
                    continue;
                }
                let k = j * self.ni + i;
                let q = [p(k), p(k + 1), p(k + self.ni), p(k + self.ni + 1)];
                if q.iter().all(|v| v.2 <= floor) {
                    continue;
                }
                drawn = true;
                let bend = (q[0].2 + q[3].2 - q[1].2 - q[2].2).abs();
                let cell = (self.i0 + i as i32, self.j0 + j as i32);
                if bend > SPLIT_BEND * tolerance {
                    self.split(k, cell, zb);
                } else {
                    zb.quad(q, cell);
                }
            }
        }
        drawn
    }

    /// Cell `k` (its first node) as `SPLIT²` bilinear pieces. Their nodes
    /// are placed in the scan by the affine map through the cell's four
    /// projected nodes (which bend, so they span 3-D): over a cell, a
    /// camera's projection departs from affine by far less than a pixel.
    fn split(&self, k: usize, cell: (i32, i32), zb: &mut ZBuffer) {
        let ks = [k, k + 1, k + self.ni, k + self.ni + 1];
        let (x0, y0, z0) = (self.xs[k], self.ys[k], self.zs[k]);
        let d = |q: usize| nalgebra::Vector3::new(self.xs[q] - x0, self.ys[q] - y0, self.zs[q] - z0);
        let m = nalgebra::Matrix3::from_columns(&[d(ks[1]), d(ks[2]), d(ks[3])]);
        let Some(inv) = m.try_inverse() else {
            return;
        };
        let img = |q: usize| nalgebra::Vector2::new(self.cs[q] - self.cs[k], self.rs[q] - self.rs[k]);
        let a = nalgebra::Matrix2x3::from_columns(&[img(ks[1]), img(ks[2]), img(ks[3])]) * inv;
        let z = [self.zs[ks[0]], self.zs[ks[1]], self.zs[ks[2]], self.zs[ks[3]]];
        let (dx, dy) = (self.xs[k + 1] - x0, self.ys[k + self.ni] - y0);
        let n = SPLIT;
        let mut pts = [(0.0, 0.0, 0.0); (SPLIT + 1) * (SPLIT + 1)];
        for b in 0..=n {
            for c in 0..=n {
                let (fa, fb) = (c as f64 / n as f64, b as f64 / n as f64);
                let zz = z[0] * (1.0 - fa) * (1.0 - fb) + z[1] * fa * (1.0 - fb) + z[2] * (1.0 - fa) * fb + z[3] * fa * fb;
                let p = a * nalgebra::Vector3::new(fa * dx, fb * dy, zz - z0);
                pts[b * (n + 1) + c] = (self.cs[k] + p.x, self.rs[k] + p.y, zz);
            }
        }
        for b in 0..n {
            for c in 0..n {
                let q = b * (n + 1) + c;
                zb.quad([pts[q], pts[q + 1], pts[q + n + 1], pts[q + n + 2]], cell);
            }
        }
    }
}
