//! Ground control points and what a fit to them leaves: the points, each
//! one's residual before and after, and the check every resection makes
//! first (points off one ground line), and the leave-one-out check that
//! names an outlier. Read and fitted in `gcp` (an RPC's bias, a frame's
//! resection) and `panoramic_resection`.

use crate::error::{Error, Result};
use nalgebra::{DMatrix, Vector3};
use std::path::Path;

/// One ground control point.
#[derive(Clone, Debug, PartialEq)]
pub struct Gcp {
    pub id: String,
    /// Where the image shows it (pixel centres at +½).
    pub col: f64,
    pub row: f64,
    /// Where it is: WGS 84 longitude, latitude (degrees) and height (m).
    pub lon: f64,
    pub lat: f64,
    pub height: f64,
    /// The height is above the ellipsoid (Orthority's files), not in the
    /// DEM's datum.
    pub ellipsoidal: bool,
}

/// What a refinement did: each point's residual before and after (image
/// pixels, image − model), and the correction.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GcpFit {
    /// "rpc shift", "rpc affine", "resection", "resection with interior",
    /// "panoramic resection" or "panoramic resection with the motion
    /// compensation".
    pub method: String,
    pub points: Vec<GcpResidual>,
    pub rms_before: f64,
    pub rms_after: f64,
    /// The RPC's image-space correction (col' = a·col + b·row + c, row' = …),
    /// or the camera's new exterior orientation, as text.
    pub correction: String,
    /// A point the others place far from where it was measured (a
    /// mistyped coordinate, a point on the wrong feature), said by its id.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub outlier: Option<String>,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct GcpResidual {
    pub id: String,
    pub before: [f64; 2],
    pub after: [f64; 2],
}

/// The root mean square of image residuals (column, row), pixels.
pub fn rms(v: &[[f64; 2]]) -> f64 {
    (v.iter().map(|d| d[0] * d[0] + d[1] * d[1]).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// Refuses GCPs on one line on the ground: the camera may turn about it
/// freely, and a resection on them fits anything.
pub fn refuse_collinear(points: &[Vector3<f64>], source: &Path) -> Result<()> {
    let n = points.len() as f64;
    let mean = points.iter().fold(Vector3::zeros(), |m, p| m + p) / n;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let (dx, dy) = (p.x - mean.x, p.y - mean.y);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    // The spread across the points' main line against the spread along it.
    let (half_trace, det) = ((sxx + syy) / 2.0, sxx * syy - sxy * sxy);
    let root = (half_trace * half_trace - det).max(0.0).sqrt();
    let (along, across) = (half_trace + root, (half_trace - root).max(0.0));
    if across.sqrt() <= 1e-3 * along.sqrt() {
        return Err(Error::format(
            source,
            format!(
                "the {} GCPs lie on one line on the ground: a resection needs points spread across the image, three or more off any one line",
                points.len()
            ),
        ));
    }
    Ok(())
}

/// The smallest over the largest singular value of `j` with its columns
/// scaled to unit length: near 0 where the points cannot see a change.
pub fn condition(j: &DMatrix<f64>) -> f64 {
    let mut scaled = j.clone();
    for mut col in scaled.column_iter_mut() {
        let norm = col.norm();
        if norm > 0.0 {
            col /= norm;
        }
    }
    let sv = scaled.singular_values();
    sv.min() / sv.max()
}

/// The most GCPs checked one by one (each check a fit of the others).
const MOST_LEFT_OUT: usize = 40;

/// Leave-one-out: `placed(i)` is how far point `i` lies from where the fit
/// of the others (at least `least` of them) places it, and that fit's RMS.
/// A point over a pixel off and five times their RMS is an outlier the fit
/// with it hides: it pulls the fit its way (one frame point of eight
/// moved 2.5 px stayed 1.93 px off, under the 2 px limit). Said of the
/// worst such point, by its id.
pub fn left_out_outlier(gcps: &[Gcp], least: usize, placed: impl Fn(usize) -> Option<(f64, f64)>) -> Option<String> {
    if gcps.len() <= least || gcps.len() > MOST_LEFT_OUT {
        return None;
    }
    let mut worst: Option<(f64, f64, f64, &str)> = None;
    for (i, g) in gcps.iter().enumerate() {
        let Some((off, rms)) = placed(i) else { continue };
        let ratio = off / rms.max(0.05);
        if off > 1.0 && ratio > 5.0 && worst.is_none_or(|w| ratio > w.0) {
            worst = Some((ratio, off, rms, &g.id));
        }
    }
    worst.map(|(_, off, rms, id)| {
        format!("GCP {id} is {off:.2} px from where the other points place it (they fit to {rms:.2} px RMS): an outlier? (a coordinate or a point mistaken)")
    })
}
