//! The Python package (python/): its wheel builds with maturin, installs
//! into a fresh virtual environment with NumPy and Dask from PyPI, and its
//! pytest suite passes against this build's command (python/tests: files
//! byte for byte as the command's, messages, Ctrl-C, windows on a Dask
//! cluster).
//!
//! Skipped where there is no Python 3.9+ with `venv`, or PyPI cannot be
//! reached; under CI (`CI` set) that fails instead.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs `cmd`, its output shown on failure; false (and why) when it fails.
fn ran(what: &str, cmd: &mut Command) -> bool {
    match cmd.output() {
        Ok(out) if out.status.success() => true,
        Ok(out) => {
            eprintln!("{what} failed:\n{}\n{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
            false
        }
        Err(e) => {
            eprintln!("{what} did not start: {e}");
            false
        }
    }
}

/// Skips (or, under CI, fails) with `why`.
fn unavailable(why: &str) {
    assert!(std::env::var_os("CI").is_none(), "the Python package cannot be tested: {why}");
    eprintln!("skipped: {why}");
}

#[test]
fn the_python_package_builds_installs_and_passes_its_tests() {
    let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".into());
    let new_enough = Command::new(&python).args(["-c", "import sys, venv; sys.exit(sys.version_info < (3, 9))"]).status();
    if !new_enough.is_ok_and(|s| s.success()) {
        return unavailable(&format!("{python} is not a Python 3.9+ with venv"));
    }
    // A fresh environment every run: what is tested is what a user installs.
    let work = root().join("target").join("python-package");
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work).expect("a work folder");
    let env = work.join("env");
    assert!(ran("venv", Command::new(&python).args(["-m", "venv"]).arg(&env)), "a virtual environment");
    let bin = env.join("bin");
    let pip = |args: &[&str]| {
        let mut c = Command::new(bin.join("python"));
        c.args(["-m", "pip", "install", "--quiet", "--disable-pip-version-check"]).args(args);
        c
    };
    if !ran("pip install", &mut pip(&["maturin>=1.5,<2", "numpy", "pytest", "dask[distributed]"])) {
        return unavailable("the test's packages did not install from PyPI");
    }
    // The wheel, as CI would publish it, built in this build's target
    // folder (cargo holds its lock while it builds, not while tests run):
    // the library's dependencies are built once.
    let wheels = work.join("wheels");
    let built = ran(
        "maturin build",
        Command::new(bin.join("maturin"))
            .args(["build", "--release", "--quiet", "--manifest-path"])
            .arg(root().join("python").join("Cargo.toml"))
            .arg("--out")
            .arg(&wheels)
            .env("CARGO_TARGET_DIR", root().join("target")),
    );
    assert!(built, "the wheel builds");
    let wheel: Vec<PathBuf> = std::fs::read_dir(&wheels).expect("wheels").map(|e| e.expect("entry").path()).collect();
    assert_eq!(wheel.len(), 1, "one wheel: {wheel:?}");
    let name = wheel[0].file_name().and_then(|n| n.to_str()).unwrap_or_default().to_string();
    // One wheel for every CPython from 3.9 on.
    assert!(name.starts_with("gcm_ortho-") && name.contains("-cp39-abi3-"), "{name}");
    assert!(ran("pip install the wheel", &mut pip(&[wheel[0].to_str().expect("a UTF-8 path")])), "the wheel installs");
    let tests = ran(
        "pytest",
        Command::new(bin.join("python"))
            .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
            .arg(root().join("python").join("tests"))
            .current_dir(&work)
            .env("GCM_ORTHO_BIN", env!("CARGO_BIN_EXE_gcm-ortho"))
            .env("PATH", prepend(&bin)),
    );
    assert!(tests, "the package's tests pass");
}

fn prepend(dir: &Path) -> std::ffi::OsString {
    let mut paths = vec![dir.to_path_buf()];
    paths.extend(std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default()));
    std::env::join_paths(paths).expect("a PATH")
}
