//! What the scan's TIFF directory says, checked before any pixel is read:
//! size, layout, samples, compression and the chunk table.

use super::{decoder_limits, SampleType};
use crate::error::{Error, Result};
use crate::io::geotiff::{read_georef, read_nodata, GeoRef};
use std::fs::File;
use std::io::BufReader;
use std::path::Path;
use tiff::decoder::Decoder;
use tiff::tags::Tag;

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
    /// The value of pixels without image (GDAL_NODATA), if the file says one.
    pub nodata: Option<f64>,
    /// Bits a sample where they are packed (9 to 15), widened to 16-bit
    /// samples when read; 0 for whole bytes.
    pub packed_bits: u16,
    /// Predictor of compressed data (1 none, 2 horizontal, 3 floating point).
    pub predictor: u16,
    pub georef: Option<GeoRef>,
    pub(super) offsets: Vec<u64>,
    pub(super) byte_counts: Vec<u64>,
    /// The chunk table (offsets, byte counts) of an internal mask (GDAL's:
    /// a later directory, NewSubfileType 4, same size and chunks).
    pub mask: Option<(Vec<u64>, Vec<u64>)>,
    /// The mask's compression (deflate as GDAL writes it, or none).
    pub mask_compression: u16,
    /// A JPEG-compressed file's JPEGTables (the tables its chunks' abbreviated streams are coded with).
    pub jpeg_tables: Option<Vec<u8>>,
}

impl SourceInfo {
    pub fn pixel_bytes(&self) -> usize {
        self.bands as usize * self.sample.bytes()
    }
    pub(super) fn chunks_across(&self) -> u32 {
        self.width.div_ceil(self.chunk.0)
    }
    pub(super) fn chunks_down(&self) -> u32 {
        self.height.div_ceil(self.chunk.1)
    }
    pub(super) fn chunks_per_plane(&self) -> u32 {
        self.chunks_across() * self.chunks_down()
    }
    /// Bytes of one (full) chunk of one plane, uncompressed.
    pub(super) fn chunk_plane_bytes(&self) -> u64 {
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

impl SourceInfo {
    /// Uncompressed bytes that chunk `k` must hold (a last strip may be short).
    pub(super) fn chunk_data_bytes(&self, k: u32) -> u64 {
        if self.tiled {
            return self.chunk_plane_bytes();
        }
        let strip = k % self.chunks_per_plane();
        let rows = (self.height - strip * self.chunk.1).min(self.chunk.1) as u64;
        self.chunk_plane_bytes() / self.chunk.1 as u64 * rows
    }
}

fn tag_u64s(dec: &mut Decoder<BufReader<File>>, tag: Tag, path: &Path) -> Result<Vec<u64>> {
    dec.get_tag_u64_vec(tag).map_err(|e| Error::from_tiff(path, e))
}

/// A scan whose file says its rows are to be shown turned or mirrored
/// (orientation `o` ≠ 1, by its `tag`) is refused: the camera's interior
/// orientation is of the sensor's rows and columns as stored, and a
/// camera file made for the rows as shown would put every pixel elsewhere.
pub(super) fn orientation_refused(path: &Path, tag: &str, o: u32) -> Error {
    let what = match o {
        2 => "to be shown mirrored left to right",
        3 => "to be shown turned 180°",
        4 => "to be shown mirrored top to bottom",
        5 => "to be shown mirrored and turned 90°",
        6 => "to be shown turned 90° clockwise",
        7 => "to be shown mirrored and turned 90° anticlockwise",
        8 => "to be shown turned 90° anticlockwise",
        _ => "a value TIFF and EXIF do not define",
    };
    Error::unsupported(
        path,
        format!(
            "its {tag} is {o} ({what}): the camera model is of the rows as stored; clear the tag (exiftool -Orientation=1 -n) if the camera file was made for the stored rows"
        ),
    )
}

pub(super) fn read_info(dec: &mut Decoder<BufReader<File>>, path: &Path, file_len: u64) -> Result<SourceInfo> {
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
        // 9 to 15 bits (a 12-bit satellite image) are widened to 16.
        (9..=16, 1) => SampleType::U16,
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
    if let Some(o) = dec.find_tag_unsigned::<u32>(Tag::Orientation).map_err(tf)?.filter(|&o| o != 1) {
        return Err(orientation_refused(path, "TIFF Orientation tag", o));
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
        nodata: read_nodata(dec, path)?,
        packed_bits: if bits[0] % 8 != 0 { bits[0] } else { 0 },
        predictor,
        georef,
        offsets,
        byte_counts,
        mask: None,
        mask_compression: 1,
        jpeg_tables: if compression == 7 { dec.find_tag(Tag::JPEGTables).map_err(tf)?.map(|v| v.into_u8_vec()).transpose().map_err(tf)? } else { None },
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
    if (compression != 1 || info.packed_bits != 0) && info.chunk_plane_bytes() > decoder_limits().decoding_buffer_size as u64 {
        let (cw, ch) = info.chunk;
        return Err(Error::limits(path, format!("compressed chunks of {cw}×{ch} pixels are too large to decode (re-tile the file)")));
    }
    if info.packed_bits != 0 {
        if info.predictor != 1 || compression == 7 {
            return Err(Error::unsupported(path, format!("{}-bit samples with a predictor or JPEG", info.packed_bits)));
        }
    } else if compression == 1 {
        for (k, &n) in info.byte_counts.iter().enumerate() {
            if n < info.chunk_data_bytes(k as u32) {
                return Err(Error::format(path, format!("chunk {k} has {n} bytes, fewer than its pixels need")));
            }
        }
    }
    Ok(info)
}

/// An internal mask's chunk offsets, byte counts and compression.
pub(super) type MaskTable = (Vec<u64>, Vec<u64>, u16);

/// The internal mask's chunk table and compression, where a later
/// directory is one: a 1-bit transparency mask (NewSubfileType 4, not an
/// overview's) of the image's size (GDAL puts it right after the image's,
/// or after the overviews' in files it has added overviews to).
pub(super) fn read_mask_table(dec: &mut Decoder<BufReader<File>>, info: &SourceInfo, path: &Path, file_len: u64) -> Result<Option<MaskTable>> {
    let tf = |e| Error::from_tiff(path, e);
    loop {
        if !dec.more_images() {
            return Ok(None);
        }
        dec.next_image().map_err(tf)?;
        let kind = dec.find_tag_unsigned::<u32>(Tag::NewSubfileType).map_err(tf)?.unwrap_or(0);
        if kind & 5 == 4 && dec.dimensions().map_err(tf)? == (info.width, info.height) {
            break;
        }
    }
    let compression = dec.find_tag_unsigned::<u16>(Tag::Compression).map_err(tf)?.unwrap_or(1);
    let (ot, ct, chunk) = if info.tiled {
        (Tag::TileOffsets, Tag::TileByteCounts, (dec.get_tag_u32(Tag::TileWidth).map_err(tf)?, dec.get_tag_u32(Tag::TileLength).map_err(tf)?))
    } else {
        (
            Tag::StripOffsets,
            Tag::StripByteCounts,
            (info.width, dec.find_tag_unsigned::<u32>(Tag::RowsPerStrip).map_err(tf)?.unwrap_or(info.height).clamp(1, info.height)),
        )
    };
    let (offsets, counts) = (tag_u64s(dec, ot, path)?, tag_u64s(dec, ct, path)?);
    let n = info.chunks_per_plane() as usize;
    if chunk != info.chunk || offsets.len() != n || counts.len() != n {
        return Err(Error::format(path, "its internal mask is not chunked as the image is"));
    }
    if offsets.iter().zip(&counts).any(|(&o, &c)| o.checked_add(c).is_none_or(|end| end > file_len)) {
        return Err(Error::format(path, "a chunk of its internal mask runs past the end of the file: truncated?"));
    }
    Ok(Some((offsets, counts, compression)))
}
