//! `--compress jpeg`: YCbCr tiles with 2×2 subsampled chroma (grey as it
//! is) and the internal mask, as GDAL reads them. The loss is measured
//! against the same run uncompressed and set beside GDAL's own JPEG of that
//! file at the same quality (libjpeg through libtiff): the codec's loss,
//! not ours. Under CI, GDAL must be there.

mod common;
use common::*;
use std::path::Path;
use std::process::Command;

/// Per quality: the mean and largest difference of `jpeg` to `plain` over
/// the pixels with a value, at the mask's edge (within 8 px of a pixel
/// without one) and inside, as GDAL decodes them; whether the masks are
/// equal; GDAL's description of the file.
const LOSS: &str = r#"
import sys, json
import numpy as np
from osgeo import gdal
gdal.UseExceptions()
jpeg, plain = gdal.Open(sys.argv[1]), gdal.Open(sys.argv[2])
a = jpeg.ReadAsArray().astype(np.float64).reshape(jpeg.RasterCount, jpeg.RasterYSize, jpeg.RasterXSize)
b = plain.ReadAsArray().astype(np.float64).reshape(a.shape)
m = jpeg.GetRasterBand(1).GetMaskBand().ReadAsArray() > 0
same_mask = bool((m == (plain.GetRasterBand(1).GetMaskBand().ReadAsArray() > 0)).all())
# Pixels within 8 px of a hole: an erosion by a 17-px square.
inner = m.copy()
for axis in (0, 1):
    for s in range(1, 9):
        inner &= np.roll(m, s, axis) & np.roll(m, -s, axis)
edge = m & ~inner
d = np.abs(a - b)
out = {"same_mask": same_mask, "mean": d[:, m].mean(), "max": d[:, m].max(), "edge_mean": d[:, edge].mean(), "inner_mean": d[:, inner].mean(),
       "edge_px": int(edge.sum()), "compression": jpeg.GetMetadata("IMAGE_STRUCTURE").get("COMPRESSION"),
       "mask_flags": jpeg.GetRasterBand(1).GetMaskFlags(), "overviews": jpeg.GetRasterBand(1).GetOverviewCount()}
print(json.dumps(out))
"#;

fn python(script: &str, args: &[&str]) -> serde_json::Value {
    let py = python_with("osgeo.gdal", "python3-gdal").expect("GDAL's Python bindings");
    let out = Command::new(py).arg("-c").arg(script).args(args).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

fn rectify(sc: &gcm_ortho::synth::SynthReport, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut a = vec!["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(out), "--quiet"];
    a.extend_from_slice(extra);
    run(&a)
}

fn gdal_ready() -> bool {
    let ok = python_with("osgeo.gdal", "python3-gdal").is_some() && have("gdal_translate");
    assert!(ok || std::env::var_os("CI").is_none(), "CI must compare with GDAL (apt-get install gdal-bin python3-gdal)");
    if !ok {
        eprintln!("skipped: GDAL is not installed (apt-get install gdal-bin python3-gdal)");
    }
    ok
}

#[test]
fn jpeg_tiles_lose_what_gdals_own_jpeg_loses_and_keep_the_mask() {
    if !gdal_ready() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A turned drone frame over buildings: sharp edges, and a footprint
    // whose edge cuts most tiles.
    let sc = drone_scene(&d.join("scene"), (1200, 900), 19000.0);
    let plain = d.join("plain.tif");
    assert!(rectify(&sc, &plain, &["--compress", "none", "--overviews", "none"]).status.success());
    for quality in [50, 75, 95] {
        let q = quality.to_string();
        let ours = d.join(format!("ours-{q}.tif"));
        let r = rectify(&sc, &ours, &["--compress", "jpeg", "--quality", &q, "--overviews", "none"]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        // GDAL's JPEG of the same pixels at the same quality, its mask too.
        let gdals = d.join(format!("gdal-{q}.tif"));
        let st = Command::new("gdal_translate")
            .args(["-q", "-co", "COMPRESS=JPEG", "-co", "PHOTOMETRIC=YCBCR", "-co", "TILED=YES", "-co", &format!("JPEG_QUALITY={q}")])
            .args(["--config", "GDAL_TIFF_INTERNAL_MASK", "YES", s(&plain), s(&gdals)])
            .status()
            .unwrap();
        assert!(st.success());
        let o = python(LOSS, &[s(&ours), s(&plain)]);
        let g = python(LOSS, &[s(&gdals), s(&plain)]);
        let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap();
        let (size_o, size_g) = (std::fs::metadata(&ours).unwrap().len(), std::fs::metadata(&gdals).unwrap().len());
        eprintln!(
            "quality {q}: ours mean {:.2} (edge {:.2}, inside {:.2}) max {} {} B; GDAL's mean {:.2} (edge {:.2}, inside {:.2}) max {} {} B",
            f(&o, "mean"),
            f(&o, "edge_mean"),
            f(&o, "inner_mean"),
            f(&o, "max"),
            size_o,
            f(&g, "mean"),
            f(&g, "edge_mean"),
            f(&g, "inner_mean"),
            f(&g, "max"),
            size_g
        );
        assert_eq!(o["compression"], "YCbCr JPEG");
        assert_eq!(o["mask_flags"], 2, "GDAL's PER_DATASET mask");
        assert_eq!(o["same_mask"], true, "the mask is the lossless run's, exactly");
        assert!(f(&o, "edge_px") > 1000.0, "the scene has a mask edge");
        // The codec's own loss: as GDAL's inside, less at the mask's edge
        // (holes are filled from their neighbours before coding).
        assert!(f(&o, "inner_mean") <= 1.1 * f(&g, "inner_mean") + 0.05, "quality {q}: inside");
        assert!(f(&o, "edge_mean") <= f(&g, "edge_mean"), "quality {q}: at the mask's edge");
        assert!(f(&o, "mean") > 0.2, "quality {q}: lossy at all");
        // The tables shared by the tiles, as libtiff does: sizes alike.
        assert!((size_o as f64) < 1.05 * size_g as f64, "quality {q}: {size_o} vs {size_g} bytes");
    }
    // Our own reader decodes the file (as `assemble` does) as GDAL does,
    // to the rounding of the chroma's upsampling.
    let file = d.join("ours-75.tif");
    let (ours, info) = whole_image(&file);
    assert_eq!((info.compression, info.photometric, info.bands), (7, 2, 3), "YCbCr read as RGB");
    let raw = d.join("gdal-decoded.raw");
    let py = python_with("osgeo.gdal", "python3-gdal").unwrap();
    let dump = "import sys\nfrom osgeo import gdal\nds = gdal.Open(sys.argv[1])\nopen(sys.argv[2], 'wb').write(ds.ReadAsArray(interleave='pixel').tobytes())";
    assert!(Command::new(py).args(["-c", dump, s(&file), s(&raw)]).status().unwrap().success());
    let theirs = std::fs::read(&raw).unwrap();
    assert_eq!(ours.len(), theirs.len());
    let diff: Vec<u8> = ours.iter().zip(&theirs).map(|(&a, &b)| a.abs_diff(b)).collect();
    let mean = diff.iter().map(|&x| x as f64).sum::<f64>() / diff.len() as f64;
    let max = *diff.iter().max().unwrap();
    eprintln!("our decoding vs GDAL's: mean {mean:.3}, max {max}");
    assert!(mean < 0.5 && max <= 16, "mean {mean:.3}, max {max}");
}

#[test]
fn grey_jpeg_is_plain_and_the_wrong_inputs_are_refused_by_name() {
    if !gdal_ready() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let grey = scene(&d.join("grey"), 500, |o| o.bands = 1);
    let out = d.join("g.tif");
    let r = rectify(&grey, &out, &["--compress", "jpeg", "--cog"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let j: serde_json::Value = serde_json::from_slice(&Command::new("gdalinfo").args(["-json", s(&out)]).output().unwrap().stdout).unwrap();
    assert_eq!(j["metadata"]["IMAGE_STRUCTURE"]["COMPRESSION"], "JPEG");
    assert_eq!(j["bands"][0]["colorInterpretation"], "Gray");
    assert_eq!(j["bands"][0]["mask"]["flags"], serde_json::json!(["PER_DATASET"]));
    // Refused, naming the option, nothing written: 16-bit, four bands, an
    // alpha band, a nodata value, a level instead of a quality, a quality
    // out of range or for a lossless codec.
    let wide = scene(&d.join("wide"), 300, |o| o.bits = 16);
    let four = scene(&d.join("four"), 300, |o| o.bands = 4);
    let rgb = scene(&d.join("rgb"), 300, |_| {});
    let bad = d.join("bad.tif");
    for (sc, extra, says) in [
        (&wide, vec!["--compress", "jpeg"], "--compress: jpeg holds 8-bit samples, these are 16-bit"),
        (&four, vec!["--compress", "jpeg"], "--compress: jpeg holds grey or RGB images, this one has 4 bands"),
        (&rgb, vec!["--compress", "jpeg", "--alpha"], "--compress: jpeg holds no alpha band"),
        (&rgb, vec!["--compress", "jpeg", "--nodata", "0"], "--compress: jpeg does not keep a nodata value"),
        (&rgb, vec!["--compress", "jpeg", "--level", "6"], "--level: 6: jpeg compression takes a quality"),
        (&rgb, vec!["--compress", "jpeg", "--quality", "0"], "--quality: 0: jpeg takes 1 to 100"),
        (&rgb, vec!["--quality", "80"], "--quality: 80: only jpeg compression has a quality"),
    ] {
        let r = rectify(sc, &bad, &extra);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains(says), "{extra:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(!bad.exists());
    }
}
