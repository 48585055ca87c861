//! `mosaic`: a synthetic block of six frames over a town (buildings in the
//! DSM), each frame exposed differently (`synth --block`). GDAL measures
//! the outputs (`tests/mosaic/measure.py`): every pixel on an image's side
//! of the seams is that image's own orthophoto bit for bit (no blend, no
//! balance); nothing any image has is lost; balancing brings the mosaic to
//! the ground's true levels and closes the jumps across seams; least-cost
//! seams cross far fewer height edges than the first partition's.

mod common;
use common::{bin, have, python_with, run, s, whole_image};
use std::path::Path;

fn block(dir: &Path) {
    let out = run(&[
        "synth",
        "--out",
        s(dir),
        "--camera",
        "digital",
        "--relief",
        "urban",
        "--size",
        "1500x1000",
        "--dem-posting",
        "1",
        "--scale",
        "8000",
        "--block",
        "3x2",
        "--quiet",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

fn mosaic(dir: &Path, args: &[&str]) {
    let mut all = vec!["mosaic", "manifest.toml", "--quiet"];
    all.extend_from_slice(args);
    let out = std::process::Command::new(bin()).current_dir(dir).args(&all).output().expect("runs");
    assert!(out.status.success(), "mosaic {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn a_block_mosaics_seamlessly_from_its_scans() {
    let Some(python) = python_with("osgeo.gdal", "python3-gdal") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    mosaic(d, &["-o", "a.tif", "--balance", "none", "--blend", "0", "--seamlines-out", "a.geojson", "--json", "a.json"]);
    mosaic(d, &["-o", "b.tif", "--json", "b.json"]);
    mosaic(d, &["-o", "c.tif", "--balance", "none", "--blend", "0", "--seams", "voronoi", "--seamlines-out", "c.geojson"]);
    mosaic(d, &["-o", "v.tif", "--balance", "gain-offset-vignetting", "--json", "v.json"]);
    // Each image alone on the grid the mosaic made it on.
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("a.json")).unwrap()).unwrap();
    for (k, im) in report["images"].as_array().unwrap().iter().enumerate() {
        let g = &im["grid"];
        let (x0, y0, gsd) = (g["x0"].as_f64().unwrap(), g["y0"].as_f64().unwrap(), g["gsd"].as_f64().unwrap());
        let (w, h) = (g["width"].as_f64().unwrap(), g["height"].as_f64().unwrap());
        let image = im["image"].as_str().unwrap();
        let bounds = format!("{x0},{},{},{y0}", y0 - h * gsd, x0 + w * gsd);
        let out = std::process::Command::new(bin())
            .current_dir(d)
            .args(["rectify", "--image", image, "--camera", &image.replace(".tif", ".toml"), "--dem", "dem.tif", "--bounds", &bounds])
            .args(["--gsd", &gsd.to_string(), "--snap", "none", "-o", &format!("o{}.tif", k + 1), "--quiet"])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let out = std::process::Command::new(python).arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/mosaic/measure.py")).arg(d).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let m: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    println!("{m}");
    let f = |k: &str| m[k].as_f64().unwrap_or_else(|| panic!("{k} in {m}"));
    // Geometry: each side of the seams is its image's orthophoto, bit for bit.
    assert!(f("own_side_pixels") > 0.99 * f("valid"), "{m}");
    assert_eq!(f("own_side_equal"), f("own_side_pixels"), "{m}");
    // Every pixel from an image that has it; nothing an image has is lost.
    assert_eq!(f("valid_from_an_image"), f("valid"), "{m}");
    assert_eq!(f("lost"), 0.0, "{m}");
    assert_eq!(m["truth_grid_same"], true);
    // Balanced: the ground's true levels (the frames' gains were 0.8 to
    // 1.2 with offsets and vignetting), and no step at the seams beyond
    // the texture's own from pixel to pixel.
    assert!(f("b_truth_mad") < 6.0 && f("b_truth_mad") < 0.6 * f("a_truth_mad"), "{m}");
    assert!(f("b_seam_jump") < 0.5 * f("a_seam_jump") && f("b_seam_jump") < 2.0 * f("b_texture_step"), "{m}");
    // With each frame's falloff solved too, nearer still; and the falloff
    // found is the one the frame was given: the correction's factor at the
    // scan's corner over its centre, (gain + b + e) / gain, against
    // 1 / (1 − vignetting), every frame and band: within 30 % of the
    // falloff (and 0.02), where no correction is off by all of it.
    assert!(f("v_truth_mad") < 0.85 * f("b_truth_mad") && f("v_seam_jump") < 1.05 * f("b_seam_jump"), "{m}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("v.json")).unwrap()).unwrap();
    let exposures = std::fs::read_to_string(d.join("exposures.csv")).unwrap();
    for (im, line) in v["images"].as_array().unwrap().iter().zip(exposures.lines().skip(1)) {
        let vignetting: f64 = line.split(',').nth(3).unwrap().parse().unwrap();
        let c = &im["correction"];
        for band in 0..3 {
            let (g, r) = (c["gain"][band].as_f64().unwrap(), &c["radial"][band]);
            let corner = (g + r[0].as_f64().unwrap() + r[1].as_f64().unwrap()) / g;
            let want = 1.0 / (1.0 - vignetting);
            assert!((corner - want).abs() < 0.3 * (want - 1.0) + 0.02, "{line}: band {band} factor {corner} for {want}");
        }
    }
    // Least-cost seams keep off the buildings' edges.
    assert!(f("a_seam_on_height_edges") < 0.5 * f("c_seam_on_height_edges"), "{m}");
    assert!(f("a_seam_on_height_edges") < 0.5 * f("edge_share"), "{m}");
}

#[test]
fn the_seamlines_are_polygons_gdal_reads_one_per_image() {
    let Some(python) = python_with("osgeo.ogr", "python3-gdal") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    mosaic(d, &["-o", "m.tif", "--seamlines-out", "seams.geojson", "--json", "m.json"]);
    let script = "import sys, json\nfrom osgeo import ogr\nds = ogr.Open(sys.argv[1]); l = ds.GetLayer(0)\nout = []\nfor f in l:\n    g = f.GetGeometryRef()\n    out.append([f.GetField('image'), g.IsValid(), g.GetArea()])\nprint(json.dumps({'features': out, 'epsg': l.GetSpatialRef().GetAuthorityCode(None)}))\n";
    let out = std::process::Command::new(python).args(["-c", script]).arg(d.join("seams.geojson")).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("m.json")).unwrap()).unwrap();
    assert_eq!(v["epsg"], "32631");
    let feats = v["features"].as_array().unwrap();
    assert_eq!(feats.len(), 6, "{v}");
    // Valid polygons whose areas are the images' shares of the covered cells.
    let total: f64 = feats.iter().map(|f| f[2].as_f64().unwrap()).sum();
    for (f, im) in feats.iter().zip(report["images"].as_array().unwrap()) {
        assert_eq!(f[1], true, "{f}");
        let share = f[2].as_f64().unwrap() / total;
        assert!((share - im["share"].as_f64().unwrap()).abs() < 0.01, "{f} {im}");
    }
}

/// Seamlines of a mosaic in a CRS without an EPSG code (a national
/// transverse Mercator) carry it: GDAL reads the CRS and places them on
/// the mosaic (they were read as WGS 84 and landed nowhere), and they are
/// read back as they were written.
#[test]
fn seamlines_in_a_crs_without_a_code_are_placed_by_gdal() {
    let Some(python) = python_with("osgeo.ogr", "python3-gdal") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    let tm = "+proj=tmerc +lat_0=0 +lon_0=3.1 +k=0.9996 +x_0=500000 +y_0=0 +ellps=WGS84 +units=m +no_defs";
    mosaic(d, &["-o", "m.tif", "--crs", tm, "--seamlines-out", "seams.geojson"]);
    let script = "import sys, json\nfrom osgeo import ogr\nds = ogr.Open(sys.argv[1])\nl = ds.GetLayer(0)\nsrs = l.GetSpatialRef()\nprint(json.dumps({'proj': srs.ExportToProj4(), 'extent': l.GetExtent()}))\n";
    let out = std::process::Command::new(python).args(["-c", script]).arg(d.join("seams.geojson")).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let proj = v["proj"].as_str().unwrap();
    assert!(proj.contains("+proj=tmerc") && proj.contains("+lon_0=3.1"), "{v}");
    // The extent lies on the mosaic's grid.
    let info = gcm_ortho::io::source::SourceImage::open(&d.join("m.tif"), 1 << 20).unwrap().info;
    let t = info.georef.unwrap().transform;
    let (x0, x1, y1, y0) = (t[0], t[0] + t[1] * info.width as f64, t[3], t[3] + t[5] * info.height as f64);
    let e: Vec<f64> = v["extent"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    assert!(e[0] >= x0 - 1e-6 && e[1] <= x1 + 1e-6 && e[2] >= y0 - 1e-6 && e[3] <= y1 + 1e-6, "{e:?} within {x0} {x1} {y0} {y1}");
    assert!((e[1] - e[0]) > 0.5 * (x1 - x0) && (e[3] - e[2]) > 0.5 * (y1 - y0), "{e:?}");
    // Read back as the edited seamlines: the same mosaic.
    mosaic(d, &["-o", "again.tif", "--crs", tm, "--seamlines", "seams.geojson"]);
    assert!(std::fs::read(d.join("m.tif")).unwrap() == std::fs::read(d.join("again.tif")).unwrap(), "the seams read back give the same mosaic");
}

#[test]
fn a_mosaic_never_writes_over_its_inputs_and_refuses_bad_manifests_in_one_line() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    let before = std::fs::read(d.join("scans/002.tif")).unwrap();
    let camera = std::fs::read(d.join("scans/001.toml")).unwrap();
    for target in ["scans/002.tif", "dem.tif", "manifest.toml", "scans/001.toml"] {
        let out = std::process::Command::new(bin()).current_dir(d).args(["mosaic", "manifest.toml", "-o", target, "--quiet"]).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{target}: {err}");
        // The refusal alone (not first a word on the name's format).
        assert!(err.trim().lines().count() == 1 && err.contains("refusing to write over an input"), "{target}: {err}");
    }
    assert_eq!(std::fs::read(d.join("scans/001.toml")).unwrap(), camera);
    // Nor its report, written after the run.
    for target in ["scans/001.toml", "scans/002.tif", "dem.tif"] {
        let out =
            std::process::Command::new(bin()).current_dir(d).args(["mosaic", "manifest.toml", "-o", "r.tif", "--json", target, "--quiet"]).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{target}: {}", String::from_utf8_lossy(&out.stderr));
        assert!(!d.join("r.tif").exists());
    }
    // Nor the record of a finished output (beside it, `.done`) over
    // another of its files, nor over an input.
    std::fs::write(d.join("kept.tif.done"), b"a file of the user's").unwrap();
    for args in [
        &["-o", "out.tif", "--plan-out", "out.tif.done"][..],
        &["-o", "out.tif", "--seamlines-out", "out.tif.done"],
        &["-o", "out.tif", "--json", "out.tif.done"],
        &["-o", "kept.tif", "--seamlines", "kept.tif.done"],
    ] {
        let out = std::process::Command::new(bin()).current_dir(d).args([&["mosaic", "manifest.toml", "--quiet"][..], args].concat()).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(".done") && err.trim().lines().count() == 1, "{args:?}: {err}");
        assert!(!d.join("out.tif").exists() && !d.join("kept.tif").exists());
    }
    assert_eq!(std::fs::read(d.join("kept.tif.done")).unwrap(), b"a file of the user's");
    // Into a folder that is not there: one line naming it, exit 2.
    for args in [&["-o", "nowhere/out.tif"][..], &["-o", "out.tif", "--seamlines-out", "nowhere/s.geojson"], &["--plan-out", "nowhere/p.json"]] {
        let out = std::process::Command::new(bin()).current_dir(d).args([&["mosaic", "manifest.toml", "--quiet"][..], args].concat()).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("the folder nowhere does not exist") && err.trim().lines().count() == 1, "{args:?}: {err}");
        assert!(!d.join("out.tif").exists());
    }
    assert_eq!(std::fs::read(d.join("scans/002.tif")).unwrap(), before);
    assert_eq!(std::fs::read(d.join("scans/001.toml")).unwrap(), camera);
    // A missing scan: one line naming it, nothing at the output path.
    std::fs::rename(d.join("scans/003.tif"), d.join("scans/gone.tif")).unwrap();
    let out = std::process::Command::new(bin()).current_dir(d).args(["mosaic", "manifest.toml", "-o", "out.tif", "--quiet"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_ne!(out.status.code(), Some(0));
    assert!(err.contains("003.tif") && err.trim().lines().count() == 1, "{err}");
    assert_eq!(err.matches("manifest.toml").count(), 1, "the manifest named once: {err}");
    assert!(!d.join("out.tif").exists());
    assert!(common::files_containing(d, "out.tif").is_empty(), "a temporary was left");
    // A blend that is not a width.
    std::fs::rename(d.join("scans/gone.tif"), d.join("scans/003.tif")).unwrap();
    let out = std::process::Command::new(bin()).current_dir(d).args(["mosaic", "manifest.toml", "-o", "out.tif", "--blend", "-3", "--quiet"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--blend"));
    // Bounds no image sees, or a GSD that leaves no cell any image sees:
    // refused naming the option and where the images are, not a mosaic of
    // nothing with exit 0.
    for (args, flag) in [(&["--bounds", "0,0,1000,1000"][..], "--bounds"), (&["--gsd", "1e5"][..], "--gsd")] {
        let out = std::process::Command::new(bin())
            .current_dir(d)
            .args([&["mosaic", "manifest.toml", "-o", "out.tif", "--quiet"][..], args].concat())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(flag) && err.contains("no image sees") && err.trim().lines().count() == 1, "{err}");
        assert!(!d.join("out.tif").exists());
    }
    // Too little memory for the render: refused in one line with the
    // figure that would do, nothing left behind (nor the seamlines and plan
    // asked for, made before the render was refused); that figure runs.
    let out = std::process::Command::new(bin())
        .current_dir(d)
        .args(["mosaic", "manifest.toml", "-o", "out.tif", "--memory", "20M", "--seamlines-out", "cut.geojson", "--plan-out", "cut.plan", "--quiet"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--memory") && err.trim().lines().count() == 1, "{err}");
    assert!(!d.join("out.tif").exists() && common::files_containing(d, "out.tif").is_empty());
    assert!(common::files_containing(d, "cut.").is_empty(), "{:?}", common::files_containing(d, "cut."));
    let enough = err.split("give --memory ").nth(1).and_then(|t| t.split_whitespace().next()).expect("a figure").to_string();
    let out = std::process::Command::new(bin())
        .current_dir(d)
        .args(["mosaic", "manifest.toml", "-o", "out.tif", "--memory", &enough, "--quiet", "--json", "small.json"])
        .output()
        .unwrap();
    assert!(out.status.success() && d.join("out.tif").exists());
    // From an absurd budget (the plan then a cell or two): a figure near
    // that one, which runs as well.
    let tried = |memory: &str| {
        std::process::Command::new(bin()).current_dir(d).args(["mosaic", "manifest.toml", "-o", "one.tif", "--memory", memory, "--quiet"]).output().unwrap()
    };
    let one = tried("1");
    let said = String::from_utf8_lossy(&one.stderr);
    assert_eq!(one.status.code(), Some(2), "{said}");
    // The refusal alone: what the plan on that budget would say of its
    // images comes only where the run goes on (a plan alone), in one line
    // for the images a grid that coarse takes nothing of, not one each.
    assert!(said.trim().lines().count() == 1, "{said}");
    let plan_only = std::process::Command::new(bin())
        .current_dir(d)
        .args(["mosaic", "manifest.toml", "--plan-out", "coarse.plan", "--memory", "1", "--quiet"])
        .output()
        .unwrap();
    let notes = String::from_utf8_lossy(&plan_only.stderr);
    assert!(plan_only.status.success(), "{notes}");
    assert_eq!(notes.lines().filter(|l| l.contains("span only one or two of the plan's cells")).count(), 1, "{notes}");
    assert!(notes.lines().all(|l| !l.contains("takes nothing of it:")), "{notes}");
    let from_one = said.split("give --memory ").nth(1).and_then(|t| t.split_whitespace().next()).expect("a figure").to_string();
    let mib = |f: &str| f.trim_end_matches('M').parse::<i64>().unwrap_or_else(|_| panic!("{f}"));
    assert!((mib(&from_one) - mib(&enough)).abs() <= 8, "{from_one} from 1 byte, {enough} from 20M");
    let one = tried(&from_one);
    assert!(one.status.success(), "{}", String::from_utf8_lossy(&one.stderr));
    // That budget makes the plan coarser than the default: said, with the
    // figure that makes it as fine, and that figure plans as finely.
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    let cell = |json: &str| serde_json::from_slice::<serde_json::Value>(&std::fs::read(d.join(json)).unwrap()).unwrap()["cell_px"].as_u64().unwrap();
    let finer = err.split("px from --memory ").nth(1).and_then(|t| t.split(':').next()).unwrap_or_else(|| panic!("no notice: {err}")).to_string();
    assert!(err.contains(&format!("the plan's cells are {} px", cell("small.json"))), "{err}");
    mosaic(d, &["-o", "out.tif", "--memory", &finer, "--json", "finer.json", "--force"]);
    mosaic(d, &["-o", "out.tif", "--json", "default.json", "--force"]);
    assert!(cell("finer.json") < cell("small.json") && cell("finer.json") == cell("default.json"));
    // Large tiles (the manifest's): each image's render holds its own, so
    // the mosaic's figure is what they take; it runs, without another
    // refusal from an image's own set-up.
    let manifest = std::fs::read_to_string(d.join("manifest.toml")).unwrap();
    std::fs::write(d.join("large.toml"), manifest.replacen("[defaults]\n", "[defaults]\ntile = 2048\n", 1)).unwrap();
    let out = std::process::Command::new(bin()).current_dir(d).args(["mosaic", "large.toml", "-o", "large.tif", "--quiet"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--memory") && !err.contains("tile") && err.trim().lines().count() == 1, "{err}");
    let enough = err.split("give --memory ").nth(1).and_then(|t| t.split_whitespace().next()).expect("a figure").to_string();
    let out =
        std::process::Command::new(bin()).current_dir(d).args(["mosaic", "large.toml", "-o", "large.tif", "--quiet", "--memory", &enough]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // Each image's set-up warnings are said, naming it, also under --quiet
    // (a GSD three scan pixels wide: bilinear aliases).
    let out =
        std::process::Command::new(bin()).current_dir(d).args(["mosaic", "manifest.toml", "-o", "coarse.tif", "--gsd", "1.5", "--quiet"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let aliasing: Vec<&str> = err.lines().filter(|l| l.contains("warning") && l.contains("aliases")).collect();
    assert!(aliasing.len() == 6 && aliasing.iter().all(|l| l.contains("scans/")), "{err}");
}

/// A mosaic whose bands the memory cannot hold across its width is made
/// in strips of tile columns, one after the other: byte for byte the file
/// of a run with room for the whole width (the same plan, so the same
/// cells), in plain and Cloud-Optimized layouts and as a true
/// orthomosaic, nothing left beside it.
#[test]
fn a_mosaic_too_wide_for_the_memory_is_made_in_strips_with_the_same_bytes() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    let strips = |name: &str| -> u64 {
        let report: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join(name)).unwrap()).unwrap();
        report["strips"].as_u64().unwrap()
    };
    for layout in [&[][..], &["--cog"][..], &["--occlusion", "nodata"][..]] {
        mosaic(d, &[&["--plan-out", "plan.json"][..], layout].concat());
        let with = |out: &'static str, memory: &'static str, json: &'static str| -> Vec<&'static str> {
            [&["--plan", "plan.json", "-o", out, "--memory", memory, "--json", json][..], layout].concat()
        };
        mosaic(d, &with("whole.tif", "256M", "whole.json"));
        assert_eq!(strips("whole.json"), 1);
        // 48 MiB holds this block's plan and a few tile columns of its
        // bands, not all of them.
        mosaic(d, &with("strips.tif", "48M", "strips.json"));
        assert!(strips("strips.json") > 1, "made at once in 48 MiB: the test no longer makes strips");
        assert!(std::fs::read(d.join("whole.tif")).unwrap() == std::fs::read(d.join("strips.tif")).unwrap(), "strips {layout:?} differ from the whole");
        assert!(common::files_containing(d, "strips.tif~").is_empty(), "the strips' folder was left");
        for f in ["whole.tif", "strips.tif"] {
            std::fs::remove_file(d.join(f)).unwrap();
        }
    }
}

/// A Float32 mosaic made in strips holds NaN where it has no value in its
/// overviews too (a float mosaic's fill), as the run with room for its
/// width does: the same bytes.
#[test]
fn a_float_mosaic_made_in_strips_is_the_single_runs_file() {
    let Some(python) = python_with("osgeo.gdal", "python3-gdal") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    let to_float = "import glob, os\nfrom osgeo import gdal\nfor p in sorted(glob.glob('scans/*.tif')):\n    gdal.Translate(p + '.f.tif', p, outputType=gdal.GDT_Float32)\n    os.replace(p + '.f.tif', p)\n";
    let out = std::process::Command::new(python).current_dir(d).args(["-c", to_float]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    mosaic(d, &["--plan-out", "plan.json"]);
    mosaic(d, &["--plan", "plan.json", "-o", "whole.tif"]);
    mosaic(d, &["--plan", "plan.json", "-o", "strips.tif", "--memory", "64M", "--json", "strips.json"]);
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("strips.json")).unwrap()).unwrap();
    assert!(report["strips"].as_u64().unwrap() > 1, "made at once in 64 MiB: the test no longer makes strips");
    assert!(std::fs::read(d.join("whole.tif")).unwrap() == std::fs::read(d.join("strips.tif")).unwrap(), "the float mosaic's strips differ from the whole");
    // NaN is tagged as the nodata value, as `rectify` tags it.
    let tag = "from osgeo import gdal\nd = gdal.Open('whole.tif'); b = d.GetRasterBand(1)\nprint(b.GetNoDataValue(), b.GetMaskFlags())\n";
    let out = std::process::Command::new(python).current_dir(d).args(["-c", tag]).output().unwrap();
    assert_eq!(String::from_utf8_lossy(&out.stdout).trim(), "nan 8", "{}", String::from_utf8_lossy(&out.stderr));
}

/// The manifest's `[defaults]` of the output grid (`gsd`, `bounds`) and
/// `nodata` are the mosaic's, as the command line's are; what a mosaic
/// cannot honour (`alpha`, images of different grids) is refused naming
/// the key, never ignored.
#[test]
fn the_manifests_grid_and_nodata_are_the_mosaics() {
    let Some(python) = python_with("osgeo.gdal", "python3-gdal") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    let manifest = std::fs::read_to_string(d.join("manifest.toml")).unwrap();
    let with = |name: &str, line: &str| std::fs::write(d.join(name), manifest.replacen("[defaults]\n", &format!("[defaults]\n{line}\n"), 1)).unwrap();
    mosaic(d, &["-o", "plain.tif", "--json", "plain.json"]);
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("plain.json")).unwrap()).unwrap();
    let corner = "from osgeo import gdal\nt = gdal.Open('plain.tif').GetGeoTransform()\nprint(t[0], t[3])\n";
    let out = std::process::Command::new(python).current_dir(d).args(["-c", corner]).output().unwrap();
    let xy: Vec<f64> = String::from_utf8_lossy(&out.stdout).split_whitespace().map(|v| v.parse().unwrap()).collect();
    let bounds = [xy[0] + 40.0, xy[1] - 240.0, xy[0] + 300.0, xy[1] - 40.0];
    let b = format!("{},{},{},{}", bounds[0], bounds[1], bounds[2], bounds[3]);
    with("grid.toml", &format!("gsd = 0.5\nbounds = [{b}]"));
    let run_with =
        |m: &str, args: &[&str]| std::process::Command::new(bin()).current_dir(d).args([&["mosaic", m, "--quiet"][..], args].concat()).output().unwrap();
    let out = run_with("grid.toml", &["-o", "grid.tif"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // Images beside a box give nothing, as expected: not a warning.
    assert!(!String::from_utf8_lossy(&out.stderr).contains("takes nothing"), "{}", String::from_utf8_lossy(&out.stderr));
    mosaic(d, &["-o", "flags.tif", "--gsd", "0.5", "--bounds", &b]);
    assert!(std::fs::read(d.join("grid.tif")).unwrap() == std::fs::read(d.join("flags.tif")).unwrap(), "the manifest's gsd and bounds are not the flags'");
    // nodata = 7: the empty pixels hold 7, tagged, no mask; the rest as the
    // masked mosaic's.
    with("seven.toml", "nodata = 7");
    let out = run_with("seven.toml", &["-o", "seven.tif"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let compare = "from osgeo import gdal\nimport numpy as np\np = gdal.Open('plain.tif'); q = gdal.Open('seven.tif')\na = p.ReadAsArray(); m = p.GetRasterBand(1).GetMaskBand().ReadAsArray() > 0; b = q.ReadAsArray()\nfor k in range(3):\n    band = q.GetRasterBand(k + 1); v = b[k][band.GetMaskBand().ReadAsArray() > 0]; md = band.GetMetadata()\n    assert abs(float(md['STATISTICS_VALID_PERCENT']) - 100.0 * v.size / b[k].size) < 1e-9 and float(md['STATISTICS_MINIMUM']) == v.min(), (k, md, v.size, v.min())\nprint(q.GetRasterBand(1).GetNoDataValue(), q.GetRasterBand(1).GetMaskFlags(), int((~m).sum() > 0), int((a[:, m] == b[:, m]).all()), int((b[:, ~m] == 7).all()), int(m.sum()), m.size)\n";
    let out = std::process::Command::new(python).current_dir(d).args(["-c", compare]).output().unwrap();
    let said = String::from_utf8_lossy(&out.stdout).trim().to_string();
    // The report's pixels with a value are those GDAL's mask says.
    let counts = report["pixels_with_value"].as_array().expect("counted").iter().map(|v| v.as_u64().unwrap().to_string()).collect::<Vec<_>>().join(" ");
    assert_eq!(said, format!("7.0 8 1 1 1 {counts}"), "{}", String::from_utf8_lossy(&out.stderr));
    // Refused in one line naming the manifest and the key, nothing written.
    with("alpha.toml", "alpha = true");
    let differing = manifest.replacen("camera = \"scans/002.toml\"", "camera = \"scans/002.toml\"\ngsd = 0.3", 1);
    assert_ne!(differing, manifest);
    std::fs::write(d.join("differ.toml"), differing).unwrap();
    with("nowhere.toml", "bounds = [0, 0, 100, 100]");
    // Refused under --resume-dir too, the folder it made not left behind.
    let out = run_with("nowhere.toml", &["-o", "refused.tif", "--resume-dir", "rd"]);
    assert_eq!(out.status.code(), Some(1), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(!d.join("rd").exists() && !d.join("refused.tif").exists());
    for (m, key) in [("alpha.toml", "alpha"), ("differ.toml", "gsd"), ("nowhere.toml", "bounds")] {
        let out = run_with(m, &["-o", "refused.tif"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_ne!(out.status.code(), Some(0), "{m}");
        assert!(err.contains(m) && err.contains(&format!("{key}:")) && !err.contains("--") && err.trim().lines().count() == 1, "{err}");
        assert!(!d.join("refused.tif").exists());
    }
}

#[test]
fn edited_seamlines_are_honoured() {
    use gcm_ortho::mosaic::plan::{Plan, PlanSettings, NONE};
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    let jobs = gcm_ortho::batch::manifest::load(&d.join("manifest.toml")).unwrap();
    let settings = PlanSettings { gsd: None, grid: None, bounds: None, crs: None, memory: 256 << 20, cell: None, thumbnails: true };
    let make = || Plan::make(jobs.iter().map(|j| (j.name.clone(), j.config.clone())).collect(), &settings, &gcm_ortho::NoProgress).unwrap();
    let mut plan = make();
    let planned = plan.label.clone();
    // A user's cut: the first two images split the block at its middle
    // easting, each given one half (a GIS's rectangles, in the mosaic's CRS).
    let g = plan.grid;
    let (west, east, north, south) = (g.x0, g.x0 + g.width as f64 * g.gsd.x, g.y0, g.y0 - g.height as f64 * g.gsd.y);
    let xm = (west + east) / 2.0;
    let rect = |x0: f64, x1: f64| serde_json::json!([[[x0, south], [x1, south], [x1, north], [x0, north], [x0, south]]]);
    // The first by its name, the second by its index.
    let a = plan.images[0].name.clone();
    let doc = serde_json::json!({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"image": a}, "geometry": {"type": "Polygon", "coordinates": rect(west, xm)}},
        {"type": "Feature", "properties": {"index": 2}, "geometry": {"type": "Polygon", "coordinates": rect(xm, east)}},
    ]});
    let file = d.join("edited.geojson");
    std::fs::write(&file, doc.to_string()).unwrap();
    let edited = gcm_ortho::mosaic::seamlines::read(&mut plan, &file).unwrap();
    let (mut to_a, mut to_b) = (0, 0);
    for y in 0..plan.ch {
        for x in 0..plan.cw {
            let (cx, _) = plan.cell_centre(x, y);
            let (label, was) = (plan.label_at(x, y), planned[y * plan.cw + x]);
            let wanted = if cx < xm { 0 } else { 1 };
            if plan.images[wanted].sees(x, y) {
                assert_eq!(label, wanted as u16, "cell ({x}, {y}) at {cx}");
                if cx < xm {
                    to_a += 1
                } else {
                    to_b += 1
                }
            } else {
                // Not seen by the image the user named: the plan's own.
                assert_eq!(label, was, "cell ({x}, {y})");
                assert!(label == NONE || plan.images[label as usize].sees(x, y));
            }
        }
    }
    assert_eq!(edited.cells_given, to_a + to_b);
    assert!(to_a > 100 && to_b > 100 && edited.cells_kept > 0, "{edited:?}");

    // The run's own seams (least-cost), as it writes them.
    mosaic(d, &["-o", "p.tif", "--seamlines-out", "plain.geojson"]);
    let mut own = make();
    assert_eq!(gcm_ortho::mosaic::seamlines::read(&mut own, &d.join("plain.geojson")).unwrap().cells_kept, 0);
    assert_ne!(own.label, planned, "least-cost seams move the first partition");
    // The mosaic honours the edit: the seamlines it writes back are the
    // edit where it gives a cell to an image that sees it, elsewhere the
    // run's own seams.
    mosaic(d, &["-o", "e.tif", "--seamlines", "edited.geojson", "--seamlines-out", "back.geojson", "--json", "e.json"]);
    let mut again = make();
    let back = gcm_ortho::mosaic::seamlines::read(&mut again, &d.join("back.geojson")).unwrap();
    let expected: Vec<u16> = (0..plan.cw * plan.ch)
        .map(|k| {
            let (cx, _) = plan.cell_centre(k % plan.cw, k / plan.cw);
            let wanted = if cx < xm { 0 } else { 1 };
            if plan.images[wanted].sees(k % plan.cw, k / plan.cw) {
                wanted as u16
            } else {
                own.label[k]
            }
        })
        .collect();
    assert!(again.label == expected, "the written seamlines give back the edited partition");
    // An image's feature left out of the run's own seamlines: its cells
    // keep its cut, and the mosaic is the run's, byte for byte.
    let mut plain: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("plain.geojson")).unwrap()).unwrap();
    plain["features"].as_array_mut().unwrap().remove(1);
    std::fs::write(d.join("dropped.geojson"), plain.to_string()).unwrap();
    mosaic(d, &["-o", "dropped.tif", "--seamlines", "dropped.geojson"]);
    assert!(std::fs::read(d.join("dropped.tif")).unwrap() == std::fs::read(d.join("p.tif")).unwrap(), "a feature left out changed the mosaic");
    assert_eq!((back.cells_kept, back.cells_overlapping), (0, 0), "every labelled cell, edge cells too, is in the file it wrote");
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("e.json")).unwrap()).unwrap();
    assert_eq!(report["edited_seams"]["cells_given"].as_u64().unwrap() as usize, edited.cells_given);
    // The same cut saved as GIS tools save GeoJSON (RFC 7946: longitude
    // and latitude, no crs member) gives the same partition.
    let ground = gcm_ortho::geodesy::GroundCrs::new(&plan.crs).unwrap();
    let ll = |x: f64, y: f64| {
        let (lon, lat) = ground.to_lonlat(x, y).unwrap();
        serde_json::json!([lon, lat])
    };
    // Each side in steps, so that its line stays the projected one.
    let ring = |x0: f64, x1: f64| {
        let side = |(ax, ay): (f64, f64), (bx, by): (f64, f64)| (0..64).map(move |k| (ax + (bx - ax) * k as f64 / 64.0, ay + (by - ay) * k as f64 / 64.0));
        let pts: Vec<serde_json::Value> = side((x0, south), (x1, south))
            .chain(side((x1, south), (x1, north)))
            .chain(side((x1, north), (x0, north)))
            .chain(side((x0, north), (x0, south)))
            .chain([(x0, south)])
            .map(|(x, y)| ll(x, y))
            .collect();
        serde_json::json!([pts])
    };
    let degrees = serde_json::json!({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"image": a}, "geometry": {"type": "Polygon", "coordinates": ring(west, xm)}},
        {"type": "Feature", "properties": {"index": 2}, "geometry": {"type": "Polygon", "coordinates": ring(xm, east)}},
    ]});
    let lonlat = d.join("lonlat.geojson");
    std::fs::write(&lonlat, degrees.to_string()).unwrap();
    let mut in_degrees = make();
    gcm_ortho::mosaic::seamlines::read(&mut in_degrees, &lonlat).unwrap();
    assert_eq!(in_degrees.label, plan.label, "the cut in degrees without a crs member");
    // Polygons in another CRS are refused by name.
    let other = doc.to_string().replacen('{', r#"{"crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::32632"}},"#, 1);
    std::fs::write(&file, other).unwrap();
    let e = gcm_ortho::mosaic::seamlines::read(&mut make(), &file).unwrap_err().to_string();
    assert!(e.contains("edited.geojson") && e.contains("EPSG:32632"), "{e}");
    // A geometry that is not an area: its type named as the file has it.
    std::fs::write(&file, doc.to_string().replacen(r#""type":"Polygon""#, r#""type":"Point""#, 1)).unwrap();
    let e = gcm_ortho::mosaic::seamlines::read(&mut make(), &file).unwrap_err().to_string();
    assert!(e.contains("'Point': expected Polygon or MultiPolygon") && !e.contains("Some("), "{e}");
}

#[test]
fn shards_of_one_plan_assemble_into_the_single_run_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    // The manifest's layout: Cloud-Optimized (the file's order is the
    // layout's), one overview level by the nearest pixel. `assemble`
    // takes it from the pieces' record, unasked.
    let manifest = std::fs::read_to_string(d.join("manifest.toml")).unwrap();
    let laid_out = manifest.replace("[defaults]\n", "[defaults]\ncog = true\noverviews = \"2\"\noverview_resampling = \"nearest\"\n");
    assert_ne!(laid_out, manifest);
    std::fs::write(d.join("manifest.toml"), laid_out).unwrap();
    // The single run, balanced with each frame's falloff (the plan
    // carries its terms).
    mosaic(d, &["-o", "whole.tif", "--json", "whole.json", "--balance", "gain-offset-vignetting"]);
    // The plan once; pieces of it on "other machines".
    mosaic(d, &["--plan-out", "plan.json", "--balance", "gain-offset-vignetting"]);
    assert!(std::fs::read_to_string(d.join("plan.json")).unwrap().contains("\"radial\""));
    let info = gcm_ortho::io::source::SourceImage::open(&d.join("whole.tif"), 1 << 20).unwrap().info;
    let t = info.chunk.0;
    let (ta, td) = (info.width.div_ceil(t), info.height.div_ceil(t));
    let r = td / 2;
    // A band of rows, and the rest split unevenly in columns.
    let windows = [[0, 0, ta, r], [0, r, 1, td - r], [1, r, ta - 1, td - r]];
    let mut a = vec!["assemble".to_string(), "-o".into(), "joined.tif".into()];
    for (k, w) in windows.iter().enumerate() {
        let name = format!("piece{k}.tif");
        let win = format!("{},{},{},{}", w[0], w[1], w[2], w[3]);
        mosaic(d, &["--plan", "plan.json", "--window", &win, "-o", &name]);
        a.push(name);
    }
    let out = std::process::Command::new(bin()).current_dir(d).args(&a).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read(d.join("whole.tif")).unwrap() == std::fs::read(d.join("joined.tif")).unwrap(), "assembled mosaic differs from the single run");
    // A damaged plan (a run longer than the grid) is refused, not obeyed.
    let text = std::fs::read_to_string(d.join("plan.json")).unwrap().replacen("\"labels\":[", "\"labels\":[[0,4000000000],", 1);
    std::fs::write(d.join("bad.json"), text).unwrap();
    let out =
        std::process::Command::new(bin()).current_dir(d).args(["mosaic", "manifest.toml", "--quiet", "--plan", "bad.json", "-o", "y.tif"]).output().unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && e.contains("bad.json") && e.contains("damaged"), "{e}");
    // A gain of 1000 under a checksum made for it (a plan forged, or a
    // solver gone wrong; 1e308 saturated the mosaic) is refused by its
    // range, naming image and band.
    let plan = std::fs::read_to_string(d.join("plan.json")).unwrap();
    let (body, sum) = plan.rsplit_once(",\"checksum\":\"").expect("a checksum");
    let fnv = |t: &str| t.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3));
    assert_eq!(format!("{:016x}\"}}", fnv(&format!("{body}}}"))), sum, "the checksum is FNV-1a of the plan without it");
    let at = body.find("\"gain\":[").unwrap() + "\"gain\":[".len();
    let end = at + body[at..].find([',', ']']).unwrap();
    let forged = format!("{}1000.0{}", &body[..at], &body[end..]);
    std::fs::write(d.join("forged.json"), format!("{forged},\"checksum\":\"{:016x}\"}}", fnv(&format!("{forged}}}")))).unwrap();
    let out =
        std::process::Command::new(bin()).current_dir(d).args(["mosaic", "manifest.toml", "--quiet", "--plan", "forged.json", "-o", "y.tif"]).output().unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && e.contains("forged.json") && e.contains("band 1") && e.contains("1/64 to 64"), "{e}");
    // The same edit without its checksum made again: refused as edited.
    std::fs::write(d.join("edited.json"), plan.replacen(&body[at..end], "1000.0", 1)).unwrap();
    let out =
        std::process::Command::new(bin()).current_dir(d).args(["mosaic", "manifest.toml", "--quiet", "--plan", "edited.json", "-o", "y.tif"]).output().unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && e.contains("checksum"), "{e}");
    assert!(!d.join("y.tif").exists());
    // Threads past any machine's: refused by name, nothing started.
    let out =
        std::process::Command::new(bin()).current_dir(d).args(["mosaic", "manifest.toml", "--quiet", "--threads", "100000", "-o", "y.tif"]).output().unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.code() == Some(2) && e.contains("--threads") && e.contains("1024"), "{e}");
    // A plan for other settings is refused, named.
    let out = std::process::Command::new(bin())
        .current_dir(d)
        .args(["mosaic", "manifest.toml", "--quiet", "--plan", "plan.json", "--gsd", "3", "-o", "x.tif"])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && e.contains("plan.json") && e.contains("another grid"), "{e}");
    assert!(!d.join("x.tif").exists());
    // A plan from other inputs or a setting every piece shares: refused,
    // named, before the render; the same DEM under another name is the
    // same input.
    let manifest = std::fs::read_to_string(d.join("manifest.toml")).unwrap();
    let moved = manifest.replace("dem = \"dem.tif\"", "dem = \"moved.tif\"");
    assert_ne!(moved, manifest);
    std::fs::copy(d.join("dem.tif"), d.join("moved.tif")).unwrap();
    std::fs::write(d.join("moved.toml"), moved).unwrap();
    let out = std::process::Command::new(bin())
        .current_dir(d)
        .args(["mosaic", "moved.toml", "--quiet", "--plan", "plan.json", "-o", "moved.tif.out"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = std::process::Command::new(bin())
        .current_dir(d)
        .args(["mosaic", "manifest.toml", "--quiet", "--plan", "plan.json", "--blend", "2", "-o", "x.tif"])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.code() == Some(1) && e.contains("plan.json") && e.contains("planned from other"), "{e}");
    assert!(!d.join("x.tif").exists());
}

/// Output pixels finer than the scans': the images' outputs are larger
/// than their shares of the memory plan nodes for at every spacing, and
/// the shares differ from window to window; the node spacing does not,
/// so pieces and a resumed run are still the single run's bytes.
#[test]
fn a_mosaic_finer_than_its_scans_by_pieces_is_the_single_runs_file() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    mosaic(d, &["-o", "whole.tif", "--gsd", "0.2"]);
    mosaic(d, &["-o", "resumed.tif", "--gsd", "0.2", "--resume-dir", "rd"]);
    assert!(std::fs::read(d.join("whole.tif")).unwrap() == std::fs::read(d.join("resumed.tif")).unwrap(), "the resumed mosaic differs from the single run");
    mosaic(d, &["--plan-out", "plan.json", "--gsd", "0.2"]);
    let info = gcm_ortho::io::source::SourceImage::open(&d.join("whole.tif"), 1 << 20).unwrap().info;
    let t = info.chunk.0;
    let (ta, td) = (info.width.div_ceil(t), info.height.div_ceil(t));
    let mut a = vec!["assemble".to_string(), "-o".into(), "joined.tif".into()];
    for (k, r0) in (0..td).step_by(3).enumerate() {
        let name = format!("piece{k}.tif");
        mosaic(d, &["--plan", "plan.json", "--gsd", "0.2", "--window", &format!("0,{r0},{ta},{}", 3.min(td - r0)), "-o", &name]);
        a.push(name);
    }
    let out = std::process::Command::new(bin()).current_dir(d).args(&a).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read(d.join("whole.tif")).unwrap() == std::fs::read(d.join("joined.tif")).unwrap(), "the assembled pieces differ from the single run");
}

/// Pieces made without a shared plan, one balanced and one not (or with
/// other seams), would meet in a step: `assemble` refuses them by name;
/// pieces of the same settings join into the single run's file.
#[test]
fn pieces_of_other_balance_or_seams_are_not_joined() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    mosaic(d, &["-o", "whole.tif"]);
    let info = gcm_ortho::io::source::SourceImage::open(&d.join("whole.tif"), 1 << 20).unwrap().info;
    let t = info.chunk.0;
    let (ta, td) = (info.width.div_ceil(t), info.height.div_ceil(t));
    let (left, right) = (format!("0,0,{},{td}", ta / 2), format!("{},0,{},{td}", ta / 2, ta - ta / 2));
    mosaic(d, &["--window", &left, "-o", "left.tif"]);
    mosaic(d, &["--window", &right, "-o", "right.tif"]);
    for (name, extra) in [("unbalanced.tif", "--balance=none"), ("voronoi.tif", "--seams=voronoi")] {
        mosaic(d, &["--window", &right, extra, "-o", name]);
        let out = std::process::Command::new(bin()).current_dir(d).args(["assemble", "-o", "bad.tif", "left.tif", name]).output().unwrap();
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.code() == Some(2) && e.contains(name) && e.contains("other inputs or settings"), "{extra}: {e}");
        assert!(!d.join("bad.tif").exists());
    }
    let out = std::process::Command::new(bin()).current_dir(d).args(["assemble", "-o", "joined.tif", "left.tif", "right.tif"]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::read(d.join("whole.tif")).unwrap() == std::fs::read(d.join("joined.tif")).unwrap(), "the pieces differ from the single run");
}

#[test]
fn a_restarted_shard_leaves_its_finished_piece_and_redoes_a_changed_one() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    mosaic(d, &["--plan-out", "plan.json"]);
    let piece = d.join("piece.tif");
    let args = ["--plan", "plan.json", "--window", "0,0,2,2", "-o", "piece.tif", "--json", "r.json"];
    mosaic(d, &args);
    let first = std::fs::metadata(&piece).unwrap().modified().unwrap();
    let skipped = |d: &Path| -> bool {
        let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("r.json")).unwrap()).unwrap();
        r["skipped"].as_bool().unwrap()
    };
    assert!(!skipped(d));
    // The same command again: the piece is current, left as it is; the
    // report says so, and no figure of a mosaic it did not make.
    mosaic(d, &args);
    assert!(skipped(d));
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("r.json")).unwrap()).unwrap();
    let keys: Vec<&str> = r.as_object().unwrap().keys().map(|k| k.as_str()).collect();
    assert_eq!(keys, ["output", "output_bytes", "skipped"], "{r}");
    assert_eq!(r["output_bytes"].as_u64(), Some(std::fs::metadata(&piece).unwrap().len()));
    assert_eq!(std::fs::metadata(&piece).unwrap().modified().unwrap(), first);
    // Asked for its seamlines as well, it makes them (and so the piece).
    let with_seams = [&args[..], &["--seamlines-out", "again.geojson"]].concat();
    mosaic(d, &with_seams);
    assert!(!skipped(d) && d.join("again.geojson").exists());
    mosaic(d, &args);
    assert!(skipped(d));
    // Another window, or --force, or a changed plan: made again.
    let mut forced = args.to_vec();
    forced.push("--force");
    mosaic(d, &forced);
    assert!(!skipped(d));
    std::thread::sleep(std::time::Duration::from_millis(20));
    let plan = std::fs::read_to_string(d.join("plan.json")).unwrap();
    std::fs::write(d.join("plan.json"), plan).unwrap();
    mosaic(d, &args);
    assert!(!skipped(d), "a plan written anew redoes the piece");
}

/// A true orthomosaic in shards: the plan made with `--occlusion nodata`,
/// pieces rendered from it with the same setting (quarters, so that bands
/// are cut across), assembled, equal the single true-orthomosaic run byte
/// for byte.
#[test]
fn true_orthomosaic_shards_assemble_into_the_single_run() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    let occ = ["--occlusion", "nodata"];
    mosaic(d, &[&occ[..], &["-o", "whole.tif", "--json", "whole.json"]].concat());
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("whole.json")).unwrap()).unwrap();
    // The frames hide ground behind the block's buildings: visibility is at work.
    let hidden: f64 = report["images"].as_array().unwrap().iter().filter_map(|i| i["hidden_share"].as_f64()).sum();
    assert!(hidden > 0.0 && report["unseen"]["covered_px"].as_u64().unwrap() > 0, "no hidden ground: {report}");
    mosaic(d, &[&occ[..], &["--plan-out", "plan.json"]].concat());
    let info = gcm_ortho::io::source::SourceImage::open(&d.join("whole.tif"), 1 << 20).unwrap().info;
    let t = info.chunk.0;
    let (ta, td) = (info.width.div_ceil(t), info.height.div_ceil(t));
    // Quarters: pieces cut across bands as well as between them.
    let (ha, hd) = (ta / 2, td / 2);
    let windows = [[0, 0, ha, hd], [ha, 0, ta - ha, hd], [0, hd, ha, td - hd], [ha, hd, ta - ha, td - hd]];
    let mut a = vec!["assemble".to_string(), "-o".into(), "joined.tif".into()];
    for (k, w) in windows.iter().enumerate() {
        let name = format!("piece{k}.tif");
        let win = format!("{},{},{},{}", w[0], w[1], w[2], w[3]);
        mosaic(d, &[&occ[..], &["--plan", "plan.json", "--window", &win, "-o", &name]].concat());
        a.push(name);
    }
    let out = std::process::Command::new(bin()).current_dir(d).args(&a).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        std::fs::read(d.join("whole.tif")).unwrap() == std::fs::read(d.join("joined.tif")).unwrap(),
        "assembled true orthomosaic differs from the single run"
    );
}

/// `--resume-dir`: a mosaic stopped (as Ctrl-C stops it) once some of its
/// pieces are finished, run again, takes those pieces as they are, renders
/// the rest and ends with the single run's file byte for byte; the folder
/// is emptied.
#[test]
fn a_stopped_mosaic_run_again_keeps_its_finished_pieces() {
    use std::time::{Duration, Instant};
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    mosaic(d, &["-o", "single.tif", "--cog"]);
    let args = ["mosaic", "manifest.toml", "--quiet", "-o", "r.tif", "--cog", "--resume-dir", "work"];
    let mut child = std::process::Command::new(bin()).current_dir(d).args(args).spawn().unwrap();
    let finished = || {
        std::fs::read_dir(d.join("work")).map_or(0, |r| {
            r.flatten()
                .filter(|e| {
                    let n = e.file_name().to_string_lossy().into_owned();
                    n.starts_with("gcm-ortho-mosaic-piece-") && n.ends_with(".done")
                })
                .count()
        })
    };
    let t0 = Instant::now();
    while finished() == 0 {
        assert!(child.try_wait().unwrap().is_none(), "the run ended before a piece was finished");
        assert!(t0.elapsed() < Duration::from_secs(120));
        std::thread::sleep(Duration::from_millis(2));
    }
    let kill = std::process::Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(kill.success());
    assert!(!child.wait().unwrap().success(), "stopped");
    assert!(!d.join("r.tif").exists());
    let kept = finished();
    let mut again: Vec<&str> = args.to_vec();
    again.extend(["--json", "r.json"]);
    let out = std::process::Command::new(bin()).current_dir(d).args(&again).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("r.json")).unwrap()).unwrap();
    let reused = &report["pieces_reused"];
    assert!(reused[0].as_u64().unwrap() as usize == kept && kept < reused[1].as_u64().unwrap() as usize, "{reused} after {kept} finished");
    assert!(std::fs::read(d.join("r.tif")).unwrap() == std::fs::read(d.join("single.tif")).unwrap(), "the resumed mosaic differs from the single run");
    assert!(!d.join("work").exists());
    // Stopped again, then run on without --cog: the plan and the finished
    // pieces still serve (the layout is the assembly's alone).
    std::fs::remove_file(d.join("r.tif")).unwrap();
    let mut child = std::process::Command::new(bin()).current_dir(d).args(args).spawn().unwrap();
    let t0 = Instant::now();
    while finished() == 0 {
        assert!(child.try_wait().unwrap().is_none(), "the run ended before a piece was finished");
        assert!(t0.elapsed() < Duration::from_secs(120));
        std::thread::sleep(Duration::from_millis(2));
    }
    std::process::Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(!child.wait().unwrap().success());
    let kept = finished();
    // What a run killed outright (SIGKILL) leaves: a piece's temporary,
    // under a process that is gone (pid 0 is no process's) of this host.
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap().trim().to_string();
    std::fs::write(d.join(format!("work/.gcm-ortho-mosaic-piece-000009.tif~0@{host}~abcdef.gcm-partial")), [0u8; 64]).unwrap();
    let plain: Vec<&str> = again.iter().copied().filter(|a| *a != "--cog").collect();
    let out = std::process::Command::new(bin()).current_dir(d).args(&plain).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("r.json")).unwrap()).unwrap();
    assert_eq!(report["pieces_reused"][0].as_u64().unwrap() as usize, kept, "{}", report["pieces_reused"]);
    assert!(!d.join("work").exists(), "the resume folder is left: {:?}", common::files_containing(&d.join("work"), ""));
    // A folder that is the output, or a file: refused by the option's name,
    // nothing made.
    for dir in ["r2.tif", "manifest.toml"] {
        let out = std::process::Command::new(bin())
            .current_dir(d)
            .args(["mosaic", "manifest.toml", "--quiet", "-o", "r2.tif", "--resume-dir", dir])
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{e}");
        assert!(e.contains("--resume-dir") && e.contains(dir), "{e}");
        assert!(!d.join("r2.tif").exists());
    }
}

/// A scan's own holes (here a nodata value over the middle of the top
/// strip's middle frame, which its neighbours see) are filled from the
/// other images: the plan gives those cells to them, and the mosaic has
/// no more empty pixels than without the hole.
#[test]
fn a_scans_own_holes_are_filled_from_the_images_around_it() {
    let Some(python) = python_with("osgeo.gdal", "python3-gdal") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    mosaic(d, &["-o", "whole.tif"]);
    const HOLE: &str = "import sys\nimport numpy as np\nfrom osgeo import gdal\ngdal.UseExceptions()\n\
        p = sys.argv[1]; a = gdal.Open(p).ReadAsArray(); b, h, w = a.shape\n\
        a[:, h * 3 // 10:h * 7 // 10, w * 3 // 10:w * 7 // 10] = 0\n\
        o = gdal.GetDriverByName('GTiff').Create(p + '.new', w, h, b, gdal.GDT_Byte, ['PHOTOMETRIC=RGB'])\n\
        [(o.GetRasterBand(i + 1).WriteArray(a[i]), o.GetRasterBand(i + 1).SetNoDataValue(0)) for i in range(b)]\n\
        o = None";
    // (The dataset and band held: GDAL's bindings crash on a mask of a
    // dataset already collected.)
    const EMPTY: &str = "import sys\nfrom osgeo import gdal\n\
        d = gdal.Open(sys.argv[1]); b = d.GetRasterBand(1); m = b.GetMaskBand()\n\
        print(int((m.ReadAsArray() == 0).sum()))";
    let scan = d.join("scans/002.tif");
    let r = std::process::Command::new(python).args(["-c", HOLE, s(&scan)]).output().unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    std::fs::rename(d.join("scans/002.tif.new"), &scan).unwrap();
    mosaic(d, &["-o", "holed.tif"]);
    let empty = |name: &str| -> u64 {
        let r = std::process::Command::new(python).args(["-c", EMPTY, s(&d.join(name))]).output().unwrap();
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        String::from_utf8_lossy(&r.stdout).trim().parse().unwrap()
    };
    let (whole, holed) = (empty("whole.tif"), empty("holed.tif"));
    // The hole is about 600×400 scan pixels; a few at its edge may stay.
    assert!(holed <= whole + 500, "{holed} empty pixels with the hole, {whole} without");
}

/// An image the mosaic takes nothing of is said, naming it and why: a DEM
/// that stops short of it (an error where the manifest says heights past
/// the DEM are one), and the same scan listed twice under another name.
#[test]
fn images_the_mosaic_takes_nothing_of_are_named() {
    if !have("gdal_translate") {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    let cut = std::process::Command::new("gdal_translate").current_dir(d).args(["-q", "-srcwin", "0", "0", "550", "1100", "dem.tif", "left.tif"]).status();
    assert!(cut.unwrap().success());
    let manifest = std::fs::read_to_string(d.join("manifest.toml")).unwrap();
    let mosaic_of = |name: &str, text: &str| {
        std::fs::write(d.join(name), text).unwrap();
        std::process::Command::new(bin()).current_dir(d).args(["mosaic", name, "-o", "out.tif", "--force", "--quiet"]).output().unwrap()
    };
    // The whole block: no warning of either kind.
    let out = mosaic_of("whole.toml", &manifest);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && !err.contains("warning"), "{err}");
    // The DEM cut to its left part: the right column's frames give
    // nothing, each named with the DEM; those it covers in part warned.
    let out = mosaic_of("left.toml", &manifest.replace("dem.tif", "left.tif"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let nothing: Vec<&str> = err.lines().filter(|l| l.contains("takes nothing of it")).collect();
    assert!(!nothing.is_empty() && nothing.iter().all(|l| l.contains("003.tif") || l.contains("006.tif")), "{err}");
    assert!(nothing.iter().all(|l| l.contains("left.tif")), "the DEM named: {err}");
    assert!(err.contains("covers only part of the image"), "{err}");
    // Under dem_outside = "error": refused in one line, nothing written.
    for done in ["out.tif", "out.tif.done"] {
        std::fs::remove_file(d.join(done)).unwrap();
    }
    let strict = manifest.replace("dem = \"dem.tif\"", "dem = \"left.tif\"\ndem_outside = \"error\"");
    let out = mosaic_of("strict.toml", &strict);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    // (The first image it does not wholly cover is named.)
    assert!(err.lines().filter(|l| l.contains("error")).count() == 1 && err.contains("left.tif: covers only part of scans/00"), "{err}");
    assert!(!d.join("out.tif").exists() && common::files_containing(d, "out.tif").is_empty());
    // A scan listed twice, under another name.
    std::fs::copy(d.join("scans/002.tif"), d.join("scans/copy.tif")).unwrap();
    let out = mosaic_of("twice.toml", &format!("{manifest}\n[[job]]\nimage = \"scans/copy.tif\"\ncamera = \"scans/002.toml\"\n"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let nothing: Vec<&str> = err.lines().filter(|l| l.contains("takes nothing of it")).collect();
    assert!(nothing.len() == 1 && nothing[0].contains("copy.tif") && nothing[0].contains("002.tif") && nothing[0].contains("twice"), "{err}");
}

/// A JPEG mosaic made by pieces (`--resume-dir`) is the single run's file
/// byte for byte, overviews included: the pieces are coded losslessly and
/// the mosaic once, at the assembly, from the same pixels.
#[test]
fn a_jpeg_mosaic_made_by_pieces_is_the_single_runs_file() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    let manifest = std::fs::read_to_string(d.join("manifest.toml")).unwrap();
    let jpeg = manifest.replace("[defaults]\n", "[defaults]\ncompress = \"jpeg\"\noverviews = \"2,4\"\n");
    assert_ne!(jpeg, manifest);
    std::fs::write(d.join("manifest.toml"), jpeg).unwrap();
    mosaic(d, &["-o", "single.tif", "--cog"]);
    mosaic(d, &["-o", "pieces.tif", "--cog", "--resume-dir", "work"]);
    assert!(std::fs::read(d.join("single.tif")).unwrap() == std::fs::read(d.join("pieces.tif")).unwrap(), "the pieces' JPEG mosaic differs");
    assert!(!d.join("work").exists());
}

/// An image given a wrong camera (its heading turned half round, or its
/// position 40 m off) still makes a plausible mosaic with its ground in
/// the wrong place: it is named, even with `--quiet`, and the images
/// around it are not. (The whole block draws no warning: the test above.)
#[test]
fn an_image_with_a_wrong_camera_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    let camera = std::fs::read_to_string(d.join("scans/002.toml")).unwrap();
    let line = |key: &str| camera.lines().find(|l| l.starts_with(key)).unwrap().to_string();
    let numbers = |l: &str| -> Vec<f64> { l[l.find('[').unwrap() + 1..l.find(']').unwrap()].split(',').map(|v| v.trim().parse().unwrap()).collect() };
    let (angles, position) = (numbers(&line("angles_deg")), numbers(&line("position")));
    let turned = format!("angles_deg = [{}, {}, {}]", angles[0], angles[1], angles[2] + 180.0);
    let moved = format!("position = [{}, {}, {}]", position[0] + 40.0, position[1], position[2]);
    for wrong in [camera.replace(&line("angles_deg"), &turned), camera.replace(&line("position"), &moved)] {
        std::fs::write(d.join("scans/002.toml"), &wrong).unwrap();
        let out = std::process::Command::new(bin()).current_dir(d).args(["mosaic", "manifest.toml", "-o", "m.tif", "--force", "--quiet"]).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        let doubted: Vec<&str> = err.lines().filter(|l| l.contains("wrong camera or pose")).collect();
        assert!(doubted.len() == 1 && doubted[0].contains("002.tif"), "{err}");
    }
}

/// Slips of editing seamlines in a GIS are said, naming the feature: an
/// outline that crosses itself (a bow-tie), a ring of no area, a polygon
/// outside the mosaic; the rest of the file is honoured.
#[test]
fn slips_in_edited_seamlines_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    mosaic(d, &["-o", "m.tif", "--seamlines-out", "seams.geojson"]);
    let mut doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("seams.geojson")).unwrap()).unwrap();
    let features = doc["features"].as_array_mut().unwrap();
    // Feature 0's box, from its first polygon's outer ring.
    let ring = features[0]["geometry"]["coordinates"][0][0].as_array().unwrap().clone();
    let xy: Vec<[f64; 2]> = ring.iter().map(|p| [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()]).collect();
    let (x0, x1) = (xy.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min), xy.iter().map(|p| p[0]).fold(f64::NEG_INFINITY, f64::max));
    let (y0, y1) = (xy.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min), xy.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max));
    let polygon = |pts: &[[f64; 2]]| serde_json::json!({ "type": "Polygon", "coordinates": [pts] });
    features[0]["geometry"] = polygon(&[[x0, y0], [x1, y1], [x1, y0], [x0, y1], [x0, y0]]);
    let image1 = features[1]["properties"].clone();
    let image2 = features[2]["properties"].clone();
    features.push(serde_json::json!({ "type": "Feature", "properties": image1, "geometry": polygon(&[[x0, y0], [x1, y1], [x0, y0]]) }));
    let far = [[x0 + 1e5, y0], [x1 + 1e5, y0], [x1 + 1e5, y1], [x0 + 1e5, y1], [x0 + 1e5, y0]];
    features.push(serde_json::json!({ "type": "Feature", "properties": image2, "geometry": polygon(&far) }));
    // Properties that disagree: the image's name is taken, the rest said.
    let mut mixed = image2.clone();
    (mixed["index"], mixed["file"]) = (serde_json::json!(1), serde_json::json!("elsewhere.tif"));
    features.push(serde_json::json!({ "type": "Feature", "properties": mixed, "geometry": polygon(&far) }));
    std::fs::write(d.join("edited.geojson"), serde_json::to_string(&doc).unwrap()).unwrap();
    let out = std::process::Command::new(bin())
        .current_dir(d)
        .args(["mosaic", "manifest.toml", "-o", "e.tif", "--seamlines", "edited.geojson", "--quiet"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let said =
        |what: &str, feature: usize| err.lines().any(|l| l.contains("edited.geojson") && l.contains(&format!("features[{feature}]")) && l.contains(what));
    let n = doc["features"].as_array().unwrap().len();
    assert!(said("crosses itself", 0), "{err}");
    assert!(said("no area", n - 3), "{err}");
    assert!(said("holds no cell of the mosaic", n - 2), "{err}");
    let name = image2["image"].as_str().unwrap();
    assert!(said(&format!("index 1 is not image '{name}'"), n - 1) && said("file elsewhere.tif is not image", n - 1), "{err}");
    // An image named again: by another shape, or by the same one pasted twice.
    let name1 = image1["image"].as_str().unwrap();
    assert!(said(&format!("names image '{name1}' as features[1] does"), n - 3), "{err}");
    assert!(said(&format!("repeats features[{}] (image '{name}', the same geometry)", n - 2), n - 1), "{err}");
    // A feature pasted forty times: twenty doubts said, the rest counted.
    let copy = doc["features"][n - 2].clone();
    doc["features"].as_array_mut().unwrap().extend(std::iter::repeat_n(copy, 40));
    std::fs::write(d.join("pasted.geojson"), serde_json::to_string(&doc).unwrap()).unwrap();
    let out = std::process::Command::new(bin())
        .current_dir(d)
        .args(["mosaic", "manifest.toml", "-o", "p.tif", "--seamlines", "pasted.geojson", "--quiet"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let doubts = err.lines().filter(|l| l.contains("pasted.geojson") && l.contains("features[")).count();
    let more = err.lines().find_map(|l| l.split("and ").nth(1)?.strip_suffix(" more such doubts")?.parse::<usize>().ok());
    assert!(doubts == 20 && more.is_some_and(|m| m >= 40), "{err}");

    // What cannot be honoured is refused, naming the feature: a ring cut
    // open by hand, an index past the manifest's images; and --seams,
    // which edited seamlines replace.
    let refused = |edit: &dyn Fn(&mut serde_json::Value), extra: &[&str]| {
        let mut doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("seams.geojson")).unwrap()).unwrap();
        edit(&mut doc);
        std::fs::write(d.join("broken.geojson"), serde_json::to_string(&doc).unwrap()).unwrap();
        let out = std::process::Command::new(bin())
            .current_dir(d)
            .args(["mosaic", "manifest.toml", "-o", "b.tif", "--seamlines", "broken.geojson", "--quiet"])
            .args(extra)
            .output()
            .unwrap();
        assert!(!d.join("b.tif").exists());
        (out.status.code(), String::from_utf8_lossy(&out.stderr).to_string())
    };
    let (code, err) = refused(&|doc| doc["features"][0]["geometry"]["coordinates"][0][0].as_array_mut().unwrap().truncate(3), &[]);
    assert!(code == Some(1) && err.contains("broken.geojson") && err.contains("features[0].geometry.coordinates") && err.contains("closed"), "{err}");
    let (code, err) = refused(&|doc| doc["features"][0]["properties"] = serde_json::json!({ "index": 99 }), &[]);
    assert!(code == Some(1) && err.contains("features[0].properties.index") && err.contains("99 is not an image of the manifest"), "{err}");
    // Coordinates that are no array (a string, an object) at any level: refused, never quoted.
    for (level, of) in [("", "polygons"), ("/0", "rings"), ("/0/0", "positions")] {
        let (code, err) = refused(&|doc| *doc.pointer_mut(&format!("/features/0/geometry/coordinates{level}")).unwrap() = serde_json::json!("TOPSECRET"), &[]);
        assert!(
            code == Some(1) && err.contains("features[0].geometry.coordinates") && err.contains(&format!("expected an array of {of}, found a string")),
            "{err}"
        );
        assert!(!err.contains("TOPSECRET"), "{err}");
    }
    let (code, err) = refused(&|_| {}, &["--seams", "voronoi"]);
    assert!(code == Some(2) && err.contains("--seams") && err.contains("--seamlines"), "{err}");
}

/// A blend hundreds of pixels wide (a typo, or a misunderstanding of the
/// option) mixes images over their whole overlaps: warned of, even with
/// `--quiet`; the default's is not.
#[test]
fn a_blend_wider_than_a_seam_needs_is_warned_of() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    for (blend, warned) in [("8", false), ("1e9", true)] {
        let out = std::process::Command::new(bin())
            .current_dir(d)
            .args(["mosaic", "manifest.toml", "-o", "m.tif", "--force", "--quiet", "--blend", blend])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert_eq!(err.contains("--blend") && err.contains("whole overlap"), warned, "--blend {blend}: {err}");
    }
}

/// An image whose pose is wrong but refined by GCPs takes the same place in
/// the mosaic as with the right pose: its footprint, seams and pixels come
/// from the refined pose (the plan took the unrefined one, so its seams
/// and footprint were where the pixels were not).
#[test]
fn a_pose_refined_by_gcps_places_the_seams_as_the_right_pose_does() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    block(d);
    mosaic(d, &["-o", "right.tif", "--seamlines-out", "right.geojson"]);
    // GCPs of frame 2 from its true camera (a lattice over the frame, at
    // heights 40 m apart), then its pose made wrong by 30 m and a degree.
    let cam_path = d.join("scans/002.toml");
    let truth = gcm_ortho::camera::file::Camera::read(&cam_path).unwrap();
    let mut csv = String::from("id,col,row,x,y,z\n");
    for k in 0..12 {
        let (c, r) = (100.0 + 433.0 * (k % 4) as f64, 100.0 + 400.0 * (k / 4) as f64);
        let z = 40.0 * (k % 3) as f64;
        let (x, y) = gcm_ortho::camera::locate(truth.model(), c, r, z, 1e-6).unwrap_or_else(|| panic!("({c}, {r}) at {z} m"));
        csv += &format!("g{k},{c},{r},{x},{y},{z}\n");
    }
    std::fs::write(d.join("gcp002.csv"), csv).unwrap();
    std::fs::write(d.join("gcp002.prj"), "EPSG:32631").unwrap();
    let mut file = gcm_ortho::camera::file::CameraFile::read(&cam_path).unwrap();
    let ext = file.exterior.as_mut().unwrap();
    ext.position[0] += 30.0;
    ext.angles_deg[0] += 1.0;
    std::fs::write(d.join("scans/002_wrong.toml"), file.to_toml()).unwrap();
    let manifest = std::fs::read_to_string(d.join("manifest.toml")).unwrap();
    let wrong = manifest.replace("camera = \"scans/002.toml\"", "camera = \"scans/002_wrong.toml\"\ngcps = \"gcp002.csv\"");
    assert_ne!(wrong, manifest);
    std::fs::write(d.join("manifest.toml"), wrong).unwrap();
    mosaic(d, &["-o", "refined.tif", "--seamlines-out", "refined.geojson"]);
    let seams = |name: &str| std::fs::read_to_string(d.join(name)).unwrap();
    assert!(seams("refined.geojson") == seams("right.geojson"), "the seams of the refined pose are not the right pose's");
    let (a, info_a) = whole_image(&d.join("right.tif"));
    let (b, info_b) = whole_image(&d.join("refined.tif"));
    assert_eq!((info_a.width, info_a.height), (info_b.width, info_b.height));
    let off = a.iter().zip(&b).filter(|(p, q)| p.abs_diff(**q) > 1).count();
    assert!(off * 10_000 <= a.len(), "{off} of {} samples more than 1 DN off the right pose's mosaic", a.len());
}
