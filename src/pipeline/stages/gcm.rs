//! Stage 2, the GCM: exact `T` at the band's nodes, the corrections
//! `c = T − A` there, and refinement of the cells that miss the bound.

use super::dem::DemMsg;
use super::SharedRows;
use crate::dem::{Dem, Lookup};
use crate::error::{Error, Result};
use crate::gcm::self_check;
use crate::gcm::{BandGcm, NodeRow};
use crate::pipeline::context::Run;
use crate::transform::visibility::{Seen, Visibility};
use rayon::prelude::*;
use std::sync::atomic::Ordering;

/// The band's GCM rows; a DEM miss under the `error` policy fails the run.
pub fn band_gcm(run: &Run, msg: DemMsg, before: &mut SharedRows<NodeRow>) -> Result<BandGcm> {
    let gcm = run.inputs.gcm;
    let mut miss = None;
    let last_j = msg.first_j + msg.heights.len() as i64 - 1;
    let (rows, reused) = before.rows(msg.first_j, last_j, |j| gcm.node_row(j, &msg.heights[(j - msg.first_j) as usize], &mut miss));
    let mut band = gcm.finish_band(msg.first_j, rows, miss);
    if let (Some(vis), None) = (run.inputs.visibility, band.miss) {
        let seen = seen(run, &band, msg.band, vis);
        run.counters.imaged.fetch_add(seen.imaged, Ordering::Relaxed);
        run.counters.hidden.fetch_add(seen.hidden, Ordering::Relaxed);
        band.seen = Some(std::sync::Arc::new(seen));
    }
    // Nodes worked out for this band, not those it shares with the one before.
    band.stats.nodes -= (reused * gcm.nodes_per_row()) as u64;
    if let Some(m) = band.miss {
        return Err(run.stop.fail(dem_miss_error(run.inputs.dem, m)));
    }
    run.counters.gcm.lock().expect("stats").add(&band.stats);
    if let Some(sampled) = &run.counters.sampled {
        // The report's sample of the error, from the band as it is used.
        let (y0, y1) = run.walk.band_rows(msg.band);
        let (t, (c0, c1)) = (run.walk.tile, run.walk.cols);
        let here = self_check::sample_band(gcm, &band, y0..y1, c0 * t..(c1 * t).min(run.walk.grid.width));
        let mut acc = sampled.lock().expect("sample");
        *acc = acc.merge(here);
    }
    Ok(band)
}

/// Which pixels of band `b` the sensor sees, a tile a task on the pool:
/// their scan positions from the band's GCM, then their Z-buffers.
fn seen(run: &Run, band: &BandGcm, b: u32, vis: &Visibility) -> Seen {
    let (y0, y1) = run.walk.band_rows(b);
    let (t, (c0, c1)) = (run.walk.tile, run.walk.cols);
    let gcm = run.inputs.gcm;
    // A tile a task: what a tile's pixels are found to see then depends
    // on that tile alone, not on which of its neighbours the band holds
    // (pieces of a --window, a mosaic's strips and its images' own column
    // ranges all cut bands differently).
    let made: Vec<(Vec<u8>, u64, u64)> = run.pool.install(|| {
        (c0..c1)
            .into_par_iter()
            .map(|tc| {
                let (x0, x1) = (tc * t, ((tc + 1) * t).min(run.walk.grid.width));
                let positions = |y: u32, x: u32, cols: &mut [f64], rows: &mut [f64]| {
                    gcm.fill_row(band, y, x, cols, rows, &mut None);
                };
                let mut tile = vec![1u8; (t * t) as usize];
                let (imaged, hidden) = vis.tile([x0, y0, x1, y1], t, positions, &mut tile);
                (tile, imaged, hidden)
            })
            .collect()
    });
    let (imaged, hidden) = made.iter().fold((0, 0), |(a, b), m| (a + m.1, b + m.2));
    Seen::new(y0, c0 * t, t, made.into_iter().map(|m| m.0).collect(), imaged, hidden)
}

/// The error of a ground point where the DEM has no height and the policy
/// for it is `error`.
pub fn dem_miss_error(dem: &Dem, (x, y, l): (f64, f64, Lookup)) -> Error {
    let (what, setting) = match l {
        Lookup::Hole => ("a hole (nodata) in the DEM", "‹dem_hole›"),
        _ => ("outside the DEM", "‹dem_outside›"),
    };
    Error::format(&dem.path, format!("no height at ground point ({x:.2}, {y:.2}), {what}; {setting} is error: nodata or a height would go on"))
}
