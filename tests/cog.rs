//! Overviews and the Cloud-Optimized layout as GDAL sees them: its COG
//! validator on every layout the writer makes, the overview levels against
//! the level below averaged here, and a COG reading back as the plain
//! file. Under CI, GDAL's Python bindings must be there.

mod common;
use common::*;
use std::path::Path;
use std::process::Command;

/// GDAL's validator (full check: leaders, trailers, the mask's places):
/// its errors and warnings.
const VALIDATE: &str = r#"
import sys, json
from osgeo import gdal
from osgeo_utils.samples.validate_cloud_optimized_geotiff import validate
gdal.UseExceptions()
errors, warnings, _ = validate(sys.argv[1], full_check=True)
print(json.dumps(errors + warnings))
"#;

/// Every level of two files (bands and masks) equal, pixel for pixel.
const SAME_LEVELS: &str = r#"
import sys
import numpy as np
from osgeo import gdal
gdal.UseExceptions()
a, b = gdal.Open(sys.argv[1]), gdal.Open(sys.argv[2])
assert a.RasterCount == b.RasterCount, "bands"
levels = 0
for i in range(1, a.RasterCount + 1):
    ba, bb = a.GetRasterBand(i), b.GetRasterBand(i)
    assert ba.GetOverviewCount() == bb.GetOverviewCount(), "overview counts"
    pairs = [(ba, bb)] + [(ba.GetOverview(k), bb.GetOverview(k)) for k in range(ba.GetOverviewCount())]
    for x, y in pairs:
        np.testing.assert_array_equal(x.ReadAsArray(), y.ReadAsArray())
        np.testing.assert_array_equal(x.GetMaskBand().ReadAsArray(), y.GetMaskBand().ReadAsArray())
    levels = len(pairs)
print(levels)
"#;

/// The full level of two files (bands and mask) equal, pixel for pixel:
/// the bands' count.
const SAME_FULL_LEVEL: &str = r#"
import sys
import numpy as np
from osgeo import gdal
gdal.UseExceptions()
a, b = gdal.Open(sys.argv[1]), gdal.Open(sys.argv[2])
np.testing.assert_array_equal(a.ReadAsArray(), b.ReadAsArray())
np.testing.assert_array_equal(a.GetRasterBand(1).GetMaskBand().ReadAsArray(), b.GetRasterBand(1).GetMaskBand().ReadAsArray())
print(a.RasterCount)
"#;

/// Each overview level against the average of the level below, made here
/// with numpy: the mean of the 2×2 pixels that have a value (the mask's),
/// rounded half up; a pixel with a value where any below has one.
const AVERAGE_OF_LEVEL_BELOW: &str = r#"
import sys
import numpy as np
from osgeo import gdal
gdal.UseExceptions()
ds = gdal.Open(sys.argv[1])
checked = 0
for i in range(1, ds.RasterCount + 1):
    band = ds.GetRasterBand(i)
    levels = [band] + [band.GetOverview(k) for k in range(band.GetOverviewCount())]
    for below, above in zip(levels, levels[1:]):
        v = below.ReadAsArray().astype(np.float64)
        m = below.GetMaskBand().ReadAsArray() > 0
        h, w = above.YSize, above.XSize
        vp = np.zeros((2 * h, 2 * w)); mp = np.zeros((2 * h, 2 * w), bool)
        vp[:v.shape[0], :v.shape[1]] = v; mp[:m.shape[0], :m.shape[1]] = m
        s = (vp * mp).reshape(h, 2, w, 2).sum(axis=(1, 3))
        n = mp.reshape(h, 2, w, 2).sum(axis=(1, 3))
        want_mask = n > 0
        want = np.floor(s / np.maximum(n, 1) + 0.5)
        got = above.ReadAsArray().astype(np.float64)
        got_mask = above.GetMaskBand().ReadAsArray() > 0
        assert (got_mask == want_mask).all(), "mask of level %dx%d" % (w, h)
        bad = np.argwhere(want_mask & (got != want))
        assert len(bad) == 0, "band %d level %dx%d: %d pixels differ, first %s: %s vs %s" % (i, w, h, len(bad), bad[0], got[tuple(bad[0])], want[tuple(bad[0])])
        assert want_mask.any() and not want_mask.all(), "the scene must have both"
        checked += 1
print(checked)
"#;

/// Each band's STATISTICS_* metadata against numpy over the pixels the
/// mask says have a value (an alpha band's mask: every pixel). A lossy
/// file's (argument "lossy") are the pixels' before coding: the mean
/// within a fraction of a level of the decoded pixels', not marked
/// approximate (GDAL would recompute them over the masked pixels too).
const STATISTICS: &str = r#"
import sys
import numpy as np
from osgeo import gdal
gdal.UseExceptions()
ds = gdal.Open(sys.argv[1])
lossy = sys.argv[2:] == ["lossy"]
for i in range(1, ds.RasterCount + 1):
    band = ds.GetRasterBand(i)
    md = band.GetMetadata()
    assert "STATISTICS_APPROXIMATE" not in md, md
    v = band.ReadAsArray().astype(np.float64)
    m = band.GetMaskBand().ReadAsArray() > 0
    want = {"MINIMUM": v[m].min(), "MAXIMUM": v[m].max(), "MEAN": v[m].mean(), "STDDEV": v[m].std(), "VALID_PERCENT": 100.0 * m.mean()}
    for k, w in want.items():
        got = float(md["STATISTICS_" + k])
        near = (0.5 if k == "MEAN" else 1.5 if k == "STDDEV" else 16.0) if lossy else 1e-9 * max(1.0, abs(w))
        assert abs(got - w) <= near, "band %d %s: %r vs numpy %r" % (i, k, got, w)
    if not lossy:
        assert band.ComputeRasterMinMax(True) == (want["MINIMUM"], want["MAXIMUM"])
print(ds.RasterCount)
"#;

/// Are GDAL's Python bindings missing (said on stderr; under CI
/// `python_with` fails the test instead)?
fn gdal_python_missing() -> bool {
    let missing = python_with("osgeo.gdal", "python3-gdal").is_none();
    if missing {
        eprintln!("skipped: GDAL's Python bindings are not installed (apt-get install python3-gdal)");
    }
    missing
}

fn python(script: &str, args: &[&str]) -> String {
    let py = python_with("osgeo.gdal", "python3-gdal").expect("GDAL's Python bindings");
    let out = Command::new(py).arg("-c").arg(script).args(args).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).trim().to_string()
}

/// `rectify` of `image` with the scene's camera and DEM into `out`, tiles
/// of 128, and `extra`.
fn rectify_run(sc: &gcm_ortho::synth::SynthReport, image: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut a = vec!["rectify", "--image", s(image), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(out), "--quiet", "--tile", "128"];
    a.extend_from_slice(extra);
    run(&a)
}

fn rectify(sc: &gcm_ortho::synth::SynthReport, image: &Path, out: &Path, extra: &[&str]) {
    let r = rectify_run(sc, image, out, extra);
    assert!(r.status.success(), "{extra:?}: {}", String::from_utf8_lossy(&r.stderr));
}

#[test]
fn every_layout_the_writer_makes_is_a_valid_cog_and_reads_back_as_the_plain_file() {
    if gdal_python_missing() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rgb = scene(&d.join("rgb"), 700, |o| o.kappa_deg = 20.0);
    let wide = scene(&d.join("wide"), 500, |o| o.bits = 16);
    // A Float32 scan the size of the 8-bit one: each pixel its own column.
    let float_scan = d.join("float-scan.tif");
    f32_raster(&float_scan, (700, 700), (0.0, 0.0, 1.0, 32631), |c, _| c as f32 + 0.5);
    let cases: Vec<(&str, &gcm_ortho::synth::SynthReport, &Path, Vec<&str>)> = vec![
        ("rgb-mask-deflate", &rgb, &rgb.scan, vec![]),
        ("rgb-columns", &rgb, &rgb.scan, vec!["--band-order", "columns"]),
        ("rgb-bigtiff", &rgb, &rgb.scan, vec!["--bigtiff", "yes"]),
        ("rgb-uncompressed", &rgb, &rgb.scan, vec!["--compress", "none"]),
        ("rgba", &rgb, &rgb.scan, vec!["--alpha"]),
        ("rgb-nodata", &rgb, &rgb.scan, vec!["--nodata", "0", "--overview-resampling", "nearest"]),
        ("u16-zstd", &wide, &wide.scan, vec!["--compress", "zstd"]),
        ("rgb-level-12", &rgb, &rgb.scan, vec!["--level", "12"]),
        ("u16-zstd-19", &wide, &wide.scan, vec!["--compress", "zstd", "--level", "19"]),
        ("u16-lzw-mode", &wide, &wide.scan, vec!["--compress", "lzw", "--overview-resampling", "mode"]),
        ("float", &rgb, &float_scan, vec![]),
        ("rgb-jpeg", &rgb, &rgb.scan, vec!["--compress", "jpeg", "--quality", "85"]),
        ("rgb-jpeg-columns", &rgb, &rgb.scan, vec!["--compress", "jpeg", "--band-order", "columns"]),
    ];
    for (name, sc, image, extra) in cases {
        let plain = d.join(format!("{name}.tif"));
        let cog = d.join(format!("{name}.cog.tif"));
        rectify(sc, image, &plain, &extra);
        let mut with_cog = extra.clone();
        with_cog.push("--cog");
        rectify(sc, image, &cog, &with_cog);
        assert_eq!(python(VALIDATE, &[s(&cog)]), "[]", "{name}: GDAL's validator");
        let levels: u32 = python(SAME_LEVELS, &[s(&plain), s(&cog)]).parse().unwrap();
        assert!(levels >= 3, "{name}: {levels} levels");
        // The plain file has the same levels, not the COG layout.
        assert_ne!(python(VALIDATE, &[s(&plain)]), "[]", "{name}: the plain file is not laid out as a COG");
    }
    // Every level of a lossless codec holds the same pixels, as GDAL reads them.
    for (a, b) in [("rgb-uncompressed", "rgb-level-12"), ("rgb-uncompressed", "rgb-mask-deflate"), ("u16-zstd", "u16-zstd-19")] {
        python(SAME_LEVELS, &[s(&d.join(format!("{a}.tif"))), s(&d.join(format!("{b}.tif")))]);
    }
    // Pieces of a run put together: a valid COG, the same levels as the
    // single run's.
    let info = gcm_ortho::io::source::SourceImage::open(&d.join("rgb-mask-deflate.tif"), 1 << 20).unwrap().info;
    let (ta, td) = (info.width.div_ceil(128), info.height.div_ceil(128));
    let (a, b) = (d.join("piece-a.tif"), d.join("piece-b.tif"));
    rectify(&rgb, &rgb.scan, &a, &["--window", &format!("0,0,2,{td}")]);
    rectify(&rgb, &rgb.scan, &b, &["--window", &format!("2,0,{},{td}", ta - 2)]);
    let joined = d.join("joined.tif");
    let r = run(&["assemble", "--cog", "-o", s(&joined), s(&a), s(&b)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(python(VALIDATE, &[s(&joined)]), "[]", "assembled pieces: GDAL's validator");
    python(SAME_LEVELS, &[s(&joined), s(&d.join("rgb-mask-deflate.tif"))]);
    // JPEG pieces: their tiles copied with their tables, the full level
    // the single run's; the overviews are made of the decoded tiles.
    let (a, b) = (d.join("jpeg-a.tif"), d.join("jpeg-b.tif"));
    rectify(&rgb, &rgb.scan, &a, &["--compress", "jpeg", "--quality", "85", "--window", &format!("0,0,2,{td}")]);
    rectify(&rgb, &rgb.scan, &b, &["--compress", "jpeg", "--quality", "85", "--window", &format!("2,0,{},{td}", ta - 2)]);
    let joined = d.join("jpeg-joined.tif");
    let r = run(&["assemble", "--cog", "-o", s(&joined), s(&a), s(&b)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(python(VALIDATE, &[s(&joined)]), "[]", "assembled JPEG pieces: GDAL's validator");
    assert_eq!(python(SAME_FULL_LEVEL, &[s(&joined), s(&d.join("rgb-jpeg.tif"))]), "3");
    // Pieces coded at two qualities cannot share one file's tables.
    let c = d.join("jpeg-c.tif");
    rectify(&rgb, &rgb.scan, &c, &["--compress", "jpeg", "--quality", "60", "--window", &format!("2,0,{},{td}", ta - 2)]);
    let r = run(&["assemble", "-o", s(&d.join("mixed.tif")), s(&a), s(&c)]);
    assert_eq!(r.status.code(), Some(2), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(String::from_utf8_lossy(&r.stderr).contains("another quality"), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(!d.join("mixed.tif").exists());
}

#[test]
fn overviews_are_the_average_of_the_level_below_under_the_mask_and_gdal_lists_them_with_the_statistics() {
    if python_with("osgeo.gdal", "python3-gdal").is_none() || !have("gdalinfo") {
        eprintln!("skipped: GDAL is not installed (apt-get install gdal-bin python3-gdal)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Turned, so that every level has pixels with and without a value.
    let sc = scene(&d.join("s"), 900, |o| o.kappa_deg = 35.0);
    let out = d.join("o.tif");
    rectify(&sc, &sc.scan, &out, &[]);
    // Three bands × every level above the full one.
    let checked: u32 = python(AVERAGE_OF_LEVEL_BELOW, &[s(&out)]).parse().unwrap();
    // The statistics in the file are the image's (GDAL shows them as the
    // band's minimum, maximum, mean and standard deviation).
    assert_eq!(python(STATISTICS, &[s(&out)]), "3");
    // An alpha band's statistics are of every pixel (0 where the colour
    // bands have none); JPEG's are marked approximate (of the pixels
    // before coding).
    let alpha = d.join("alpha.tif");
    rectify(&sc, &sc.scan, &alpha, &["--alpha"]);
    assert_eq!(python(STATISTICS, &[s(&alpha)]), "4");
    let jpeg = d.join("jpeg.tif");
    rectify(&sc, &sc.scan, &jpeg, &["--compress", "jpeg"]);
    assert_eq!(python(STATISTICS, &[s(&jpeg), "lossy"]), "3");
    let j: serde_json::Value = serde_json::from_slice(&Command::new("gdalinfo").args(["-json", s(&out)]).output().unwrap().stdout).unwrap();
    let (w, h) = (j["size"][0].as_u64().unwrap(), j["size"][1].as_u64().unwrap());
    let band = &j["bands"][0];
    let sizes: Vec<(u64, u64)> =
        band["overviews"].as_array().unwrap().iter().map(|o| (o["size"][0].as_u64().unwrap(), o["size"][1].as_u64().unwrap())).collect();
    // Halved (rounded up) until one 128-px tile holds the level.
    let mut want = Vec::new();
    let (mut lw, mut lh) = (w, h);
    while lw > 128 || lh > 128 {
        (lw, lh) = (lw.div_ceil(2), lh.div_ceil(2));
        want.push((lw, lh));
    }
    assert_eq!(sizes, want);
    assert_eq!(checked as usize, 3 * want.len());
    assert_eq!(band["mask"]["flags"], serde_json::json!(["PER_DATASET"]));
    assert_eq!(band["mask"]["overviews"].as_array().unwrap().len(), want.len());
    // None asked: none made.
    let none = d.join("none.tif");
    rectify(&sc, &sc.scan, &none, &["--overviews", "none"]);
    let j: serde_json::Value = serde_json::from_slice(&Command::new("gdalinfo").args(["-json", s(&none)]).output().unwrap().stdout).unwrap();
    assert!(j["bands"][0]["overviews"].as_array().is_none_or(|o| o.is_empty()));
}

#[test]
fn batch_writes_cogs_and_their_overviews_as_the_manifest_says() {
    if gdal_python_missing() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("scene"), 600, |_| {});
    let manifest = d.join("block.toml");
    std::fs::write(
        &manifest,
        format!(
            "[defaults]\ndem = \"{}\"\noutput_dir = \"ortho\"\ntile = 128\ncog = true\noverviews = \"2,4\"\noverview_resampling = \"mode\"\n\n[[job]]\nimage = \"{}\"\ncamera = \"{}\"\n",
            s(&sc.dem),
            s(&sc.scan),
            s(&sc.camera)
        ),
    )
    .unwrap();
    let r = run(&["batch", s(&manifest), "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let out = d.join("ortho/scan.tif");
    assert_eq!(python(VALIDATE, &[s(&out)]), "[]");
    // The full level and the two asked for.
    let levels: u32 = python(SAME_LEVELS, &[s(&out), s(&out)]).parse().unwrap();
    assert_eq!(levels, 3);
    // A list that cannot be made level from level is refused by name.
    std::fs::write(&manifest, std::fs::read_to_string(&manifest).unwrap().replace("\"2,4\"", "\"2,8\"")).unwrap();
    let r = run(&["batch", s(&manifest), "--quiet", "--force"]);
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("overviews"), "{}", String::from_utf8_lossy(&r.stderr));
    // The overviews' own level from the manifest: tighter, the same pixels;
    // one the codec does not take is refused by its key.
    let fastest = std::fs::read(&out).unwrap();
    std::fs::copy(&out, d.join("fastest.tif")).unwrap();
    let text = std::fs::read_to_string(&manifest).unwrap().replace("\"2,8\"", "\"2,4\"");
    std::fs::write(&manifest, text.replace("cog = true\n", "cog = true\noverview_level = 9\n")).unwrap();
    let r = run(&["batch", s(&manifest), "--quiet", "--force"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(std::fs::metadata(&out).unwrap().len() < fastest.len() as u64);
    assert_eq!(python(SAME_LEVELS, &[s(&out), s(&d.join("fastest.tif"))]), "3");
    std::fs::write(&manifest, text.replace("cog = true\n", "cog = true\noverview_level = 13\n")).unwrap();
    let r = run(&["batch", s(&manifest), "--quiet", "--force"]);
    assert!(!r.status.success() && String::from_utf8_lossy(&r.stderr).contains("overview_level"), "{}", String::from_utf8_lossy(&r.stderr));
}

/// Overview tiles are coded at their own level: by default deflate's
/// fastest coder (level 0), at `--overview-level` when given, at `--level`
/// when only that is; the pixels are the same whichever (lossless), the
/// file's size is not, GDAL's validator takes each as a COG, and a level a
/// codec does not take is refused by name.
#[test]
fn overview_tiles_are_coded_at_their_own_level_with_the_same_pixels() {
    if gdal_python_missing() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("s"), 900, |o| o.kappa_deg = 35.0);
    let made = |name: &str, extra: &[&str]| {
        let out = d.join(name);
        rectify(&sc, &sc.scan, &out, extra);
        out
    };
    let fastest = made("fastest.tif", &["--cog"]);
    let tight = made("tight.tif", &["--cog", "--overview-level", "9"]);
    let level1 = made("level1.tif", &["--cog", "--overview-level", "1"]);
    let both9 = made("both9.tif", &["--cog", "--level", "9"]);
    let full9 = made("full9.tif", &["--cog", "--level", "9", "--overview-level", "0"]);
    let size = |p: &Path| std::fs::metadata(p).unwrap().len();
    for f in [&fastest, &tight, &level1, &both9, &full9] {
        assert_eq!(python(VALIDATE, &[s(f)]), "[]", "{}", f.display());
        assert!(python(SAME_LEVELS, &[s(&fastest), s(f)]).parse::<u32>().unwrap() > 2);
    }
    // Tighter levels make smaller overviews; the full level's bytes stay.
    assert!(size(&tight) < size(&level1) && size(&level1) < size(&fastest), "{} {} {}", size(&tight), size(&level1), size(&fastest));
    // `--level` alone sets the overviews' level too: as the full level at 9
    // with overviews at 9 is to the full level at 9 with the fastest ones.
    assert!(size(&both9) < size(&full9));
    assert_eq!(size(&fastest) - size(&tight), size(&full9) - size(&both9));
    for (compress, level) in [("jpeg", "80"), ("lzw", "3"), ("deflate", "13"), ("zstd", "0")] {
        let out = d.join("refused.tif");
        let r = rectify_run(&sc, &sc.scan, &out, &["--compress", compress, "--overview-level", level]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{compress} {level}: {err}");
        assert!(err.contains("--overview-level") && err.lines().count() == 1, "{err}");
        assert!(!out.exists());
    }
}

/// A Float32 scan's holes (NaN) have no value under an internal mask, as
/// under NaN as nodata: the statistics GDAL reads are of the pixels with a
/// value, never NaN. A float alpha band, which GDAL does not take for a
/// mask, is refused.
#[test]
fn a_float_scans_holes_are_out_of_the_mask_and_its_statistics() {
    if gdal_python_missing() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("scene"), 500, |o| o.kappa_deg = 10.0);
    let scan = d.join("float.tif");
    let hole = |c: u32, r: u32| (200..260).contains(&c) && (150..190).contains(&r);
    f32_raster(&scan, (500, 500), (0.0, 0.0, 1.0, 32631), |c, r| if hole(c, r) { f32::NAN } else { (c as f32 - 250.0) / 37.0 });
    let (masked, by_nan) = (d.join("masked.tif"), d.join("nan.tif"));
    rectify(&sc, &scan, &masked, &["--nodata", "mask"]);
    rectify(&sc, &scan, &by_nan, &[]);
    let script = r#"
import sys, math
from osgeo import gdal
import numpy as np
ds = gdal.Open(sys.argv[1]); b = ds.GetRasterBand(1)
v = b.ReadAsArray(); md = b.GetMetadata()
if b.GetNoDataValue() is None:
    m = b.GetMaskBand().ReadAsArray() > 0
    assert b.GetMaskFlags() == gdal.GMF_PER_DATASET, b.GetMaskFlags()
    assert not np.isnan(v[m]).any(), "%d NaN pixels in the mask" % np.isnan(v[m]).sum()
else:
    m = ~np.isnan(v)
mean = float(md["STATISTICS_MEAN"])
assert math.isfinite(mean) and abs(mean - v[m].mean()) < 1e-4, (mean, v[m].mean())
print("%.6f %.6f" % (float(md["STATISTICS_VALID_PERCENT"]), mean))
"#;
    let (a, b) = (python(script, &[s(&masked)]), python(script, &[s(&by_nan)]));
    assert_eq!(a, b, "the mask and NaN as nodata say the same");
    let r = rectify_run(&sc, &scan, &d.join("alpha.tif"), &["--alpha"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("--alpha: a Float32 orthophoto"), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(!d.join("alpha.tif").exists());
}
