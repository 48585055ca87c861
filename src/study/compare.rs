//! Comparing two rasters on the same grid (an orthophoto and its truth):
//! mean absolute difference over pixels valid in both, and the geometric
//! offset between them measured by cross-correlation in windows.

use crate::error::{Error, Result};
use crate::io::source::{SampleType, SourceImage, Window};
use std::path::Path;

/// A whole raster as grey f32 (band mean), with validity (non-nodata).
pub struct Grey {
    pub width: usize,
    // Read by the project's tests through `read_grey`.
    #[cfg_attr(not(feature = "internals"), allow(dead_code))]
    pub height: usize,
    pub v: Vec<f32>,
    pub valid: Vec<bool>,
    #[cfg_attr(not(feature = "internals"), allow(dead_code))]
    pub georef: Option<crate::io::geotiff::GeoRef>,
}

#[cfg(any(test, feature = "internals"))]
/// Reads a raster (up to ~200 Mpx) as grey values; pixels whose every band
/// equals `nodata` are invalid.
pub fn read_grey(path: &Path, nodata: f64) -> Result<Grey> {
    let src = SourceImage::open(path, 64 << 20)?;
    let info = &src.info;
    if info.width as u64 * info.height as u64 > 200_000_000 {
        return Err(Error::limits(path, "too large to compare in memory"));
    }
    grey_rows(&src, 0, info.height, nodata)
}

/// Rows `[y0, y0 + rows)` of `src` as grey values (see [`read_grey`]).
fn grey_rows(src: &SourceImage, y0: u32, rows: u32, nodata: f64) -> Result<Grey> {
    let info = &src.info;
    let mut win = Window::default();
    src.read_window(0, y0, info.width, rows, &mut win)?;
    let b = info.bands as usize;
    let colour = if info.has_alpha { b - 1 } else { b };
    let n = info.width as usize * rows as usize;
    let mut v = vec![0f32; n];
    let mut valid = vec![false; n];
    let bytes = win.bytes();
    for i in 0..n {
        let s = |k: usize| -> f32 {
            let j = i * b + k;
            match info.sample {
                SampleType::U8 => bytes[j] as f32,
                SampleType::U16 => u16::from_ne_bytes([bytes[2 * j], bytes[2 * j + 1]]) as f32,
                SampleType::F32 => f32::from_ne_bytes(bytes[4 * j..4 * j + 4].try_into().expect("4 bytes")),
            }
        };
        let sum: f32 = (0..colour).map(s).sum();
        v[i] = sum / colour as f32;
        valid[i] = if info.has_alpha { s(b - 1) > 0.0 } else { (0..colour).any(|k| s(k) as f64 != nodata) };
    }
    Ok(Grey { width: info.width as usize, height: rows as usize, v, valid, georef: info.georef.clone() })
}

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Comparison {
    pub pixels: u64,
    pub mean_abs_diff: f64,
    /// Offsets (pixels) found by cross-correlation in windows with texture.
    pub windows: usize,
    pub mean_shift: f64,
    /// 95th percentile of the window offsets.
    pub p95_shift: f64,
    pub max_shift: f64,
    pub mean_shift_xy: [f64; 2],
}

/// Half the side of the correlation's search, in pixels.
const SEARCH: usize = 3;

#[cfg(any(test, feature = "internals"))]
/// Compares `a` (measured) with `b` (reference) on the same grid.
pub fn compare(a: &Grey, b: &Grey, window: usize) -> Comparison {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let mut t = Tally::default();
    t.add_differences(a, b, 0..a.height);
    let mut y = 0;
    while y + window + 2 * SEARCH <= a.height {
        t.add_windows(a, b, y, window);
        y += window;
    }
    t.finish()
}

/// [`compare`] of two files on the same grid, read a band of rows at a
/// time (a window's rows and the search around them): the same figures in a
/// few MB, where reading both whole took about 1 GB for 8190² RGB.
pub fn compare_files(a: &Path, b: &Path, nodata: f64, window: usize) -> Result<Comparison> {
    // Two rows of 512-px tiles of 8192 RGB pixels each: a band of rows
    // crossing from one row of tiles to the next decodes each tile once.
    const CACHE: usize = 2 * 512 * 8192 * 3;
    let (sa, sb) = (SourceImage::open(a, CACHE)?, SourceImage::open(b, CACHE)?);
    let (w, h) = (sa.info.width, sa.info.height);
    if (sb.info.width, sb.info.height) != (w, h) {
        return Err(Error::format(b, format!("{}×{} pixels, not the {w}×{h} of {}", sb.info.width, sb.info.height, a.display())));
    }
    let mut t = Tally::default();
    let step = window.max(1) as u32;
    let mut y = 0;
    while y < h {
        let rows = (step + 2 * SEARCH as u32).min(h - y);
        let (ga, gb) = (grey_rows(&sa, y, rows, nodata)?, grey_rows(&sb, y, rows, nodata)?);
        t.add_differences(&ga, &gb, 0..(step.min(h - y)) as usize);
        if (y + step + 2 * SEARCH as u32) <= h {
            t.add_windows(&ga, &gb, 0, window);
        }
        y += step;
    }
    Ok(t.finish())
}

/// What a comparison has summed so far.
#[derive(Default)]
struct Tally {
    pixels: u64,
    sum: f64,
    shifts: Vec<[f64; 2]>,
}

impl Tally {
    /// The absolute differences of `rows` where both have a value.
    fn add_differences(&mut self, a: &Grey, b: &Grey, rows: std::ops::Range<usize>) {
        for i in rows.start * a.width..rows.end * a.width {
            if a.valid[i] && b.valid[i] {
                self.pixels += 1;
                self.sum += (a.v[i] - b.v[i]).abs() as f64;
            }
        }
    }

    /// The offsets in the row of windows whose search starts at row `y`.
    fn add_windows(&mut self, a: &Grey, b: &Grey, y: usize, window: usize) {
        let r = SEARCH;
        let mut x = 0;
        while x + window + 2 * r <= a.width {
            if let Some(s) = window_shift(a, b, x + r, y + r, window, r as i64) {
                self.shifts.push(s);
            }
            x += window;
        }
    }

    fn finish(self) -> Comparison {
        let shifts = self.shifts;
        let mut mags: Vec<f64> = shifts.iter().map(|s: &[f64; 2]| s[0].hypot(s[1])).collect();
        mags.sort_by(f64::total_cmp);
        let p95 = mags.get(((mags.len() as f64 * 0.95) as usize).min(mags.len().saturating_sub(1))).copied().unwrap_or(0.0);
        let m = mags.len().max(1) as f64;
        Comparison {
            pixels: self.pixels,
            mean_abs_diff: self.sum / self.pixels.max(1) as f64,
            windows: shifts.len(),
            mean_shift: mags.iter().sum::<f64>() / m,
            p95_shift: p95,
            max_shift: mags.iter().copied().fold(0.0, f64::max),
            mean_shift_xy: [shifts.iter().map(|s| s[0]).sum::<f64>() / m, shifts.iter().map(|s| s[1]).sum::<f64>() / m],
        }
    }
}

/// Sub-pixel shift of `a` relative to `b` in one window: normalised
/// cross-correlation over integer shifts ±r, refined by a parabola through
/// the peak and its neighbours. `None` for windows with little texture or
/// invalid pixels.
fn window_shift(a: &Grey, b: &Grey, x0: usize, y0: usize, w: usize, r: i64) -> Option<[f64; 2]> {
    let idx = |x: usize, y: usize| y * a.width + x;
    for y in y0 - r as usize..y0 + w + r as usize {
        for x in x0 - r as usize..x0 + w + r as usize {
            if !a.valid[idx(x, y)] || !b.valid[idx(x, y)] {
                return None;
            }
        }
    }
    let stats = |img: &Grey, dx: i64, dy: i64| {
        let (mut s, mut s2) = (0f64, 0f64);
        for y in 0..w {
            for x in 0..w {
                let v = img.v[idx((x0 as i64 + x as i64 + dx) as usize, (y0 as i64 + y as i64 + dy) as usize)] as f64;
                s += v;
                s2 += v * v;
            }
        }
        let n = (w * w) as f64;
        (s / n, (s2 / n - (s / n) * (s / n)).max(0.0).sqrt())
    };
    let (mb, sb) = stats(b, 0, 0);
    if sb < 4.0 {
        return None;
    }
    let size = (2 * r + 1) as usize;
    let mut ncc = vec![0f64; size * size];
    for dy in -r..=r {
        for dx in -r..=r {
            let (ma, sa) = stats(a, dx, dy);
            if sa == 0.0 {
                return None;
            }
            let mut s = 0f64;
            for y in 0..w {
                for x in 0..w {
                    let va = a.v[idx((x0 as i64 + x as i64 + dx) as usize, (y0 as i64 + y as i64 + dy) as usize)] as f64;
                    let vb = b.v[idx(x0 + x, y0 + y)] as f64;
                    s += (va - ma) * (vb - mb);
                }
            }
            ncc[((dy + r) as usize) * size + (dx + r) as usize] = s / ((w * w) as f64 * sa * sb);
        }
    }
    let (k, _) = ncc.iter().enumerate().fold((0, f64::MIN), |acc, (k, &v)| if v > acc.1 { (k, v) } else { acc });
    let (px, py) = ((k % size) as i64, (k / size) as i64);
    if px == 0 || py == 0 || px == 2 * r || py == 2 * r {
        return None;
    }
    let at = |x: i64, y: i64| ncc[y as usize * size + x as usize];
    let para = |m: f64, c: f64, p: f64| {
        let d = m - 2.0 * c + p;
        if d.abs() < 1e-12 {
            0.0
        } else {
            0.5 * (m - p) / d
        }
    };
    let sx = (px - r) as f64 + para(at(px - 1, py), at(px, py), at(px + 1, py));
    let sy = (py - r) as f64 + para(at(px, py - 1), at(px, py), at(px, py + 1));
    // `a` content at (x + s) equals `b` at x: `a` is displaced by +s.
    Some([sx, sy])
}
