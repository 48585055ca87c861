//! What a run did and how fast: written as JSON with `--json`.

use crate::gcm::self_check::ErrorStats;
use crate::gcm::GcmStats;
use crate::geom::OutputGrid;

/// Busy seconds of each stage (waiting on channels excluded).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct StageTimes {
    pub setup: f64,
    pub dem: f64,
    pub gcm: f64,
    pub read: f64,
    pub resample: f64,
    pub encode: f64,
    pub write: f64,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Report {
    pub config: crate::options::RectifyOptions,
    pub grid: OutputGrid,
    pub crs: String,
    /// Ground units are degrees.
    pub geographic: bool,
    pub scan: ScanInfo,
    pub bands: u32,
    pub chunks: u64,
    /// Chunks whose scan rows were read in place from the mapping (the
    /// others' windows were copied or decoded).
    pub chunks_in_place: u64,
    pub stage_seconds: StageTimes,
    pub wall_seconds: f64,
    pub input_mb_per_s: f64,
    pub output_mpx_per_s: f64,
    pub peak_rss_mib: Option<f64>,
    /// The instruction set the run's kernels were chosen for (`avx2`,
    /// `ssse3`, `portable`): a figure's machine, in its report.
    pub kernels: &'static str,
    pub gcm: GcmStats,
    /// `|A + c − T|` on a sample of output pixels.
    pub accuracy_estimate: ErrorStats,
    /// The error bound the run was held to (scan px), if any.
    pub error_bound: Option<f64>,
    /// Whether the sampled error stayed within the bound (or, without one,
    /// within half a pixel).
    pub error_within: bool,
    pub output_bytes: u64,
    /// Doubtful inputs met and errors beyond what was asked: the binary
    /// prints them even when quiet.
    pub warnings: Vec<String>,
    /// What the ground control points did to the model, where given.
    pub gcps: Option<crate::camera::gcp::GcpFit>,
    /// Under `--occlusion`: how much of the ground the scan images the
    /// sensor does not see.
    pub occlusion: Option<Hidden>,
}

/// Output pixels hidden from the sensor by the DSM (a true orthophoto's).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Hidden {
    /// Output pixels whose ground the scan images.
    pub imaged_px: u64,
    /// Of them, those the sensor does not see.
    pub hidden_px: u64,
    /// `hidden_px / imaged_px`.
    pub share: f64,
}

impl Hidden {
    pub fn new(imaged_px: u64, hidden_px: u64) -> Hidden {
        Hidden { imaged_px, hidden_px, share: if imaged_px == 0 { 0.0 } else { hidden_px as f64 / imaged_px as f64 } }
    }
}

/// Past this (scan px), a run without a bound is warned about.
pub const UNBOUNDED_WARNING_PX: f64 = 0.5;

#[derive(Clone, Debug, serde::Serialize)]
pub struct ScanInfo {
    pub width: u32,
    pub height: u32,
    pub bands: u32,
    pub sample: crate::io::source::SampleType,
    pub tiled: bool,
    pub compression: u16,
    pub memory_mapped: bool,
    pub bytes: u64,
}
