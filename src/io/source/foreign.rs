//! Scans that are not TIFF. A JPEG or PNG has no chunk table to read a
//! window from, so it is decoded once, at opening, into an unnamed
//! temporary file of plain rows (removed by the system when the run ends,
//! however it ends), which is then read as an uncompressed TIFF is: mapped,
//! a window at a time. PNG rows are decoded one after another, in little
//! memory, and so are a sequential JPEG's (`jpeg.rs`); JPEG 2000 is
//! decoded a tile at a time (`jpeg2000.rs`).

use super::header::SourceInfo;
use super::SampleType;
use crate::error::{Error, Result};
use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::Path;

/// What a file holds, from its first bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    Tiff,
    Jpeg,
    Png,
    /// A JP2 file or a bare codestream.
    Jpeg2000,
}

impl ImageFormat {
    /// The format of `path`, or why it is not one this build reads (what
    /// was found instead, where the first bytes tell).
    pub fn of(path: &Path) -> Result<ImageFormat> {
        let head = &crate::io::bounded_read::read_head(path, 16)?;
        let n = head.len();
        let starts = |s: &[u8]| head.starts_with(s);
        if starts(b"II*\0") || starts(b"MM\0*") || starts(b"II+\0") || starts(b"MM\0+") {
            return Ok(ImageFormat::Tiff);
        }
        if starts(&[0xFF, 0xD8, 0xFF]) {
            return Ok(ImageFormat::Jpeg);
        }
        if starts(b"\x89PNG\r\n\x1a\n") {
            return Ok(ImageFormat::Png);
        }
        if starts(b"\0\0\0\x0cjP  \r\n\x87\n") || starts(&[0xFF, 0x4F, 0xFF, 0x51]) {
            return Ok(ImageFormat::Jpeg2000);
        }
        let found = if n == 0 {
            "an empty file".to_string()
        } else if starts(b"GIF8") {
            "a GIF".into()
        } else if starts(b"BM") {
            "a BMP".into()
        } else if starts(b"NITF") || starts(b"NSIF") {
            "a NITF file (convert it with gdal_translate -of GTiff)".into()
        } else if starts(b"EHFA_HEADER_TAG") {
            "an ERDAS Imagine file (convert it with gdal_translate -of GTiff)".into()
        } else if head.iter().all(|&b| b == b'\t' || b == b'\n' || b == b'\r' || (0x20..0x7F).contains(&b)) {
            // Never quoted: it may be any file at all (a password file).
            if head.first() == Some(&b'<') { "XML or HTML text".to_string() } else { "text".to_string() }
        } else {
            format!("first bytes {}", head.iter().take(8).map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(" "))
        };
        Err(Error::unsupported(path, format!("is not an image this build reads ({found}): TIFF or BigTIFF, JPEG, PNG and JPEG 2000 are")))
    }
}

/// The header of a decoded image, describing its plain rows as a
/// one-strip uncompressed TIFF would, and the file that holds them
/// (`None` where only the header was asked for).
pub(super) type Decoded = (SourceInfo, Option<File>);

/// `info` for plain chunky rows of `width`×`height` at offset 0.
pub(super) fn plain_info(width: u32, height: u32, bands: u32, sample: SampleType, has_alpha: bool) -> SourceInfo {
    let bytes = width as u64 * height as u64 * bands as u64 * sample.bytes() as u64;
    SourceInfo {
        width,
        height,
        bands,
        sample,
        planar: false,
        chunk: (width, height),
        tiled: false,
        compression: 1,
        photometric: if bands >= 3 { 2 } else { 1 },
        has_alpha,
        predictor: 1,
        nodata: None,
        packed_bits: 0,
        georef: None,
        offsets: vec![0],
        byte_counts: vec![bytes],
        mask: None,
        mask_compression: 1,
        jpeg_tables: None,
    }
}

/// Refuses sizes past what any scan needs before anything is allocated.
pub(super) fn check_size(path: &Path, width: u32, height: u32, bands: u32) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::format(path, format!("has a size of {width}×{height}")));
    }
    if !(1..=4).contains(&bands) {
        return Err(Error::unsupported(path, format!("{bands} bands (1 to 4 are read)")));
    }
    Ok(())
}

/// An image decoded whole (`what`) needs `need` bytes, more than the
/// `memory` budget: refused naming the file and the budget that would do.
pub(super) fn past_budget(path: &Path, what: &str, need: u64, memory: u64) -> Error {
    let mib = |b: u64| b.div_ceil(1 << 20);
    Error::setting(
        "memory",
        format!(
            "{}: {what} is decoded whole, and this one needs {} MiB, more than the budget's {} MiB: give {}M or more, or convert it to a tiled TIFF",
            path.display(),
            mib(need),
            mib(memory),
            mib(need) + 16
        ),
    )
}

/// A file for the decoded rows: unnamed, so nothing is left behind.
pub(super) fn scratch(path: &Path) -> Result<File> {
    tempfile::tempfile().map_err(|e| Error::format(path, format!("no temporary file for its decoded pixels: {e}")))
}

/// Decodes the PNG at `path`, a row at a time (an interlaced one whole,
/// within `memory` bytes; `None`: reads only its header).
pub(super) fn decode_png(path: &Path, memory: Option<u64>) -> Result<Decoded> {
    let f = File::open(path).map_err(|e| Error::io(path, e))?;
    let mut dec = png::Decoder::new(BufReader::new(f));
    // Palettes and transparency chunks to RGB(A), bit depths below 8 to 8.
    dec.set_transformations(png::Transformations::EXPAND);
    let bad = |e: png::DecodingError| Error::format(path, format!("PNG: {e}"));
    let mut reader = dec.read_info().map_err(bad)?;
    let (w, h) = (reader.info().width, reader.info().height);
    let interlaced = reader.info().interlaced;
    let (colour, depth) = reader.output_color_type();
    let (bands, has_alpha) = match colour {
        png::ColorType::Grayscale => (1, false),
        png::ColorType::GrayscaleAlpha => (2, true),
        png::ColorType::Rgb => (3, false),
        png::ColorType::Rgba => (4, true),
        png::ColorType::Indexed => return Err(Error::unsupported(path, "a PNG palette the decoder did not expand")),
    };
    let sample = match depth {
        png::BitDepth::Eight => SampleType::U8,
        png::BitDepth::Sixteen => SampleType::U16,
        d => return Err(Error::unsupported(path, format!("PNG samples of {d:?} bits"))),
    };
    check_size(path, w, h, bands)?;
    let info = plain_info(w, h, bands, sample, has_alpha);
    let Some(memory) = memory else { return Ok((info, None)) };
    let row_bytes = w as usize * info.pixel_bytes();
    let file = scratch(path)?;
    let mut out = BufWriter::with_capacity(1 << 20, file);
    let write_err = |e: std::io::Error| Error::format(path, format!("writing its decoded pixels to a temporary file: {e}"));
    // PNG's 16-bit samples are big-endian; ours native.
    let native = |row: &mut [u8]| {
        if sample == SampleType::U16 {
            for s in row.chunks_exact_mut(2) {
                let v = u16::from_be_bytes([s[0], s[1]]);
                s.copy_from_slice(&v.to_ne_bytes());
            }
        }
    };
    if interlaced {
        let need = reader.output_buffer_size() as u64;
        if need > memory {
            return Err(past_budget(path, "an interlaced PNG", need, memory));
        }
        let mut buf = vec![0u8; need as usize];
        reader.next_frame(&mut buf).map_err(bad)?;
        for row in buf.chunks_exact_mut(row_bytes).take(h as usize) {
            native(row);
            out.write_all(row).map_err(write_err)?;
        }
    } else {
        let (mut rows, mut row) = (0u32, Vec::with_capacity(row_bytes));
        while let Some(next) = reader.next_row().map_err(bad)? {
            row.clear();
            row.extend_from_slice(next.data());
            if row.len() != row_bytes {
                return Err(Error::format(path, format!("PNG: row {rows} has {} bytes, {row_bytes} expected", row.len())));
            }
            native(&mut row);
            out.write_all(&row).map_err(write_err)?;
            rows += 1;
        }
        if rows != h {
            return Err(Error::format(path, format!("PNG: {rows} rows of {h}: truncated?")));
        }
    }
    let file = out.into_inner().map_err(|e| write_err(e.into_error()))?;
    Ok((info, Some(file)))
}
