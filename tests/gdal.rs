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
        "rectify",
        "--image",
        s(&sc.scan),
        "--camera",
        s(&sc.camera),
        "--dem",
        s(&sc.dem),
        "-o",
        s(&out),
        "--quiet",
        "--gsd",
        "2.5",
        "--bounds",
        "649000,4889000,651000,4891000",
        "--tile",
        "128",
        "--nodata",
        "7",
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
            "rectify",
            "--image",
            s(&sc.scan),
            "--camera",
            s(&sc.camera),
            "--dem",
            s(&sc.dem),
            "-o",
            s(&out),
            "--quiet",
            "--compress",
            comp,
            "--alpha",
            "--bigtiff",
            if comp == "lzw" { "yes" } else { "no" },
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
    let t = Command::new("gdal_translate")
        .args(["-q", "-co", "INTERLEAVE=BAND", "-co", "TILED=YES", "-co", "COMPRESS=PACKBITS", s(&sc.scan), s(&planar)])
        .status()
        .unwrap();
    assert!(t.success());
    let mut outs = Vec::new();
    for (name, img) in [("chunky", &sc.scan), ("planar", &planar)] {
        let out = dir.path().join(format!("ortho_{name}.tif"));
        let r = run(&["rectify", "--image", s(img), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(&out), "--quiet"]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        outs.push(content(&out));
    }
    assert!(outs[0] == outs[1]);
}

/// Copies `src` with `gdal_translate` and these creation options.
fn gdal_copy(src: &std::path::Path, dst: &std::path::Path, opts: &[&str]) -> bool {
    let mut args = vec!["-q"];
    for o in opts {
        args.extend(["-co", o]);
    }
    let r = Command::new("gdal_translate").args(&args).args([s(src), s(dst)]).output().unwrap();
    if !r.status.success() {
        eprintln!("gdal_translate {opts:?}: {}", String::from_utf8_lossy(&r.stderr));
    }
    r.status.success()
}

/// The orthophoto of a scene with this scan and DEM: what it shows (its
/// metadata names the files it was made from).
fn ortho(sc: &gcm_ortho::synth::SynthReport, scan: &std::path::Path, dem: &std::path::Path, out: &std::path::Path) -> Content {
    let r = run(&["rectify", "--image", s(scan), "--camera", s(&sc.camera), "--dem", s(dem), "-o", s(out), "--quiet", "--compress", "none"]);
    assert!(r.status.success(), "{}: {}", s(scan), String::from_utf8_lossy(&r.stderr));
    content(out)
}

#[test]
fn an_rgb_nir_scan_compressed_by_gdal_gives_the_same_orthophoto_in_every_coding() {
    if !have("gdal_translate") {
        eprintln!("skipped: gdal_translate not installed (apt-get install gdal-bin)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // 16-bit RGB + a 4th band that is not alpha: interleaved, the `tiff`
    // crate would decode three bands; big-endian copies test byte order.
    let sc = scene(&dir.path().join("scene"), 500, |o| {
        o.bands = 4;
        o.bits = 16;
    });
    let j = gdalinfo_json(&sc.scan);
    assert_eq!(j["bands"][3]["colorInterpretation"], "Undefined");
    let want = ortho(&sc, &sc.scan, &sc.dem, &dir.path().join("plain-ortho.tif"));
    let mut made = 0;
    for (name, opts) in [
        ("deflate-h", &["COMPRESS=DEFLATE", "PREDICTOR=2"][..]),
        ("lzw-tiles", &["COMPRESS=LZW", "TILED=YES", "BLOCKXSIZE=48", "BLOCKYSIZE=32"][..]),
        ("lzw-h-big", &["COMPRESS=LZW", "PREDICTOR=2", "ENDIANNESS=BIG", "BLOCKYSIZE=7"][..]),
        ("packbits-big-tiles", &["COMPRESS=PACKBITS", "ENDIANNESS=BIG", "TILED=YES"][..]),
        ("zstd-h", &["COMPRESS=ZSTD", "PREDICTOR=2", "TILED=YES", "BLOCKXSIZE=64", "BLOCKYSIZE=16"][..]),
    ] {
        let copy = dir.path().join(format!("{name}.tif"));
        if !gdal_copy(&sc.scan, &copy, opts) {
            assert!(name.starts_with("zstd"), "GDAL could not write {name}");
            eprintln!("this GDAL lacks ZSTD; skipped {name}");
            continue;
        }
        let got = ortho(&sc, &copy, &sc.dem, &dir.path().join(format!("{name}-ortho.tif")));
        assert!(got == want, "{name} gives another orthophoto");
        made += 1;
    }
    assert!(made >= 4);
}

#[test]
fn a_dem_compressed_by_gdal_gives_the_same_orthophoto_in_every_coding() {
    if !have("gdal_translate") {
        eprintln!("skipped: gdal_translate not installed (apt-get install gdal-bin)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 400, |_| {});
    let j = gdalinfo_json(&sc.dem);
    assert_eq!(j["bands"][0]["type"], "Float32");
    let want = ortho(&sc, &sc.scan, &sc.dem, &dir.path().join("plain-ortho.tif"));
    // Float32 heights in every coding, and Float64 (exact for them). LZW
    // tiles whose data ends on a tile's last byte failed in the `tiff`
    // crate's reader (image-rs/image-tiff#395).
    for (name, opts) in [
        ("lzw-fp-tiles", &["COMPRESS=LZW", "PREDICTOR=3", "TILED=YES", "BLOCKXSIZE=16", "BLOCKYSIZE=16"][..]),
        ("lzw-tiles-48", &["COMPRESS=LZW", "TILED=YES", "BLOCKXSIZE=48", "BLOCKYSIZE=48"][..]),
        ("deflate-h-big", &["COMPRESS=DEFLATE", "PREDICTOR=2", "ENDIANNESS=BIG"][..]),
        // (Not PREDICTOR=3 with ENDIANNESS=BIG: GDAL reads its own such
        // files back as other numbers.)
        ("deflate-fp-strips", &["COMPRESS=DEFLATE", "PREDICTOR=3", "BLOCKYSIZE=5"][..]),
        ("packbits", &["COMPRESS=PACKBITS"][..]),
        ("float64-fp", &["COMPRESS=DEFLATE", "PREDICTOR=3"][..]),
    ] {
        let copy = dir.path().join(format!("{name}.tif"));
        let ok = if name.starts_with("float64") {
            Command::new("gdal_translate")
                .args(["-q", "-ot", "Float64"])
                .args(opts.iter().flat_map(|o| ["-co", o]))
                .args([s(&sc.dem), s(&copy)])
                .status()
                .unwrap()
                .success()
        } else {
            gdal_copy(&sc.dem, &copy, opts)
        };
        assert!(ok, "GDAL could not write {name}");
        let got = ortho(&sc, &sc.scan, &copy, &dir.path().join(format!("{name}-ortho.tif")));
        assert!(got == want, "the DEM as {name} gives another orthophoto");
    }
    // Int16 heights (as SRTM has them): every coding as the plain copy.
    let int16 = dir.path().join("int16.tif");
    assert!(Command::new("gdal_translate").args(["-q", "-ot", "Int16", s(&sc.dem), s(&int16)]).status().unwrap().success());
    let want16 = ortho(&sc, &sc.scan, &int16, &dir.path().join("int16-ortho.tif"));
    for (name, opts) in [
        ("int16-lzw-h-tiles", &["COMPRESS=LZW", "PREDICTOR=2", "TILED=YES", "BLOCKXSIZE=32", "BLOCKYSIZE=16"][..]),
        ("int16-deflate-big", &["COMPRESS=DEFLATE", "ENDIANNESS=BIG"][..]),
    ] {
        let copy = dir.path().join(format!("{name}.tif"));
        assert!(gdal_copy(&int16, &copy, opts), "GDAL could not write {name}");
        let got = ortho(&sc, &sc.scan, &copy, &dir.path().join(format!("{name}-ortho.tif")));
        assert!(got == want16, "the DEM as {name} gives another orthophoto");
    }
}

#[test]
fn a_jpeg_compressed_rgb_scan_gives_the_orthophoto_within_jpeg_loss() {
    if !have("gdal_translate") {
        eprintln!("skipped: gdal_translate not installed (apt-get install gdal-bin)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 400, |_| {});
    let jpeg = dir.path().join("jpeg.tif");
    assert!(gdal_copy(&sc.scan, &jpeg, &["COMPRESS=JPEG", "PHOTOMETRIC=RGB", "JPEG_QUALITY=90", "TILED=YES"]));
    let want = ortho(&sc, &sc.scan, &sc.dem, &dir.path().join("a.tif")).0;
    let got = ortho(&sc, &jpeg, &sc.dem, &dir.path().join("b.tif")).0;
    assert_eq!(got.len(), want.len());
    let mean = got.iter().zip(&want).map(|(&a, &b)| (a as f64 - b as f64).abs()).sum::<f64>() / got.len() as f64;
    // JPEG at quality 90 moves a level or two on average; a band dropped,
    // swapped or misplaced would move tens.
    assert!(mean < 3.0, "mean difference {mean} levels");
    // YCbCr (GDAL's usual JPEG, chroma 2×2 subsampled): the same
    // orthophoto as from GDAL's own decoding of the file (libjpeg's
    // upsampling and colour conversion, as ours), to a level, no bias.
    let ycbcr = dir.path().join("ycbcr.tif");
    assert!(gdal_copy(&sc.scan, &ycbcr, &["COMPRESS=JPEG", "PHOTOMETRIC=YCBCR", "TILED=YES"]));
    let by_gdal = dir.path().join("ycbcr-decoded-by-gdal.tif");
    assert!(Command::new("gdal_translate").args(["-q", s(&ycbcr), s(&by_gdal)]).status().unwrap().success());
    let want = ortho(&sc, &by_gdal, &sc.dem, &dir.path().join("c.tif")).0;
    let got = ortho(&sc, &ycbcr, &sc.dem, &dir.path().join("d.tif")).0;
    let diff: Vec<f64> = got.iter().zip(&want).map(|(&a, &b)| a as f64 - b as f64).collect();
    let (bias, max) = (diff.iter().sum::<f64>() / diff.len() as f64, diff.iter().map(|d| d.abs()).fold(0.0, f64::max));
    // (The tiff crate's decoding, with libjpeg's colour arithmetic after
    // it, was +0.2 to +0.3 levels off in the mean and 10 at most.)
    assert!(bias.abs() < 0.02 && max <= 1.0, "YCbCr: mean difference {bias}, largest {max} levels");
    assert_eq!(gdalinfo_json(&dir.path().join("d.tif"))["bands"][2]["colorInterpretation"], "Blue");
}

#[test]
fn gdal_reads_tiles_stored_column_by_column_where_they_belong() {
    if !have("gdal_translate") {
        eprintln!("skipped: gdal_translate not installed (apt-get install gdal-bin)");
        return;
    }
    // A scan turned 90°: made in bands of tile columns, its tiles stored
    // column by column. GDAL's copy of it into a striped file (its own
    // reading of the tile table) holds the same pixels as our reader sees,
    // and the same georeferencing.
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 500, |o| o.kappa_deg = 90.0);
    let out = dir.path().join("ortho.tif");
    let json = dir.path().join("r.json");
    let r =
        run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(&out), "--quiet", "--tile", "64", "--json", s(&json)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let rep: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(rep["config"]["band_order"], "columns");
    let copy = dir.path().join("copy.tif");
    assert!(gdal_copy(&out, &copy, &["COMPRESS=NONE", "TILED=NO"]));
    let pixels = |p: &std::path::Path| {
        let (bytes, info) = whole_image(p);
        (bytes, info.georef)
    };
    let (ours, gdals) = (pixels(&out), pixels(&copy));
    assert!(ours.0.iter().any(|&v| v != 0));
    let (og, gg) = (ours.1.unwrap(), gdals.1.unwrap());
    assert_eq!((og.transform, og.nodata), (gg.transform, gg.nodata));
    // GDAL adds citations to the keys; the CRS is the same.
    let crs = |k| gcm_ortho::geodesy::geokeys::crs_of(k).unwrap().unwrap();
    assert_eq!(crs(&og.keys), crs(&gg.keys));
    assert!(ours.0 == gdals.0, "GDAL places the tiles elsewhere");
}

/// GDAL's view of an orthophoto through Python: its mask flags and nodata
/// value, whether its mask and pixels equal those of the `--alpha` run
/// `alpha` (alpha band and colour bands), and how many pixels with a value
/// are black in every band.
fn mask_as_gdal_sees_it(python: &str, out: &std::path::Path, alpha: &std::path::Path) -> serde_json::Value {
    const SCRIPT: &str = r#"
import json, sys
import numpy as np
from osgeo import gdal
o, a = gdal.Open(sys.argv[1]), gdal.Open(sys.argv[2])
b = o.GetRasterBand(1)
mask = b.GetMaskBand().ReadAsArray()
data, ref = o.ReadAsArray(), a.ReadAsArray()
print(json.dumps({
    "flags": b.GetMaskFlags(),
    "nodata": b.GetNoDataValue(),
    "mask_is_alpha": bool((mask == np.where(ref[-1] > 0, 255, 0)).all()),
    "pixels_equal": bool((data == ref[:-1]).all()),
    "black_with_value": int(((data == 0).all(axis=0) & (mask > 0)).sum()),
    "without_value": int((mask == 0).sum()),
}))
"#;
    let r = Command::new(python).args(["-c", SCRIPT, s(out), s(alpha)]).output().unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    serde_json::from_slice(&r.stdout).unwrap()
}

#[test]
fn the_default_output_masks_where_there_is_no_image_and_keeps_black_pixels() {
    let Some(python) = python_with("osgeo", "python3-gdal") else { return };
    let dir = tempfile::tempdir().unwrap();
    for (bits, compress, order) in [(8, "deflate", "rows"), (8, "none", "columns"), (16, "zstd", "rows")] {
        let sc = scene(&dir.path().join(format!("scene{bits}{compress}")), 500, |o| {
            o.bits = bits;
            o.kappa_deg = 25.0;
        });
        // A black square in the middle of the image: real data, not a hole.
        let paint = "from osgeo import gdal; import sys; d = gdal.Open(sys.argv[1], gdal.GA_Update)\n\
                     for k in range(d.RasterCount): d.GetRasterBand(k + 1).WriteArray(__import__('numpy').zeros((60, 60)), 220, 220)";
        assert!(Command::new(python).args(["-c", paint, s(&sc.scan)]).status().unwrap().success());
        let rectify = |out: &std::path::Path, extra: &[&str]| {
            let mut a = vec!["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet"];
            a.extend(["--compress", compress, "--band-order", order, "-o", s(out)]);
            a.extend_from_slice(extra);
            let r = run(&a);
            assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        };
        let (out, alpha) = (dir.path().join(format!("m{bits}{compress}.tif")), dir.path().join(format!("a{bits}{compress}.tif")));
        rectify(&out, &[]);
        rectify(&alpha, &["--alpha"]);
        let j = mask_as_gdal_sees_it(python, &out, &alpha);
        if compress == "none" {
            // The mask's tiles between them are padded: every image tile starts on a page.
            let info = gcm_ortho::io::source::SourceImage::open(&out, 1 << 20).unwrap().info;
            assert!(info.chunk_table().0.iter().all(|o| o % 4096 == 0) && info.mask.is_some());
        }
        // GMF_PER_DATASET (2): one mask for all bands, and no nodata value.
        assert_eq!((j["flags"].as_u64(), j["nodata"].is_null()), (Some(2), true), "{bits}-bit {compress}: {j}");
        assert_eq!((j["mask_is_alpha"].as_bool(), j["pixels_equal"].as_bool()), (Some(true), Some(true)), "{bits}-bit {compress}: {j}");
        assert!(j["black_with_value"].as_u64().unwrap() > 2000 && j["without_value"].as_u64().unwrap() > 2000, "{bits}-bit {compress}: {j}");
    }
}

/// A DEM whose heights are in feet (its band's unit, as `gdal_edit.py
/// -units ft` sets it) gives the orthophoto of the same DEM in metres,
/// and says it took them into metres.
#[test]
fn heights_in_feet_are_taken_into_metres() {
    let Some(python) = python_with("osgeo", "python3-gdal") else { return };
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 500, |_| {});
    let feet = dir.path().join("dem_ft.tif");
    let convert = "from osgeo import gdal; import sys\n\
                   d = gdal.Translate(sys.argv[2], sys.argv[1], outputType=gdal.GDT_Float32)\n\
                   b = d.GetRasterBand(1); b.WriteArray(b.ReadAsArray() / 0.3048); b.SetUnitType('ft'); d = None";
    let r = Command::new(python).args(["-c", convert, s(&sc.dem), s(&feet)]).output().unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let ortho = |dem: &std::path::Path, name: &str| {
        let out = dir.path().join(name);
        let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(dem), "--quiet", "-o", s(&out)]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        (whole_image(&out), String::from_utf8_lossy(&r.stderr).into_owned())
    };
    // The same in US survey feet, said by a vertical CRS in feet alone
    // (GDAL writes `EPSG:32631+6360` as its code, no unit key).
    let us_feet = dir.path().join("dem_ftus.tif");
    let convert = "from osgeo import gdal; import sys\n\
                   d = gdal.Translate(sys.argv[2], sys.argv[1], outputType=gdal.GDT_Float32, outputSRS='EPSG:32631+6360')\n\
                   b = d.GetRasterBand(1); b.WriteArray(b.ReadAsArray() * 3937 / 1200); d = None";
    let r = Command::new(python).args(["-c", convert, s(&sc.dem), s(&us_feet)]).output().unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let ((metres, mi), _) = ortho(&sc.dem, "m.tif");
    for (dem, name) in [(&feet, "ft.tif"), (&us_feet, "ftus.tif")] {
        let ((ft, fi), said) = ortho(dem, name);
        assert!(said.contains("warning") && said.contains("feet") && said.contains("metres"), "{name}: {said}");
        assert_eq!((fi.width, fi.height), (mi.width, mi.height), "{name}");
        // Heights through feet and back differ by float rounding only.
        let worst = metres.iter().zip(&ft).map(|(a, b)| a.abs_diff(*b)).max().unwrap();
        assert!(worst <= 2, "{name}: {worst} DN apart");
    }
    // A unit not read here is warned of (as metres it is taken); metres,
    // however spelled, are not.
    for (unit, warned) in [("furlong", true), ("metre", false), ("m", false)] {
        let dem = dir.path().join(format!("dem_{unit}.tif"));
        let set = "from osgeo import gdal; import sys\n\
                   d = gdal.Translate(sys.argv[2], sys.argv[1]); d.GetRasterBand(1).SetUnitType(sys.argv[3]); d = None";
        assert!(Command::new(python).args(["-c", set, s(&sc.dem), s(&dem), unit]).status().unwrap().success());
        let (_, said) = ortho(&dem, &format!("{unit}.tif"));
        let named = said.contains("warning") && said.contains(&format!("heights in '{unit}'")) && said.contains("not read here");
        assert_eq!(named, warned, "{unit}: {said}");
    }
}

/// The scan's own marks of pixels without image — an alpha band, a nodata
/// value, GDAL's internal mask — make holes in the orthophoto exactly where
/// the kernel would read such a pixel, and change no other pixel. Checked
/// over every pixel with coordinate images: each output pixel of the plain
/// run holds the scan position it sampled, so which scan pixels its kernel
/// read is known.
#[test]
fn the_scans_own_holes_become_holes_exactly_where_the_kernel_reads_them() {
    let Some(python) = python_with("osgeo", "python3-gdal") else { return };
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 500, |o| o.kappa_deg = 25.0);
    let (sw, sh) = (500, 500);
    let coords = dir.path().join("coords.tif");
    coordinate_image(&coords, sw, sh);
    // The hole: scan columns 150..260, rows 180..300.
    let (hc, hr) = (150..260i64, 180..300i64);
    const MARK: &str = r#"
import sys
import numpy as np
from osgeo import gdal
gdal.UseExceptions()
src, kind, out = sys.argv[1], sys.argv[2], sys.argv[3]
a = gdal.Open(src).ReadAsArray()
b, h, w = a.shape
hole = np.zeros((h, w), bool); hole[180:300, 150:260] = True
d = gdal.GetDriverByName("GTiff")
if kind == "alpha":
    o = d.Create(out, w, h, 3, gdal.GDT_Float32, ["ALPHA=YES"])
    for i in range(2): o.GetRasterBand(i + 1).WriteArray(a[i])
    o.GetRasterBand(3).WriteArray(np.where(hole, 0, 1).astype(np.float32))
elif kind == "alpha+nodata":
    # A nodata value no pixel holds, and the alpha band: the alpha marks the hole.
    o = d.Create(out, w, h, 3, gdal.GDT_Float32, ["ALPHA=YES", "TILED=YES"])
    for i in range(2):
        o.GetRasterBand(i + 1).WriteArray(a[i])
        o.GetRasterBand(i + 1).SetNoDataValue(-1)
    o.GetRasterBand(3).WriteArray(np.where(hole, 0, 1).astype(np.float32))
    o.GetRasterBand(3).SetNoDataValue(-1)
elif kind == "nodata":
    o = d.Create(out, w, h, 2, gdal.GDT_Float32, ["TILED=YES", "COMPRESS=DEFLATE"])
    for i in range(2):
        o.GetRasterBand(i + 1).WriteArray(np.where(hole, -1, a[i]))
        o.GetRasterBand(i + 1).SetNoDataValue(-1)
else:
    gdal.SetConfigOption("GDAL_TIFF_INTERNAL_MASK", "YES")
    o = d.Create(out, w, h, 2, gdal.GDT_Float32, ["TILED=YES", "COMPRESS=DEFLATE", "BLOCKXSIZE=128", "BLOCKYSIZE=64"])
    for i in range(2): o.GetRasterBand(i + 1).WriteArray(a[i])
    o.CreateMaskBand(gdal.GMF_PER_DATASET)
    o.GetRasterBand(1).GetMaskBand().WriteArray(np.where(hole, 0, 255).astype(np.uint8))
o = None
"#;
    let ortho = |scan: &std::path::Path, name: &str, kernel: &str| {
        let out = dir.path().join(name);
        let r = run(&["rectify", "--image", s(scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--resample", kernel, "--quiet", "-o", s(&out)]);
        assert!(r.status.success(), "{name}: {}", String::from_utf8_lossy(&r.stderr));
        read_f32(&out)
    };
    for kernel in ["bilinear", "nearest"] {
        let (w, h, b, base) = ortho(&coords, &format!("base-{kernel}.tif"), kernel);
        for kind in ["alpha", "nodata", "mask", "alpha+nodata"] {
            let marked = dir.path().join(format!("{kind}.tif"));
            let r = Command::new(python).args(["-c", MARK, s(&coords), kind, s(&marked)]).output().unwrap();
            assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
            let (w2, h2, b2, got) = ortho(&marked, &format!("{kind}-{kernel}.tif"), kernel);
            assert_eq!((w2, h2), (w, h), "{kind}");
            let (mut holes, mut kept) = (0, 0);
            for p in 0..(w * h) as usize {
                let (c, r) = (base[p * b as usize] as f64, base[p * b as usize + 1] as f64);
                let (gc, gr) = (got[p * b2 as usize], got[p * b2 as usize + 1]);
                if c.is_nan() {
                    assert!(gc.is_nan(), "{kind} {kernel}: pixel {p} has a value the plain run has not");
                    continue;
                }
                // The scan pixels the kernel reads (clamped at the scan's edge).
                let (cols, rows) = if kernel == "nearest" {
                    let (i, j) = (c.floor() as i64, r.floor() as i64);
                    (i..=i, j..=j)
                } else {
                    let (i, j) = ((c - 0.5).floor() as i64, (r - 0.5).floor() as i64);
                    (i.max(0)..=(i + 1).min(sw as i64 - 1), j.max(0)..=(j + 1).min(sh as i64 - 1))
                };
                // A position a hair from a pixel edge: the float copy of it
                // may fall either side.
                let edge = |v: f64| {
                    let f = if kernel == "nearest" { v.fract() } else { (v - 0.5).fract() };
                    !(1e-3..=1.0 - 1e-3).contains(&f)
                };
                if edge(c) || edge(r) {
                    continue;
                }
                let reads_hole = cols.clone().any(|i| hc.contains(&i)) && rows.clone().any(|j| hr.contains(&j));
                if reads_hole {
                    assert!(gc.is_nan() && gr.is_nan(), "{kind} {kernel}: pixel {p} reads the hole at ({c}, {r}) but holds ({gc}, {gr})");
                    holes += 1;
                } else {
                    assert!(gc == c as f32 && gr == r as f32, "{kind} {kernel}: pixel {p} ({c}, {r}) became ({gc}, {gr})");
                    kept += 1;
                }
            }
            assert!(holes > 5000 && kept > 100_000, "{kind} {kernel}: {holes} holes, {kept} kept");
        }
    }
}
