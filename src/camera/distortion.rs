//! Lens distortion in the ground → image direction: an ideal photo point
//! (mm from the principal point, y up) moves to where the lens puts it.
//! Thesis §2.3: radial `σ(r) = b1 r + b2 r² + b3 r³` (r, σ in mm; `σ = E r³`
//! is `b3 = E`). Brown–Conrady in OpenCV's convention (`projectPoints`):
//! on normalised coordinates x right, y **down** (`x/f, −y/f` of the photo
//! point), with OpenCV's k1, k2, k3, p1, p2, so that a calibration from
//! OpenCV (or a tool built on it) is used as it is.
//! Small enough to live in the GCM, never in `A`.

use super::lanes::Lanes;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Brown {
    #[serde(default)]
    pub k1: f64,
    #[serde(default)]
    pub k2: f64,
    #[serde(default)]
    pub k3: f64,
    #[serde(default)]
    pub p1: f64,
    #[serde(default)]
    pub p2: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Distortion {
    None,
    /// `[b1, b2, b3]`, mm.
    Radial([f64; 3]),
    Brown(Brown),
}

impl Distortion {
    /// Ideal photo point → distorted photo point (mm), focal length `f` (mm).
    #[inline]
    #[must_use]
    pub fn apply(&self, x: f64, y: f64, f: f64) -> (f64, f64) {
        match *self {
            Distortion::None => (x, y),
            Distortion::Radial(b) => Distortion::radial(b, x, y),
            Distortion::Brown(b) => Distortion::brown(&b, x, y, f),
        }
    }

    /// The ideal radius (mm from the principal point) past which the lens
    /// model stops moving points outward: there its radial polynomial turns
    /// back (d r_distorted / d r falls to nearly nothing), and a point past it
    /// would land folded back inside the image. Infinite where the model
    /// never turns within four focal lengths.
    #[must_use]
    pub fn fold_radius(&self, f: f64) -> f64 {
        // d r_d / d r along the radius, at ideal radius r (mm).
        let slope = |r: f64| match *self {
            Distortion::None => 1.0,
            Distortion::Radial([b1, b2, b3]) => 1.0 + b1 + 2.0 * b2 * r + 3.0 * b3 * r * r,
            Distortion::Brown(b) => {
                let n2 = (r / f) * (r / f);
                1.0 + 3.0 * b.k1 * n2 + 5.0 * b.k2 * n2 * n2 + 7.0 * b.k3 * n2 * n2 * n2
            }
        };
        let (step, end) = (f / 2000.0, 4.0 * f);
        let mut r = step;
        while r <= end {
            if !(slope(r) > 0.05) {
                return r - step;
            }
            r += step;
        }
        f64::INFINITY
    }

    /// The radial polynomial `[b1, b2, b3]` (mm) at (x, y).
    #[inline(always)]
    #[must_use]
    pub fn radial<T: Lanes>([b1, b2, b3]: [f64; 3], x: T, y: T) -> (T, T) {
        let r = (x * x + y * y).sqrt();
        // σ/r = b1 + b2 r + b3 r²
        let s = T::splat(1.0) + T::splat(b1) + T::splat(b2) * r + T::splat(b3) * r * r;
        let zero = T::splat(0.0);
        (T::if_greater(r, zero, x * s, x), T::if_greater(r, zero, y * s, y))
    }

    /// Brown–Conrady at photo point (x, y) (mm, y up), focal length `f`
    /// (mm): OpenCV's formula on (x/f, −y/f), turned back to y up.
    #[inline(always)]
    #[must_use]
    pub fn brown(b: &Brown, x: f64, y: f64, f: f64) -> (f64, f64) {
        let (xn, yn) = (x / f, -y / f);
        let r2 = xn * xn + yn * yn;
        let radial = 1.0 + r2 * (b.k1 + r2 * (b.k2 + r2 * b.k3));
        let xd = xn * radial + 2.0 * b.p1 * xn * yn + b.p2 * (r2 + 2.0 * xn * xn);
        let yd = yn * radial + b.p1 * (r2 + 2.0 * yn * yn) + 2.0 * b.p2 * xn * yn;
        (xd * f, -yd * f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radial_moves_along_the_radius_by_sigma() {
        // r = 100 mm: σ = 1e-4·100 + 2e-6·100² + (−3e-9)·100³ = 0.01 + 0.02 − 0.003 = 0.027 mm.
        let d = Distortion::Radial([1e-4, 2e-6, -3e-9]);
        let (x, y) = d.apply(60.0, 80.0, 152.0);
        let r = (x * x + y * y).sqrt();
        assert!((r - 100.027).abs() < 1e-12);
        assert!((y / x - 80.0 / 60.0).abs() < 1e-12);
    }

    #[test]
    fn brown_matches_hand_values() {
        // f = 100, point (10, 0): xn = 0.1, r² = 0.01; k1 = 0.1 → radial 1.001;
        // p2 = 0.001 → +p2·(r² + 2 xn²) = 0.001·0.03 = 3e-5;
        // p1 = 0.002 → y down: p1·(r² + 0) = 2e-5, so y up: −2e-5.
        let d = Distortion::Brown(Brown { k1: 0.1, k2: 0.0, k3: 0.0, p1: 0.002, p2: 0.001 });
        let (x, y) = d.apply(10.0, 0.0, 100.0);
        assert!((x - (0.1 * 1.001 + 3e-5) * 100.0).abs() < 1e-12);
        assert!((y + 2e-5 * 100.0).abs() < 1e-12);
        // Point (0, 10) (up): yn = −0.1 (down); p1 → y down: p1·(r² + 2yn²) = 6e-5,
        // 2·p2·xn·yn = 0; x: 2·p1·xn·yn = 0, p2·(r²) = 1e-5.
        let (x, y) = d.apply(0.0, 10.0, 100.0);
        assert!((x - 1e-5 * 100.0).abs() < 1e-12);
        assert!((y - (0.1 * 1.001 - 6e-5) * 100.0).abs() < 1e-12, "{y}");
    }
}
