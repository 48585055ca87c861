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
    assert!(e.contains("cut.txt") && e.contains("SAMP_DEN_COEFF_7") && e.contains("missing"), "{e}");
    let cut: String = text.lines().filter(|l| !l.starts_with("LAT_SCALE")).map(|l| format!("{l}\n")).collect();
    let e = Rpc::parse_text(&cut, Path::new("cut.txt")).unwrap_err().to_string();
    assert!(e.contains("LAT_SCALE missing"), "{e}");
}

fn ventoux(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/ventoux").join(name)
}

fn close(rpc: &Rpc, p: (f64, f64, f64), want: (f64, f64), tol: f64, what: &str) {
    let (c, r) = rpc.project(p.0, p.1, p.2).unwrap();
    assert!((c - want.0).abs() < tol && (r - want.1).abs() < tol, "{what}: ({c}, {r}) vs ({}, {})", want.0, want.1);
}

/// The same Pléiades scene as an OSSIM keyword list (0-based pixels) and as
/// DIMAP XML ((1, 1) = first pixel): after the DIMAP shift both give the
/// same pixel, to the precision the .geom prints its numbers with.
#[test]
fn dimap_and_ossim_geom_of_one_scene_agree() {
    let geom = Rpc::read(&ventoux("left_image.geom")).unwrap();
    let dimap = Rpc::read(&ventoux("RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML")).unwrap();
    assert_eq!(geom.line_off, 21109.5);
    assert!((dimap.line_off - 21109.5).abs() < 1e-9 && (dimap.samp_off - 19207.5).abs() < 1e-9);
    for p in [(5.2846, 44.137, 1075.0), (5.20, 44.20, 600.0), (5.40, 44.05, 1800.0)] {
        let want = dimap.project(p.0, p.1, p.2).unwrap();
        close(&geom, p, want, 1e-6, "geom vs DIMAP");
    }
}

/// Golden values from the rpcm project's reader and model (an independent
/// implementation; its pixel centres are at 0, ours at ½).
#[test]
fn xml_readers_match_rpcm() {
    let cases: [(&str, PathBuf, (f64, f64, f64), (f64, f64)); 4] = [
        ("WorldView-2", fx("rpc_WV2.xml"), (-0.3248, 45.6543, 97.0), (14104.1695925412, 10125.381115577)),
        ("WorldView-2", fx("rpc_WV2.xml"), (-0.30, 45.67, 150.0), (19601.075744337348, 6556.053249899548)),
        ("Pléiades DIMAP", ventoux("RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML"), (5.2846, 44.137, 1075.0), (19113.19782004122, 21147.052657720364)),
        ("SPOT 6 DIMAP", fx("rpc_SPOT6.xml"), (-72.26, 18.57, 500.0), (11478.129935618585, 12764.211207623881)),
    ];
    for (what, path, p, (c, r)) in cases {
        let rpc = Rpc::read(&path).unwrap();
        close(&rpc, p, (c + 0.5, r + 0.5), 1e-6, what);
    }
}

/// The RPB sidecar GDAL wrote for the Pléiades GeoTIFF (`gdal_translate -co
/// RPB=YES`) holds the same model as the file's RPC tag.
#[test]
fn rpb_sidecar_equals_the_geotiff_tag() {
    let tag = Rpc::read(&fx("PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif")).unwrap();
    let rpb = Rpc::read(&fx("PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.RPB")).unwrap();
    for p in [(7.18, 43.68, 670.0), (7.1, 43.65, 300.0)] {
        close(&rpb, p, tag.project(p.0, p.1, p.2).unwrap(), 1e-6, "RPB vs tag");
    }
}

/// The NITF RPC00B TRE, against GDAL's RPC transformer on the same file
/// (GDAL 3.6, pixel centres at ½).
#[test]
fn nitf_rpc00b_tre_matches_gdal() {
    let rpc = Rpc::read(&fx("wv3_20.NTF")).unwrap();
    close(&rpc, (-58.6024, -34.5043, 31.0), (20856.0501775, 17538.717519972), 1e-6, "NITF");
    close(&rpc, (-58.5924, -34.5143, 81.0), (18195.08183080436, 14131.091302820176), 1e-6, "NITF");
}

/// `locate` inverts `project` to the asked tolerance.
#[test]
fn locate_inverts_project() {
    let rpc = Rpc::read(&fx("rpc_WV2.xml")).unwrap();
    for (c, r, h) in [(100.0, 200.0, 97.0), (14000.0, 10000.0, 300.0), (28000.0, 21000.0, 0.0)] {
        let (lon, lat) = rpc.locate(c, r, h, 1e-6).unwrap();
        close(&rpc, (lon, lat, h), (c, r), 1e-6, "locate");
    }
}

/// Files that are not RPC, or hold an RPC of a kind we do not read, say so.
#[test]
fn unsupported_formats_are_named() {
    let e = Rpc::read(&fx("rpc_unsupported.xml")).unwrap_err().to_string();
    assert!(e.contains("rpc_unsupported.xml") && e.contains("VRTDataset"), "{e}");
    let e = Rpc::read(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini/scan.tif")).unwrap_err().to_string();
    assert!(e.contains("scan.tif") && e.contains("no RPC tag"), "{e}");
    let geom = std::fs::read_to_string(ventoux("left_image.geom")).unwrap().replace("polynomial_format:  B", "polynomial_format:  A");
    let e = Rpc::parse_geom(&geom, Path::new("a.geom")).unwrap_err().to_string();
    assert!(e.contains("a.geom") && e.contains("polynomial_format A"), "{e}");
    let e = Rpc::parse_nitf(b"NITF02.10 no tre here", Path::new("x.ntf")).unwrap_err().to_string();
    assert!(e.contains("x.ntf") && e.contains("RPC00B"), "{e}");
}
