//! `eprintln!` for the command line's modules (the binary's and the Python
//! package's copy of the command).

/// `eprintln!` that never panics: where stderr is gone (a closed pipe, as
/// under `2>&1 | head -1`) the line is dropped and the run goes on, so
/// that a reader going away never fails the work (std's panics, exit 101).
macro_rules! eprintln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($t)*);
    }};
}
