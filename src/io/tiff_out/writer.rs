//! Writing the file: the header, the tiles in any order (their places
//! recorded), the directories with their tile tables and GeoTIFF tags;
//! uncompressed tiles aligned to pages; or the Cloud-Optimized layout.

use super::directory::{header, header_len, Ifd, Value};
use super::{encode_tile, jpeg_tables, verify, Chunking, Compression, OutputSpec, PendingFile, SampleType};
use crate::error::{Error, Result};
use crate::io::geotiff::georef_tags;
use std::io::{Seek, Write};
use std::os::unix::fs::FileExt;
use std::path::Path;

/// Writes the whole file: `next_tile` yields encoded tiles in row-major
/// order (`Ok(None)` at the end). `spool_dir`: where a Cloud-Optimized
/// file keeps its tiles until its directories are written (the target's
/// folder).
pub fn write_tiled<E, B: AsRef<[u8]>>(
    file: std::fs::File,
    spec: &OutputSpec,
    spool_dir: &Path,
    mut next_tile: impl FnMut() -> std::result::Result<Option<B>, E>,
) -> std::result::Result<(), WriteError<E>> {
    let mut index = 0;
    write_placed(file, spec, spool_dir, || {
        let tile = next_tile()?.map(|t| (index, t));
        index += 1;
        Ok(tile)
    })
}

/// As [`write_tiled`], for chunks that come in any order: `next_tile`
/// yields each with its number ([`OutputSpec::chunk_index`]); every number
/// must come exactly once.
pub fn write_placed<E, B: AsRef<[u8]>>(
    file: std::fs::File,
    spec: &OutputSpec,
    spool_dir: &Path,
    mut next_tile: impl FnMut() -> std::result::Result<Option<(usize, B)>, E>,
) -> std::result::Result<(), WriteError<E>> {
    let mut w = TileWriter::new(file, spec, spool_dir)?;
    while let Some((k, tile)) = next_tile().map_err(WriteError::Source)? {
        w.put(k, tile.as_ref())?;
    }
    w.finish(None)?;
    Ok(())
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

impl<E> From<std::io::Error> for WriteError<E> {
    fn from(e: std::io::Error) -> Self {
        WriteError::Tiff(tiff::TiffError::IoError(e))
    }
}

/// A file being written, chunk by chunk in any order. Streamed, each chunk
/// is appended as it comes and the directories follow the last one;
/// Cloud-Optimized, each level's chunks go to a spool of their own (an
/// unnamed temporary file in the target's folder) and the file is laid out
/// at the end: directories, then the levels smallest first, each copied
/// whole where its chunks came in row-major order (the kernel copies it,
/// `copy_file_range`), else chunk by chunk. Replayed, chunks that come in
/// another order than a streamed run's go to a spool, and are appended at
/// the end in that run's order: the same bytes.
pub struct TileWriter {
    out: std::fs::File,
    spec: OutputSpec,
    /// Each chunk's offset (in the file, or in its level's spool) and length;
    /// a length of 0 marks a chunk not written yet (no chunk is empty).
    places: Vec<(u64, u64)>,
    written: usize,
    body: Body,
    /// The tables JPEG chunks are coded with: those of the full level,
    /// and of the overviews (JPEG compression only).
    jpeg_tables: Option<JpegTables>,
}

/// A JPEG file's tables: the full level's, and the overviews'. They differ
/// only where `assemble` copies chunks coded at another quality.
#[derive(Clone)]
struct JpegTables {
    full: Vec<u8>,
    overviews: Vec<u8>,
}

enum Body {
    Streamed {
        pos: u64,
        paged: bool,
    },
    Cog(Vec<Spool>),
    /// The chunks as they came, and the order to write them in.
    Replayed {
        spool: std::io::BufWriter<std::fs::File>,
        len: u64,
        order: Vec<usize>,
    },
}

/// One level's chunks waiting for their place in a Cloud-Optimized file,
/// each between its leader and trailer.
struct Spool {
    file: std::io::BufWriter<std::fs::File>,
    len: u64,
    /// The place in the level's row-major order (image, mask, image, …)
    /// the next chunk must have for the spool to be in that order.
    next: usize,
    in_order: bool,
}

fn misplaced(k: usize, n: usize) -> tiff::TiffError {
    tiff::TiffError::UsageError(tiff::UsageError::InvalidCodingUnit(k as u32, n as u32))
}

impl TileWriter {
    pub fn new(out: std::fs::File, spec: &OutputSpec, spool_dir: &Path) -> std::io::Result<TileWriter> {
        TileWriter::new_in_order(out, spec, spool_dir, None)
    }

    /// As [`TileWriter::new`]; a streamed file's chunks are laid out in
    /// `order` (every chunk's number once), whatever order they come in.
    pub fn new_in_order(mut out: std::fs::File, spec: &OutputSpec, spool_dir: &Path, order: Option<Vec<usize>>) -> std::io::Result<TileWriter> {
        let body = if spec.cog {
            let spools = (0..=spec.overviews)
                .map(|_| {
                    let file = tempfile::tempfile_in(spool_dir)?;
                    Ok(Spool { file: std::io::BufWriter::with_capacity(256 << 10, file), len: 0, next: 0, in_order: true })
                })
                .collect::<std::io::Result<_>>()?;
            Body::Cog(spools)
        } else if let Some(order) = order {
            if order.len() != spec.chunk_count() {
                return Err(std::io::Error::other(format!("{} chunks to lay out in an order of {}", spec.chunk_count(), order.len())));
            }
            let file = tempfile::tempfile_in(spool_dir)?;
            Body::Replayed { spool: std::io::BufWriter::with_capacity(256 << 10, file), len: 0, order }
        } else {
            out.write_all(&header(0, spec.bigtiff))?;
            Body::Streamed { pos: header_len(spec.bigtiff), paged: page_padding(spec).is_some() }
        };
        let jpeg_tables = match spec.compression {
            Compression::Jpeg => {
                let t = jpeg_tables(spec).map_err(|e| std::io::Error::other(e.to_string()))?;
                Some(JpegTables { full: t.clone(), overviews: t })
            }
            _ => None,
        };
        Ok(TileWriter { out, spec: spec.clone(), places: vec![(0, 0); spec.chunk_count()], written: 0, body, jpeg_tables })
    }

    /// The full level's chunks are coded with these JPEG tables (another
    /// file's, whose chunks are copied), not with the spec's.
    pub fn full_level_jpeg_tables(&mut self, tables: Vec<u8>) {
        if let Some(t) = &mut self.jpeg_tables {
            t.full = tables;
        }
    }

    /// Takes chunk `k` ([`OutputSpec::chunk_index`]).
    pub fn put(&mut self, k: usize, chunk: &[u8]) -> std::result::Result<(), tiff::TiffError> {
        let n = self.places.len();
        if k >= n || self.places[k].1 != 0 || chunk.is_empty() {
            return Err(misplaced(k, n));
        }
        let (l, j, of_mask) = self.spec.locate(k);
        match &mut self.body {
            Body::Streamed { pos, paged } => self.places[k] = append(&mut self.out, pos, *paged && !of_mask, chunk)?,
            Body::Replayed { spool, len, .. } => {
                spool.write_all(chunk)?;
                self.places[k] = (*len, chunk.len() as u64);
                *len += chunk.len() as u64;
            }
            Body::Cog(spools) => {
                let s = &mut spools[l as usize];
                let len = u32::try_from(chunk.len()).map_err(|_| misplaced(k, n))?;
                let leader = len.to_le_bytes();
                // The trailer repeats the chunk's last four bytes (those of
                // leader and chunk together where the chunk is shorter).
                let mut tail = [0u8; 4];
                let m = chunk.len().min(4);
                tail[4 - m..].copy_from_slice(&chunk[chunk.len() - m..]);
                tail[..4 - m].copy_from_slice(&leader[m..]);
                s.file.write_all(&leader)?;
                s.file.write_all(chunk)?;
                s.file.write_all(&tail)?;
                self.places[k] = (s.len + 4, chunk.len() as u64);
                s.len += chunk.len() as u64 + 8;
                let place = if self.spec.mask { 2 * j + usize::from(of_mask) } else { j };
                s.in_order &= place == s.next;
                s.next = place + 1;
            }
        }
        self.written += 1;
        Ok(())
    }

    /// Writes the directories (with `gdal_metadata`, GDAL's XML of band
    /// statistics, on the first) and, Cloud-Optimized, lays out the file.
    /// Every chunk must have come.
    pub fn finish(mut self, gdal_metadata: Option<String>) -> std::result::Result<std::fs::File, tiff::TiffError> {
        let n = self.places.len();
        if self.written != n {
            return Err(misplaced(self.written, n));
        }
        let big = self.spec.bigtiff;
        let body = match std::mem::replace(&mut self.body, Body::Streamed { pos: 0, paged: false }) {
            Body::Replayed { spool, order, .. } => self.replay(spool, &order)?,
            body => body,
        };
        match body {
            Body::Replayed { .. } => unreachable!("replayed above"),
            Body::Streamed { mut pos, .. } => {
                if pos % 2 == 1 {
                    self.out.write_all(&[0])?;
                    pos += 1;
                }
                let offsets: Vec<u64> = self.places.iter().map(|p| p.0).collect();
                let ifds = directories(&self.spec, &offsets, &self.places, gdal_metadata, self.jpeg_tables.as_ref());
                let bytes = lay_out(&ifds, pos, big);
                self.out.write_all(&bytes)?;
                self.out.write_all_at(&header(pos, big), 0)?;
            }
            Body::Cog(spools) => self.lay_out_cog(spools, gdal_metadata)?,
        }
        Ok(self.out)
    }

    /// Appends the spooled chunks to the file in `order`, as a streamed
    /// run would have: the body it leaves.
    fn replay(&mut self, spool: std::io::BufWriter<std::fs::File>, order: &[usize]) -> std::io::Result<Body> {
        let spool = spool.into_inner().map_err(|e| e.into_error())?;
        self.out.write_all(&header(0, self.spec.bigtiff))?;
        let mut pos = header_len(self.spec.bigtiff);
        let paged = page_padding(&self.spec).is_some();
        let mut out = std::io::BufWriter::with_capacity(1 << 20, &self.out);
        let mut buf = Vec::new();
        for &k in order {
            let (o, len) = self.places[k];
            buf.resize(len as usize, 0);
            spool.read_exact_at(&mut buf, o)?;
            self.places[k] = append(&mut out, &mut pos, paged && !self.spec.locate(k).2, &buf)?;
        }
        out.flush()?;
        Ok(Body::Streamed { pos, paged })
    }

    fn lay_out_cog(&mut self, spools: Vec<Spool>, gdal_metadata: Option<String>) -> std::result::Result<(), tiff::TiffError> {
        let spec = &self.spec;
        let big = spec.bigtiff;
        let ghost = ghost_header(spec.mask);
        let first = (header_len(big) + ghost.len() as u64).next_multiple_of(2);
        // The directories' size does not depend on the offsets they hold.
        let zeros = vec![0u64; self.places.len()];
        let sizes: u64 = directories(spec, &zeros, &self.places, gdal_metadata.clone(), self.jpeg_tables.as_ref()).iter().map(|d| d.len(big)).sum();
        // Each level's chunks in row-major order, a mask's after its image's.
        let order = |l: u32| {
            (0..spec.level_tile_count(l)).flat_map(move |j| {
                let image = spec.chunk_index(l, j, false);
                let mask = spec.mask.then(|| spec.chunk_index(l, j, true));
                std::iter::once(image).chain(mask)
            })
        };
        let mut offsets = vec![0u64; self.places.len()];
        let mut at = first + sizes;
        for l in (0..=spec.overviews).rev() {
            for k in order(l) {
                offsets[k] = at + 4;
                at += self.places[k].1 + 8;
            }
        }
        let ifds = directories(spec, &offsets, &self.places, gdal_metadata, self.jpeg_tables.as_ref());
        let mut head = header(first, big);
        head.extend_from_slice(&ghost);
        head.resize(first as usize, 0);
        head.extend(lay_out(&ifds, first, big));
        self.out.write_all(&head)?;
        let mut spools: Vec<(std::fs::File, bool)> =
            spools.into_iter().map(|s| s.file.into_inner().map(|f| (f, s.in_order)).map_err(|e| e.into_error())).collect::<std::io::Result<_>>()?;
        for l in (0..=spec.overviews).rev() {
            let (spool, in_order) = &mut spools[l as usize];
            if *in_order {
                spool.seek(std::io::SeekFrom::Start(0))?;
                std::io::copy(spool, &mut self.out)?;
            } else {
                let mut out = std::io::BufWriter::with_capacity(1 << 20, &self.out);
                let mut buf = Vec::new();
                for k in order(l) {
                    let (o, len) = self.places[k];
                    buf.resize(len as usize + 8, 0);
                    spool.read_exact_at(&mut buf, o - 4)?;
                    out.write_all(&buf)?;
                }
                out.flush()?;
            }
        }
        Ok(())
    }
}

/// Appends `chunk` at `pos` (first to a page, `paged`): its place.
fn append(out: &mut impl Write, pos: &mut u64, paged: bool, chunk: &[u8]) -> std::io::Result<(u64, u64)> {
    if paged && !(*pos).is_multiple_of(PAGE) {
        // Unreferenced bytes (TIFF allows them) so that every tile of an
        // uncompressed output starts on a page of the file: the page cache
        // then takes whole pages, without zeroing and merging the pages two
        // tiles share.
        let pad = (PAGE - *pos % PAGE) as usize;
        out.write_all(&vec![0u8; pad])?;
        *pos += pad as u64;
    }
    out.write_all(chunk)?;
    let place = (*pos, chunk.len() as u64);
    *pos += chunk.len() as u64;
    Ok(place)
}

/// GDAL's structural metadata, right after the header of a Cloud-Optimized
/// file: what a reader may rely on without reading the directories (its
/// COG driver writes the same text).
fn ghost_header(mask: bool) -> Vec<u8> {
    let mut body = String::from("LAYOUT=IFDS_BEFORE_DATA\nBLOCK_ORDER=ROW_MAJOR\nBLOCK_LEADER=SIZE_AS_UINT4\nBLOCK_TRAILER=LAST_4_BYTES_REPEATED\n");
    if mask {
        body += "MASK_INTERLEAVED_WITH_IMAGERY=YES\n";
    }
    body += "KNOWN_INCOMPATIBLE_EDITION=NO\n ";
    format!("GDAL_STRUCTURAL_METADATA_SIZE={:06} bytes\n{body}", body.len()).into_bytes()
}

/// The directories one after the other from `at`, chained.
fn lay_out(ifds: &[Ifd], at: u64, big: bool) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut here = at;
    for (i, d) in ifds.iter().enumerate() {
        let next = if i + 1 < ifds.len() { here + d.len(big) } else { 0 };
        bytes.extend(d.encode(here, next, big));
        here += d.len(big);
    }
    bytes
}

/// Every directory of the file, in its order: each level's image, then its
/// mask's (full resolution first). `offsets` and `places` are indexed by
/// [`OutputSpec::chunk_index`].
fn directories(spec: &OutputSpec, offsets: &[u64], places: &[(u64, u64)], gdal_metadata: Option<String>, jpeg_tables: Option<&JpegTables>) -> Vec<Ifd> {
    let mut ifds = Vec::new();
    for l in 0..=spec.overviews {
        let (w, h) = spec.level_size(l);
        let table = |mask: bool| {
            let ks = (0..spec.level_tile_count(l)).map(|j| spec.chunk_index(l, j, mask));
            let (o, c): (Vec<u64>, Vec<u64>) = ks.map(|k| (offsets[k], places[k].1)).unzip();
            (o, c)
        };
        let mut d = Ifd::default();
        if l > 0 {
            d.set(TAG_NEW_SUBFILE_TYPE, Value::Long(vec![1]));
        }
        d.set(256, Value::Long(vec![w]));
        d.set(257, Value::Long(vec![h]));
        d.set(258, Value::Short(vec![(spec.sample.bytes() * 8) as u16; spec.bands as usize]));
        d.set(259, Value::Short(vec![spec.compression.tag()]));
        d.set(262, Value::Short(vec![spec.stored_photometric()]));
        if spec.stored_photometric() == 6 {
            d.set(TAG_YCBCR_SUBSAMPLING, Value::Short(vec![2, 2]));
        }
        if let Some(t) = jpeg_tables {
            d.set(TAG_JPEG_TABLES, Value::Undefined(if l == 0 { t.full.clone() } else { t.overviews.clone() }));
        }
        d.set(277, Value::Short(vec![spec.bands as u16]));
        d.set(284, Value::Short(vec![1]));
        let (o, c) = table(false);
        chunk_tables(&mut d, spec, o, c);
        let format = if spec.sample == SampleType::F32 { 3u16 } else { 1u16 };
        d.set(339, Value::Short(vec![format; spec.bands as usize]));
        let colour = if spec.photometric == 2 { 3 } else { 1 };
        if spec.bands > colour {
            let mut extra = vec![0u16; (spec.bands - colour) as usize];
            if spec.alpha {
                *extra.last_mut().expect("at least one extra sample") = 2; // unassociated alpha
            }
            d.set(338, Value::Short(extra));
        }
        if spec.predictor() != 1 {
            d.set(317, Value::Short(vec![spec.predictor()]));
        }
        if let Some(g) = &spec.geo {
            if l == 0 {
                for (tag, value) in georef_tags(g.x0, g.y0, g.gsd, &g.keys) {
                    d.set(tag, value);
                }
                if let Some(m) = &gdal_metadata {
                    d.set(TAG_GDAL_METADATA, Value::Ascii(m.clone()));
                }
            }
            if let Some(nd) = g.nodata {
                d.set(TAG_GDAL_NODATA, Value::Ascii(format!("{nd}")));
            }
        }
        ifds.push(d);
        if spec.mask {
            // GDAL's internal mask: a 1-bit transparency mask of the same
            // size and tiles.
            let mut m = Ifd::default();
            m.set(TAG_NEW_SUBFILE_TYPE, Value::Long(vec![if l > 0 { 5 } else { 4 }]));
            m.set(256, Value::Long(vec![w]));
            m.set(257, Value::Long(vec![h]));
            m.set(258, Value::Short(vec![1]));
            m.set(259, Value::Short(vec![Compression::Deflate.tag()]));
            m.set(262, Value::Short(vec![4]));
            m.set(277, Value::Short(vec![1]));
            m.set(284, Value::Short(vec![1]));
            let (o, c) = table(true);
            chunk_tables(&mut m, spec, o, c);
            ifds.push(m);
        }
    }
    ifds
}

const TAG_NEW_SUBFILE_TYPE: u16 = 254;
const TAG_GDAL_METADATA: u16 = 42112;
const TAG_YCBCR_SUBSAMPLING: u16 = 530;
const TAG_JPEG_TABLES: u16 = 347;
const TAG_GDAL_NODATA: u16 = 42113;

/// The chunk size and table tags of a directory.
fn chunk_tables(d: &mut Ifd, spec: &OutputSpec, offsets: Vec<u64>, counts: Vec<u64>) {
    match spec.chunking {
        Chunking::Tiles(t) => {
            d.set(322, Value::Long(vec![t]));
            d.set(323, Value::Long(vec![t]));
            d.set(324, Value::Offsets(offsets));
            d.set(325, Value::Offsets(counts));
        }
        Chunking::Strips(_) => {
            d.set(278, Value::Long(vec![spec.chunk().1]));
            d.set(273, Value::Offsets(offsets));
            d.set(279, Value::Offsets(counts));
        }
    }
}

/// The page size tiles of an uncompressed output are aligned to.
pub(super) const PAGE: u64 = 4096;

/// Bytes to write after the header so that the first tile (and so, each
/// tile being a whole number of pages, every tile) starts on a page:
/// `None` for compressed tiles, whose sizes vary, tiles that are not
/// whole pages, or the Cloud-Optimized layout (tiles between leaders). (A mask's tiles between them are padded to whole pages.)
pub fn page_padding(spec: &OutputSpec) -> Option<usize> {
    let header = if spec.bigtiff { 16 } else { 8 };
    (!spec.cog && spec.compression == Compression::None && (spec.tile_bytes() as u64).is_multiple_of(PAGE)).then_some((PAGE - header) as usize)
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
    let result = write_tiled(file, spec, &crate::io::publish::folder_of(path), || -> Result<Option<Vec<u8>>> {
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
                    encode_tile(spec, 0, t, None)
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
