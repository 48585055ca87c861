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
    for y in r..h - r {
        let rows: [&[f32]; 7] = std::array::from_fn(|k| &img.v[(y + k - r) * w..(y + k - r + 1) * w]);
        for x in r..w - r {
            let c = rows[r][x];
            if c.is_nan() {
                continue;
            }
            let mut bits = 0u64;
            let mut whole = true;
            for (k, row) in rows.iter().enumerate() {
                for (i, &v) in row[x - r..=x + r].iter().enumerate() {
                    if k == r && i == r {
                        continue;
                    }
                    whole &= !v.is_nan();
                    bits = (bits << 1) | u64::from(v < c);
                }
            }
            if whole {
                out[y * w + x] = Some(bits);
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
