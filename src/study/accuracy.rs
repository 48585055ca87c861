//! How far `A + c` is from `T`: per-pixel distance in scan pixels over an
//! output grid, summarised as Beloshapkin and Chibunichev & Sonyushkin
//! publish it (mean abs, RMS, max, share of pixels under 0.1 / 0.25 / 0.5
//! / 1 px), with the time the GCM took.

pub use crate::gcm::self_check::{Acc, ErrorStats};
use crate::gcm::{Gcm, GcmStats};
use crate::transform::Mapped;
use rayon::prelude::*;
use std::time::{Duration, Instant};

/// The result of one evaluation.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Evaluation {
    pub errors: ErrorStats,
    pub gcm: GcmStats,
    /// Wall time to prepare the GCM (nodes, checks) for all rows.
    pub prepare: Duration,
    /// Wall time to fill all rows (every row, not only the sampled ones).
    pub fill: Duration,
}

#[cfg(any(test, feature = "internals"))]
/// Compares `A + c` with `T` on every `step`-th row and column. `error_map`,
/// when given, receives the per-pixel error of the sampled pixels (NaN
/// elsewhere), row-major over the sampled grid ⌈W/step⌉ × ⌈H/step⌉.
pub fn evaluate(gcm: &Gcm<'_>, step: u32, error_map: Option<&mut Vec<f32>>) -> Evaluation {
    evaluate_where(gcm, step, None, None, error_map)
}

/// As `evaluate`, counting only pixels whose terrain slope (from the DEM's
/// gradient) is at most `max_slope_deg` when given — the thesis judges
/// mountains "wherever the slope is below 35°".
/// `scan`: count only the pixels that see a scan of that many columns and
/// rows (the others are nodata in an orthophoto).
pub fn evaluate_where(gcm: &Gcm<'_>, step: u32, max_slope_deg: Option<f64>, scan: Option<(u32, u32)>, mut error_map: Option<&mut Vec<f32>>) -> Evaluation {
    let max_tan = max_slope_deg.map(|d| d.to_radians().tan());
    let grid = gcm.t.grid;
    let band = 256u32;
    let bands: Vec<u32> = (0..grid.height.div_ceil(band)).collect();
    let sw = grid.width.div_ceil(step) as usize;
    let sh = grid.height.div_ceil(step) as usize;
    if let Some(m) = error_map.as_deref_mut() {
        m.clear();
        m.resize(sw * sh, f32::NAN);
    }
    // Timing pass: prepare and fill every row, as rectify would.
    let t0 = Instant::now();
    let prepared: Vec<_> = bands.par_iter().map(|&b| gcm.prepare(b * band, ((b + 1) * band).min(grid.height))).collect();
    let prepare = t0.elapsed();
    let t1 = Instant::now();
    let exact_pixels: u64 = prepared
        .par_iter()
        .zip(&bands)
        .map(|(g, &b)| {
            let mut cols = vec![0.0; grid.width as usize];
            let mut rows = vec![0.0; grid.width as usize];
            let mut miss = None;
            (b * band..((b + 1) * band).min(grid.height)).map(|y| gcm.fill_row(g, y, 0, &mut cols, &mut rows, &mut miss)).sum::<u64>()
        })
        .sum();
    let fill = t1.elapsed();
    let mut stats = GcmStats { exact_pixels, ..Default::default() };
    for g in &prepared {
        stats.add(&g.stats);
    }
    // Error pass on the sampled pixels (their errors kept only for a map).
    let want_map = error_map.is_some();
    let per_band: Vec<(Acc, Vec<(usize, f32)>)> = prepared
        .par_iter()
        .zip(&bands)
        .map(|(g, &b)| {
            let mut acc = Acc::default();
            let mut map = Vec::new();
            let mut cols = vec![0.0; grid.width as usize];
            let mut rows = vec![0.0; grid.width as usize];
            let mut miss = None;
            for y in (b * band..((b + 1) * band).min(grid.height)).filter(|y| y % step == 0) {
                gcm.fill_row(g, y, 0, &mut cols, &mut rows, &mut miss);
                for x in (0..grid.width).step_by(step as usize) {
                    if let Some(t) = max_tan {
                        let (gx, gy) = gcm.t.ground(x as f64 + 0.5, y as f64 + 0.5);
                        match gcm.t.dem.height_gradient(gx, gy) {
                            Some((_, dx, dy)) if dx.hypot(dy) <= t => {}
                            _ => continue,
                        }
                    }
                    if let Mapped::Px(c, r) = gcm.t.exact(x as f64 + 0.5, y as f64 + 0.5) {
                        let (ac, ar) = (cols[x as usize], rows[x as usize]);
                        if ac.is_nan() || scan.is_some_and(|(w, h)| !(c >= 0.0 && r >= 0.0 && c <= w as f64 && r <= h as f64)) {
                            continue;
                        }
                        let e = (c - ac).hypot(r - ar);
                        acc.push(e, x, y);
                        if want_map {
                            map.push(((y / step) as usize * sw + (x / step) as usize, e as f32));
                        }
                    }
                }
            }
            (acc, map)
        })
        .collect();
    let mut acc = Acc::default();
    for (a, map) in per_band {
        acc = acc.merge(a);
        if let Some(m) = error_map.as_deref_mut() {
            for (i, e) in map {
                m[i] = e;
            }
        }
    }
    Evaluation { errors: ErrorStats::of(&acc, step), gcm: stats, prepare, fill }
}

/// A ground point with its exact scan position (synth's checkpoints.csv).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Checkpoint {
    pub id: u32,
    pub ground: [f64; 3],
    /// Scan (column, row), continuous.
    pub scan: [f64; 2],
}

/// Reads `id,X,Y,Z,col,row` with a header line.
pub fn read_checkpoints(path: &std::path::Path) -> crate::Result<Vec<Checkpoint>> {
    let text = crate::io::bounded_read::read_text_bounded(path, "a list of checkpoints", crate::io::bounded_read::LIST)?;
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        if line.trim().is_empty() {
            continue;
        }
        let v: Vec<f64> = line
            .split(',')
            .map(|s| s.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| crate::Error::format(path, format!("line {}: not six numbers", n + 1)))?;
        if v.len() != 6 {
            return Err(crate::Error::format(path, format!("line {}: expected id,X,Y,Z,col,row", n + 1)));
        }
        out.push(Checkpoint { id: v[0] as u32, ground: [v[1], v[2], v[3]], scan: [v[4], v[5]] });
    }
    Ok(out)
}

/// Thesis Table 2 for synthetic scenes: where each checkpoint's true scan
/// point appears in the orthophoto (the inverse of `A + c`, linearised
/// between the four surrounding pixel centres) minus where it should be.
/// Returns per-checkpoint (dx, dy) in output pixels (east, south).
pub fn checkpoint_offsets(gcm: &Gcm<'_>, cps: &[Checkpoint]) -> Vec<(u32, [f64; 2])> {
    let grid = gcm.t.grid;
    let mut out = Vec::new();
    for cp in cps {
        let (u, v) = grid.pixel(cp.ground[0], cp.ground[1]);
        let (x0, y0) = ((u - 0.5).floor(), (v - 0.5).floor());
        if x0 < 0.0 || y0 < 0.0 || x0 + 2.0 > grid.width as f64 || y0 + 2.0 > grid.height as f64 {
            continue;
        }
        let (x0, y0) = (x0 as u32, y0 as u32);
        let band = gcm.prepare(y0, y0 + 2);
        let mut c = [[0.0f64; 2]; 2];
        let mut r = [[0.0f64; 2]; 2];
        let mut miss = None;
        for dy in 0..2 {
            gcm.fill_row(&band, y0 + dy, x0, &mut c[dy as usize], &mut r[dy as usize], &mut miss);
        }
        if c.iter().flatten().chain(r.iter().flatten()).any(|v| v.is_nan()) {
            continue;
        }
        let (fx, fy) = (u - 0.5 - x0 as f64, v - 0.5 - y0 as f64);
        let lerp = |m: &[[f64; 2]; 2]| {
            let top = m[0][0] + fx * (m[0][1] - m[0][0]);
            let bot = m[1][0] + fx * (m[1][1] - m[1][0]);
            top + fy * (bot - top)
        };
        let mapped = [lerp(&c), lerp(&r)];
        // Jacobian d(scan)/d(output) from the four centres.
        let j = nalgebra::Matrix2::new(
            (c[0][1] - c[0][0] + c[1][1] - c[1][0]) / 2.0,
            (c[1][0] - c[0][0] + c[1][1] - c[0][1]) / 2.0,
            (r[0][1] - r[0][0] + r[1][1] - r[1][0]) / 2.0,
            (r[1][0] - r[0][0] + r[1][1] - r[0][1]) / 2.0,
        );
        let Some(ji) = j.try_inverse() else { continue };
        // The true scan point sits at output position (u, v) + J⁻¹(true − mapped);
        // the orthophoto shows it there, so the error is that offset.
        let d = ji * nalgebra::Vector2::new(cp.scan[0] - mapped[0], cp.scan[1] - mapped[1]);
        out.push((cp.id, [d.x, d.y]));
    }
    out
}
