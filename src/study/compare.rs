//! Comparing two rasters on the same grid (an orthophoto and its truth):
//! mean absolute difference over pixels valid in both, and the geometric
//! offset between them measured by cross-correlation in windows.

use crate::error::{Error, Result};
use crate::io::source::{SampleType, SourceImage, Window};
use std::path::Path;

/// A whole raster as grey f32 (band mean), with validity (non-nodata).
pub struct Grey {
    pub width: usize,
    pub height: usize,
    pub v: Vec<f32>,
    pub valid: Vec<bool>,
    pub georef: Option<crate::io::geotiff::GeoRef>,
}

/// Reads a raster (up to ~200 Mpx) as grey values; pixels whose every band
/// equals `nodata` are invalid.
pub fn read_grey(path: &Path, nodata: f64) -> Result<Grey> {
    let src = SourceImage::open(path, 64 << 20)?;
    let info = &src.info;
    if info.width as u64 * info.height as u64 > 200_000_000 {
        return Err(Error::limits(path, "too large to compare in memory"));
    }
    let mut win = Window::default();
    src.read_window(0, 0, info.width, info.height, &mut win)?;
    let b = info.bands as usize;
    let colour = if info.has_alpha { b - 1 } else { b };
    let n = info.width as usize * info.height as usize;
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
    Ok(Grey { width: info.width as usize, height: info.height as usize, v, valid, georef: info.georef.clone() })
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

/// Compares `a` (measured) with `b` (reference) on the same grid.
pub fn compare(a: &Grey, b: &Grey, window: usize) -> Comparison {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let mut n = 0u64;
    let mut sum = 0f64;
    for i in 0..a.v.len() {
        if a.valid[i] && b.valid[i] {
            n += 1;
            sum += (a.v[i] - b.v[i]).abs() as f64;
        }
    }
    let mut shifts = Vec::new();
    let r = 3i64;
    let mut y = 0;
    while y + window + 2 * r as usize <= a.height {
        let mut x = 0;
        while x + window + 2 * r as usize <= a.width {
            if let Some(s) = window_shift(a, b, x + r as usize, y + r as usize, window, r) {
                shifts.push(s);
            }
            x += window;
        }
        y += window;
    }
    let mut mags: Vec<f64> = shifts.iter().map(|s: &[f64; 2]| s[0].hypot(s[1])).collect();
    mags.sort_by(f64::total_cmp);
    let p95 = mags.get(((mags.len() as f64 * 0.95) as usize).min(mags.len().saturating_sub(1))).copied().unwrap_or(0.0);
    let m = mags.len().max(1) as f64;
    Comparison {
        pixels: n,
        mean_abs_diff: sum / n.max(1) as f64,
        windows: shifts.len(),
        mean_shift: mags.iter().sum::<f64>() / m,
        p95_shift: p95,
        max_shift: mags.iter().copied().fold(0.0, f64::max),
        mean_shift_xy: [shifts.iter().map(|s| s[0]).sum::<f64>() / m, shifts.iter().map(|s| s[1]).sum::<f64>() / m],
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
