//! Stage 1, DEM lookup: the heights (and ground coordinates) at the GCM
//! nodes of one band.

use super::SharedRows;
use crate::gcm::NodeHeights;
use crate::pipeline::context::Run;

/// The heights at the nodes of one band, from node row `first_j` on.
pub struct DemMsg {
    pub band: u32,
    pub first_j: i64,
    pub heights: Vec<NodeHeights>,
}

/// The heights at the nodes of band `b`; the node rows it shares with the
/// band before come from `before`.
pub fn node_heights(run: &Run, b: u32, before: &mut SharedRows<NodeHeights>) -> DemMsg {
    let gcm = run.inputs.gcm;
    let (y0, y1) = run.walk.band_rows(b);
    let (j0, j1) = gcm.node_rows_for(y0, y1);
    DemMsg { band: b, first_j: j0, heights: before.rows(j0, j1, |j| gcm.node_heights(j)).0 }
}
