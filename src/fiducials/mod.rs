//! Fiducial marks found in a film scan without hand work (Chibunichev's
//! thesis §2.6): templates generated from a formal description of the mark
//! (`shape.rs`, `template.rs`), searched by normalised correlation (2.6.11,
//! `correlate.rs`) on a pyramid of the scan's margins — a coarse level over
//! windows where the calibrated marks can lie whatever the film's turn
//! (`search.rs`), then the levels reduced 5, 4, 3, 2 times and the full
//! resolution, and the second template to a fraction of a pixel
//! (`refine.rs`) — and the interior orientation fitted with its checks
//! (`fit.rs`). Only windows around the marks are read: memory does not
//! grow with the scan.

pub mod camera;
pub mod correlate;
pub mod fit;
pub mod gray;
pub mod refine;
pub mod search;
pub mod shape;
pub mod sheet;
pub mod template;
pub mod turn;

use crate::error::{Error, Result};
use crate::io::source::SourceImage;
use rayon::prelude::*;
pub use shape::{MarkLook, Shape};
pub use turn::Turn;

/// The marks' tone against the film around them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Polarity {
    /// Found from the scan (a positive or a negative).
    #[default]
    Auto,
    /// Marks lighter than the film around them.
    Light,
    /// Marks darker than the film around them.
    Dark,
}

impl crate::options::Choice for Polarity {
    const NAMES: &'static [&'static str] = &["auto", "light", "dark"];
    fn from_name(name: &str) -> Option<Self> {
        [Polarity::Auto, Polarity::Light, Polarity::Dark].into_iter().zip(Self::NAMES).find(|(_, n)| **n == name).map(|(p, _)| p)
    }
}

/// What to look for.
pub struct Request<'a> {
    /// Calibrated mark coordinates, mm (fiducial system, y up).
    pub marks_mm: &'a [[f64; 2]],
    /// Each mark's shape, and which marks share one (for the templates).
    pub shapes: Vec<Shape>,
    pub shape_index: Vec<usize>,
    /// The scan's pixel size, mm, where known (the camera file, the
    /// scan's resolution tags); else the scan's size bounds it.
    pub pixel_mm: Option<f64>,
    pub polarity: Polarity,
    /// The film's turn on the scanner where known; None: found.
    pub turn: Option<Turn>,
    /// The most a mark may sit off the fitted map, px.
    pub limit_px: f64,
}

/// A mark correlating less than this with its template is not found.
pub const MIN_SCORE: f32 = 0.45;

/// With only three marks (no check), each must correlate this well.
pub const STRONG_SCORE: f32 = 0.7;

/// One mark of the camera's.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FoundMark {
    /// 1-based, in the camera file's order.
    pub mark: usize,
    pub mm: [f64; 2],
    /// Its centre in the scan (column, row; pixel centres at ½).
    pub px: Option<[f64; 2]>,
    /// Correlation of the mark's template and of its centre's there.
    pub score: f32,
    pub centre_score: f32,
    /// In the interior orientation.
    pub used: bool,
    /// Found minus fitted, px and µm (photo axes).
    pub residual_px: Option<[f64; 2]>,
    pub residual_um: Option<[f64; 2]>,
    /// Why it is not used.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub why: Option<String>,
    /// Half the side of its template, mm (for the sheet).
    #[serde(skip)]
    pub radius_mm: f64,
}

/// What `fiducials` found.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Detection {
    pub marks: Vec<FoundMark>,
    pub turn: Turn,
    pub turn_text: String,
    /// The marks' layout looks the same turned: the scan was taken as it lies.
    pub turn_ambiguous: bool,
    pub polarity: Polarity,
    /// The scan's pixel size along the photo's axes, mm.
    pub pixel_mm: [f64; 2],
    /// The film's small turn on the scanner beyond the quarter turns, degrees.
    pub rotation_deg: f64,
    pub rms_px: f64,
    pub max_px: f64,
    pub max_um: f64,
    /// The pyramid's coarsest level (reduction).
    pub coarse_level: u32,
    /// Doubtful things (a fit without redundancy, marks left out).
    pub warnings: Vec<String>,
}

impl Detection {
    /// Measured positions of the marks used, in the camera's order, with
    /// their calibrated coordinates.
    #[must_use]
    pub fn used(&self) -> (Vec<[f64; 2]>, Vec<[f64; 2]>) {
        self.marks.iter().filter(|m| m.used).filter_map(|m| Some((m.mm, m.px?))).unzip()
    }
}

/// The marks (indices) of a layout that has mirror images about its centre
/// (every camera's: corners and sides in pairs) but none of their own, to
/// 1 mm: mistyped coordinates. None where the layout has no such pairs.
fn lone_marks(marks: &[[f64; 2]]) -> Vec<usize> {
    let near = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]) <= 1.0;
    let mirrored = |k: usize| {
        let [x, y] = marks[k];
        [[-x, -y], [-x, y], [x, -y]].iter().any(|&m| marks.iter().enumerate().any(|(j, &o)| j != k && near(m, o)))
    };
    let lone: Vec<usize> = (0..marks.len()).filter(|&k| !mirrored(k)).collect();
    if lone.len() * 2 <= marks.len() {
        lone
    } else {
        Vec::new()
    }
}

/// Finds the marks in `src`.
pub fn detect(src: &SourceImage, req: &Request<'_>) -> Result<Detection> {
    let path = &src.path;
    let n = req.marks_mm.len();
    if n < 3 {
        return Err(Error::format(path, format!("{n} calibrated fiducial marks: at least 3 are needed")));
    }
    let scale = scale_range(src, req);
    let coarse = search::coarse(req, src, scale)?;
    let found_coarse = coarse.places.iter().filter(|p| p.is_some()).count();
    if found_coarse < 2 {
        return Err(Error::format(
            path,
            format!("no fiducial marks like the camera's ({}) where its calibrated marks would lie in this scan", describe_shapes(req)),
        ));
    }
    let sign = if coarse.polarity == Polarity::Dark { -1.0 } else { 1.0 };
    let starts: Vec<[f64; 2]> = (0..n)
        .map(|k| match &coarse.places[k] {
            Some(c) => c.at,
            None => {
                let p = coarse.centre + coarse.to_px * nalgebra::Vector2::from(req.marks_mm[k]);
                [p.x, p.y]
            }
        })
        .collect();
    let mut refined = refine_marks(src, req, &coarse.to_px, &(0..n).collect::<Vec<_>>(), &starts, coarse.factor, sign)?;
    // The coarse level's turn and scale are a few tenths of a degree and
    // of a percent off; a template whose features lie far from its centre
    // (a real mark cut with its surroundings) then peaks that much off.
    // Once the marks are found, the templates are drawn again with the map
    // they give, and the marks found looked for again at full resolution
    // (a mark not found stays so: the scan's edge may cut it).
    let good = |r: &Option<refine::Refined>| r.is_some_and(|r| r.score >= MIN_SCORE && r.centre_score >= MIN_SCORE);
    let found: Vec<usize> = (0..n).filter(|&k| good(&refined[k])).collect();
    let mm: Vec<[f64; 2]> = found.iter().map(|&k| req.marks_mm[k]).collect();
    let px: Vec<[f64; 2]> = found.iter().filter_map(|&k| Some(refined[k]?.at)).collect();
    if let Some(map) = (found.len() >= 3).then(|| crate::geom::Affine2::fit(&mm, &px)).flatten() {
        let again = refine_marks(src, req, &map.m, &found, &px, 2, sign)?;
        for (&k, a) in found.iter().zip(again) {
            if good(&a) {
                refined[k] = a;
            }
        }
    }
    let mut marks: Vec<FoundMark> = (0..n)
        .map(|k| {
            let r = refined[k];
            let good = r.is_some_and(|r| r.score >= MIN_SCORE && r.centre_score >= MIN_SCORE);
            FoundMark {
                mark: k + 1,
                mm: req.marks_mm[k],
                px: r.map(|r| r.at),
                score: r.map_or(0.0, |r| r.score),
                centre_score: r.map_or(0.0, |r| r.centre_score),
                used: good,
                residual_px: None,
                residual_um: None,
                radius_mm: req.shapes[k].radius_mm,
                why: (!good).then(|| format!("correlation {:.2} / {:.2}, below {MIN_SCORE}", r.map_or(0.0, |r| r.score), r.map_or(0.0, |r| r.centre_score))),
            }
        })
        .collect();
    let usable: Vec<(usize, [f64; 2], [f64; 2])> = marks.iter().enumerate().filter(|(_, m)| m.used).filter_map(|(k, m)| Some((k, m.mm, m.px?))).collect();
    let list = |marks: &[FoundMark]| marks.iter().map(|m| format!("mark {}: {:.2}", m.mark, m.score)).collect::<Vec<_>>().join(", ");
    if usable.len() < 3 {
        // A calibrated mark typed wrong moves every search window: say so
        // where the layout shows it.
        let why = match lone_marks(req.marks_mm).as_slice() {
            [] => "is the mark's shape right?".to_string(),
            lone => format!(
                "calibrated mark(s) {} have no mirror image in the layout about its centre: is fiducials_mm typed right? Else, is the mark's shape right?",
                lone.iter().map(|&k| format!("{} at {:?} mm", k + 1, req.marks_mm[k])).collect::<Vec<_>>().join(", ")
            ),
        };
        return Err(Error::format(path, format!("found {} of {n} fiducial marks, 3 at least are needed ({}): {why}", usable.len(), list(&marks))));
    }
    let fit = fit::robust_affine(&usable, req.limit_px).ok_or_else(|| Error::format(path, "the marks found lie on one line"))?;
    let inverse = fit.map.inverse().ok_or_else(|| Error::format(path, "the marks found lie on one line"))?;
    let mut warnings = Vec::new();
    for (u, &(k, mm, px)) in usable.iter().enumerate() {
        let r = fit.residuals_px[u];
        let (x, y) = inverse.apply(px[0], px[1]);
        marks[k].residual_px = Some(r);
        marks[k].residual_um = Some([(x - mm[0]) * 1e3, (y - mm[1]) * 1e3]);
        if !fit.kept.contains(&k) {
            marks[k].used = false;
            marks[k].why = Some(format!("{:.2} px off the map of the others", r[0].hypot(r[1])));
            warnings.push(format!("fiducial mark {} left out: it sits {:.2} px off the map of the others", k + 1, r[0].hypot(r[1])));
        }
    }
    let kept: Vec<&FoundMark> = marks.iter().filter(|m| m.used).collect();
    let off: Vec<f64> = kept.iter().map(|m| m.residual_px.map_or(0.0, |r| r[0].hypot(r[1]))).collect();
    let max_px = off.iter().cloned().fold(0.0, f64::max);
    let rms_px = (off.iter().map(|d| d * d).sum::<f64>() / off.len() as f64).sqrt();
    let max_um = kept.iter().map(|m| m.residual_um.map_or(0.0, |r| r[0].hypot(r[1]))).fold(0.0, f64::max);
    if max_px > req.limit_px {
        return Err(Error::format(
            path,
            format!("the fiducial marks found sit up to {max_px:.2} px off one interior orientation, more than {} px ({}): a mark found wrong, or the wrong calibration?", req.limit_px, list(&marks)),
        ));
    }
    if let Some(why) = fit::implausible(&fit.map) {
        return Err(Error::format(path, format!("{why}: no scanner does that; the marks were found wrong or the calibration is another camera's")));
    }
    if kept.len() == 3 {
        // Three marks fit any affine map exactly: only strong matches pass.
        if let Some(weak) = kept.iter().find(|m| m.score.min(m.centre_score) < STRONG_SCORE) {
            return Err(Error::format(
                path,
                format!(
                    "only 3 fiducial marks found, mark {} weakly ({:.2}): an interior orientation from them would have no check ({})",
                    weak.mark,
                    weak.score.min(weak.centre_score),
                    list(&marks)
                ),
            ));
        }
        warnings.push("only 3 fiducial marks found: the interior orientation has no check".into());
    }
    let (sw, sh) = (src.info.width as f64, src.info.height as f64);
    for m in &marks {
        if m.px.is_none() || (!m.used && m.why.as_deref().is_some_and(|w| w.starts_with("correlation"))) {
            // Where the others put it: a mark the scan's edge cuts off is
            // the scan's fault, not the search's.
            let (c, r) = fit.map.apply(m.mm[0], m.mm[1]);
            let reach = m.radius_mm * fit.map.m.norm() / std::f64::consts::SQRT_2;
            let edge = if c < reach || r < reach || c > sw - reach || r > sh - reach {
                format!("; the others put it at ({c:.0}, {r:.0}), where the scan's edge cuts it off: scan the whole film")
            } else {
                String::new()
            };
            warnings.push(format!("fiducial mark {} not found ({}){edge}", m.mark, m.why.clone().unwrap_or_default()));
        }
    }
    let turn = Turn::nearest(&fit.map.m);
    if turn != coarse.turn {
        warnings.push(format!("the marks' fit turns the film otherwise ({}) than their search ({})", turn.describe(), coarse.turn.describe()));
    }
    let lin = fit.map.m * turn.matrix().transpose();
    let rotation_deg = lin[(1, 0)].atan2(lin[(0, 0)]).to_degrees();
    let (a, b) = (fit.map.m.column(0).norm(), fit.map.m.column(1).norm());
    Ok(Detection {
        marks,
        turn,
        turn_text: turn.describe(),
        turn_ambiguous: coarse.ambiguous && req.turn.is_none(),
        polarity: coarse.polarity,
        pixel_mm: [1.0 / a, 1.0 / b],
        rotation_deg,
        rms_px,
        max_px,
        max_um,
        coarse_level: coarse.factor,
        warnings,
    })
}

/// The marks `which` refined from their `starts` with templates drawn by
/// `to_px` (photo mm → scan px, linear part), from the level below `factor`.
fn refine_marks(src: &SourceImage, req: &Request<'_>, to_px: &nalgebra::Matrix2<f64>, which: &[usize], starts: &[[f64; 2]], factor: u32, sign: f32) -> Result<Vec<Option<refine::Refined>>> {
    which
        .par_iter()
        .zip(starts)
        .map(|(&k, &start)| {
            let shape = &req.shapes[k];
            refine::refine(src, shape, &(to_px * search::own_turn(shape, req.marks_mm[k])), start, factor, sign)
        })
        .collect()
}

fn describe_shapes(req: &Request<'_>) -> String {
    let mut names: Vec<&str> = req.shapes.iter().map(|s| s.name.as_str()).collect();
    names.dedup();
    names.join(", ")
}

/// Pixels a millimetre the scan can have: about the known pixel size, or
/// from the scan's size (the marks lie inside it, the film's border does
/// not take more than a quarter of it).
fn scale_range(src: &SourceImage, req: &Request<'_>) -> search::ScaleRange {
    if let Some(p) = req.pixel_mm {
        return search::ScaleRange { lo: 0.97 / p, hi: 1.03 / p };
    }
    let extent = req.marks_mm.iter().flat_map(|m| [m[0].abs(), m[1].abs()]).fold(0.0, f64::max);
    let margin = req.shapes.iter().map(|s| s.radius_mm).fold(0.0, f64::max);
    let half = src.info.width.min(src.info.height) as f64 / 2.0;
    let hi = half / (extent + margin);
    search::ScaleRange { lo: hi / 1.35, hi }
}
