//! Hostile and absurd inputs (a class each): recursion that would
//! overflow the stack, files outside the inputs that a message could echo,
//! points given twice that would fit a wrong camera to 0 px. Each is
//! refused in one line naming the input, with no crash and nothing left
//! at the output path.

mod common;
use common::*;
use std::path::{Path, PathBuf};

/// The mini scene copied into `dir`: scan, camera, DEM, checkpoints.
fn mini(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini");
    for f in ["scan.tif", "camera.toml", "dem.tif", "checkpoints.csv"] {
        std::fs::copy(root.join(f), dir.join(f)).unwrap();
    }
    (dir.join("scan.tif"), dir.join("camera.toml"), dir.join("dem.tif"))
}

/// Runs `rectify` on the mini scene with `extra`; it must fail (exit 1 or
/// 2, not a signal's abort) in one line holding every one of `words` and
/// none of `never`, leaving no output.
fn refused(dir: &Path, extra: &[&str], words: &[&str], never: &[&str]) -> String {
    let (scan, camera, dem) = (dir.join("scan.tif"), dir.join("camera.toml"), dir.join("dem.tif"));
    let out = dir.join("out.tif");
    let mut args = vec!["rectify", "--image", s(&scan), "--quiet", "-o", s(&out)];
    if !extra.contains(&"--camera") {
        args.extend(["--camera", s(&camera)]);
    }
    if !extra.contains(&"--dem") {
        args.extend(["--dem", s(&dem)]);
    }
    args.extend_from_slice(extra);
    let child = std::process::Command::new(bin()).args(&args).stdout(std::process::Stdio::piped()).stderr(std::process::Stdio::piped()).spawn().unwrap();
    let r = wait_deadline(child, 60);
    let err = String::from_utf8_lossy(&r.stderr).into_owned();
    assert!(matches!(r.status.code(), Some(1 | 2)), "{extra:?}: exit {:?}: {err}", r.status);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    for w in words {
        assert!(err.contains(w), "{extra:?}: '{w}' not in: {err}");
    }
    for n in never {
        assert!(!err.contains(n), "{extra:?}: '{n}' echoed in: {err}");
    }
    assert!(!out.exists() && files_containing(dir, "out.tif").is_empty(), "{extra:?} left an output");
    err
}

/// A file outside the inputs, whose lines no message may show.
fn secret(dir: &Path) -> PathBuf {
    let p = dir.join("secret.txt");
    std::fs::write(&p, "hunter2:x:0:0:the secret line:/root:/bin/sh\nsecond:x:1:1\n").unwrap();
    p
}

#[test]
fn recursion_in_wkt_and_dem_mosaics_is_refused_not_a_stack_overflow() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    mini(d);
    // WKT 80,000 brackets deep, well under the CRS file's size limit.
    let deep = d.join("deep.prj");
    std::fs::write(&deep, format!("GEOGCS[{}1{}", "A[".repeat(80_000), "]".repeat(80_001))).unwrap();
    refused(d, &["--crs", s(&deep)], &["deep.prj", "nested more than"], &[]);
    // A VRT whose source is itself, directly and through another.
    let vrt = |name: &str, source: &str| {
        let text = format!(
            "<VRTDataset rasterXSize=\"10\" rasterYSize=\"10\"><GeoTransform>0,1,0,10,0,-1</GeoTransform><VRTRasterBand dataType=\"Float32\" band=\"1\"><SimpleSource><SourceFilename relativeToVRT=\"1\">{source}</SourceFilename><SourceBand>1</SourceBand></SimpleSource></VRTRasterBand></VRTDataset>"
        );
        std::fs::write(d.join(name), text).unwrap();
        d.join(name)
    };
    let own = vrt("own.vrt", "own.vrt");
    refused(d, &["--dem", s(&own)], &["own.vrt", "names itself"], &[]);
    vrt("a.vrt", "b.vrt");
    let b = vrt("b.vrt", "a.vrt");
    refused(d, &["--dem", s(&b)], &["a.vrt", "b.vrt", "names itself"], &[]);
    // A list of tiles naming itself.
    std::fs::write(d.join("tiles.txt"), "tiles.txt\n").unwrap();
    refused(d, &["--dem", s(&d.join("tiles.txt"))], &["tiles.txt", "names itself"], &[]);
}

#[test]
fn yaml_nested_past_any_camera_file_is_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    mini(d);
    let cam = d.join("cam.yaml");
    std::fs::write(&cam, "[".repeat(300_000)).unwrap();
    // Named as YAML, told as YAML (not as a TOML error).
    refused(d, &["--camera", s(&cam)], &["cam.yaml", "as YAML", "nested more than"], &["as TOML"]);
    std::fs::write(&cam, "cam1:\n  type: pinhole\n  im_size: [100, 100\n").unwrap();
    refused(d, &["--camera", s(&cam)], &["cam.yaml", "as YAML"], &["as TOML"]);
    // A valid simple-ortho config with 3·10⁶ numbers among its settings:
    // parsed whole it peaked at 610 MiB; refused by its count first.
    let numbers = vec!["1"; 3_000_000].join(",");
    let config = format!("camera:\n  type: pinhole\n  im_size: [100, 100]\n  focal_len: 0.6\n  sensor_size: [1.0, 1.0]\northo:\n  junk: [{numbers}]\n");
    std::fs::write(&cam, config).unwrap();
    refused(d, &["--camera", s(&cam)], &["cam.yaml", "as YAML", "3000008 items"], &["as TOML"]);
    // One camera and 20,000 aliases of it: each a copy in the tree.
    let aliases: String = (0..20_000).map(|i| format!("c{i}: *x\n")).collect();
    std::fs::write(&cam, format!("x: &x {{type: pinhole, im_size: [640, 480], focal_len: 0.8}}\n{aliases}")).unwrap();
    refused(d, &["--camera", s(&cam)], &["cam.yaml", "as YAML", "more than 1000 aliases"], &["as TOML"]);
}

#[test]
fn no_message_shows_the_lines_of_a_file_that_is_not_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    mini(d);
    let secret = secret(d);
    // A .prj that is a link to it.
    std::os::unix::fs::symlink(&secret, d.join("link.prj")).unwrap();
    refused(d, &["--crs", s(&d.join("link.prj"))], &["link.prj", "not a CRS"], &["hunter2", "secret line"]);
    // A DEM tile list naming it: read as a list itself, never quoted.
    std::fs::write(d.join("tiles.txt"), format!("{}\n", secret.display())).unwrap();
    refused(d, &["--dem", s(&d.join("tiles.txt"))], &["secret.txt"], &["hunter2", "secret line"]);
    // A VRT whose source it is.
    let vrt = format!(
        "<VRTDataset rasterXSize=\"10\" rasterYSize=\"10\"><GeoTransform>0,1,0,10,0,-1</GeoTransform><VRTRasterBand dataType=\"Float32\" band=\"1\"><SimpleSource><SourceFilename relativeToVRT=\"0\">{}</SourceFilename><SourceBand>1</SourceBand></SimpleSource></VRTRasterBand></VRTDataset>",
        secret.display()
    );
    std::fs::write(d.join("s.vrt"), vrt).unwrap();
    refused(d, &["--dem", s(&d.join("s.vrt"))], &["s.vrt"], &["hunter2", "secret line"]);
    // As the camera file.
    refused(d, &["--camera", s(&secret)], &["secret.txt"], &["hunter2", "secret line"]);
}

/// A VRT that opens with an XML declaration and a comment, as editors
/// leave them, is read as a VRT (it was read as a list of tiles).
#[test]
fn a_vrt_with_an_xml_declaration_is_a_vrt() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = mini(d);
    let g = gcm_ortho::dem::GridDem::read(&dem).unwrap();
    let t = g.transform;
    let vrt = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!-- edited by hand -->\n<VRTDataset rasterXSize=\"{w}\" rasterYSize=\"{h}\">\n<SRS>EPSG:32631</SRS><GeoTransform>{},{},0,{},0,{}</GeoTransform><VRTRasterBand dataType=\"Float32\" band=\"1\"><SimpleSource><SourceFilename relativeToVRT=\"1\">dem.tif</SourceFilename><SourceBand>1</SourceBand><SrcRect xOff=\"0\" yOff=\"0\" xSize=\"{w}\" ySize=\"{h}\"/><DstRect xOff=\"0\" yOff=\"0\" xSize=\"{w}\" ySize=\"{h}\"/></SimpleSource></VRTRasterBand></VRTDataset>\n",
        t[0],
        t[1],
        t[3],
        t[5],
        w = g.width,
        h = g.height
    );
    std::fs::write(d.join("dem.vrt"), vrt).unwrap();
    let (a, b) = (d.join("a.tif"), d.join("b.tif"));
    for (dem, out) in [(&dem, &a), (&d.join("dem.vrt"), &b)] {
        let r = run(&["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(dem), "--quiet", "-o", s(out)]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    }
    assert_eq!(whole_image(&a).0, whole_image(&b).0, "the VRT's heights are the file's");
}

/// A VRT of `copies` × the mini DEM's 8×8-sample windows, each a source
/// of its own (the same file): the DEM's heights, in many tiles.
fn dem_in_windows(d: &Path, dem: &Path, copies: usize) -> PathBuf {
    let g = gcm_ortho::dem::GridDem::read(dem).unwrap();
    let t = g.transform;
    let mut sources = String::new();
    for _ in 0..copies {
        for y in (0..g.height).step_by(8) {
            for x in (0..g.width).step_by(8) {
                let (w, h) = (8.min(g.width - x), 8.min(g.height - y));
                sources.push_str(&format!(
                    "<SimpleSource><SourceFilename relativeToVRT=\"1\">dem.tif</SourceFilename><SourceBand>1</SourceBand><SrcRect xOff=\"{x}\" yOff=\"{y}\" xSize=\"{w}\" ySize=\"{h}\"/><DstRect xOff=\"{x}\" yOff=\"{y}\" xSize=\"{w}\" ySize=\"{h}\"/></SimpleSource>\n"
                ));
            }
        }
    }
    let vrt = format!(
        "<VRTDataset rasterXSize=\"{}\" rasterYSize=\"{}\"><SRS>EPSG:32631</SRS><GeoTransform>{},{},0,{},0,{}</GeoTransform><VRTRasterBand dataType=\"Float32\" band=\"1\">\n{sources}</VRTRasterBand></VRTDataset>\n",
        g.width, g.height, t[0], t[1], t[3], t[5]
    );
    let path = d.join(format!("windows{copies}.vrt"));
    std::fs::write(&path, vrt).unwrap();
    path
}

/// A DEM of more tiles than a process may hold files open (each read a
/// chunk at a time) is read through a few handles at once, its heights
/// the file's; one of more tiles than the budget holds is refused by
/// name before a tile is opened.
#[test]
fn a_dem_of_many_tiles_holds_few_files_open_and_one_past_the_budget_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = mini(d);
    // 2 × 144 sources, each of which held a handle; 256 handles at most.
    let many = dem_in_windows(d, &dem, 2);
    let (a, b) = (d.join("a.tif"), d.join("b.tif"));
    for (dem, out) in [(&dem, &a), (&many, &b)] {
        let cmd = format!(
            "ulimit -n 256 && exec '{}' rectify --image '{}' --camera '{}' --dem '{}' --memory 32M --quiet -o '{}'",
            s(&bin()),
            s(&scan),
            s(&camera),
            s(dem),
            s(out)
        );
        let r = std::process::Command::new("bash").arg("-c").arg(cmd).output().unwrap();
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    }
    assert_eq!(whole_image(&a).0, whole_image(&b).0, "the tiles' heights are the file's");
    // 140 × 144 sources: under 16M refused before a tile is read; under
    // 512M once the tiles opened hold twice the DEM's share (each keeps two
    // chunks whatever its share).
    let past = dem_in_windows(d, &dem, 140);
    let e = refused(d, &["--dem", s(&past), "--memory", "16M"], &["windows140.vrt", "20160 tiles", "--memory"], &[]);
    assert!(e.contains("before a height is read"), "{e}");
    let e = refused(d, &["--dem", s(&past), "--memory", "512M"], &["windows140.vrt", "of its 20160 tiles hold", "--memory"], &[]);
    assert!(e.contains("past twice the DEM's share"), "{e}");
}

/// One point under several ids would weigh the fit as several: refused,
/// naming them; points on one line cannot fix a pose: refused as such.
#[test]
fn gcps_given_twice_or_on_one_line_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    mini(d);
    let cp = std::fs::read_to_string(d.join("checkpoints.csv")).unwrap();
    let rows: Vec<Vec<String>> = cp.lines().skip(1).map(|l| l.split(',').map(str::to_string).collect()).collect();
    assert!(rows.len() >= 4);
    let as_gcps = |rows: &[Vec<String>]| {
        let mut t = "id,x,y,z,col,row\n".to_string();
        for r in rows {
            t.push_str(&format!("{},{},{},{},{},{}\n", r[0], r[1], r[2], r[3], r[4], r[5]));
        }
        t
    };
    std::fs::write(d.join("gcps.prj"), "EPSG:32631").unwrap();
    // The first point again under four other ids, with the others.
    let mut twice = rows.clone();
    for id in ["a", "b", "c", "d"] {
        let mut r = rows[0].clone();
        r[0] = id.to_string();
        twice.push(r);
    }
    std::fs::write(d.join("gcps.csv"), as_gcps(&twice)).unwrap();
    let first = rows[0][0].clone();
    refused(d, &["--gcps", s(&d.join("gcps.csv"))], &["gcps.csv", "are one point", &format!("{first}, a, b, c, d")], &[]);
    // Three or more points on one ground line (the image positions are
    // those the camera would see; the line is what is wrong).
    let (x0, y0): (f64, f64) = (rows[0][1].parse().unwrap(), rows[0][2].parse().unwrap());
    let (x1, y1): (f64, f64) = (rows[1][1].parse().unwrap(), rows[1][2].parse().unwrap());
    let line: Vec<Vec<String>> = (0..4)
        .map(|k| {
            let f = k as f64 / 3.0;
            let mut r = rows[k].clone();
            r[1] = format!("{}", x0 + f * (x1 - x0));
            r[2] = format!("{}", y0 + f * (y1 - y0));
            r
        })
        .collect();
    std::fs::write(d.join("gcps.csv"), as_gcps(&line)).unwrap();
    refused(d, &["--gcps", s(&d.join("gcps.csv"))], &["on one line"], &["left the"]);
}

/// Absurd values in one input are blamed on that input and its field, not
/// on the DEM the run then fails to meet.
#[test]
fn absurd_values_are_blamed_on_their_input_not_on_the_dem() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (_, camera, _) = mini(d);
    refused(d, &["--crs", "+proj=tmerc +lon_0=1e300 +ellps=WGS84"], &["--crs", "+lon_0=1e300", "out of range"], &["dem.tif"]);
    refused(d, &["--crs", "+proj=tmerc +lon_0=3 +k=0 +ellps=WGS84"], &["--crs", "+k=0", "scale factor"], &["dem.tif"]);
    refused(d, &["--gsd", "1e9"], &["--gsd", "less than one pixel"], &["dem.tif"]);
    let text = std::fs::read_to_string(&camera).unwrap();
    let line = text.lines().find(|l| l.trim_start().starts_with("position")).expect("a position line").to_string();
    let nums: Vec<&str> = line.split(['[', ']']).nth(1).unwrap().split(',').map(str::trim).collect();
    for (name, position) in
        [("far.toml", format!("position = [1e308, {}, {}]", nums[1], nums[2])), ("high.toml", format!("position = [{}, {}, 1e300]", nums[0], nums[1]))]
    {
        std::fs::write(d.join(name), text.replace(&line, &position)).unwrap();
        refused(d, &["--camera", s(&d.join(name))], &[name, "exterior.position", "1e3"], &["dem.tif"]);
    }
    // A lens past any lens's lengths: blamed on its field, not on the
    // distortion or the format it would otherwise make absurd.
    for (name, from, to, field) in [
        ("focal.toml", "focal_length_mm = 152.0", "focal_length_mm = 1e300", "camera.focal_length_mm: 1e300 mm is no lens's"),
        ("pp.toml", "principal_point_mm = [0.004, -0.009]", "principal_point_mm = [1e300, 0.0]", "interior.principal_point_mm: 1e300 mm"),
        ("tiny.toml", "focal_length_mm = 152.0", "focal_length_mm = 1e-300", "camera.focal_length_mm: 1e-300 mm across"),
    ] {
        assert!(text.contains(from));
        std::fs::write(d.join(name), text.replace(from, to)).unwrap();
        refused(d, &["--camera", s(&d.join(name))], &[name, field], &["dem.tif", "distortion", "format"]);
    }
    // Heights scaled past any terrain: the DEM is named, not the camera.
    let scaled = d.join("scaled.tif");
    f32_raster(&scaled, (300, 300), (650_000.0, 4_891_500.0, 5.0, 32631), |_, _| 3.5e32);
    refused(d, &["--dem", s(&scaled)], &["scaled.tif", "3.5e32 m under the camera is past any terrain"], &["camera.toml"]);
}

/// A CRS file is an input wherever it is named (`--crs`, a camera file's
/// `crs`): no output is written over it (it was: `-o c.prj` made it a
/// TIFF, exit 0).
#[test]
fn no_output_is_written_over_a_crs_file_the_run_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = mini(d);
    let prj = d.join("c.prj");
    std::fs::write(&prj, "EPSG:32631\n").unwrap();
    let cam = d.join("cam.toml");
    std::fs::write(&cam, std::fs::read_to_string(&camera).unwrap().replace("crs = \"EPSG:32631\"", "crs = \"c.prj\"")).unwrap();
    let base = ["rectify", "--image", s(&scan), "--dem", s(&dem), "--quiet"];
    for extra in [
        vec!["--camera", s(&camera), "--crs", s(&prj), "-o", s(&prj)],
        vec!["--camera", s(&camera), "--crs", s(&prj), "-o", "o.tif", "--json", s(&prj)],
        vec!["--camera", s(&cam), "-o", s(&prj)],
    ] {
        let r = std::process::Command::new(bin()).current_dir(d).args(base).args(&extra).output().unwrap();
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains("c.prj") && err.contains("refusing to write over an input"), "{extra:?}: {err}");
        assert_eq!(std::fs::read_to_string(&prj).unwrap(), "EPSG:32631\n", "{extra:?}");
        assert!(files_containing(d, "gcm-partial").is_empty() && !d.join("o.tif").exists(), "{extra:?}");
    }
    // The same run to another name works.
    let r = std::process::Command::new(bin()).current_dir(d).args(base).args(["--camera", s(&cam), "-o", "o.tif"]).output().unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
}

/// A file given where points or an image go is read only as far as it
/// shows itself one: a password file's lines are never quoted (grid
/// quoted its first line, or its second with --columns; rectify the first
/// 16 bytes).
#[test]
fn a_text_file_given_as_points_or_image_is_never_quoted() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (_, camera, dem) = mini(d);
    let secret = secret(d);
    let out = d.join("o.tif");
    let runs: [Vec<&str>; 4] = [
        vec!["grid", s(&secret), "--gsd", "10", "--crs", "EPSG:32631", "-o", s(&out)],
        vec!["grid", s(&secret), "--gsd", "10", "--crs", "EPSG:32631", "--columns", "1,2,3", "-o", s(&out)],
        vec!["rectify", "--image", s(&secret), "--camera", s(&camera), "--dem", s(&dem), "-o", s(&out)],
        vec!["assemble", s(&secret), "-o", s(&out)],
    ];
    for args in runs {
        let r = std::process::Command::new(bin()).args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(matches!(r.status.code(), Some(1 | 2)), "{args:?}: {err}");
        assert!(err.contains("secret.txt"), "{args:?}: {err}");
        for never in ["hunter2", "secret line", "second:x"] {
            assert!(!err.contains(never), "{args:?} quoted the file: {err}");
        }
        assert!(!out.exists(), "{args:?}");
    }
}

/// `nan` and `inf` are no values for a number: each refused naming its
/// option (they became the default on their way to the run: `grid
/// --power=nan` ran as power 2, `rectify --height nan` blamed the DEM).
#[test]
fn nan_and_inf_are_refused_by_the_option_that_took_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, _) = mini(d);
    let out = d.join("o.tif");
    let runs: [(Vec<&str>, &str); 4] = [
        (vec!["grid", "p.csv", "--method", "idw", "--power=nan", "-o", s(&out)], "--power"),
        (vec!["grid", "p.csv", "--max-edge=-inf", "-o", s(&out)], "--max-edge"),
        (vec!["rectify", "--image", s(&scan), "--camera", s(&camera), "--height", "nan", "-o", s(&out)], "--height"),
        (vec!["dem", "--left", "l.tif", "--right", "r.tif", "--min-correlation", "inf", "-o", s(&out)], "--min-correlation"),
    ];
    for (args, flag) in runs {
        let r = std::process::Command::new(bin()).current_dir(d).args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(flag) && err.contains("not a finite number"), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(!out.exists());
    }
}

#[test]
fn synth_settings_past_any_scene_are_refused_by_name_and_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("mine")).unwrap();
    std::fs::write(d.join("mine/notes.txt"), "kept").unwrap();
    let runs: [(&[&str], &str); 6] = [
        (&["--points", "99999999999999999"], "--points"),
        (&["--size", "200x200", "--dem-posting", "1e-9"], "--dem-posting"),
        (&["--dust", "999999999"], "--dust"),
        (&["--size", "99999999x99999999"], "--size"),
        (&["--scale", "1e12"], "--scale"),
        // Low enough that the hills reach the camera: found once the relief is made.
        (&["--size", "256x256", "--relief", "hilly", "--scale", "200"], "--scale"),
    ];
    for (args, flag) in runs {
        for out in ["fresh/scene", "mine"] {
            let r = std::process::Command::new(bin()).current_dir(d).args(["synth", "--out", out]).args(args).output().unwrap();
            let err = String::from_utf8_lossy(&r.stderr);
            assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
            assert!(err.starts_with(&format!("gcm-ortho: error: {flag}:")), "{args:?}: {err}");
            assert!(!d.join("fresh").exists(), "{args:?}");
            let left: Vec<_> = std::fs::read_dir(d.join("mine")).unwrap().map(|e| e.unwrap().file_name()).collect();
            assert_eq!(left, ["notes.txt"], "{args:?}");
        }
    }
}

#[test]
fn a_fixed_length_array_given_longer_is_refused_not_cut() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (_, camera, _) = mini(d);
    let text = std::fs::read_to_string(&camera).unwrap();
    let cuts = [
        ("radial_mm = [0.0, 0.00000015, -0.000000002]", "radial_mm = [0.0, 0.00000015, -0.000000002, 1e-12]", "distortion.radial_mm: 4 entries where 3"),
        ("principal_point_mm = [0.004, -0.009]", "principal_point_mm = [0.004, -0.009, 0.0]", "interior.principal_point_mm: 3 entries where 2"),
        ("[[-117.5, -117.5], [117.5, 117.5],", "[[-117.5, -117.5], [117.5, 117.5, 3.0],", "interior.fiducials_mm[2]: 3 entries where 2"),
        ("position = [650534.0, 4890911.0, 1820.0]", "position = [650534.0, 4890911.0, 1820.0, 9.0]", "exterior.position: 4 entries where 3"),
    ];
    for (from, to, words) in cuts {
        assert!(text.contains(from), "{from}");
        std::fs::write(&camera, text.replace(from, to)).unwrap();
        refused(d, &[], &["camera.toml", words], &[]);
    }
}

#[test]
fn a_report_that_cannot_be_written_takes_the_runs_outputs_with_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    mini(d);
    let err = refused(d, &["--json", "/dev/full"], &["report", "/dev/full", "removed"], &[]);
    assert!(err.contains("no space"), "{err}");
    // Written where it can be, the same run leaves both.
    let r = std::process::Command::new(bin())
        .current_dir(d)
        .args(["rectify", "--image", "scan.tif", "--camera", "camera.toml", "--dem", "dem.tif", "-o", "out.tif", "--json", "r.json", "--quiet"])
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(d.join("out.tif").exists() && d.join("r.json").exists());
}

#[test]
fn a_pose_file_s_short_row_is_named_by_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    mini(d);
    let poses = d.join("poses.csv");
    std::fs::write(&poses, "filename,x,y,z,omega,phi,kappa\nother.tif,650534.0,4890911.0,1820.0,0.1,0.2,0\n\nscan.tif,650534.0,4890911.0,1820.0,0.1,0.2\n")
        .unwrap();
    refused(d, &["--exterior", s(&poses)], &["poses.csv", "line 4: 6 fields where the first line has 7"], &["line 1"]);
}

#[test]
fn a_geotransform_beside_a_dem_that_places_no_pixel_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    mini(d);
    // A DEM with no georeferencing of its own: GDAL's .aux.xml gives it.
    let plain = d.join("plain.tif");
    let spec = plain_spec((60, 60), 1, gcm_ortho::io::source::SampleType::F32, None);
    gcm_ortho::io::tiff_out::write_raster(&plain, &spec, |_, _, buf| buf.chunks_exact_mut(4).for_each(|v| v.copy_from_slice(&350f32.to_ne_bytes()))).unwrap();
    for (gt, said) in [("nan, 50, 0, 4893300, 0, -50", "GeoTransform: NaN is not a finite number"), ("648150, 0, 0, 4893300, 0, -50", "pixels of no area")] {
        std::fs::write(d.join("plain.tif.aux.xml"), format!("<PAMDataset><SRS>EPSG:32631</SRS><GeoTransform>{gt}</GeoTransform></PAMDataset>")).unwrap();
        refused(d, &["--dem", s(&plain)], &["plain.tif.aux.xml", said], &["camera.toml"]);
    }
}

/// A TIFF scan whose Orientation tag says its rows are shown turned (6)
/// or holds a value no standard defines (9) is refused by the tag, as a
/// JPEG's EXIF is: the camera model is of the rows as stored. 1 is read.
#[test]
fn a_tiff_scan_shown_turned_is_refused_by_its_orientation_tag() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, _, _) = mini(d);
    let (pixels, info) = whole_image(&scan);
    assert_eq!((info.width, info.height, info.bands), (200, 200, 1));
    let with_orientation = |o: u16| {
        let mut file = std::io::BufWriter::new(std::fs::File::create(&scan).unwrap());
        let mut tiff = tiff::encoder::TiffEncoder::new(&mut file).unwrap();
        let mut image = tiff.new_image::<tiff::encoder::colortype::Gray8>(200, 200).unwrap();
        image.encoder().write_tag(tiff::tags::Tag::Orientation, o).unwrap();
        image.write_data(&pixels).unwrap();
    };
    for o in [6u16, 9] {
        with_orientation(o);
        let err = refused(d, &[], &["scan.tif", &format!("TIFF Orientation tag is {o}")], &[]);
        assert!(err.contains(if o == 6 { "turned 90° clockwise" } else { "do not define" }), "{err}");
    }
    with_orientation(1);
    let out = d.join("upright.tif");
    let r = run(&["rectify", "--image", s(&scan), "--camera", s(&d.join("camera.toml")), "--dem", s(&d.join("dem.tif")), "--quiet", "-o", s(&out)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
}

/// A path that is not UTF-8 is refused naming the option it was given to
/// (it was "the arguments: path contains invalid UTF-8 characters").
#[test]
fn a_path_that_is_not_utf8_is_refused_by_its_option() {
    use std::os::unix::ffi::OsStrExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (scan, camera, dem) = mini(d);
    let odd = d.join(std::ffi::OsStr::from_bytes(b"scan\xff.tif"));
    std::fs::copy(&scan, &odd).unwrap();
    let out = d.join("out.tif");
    for (flag, image, output) in [("--image", &odd, &out), ("-o", &scan, &odd.with_file_name(std::ffi::OsStr::from_bytes(b"out\xff.tif")))] {
        let r = std::process::Command::new(bin())
            .args(["rectify", "--quiet", "--camera", s(&camera), "--dem", s(&dem), "--image"])
            .arg(image)
            .arg("-o")
            .arg(output)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{flag}: {err}");
        assert!(err.contains(&format!("{flag}: '")) && err.contains("is not UTF-8 text"), "{flag}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(!out.exists() && !output.exists());
    }
}
