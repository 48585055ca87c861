//! A band's rows as spans of scan positions: `A + c` between node columns,
//! the exact model where a cell asks for it, cut at every tile edge.

use super::quadtree::{self, Piece};
use super::{line_left_of, quadratic_steps, BandGcm, CorrectionMode, Gcm, A_LINEAR_TOLERANCE, MAX_SPANS_A_GAP};
use crate::dem::Lookup;
use crate::geom::Span;


impl<'a> Gcm<'a> {
    /// The node columns (indices from the first node, inclusive) that output
    /// columns `[x0, x0 + len)` interpolate between.
    pub(super) fn node_span(&self, x0: u32, len: usize) -> (usize, usize) {
        let k = self.spec.k as usize;
        let x1 = x0 as usize + len.max(1) - 1;
        match self.spec.mode {
            CorrectionMode::Cell => (x0 as usize / k, x1 / k),
            CorrectionMode::Bilinear => {
                let seg = |x: usize| (self.segment(x) - self.first_node) as usize;
                (seg(x0 as usize), seg(x1) + 1)
            }
        }
    }

    /// Output row `y`'s columns `x0..x0+len` as [`Span`]s, one per gap
    /// between node columns (in a refined cell, one per leaf the row
    /// crosses; a leaf marked exact not stepped), into `spans`; `false` (and `spans` empty)
    /// where the row cannot have stepped spans: cell mode, A behind the
    /// camera anywhere along the row, or A, whose denominator is linear in
    /// u, curving so much that a gap would need more than
    /// [`MAX_SPANS_A_GAP`] quadratic pieces to stay within
    /// [`A_LINEAR_TOLERANCE`] of it. Where A's deviation from a chord
    /// across the widest gap (|A''|·L²/8) is within the tolerance, each gap
    /// is one straight span; elsewhere every gap is cut into as many equal
    /// quadratic pieces as bring the widest within it (the interpolating
    /// quadratic's error, at most |A'''|·L³/48), each through `A + c` at
    /// its first, middle and last pixels. The tests look at the whole row
    /// or the gap alone, and each piece is anchored at its gap's (or
    /// piece's) first pixel, so a pixel's position does not depend on which
    /// piece of the row is asked for.
    pub fn row_spans(&self, band: &BandGcm, y: u32, x0: u32, len: usize, spans: &mut Vec<Span>) -> bool {
        spans.clear();
        if self.spec.mode != CorrectionMode::Bilinear || len == 0 {
            return false;
        }
        let (j0, j1, fy) = self.rows_for(y);
        let ra = self.a.row(y as f64 + 0.5);
        let (da, db) = (ra.e * self.xs[0] + ra.f, ra.e * self.xs[self.nodes_x - 1] + ra.f);
        let d = da.min(db);
        if !(d > 0.0) {
            return false;
        }
        // The largest |A''| of either coordinate, at the smallest
        // denominator, and |A'''| = 3·|e|/d·|A''| there.
        let bend = 2.0 * ra.e.abs() * (ra.m * ra.f - ra.e * ra.n).abs().max((ra.p * ra.f - ra.e * ra.q).abs()) / (d * d * d);
        let twist = 3.0 * ra.e.abs() / d * bend;
        let straight = bend * self.max_gap * self.max_gap / 8.0 <= A_LINEAR_TOLERANCE;
        let cuts = if straight { 1.0 } else { (self.max_gap * (twist / (48.0 * A_LINEAR_TOLERANCE)).cbrt()).ceil().max(1.0) };
        if !(cuts <= MAX_SPANS_A_GAP as f64) {
            return false;
        }
        let cuts = cuts as usize;
        let (a, b) = (&band.rows[(j0 - band.first_j) as usize], &band.rows[(j1 - band.first_j) as usize]);
        let (lo, hi) = self.node_span(x0, len);
        // Node columns lo..=hi and the gaps lo..hi between them, cut out
        // once (no bounds checks per gap below).
        let nodes = lo..hi + 1;
        let (xs, first_px) = (&self.xs[nodes.clone()], &self.first_px[nodes.clone()]);
        let (adc, adr, bdc, bdr) = (&a.dc[nodes.clone()], &a.dr[nodes.clone()], &b.dc[nodes.clone()], &b.dr[nodes]);
        let (inv_dx, anchor_off) = (&self.inv_dx[lo..hi], &self.anchor_off[lo..hi]);
        // Refined cells (only with --max-error, and only rows with one).
        let refined = band.cells.get((j0 - band.first_j) as usize).filter(|c| !c.is_empty()).map(|c| &c[lo..hi]);
        let x_end = x0 as usize + len;
        let last_gap = self.nodes_x - 2;
        let mut x = x0 as usize;
        // Node columns a block at a time: first the position at each (A
        // there plus the correction; the divisions of a block independent
        // of each other, two at a time), then the block's gaps.
        const BLOCK: usize = 32;
        let (mut pc, mut pr) = ([0.0f64; BLOCK + 1], [0.0f64; BLOCK + 1]);
        // A alone at the nodes, and A + c at the gaps' middles (quadratic spans only).
        let (mut acs, mut ars) = ([0.0f64; BLOCK + 1], [0.0f64; BLOCK + 1]);
        let (mut mc, mut mr) = ([0.0f64; BLOCK], [0.0f64; BLOCK]);
        let n_gaps = xs.len() - 1;
        // A refined cell's leaves along the row (reused from cell to cell).
        let mut leaf_runs = Vec::new();
        let mut g0 = 0;
        while g0 < n_gaps {
            // Nodes g0..=g0+m (the first one is the last of the block before).
            let m = (n_gaps - g0).min(BLOCK);
            let nodes = g0..g0 + m + 1;
            let (xs, adc, adr, bdc, bdr) = (&xs[nodes.clone()], &adc[nodes.clone()], &adr[nodes.clone()], &bdc[nodes.clone()], &bdr[nodes]);
            for (((&u, (&adc, &adr)), (&bdc, &bdr)), (oc, or)) in
                xs.iter().zip(adc.iter().zip(adr)).zip(bdc.iter().zip(bdr)).zip(pc.iter_mut().zip(pr.iter_mut()))
            {
                let (ac, ar) = ra.at(u);
                (*oc, *or) = (ac + adc + fy * (bdc - adc), ar + adr + fy * (bdr - adr));
            }
            if !straight && cuts == 1 {
                // A alone at the nodes (again: the loop above stays as the
                // straight rows, nearly all, want it).
                for ((&u, a_c), a_r) in xs.iter().zip(acs.iter_mut()).zip(ars.iter_mut()) {
                    (*a_c, *a_r) = ra.at(u);
                }
                // At each gap's middle: A there, and the mean of its nodes' corrections.
                for (k, (oc, or)) in mc.iter_mut().zip(mr.iter_mut()).enumerate().take(m) {
                    let (ac, ar) = ra.at(0.5 * (xs[k] + xs[k + 1]));
                    *oc = ac + 0.5 * ((pc[k] - acs[k]) + (pc[k + 1] - acs[k + 1]));
                    *or = ar + 0.5 * ((pr[k] - ars[k]) + (pr[k + 1] - ars[k + 1]));
                }
            }
            for k in 0..m {
                let g = g0 + k;
                let (left, right) = ((pc[k], pr[k]), (pc[k + 1], pr[k + 1]));
                // (max, min rather than clamp: no check that x ≤ x_end, which holds.)
                let end = if lo + g >= last_gap { x_end } else { first_px[g + 1].max(x).min(x_end) };
                // Within what the fixed point's conversion holds exactly
                // (positions ·2³² below 2⁵¹: a scan of 2¹⁸ pixels a side).
                const FIXED: f64 = (1u64 << 18) as f64;
                let leaves = refined.and_then(|q| q[g]);
                let fits = |c: f64, r: f64, d: [f64; 4]| c.abs() < FIXED && r.abs() < FIXED && d.iter().all(|d| d.abs() * 1024.0 < FIXED);
                let stepped = |c: f64, r: f64, d: [f64; 4]| leaves.is_none() && fits(c, r, d);
                if let (Some(q), true) = (leaves, end > x) {
                    // A refined cell: a span for each leaf's run of
                    // pixels along the row (A and the leaf's correction,
                    // linear along it, as one quadratic: a piece of a gap
                    // A fits within the tolerance across), anchored at the
                    // run's first pixel in the whole gap; a leaf marked
                    // exact, pixel by pixel.
                    let v = y as f64 + 0.5;
                    let (gap_first, gap_end) = (first_px[g], first_px[g + 1].max(end));
                    leaf_runs.clear();
                    quadtree::runs(&band.quads, q, self.cell_frame(j0, j1, lo + g), v, gap_first, gap_end, &mut leaf_runs);
                    for &(l0, l1, piece) in &leaf_runs {
                        let (first, stop) = (l0.max(x), l1.min(end));
                        if first >= stop {
                            continue;
                        }
                        let exact = Span { stepped: false, first, end: stop, anchor: l0, c: 0.0, r: 0.0, dc: 0.0, dr: 0.0, ddc: 0.0, ddr: 0.0 };
                        let leaf = match piece {
                            // Where A curves too much along the row for one
                            // quadratic a leaf, A + c at each pixel.
                            Piece::Leaf(_) if cuts > 1 => {
                                spans.push(exact);
                                continue;
                            }
                            Piece::Leaf(leaf) => leaf,
                            Piece::Rows => {
                                // Anchored at the run's first pixel, whatever piece of the row is asked for.
                                spans.push(match self.row_quadratic(v, l0, l1) {
                                    Some([c, r, dc, dr, ddc, ddr]) => Span { stepped: fits(c, r, [dc, dr, ddc, ddr]), c, r, dc, dr, ddc, ddr, ..exact },
                                    None => exact,
                                });
                                continue;
                            }
                            Piece::Exact => {
                                spans.push(exact);
                                continue;
                            }
                        };
                        let fv = leaf.fv(v);
                        let at = |px: usize| {
                            let u = px as f64 + 0.5;
                            let (ac, ar) = ra.at(u);
                            let [dc, dr] = leaf.at(u, fv);
                            (ac + dc, ar + dr)
                        };
                        let (c, r) = at(l0);
                        let ([dc, dr], [ddc, ddr]) = quadratic_steps((c, r), l0, l1, at);
                        spans.push(Span { stepped: fits(c, r, [dc, dr, ddc, ddr]), first, end: stop, anchor: l0, c, r, dc, dr, ddc, ddr });
                    }
                } else if end > x && straight {
                    let inv = inv_dx[g];
                    let (dc, dr) = ((right.0 - left.0) * inv, (right.1 - left.1) * inv);
                    let off = anchor_off[g];
                    let (c, r) = (left.0 + off * dc, left.1 + off * dr);
                    spans.push(Span { stepped: stepped(c, r, [dc, dr, 0.0, 0.0]), first: x, end, anchor: first_px[g], c, r, dc, dr, ddc: 0.0, ddr: 0.0 });
                } else if end > x && cuts == 1 {
                    // The quadratic through A + c at the gap's nodes and
                    // middle, s = u − u_left: f = fl + b·s + q·s²; stepped
                    // from the gap's first pixel (s = off).
                    let (half, off) = (0.5 / inv_dx[g], anchor_off[g]);
                    let steps = |fl: f64, fm: f64, fr: f64| {
                        let q = (fl - 2.0 * fm + fr) / (2.0 * half * half);
                        let b = (fm - fl) / half - q * half;
                        (fl + off * (b + q * off), b + q * (2.0 * off + 1.0), 2.0 * q)
                    };
                    let ((c, dc, ddc), (r, dr, ddr)) = (steps(left.0, mc[k], right.0), steps(left.1, mr[k], right.1));
                    spans.push(Span { stepped: stepped(c, r, [dc, dr, ddc, ddr]), first: x, end, anchor: first_px[g], c, r, dc, dr, ddc, ddr });
                } else if end > x {
                    // The gap's pixels (all of them, wherever the asked
                    // piece of the row begins and ends) in `cuts` pieces.
                    let (gap_first, gap_end) = (first_px[g], first_px[g + 1].max(end));
                    let n = gap_end - gap_first;
                    let (u0, inv) = (xs[k], inv_dx[g]);
                    // The correction at either node (linear in between).
                    let correction = |(c, r): (f64, f64), u: f64| {
                        let (ac, ar) = ra.at(u);
                        (c - ac, r - ar)
                    };
                    let (cl, cr) = (correction(left, u0), correction(right, xs[k + 1]));
                    let at = |px: usize| {
                        let u = px as f64 + 0.5;
                        let (ac, ar) = ra.at(u);
                        let t = (u - u0) * inv;
                        (ac + cl.0 + t * (cr.0 - cl.0), ar + cl.1 + t * (cr.1 - cl.1))
                    };
                    for i in 0..cuts {
                        let (p0, p1) = (gap_first + n * i / cuts, gap_first + n * (i + 1) / cuts);
                        let (first, stop) = (p0.max(x), p1.min(end));
                        if first >= stop {
                            continue;
                        }
                        let (c, r) = at(p0);
                        let ([dc, dr], [ddc, ddr]) = quadratic_steps((c, r), p0, p1, at);
                        spans.push(Span { stepped: stepped(c, r, [dc, dr, ddc, ddr]), first, end: stop, anchor: p0, c, r, dc, dr, ddc, ddr });
                    }
                }
                x = end;
            }
            g0 += m;
        }
        true
    }

    /// Fills output row `y` (columns `x0..x0+cols.len()`) with scan
    /// coordinates `A + c`, NaN where there is no value. Returns the number
    /// of pixels that fell back to `T`. Where the row is straight lines
    /// between node columns ([`Gcm::row_spans`]), two multiply-adds a
    /// pixel; elsewhere one reciprocal (for `A`) and a few multiply-adds.
    pub fn fill_row(&self, band: &BandGcm, y: u32, x0: u32, cols: &mut [f64], rows: &mut [f64], miss: &mut Option<(f64, f64, Lookup)>) -> u64 {
        let mut spans = Vec::new();
        if !self.row_spans(band, y, x0, cols.len(), &mut spans) {
            return self.fill_exact(band, y, x0, cols, rows, miss);
        }
        let mut fallback = 0;
        for s in &spans {
            let (a, b) = (s.first - x0 as usize, s.end - x0 as usize);
            if s.stepped {
                s.fill(&self.ramp, &mut cols[a..b], &mut rows[a..b]);
            } else {
                fallback += self.fill_exact(band, y, s.first as u32, &mut cols[a..b], &mut rows[a..b], miss);
            }
        }
        fallback
    }

    /// [`Gcm::fill_row`] without stepped spans: A itself at every pixel.
    pub fn fill_exact(&self, band: &BandGcm, y: u32, x0: u32, cols: &mut [f64], rows: &mut [f64], miss: &mut Option<(f64, f64, Lookup)>) -> u64 {
        self.fill_exact_at(band, y, y as f64 + 0.5, x0, cols, rows, miss)
    }

    /// [`Gcm::fill_exact`] at `v` within output row `y` (its top edge `y`,
    /// its bottom edge `y + 1`: an area kernel's footprints), from the node
    /// rows row `y` takes (carried on straight past them).
    #[allow(clippy::too_many_arguments)] // fill_exact's, and where in the row
    pub fn fill_exact_at(&self, band: &BandGcm, y: u32, v: f64, x0: u32, cols: &mut [f64], rows: &mut [f64], miss: &mut Option<(f64, f64, Lookup)>) -> u64 {
        let (j0, j1, fy) = self.rows_for(y);
        let a = &band.rows[(j0 - band.first_j) as usize];
        let b = &band.rows[(j1 - band.first_j) as usize];
        let fy = match self.spec.mode {
            CorrectionMode::Bilinear if v != y as f64 + 0.5 => {
                let (ya, yb) = (self.ys[(j0 - self.first_node) as usize], self.ys[(j1 - self.first_node) as usize]);
                (v - ya) / (yb - ya)
            }
            _ => fy,
        };
        let ra = self.a.row(v);
        let cells = band.cells.get((j0 - band.first_j) as usize).filter(|c| !c.is_empty());
        // The correction along this row at the node columns this segment
        // uses (indices relative to `lo`).
        let n = self.nodes_x;
        let (lo, hi_node) = self.node_span(x0, cols.len());
        let mut cc = Vec::with_capacity(hi_node - lo + 1);
        let mut cr = Vec::with_capacity(hi_node - lo + 1);
        for i in lo..=hi_node {
            cc.push(a.dc[i] + fy * (b.dc[i] - a.dc[i]));
            cr.push(a.dr[i] + fy * (b.dr[i] - a.dr[i]));
        }
        let k = self.spec.k as usize;
        let len = cols.len();
        let x_end = x0 as usize + len;
        // Pass 1, segment by segment (a cell, or the stretch between two
        // nodes): A plus the linearly varying correction. No branches inside,
        // so the compiler can vectorise it.
        let mut p = 0usize;
        // The gap between node columns that holds the current pixel.
        let mut gap = (self.segment(x0 as usize) - self.first_node) as usize;
        while p < len {
            let x = x0 as usize + p;
            let (i, seg_end, base) = match self.spec.mode {
                CorrectionMode::Cell => (x / k, ((x / k + 1) * k).min(x_end), 0.0),
                CorrectionMode::Bilinear => {
                    // Gaps only move right (skipping any no pixel centre falls in).
                    while gap + 2 < n && self.xs[gap + 1] <= x as f64 + 0.5 {
                        gap += 1;
                    }
                    let il = gap;
                    // First pixel of the next gap: its centre at or past the line.
                    let next = if il + 2 >= n { x_end } else { self.first_px[il + 1].clamp(x + 1, x_end) };
                    (il, next, self.xs[il])
                }
            };
            let il = i - lo;
            let refined = cells.and_then(|c| c.get(i)).is_some_and(|q| q.is_some());
            let (oc, or) = (&mut cols[p..seg_end - x0 as usize], &mut rows[p..seg_end - x0 as usize]);
            if refined {
                let q = cells.and_then(|c| c[i]).expect("refined cell");
                // The corrections leaf by leaf along the row, then A.
                quadtree::row(&band.quads, q, self.cell_frame(j0, j1, i), v, x, oc, or);
                for (m, (oc, or)) in oc.iter_mut().zip(or.iter_mut()).enumerate() {
                    let (ac, ar) = ra.at((x + m) as f64 + 0.5);
                    *oc += ac;
                    *or += ar;
                }
            } else {
                let (c0, r0) = (cc[il], cr[il]);
                let (sc, sr) = match self.spec.mode {
                    CorrectionMode::Cell => (0.0, 0.0),
                    CorrectionMode::Bilinear => (cc[il + 1] - c0, cr[il + 1] - r0),
                };
                let inv_w = match self.spec.mode {
                    CorrectionMode::Cell => 0.0,
                    CorrectionMode::Bilinear => self.inv_dx[i],
                };
                for (m, (oc, or)) in oc.iter_mut().zip(or.iter_mut()).enumerate() {
                    let u = (x + m) as f64 + 0.5;
                    let inv = 1.0 / (ra.e * u + ra.f);
                    let fx = (u - base) * inv_w;
                    *oc = (ra.m * u + ra.n) * inv + c0 + fx * sc;
                    *or = (ra.p * u + ra.q) * inv + r0 + fx * sr;
                }
            }
            p = seg_end - x0 as usize;
        }
        // Pass 2: where a node had no value, or the plane of A is behind the
        // camera (its denominator is linear in u: check the ends first),
        // fall back to T itself.
        let den = |x: usize| ra.e * (x as f64 + 0.5) + ra.f;
        let den_ok = den(x0 as usize) > 0.0 && den(x_end.saturating_sub(1)) > 0.0;
        let exact: Vec<usize> = (0..len).filter(|&m| cols[m].is_nan() || rows[m].is_nan() || (!den_ok && !(den(x0 as usize + m) > 0.0))).collect();
        self.t.exact_at(v, x0 as f64 + 0.5, &exact, cols, rows, miss);
        exact.len() as u64
    }

    /// The bilinear segment (absolute index of its left node) of column `x`.
    #[inline]
    pub(super) fn segment(&self, x: usize) -> i64 {
        line_left_of(&self.xs, x as f64 + 0.5) as i64 + self.first_node
    }
}
