//! The Brown–Conrady lens model against OpenCV's own `projectPoints`: a
//! camera file's k1, k2, k3, p1, p2 mean what they mean to OpenCV (x right,
//! y down, normalised by the focal length), so a calibration made with
//! OpenCV, or a tool built on it, is used as it is.

mod common;

use gcm_ortho::camera::atmosphere::Refraction;
use gcm_ortho::camera::distortion::{Brown, Distortion};
use gcm_ortho::camera::interior::InteriorOrientation;
use gcm_ortho::camera::rotation::AngleConvention;
use gcm_ortho::camera::{FrameCamera, SensorModel};
use nalgebra::{Matrix3, Vector3};
use std::io::Write;
use std::process::{Command, Stdio};

/// OpenCV's projection of `points` (ground, metres) through a camera at
/// `centre` whose matrix `r` turns camera axes (x right, y up, looking
/// down −z) into ground axes; `None` where Python has no OpenCV.
fn opencv_project(points: &[[f64; 3]], centre: Vector3<f64>, r: Matrix3<f64>, f_px: f64, pp: [f64; 2], b: &Brown) -> Option<Vec<[f64; 2]>> {
    const SCRIPT: &str = r#"
import json, sys
import numpy as np
import cv2
d = json.load(sys.stdin)
# OpenCV's camera: x right, y down, z forward: ours with y and z turned.
to_cv = np.diag([1.0, -1.0, -1.0]) @ np.array(d["r"]).T
rvec, _ = cv2.Rodrigues(to_cv)
tvec = -to_cv @ np.array(d["centre"])
k = np.array([[d["f"], 0.0, d["pp"][0]], [0.0, d["f"], d["pp"][1]], [0.0, 0.0, 1.0]])
img, _ = cv2.projectPoints(np.array(d["points"], dtype=np.float64).reshape(-1, 1, 3), rvec, tvec, k, np.array(d["dist"]))
print(json.dumps(img.reshape(-1, 2).tolist()))
"#;
    let rows: Vec<[f64; 3]> = (0..3).map(|i| [r[(i, 0)], r[(i, 1)], r[(i, 2)]]).collect();
    let input = serde_json::json!({
        "r": rows, "centre": [centre.x, centre.y, centre.z], "f": f_px, "pp": pp,
        "dist": [b.k1, b.k2, b.p1, b.p2, b.k3], "points": points,
    });
    let python = common::python_with("cv2", "python3-opencv")?;
    let mut child = Command::new(python).args(["-c", SCRIPT]).stdin(Stdio::piped()).stdout(Stdio::piped()).spawn().expect("python3 runs");
    child.stdin.take().unwrap().write_all(input.to_string().as_bytes()).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "OpenCV's projectPoints failed");
    Some(serde_json::from_slice(&out.stdout).expect("a list of points"))
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
        // Ground points seen all over the frame, corners included, on
        // ground between 0 and 30 m.
        let mut points = Vec::new();
        for j in 0..=12 {
            for i in 0..=16 {
                let (c, row) = (i as f64 * 250.0, j as f64 * 250.0);
                let z = ((i * 7 + j * 3) % 5) as f64 * 7.5;
                let (x, y) = cam.locate_approx(c, row, z).unwrap();
                points.push([x, y, z]);
            }
        }
        let Some(theirs) = opencv_project(&points, centre, r, f / ps, pp, &b) else { return };
        let mut worst = 0.0f64;
        let mut moved = 0.0f64;
        for (p, t) in points.iter().zip(&theirs) {
            let (c, row) = cam.project(p[0], p[1], p[2]).expect("imaged");
            worst = worst.max((c - t[0]).abs()).max((row - t[1]).abs());
            let ideal = FrameCamera::new(f, centre, r, interior.clone(), Distortion::None, Refraction::None, false).project(p[0], p[1], p[2]).unwrap();
            moved = moved.max((c - ideal.0).hypot(row - ideal.1));
        }
        assert!(moved > 20.0, "the distortion moves corners by {moved} px: too weak a test");
        assert!(worst < 1e-6, "{b:?}: {worst} px from OpenCV");
    }
}
