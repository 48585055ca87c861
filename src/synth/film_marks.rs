//! A film's margin as a scanner sees it: the base, the fiducial marks of a
//! chosen shape (drawn from the same formal description the detector's
//! templates come from, sampled 4 × 4 a pixel), a positive or a negative,
//! the film turned on the scanner, grain, dust and scratches, a mark
//! scratched out. `marks_only` writes such a scan with a cheap texture in
//! the image area and its camera file (the marks' true places in
//! `fiducials_px`), without terrain: for the fiducial tests and benchmark.

use super::{camera_file, noise, scan_spec, write_pixel, SynthOptions, BASE_HEIGHT};
use crate::camera::file::CameraFile;
use crate::camera::interior::InteriorOrientation;
use crate::error::{Error, Result};
use crate::fiducials::search::own_turn;
use crate::fiducials::{MarkLook, Shape};
use crate::io::tiff_out::write_raster;
use nalgebra::Vector2;
use std::path::PathBuf;

/// How the film's marks and margin are drawn.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct FilmMarks {
    /// The marks' shape (a name `fiducials` knows), or one a mark
    /// separated by commas.
    pub shape: String,
    /// A negative: dark marks on a light base (else light on dark).
    pub negative: bool,
    /// The film's small turn on the scanner, degrees.
    pub scan_turn_deg: f64,
    /// Quarter turns counter-clockwise of the film on the scanner.
    pub quarters: u8,
    /// Scanned through the base.
    pub mirrored: bool,
    /// Specks of dust and scratches in the margin (some over the marks).
    pub dust: u32,
    /// This mark (1-based) is scratched out; 0: none.
    pub hidden_mark: u32,
    /// Grain: the tone's random spread (0..1 of the full range).
    pub grain: f64,
}

impl Default for FilmMarks {
    fn default() -> Self {
        FilmMarks { shape: "cross".into(), negative: false, scan_turn_deg: 0.3, quarters: 0, mirrored: false, dust: 0, hidden_mark: 0, grain: 0.0 }
    }
}

/// The calibrated marks of a synthetic film: corners, and mid-sides for 8.
#[must_use]
pub fn mark_places(o: &SynthOptions) -> Vec<[f64; 2]> {
    let d = o.frame_half() + 2.5;
    let mut marks = vec![[-d, -d], [d, d], [-d, d], [d, -d]];
    if o.fiducials == 8 {
        marks.extend([[-d, 0.0], [d, 0.0], [0.0, d], [0.0, -d]]);
    }
    marks
}

/// One shape name a mark: `spec` names one for all, or one a mark.
pub fn shape_names(spec: &str, marks: usize) -> Result<Vec<String>> {
    let names: Vec<String> = spec.split(',').map(|n| n.trim().to_string()).collect();
    match names.len() {
        1 => Ok(vec![names[0].clone(); marks]),
        n if n == marks => Ok(names),
        n => Err(Error::setting("mark", format!("{n} shapes for {marks} marks"))),
    }
}

/// The margin's drawing: tone at photo (x, y) mm, 0..1.
pub struct Margin {
    marks: Vec<[f64; 2]>,
    shapes: Vec<Shape>,
    reach_mm: f64,
    look: FilmMarks,
    specks: Vec<Speck>,
    seed: u64,
    /// The scanner's map, and the principal point's offset from the
    /// fiducial centre (the marks are in the fiducial system).
    interior: InteriorOrientation,
    pp: [f64; 2],
}

/// A speck of dust (a disc) or a scratch (a thin bar), light or dark.
struct Speck {
    at: [f64; 2],
    r: f64,
    len: f64,
    angle: f64,
    tone: f32,
}

impl Margin {
    /// The margin of the film `o` whose camera file is `file` and whose
    /// scan the interior orientation `interior` maps.
    pub fn new(o: &SynthOptions, file: &CameraFile, interior: &InteriorOrientation) -> Result<Margin> {
        let pp = file.interior.as_ref().and_then(|i| i.principal_point_mm).unwrap_or([0.0, 0.0]);
        let look = o.marks.clone();
        let marks = mark_places(o);
        let names = shape_names(&look.shape, marks.len())?;
        let shapes = names
            .iter()
            .map(|n| Shape::from_look(&MarkLook { shape: n.clone(), ..Default::default() }).map_err(|m| Error::setting("mark", m)))
            .collect::<Result<Vec<_>>>()?;
        let reach_mm = shapes.iter().map(|s| s.radius_mm).fold(0.0, f64::max) * 1.5;
        let mut specks = Vec::new();
        let u = |k: u32, j: i64| noise::unit(k as i64, j, o.seed ^ 0xd057);
        for k in 0..look.dust {
            // A third of them near a mark, the rest anywhere in the margin.
            let at = if k % 3 == 0 {
                let m = marks[(k as usize / 3) % marks.len()];
                [m[0] + (u(k, 1) - 0.5) * 4.0, m[1] + (u(k, 2) - 0.5) * 4.0]
            } else {
                let side = o.film_mm() / 2.0;
                [(u(k, 1) - 0.5) * 2.0 * side, (u(k, 2) - 0.5) * 2.0 * side]
            };
            let scratch = k % 4 == 1;
            specks.push(Speck {
                at,
                r: if scratch { 0.015 } else { 0.02 + 0.1 * u(k, 3) },
                len: if scratch { 1.0 + 4.0 * u(k, 4) } else { 0.0 },
                angle: u(k, 5) * std::f64::consts::PI,
                tone: if u(k, 6) < 0.5 { 0.0 } else { 1.0 },
            });
        }
        Ok(Margin { marks, reach_mm, shapes, look, specks, seed: o.seed, interior: interior.clone(), pp })
    }

    /// The mark's tone (0 film, 1 mark) at photo (x, y), or None away from every mark.
    fn mark_tone(&self, x: f64, y: f64) -> Option<f32> {
        for (k, m) in self.marks.iter().enumerate() {
            let (dx, dy) = (x - m[0], y - m[1]);
            if dx.abs() > self.reach_mm || dy.abs() > self.reach_mm {
                continue;
            }
            if self.look.hidden_mark as usize == k + 1 {
                return Some(0.0);
            }
            let shape = &self.shapes[k];
            let local = own_turn(shape, *m).transpose() * Vector2::new(dx, dy);
            return Some(shape.tone(local.x, local.y));
        }
        None
    }

    /// Scan pixel (c, r) → fiducial-system mm.
    pub fn to_mm(&self, c: f64, r: f64) -> (f64, f64) {
        let (x, y) = self.interior.px_to_mm(c, r);
        (x + self.pp[0], y + self.pp[1])
    }

    /// The margin's tone at scan pixel (c, r).
    pub fn tone(&self, c: f64, r: f64) -> f32 {
        let to_mm = |c, r| self.to_mm(c, r);
        let pixel_mm = self.interior.pixel_size_mm();
        let (x, y) = to_mm(c, r);
        let near = self.marks.iter().any(|m| (x - m[0]).abs() <= self.reach_mm + pixel_mm && (y - m[1]).abs() <= self.reach_mm + pixel_mm);
        let mut mark = 0.0f32;
        if near {
            for b in 0..4 {
                for a in 0..4 {
                    let (sx, sy) = to_mm(c + (a as f64 - 1.5) / 4.0, r + (b as f64 - 1.5) / 4.0);
                    mark += self.mark_tone(sx, sy).unwrap_or(0.0);
                }
            }
            mark /= 16.0;
        }
        let (base, ink) = if self.look.negative { (0.88f32, 0.12f32) } else { (0.07f32, 0.93f32) };
        let mut v = base + (ink - base) * mark;
        for s in &self.specks {
            let (dx, dy) = (x - s.at[0], y - s.at[1]);
            let hit = if s.len > 0.0 {
                let (sn, cs) = s.angle.sin_cos();
                (dx * cs + dy * sn).abs() <= s.len / 2.0 && (-dx * sn + dy * cs).abs() <= s.r
            } else {
                dx * dx + dy * dy <= s.r * s.r
            };
            if hit {
                v = s.tone;
            }
        }
        if self.look.grain > 0.0 {
            let g = noise::unit(c as i64 * 7919 + r as i64 * 104_729, 11, self.seed) - 0.5;
            v += (g * 2.0 * self.look.grain) as f32;
        }
        v.clamp(0.0, 1.0)
    }
}

/// A film scan of marks only (a cheap texture in the image area) and its
/// camera file, in `o.out`: (scan, camera).
pub fn marks_only(o: &SynthOptions) -> Result<(PathBuf, PathBuf)> {
    super::check(o)?;
    std::fs::create_dir_all(&o.out).map_err(|e| Error::io(&o.out, e))?;
    let cam_path = o.out.join("camera.toml");
    let scan_path = o.out.join("scan.tif");
    let file = camera_file(o, BASE_HEIGHT);
    crate::io::publish::write_file(&cam_path, file.to_toml().as_bytes())?;
    let camera = crate::camera::file::Camera::read(&cam_path)?;
    let margin = Margin::new(o, &file, &camera.frame(&cam_path)?.interior)?;
    let half = o.frame_half();
    let spec = scan_spec(o);
    let pb = o.bands as usize * spec.sample.bytes();
    let width = o.width as usize;
    write_raster(&scan_path, &spec, |y0, _y1, buf| {
        use rayon::prelude::*;
        buf.par_chunks_mut(width * pb).enumerate().for_each(|(k, row)| {
            let r = (y0 as usize + k) as f64 + 0.5;
            for (j, out) in row.chunks_mut(pb).enumerate() {
                let c = j as f64 + 0.5;
                let (x, y) = margin.to_mm(c, r);
                let v = if x.abs() <= half && y.abs() <= half { (0.25 + 0.5 * noise::fbm(x / 3.0, y / 3.0, 4, o.seed)) as f32 } else { margin.tone(c, r) };
                write_pixel([v, v, v], o.bands, o.bits, out);
            }
        });
    })?;
    Ok((scan_path, cam_path))
}
