//! Multilevel B-spline approximation of scattered data (Lee, Wolberg and
//! Shin, 1997), as Chibunichev and Sonyushkin use it to fill the
//! "dead-zone" nodes of their grid: a hierarchy of uniform cubic B-spline lattices, each coarse level
//! fitted to the data (the BA algorithm: every point pulls its 4×4 control
//! points by w/Σw²), each finer level fitted to what the coarser ones left.

/// One cubic B-spline control lattice over `[0, 1]²`, `n × n` cells
/// ((n + 3)² control points).
struct Lattice {
    n: usize,
    phi: Vec<f64>,
}

/// The four uniform cubic B-spline basis functions at `t ∈ [0, 1)`.
fn basis(t: f64) -> [f64; 4] {
    let s = 1.0 - t;
    [s * s * s / 6.0, (3.0 * t * t * t - 6.0 * t * t + 4.0) / 6.0, (-3.0 * t * t * t + 3.0 * t * t + 3.0 * t + 1.0) / 6.0, t * t * t / 6.0]
}

impl Lattice {
    /// Cell index and basis weights of a coordinate in [0, 1].
    fn locate(&self, u: f64) -> (usize, [f64; 4]) {
        let x = (u.clamp(0.0, 1.0) * self.n as f64).min(self.n as f64 - 1e-9);
        let i = x.floor() as usize;
        (i, basis(x - i as f64))
    }

    fn eval(&self, u: f64, v: f64) -> f64 {
        let (i, bu) = self.locate(u);
        let (j, bv) = self.locate(v);
        let m = self.n + 3;
        let mut s = 0.0;
        for (l, wv) in bv.iter().enumerate() {
            for (k, wu) in bu.iter().enumerate() {
                s += wu * wv * self.phi[(j + l) * m + i + k];
            }
        }
        s
    }

    /// The BA fit of `values` at `points` (in [0, 1]²).
    fn fit(n: usize, points: &[(f64, f64)], values: &[f64]) -> Lattice {
        let m = n + 3;
        let mut num = vec![0.0; m * m];
        let mut den = vec![0.0; m * m];
        let mut lat = Lattice { n, phi: vec![0.0; m * m] };
        for (&(u, v), &z) in points.iter().zip(values) {
            let (i, bu) = lat.locate(u);
            let (j, bv) = lat.locate(v);
            let mut w2 = 0.0;
            for wv in bv {
                for wu in bu {
                    w2 += (wu * wv) * (wu * wv);
                }
            }
            if w2 == 0.0 {
                continue;
            }
            for (l, wv) in bv.iter().enumerate() {
                for (k, wu) in bu.iter().enumerate() {
                    let w = wu * wv;
                    let idx = (j + l) * m + i + k;
                    num[idx] += w * w * (w * z / w2);
                    den[idx] += w * w;
                }
            }
        }
        for k in 0..m * m {
            if den[k] > 0.0 {
                lat.phi[k] = num[k] / den[k];
            }
        }
        lat
    }
}

/// A fitted multilevel B-spline: the sum of its levels.
pub struct Mba {
    levels: Vec<Lattice>,
}

impl Mba {
    /// Fits `values` at `points` (both coordinates in [0, 1]) with lattices
    /// of 1, 2, 4, … cells a side up to `finest` cells.
    pub fn fit(points: &[(f64, f64)], values: &[f64], finest: usize) -> Mba {
        let mut residual = values.to_vec();
        let mut levels = Vec::new();
        let mut n = 1;
        while n <= finest.max(1) {
            let lat = Lattice::fit(n, points, &residual);
            for (r, &(u, v)) in residual.iter_mut().zip(points) {
                *r -= lat.eval(u, v);
            }
            levels.push(lat);
            n *= 2;
        }
        Mba { levels }
    }

    pub fn eval(&self, u: f64, v: f64) -> f64 {
        self.levels.iter().map(|l| l.eval(u, v)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_smooth_surface_is_reproduced_between_its_samples() {
        let f = |u: f64, v: f64| (3.0 * u).sin() + (2.0 * v).cos() * u;
        let mut pts = Vec::new();
        for j in 0..=20 {
            for i in 0..=20 {
                // A hole in the middle, as dead zones leave.
                if (8..=12).contains(&i) && (8..=12).contains(&j) {
                    continue;
                }
                pts.push((i as f64 / 20.0, j as f64 / 20.0));
            }
        }
        let vals: Vec<f64> = pts.iter().map(|&(u, v)| f(u, v)).collect();
        let m = Mba::fit(&pts, &vals, 32);
        for (&(u, v), &z) in pts.iter().zip(&vals) {
            assert!((m.eval(u, v) - z).abs() < 5e-3, "at data ({u}, {v}): {} vs {z}", m.eval(u, v));
        }
        // Inside the hole (a quarter of the domain wide), the surface is
        // still followed to a few hundredths.
        assert!((m.eval(0.5, 0.5) - f(0.5, 0.5)).abs() < 0.05, "{} vs {}", m.eval(0.5, 0.5), f(0.5, 0.5));
    }
}
