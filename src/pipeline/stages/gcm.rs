//! Stage 2, the GCM: exact `T` at the band's nodes, the corrections
//! `c = T − A` there, and refinement of the cells that miss the bound.

use super::dem::DemMsg;
use super::SharedRows;
use crate::dem::{Dem, Lookup};
use crate::error::{Error, Result};
use crate::gcm::{BandGcm, NodeRow};
use crate::pipeline::context::Run;

/// The band's GCM rows; a DEM miss under the `error` policy fails the run.
pub fn band_gcm(run: &Run, msg: DemMsg, before: &mut SharedRows<NodeRow>) -> Result<BandGcm> {
    let gcm = run.inputs.gcm;
    let mut miss = None;
    let last_j = msg.first_j + msg.heights.len() as i64 - 1;
    let (rows, reused) = before.rows(msg.first_j, last_j, |j| gcm.node_row(j, &msg.heights[(j - msg.first_j) as usize], &mut miss));
    let mut band = gcm.finish_band(msg.first_j, rows, miss);
    // Nodes worked out for this band, not those it shares with the one before.
    band.stats.nodes -= (reused * gcm.nodes_per_row()) as u64;
    if let Some(m) = band.miss {
        return Err(run.stop.fail(dem_miss_error(run.inputs.dem, m)));
    }
    run.counters.gcm.lock().expect("stats").add(&band.stats);
    Ok(band)
}

/// The error of a ground point where the DEM has no height and the policy
/// for it is `error`.
pub fn dem_miss_error(dem: &Dem, (x, y, l): (f64, f64, Lookup)) -> Error {
    let (what, setting) = match l {
        Lookup::Hole => ("a hole (nodata) in the DEM", "DEM holes"),
        _ => ("outside the DEM", "points outside the DEM"),
    };
    Error::format(&dem.path, format!("no height at ground point ({x:.2}, {y:.2}), {what}; the policy for {setting} is error (nodata or a height would go on)"))
}
