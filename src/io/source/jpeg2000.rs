//! JPEG 2000 scans (a JP2 file or a bare codestream), read a chunk at a
//! time: the header comes from the codestream's SIZ segment, read here;
//! each chunk (a codestream tile, or a part of one) is decoded alone by
//! OpenJPEG's area decoding, which reads only the code-blocks it covers, so
//! memory stays that of the chunk cache whatever the scene's size. A
//! chunk costs tens of milliseconds to decode, and the windows of the
//! output's bands come back to the same chunks: each is decoded once, and
//! kept in an unnamed file ([`Spill`]) for the windows after.

use super::header::SourceInfo;
use super::SampleType;
use crate::error::{Error, Result};
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

/// A chunk's side at most: a codestream tile larger than this is read in
/// parts (areas), so that decoding one holds little memory.
const MAX_CHUNK: u32 = 1024;
/// The most chunks a JPEG 2000 scan is read in: each has its place in
/// the bookkeeping (offsets, a lock), some 40 bytes (160 MiB at this
/// limit); 4 Tpx in chunks of [`MAX_CHUNK`].
const MAX_CHUNKS: u64 = 1 << 22;

/// What the codestream's SIZ segment says.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Siz {
    /// The image area on the reference grid: [x0, x1) × [y0, y1).
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
    /// The tile size and the tile grid's origin.
    pub tile: (u32, u32),
    pub tile_origin: (u32, u32),
    /// Per component: bit depth, signed, subsampling (dx, dy).
    pub components: Vec<(u8, bool, u8, u8)>,
}

/// Reads the SIZ segment of the JPEG 2000 file at `path` (a JP2 file: its
/// contiguous codestream box; or a bare codestream).
pub(super) fn read_siz(path: &Path) -> Result<Siz> {
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let bad = |m: &str| Error::format(path, format!("JPEG 2000: {m}"));
    let io = |e: std::io::Error| Error::format(path, format!("JPEG 2000: {e} (truncated?)"));
    let mut head = [0u8; 4];
    f.read_exact(&mut head).map_err(io)?;
    if head != [0xFF, 0x4F, 0xFF, 0x51] {
        // JP2 boxes: length (4, big-endian; 1: an 8-byte length follows;
        // 0: to the end), type (4). The codestream is the `jp2c` box.
        f.seek(SeekFrom::Start(0)).map_err(io)?;
        let mut at = 0u64;
        loop {
            let mut b = [0u8; 8];
            f.read_exact(&mut b).map_err(|_| bad("no codestream box (jp2c)"))?;
            let mut len = u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as u64;
            let mut header = 8;
            if len == 1 {
                let mut l = [0u8; 8];
                f.read_exact(&mut l).map_err(io)?;
                len = u64::from_be_bytes(l);
                header = 16;
            }
            if &b[4..8] == b"jp2c" {
                break;
            }
            if len == 0 || len < header {
                return Err(bad("a box of a bad length before the codestream"));
            }
            at += len;
            f.seek(SeekFrom::Start(at)).map_err(io)?;
        }
        f.read_exact(&mut head).map_err(io)?;
        if head != [0xFF, 0x4F, 0xFF, 0x51] {
            return Err(bad("the codestream does not start with SOC and SIZ"));
        }
    }
    let mut len = [0u8; 2];
    f.read_exact(&mut len).map_err(io)?;
    let len = u16::from_be_bytes(len) as usize;
    if len < 41 {
        return Err(bad("a SIZ segment too short"));
    }
    let mut s = vec![0u8; len - 2];
    f.read_exact(&mut s).map_err(io)?;
    let u32_at = |i: usize| u32::from_be_bytes([s[i], s[i + 1], s[i + 2], s[i + 3]]);
    let n = u16::from_be_bytes([s[34], s[35]]) as usize;
    if s.len() < 36 + 3 * n {
        return Err(bad("a SIZ segment shorter than its components"));
    }
    let components = (0..n)
        .map(|c| {
            let ssiz = s[36 + 3 * c];
            ((ssiz & 0x7F) + 1, ssiz & 0x80 != 0, s[37 + 3 * c], s[38 + 3 * c])
        })
        .collect();
    let siz =
        Siz { x1: u32_at(2), y1: u32_at(6), x0: u32_at(10), y0: u32_at(14), tile: (u32_at(18), u32_at(22)), tile_origin: (u32_at(26), u32_at(30)), components };
    if siz.x1 <= siz.x0 || siz.y1 <= siz.y0 || siz.tile.0 == 0 || siz.tile.1 == 0 {
        return Err(bad("an empty image or tile in its SIZ segment"));
    }
    Ok(siz)
}

/// The scan's header: its chunks are the codestream's tiles (parts of
/// them where they are larger than [`MAX_CHUNK`]; areas of that size when
/// the tile grid is not the image's).
pub(super) fn info(path: &Path, siz: &Siz) -> Result<SourceInfo> {
    let (w, h) = (siz.x1 - siz.x0, siz.y1 - siz.y0);
    let bands = siz.components.len() as u32;
    if !(1..=4).contains(&bands) {
        return Err(Error::unsupported(path, format!("a JPEG 2000 image of {bands} components (1 to 4 are read)")));
    }
    let (depth, signed, _, _) = siz.components[0];
    if siz.components.iter().any(|&c| c != siz.components[0]) || siz.components[0].2 != 1 || siz.components[0].3 != 1 {
        return Err(Error::unsupported(path, "JPEG 2000 components of different depths or subsampled (all full-size and alike are read)"));
    }
    if signed {
        return Err(Error::unsupported(path, format!("signed {depth}-bit JPEG 2000 samples (unsigned are read)")));
    }
    let sample = match depth {
        1..=8 => SampleType::U8,
        9..=16 => SampleType::U16,
        d => return Err(Error::unsupported(path, format!("{d}-bit JPEG 2000 samples (up to 16 are read)"))),
    };
    let aligned = siz.tile_origin == (siz.x0, siz.y0);
    let mut chunk = if aligned { (siz.tile.0.min(w), siz.tile.1.min(h)) } else { (MAX_CHUNK, MAX_CHUNK) };
    while chunk.0 > MAX_CHUNK {
        chunk.0 = chunk.0.div_ceil(2);
    }
    while chunk.1 > MAX_CHUNK {
        chunk.1 = chunk.1.div_ceil(2);
    }
    // Every tile of the codestream has a tile-part (a 12-byte SOT segment
    // and an SOD marker at least): a header claiming more tiles than the
    // file can hold is refused before anything is counted out per chunk.
    let tiles = u64::from(siz.x1.div_ceil(siz.tile.0)) * u64::from(siz.y1.div_ceil(siz.tile.1));
    let len = std::fs::metadata(path).map_err(|e| Error::io(path, e))?.len();
    if tiles > len / 14 {
        return Err(Error::format(path, format!("its JPEG 2000 header claims {tiles} tiles ({w}×{h} px), more than its {len} bytes can hold")));
    }
    let n = u64::from(w.div_ceil(chunk.0)) * u64::from(h.div_ceil(chunk.1));
    if n > MAX_CHUNKS {
        return Err(Error::limits(path, format!("a JPEG 2000 image of {n} tiles of {}×{} px (at most {MAX_CHUNKS} are read)", chunk.0, chunk.1)));
    }
    let n = n as usize;
    Ok(SourceInfo {
        width: w,
        height: h,
        bands,
        sample,
        planar: false,
        chunk,
        tiled: true,
        // TIFF's code for JPEG 2000.
        compression: 34712,
        photometric: if bands >= 3 { 2 } else { 1 },
        has_alpha: false,
        predictor: 1,
        nodata: None,
        packed_bits: 0,
        georef: None,
        offsets: vec![0; n],
        byte_counts: vec![0; n],
        mask: None,
        mask_compression: 1,
        jpeg_tables: None,
    })
}

/// Decoded chunks kept on disk: an unnamed file (removed by the system
/// however the run ends) with a place for every chunk, and which are there.
pub(super) struct Spill {
    file: std::fs::File,
    chunk_bytes: u64,
    /// Per chunk: decoded and written (`true`); held while it is decoded,
    /// so that two readers never decode the same chunk.
    done: Vec<std::sync::Mutex<bool>>,
    /// Decodes running, and how many may run at once (each holds several
    /// times a chunk: the memory plan sets the limit).
    running: (std::sync::Mutex<usize>, std::sync::Condvar),
    limit: std::sync::atomic::AtomicUsize,
}

impl Spill {
    pub fn new(path: &Path, info: &SourceInfo) -> Result<Spill> {
        let file = tempfile::tempfile().map_err(|e| Error::format(path, format!("no temporary file for its decoded chunks: {e}")))?;
        let chunk_bytes = info.chunk.0 as u64 * info.chunk.1 as u64 * info.pixel_bytes() as u64;
        Ok(Spill {
            file,
            chunk_bytes,
            done: (0..info.offsets.len()).map(|_| std::sync::Mutex::new(false)).collect(),
            running: Default::default(),
            limit: usize::MAX.into(),
        })
    }

    /// At most `n` (at least one) chunks decoded at once.
    pub fn limit_decoders(&self, n: usize) {
        self.limit.store(n.max(1), std::sync::atomic::Ordering::Relaxed);
    }

    /// `decode`, once a decoder is free.
    fn decode_in_turn(&self, decode: impl FnOnce() -> Result<Vec<u8>>) -> Result<Vec<u8>> {
        let (count, free) = (&self.running.0, &self.running.1);
        let limit = self.limit.load(std::sync::atomic::Ordering::Relaxed);
        let mut n = free.wait_while(count.lock().unwrap_or_else(|e| e.into_inner()), |n| *n >= limit).unwrap_or_else(|e| e.into_inner());
        *n += 1;
        drop(n);
        // Freed however the decode ends (a panic too: the others would wait).
        struct Turn<'a>(&'a Spill);
        impl Drop for Turn<'_> {
            fn drop(&mut self) {
                *self.0.running.0.lock().unwrap_or_else(|e| e.into_inner()) -= 1;
                self.0.running.1.notify_one();
            }
        }
        let _turn = Turn(self);
        decode()
    }

    /// Chunk `k`: read back, or decoded by `decode` and kept.
    pub fn chunk(&self, path: &Path, k: u32, decode: impl FnOnce() -> Result<Vec<u8>>) -> Result<Vec<u8>> {
        use std::os::unix::fs::FileExt;
        let io = |e: std::io::Error| Error::format(path, format!("its decoded chunks' temporary file: {e}"));
        let mut done = self.done[k as usize].lock().unwrap_or_else(|e| e.into_inner());
        let at = k as u64 * self.chunk_bytes;
        if *done {
            let mut v = vec![0u8; self.chunk_bytes as usize];
            self.file.read_exact_at(&mut v, at).map_err(io)?;
            return Ok(v);
        }
        let v = self.decode_in_turn(decode)?;
        self.file.write_all_at(&v, at).map_err(io)?;
        *done = true;
        Ok(v)
    }
}

/// Chunk `k` of the scan decoded: full chunk width and height, chunky,
/// native-endian (past the image's right and bottom edges, zeros).
pub(super) fn decode_chunk(path: &Path, info: &SourceInfo, origin: (u32, u32), k: u32) -> Result<Vec<u8>> {
    let (cw, ch) = info.chunk;
    let across = info.width.div_ceil(cw);
    let (cx, cy) = ((k % across) * cw, (k / across) * ch);
    let (w, h) = ((info.width - cx).min(cw), (info.height - cy).min(ch));
    let area = jpeg2k::DecodeArea::new(origin.0 + cx, origin.1 + cy, origin.0 + cx + w, origin.1 + cy + h);
    let img = jpeg2k::Image::from_file_with(path, jpeg2k::DecodeParameters::new().decode_area(Some(area)))
        .map_err(|e| Error::format(path, format!("JPEG 2000: chunk {k} ({w}×{h} px at column {cx}, row {cy}): {e}")))?;
    let comps = img.components();
    if comps.len() != info.bands as usize || comps.iter().any(|c| c.width() != w || c.height() != h) {
        return Err(Error::format(path, format!("JPEG 2000: chunk {k} decodes to other components or sizes than its header's")));
    }
    let (bands, sb) = (info.bands as usize, info.sample.bytes());
    let max = if sb == 1 { u8::MAX as i32 } else { u16::MAX as i32 };
    let mut out = vec![0u8; cw as usize * ch as usize * bands * sb];
    for (b, c) in comps.iter().enumerate() {
        for (y, row) in c.data().chunks_exact(w as usize).enumerate() {
            let line = &mut out[y * cw as usize * bands * sb..];
            for (x, &v) in row.iter().enumerate() {
                let v = v.clamp(0, max);
                let at = (x * bands + b) * sb;
                if sb == 1 {
                    line[at] = v as u8;
                } else {
                    line[at..at + 2].copy_from_slice(&(v as u16).to_ne_bytes());
                }
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A codestream's first bytes: SOC, then SIZ for a 1000×700 image at
    /// (8, 4) on the reference grid, tiles of 256 from (8, 4), `n`
    /// components of 12 bits.
    fn codestream(n: u16) -> Vec<u8> {
        let mut s = vec![0xFF, 0x4F, 0xFF, 0x51];
        s.extend_from_slice(&(38 + 3 * n).to_be_bytes());
        s.extend_from_slice(&0u16.to_be_bytes()); // Rsiz
        for v in [1008u32, 704, 8, 4, 256, 256, 8, 4] {
            s.extend_from_slice(&v.to_be_bytes());
        }
        s.extend_from_slice(&n.to_be_bytes());
        for _ in 0..n {
            s.extend_from_slice(&[11, 1, 1]);
        }
        s
    }

    #[test]
    fn siz_is_read_from_a_bare_codestream_and_from_a_jp2_box() {
        let dir = tempfile::tempdir().unwrap();
        let bare = dir.path().join("a.j2k");
        std::fs::write(&bare, codestream(4)).unwrap();
        let want = Siz { x0: 8, y0: 4, x1: 1008, y1: 704, tile: (256, 256), tile_origin: (8, 4), components: vec![(12, false, 1, 1); 4] };
        assert_eq!(read_siz(&bare).unwrap(), want);
        // Signature, file type and a header box before the codestream.
        let mut jp2 = b"\0\0\0\x0cjP  \r\n\x87\n\0\0\0\x14ftypjp2 \0\0\0\0jp2 \0\0\0\x09jp2h\0".to_vec();
        jp2.extend_from_slice(&((8 + codestream(4).len()) as u32).to_be_bytes());
        jp2.extend_from_slice(b"jp2c");
        jp2.extend_from_slice(&codestream(4));
        let boxed = dir.path().join("a.jp2");
        // Room for the tile-parts the header promises (read_siz stops at SIZ).
        let mut padded = jp2.clone();
        padded.resize(jp2.len() + 4096, 0);
        std::fs::write(&boxed, padded).unwrap();
        assert_eq!(read_siz(&boxed).unwrap(), want);
        let i = info(&boxed, &want).unwrap();
        assert_eq!((i.width, i.height, i.bands, i.sample, i.chunk), (1000, 700, 4, SampleType::U16, (256, 256)));
        // Tiles larger than a chunk may be are halved; five components refused.
        let big = Siz { tile: (4096, 4096), tile_origin: (8, 4), x1: 3008, y1: 2404, ..want.clone() };
        assert_eq!(info(&boxed, &big).unwrap().chunk, (750, 600));
        let five = Siz { components: vec![(12, false, 1, 1); 5], ..want.clone() };
        assert!(info(&boxed, &five).unwrap_err().to_string().contains("5 components"));
        // A header claiming 4.29e9² px in 1-px tiles: refused by what the
        // file can hold, not by the allocator.
        let vast = Siz { x0: 0, y0: 0, x1: u32::MAX, y1: u32::MAX, tile: (1, 1), tile_origin: (0, 0), ..want.clone() };
        assert!(info(&boxed, &vast).unwrap_err().to_string().contains("more than its"), "{:?}", info(&boxed, &vast).err());
        let wide = Siz { x0: 0, y0: 0, x1: u32::MAX, y1: u32::MAX, tile: (u32::MAX, u32::MAX), tile_origin: (0, 0), ..want.clone() };
        assert!(info(&boxed, &wide).unwrap_err().to_string().contains("at most"));
        // Cut short: refused by name.
        std::fs::write(&bare, &codestream(4)[..30]).unwrap();
        assert!(read_siz(&bare).unwrap_err().to_string().contains("truncated"));
    }
}
