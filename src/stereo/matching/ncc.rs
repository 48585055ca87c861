//! The correlation search of Nekrasov's thesis (§2.7): along the row, the
//! sequential similarity detection algorithm (Barnea & Silverman) finds
//! the disparity of least absolute difference of the two windows
//! (brightness and contrast taken out), abandoning a candidate as soon as
//! its sum passes the best so far; the normalised cross-correlation of
//! that one candidate accepts or rejects it against a threshold set by the
//! window's size; the right pixel found must find the left one back.

use crate::stereo::resample::Img;

/// Each pixel's window mean and 1/spread, NaN where the window is not
/// whole or flat.
struct Stats {
    mean: Vec<f32>,
    inv_sd: Vec<f32>,
}

fn stats(img: &Img, r: i64) -> Stats {
    let (w, h) = (img.w as i64, img.h as i64);
    let mut mean = vec![f32::NAN; img.w * img.h];
    let mut inv_sd = vec![f32::NAN; img.w * img.h];
    for y in r..h - r {
        for x in r..w - r {
            let (mut s, mut s2) = (0.0f64, 0.0f64);
            for dy in -r..=r {
                for dx in -r..=r {
                    let v = img.v[((y + dy) * w + x + dx) as usize] as f64;
                    s += v;
                    s2 += v * v;
                }
            }
            let n = ((2 * r + 1) * (2 * r + 1)) as f64;
            let m = s / n;
            let var = s2 / n - m * m;
            // NaN sums stay NaN: a window with a hole is no window.
            if var > 1e-6 * (1.0 + m * m) {
                mean[(y * w + x) as usize] = m as f32;
                inv_sd[(y * w + x) as usize] = (1.0 / var.sqrt()) as f32;
            }
        }
    }
    Stats { mean, inv_sd }
}

/// A window of one image at a pixel, normalised.
struct Probe<'a> {
    img: &'a Img,
    st: &'a Stats,
    r: i64,
}

impl Probe<'_> {
    /// Index of the pixel at grid column `gx`, row `gy`, or None where its
    /// window is not whole.
    fn index(&self, gx: i64, gy: i64) -> Option<usize> {
        let (x, y) = (gx - self.img.x0, gy - self.img.y0);
        if x < 0 || y < 0 || x >= self.img.w as i64 || y >= self.img.h as i64 {
            return None;
        }
        let k = (y * self.img.w as i64 + x) as usize;
        (!self.st.mean[k].is_nan()).then_some(k)
    }

    /// The normalised window at index `k` into `out`.
    fn window(&self, k: usize, out: &mut [f32]) {
        let w = self.img.w as i64;
        let (m, s) = (self.st.mean[k], self.st.inv_sd[k]);
        let mut i = 0;
        for dy in -self.r..=self.r {
            let row = k as i64 + dy * w;
            for dx in -self.r..=self.r {
                out[i] = (self.img.v[(row + dx) as usize] - m) * s;
                i += 1;
            }
        }
    }

    /// Σ|a − window at k|, given up once past `limit`.
    fn sad(&self, k: usize, a: &[f32], limit: f32) -> f32 {
        let w = self.img.w as i64;
        let (m, s) = (self.st.mean[k], self.st.inv_sd[k]);
        let mut sum = 0.0;
        let mut i = 0;
        for dy in -self.r..=self.r {
            let row = k as i64 + dy * w;
            for dx in -self.r..=self.r {
                sum += (a[i] - (self.img.v[(row + dx) as usize] - m) * s).abs();
                i += 1;
            }
            if sum >= limit {
                return f32::INFINITY;
            }
        }
        sum
    }

    fn ncc(&self, k: usize, a: &[f32]) -> f32 {
        let w = self.img.w as i64;
        let (m, s) = (self.st.mean[k], self.st.inv_sd[k]);
        let mut sum = 0.0;
        let mut i = 0;
        for dy in -self.r..=self.r {
            let row = k as i64 + dy * w;
            for dx in -self.r..=self.r {
                sum += a[i] * (self.img.v[(row + dx) as usize] - m) * s;
                i += 1;
            }
        }
        sum / a.len() as f32
    }
}

/// The disparity of each pixel of `left` searched over `lo[p] ..
/// lo[p] + n` with `side × side` windows, NaN where rejected; sub-pixel by
/// a parabola through the correlations.
pub fn disparities(left: &Img, right: &Img, lo: &[i32], n: usize, side: usize, threshold: f32) -> Vec<f32> {
    let r = (side / 2) as i64;
    let (sl, sr) = (stats(left, r), stats(right, r));
    let (pl, pr) = (Probe { img: left, st: &sl, r }, Probe { img: right, st: &sr, r });
    let len = (2 * r + 1) as usize * (2 * r + 1) as usize;
    let (mut a, mut b) = (vec![0f32; len], vec![0f32; len]);
    let mut out = vec![f32::NAN; left.w * left.h];
    for y in 0..left.h {
        let gy = y as i64 + left.y0;
        for x in 0..left.w {
            let p = y * left.w + x;
            let gx = x as i64 + left.x0;
            let Some(kl) = pl.index(gx, gy) else { continue };
            pl.window(kl, &mut a);
            // SSDA along the row.
            let (mut best, mut best_k, mut best_idx) = (f32::INFINITY, usize::MAX, 0);
            for k in 0..n {
                let d = (lo[p] + k as i32) as i64;
                let Some(kr) = pr.index(gx - d, gy) else { continue };
                let s = pr.sad(kr, &a, best);
                if s < best {
                    (best, best_k, best_idx) = (s, k, kr);
                }
            }
            if best_k == usize::MAX || best_k == 0 || best_k + 1 >= n {
                continue;
            }
            let c0 = pr.ncc(best_idx, &a);
            if c0 < threshold {
                continue;
            }
            // Back from the right pixel: the left pixel it finds.
            let d = (lo[p] + best_k as i32) as i64;
            pr.window(best_idx, &mut b);
            let (mut back, mut back_k) = (f32::INFINITY, usize::MAX);
            for k in 0..n {
                let dd = (lo[p] + k as i32) as i64;
                let Some(kk) = pl.index(gx - d + dd, gy) else { continue };
                let s = pl.sad(kk, &b, back);
                if s < back {
                    (back, back_k) = (s, k);
                }
            }
            if back_k == usize::MAX || back_k.abs_diff(best_k) > 1 {
                continue;
            }
            let (Some(km), Some(kp)) = (pr.index(gx - d - 1, gy), pr.index(gx - d + 1, gy)) else { continue };
            // d + 1 is the right pixel one to the left.
            let (cm, cp) = (pr.ncc(kp, &a), pr.ncc(km, &a));
            let den = cm - 2.0 * c0 + cp;
            let frac = if den < 0.0 { ((cm - cp) / (2.0 * den)).clamp(-0.5, 0.5) } else { 0.0 };
            out[p] = d as f32 + frac;
        }
    }
    out
}
