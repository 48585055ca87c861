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
use crate::geodesy::ecef::{enu_axes, from_ecef, local_turn, to_ecef};
use crate::geodesy::{utm_zone, GroundCrs};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use serde_json::Value;
use std::path::Path;

/// A `reconstruction.json` or a `cameras.json`.
pub fn read(path: &Path, text: &str) -> Result<Imported> {
    let v = super::json::parse(text).map_err(|e| Error::format(path, format!("JSON: {e}")))?;
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
                let frame = Frame { lon, lat, alt, ground: &ground, geocoded };
                for (name, shot) in shots {
                    let field = |f: &str| at(&format!("shots.{name}.{f}"));
                    let three = |f: &str| -> Result<Vector3<f64>> {
                        let a = shot.get(f).and_then(Value::as_array).filter(|a| a.len() == 3);
                        let v: Option<Vec<f64>> = a.and_then(|a| a.iter().map(|x| x.as_f64().filter(|x| x.is_finite())).collect());
                        v.map(|v| Vector3::new(v[0], v[1], v[2])).ok_or_else(|| Error::config(path, field(f), "expected three numbers"))
                    };
                    let axis_angle = three("rotation")?;
                    if axis_angle.norm() > std::f64::consts::PI + 1e-9 {
                        set.warnings.push(format!(
                            "{}: {}: turns by {:.0}°: OpenSfM writes angle-axis vectors of π at most (radians); degrees?",
                            path.display(),
                            field("rotation"),
                            axis_angle.norm().to_degrees()
                        ));
                    }
                    let w2c = Rotation3::new(axis_angle).into_inner();
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
struct Frame<'a> {
    lon: f64,
    lat: f64,
    alt: f64,
    ground: &'a GroundCrs,
    geocoded: bool,
}

impl Frame<'_> {
    /// The world position (X, Y, h) of a point at `p` in the reconstruction.
    fn at(&self, p: Vector3<f64>) -> Option<Vector3<f64>> {
        let (lon, lat, h) = from_ecef(to_ecef(self.lon, self.lat, self.alt) + enu_axes(self.lon, self.lat) * p);
        let (x, y) = self.ground.lonlat_to_ground(lon, lat)?;
        Some(Vector3::new(x, y, h))
    }

    /// The reconstruction's axes at `c`, seen in the world: the grid's
    /// convergence and the tangent plane's tilt, scale removed.
    fn turn(&self, c: Vector3<f64>) -> Option<Matrix3<f64>> {
        local_turn(|p| self.at(p), c)
    }

    /// A camera's centre and rotation (photo → reconstruction axes) in the
    /// world: position, rotation photo → world.
    fn world(&self, c: Vector3<f64>, r: Matrix3<f64>) -> Option<([f64; 3], Matrix3<f64>)> {
        if self.geocoded {
            let (x0, y0) = self.ground.lonlat_to_ground(self.lon, self.lat)?;
            return Some(([x0 + c.x, y0 + c.y, self.alt + c.z], r));
        }
        let here = self.at(c)?;
        Some(([here.x, here.y, here.z], self.turn(c)? * r))
    }

    /// The inverse of [`Frame::world`] (topocentric frames only).
    fn local(&self, position: [f64; 3], r: Matrix3<f64>) -> Option<(Vector3<f64>, Matrix3<f64>)> {
        let (lon, lat) = self.ground.to_lonlat(position[0], position[1])?;
        let offset = to_ecef(lon, lat, position[2]) - to_ecef(self.lon, self.lat, self.alt);
        let c = enu_axes(self.lon, self.lat).transpose() * offset;
        Some((c, self.turn(c)?.transpose() * r))
    }
}

/// Lenses and poses (in `crs`) as an OpenSfM `reconstruction.json`: the
/// shots in east-north-up metres at the cameras' mean position, as OpenSfM
/// itself writes them; `cameras[k]` is the id of pose k's lens.
pub fn write(lenses: &[(String, Lens)], poses: &[Pose], cameras: &[String], crs: &GroundCrs, path: &Path) -> Result<String> {
    use serde_json::{json, Map};
    let mut cams = Map::new();
    for (id, l) in lenses {
        let [w, h] = l.size;
        let long = f64::from(w.max(h));
        let pp = l.opencv_pp();
        let c = [(pp[0] - (f64::from(w) - 1.0) / 2.0) / long, (pp[1] - (f64::from(h) - 1.0) / 2.0) / long];
        let (fx, fy) = (l.focal_px[0] / long, l.focal_px[1] / long);
        let d = &l.distortion;
        let cam = if let Some(k) = d.fisheye {
            json!({"projection_type": "fisheye_opencv", "width": w, "height": h, "focal_x": fx, "focal_y": fy, "c_x": c[0], "c_y": c[1],
                   "k1": k.k1, "k2": k.k2, "k3": k.k3, "k4": k.k4})
        } else if d.opencv.is_some() || d.radial_mm.is_some() || d.metashape.is_some() {
            return Err(Error::unsupported(path, format!("camera '{id}': OpenSfM has Brown's and the fisheye lens models only")));
        } else {
            let b = d.brown.unwrap_or(Brown { k1: 0.0, k2: 0.0, k3: 0.0, p1: 0.0, p2: 0.0 });
            json!({"projection_type": "brown", "width": w, "height": h, "focal_x": fx, "focal_y": fy, "c_x": c[0], "c_y": c[1],
                   "k1": b.k1, "k2": b.k2, "k3": b.k3, "p1": b.p1, "p2": b.p2})
        };
        cams.insert(id.clone(), cam);
    }
    let k = poses.len().max(1) as f64;
    let mean = poses.iter().fold([0.0; 3], |a, p| [a[0] + p.position[0] / k, a[1] + p.position[1] / k, a[2] + p.position[2] / k]);
    let (lon, lat) = crs.to_lonlat(mean[0], mean[1]).ok_or_else(|| Error::format(path, "the cameras are outside their CRS"))?;
    let frame = Frame { lon, lat, alt: 0.0, ground: crs, geocoded: false };
    let mut shots = Map::new();
    for (p, id) in poses.iter().zip(cameras) {
        let (c, r_local) = frame.local(p.position, p.r).ok_or_else(|| Error::at(path, &p.origin, "outside the CRS"))?;
        // OpenCV's camera axes are ours with y and z turned.
        let w2c = Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0)) * r_local.transpose();
        let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(w2c));
        let rotation = q.scaled_axis();
        let t = -(w2c * c);
        shots.insert(p.name.clone(), json!({"rotation": [rotation.x, rotation.y, rotation.z], "translation": [t.x, t.y, t.z], "camera": id}));
    }
    let rec = json!([{"cameras": cams, "shots": shots, "points": {}, "reference_lla": {"latitude": lat, "longitude": lon, "altitude": 0.0}}]);
    Ok(serde_json::to_string_pretty(&rec).unwrap_or_default())
}

/// One OpenSfM camera.
fn lens(path: &Path, at: &str, c: &Value) -> Result<Lens> {
    let field = |k: &str| format!("{at}.{k}");
    let Value::Object(m) = c else { return Err(Error::config(path, at, "expected the camera's parameters")) };
    let kind = m.get("projection_type").and_then(Value::as_str).ok_or_else(|| Error::config(path, field("projection_type"), "missing"))?;
    let allowed: &[&str] = match kind {
        "perspective" => &["focal", "k1", "k2"],
        // OpenSfM's radial cameras carry fx, fy and the principal point.
        "radial" => &["focal_x", "focal_y", "c_x", "c_y", "k1", "k2"],
        "simple_radial" => &["focal_x", "focal_y", "c_x", "c_y", "k1"],
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
