//! `gcm-ortho cameras`: the cameras of a set of files, one per image, shown
//! as a table and written as our camera files or in Orthority's or
//! OpenSfM's form — so that what another tool's files say can be seen and
//! fixed before a night's run, and a block can go back to those tools.

use super::{distinct_lenses, opensfm, orthority, Lens, Pose};
use crate::camera::atmosphere::Refraction;
use crate::camera::file::CameraFile;
use crate::camera::rotation::AngleConvention;
use crate::error::{Error, Result};
use crate::geodesy::{Crs, GroundCrs};
use crate::io::overwrite::{check_outputs, Role};
use crate::io::publish::write_file;
use crate::io::source::SourceImage;
use std::path::{Path, PathBuf};

/// The form the cameras are written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// One gcm-ortho camera file per image, `<image stem>.toml`.
    Toml,
    /// `int_param.yaml`, `ext_param.csv` and `ext_param.prj`.
    Orthority,
    /// `reconstruction.json`.
    OpenSfm,
}

/// What `cameras` is asked.
#[derive(Clone, Debug)]
pub struct ConvertOptions {
    pub camera: PathBuf,
    pub exterior: Option<PathBuf>,
    /// The unit of a pose CSV's angles.
    pub angles: super::AngleUnit,
    /// Only these images' cameras, sized from the files; empty: every pose.
    pub images: Vec<PathBuf>,
    /// The positions' CRS where the files give none.
    pub crs: Option<Crs>,
    /// Where to write; `None`: the table only.
    pub out_dir: Option<PathBuf>,
    pub target: Target,
}

/// One image's camera.
#[derive(Clone, Debug)]
pub struct Entry {
    /// The image's file name (or the pose's name).
    pub name: String,
    pub file: CameraFile,
    /// The image's size in pixels, where known.
    pub size: Option<[u32; 2]>,
    /// Where the pose was read.
    pub origin: String,
}

/// The cameras, and warnings the files gave.
pub struct Converted {
    pub entries: Vec<Entry>,
    pub warnings: Vec<String>,
    /// The files written.
    pub written: Vec<PathBuf>,
}

/// Reads the cameras and, with `out_dir`, writes them.
pub fn convert(o: &ConvertOptions) -> Result<Converted> {
    let exif = super::is_exif(&o.camera);
    if exif && o.images.is_empty() {
        return Err(Error::Usage("‹camera› exif: name the images".into()));
    }
    let mut set = if exif { Default::default() } else { super::read_with(&o.camera, o.exterior.as_deref(), o.images.first().map(PathBuf::as_path), o.angles)? };
    let mut entries = Vec::new();
    if !o.images.is_empty() {
        for image in &o.images {
            let info = SourceImage::info_of(image)?;
            let name = image.file_name().map_or_else(|| image.display().to_string(), |n| n.to_string_lossy().into_owned());
            let own;
            let from = if exif {
                own = super::read_for(image, &o.camera, None, o.crs.as_ref())?;
                set.warnings.extend(own.warnings.iter().cloned());
                &own
            } else {
                &set
            };
            entries.push(Entry { name, file: from.camera_for(image)?, size: Some([info.width, info.height]), origin: image.display().to_string() });
        }
    } else if !set.poses.is_empty() {
        for (name, file, origin) in set.all()? {
            entries.push(Entry { name, file, size: None, origin });
        }
    } else if let Some(base) = &set.base {
        let name = o.camera.file_stem().map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        entries.push(Entry { name, file: base.clone(), size: None, origin: o.camera.display().to_string() });
    }
    if entries.is_empty() {
        return Err(Error::format(&o.camera, "holds no camera with an exterior orientation: add ‹exterior› with the poses"));
    }
    let dir = o.camera.parent().unwrap_or(Path::new("")).to_path_buf();
    for e in &mut entries {
        if let Some(sec) = e.file.panoramic.as_ref() {
            // An optical bar's position is ECEF: its CRS is only where its
            // orthophoto goes (the UTM zone under it unless given).
            if e.file.crs.trim().is_empty() {
                e.file.crs = o.crs.as_ref().map_or_else(|| "auto".into(), |c| c.epsg().map_or_else(|| c.proj4().to_string(), |n| format!("EPSG:{n}")));
            }
            if let Some(real) = e.size.filter(|&real| real != sec.size_px) {
                return Err(Error::config(
                    &o.camera,
                    "panoramic.size_px",
                    format!("the camera is for {}×{} images, but {} is {}×{}", sec.size_px[0], sec.size_px[1], e.origin, real[0], real[1]),
                ));
            }
            e.file.clone().build(&o.camera)?;
            continue;
        }
        // A CRS given as a file beside the camera file is written as the
        // CRS itself: the path would not hold where the output goes.
        if !e.file.crs.trim().is_empty() && dir.join(e.file.crs.trim()).is_file() {
            let c = Crs::parse(&e.file.crs, &dir).map_err(|m| Error::config(&o.camera, "crs", m))?;
            e.file.crs = c.epsg().map_or_else(|| c.proj4().to_string(), |n| format!("EPSG:{n}"));
        }
        if e.file.crs.trim().is_empty() {
            match &o.crs {
                Some(c) => e.file.crs = c.epsg().map_or_else(|| c.proj4().to_string(), |n| format!("EPSG:{n}")),
                None => return Err(Error::at(&o.camera, &e.origin, "the CRS of the positions is not given: a .prj beside the poses, or ‹crs›")),
            }
        }
        let interior = e.file.interior.get_or_insert_with(Default::default);
        match (interior.image_size_px, e.size) {
            (Some(own), Some(real)) if own != real => {
                return Err(Error::config(
                    &o.camera,
                    "interior.image_size_px",
                    format!("the camera is for {}×{} images, but {} is {}×{}", own[0], own[1], e.origin, real[0], real[1]),
                ));
            }
            (Some(own), None) => e.size = Some(own),
            (None, Some(real)) if e.file.camera.model == "frame" && interior.pixel_size_mm.is_some() => interior.image_size_px = Some(real),
            _ => {}
        }
        // Built once, so that what is written is a camera rectify takes.
        e.file.clone().build(&o.camera)?;
    }
    let mut written = Vec::new();
    if let Some(dir) = &o.out_dir {
        written = write(&entries, dir, o)?;
    }
    Ok(Converted { entries, warnings: set.warnings, written })
}

fn write(entries: &[Entry], dir: &Path, o: &ConvertOptions) -> Result<Vec<PathBuf>> {
    if dir.exists() && !dir.is_dir() {
        return Err(Error::Usage(format!("‹out_dir› {}: not a folder", dir.display())));
    }
    let files: Vec<(PathBuf, String)> = match o.target {
        Target::Toml => {
            let mut out: Vec<(PathBuf, String)> = Vec::new();
            for e in entries {
                let stem = Path::new(&e.name).file_stem().map_or_else(|| e.name.clone(), |s| s.to_string_lossy().into_owned());
                let path = dir.join(format!("{stem}.toml"));
                if out.iter().any(|(p, _)| *p == path) {
                    return Err(Error::format(
                        &o.camera,
                        format!("two images would be written to {}: their names differ only in the extension", path.display()),
                    ));
                }
                let mut text = String::new();
                if e.file.interior.as_ref().and_then(|i| i.pixel_size_mm).is_some_and(|p| p.sides()[0] == 1.0) {
                    text += "# The source gives no sensor size: the focal length is in pixels, on pixels 1 \"mm\" across.\n";
                }
                out.push((path, text + &e.file.to_toml()));
            }
            out
        }
        Target::Orthority | Target::OpenSfm => {
            if entries.iter().any(|e| e.file.panoramic.is_some()) {
                return Err(Error::unsupported(&o.camera, "a panoramic camera has no form in Orthority's or OpenSfM's files (‹to› toml)"));
            }
            let (lenses, poses) = lenses_and_poses(entries, &o.camera)?;
            let (unique, ids) = distinct_lenses(&lenses);
            let crs_text = one_crs(entries, &o.camera)?;
            if o.target == Target::Orthority {
                vec![
                    (dir.join("int_param.yaml"), orthority::write_interior(&unique, &o.camera)?),
                    (dir.join("ext_param.csv"), orthority::write_csv(&poses, &ids)),
                    (dir.join("ext_param.prj"), crs_text),
                ]
            } else {
                let crs = Crs::parse(&crs_text, o.camera.parent().unwrap_or(Path::new(""))).map_err(|m| Error::format(&o.camera, m))?;
                let ground = GroundCrs::new(&crs).map_err(|m| Error::format(&o.camera, m))?;
                vec![(dir.join("reconstruction.json"), opensfm::write(&unique, &poses, &ids, &ground, &o.camera)?)]
            }
        }
    };
    let mut inputs = vec![Role::new("camera file", &o.camera)];
    if let Some(e) = &o.exterior {
        inputs.push(Role::new("exterior orientations", e));
    }
    inputs.extend(o.images.iter().map(|i| Role::new("image", i)));
    let outputs: Vec<Role> = files.iter().map(|(p, _)| Role::new("output", p)).collect();
    // A folder not there yet is made (and removed again if refused).
    let made = !dir.exists();
    if made {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    if let Err(e) = check_outputs(&inputs, &outputs) {
        if made {
            let _ = std::fs::remove_dir(dir);
        }
        return Err(e);
    }
    for (path, text) in &files {
        write_file(path, text.as_bytes())?;
    }
    Ok(files.into_iter().map(|(p, _)| p).collect())
}

fn lenses_and_poses(entries: &[Entry], source: &Path) -> Result<(Vec<Lens>, Vec<Pose>)> {
    let mut lenses = Vec::new();
    let mut poses = Vec::new();
    for e in entries {
        let size = e.size.ok_or_else(|| Error::at(source, &e.origin, "the image size is not known: name the images on the command line"))?;
        lenses.push(Lens::of(&e.file, source, size)?);
        // Orthority and OpenSfM model neither; dropped, the cameras would
        // rectify differently there.
        let c = &e.file.corrections;
        if c.refraction != Refraction::None || c.earth_curvature {
            let refraction = format!("{:?}", c.refraction).to_lowercase();
            return Err(Error::at(
                source,
                &e.origin,
                format!(
                    "[corrections] (refraction = \"{refraction}\", earth_curvature = {}) has no form in Orthority's or OpenSfM's files; set them to \"none\" and false to convert without them",
                    c.earth_curvature
                ),
            ));
        }
        poses.push(Pose::of(&e.name, &e.file, source)?);
    }
    Ok((lenses, poses))
}

/// The CRS all cameras share (as text), or a refusal.
fn one_crs(entries: &[Entry], source: &Path) -> Result<String> {
    let first = &entries[0].file.crs;
    match entries.iter().find(|e| e.file.crs != *first) {
        Some(e) => Err(Error::unsupported(source, format!("the cameras are in two CRSs ({first}, {}): one file set holds one", e.file.crs))),
        None => Ok(first.clone()),
    }
}

/// The cameras as a table, one line per image.
#[must_use]
pub fn table(entries: &[Entry]) -> String {
    let mut out = format!(
        "{:<24} {:>12} {:>13} {:>9} {:>9} {:>9} {:>9} {:>9} {:>17} {:>11}  {}\n",
        "image", "X", "Y", "Z", "omega°", "phi°", "kappa°", "f px", "principal pt px", "size", "lens"
    );
    for e in entries {
        let f = &e.file;
        if let Some(p) = &f.panoramic {
            // ECEF position; focal length in film pixels; the lens axis on the film.
            let fpx = f.camera.focal_length_mm.map_or_else(|| "-".into(), |mm| format!("{:.2}", mm / p.pixel_size_mm));
            let pp = format!("{:.2},{:.2}", p.centre_px[0], p.centre_px[1]);
            let size = format!("{}x{}", p.size_px[0], p.size_px[1]);
            let [x, y, z] = p.position_ecef;
            out += &format!("{:<24} {x:>12.3} {y:>13.3} {z:>9.0} {:>9} {:>9} {:>9} {fpx:>9} {pp:>17} {size:>11}  panoramic (ECEF)\n", e.name, "-", "-", "-");
            continue;
        }
        let (pos, opk) = match &f.exterior {
            Some(x) => {
                (x.position, AngleConvention::OmegaPhiKappa.angles(&x.convention.matrix(x.angles_deg.map(f64::to_radians))).map(|a| a.to_degrees() + 0.0))
            }
            None => ([f64::NAN; 3], [f64::NAN; 3]),
        };
        let interior = f.interior.clone().unwrap_or_default();
        let fpx = match (f.camera.focal_length_mm, interior.pixel_size_mm) {
            (Some(mm), Some(p)) => format!("{:.2}", mm / p.sides()[0]),
            _ => "-".into(),
        };
        let pp = interior.principal_point_px.map_or_else(|| "-".into(), |p| format!("{:.2},{:.2}", p[0], p[1]));
        let size = e.size.map_or_else(|| "-".into(), |s| format!("{}x{}", s[0], s[1]));
        let d = f.distortion.clone().unwrap_or_default();
        let lens = if d.brown.is_some() {
            "brown"
        } else if d.opencv.is_some() {
            "opencv"
        } else if d.fisheye.is_some() {
            "fisheye"
        } else if d.radial_mm.is_some() {
            "radial"
        } else if d.metashape.is_some() {
            "metashape"
        } else {
            "pinhole"
        };
        out += &format!(
            "{:<24} {:>12.3} {:>13.3} {:>9.3} {:>9.4} {:>9.4} {:>9.4} {:>9} {:>17} {:>11}  {}\n",
            e.name, pos[0], pos[1], pos[2], opk[0], opk[1], opk[2], fpx, pp, size, lens
        );
    }
    out
}
