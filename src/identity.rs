//! Keys of what an output is made from: byte strings and files, told by
//! their contents (or their path, size and time), hashed to 64 bits. An
//! orthophoto's own is the scene's (`scene::made_from`).

use std::path::Path;

/// A 64-bit FNV-1a hash: stable across runs and machines.
pub(crate) fn fnv(h: &mut u64, bytes: &[u8]) {
    for b in bytes {
        *h ^= *b as u64;
        *h = h.wrapping_mul(0x100_0000_01b3);
    }
}

pub(crate) fn file_stamp(h: &mut u64, p: &Path) {
    fnv(h, p.as_os_str().as_encoded_bytes());
    if let Ok(m) = std::fs::metadata(p) {
        fnv(h, &m.len().to_le_bytes());
        if let Ok(t) = m.modified().and_then(|t| t.duration_since(std::time::UNIX_EPOCH).map_err(std::io::Error::other)) {
            fnv(h, &t.as_nanos().to_le_bytes());
        }
    }
}

/// A file as its contents tell it: its size and three samples of
/// [`CONTENT_SAMPLE`] bytes (start, middle, end), so that a copy, a moved
/// or touched file, or one reached by another path matches, and another
/// image, DEM or camera does not.
pub(crate) fn content_stamp(h: &mut u64, p: &Path) {
    use std::io::{Read, Seek, SeekFrom};
    let Ok(mut f) = std::fs::File::open(p) else { return fnv(h, p.as_os_str().as_encoded_bytes()) };
    let len = f.metadata().map_or(0, |m| m.len());
    fnv(h, &len.to_le_bytes());
    let n = CONTENT_SAMPLE.min(len);
    let mut buf = vec![0u8; n as usize];
    for at in [0, (len - n) / 2, len - n] {
        if f.seek(SeekFrom::Start(at)).is_ok() && f.read_exact(&mut buf).is_ok() {
            fnv(h, &buf);
        }
    }
}

/// Bytes of each of a file's samples in [`content_stamp`].
const CONTENT_SAMPLE: u64 = 64 << 10;

/// A key over byte strings and files (path, size, modification time).
pub fn key_of(bytes: &[&[u8]], files: &[&Path]) -> String {
    keyed(bytes, files, file_stamp)
}

/// [`key_of`] with the files told by their contents, not their paths or
/// times (see [`source_key`]).
pub fn content_key_of(bytes: &[&[u8]], files: &[&Path]) -> String {
    keyed(bytes, files, content_stamp)
}

fn keyed(bytes: &[&[u8]], files: &[&Path], stamp: fn(&mut u64, &Path)) -> String {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for b in bytes {
        fnv(&mut h, &(b.len() as u64).to_le_bytes());
        fnv(&mut h, b);
    }
    for f in files {
        stamp(&mut h, f);
    }
    format!("{h:016x}")
}
