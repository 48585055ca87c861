//! Helpers shared by the integration tests: scenes, running the binary.
#![allow(dead_code)]

use gcm_ortho::synth::{synth, SynthOptions, SynthReport};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_gcm-ortho"))
}

/// Runs the binary with `args`.
pub fn run(args: &[&str]) -> Output {
    Command::new(bin()).args(args).output().expect("the binary runs")
}

/// A small film scene (hilly, swing 30°) in `dir`.
pub fn scene(dir: &Path, size: u32, f: impl FnOnce(&mut SynthOptions)) -> SynthReport {
    let mut o = SynthOptions { out: dir.to_path_buf(), width: size, height: size, kappa_deg: 30.0, ..Default::default() };
    f(&mut o);
    synth(&o).expect("synth works")
}

pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Is a GDAL command-line tool installed? Tests that compare with GDAL
/// print why they are skipped when it is not (CI installs it).
pub fn have(tool: &str) -> bool {
    Command::new(tool).arg("--version").output().map(|o| o.status.success()).unwrap_or(false)
}

/// Files in `dir` whose names contain `part`.
pub fn files_containing(dir: &Path, part: &str) -> Vec<String> {
    std::fs::read_dir(dir)
        .map(|rd| rd.filter_map(|e| e.ok()).map(|e| e.file_name().to_string_lossy().into_owned()).filter(|n| n.contains(part)).collect())
        .unwrap_or_default()
}

/// Waits for a child at most `secs` seconds; a hang kills it and fails.
pub fn wait_deadline(mut child: std::process::Child, secs: u64) -> Output {
    let t = std::time::Instant::now();
    loop {
        if child.try_wait().expect("try_wait").is_some() {
            return child.wait_with_output().expect("output");
        }
        if t.elapsed().as_secs() >= secs {
            let _ = child.kill();
            panic!("the process hung for {secs} s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}
