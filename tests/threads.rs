//! `--threads 1` runs the steps one after the other (the sequential runner),
//! `--threads 2` each on a thread of its own (the threaded runner): both
//! write the same file, and fail the same way.

mod common;
use common::*;
use std::path::Path;

/// Runs rectify on `sc` into `out` with `threads` and `extra` arguments.
fn rectify(sc: &gcm_ortho::synth::SynthReport, out: &Path, threads: &str, extra: &[&str]) -> std::process::Output {
    let json = out.with_extension("json");
    let mut a = vec!["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(out), "--json", s(&json)];
    a.extend_from_slice(&["--threads", threads]);
    a.extend_from_slice(extra);
    run(&a)
}

/// The report of a run into `out`.
fn report(out: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(out.with_extension("json")).unwrap()).unwrap()
}

/// One thread and two make byte for byte the same file from `sc` with
/// `extra`, from the same chunks; returns the report of one thread.
fn assert_same_file(sc: &gcm_ortho::synth::SynthReport, dir: &Path, extra: &[&str]) -> serde_json::Value {
    let (one, two) = (dir.join("one.tif"), dir.join("two.tif"));
    for (out, threads) in [(&one, "1"), (&two, "2")] {
        let r = rectify(sc, out, threads, extra);
        assert!(r.status.success(), "{extra:?}: {}", String::from_utf8_lossy(&r.stderr));
    }
    let (a, b) = (std::fs::read(&one).unwrap(), std::fs::read(&two).unwrap());
    assert!(a == b, "{extra:?}: one thread and two wrote different files ({} and {} bytes)", a.len(), b.len());
    let (ra, rb) = (report(&one), report(&two));
    assert_eq!(ra["chunks"], rb["chunks"], "{extra:?}");
    assert_eq!(ra["chunks_in_place"], rb["chunks_in_place"], "{extra:?}");
    assert_eq!(ra["gcm"], rb["gcm"], "{extra:?}");
    // Something was made: not a file of nodata.
    let (bytes, _) = whole_image(&one);
    assert!(bytes.iter().filter(|&&v| v != 0).count() * 2 > bytes.len(), "{extra:?}: mostly empty");
    ra
}

#[test]
fn one_thread_and_two_write_the_same_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rgb = scene(&d.join("rgb"), 700, |o| o.bands = 3);
    for extra in [
        &["--compress", "none"][..],
        &["--compress", "deflate", "--alpha"],
        // Small chunks, several a band, and tiles of 64.
        &["--compress", "lzw", "--tile", "64", "--memory", "16M"],
        // A piece of the grid.
        &["--compress", "none", "--tile", "64", "--window", "4,4,4,3"],
    ] {
        let rep = assert_same_file(&rgb, d, extra);
        assert!(rep["chunks"].as_u64().unwrap() >= 2, "{extra:?}");
    }
    // A tiled, deflated scan: windows decoded tile by tile.
    let packed = scene(&d.join("packed"), 700, |o| {
        o.tiled = true;
        o.compress = gcm_ortho::io::tiff_out::Compression::Deflate;
    });
    let rep = assert_same_file(&packed, d, &["--compress", "none", "--tile", "64", "--memory", "16M"]);
    assert_eq!(rep["chunks_in_place"], 0);
    // 16-bit, turned 90°, 5 MB of scan: bands of tile columns, read in
    // place; and bands of tile rows, whose windows span more scan rows than
    // `--memory 16M` lets a chunk read in place, and are copied.
    let turned = scene(&d.join("turned"), 1600, |o| {
        o.kappa_deg = 90.0;
        o.bits = 16;
        o.bands = 1;
    });
    let rep = assert_same_file(&turned, d, &["--compress", "none", "--tile", "64", "--memory", "16M"]);
    assert_eq!(rep["config"]["band_order"], "columns");
    assert_eq!(rep["chunks_in_place"], rep["chunks"]);
    let rep = assert_same_file(&turned, d, &["--compress", "zstd", "--tile", "64", "--memory", "16M", "--band-order", "rows"]);
    assert!(rep["chunks_in_place"].as_u64().unwrap() < rep["chunks"].as_u64().unwrap(), "no window copied");
}

/// An output area beyond the DEM, with `--dem-outside error`: both runners
/// stop with one line naming the DEM, and leave no file.
#[test]
fn one_thread_and_two_fail_alike_where_the_dem_has_no_height() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("scene"), 400, |_| {});
    let probe = d.join("probe.tif");
    let r = rectify(&sc, &probe, "2", &["--compress", "none"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let g = &report(&probe)["grid"];
    let (x0, y0, gsd) = (g["x0"].as_f64().unwrap(), g["y0"].as_f64().unwrap(), g["gsd"].as_f64().unwrap());
    let (w, h) = (g["width"].as_f64().unwrap() * gsd, g["height"].as_f64().unwrap() * gsd);
    // The area and as much again east of it: the DEM ends a little past the scan's footprint.
    let bounds = format!("{},{},{},{}", x0, y0 - h, x0 + 2.0 * w, y0);
    for threads in ["1", "2"] {
        let out = d.join(format!("out{threads}.tif"));
        let r = rectify(&sc, &out, threads, &["--bounds", &bounds, "--dem-outside", "error"]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(1), "threads {threads}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "threads {threads}: {err}");
        assert!(err.contains(s(&sc.dem)) && err.contains("outside the DEM"), "threads {threads}: {err}");
        assert!(!out.exists(), "threads {threads}: output left");
        assert!(files_containing(d, "partial").is_empty(), "threads {threads}: temporary left");
    }
}

/// Scan rows read in place are given back as the run moves on: a 100 MB
/// scan made at `--memory 32M` peaks far below its size, with one thread
/// and with two (without giving them back, the mapped scan alone would
/// hold ~100 MB).
#[test]
fn scan_rows_read_in_place_are_given_back_with_one_thread_and_two() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("scene"), 5800, |o| {
        o.kappa_deg = 0.0;
        o.bands = 3;
    });
    assert!(std::fs::metadata(&sc.scan).unwrap().len() > 100_000_000);
    for threads in ["1", "2"] {
        let out = d.join(format!("out{threads}.tif"));
        let r = rectify(&sc, &out, threads, &["--compress", "none", "--memory", "32M", "--no-sync"]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let rep = report(&out);
        assert_eq!(rep["chunks_in_place"], rep["chunks"], "threads {threads}");
        let peak = rep["peak_rss_mib"].as_f64().unwrap();
        assert!(peak < 60.0, "threads {threads}: peak {peak} MiB");
        std::fs::remove_file(&out).unwrap();
    }
}
