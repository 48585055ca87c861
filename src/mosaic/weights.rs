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
    /// The cells whose own image weighs under 1 (within the ramp of a
    /// boundary, off height edges): that weight, and the image across.
    near: HashMap<u32, (f32, u16)>,
    /// Whether the blend is a ramp at all.
    ramp: bool,
}

/// No boundary cell found yet.
const FAR: u32 = u32::MAX;

impl Weights {
    pub fn new(plan: &Plan, blend_px: f64, edges: &[bool]) -> Weights {
        let (cw, ch) = (plan.cw, plan.ch);
        let n = cw * ch;
        // Ramp width, cells (0: no blend).
        let ramp = (blend_px / plan.cell as f64) as f32;
        if ramp <= 0.0 {
            return Weights { cw, near: HashMap::default(), ramp: false };
        }
        // The image across a boundary cell (NONE: the cell is no boundary).
        let across = |k: usize| -> u16 {
            let (x, y) = (k % cw, k / cw);
            let l = plan.label[k];
            if l == NONE {
                return NONE;
            }
            [(x.wrapping_sub(1), y), (x + 1, y), (x, y.wrapping_sub(1)), (x, y + 1)]
                .into_iter()
                .filter(|&(a, b)| a < cw && b < ch)
                .map(|(a, b)| plan.label_at(a, b))
                .find(|&m| m != NONE && m != l)
                .unwrap_or(NONE)
        };
        // Each cell's nearest boundary cell of its image, as an index (the
        // image across is that cell's): 4 bytes a cell while it is made.
        let mut seed: Vec<u32> = (0..n).map(|k| if across(k) != NONE { k as u32 } else { FAR }).collect();
        let d2 = |k: usize, s: u32| {
            if s == FAR {
                return i64::MAX;
            }
            let (x, y) = ((k % cw) as i64, (k / cw) as i64);
            let (sx, sy) = ((s as usize % cw) as i64, (s as usize / cw) as i64);
            (x - sx).pow(2) + (y - sy).pow(2)
        };
        let relax = |k: usize, n: usize, seed: &mut Vec<u32>| {
            if plan.label[n] == plan.label[k] && d2(k, seed[n]) < d2(k, seed[k]) {
                seed[k] = seed[n];
            }
        };
        for y in 0..ch {
            for x in 0..cw {
                let k = y * cw + x;
                for (dx, dy) in [(-1i64, 0i64), (-1, -1), (0, -1), (1, -1)] {
                    let (a, b) = (x as i64 + dx, y as i64 + dy);
                    if a >= 0 && b >= 0 && a < cw as i64 {
                        relax(k, b as usize * cw + a as usize, &mut seed);
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
                        relax(k, b as usize * cw + a as usize, &mut seed);
                    }
                }
            }
        }
        // From the cell's centre to the boundary's edge, over the ramp.
        let near = (0..n)
            .filter(|&k| seed[k] != FAR && !edges[k] && plan.label[k] != NONE)
            .filter_map(|k| {
                let own = (0.5 + ((d2(k, seed[k]) as f32).sqrt() + 0.5) / ramp).min(1.0);
                (own < 1.0).then(|| (k as u32, (own, across(seed[k] as usize))))
            })
            .collect();
        Weights { cw, near, ramp: true }
    }

    /// The bytes it holds: a hash table's entry and control byte a cell
    /// within a ramp.
    pub fn bytes(&self) -> u64 {
        (self.near.capacity() * (std::mem::size_of::<(u32, (f32, u16))>() + 1)) as u64
    }

    /// Whether the blend is a ramp (else each pixel takes its cell's image).
    pub fn blends(&self) -> bool {
        self.ramp
    }

    /// Image `i`'s weight in cell (x, y), whose label (the plan's) is `l`.
    pub fn weight(&self, l: u16, x: usize, y: usize, i: u16) -> f32 {
        let k = y * self.cw + x;
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

    /// The images with a weight in cell (x, y), whose label is `l`: its
    /// own and the one across.
    pub fn images(&self, l: u16, x: usize, y: usize) -> [u16; 2] {
        let k = y * self.cw + x;
        let other = self.near.get(&(k as u32)).map_or(NONE, |&(_, o)| o);
        [l, other]
    }
}
