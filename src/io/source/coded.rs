//! The compressed backend: a chunk (strip or tile) decoded on demand —
//! deflate, LZW, PackBits and zstd by `chunk_codec`, JPEG by the `tiff`
//! crate, a JPEG 2000 area by OpenJPEG — and kept in the cache for the
//! next window.

use super::{decoder_limits, Backend, SampleType, SourceImage};
use crate::error::{Error, Result};
use crate::io::chunk_codec::ChunkCodec;
use std::fs::File;
use std::io::BufReader;
use std::sync::{Arc, Mutex};
use tiff::decoder::{Decoder, DecodingResult};

pub(super) enum Coder {
    /// Deflate, LZW, PackBits, zstd: decoded by `chunk_codec` from the
    /// chunk's bytes, read with `pread`.
    Own(ChunkCodec, File),
    /// JPEG: `tiff` crate decoders, one per concurrent reader; `ycbcr`
    /// when its samples are Y, Cb, Cr to be turned into RGB.
    Tiff { decoders: Mutex<Vec<Decoder<BufReader<File>>>>, ycbcr: bool },
    /// JPEG 2000: each chunk an area decoded by OpenJPEG, once (`spill`
    /// keeps it); `origin` is the image's on the codestream's reference grid.
    Jpeg2000 { origin: (u32, u32), spill: super::jpeg2000::Spill },
}

impl SourceImage {
    /// A decoded chunk (full chunk width, native-endian), from the cache.
    pub(super) fn decoded(&self, k: u32) -> Result<Arc<Vec<u8>>> {
        let Backend::Coded { coder, cache } = &self.backend else { unreachable!("only for coded files") };
        if let Some(v) = cache.lock().expect("cache lock").get(k as usize) {
            return Ok(v);
        }
        let bytes = match coder {
            Coder::Own(codec, file) => self.decode_own(k, codec, file)?,
            Coder::Tiff { decoders, ycbcr } => {
                let mut bytes = self.decode_with_tiff(k, decoders)?;
                if *ycbcr {
                    ycbcr_to_rgb(&mut bytes);
                }
                bytes
            }
            Coder::Jpeg2000 { origin, spill } => spill.chunk(&self.path, k, || super::jpeg2000::decode_chunk(&self.path, &self.info, *origin, k))?,
        };
        let v = Arc::new(bytes);
        cache.lock().expect("cache lock").put(k as usize, v.clone());
        Ok(v)
    }

    /// Chunk `k` decoded by the `tiff` crate, re-padded to the full chunk width.
    fn decode_with_tiff(&self, k: u32, decoders: &Mutex<Vec<Decoder<BufReader<File>>>>) -> Result<Vec<u8>> {
        let mut dec = match decoders.lock().expect("decoder lock").pop() {
            Some(d) => d,
            None => {
                let f = File::open(&self.path).map_err(|e| Error::io(&self.path, e))?;
                Decoder::new(BufReader::new(f)).map_err(|e| Error::from_tiff(&self.path, e))?.with_limits(decoder_limits())
            }
        };
        let result = dec.read_chunk(k);
        decoders.lock().expect("decoder lock").push(dec);
        let result = result.map_err(|e| Error::from_tiff(&self.path, e))?;
        let info = &self.info;
        let spp = if info.planar { 1 } else { info.bands as usize };
        let (cw, ch) = info.chunk;
        let rows = (info.chunk_data_bytes(k) / (cw as u64 * spp as u64 * info.sample.bytes() as u64)) as u32;
        let data_w = if info.tiled { cw } else { info.width };
        let bytes = decoding_bytes(result, info.sample)
            .ok_or_else(|| Error::format(&self.path, format!("chunk {k} decodes to a sample type other than the header's")))?;
        // Tiles at the right edge decode cropped: re-pad them to the chunk
        // width so that every chunk has the same row stride.
        let sb = info.sample.bytes();
        let want_rows = if info.tiled { ch } else { rows };
        let got_w = if info.tiled { (info.width - (k % info.chunks_per_plane() % info.chunks_across()) * cw).min(cw) } else { data_w };
        let got_h = if info.tiled { (info.height - (k % info.chunks_per_plane() / info.chunks_across()) * ch).min(ch) } else { rows };
        if bytes.len() < got_w as usize * got_h as usize * spp * sb {
            return Err(Error::format(&self.path, format!("chunk {k} decodes to fewer bytes than its pixels need")));
        }
        let stride = cw as usize * spp * sb;
        if got_w == cw && got_h == want_rows {
            return Ok(bytes);
        }
        let mut padded = vec![0u8; stride * want_rows as usize];
        let row = got_w as usize * spp * sb;
        for y in 0..got_h as usize {
            padded[y * stride..y * stride + row].copy_from_slice(&bytes[y * row..(y + 1) * row]);
        }
        Ok(padded)
    }

    /// Chunk `k` decoded by `chunk_codec`: tiles are stored whole, so the
    /// bytes come out at the chunk's full width and height already.
    fn decode_own(&self, k: u32, codec: &ChunkCodec, file: &File) -> Result<Vec<u8>> {
        let info = &self.info;
        let (cw, ch) = info.chunk;
        let rows = if info.tiled { ch } else { (info.height - k % info.chunks_per_plane() * ch).min(ch) };
        let stored = (info.offsets[k as usize], info.byte_counts[k as usize]);
        codec.read_chunk(file, &self.path, k as usize, stored, cw as usize, rows as usize, ch as usize)
    }
}

/// JPEG's YCbCr (JFIF, full range) to RGB in place, three bytes a pixel,
/// in libjpeg's fixed-point arithmetic (16 fraction bits, rounded), so that
/// the pixels are those GDAL reads through libjpeg.
pub(super) fn ycbcr_to_rgb(px: &mut [u8]) {
    const ONE: i32 = 1 << 16;
    let fix = |v: f64| (v * ONE as f64 + 0.5) as i32;
    let (cr_r, cb_b, cb_g, cr_g) = (fix(1.402), fix(1.772), fix(0.34414), fix(0.71414));
    for p in px.chunks_exact_mut(3) {
        let (y, cb, cr) = (p[0] as i32, p[1] as i32 - 128, p[2] as i32 - 128);
        let r = y + ((cr_r * cr + ONE / 2) >> 16);
        let g = y + ((-cb_g * cb - cr_g * cr + ONE / 2) >> 16);
        let b = y + ((cb_b * cb + ONE / 2) >> 16);
        p[0] = r.clamp(0, 255) as u8;
        p[1] = g.clamp(0, 255) as u8;
        p[2] = b.clamp(0, 255) as u8;
    }
}

fn decoding_bytes(r: DecodingResult, s: SampleType) -> Option<Vec<u8>> {
    match (r, s) {
        (DecodingResult::U8(v), SampleType::U8) => Some(v),
        (DecodingResult::U16(v), SampleType::U16) => Some(v.iter().flat_map(|x| x.to_ne_bytes()).collect()),
        (DecodingResult::F32(v), SampleType::F32) => Some(v.iter().flat_map(|x| x.to_ne_bytes()).collect()),
        _ => None,
    }
}
