//! Ground control points: an RPC's known bias recovered in image space, a
//! frame camera's perturbed pose recovered by resection to the points'
//! noise, the files read as Orthority writes them, and a bad point refused.

mod common;

use common::{run, s};
use gcm_ortho::camera::file::{Camera, CameraFile};
use gcm_ortho::camera::gcp::{refine, BiasModel, Gcp};
use gcm_ortho::geom::Affine2;
use nalgebra::{Matrix2, Vector2};
use std::path::{Path, PathBuf};

fn ventoux(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/ventoux").join(name)
}

/// The Pléiades crop's RPC camera (SRTM heights above EGM96).
fn pleiades() -> Camera {
    let geom = ventoux("left_image.geom");
    Camera::rpc_file(&geom, Some([5000.0, 5000.0]), Some(&ventoux("egm96_15_ventoux.gtx")), None).build(&geom).unwrap()
}

/// The bias a real product might carry: 2.9, 2.0 px (Orthority's QuickBird
/// case) and a slight drift.
fn true_bias() -> Affine2 {
    Affine2 { m: Matrix2::new(1.0 + 2e-4, -1e-4, 8e-5, 1.0 - 1.5e-4), t: Vector2::new(2.9, 2.0) }
}

/// Ground points seen at image positions over the crop, at heights around
/// the terrain's, and where the biased image shows them.
fn points(truth: &Camera, bias: &Affine2, lattice: &[(f64, f64)]) -> Vec<([f64; 3], [f64; 2])> {
    lattice
        .iter()
        .enumerate()
        .map(|(k, &(c, r))| {
            let z = 900.0 + 150.0 * (k % 4) as f64;
            let (x, y) = gcm_ortho::camera::locate(truth.model(), c, r, z, 1e-6).unwrap();
            let (c0, r0) = truth.model().project(x, y, z).unwrap();
            let (cb, rb) = bias.apply(c0, r0);
            ([x, y, z], [cb, rb])
        })
        .collect()
}

fn gcps_of(truth: &Camera, pts: &[([f64; 3], [f64; 2])]) -> Vec<Gcp> {
    let ground = gcm_ortho::geodesy::GroundCrs::new(&truth.crs).unwrap();
    pts.iter()
        .enumerate()
        .map(|(k, (p, o))| {
            let (lon, lat) = ground.to_lonlat(p[0], p[1]).unwrap();
            Gcp { id: format!("g{k}"), col: o[0], row: o[1], lon, lat, height: p[2], ellipsoidal: false }
        })
        .collect()
}

#[test]
fn an_rpc_bias_is_recovered_in_image_space() {
    let truth = pleiades();
    let bias = true_bias();
    let gcp_at = [(30.0, 40.0), (450.0, 60.0), (250.0, 250.0), (75.0, 440.0), (435.0, 425.0)];
    let gcps = gcps_of(&truth, &points(&truth, &bias, &gcp_at));
    let check_at: Vec<(f64, f64)> = (0..5).flat_map(|j| (0..5).map(move |i| (10.0 + 120.0 * i as f64, 15.0 + 117.0 * j as f64))).collect();
    let checks = points(&truth, &bias, &check_at);
    for (model, tolerance) in [(BiasModel::Affine, 0.05), (BiasModel::Auto, 0.05)] {
        let mut cam = pleiades();
        let fit = refine(&mut cam, &gcps, model, 2.0, Path::new("gcps.csv")).unwrap();
        assert_eq!(fit.method, "rpc affine");
        assert!(fit.rms_before > 3.0 && fit.rms_after < 1e-6, "{fit:?}");
        for (p, o) in &checks {
            let (c, r) = cam.model().project(p[0], p[1], p[2]).unwrap();
            assert!((c - o[0]).hypot(r - o[1]) < tolerance, "({c}, {r}) vs {o:?}");
        }
    }
    // A shift alone leaves the drift: off by the drift across the crop.
    let mut cam = pleiades();
    let fit = refine(&mut cam, &gcps, BiasModel::Shift, 2.0, Path::new("gcps.csv")).unwrap();
    assert_eq!(fit.method, "rpc shift");
    assert!(fit.rms_after > 0.01 && fit.rms_after < 0.3, "{fit:?}");
    assert!(fit.outlier.is_none(), "{fit:?}");
    // Of six points, one measured 3 px off: the bias the other five give
    // names it, with an affine bias and with a shift alike.
    let mut six = gcps_of(&truth, &points(&truth, &bias, &[(30.0, 40.0), (450.0, 60.0), (250.0, 250.0), (75.0, 440.0), (435.0, 425.0), (240.0, 30.0)]));
    for model in [BiasModel::Auto, BiasModel::Shift] {
        let fit = refine(&mut pleiades(), &six, model, 2.0, Path::new("gcps.csv")).unwrap();
        assert!(fit.outlier.is_none(), "{fit:?}");
    }
    six[2].row += 3.0;
    for model in [BiasModel::Auto, BiasModel::Shift] {
        let fit = refine(&mut pleiades(), &six, model, 3.0, Path::new("gcps.csv")).unwrap();
        let said = fit.outlier.clone().unwrap_or_default();
        assert!(said.contains("GCP g2 ") && said.contains("outlier"), "{model:?}: {fit:?}");
    }
    // Two points cannot fix an affine bias.
    let mut cam = pleiades();
    let e = refine(&mut cam, &gcps[..2], BiasModel::Affine, 2.0, Path::new("gcps.csv")).unwrap_err().to_string();
    assert!(e.contains("gcps.csv") && e.contains("needs 3"), "{e}");
}

#[test]
fn rectify_reads_gcps_reports_residuals_and_refuses_a_bad_point() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let truth = pleiades();
    let gcp_at = [(30.0, 40.0), (450.0, 60.0), (250.0, 250.0), (75.0, 440.0), (435.0, 425.0), (150.0, 350.0)];
    let pts = points(&truth, &true_bias(), &gcp_at);
    let ground = gcm_ortho::geodesy::GroundCrs::new(&truth.crs).unwrap();
    // As longitude, latitude: the .prj says EPSG:4326.
    let mut csv = String::from("ID,Col,Row,X,Y,Z\n");
    for (k, (p, o)) in pts.iter().enumerate() {
        let (lon, lat) = ground.to_lonlat(p[0], p[1]).unwrap();
        csv += &format!("gcp{k},{},{},{lon:.10},{lat:.10},{}\n", o[0], o[1], p[2]);
    }
    std::fs::write(d.join("gcps.csv"), &csv).unwrap();
    std::fs::write(d.join("gcps.prj"), "EPSG:4326").unwrap();
    let out = d.join("o.tif");
    let json = d.join("o.json");
    let (image, geom, dem, geoid, gcps) =
        (ventoux("left_image.tif"), ventoux("left_image.geom"), ventoux("srtm_N44E005_crop.tif"), ventoux("egm96_15_ventoux.gtx"), d.join("gcps.csv"));
    let args = vec![
        "rectify",
        "--image",
        s(&image),
        "--rpc",
        s(&geom),
        "--rpc-offset",
        "5000,5000",
        "--dem",
        s(&dem),
        "--geoid",
        s(&geoid),
        "--gcps",
        s(&gcps),
        "--quiet",
    ];
    let mut ok = args.clone();
    ok.extend(["-o", s(&out), "--json", s(&json)]);
    let r = run(&ok);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let g = &report["gcps"];
    assert_eq!(g["method"], "rpc affine");
    assert!(g["rms_before"].as_f64().unwrap() > 3.0 && g["rms_after"].as_f64().unwrap() < 0.01, "{g}");
    assert_eq!(g["points"].as_array().unwrap().len(), 6);

    // A point 10 px off is refused by name; nothing is written.
    let bad = {
        let mut lines: Vec<String> = csv.lines().map(str::to_string).collect();
        let f: Vec<String> = lines[4].split(',').map(str::to_string).collect();
        let c: f64 = pts[3].1[0] + 10.0;
        lines[4] = format!("gcp3,{c},{},{},{},{}", f[2], f[3], f[4], f[5]);
        lines.join("\n") + "\n"
    };
    std::fs::write(d.join("gcps.csv"), bad).unwrap();
    let out2 = d.join("o2.tif");
    let mut refused = args.clone();
    refused.extend(["-o", s(&out2)]);
    let r = run(&refused);
    let e = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{e}");
    assert!(e.contains("gcps.csv") && e.contains("GCP gcp3") && e.contains("--gcp-max-residual"), "{e}");
    assert!(!out2.exists());
}

#[test]
fn orthority_gcp_files_are_read_as_it_writes_them() {
    // ji with pixel centres at integers; WGS 84 longitude, latitude and
    // ellipsoidal height; features of other images skipped.
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("gcps.geojson");
    std::fs::write(
        &file,
        r#"{"type": "FeatureCollection", "features": [
 {"type": "Feature", "properties": {"ji": [10.0, 20.5], "filename": "a.tif", "id": "p1", "info": null},
  "geometry": {"type": "Point", "coordinates": [5.1, 44.2, 812.5]}},
 {"type": "Feature", "properties": {"ji": [3.0, 4.0], "filename": "b.tif", "id": "p2", "info": null},
  "geometry": {"type": "Point", "coordinates": [5.2, 44.3, 700.0]}}]}"#,
    )
    .unwrap();
    let g = gcm_ortho::camera::gcp::read(&file, Path::new("/data/a.jpg")).unwrap();
    assert_eq!(g, vec![Gcp { id: "p1".into(), col: 10.5, row: 21.0, lon: 5.1, lat: 44.2, height: 812.5, ellipsoidal: true }]);
    let e = gcm_ortho::camera::gcp::read(&file, Path::new("c.tif")).unwrap_err().to_string();
    assert!(e.contains("gcps.geojson") && e.contains("no ground control point for the image c.tif"), "{e}");
}

/// The farthest `cam` images the ground the true camera sees at a 13 × 9
/// lattice over a 600 × 400 frame, at heights from the ground to roofs
/// (150–180 m), pixels.
fn worst_over_frame(truth: &Camera, cam: &Camera) -> f64 {
    let mut worst = 0f64;
    for j in 0..=8 {
        for i in 0..=12 {
            let (c, r) = (i as f64 * 50.0, j as f64 * 50.0);
            let z = 150.0 + 10.0 * ((i + j) % 4) as f64;
            let (x, y) = gcm_ortho::camera::locate(truth.model(), c, r, z, 1e-9).unwrap();
            let (c2, r2) = cam.model().project(x, y, z).unwrap();
            worst = worst.max((c2 - c).hypot(r2 - r));
        }
    }
    worst
}

#[test]
fn a_frame_cameras_pose_is_recovered_by_resection() {
    let dir = tempfile::tempdir().unwrap();
    let sc = common::drone_scene(dir.path(), (600, 400), 12_000.0);
    let truth = Camera::read(&sc.camera).unwrap();
    // The pose a rough GNSS/IMU gives: metres and tenths of a degree off.
    let mut file = CameraFile::read(&sc.camera).unwrap();
    let ext = file.exterior.as_mut().unwrap();
    ext.position = [ext.position[0] + 3.0, ext.position[1] - 2.0, ext.position[2] + 1.5];
    ext.angles_deg = [ext.angles_deg[0] + 0.3, ext.angles_deg[1] - 0.2, ext.angles_deg[2] + 0.4];
    let crs = file.crs.clone();
    let perturbed = file.clone().build(&sc.camera).unwrap();
    // Eight points with ±0.05 px of measuring noise.
    let at = [(40.0, 30.0), (560.0, 40.0), (300.0, 200.0), (60.0, 370.0), (550.0, 360.0), (200.0, 120.0), (420.0, 280.0), (150.0, 300.0)];
    let noise = [(0.05, -0.03), (-0.04, 0.05), (0.02, 0.01), (-0.05, -0.04), (0.03, 0.05), (0.0, -0.05), (-0.02, 0.03), (0.05, 0.0)];
    let ground = gcm_ortho::geodesy::GroundCrs::new(&truth.crs).unwrap();
    let mut csv = String::from("id,col,row,x,y,z\n");
    for (k, (&(c, r), &(nc, nr))) in at.iter().zip(&noise).enumerate() {
        let z = 150.0 + 5.0 * (k % 3) as f64;
        let (x, y) = gcm_ortho::camera::locate(truth.model(), c, r, z, 1e-9).unwrap();
        csv += &format!("{k},{},{},{x},{y},{z}\n", c + nc, r + nr);
        let _ = ground.to_lonlat(x, y).unwrap();
    }
    let gcp_file = dir.path().join("gcps.csv");
    std::fs::write(&gcp_file, csv).unwrap();
    std::fs::write(dir.path().join("gcps.prj"), &crs).unwrap();
    let gcps = gcm_ortho::camera::gcp::read(&gcp_file, &sc.scan).unwrap();
    let mut cam = perturbed;
    let fit = refine(&mut cam, &gcps, BiasModel::Auto, 1.0, &gcp_file).unwrap();
    assert_eq!(fit.method, "resection");
    assert!(fit.rms_before > 3.0 && fit.rms_after < 0.06, "{fit:?}");
    // Over the whole frame, from the ground to the roofs: within the noise.
    let worst = worst_over_frame(&truth, &cam);
    assert!(worst < 0.15, "{worst} px from the true camera");
    assert!(fit.outlier.is_none(), "{fit:?}");
    // Point 5 measured 2.5 px off: the fit keeps it under the 2 px limit
    // (it pulls the pose its way), and the others, fitted without it,
    // name it.
    let off: String = std::fs::read_to_string(&gcp_file)
        .unwrap()
        .lines()
        .map(|l| match l.split_once(',') {
            Some(("5", rest)) => {
                let (c, rest) = rest.split_once(',').unwrap();
                format!("5,{},{rest}\n", c.parse::<f64>().unwrap() + 2.5)
            }
            _ => format!("{l}\n"),
        })
        .collect();
    std::fs::write(&gcp_file, off).unwrap();
    let gcps = gcm_ortho::camera::gcp::read(&gcp_file, &sc.scan).unwrap();
    let mut cam = file.build(&sc.camera).unwrap();
    let fit = refine(&mut cam, &gcps, BiasModel::Auto, 2.0, &gcp_file).unwrap();
    let said = fit.outlier.clone().unwrap_or_default();
    assert!(said.contains("GCP 5 ") && said.contains("outlier"), "{fit:?}");
}

#[test]
fn batch_jobs_take_their_images_gcps() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let truth = pleiades();
    let pts = points(&truth, &true_bias(), &[(30.0, 40.0), (450.0, 60.0), (250.0, 250.0), (75.0, 440.0)]);
    let ground = gcm_ortho::geodesy::GroundCrs::new(&truth.crs).unwrap();
    // One file for the block: rows of other images are skipped.
    let mut csv = String::from("image,id,col,row,x,y,z\nother.tif,x1,1,1,5.2,44.2,900\n");
    for (k, (p, o)) in pts.iter().enumerate() {
        let (lon, lat) = ground.to_lonlat(p[0], p[1]).unwrap();
        csv += &format!("left_image.tif,g{k},{},{},{lon:.10},{lat:.10},{}\n", o[0], o[1], p[2]);
    }
    std::fs::write(d.join("gcps.csv"), &csv).unwrap();
    std::fs::write(d.join("gcps.prj"), "EPSG:4326").unwrap();
    let cam = format!(
        "crs = \"auto\"\n[camera]\nmodel = \"rpc\"\n[rpc]\nfile = {:?}\noffset_px = [5000, 5000]\ngeoid = {:?}\n",
        s(&ventoux("left_image.geom")),
        s(&ventoux("egm96_15_ventoux.gtx"))
    );
    std::fs::write(d.join("cam.toml"), cam).unwrap();
    let manifest = format!(
        "[defaults]\ndem = {:?}\ngcps = \"gcps.csv\"\noutput_dir = \"out\"\n\n[[job]]\nimage = {:?}\ncamera = \"cam.toml\"\n",
        s(&ventoux("srtm_N44E005_crop.tif")),
        s(&ventoux("left_image.tif"))
    );
    std::fs::write(d.join("m.toml"), &manifest).unwrap();
    std::fs::create_dir(d.join("out")).unwrap();
    let report = d.join("r.jsonl");
    let r = run(&["batch", s(&d.join("m.toml")), "--quiet", "--report", s(&report)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let line: serde_json::Value = serde_json::from_str(std::fs::read_to_string(&report).unwrap().lines().last().unwrap()).unwrap();
    assert!(line.to_string().contains("rpc affine"), "{line}");
    // A refine setting without GCPs is a mistake, named.
    std::fs::write(d.join("m.toml"), manifest.replace("gcps = \"gcps.csv\"", "gcp_refine = \"shift\"")).unwrap();
    let r = run(&["batch", s(&d.join("m.toml")), "--quiet", "--dry-run"]);
    let e = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && e.contains("gcp_refine"), "{e}");
}

/// `--gcp-refine interior`: a drone frame whose calibration is off (focal
/// length 1 %, principal point 6 and −4 px) and whose pose is rough is
/// recovered — focal length, principal point and pose — from twelve GCPs
/// spread over the frame and in height; GCPs at one height under a camera
/// looking straight down cannot tell focal length from flying height, and
/// are refused by name.
#[test]
fn a_frame_cameras_interior_is_recovered_with_its_pose() {
    let dir = tempfile::tempdir().unwrap();
    let sc = common::drone_scene(dir.path(), (600, 400), 12_000.0);
    let truth_file = CameraFile::read(&sc.camera).unwrap();
    let truth = Camera::read(&sc.camera).unwrap();
    let f_true = truth_file.camera.focal_length_mm.unwrap();
    let pp_true = truth_file.interior.as_ref().unwrap().principal_point_px.unwrap();
    let perturb = |mut file: CameraFile| {
        file.camera.focal_length_mm = Some(f_true * 1.01);
        let i = file.interior.as_mut().unwrap();
        i.principal_point_px = Some([pp_true[0] + 6.0, pp_true[1] - 4.0]);
        let ext = file.exterior.as_mut().unwrap();
        ext.position = [ext.position[0] + 2.0, ext.position[1] - 1.5, ext.position[2] + 1.0];
        ext.angles_deg = [ext.angles_deg[0] + 0.2, ext.angles_deg[1] - 0.1, ext.angles_deg[2] + 0.3];
        file
    };
    let gcp_set = |truth: &Camera, crs: &str, height: &dyn Fn(usize) -> f64, name: &str| {
        let mut csv = String::from("id,col,row,x,y,z\n");
        let mut k = 0;
        for j in 0..3 {
            for i in 0..4 {
                let (c, r) = (40.0 + 173.0 * i as f64, 40.0 + 160.0 * j as f64);
                let z = height(k);
                let (x, y) = gcm_ortho::camera::locate(truth.model(), c, r, z, 1e-9).unwrap();
                let noise = [0.03, -0.02, 0.01, -0.03][k % 4];
                csv += &format!("{k},{},{},{x},{y},{z}\n", c + noise, r - noise);
                k += 1;
            }
        }
        let file = dir.path().join(format!("{name}.csv"));
        std::fs::write(&file, csv).unwrap();
        std::fs::write(dir.path().join(format!("{name}.prj")), crs).unwrap();
        gcm_ortho::camera::gcp::read(&file, &sc.scan).map(|g| (g, file)).unwrap()
    };
    let crs = truth_file.crs.clone();
    let (gcps, file) = gcp_set(&truth, &crs, &|k| 150.0 + 20.0 * (k % 4) as f64 + 5.0 * (k / 4) as f64, "spread");
    let mut cam = perturb(truth_file.clone()).build(&sc.camera).unwrap();
    // The pose alone cannot take up the calibration's error.
    let mut pose_only = perturb(truth_file.clone()).build(&sc.camera).unwrap();
    let pose_fit = refine(&mut pose_only, &gcps, BiasModel::Auto, 50.0, &file).unwrap();
    let fit = refine(&mut cam, &gcps, BiasModel::Interior, 1.0, &file).unwrap();
    assert_eq!(fit.method, "resection with interior");
    assert!(fit.rms_after < 0.05 && pose_fit.rms_after > 4.0 * fit.rms_after, "{fit:?} vs pose only {pose_fit:?}");
    let gcm_ortho::camera::file::Sensor::Frame(f) = &cam.sensor else { panic!("a frame camera") };
    assert!((f.focal_mm / f_true - 1.0).abs() < 1e-3, "focal {} vs {f_true}", f.focal_mm);
    let pp = f.interior.principal_point_px();
    assert!((pp[0] - pp_true[0]).hypot(pp[1] - pp_true[1]) < 0.5, "{pp:?} vs {pp_true:?}");
    let worst = worst_over_frame(&truth, &cam);
    assert!(worst < 0.15, "{worst} px from the true camera");
    // Straight down over GCPs at one height: refused, naming the file.
    let mut nadir_file = truth_file.clone();
    let ext = nadir_file.exterior.as_mut().unwrap();
    ext.angles_deg = [0.0, 0.0, ext.angles_deg[2]];
    nadir_file.distortion = None;
    let nadir = nadir_file.clone().build(&sc.camera).unwrap();
    let (flat, flat_file) = gcp_set(&nadir, &crs, &|_| 150.0, "flat");
    let mut off = perturb(nadir_file).build(&sc.camera).unwrap();
    let e = refine(&mut off, &flat, BiasModel::Interior, 1.0, &flat_file).unwrap_err().to_string();
    assert!(e.contains("flat.csv") && e.contains("focal length"), "{e}");
}

/// A film camera refined by GCPs keeps its calibrated format on the scan:
/// the scanner's margins and the fiducial marks stay out of the
/// orthophoto, which covers what the run without GCPs covers.
#[test]
fn a_film_camera_refined_by_gcps_keeps_its_format() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = common::scene(&d.join("film"), 600, |_| {});
    // The scene's checkpoints (id, X, Y, Z, col, row) are exact GCPs.
    let gcps = d.join("gcps.csv");
    std::fs::copy(sc.scan.parent().unwrap().join("checkpoints.csv"), &gcps).unwrap();
    let crs = gcm_ortho::geodesy::Crs::parse("EPSG:32631", Path::new("")).unwrap();
    std::fs::write(gcps.with_extension("prj"), crs.proj4()).unwrap();
    let ortho = |extra: &[&str], out: &Path| {
        let r = run(&[&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(out)][..], extra].concat());
        assert!(r.status.success(), "{extra:?}: {}", String::from_utf8_lossy(&r.stderr));
        let (bytes, info) = common::whole_image(out);
        ((info.width, info.height), bytes.iter().filter(|&&v| v != 0).count())
    };
    let (plain, with) = (ortho(&[], &d.join("plain.tif")), ortho(&["--gcps", s(&gcps)], &d.join("gcps.tif")));
    assert_eq!(with.0, plain.0, "the grid of the footprint within the format");
    let (a, b) = (plain.1 as f64, with.1 as f64);
    assert!((b - a).abs() < 0.005 * a, "pixels with a value: {b} with GCPs, {a} without");
}
