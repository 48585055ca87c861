//! The other direction: which ground point on the DEM a scan pixel sees.
//! Used for the footprint of a scan (auto bounds, thesis 2.4.3–2.4.4) and by
//! the scene generator, which renders scans by casting every pixel's ray.
//! Newton's method on `project(X, Y, Z(X, Y)) = (col, row)` with the DEM's
//! gradient; the camera's partial derivatives are cached, since they change
//! slowly from one pixel to the next.

use crate::camera::SensorModel;
use crate::dem::Dem;

/// Casts rays from scan pixels onto the DEM. Generic over the sensor
/// model so that a caller that knows its model (the scene generator casts
/// one ray per scan pixel) gets `project` inlined; `dyn SensorModel` by
/// default.
pub struct RayCaster<'a, M: SensorModel + ?Sized = dyn SensorModel> {
    pub model: &'a M,
    pub dem: &'a Dem,
    /// d(col, row)/d(X, Y, Z) near `at`.
    partials: Option<([[f64; 3]; 2], (f64, f64))>,
    /// How far (ground units) the partials stay good: 5000 ground steps.
    stale_after: f64,
}

impl<'a, M: SensorModel + ?Sized> RayCaster<'a, M> {
    pub fn new(model: &'a M, dem: &'a Dem) -> Self {
        RayCaster { model, dem, partials: None, stale_after: 5000.0 * model.ground_step() }
    }

    fn partials_at(&self, x: f64, y: f64, z: f64) -> Option<[[f64; 3]; 2]> {
        let h = 5.0 * self.model.ground_step();
        let (c, r) = self.model.project(x, y, z)?;
        let (cx, rx) = self.model.project(x + h, y, z)?;
        let (cy, ry) = self.model.project(x, y + h, z)?;
        let (cz, rz) = self.model.project(x, y, z + h)?;
        Some([[(cx - c) / h, (cy - c) / h, (cz - c) / h], [(rx - r) / h, (ry - r) / h, (rz - r) / h]])
    }

    /// Ground (X, Y, Z) on the DEM imaged at (col, row), to `tol` pixels,
    /// starting from `guess` (a neighbouring pixel's answer) or from the
    /// model's own inverse at `z_guess`.
    pub fn cast(&mut self, col: f64, row: f64, guess: Option<(f64, f64)>, z_guess: f64, tol: f64) -> Option<[f64; 3]> {
        let (mut x, mut y) = match guess {
            Some(g) => g,
            None => self.model.locate_approx(col, row, z_guess)?,
        };
        // The error is compared squared (no square root per pixel).
        let tol2 = tol * tol;
        let mut best: Option<([f64; 3], f64)> = None;
        let mut refreshed = false;
        for it in 0..30 {
            let (z, gx, gy) = self.dem.height_gradient(x, y)?;
            let (c, r) = self.model.project(x, y, z)?;
            let e = (col - c, row - r);
            let err2 = e.0 * e.0 + e.1 * e.1;
            if err2 < tol2 {
                // One more Newton step costs no projection: the answer is
                // then far inside the tolerance, and a neighbour's guess
                // extrapolated from it stays inside it too.
                if let Some(d) = self.partials.and_then(|(p, _)| newton_step(p, gx, gy, e)) {
                    return Some([x + d.0, y + d.1, z + gx * d.0 + gy * d.1]);
                }
                return Some([x, y, z]);
            }
            if best.is_none_or(|b| err2 < b.1) {
                best = Some(([x, y, z], err2));
            }
            let stale = match self.partials {
                None => true,
                Some((_, at)) => (at.0 - x).abs() + (at.1 - y).abs() > self.stale_after,
            };
            if stale || (it > 4 && !refreshed) {
                self.partials = self.partials_at(x, y, z).map(|p| (p, (x, y)));
                refreshed = it > 4;
            }
            let (p, _) = self.partials?;
            let step = newton_step(p, gx, gy, e)?;
            // Damp long steps: beyond a few pixels the cell's gradient says little.
            let scale = if it > 10 { 0.5 } else { 1.0 };
            x += scale * step.0;
            y += scale * step.1;
        }
        let give_up = 10.0 * tol.max(0.01);
        best.filter(|b| b.1 < give_up * give_up).map(|b| b.0)
    }
}

/// The ground step (ΔX, ΔY) that moves the image point by `e` = (Δcol,
/// Δrow) along the DEM surface: `e` solved against the 2×2 Jacobian
/// d(col, row)/d(X, Y), whose Z column follows the terrain's slope (gx, gy).
/// `None` when the Jacobian is singular.
#[inline]
fn newton_step(p: [[f64; 3]; 2], gx: f64, gy: f64, e: (f64, f64)) -> Option<(f64, f64)> {
    let (a, b) = (p[0][0] + p[0][2] * gx, p[0][1] + p[0][2] * gy);
    let (c, d) = (p[1][0] + p[1][2] * gx, p[1][1] + p[1][2] * gy);
    let det = a * d - b * c;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv = 1.0 / det;
    Some(((d * e.0 - b * e.1) * inv, (a * e.1 - c * e.0) * inv))
}


#[cfg(test)]
mod tests {
    use super::newton_step;

    #[test]
    fn the_newton_step_solves_the_jacobian_along_the_slope() {
        // Partials d(col, row)/d(X, Y, Z) and a slope of 0.5 in X: the
        // Jacobian along the surface is [[2 + 0.5, 1], [1 + 0, 3]] (det 6.5),
        // so e = (1, 2) takes the step (1, 4) / 6.5.
        let p = [[2.0, 1.0, 1.0], [1.0, 3.0, 0.0]];
        let (dx, dy) = newton_step(p, 0.5, 0.0, (1.0, 2.0)).unwrap();
        assert!((dx - 1.0 / 6.5).abs() < 1e-15 && (dy - 4.0 / 6.5).abs() < 1e-15, "{dx} {dy}");
        // A slope that makes the two rows parallel leaves no step.
        assert_eq!(newton_step([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0]], 0.3, 0.1, (1.0, 1.0)), None);
    }
}
