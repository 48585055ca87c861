//! A window of the epipolar grid filled from one scan: each grid pixel's
//! scan position exact at nodes every [`NODE_STEP`] pixels (the model
//! projects the node's ground point on the plane) and bilinear between
//! them, the scan read once for the window and sampled bilinearly, in grey.

use super::epipolar::EpipolarFrame;
use crate::camera::SensorModel;
use crate::error::Result;
use crate::io::format::SampleType;
use crate::io::source::{SourceImage, Window};

/// Grid pixels between exact nodes: the plane's image is a homography
/// (frames) or nearly one (RPC), whose curvature over 16 pixels moves a
/// position by well under a thousandth of a pixel.
pub const NODE_STEP: usize = 16;

/// Grey values on a window of a grid (the epipolar one, or one of its
/// pyramid's levels): `v[y·w + x]` at grid pixel `(x0 + x, y0 + y)`, NaN
/// where the scan has no image.
#[derive(Clone, Debug, Default)]
pub struct Img {
    pub x0: i64,
    pub y0: i64,
    pub w: usize,
    pub h: usize,
    pub v: Vec<f32>,
}

impl Img {
    pub fn filled(x0: i64, y0: i64, w: usize, h: usize, value: f32) -> Img {
        Img { x0, y0, w, h, v: vec![value; w * h] }
    }

    /// The value at grid pixel `(x, y)` (NaN outside).
    #[inline]
    pub fn at(&self, x: i64, y: i64) -> f32 {
        let (a, b) = (x - self.x0, y - self.y0);
        if a < 0 || b < 0 || a >= self.w as i64 || b >= self.h as i64 {
            return f32::NAN;
        }
        self.v[b as usize * self.w + a as usize]
    }

    /// Half the size: each pixel the mean of the 2 × 2 it covers (those
    /// with a value); the origin halved (it is even).
    pub fn halved(&self) -> Img {
        let (w, h) = (self.w.div_ceil(2), self.h.div_ceil(2));
        let mut out = Img::filled(self.x0.div_euclid(2), self.y0.div_euclid(2), w, h, f32::NAN);
        for y in 0..h {
            for x in 0..w {
                let (mut s, mut n) = (0.0f32, 0u32);
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (a, b) = (2 * x + dx, 2 * y + dy);
                    if a < self.w && b < self.h {
                        let v = self.v[b * self.w + a];
                        if !v.is_nan() {
                            s += v;
                            n += 1;
                        }
                    }
                }
                // A pixel with under half its area imaged is no pixel.
                if n >= 2 {
                    out.v[y * w + x] = s / n as f32;
                }
            }
        }
        out
    }
}

/// One image of the pair: its scan and its model on the ground.
pub struct Side<'a> {
    pub scan: &'a SourceImage,
    pub model: &'a dyn SensorModel,
}

/// The grid window `[x0, x0 + w) × [y0, y0 + h)` of `frame` filled from
/// `side`'s scan, its rows moved by `row_shift` (the right image's
/// pointing correction; 0 for the left).
pub fn resample(frame: &EpipolarFrame, side: &Side, x0: i64, y0: i64, w: usize, h: usize, row_shift: f64) -> Result<Img> {
    let mut img = Img::filled(x0, y0, w, h, f32::NAN);
    let (nx, ny) = (w.div_ceil(NODE_STEP) + 1, h.div_ceil(NODE_STEP) + 1);
    let mut nodes = vec![(f64::NAN, f64::NAN); nx * ny];
    let (mut c0, mut r0, mut c1, mut r1) = (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
    for b in 0..ny {
        for a in 0..nx {
            let g = frame.ground((x0 + (a * NODE_STEP) as i64) as f64 + 0.5, (y0 + (b * NODE_STEP) as i64) as f64 + 0.5 + row_shift);
            if let Some((c, r)) = side.model.project(g[0], g[1], frame.plane_z) {
                nodes[b * nx + a] = (c, r);
                (c0, r0, c1, r1) = (c0.min(c), r0.min(r), c1.max(c), r1.max(r));
            }
        }
    }
    let info = &side.scan.info;
    let (sw, sh) = (info.width as f64, info.height as f64);
    let (wc0, wr0) = ((c0 - 2.0).floor().max(0.0), (r0 - 2.0).floor().max(0.0));
    let (wc1, wr1) = ((c1 + 2.0).ceil().min(sw), (r1 + 2.0).ceil().min(sh));
    if !(wc1 > wc0 && wr1 > wr0) {
        return Ok(img);
    }
    let (wx, wy, ww, wh) = (wc0 as u32, wr0 as u32, (wc1 - wc0) as u32, (wr1 - wr0) as u32);
    let mut win = Window::default();
    side.scan.read_window(wx, wy, ww, wh, &mut win)?;
    let grey = grey(win.bytes(), info.sample, info.bands as usize, info.has_alpha, info.nodata);
    let (ww, wh) = (ww as usize, wh as usize);
    for y in 0..h {
        let (b, fy) = (y / NODE_STEP, (y % NODE_STEP) as f64 / NODE_STEP as f64);
        for x in 0..w {
            let (a, fx) = (x / NODE_STEP, (x % NODE_STEP) as f64 / NODE_STEP as f64);
            let n = |i: usize, j: usize| nodes[(b + j) * nx + a + i];
            let (p00, p10, p01, p11) = (n(0, 0), n(1, 0), n(0, 1), n(1, 1));
            let c = (p00.0 * (1.0 - fx) + p10.0 * fx) * (1.0 - fy) + (p01.0 * (1.0 - fx) + p11.0 * fx) * fy;
            let r = (p00.1 * (1.0 - fx) + p10.1 * fx) * (1.0 - fy) + (p01.1 * (1.0 - fx) + p11.1 * fx) * fy;
            // Pixel centres at +½; within the scan's outer centres only.
            let (u, v) = (c - 0.5 - wc0, r - 0.5 - wr0);
            if !(u >= 0.0 && v >= 0.0 && c <= sw - 0.5 && r <= sh - 0.5) {
                continue;
            }
            let (iu, iv) = ((u as usize).min(ww.saturating_sub(2)), (v as usize).min(wh.saturating_sub(2)));
            if iu + 1 >= ww || iv + 1 >= wh {
                continue;
            }
            let (fu, fv) = ((u - iu as f64) as f32, (v - iv as f64) as f32);
            let g = |i: usize, j: usize| grey[(iv + j) * ww + iu + i];
            let top = g(0, 0) * (1.0 - fu) + g(1, 0) * fu;
            let bot = g(0, 1) * (1.0 - fu) + g(1, 1) * fu;
            img.v[y * w + x] = top * (1.0 - fv) + bot * fv;
        }
    }
    Ok(img)
}

/// The grey value of each pixel of chunky samples: the mean of the colour
/// bands (the alpha band left out), NaN where every band holds `nodata` or
/// the alpha is 0.
fn grey(bytes: &[u8], sample: SampleType, bands: usize, alpha: bool, nodata: Option<f64>) -> Vec<f32> {
    let values: Vec<f32> = match sample {
        SampleType::U8 => bytes.iter().map(|&v| v as f32).collect(),
        SampleType::U16 => bytes.chunks_exact(2).map(|b| u16::from_ne_bytes([b[0], b[1]]) as f32).collect(),
        SampleType::F32 => bytes.chunks_exact(4).map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])).collect(),
    };
    let colour = if alpha { (bands - 1).clamp(1, 3) } else { bands.min(3) };
    values
        .chunks_exact(bands)
        .map(|px| {
            if alpha && px[bands - 1] == 0.0 {
                return f32::NAN;
            }
            let c = &px[..colour];
            if nodata.is_some_and(|nd| c.iter().all(|&v| v as f64 == nd)) || c.iter().any(|v| !v.is_finite()) {
                return f32::NAN;
            }
            c.iter().sum::<f32>() / colour as f32
        })
        .collect()
}
