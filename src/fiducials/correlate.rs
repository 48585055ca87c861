//! Normalised correlation of a template with a grey window (thesis eq.
//! 2.6.11) at every place the template fits: the template's sum over its
//! marked pixels only, the window's mean and spread from integral images.

use super::gray::Gray;
use super::template::Template;

/// Correlation for every place of the template's top-left corner in
/// `[i0, i0 + width) × [j0, j0 + height)` of the window.
#[derive(Clone, Debug)]
pub struct Surface {
    pub i0: usize,
    pub j0: usize,
    pub width: usize,
    pub height: usize,
    pub r: Vec<f32>,
}

/// A correlation peak: the template's top-left corner in window pixels,
/// and its coefficient.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Peak {
    pub i: usize,
    pub j: usize,
    pub r: f32,
}

/// Sums of the window's tones and squared tones over rectangles.
struct Integrals {
    w: usize,
    s: Vec<f64>,
    ss: Vec<f64>,
}

impl Integrals {
    fn new(g: &Gray) -> Integrals {
        let w = g.width + 1;
        let mut s = vec![0.0; w * (g.height + 1)];
        let mut ss = vec![0.0; w * (g.height + 1)];
        for j in 0..g.height {
            let (mut row, mut row2) = (0.0, 0.0);
            for i in 0..g.width {
                let v = g.at(i, j) as f64;
                row += v;
                row2 += v * v;
                s[(j + 1) * w + i + 1] = s[j * w + i + 1] + row;
                ss[(j + 1) * w + i + 1] = ss[j * w + i + 1] + row2;
            }
        }
        Integrals { w, s, ss }
    }

    /// Sum and sum of squares over `[i, i+n) × [j, j+n)`.
    fn square(&self, i: usize, j: usize, n: usize) -> (f64, f64) {
        let w = self.w;
        let at = |v: &Vec<f64>| v[(j + n) * w + i + n] - v[j * w + i + n] - v[(j + n) * w + i] + v[j * w + i];
        (at(&self.s), at(&self.ss))
    }
}

/// The correlation of `t` over the places whose top-left corner lies in
/// `[i0, i1) × [j0, j1)` (clipped to where the template fits).
#[must_use]
pub fn correlate(g: &Gray, t: &Template, (i0, j0, i1, j1): (usize, usize, usize, usize)) -> Surface {
    let n = t.size;
    let i1 = i1.min((g.width + 1).saturating_sub(n));
    let j1 = j1.min((g.height + 1).saturating_sub(n));
    let (width, height) = (i1.saturating_sub(i0), j1.saturating_sub(j0));
    let mut r = vec![0f32; width * height];
    if width == 0 || height == 0 {
        return Surface { i0, j0, width, height, r };
    }
    let ints = Integrals::new(g);
    // The template's marked pixels as window offsets.
    let taps: Vec<(usize, f32)> = t.nonzero.iter().map(|&(k, tone)| ((k as usize / n) * g.width + k as usize % n, tone)).collect();
    let count = (n * n) as f64;
    for j in 0..height {
        for i in 0..width {
            let (pi, pj) = (i0 + i, j0 + j);
            let base = &g.data[pj * g.width + pi..];
            // In f64: 16-bit tones over a template's thousands of taps
            // reach 1e8, where f32's sum is off by more than the
            // difference from `mean·s` the coefficient is made of.
            let dot: f64 = taps.iter().map(|&(o, tone)| base[o] as f64 * tone as f64).sum();
            let (s, ss) = ints.square(pi, pj, n);
            let var = ss - s * s / count;
            r[j * width + i] = if var > 1e-9 * count { ((dot - t.mean as f64 * s) / (t.norm as f64 * var.sqrt())) as f32 } else { 0.0 };
        }
    }
    Surface { i0, j0, width, height, r }
}

impl Surface {
    #[must_use]
    pub fn at(&self, i: usize, j: usize) -> f32 {
        self.r[(j - self.j0) * self.width + (i - self.i0)]
    }

    /// The `k` strongest peaks of `sign`·r (sign +1: the template's tones;
    /// −1: inverted), at least `apart` places from each other.
    #[must_use]
    pub fn peaks(&self, sign: f32, k: usize, apart: usize) -> Vec<Peak> {
        // k passes over the surface (k is a few; sorting it all cost more
        // than the correlation): each the strongest place apart from those
        // taken (of equal ones, the first).
        let mut out: Vec<Peak> = Vec::new();
        while out.len() < k {
            let mut best: Option<Peak> = None;
            for (idx, &r) in self.r.iter().enumerate() {
                let r = sign * r;
                if best.is_some_and(|b| !(r > b.r)) || r.is_nan() {
                    continue;
                }
                let (i, j) = (self.i0 + idx % self.width, self.j0 + idx / self.width);
                if out.iter().all(|p| p.i.abs_diff(i) > apart || p.j.abs_diff(j) > apart) {
                    best = Some(Peak { i, j, r });
                }
            }
            match best {
                Some(p) => out.push(p),
                None => break,
            }
        }
        out
    }

    /// The sub-place of a peak by a parabola through it and its
    /// neighbours along each axis (0 at the border).
    #[must_use]
    pub fn refine(&self, p: Peak, sign: f32) -> [f64; 2] {
        let v = |i: usize, j: usize| (sign * self.at(i, j)) as f64;
        let axis = |a: f64, c: f64, b: f64| {
            let d = a - 2.0 * c + b;
            if d < 0.0 {
                (0.5 * (a - b) / d).clamp(-0.5, 0.5)
            } else {
                0.0
            }
        };
        let inside = |i: usize, lo: usize, n: usize| i > lo && i + 1 < lo + n;
        let dx = if inside(p.i, self.i0, self.width) { axis(v(p.i - 1, p.j), v(p.i, p.j), v(p.i + 1, p.j)) } else { 0.0 };
        let dy = if inside(p.j, self.j0, self.height) { axis(v(p.i, p.j - 1), v(p.i, p.j), v(p.i, p.j + 1)) } else { 0.0 };
        [p.i as f64 + dx, p.j as f64 + dy]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fiducials::shape::{MarkLook, Shape};
    use nalgebra::Matrix2;

    #[test]
    fn the_template_is_found_where_it_was_drawn_and_inverted() {
        let shape = Shape::from_look(&MarkLook { shape: "cross".into(), size_mm: Some(1.0), line_mm: Some(0.1), ..Default::default() }).unwrap();
        let to_px = Matrix2::new(20.0, 0.0, 0.0, -20.0);
        let t = Template::render(&shape, &to_px, shape.radius_mm, [0.0, 0.0]).unwrap();
        // A window with the template's tones (inverted: a negative) at (17, 9).
        let (w, h) = (80, 60);
        let mut g = Gray { factor: 1, width: w, height: h, data: vec![0.7; w * h], ..Default::default() };
        for &(idx, tone) in &t.nonzero {
            let (i, j) = (idx as usize % t.size, idx as usize / t.size);
            g.data[(9 + j) * w + 17 + i] = 0.7 - 0.5 * tone;
        }
        let s = correlate(&g, &t, (0, 0, w, h));
        let best = s.peaks(-1.0, 1, 3)[0];
        assert_eq!((best.i, best.j), (17, 9));
        assert!((best.r - 1.0).abs() < 1e-4, "{}", best.r);
        assert!(s.peaks(1.0, 1, 3)[0].r < 0.5);
    }
}
