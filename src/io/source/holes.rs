//! The scan's own marks of pixels that hold no image: an alpha band (zero:
//! transparent), a nodata value (GDAL_NODATA: a pixel whose every band
//! holds it), or an internal mask (GDAL's 1-bit mask directory). The
//! resampler leaves an output pixel without a value where its kernel would
//! read such a pixel, so nothing of a collar or a cut-out is mixed into
//! the image.

use super::{SourceImage, SourceInfo};
use crate::error::{Error, Result};
use crate::io::chunk_codec::ChunkCodec;

/// How the scan marks its pixels without image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum HoleMark {
    /// This band is the alpha band; zero marks a hole.
    Alpha(u32),
    /// A pixel whose every band holds this value (NaN: is NaN) is a hole.
    Value(f64),
    /// With an alpha band (this one): its zero, or every other band at
    /// the value.
    ValueOrAlpha(f64, u32),
    /// The internal mask's clear bits ([`MaskRuns`]).
    Mask,
}

impl HoleMark {
    /// How `info` marks its holes, if it does: the mask before a nodata
    /// value before the alpha band (GDAL's order for a GeoTIFF's mask).
    pub fn of(info: &SourceInfo) -> Option<HoleMark> {
        if info.mask.is_some() {
            Some(HoleMark::Mask)
        } else if let Some(v) = info.nodata {
            Some(if info.has_alpha { HoleMark::ValueOrAlpha(v, info.bands - 1) } else { HoleMark::Value(v) })
        } else {
            info.has_alpha.then(|| HoleMark::Alpha(info.bands - 1))
        }
    }

    /// Whether a pixel's samples (all its bands) are a hole by an alpha
    /// band or a nodata value (never by the mask, which is not in them).
    #[inline]
    pub fn is_hole(self, px: impl Fn(usize) -> f32, bands: usize) -> bool {
        let all_at = |v: f64, n: usize| if v.is_nan() { (0..n).all(|b| px(b).is_nan()) } else { (0..n).all(|b| px(b) == v as f32) };
        match self {
            HoleMark::Alpha(b) => px(b as usize) == 0.0,
            HoleMark::Value(v) => all_at(v, bands),
            HoleMark::ValueOrAlpha(v, a) => px(a as usize) == 0.0 || all_at(v, a as usize),
            HoleMark::Mask => false,
        }
    }
}

/// Runs of set bits a row make a mask small whatever the scan's size
/// (a collar or a cut-out: a few runs a row); past this many (8 MB of
/// them), the mask is refused rather than held outside the budget.
const MAX_RUNS: usize = 1 << 20;

/// An internal mask as runs of image pixels, row by row.
#[derive(Debug, Default)]
pub struct MaskRuns {
    /// Row `r`'s runs are `runs[first[r]..first[r + 1]]`.
    first: Vec<u32>,
    /// Half-open column ranges of set bits, left to right.
    runs: Vec<[u32; 2]>,
}

impl MaskRuns {
    /// Reads `src`'s internal mask a row of chunks at a time, as bits (in
    /// any compression the scan's chunks may have).
    pub fn read(src: &SourceImage) -> Result<MaskRuns> {
        let info = &src.info;
        let Some((offsets, counts)) = &info.mask else { return Ok(MaskRuns::default()) };
        let path = &src.path;
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let codec =
            ChunkCodec { compression: info.mask_compression, predictor: 1, sample_bytes: 1, float: false, samples: 1, big_endian: false, packed_bits: 0 };
        codec.check().map_err(|what| Error::unsupported(path, format!("its internal mask: {what}")))?;
        let (cw, ch) = (info.chunk.0 as usize, info.chunk.1 as usize);
        let row_bytes = cw.div_ceil(8);
        let across = info.width.div_ceil(info.chunk.0) as usize;
        let mut out = MaskRuns { first: Vec::with_capacity(info.height as usize + 1), runs: Vec::new() };
        let mut chunks: Vec<Vec<u8>> = Vec::with_capacity(across);
        for cy in 0..info.height.div_ceil(info.chunk.1) as usize {
            chunks.clear();
            // A last strip may be short (or written at full height); tiles are whole.
            let rows = if info.tiled { ch } else { ch.min(info.height as usize - cy * ch) };
            for cx in 0..across {
                let k = cy * across + cx;
                let bits = codec
                    .read_chunk(&file, path, k, (offsets[k], counts[k]), row_bytes, rows, ch)
                    .map_err(|e| Error::Named(format!("{e} (of its internal mask)")))?;
                chunks.push(bits);
            }
            for y in 0..rows.min(info.height as usize - cy * ch) {
                out.first.push(out.runs.len() as u32);
                let mut open: Option<u32> = None;
                let mut x = 0usize;
                while x < info.width as usize {
                    let (chunk, cx) = (&chunks[x / cw], x % cw);
                    let byte = chunk[y * row_bytes + cx / 8];
                    // Whole bytes of one kind eight pixels a step, else a bit.
                    let whole = cx % 8 == 0 && cx + 8 <= cw && x + 8 <= info.width as usize && (byte == 0 || byte == 0xFF);
                    let (set, step) = if whole { (byte == 0xFF, 8) } else { ((byte >> (7 - cx % 8)) & 1 != 0, 1) };
                    match (set, open) {
                        (true, None) => open = Some(x as u32),
                        (false, Some(s)) => {
                            out.runs.push([s, x as u32]);
                            open = None;
                        }
                        _ => {}
                    }
                    x += step;
                }
                if let Some(s) = open {
                    out.runs.push([s, info.width]);
                }
                if out.runs.len() > MAX_RUNS {
                    return Err(Error::limits(
                        path,
                        format!("its internal mask breaks into more than {MAX_RUNS} runs of image pixels; flatten it (gdal_translate -b mask) or drop it"),
                    ));
                }
            }
        }
        out.first.push(out.runs.len() as u32);
        Ok(out)
    }

    /// Whether every pixel of columns `c0..=c1` of row `r` is image.
    #[inline]
    pub fn all_set(&self, r: u32, c0: u32, c1: u32) -> bool {
        let Some(&[a, b]) = self.first.get(r as usize..r as usize + 2).map(|s| <&[u32; 2]>::try_from(s).expect("two")) else { return false };
        let runs = &self.runs[a as usize..b as usize];
        // The last run that starts at or before c0.
        let i = runs.partition_point(|run| run[0] <= c0);
        i > 0 && runs[i - 1][1] > c1
    }

    /// Row `r`'s half-open column ranges of image pixels, left to right.
    pub fn row(&self, r: u32) -> &[[u32; 2]] {
        match self.first.get(r as usize..r as usize + 2) {
            Some(&[a, b]) => &self.runs[a as usize..b as usize],
            _ => &[],
        }
    }

}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_answer_whether_a_stretch_of_a_row_is_all_image() {
        // Row 0: image at 2..5 and 7..10; row 1: none; row 2: all of 0..10.
        let m = MaskRuns { first: vec![0, 2, 2, 3], runs: vec![[2, 5], [7, 10], [0, 10]] };
        assert!(m.all_set(0, 2, 4) && m.all_set(0, 3, 3) && m.all_set(0, 7, 9));
        assert!(!m.all_set(0, 1, 2) && !m.all_set(0, 4, 5) && !m.all_set(0, 4, 7) && !m.all_set(0, 0, 0));
        assert!(!m.all_set(1, 0, 0) && !m.all_set(1, 5, 5));
        assert!(m.all_set(2, 0, 9) && !m.all_set(2, 0, 10));
        // Past the last row: no image.
        assert!(!m.all_set(3, 0, 0));
    }

    #[test]
    fn a_hole_is_a_clear_alpha_or_every_band_at_the_nodata_value() {
        let px = |v: [f32; 3]| move |b: usize| v[b];
        assert!(HoleMark::Alpha(2).is_hole(px([5.0, 5.0, 0.0]), 3));
        assert!(!HoleMark::Alpha(2).is_hole(px([0.0, 0.0, 1.0]), 3));
        assert!(HoleMark::Value(0.0).is_hole(px([0.0, 0.0, 0.0]), 3));
        // Black in one band only is image (a dark red roof).
        assert!(!HoleMark::Value(0.0).is_hole(px([9.0, 0.0, 0.0]), 3));
        assert!(HoleMark::Value(f64::NAN).is_hole(px([f32::NAN; 3]), 3));
        assert!(!HoleMark::Value(f64::NAN).is_hole(px([f32::NAN, 1.0, f32::NAN]), 3));
        assert!(!HoleMark::Mask.is_hole(px([0.0; 3]), 3));
        // Grey and alpha with a nodata value: either marks a hole (the
        // alpha band is not compared with the value).
        let both = HoleMark::ValueOrAlpha(0.0, 1);
        assert!(both.is_hole(px([5.0, 0.0, 9.0]), 2) && both.is_hole(px([0.0, 255.0, 9.0]), 2) && !both.is_hole(px([5.0, 255.0, 9.0]), 2));
    }
}
