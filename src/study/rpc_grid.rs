//! The accuracy of an RPC image's regular grid (`rpc-grid --accuracy`):
//! the grid's longitude/latitude against the exact solve, in metres, as in
//! Chibunichev and Sonyushkin's table.

use crate::camera::RpcCamera;
use crate::dem::Dem;
use crate::rpcgrid::{RpcGrid, METRES_PER_DEGREE};
use crate::transform::inverse::RayCaster;
use rayon::prelude::*;

/// A row of Chibunichev and Sonyushkin's accuracy table: the grid's longitude/latitude against the
/// exact solve, in metres, over every `sample`-th pixel of each row and column.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GridAccuracy {
    pub step: u32,
    pub pixels: u64,
    pub mean_abs_m: f64,
    pub rms_m: f64,
    pub max_m: f64,
    /// % of pixels under 0.5, 1, 2.5 and 5 m.
    pub pct_under: [f64; 4],
    pub bad_nodes: usize,
    pub corrected_nodes: usize,
}

pub fn accuracy(grid: &RpcGrid, model: &RpcCamera, dem: &Dem, w: u32, h: u32, sample: u32, z_guess: f64) -> GridAccuracy {
    let sample = sample.max(1);
    let per_row: Vec<(u64, f64, f64, f64, [u64; 4])> = (0..h)
        .step_by(sample as usize)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|y| {
            let mut caster = RayCaster::new(model, dem);
            let mut prev = None;
            let (mut n, mut sum, mut sum2, mut max, mut under) = (0u64, 0.0, 0.0, 0.0f64, [0u64; 4]);
            for x in (0..w).step_by(sample as usize) {
                let (c, r) = (x as f64 + 0.5, y as f64 + 0.5);
                let Some(p) = caster.cast(c, r, prev, z_guess, 1e-4) else {
                    prev = None;
                    continue;
                };
                prev = Some((p[0], p[1]));
                let (lon, lat) = grid.interpolate(c, r);
                let e = ((lon - p[0]) * METRES_PER_DEGREE * p[1].to_radians().cos()).hypot((lat - p[1]) * METRES_PER_DEGREE);
                n += 1;
                sum += e;
                sum2 += e * e;
                max = max.max(e);
                for (k, t) in [0.5, 1.0, 2.5, 5.0].iter().enumerate() {
                    if e < *t {
                        under[k] += 1;
                    }
                }
            }
            (n, sum, sum2, max, under)
        })
        .collect();
    let (mut n, mut sum, mut sum2, mut max, mut under) = (0u64, 0.0, 0.0, 0.0f64, [0u64; 4]);
    for (a, b, c, d, e) in per_row {
        n += a;
        sum += b;
        sum2 += c;
        max = max.max(d);
        for k in 0..4 {
            under[k] += e[k];
        }
    }
    let m = n.max(1) as f64;
    GridAccuracy {
        step: grid.step,
        pixels: n,
        mean_abs_m: sum / m,
        rms_m: (sum2 / m).sqrt(),
        max_m: max,
        pct_under: under.map(|u| 100.0 * u as f64 / m),
        bad_nodes: grid.bad,
        corrected_nodes: grid.corrected,
    }
}
