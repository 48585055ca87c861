//! A JPEG scan, decoded at opening into plain rows (`foreign.rs` keeps
//! them in an unnamed file, read as an uncompressed TIFF is). libjpeg
//! (libjpeg-turbo as mozjpeg builds it from its sources: no system
//! package) hands out the rows as it decodes them, so a sequential
//! (baseline) JPEG of any size is decoded in a few MCU rows of memory; a
//! progressive one keeps every coefficient of the image until its last
//! scan, so it must fit the memory budget. Its colour conversion and
//! upsampling are libjpeg's, as GDAL's.
//!
//! The file's structure is walked first, without decoding: the frame's
//! kind, its components' sampling, and whether the data ends with its
//! end-of-image marker (libjpeg fills a truncated image with grey and
//! says nothing).

use super::foreign::{check_size, past_budget, plain_info, scratch, Decoded};
use super::SampleType;
use crate::error::{Error, Result};
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::Path;

/// What the markers of a JPEG say.
#[derive(Clone, Debug, PartialEq)]
struct Layout {
    width: u32,
    height: u32,
    /// SOF2/6/10/14: decoded whole (libjpeg keeps the coefficients).
    progressive: bool,
    /// SOF0/1: sequential, Huffman-coded, where every 8×8 block takes
    /// two bits at the least (a DC code and an end-of-block or AC code).
    sequential_huffman: bool,
    /// Bytes of entropy-coded data in the scans (stuffed zeros not counted).
    scan_bytes: u64,
    /// Each component's (horizontal, vertical) sampling factors.
    sampling: Vec<(u8, u8)>,
    /// The EXIF block of APP1 (after "Exif\0\0"), if any.
    exif: Option<Vec<u8>>,
}

/// The bytes of a JPEG, read through a buffer.
struct Bytes<R> {
    r: R,
    /// Bytes passed over by [`Bytes::skip_to_marker`].
    skipped: u64,
}

impl<R: BufRead> Bytes<R> {
    fn buffer(&mut self) -> std::result::Result<&[u8], String> {
        let buf = self.r.fill_buf().map_err(|e| e.to_string())?;
        if buf.is_empty() {
            return Err("the data ends before its end-of-image marker: truncated?".into());
        }
        Ok(buf)
    }

    fn next(&mut self) -> std::result::Result<u8, String> {
        let b = self.buffer()?[0];
        self.r.consume(1);
        Ok(b)
    }

    /// Skips entropy-coded data to the next 0xFF (not taken).
    fn skip_to_marker(&mut self) -> std::result::Result<(), String> {
        loop {
            let buf = self.buffer()?;
            match buf.iter().position(|&b| b == 0xff) {
                Some(p) => {
                    self.r.consume(p);
                    self.skipped += p as u64;
                    return Ok(());
                }
                None => {
                    let n = buf.len();
                    self.r.consume(n);
                    self.skipped += n as u64;
                }
            }
        }
    }
}

/// Walks the markers of the JPEG in `r` to the end-of-image marker.
fn layout(r: impl BufRead) -> std::result::Result<Layout, String> {
    let mut bytes = Bytes { r, skipped: 0 };
    if (bytes.next()?, bytes.next()?) != (0xff, 0xd8) {
        return Err("no start-of-image marker".into());
    }
    let mut frame: Option<Layout> = None;
    let mut exif = None;
    // After a scan's header, the entropy-coded data: markers in it are
    // restarts (D0–D7) and stuffed zeros (FF 00) only.
    let mut in_scan = false;
    loop {
        if in_scan {
            bytes.skip_to_marker()?;
        }
        let b = bytes.next()?;
        if b != 0xff {
            return Err(format!("a byte 0x{b:02x} where a marker should be"));
        }
        let mut marker = bytes.next()?;
        while marker == 0xff {
            marker = bytes.next()?;
        }
        match marker {
            // A stuffed zero stands for a data byte 0xFF.
            0x00 if in_scan => {
                bytes.skipped += 1;
                continue;
            }
            0xd0..=0xd7 if in_scan => continue,
            0x01 | 0xd0..=0xd7 => continue,
            0xd9 => {
                let mut f = frame.ok_or("no frame header")?;
                if !in_scan {
                    return Err("no scan".into());
                }
                f.exif = exif;
                f.scan_bytes = bytes.skipped;
                return Ok(f);
            }
            _ => {}
        }
        let len = u16::from_be_bytes([bytes.next()?, bytes.next()?]) as usize;
        if len < 2 {
            return Err(format!("marker 0x{marker:02x} with a length of {len}"));
        }
        let mut body = Vec::with_capacity(len - 2);
        for _ in 2..len {
            body.push(bytes.next()?);
        }
        match marker {
            0xc0..=0xcf if ![0xc4, 0xc8, 0xcc].contains(&marker) => {
                if frame.is_some() {
                    return Err("two frames".into());
                }
                if body.len() < 6 || body.len() < 6 + 3 * body[5] as usize {
                    return Err("a short frame header".into());
                }
                if [0xc3, 0xc7, 0xcb, 0xcf].contains(&marker) {
                    return Err("lossless JPEG (SOF3), which libjpeg does not decode".into());
                }
                if body[0] != 8 {
                    return Err(format!("{}-bit samples (8-bit JPEG is read)", body[0]));
                }
                let n = body[5] as usize;
                frame = Some(Layout {
                    height: u16::from_be_bytes([body[1], body[2]]) as u32,
                    width: u16::from_be_bytes([body[3], body[4]]) as u32,
                    progressive: matches!(marker, 0xc2 | 0xc6 | 0xca | 0xce),
                    sequential_huffman: matches!(marker, 0xc0 | 0xc1),
                    scan_bytes: 0,
                    sampling: (0..n).map(|i| (body[7 + 3 * i] >> 4, body[7 + 3 * i] & 15)).collect(),
                    exif: None,
                });
            }
            0xe1 if exif.is_none() && body.starts_with(b"Exif\0\0") => exif = Some(body[6..].to_vec()),
            0xda => in_scan = true,
            _ => {}
        }
    }
}

/// The components' largest horizontal and vertical sampling factors (an
/// MCU's size in 8×8 blocks).
fn max_sampling(l: &Layout) -> (u64, u64) {
    let most = |f: fn(&(u8, u8)) -> u8| l.sampling.iter().map(f).max().unwrap_or(1).max(1) as u64;
    (most(|s| s.0), most(|s| s.1))
}

/// The bytes libjpeg keeps for a progressive image: every component's
/// DCT coefficients (64 two-byte values a block), blocks padded to whole
/// MCUs.
fn coefficient_bytes(l: &Layout) -> u64 {
    let (hmax, vmax) = max_sampling(l);
    let (mcus_x, mcus_y) = ((l.width as u64).div_ceil(8 * hmax), (l.height as u64).div_ceil(8 * vmax));
    l.sampling.iter().map(|&(h, v)| mcus_x * h as u64 * mcus_y * v as u64 * 128).sum()
}

/// 8×8 blocks of a frame's components, each component's own (as a scan
/// of it alone codes them: no fewer than an interleaved scan's).
fn blocks(l: &Layout) -> u64 {
    let (hmax, vmax) = max_sampling(l);
    l.sampling
        .iter()
        .map(|&(h, v)| {
            let (cw, ch) = ((l.width as u64 * h as u64).div_ceil(hmax), (l.height as u64 * v as u64).div_ceil(vmax));
            cw.div_ceil(8) * ch.div_ceil(8)
        })
        .sum()
}

/// A sequential Huffman-coded JPEG whose scans hold fewer bytes than its
/// blocks need at the least (two bits a block) is refused before
/// decoding: libjpeg would fill the missing rows with grey, warning only,
/// and a header claiming 65500² px over a few bytes of data cost a
/// minute and 12 GB of decoded grey.
fn check_scan_bytes(path: &Path, l: &Layout) -> Result<()> {
    let least = blocks(l).div_ceil(4);
    if l.sequential_huffman && l.scan_bytes < least {
        return Err(Error::format(
            path,
            format!(
                "JPEG: its scans hold {} bytes, fewer than the {least} that {}×{} pixels need at the least (two bits an 8×8 block): truncated, or its frame's size is false",
                l.scan_bytes, l.width, l.height
            ),
        ));
    }
    Ok(())
}

/// Rows handed out by libjpeg at a time.
const ROWS: usize = 16;

/// Decodes the JPEG at `path` within `memory` bytes (`None`: reads only
/// its header).
pub(super) fn decode_jpeg(path: &Path, memory: Option<u64>) -> Result<Decoded> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let l = layout(BufReader::with_capacity(1 << 16, file)).map_err(|m| Error::format(path, format!("JPEG: {m}")))?;
    if let Some(exif) = &l.exif {
        check_orientation(path, exif)?;
    }
    let bands = match l.sampling.len() {
        1 => 1,
        3 => 3,
        n => return Err(Error::unsupported(path, format!("a JPEG of {n} components (grey, YCbCr and RGB are read)"))),
    };
    check_size(path, l.width, l.height, bands)?;
    check_scan_bytes(path, &l)?;
    let info = plain_info(l.width, l.height, bands, SampleType::U8, false);
    let Some(memory) = memory else { return Ok((info, None)) };
    if l.progressive {
        let need = coefficient_bytes(&l);
        if need > memory {
            return Err(past_budget(path, &format!("a progressive JPEG ({}×{}×{bands})", l.width, l.height), need, memory));
        }
    }
    // libjpeg reports a fatal error by unwinding (without the panic hook:
    // nothing is printed); caught here, it is the file's error.
    let decoded = std::panic::catch_unwind(|| decode_rows(path, &l, bands));
    let file = match decoded {
        Ok(r) => r?,
        Err(payload) => {
            let why = payload.downcast_ref::<String>().cloned().or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string())).unwrap_or_default();
            return Err(Error::format(path, format!("JPEG: {}", why.trim_start_matches("libjpeg fatal error: "))));
        }
    };
    Ok((info, Some(file)))
}

/// The rows of the JPEG at `path`, decoded by libjpeg into an unnamed file.
fn decode_rows(path: &Path, l: &Layout, bands: u32) -> Result<std::fs::File> {
    let io = |e: std::io::Error| Error::format(path, format!("JPEG: {e}"));
    let dec = mozjpeg::Decompress::new_path(path).map_err(io)?;
    let mut rows = if bands == 1 { dec.grayscale() } else { dec.rgb() }.map_err(io)?;
    if (rows.width(), rows.height()) != (l.width as usize, l.height as usize) {
        return Err(Error::format(path, "JPEG: the decoder's size is not the frame's"));
    }
    let row_bytes = l.width as usize * bands as usize;
    let mut out = BufWriter::with_capacity(1 << 20, scratch(path)?);
    let write_err = |e: std::io::Error| Error::format(path, format!("writing its decoded pixels to a temporary file: {e}"));
    let mut buf = vec![0u8; ROWS * row_bytes];
    let mut done = 0;
    while done < l.height as usize {
        let n = ROWS.min(l.height as usize - done);
        rows.read_scanlines_into::<u8>(&mut buf[..n * row_bytes]).map_err(io)?;
        out.write_all(&buf[..n * row_bytes]).map_err(write_err)?;
        done += n;
    }
    rows.finish().map_err(io)?;
    out.into_inner().map_err(|e| write_err(e.into_error()))
}

/// A JPEG whose EXIF says its rows are to be shown turned or mirrored is
/// refused: the camera's interior orientation is of the sensor's rows and
/// columns as stored, and turning the pixels for display would move them.
fn check_orientation(path: &Path, exif: &[u8]) -> Result<()> {
    let Ok(data) = exif::Reader::new().read_raw(exif.to_vec()) else {
        return Ok(());
    };
    let Some(o) = data.get_field(exif::Tag::Orientation, exif::In::PRIMARY).and_then(|f| f.value.get_uint(0)) else {
        return Ok(());
    };
    if o == 1 {
        return Ok(());
    }
    Err(super::header::orientation_refused(path, "EXIF orientation", o))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 40 × 24 RGB pixels, and their baseline JPEG (4:2:0) by jpeg-encoder.
    fn sample_jpeg() -> (Vec<u8>, Vec<u8>) {
        let pixels: Vec<u8> = (0..40 * 24 * 3).map(|i| (i % 251) as u8).collect();
        let mut whole = Vec::new();
        let mut e = jpeg_encoder::Encoder::new(&mut whole, 80);
        e.set_sampling_factor(jpeg_encoder::SamplingFactor::R_4_2_0);
        e.encode(&pixels, 40, 24, jpeg_encoder::ColorType::Rgb).unwrap();
        (pixels, whole)
    }

    /// A 40 × 24 RGB JPEG (4:2:0) made by jpeg-encoder: its layout, and
    /// every cut of it short of its end refused as truncated.
    #[test]
    fn the_markers_give_the_frame_and_a_cut_file_is_refused() {
        let (pixels, whole) = sample_jpeg();
        let l = layout(&whole[..]).unwrap();
        assert_eq!((l.width, l.height, l.progressive, l.sampling.clone()), (40, 24, false, vec![(2, 2), (1, 1), (1, 1)]));
        // Three MCUs across, two down; Y 2×2 blocks an MCU, Cb and Cr one.
        assert_eq!(coefficient_bytes(&l), 3 * 2 * (4 + 1 + 1) * 128);
        for cut in [whole.len() - 1, whole.len() - 2, whole.len() / 2, 300] {
            let e = layout(&whole[..cut]).unwrap_err();
            assert!(e.contains("truncated"), "{cut}: {e}");
        }
        let mut progressive = Vec::new();
        let mut e = jpeg_encoder::Encoder::new(&mut progressive, 80);
        e.set_progressive(true);
        e.encode(&pixels, 40, 24, jpeg_encoder::ColorType::Rgb).unwrap();
        assert!(layout(&progressive[..]).unwrap().progressive);
    }

    /// A frame whose size the scans cannot hold is refused before any
    /// decoding; the same data under its true size passes.
    #[test]
    fn a_frame_larger_than_its_data_is_refused_before_decoding() {
        let (_, mut whole) = sample_jpeg();
        let l = layout(&whole[..]).unwrap();
        // Y 5×3 blocks, Cb and Cr 3×2 each.
        assert_eq!(blocks(&l), 15 + 6 + 6);
        assert!(l.sequential_huffman && l.scan_bytes > 7 && (l.scan_bytes as usize) < whole.len() - 300, "{} of {}", l.scan_bytes, whole.len());
        check_scan_bytes(Path::new("a.jpg"), &l).unwrap();
        // The frame header's height and width (after FF C0, length, precision).
        let sof = whole.windows(2).position(|w| w == [0xff, 0xc0]).unwrap();
        whole[sof + 5..sof + 9].copy_from_slice(&[0xff, 0xdc, 0xff, 0xdc]);
        let big = layout(&whole[..]).unwrap();
        assert_eq!((big.width, big.height), (65500, 65500));
        let e = check_scan_bytes(Path::new("a.jpg"), &big).unwrap_err().to_string();
        assert!(e.contains("a.jpg") && e.contains("65500×65500") && e.contains(&format!("hold {} bytes", l.scan_bytes)), "{e}");
    }
}
