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
/// The SSSE3 + SSE4.1 kernel where the build has them (x86-64-v2, what
/// the project builds for: `.cargo/config.toml`), else the SSE2 one, else
/// band by band. All give the same bytes.
#[inline(always)]
pub fn bilerp_pixel<const B: usize>(upper: &[u8], lower: &[u8], wx: u32, wy: u32) -> u32 {
    #[cfg(all(target_arch = "x86_64", target_feature = "ssse3", target_feature = "sse4.1"))]
    return bilerp_pixel_ssse3::<B>(upper, lower, wx, wy);
    #[cfg(all(target_arch = "x86_64", not(all(target_feature = "ssse3", target_feature = "sse4.1"))))]
    return bilerp_pixel_sse2::<B>(upper, lower, wx, wy);
    #[cfg(not(target_arch = "x86_64"))]
    return bilerp_pixel_scalar::<B>(upper, lower, wx, wy);
}

/// [`bilerp_pixel`] with SSSE3 and SSE4.1: byte shuffles put each band's
/// left and right samples side by side in 16-bit lanes, a blend pairs the
/// rows' sums, and one shuffle takes the results out: 17 vector steps
/// where plain SSE2 takes 25.
#[cfg(all(target_arch = "x86_64", target_feature = "ssse3", target_feature = "sse4.1"))]
#[inline(always)]
fn bilerp_pixel_ssse3<const B: usize>(upper: &[u8], lower: &[u8], wx: u32, wy: u32) -> u32 {
    use safe_arch::*;
    let word = |s: &[u8]| i64::from_le_bytes(s[..8].try_into().expect("8 bytes"));
    // Upper row in the low 8 bytes, lower row in the high 8: [a0 a1 a2 b0 …].
    let v = set_i64_m128i(word(lower), word(upper));
    // Lane k (16-bit pairs): band k of the left pixel, band k of the right
    // one (3 or 4 bytes on), zero-extended; -1 gives a zero byte.
    const fn pairs(b: i8, row: i8) -> [i8; 16] {
        let mut t = [-1i8; 16];
        let mut k = 0;
        while k < b {
            t[4 * k as usize] = row + k;
            t[4 * k as usize + 2] = row + b + k;
            k += 1;
        }
        t
    }
    let (pu, pl) = if B == 3 { (pairs(3, 0), pairs(3, 8)) } else { (pairs(4, 0), pairs(4, 8)) };
    let u = shuffle_av_i8z_all_m128i(v, m128i::from(pu));
    let l = shuffle_av_i8z_all_m128i(v, m128i::from(pl));
    let wx2 = set_splat_i32_m128i(WEIGHT_PAIRS[(wx as usize).min(1024)] as i32);
    let eight = set_splat_i32_m128i(8);
    let top = shr_imm_u32_m128i::<4>(add_i32_m128i(mul_i16_horizontal_add_m128i(u, wx2), eight));
    // (bot + 8) >> 4 in the high half of each lane: bits 16 and up of
    // (bot + 8) << 12; the low half from `top` (below 2¹⁵).
    let bot = shl_imm_u32_m128i::<12>(add_i32_m128i(mul_i16_horizontal_add_m128i(l, wx2), eight));
    let tb = blend_imm_i16_m128i::<0b1010_1010>(top, bot);
    let wy2 = set_splat_i32_m128i(WEIGHT_PAIRS[(wy as usize).min(1024)] as i32);
    let r = add_i32_m128i(mul_i16_horizontal_add_m128i(tb, wy2), set_splat_i32_m128i(1 << 15));
    // The result is bits 16–23 of each lane (below 2²⁴ all told).
    const OUT: [i8; 16] = [2, 6, 10, 14, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1];
    get_i32_from_m128i_s(shuffle_av_i8z_all_m128i(r, m128i::from(OUT))) as u32
}

/// [`bilerp_pixel`] with plain SSE2 (any x86-64).
#[cfg(target_arch = "x86_64")]
#[cfg_attr(all(target_feature = "ssse3", target_feature = "sse4.1"), allow(dead_code))]
#[inline(always)]
fn bilerp_pixel_sse2<const B: usize>(upper: &[u8], lower: &[u8], wx: u32, wy: u32) -> u32 {
    use safe_arch::*;
    let word = |s: &[u8]| i64::from_le_bytes(s[..8].try_into().expect("8 bytes"));
    // Upper row in the low 8 bytes, lower row in the high 8: [a0 a1 a2 b0 …].
    let v = set_i64_m128i(word(lower), word(upper));
    // Each row shifted by one pixel, so that interleaving the bytes pairs
    // every band of the left pixel with the same band of the right one:
    // [a0 b0 a1 b1 a2 b2 …], then widened to 16-bit lanes (a_k, b_k).
    let right = if B == 3 { shr_imm_u64_m128i::<24>(v) } else { shr_imm_u64_m128i::<32>(v) };
    let zero = zeroed_m128i();
    let u = unpack_low_i8_m128i(unpack_low_i8_m128i(v, right), zero);
    let l = unpack_low_i8_m128i(unpack_high_i8_m128i(v, right), zero);
    let wx2 = set_splat_i32_m128i(WEIGHT_PAIRS[(wx as usize).min(1024)] as i32);
    let eight = set_splat_i32_m128i(8);
    let top = shr_imm_u32_m128i::<4>(add_i32_m128i(mul_i16_horizontal_add_m128i(u, wx2), eight));
    let bot = shr_imm_u32_m128i::<4>(add_i32_m128i(mul_i16_horizontal_add_m128i(l, wx2), eight));
    // Both below 2¹⁵: one 32-bit lane holds the pair (top, bot).
    let tb = bitor_m128i(top, shl_imm_u32_m128i::<16>(bot));
    let wy2 = set_splat_i32_m128i(WEIGHT_PAIRS[(wy as usize).min(1024)] as i32);
    let r = shr_imm_u32_m128i::<16>(add_i32_m128i(mul_i16_horizontal_add_m128i(tb, wy2), set_splat_i32_m128i(1 << 15)));
    let r16 = pack_i32_to_i16_m128i(r, r);
    get_i32_from_m128i_s(pack_i16_to_u8_m128i(r16, r16)) as u32
}

/// [`bilerp_pixel`] band by band (other architectures).
#[cfg_attr(target_arch = "x86_64", allow(dead_code))]
#[inline(always)]
fn bilerp_pixel_scalar<const B: usize>(upper: &[u8], lower: &[u8], wx: u32, wy: u32) -> u32 {
    let mut r = 0u32;
    for k in 0..B {
        r |= (bilerp(upper[k], upper[B + k], lower[k], lower[B + k], wx, wy) as u32) << (8 * k);
    }
    r
}

/// A straight run of `out.len() / B` pixels whose four neighbours all lie
/// inside `bytes` (rows `row` bytes apart): pixel `i` at fixed-point
/// position `q + i·dq` (32 fractional bits, the kernel's origin: position
/// − ½), less the window's origin `origin` in whole pixels. The caller has
/// checked that the span's bounds lie inside. Same arithmetic as
/// [`bilerp_pixel`].
#[inline(always)]
pub fn span_inside<const B: usize>(bytes: &[u8], row: usize, origin: (i64, i64), q: (i64, i64), dq: (i64, i64), out: &mut [u8]) {
    let (mut qc, mut qr) = (window_fixed(q.0, origin.0), window_fixed(q.1, origin.1));
    let pixel = |qc: i64, qr: i64| pixel_at::<B>(bytes, row, qc, qr);
    // Four bytes a pixel, also for three bands (the fourth is written over
    // by the next pixel), but for the last pixel.
    let body = out.len().saturating_sub(B);
    let mut o = 0;
    while o < body {
        out[o..o + 4].copy_from_slice(&pixel(qc, qr).to_le_bytes());
        qc = qc.wrapping_add(dq.0);
        qr = qr.wrapping_add(dq.1);
        o += B;
    }
    if let Some(last) = out.get_mut(o..o + B) {
        last.copy_from_slice(&pixel(qc, qr).to_le_bytes()[..B]);
    }
}

/// [`span_inside`] for a quadratic span: the step `dq` itself steps by
/// `ddq` from one pixel to the next (a separate loop: the straight one,
/// which nearly every span takes, keeps its registers).
#[inline(never)]
pub fn span_inside_quadratic<const B: usize>(bytes: &[u8], row: usize, origin: (i64, i64), f: &super::Fixed, out: &mut [u8]) {
    let (mut qc, mut qr) = (window_fixed(f.q[0], origin.0), window_fixed(f.q[1], origin.1));
    let ([mut dqc, mut dqr], [ddqc, ddqr]) = (f.dq, f.ddq);
    let pixel = |qc: i64, qr: i64| pixel_at::<B>(bytes, row, qc, qr);
    let body = out.len().saturating_sub(B);
    let mut o = 0;
    while o < body {
        out[o..o + 4].copy_from_slice(&pixel(qc, qr).to_le_bytes());
        qc = qc.wrapping_add(dqc);
        qr = qr.wrapping_add(dqr);
        dqc = dqc.wrapping_add(ddqc);
        dqr = dqr.wrapping_add(ddqr);
        o += B;
    }
    if let Some(last) = out.get_mut(o..o + B) {
        last.copy_from_slice(&pixel(qc, qr).to_le_bytes()[..B]);
    }
}

/// A fixed-point position `q` counted from the window's origin `o` (whole
/// pixels: the fractions, and so the weights, stay as they are), plus half
/// of 1/1024 pixel, so that dropping the low 22 bits rounds to the weights'
/// resolution.
#[inline(always)]
fn window_fixed(q: i64, o: i64) -> i64 {
    q.wrapping_sub(o << 32).wrapping_add(1 << 21)
}

/// The pixel at window-relative fixed-point position (qc, qr)
/// ([`window_fixed`]): whole pixels above the 32 fractional bits, the
/// weights (1/1024 pixel) the fraction's top 10 bits.
#[inline(always)]
fn pixel_at<const B: usize>(bytes: &[u8], row: usize, qc: i64, qr: i64) -> u32 {
    let s = (qr >> 32) as usize * row + (qc >> 32) as usize * B;
    let (wx, wy) = (qc as u32 >> 22, qr as u32 >> 22);
    // Both rows' 8 bytes under one bounds check.
    let both = &bytes[s..s + row + 8];
    bilerp_pixel::<B>(&both[..8], &both[row..], wx, wy)
}

/// [`span_inside`] or [`span_inside_quadratic`], as the span is.
#[inline(always)]
pub fn span_inside_any<const B: usize>(bytes: &[u8], row: usize, origin: (i64, i64), f: &super::Fixed, out: &mut [u8]) {
    if f.ddq == [0, 0] {
        span_inside::<B>(bytes, row, origin, (f.q[0], f.q[1]), (f.dq[0], f.dq[1]), out)
    } else {
        span_inside_quadratic::<B>(bytes, row, origin, f, out)
    }
}

#[cfg(test)]
mod tests {
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

    /// A kernel for one band count: (upper, lower, wx, wy) → bands.
    type Kernel = fn(&[u8], &[u8], u32, u32) -> u32;

    /// Every kernel this build compiles, for 3 and 4 bands.
    fn kernels() -> Vec<(&'static str, Kernel, Kernel)> {
        let mut k: Vec<(&'static str, Kernel, Kernel)> =
            vec![("scalar", bilerp_pixel_scalar::<3>, bilerp_pixel_scalar::<4>), ("chosen", bilerp_pixel::<3>, bilerp_pixel::<4>)];
        #[cfg(target_arch = "x86_64")]
        k.push(("sse2", bilerp_pixel_sse2::<3>, bilerp_pixel_sse2::<4>));
        #[cfg(all(target_arch = "x86_64", target_feature = "ssse3", target_feature = "sse4.1"))]
        k.push(("ssse3", bilerp_pixel_ssse3::<3>, bilerp_pixel_ssse3::<4>));
        k
    }

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
        for (name, k3, k4) in kernels() {
            for &(row, wx, wy) in &cases {
                let three = k3(&row[0], &row[1], wx, wy).to_le_bytes();
                let four = k4(&row[0], &row[1], wx, wy).to_le_bytes();
                for k in 0..3 {
                    assert_eq!(three[k], bilerp(row[0][k], row[0][3 + k], row[1][k], row[1][3 + k], wx, wy), "{name} {row:?} {wx} {wy}");
                }
                for k in 0..4 {
                    assert_eq!(four[k], bilerp(row[0][k], row[0][4 + k], row[1][k], row[1][4 + k], wx, wy), "{name} {row:?} {wx} {wy}");
                }
            }
        }
    }
}
