//! The ground point of a match: the two scan positions the epipolar grid
//! gives for it intersected with the cameras' exact models, the point
//! whose images miss the two positions least (Beloshapkin's thesis,
//! eq. 2.5.11: the height by the minimum residual parallax, one answer
//! for any orientation with a base). What remains is the match's residual
//! parallax, kept as its quality.

use super::epipolar::EpipolarFrame;
use crate::camera::SensorModel;
use nalgebra::{Matrix3, Vector3};

/// A matched point on the ground and its residual parallax, pixels.
#[derive(Clone, Copy, Debug)]
pub struct GroundPoint {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub residual_px: f32,
}

/// Intersects the left grid position `(i, j)` matched at disparity `d`.
pub fn intersect(frame: &EpipolarFrame, left: &dyn SensorModel, right: &dyn SensorModel, i: f64, j: f64, d: f64) -> Option<GroundPoint> {
    let z0 = frame.plane_z;
    let gl = frame.ground(i, j);
    let gr = frame.ground(i - d, j + frame.right_row_shift);
    let pl = left.project(gl[0], gl[1], z0)?;
    let pr = right.project(gr[0], gr[1], z0)?;
    // The start: the height the disparity gives at the grid's rate, the
    // place half-way between the two rays' feet.
    let mut v = Vector3::new(0.5 * (gl[0] + gr[0]), 0.5 * (gl[1] + gr[1]), z0 + d / frame.px_per_m);
    let h = left.ground_step().max(1e-9);
    let residual = |v: &Vector3<f64>| -> Option<[f64; 4]> {
        let a = left.project(v.x, v.y, v.z)?;
        let b = right.project(v.x, v.y, v.z)?;
        Some([a.0 - pl.0, a.1 - pl.1, b.0 - pr.0, b.1 - pr.1])
    };
    let mut r = residual(&v)?;
    for _ in 0..8 {
        // Jacobian by forward differences: (4 × 3).
        let mut jac = [[0.0f64; 3]; 4];
        for (c, e) in [Vector3::x(), Vector3::y(), Vector3::z()].iter().enumerate() {
            // Heights are metres whatever the ground's units.
            let step = if c == 2 { 0.01 } else { h };
            let rs = residual(&(v + e * step))?;
            for k in 0..4 {
                jac[k][c] = (rs[k] - r[k]) / step;
            }
        }
        // Normal equations JᵀJ δ = −Jᵀr.
        let mut n = Matrix3::zeros();
        let mut g = Vector3::zeros();
        for k in 0..4 {
            let row = Vector3::new(jac[k][0], jac[k][1], jac[k][2]);
            n += row * row.transpose();
            g += row * r[k];
        }
        let delta = n.try_inverse()? * -g;
        v += delta;
        r = residual(&v)?;
        if delta.x.abs().max(delta.y.abs()) < 0.01 * h && delta.z.abs() < 1e-4 {
            break;
        }
    }
    let res = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]).sqrt();
    Some(GroundPoint { x: v.x, y: v.y, z: v.z, residual_px: res as f32 })
}

/// Exact intersections on a lattice of nodes in (column, row, disparity)
/// over a tile, every [`NODE`] pixels and [`NODE_D`] disparities, and
/// trilinear between them: the map from a match to its ground point is as
/// smooth as the plane's image, and a tile's quarter of a million
/// matches cost a few thousand intersections (the GCM's way: exact at
/// nodes, interpolated between).
pub struct Lattice {
    origin: (f64, f64, f64),
    n: (usize, usize, usize),
    nodes: Vec<Option<GroundPoint>>,
}

pub const NODE: f64 = 16.0;
pub const NODE_D: f64 = 8.0;

impl Lattice {
    /// Nodes over columns `[i0, i0 + w]`, rows `[j0, j0 + h]`, disparities
    /// `[dmin, dmax]`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        frame: &EpipolarFrame,
        left: &dyn SensorModel,
        right: &dyn SensorModel,
        (i0, j0): (f64, f64),
        (w, h): (f64, f64),
        (dmin, dmax): (f64, f64),
    ) -> Lattice {
        let n = ((w / NODE).ceil() as usize + 1, (h / NODE).ceil() as usize + 1, ((dmax - dmin) / NODE_D).ceil().max(1.0) as usize + 1);
        let mut nodes = Vec::with_capacity(n.0 * n.1 * n.2);
        for c in 0..n.2 {
            for b in 0..n.1 {
                for a in 0..n.0 {
                    nodes.push(intersect(frame, left, right, i0 + a as f64 * NODE, j0 + b as f64 * NODE, dmin + c as f64 * NODE_D));
                }
            }
        }
        Lattice { origin: (i0, j0, dmin), n, nodes }
    }

    /// The ground point of the match at `(i, j)` with disparity `d`, None
    /// where a node around it has none.
    pub fn at(&self, i: f64, j: f64, d: f64) -> Option<GroundPoint> {
        let (u, v, t) = ((i - self.origin.0) / NODE, (j - self.origin.1) / NODE, (d - self.origin.2) / NODE_D);
        let cell = |f: f64, n: usize| -> Option<(usize, f64)> {
            if !(f >= 0.0 && f <= (n - 1) as f64) {
                return None;
            }
            let k = (f as usize).min(n - 2);
            Some((k, f - k as f64))
        };
        let ((a, fa), (b, fb), (c, fc)) = (cell(u, self.n.0)?, cell(v, self.n.1)?, cell(t, self.n.2)?);
        let (mut x, mut y, mut z, mut r) = (0.0, 0.0, 0.0, 0.0);
        for (dc, wc) in [(0, 1.0 - fc), (1, fc)] {
            for (db, wb) in [(0, 1.0 - fb), (1, fb)] {
                for (da, wa) in [(0, 1.0 - fa), (1, fa)] {
                    let p = self.nodes[((c + dc) * self.n.1 + b + db) * self.n.0 + a + da]?;
                    let w = wa * wb * wc;
                    x += w * p.x;
                    y += w * p.y;
                    z += w * p.z;
                    r += w * f64::from(p.residual_px);
                }
            }
        }
        Some(GroundPoint { x, y, z, residual_px: r as f32 })
    }
}
