//! The camera file (TOML, one per image): the contract between gcm-ortho, the
//! synthetic-scene generator and the users' aerotriangulation exports. Field
//! names are fixed and unknown fields are an error, so a typo never changes
//! the geometry silently. See README "The camera file".

use super::atmosphere::Refraction;
use super::distortion::{Brown, Distortion, Fisheye, Metashape, OpenCv};
use super::frame::FrameCamera;
use super::interior::InteriorOrientation;
use super::reprojected::Reprojected;
use super::rotation::AngleConvention;
use super::rpc::Rpc;
use super::satellite::RpcCamera;
use super::SensorModel;
use crate::error::{Error, Result};
use crate::geodesy::{utm_zone, Crs, Geoid, GroundCrs};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSection {
    pub model: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub focal_length_mm: Option<f64>,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InteriorSection {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fiducials_mm: Option<Vec<[f64; 2]>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fiducials_px: Option<Vec<[f64; 2]>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub principal_point_mm: Option<[f64; 2]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fiducial_distances_mm: Option<[f64; 2]>,
    /// Square pixels, or `[x, y]` (OpenCV's fx ≠ fy).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pixel_size_mm: Option<PixelSize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub principal_point_px: Option<[f64; 2]>,
    /// The size of the images this camera is for, pixels (width, height):
    /// another image is refused (a calibration from other tools holds it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub image_size_px: Option<[u32; 2]>,
    /// A digital frame's affinity and skew (Metashape's B1, B2, pixels):
    /// column = cx + x'(f + B1) + y'·B2, row = cy + y'·f on the normalised
    /// image plane (x', y' right, down), f the focal length in pixels.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub affinity_skew_px: Option<[f64; 2]>,
    /// The most a fiducial mark may sit off the fitted interior orientation,
    /// scan pixels (default 2): past it a mark was placed wrong.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_fiducial_residual_px: Option<f64>,
    /// A film camera's calibrated format, mm (width, height), centred on
    /// the fiducial centre; outside it the scan is margin, masked. Default:
    /// the standard format the fiducial marks belong to ([`standard_format_mm`]);
    /// `"scan"`: the whole scan is image.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub format_mm: Option<FormatSetting>,
    /// What the fiducial marks look like, for finding them in the scan
    /// (`fiducials`, or a scan whose `fiducials_px` are not given).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fiducial_mark: Option<MarkSetting>,
    /// The scanner's pixel size, mm (narrows the search for the marks).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scan_pixel_mm: Option<f64>,
}

/// `interior.fiducial_mark`: a shape by name (one for all marks, or one a
/// mark) with its sizes, or a template image.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MarkSetting {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shape: Option<OneOrMany>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub size_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub line_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dot_mm: Option<f64>,
    /// A small image of the mark (PNG, JPEG or TIFF, the mark at its
    /// centre), relative to the camera file; or one a mark, in the marks'
    /// order (a film's side marks differ from side to side).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub template: Option<OneOrMany>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub template_pixel_mm: Option<f64>,
    /// "light", "dark" or "auto" (default): the marks' tone on the film.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub polarity: Option<String>,
}

/// One name, or one a mark.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum OneOrMany {
    One(String),
    Many(Vec<String>),
}

/// `interior.pixel_size_mm`: one size, or across and down.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum PixelSize {
    Square(f64),
    Sides([f64; 2]),
}

impl PixelSize {
    /// (across, down), mm.
    #[must_use]
    pub fn sides(self) -> [f64; 2] {
        match self {
            PixelSize::Square(s) => [s, s],
            PixelSize::Sides(s) => s,
        }
    }
}

/// `interior.format_mm`: a size, or `"scan"` (no mask).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum FormatSetting {
    Size([f64; 2]),
    Word(String),
}

/// The square film formats of aerial cameras, mm: 18 cm (older and Soviet
/// cameras), 23 cm (RC, RMK, LMK and most others), 30 cm.
const STANDARD_FORMATS_MM: [f64; 3] = [180.0, 230.0, 300.0];

/// The standard format that fiducial marks `fiducials_mm` (fiducial-centred)
/// belong to: the smallest whose edge lies no more than 5 mm inside the
/// farthest mark (marks sit at the format's corners or edges, at most a few
/// mm outside it). `None` for marks beyond every standard format.
pub fn standard_format_mm(fiducials_mm: &[[f64; 2]]) -> Option<f64> {
    let reach = fiducials_mm.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    STANDARD_FORMATS_MM.into_iter().find(|f| f / 2.0 + 5.0 >= reach)
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DistortionSection {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radial_mm: Option<[f64; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub brown: Option<Brown>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub opencv: Option<OpenCv>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fisheye: Option<Fisheye>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub metashape: Option<Metashape>,
}

impl DistortionSection {
    /// The lens model, checked: at most one form, finite coefficients.
    fn model(&self) -> std::result::Result<Distortion, (String, String)> {
        let given = [self.radial_mm.is_some(), self.brown.is_some(), self.opencv.is_some(), self.fisheye.is_some(), self.metashape.is_some()];
        if given.iter().filter(|&&g| g).count() > 1 {
            return Err(("distortion".into(), "give one of radial_mm, brown, opencv, fisheye or metashape".into()));
        }
        let check = |name: &str, v: &[f64]| all_finite(v).map_err(|m| (format!("distortion.{name}"), m));
        if let Some(r) = self.radial_mm {
            check("radial_mm", &r)?;
            return Ok(Distortion::Radial(r));
        }
        if let Some(b) = self.brown {
            check("brown", &[b.k1, b.k2, b.k3, b.p1, b.p2])?;
            return Ok(Distortion::Brown(b));
        }
        if let Some(o) = self.opencv {
            check("opencv", &o.opencv_order())?;
            return Ok(Distortion::OpenCv(o));
        }
        if let Some(k) = self.fisheye {
            check("fisheye", &[k.k1, k.k2, k.k3, k.k4])?;
            return Ok(Distortion::Fisheye(k));
        }
        if let Some(m) = self.metashape {
            check("metashape", &[m.k1, m.k2, m.k3, m.k4, m.p1, m.p2, m.p3, m.p4])?;
            return Ok(Distortion::Metashape(m));
        }
        Ok(Distortion::None)
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExteriorSection {
    pub position: [f64; 3],
    pub angles_deg: [f64; 3],
    pub convention: AngleConvention,
}

fn default_refraction() -> Refraction {
    Refraction::None
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CorrectionsSection {
    #[serde(default = "default_refraction")]
    pub refraction: Refraction,
    #[serde(default)]
    pub earth_curvature: bool,
}

impl Default for CorrectionsSection {
    fn default() -> Self {
        CorrectionsSection { refraction: Refraction::None, earth_curvature: false }
    }
}

/// `[rpc]` of a camera file with `model = "rpc"`: the coefficients in a
/// file of any supported format (`file`, relative to the camera file) or
/// inline under GDAL's names in lower case.
/// Unknown keys are refused by `build_rpc` (serde cannot deny them beside a
/// flattened map).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RpcSection {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// (column, row) of the image's first pixel in the scene the RPC
    /// describes (the image is a crop of it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub offset_px: Option<[f64; 2]>,
    /// Geoid grid (PROJ `.gtx` or GeoTIFF): the DEM's heights are above this geoid.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub geoid: Option<String>,
    /// Where `file` holds the RPCs of several images (Orthority's YAML):
    /// this image's file name.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub image: Option<String>,
    #[serde(flatten)]
    pub inline: std::collections::BTreeMap<String, toml::Value>,
}

/// The camera file as written on disk.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraFile {
    /// Any CRS `geodesy::Crs::parse` reads; may be left out of a block's
    /// interior file when a `.prj` lies beside its CSV.
    #[serde(default)]
    pub crs: String,
    pub camera: CameraSection,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interior: Option<InteriorSection>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub distortion: Option<DistortionSection>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exterior: Option<ExteriorSection>,
    #[serde(default)]
    pub corrections: CorrectionsSection,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rpc: Option<RpcSection>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub panoramic: Option<super::panoramic_file::PanoramicSection>,
}

/// The sensor model a camera file describes.
#[allow(clippy::large_enum_variant)] // one a run, never moved about in numbers
pub enum Sensor {
    Frame(FrameCamera),
    Rpc(RpcCamera),
    /// A frame camera whose orthophoto is made in another CRS.
    ReprojectedFrame(Reprojected<FrameCamera>),
    /// A panoramic (optical-bar) film camera.
    Panoramic(super::panoramic::PanoramicCamera),
}

/// A parsed and validated camera: its ground CRS and its sensor model.
pub struct Camera {
    /// The CRS of the model's ground (X, Y): the camera file's, or the
    /// orthophoto's after [`Camera::in_crs`].
    pub crs: Crs,
    pub sensor: Sensor,
    pub file: CameraFile,
    /// Doubtful things the camera's files hold, for the run to print.
    pub warnings: Vec<String>,
    /// A drone's height above its take-off point from its own tags: with the
    /// DEM, a check of the height the camera is placed at.
    pub relative_altitude: Option<f64>,
}

/// One-line position "line L" of a byte offset in a text.
fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

impl CameraFile {
    /// The files a camera file at `path` names (an RPC file, a geoid grid,
    /// a fiducial mark's template), each with what it is: inputs of a run
    /// as much as the camera file. None where `path` is not a camera file
    /// (its reader says why).
    pub fn files_named_in(path: &Path) -> Vec<(&'static str, PathBuf)> {
        let Ok(file) = CameraFile::read(path) else { return Vec::new() };
        let near = |f: &String| path.parent().unwrap_or(Path::new("")).join(f);
        let rpc = file.rpc.as_ref();
        let templates = match file.interior.as_ref().and_then(|i| i.fiducial_mark.as_ref()).and_then(|m| m.template.as_ref()) {
            Some(OneOrMany::One(t)) => vec![t],
            Some(OneOrMany::Many(v)) => v.iter().collect(),
            None => Vec::new(),
        };
        let panoramic_geoid = file.panoramic.as_ref().and_then(|p| p.geoid.as_ref());
        [("RPC file", rpc.and_then(|r| r.file.as_ref())), ("geoid grid", rpc.and_then(|r| r.geoid.as_ref())), ("geoid grid", panoramic_geoid)]
            .into_iter()
            .chain(templates.into_iter().map(|t| ("fiducial template", Some(t))))
            .filter_map(|(what, f)| Some((what, near(f?))))
            .collect()
    }

    pub fn read(path: &Path) -> Result<CameraFile> {
        let text = crate::io::bounded_read::read_text_bounded(path, "a camera file", crate::io::bounded_read::SMALL)?;
        Self::parse(&text, path)
    }

    pub fn parse(text: &str, path: &Path) -> Result<CameraFile> {
        let file = toml::from_str::<CameraFile>(text).map_err(|e| {
            let line = e.span().map(|s| line_of(text, s.start));
            let msg = e.message().replace('\n', " ");
            Error::config(path, line.map(|l| format!("line {l}")).unwrap_or_else(|| "toml".into()), msg)
        })?;
        if let Some((key, given, read)) = crate::io::toml_lengths::first_cut_array(text, &file) {
            return Err(Error::config(path, key, format!("{given} entries where {read} are read")));
        }
        Ok(file)
    }

    /// A film camera whose marks are calibrated but not measured in the
    /// scan: they are found in it (`fiducials::for_camera`, joined in `scene::camera`).
    #[must_use]
    pub fn needs_marks(&self) -> bool {
        self.interior.as_ref().is_some_and(|i| (i.fiducials_mm.is_some() || i.fiducial_distances_mm.is_some()) && i.fiducials_px.is_none())
    }

    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("camera files always serialise")
    }

    /// Validates every field and builds the sensor model.
    pub fn build(self, path: &Path) -> Result<Camera> {
        let err = |field: &str, msg: String| Error::config(path, field, msg);
        match self.camera.model.as_str() {
            "frame" => {}
            "rpc" => return self.build_rpc(path),
            "panoramic" => return self.build_panoramic(path),
            other => return Err(err("camera.model", format!("unknown model '{other}' (expected \"frame\", \"rpc\" or \"panoramic\")"))),
        }
        if self.crs.trim().is_empty() {
            return Err(err("crs", "the CRS of the positions is not given: give crs here, a .prj beside the exterior orientations, or ‹crs›".into()));
        }
        let crs = Crs::parse(&self.crs, path.parent().unwrap_or(Path::new(""))).map_err(|m| err("crs", m))?;
        for (section, present, model) in [("rpc", self.rpc.is_some(), "rpc"), ("panoramic", self.panoramic.is_some(), "panoramic")] {
            if present {
                return Err(err(section, format!("only for camera.model = \"{model}\"")));
            }
        }
        let f = self.camera.focal_length_mm.ok_or_else(|| err("camera.focal_length_mm", "missing".into()))?;
        finite_positive(f).map_err(|m| err("camera.focal_length_mm", m))?;
        within_a_lens(f).map_err(|m| err("camera.focal_length_mm", m))?;
        if let Some(pp) = self.interior.as_ref().and_then(|i| i.principal_point_mm) {
            pp.iter().try_for_each(|&v| within_a_lens(v)).map_err(|m| err("interior.principal_point_mm", m))?;
        }

        let interior = self.interior.clone().ok_or_else(|| err("interior", "missing section".into()))?;
        let io = build_interior(&interior, f).map_err(|(field, m)| err(&field, m))?;

        let distortion = match &self.distortion {
            None => Distortion::None,
            Some(d) => d.model().map_err(|(field, m)| err(&field, m))?,
        };

        let ext = self.exterior.clone().ok_or_else(|| err("exterior", "missing section".into()))?;
        all_finite(&ext.position).map_err(|m| err("exterior.position", m))?;
        all_finite(&ext.angles_deg).map_err(|m| err("exterior.angles_deg", m))?;
        plausible_position(&crs, ext.position).map_err(|m| err("exterior.position", m))?;
        let angles = ext.angles_deg.map(f64::to_radians);
        let r = ext.convention.matrix(angles);
        let mut frame = FrameCamera::new(f, Vector3::from(ext.position), r, io, distortion, self.corrections.refraction, self.corrections.earth_curvature);
        if let Some(size) = film_format(&interior).map_err(|m| err("interior.format_mm", m))? {
            let pp = interior.principal_point_mm.unwrap_or([0.0, 0.0]);
            frame = frame.with_format(size, pp).ok_or_else(|| err("interior.format_mm", "the format maps to no area of the scan".into()))?;
        }
        Ok(Camera { crs, sensor: Sensor::Frame(frame), file: self, warnings: Vec::new(), relative_altitude: None })
    }

    /// Refuses, by name, a frame's sections and the other models' in the
    /// file of a model whose own section is `own` (`what` names the model).
    fn refuse_sections_but(&self, path: &Path, own: &str, what: &str) -> Result<()> {
        let present = [
            ("interior", self.interior.is_some()),
            ("exterior", self.exterior.is_some()),
            ("distortion", self.distortion.is_some()),
            ("rpc", self.rpc.is_some()),
            ("panoramic", self.panoramic.is_some()),
        ];
        match present.into_iter().find(|&(section, is)| is && section != own) {
            Some((section, _)) => Err(Error::config(path, section, format!("not used by {what}"))),
            None => Ok(()),
        }
    }

    /// `model = "rpc"`: the RPC from `[rpc]`, the ground CRS from `crs`
    /// (`"auto"`: the WGS84 UTM zone of the scene's centre).
    fn build_rpc(self, path: &Path) -> Result<Camera> {
        let err = |field: &str, msg: String| Error::config(path, field, msg);
        self.refuse_sections_but(path, "rpc", "an RPC camera")?;
        if self.camera.focal_length_mm.is_some() {
            return Err(err("camera.focal_length_mm", "not used by an RPC camera".into()));
        }
        let sec = self.rpc.clone().ok_or_else(|| err("rpc", "missing section".into()))?;
        let near = |f: &str| -> PathBuf { path.parent().unwrap_or(Path::new("")).join(f) };
        let mut rpc = match (&sec.file, sec.inline.is_empty()) {
            (Some(f), true) => Rpc::read_for(&near(f), sec.image.as_deref())?,
            (None, false) => {
                let get = |k: &str| -> Option<Vec<f64>> {
                    match sec.inline.get(&k.to_ascii_lowercase())? {
                        toml::Value::Array(a) => a.iter().map(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64))).collect(),
                        v => v.as_float().or_else(|| v.as_integer().map(|i| i as f64)).map(|x| vec![x]),
                    }
                };
                let known: Vec<String> = super::rpc::GDAL_NAMES.iter().map(|k| k.to_ascii_lowercase()).collect();
                if let Some(k) = sec.inline.keys().find(|k| !known.contains(k)) {
                    return Err(err(&format!("rpc.{k}"), "unknown field".into()));
                }
                Rpc::from_map(&get, path)?
            }
            (Some(_), false) => return Err(err("rpc", "give file or the inline coefficients, not both".into())),
            (None, true) => return Err(err("rpc", "give file = \"…\" or the coefficients inline".into())),
        };
        if let Some(o) = sec.offset_px {
            all_finite(&o).map_err(|m| err("rpc.offset_px", m))?;
            rpc = rpc.cropped(o[0], o[1]);
        }
        let geoid = match &sec.geoid {
            Some(g) => {
                let geoid = Geoid::read(&near(g))?;
                if geoid.undulation(rpc.long_off, rpc.lat_off).is_none() {
                    return Err(Error::format(
                        &geoid.path,
                        format!("the geoid grid does not cover the scene's centre ({:.4}°, {:.4}°)", rpc.long_off, rpc.lat_off),
                    ));
                }
                Some(geoid)
            }
            None => None,
        };
        let crs = if self.crs.trim().eq_ignore_ascii_case("auto") {
            utm_zone(rpc.long_off, rpc.lat_off)
        } else {
            Crs::parse(&self.crs, path.parent().unwrap_or(Path::new(""))).map_err(|m| err("crs", format!("{m}, or \"auto\" (the scene's UTM zone)")))?
        };
        let ground = GroundCrs::new(&crs).map_err(|m| err("crs", m))?;
        let model = RpcCamera::new(rpc, ground, geoid);
        Ok(Camera { crs, sensor: Sensor::Rpc(model), file: self, warnings: Vec::new(), relative_altitude: None })
    }
}

impl CameraFile {
    /// A camera file for `bar`, its orthophoto in `crs` ("auto": the UTM
    /// zone under the camera).
    #[must_use]
    pub fn panoramic(bar: &super::panoramic::OpticalBar, crs: &str) -> CameraFile {
        CameraFile {
            crs: crs.into(),
            camera: CameraSection { model: "panoramic".into(), focal_length_mm: Some(bar.focal * 1000.0) },
            interior: None,
            distortion: None,
            exterior: None,
            corrections: CorrectionsSection::default(),
            rpc: None,
            panoramic: Some(super::panoramic_file::PanoramicSection::of(bar, None)),
        }
    }

    /// `model = "panoramic"`: the optical bar from `[panoramic]`, the
    /// ground CRS from `crs` (empty or `"auto"`: the UTM zone under the
    /// camera's first position).
    fn build_panoramic(self, path: &Path) -> Result<Camera> {
        let err = |field: &str, msg: String| Error::config(path, field, msg);
        self.refuse_sections_but(path, "panoramic", "a panoramic camera")?;
        let sec = self.panoramic.clone().ok_or_else(|| err("panoramic", "missing section".into()))?;
        let f = self.camera.focal_length_mm.ok_or_else(|| err("camera.focal_length_mm", "missing".into()))?;
        let bar = sec.bar(f);
        bar.check().map_err(|(field, m)| err(&field, m))?;
        let near = |f: &str| path.parent().unwrap_or(Path::new("")).join(f);
        let (lon, lat, _) = crate::geodesy::ecef::from_ecef(bar.position);
        let geoid = match &sec.geoid {
            Some(g) => {
                let geoid = Geoid::read(&near(g))?;
                if geoid.undulation(lon, lat).is_none() {
                    return Err(Error::format(&geoid.path, format!("the geoid grid does not cover the camera's position ({lon:.4}°, {lat:.4}°)")));
                }
                Some(geoid)
            }
            None => None,
        };
        let crs = if self.crs.trim().is_empty() || self.crs.trim().eq_ignore_ascii_case("auto") {
            utm_zone(lon, lat)
        } else {
            Crs::parse(&self.crs, path.parent().unwrap_or(Path::new("")))
                .map_err(|m| err("crs", format!("{m}, or \"auto\" (the UTM zone under the camera)")))?
        };
        let ground = GroundCrs::new(&crs).map_err(|m| err("crs", m))?;
        let model = super::panoramic::PanoramicCamera::new(bar, ground, geoid);
        Ok(Camera { crs, sensor: Sensor::Panoramic(model), file: self, warnings: Vec::new(), relative_altitude: None })
    }
}

impl Camera {
    /// An error naming a mapped file of the camera's (an RPC's geoid grid)
    /// truncated while it was read.
    pub fn check_intact(&self) -> Result<()> {
        match &self.sensor {
            Sensor::Rpc(r) => r.geoid.as_ref().map_or(Ok(()), |g| g.check_intact()),
            _ => Ok(()),
        }
    }

    pub fn read(path: &Path) -> Result<Camera> {
        CameraFile::read(path)?.build(path)
    }

    /// The camera file for an RPC file given on the command line.
    /// `image`: the image's file name, for a file of several images' RPCs.
    pub fn rpc_file(rpc: &Path, offset: Option<[f64; 2]>, geoid: Option<&Path>, image: Option<&str>) -> CameraFile {
        let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf()).to_string_lossy().into_owned();
        CameraFile {
            crs: "auto".into(),
            camera: CameraSection { model: "rpc".into(), focal_length_mm: None },
            interior: None,
            distortion: None,
            exterior: None,
            corrections: CorrectionsSection::default(),
            rpc: Some(RpcSection {
                file: Some(abs(rpc)),
                offset_px: offset,
                geoid: geoid.map(abs),
                image: image.map(str::to_string),
                inline: Default::default(),
            }),
            panoramic: None,
        }
    }

    pub fn model(&self) -> &dyn SensorModel {
        match &self.sensor {
            Sensor::Frame(f) => f,
            Sensor::Rpc(r) => r,
            Sensor::ReprojectedFrame(r) => r,
            Sensor::Panoramic(p) => p,
        }
    }

    /// This camera making its orthophoto in the CRS `ground`: an RPC's
    /// ground conversion is that CRS's; a frame camera's ground points are
    /// converted to its own CRS first.
    pub fn in_crs(self, ground: &Crs) -> std::result::Result<Camera, String> {
        if *ground == self.crs {
            return Ok(self);
        }
        let sensor = match self.sensor {
            Sensor::Rpc(r) => Sensor::Rpc(RpcCamera::new(r.rpc, GroundCrs::new(ground)?, r.geoid)),
            Sensor::Panoramic(p) => Sensor::Panoramic(super::panoramic::PanoramicCamera::new(p.bar, GroundCrs::new(ground)?, p.geoid)),
            // The same CRS spelled another way (a .prj of EPSG:32631).
            Sensor::Frame(f) if self.crs.agrees_at(ground, f.centre.x, f.centre.y) => Sensor::Frame(f),
            Sensor::Frame(f) => {
                let near = (f.centre.x, f.centre.y);
                Sensor::ReprojectedFrame(Reprojected::new(f, &self.crs, ground, near)?)
            }
            Sensor::ReprojectedFrame(r) => {
                let own = r.own_crs().clone();
                let f = r.inner;
                let near = (f.centre.x, f.centre.y);
                Sensor::ReprojectedFrame(Reprojected::new(f, &own, ground, near)?)
            }
        };
        Ok(Camera { crs: ground.clone(), sensor, file: self.file, warnings: self.warnings, relative_altitude: self.relative_altitude })
    }

    /// The frame camera, or an error naming the file for a model that is not one.
    pub fn frame(&self, path: &Path) -> Result<&FrameCamera> {
        match &self.sensor {
            Sensor::Frame(f) => Ok(f),
            Sensor::ReprojectedFrame(r) => Ok(&r.inner),
            Sensor::Rpc(_) => Err(Error::unsupported(path, "this needs a frame camera, not an RPC model")),
            Sensor::Panoramic(_) => Err(Error::unsupported(path, "this needs a frame camera, not a panoramic one")),
        }
    }

    /// A ground height to start ray casting from when the DEM gives none:
    /// 1000 m below a frame camera, the RPC's mid height.
    pub fn height_hint(&self) -> f64 {
        match &self.sensor {
            Sensor::Frame(f) => f.centre.z - 1000.0,
            Sensor::ReprojectedFrame(r) => r.inner.centre.z - 1000.0,
            Sensor::Rpc(r) => r.height_hint(),
            Sensor::Panoramic(p) => p.height_hint(),
        }
    }
}

/// The most a camera may be above or below the ground, metres: beyond a
/// geostationary orbit's height no frame camera images the Earth.
const MOST_HEIGHT: f64 = 1e8;

/// Refuses a camera position that is no place in its CRS (a translation of
/// 1e308, a height of 1e300), naming the position rather than the DEM it
/// then fails to meet.
fn plausible_position(crs: &Crs, [x, y, z]: [f64; 3]) -> std::result::Result<(), String> {
    // (Huge numbers shown as 1e308, not 309 digits.)
    let shown = |v: f64| if v.abs() < 1e9 { format!("{v}") } else { format!("{v:e}") };
    if z.abs() > MOST_HEIGHT {
        return Err(format!("a height of {} m is no camera's (at most {MOST_HEIGHT:e} m)", shown(z)));
    }
    // (A CRS that is no ground, a geocentric one, is left to the model.)
    let Ok(ground) = crate::geodesy::GroundCrs::new(crs) else { return Ok(()) };
    match ground.to_lonlat(x, y) {
        Some((lon, lat)) if lon.is_finite() && lat.is_finite() && lat.abs() <= 90.0 => Ok(()),
        _ => Err(format!("({}, {}) is no place in {crs}", shown(x), shown(y))),
    }
}

fn all_finite(v: &[f64]) -> std::result::Result<(), String> {
    match v.iter().find(|x| !x.is_finite()) {
        Some(x) => Err(format!("{x} is not a finite number")),
        None => Ok(()),
    }
}

/// A length in a lens's interior orientation: within a kilometre (lenses
/// in pixel units, whose "mm" are pixels, included). Past it, the value
/// would pass for a wrong distortion or format, which are then blamed.
/// (NaN passes: the finiteness check names it as such.)
fn within_a_lens(v: f64) -> std::result::Result<(), String> {
    match !(v.abs() > 1e6) {
        true => Ok(()),
        false => Err(format!("{v:e} mm is no lens's (1 km at most)")),
    }
}

fn finite_positive(v: f64) -> std::result::Result<(), String> {
    if !v.is_finite() {
        Err(format!("{v} is not a finite number"))
    } else if v <= 0.0 {
        Err(format!("{v} must be positive"))
    } else {
        Ok(())
    }
}

/// Refuses fiducial marks that sit further off the fitted interior
/// orientation than `limit` pixels (default 2), listing every mark's
/// residual so that the one placed wrong shows.
fn check_residuals(io: &InteriorOrientation, limit: Option<f64>) -> std::result::Result<(), String> {
    let limit = limit.unwrap_or(2.0);
    let off: Vec<f64> = io.residuals.iter().map(|r| r.px[0].hypot(r.px[1])).collect();
    let worst = off.iter().cloned().fold(0.0, f64::max);
    if !(worst <= limit) {
        let list: Vec<String> = off.iter().enumerate().map(|(k, d)| format!("mark {}: {d:.2} px", k + 1)).collect();
        return Err(format!(
            "a mark sits {worst:.2} px off the fitted interior orientation, more than {limit} px (max_fiducial_residual_px): {}; one was placed wrong?",
            list.join(", ")
        ));
    }
    Ok(())
}

/// The format a film scan is masked to (mm), or `None`: a digital camera,
/// `format_mm = "scan"`, or marks beyond every standard format.
/// A warning where the frame camera of `file` (at `path`, for a scan of
/// `scan` pixels, `above_ground` metres up) sees less than a degree
/// across, or two from an aircraft (its frame: the film's
/// format, else the sensor's pixels, else the spread of its marks): a
/// focal length in pixels, most likely, as other tools give it (mapping
/// cameras see 20° and more).
pub fn narrow_view(path: &Path, file: &CameraFile, scan: (u32, u32), above_ground: f64) -> Option<String> {
    let (f, s) = (file.camera.focal_length_mm?, file.interior.as_ref()?);
    let format = film_format(s).ok().flatten();
    let [w, h] = s.image_size_px.unwrap_or([scan.0, scan.1]);
    let sensor = s.pixel_size_mm.map(|p| [p.sides()[0] * f64::from(w), p.sides()[1] * f64::from(h)]);
    let marks = s.fiducials_mm.as_ref().filter(|m| m.len() >= 2).map(|m| {
        let span = |k: usize| m.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max) - m.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min);
        [span(0), span(1)]
    });
    let [w, h] = format.or(sensor).or(marks)?;
    let fov = 2.0 * (w.hypot(h) / 2.0 / f).atan().to_degrees();
    // Satellites' frame cameras see under a degree from hundreds of km;
    // an aerial one (under 10 km above the ground) under two, none.
    let aerial = above_ground < 10_000.0;
    // (Under 0.2° the camera is refused: no lens of this image.)
    (fov >= 0.2 && (fov < 1.0 || (aerial && fov < 2.0))).then(|| {
        format!(
            "{}: camera.focal_length_mm = {f} on a frame of {w:.1}×{h:.1} mm sees only {fov:.3}° across: a focal length in pixels (it is in millimetres here)?",
            path.display()
        )
    })
}

fn film_format(s: &InteriorSection) -> std::result::Result<Option<[f64; 2]>, String> {
    let film = s.fiducials_mm.is_some() || s.fiducial_distances_mm.is_some();
    match &s.format_mm {
        Some(FormatSetting::Word(w)) if w == "scan" => Ok(None),
        Some(FormatSetting::Word(w)) => Err(format!("'{w}' is neither [width, height] in mm nor \"scan\"")),
        Some(FormatSetting::Size(_)) if !film => Err("only for a film camera (fiducials); a digital frame is all image".into()),
        Some(FormatSetting::Size([w, h])) => {
            finite_positive(w.min(*h)).map_err(|m| format!("{m} (width and height in mm)"))?;
            all_finite(&[*w, *h])?;
            Ok(Some([*w, *h]))
        }
        None if !film => Ok(None),
        None => {
            let marks: Vec<[f64; 2]> = match (&s.fiducials_mm, s.fiducial_distances_mm) {
                (Some(mm), _) => mm.clone(),
                (None, Some([dx, dy])) => vec![[dx / 2.0, dy / 2.0]],
                (None, None) => Vec::new(),
            };
            Ok(standard_format_mm(&marks).map(|f| [f, f]))
        }
    }
}

fn build_interior(s: &InteriorSection, focal_mm: f64) -> std::result::Result<InteriorOrientation, (String, String)> {
    let e = |f: &str, m: String| (format!("interior.{f}"), m);
    let forms = [s.fiducials_mm.is_some(), s.fiducial_distances_mm.is_some(), s.pixel_size_mm.is_some()];
    if forms.iter().filter(|&&b| b).count() != 1 {
        return Err(("interior".into(), "give exactly one of fiducials_mm, fiducial_distances_mm or pixel_size_mm".into()));
    }
    let pp = s.principal_point_mm.unwrap_or([0.0, 0.0]);
    all_finite(&pp).map_err(|m| e("principal_point_mm", m))?;
    let flat = |v: &Vec<[f64; 2]>| v.iter().flatten().copied().collect::<Vec<f64>>();
    const UNMEASURED: &str = "missing: measure the marks with `gcm-ortho fiducials`, or rectify with the scan so that they are found";
    if let Some(mm) = &s.fiducials_mm {
        let px = s.fiducials_px.as_ref().ok_or_else(|| e("fiducials_px", UNMEASURED.into()))?;
        all_finite(&flat(mm)).map_err(|m| e("fiducials_mm", m))?;
        all_finite(&flat(px)).map_err(|m| e("fiducials_px", m))?;
        let io = InteriorOrientation::from_fiducials(mm, px, pp).map_err(|x| e("fiducials_px", x.to_string()))?;
        check_residuals(&io, s.max_fiducial_residual_px).map_err(|m| e("fiducials_px", m))?;
        return Ok(io);
    }
    if let Some(d) = s.fiducial_distances_mm {
        let px = s.fiducials_px.as_ref().ok_or_else(|| e("fiducials_px", UNMEASURED.into()))?;
        all_finite(&d).map_err(|m| e("fiducial_distances_mm", m))?;
        finite_positive(d[0].min(d[1])).map_err(|m| e("fiducial_distances_mm", m))?;
        all_finite(&flat(px)).map_err(|m| e("fiducials_px", m))?;
        return InteriorOrientation::from_fiducial_distances(d, px, pp).map_err(|x| e("fiducials_px", x.to_string()));
    }
    let ps = s.pixel_size_mm.map_or([0.0, 0.0], PixelSize::sides);
    all_finite(&ps).map_err(|m| e("pixel_size_mm", m))?;
    finite_positive(ps[0].min(ps[1])).map_err(|m| e("pixel_size_mm", m))?;
    let ppx = s.principal_point_px.ok_or_else(|| e("principal_point_px", "missing".into()))?;
    all_finite(&ppx).map_err(|m| e("principal_point_px", m))?;
    match s.affinity_skew_px {
        None => InteriorOrientation::digital_sides(ps, ppx).map_err(|x| e("pixel_size_mm", x.to_string())),
        Some(b) => {
            all_finite(&b).map_err(|m| e("affinity_skew_px", m))?;
            InteriorOrientation::digital_affine(ps, ppx, b, focal_mm).map_err(|x| e("affinity_skew_px", x.to_string()))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
crs = "EPSG:32631"
[camera]
model = "frame"
focal_length_mm = 152.82
[interior]
fiducials_mm = [[-106.0, -106.0], [106.0, 106.0], [-106.0, 106.0], [106.0, -106.0]]
fiducials_px = [[412.7, 9531.2], [9488.1, 455.0], [430.2, 470.9], [9470.4, 9515.6]]
principal_point_mm = [0.003, -0.011]
[distortion]
radial_mm = [0.0, 2.1e-8, -3.0e-12]
[exterior]
position = [642310.25, 4829117.80, 1240.5]
angles_deg = [0.81, -1.12, 91.4]
convention = "alpha-omega-kappa"
[corrections]
refraction = "auto"
earth_curvature = true
"#;

    fn build(text: &str) -> Result<Camera> {
        CameraFile::parse(text, Path::new("cam.toml"))?.build(Path::new("cam.toml"))
    }

    #[test]
    fn the_issue_example_parses() {
        let cam = build(GOOD).unwrap();
        assert_eq!(cam.crs.epsg(), Some(32631));
        let frame = cam.frame(Path::new("cam.toml")).unwrap();
        assert_eq!(frame.focal_mm, 152.82);
        assert_eq!(frame.interior.residuals.len(), 4);
    }

    #[test]
    fn a_film_camera_is_masked_to_its_format() {
        // Marks at ±106 mm: the 23 cm format; its corners in scan pixels are
        // the fiducial fit's image of (±115 − pp) mm.
        let cam = build(GOOD).unwrap();
        let frame = cam.frame(Path::new("cam.toml")).unwrap();
        let area = frame.image_area().expect("a film scan has a format");
        let pp = [0.003, -0.011];
        let want = frame.interior.mm_to_px(-115.0 - pp[0], -115.0 - pp[1]);
        let got = area.corners()[0];
        assert!((got.0 - want.0).abs() < 1e-9 && (got.1 - want.1).abs() < 1e-9, "{got:?} {want:?}");
        // Given, or the whole scan.
        let with = |v: &str| build(&GOOD.replace("[interior]\n", &format!("[interior]\nformat_mm = {v}\n")));
        let corner = with("[180, 200]").unwrap().model().image_area().unwrap().corners()[2];
        let want = frame.interior.mm_to_px(90.0 - pp[0], 100.0 - pp[1]);
        assert!((corner.0 - want.0).abs() < 1e-9 && (corner.1 - want.1).abs() < 1e-9);
        assert!(with("\"scan\"").unwrap().model().image_area().is_none());
        for (bad, word) in [("\"all\"", "neither"), ("[0, 230]", "positive"), ("[230, nan]", "finite")] {
            let e = with(bad).err().unwrap().to_string();
            assert!(e.contains("interior.format_mm") && e.contains(word), "{bad}: {e}");
        }
        // A digital frame is all image: no format to give.
        let digital = GOOD
            .replace("fiducials_mm", "# fiducials_mm")
            .replace("fiducials_px", "# fiducials_px")
            .replace("principal_point_mm = [0.003, -0.011]", "pixel_size_mm = 0.02\nprincipal_point_px = [5000.0, 5000.0]");
        assert!(build(&digital).unwrap().model().image_area().is_none());
        let e = build(&digital.replace("[interior]\n", "[interior]\nformat_mm = [230, 230]\n")).err().unwrap().to_string();
        assert!(e.contains("interior.format_mm") && e.contains("only for a film camera"), "{e}");
        // The standard formats the marks belong to.
        assert_eq!(standard_format_mm(&[[-117.5, 117.5]]), Some(230.0));
        assert_eq!(standard_format_mm(&[[106.0, -106.0], [0.0, 113.0]]), Some(230.0));
        assert_eq!(standard_format_mm(&[[88.0, -88.0]]), Some(180.0));
        assert_eq!(standard_format_mm(&[[150.0, 0.0]]), Some(300.0));
        assert_eq!(standard_format_mm(&[[170.0, 0.0]]), None);
    }

    #[test]
    fn unknown_field_is_an_error_with_its_line() {
        let bad = GOOD.replace("focal_length_mm", "focal_lenght_mm");
        let e = build(&bad).err().unwrap().to_string();
        assert!(e.contains("cam.toml") && e.contains("focal_lenght_mm") && e.contains("line 5"), "{e}");
    }

    #[test]
    fn nan_focal_and_negative_focal_are_errors() {
        for (v, word) in [("nan", "finite"), ("-152.0", "positive"), ("inf", "finite")] {
            let bad = GOOD.replace("152.82", v);
            let e = build(&bad).err().unwrap().to_string();
            assert!(e.contains("camera.focal_length_mm") && e.contains(word), "{e}");
        }
    }

    #[test]
    fn too_few_fiducials_are_an_error() {
        let bad = GOOD
            .replace("[[-106.0, -106.0], [106.0, 106.0], [-106.0, 106.0], [106.0, -106.0]]", "[[-106.0, -106.0], [106.0, 106.0]]")
            .replace("[[412.7, 9531.2], [9488.1, 455.0], [430.2, 470.9], [9470.4, 9515.6]]", "[[412.7, 9531.2], [9488.1, 455.0]]");
        let e = build(&bad).err().unwrap().to_string();
        assert!(e.contains("at least 3"), "{e}");
    }

    #[test]
    fn missing_section_is_named() {
        let bad = GOOD.replace("[exterior]", "[exteriorx]");
        let e = build(&bad).err().unwrap().to_string();
        assert!(e.contains("exteriorx"), "{e}");
        let cut = &GOOD[..GOOD.find("[exterior]").unwrap()];
        let e = build(cut).err().unwrap().to_string();
        assert!(e.contains("exterior") && e.contains("missing"), "{e}");
    }

    #[test]
    fn round_trips_through_toml() {
        let cam = build(GOOD).unwrap();
        let again = build(&cam.file.to_toml()).unwrap();
        assert_eq!(again.file, cam.file);
    }
}
