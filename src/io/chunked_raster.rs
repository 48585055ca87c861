//! A single-band TIFF (a DEM) read a chunk at a time as `f32` heights:
//! strips or tiles, uncompressed or compressed, any integer or float sample
//! type GDAL writes for elevations. Chunks are decoded by `chunk_codec` from
//! bytes read with `pread`, so any number of threads read at once.

use crate::error::{Error, Result};
use crate::io::chunk_codec::{file_is_big_endian, ChunkCodec};
use crate::io::file_pool::PooledFile;
use std::fs::File;
use std::io::BufReader;
use std::path::Path;
use tiff::decoder::Decoder;
use tiff::tags::Tag;

/// The sample types a DEM may have.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Sample {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    F32,
    F64,
}

impl Sample {
    fn bytes(self) -> usize {
        match self {
            Sample::U8 | Sample::I8 => 1,
            Sample::U16 | Sample::I16 => 2,
            Sample::U32 | Sample::I32 | Sample::F32 => 4,
            Sample::F64 => 8,
        }
    }

    /// The first `out.len()` native-endian samples of `bytes` to heights, into `out`.
    fn to_f32_into(self, bytes: &[u8], out: &mut [f32]) {
        fn each<const N: usize>(bytes: &[u8], out: &mut [f32], f: impl Fn([u8; N]) -> f32) {
            for (o, c) in out.iter_mut().zip(bytes.chunks_exact(N)) {
                *o = f(c.try_into().expect("N bytes"));
            }
        }
        match self {
            Sample::U8 => each(bytes, out, |[b]| f32::from(b)),
            Sample::I8 => each(bytes, out, |[b]| f32::from(b as i8)),
            Sample::U16 => each(bytes, out, |b| f32::from(u16::from_ne_bytes(b))),
            Sample::I16 => each(bytes, out, |b| f32::from(i16::from_ne_bytes(b))),
            Sample::U32 => each(bytes, out, |b| u32::from_ne_bytes(b) as f32),
            Sample::I32 => each(bytes, out, |b| i32::from_ne_bytes(b) as f32),
            Sample::F32 => each(bytes, out, f32::from_ne_bytes),
            Sample::F64 => each(bytes, out, |b| f64::from_ne_bytes(b) as f32),
        }
    }
}

/// A single-band raster's chunk table and coding.
pub struct ChunkedRaster {
    /// Through the pool: a DEM of many tiles holds few handles.
    file: PooledFile,
    pub width: usize,
    pub height: usize,
    /// (width, height) of a chunk: a tile, or a strip (image width × rows).
    pub chunk: (usize, usize),
    tiled: bool,
    offsets: Vec<u64>,
    counts: Vec<u64>,
    codec: ChunkCodec,
    sample: Sample,
    /// Chunks decoded so far (what a summary's reading costs, for tests).
    decoded: std::sync::atomic::AtomicUsize,
}

impl ChunkedRaster {
    /// Reads the layout from `dec`'s current directory (a decoder opened on
    /// `path`); refuses what it cannot read, naming the file.
    pub fn open(dec: &mut Decoder<BufReader<File>>, path: &Path) -> Result<ChunkedRaster> {
        let tf = |e| Error::from_tiff(path, e);
        let (w, h) = dec.dimensions().map_err(tf)?;
        let (width, height) = (w as usize, h as usize);
        if width == 0 || height == 0 {
            return Err(Error::format(path, format!("raster of {w}×{h} samples is empty")));
        }
        let bands = dec.find_tag_unsigned::<u32>(Tag::SamplesPerPixel).map_err(tf)?.unwrap_or(1);
        if bands != 1 {
            return Err(Error::format(path, format!("a DEM must be a single-band raster, this one has {bands} bands")));
        }
        let bits = dec.find_tag_unsigned_vec::<u16>(Tag::BitsPerSample).map_err(tf)?.unwrap_or_else(|| vec![1]);
        let format = dec.find_tag_unsigned_vec::<u16>(Tag::SampleFormat).map_err(tf)?.unwrap_or_else(|| vec![1]);
        let sample = match (bits[0], format[0]) {
            (8, 1) => Sample::U8,
            (8, 2) => Sample::I8,
            (16, 1) => Sample::U16,
            (16, 2) => Sample::I16,
            (32, 1) => Sample::U32,
            (32, 2) => Sample::I32,
            (32, 3) => Sample::F32,
            (64, 3) => Sample::F64,
            (b, f) => return Err(Error::unsupported(path, format!("DEM samples of {b} bits, sample format {f}"))),
        };
        let compression = dec.find_tag_unsigned::<u16>(Tag::Compression).map_err(tf)?.unwrap_or(1);
        let predictor = dec.find_tag_unsigned::<u16>(Tag::Predictor).map_err(tf)?.unwrap_or(1);
        let tiled = dec.find_tag(Tag::TileWidth).map_err(tf)?.is_some();
        let (chunk, (ot, ct)) = if tiled {
            let tw = dec.get_tag_u32(Tag::TileWidth).map_err(tf)? as usize;
            let th = dec.get_tag_u32(Tag::TileLength).map_err(tf)? as usize;
            ((tw, th), (Tag::TileOffsets, Tag::TileByteCounts))
        } else {
            let rps = dec.find_tag_unsigned::<u32>(Tag::RowsPerStrip).map_err(tf)?.unwrap_or(h).clamp(1, h) as usize;
            ((width, rps), (Tag::StripOffsets, Tag::StripByteCounts))
        };
        if chunk.0 == 0 || chunk.1 == 0 {
            return Err(Error::format(path, format!("chunks of {}×{} samples", chunk.0, chunk.1)));
        }
        // A chunk is decoded whole into memory.
        if (chunk.0 as u64 * chunk.1 as u64).saturating_mul(sample.bytes() as u64) > crate::io::format::decoder_limits().decoding_buffer_size as u64 {
            return Err(Error::limits(path, format!("chunks of {}×{} samples are too large to decode (re-tile the file)", chunk.0, chunk.1)));
        }
        let offsets = dec.get_tag_u64_vec(ot).map_err(tf)?;
        let counts = dec.get_tag_u64_vec(ct).map_err(tf)?;
        let file = PooledFile::open(path)?;
        let (len, big_endian) = file.with(|f| {
            let len = f.metadata().map_err(|e| Error::io(path, e))?.len();
            Ok((len, file_is_big_endian(f).map_err(|e| Error::io(path, e))?))
        })?;
        let want = width.div_ceil(chunk.0) * height.div_ceil(chunk.1);
        if offsets.len() != want || counts.len() != want {
            return Err(Error::format(path, format!("{} chunk offsets and {} byte counts, the raster needs {want}", offsets.len(), counts.len())));
        }
        if let Some(k) = offsets.iter().zip(&counts).position(|(&o, &n)| o.checked_add(n).is_none_or(|end| end > len)) {
            return Err(Error::format(path, format!("chunk {k} runs past the end of the {len}-byte file: truncated?")));
        }
        let codec = ChunkCodec {
            compression,
            predictor,
            sample_bytes: sample.bytes(),
            float: matches!(sample, Sample::F32 | Sample::F64),
            samples: 1,
            big_endian,
            packed_bits: 0,
        };
        codec.check().map_err(|what| Error::unsupported(path, what))?;
        Ok(ChunkedRaster { file, width, height, chunk, tiled, offsets, counts, codec, sample, decoded: Default::default() })
    }

    /// Chunks across the raster (1 for strips).
    pub fn across(&self) -> usize {
        self.width.div_ceil(self.chunk.0)
    }

    /// Chunk `k`'s heights, row-major with the chunk's full width as the
    /// stride (edge tiles are stored whole); a last strip has fewer rows.
    pub fn chunk(&self, k: usize) -> Result<Vec<f32>> {
        let (mut bytes, mut out) = (Vec::new(), Vec::new());
        self.chunk_into(k, &mut bytes, &mut out)?;
        Ok(out)
    }

    /// [`chunk`](Self::chunk) into `out`, through `bytes`: the room of
    /// both used again.
    pub fn chunk_into(&self, k: usize, bytes: &mut Vec<u8>, out: &mut Vec<f32>) -> Result<()> {
        self.chunk_bytes_into(k, bytes)?;
        out.clear();
        out.resize(bytes.len() / self.sample.bytes(), 0.0);
        self.sample.to_f32_into(bytes, out);
        Ok(())
    }

    /// Chunk `k` as stored, decoded (native-endian samples).
    fn chunk_bytes(&self, k: usize) -> Result<Vec<u8>> {
        let mut bytes = Vec::new();
        self.chunk_bytes_into(k, &mut bytes)?;
        Ok(bytes)
    }

    #[cfg(test)]
    /// Chunks decoded so far.
    pub fn chunks_decoded(&self) -> usize {
        self.decoded.load(std::sync::atomic::Ordering::Relaxed)
    }

    fn chunk_bytes_into(&self, k: usize, bytes: &mut Vec<u8>) -> Result<()> {
        self.decoded.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let (cw, ch) = self.chunk;
        let rows = if self.tiled { ch } else { ch.min(self.height - k * ch) };
        self.file.with(|f| self.codec.read_chunk_into(f, self.file.path(), k, (self.offsets[k], self.counts[k]), (cw, rows, ch), bytes))
    }

    /// Samples `[i0, i0 + w) × [j0, j0 + h)` (inside the raster),
    /// row-major: each chunk they touch decoded once, each row of chunks on
    /// its own (on the current rayon pool).
    pub fn read_window(&self, [i0, j0, w, h]: [usize; 4]) -> Result<Vec<f32>> {
        use rayon::prelude::*;
        let (cw, ch) = self.chunk;
        let mut out = vec![0f32; w * h];
        if w == 0 || h == 0 {
            return Ok(out);
        }
        let ty0 = j0 / ch;
        // Rows of the window by the row of chunks they lie in.
        let first = (ch - j0 % ch).min(h);
        let mut bands: Vec<(usize, &mut [f32])> = Vec::new();
        let (head, mut rest) = out.split_at_mut(first * w);
        bands.push((ty0, head));
        let mut ty = ty0 + 1;
        while !rest.is_empty() {
            let (band, tail) = rest.split_at_mut((ch * w).min(rest.len()));
            bands.push((ty, band));
            (rest, ty) = (tail, ty + 1);
        }
        bands.into_par_iter().try_for_each(|(ty, rows)| {
            let row0 = (ty * ch).max(j0);
            for tx in i0 / cw..=(i0 + w - 1) / cw {
                let chunk = self.chunk(ty * self.across() + tx)?;
                let (a, b) = ((tx * cw).max(i0), ((tx + 1) * cw).min(i0 + w));
                for (r, to) in rows.chunks_exact_mut(w).enumerate() {
                    let at = (row0 + r - ty * ch) * cw;
                    to[a - i0..b - i0].copy_from_slice(&chunk[at + a - tx * cw..at + b - tx * cw]);
                }
            }
            Ok::<(), crate::error::Error>(())
        })?;
        Ok(out)
    }

    /// The whole raster, row-major: each row of chunks read and decoded
    /// on its own (on the current rayon pool).
    pub fn read_all(&self) -> Result<Vec<f32>> {
        use rayon::prelude::*;
        let (cw, ch) = self.chunk;
        let across = self.across();
        let mut all = vec![0f32; self.width * self.height];
        all.par_chunks_mut(self.width * ch).enumerate().try_for_each(|(cy, rows)| {
            for cx in 0..across {
                // Converted straight into place, row by row.
                let bytes = self.chunk_bytes(cy * across + cx)?;
                let x0 = cx * cw;
                let w = cw.min(self.width - x0);
                // (A last strip or row of tiles: as many rows as the raster has.)
                for (from, to) in bytes.chunks_exact(cw * self.sample.bytes()).zip(rows.chunks_exact_mut(self.width)) {
                    self.sample.to_f32_into(from, &mut to[x0..x0 + w]);
                }
            }
            Ok::<(), crate::error::Error>(())
        })?;
        Ok(all)
    }
}
