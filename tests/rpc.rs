//! The RPC model and its readers on real files (fixtures/rpc, from the rpcm
//! and shareloc projects; see the licences there), against GDAL's RPC
//! transformer.

mod common;
use common::*;
use gcm_ortho::camera::rpc::Rpc;
use std::path::{Path, PathBuf};
use std::process::Command;

fn fx(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/rpc").join(name)
}

/// Golden values from `gdaltransform -rpc -i` (GDAL 3.6) on the Pléiades
/// GeoTIFF's RPC tag: (lon, lat, h) → (pixel, line), GDAL pixel coordinates
/// with the first pixel's centre at 0.5.
#[test]
fn geotiff_rpc_tag_matches_gdal() {
    let rpc = Rpc::from_geotiff(&fx("PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif")).unwrap();
    for ((lon, lat, h), (c, r)) in [
        ((7.18, 43.68, 670.0), (20465.1950262905, 10884.1657995612)),
        ((7.1, 43.65, 300.0), (8077.18283485928, 16910.7743255159)),
        ((7.25, 43.70, 1000.0), (31281.7116323, 6940.38433821241)),
    ] {
        let (pc, pr) = rpc.project(lon, lat, h).unwrap();
        assert!((pc - c).abs() < 1e-6 && (pr - r).abs() < 1e-6, "{pc} {pr} vs {c} {r}");
    }
}

/// The text readers: the file as a GDAL `_RPC.TXT` sidecar of a dummy image,
/// projected by GDAL and by us.
fn text_matches_gdal(name: &str, points: &[(f64, f64, f64)]) {
    let rpc = Rpc::read_text(&fx(name)).unwrap();
    if !have("gdaltransform") {
        eprintln!("skipped the GDAL comparison: gdaltransform not installed");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // A plain TIFF of ours (no RPC tag) with the file beside it as a sidecar.
    let plain = dir.path().join("plain.tif");
    std::fs::copy(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini/scan.tif"), &plain).unwrap();
    std::fs::copy(fx(name), dir.path().join("plain_RPC.TXT")).unwrap();
    let input: String = points.iter().map(|(a, b, c)| format!("{a} {b} {c}\n")).collect();
    let mut child = Command::new("gdaltransform")
        .args(["-rpc", "-i", s(&plain)])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::io::Write::write_all(child.stdin.as_mut().unwrap(), input.as_bytes()).unwrap();
    drop(child.stdin.take());
    let out = child.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let got: Vec<Vec<f64>> = text.lines().map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect()).collect();
    assert_eq!(got.len(), points.len(), "{text} {}", String::from_utf8_lossy(&out.stderr));
    for (p, g) in points.iter().zip(&got) {
        let (c, r) = rpc.project(p.0, p.1, p.2).unwrap();
        assert!((c - g[0]).abs() < 1e-6 && (r - g[1]).abs() < 1e-6, "{name}: ours ({c}, {r}) GDAL ({}, {})", g[0], g[1]);
    }
}

#[test]
fn ikonos_text_matches_gdal() {
    text_matches_gdal("rpc_IKONOS.txt", &[(-56.1722, -34.903, 28.0), (-56.2, -34.88, 60.0), (-56.14, -34.95, 0.0)]);
}

#[test]
fn skysat_rpc_txt_matches_gdal() {
    text_matches_gdal("20191015_073816_ssc1d3_0011_basic_l1a_panchromatic_dn_RPC.TXT", &[(49.6688, 25.9286, 3287.0), (49.66, 25.93, 3000.0)]);
}

#[test]
fn a_crop_shifts_the_offsets() {
    let rpc = Rpc::read_text(&fx("rpc_IKONOS.txt")).unwrap();
    let crop = rpc.cropped(1000.0, 2000.0);
    let (a, b) = (rpc.project(-56.17, -34.9, 28.0).unwrap(), crop.project(-56.17, -34.9, 28.0).unwrap());
    assert!((a.0 - 1000.0 - b.0).abs() < 1e-9 && (a.1 - 2000.0 - b.1).abs() < 1e-9);
}

#[test]
fn broken_rpc_files_are_clear_errors() {
    let e = Rpc::read_text(&fx("rpc_unsupported.xml")).unwrap_err().to_string();
    assert!(e.contains("rpc_unsupported.xml"), "{e}");
    let text = std::fs::read_to_string(fx("rpc_IKONOS.txt")).unwrap();
    let cut: String = text.lines().filter(|l| !l.starts_with("SAMP_DEN_COEFF_7:")).map(|l| format!("{l}\n")).collect();
    let e = Rpc::parse_text(&cut, Path::new("cut.txt")).unwrap_err().to_string();
    assert!(e.contains("cut.txt") && e.contains("SAMP_DEN_COEFF") && e.contains("non-finite"), "{e}");
    let cut: String = text.lines().filter(|l| !l.starts_with("LAT_SCALE")).map(|l| format!("{l}\n")).collect();
    let e = Rpc::parse_text(&cut, Path::new("cut.txt")).unwrap_err().to_string();
    assert!(e.contains("LAT_SCALE missing"), "{e}");
}
