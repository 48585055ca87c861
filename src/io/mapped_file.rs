//! A whole file mapped read-only (an `.hgt` DEM tile, a `.gtx` geoid grid)
//! and watched by the SIGBUS guard: where the program installed the guard,
//! a file cut short by another process while it is read yields zeros from
//! the cut instead of ending the process, and [`MappedFile::check_intact`]
//! says so by name before anything made of it is published.

use crate::error::{Error, Result};
use crate::io::mmap_guard::{watch_also, watch_range, Watched};
use std::path::{Path, PathBuf};

/// A read-only map of a file of a known length.
#[derive(Debug)]
pub struct MappedFile {
    // Dropped before the map: a watched range is forgotten before it is
    // unmapped.
    watched: Option<Watched>,
    map: memmap2::Mmap,
    path: PathBuf,
}

impl MappedFile {
    /// Maps `path`, which must hold `len` bytes.
    pub fn open(path: &Path, len: u64) -> Result<MappedFile> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        // SAFETY: a read-only map; its length is checked below to be the
        // `len` bytes its reader asked for, so no read within them lies past
        // the file's end as it was. Another process truncating it meanwhile
        // raises SIGBUS inside the watched range: the guard swaps in zero
        // pages and marks the range (`check_intact`).
        let map = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| Error::io(path, e))?;
        if map.len() as u64 != len {
            return Err(Error::format(path, "the file changed size while it was opened"));
        }
        let watched = watch_range(&map);
        // Every slot taken: a fault then ends the process, naming the file.
        if watched.is_none() {
            watch_also(path);
        }
        Ok(MappedFile { watched, map, path: path.to_path_buf() })
    }

    /// An error naming the file where a read of it met its end, the file
    /// truncated underneath (zeros were read from there on).
    pub fn check_intact(&self) -> Result<()> {
        match &self.watched {
            Some(w) if w.truncated() => Err(Error::format(&self.path, "was truncated while being read (its memory map met the end of the file)")),
            _ => Ok(()),
        }
    }
}

impl std::ops::Deref for MappedFile {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        &self.map
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file cut short under its map reads as zeros from the cut, and
    /// says so, instead of ending the process.
    #[test]
    fn a_file_truncated_under_its_map_is_told() {
        crate::io::mmap_guard::install_sigbus_handler();
        let dir = std::env::temp_dir().join(format!("mapped-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("N44E005.hgt");
        let page = 1 << 16;
        std::fs::write(&path, vec![7u8; 4 * page]).unwrap();
        let m = MappedFile::open(&path, 4 * page as u64).unwrap();
        assert_eq!(m[3 * page], 7);
        m.check_intact().unwrap();
        std::fs::OpenOptions::new().write(true).open(&path).unwrap().set_len(page as u64).unwrap();
        assert_eq!(m[page - 1], 7);
        assert_eq!(m[3 * page], 0);
        let e = m.check_intact().unwrap_err().to_string();
        assert!(e.contains("N44E005.hgt") && e.contains("truncated"), "{e}");
        assert!(MappedFile::open(&path, 4 * page as u64).unwrap_err().to_string().contains("changed size"));
        drop(m);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
