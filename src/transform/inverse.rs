//! The other direction: which ground point on the DEM a scan pixel sees.
//! Used for the footprint of a scan (auto bounds, thesis 2.4.3–2.4.4) and by
//! the scene generator, which renders scans by casting every pixel's ray.
//! Newton's method on `project(X, Y, Z(X, Y)) = (col, row)` with the DEM's
//! gradient; the camera's partial derivatives are cached, since they change
//! slowly from one pixel to the next.

use crate::camera::SensorModel;
use crate::dem::Dem;
use nalgebra::{Matrix2, Vector2};

/// Casts rays from scan pixels onto the DEM.
pub struct RayCaster<'a> {
    pub model: &'a dyn SensorModel,
    pub dem: &'a Dem,
    /// d(col, row)/d(X, Y, Z) near `at`.
    partials: Option<([[f64; 3]; 2], (f64, f64))>,
    /// How far (ground units) the partials stay good: 5000 ground steps.
    stale_after: f64,
}

impl<'a> RayCaster<'a> {
    pub fn new(model: &'a dyn SensorModel, dem: &'a Dem) -> Self {
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
        let mut best: Option<([f64; 3], f64)> = None;
        let mut refreshed = false;
        for it in 0..30 {
            let (z, gx, gy) = self.dem.height_gradient(x, y)?;
            let (c, r) = self.model.project(x, y, z)?;
            let e = Vector2::new(col - c, row - r);
            let err = e.norm();
            if err < tol {
                // One more Newton step costs no projection: the answer is
                // then far inside the tolerance, and a neighbour's guess
                // extrapolated from it stays inside it too.
                if let Some(j) = self.partials.and_then(|(p, _)| jacobian(p, gx, gy).try_inverse()) {
                    let d = j * e;
                    return Some([x + d.x, y + d.y, z + gx * d.x + gy * d.y]);
                }
                return Some([x, y, z]);
            }
            if best.is_none_or(|b| err < b.1) {
                best = Some(([x, y, z], err));
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
            let step = jacobian(p, gx, gy).try_inverse()? * e;
            // Damp long steps: beyond a few pixels the cell's gradient says little.
            let scale = if it > 10 { 0.5 } else { 1.0 };
            x += scale * step.x;
            y += scale * step.y;
        }
        best.filter(|b| b.1 < 10.0 * tol.max(0.01)).map(|b| b.0)
    }
}

/// d(col, row)/d(X, Y) along the DEM surface: the model's partials in X, Y
/// and Z, with Z following the terrain's slope (gx, gy).
#[inline]
fn jacobian(p: [[f64; 3]; 2], gx: f64, gy: f64) -> Matrix2<f64> {
    Matrix2::new(p[0][0] + p[0][2] * gx, p[0][1] + p[0][2] * gy, p[1][0] + p[1][2] * gx, p[1][1] + p[1][2] * gy)
}

