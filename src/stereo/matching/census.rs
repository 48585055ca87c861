//! The census transform (Zabih & Woodfill): each pixel as the bits of
//! which neighbours in a 7 × 7 window are darker than it, so that a cost
//! (the bits that differ) does not care for the two images' exposures.

use crate::stereo::resample::Img;

/// Half the window's side.
const R: i64 = 3;
/// The cost of a disparity that puts the left pixel's match outside the
/// right image: below what a match with other ground costs (about half
/// the bits differ), above a true match's. Where the true match lies
/// outside, the pixel then chooses outside and is left unmatched, rather
/// than taking the least bad match among the ground the right image does
/// show, and dragging its neighbours' paths with it.
pub const NO_IMAGE: u8 = 12;

/// The census bits of each pixel of `img`, `None` where its window is not
/// whole: an image's edge (missing neighbours would compare as if
/// brighter, and differently in the other image) and the window's own
/// border of 3 pixels (the tile's context, never its own pixels).
pub fn transform(img: &Img) -> Vec<Option<u64>> {
    let (w, h) = (img.w, img.h);
    let r = R as usize;
    let mut out = vec![None; w * h];
    if w <= 2 * r || h <= 2 * r {
        return out;
    }
    // Row by row, a neighbour at a time over the whole row (loops the
    // compiler vectorises): the first 24 neighbours' bits in `hi`, the
    // last 24 in `lo`, each in the order of a walk of the window; a NaN
    // compares as not darker and is looked for apart.
    let side = 2 * r + 1;
    let span = w - 2 * r;
    let (mut hi, mut lo) = (vec![0u32; span], vec![0u32; span]);
    let mut nan_in_column = vec![false; w];
    for y in r..h - r {
        hi.fill(0);
        lo.fill(0);
        nan_in_column.fill(false);
        let centre = &img.v[y * w + r..y * w + w - r];
        let mut walked = 0;
        for k in 0..side {
            let row = &img.v[(y + k - r) * w..(y + k - r + 1) * w];
            for (n, v) in nan_in_column.iter_mut().zip(row) {
                *n |= v.is_nan();
            }
            for i in 0..side {
                if k == r && i == r {
                    continue;
                }
                let bits = if walked < 24 { &mut hi } else { &mut lo };
                walked += 1;
                for (b, (&v, &c)) in bits.iter_mut().zip(row[i..i + span].iter().zip(centre)) {
                    *b = (*b << 1) | u32::from(v < c);
                }
            }
        }
        for j in 0..span {
            if !nan_in_column[j..j + side].iter().any(|&n| n) {
                out[y * w + r + j] = Some((u64::from(hi[j]) << 24) | u64::from(lo[j]));
            }
        }
    }
    out
}

/// The cost of two census values.
#[inline]
pub fn cost(a: Option<u64>, b: Option<u64>) -> u8 {
    match (a, b) {
        (Some(a), Some(b)) => (a ^ b).count_ones() as u8,
        _ => NO_IMAGE,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The row-at-a-time transform gives each window's bits as a walk of
    /// that window alone does, NaNs and edges left out alike.
    #[test]
    fn rows_at_a_time_give_each_windows_own_bits() {
        let (w, h) = (23usize, 17usize);
        let mut v: Vec<f32> = (0..w * h).map(|k| ((k * 7919) % 97) as f32).collect();
        v[8 * w + 11] = f32::NAN;
        let img = Img { x0: 0, y0: 0, w, h, v };
        let got = transform(&img);
        for y in 0..h {
            for x in 0..w {
                let want = (x >= 3 && y >= 3 && x + 3 < w && y + 3 < h)
                    .then(|| {
                        let c = img.v[y * w + x];
                        let mut bits = 0u64;
                        for yy in y - 3..=y + 3 {
                            for xx in x - 3..=x + 3 {
                                if (xx, yy) != (x, y) {
                                    let n = img.v[yy * w + xx];
                                    if n.is_nan() || c.is_nan() {
                                        return None;
                                    }
                                    bits = (bits << 1) | u64::from(n < c);
                                }
                            }
                        }
                        Some(bits)
                    })
                    .flatten();
                assert_eq!(got[y * w + x], want, "({x}, {y})");
            }
        }
        assert!(got.iter().filter(|b| b.is_some()).count() > 100);
    }
}
