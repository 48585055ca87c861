//! The camera file (TOML, one per image): the contract between gcm-ortho, the
//! synthetic-scene generator and the users' aerotriangulation exports. Field
//! names are fixed and unknown fields are an error, so a typo never changes
//! the geometry silently. See README "The camera file".

use super::atmosphere::Refraction;
use super::distortion::{Brown, Distortion};
use super::frame::FrameCamera;
use super::interior::InteriorOrientation;
use super::rotation::AngleConvention;
use crate::error::{Error, Result};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A coordinate reference system named by its EPSG code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Crs {
    pub epsg: u32,
}

impl Crs {
    pub fn parse(s: &str) -> Option<Crs> {
        let code = s.trim().strip_prefix("EPSG:").or_else(|| s.trim().strip_prefix("epsg:"))?;
        let epsg: u32 = code.parse().ok()?;
        (epsg > 0).then_some(Crs { epsg })
    }
}

impl std::fmt::Display for Crs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "EPSG:{}", self.epsg)
    }
}

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
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pixel_size_mm: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub principal_point_px: Option<[f64; 2]>,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DistortionSection {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub radial_mm: Option<[f64; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub brown: Option<Brown>,
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

/// The camera file as written on disk.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraFile {
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
}

/// A parsed and validated camera: its CRS and its sensor model.
pub struct Camera {
    pub crs: Crs,
    pub frame: FrameCamera,
    pub file: CameraFile,
}

/// One-line position "line L" of a byte offset in a text.
fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

impl CameraFile {
    pub fn read(path: &Path) -> Result<CameraFile> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::parse(&text, path)
    }

    pub fn parse(text: &str, path: &Path) -> Result<CameraFile> {
        toml::from_str::<CameraFile>(text).map_err(|e| {
            let line = e.span().map(|s| line_of(text, s.start));
            let msg = e.message().replace('\n', " ");
            Error::config(path, line.map(|l| format!("line {l}")).unwrap_or_else(|| "toml".into()), msg)
        })
    }

    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("camera files always serialise")
    }

    /// Validates every field and builds the sensor model.
    pub fn build(self, path: &Path) -> Result<Camera> {
        let err = |field: &str, msg: String| Error::config(path, field, msg);
        let crs = Crs::parse(&self.crs).ok_or_else(|| err("crs", format!("'{}' is not of the form EPSG:<code>", self.crs)))?;
        match self.camera.model.as_str() {
            "frame" => {}
            "rpc" => {
                return Err(Error::unsupported(path, "camera.model = \"rpc\" is not supported yet (frame cameras only)"))
            }
            other => return Err(err("camera.model", format!("unknown model '{other}' (expected \"frame\")"))),
        }
        let f = self.camera.focal_length_mm.ok_or_else(|| err("camera.focal_length_mm", "missing".into()))?;
        finite_positive(f).map_err(|m| err("camera.focal_length_mm", m))?;

        let interior = self.interior.clone().ok_or_else(|| err("interior", "missing section".into()))?;
        let io = build_interior(&interior).map_err(|(field, m)| err(&field, m))?;

        let distortion = match &self.distortion {
            None => Distortion::None,
            Some(DistortionSection { radial_mm: Some(_), brown: Some(_) }) => {
                return Err(err("distortion", "give radial_mm or brown, not both".into()))
            }
            Some(DistortionSection { radial_mm: Some(r), brown: None }) => {
                all_finite(r).map_err(|m| err("distortion.radial_mm", m))?;
                Distortion::Radial(*r)
            }
            Some(DistortionSection { radial_mm: None, brown: Some(b) }) => {
                all_finite(&[b.k1, b.k2, b.k3, b.p1, b.p2]).map_err(|m| err("distortion.brown", m))?;
                Distortion::Brown(*b)
            }
            Some(DistortionSection { radial_mm: None, brown: None }) => Distortion::None,
        };

        let ext = self.exterior.clone().ok_or_else(|| err("exterior", "missing section".into()))?;
        all_finite(&ext.position).map_err(|m| err("exterior.position", m))?;
        all_finite(&ext.angles_deg).map_err(|m| err("exterior.angles_deg", m))?;
        let angles = ext.angles_deg.map(f64::to_radians);
        let r = ext.convention.matrix(angles);
        let frame = FrameCamera::new(
            f,
            Vector3::from(ext.position),
            r,
            io,
            distortion,
            self.corrections.refraction,
            self.corrections.earth_curvature,
        );
        Ok(Camera { crs, frame, file: self })
    }
}

impl Camera {
    pub fn read(path: &Path) -> Result<Camera> {
        CameraFile::read(path)?.build(path)
    }
}

fn all_finite(v: &[f64]) -> std::result::Result<(), String> {
    match v.iter().find(|x| !x.is_finite()) {
        Some(x) => Err(format!("{x} is not a finite number")),
        None => Ok(()),
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

fn build_interior(s: &InteriorSection) -> std::result::Result<InteriorOrientation, (String, String)> {
    let e = |f: &str, m: String| (format!("interior.{f}"), m);
    let forms = [
        s.fiducials_mm.is_some(),
        s.fiducial_distances_mm.is_some(),
        s.pixel_size_mm.is_some(),
    ];
    if forms.iter().filter(|&&b| b).count() != 1 {
        return Err((
            "interior".into(),
            "give exactly one of fiducials_mm, fiducial_distances_mm or pixel_size_mm".into(),
        ));
    }
    let pp = s.principal_point_mm.unwrap_or([0.0, 0.0]);
    all_finite(&pp).map_err(|m| e("principal_point_mm", m))?;
    let flat = |v: &Vec<[f64; 2]>| v.iter().flatten().copied().collect::<Vec<f64>>();
    if let Some(mm) = &s.fiducials_mm {
        let px = s.fiducials_px.as_ref().ok_or_else(|| e("fiducials_px", "missing".into()))?;
        all_finite(&flat(mm)).map_err(|m| e("fiducials_mm", m))?;
        all_finite(&flat(px)).map_err(|m| e("fiducials_px", m))?;
        return InteriorOrientation::from_fiducials(mm, px, pp).map_err(|x| e("fiducials_px", x.to_string()));
    }
    if let Some(d) = s.fiducial_distances_mm {
        let px = s.fiducials_px.as_ref().ok_or_else(|| e("fiducials_px", "missing".into()))?;
        all_finite(&d).map_err(|m| e("fiducial_distances_mm", m))?;
        finite_positive(d[0].min(d[1])).map_err(|m| e("fiducial_distances_mm", m))?;
        all_finite(&flat(px)).map_err(|m| e("fiducials_px", m))?;
        return InteriorOrientation::from_fiducial_distances(d, px, pp).map_err(|x| e("fiducials_px", x.to_string()));
    }
    let ps = s.pixel_size_mm.unwrap_or(0.0);
    finite_positive(ps).map_err(|m| e("pixel_size_mm", m))?;
    let ppx = s.principal_point_px.ok_or_else(|| e("principal_point_px", "missing".into()))?;
    all_finite(&ppx).map_err(|m| e("principal_point_px", m))?;
    InteriorOrientation::digital(ps, ppx).map_err(|x| e("pixel_size_mm", x.to_string()))
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
        assert_eq!(cam.crs.epsg, 32631);
        assert_eq!(cam.frame.focal_mm, 152.82);
        assert_eq!(cam.frame.interior.residuals.len(), 4);
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
