//! The refined cells of a band, as nodes in one vector: a refined cell is
//! an index into it, a split names its four children by the index of the
//! first. Only what the rows read is kept (where children meet, a leaf's
//! corner corrections; a leaf's box follows from the cell's and the splits
//! above it); what the refinement weighs (heights, rates, curvatures)
//! stays on its stack. Boxed trees cost an allocation a split and 960
//! bytes where these take 288: on an oblique drone frame over buildings at
//! a small `--memory`, the trees were over half the heap.

/// A node of a refined cell.
#[derive(Clone, Debug)]
pub(super) enum Node {
    /// Four children from `first` on (top left, top right, bottom left,
    /// bottom right), meeting at `at` (u, v).
    Split { at: (f64, f64), first: u32 },
    /// Corrections (dc, dr) at the corners of its box (top left, top
    /// right, bottom left, bottom right), interpolated between them.
    Leaf([[f64; 2]; 4]),
    /// Over the bound and too small to split: the exact model at each pixel.
    Exact,
    /// Over the bound inside one column of cells of a DEM aligned with the
    /// output: there the height is linear along each output row, so `T`
    /// along a row is smooth, and each row's run is the quadratic through the
    /// exact model at its ends and middle where a check between them
    /// holds it (else the exact model at each pixel).
    Rows,
}

/// What a row meets of a refined cell: a leaf's run of pixels, or one
/// over the bound ([`Node::Rows`], [`Node::Exact`]).
#[derive(Clone, Copy, Debug)]
pub(super) enum Piece<'n> {
    Leaf(Leaf<'n>),
    Rows,
    Exact,
}

/// A node's box: its top left corner and size, output pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Frame {
    pub u0: f64,
    pub v0: f64,
    pub du: f64,
    pub dv: f64,
}

impl Frame {
    /// The box of child `k` (in [`Node::Split`]'s order) of a split at `at`.
    #[inline]
    pub fn child(self, at: (f64, f64), k: u32) -> Frame {
        let (su, sv) = at;
        let (u1, v1) = (self.u0 + self.du, self.v0 + self.dv);
        let (u0, du) = if k.is_multiple_of(2) { (self.u0, su - self.u0) } else { (su, u1 - su) };
        let (v0, dv) = if k < 2 { (self.v0, sv - self.v0) } else { (sv, v1 - sv) };
        Frame { u0, v0, du, dv }
    }
}

/// A leaf along one row: its corner corrections and box.
#[derive(Clone, Copy, Debug)]
pub(super) struct Leaf<'n> {
    pub corners: &'n [[f64; 2]; 4],
    pub frame: Frame,
}

impl Leaf<'_> {
    /// The corrections at column `u` of row `fv` ([`Leaf::fv`]).
    #[inline]
    pub fn at(&self, u: f64, fv: f64) -> [f64; 2] {
        bilerp(self.corners, (u - self.frame.u0) / self.frame.du, fv)
    }

    /// Where row `v` runs through the box, from its top (0) to its bottom (1).
    #[inline]
    pub fn fv(&self, v: f64) -> f64 {
        (v - self.frame.v0) / self.frame.dv
    }
}

#[inline]
fn bilerp(c: &[[f64; 2]; 4], fu: f64, fv: f64) -> [f64; 2] {
    let w = [(1.0 - fu) * (1.0 - fv), fu * (1.0 - fv), (1.0 - fu) * fv, fu * fv];
    [c[0][0] * w[0] + c[1][0] * w[1] + c[2][0] * w[2] + c[3][0] * w[3], c[0][1] * w[0] + c[1][1] * w[1] + c[2][1] * w[2] + c[3][1] * w[3]]
}

/// The first pixel (of those from `x0` on, at most `len`) whose centre is
/// at or past a split at `u`: it and those after it take the right child.
#[inline]
fn right_of(u: f64, x0: usize, len: usize) -> usize {
    ((u - 0.5).ceil() - x0 as f64).clamp(0.0, len as f64) as usize
}

/// The corrections of the cell rooted at `root` (its box `frame`) along
/// row `v` at pixels `x0, x0 + 1, …` (their centres half a pixel on), as
/// many as `dc` holds: each leaf's run of pixels interpolated between its
/// corners, NaN on an exact one (one descent a run of pixels, not one a
/// pixel).
pub(super) fn row(nodes: &[Node], root: u32, frame: Frame, v: f64, x0: usize, dc: &mut [f64], dr: &mut [f64]) {
    match &nodes[root as usize] {
        Node::Exact | Node::Rows => {
            dc.fill(f64::NAN);
            dr.fill(f64::NAN);
        }
        Node::Leaf(corners) => {
            let leaf = Leaf { corners, frame };
            let fv = leaf.fv(v);
            for (m, (dc, dr)) in dc.iter_mut().zip(dr.iter_mut()).enumerate() {
                [*dc, *dr] = leaf.at((x0 + m) as f64 + 0.5, fv);
            }
        }
        &Node::Split { at, first } => {
            let k = 2 * u32::from(v >= at.1);
            let right = right_of(at.0, x0, dc.len());
            let ((lc, rc), (lr, rr)) = (dc.split_at_mut(right), dr.split_at_mut(right));
            row(nodes, first + k, frame.child(at, k), v, x0, lc, lr);
            row(nodes, first + k + 1, frame.child(at, k + 1), v, x0 + right, rc, rr);
        }
    }
}

/// The leaves of the cell rooted at `root` (its box `frame`) along row `v`
/// over pixels `[x0, x1)`, in order: each leaf's run of the pixels whose
/// centres it holds (split as [`row`] splits them).
pub(super) fn runs<'n>(nodes: &'n [Node], root: u32, frame: Frame, v: f64, x0: usize, x1: usize, out: &mut Vec<(usize, usize, Piece<'n>)>) {
    if x0 >= x1 {
        return;
    }
    match &nodes[root as usize] {
        &Node::Split { at, first } => {
            let k = 2 * u32::from(v >= at.1);
            let right = x0 + right_of(at.0, x0, x1 - x0);
            runs(nodes, first + k, frame.child(at, k), v, x0, right, out);
            runs(nodes, first + k + 1, frame.child(at, k + 1), v, right, x1, out);
        }
        Node::Leaf(corners) => out.push((x0, x1, Piece::Leaf(Leaf { corners, frame }))),
        Node::Rows => out.push((x0, x1, Piece::Rows)),
        Node::Exact => out.push((x0, x1, Piece::Exact)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cell 0 ≤ u ≤ 20, 0 ≤ v ≤ 10.
    const CELL: Frame = Frame { u0: 0.0, v0: 0.0, du: 20.0, dv: 10.0 };

    /// The cell split at u = 10.2, v = 5: its top left an exact leaf, the
    /// others leaves whose corrections are u + 100·(child) at each corner.
    fn cell() -> Vec<Node> {
        let leaf = |u0: f64, du: f64, k: f64| {
            let c = |u: f64| [u + 100.0 * k, -(u + 100.0 * k)];
            Node::Leaf([c(u0), c(u0 + du), c(u0), c(u0 + du)])
        };
        vec![Node::Exact, leaf(10.2, 9.8, 1.0), leaf(0.0, 10.2, 2.0), leaf(10.2, 9.8, 3.0), Node::Split { at: (10.2, 5.0), first: 0 }]
    }

    #[test]
    fn children_tile_their_parent() {
        let at = (10.2, 5.0);
        assert_eq!(CELL.child(at, 0), Frame { u0: 0.0, v0: 0.0, du: 10.2, dv: 5.0 });
        assert_eq!(CELL.child(at, 1), Frame { u0: 10.2, v0: 0.0, du: 20.0 - 10.2, dv: 5.0 });
        assert_eq!(CELL.child(at, 2), Frame { u0: 0.0, v0: 5.0, du: 10.2, dv: 5.0 });
        assert_eq!(CELL.child(at, 3), Frame { u0: 10.2, v0: 5.0, du: 20.0 - 10.2, dv: 5.0 });
    }

    #[test]
    fn a_row_takes_each_pixel_from_the_leaf_that_holds_its_centre() {
        let nodes = cell();
        // Row 2.5 (top children): pixels 8, 9 (centres 8.5, 9.5) exact;
        // 10 (centre 10.5) on, the top right leaf, linear in u.
        let (mut dc, mut dr) = (vec![0.0; 5], vec![0.0; 5]);
        row(&nodes, 4, CELL, 2.5, 8, &mut dc, &mut dr);
        assert!(dc[0].is_nan() && dc[1].is_nan() && dr[1].is_nan());
        for m in 2..5 {
            let u = (8 + m) as f64 + 0.5;
            assert!((dc[m] - (u + 100.0)).abs() < 1e-9 && (dr[m] + u + 100.0).abs() < 1e-9, "{m}: {}", dc[m]);
        }
        let mut out = Vec::new();
        runs(&nodes, 4, CELL, 2.5, 8, 13, &mut out);
        assert_eq!(out.iter().map(|r| (r.0, r.1, matches!(r.2, Piece::Leaf(_)))).collect::<Vec<_>>(), vec![(8, 10, false), (10, 13, true)]);
        // Row 7.5 (bottom children), the same columns.
        row(&nodes, 4, CELL, 7.5, 8, &mut dc, &mut dr);
        for (m, d) in dc.iter().enumerate() {
            let u = (8 + m) as f64 + 0.5;
            assert!((d - (u + if m < 2 { 200.0 } else { 300.0 })).abs() < 1e-9, "{m}: {d}");
        }
        out.clear();
        runs(&nodes, 4, CELL, 7.5, 8, 13, &mut out);
        assert_eq!(out.iter().map(|r| (r.0, r.1)).collect::<Vec<_>>(), vec![(8, 10), (10, 13)]);
    }
}
