//! Semi-global matching (Hirschmüller 2008) of census costs: each pixel's
//! cost at each disparity summed with the smoothest way to it along eight
//! paths, a small penalty for a step of one pixel and a large one for
//! more; the disparity of least sum, kept where the right image's own
//! least sum points back (the left-right check on the same sums).
//!
//! Each pixel searches its own `n` disparities from `lo[p]` (the coarser
//! level's answer); a path's step between pixels compares costs at the
//! same disparity, whatever the two pixels' ranges.

use super::census::{self, NO_IMAGE};
use crate::stereo::resample::Img;

/// The penalties for a step of one disparity and for more, in census bits
/// (a cost is 0 to 48): the large one about a third of a cost that matches
/// nothing alike, so surfaces may break at edges but not at noise.
const P1: i16 = 8;
const P2: i16 = 40;
/// Past any sum a path reaches (a cost and a jump at most, 88), with
/// room for the penalties added to it. The paths' sums are signed: the
/// baseline x86-64 has a signed 16-bit minimum in one instruction only.
const FAR: i16 = i16::MAX / 4;

/// The eight paths in two raster walks: each path's pixel before is one
/// the walk has passed (the row before, or this row behind it).
const FORWARD: [(i64, i64); 4] = [(1, 0), (0, 1), (1, 1), (-1, 1)];
const BACKWARD: [(i64, i64); 4] = [(-1, 0), (0, -1), (-1, -1), (1, -1)];

/// The disparity of each pixel of `left` (sub-pixel by a parabola through
/// the sums), NaN where it has no image, where the least sum is at the
/// range's end, or where the left-right check fails.
pub fn disparities(left: &Img, right: &Img, lo: &[i32], n: usize) -> Vec<f32> {
    let (w, h) = (left.w, left.h);
    let cl = census::transform(left);
    let cr = census::transform(right);
    VOLUMES.with_borrow_mut(|(cost, sum)| {
        cost.clear();
        cost.resize(w * h * n, NO_IMAGE);
        sum.clear();
        sum.resize(w * h * n, 0);
        search(left, right, lo, n, (&cl, &cr), cost, sum)
    })
}

use std::cell::RefCell;

thread_local! {
    /// The cost and sum volumes of the thread's last search, kept for its
    /// next: megabytes each, past glibc's mmap threshold, fresh ones were
    /// new mappings faulted in a page at a time, and unmapping them
    /// stopped the other threads to flush their address caches.
    static VOLUMES: RefCell<(Vec<u8>, Vec<u16>)> = const { RefCell::new((Vec::new(), Vec::new())) };
}

/// The search on zeroed volumes of `w·h·n` (the costs all [`NO_IMAGE`]).
fn search(left: &Img, right: &Img, lo: &[i32], n: usize, (cl, cr): (&[Option<u64>], &[Option<u64>]), cost: &mut [u8], sum: &mut [u16]) -> Vec<f32> {
    let (w, h) = (left.w, left.h);
    for y in 0..h {
        let ry = y as i64 + left.y0 - right.y0;
        if ry < 0 || ry >= right.h as i64 {
            continue;
        }
        for x in 0..w {
            let p = y * w + x;
            if cl[p].is_none() {
                continue;
            }
            for k in 0..n {
                let xr = x as i64 + left.x0 - (lo[p] + k as i32) as i64 - right.x0;
                if xr >= 0 && xr < right.w as i64 {
                    cost[p * n + k] = census::cost(cl[p], cr[ry as usize * right.w + xr as usize]);
                }
            }
        }
    }
    aggregate(cost, lo, n, w, h, false, sum);
    aggregate(cost, lo, n, w, h, true, sum);
    // A disparity is only chosen where the right image is there.
    let right_at = |p: usize, d: i32| {
        let (x, y) = ((p % w) as i64 + left.x0 - d as i64 - right.x0, (p / w) as i64 + left.y0 - right.y0);
        x >= 0 && y >= 0 && x < right.w as i64 && y < right.h as i64 && cr[y as usize * right.w + x as usize].is_some()
    };
    choose(sum, cl, lo, n, w, h, &right_at)
}

/// One path's sums `L_r(p, d) = C(p, d) + min(L_r(q, d), L_r(q, d ± 1) + P1,
/// min L_r(q) + P2) − min L_r(q)`, `q` the pixel before `p` on the path.
/// Only the row before is kept (the pixel before, for a path along the
/// rows).
struct Path {
    dx: i64,
    dy: i64,
    prev: Vec<i16>,
    cur: Vec<i16>,
    prev_min: Vec<i16>,
    cur_min: Vec<i16>,
    /// The pixel before's sums, aligned to this pixel's range and padded:
    /// `near[t] = L_r(q, lo[p] + t − 1)`.
    near: Vec<i16>,
}

impl Path {
    fn new((dx, dy): (i64, i64), w: usize, n: usize) -> Path {
        Path { dx, dy, prev: vec![0; w * n], cur: vec![0; w * n], prev_min: vec![0; w], cur_min: vec![0; w], near: vec![FAR; n + 2] }
    }

    /// This path's sums at `(x, y)`, the walk's `yi`-th row.
    fn step(&mut self, c: &[u8], lo: &[i32], (n, w): (usize, usize), (x, y, yi): (usize, usize, usize)) -> &[i16] {
        let p = y * w + x;
        let qx = x as i64 - self.dx;
        let before = qx >= 0 && qx < w as i64 && (self.dy == 0 || yi > 0);
        let mut best = FAR;
        if !before {
            let out = &mut self.cur[x * n..(x + 1) * n];
            for k in 0..n {
                out[k] = i16::from(c[k]);
                best = best.min(out[k]);
            }
        } else {
            let qx = qx as usize;
            let qy = (y as i64 - self.dy) as usize;
            let (values, mq) = if self.dy == 0 { (&self.cur[qx * n..(qx + 1) * n], self.cur_min[qx]) } else { (&self.prev[qx * n..(qx + 1) * n], self.prev_min[qx]) };
            let shift = (lo[p] - lo[qy * w + qx]) as i64;
            let near = &mut self.near;
            if shift == 0 {
                near[1..=n].copy_from_slice(values);
                near[0] = FAR;
                near[n + 1] = FAR;
            } else {
                for (t, v) in near.iter_mut().enumerate() {
                    let kq = t as i64 - 1 + shift;
                    *v = if kq >= 0 && kq < n as i64 { values[kq as usize] } else { FAR };
                }
            }
            let jump = mq + P2;
            // Three shifted slices, not windows: a loop the compiler
            // vectorises.
            let (down, same, up) = (&near[..n], &near[1..=n], &near[2..n + 2]);
            let out = &mut self.cur[x * n..(x + 1) * n];
            for k in 0..n {
                let v = i16::from(c[k]) + same[k].min(down[k] + P1).min(up[k] + P1).min(jump) - mq;
                out[k] = v;
                best = best.min(v);
            }
        }
        self.cur_min[x] = best;
        &self.cur[x * n..(x + 1) * n]
    }

    fn next_row(&mut self) {
        std::mem::swap(&mut self.prev, &mut self.cur);
        std::mem::swap(&mut self.prev_min, &mut self.cur_min);
    }
}

/// The sums of four paths, one raster walk (backward: from the last
/// row's last pixel), added into `sum` (integers: the order of the paths
/// changes nothing).
fn aggregate(cost: &[u8], lo: &[i32], n: usize, w: usize, h: usize, backward: bool, sum: &mut [u16]) {
    let mut paths = (if backward { BACKWARD } else { FORWARD }).map(|d| Path::new(d, w, n));
    let mut total = vec![0u16; n];
    for yi in 0..h {
        let y = if backward { h - 1 - yi } else { yi };
        for xi in 0..w {
            let x = if backward { w - 1 - xi } else { xi };
            let p = y * w + x;
            let c = &cost[p * n..(p + 1) * n];
            total.copy_from_slice(&sum[p * n..(p + 1) * n]);
            for path in &mut paths {
                for (t, &v) in total.iter_mut().zip(path.step(c, lo, (n, w), (x, y, yi))) {
                    *t += v as u16;
                }
            }
            sum[p * n..(p + 1) * n].copy_from_slice(&total);
        }
        paths.iter_mut().for_each(Path::next_row);
    }
}

/// The disparity of least sum, checked against the right image's.
fn choose(sum: &[u16], cl: &[Option<u64>], lo: &[i32], n: usize, w: usize, h: usize, right_at: &dyn Fn(usize, i32) -> bool) -> Vec<f32> {
    let mut out = vec![f32::NAN; w * h];
    for y in 0..h {
        let row = y * w..(y + 1) * w;
        let dmax = lo[row.clone()].iter().max().copied().unwrap_or(0) + n as i32 - 1;
        let dmin = lo[row.clone()].iter().min().copied().unwrap_or(0);
        // The right pixel x − d's least sum and its disparity, indexed by
        // x − d + dmax.
        let span = w + (dmax - dmin) as usize;
        let mut right = vec![(u16::MAX, 0i32); span];
        let mut left = vec![(0usize, u16::MAX); w];
        for x in 0..w {
            let p = y * w + x;
            for k in 0..n {
                let s = sum[p * n + k];
                let d = lo[p] + k as i32;
                let r = &mut right[(x as i32 - d + dmax) as usize];
                if s < r.0 {
                    *r = (s, d);
                }
                if s < left[x].1 {
                    left[x] = (k, s);
                }
            }
        }
        for x in 0..w {
            let p = y * w + x;
            let (k, _) = left[x];
            if cl[p].is_none() || k == 0 || k + 1 >= n {
                continue;
            }
            let d = lo[p] + k as i32;
            if !right_at(p, d) {
                continue;
            }
            if (right[(x as i32 - d + dmax) as usize].1 - d).abs() > 1 {
                continue;
            }
            let (a, b, c) = (f32::from(sum[p * n + k - 1]), f32::from(sum[p * n + k]), f32::from(sum[p * n + k + 1]));
            let den = a - 2.0 * b + c;
            let frac = if den > 0.0 { ((a - c) / (2.0 * den)).clamp(-0.5, 0.5) } else { 0.0 };
            out[p] = d as f32 + frac;
        }
    }
    out
}
