//! The error bound (`max_error`, bilinear only): every cell between four
//! nodes held to it at every pixel, by two estimates that see what a few check
//! points cannot:
//!
//! * the terrain's part, complete: within a cell the DEM is piecewise
//!   bilinear, bending only along its post lines, so its greatest departure
//!   from the plane of the cell's four corners is at the posts inside the
//!   cell or where post lines cross its edges. That height error times the
//!   image's displacement per metre of height (the relief rate, at the
//!   cell) bounds what the corrections' interpolation can miss of the
//!   terrain: a wall or a roof edge between the nodes shows there, however
//!   thin;
//! * the smooth part (the lens, `A`'s curvature, slopes): from the second
//!   differences of the corrections at the nodes around the cell.
//!
//! A cell over the bound is split as a quadtree — at the DEM's own lines
//! where one crosses it (the pieces are then smooth), else in the middle —
//! and pieces that would cost more to split than to compute (≤ 52 px) are
//! evaluated exactly; inside one DEM column (height linear along a row)
//! such pieces, and those far over the bound, row by row as quadratics
//! through the exact model, checked between.

use super::quadtree::Node;
use super::{steps_through, Gcm, GcmStats, NodeRow, Quad, EDGE};
use crate::dem::{Height, Lookup};

impl<'a> Gcm<'a> {
    /// Whether every cell of the band is within `bound` without a look at
    /// each: where no DEM line runs inside a cell (a flat DEM, or its post
    /// lines among the node lines), the band's largest curvature over its
    /// widest cell and its largest height span hold the bound for all.
    pub(super) fn band_within(&self, rows: &[NodeRow], (uu, vv): &(Vec<Vec<f64>>, Vec<Vec<f64>>), bound: f64) -> bool {
        let flat = matches!(self.t.dem.model, crate::dem::HeightModel::Flat(_));
        if !(flat || self.dem_aligned_lines()) || rows.len() < 2 {
            return false;
        }
        // A height a policy gives meets the DEM's own in a step off its
        // post lines (its edge is half a posting past them): each cell is
        // looked at.
        if !flat && self.policy_heights() {
            return false;
        }
        let n = self.nodes_x;
        // The first and last node columns have no second difference.
        let most = |g: &Vec<Vec<f64>>| -> f64 {
            let mut m = 0.0f64;
            for row in g {
                for &x in &row[1..n - 1] {
                    m = if x.is_nan() { f64::INFINITY } else { m.max(x) };
                }
            }
            m
        };
        let (cu, cv) = (most(uu), most(vv));
        let du = self.max_gap;
        let dv = rows.windows(2).map(|p| self.node_v(p[1].j) - self.node_v(p[0].j)).fold(0.0, f64::max);
        let mut span = 0.0f64;
        if !flat {
            for p in rows.windows(2) {
                for i in 0..n - 1 {
                    let z = [p[0].z[i], p[0].z[i + 1], p[1].z[i], p[1].z[i + 1]];
                    let (lo, hi) = z.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
                    // Cells without heights are the nodata cells, filled by T.
                    if lo.is_finite() {
                        span = span.max(hi - lo);
                    }
                }
            }
        }
        let h = span / 2.0;
        (du * du * cu + dv * dv * cv) / 8.0 + 0.5 * self.relief.1 * h * h <= bound
    }

    /// The second derivatives of the corrections' smooth part at every
    /// node of `rows` (scan pixels a pixel²), along u and along v: from
    /// their second differences with the neighbouring nodes, the terrain's
    /// part taken out first (the height's change from the node times the
    /// image's movement a metre there), so that what is measured is the
    /// lens, `A`'s curvature and the slopes; the terrain's kinks are
    /// `terrain_error`'s. NaN where a neighbour has no value; along v, a
    /// band's first and last rows take their neighbour's.
    pub(super) fn smooth_curvature(&self, rows: &[NodeRow]) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
        let n = self.nodes_x;
        // |f''| at the middle of three nodes `a`, `b`, `c` (the terrain's
        // part, as the middle node sees it, taken out), their spacings `d1`,
        // `d2`: one division for both coordinates.
        #[inline(always)]
        fn curvature(d1: f64, d2: f64, (ac, ar, az): (f64, f64, f64), (bc, br, bz, [tc, tr]): (f64, f64, f64, [f64; 2]), (cc, cr, cz): (f64, f64, f64)) -> f64 {
            let k = 2.0 / (d1 * d2 * (d1 + d2));
            let (tc, tr) = if tc.is_nan() { (0.0, 0.0) } else { (tc, tr) };
            let (ac, ar) = (ac - tc * (az - bz), ar - tr * (az - bz));
            let (cc, cr) = (cc - tc * (cz - bz), cr - tr * (cz - bz));
            let sc = ((cc - bc) * d1 - (bc - ac) * d2) * k;
            let sr = ((cr - br) * d1 - (br - ar) * d2) * k;
            (sc * sc + sr * sr).sqrt()
        }
        let tz = |row: &NodeRow, m: usize| row.tz.get(m).copied().unwrap_or([0.0; 2]);
        let uu: Vec<Vec<f64>> = rows
            .iter()
            .map(|row| {
                let mut out = vec![f64::NAN; n];
                let (dc, dr, z, xs) = (&row.dc[..n], &row.dr[..n], &row.z[..n], &self.xs[..n]);
                for m in 1..n - 1 {
                    out[m] = curvature(
                        xs[m] - xs[m - 1],
                        xs[m + 1] - xs[m],
                        (dc[m - 1], dr[m - 1], z[m - 1]),
                        (dc[m], dr[m], z[m], tz(row, m)),
                        (dc[m + 1], dr[m + 1], z[m + 1]),
                    );
                }
                out
            })
            .collect();
        let mut vv: Vec<Vec<f64>> = (0..rows.len())
            .map(|r| {
                if r == 0 || r + 1 == rows.len() {
                    return Vec::new();
                }
                let (p, c, q) = (&rows[r - 1], &rows[r], &rows[r + 1]);
                let (d1, d2) = (self.node_v(c.j) - self.node_v(p.j), self.node_v(q.j) - self.node_v(c.j));
                (0..n).map(|m| curvature(d1, d2, (p.dc[m], p.dr[m], p.z[m]), (c.dc[m], c.dr[m], c.z[m], tz(c, m)), (q.dc[m], q.dr[m], q.z[m]))).collect()
            })
            .collect();
        let last = rows.len() - 1;
        if rows.len() >= 3 {
            vv[0] = vv[1].clone();
            vv[last] = vv[last - 1].clone();
        } else {
            // Too few rows for a difference across them: as steep as along u.
            vv = uu.clone();
        }
        (uu, vv)
    }

    /// The interpolation error over a cell of `du`×`dv` pixels between node
    /// rows `n`, `n + 1` and columns `i`, `i + 1`, of the corrections'
    /// smooth part (bilinear interpolation misses at most h²/8 of the second
    /// derivative along each side of length h): the largest curvature at the
    /// cell's nodes and their neighbours along each axis. Infinite where a
    /// node has no value.
    pub(super) fn smooth_error(&self, (uu, vv): &(Vec<Vec<f64>>, Vec<Vec<f64>>), n: usize, i: usize, du: f64, dv: f64) -> f64 {
        let most = |g: &Vec<Vec<f64>>| {
            let mut m = f64::NEG_INFINITY;
            for row in &g[n..n + 2] {
                for &x in &row[i.saturating_sub(1)..(i + 3).min(row.len())] {
                    if !x.is_nan() {
                        m = m.max(x);
                    }
                }
            }
            m
        };
        let (cu, cv) = (most(uu), most(vv));
        let e = (du * du * cu + dv * dv * cv) / 8.0;
        if e.is_finite() && e >= 0.0 {
            e
        } else {
            f64::INFINITY
        }
    }

    /// Where output position (u, v) falls among the DEM's samples.
    pub(super) fn dem_coords(&self, u: f64, v: f64) -> [f64; 2] {
        let (x, y) = self.t.ground(u, v);
        self.t.dem.sample_coords(x, y).map_or([f64::NAN; 2], |(c, r)| [c, r])
    }

    /// The greatest departure of a DEM not aligned with the output from the
    /// plane through `q`'s corner heights, and the range of heights met:
    /// at the DEM's samples inside the cell and where its sample lines
    /// cross the edges (the cell is a near-parallelogram among the samples,
    /// mapped by its corners). `None` where the corners' places are unknown.
    pub(super) fn unaligned_departure(&self, q: &Quad, plane: &dyn Fn(f64, f64) -> f64) -> Option<(f64, f64, f64)> {
        let crate::dem::HeightModel::Grid(g) = &self.t.dem.model else { return None };
        let p = q.dp;
        if p.iter().flatten().any(|v| !v.is_finite()) {
            return None;
        }
        // (fu, fv) in the cell → sample coordinates, bilinear in the corners.
        let at = |fu: f64, fv: f64| {
            let top = [p[0][0] + fu * (p[1][0] - p[0][0]), p[0][1] + fu * (p[1][1] - p[0][1])];
            let bottom = [p[2][0] + fu * (p[3][0] - p[2][0]), p[2][1] + fu * (p[3][1] - p[2][1])];
            [top[0] + fv * (bottom[0] - top[0]), top[1] + fv * (bottom[1] - top[1])]
        };
        let (mut worst, mut lo, mut hi) = (0.0f64, f64::INFINITY, f64::NEG_INFINITY);
        let mut look = |fu: f64, fv: f64, z: f64| {
            let d = (z - plane(q.u0 + fu * q.du, q.v0 + fv * q.dv)).abs();
            worst = if d.is_nan() { f64::INFINITY } else { worst.max(d) };
            (lo, hi) = (lo.min(z), hi.max(z));
        };
        // Where sample lines cross the four edges.
        for (a, b, fixed_u) in [(0usize, 1usize, None), (2, 3, None), (0, 2, Some(0.0)), (1, 3, Some(1.0))] {
            for (s0, s1) in [(p[a][0], p[b][0]), (p[a][1], p[b][1])] {
                let (first, last) = (s0.min(s1).floor() as i64 + 1, s0.max(s1).ceil() as i64 - 1);
                if last - first > 4096 {
                    return None;
                }
                for line in first..=last {
                    let t = (line as f64 - s0) / (s1 - s0);
                    let (fu, fv) = match fixed_u {
                        None => (t, if a == 0 { 0.0 } else { 1.0 }),
                        Some(u) => (u, t),
                    };
                    let [c, r] = at(fu, fv);
                    look(fu, fv, g.height_at_sample(c, r));
                }
            }
        }
        // The samples inside: found in sample space, placed in the cell by
        // inverting the corners' map (nearly affine over a cell: a few
        // Newton steps).
        let (ilo, ihi) = (p.iter().map(|c| c[0]).fold(f64::INFINITY, f64::min), p.iter().map(|c| c[0]).fold(f64::NEG_INFINITY, f64::max));
        let (jlo, jhi) = (p.iter().map(|c| c[1]).fold(f64::INFINITY, f64::min), p.iter().map(|c| c[1]).fold(f64::NEG_INFINITY, f64::max));
        let (i0, i1, j0, j1) = (ilo.floor() as i64 + 1, ihi.ceil() as i64 - 1, jlo.floor() as i64 + 1, jhi.ceil() as i64 - 1);
        // More samples than pixels: the pixel centres say as much, for less.
        if ((i1 - i0 + 1).max(0) * (j1 - j0 + 1).max(0)) as f64 > q.du * q.dv {
            return None;
        }
        // at(fu, fv) = p0 + fu·du0 + fv·dv0 + fu·fv·twist.
        let du0 = [p[1][0] - p[0][0], p[1][1] - p[0][1]];
        let dv0 = [p[2][0] - p[0][0], p[2][1] - p[0][1]];
        let twist = [p[3][0] - p[2][0] - du0[0], p[3][1] - p[2][1] - du0[1]];
        for j in j0..=j1 {
            for i in i0..=i1 {
                let target = [i as f64, j as f64];
                let (mut fu, mut fv) = (0.5, 0.5);
                for _ in 0..4 {
                    let c = at(fu, fv);
                    // The map's Jacobian, exactly (it is bilinear): what
                    // differences over 1/1000 of the cell gave, without
                    // their two more evaluations.
                    let (a11, a21) = (du0[0] + fv * twist[0], du0[1] + fv * twist[1]);
                    let (a12, a22) = (dv0[0] + fu * twist[0], dv0[1] + fu * twist[1]);
                    let det = a11 * a22 - a12 * a21;
                    if det == 0.0 {
                        break;
                    }
                    let (rx, ry) = (target[0] - c[0], target[1] - c[1]);
                    fu += (a22 * rx - a12 * ry) / det;
                    fv += (a11 * ry - a21 * rx) / det;
                }
                if (0.0..=1.0).contains(&fu) && (0.0..=1.0).contains(&fv) {
                    look(fu, fv, g.post(i, j));
                }
            }
        }
        Some((worst, lo, hi))
    }

    /// The height at output position (u, v), NaN where there is none.
    pub(super) fn height_at(&self, u: f64, v: f64) -> f64 {
        let (x, y) = self.t.ground(u, v);
        match self.t.dem.height(x, y) {
            Height::Value(z) => z,
            _ => f64::NAN,
        }
    }

    /// Whether the DEM's hole or outside policy gives heights of its own.
    pub(super) fn policy_heights(&self) -> bool {
        [self.t.dem.on_hole, self.t.dem.on_outside].iter().any(|m| matches!(m, crate::dem::Miss::Height(_)))
    }

    /// Whether the DEM has a height of its own under output position
    /// (u, v), not one its hole or outside policy gives.
    pub(super) fn own_height(&self, u: f64, v: f64) -> bool {
        let (x, y) = self.t.ground(u, v);
        matches!(self.t.dem.lookup(x, y), Lookup::Height(_))
    }

    /// The terrain's part of `q`'s interpolation error, scan pixels. The
    /// DEM departs from the plane through the heights at the cell's corners
    /// at most where it bends: at its posts inside the cell and where its
    /// post lines cross the edges (or, a DEM not aligned with the output,
    /// on a lattice of half its posting); that departure moves the image by
    /// at most R a metre. And the image moves with height not quite
    /// linearly: over the cell's span of heights 2h, by up to |∂²T/∂Z²|·h²/2
    /// off the line (a wall seen from the side).
    pub(super) fn terrain_error(&self, q: &Quad) -> f64 {
        if matches!(self.t.dem.model, crate::dem::HeightModel::Flat(_)) {
            return 0.0;
        }
        let (global_rate, bend) = self.relief;
        let rate = if q.rate.is_finite() { q.rate } else { global_rate };
        let (u1, v1) = (q.u0 + q.du, q.v0 + q.dv);
        let corners = q.z;
        let plane = |u: f64, v: f64| {
            let (fu, fv) = ((u - q.u0) / q.du, (v - q.v0) / q.dv);
            let top = corners[0] + fu * (corners[1] - corners[0]);
            let bottom = corners[2] + fu * (corners[3] - corners[2]);
            top + fv * (bottom - top)
        };
        let (mut lo, mut hi) = corners.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &z| (a.min(z), b.max(z)));
        let mut off_plane = 0.0f64;
        // The lines a + b·i strictly inside (lo, hi): (a, b, first i, last i).
        let lines = |a: f64, b: f64, lo: f64, hi: f64| {
            let (mut first, mut last) = (((lo - a) / b).floor() as i64 + 1, ((hi - a) / b).ceil() as i64 - 1);
            while first <= last && !(a + b * first as f64 > lo) {
                first += 1;
            }
            while first <= last && !((a + b * last as f64) < hi) {
                last -= 1;
            }
            (a, b, first, last)
        };
        let none = (0.0, 1.0, 0, -1);
        // The bound is at pixel centres: a DEM posted finer than the
        // pixels is looked at there (no more lookups than pixels).
        let centres = |b: f64| if b < 1.0 { (0.5, 1.0) } else { (f64::NAN, b) };
        let (us, vs) = match (self.kinks, self.dem_sampling) {
            (Some([au, bu, av, bv]), _) if bu > 0.0 && bv > 0.0 => {
                let ((cu, bu2), (cv, bv2)) = (centres(bu), centres(bv));
                let (au, av) = (if cu.is_nan() { au } else { cu }, if cv.is_nan() { av } else { cv });
                (lines(au, bu2, q.u0, u1), lines(av, bv2, q.v0, v1))
            }
            (_, Some(s)) => match self.unaligned_departure(q, &plane) {
                Some((d, zl, zh)) => {
                    (off_plane, lo, hi) = (d, lo.min(zl), hi.max(zh));
                    (none, none)
                }
                // Where the corners' places are unknown: a lattice of half
                // the DEM's posting, and at least three lines a side.
                None => {
                    let s = s.min(q.du / 4.0).min(q.dv / 4.0).floor().max(1.0);
                    (lines(0.5, s, q.u0, u1), lines(0.5, s, q.v0, v1))
                }
            },
            _ => (none, none),
        };
        // A height the hole or outside policy gives meets the DEM's own
        // in a step (at the DEM's edge, half a posting past its last
        // posts, or around a hole), which no plane holds: a cell with
        // both, at its corners or where it is looked at, is not proved.
        let policy_heights = self.policy_heights();
        let mut kinds = [false; 2];
        if policy_heights {
            for (u, v) in [(q.u0, q.v0), (u1, q.v0), (q.u0, v1), (u1, v1)] {
                kinds[usize::from(self.own_height(u, v))] = true;
            }
        }
        let mut look = |u: f64, v: f64| {
            let z = self.height_at(u, v);
            let d = (z - plane(u, v)).abs();
            off_plane = if d.is_nan() { f64::INFINITY } else { off_plane.max(d) };
            (lo, hi) = (lo.min(z), hi.max(z));
            if policy_heights {
                kinds[usize::from(self.own_height(u, v))] = true;
            }
        };
        // Inside one piece of the DEM it is bilinear, reproduced exactly:
        // only where its lines cross the cell can it depart from the plane.
        let at = |(a, b, _, _): (f64, f64, i64, i64), i: i64| a + b * i as f64;
        for i in us.2..=us.3 {
            let u = at(us, i);
            look(u, q.v0);
            look(u, v1);
            for j in vs.2..=vs.3 {
                look(u, at(vs, j));
            }
        }
        for j in vs.2..=vs.3 {
            let v = at(vs, j);
            look(q.u0, v);
            look(u1, v);
        }
        if kinds == [true, true] {
            return f64::INFINITY;
        }
        let h = (hi - lo) / 2.0;
        let e = off_plane * rate + 0.5 * bend * h * h;
        if e.is_nan() {
            f64::INFINITY
        } else {
            e
        }
    }

    /// Whether `q` lies inside one column of cells of a DEM aligned with
    /// the output and posted at least a pixel apart (none of its post
    /// lines across the rows inside): there the height along each output
    /// row is linear (the DEM is bilinear in each of its cells).
    pub(super) fn inside_one_dem_column(&self, q: &Quad) -> bool {
        let Some([au, bu, _, _]) = self.kinks else { return false };
        // Node lines are DEM lines: one on an edge is not inside.
        bu >= 1.0 && !(au + bu * (((q.u0 + EDGE - au) / bu).floor() + 1.0) < q.u0 + q.du - EDGE)
    }

    /// Row `v`'s run `[l0, l1)` of a [`quadtree::Node::Rows`] piece as a
    /// quadratic through the exact model at its first, middle and last
    /// pixels (its first position, column and row, and their forward
    /// differences, first and second), where it holds
    /// within half the bound at the pixel a quarter of the way along
    /// (along a row inside one DEM column the interpolation's error is
    /// cubic in the pixel: it peaks near a quarter and three quarters of
    /// the way, alike); `None` where it does not, a point has no value,
    /// or the run is too short to be worth four evaluations.
    pub(super) fn row_quadratic(&self, v: f64, l0: usize, l1: usize) -> Option<[f64; 6]> {
        const SHORTEST: usize = 6;
        let bound = self.spec.max_error?;
        if l1 < l0 + SHORTEST {
            return None;
        }
        // The span's last pixel, its middle (as `quadratic_steps` takes
        // it) and the check a quarter of the way.
        let (l, q) = (l1 - 1 - l0, (l1 - 1 - l0) / 4);
        let [f0, (ec, er), fm, fl] = self.t.exact_all(v, [l0, l0 + q, l0 + l / 2, l0 + l])?;
        let (d, dd) = steps_through(f0, fm, fl, l / 2, l);
        let t = q as f64;
        let step = |f: f64, d: f64, dd: f64| f + t * d + 0.5 * t * (t - 1.0) * dd;
        let off = (ec - step(f0.0, d[0], dd[0])).hypot(er - step(f0.1, d[1], dd[1]));
        (off <= bound / 2.0).then_some([f0.0, f0.1, d[0], d[1], dd[0], dd[1]])
    }

    /// Holds `q` to `bound` at every pixel: splits it where its smooth or
    /// its terrain error may miss it. Returns its node: a leaf where it is
    /// within the bound, else a split (its pieces put into `quads`), rows
    /// (inside one DEM column) or exact.
    pub(super) fn refine(&self, q: &Quad, bound: f64, stats: &mut GcmStats, miss: &mut Option<(f64, f64, Lookup)>, quads: &mut Vec<Node>) -> Node {
        let error = q.smooth + self.terrain_error(q);
        if error <= bound || self.off_the_scan(q, error) {
            return Node::Leaf(q.corners);
        }
        // Splitting costs 5 exact evaluations and the pieces' checks; below
        // about 52 pixels, computing every pixel exactly is cheaper (and exact).
        let small = q.du * q.dv <= 52.0;
        // A split quarters the error at best: a piece far over the bound
        // would be split down to pieces too small to split. Inside one DEM
        // column its rows are smooth, each one quadratic (a few exact
        // evaluations a row, not one a pixel).
        if error.is_finite() && (small || error > 4.0 * bound) && self.inside_one_dem_column(q) {
            return Node::Rows;
        }
        if small {
            return Node::Exact;
        }
        // Split at the DEM's lines where they cross the cell (the pieces are
        // then smooth), else in the middle. New corners: four edge points and
        // the centre.
        let (su, sv) = (self.split_at(q.u0, q.du, 0), self.split_at(q.v0, q.dv, 1));
        let (u1, v1) = (q.u0 + q.du, q.v0 + q.dv);
        let mut at = |u: f64, v: f64| {
            stats.checks += 1;
            self.correction(u, v, miss)
        };
        let (top, left, right, bottom, centre) = (at(su, q.v0), at(q.u0, sv), at(u1, sv), at(su, v1), at(su, sv));
        let [c00, c10, c01, c11] = q.corners;
        let [z00, z10, z01, z11] = q.z;
        let [p00, p10, p01, p11] = q.dp;
        let (pt, pl, pr, pb, pc) = if self.dem_sampling.is_some() {
            (self.dem_coords(su, q.v0), self.dem_coords(q.u0, sv), self.dem_coords(u1, sv), self.dem_coords(su, v1), self.dem_coords(su, sv))
        } else {
            ([f64::NAN; 2], [f64::NAN; 2], [f64::NAN; 2], [f64::NAN; 2], [f64::NAN; 2])
        };
        let (zt, zl, zr, zb, zc) = (self.height_at(su, q.v0), self.height_at(q.u0, sv), self.height_at(u1, sv), self.height_at(su, v1), self.height_at(su, sv));
        // A piece's smooth error shrinks with the square of its size.
        let mk = |u0: f64, v0: f64, du: f64, dv: f64, corners: [[f64; 2]; 4], z: [f64; 4], dp: [[f64; 2]; 4]| {
            let shrink = (du / q.du).max(dv / q.dv);
            Quad { u0, v0, du, dv, corners, smooth: q.smooth * shrink * shrink, z, rate: q.rate, dp }
        };
        let kids = [
            mk(q.u0, q.v0, su - q.u0, sv - q.v0, [c00, top, left, centre], [z00, zt, zl, zc], [p00, pt, pl, pc]),
            mk(su, q.v0, u1 - su, sv - q.v0, [top, c10, centre, right], [zt, z10, zc, zr], [pt, p10, pc, pr]),
            mk(q.u0, sv, su - q.u0, v1 - sv, [left, centre, c01, bottom], [zl, zc, z01, zb], [pl, pc, p01, pb]),
            mk(su, sv, u1 - su, v1 - sv, [centre, right, bottom, c11], [zc, zr, zb, z11], [pc, pr, pb, p11]),
        ];
        // The four children side by side, theirs after them.
        let first = quads.len();
        quads.extend(std::iter::repeat_n(Node::Exact, 4));
        for (k, kid) in kids.iter().enumerate() {
            if !kid.corners.iter().flatten().any(|v| v.is_nan()) {
                quads[first + k] = self.refine(kid, bound, stats, miss, quads);
            }
        }
        Node::Split { at: (su, sv), first: first as u32 }
    }
}
