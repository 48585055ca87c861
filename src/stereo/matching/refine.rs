//! The last step at full resolution (Nekrasov's thesis §2.7): the
//! normalised cross-correlation of the left window with the right one at
//! the whole disparities around each match, the peak moved to the
//! neighbour where that one correlates better, then the fraction of a
//! pixel from the parabola through the three (0.05–0.125 px in the
//! thesis's tests); matches whose peak correlates less than the threshold
//! are dropped.
//!
//! Everything but the windows' cross products is a box sum shared by the
//! row's pixels (`RowSums`): the correlation at a disparity and each
//! least-squares step within one pixel of the right row then cost a few
//! operations, and a match costs the three or four cross products of its
//! windows.

use crate::stereo::resample::Img;

/// Box sums over the windows centred on each pixel of one image row.
#[derive(Default)]
struct RowSums {
    /// Σ v over the window.
    s1: Vec<f64>,
    /// Σ v².
    s2: Vec<f64>,
    /// Σ v·(its right neighbour): the window's samples against the
    /// window one pixel to the right (meaningful where both are whole).
    next: Vec<f64>,
    /// The window lies inside the image and holds no NaN.
    whole: Vec<bool>,
    /// Per column, over the window's rows: Σ v, Σ v², Σ v·right, NaNs.
    col: Vec<(f64, f64, f64, u32)>,
}

impl RowSums {
    /// The sums for image row `y` (local; the window's rows past the
    /// image make every window there not whole), windows of `2r + 1`.
    fn fill(&mut self, img: &Img, y: i64, r: usize) {
        let w = img.w;
        self.s1.clear();
        self.s1.resize(w, 0.0);
        self.s2.clear();
        self.s2.resize(w, 0.0);
        self.next.clear();
        self.next.resize(w, 0.0);
        self.whole.clear();
        self.whole.resize(w, false);
        if y < r as i64 || y + r as i64 >= img.h as i64 || w < 2 * r + 1 {
            return;
        }
        self.col.clear();
        self.col.resize(w, (0.0, 0.0, 0.0, 0));
        for yy in y as usize - r..=y as usize + r {
            let row = &img.v[yy * w..(yy + 1) * w];
            for (x, c) in self.col.iter_mut().enumerate() {
                let v = f64::from(row[x]);
                if v.is_nan() {
                    c.3 += 1;
                    continue;
                }
                c.0 += v;
                c.1 += v * v;
                let after = row.get(x + 1).map_or(f64::NAN, |&u| f64::from(u));
                if !after.is_nan() {
                    c.2 += v * after;
                }
            }
        }
        for x in r..w - r {
            let cols = &self.col[x - r..=x + r];
            let (mut a, mut b, mut c, mut bad) = (0.0, 0.0, 0.0, 0);
            for k in cols {
                a += k.0;
                b += k.1;
                c += k.2;
                bad += k.3;
            }
            self.s1[x] = a;
            self.s2[x] = b;
            self.next[x] = c;
            self.whole[x] = bad == 0;
        }
    }
}

/// Each match of `disp` within `[x0, x1) × [y0, y1)` (the tile's own
/// pixels) refined; returns the disparities and their peak correlations
/// (NaN where there is no match, and outside).
pub fn subpixel(left: &Img, right: &Img, disp: &mut [f32], side: usize, min_corr: f32, [x0, y0, x1, y1]: [usize; 4]) -> (Vec<f32>, Vec<f32>) {
    let r = side / 2;
    let n = (side * side) as f64;
    let mut out = vec![f32::NAN; disp.len()];
    let mut corr = vec![f32::NAN; disp.len()];
    let (mut ls, mut rs) = (RowSums::default(), RowSums::default());
    for y in y0..y1.min(left.h) {
        let ry = y as i64 + left.y0 - right.y0;
        ls.fill(left, y as i64, r);
        rs.fill(right, ry, r);
        if !rs.whole.iter().any(|&b| b) {
            continue;
        }
        for x in x0..x1.min(left.w) {
            let p = y * left.w + x;
            if disp[p].is_nan() || !ls.whole[x] {
                continue;
            }
            let ml = ls.s1[x] / n;
            let va = ls.s2[x] - ls.s1[x] * ml;
            if !(va.is_finite() && va > 1e-6 * n) {
                continue;
            }
            let d0 = disp[p].round() as i64;
            let pixel = Pixel { left, right, rs: &rs, x, y, ry: ry as usize, r, n, ml, va, d0, cross: [None; CACHED] };
            let Some((fine, c0)) = pixel.refine(min_corr) else { continue };
            out[p] = fine as f32;
            corr[p] = c0;
        }
    }
    disp.copy_from_slice(&out);
    (out, corr)
}

/// The disparities around a match whose cross products are kept: the
/// correlation's peak may step one pixel, the least squares two more.
const CACHED: usize = 9;

/// One left pixel's windows against the right row.
struct Pixel<'a> {
    left: &'a Img,
    right: &'a Img,
    rs: &'a RowSums,
    x: usize,
    y: usize,
    ry: usize,
    r: usize,
    n: f64,
    /// The left window's mean and Σ (v − mean)².
    ml: f64,
    va: f64,
    /// The match's whole disparity; `cross[k]` is at `d0 + k − CACHED/2`.
    d0: i64,
    cross: [Option<f64>; CACHED],
}

impl Pixel<'_> {
    /// The right column (local) of the window at disparity `d`, where
    /// that window is whole.
    fn column(&self, d: i64) -> Option<usize> {
        let c = self.x as i64 + self.left.x0 - d - self.right.x0;
        (c >= 0 && (c as usize) < self.rs.whole.len() && self.rs.whole[c as usize]).then_some(c as usize)
    }

    /// Σ a·b, the left window's samples less their mean (a) against the
    /// right window's at disparity `d` (b); None where that is not whole.
    fn cross(&mut self, d: i64) -> Option<f64> {
        let k = d - self.d0 + (CACHED / 2) as i64;
        let slot = usize::try_from(k).ok().filter(|&k| k < CACHED);
        if let Some(v) = slot.and_then(|k| self.cross[k]) {
            return Some(v);
        }
        let c = self.column(d)?;
        let side = 2 * self.r + 1;
        let (lw, rw) = (self.left.w, self.right.w);
        let mut acc = [0f64; 3];
        for j in 0..side {
            let a = &self.left.v[(self.y + j - self.r) * lw + self.x - self.r..][..side];
            let b = &self.right.v[(self.ry + j - self.r) * rw + c - self.r..][..side];
            for (i, (&a, &b)) in a.iter().zip(b).enumerate() {
                acc[i % 3] += f64::from(a) * f64::from(b);
            }
        }
        let v = acc[0] + acc[1] + acc[2] - self.ml * self.rs.s1[c];
        if let Some(k) = slot {
            self.cross[k] = Some(v);
        }
        Some(v)
    }

    /// The cross products at `d − 1`, `d` and `d + 1` in one walk of the
    /// windows (three sums in flight), kept for `ncc` and the least
    /// squares; where a window is not whole, each is left to `cross`.
    fn cross_around(&mut self, d: i64) {
        let k = d - self.d0 + (CACHED / 2) as i64;
        let (Some(cl), Some(_), Some(_)) = (self.column(d + 1), self.column(d), self.column(d - 1)) else { return };
        let Some(k) = usize::try_from(k - 1).ok().filter(|&k| k + 2 < CACHED) else { return };
        let side = 2 * self.r + 1;
        let (lw, rw) = (self.left.w, self.right.w);
        let mut acc = [0f64; 3];
        for j in 0..side {
            let a = &self.left.v[(self.y + j - self.r) * lw + self.x - self.r..][..side];
            let b = &self.right.v[(self.ry + j - self.r) * rw + cl - self.r..][..side + 2];
            for (i, &a) in a.iter().enumerate() {
                let a = f64::from(a);
                acc[0] += a * f64::from(b[i]);
                acc[1] += a * f64::from(b[i + 1]);
                acc[2] += a * f64::from(b[i + 2]);
            }
        }
        for (t, acc) in acc.into_iter().enumerate() {
            self.cross[k + 2 - t] = Some(acc - self.ml * self.rs.s1[cl + t]);
        }
    }

    /// The correlation with the right window at disparity `d`; None where
    /// it is not whole or is flat.
    fn ncc(&mut self, d: i64) -> Option<f32> {
        let c = self.column(d)?;
        let (s1, s2) = (self.rs.s1[c], self.rs.s2[c]);
        let vb = s2 - s1 * s1 / self.n;
        let sab = self.cross(d)?;
        let r = sab / (self.va * vb).sqrt();
        (r.is_finite() && vb > 1e-6 * self.n).then_some(r as f32)
    }

    /// The refined disparity and the peak's correlation, None where the
    /// peak is not found or correlates less than `min_corr`.
    fn refine(mut self, min_corr: f32) -> Option<(f64, f32)> {
        let mut d = self.d0;
        self.cross_around(d);
        let (mut cm, mut c0, mut cp) = (self.ncc(d - 1)?, self.ncc(d)?, self.ncc(d + 1)?);
        // One step to the better neighbour, where the peak is not here.
        if cm > c0 || cp > c0 {
            let step = if cm > cp { -1 } else { 1 };
            d += step;
            let c = self.ncc(d + step)?;
            (cm, c0, cp) = if step < 0 { (c, cm, c0) } else { (c0, cp, c) };
            if cm > c0 || cp > c0 {
                return None;
            }
        }
        if c0 < min_corr {
            return None;
        }
        let den = cm - 2.0 * c0 + cp;
        let frac = if den < 0.0 { ((cm - cp) / (2.0 * den)).clamp(-0.5, 0.5) } else { 0.0 };
        let parabola = d as f64 + frac as f64;
        // The paraboloid's fraction leans toward whole pixels; the
        // windows' least squares (gain and offset free, the right
        // row interpolated) takes it the rest of the way.
        let fine = self.least_squares(parabola).filter(|f| (f - parabola).abs() < 0.75).unwrap_or(parabola);
        Some((fine, c0))
    }

    /// The disparity near `d0` at which the right window, linearly
    /// interpolated along its row, matches the left one best after a
    /// gain and an offset (Gauss–Newton, a few steps); None where a
    /// window is not whole or the step does not settle.
    ///
    /// At `x − d`, between the right windows at the whole disparities `D`
    /// and `D − 1` (`f = D − d`), the samples are `b = v₀ + f·g` with `g =
    /// v₁ − v₀`: every sum a step needs is one of seven sums of the two
    /// windows, whatever `f`.
    fn least_squares(&mut self, d0: f64) -> Option<f64> {
        let n = self.n;
        let gx = (self.x as i64 + self.left.x0) as f64;
        let mut d = d0;
        for _ in 0..4 {
            let pos = gx - d;
            let base = pos.floor();
            let f = pos - base;
            let whole_d = gx as i64 - base as i64;
            let c = self.column(whole_d)?;
            self.column(whole_d - 1)?;
            let (sv0, sv1) = (self.rs.s1[c], self.rs.s1[c + 1]);
            let (qv0, qv1, x01) = (self.rs.s2[c], self.rs.s2[c + 1], self.rs.next[c]);
            let (av0, av1) = (self.cross(whole_d)?, self.cross(whole_d - 1)?);
            let (sg, sgg, sv0g, sag) = (sv1 - sv0, qv1 - 2.0 * x01 + qv0, x01 - qv0, av1 - av0);
            let sb = sv0 + f * sg;
            let mb = sb / n;
            let var = qv0 + 2.0 * f * sv0g + f * f * sgg - sb * mb;
            if !(var > 1e-9) || !var.is_finite() {
                return None;
            }
            // a (mean 0) ≈ gain·(b − mean b); ∂/∂d of the model is −gain·g.
            let gain = (av0 + f * sag) / var;
            let sgb = sv0g + f * sgg;
            let num = -gain * (sag - gain * (sgb - mb * sg));
            let den = gain * gain * sgg;
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
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The box sums and their closed forms against the windows summed
    /// sample by sample: the correlation at whole disparities and the
    /// least squares' answer, on a textured pair with a NaN in it.
    #[test]
    fn the_sums_give_what_the_windows_give_summed_directly() {
        let (w, h) = (40usize, 30usize);
        let tex = |x: f64, y: f64| (500.0 + 300.0 * (x * 0.3).sin() * (y * 0.45).cos() + 120.0 * (x * 0.17 + y * 0.33).sin()) as f32;
        let left = Img { x0: 100, y0: 7, w, h, v: (0..w * h).map(|k| tex((k % w) as f64, (k / w) as f64)).collect() };
        let shift = 3.37;
        let mut right = Img { x0: 90, y0: 7, w: w + 20, h, v: (0..(w + 20) * h).map(|k| tex((k % (w + 20)) as f64 - 10.0 + shift, (k / (w + 20)) as f64)).collect() };
        right.v[15 * (w + 20) + 2] = f32::NAN;
        let r = 4usize;
        let n = 81.0;
        let (mut ls, mut rs) = (RowSums::default(), RowSums::default());
        let y = 15usize;
        ls.fill(&left, y as i64, r);
        rs.fill(&right, y as i64, r);
        let direct = |x: usize, d: i64| -> Option<f64> {
            let gx = x as i64 + left.x0;
            let (mut a, mut b) = (Vec::new(), Vec::new());
            for j in y - r..=y + r {
                for i in -(r as i64)..=r as i64 {
                    a.push(f64::from(left.at(gx + i, j as i64 + left.y0)));
                    b.push(f64::from(right.at(gx - d + i, j as i64 + right.y0)));
                }
            }
            let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
            let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
            for (p, q) in a.iter().zip(&b) {
                sab += (p - ma) * (q - mb);
                saa += (p - ma) * (p - ma);
                sbb += (q - mb) * (q - mb);
            }
            let c = sab / (saa * sbb).sqrt();
            c.is_finite().then_some(c)
        };
        let (mut compared, mut solved) = (0, 0);
        for x in r..w - r {
            let ml = ls.s1[x] / n;
            let va = ls.s2[x] - ls.s1[x] * ml;
            for d in -2..=9 {
                let mut px = Pixel { left: &left, right: &right, rs: &rs, x, y, ry: y, r, n, ml, va, d0: d, cross: [None; CACHED] };
                match (px.ncc(d), direct(x, d)) {
                    (Some(a), Some(b)) => {
                        assert!((f64::from(a) - b).abs() < 1e-6, "x {x} d {d}: {a} against {b}");
                        compared += 1;
                    }
                    (None, None) => {}
                    (a, b) => panic!("x {x} d {d}: {a:?} against {b:?}"),
                }
            }
            // The right image at x − shift shows the left one's x.
            let mut px = Pixel { left: &left, right: &right, rs: &rs, x, y, ry: y, r, n, ml, va, d0: 3, cross: [None; CACHED] };
            if let Some(d) = px.least_squares(3.1) {
                assert!((d - shift).abs() < 0.02, "x {x}: {d}");
                solved += 1;
            }
        }
        assert!(compared > 200 && solved > 20, "{compared} {solved}");
    }
}
