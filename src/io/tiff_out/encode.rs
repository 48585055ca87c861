//! A tile's bytes as the file holds them: the horizontal predictor for
//! integer samples, then deflate, LZW or zstd; and a mask tile's, its bits
//! packed and deflated.

use super::{Compression, OutputSpec, SampleType};
use crate::error::{Error, Result};
use tiff::encoder::compression::{CompressionAlgorithm, Lzw};

/// Applies the predictor and compression to one chunk (chunky,
/// native-endian samples, whole rows of the chunk width). Consumes the buffer.
pub fn encode_tile(spec: &OutputSpec, mut tile: Vec<u8>) -> Result<Vec<u8>> {
    if spec.predictor() == 2 {
        let per_row = spec.chunk().0 as usize * spec.bands as usize;
        let b = spec.bands as usize;
        // Each sample less the same band's sample of the pixel before, from
        // a copy of the row: a forward loop over separate slices, which the
        // compiler vectorises (in place it had to go backwards, a byte at a time).
        match spec.sample {
            SampleType::U8 => {
                let mut before = Vec::new();
                for row in tile.chunks_exact_mut(per_row) {
                    before.clear();
                    before.extend_from_slice(row);
                    for (d, (&cur, &prev)) in row[b..].iter_mut().zip(before[b..].iter().zip(&before[..])) {
                        *d = cur.wrapping_sub(prev);
                    }
                }
            }
            SampleType::U16 => {
                let mut old: Vec<u16> = Vec::new();
                for row in tile.chunks_exact_mut(per_row * 2) {
                    old.clear();
                    old.extend(row.chunks_exact(2).map(|p| u16::from_ne_bytes([p[0], p[1]])));
                    for (d, (&cur, &prev)) in row[2 * b..].chunks_exact_mut(2).zip(old[b..].iter().zip(&old[..])) {
                        d.copy_from_slice(&cur.wrapping_sub(prev).to_ne_bytes());
                    }
                }
            }
            SampleType::F32 => unreachable!("no predictor for floats"),
        }
    }
    let io = |e: std::io::Error| Error::Usage(format!("tile compression failed: {e}"));
    let level = spec.compression.level_or_default(spec.level);
    Ok(match spec.compression {
        Compression::None => tile,
        Compression::Deflate => {
            // Room for tiles that hardly compress (overviews of detailed
            // scenes), without growing the buffer.
            zlib(&tile, level)
        }
        Compression::Lzw => {
            // Room for tiles that hardly compress (overviews of detailed
            // scenes), without growing the buffer.
            let mut out = Vec::with_capacity(tile.len() + 1024);
            Lzw.write_to(&mut out, &tile).map_err(io)?;
            out
        }
        Compression::Zstd => {
            // With the frame's checksum, so that a reader can tell a damaged
            // tile from a good one (zstd decodes much damage silently).
            let mut c = zstd::bulk::Compressor::new(level.into()).map_err(io)?;
            c.set_parameter(zstd::zstd_safe::CParameter::ChecksumFlag(true)).map_err(io)?;
            c.compress(&tile).map_err(io)?
        }
    })
}

/// A mask tile as the file holds it: one bit a pixel (1: has a value),
/// the first pixel in the high bit, each of the chunk's rows padded to a
/// whole byte, deflated. `valid` holds the chunk's pixels row by row, 1
/// where a pixel has a value, else 0.
pub fn encode_mask(spec: &OutputSpec, valid: &[u8]) -> Result<Vec<u8>> {
    let (w, h) = (spec.chunk().0 as usize, spec.chunk().1 as usize);
    assert_eq!(valid.len(), w * h, "a mask tile's pixels");
    // Nearly every tile is all image or all outside: those are encoded once.
    let first = valid.first().copied().unwrap_or(0);
    // (Blocks of 64 folded without a branch: the compiler vectorises them.)
    if valid.chunks(64).all(|b| b.iter().fold(0u8, |acc, &v| acc | (v ^ first)) == 0) {
        static UNIFORM: std::sync::Mutex<Vec<(UniformKey, Vec<u8>)>> = std::sync::Mutex::new(Vec::new());
        let key = (w, h, first);
        if let Some((_, bytes)) = UNIFORM.lock().ok().and_then(|u| u.iter().find(|(k, _)| *k == key).cloned()) {
            return Ok(bytes);
        }
        let bytes = pack_and_deflate(w, h, valid)?;
        if let Ok(mut u) = UNIFORM.lock() {
            u.push((key, bytes.clone()));
        }
        return Ok(bytes);
    }
    pack_and_deflate(w, h, valid)
}

/// A uniform mask tile: its width, height and the one value of its pixels.
type UniformKey = (usize, usize, u8);

/// [`encode_mask`]'s bits, packed and deflated.
fn pack_and_deflate(w: usize, h: usize, valid: &[u8]) -> Result<Vec<u8>> {
    let row_bytes = w.div_ceil(8);
    let mut bits = vec![0u8; row_bytes * h];
    for (row, pixels) in bits.chunks_exact_mut(row_bytes).zip(valid.chunks_exact(w)) {
        let eights = pixels.chunks_exact(8);
        let rest = eights.remainder();
        for (byte, eight) in row.iter_mut().zip(eights) {
            // Eight 0/1 bytes, the first the lowest: the multiply gathers
            // them into the top byte, the first pixel highest.
            let v = u64::from_le_bytes(eight.try_into().expect("8 bytes")) & 0x0101_0101_0101_0101;
            *byte = (v.wrapping_mul(0x8040_2010_0804_0201) >> 56) as u8;
        }
        for (x, &p) in rest.iter().enumerate() {
            row[w / 8] |= (p & 1) << (7 - x);
        }
    }
    Ok(zlib(&bits, MASK_LEVEL))
}

/// Mask tiles are deflated at libdeflate's level 6: nearly all are all
/// image or all outside, encoded once, and the rest are small.
const MASK_LEVEL: u8 = 6;

/// `bytes` as a zlib stream (deflate with the Adler-32 check, as TIFF's
/// compression 8 holds it), by libdeflate at `level` (1–12): at level 1
/// far tighter than zlib's fastest, above it as tight as zlib and faster
/// (docs/BENCHMARKS.md).
pub fn zlib(bytes: &[u8], level: u8) -> Vec<u8> {
    thread_local! {
        /// A compressor per thread and level: making one allocates its
        /// hash tables.
        static COMPRESSORS: std::cell::RefCell<Vec<(u8, libdeflater::Compressor)>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    COMPRESSORS.with_borrow_mut(|cs| {
        let i = match cs.iter().position(|(l, _)| *l == level) {
            Some(i) => i,
            None => {
                let lvl = libdeflater::CompressionLvl::new(level.into()).expect("levels are checked with the options");
                cs.push((level, libdeflater::Compressor::new(lvl)));
                cs.len() - 1
            }
        };
        let c = &mut cs[i].1;
        let mut out = vec![0u8; c.zlib_compress_bound(bytes.len())];
        let n = c.zlib_compress(bytes, &mut out).expect("the bound holds the stream");
        out.truncate(n);
        out
    })
}

/// A mask tile as [`encode_mask`] writes it (and GDAL: deflated, or
/// uncompressed when `compression` is 1), back to 0/1 bytes for `w`×`h`
/// pixels.
pub fn decode_mask(bytes: &[u8], compression: u16, w: usize, h: usize) -> std::result::Result<Vec<u8>, String> {
    use std::io::Read;
    let row_bytes = w.div_ceil(8);
    let bits = match compression {
        1 => bytes.to_vec(),
        8 | 32946 => {
            let mut out = Vec::with_capacity(row_bytes * h);
            flate2::read::ZlibDecoder::new(bytes)
                .take((row_bytes * h) as u64)
                .read_to_end(&mut out)
                .map_err(|e| format!("a mask tile does not inflate: {e}"))?;
            out
        }
        c => return Err(format!("mask compression {c} is not read")),
    };
    if bits.len() < row_bytes * h {
        return Err(format!("a mask tile holds {} bytes, not {}", bits.len(), row_bytes * h));
    }
    Ok((0..w * h).map(|p| (p / w, p % w)).map(|(y, x)| (bits[y * row_bytes + x / 8] >> (7 - x % 8)) & 1).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    /// Every level makes a zlib stream that zlib itself decodes to the
    /// bytes given (GDAL reads them with zlib), and compresses.
    #[test]
    fn every_deflate_level_round_trips_through_zlib() {
        let bytes: Vec<u8> = (0..200_000u32).map(|i| ((i * 7919) % 251 / 9 + (i / 1000) % 7) as u8).collect();
        for level in [1, 2, 6, 12] {
            let z = zlib(&bytes, level);
            let mut back = Vec::new();
            flate2::read::ZlibDecoder::new(&z[..]).read_to_end(&mut back).unwrap();
            assert!(back == bytes, "level {level}");
            assert!(z.len() < bytes.len() / 4, "level {level}: {} bytes", z.len());
        }
    }
}
