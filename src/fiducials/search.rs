//! The first, coarse search: where a mark can be (its calibrated place,
//! the scan's size, an unknown turn and an uncertain scan scale) gives a
//! window in the scan's margin; each window is read reduced (a level
//! coarse enough for the mark to span some 16 pixels) and correlated with
//! the templates of every mark a turn can put there. The turn and the
//! film's tone (positive or negative) are then the ones whose peaks agree
//! with one similarity transform of the calibrated layout.

use super::correlate::{correlate, Peak};
use super::gray::Gray;
use super::shape::Shape;
use super::template::Template;
use super::turn::Turn;
use super::{Polarity, Request};
use crate::error::Result;
use crate::io::source::SourceImage;
use nalgebra::{Matrix2, Vector2};
use rayon::prelude::*;

/// The scan scale (pixels a millimetre) and how sure it is.
#[derive(Clone, Copy, Debug)]
pub struct ScaleRange {
    pub lo: f64,
    pub hi: f64,
}

impl ScaleRange {
    pub fn mid(&self) -> f64 {
        (self.lo * self.hi).sqrt()
    }
}

/// Peaks kept per template and tone.
const CANDIDATES: usize = 3;

/// The most a film lies turned on the scanner beyond quarter turns, degrees.
const MAX_TURN_DEG: f64 = 4.0;

/// A search window and the templates looked for in it.
struct Slot {
    /// Full-resolution window (x0, y0, x1, y1).
    window: [f64; 4],
    /// (turn index, mark) pairs that land here, with their template's index.
    members: Vec<(usize, usize, usize)>,
}

/// What the coarse search found for one mark under one turn and tone.
#[derive(Clone, Debug)]
pub struct Candidate {
    pub at: [f64; 2],
    pub score: f32,
}

/// The coarse search's answer: the turn, the tone, a similarity and each
/// mark's place (None: nothing that agrees).
#[derive(Clone, Debug)]
pub struct Coarse {
    pub turn: Turn,
    /// Another turn fits as well (a symmetric layout): taken as scanned.
    pub ambiguous: bool,
    pub polarity: Polarity,
    /// Photo mm (fiducial system) → scan px, similarity.
    pub to_px: Matrix2<f64>,
    pub centre: Vector2<f64>,
    pub places: Vec<Option<Candidate>>,
    pub factor: u32,
}

pub fn linear(turn: Turn, scale: f64, shape: &Shape, mark: [f64; 2]) -> Matrix2<f64> {
    turn.matrix() * scale * own_turn(shape, mark)
}

/// The mark's own frame → photo: turned to the mark's direction from the
/// centre for shapes that turn with their place.
pub fn own_turn(shape: &Shape, mark: [f64; 2]) -> Matrix2<f64> {
    if shape.turns_with_place && mark[0].hypot(mark[1]) > 0.0 {
        let a = mark[1].atan2(mark[0]);
        let (s, c) = a.sin_cos();
        Matrix2::new(c, -s, s, c)
    } else {
        Matrix2::identity()
    }
}

/// The coarse search.
pub fn coarse(req: &Request<'_>, src: &SourceImage, scale: ScaleRange) -> Result<Coarse> {
    let (w, h) = (src.info.width as f64, src.info.height as f64);
    let turns: Vec<Turn> = match req.turn {
        Some(t) => vec![t],
        None => Turn::all().to_vec(),
    };
    let s = scale.mid();
    // A level where the largest mark spans some 16 pixels.
    let size_px = req.shapes.iter().map(|sh| 2.0 * sh.radius_mm).fold(0.0, f64::max) * s;
    let factor = ((size_px / 16.0).floor() as u32).clamp(1, 16);
    let slack = 0.03 * w.max(h) + 4.0 * factor as f64;
    let margin_px = req.shapes.iter().map(|sh| sh.radius_mm).fold(0.0, f64::max) * scale.hi;
    let mut templates: Vec<(Template, Matrix2<f64>, usize)> = Vec::new();
    let mut slots: Vec<Slot> = Vec::new();
    for (ti, &turn) in turns.iter().enumerate() {
        let m = turn.matrix();
        for (k, &mm) in req.marks_mm.iter().enumerate() {
            let shape = &req.shapes[k];
            let dir = m * Vector2::new(mm[0], mm[1]);
            let r = shape.radius_mm * scale.hi;
            let (a, b) = (dir * scale.lo, dir * scale.hi);
            let window = [
                w / 2.0 + a.x.min(b.x) - slack - r,
                h / 2.0 + a.y.min(b.y) - slack - r,
                w / 2.0 + a.x.max(b.x) + slack + r,
                h / 2.0 + a.y.max(b.y) + slack + r,
            ];
            if window[2] <= 0.0 || window[3] <= 0.0 || window[0] >= w || window[1] >= h {
                continue;
            }
            // Templates turned by the film's few degrees on the scanner, in
            // steps that move the template's rim by about half a pixel.
            let rim = shape.radius_mm * s / factor as f64;
            let step = (0.6 / rim.max(1.0)).atan().to_degrees().max(0.5);
            let turns_of_film = (MAX_TURN_DEG / step + 0.5).floor() as i32;
            let mut tpls = Vec::new();
            for a in -turns_of_film..=turns_of_film {
                let (sn, cs) = (a as f64 * step).to_radians().sin_cos();
                let lin = Matrix2::new(cs, -sn, sn, cs) * linear(turn, s / factor as f64, shape, mm);
                let tpl = match templates.iter().position(|(_, l, sh)| *sh == req.shape_index[k] && (l - lin).norm() < 1e-6) {
                    Some(i) => i,
                    None => {
                        let Some(t) = Template::render(shape, &lin, shape.radius_mm, [0.0, 0.0]) else { continue };
                        templates.push((t, lin, req.shape_index[k]));
                        templates.len() - 1
                    }
                };
                tpls.push(tpl);
            }
            let centre = [(window[0] + window[2]) / 2.0, (window[1] + window[3]) / 2.0];
            let near = slots.iter().position(|sl| {
                let c = [(sl.window[0] + sl.window[2]) / 2.0, (sl.window[1] + sl.window[3]) / 2.0];
                (c[0] - centre[0]).abs() < (window[2] - window[0]) / 4.0 && (c[1] - centre[1]).abs() < (window[3] - window[1]) / 4.0
            });
            match near {
                Some(i) => {
                    let sl = &mut slots[i];
                    sl.window = [sl.window[0].min(window[0]), sl.window[1].min(window[1]), sl.window[2].max(window[2]), sl.window[3].max(window[3])];
                    sl.members.extend(tpls.iter().map(|&t| (ti, k, t)));
                }
                None => slots.push(Slot { window, members: tpls.iter().map(|&t| (ti, k, t)).collect() }),
            }
        }
    }
    // Each slot read once, reduced, and correlated with its templates.
    let found: Vec<Vec<(usize, [Vec<Candidate>; 2])>> = slots
        .par_iter()
        .map(|sl| -> Result<Vec<(usize, [Vec<Candidate>; 2])>> {
            // Past the scan's edge by a template's reach: a mark cut by the
            // edge still has its whole template (the rest padded).
            let pad = margin_px;
            let x0 = sl.window[0].max(-pad).floor() as i64;
            let y0 = sl.window[1].max(-pad).floor() as i64;
            let x1 = sl.window[2].min(w + pad).ceil() as i64;
            let y1 = sl.window[3].min(h + pad).ceil() as i64;
            let gray = Gray::read_padded(src, (x0, y0, (x1 - x0) as u32, (y1 - y0) as u32), factor)?;
            let mut tpls: Vec<usize> = sl.members.iter().map(|m| m.2).collect();
            tpls.sort_unstable();
            tpls.dedup();
            Ok(tpls
                .into_iter()
                .map(|t| {
                    let tpl = &templates[t].0;
                    let surface = correlate(&gray, tpl, (0, 0, gray.width, gray.height));
                    let to_candidates = |sign: f32| -> Vec<Candidate> {
                        surface.peaks(sign, CANDIDATES, tpl.half).into_iter().map(|p: Peak| Candidate { at: centre_of(&gray, p, tpl), score: p.r }).collect()
                    };
                    (t, [to_candidates(1.0), to_candidates(-1.0)])
                })
                .collect())
        })
        .collect::<Result<_>>()?;
    // Candidates of (turn, mark) by tone.
    let lookup = |ti: usize, k: usize, tone: usize| -> Vec<Candidate> {
        let mut out = Vec::new();
        for (sl, res) in slots.iter().zip(&found) {
            for &(t, kk, tpl) in &sl.members {
                if t == ti && kk == k {
                    if let Some((_, c)) = res.iter().find(|(x, _)| *x == tpl) {
                        out.extend(c[tone].iter().cloned());
                    }
                }
            }
        }
        out
    };
    let tones: Vec<(usize, Polarity)> = match req.polarity {
        Polarity::Auto => vec![(0, Polarity::Light), (1, Polarity::Dark)],
        Polarity::Light => vec![(0, Polarity::Light)],
        Polarity::Dark => vec![(1, Polarity::Dark)],
    };
    let tolerance = 2.5 * factor as f64 + 0.004 * s * reach(req.marks_mm);
    let mut best: Option<(f64, Coarse)> = None;
    let mut scores = Vec::new();
    for (ti, &turn) in turns.iter().enumerate() {
        for &(tone, polarity) in &tones {
            let cands: Vec<Vec<Candidate>> = (0..req.marks_mm.len()).map(|k| lookup(ti, k, tone)).collect();
            let Some((score, places, to_px, centre)) = agree(req.marks_mm, turn, &cands, tolerance) else { continue };
            scores.push((ti, tone, score));
            if best.as_ref().is_none_or(|(b, _)| score > *b + 1e-4 * b.abs()) {
                best = Some((score, Coarse { turn, ambiguous: false, polarity, to_px, centre, places, factor }));
            }
        }
    }
    let Some((score, mut coarse)) = best else {
        return Ok(Coarse {
            turn: Turn::NONE,
            ambiguous: false,
            polarity: Polarity::Light,
            to_px: Matrix2::zeros(),
            centre: Vector2::zeros(),
            places: vec![None; req.marks_mm.len()],
            factor,
        });
    };
    let winner = turns.iter().position(|t| *t == coarse.turn).unwrap_or(0);
    let tied: Vec<Turn> = scores.iter().filter(|&&(ti, _, sc)| ti != winner && sc >= score - 1e-3 * score.abs()).map(|&(ti, _, _)| turns[ti]).collect();
    coarse.ambiguous = !tied.is_empty();
    if coarse.ambiguous && coarse.turn != Turn::NONE {
        // Turned, but the marks cannot say which way: taking one would be a guess.
        let mut ways: Vec<String> = std::iter::once(coarse.turn).chain(tied).map(Turn::describe).collect();
        ways.dedup();
        return Err(crate::error::Error::format(
            &src.path,
            format!("the film lies turned on the scanner, but its marks fit it {}: give ‹turn› (marks that differ from each other tell it)", ways.join(" or ")),
        ));
    }
    Ok(coarse)
}

/// The largest distance of a mark from the fiducial centre, mm.
pub fn reach(marks: &[[f64; 2]]) -> f64 {
    marks.iter().map(|m| m[0].hypot(m[1])).fold(0.0, f64::max)
}

/// A peak's mark centre in scan pixels.
fn centre_of(g: &Gray, p: Peak, t: &Template) -> [f64; 2] {
    g.to_scan(p.i as f64 + t.half as f64 + 0.5, p.j as f64 + t.half as f64 + 0.5)
}

/// The similarity (through pairs of marks' best candidates) that most
/// candidates agree with: its summed scores, each mark's agreeing
/// candidate, and the map.
#[allow(clippy::type_complexity)]
fn agree(marks: &[[f64; 2]], turn: Turn, cands: &[Vec<Candidate>], tol: f64) -> Option<(f64, Vec<Option<Candidate>>, Matrix2<f64>, Vector2<f64>)> {
    let m = turn.matrix();
    let n = marks.len();
    let mut best: Option<(f64, Vec<Option<Candidate>>, Matrix2<f64>, Vector2<f64>)> = None;
    for a in 0..n {
        for b in a + 1..n {
            for ca in cands[a].iter().take(2) {
                for cb in cands[b].iter().take(2) {
                    if ca.score <= 0.0 || cb.score <= 0.0 {
                        continue;
                    }
                    // Similarity p = c + λ·R·M·mm through the two.
                    let (pa, pb) = (m * Vector2::from(marks[a]), m * Vector2::from(marks[b]));
                    let (qa, qb) = (Vector2::from(ca.at), Vector2::from(cb.at));
                    let (dp, dq) = (pb - pa, qb - qa);
                    if dp.norm() == 0.0 {
                        continue;
                    }
                    let lambda = dq.norm() / dp.norm();
                    let ang = dq.y.atan2(dq.x) - dp.y.atan2(dp.x);
                    // Scans lie square within a few degrees.
                    let ang = (ang + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI;
                    if ang.abs() > 8f64.to_radians() {
                        continue;
                    }
                    let (s, c) = ang.sin_cos();
                    let lin = Matrix2::new(c, -s, s, c) * lambda * m;
                    let centre = qa - lin * Vector2::from(marks[a]);
                    let mut total = 0.0;
                    let places: Vec<Option<Candidate>> = (0..n)
                        .map(|k| {
                            let want = centre + lin * Vector2::from(marks[k]);
                            let hit = cands[k]
                                .iter()
                                .filter(|c| c.score > 0.0 && (Vector2::from(c.at) - want).norm() < tol)
                                .max_by(|x, y| x.score.total_cmp(&y.score))
                                .cloned();
                            total += hit.as_ref().map_or(0.0, |c| c.score as f64);
                            hit
                        })
                        .collect();
                    if best.as_ref().is_none_or(|bb| total > bb.0) {
                        best = Some((total, places, lin, centre));
                    }
                }
            }
        }
    }
    best
}
