//! Gross errors found and dropped before gridding, as the textbook and
//! Nekrasov's thesis (§3.3) ask: a point is a blunder when its height lies
//! outside its Delaunay neighbours' by more than `k` of their robust
//! sigmas (half the range of their heights, the highest and lowest left
//! out where there are five or more, so that one other blunder beside it
//! does not hide it; a corner of a roof seen by one point of the roof
//! among five or more neighbours is dropped with them). A point inside its ring on a plane or a slope lies
//! within their heights, and a roof's edge, whose neighbours are partly
//! on the roof, is never one; only a point with its ring all round it
//! (not on the hull, not beside a gap) is judged.

use super::neighbourhood::{delaunay_cell, joined_faces, Post, Settle, Tin};
use spade::Triangulation;

/// The places `(x, y)` of the blunders among the points of `tin` that
/// `judged` takes.
pub fn find(tin: &Tin, settle: &mut Settle, judged: &dyn Fn(&Post) -> bool, max_edge: f64, k: f64) -> Vec<(f64, f64)> {
    let l2 = max_edge * max_edge;
    let mut found = Vec::new();
    let mut ring: Vec<(f64, f64, f64)> = Vec::new();
    let mut cell = Vec::with_capacity(8);
    // Each face is met from each of its corners: what is known of it is
    // found once (whether it shares its circle with a neighbour; whether
    // it was checked settled).
    let joined = joined_faces(tin);
    let mut checked = vec![false; joined.len()];
    for v in tin.vertices() {
        let p: Post = *v.data();
        if !judged(&p) {
            continue;
        }
        // A point beside a gap (a side over the longest gridded) is not
        // judged: its neighbours there are not the surface's.
        ring.clear();
        let (mut inside, mut on_hull) = (true, false);
        for e in v.out_edges() {
            match e.face().as_inner() {
                Some(f) => {
                    let i = f.fix().index();
                    if !checked[i] {
                        let [a, b, c] = f.vertices().map(|v| v.position());
                        settle.check(a, b, c);
                        checked[i] = true;
                    }
                    // The corners of its Delaunay cell: on a lattice, the
                    // same neighbours whichever diagonals were drawn.
                    if joined[i] {
                        delaunay_cell(tin, f.fix(), &mut cell);
                    } else {
                        cell.clear();
                        cell.extend(f.vertices().map(|v| *v.data()));
                    }
                    for q in cell.iter().copied() {
                        let r = (q.x - p.x, q.y - p.y, q.z);
                        if (r.0, r.1) != (0.0, 0.0) && !ring.contains(&r) {
                            inside &= r.0 * r.0 + r.1 * r.1 <= l2;
                            ring.push(r);
                        }
                    }
                }
                // On the hull: judged only by a plane through its neighbours
                // (beyond their heights, it may be on a slope).
                None => on_hull = true,
            }
        }
        // In one order, whatever order the triangulation went round in.
        ring.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        if !inside || ring.len() < if on_hull { 6 } else { 3 } {
            continue;
        }
        if is_blunder(p.z, &mut ring, k) {
            found.push((p.x, p.y));
        }
    }
    found
}

/// Whether a height `z` at the origin is a blunder among its `ring` of
/// neighbours (x, y relative to it; height): beyond their heights (the
/// highest and lowest left out where there are six or more), and off
/// the plane they fit (the one fitting worst left out) by more than `k`
/// times their scatter about it; with fewer than six, by more than `k`
/// times half their range.
pub fn is_blunder(z: f64, ring: &mut [(f64, f64, f64)], k: f64) -> bool {
    let n = ring.len();
    let mut heights: Vec<f64> = ring.iter().map(|r| r.2).collect();
    heights.sort_unstable_by(f64::total_cmp);
    let (lo, hi) = if n >= 6 { (heights[1], heights[n - 2]) } else { (heights[0], heights[n - 1]) };
    let floor = 1e-9 * (1.0 + z.abs());
    if z <= hi + floor && z >= lo - floor {
        return false;
    }
    // Too few to fit a plane and see their scatter about it: half their
    // range is their sigma (a point on a slope lies within it).
    if n < 6 {
        return (z - hi).max(lo - z) > k * 0.5 * (hi - lo) + floor;
    }
    let Some(mut plane) = fit(ring) else { return false };
    {
        let worst = (0..n).max_by(|&a, &b| off(&plane, &ring[a]).total_cmp(&off(&plane, &ring[b]))).expect("six");
        ring.swap(worst, n - 1);
        match fit(&ring[..n - 1]) {
            Some(p) => plane = p,
            None => return false,
        }
    }
    let kept = &ring[..n - 1];
    // Over the degrees of freedom the plane leaves.
    let scatter = (kept.iter().map(|r| off(&plane, r).powi(2)).sum::<f64>() / (kept.len() - 3) as f64).sqrt();
    (z - plane[0]).abs() > k * scatter + floor
}

/// Height off the plane `[c, a, b]` (z = c + a x + b y).
fn off(plane: &[f64; 3], r: &(f64, f64, f64)) -> f64 {
    (r.2 - plane[0] - plane[1] * r.0 - plane[2] * r.1).abs()
}

/// The least-squares plane through the points (`None`: on one line).
fn fit(pts: &[(f64, f64, f64)]) -> Option<[f64; 3]> {
    let m = nalgebra::Matrix3::from_fn(|i, j| pts.iter().map(|p| [1.0, p.0, p.1][i] * [1.0, p.0, p.1][j]).sum::<f64>());
    let v = nalgebra::Vector3::from_fn(|i, _| pts.iter().map(|p| [1.0, p.0, p.1][i] * p.2).sum::<f64>());
    let s = m.lu().solve(&v)?;
    s.iter().all(|c| c.is_finite()).then(|| [s[0], s[1], s[2]])
}
