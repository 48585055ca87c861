//! Orthority's parameter files, read as Orthority 0.7 reads them:
//!
//! * interior (YAML): camera id → `type` (pinhole, brown, fisheye, opencv),
//!   `im_size`, `focal_len` (a number or [fx, fy]; with `sensor_size` in
//!   its units, else normalised by the image **width**, as Orthority's code
//!   does), `cx`, `cy` (normalised by the larger side, from the image
//!   centre), and the model's coefficients; any other key is refused;
//! * exterior CSV: a header of `filename`, `x y z` or `latitude longitude
//!   altitude`, `omega phi kappa` or `roll pitch yaw` (degrees), optional
//!   `camera` (names in any case, other columns ignored; `name` also for
//!   `filename`, `easting northing altitude` for `x y z`), or no header
//!   and the order `filename x y z omega phi kappa`; the delimiter `,` `;`
//!   tab `:` or spaces; fields in double or single quotes; angles in
//!   degrees unless `--radians` says otherwise; a `.prj` beside it is the
//!   CRS;
//! * exterior GeoJSON: `world_crs` and features with `filename`, `camera`,
//!   `xyz` and `opk` (radians).
//!
//! Omega, phi, kappa rotate the photo (x right, y up, z back) into the
//! world as `Rx(ω)·Ry(φ)·Rz(κ)`: our `omega-phi-kappa`. Roll, pitch, yaw
//! are a body's (x forward, y right, z down; pitch 0 looks straight down)
//! against grid north at the camera, which includes the meridian
//! convergence of the world CRS.

use super::{brown_section, fisheye_section, opencv_section, Imported, Lens, Pose};
use crate::camera::distortion::{Brown, Fisheye, OpenCv};
use crate::camera::rotation::AngleConvention;
use crate::error::{Error, Result};
use crate::geodesy::{utm_zone, Crs, GroundCrs};
use crate::io::bounded_read::{read_text_bounded, SMALL};
use nalgebra::{Matrix3, Vector3};
use serde_yaml_ng::Value;
use std::path::Path;

/// How deep YAML collections may nest (a camera file nests three or four
/// deep): the parser recurses a level at a time, and a text of 300,000
/// `[` took minutes before failing.
const MAX_YAML_DEPTH: usize = 64;

/// How many aliases (`*name`) a YAML text may hold: each is a copy of
/// what its anchor names in the tree (200,000 aliases of one camera in a
/// 2.3 MB file took 489 MB). A camera file needs a few at most.
const MAX_YAML_ALIASES: usize = 1000;

/// How many items (commas and lines) a YAML text may hold: its tree and
/// the parser's events take some 200 bytes an item (a 6 MB list of
/// numbers peaked at 610 MiB). A camera file holds tens, an RPC file a
/// hundred an image.
const MAX_YAML_ITEMS: usize = 250_000;

/// A YAML text as a tree, refused before parsing where its brackets or
/// its indentation nest deeper than [`MAX_YAML_DEPTH`] or it holds more
/// than [`MAX_YAML_ITEMS`] items.
pub fn parse_yaml(text: &str) -> std::result::Result<Value, String> {
    let items = text.bytes().filter(|&b| b == b',' || b == b'\n').count();
    if items > MAX_YAML_ITEMS {
        return Err(format!("{items} items (commas and lines): more than the {MAX_YAML_ITEMS} a parameter file could hold"));
    }
    let (mut depth, mut quote, mut aliases) = (0usize, None, 0usize);
    for line in text.lines() {
        let indent = line.len() - line.trim_start_matches([' ', '-']).len();
        if indent / 2 > MAX_YAML_DEPTH * 2 {
            return Err(format!("YAML indented more than {} levels deep", MAX_YAML_DEPTH * 2));
        }
        for c in line.chars() {
            match (c, quote) {
                ('"' | '\'', None) => quote = Some(c),
                (q, Some(open)) if q == open => quote = None,
                ('#', None) => break,
                ('[' | '{', None) => {
                    depth += 1;
                    if depth > MAX_YAML_DEPTH {
                        return Err(format!("YAML nested more than {MAX_YAML_DEPTH} brackets deep"));
                    }
                }
                (']' | '}', None) => depth = depth.saturating_sub(1),
                ('*', None) => {
                    aliases += 1;
                    if aliases > MAX_YAML_ALIASES {
                        return Err(format!("more than {MAX_YAML_ALIASES} aliases (*name): no camera or RPC file holds so many"));
                    }
                }
                _ => {}
            }
        }
        // A quote left open at a line's end in plain YAML is an apostrophe.
        if quote == Some('\'') {
            quote = None;
        }
    }
    serde_yaml_ng::from_str::<Value>(text).map_err(|e| e.to_string())
}

/// Does this YAML hold Orthority cameras (a mapping of mappings with
/// `type` and `im_size`, or one such mapping)?
pub fn looks_like_interior(text: &str) -> bool {
    // A mapping's first line names a key (`id:`) or opens one (`{`, `?`);
    // a CSV's header does not, and a CSV of 10⁶ poses parsed as YAML first.
    let first = text.lines().map(str::trim).find(|l| !l.is_empty() && !l.starts_with('#'));
    if !first.is_some_and(|l| l.contains(':') || l.starts_with('{') || l.starts_with('?')) {
        return false;
    }
    let Ok(Value::Mapping(root)) = parse_yaml(text) else { return false };
    is_camera(&Value::Mapping(root.clone())) || root.get(LEGACY_CAMERA).is_some_and(is_camera) || (!root.is_empty() && root.values().all(is_camera))
}

/// An Orthority camera: a `type` of its own or a `focal_len` (the reader
/// then names what else is missing).
fn is_camera(v: &Value) -> bool {
    v.get("focal_len").is_some() || v.get("type").and_then(Value::as_str).is_some_and(|t| ["pinhole", "brown", "fisheye", "opencv"].contains(&t))
}

/// The section of simple-ortho's `config.yaml` (Orthority's forerunner,
/// still what national archives hand out beside their scans) holding its
/// one camera; its other sections (`ortho`, …) are that tool's run
/// settings.
const LEGACY_CAMERA: &str = "camera";

/// Does this text look like a list of exterior orientations?
pub fn looks_like_csv(text: &str) -> bool {
    let Some(first) = text.lines().find(|l| !l.trim().is_empty()) else { return false };
    DELIMITERS.iter().any(|&d| fields(first, d).len() >= 7 || has_file_column(&fields(first, d)))
}

/// Does a header name the image file (`name`: our block CSV; `imagename`:
/// Pix4D's) among other columns?
fn has_file_column(head: &[String]) -> bool {
    head.len() >= 2 && head.iter().any(|f| matches!(f.to_ascii_lowercase().as_str(), "filename" | "name" | "imagename"))
}

const DELIMITERS: [u8; 5] = [b',', b';', b'\t', b':', b' '];

/// The fields of one CSV line with delimiter `d` (quotes kept together;
/// spaces after a delimiter, and empty fields between spaces, dropped).
fn fields(line: &str, d: u8) -> Vec<String> {
    fields_quoted(line, d, b'"')
}

/// [`fields`] with fields quoted by `quote`.
fn fields_quoted(line: &str, d: u8, quote: u8) -> Vec<String> {
    // A line without quotes splits at its delimiters: the CSV reader's
    // set-up, a line at a time, made a file of 10⁶ poses take 18 s.
    if !line.as_bytes().contains(&quote) {
        return line.split(char::from(d)).map(str::trim).filter(|f| d != b' ' || !f.is_empty()).map(str::to_string).collect();
    }
    let mut r = csv::ReaderBuilder::new().delimiter(d).quote(quote).has_headers(false).flexible(true).trim(csv::Trim::All).from_reader(line.as_bytes());
    let Some(Ok(rec)) = r.records().next() else { return Vec::new() };
    rec.iter().filter(|f| d != b' ' || !f.is_empty()).map(str::to_string).collect()
}

/// Orthority's interior parameter file.
pub fn read_interior(path: &Path, text: &str) -> Result<Imported> {
    let root: Value = parse_yaml(text).map_err(|e| Error::format(path, format!("YAML: {e}")))?;
    let Value::Mapping(map) = root else { return Err(Error::format(path, "expected camera ids, each with its parameters")) };
    let mut set = Imported::default();
    // The legacy forms: one camera's keys at the top, or under `camera`
    // beside simple-ortho's run settings (its id under `name`).
    let flat = map.values().next().is_some_and(|v| !v.is_mapping());
    let legacy = map.get(LEGACY_CAMERA).filter(|c| is_camera(c));
    let named = |m: &Value| m.get("name").and_then(Value::as_str).unwrap_or("unknown").to_string();
    let cameras: Vec<(String, Value)> = if flat {
        vec![(named(&Value::Mapping(map.clone())), Value::Mapping(map.clone()))]
    } else if let Some(camera) = legacy {
        // Its CRS of the positions and the orthophoto, where given, is the
        // poses' (as simple-ortho takes it).
        let crs = map.get("ortho").and_then(|o| o.get("crs")).filter(|c| !c.is_null());
        if let Some(c) = crs {
            let text = match c {
                Value::String(t) => t.clone(),
                Value::Number(n) => format!("EPSG:{n}"),
                _ => return Err(Error::config(path, "ortho.crs", "expected an EPSG code or a WKT or PROJ string")),
            };
            set.crs = Some(text);
            set.crs_from = Some(path.to_path_buf());
        } else {
            set.crs_of_image = true;
        }
        set.warnings.extend(legacy_settings_left(path, &map));
        vec![(named(camera), camera.clone())]
    } else {
        map.iter().map(|(k, v)| (key_text(k), v.clone())).collect()
    };
    for (id, params) in cameras {
        let (lens, warning) = lens(path, &id, &params)?;
        set.warnings.extend(warning);
        set.lenses.push((id, lens));
    }
    Ok(set)
}

/// A warning naming the run settings of a simple-ortho `config.yaml`
/// that have a value (its `ortho` section's resolution, resampling…; its
/// CRS is read): they are that tool's, and a run here takes its own
/// options.
fn legacy_settings_left(path: &Path, map: &serde_yaml_ng::Mapping) -> Option<String> {
    let given: Vec<String> = map
        .iter()
        .filter(|(k, _)| key_text(k) != LEGACY_CAMERA)
        .flat_map(|(section, v)| {
            let section = key_text(section);
            let settings: Vec<String> = match v {
                Value::Mapping(m) => m
                    .iter()
                    // The CRS is read (above).
                    .filter(|(k, v)| !(v.is_null() || section == "ortho" && key_text(k) == "crs"))
                    .map(|(k, _)| format!("{section}.{}", key_text(k)))
                    .collect(),
                Value::Null => Vec::new(),
                _ => vec![section],
            };
            settings
        })
        .collect();
    (!given.is_empty()).then(|| {
        format!(
            "{}: simple-ortho's run settings are not read, only its camera and CRS ({}): the run's own options decide the grid and resampling",
            path.display(),
            given.join(", ")
        )
    })
}

fn key_text(k: &Value) -> String {
    match k {
        Value::String(s) => s.clone(),
        other => serde_yaml_ng::to_string(other).unwrap_or_default().trim().to_string(),
    }
}

/// One Orthority camera: the lens, and a warning where Orthority's reading
/// of it is doubtful.
fn lens(path: &Path, id: &str, p: &Value) -> Result<(Lens, Option<String>)> {
    let field = |k: &str| format!("{id}.{k}");
    let Value::Mapping(m) = p else { return Err(Error::config(path, id, "expected the camera's parameters")) };
    let kind = m.get("type").and_then(Value::as_str).ok_or_else(|| Error::config(path, field("type"), "missing"))?.to_ascii_lowercase();
    let allowed: &[&str] = match kind.as_str() {
        "pinhole" => &[],
        "brown" => &["k1", "k2", "p1", "p2", "k3"],
        "fisheye" => &["k1", "k2", "k3", "k4"],
        "opencv" => &["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tx", "ty"],
        other => return Err(Error::config(path, field("type"), format!("'{other}' is not a frame camera type (pinhole, brown, fisheye, opencv)"))),
    };
    for k in m.keys() {
        let k = key_text(k);
        if !["type", "im_size", "focal_len", "sensor_size", "cx", "cy", "name"].contains(&k.as_str()) && !allowed.contains(&k.as_str()) {
            return Err(Error::config(path, field(&k), format!("unknown for a {kind} camera")));
        }
    }
    let num = |k: &str| -> Result<f64> {
        match m.get(k) {
            None => Ok(0.0),
            Some(v) => v.as_f64().filter(|x| x.is_finite()).ok_or_else(|| Error::config(path, field(k), "not a finite number")),
        }
    };
    let pair = |k: &str| -> Result<Option<[f64; 2]>> {
        match m.get(k) {
            None => Ok(None),
            Some(Value::Sequence(s)) if s.len() == 2 => {
                let v: Option<Vec<f64>> = s.iter().map(|x| x.as_f64().filter(|x| x.is_finite() && *x > 0.0)).collect();
                v.map(|v| Some([v[0], v[1]])).ok_or_else(|| Error::config(path, field(k), "expected two positive numbers"))
            }
            Some(v) => v
                .as_f64()
                .filter(|x| x.is_finite() && *x > 0.0)
                .map(|x| Some([x, x]))
                .ok_or_else(|| Error::config(path, field(k), "expected a positive number")),
        }
    };
    let size = match m.get("im_size") {
        Some(Value::Sequence(s)) if s.len() == 2 && s.iter().all(|v| v.as_u64().is_some_and(|n| n > 0 && n < 1 << 31)) => {
            [s[0].as_u64().unwrap_or(0) as u32, s[1].as_u64().unwrap_or(0) as u32]
        }
        _ => return Err(Error::config(path, field("im_size"), "expected [width, height] in pixels")),
    };
    let focal = pair("focal_len")?.ok_or_else(|| Error::config(path, field("focal_len"), "missing"))?;
    let sensor = match m.get("sensor_size") {
        None => None,
        Some(Value::Sequence(_)) => pair("sensor_size")?,
        Some(_) => return Err(Error::config(path, field("sensor_size"), "expected [width, height]")),
    };
    let (w, h) = (size[0] as f64, size[1] as f64);
    let mut warning = None;
    let (focal_px, focal_mm) = match sensor {
        Some(s) => ([focal[0] * w / s[0], focal[1] * h / s[1]], Some(focal[0])),
        None => {
            if h > w {
                warning = Some(format!(
                    "{}: camera '{id}': focal_len without sensor_size on a portrait image is read as Orthority's code reads it, as a fraction of the width (its documentation says of the larger side)",
                    path.display()
                ));
            }
            ([focal[0] * w, focal[1] * w], None)
        }
    };
    let long = w.max(h);
    let opencv_pp = [(w - 1.0) / 2.0 + long * num("cx")?, (h - 1.0) / 2.0 + long * num("cy")?];
    let distortion = match kind.as_str() {
        "brown" => brown_section(Brown { k1: num("k1")?, k2: num("k2")?, k3: num("k3")?, p1: num("p1")?, p2: num("p2")? }),
        "fisheye" => fisheye_section(Fisheye { k1: num("k1")?, k2: num("k2")?, k3: num("k3")?, k4: num("k4")? }),
        "opencv" => {
            for t in ["tx", "ty"] {
                if num(t)? != 0.0 {
                    return Err(Error::config(path, field(t), "OpenCV's tilted-sensor terms are not supported"));
                }
            }
            opencv_section(OpenCv {
                k1: num("k1")?,
                k2: num("k2")?,
                k3: num("k3")?,
                k4: num("k4")?,
                k5: num("k5")?,
                k6: num("k6")?,
                p1: num("p1")?,
                p2: num("p2")?,
                s1: num("s1")?,
                s2: num("s2")?,
                s3: num("s3")?,
                s4: num("s4")?,
            })
        }
        _ => Default::default(),
    };
    let mut lens = Lens::from_opencv(size, focal_px, opencv_pp, distortion);
    lens.focal_mm = focal_mm;
    Ok((lens, warning))
}

/// `angles` as given, with a warning where one passes 2π: radians that
/// large are degrees written where radians belong.
pub fn radians(path: &Path, field: &str, angles: [f64; 3], warnings: &mut Vec<String>) -> [f64; 3] {
    if angles.iter().any(|a| a.abs() > std::f64::consts::TAU) {
        warnings.push(format!("{}: {field}: {angles:?} holds angles past 2π, read as radians: degrees?", path.display()));
    }
    angles
}

/// The rotation of Orthority's omega, phi, kappa (radians): photo → world.
#[must_use]
pub fn opk_rotation(opk: [f64; 3]) -> Matrix3<f64> {
    AngleConvention::OmegaPhiKappa.matrix(opk)
}

/// Roll, pitch, yaw (radians) of a camera at `lonlat` (degrees) → its
/// rotation photo → world in `crs`: the body's axes (x forward, y right,
/// z down) against north, east, down, with north taken along the CRS's grid
/// north at that point (Orthority's `_rpy_to_opk`).
pub fn rpy_rotation(rpy: [f64; 3], lonlat: (f64, f64), crs: &GroundCrs) -> Option<Matrix3<f64>> {
    let [roll, pitch, yaw] = rpy;
    let c_nb = rz(yaw) * ry(pitch) * rx(roll);
    let c_bb = Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0);
    Some(ned_to_ground(lonlat, crs)? * c_nb * c_bb)
}

/// North, east, down at `lonlat` (degrees) → the axes of `crs`, north
/// taken along the CRS's grid north there (the meridian convergence).
pub fn ned_to_ground(lonlat: (f64, f64), crs: &GroundCrs) -> Option<Matrix3<f64>> {
    // About a metre: far above the projection's rounding, the meridian's
    // curvature cancels in the central difference.
    let d = 1e-5;
    let (x1, y1) = crs.lonlat_to_ground(lonlat.0, lonlat.1 + d)?;
    let (x2, y2) = crs.lonlat_to_ground(lonlat.0, lonlat.1 - d)?;
    let north = Vector3::new(x1 - x2, y1 - y2, 0.0).try_normalize(0.0)?;
    let down = Vector3::new(0.0, 0.0, -1.0);
    Some(Matrix3::from_columns(&[north, down.cross(&north), down]))
}

pub(super) fn rx(t: f64) -> Matrix3<f64> {
    AngleConvention::OmegaPhiKappa.matrix([t, 0.0, 0.0])
}
pub(super) fn ry(t: f64) -> Matrix3<f64> {
    AngleConvention::OmegaPhiKappa.matrix([0.0, t, 0.0])
}
pub(super) fn rz(t: f64) -> Matrix3<f64> {
    AngleConvention::OmegaPhiKappa.matrix([0.0, 0.0, t])
}

/// The image name of a file name as a pose file writes it: its directory
/// part dropped (either separator).
fn image_name(s: &str) -> String {
    s.rsplit(['/', '\\']).next().unwrap_or(s).to_string()
}

/// Orthority's exterior CSV (also the block CSV `name,X,Y,Z,omega,phi,kappa`).
/// `unit`: the unit of its angles. `only`: keep the poses that may be this
/// image's (by name, or by name without extension) and count the others:
/// a run of one image of a block holds one pose, not the block's.
pub fn read_csv(path: &Path, text: &str, unit: super::AngleUnit, only: Option<&Path>) -> Result<Imported> {
    // The lines with content, walked again rather than held (10⁶ poses).
    let lines = || text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((_, first)) = lines().next() else { return Err(Error::format(path, "holds no exterior orientations")) };
    // Single quotes where the first field opens with one (ODM's and
    // Orthority's space-delimited files), else double quotes.
    let quote = if first.trim_start().starts_with('\'') { b'\'' } else { b'"' };
    let fields = |line: &str, d: u8| fields_quoted(line, d, quote);
    // The delimiter that gives the first line seven or more fields, and every line as many.
    // (A header short of a column: the columns' check names it.)
    let fits_first = |d: u8| {
        let head = fields(first, d);
        (head.len() >= 7 || has_file_column(&head)).then_some(head.len())
    };
    let delimiter = DELIMITERS.into_iter().find(|&d| fits_first(d).is_some_and(|n| lines().take(20).all(|(_, l)| fields(l, d).len() == n)));
    let Some(delimiter) = delimiter else {
        // A first line that is a table's, and a line after it that is not:
        // that line is named, not the first.
        let short = DELIMITERS.into_iter().find_map(|d| {
            let n = fits_first(d)?;
            lines().take(20).find(|(_, l)| fields(l, d).len() != n).map(|(i, l)| (i + 1, fields(l, d).len(), n))
        });
        return Err(Error::format(
            path,
            match short {
                Some((line, got, n)) => format!("line {line}: {got} fields where the first line has {n}"),
                None => "line 1: expected a header (filename, x, y, z, omega, phi, kappa, …) or seven fields, all lines alike".into(),
            },
        ));
    };
    let head: Vec<String> = fields(first, delimiter).iter().map(|f| f.to_ascii_lowercase()).collect();
    // `name` (our block CSV) and `imagename` (Pix4D's calibrated external
    // camera parameters: the same columns and ω, φ, κ) name the file too.
    let is_file_column = |f: &str| f == "filename" || f == "name" || f == "imagename";
    let has_header = head.iter().any(|f| is_file_column(f));
    // Easting, northing (ODM's name for them) are x, y; altitude beside them, z.
    let projected = head.iter().any(|f| f == "easting") && head.iter().any(|f| f == "northing");
    let synonym = |f: String| match f.as_str() {
        "easting" => "x".to_string(),
        "northing" => "y".to_string(),
        "altitude" if projected => "z".to_string(),
        _ => f,
    };
    let names: Vec<String> = if has_header {
        head.into_iter().map(synonym).collect()
    } else {
        ["filename", "x", "y", "z", "omega", "phi", "kappa"].iter().map(|s| s.to_string()).collect()
    };
    let col = |k: &str| names.iter().position(|n| n == k || (k == "filename" && is_file_column(n)));
    let need = |ks: [&str; 3]| -> Option<[usize; 3]> { Some([col(ks[0])?, col(ks[1])?, col(ks[2])?]) };
    let (xyz, lla) = (need(["x", "y", "z"]), need(["latitude", "longitude", "altitude"]));
    let (opk, rpy) = (need(["omega", "phi", "kappa"]), need(["roll", "pitch", "yaw"]));
    let file_col = col("filename").ok_or_else(|| Error::format(path, "line 1: no filename column"))?;
    let position = xyz.or(lla).ok_or_else(|| Error::format(path, "line 1: needs x, y, z or latitude, longitude, altitude columns"))?;
    let angle_cols = opk.or(rpy).ok_or_else(|| Error::format(path, "line 1: needs omega, phi, kappa or roll, pitch, yaw columns"))?;
    let camera_col = col("camera");

    let mut rows = Vec::new();
    let for_image = |name: &str| match only {
        None => true,
        Some(image) => super::may_name(name, image),
    };
    // Every row's, kept or not: their count and mean position.
    let (mut listed, mut sum) = (0usize, [0.0f64; 2]);
    let (mut warnings, mut past_a_turn) = (Vec::new(), false);
    // Whether every angle lies within half a turn, and the largest.
    let (mut within_half_turn, mut largest) = (true, 0f64);
    for (n, line) in lines().skip(usize::from(has_header)) {
        let f = fields(line, delimiter);
        let at = |k: usize| -> Result<f64> {
            f.get(k)
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| Error::format(path, format!("line {}: {} is not a number", n + 1, names.get(k).map_or("a field", |s| s.as_str()))))
        };
        let p = [at(position[0])?, at(position[1])?, at(position[2])?];
        let given = [at(angle_cols[0])?, at(angle_cols[1])?, at(angle_cols[2])?];
        // (Said once a file: every line of a wrong column would say it.)
        let turn = if unit == super::AngleUnit::Radians { std::f64::consts::TAU } else { 360.0 };
        if !past_a_turn && given.iter().any(|a| a.abs() > turn) {
            past_a_turn = true;
            let what = if turn == 360.0 { "360°: read as degrees" } else { "2π: read as radians (‹radians›): degrees?" };
            warnings.push(format!("{}: line {}: angles {given:?} past {what}", path.display(), n + 1));
        }
        within_half_turn &= given.iter().all(|a| a.abs() <= std::f64::consts::PI + 1e-9);
        largest = given.iter().fold(largest, |m, a| m.max(a.abs()));
        let a = if unit == super::AngleUnit::Radians { given } else { given.map(f64::to_radians) };
        let camera = camera_col.and_then(|c| f.get(c)).filter(|c| !c.is_empty()).cloned();
        let file = f.get(file_col).ok_or_else(|| Error::format(path, format!("line {}: no filename", n + 1)))?;
        listed += 1;
        sum = [sum[0] + p[0], sum[1] + p[1]];
        let name = image_name(file);
        if for_image(&name) {
            rows.push((n + 1, name, camera, p, a));
        }
    }
    // Radians read as degrees turn a block's cameras by under 3.2°: every
    // angle of several images within ±π, one past a few hundredths, is
    // doubtful (a block flown north with level cameras may do it too).
    if unit == super::AngleUnit::Degrees && listed >= 3 && within_half_turn && largest > 0.05 {
        warnings.push(format!(
            "{}: every angle lies within ±π (the largest {largest}), read as degrees as Orthority reads them: if they are radians, give ‹radians›",
            path.display()
        ));
    }

    // The CRS: a .prj beside the file; latitude/longitude with roll/pitch/yaw
    // without one: the UTM zone of their mean.
    let prj = path.with_extension("prj");
    let mut crs_text = match prj.is_file() {
        true => Some(read_text_bounded(&prj, "a .prj", SMALL)?.trim().to_string()),
        false => None,
    };
    let is_lla = xyz.is_none();
    if crs_text.is_none() && is_lla {
        if opk.is_some() {
            return Err(Error::format(path, format!("latitude/longitude with omega/phi/kappa need the CRS the angles are in: put it in {}", prj.display())));
        }
        let k = listed as f64;
        let (lat, lon) = (sum[0] / k, sum[1] / k);
        crs_text = utm_zone(lon, lat).epsg().map(|c| format!("EPSG:{c}"));
    }
    let ground = match &crs_text {
        Some(t) => Some(Crs::parse(t, Path::new("")).and_then(|c| GroundCrs::new(&c)).map_err(|m| Error::format(&prj, m))?),
        None if opk.is_none() => {
            return Err(Error::format(path, format!("roll/pitch/yaw need the CRS of the positions: put it in {}", prj.display())));
        }
        None => None,
    };
    let crs_from = prj.is_file().then(|| prj.clone());
    let mut set = Imported { crs: crs_text, crs_from, warnings, listed, ..Default::default() };
    for (line, name, camera, p, a) in rows {
        let origin = format!("{}:{line}", path.display());
        let bad = |what: &str| Error::format(path, format!("line {line}: {what}"));
        let (position, lonlat) = match (&ground, is_lla) {
            (Some(g), true) => {
                let (x, y) = g.lonlat_to_ground(p[1], p[0]).ok_or_else(|| bad("the position is outside the CRS"))?;
                ([x, y, p[2]], Some((p[1], p[0])))
            }
            (Some(g), false) => (p, g.to_lonlat(p[0], p[1])),
            (None, _) => (p, None),
        };
        let r = match (opk.is_some(), &ground) {
            (true, _) => opk_rotation(a),
            (false, Some(g)) => rpy_rotation(a, lonlat.ok_or_else(|| bad("the position is outside the CRS"))?, g).ok_or_else(|| bad("no grid north there"))?,
            (false, None) => unreachable!("refused above"),
        };
        set.poses.push(Pose { name, camera, position, r, origin });
    }
    Ok(set)
}

/// Orthority's exterior GeoJSON.
pub fn read_geojson(path: &Path, text: &str) -> Result<Imported> {
    let v = super::json::parse(text).map_err(|e| Error::format(path, format!("JSON: {e}")))?;
    let crs = v.get("world_crs").and_then(|c| c.as_str()).ok_or_else(|| Error::config(path, "world_crs", "missing"))?;
    let features = v.get("features").and_then(|f| f.as_array()).ok_or_else(|| Error::config(path, "features", "missing"))?;
    let mut set = Imported { crs: Some(crs.to_string()), ..Default::default() };
    for (k, f) in features.iter().enumerate() {
        let field = |name: &str| format!("features[{k}].properties.{name}");
        let props = f.get("properties").ok_or_else(|| Error::config(path, format!("features[{k}].properties"), "missing"))?;
        let three = |name: &str| -> Result<[f64; 3]> {
            let a = props.get(name).and_then(|a| a.as_array()).filter(|a| a.len() == 3);
            let v: Option<Vec<f64>> = a.and_then(|a| a.iter().map(|x| x.as_f64().filter(|x| x.is_finite())).collect());
            v.map(|v| [v[0], v[1], v[2]]).ok_or_else(|| Error::config(path, field(name), "expected three numbers"))
        };
        let name = props.get("filename").and_then(|n| n.as_str()).ok_or_else(|| Error::config(path, field("filename"), "missing"))?;
        let camera = props.get("camera").and_then(|c| c.as_str()).map(str::to_string);
        set.poses.push(Pose {
            name: image_name(name),
            camera,
            position: three("xyz")?,
            r: opk_rotation(radians(path, &format!("features[{k}].properties.opk"), three("opk")?, &mut set.warnings)),
            origin: format!("{}: feature {k}", path.display()),
        });
    }
    Ok(set)
}

/// Lenses as Orthority's interior parameter file. The sensor size is
/// always given (in pixels where the focal length is), so that Orthority's
/// code and its documentation read the focal length alike.
pub fn write_interior(lenses: &[(String, Lens)], path: &Path) -> Result<String> {
    let mut out = String::from("# Interior parameters for Orthority (written by gcm-ortho)\n");
    for (id, l) in lenses {
        let d = &l.distortion;
        let (kind, terms): (&str, Vec<(&str, f64)>) = if let Some(b) = d.brown {
            ("brown", vec![("k1", b.k1), ("k2", b.k2), ("p1", b.p1), ("p2", b.p2), ("k3", b.k3)])
        } else if let Some(o) = d.opencv {
            let names = ["k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4"];
            ("opencv", names.into_iter().zip(o.opencv_order()).collect())
        } else if let Some(k) = d.fisheye {
            ("fisheye", vec![("k1", k.k1), ("k2", k.k2), ("k3", k.k3), ("k4", k.k4)])
        } else if d.radial_mm.is_some() || d.metashape.is_some() {
            let field = if d.radial_mm.is_some() { "distortion.radial_mm" } else { "distortion.metashape" };
            return Err(Error::config(path, field, "this lens model has no form in Orthority's files"));
        } else {
            ("pinhole", Vec::new())
        };
        let [w, h] = l.size;
        let (focal, sensor) = match l.focal_mm {
            Some(f) => ([f, f], [f / l.focal_px[0] * f64::from(w), f / l.focal_px[1] * f64::from(h)]),
            None => (l.focal_px, [f64::from(w), f64::from(h)]),
        };
        let long = f64::from(w.max(h));
        let pp = l.opencv_pp();
        let c = [(pp[0] - (f64::from(w) - 1.0) / 2.0) / long, (pp[1] - (f64::from(h) - 1.0) / 2.0) / long];
        out += &format!("{id:?}:\n  type: {kind}\n  im_size: [{w}, {h}]\n");
        let y = yaml_float;
        out += &if focal[0] == focal[1] { format!("  focal_len: {}\n", y(focal[0])) } else { format!("  focal_len: [{}, {}]\n", y(focal[0]), y(focal[1])) };
        out += &format!("  sensor_size: [{}, {}]\n  cx: {}\n  cy: {}\n", y(sensor[0]), y(sensor[1]), y(c[0]), y(c[1]));
        for (name, v) in terms {
            out += &format!("  {name}: {}\n", y(v));
        }
    }
    Ok(out)
}

/// A float as YAML 1.1 (PyYAML, which Orthority reads with) takes it: the
/// shortest round-trip digits, always with a point, and a signed exponent.
fn yaml_float(v: f64) -> String {
    let s = format!("{v:?}");
    match s.split_once('e') {
        Some((m, e)) => {
            let m = if m.contains('.') { m.to_string() } else { format!("{m}.0") };
            let e = if e.starts_with('-') { e.to_string() } else { format!("+{e}") };
            format!("{m}e{e}")
        }
        None => s,
    }
}

/// Poses as Orthority's exterior CSV (ω, φ, κ in degrees); `cameras[k]`
/// is the id of pose k's lens. The CRS goes in a `.prj` beside it.
#[must_use]
pub fn write_csv(poses: &[Pose], cameras: &[String]) -> String {
    let mut w = csv::WriterBuilder::new().from_writer(Vec::new());
    let _ = w.write_record(["filename", "x", "y", "z", "omega", "phi", "kappa", "camera"]);
    for (p, id) in poses.iter().zip(cameras) {
        let a = AngleConvention::OmegaPhiKappa.angles(&p.r).map(f64::to_degrees);
        let n = |v: f64| format!("{v:?}");
        let _ = w.write_record([p.name.clone(), n(p.position[0]), n(p.position[1]), n(p.position[2]), n(a[0]), n(a[1]), n(a[2]), id.clone()]);
    }
    String::from_utf8(w.into_inner().unwrap_or_default()).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    /// A line without quotes splits as the CSV reader splits it.
    #[test]
    fn unquoted_lines_split_as_the_csv_reader_does() {
        let by_reader = |line: &str, d: u8| -> Vec<String> {
            let mut r = csv::ReaderBuilder::new().delimiter(d).has_headers(false).flexible(true).trim(csv::Trim::All).from_reader(line.as_bytes());
            let Some(Ok(rec)) = r.records().next() else { return Vec::new() };
            rec.iter().filter(|f| d != b' ' || !f.is_empty()).map(str::to_string).collect()
        };
        for line in ["img_001.tif,640000.5, 4800000.25 ,1500,0.1,-0.2,91", "a;b;;c;", "0182.tif  652310.1   4830122.7 1820.0\t0.7 1.1 0.0", " x\ty\t z ", "one"]
        {
            for d in super::DELIMITERS {
                assert_eq!(super::fields_quoted(line, d, b'"'), by_reader(line, d), "{line:?} split at {:?}", char::from(d));
            }
        }
    }

    #[test]
    fn yaml_floats_read_as_floats_in_yaml_1_1() {
        assert_eq!(super::yaml_float(1e-5), "1.0e-5");
        assert_eq!(super::yaml_float(2.5e20), "2.5e+20");
        assert_eq!(super::yaml_float(-0.25), "-0.25");
        assert_eq!(super::yaml_float(533.312), "533.312");
    }
}
