//! `model = "panoramic"` in the camera file: the `[panoramic]` section
//! (the camera file builds it: `CameraFile::build`), and Ames Stereo
//! Pipeline's `OPTICAL_BAR` camera files (VERSION_4) read as they are into
//! it.
//!
//! ASP's pixel (0, 0) is the first pixel's centre; ours is (0.5, 0.5), so
//! its `image_center` is shifted by half a pixel on reading. Its `iR` is
//! the camera-to-ECEF rotation, written row by row.

use super::panoramic::OpticalBar;
use crate::error::{Error, Result};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The order the lens swept the film's columns in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScanDirection {
    LeftToRight,
    RightToLeft,
}

fn one() -> f64 {
    1.0
}

fn earth_radius() -> f64 {
    6_371_000.0
}

/// `[panoramic]`: the optical bar's parameters (`camera.focal_length_mm`
/// gives the focal length).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PanoramicSection {
    /// Columns (along the scan) and rows of the scan the camera is for.
    pub size_px: [u32; 2],
    /// Where the lens axis meets the film at the scan's middle, pixels
    /// (pixel centres at +½: the middle of a W×H scan is W/2, H/2).
    pub centre_px: [f64; 2],
    pub pixel_size_mm: f64,
    /// Seconds the scan takes from its first column to its last.
    pub scan_time_s: f64,
    pub scan: ScanDirection,
    /// The lens looking forward of the vertical along the flight (the
    /// aft camera of a pair: negative), degrees.
    #[serde(default)]
    pub forward_tilt_deg: f64,
    /// The projection centre at the first column scanned, ECEF metres.
    pub position_ecef: [f64; 3],
    /// Camera frame (x along the scan, y along the flight, z out of the
    /// lens) → ECEF, row by row.
    pub rotation: [[f64; 3]; 3],
    /// Metres a second, along the camera's y axis before the tilt.
    #[serde(default)]
    pub speed_m_s: f64,
    /// The centre's whole motion over the scan, ECEF metres (instead of
    /// `speed_m_s`: ASP's later form).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion_ecef: Option<[f64; 3]>,
    /// The image motion compensation's factor (1: full, 0: none; the
    /// sign flips it).
    #[serde(default = "one")]
    pub motion_compensation: f64,
    #[serde(default = "earth_radius")]
    pub mean_earth_radius_m: f64,
    #[serde(default)]
    pub mean_surface_elevation_m: f64,
    /// The scanning mirror's distance in front of the lens (KVR-1000:
    /// 26.07), mm.
    #[serde(default)]
    pub mirror_offset_mm: f64,
    /// Geoid grid (PROJ `.gtx` or GeoTIFF): the DEM's heights are above it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub geoid: Option<String>,
}

impl PanoramicSection {
    /// The optical bar of this section and a focal length in mm.
    #[must_use]
    pub fn bar(&self, focal_mm: f64) -> OpticalBar {
        let r = self.rotation;
        OpticalBar {
            size: self.size_px,
            centre_px: self.centre_px,
            pitch: self.pixel_size_mm / 1000.0,
            focal: focal_mm / 1000.0,
            scan_time: self.scan_time_s,
            left_to_right: self.scan == ScanDirection::LeftToRight,
            forward_tilt: self.forward_tilt_deg.to_radians(),
            position: Vector3::from(self.position_ecef),
            rotation: Matrix3::new(r[0][0], r[0][1], r[0][2], r[1][0], r[1][1], r[1][2], r[2][0], r[2][1], r[2][2]),
            speed: self.speed_m_s,
            motion: self.motion_ecef.map(Vector3::from),
            motion_compensation: self.motion_compensation,
            earth_radius: self.mean_earth_radius_m,
            surface_elevation: self.mean_surface_elevation_m,
            mirror_offset: self.mirror_offset_mm / 1000.0,
        }
    }

    /// The section describing `bar` (the inverse of [`PanoramicSection::bar`]).
    #[must_use]
    pub fn of(bar: &OpticalBar, geoid: Option<String>) -> PanoramicSection {
        let m = bar.rotation;
        PanoramicSection {
            size_px: bar.size,
            centre_px: bar.centre_px,
            pixel_size_mm: bar.pitch * 1000.0,
            scan_time_s: bar.scan_time,
            scan: if bar.left_to_right { ScanDirection::LeftToRight } else { ScanDirection::RightToLeft },
            forward_tilt_deg: bar.forward_tilt.to_degrees(),
            position_ecef: [bar.position.x, bar.position.y, bar.position.z],
            rotation: [[m[(0, 0)], m[(0, 1)], m[(0, 2)]], [m[(1, 0)], m[(1, 1)], m[(1, 2)]], [m[(2, 0)], m[(2, 1)], m[(2, 2)]]],
            speed_m_s: bar.speed,
            motion_ecef: bar.motion.map(|v| [v.x, v.y, v.z]),
            motion_compensation: bar.motion_compensation,
            mean_earth_radius_m: bar.earth_radius,
            mean_surface_elevation_m: bar.surface_elevation,
            mirror_offset_mm: bar.mirror_offset * 1000.0,
            geoid,
        }
    }
}

/// True where `text` is an ASP optical-bar camera file.
#[must_use]
pub fn looks_like_asp(text: &str) -> bool {
    let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
    lines.next().is_some_and(|l| l.starts_with("VERSION_")) && lines.next().is_some_and(|l| l == "OPTICAL_BAR")
}

/// An ASP `OPTICAL_BAR` camera file (VERSION_4, with or without the
/// optional `velocity` line): our `[panoramic]` section and the focal
/// length, mm.
pub fn read_asp(path: &Path, text: &str) -> Result<(PanoramicSection, f64)> {
    let mut fields: Vec<(usize, &str, Vec<&str>)> = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || n < 2 && (line.starts_with("VERSION_") || line == "OPTICAL_BAR") {
            continue;
        }
        let Some((k, v)) = line.split_once('=') else {
            return Err(Error::format(path, format!("line {}: `{line}` is not `name = values`", n + 1)));
        };
        fields.push((n + 1, k.trim(), v.split_whitespace().collect()));
    }
    let version = text.lines().next().unwrap_or("").trim().trim_start_matches("VERSION_").parse::<u32>().unwrap_or(0);
    if version < 4 {
        return Err(Error::unsupported(
            path,
            format!("an optical-bar file of VERSION_{version}: ASP reads VERSION_4 and later (scan_time, forward_tilt, a 3×3 iR)"),
        ));
    }
    let get = |k: &str, n: usize| -> Result<Vec<f64>> {
        let (line, _, v) = fields.iter().find(|(_, key, _)| *key == k).ok_or_else(|| Error::format(path, format!("no `{k} =` line")))?;
        if v.len() != n {
            return Err(Error::format(path, format!("line {line}: {k} takes {n} number{}, not {}", if n == 1 { "" } else { "s" }, v.len())));
        }
        v.iter()
            .map(|s| s.parse::<f64>().ok().filter(|x| x.is_finite()).ok_or_else(|| Error::format(path, format!("line {line}: {k}: `{s}` is not a number"))))
            .collect()
    };
    let size = get("image_size", 2)?;
    if size.iter().any(|&s| s < 1.0 || s.fract() != 0.0 || s > 1e7) {
        return Err(Error::format(path, format!("image_size {} {} is no scan's size", size[0], size[1])));
    }
    let centre = get("image_center", 2)?;
    let r = get("iR", 9)?;
    let scan = match fields.iter().find(|(_, k, _)| *k == "scan_dir").map(|(l, _, v)| (l, v.first().copied().unwrap_or(""))) {
        Some((_, "right")) => ScanDirection::LeftToRight,
        Some((_, "left")) => ScanDirection::RightToLeft,
        Some((l, other)) => return Err(Error::format(path, format!("line {l}: scan_dir is `{other}`: left or right"))),
        None => return Err(Error::format(path, "no `scan_dir =` line")),
    };
    let motion = match fields.iter().any(|(_, k, _)| *k == "velocity") {
        true => Some(get("velocity", 3)?).filter(|v| v.iter().any(|&x| x != 0.0)).map(|v| [v[0], v[1], v[2]]),
        false => None,
    };
    let known = [
        "image_size",
        "image_center",
        "pitch",
        "f",
        "scan_time",
        "forward_tilt",
        "iC",
        "iR",
        "speed",
        "mean_earth_radius",
        "mean_surface_elevation",
        "motion_compensation_factor",
        "scan_dir",
        "velocity",
    ];
    if let Some((l, k, _)) = fields.iter().find(|(_, k, _)| !known.contains(k)) {
        return Err(Error::format(path, format!("line {l}: `{k}` is not a field of an optical-bar camera")));
    }
    let ic = get("iC", 3)?;
    let section = PanoramicSection {
        size_px: [size[0] as u32, size[1] as u32],
        centre_px: [centre[0] + 0.5, centre[1] + 0.5],
        pixel_size_mm: get("pitch", 1)?[0] * 1000.0,
        scan_time_s: get("scan_time", 1)?[0],
        scan,
        forward_tilt_deg: get("forward_tilt", 1)?[0].to_degrees(),
        position_ecef: [ic[0], ic[1], ic[2]],
        rotation: [[r[0], r[1], r[2]], [r[3], r[4], r[5]], [r[6], r[7], r[8]]],
        speed_m_s: get("speed", 1)?[0],
        motion_ecef: motion,
        motion_compensation: get("motion_compensation_factor", 1)?[0],
        mean_earth_radius_m: get("mean_earth_radius", 1)?[0],
        mean_surface_elevation_m: get("mean_surface_elevation", 1)?[0],
        mirror_offset_mm: 0.0,
        geoid: None,
    };
    Ok((section, get("f", 1)?[0] * 1000.0))
}

/// ASP's optical-bar file for `bar` (VERSION_4; the `velocity` line where
/// the motion is given as a vector): what `synth --camera panoramic`
/// writes beside our camera file.
#[must_use]
pub fn asp_text(bar: &OpticalBar) -> String {
    let m = bar.rotation;
    let mut s = format!(
        "VERSION_4\nOPTICAL_BAR\nimage_size = {} {}\nimage_center = {:?} {:?}\npitch = {:?}\nf = {:?}\nscan_time = {:?}\nforward_tilt = {:?}\niC = {:?} {:?} {:?}\niR = {}\nspeed = {:?}\nmean_earth_radius = {:?}\nmean_surface_elevation = {:?}\nmotion_compensation_factor = {:?}\nscan_dir = {}\n",
        bar.size[0],
        bar.size[1],
        bar.centre_px[0] - 0.5,
        bar.centre_px[1] - 0.5,
        bar.pitch,
        bar.focal,
        bar.scan_time,
        bar.forward_tilt,
        bar.position.x,
        bar.position.y,
        bar.position.z,
        (0..9).map(|k| format!("{:?}", m[(k / 3, k % 3)])).collect::<Vec<_>>().join(" "),
        bar.speed,
        bar.earth_radius,
        bar.surface_elevation,
        bar.motion_compensation,
        if bar.left_to_right { "right" } else { "left" },
    );
    if let Some(v) = bar.motion {
        s.push_str(&format!("velocity = {:?} {:?} {:?}\n", v.x, v.y, v.z));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const KH9: &str = include_str!("../../fixtures/panoramic/kh9_sample.tsai");

    #[test]
    fn asp_s_kh9_sample_reads_and_writes_back_the_same_numbers() {
        assert!(looks_like_asp(KH9));
        let (sec, focal) = read_asp(Path::new("kh9.tsai"), KH9).unwrap();
        assert_eq!(sec.centre_px, [55254.0, 3952.5]);
        assert_eq!(sec.scan, ScanDirection::RightToLeft);
        let bar = sec.bar(focal);
        let (again, focal2) = read_asp(Path::new("again.tsai"), &asp_text(&bar)).unwrap();
        let bar2 = again.bar(focal2);
        assert!((bar2.focal - bar.focal).abs() < 1e-15 && (bar2.forward_tilt - bar.forward_tilt).abs() < 1e-15);
        assert_eq!(bar2.rotation, bar.rotation);
    }

    #[test]
    fn a_stray_or_short_line_is_named() {
        let bad = KH9.replace("speed = 7700", "sped = 7700");
        assert!(read_asp(Path::new("k.tsai"), &bad).unwrap_err().to_string().contains("sped"));
        let short = KH9.replace("iC = -1047140.9611702315 ", "iC = ");
        assert!(read_asp(Path::new("k.tsai"), &short).unwrap_err().to_string().contains("iC takes 3"));
    }
}
