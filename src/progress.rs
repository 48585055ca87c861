//! Progress on a terminal: an indicatif bar with rate and ETA, hidden when
//! standard error is not a terminal or the user asked for quiet.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressState, ProgressStyle};
use std::fmt::Write;
use std::io::IsTerminal;

fn hidden(quiet: bool) -> bool {
    quiet || !std::io::stderr().is_terminal()
}

/// A bar of `total` units named `what`; hidden when `quiet` or not on a terminal.
pub fn bar(total: u64, what: &str, quiet: bool) -> ProgressBar {
    if hidden(quiet) {
        return ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::hidden());
    }
    let pb = ProgressBar::new(total);
    pb.set_style(ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} {per_sec} ETA {eta}").expect("valid template").progress_chars("=> "));
    pb.set_message(what.to_string());
    pb
}

/// A bar counted in `units` of work (tiles written) that shows what they
/// stand for: output rows (or columns, `lines` named `what`) out of `rows`,
/// and megabytes of the scan's `input_bytes` read a second; hidden when
/// `quiet` or not on a terminal.
pub fn rows_bar(units: u64, rows: u64, what: &str, input_bytes: u64, quiet: bool) -> ProgressBar {
    if hidden(quiet) {
        return ProgressBar::with_draw_target(Some(units), ProgressDrawTarget::hidden());
    }
    let pb = ProgressBar::new(units);
    let style = ProgressStyle::with_template(&format!("rectify [{{bar:40}}] {{rows}} {what} {{input_rate}} ETA {{eta}}"))
        .expect("valid template")
        .with_key("rows", move |s: &ProgressState, w: &mut dyn Write| {
            let _ = write!(w, "{}/{rows}", rows_done(s.pos(), units, rows));
        })
        .with_key("input_rate", move |s: &ProgressState, w: &mut dyn Write| {
            let _ = write!(w, "{:.0} MB/s", input_mb_per_s(s.per_sec(), units, input_bytes));
        })
        .progress_chars("=> ");
    pb.set_style(style);
    pb
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
