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
/// whole (an image's edge: the missing neighbours would compare as if
/// brighter, and differently in the other image).
pub fn transform(img: &Img) -> Vec<Option<u64>> {
    let (w, h) = (img.w as i64, img.h as i64);
    let mut out = vec![None; img.w * img.h];
    for y in 0..h {
        for x in 0..w {
            let c = img.v[(y * w + x) as usize];
            if c.is_nan() {
                continue;
            }
            let mut bits = 0u64;
            let mut whole = true;
            for dy in -R..=R {
                for dx in -R..=R {
                    if dx == 0 && dy == 0 {
                        continue;
                    }
                    let (xx, yy) = ((x + dx).clamp(0, w - 1), (y + dy).clamp(0, h - 1));
                    let v = img.v[(yy * w + xx) as usize];
                    whole &= !v.is_nan();
                    bits = (bits << 1) | u64::from(v < c);
                }
            }
            if whole {
                out[(y * w + x) as usize] = Some(bits);
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
