//! A panoramic camera fitted to ground control points: historical
//! metadata gives a pose kilometres and degrees off, and a scan time and
//! motion compensation only by type. Least squares on every point's image
//! position (Gauss-Newton, numerical derivatives):
//!
//! * the pose (the first position, three small turns of the camera frame)
//!   with three points or more;
//! * with six or more, the scan's dynamics too, as far as image points can
//!   tell them apart: the motion compensation's factor, which moves a
//!   point along the film by sin α — taken where the points fix it (a
//!   column-scaled condition number), else the pose alone (`auto`) or
//!   refused (`--gcp-refine interior`).
//!
//! The scan time and the forward tilt stay as given: the distance flown
//! over the scan shears the image linearly in α, as a turn about the lens
//! axis does, and the compensation scales with the scan time as with its
//! factor; the tilt only turns the flight's direction in the camera frame.
//! Fitted together they trade against each other and the pose (a fit of
//! all three on ten GCPs of a synthetic strip put the tilt at 72° with
//! 0.17 px residuals), so the one separable term stands for them.

use super::gcp_points::{condition, left_out_outlier, refuse_collinear, rms, Gcp, GcpFit, GcpResidual};
use super::panoramic::{OpticalBar, PanoramicCamera};
use crate::error::{Error, Result};
use crate::geodesy::ecef::{nearest_rotation, to_ecef};
use nalgebra::{DMatrix, DVector, Vector3};
use std::path::Path;

/// The least number of points for the pose, and for the pose and dynamics.
const POSE: usize = 3;
const DYNAMICS: usize = 6;
/// The least ratio of the smallest to the largest singular value of the
/// column-scaled Jacobian at which the dynamics are fitted.
const CONDITION: f64 = 1e-5;

/// Fits `cam` to `gcps`; `dynamics`: `Some(true)` the scan's dynamics must
/// be fitted, `Some(false)` never, `None` where the points fix them.
pub fn resection(cam: &PanoramicCamera, gcps: &[Gcp], dynamics: Option<bool>, source: &Path) -> Result<(OpticalBar, GcpFit)> {
    resection_from(cam, &cam.bar, gcps, dynamics, source)
}

/// [`resection`] from the optical bar `start` (in `cam`'s CRS and geoid).
fn resection_from(cam: &PanoramicCamera, start: &OpticalBar, gcps: &[Gcp], dynamics: Option<bool>, source: &Path) -> Result<(OpticalBar, GcpFit)> {
    let least = if dynamics == Some(true) { DYNAMICS } else { POSE };
    if gcps.len() < least {
        let what = if dynamics == Some(true) { "a panoramic resection with the scan's dynamics" } else { "a panoramic resection" };
        return Err(Error::format(source, format!("{} GCPs: {what} needs {least} or more", gcps.len())));
    }
    let mut local = Vec::with_capacity(gcps.len());
    let mut points = Vec::with_capacity(gcps.len());
    for g in gcps {
        let n = match (&cam.geoid, g.ellipsoidal) {
            (Some(geoid), false) => geoid.undulation(g.lon, g.lat).ok_or_else(|| Error::format(source, format!("GCP {}: outside the geoid grid", g.id)))?,
            _ => 0.0,
        };
        points.push(to_ecef(g.lon, g.lat, g.height + n));
        let (x, y) = cam.crs.lonlat_to_ground(g.lon, g.lat).ok_or_else(|| Error::format(source, format!("GCP {}: outside the CRS", g.id)))?;
        local.push(Vector3::new(x, y, g.height));
    }
    refuse_collinear(&local, source)?;
    let residuals =
        |bar: &OpticalBar| -> Option<Vec<[f64; 2]>> { points.iter().zip(gcps).map(|(p, g)| bar.image_of(p).map(|(c, r)| [g.col - c, g.row - r])).collect() };
    let left_view = || Error::format(source, "the panoramic resection left the GCPs' view");
    let before = residuals(start).ok_or_else(|| Error::format(source, "a GCP is behind the panoramic camera"))?;
    let moved = |b: &OpticalBar, d: &[f64]| {
        let mut b = b.clone();
        b.position += Vector3::new(d[0], d[1], d[2]);
        b.rotation *= super::panoramic::rot_x(d[3]) * rot_y(d[4]) * rot_z(d[5]);
        if d.len() > 6 {
            b.motion_compensation += d[6];
        }
        b
    };
    let fit_with = |unknowns: usize| -> Result<(OpticalBar, f64)> {
        let n = points.len();
        let mut bar = start.clone();
        let mut current = before.clone();
        let mut j = DMatrix::<f64>::zeros(2 * n, unknowns);
        let mut worst_condition = f64::INFINITY;
        for _ in 0..40 {
            for k in 0..unknowns {
                let h = match k {
                    0..=2 => 1.0,
                    3..=5 => 1e-7,
                    _ => 1e-4,
                };
                let mut d = vec![0.0; unknowns];
                d[k] = h;
                let shifted = residuals(&moved(&bar, &d)).ok_or_else(left_view)?;
                for i in 0..n {
                    j[(2 * i, k)] = -(shifted[i][0] - current[i][0]) / h;
                    j[(2 * i + 1, k)] = -(shifted[i][1] - current[i][1]) / h;
                }
            }
            worst_condition = worst_condition.min(condition(&j));
            let e = DVector::from_iterator(2 * n, current.iter().flat_map(|d| [d[0], d[1]]));
            let delta = j.clone().svd(true, true).solve(&e, 1e-14).map_err(|_| Error::format(source, "the GCPs do not fix the panoramic camera's pose"))?;
            bar = moved(&bar, delta.as_slice());
            bar.rotation = nearest_rotation(&bar.rotation).unwrap_or(bar.rotation);
            current = residuals(&bar).ok_or_else(left_view)?;
            if delta.rows(0, 3).norm() < 1e-5 && delta.rows(3, unknowns - 3).norm() < 1e-11 {
                break;
            }
        }
        Ok((bar, worst_condition))
    };
    let want_dynamics = dynamics.unwrap_or(gcps.len() >= DYNAMICS) && gcps.len() >= DYNAMICS;
    let (bar, method) = if want_dynamics {
        let (bar, cond) = fit_with(7)?;
        if cond > CONDITION {
            (bar, "panoramic resection with the motion compensation")
        } else if dynamics == Some(true) {
            return Err(Error::format(
                source,
                format!(
                    "the GCPs do not tell the motion compensation from the pose (condition {:.0e}): spread them along the whole scan and across the film (or ‹gcp_refine› auto)",
                    1.0 / cond
                ),
            ));
        } else {
            (fit_with(6)?.0, "panoramic resection")
        }
    } else {
        (fit_with(6)?.0, "panoramic resection")
    };
    let after = residuals(&bar).ok_or_else(left_view)?;
    let p = bar.position;
    let mut correction = format!("first position ECEF ({:.3}, {:.3}, {:.3})", p.x, p.y, p.z);
    if method.contains("compensation") {
        correction += &format!(", motion compensation {:.4} (was {:.4})", bar.motion_compensation, start.motion_compensation);
    }
    let fit = GcpFit {
        method: method.into(),
        points: gcps.iter().zip(before.iter().zip(&after)).map(|(g, (b, a))| GcpResidual { id: g.id.clone(), before: *b, after: *a }).collect(),
        rms_before: rms(&before),
        rms_after: rms(&after),
        correction,
        outlier: None,
    };
    Ok((bar, fit))
}

/// Leave-one-out over the GCPs: each point against the camera the others
/// give (twice as many resections), as a frame's.
pub fn outlier(cam: &PanoramicCamera, gcps: &[Gcp], dynamics: Option<bool>, source: &Path) -> Option<String> {
    let least = if dynamics == Some(true) { DYNAMICS } else { POSE };
    left_out_outlier(gcps, least, |i| {
        let rest: Vec<Gcp> = gcps.iter().enumerate().filter(|(k, _)| *k != i).map(|(_, g)| g.clone()).collect();
        let (bar, fit) = resection(cam, &rest, dynamics, source).ok()?;
        // Its residual under that camera: the `before` of a fit from it.
        let (_, from) = resection_from(cam, &bar, gcps, dynamics, source).ok()?;
        Some((from.points[i].before[0].hypot(from.points[i].before[1]), fit.rms_after))
    })
}

fn rot_y(a: f64) -> nalgebra::Matrix3<f64> {
    let (s, c) = a.sin_cos();
    nalgebra::Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}

fn rot_z(a: f64) -> nalgebra::Matrix3<f64> {
    let (s, c) = a.sin_cos();
    nalgebra::Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}
