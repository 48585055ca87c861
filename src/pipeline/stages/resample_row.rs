//! One output row of a chunk: its scan positions from the GCM (stepped
//! spans, or worked out exactly where a cell was refined), the kernel over
//! the scan's window, then what takes a pixel's value away (the scan's
//! holes, ground the sensor does not see) and the nodata value moved off
//! real samples.

use super::holes::ScanHoles;
use crate::dem::Lookup;
use crate::gcm::{BandGcm, Gcm};
use crate::geom::Span;
use crate::io::source::{SampleType, SourceImage, Window};
use crate::options::Occlusion;
use crate::pipeline::context::PixelOptions;
use crate::resample::area::{area_pixel, footprint_window, pixel_quad, AreaKind, AreaScratch, Covered};
use crate::resample::{resample_row, resample_spans, span_bounds, span_position, Kernel, Sample, SpanOutcome, View};
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

/// A ground point where the DEM had no height (under the `error` policy).
pub type Miss = (f64, f64, Lookup);

/// The value a sample holding the nodata value `v` is moved to: GDAL's
/// warper's choice, one up (one down at the top of the type; a float's
/// next one up).
pub fn off_nodata(v: f64, sample: SampleType) -> f64 {
    match sample {
        SampleType::U8 if v >= 255.0 => 254.0,
        SampleType::U16 if v >= 65535.0 => 65534.0,
        SampleType::F32 => {
            // f32::next_up, newer than the crate's Rust.
            let x = v as f32;
            f64::from(match x {
                _ if x.is_nan() || x == f32::INFINITY => x,
                0.0 => f32::from_bits(1),
                _ if x > 0.0 => f32::from_bits(x.to_bits() + 1),
                _ => f32::from_bits(x.to_bits() - 1),
            })
        }
        _ => v + 1.0,
    }
}

/// Makes the rows of one scan window (a chunk's, or a strip's of it).
pub(super) struct RowMaker<'a, T: Sample> {
    pub gcm: &'a Gcm<'a>,
    pub band: &'a BandGcm,
    pub src: &'a SourceImage,
    pub view: View<'a, T>,
    pub opts: &'a PixelOptions,
    pub holes: Option<&'a ScanHoles<'a>>,
    /// Where the kernel stays inside the window (or the window reaches the
    /// scan's edge, where clamping is the intended behaviour).
    pub safe: [f64; 4],
    pub fill: T,
    pub bands_in: usize,
    /// Whether the output's pixels are the scan's bands alone (no alpha
    /// band to say which have a value).
    pub direct: bool,
    /// The chunk's first column and row on the grid.
    pub x0: u32,
    pub y0: u32,
    /// Pixels worked out exactly; samples moved off the nodata value.
    pub exact: &'a AtomicU64,
    pub nudged: &'a AtomicU64,
}

/// What a task keeps from one row to the next: scan positions (made on
/// first need, not zeroed for every row), the GCM's spans, the area
/// kernels' corners.
#[derive(Default)]
pub(super) struct RowScratch {
    cols: Vec<f64>,
    rws: Vec<f64>,
    spans: Vec<Span>,
    feet: Footprints,
}

impl RowScratch {
    /// Room for the positions of `w` pixels.
    fn positions(&mut self, w: usize) {
        self.cols.resize(w, 0.0);
        self.rws.resize(w, 0.0);
    }
}

impl<T: Sample> RowMaker<'_, T> {
    /// Row `r` of the chunk, its pixels `cx` (chunk columns), into those of
    /// `px` and `valid`; a DEM miss under the `error` policy into `miss`.
    #[allow(clippy::too_many_arguments)] // the row, its pixels and the task's buffers
    pub fn make(&self, r: usize, cx: Range<usize>, s: &mut RowScratch, px: &mut [T], valid: &mut [bool], miss: &mut Option<Miss>) {
        let bands_in = self.bands_in;
        let (px, valid) = (&mut px[cx.start * bands_in..cx.end * bands_in], &mut valid[cx.clone()]);
        let (x0, w) = ((self.x0 + cx.start as u32) as usize, cx.len());
        let y = self.y0 + r as u32;
        let kernel = self.opts.kernel;
        let by_spans = kernel == Kernel::Bilinear && !self.view.is_empty() && self.gcm.row_spans(self.band, y, x0 as u32, w, &mut s.spans);
        if by_spans {
            self.by_spans(y, x0, w, s, px, valid, miss);
        } else if let Some(kind) = kernel.area() {
            self.by_area(kind, y, x0, w, s, px, valid, miss);
        } else {
            s.positions(w);
            self.exact.fetch_add(self.gcm.fill_row(self.band, y, x0 as u32, &mut s.cols, &mut s.rws, miss), Ordering::Relaxed);
            if resample_row(kernel, &self.view, &s.cols, &s.rws, px, valid, self.fill) {
                for (i, p) in px.chunks_exact_mut(bands_in).enumerate().filter(|(i, _)| valid[*i]) {
                    self.reread((s.cols[i], s.rws[i]), p);
                }
            }
        }
        if let (Some(h), None) = (self.holes, kernel.area()) {
            self.clear_holes(h, by_spans, x0, w, s, px, valid);
        }
        if let Some(seen) = &self.band.seen {
            // Ground the sensor does not see: no value (and, unless asked
            // to keep them, not the occluder's pixels either).
            let keep = self.opts.occlusion == Occlusion::Mask;
            for (i, p) in px.chunks_exact_mut(bands_in).enumerate() {
                if !seen.at((x0 + i) as u32, y) {
                    valid[i] = false;
                    if !keep {
                        p.fill(self.fill);
                    }
                }
            }
        }
        if self.opts.nudge {
            self.nudge(px, valid);
        }
    }

    fn is_safe(&self, (c, r): (f64, f64)) -> bool {
        let safe = &self.safe;
        c >= safe[0] && r >= safe[1] && c < safe[2] && r < safe[3]
    }

    /// A pixel whose kernel would leave the window, read from its own
    /// neighbourhood (rare; the plan adds a margin).
    fn reread(&self, at: (f64, f64), out: &mut [T]) {
        if !self.is_safe(at) {
            single_pixel(self.src, self.opts.kernel, at.0, at.1, out, self.fill);
        }
    }

    /// Bilinear along the GCM's spans: positions step in fixed point, runs
    /// of stepped spans in one call; the rest (refined cells) pixel by pixel.
    #[allow(clippy::too_many_arguments)] // the row and the task's buffers
    fn by_spans(&self, y: u32, x0: usize, w: usize, s: &mut RowScratch, px: &mut [T], valid: &mut [bool], miss: &mut Option<Miss>) {
        let bands_in = self.bands_in;
        let RowScratch { cols, rws, spans, .. } = s;
        for run in spans.chunk_by(|p, q| p.stepped == q.stepped) {
            let (first, end) = (run[0].first, run[run.len() - 1].end);
            let (a, b) = (first - x0, end - x0);
            let out: &mut [T] = &mut px[a * bands_in..b * bands_in];
            let valid = &mut valid[a..b];
            let stepped = run[0].stepped;
            let outcome = if stepped {
                resample_spans(&self.view, run, out, valid, self.fill)
            } else {
                cols.resize(w, 0.0);
                rws.resize(w, 0.0);
                let n = self.gcm.fill_exact(self.band, y, first as u32, &mut cols[a..b], &mut rws[a..b], miss);
                self.exact.fetch_add(n, Ordering::Relaxed);
                SpanOutcome::Checked { clamped: resample_row(self.opts.kernel, &self.view, &cols[a..b], &rws[a..b], out, valid, self.fill) }
            };
            if outcome == SpanOutcome::Inside && (!self.direct || self.opts.mask || self.holes.is_some() || self.opts.nudge) {
                // The alpha band or the mask below reads it.
                valid.fill(true);
            }
            if outcome == (SpanOutcome::Checked { clamped: true }) {
                for s in run {
                    // A stepped span whose bounds are safe is safe throughout.
                    if stepped && {
                        let b = span_bounds(s);
                        self.is_safe((b[0], b[1])) && self.is_safe((b[2], b[3]))
                    } {
                        continue;
                    }
                    for x in s.first..s.end {
                        let j = x - first;
                        if valid[j] {
                            let at = if stepped { span_position(s, x) } else { (cols[x - x0], rws[x - x0]) };
                            self.reread(at, &mut out[j * bands_in..(j + 1) * bands_in]);
                        }
                    }
                }
            }
        }
    }

    /// An area kernel (average, mode) over each output pixel's footprint.
    #[allow(clippy::too_many_arguments)] // the row and the task's buffers
    fn by_area(&self, kind: AreaKind, y: u32, x0: usize, w: usize, s: &mut RowScratch, px: &mut [T], valid: &mut [bool], miss: &mut Option<Miss>) {
        s.positions(w);
        let RowScratch { cols, rws, feet, .. } = s;
        self.exact.fetch_add(self.gcm.fill_row(self.band, y, x0 as u32, cols, rws, miss), Ordering::Relaxed);
        feet.corners(self.gcm, self.band, y, x0, w, miss);
        for (i, p) in px.chunks_exact_mut(self.bands_in).enumerate() {
            valid[i] = self.view.has_value(cols[i], rws[i]) && {
                let quad = pixel_quad((&feet.top.0, &feet.top.1), (&feet.bottom.0, &feet.bottom.1), i);
                let at = (cols[i], rws[i]);
                let (covered, read) = match area_pixel(kind, &self.view, &quad, p, &mut feet.scratch) {
                    Covered::Value => (true, Some(&quad)),
                    Covered::LeavesWindow => (single_footprint(self.src, kind, &quad, self.opts.area, p, &mut feet.scratch, at), Some(&quad)),
                    // No area (a degenerate corner): the scan at the centre.
                    Covered::Nothing => (nearest_at(&self.view, at, p, self.fill), None),
                };
                covered
                    && self.holes.is_none_or(|h| match read {
                        Some(quad) => h.clear_quad(&self.view, quad),
                        None => h.clear_pixel(&self.view, at),
                    })
            };
            if !valid[i] {
                p.fill(self.fill);
            }
        }
    }

    /// Pixels whose kernel reads the scan's holes: none.
    #[allow(clippy::too_many_arguments)] // the row and the task's buffers
    fn clear_holes(&self, h: &ScanHoles<'_>, by_spans: bool, x0: usize, w: usize, s: &RowScratch, px: &mut [T], valid: &mut [bool]) {
        let bands_in = self.bands_in;
        let mut clear = |i: usize, at: (f64, f64)| {
            if valid[i] && !h.clear_at(&self.view, at) {
                valid[i] = false;
                px[i * bands_in..(i + 1) * bands_in].fill(self.fill);
            }
        };
        if by_spans {
            for sp in s.spans.iter() {
                for x in sp.first..sp.end {
                    clear(x - x0, if sp.stepped { span_position(sp, x) } else { (s.cols[x - x0], s.rws[x - x0]) });
                }
            }
        } else {
            (0..w).for_each(|i| clear(i, (s.cols[i], s.rws[i])));
        }
    }

    /// Samples of pixels with a value that hold the nodata value, moved
    /// off it (as GDAL's warper does). Each run of pixels with a value is
    /// looked at whole (a compare without a branch, which the compiler
    /// vectorises; a whole row found at memchr's speed); the rare run that
    /// holds the value, sample by sample.
    fn nudge(&self, px: &mut [T], valid: &[bool]) {
        let (fill, bands_in) = (self.fill, self.bands_in);
        let mut moved = 0;
        let off = T::from_f32(off_nodata(f64::from(fill.to_f32()), T::TYPE) as f32);
        let mut nudge = |run: &mut [T]| {
            if run.iter().fold(false, |hit, &s| hit | (s == fill)) {
                for s in run.iter_mut().filter(|s| **s == fill) {
                    *s = off;
                    moved += 1;
                }
            }
        };
        let flags: &[u8] = bytemuck::cast_slice(valid);
        if !flags.contains(&0) {
            nudge(px);
        } else {
            let mut x = 0;
            while let Some(start) = valid[x..].iter().position(|&v| v).map(|p| x + p) {
                let end = valid[start..].iter().position(|&v| !v).map_or(valid.len(), |p| start + p);
                nudge(&mut px[start * bands_in..end * bands_in]);
                x = end;
            }
        }
        if moved > 0 {
            self.nudged.fetch_add(moved, Ordering::Relaxed);
        }
    }
}

/// The corners of a row's output pixels in the scan, along its top and
/// bottom edges, for the area kernels; and their scratch buffers.
#[derive(Default)]
struct Footprints {
    top: (Vec<f64>, Vec<f64>),
    bottom: (Vec<f64>, Vec<f64>),
    centres: (Vec<f64>, Vec<f64>),
    scratch: AreaScratch,
}

impl Footprints {
    /// Corners `x0..=x0 + w` of output row `y`: on each edge, half-way
    /// between the neighbouring pixels' positions on it (the same whatever
    /// the chunk, so results do not depend on where chunks begin); past the
    /// grid's first and last pixel, carried on straight.
    fn corners(&mut self, gcm: &Gcm<'_>, band: &crate::gcm::BandGcm, y: u32, x0: usize, w: usize, miss: &mut Option<Miss>) {
        let width = gcm.t.grid.width as usize;
        let (a, b) = (x0.saturating_sub(1), (x0 + w + 1).min(width));
        let (cc, cr) = &mut self.centres;
        for (v, (oc, or)) in [(y as f64, &mut self.top), (y as f64 + 1.0, &mut self.bottom)] {
            cc.resize(b - a, 0.0);
            cr.resize(b - a, 0.0);
            gcm.fill_exact_at(band, y, v, a as u32, cc, cr, miss);
            let p = |x: usize| (cc[x - a], cr[x - a]);
            oc.clear();
            or.clear();
            for x in x0..=x0 + w {
                let (c, r) = if x == 0 || x == width {
                    // An end: one pixel's centre and half its step on.
                    let (e, n) = if x == 0 { (0, 1) } else { (width - 1, width.saturating_sub(2)) };
                    let (pe, pn) = (p(e), if n < width && n != e { p(n) } else { p(e) });
                    (pe.0 + 0.5 * (pe.0 - pn.0), pe.1 + 0.5 * (pe.1 - pn.1))
                } else {
                    let (l, r) = (p(x - 1), p(x));
                    (0.5 * (l.0 + r.0), 0.5 * (l.1 + r.1))
                };
                oc.push(c);
                or.push(r);
            }
        }
    }
}

/// An area kernel's pixel from a window read just for its footprint;
/// whether it has a value.
fn single_footprint<T: Sample>(
    src: &SourceImage,
    kind: AreaKind,
    quad: &[[f64; 2]; 4],
    area: Option<crate::geom::ImageArea>,
    out: &mut [T],
    scratch: &mut AreaScratch,
    centre: (f64, f64),
) -> bool {
    let info = &src.info;
    let Some([c0, r0, c1, r1]) = footprint_window(quad, info.width as f64, info.height as f64) else {
        return false;
    };
    let mut win = Window::default();
    if src.read_window(c0 as u32, r0 as u32, (c1 - c0) as u32, (r1 - r0) as u32, &mut win).is_err() {
        return false;
    }
    let view = View::<T>::new(&win, info.bands, info.width, info.height).with_area(area);
    match area_pixel(kind, &view, quad, out, scratch) {
        Covered::Value => true,
        _ => nearest_at(&view, centre, out, T::default()),
    }
}

/// The scan pixel at `at` (a footprint without area); whether it has a value.
fn nearest_at<T: Sample>(view: &View<'_, T>, at: (f64, f64), out: &mut [T], fill: T) -> bool {
    let mut valid = [false];
    resample_row(Kernel::Nearest, view, &[at.0], &[at.1], out, &mut valid, fill);
    valid[0]
}

/// Resamples one pixel from a window read just for it.
fn single_pixel<T: Sample>(src: &SourceImage, kernel: Kernel, c: f64, r: f64, out: &mut [T], fill: T) {
    let info = &src.info;
    let rad = kernel.radius() as i64 + 1;
    let (ci, ri) = (c.floor() as i64, r.floor() as i64);
    let c0 = (ci - rad).clamp(0, info.width as i64) as u32;
    let r0 = (ri - rad).clamp(0, info.height as i64) as u32;
    let c1 = (ci + rad + 1).clamp(0, info.width as i64) as u32;
    let r1 = (ri + rad + 1).clamp(0, info.height as i64) as u32;
    let mut win = Window::default();
    if src.read_window(c0, r0, c1 - c0, r1 - r0, &mut win).is_err() {
        out.fill(fill);
        return;
    }
    let view = View::<T>::new(&win, info.bands, info.width, info.height);
    let mut valid = [false];
    resample_row(kernel, &view, &[c], &[r], out, &mut valid, fill);
}
