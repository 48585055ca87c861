//! A tile's bytes as the file holds them: the horizontal predictor for
//! integer samples, then deflate, LZW or zstd, or JPEG; and a mask tile's,
//! its bits packed and deflated.

use super::{Compression, OutputSpec, SampleType};
use crate::error::{Error, Result};

/// Applies the predictor and compression to one chunk (chunky,
/// native-endian samples, whole rows of the chunk width) of level `l`
/// (0: full resolution), at that level's codec level. Consumes the
/// buffer. `valid` (1 where a pixel has a value, under a mask) lets JPEG
/// fill the pixels without one from their neighbours first.
pub fn encode_tile(spec: &OutputSpec, l: u32, mut tile: Vec<u8>, valid: Option<&[u8]>) -> Result<Vec<u8>> {
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
    let io = |e: std::io::Error| Error::Internal(format!("tile compression failed: {e}"));
    let level = spec.level_of(l);
    Ok(match spec.compression {
        Compression::None => tile,
        Compression::Deflate => {
            // Room for tiles that hardly compress (overviews of detailed
            // scenes), without growing the buffer.
            zlib(&tile, level)
        }
        Compression::Lzw => {
            // Room for tiles that hardly compress (overviews of detailed
            // scenes), without growing the buffer. Straight into it: weezl's
            // stream interface (the tiff crate's) takes a 16 MiB buffer for
            // every tile, 50 MiB past the budget with two threads.
            let mut out = Vec::with_capacity(tile.len() + 1024);
            let mut lzw = weezl::encode::Encoder::with_tiff_size_switch(weezl::BitOrder::Msb, 8);
            lzw.into_vec(&mut out).encode_all(&tile).status.map_err(|e| io(std::io::Error::other(e)))?;
            out
        }
        Compression::Zstd => {
            // With the frame's checksum, so that a reader can tell a damaged
            // tile from a good one (zstd decodes much damage silently).
            let mut c = zstd::bulk::Compressor::new(level.into()).map_err(io)?;
            c.set_parameter(zstd::zstd_safe::CParameter::ChecksumFlag(true)).map_err(io)?;
            c.compress(&tile).map_err(io)?
        }
        Compression::Jpeg => {
            if let Some(v) = valid {
                let (w, h) = spec.chunk();
                fill_holes(&mut tile, v, w as usize, h as usize, spec.bands as usize, if spec.bands == 3 { 16 } else { 8 });
            }
            jpeg(spec, &tile, level)?
        }
    })
}

/// A chunk as an abbreviated JPEG stream: its frame and scan, the tables
/// (the same for every chunk of a file) left to the JPEGTables tag
/// ([`jpeg_tables`]) as libtiff writes it — some 600 bytes a tile less.
/// RGB is coded as YCbCr with the chroma of each 2×2 pixels averaged
/// (libtiff checks the stream's sampling against the file's
/// YCbCrSubSampling), grey as it is. Baseline Huffman tables: optimised
/// ones would differ from tile to tile and cost a second pass.
fn jpeg(spec: &OutputSpec, tile: &[u8], quality: u8) -> Result<Vec<u8>> {
    let whole = jpeg_stream(spec, tile, quality)?;
    let (_, coded) = split_jpeg(&whole).ok_or_else(|| Error::Internal("jpeg coding made a stream without a scan".into()))?;
    Ok(coded)
}

/// The JPEGTables of a JPEG-compressed file: a stream of nothing but the
/// quantisation and Huffman tables every chunk is coded with.
pub fn jpeg_tables(spec: &OutputSpec) -> Result<Vec<u8>> {
    let quality = spec.compression.level_or_default(spec.level);
    let probe = OutputSpec { chunking: super::Chunking::Tiles(16), ..spec.clone() };
    let pixels = vec![0u8; probe.tile_bytes()];
    let whole = jpeg_stream(&probe, &pixels, quality)?;
    let (tables, _) = split_jpeg(&whole).ok_or_else(|| Error::Internal("jpeg coding made a stream without a scan".into()))?;
    Ok(tables)
}

/// The quality whose tables are `tables` for `spec`'s bands (`None`:
/// none is, e.g. another encoder's).
pub fn jpeg_quality_of(spec: &OutputSpec, tables: &[u8]) -> Option<u8> {
    (1..=100u8).find(|&q| jpeg_tables(&OutputSpec { level: Some(q), ..spec.clone() }).is_ok_and(|t| t == tables))
}

/// A complete stream (SOI … EOI) split into its tables (DQT, DHT, as a
/// stream of their own: SOI, tables, EOI) and the rest (SOI, the frame,
/// the scan with its data, EOI), the JFIF header dropped; `None` when it
/// is not such a stream.
fn split_jpeg(stream: &[u8]) -> Option<(Vec<u8>, Vec<u8>)> {
    const SOI: [u8; 2] = [0xff, 0xd8];
    const EOI: [u8; 2] = [0xff, 0xd9];
    if stream.get(..2)? != SOI {
        return None;
    }
    let (mut tables, mut rest) = (SOI.to_vec(), SOI.to_vec());
    let mut at = 2;
    loop {
        let (marker, len) = (*stream.get(at + 1)?, u16::from_be_bytes([*stream.get(at + 2)?, *stream.get(at + 3)?]) as usize);
        if *stream.get(at)? != 0xff {
            return None;
        }
        let segment = stream.get(at..at + 2 + len)?;
        match marker {
            0xdb | 0xc4 => tables.extend_from_slice(segment),
            0xe0 => {}
            0xda => {
                // The scan: its header, its data and the end, as they are.
                rest.extend_from_slice(&stream[at..]);
                tables.extend_from_slice(&EOI);
                return Some((tables, rest));
            }
            _ => rest.extend_from_slice(segment),
        }
        at += 2 + len;
    }
}

/// A chunk as a complete JPEG stream.
fn jpeg_stream(spec: &OutputSpec, tile: &[u8], quality: u8) -> Result<Vec<u8>> {
    let (w, h) = spec.chunk();
    let colour = match spec.bands {
        1 => jpeg_encoder::ColorType::Luma,
        3 => jpeg_encoder::ColorType::Rgb,
        b => return Err(Error::setting("compress", format!("jpeg holds 1 or 3 bands, not {b}"))),
    };
    let (w, h) = (u16::try_from(w), u16::try_from(h));
    let (Ok(w), Ok(h)) = (w, h) else { return Err(Error::setting("compress", "jpeg: a chunk wider or taller than 65535 pixels")) };
    let mut out = Vec::with_capacity(tile.len() / 8);
    let mut e = jpeg_encoder::Encoder::new(&mut out, quality);
    e.set_sampling_factor(jpeg_encoder::SamplingFactor::R_4_2_0);
    e.encode(tile, w, h, colour).map_err(|e| Error::Internal(format!("jpeg coding failed: {e}")))?;
    Ok(out)
}

/// Pixels without a value (`valid` 0) in blocks of `block`² pixels that
/// also hold pixels with one take the nearest valid pixel's value along
/// their row (rows with none, the nearest such row's): a lossy block
/// coded across a step from image to black rings into the image (twice
/// the error at the mask's edge, measured); smoothly continued, it does
/// not. Blocks are coded apart, so only mixed blocks matter.
fn fill_holes(tile: &mut [u8], valid: &[u8], w: usize, h: usize, bands: usize, block: usize) {
    for by in (0..h).step_by(block) {
        for bx in (0..w).step_by(block) {
            let (bw, bh) = (block.min(w - bx), block.min(h - by));
            let at = |x: usize, y: usize| (by + y) * w + bx + x;
            let count: usize = (0..bh).map(|y| valid[at(0, y)..at(bw, y)].iter().filter(|&&v| v != 0).count()).sum();
            if count == 0 || count == bw * bh {
                continue;
            }
            let mut row_has = [false; 64];
            for y in 0..bh {
                let row = &valid[at(0, y)..at(bw, y)];
                row_has[y] = row.iter().any(|&v| v != 0);
                if !row_has[y] {
                    continue;
                }
                for x in 0..bw {
                    if row[x] != 0 {
                        continue;
                    }
                    // The nearest valid pixel of the row (the left one on a tie).
                    let from =
                        (1..bw).flat_map(|d| [x.checked_sub(d), Some(x + d).filter(|&r| r < bw)]).flatten().find(|&i| row[i] != 0).expect("the row has one");
                    let (to, src) = (at(x, y) * bands, at(from, y) * bands);
                    tile.copy_within(src..src + bands, to);
                }
            }
            for y in 0..bh {
                if row_has[y] {
                    continue;
                }
                let from = (1..bh).flat_map(|d| [y.checked_sub(d), Some(y + d).filter(|&r| r < bh)]).flatten().find(|&r| row_has[r]).expect("a row has one");
                let (to, src) = (at(0, y) * bands, at(0, from) * bands);
                tile.copy_within(src..src + bw * bands, to);
            }
        }
    }
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
/// (docs/BENCHMARKS.md); at 0 by Huffman codes alone ([`super::huffman`]),
/// the fastest.
pub fn zlib(bytes: &[u8], level: u8) -> Vec<u8> {
    if level == 0 {
        // Huffman codes only: on bytes unlike predicted rows (floats,
        // noise) it would come out larger than they are.
        return super::huffman::zlib(bytes).unwrap_or_else(|| zlib(bytes, 1));
    }
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

    /// Holes in a block with image pixels take the nearest image pixel
    /// of their row (rows without any, the nearest such row's); blocks all
    /// hole or all image are left as they are.
    #[test]
    fn holes_take_their_nearest_image_pixel_in_mixed_blocks_only() {
        // 16 × 8 grey in 8 × 8 blocks: the left block has image at x = 2
        // and 5 in rows 1 and 2 only; the right block is all hole.
        let (w, h) = (16, 8);
        let mut valid = vec![0u8; w * h];
        let mut tile = vec![0u8; w * h];
        for y in [1, 2] {
            for x in [2, 5] {
                valid[y * w + x] = 1;
                tile[y * w + x] = (10 * y + x) as u8;
            }
        }
        fill_holes(&mut tile, &valid, w, h, 1, 8);
        let row = |y: usize| tile[y * w..y * w + 8].to_vec();
        // Row 1: 0,1 ← x 2; 3 ← 2 (a tie: the left); 4 ← 5; 6,7 ← 5.
        assert_eq!(row(1), [12, 12, 12, 12, 15, 15, 15, 15]);
        assert_eq!(row(2), [22, 22, 22, 22, 25, 25, 25, 25]);
        assert_eq!(row(0), row(1), "the nearest row with image");
        for y in 3..8 {
            assert_eq!(row(y), row(2), "row {y}");
        }
        assert!((0..h).all(|y| tile[y * w + 8..(y + 1) * w].iter().all(|&v| v == 0)), "an all-hole block stays");
    }

    /// A tile's abbreviated stream with the file's tables put back in
    /// front (as libtiff and the `tiff` crate do) decodes as the whole
    /// stream does, for RGB and grey.
    #[test]
    fn tables_and_abbreviated_tiles_make_the_whole_stream_again() {
        for bands in [1u32, 3] {
            let spec = OutputSpec {
                width: 40,
                height: 40,
                bands,
                sample: SampleType::U8,
                chunking: super::super::Chunking::Tiles(32),
                compression: Compression::Jpeg,
                level: Some(80),
                overview_level: None,
                bigtiff: false,
                photometric: if bands == 3 { 2 } else { 1 },
                alpha: false,
                mask: true,
                geo: None,
                overviews: 0,
                cog: false,
            };
            let pixels: Vec<u8> = (0..spec.tile_bytes()).map(|i| ((i * 37) % 199 + (i / 96) % 40) as u8).collect();
            let whole = jpeg_stream(&spec, &pixels, 80).unwrap();
            let tile = encode_tile(&spec, 0, pixels.clone(), None).unwrap();
            let tables = jpeg_tables(&spec).unwrap();
            assert!(tile.len() + 250 < whole.len(), "the tables are not in the tile");
            let mut joined = tables[..tables.len() - 2].to_vec();
            joined.extend_from_slice(&tile[2..]);
            let decode = |b: &[u8]| zune_jpeg::JpegDecoder::new(b).decode().unwrap();
            assert_eq!(decode(&joined), decode(&whole), "{bands} bands");
            assert_eq!(jpeg_quality_of(&spec, &tables), Some(80));
        }
    }

    /// Every level makes a zlib stream that zlib itself decodes to the
    /// bytes given (GDAL reads them with zlib), and compresses.
    #[test]
    fn every_deflate_level_round_trips_through_zlib() {
        let bytes: Vec<u8> = (0..200_000u32).map(|i| ((i * 7919) % 251 / 9 + (i / 1000) % 7) as u8).collect();
        for level in [0, 1, 2, 6, 12] {
            let z = zlib(&bytes, level);
            let mut back = Vec::new();
            flate2::read::ZlibDecoder::new(&z[..]).read_to_end(&mut back).unwrap();
            assert!(back == bytes, "level {level}");
            // Level 0 looks for no matches: a code a byte (here about 5 bits).
            let most = if level == 0 { bytes.len() * 2 / 3 } else { bytes.len() / 4 };
            assert!(z.len() < most, "level {level}: {} bytes", z.len());
        }
    }

    /// Level 0 (Huffman codes alone) on what it is for, rows of a photograph after the
    /// predictor: small differences around zero. Decodes by zlib, within
    /// a quarter of level 1's size.
    #[test]
    fn level_zero_codes_predicted_rows_nearly_as_tight_as_level_one() {
        let mut state = 12345u32;
        let mut noise = || {
            state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (state >> 16) % 9
        };
        let bytes: Vec<u8> = (0..300_000).map(|_| (noise() as u8).wrapping_sub(4)).collect();
        let (z0, z1) = (zlib(&bytes, 0), zlib(&bytes, 1));
        let mut back = Vec::new();
        flate2::read::ZlibDecoder::new(&z0[..]).read_to_end(&mut back).unwrap();
        assert!(back == bytes);
        assert!(z0.len() * 4 < z1.len() * 5, "{} vs level 1's {}", z0.len(), z1.len());
    }
}
