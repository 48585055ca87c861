//! From the coarse place to the mark's centre (thesis §2.6): the pyramid's
//! levels reduced 5, 4, 3 and 2 times and the full resolution, each
//! searching a few pixels around the last level's answer with the template
//! rendered at its scale and the scan's turn; then the second template (the
//! mark's centre: its dot, its crossing) to a fraction of a pixel, re-rendered
//! at the fraction found until the correlation peak is centred.

use super::correlate::correlate;
use super::gray::Gray;
use super::shape::Shape;
use super::template::Template;
use crate::error::Result;
use crate::io::source::SourceImage;
use nalgebra::Matrix2;

/// A refined mark: its centre in scan pixels and the correlation of the
/// full template and of the second one there.
#[derive(Clone, Copy, Debug)]
pub struct Refined {
    pub at: [f64; 2],
    pub score: f32,
    pub centre_score: f32,
}

/// The levels below `coarse` (the thesis's 5, 4, 3, 2), then 1.
fn levels(coarse: u32) -> impl Iterator<Item = u32> {
    [5u32, 4, 3, 2, 1].into_iter().filter(move |&f| f < coarse || f == 1)
}

/// Refines a mark found at `start` on the level reduced `coarse` times,
/// whose own frame maps to scan pixels by `to_px`; `sign` +1 for a mark
/// lighter than the film, −1 darker. None when a level finds no peak.
pub fn refine(src: &SourceImage, shape: &Shape, to_px: &Matrix2<f64>, start: [f64; 2], coarse: u32, sign: f32) -> Result<Option<Refined>> {
    let mut at = start;
    let mut uncertain = 2.5 * coarse as f64;
    let mut score = 0.0f32;
    for f in levels(coarse) {
        let lin = to_px / f as f64;
        let Some(t) = Template::render(shape, &lin, shape.radius_mm, [0.0, 0.0]) else { return Ok(None) };
        let Some((p, r)) = best_near(src, &t, f, at, uncertain, sign)? else { return Ok(None) };
        at = p;
        score = r;
        uncertain = 1.5 * f as f64;
    }
    // The second template, to a fraction of a pixel.
    let Some((at, centre_score)) = centre(src, shape, to_px, at, sign)? else { return Ok(None) };
    Ok(Some(Refined { at, score, centre_score }))
}

/// The strongest correlation of `t` (at level `f`) whose mark centre lies
/// within `radius` scan px of `at`: the centre (parabola-refined) and r.
fn best_near(src: &SourceImage, t: &Template, f: u32, at: [f64; 2], radius: f64, sign: f32) -> Result<Option<([f64; 2], f32)>> {
    let reach = (t.half as f64 + 1.0) * f as f64 + radius + f as f64;
    let Some(gray) = read_around(src, at, reach, f)? else { return Ok(None) };
    let surface = correlate(&gray, t, (0, 0, gray.width, gray.height));
    // Places whose centre is within the radius (in level pixels).
    let lev = |v: f64, o: i64| (v - o as f64) / f as f64 - t.half as f64 - 0.5;
    let (ci, cj) = (lev(at[0], gray.x0), lev(at[1], gray.y0));
    let rl = radius / f as f64 + 0.5;
    let mut best: Option<(usize, usize, f32)> = None;
    for j in 0..surface.height {
        for i in 0..surface.width {
            if (i as f64 - ci).abs() > rl || (j as f64 - cj).abs() > rl {
                continue;
            }
            let r = sign * surface.r[j * surface.width + i];
            if best.is_none_or(|b| r > b.2) {
                best = Some((i, j, r));
            }
        }
    }
    let Some((i, j, r)) = best else { return Ok(None) };
    let p = surface.refine(super::correlate::Peak { i, j, r }, sign);
    Ok(Some((gray.to_scan(p[0] + t.half as f64 + 0.5, p[1] + t.half as f64 + 0.5), r)))
}

/// The mark's centre by its second template: the template's place is
/// kept whole and its drawing moved by fractions of a pixel, the
/// correlation's quadratic surface over the fractions fitted three times on
/// ever closer 3 × 3 grids; the fraction at its top is the centre's.
fn centre(src: &SourceImage, shape: &Shape, to_px: &Matrix2<f64>, at: [f64; 2], sign: f32) -> Result<Option<([f64; 2], f32)>> {
    let Some(probe) = Template::render(shape, to_px, shape.fine_radius_mm, [0.0, 0.0]) else { return Ok(None) };
    let half = probe.half as f64;
    let Some(gray) = read_around(src, at, half + 3.0, 1)? else { return Ok(None) };
    let ti = (at[0] - gray.x0 as f64 - half - 0.5).round();
    let tj = (at[1] - gray.y0 as f64 - half - 0.5).round();
    if ti < 0.0 || tj < 0.0 || ti as usize + probe.size > gray.width || tj as usize + probe.size > gray.height {
        return Ok(None);
    }
    let base = [at[0] - (gray.x0 as f64 + ti + half + 0.5), at[1] - (gray.y0 as f64 + tj + half + 0.5)];
    let r_at = |f: [f64; 2]| -> Option<f64> {
        let t = Template::render(shape, to_px, shape.fine_radius_mm, f)?;
        (t.size == probe.size).then(|| sign as f64 * correlation_at(&gray, &t, ti as usize, tj as usize))
    };
    let mut frac = base;
    let mut best = r_at(frac).unwrap_or(f64::MIN);
    for step in [0.3, 0.1, 0.03] {
        let mut grid = [[0.0; 3]; 3];
        for (b, row) in grid.iter_mut().enumerate() {
            for (a, v) in row.iter_mut().enumerate() {
                *v = r_at([frac[0] + (a as f64 - 1.0) * step, frac[1] + (b as f64 - 1.0) * step]).unwrap_or(f64::MIN);
            }
        }
        let (d, r) = quadratic_top(&grid);
        let next = [(frac[0] + d[0] * step).clamp(-1.0, 1.0), (frac[1] + d[1] * step).clamp(-1.0, 1.0)];
        let rn = r_at(next).unwrap_or(f64::MIN);
        if rn >= best || r > best {
            frac = next;
            best = rn.max(best);
        }
    }
    Ok(Some(([gray.x0 as f64 + ti + half + 0.5 + frac[0], gray.y0 as f64 + tj + half + 0.5 + frac[1]], best as f32)))
}

/// The top of the quadratic through a 3 × 3 grid of values (spacing 1,
/// centre 0), clamped to the grid; and the top's value.
fn quadratic_top(g: &[[f64; 3]; 3]) -> ([f64; 2], f64) {
    let v = |a: i32, b: i32| g[(b + 1) as usize][(a + 1) as usize];
    // Least-squares fit of c0 + c1 x + c2 y + c3 x² + c4 xy + c5 y².
    let c0 = (5.0 * v(0, 0) + 2.0 * (v(1, 0) + v(-1, 0) + v(0, 1) + v(0, -1)) - (v(1, 1) + v(-1, 1) + v(1, -1) + v(-1, -1))) / 9.0;
    let c1 = (v(1, -1) + v(1, 0) + v(1, 1) - v(-1, -1) - v(-1, 0) - v(-1, 1)) / 6.0;
    let c2 = (v(-1, 1) + v(0, 1) + v(1, 1) - v(-1, -1) - v(0, -1) - v(1, -1)) / 6.0;
    let col = |a: i32| v(a, -1) + v(a, 0) + v(a, 1);
    let row = |b: i32| v(-1, b) + v(0, b) + v(1, b);
    let c3 = (col(1) + col(-1) - 2.0 * col(0)) / 6.0;
    let c5 = (row(1) + row(-1) - 2.0 * row(0)) / 6.0;
    let c4 = (v(1, 1) + v(-1, -1) - v(1, -1) - v(-1, 1)) / 4.0;
    let det = 4.0 * c3 * c5 - c4 * c4;
    if !(c3 < 0.0 && det > 0.0) {
        // Not a top: the best grid point.
        let (mut bi, mut bv) = ([0.0, 0.0], f64::MIN);
        for b in -1..=1 {
            for a in -1..=1 {
                if v(a, b) > bv {
                    (bi, bv) = ([a as f64, b as f64], v(a, b));
                }
            }
        }
        return (bi, bv);
    }
    let x = ((-2.0 * c5 * c1 + c4 * c2) / det).clamp(-1.0, 1.0);
    let y = ((-2.0 * c3 * c2 + c4 * c1) / det).clamp(-1.0, 1.0);
    ([x, y], c0 + c1 * x + c2 * y + c3 * x * x + c4 * x * y + c5 * y * y)
}

/// The correlation of `t` with its top-left corner at (i, j), over the
/// scan's pixels only (a mark cut by the scan's edge: the padding left out).
fn correlation_at(g: &Gray, t: &Template, i: usize, j: usize) -> f64 {
    let [i0, j0, i1, j1] = g.inside;
    let (mut n, mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for b in 0..t.size {
        let y = j + b;
        if y < j0 || y >= j1 {
            continue;
        }
        for a in 0..t.size {
            let x = i + a;
            if x < i0 || x >= i1 {
                continue;
            }
            let (v, w) = (g.at(x, y) as f64, t.weights[b * t.size + a] as f64);
            n += 1.0;
            sx += v;
            sy += w;
            sxx += v * v;
            syy += w * w;
            sxy += v * w;
        }
    }
    let (vx, vy) = (sxx - sx * sx / n, syy - sy * sy / n);
    if n < 4.0 || vx <= 1e-12 || vy <= 1e-12 {
        return 0.0;
    }
    (sxy - sx * sy / n) / (vx * vy).sqrt()
}

/// The scan around `at` (±`reach` px) at level `f`, padded past its
/// edges; None when `at` is off the scan.
fn read_around(src: &SourceImage, at: [f64; 2], reach: f64, f: u32) -> Result<Option<Gray>> {
    let (w, h) = (src.info.width as f64, src.info.height as f64);
    if !(at[0] >= 0.0 && at[1] >= 0.0 && at[0] < w && at[1] < h) {
        return Ok(None);
    }
    let x0 = (at[0] - reach).floor() as i64;
    let y0 = (at[1] - reach).floor() as i64;
    let side = (2.0 * reach).ceil() as u32 + 1;
    Ok(Some(Gray::read_padded(src, (x0, y0, side, side), f)?))
}
