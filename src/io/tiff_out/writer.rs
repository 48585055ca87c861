//! Writing the file: the header, the tiles in any order (their places
//! recorded), the tile tables and the GeoTIFF tags; uncompressed tiles
//! aligned to pages.

use super::{encode_tile, verify, Chunking, Compression, OutputSpec, PendingFile, SampleType};
use crate::error::{Error, Result};
use crate::io::geotiff::write_georef;
use std::path::Path;
use tiff::encoder::{TiffEncoder, TiffKind, TiffKindBig, TiffKindStandard};
use tiff::tags::Tag;

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
    // The image's tiles, then the mask's.
    let n = spec.tile_count() * if spec.mask { 2 } else { 1 };
    // A byte count of 0 marks a tile not written yet (no tile is empty).
    let mut offsets = vec![0u64; n];
    let mut counts = vec![0u64; n];
    let mut written = 0usize;
    let mut dir = enc.image_directory()?;
    let paged = page_padding(spec);
    if let Some(pad) = paged {
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
        if paged.is_some() && k >= spec.tile_count() {
            // A mask's tile, padded so that the next image tile starts on a page.
            let end = offsets[k] + counts[k];
            dir.write_data(&vec![0u8; ((PAGE - end % PAGE) % PAGE) as usize][..])?;
        }
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
    let image = spec.tile_count();
    write_chunk_tables::<K, _>(&mut dir, spec, &offsets[..image], &counts[..image])?;
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
    if spec.mask {
        // GDAL's internal mask: the next directory, a 1-bit transparency
        // mask of the same size and tiles.
        let mut m = enc.image_directory()?;
        m.write_tag(Tag::NewSubfileType, 4u32)?;
        m.write_tag(Tag::ImageWidth, spec.width)?;
        m.write_tag(Tag::ImageLength, spec.height)?;
        m.write_tag(Tag::BitsPerSample, 1u16)?;
        m.write_tag(Tag::Compression, Compression::Deflate.tag())?;
        m.write_tag(Tag::PhotometricInterpretation, 4u16)?;
        m.write_tag(Tag::SamplesPerPixel, 1u16)?;
        m.write_tag(Tag::PlanarConfiguration, 1u16)?;
        write_chunk_tables::<K, _>(&mut m, spec, &offsets[image..], &counts[image..])?;
        m.finish()?;
    }
    Ok(())
}

/// The chunk size and table tags of a directory.
fn write_chunk_tables<K: TiffKind, W: std::io::Write + std::io::Seek>(
    dir: &mut tiff::encoder::DirectoryEncoder<'_, W, K>,
    spec: &OutputSpec,
    offsets: &[K::OffsetType],
    counts: &[K::OffsetType],
) -> tiff::TiffResult<()> {
    match spec.chunking {
        Chunking::Tiles(t) => {
            dir.write_tag(Tag::TileWidth, t)?;
            dir.write_tag(Tag::TileLength, t)?;
            dir.write_tag(Tag::TileOffsets, K::convert_slice(offsets))?;
            dir.write_tag(Tag::TileByteCounts, K::convert_slice(counts))?;
        }
        Chunking::Strips(_) => {
            dir.write_tag(Tag::RowsPerStrip, spec.chunk().1)?;
            dir.write_tag(Tag::StripOffsets, K::convert_slice(offsets))?;
            dir.write_tag(Tag::StripByteCounts, K::convert_slice(counts))?;
        }
    }
    Ok(())
}

/// The page size tiles of an uncompressed output are aligned to.
pub(super) const PAGE: u64 = 4096;

/// Bytes to write after the header so that the first tile (and so, each
/// tile being a whole number of pages, every tile) starts on a page:
/// `None` for compressed tiles, whose sizes vary, or tiles that are not
/// whole pages. (A mask's tiles between them are padded to whole pages.)
pub fn page_padding(spec: &OutputSpec) -> Option<usize> {
    let header = if spec.bigtiff { 16 } else { 8 };
    (spec.compression == Compression::None && spec.tile_bytes() as u64 % PAGE == 0).then_some((PAGE - header) as usize)
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
