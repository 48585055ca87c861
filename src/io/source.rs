//! The scan: a TIFF or BigTIFF, striped or tiled, chunky or planar, read a
//! window at a time. Uncompressed files are memory-mapped and copied from in
//! place (with `io::mmap_guard`, the only `unsafe` of the program); compressed ones are decoded
//! chunk by chunk into a small cache. After each window
//! the mapped pages are handed back to the kernel, so resident memory does
//! not grow with the scan, whatever the read pattern (a swing of 90° reads
//! source columns).

use crate::error::{Error, Result};
use crate::io::chunk_codec::{file_is_big_endian, ChunkCodec};
use crate::io::geotiff::{read_georef, GeoRef};
use std::collections::HashMap;
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use tiff::decoder::{Decoder, DecodingResult};
use tiff::tags::Tag;

/// The `tiff` decoder limits we use everywhere: generous for real scans,
/// but a header claiming an absurd size must not allocate.
pub fn decoder_limits() -> tiff::decoder::Limits {
    let mut l = tiff::decoder::Limits::default();
    l.decoding_buffer_size = 1 << 30;
    l.ifd_value_size = 64 << 20;
    l.intermediate_buffer_size = 256 << 20;
    l
}

/// Sample types we read and write.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum SampleType {
    U8,
    U16,
    F32,
}

impl SampleType {
    pub fn bytes(self) -> usize {
        match self {
            SampleType::U8 => 1,
            SampleType::U16 => 2,
            SampleType::F32 => 4,
        }
    }
}

/// What the header says about the raster.
#[derive(Clone, Debug)]
pub struct SourceInfo {
    pub width: u32,
    pub height: u32,
    pub bands: u32,
    pub sample: SampleType,
    pub planar: bool,
    /// (width, height) of a chunk: a tile, or a strip (image width × rows per strip).
    pub chunk: (u32, u32),
    pub tiled: bool,
    pub compression: u16,
    pub photometric: u16,
    /// An alpha channel among the bands (ExtraSamples = associated/unassociated alpha).
    pub has_alpha: bool,
    /// Predictor of compressed data (1 none, 2 horizontal, 3 floating point).
    pub predictor: u16,
    pub georef: Option<GeoRef>,
    offsets: Vec<u64>,
    byte_counts: Vec<u64>,
}

impl SourceInfo {
    pub fn pixel_bytes(&self) -> usize {
        self.bands as usize * self.sample.bytes()
    }
    fn chunks_across(&self) -> u32 {
        self.width.div_ceil(self.chunk.0)
    }
    fn chunks_down(&self) -> u32 {
        self.height.div_ceil(self.chunk.1)
    }
    fn chunks_per_plane(&self) -> u32 {
        self.chunks_across() * self.chunks_down()
    }
    /// Bytes of one (full) chunk of one plane, uncompressed.
    fn chunk_plane_bytes(&self) -> u64 {
        let spp = if self.planar { 1 } else { self.bands as u64 };
        self.chunk.0 as u64 * self.chunk.1 as u64 * spp * self.sample.bytes() as u64
    }
    /// Byte offsets and counts of the chunks, as the file records them.
    pub fn chunk_table(&self) -> (&[u64], &[u64]) {
        (&self.offsets, &self.byte_counts)
    }
    pub fn data_bytes(&self) -> u64 {
        self.width as u64 * self.height as u64 * self.pixel_bytes() as u64
    }
}

/// A window of the scan, chunky (band-interleaved), native-endian samples.
/// The bytes live in a `u64` buffer so that they can be viewed as any
/// sample type without misalignment.
#[derive(Default)]
pub struct Window {
    pub x0: u32,
    pub y0: u32,
    pub w: u32,
    pub h: u32,
    buf: Vec<u64>,
    len: usize,
}

impl Window {
    /// A window holding `bytes` (for tests and small rasters).
    pub fn from_bytes(x0: u32, y0: u32, w: u32, h: u32, bytes: &[u8]) -> Window {
        let mut win = Window { x0, y0, w, h, ..Default::default() };
        win.resize(bytes.len());
        win.bytes_mut().copy_from_slice(bytes);
        win
    }
    /// Room for `len` bytes, whatever they held: every caller writes them
    /// all (the chunks a window meets tile it). Zeroing a reused window
    /// first took ~4 % of the CPU time of runs that copy their windows.
    fn resize(&mut self, len: usize) {
        self.buf.resize(len.div_ceil(8), 0);
        self.len = len;
    }
    pub fn bytes(&self) -> &[u8] {
        &bytemuck::cast_slice(&self.buf[..])[..self.len]
    }
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        &mut bytemuck::cast_slice_mut(&mut self.buf[..])[..self.len]
    }
    /// Bytes held (for memory accounting).
    pub fn capacity_bytes(&self) -> usize {
        self.buf.capacity() * 8
    }
}

enum Backend {
    /// Uncompressed: read in place from the mapping (or by `pread` where
    /// the file cannot be mapped).
    Raw { map: Option<memmap2::Mmap>, file: File },
    /// Compressed: how chunks are decoded, and a cache of decoded chunks.
    Coded { coder: Coder, cache: Mutex<ChunkCache> },
}

enum Coder {
    /// Deflate, LZW, PackBits, zstd: decoded by `chunk_codec` from the
    /// chunk's bytes, read with `pread`.
    Own(ChunkCodec, File),
    /// JPEG: `tiff` crate decoders, one per concurrent reader; `ycbcr`
    /// when its samples are Y, Cb, Cr to be turned into RGB.
    Tiff { decoders: Mutex<Vec<Decoder<BufReader<File>>>>, ycbcr: bool },
}

/// Decoded chunks kept for the next window, bounded in bytes.
struct ChunkCache {
    map: HashMap<u32, (Arc<Vec<u8>>, u64)>,
    bytes: usize,
    budget: usize,
    tick: u64,
}

impl ChunkCache {
    fn get(&mut self, k: u32) -> Option<Arc<Vec<u8>>> {
        self.tick += 1;
        let t = self.tick;
        self.map.get_mut(&k).map(|e| {
            e.1 = t;
            e.0.clone()
        })
    }
    fn put(&mut self, k: u32, v: Arc<Vec<u8>>) {
        self.tick += 1;
        self.bytes += v.len();
        if let Some(old) = self.map.insert(k, (v, self.tick)) {
            self.bytes -= old.0.len();
        }
        while self.bytes > self.budget && self.map.len() > 1 {
            let (&oldest, _) = self.map.iter().min_by_key(|(_, e)| e.1).expect("non-empty");
            let (v, _) = self.map.remove(&oldest).expect("present");
            self.bytes -= v.len();
        }
    }
}

pub struct SourceImage {
    pub path: PathBuf,
    pub info: SourceInfo,
    backend: Backend,
}

fn tag_u64s(dec: &mut Decoder<BufReader<File>>, tag: Tag, path: &Path) -> Result<Vec<u64>> {
    dec.get_tag_u64_vec(tag).map_err(|e| Error::from_tiff(path, e))
}

fn read_info(dec: &mut Decoder<BufReader<File>>, path: &Path, file_len: u64) -> Result<SourceInfo> {
    let tf = |e| Error::from_tiff(path, e);
    let (width, height) = dec.dimensions().map_err(tf)?;
    if width == 0 || height == 0 {
        return Err(Error::format(path, format!("image of {width}×{height} pixels is empty")));
    }
    let bands = dec.find_tag_unsigned::<u32>(Tag::SamplesPerPixel).map_err(tf)?.unwrap_or(1);
    if !(1..=4).contains(&bands) {
        return Err(Error::unsupported(path, format!("{bands} samples per pixel (1 to 4 are supported)")));
    }
    let bits = dec.find_tag_unsigned_vec::<u16>(Tag::BitsPerSample).map_err(tf)?.unwrap_or_else(|| vec![1]);
    if bits.iter().any(|&b| b != bits[0]) {
        return Err(Error::unsupported(path, format!("mixed bits per sample {bits:?}")));
    }
    let format = dec.find_tag_unsigned_vec::<u16>(Tag::SampleFormat).map_err(tf)?.unwrap_or_else(|| vec![1]);
    let sample = match (bits[0], format[0]) {
        (8, 1) => SampleType::U8,
        (16, 1) => SampleType::U16,
        (32, 3) => SampleType::F32,
        (b, f) => {
            let kind = match f {
                1 => "unsigned",
                2 => "signed",
                3 => "float",
                _ => "unknown-format",
            };
            return Err(Error::unsupported(path, format!("{b}-bit {kind} samples (8/16-bit unsigned and 32-bit float are supported)")));
        }
    };
    let photometric = dec.find_tag_unsigned::<u16>(Tag::PhotometricInterpretation).map_err(tf)?.unwrap_or(1);
    match photometric {
        0..=2 => {}
        3 => return Err(Error::unsupported(path, "palette (colour-mapped) images")),
        // JPEG's own YCbCr: decoded by the `tiff` crate, turned into RGB here.
        6 if dec.find_tag_unsigned::<u16>(Tag::Compression).map_err(tf)? == Some(7) => {}
        6 => return Err(Error::unsupported(path, "YCbCr images other than JPEG-compressed ones (convert to RGB first)")),
        p => return Err(Error::unsupported(path, format!("photometric interpretation {p}"))),
    }
    let extra = dec.find_tag_unsigned_vec::<u16>(Tag::ExtraSamples).map_err(tf)?.unwrap_or_default();
    let has_alpha = extra.iter().any(|&e| e == 1 || e == 2);
    let planar = dec.find_tag_unsigned::<u16>(Tag::PlanarConfiguration).map_err(tf)?.unwrap_or(1) == 2;
    let compression = dec.find_tag_unsigned::<u16>(Tag::Compression).map_err(tf)?.unwrap_or(1);
    let tiled = dec.find_tag(Tag::TileWidth).map_err(tf)?.is_some();
    let (chunk, offsets, byte_counts) = if tiled {
        let tw = dec.get_tag_u32(Tag::TileWidth).map_err(tf)?;
        let th = dec.get_tag_u32(Tag::TileLength).map_err(tf)?;
        if tw == 0 || th == 0 {
            return Err(Error::format(path, format!("tile size {tw}×{th} is zero")));
        }
        ((tw, th), tag_u64s(dec, Tag::TileOffsets, path)?, tag_u64s(dec, Tag::TileByteCounts, path)?)
    } else {
        let rps = dec.find_tag_unsigned::<u32>(Tag::RowsPerStrip).map_err(tf)?.unwrap_or(height).clamp(1, height);
        ((width, rps), tag_u64s(dec, Tag::StripOffsets, path)?, tag_u64s(dec, Tag::StripByteCounts, path)?)
    };
    let georef = read_georef(dec, path)?;
    let predictor = dec.find_tag_unsigned::<u16>(Tag::Predictor).map_err(tf)?.unwrap_or(1);
    let info = SourceInfo {
        width,
        height,
        bands,
        sample,
        planar: planar && bands > 1,
        chunk,
        tiled,
        compression,
        photometric,
        has_alpha,
        predictor,
        georef,
        offsets,
        byte_counts,
    };
    // Sizes that overflow or chunk tables that do not match are refused
    // before anything is allocated or mapped.
    let pixels = (width as u64).checked_mul(height as u64);
    if pixels.and_then(|p| p.checked_mul(info.pixel_bytes() as u64)).is_none_or(|b| b > 1 << 46) {
        return Err(Error::limits(path, format!("{width}×{height}×{bands} samples is too large")));
    }
    let planes = if info.planar { bands } else { 1 };
    let want = info.chunks_per_plane() as u64 * planes as u64;
    if info.offsets.len() as u64 != want || info.byte_counts.len() as u64 != want {
        return Err(Error::format(path, format!("{} chunk offsets and {} byte counts, the image needs {want}", info.offsets.len(), info.byte_counts.len())));
    }
    for (k, (&o, &n)) in info.offsets.iter().zip(&info.byte_counts).enumerate() {
        if o.checked_add(n).is_none_or(|end| end > file_len) {
            return Err(Error::format(path, format!("chunk {k} ({n} bytes at offset {o}) runs past the end of the {file_len}-byte file: truncated?")));
        }
    }
    // A compressed chunk is decoded whole into memory.
    if compression != 1 && info.chunk_plane_bytes() > decoder_limits().decoding_buffer_size as u64 {
        let (cw, ch) = info.chunk;
        return Err(Error::limits(path, format!("compressed chunks of {cw}×{ch} pixels are too large to decode (re-tile the file)")));
    }
    if compression == 1 {
        for (k, &n) in info.byte_counts.iter().enumerate() {
            if n < info.chunk_data_bytes(k as u32) {
                return Err(Error::format(path, format!("chunk {k} has {n} bytes, fewer than its pixels need")));
            }
        }
    }
    Ok(info)
}

impl SourceInfo {
    /// Uncompressed bytes that chunk `k` must hold (a last strip may be short).
    fn chunk_data_bytes(&self, k: u32) -> u64 {
        if self.tiled {
            return self.chunk_plane_bytes();
        }
        let strip = k % self.chunks_per_plane();
        let rows = (self.height - strip * self.chunk.1).min(self.chunk.1) as u64;
        self.chunk_plane_bytes() / self.chunk.1 as u64 * rows
    }
}

impl SourceImage {
    /// Opens a scan; `cache_bytes` bounds the decoded-chunk cache of
    /// compressed files.
    pub fn open(path: &Path, cache_bytes: usize) -> Result<SourceImage> {
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        let mut dec = Decoder::new(BufReader::new(file.try_clone().map_err(|e| Error::io(path, e))?))
            .map_err(|e| Error::from_tiff(path, e))?
            .with_limits(decoder_limits());
        let mut info = read_info(&mut dec, path, len)?;
        let backend = if info.compression == 1 {
            // SAFETY: the mapping is read-only; every chunk's extent was
            // checked against the file's length in `read_info`, so no slice
            // we take reaches past the end. The remaining hazard is another
            // process truncating the file while we read it (SIGBUS); the
            // file is opened read-only and we never write through the map.
            let map = unsafe { memmap2::MmapOptions::new().map(&file) }.ok();
            if let Some(m) = &map {
                // The rectifier asks for the rows it will read itself
                // (`will_need_rows`); the kernel's own sequential readahead
                // on top walked the page cache again at every few faults
                // (1 GiB after dropping the cache: 0.86x the time with
                // MADV_NORMAL, 6 pairs; from memory 0.98x, 10 pairs).
                let _ = m.advise(memmap2::Advice::Normal);
                crate::io::mmap_guard::watch_mapped(path);
            }
            Backend::Raw { map, file }
        } else {
            let cache = Mutex::new(ChunkCache { map: HashMap::new(), bytes: 0, budget: cache_bytes, tick: 0 });
            let coder = if info.compression == 7 {
                // JPEG: decoded by the `tiff` crate, which hands out the
                // samples of its colour type.
                if let Ok(colour) = dec.colortype() {
                    if !info.planar && u32::from(colour.num_samples()) != info.bands {
                        return Err(Error::unsupported(
                            path,
                            format!("JPEG compression of {} interleaved bands (the decoder delivers {})", info.bands, colour.num_samples()),
                        ));
                    }
                }
                // YCbCr JPEG comes out of the decoder as full-resolution
                // Y, Cb, Cr samples; the scan is RGB from here on.
                let ycbcr = info.photometric == 6;
                if ycbcr {
                    if info.bands != 3 || info.sample != SampleType::U8 || info.planar {
                        return Err(Error::unsupported(path, format!("YCbCr JPEG of {} {:?} bands", info.bands, info.sample)));
                    }
                    info.photometric = 2;
                }
                Coder::Tiff { decoders: Mutex::new(vec![dec]), ycbcr }
            } else {
                let codec = ChunkCodec {
                    compression: info.compression,
                    predictor: info.predictor,
                    sample_bytes: info.sample.bytes(),
                    float: info.sample == SampleType::F32,
                    samples: if info.planar { 1 } else { info.bands as usize },
                    big_endian: file_is_big_endian(&file).map_err(|e| Error::io(path, e))?,
                };
                codec.check().map_err(|what| Error::unsupported(path, what))?;
                Coder::Own(codec, file)
            };
            Backend::Coded { coder, cache }
        };
        Ok(SourceImage { path: path.to_path_buf(), info, backend })
    }

    pub fn is_mapped(&self) -> bool {
        matches!(self.backend, Backend::Raw { map: Some(_), .. })
    }

    /// Reads `[x0, x0+w) × [y0, y0+h)` (clipped to the image by the caller)
    /// into `win`, chunky.
    pub fn read_window(&self, x0: u32, y0: u32, w: u32, h: u32, win: &mut Window) -> Result<()> {
        self.check_size()?;
        self.place(x0, y0, w, h, win);
        self.read_rows(x0, y0, w, h, win.bytes_mut())
    }

    /// `read_window`, with the rows of a tall window read in blocks in
    /// parallel on `pool` where they are read by `pread` (an uncompressed,
    /// chunky scan that is not read in place): a row a call, the windows of
    /// a scan turned 20–70° against the output take more system time than
    /// the resampling of their pixels, and on one thread held up the
    /// workers.
    pub fn read_window_on(&self, pool: &rayon::ThreadPool, x0: u32, y0: u32, w: u32, h: u32, win: &mut Window) -> Result<()> {
        /// Rows a block: ~64 `pread`s, a few hundred µs.
        const BLOCK: usize = 64;
        self.check_size()?;
        self.place(x0, y0, w, h, win);
        let by_rows = matches!(self.backend, Backend::Raw { .. }) && !self.info.planar;
        if !by_rows || w == 0 || (h as usize) < 2 * BLOCK || pool.current_num_threads() < 2 {
            return self.read_rows(x0, y0, w, h, win.bytes_mut());
        }
        use rayon::prelude::*;
        let row_bytes = w as usize * self.info.pixel_bytes();
        pool.install(|| {
            win.bytes_mut().par_chunks_mut(BLOCK * row_bytes).enumerate().try_for_each(|(i, bytes)| {
                let rows = (bytes.len() / row_bytes) as u32;
                self.read_rows(x0, y0 + (i * BLOCK) as u32, w, rows, bytes)
            })
        })
    }

    /// Sets `win` to the window `[x0, x0+w) × [y0, y0+h)`, with room for
    /// its bytes.
    fn place(&self, x0: u32, y0: u32, w: u32, h: u32, win: &mut Window) {
        debug_assert!(x0 + w <= self.info.width && y0 + h <= self.info.height);
        (win.x0, win.y0, win.w, win.h) = (x0, y0, w, h);
        win.resize(w as usize * h as usize * self.info.pixel_bytes());
    }

    /// Rows `[y0, y0+h)`, columns `[x0, x0+w)` into `bytes`, chunky, row
    /// after row.
    fn read_rows(&self, x0: u32, y0: u32, w: u32, h: u32, bytes: &mut [u8]) -> Result<()> {
        let info = &self.info;
        if w == 0 || h == 0 {
            return Ok(());
        }
        let (cw, ch) = info.chunk;
        let (cx0, cx1) = (x0 / cw, (x0 + w - 1) / cw);
        let (cy0, cy1) = (y0 / ch, (y0 + h - 1) / ch);
        for cy in cy0..=cy1 {
            for cx in cx0..=cx1 {
                // Intersection of the chunk with the window.
                let (ix0, ix1) = ((cx * cw).max(x0), ((cx + 1) * cw).min(x0 + w));
                let (iy0, iy1) = ((cy * ch).max(y0), ((cy + 1) * ch).min(y0 + h));
                let planes = if info.planar { info.bands } else { 1 };
                for plane in 0..planes {
                    let k = plane * info.chunks_per_plane() + cy * info.chunks_across() + cx;
                    self.copy_chunk(k, plane, (cx * cw, cy * ch), (ix0, ix1, iy0, iy1), (x0, y0, w as usize), bytes)?;
                }
            }
            // Hand the rows of this chunk row back to the kernel (only
            // planar files are copied through the mapping).
            if info.planar {
                self.release(cy, cx0, cx1);
            }
        }
        Ok(())
    }

    /// Has the file shrunk since it was opened (another process truncating
    /// it)? Checked before each window of a mapped file, so that the map is
    /// never read past the file's end in the ordinary course.
    fn check_size(&self) -> Result<()> {
        if let Backend::Raw { map: Some(m), file } = &self.backend {
            let now = file.metadata().map_err(|e| Error::io(&self.path, e))?.len();
            if now < m.len() as u64 {
                return Err(Error::format(&self.path, format!("the input file was truncated while being read ({} bytes, was {})", now, m.len())));
            }
        }
        Ok(())
    }

    /// The part `r` (columns `ix0..ix1`, rows `iy0..iy1`) of chunk `k` (of
    /// `plane`, whose first pixel is `origin`) into `bytes`, which hold
    /// rows of `w` pixels from `(x0, y0)`.
    #[allow(clippy::too_many_arguments)]
    fn copy_chunk(
        &self,
        k: u32,
        plane: u32,
        origin: (u32, u32),
        r: (u32, u32, u32, u32),
        (win_x0, win_y0, win_w): (u32, u32, usize),
        bytes: &mut [u8],
    ) -> Result<()> {
        let info = &self.info;
        let sb = info.sample.bytes();
        let pb = info.pixel_bytes();
        let spp_in_chunk = if info.planar { 1 } else { info.bands as usize };
        let chunk_row_bytes = info.chunk.0 as usize * spp_in_chunk * sb;
        let (ix0, ix1, iy0, iy1) = r;
        let n = (ix1 - ix0) as usize;
        // Where row `y` of the intersection starts in the chunk and in the window.
        let row_at = |y: u32| {
            let s = (y - origin.1) as usize * chunk_row_bytes + (ix0 - origin.0) as usize * spp_in_chunk * sb;
            (s, ((y - win_y0) as usize * win_w + (ix0 - win_x0) as usize) * pb)
        };
        let mut put = |src: &[u8]| {
            for y in iy0..iy1 {
                let (s, d) = row_at(y);
                if info.planar {
                    let dst = &mut bytes[d..d + n * pb];
                    for i in 0..n {
                        dst[i * pb + plane as usize * sb..][..sb].copy_from_slice(&src[s + i * sb..][..sb]);
                    }
                } else {
                    bytes[d..d + n * pb].copy_from_slice(&src[s..s + n * pb]);
                }
            }
        };
        match &self.backend {
            Backend::Raw { file, .. } if !info.planar => {
                // Copies are read with `pread`, row by row, straight into the
                // window: through the mapping, every row of a tall, narrow
                // window (a scan turned 90°) cost a page fault that mapped
                // 64 KiB around it, and dropping them again a TLB flush on
                // both cores: ~5.6 µs a row, 7–8 s of system time on a 1 GiB
                // scan. In place, unneeded: the resampler reads the mapping.
                use std::os::unix::fs::FileExt;
                let o = info.offsets[k as usize];
                for y in iy0..iy1 {
                    let (s, d) = row_at(y);
                    file.read_exact_at(&mut bytes[d..d + n * pb], o + s as u64).map_err(|e| Error::io(&self.path, e))?;
                }
            }
            Backend::Raw { map: Some(m), .. } => {
                let o = info.offsets[k as usize] as usize;
                let len = info.byte_counts[k as usize] as usize;
                put(&m[o..o + len]);
            }
            Backend::Raw { map: None, file } => {
                use std::os::unix::fs::FileExt;
                // Read only the rows we need.
                let o = info.offsets[k as usize];
                let first = (iy0 - origin.1) as u64 * chunk_row_bytes as u64;
                let last = (iy1 - origin.1) as u64 * chunk_row_bytes as u64;
                let mut buf = vec![0u8; (last - first) as usize];
                file.read_exact_at(&mut buf, o + first).map_err(|e| Error::io(&self.path, e))?;
                // Re-base: `put` indexes from the chunk start.
                let mut full = vec![0u8; last as usize];
                full[first as usize..].copy_from_slice(&buf);
                put(&full);
            }
            Backend::Coded { .. } => {
                let data = self.decoded(k)?;
                put(&data);
            }
        }
        Ok(())
    }

    /// A decoded chunk (full chunk width, native-endian), from the cache.
    fn decoded(&self, k: u32) -> Result<Arc<Vec<u8>>> {
        let Backend::Coded { coder, cache } = &self.backend else { unreachable!("only for coded files") };
        if let Some(v) = cache.lock().expect("cache lock").get(k) {
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
        };
        let v = Arc::new(bytes);
        cache.lock().expect("cache lock").put(k, v.clone());
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
        codec.read_chunk(file, &self.path, k as usize, stored, cw as usize, rows as usize)
    }

    /// Rows `[y0, y0+h)`, columns `[x0, x0+w)` in place in the mapped file,
    /// without copying: the bytes from the window's first pixel to its last,
    /// and the stride of a row in bytes. Only for uncompressed, chunky,
    /// striped files whose strips lie back to back (as most writers lay them
    /// out) and whose samples are aligned in the file; `None` otherwise (read
    /// a copy with `read_window`). Give the rows back with `release_rows`.
    pub fn mapped_rows(&self, x0: u32, y0: u32, w: u32, h: u32) -> Result<Option<(&[u8], usize)>> {
        let info = &self.info;
        let Backend::Raw { map: Some(m), .. } = &self.backend else { return Ok(None) };
        if info.planar || info.tiled || w == 0 || h == 0 || x0 + w > info.width || y0 + h > info.height {
            return Ok(None);
        }
        self.check_size()?;
        let pb = info.pixel_bytes();
        let row_bytes = info.width as usize * pb;
        let rps = info.chunk.1 as usize;
        let (k0, k1) = (y0 as usize / rps, (y0 + h - 1) as usize / rps);
        let first = info.offsets[k0] as usize;
        if (k0..=k1).any(|k| info.offsets[k] as usize != first + (k - k0) * rps * row_bytes) {
            return Ok(None);
        }
        let start = first + (y0 as usize - k0 * rps) * row_bytes + x0 as usize * pb;
        let end = start + (h as usize - 1) * row_bytes + w as usize * pb;
        if end > m.len() || start % info.sample.bytes() != 0 {
            return Ok(None);
        }
        Ok(Some((&m[start..end], row_bytes)))
    }

    /// The mapping and the whole pages that hold rows `[y0, y0+h)` of a
    /// striped, chunky uncompressed scan (from the first row's strip to the
    /// last one's: the strips between, where they lie back to back).
    fn row_pages(&self, y0: u32, h: u32) -> Option<(&memmap2::Mmap, usize, usize)> {
        let Backend::Raw { map: Some(m), .. } = &self.backend else { return None };
        let info = &self.info;
        if info.planar || info.tiled || h == 0 || y0 as u64 + h as u64 > info.height as u64 {
            return None;
        }
        let row_bytes = info.width as u64 * info.pixel_bytes() as u64;
        let rps = info.chunk.1 as u64;
        let (k0, k1) = ((y0 as u64 / rps) as usize, ((y0 + h - 1) as u64 / rps) as usize);
        let start = info.offsets[k0] + (y0 as u64 - k0 as u64 * rps) * row_bytes;
        let end = info.offsets[k1] + ((y0 + h) as u64 - k1 as u64 * rps) * row_bytes;
        let page = 4096;
        let (s, e) = ((start / page * page) as usize, (end.div_ceil(page) * page).min(m.len() as u64) as usize);
        (e > s).then_some((m, s, e))
    }

    /// Asks the kernel to start reading rows `[y0, y0+h)` from disk now
    /// (`MADV_WILLNEED`: one large read ahead of the faults that would
    /// each wait for a small one); nothing where they are in memory.
    pub fn will_need_rows(&self, y0: u32, h: u32) {
        if let Some((m, s, e)) = self.row_pages(y0, h) {
            let _ = m.advise_range(memmap2::Advice::WillNeed, s, e - s);
        }
    }

    /// Gives the mapped pages of rows `[y0, y0+h)` back to the kernel (after
    /// `mapped_rows`); a later read of them faults the same bytes in again.
    pub fn release_rows(&self, y0: u32, h: u32) {
        if let Some((m, s, e)) = self.row_pages(y0, h) {
            // SAFETY: the range lies inside the mapping (`row_pages` clamps
            // it). The mapping is read-only and nothing ever writes the file
            // through it, so MADV_DONTNEED only drops our page-table entries: slices
            // still alive into these pages (another window of the same rows)
            // read the same bytes again, faulted in from the file.
            let _ = unsafe { m.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, s, e - s) };
        }
    }

    /// Gives the mapped pages of chunk row `cy` (columns cx0..=cx1) back.
    fn release(&self, cy: u32, cx0: u32, cx1: u32) {
        let Backend::Raw { map: Some(m), .. } = &self.backend else { return };
        let info = &self.info;
        let planes = if info.planar { info.bands } else { 1 };
        for plane in 0..planes {
            let base = plane * info.chunks_per_plane() + cy * info.chunks_across();
            let (a, b) = ((base + cx0) as usize, (base + cx1) as usize);
            let start = info.offsets[a..=b].iter().min().copied().unwrap_or(0) as usize;
            let end = info.offsets[a..=b].iter().zip(&info.byte_counts[a..=b]).map(|(o, n)| o + n).max().unwrap_or(0) as usize;
            let page = 4096;
            let s = start / page * page;
            let e = end.div_ceil(page) * page;
            let e = e.min(m.len());
            if e > s {
                // SAFETY: the range lies inside the mapping (clamped above)
                // and no slice into it is alive: `copy_chunk` has finished
                // copying this chunk row. MADV_DONTNEED on a read-only file
                // mapping only drops our page-table entries; a later access
                // refaults the same bytes from the file.
                let _ = unsafe { m.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, s, e - s) };
            }
        }
    }
}

/// JPEG's YCbCr (JFIF, full range) to RGB in place, three bytes a pixel,
/// in libjpeg's fixed-point arithmetic (16 fraction bits, rounded), so that
/// the pixels are those GDAL reads through libjpeg.
fn ycbcr_to_rgb(px: &mut [u8]) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::tiff_out::{write_raster, Chunking, Compression, OutputSpec};

    /// A 40×30 file of `bands` bands, samples that vary in every direction.
    fn raster(path: &Path, bands: u32, sample: SampleType, chunking: Chunking, compression: Compression) {
        let spec = OutputSpec {
            width: 40,
            height: 30,
            bands,
            sample,
            chunking,
            compression,
            bigtiff: false,
            photometric: if bands >= 3 { 2 } else { 1 },
            alpha: false,
            geo: None,
        };
        let sb = sample.bytes();
        write_raster(path, &spec, |y0, _, buf| {
            let first = y0 as usize * 40 * bands as usize;
            for (i, v) in buf.chunks_exact_mut(sb).enumerate() {
                let x = ((first + i) as u32 * 37 % 100_003) as f32;
                match sample {
                    SampleType::U8 => v[0] = (x as u32 % 251) as u8,
                    SampleType::U16 => v.copy_from_slice(&((x as u32 * 97 % 65521) as u16).to_ne_bytes()),
                    SampleType::F32 => v.copy_from_slice(&(x.sin() * 1000.0).to_ne_bytes()),
                }
            }
        })
        .unwrap();
    }

    fn whole(img: &SourceImage) -> Vec<u8> {
        let mut win = Window::default();
        img.read_window(0, 0, img.info.width, img.info.height, &mut win).unwrap();
        win.bytes().to_vec()
    }

    #[test]
    fn ycbcr_turns_into_rgb_as_libjpeg_turns_it() {
        // Grey stays grey; a saturated red, green and blue (their JFIF
        // YCbCr worked by hand from the BT.601 matrix, rounded; blue's Cb
        // of 255.5 is clipped, so it comes back as 254).
        let mut px = [128, 128, 128, 0, 128, 128, 255, 128, 128, 76, 85, 255, 150, 44, 21, 29, 255, 107];
        ycbcr_to_rgb(&mut px);
        assert_eq!(px, [128, 128, 128, 0, 0, 0, 255, 255, 255, 254, 0, 0, 0, 255, 1, 0, 0, 254]);
    }

    #[test]
    fn compressed_copies_read_exactly_as_the_uncompressed_file() {
        let dir = tempfile::tempdir().unwrap();
        let mut cases = 0;
        for sample in [SampleType::U8, SampleType::U16, SampleType::F32] {
            for bands in [1, 3, 4] {
                let plain = dir.path().join("plain.tif");
                raster(&plain, bands, sample, Chunking::Strips(7), Compression::None);
                let want = whole(&SourceImage::open(&plain, 1 << 20).unwrap());
                for compression in [Compression::Deflate, Compression::Lzw, Compression::Zstd] {
                    for chunking in [Chunking::Strips(7), Chunking::Strips(30), Chunking::Tiles(16)] {
                        let packed = dir.path().join(format!("packed{cases}.tif"));
                        raster(&packed, bands, sample, chunking, compression);
                        let img = SourceImage::open(&packed, 1 << 20).unwrap();
                        assert_eq!(img.info.bands, bands);
                        let what = format!("{bands}×{sample:?} {chunking:?} {compression:?}");
                        assert!(whole(&img) == want, "{what}");
                        // A window inside, across chunk edges.
                        let mut win = Window::default();
                        img.read_window(13, 5, 20, 17, &mut win).unwrap();
                        let pb = bands as usize * sample.bytes();
                        for y in 0..17 {
                            let src = ((5 + y) * 40 + 13) * pb;
                            assert_eq!(&win.bytes()[y * 20 * pb..(y + 1) * 20 * pb], &want[src..src + 20 * pb], "{what}");
                        }
                        cases += 1;
                    }
                }
            }
        }
        assert_eq!(cases, 81);
    }

    /// Tall windows read in blocks of rows on two threads hold what one
    /// read row after row holds, striped or tiled, to the last row of a
    /// block that ends short.
    #[test]
    fn tall_windows_read_in_parallel_as_in_one_go() {
        let dir = tempfile::tempdir().unwrap();
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        for chunking in [Chunking::Strips(7), Chunking::Tiles(16)] {
            let path = dir.path().join("tall.tif");
            let (w, h) = (37u32, 400u32);
            let spec = OutputSpec {
                width: w,
                height: h,
                bands: 3,
                sample: SampleType::U8,
                chunking,
                compression: Compression::None,
                bigtiff: false,
                photometric: 2,
                alpha: false,
                geo: None,
            };
            write_raster(&path, &spec, |y0, _, buf| {
                for (i, v) in buf.iter_mut().enumerate() {
                    *v = ((y0 as usize * w as usize * 3 + i) * 31 % 253) as u8;
                }
            })
            .unwrap();
            let img = SourceImage::open(&path, 1 << 20).unwrap();
            let want = whole(&img);
            // 391 rows: six blocks of 64 and one of 7.
            let (x0, y0, ww, wh) = (3u32, 5u32, 30u32, 391u32);
            let mut win = Window::default();
            img.read_window_on(&pool, x0, y0, ww, wh, &mut win).unwrap();
            assert_eq!((win.x0, win.y0, win.w, win.h), (x0, y0, ww, wh));
            for y in 0..wh as usize {
                let src = ((y0 as usize + y) * w as usize + x0 as usize) * 3;
                assert_eq!(&win.bytes()[y * ww as usize * 3..(y + 1) * ww as usize * 3], &want[src..src + ww as usize * 3], "{chunking:?} row {y}");
            }
        }
    }

    /// The pages that read-ahead asks for and release gives back hold
    /// exactly the rows asked for (from the first row's first byte to the
    /// last row's last, rounded out to whole pages), and nothing for rows
    /// past the scan or a compressed file.
    #[test]
    fn row_pages_are_the_rows_rounded_out_to_pages() {
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain.tif");
        // Rows of 1500 bytes: pages hold 2.7 rows, strips 7.
        let spec = OutputSpec {
            width: 500,
            height: 30,
            bands: 3,
            sample: SampleType::U8,
            chunking: Chunking::Strips(7),
            compression: Compression::None,
            bigtiff: false,
            photometric: 2,
            alpha: false,
            geo: None,
        };
        write_raster(&plain, &spec, |_, _, buf| buf.fill(7)).unwrap();
        let img = SourceImage::open(&plain, 1 << 20).unwrap();
        let (offsets, _) = img.info.chunk_table();
        let row = 500 * 3;
        for (y0, h) in [(0u32, 1u32), (0, 30), (5, 3), (6, 2), (13, 17), (29, 1), (8, 1)] {
            let (m, s, e) = img.row_pages(y0, h).unwrap();
            let first = offsets[(y0 / 7) as usize] as usize + (y0 % 7) as usize * row;
            let last = offsets[((y0 + h - 1) / 7) as usize] as usize + ((y0 + h - 1) % 7 + 1) as usize * row;
            assert_eq!((s, e), (first / 4096 * 4096, (last.div_ceil(4096) * 4096).min(m.len())), "rows {y0}+{h}");
            img.will_need_rows(y0, h);
            img.release_rows(y0, h);
        }
        assert!(img.row_pages(29, 2).is_none() && img.row_pages(3, 0).is_none());
        img.will_need_rows(29, 2);
        img.release_rows(40, 5);
        let packed = dir.path().join("packed.tif");
        raster(&packed, 3, SampleType::U8, Chunking::Strips(7), Compression::Deflate);
        assert!(SourceImage::open(&packed, 1 << 20).unwrap().row_pages(0, 5).is_none());
    }

    #[test]
    fn a_corrupt_chunk_of_a_four_band_file_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let packed = dir.path().join("packed.tif");
        raster(&packed, 4, SampleType::U8, Chunking::Strips(7), Compression::Deflate);
        let img = SourceImage::open(&packed, 1 << 20).unwrap();
        let (offsets, _) = img.info.chunk_table();
        let mut bytes = std::fs::read(&packed).unwrap();
        for b in &mut bytes[offsets[1] as usize..offsets[1] as usize + 8] {
            *b ^= 0x5A;
        }
        std::fs::write(&packed, &bytes).unwrap();
        let img = SourceImage::open(&packed, 1 << 20).unwrap();
        let mut win = Window::default();
        let e = img.read_window(0, 0, 40, 30, &mut win).unwrap_err().to_string();
        assert!(e.starts_with(&packed.display().to_string()) && e.contains("chunk 1"), "{e}");
    }
}
