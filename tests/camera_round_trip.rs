//! A synthetic drone frame whose camera we know, written by `cameras` in
//! each form (ours, Orthority's, OpenSfM's) and read back: the camera
//! images every point where our own file's does, and the orthophoto of a
//! coordinate image is the same.

mod common;

use common::{coordinate_image, coordinate_map_difference, run, s, scene};
use gcm_ortho::camera::file::Camera;
use gcm_ortho::synth::{CameraKind, Relief};
use std::path::{Path, PathBuf};

const W: u32 = 600;
const H: u32 = 400;

/// The oblique drone frame (Brown distortion, 25° off nadir) over buildings.
fn drone(dir: &Path) -> gcm_ortho::synth::SynthReport {
    scene(&dir.join("scene"), W, |o| {
        o.height = H;
        o.camera = CameraKind::Drone;
        o.relief = Relief::Urban;
        o.dem_posting = 1.0;
        o.scale = 12_000.0;
        o.off_nadir_deg = 25.0;
        o.kappa_deg = 17.0;
    })
}

/// `cameras --to target` of the scene's camera for `image` into `out`; the
/// arguments that give rectify the written camera.
fn convert(camera: &Path, image: &Path, out: &Path, target: &str) -> Vec<String> {
    std::fs::create_dir_all(out).unwrap();
    let r = run(&["cameras", "--camera", s(camera), s(image), "--out-dir", s(out), "--to", target]);
    assert!(r.status.success(), "{target}: {}", String::from_utf8_lossy(&r.stderr));
    let table = String::from_utf8_lossy(&r.stdout);
    let name = image.file_name().unwrap().to_string_lossy();
    assert!(table.contains(&*name) && table.contains(&format!("{W}x{H}")) && table.contains("brown"), "{table}");
    let p = |n: &str| out.join(n).to_string_lossy().into_owned();
    match target {
        "toml" => vec!["--camera".into(), p("scan.toml")],
        "orthority" => vec!["--camera".into(), p("int_param.yaml"), "--exterior".into(), p("ext_param.csv")],
        _ => vec!["--camera".into(), p("reconstruction.json")],
    }
}

fn camera_of(image: &Path, args: &[String]) -> Camera {
    let exterior = args.get(3).map(PathBuf::from);
    Camera::read_for(image, Path::new(&args[1]), exterior.as_deref(), None).unwrap_or_else(|e| panic!("{args:?}: {e}"))
}

#[test]
fn every_written_form_reads_back_as_the_same_camera() {
    let dir = tempfile::tempdir().unwrap();
    let sc = drone(dir.path());
    let truth = Camera::read(&sc.camera).unwrap();
    let image = sc.scan.clone();
    for target in ["toml", "orthority", "opensfm"] {
        let args = convert(&sc.camera, &image, &dir.path().join(target), target);
        let cam = camera_of(&image, &args);
        // Points over the whole frame, from the ground to roof height.
        let mut worst = 0f64;
        for j in 0..=8 {
            for i in 0..=12 {
                let (c, r) = (i as f64 * W as f64 / 12.0, j as f64 * H as f64 / 8.0);
                let z = 150.0 + 10.0 * ((i + j) % 4) as f64;
                let (x, y) = gcm_ortho::camera::locate(truth.model(), c, r, z, 1e-9).expect("the frame sees the ground");
                let (x2, y2) = if cam.crs == truth.crs { (x, y) } else { panic!("{target}: read back in {:?}, not {:?}", cam.crs, truth.crs) };
                let (c2, r2) = cam.model().project(x2, y2, z).expect("imaged");
                worst = worst.max((c2 - c).hypot(r2 - r));
            }
        }
        assert!(worst < 1e-6, "{target}: {worst} px from our own camera");
    }
}

#[test]
fn the_orthophoto_from_each_written_form_is_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let sc = drone(dir.path());
    // The coordinate image in the scan's place, under the scan's name.
    let coords = dir.path().join("coords").join("scan.tif");
    std::fs::create_dir_all(coords.parent().unwrap()).unwrap();
    coordinate_image(&coords, W, H);
    // The exact model at every pixel: no refinement decision to differ.
    let exact = ["--sparsity", "1", "--corrections", "cell", "--memory", "1G", "--nodata", "-1", "--compress", "none", "--quiet"];
    let rectify = |camera_args: &[String], out: &Path, like: Option<&Path>| {
        let mut a: Vec<String> = ["rectify", "--image", s(&coords), "--dem", s(&sc.dem)].iter().map(|x| x.to_string()).collect();
        a.extend(camera_args.iter().cloned());
        a.extend(exact.iter().map(|x| x.to_string()));
        if let Some(l) = like {
            a.extend(["--like".to_string(), s(l).to_string()]);
        }
        a.extend(["-o".to_string(), s(out).to_string()]);
        let refs: Vec<&str> = a.iter().map(String::as_str).collect();
        let r = run(&refs);
        assert!(r.status.success(), "{a:?}: {}", String::from_utf8_lossy(&r.stderr));
    };
    let reference = dir.path().join("ours.tif");
    rectify(&["--camera".to_string(), s(&sc.camera).to_string()], &reference, None);
    for target in ["toml", "orthority", "opensfm"] {
        let args = convert(&sc.camera, &coords, &dir.path().join(target), target);
        let out = dir.path().join(format!("{target}.tif"));
        rectify(&args, &out, Some(&reference));
        let d = coordinate_map_difference(&reference, &out, W, H);
        assert!(d.pixels > 50_000, "{target}: {} pixels compared", d.pixels);
        // Float32 positions below 1000 are good to 6e-5 px.
        assert!(d.max < 2e-4, "{target}: max {} px, offset {:?}", d.max, d.offset);
    }
}

#[test]
fn what_other_forms_cannot_hold_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("film"), 300, |_| {});
    for target in ["orthority", "opensfm"] {
        let out = dir.path().join(target);
        std::fs::create_dir_all(&out).unwrap();
        let r = run(&["cameras", "--camera", s(&sc.camera), s(&sc.scan), "--out-dir", s(&out), "--to", target]);
        let e = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && e.contains("interior") && e.contains("fiducial"), "{target}: {e}");
        assert_eq!(std::fs::read_dir(&out).unwrap().count(), 0, "{target}: nothing written");
    }
    // Never over an input: the camera file is scan.toml, where the
    // image's camera would be written.
    let own = sc.scan.with_extension("toml");
    std::fs::copy(&sc.camera, &own).unwrap();
    let before = std::fs::read(&own).unwrap();
    let r = run(&["cameras", "--camera", s(&own), s(&sc.scan), "--out-dir", s(own.parent().unwrap()), "--to", "toml"]);
    let e = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && e.contains("refusing to write over an input"), "{e}");
    assert_eq!(std::fs::read(&own).unwrap(), before);
}

#[test]
fn a_block_given_by_orthority_files_runs_in_batch() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = drone(d);
    std::fs::create_dir_all(d.join("scans")).unwrap();
    std::fs::copy(&sc.scan, d.join("scans/DJI_0001.tif")).unwrap();
    let oty = d.join("oty");
    convert(&sc.camera, &d.join("scans/DJI_0001.tif"), &oty, "orthority");
    // Names as exports write them: with the extension, a folder in front.
    let csv = std::fs::read_to_string(oty.join("ext_param.csv")).unwrap().replace("DJI_0001.tif,", "images/DJI_0001.tif,");
    std::fs::write(oty.join("ext_param.csv"), csv).unwrap();
    std::fs::write(
        d.join("manifest.toml"),
        "[defaults]\ndem = \"scene/dem.tif\"\noutput_dir = \"ortho\"\n\n[block]\ninterior = \"oty/int_param.yaml\"\nexterior = \"oty/ext_param.csv\"\nimages = \"scans/{name}.tif\"\n",
    )
    .unwrap();
    let o = run(&["batch", s(&d.join("manifest.toml")), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let single = d.join("single.tif");
    let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(&single), "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let a = gcm_ortho::study::compare::read_grey(&single, 0.0).unwrap();
    let b = gcm_ortho::study::compare::read_grey(&d.join("ortho/DJI_0001.tif"), 0.0).unwrap();
    assert_eq!(a.v.len(), b.v.len(), "one grid");
    let diff = a.v.iter().zip(&b.v).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
    assert!(diff <= 1.0, "the block's orthophoto differs by {diff}");
}
