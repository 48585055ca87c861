//! Area kernels, for output pixels larger than the scan's: each output
//! pixel's footprint in the scan is the quadrilateral its four corners map
//! to, and every scan pixel counts by the share of it the footprint covers
//! (exact for the quadrilateral: the signed-area accumulation fonts are
//! drawn with). `average` is the covered scan's mean; `mode` the value
//! covering the most of it (classified rasters). Scan pixels without a
//! value (outside the scan or the image area, NaN) do not count.

use super::{Sample, View};
use ab_glyph_rasterizer::{point, Rasterizer};

/// Which area kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AreaKind {
    Average,
    Mode,
}

/// What became of one output pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Covered {
    /// It has a value.
    Value,
    /// Nothing under its footprint has a value.
    Nothing,
    /// Its footprint reaches past the window into the scan: read a window
    /// around it ([`footprint_window`]) and try again.
    LeavesWindow,
}

/// Buffers reused from pixel to pixel.
pub struct AreaScratch {
    raster: Rasterizer,
    sums: Vec<f64>,
    weights: Vec<f64>,
    /// Per band: (value, covered area) of the values met (`mode`).
    tally: Vec<Vec<(f32, f32)>>,
}

impl Default for AreaScratch {
    fn default() -> Self {
        AreaScratch { raster: Rasterizer::new(1, 1), sums: Vec::new(), weights: Vec::new(), tally: Vec::new() }
    }
}

/// Coverage smaller than this (a share of a scan pixel) is rounding.
const NO_COVER: f32 = 1e-6;

/// The whole pixels around a footprint, `[c0, r0, c1, r1)`, not clipped
/// to the scan; `None` if a corner is not a number.
fn pixels_around(quad: &[[f64; 2]; 4]) -> Option<[f64; 4]> {
    if quad.iter().flatten().any(|v| !v.is_finite()) {
        return None;
    }
    let lo = |k: usize| quad.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min).floor();
    let hi = |k: usize| quad.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max).ceil();
    Some([lo(0), lo(1), hi(0), hi(1)])
}

/// The scan pixels `[c0, r0, c1, r1)` a footprint touches, within the
/// scan of `w`×`h` pixels; `None` if it has no area there or a corner is
/// not a number.
#[must_use]
pub fn footprint_window(quad: &[[f64; 2]; 4], w: f64, h: f64) -> Option<[i64; 4]> {
    let [c0, r0, c1, r1] = pixels_around(quad)?;
    let (c0, r0, c1, r1) = (c0.max(0.0), r0.max(0.0), c1.min(w), r1.min(h));
    (c1 > c0 && r1 > r0).then_some([c0 as i64, r0 as i64, c1 as i64, r1 as i64])
}

/// Twice the signed area of a quadrilateral (its corners in order).
fn doubled_area(q: &[[f64; 2]; 4]) -> f64 {
    (0..4).map(|k| q[k][0] * q[(k + 1) % 4][1] - q[(k + 1) % 4][0] * q[k][1]).sum()
}

/// One output pixel of `view.bands` samples into `px`: the scan under the
/// quadrilateral `quad` (its corners in order around it, scan positions).
pub fn area_pixel<T: Sample>(kind: AreaKind, view: &View<'_, T>, quad: &[[f64; 2]; 4], px: &mut [T], s: &mut AreaScratch) -> Covered {
    let Some([c0, r0, c1, r1]) = footprint_window(quad, view.img_w, view.img_h) else {
        return Covered::Nothing;
    };
    if c0 < view.x0 || r0 < view.y0 || c1 > view.x0 + view.w || r1 > view.y0 + view.h {
        return Covered::LeavesWindow;
    }
    if doubled_area(quad).abs() < 1e-12 {
        return Covered::Nothing;
    }
    // Drawn relative to the whole pixels around the footprint (not clipped
    // to the scan, so the outline closes inside the raster), one column
    // spare for the accumulation's last step.
    let [ox, oy, ex, ey] = pixels_around(quad).expect("corners are numbers: the window says so");
    let (bw, bh) = ((ex - ox) as usize, (ey - oy) as usize);
    let stride = bw + 2;
    s.raster.reset(stride, bh);
    let at = |p: [f64; 2]| point((p[0] - ox) as f32, (p[1] - oy) as f32);
    for k in 0..4 {
        s.raster.draw_line(at(quad[k]), at(quad[(k + 1) % 4]));
    }
    let b = view.bands;
    s.sums.clear();
    s.sums.resize(b, 0.0);
    s.weights.clear();
    s.weights.resize(b, 0.0);
    if kind == AreaKind::Mode {
        s.tally.resize_with(b, Vec::new);
        s.tally.iter_mut().for_each(Vec::clear);
    }
    let (ox, oy) = (ox as i64, oy as i64);
    // The image area is convex: a footprint whose box lies in it needs no
    // test a pixel.
    let whole = view.area.is_none_or(|area| area.contains_rect(c0 as f64, r0 as f64, c1 as f64, r1 as f64));
    let (sums, weights, tally) = (&mut s.sums, &mut s.weights, &mut s.tally);
    // Cells come in order, row after row.
    let (mut ix, mut iy) = (0usize, 0i64);
    s.raster.for_each_pixel(|_, a| {
        let (c, r) = (ox + ix as i64, oy + iy);
        let inside = ix < bw;
        ix += 1;
        if ix == stride {
            (ix, iy) = (0, iy + 1);
        }
        if a < NO_COVER || !inside || c < c0 || c >= c1 || r < r0 || r >= r1 {
            return;
        }
        if !whole && !view.has_value(c as f64 + 0.5, r as f64 + 0.5) {
            return;
        }
        let at = ((r - view.y0) * view.stride + (c - view.x0)) as usize * b;
        for (band, v) in view.data[at..at + b].iter().enumerate() {
            let v = v.to_f32();
            if v.is_nan() {
                continue;
            }
            match kind {
                AreaKind::Average => {
                    sums[band] += a as f64 * v as f64;
                    weights[band] += a as f64;
                }
                AreaKind::Mode => {
                    let t = &mut tally[band];
                    match t.iter_mut().find(|(x, _)| *x == v) {
                        Some((_, w)) => *w += a,
                        None => t.push((v, a)),
                    }
                }
            }
        }
    });
    match kind {
        AreaKind::Average => {
            if weights.iter().all(|&w| w <= 0.0) {
                return Covered::Nothing;
            }
            for (p, (&sum, &w)) in px.iter_mut().zip(sums.iter().zip(weights.iter())) {
                *p = T::from_f32(if w > 0.0 { (sum / w) as f32 } else { f32::NAN });
            }
        }
        AreaKind::Mode => {
            if tally.iter().all(Vec::is_empty) {
                return Covered::Nothing;
            }
            for (p, t) in px.iter_mut().zip(tally.iter()) {
                // The most area; of equal areas, the smaller value.
                let best = t.iter().fold(None, |best: Option<(f32, f32)>, &(v, w)| match best {
                    Some((bv, bw)) if bw > w || (bw == w && bv <= v) => Some((bv, bw)),
                    _ => Some((v, w)),
                });
                *p = T::from_f32(best.map_or(f32::NAN, |(v, _)| v));
            }
        }
    }
    Covered::Value
}

/// The quadrilateral of output pixel `i` of a row, from the corners along
/// its top edge (`top`, `i` and `i + 1`) and bottom edge (`bottom`).
#[inline]
#[must_use]
pub fn pixel_quad(top: (&[f64], &[f64]), bottom: (&[f64], &[f64]), i: usize) -> [[f64; 2]; 4] {
    [[top.0[i], top.1[i]], [top.0[i + 1], top.1[i + 1]], [bottom.0[i + 1], bottom.1[i + 1]], [bottom.0[i], bottom.1[i]]]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::source::Window;

    /// A `w`×`h` one-band u8 view of `f(c, r)`.
    fn window(w: u32, h: u32, f: impl Fn(u32, u32) -> u8) -> Window {
        let data: Vec<u8> = (0..w * h).map(|k| f(k % w, k / w)).collect();
        Window::from_bytes(0, 0, w, h, &data)
    }

    fn quad(c0: f64, r0: f64, c1: f64, r1: f64) -> [[f64; 2]; 4] {
        [[c0, r0], [c1, r0], [c1, r1], [c0, r1]]
    }

    #[test]
    fn average_weights_each_pixel_by_the_share_covered() {
        let win = window(8, 8, |c, _| (c * 10) as u8);
        let view = View::<u8>::new(&win, 1, 8, 8);
        let mut s = AreaScratch::default();
        let mut px = [0u8];
        // Whole pixels 2..5: (20 + 30 + 40) / 3.
        assert_eq!(area_pixel(AreaKind::Average, &view, &quad(2.0, 1.0, 5.0, 4.0), &mut px, &mut s), Covered::Value);
        assert_eq!(px[0], 30);
        // Half of pixel 2, all of 3, a quarter of 4: (10 + 30 + 10) / 1.75.
        area_pixel(AreaKind::Average, &view, &quad(2.5, 1.0, 4.25, 2.0), &mut px, &mut s);
        assert_eq!(px[0], (50.0f32 / 1.75).round() as u8);
        // A diamond over a ramp: its mean is the ramp at its centre.
        let d = [[4.0, 1.0], [6.0, 3.0], [4.0, 5.0], [2.0, 3.0]];
        let fine = window(8, 8, |c, r| (c * 20 + r) as u8);
        let view = View::<u8>::new(&fine, 1, 8, 8);
        area_pixel(AreaKind::Average, &view, &d, &mut px, &mut s);
        // Ramp at (4, 3) in pixel units: each pixel holds its left edge's c·20 + r, i.e. the
        // value at its centre minus (10 + 0.5): 80 + 3 − 10.5.
        assert_eq!(px[0], (80.0f32 + 3.0 - 10.5).round() as u8);
    }

    #[test]
    fn mode_takes_the_value_covering_most() {
        let win = window(6, 6, |c, _| if c < 2 { 7 } else { 3 });
        let view = View::<u8>::new(&win, 1, 6, 6);
        let (mut s, mut px) = (AreaScratch::default(), [0u8]);
        // 1.5 columns of 7, 1 of 3: 7.
        area_pixel(AreaKind::Mode, &view, &quad(0.5, 0.0, 3.0, 2.0), &mut px, &mut s);
        assert_eq!(px[0], 7);
        // 0.5 of 7, 2 of 3: 3.
        area_pixel(AreaKind::Mode, &view, &quad(1.5, 0.0, 4.0, 2.0), &mut px, &mut s);
        assert_eq!(px[0], 3);
    }

    #[test]
    fn outside_the_scan_and_the_window_is_told() {
        let win = window(4, 4, |_, _| 100);
        let view = View::<u8>::new(&win, 1, 4, 4);
        let (mut s, mut px) = (AreaScratch::default(), [0u8]);
        // Half over the scan's edge: the part inside counts alone.
        assert_eq!(area_pixel(AreaKind::Average, &view, &quad(-1.0, 0.0, 1.0, 2.0), &mut px, &mut s), Covered::Value);
        assert_eq!(px[0], 100);
        assert_eq!(area_pixel(AreaKind::Average, &view, &quad(-3.0, 0.0, -1.0, 2.0), &mut px, &mut s), Covered::Nothing);
        // A window of part of a larger scan: past its edge into the scan.
        let view = View::<u8>::new(&win, 1, 40, 40);
        assert_eq!(area_pixel(AreaKind::Average, &view, &quad(3.0, 0.0, 5.0, 2.0), &mut px, &mut s), Covered::LeavesWindow);
    }
}
