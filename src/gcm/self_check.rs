//! The GCM's check of itself while a run uses it: `|A + c − T|` sampled on
//! the run's own rows and columns, summed as the report gives it (mean,
//! RMS, max, share under 0.1 / 0.25 / 0.5 / 1 px), the figures the study
//! tools publish too.

use super::{BandGcm, Gcm};
use crate::transform::Mapped;

pub const THRESHOLDS: [f64; 4] = [0.1, 0.25, 0.5, 1.0];

#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ErrorStats {
    /// Pixels compared (both `T` and `A + c` valid).
    pub count: u64,
    pub mean_abs: f64,
    pub rms: f64,
    pub max: f64,
    /// Percent of pixels under each of `THRESHOLDS`.
    pub pct_under: [f64; 4],
    /// Every `step`-th row and column was evaluated (1 = all pixels).
    pub step: u32,
    /// Where the maximum is (output column, row).
    pub argmax: [u32; 2],
}

/// Errors summed as they are sampled.
#[derive(Clone, Copy, Debug, Default)]
pub struct Acc {
    n: u64,
    sum: f64,
    sum2: f64,
    max: f64,
    argmax: [u32; 2],
    under: [u64; 4],
}

impl Acc {
    pub fn push(&mut self, e: f64, x: u32, y: u32) {
        self.n += 1;
        self.sum += e;
        self.sum2 += e * e;
        if e > self.max {
            self.max = e;
            self.argmax = [x, y];
        }
        for (k, t) in THRESHOLDS.iter().enumerate() {
            if e < *t {
                self.under[k] += 1;
            }
        }
    }
    pub fn merge(mut self, o: Acc) -> Acc {
        self.n += o.n;
        self.sum += o.sum;
        self.sum2 += o.sum2;
        if o.max > self.max {
            self.max = o.max;
            self.argmax = o.argmax;
        }
        for k in 0..4 {
            self.under[k] += o.under[k];
        }
        self
    }
}

impl ErrorStats {
    /// The statistics of `acc`, sampled every `step`-th column.
    pub fn of(acc: &Acc, step: u32) -> ErrorStats {
        let n = acc.n.max(1) as f64;
        ErrorStats {
            count: acc.n,
            mean_abs: acc.sum / n,
            rms: (acc.sum2 / n).sqrt(),
            max: acc.max,
            pct_under: acc.under.map(|u| 100.0 * u as f64 / n),
            step,
            argmax: acc.argmax,
        }
    }
}

/// The grid's rows and columns a run's report samples: every
/// `(height / 64)`-th row, every 7th column.
pub fn run_sample_steps(grid: &crate::geom::OutputGrid) -> (u32, u32) {
    ((grid.height / 64).max(1), 7)
}

/// `|A + c − T|` in `band`, the GCM a run made and used, on its rows
/// `rows` and columns `cols` at the steps of [`run_sample_steps`]
/// (counted from the grid's first row and column, so that pieces of a
/// grid sample what the whole would).
pub fn sample_band(gcm: &Gcm<'_>, band: &BandGcm, rows: std::ops::Range<u32>, cols: std::ops::Range<u32>) -> Acc {
    let (row_step, col_step) = run_sample_steps(&gcm.t.grid);
    let mut acc = Acc::default();
    let x0 = cols.start.next_multiple_of(col_step);
    if x0 >= cols.end {
        return acc;
    }
    let len = (cols.end - x0) as usize;
    let (mut at_c, mut at_r) = (vec![0.0; len], vec![0.0; len]);
    for y in rows.filter(|y| y % row_step == 0) {
        gcm.fill_row(band, y, x0, &mut at_c, &mut at_r, &mut None);
        for x in (x0..cols.end).step_by(col_step as usize) {
            let i = (x - x0) as usize;
            if let Mapped::Px(c, r) = gcm.t.exact(x as f64 + 0.5, y as f64 + 0.5) {
                // Only pixels of the image: the bound is not kept (nor
                // needed) where the ground falls outside the scan.
                let in_scan = gcm.t.scan.is_none_or(|(w, h)| c >= 0.0 && r >= 0.0 && c <= w && r <= h);
                if !at_c[i].is_nan() && in_scan {
                    acc.push((c - at_c[i]).hypot(r - at_r[i]), x, y);
                }
            }
        }
    }
    acc
}
