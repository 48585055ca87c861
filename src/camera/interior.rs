//! Interior orientation: photo coordinates (mm, origin at the principal
//! point, x right, y up) ↔ scan pixels (column, row from the top-left
//! corner; continuous, pixel centres at +½ as in GDAL).
//!
//! Three forms (thesis §2.3, textbook 9.27–9.33):
//! * fiducials with calibrated coordinates: least-squares affine (n ≥ 3);
//! * fiducials with calibrated distances only (4 marks: 1→2 is the photo +x
//!   direction, 3→4 the photo +y direction): rotation γ, scales kx, ky and
//!   the origin at the intersection of the lines 1–2 and 3–4;
//! * digital frame: pixel size and principal point in pixels.

use crate::geom::Affine2;
use nalgebra::{Matrix2, Vector2};

/// Residual of one fiducial mark after the fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FiducialResidual {
    /// Measured minus fitted position, scan pixels (column, row).
    pub px: [f64; 2],
    /// The same residual in the photo system, micrometres.
    pub um: [f64; 2],
}

/// Photo mm ↔ scan pixel map.
#[derive(Clone, Debug)]
pub struct InteriorOrientation {
    /// Photo coordinates relative to the principal point → scan pixels.
    to_px: Affine2,
    to_mm: Affine2,
    /// Per-mark residuals (empty for digital cameras).
    pub residuals: Vec<FiducialResidual>,
}

/// Why an interior orientation could not be built.
#[derive(Debug, Clone, PartialEq)]
pub enum InteriorError {
    TooFewMarks(usize),
    MismatchedCounts(usize, usize),
    Degenerate(&'static str),
}

impl std::fmt::Display for InteriorError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            InteriorError::TooFewMarks(n) => write!(f, "needs at least 3 fiducial marks, got {n}"),
            InteriorError::MismatchedCounts(a, b) => {
                write!(f, "{a} calibrated marks but {b} measured positions")
            }
            InteriorError::Degenerate(why) => write!(f, "degenerate fiducials: {why}"),
        }
    }
}

impl InteriorOrientation {
    fn from_affine(to_px: Affine2, residuals: Vec<FiducialResidual>) -> Result<Self, InteriorError> {
        let to_mm = to_px.inverse().ok_or(InteriorError::Degenerate("the fitted map is singular"))?;
        Ok(InteriorOrientation { to_px, to_mm, residuals })
    }

    /// Form (a): calibrated fiducial coordinates (mm, fiducial system, y up),
    /// their measured scan positions, and the principal point's offset from
    /// the fiducial centre (mm).
    pub fn from_fiducials(fiducials_mm: &[[f64; 2]], fiducials_px: &[[f64; 2]], principal_point_mm: [f64; 2]) -> Result<Self, InteriorError> {
        if fiducials_mm.len() != fiducials_px.len() {
            return Err(InteriorError::MismatchedCounts(fiducials_mm.len(), fiducials_px.len()));
        }
        if fiducials_mm.len() < 3 {
            return Err(InteriorError::TooFewMarks(fiducials_mm.len()));
        }
        let fid = Affine2::fit(fiducials_mm, fiducials_px).ok_or(InteriorError::Degenerate("the marks lie on one line"))?;
        // Photo coordinates are relative to the principal point:
        // fiducial-system mm = photo mm + principal_point_mm.
        let pp = Vector2::new(principal_point_mm[0], principal_point_mm[1]);
        let to_px = Affine2 { m: fid.m, t: fid.t + fid.m * pp };
        let inv = fid.inverse().ok_or(InteriorError::Degenerate("the fitted map is singular"))?;
        let residuals = fiducials_mm
            .iter()
            .zip(fiducials_px)
            .map(|(mm, px)| {
                let (fx, fy) = fid.apply(mm[0], mm[1]);
                let r_px = [px[0] - fx, px[1] - fy];
                let (mx, my) = inv.apply(px[0], px[1]);
                FiducialResidual { px: r_px, um: [(mx - mm[0]) * 1e3, (my - mm[1]) * 1e3] }
            })
            .collect();
        Self::from_affine(to_px, residuals)
    }

    /// Form (b): calibrated distances `[lx, ly]` between opposite marks and
    /// four measured positions: 1→2 along photo +x, 3→4 along photo +y.
    pub fn from_fiducial_distances(distances_mm: [f64; 2], fiducials_px: &[[f64; 2]], principal_point_mm: [f64; 2]) -> Result<Self, InteriorError> {
        if fiducials_px.len() != 4 {
            return Err(InteriorError::MismatchedCounts(4, fiducials_px.len()));
        }
        // Work in a y-up scan frame s = (col, −row) so that rotations keep
        // their usual sense; flip back at the end.
        let s = |p: [f64; 2]| Vector2::new(p[0], -p[1]);
        let (p1, p2, p3, p4) = (s(fiducials_px[0]), s(fiducials_px[1]), s(fiducials_px[2]), s(fiducials_px[3]));
        let dx = p2 - p1;
        let dy = p4 - p3;
        if dx.norm() == 0.0 || dy.norm() == 0.0 {
            return Err(InteriorError::Degenerate("two opposite marks coincide"));
        }
        // γ from both axes (textbook 9.29 uses marks 1-2; the y axis gives a
        // second estimate 90° away; averaging halves the measuring error).
        let gx = dx.y.atan2(dx.x);
        let gy = dy.y.atan2(dy.x) - std::f64::consts::FRAC_PI_2;
        let dg = (gy - gx + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI;
        if dg.abs() > 0.1 {
            return Err(InteriorError::Degenerate("the lines 1-2 and 3-4 are not perpendicular"));
        }
        let gamma = gx + dg / 2.0;
        let kx = dx.norm() / distances_mm[0];
        let ky = dy.norm() / distances_mm[1];
        // Origin: intersection of line p1 + a·dx with line p3 + b·dy.
        let m = Matrix2::from_columns(&[dx, -dy]);
        let ab = m.try_inverse().ok_or(InteriorError::Degenerate("the lines 1-2 and 3-4 are parallel"))? * (p3 - p1);
        let origin = p1 + dx * ab.x;
        let (sg, cg) = gamma.sin_cos();
        // s = origin + kx·x·(cγ, sγ) + ky·y·(−sγ, cγ); px = (s.x, −s.y).
        let lin = Matrix2::new(kx * cg, -ky * sg, -(kx * sg), -(ky * cg));
        let fid = Affine2 { m: lin, t: Vector2::new(origin.x, -origin.y) };
        let pp = Vector2::new(principal_point_mm[0], principal_point_mm[1]);
        let to_px = Affine2 { m: fid.m, t: fid.t + fid.m * pp };
        // Residuals: where each mark should be at its calibrated position
        // (±lx/2 on x, ±ly/2 on y).
        let nominal = [[-distances_mm[0] / 2.0, 0.0], [distances_mm[0] / 2.0, 0.0], [0.0, -distances_mm[1] / 2.0], [0.0, distances_mm[1] / 2.0]];
        let inv = fid.inverse().ok_or(InteriorError::Degenerate("the fitted map is singular"))?;
        let residuals = nominal
            .iter()
            .zip(fiducials_px)
            .map(|(mm, px)| {
                let (fx, fy) = fid.apply(mm[0], mm[1]);
                let (mx, my) = inv.apply(px[0], px[1]);
                FiducialResidual { px: [px[0] - fx, px[1] - fy], um: [(mx - mm[0]) * 1e3, (my - mm[1]) * 1e3] }
            })
            .collect();
        Self::from_affine(to_px, residuals)
    }

    /// Form (c): a digital frame camera.
    pub fn digital(pixel_size_mm: f64, principal_point_px: [f64; 2]) -> Result<Self, InteriorError> {
        Self::digital_sides([pixel_size_mm, pixel_size_mm], principal_point_px)
    }

    /// Form (c) with pixels of other sizes across and down (OpenCV's
    /// fx ≠ fy: `fx = f / across`, `fy = f / down`).
    pub fn digital_sides([across, down]: [f64; 2], principal_point_px: [f64; 2]) -> Result<Self, InteriorError> {
        if !(across > 0.0 && down > 0.0) {
            return Err(InteriorError::Degenerate("pixel size must be positive"));
        }
        let to_px = Affine2 { m: Matrix2::new(1.0 / across, 0.0, 0.0, -1.0 / down), t: Vector2::new(principal_point_px[0], principal_point_px[1]) };
        Self::from_affine(to_px, Vec::new())
    }

    /// Form (c) with Metashape's affinity and skew `[b1, b2]` (pixels) for
    /// a focal length of `focal_mm`: column = cx + x'(f + b1) + y'·b2,
    /// row = cy + y'·f, with x', y' (right, down) on the normalised plane
    /// and f in pixels down.
    pub fn digital_affine([across, down]: [f64; 2], principal_point_px: [f64; 2], [b1, b2]: [f64; 2], focal_mm: f64) -> Result<Self, InteriorError> {
        if !(across > 0.0 && down > 0.0 && focal_mm > 0.0) {
            return Err(InteriorError::Degenerate("pixel size and focal length must be positive"));
        }
        // x' = x/f_mm, y' = −y/f_mm (y up in mm).
        let m = Matrix2::new(1.0 / across + b1 / focal_mm, -b2 / focal_mm, 0.0, -1.0 / down);
        if m.determinant().abs() < 1e-12 {
            return Err(InteriorError::Degenerate("the affinity leaves no area"));
        }
        Self::from_affine(Affine2 { m, t: Vector2::new(principal_point_px[0], principal_point_px[1]) }, Vec::new())
    }

    /// The same orientation with the principal point `d` pixels further
    /// (a calibration refined by resection).
    #[must_use]
    pub fn with_principal_point_moved(&self, d: [f64; 2]) -> Self {
        let mut to_px = self.to_px;
        to_px.t += Vector2::new(d[0], d[1]);
        let to_mm = to_px.inverse().expect("a translation keeps the map regular");
        InteriorOrientation { to_px, to_mm, residuals: self.residuals.clone() }
    }

    /// The principal point, pixels.
    #[must_use]
    pub fn principal_point_px(&self) -> [f64; 2] {
        [self.to_px.t.x, self.to_px.t.y]
    }

    /// Photo mm (relative to the principal point) → scan pixel.
    #[inline]
    pub fn mm_to_px(&self, x: f64, y: f64) -> (f64, f64) {
        self.to_px.apply(x, y)
    }

    /// Scan pixel → photo mm (relative to the principal point).
    #[inline]
    pub fn px_to_mm(&self, col: f64, row: f64) -> (f64, f64) {
        self.to_mm.apply(col, row)
    }

    /// The affine map photo mm → scan pixel.
    pub fn affine(&self) -> &Affine2 {
        &self.to_px
    }

    /// Mean scan pixel size in mm (geometric mean of the two axes).
    pub fn pixel_size_mm(&self) -> f64 {
        1.0 / self.to_px.m.determinant().abs().sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metashape_affinity_and_skew() {
        // f = 3000 px on 0.004 mm pixels (12 mm); x' = 0.1, y' = 0.2 (down):
        // u = cx + x'(f + b1) + y'·b2, v = cy + y'·f.
        let (f_mm, ps, b1, b2) = (12.0, 0.004, 0.5, -0.3);
        let io = InteriorOrientation::digital_affine([ps, ps], [2640.0, 1978.0], [b1, b2], f_mm).unwrap();
        let (u, v) = io.mm_to_px(0.1 * f_mm, -0.2 * f_mm);
        assert!((u - (2640.0 + 0.1 * (3000.0 + b1) + 0.2 * b2)).abs() < 1e-9, "{u}");
        assert!((v - (1978.0 + 0.2 * 3000.0)).abs() < 1e-9, "{v}");
    }

    /// A constructed flatbed scan: 0.3° rotation, 0.021/0.0212 mm pixels
    /// (x and y scales differ), photo centre at pixel (5000.5, 5010.25).
    fn scanner(x: f64, y: f64) -> [f64; 2] {
        let g = 0.3f64.to_radians();
        let (sx, sy) = (1.0 / 0.021, 1.0 / 0.0212);
        // y up in the photo, rows down in the scan.
        let c = 5000.5 + sx * x * g.cos() - sy * y * g.sin();
        let r = 5010.25 - (sx * x * g.sin() + sy * y * g.cos());
        [c, r]
    }

    #[test]
    fn fiducial_affine_recovers_constructed_scan() {
        let mm = [[-106.0, -106.0], [106.0, 106.0], [-106.0, 106.0], [106.0, -106.0]];
        let px: Vec<[f64; 2]> = mm.iter().map(|p| scanner(p[0], p[1])).collect();
        let io = InteriorOrientation::from_fiducials(&mm, &px, [0.0, 0.0]).unwrap();
        for (x, y) in [(0.0, 0.0), (50.0, -30.0), (-100.0, 80.0)] {
            let (c, r) = io.mm_to_px(x, y);
            let want = scanner(x, y);
            assert!((c - want[0]).abs() < 1e-9 && (r - want[1]).abs() < 1e-9);
            let (bx, by) = io.px_to_mm(c, r);
            assert!((bx - x).abs() < 1e-12 && (by - y).abs() < 1e-12);
        }
        for res in &io.residuals {
            assert!(res.px[0].abs() < 1e-9 && res.um[1].abs() < 1e-6);
        }
    }

    #[test]
    fn residuals_show_a_misplaced_mark() {
        let mm = [[-106.0, -106.0], [106.0, 106.0], [-106.0, 106.0], [106.0, -106.0]];
        let mut px: Vec<[f64; 2]> = mm.iter().map(|p| scanner(p[0], p[1])).collect();
        px[0][0] += 2.0; // 2 px error on mark 1
        let io = InteriorOrientation::from_fiducials(&mm, &px, [0.0, 0.0]).unwrap();
        // With four marks and six parameters the error spreads: ±0.5 px
        // on every mark (the residual vector is orthogonal to the affine span).
        for res in &io.residuals {
            assert!((res.px[0].abs() - 0.5).abs() < 1e-9, "{:?}", res);
        }
    }

    #[test]
    fn principal_point_offset_shifts_the_origin() {
        let mm = [[-106.0, -106.0], [106.0, 106.0], [-106.0, 106.0], [106.0, -106.0]];
        let px: Vec<[f64; 2]> = mm.iter().map(|p| scanner(p[0], p[1])).collect();
        let io = InteriorOrientation::from_fiducials(&mm, &px, [0.021, -0.0424]).unwrap();
        let (c, r) = io.mm_to_px(0.0, 0.0);
        let want = scanner(0.021, -0.0424);
        assert!((c - want[0]).abs() < 1e-9 && (r - want[1]).abs() < 1e-9);
    }

    #[test]
    fn distance_form_recovers_rotation_and_scales() {
        let (lx, ly) = (212.0, 211.0);
        let px = [scanner(-lx / 2.0, 0.0), scanner(lx / 2.0, 0.0), scanner(0.0, -ly / 2.0), scanner(0.0, ly / 2.0)];
        let io = InteriorOrientation::from_fiducial_distances([lx, ly], &px, [0.0, 0.0]).unwrap();
        for (x, y) in [(0.0, 0.0), (70.0, -30.0), (-100.0, 100.0)] {
            let (c, r) = io.mm_to_px(x, y);
            let want = scanner(x, y);
            assert!((c - want[0]).abs() < 1e-8 && (r - want[1]).abs() < 1e-8, "{c} {r} {want:?}");
        }
    }

    #[test]
    fn collinear_and_too_few_marks_are_rejected() {
        let mm = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]];
        assert!(matches!(InteriorOrientation::from_fiducials(&mm, &mm, [0.0, 0.0]), Err(InteriorError::Degenerate(_))));
        assert!(matches!(InteriorOrientation::from_fiducials(&mm[..2], &mm[..2], [0.0, 0.0]), Err(InteriorError::TooFewMarks(2))));
    }

    #[test]
    fn digital_camera_flips_y() {
        let io = InteriorOrientation::digital(0.005, [2000.0, 1500.0]).unwrap();
        assert_eq!(io.mm_to_px(1.0, 1.0), (2200.0, 1300.0));
    }
}
