//! Tried as a careless or unlucky user would: outputs named like inputs,
//! absurd settings, files of the wrong kind, killed runs, damaged data. No
//! input is ever changed, nothing is left at an output path after a
//! failure, and the message names the real cause.

mod common;
use common::*;
use std::path::{Path, PathBuf};

fn fixture(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini");
    for f in ["scan.tif", "camera.toml", "dem.tif"] {
        std::fs::copy(root.join(f), dir.join(f)).unwrap();
    }
    (dir.join("scan.tif"), dir.join("camera.toml"), dir.join("dem.tif"))
}

/// The bytes of every file in `dir`, by name.
fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_type().map(|t| t.is_file()).unwrap_or(false))
        .map(|e| (e.file_name().to_string_lossy().into_owned(), std::fs::read(e.path()).unwrap()))
        .collect();
    v.sort();
    v
}

/// Runs `args`, which must be refused with exit code 2 and one line that
/// contains every one of `words`, leaving `dir` exactly as it was.
fn refused(dir: &Path, args: &[&str], words: &[&str]) {
    let before = snapshot(dir);
    let r = run(args);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    for w in words {
        assert!(err.contains(w), "{args:?}: '{w}' not in: {err}");
    }
    assert!(snapshot(dir) == before, "{args:?} changed the folder");
}

/// Runs `args` with `--json` into `dir`; the run must succeed. Its report.
fn report_of(args: &[&str], dir: &Path) -> serde_json::Value {
    let json = dir.join("report.json");
    let r = run(&[args, &["--json", s(&json)]].concat());
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap()
}

#[test]
fn rectify_never_writes_over_an_input_under_any_name() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = fixture(d);
    std::fs::create_dir(d.join("sub")).unwrap();
    std::os::unix::fs::symlink(&scan, d.join("link.tif")).unwrap();
    std::fs::hard_link(&dem, d.join("hard.tif")).unwrap();
    // Files other tools keep beside an input, read with it.
    std::fs::write(d.join("scan.xmp"), "<x:xmpmeta xmlns:x=\"adobe:ns:meta/\"/>").unwrap();
    std::fs::write(d.join("dem.prj"), "EPSG:32631").unwrap();
    let base = ["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--quiet"];
    let with = |extra: &[&str]| -> Vec<String> { base.iter().chain(extra).map(|a| a.to_string()).collect() };
    let cases: Vec<(Vec<String>, Vec<&str>)> = vec![
        (with(&["-o", s(&scan)]), vec!["image", "refusing to write over an input"]),
        (with(&["-o", s(&d.join("sub/../scan.tif"))]), vec!["image"]),
        (with(&["-o", s(&d.join("link.tif"))]), vec!["link.tif", "image"]),
        (with(&["-o", s(&d.join("hard.tif"))]), vec!["hard.tif", "DEM"]),
        (with(&["-o", s(&camera)]), vec!["camera file"]),
        (with(&["-o", s(&d.join("o.tif")), "--json", s(&scan)]), vec!["report", "image"]),
        (with(&["-o", s(&d.join("o.tif")), "--json", s(&d.join("o.tif"))]), vec!["are one file"]),
        (with(&["-o", s(d)]), vec!["is a folder"]),
        (with(&["-o", s(&d.join("scan.xmp"))]), vec!["scan.xmp", "beside an input"]),
        (with(&["-o", s(&d.join("dem.prj"))]), vec!["dem.prj", "beside an input"]),
        (with(&["-o", s(&d.join("o.tif")), "--json", s(&d.join("dem.prj"))]), vec!["report", "dem.prj"]),
    ];
    for (args, words) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        refused(d, &args, &words);
    }
}

/// A pipe or device named as the orthophoto is refused (a file renamed
/// over `/dev/null` would replace it for every process after); a report
/// goes straight into one (`--json /dev/stdout`); a symbolic link to a
/// file is written through, the link kept; one to nothing is refused.
#[test]
fn outputs_that_are_not_files_are_refused_or_written_through() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = fixture(d);
    let fifo = d.join("fifo");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    std::os::unix::fs::symlink("nowhere.tif", d.join("dangling.tif")).unwrap();
    let base = ["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--quiet"];
    refused(d, &[&base[..], &["-o", s(&fifo)]].concat(), &["fifo", "is a named pipe, not a file"]);
    refused(d, &[&base[..], &["-o", s(&d.join("dangling.tif"))]].concat(), &["dangling.tif", "symbolic link to nowhere.tif"]);
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo(), "the pipe is a pipe still");
    // A report into stdout, and into a device, as they are.
    let r = run(&[&base[..], &["-o", s(&d.join("a.tif")), "--json", "/dev/stdout"]].concat());
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let report: serde_json::Value = serde_json::from_slice(&r.stdout).expect("the report on stdout");
    assert!(report["output_bytes"].as_u64().unwrap() > 0, "{report}");
    let r = run(&[&base[..], &["-o", s(&d.join("b.tif")), "--json", "/dev/null"]].concat());
    assert!(r.status.success() && std::fs::metadata("/dev/null").unwrap().file_type().is_char_device());
    // Through a link: the file it names becomes the orthophoto.
    std::fs::write(d.join("old.tif"), b"old").unwrap();
    std::os::unix::fs::symlink("old.tif", d.join("link.tif")).unwrap();
    let r = run(&[&base[..], &["-o", s(&d.join("link.tif"))]].concat());
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(std::fs::symlink_metadata(d.join("link.tif")).unwrap().file_type().is_symlink(), "the link stays");
    assert_eq!(std::fs::read(d.join("old.tif")).unwrap(), std::fs::read(d.join("a.tif")).unwrap(), "the file it names is the orthophoto");
}

/// A reader of the messages that goes away (`2>&1 | head -1`) never fails
/// the work: the run that warns into a closed pipe ends as it would have,
/// its output made (std's printing would panic, exit 101).
#[test]
fn a_closed_pipe_for_messages_does_not_fail_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = fixture(d);
    let out = d.join("o.tif");
    // `--cog --overviews none` is warned of, even with --quiet.
    let mut child = std::process::Command::new(common::bin())
        .args(["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--quiet", "--cog", "--overviews", "none", "-o", s(&out)])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stderr.take());
    drop(child.stdout.take());
    let status = child.wait().unwrap();
    assert!(status.success(), "{status:?}");
    assert!(std::fs::metadata(&out).unwrap().len() > 0);
}

/// An orthophoto without one pixel of image (a grid beside the scan's
/// ground) is warned of, even with --quiet; a DEM whose holes lie under
/// the whole scan is named as that, not as a DEM that misses the scan.
#[test]
fn an_orthophoto_of_nothing_and_a_void_under_the_scan_are_said() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = fixture(d);
    let base = ["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--quiet"];
    let empty = "no pixel of it has a value";
    let r = run(&[&base[..], &["-o", s(&d.join("a.tif"))]].concat());
    assert!(r.status.success() && !String::from_utf8_lossy(&r.stderr).contains(empty), "{}", String::from_utf8_lossy(&r.stderr));
    let r = run(&[&base[..], &["-o", s(&d.join("b.tif")), "--bounds", "648200,4888700,649000,4889500"]].concat());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success() && err.contains("b.tif") && err.contains(empty), "{err}");
    // The DEM's every post a void but one corner's.
    let Some(py) = python_with("osgeo.gdal", "python3-gdal") else { return };
    let script = "import sys\nfrom osgeo import gdal\nds = gdal.Open(sys.argv[1])\na = ds.GetRasterBand(1).ReadAsArray().astype('float32')\na[:, :] = -32768\na[0, 0] = 300\nd = gdal.GetDriverByName('GTiff').CreateCopy(sys.argv[2], ds)\nd.GetRasterBand(1).WriteArray(a)\nd.GetRasterBand(1).SetNoDataValue(-32768)\nd = None\n";
    let void = d.join("void.tif");
    assert!(std::process::Command::new(py).args(["-c", script, s(&dem), s(&void)]).status().unwrap().success());
    let r = run(&["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&void), "--quiet", "-o", s(&d.join("c.tif"))]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.contains("void.tif") && err.contains("fall in its nodata") && !err.contains("does the DEM cover"), "{err}");
    assert!(!d.join("c.tif").exists());
}

/// Under `--nodata 0`, black pixels of the image are not made holes: each
/// sample of a pixel with a value that holds 0 is made 1 (as GDAL's warper
/// does), and the count is said; the internal mask keeps them as they are.
#[test]
fn black_pixels_under_a_nodata_value_of_0_stay_pixels() {
    let Some(py) = python_with("osgeo.gdal", "python3-gdal") else { return };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = fixture(d);
    let black = d.join("black.tif");
    let script = "import sys\nfrom osgeo import gdal\nd = gdal.GetDriverByName('GTiff').CreateCopy(sys.argv[2], gdal.Open(sys.argv[1]))\nfor b in range(d.RasterCount):\n    a = d.GetRasterBand(b + 1).ReadAsArray()\n    a[100:140, 100:140] = 0\n    d.GetRasterBand(b + 1).WriteArray(a)\nd = None\n";
    assert!(std::process::Command::new(py).args(["-c", script, s(&scan), s(&black)]).status().unwrap().success());
    let base = ["rectify", "--image", s(&black), "--camera", s(&camera), "--dem", s(&dem), "--quiet"];
    let r = run(&[&base[..], &["-o", s(&d.join("m.tif"))]].concat());
    assert!(r.status.success() && r.stderr.is_empty(), "{}", String::from_utf8_lossy(&r.stderr));
    let r = run(&[&base[..], &["-o", s(&d.join("n.tif")), "--nodata", "0"]].concat());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    let said: u64 = err.split_whitespace().find_map(|w| w.parse().ok()).unwrap_or_else(|| panic!("a count: {err}"));
    assert!(err.contains("held the nodata value 0 and were made 1"), "{err}");
    // Pixels all 0 (no value) and pixels with some bands 0 (a band read as a hole).
    let zeros = |path: &Path| {
        let (px, info) = common::whole_image(path);
        let b = info.bands as usize;
        let all = px.chunks_exact(b).filter(|p| p.iter().all(|&v| v == 0)).count();
        let some = px.chunks_exact(b).filter(|p| p.contains(&0) && p.iter().any(|&v| v != 0)).count();
        (all, some, b as u64)
    };
    let ((all_m, _, _), (all_n, some_n, bands)) = (zeros(&d.join("m.tif")), zeros(&d.join("n.tif")));
    assert_eq!(some_n, 0, "no pixel with a value has a band read as a hole");
    let made = (all_m - all_n) as u64;
    assert!(made > 500 && bands * made <= said, "{made} black pixels kept, {said} samples said");
}

#[test]
fn files_an_input_names_are_inputs_too() {
    // A DEM folder's, list's or VRT's tiles, and the RPC file a camera
    // file names, are never written over; nor is anything made inside a
    // DEM folder (it would be read as a tile next time).
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = fixture(d);
    std::fs::create_dir(d.join("tiles")).unwrap();
    let tile = d.join("tiles/a.tif");
    std::fs::copy(&dem, &tile).unwrap();
    std::fs::write(d.join("list.txt"), "tiles/a.tif\n").unwrap();
    std::fs::write(
        d.join("dem.vrt"),
        "<VRTDataset rasterXSize=\"1\" rasterYSize=\"1\"><VRTRasterBand band=\"1\"><SimpleSource><SourceFilename relativeToVRT=\"1\">tiles/a.tif</SourceFilename></SimpleSource></VRTRasterBand></VRTDataset>\n",
    )
    .unwrap();
    let rectify = |dem: &Path, camera: &Path, out: &Path| -> Vec<String> {
        ["rectify", "--image", s(&scan), "--camera", s(camera), "--dem", s(dem), "--quiet", "-o", s(out)].iter().map(|a| a.to_string()).collect()
    };
    let tiles = d.join("tiles");
    for (dem, out, words) in [
        (d.join("tiles"), tile.clone(), vec!["inside the DEM", "refusing to write into an input"]),
        (d.join("tiles"), tiles.join("new.tif"), vec!["inside the DEM"]),
        (d.join("list.txt"), tile.clone(), vec!["DEM tile", "refusing to write over an input"]),
        (d.join("dem.vrt"), tile.clone(), vec!["DEM tile"]),
    ] {
        let args = rectify(&dem, &camera, &out);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        refused(&tiles, &args, &words);
    }
    // A camera file of model "rpc" naming its coefficients' file.
    let rpc = d.join("scan_RPC.TXT");
    std::fs::write(&rpc, "LINE_OFF: 1\n").unwrap();
    let rpc_camera = d.join("rpc.toml");
    std::fs::write(&rpc_camera, "crs = \"EPSG:4326\"\n[camera]\nmodel = \"rpc\"\n[rpc]\nfile = \"scan_RPC.TXT\"\n").unwrap();
    let args = rectify(&dem, &rpc_camera, &rpc);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    refused(d, &args, &["RPC file", "refusing to write over an input"]);
}

#[test]
fn batch_names_two_images_of_one_name_by_their_folders() {
    // scan.tif in two folders, each job with its own output: both run.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fixture(d);
    for f in ["one", "two"] {
        std::fs::create_dir(d.join(f)).unwrap();
        std::fs::copy(d.join("scan.tif"), d.join(f).join("scan.tif")).unwrap();
    }
    let manifest = d.join("m.toml");
    std::fs::write(
        &manifest,
        "[defaults]\ndem = \"dem.tif\"\noutput_dir = \"out\"\n[[job]]\nimage = \"one/scan.tif\"\ncamera = \"camera.toml\"\n[[job]]\nimage = \"two/scan.tif\"\ncamera = \"camera.toml\"\n",
    )
    .unwrap();
    std::fs::create_dir(d.join("out")).unwrap();
    let r = run(&["batch", s(&manifest), "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(d.join("out/scan.tif").exists() && d.join("out/two_scan.tif").exists());
}

#[test]
fn assemble_accuracy_and_rpc_grid_never_write_over_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = fixture(d);
    let piece = d.join("piece.tif");
    let r = run(&["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--quiet", "-o", s(&piece)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    refused(d, &["assemble", "-o", s(&piece), s(&piece)], &["piece", "refusing"]);
    // Under other names: a symbolic link and a hard link.
    std::os::unix::fs::symlink(&piece, d.join("piece_link.tif")).unwrap();
    refused(d, &["assemble", "-o", s(&d.join("piece_link.tif")), s(&piece)], &["piece", "refusing"]);
    std::fs::hard_link(&dem, d.join("dem_hard.tif")).unwrap();
    refused(d, &["accuracy", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--json", s(&dem)], &["table", "DEM"]);
    refused(d, &["accuracy", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--json", s(&d.join("dem_hard.tif"))], &["table", "DEM"]);
    // The reference grid of --like is an input too.
    refused(
        d,
        &["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--like", s(&piece), "-o", s(&d.join("piece_link.tif"))],
        &["reference grid"],
    );
    // rpc-grid: the image itself, and a grid named .vrt whose VRT would be itself.
    let v = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/ventoux");
    let image = d.join("left.tif");
    std::fs::copy(v.join("left_image.tif"), &image).unwrap();
    let rpc = v.join("left_image.geom");
    let srtm = v.join("srtm_N44E005_crop.tif");
    let grid = ["rpc-grid", "--image", s(&image), "--rpc", s(&rpc), "--rpc-offset", "5000,5000", "--dem", s(&srtm)];
    refused(d, &[&grid[..], &["-o", s(&image)]].concat(), &["grid", "image"]);
    std::os::unix::fs::symlink(&image, d.join("left_link.tif")).unwrap();
    refused(d, &[&grid[..], &["-o", s(&d.join("left_link.tif"))]].concat(), &["grid", "image"]);
    refused(d, &[&grid[..], &["-o", s(&d.join("grid.vrt"))]].concat(), &["are one file"]);
}

#[test]
fn batch_refuses_outputs_over_inputs_and_collisions() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fixture(d);
    std::fs::copy(d.join("scan.tif"), d.join("b.tif")).unwrap();
    let manifest = d.join("m.toml");
    let cases = [
        // output_dir holding the scans: scan.tif -> ./scan.tif
        ("[defaults]\ndem = \"dem.tif\"\noutput_dir = \".\"\n[[job]]\nimage = \"scan.tif\"\ncamera = \"camera.toml\"\n", "refusing to write over an input"),
        // a job's output is another job's image
        (
            "[defaults]\ndem = \"dem.tif\"\n[[job]]\nimage = \"scan.tif\"\ncamera = \"camera.toml\"\noutput = \"b.tif\"\n[[job]]\nimage = \"b.tif\"\ncamera = \"camera.toml\"\noutput = \"c.tif\"\n",
            "refusing to write over an input",
        ),
        // two jobs, one output
        (
            "[defaults]\ndem = \"dem.tif\"\n[[job]]\nimage = \"scan.tif\"\ncamera = \"camera.toml\"\noutput = \"o.tif\"\n[[job]]\nimage = \"b.tif\"\ncamera = \"camera.toml\"\noutput = \"o.tif\"\n",
            "are one file",
        ),
    ];
    for (text, word) in cases {
        std::fs::write(&manifest, text).unwrap();
        let before = snapshot(d);
        for extra in [&["--dry-run"][..], &[][..]] {
            let r = run(&[&["batch", s(&manifest), "--quiet"][..], extra].concat());
            let err = String::from_utf8_lossy(&r.stderr);
            // A refusal, as for rectify: exit 2, the manifest named once.
            assert_eq!(r.status.code(), Some(2), "{text}: {err}");
            assert!(err.contains(word), "{text}: {err}");
            assert_eq!(err.matches("m.toml").count(), 1, "{err}");
        }
        assert!(snapshot(d) == before, "{text}");
    }
    // The report over the manifest.
    std::fs::write(&manifest, "[defaults]\ndem = \"dem.tif\"\n[[job]]\nimage = \"scan.tif\"\ncamera = \"camera.toml\"\n").unwrap();
    refused(d, &["batch", s(&manifest), "--quiet", "--report", s(&manifest)], &["report", "manifest"]);
}

#[test]
fn absurd_settings_are_refused_before_any_work_with_their_flag() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = fixture(d);
    let out = d.join("o.tif");
    let base = ["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--quiet", "-o", s(&out)];
    for (extra, flag) in [
        (&["--memory", "1e20"][..], "--memory"),
        (&["--memory", "100T"][..], "--memory"),
        (&["--threads", "100000"][..], "--threads"),
        (&["--sparsity", "100000000"][..], "--sparsity"),
        (&["--gsd", "0.00001"][..], "--gsd"),
        (&["--gsd", "0.01"][..], "--max-output-pixels"),
        (&["--nodata", "300"][..], "--nodata"),
        (&["--nodata", "0.5"][..], "--nodata"),
        (&["--window", "4294967295,0,2,1"][..], "--window"),
        (&["--tile", "100"][..], "--tile"),
    ] {
        let t = std::time::Instant::now();
        refused(d, &[&base[..], extra].concat(), &[flag]);
        assert!(t.elapsed().as_secs() < 10, "{extra:?} took {:?}", t.elapsed());
        assert!(files_containing(d, "partial").is_empty());
    }
    // accuracy's own options, by name, never a panic.
    for (extra, flag) in [
        (&["--sparsity", "0"][..], "--sparsity"),
        (&["--step", "0"], "--step"),
        (&["--max-error=-1"], "--max-error"),
        (&["--map-sparsity", "0"], "--map-sparsity"),
    ] {
        refused(d, &[&["accuracy", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem)][..], extra].concat(), &[flag]);
    }
    // A report that cannot be written is found before the work: nothing
    // is left at the output path.
    let r = run(&[&base[..], &["--json", "/proc/gcm-ortho-report.json"]].concat());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("/proc/gcm-ortho-report.json") && err.trim_end().lines().count() == 1, "{err}");
    assert!(!out.exists(), "{err}");
    // A constant height no ground has.
    refused(d, &["rectify", "--image", s(&scan), "--camera", s(&camera), "--height=-1e30", "--quiet", "-o", s(&out)], &["--height", "earth's surface"]);
    // A GSD past the footprint is said to be that, not too many pixels.
    refused(d, &[&base[..], &["--gsd", "1e30"]].concat(), &["--gsd", "less than one pixel"]);
    refused(d, &[&base[..], &["--gsd", "1e-30"]].concat(), &["--gsd", "more pixels a side than a raster holds"]);
    // An input that is not there is named with its option.
    for (flag, with) in [("--image", vec!["--camera", s(&camera), "--dem", s(&dem)]), ("--dem", vec!["--image", s(&scan), "--camera", s(&camera)])] {
        let r = run(&[&["rectify", flag, "gone.tif", "--quiet", "-o", s(&out)][..], &with].concat());
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.code() == Some(1) && err.contains(&format!("{flag} gone.tif")) && err.trim_end().lines().count() == 1, "{err}");
    }
    // Metres meant, in a CRS of degrees: refused, not a one-pixel orthophoto.
    refused(d, &[&base[..], &["--crs", "EPSG:4326", "--gsd", "0.5"]].concat(), &["--gsd", "degrees"]);
    // Usage errors in one line with the program's prefix, the argument named.
    refused(d, &[&base[..], &["--bogus"]].concat(), &["gcm-ortho: error:", "'--bogus'", "--bounds"]);
    refused(d, &["rectify", "--quiet"], &["gcm-ortho: error:", "--image", "--camera"]);
    // A satellite image has no camera file: its RPC is named beside it.
    refused(d, &["rectify", "--image", s(&scan), "--height", "100", "--quiet", "-o", s(&out)], &["--camera <CAMERA> (or --rpc <RPC>"]);
    // Negative numbers are values, refused as such (not taken for flags).
    refused(d, &[&base[..], &["--gsd", "-0.5"]].concat(), &["--gsd", "-0.5 must be positive"]);
    refused(d, &[&base[..], &["--max-error", "-1"]].concat(), &["--max-error", "'-1'"]);
    // Bounds in degrees under a CRS in metres: said so.
    let r = run(&[&base[..], &["--bounds", "5.29,44.14,5.31,44.16"]].concat());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.code() == Some(2) && err.contains("--bounds") && err.contains("look like degrees") && err.trim_end().lines().count() == 1, "{err}");
    assert!(!out.exists());
    // Northing first: said so, naming --bounds (not the DEM alone).
    let r = run(&[&base[..], &["--bounds", "4890800,650400,4891000,650600"]].concat());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.code() == Some(2) && err.contains("--bounds") && err.contains("X and Y swapped") && err.trim_end().lines().count() == 1, "{err}");
    assert!(!out.exists());
    // A COG without overviews is warned of, even when quiet.
    let r = run(&[&base[..], &["--cog", "--overviews", "none"]].concat());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success() && err.contains("--cog with --overviews none"), "{err}");
    std::fs::remove_file(&out).unwrap();
    refused(d, &[&base[..], &["--resample", "sinc"]].concat(), &["gcm-ortho: error:", "'sinc'", "--resample", "lanczos3"]);
    // The limit is the user's to set, down or up.
    refused(d, &[&base[..], &["--max-output-pixels", "1k"]].concat(), &["--max-output-pixels", "0.00 Gpx allowed"]);
    let r = run(&[&base[..], &["--max-output-pixels", "1G"]].concat());
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
}

#[test]
fn a_node_spacing_whose_nodes_alone_pass_the_budget_is_refused_with_what_it_takes() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 1000, |_| {});
    let out = dir.path().join("o.tif");
    let base = ["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(&out), "--memory", "16M"];
    refused(dir.path(), &[&base[..], &["--sparsity", "1", "--corrections", "cell"]].concat(), &["--sparsity", "MB of GCM nodes", "or more"]);
    // A spacing of 3: its node rows (about 7 MB) fit the whole budget but
    // not what the plan can give them beside the rest (a quarter).
    let r = run(&[&base[..], &["--sparsity", "3"]].concat());
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    // With the memory it names, it runs.
    let need = err.split("--memory ").nth(1).and_then(|t| t.split_whitespace().next()).expect("the memory it takes").to_string();
    let r = run(&[&base[..10], &["--memory", &need, "--sparsity", "3"]].concat());
    assert!(r.status.success(), "--memory {need}: {}", String::from_utf8_lossy(&r.stderr));
    // The same run at a spacing of 8 fits.
    let r = run(&[&base[..], &["--sparsity", "8"]].concat());
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
}

#[test]
fn a_long_output_name_works_and_dead_runs_leave_nothing_for_long() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = fixture(d);
    // What a run killed by SIGKILL leaves: its temporary, under a process
    // that is gone (pid 0 is no process's) of this host.
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap().trim().to_string();
    let stale = d.join(format!(".o.tif~0@{host}~abcdef.gcm-partial"));
    std::fs::write(&stale, vec![0u8; 4096]).unwrap();
    let name = format!("{}.tif", "n".repeat(246));
    assert_eq!(name.len(), 250);
    let out = d.join(&name);
    let r = run(&["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--quiet", "-o", s(&out)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(out.exists() && !stale.exists());
    assert!(files_containing(d, "partial").is_empty());
}

#[test]
fn a_chunk_that_fails_its_checksum_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("scene"), 400, |o| o.compress = gcm_ortho::io::tiff_out::Compression::Deflate);
    let src = gcm_ortho::io::source::SourceImage::open(&sc.scan, 1 << 20).unwrap();
    let (offsets, counts) = src.info.chunk_table();
    let (at, len) = (offsets[1], counts[1]);
    drop(src);
    // The last byte of chunk 1's stream is its Adler-32's last byte.
    let mut bytes = std::fs::read(&sc.scan).unwrap();
    bytes[(at + len - 1) as usize] ^= 0x01;
    std::fs::write(&sc.scan, bytes).unwrap();
    let out = d.join("o.tif");
    let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(&out)]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.contains("scan.tif") && err.contains("chunk 1") && err.contains("deflate"), "{err}");
    assert!(!out.exists() && files_containing(d, "partial").is_empty());
}

#[test]
fn an_rpc_tag_is_read_from_a_large_image_without_reading_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let small = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif");
    // The same TIFF, grown to 20 GB (a hole in the file): the directory and
    // the pixels are where they were, and the RPC tag is in the directory.
    let big = d.join("big.tif");
    std::fs::copy(&small, &big).unwrap();
    std::fs::OpenOptions::new().write(true).open(&big).unwrap().set_len(20 << 30).unwrap();
    let out = d.join("o.tif");
    // Any image will do for the geometry: the point is the RPC file's size.
    let image = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/ventoux/left_image.tif");
    let report = report_of(&["rectify", "--image", s(&image), "--rpc", s(&big), "--quiet", "-o", s(&out)], d);
    let peak = report["peak_rss_mib"].as_f64().unwrap();
    assert!(peak < 256.0, "peak {peak} MiB");
    // A text RPC file that is in fact that image is refused from its size.
    let r = run(&["rectify", "--image", s(&image), "--camera", s(&big), "--height", "100", "--quiet", "-o", s(&out)]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.contains("too large for a camera or pose file"), "{err}");
}

#[test]
fn a_batch_of_more_jobs_than_its_memory_holds_runs_fewer_at_once_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fixture(d);
    let manifest = d.join("m.toml");
    std::fs::write(&manifest, "[defaults]\ndem = \"dem.tif\"\noutput_dir = \"out\"\n[[job]]\nimage = \"scan.tif\"\ncamera = \"camera.toml\"\n").unwrap();
    let r = run(&["batch", s(&manifest), "--quiet", "--jobs", "96", "--memory", "64M"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains("warning") && err.contains("running 4 at a time, not 96"), "{err}");
    assert!(d.join("out/scan.tif").exists());
}

#[test]
fn a_batch_rerun_redoes_an_output_damaged_since() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fixture(d);
    let manifest = d.join("m.toml");
    std::fs::write(&manifest, "[defaults]\ndem = \"dem.tif\"\noutput_dir = \"out\"\n[[job]]\nimage = \"scan.tif\"\ncamera = \"camera.toml\"\n").unwrap();
    let report = d.join("r.jsonl");
    let status = || -> String {
        let r = run(&["batch", s(&manifest), "--quiet", "--report", s(&report)]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let line: serde_json::Value = serde_json::from_str(std::fs::read_to_string(&report).unwrap().lines().next().unwrap()).unwrap();
        line["status"].as_str().unwrap().to_string()
    };
    assert_eq!(status(), "done");
    assert_eq!(status(), "skipped");
    let out = d.join("out/scan.tif");
    let good = std::fs::read(&out).unwrap();
    // Cut short by something else: made again, whole.
    std::fs::write(&out, &good[..good.len() / 2]).unwrap();
    assert_eq!(status(), "done");
    assert!(std::fs::read(&out).unwrap() == good);
    // A changed camera that fails: the earlier output is no longer marked
    // finished, and the job's error says it is left from an earlier run.
    let camera = std::fs::read_to_string(d.join("camera.toml")).unwrap();
    let broken = camera.replace("focal_length_mm", "focal_length_mm = -1\nold_focal");
    assert_ne!(broken, camera);
    std::fs::write(d.join("camera.toml"), broken).unwrap();
    let r = run(&["batch", s(&manifest), "--quiet", "--report", s(&report)]);
    assert_eq!(r.status.code(), Some(3), "{}", String::from_utf8_lossy(&r.stderr));
    let line: serde_json::Value = serde_json::from_str(std::fs::read_to_string(&report).unwrap().lines().next().unwrap()).unwrap();
    assert_eq!(line["status"], "failed");
    assert!(line["error"].as_str().unwrap().contains("left from an earlier run"), "{line}");
    assert!(!d.join("out/scan.tif.done").exists(), "the stale output's record is gone");
}

#[test]
fn a_command_that_does_not_poll_still_ends_at_sigterm() {
    let dir = tempfile::tempdir().unwrap();
    let child = std::process::Command::new(bin())
        .args(["synth", "--out", s(&dir.path().join("scene")), "--size", "6000x6000", "--quiet"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(300));
    assert!(std::process::Command::new("kill").args(["-15", &child.id().to_string()]).status().unwrap().success());
    let out = wait_deadline(child, 10);
    assert_eq!(out.status.code(), Some(143), "{}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn a_global_geoid_grid_is_read_only_where_the_scene_is() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A global grid at 1′ (10801 × 21601 samples, 933 MB; a hole in the
    // file: every undulation 0).
    let gtx = d.join("global_1min.gtx");
    let (rows, cols) = (10801i32, 21601i32);
    let mut head = Vec::new();
    for v in [-90.0f64, -180.0, 1.0 / 60.0, 1.0 / 60.0] {
        head.extend_from_slice(&v.to_be_bytes());
    }
    head.extend_from_slice(&rows.to_be_bytes());
    head.extend_from_slice(&cols.to_be_bytes());
    std::fs::write(&gtx, &head).unwrap();
    std::fs::OpenOptions::new().write(true).open(&gtx).unwrap().set_len(40 + 4 * rows as u64 * cols as u64).unwrap();
    let v = |n: &str| Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/ventoux").join(n);
    let out = d.join("o.tif");
    let (image, rpc, dem) = (v("left_image.tif"), v("left_image.geom"), v("srtm_N44E005_crop.tif"));
    let args = ["rectify", "--image", s(&image), "--rpc", s(&rpc), "--rpc-offset", "5000,5000", "--dem", s(&dem), "--geoid", s(&gtx), "--quiet"];
    let report = report_of(&[&args[..], &["-o", s(&out)]].concat(), d);
    let peak = report["peak_rss_mib"].as_f64().unwrap();
    assert!(peak < 128.0, "peak {peak} MiB with a 933 MB geoid grid");
}

/// A striped `w`×`h` 8-bit grey TIFF whose strips are a hole in the file
/// (zeros), written without writing its pixels.
fn sparse_tiff(path: &Path, w: u32, h: u32) {
    let rps = 16u32;
    let n = h.div_ceil(rps) as usize;
    let (ifd, entries) = (16u64, 9u64);
    let offs_at = ifd + 8 + entries * 20 + 8;
    let counts_at = offs_at + 8 * n as u64;
    let pixels_at = (counts_at + 8 * n as u64).div_ceil(4096) * 4096;
    let row = w as u64;
    let offsets: Vec<u64> = (0..n as u64).map(|i| pixels_at + i * rps as u64 * row).collect();
    let counts: Vec<u64> = (0..n as u64).map(|i| (rps as u64).min(h as u64 - i * rps as u64) * row).collect();
    let mut b = b"II".to_vec();
    b.extend(43u16.to_le_bytes().iter().chain(&8u16.to_le_bytes()).chain(&0u16.to_le_bytes()).chain(&ifd.to_le_bytes()));
    b.extend_from_slice(&entries.to_le_bytes());
    let mut entry = |tag: u16, typ: u16, count: u64, value: u64| {
        b.extend(tag.to_le_bytes().iter().chain(&typ.to_le_bytes()).chain(&count.to_le_bytes()).chain(&value.to_le_bytes()));
    };
    entry(256, 4, 1, w as u64);
    entry(257, 4, 1, h as u64);
    entry(258, 3, 1, 8);
    entry(259, 3, 1, 1);
    entry(262, 3, 1, 1);
    entry(273, 16, n as u64, offs_at);
    entry(277, 3, 1, 1);
    entry(278, 4, 1, rps as u64);
    entry(279, 16, n as u64, counts_at);
    b.extend_from_slice(&0u64.to_le_bytes());
    b.extend(offsets.iter().flat_map(|o| o.to_le_bytes()));
    b.extend(counts.iter().flat_map(|c| c.to_le_bytes()));
    std::fs::write(path, &b).unwrap();
    std::fs::OpenOptions::new().write(true).open(path).unwrap().set_len(offsets[n - 1] + counts[n - 1]).unwrap();
}

#[test]
fn every_reader_on_a_large_file_stays_within_the_memory_budget() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini");
    // The mini scene's film scanned 150 times finer (30000² px, 900 MB;
    // its fiducials in pixels scaled alike), and a 256 MB DEM over it at
    // 0.6 m: both far past the budget.
    let scan = d.join("scan.tif");
    sparse_tiff(&scan, 30_000, 30_000);
    let mut cam = gcm_ortho::camera::file::CameraFile::read(&root.join("camera.toml")).unwrap();
    let interior = cam.interior.as_mut().unwrap();
    for p in interior.fiducials_px.as_mut().unwrap() {
        *p = [p[0] * 150.0, p[1] * 150.0];
    }
    let camera = d.join("camera.toml");
    std::fs::write(&camera, cam.to_toml()).unwrap();
    let mini = gcm_ortho::dem::GridDem::read(&root.join("dem.tif")).unwrap();
    let dem = d.join("dem.tif");
    let z = mini.sample(47, 47);
    f32_raster(&dem, (8000, 8000), (mini.transform[0], mini.transform[3], 0.6, 32631), |_, _| z);
    let out = d.join("o.tif");
    let args = ["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--gsd", "11.54", "--memory", "64M", "--quiet"];
    let report = report_of(&[&args[..], &["-o", s(&out)]].concat(), d);
    let peak = report["peak_rss_mib"].as_f64().unwrap();
    eprintln!("peak {peak} MiB, grid {}", report["grid"]);
    assert!(peak < 64.0, "peak {peak} MiB under --memory 64M");
}

#[test]
fn a_tile_whose_window_passes_the_budget_is_made_strip_by_strip_with_the_same_pixels() {
    // An output pixel 40 scan pixels wide: one tile's window is the whole
    // scan, far past what 16 MiB allows a window. The scan is turned 30°
    // against the output, so that a row's window crosses much of it: the
    // strips are cut across too.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("scene"), 3000, |_| {});
    let gsd = (40.0 * sc.gsd).to_string();
    for order in ["rows", "columns"] {
        let make = |memory: &str| {
            let out = d.join(format!("o{memory}{order}.tif"));
            let a = ["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--gsd", &gsd, "--memory", memory, "--quiet"];
            let report = report_of(&[&a[..], &["--band-order", order, "-o", s(&out)]].concat(), d);
            (std::fs::read(&out).unwrap(), report)
        };
        let (small, report) = make("16M");
        let (large, _) = make("1G");
        assert!(small == large, "{order}: the strips make other pixels than the whole window");
        // (The whole window alone, 27 MB, took the run to 39 MiB.)
        assert!(report["peak_rss_mib"].as_f64().unwrap() < 24.0, "{order}: {}", report["peak_rss_mib"]);
    }
}

#[test]
fn a_tile_too_large_for_the_budget_is_refused_with_what_it_takes_and_that_holds() {
    // 4096² RGB tiles and their mask: 64 MiB each, two of them in hand
    // (the one tile, and its encoding): past half of the default 128M.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("scene"), 1200, |_| {});
    let out = d.join("o.tif");
    let base = ["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(&out), "--tile", "4096"];
    refused(d, &base, &["--tile", "4096", "give --memory", "smaller tile"]);
    // 1024² tiles at 24M on an output four tiles wide: the streamed
    // overviews and the tiles both pass the budget; the figure given is
    // the one that holds both, not one refused by the other check.
    let wide = ["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(&out), "--tile", "1024", "--gsd", "0.7"];
    let wide_at = [&wide[..], &["--memory", "24M"]].concat();
    for (base, bare) in [(&base[..], &base[..]), (&wide_at[..], &wide[..])] {
        let r = run(base);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{err}");
        let need = err.split("--memory ").nth(1).and_then(|t| t.split_whitespace().next()).expect("the memory it takes").to_string();
        // With it, the run stays within it.
        let report = report_of(&[bare, &["--memory", &need]].concat(), d);
        let mib: f64 = need.trim_end_matches('M').parse().unwrap();
        assert!(report["peak_rss_mib"].as_f64().unwrap() < mib, "{} MiB at --memory {need}", report["peak_rss_mib"]);
    }
}

/// `gcm-ortho rectify … | head -1`: the report meets a closed pipe. The
/// orthophoto is made, nothing panics, the exit is 0.
#[test]
fn a_closed_stdout_is_no_panic() {
    let dir = tempfile::tempdir().unwrap();
    let r = common::scene(&dir.path().join("scene"), 400, |_| {});
    let out = dir.path().join("o.tif");
    let mut child = std::process::Command::new(common::bin())
        .args(["rectify", "--image", common::s(&r.scan), "--camera", common::s(&r.camera), "--dem", common::s(&r.dem), "-o", common::s(&out)])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && !err.contains("panicked"), "{err}");
    assert!(out.exists());
}

/// A scan five times the size its camera file describes (the wrong camera
/// file, or a resized image), rectified at a coarse pixel: the plan's
/// samples of some chunks all fell off the scan while pixels between them
/// were on it; the resampler indexed the empty window and panicked, and
/// the pipeline then waited for that chunk forever. Now such pixels are
/// read on their own: the run ends, and the same at any memory budget.
#[test]
fn a_chunk_whose_window_is_empty_neither_panics_nor_hangs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let small = scene(&d.join("small"), 800, |o| {
        o.height = 600;
        o.camera = gcm_ortho::synth::CameraKind::Drone;
        o.relief = gcm_ortho::synth::Relief::Urban;
    });
    let big = scene(&d.join("big"), 4000, |o| {
        o.height = 3000;
        o.camera = gcm_ortho::synth::CameraKind::Drone;
        o.relief = gcm_ortho::synth::Relief::Urban;
        o.no_scan = false;
    });
    let mut outputs = Vec::new();
    for memory in ["24M", "1G"] {
        let out = d.join(format!("o-{memory}.tif"));
        let child = std::process::Command::new(bin())
            .args(["rectify", "--image", s(&big.scan), "--camera", s(&small.camera), "--dem", s(&small.dem), "-o", s(&out), "--quiet"])
            .args(["--gsd", "2", "--overviews", "none", "--memory", memory])
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let r = wait_deadline(child, 60);
        assert!(r.status.success(), "{memory}: {}", String::from_utf8_lossy(&r.stderr));
        outputs.push(whole_image(&out).0);
    }
    assert!(outputs[0] == outputs[1], "the same pixels at 24M and 1G");
}

#[test]
fn doubtful_inputs_are_warned_about_even_when_quiet() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = fixture(d);
    let warned = |args: &[&str], words: &[&str]| {
        let r = run(args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.success(), "{args:?}: {err}");
        for w in words {
            assert!(err.contains("warning") && err.contains(w), "{args:?}: '{w}' not in: {err}");
        }
    };
    let out = d.join("o.tif");
    // A DEM without a CRS: taken to be in the ground's, said so.
    let g = gcm_ortho::dem::GridDem::read(&dem).unwrap();
    let bare = d.join("bare.tif");
    let t = g.transform;
    f32_raster_with_keys(&bare, (g.width as u32, g.height as u32), (t[0], t[3], t[1]), Default::default(), |c, r| g.sample(c as usize, r as usize));
    warned(&["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&bare), "--quiet", "-o", s(&out)], &["has no CRS"]);
    // More threads than cores: fewer taken, said so; a GSD so coarse the
    // output is one pixel: its aliasing said (a whole pixel from the grid's
    // centre lies past the horizon there).
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let many = (cores + 1).to_string();
    for (extra, words) in [(["--threads", &many], &["--threads", "more than the"]), (["--gsd", "200"], &["scan pixels", "aliases"])] {
        std::fs::remove_file(&out).unwrap();
        warned(&[&["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--quiet", "-o", s(&out)][..], &extra].concat(), words);
    }
    // What was said is in the report too.
    std::fs::remove_file(&out).unwrap();
    let report = report_of(&["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--quiet", "-o", s(&out), "--gsd", "200"], d);
    assert!(report["warnings"].as_array().unwrap().iter().any(|w| w.as_str().unwrap().contains("aliases")), "{report}");
    // An output named as another format is still a GeoTIFF: said.
    let png = d.join("o.png");
    warned(&["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--quiet", "-o", s(&png)], &["GeoTIFF", ".png"]);
    // A camera for another scan: its principal point far off this one's
    // centre (the marks 60 px to the right).
    let text = std::fs::read_to_string(&camera).unwrap();
    let (head, tail) = text.split_once("fiducials_px = [").unwrap();
    let (marks, rest) = tail.split_once("]]").unwrap();
    let moved: Vec<String> = marks
        .split("], [")
        .map(|p| {
            let v: Vec<f64> = p.trim_matches(|c| c == '[' || c == ']').split(',').map(|x| x.trim().parse().unwrap()).collect();
            format!("[{}, {}]", v[0] + 60.0, v[1])
        })
        .collect();
    let other = d.join("other.toml");
    std::fs::write(&other, format!("{head}fiducials_px = [{}]{rest}", moved.join(", "))).unwrap();
    std::fs::remove_file(&out).unwrap();
    warned(&["rectify", "--image", s(&scan), "--camera", s(&other), "--dem", s(&dem), "--quiet", "-o", s(&out)], &["principal point", "this image's camera"]);
    // An RPC with SRTM's .hgt (heights above EGM96) and no --geoid; and
    // an image placed beyond the scene the RPC was fitted over.
    let v = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/ventoux");
    let hgt = d.join("N44E005.hgt");
    std::fs::write(&hgt, 1000i16.to_be_bytes().repeat(1201 * 1201)).unwrap();
    let (image, geom) = (v.join("left_image.tif"), v.join("left_image.geom"));
    let rpc = ["rectify", "--image", s(&image), "--rpc", s(&geom), "--dem", s(&hgt), "--quiet"];
    let rpc_out = d.join("rpc.tif");
    warned(&[&rpc[..], &["--rpc-offset", "5000,5000", "-o", s(&rpc_out)]].concat(), &["EGM96", "--geoid"]);
    std::fs::remove_file(&rpc_out).unwrap();
    warned(&[&rpc[..], &["--rpc-offset", "50000,50000", "-o", s(&rpc_out)]].concat(), &["extrapolated"]);
}

/// A run whose peak passes its `--memory` says so, even when quiet, with
/// the figure a job limit needs (a Slurm `--mem` set from `--memory` would
/// have killed it); within the budget it says nothing of the kind. 16M,
/// the least `--memory` taken, is less than the program itself holds
/// with a drone frame over buildings in hand (about 21 MiB).
#[test]
fn a_peak_past_the_memory_budget_is_said() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = drone_scene(d, (1200, 900), 12_000.0);
    let (out, json) = (d.join("o.tif"), d.join("o.json"));
    let args = |memory: &'static str| {
        let mut a =
            vec!["rectify", "--image", s(&scene.scan), "--camera", s(&scene.camera), "--dem", s(&scene.dem), "--quiet", "-o", s(&out), "--json", s(&json)];
        a.extend(["--memory", memory]);
        a
    };
    let r = run(&args("16M"));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains("warning: the peak memory") && err.contains("passed --memory 16M"), "{err}");
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let peak = report["peak_rss_mib"].as_f64().unwrap();
    assert!(peak > 16.0, "{peak}");
    assert!(report["warnings"].as_array().unwrap().iter().any(|w| w.as_str().unwrap().contains("passed --memory 16M")), "{report}");
    std::fs::remove_file(&out).unwrap();
    let r = run(&args("256M"));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success() && !err.contains("peak memory"), "{err}");
}

/// A missing input is named with its flag in words (no "os error"); DEM
/// tiles listed on the command line are told how several tiles are given.
#[test]
fn a_missing_input_is_named_in_words_and_listed_tiles_are_told_the_way() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = fixture(d);
    let out = d.join("o.tif");
    let tiles = format!("{},{}", dem.display(), dem.display());
    for (dem, words) in
        [(tiles.as_str(), &["--dem", "no such file or folder", "a GDAL VRT of them"][..]), ("nowhere.tif", &["--dem nowhere.tif: no such file or folder"][..])]
    {
        let r = run(&["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", dem, "--quiet", "-o", s(&out)]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.code() == Some(1) && err.trim_end().lines().count() == 1 && !err.contains("os error"), "{err}");
        assert!(words.iter().all(|w| err.contains(w)), "{err}");
        assert!(!out.exists());
    }
    // A camera file missing from a manifest's job: the same words.
    std::fs::write(d.join("m.toml"), format!("[[job]]\nimage = \"{}\"\ncamera = \"nope.toml\"\ndem = \"{}\"\n", scan.display(), dem.display())).unwrap();
    let r = run(&["batch", s(&d.join("m.toml")), "--quiet"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("nope.toml: no such file or folder") && !err.contains("os error"), "{err}");
    // A mosaic's and an assembly's inputs, named with their options; a
    // piece found missing only when opened (a link to nothing): its cause
    // said once, in words.
    std::os::unix::fs::symlink(d.join("gone.tif"), d.join("link.tif")).unwrap();
    for (args, said) in [
        (vec!["mosaic", s(&d.join("m.toml")), "-o", s(&out), "--seamlines", "nope.geojson"], "--seamlines nope.geojson: no such file or folder"),
        (vec!["mosaic", "nope-manifest.toml", "-o", s(&out)], "manifest nope-manifest.toml: no such file or folder"),
        (vec!["assemble", "-o", s(&out), "nope-piece.tif"], "piece nope-piece.tif: no such file or folder"),
        (vec!["assemble", "-o", s(&out), s(&d.join("link.tif"))], "link.tif: no such file or folder"),
    ] {
        let r = run(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(
            r.status.code() == Some(1) && err.trim_end().lines().count() == 1 && err.contains(said) && !err.contains("os error") && !err.contains("No such"),
            "{err}"
        );
        assert!(!out.exists());
    }
}

/// A focal length in pixels written where millimetres are meant (as other
/// tools give it) makes a lens that sees a degree or two from an aircraft:
/// warned of, even with `--quiet`, naming the camera file; the real one
/// is not.
#[test]
fn a_focal_length_in_the_wrong_unit_is_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = fixture(d);
    let text = std::fs::read_to_string(&camera).unwrap();
    std::fs::write(d.join("px.toml"), text.replace("focal_length_mm = 152.0", "focal_length_mm = 12000.0")).unwrap();
    for (cam, warned) in [(camera.clone(), false), (d.join("px.toml"), true)] {
        let out = d.join("o.tif");
        let r = run(&["rectify", "--image", s(&scan), "--camera", s(&cam), "--dem", s(&dem), "--quiet", "-o", s(&out)]);
        let err = String::from_utf8_lossy(&r.stderr);
        let said = err.lines().any(|l| l.contains("warning") && l.contains(s(&cam)) && l.contains("focal_length_mm") && l.contains("in pixels"));
        assert_eq!(said, warned, "{}: {err}", cam.display());
        let _ = std::fs::remove_file(&out);
    }
}

/// A camera file that is empty, or that calibrates too few marks, is
/// refused naming that file (not the scan), in one line.
#[test]
fn an_empty_camera_file_and_too_few_marks_name_the_camera_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = fixture(d);
    std::fs::write(d.join("empty.yaml"), "").unwrap();
    let text = std::fs::read_to_string(&camera).unwrap();
    let two: String = text
        .lines()
        .filter(|l| !l.starts_with("fiducials_px"))
        .map(|l| if l.starts_with("fiducials_mm") { "fiducials_mm = [[-117.5, -117.5], [117.5, 117.5]]" } else { l })
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(d.join("two.toml"), two).unwrap();
    let out = d.join("o.tif");
    for (cam, said) in [("empty.yaml", "empty.yaml: the file is empty"), ("two.toml", "two.toml: interior.fiducials_mm: 2 calibrated fiducial marks")] {
        let r = run(&["rectify", "--image", s(&scan), "--camera", s(&d.join(cam)), "--dem", s(&dem), "--quiet", "-o", s(&out)]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.code() == Some(1) && err.contains(said) && err.trim_end().lines().count() == 1, "{cam}: {err}");
        assert!(!out.exists());
    }
}
