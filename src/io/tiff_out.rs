//! The orthophoto file: a tiled TIFF or BigTIFF with GeoTIFF georeferencing,
//! written on the `tiff` crate's `DirectoryEncoder` (tiles through
//! `write_data`, the tile tables and tags through `write_tag`). Tiles are
//! compressed by the caller's threads (`encode_tile`) and appended in order
//! by one writer. The file is born under a temporary name in the target
//! folder and renamed into place only after it has been re-read and checked.

use crate::error::{Error, Result};
use crate::io::geotiff::write_georef;
use crate::io::source::SampleType;
use std::path::{Path, PathBuf};
use tiff::encoder::compression::{CompressionAlgorithm, Deflate, DeflateLevel, Lzw};
use tiff::encoder::{TiffEncoder, TiffKind, TiffKindBig, TiffKindStandard};
use tiff::tags::Tag;

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Compression {
    None,
    Deflate,
    Lzw,
    Zstd,
}

impl Compression {
    fn tag(self) -> u16 {
        match self {
            Compression::None => 1,
            Compression::Lzw => 5,
            Compression::Deflate => 8,
            Compression::Zstd => 50000,
        }
    }
}

/// North-up georeferencing of a written raster.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GeoTags {
    /// Ground X of the west edge, Y of the north edge, pixel size.
    pub x0: f64,
    pub y0: f64,
    pub gsd: f64,
    pub epsg: u32,
    pub nodata: Option<f64>,
}

/// How the pixels are cut into chunks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Chunking {
    /// Square tiles of this size (a multiple of 16).
    Tiles(u32),
    /// Strips of this many rows (the last one may be shorter).
    Strips(u32),
}

/// Everything about the output file but its pixels.
#[derive(Clone, Debug)]
pub struct OutputSpec {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel, alpha included.
    pub bands: u32,
    pub sample: SampleType,
    pub chunking: Chunking,
    pub compression: Compression,
    pub bigtiff: bool,
    /// Photometric: 1 grey, 2 RGB.
    pub photometric: u16,
    /// The last band is (unassociated) alpha.
    pub alpha: bool,
    pub geo: Option<GeoTags>,
}

impl OutputSpec {
    /// Chunk width and height.
    pub fn chunk(&self) -> (u32, u32) {
        match self.chunking {
            Chunking::Tiles(t) => (t, t),
            Chunking::Strips(r) => (self.width, r.min(self.height)),
        }
    }
    pub fn tiles_across(&self) -> u32 {
        self.width.div_ceil(self.chunk().0)
    }
    pub fn tiles_down(&self) -> u32 {
        self.height.div_ceil(self.chunk().1)
    }
    /// Uncompressed bytes of a full chunk.
    pub fn tile_bytes(&self) -> usize {
        let (w, h) = self.chunk();
        w as usize * h as usize * self.bands as usize * self.sample.bytes()
    }
    /// Horizontal differencing for integer samples under compression.
    fn predictor(&self) -> u16 {
        if self.compression != Compression::None && self.sample != SampleType::F32 {
            2
        } else {
            1
        }
    }
    /// Would a classic TIFF overflow its 32-bit offsets? (uncompressed size
    /// plus tables, with a margin; compressed output is assumed no larger).
    pub fn needs_bigtiff(&self) -> bool {
        let data = self.tile_bytes() as u64 * self.tiles_across() as u64 * self.tiles_down() as u64;
        data + (data >> 6) + (1 << 20) > u32::MAX as u64
    }
}

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
    Ok(match spec.compression {
        Compression::None => tile,
        Compression::Deflate => {
            let mut out = Vec::with_capacity(tile.len() / 2);
            Deflate::with_level(DeflateLevel::Fast).write_to(&mut out, &tile).map_err(io)?;
            out
        }
        Compression::Lzw => {
            let mut out = Vec::with_capacity(tile.len() / 2);
            Lzw.write_to(&mut out, &tile).map_err(io)?;
            out
        }
        Compression::Zstd => zstd::bulk::compress(&tile, 9).map_err(io)?,
    })
}

/// Writes the whole file: `next_tile` yields encoded tiles in row-major
/// order (`Ok(None)` at the end); their offsets go into the directory, which
/// is written last. One directory encoder lives for the whole file, which is
/// why this is a function that pulls tiles rather than an object.
pub fn write_tiled<E, B: AsRef<[u8]>>(
    file: std::fs::File,
    spec: &OutputSpec,
    mut next_tile: impl FnMut() -> std::result::Result<Option<B>, E>,
) -> std::result::Result<(), WriteError<E>> {
    let mut index = 0;
    write_placed(file, spec, || {
        let tile = next_tile()?.map(|t| (index, t));
        index += 1;
        Ok(tile)
    })
}

/// As [`write_tiled`], for tiles that come in any order: `next_tile` yields
/// each tile with its row-major index; every index must come exactly once.
/// The file holds the tiles in the order they came.
pub fn write_placed<E, B: AsRef<[u8]>>(
    file: std::fs::File,
    spec: &OutputSpec,
    next_tile: impl FnMut() -> std::result::Result<Option<(usize, B)>, E>,
) -> std::result::Result<(), WriteError<E>> {
    // Unbuffered on purpose: tiles are large single writes, and every write
    // error (a full disk) must reach us rather than vanish in a buffer's drop.
    let w = file;
    if spec.bigtiff {
        write_kind::<TiffKindBig, E, B>(TiffEncoder::new_big(w)?, spec, next_tile)
    } else {
        write_kind::<TiffKindStandard, E, B>(TiffEncoder::new(w)?, spec, next_tile)
    }
}

/// Either the tile source failed or the file could not be written.
#[derive(Debug)]
pub enum WriteError<E> {
    Source(E),
    Tiff(tiff::TiffError),
}

impl<E> From<tiff::TiffError> for WriteError<E> {
    fn from(e: tiff::TiffError) -> Self {
        WriteError::Tiff(e)
    }
}

fn write_kind<K: TiffKind, E, B: AsRef<[u8]>>(
    mut enc: TiffEncoder<std::fs::File, K>,
    spec: &OutputSpec,
    mut next_tile: impl FnMut() -> std::result::Result<Option<(usize, B)>, E>,
) -> std::result::Result<(), WriteError<E>> {
    let n = (spec.tiles_across() * spec.tiles_down()) as usize;
    // A byte count of 0 marks a tile not written yet (no tile is empty).
    let mut offsets = vec![0u64; n];
    let mut counts = vec![0u64; n];
    let mut written = 0usize;
    let mut dir = enc.image_directory()?;
    if let Some(pad) = page_padding(spec) {
        // Unreferenced bytes (TIFF allows them) so that every tile of an
        // uncompressed output starts on a page of the file: the page cache
        // then takes whole pages, without zeroing and merging the pages
        // two tiles share.
        dir.write_data(&vec![0u8; pad][..])?;
    }
    let misplaced = |k: usize| WriteError::Tiff(tiff::TiffError::UsageError(tiff::UsageError::InvalidCodingUnit(k as u32, n as u32)));
    while let Some((k, tile)) = next_tile().map_err(WriteError::Source)? {
        let tile = tile.as_ref();
        if k >= n || counts[k] != 0 || tile.is_empty() {
            return Err(misplaced(k));
        }
        offsets[k] = dir.write_data(tile)?;
        counts[k] = tile.len() as u64;
        written += 1;
    }
    if written != n {
        return Err(misplaced(written));
    }
    dir.write_tag(Tag::ImageWidth, spec.width)?;
    dir.write_tag(Tag::ImageLength, spec.height)?;
    let bits = vec![(spec.sample.bytes() * 8) as u16; spec.bands as usize];
    dir.write_tag(Tag::BitsPerSample, &bits[..])?;
    dir.write_tag(Tag::Compression, spec.compression.tag())?;
    dir.write_tag(Tag::PhotometricInterpretation, spec.photometric)?;
    dir.write_tag(Tag::SamplesPerPixel, spec.bands as u16)?;
    dir.write_tag(Tag::PlanarConfiguration, 1u16)?;
    let offsets: Vec<K::OffsetType> = offsets.iter().map(|&o| K::convert_offset(o)).collect::<tiff::TiffResult<_>>()?;
    let counts: Vec<K::OffsetType> = counts.iter().map(|&o| K::convert_offset(o)).collect::<tiff::TiffResult<_>>()?;
    match spec.chunking {
        Chunking::Tiles(t) => {
            dir.write_tag(Tag::TileWidth, t)?;
            dir.write_tag(Tag::TileLength, t)?;
            dir.write_tag(Tag::TileOffsets, K::convert_slice(&offsets))?;
            dir.write_tag(Tag::TileByteCounts, K::convert_slice(&counts))?;
        }
        Chunking::Strips(_) => {
            dir.write_tag(Tag::RowsPerStrip, spec.chunk().1)?;
            dir.write_tag(Tag::StripOffsets, K::convert_slice(&offsets))?;
            dir.write_tag(Tag::StripByteCounts, K::convert_slice(&counts))?;
        }
    }
    let format = if spec.sample == SampleType::F32 { 3u16 } else { 1u16 };
    dir.write_tag(Tag::SampleFormat, &vec![format; spec.bands as usize][..])?;
    let colour = if spec.photometric == 2 { 3 } else { 1 };
    if spec.bands > colour {
        let mut extra = vec![0u16; (spec.bands - colour) as usize];
        if spec.alpha {
            *extra.last_mut().expect("at least one extra sample") = 2; // unassociated alpha
        }
        dir.write_tag(Tag::ExtraSamples, &extra[..])?;
    }
    if spec.predictor() != 1 {
        dir.write_tag(Tag::Predictor, spec.predictor())?;
    }
    if let Some(g) = spec.geo {
        write_georef(&mut dir, g.x0, g.y0, g.gsd, g.epsg, g.nodata)?;
    }
    dir.finish()?;
    Ok(())
}

/// The page size tiles of an uncompressed output are aligned to.
const PAGE: u64 = 4096;

/// Bytes to write after the header so that the first tile (and so, each
/// tile being a whole number of pages, every tile) starts on a page:
/// `None` for compressed tiles, whose sizes vary, or tiles that are not
/// whole pages.
pub fn page_padding(spec: &OutputSpec) -> Option<usize> {
    let header = if spec.bigtiff { 16 } else { 8 };
    (spec.compression == Compression::None && spec.tile_bytes() as u64 % PAGE == 0).then_some((PAGE - header) as usize)
}

/// Allocates the first `len` bytes of `file` on disk ahead of the writes
/// (its size stays as it is): ext4 and XFS then skip, for every page
/// written, the bookkeeping of delayed allocation (about 0.15 s of system
/// time for a 1.1 GB output). Where the file system cannot, nothing
/// happens; the writes allocate as usual. Not on tmpfs, whose "disk" is
/// memory: there it would take every page of the output up front, on one
/// thread before any tile is made (0.34 s for a 1.1 GB output), instead of
/// page by page as the writer writes them, beside the resampling.
pub fn reserve(file: &std::fs::File, len: u64) {
    const TMPFS_MAGIC: u64 = 0x0102_1994;
    if rustix::fs::fstatfs(file).is_ok_and(|s| s.f_type as u64 == TMPFS_MAGIC) {
        return;
    }
    let _ = rustix::fs::fallocate(file, rustix::fs::FallocateFlags::KEEP_SIZE, 0, len);
}

/// A temporary file next to the output that becomes the output only when
/// `publish` is called; dropped, it is removed.
pub struct PendingFile {
    /// `None` once published.
    tmp: Option<tempfile::NamedTempFile>,
    target: PathBuf,
}

impl Drop for PendingFile {
    fn drop(&mut self) {
        // The NamedTempFile removes itself right after this.
        if let Some(t) = &self.tmp {
            crate::io::mmap_guard::unregister_cleanup(t.path());
        }
    }
}

impl PendingFile {
    pub fn create(target: &Path) -> Result<PendingFile> {
        let dir = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let name = target.file_name().and_then(|n| n.to_str()).unwrap_or("out");
        let tmp = tempfile::Builder::new().prefix(&format!(".{name}.")).suffix(".partial").tempfile_in(&dir).map_err(|e| Error::io(&dir, e))?;
        crate::io::mmap_guard::register_cleanup(tmp.path());
        Ok(PendingFile { tmp: Some(tmp), target: target.to_path_buf() })
    }

    fn tmp(&self) -> &tempfile::NamedTempFile {
        self.tmp.as_ref().expect("not yet published")
    }

    pub fn file(&self) -> Result<std::fs::File> {
        self.tmp().reopen().map_err(|e| Error::io(self.tmp().path(), e))
    }

    pub fn path(&self) -> &Path {
        self.tmp().path()
    }

    /// Syncs, then renames onto the target (readable by all, as a plain
    /// new file would be; the temporary file was private).
    pub fn publish(self) -> Result<()> {
        self.publish_synced(true)
    }

    /// [`publish`](Self::publish), with the sync only when `sync` (without
    /// it, a power failure soon after may leave the target incomplete).
    pub fn publish_synced(mut self, sync: bool) -> Result<()> {
        use std::os::unix::fs::PermissionsExt;
        let f = self.tmp().as_file();
        f.set_permissions(std::fs::Permissions::from_mode(0o644)).map_err(|e| Error::io(&self.target, e))?;
        if sync {
            f.sync_all().map_err(|e| Error::io(&self.target, e))?;
        }
        let target = self.target.clone();
        let tmp = self.tmp.take().expect("not yet published");
        let tmp_path = tmp.path().to_path_buf();
        crate::io::mmap_guard::unregister_cleanup(&tmp_path);
        tmp.persist(&target).map_err(|e| Error::io(&target, e.error))?;
        Ok(())
    }
}

/// Re-reads a written file's directory and checks its tile tables against
/// the spec and the file length, so that a writer bug never publishes a
/// broken file.
pub fn verify(path: &Path, spec: &OutputSpec) -> Result<()> {
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let len = f.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut dec =
        tiff::decoder::Decoder::new(std::io::BufReader::new(f)).map_err(|e| Error::from_tiff(path, e))?.with_limits(crate::io::source::decoder_limits());
    let bad = |m: String| Error::format(path, format!("written file failed verification: {m}"));
    let (w, h) = dec.dimensions().map_err(|e| Error::from_tiff(path, e))?;
    if (w, h) != (spec.width, spec.height) {
        return Err(bad(format!("size {w}×{h}")));
    }
    let (ot, ct) = match spec.chunking {
        Chunking::Tiles(_) => (Tag::TileOffsets, Tag::TileByteCounts),
        Chunking::Strips(_) => (Tag::StripOffsets, Tag::StripByteCounts),
    };
    let offsets = dec.get_tag_u64_vec(ot).map_err(|e| Error::from_tiff(path, e))?;
    let counts = dec.get_tag_u64_vec(ct).map_err(|e| Error::from_tiff(path, e))?;
    let n = (spec.tiles_across() * spec.tiles_down()) as usize;
    if offsets.len() != n || counts.len() != n {
        return Err(bad(format!("{} tiles, expected {n}", offsets.len())));
    }
    if let Some(k) = offsets.iter().zip(&counts).position(|(&o, &c)| c == 0 || o + c > len) {
        return Err(bad(format!("tile {k} lies outside the file")));
    }
    Ok(())
}

/// Writes a whole raster to `path` (atomically), one row of chunks at a
/// time: `produce(y0, y1, buf)` fills rows `[y0, y1)` (chunky, native-endian,
/// full image width) and may itself run in parallel; the chunks of each row
/// are compressed in parallel. Memory: one row of chunks.
pub fn write_raster(path: &Path, spec: &OutputSpec, produce: impl Fn(u32, u32, &mut [u8]) + Sync) -> Result<()> {
    use rayon::prelude::*;
    let pending = PendingFile::create(path)?;
    let file = pending.file()?;
    let (cw, ch) = spec.chunk();
    let pb = spec.bands as usize * spec.sample.bytes();
    let row_bytes = spec.width as usize * pb;
    let mut band = vec![0u8; row_bytes * ch as usize];
    let mut queue: std::collections::VecDeque<Vec<u8>> = Default::default();
    let mut band_index = 0u32;
    let bands = spec.tiles_down();
    let result = write_tiled(file, spec, || -> Result<Option<Vec<u8>>> {
        if queue.is_empty() {
            if band_index == bands {
                return Ok(None);
            }
            let y0 = band_index * ch;
            let y1 = (y0 + ch).min(spec.height);
            let rows = (y1 - y0) as usize;
            produce(y0, y1, &mut band[..rows * row_bytes]);
            let tiles: Vec<Result<Vec<u8>>> = (0..spec.tiles_across())
                .into_par_iter()
                .map(|tx| {
                    let (x0, x1) = (tx * cw, ((tx + 1) * cw).min(spec.width));
                    // Tiles are always full size (zero padded); strips keep their rows.
                    let out_rows = match spec.chunking {
                        Chunking::Tiles(_) => ch as usize,
                        Chunking::Strips(_) => rows,
                    };
                    let mut t = vec![0u8; cw as usize * out_rows * pb];
                    let n = (x1 - x0) as usize * pb;
                    for y in 0..rows {
                        let s = y * row_bytes + x0 as usize * pb;
                        t[y * cw as usize * pb..][..n].copy_from_slice(&band[s..s + n]);
                    }
                    encode_tile(spec, t)
                })
                .collect();
            for t in tiles {
                queue.push_back(t?);
            }
            band_index += 1;
        }
        Ok(queue.pop_front())
    });
    match result {
        Ok(()) => {}
        Err(WriteError::Source(e)) => return Err(e),
        Err(WriteError::Tiff(e)) => return Err(tiff_write_error(pending.path(), e)),
    }
    verify(pending.path(), spec)?;
    pending.publish()
}

/// A write-side `tiff` error as our error, naming the file.
pub fn tiff_write_error(path: &Path, e: tiff::TiffError) -> Error {
    match e {
        tiff::TiffError::IoError(io) => Error::io(path, io),
        other => Error::format(path, format!("writing failed: {other}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    fn spec(bands: u32, sample: SampleType) -> OutputSpec {
        OutputSpec {
            width: 40,
            height: 16,
            bands,
            sample,
            chunking: Chunking::Tiles(16),
            compression: Compression::Deflate,
            bigtiff: false,
            photometric: 2,
            alpha: false,
            geo: None,
        }
    }

    fn inflate(bytes: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        flate2::read::ZlibDecoder::new(bytes).read_to_end(&mut out).unwrap();
        out
    }

    #[test]
    fn uncompressed_tiles_start_on_pages_and_read_back() {
        // 64×64 RGB tiles are three pages each: after the padding every
        // tile starts on a page, in classic TIFF and BigTIFF; compressed
        // tiles are not padded. The pixels read back as written.
        for (compression, bigtiff) in [(Compression::None, false), (Compression::None, true), (Compression::Deflate, false)] {
            let spec = OutputSpec { width: 150, height: 70, chunking: Chunking::Tiles(64), compression, bigtiff, ..spec(3, SampleType::U8) };
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("t.tif");
            let value = |x: usize, y: usize, b: usize| ((x * 7 + y * 13 + b * 29) % 251) as u8;
            write_raster(&path, &spec, |y0, y1, buf| {
                for (k, v) in buf.iter_mut().enumerate() {
                    let (p, b) = (k / 3, k % 3);
                    *v = value(p % 150, y0 as usize + p / 150, b);
                }
                assert_eq!(buf.len(), (y1 - y0) as usize * 150 * 3);
            })
            .unwrap();
            let mut dec = tiff::decoder::Decoder::new(std::fs::File::open(&path).unwrap()).unwrap();
            let offsets = dec.get_tag_u64_vec(Tag::TileOffsets).unwrap();
            let paged = offsets.iter().all(|o| o % PAGE == 0);
            assert_eq!(paged, compression == Compression::None, "{compression:?} {bigtiff}: {offsets:?}");
            assert_eq!(page_padding(&spec).is_some(), compression == Compression::None);
            let tiff::decoder::DecodingResult::U8(px) = dec.read_image().unwrap() else { panic!("8-bit") };
            assert!(px.iter().enumerate().all(|(k, &v)| v == value((k / 3) % 150, k / 3 / 150, k % 3)), "{compression:?} {bigtiff}");
        }
    }

    #[test]
    fn tiles_written_column_by_column_read_back_in_place() {
        // 3 × 2 tiles of 16×16 grey, sent column by column: the directory
        // puts each where it belongs. A tile sent twice, or one missing, is
        // an error.
        let spec = OutputSpec { width: 40, height: 20, compression: Compression::None, photometric: 1, ..spec(1, SampleType::U8) };
        let tile = |k: usize| vec![k as u8 * 10 + 1; 16 * 16];
        let write = |order: &[usize]| {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("t.tif");
            let mut next = order.iter();
            let r = write_placed(std::fs::File::create(&path).unwrap(), &spec, || -> std::result::Result<_, ()> { Ok(next.next().map(|&k| (k, tile(k)))) });
            (r.map_err(|_| ()), std::fs::read(&path).unwrap())
        };
        let (r, bytes) = write(&[0, 3, 1, 4, 2, 5]);
        assert!(r.is_ok());
        let mut dec = tiff::decoder::Decoder::new(std::io::Cursor::new(bytes)).unwrap();
        let offsets = dec.get_tag_u64_vec(Tag::TileOffsets).unwrap();
        assert!(offsets.windows(2).any(|p| p[1] < p[0]), "stored column by column: {offsets:?}");
        let tiff::decoder::DecodingResult::U8(px) = dec.read_image().unwrap() else { panic!("8-bit") };
        let want = |x: usize, y: usize| (y / 16 * 3 + x / 16) as u8 * 10 + 1;
        assert!(px.iter().enumerate().all(|(k, &v)| v == want(k % 40, k / 40)));
        assert!(write(&[0, 3, 1, 4, 2, 2]).0.is_err(), "a tile twice");
        assert!(write(&[0, 3, 1, 4, 2]).0.is_err(), "a tile missing");
        assert!(write(&[0, 3, 1, 4, 2, 6]).0.is_err(), "a tile past the end");
    }

    #[test]
    fn reserving_space_leaves_the_file_as_it_was() {
        use std::io::{Seek, Write};
        use std::os::unix::fs::MetadataExt;
        let mut f = tempfile::tempfile().unwrap();
        reserve(&f, 1 << 20);
        let m = f.metadata().unwrap();
        assert_eq!(m.len(), 0, "the size is the writes' to set");
        // Allocated where the file system can (ext4, XFS, tmpfs), else nothing.
        assert!(m.blocks() == 0 || m.blocks() * 512 >= 1 << 20, "{} blocks", m.blocks());
        f.write_all(b"II*\0").unwrap();
        f.rewind().unwrap();
        let mut back = String::new();
        f.read_to_string(&mut back).unwrap();
        assert_eq!((back.as_str(), f.metadata().unwrap().len()), ("II*\0", 4));
    }

    #[test]
    fn the_horizontal_predictor_is_each_sample_less_the_same_band_one_pixel_before() {
        // TIFF 6.0, section 14: per row, per band, modulo the sample size.
        for (bands, sample) in [(3u32, SampleType::U8), (4, SampleType::U8), (3, SampleType::U16), (1, SampleType::U16)] {
            let s = spec(bands, sample);
            let b = bands as usize;
            let n = s.tile_bytes() / sample.bytes();
            let mask = if sample == SampleType::U8 { 0xff } else { 0xffff };
            let values: Vec<u16> = (0..n as u32).map(|i| (i.wrapping_mul(2654435761) >> 16) as u16 & mask).collect();
            let row = 16 * b;
            let want: Vec<u16> = (0..n).map(|i| if i % row < b { values[i] } else { values[i].wrapping_sub(values[i - b]) & mask }).collect();
            let bytes = |v: &[u16]| -> Vec<u8> {
                if sample == SampleType::U8 {
                    v.iter().map(|&x| x as u8).collect()
                } else {
                    v.iter().flat_map(|x| x.to_ne_bytes()).collect()
                }
            };
            let (raw, want) = (bytes(&values), bytes(&want));
            let encoded = encode_tile(&s, raw).unwrap();
            assert_eq!(inflate(&encoded), want, "{bands} bands of {sample:?}");
        }
    }
}
