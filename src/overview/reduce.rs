//! One level of an overview from the level below: each output pixel from
//! the 2×2 pixels under it, skipping those without a value.

use crate::io::format::SampleType;

/// How an overview pixel is made of the four below it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OverviewResampling {
    /// The mean of those that have a value (rounded to the nearest integer
    /// for integer samples): imagery.
    #[default]
    Average,
    /// The top-left one, value or not: classified data, exact values.
    Nearest,
    /// The value most of them have (the first of them on a tie), among
    /// those that have a value: classified data without bias to a corner.
    Mode,
}

/// How a level's pixels say they have no value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ValidBy {
    /// A mask of 0/1 bytes beside the pixels.
    Mask,
    /// Every band holds this value.
    Nodata(f64),
    /// A band is NaN.
    Nan,
    /// The last band (alpha) is 0.
    Alpha,
}

impl ValidBy {
    /// How the pixels of a file written to `spec` say they have no value:
    /// its internal mask, else its nodata value (NaN for floats), else its
    /// alpha band.
    pub fn of(spec: &crate::io::tiff_out::OutputSpec) -> ValidBy {
        match spec.geo.as_ref().and_then(|g| g.nodata) {
            _ if spec.mask => ValidBy::Mask,
            Some(v) if v.is_nan() => ValidBy::Nan,
            Some(v) => ValidBy::Nodata(v),
            None if spec.alpha => ValidBy::Alpha,
            None => ValidBy::Nan,
        }
    }

    /// Does a pixel of these samples have a value? (`mask`: its mask byte,
    /// under [`ValidBy::Mask`].)
    pub fn has_value(self, mut samples: impl ExactSizeIterator<Item = f64>, mask: Option<u8>) -> bool {
        match self {
            ValidBy::Mask => mask.is_some_and(|m| m != 0),
            ValidBy::Nodata(v) => samples.any(|s| s != v),
            ValidBy::Nan => samples.all(|s| !s.is_nan()),
            ValidBy::Alpha => samples.last().is_some_and(|a| a != 0.0),
        }
    }
}

/// A pixel of `lay`'s that holds `fill` in every band, as the file holds it.
pub fn fill_pixel(lay: TileLayout, fill: f64) -> Vec<u8> {
    match lay.sample {
        SampleType::U8 => vec![u8::put(fill); lay.bands],
        SampleType::U16 => bytemuck::cast_slice(&vec![u16::put(fill); lay.bands]).to_vec(),
        SampleType::F32 => bytemuck::cast_slice(&vec![f32::put(fill); lay.bands]).to_vec(),
    }
}

/// The pixel layout of a level's tiles: `tile`×`tile` pixels of `bands`
/// samples, row after row.
#[derive(Clone, Copy, Debug)]
pub struct TileLayout {
    pub tile: usize,
    pub bands: usize,
    pub sample: SampleType,
}

/// A tile reduced to a quarter: (tile/2)² pixels and their 0/1 validity.
#[derive(Clone, Debug, Default)]
pub struct Quarter {
    pub pixels: Vec<u8>,
    pub valid: Vec<u8>,
}

/// Reduces one tile: `pixels` (native-endian samples), `valid` (0/1 a
/// pixel, under [`ValidBy::Mask`]), of which the first `extent` columns
/// and rows are image (the rest, padding, count as without a value).
/// Pixels without a value in the result hold `fill` in every band.
pub fn reduce(kernel: OverviewResampling, lay: TileLayout, by: ValidBy, fill: f64, pixels: &[u8], valid: Option<&[u8]>, extent: (usize, usize)) -> Quarter {
    match lay.sample {
        SampleType::U8 => reduce_as::<u8>(kernel, lay, by, fill, pixels, valid, extent),
        SampleType::U16 => reduce_as::<u16>(kernel, lay, by, fill, pixels, valid, extent),
        SampleType::F32 => reduce_as::<f32>(kernel, lay, by, fill, pixels, valid, extent),
    }
}

/// A sample type the kernels work on, through f64.
trait Sample: bytemuck::Pod + PartialEq {
    fn value(self) -> f64;
    /// The nearest value of the type (integers rounded half up, clamped).
    fn put(v: f64) -> Self;
    /// The mean of four, as `put` of their sum (in this order) over 4.
    fn mean4(a: Self, b: Self, c: Self, d: Self) -> Self;
    /// An integer sample as u32 (floats: none).
    fn widen(self) -> Option<u32>;
    fn narrow(v: u32) -> Self;
}

/// An integer sample: summed as u32, rounded half up, clamped.
macro_rules! integer_sample {
    ($t:ty) => {
        impl Sample for $t {
            fn value(self) -> f64 {
                self as f64
            }
            fn put(v: f64) -> Self {
                (v + 0.5).floor().clamp(0.0, <$t>::MAX as f64) as $t
            }
            fn mean4(a: Self, b: Self, c: Self, d: Self) -> Self {
                ((a as u32 + b as u32 + c as u32 + d as u32 + 2) >> 2) as $t
            }
            fn widen(self) -> Option<u32> {
                Some(self as u32)
            }
            fn narrow(v: u32) -> Self {
                v as $t
            }
        }
    };
}

integer_sample!(u8);
integer_sample!(u16);

impl Sample for f32 {
    fn value(self) -> f64 {
        self as f64
    }
    fn put(v: f64) -> Self {
        v as f32
    }
    fn mean4(a: Self, b: Self, c: Self, d: Self) -> Self {
        ((a as f64 + b as f64 + c as f64 + d as f64) / 4.0) as f32
    }
    fn widen(self) -> Option<u32> {
        None
    }
    fn narrow(_: u32) -> Self {
        unreachable!("floats are not summed as integers")
    }
}

fn reduce_as<T: Sample>(
    kernel: OverviewResampling,
    lay: TileLayout,
    by: ValidBy,
    fill: f64,
    pixels: &[u8],
    valid: Option<&[u8]>,
    extent: (usize, usize),
) -> Quarter {
    let (t, b) = (lay.tile, lay.bands);
    let half = t / 2;
    // Tiles are slices of larger buffers: read in place where aligned.
    let owned;
    let px: &[T] = match bytemuck::try_cast_slice(pixels) {
        Ok(p) => p,
        Err(_) => {
            let mut v = vec![T::zeroed(); pixels.len() / std::mem::size_of::<T>()];
            bytemuck::cast_slice_mut::<T, u8>(&mut v).copy_from_slice(pixels);
            owned = v;
            &owned
        }
    };
    assert_eq!(px.len(), t * t * b, "a whole tile");
    // Which pixels below have a value, 0/1 (the mask's own bytes under a mask).
    let derived: Vec<u8>;
    let valid_below: &[u8] = match (by, valid) {
        (ValidBy::Mask, Some(v)) => v,
        _ => {
            derived = px.chunks_exact(b).map(|p| u8::from(by.has_value(p.iter().map(|s| s.value()), None))).collect();
            &derived
        }
    };
    let has = |i: usize| valid_below[i] != 0;
    let mut out = vec![T::put(fill); half * half * b];
    let mut ok = vec![0u8; half * half];
    let mut sum = vec![0f64; b];
    let integer = px.first().is_some_and(|p| p.widen().is_some());
    let mut column_sums = vec![0u32; t * b];
    let mut narrow_sums = vec![0u16; t * b];
    let mut means = Vec::with_capacity(t * b);
    for oy in 0..half {
        let rows_inside = 2 * oy + 1 < extent.1;
        let (r0, r1) = (2 * oy * t, (2 * oy + 1) * t);
        if kernel == OverviewResampling::Average
            && integer
            && rows_inside
            && extent.0 == t
            // (The two rows are one run of the mask; 0/1 bytes folded
            // with a branch-free AND, which the compiler vectorises.)
            && valid_below[r0..r1 + t].iter().fold(1u8, |a, &m| a & m) != 0
        {
            // A whole row of blocks with values (nearly every row): the
            // two rows added sample by sample, then pairs of pixels, in
            // loops the compiler vectorises (8-bit samples summed in 16
            // bits: twice the lanes).
            let to = &mut out[oy * half * b..(oy + 1) * half * b];
            if let (Some(r0), Some(r1), Some(to)) = (as_u8(&px[r0 * b..(r0 + t) * b]), as_u8(&px[r1 * b..(r1 + t) * b]), as_u8_mut(to)) {
                for (s, (&a, &c)) in narrow_sums.iter_mut().zip(r0.iter().zip(r1)) {
                    *s = a as u16 + c as u16;
                }
                match b {
                    1 => pair_means_u8::<1>(&narrow_sums, to, &mut means),
                    2 => pair_means_u8::<2>(&narrow_sums, to, &mut means),
                    3 => pair_means_u8::<3>(&narrow_sums, to, &mut means),
                    4 => pair_means_u8::<4>(&narrow_sums, to, &mut means),
                    _ => {
                        for (to, pair) in to.chunks_exact_mut(b).zip(narrow_sums.chunks_exact(2 * b)) {
                            for (k, d) in to.iter_mut().enumerate() {
                                *d = ((pair[k] + pair[b + k] + 2) >> 2) as u8;
                            }
                        }
                    }
                }
                ok[oy * half..(oy + 1) * half].fill(1);
                continue;
            }
            let widen = |p: &T| p.widen().unwrap_or(0);
            for (s, (a, c)) in column_sums.iter_mut().zip(px[r0 * b..(r0 + t) * b].iter().zip(&px[r1 * b..(r1 + t) * b])) {
                *s = widen(a) + widen(c);
            }
            match b {
                1 => pair_means::<T, 1>(&column_sums, to),
                2 => pair_means::<T, 2>(&column_sums, to),
                3 => pair_means::<T, 3>(&column_sums, to),
                4 => pair_means::<T, 4>(&column_sums, to),
                _ => {
                    for (to, pair) in to.chunks_exact_mut(b).zip(column_sums.chunks_exact(2 * b)) {
                        for (k, d) in to.iter_mut().enumerate() {
                            *d = T::narrow((pair[k] + pair[b + k] + 2) >> 2);
                        }
                    }
                }
            }
            ok[oy * half..(oy + 1) * half].fill(1);
            continue;
        }
        for ox in 0..half {
            let o = oy * half + ox;
            // Nearly always: four pixels inside, all with a value.
            let (i00, i10) = (2 * oy * t + 2 * ox, (2 * oy + 1) * t + 2 * ox);
            if kernel == OverviewResampling::Average
                && rows_inside
                && 2 * ox + 1 < extent.0
                && valid_below[i00] & valid_below[i00 + 1] & valid_below[i10] & valid_below[i10 + 1] != 0
            {
                let (a, bb, c, d) = (&px[i00 * b..], &px[(i00 + 1) * b..], &px[i10 * b..], &px[(i10 + 1) * b..]);
                for (k, to) in out[o * b..(o + 1) * b].iter_mut().enumerate() {
                    *to = T::mean4(a[k], bb[k], c[k], d[k]);
                }
                ok[o] = 1;
                continue;
            }
            // The four below, in raster order, image pixels only.
            let mut under = [0usize; 4];
            let mut n = 0;
            for (dy, dx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                let (x, y) = (2 * ox + dx, 2 * oy + dy);
                if x < extent.0 && y < extent.1 {
                    under[n] = y * t + x;
                    n += 1;
                }
            }
            let under = &under[..n];
            let chosen: Option<usize> = match kernel {
                OverviewResampling::Nearest => {
                    let top_left = 2 * oy * t + 2 * ox;
                    (2 * ox < extent.0 && 2 * oy < extent.1 && has(top_left)).then_some(top_left)
                }
                OverviewResampling::Mode => {
                    let with: Vec<usize> = under.iter().copied().filter(|&i| has(i)).collect();
                    let same = |i: usize, j: usize| px[i * b..(i + 1) * b] == px[j * b..(j + 1) * b];
                    // The most frequent; on a tie, the first in raster order.
                    with.iter().copied().max_by_key(|&i| (with.iter().filter(|&&j| same(i, j)).count(), std::cmp::Reverse(i)))
                }
                OverviewResampling::Average => {
                    sum.iter_mut().for_each(|s| *s = 0.0);
                    let mut m = 0u32;
                    for &i in under {
                        if has(i) {
                            for (s, v) in sum.iter_mut().zip(&px[i * b..(i + 1) * b]) {
                                *s += v.value();
                            }
                            m += 1;
                        }
                    }
                    if m > 0 {
                        for (d, s) in out[o * b..(o + 1) * b].iter_mut().zip(&sum) {
                            *d = T::put(s / m as f64);
                        }
                        ok[o] = 1;
                    }
                    None
                }
            };
            if let Some(i) = chosen {
                out[o * b..(o + 1) * b].copy_from_slice(&px[i * b..(i + 1) * b]);
                ok[o] = 1;
            }
        }
    }
    // 8-bit pixels are the bytes already; wider ones are copied to bytes.
    let pixels = bytemuck::allocation::try_cast_vec(out).unwrap_or_else(|(_, out)| bytemuck::cast_slice(&out).to_vec());
    Quarter { pixels, valid: ok }
}

/// 8-bit samples as they are (other sample types: none).
fn as_u8<T: Sample>(s: &[T]) -> Option<&[u8]> {
    (std::mem::size_of::<T>() == 1 && s.first().is_some_and(|p| p.widen().is_some())).then(|| bytemuck::cast_slice(s))
}

fn as_u8_mut<T: Sample>(s: &mut [T]) -> Option<&mut [u8]> {
    (std::mem::size_of::<T>() == 1).then(|| bytemuck::cast_slice_mut(s))
}

/// [`pair_means`] of 8-bit samples from 16-bit sums: every sample's mean
/// with the same band's a pixel on (one vectorised pass over the row, into
/// `means`), then every other pixel's kept, eight bytes copied a pixel
/// (each copy's excess overwritten by the next; the last pixels one by
/// one).
fn pair_means_u8<const B: usize>(sums: &[u16], to: &mut [u8], means: &mut Vec<u8>) {
    let n = sums.len() - B;
    means.resize(n, 0);
    for (m, (&a, &c)) in means.iter_mut().zip(sums.iter().zip(&sums[B..])) {
        *m = ((a + c + 2) >> 2) as u8;
    }
    let pixels = to.len() / B;
    // Pixels whose eight bytes stay inside both rows.
    let wide = if B < 8 { pixels.saturating_sub(8usize.div_ceil(B)).min((n.saturating_sub(8)) / (2 * B) + 1) } else { 0 };
    for i in 0..wide {
        to[i * B..i * B + 8].copy_from_slice(&means[2 * i * B..2 * i * B + 8]);
    }
    for i in wide..pixels {
        to[i * B..(i + 1) * B].copy_from_slice(&means[2 * i * B..2 * i * B + B]);
    }
}

/// Each pixel of `to` (`B` samples) the rounded mean of two neighbouring
/// pixels' column sums (of two rows each).
fn pair_means<T: Sample, const B: usize>(sums: &[u32], to: &mut [T]) {
    for (to, pair) in to.chunks_exact_mut(B).zip(sums.chunks_exact(2 * B)) {
        for k in 0..B {
            to[k] = T::narrow((pair[k] + pair[B + k] + 2) >> 2);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lay(bands: usize, sample: SampleType) -> TileLayout {
        TileLayout { tile: 4, bands, sample }
    }

    #[test]
    fn average_skips_pixels_without_a_value_and_rounds_half_up() {
        // 4×4 grey: the top-left block 10, 11, 12, 14 (mean 11.75 → 12);
        // top-right: only 7 and 8 have a value (7.5 → 8); bottom-left:
        // none (fill 0, not valid); bottom-right: padding beyond a
        // 3-column extent leaves 1 and 2 (1.5 → 2).
        let px: Vec<u8> = vec![10, 11, 7, 9, 12, 14, 8, 9, 5, 5, 1, 50, 5, 5, 2, 60];
        let valid: Vec<u8> = vec![1, 1, 1, 0, 1, 1, 1, 0, 0, 0, 1, 1, 0, 0, 1, 1];
        let q = reduce(OverviewResampling::Average, lay(1, SampleType::U8), ValidBy::Mask, 0.0, &px, Some(&valid), (3, 4));
        assert_eq!(q.pixels, [12, 8, 0, 2]);
        assert_eq!(q.valid, [1, 1, 0, 1]);
    }

    #[test]
    fn whole_rows_of_any_band_count_are_the_rounded_mean_of_each_block() {
        // The vectorised path (8- and 16-bit, every pixel with a value) of
        // 1–5 bands against the mean worked out here, in 12-px tiles (three
        // blocks of four pixels and their remainder in each row).
        let t = 12;
        for bands in 1..=5 {
            for sample in [SampleType::U8, SampleType::U16] {
                let n = t * t * bands;
                let v: Vec<u32> = (0..n as u64).map(|i| (i.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 56) as u32).collect();
                let bytes: Vec<u8> = match sample {
                    SampleType::U8 => v.iter().map(|&x| x as u8).collect(),
                    _ => v.iter().flat_map(|&x| ((x * 250) as u16).to_ne_bytes()).collect(),
                };
                let scale = if sample == SampleType::U8 { 1 } else { 250 };
                let q = reduce(OverviewResampling::Average, TileLayout { tile: t, bands, sample }, ValidBy::Mask, 0.0, &bytes, Some(&vec![1; t * t]), (t, t));
                let half = t / 2;
                for i in 0..half * half * bands {
                    let (o, k) = (i / bands, i % bands);
                    let (x, y) = (2 * (o % half), 2 * (o / half));
                    let at = |dx: usize, dy: usize| v[((y + dy) * t + x + dx) * bands + k] * scale;
                    let want = (at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1) + 2) / 4;
                    let got = match sample {
                        SampleType::U8 => q.pixels[i] as u32,
                        _ => u16::from_ne_bytes([q.pixels[2 * i], q.pixels[2 * i + 1]]) as u32,
                    };
                    assert_eq!(got, want, "{bands} bands {sample:?}, sample {i}");
                }
                assert!(q.valid.iter().all(|&m| m == 1));
            }
        }
    }

    #[test]
    fn nearest_takes_the_top_left_and_mode_the_most_frequent() {
        // RGB pixels compared whole.
        let a = [1u8, 2, 3];
        let c = [9u8, 9, 9];
        let block = |p: [[u8; 3]; 4]| -> Vec<u8> {
            // One block in the top-left 2×2 of a 4×4 tile, the rest c.
            let mut v = Vec::new();
            for y in 0..4 {
                for x in 0..4 {
                    v.extend_from_slice(&if x < 2 && y < 2 { p[y * 2 + x] } else { c });
                }
            }
            v
        };
        let px = block([c, a, a, c]);
        let q = reduce(OverviewResampling::Nearest, lay(3, SampleType::U8), ValidBy::Nodata(0.0), 0.0, &px, None, (4, 4));
        assert_eq!(&q.pixels[..3], &c);
        // c and a twice each: the first in raster order wins.
        let q = reduce(OverviewResampling::Mode, lay(3, SampleType::U8), ValidBy::Nodata(0.0), 0.0, &px, None, (4, 4));
        assert_eq!(&q.pixels[..3], &c);
        let px = block([a, c, c, [0, 0, 0]]);
        // c twice, a once, the nodata pixel skipped.
        let q = reduce(OverviewResampling::Mode, lay(3, SampleType::U8), ValidBy::Nodata(0.0), 0.0, &px, None, (4, 4));
        assert_eq!(&q.pixels[..3], &c);
        // Nearest of a top-left without a value has none.
        let px = block([[0, 0, 0], c, c, c]);
        let q = reduce(OverviewResampling::Nearest, lay(3, SampleType::U8), ValidBy::Nodata(0.0), 0.0, &px, None, (4, 4));
        assert_eq!((&q.pixels[..3], q.valid[0]), (&[0u8, 0, 0][..], 0));
    }

    #[test]
    fn floats_skip_nan_and_alpha_zero_counts_as_empty() {
        let v: Vec<f32> = vec![1.0, f32::NAN, 0.5, 0.5, 2.0, 4.0, 0.5, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let q = reduce(OverviewResampling::Average, lay(1, SampleType::F32), ValidBy::Nan, f64::NAN, bytemuck::cast_slice(&v), None, (4, 4));
        let out: &[f32] = bytemuck::cast_slice(&q.pixels);
        assert_eq!((out[0], out[1], q.valid[0]), (7.0 / 3.0, 0.5, 1));
        // Grey + alpha, 16-bit: alpha 0 pixels are left out.
        let v: Vec<u16> = [[100u16, 65535], [300, 65535], [5000, 0], [200, 65535]].into_iter().chain(std::iter::repeat_n([0, 0], 12)).flatten().collect();
        // (Laid out as a 4×4 tile: the first row holds the four.)
        let q = reduce(OverviewResampling::Average, lay(2, SampleType::U16), ValidBy::Alpha, 0.0, bytemuck::cast_slice(&v), None, (4, 4));
        let out: &[u16] = bytemuck::cast_slice(&q.pixels);
        assert_eq!(&out[..4], &[200, 65535, 200, 65535]);
        assert_eq!(&q.valid, &[1, 1, 0, 0]);
    }
}
