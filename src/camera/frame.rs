//! The frame camera: ground (X east, Y north, Z up; metres) → scan pixel by
//! the collinearity equations (thesis 2.4.2 with the DEM height, 2.4.12)
//! followed by refraction, lens distortion and the interior orientation.
//! Earth curvature is applied to the ground point first.

use super::atmosphere::{curvature_drop, Refraction};
use super::distortion::Distortion;
use super::interior::InteriorOrientation;
use super::lanes::Lanes;
use super::SensorModel;
use crate::geom::Plane;
use crate::geom::{ImageArea, OutputGrid};
use nalgebra::{Matrix3, Vector3};
use wide::f64x2;

#[derive(Clone, Debug)]
pub struct FrameCamera {
    /// Focal length, mm.
    pub focal_mm: f64,
    /// Projection centre (Xs, Ys, Zs), ground CRS, metres.
    pub centre: Vector3<f64>,
    /// Photo → ground rotation (see `rotation`).
    pub r: Matrix3<f64>,
    pub interior: InteriorOrientation,
    pub distortion: Distortion,
    pub refraction: Refraction,
    pub earth_curvature: bool,
    /// Photo coordinates of the nadir point (mm), where refraction is radial from.
    nadir_mm: (f64, f64),
    /// Ideal radius (mm) past which the lens model folds back: points there
    /// are not imaged (nodata), never mirrored into the image.
    fold_mm: f64,
    /// The calibrated format on the film (scan pixels), where the scan
    /// holds more than the image (film margins): [`FrameCamera::with_format`].
    area: Option<ImageArea>,
}

impl FrameCamera {
    pub fn new(
        focal_mm: f64,
        centre: Vector3<f64>,
        r: Matrix3<f64>,
        interior: InteriorOrientation,
        distortion: Distortion,
        refraction: Refraction,
        earth_curvature: bool,
    ) -> Self {
        let q = r.transpose() * Vector3::new(0.0, 0.0, -1.0);
        let nadir_mm = (-focal_mm * q.x / q.z, -focal_mm * q.y / q.z);
        let fold_mm = distortion.fold_radius(focal_mm);
        FrameCamera { focal_mm, centre, r, interior, distortion, refraction, earth_curvature, nadir_mm, fold_mm, area: None }
    }

    /// Limits the image to the calibrated format: a `w × h` mm rectangle
    /// centred on the fiducial centre (the origin of the fiducial
    /// coordinates, `principal_point_mm` away from the principal point).
    /// `None` where the interior orientation makes it degenerate.
    pub fn with_format(mut self, [w, h]: [f64; 2], principal_point_mm: [f64; 2]) -> Option<Self> {
        let at = |x: f64, y: f64| self.interior.mm_to_px(x - principal_point_mm[0], y - principal_point_mm[1]);
        let p0 = at(-w / 2.0, -h / 2.0);
        let (pu, pv) = (at(w / 2.0, -h / 2.0), at(-w / 2.0, h / 2.0));
        self.area = Some(ImageArea::parallelogram(p0, (pu.0 - p0.0, pu.1 - p0.1), (pv.0 - p0.0, pv.1 - p0.1))?);
        Some(self)
    }

    /// This camera limited to `other`'s format on the scan, if it has one.
    pub fn with_area_of(mut self, other: &FrameCamera) -> Self {
        self.area = other.area;
        self
    }

    /// Checks, before any footprint is sought, that this camera can see
    /// the ground of an image of `w`×`h` pixels at height `ground_z`: its
    /// principal point in the image, a focal length that gives a field of
    /// view, the axis below the horizon, the centre above the ground. Each
    /// has its own message naming the camera file.
    pub fn check_sees_ground(&self, w: u32, h: u32, ground_z: f64, path: &std::path::Path) -> crate::error::Result<()> {
        use crate::error::Error;
        let (w, h) = (w as f64, h as f64);
        let (pc, pr) = self.interior.mm_to_px(0.0, 0.0);
        if !(pc > -0.5 * w && pc < 1.5 * w && pr > -0.5 * h && pr < 1.5 * h) {
            return Err(Error::config(path, "interior", format!("the principal point falls at pixel ({pc:.0}, {pr:.0}), far outside the {w}×{h} image")));
        }
        // A lens model that folds back inside the image would leave all
        // past the fold unimaged (k1 = 1e6: a disc of a few pixels): terms
        // in the wrong unit or sign, not a lens. (A circular fisheye's
        // circle reaches the nearest edge; its model may fold beyond it.)
        if self.fold_mm.is_finite() {
            let (dx, dy) = self.distortion.apply(self.fold_mm, 0.0, self.focal_mm);
            let (fc, fr) = self.interior.mm_to_px(dx, dy);
            let reach = (fc - pc).hypot(fr - pr);
            let edge = pc.min(w - pc).min(pr).min(h - pr);
            if reach < 0.9 * edge {
                return Err(Error::config(
                    path,
                    "distortion",
                    format!(
                        "the lens model folds back {reach:.0} px from the principal point, inside the image (its nearest edge is {edge:.0} px away), so nothing past it is imaged: these terms are not this lens's (their unit or sign?)"
                    ),
                ));
            }
        }
        // Terms that shrink the view many times (k1 = 1e6: the whole image
        // within half a degree of the axis) are not a lens's either: real
        // ones move a point by tens of per cent, a fisheye outward.
        let edge = pc.min(w - pc).min(pr).min(h - pr);
        let (ex, ey) = self.interior.px_to_mm(pc + edge, pr);
        let distorted = ex.hypot(ey);
        // The ideal radius imaged at the edge, found from the axis out
        // (the model grows up to its fold; past it lie other roots).
        let along = |t: f64| {
            let (x, y) = self.distortion.apply(t * ex / distorted, t * ey / distorted, self.focal_mm);
            x.hypot(y)
        };
        let (mut lo, mut hi) = (0.0, if self.fold_mm.is_finite() { self.fold_mm } else { 4.0 * self.focal_mm });
        if distorted > 0.0 && along(hi) >= distorted {
            for _ in 0..100 {
                let mid = 0.5 * (lo + hi);
                if along(mid) < distorted {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let ideal = 0.5 * (lo + hi);
            if ideal < distorted / 3.0 {
                return Err(Error::config(
                    path,
                    "distortion",
                    format!(
                        "the lens terms put the image's nearest edge {:.2}° off the axis, where its focal length puts it {:.1}°: these terms are not this lens's (their unit or sign?)",
                        (ideal / self.focal_mm).atan().to_degrees(),
                        (distorted / self.focal_mm).atan().to_degrees()
                    ),
                ));
            }
        }
        let (x0, y0) = self.interior.px_to_mm(0.0, 0.0);
        let (x1, y1) = self.interior.px_to_mm(w, h);
        let diagonal = (x1 - x0).hypot(y1 - y0);
        let fov = 2.0 * (diagonal / 2.0 / self.focal_mm).atan().to_degrees();
        if !(self.focal_mm > 0.0 && (0.2..=175.0).contains(&fov)) {
            // No field of view, and an image a metre across (the largest
            // film frame is 230 mm a side): a pixel size in the wrong unit
            // (µm given as mm), not a lens. (Lenses in pixel units, whose
            // "mm" are pixels, have a field of view and never come here.)
            if diagonal > 1000.0 {
                return Err(Error::config(
                    path,
                    "interior",
                    format!(
                        "the {w}×{h} image is {:.1} m across at this pixel size, a field of view of {fov:.2}° with a {} mm lens: pixel_size_mm is in millimetres (a 32 µm pixel is 0.032)",
                        diagonal / 1000.0,
                        self.focal_mm
                    ),
                ));
            }
            return Err(Error::config(
                path,
                "camera.focal_length_mm",
                format!("{} mm across the image's {diagonal:.1} mm diagonal is a field of view of {fov:.2}°: not this image's lens", crate::error::short_number(self.focal_mm)),
            ));
        }
        let axis = self.r * Vector3::new(0.0, 0.0, -1.0);
        if !(axis.z < 0.0) {
            let off_nadir = (-axis.z).clamp(-1.0, 1.0).acos().to_degrees();
            return Err(Error::config(
                path,
                "exterior.angles_deg",
                format!("the camera looks {off_nadir:.0}° away from straight down, at or above the horizon: check the angles and their convention"),
            ));
        }
        if !(self.centre.z > ground_z) {
            return Err(Error::config(
                path,
                "exterior.position",
                format!("the projection centre is at {:.1} m, not above the ground ({ground_z:.1} m)", self.centre.z),
            ));
        }
        Ok(())
    }

    /// Ground point → ideal photo point (mm from the principal point, y up),
    /// before refraction and distortion. `None` behind the camera.
    #[inline]
    pub fn collinearity(&self, x: f64, y: f64, z: f64) -> Option<(f64, f64)> {
        let (px, py) = self.ideal_photo(x, y, z);
        (!px.is_nan()).then_some((px, py))
    }

    /// `collinearity` with NaN behind the camera, without a branch.
    #[inline(always)]
    fn ideal_photo(&self, x: f64, y: f64, z: f64) -> (f64, f64) {
        let dx = x - self.centre.x;
        let dy = y - self.centre.y;
        let mut dz = z - self.centre.z;
        if self.earth_curvature {
            dz -= curvature_drop(dx * dx + dy * dy);
        }
        let p = self.r.tr_mul(&Vector3::new(dx, dy, dz));
        let s = -self.focal_mm / p.z;
        if p.z < 0.0 {
            (p.x * s, p.y * s)
        } else {
            (f64::NAN, f64::NAN)
        }
    }

    /// Refraction moves the photo point (x, y) of ground point `ground`
    /// away from the nadir point; `per_tan` is λ / tanζ there.
    #[inline(always)]
    fn refracted<T: Lanes>(&self, x: T, y: T, ground: (T, T, T), per_tan: T) -> (T, T) {
        let dx = ground.0 - T::splat(self.centre.x);
        let dy = ground.1 - T::splat(self.centre.y);
        let h = T::splat(self.centre.z) - ground.2;
        let (ex, ey) = (x - T::splat(self.nadir_mm.0), y - T::splat(self.nadir_mm.1));
        let e2 = ex * ex + ey * ey;
        // Δr = λ·f·(1 + tan²ζ) along the radius e from the nadir, with
        // λ = tanζ·per_tan and tanζ = D/h. The point moves by
        // k = Δr/e = per_tan·f·(1 + D²/h²)·D/(h·e), taken here with one
        // division, q = 1/(h⁴e²), and one square root.
        let (d2, h2) = (dx * dx + dy * dy, h * h);
        let q = T::splat(1.0) / (h2 * h2 * e2);
        let one_plus_tan2 = (h2 + d2) * (q * h2 * e2);
        let tan_over_e = (d2 * q * h2).sqrt();
        let k = per_tan * T::splat(self.focal_mm) * one_plus_tan2 * tan_over_e;
        // Only in front of a ground point below the camera, off the nadir.
        let zero = T::splat(0.0);
        let k = T::if_greater(h, zero, T::if_greater(e2, zero, k, zero), zero);
        (x + k * ex, y + k * ey)
    }

    /// Ideal photo point → photo point with refraction and distortion.
    #[inline]
    fn photo_corrections(&self, x: f64, y: f64, ground: (f64, f64, f64)) -> (f64, f64) {
        let (mut x, mut y) = (x, y);
        if self.refraction != Refraction::None {
            let per_tan = self.refraction.angle_per_tan(self.centre.z, ground.2);
            (x, y) = self.refracted(x, y, ground, per_tan);
        }
        self.distortion.apply(x, y, self.focal_mm)
    }

    /// The refraction pass of `project_many`, with λ / tanζ from `per_tan`
    /// (any formula, one point at a time).
    #[inline(always)]
    fn refract_all(&self, g: [&[f64]; 3], col: &mut [f64], row: &mut [f64], per_tan: impl Fn(f64) -> f64) {
        let n = col.len().min(row.len()).min(g[0].len()).min(g[1].len()).min(g[2].len());
        for k in 0..n {
            let ground = (g[0][k], g[1][k], g[2][k]);
            (col[k], row[k]) = self.refracted(col[k], row[k], ground, per_tan(ground.2));
        }
    }

    /// The refraction pass of `project_many` with Aschenbrenner's formula,
    /// two points at a time.
    fn refract_all_aschenbrenner(&self, g: [&[f64]; 3], col: &mut [f64], row: &mut [f64]) {
        let n = col.len().min(row.len()).min(g[0].len()).min(g[1].len()).min(g[2].len());
        let ha = f64x2::splat(self.centre.z);
        let pair = |v: &[f64], k: usize| f64x2::new([v[k], v[k + 1]]);
        for k in (0..n / 2).map(|i| 2 * i) {
            let ground = (pair(g[0], k), pair(g[1], k), pair(g[2], k));
            let per_tan = Refraction::aschenbrenner_per_tan(ha, ground.2);
            let (x, y) = self.refracted(pair(col, k), pair(row, k), ground, per_tan);
            let (x, y) = (x.to_array(), y.to_array());
            (col[k], col[k + 1], row[k], row[k + 1]) = (x[0], x[1], y[0], y[1]);
        }
        if n % 2 == 1 {
            let k = n - 1;
            let per_tan = Refraction::aschenbrenner_per_tan(self.centre.z, g[2][k]);
            (col[k], row[k]) = self.refracted(col[k], row[k], (g[0][k], g[1][k], g[2][k]), per_tan);
        }
    }
}

impl SensorModel for FrameCamera {
    fn image_area(&self) -> Option<ImageArea> {
        self.area
    }

    #[inline]
    fn project(&self, x: f64, y: f64, z: f64) -> Option<(f64, f64)> {
        let (px, py) = self.collinearity(x, y, z)?;
        if !(px * px + py * py <= self.fold_mm * self.fold_mm) {
            return None;
        }
        let (px, py) = self.photo_corrections(px, py, (x, y, z));
        Some(self.interior.mm_to_px(px, py))
    }

    /// In passes over the arrays (collinearity, refraction, distortion,
    /// interior orientation), each without a branch per point, so that the
    /// compiler works on two points per instruction; the numbers are
    /// exactly those of `project`.
    fn project_many(&self, x: &[f64], y: &[f64], z: &[f64], col: &mut [f64], row: &mut [f64]) {
        let n = x.len();
        assert!(y.len() == n && z.len() == n && col.len() == n && row.len() == n, "project_many: arrays of one length");
        for k in 0..n {
            (col[k], row[k]) = self.ideal_photo(x[k], y[k], z[k]);
        }
        // Past the fold the lens model turns back: not imaged.
        if self.fold_mm.is_finite() {
            let fold2 = self.fold_mm * self.fold_mm;
            for (c, r) in col.iter_mut().zip(row.iter_mut()) {
                if !(*c * *c + *r * *r <= fold2) {
                    (*c, *r) = (f64::NAN, f64::NAN);
                }
            }
        }
        let ha = self.centre.z;
        match self.refraction {
            Refraction::None => {}
            r if r.is_aschenbrenner_at(ha) => self.refract_all_aschenbrenner([x, y, z], col, row),
            r => self.refract_all([x, y, z], col, row, |hg| r.angle_per_tan(ha, hg)),
        }
        let f = self.focal_mm;
        match self.distortion {
            Distortion::None => {}
            Distortion::Radial(b) => {
                let (pairs, rows) = (col.chunks_exact_mut(2), row.chunks_exact_mut(2));
                for (c, r) in pairs.zip(rows) {
                    let (x, y) = Distortion::radial(b, f64x2::new([c[0], c[1]]), f64x2::new([r[0], r[1]]));
                    c.copy_from_slice(&x.to_array());
                    r.copy_from_slice(&y.to_array());
                }
                if n % 2 == 1 {
                    (col[n - 1], row[n - 1]) = Distortion::radial(b, col[n - 1], row[n - 1]);
                }
            }
            Distortion::Brown(b) => {
                for k in 0..n {
                    (col[k], row[k]) = Distortion::brown(&b, col[k], row[k], f);
                }
            }
            Distortion::OpenCv(o) => {
                for k in 0..n {
                    (col[k], row[k]) = Distortion::opencv(&o, col[k], row[k], f);
                }
            }
            Distortion::Fisheye(o) => {
                for k in 0..n {
                    (col[k], row[k]) = Distortion::fisheye(&o, col[k], row[k], f);
                }
            }
            Distortion::Metashape(m) => {
                for k in 0..n {
                    (col[k], row[k]) = Distortion::metashape(&m, col[k], row[k], f);
                }
            }
        }
        for k in 0..n {
            (col[k], row[k]) = self.interior.mm_to_px(col[k], row[k]);
        }
    }

    /// Through the lens model's inverse (a fisheye moves the corners by
    /// hundreds of pixels), refraction left out.
    fn locate_approx(&self, col: f64, row: f64, z: f64) -> Option<(f64, f64)> {
        let (x, y) = self.interior.px_to_mm(col, row);
        let (x, y) = self.distortion.remove(x, y, self.focal_mm).unwrap_or((x, y));
        let d = self.r * Vector3::new(x, y, -self.focal_mm);
        if d.z.abs() < 1e-12 {
            return None;
        }
        let t = (z - self.centre.z) / d.z;
        if !(t > 0.0) {
            return None;
        }
        Some((self.centre.x + t * d.x, self.centre.y + t * d.y))
    }

    /// Exact for collinearity + interior orientation on the plane: the ground
    /// point of output pixel (u, v) is affine in (u, v), so scan = H·(u, v, 1).
    fn plane_homography(&self, grid: &OutputGrid, plane: &Plane) -> Option<Matrix3<f64>> {
        // (ΔX, ΔY, ΔZ) as an affine function of (u, v, 1). Earth curvature is
        // left to the GCM (it is quadratic).
        let (gx, gy) = (grid.gsd.x, grid.gsd.y);
        let cx = grid.x0 - self.centre.x;
        let cy = grid.y0 - self.centre.y;
        let l = Matrix3::new(gx, 0.0, cx, 0.0, -gy, cy, plane.b * gx, -plane.c * gy, plane.a + plane.b * grid.x0 + plane.c * grid.y0 - self.centre.z);
        let f = self.focal_mm;
        // Photo (x, y, w) homogeneous = (−f p.x, −f p.y, p.z) with p = Rᵀ L (u, v, 1).
        let k = Matrix3::new(-f, 0.0, 0.0, 0.0, -f, 0.0, 0.0, 0.0, 1.0);
        let a = self.interior.affine();
        let aff = Matrix3::new(a.m[(0, 0)], a.m[(0, 1)], a.t.x, a.m[(1, 0)], a.m[(1, 1)], a.t.y, 0.0, 0.0, 1.0);
        Some(aff * k * self.r.transpose() * l)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::rotation::AngleConvention;

    fn vertical(centre: Vector3<f64>) -> FrameCamera {
        let io = InteriorOrientation::digital(0.01, [5000.0, 5000.0]).unwrap();
        FrameCamera::new(150.0, centre, Matrix3::identity(), io, Distortion::None, Refraction::None, false)
    }

    #[test]
    fn ground_past_the_lens_models_fold_is_not_imaged_never_mirrored() {
        // k1 = -0.3: r(1 - 0.3 r²) turns back at r = 1/√0.9 ≈ 1.054 (slope
        // 1 - 0.9 r² reaches 0.05 at r ≈ 1.027 focal lengths).
        let b = crate::camera::distortion::Brown { k1: -0.3, k2: 0.0, k3: 0.0, p1: 0.0, p2: 0.0 };
        let io = InteriorOrientation::digital(0.01, [5000.0, 5000.0]).unwrap();
        let cam = FrameCamera::new(50.0, Vector3::new(0.0, 0.0, 1000.0), Matrix3::identity(), io, Distortion::Brown(b), Refraction::None, false);
        let fold = Distortion::Brown(b).fold_radius(50.0) / 50.0;
        assert!((fold - 1.027).abs() < 0.002, "{fold}");
        // Ground at 0.9 and 1.3 focal lengths from the nadir (1000 m below):
        // the first is imaged, the second would fold back to r = 0.64, on
        // the first's side of it — inside the image — and is not.
        let near = cam.project(900.0, 0.0, 0.0).unwrap();
        assert!(near.0 > 5000.0);
        let r_folded = 1.3 * (1.0 - 0.3 * 1.69);
        assert!(r_folded < 0.9 * (1.0 - 0.3 * 0.81), "the fold would mirror it inside");
        assert_eq!(cam.project(1300.0, 0.0, 0.0), None);
        let (mut c, mut r) = ([0.0; 2], [0.0; 2]);
        cam.project_many(&[900.0, 1300.0], &[0.0, 0.0], &[0.0, 0.0], &mut c, &mut r);
        assert_eq!((c[0], r[0]), near);
        assert!(c[1].is_nan() && r[1].is_nan());
    }

    /// Lens terms that fold back inside the image, or shrink its view many
    /// times, are refused by name; a lens whose fold lies past the image
    /// (and a barrel of tens of per cent) is not.
    #[test]
    fn lens_terms_that_fold_inside_the_image_or_shrink_it_are_refused() {
        let camera = |d: Distortion| {
            let io = InteriorOrientation::digital(0.01, [5000.0, 5000.0]).unwrap();
            FrameCamera::new(50.0, Vector3::new(0.0, 0.0, 1000.0), Matrix3::identity(), io, d, Refraction::None, false)
        };
        let brown = |k1: f64| Distortion::Brown(crate::camera::distortion::Brown { k1, k2: 0.0, k3: 0.0, p1: 0.0, p2: 0.0 });
        let path = std::path::Path::new("cam.toml");
        // The 10000 px image reaches 1 focal length from its centre. k1 =
        // -0.1 folds at 1.78 focal lengths, its image there 1.22 out: past
        // the edge. k1 = -0.3 folds where its image is 0.70 out, and k1 = -3
        // at 0.22: inside.
        camera(brown(-0.1)).check_sees_ground(10_000, 10_000, 0.0, path).unwrap();
        assert!(camera(brown(-0.3)).check_sees_ground(10_000, 10_000, 0.0, path).is_err());
        let e = camera(brown(-3.0)).check_sees_ground(10_000, 10_000, 0.0, path).unwrap_err().to_string();
        assert!(e.starts_with("cam.toml: distortion: the lens model folds back") && e.contains("inside the image"), "{e}");
        let fisheye = |k1: f64, k2: f64| Distortion::Fisheye(crate::camera::distortion::Fisheye { k1, k2, k3: 0.0, k4: 0.0 });
        camera(fisheye(-0.05, 0.01)).check_sees_ground(10_000, 10_000, 0.0, path).unwrap();
        let e = camera(fisheye(1e6, -1e6)).check_sees_ground(10_000, 10_000, 0.0, path).unwrap_err().to_string();
        assert!(e.starts_with("cam.toml: distortion: the lens terms put the image's nearest edge"), "{e}");
    }

    #[test]
    fn vertical_photo_has_scale_f_over_h() {
        // H = 1500 m above the ground, f = 150 mm: scale 1:10000, so 100 m on
        // the ground east of the nadir is 10 mm = 1000 px (0.01 mm pixels) to
        // the right, and 100 m north is 1000 px up.
        let cam = vertical(Vector3::new(1000.0, 2000.0, 1700.0));
        let (c, r) = cam.project(1100.0, 2100.0, 200.0).unwrap();
        assert!((c - 6000.0).abs() < 1e-9 && (r - 4000.0).abs() < 1e-9, "{c} {r}");
    }

    #[test]
    fn tilted_photo_hand_derivation() {
        // ω-φ-κ with only φ = 10°: R = R_y(φ), Rᵀ = [[c,0,−s],[0,1,0],[s,0,c]].
        // The point straight below, ΔG = (0, 0, −H): p = Rᵀ ΔG = (sH, 0, −cH),
        // so x = −f·p.x/p.z = f·tan φ and y = 0.
        let phi = 10f64.to_radians();
        let r = AngleConvention::OmegaPhiKappa.matrix([0.0, phi, 0.0]);
        let io = InteriorOrientation::digital(0.01, [5000.0, 5000.0]).unwrap();
        let cam = FrameCamera::new(150.0, Vector3::new(0.0, 0.0, 1000.0), r, io, Distortion::None, Refraction::None, false);
        let (x, y) = cam.collinearity(0.0, 0.0, 0.0).unwrap();
        assert!((x - 150.0 * phi.tan()).abs() < 1e-12 && y.abs() < 1e-12);
        // A point 200 m east at height 0: ΔG = (200, 0, −1000);
        // p.x = c·200 + s·1000, p.z = s·200 − c·1000; x = −f p.x/p.z.
        let (s, c) = phi.sin_cos();
        let want = -150.0 * (c * 200.0 + s * 1000.0) / (s * 200.0 - c * 1000.0);
        let (x, _) = cam.collinearity(200.0, 0.0, 0.0).unwrap();
        assert!((x - want).abs() < 1e-12);
    }

    #[test]
    fn refraction_moves_the_point_away_from_the_nadir_by_lambda_f_sec2() {
        // Vertical photo, f = 150 mm, 0.01 mm pixels, camera 3000 m above
        // sea level, ground at 200 m, a point 600 m east and 800 m north:
        // D = 1000 m, H = 2800 m, tanζ = D/H; the ideal photo point is
        // r = f·tanζ from the nadir (the principal point here), and
        // refraction adds Δr = λ·f·(1 + tan²ζ) along the same radius, with
        // Aschenbrenner's λ″ = 3.1·L·(1 − 0.035·(3Ha − H)), L = D in km.
        let io = InteriorOrientation::digital(0.01, [5000.0, 5000.0]).unwrap();
        let (x0, y0) = (1000.0, 2000.0);
        let cam = |refraction| FrameCamera::new(150.0, Vector3::new(x0, y0, 3000.0), Matrix3::identity(), io.clone(), Distortion::None, refraction, false);
        let (g, (d, h)) = ((x0 + 600.0, y0 + 800.0, 200.0), (1000.0f64, 2800.0f64));
        let tan_z = d / h;
        let lambda = 3.1 * 1.0 * (1.0 - 0.035 * (3.0 * 3.0 - 2.8)) / 206_264.806_247;
        let want_r = 150.0 * tan_z + lambda * 150.0 * (1.0 + tan_z * tan_z);
        let (c, r) = cam(Refraction::Aschenbrenner).project(g.0, g.1, g.2).unwrap();
        let (x, y) = ((c - 5000.0) * 0.01, (5000.0 - r) * 0.01);
        assert!(((x * x + y * y).sqrt() - want_r).abs() < 1e-9, "{} vs {want_r}", (x * x + y * y).sqrt());
        assert!((y / x - 800.0 / 600.0).abs() < 1e-12, "radial");
        // Without refraction, the same point lies Δr closer (≈ 2.0 µm).
        let (c0, _) = cam(Refraction::None).project(g.0, g.1, g.2).unwrap();
        let dr = (c - c0) * 0.01 / 0.6;
        assert!((dr - lambda * 150.0 * (1.0 + tan_z * tan_z)).abs() < 1e-10 && dr > 1.9e-3, "{dr}");
    }

    #[test]
    fn project_many_gives_exactly_what_project_gives() {
        use crate::camera::distortion::Brown;
        let io = InteriorOrientation::digital(0.012, [10000.0, 10000.0]).unwrap();
        let r = AngleConvention::AlphaOmegaKappa.matrix([0.02, -0.03, 0.7]);
        let brown = Distortion::Brown(Brown { k1: -0.02, k2: 0.004, k3: 1e-4, p1: 1e-5, p2: -2e-5 });
        // Low (Aschenbrenner) and high (Kushtin) cameras, each distortion,
        // with and without earth curvature.
        for (h, refraction) in [(1800.0, Refraction::Auto), (9000.0, Refraction::Auto), (1800.0, Refraction::Kushtin), (1800.0, Refraction::None)] {
            for distortion in [Distortion::None, Distortion::Radial([1e-5, 1.5e-7, -2e-9]), brown] {
                for curvature in [false, true] {
                    let cam = FrameCamera::new(152.0, Vector3::new(5000.0, 5000.0, h), r, io.clone(), distortion, refraction, curvature);
                    // Points all over the photo, the nadir itself, and some
                    // above the camera (not imaged).
                    let n = 203;
                    let x: Vec<f64> = (0..n).map(|k| 5000.0 + ((k * 37) % 101) as f64 * 23.0 - 1150.0).collect();
                    let y: Vec<f64> = (0..n).map(|k| 5000.0 + ((k * 53) % 97) as f64 * 19.0 - 920.0).collect();
                    let mut z: Vec<f64> = (0..n).map(|k| 300.0 + (k % 7) as f64 * 40.0).collect();
                    z[5] = h + 10.0;
                    z[6] = h;
                    let (mut col, mut row) = (vec![0.0; n], vec![0.0; n]);
                    cam.project_many(&x, &y, &z, &mut col, &mut row);
                    for k in 0..n {
                        match cam.project(x[k], y[k], z[k]) {
                            Some((c, r)) => {
                                assert!(c.to_bits() == col[k].to_bits() && r.to_bits() == row[k].to_bits(), "{k}: {c} {r} vs {} {}", col[k], row[k])
                            }
                            None => assert!(col[k].is_nan() && row[k].is_nan(), "{k}"),
                        }
                    }
                    assert!(col[5].is_nan() && !col[0].is_nan());
                }
            }
        }
    }

    #[test]
    fn behind_the_camera_fails() {
        let cam = vertical(Vector3::new(0.0, 0.0, 1000.0));
        assert!(cam.project(0.0, 0.0, 1200.0).is_none());
    }

    #[test]
    fn homography_matches_collinearity_on_a_plane() {
        let r = AngleConvention::AlphaOmegaKappa.matrix([0.02, -0.03, 0.7]);
        let io = InteriorOrientation::digital(0.01, [5000.0, 5000.0]).unwrap();
        let cam = FrameCamera::new(150.0, Vector3::new(500.0, 500.0, 1500.0), r, io, Distortion::None, Refraction::None, false);
        let grid = OutputGrid { x0: 0.0, y0: 1000.0, gsd: crate::geom::Gsd::square(1.0), width: 1000, height: 1000 };
        let plane = Plane { a: 100.0, b: 0.05, c: -0.02 };
        let h = cam.plane_homography(&grid, &plane).unwrap();
        for (u, v) in [(0.5, 0.5), (300.5, 700.5), (999.5, 10.5)] {
            let (x, y) = grid.ground(u, v);
            let want = cam.project(x, y, plane.height(x, y)).unwrap();
            let p = h * Vector3::new(u, v, 1.0);
            assert!((p.x / p.z - want.0).abs() < 1e-8 && (p.y / p.z - want.1).abs() < 1e-8);
        }
    }
}
