//! The orthophoto file: a tiled TIFF or BigTIFF with GeoTIFF georeferencing,
//! written on the `tiff` crate's `DirectoryEncoder` (tiles through
//! `write_data`, the tile tables and tags through `write_tag`). Its layout
//! is an [`OutputSpec`]; tiles are compressed by the caller's threads
//! (`encode.rs`) and appended by one writer (`writer.rs`). The file is born
//! under a temporary name in the target folder (`io/publish.rs`) and
//! renamed into place only after it has been re-read and checked
//! (`verify.rs`).

mod directory;
mod encode;
mod huffman;
mod verify;
mod writer;

pub use crate::io::publish::{folder_of, reserve, PendingFile};
pub use directory::Value as TagValue;
pub use encode::{decode_mask, encode_mask, encode_tile, jpeg_quality_of, jpeg_tables};
#[cfg(feature = "internals")]
pub use encode::zlib;
pub use verify::verify;
pub use writer::{page_padding, tiff_write_error, write_raster, TileWriter};

use crate::io::format::SampleType;

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Compression {
    None,
    Deflate,
    Lzw,
    Zstd,
    /// Lossy, 8-bit only: YCbCr with 2×2 subsampled chroma for RGB
    /// (GDAL's `PHOTOMETRIC=YCBCR`), plain for grey; pixels without a
    /// value are told by the internal mask, never by a value.
    Jpeg,
}

impl Compression {
    /// Whether the file's pixels differ from those given to the coder.
    pub fn is_lossy(self) -> bool {
        self == Compression::Jpeg
    }

    /// The levels a codec takes and the one it gets by default; `None` for
    /// a codec without levels. The defaults are the fastest levels: higher
    /// ones cost far more time than they save space (docs/BENCHMARKS.md).
    /// Deflate's 1–12 are libdeflate's; its 0 is our own Huffman-only
    /// coder (a code fitted to each tile, runs of zeros its only matches),
    /// several times as fast as level 1 on predicted image rows for some
    /// 12 % more bytes: the default where the rows are predicted
    /// ([`OutputSpec::level_of`]), level 1 elsewhere (floats).
    pub fn levels(self) -> Option<(std::ops::RangeInclusive<u8>, u8)> {
        match self {
            Compression::Deflate => Some((0..=12, 1)),
            Compression::Zstd => Some((1..=22, 1)),
            // Its quality, as libjpeg's (and GDAL's JPEG_QUALITY, whose
            // default this is).
            Compression::Jpeg => Some((1..=100, 75)),
            Compression::None | Compression::Lzw => None,
        }
    }

    /// `level`, or the codec's default.
    pub fn level_or_default(self, level: Option<u8>) -> u8 {
        level.or(self.levels().map(|(_, d)| d)).unwrap_or(0)
    }

    fn tag(self) -> u16 {
        match self {
            Compression::None => 1,
            Compression::Lzw => 5,
            Compression::Deflate => 8,
            Compression::Zstd => 50000,
            Compression::Jpeg => 7,
        }
    }

    /// The name its level goes by: JPEG's is its quality.
    pub fn level_name(self) -> &'static str {
        if self == Compression::Jpeg {
            "quality"
        } else {
            "level"
        }
    }
}

/// North-up georeferencing of a written raster.
#[derive(Clone, Debug, PartialEq)]
pub struct GeoTags {
    /// Ground X of the west edge, Y of the north edge, pixel size.
    pub x0: f64,
    pub y0: f64,
    pub gsd: crate::geom::Gsd,
    /// The CRS as GeoTIFF keys.
    pub keys: crate::io::geotiff::GeoKeys,
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
    /// The codec's level (`None`: [`Compression::levels`]' default).
    pub level: Option<u8>,
    /// The overview tiles' level (`None`: `level` when given, else the
    /// codec's fastest coding — overviews are a third more tiles that
    /// compress worse, and viewers only glance at them).
    pub overview_level: Option<u8>,
    pub bigtiff: bool,
    /// Photometric: 1 grey, 2 RGB.
    pub photometric: u16,
    /// The last band is (unassociated) alpha.
    pub alpha: bool,
    /// A 1-bit internal mask says which pixels have a value: GDAL's TIFF
    /// internal mask, a second directory (NewSubfileType 4, transparency
    /// mask) with the same tiles, deflated. Its tiles are numbered after
    /// the image's ([`OutputSpec::mask_tile`]).
    pub mask: bool,
    pub geo: Option<GeoTags>,
    /// Reduced-resolution levels after the full one (2×, 4×, …, each made
    /// from the one before), in directories of their own (NewSubfileType 1)
    /// with their own masks. Tiled output only.
    pub overviews: u32,
    /// The Cloud-Optimized layout: every directory before the tiles, the
    /// smallest level's tiles first, each tile between its byte count and
    /// its last four bytes, a mask's tile right after its image's (GDAL's
    /// COG driver's layout, which its validator checks).
    pub cog: bool,
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
    /// Chunks of the image (of the mask as many again).
    pub fn tile_count(&self) -> usize {
        self.tiles_across() as usize * self.tiles_down() as usize
    }
    /// The number under which the writer takes the mask tile of image tile `k`.
    pub fn mask_tile(&self, k: usize) -> usize {
        self.chunk_index(0, k, true)
    }
    /// The codec level of level `l`'s tiles (0: full resolution). Deflate
    /// without a level asked for codes predicted integer samples with its
    /// fastest coder (level 0, Huffman codes alone: a third of level 1's
    /// CPU for some 12 % more bytes, docs/BENCHMARKS.md), other samples at
    /// level 1; overview tiles take `--overview-level`, else the full
    /// level's. JPEG's overviews keep the full level's quality (one set
    /// of tables).
    pub fn level_of(&self, l: u32) -> u8 {
        let c = self.compression;
        let asked = if l == 0 || c == Compression::Jpeg { self.level } else { self.overview_level.or(self.level) };
        match (asked, c) {
            (None, Compression::Deflate) if self.predictor() == 2 => 0,
            _ => c.level_or_default(asked),
        }
    }
    /// Width and height of level `l` (0: full resolution; each level half
    /// the one before, rounded up).
    pub fn level_size(&self, l: u32) -> (u32, u32) {
        (self.width.div_ceil(1 << l), self.height.div_ceil(1 << l))
    }
    /// Tiles across and down of level `l`.
    pub fn level_tiles(&self, l: u32) -> (u32, u32) {
        let (w, h) = self.level_size(l);
        let (cw, ch) = self.chunk();
        (w.div_ceil(cw), h.div_ceil(ch))
    }
    /// Columns and rows of tile `k` (row-major) of level `l` that are
    /// image, not padding.
    pub fn tile_extent(&self, l: u32, k: usize) -> (usize, usize) {
        let (w, h) = self.level_size(l);
        let (cw, ch) = self.chunk();
        let across = self.level_tiles(l).0 as usize;
        let (x0, y0) = (k % across * cw as usize, k / across * ch as usize);
        ((w as usize - x0).min(cw as usize), (h as usize - y0).min(ch as usize))
    }
    /// Chunks of level `l`'s image.
    pub fn level_tile_count(&self, l: u32) -> usize {
        let (a, d) = self.level_tiles(l);
        a as usize * d as usize
    }
    /// The number under which the writer takes chunk `k` (row-major) of
    /// level `l`, of its image or of its mask: level by level, each level's
    /// image chunks, then its mask's.
    pub fn chunk_index(&self, l: u32, k: usize, mask: bool) -> usize {
        let per = |l: u32| self.level_tile_count(l) * if self.mask { 2 } else { 1 };
        (0..l).map(per).sum::<usize>() + if mask { self.level_tile_count(l) } else { 0 } + k
    }
    /// The level, the chunk's row-major number in it and whether it is a
    /// mask's, of the chunk the writer takes under number `k`.
    pub fn locate(&self, mut k: usize) -> (u32, usize, bool) {
        for l in 0..=self.overviews {
            let n = self.level_tile_count(l);
            if k < n {
                return (l, k, false);
            }
            if self.mask && k < 2 * n {
                return (l, k - n, true);
            }
            k -= n * if self.mask { 2 } else { 1 };
        }
        (self.overviews + 1, k, false)
    }
    /// Every chunk the file holds: all levels, images and masks.
    pub fn chunk_count(&self) -> usize {
        self.chunk_index(self.overviews + 1, 0, false)
    }
    /// Levels to make for an output of `width`×`height` in `tile`-pixel
    /// tiles: halved until one tile holds the level (GDAL's default for
    /// COGs and `gdaladdo`); one level at least on an image over 512 px (a
    /// larger image without overviews is what GDAL's COG validator warns
    /// of; tiles that large hold a whole small image).
    pub fn auto_overviews(width: u32, height: u32, tile: u32) -> u32 {
        let mut l = 0;
        while width.div_ceil(1 << l) > tile || height.div_ceil(1 << l) > tile {
            l += 1;
        }
        if l == 0 && width.max(height) > 512 {
            1
        } else {
            l
        }
    }
    /// Uncompressed bytes of a full chunk.
    pub fn tile_bytes(&self) -> usize {
        let (w, h) = self.chunk();
        w as usize * h as usize * self.bands as usize * self.sample.bytes()
    }
    /// Horizontal differencing for integer samples under lossless compression.
    fn predictor(&self) -> u16 {
        if !matches!(self.compression, Compression::None | Compression::Jpeg) && self.sample != SampleType::F32 {
            2
        } else {
            1
        }
    }
    /// The photometric interpretation the file states: JPEG codes RGB as
    /// YCbCr (TIFF's 6), each tile's chroma subsampled 2×2.
    fn stored_photometric(&self) -> u16 {
        if self.compression == Compression::Jpeg && self.photometric == 2 {
            6
        } else {
            self.photometric
        }
    }

    /// Can the codec hold this layout? `Err` says why not, for the user.
    /// JPEG takes 8-bit grey or RGB only: lossy coding would blur an alpha
    /// band's edges and a nodata value (the internal mask says which
    /// pixels have a value instead), and other band counts have no
    /// colour model in TIFF's JPEG.
    pub fn check_codec(&self) -> std::result::Result<(), String> {
        if self.compression != Compression::Jpeg {
            return Ok(());
        }
        if self.sample != SampleType::U8 {
            return Err(format!("jpeg holds 8-bit samples, these are {}: take deflate or zstd", self.sample.describe()));
        }
        if self.alpha {
            return Err("jpeg holds no alpha band (lossy coding would blur its edges): the internal mask says which pixels have a value; drop ‹alpha›, or take deflate or zstd".into());
        }
        if let Some(v) = self.geo.as_ref().and_then(|g| g.nodata) {
            return Err(format!("jpeg does not keep a nodata value ({v}) exact: the internal mask says which pixels have a value; drop ‹nodata› VALUE"));
        }
        match (self.bands, self.photometric) {
            (1, _) | (3, 2) => Ok(()),
            (b, _) => Err(format!("jpeg holds grey or RGB images, this one has {b} bands: take deflate or zstd")),
        }
    }

    /// Would a classic TIFF overflow its 32-bit offsets? (uncompressed size
    /// plus tables, with a margin; compressed output is assumed no larger).
    pub fn needs_bigtiff(&self) -> bool {
        let level0 = self.tile_bytes() as u64 * self.tiles_across() as u64 * self.tiles_down() as u64;
        // Overviews add at most a third (a quarter, a sixteenth, …), and
        // each level's edge tiles.
        let levels = if self.overviews > 0 { level0 / 3 + self.tile_bytes() as u64 * 4 * self.overviews as u64 } else { 0 };
        let data = level0 + levels;
        data + (data >> 6) + (1 << 20) > u32::MAX as u64
    }
}

/// What to say of an output named as another format (`out.png`): it is a
/// GeoTIFF whatever its name says. `None` for a TIFF's name, or none.
pub fn named_as_other_format(output: &std::path::Path) -> Option<String> {
    let ext = output.extension()?.to_string_lossy().to_lowercase();
    if matches!(ext.as_str(), "tif" | "tiff" | "gtiff" | "gtif") {
        return None;
    }
    Some(format!("{}: the output is a GeoTIFF, whatever its name's .{ext} says", output.display()))
}

#[cfg(test)]
mod tests {
    use super::writer::{write_placed, PAGE};
    use super::*;
    use std::io::Read;
    use tiff::tags::Tag;

    fn spec(bands: u32, sample: SampleType) -> OutputSpec {
        OutputSpec {
            overviews: 0,
            cog: false,
            width: 40,
            height: 16,
            bands,
            sample,
            chunking: Chunking::Tiles(16),
            compression: Compression::Deflate,
            level: None,
            overview_level: None,
            bigtiff: false,
            photometric: 2,
            alpha: false,
            mask: false,
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
            let r = write_placed(std::fs::File::create(&path).unwrap(), &spec, dir.path(), || -> std::result::Result<_, ()> {
                Ok(next.next().map(|&k| (k, tile(k))))
            });
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
    fn a_mask_is_the_next_directory_one_bit_a_pixel_high_bit_first() {
        // 20 × 20 grey in 16 × 16 tiles (2 × 2), the mask's tiles after
        // the image's: a pixel has a value where x + y is even and x < 18,
        // and in the last row but one (runs of eight alike).
        let spec = OutputSpec { width: 20, height: 20, compression: Compression::None, photometric: 1, mask: true, ..spec(1, SampleType::U8) };
        let has = |x: usize, y: usize| ((x + y).is_multiple_of(2) && x < 18) || y == 18;
        let mut order = Vec::new();
        for k in 0..4 {
            let (tx, ty) = (k % 2 * 16, k / 2 * 16);
            let valid: Vec<u8> = (0..256).map(|p| u8::from(has(tx + p % 16, ty + p / 16))).collect();
            order.push((k, vec![7u8; 256]));
            order.push((spec.mask_tile(k), encode_mask(&spec, &valid).unwrap()));
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.tif");
        let mut next = order.into_iter();
        write_placed(std::fs::File::create(&path).unwrap(), &spec, dir.path(), || -> std::result::Result<_, ()> { Ok(next.next()) }).unwrap();
        verify(&path, &spec).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let mut dec = tiff::decoder::Decoder::new(std::io::Cursor::new(&bytes)).unwrap();
        dec.next_image().unwrap();
        assert_eq!(dec.get_tag_u32(Tag::NewSubfileType).unwrap(), 4);
        assert_eq!((dec.get_tag_u32(Tag::PhotometricInterpretation).unwrap(), dec.get_tag_u32(Tag::BitsPerSample).unwrap()), (4, 1));
        let (offs, counts) = (dec.get_tag_u64_vec(Tag::TileOffsets).unwrap(), dec.get_tag_u64_vec(Tag::TileByteCounts).unwrap());
        for k in 0..4 {
            let bits = inflate(&bytes[offs[k] as usize..(offs[k] + counts[k]) as usize]);
            assert_eq!(bits.len(), 2 * 16, "two bytes a row of 16");
            let (tx, ty) = (k % 2 * 16, k / 2 * 16);
            for p in 0..256 {
                let (x, y) = (p % 16, p / 16);
                let bit = bits[y * 2 + x / 8] & (0x80 >> (x % 8)) != 0;
                assert_eq!(bit, has(tx + x, ty + y), "tile {k} pixel {x},{y}");
            }
        }
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
            let encoded = encode_tile(&s, 0, raw, None).unwrap();
            assert_eq!(inflate(&encoded), want, "{bands} bands of {sample:?}");
        }
    }
}
