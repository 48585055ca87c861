//! The last step at full resolution (Nekrasov's thesis §2.7): the
//! normalised cross-correlation of the left window with the right one at
//! the whole disparities around each match, the peak moved to the
//! neighbour where that one correlates better, then the fraction of a
//! pixel from the parabola through the three (0.05–0.125 px in the
//! thesis's tests); matches whose peak correlates less than the threshold
//! are dropped.

use crate::stereo::resample::Img;

/// The left window of a match, its mean taken out.
struct LeftWindow {
    a: Vec<f64>,
    /// Σ a² (n times the variance).
    va: f64,
    r: i64,
}

impl LeftWindow {
    fn new(r: i64) -> LeftWindow {
        let side = (2 * r + 1) as usize;
        LeftWindow { a: Vec::with_capacity(side * side), va: 0.0, r }
    }

    /// This window filled at `(gx, gy)` (its buffer reused: a match costs
    /// no allocation); false where it is not whole or is flat.
    fn fill(&mut self, left: &Img, gx: i64, gy: i64) -> bool {
        let r = self.r;
        let side = (2 * r + 1) as usize;
        self.a.clear();
        for dy in -r..=r {
            let Some(row) = left.row(gy + dy, gx - r, side) else { return false };
            self.a.extend(row.iter().map(|&v| f64::from(v)));
        }
        let mean = self.a.iter().sum::<f64>() / self.a.len() as f64;
        self.a.iter_mut().for_each(|v| *v -= mean);
        self.va = self.a.iter().map(|v| v * v).sum::<f64>();
        self.va.is_finite() && self.va > 1e-6 * self.a.len() as f64
    }

    /// The correlation with the right window at `(gx − d, gy)`; None where
    /// it is not whole or is flat.
    fn ncc(&self, right: &Img, gx: i64, gy: i64, d: i64) -> Option<f32> {
        let r = self.r;
        let side = (2 * r + 1) as usize;
        let (mut sb, mut sbb, mut sab) = (0f64, 0f64, 0f64);
        for (j, dy) in (-r..=r).enumerate() {
            let row = right.row(gy + dy, gx - d - r, side)?;
            let a = &self.a[j * side..(j + 1) * side];
            for (&b, &a) in row.iter().zip(a) {
                let b = f64::from(b);
                sb += b;
                sbb += b * b;
                sab += a * b;
            }
        }
        let n = self.a.len() as f64;
        let vb = sbb - sb * sb / n;
        let c = sab / (self.va * vb).sqrt();
        (c.is_finite() && vb > 1e-6 * n).then_some(c as f32)
    }
}

/// Each match of `disp` within `[x0, x1) × [y0, y1)` (the tile's own
/// pixels) refined; returns the disparities and their peak correlations
/// (NaN where there is no match, and outside).
pub fn subpixel(left: &Img, right: &Img, disp: &mut [f32], side: usize, min_corr: f32, [x0, y0, x1, y1]: [usize; 4]) -> (Vec<f32>, Vec<f32>) {
    let r = (side / 2) as i64;
    let mut out = vec![f32::NAN; disp.len()];
    let mut corr = vec![f32::NAN; disp.len()];
    let mut lw = LeftWindow::new(r);
    let mut scratch = (Vec::new(), Vec::new());
    for y in y0..y1.min(left.h) {
        let gy = y as i64 + left.y0;
        for x in x0..x1.min(left.w) {
            let p = y * left.w + x;
            if disp[p].is_nan() {
                continue;
            }
            let gx = x as i64 + left.x0;
            let mut d = disp[p].round() as i64;
            if !lw.fill(left, gx, gy) {
                continue;
            }
            let lw = &lw;
            let at = |d: i64| lw.ncc(right, gx, gy, d);
            let (Some(mut cm), Some(mut c0), Some(mut cp)) = (at(d - 1), at(d), at(d + 1)) else { continue };
            // One step to the better neighbour, where the peak is not here.
            if cm > c0 || cp > c0 {
                let step = if cm > cp { -1 } else { 1 };
                d += step;
                let Some(c) = at(d + step) else { continue };
                (cm, c0, cp) = if step < 0 { (c, cm, c0) } else { (c0, cp, c) };
                if cm > c0 || cp > c0 {
                    continue;
                }
            }
            if c0 < min_corr {
                continue;
            }
            let den = cm - 2.0 * c0 + cp;
            let frac = if den < 0.0 { ((cm - cp) / (2.0 * den)).clamp(-0.5, 0.5) } else { 0.0 };
            let parabola = d as f64 + frac as f64;
            // The paraboloid's fraction leans toward whole pixels; the
            // windows' least squares (gain and offset free, the right
            // row interpolated) takes it the rest of the way.
            let fine = least_squares(lw, right, gx, gy, parabola, &mut scratch).filter(|f| (f - parabola).abs() < 0.75).unwrap_or(parabola);
            out[p] = fine as f32;
            corr[p] = c0;
        }
    }
    disp.copy_from_slice(&out);
    (out, corr)
}

/// The disparity near `d0` at which the right window, linearly
/// interpolated along its row, matches the left one best after a gain and
/// an offset (Gauss–Newton, a few steps); None where a window is not whole
/// or the step does not settle.
fn least_squares(lw: &LeftWindow, right: &Img, gx: i64, gy: i64, d0: f64, (b, g): &mut (Vec<f64>, Vec<f64>)) -> Option<f64> {
    let r = lw.r;
    let side = (2 * r + 1) as usize;
    let n = lw.a.len();
    let nf = n as f64;
    b.resize(n, 0.0);
    g.resize(n, 0.0);
    let mut d = d0;
    for _ in 0..4 {
        // The right samples at x − d and their slope along the row.
        let pos = gx as f64 - d;
        let base = pos.floor();
        let f = pos - base;
        for (j, dy) in (-r..=r).enumerate() {
            let row = right.row(gy + dy, base as i64 - r, side + 1)?;
            for i in 0..side {
                let (v0, v1) = (f64::from(row[i]), f64::from(row[i + 1]));
                b[j * side + i] = v0 + f * (v1 - v0);
                g[j * side + i] = v1 - v0;
            }
        }
        let sb: f64 = b.iter().sum();
        let mb = sb / nf;
        let (mut var, mut cov) = (0.0, 0.0);
        for (bk, ak) in b.iter().zip(&lw.a) {
            let bc = bk - mb;
            var += bc * bc;
            cov += ak * bc;
        }
        if !(var > 1e-9) || !var.is_finite() {
            return None;
        }
        // a (mean 0) ≈ gain·(b − mean b); ∂/∂d of the model is −gain·slope.
        let gain = cov / var;
        let (mut num, mut den) = (0.0, 0.0);
        for k in 0..n {
            let e = lw.a[k] - gain * (b[k] - mb);
            let j = -gain * g[k];
            num += j * e;
            den += j * j;
        }
        if !(den > 0.0) {
            return None;
        }
        let step = (num / den).clamp(-0.5, 0.5);
        d += step;
        if step.abs() < 0.01 {
            return Some(d);
        }
    }
    Some(d)
}
