//! The compressed backend: a chunk (strip or tile) decoded on demand —
//! deflate, LZW, PackBits and zstd by `chunk_codec`, JPEG by the `tiff`
//! crate (YCbCr by libjpeg), a JPEG 2000 area by OpenJPEG — and kept in the cache for the
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
    /// JPEG of grey or RGB samples: `tiff` crate decoders, one per
    /// concurrent reader.
    Tiff { decoders: Mutex<Vec<Decoder<BufReader<File>>>> },
    /// JPEG of YCbCr samples: libjpeg, to RGB; the chunks read with `pread`.
    LibJpeg(File),
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
            Coder::Tiff { decoders } => self.decode_with_tiff(k, decoders)?,
            // libjpeg's upsampling and colour conversion, as GDAL's.
            Coder::LibJpeg(file) => self.decode_with_libjpeg(k, file)?,
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

    /// YCbCr JPEG chunk `k` decoded to RGB by libjpeg (as libtiff has GDAL
    /// do it: the file's tables before the chunk's abbreviated stream),
    /// re-padded to the full chunk size. The `tiff` crate's decoding with
    /// libjpeg's colour arithmetic after it was 0.2–0.3 levels off in the
    /// mean, from its chroma upsampling.
    fn decode_with_libjpeg(&self, k: u32, file: &File) -> Result<Vec<u8>> {
        use std::os::unix::fs::FileExt;
        let info = &self.info;
        let (at, len) = (info.offsets[k as usize], info.byte_counts[k as usize]);
        if len > info.chunk_plane_bytes() * 4 + (1 << 20) {
            return Err(Error::format(&self.path, format!("JPEG chunk {k}: {len} bytes, more than its pixels could take")));
        }
        let mut chunk = vec![0u8; len as usize];
        file.read_exact_at(&mut chunk, at).map_err(|e| Error::io(&self.path, e))?;
        // The tables (SOI … EOI) without their EOI, then the chunk without its SOI.
        let stream = match &info.jpeg_tables {
            Some(t) if t.len() >= 4 && t.starts_with(&[0xFF, 0xD8]) && t.ends_with(&[0xFF, 0xD9]) && chunk.starts_with(&[0xFF, 0xD8]) => {
                [&t[..t.len() - 2], &chunk[2..]].concat()
            }
            _ => chunk,
        };
        let (cw, ch) = info.chunk;
        let want_rows = if info.tiled { ch } else { (info.chunk_data_bytes(k) / (cw as u64 * 3)) as u32 };
        let jpeg_error = |e: std::io::Error| Error::format(&self.path, format!("JPEG chunk {k}: {e}"));
        // libjpeg reports a fatal error by unwinding; caught here, it is the file's.
        let decoded = std::panic::catch_unwind(|| -> std::result::Result<(usize, usize, Vec<u8>), std::io::Error> {
            let mut rows = mozjpeg::Decompress::new_mem(&stream)?.rgb()?;
            let (w, h) = (rows.width(), rows.height());
            let bytes = rows.read_scanlines::<u8>()?;
            rows.finish()?;
            Ok((w, h, bytes))
        });
        let (w, h, bytes) = match decoded {
            Ok(r) => r.map_err(jpeg_error)?,
            Err(payload) => {
                let why = payload.downcast_ref::<String>().cloned().or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string())).unwrap_or_default();
                return Err(Error::format(&self.path, format!("JPEG chunk {k}: {}", why.trim_start_matches("libjpeg fatal error: "))));
            }
        };
        if w < cw as usize && (info.tiled || w < info.width as usize) || bytes.len() < w * h * 3 {
            return Err(Error::format(&self.path, format!("JPEG chunk {k} decodes to {w}×{h} pixels, fewer than its {cw} columns")));
        }
        // Rows of the chunk's width, as many as it holds (padded with zeros).
        let (stride, row) = (cw as usize * 3, w * 3);
        let mut out = vec![0u8; stride * want_rows as usize];
        for (y, to) in out.chunks_exact_mut(stride).take(h).enumerate() {
            to.copy_from_slice(&bytes[y * row..y * row + stride]);
        }
        Ok(out)
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

fn decoding_bytes(r: DecodingResult, s: SampleType) -> Option<Vec<u8>> {
    match (r, s) {
        (DecodingResult::U8(v), SampleType::U8) => Some(v),
        (DecodingResult::U16(v), SampleType::U16) => Some(v.iter().flat_map(|x| x.to_ne_bytes()).collect()),
        (DecodingResult::F32(v), SampleType::F32) => Some(v.iter().flat_map(|x| x.to_ne_bytes()).collect()),
        _ => None,
    }
}
