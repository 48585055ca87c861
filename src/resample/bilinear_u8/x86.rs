//! The x86-64 kernels of [`super`], each the same arithmetic as
//! [`super::bilerp`]: plain SSE2 (every x86-64, so always compiled in),
//! SSSE3 + SSE4.1 and AVX2, the last two compiled for those instructions
//! whatever the build's target and run only where the processor has them
//! (`super::dispatch`).

use super::{corner, span_loop, window_fixed, WEIGHT_PAIRS};
use crate::resample::Fixed;
use core::arch::x86_64::*;

/// Eight bytes from the start of `s` as one 64-bit lane.
#[inline(always)]
fn word(s: &[u8]) -> i64 {
    i64::from_le_bytes(s[..8].try_into().expect("8 bytes"))
}

/// The 16-bit weight pairs of `w` (1/1024) in one 32-bit lane.
#[inline(always)]
fn weight_pair(w: u32) -> i32 {
    WEIGHT_PAIRS[(w as usize).min(1024)] as i32
}

/// [`super::bilerp_pixel`] with plain SSE2.
#[inline(always)]
pub(super) fn bilerp_pixel_sse2<const B: usize>(upper: &[u8], lower: &[u8], wx: u32, wy: u32) -> u32 {
    use safe_arch::*;
    // Upper row in the low 8 bytes, lower row in the high 8: [a0 a1 a2 b0 …].
    let v = set_i64_m128i(word(lower), word(upper));
    // Each row shifted by one pixel, so that interleaving the bytes pairs
    // every band of the left pixel with the same band of the right one:
    // [a0 b0 a1 b1 a2 b2 …], then widened to 16-bit lanes (a_k, b_k).
    let right = if B == 3 { shr_imm_u64_m128i::<24>(v) } else { shr_imm_u64_m128i::<32>(v) };
    let zero = zeroed_m128i();
    let u = unpack_low_i8_m128i(unpack_low_i8_m128i(v, right), zero);
    let l = unpack_low_i8_m128i(unpack_high_i8_m128i(v, right), zero);
    let wx2 = set_splat_i32_m128i(weight_pair(wx));
    let eight = set_splat_i32_m128i(8);
    let top = shr_imm_u32_m128i::<4>(add_i32_m128i(mul_i16_horizontal_add_m128i(u, wx2), eight));
    let bot = shr_imm_u32_m128i::<4>(add_i32_m128i(mul_i16_horizontal_add_m128i(l, wx2), eight));
    // Both below 2¹⁵: one 32-bit lane holds the pair (top, bot).
    let tb = bitor_m128i(top, shl_imm_u32_m128i::<16>(bot));
    let wy2 = set_splat_i32_m128i(weight_pair(wy));
    let r = shr_imm_u32_m128i::<16>(add_i32_m128i(mul_i16_horizontal_add_m128i(tb, wy2), set_splat_i32_m128i(1 << 15)));
    let r16 = pack_i32_to_i16_m128i(r, r);
    get_i32_from_m128i_s(pack_i16_to_u8_m128i(r16, r16)) as u32
}

/// Byte shuffle moving band k of the left pixel and of the right one (`b`
/// bytes on) of the row starting at byte `row` into 16-bit lane k's two
/// halves, zero-extended (−1 gives a zero byte); as two 64-bit halves.
const fn pairs(b: i8, row: i8) -> (i64, i64) {
    let mut t = [-1i8; 16];
    let mut k = 0;
    while k < b {
        t[4 * k as usize] = row + k;
        t[4 * k as usize + 2] = row + b + k;
        k += 1;
    }
    halves(t)
}

/// A 16-byte shuffle as its low and high 64-bit halves.
const fn halves(t: [i8; 16]) -> (i64, i64) {
    let (mut lo, mut hi) = (0i64, 0i64);
    let mut k = 0;
    while k < 8 {
        lo |= (t[k] as u8 as i64) << (8 * k);
        hi |= (t[k + 8] as u8 as i64) << (8 * k);
        k += 1;
    }
    (lo, hi)
}

/// The shuffles of the upper and the lower row for `B` bands.
const fn row_shuffles<const B: usize>() -> ((i64, i64), (i64, i64)) {
    if B == 3 {
        (pairs(3, 0), pairs(3, 8))
    } else {
        (pairs(4, 0), pairs(4, 8))
    }
}

/// [`row_shuffles`] as constants (a `const fn` called where it runs is a
/// call a pixel).
struct Shuffles<const B: usize>;
impl<const B: usize> Shuffles<B> {
    const ROWS: ((i64, i64), (i64, i64)) = row_shuffles::<B>();
}

/// Bits 16–23 of each 32-bit lane (the results) into the low 4 bytes.
const OUT: (i64, i64) = halves([2, 6, 10, 14, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1]);

/// [`super::bilerp_pixel`] with SSSE3 and SSE4.1: byte shuffles put each
/// band's left and right samples side by side in 16-bit lanes, a blend
/// pairs the rows' sums, and one shuffle takes the results out: 17 vector
/// steps where plain SSE2 takes 25.
#[target_feature(enable = "ssse3,sse4.1")]
#[inline]
pub(super) fn bilerp_pixel_ssse3<const B: usize>(upper: &[u8], lower: &[u8], wx: u32, wy: u32) -> u32 {
    let v = _mm_set_epi64x(word(lower), word(upper));
    let (pu, pl) = Shuffles::<B>::ROWS;
    let u = _mm_shuffle_epi8(v, _mm_set_epi64x(pu.1, pu.0));
    let l = _mm_shuffle_epi8(v, _mm_set_epi64x(pl.1, pl.0));
    let wx2 = _mm_set1_epi32(weight_pair(wx));
    let eight = _mm_set1_epi32(8);
    let top = _mm_srli_epi32::<4>(_mm_add_epi32(_mm_madd_epi16(u, wx2), eight));
    // (bot + 8) >> 4 in the high half of each lane: bits 16 and up of
    // (bot + 8) << 12; the low half from `top` (below 2¹⁵).
    let bot = _mm_slli_epi32::<12>(_mm_add_epi32(_mm_madd_epi16(l, wx2), eight));
    let tb = _mm_blend_epi16::<0b1010_1010>(top, bot);
    let wy2 = _mm_set1_epi32(weight_pair(wy));
    let r = _mm_add_epi32(_mm_madd_epi16(tb, wy2), _mm_set1_epi32(1 << 15));
    _mm_cvtsi128_si32(_mm_shuffle_epi8(r, _mm_set_epi64x(OUT.1, OUT.0))) as u32
}

/// [`bilerp_pixel_ssse3`] for two pixels at once, one in each 128-bit
/// half: `a` and `b` start at each one's upper-left neighbour, their lower
/// rows `row` bytes on.
#[target_feature(enable = "avx2")]
#[inline]
fn bilerp_pixels_avx2<const B: usize>(a: &[u8], b: &[u8], row: usize, (wxa, wya): (u32, u32), (wxb, wyb): (u32, u32)) -> (u32, u32) {
    let v = _mm256_set_epi64x(word(&b[row..]), word(b), word(&a[row..]), word(a));
    let (pu, pl) = Shuffles::<B>::ROWS;
    let u = _mm256_shuffle_epi8(v, _mm256_set_epi64x(pu.1, pu.0, pu.1, pu.0));
    let l = _mm256_shuffle_epi8(v, _mm256_set_epi64x(pl.1, pl.0, pl.1, pl.0));
    let both = |wa: u32, wb: u32| {
        let (wa, wb) = (weight_pair(wa), weight_pair(wb));
        _mm256_set_epi32(wb, wb, wb, wb, wa, wa, wa, wa)
    };
    let wx2 = both(wxa, wxb);
    let eight = _mm256_set1_epi32(8);
    let top = _mm256_srli_epi32::<4>(_mm256_add_epi32(_mm256_madd_epi16(u, wx2), eight));
    let bot = _mm256_slli_epi32::<12>(_mm256_add_epi32(_mm256_madd_epi16(l, wx2), eight));
    let tb = _mm256_blend_epi16::<0b1010_1010>(top, bot);
    let r = _mm256_add_epi32(_mm256_madd_epi16(tb, both(wya, wyb)), _mm256_set1_epi32(1 << 15));
    let out = _mm256_shuffle_epi8(r, _mm256_set_epi64x(OUT.1, OUT.0, OUT.1, OUT.0));
    (_mm256_extract_epi32::<0>(out) as u32, _mm256_extract_epi32::<4>(out) as u32)
}

/// [`super::span_inside_any`] with the SSSE3 kernel.
#[target_feature(enable = "ssse3,sse4.1")]
pub(super) fn span_inside_ssse3<const B: usize>(bytes: &[u8], row: usize, origin: (i64, i64), f: &Fixed, out: &mut [u8]) {
    if f.ddq == [0, 0] {
        span_loop!(bilerp_pixel_ssse3::<B>, B, bytes, row, origin, f, out, false)
    } else {
        quadratic_ssse3::<B>(bytes, row, origin, f, out)
    }
}

/// The quadratic span's loop apart (the straight one, which nearly every
/// span takes, keeps its registers).
#[target_feature(enable = "ssse3,sse4.1")]
#[inline(never)]
fn quadratic_ssse3<const B: usize>(bytes: &[u8], row: usize, origin: (i64, i64), f: &Fixed, out: &mut [u8]) {
    span_loop!(bilerp_pixel_ssse3::<B>, B, bytes, row, origin, f, out, true)
}

/// [`super::span_inside_any`] with the AVX2 kernel: a straight span two
/// pixels a step, then the SSSE3 kernel (the same bytes) for the rest.
#[target_feature(enable = "avx2")]
pub(super) fn span_inside_avx2<const B: usize>(bytes: &[u8], row: usize, origin: (i64, i64), f: &Fixed, out: &mut [u8]) {
    if f.ddq != [0, 0] {
        return quadratic_ssse3::<B>(bytes, row, origin, f, out);
    }
    let (mut qc, mut qr) = (window_fixed(f.q[0], origin.0), window_fixed(f.q[1], origin.1));
    let (dqc, dqr) = (f.dq[0], f.dq[1]);
    // As `span_loop`: four bytes a pixel but for the last; pairs while
    // both are before it.
    let body = out.len().saturating_sub(B);
    let mut o = 0;
    while o + B < body {
        let (qc1, qr1) = (qc.wrapping_add(dqc), qr.wrapping_add(dqr));
        let ((sa, wxa, wya), (sb, wxb, wyb)) = (corner::<B>(row, qc, qr), corner::<B>(row, qc1, qr1));
        let (a, b) = (&bytes[sa..sa + row + 8], &bytes[sb..sb + row + 8]);
        let (pa, pb) = bilerp_pixels_avx2::<B>(a, b, row, (wxa, wya), (wxb, wyb));
        out[o..o + 4].copy_from_slice(&pa.to_le_bytes());
        out[o + B..o + B + 4].copy_from_slice(&pb.to_le_bytes());
        qc = qc1.wrapping_add(dqc);
        qr = qr1.wrapping_add(dqr);
        o += 2 * B;
    }
    // The rest from pixel o/B on, at (qc, qr).
    let rest = Fixed { q: [qc.wrapping_sub(1 << 21), qr.wrapping_sub(1 << 21)], dq: f.dq, ddq: [0, 0] };
    span_loop!(bilerp_pixel_ssse3::<B>, B, bytes, row, (0i64, 0i64), &rest, &mut out[o..], false)
}
