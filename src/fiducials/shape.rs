//! Fiducial marks described formally (thesis §2.6: templates come from a
//! generator and a description of the mark, not from images cut by hand):
//! a few primitives in millimetres, painted in order, in the mark's own
//! frame (centre at the mark's calibrated point, x right, y up in the photo).
//! A shape that "turns with its place" is drawn for a mark on the photo's +x
//! axis and turned with the mark's direction from the frame centre (a corner
//! whose tip points inward looks the same at every mark of the frame).

use crate::error::{Error, Result};
use std::path::Path;

/// One painted piece; `value` is the tone it leaves (1 the mark, 0 the film).
#[derive(Clone, Debug, PartialEq)]
pub enum Primitive {
    Disc {
        x: f64,
        y: f64,
        r: f64,
        value: f32,
    },
    Ring {
        r: f64,
        width: f64,
        value: f32,
    },
    /// A rectangle centred at (x, y), `len` along the unit direction
    /// `dir` (cos, sin of its angle), `width` across.
    Bar {
        x: f64,
        y: f64,
        len: f64,
        width: f64,
        dir: [f64; 2],
        value: f32,
    },
    /// A filled triangle.
    Triangle {
        p: [[f64; 2]; 3],
        value: f32,
    },
}

impl Primitive {
    fn covers(&self, x: f64, y: f64) -> Option<f32> {
        let hit = match *self {
            Primitive::Disc { x: cx, y: cy, r, .. } => (x - cx).powi(2) + (y - cy).powi(2) <= r * r,
            Primitive::Ring { r, width, .. } => (x.hypot(y) - r).abs() <= width / 2.0,
            Primitive::Bar { x: cx, y: cy, len, width, dir: [c, s], .. } => {
                let (dx, dy) = (x - cx, y - cy);
                (dx * c + dy * s).abs() <= len / 2.0 && (-dx * s + dy * c).abs() <= width / 2.0
            }
            Primitive::Triangle { p, .. } => {
                let side = |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]);
                let (d1, d2, d3) = (side(p[0], p[1]), side(p[1], p[2]), side(p[2], p[0]));
                !((d1 < 0.0 || d2 < 0.0 || d3 < 0.0) && (d1 > 0.0 || d2 > 0.0 || d3 > 0.0))
            }
        };
        let value = match *self {
            Primitive::Disc { value, .. } | Primitive::Ring { value, .. } | Primitive::Bar { value, .. } | Primitive::Triangle { value, .. } => value,
        };
        hit.then_some(value)
    }
}

/// A small image of the mark (the user's template): tones 0..1, centre at
/// its middle, `pixel_mm` its pixel size.
#[derive(Clone, Debug, PartialEq)]
pub struct Picture {
    pub width: usize,
    pub height: usize,
    pub tones: Vec<f32>,
    pub pixel_mm: f64,
}

impl Picture {
    /// Bilinear tone at (x, y) mm from the centre (y up).
    fn tone(&self, x: f64, y: f64) -> f32 {
        let u = x / self.pixel_mm + self.width as f64 / 2.0 - 0.5;
        let v = -y / self.pixel_mm + self.height as f64 / 2.0 - 0.5;
        let (u0, v0) = (u.floor(), v.floor());
        let (fu, fv) = ((u - u0) as f32, (v - v0) as f32);
        // Past its edge the picture goes on as its edge pixels: a template
        // turned a little, or a pixel larger than the picture, reaches
        // there, and black would draw a frame the scan does not have.
        let at = |i: f64, j: f64| -> f32 {
            let i = i.clamp(0.0, self.width as f64 - 1.0) as usize;
            let j = j.clamp(0.0, self.height as f64 - 1.0) as usize;
            self.tones[j * self.width + i]
        };
        let top = at(u0, v0) * (1.0 - fu) + at(u0 + 1.0, v0) * fu;
        let bottom = at(u0, v0 + 1.0) * (1.0 - fu) + at(u0 + 1.0, v0 + 1.0) * fu;
        top * (1.0 - fv) + bottom * fv
    }

    /// The share of the template's half side the second template covers:
    /// its middle half where that shows the mark (a cross's crossing, a
    /// dot), more where the middle is one plain tone (a block's body, whose
    /// edges lie farther out) — the least of ½, ¾, 1 whose spread of tones
    /// is a quarter of the whole template's at least.
    fn fine_share(&self, side: usize) -> f64 {
        let spread = |half: usize| {
            let (cx, cy) = (self.width / 2, self.height / 2);
            let (mut n, mut s, mut ss) = (0.0f64, 0.0f64, 0.0f64);
            for y in cy.saturating_sub(half)..(cy + half).min(self.height) {
                for &t in &self.tones[y * self.width + cx.saturating_sub(half)..y * self.width + (cx + half).min(self.width)] {
                    n += 1.0;
                    s += t as f64;
                    ss += (t * t) as f64;
                }
            }
            (ss / n - (s / n).powi(2)).max(0.0).sqrt()
        };
        let whole = spread(side / 2);
        [0.5, 0.75].into_iter().find(|&share| spread((side as f64 * share / 2.0) as usize) >= 0.25 * whole).unwrap_or(1.0)
    }
}

/// A mark's shape: what the templates are rendered from.
#[derive(Clone, Debug, PartialEq)]
pub struct Shape {
    pub name: String,
    pub primitives: Vec<Primitive>,
    pub picture: Option<Picture>,
    /// Half the side of the square the template covers, mm.
    pub radius_mm: f64,
    /// Half the side of the second template (the mark's precise centre:
    /// its dot, its crossing), mm; thesis §2.6: the coarse template finds
    /// the mark, the second fixes its centre.
    pub fine_radius_mm: f64,
    pub turns_with_place: bool,
}

/// The named shapes and camera families (`interior.fiducial_mark.shape`).
pub const SHAPE_NAMES: &[&str] = &["cross", "dot", "circle-dot", "cross-dot", "corner-dot", "wings", "wild-rc", "zeiss-rmk", "fairchild", "afa"];

/// What a mark looks like: a shape by name, sizes, or a template image.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MarkLook {
    pub shape: String,
    /// The mark's overall size (a cross's arm to arm, a ring's diameter), mm.
    pub size_mm: Option<f64>,
    /// Line width (a cross's bars, a ring), mm.
    pub line_mm: Option<f64>,
    /// A light dot's diameter, mm.
    pub dot_mm: Option<f64>,
}

impl Shape {
    /// The shape a look describes; the camera families are the shapes of
    /// their marks at nominal sizes (set `size_mm`, `line_mm`, `dot_mm`
    /// for another camera, or give a template image).
    pub fn from_look(look: &MarkLook) -> std::result::Result<Shape, String> {
        let family = match look.shape.as_str() {
            "wild-rc" => "cross-dot",
            "zeiss-rmk" => "circle-dot",
            "fairchild" => "wings",
            "afa" => "corner-dot",
            s => s,
        };
        let (size0, line0, dot0) = match family {
            "cross" => (2.0, 0.06, 0.0),
            "dot" => (1.0, 0.0, 1.0),
            "circle-dot" => (1.2, 0.08, 0.12),
            "cross-dot" => (2.0, 0.08, 0.12),
            "corner-dot" => (2.0, 0.0, 0.15),
            "wings" => (2.0, 0.0, 0.12),
            other => return Err(format!("unknown mark shape '{other}' (one of {})", SHAPE_NAMES.join(", "))),
        };
        let size = look.size_mm.unwrap_or(size0);
        let line = look.line_mm.unwrap_or(line0);
        let dot = look.dot_mm.unwrap_or(dot0);
        for (what, v) in [("size_mm", size), ("line_mm", line), ("dot_mm", dot)] {
            if !(v.is_finite() && (0.0..=20.0).contains(&v)) {
                return Err(format!("{what} = {v}: not a size from 0 to 20 mm"));
            }
        }
        if size <= 0.0 || (family == "cross" && line <= 0.0) || (family == "dot" && dot <= 0.0) {
            return Err(format!("a {family} mark needs a positive size and line"));
        }
        let h = size / 2.0;
        let (primitives, fine, turns) = match family {
            "cross" => (vec![bar(0.0, line, size), bar(90.0, line, size)], (6.0 * line).max(0.3 * h), false),
            "dot" => (vec![Primitive::Disc { x: 0.0, y: 0.0, r: dot / 2.0, value: 1.0 }], dot, false),
            "circle-dot" => (
                vec![Primitive::Ring { r: h, width: line, value: 1.0 }, Primitive::Disc { x: 0.0, y: 0.0, r: dot / 2.0, value: 1.0 }],
                (3.0 * dot).max(0.4 * h),
                false,
            ),
            "cross-dot" => {
                // Four arms that stop short of the centre, a dot in the gap.
                let gap = (3.0 * dot).max(0.15 * size);
                let arm = h - gap;
                let mut p = Vec::new();
                for k in 0..4 {
                    let a = (k as f64 * 90.0).to_radians();
                    let m = gap + arm / 2.0;
                    p.push(Primitive::Bar { x: m * a.cos(), y: m * a.sin(), len: arm, width: line, dir: [a.cos(), a.sin()], value: 1.0 });
                }
                p.push(Primitive::Disc { x: 0.0, y: 0.0, r: dot / 2.0, value: 1.0 });
                (p, gap + 0.3 * arm, false)
            }
            "corner-dot" => {
                // The thesis's mark: a dark corner whose tip points to the
                // frame centre, a light dot just inside the tip.
                let tip = -0.6 * dot.max(0.1);
                let reach = size;
                let p = vec![
                    Primitive::Triangle { p: [[tip, 0.0], [tip + reach, reach], [tip + reach, -reach]], value: 1.0 },
                    Primitive::Disc { x: 0.0, y: 0.0, r: dot / 2.0, value: 0.0 },
                ];
                (p, (4.0 * dot).max(0.25 * h), true)
            }
            "wings" => {
                // Two triangles tip to tip across the frame edge, a dot
                // between the tips (Fairchild's "wing" marks).
                let gap = 1.5 * dot.max(0.05);
                let p = vec![
                    Primitive::Triangle { p: [[gap, 0.0], [h, h / 2.0], [h, -h / 2.0]], value: 1.0 },
                    Primitive::Triangle { p: [[-gap, 0.0], [-h, h / 2.0], [-h, -h / 2.0]], value: 1.0 },
                    Primitive::Disc { x: 0.0, y: 0.0, r: dot / 2.0, value: 1.0 },
                ];
                (p, (4.0 * dot).max(0.3 * h), true)
            }
            _ => unreachable!("checked above"),
        };
        Ok(Shape { name: look.shape.clone(), primitives, picture: None, radius_mm: h * 1.25, fine_radius_mm: fine.min(h * 1.25), turns_with_place: turns })
    }

    /// A template image (PNG or TIFF, grey or colour; the mark at its
    /// centre) of pixels `pixel_mm` wide.
    pub fn from_picture(path: &Path, pixel_mm: f64) -> Result<Shape> {
        if !(pixel_mm.is_finite() && pixel_mm > 0.0) {
            return Err(Error::setting("template_pixel_mm", format!("{pixel_mm} is not a positive pixel size")));
        }
        let src = crate::io::source::SourceImage::open(path, 8 << 20)?;
        let (w, h) = (src.info.width, src.info.height);
        if w < 5 || h < 5 || w > 2048 || h > 2048 {
            return Err(Error::format(path, format!("{w}×{h}: a mark template is 5 to 2048 pixels a side")));
        }
        let gray = super::gray::Gray::read(&src, (0, 0, w, h), 1)?;
        let (lo, hi) = gray.data.iter().fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        if !(hi > lo) {
            return Err(Error::format(path, "the template is all one tone"));
        }
        let tones = gray.data.iter().map(|v| (v - lo) / (hi - lo)).collect();
        let picture = Picture { width: w as usize, height: h as usize, tones, pixel_mm };
        let side = w.min(h) as usize;
        let radius = side as f64 * pixel_mm / 2.0;
        let fine_radius_mm = radius * picture.fine_share(side);
        Ok(Shape {
            name: format!("template {}", path.display()),
            primitives: Vec::new(),
            picture: Some(picture),
            radius_mm: radius,
            fine_radius_mm,
            turns_with_place: false,
        })
    }

    /// The tone at (x, y) mm in the mark's frame: the last primitive that
    /// covers the point, else the film (0).
    #[must_use]
    pub fn tone(&self, x: f64, y: f64) -> f32 {
        if let Some(p) = &self.picture {
            return p.tone(x, y);
        }
        self.primitives.iter().rev().find_map(|p| p.covers(x, y)).unwrap_or(0.0)
    }
}

fn bar(angle_deg: f64, width: f64, len: f64) -> Primitive {
    let (s, c) = angle_deg.to_radians().sin_cos();
    Primitive::Bar { x: 0.0, y: 0.0, len, width, dir: [c, s], value: 1.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn look(shape: &str) -> MarkLook {
        MarkLook { shape: shape.into(), ..Default::default() }
    }

    #[test]
    fn a_cross_is_its_bars() {
        let s = Shape::from_look(&look("cross")).unwrap();
        assert_eq!(s.tone(0.0, 0.0), 1.0);
        assert_eq!(s.tone(0.9, 0.02), 1.0);
        assert_eq!(s.tone(0.9, 0.05), 0.0, "a line 0.06 mm wide");
        assert_eq!(s.tone(1.1, 0.0), 0.0, "arms 1 mm");
        assert_eq!(s.tone(0.3, 0.3), 0.0);
    }

    #[test]
    fn the_thesis_mark_is_a_dark_corner_with_a_light_dot() {
        let s = Shape::from_look(&look("afa")).unwrap();
        assert!(s.turns_with_place);
        assert_eq!(s.tone(0.0, 0.0), 0.0, "the light dot");
        assert_eq!(s.tone(0.5, 0.0), 1.0, "the corner, outward of the tip");
        assert_eq!(s.tone(-0.5, 0.0), 0.0, "nothing toward the frame centre");
    }

    #[test]
    fn unknown_shapes_and_absurd_sizes_are_refused() {
        assert!(Shape::from_look(&look("star")).unwrap_err().contains("unknown mark shape 'star'"));
        let big = MarkLook { size_mm: Some(1e6), ..look("cross") };
        assert!(Shape::from_look(&big).unwrap_err().contains("size_mm"));
    }
}
