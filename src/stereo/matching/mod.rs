//! Dense matching of a tile of the epipolar pair: the disparity (left
//! column − right column) of each left pixel, found coarse to fine on an
//! image pyramid (the whole search range at the coarsest level, a few
//! pixels around the coarser answer below it), checked left against
//! right, and refined to a fraction of a pixel by the correlation
//! paraboloid of Nekrasov's thesis (§2.7).
//!
//! Two searches: `sgm`, semi-global matching of census costs along eight
//! paths (Hirschmüller), the default; and `ncc`, the thesis's own
//! correlation (a sequential-similarity search, accepted by a normalised
//! cross-correlation whose threshold falls with the window's size).

mod census;
mod ncc;
mod refine;
mod sgm;

use super::resample::Img;

/// The search at each level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Matcher {
    /// Semi-global matching (census, eight paths).
    Sgm,
    /// Sequential similarity search, accepted by normalised correlation.
    Ncc,
}

/// How matching is done.
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
pub struct MatchParams {
    pub matcher: Matcher,
    /// Side of the correlation window, pixels (odd).
    pub window: usize,
    /// Accept a match whose correlation is at least this (`None`: the
    /// window size's threshold, [`ncc_threshold`]).
    pub min_correlation: Option<f32>,
}

impl Default for MatchParams {
    fn default() -> Self {
        MatchParams { matcher: Matcher::Sgm, window: 9, min_correlation: None }
    }
}

/// The correlation a match of a `side` × `side` window must reach: the
/// coefficient a chance match of `n` uncorrelated samples passes ever more
/// rarely as `n` grows (its spread falls as 1/√n): `0.5 + 2.5/√n`, 0.86
/// for 7 × 7, 0.73 for 11 × 11, 0.67 for 15 × 15.
pub fn ncc_threshold(side: usize) -> f32 {
    0.5 + 2.5 / ((side * side) as f32).sqrt()
}

/// Disparities searched around the coarser level's answer, each side.
const RADIUS: i32 = 4;
/// The coarsest level holds at most this many disparities.
const COARSE_RANGE: f64 = 48.0;

/// The pyramid's levels below the full resolution for a tile of `w × h`
/// searched over `range` disparities: halvings until the range is at most
/// [`COARSE_RANGE`], while the tile stays 24 pixels or more; 6 at most.
pub fn levels(w: usize, h: usize, range: f64) -> u32 {
    let mut l = 0;
    while l < 6 && range / f64::from(1u32 << l) > COARSE_RANGE && (w.min(h) >> (l + 1)) >= 24 {
        l += 1;
    }
    l
}

/// A tile's matches.
pub struct Matches {
    /// Each left pixel's disparity, NaN where it has no match.
    pub disparity: Vec<f32>,
    /// The correlation of each match's windows.
    pub correlation: Vec<f32>,
    /// The disparity the coarser levels expected at each pixel (the
    /// middle of its last search): where the right image is there, the
    /// pixel was seen by both.
    pub expected: Vec<i32>,
}

/// The disparity of each pixel of `left` within `core` (`[x0, y0, x1,
/// y1)`, local; the rest is context) searching `right` over `[dmin,
/// dmax]`. Both windows' origins are multiples of `2^levels`, their rows
/// the same.
pub fn match_tile(left: &Img, right: &Img, dmin: f64, dmax: f64, p: &MatchParams, core: [usize; 4]) -> Matches {
    let nl = levels(left.w, left.h, dmax - dmin);
    let mut lp = vec![left.clone()];
    let mut rp = vec![right.clone()];
    for l in 0..nl as usize {
        lp.push(lp[l].halved());
        rp.push(rp[l].halved());
    }
    let f = f64::from(1u32 << nl);
    let (c0, c1) = ((dmin / f).floor() as i32 - 1, (dmax / f).ceil() as i32 + 1);
    let top = &lp[nl as usize];
    let mut lo = vec![c0; top.w * top.h];
    let mut n = (c1 - c0 + 1) as usize;
    let mut disp = Vec::new();
    for l in (0..=nl as usize).rev() {
        let (li, ri) = (&lp[l], &rp[l]);
        disp = match p.matcher {
            Matcher::Sgm => sgm::disparities(li, ri, &lo, n),
            Matcher::Ncc => ncc::disparities(li, ri, &lo, n, p.window, p.min_correlation.unwrap_or(ncc_threshold(p.window)) * if l > 0 { 0.8 } else { 1.0 }),
        };
        if l > 0 {
            let filled = fill_holes(&disp, li.w, li.h, 0.5 * (lo[0] as f32 + (lo[0] + n as i32 - 1) as f32));
            let finer = &lp[l - 1];
            // Each coarse pixel's median once, for the four finer ones it covers.
            let start: Vec<i32> = (0..li.w * li.h).map(|k| (2.0 * median3(&filled, li.w, li.h, k % li.w, k / li.w)).round() as i32 - RADIUS).collect();
            lo = (0..finer.w * finer.h).map(|k| start[((k / finer.w) / 2).min(li.h - 1) * li.w + ((k % finer.w) / 2).min(li.w - 1)]).collect();
            n = (2 * RADIUS + 1) as usize;
        }
    }
    let min_corr = match p.matcher {
        Matcher::Ncc => p.min_correlation.unwrap_or(ncc_threshold(p.window)),
        // SGM's answer stands on the paths' agreement; the correlation
        // only drops what matched nothing alike (flat or changed ground).
        Matcher::Sgm => p.min_correlation.unwrap_or(0.5),
    };
    let (mut disparity, mut correlation) = refine::subpixel(left, right, &mut disp, p.window, min_corr, core);
    drop_outliers(&mut disparity, &mut correlation, left.w, left.h, core);
    let half = (n / 2) as i32;
    Matches { disparity, correlation, expected: lo.iter().map(|l| l + half).collect() }
}

/// Disparities off their neighbourhood dropped: a match more than
/// [`OUTLIER_PX`] from the median of the matches in the 5 × 5 around it,
/// or with fewer than 6 of those 24 matched (a speckle). The gross errors
/// a DSM's gridding would otherwise have to find among its points.
fn drop_outliers(d: &mut [f32], corr: &mut [f32], w: usize, h: usize, [x0, y0, x1, y1]: [usize; 4]) {
    let src = d.to_vec();
    for y in y0..y1.min(h) {
        for x in x0..x1.min(w) {
            let p = y * w + x;
            let v = src[p];
            if v.is_nan() {
                continue;
            }
            // The median of the matches around (the m-th of n) lies within
            // OUTLIER_PX of v unless at least m + 1 of them lie that far
            // below, or n − m that far above: counted, not sorted.
            let (mut n, mut below, mut above) = (0usize, 0usize, 0usize);
            for yy in y.saturating_sub(2)..(y + 3).min(h) {
                for &e in &src[yy * w + x.saturating_sub(2)..yy * w + (x + 3).min(w)] {
                    if !e.is_nan() {
                        n += 1;
                        below += usize::from(v - e > OUTLIER_PX);
                        above += usize::from(v - e < -OUTLIER_PX);
                    }
                }
            }
            let m = n / 2;
            if !(n > 6 && below <= m && above < n - m) {
                d[p] = f32::NAN;
                corr[p] = f32::NAN;
            }
        }
    }
}

/// How far a match may lie from its neighbours' median, pixels.
const OUTLIER_PX: f32 = 2.0;

/// Holes filled along the row from the lower of the nearest disparities
/// on either side (the background's, where a hole is an occlusion), rows
/// without any from the nearest row that has them, all from `mid` where
/// nothing matched.
fn fill_holes(d: &[f32], w: usize, h: usize, mid: f32) -> Vec<f32> {
    let mut out = d.to_vec();
    let mut row_has = vec![false; h];
    for y in 0..h {
        let row = &mut out[y * w..(y + 1) * w];
        let mut left = vec![f32::NAN; w];
        let mut last = f32::NAN;
        for x in 0..w {
            if !row[x].is_nan() {
                last = row[x];
            }
            left[x] = last;
        }
        last = f32::NAN;
        for x in (0..w).rev() {
            if !row[x].is_nan() {
                last = row[x];
                row_has[y] = true;
                continue;
            }
            row[x] = match (left[x].is_nan(), last.is_nan()) {
                (false, false) => left[x].min(last),
                (false, true) => left[x],
                (true, false) => last,
                (true, true) => f32::NAN,
            };
        }
    }
    let Some(first) = row_has.iter().position(|&b| b) else { return vec![mid; w * h] };
    for y in 0..h {
        if !row_has[y] {
            // The nearest row with matches.
            let near = (0..h).filter(|&k| row_has[k]).min_by_key(|&k| k.abs_diff(y)).unwrap_or(first);
            let (a, b) = (near * w, y * w);
            for x in 0..w {
                out[b + x] = out[a + x];
            }
        }
    }
    out
}

/// The median of the 3 × 3 around `(x, y)` (fewer at the edges).
fn median3(d: &[f32], w: usize, h: usize, x: usize, y: usize) -> f32 {
    let mut v = [0f32; 9];
    let mut n = 0;
    for yy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
        for xx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
            v[n] = d[yy * w + xx];
            n += 1;
        }
    }
    let v = &mut v[..n];
    v.sort_by(f32::total_cmp);
    v[n / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A textured pair with a known disparity field: the match finds it
    /// to a tenth of a pixel wherever there is texture.
    #[test]
    fn finds_a_known_disparity_field() {
        let (w, h) = (192usize, 128usize);
        let tex = |x: f64, y: f64| -> f32 {
            let s = (x * 0.71).sin() * (y * 0.53).cos() + (x * 0.23 + y * 0.37).sin() + 0.5 * ((x * 1.3 - y * 0.9).sin());
            (100.0 + 40.0 * s) as f32
        };
        let truth = |x: f64, y: f64| 20.0 + 6.0 * (x / 60.0).sin() + 3.0 * (y / 40.0).cos();
        let left = Img { x0: 0, y0: 0, w, h, v: (0..w * h).map(|k| tex((k % w) as f64, (k / w) as f64)).collect() };
        // right(x) = left(x + d(x)): the ground at left column x is at right column x − d.
        let rx0 = -64i64;
        let rw = w + 64;
        let right = Img {
            x0: rx0,
            y0: 0,
            w: rw,
            h,
            v: (0..rw * h)
                .map(|k| {
                    let (xr, y) = ((k % rw) as i64 + rx0, (k / rw) as f64);
                    // Solve xl − d(xl) = xr by fixed point.
                    let mut xl = xr as f64 + 20.0;
                    for _ in 0..30 {
                        xl = xr as f64 + truth(xl, y);
                    }
                    tex(xl, y)
                })
                .collect(),
        };
        for m in [Matcher::Sgm, Matcher::Ncc] {
            let d = match_tile(&left, &right, 0.0, 40.0, &MatchParams { matcher: m, ..Default::default() }, [0, 0, w, h]).disparity;
            let (mut n, mut sq) = (0, 0.0);
            for y in 8..h - 8 {
                for x in 8..w - 8 {
                    let v = d[y * w + x];
                    if !v.is_nan() {
                        n += 1;
                        sq += (v as f64 - truth(x as f64, y as f64)).powi(2);
                    }
                }
            }
            let rms = (sq / n as f64).sqrt();
            let share = n as f64 / ((w - 16) * (h - 16)) as f64;
            assert!(share > 0.9 && rms < 0.1, "{m:?}: matched {share:.3}, rms {rms:.3} px");
        }
    }
}
