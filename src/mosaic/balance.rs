//! Radiometric balancing: per image and band a gain and an offset, solved
//! by least squares from the overlaps' statistics on the plan's cells, so
//! that overlapping images agree in mean (and, with offsets, in spread),
//! anchored so that the block keeps its overall mean and spread.

use super::plan::Plan;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Balance {
    None,
    Gain,
    GainOffset,
}

impl crate::options::Choice for Balance {
    const NAMES: &'static [&'static str] = &["none", "gain", "gain-offset"];
    fn from_name(name: &str) -> Option<Self> {
        [Balance::None, Balance::Gain, Balance::GainOffset].into_iter().zip(Self::NAMES).find(|(_, n)| **n == name).map(|(b, _)| b)
    }
}

/// One image's correction: `v' = gain · v + offset`, per band.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct Correction {
    pub gain: Vec<f64>,
    pub offset: Vec<f64>,
}

impl Correction {
    pub fn identity(bands: usize) -> Correction {
        Correction { gain: vec![1.0; bands], offset: vec![0.0; bands] }
    }

    pub fn is_identity(&self) -> bool {
        self.gain.iter().all(|&g| g == 1.0) && self.offset.iter().all(|&o| o == 0.0)
    }
}

/// Sums over the cells two images both see, per band.
#[derive(Clone, Default)]
struct Sums {
    n: f64,
    a: f64,
    b: f64,
    aa: f64,
    bb: f64,
}

impl Sums {
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

/// The corrections of `mode` for every image of the plan.
pub fn solve(plan: &Plan, mode: Balance) -> Vec<Correction> {
    let nb = plan.images.first().map_or(1, |i| i.bands as usize);
    let n = plan.images.len();
    let mut out: Vec<Correction> = (0..n).map(|_| Correction::identity(nb)).collect();
    if mode == Balance::None || n < 2 {
        return out;
    }
    // Each pair's sums, per band.
    let mut pairs: Vec<(usize, usize, Vec<Sums>)> = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (&plan.images[i], &plan.images[j]);
            let x0 = a.cells[0].max(b.cells[0]);
            let x1 = a.cells[2].min(b.cells[2]);
            let y0 = a.cells[1].max(b.cells[1]);
            let y1 = a.cells[3].min(b.cells[3]);
            let mut sums = vec![Sums::default(); nb];
            for y in y0..y1 {
                for x in x0..x1 {
                    if let (Some(va), Some(vb)) = (a.value(x, y), b.value(x, y)) {
                        for (s, (&p, &q)) in sums.iter_mut().zip(va.iter().zip(vb)) {
                            let (p, q) = (p as f64, q as f64);
                            s.n += 1.0;
                            s.a += p;
                            s.b += q;
                            s.aa += p * p;
                            s.bb += q * q;
                        }
                    }
                }
            }
            if sums[0].n >= MIN_CELLS {
                pairs.push((i, j, sums));
            }
        }
    }
    if pairs.is_empty() {
        return out;
    }
    let offsets = mode == Balance::GainOffset;
    let per = if offsets { 2 } else { 1 };
    for band in 0..nb {
        // Values in units of the block's mean level, so that gains and
        // offsets weigh alike.
        let level = pairs.iter().map(|(_, _, s)| s[band].a + s[band].b).sum::<f64>() / pairs.iter().map(|(_, _, s)| 2.0 * s[band].n).sum::<f64>();
        let scale = if level.abs() > 1e-12 { level.abs() } else { 1.0 };
        let total: f64 = pairs.iter().map(|(_, _, s)| s[band].n).sum();
        let mut ata = DMatrix::<f64>::zeros(per * n, per * n);
        let mut atb = DVector::<f64>::zeros(per * n);
        let mut add = |row: &[(usize, f64)], rhs: f64, w: f64| {
            for &(p, u) in row {
                atb[p] += w * u * rhs;
                for &(q, v) in row {
                    ata[(p, q)] += w * u * v;
                }
            }
        };
        for (i, j, s) in &pairs {
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
        let Some(x) = ata.cholesky().map(|c| c.solve(&atb)) else { continue };
        let (mut g, mut o): (Vec<f64>, Vec<f64>) = (0..n).map(|i| (x[per * i], if offsets { x[2 * i + 1] * scale } else { 0.0 })).unzip();
        anchor(plan, band, offsets, &mut g, &mut o);
        for i in 0..n {
            out[i].gain[band] = g[i];
            out[i].offset[band] = o[i];
        }
    }
    out
}

/// Keeps the block's mean and spread (with offsets; its mean alone
/// without) on the cells each image is taken from: one common gain and
/// offset over all images' corrections.
fn anchor(plan: &Plan, band: usize, offsets: bool, g: &mut [f64], o: &mut [f64]) {
    let (mut n, mut s, mut ss, mut c, mut cc) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for y in 0..plan.ch {
        for x in 0..plan.cw {
            let l = plan.label_at(x, y);
            let Some(v) = plan.images.get(l as usize).and_then(|im| im.value(x, y)) else { continue };
            let v = v[band] as f64;
            let w = g[l as usize] * v + o[l as usize];
            n += 1.0;
            s += v;
            ss += v * v;
            c += w;
            cc += w * w;
        }
    }
    if n < 2.0 {
        return;
    }
    let (m0, m1) = (s / n, c / n);
    let (sd0, sd1) = ((ss / n - m0 * m0).max(0.0).sqrt(), (cc / n - m1 * m1).max(0.0).sqrt());
    if !offsets {
        let k = if m1.abs() > 1e-12 { m0 / m1 } else { 1.0 };
        g.iter_mut().for_each(|g| *g *= k);
        return;
    }
    let k = if sd1 > 1e-12 { sd0 / sd1 } else { 1.0 };
    for (g, o) in g.iter_mut().zip(o.iter_mut()) {
        *g *= k;
        *o = k * (*o - m1) + m0;
    }
}
