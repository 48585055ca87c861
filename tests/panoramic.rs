//! Panoramic (optical-bar) cameras: the model against an independent
//! implementation of Ames Stereo Pipeline's optical bar (written here from
//! its published equations, ASP's pixel convention), on ASP's published
//! KH-4B and KH-9 sample cameras; the image motion compensation's sign for
//! each scan direction; a synthetic KH-4B-like strip rectified at the
//! defaults within the bound at every pixel (coordinate images) and on the
//! truth; a resection from noisy GCPs; bad cameras named.

mod common;
use common::*;
use gcm_ortho::camera::file::{Camera, Sensor};
use nalgebra::{Matrix3, Vector3};
use std::path::Path;

/// ASP's published sample cameras (its documentation's KH-4B and KH-9).
fn sample(name: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/panoramic").join(name)).unwrap()
}

/// ASP's optical bar, pixel → ray, from its published equations (not the
/// project's code): ASP pixels (the first pixel's centre at 0, 0).
struct AspBar {
    size: [f64; 2],
    centre: [f64; 2],
    pitch: f64,
    f: f64,
    scan_time: f64,
    tilt: f64,
    c0: Vector3<f64>,
    r: Matrix3<f64>,
    speed: f64,
    radius: f64,
    elevation: f64,
    mcf: f64,
    left_to_right: bool,
}

impl AspBar {
    fn parse(text: &str) -> AspBar {
        let get = |k: &str| -> Vec<f64> {
            let line = text.lines().find(|l| l.split('=').next().unwrap().trim() == k).unwrap();
            line.split('=').nth(1).unwrap().split_whitespace().map(|v| v.parse().unwrap()).collect()
        };
        let r = get("iR");
        AspBar {
            size: [get("image_size")[0], get("image_size")[1]],
            centre: [get("image_center")[0], get("image_center")[1]],
            pitch: get("pitch")[0],
            f: get("f")[0],
            scan_time: get("scan_time")[0],
            tilt: get("forward_tilt")[0],
            c0: Vector3::new(get("iC")[0], get("iC")[1], get("iC")[2]),
            r: Matrix3::new(r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]),
            speed: get("speed")[0],
            radius: get("mean_earth_radius")[0],
            elevation: get("mean_surface_elevation")[0],
            mcf: get("motion_compensation_factor")[0],
            left_to_right: !text.contains("scan_dir = left"),
        }
    }

    /// (origin, unit direction) of ASP pixel (x, y), ECEF.
    fn ray(&self, x: f64, y: f64) -> (Vector3<f64>, Vector3<f64>) {
        let (sx, sy) = ((x - self.centre[0]) * self.pitch, (y - self.centre[1]) * self.pitch);
        let angle = |px: f64| (px - self.centre[0]) * self.pitch / self.f;
        let rate = (angle(self.size[0] - 1.0) - angle(0.0)) / self.scan_time;
        let max_col = self.size[0] - 1.0;
        let fraction = if self.left_to_right { x / max_col } else { (max_col - x) / max_col };
        let (s, c) = self.tilt.sin_cos();
        let tilt_x = Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c);
        let velocity = self.r * tilt_x * Vector3::new(0.0, self.speed, 0.0);
        let centre = self.c0 + fraction * self.scan_time * velocity;
        let alpha = sx / self.f;
        let h = centre.norm() - (self.elevation + self.radius);
        let mut imc = self.f * self.speed / (h * rate) * alpha.sin() * self.mcf;
        if !self.left_to_right {
            imc = -imc;
        }
        let d = Vector3::new(self.f * alpha.sin(), sy + imc, self.f * alpha.cos()).normalize();
        (centre, self.r * d)
    }
}

/// WGS84 longitude, latitude (degrees), height of an ECEF point (the test's
/// own: Bowring's start, fixed-point on the latitude).
fn geodetic(p: Vector3<f64>) -> (f64, f64, f64) {
    let (a, f) = (6_378_137.0, 1.0 / 298.257_223_563);
    let e2 = f * (2.0 - f);
    let r = p.x.hypot(p.y);
    let mut lat = p.z.atan2(r * (1.0 - e2));
    let mut h = 0.0;
    for _ in 0..10 {
        let n = a / (1.0 - e2 * lat.sin().powi(2)).sqrt();
        h = r / lat.cos() - n;
        lat = p.z.atan2(r * (1.0 - e2 * n / (n + h)));
    }
    (p.y.atan2(p.x).to_degrees(), lat.to_degrees(), h)
}

/// The camera an ASP file at `path` gives, its ground in EPSG:4326.
fn camera_of(path: &Path) -> Camera {
    let set = gcm_ortho::camera::formats::read(path, None, None).unwrap();
    let cam = set.camera_for(Path::new("scan.tif")).unwrap().build(path).unwrap();
    cam.in_crs(&gcm_ortho::geodesy::Crs::from_epsg(4326).unwrap()).unwrap()
}

#[test]
fn asp_s_kh4b_and_kh9_samples_go_ground_to_image_as_asp_s_rays_say_to_a_millionth_of_a_pixel() {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in [("kh4b.tsai", sample("kh4b_sample.tsai")), ("kh9.tsai", sample("kh9_sample.tsai"))] {
        let text = text.as_str();
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        let cam = camera_of(&path);
        assert!(matches!(cam.sensor, Sensor::Panoramic(_)), "{name}: read as a panoramic camera");
        let asp = AspBar::parse(text);
        let mut worst: f64 = 0.0;
        for j in 0..=8 {
            for i in 0..=16 {
                let (x, y) = ((asp.size[0] - 1.0) * f64::from(i) / 16.0, (asp.size[1] - 1.0) * f64::from(j) / 8.0);
                let (o, d) = asp.ray(x, y);
                // Down the ray to the mean surface's sphere (the test's own).
                let rad = asp.radius + asp.elevation;
                let b = o.dot(&d);
                let t = -b - (b * b - (o.norm_squared() - rad * rad)).sqrt();
                let (lon, lat, h) = geodetic(o + t * d);
                let (c, r) = cam.model().project(lon, lat, h).expect("the ground point is imaged");
                worst = worst.max((c - (x + 0.5)).abs()).max((r - (y + 0.5)).abs());
            }
        }
        eprintln!("{name}: worst {worst:.2e} px");
        assert!(worst <= 1e-6, "{name}: {worst} px");
    }
}

#[test]
fn the_motion_compensation_moves_the_image_along_the_film_with_the_scan_s_sign() {
    let dir = tempfile::tempdir().unwrap();
    for dir_word in ["right", "left"] {
        let text = sample("kh4b_sample.tsai").replace("scan_dir = right", &format!("scan_dir = {dir_word}"));
        let off = text.replace("motion_compensation_factor = 1.0", "motion_compensation_factor = 0.0");
        let (on_path, off_path) = (dir.path().join(format!("on_{dir_word}.tsai")), dir.path().join(format!("off_{dir_word}.tsai")));
        std::fs::write(&on_path, &text).unwrap();
        std::fs::write(&off_path, &off).unwrap();
        let (on, off_cam) = (camera_of(&on_path), camera_of(&off_path));
        // A ground point seen 3000 columns right of the lens axis.
        let asp = AspBar::parse(&off);
        let (o, d) = asp.ray(asp.centre[0] + 3000.0, asp.centre[1]);
        let (lon, lat, h) = geodetic(o + 170_000.0 * d);
        let (_, r_on) = on.model().project(lon, lat, h).unwrap();
        let (c_off, r_off) = off_cam.model().project(lon, lat, h).unwrap();
        let alpha = (c_off - 0.5 - asp.centre[0]) * asp.pitch / asp.f;
        let rate = (asp.size[0] - 1.0) * asp.pitch / asp.f / asp.scan_time;
        let centre = o; // (the centre's height changes by metres over the scan: far below the tolerance)
        let height = centre.norm() - (asp.radius + asp.elevation);
        let imc_px = asp.f * asp.speed / (height * rate) * alpha.sin() / asp.pitch;
        let expected = if dir_word == "right" { -imc_px } else { imc_px };
        eprintln!("scan {dir_word}: the row moves {:.3} px (expected {expected:.3})", r_on - r_off);
        assert!(imc_px > 10.0, "a compensation worth testing: {imc_px} px");
        assert!((r_on - r_off - expected).abs() < 1e-3 * imc_px, "scan {dir_word}: {} vs {expected}", r_on - r_off);
    }
}

/// A KH-4B-like strip (70° scan) over `relief`, DEM posted every 300 m (about 4 output px).
fn strip(dir: &Path, relief: gcm_ortho::synth::Relief) -> gcm_ortho::synth::SynthReport {
    let mut o = gcm_ortho::synth::SynthOptions::default();
    (o.out, o.width, o.height, o.bands, o.relief) = (dir.to_path_buf(), 2400, 200, 1, relief);
    (o.camera, o.dem_posting) = (gcm_ortho::synth::CameraKind::Panoramic, 300.0);
    gcm_ortho::synth::synth(&o, &gcm_ortho::progress::NoProgress).unwrap()
}

/// `sc`'s coordinate image rectified at the defaults and exactly onto the
/// truth's grid, with `camera`; (default, exact, default's report).
/// The strip's coordinate image (written once into `dir`) rectified with
/// `camera` onto the truth's grid, into `name` (its report beside it):
/// the output, and how the run ended.
fn rectify_coords(dir: &Path, sc: &gcm_ortho::synth::SynthReport, camera: &Path, name: &str, extra: &[&str]) -> (std::path::PathBuf, std::process::Output) {
    let coords = dir.join("coords.tif");
    if !coords.exists() {
        coordinate_image(&coords, 2400, 200);
    }
    let truth = sc.truth.as_ref().unwrap();
    let out = dir.join(name);
    let json = out.with_extension("json");
    let mut a = vec![
        "rectify",
        "--image",
        s(&coords),
        "--camera",
        s(camera),
        "--dem",
        s(&sc.dem),
        "--like",
        s(truth),
        "--nodata",
        "-1",
        "--compress",
        "none",
        "--quiet",
    ];
    a.extend_from_slice(extra);
    a.extend(["-o", s(&out), "--json", s(&json)]);
    let r = run(&a);
    (out, r)
}

/// A successful run's report.
fn report_of(out: &Path, r: &std::process::Output) -> serde_json::Value {
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    serde_json::from_slice(&std::fs::read(out.with_extension("json")).unwrap()).unwrap()
}

/// `sc`'s coordinate image rectified at the defaults and exactly onto the
/// truth's grid, with `camera`: their difference, and the default's report.
fn coordinate_runs(dir: &Path, sc: &gcm_ortho::synth::SynthReport, camera: &Path) -> (MapDifference, serde_json::Value) {
    let (default, r) = rectify_coords(dir, sc, camera, "default.tif", &[]);
    let report = report_of(&default, &r);
    let (exact, r) = rectify_coords(dir, sc, camera, "exact.tif", &["--sparsity", "1", "--corrections", "cell", "--memory", "1G"]);
    report_of(&exact, &r);
    (coordinate_map_difference(&default, &exact, 2400, 200), report)
}

#[test]
fn a_kh4b_like_strip_is_within_the_bound_at_every_pixel_and_on_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let sc = strip(dir.path(), gcm_ortho::synth::Relief::Hilly);
    let (m, report) = coordinate_runs(dir.path(), &sc, &sc.camera);
    eprintln!("panoramic strip over hills: {} px, max {:.4} px, mean {:.5} px; gcm {}", m.pixels, m.max, m.mean, report["gcm"]);
    // (At the strip's mean GSD: its ends, seen slant, are coarser than its middle.)
    assert!(m.pixels > 400_000, "{} px compared", m.pixels);
    assert!(m.max <= 0.1, "max {} px", m.max);
    assert_eq!(report["error_within"], true, "{}", report["error_within"]);

    // The picture: the scan rectified onto the truth's grid.
    let ortho = dir.path().join("ortho.tif");
    let r = run(&[
        "rectify",
        "--image",
        s(&sc.scan),
        "--camera",
        s(&sc.camera),
        "--dem",
        s(&sc.dem),
        "--like",
        s(sc.truth.as_ref().unwrap()),
        "--quiet",
        "-o",
        s(&ortho),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let (a, _) = whole_image(&ortho);
    let (t, _) = whole_image(sc.truth.as_ref().unwrap());
    let both: Vec<(f64, f64)> = a.iter().zip(&t).filter(|(x, y)| **x > 0 && **y > 0).map(|(x, y)| (f64::from(*x), f64::from(*y))).collect();
    let mean = both.iter().map(|(x, y)| (x - y).abs()).sum::<f64>() / both.len() as f64;
    let (ma, mt) = both.iter().fold((0.0, 0.0), |s, (x, y)| (s.0 + x / both.len() as f64, s.1 + y / both.len() as f64));
    let (mut sab, mut saa, mut stt) = (0.0, 0.0, 0.0);
    for (x, y) in &both {
        sab += (x - ma) * (y - mt);
        saa += (x - ma) * (x - ma);
        stt += (y - mt) * (y - mt);
    }
    let corr = sab / (saa * stt).sqrt();
    eprintln!("ortho against truth: {} px, mean |diff| {mean:.2} DN, correlation {corr:.4}", both.len());
    assert!(both.len() > 300_000 && corr > 0.97, "{} px, correlation {corr}", both.len());
}

#[test]
fn over_flat_ground_a_70_degree_scan_needs_no_refined_cell_and_asp_s_file_gives_the_same_orthophoto() {
    let dir = tempfile::tempdir().unwrap();
    let sc = strip(dir.path(), gcm_ortho::synth::Relief::Flat);
    let (m, report) = coordinate_runs(dir.path(), &sc, &sc.camera);
    let g = &report["gcm"];
    eprintln!("flat: max {:.4} px; gcm {g}", m.max);
    assert!(m.max <= 0.1, "max {} px", m.max);
    // The cylinder's bending over the whole scan is carried by the
    // corrections between nodes 16 px apart: the GCM stays sparse.
    assert_eq!(g["refined_cells"], 0, "{g}");
    assert!(g["exact_pixels"].as_u64().unwrap() < (m.pixels / 100) as u64, "{g}");
    // ASP's form of the same camera: the same bytes.
    let tsai = sc.camera.with_file_name("scan.tsai");
    let asp = dir.path().join("asp");
    std::fs::create_dir_all(&asp).unwrap();
    let (a, _) = coordinate_runs(&asp, &sc, &tsai);
    assert_eq!(read_f32(&dir.path().join("default.tif")).3, read_f32(&asp.join("default.tif")).3);
    assert_eq!(a.max, m.max);
    // `cameras` turns ASP's file into ours: the same orthophoto again; to
    // Orthority's form it is refused by name.
    let cams = dir.path().join("cams");
    let r = run(&["cameras", "--camera", s(&tsai), "--out-dir", s(&cams), "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let (ours, r) = rectify_coords(&asp, &sc, &cams.join("scan.toml"), "ours.tif", &[]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(read_f32(&ours).3, read_f32(&asp.join("default.tif")).3);
    let r = run(&["cameras", "--camera", s(&tsai), "--out-dir", s(&dir.path().join("oty")), "--to", "orthority"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("scan.tsai") && err.contains("panoramic"), "{err}");
}

#[test]
fn a_resection_from_ten_noisy_gcps_recovers_the_strip_s_camera() {
    let dir = tempfile::tempdir().unwrap();
    let sc = strip(dir.path(), gcm_ortho::synth::Relief::Hilly);
    // Ten of synth's checkpoints spread over the strip, 0.2 px of noise.
    let text = std::fs::read_to_string(&sc.checkpoints).unwrap();
    let mut rows: Vec<Vec<f64>> = text.lines().skip(1).map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    rows.sort_by(|a, b| a[4].total_cmp(&b[4]));
    let step = rows.len() / 10;
    let mut csv = String::from("id,col,row,x,y,z\n");
    for (k, r) in rows.iter().step_by(step).take(10).enumerate() {
        let noise = |i: usize| 0.2 * (((k * 7 + i * 3) % 5) as f64 / 2.0 - 1.0);
        csv += &format!("{k},{},{},{},{},{}\n", r[4] + noise(0), r[5] + noise(1), r[1], r[2], r[3]);
    }
    let gcps = dir.path().join("gcps.csv");
    std::fs::write(&gcps, csv).unwrap();
    std::fs::write(dir.path().join("gcps.prj"), "EPSG:32631").unwrap();
    // The camera as poor metadata gives it: 3 km and half a degree off,
    // half the motion compensation.
    let truth_cam = std::fs::read_to_string(&sc.camera).unwrap();
    let mut bad = gcm_ortho::camera::file::CameraFile::parse(&truth_cam, &sc.camera).unwrap();
    let p = bad.panoramic.as_mut().unwrap();
    p.position_ecef[0] += 3000.0;
    p.position_ecef[2] -= 1500.0;
    let turn = nalgebra::Rotation3::from_euler_angles(0.005, -0.008, 0.004).into_inner();
    let r = Matrix3::from_fn(|i, j| p.rotation[i][j]) * turn;
    p.rotation = [[r[(0, 0)], r[(0, 1)], r[(0, 2)]], [r[(1, 0)], r[(1, 1)], r[(1, 2)]], [r[(2, 0)], r[(2, 1)], r[(2, 2)]]];
    p.motion_compensation = 0.5;
    let bad_path = dir.path().join("bad.toml");
    std::fs::write(&bad_path, bad.to_toml()).unwrap();
    let go = |camera: &Path, name: &str, extra: &[&str]| rectify_coords(dir.path(), &sc, camera, name, extra);
    let (right, r) = go(&sc.camera, "right.tif", &[]);
    report_of(&right, &r);
    let (fitted, r) = go(&bad_path, "fitted.tif", &["--gcps", s(&gcps), "--gcp-refine", "interior"]);
    let report = report_of(&fitted, &r);
    let g = &report["gcps"];
    eprintln!("resection: {g}");
    assert!(g["rms_before"].as_f64().unwrap() > 20.0 && g["rms_after"].as_f64().unwrap() < 0.3, "{g}");
    assert!(g["method"].as_str().unwrap().contains("motion compensation"), "{g}");
    let m = coordinate_map_difference(&fitted, &right, 2400, 200);
    eprintln!("fitted against the true camera: {} px, mean {:.3} px, max {:.3} px", m.pixels, m.mean, m.max);
    assert!(m.pixels > 300_000 && m.mean < 0.3 && m.max < 1.5, "mean {} max {}", m.mean, m.max);
    assert!(g.get("outlier").is_none(), "{g}");
    // Point 4 measured 3 px off along the scan: the others, fitted
    // without it, name it (in the report and on stderr, even quiet).
    let moved: String = std::fs::read_to_string(&gcps)
        .unwrap()
        .lines()
        .map(|l| match l.split_once(',') {
            Some(("4", rest)) => {
                let (c, rest) = rest.split_once(',').unwrap();
                format!("4,{},{rest}\n", c.parse::<f64>().unwrap() + 3.0)
            }
            _ => format!("{l}\n"),
        })
        .collect();
    std::fs::write(&gcps, moved).unwrap();
    let (off, r) = go(&bad_path, "off.tif", &["--gcps", s(&gcps), "--gcp-refine", "interior", "--gcp-max-residual", "5"]);
    let said = report_of(&off, &r)["gcps"]["outlier"].as_str().unwrap_or_default().to_string();
    assert!(said.contains("GCP 4 ") && said.contains("outlier"), "{said}");
    assert!(String::from_utf8_lossy(&r.stderr).contains("GCP 4 "), "{}", String::from_utf8_lossy(&r.stderr));
    // Three GCPs cannot fix the dynamics: asked for, refused by name.
    let three: String = std::fs::read_to_string(&gcps).unwrap().lines().take(4).map(|l| format!("{l}\n")).collect();
    std::fs::write(&gcps, three).unwrap();
    let (_, r) = go(&bad_path, "three.tif", &["--gcps", s(&gcps), "--gcp-refine", "interior"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("gcps.csv") && err.contains("6 or more"), "{err}");
    assert!(!dir.path().join("three.tif").exists());
}

#[test]
fn a_scan_over_180_degrees_and_no_scan_time_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let coords = dir.path().join("coords.tif");
    coordinate_image(&coords, 13656, 8);
    for (what, text, expect) in [
        ("wide", sample("kh4b_sample.tsai").replace("pitch = 7.0e-06", "pitch = 2.0e-04"), "spans"),
        ("still", sample("kh4b_sample.tsai").replace("scan_time = 0.5", "scan_time = 0"), "scan time"),
        ("short", sample("kh4b_sample.tsai").replace("iC = -1030862.1946224371 ", "iC = "), "iC takes 3"),
    ] {
        let cam = dir.path().join(format!("{what}.tsai"));
        std::fs::write(&cam, text).unwrap();
        let out = dir.path().join(format!("{what}.tif"));
        let r = run(&["rectify", "--image", s(&coords), "--camera", s(&cam), "--height", "4000", "-o", s(&out)]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && err.contains(&format!("{what}.tsai")) && err.contains(expect), "{what}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{what}: one line: {err}");
        assert!(!out.exists());
    }
}

/// A fore/aft pair as KH-4B's cameras took them (±15°, B/H 0.54, the aft
/// camera sweeping back) over hills: `dem` with the two cameras (ours and
/// ASP's file) matches nearly all the overlap, its heights within a third
/// of the theoretical precision of the truth's.
#[test]
fn a_fore_and_aft_pair_gives_a_dsm_of_the_ground() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = run(&[
        "synth",
        "--out",
        s(d),
        "--camera",
        "panoramic",
        "--stereo",
        "0.54",
        "--size",
        "6000x600",
        "--bands",
        "1",
        "--relief",
        "hilly",
        "--dem-posting",
        "150",
        "--quiet",
    ]);
    assert!(o.status.success(), "synth --stereo: {}", String::from_utf8_lossy(&o.stderr));
    for f in ["left.tif", "right.tif", "left.toml", "right.toml", "left.tsai", "right.tsai", "dem.tif"] {
        assert!(d.join(f).exists(), "{f}");
    }
    let (dsm, json) = (d.join("dsm.tif"), d.join("dsm.json"));
    let o = run(&[
        "dem",
        "--left",
        s(&d.join("left.tif")),
        "--right",
        s(&d.join("right.tif")),
        "--left-camera",
        s(&d.join("left.toml")),
        "--right-camera",
        s(&d.join("right.tsai")),
        "--gsd",
        "100",
        "--json",
        s(&json),
        "--quiet",
        "-o",
        s(&dsm),
    ]);
    assert!(o.status.success(), "dem: {}", String::from_utf8_lossy(&o.stderr));
    let r: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let g = gcm_ortho::dem::GridDem::read(&dsm).unwrap();
    let truth = gcm_ortho::dem::Dem::open(&d.join("dem.tif"), &gcm_ortho::geodesy::Crs::from_epsg(32631).unwrap()).unwrap();
    let mut diffs = Vec::new();
    for j in 1..g.height - 1 {
        for i in 1..g.width - 1 {
            let v = g.sample(i, j);
            if v == -9999.0 {
                continue;
            }
            let t = g.transform;
            let (x, y) = (t[0] + (i as f64 + 0.5) * t[1], t[3] + (j as f64 + 0.5) * t[5]);
            if let gcm_ortho::dem::Height::Value(h) = truth.height(x, y) {
                diffs.push(f64::from(v) - h);
            }
        }
    }
    diffs.sort_by(f64::total_cmp);
    let n = diffs.len();
    let median_abs = {
        let mut a: Vec<f64> = diffs.iter().map(|d| d.abs()).collect();
        a.sort_by(f64::total_cmp);
        a[n / 2]
    };
    let precision = r["height_precision_m"].as_f64().unwrap();
    eprintln!(
        "panoramic pair: {n} cells, median |error| {median_abs:.1} m, bias {:.1} m, theoretical {precision:.1} m, matched {}",
        diffs[n / 2],
        r["matched_share"]
    );
    assert!(n > 300_000, "{n} cells");
    assert!(r["matched_share"].as_f64().unwrap() > 0.9, "matched {}", r["matched_share"]);
    assert!(median_abs < 0.5 * precision, "median |error| {median_abs} m against a theoretical {precision} m");
    assert!(diffs[n / 2].abs() < 0.1 * precision, "bias {}", diffs[n / 2]);
}
