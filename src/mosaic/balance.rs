//! Radiometric balancing: per image and band a gain and an offset, solved
//! by least squares from the overlaps' statistics on the plan's cells, so
//! that overlapping images agree in mean (and, with offsets, in spread),
//! anchored so that the block keeps its overall mean and spread. With
//! `gain-offset-vignetting`, also a radial falloff in each image's frame
//! (terms in ρ² and ρ⁴, ρ the distance from the scan's centre over its
//! half-diagonal), solved cell by cell from the overlaps.

use super::normal::Normal;
use super::plan::Plan;
use crate::error::Result;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Balance {
    None,
    Gain,
    GainOffset,
    GainOffsetVignetting,
}

impl crate::options::Choice for Balance {
    const NAMES: &'static [&'static str] = &["none", "gain", "gain-offset", "gain-offset-vignetting"];
    fn from_name(name: &str) -> Option<Self> {
        [Balance::None, Balance::Gain, Balance::GainOffset, Balance::GainOffsetVignetting]
            .into_iter()
            .zip(Self::NAMES)
            .find(|(_, n)| **n == name)
            .map(|(b, _)| b)
    }
}

/// One image's correction, per band:
/// `v' = gain · v + radial[0] · v · ρ² + radial[1] · v · ρ⁴ + offset`
/// (ρ: the pixel's distance from the scan's centre over its
/// half-diagonal; `radial` empty without the vignetting term).
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct Correction {
    pub gain: Vec<f64>,
    pub offset: Vec<f64>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub radial: Vec<[f64; 2]>,
}

impl Correction {
    pub fn identity(bands: usize) -> Correction {
        Correction { gain: vec![1.0; bands], offset: vec![0.0; bands], radial: Vec::new() }
    }

    pub fn is_identity(&self) -> bool {
        self.gain.iter().all(|&g| g == 1.0) && self.offset.iter().all(|&o| o == 0.0) && !self.has_radial()
    }

    /// Does it depend on where in the scan a pixel was seen?
    pub fn has_radial(&self) -> bool {
        self.radial.iter().any(|r| r[0] != 0.0 || r[1] != 0.0)
    }

    /// Value `v` of `band` seen at `rho2` (ρ²) corrected.
    #[inline]
    pub fn apply(&self, band: usize, v: f64, rho2: f64) -> f64 {
        let mut out = self.gain[band] * v + self.offset[band];
        if let Some([b, e]) = self.radial.get(band) {
            out += v * rho2 * (b + e * rho2);
        }
        out
    }
}

/// Sums over the cells two images both see, per band.
#[derive(Clone, Copy, Debug, Default)]
pub struct Sums {
    n: f64,
    a: f64,
    b: f64,
    aa: f64,
    bb: f64,
    ab: f64,
}

/// Two images (by index) and their overlap's sums, per band.
pub type Pair = (usize, usize, Vec<Sums>);

impl Sums {
    /// The two images' correlation over the overlap's cells, where both
    /// vary by more than `least` (a flat overlap says nothing).
    pub fn correlation(&self, least: f64) -> Option<f64> {
        let ((ma, sa), (mb, sb)) = self.mean_sd();
        (sa > least && sb > least).then(|| ((self.ab / self.n - ma * mb) / (sa * sb)).clamp(-1.0, 1.0))
    }

    #[cfg(any(test, feature = "internals"))]
    pub fn cells(&self) -> f64 {
        self.n
    }

    fn mean_sd(&self) -> ((f64, f64), (f64, f64)) {
        let (ma, mb) = (self.a / self.n, self.b / self.n);
        let sd = |ss: f64, m: f64| (ss / self.n - m * m).max(0.0).sqrt();
        ((ma, sd(self.aa, ma)), (mb, sd(self.bb, mb)))
    }
}

/// Overlaps with fewer common cells than this say too little.
const MIN_CELLS: f64 = 16.0;
/// Weight of each image's pull towards no correction, against one overlap's.
const PRIOR: f64 = 0.01;

/// Every pair of images that overlap on enough cells, with the sums of
/// their thumbnails there (none without thumbnails: a plan read back).
pub fn overlaps(plan: &Plan) -> Result<Vec<Pair>> {
    let nb = plan.images.first().map_or(1, |i| i.bands as usize);
    let n = plan.images.len();
    let mut pairs: Vec<Pair> = Vec::new();
    for i in 0..n {
        let mut a = None;
        for j in i + 1..n {
            let (x0, x1, y0, y1) = common_box(plan, i, j);
            if x0 >= x1 || y0 >= y1 {
                continue;
            }
            let a = match &mut a {
                Some(a) => a,
                None => a.insert(plan.rows_of(i, 0..plan.ch)?),
            };
            let b = plan.rows_of(j, y0..y1)?;
            let mut sums = vec![Sums::default(); nb];
            for y in y0..y1 {
                for x in x0..x1 {
                    if let (Some(va), Some(vb)) = (a.value(x, y), b.value(x, y)) {
                        for (s, (p, q)) in sums.iter_mut().zip(va.bands().zip(vb.bands())) {
                            let (p, q) = (p as f64, q as f64);
                            s.n += 1.0;
                            s.a += p;
                            s.b += q;
                            s.aa += p * p;
                            s.bb += q * q;
                            s.ab += p * q;
                        }
                    }
                }
            }
            if sums[0].n >= MIN_CELLS {
                pairs.push((i, j, sums));
            }
        }
    }
    Ok(pairs)
}

/// The box both images' boxes hold: `(x0, x1, y0, y1)` (empty where
/// `x0 >= x1` or `y0 >= y1`).
fn common_box(plan: &Plan, i: usize, j: usize) -> (usize, usize, usize, usize) {
    let (a, b) = (plan.images[i].cells, plan.images[j].cells);
    (a[0].max(b[0]), a[2].min(b[2]), a[1].max(b[1]), a[3].min(b[3]))
}

/// The corrections of `mode` for every image of the plan, from its
/// `pairs` ([`overlaps`]).
pub fn solve(plan: &Plan, mode: Balance, pairs: &[Pair]) -> Result<Vec<Correction>> {
    let nb = plan.images.first().map_or(1, |i| i.bands as usize);
    let n = plan.images.len();
    let mut out: Vec<Correction> = (0..n).map(|_| Correction::identity(nb)).collect();
    if mode == Balance::None || n < 2 || pairs.is_empty() {
        return Ok(out);
    }
    if mode == Balance::GainOffsetVignetting {
        return solve_radial(plan, pairs, out);
    }
    let offsets = mode == Balance::GainOffset;
    let per = if offsets { 2 } else { 1 };
    for band in 0..nb {
        let (scale, total) = level_and_cells(pairs, band);
        let mut normal = Normal::new(per * n);
        let mut add = |row: &[(usize, f64)], rhs: f64, w: f64| normal.add(row, rhs, w);
        for (i, j, s) in pairs {
            let ((ma, sa), (mb, sb)) = s[band].mean_sd();
            let w = s[band].n / total;
            let (ma, sa, mb, sb) = (ma / scale, sa / scale, mb / scale, sb / scale);
            if offsets {
                add(&[(2 * i, ma), (2 * i + 1, 1.0), (2 * j, -mb), (2 * j + 1, -1.0)], 0.0, w);
                add(&[(2 * i, sa), (2 * j, -sb)], 0.0, w);
            } else {
                add(&[(*i, ma), (*j, -mb)], 0.0, w);
            }
        }
        let prior = PRIOR / n as f64;
        for i in 0..n {
            add(&[(per * i, 1.0)], 1.0, prior);
            if offsets {
                add(&[(2 * i + 1, 1.0)], 0.0, prior);
            }
        }
        let Some(x) = normal.solve() else { continue };
        let (g, o): (Vec<f64>, Vec<f64>) = (0..n).map(|i| (x[per * i], if offsets { x[2 * i + 1] * scale } else { 0.0 })).unzip();
        for i in 0..n {
            out[i].gain[band] = g[i];
            out[i].offset[band] = o[i];
        }
        anchor(plan, band, offsets, &mut out)?;
    }
    Ok(out)
}

/// The block's mean level of `band` over the overlaps (values are solved
/// in its units, so that gains and offsets weigh alike) and the overlaps'
/// cells in all.
fn level_and_cells(pairs: &[Pair], band: usize) -> (f64, f64) {
    let level = pairs.iter().map(|(_, _, s)| s[band].a + s[band].b).sum::<f64>() / pairs.iter().map(|(_, _, s)| 2.0 * s[band].n).sum::<f64>();
    let scale = if level.abs() > 1e-12 { level.abs() } else { 1.0 };
    (scale, pairs.iter().map(|(_, _, s)| s[band].n).sum())
}

/// Gains, offsets and radial terms from every cell two images both see:
/// each such cell asks that the two corrected values agree. Weakly pulled
/// towards no correction; anchored as [`solve`]'s.
fn solve_radial(plan: &Plan, pairs: &[Pair], mut out: Vec<Correction>) -> Result<Vec<Correction>> {
    let nb = out.first().map_or(1, |c| c.gain.len());
    let n = plan.images.len();
    const PER: usize = 4;
    for c in &mut out {
        c.radial = vec![[0.0; 2]; nb];
    }
    for band in 0..nb {
        let (scale, total) = level_and_cells(pairs, band);
        let mut normal = Normal::new(PER * n);
        let w = 1.0 / total;
        // Unknowns of image i: gain, ρ² term, ρ⁴ term, offset.
        let terms = |v: f64, rho: f32, sign: f64| {
            let r2 = f64::from(rho * rho);
            [sign * v, sign * v * r2, sign * v * r2 * r2, sign]
        };
        for (i, j, _) in pairs {
            let (x0, x1, y0, y1) = common_box(plan, *i, *j);
            let (a, b) = (plan.rows_of(*i, y0..y1)?, plan.rows_of(*j, y0..y1)?);
            // The pair's cells summed into its own block first (the
            // rows' right-hand sides are zero).
            let mut block = DMatrix::zeros(2 * PER, 2 * PER);
            for y in y0..y1 {
                for x in x0..x1 {
                    let (Some(va), Some(vb), Some(ra), Some(rb)) = (a.value(x, y), b.value(x, y), a.radius(x, y), b.radius(x, y)) else { continue };
                    let (ta, tb) = (terms(f64::from(va.band(band)) / scale, ra, 1.0), terms(f64::from(vb.band(band)) / scale, rb, -1.0));
                    let row: [f64; 2 * PER] = std::array::from_fn(|k| if k < PER { ta[k] } else { tb[k - PER] });
                    for p in 0..2 * PER {
                        for q in 0..2 * PER {
                            block[(p, q)] += w * row[p] * row[q];
                        }
                    }
                }
            }
            let at: [usize; 2 * PER] = std::array::from_fn(|k| if k < PER { PER * i + k } else { PER * j + k - PER });
            normal.add_block(&at, &block, &DVector::zeros(2 * PER));
        }
        let prior = PRIOR / n as f64;
        for i in 0..n {
            normal.add(&[(PER * i, 1.0)], 1.0, prior);
            for k in 1..PER {
                normal.add(&[(PER * i + k, 1.0)], 0.0, prior);
            }
        }
        let Some(x) = normal.solve() else { continue };
        for (i, c) in out.iter_mut().enumerate() {
            c.gain[band] = x[PER * i];
            c.radial[band] = [x[PER * i + 1], x[PER * i + 2]];
            c.offset[band] = x[PER * i + 3] * scale;
        }
        anchor(plan, band, true, &mut out)?;
    }
    Ok(out)
}

/// Keeps the block's mean and spread (with offsets; its mean alone
/// without) on the cells each image is taken from: one common gain and
/// offset over all images' corrections of `band`.
fn anchor(plan: &Plan, band: usize, offsets: bool, out: &mut [Correction]) -> Result<()> {
    let (mut n, mut s, mut ss, mut c, mut cc) = (0.0, 0.0, 0.0, 0.0, 0.0);
    // A band of cell rows at a time, with the boxes of the images there.
    const ROWS: usize = 64;
    for y0 in (0..plan.ch).step_by(ROWS) {
        let y1 = (y0 + ROWS).min(plan.ch);
        let held: Vec<Option<_>> = (0..plan.images.len())
            .map(|k| {
                let [_, b0, _, b1] = plan.images[k].cells;
                (b0 < y1 && b1 > y0).then(|| plan.rows_of(k, y0..y1)).transpose()
            })
            .collect::<Result<_>>()?;
        for y in y0..y1 {
            for x in 0..plan.cw {
                let l = plan.label_at(x, y) as usize;
                let Some(Some(im)) = held.get(l) else { continue };
                let Some(v) = im.value(x, y) else { continue };
                let v = v.band(band) as f64;
                let rho = im.radius(x, y).unwrap_or(0.0) as f64;
                let w = out[l].apply(band, v, rho * rho);
                n += 1.0;
                s += v;
                ss += v * v;
                c += w;
                cc += w * w;
            }
        }
    }
    if n < 2.0 {
        return Ok(());
    }
    let (m0, m1) = (s / n, c / n);
    let (sd0, sd1) = ((ss / n - m0 * m0).max(0.0).sqrt(), (cc / n - m1 * m1).max(0.0).sqrt());
    let k = match (offsets, m1.abs() > 1e-12, sd1 > 1e-12) {
        (false, true, _) => m0 / m1,
        (true, _, true) => sd0 / sd1,
        _ => 1.0,
    };
    for corr in out.iter_mut() {
        corr.gain[band] *= k;
        if let Some(r) = corr.radial.get_mut(band) {
            *r = [r[0] * k, r[1] * k];
        }
        if offsets {
            corr.offset[band] = k * (corr.offset[band] - m1) + m0;
        }
    }
    Ok(())
}
