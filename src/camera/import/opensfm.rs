//! OpenSfM's `reconstruction.json` (cameras and shots) and `cameras.json`,
//! as OpenSfM defines them and OpenDroneMap writes them.
//!
//! Cameras: focal lengths and principal point normalised by the larger side
//! of the image, the principal point from its centre (OpenSfM's "normalised
//! image coordinates"); `perspective`, `simple_radial`, `radial`, `brown`
//! (OpenCV's Brown), `fisheye` (θ(1 + k1θ² + k2θ⁴)) and `fisheye_opencv`.
//!
//! Shots: `rotation` (angle-axis, world → camera, OpenCV's camera axes) and
//! `translation` t, the centre at −Rᵀt. Where the reconstruction is
//! OpenDroneMap's (its `opensfm/` folder: the file was georeferenced in
//! place, beside `reconstruction.topocentric.json` or in a project with
//! `odm_*` folders), positions are UTM coordinates less the UTM position of
//! `reference_lla`; elsewhere they are east-north-up metres on the tangent
//! plane at `reference_lla`, turned rigorously (through geocentric
//! coordinates) into that point's UTM zone, each camera's axes turned with
//! the grid at its position.

use super::{brown_section, fisheye_section, Imported, Lens, Pose};
use crate::camera::distortion::{Brown, Fisheye};
use crate::error::{Error, Result};
use crate::geodesy::ecef::{enu_axes, from_ecef, to_ecef};
use crate::geodesy::{utm_zone, GroundCrs};
use nalgebra::{Matrix3, Rotation3, Vector3};
use serde_json::Value;
use std::path::Path;

/// A `reconstruction.json` or a `cameras.json`.
pub fn read(path: &Path, text: &str) -> Result<Imported> {
    let v: Value = serde_json::from_str(text).map_err(|e| Error::format(path, format!("JSON: {e}")))?;
    let mut set = Imported::default();
    match &v {
        Value::Array(recs) => {
            let geocoded = written_by_odm(path);
            for (k, rec) in recs.iter().enumerate() {
                let at = |f: &str| format!("[{k}].{f}");
                if let Some(Value::Object(cams)) = rec.get("cameras") {
                    for (id, c) in cams {
                        if !set.lenses.iter().any(|(known, _)| known == strip_v2(id)) {
                            set.lenses.push((strip_v2(id).to_string(), lens(path, &at(&format!("cameras.{id}")), c)?));
                        }
                    }
                }
                let Some(Value::Object(shots)) = rec.get("shots") else { continue };
                if shots.is_empty() {
                    continue;
                }
                let reference = rec.get("reference_lla").ok_or_else(|| Error::config(path, at("reference_lla"), "missing"))?;
                let get = |k: &str| reference.get(k).and_then(Value::as_f64).filter(|x| x.is_finite());
                let (lat, lon, alt) = match (get("latitude"), get("longitude"), get("altitude")) {
                    (Some(a), Some(b), Some(c)) => (a, b, c),
                    _ => return Err(Error::config(path, at("reference_lla"), "needs latitude, longitude and altitude")),
                };
                let crs = utm_zone(lon, lat);
                let ground = GroundCrs::new(&crs).map_err(|m| Error::format(path, m))?;
                let text = crs.epsg().map(|c| format!("EPSG:{c}")).unwrap_or_else(|| crs.to_string());
                match &set.crs {
                    Some(other) if *other != text => {
                        return Err(Error::unsupported(path, format!("reconstructions in two UTM zones ({other}, {text})")));
                    }
                    _ => set.crs = Some(text),
                }
                let frame = Frame { lon, lat, alt, ground, geocoded };
                for (name, shot) in shots {
                    let field = |f: &str| at(&format!("shots.{name}.{f}"));
                    let three = |f: &str| -> Result<Vector3<f64>> {
                        let a = shot.get(f).and_then(Value::as_array).filter(|a| a.len() == 3);
                        let v: Option<Vec<f64>> = a.and_then(|a| a.iter().map(|x| x.as_f64().filter(|x| x.is_finite())).collect());
                        v.map(|v| Vector3::new(v[0], v[1], v[2])).ok_or_else(|| Error::config(path, field(f), "expected three numbers"))
                    };
                    let w2c = Rotation3::new(three("rotation")?).into_inner();
                    let centre = -(w2c.transpose() * three("translation")?);
                    // Photo axes (x right, y up, z back) = OpenCV's with y, z turned.
                    let r_local = w2c.transpose() * Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
                    let (position, r) =
                        frame.world(centre, r_local).ok_or_else(|| Error::format(path, format!("{}: outside the UTM zone", field("translation"))))?;
                    let camera = shot.get("camera").and_then(Value::as_str).map(|c| strip_v2(c).to_string());
                    set.poses.push(Pose { name: name.clone(), camera, position, r, origin: format!("{}: shot {name}", path.display()) });
                }
            }
        }
        Value::Object(cams) => {
            for (id, c) in cams {
                set.lenses.push((strip_v2(id).to_string(), lens(path, id, c)?));
            }
        }
        _ => return Err(Error::format(path, "expected an OpenSfM reconstruction (a list) or cameras (an object)")),
    }
    Ok(set)
}

/// OpenDroneMap names cameras "v2 make model w h type f"; shots say the same.
fn strip_v2(id: &str) -> &str {
    id.strip_prefix("v2 ").unwrap_or(id)
}

/// Is this reconstruction OpenDroneMap's georeferenced one (UTM less an
/// offset) rather than OpenSfM's topocentric frame?
fn written_by_odm(path: &Path) -> bool {
    let dir = path.parent().unwrap_or(Path::new("."));
    if dir.join("reconstruction.topocentric.json").is_file() {
        return true;
    }
    let in_opensfm = dir.file_name().is_some_and(|n| n == "opensfm");
    let project = dir.parent().unwrap_or(Path::new("."));
    in_opensfm && ["odm_dem", "odm_orthophoto", "odm_georeferencing", "odm_report"].iter().any(|d| project.join(d).is_dir())
}

/// How a reconstruction's coordinates become the world's.
struct Frame {
    lon: f64,
    lat: f64,
    alt: f64,
    ground: GroundCrs,
    geocoded: bool,
}

impl Frame {
    /// A camera's centre and rotation (photo → reconstruction axes) in the
    /// world: position, rotation photo → world.
    fn world(&self, c: Vector3<f64>, r: Matrix3<f64>) -> Option<([f64; 3], Matrix3<f64>)> {
        let (x0, y0) = self.ground.from_lonlat(self.lon, self.lat)?;
        if self.geocoded {
            return Some(([x0 + c.x, y0 + c.y, self.alt + c.z], r));
        }
        let at = |p: Vector3<f64>| -> Option<Vector3<f64>> {
            let (lon, lat, h) = from_ecef(to_ecef(self.lon, self.lat, self.alt) + enu_axes(self.lon, self.lat) * p);
            let (x, y) = self.ground.from_lonlat(lon, lat)?;
            Some(Vector3::new(x, y, h))
        };
        let here = at(c)?;
        // The reconstruction's axes at the camera, seen in the world: the
        // grid's convergence and the tangent plane's tilt, scale removed.
        let step = 1.0;
        let cols = [at(c + Vector3::x() * step)? - here, at(c + Vector3::y() * step)? - here, at(c + Vector3::z() * step)? - here];
        let m = Matrix3::from_columns(&cols) / step;
        let svd = m.svd(true, true);
        let turn = svd.u? * svd.v_t?;
        Some(([here.x, here.y, here.z], turn * r))
    }
}

/// One OpenSfM camera.
fn lens(path: &Path, at: &str, c: &Value) -> Result<Lens> {
    let field = |k: &str| format!("{at}.{k}");
    let Value::Object(m) = c else { return Err(Error::config(path, at, "expected the camera's parameters")) };
    let kind = m.get("projection_type").and_then(Value::as_str).ok_or_else(|| Error::config(path, field("projection_type"), "missing"))?;
    let allowed: &[&str] = match kind {
        "perspective" | "radial" => &["focal", "k1", "k2"],
        "simple_radial" => &["focal", "k1"],
        "brown" => &["focal_x", "focal_y", "c_x", "c_y", "k1", "k2", "k3", "p1", "p2"],
        "fisheye" => &["focal", "k1", "k2"],
        "fisheye_opencv" => &["focal_x", "focal_y", "c_x", "c_y", "k1", "k2", "k3", "k4"],
        other => {
            return Err(Error::unsupported(
                path,
                format!("{}: '{other}' (only perspective, simple_radial, radial, brown, fisheye, fisheye_opencv)", field("projection_type")),
            ))
        }
    };
    for k in m.keys() {
        let known = ["projection_type", "width", "height"].contains(&k.as_str()) || allowed.contains(&k.as_str()) || k.ends_with("_prior");
        if !known {
            return Err(Error::config(path, field(k), format!("unknown for a {kind} camera")));
        }
    }
    let num = |k: &str| -> Result<f64> {
        match m.get(k) {
            None => Ok(0.0),
            Some(v) => v.as_f64().filter(|x| x.is_finite()).ok_or_else(|| Error::config(path, field(k), "not a finite number")),
        }
    };
    let dim = |k: &str| -> Result<u32> {
        m.get(k)
            .and_then(Value::as_u64)
            .filter(|&n| n > 0 && n < 1 << 31)
            .map(|n| n as u32)
            .ok_or_else(|| Error::config(path, field(k), "expected a positive number of pixels"))
    };
    let (w, h) = (dim("width")?, dim("height")?);
    let long = w.max(h) as f64;
    let (fx, fy) = if allowed.contains(&"focal") { (num("focal")?, num("focal")?) } else { (num("focal_x")?, num("focal_y")?) };
    if !(fx > 0.0 && fy > 0.0) {
        return Err(Error::config(path, field(if allowed.contains(&"focal") { "focal" } else { "focal_x" }), "must be positive"));
    }
    let pp = [(w as f64 - 1.0) / 2.0 + long * num("c_x")?, (h as f64 - 1.0) / 2.0 + long * num("c_y")?];
    let distortion = match kind {
        "fisheye" | "fisheye_opencv" => fisheye_section(Fisheye { k1: num("k1")?, k2: num("k2")?, k3: num("k3")?, k4: num("k4")? }),
        _ => brown_section(Brown { k1: num("k1")?, k2: num("k2")?, k3: num("k3")?, p1: num("p1")?, p2: num("p2")? }),
    };
    Ok(Lens::from_opencv([w, h], [fx * long, fy * long], pp, distortion))
}
