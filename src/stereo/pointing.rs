//! The pair's relative pointing error, measured before the dense search:
//! satellite RPCs (and frame poses) are each a few pixels off, and two
//! such errors leave the epipolar rows of the pair a few rows apart — too
//! many for a one-dimensional search. As s2p does, a sparse set of points
//! spread over the overlap is matched in two dimensions (coarse then at
//! full resolution), and the median offset across the rows becomes a
//! shift of the right image's rows; the disparities found narrow the
//! dense search's range.

use super::epipolar::EpipolarFrame;
use super::resample::{resample, Img, Side};
use crate::error::Result;
use rayon::prelude::*;

/// What the sparse matching found.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Pointing {
    /// The right image's rows are the left's moved by this, pixels.
    pub row_shift: f64,
    /// The median absolute deviation of the samples' row offsets, pixels.
    pub spread: f64,
    /// Points matched of those tried.
    pub matched: usize,
    pub tried: usize,
    /// The disparities the points found, widened (None: too few points
    /// to narrow the search).
    pub disparity: Option<[f64; 2]>,
}

/// Samples a side of the overlap.
const GRID: usize = 16;
/// Rows searched each side across the epipolar rows, pixels.
const ACROSS: i64 = 16;
/// Half the side of the correlation window at full resolution.
const R_FINE: i64 = 10;
const R_COARSE: i64 = 7;
const MIN_CORRELATION: f32 = 0.6;

/// Matches points on a `GRID × GRID` lattice of the overlap.
pub fn estimate(frame: &EpipolarFrame, left: &Side, right: &Side) -> Result<Pointing> {
    let (dlo, dhi) = (frame.disparity[0], frame.disparity[1]);
    let centres: Vec<(i64, i64)> = (0..GRID * GRID)
        .map(|k| {
            let (a, b) = ((k % GRID) as f64 + 0.5, (k / GRID) as f64 + 0.5);
            ((a / GRID as f64 * frame.width as f64) as i64, (b / GRID as f64 * frame.height as f64) as i64)
        })
        .collect();
    let found: Vec<Option<(f64, f64)>> = centres.par_iter().map(|&(cx, cy)| sample(frame, left, right, cx, cy, dlo, dhi)).collect::<Result<_>>()?;
    let got: Vec<(f64, f64)> = found.into_iter().flatten().collect();
    let mut p = Pointing { tried: centres.len(), ..Default::default() };
    if got.len() < 5 {
        p.matched = got.len();
        return Ok(p);
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    // The points that agree on the rows' offset (a point matched to other
    // ground lands anywhere): within a pixel of the median.
    let first = median(got.iter().map(|g| g.1).collect());
    let agree: Vec<(f64, f64)> = got.iter().copied().filter(|g| (g.1 - first).abs() <= 1.0).collect();
    p.matched = agree.len();
    if agree.len() < 5 {
        return Ok(p);
    }
    p.row_shift = median(agree.iter().map(|g| g.1).collect());
    p.spread = median(agree.iter().map(|g| (g.1 - p.row_shift).abs()).collect());
    if agree.len() >= 8 {
        let (a, b) = agree.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), g| (a.min(g.0), b.max(g.0)));
        let margin = (0.5 * (b - a)).max(48.0);
        p.disparity = Some([(a - margin).max(dlo).floor(), (b + margin).min(dhi).ceil()]);
    }
    Ok(p)
}

/// The disparity and the offset across rows of the point `(cx, cy)`, or
/// None where it does not match well.
fn sample(frame: &EpipolarFrame, left: &Side, right: &Side, cx: i64, cy: i64, dlo: f64, dhi: f64) -> Result<Option<(f64, f64)>> {
    let range = dhi - dlo;
    let mut levels = 0u32;
    while levels < 3 && range / f64::from(1u32 << levels) > 160.0 {
        levels += 1;
    }
    let f = 1i64 << levels;
    let align = |v: i64| v.div_euclid(32) * 32;
    // The coarse window whole at the coarse level.
    let half = ((R_COARSE + 2) * f).max(32);
    let (lx0, ly0) = (align(cx - half), align(cy - half - ACROSS));
    let lh = (2 * half + 2 * ACROSS + 32) as usize;
    let li = resample(frame, left, lx0, ly0, (2 * half + 32) as usize, lh, 0.0)?;
    if li.at(cx, cy).is_nan() {
        return Ok(None);
    }
    let rx0 = align(cx - half - dhi.ceil() as i64 - 16);
    let rx1 = align(cx + half - dlo.floor() as i64 + 16) + 32;
    let ri = resample(frame, right, rx0, ly0, (rx1 - rx0) as usize, lh, 0.0)?;
    // Coarse: the whole range, rows ± ACROSS.
    let (mut lc, mut rc) = (li.clone(), ri.clone());
    for _ in 0..levels {
        lc = lc.halved();
        rc = rc.halved();
    }
    let (ccx, ccy) = (cx.div_euclid(f), cy.div_euclid(f));
    let mut best = (f32::NEG_INFINITY, 0i64, 0i64);
    for dy in -ACROSS / f..=ACROSS / f {
        for d in (dlo / f as f64).floor() as i64..=(dhi / f as f64).ceil() as i64 {
            if let Some(c) = ncc(&lc, &rc, ccx, ccy, d, dy, R_COARSE) {
                if c > best.0 {
                    best = (c, d, dy);
                }
            }
        }
    }
    if !best.0.is_finite() {
        return Ok(None);
    }
    // Fine: around the coarse answer.
    let (d0, y0) = (best.1 * f, best.2 * f);
    let mut fine = (f32::NEG_INFINITY, 0i64, 0i64);
    for dy in y0 - f - 1..=y0 + f + 1 {
        for d in d0 - f - 1..=d0 + f + 1 {
            if let Some(c) = ncc(&li, &ri, cx, cy, d, dy, R_FINE) {
                if c > fine.0 {
                    fine = (c, d, dy);
                }
            }
        }
    }
    let (c0, d, dy) = fine;
    if c0 < MIN_CORRELATION {
        return Ok(None);
    }
    let at = |d: i64, dy: i64| ncc(&li, &ri, cx, cy, d, dy, R_FINE);
    let peak = |m: Option<f32>, p: Option<f32>| match (m, p) {
        (Some(m), Some(p)) if m <= c0 && p <= c0 && m - 2.0 * c0 + p < 0.0 => Some(f64::from((m - p) / (2.0 * (m - 2.0 * c0 + p)))),
        _ => None,
    };
    let (Some(fd), Some(fy)) = (peak(at(d - 1, dy), at(d + 1, dy)), peak(at(d, dy - 1), at(d, dy + 1))) else { return Ok(None) };
    Ok(Some((d as f64 + fd, dy as f64 + fy)))
}

/// The correlation of the windows at left `(x, y)` and right `(x − d, y + dy)`.
fn ncc(left: &Img, right: &Img, x: i64, y: i64, d: i64, dy: i64, r: i64) -> Option<f32> {
    let (mut sa, mut sb, mut saa, mut sbb, mut sab) = (0f64, 0f64, 0f64, 0f64, 0f64);
    for j in -r..=r {
        for i in -r..=r {
            let a = left.at(x + i, y + j) as f64;
            let b = right.at(x - d + i, y + dy + j) as f64;
            sa += a;
            sb += b;
            saa += a * a;
            sbb += b * b;
            sab += a * b;
        }
    }
    let n = ((2 * r + 1) * (2 * r + 1)) as f64;
    let (va, vb) = (saa - sa * sa / n, sbb - sb * sb / n);
    let c = (sab - sa * sb / n) / (va * vb).sqrt();
    (c.is_finite() && va > 1e-6 * n && vb > 1e-6 * n).then_some(c as f32)
}
