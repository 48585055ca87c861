//! Decoding one TIFF chunk (strip or tile) into native-endian samples, with
//! every band kept.
//!
//! The `tiff` crate (0.11) is not used for this, for two reasons found on
//! real files: it decodes through its colour type, so an interleaved RGB
//! file with a fourth band that is not alpha (an RGB + NIR aerial) comes out
//! with three of its four bands; and its LZW reader fails on some tiles that
//! GDAL writes ("unexpected end of file" when a tile's output fills before
//! the end code is read; image-rs/image-tiff#395). Here a chunk is
//! decompressed whole (deflate, LZW, PackBits, zstd, through the codec crates
//! the `tiff` crate uses itself), then the file's byte order and predictor
//! are undone row by row. Like libtiff, LZW stops once the chunk's bytes are
//! out, whether or not an end code follows.

use std::fs::File;
use std::io::Read;
use std::path::Path;

/// How the chunks of one file are coded.
#[derive(Clone, Copy, Debug)]
pub struct ChunkCodec {
    /// TIFF Compression tag: 1 none, 5 LZW, 8/32946 deflate, 32773 PackBits, 50000 zstd.
    pub compression: u16,
    /// TIFF Predictor tag: 1 none, 2 horizontal differencing, 3 floating point.
    pub predictor: u16,
    /// Bytes of one sample: 1, 2, 4 or 8.
    pub sample_bytes: usize,
    /// IEEE floating-point samples (the only ones predictor 3 applies to).
    pub float: bool,
    /// Samples interleaved in a pixel of the chunk (1 for planar files).
    pub samples: usize,
    /// The file is big-endian ("MM").
    pub big_endian: bool,
    /// Bits a sample where they are packed (9 to 15: a 12-bit satellite
    /// image), widened here to 16-bit samples; 0 for whole bytes.
    pub packed_bits: u16,
}

impl ChunkCodec {
    /// Can this codec decode such chunks? `Err` says what it cannot.
    pub fn check(&self) -> Result<(), String> {
        match self.compression {
            1 | 5 | 8 | 32946 | 32773 | 50000 => {}
            c => return Err(format!("TIFF compression {c}")),
        }
        if ![1, 2, 4, 8].contains(&self.sample_bytes) || self.samples == 0 {
            return Err(format!("{}-byte samples", self.sample_bytes));
        }
        match self.predictor {
            1 | 2 => Ok(()),
            3 if self.float && self.sample_bytes >= 2 => Ok(()),
            3 => Err("the floating-point predictor on integer samples".into()),
            p => Err(format!("predictor {p}")),
        }
    }

    /// The chunk's pixels: `rows` rows of `width` pixels, native-endian.
    /// `coded` is the chunk's bytes as stored in the file; it may decode to
    /// up to `full_rows` rows (a last strip written at full height), and a
    /// stream that runs on past them, or ends before `rows`, is an error.
    #[cfg(test)]
    pub fn decode(&self, coded: &[u8], width: usize, rows: usize, full_rows: usize) -> Result<Vec<u8>, String> {
        let row_bytes = self.stored_row_bytes(width);
        let want = row_bytes * rows;
        let allowed = row_bytes * full_rows.max(rows);
        let mut out = Vec::new();
        self.decompress(coded, want, allowed, &mut out)?;
        self.finish(&mut out, row_bytes, rows, full_rows)?;
        Ok(if self.packed_bits != 0 { self.widened(&out, width, rows) } else { out })
    }

    /// Chunk `k` of the file at `path`, stored as `count` bytes from
    /// `offset`, read with `pread` and decoded: `rows` rows of `width`
    /// pixels, native-endian, of a chunk `full_rows` high (a last strip may
    /// hold fewer rows than that, or be written at full height). Errors name
    /// the file and the chunk.
    #[allow(clippy::too_many_arguments)] // the chunk's place in the file, and its size
    pub fn read_chunk(
        &self,
        file: &File,
        path: &Path,
        k: usize,
        stored: (u64, u64),
        width: usize,
        rows: usize,
        full_rows: usize,
    ) -> crate::error::Result<Vec<u8>> {
        let mut out = Vec::new();
        self.read_chunk_into(file, path, k, stored, (width, rows, full_rows), &mut out)?;
        Ok(out)
    }

    /// [`read_chunk`](Self::read_chunk) into `out`, whose room is used
    /// again: a DEM read a strip at a time over and over allocates (and
    /// faults in) no new memory for each.
    pub fn read_chunk_into(
        &self,
        file: &File,
        path: &Path,
        k: usize,
        (offset, count): (u64, u64),
        (width, rows, full_rows): (usize, usize, usize),
        out: &mut Vec<u8>,
    ) -> crate::error::Result<()> {
        use crate::error::Error;
        use std::os::unix::fs::FileExt;
        if count > crate::io::format::decoder_limits().intermediate_buffer_size as u64 {
            return Err(Error::limits(path, format!("chunk {k} holds {count} compressed bytes")));
        }
        let in_chunk = |e: String| Error::format(path, format!("chunk {k}: {e}"));
        let row_bytes = self.stored_row_bytes(width);
        if self.compression == 1 {
            // Stored as is: read into place, with no buffer of the coded
            // bytes to allocate, copy and free for every chunk.
            out.clear();
            out.resize((row_bytes * rows).min(count as usize), 0);
            file.read_exact_at(out, offset).map_err(|e| Error::io(path, e))?;
        } else {
            let mut coded = vec![0u8; count as usize];
            file.read_exact_at(&mut coded, offset).map_err(|e| Error::io(path, e))?;
            self.decompress(&coded, row_bytes * rows, row_bytes * full_rows.max(rows), out).map_err(in_chunk)?;
        }
        self.finish(out, row_bytes, rows, full_rows).map_err(in_chunk)?;
        if self.packed_bits != 0 {
            *out = self.widened(out, width, rows);
        }
        Ok(())
    }

    /// Bytes of a row as stored: whole samples, or packed bits padded to a
    /// byte.
    pub fn stored_row_bytes(&self, width: usize) -> usize {
        match self.packed_bits {
            0 => width * self.samples * self.sample_bytes,
            b => (width * self.samples * b as usize).div_ceil(8),
        }
    }

    /// Packed rows (most significant bit first, each row from a byte's
    /// start) as native-endian 16-bit samples.
    fn widened(&self, packed: &[u8], width: usize, rows: usize) -> Vec<u8> {
        let (bits, n) = (self.packed_bits as usize, width * self.samples);
        let stored = self.stored_row_bytes(width);
        let mut out = Vec::with_capacity(rows * n * 2);
        for row in packed.chunks_exact(stored).take(rows) {
            let (mut acc, mut held) = (0u32, 0usize);
            let mut bytes = row.iter();
            for _ in 0..n {
                while held < bits {
                    acc = (acc << 8) | u32::from(*bytes.next().unwrap_or(&0));
                    held += 8;
                }
                held -= bits;
                let v = ((acc >> held) & ((1 << bits) - 1)) as u16;
                out.extend_from_slice(&v.to_ne_bytes());
            }
        }
        out
    }

    /// Decompressed bytes `out` checked against the chunk's size (`rows`
    /// of `row_bytes`, up to `full_rows` allowed), cut to its rows and
    /// unpredicted.
    fn finish(&self, out: &mut Vec<u8>, row_bytes: usize, rows: usize, full_rows: usize) -> Result<(), String> {
        let want = row_bytes * rows;
        let allowed = row_bytes * full_rows.max(rows);
        if out.len() > allowed {
            return Err(format!("the stream runs on past the chunk's {allowed} bytes"));
        }
        if out.len() < want {
            return Err(format!("decodes to {} bytes, its pixels need {want}", out.len()));
        }
        out.truncate(want);
        // Packed bits have no byte order (and no predictor): widened later.
        if row_bytes > 0 && self.packed_bits == 0 {
            let mut scratch = Vec::new();
            for row in out.chunks_exact_mut(row_bytes) {
                self.unpredict_row(row, &mut scratch);
            }
        }
        Ok(())
    }

    /// The decompressed bytes: at least `want` of them unless the data ends
    /// first, and one more than `allowed` where it runs on past them (the
    /// caller reports either).
    fn decompress(&self, coded: &[u8], want: usize, allowed: usize, out: &mut Vec<u8>) -> Result<(), String> {
        out.clear();
        out.reserve(want);
        match self.compression {
            1 => out.extend_from_slice(&coded[..want.min(coded.len())]),
            8 | 32946 => read_up_to(flate2::read::ZlibDecoder::new(coded), want, allowed, out, "deflate")?,
            50000 => read_up_to(zstd::stream::read::Decoder::new(coded).map_err(|e| format!("zstd: {e}"))?, want, allowed, out, "zstd")?,
            5 => {
                // Decoded into a buffer one byte past what the chunk may
                // hold: a stream that fills it runs on (corrupt or hostile)
                // and stops there.
                let cap = allowed + 1;
                out.resize(cap, 0);
                let mut lzw = weezl::decode::Decoder::with_tiff_size_switch(weezl::BitOrder::Msb, 8);
                let (mut read, mut written) = (0, 0);
                while written < cap {
                    let r = lzw.decode_bytes(&coded[read..], &mut out[written..]);
                    read += r.consumed_in;
                    written += r.consumed_out;
                    match r.status {
                        Ok(weezl::LzwStatus::Ok) if r.consumed_in + r.consumed_out > 0 => {}
                        // The end code, or the data ran out: what is there
                        // is all there is.
                        Ok(_) => break,
                        Err(e) => return Err(format!("LZW: {e}")),
                    }
                }
                // A stream that breaks off after the chunk's bytes (no end
                // code, junk after it) has given all we need.
                out.truncate(written);
            }
            32773 => unpack_bits(coded, allowed + 1, out),
            c => return Err(format!("TIFF compression {c}")),
        }
        Ok(())
    }

    /// One row from the file's coding to native-endian samples.
    fn unpredict_row(&self, row: &mut [u8], scratch: &mut Vec<u8>) {
        let (n, sb) = (self.samples, self.sample_bytes);
        if self.predictor == 3 {
            // Bytes were differenced across the row, then stored as planes
            // of most- to least-significant bytes.
            for i in n..row.len() {
                row[i] = row[i].wrapping_add(row[i - n]);
            }
            scratch.clear();
            scratch.extend_from_slice(row);
            let plane = row.len() / sb;
            for (i, v) in row.chunks_exact_mut(sb).enumerate() {
                for (b, byte) in v.iter_mut().enumerate() {
                    // Big-endian order in the planes; native order out.
                    let from = if cfg!(target_endian = "big") { b } else { sb - 1 - b };
                    *byte = scratch[from * plane + i];
                }
            }
            return;
        }
        if self.big_endian != cfg!(target_endian = "big") && sb > 1 {
            for v in row.chunks_exact_mut(sb) {
                v.reverse();
            }
        }
        if self.predictor == 2 {
            match sb {
                1 => add_previous(row, n, |a: u8, b| a.wrapping_add(b), u8::from_ne_bytes, u8::to_ne_bytes),
                2 => add_previous(row, n, u16::wrapping_add, u16::from_ne_bytes, u16::to_ne_bytes),
                4 => add_previous(row, n, u32::wrapping_add, u32::from_ne_bytes, u32::to_ne_bytes),
                _ => add_previous(row, n, u64::wrapping_add, u64::from_ne_bytes, u64::to_ne_bytes),
            }
        }
    }
}

/// Undoes horizontal differencing: each sample plus the same band's sample
/// of the pixel before, with wrapping integers of `N` bytes (as libtiff and
/// the `tiff` crate do, also for floats).
fn add_previous<T: Copy, const N: usize>(row: &mut [u8], bands: usize, add: fn(T, T) -> T, load: fn([u8; N]) -> T, store: fn(T) -> [u8; N]) {
    let get = |row: &[u8], i: usize| load(row[i * N..i * N + N].try_into().expect("N bytes"));
    for i in bands..row.len() / N {
        let v = add(get(row, i), get(row, i - bands));
        row[i * N..i * N + N].copy_from_slice(&store(v));
    }
}

/// Is this TIFF file big-endian ("MM")? From its first two bytes.
pub fn file_is_big_endian(file: &std::fs::File) -> std::io::Result<bool> {
    use std::os::unix::fs::FileExt;
    let mut order = [0u8; 2];
    file.read_exact_at(&mut order, 0)?;
    Ok(&order == b"MM")
}

/// Reads up to `want` bytes of a decompressing reader into `out`, then on
/// to the stream's end, so that the codec checks what it carries to check
/// (zlib's Adler-32, zstd's checksum): a chunk that does not check out is
/// an error, not pixels. What a stream holds past `want` up to `allowed`
/// (a last strip written at full height) is passed over; past that, it
/// runs on, and `out` gets one byte more than `allowed` to say so.
fn read_up_to(mut r: impl Read, want: usize, allowed: usize, out: &mut Vec<u8>, what: &str) -> Result<(), String> {
    let err = |e: std::io::Error| format!("{what}: {e}");
    (&mut r).take(want as u64).read_to_end(out).map_err(err)?;
    let mut rest = [0u8; 4096];
    let mut past = 0usize;
    loop {
        match r.read(&mut rest) {
            Ok(0) => return Ok(()),
            Ok(n) => past += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(err(e)),
        }
        if want + past > allowed {
            out.resize(allowed + 1, 0);
            return Ok(());
        }
    }
}

/// Apple PackBits, as TIFF uses it: a header byte n, then n+1 literal bytes
/// (0 ≤ n ≤ 127) or one byte repeated 1−n times (−127 ≤ n ≤ −1); −128 is a
/// no-op. Stops at `want` bytes or at the end of the data.
fn unpack_bits(mut coded: &[u8], want: usize, out: &mut Vec<u8>) {
    while out.len() < want {
        let Some((&h, rest)) = coded.split_first() else { return };
        coded = rest;
        let h = h as i8;
        if h >= 0 {
            let n = (h as usize + 1).min(coded.len());
            out.extend_from_slice(&coded[..n]);
            coded = &coded[n..];
        } else if h != -128 {
            let Some((&b, rest)) = coded.split_first() else { return };
            coded = rest;
            out.resize(out.len() + (1 - h as isize) as usize, b);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn twelve_bit_rows_widen_to_their_samples() {
        // Two rows of three 12-bit samples: 0xABC 0x123 0xFFF (4.5 bytes,
        // padded to 5), then 0x001 0x800 0x7FF.
        let packed = [0xAB, 0xC1, 0x23, 0xFF, 0xF0, 0x00, 0x18, 0x00, 0x7F, 0xF0];
        // The same from a big-endian file: bits have no byte order.
        for big_endian in [false, true] {
            let mut c = codec(1, 1, 2, 1, big_endian);
            c.packed_bits = 12;
            let got = c.decode(&packed, 3, 2, 2).unwrap();
            let v: Vec<u16> = got.chunks_exact(2).map(|b| u16::from_ne_bytes([b[0], b[1]])).collect();
            assert_eq!(v, [0xABC, 0x123, 0xFFF, 0x001, 0x800, 0x7FF], "big-endian: {big_endian}");
        }
    }

    #[test]
    fn packbits_decodes_the_tiff_specification_example() {
        // TIFF 6.0, section 9: the packed bytes and what they unpack to.
        let packed = [0xFE, 0xAA, 0x02, 0x80, 0x00, 0x2A, 0xFD, 0xAA, 0x03, 0x80, 0x00, 0x2A, 0x22, 0xF7, 0xAA];
        let unpacked =
            [0xAA, 0xAA, 0xAA, 0x80, 0x00, 0x2A, 0xAA, 0xAA, 0xAA, 0xAA, 0x80, 0x00, 0x2A, 0x22, 0xAA, 0xAA, 0xAA, 0xAA, 0xAA, 0xAA, 0xAA, 0xAA, 0xAA, 0xAA];
        let mut out = Vec::new();
        unpack_bits(&packed, 1000, &mut out);
        assert_eq!(out, unpacked);
        // Stops at what was asked, and at the end of truncated data.
        let mut out = Vec::new();
        unpack_bits(&packed, 5, &mut out);
        assert!(out.len() >= 5 && out[..5] == unpacked[..5]);
        let mut out = Vec::new();
        unpack_bits(&packed[..3], 1000, &mut out);
        assert_eq!(out, [0xAA, 0xAA, 0xAA]);
    }

    fn codec(compression: u16, predictor: u16, sample_bytes: usize, samples: usize, big_endian: bool) -> ChunkCodec {
        ChunkCodec { compression, predictor, sample_bytes, float: sample_bytes >= 4, samples, big_endian, packed_bits: 0 }
    }

    #[test]
    fn horizontal_and_floating_point_predictors_are_undone() {
        // Two pixels of four 8-bit bands, differenced per band.
        let mut row = vec![10, 20, 30, 40, 1, 2, 3, 250];
        codec(8, 2, 1, 4, false).unpredict_row(&mut row, &mut Vec::new());
        assert_eq!(row, [10, 20, 30, 40, 11, 22, 33, 34]);
        // 16-bit big-endian: byte order first, then differences (wrapping).
        let mut row = vec![0x01, 0x00, 0xFF, 0xFF];
        codec(8, 2, 2, 1, true).unpredict_row(&mut row, &mut Vec::new());
        assert_eq!(row, [256u16.to_ne_bytes(), 255u16.to_ne_bytes()].concat());
        // Floating point: the values 1.0 and −2.5 coded as byte planes of
        // their big-endian bytes, then differenced byte by byte.
        let (a, b) = (1.0f32.to_be_bytes(), (-2.5f32).to_be_bytes());
        let planes = [a[0], b[0], a[1], b[1], a[2], b[2], a[3], b[3]];
        let mut coded = planes;
        for i in (1..coded.len()).rev() {
            coded[i] = coded[i].wrapping_sub(coded[i - 1]);
        }
        let mut row = coded.to_vec();
        codec(8, 3, 4, 1, false).unpredict_row(&mut row, &mut Vec::new());
        assert_eq!(row, [1.0f32.to_ne_bytes(), (-2.5f32).to_ne_bytes()].concat());
    }

    /// The encoder's side of both predictors, written from the TIFF
    /// specification and Technical Note 3: `values` are `sb`-byte integers
    /// (or float bits), `n` bands a pixel.
    fn predicted(values: &[u64], sb: usize, n: usize, predictor: u16, big_endian: bool) -> Vec<u8> {
        let mask = if sb == 8 { u64::MAX } else { (1u64 << (8 * sb)) - 1 };
        if predictor == 3 {
            let (w, mut row) = (values.len(), vec![0u8; values.len() * sb]);
            for (i, v) in values.iter().enumerate() {
                for (k, b) in v.to_be_bytes()[8 - sb..].iter().enumerate() {
                    row[k * w + i] = *b;
                }
            }
            for i in (n..row.len()).rev() {
                row[i] = row[i].wrapping_sub(row[i - n]);
            }
            return row;
        }
        let mut out = Vec::new();
        for (i, &v) in values.iter().enumerate() {
            let d = if predictor == 2 && i >= n { v.wrapping_sub(values[i - n]) & mask } else { v };
            let be = &d.to_be_bytes()[8 - sb..];
            out.extend(if big_endian { be.to_vec() } else { be.iter().rev().copied().collect() });
        }
        out
    }

    #[test]
    fn every_sample_width_band_count_and_byte_order_round_trips() {
        let mut cases = 0;
        for sb in [1usize, 2, 4, 8] {
            for n in [1usize, 3, 4] {
                for big_endian in [false, true] {
                    for predictor in [1u16, 2, 3] {
                        if predictor == 3 && sb < 4 {
                            continue;
                        }
                        let mask = if sb == 8 { u64::MAX } else { (1u64 << (8 * sb)) - 1 };
                        let values: Vec<u64> = (0..7 * n as u64).map(|i| i.wrapping_mul(0x9E37_79B9_7F4A_7C15).rotate_left(17) & mask).collect();
                        let mut row = predicted(&values, sb, n, predictor, big_endian);
                        let c = ChunkCodec { compression: 1, predictor, sample_bytes: sb, float: true, samples: n, big_endian, packed_bits: 0 };
                        c.check().unwrap();
                        c.unpredict_row(&mut row, &mut Vec::new());
                        // Native-endian samples of `sb` bytes, read back.
                        let got: Vec<u64> = row
                            .chunks_exact(sb)
                            .map(|b| {
                                let msb_first: Vec<u8> = if cfg!(target_endian = "little") { b.iter().rev().copied().collect() } else { b.to_vec() };
                                msb_first.iter().fold(0u64, |a, &x| a << 8 | x as u64)
                            })
                            .collect();
                        assert_eq!(got, values, "{sb}-byte, {n} bands, big-endian {big_endian}, predictor {predictor}");
                        cases += 1;
                    }
                }
            }
        }
        assert_eq!(cases, 60);
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_bytes_decode_or_fail_without_panic(
            coded in proptest::collection::vec(proptest::num::u8::ANY, 0..300),
            which in 0usize..6, predictor in 1u16..4, sb in 0usize..4, n in 1usize..5, width in 0usize..40, rows in 0usize..9,
        ) {
            let compression = [1, 5, 8, 32946, 32773, 50000][which];
            let c = ChunkCodec { compression, predictor, sample_bytes: 1 << sb, float: true, samples: n, big_endian: width % 2 == 0, packed_bits: 0 };
            if c.check().is_ok() {
                if let Ok(v) = c.decode(&coded, width, rows, rows) {
                    proptest::prop_assert_eq!(v.len(), width * rows * n * (1 << sb));
                }
            }
        }
    }

    #[test]
    fn short_or_corrupt_data_is_an_error_not_a_panic() {
        let c = codec(8, 1, 1, 4, false);
        let e = c.decode(&[1, 2, 3], 4, 4, 4).unwrap_err();
        assert!(e.contains("deflate"), "{e}");
        let c = codec(32773, 1, 1, 4, false);
        let e = c.decode(&[0x01, 7, 7], 4, 4, 4).unwrap_err();
        assert!(e.contains("its pixels need 64"), "{e}");
        assert!(codec(7, 1, 1, 4, false).check().is_err());
        assert!(codec(8, 3, 2, 4, false).check().is_err());
    }

    #[test]
    fn a_chunk_that_fails_its_checksum_is_an_error() {
        use std::io::Write;
        let pixels: Vec<u8> = (0..64u8).collect();
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&pixels).unwrap();
        let mut deflated = z.finish().unwrap();
        let c = codec(8, 1, 1, 4, false);
        assert_eq!(c.decode(&deflated, 4, 4, 4).unwrap(), pixels);
        // The Adler-32 at the end, one bit off: the pixels are all there,
        // but the chunk is not what was written.
        *deflated.last_mut().unwrap() ^= 1;
        let e = c.decode(&deflated, 4, 4, 4).unwrap_err();
        assert!(e.contains("deflate"), "{e}");
        // A larger chunk, whose pixels come out before the checksum is read.
        let big: Vec<u8> = (0..64 * 64 * 4).map(|i: u32| (i.wrapping_mul(2_654_435_761) >> 24) as u8).collect();
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&big).unwrap();
        let mut deflated = z.finish().unwrap();
        assert_eq!(c.decode(&deflated, 64, 64, 64).unwrap(), big);
        *deflated.last_mut().unwrap() ^= 1;
        assert!(c.decode(&deflated, 64, 64, 64).unwrap_err().contains("deflate"));
        // zstd with its content checksum, one bit of it off.
        let mut enc = zstd::stream::write::Encoder::new(Vec::new(), 3).unwrap();
        enc.include_checksum(true).unwrap();
        enc.write_all(&pixels).unwrap();
        let mut zst = enc.finish().unwrap();
        let c = codec(50000, 1, 1, 4, false);
        assert_eq!(c.decode(&zst, 4, 4, 4).unwrap(), pixels);
        *zst.last_mut().unwrap() ^= 1;
        assert!(c.decode(&zst, 4, 4, 4).unwrap_err().contains("zstd"));
        // A stream that runs on far past its chunk is not this chunk.
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&vec![7u8; 64 * 1024]).unwrap();
        let long = z.finish().unwrap();
        assert!(codec(8, 1, 1, 4, false).decode(&long, 4, 4, 4).unwrap_err().contains("runs on past"));
    }

    #[test]
    fn streams_that_run_on_past_their_chunk_are_errors_a_full_height_last_strip_is_not() {
        use std::io::Write;
        // 4 pixels of 4 one-byte samples a row: 16 bytes.
        let rows2: Vec<u8> = (0..32u8).collect();
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&rows2).unwrap();
        let two_rows = z.finish().unwrap();
        let deflate = codec(8, 1, 1, 4, false);
        // A last strip of one row, written at the strip's full two rows.
        assert_eq!(deflate.decode(&two_rows, 4, 1, 2).unwrap(), rows2[..16]);
        // The same stream for a chunk of one row: it runs on.
        assert!(deflate.decode(&two_rows, 4, 1, 1).unwrap_err().contains("runs on past"));
        // PackBits: 128 copies of one byte where 16 are wanted.
        let packbits = codec(32773, 1, 1, 4, false);
        assert!(packbits.decode(&[0x81, 7], 4, 1, 1).unwrap_err().contains("runs on past"));
        assert_eq!(packbits.decode(&[0xF1, 7], 4, 1, 1).unwrap(), vec![7; 16]);
        // LZW: 64 bytes where 16 are wanted.
        let mut lzw = weezl::encode::Encoder::with_tiff_size_switch(weezl::BitOrder::Msb, 8);
        let coded = lzw.encode(&[3u8; 64]).unwrap();
        let lzw_codec = codec(5, 1, 1, 4, false);
        assert!(lzw_codec.decode(&coded, 4, 1, 1).unwrap_err().contains("runs on past"));
        assert_eq!(lzw_codec.decode(&coded, 4, 4, 4).unwrap(), vec![3; 64]);
    }
}
