//! The camera file's side of the marks: what to look for (its calibrated
//! marks and `interior.fiducial_mark`), and the file again with the marks'
//! measured places (`fiducials_px`) — for `fiducials --write`, and for a
//! scan rectified with marks calibrated but not measured.

use super::{Detection, MarkLook, Polarity, Request, Shape, Turn};
use crate::camera::file::{CameraFile, InteriorSection, OneOrMany};
use crate::error::{Error, Result};
use crate::io::source::SourceImage;
use std::path::Path;

/// Settings from the command line over the camera file's.
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    pub shape: Option<String>,
    pub size_mm: Option<f64>,
    pub polarity: Option<Polarity>,
    pub turn: Option<Turn>,
    pub pixel_mm: Option<f64>,
    pub limit_px: Option<f64>,
}

/// The calibrated marks: `fiducials_mm`, or the four marks that
/// `fiducial_distances_mm` puts on the photo's axes (1→2 along x, 3→4 along y).
pub fn calibrated(i: &InteriorSection) -> Option<Vec<[f64; 2]>> {
    if let Some(mm) = &i.fiducials_mm {
        return Some(mm.clone());
    }
    let [lx, ly] = i.fiducial_distances_mm?;
    Some(vec![[-lx / 2.0, 0.0], [lx / 2.0, 0.0], [0.0, -ly / 2.0], [0.0, ly / 2.0]])
}

/// Finds the marks of the camera file `file` (at `camera_path`) in the
/// scan `src`.
pub fn detect_for(file: &CameraFile, camera_path: &Path, src: &SourceImage, over: &Overrides) -> Result<Detection> {
    let err = |field: &str, m: String| Error::config(camera_path, format!("interior.{field}"), m);
    // The command line's values are named by their options, the file's by their keys.
    let pixel_size = |p: f64| (p.is_finite() && p > 0.0 && p < 1.0).then_some(()).ok_or_else(|| format!("{p} is not a scanner's pixel size in mm"));
    let residual = |r: f64| (r.is_finite() && r > 0.0).then_some(()).ok_or_else(|| format!("{r} is not a positive number of pixels"));
    let size = |v: f64| (v.is_finite() && v > 0.0 && v <= 20.0).then_some(()).ok_or_else(|| format!("{v} is not a mark's size from 0 to 20 mm"));
    over.pixel_mm.map(pixel_size).transpose().map_err(|m| Error::setting("scan_pixel_mm", m))?;
    over.limit_px.map(residual).transpose().map_err(|m| Error::setting("max_residual_px", m))?;
    over.size_mm.map(size).transpose().map_err(|m| Error::setting("size_mm", m))?;
    let interior = file.interior.as_ref().ok_or_else(|| Error::config(camera_path, "interior", "missing section"))?;
    let marks = calibrated(interior).ok_or_else(|| err("fiducials_mm", "no calibrated fiducial marks (fiducials_mm or fiducial_distances_mm)".into()))?;
    let setting = interior.fiducial_mark.clone().unwrap_or_default();
    let (shapes, shape_index) = match (&setting.template, &over.shape) {
        (Some(t), None) => {
            let px = setting.template_pixel_mm.ok_or_else(|| err("fiducial_mark.template_pixel_mm", "missing: the template image's pixel size, mm".into()))?;
            let picture = |t: &String| Shape::from_picture(&camera_path.parent().unwrap_or(Path::new("")).join(t), px);
            match t {
                OneOrMany::One(t) => (vec![picture(t)?; marks.len()], vec![0; marks.len()]),
                OneOrMany::Many(v) if v.len() == marks.len() => (v.iter().map(picture).collect::<Result<Vec<_>>>()?, (0..marks.len()).collect()),
                OneOrMany::Many(v) => return Err(err("fiducial_mark.template", format!("{} templates for {} marks", v.len(), marks.len()))),
            }
        }
        _ => {
            let names: Vec<String> = match (&over.shape, &setting.shape) {
                (Some(s), _) => vec![s.clone(); marks.len()],
                (None, Some(OneOrMany::One(s))) => vec![s.clone(); marks.len()],
                (None, Some(OneOrMany::Many(v))) if v.len() == marks.len() => v.clone(),
                (None, Some(OneOrMany::Many(v))) => return Err(err("fiducial_mark.shape", format!("{} shapes for {} marks", v.len(), marks.len()))),
                (None, None) => vec!["cross".into(); marks.len()],
            };
            let mut distinct: Vec<String> = names.clone();
            distinct.sort();
            distinct.dedup();
            let mut shapes = Vec::new();
            for name in &names {
                let look = MarkLook { shape: name.clone(), size_mm: over.size_mm.or(setting.size_mm), line_mm: setting.line_mm, dot_mm: setting.dot_mm };
                shapes.push(Shape::from_look(&look).map_err(|m| match over.shape {
                    Some(_) => Error::setting("shape", m),
                    None => err("fiducial_mark", format!("{m}; or a template image: template = \"FILE\" with template_pixel_mm")),
                })?);
            }
            let index = names.iter().map(|n| distinct.iter().position(|d| d == n).expect("listed")).collect();
            (shapes, index)
        }
    };
    let polarity = match (over.polarity, setting.polarity.as_deref()) {
        (Some(p), _) => p,
        (None, None) => Polarity::Auto,
        (None, Some(p)) => {
            crate::options::parse_choice::<Polarity>("polarity", p).map_err(|_| err("fiducial_mark.polarity", format!("'{p}' is not light, dark or auto")))?
        }
    };
    interior.scan_pixel_mm.map(pixel_size).transpose().map_err(|m| err("scan_pixel_mm", m))?;
    interior.max_fiducial_residual_px.map(residual).transpose().map_err(|m| err("max_fiducial_residual_px", m))?;
    if marks.len() < 3 {
        // The camera file's fault, not the scan's.
        return Err(err("fiducials_mm", format!("{} calibrated fiducial marks: at least 3 are needed", marks.len())));
    }
    let pixel_mm = over.pixel_mm.or(interior.scan_pixel_mm);
    let limit_px = over.limit_px.or(interior.max_fiducial_residual_px).unwrap_or(1.0);
    let mut req =
        Request { marks_mm: &marks, shapes, shape_index, pixel_mm: pixel_mm.or_else(|| resolution_mm(&src.path)), polarity, turn: over.turn, limit_px };
    match super::detect(src, &req) {
        // The resolution tags can be wrong (a scanner's default): search
        // by the scan's size instead before giving up.
        Err(_) if pixel_mm.is_none() && req.pixel_mm.is_some() => {
            req.pixel_mm = None;
            super::detect(src, &req)
        }
        other => other,
    }
}

/// The scan's pixel size from its TIFF resolution tags, where they give a
/// scanner's (300 to 10 000 dpi).
fn resolution_mm(path: &Path) -> Option<f64> {
    use tiff::decoder::ifd::Value;
    use tiff::tags::Tag;
    let file = std::fs::File::open(path).ok()?;
    let mut dec = tiff::decoder::Decoder::new(std::io::BufReader::new(file)).ok()?;
    let unit = match dec.find_tag(Tag::ResolutionUnit).ok()? {
        Some(v) => v.into_u16().ok()?,
        None => 2,
    };
    let per_unit = match dec.find_tag(Tag::XResolution).ok()?? {
        Value::Rational(n, d) if d != 0 => n as f64 / d as f64,
        other => other.into_f64().ok()?,
    };
    let mm = match unit {
        2 => 25.4 / per_unit,
        3 => 10.0 / per_unit,
        _ => return None,
    };
    (0.0025..=0.085).contains(&mm).then_some(mm)
}

/// `file` with the marks' measured places: those used, in the camera's
/// order (the calibrated coordinates of marks left out are left out too).
pub fn with_marks(mut file: CameraFile, det: &Detection) -> Result<CameraFile> {
    let interior = file.interior.as_mut().expect("detected from it");
    let (mm, px) = det.used();
    if interior.fiducial_distances_mm.is_some() {
        if px.len() != 4 {
            return Err(Error::Geometry(format!("the distance form needs all 4 fiducial marks; {} were found", px.len())));
        }
    } else {
        interior.fiducials_mm = Some(mm);
    }
    interior.fiducials_px = Some(px);
    Ok(file)
}

/// The camera of `image`: `file` as it is, or with its marks found in the
/// scan where they are calibrated but not measured; and what was doubtful.
pub fn measured(file: CameraFile, camera_path: &Path, image: &Path) -> Result<(CameraFile, Vec<String>)> {
    if !file.needs_marks() {
        return Ok((file, Vec::new()));
    }
    let src = SourceImage::open(image, 16 << 20)?;
    // The camera file is named first: its marks are what is missing.
    let det = detect_for(&file, camera_path, &src, &Overrides::default())
        .map_err(|e| Error::config(camera_path, "interior.fiducials_px", format!("not given, and not found in the scan: {}", e.marked())))?;
    let mut notes: Vec<String> = det.warnings.iter().map(|w| format!("{}: {w}", image.display())).collect();
    if det.turn_ambiguous {
        // Identical marks cannot tell a film scanned turned: said, not guessed.
        notes.push(format!(
            "{}: the fiducial marks look the same turned, so the scan is taken as it lies; if the film was scanned turned, the orthophoto is turned too: measure the marks with `gcm-ortho fiducials --turn 90|180|270 --write CAMERA` and rectify with that camera file",
            image.display()
        ));
    }
    Ok((with_marks(file, &det)?, notes))
}

/// The camera file's text with `[interior]`'s marks replaced by `measured`'s
/// (measured places, and calibrated marks without those left out); every
/// other line, comment and layout kept.
pub fn edit_toml(text: &str, measured: &CameraFile, path: &Path) -> Result<String> {
    use toml_edit::{Array, DocumentMut, Item, Value};
    let mut doc: DocumentMut = text.parse().map_err(|e: toml_edit::TomlError| Error::config(path, "toml", e.message().to_string()))?;
    let interior = measured.interior.as_ref().expect("measured");
    let pairs = |v: &[[f64; 2]], decimals: i32| -> Value {
        let k = 10f64.powi(decimals);
        let mut outer = Array::new();
        for p in v {
            let mut inner = Array::new();
            inner.push((p[0] * k).round() / k);
            inner.push((p[1] * k).round() / k);
            outer.push(inner);
        }
        Value::Array(outer)
    };
    let table = doc.get_mut("interior").and_then(Item::as_table_like_mut).ok_or_else(|| Error::config(path, "interior", "missing section"))?;
    if let (Some(mm), true) = (&interior.fiducials_mm, table.get("fiducials_mm").is_some()) {
        table.insert("fiducials_mm", Item::Value(pairs(mm, 6)));
    }
    let px = interior.fiducials_px.as_ref().expect("measured");
    table.insert("fiducials_px", Item::Value(pairs(px, 3)));
    Ok(doc.to_string())
}
