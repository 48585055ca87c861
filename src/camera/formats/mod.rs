//! Camera and pose files of other tools, read into our camera file: the
//! format is found by content, never by the name alone.
//!
//! * Orthority: interior parameters (YAML: camera id → `type`, `im_size`,
//!   `focal_len`, …), exterior parameters (CSV with x/y/z or
//!   latitude/longitude/altitude and omega/phi/kappa or roll/pitch/yaw; its
//!   GeoJSON) — [`orthority`];
//! * OpenSfM / OpenDroneMap: `reconstruction.json` (cameras and shots) and
//!   `cameras.json` — [`opensfm`];
//! * Metashape's camera XML — [`metashape`];
//! * Pix4D's calibrated camera parameters and `.cam` — [`pix4d`] (its
//!   external parameters are an exterior CSV);
//! * our own camera file (TOML) as the interior, with a list of poses.
//!
//! Each reader yields lenses (by camera id) and poses (by image name). An
//! image takes the pose whose name is its file name, with or without the
//! extension; its lens is the pose's camera, or the only one there is.
//! The same two types are written back out in Orthority's and OpenSfM's
//! forms ([`orthority::write_interior`], [`orthority::write_csv`],
//! [`opensfm::write`]), so a block travels between the tools.

pub mod convert;
pub mod exif;
pub mod json;
pub mod metashape;
pub mod opensfm;
pub mod orthority;
pub mod pix4d;

use super::distortion::{Brown, Fisheye, OpenCv};
use super::file::{CameraFile, CameraSection, DistortionSection, ExteriorSection, InteriorSection, PixelSize};
use super::rotation::AngleConvention;
use crate::error::{Error, Result};
use crate::geodesy::Crs;
use crate::io::bounded_read::{read_text_bounded, SMALL};
use nalgebra::Matrix3;
use std::path::{Path, PathBuf};

/// A lens in pixels, as calibration tools give it.
#[derive(Clone, Debug, PartialEq)]
pub struct Lens {
    /// The image it was calibrated on, pixels (width, height).
    pub size: [u32; 2],
    /// Focal length in pixels across and down (OpenCV's fx, fy).
    pub focal_px: [f64; 2],
    /// The principal point, pixels from the top-left corner (centres at +½).
    pub principal_point_px: [f64; 2],
    /// The focal length in mm, where the source gives a sensor size.
    pub focal_mm: Option<f64>,
    pub distortion: DistortionSection,
    /// Metashape's affinity and skew (B1, B2), pixels.
    pub affinity_skew_px: Option<[f64; 2]>,
}

impl Lens {
    /// A lens with OpenCV's parameters: principal point in OpenCV's
    /// pixels (centres at integers), the coefficients of `kind`.
    #[must_use]
    pub fn from_opencv(size: [u32; 2], focal_px: [f64; 2], opencv_pp: [f64; 2], distortion: DistortionSection) -> Lens {
        Lens { size, focal_px, principal_point_px: [opencv_pp[0] + 0.5, opencv_pp[1] + 0.5], focal_mm: None, distortion, affinity_skew_px: None }
    }

    /// The lens of our camera file `file` (read from `path`) on images of
    /// `size` pixels: a digital camera's (pixel size, principal point in
    /// pixels). A film camera's fiducial interior orientation and our
    /// radial polynomial in mm have no form in other tools' files.
    pub fn of(file: &CameraFile, path: &Path, size: [u32; 2]) -> Result<Lens> {
        let no_form = |field: &str, what: &str| Error::config(path, field, format!("{what} has no form in Orthority's or OpenSfM's camera files"));
        if file.camera.model != "frame" {
            return Err(no_form("camera.model", "an RPC model"));
        }
        let interior = file.interior.clone().unwrap_or_default();
        if interior.fiducials_mm.is_some() || interior.fiducial_distances_mm.is_some() {
            return Err(no_form("interior", "a film camera's interior orientation from fiducial marks"));
        }
        if interior.affinity_skew_px.is_some_and(|b| b != [0.0, 0.0]) {
            return Err(no_form("interior.affinity_skew_px", "Metashape's affinity and skew"));
        }
        if interior.principal_point_mm.is_some_and(|p| p != [0.0, 0.0]) {
            return Err(no_form("interior.principal_point_mm", "a principal point in mm on a digital camera"));
        }
        let f = file.camera.focal_length_mm.ok_or_else(|| Error::config(path, "camera.focal_length_mm", "missing"))?;
        let [px, py] = interior.pixel_size_mm.map(PixelSize::sides).ok_or_else(|| Error::config(path, "interior.pixel_size_mm", "missing"))?;
        let pp = interior.principal_point_px.ok_or_else(|| Error::config(path, "interior.principal_point_px", "missing"))?;
        let distortion = file.distortion.clone().unwrap_or_default();
        if distortion.radial_mm.is_some() {
            return Err(no_form("distortion.radial_mm", "the radial polynomial in mm"));
        }
        // Pixels 1 "mm" across are the form for a focal length in pixels.
        let focal_mm = (px != 1.0 || py != 1.0).then_some(f);
        Ok(Lens { size, focal_px: [f / px, f / py], principal_point_px: pp, focal_mm, distortion, affinity_skew_px: None })
    }

    /// The principal point in OpenCV's pixels (centres at integers).
    #[must_use]
    pub fn opencv_pp(&self) -> [f64; 2] {
        [self.principal_point_px[0] - 0.5, self.principal_point_px[1] - 0.5]
    }

    /// Our camera and interior sections. Without a sensor size the focal
    /// length is written in pixels, on pixels 1 "mm" across: the geometry
    /// depends only on their ratio.
    fn sections(&self) -> (CameraSection, InteriorSection) {
        let f = self.focal_mm.unwrap_or(self.focal_px[0]);
        let sides = [f / self.focal_px[0], f / self.focal_px[1]];
        let pixel = if sides[0] == sides[1] { PixelSize::Square(sides[0]) } else { PixelSize::Sides(sides) };
        let camera = CameraSection { model: "frame".into(), focal_length_mm: Some(f) };
        let interior = InteriorSection {
            pixel_size_mm: Some(pixel),
            principal_point_px: Some(self.principal_point_px),
            image_size_px: Some(self.size),
            affinity_skew_px: self.affinity_skew_px,
            ..Default::default()
        };
        (camera, interior)
    }
}

/// Brown's coefficients as a distortion section (none when all are zero).
#[must_use]
pub fn brown_section(b: Brown) -> DistortionSection {
    if b == (Brown { k1: 0.0, k2: 0.0, k3: 0.0, p1: 0.0, p2: 0.0 }) {
        return DistortionSection::default();
    }
    DistortionSection { brown: Some(b), ..Default::default() }
}

/// OpenCV's full model as a distortion section, Brown's where it is one.
#[must_use]
pub fn opencv_section(o: OpenCv) -> DistortionSection {
    if [o.k4, o.k5, o.k6, o.s1, o.s2, o.s3, o.s4] == [0.0; 7] {
        return brown_section(Brown { k1: o.k1, k2: o.k2, k3: o.k3, p1: o.p1, p2: o.p2 });
    }
    DistortionSection { opencv: Some(o), ..Default::default() }
}

/// The fisheye model as a distortion section.
#[must_use]
pub fn fisheye_section(k: Fisheye) -> DistortionSection {
    DistortionSection { fisheye: Some(k), ..Default::default() }
}

/// Where an image was and how it looked.
#[derive(Clone, Debug, PartialEq)]
pub struct Pose {
    /// The image's name as the file gives it (a directory part dropped).
    pub name: String,
    /// The lens's id, where the file names one.
    pub camera: Option<String>,
    /// The projection centre in the set's CRS.
    pub position: [f64; 3],
    /// Photo (x right, y up, looking down −z) → ground (X east, Y north, Z up).
    pub r: Matrix3<f64>,
    /// Where it was read: "file:line" or "file: shot NAME".
    pub origin: String,
}

impl Pose {
    /// The pose of our camera file `file` (read from `path`), for the image `name`.
    pub fn of(name: &str, file: &CameraFile, path: &Path) -> Result<Pose> {
        let e = file.exterior.as_ref().ok_or_else(|| Error::config(path, "exterior", "missing"))?;
        let r = e.convention.matrix(e.angles_deg.map(f64::to_radians));
        Ok(Pose { name: name.to_string(), camera: None, position: e.position, r, origin: path.display().to_string() })
    }
}

/// Distinct lenses of `lenses` by value, each with an id, and for every
/// input the id of its lens: "camera 1", "camera 2"… (never a bare
/// "camera": Orthority takes a file with that one key for its legacy form).
#[must_use]
pub fn distinct_lenses(lenses: &[Lens]) -> (Vec<(String, Lens)>, Vec<String>) {
    let mut unique: Vec<Lens> = Vec::new();
    let index: Vec<usize> = lenses
        .iter()
        .map(|l| {
            unique.iter().position(|u| u == l).unwrap_or_else(|| {
                unique.push(l.clone());
                unique.len() - 1
            })
        })
        .collect();
    let id = |k: usize| format!("camera {}", k + 1);
    let ids = index.iter().map(|&k| id(k)).collect();
    (unique.into_iter().enumerate().map(|(k, l)| (id(k), l)).collect(), ids)
}

/// What a set of files says: lenses, poses, and the CRS of the poses.
#[derive(Clone, Debug, Default)]
pub struct Imported {
    pub lenses: Vec<(String, Lens)>,
    pub poses: Vec<Pose>,
    /// The poses' CRS as the files give it (any form `Crs::parse` reads).
    pub crs: Option<String>,
    /// The file that gave `crs` where it is not the poses' own (a `.prj`).
    pub crs_from: Option<PathBuf>,
    /// Our own camera file when it is the interior: its sections are kept.
    pub base: Option<CameraFile>,
    /// Doubtful things the files hold (printed as warnings).
    pub warnings: Vec<String>,
    /// The files read, for messages and for the no-overwrite check.
    pub files: Vec<PathBuf>,
    /// A drone's height above its take-off point, where its tags give one
    /// (a check of the absolute height against the DEM).
    pub relative_altitude: Option<f64>,
    /// The lens each image was calibrated with (image name, lens id), where
    /// the lenses' file says so: poses from another file that name no
    /// camera take it by their image's name.
    pub lens_of_image: Vec<(String, String)>,
    /// Poses the files list, where only those of one image were kept.
    pub listed: usize,
    /// Where no file gives the poses' CRS, the image's own is theirs
    /// (simple-ortho's `config.yaml` says so of an empty `ortho.crs`).
    pub crs_of_image: bool,
}

/// Whether a pose named `name` may be `image`'s: the same file name, or
/// the same name without its extension (see [`Imported::camera_for`]).
pub fn may_name(name: &str, image: &Path) -> bool {
    let file = image.file_name().and_then(|n| n.to_str()).unwrap_or("");
    let stem = image.file_stem().and_then(|n| n.to_str()).unwrap_or("");
    name == file || name == stem || Path::new(name).file_stem().and_then(|s| s.to_str()).unwrap_or(name) == stem
}

/// What a file holds, by its content.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Our camera file (TOML).
    Ours,
    OrthorityInterior,
    OrthorityCsv,
    OrthorityGeoJson,
    OpenSfmReconstruction,
    OpenSfmCameras,
    MetashapeXml,
    Pix4dCalibrated,
    Pix4dCam,
    /// Ames Stereo Pipeline's optical-bar (panoramic) camera.
    AspOpticalBar,
}

impl Kind {
}

/// Names for a message: the first ten, then how many more (a file of
/// 200,000 cameras made a line of 1.9 MB).
fn listed<'a>(names: impl ExactSizeIterator<Item = &'a str>) -> String {
    const MOST: usize = 10;
    let n = names.len();
    let mut text = names.take(MOST).collect::<Vec<_>>().join(", ");
    if n > MOST {
        text.push_str(&format!(" and {} more", n - MOST));
    }
    text
}

/// The forms of camera file read, as a refusal lists them.
const FORMS: &str = "ours in TOML; Orthority's YAML, CSV or GeoJSON; OpenSfM's JSON; Metashape's XML; Pix4D's; ASP's OPTICAL_BAR";

/// The kind of a camera or pose file, from its text.
pub fn detect(path: &Path, text: &str) -> Result<Kind> {
    let t = text.trim_start_matches('\u{feff}').trim_start();
    if t.starts_with('{') || t.starts_with("[\n") || t.starts_with("[ ") || t.starts_with("[{") || t.starts_with("[\r") {
        match json::parse(t) {
            Ok(v) => return detect_json(path, &v),
            Err(json::Problem::TooLarge(m)) => return Err(Error::format(path, m)),
            Err(json::Problem::Syntax(_)) => {}
        }
    }
    if metashape::looks_like(t) {
        return Ok(Kind::MetashapeXml);
    }
    if crate::camera::panoramic_file::looks_like_asp(t) {
        return Ok(Kind::AspOpticalBar);
    }
    // TOML opens with a table (`[camera]`) or a key (`crs = …`); its
    // parser's error holds a copy of the whole text (a 10⁶-pose CSV's too).
    let first = t.lines().map(str::trim).find(|l| !l.is_empty() && !l.starts_with('#'));
    let may_be_toml = first.is_some_and(|l| l.starts_with('[') || l.contains('='));
    if may_be_toml && toml::from_str::<toml::Table>(t).is_ok_and(|table| table.contains_key("camera") || table.contains_key("crs")) {
        return Ok(Kind::Ours);
    }
    if pix4d::looks_like_cam(t) {
        return Ok(Kind::Pix4dCam);
    }
    if pix4d::looks_like_calibrated(t) {
        return Ok(Kind::Pix4dCalibrated);
    }
    if orthority::looks_like_interior(t) {
        return Ok(Kind::OrthorityInterior);
    }
    // A file named as YAML or JSON is told its own parser's complaint, not
    // TOML's (nor the CSV reader's: a YAML line can have seven fields).
    let named = |exts: &[&str]| path.extension().and_then(|e| e.to_str()).is_some_and(|e| exts.iter().any(|x| e.eq_ignore_ascii_case(x)));
    if !named(&["yaml", "yml"]) && orthority::looks_like_csv(t) {
        return Ok(Kind::OrthorityCsv);
    }
    if named(&["yaml", "yml"]) {
        let why = match orthority::parse_yaml(t) {
            Err(e) => e,
            Ok(_) => "it holds no Orthority cameras (a mapping of camera ids, each with `type`, `im_size` and `focal_len`)".to_string(),
        };
        return Err(Error::format(path, format!("not a camera file of a form read here ({FORMS}): as YAML, {why}")));
    }
    if named(&["json", "geojson"]) {
        if let Err(e) = serde_json::from_str::<serde::de::IgnoredAny>(t) {
            return Err(Error::format(path, format!("not a camera file of a form read here ({FORMS}): as JSON, {e}")));
        }
    }
    // Our own file with a mistake (its parser says what), or no form read.
    let named_toml = named(&["toml"]);
    match toml::from_str::<toml::Table>(t) {
        Err(e) if !named_toml => {
            let line =
                e.span().map_or(String::new(), |s| format!("line {}: ", text[..(text.len() - t.len() + s.start).min(text.len())].matches('\n').count() + 1));
            Err(Error::format(path, format!("not a camera file of a form read here ({FORMS}): as TOML, {line}{}", e.message().replace('\n', " "))))
        }
        _ => Ok(Kind::Ours),
    }
}

fn detect_json(path: &Path, v: &serde_json::Value) -> Result<Kind> {
    use serde_json::Value;
    match v {
        Value::Object(o) if o.get("type").and_then(Value::as_str) == Some("FeatureCollection") => Ok(Kind::OrthorityGeoJson),
        Value::Object(o) if o.values().all(|c| c.get("projection_type").is_some()) && !o.is_empty() => Ok(Kind::OpenSfmCameras),
        Value::Array(a) if a.first().is_some_and(|r| r.get("shots").is_some() || r.get("cameras").is_some()) => Ok(Kind::OpenSfmReconstruction),
        _ => Err(Error::unsupported(path, "JSON that is neither an OpenSfM reconstruction.json / cameras.json nor an Orthority GeoJSON (FeatureCollection)")),
    }
}

/// The unit of the angles in a CSV of exterior orientations: degrees,
/// as Orthority reads them unless told (`--radians`), or radians.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AngleUnit {
    #[default]
    Degrees,
    Radians,
}

/// `--camera exif`: the camera from the image's own tags.
#[must_use]
pub fn is_exif(camera: &Path) -> bool {
    camera == Path::new("exif")
}

/// The set for `image`: from its own tags where `camera` is `exif`
/// (positions in `crs`, default their UTM zone), else [`read`].
pub fn read_for(image: &Path, camera: &Path, exterior: Option<&Path>, crs: Option<&Crs>) -> Result<Imported> {
    read_for_with(image, camera, exterior, AngleUnit::Degrees, crs)
}

/// As [`read_for`], a pose CSV's angles in `angles`.
pub fn read_for_with(image: &Path, camera: &Path, exterior: Option<&Path>, angles: AngleUnit, crs: Option<&Crs>) -> Result<Imported> {
    if !is_exif(camera) {
        return read_with_only(camera, exterior, Some(image), angles, true);
    }
    if let Some(e) = exterior {
        return Err(Error::unsupported(e, "‹camera› exif takes the position from the image: give a camera file with ‹exterior›"));
    }
    exif::read(image, crs)
}

#[cfg(feature = "internals")]
/// Reads a camera file (`--camera`) and, where given, a pose file
/// (`--exterior`) into one set; `image`, where known, gives the pixels of
/// a lens given in mm only (Pix4D's `.cam`).
pub fn read(camera: &Path, exterior: Option<&Path>, image: Option<&Path>) -> Result<Imported> {
    read_with(camera, exterior, image, AngleUnit::Degrees)
}

/// As [`read`], a pose CSV's angles in `angles`.
pub fn read_with(camera: &Path, exterior: Option<&Path>, image: Option<&Path>, angles: AngleUnit) -> Result<Imported> {
    read_with_only(camera, exterior, image, angles, false)
}

/// As [`read_with`]; `only`: a pose CSV keeps only the poses that may be
/// `image`'s (a block's file of 10⁶ poses for one image's run).
fn read_with_only(camera: &Path, exterior: Option<&Path>, image: Option<&Path>, angles: AngleUnit, only: bool) -> Result<Imported> {
    let only = image.filter(|_| only);
    let mut set = read_one(camera, exterior.is_some(), image, angles, only)?;
    if let Some(e) = exterior {
        let mut poses = read_one(e, false, image, angles, only)?;
        let stem = |n: &str| Path::new(n).file_stem().and_then(|s| s.to_str()).unwrap_or(n).to_string();
        for p in poses.poses.iter_mut().filter(|p| p.camera.is_none()) {
            let named = set.lens_of_image.iter().find(|(n, _)| *n == p.name).or_else(|| set.lens_of_image.iter().find(|(n, _)| stem(n) == stem(&p.name)));
            p.camera = named.map(|(_, id)| id.clone());
        }
        if poses.poses.is_empty() && poses.listed == 0 {
            return Err(Error::format(e, "holds no exterior orientations"));
        }
        if !set.poses.is_empty() || set.listed > 0 {
            return Err(Error::unsupported(e, format!("{} holds poses already: give one of the two", camera.display())));
        }
        set.poses = poses.poses;
        set.listed = poses.listed;
        set.lenses.extend(poses.lenses);
        set.warnings.extend(poses.warnings);
        set.files.extend(poses.files);
        if let Some(c) = poses.crs {
            set.crs = Some(c);
            set.crs_from = poses.crs_from;
        }
    }
    Ok(set)
}

/// One file; `for_lenses` when another gives the poses; `only`: see
/// [`orthority::read_csv`].
fn read_one(path: &Path, for_lenses: bool, image: Option<&Path>, angles: AngleUnit, only: Option<&Path>) -> Result<Imported> {
    let text = read_text_bounded(path, "a camera or pose file", SMALL * 64)?;
    // A byte-order mark (Windows editors) is no part of any of these forms.
    let text = text.trim_start_matches('\u{feff}');
    if text.trim().is_empty() {
        return Err(Error::format(path, "the file is empty: a camera or pose file was expected"));
    }
    let mut set = match detect(path, text)? {
        Kind::Ours => {
            let file = CameraFile::parse(text, path)?;
            Imported { base: Some(file), ..Default::default() }
        }
        Kind::OrthorityInterior => orthority::read_interior(path, text)?,
        Kind::OrthorityCsv => orthority::read_csv(path, text, angles, only)?,
        Kind::OrthorityGeoJson => orthority::read_geojson(path, text)?,
        Kind::OpenSfmReconstruction | Kind::OpenSfmCameras => opensfm::read(path, text)?,
        Kind::MetashapeXml => metashape::read(path, text)?,
        Kind::AspOpticalBar => {
            let (section, focal_mm) = crate::camera::panoramic_file::read_asp(path, text)?;
            // The CRS is left to the run (--crs, else the UTM zone under the camera).
            let file = CameraFile {
                crs: String::new(),
                camera: CameraSection { model: "panoramic".into(), focal_length_mm: Some(focal_mm) },
                interior: None,
                distortion: None,
                exterior: None,
                corrections: Default::default(),
                rpc: None,
                panoramic: Some(section),
            };
            Imported { base: Some(file), ..Default::default() }
        }
        Kind::Pix4dCalibrated => pix4d::read_calibrated(path, text, for_lenses)?,
        Kind::Pix4dCam => {
            let image = image.ok_or_else(|| {
                Error::unsupported(
                    path,
                    "gives the lens in mm, whose pixels come from the image: give it per image, or take the calibrated_camera_parameters.txt",
                )
            })?;
            let info = crate::io::source::SourceImage::info_of(image)?;
            pix4d::read_cam(path, text, [info.width, info.height])?
        }
    };
    for (id, lens) in &set.lenses {
        set.warnings.extend(narrow_lens(path, id, lens));
    }
    set.files.push(path.to_path_buf());
    Ok(set)
}

/// Narrower than this across its diagonal, a lens is doubted: mapping
/// cameras see 20° and more (a 600 mm telephoto on full frame 4°), frame
/// cameras see less than a degree only on satellites, and a focal length
/// in the wrong unit (mm where a form wants pixels or a fraction of the
/// image's side) gives tenths of one or less.
const NARROWEST_DEG: f64 = 1.0;

/// A warning where `lens` sees less than [`NARROWEST_DEG`] across.
fn narrow_lens(path: &Path, id: &str, lens: &Lens) -> Option<String> {
    let [w, h] = lens.size.map(f64::from);
    let f = lens.focal_px[0].max(lens.focal_px[1]);
    let fov = 2.0 * (w.hypot(h) / 2.0 / f).atan().to_degrees();
    (fov < NARROWEST_DEG).then(|| {
        format!(
            "{}: camera '{id}': a focal length of {f:.0} px on {w}×{h} px sees only {fov:.3}° across: a focal length in the wrong unit (mm where the form wants pixels, or a fraction of the image's side)?",
            path.display()
        )
    })
}

impl Imported {
    /// The camera file of the pose that names `image`: by file name, else
    /// by the names without their extensions. None or two: refused by name.
    pub fn camera_for(&self, image: &Path) -> Result<CameraFile> {
        let source = self.files.last().cloned().unwrap_or_default();
        if self.poses.is_empty() && self.listed == 0 {
            return match &self.base {
                Some(b) => Ok(b.clone()),
                None => Err(Error::unsupported(&source, "gives no exterior orientation: add ‹exterior› with the poses")),
            };
        }
        let file = image.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let stem = image.file_stem().and_then(|n| n.to_str()).unwrap_or("");
        let stem_of = |n: &str| Path::new(n).file_stem().and_then(|s| s.to_str()).unwrap_or(n).to_string();
        let mut found: Vec<&Pose> = self.poses.iter().filter(|p| p.name == file).collect();
        if found.is_empty() {
            found = self.poses.iter().filter(|p| p.name == stem || stem_of(&p.name) == stem).collect();
        }
        match found.as_slice() {
            [one] => self.camera_file(one, &source),
            [] => Err(Error::format(
                &source,
                format!("no exterior orientation for the image {file} ({} poses, none named {file} or {stem})", self.poses.len().max(self.listed)),
            )),
            many => Err(Error::format(
                &source,
                format!(
                    "{} exterior orientations match the image {file}: {}",
                    many.len(),
                    listed(many.iter().map(|p| p.origin.as_str()))
                ),
            )),
        }
    }

    /// Every pose's camera file, in the files' order.
    pub fn all(&self) -> Result<Vec<(String, CameraFile, String)>> {
        let source = self.files.last().cloned().unwrap_or_default();
        self.poses.iter().map(|p| Ok((p.name.clone(), self.camera_file(p, &source)?, p.origin.clone()))).collect()
    }

    /// Pose `p` with its lens, as our camera file.
    pub fn camera_file(&self, p: &Pose, source: &Path) -> Result<CameraFile> {
        let angles = AngleConvention::OmegaPhiKappa.angles(&p.r).map(f64::to_degrees);
        let exterior = Some(ExteriorSection { position: p.position, angles_deg: angles, convention: AngleConvention::OmegaPhiKappa });
        let own = self.base.as_ref().map(|b| b.crs.clone()).filter(|c| !c.trim().is_empty());
        if let (Some(ours), Some(theirs)) = (&own, &self.crs) {
            self.check_same_crs(ours, theirs, p, source)?;
        }
        let crs = self.crs.clone().or(own).unwrap_or_default();
        if let Some(base) = &self.base {
            if self.lenses.is_empty() {
                return Ok(CameraFile { crs, exterior, ..base.clone() });
            }
        }
        let lens = self.lens_of(p, source)?;
        let (camera, interior) = lens.sections();
        let distortion = (lens.distortion != DistortionSection::default()).then(|| lens.distortion.clone());
        let corrections = self.base.as_ref().map(|b| b.corrections.clone()).unwrap_or_default();
        Ok(CameraFile { crs, camera, interior: Some(interior), distortion, exterior, corrections, rpc: None, panoramic: None })
    }

    /// The camera file's `crs` and the poses' CRS must be one CRS.
    fn check_same_crs(&self, ours: &str, theirs: &str, p: &Pose, source: &Path) -> Result<()> {
        let camera = self.files.first().cloned().unwrap_or_default();
        let parse = |t: &str| Crs::parse(t, camera.parent().unwrap_or(Path::new("")));
        let ours_crs = parse(ours).map_err(|m| Error::config(&camera, "crs", m))?;
        let theirs_crs = parse(theirs).map_err(|m| Error::format(source, m))?;
        if ours_crs.agrees_at(&theirs_crs, p.position[0], p.position[1]) {
            return Ok(());
        }
        Err(Error::config(
            &camera,
            "crs",
            format!("is {ours_crs}, but {} says the exterior orientations are in {theirs_crs}: give one", self.crs_from.as_deref().unwrap_or(source).display()),
        ))
    }

    fn lens_of(&self, p: &Pose, source: &Path) -> Result<&Lens> {
        match &p.camera {
            Some(id) => self.lenses.iter().find(|(k, _)| k == id).map(|(_, l)| l).ok_or_else(|| {
                Error::at(source, &p.origin, format!("camera '{id}' is not among the interior parameters ({})", listed(self.lenses.iter().map(|(k, _)| k.as_str()))))
            }),
            None => match self.lenses.as_slice() {
                [(_, one)] => Ok(one),
                [] => Err(Error::at(source, &p.origin, "no interior parameters: give them with ‹camera›")),
                _ => Err(Error::at(source, &p.origin, format!("names no camera, and there are {} interior parameter sets", self.lenses.len()))),
            },
        }
    }
}
