//! The output as the ecosystem's reference reader sees it. These tests need
//! GDAL's command-line tools (CI installs gdal-bin); without them they print
//! why they are skipped.

mod common;
use common::*;
use std::process::Command;

fn gdalinfo_json(path: &std::path::Path) -> serde_json::Value {
    let out = Command::new("gdalinfo").args(["-json", s(path)]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn gdal_reads_size_blocks_crs_geotransform_and_nodata() {
    if !have("gdalinfo") {
        eprintln!("skipped: gdalinfo not installed (apt-get install gdal-bin)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 600, |_| {});
    let out = dir.path().join("ortho.tif");
    let r = run(&[
        "rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(&out), "--quiet",
        "--gsd", "2.5", "--bounds", "649000,4889000,651000,4891000", "--tile", "128", "--nodata", "7",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let j = gdalinfo_json(&out);
    assert_eq!(j["size"], serde_json::json!([800, 800]));
    assert_eq!(j["geoTransform"], serde_json::json!([649000.0, 2.5, 0.0, 4891000.0, 0.0, -2.5]));
    let wkt = j["coordinateSystem"]["wkt"].as_str().unwrap();
    assert!(wkt.contains("UTM zone 31N") && wkt.contains("ID[\"EPSG\",32631]"), "{wkt}");
    for b in j["bands"].as_array().unwrap() {
        assert_eq!(b["block"], serde_json::json!([128, 128]));
        assert_eq!(b["noDataValue"], serde_json::json!(7.0));
        assert_eq!(b["type"], "Byte");
    }
    assert_eq!(j["bands"].as_array().unwrap().len(), 3);
    assert_eq!(j["metadata"]["IMAGE_STRUCTURE"]["COMPRESSION"], "DEFLATE");
    // GDAL decodes every tile (a broken tile would fail the checksum run).
    let cs = Command::new("gdalinfo").args(["-checksum", s(&out)]).output().unwrap();
    assert!(cs.status.success() && !String::from_utf8_lossy(&cs.stderr).contains("ERROR"));
}

#[test]
fn gdal_reads_alpha_bigtiff_and_every_compression() {
    if !have("gdalinfo") {
        eprintln!("skipped: gdalinfo not installed (apt-get install gdal-bin)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 400, |o| o.bits = 16);
    let mut sums = Vec::new();
    for comp in ["none", "deflate", "lzw", "zstd"] {
        let out = dir.path().join(format!("{comp}.tif"));
        let r = run(&[
            "rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(&out), "--quiet",
            "--compress", comp, "--alpha", "--bigtiff", if comp == "lzw" { "yes" } else { "no" },
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let j = gdalinfo_json(&out);
        let bands = j["bands"].as_array().unwrap();
        assert_eq!(bands.len(), 4);
        assert_eq!(bands[3]["colorInterpretation"], "Alpha");
        assert_eq!(bands[0]["type"], "UInt16");
        let cs = Command::new("gdalinfo").args(["-checksum", s(&out)]).output().unwrap();
        let text = String::from_utf8_lossy(&cs.stdout).to_string();
        if comp == "zstd" && String::from_utf8_lossy(&cs.stderr).contains("ZSTD") {
            eprintln!("this GDAL lacks ZSTD; skipped the zstd checksum");
            continue;
        }
        let checks: Vec<String> = text.lines().filter(|l| l.contains("Checksum=")).map(str::to_string).collect();
        assert_eq!(checks.len(), 4, "{text}");
        sums.push(checks);
    }
    // Every compression decodes to the same pixels.
    for s in &sums[1..] {
        assert_eq!(s, &sums[0]);
    }
}

#[test]
fn planar_input_made_by_gdal_gives_the_same_orthophoto() {
    if !have("gdal_translate") {
        eprintln!("skipped: gdal_translate not installed (apt-get install gdal-bin)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 500, |_| {});
    let planar = dir.path().join("planar.tif");
    let t = Command::new("gdal_translate").args(["-q", "-co", "INTERLEAVE=BAND", "-co", "TILED=YES", "-co", "COMPRESS=PACKBITS", s(&sc.scan), s(&planar)]).status().unwrap();
    assert!(t.success());
    let mut outs = Vec::new();
    for (name, img) in [("chunky", &sc.scan), ("planar", &planar)] {
        let out = dir.path().join(format!("{name}.tif"));
        let r = run(&["rectify", "--image", s(img), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(&out), "--quiet"]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        outs.push(std::fs::read(&out).unwrap());
    }
    assert!(outs[0] == outs[1]);
}
