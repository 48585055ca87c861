//! A 2-D affine map `p' = M p + t`, with least-squares estimation from point
//! pairs (used for fiducial interior orientation).

use nalgebra::{DMatrix, DVector, Matrix2, Vector2};

/// `p' = m * p + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Affine2 {
    pub m: Matrix2<f64>,
    pub t: Vector2<f64>,
}

impl Affine2 {
    pub fn identity() -> Self {
        Affine2 { m: Matrix2::identity(), t: Vector2::zeros() }
    }

    #[inline]
    #[must_use]
    pub fn apply(&self, x: f64, y: f64) -> (f64, f64) {
        (self.m[(0, 0)] * x + self.m[(0, 1)] * y + self.t.x, self.m[(1, 0)] * x + self.m[(1, 1)] * y + self.t.y)
    }

    /// The inverse map, `None` when the linear part is singular.
    #[must_use]
    pub fn inverse(&self) -> Option<Affine2> {
        let det = self.m.determinant();
        if !det.is_finite() || det.abs() < 1e-300 {
            return None;
        }
        let mi = self.m.try_inverse()?;
        Some(Affine2 { m: mi, t: -(mi * self.t) })
    }

    /// Least-squares affine map taking `from[i]` to `to[i]` (n ≥ 3, not all on
    /// one line). Returns `None` for degenerate configurations.
    #[must_use]
    pub fn fit(from: &[[f64; 2]], to: &[[f64; 2]]) -> Option<Affine2> {
        let n = from.len();
        if n < 3 || to.len() != n {
            return None;
        }
        // Centre the source points for a well-conditioned system.
        let cx = from.iter().map(|p| p[0]).sum::<f64>() / n as f64;
        let cy = from.iter().map(|p| p[1]).sum::<f64>() / n as f64;
        let spread = from.iter().map(|p| (p[0] - cx).hypot(p[1] - cy)).fold(0.0, f64::max);
        if spread == 0.0 {
            return None;
        }
        let mut a = DMatrix::<f64>::zeros(n, 3);
        let mut bx = DVector::<f64>::zeros(n);
        let mut by = DVector::<f64>::zeros(n);
        for i in 0..n {
            a[(i, 0)] = (from[i][0] - cx) / spread;
            a[(i, 1)] = (from[i][1] - cy) / spread;
            a[(i, 2)] = 1.0;
            bx[i] = to[i][0];
            by[i] = to[i][1];
        }
        // Collinear points make the normal matrix singular: reject by its
        // smallest singular value relative to the largest.
        let svd = a.clone().svd(false, false);
        let smax = svd.singular_values.max();
        let smin = svd.singular_values.min();
        if smin <= 1e-9 * smax {
            return None;
        }
        let ata = a.transpose() * &a;
        let chol = ata.cholesky()?;
        let sx = chol.solve(&(a.transpose() * bx));
        let sy = chol.solve(&(a.transpose() * by));
        let m = Matrix2::new(sx[0], sx[1], sy[0], sy[1]) / spread;
        let t = Vector2::new(sx[2], sy[2]) - m * Vector2::new(cx, cy);
        Some(Affine2 { m, t })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_recovers_known_map_and_inverse() {
        let truth = Affine2 { m: Matrix2::new(2.0, 0.1, -0.2, 1.5), t: Vector2::new(10.0, -3.0) };
        let from = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [3.0, 4.0]];
        let to: Vec<[f64; 2]> = from
            .iter()
            .map(|p| {
                let (x, y) = truth.apply(p[0], p[1]);
                [x, y]
            })
            .collect();
        let fit = Affine2::fit(&from, &to).unwrap();
        assert!((fit.m - truth.m).norm() < 1e-12);
        assert!((fit.t - truth.t).norm() < 1e-12);
        let inv = fit.inverse().unwrap();
        let (x, y) = inv.apply(13.0, 4.0);
        let (bx, by) = fit.apply(x, y);
        assert!((bx - 13.0).abs() < 1e-12 && (by - 4.0).abs() < 1e-12);
    }

    #[test]
    fn fit_rejects_collinear_points() {
        let from = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]];
        assert!(Affine2::fit(&from, &from).is_none());
    }
}
