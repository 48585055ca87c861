//! How much of each image goes into each cell: all of the cell's own
//! image away from the seams; across a seam, a ramp `--blend` pixels wide
//! from one image to the other (feathering), except on a height edge of
//! the DSM, where the cut stays sharp (a blend there would show a roof
//! twice). Each cell knows its distance to the nearest boundary cell of
//! its own image and the image across it (a two-pass propagation of the
//! nearest boundary cell, 8-connected). Only the cells within the ramp
//! are kept (a few per seam cell): elsewhere a cell is its own image's.

use super::plan::{Plan, NONE};
use rustc_hash::FxHashMap as HashMap;

pub struct Weights {
    cw: usize,
    label: Vec<u16>,
    /// The cells whose own image weighs under 1 (within the ramp of a
    /// boundary, off height edges): that weight, and the image across.
    near: HashMap<u32, (f32, u16)>,
    /// Whether the blend is a ramp at all.
    ramp: bool,
}

impl Weights {
    pub fn new(plan: &Plan, blend_px: f64, edges: &[bool]) -> Weights {
        let (cw, ch) = (plan.cw, plan.ch);
        let n = cw * ch;
        // Ramp width, cells (0: no blend).
        let ramp = (blend_px / plan.cell as f64) as f32;
        if ramp <= 0.0 {
            return Weights { cw, label: plan.label.clone(), near: HashMap::default(), ramp: false };
        }
        let mut seed = vec![(i32::MIN, i32::MIN); n];
        let mut other = vec![NONE; n];
        for y in 0..ch {
            for x in 0..cw {
                let l = plan.label_at(x, y);
                if l == NONE {
                    continue;
                }
                let across = [(x.wrapping_sub(1), y), (x + 1, y), (x, y.wrapping_sub(1)), (x, y + 1)]
                    .into_iter()
                    .filter(|&(a, b)| a < cw && b < ch)
                    .map(|(a, b)| plan.label_at(a, b))
                    .find(|&m| m != NONE && m != l);
                if let Some(m) = across {
                    seed[y * cw + x] = (x as i32, y as i32);
                    other[y * cw + x] = m;
                }
            }
        }
        let d2 = |k: usize, s: (i32, i32)| {
            if s.0 == i32::MIN {
                return i64::MAX;
            }
            let (x, y) = ((k % cw) as i64, (k / cw) as i64);
            (x - s.0 as i64).pow(2) + (y - s.1 as i64).pow(2)
        };
        let relax = |k: usize, n: usize, seed: &mut Vec<(i32, i32)>, other: &mut Vec<u16>| {
            if plan.label[n] == plan.label[k] && d2(k, seed[n]) < d2(k, seed[k]) {
                seed[k] = seed[n];
                other[k] = other[n];
            }
        };
        for y in 0..ch {
            for x in 0..cw {
                let k = y * cw + x;
                for (dx, dy) in [(-1i64, 0i64), (-1, -1), (0, -1), (1, -1)] {
                    let (a, b) = (x as i64 + dx, y as i64 + dy);
                    if a >= 0 && b >= 0 && a < cw as i64 {
                        relax(k, b as usize * cw + a as usize, &mut seed, &mut other);
                    }
                }
            }
        }
        for y in (0..ch).rev() {
            for x in (0..cw).rev() {
                let k = y * cw + x;
                for (dx, dy) in [(1i64, 0i64), (1, 1), (0, 1), (-1, 1)] {
                    let (a, b) = (x as i64 + dx, y as i64 + dy);
                    if a >= 0 && a < cw as i64 && b < ch as i64 {
                        relax(k, b as usize * cw + a as usize, &mut seed, &mut other);
                    }
                }
            }
        }
        // From the cell's centre to the boundary's edge, over the ramp.
        let near = (0..n)
            .filter(|&k| seed[k].0 != i32::MIN && !edges[k] && plan.label[k] != NONE)
            .filter_map(|k| {
                let own = (0.5 + ((d2(k, seed[k]) as f32).sqrt() + 0.5) / ramp).min(1.0);
                (own < 1.0).then_some((k as u32, (own, other[k])))
            })
            .collect();
        Weights { cw, label: plan.label.clone(), near, ramp: true }
    }

    /// Whether the blend is a ramp (else each pixel takes its cell's image).
    pub fn blends(&self) -> bool {
        self.ramp
    }

    /// Image `i`'s weight in cell (x, y).
    pub fn weight(&self, x: usize, y: usize, i: u16) -> f32 {
        let k = y * self.cw + x;
        let l = self.label[k];
        if l == NONE {
            return 0.0;
        }
        let (own, other) = self.near.get(&(k as u32)).copied().unwrap_or((1.0, NONE));
        if i == l {
            own
        } else if i == other {
            1.0 - own
        } else {
            0.0
        }
    }

    /// The images with a weight in cell (x, y): its own and the one across.
    pub fn images(&self, x: usize, y: usize) -> [u16; 2] {
        let k = y * self.cw + x;
        let other = self.near.get(&(k as u32)).map_or(NONE, |&(_, o)| o);
        [self.label[k], other]
    }
}
