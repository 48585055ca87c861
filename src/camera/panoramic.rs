//! A panoramic (optical-bar) film camera: the lens turns about an axis
//! along the flight while the film lies on a cylinder around it, so a
//! column of the film is one instant and one scan angle. Corona KH-4/4A/4B,
//! KH-9 Hexagon's panoramic cameras and KVR-1000 take their pictures so.
//!
//! The geometry is the optical-bar model of Ames Stereo Pipeline (after
//! Schenk et al., "Rigorous panoramic camera model for DISP imagery", and
//! Sohn et al., "Mathematical modelling of historical reconnaissance
//! CORONA KH-4B imagery"), term for term, so that its `OPTICAL_BAR` camera
//! files mean here what they mean there; Nekrasov's thesis (§2.5) models
//! the panoramic image the same way (a cylinder's angle along the film, a
//! projection centre that moves over the scan) and adds the scanning
//! mirror's offset from the lens, kept here as an optional term.
//!
//! In the camera's frame x runs along the scan (across the track), y along
//! the film's rows (with the flight before the forward tilt), z out of the
//! lens. For a film point (x, y) (metres from the lens axis's place on the
//! film) the scan angle is `α = x / f`, and the ray is
//! `(f sin α, y + imc(α), f cos α)` with the image motion compensation
//! `imc = f v / (H ω) · sin α · k`, negated for a right-to-left scan, where
//! `v` is the speed, `H` the height above the mean surface, `ω` the scan
//! rate and `k` the compensation factor. The projection centre moves at
//! constant velocity from `position` (at the first column scanned) over
//! the scan time.

use super::SensorModel;
use crate::geodesy::ecef::{from_ecef, to_ecef};
use crate::geodesy::{Geoid, GroundCrs};
use crate::geom::{OutputGrid, Plane};
use nalgebra::{Matrix3, Vector3};

/// The physical camera: every length in metres, angles in radians.
#[derive(Clone, Debug, PartialEq)]
pub struct OpticalBar {
    /// Columns (along the scan) and rows of the scanned film, pixels.
    pub size: [u32; 2],
    /// Where the lens axis meets the film at the scan's middle, in pixels
    /// (pixel centres at +½).
    pub centre_px: [f64; 2],
    /// The scan's pixel, metres of film.
    pub pitch: f64,
    pub focal: f64,
    /// Seconds from the first column scanned to the last.
    pub scan_time: f64,
    /// The lens swept the film from column 0 to the last (false: back).
    pub left_to_right: bool,
    /// The lens looking forward of the vertical, along the flight.
    pub forward_tilt: f64,
    /// The projection centre at the first column scanned, ECEF.
    pub position: Vector3<f64>,
    /// Camera frame → ECEF.
    pub rotation: Matrix3<f64>,
    /// Metres a second along the camera's (untilted) y axis.
    pub speed: f64,
    /// Where given, the centre's whole motion over the scan, ECEF metres
    /// (ASP's later form): then `speed` is not used for the motion and the
    /// compensation is `f sin α · k`.
    pub motion: Option<Vector3<f64>>,
    pub motion_compensation: f64,
    pub earth_radius: f64,
    pub surface_elevation: f64,
    /// The scanning mirror's distance in front of the lens (KVR-1000:
    /// 26.07 mm): the projection centre then sits that far along the
    /// scanned axis from the scan's axis. 0 for the optical-bar cameras.
    pub mirror_offset: f64,
}

/// The most a scan's angle may span: a cylinder's half seen from its axis.
pub const MOST_SCAN_DEG: f64 = 180.0;

impl OpticalBar {
    /// Validates the parameters: what is wrong, naming the field.
    pub fn check(&self) -> std::result::Result<(), (String, String)> {
        let bad = |f: &str, m: String| Err((f.to_string(), m));
        if self.size[0] < 2 || self.size[1] < 1 {
            return bad("panoramic.size_px", format!("{}×{} px is no scan", self.size[0], self.size[1]));
        }
        for (f, v) in [("panoramic.pixel_size_mm", self.pitch), ("camera.focal_length_mm", self.focal)] {
            if !(v.is_finite() && v > 0.0) {
                return bad(f, format!("{} is not a positive length", v * 1000.0));
            }
        }
        if !(self.scan_time.is_finite() && self.scan_time > 0.0) {
            return bad("panoramic.scan_time_s", format!("a scan time of {} s: the scan takes some time", self.scan_time));
        }
        let span = self.scan_angle().to_degrees();
        if span >= MOST_SCAN_DEG {
            return bad(
                "panoramic.pixel_size_mm",
                format!("the scan spans {span:.1}° (columns × pixel size ÷ focal length): at most {MOST_SCAN_DEG}° can be imaged"),
            );
        }
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !finite(&self.centre_px) {
            return bad("panoramic.centre_px", "not finite".into());
        }
        if !finite(self.position.as_slice()) || self.position.norm() < 6.0e6 || self.position.norm() > 4.3e7 {
            return bad("panoramic.position_ecef", format!("{:?} is no place above the earth (ECEF metres)", self.position.as_slice()));
        }
        let r = &self.rotation;
        if !finite(r.as_slice()) || (r.transpose() * r - Matrix3::identity()).abs().max() > 1e-6 || (r.determinant() - 1.0).abs() > 1e-6 {
            return bad("panoramic.rotation", "not a rotation (orthonormal, determinant 1)".into());
        }
        for (f, v) in [
            ("panoramic.forward_tilt_deg", self.forward_tilt),
            ("panoramic.speed_m_s", self.speed),
            ("panoramic.motion_compensation", self.motion_compensation),
            ("panoramic.mirror_offset_mm", self.mirror_offset),
        ] {
            if !v.is_finite() {
                return bad(f, "not finite".into());
            }
        }
        if self.forward_tilt.abs() >= std::f64::consts::FRAC_PI_2 {
            return bad("panoramic.forward_tilt_deg", format!("{:.1}° looks along the horizon or behind", self.forward_tilt.to_degrees()));
        }
        if !(self.earth_radius.is_finite() && (6.0e6..7.0e6).contains(&self.earth_radius)) {
            return bad("panoramic.mean_earth_radius_m", format!("{} m is not the earth's", self.earth_radius));
        }
        if !self.surface_elevation.is_finite() || self.height_above_surface(&self.position) <= 0.0 {
            return bad("panoramic.mean_surface_elevation_m", "the camera is not above it".into());
        }
        if let Some(m) = self.motion {
            if !finite(m.as_slice()) {
                return bad("panoramic.motion_ecef", "not finite".into());
            }
        }
        Ok(())
    }

    /// The angle the whole scan spans, radians (ASP's: from the first
    /// pixel's centre to the last's).
    #[must_use]
    pub fn scan_angle(&self) -> f64 {
        f64::from(self.size[0] - 1) * self.pitch / self.focal
    }

    /// The scan's angular rate, radians a second.
    #[must_use]
    pub fn scan_rate(&self) -> f64 {
        self.scan_angle() / self.scan_time
    }

    fn height_above_surface(&self, c: &Vector3<f64>) -> f64 {
        c.norm() - (self.earth_radius + self.surface_elevation)
    }

    /// The fraction of the scan done at column `col` (continuous, centres
    /// at +½), 0 at the first column scanned.
    fn scan_fraction(&self, col: f64) -> f64 {
        let last = f64::from(self.size[0] - 1);
        let c = col - 0.5;
        if self.left_to_right {
            c / last
        } else {
            (last - c) / last
        }
    }

    /// The centre's displacement over the whole scan, ECEF metres.
    fn travel(&self) -> Vector3<f64> {
        match self.motion {
            Some(m) => m,
            None => self.rotation * rot_x(self.forward_tilt) * Vector3::new(0.0, self.speed * self.scan_time, 0.0),
        }
    }

    /// The projection centre when column `col` was exposed (before the
    /// mirror's offset).
    fn centre_at(&self, col: f64) -> Vector3<f64> {
        self.position + self.scan_fraction(col) * self.travel()
    }

    /// The image motion compensation at scan angle `alpha` for a centre
    /// at `c`, metres of film along y.
    fn imc(&self, alpha: f64, c: &Vector3<f64>) -> f64 {
        let k = match self.motion {
            Some(_) => self.focal * alpha.sin() * self.motion_compensation,
            None => self.focal * self.speed / (self.height_above_surface(c) * self.scan_rate()) * alpha.sin() * self.motion_compensation,
        };
        if self.left_to_right {
            k
        } else {
            -k
        }
    }

    /// The mirror's shift of the projection centre at scan angle `alpha`,
    /// camera frame.
    fn mirror(&self, alpha: f64) -> Vector3<f64> {
        Vector3::new(self.mirror_offset * alpha.sin(), 0.0, self.mirror_offset * alpha.cos())
    }

    /// The ray of scan pixel (col, row) (continuous, centres at +½): its
    /// origin and unit direction, ECEF.
    #[must_use]
    pub fn ray(&self, col: f64, row: f64) -> (Vector3<f64>, Vector3<f64>) {
        let x = (col - self.centre_px[0]) * self.pitch;
        let y = (row - self.centre_px[1]) * self.pitch;
        let alpha = x / self.focal;
        let c = self.centre_at(col);
        let r = Vector3::new(self.focal * alpha.sin(), y + self.imc(alpha, &c), self.focal * alpha.cos()).normalize();
        (c + self.rotation * self.mirror(alpha), self.rotation * r)
    }

    /// The scan pixel (col, row) (centres at +½) that sees the ECEF point
    /// `p`; `None` behind the lens or where the scan's column does not
    /// settle. Outside the film's columns is returned too (the caller
    /// decides): the cylinder goes on.
    #[must_use]
    pub fn image_of(&self, p: &Vector3<f64>) -> Option<(f64, f64)> {
        let rt = self.rotation.transpose();
        // The column sets the instant, the instant the centre, the centre
        // the angle: Newton's method on the column, whose equation
        // g(c) = c − c₀ − α(c)·f/p is nearly linear (the centre moves a
        // hundredth as far as the ground seen), two or three steps.
        let last = f64::from(self.size[0] - 1);
        let per_col = if self.left_to_right { 1.0 / last } else { -1.0 / last };
        // How the point moves in the camera frame a column on.
        let e = -per_col * (rt * self.travel());
        let k = self.focal / self.pitch;
        let mut col = self.centre_px[0];
        let mut alpha = 0.0;
        for _ in 0..30 {
            let c = self.centre_at(col);
            let d = rt * (p - c) - self.mirror(alpha);
            if d.z <= 0.0 {
                return None;
            }
            alpha = d.x.atan2(d.z);
            let g = col - self.centre_px[0] - alpha * k;
            let slope = 1.0 - k * (d.z * e.x - d.x * e.z) / (d.x * d.x + d.z * d.z);
            let step = g / slope;
            col -= step;
            if step.abs() < 1e-9 {
                let c = self.centre_at(col);
                let y = self.focal * d.y / d.x.hypot(d.z) - self.imc(alpha, &c);
                return Some((col, self.centre_px[1] + y / self.pitch));
            }
        }
        None
    }
}

/// Rotation about x by `a` (a vector's y turning towards z).
#[must_use]
pub fn rot_x(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}

/// A panoramic camera over a ground CRS: ground (X, Y) → longitude,
/// latitude; the DEM's height Z (above the geoid where one is given) →
/// ellipsoidal; → ECEF → the optical bar. `A` is the homography fitted on
/// the terrain plane, as for an RPC: the cylinder's bending is smooth, and
/// the corrections carry it (docs/PANORAMIC.md measures how sparse they stay).
pub struct PanoramicCamera {
    pub bar: OpticalBar,
    pub crs: GroundCrs,
    pub geoid: Option<Geoid>,
    /// Ground units per scan pixel under the scan's middle.
    ground_per_px: f64,
}

impl PanoramicCamera {
    #[must_use]
    pub fn new(bar: OpticalBar, crs: GroundCrs, geoid: Option<Geoid>) -> PanoramicCamera {
        let h = bar.height_above_surface(&bar.position).max(1.0);
        let metres_per_px = h * bar.pitch / bar.focal;
        let (_, lat, _) = from_ecef(bar.position);
        let ground_per_px = metres_per_px * crs.units_per_metre(lat);
        PanoramicCamera { bar, crs, geoid, ground_per_px }
    }

    /// A height to start from: the mean surface the file gives, in the
    /// DEM's datum.
    #[must_use]
    pub fn height_hint(&self) -> f64 {
        let (lon, lat, _) = from_ecef(self.bar.position);
        let n = self.geoid.as_ref().and_then(|g| g.undulation(lon, lat)).unwrap_or(0.0);
        self.bar.surface_elevation - n
    }

    /// Ellipsoidal height of a height `z` in the DEM's vertical datum.
    #[inline]
    fn ellipsoidal(&self, lon: f64, lat: f64, z: f64) -> Option<f64> {
        match &self.geoid {
            None => Some(z),
            Some(g) => Some(z + g.undulation(lon, lat)?),
        }
    }

    /// The ECEF point of ground (X, Y) at height `z` in the DEM's datum.
    #[must_use]
    pub fn ecef(&self, x: f64, y: f64, z: f64) -> Option<Vector3<f64>> {
        let (lon, lat) = self.crs.to_lonlat(x, y)?;
        Some(to_ecef(lon, lat, self.ellipsoidal(lon, lat, z)?))
    }
}

impl SensorModel for PanoramicCamera {
    fn project(&self, x: f64, y: f64, z: f64) -> Option<(f64, f64)> {
        self.bar.image_of(&self.ecef(x, y, z)?)
    }

    fn lonlat_from(&self) -> Option<&crate::geodesy::Crs> {
        Some(&self.crs.crs)
    }

    fn project_many_lonlat(&self, lon: &[f64], lat: &[f64], z: &[f64], col: &mut [f64], row: &mut [f64]) {
        assert!(
            lat.len() == lon.len() && z.len() == lon.len() && col.len() == lon.len() && row.len() == lon.len(),
            "project_many_lonlat: arrays of one length"
        );
        for k in 0..lon.len() {
            let p = self.ellipsoidal(lon[k], lat[k], z[k]).and_then(|h| self.bar.image_of(&to_ecef(lon[k], lat[k], h)));
            (col[k], row[k]) = p.unwrap_or((f64::NAN, f64::NAN));
        }
    }

    fn locate_approx(&self, col: f64, row: f64, z: f64) -> Option<(f64, f64)> {
        let (c, d) = self.bar.ray(col, row);
        // Along the ray to the ellipsoidal height of z: Newton on the
        // distance, the height's rate along the ray from a step.
        let (lon0, lat0, _) = from_ecef(c);
        let mut h = self.ellipsoidal(lon0, lat0, z)?;
        let mut t = (c.norm() - (6_371_000.0 + h)) / (-d.dot(&c.normalize())).max(1e-6);
        for _ in 0..30 {
            let (lon, lat, hp) = from_ecef(c + t * d);
            h = self.ellipsoidal(lon, lat, z)?;
            let (_, _, h2) = from_ecef(c + (t + 1.0) * d);
            let rate = h2 - hp;
            if rate.abs() < 1e-9 {
                return None;
            }
            let step = (h - hp) / rate;
            t += step;
            if step.abs() < 1e-4 {
                break;
            }
        }
        if t <= 0.0 {
            return None;
        }
        let (lon, lat, _) = from_ecef(c + t * d);
        self.crs.lonlat_to_ground(lon, lat)
    }

    fn plane_homography(&self, grid: &OutputGrid, plane: &Plane) -> Option<Matrix3<f64>> {
        super::fitted_plane_homography(self, grid, plane)
    }

    fn ground_step(&self) -> f64 {
        0.05 * self.ground_per_px
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[allow(clippy::excessive_precision)] // ASP's published numbers, as printed
    fn kh4b() -> OpticalBar {
        // ASP's published KH-4B sample (its pixel (0, 0) is our (0.5, 0.5)).
        OpticalBar {
            size: [13656, 1033],
            centre_px: [6828.5, 517.5],
            pitch: 7.0e-6,
            focal: 0.61000001430511475,
            scan_time: 0.5,
            left_to_right: true,
            forward_tilt: 0.2618,
            position: Vector3::new(-1030862.1946224371, 5468503.8842079658, 3407902.5154047827),
            rotation: Matrix3::new(
                -0.95700845635275322,
                -0.27527006183758934,
                0.091439638698163225,
                -0.26345593052063937,
                0.69302501329766897,
                -0.67104940475144637,
                0.1213498543172795,
                -0.66629027007731101,
                -0.73575232847574434,
            ),
            speed: 7700.0,
            motion: None,
            motion_compensation: 1.0,
            earth_radius: 6371000.0,
            surface_elevation: 4000.0,
            mirror_offset: 0.0,
        }
    }

    #[test]
    fn a_ray_comes_back_to_its_pixel_in_both_scan_directions() {
        for ltr in [true, false] {
            for mirror in [0.0, 0.02607] {
                let bar = OpticalBar { left_to_right: ltr, mirror_offset: mirror, ..kh4b() };
                for &(c, r) in &[(0.5, 0.5), (6828.0, 517.0), (13655.5, 1032.5), (3000.25, 100.75)] {
                    let (o, d) = bar.ray(c, r);
                    let p = o + 180_000.0 * d;
                    let (c2, r2) = bar.image_of(&p).unwrap();
                    assert!((c2 - c).abs() < 1e-7 && (r2 - r).abs() < 1e-7, "{ltr} {mirror}: ({c}, {r}) → ({c2}, {r2})");
                }
            }
        }
    }

    #[test]
    fn a_scan_over_half_a_turn_and_no_scan_time_are_refused() {
        let wide = OpticalBar { pitch: 2e-4, ..kh4b() };
        assert!(wide.check().unwrap_err().1.contains("spans"));
        let still = OpticalBar { scan_time: 0.0, ..kh4b() };
        assert_eq!(still.check().unwrap_err().0, "panoramic.scan_time_s");
        assert!(kh4b().check().is_ok());
    }
}
