//! The scan: a TIFF or BigTIFF, striped or tiled, chunky or planar, read a
//! window at a time. Uncompressed files are memory-mapped and copied from
//! in place (`mapped.rs`; with `io::mmap_guard`, the only `unsafe` of the
//! program); compressed ones are decoded chunk by chunk into a small cache
//! (`coded.rs`). After each window the mapped pages are handed back to the
//! kernel, so resident memory does not grow with the scan, whatever the
//! read pattern (a swing of 90° reads source columns). The header's checks
//! are in `header.rs`.

mod coded;
mod foreign;
mod header;
mod holes;
mod jpeg;
mod jpeg2000;
mod mapped;
mod window;

pub use crate::io::format::{decoder_limits, SampleType};
pub use foreign::ImageFormat;
pub use header::SourceInfo;
pub use holes::{HoleMark, MaskRuns};
pub use window::Window;

use crate::error::{Error, Result};
use crate::io::chunk_cache::ChunkCache;
use crate::io::chunk_codec::{file_is_big_endian, ChunkCodec};
use coded::Coder;
use header::read_info;
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use tiff::decoder::Decoder;

enum Backend {
    /// Uncompressed: read in place from the mapping (or by `pread` where
    /// the file cannot be mapped).
    /// `guard`: the mapping's faults survived (a file truncated
    /// underneath); first, so that it is forgotten before the unmapping.
    Raw { guard: Option<crate::io::mmap_guard::Watched>, map: Option<memmap2::Mmap>, file: File },
    /// Compressed: how chunks are decoded, and a cache of decoded chunks.
    Coded { coder: Coder, cache: Mutex<ChunkCache<u8>> },
}

pub struct SourceImage {
    pub path: PathBuf,
    pub info: SourceInfo,
    backend: Backend,
    /// The internal mask as runs, read on first need.
    mask_runs: std::sync::OnceLock<MaskRuns>,
}

impl SourceImage {
    /// Opens a scan; `cache_bytes` bounds the decoded-chunk cache of
    /// compressed files. A JPEG or PNG is decoded at opening, within the
    /// default memory budget where it is decoded whole (see
    /// [`SourceImage::open_within`]).
    pub fn open(path: &Path, cache_bytes: usize) -> Result<SourceImage> {
        Self::open_within(path, cache_bytes, 128 << 20)
    }

    /// Opens a scan of any format this build reads; an image decoded whole
    /// at opening (a progressive JPEG, an interlaced PNG) must fit `memory`
    /// bytes.
    pub fn open_within(path: &Path, cache_bytes: usize, memory: u64) -> Result<SourceImage> {
        let (info, file) = match ImageFormat::of(path)? {
            ImageFormat::Tiff => return Self::open_tiff(path, cache_bytes),
            ImageFormat::Jpeg => jpeg::decode_jpeg(path, Some(memory))?,
            ImageFormat::Png => foreign::decode_png(path, Some(memory))?,
            ImageFormat::Jpeg2000 => {
                let siz = jpeg2000::read_siz(path)?;
                let info = jpeg2000::info(path, &siz)?;
                let coder = Coder::Jpeg2000 { origin: (siz.x0, siz.y0), spill: jpeg2000::Spill::new(path, &info)? };
                // Chunks come back from the spill at the cost of a copy:
                // the cache's share goes to decoding them instead (OpenJPEG
                // holds several times a chunk's samples while it decodes).
                let cache = cache_bytes.min(2 * info.chunk_plane_bytes() as usize);
                return Ok(SourceImage {
                    path: path.to_path_buf(),
                    info,
                    backend: Backend::Coded { coder, cache: Mutex::new(ChunkCache::new(cache)) },
                    mask_runs: Default::default(),
                });
            }
        };
        let file = file.expect("decoded pixels");
        Ok(SourceImage { path: path.to_path_buf(), info, backend: Self::mapped(path, file), mask_runs: Default::default() })
    }

    /// The header of the scan at `path`, without decoding its pixels.
    pub fn info_of(path: &Path) -> Result<SourceInfo> {
        Ok(match ImageFormat::of(path)? {
            ImageFormat::Tiff => Self::open_tiff(path, 1 << 20)?.info,
            ImageFormat::Jpeg => jpeg::decode_jpeg(path, None)?.0,
            ImageFormat::Png => foreign::decode_png(path, None)?.0,
            ImageFormat::Jpeg2000 => jpeg2000::info(path, &jpeg2000::read_siz(path)?)?,
        })
    }

    /// An uncompressed file, read in place through a mapping where it can be.
    fn mapped(path: &Path, file: File) -> Backend {
        // SAFETY: the mapping is read-only; every chunk's extent was
        // checked against the file's length when its header was read, so
        // no slice we take reaches past the end. The remaining hazard is
        // another process truncating the file while we read it (SIGBUS);
        // the file is opened read-only and we never write through the map.
        let map = unsafe { memmap2::MmapOptions::new().map(&file) }.ok();
        if let Some(m) = &map {
            // The rectifier asks for the rows it will read itself
            // (`will_need_rows`); the kernel's own sequential readahead
            // on top walked the page cache again at every few faults.
            let _ = m.advise(memmap2::Advice::Normal);
            crate::io::mmap_guard::watch_mapped(path);
        }
        let guard = map.as_deref().and_then(crate::io::mmap_guard::watch_range);
        Backend::Raw { map, file, guard }
    }

    fn open_tiff(path: &Path, cache_bytes: usize) -> Result<SourceImage> {
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        let mut dec = Decoder::new(BufReader::new(file.try_clone().map_err(|e| Error::io(path, e))?))
            .map_err(|e| Error::from_tiff(path, e))?
            .with_limits(decoder_limits());
        let mut info = read_info(&mut dec, path, len)?;
        {
            // On a decoder (and file offset) of its own: `dec` stays on the
            // image's directory.
            let mut next = Decoder::new(BufReader::new(File::open(path).map_err(|e| Error::io(path, e))?))
                .map_err(|e| Error::from_tiff(path, e))?
                .with_limits(decoder_limits());
            if let Some((o, c, compression)) = header::read_mask_table(&mut next, &info, path, len)? {
                info.mask = Some((o, c));
                info.mask_compression = compression;
            }
        }
        // Packed samples are widened chunk by chunk, as if compressed.
        let backend = if info.compression == 1 && info.packed_bits == 0 {
            Self::mapped(path, file)
        } else {
            let cache = Mutex::new(ChunkCache::new(cache_bytes));
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
                // YCbCr JPEG is decoded to RGB by libjpeg; the scan is RGB
                // from here on.
                if info.photometric == 6 {
                    if info.bands != 3 || info.sample != SampleType::U8 || info.planar {
                        return Err(Error::unsupported(path, format!("YCbCr JPEG of {} {:?} bands", info.bands, info.sample)));
                    }
                    info.photometric = 2;
                    Coder::LibJpeg(file)
                } else {
                    Coder::Tiff { decoders: Mutex::new(vec![dec]) }
                }
            } else {
                let codec = ChunkCodec {
                    compression: info.compression,
                    predictor: info.predictor,
                    sample_bytes: info.sample.bytes(),
                    float: info.sample == SampleType::F32,
                    samples: if info.planar { 1 } else { info.bands as usize },
                    big_endian: file_is_big_endian(&file).map_err(|e| Error::io(path, e))?,
                    packed_bits: info.packed_bits,
                };
                codec.check().map_err(|what| Error::unsupported(path, what))?;
                Coder::Own(codec, file)
            };
            Backend::Coded { coder, cache }
        };
        Ok(SourceImage { path: path.to_path_buf(), info, backend, mask_runs: Default::default() })
    }

    /// What decoding one chunk holds beyond the chunk itself: OpenJPEG
    /// keeps its samples as 32-bit integers, in the image and the tile
    /// being decoded, and code-block buffers (about eight bytes a sample);
    /// 0 for the other formats, whose decoders hold little.
    pub fn decoding_bytes(&self) -> u64 {
        match &self.backend {
            Backend::Coded { coder: Coder::Jpeg2000 { .. }, .. } => {
                let (w, h) = self.info.chunk;
                8 * w as u64 * h as u64 * self.info.bands as u64
            }
            _ => 0,
        }
    }

    /// At most `n` chunks decoded at once (JPEG 2000; the others decode
    /// on every thread that reads).
    pub fn limit_decoders(&self, n: usize) {
        if let Backend::Coded { coder: Coder::Jpeg2000 { spill, .. }, .. } = &self.backend {
            spill.limit_decoders(n);
        }
    }

    /// How the scan marks pixels without image, its internal mask read
    /// (once) where that is how.
    pub fn hole_mark(&self) -> Result<Option<HoleMark>> {
        let mark = HoleMark::of(&self.info);
        if mark == Some(HoleMark::Mask) && self.mask_runs.get().is_none() {
            let _ = self.mask_runs.set(MaskRuns::read(self)?);
        }
        Ok(mark)
    }

    /// The internal mask's runs, once [`SourceImage::hole_mark`] has read them.
    pub fn mask_runs(&self) -> Option<&MaskRuns> {
        self.mask_runs.get()
    }

    /// An error naming the file where a read of its mapping met the end of
    /// the file, truncated by another process (zeros were read from there
    /// on): checked before an output made of it is published.
    pub fn check_intact(&self) -> Result<()> {
        match &self.backend {
            Backend::Raw { guard: Some(g), .. } if g.truncated() => {
                Err(Error::format(&self.path, "was truncated while being read (its memory map met the end of the file)"))
            }
            _ => Ok(()),
        }
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
        if let Backend::Raw { map: Some(m), file, .. } = &self.backend {
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
                // both cores. In place, unneeded: the resampler reads the
                // mapping.
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
            Backend::Raw { map: None, file, .. } => {
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::tiff_out::{write_raster, Chunking, Compression, OutputSpec};

    /// A 40×30 file of `bands` bands, samples that vary in every direction.
    fn raster(path: &Path, bands: u32, sample: SampleType, chunking: Chunking, compression: Compression) {
        let spec = OutputSpec {
            overviews: 0,
            cog: false,
            width: 40,
            height: 30,
            bands,
            sample,
            chunking,
            compression,
            level: None,
            overview_level: None,
            bigtiff: false,
            photometric: if bands >= 3 { 2 } else { 1 },
            alpha: false,
            mask: false,
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
                overviews: 0,
                cog: false,
                width: w,
                height: h,
                bands: 3,
                sample: SampleType::U8,
                chunking,
                compression: Compression::None,
                level: None,
                overview_level: None,
                bigtiff: false,
                photometric: 2,
                alpha: false,
                mask: false,
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
            overviews: 0,
            cog: false,
            width: 500,
            height: 30,
            bands: 3,
            sample: SampleType::U8,
            chunking: Chunking::Strips(7),
            compression: Compression::None,
            level: None,
            overview_level: None,
            bigtiff: false,
            photometric: 2,
            alpha: false,
            mask: false,
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
