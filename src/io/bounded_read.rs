//! Small files (camera files, RPC text, manifests, CSVs) read whole, but
//! never more than their kind can be: a scan given by mistake where a text
//! file belongs is refused from its size, not read into memory.

use crate::error::{Error, Result};
use std::io::Read;
use std::path::Path;

/// Camera files, RPC files in text, XML or NITF headers, world files.
pub const SMALL: u64 = 16 << 20;
/// Manifests, exterior orientations and checkpoint lists of big blocks.
pub const LIST: u64 = 64 << 20;

/// The bytes of `path`, refused (naming `what` it should be) if it holds
/// more than `limit`.
pub fn read_bounded(path: &Path, what: &str, limit: u64) -> Result<Vec<u8>> {
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let len = f.metadata().map_err(|e| Error::io(path, e))?.len();
    let too_large = |n: u64| Error::limits(path, format!("{} MB is too large for {what} (at most {} MB)", n / 1_000_000, limit / 1_000_000));
    if len > limit {
        return Err(too_large(len));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    // The file may grow while it is read: never past the limit.
    f.take(limit + 1).read_to_end(&mut bytes).map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// [`read_bounded`] as UTF-8 text.
pub fn read_text_bounded(path: &Path, what: &str, limit: u64) -> Result<String> {
    String::from_utf8(read_bounded(path, what, limit)?).map_err(|_| Error::format(path, format!("not {what}: not UTF-8 text")))
}

/// The first `n` bytes of `path` (fewer if it is shorter).
pub fn read_head(path: &Path, n: u64) -> Result<Vec<u8>> {
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut bytes = Vec::new();
    f.take(n).read_to_end(&mut bytes).map_err(|e| Error::io(path, e))?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_over_its_limit_is_refused_by_its_size() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("camera.toml");
        std::fs::write(&p, vec![b'x'; 1000]).unwrap();
        assert_eq!(read_bounded(&p, "a camera file", 1000).unwrap().len(), 1000);
        let e = read_bounded(&p, "a camera file", 999).unwrap_err().to_string();
        assert!(e.contains("too large for a camera file") && e.contains("camera.toml"), "{e}");
        assert_eq!(read_head(&p, 10).unwrap().len(), 10);
        std::fs::write(&p, [0xff, 0xfe]).unwrap();
        assert!(read_text_bounded(&p, "a camera file", 10).unwrap_err().to_string().contains("not UTF-8"));
    }
}
