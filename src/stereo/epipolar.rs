//! The pair brought to epipolar geometry on the ground: both images
//! resampled onto one grid on a horizontal plane at the middle of the
//! search heights, the grid turned so that its rows run along the
//! parallax. A point off the plane lands in the two resampled images at
//! places that differ along the row only, by a disparity proportional to
//! its height above the plane. For frame cameras at one flying height this
//! is exact (the parallax of a plane image is along the base); for RPC and
//! pushbroom pairs it holds to the residual vertical parallax the frame
//! measures and reports, the quasi-epipolar geometry s2p and ASP use
//! piecewise. The mapping from a grid pixel to a scan is the one
//! `rectify` makes on a plane: exact positions at nodes, interpolated
//! between them.

use crate::camera::{locate, SensorModel};
use crate::error::{Error, Result};

/// One side of the pair as the frame needs it.
pub struct View<'a> {
    pub model: &'a dyn SensorModel,
    pub width: u32,
    pub height: u32,
}

/// The epipolar grid on the plane `z = plane_z`: pixel `(i, j)` (centres at
/// +½) is the ground point `origin + i·s·u − j·s·w`, `w` the row axis `u`
/// turned a quarter to the left (so the grid is not mirrored).
#[derive(Clone, Debug, serde::Serialize)]
pub struct EpipolarFrame {
    pub origin: [f64; 2],
    /// Unit vector along the rows (the direction of the parallax).
    pub u: [f64; 2],
    /// Ground units a pixel.
    pub pixel: f64,
    pub width: u32,
    pub height: u32,
    pub plane_z: f64,
    /// Disparity (left column − right column) per unit height above the
    /// plane, at the overlap's centre: pixels per metre.
    pub px_per_m: f64,
    /// The disparities heights in the search range take over the overlap,
    /// pixels, widened by a few pixels.
    pub disparity: [f64; 2],
    /// The largest parallax across the rows any height of the range makes
    /// anywhere in the overlap, pixels: what the one-dimensional search
    /// does not see.
    pub vertical_parallax_px: f64,
    /// The base-to-height ratio at the overlap's centre.
    pub base_to_height: f64,
    /// The right image's rows are the left's moved by this many pixels
    /// (the pair's relative pointing error, measured: pointing.rs).
    pub right_row_shift: f64,
}

impl EpipolarFrame {
    /// The grid for `left` and `right` seen over heights `[zlo, zhi]`, its
    /// pixel `pixel` ground units (0: the finer image's own).
    pub fn new(left: &View, right: &View, zlo: f64, zhi: f64, pixel: f64) -> Result<EpipolarFrame> {
        let z0 = 0.5 * (zlo + zhi);
        let fl = footprint(left, z0).ok_or_else(|| Error::Geometry("the left image does not reach the ground at the search's middle height".into()))?;
        let fr = footprint(right, z0).ok_or_else(|| Error::Geometry("the right image does not reach the ground at the search's middle height".into()))?;
        let c = centroid(&fl);
        let pixel = if pixel > 0.0 { pixel } else { gsd_at(left, c, z0).min(gsd_at(right, c, z0)) };
        if !(pixel > 0.0 && pixel.is_finite()) {
            return Err(Error::Geometry("the images' ground pixel size cannot be found".into()));
        }
        // The parallax a height step makes at the left image's centre: its
        // direction is the rows'.
        let dz = ((zhi - zlo) / 4.0).max(1.0);
        let shift = |g: [f64; 2], z: f64| -> Option<[f64; 2]> {
            let a = seen_on_plane(left.model, g, z, z0)?;
            let b = seen_on_plane(right.model, g, z, z0)?;
            Some([a[0] - b[0], a[1] - b[1]])
        };
        let (hi, lo) =
            shift(c, z0 + dz).zip(shift(c, z0 - dz)).ok_or_else(|| Error::Geometry("the pair's parallax cannot be found at the left image's centre".into()))?;
        let d = [(hi[0] - lo[0]) / (2.0 * dz), (hi[1] - lo[1]) / (2.0 * dz)];
        let b_h = d[0].hypot(d[1]);
        if !(b_h > 0.0 && b_h.is_finite()) {
            return Err(Error::Geometry("the two images see the ground from one place: there is no base".into()));
        }
        let u = [d[0] / b_h, d[1] / b_h];
        let w = [-u[1], u[0]];
        // The disparities the heights searched make over the left image
        // (its border and centre, a little inward: the corners are where
        // rays graze), and the parallax across the rows.
        let disparities = |pts: &[[f64; 2]], c: [f64; 2]| {
            let (mut dlo, mut dhi, mut vert) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
            for g in pts.iter().chain(std::iter::once(&c)) {
                let g = [0.98 * g[0] + 0.02 * c[0], 0.98 * g[1] + 0.02 * c[1]];
                for z in [zlo, zhi] {
                    if let Some(s) = shift(g, z) {
                        let along = (s[0] * u[0] + s[1] * u[1]) / pixel;
                        let across = (s[0] * w[0] + s[1] * w[1]) / pixel;
                        (dlo, dhi, vert) = (dlo.min(along), dhi.max(along), vert.max(across.abs()));
                    }
                }
            }
            (dlo, dhi, vert)
        };
        let (dlo, dhi, _) = disparities(&fl, c);
        if !dlo.is_finite() {
            return Err(Error::Geometry("no height of the search range is seen by both images".into()));
        }
        // What the left image may match: its ground where the right image,
        // moved by any disparity of the range, covers it.
        let moved = |dd: f64| fr.iter().map(move |p| [p[0] + dd * pixel * u[0], p[1] + dd * pixel * u[1]]);
        let swept = convex_hull(moved(dlo).chain(moved(dhi)).collect());
        let overlap = clip(&fl, &swept);
        let area = if overlap.len() < 3 { 0.0 } else { polygon_area(&overlap).abs() };
        let smaller = polygon_area(&fl).abs().min(polygon_area(&fr).abs());
        if area <= 0.0 {
            return Err(Error::Geometry(format!("the two images do not overlap on the ground at any height from {zlo:.0} to {zhi:.0}")));
        }
        if area < 0.01 * smaller {
            return Err(Error::Geometry(format!("the two images overlap on {:.2} % of the smaller one's ground only", 100.0 * area / smaller)));
        }
        // The overlap in the turned axes.
        let (mut u0, mut u1, mut w0, mut w1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for p in &overlap {
            let (a, b) = (p[0] * u[0] + p[1] * u[1], p[0] * w[0] + p[1] * w[1]);
            (u0, u1, w0, w1) = (u0.min(a), u1.max(a), w0.min(b), w1.max(b));
        }
        let width = ((u1 - u0) / pixel).ceil();
        let height = ((w1 - w0) / pixel).ceil();
        if width * height > 4.0e10 || width < 8.0 || height < 8.0 {
            return Err(Error::Geometry(format!("the overlap is {width} × {height} pixels of {pixel:.3}: too small or too large to match")));
        }
        let origin = [u0 * u[0] + w1 * w[0], u0 * u[1] + w1 * w[1]];
        let mut frame = EpipolarFrame {
            origin,
            u,
            pixel,
            width: width as u32,
            height: height as u32,
            plane_z: z0,
            px_per_m: b_h / pixel,
            disparity: [0.0; 2],
            vertical_parallax_px: 0.0,
            base_to_height: b_h,
            right_row_shift: 0.0,
        };
        let mut samples = overlap.clone();
        for k in 0..overlap.len() {
            let (a, b) = (overlap[k], overlap[(k + 1) % overlap.len()]);
            samples.push([0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])]);
        }
        let (dlo, dhi, vert) = disparities(&samples, centroid(&overlap));
        frame.disparity = [dlo.floor() - 4.0, dhi.ceil() + 4.0];
        frame.vertical_parallax_px = vert;
        Ok(frame)
    }

    /// The row axis turned a quarter to the left.
    pub fn w(&self) -> [f64; 2] {
        [-self.u[1], self.u[0]]
    }

    /// Ground (x, y) of the continuous grid position `(i, j)`.
    pub fn ground(&self, i: f64, j: f64) -> [f64; 2] {
        let (s, w) = (self.pixel, self.w());
        [self.origin[0] + s * (i * self.u[0] - j * w[0]), self.origin[1] + s * (i * self.u[1] - j * w[1])]
    }

    /// The continuous grid position of ground (x, y).
    pub fn position(&self, g: [f64; 2]) -> (f64, f64) {
        let (dx, dy) = (g[0] - self.origin[0], g[1] - self.origin[1]);
        let w = self.w();
        ((dx * self.u[0] + dy * self.u[1]) / self.pixel, -(dx * w[0] + dy * w[1]) / self.pixel)
    }
}

/// Where on the plane `z0` the model sees the ground point `g` at height `z`.
fn seen_on_plane(model: &dyn SensorModel, g: [f64; 2], z: f64, z0: f64) -> Option<[f64; 2]> {
    let (c, r) = model.project(g[0], g[1], z)?;
    locate(model, c, r, z0, 1e-6).map(|(x, y)| [x, y])
}

/// The ground a scan covers on the plane `z`: its border, 16 points a side.
fn footprint(view: &View, z: f64) -> Option<Vec<[f64; 2]>> {
    let (w, h) = (view.width as f64, view.height as f64);
    let n = 16;
    let mut pts = Vec::with_capacity(4 * n);
    let corners = [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)];
    for k in 0..4 {
        let (a, b) = (corners[k], corners[(k + 1) % 4]);
        for t in 0..n {
            let f = t as f64 / n as f64;
            let (c, r) = (a.0 + f * (b.0 - a.0), a.1 + f * (b.1 - a.1));
            let (x, y) = locate(view.model, c, r, z, 1e-3)?;
            pts.push([x, y]);
        }
    }
    if polygon_area(&pts) < 0.0 {
        pts.reverse();
    }
    Some(pts)
}

/// Ground units per scan pixel near `g`: the square root of a pixel's area.
fn gsd_at(view: &View, g: [f64; 2], z: f64) -> f64 {
    let Some((c, r)) = view.model.project(g[0], g[1], z) else { return f64::NAN };
    let at = |dc: f64, dr: f64| locate(view.model, c + dc, r + dr, z, 1e-6);
    match (at(0.0, 0.0), at(1.0, 0.0), at(0.0, 1.0)) {
        (Some(a), Some(b), Some(d)) => (((b.0 - a.0) * (d.1 - a.1) - (b.1 - a.1) * (d.0 - a.0)).abs()).sqrt(),
        _ => f64::NAN,
    }
}

/// The convex hull, counter-clockwise (Andrew's monotone chain).
fn convex_hull(mut p: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    p.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(p.len() + 1);
    for pass in 0..2 {
        let start = hull.len();
        let pts: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 { Box::new(p.iter()) } else { Box::new(p.iter().rev()) };
        for &q in pts {
            while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0 {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    hull
}

/// Signed area (counter-clockwise positive).
fn polygon_area(p: &[[f64; 2]]) -> f64 {
    (0..p.len())
        .map(|k| {
            let (a, b) = (p[k], p[(k + 1) % p.len()]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        / 2.0
}

fn centroid(p: &[[f64; 2]]) -> [f64; 2] {
    let n = p.len() as f64;
    [p.iter().map(|q| q[0]).sum::<f64>() / n, p.iter().map(|q| q[1]).sum::<f64>() / n]
}

/// `subject` clipped by the convex, counter-clockwise `clipper`
/// (Sutherland–Hodgman): the overlap of two footprints.
fn clip(subject: &[[f64; 2]], clipper: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut out = subject.to_vec();
    for k in 0..clipper.len() {
        let (a, b) = (clipper[k], clipper[(k + 1) % clipper.len()]);
        let side = |p: [f64; 2]| (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        let input = std::mem::take(&mut out);
        for m in 0..input.len() {
            let (p, q) = (input[m], input[(m + 1) % input.len()]);
            let (sp, sq) = (side(p), side(q));
            if sp >= 0.0 {
                out.push(p);
            }
            if (sp >= 0.0) != (sq >= 0.0) {
                let t = sp / (sp - sq);
                out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
            }
        }
        if out.is_empty() {
            break;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlap_of_two_squares() {
        let sq = |x0: f64, y0: f64| vec![[x0, y0], [x0 + 2.0, y0], [x0 + 2.0, y0 + 2.0], [x0, y0 + 2.0]];
        let o = clip(&sq(0.0, 0.0), &sq(1.0, 1.0));
        assert!((polygon_area(&o) - 1.0).abs() < 1e-12, "{o:?}");
        assert!(clip(&sq(0.0, 0.0), &sq(5.0, 5.0)).len() < 3);
    }
}
