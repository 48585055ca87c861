//! `batch`: failures isolated, reruns skip finished work, shards cover every
//! job exactly once, signals leave nothing half-written.

mod common;
use common::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// A block of `n` small scans copied from one scene (each its own file).
fn block(dir: &Path, n: usize) -> (PathBuf, Vec<PathBuf>) {
    let sc = scene(&dir.join("scene"), 300, |o| o.dem_posting = 20.0);
    let scans: Vec<PathBuf> = (0..n)
        .map(|i| {
            let p = dir.join(format!("scans/s{i:02}.tif"));
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::copy(&sc.scan, &p).unwrap();
            p
        })
        .collect();
    (dir.join("scene"), scans)
}

fn jobs_toml(n: usize) -> String {
    (0..n).map(|i| format!("[[job]]\nimage = \"scans/s{i:02}.tif\"\ncamera = \"scene/camera.toml\"\n\n")).collect()
}

fn batch(dir: &Path, args: &[&str]) -> std::process::Output {
    let m = dir.join("manifest.toml");
    let mut a = vec!["batch", s(&m), "--quiet"];
    a.extend_from_slice(args);
    run(&a)
}

fn lines(report: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(report).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

#[test]
fn failures_are_isolated_and_reported() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    block(d, 5);
    std::fs::write(d.join("bad.toml"), "crs = \"EPSG:32631\"\n[camera]\nmodel = \"frame\"\n").unwrap();
    let manifest = format!(
        "[defaults]\ndem = \"scene/dem.tif\"\noutput_dir = \"ortho\"\ncompress = \"deflate\"\n\n{}\
         [[job]]\nimage = \"scans/s03.tif\"\ncamera = \"bad.toml\"\n\n\
         [[job]]\nimage = \"scans/s04.tif\"\ncamera = \"scene/camera.toml\"\ndem = \"missing/dem.tif\"\n",
        jobs_toml(3)
    );
    std::fs::write(d.join("manifest.toml"), manifest).unwrap();
    let r = batch(d, &["--report", s(&d.join("report.jsonl")), "--jobs", "2"]);
    assert_eq!(r.status.code(), Some(3), "{}", String::from_utf8_lossy(&r.stderr));
    for i in 0..3 {
        let out = d.join(format!("ortho/s{i:02}.tif"));
        assert!(out.is_file(), "{}", out.display());
        gcm_ortho::io::source::SourceImage::open(&out, 1 << 20).unwrap();
    }
    let rep = lines(&d.join("report.jsonl"));
    assert_eq!(rep.len(), 5);
    let failed: Vec<_> = rep.iter().filter(|l| l["status"] == "failed").collect();
    assert_eq!(failed.len(), 2);
    let errs: Vec<String> = failed.iter().map(|l| l["error"].as_str().unwrap().to_string()).collect();
    assert!(errs.iter().any(|e| e.contains("bad.toml") && e.contains("focal_length_mm")), "{errs:?}");
    assert!(errs.iter().any(|e| e.contains("missing/dem.tif") && e.contains("line")), "{errs:?}");
    assert!(!d.join("ortho/s03.tif").exists() && !d.join("ortho/s04.tif").exists());
}

#[test]
fn reruns_skip_finished_jobs_and_redo_changed_ones() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (_, scans) = block(d, 3);
    std::fs::write(d.join("manifest.toml"), format!("[defaults]\ndem = \"scene/dem.tif\"\noutput_dir = \"ortho\"\n\n{}", jobs_toml(3))).unwrap();
    let rep = d.join("r.jsonl");
    assert!(batch(d, &["--report", s(&rep)]).status.success());
    assert!(lines(&rep).iter().all(|l| l["status"] == "done"));
    assert!(batch(d, &["--report", s(&rep)]).status.success());
    assert!(lines(&rep).iter().all(|l| l["status"] == "skipped"));
    // Touch one input: only that job reruns.
    std::thread::sleep(std::time::Duration::from_millis(20));
    let f = std::fs::OpenOptions::new().append(true).open(&scans[1]).unwrap();
    f.set_modified(std::time::SystemTime::now()).unwrap();
    drop(f);
    assert!(batch(d, &["--report", s(&rep)]).status.success());
    let st: Vec<String> = lines(&rep).iter().map(|l| l["status"].as_str().unwrap().to_string()).collect();
    assert_eq!(st, ["skipped", "done", "skipped"]);
    // A changed parameter redoes everything; --force too.
    assert!(batch(d, &["--report", s(&rep), "--force"]).status.success());
    assert!(lines(&rep).iter().all(|l| l["status"] == "done"));
}

#[test]
fn a_job_another_run_is_making_is_left_to_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    block(d, 3);
    std::fs::write(d.join("manifest.toml"), format!("[defaults]\ndem = \"scene/dem.tif\"\noutput_dir = \"ortho\"\n\n{}", jobs_toml(3))).unwrap();
    // Another run making the second job holds its lock.
    std::fs::create_dir_all(d.join("ortho")).unwrap();
    let held = std::fs::File::create(d.join("ortho/s01.tif.lock")).unwrap();
    held.lock().unwrap();
    let rep = d.join("r.jsonl");
    let r = batch(d, &["--report", s(&rep)]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    let st: Vec<String> = lines(&rep).iter().map(|l| l["status"].as_str().unwrap().to_string()).collect();
    assert_eq!(st, ["done", "busy", "done"]);
    // Said even when quiet, naming the lock; the job's output left alone.
    assert!(err.contains("s01") && err.contains("another run is making it") && err.contains("s01.tif.lock"), "{err}");
    assert!(!d.join("ortho/s01.tif").exists() && d.join("ortho/s00.tif").is_file());
    // The other run's own lock stays; the finished jobs' are gone.
    assert!(d.join("ortho/s01.tif.lock").exists() && !d.join("ortho/s00.tif.lock").exists());
    // Once it lets go (without making the job), a rerun makes it.
    drop(held);
    assert!(batch(d, &["--report", s(&rep)]).status.success());
    let st: Vec<String> = lines(&rep).iter().map(|l| l["status"].as_str().unwrap().to_string()).collect();
    assert_eq!(st, ["skipped", "done", "skipped"]);
    assert!(!d.join("ortho/s01.tif.lock").exists());
}

#[test]
fn three_shards_run_every_job_exactly_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    block(d, 10);
    std::fs::write(d.join("manifest.toml"), format!("[defaults]\nheight = 350.0\noutput_dir = \"ortho\"\ngsd = 20.0\n\n{}", jobs_toml(10))).unwrap();
    let mut seen = Vec::new();
    for (i, how) in [(1, "flag"), (2, "slurm"), (3, "k8s")] {
        let rep = d.join(format!("r{i}.jsonl"));
        let mut cmd = Command::new(bin());
        cmd.args(["batch", s(&d.join("manifest.toml")), "--quiet", "--report", s(&rep)]);
        match how {
            "flag" => {
                cmd.args(["--shard", &format!("{i}/3")]);
            }
            "slurm" => {
                cmd.env("SLURM_ARRAY_TASK_ID", (i - 1).to_string()).env("SLURM_ARRAY_TASK_COUNT", "3");
            }
            _ => {
                cmd.env("JOB_COMPLETION_INDEX", (i - 1).to_string()).args(["--shard-count", "3"]);
            }
        }
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        seen.extend(lines(&rep).iter().map(|l| l["job"].as_str().unwrap().to_string()));
    }
    seen.sort();
    let want: Vec<String> = (0..10).map(|i| format!("s{i:02}")).collect();
    assert_eq!(seen, want);
}

#[test]
fn block_of_exterior_orientations() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    block(d, 2);
    // The interior file: the scene camera without [exterior]; the CSV gives
    // the same exterior orientation in ω-φ-κ.
    let cam = gcm_ortho::camera::file::CameraFile::read(&d.join("scene/camera.toml")).unwrap();
    let ext = cam.exterior.clone().unwrap();
    let r = ext.convention.matrix(ext.angles_deg.map(f64::to_radians));
    let opk = gcm_ortho::camera::rotation::AngleConvention::OmegaPhiKappa.angles(&r).map(f64::to_degrees);
    let mut interior = cam.clone();
    interior.exterior = None;
    std::fs::write(d.join("rc30.toml"), interior.to_toml()).unwrap();
    let p = ext.position;
    let mut csv = String::from("name,X,Y,Z,omega,phi,kappa\n");
    for i in 0..2 {
        csv += &format!("s{i:02},{},{},{},{},{},{}\n", p[0], p[1], p[2], opk[0], opk[1], opk[2]);
    }
    std::fs::write(d.join("eo.csv"), csv).unwrap();
    std::fs::write(
        d.join("manifest.toml"),
        "[defaults]\ndem = \"scene/dem.tif\"\noutput_dir = \"ortho\"\n\n[block]\ninterior = \"rc30.toml\"\nexterior_csv = \"eo.csv\"\nimages = \"scans/{name}.tif\"\n",
    )
    .unwrap();
    let o = batch(d, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The block camera equals the camera file: the same orthophoto as a plain rectify.
    let single = d.join("single.tif");
    let sc = d.join("scene");
    assert!(run(&[
        "rectify",
        "--image",
        s(&d.join("scans/s00.tif")),
        "--camera",
        s(&sc.join("camera.toml")),
        "--dem",
        s(&sc.join("dem.tif")),
        "-o",
        s(&single),
        "--quiet"
    ])
    .status
    .success());
    let a = gcm_ortho::study::compare::read_grey(&single, 0.0).unwrap();
    let b = gcm_ortho::study::compare::read_grey(&d.join("ortho/s00.tif"), 0.0).unwrap();
    let diff = a.v.iter().zip(&b.v).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
    assert!(diff <= 1.0, "{diff}");

    // The CRS from a .prj beside the CSV (ESRI WKT of UTM 31N), the
    // interior file without crs: the same orthophotos.
    let utm_esri = r#"PROJCS["WGS_1984_UTM_Zone_31N",GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["False_Easting",500000.0],PARAMETER["False_Northing",0.0],PARAMETER["Central_Meridian",3.0],PARAMETER["Scale_Factor",0.9996],PARAMETER["Latitude_Of_Origin",0.0],UNIT["Meter",1.0]]"#;
    std::fs::write(d.join("eo.prj"), utm_esri).unwrap();
    let mut no_crs = interior.clone();
    no_crs.crs = String::new();
    std::fs::write(d.join("rc30.toml"), no_crs.to_toml().replace("crs = \"\"\n", "")).unwrap();
    let manifest = std::fs::read_to_string(d.join("manifest.toml")).unwrap().replace("output_dir = \"ortho\"", "output_dir = \"ortho-prj\"");
    std::fs::write(d.join("manifest.toml"), &manifest).unwrap();
    let o = batch(d, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let c = gcm_ortho::study::compare::read_grey(&d.join("ortho-prj/s00.tif"), 0.0).unwrap();
    let diff = b.v.iter().zip(&c.v).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
    assert!(diff <= 1.0, "the .prj's orthophoto differs by {diff}");
    // A .prj that disagrees with the interior file's crs is refused.
    let mut other = interior.clone();
    other.crs = "EPSG:32632".into();
    std::fs::write(d.join("rc30.toml"), other.to_toml()).unwrap();
    std::fs::write(d.join("manifest.toml"), manifest.replace("ortho-prj", "ortho-bad")).unwrap();
    let o = batch(d, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("eo.prj") && err.contains("EPSG:32632"), "{err}");

    // Names with the image's extension (as exports write them) name the
    // same images; --dry-run says which jobs would fail, and fails.
    std::fs::remove_file(d.join("eo.prj")).unwrap();
    std::fs::write(d.join("rc30.toml"), interior.to_toml()).unwrap();
    std::fs::write(d.join("eo.csv"), std::fs::read_to_string(d.join("eo.csv")).unwrap().replace("s00,", "s00.tif,").replace("s01,", "s01.TIF,")).unwrap();
    std::fs::write(d.join("manifest.toml"), manifest.replace("ortho-prj", "ortho-ext")).unwrap();
    let o = batch(d, &["--dry-run"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && out.contains("scans/s00.tif ->") && !out.contains(".tif.tif"), "{out}{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(d.join("eo.csv")).unwrap();
    std::fs::write(d.join("eo.csv"), format!("{csv}{}", csv.lines().nth(1).unwrap().replace("s00.tif", "s99"))).unwrap();
    let o = batch(d, &["--dry-run"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("s99") && err.contains("does not exist"), "{err}");
    // An image cut short, or not an image at all: said by the dry run too.
    std::fs::write(d.join("eo.csv"), &csv).unwrap();
    let whole = std::fs::read(d.join("scans/s01.tif")).unwrap();
    for (bytes, says) in [(&whole[..whole.len() / 3], "truncated"), (&b"not a TIFF at all, nor any image"[..], "not an image")] {
        std::fs::write(d.join("scans/s01.tif"), bytes).unwrap();
        let o = batch(d, &["--dry-run"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(3), "{err}");
        assert!(err.contains("s01") && err.contains(says) && err.trim().lines().count() == 1, "{err}");
    }
    std::fs::write(d.join("scans/s01.tif"), whole).unwrap();
}

/// Two jobs that would write one file (an output, or one's record beside
/// it) are refused before any work also where their folder is still to
/// be made, as a first run's is.
#[test]
fn jobs_writing_one_file_are_refused_before_their_folder_exists() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    block(d, 2);
    for (a, b) in [("new/x.tif", "new/x.tif"), ("new/y.tif", "new/y.tif.done"), ("new/s00.tif", "new/deeper/../s00.tif")] {
        let jobs: String = [a, b]
            .iter()
            .enumerate()
            .map(|(i, out)| format!("[[job]]\nimage = \"scans/s{i:02}.tif\"\ncamera = \"scene/camera.toml\"\noutput = \"{out}\"\n\n"))
            .collect();
        std::fs::write(d.join("manifest.toml"), format!("[defaults]\ndem = \"scene/dem.tif\"\n\n{jobs}")).unwrap();
        for args in [&["--dry-run"][..], &[]] {
            let o = batch(d, args);
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(2), "{a} {b} {args:?}: {err}");
            assert!(err.contains("are one file"), "{err}");
            assert!(!d.join("new").exists(), "{a} {b}: work was done");
        }
    }
}

#[test]
fn a_broken_manifest_lists_every_problem_with_lines() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("manifest.toml"), "[defaults]\ndme = \"x.tif\"\n").unwrap();
    let o = batch(d, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1));
    assert!(err.contains("manifest.toml") && err.contains("line 2") && err.contains("dme"), "{err}");
    // A slip in a job: said at its own line (not its job's first), with
    // the keys a job takes, the nearest first; a job's other problems at
    // its image's line.
    let job = |image: &str, camera_key: &str| format!("[[job]]\nimage = \"{image}\"\n{camera_key} = \"c.toml\"\n\n");
    std::fs::write(d.join("manifest.toml"), format!("{}{}", job("a.tif", "camera"), job("b.tif", "camrea"))).unwrap();
    let err = String::from_utf8_lossy(&batch(d, &[]).stderr).to_string();
    assert!(err.contains("line 7: unknown field `camrea` (did you mean `camera`?), expected one of `image`, `camera`"), "{err}");
    // A slip in the key a job must have: the slip named at its line, not
    // only the key found missing.
    std::fs::write(d.join("manifest.toml"), format!("{}[[job]]\nimgae = \"b.tif\"\ncamera = \"c.toml\"\n", job("a.tif", "camera"))).unwrap();
    let err = String::from_utf8_lossy(&batch(d, &[]).stderr).to_string();
    assert!(err.contains("line 6: missing field `image`, and `imgae` is no key a job takes (did you mean `image`?)"), "{err}");
    std::fs::write(d.join("manifest.toml"), format!("{}{}", job("a.tif", "camera"), job("b.tif", "camera"))).unwrap();
    let err = String::from_utf8_lossy(&batch(d, &["--dry-run"]).stderr).to_string();
    assert!(err.contains("line 6: image ") && err.contains("b.tif does not exist"), "{err}");
    // A DEM the jobs take from [defaults]: a missing one said at its line
    // there, not at a job's; a folder of tiles is a DEM (as --dem takes).
    block(d, 1);
    std::fs::write(d.join("manifest.toml"), format!("# a block\n[defaults]\ndem = \"nowhere\"\n\n{}", jobs_toml(1))).unwrap();
    let err = String::from_utf8_lossy(&batch(d, &["--dry-run"]).stderr).to_string();
    assert!(err.contains("line 3: dem: ") && err.contains("nowhere does not exist"), "{err}");
    std::fs::create_dir(d.join("tiles")).unwrap();
    std::fs::copy(d.join("scene/dem.tif"), d.join("tiles/dem.tif")).unwrap();
    std::fs::write(d.join("manifest.toml"), format!("[defaults]\ndem = \"tiles\"\n\n{}", jobs_toml(1))).unwrap();
    let o = batch(d, &["--dry-run"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn sigterm_mid_batch_keeps_finished_jobs_and_a_rerun_finishes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    block(d, 4);
    std::fs::write(d.join("manifest.toml"), format!("[defaults]\ndem = \"scene/dem.tif\"\noutput_dir = \"ortho\"\ngsd = 0.6\n\n{}", jobs_toml(4))).unwrap();
    let rep = d.join("r.jsonl");
    let child = Command::new(bin())
        .args(["batch", s(&d.join("manifest.toml")), "--quiet", "--report", s(&rep), "--threads", "1"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until the first job is done, then stop the batch.
    let t = std::time::Instant::now();
    while !std::fs::read_to_string(&rep).map(|s| s.contains("\"done\"")).unwrap_or(false) {
        assert!(t.elapsed().as_secs() < 60, "no job finished");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    Command::new("kill").args(["-15", &child.id().to_string()]).status().unwrap();
    let o = wait_deadline(child, 30);
    assert_eq!(o.status.code(), Some(143), "{}", String::from_utf8_lossy(&o.stderr));
    let done: Vec<String> = lines(&rep).iter().filter(|l| l["status"] == "done").map(|l| l["job"].as_str().unwrap().to_string()).collect();
    assert!(!done.is_empty() && done.len() < 4, "{done:?}");
    assert!(files_containing(&d.join("ortho"), "partial").is_empty());
    for name in &done {
        assert!(d.join(format!("ortho/{name}.tif")).is_file());
    }
    // The rerun skips what was done and finishes the rest.
    let o = batch(d, &["--report", s(&rep)]);
    assert!(o.status.success());
    let st = lines(&rep);
    assert_eq!(st.iter().filter(|l| l["status"] == "skipped").count(), done.len());
    assert_eq!(st.iter().filter(|l| l["status"] == "done").count(), 4 - done.len());
}

/// `rectify` with `base` and then `more`.
fn a_whole_with<'a>(base: &[&'a str], more: &[&'a str]) -> Vec<&'a str> {
    [&["rectify"][..], base, more].concat()
}

#[test]
fn window_pieces_assemble_into_the_single_run_bit_for_bit() {
    // Cloud-Optimized, so that the file's order is the layout's, not the
    // order tiles were made in: the whole's overviews, made anew by
    // assemble from the pieces' tiles, must equal the single run's.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("scene"), 700, |o| o.kappa_deg = 20.0);
    let base = ["--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "--tile", "128"];
    let whole = d.join("whole.tif");
    let mut a = vec!["rectify"];
    a.extend_from_slice(&base);
    a.extend_from_slice(&["-o", s(&whole), "--cog"]);
    assert!(run(&a).status.success());
    let info = gcm_ortho::io::source::SourceImage::open(&whole, 1 << 20).unwrap().info;
    let (ta, td) = (info.width.div_ceil(128), info.height.div_ceil(128));
    // Four uneven pieces: a column of 2 tiles, and the rest split in three;
    // the last asks past both edges (shards of a fixed size), cut at them.
    let (c, r) = (2, td / 2);
    let windows = [[0, 0, c, td], [c, 0, ta - c, r], [c, r, 1, td - r], [c + 1, r, 9999, 9999]];
    let mut pieces = Vec::new();
    for (k, w) in windows.iter().enumerate() {
        let p = d.join(format!("piece{k}.tif"));
        let win = format!("{},{},{},{}", w[0], w[1], w[2], w[3]);
        let mut a = vec!["rectify"];
        a.extend_from_slice(&base);
        a.extend_from_slice(&["--window", &win, "-o", s(&p)]);
        let o = run(&a);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        pieces.push(p);
    }
    // A window that starts past the edge is refused, with the grid's size.
    let mut a = vec!["rectify"];
    a.extend_from_slice(&base);
    let (past, none) = (format!("0,{td},1,1"), d.join("none.tif"));
    a.extend_from_slice(&["--window", &past, "-o", s(&none)]);
    let o = run(&a);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.code() == Some(2) && err.contains(&format!("does not start inside the output's {ta}×{td} tiles")) && !none.exists(), "{err}");
    let joined = d.join("joined.tif");
    let mut a = vec!["assemble", "--cog", "-o", s(&joined)];
    for p in &pieces {
        a.push(s(p));
    }
    let o = run(&a);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::read(&whole).unwrap() == std::fs::read(&joined).unwrap(), "assembled file differs from the single run");
    // Lossless pieces coded anew in JPEG: the single JPEG run's bytes,
    // its overviews made from the same pixels.
    let jpeg = d.join("jpeg.tif");
    assert!(run(&[&a_whole_with(&base, &["-o", s(&jpeg), "--cog", "--compress", "jpeg"])[..]].concat()).status.success());
    let recoded = d.join("recoded.tif");
    let mut a = vec!["assemble", "--cog", "--compress", "jpeg", "-o", s(&recoded)];
    a.extend(pieces.iter().map(|p| s(p)));
    let o = run(&a);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::read(&jpeg).unwrap() == std::fs::read(&recoded).unwrap(), "recoded pieces differ from the single JPEG run");
    // A piece made on a node that staged the inputs elsewhere (copies:
    // other paths, other times) joins the others as theirs.
    let node = d.join("node");
    std::fs::create_dir(&node).unwrap();
    let staged: Vec<std::path::PathBuf> = [&sc.scan, &sc.camera, &sc.dem]
        .iter()
        .map(|f| {
            let to = node.join(f.file_name().unwrap());
            std::fs::copy(f, &to).unwrap();
            to
        })
        .collect();
    let w = windows[3];
    let win = format!("{},{},{},{}", w[0], w[1], w[2], w[3]);
    let elsewhere = d.join("elsewhere.tif");
    let o = run(&[
        "rectify",
        "--image",
        s(&staged[0]),
        "--camera",
        s(&staged[1]),
        "--dem",
        s(&staged[2]),
        "--quiet",
        "--tile",
        "128",
        "--window",
        &win,
        "-o",
        s(&elsewhere),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rejoined = d.join("rejoined.tif");
    let o = run(&["assemble", "--cog", "-o", s(&rejoined), s(&pieces[0]), s(&pieces[1]), s(&pieces[2]), s(&elsewhere)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::read(&whole).unwrap() == std::fs::read(&rejoined).unwrap(), "pieces of staged inputs differ from the single run");
    // A missing piece is an error naming the gap.
    let o = run(&["assemble", "-o", s(&d.join("gap.tif")), s(&pieces[0]), s(&pieces[1])]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(err.contains("no piece covers tile") && err.contains("tiles uncovered): a piece is missing"), "{err}");
    // Pieces that leave out an edge of the whole (a last shard that
    // failed) make no smaller file: refused, naming what is missing.
    for (set, missing) in [(vec![&pieces[0]], "0..2 across"), (vec![&pieces[1], &pieces[2], &pieces[3]], "2..")] {
        let edge = d.join("edge.tif");
        let mut a = vec!["assemble", "-o", s(&edge)];
        a.extend(set.iter().map(|p| s(p)));
        let o = run(&a);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains("pieces at its edges are missing") && err.contains(missing), "{err}");
        assert!(!edge.exists());
    }
    // A piece of another orthophoto on the same grid (here resampled
    // otherwise) is refused by name, nothing written.
    let cubic = d.join("cubic.tif");
    let w = windows[3];
    let win = format!("{},{},{},{}", w[0], w[1], w[2], w[3]);
    let o = run(&[&["rectify"][..], &base, &["--window", &win, "--resample", "cubic", "-o", s(&cubic)]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mixed = d.join("mixed.tif");
    let o = run(&["assemble", "-o", s(&mixed), s(&pieces[0]), s(&pieces[1]), s(&pieces[2]), s(&cubic)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("cubic.tif") && err.contains("other inputs or settings"), "{err}");
    assert!(!mixed.exists());
    // A piece coded otherwise: the refusal says how (the codecs).
    let zstd = d.join("zstd.tif");
    let o = run(&[&["rectify"][..], &base, &["--window", &win, "--compress", "zstd", "-o", s(&zstd)]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = run(&["assemble", "-o", s(&mixed), s(&pieces[0]), s(&pieces[1]), s(&pieces[2]), s(&zstd)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("zstd.tif") && err.contains("compression zstd, the first piece's deflate"), "{err}");
    assert!(!mixed.exists());
    // A piece whose run asked for another layout of the whole (--cog):
    // refused unless assemble is told which, whatever the pieces' order
    // (else the first piece named would choose it).
    let cog = d.join("cog_piece.tif");
    let o = run(&[&["rectify"][..], &base, &["--window", &win, "--cog", "-o", s(&cog)]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for set in [[&pieces[0], &pieces[1], &pieces[2], &cog], [&cog, &pieces[0], &pieces[1], &pieces[2]]] {
        let o = run(&["assemble", "-o", s(&mixed), s(set[0]), s(set[1]), s(set[2]), s(set[3])]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains("is not a piece of the same orthophoto") && err.contains("Cloud-Optimized layout"), "{err}");
        assert!(!mixed.exists());
    }
    let o = run(&["assemble", "--cog", "-o", s(&mixed), s(&cog), s(&pieces[0]), s(&pieces[1]), s(&pieces[2])]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::remove_file(&mixed).unwrap();
    // A piece given twice: both named, exit 2 as for the gap.
    let o = run(&["assemble", "-o", s(&d.join("twice.tif")), s(&pieces[0]), s(&pieces[0]), s(&pieces[1])]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("is given twice"), "{}", String::from_utf8_lossy(&o.stderr));
    // Two files of one window (a piece copied): both named, with the tile.
    let copy = d.join("copy.tif");
    std::fs::copy(&pieces[0], &copy).unwrap();
    let o = run(&["assemble", "-o", s(&d.join("twice.tif")), s(&pieces[0]), s(&copy), s(&pieces[1])]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("both cover tile"));
    // Float pieces (NaN their nodata value, which is not equal to
    // itself) assemble as well: a coordinate image in two pieces.
    let src = gcm_ortho::io::source::SourceImage::open(&sc.scan, 1 << 20).unwrap().info;
    let coords = d.join("coords.tif");
    common::coordinate_image(&coords, src.width, src.height);
    let base = ["--image", s(&coords), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "--tile", "128"];
    let with = |extra: &[&str]| -> bool {
        let mut a = vec!["rectify"];
        a.extend_from_slice(&base);
        a.extend_from_slice(extra);
        run(&a).status.success()
    };
    let (whole, p0, p1, joined) = (d.join("fwhole.tif"), d.join("f0.tif"), d.join("f1.tif"), d.join("fjoined.tif"));
    assert!(with(&["-o", s(&whole), "--cog"]));
    assert!(with(&["--window", &format!("0,0,{c},{td}"), "-o", s(&p0)]));
    assert!(with(&["--window", &format!("{c},0,{},{td}", ta - c), "-o", s(&p1)]));
    let o = run(&["assemble", "--cog", "-o", s(&joined), s(&p0), s(&p1)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::read(&whole).unwrap() == std::fs::read(&joined).unwrap(), "assembled float file differs from the single run");
    // Nor JPEG of floats: refused by the option, nothing written.
    let o = run(&["assemble", "--compress", "jpeg", "-o", s(&d.join("fjpeg.tif")), s(&p0), s(&p1)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--compress") && !d.join("fjpeg.tif").exists(), "{err}");
}

/// The manifest takes the error bound as the CLI does: 0.1 by default,
/// `"none"` to opt out, and a bad value fails that job with its line.
#[test]
fn the_error_bound_in_a_manifest() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    block(d, 2);
    let m = d.join("manifest.toml");
    let report = d.join("r.jsonl");
    let jobs = "[[job]]\nimage = \"scans/s00.tif\"\ncamera = \"scene/camera.toml\"\n\n[[job]]\nimage = \"scans/s01.tif\"\ncamera = \"scene/camera.toml\"\nmax_error = \"none\"\n";
    std::fs::write(&m, format!("[defaults]\ndem = \"scene/dem.tif\"\n{jobs}")).unwrap();
    let r = batch(d, &["--report", s(&report)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let bounds: Vec<serde_json::Value> = lines(&report).iter().map(|l| l["error_bound"].clone()).collect();
    assert_eq!(bounds, [serde_json::json!(0.1), serde_json::Value::Null]);
    std::fs::write(&m, "[defaults]\ndem = \"scene/dem.tif\"\nmax_error = -3\n[[job]]\nimage = \"scans/s00.tif\"\ncamera = \"scene/camera.toml\"\n").unwrap();
    let r = batch(d, &["--force"]);
    let err = String::from_utf8_lossy(&r.stderr);
    // (In [defaults]: the manifest is refused, at the key's line.)
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.contains("line 3: [defaults]: max_error: -3 must be a positive number"), "{err}");
}

/// The manifest takes `nodata` as the CLI does: the mask by default, a
/// number as a tagged nodata value, `"mask"` by name; a bad word fails
/// with its line.
#[test]
fn nodata_in_a_manifest() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    block(d, 3);
    let m = d.join("manifest.toml");
    let report = d.join("r.jsonl");
    let job = |i: usize, extra: &str| format!("[[job]]\nimage = \"scans/s{i:02}.tif\"\ncamera = \"scene/camera.toml\"\n{extra}\n");
    let jobs = [job(0, ""), job(1, "nodata = 0"), job(2, "nodata = \"mask\"")].concat();
    std::fs::write(&m, format!("[defaults]\ndem = \"scene/dem.tif\"\n{jobs}")).unwrap();
    let r = batch(d, &["--report", s(&report)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let outputs: Vec<PathBuf> = lines(&report).iter().map(|l| d.join(l["output"].as_str().unwrap())).collect();
    let marks: Vec<(Option<f64>, bool)> = outputs
        .iter()
        .map(|o| {
            let info = gcm_ortho::io::source::SourceImage::open(o, 1 << 20).unwrap().info;
            (info.georef.unwrap().nodata, info.mask.is_some())
        })
        .collect();
    assert_eq!(marks, [(None, true), (Some(0.0), false), (None, true)]);
    std::fs::write(&m, format!("[defaults]\ndem = \"scene/dem.tif\"\nnodata = \"none\"\n{}", job(0, ""))).unwrap();
    let r = batch(d, &["--force"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.contains("line 3: [defaults]: nodata") && err.contains("neither auto, mask nor a number"), "{err}");
}

/// The same image in two jobs, however spelt, is refused naming both lines
/// (before, a second was taken under a longer name and rectified twice;
/// a third was refused naming itself as the second).
#[test]
fn the_same_image_twice_is_refused_naming_both_jobs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    block(d, 1);
    let job = |image: &str| format!("[[job]]\nimage = \"{image}\"\ncamera = \"scene/camera.toml\"\n");
    let text = format!("[defaults]\ndem = \"scene/dem.tif\"\n\n{}{}{}", job("scans/s00.tif"), job("./scans/s00.tif"), job("scans/../scans/s00.tif"));
    std::fs::write(d.join("manifest.toml"), text).unwrap();
    let o = batch(d, &["--dry-run"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains("line 8: a second job for the image") && err.contains("./scans/s00.tif (the first at line 5)"), "{err}");
    assert!(err.contains("line 11: a second job for the image") && err.contains("scans/../scans/s00.tif (the first at line 5)"), "{err}");
}

/// A DEM with a hole under the footprint: `--dry-run` fails the job (exit
/// 3) with the run's own message, where the set-up alone passed it; with
/// `dem_hole = "nodata"` the dry run and the run both pass.
#[test]
fn a_dry_run_finds_the_dems_hole_the_run_would_fail_on() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("scene"), 400, |_| {});
    let g = gcm_ortho::dem::GridDem::read_within(&sc.dem, u64::MAX).unwrap();
    let (gw, gh, gt) = (g.width as u32, g.height as u32, g.transform);
    let holed = d.join("holed.tif");
    let hole = |c: u32, r: u32| c.abs_diff(gw / 2) < 4 && r.abs_diff(gh / 2) < 4;
    common::f32_raster(&holed, (gw, gh), (gt[0], gt[3], gt[1], 32631), |c, r| if hole(c, r) { f32::NAN } else { g.sample(c as usize, r as usize) });
    let job = |extra: &str| format!("[[job]]\nimage = {:?}\ncamera = {:?}\ndem = {:?}\noutput = \"out/o.tif\"\n{extra}", s(&sc.scan), s(&sc.camera), s(&holed));
    std::fs::write(d.join("manifest.toml"), job("")).unwrap();
    let dry = batch(d, &["--dry-run"]);
    let dry_err = String::from_utf8_lossy(&dry.stderr).to_string();
    assert_eq!(dry.status.code(), Some(3), "{dry_err}");
    assert!(dry_err.contains("holed.tif") && dry_err.contains("a hole (nodata) in the DEM"), "{dry_err}");
    let ran = batch(d, &[]);
    let ran_err = String::from_utf8_lossy(&ran.stderr).to_string();
    assert!(!ran.status.success() && !d.join("out/o.tif").exists(), "{ran_err}");
    let point = |t: &str| t.split("ground point ").nth(1).map(|r| r.split(')').next().unwrap_or("").to_string());
    assert_eq!(point(&dry_err), point(&ran_err), "the dry run names the run's point: {dry_err} / {ran_err}");
    // A manifest naming itself as the DEM: the dry run reads it as the run would.
    let own = format!("[[job]]\nimage = {:?}\ncamera = {:?}\ndem = \"manifest.toml\"\noutput = \"out/o.tif\"\n", s(&sc.scan), s(&sc.camera));
    std::fs::write(d.join("manifest.toml"), own).unwrap();
    let dry = batch(d, &["--dry-run"]);
    let err = String::from_utf8_lossy(&dry.stderr);
    assert!(dry.status.code() == Some(3) && err.contains("manifest.toml") && err.contains("will fail"), "{err}");
    std::fs::write(d.join("manifest.toml"), job("dem_hole = \"nodata\"\n")).unwrap();
    let dry = batch(d, &["--dry-run"]);
    assert_eq!(dry.status.code(), Some(0), "{}", String::from_utf8_lossy(&dry.stderr));
    assert!(batch(d, &[]).status.success());
}
