//! Lens distortion in the ground → image direction: an ideal photo point
//! (mm from the principal point, y up) moves to where the lens puts it.
//! Thesis §2.3: radial `σ(r) = b1 r + b2 r² + b3 r³` (r, σ in mm; `σ = E r³`
//! is `b3 = E`). Brown–Conrady in OpenCV's convention (`projectPoints`):
//! on normalised coordinates x right, y **down** (`x/f, −y/f` of the photo
//! point), with OpenCV's k1, k2, k3, p1, p2, so that a calibration from
//! OpenCV (or a tool built on it) is used as it is.
//! OpenCV's full (rational, thin-prism) and fisheye models on the same
//! normalised coordinates. Left to the GCM, never in `A`.

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

/// OpenCV's full model (`projectPoints` without the tilt terms): rational
/// radial `(1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶)`,
/// tangential p1, p2 and thin prism s1–s4, on the same normalised
/// coordinates as [`Brown`] (which is this model with k4…s4 zero).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpenCv {
    #[serde(default)]
    pub k1: f64,
    #[serde(default)]
    pub k2: f64,
    #[serde(default)]
    pub k3: f64,
    #[serde(default)]
    pub k4: f64,
    #[serde(default)]
    pub k5: f64,
    #[serde(default)]
    pub k6: f64,
    #[serde(default)]
    pub p1: f64,
    #[serde(default)]
    pub p2: f64,
    #[serde(default)]
    pub s1: f64,
    #[serde(default)]
    pub s2: f64,
    #[serde(default)]
    pub s3: f64,
    #[serde(default)]
    pub s4: f64,
}

impl OpenCv {
    /// The coefficients in OpenCV's order (k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4).
    #[must_use]
    pub fn opencv_order(&self) -> [f64; 12] {
        [self.k1, self.k2, self.p1, self.p2, self.k3, self.k4, self.k5, self.k6, self.s1, self.s2, self.s3, self.s4]
    }
}

/// OpenCV's fisheye (Kannala–Brandt) model, `cv::fisheye::projectPoints`:
/// the angle θ from the axis becomes `θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸)`
/// on the normalised image plane.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Fisheye {
    #[serde(default)]
    pub k1: f64,
    #[serde(default)]
    pub k2: f64,
    #[serde(default)]
    pub k3: f64,
    #[serde(default)]
    pub k4: f64,
}

/// Agisoft Metashape's frame model on OpenCV's normalised coordinates
/// (x right, y down): radial to r⁸, and tangential terms in Metashape's own
/// order — its P1 goes with r² + 2x² in x (OpenCV's p2), P2 with r² + 2y²
/// in y — scaled by (1 + P3 r² + P4 r⁴).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Metashape {
    #[serde(default)]
    pub k1: f64,
    #[serde(default)]
    pub k2: f64,
    #[serde(default)]
    pub k3: f64,
    #[serde(default)]
    pub k4: f64,
    #[serde(default)]
    pub p1: f64,
    #[serde(default)]
    pub p2: f64,
    #[serde(default)]
    pub p3: f64,
    #[serde(default)]
    pub p4: f64,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Distortion {
    None,
    /// `[b1, b2, b3]`, mm.
    Radial([f64; 3]),
    Brown(Brown),
    OpenCv(OpenCv),
    Fisheye(Fisheye),
    Metashape(Metashape),
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
            Distortion::OpenCv(o) => Distortion::opencv(&o, x, y, f),
            Distortion::Fisheye(k) => Distortion::fisheye(&k, x, y, f),
            Distortion::Metashape(m) => Distortion::metashape(&m, x, y, f),
        }
    }

    /// The ideal photo point whose distorted image is (xd, yd) (mm): the
    /// inverse of [`Distortion::apply`] by Newton's method, to 1e-9 of the
    /// focal length. `None` where it does not converge (past the fold).
    #[must_use]
    pub fn remove(&self, xd: f64, yd: f64, f: f64) -> Option<(f64, f64)> {
        if *self == Distortion::None {
            return Some((xd, yd));
        }
        let (mut x, mut y) = (xd, yd);
        let h = f * 1e-7;
        for _ in 0..50 {
            let (ax, ay) = self.apply(x, y, f);
            let (ex, ey) = (xd - ax, yd - ay);
            if ex.hypot(ey) < f * 1e-9 {
                return Some((x, y));
            }
            let (bx, by) = self.apply(x + h, y, f);
            let (cx, cy) = self.apply(x, y + h, f);
            let j = nalgebra::Matrix2::new((bx - ax) / h, (cx - ax) / h, (by - ay) / h, (cy - ay) / h);
            let step = j.try_inverse()? * nalgebra::Vector2::new(ex, ey);
            // Damped: a step never more than doubles the radius.
            let scale = (x.hypot(y).max(f * 0.01) / step.norm()).min(1.0);
            x += step.x * scale;
            y += step.y * scale;
        }
        None
    }

    /// The ideal radius (mm from the principal point) past which the lens
    /// model stops moving points outward: there its radial polynomial turns
    /// back (d r_distorted / d r falls to nearly nothing), and a point past it
    /// would land folded back inside the image. Infinite where the model
    /// never turns within four focal lengths (a fisheye: within 89.9° of
    /// its axis).
    #[must_use]
    pub fn fold_radius(&self, f: f64) -> f64 {
        // The distorted radius along the x axis at ideal radius r (mm), its
        // tangential and prism terms left out (they do not fold the radius).
        let along = |r: f64| -> f64 {
            match *self {
                Distortion::None => r,
                Distortion::Radial(b) => Distortion::radial(b, r, 0.0).0,
                Distortion::Brown(b) => Distortion::brown(&Brown { p1: 0.0, p2: 0.0, ..b }, r, 0.0, f).0,
                Distortion::OpenCv(o) => Distortion::opencv(&OpenCv { p1: 0.0, p2: 0.0, s1: 0.0, s2: 0.0, s3: 0.0, s4: 0.0, ..o }, r, 0.0, f).0,
                Distortion::Fisheye(k) => Distortion::fisheye(&k, r, 0.0, f).0,
                Distortion::Metashape(m) => Distortion::metashape(&Metashape { p1: 0.0, p2: 0.0, ..m }, r, 0.0, f).0,
            }
        };
        if let Distortion::Fisheye(k) = *self {
            // Stepped in the angle θ from the axis, up to 89.9°.
            let theta_d = |t: f64| {
                let t2 = t * t;
                t * (1.0 + t2 * (k.k1 + t2 * (k.k2 + t2 * (k.k3 + t2 * k.k4))))
            };
            let (step, end) = (1e-4, 89.9f64.to_radians());
            let mut t = step;
            while t <= end {
                if !((theta_d(t + step) - theta_d(t)) / step > 0.05) {
                    return f * t.tan();
                }
                t += step;
            }
            return f64::INFINITY;
        }
        let (step, end) = (f / 2000.0, 4.0 * f);
        let mut r = step;
        while r <= end {
            if !((along(r + step / 10.0) - along(r)) / (step / 10.0) > 0.05) {
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

    /// OpenCV's full model at photo point (x, y) (mm, y up), as [`Distortion::brown`].
    #[inline(always)]
    #[must_use]
    pub fn opencv(o: &OpenCv, x: f64, y: f64, f: f64) -> (f64, f64) {
        let (xn, yn) = (x / f, -y / f);
        let r2 = xn * xn + yn * yn;
        let r4 = r2 * r2;
        let radial = (1.0 + r2 * (o.k1 + r2 * (o.k2 + r2 * o.k3))) / (1.0 + r2 * (o.k4 + r2 * (o.k5 + r2 * o.k6)));
        let xd = xn * radial + 2.0 * o.p1 * xn * yn + o.p2 * (r2 + 2.0 * xn * xn) + o.s1 * r2 + o.s2 * r4;
        let yd = yn * radial + o.p1 * (r2 + 2.0 * yn * yn) + 2.0 * o.p2 * xn * yn + o.s3 * r2 + o.s4 * r4;
        (xd * f, -yd * f)
    }

    /// Metashape's model at photo point (x, y) (mm, y up), as [`Distortion::brown`].
    #[inline(always)]
    #[must_use]
    pub fn metashape(m: &Metashape, x: f64, y: f64, f: f64) -> (f64, f64) {
        let (xn, yn) = (x / f, -y / f);
        let r2 = xn * xn + yn * yn;
        let radial = 1.0 + r2 * (m.k1 + r2 * (m.k2 + r2 * (m.k3 + r2 * m.k4)));
        let scale = 1.0 + r2 * (m.p3 + r2 * m.p4);
        let xd = xn * radial + (m.p1 * (r2 + 2.0 * xn * xn) + 2.0 * m.p2 * xn * yn) * scale;
        let yd = yn * radial + (m.p2 * (r2 + 2.0 * yn * yn) + 2.0 * m.p1 * xn * yn) * scale;
        (xd * f, -yd * f)
    }

    /// The fisheye model at photo point (x, y) (mm, y up): the ideal point
    /// is `f·tan θ` from the principal point, the distorted one `f·θ_d`.
    #[inline(always)]
    #[must_use]
    pub fn fisheye(k: &Fisheye, x: f64, y: f64, f: f64) -> (f64, f64) {
        let r = x.hypot(y) / f;
        if !(r > 1e-15) {
            return (x, y);
        }
        let t = r.atan();
        let t2 = t * t;
        let td = t * (1.0 + t2 * (k.k1 + t2 * (k.k2 + t2 * (k.k3 + t2 * k.k4))));
        let s = td / r;
        (x * s, y * s)
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

    #[test]
    fn remove_undoes_apply_for_every_model() {
        let f = 8.8;
        let models = [
            Distortion::Radial([1e-4, 2e-6, -3e-9]),
            Distortion::Brown(Brown { k1: -0.11, k2: 0.035, k3: -0.004, p1: 4e-4, p2: -2.5e-4 }),
            Distortion::OpenCv(OpenCv { k1: -0.11, k2: 0.035, k4: 0.02, k6: 0.01, p1: 4e-4, s1: 1.5e-3, s4: 1e-3, ..Default::default() }),
            Distortion::Fisheye(Fisheye { k1: 0.052, k2: -0.013, k3: 0.0021, k4: -3e-4 }),
            Distortion::Metashape(Metashape { k1: -0.09, k2: -0.076, k3: 0.116, k4: -0.076, p1: -3e-4, p2: 1.2e-4, p3: 0.1, p4: -0.05 }),
        ];
        for d in models {
            for (x, y) in [(0.0, 0.0), (3.1, -2.2), (-4.5, 3.4), (0.7, 5.0)] {
                let (xd, yd) = d.apply(x, y, f);
                let (bx, by) = d.remove(xd, yd, f).unwrap_or_else(|| panic!("{d:?} at ({x}, {y})"));
                assert!((bx - x).abs() < 1e-7 && (by - y).abs() < 1e-7, "{d:?}: ({x}, {y}) came back as ({bx}, {by})");
            }
        }
    }

    #[test]
    fn metashape_matches_hand_values() {
        // f = 100, point (10, −20) mm, y up: x' = 0.1, y' = 0.2 (down),
        // r² = 0.05. Radial: 1 + 0.1·0.05 + 0.01·0.0025 + 0 + 0.001·0.05⁴ =
        // 1.005025 + 6.25e-9. Tangential, Metashape's order: x gets
        // P1(r² + 2x'²) + 2 P2 x'y' = 0.002·0.07 + 2·0.001·0.02 = 1.8e-4,
        // y gets P2(r² + 2y'²) + 2 P1 x'y' = 0.001·0.13 + 2·0.002·0.02 = 2.1e-4,
        // both times 1 + P3 r² + P4 r⁴ = 1 + 0.5·0.05 + 0.2·0.0025 = 1.0255.
        let m = Metashape { k1: 0.1, k2: 0.01, k3: 0.0, k4: 0.001, p1: 0.002, p2: 0.001, p3: 0.5, p4: 0.2 };
        let (x, y) = Distortion::Metashape(m).apply(10.0, -20.0, 100.0);
        let radial = 1.005025 + 6.25e-9;
        assert!((x - (0.1 * radial + 1.8e-4 * 1.0255) * 100.0).abs() < 1e-12, "{x}");
        assert!((y + (0.2 * radial + 2.1e-4 * 1.0255) * 100.0).abs() < 1e-12, "{y}");
        // With k4 = p3 = p4 = 0 it is Brown's model with p1 and p2 swapped.
        let b = Brown { k1: 0.1, k2: 0.01, k3: 0.003, p1: 0.001, p2: 0.002 };
        let as_metashape = Metashape { k1: 0.1, k2: 0.01, k3: 0.003, p1: 0.002, p2: 0.001, ..Default::default() };
        let (a, c) = (Distortion::Brown(b).apply(3.0, 4.0, 8.8), Distortion::Metashape(as_metashape).apply(3.0, 4.0, 8.8));
        assert!((a.0 - c.0).abs() < 1e-14 && (a.1 - c.1).abs() < 1e-14);
    }

    #[test]
    fn fisheye_maps_the_angle_from_the_axis() {
        // 30° off the axis with k1 = 0.1: θd = θ(1 + 0.1 θ²), on the image
        // f·θd from the principal point, on the ray's side.
        let k = Fisheye { k1: 0.1, ..Default::default() };
        let t = 30f64.to_radians();
        let (f, r) = (2.8, 2.8 * t.tan());
        let (x, y) = Distortion::Fisheye(k).apply(r * 0.6, r * 0.8, f);
        let want = f * t * (1.0 + 0.1 * t * t);
        assert!((x.hypot(y) - want).abs() < 1e-12 && (y / x - 0.8 / 0.6).abs() < 1e-12);
        // No fold without terms that turn θd back; with k1 = −0.3 it turns
        // where 1 − 0.9 θ² = 0.05, θ ≈ 1.027 rad.
        assert_eq!(Distortion::Fisheye(Fisheye::default()).fold_radius(f), f64::INFINITY);
        let fold = Distortion::Fisheye(Fisheye { k1: -0.3, ..Default::default() }).fold_radius(f);
        assert!(((fold / f).atan() - (0.95f64 / 0.9).sqrt()).abs() < 2e-3, "{}", (fold / f).atan());
    }
}
