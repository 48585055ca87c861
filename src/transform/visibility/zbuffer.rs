//! The Z-buffer: the highest surface seen at each sample of a scan window,
//! and how its samples are laid on the scan.

/// A surface point projected: scan column, row, and its height.
pub(super) type Projected = (f64, f64, f64);


/// The highest surface seen at each sample of a scan window, with the
/// slope of the triangle that put it there: the surface seen at any scan
/// position is then its nearest sample's plane, not the sample's value.
pub(super) struct ZBuffer {
    /// Scan → samples, and the first sample's place in that frame.
    pub(super) frame: SampleFrame,
    u0: f64,
    v0: f64,
    pub(super) w: usize,
    pub(super) h: usize,
    pub(super) z: Vec<f32>,
    /// The triangle seen at each sample, in `tris`.
    tri: Vec<u32>,
    /// Each triangle drawn: d z / d (buffer column, row), and its lattice cell.
    tris: Vec<([f32; 2], (i32, i32))>,
}

impl ZBuffer {
    /// Samples of `frame` over its box `[u0, v0, u1, v1]` and two beyond.
    pub(super) fn new(frame: SampleFrame, [u0, v0, u1, v1]: [f64; 4]) -> ZBuffer {
        let (u0, v0) = (u0 - 2.0, v0 - 2.0);
        let w = (u1 - u0).ceil() as usize + 3;
        let h = (v1 - v0).ceil() as usize + 3;
        ZBuffer { frame, u0, v0, w, h, z: vec![f32::NEG_INFINITY; w * h], tri: vec![0; w * h], tris: Vec::new() }
    }

    /// Buffer coordinates of scan (c, r): sample centres at integers.
    #[inline]
    pub(super) fn at(&self, c: f64, r: f64) -> (f64, f64) {
        let (u, v) = self.frame.apply(c, r);
        (u - self.u0 - 0.5, v - self.v0 - 0.5)
    }

    /// The scan box the samples cover.
    pub(super) fn extent(&self) -> [f32; 4] {
        let (u1, v1) = (self.u0 + self.w as f64, self.v0 + self.h as f64);
        let mut b = [f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY];
        for (u, v) in [(self.u0, self.v0), (u1, self.v0), (self.u0, v1), (u1, v1)] {
            let (c, r) = self.frame.invert(u, v);
            b = [b[0].min(c as f32), b[1].min(r as f32), b[2].max(c as f32), b[3].max(r as f32)];
        }
        b
    }

    /// Quad `[p00, p10, p01, p11]` as two triangles.
    pub(super) fn quad(&mut self, q: [Projected; 4], cell: (i32, i32)) {
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
        // Along a row of samples the barycentric weights of b and c are
        // p + q x, p linear in the row: each edge bounds the row's run of
        // samples inside (edges count, as a max never double-counts) by a
        // column linear in the row, worked out once a triangle.
        let (qb, qc) = ((cy - ay) * inv, -(by - ay) * inv);
        let (pb0, pb1) = (-ax * (cy - ay) * inv, -(cx - ax) * inv);
        let (pc0, pc1) = ((by - ay) * ax * inv, (bx - ax) * inv);
        let eps = -1e-9;
        // Per edge: its weight's p (at row offset 0, per row) and q.
        let edges = [(pb0, pb1, qb), (pc0, pc1, qc), (1.0 - pb0 - pc0, -pb1 - pc1, -qb - qc)];
        // (from, per row, lower bound?) of each edge whose q is not 0;
        // an edge along the rows bounds the rows instead.
        let mut bounds = [(0.0, 0.0, true); 3];
        let mut n = 0;
        let (mut ya, mut yb) = (ya as f64, yb as f64);
        for (p0, p1, q) in edges {
            if q != 0.0 {
                bounds[n] = ((eps - p0) / q, -p1 / q, q > 0.0);
                n += 1;
            } else if p1 == 0.0 {
                if p0 < eps {
                    return;
                }
            } else {
                // p0 + p1 (y − ay) ≥ eps
                let edge = ay + (eps - p0) / p1;
                if p1 > 0.0 {
                    ya = ya.max(edge.ceil());
                } else {
                    yb = yb.min(edge.floor());
                }
            }
        }
        let (z_b, z_c) = (db * qb + dc * qc, a.2 + db * pb0 + dc * pc0);
        let z_row = db * pb1 + dc * pc1;
        let (id, dz) = (self.tris.len() as u32, z_b as f32);
        let mut drawn = false;
        let mut y = ya;
        while y <= yb {
            let fy = y - ay;
            let (mut lo, mut hi) = (xa as f64, xb as f64);
            for &(from, step, lower) in &bounds[..n] {
                let edge = from + fy * step;
                if lower {
                    lo = lo.max(edge.ceil());
                } else {
                    hi = hi.min(edge.floor());
                }
            }
            if lo <= hi {
                let (row, lo, hi) = (y as usize * self.w, lo as usize, hi as usize);
                // z = a + db·wb + dc·wc, linear in x along the row, in f32
                // (a millimetre on heights of thousands of metres); the
                // row's slices and a float counter, no branch: the fill's
                // cost.
                let z0 = (z_c + z_row * fy) as f32;
                let mut x = lo as f32;
                for (zk, tk) in self.z[row + lo..=row + hi].iter_mut().zip(&mut self.tri[row + lo..=row + hi]) {
                    let z = z0 + dz * x;
                    let higher = z > *zk;
                    *zk = if higher { z } else { *zk };
                    *tk = if higher { id } else { *tk };
                    drawn |= higher;
                    x += 1.0;
                }
            }
            y += 1.0;
        }
        if drawn {
            self.tris.push(([gx as f32, gy as f32], cell));
        }
    }

    /// The height of the surface seen at scan (c, r): its nearest sample's
    /// plane there, within the heights of the four samples around (a
    /// wall seen edge-on is steep enough to reach anywhere), and its
    /// lattice cell; −∞ where nothing is seen.
    pub(super) fn seen_height(&self, c: f64, r: f64) -> (f64, (i32, i32)) {
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
        let ([gx, gy], cell) = self.tris[self.tri[near] as usize];
        let plane = z as f64 + gx as f64 * (x - sx) + gy as f64 * (y - sy);
        if lo == f32::NEG_INFINITY {
            return (plane.min(hi as f64), cell);
        }
        (plane.clamp(lo as f64, hi as f64), cell)
    }
}

/// A Z-buffer's sampling of the scan: a linear map from scan (column,
/// row) to samples, half an output pixel apart along the output grid's own
/// axes. Samples along the scan's axes would need as many again: an oblique
/// view turns and shears the output's pixels in the scan, and a box of the
/// scan around them holds far more than they cover.
#[derive(Clone, Copy, Debug)]
pub(super) struct SampleFrame {
    /// Scan → samples, and back.
    pub(super) m: [[f64; 2]; 2],
    pub(super) inv: [[f64; 2]; 2],
}

impl SampleFrame {
    /// The frame of `j` (d(column, row) / d(output x, y), at a point),
    /// samples `1/density` output pixels apart; `None` where `j` is singular.
    pub(super) fn of_jacobian(j: [[f64; 2]; 2], density: f64) -> Option<SampleFrame> {
        let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
        if !det.is_finite() || det.abs() < 1e-12 {
            return None;
        }
        let inv = [[j[1][1] / det, -j[0][1] / det], [-j[1][0] / det, j[0][0] / det]];
        let m = [[inv[0][0] * density, inv[0][1] * density], [inv[1][0] * density, inv[1][1] * density]];
        Some(SampleFrame { m, inv: [[j[0][0] / density, j[0][1] / density], [j[1][0] / density, j[1][1] / density]] })
    }

    #[inline]
    pub(super) fn apply(&self, c: f64, r: f64) -> (f64, f64) {
        (self.m[0][0] * c + self.m[0][1] * r, self.m[1][0] * c + self.m[1][1] * r)
    }

    pub(super) fn invert(&self, u: f64, v: f64) -> (f64, f64) {
        (self.inv[0][0] * u + self.inv[0][1] * v, self.inv[1][0] * u + self.inv[1][1] * v)
    }

    /// The same axes, `k` times as many samples a unit.
    pub(super) fn scaled(&self, k: f64) -> SampleFrame {
        let m = self.m.map(|row| row.map(|v| v * k));
        let inv = self.inv.map(|row| row.map(|v| v / k));
        SampleFrame { m, inv }
    }
}

/// d(column, row) / d(x, y) from positions at a point and one step along x and y.
pub(super) fn jacobian(p: (f64, f64), px: (f64, f64), py: (f64, f64)) -> [[f64; 2]; 2] {
    [[px.0 - p.0, py.0 - p.0], [px.1 - p.1, py.1 - p.1]]
}
