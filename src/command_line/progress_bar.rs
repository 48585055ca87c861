//! Progress on a terminal: an indicatif bar with rate and ETA, drawn only
//! when standard error is a terminal and the user did not ask for quiet.

use crate::progress::{Progress, Task};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressState, ProgressStyle};
use std::fmt::Write;
use std::io::IsTerminal;
use std::sync::Mutex;

/// The binary's [`Progress`]: one bar per task.
pub struct Bar {
    shown: bool,
    bar: Mutex<Option<ProgressBar>>,
}

impl Bar {
    /// A bar that draws unless `quiet` or standard error is not a terminal.
    pub fn new(quiet: bool) -> Bar {
        Bar { shown: !quiet && std::io::stderr().is_terminal(), bar: Mutex::new(None) }
    }

    fn with(&self, f: impl FnOnce(&ProgressBar)) {
        if let Some(b) = self.bar.lock().expect("progress bar").as_ref() {
            f(b)
        }
    }
}

impl Progress for Bar {
    fn start(&self, task: &Task) {
        let pb = if self.shown { ProgressBar::new(task.units) } else { ProgressBar::with_draw_target(Some(task.units), ProgressDrawTarget::hidden()) };
        pb.set_style(style(task));
        *self.bar.lock().expect("progress bar") = Some(pb);
    }
    fn advance(&self, units: u64) {
        self.with(|b| b.inc(units));
    }
    fn finish(&self) {
        if let Some(b) = self.bar.lock().expect("progress bar").take() {
            b.finish_and_clear();
        }
    }
    fn peak_memory_mib(&self) -> Option<f64> {
        super::os_memory::peak_rss_mib()
    }
    fn memory_freed(&self) {
        super::os_memory::release_free_memory();
    }
    fn warn(&self, message: &str) {
        // Quiet hides progress, not warnings.
        let line = format!("gcm-ortho: warning: {}", super::flag_names::with_flags(message));
        match self.bar.lock().expect("progress bar").as_ref() {
            Some(b) if self.shown => b.suspend(|| eprintln!("{line}")),
            _ => eprintln!("{line}"),
        }
    }
}

/// Counted in units of work, shown as the lines they stand for (output rows
/// or columns) and, for a task that reads, megabytes of input a second.
fn style(task: &Task) -> ProgressStyle {
    let (units, lines, input_bytes) = (task.units, task.lines, task.input_bytes);
    let rate = if input_bytes > 0 { "{input_rate}" } else { "{per_sec}" };
    // A task not of lines shows its units: bytes read, or the things done.
    let done = match (lines, input_bytes) {
        (0, 0) => "{pos}/{len}",
        (0, _) => "{bytes}/{total_bytes}",
        _ => "{lines}",
    };
    ProgressStyle::with_template(&format!("{:>8} [{{bar:40}}] {done} {} {rate} ETA {{eta}}", task.name, task.line_name))
        .expect("valid template")
        .with_key("lines", move |s: &ProgressState, w: &mut dyn Write| {
            let _ = write!(w, "{}/{lines}", rows_done(s.pos(), units, lines));
        })
        .with_key("input_rate", move |s: &ProgressState, w: &mut dyn Write| {
            let _ = write!(w, "{:.0} MB/s", input_mb_per_s(s.per_sec(), units, input_bytes));
        })
        .progress_chars("=> ")
}

/// Rows done when `pos` of `units` are: the same share of `rows`.
pub fn rows_done(pos: u64, units: u64, rows: u64) -> u64 {
    (pos.min(units) as u128 * rows as u128 / units.max(1) as u128) as u64
}

/// Megabytes (10⁶ bytes) of input a second at `units_per_s`.
pub fn input_mb_per_s(units_per_s: f64, units: u64, input_bytes: u64) -> f64 {
    units_per_s * input_bytes as f64 / units.max(1) as f64 / 1e6
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_and_rate_follow_the_units_done() {
        // 76 tiles across 75 bands of a 19182-row output from a 1 GiB scan.
        let units = 76 * 75;
        assert_eq!(rows_done(0, units, 19182), 0);
        assert_eq!(rows_done(units / 2, units, 19182), 9591);
        assert_eq!(rows_done(units, units, 19182), 19182);
        assert_eq!(rows_done(units + 5, units, 19182), 19182);
        assert_eq!(rows_done(3, 0, 10), 0, "no work, no division by zero");
        // The whole scan in 2 s: 537 MB/s.
        let rate = input_mb_per_s(units as f64 / 2.0, units, 1_073_672_172);
        assert!((rate - 536.836_086).abs() < 1e-3, "{rate}");
    }
}
