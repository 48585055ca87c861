//! Resampling kernels: the value of the scan at a continuous position
//! (column, row; pixel centres at +½), from a window of the scan. Kernels
//! take slices and plain numbers; one output row segment per call.
//!
//! * nearest — the pixel containing the position (textbook §9.10.3);
//! * bilinear — the four nearest centres (textbook 9.36);
//! * cubic — Keys' convolution, a = −0.5 (as GDAL), 4×4;
//! * lanczos3 — windowed sinc, 6×6, weights normalised.
//!
//! Positions outside the scan give no value; near the border the kernel's
//! missing neighbours repeat the edge pixel.

pub mod area;
mod bilinear_u8;
mod spans;

use crate::geom::{floor_i64, ImageArea};
use crate::io::source::{SampleType, Window};
#[cfg(any(test, feature = "internals"))]
pub use spans::resample_span;
pub use spans::{resample_spans, span_bounds, span_position, Fixed, SpanOutcome};

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Kernel {
    Nearest,
    Bilinear,
    Cubic,
    Lanczos3,
    /// The scan's mean over each output pixel's footprint ([`area`]).
    Average,
    /// The value covering most of each output pixel's footprint.
    Mode,
}

impl Kernel {
    /// How many source pixels beyond the position's own the kernel reads
    /// (area kernels: beyond the footprint, which the caller adds).
    pub fn radius(self) -> u32 {
        match self {
            Kernel::Nearest | Kernel::Average | Kernel::Mode => 0,
            Kernel::Bilinear => 1,
            Kernel::Cubic => 2,
            Kernel::Lanczos3 => 3,
        }
    }

    /// The area kernel this is, if it is one.
    pub fn area(self) -> Option<area::AreaKind> {
        match self {
            Kernel::Average => Some(area::AreaKind::Average),
            Kernel::Mode => Some(area::AreaKind::Mode),
            _ => None,
        }
    }
}

/// Bilinear weights of one position: as floats and as 10-bit fixed point.
#[derive(Clone, Copy)]
pub struct Weights {
    pub fx: f32,
    pub fy: f32,
    pub ix: u32,
    pub iy: u32,
}

impl Weights {
    #[inline]
    fn new(fx: f64, fy: f64) -> Weights {
        Weights { fx: fx as f32, fy: fy as f32, ix: (fx * 1024.0 + 0.5) as u32, iy: (fy * 1024.0 + 0.5) as u32 }
    }

    /// From fixed-point fractions (0..1024).
    #[inline]
    fn fixed(ix: u32, iy: u32) -> Weights {
        Weights { fx: ix as f32 * (1.0 / 1024.0), fy: iy as f32 * (1.0 / 1024.0), ix, iy }
    }
}

/// A sample type the kernels read and write.
pub trait Sample: Copy + Default + PartialEq + Send + Sync + bytemuck::Pod {
    const TYPE: SampleType;
    fn to_f32(self) -> f32;
    fn from_f32(v: f32) -> Self;
    /// Bilinear interpolation of four neighbours (integers in fixed point,
    /// rounded half up: exact to the sample's own precision).
    #[inline]
    fn bilerp(p00: Self, p10: Self, p01: Self, p11: Self, w: Weights) -> Self {
        let top = p00.to_f32() + w.fx * (p10.to_f32() - p00.to_f32());
        let bot = p01.to_f32() + w.fx * (p11.to_f32() - p01.to_f32());
        Self::from_f32(top + w.fy * (bot - top))
    }
}

impl Sample for u8 {
    const TYPE: SampleType = SampleType::U8;
    #[inline]
    fn bilerp(p00: u8, p10: u8, p01: u8, p11: u8, w: Weights) -> u8 {
        bilinear_u8::bilerp(p00, p10, p01, p11, w.ix, w.iy)
    }
    #[inline]
    fn to_f32(self) -> f32 {
        self as f32
    }
    #[inline]
    fn from_f32(v: f32) -> Self {
        // Round half up without a libm call; `as` saturates NaN to 0.
        (v.clamp(0.0, 255.0) + 0.5) as u8
    }
}
impl Sample for u16 {
    const TYPE: SampleType = SampleType::U16;
    #[inline]
    fn bilerp(p00: u16, p10: u16, p01: u16, p11: u16, w: Weights) -> u16 {
        let (ax, ay) = ((1024 - w.ix) as u64, (1024 - w.iy) as u64);
        let (ix, iy) = (w.ix as u64, w.iy as u64);
        let top = p00 as u64 * ax + p10 as u64 * ix;
        let bot = p01 as u64 * ax + p11 as u64 * ix;
        ((top * ay + bot * iy + (1 << 19)) >> 20) as u16
    }
    #[inline]
    fn to_f32(self) -> f32 {
        self as f32
    }
    #[inline]
    fn from_f32(v: f32) -> Self {
        (v.clamp(0.0, 65535.0) + 0.5) as u16
    }
}
impl Sample for f32 {
    const TYPE: SampleType = SampleType::F32;
    #[inline]
    fn to_f32(self) -> f32 {
        self
    }
    #[inline]
    fn from_f32(v: f32) -> Self {
        v
    }
}

/// A typed view of a window: `bands` interleaved samples per pixel.
pub struct View<'a, T> {
    pub data: &'a [T],
    pub x0: i64,
    pub y0: i64,
    pub w: i64,
    pub h: i64,
    /// Pixels from one row of `data` to the next (≥ w).
    pub stride: i64,
    pub bands: usize,
    /// Size of the whole scan (for "outside" and edge clamping).
    pub img_w: f64,
    pub img_h: f64,
    /// The window lies wholly inside the scan.
    in_scan: bool,
    /// Where less than the whole scan holds the image (a film's format):
    /// positions outside it have no value.
    pub area: Option<ImageArea>,
    /// An upright rectangle inside the area (with room: see
    /// [`ImageArea::holds_rect_with_room`]), in the kernel's fixed point
    /// (`[c_lo, r_lo, c_hi, r_hi]`, see [`Fixed`]): a span whose positions
    /// lie in it is inside the area by four integer compares. The area's
    /// own test on every span cost 0.2 s of a 1 GiB scan's 4.6 s.
    area_inner: Option<[i64; 4]>,
}

impl<'a, T: Sample> View<'a, T> {
    pub fn new(win: &'a Window, bands: u32, img_w: u32, img_h: u32) -> View<'a, T> {
        Self::in_place(bytemuck::cast_slice(win.bytes()), win.x0, win.y0, win.w, win.h, win.w as usize, bands, img_w, img_h)
    }

    /// A view of samples in place (in a mapped file): `w`×`h` pixels at scan
    /// position (x0, y0), rows `stride` pixels apart.
    #[allow(clippy::too_many_arguments)]
    pub fn in_place(data: &'a [T], x0: u32, y0: u32, w: u32, h: u32, stride: usize, bands: u32, img_w: u32, img_h: u32) -> View<'a, T> {
        View {
            data,
            x0: x0 as i64,
            y0: y0 as i64,
            w: w as i64,
            h: h as i64,
            stride: stride as i64,
            bands: bands as usize,
            img_w: img_w as f64,
            img_h: img_h as f64,
            in_scan: x0 as u64 + w as u64 <= img_w as u64 && y0 as u64 + h as u64 <= img_h as u64,
            area: None,
            area_inner: None,
        }
    }

    /// Only positions inside `area` (and the scan) take a value.
    pub fn with_area(mut self, area: Option<ImageArea>) -> Self {
        self.area = area;
        self.area_inner = area.and_then(|a| {
            // Between each axis's second and third corner: a parallelogram
            // near upright (a film's format) holds that rectangle.
            let middle = |k: usize| {
                let mut v = a.corners().map(|p| if k == 0 { p.0 } else { p.1 });
                v.sort_by(f64::total_cmp);
                (v[1], v[2])
            };
            let ((c0, c1), (r0, r1)) = (middle(0), middle(1));
            const ONE: f64 = 4_294_967_296.0;
            let (lo, hi) = (|v: f64| ((v - 0.5) * ONE).ceil(), |v: f64| ((v - 0.5) * ONE).floor());
            let fits = [lo(c0), lo(r0), hi(c1), hi(r1)].iter().all(|q| q.abs() < 2f64.powi(62));
            (c0 < c1 && r0 < r1 && fits && a.holds_rect_with_room(c0, r0, c1, r1)).then(|| [lo(c0) as i64, lo(r0) as i64, hi(c1) as i64, hi(r1) as i64])
        });
        self
    }

    /// A window of no pixels.
    pub fn is_empty(&self) -> bool {
        self.w <= 0 || self.h <= 0
    }

    /// Whether scan position (c, r) has a value: inside the scan and the
    /// image area.
    #[inline(always)]
    pub fn has_value(&self, c: f64, r: f64) -> bool {
        c >= 0.0 && r >= 0.0 && c < self.img_w && r < self.img_h && self.area.is_none_or(|a| a.contains(c, r))
    }

    /// Whether the bilinear neighbours of window pixel (i0, j0) (it, the
    /// next to the right and the two below) leave the window across an
    /// edge that the scan goes on past: there the clamped value differs
    /// from the scan's, and the caller reads the pixel again. At the scan's
    /// own edges clamping is what is meant.
    #[inline]
    fn leaves_into_scan(&self, i0: i64, j0: i64) -> bool {
        (i0 < 0 && self.x0 > 0)
            || (i0 + 1 >= self.w && ((self.x0 + self.w) as f64) < self.img_w)
            || (j0 < 0 && self.y0 > 0)
            || (j0 + 1 >= self.h && ((self.y0 + self.h) as f64) < self.img_h)
    }

    /// Sample index of window-relative (clamped) pixel (i, j).
    #[inline]
    fn at(&self, i: i64, j: i64) -> usize {
        let i = i.clamp(0, self.w - 1);
        let j = j.clamp(0, self.h - 1);
        (j * self.stride + i) as usize * self.bands
    }
}

#[inline]
fn cubic_weights(t: f32) -> [f32; 4] {
    // Keys, a = −0.5, for the taps at −1, 0, 1, 2 from floor.
    let a = -0.5f32;
    let w = |x: f32| {
        let x = x.abs();
        if x <= 1.0 {
            ((a + 2.0) * x - (a + 3.0)) * x * x + 1.0
        } else if x < 2.0 {
            ((a * x - 5.0 * a) * x + 8.0 * a) * x - 4.0 * a
        } else {
            0.0
        }
    };
    [w(1.0 + t), w(t), w(1.0 - t), w(2.0 - t)]
}

#[inline]
fn lanczos3_weights(t: f32) -> [f32; 6] {
    let mut w = [0f32; 6];
    let mut sum = 0.0;
    for (k, wk) in w.iter_mut().enumerate() {
        let x = t - (k as f32 - 2.0);
        *wk = if x.abs() < 1e-6 {
            1.0
        } else if x.abs() < 3.0 {
            let px = std::f32::consts::PI * x;
            3.0 * px.sin() * (px / 3.0).sin() / (px * px)
        } else {
            0.0
        };
        sum += *wk;
    }
    for wk in &mut w {
        *wk /= sum;
    }
    w
}

/// Resamples one output row segment: `out` gets `cols.len()` pixels of
/// `view.bands` samples; `valid[i]` says whether pixel i got a value (else
/// its samples are `fill`). Neighbours outside the view repeat its edge
/// pixels; the result says whether any pixel may have needed one across an
/// edge of the view that is not the scan's (then the caller reads those
/// pixels again from a wider window). Bilinear tells exactly; the other
/// kernels always say yes.
pub fn resample_row<T: Sample>(kernel: Kernel, view: &View<'_, T>, cols: &[f64], rows: &[f64], out: &mut [T], valid: &mut [bool], fill: T) -> bool {
    if view.is_empty() {
        // A window of no pixels (the plan's samples of the chunk all fell
        // off the scan, the pixels between them did not): every pixel
        // with a value is the caller's to read on its own.
        for (i, (&c, &r)) in cols.iter().zip(rows).enumerate() {
            valid[i] = view.has_value(c, r);
        }
        out.fill(fill);
        return valid.iter().any(|&v| v);
    }
    // The common kernels with the band count known at compile time.
    match (kernel, view.bands) {
        (Kernel::Bilinear, 1) => return bilinear_row::<T, 1>(view, cols, rows, out, valid, fill),
        (Kernel::Bilinear, 2) => return bilinear_row::<T, 2>(view, cols, rows, out, valid, fill),
        (Kernel::Bilinear, 3) => return bilinear_row::<T, 3>(view, cols, rows, out, valid, fill),
        (Kernel::Bilinear, 4) => return bilinear_row::<T, 4>(view, cols, rows, out, valid, fill),
        _ => {}
    }
    let b = view.bands;
    for (i, (&c, &r)) in cols.iter().zip(rows).enumerate() {
        let px = &mut out[i * b..(i + 1) * b];
        if !view.has_value(c, r) {
            px.fill(fill);
            valid[i] = false;
            continue;
        }
        valid[i] = true;
        match kernel {
            Kernel::Nearest => {
                let s = view.at(floor_i64(c) - view.x0, floor_i64(r) - view.y0);
                px.copy_from_slice(&view.data[s..s + b]);
            }
            Kernel::Bilinear => {
                let (x, y) = (c - 0.5, r - 0.5);
                let (xi, yi) = (floor_i64(x), floor_i64(y));
                let w = Weights::new(x - xi as f64, y - yi as f64);
                let (i0, j0) = (xi - view.x0, yi - view.y0);
                let (s00, s10, s01, s11) = if i0 >= 0 && j0 >= 0 && i0 + 1 < view.w && j0 + 1 < view.h {
                    let s = (j0 * view.stride + i0) as usize * b;
                    let row = view.stride as usize * b;
                    (s, s + b, s + row, s + row + b)
                } else {
                    (view.at(i0, j0), view.at(i0 + 1, j0), view.at(i0, j0 + 1), view.at(i0 + 1, j0 + 1))
                };
                let d = view.data;
                for k in 0..b {
                    px[k] = T::bilerp(d[s00 + k], d[s10 + k], d[s01 + k], d[s11 + k], w);
                }
            }
            Kernel::Cubic => separable(view, c, r, cubic_weights, px),
            Kernel::Lanczos3 => separable(view, c, r, lanczos3_weights, px),
            // Area kernels come here for a footprint without area: the
            // scan at the position.
            Kernel::Average | Kernel::Mode => {
                let s = view.at(floor_i64(c) - view.x0, floor_i64(r) - view.y0);
                px.copy_from_slice(&view.data[s..s + b]);
            }
        }
    }
    true
}

/// A separable `N`-tap kernel (cubic: 4, Lanczos: 6) at scan position (c, r).
#[inline]
fn separable<T: Sample, const N: usize>(view: &View<'_, T>, c: f64, r: f64, weights: fn(f32) -> [f32; N], px: &mut [T]) {
    let (x, y) = (c - 0.5, r - 0.5);
    let (xi, yi) = (floor_i64(x), floor_i64(y));
    let wx = weights((x - xi as f64) as f32);
    let wy = weights((y - yi as f64) as f32);
    // Taps start (N/2 − 1) pixels left of and above the floor.
    let back = (N / 2 - 1) as i64;
    let (i0, j0) = (xi - view.x0 - back, yi - view.y0 - back);
    let mut acc = [0f32; 4];
    let b = view.bands;
    for (dj, wyj) in wy.iter().enumerate() {
        for (di, wxi) in wx.iter().enumerate() {
            let s = view.at(i0 + di as i64, j0 + dj as i64);
            let w = wxi * wyj;
            for (a, v) in acc[..b].iter_mut().zip(&view.data[s..s + b]) {
                *a += w * v.to_f32();
            }
        }
    }
    for k in 0..b {
        px[k] = T::from_f32(acc[k]);
    }
}

/// Bilinear with `B` bands, in two passes over blocks of pixels. The first
/// (branch-free, so it vectorises) turns positions into window positions in
/// 1/1024 pixel, rounded (the fixed-point weights' resolution), and says
/// which pixels have all four neighbours inside the window; the second
/// gathers those and leaves the rest to the clamping generic path.
/// Returns whether any pixel needed a neighbour outside the window where
/// the scan goes on past it ([`View::leaves_into_scan`]).
fn bilinear_row<T: Sample, const B: usize>(view: &View<'_, T>, cols: &[f64], rows: &[f64], out: &mut [T], valid: &mut [bool], fill: T) -> bool {
    const BLOCK: usize = 256;
    // Positions are shifted by PAD pixels so that every one that matters is
    // positive, and clamped to a harmless range; adding 2^52 then rounds to
    // an integer held in the low bits of the f64 (no conversion instruction).
    const PAD: f64 = 4.0;
    const MAGIC: f64 = 4_503_599_627_370_496.0;
    let (ox, oy) = (view.x0 as f64 + 0.5 - PAD, view.y0 as f64 + 0.5 - PAD);
    let (ux_max, uy_max) = ((view.w + 8) as f64, (view.h + 8) as f64);
    let (wx_lim, wy_lim) = ((view.w - 1) as u32, (view.h - 1) as u32);
    let mut qx = [0u32; BLOCK];
    let mut qy = [0u32; BLOCK];
    let mut state = [0u8; BLOCK];
    let mut clamped = false;
    let src = Gather::new::<B>(view);
    for (b0, (cb, rb)) in cols.chunks(BLOCK).zip(rows.chunks(BLOCK)).enumerate() {
        let n = cb.len();
        for i in 0..n {
            let (c, r) = (cb[i], rb[i]);
            let inside = c >= 0.0 && r >= 0.0 && c < view.img_w && r < view.img_h;
            let ux = (c - ox).max(0.0).min(ux_max);
            let uy = (r - oy).max(0.0).min(uy_max);
            let (x, y) = ((ux * 1024.0 + MAGIC).to_bits() as u32, (uy * 1024.0 + MAGIC).to_bits() as u32);
            qx[i] = x;
            qy[i] = y;
            // Window-relative floor: (x >> 10) − PAD, wrapping below zero.
            let fast = (x >> 10).wrapping_sub(PAD as u32) < wx_lim && (y >> 10).wrapping_sub(PAD as u32) < wy_lim;
            state[i] = u8::from(inside) * (1 + u8::from(!fast));
        }
        if let Some(area) = &view.area {
            for (s, (&c, &r)) in state[..n].iter_mut().zip(cb.iter().zip(rb)) {
                if !area.contains(c, r) {
                    *s = 0;
                }
            }
        }
        let o = &mut out[b0 * BLOCK * B..(b0 * BLOCK + n) * B];
        let v = &mut valid[b0 * BLOCK..b0 * BLOCK + n];
        for i in 0..n {
            let px: &mut [T; B] = (&mut o[i * B..(i + 1) * B]).try_into().expect("B samples");
            v[i] = state[i] != 0;
            match state[i] {
                0 => *px = [fill; B],
                1 => {
                    let (i0, j0) = ((qx[i] >> 10) as usize - PAD as usize, (qy[i] >> 10) as usize - PAD as usize);
                    let w = Weights::fixed(qx[i] & 1023, qy[i] & 1023);
                    gather_inside(&src, (j0 * view.stride as usize + i0) * B, w, px);
                }
                _ => {
                    let (x, y) = (cb[i] - 0.5, rb[i] - 0.5);
                    let (xi, yi) = (floor_i64(x), floor_i64(y));
                    clamped |= view.leaves_into_scan(xi - view.x0, yi - view.y0);
                    let w = Weights::new(x - xi as f64, y - yi as f64);
                    gather_clamped(view, xi - view.x0, yi - view.y0, w, px);
                }
            }
        }
    }
    clamped
}

/// A window's samples as the bilinear gathers read them.
struct Gather<'v, T> {
    data: &'v [T],
    /// The same bytes, for 8-bit RGB and RGBA (all bands at once), else empty.
    bytes: &'v [u8],
    /// Samples from one row to the next.
    row: usize,
}

impl<'v, T: Sample> Gather<'v, T> {
    fn new<const B: usize>(view: &View<'v, T>) -> Gather<'v, T> {
        let all_bands = T::TYPE == SampleType::U8 && (B == 3 || B == 4);
        Gather { data: view.data, bytes: if all_bands { bytemuck::cast_slice(view.data) } else { &[] }, row: view.stride as usize * B }
    }
}

/// Bilinear at the four pixels from sample index `s` (upper left), all
/// inside the window.
#[inline(always)]
fn gather_inside<T: Sample, const B: usize>(g: &Gather<'_, T>, s: usize, w: Weights, px: &mut [T; B]) {
    let row = g.row;
    if let (Some(u), Some(l)) = (g.bytes.get(s..s + 8), g.bytes.get(s + row..s + row + 8)) {
        let v = bilinear_u8::bilerp_pixel::<B>(u, l, w.ix, w.iy).to_le_bytes();
        bytemuck::cast_slice_mut::<T, u8>(&mut px[..]).copy_from_slice(&v[..B]);
        return;
    }
    let d = g.data;
    let (p0, p1) = (&d[s..s + 2 * B], &d[s + row..s + row + 2 * B]);
    for k in 0..B {
        px[k] = T::bilerp(p0[k], p0[B + k], p1[k], p1[B + k], w);
    }
}

/// Bilinear at window pixel (i0, j0) and its neighbours, those outside the
/// window repeating its edge.
#[inline]
fn gather_clamped<T: Sample, const B: usize>(view: &View<'_, T>, i0: i64, j0: i64, w: Weights, px: &mut [T; B]) {
    let d = view.data;
    let (s00, s10, s01, s11) = (view.at(i0, j0), view.at(i0 + 1, j0), view.at(i0, j0 + 1), view.at(i0 + 1, j0 + 1));
    for k in 0..B {
        px[k] = T::bilerp(d[s00 + k], d[s10 + k], d[s01 + k], d[s11 + k], w);
    }
}

#[cfg(test)]
mod tests {
    use super::spans::{inside_limits, span_fixed};
    use super::*;
    use crate::geom::{floor_split, Span};

    /// A window of no pixels (the plan's samples of a chunk all off the
    /// scan, pixels between them on it): no kernel reads it; the pixels
    /// with a value are said to need reading on their own.
    #[test]
    fn an_empty_window_leaves_every_pixel_to_the_caller() {
        let data: [u8; 0] = [];
        for (x0, w, h) in [(0, 0, 0), (40, 0, 30), (0, 30, 0)] {
            let view = View::<u8>::in_place(&data, x0, 0, w, h, w as usize, 3, 40, 30);
            for kernel in [Kernel::Nearest, Kernel::Bilinear, Kernel::Cubic, Kernel::Lanczos3] {
                let (cols, rows) = ([5.5, 39.0, 45.0], [5.5, 29.5, 5.0]);
                let mut out = [7u8; 9];
                let mut valid = [false; 3];
                assert!(resample_row(kernel, &view, &cols, &rows, &mut out, &mut valid, 0));
                assert_eq!(valid, [true, true, false], "{kernel:?}");
                assert_eq!(out, [0; 9]);
            }
        }
    }

    /// A 4×4 one-band image whose value is 10·col + row.
    fn ramp() -> Window {
        let data: Vec<u8> = (0..16).map(|k| (10 * (k % 4) + k / 4) as u8).collect();
        Window::from_bytes(0, 0, 4, 4, &data)
    }

    #[test]
    fn floor_split_is_floor() {
        let cases = [0.0, -0.0, 0.5, 1.0, 2.5, 3.5, -0.5, -1.0, -1.5, -2.5, 0.999_999_999_999, -1e-300, 1e-300, 123_456.789, -98_765.432_1];
        let mut all = cases.to_vec();
        // Integers and the numbers just beside them, up to the stated range.
        for e in [1.0, 1e3, 1e9, 2f64.powi(50), 2f64.powi(51) - 1.0] {
            for v in [e, -e] {
                all.extend([v, v.next_up(), v.next_down(), v + 0.5, v - 0.5]);
            }
        }
        for x in all {
            let (i, f) = floor_split(x);
            assert_eq!(f, x.floor(), "{x}");
            assert_eq!(i, x.floor() as i64, "{x}");
        }
    }

    /// The fixed point of a straight span, by the float trick, equals the
    /// plain conversion for every position and step a straight span may
    /// hold (below 2¹⁸ pixels, `Gcm::row_spans`), up to its edges.
    #[test]
    fn span_fixed_is_the_plain_conversion() {
        let plain = |v: f64| floor_i64(v * 4_294_967_296.0 + 0.5);
        let edge = (1u64 << 18) as f64;
        let mut vals = vec![0.0, 0.5, -0.5, 1.0 / 3.0, edge.next_down(), -edge.next_down(), edge - 0.5, 1e-12, -1e-12];
        let mut seed = 7u64;
        for _ in 0..20_000 {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64;
            vals.push((2.0 * u - 1.0) * edge);
            vals.push((2.0 * u - 1.0) * 3.0);
        }
        for w in vals.windows(2) {
            let (c, dc) = (w[0], w[1]);
            let span = Span { stepped: true, first: 5, end: 20, anchor: 3, c, r: -c, dc, dr: -dc, ddc: 0.0, ddr: 0.0 };
            let Fixed { q, dq, .. } = span_fixed(&span, 5);
            let (pq, pd) = ([plain(c - 0.5), plain(-c - 0.5)], [plain(dc), plain(-dc)]);
            assert_eq!(dq, pd, "{c} {dc}");
            assert_eq!(q, [pq[0].wrapping_add(2 * pd[0]), pq[1].wrapping_add(2 * pd[1])], "{c} {dc}");
        }
    }

    fn one(kernel: Kernel, c: f64, r: f64) -> Option<u8> {
        let win = ramp();
        let v = View::<u8>::new(&win, 1, 4, 4);
        let mut out = [0u8];
        let mut ok = [false];
        resample_row(kernel, &v, &[c], &[r], &mut out, &mut ok, 255);
        ok[0].then_some(out[0])
    }

    #[test]
    fn nearest_takes_the_containing_pixel() {
        assert_eq!(one(Kernel::Nearest, 2.99, 1.01), Some(21));
        assert_eq!(one(Kernel::Nearest, 4.0, 1.0), None);
        assert_eq!(one(Kernel::Nearest, -0.01, 1.0), None);
    }

    #[test]
    fn fixed_point_bilinear_matches_float_to_half_a_level() {
        let w = Weights::new(0.37, 0.81);
        for (a, b, c, d) in [(0u8, 255u8, 17u8, 200u8), (255, 255, 255, 255), (0, 0, 0, 0), (10, 20, 30, 40)] {
            let f = {
                let top = a as f32 + 0.37 * (b as f32 - a as f32);
                let bot = c as f32 + 0.37 * (d as f32 - c as f32);
                top + 0.81 * (bot - top)
            };
            let i = u8::bilerp(a, b, c, d, w) as f32;
            assert!((i - f).abs() <= 0.5 + 0.26, "{a} {b} {c} {d}: {i} vs {f}");
            let i16v = u16::bilerp(a as u16 * 257, b as u16 * 257, c as u16 * 257, d as u16 * 257, w) as f32;
            assert!((i16v - f * 257.0).abs() <= 0.5 + 0.26 * 257.0, "{i16v} vs {}", f * 257.0);
        }
        assert_eq!(u8::bilerp(255, 255, 255, 255, Weights::new(0.999, 0.999)), 255);
    }

    #[test]
    fn bilinear_reproduces_a_linear_ramp() {
        // At (2.0, 2.5): x = 1.5 → 15, y = 2.0 → +2.
        assert_eq!(one(Kernel::Bilinear, 2.0, 2.5), Some(17));
        // Exactly at a centre: the pixel itself.
        assert_eq!(one(Kernel::Bilinear, 1.5, 3.5), Some(13));
    }

    #[test]
    fn cubic_and_lanczos_interpolate_centres_and_ramps() {
        // Interpolating kernels give the pixel itself at its centre.
        assert_eq!(one(Kernel::Cubic, 1.5, 1.5), Some(11));
        assert_eq!(one(Kernel::Lanczos3, 2.5, 1.5), Some(21));
        // Keys' cubic reproduces linear functions exactly away from edges.
        // (2.0, 2.5) → x = 1.5, y = 2.0: 15 + 2; (2.2, 1.5) → 17 + 1.
        assert_eq!(one(Kernel::Cubic, 2.0, 2.5), Some(17));
        assert_eq!(one(Kernel::Cubic, 2.2, 1.5), Some(18));
    }

    #[test]
    fn bilinear_fast_path_equals_the_generic_one() {
        // Three bands take the const-generic path; compare with two calls
        // over a one-band view of each band's samples.
        let data: Vec<u8> = (0..4 * 4 * 3).map(|k| (k * 37 % 251) as u8).collect();
        let win = Window::from_bytes(0, 0, 4, 4, &data);
        let v3 = View::<u8>::new(&win, 3, 4, 4);
        let (cols, rows) = ([0.3, 1.7, 2.2, 3.9, 0.01], [0.6, 2.5, 3.99, 1.1, 0.2]);
        let mut out = [0u8; 15];
        let mut ok = [false; 5];
        resample_row(Kernel::Bilinear, &v3, &cols, &rows, &mut out, &mut ok, 0);
        for band in 0..3 {
            let one: Vec<u8> = data.iter().skip(band).step_by(3).copied().collect();
            let w1 = Window::from_bytes(0, 0, 4, 4, &one);
            let v1 = View::<u8>::new(&w1, 1, 4, 4);
            let mut o1 = [0u8; 5];
            resample_row(Kernel::Bilinear, &v1, &cols, &rows, &mut o1, &mut ok, 0);
            for i in 0..5 {
                assert_eq!(out[i * 3 + band], o1[i]);
            }
        }
    }

    #[test]
    fn a_run_of_spans_equals_its_spans_one_by_one() {
        // Consecutive spans of a row (each anchored at its own first pixel,
        // as the GCM makes them), some wholly inside the window and some
        // running off it or off the scan, in either order: one call for the
        // run gives the values and validity of one call per span, and says
        // `Inside` only when no pixel needed checking.
        let (w, h) = (50u32, 20u32);
        let bytes: Vec<u8> = (0..w * h * 3).map(|k| (k.wrapping_mul(2654435761) >> 24) as u8).collect();
        let win = Window::from_bytes(5, 5, w, h, &bytes);
        let view = View::<u8>::new(&win, 3, 60, 40);
        let span = |first: usize, end: usize, c: f64, r: f64| Span { stepped: true, first, end, anchor: first, c, r, dc: 0.93, dr: 0.11, ddc: 0.0, ddr: 0.0 };
        let inside = [span(10, 22, 8.3, 7.2), span(22, 35, 19.5, 8.6), span(35, 47, 31.6, 10.0)];
        let off_window = span(47, 60, 46.0, 11.3);
        let off_scan = span(0, 10, -3.0, 6.0);
        // Many short spans (more than one block of the 8-bit path), some
        // off the window or the scan on either side of a block's edge.
        let many = |odd: &[usize]| -> Vec<Span> {
            let mut x = 0;
            (0..80)
                .map(|k| {
                    let len = 1 + k % 3;
                    let (c, r) = if odd.contains(&k) {
                        if k == 70 {
                            (-3.0, 8.0)
                        } else {
                            (20.0, 30.0)
                        }
                    } else {
                        (8.0 + 0.4 * k as f64, 7.0 + 0.05 * k as f64)
                    };
                    let s = Span { stepped: true, first: x, end: x + len, anchor: x, c, r, dc: 0.1, dr: 0.02, ddc: 0.0, ddr: 0.0 };
                    x += len;
                    s
                })
                .collect()
        };
        let runs: [(Vec<Span>, bool); 6] = [
            (inside.to_vec(), true),
            ([&inside[..], &[off_window]].concat(), false),
            ([&[off_scan], &inside[..]].concat(), false),
            ([&inside[..1], &[span(22, 35, 19.5, 24.0)], &inside[2..]].concat(), false),
            (many(&[]), true),
            (many(&[31, 32, 64, 70]), false),
        ];
        for (run, all_inside) in runs {
            let (first, end) = (run[0].first, run[run.len() - 1].end);
            let n = end - first;
            let (mut out, mut valid) = (vec![0u8; n * 3], vec![false; n]);
            let outcome = resample_spans(&view, &run, &mut out, &mut valid, 9);
            assert_eq!(outcome == SpanOutcome::Inside, all_inside, "{run:?}");
            if outcome == SpanOutcome::Inside {
                assert!(valid.iter().all(|v| !v), "valid left as it was");
                valid.fill(true);
            }
            let (mut e, mut ve) = (vec![0u8; n * 3], vec![false; n]);
            for s in &run {
                let (a, b) = (s.first - first, s.end - first);
                if resample_span(&view, s, &mut e[a * 3..b * 3], &mut ve[a..b], 9) == SpanOutcome::Inside {
                    ve[a..b].fill(true);
                }
            }
            assert_eq!(valid, ve, "validity of {run:?}");
            assert_eq!(out, e, "values of {run:?}");
            assert_eq!(valid.iter().all(|&v| v), all_inside || run.iter().all(|s| s.c >= 0.0), "{run:?}");
        }
    }

    #[test]
    fn weights_sum_to_one() {
        for t in [0.0f32, 0.25, 0.5, 0.9] {
            let c: f32 = cubic_weights(t).iter().sum();
            let l: f32 = lanczos3_weights(t).iter().sum();
            assert!((c - 1.0).abs() < 1e-6 && (l - 1.0).abs() < 1e-6);
        }
    }

    /// Below `inside_limits` every 8-byte load of both rows lies in the
    /// window's bytes, and the limits are the largest with that property.
    #[test]
    fn inside_limits_keep_every_load_in_the_bytes() {
        for (w, h) in [(1u32, 1u32), (2, 2), (3, 5), (40, 30), (7, 2)] {
            for bands in [3usize, 4] {
                let bytes = vec![0u8; w as usize * h as usize * bands];
                let win = Window::from_bytes(0, 0, w, h, &bytes);
                let view = View::<u8>::new(&win, bands as u32, w, h);
                let (wl, hl) = if bands == 3 { inside_limits::<u8, 3>(&view) } else { inside_limits::<u8, 4>(&view) };
                let row = w as u64 * bands as u64;
                let fits = |i: u64, j: u64| (j + 1) * row + i * bands as u64 + 8 <= bytes.len() as u64;
                assert_eq!(wl, (w as u64).saturating_sub(1), "{w}x{h}x{bands}");
                assert!((0..wl).all(|i| (0..hl).all(|j| fits(i, j))), "{w}x{h}x{bands}: {hl}");
                // One row more would hold a load past the end or a neighbour past the window.
                assert!(hl + 1 >= h as u64 || wl == 0 || !fits(wl - 1, hl), "{w}x{h}x{bands}: {hl}");
            }
        }
        // RGBA loads fit in the last row but one; RGB's do not.
        let bytes = vec![0u8; 40 * 30 * 4];
        let win = Window::from_bytes(0, 0, 40, 30, &bytes);
        assert_eq!(inside_limits::<u8, 4>(&View::<u8>::new(&win, 4, 40, 30)), (39, 29));
        let win = Window::from_bytes(0, 0, 40, 30, &bytes[..40 * 30 * 3]);
        assert_eq!(inside_limits::<u8, 3>(&View::<u8>::new(&win, 3, 40, 30)), (39, 28));
    }

    /// Clamping is reported only where a window's edge is not the scan's:
    /// there the caller must read the pixel again, at the scan's own edges
    /// the clamped value is the answer.
    #[test]
    fn clamping_is_reported_only_at_edges_inside_the_scan() {
        let (sw, sh) = (60u32, 40u32);
        let scan: Vec<u8> = (0..sw * sh * 3).map(|k| (k * 7 % 251) as u8).collect();
        let crop = |x0: u32, y0: u32, w: u32, h: u32| {
            let rows: Vec<u8> = (y0..y0 + h).flat_map(|y| scan[((y * sw + x0) * 3) as usize..((y * sw + x0 + w) * 3) as usize].to_vec()).collect();
            Window::from_bytes(x0, y0, w, h, &rows)
        };
        // (window, which of its edges — left, top, right, bottom — are the scan's)
        let windows = [
            (crop(0, 0, sw, sh), [true, true, true, true]),
            (crop(10, 5, 40, 30), [false, false, false, false]),
            (crop(0, 5, sw, 30), [true, false, true, false]),
            (crop(10, 0, 40, sh), [false, true, false, true]),
        ];
        for (win, scan_edge) in &windows {
            let view = View::<u8>::new(win, 3, sw, sh);
            let (x0, y0, x1, y1) = (win.x0 as f64, win.y0 as f64, (win.x0 + win.w) as f64, (win.y0 + win.h) as f64);
            let my = (y0 + y1) / 2.0;
            let mx = (x0 + x1) / 2.0;
            // Straight spans across each edge, 0.2 px inside the scan's
            // edge where it is one (a kernel there clamps), and one
            // wholly inside.
            let cases = [
                (x0 + 0.2, my, 0.5, 0.0, scan_edge[0]),
                (mx, y0 + 0.2, 0.0, 0.5, scan_edge[1]),
                (x1 - 6.0, my, 1.0, 0.0, scan_edge[2]),
                (mx, y1 - 6.0, 0.0, 1.0, scan_edge[3]),
                (mx - 3.0, my, 0.5, 0.25, true),
            ];
            for (k, &(c, r, dc, dr, at_scan_edge)) in cases.iter().enumerate() {
                let span = Span { stepped: true, first: 0, end: 10, anchor: 0, c, r, dc, dr, ddc: 0.0, ddr: 0.0 };
                let (mut out, mut valid) = (vec![0u8; 30], vec![false; 10]);
                let outcome = resample_span(&view, &span, &mut out, &mut valid, 0);
                assert_eq!(outcome == (SpanOutcome::Checked { clamped: true }), !at_scan_edge, "window at {},{} case {k}: {outcome:?}", win.x0, win.y0);
                let (cols, rows): (Vec<f64>, Vec<f64>) = (0..10).map(|x| span_position(&span, x)).unzip();
                let clamped = resample_row(Kernel::Bilinear, &view, &cols, &rows, &mut out, &mut valid, 0);
                assert_eq!(clamped, !at_scan_edge, "row kernel, window at {},{} case {k}", win.x0, win.y0);
            }
        }
    }

    /// A quadratic span's fixed point from any pixel on equals stepping
    /// from its anchor, and the float position to the fixed point's
    /// resolution.
    #[test]
    fn a_quadratic_span_steps_to_the_same_integers_from_any_pixel() {
        let span = Span { stepped: true, first: 40, end: 70, anchor: 37, c: 812.3, r: -5.25, dc: 0.71, dr: 1.02, ddc: -3.1e-3, ddr: 7.7e-4 };
        let mut f = span_fixed(&span, span.anchor);
        for x in span.anchor..span.end {
            assert_eq!(span_fixed(&span, x), f, "{x}");
            let (c, r) = span_position(&span, x);
            let (ec, er) = span.at(x);
            assert!((c - ec).abs() <= 0.5 / 1024.0 + 1e-9 && (r - er).abs() <= 0.5 / 1024.0 + 1e-9, "{x}");
            for k in 0..2 {
                f.q[k] = f.q[k].wrapping_add(f.dq[k]);
                f.dq[k] = f.dq[k].wrapping_add(f.ddq[k]);
            }
        }
    }

    /// A span through [`resample_span`] and, at the positions it steps
    /// through ([`span_position`]), through the row kernel: (pixels,
    /// validity) of each, and the positions.
    #[allow(clippy::type_complexity)] // two results and the positions
    fn span_and_row_kernel(view: &View<'_, u8>, span: &Span) -> ((Vec<u8>, Vec<bool>), (Vec<u8>, Vec<bool>), (Vec<f64>, Vec<f64>)) {
        let (n, b) = (span.end - span.first, view.bands);
        let (mut a, mut va) = (vec![0u8; n * b], vec![false; n]);
        if resample_span(view, span, &mut a, &mut va, 9) == SpanOutcome::Inside {
            va.fill(true);
        }
        let (cols, rows): (Vec<f64>, Vec<f64>) = (span.first..span.end).map(|x| span_position(span, x)).unzip();
        let (mut e, mut ve) = (vec![0u8; n * b], vec![false; n]);
        resample_row(Kernel::Bilinear, view, &cols, &rows, &mut e, &mut ve, 9);
        ((a, va), (e, ve), (cols, rows))
    }

    /// Quadratic spans whose ends lie well inside the window but whose
    /// middles bulge past its edge (or the scan's): the span kernel must
    /// see the bulge and agree with the row kernel pixel for pixel.
    #[test]
    fn a_bulging_quadratic_span_resamples_what_the_row_kernel_does() {
        for bands in [3u32, 4] {
            let (w, h) = (40u32, 30u32);
            let bytes: Vec<u8> = (0..w * h * bands).map(|k| (k * 37 % 251) as u8).collect();
            let win = Window::from_bytes(10, 5, w, h, &bytes);
            for (sw, sh) in [(60, 40), (50, 35)] {
                let view = View::<u8>::new(&win, bands, sw, sh);
                // Along a row through the middle, then bending up past the
                // window's top (row 5) and back; and along a column bending
                // right past its right edge (column 49).
                for (c, r, dc, dr, ddc, ddr) in [(14.0, 8.0, 1.0, -0.6, 0.0, 0.05), (40.0, 8.0, 0.6, 1.0, -0.05, 0.0), (20.0, 20.0, 0.5, 0.1, 0.0, 0.0)] {
                    let span = Span { stepped: true, first: 3, end: 28, anchor: 0, c, r, dc, dr, ddc, ddr };
                    let ((a, va), (e, ve), (cols, rows)) = span_and_row_kernel(&view, &span);
                    assert_eq!((va, a), (ve, e), "{bands} bands, scan {sw}x{sh}, span at {c},{r}");
                    let bounds = span_bounds(&span);
                    assert!(cols.iter().zip(&rows).all(|(&c, &r)| c >= bounds[0] && r >= bounds[1] && c <= bounds[2] && r <= bounds[3]));
                }
            }
        }
    }

    #[test]
    fn a_span_resamples_what_the_row_kernel_does_at_its_positions() {
        // Random RGB and grey windows inside a larger scan; spans that run
        // off the window (clamped edge) and off the scan (no value), and one
        // along the window's last two rows into its corner, where an 8-byte
        // load of RGB would pass the end of the bytes.
        for bands in [1u32, 3, 4] {
            let (w, h) = (40u32, 30u32);
            let mut seed = 7u64;
            let bytes: Vec<u8> = (0..w * h * bands)
                .map(|_| {
                    seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                    (seed >> 56) as u8
                })
                .collect();
            let win = Window::from_bytes(10, 5, w, h, &bytes);
            let view = View::<u8>::new(&win, bands, 60, 40);
            for (c, r, dc, dr) in [(12.3, 7.9, 0.731, 0.213), (8.0, 6.0, 1.117, -0.05), (45.5, 30.2, 0.9, 0.4), (55.1, 38.7, 0.3, 0.2), (14.0, 33.9, 1.1, 0.0)]
            {
                let span = Span { stepped: true, first: 100, end: 130, anchor: 97, c, r, dc, dr, ddc: 0.0, ddr: 0.0 };
                let ((a, va), (e, ve), (cols, rows)) = span_and_row_kernel(&view, &span);
                assert_eq!(va, ve, "validity, {bands} bands, span at {c},{r}");
                assert_eq!(a, e, "values, {bands} bands, span at {c},{r}");
                // Within 1/1024 pixel of the span's own straight line.
                for (i, x) in (span.first..span.end).enumerate() {
                    let (pc, pr) = span.at(x);
                    assert!((pc - cols[i]).abs() <= 0.5 / 1024.0 + 1e-9 && (pr - rows[i]).abs() <= 0.5 / 1024.0 + 1e-9);
                }
            }
        }
    }
}
