//! A window of the scan as one grey band, reduced by a whole factor (the
//! pyramid's levels): read a strip of rows at a time, so a search window
//! of any size costs a few MB.

use crate::error::Result;
use crate::io::source::{SampleType, SourceImage, Window};

/// Grey tones of a window reduced `factor` times: pixel (i, j) is the mean
/// of the full-resolution pixels `[x0 + i·f, x0 + (i+1)·f) × [y0 + j·f, …)`.
#[derive(Clone, Debug, Default)]
pub struct Gray {
    /// The window's corner in the scan (negative: it reaches past the scan).
    pub x0: i64,
    pub y0: i64,
    pub factor: u32,
    pub width: usize,
    pub height: usize,
    pub data: Vec<f32>,
    /// The pixels that are the scan's, not padding: [i0, j0, i1, j1).
    pub inside: [usize; 4],
}

/// Bytes of scan a strip holds at most.
const STRIP_BYTES: usize = 4 << 20;

impl Gray {
    /// The window `(x0, y0, w, h)` (clipped to the scan) reduced by `factor`;
    /// the grey tone is the mean of the first three bands (or the one band).
    pub fn read(src: &SourceImage, (x0, y0, w, h): (u32, u32, u32, u32), factor: u32) -> Result<Gray> {
        let f = factor.max(1);
        let x1 = (x0 + w).min(src.info.width);
        let y1 = (y0 + h).min(src.info.height);
        let width = (x1.saturating_sub(x0) / f) as usize;
        let height = (y1.saturating_sub(y0) / f) as usize;
        let mut gray = Gray { x0: x0 as i64, y0: y0 as i64, factor: f, width, height, data: vec![0.0; width * height], inside: [0, 0, width, height] };
        if width == 0 || height == 0 {
            return Ok(gray);
        }
        let info = &src.info;
        let bands = info.bands as usize;
        let used = bands.min(3);
        let pb = info.pixel_bytes();
        let cols = width * f as usize;
        let row_bytes = cols * pb;
        let rows_a_strip = ((STRIP_BYTES / row_bytes.max(1)) / f as usize).max(1) * f as usize;
        let mut win = Window::default();
        let mut row = vec![0f32; cols];
        let scale = 1.0 / (f * f) as f32;
        let mut y = 0usize;
        while y < height * f as usize {
            let n = rows_a_strip.min(height * f as usize - y);
            src.read_window(x0, y0 + y as u32, cols as u32, n as u32, &mut win)?;
            let bytes = win.bytes();
            for k in 0..n {
                let line = &bytes[k * row_bytes..(k + 1) * row_bytes];
                tones(line, info.sample, bands, used, &mut row);
                let out = &mut gray.data[((y + k) / f as usize) * width..][..width];
                for (i, o) in out.iter_mut().enumerate() {
                    *o += row[i * f as usize..(i + 1) * f as usize].iter().sum::<f32>() * scale;
                }
            }
            y += n;
        }
        Ok(gray)
    }

    /// The window `(x0, y0, w, h)` reduced by `factor`, where it reaches
    /// past the scan filled with the mean tone of the part inside (a mark
    /// near the scan's edge keeps its whole template).
    pub fn read_padded(src: &SourceImage, (x0, y0, w, h): (i64, i64, u32, u32), factor: u32) -> Result<Gray> {
        let f = factor.max(1) as i64;
        let (sw, sh) = (src.info.width as i64, src.info.height as i64);
        let ix0 = x0 + ((-x0).max(0) as u64).div_ceil(f as u64) as i64 * f;
        let iy0 = y0 + ((-y0).max(0) as u64).div_ceil(f as u64) as i64 * f;
        let iw = ((x0 + w as i64).min(sw) - ix0).max(0) / f * f;
        let ih = ((y0 + h as i64).min(sh) - iy0).max(0) / f * f;
        let (width, height) = ((w as i64 / f) as usize, (h as i64 / f) as usize);
        if ix0 == x0 && iy0 == y0 && iw == w as i64 / f * f && ih == h as i64 / f * f {
            return Self::read(src, (x0 as u32, y0 as u32, w, h), factor);
        }
        let inner =
            if iw > 0 && ih > 0 && ix0 < sw && iy0 < sh { Self::read(src, (ix0 as u32, iy0 as u32, iw as u32, ih as u32), factor)? } else { Gray::default() };
        let mean = if inner.data.is_empty() { 0.0 } else { inner.data.iter().sum::<f32>() / inner.data.len() as f32 };
        let (oi, oj) = (((ix0 - x0) / f) as usize, ((iy0 - y0) / f) as usize);
        let inside = [oi.min(width), oj.min(height), (oi + inner.width).min(width), (oj + inner.height).min(height)];
        let mut gray = Gray { x0, y0, factor: f as u32, width, height, data: vec![mean; width * height], inside };
        for j in 0..inner.height.min(height.saturating_sub(oj)) {
            let n = inner.width.min(width.saturating_sub(oi));
            gray.data[(oj + j) * width + oi..][..n].copy_from_slice(&inner.data[j * inner.width..][..n]);
        }
        Ok(gray)
    }

    #[inline]
    #[must_use]
    pub fn at(&self, i: usize, j: usize) -> f32 {
        self.data[j * self.width + i]
    }

    /// A window's pixel (i, j) as a full-resolution scan position (its
    /// centre, GDAL's convention): `x0 + f·(i + ½)`.
    #[must_use]
    pub fn to_scan(&self, i: f64, j: f64) -> [f64; 2] {
        let f = self.factor as f64;
        [self.x0 as f64 + f * i, self.y0 as f64 + f * j]
    }
}

/// One row of chunky samples → mean tone of the first `used` bands.
fn tones(line: &[u8], sample: SampleType, bands: usize, used: usize, out: &mut [f32]) {
    let k = 1.0 / used as f32;
    match sample {
        SampleType::U8 => {
            for (o, px) in out.iter_mut().zip(line.chunks_exact(bands)) {
                *o = px[..used].iter().map(|&v| v as f32).sum::<f32>() * k;
            }
        }
        SampleType::U16 => {
            for (o, px) in out.iter_mut().zip(line.chunks_exact(bands * 2)) {
                *o = px[..used * 2].chunks_exact(2).map(|b| u16::from_ne_bytes([b[0], b[1]]) as f32).sum::<f32>() * k;
            }
        }
        SampleType::F32 => {
            for (o, px) in out.iter_mut().zip(line.chunks_exact(bands * 4)) {
                let s: f32 = px[..used * 4].chunks_exact(4).map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])).sum();
                *o = if s.is_finite() { s * k } else { 0.0 };
            }
        }
    }
}
