//! The last step at full resolution (Nekrasov's thesis §2.7): the
//! normalised cross-correlation of the left window with the right one at
//! the whole disparities around each match, the peak moved to the
//! neighbour where that one correlates better, then the fraction of a
//! pixel from the parabola through the three (0.05–0.125 px in the
//! thesis's tests); matches whose peak correlates less than the threshold
//! are dropped.

use crate::stereo::resample::Img;

/// The correlation of the `side × side` windows at left grid pixel
/// `(gx, gy)` and right grid pixel `(gx − d, gy)`; None where either
/// window is not whole or is flat.
fn ncc(left: &Img, right: &Img, gx: i64, gy: i64, d: i64, r: i64) -> Option<f32> {
    let (mut sa, mut sb, mut saa, mut sbb, mut sab) = (0f64, 0f64, 0f64, 0f64, 0f64);
    for dy in -r..=r {
        for dx in -r..=r {
            let a = left.at(gx + dx, gy + dy) as f64;
            let b = right.at(gx - d + dx, gy + dy) as f64;
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

/// Each match of `disp` refined; returns the disparities and their peak
/// correlations (NaN where there is no match).
pub fn subpixel(left: &Img, right: &Img, disp: &mut [f32], side: usize, min_corr: f32) -> (Vec<f32>, Vec<f32>) {
    let r = (side / 2) as i64;
    let mut out = vec![f32::NAN; disp.len()];
    let mut corr = vec![f32::NAN; disp.len()];
    for y in 0..left.h {
        let gy = y as i64 + left.y0;
        for x in 0..left.w {
            let p = y * left.w + x;
            if disp[p].is_nan() {
                continue;
            }
            let gx = x as i64 + left.x0;
            let mut d = disp[p].round() as i64;
            let at = |d: i64| ncc(left, right, gx, gy, d, r);
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
            let fine = least_squares(left, right, gx, gy, parabola, r).filter(|f| (f - parabola).abs() < 0.75).unwrap_or(parabola);
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
fn least_squares(left: &Img, right: &Img, gx: i64, gy: i64, d0: f64, r: i64) -> Option<f64> {
    let side = (2 * r + 1) as usize;
    let n = side * side;
    let mut a = [0f64; 21 * 21];
    let mut k = 0;
    for dy in -r..=r {
        for dx in -r..=r {
            a[k] = left.at(gx + dx, gy + dy) as f64;
            k += 1;
        }
    }
    let mut d = d0;
    let (mut b, mut g) = ([0f64; 21 * 21], [0f64; 21 * 21]);
    for _ in 0..4 {
        // The right samples at x − d and their slope along the row.
        let pos = gx as f64 - d;
        let base = pos.floor();
        let f = pos - base;
        let mut k = 0;
        for dy in -r..=r {
            for dx in -r..=r {
                let x = base as i64 + dx;
                let (v0, v1) = (right.at(x, gy + dy) as f64, right.at(x + 1, gy + dy) as f64);
                b[k] = v0 + f * (v1 - v0);
                g[k] = v1 - v0;
                k += 1;
            }
        }
        let (mut sb, mut sa, mut sbb, mut sab) = (0.0, 0.0, 0.0, 0.0);
        for k in 0..n {
            sb += b[k];
            sa += a[k];
            sbb += b[k] * b[k];
            sab += a[k] * b[k];
        }
        let nf = n as f64;
        let var = sbb - sb * sb / nf;
        if !(var > 1e-9) || !var.is_finite() {
            return None;
        }
        let gain = (sab - sa * sb / nf) / var;
        let offset = (sa - gain * sb) / nf;
        // m = gain·b(d) + offset; ∂m/∂d = −gain·slope.
        let (mut num, mut den) = (0.0, 0.0);
        for k in 0..n {
            let e = a[k] - gain * b[k] - offset;
            let j = -gain * g[k];
            num += j * e;
            den += j * j;
        }
        if !(den > 0.0) {
            return None;
        }
        let step = (num / den).clamp(-0.5, 0.5);
        d += step;
        if step.abs() < 0.005 {
            return Some(d);
        }
    }
    Some(d)
}
