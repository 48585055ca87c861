//! Agisoft Metashape's camera export (XML, "Agisoft XML"): its sensors'
//! calibrations and its aligned cameras, as the Metashape manual defines
//! them.
//!
//! * Calibration (`type="frame"`, the adjusted one where present): `f`,
//!   `cx`, `cy` (offsets from the image centre), `b1`, `b2` (affinity and
//!   skew), `k1`–`k4`, `p1`–`p4`, in pixels on the image whose top-left
//!   corner is (0, 0): u = w/2 + cx + x'(f + B1) + y'B2, v = h/2 + cy + y'f.
//!   Where k4, p3 and p4 are zero this is Brown's model with OpenCV's p1, p2
//!   = Metashape's P2, P1.
//! * A camera's `transform`: 4×4, camera (x right, y down, z forward) →
//!   the chunk's internal frame; the component's (or, in older exports, the
//!   chunk's) `transform` (rotation, translation, scale): internal →
//!   geocentric (WGS 84). The chunk's `reference` CRS (WKT) is where the
//!   poses go: a projected one as it is, a geographic one in the UTM zone
//!   of the cameras; each camera's axes are turned with that grid.

use super::{brown_section, Imported, Lens, Pose};
use crate::camera::distortion::{Brown, Metashape};
use crate::camera::file::DistortionSection;
use crate::error::{Error, Result};
use crate::geodesy::ecef::{from_ecef, local_turn, nearest_rotation};
use crate::geodesy::{utm_zone, Crs, GroundCrs};
use nalgebra::{Matrix3, Matrix4, Vector3};
use roxmltree::Node;
use std::path::Path;

/// Does this text hold a Metashape camera export?
#[must_use]
pub fn looks_like(text: &str) -> bool {
    let t = text.trim_start();
    (t.starts_with("<?xml") || t.starts_with("<document")) && t.contains("<chunk") && (t.contains("<sensors") || t.contains("<cameras"))
}

fn child<'a, 'i>(n: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    n.children().find(|c| c.has_tag_name(name))
}

fn numbers(path: &Path, n: Node, field: &str, count: usize) -> Result<Vec<f64>> {
    let v: Vec<f64> = n.text().unwrap_or("").split_whitespace().map(|x| x.parse().unwrap_or(f64::NAN)).collect();
    if v.len() != count || v.iter().any(|x| !x.is_finite()) {
        return Err(Error::config(path, field, format!("expected {count} numbers")));
    }
    Ok(v)
}

/// A Metashape camera export.
pub fn read(path: &Path, text: &str) -> Result<Imported> {
    let doc = roxmltree::Document::parse(text).map_err(|e| Error::format(path, format!("XML: {e}")))?;
    let root = doc.root_element();
    let chunks: Vec<Node> = root.children().filter(|c| c.has_tag_name("chunk")).collect();
    let chunk = match chunks.as_slice() {
        [one] => *one,
        [] => return Err(Error::format(path, "no <chunk>: not a Metashape camera export")),
        many => return Err(Error::unsupported(path, format!("{} chunks: export the cameras of one chunk", many.len()))),
    };
    let mut set = Imported::default();
    if let Some(sensors) = child(chunk, "sensors") {
        for s in sensors.children().filter(|c| c.has_tag_name("sensor")) {
            let id = s.attribute("id").unwrap_or("0").to_string();
            set.lenses.push((id, lens(path, s)?));
        }
    }
    let cameras: Vec<Node> = child(chunk, "cameras").map(|c| c.descendants().filter(|n| n.has_tag_name("camera")).collect()).unwrap_or_default();
    if cameras.is_empty() {
        return Ok(set);
    }
    let crs_text = child(chunk, "reference").and_then(|r| r.text()).map(str::trim).unwrap_or("");
    if crs_text.starts_with("LOCAL_CS") || crs_text.starts_with("ENGCRS") {
        return Err(Error::unsupported(path, "the chunk is in a local coordinate system, not georeferenced"));
    }
    let reference = match crs_text {
        // Without one, the transform must still be geocentric (checked below).
        "" => Crs::wgs84(),
        t => Crs::parse(t, Path::new("")).map_err(|m| Error::config(path, "chunk.reference", m))?,
    };
    if let Some(datum) = reference.unknown_datum() {
        return Err(Error::unsupported(path, format!("chunk.reference: datum {datum}: export the cameras in WGS 84 or a projection of it")));
    }
    if reference.vertical().is_some() {
        set.warnings.push(format!(
            "{}: the chunk's CRS names a vertical datum, but the cameras' heights come from Metashape's geocentric frame: they are ellipsoidal, and so must the DEM's be",
            path.display()
        ));
    }
    let mut aligned = Vec::new();
    let mut unaligned = 0;
    for c in &cameras {
        match child(*c, "transform") {
            Some(t) => aligned.push((*c, t)),
            None => unaligned += 1,
        }
    }
    if unaligned > 0 {
        set.warnings.push(format!("{}: {unaligned} of {} cameras are not aligned (no transform): they have no pose", path.display(), cameras.len()));
    }
    // Internal → geocentric, per component (Metashape 1.6 and later) or for the chunk.
    let chunk_transform = child(chunk, "transform").map(|t| similarity(path, t, "chunk.transform")).transpose()?;
    let components: Vec<(String, Matrix4<f64>)> = match child(chunk, "components") {
        Some(cs) => cs
            .children()
            .filter(|c| c.has_tag_name("component"))
            .filter_map(|c| Some((c, child(c, "transform")?)))
            .map(|(c, t)| Ok((c.attribute("id").unwrap_or("0").to_string(), similarity(path, t, "component.transform")?)))
            .collect::<Result<_>>()?,
        None => Vec::new(),
    };
    let mut located = Vec::new();
    for (c, t) in aligned {
        let label = c.attribute("label").unwrap_or("");
        let field = format!("camera '{label}'.transform");
        let to_world = match (c.attribute("component_id"), components.as_slice(), &chunk_transform) {
            (Some(id), cs, _) if !cs.is_empty() => {
                cs.iter().find(|(k, _)| k == id).map(|(_, m)| *m).ok_or_else(|| Error::config(path, &field, format!("component {id} has no transform")))?
            }
            (None, [(_, m)], _) => *m,
            (_, [], Some(m)) => *m,
            _ => return Err(Error::unsupported(path, format!("{field}: no geocentric transform for this camera (chunk or component)"))),
        };
        let m = numbers(path, t, &field, 16)?;
        let cam = Matrix4::from_row_slice(&m);
        let world = to_world * cam;
        let centre = Vector3::new(world[(0, 3)], world[(1, 3)], world[(2, 3)]);
        // Camera axes in geocentric directions, scale removed.
        let r_cv = nearest_rotation(&world.fixed_view::<3, 3>(0, 0).into_owned()).ok_or_else(|| Error::config(path, &field, "no rotation"))?;
        // Our photo axes: OpenCV's with y and z turned.
        let r_photo = r_cv * Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
        let camera = c.attribute("sensor_id").map(str::to_string);
        located.push((label.rsplit(['/', '\\']).next().unwrap_or(label).to_string(), camera, centre, r_photo));
    }
    // Geocentric positions lie near the earth's surface (−1 to +30 km).
    if let Some((name, ..)) = located.iter().find(|l| !(-1000.0..30_000.0).contains(&from_ecef(l.2).2)) {
        return Err(Error::unsupported(
            path,
            format!("camera '{name}' is not near the earth's surface: the chunk's transform is not geocentric (a local coordinate system?)"),
        ));
    }
    if crs_text.is_empty() {
        set.warnings.push(format!("{}: the chunk names no CRS: its cameras are placed from its geocentric transform (WGS 84)", path.display()));
    }
    // The poses' CRS: the chunk's if projected, else the cameras' UTM zone.
    let ground_crs = if reference.is_geographic() {
        let k = located.len().max(1) as f64;
        let mean = located.iter().fold(Vector3::zeros(), |a, l| a + l.2 / k);
        let (lon, lat, _) = from_ecef(mean);
        utm_zone(lon, lat)
    } else {
        reference.clone()
    };
    let ground = GroundCrs::new(&ground_crs).map_err(|m| Error::format(path, m))?;
    for (name, camera, centre, r) in located {
        let (position, turn) = geocentric_to_ground(centre, &ground).ok_or_else(|| Error::format(path, format!("camera '{name}': outside {ground_crs}")))?;
        set.poses.push(Pose { name: name.clone(), camera, position, r: turn * r, origin: format!("{}: camera {name}", path.display()) });
    }
    set.crs = Some(match ground_crs.epsg() {
        Some(e) => format!("EPSG:{e}"),
        None => ground_crs.proj4().to_string(),
    });
    Ok(set)
}

/// `<transform>` of rotation, translation and scale → a 4×4 similarity.
fn similarity(path: &Path, t: Node, field: &str) -> Result<Matrix4<f64>> {
    let part = |name: &str, n: usize| -> Result<Vec<f64>> {
        let node = child(t, name).ok_or_else(|| Error::config(path, format!("{field}.{name}"), "missing"))?;
        numbers(path, node, &format!("{field}.{name}"), n)
    };
    let r = part("rotation", 9)?;
    let tr = part("translation", 3)?;
    let s = match child(t, "scale") {
        Some(n) => numbers(path, n, &format!("{field}.scale"), 1)?[0],
        None => 1.0,
    };
    let mut m = Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&(Matrix3::from_row_slice(&r) * s));
    m[(0, 3)] = tr[0];
    m[(1, 3)] = tr[1];
    m[(2, 3)] = tr[2];
    Ok(m)
}

/// A geocentric point → its (X, Y, h) in `ground`, and the rotation that
/// turns geocentric directions there into the ground's axes (the grid's
/// convergence and the tangent plane, scale removed).
fn geocentric_to_ground(p: Vector3<f64>, ground: &GroundCrs) -> Option<([f64; 3], Matrix3<f64>)> {
    let at = |q: Vector3<f64>| -> Option<Vector3<f64>> {
        let (lon, lat, h) = from_ecef(q);
        let (x, y) = ground.lonlat_to_ground(lon, lat)?;
        Some(Vector3::new(x, y, h))
    };
    let here = at(p)?;
    Some(([here.x, here.y, here.z], local_turn(at, p)?))
}

/// One sensor's lens.
fn lens(path: &Path, s: Node) -> Result<Lens> {
    let label = s.attribute("label").unwrap_or("?");
    let field = |k: &str| format!("sensor '{label}'.{k}");
    let kind = s.attribute("type").unwrap_or("frame");
    if kind != "frame" {
        return Err(Error::unsupported(path, format!("{}: '{kind}' (only frame sensors)", field("type"))));
    }
    let calibrations: Vec<Node> = s.children().filter(|c| c.has_tag_name("calibration")).collect();
    let cal = calibrations
        .iter()
        .find(|c| c.attribute("class") == Some("adjusted"))
        .or_else(|| calibrations.first())
        .ok_or_else(|| Error::config(path, field("calibration"), "missing: the sensor was never calibrated"))?;
    if cal.attribute("type").is_some_and(|t| t != "frame") {
        return Err(Error::unsupported(path, format!("{}: '{}' (only frame)", field("calibration.type"), cal.attribute("type").unwrap_or(""))));
    }
    const KNOWN: [&str; 15] = ["resolution", "f", "cx", "cy", "b1", "b2", "k1", "k2", "k3", "k4", "p1", "p2", "p3", "p4", "date"];
    for c in calibrations.iter().flat_map(|c| c.children()).filter(Node::is_element) {
        let name = c.tag_name().name();
        if !KNOWN.contains(&name) {
            let hint = if name == "fx" { ": PhotoScan's older form; export from Metashape 1.4 or later" } else { "" };
            return Err(Error::config(path, field(&format!("calibration.{name}")), format!("unknown{hint}")));
        }
    }
    let num = |k: &str| -> Result<f64> {
        match child(*cal, k) {
            None => Ok(0.0),
            Some(n) => n
                .text()
                .and_then(|t| t.trim().parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| Error::config(path, field(&format!("calibration.{k}")), "not a number")),
        }
    };
    let res = child(*cal, "resolution").or_else(|| child(s, "resolution")).ok_or_else(|| Error::config(path, field("resolution"), "missing"))?;
    let dim = |k: &str| {
        res.attribute(k)
            .and_then(|v| v.parse::<u32>().ok())
            .filter(|&n| n > 0)
            .ok_or_else(|| Error::config(path, field(&format!("resolution.{k}")), "expected pixels"))
    };
    let size = [dim("width")?, dim("height")?];
    let f = num("f")?;
    if !(f > 0.0) {
        return Err(Error::config(path, field("calibration.f"), "missing or not positive"));
    }
    let pp = [f64::from(size[0]) / 2.0 + num("cx")?, f64::from(size[1]) / 2.0 + num("cy")?];
    let m = Metashape { k1: num("k1")?, k2: num("k2")?, k3: num("k3")?, k4: num("k4")?, p1: num("p1")?, p2: num("p2")?, p3: num("p3")?, p4: num("p4")? };
    let distortion = if [m.k4, m.p3, m.p4] == [0.0; 3] {
        brown_section(Brown { k1: m.k1, k2: m.k2, k3: m.k3, p1: m.p2, p2: m.p1 })
    } else {
        DistortionSection { metashape: Some(m), ..Default::default() }
    };
    let b = [num("b1")?, num("b2")?];
    Ok(Lens { size, focal_px: [f, f], principal_point_px: pp, focal_mm: None, distortion, affinity_skew_px: (b != [0.0, 0.0]).then_some(b) })
}
