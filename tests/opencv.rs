//! The lens models against OpenCV's own `projectPoints` and
//! `fisheye.projectPoints`: a camera file's coefficients mean what they
//! mean to OpenCV (x right, y down, normalised by the focal length), so a
//! calibration made with OpenCV, or a tool built on it, is used as it is.

mod common;

use gcm_ortho::camera::atmosphere::Refraction;
use gcm_ortho::camera::distortion::{Brown, Distortion, Fisheye, OpenCv};
use gcm_ortho::camera::interior::InteriorOrientation;
use gcm_ortho::camera::rotation::AngleConvention;
use gcm_ortho::camera::{FrameCamera, SensorModel};
use nalgebra::{Matrix3, Vector3};
use std::io::Write;
use std::process::{Command, Stdio};

/// Which OpenCV projection a comparison calls.
#[derive(Clone, Copy)]
enum Kind {
    /// `cv2.projectPoints` with the coefficients in OpenCV's order.
    Standard,
    /// `cv2.fisheye.projectPoints` with k1–k4.
    Fisheye,
}

/// OpenCV's projection of `points` (ground, metres) through a camera at
/// `centre` whose matrix `r` turns camera axes (x right, y up, looking
/// down −z) into ground axes, focal lengths `(fx, fy)` and principal point
/// `pp` in pixels; `None` where Python has no OpenCV.
fn opencv_project(
    points: &[[f64; 3]],
    centre: Vector3<f64>,
    r: Matrix3<f64>,
    (fx, fy): (f64, f64),
    pp: [f64; 2],
    kind: Kind,
    dist: &[f64],
) -> Option<Vec<[f64; 2]>> {
    const SCRIPT: &str = r#"
import json, sys
import numpy as np
import cv2
d = json.load(sys.stdin)
# OpenCV's camera: x right, y down, z forward: ours with y and z turned.
to_cv = np.diag([1.0, -1.0, -1.0]) @ np.array(d["r"]).T
rvec, _ = cv2.Rodrigues(to_cv)
tvec = -to_cv @ np.array(d["centre"])
k = np.array([[d["fx"], 0.0, d["pp"][0]], [0.0, d["fy"], d["pp"][1]], [0.0, 0.0, 1.0]])
pts = np.array(d["points"], dtype=np.float64).reshape(-1, 1, 3)
if d["kind"] == "fisheye":
    img, _ = cv2.fisheye.projectPoints(pts, rvec.reshape(1, 1, 3), tvec.reshape(1, 1, 3), k, np.array(d["dist"]))
else:
    img, _ = cv2.projectPoints(pts, rvec, tvec, k, np.array(d["dist"]))
print(json.dumps(img.reshape(-1, 2).tolist()))
"#;
    let rows: Vec<[f64; 3]> = (0..3).map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]).collect();
    let kind = match kind {
        Kind::Standard => "standard",
        Kind::Fisheye => "fisheye",
    };
    let input = serde_json::json!({
        "r": rows, "centre": [centre.x, centre.y, centre.z], "fx": fx, "fy": fy, "pp": pp,
        "kind": kind, "dist": dist, "points": points,
    });
    let python = common::python_with("cv2", "python3-opencv")?;
    let mut child = Command::new(python).args(["-c", SCRIPT]).stdin(Stdio::piped()).stdout(Stdio::piped()).spawn().expect("python3 runs");
    child.stdin.take().unwrap().write_all(input.to_string().as_bytes()).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "OpenCV's projectPoints failed");
    Some(serde_json::from_slice(&out.stdout).expect("a list of points"))
}

/// Ground points seen on a lattice over a `w`×`h` image, every `step`
/// pixels, corners included, on ground between 0 and 30 m.
fn seen_points(cam: &FrameCamera, (w, h): (u32, u32), step: u32) -> Vec<[f64; 3]> {
    let mut points = Vec::new();
    for j in 0..=h / step {
        for i in 0..=w / step {
            let z = ((i * 7 + j * 3) % 5) as f64 * 7.5;
            let (x, y) = gcm_ortho::camera::locate(cam, (i * step) as f64, (j * step) as f64, z, 1e-6).expect("the lattice is imaged");
            points.push([x, y, z]);
        }
    }
    points
}

/// The most any point lies from OpenCV's projection (px), after checking
/// that the lens moves some point by more than `min_moved` px.
fn worst_vs_opencv(cam: &FrameCamera, ideal: &FrameCamera, points: &[[f64; 3]], theirs: &[[f64; 2]], min_moved: f64) -> f64 {
    let mut worst = 0.0f64;
    let mut moved = 0.0f64;
    for (p, t) in points.iter().zip(theirs) {
        let (c, row) = cam.project(p[0], p[1], p[2]).expect("imaged");
        worst = worst.max((c - t[0]).abs()).max((row - t[1]).abs());
        let i = ideal.project(p[0], p[1], p[2]).unwrap();
        moved = moved.max((c - i.0).hypot(row - i.1));
    }
    assert!(moved > min_moved, "the distortion moves points by {moved} px: too weak a test");
    worst
}

#[test]
fn opencvs_full_model_with_unequal_focal_lengths_is_opencvs() {
    // fx ≠ fy (pixels 2.4 × 2.45 µm), rational radial terms, tangential
    // and thin-prism terms of both signs: each term moves corner points by
    // pixels, so a slip in any of them fails.
    let (f, sides, pp) = (8.8, [0.0024, 0.00245], [2011.3, 1489.6]);
    let interior = InteriorOrientation::digital_sides(sides, pp).unwrap();
    let r = AngleConvention::OmegaPhiKappa.matrix([4.0f64.to_radians(), -9.0f64.to_radians(), 27.0f64.to_radians()]);
    let centre = Vector3::new(120.0, -40.0, 95.0);
    let o =
        OpenCv { k1: -0.11, k2: 0.035, k3: -0.004, k4: 0.02, k5: -0.005, k6: 0.012, p1: 4.0e-4, p2: -2.5e-4, s1: 1.5e-3, s2: -1.6e-3, s3: -1.1e-3, s4: 1.4e-3 };
    let cam = FrameCamera::new(f, centre, r, interior.clone(), Distortion::OpenCv(o), Refraction::None, false);
    let ideal = FrameCamera::new(f, centre, r, interior, Distortion::None, Refraction::None, false);
    let points = seen_points(&cam, (4000, 3000), 250);
    let Some(theirs) = opencv_project(&points, centre, r, (f / sides[0], f / sides[1]), pp, Kind::Standard, &o.opencv_order()) else { return };
    let worst = worst_vs_opencv(&cam, &ideal, &points, &theirs, 20.0);
    assert!(worst < 1e-6, "{worst} px from OpenCV");
    // Each extra term on its own matters to more than a pixel at the corners.
    for term in 5..12 {
        let mut c = o.opencv_order();
        c[term] = 0.0;
        let Some(without) = opencv_project(&points, centre, r, (f / sides[0], f / sides[1]), pp, Kind::Standard, &c) else { return };
        let most = theirs.iter().zip(&without).map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1])).fold(0.0, f64::max);
        assert!(most > 1.0, "term {term} of OpenCV's order moves points by only {most} px");
    }
}

#[test]
fn fisheye_is_opencvs() {
    // A 2.8 mm fisheye on a 4000 × 3000 sensor of 1.55 µm pixels: corners
    // 66° off the axis, where the model is hundreds of pixels from a
    // pinhole camera's.
    let (f, ps, pp) = (2.8, 0.00155, [1995.2, 1507.9]);
    let interior = InteriorOrientation::digital(ps, pp).unwrap();
    let r = AngleConvention::OmegaPhiKappa.matrix([-6.0f64.to_radians(), 3.0f64.to_radians(), -121.0f64.to_radians()]);
    let centre = Vector3::new(-300.0, 850.0, 60.0);
    let k = Fisheye { k1: 0.052, k2: -0.013, k3: 0.0021, k4: -3.0e-4 };
    let cam = FrameCamera::new(f, centre, r, interior.clone(), Distortion::Fisheye(k), Refraction::None, false);
    let ideal = FrameCamera::new(f, centre, r, interior, Distortion::None, Refraction::None, false);
    let points = seen_points(&cam, (4000, 3000), 250);
    let Some(theirs) = opencv_project(&points, centre, r, (f / ps, f / ps), pp, Kind::Fisheye, &[k.k1, k.k2, k.k3, k.k4]) else { return };
    let worst = worst_vs_opencv(&cam, &ideal, &points, &theirs, 300.0);
    assert!(worst < 1e-6, "{worst} px from OpenCV's fisheye");
}

#[test]
fn brown_distortion_is_opencvs() {
    // A drone-like frame: 4000 × 3000 px of 2.4 µm, 8.8 mm lens, principal
    // point off centre, turned and tilted; strong barrel distortion with
    // tangential terms of both signs (a sign slip in p1 or p2 moves
    // corner points by pixels).
    let (ps, f, pp) = (0.0024, 8.8, [2011.3, 1489.6]);
    let interior = InteriorOrientation::digital(ps, pp).unwrap();
    let r = AngleConvention::OmegaPhiKappa.matrix([4.0f64.to_radians(), -9.0f64.to_radians(), 27.0f64.to_radians()]);
    let centre = Vector3::new(120.0, -40.0, 95.0);
    for b in [Brown { k1: -0.11, k2: 0.035, k3: -0.004, p1: 4.0e-4, p2: -2.5e-4 }, Brown { k1: 0.02, k2: -0.01, k3: 0.0, p1: -1.2e-3, p2: 9.0e-4 }] {
        let cam = FrameCamera::new(f, centre, r, interior.clone(), Distortion::Brown(b), Refraction::None, false);
        let ideal = FrameCamera::new(f, centre, r, interior.clone(), Distortion::None, Refraction::None, false);
        let points = seen_points(&cam, (4000, 3000), 250);
        let Some(theirs) = opencv_project(&points, centre, r, (f / ps, f / ps), pp, Kind::Standard, &[b.k1, b.k2, b.p1, b.p2, b.k3]) else { return };
        let worst = worst_vs_opencv(&cam, &ideal, &points, &theirs, 20.0);
        assert!(worst < 1e-6, "{b:?}: {worst} px from OpenCV");
    }
}
