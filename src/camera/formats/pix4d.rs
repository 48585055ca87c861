//! Pix4Dmapper's calibrated parameters (its project's `1_initial/params`):
//!
//! * `<project>_calibrated_camera_parameters.txt` — for each image a block
//!   of ten lines: `name width height`, K (3 lines), radial R1 R2 R3,
//!   tangential T1 T2, the centre t, the rotation R (3 lines), the camera
//!   being `m = K [R | −Rt] X`. R maps the world to OpenCV's camera axes
//!   (x right, y down, looking along +z); t and X are in the project's
//!   local frame, the output CRS less `<project>_offset.xyz` (read from
//!   beside the file). The lens is OpenCV's Brown model with k1–k3 = R1–R3
//!   and p1, p2 = T1, T2 (Pix4D's own tools map them so), the principal
//!   point from the top-left corner of the top-left pixel (Pix4D's OPF
//!   specification), as ours is.
//! * `<project>_pix4d_calibrated_internal_camera_parameters.cam` — the same
//!   lens in mm on the sensor width its header names: pixels from the
//!   image's own width.
//! * `<project>_calibrated_external_camera_parameters.txt` is the exterior
//!   CSV (`imageName X Y Z Omega Phi Kappa`, absolute coordinates), read by
//!   [`super::orthority`].

use super::{brown_section, distinct_lenses, Imported, Lens, Pose};
use crate::camera::distortion::Brown;
use crate::error::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use std::path::{Path, PathBuf};

/// The header Pix4D writes above the blocks of the calibrated camera
/// parameters.
const CAMERA_MODEL_LINE: &str = "camera model m = K [R|-Rt] X";

/// Is `text` a calibrated camera parameters file? By its header, else by
/// its first block's shape.
#[must_use]
pub fn looks_like_calibrated(text: &str) -> bool {
    if text.lines().take(12).any(|l| l.trim().trim_start_matches('#').trim() == CAMERA_MODEL_LINE) {
        return true;
    }
    let lines: Vec<Vec<&str>> = data_lines(text).take(10).map(|(_, l)| l.split_whitespace().collect()).collect();
    let counts: Vec<usize> = lines.iter().map(Vec::len).collect();
    counts == [3, 3, 3, 3, 3, 2, 3, 3, 3, 3] && lines[3] == ["0", "0", "1"]
}

/// Is `text` Pix4D's internal camera parameters in mm (`.cam`)?
#[must_use]
pub fn looks_like_cam(text: &str) -> bool {
    text.trim_start().starts_with("Pix4D camera calibration file")
}

/// Lines that are not blank and not a comment, numbered from 1.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().map(|(i, l)| (i + 1, l.trim())).filter(|(_, l)| !l.is_empty() && !l.starts_with('#') && !is_header(l))
}

/// The header lines of the calibrated camera parameters, which Pix4D
/// writes without a comment sign.
fn is_header(line: &str) -> bool {
    [
        "fileName imageWidth imageHeight",
        "camera matrix K",
        "radial distortion",
        "tangential distortion",
        "camera position t",
        "camera rotation R",
        "camera model m",
    ]
    .iter()
    .any(|h| line.starts_with(h))
}

/// The calibrated camera parameters: a lens and a pose for each image.
/// With `lenses_only` (the poses come from another file) the poses are
/// kept local and no offset is needed.
pub fn read_calibrated(path: &Path, text: &str, lenses_only: bool) -> Result<Imported> {
    let lines: Vec<(usize, &str)> = data_lines(text).collect();
    if lines.is_empty() || !lines.len().is_multiple_of(10) {
        return Err(Error::format(path, format!("{} lines of numbers: Pix4D's calibrated camera parameters come in blocks of ten", lines.len())));
    }
    let offset = if lenses_only { [0.0; 3] } else { offset_beside(path)? };
    let numbers = |(n, l): (usize, &str), count: usize, what: &str| -> Result<Vec<f64>> {
        let v: Vec<f64> = l.split_whitespace().map(str::parse::<f64>).collect::<std::result::Result<_, _>>().unwrap_or_default();
        if v.len() != count || v.iter().any(|x| !x.is_finite()) {
            return Err(Error::format(path, format!("line {n}: expected {count} numbers ({what})")));
        }
        Ok(v)
    };
    let mut lenses = Vec::new();
    let mut poses = Vec::new();
    for block in lines.chunks_exact(10) {
        let (n, head) = block[0];
        let parts: Vec<&str> = head.split_whitespace().collect();
        let size = match parts.as_slice() {
            [_, w, h] => w.parse::<u32>().ok().zip(h.parse::<u32>().ok()).filter(|&(w, h)| w > 0 && h > 0),
            _ => None,
        }
        .ok_or_else(|| Error::format(path, format!("line {n}: expected 'imageName imageWidth imageHeight'")))?;
        let k: Vec<Vec<f64>> = block[1..4].iter().map(|&l| numbers(l, 3, "a row of K")).collect::<Result<_>>()?;
        if k[0][1] != 0.0 || k[1][0] != 0.0 || k[2] != [0.0, 0.0, 1.0] || k[0][0] <= 0.0 || k[1][1] <= 0.0 {
            return Err(Error::format(path, format!("line {}: K is not [f 0 cx; 0 f cy; 0 0 1]", block[1].0)));
        }
        let radial = numbers(block[4], 3, "R1 R2 R3")?;
        let tangential = numbers(block[5], 2, "T1 T2")?;
        let t = numbers(block[6], 3, "the camera position")?;
        let rows: Vec<Vec<f64>> = block[7..10].iter().map(|&l| numbers(l, 3, "a row of R")).collect::<Result<_>>()?;
        let w2c = Matrix3::from_fn(|i, j| rows[i][j]);
        if (w2c * w2c.transpose() - Matrix3::identity()).abs().max() > 1e-6 || w2c.determinant() < 0.0 {
            return Err(Error::format(path, format!("line {}: R is not a rotation", block[7].0)));
        }
        let brown = Brown { k1: radial[0], k2: radial[1], k3: radial[2], p1: tangential[0], p2: tangential[1] };
        lenses.push(Lens {
            size: [size.0, size.1],
            focal_px: [k[0][0], k[1][1]],
            principal_point_px: [k[0][2], k[1][2]],
            focal_mm: None,
            distortion: brown_section(brown),
            affinity_skew_px: None,
        });
        // Photo axes (x right, y up, z back) are OpenCV's with y and z turned.
        let r = w2c.transpose() * Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
        poses.push(Pose {
            name: parts[0].to_string(),
            camera: None,
            position: [t[0] + offset[0], t[1] + offset[1], t[2] + offset[2]],
            r,
            origin: format!("{}:{n}", path.display()),
        });
    }
    let (unique, ids) = distinct_lenses(&lenses);
    let lens_of_image = poses.iter().zip(&ids).map(|(p, id)| (p.name.clone(), id.clone())).collect();
    for (p, id) in poses.iter_mut().zip(ids) {
        p.camera = Some(id);
    }
    Ok(Imported { lenses: unique, poses: if lenses_only { Vec::new() } else { poses }, lens_of_image, ..Default::default() })
}

/// The project's offset (`<project>_offset.xyz`, "X Y Z") beside the
/// calibrated camera parameters: the one of the same project, else the
/// only one in the folder.
fn offset_beside(path: &Path) -> Result<[f64; 3]> {
    let folder = path.parent().unwrap_or(Path::new("."));
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    let own: Option<PathBuf> = name.strip_suffix("calibrated_camera_parameters.txt").map(|p| folder.join(format!("{p}offset.xyz")));
    let found = match own.filter(|p| p.is_file()) {
        Some(p) => Some(p),
        None => {
            let all: Vec<PathBuf> = std::fs::read_dir(folder)
                .map(|d| d.flatten().map(|e| e.path()).filter(|p| p.to_str().is_some_and(|s| s.ends_with("_offset.xyz"))).collect())
                .unwrap_or_default();
            match all.as_slice() {
                [one] => Some(one.clone()),
                _ => None,
            }
        }
    };
    let Some(xyz) = found else {
        return Err(Error::format(
            path,
            "holds positions relative to the project's offset, and no <project>_offset.xyz is beside it: put it there, or give the poses with ‹exterior› <project>_calibrated_external_camera_parameters.txt",
        ));
    };
    let text = crate::io::bounded_read::read_text_bounded(&xyz, "a Pix4D offset", 4096)?;
    let v: Vec<f64> = text.split_whitespace().map(str::parse::<f64>).collect::<std::result::Result<_, _>>().unwrap_or_default();
    match v.as_slice() {
        [x, y, z] if v.iter().all(|a| a.is_finite()) => Ok([*x, *y, *z]),
        _ => Err(Error::format(&xyz, "expected three numbers, the project's offset X Y Z")),
    }
}

/// The `.cam` file's lens on images of `size` pixels: F, Px, Py in mm on
/// the sensor width of its header, scaled by the image's width.
pub fn read_cam(path: &Path, text: &str, size: [u32; 2]) -> Result<Imported> {
    let mut sensor: Option<[f64; 2]> = None;
    let mut values = std::collections::HashMap::new();
    for (i, line) in text.lines().enumerate() {
        let l = line.trim();
        if let Some(rest) = l.strip_prefix('#') {
            // "#Focal Length mm assuming a sensor width of 17.49x13.12mm"
            if let Some(dims) = rest.split("sensor width of").nth(1) {
                let dims = dims.trim().trim_end_matches("mm");
                let wh: Vec<f64> = dims.split('x').filter_map(|d| d.trim().parse().ok()).collect();
                if let [w, h] = wh.as_slice() {
                    sensor = Some([*w, *h]);
                }
            }
            continue;
        }
        let parts: Vec<&str> = l.split_whitespace().collect();
        if let [key @ ("F" | "Px" | "Py" | "K1" | "K2" | "K3" | "T1" | "T2"), v] = parts.as_slice() {
            let v: f64 = v.parse().ok().filter(|x: &f64| x.is_finite()).ok_or_else(|| Error::format(path, format!("line {}: {key} is not a number", i + 1)))?;
            values.insert(*key, v);
        }
    }
    let [w_mm, _] = sensor.filter(|s| s[0] > 0.0).ok_or_else(|| Error::format(path, "no 'sensor width of W x H mm' in its header"))?;
    let get = |k: &str| values.get(k).copied().ok_or_else(|| Error::config(path, k, "missing"));
    let s = f64::from(size[0]) / w_mm;
    let brown = Brown { k1: get("K1")?, k2: get("K2")?, k3: get("K3")?, p1: get("T1")?, p2: get("T2")? };
    let f = get("F")?;
    let lens = Lens {
        size,
        focal_px: [f * s, f * s],
        principal_point_px: [get("Px")? * s, get("Py")? * s],
        focal_mm: Some(f),
        distortion: brown_section(brown),
        affinity_skew_px: None,
    };
    Ok(Imported { lenses: vec![("camera 1".into(), lens)], ..Default::default() })
}
