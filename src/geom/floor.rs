//! Floors without a libm call, for the per-pixel loops (resampling, DEM
//! and texture lookups).

/// `floor` without a libm call (x86-64 has no rounding instruction before
/// SSE4.1); exact for |x| < 2⁶³.
#[inline(always)]
pub fn floor_i64(x: f64) -> i64 {
    let i = x as i64;
    i - i64::from((i as f64) > x)
}

/// `⌊x⌋` as an integer and as a float, exact for |x| < 2⁵¹ (NaN gives
/// garbage, not a panic). Adding 1.5·2⁵² rounds x to an integer that then
/// sits in the low mantissa bits, so no float → integer conversion is
/// needed: Rust's saturating conversions cost more than the rest of a
/// texture or DEM sample.
#[inline(always)]
pub fn floor_split(x: f64) -> (i64, f64) {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    let t = x + MAGIC;
    let nearest = t - MAGIC;
    let i = (t.to_bits() as i64 - MAGIC.to_bits() as i64) - i64::from(nearest > x);
    // The float from the integer (a plain conversion): selecting between
    // two floats compiles to a branch, mispredicted half the time.
    (i, i as f64)
}
