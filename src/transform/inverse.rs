//! The other direction: which ground point on the DEM a scan pixel sees.
//! Used for the footprint of a scan (auto bounds, thesis 2.4.3–2.4.4) and by
//! the scene generator, which renders scans by casting every pixel's ray.
//! Newton's method on `project(X, Y, Z(X, Y)) = (col, row)` with the DEM's
//! gradient; the camera's partial derivatives are cached, since they change
//! slowly from one pixel to the next.

use crate::camera::SensorModel;
use crate::dem::Dem;

/// d(col, row)/d(X, Y, Z): the image's partial derivatives in the ground.
type Partials = [[f64; 3]; 2];

/// Casts rays from scan pixels onto the DEM. Generic over the sensor
/// model so that a caller that knows its model (the scene generator casts
/// one ray per scan pixel) gets `project` inlined; `dyn SensorModel` by
/// default.
pub struct RayCaster<'a, M: SensorModel + ?Sized = dyn SensorModel> {
    pub model: &'a M,
    pub dem: &'a Dem,
    /// d(col, row)/d(X, Y, Z) near `at`.
    partials: Option<(Partials, (f64, f64))>,
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

    /// Are there no partials, or were they taken too far from (x, y)?
    #[inline]
    fn partials_stale(&self, x: f64, y: f64) -> bool {
        match self.partials {
            None => true,
            Some((_, at)) => (at.0 - x).abs() + (at.1 - y).abs() > self.stale_after,
        }
    }

    /// A ground point `p` within the tolerance (image error `e`, terrain
    /// slope `slope` there) after one more Newton step, which costs no
    /// projection: the answer is then far inside the tolerance, and a
    /// neighbour's guess extrapolated from it stays inside it too.
    #[inline]
    fn polished(&self, [x, y, z]: [f64; 3], (gx, gy): (f64, f64), e: (f64, f64)) -> [f64; 3] {
        match self.partials.and_then(|(p, _)| newton_step(p, gx, gy, e)) {
            Some(d) => [x + d.0, y + d.1, z + gx * d.0 + gy * d.1],
            None => [x, y, z],
        }
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
                return Some(self.polished([x, y, z], (gx, gy), e));
            }
            if best.is_none_or(|b| err2 < b.1) {
                best = Some(([x, y, z], err2));
            }
            if self.partials_stale(x, y) || (it > 4 && !refreshed) {
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

/// Scratch arrays of `RayCaster::cast_run`, kept between calls.
#[derive(Default)]
pub struct RunScratch {
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
    height: Vec<(f64, f64, f64)>,
    col: Vec<f64>,
    row: Vec<f64>,
}

impl<M: SensorModel + ?Sized> RayCaster<'_, M> {
    /// Casts a run of pixels of scan row `row` at once, each from a guess
    /// good to a small fraction of a pixel (in the scene generator: the
    /// rays of the two rows above, extrapolated). Each pixel costs one DEM
    /// lookup, and the run one `project_many`; where the guess is within
    /// `tol` pixels, `out[k]` is the ground point after one more Newton
    /// step (as `cast` returns it), elsewhere `None`: the caller casts
    /// that pixel alone.
    pub fn cast_run(&mut self, cols: &[f64], row: f64, guess: &[(f64, f64)], tol: f64, out: &mut [Option<[f64; 3]>], s: &mut RunScratch) {
        let n = cols.len();
        assert!(guess.len() == n && out.len() == n, "cast_run: one guess and one answer per pixel");
        if n == 0 {
            return;
        }
        s.x.clear();
        s.y.clear();
        s.x.extend(guess.iter().map(|g| g.0));
        s.y.extend(guess.iter().map(|g| g.1));
        s.height.resize(n, (0.0, 0.0, 0.0));
        self.dem.height_gradient_many(&s.x, &s.y, &mut s.height);
        s.z.clear();
        s.z.extend(s.height.iter().map(|h| h.0));
        s.col.resize(n, 0.0);
        s.row.resize(n, 0.0);
        self.model.project_many(&s.x, &s.y, &s.z, &mut s.col, &mut s.row);
        // The partials near the middle of the run.
        let (mx, my, mz) = (s.x[n / 2], s.y[n / 2], s.z[n / 2]);
        if self.partials_stale(mx, my) && !mz.is_nan() {
            self.partials = self.partials_at(mx, my, mz).map(|p| (p, (mx, my)));
        }
        let tol2 = tol * tol;
        for k in 0..n {
            let e = (cols[k] - s.col[k], row - s.row[k]);
            // NaN (no height, not imaged) fails the test too.
            out[k] = if e.0 * e.0 + e.1 * e.1 < tol2 {
                let (_, gx, gy) = s.height[k];
                Some(self.polished([s.x[k], s.y[k], s.z[k]], (gx, gy), e))
            } else {
                None
            };
        }
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
    use super::{newton_step, RayCaster, RunScratch};
    use crate::camera::atmosphere::Refraction;
    use crate::camera::distortion::Distortion;
    use crate::camera::interior::InteriorOrientation;
    use crate::camera::rotation::AngleConvention;
    use crate::camera::{FrameCamera, SensorModel};
    use crate::dem::{Dem, GridDem};
    use nalgebra::Vector3;

    #[test]
    fn a_run_from_the_rows_above_finds_what_single_casts_find() {
        // A tilted film camera over hills posted every 5 m, ~0.1 m pixels.
        let io = InteriorOrientation::digital(0.012, [10000.0, 10000.0]).unwrap();
        let r = AngleConvention::AlphaOmegaKappa.matrix([0.01, -0.02, 0.5]);
        let cam = FrameCamera::new(152.0, Vector3::new(5000.0, 5000.0, 1600.0), r, io, Distortion::Radial([0.0, 1.5e-7, -2e-9]), Refraction::Auto, true);
        let n = 1000usize;
        let data = (0..n * n)
            .map(|k| {
                let (x, y) = ((k % n) as f64 * 5.0, (k / n) as f64 * 5.0);
                (300.0 + 40.0 * ((x / 310.0).sin() * (y / 270.0).cos())) as f32
            })
            .collect();
        let dem = Dem::grid(GridDem::new(n, n, data, [2500.0, 5.0, 0.0, 7500.0, 0.0, -5.0], None, None), std::path::Path::new("hills"));
        let mut caster = RayCaster::new(&cam, &dem);
        let cols: Vec<f64> = (0..600).map(|i| 4000.5 + i as f64).collect();
        let cast_row = |caster: &mut RayCaster<'_, FrameCamera>, r: f64| -> Vec<[f64; 3]> {
            cols.iter().map(|&c| caster.cast(c, r, None, 300.0, 1e-3).unwrap()).collect()
        };
        let (a, b) = (cast_row(&mut caster, 5000.5), cast_row(&mut caster, 5001.5));
        let guess: Vec<(f64, f64)> = a.iter().zip(&b).map(|(a, b)| (2.0 * b[0] - a[0], 2.0 * b[1] - a[1])).collect();
        let mut found = vec![None; cols.len()];
        caster.cast_run(&cols, 5002.5, &guess, 1e-3, &mut found, &mut RunScratch::default());
        let single = cast_row(&mut caster, 5002.5);
        let mut open = 0;
        for (k, f) in found.iter().enumerate() {
            let Some(p) = f else {
                open += 1;
                continue;
            };
            // On the DEM, imaged at its pixel, and where a single cast lands.
            let (c, r) = cam.project(p[0], p[1], p[2]).unwrap();
            assert!((c - cols[k]).hypot(r - 5002.5) < 1e-4, "{k}: {c} {r}");
            assert!((dem.height_gradient(p[0], p[1]).unwrap().0 - p[2]).abs() < 1e-6, "{k}");
            assert!((p[0] - single[k][0]).hypot(p[1] - single[k][1]) < 1e-3 * 0.12, "{k}");
        }
        // Only rays crossing a DEM cell's edge between the rows miss.
        assert!(open < cols.len() / 10, "{open} of {} left open", cols.len());
        // A guess a pixel off is left to the caller.
        let off: Vec<(f64, f64)> = guess.iter().map(|g| (g.0 + 0.12, g.1)).collect();
        caster.cast_run(&cols, 5002.5, &off, 1e-3, &mut found, &mut RunScratch::default());
        assert!(found.iter().all(Option::is_none));
    }

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
