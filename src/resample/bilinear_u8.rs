//! The bilinear kernel on 8-bit pixels of 3 or 4 interleaved bands, all
//! bands at once. One arithmetic for every path (SIMD or not, inside the
//! window or clamped at its edge), so that where a pixel is computed never
//! changes its value:
//!
//! * across: `top = a·(1024 − wx) + b·wx` (exact), rounded to 1/16:
//!   `t = (top + 8) >> 4` (≤ 16320, so it fits an i16);
//! * down: `(t·(1024 − wy) + t'·wy + 2¹⁵) >> 16`.
//!
//! The one intermediate rounding moves the result by at most 1/128 of a
//! grey level before the final rounding.
//!
//! The kernels for particular instruction sets are in `x86`, the choice
//! among them at run time in `dispatch`.

mod dispatch;
#[cfg(target_arch = "x86_64")]
mod x86;

use super::Fixed;

/// One band: `p00 p10` (upper row, left and right), `p01 p11` (lower row).
#[inline]
pub fn bilerp(p00: u8, p10: u8, p01: u8, p11: u8, wx: u32, wy: u32) -> u8 {
    let ax = 1024 - wx;
    let top = (p00 as u32 * ax + p10 as u32 * wx + 8) >> 4;
    let bot = (p01 as u32 * ax + p11 as u32 * wx + 8) >> 4;
    ((top * (1024 - wy) + bot * wy + (1 << 15)) >> 16) as u8
}

/// `(w << 16) | (1024 − w)` for every weight `w` in 1/1024 (0 to 1024):
/// the pair of 16-bit factors one multiply-add applies to a pair of samples.
const WEIGHT_PAIRS: [u32; 1025] = {
    let mut t = [0u32; 1025];
    let mut w = 0;
    while w <= 1024 {
        t[w] = ((w as u32) << 16) | (1024 - w as u32);
        w += 1;
    }
    t
};

/// All `B` (3 or 4) bands of one pixel from the two neighbouring pixels
/// of each row, `upper` and `lower`: each slice starts at the left pixel
/// and holds at least 8 bytes. Returns the bands in the low bytes.
///
/// The kernel every build has (SSE2 on x86-64, band by band elsewhere),
/// for the spans the checked path takes; the spans inside a window go
/// through [`span_inside_any`], which runs the best kernel the processor
/// has. All give the same bytes.
#[inline(always)]
pub fn bilerp_pixel<const B: usize>(upper: &[u8], lower: &[u8], wx: u32, wy: u32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    return x86::bilerp_pixel_sse2::<B>(upper, lower, wx, wy);
    #[cfg(not(target_arch = "x86_64"))]
    return bilerp_pixel_scalar::<B>(upper, lower, wx, wy);
}

/// [`bilerp_pixel`] band by band (other architectures, and the tests'
/// reference).
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
#[inline(always)]
fn bilerp_pixel_scalar<const B: usize>(upper: &[u8], lower: &[u8], wx: u32, wy: u32) -> u32 {
    let mut r = 0u32;
    for k in 0..B {
        r |= (bilerp(upper[k], upper[B + k], lower[k], lower[B + k], wx, wy) as u32) << (8 * k);
    }
    r
}

/// The loop over a run of `out.len() / B` pixels whose four neighbours all
/// lie inside `bytes` (rows `row` bytes apart), each made by the kernel
/// `$kernel` (as [`bilerp_pixel`]): pixel `i` at fixed-point position
/// `q + i·dq` (32 fractional bits, the kernel's origin: position − ½),
/// less the window's origin `origin` in whole pixels; where `$quadratic`,
/// the step `dq` itself steps by `ddq`. The caller has checked that the
/// span's bounds lie inside. A macro, written out in each kernel's own
/// function, so that a kernel compiled for other instructions inlines into
/// its loop (through a generic loop taking a closure it stayed a call a
/// pixel: 3.5 times slower).
macro_rules! span_loop {
    ($kernel:path, $b:ident, $bytes:expr, $row:expr, $origin:expr, $f:expr, $out:expr, $quadratic:expr) => {{
        let (bytes, row, f, out): (&[u8], usize, &Fixed, &mut [u8]) = ($bytes, $row, $f, $out);
        let (mut qc, mut qr) = (window_fixed(f.q[0], $origin.0), window_fixed(f.q[1], $origin.1));
        let ([mut dqc, mut dqr], [ddqc, ddqr]) = (f.dq, if $quadratic { f.ddq } else { [0, 0] });
        // Four bytes a pixel, also for three bands (the fourth is written
        // over by the next pixel), but for the last pixel.
        let body = out.len().saturating_sub($b);
        let mut o = 0;
        while o < body {
            let (s, wx, wy) = corner::<$b>(row, qc, qr);
            // Both rows' 8 bytes under one bounds check.
            let both = &bytes[s..s + row + 8];
            out[o..o + 4].copy_from_slice(&$kernel(&both[..8], &both[row..], wx, wy).to_le_bytes());
            qc = qc.wrapping_add(dqc);
            qr = qr.wrapping_add(dqr);
            dqc = dqc.wrapping_add(ddqc);
            dqr = dqr.wrapping_add(ddqr);
            o += $b;
        }
        if let Some(last) = out.get_mut(o..o + $b) {
            let (s, wx, wy) = corner::<$b>(row, qc, qr);
            let both = &bytes[s..s + row + 8];
            last.copy_from_slice(&$kernel(&both[..8], &both[row..], wx, wy).to_le_bytes()[..$b]);
        }
    }};
}
use span_loop;

/// A fixed-point position `q` counted from the window's origin `o` (whole
/// pixels: the fractions, and so the weights, stay as they are), plus half
/// of 1/1024 pixel, so that dropping the low 22 bits rounds to the weights'
/// resolution.
#[inline(always)]
fn window_fixed(q: i64, o: i64) -> i64 {
    q.wrapping_sub(o << 32).wrapping_add(1 << 21)
}

/// At window-relative fixed-point position (qc, qr) ([`window_fixed`]):
/// the byte of the upper-left neighbour (whole pixels above the 32
/// fractional bits) and the weights (1/1024 pixel: the fraction's top 10
/// bits).
#[inline(always)]
fn corner<const B: usize>(row: usize, qc: i64, qr: i64) -> (usize, u32, u32) {
    ((qr >> 32) as usize * row + (qc >> 32) as usize * B, qc as u32 >> 22, qr as u32 >> 22)
}

/// A span of 8-bit pixels wholly inside the window's `bytes` (see
/// [`span_loop`]; straight or quadratic as `f` is), by the best kernel
/// the processor has ([`crate::processor`]).
#[inline(always)]
pub fn span_inside_any<const B: usize>(bytes: &[u8], row: usize, origin: (i64, i64), f: &Fixed, out: &mut [u8]) {
    dispatch::span_inside::<B>(crate::processor::chosen(), bytes, row, origin, f, out)
}

/// [`span_inside_any`] with the kernel every build has.
#[inline(always)]
fn span_inside_portable<const B: usize>(bytes: &[u8], row: usize, origin: (i64, i64), f: &Fixed, out: &mut [u8]) {
    if f.ddq == [0, 0] {
        span_loop!(bilerp_pixel::<B>, B, bytes, row, origin, f, out, false)
    } else {
        quadratic_portable::<B>(bytes, row, origin, f, out)
    }
}

/// The quadratic span's loop apart (the straight one, which nearly every
/// span takes, keeps its registers).
#[inline(never)]
fn quadratic_portable<const B: usize>(bytes: &[u8], row: usize, origin: (i64, i64), f: &Fixed, out: &mut [u8]) {
    span_loop!(bilerp_pixel::<B>, B, bytes, row, origin, f, out, true)
}

#[cfg(test)]
mod tests {
    use super::dispatch;
    use crate::processor::{self, Kernels};
    use super::*;

    /// The exact bilinear value, for the bound on the one intermediate rounding.
    fn exact(p: [u8; 4], wx: u32, wy: u32) -> f64 {
        let (fx, fy) = (wx as f64 / 1024.0, wy as f64 / 1024.0);
        let top = p[0] as f64 * (1.0 - fx) + p[1] as f64 * fx;
        let bot = p[2] as f64 * (1.0 - fx) + p[3] as f64 * fx;
        top * (1.0 - fy) + bot * fy
    }

    #[test]
    fn one_band_is_within_half_a_level_and_a_128th_of_exact() {
        let mut seed = 12345u64;
        for _ in 0..200_000 {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let b = seed.to_le_bytes();
            let (wx, wy) = ((seed >> 40) as u32 % 1025, (seed >> 52) as u32 % 1025);
            let p = [b[0], b[1], b[2], b[3]];
            let got = bilerp(p[0], p[1], p[2], p[3], wx, wy) as f64;
            assert!((got - exact(p, wx, wy)).abs() <= 0.5 + 1.0 / 128.0, "{p:?} {wx} {wy}: {got}");
        }
        // Corners give the corner pixels; the middle of 0 and 255 rounds up.
        assert_eq!(bilerp(10, 20, 30, 40, 0, 0), 10);
        assert_eq!(bilerp(10, 20, 30, 40, 1024, 1024), 40);
        assert_eq!(bilerp(0, 255, 0, 255, 512, 0), 128);
    }

    /// `bilerp_pixel` (SSE2 on x86-64) against the band-by-band kernel,
    /// whole weights and the largest sums among the cases.
    #[test]
    fn all_bands_at_once_equal_band_by_band() {
        let mut seed = 99u64;
        let mut cases = Vec::new();
        for _ in 0..50_000 {
            let mut row = [[0u8; 8]; 2];
            for r in row.iter_mut() {
                seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                *r = seed.to_le_bytes();
            }
            cases.push((row, (seed >> 20) as u32 % 1025, (seed >> 40) as u32 % 1025));
        }
        // The extremes: all 255 (the largest sums), 0 beside 255, whole weights.
        for (w1, w2) in [(0, 0), (1024, 1024), (0, 1024), (1024, 0), (1023, 1), (512, 512)] {
            cases.push(([[255; 8], [255; 8]], w1, w2));
            cases.push(([[0, 0, 0, 255, 255, 255, 255, 0], [255, 255, 255, 0, 0, 0, 0, 255]], w1, w2));
        }
        for &(row, wx, wy) in &cases {
            let three = bilerp_pixel::<3>(&row[0], &row[1], wx, wy).to_le_bytes();
            let four = bilerp_pixel::<4>(&row[0], &row[1], wx, wy).to_le_bytes();
            assert_eq!(bilerp_pixel_scalar::<3>(&row[0], &row[1], wx, wy).to_le_bytes()[..3], three[..3]);
            assert_eq!(bilerp_pixel_scalar::<4>(&row[0], &row[1], wx, wy).to_le_bytes(), four);
            for k in 0..3 {
                assert_eq!(three[k], bilerp(row[0][k], row[0][3 + k], row[1][k], row[1][3 + k], wx, wy), "{row:?} {wx} {wy}");
            }
        }
    }

    /// Random spans (straight and quadratic, 1 to 40 pixels, 3 and 4
    /// bands) over random bytes with runs of 0 and 255, through each kernel
    /// this processor has: the bytes of the band-by-band loops.
    fn every_kernel_gives_the_scalar_bytes<const B: usize>() {
        let (w, h) = (64usize, 16usize);
        let row = w * B;
        let mut seed = 2024u64 + B as u64;
        let mut next = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            seed >> 11
        };
        let bytes: Vec<u8> = (0..h * row + 8)
            .map(|i| match (i / 97) % 5 {
                0 => 255,
                1 => 0,
                _ => (i as u64).wrapping_mul(2654435761) as u8,
            })
            .collect();
        let origin = (5i64, 3i64);
        let kernels: Vec<Kernels> = Kernels::ALL.into_iter().filter(|&k| k <= processor::best()).collect();
        if kernels.len() < 3 {
            eprintln!("this processor runs only {kernels:?}: the others not tried");
        }
        for case in 0..20_000 {
            let n = 1 + (next() % 40) as usize;
            let frac = |v: u64| (v % (1 << 32)) as i64;
            let q = [((origin.0 + 1 + (next() % 20) as i64) << 32) + frac(next()), ((origin.1 + 3 + (next() % 6) as i64) << 32) + frac(next())];
            let dq = [frac(next()), frac(next()) / 10 - (1 << 32) / 20];
            let ddq = if case % 3 == 0 { [frac(next()) / 2000 - (1 << 32) / 4000, frac(next()) / 2000 - (1 << 32) / 4000] } else { [0, 0] };
            let f = Fixed { q, dq, ddq };
            let mut want = vec![0u8; n * B];
            span_loop!(bilerp_pixel_scalar::<B>, B, &bytes, row, origin, &f, &mut want, true);
            for &k in &kernels {
                let mut got = vec![0u8; n * B];
                dispatch::span_inside::<B>(k, &bytes, row, origin, &f, &mut got);
                assert_eq!(got, want, "{k:?}, {B} bands, case {case}: {f:?}");
            }
        }
    }

    #[test]
    fn every_kernel_gives_the_scalar_bytes_for_three_and_four_bands() {
        every_kernel_gives_the_scalar_bytes::<3>();
        every_kernel_gives_the_scalar_bytes::<4>();
    }
}
