//! A drone image's own tags as its camera (`--camera exif`): EXIF (focal
//! length with the focal-plane resolution, or the 35 mm equivalent; GPS)
//! and the XMP that DJI, senseFly and Pix4D cameras write (position, the
//! camera's yaw, pitch and roll, DJI's `DewarpData` calibration).
//!
//! DJI's gimbal angles are the camera's yaw, pitch and roll as aircraft
//! angles (z down; x the optical axis, level at pitch 0, straight down at
//! −90; roll about the optical axis). Read so, a nadir frame tagged
//! `GimbalRollDegree = ±180` (some DJI payloads turn the camera that way
//! instead of the yaw) is the frame turned 180° in its own plane, as it
//! is — not a camera looking up. With roll 0, which is nearly every image,
//! this is Orthority's reading exactly.

use super::{brown_section, Imported, Lens, Pose};
use crate::camera::distortion::Brown;
use crate::error::{Error, Result};
use crate::geodesy::{utm_zone, Crs, GroundCrs};
use crate::io::source::SourceImage;
use exif::{In, Tag, Value};
use nalgebra::Matrix3;
use std::collections::HashMap;
use std::io::{BufReader, Read};
use std::path::Path;

const DJI: &str = "http://www.dji.com/drone-dji/1.0/";
const SENSEFLY: &str = "http://ns.sensefly.com/Camera/1.0/";
const PIX4D: &str = "http://pix4d.com/camera/1.0/";

/// What an image's tags say about its camera.
#[derive(Clone, Debug, Default)]
pub struct Tags {
    pub make: Option<String>,
    pub model: Option<String>,
    /// The size the tags were written for (`PixelXDimension`, `PixelYDimension`).
    pub tag_size: Option<[u32; 2]>,
    pub focal_mm: Option<f64>,
    pub focal_35mm: Option<f64>,
    /// The sensor's size in mm from the focal-plane resolution.
    pub sensor_mm: Option<[f64; 2]>,
    pub orientation: Option<u32>,
    /// Latitude, longitude (degrees), altitude (m; NaN where the tags
    /// give none).
    pub gps: Option<[f64; 3]>,
    /// XMP properties by namespace and name.
    pub xmp: HashMap<(String, String), String>,
    /// Why its EXIF block, or part of it, could not be read (the tags
    /// read are kept): said with the camera made, and where none can be.
    pub unreadable: Option<String>,
}

impl Tags {
    /// The tags of the image at `path` (JPEG or TIFF).
    pub fn read(path: &Path) -> Result<Tags> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let mut tags = Tags::default();
        // An XMP sidecar first: the image's own packet, read after, wins.
        if let Some(sidecar) = xmp_sidecar(path) {
            let text = crate::io::bounded_read::read_text_bounded(&sidecar, "an XMP sidecar", crate::io::bounded_read::SMALL)?;
            tags.xmp_packet(&text);
        }
        // GDAL, for one, ends its EXIF directories with a pointer to the
        // next one that is not zero: the reader's strict mode would give
        // up on the whole block for that.
        let mut reader = exif::Reader::new();
        reader.continue_on_error(true);
        let read = reader.read_from_container(&mut BufReader::new(file)).or_else(|e| {
            e.distill_partial_result(|errors| {
                // A block that merely ends oddly loses no tag: not worth a word.
                let lost: Vec<String> =
                    errors.iter().filter(|e| !matches!(e, exif::Error::InvalidFormat("Unexpected next IFD"))).map(ToString::to_string).collect();
                if !lost.is_empty() {
                    tags.unreadable = Some(format!("part of its EXIF block cannot be read ({})", lost.join("; ")));
                }
            })
        });
        match read {
            Err(exif::Error::NotFound(_)) => {}
            Err(e) => tags.unreadable = Some(format!("its EXIF block cannot be read ({e})")),
            Ok(exif) => {
                tags.exif(&exif);
                // A TIFF's XMP packet is its tag 700.
                if let Some(f) = exif.get_field(Tag(exif::Context::Tiff, 700), In::PRIMARY) {
                    // BYTE as the TIFF/XMP specifications say; UNDEFINED
                    // and ASCII as some cameras' firmware writes it.
                    match &f.value {
                        Value::Byte(b) | Value::Undefined(b, _) => tags.xmp_packet(&String::from_utf8_lossy(b)),
                        Value::Ascii(lines) => tags.xmp_packet(&lines.iter().map(|l| String::from_utf8_lossy(l)).collect::<Vec<_>>().join("\n")),
                        _ => {}
                    }
                }
                if let Some(f) = exif.get_field(Tag(exif::Context::Tiff, 42112), In::PRIMARY) {
                    if let Value::Ascii(lines) = &f.value {
                        tags.gdal_items(&lines.iter().map(|l| String::from_utf8_lossy(l)).collect::<String>());
                    }
                }
            }
        }
        if let Some(packet) = jpeg_xmp(path)? {
            tags.xmp_packet(&packet);
        }
        Ok(tags)
    }

    fn exif(&mut self, e: &exif::Exif) {
        let text = |t: Tag| e.get_field(t, In::PRIMARY).map(|f| f.display_value().to_string().trim_matches('"').trim().to_string());
        let nums = |t: Tag| -> Option<Vec<f64>> {
            let v: Vec<f64> = match &e.get_field(t, In::PRIMARY)?.value {
                Value::Rational(r) => r.iter().map(|r| if r.denom == 0 { f64::NAN } else { r.to_f64() }).collect(),
                Value::SRational(r) => r.iter().map(|r| if r.denom == 0 { f64::NAN } else { r.to_f64() }).collect(),
                v => v.iter_uint()?.map(f64::from).collect(),
            };
            Some(v)
        };
        self.fill(&text, &nums);
    }

    /// The EXIF tags GDAL keeps as `EXIF_*` items of its metadata (tag
    /// 42112), as `gdal_translate` writes a JPEG's EXIF into a TIFF:
    /// rationals in parentheses, `(45) (30) (0)`.
    fn gdal_items(&mut self, xml: &str) {
        let Ok(doc) = roxmltree::Document::parse(xml.trim_matches(char::from(0))) else { return };
        let items: HashMap<String, String> = doc
            .descendants()
            .filter(|n| n.has_tag_name("Item") && n.attribute("domain").is_none() && n.attribute("band").is_none())
            .filter_map(|n| Some((n.attribute("name")?.strip_prefix("EXIF_")?.to_string(), n.text().unwrap_or("").trim().to_string())))
            .collect();
        if items.is_empty() {
            return;
        }
        let text = |t: Tag| items.get(&t.to_string()).cloned();
        let nums = |t: Tag| -> Option<Vec<f64>> {
            let v = items.get(&t.to_string())?;
            let parse = |x: &str| match x.strip_prefix("0x") {
                Some(h) => u64::from_str_radix(h, 16).map(|n| n as f64).ok(),
                None => x.parse::<f64>().ok(),
            };
            v.split(|c: char| c.is_whitespace() || c == '(' || c == ')').filter(|x| !x.is_empty()).map(parse).collect()
        };
        self.fill(&text, &nums);
    }

    /// The camera's tags from `text` and `nums` (every value of a tag, as
    /// numbers), each as EXIF names it; tags read before are kept.
    fn fill(&mut self, text: &dyn Fn(Tag) -> Option<String>, nums: &dyn Fn(Tag) -> Option<Vec<f64>>) {
        let num = |t: Tag| nums(t).and_then(|v| v.first().copied()).filter(|v| v.is_finite());
        self.make = self.make.take().or_else(|| text(Tag::Make));
        self.model = self.model.take().or_else(|| text(Tag::Model));
        self.focal_mm = self.focal_mm.or_else(|| num(Tag::FocalLength).filter(|f| *f > 0.0));
        self.focal_35mm = self.focal_35mm.or_else(|| num(Tag::FocalLengthIn35mmFilm).filter(|f| *f > 0.0));
        self.orientation = self.orientation.or_else(|| num(Tag::Orientation).map(|o| o as u32));
        let (w, h) = (num(Tag::PixelXDimension), num(Tag::PixelYDimension));
        if let (None, Some(w), Some(h)) = (self.tag_size, w.filter(|w| *w >= 1.0), h.filter(|h| *h >= 1.0)) {
            self.tag_size = Some([w as u32, h as u32]);
        }
        // mm per focal-plane resolution unit: inch, cm, mm, µm.
        let unit = num(Tag::FocalPlaneResolutionUnit).and_then(|u| match u as u32 {
            2 => Some(25.4),
            3 => Some(10.0),
            4 => Some(1.0),
            5 => Some(0.001),
            _ => None,
        });
        let resolution = (num(Tag::FocalPlaneXResolution), num(Tag::FocalPlaneYResolution));
        if let (None, Some(mm), (Some(xr), Some(yr)), Some([w, h])) = (self.sensor_mm, unit, resolution, self.tag_size) {
            if xr > 0.0 && yr > 0.0 {
                self.sensor_mm = Some([mm * f64::from(w) / xr, mm * f64::from(h) / yr]);
            }
        }
        let dms = |t: Tag| -> Option<f64> {
            let v = nums(t)?;
            (v.len() == 3 && v.iter().all(|x| x.is_finite())).then(|| v[0] + v[1] / 60.0 + v[2] / 3600.0)
        };
        let sign = |t: Tag, negative: &str| if text(t).is_some_and(|s| s.starts_with(negative)) { -1.0 } else { 1.0 };
        if let (None, Some(lat), Some(lon)) = (self.gps, dms(Tag::GPSLatitude), dms(Tag::GPSLongitude)) {
            let below = num(Tag::GPSAltitudeRef) == Some(1.0);
            // No GPSAltitude: NaN, refused when the position is used (it
            // was taken as 0 m and blamed on the DEM below).
            let alt = num(Tag::GPSAltitude).map_or(f64::NAN, |a| a * if below { -1.0 } else { 1.0 });
            self.gps = Some([lat * sign(Tag::GPSLatitudeRef, "S"), lon * sign(Tag::GPSLongitudeRef, "W"), alt]);
        }
    }

    /// Every property of an XMP packet: attributes and simple elements.
    fn xmp_packet(&mut self, packet: &str) {
        let Ok(doc) = roxmltree::Document::parse(packet.trim_matches(char::from(0))) else { return };
        for node in doc.descendants().filter(|n| n.is_element()) {
            for a in node.attributes() {
                if let Some(ns) = a.namespace() {
                    self.xmp.insert((ns.to_string(), a.name().to_string()), a.value().trim().to_string());
                }
            }
            if let (Some(ns), Some(text)) = (node.tag_name().namespace(), node.text()) {
                if node.children().all(|c| c.is_text()) && !text.trim().is_empty() {
                    self.xmp.insert((ns.to_string(), node.tag_name().name().to_string()), text.trim().to_string());
                }
            }
        }
    }

    fn xmp_num(&self, ns: &str, name: &str) -> Option<f64> {
        self.xmp.get(&(ns.to_string(), name.to_string())).and_then(|v| v.parse::<f64>().ok()).filter(|v| v.is_finite())
    }

    /// The camera's id: make and model, as Orthority names it.
    #[must_use]
    pub fn camera_id(&self) -> String {
        let id = [&self.make, &self.model].iter().filter_map(|s| s.as_deref()).collect::<Vec<_>>().join(" ").to_lowercase();
        if id.is_empty() {
            "unknown".into()
        } else {
            id
        }
    }
}

/// The XMP sidecar beside an image, where there is one: `IMG.xmp` (as
/// Adobe's tools name it) or `IMG.tif.xmp` (as darktable's do).
pub fn xmp_sidecar(image: &Path) -> Option<std::path::PathBuf> {
    let mut appended = image.as_os_str().to_owned();
    appended.push(".xmp");
    [image.with_extension("xmp"), image.with_extension("XMP"), std::path::PathBuf::from(appended)].into_iter().find(|p| p.is_file() && p != image)
}

/// The XMP packet of a JPEG (its APP1 segment), read segment by segment up
/// to the image data; `None` for other files.
fn jpeg_xmp(path: &Path) -> Result<Option<String>> {
    const XMP: &[u8] = b"http://ns.adobe.com/xap/1.0/\0";
    let mut f = BufReader::new(std::fs::File::open(path).map_err(|e| Error::io(path, e))?);
    let mut two = [0u8; 2];
    if f.read_exact(&mut two).is_err() || two != [0xFF, 0xD8] {
        return Ok(None);
    }
    loop {
        let mut marker = [0u8; 2];
        if f.read_exact(&mut marker).is_err() || marker[0] != 0xFF || marker[1] == 0xDA || marker[1] == 0xD9 {
            return Ok(None);
        }
        let mut len = [0u8; 2];
        f.read_exact(&mut len).map_err(|e| Error::io(path, e))?;
        let n = usize::from(u16::from_be_bytes(len)).saturating_sub(2);
        let mut body = vec![0u8; n];
        f.read_exact(&mut body).map_err(|e| Error::io(path, e))?;
        if marker[1] == 0xE1 && body.starts_with(XMP) {
            return Ok(Some(String::from_utf8_lossy(&body[XMP.len()..]).into_owned()));
        }
    }
}

/// The camera of `image` from its own tags, its position in `crs` (default:
/// its UTM zone).
pub fn read(image: &Path, crs: Option<&Crs>) -> Result<Imported> {
    let tags = Tags::read(image)?;
    let info = SourceImage::info_of(image)?;
    let size = [info.width, info.height];
    let mut set = Imported::default();
    if let Some(o) = tags.orientation.filter(|&o| o > 1) {
        return Err(Error::unsupported(
            image,
            format!("EXIF orientation {o}: the pixels are stored turned or mirrored from the view the camera tags describe"),
        ));
    }
    let id = tags.camera_id();
    let (lens, warning) = lens(image, &tags, size)?;
    set.warnings.extend(warning);
    set.warnings.extend(tags.unreadable.as_ref().map(|u| format!("{}: {u}; the tags read are used", image.display())));
    set.lenses.push((id.clone(), lens));

    // Position: DJI's XMP (more digits), else EXIF GPS.
    let lat = tags.xmp_num(DJI, "GpsLatitude");
    let lon = tags.xmp_num(DJI, "GpsLongitude").or_else(|| tags.xmp_num(DJI, "GpsLongtitude"));
    let alt = tags.xmp_num(DJI, "AbsoluteAltitude");
    let [lat, lon, alt] = match (lat, lon, alt, tags.gps) {
        (Some(a), Some(b), Some(c), _) => [a, b, c],
        // EXIF's position with XMP's height where EXIF has none.
        (_, _, Some(c), Some([a, b, z])) if z.is_nan() => [a, b, c],
        (_, _, _, Some([_, _, z])) if z.is_nan() => {
            return Err(Error::format(
                image,
                "its EXIF GPS position has no GPSAltitude (nor XMP AbsoluteAltitude): the camera's height is unknown; give a camera file",
            ));
        }
        (_, _, _, Some(g)) => g,
        _ => {
            let why = tags.unreadable.as_ref().map_or(String::new(), |u| format!(" ({u})"));
            return Err(Error::format(image, format!("no GPS position in its EXIF or XMP tags{why}: give a camera file")));
        }
    };
    let crs = crs.cloned().unwrap_or_else(|| utm_zone(lon, lat));
    let ground = GroundCrs::new(&crs).map_err(|m| Error::format(image, m))?;
    let (x, y) = ground.lonlat_to_ground(lon, lat).ok_or_else(|| Error::format(image, format!("its position ({lat}, {lon}) is outside {crs}")))?;
    let r = attitude(image, &tags, (lon, lat), &ground)?;
    let name = image.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    set.poses.push(Pose { name, camera: Some(id), position: [x, y, alt], r, origin: format!("{}: EXIF/XMP", image.display()) });
    set.crs = Some(crs.epsg().map_or_else(|| crs.proj4().to_string(), |e| format!("EPSG:{e}")));
    set.files.push(image.to_path_buf());
    set.relative_altitude = tags.xmp_num(DJI, "RelativeAltitude");
    Ok(set)
}

/// The lens: DJI's DewarpData where the image was not undistorted already,
/// else a pinhole from the focal length and sensor size, else from the
/// 35 mm equivalent (approximate: warned).
fn lens(image: &Path, tags: &Tags, size: [u32; 2]) -> Result<(Lens, Option<String>)> {
    let [w, h] = size.map(f64::from);
    let centre = [(w - 1.0) / 2.0, (h - 1.0) / 2.0];
    // Calibrated on the tagged size; without size tags, on the image's own.
    if let (Some(text), Some(tag)) = (tags.xmp.get(&(DJI.to_string(), "DewarpData".to_string())), tags.tag_size.or(Some(size))) {
        let v: Vec<f64> = text.rsplit(';').next().unwrap_or("").split(',').filter_map(|x| x.trim().parse().ok()).collect();
        if v.len() == 9 && v.iter().any(|x| *x != 0.0) {
            // Calibrated on the tagged size: focal lengths in its pixels,
            // the principal point as offsets from its centre.
            let (sx, sy) = (w / f64::from(tag[0]), h / f64::from(tag[1]));
            let scale = w.max(h) / f64::from(tag[0].max(tag[1]));
            let pp = [centre[0] + v[2] * scale, centre[1] + v[3] * scale];
            let undistorted = tags.xmp_num(DJI, "DewarpFlag") == Some(1.0);
            let distortion = if undistorted { Default::default() } else { brown_section(Brown { k1: v[4], k2: v[5], p1: v[6], p2: v[7], k3: v[8] }) };
            return Ok((Lens::from_opencv(size, [v[0] * sx, v[1] * sy], pp, distortion), None));
        }
    }
    if let (Some(f), Some(s)) = (tags.focal_mm, tags.sensor_mm) {
        let mut lens = Lens::from_opencv(size, [f * w / s[0], f * h / s[1]], centre, Default::default());
        lens.focal_mm = Some(f);
        return Ok((lens, None));
    }
    if let Some(f35) = tags.focal_35mm {
        // The 35 mm equivalent is by the diagonal (36 × 24 mm).
        let f = f35 * w.hypot(h) / 36f64.hypot(24.0);
        let warning = format!(
            "{}: the focal length is only the 35 mm equivalent ({f35} mm, {f:.1} px) and the lens's distortion is unknown: calibrate the camera for accurate geometry",
            image.display()
        );
        return Ok((Lens::from_opencv(size, [f, f], centre, Default::default()), Some(warning)));
    }
    let why = tags.unreadable.as_ref().map_or(String::new(), |u| format!(" ({u})"));
    Err(Error::format(
        image,
        format!("no focal length with a sensor size (focal-plane resolution), no 35 mm equivalent and no DJI DewarpData{why}: give a camera file"),
    ))
}

/// The camera's rotation (photo → `ground`) from the vendor's attitude tags.
fn attitude(image: &Path, tags: &Tags, lonlat: (f64, f64), ground: &GroundCrs) -> Result<Matrix3<f64>> {
    let deg = |ns: &str, n: &str| tags.xmp_num(ns, n).map(f64::to_radians);
    if let Some(pitch) = deg(DJI, "GimbalPitchDegree") {
        // The gimbal's yaw is the camera's heading; the aircraft's is not
        // where the gimbal turns on its own.
        let yaw = deg(DJI, "GimbalYawDegree").or_else(|| deg(DJI, "FlightYawDegree"));
        let yaw = yaw.ok_or_else(|| Error::format(image, "DJI tags with a gimbal pitch but no gimbal or flight yaw"))?;
        let roll = deg(DJI, "GimbalRollDegree").unwrap_or(0.0);
        return gimbal_rotation([yaw, pitch, roll], lonlat, ground).ok_or_else(|| Error::format(image, "no grid north at its position"));
    }
    for ns in [SENSEFLY, PIX4D] {
        if let (Some(r), Some(p), Some(y)) = (deg(ns, "Roll"), deg(ns, "Pitch"), deg(ns, "Yaw")) {
            return super::orthority::rpy_rotation([r, p, y], lonlat, ground).ok_or_else(|| Error::format(image, "no grid north at its position"));
        }
    }
    Err(Error::format(image, "no camera attitude in its XMP (DJI gimbal yaw/pitch/roll, senseFly or Pix4D roll/pitch/yaw): give a camera file"))
}

/// Aircraft angles yaw, pitch, roll (radians) of a camera body whose x is
/// the optical axis, y the image's right, z its down, against north, east,
/// down with north along the grid north of `ground` at `lonlat` → the
/// rotation photo (x right, y up, z back) → ground.
#[must_use]
pub fn gimbal_rotation([yaw, pitch, roll]: [f64; 3], lonlat: (f64, f64), ground: &GroundCrs) -> Option<Matrix3<f64>> {
    use super::orthority::{rx, ry, rz};
    let body_to_ned = rz(yaw) * ry(pitch) * rx(roll);
    // Photo x = body y, photo y = −body z, photo z = −body x.
    let photo_to_body = Matrix3::new(0.0, 0.0, -1.0, 1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
    Some(super::orthority::ned_to_ground(lonlat, ground)? * body_to_ned * photo_to_body)
}
