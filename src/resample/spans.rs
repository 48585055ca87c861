//! Spans: a run of output pixels whose scan positions step as a quadratic
//! (the GCM's `A + c` between two node columns), resampled bilinearly in
//! fixed point, with the fast paths of a span wholly inside the window.

use super::{bilinear_u8, gather_clamped, gather_inside, Gather, Sample, View, Weights};
use crate::geom::{floor_split, Span};
use crate::io::source::SampleType;

/// What [`resample_span`] leaves to its caller.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpanOutcome {
    /// Every pixel's neighbours lay inside the window: all have a value,
    /// and `valid` was not touched.
    Inside,
    /// Pixel by pixel: `valid` says which have a value; `clamped` as
    /// [`resample_row`] returns it.
    Checked { clamped: bool },
}

/// Whether the `n` pixels of a span from fixed-point position `q` in steps
/// of `dq`, the steps growing by `ddq` ([`span_fixed`]), can take the loop
/// with nothing to check per pixel: 8-bit RGB/RGBA whose four neighbours
/// all lie inside a window that lies in the scan (so every pixel has a
/// value), with the 8-byte loads inside the window's bytes: every
/// upper-left neighbour below `limits` ([`inside_limits`], worked out once
/// for the window).
#[inline(always)]
pub(super) fn span_is_inside<T: Sample, const B: usize>(view: &View<'_, T>, f: &Fixed, n: usize, (wl, hl): (u64, u64)) -> bool {
    if !(n > 0 && byte_loop_applies::<T, B>(view)) {
        return false;
    }
    // Each coordinate's least and greatest position: its ends', widened by
    // the most a quadratic strays from its chord (|ddq|·(n − 1)²/8, none
    // for a straight span); then the window-relative upper-left neighbour,
    // rounded as the weights are (to 1/1024 pixel): monotone, so these
    // bound every pixel between.
    let last = f.at(n as i64 - 1);
    let sag = |k: usize| f.ddq[k].unsigned_abs().saturating_mul(((n - 1) * (n - 1)) as u64).div_ceil(8).min(1 << 62) as i64;
    let index = |q: i64, o: i64| (q.wrapping_add(1 << 21) >> 32) - o;
    let (sc, sr) = if f.ddq == [0, 0] { (0, 0) } else { (sag(0), sag(1)) };
    let (qa, qb) = (
        [f.q[0].min(last[0]).wrapping_sub(sc), f.q[1].min(last[1]).wrapping_sub(sr)],
        [f.q[0].max(last[0]).wrapping_add(sc), f.q[1].max(last[1]).wrapping_add(sr)],
    );
    let (ia, ib, ja, jb) = (index(qa[0], view.x0), index(qb[0], view.x0), index(qa[1], view.y0), index(qb[1], view.y0));
    let in_window = ia <= ib && ja <= jb && (ia as u64) < wl && (ib as u64) < wl && (ja as u64) < hl && (jb as u64) < hl;
    // Inside the image area too, where there is one: the positions' box,
    // in the area's upright inner rectangle or else by the area's own test.
    let position = |q: i64| q as f64 / 4_294_967_296.0 + 0.5;
    let in_inner = |r: [i64; 4]| qa[0] >= r[0] && qa[1] >= r[1] && qb[0] <= r[2] && qb[1] <= r[3];
    in_window
        && view
            .area
            .is_none_or(|a| view.area_inner.is_some_and(in_inner) || a.contains_rect(position(qa[0]), position(qa[1]), position(qb[0]), position(qb[1])))
}

/// Whether [`bilinear_u8::span_inside`] can serve this window at all:
/// 8-bit RGB or RGBA, the window lying in the scan.
#[inline(always)]
pub(super) fn byte_loop_applies<T: Sample, const B: usize>(view: &View<'_, T>) -> bool {
    T::TYPE == SampleType::U8 && (B == 3 || B == 4) && view.in_scan
}

/// The bounds (columns, rows) below which the upper-left neighbour (i, j)
/// of a pixel must lie for [`bilinear_u8::span_inside`]: its right and
/// lower neighbours in the window (i < w − 1, j < h − 1), and the 8-byte
/// loads at any such column of row j + 1 inside the window's bytes:
/// (j + 1)·row + (w − 2)·B + 8 ≤ len, which a window's last row may fail
/// (its spans then take the checked path, with the same result).
pub(super) fn inside_limits<T: Sample, const B: usize>(view: &View<'_, T>) -> (u64, u64) {
    let (wl, hl) = ((view.w - 1).max(0) as u64, (view.h - 1).max(0) as u64);
    let row = view.stride.max(0) as u64 * B as u64;
    let len = std::mem::size_of_val(view.data) as u64;
    let farthest = wl.saturating_sub(1) * B as u64 + 8;
    let loads = if row == 0 { 0 } else { len.checked_sub(farthest).map_or(0, |room| room / row) };
    (wl, hl.min(loads))
}

/// Asks the processor to fetch the window's bytes at the upper-left
/// neighbour of pixel `n − 1` of a span, in its row and the next (a hint:
/// nothing where they lie outside the bytes, nothing off x86-64).
#[inline(always)]
pub(super) fn prefetch_corner<const B: usize>(view: &View<'_, impl Sample>, bytes: &[u8], row: usize, f: &Fixed, n: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        let last = f.at(n as i64 - 1);
        let at = |k: usize, o: i64| ((last[k].wrapping_add(1 << 21) >> 32) - o) as usize;
        let s = at(1, view.y0).wrapping_mul(row).wrapping_add(at(0, view.x0).wrapping_mul(B));
        if let Some(b) = bytes.get(s) {
            safe_arch::prefetch_t0(b);
        }
        if let Some(b) = bytes.get(s.wrapping_add(row)) {
            safe_arch::prefetch_t0(b);
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (view, bytes, row, f, n);
}

/// Bilinear along a stepped span of scan positions (output pixels
/// `span.first..span.end`, `B` bands each into `out`): the position steps
/// in fixed point with 32 fractional bits, by a step that itself steps by a
/// constant, counted from the span's anchor so that a pixel's value does
/// not depend on where a piece of the row starts. As [`resample_row`],
/// except that a span wholly inside the window leaves `valid` as it is
/// ([`SpanOutcome::Inside`]).
#[inline(always)]
pub fn bilinear_span<T: Sample, const B: usize>(view: &View<'_, T>, span: &Span, out: &mut [T], valid: &mut [bool], fill: T) -> SpanOutcome {
    let f = span_fixed(span, span.first);
    let n = out.len() / B;
    // 8-bit RGB/RGBA wholly inside the window (nearly every span): a loop
    // with nothing to check per pixel.
    // (The limits, with their division, only for a window the loop takes.)
    if byte_loop_applies::<T, B>(view) && span_is_inside::<T, B>(view, &f, n, inside_limits::<T, B>(view)) {
        let bytes: &[u8] = bytemuck::cast_slice(view.data);
        bilinear_u8::span_inside_any::<B>(bytes, view.stride as usize * B, (view.x0, view.y0), &f, bytemuck::cast_slice_mut(out));
        return SpanOutcome::Inside;
    }
    let Fixed { q: [mut qc, mut qr], dq: [mut dqc, mut dqr], ddq: [ddqc, ddqr] } = f;
    let half = 1i64 << 31;
    let (w_lim, h_lim) = ((view.img_w as i64) << 32, (view.img_h as i64) << 32);
    let (wl, hl) = ((view.w - 1).max(0) as u64, (view.h - 1).max(0) as u64);
    let src = Gather::new::<B>(view);
    let stride = view.stride as usize;
    let mut clamped = false;
    for (px, v) in out.chunks_exact_mut(B).zip(valid.iter_mut()) {
        let px: &mut [T; B] = px.try_into().expect("B samples");
        let (c, r) = (qc.wrapping_add(half), qr.wrapping_add(half));
        *v = c >= 0 && c < w_lim && r >= 0 && r < h_lim;
        if let Some(area) = &view.area {
            // The position, as the fixed point holds it.
            const ONE: f64 = 4_294_967_296.0;
            *v &= area.contains(c as f64 / ONE, r as f64 / ONE);
        }
        // In 1/1024 pixel, rounded: the fixed-point weights' resolution.
        let (fx, fy) = (qc.wrapping_add(1 << 21) >> 22, qr.wrapping_add(1 << 21) >> 22);
        qc = qc.wrapping_add(dqc);
        qr = qr.wrapping_add(dqr);
        dqc = dqc.wrapping_add(ddqc);
        dqr = dqr.wrapping_add(ddqr);
        if !*v {
            *px = [fill; B];
            continue;
        }
        let (i0, j0) = ((fx >> 10) - view.x0, (fy >> 10) - view.y0);
        let w = Weights::fixed((fx & 1023) as u32, (fy & 1023) as u32);
        if (i0 as u64) < wl && (j0 as u64) < hl {
            gather_inside(&src, (j0 as usize * stride + i0 as usize) * B, w, px);
        } else {
            clamped |= view.leaves_into_scan(i0, j0);
            gather_clamped(view, i0, j0, w, px);
        }
    }
    SpanOutcome::Checked { clamped }
}

/// A span's positions in fixed point, (position − ½)·2³² (the kernel's
/// origin), from one of its pixels on: the position `q` there, its step
/// `dq` to the next pixel, and the step's own step `ddq` (zero on a
/// straight span). Stepping by additions and [`Fixed::at`] give the same
/// integers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Fixed {
    pub q: [i64; 2],
    pub dq: [i64; 2],
    pub ddq: [i64; 2],
}

impl Fixed {
    /// The position `m` pixels on.
    #[inline(always)]
    pub fn at(&self, m: i64) -> [i64; 2] {
        if self.ddq == [0, 0] {
            return [self.q[0].wrapping_add(m.wrapping_mul(self.dq[0])), self.q[1].wrapping_add(m.wrapping_mul(self.dq[1]))];
        }
        let t = m.wrapping_mul(m.wrapping_sub(1)) / 2;
        let one = |k: usize| self.q[k].wrapping_add(m.wrapping_mul(self.dq[k])).wrapping_add(t.wrapping_mul(self.ddq[k]));
        [one(0), one(1)]
    }
}

/// [`Fixed`] at output pixel `x` of a span.
#[inline(always)]
pub(super) fn span_fixed(span: &Span, x: usize) -> Fixed {
    const ONE: f64 = 4_294_967_296.0;
    // Exact for what a stepped span holds (|v| < 2¹⁸, see `Gcm::row_spans`).
    let fixed = |v: f64| floor_split(v * ONE + 0.5).0;
    let skip = x as i64 - span.anchor as i64;
    let (q, dq) = ([fixed(span.c - 0.5), fixed(span.r - 0.5)], [fixed(span.dc), fixed(span.dr)]);
    if span.ddc == 0.0 && span.ddr == 0.0 {
        // A straight span (nearly all): no second differences to work out.
        let at = |k: usize| q[k].wrapping_add(skip.wrapping_mul(dq[k]));
        return Fixed { q: [at(0), at(1)], dq, ddq: [0, 0] };
    }
    let from_anchor = Fixed { q, dq, ddq: [fixed(span.ddc), fixed(span.ddr)] };
    let dq = |k: usize| from_anchor.dq[k].wrapping_add(skip.wrapping_mul(from_anchor.ddq[k]));
    Fixed { q: from_anchor.at(skip), dq: [dq(0), dq(1)], ddq: from_anchor.ddq }
}

/// The scan position [`bilinear_span`] resamples at output pixel `x` of a
/// span, to 1/1024 pixel: the same value there through [`resample_row`].
pub fn span_position(span: &Span, x: usize) -> (f64, f64) {
    let q = span_fixed(span, x).q;
    let to = |v: i64| (v.wrapping_add(1 << 21) >> 22) as f64 / 1024.0 + 0.5;
    (to(q[0]), to(q[1]))
}

/// A box (`[c_min, r_min, c_max, r_max]`) holding every position
/// [`span_position`] gives over the span's pixels.
pub fn span_bounds(span: &Span) -> [f64; 4] {
    // Span::bounds on the float positions, widened by the fixed point's
    // rounding (half of 1/1024 pixel) and the steps' (far below).
    let b = span.bounds();
    let e = 1.0 / 1024.0;
    [b[0] - e, b[1] - e, b[2] + e, b[3] + e]
}

#[cfg(any(test, feature = "internals"))]
/// [`bilinear_span`] for 1 to 4 bands.
pub fn resample_span<T: Sample>(view: &View<'_, T>, span: &Span, out: &mut [T], valid: &mut [bool], fill: T) -> SpanOutcome {
    resample_spans(view, std::slice::from_ref(span), out, valid, fill)
}

/// [`bilinear_span`] along consecutive stepped spans (a row or a piece of
/// one, as the GCM's `row_spans` makes them), into `out` and
/// `valid` from the first span's first pixel on: one call for the whole
/// run, so that the work per span stays small beside its ~16 pixels.
/// [`SpanOutcome::Inside`] when every span was; otherwise `valid` is
/// written for every pixel.
pub fn resample_spans<T: Sample>(view: &View<'_, T>, spans: &[Span], out: &mut [T], valid: &mut [bool], fill: T) -> SpanOutcome {
    match view.bands {
        1 => bilinear_spans::<T, 1>(view, spans, out, valid, fill),
        2 => bilinear_spans::<T, 2>(view, spans, out, valid, fill),
        3 => bilinear_spans::<T, 3>(view, spans, out, valid, fill),
        _ => bilinear_spans::<T, 4>(view, spans, out, valid, fill),
    }
}

pub(super) fn bilinear_spans<T: Sample, const B: usize>(view: &View<'_, T>, spans: &[Span], out: &mut [T], valid: &mut [bool], fill: T) -> SpanOutcome {
    let Some(x0) = spans.first().map(|s| s.first) else {
        return SpanOutcome::Inside;
    };
    let mut outcome = SpanOutcome::Inside;
    // Where `valid` is written: for every pixel once one span was checked.
    let merge = |outcome: SpanOutcome, here: SpanOutcome, valid: &mut [bool], (a, b): (usize, usize)| match (outcome, here) {
        (SpanOutcome::Inside, SpanOutcome::Inside) => outcome,
        (SpanOutcome::Inside, SpanOutcome::Checked { .. }) => {
            valid[..a].fill(true);
            here
        }
        (SpanOutcome::Checked { .. }, SpanOutcome::Inside) => {
            valid[a..b].fill(true);
            outcome
        }
        (SpanOutcome::Checked { clamped: before }, SpanOutcome::Checked { clamped }) => SpanOutcome::Checked { clamped: before || clamped },
    };
    if !(byte_loop_applies::<T, B>(view) && spans.len() > 1) {
        for span in spans {
            let (a, b) = (span.first - x0, span.end - x0);
            let here = bilinear_span::<T, B>(view, span, &mut out[a * B..b * B], &mut valid[a..b], fill);
            outcome = merge(outcome, here, valid, (a, b));
        }
        return outcome;
    }
    // 8-bit RGB/RGBA, spans a block at a time: first every span's fixed
    // point and whether it lies inside (no span waits for another, so these
    // overlap), then their pixel loops, each starting at once. Span by span,
    // every span's set-up (~40 cycles of dependent steps) waited for the
    // loop before it: 14 ns a span in `resample_rgb8/bilinear_span_run_varied`,
    // 10 ns this way.
    const BLOCK: usize = 32;
    let bytes: &[u8] = bytemuck::cast_slice(view.data);
    let row = view.stride as usize * B;
    let mut prepared = [(Fixed::default(), false); BLOCK];
    let limits = inside_limits::<T, B>(view);
    for block in spans.chunks(BLOCK) {
        for (p, span) in prepared.iter_mut().zip(block) {
            let f = span_fixed(span, span.first);
            let n = span.end.saturating_sub(span.first);
            *p = (f, span_is_inside::<T, B>(view, &f, n, limits));
            // The scan bytes at the span's last pixel, in both rows, asked
            // for now: its loop runs after the rest of the block's.
            prefetch_corner::<B>(view, bytes, row, &f, n);
        }
        for (&(f, inside), span) in prepared.iter().zip(block) {
            let (a, b) = (span.first - x0, span.end - x0);
            let here = if inside {
                bilinear_u8::span_inside_any::<B>(bytes, row, (view.x0, view.y0), &f, bytemuck::cast_slice_mut(&mut out[a * B..b * B]));
                SpanOutcome::Inside
            } else {
                bilinear_span::<T, B>(view, span, &mut out[a * B..b * B], &mut valid[a..b], fill)
            };
            outcome = merge(outcome, here, valid, (a, b));
        }
    }
    outcome
}
