//! Files read a chunk at a time share a bounded number of open handles: a
//! DEM of 10⁵ tiles (a national VRT) would otherwise hold 10⁵ descriptors
//! and fail past the process's limit ("Too many open files"). A file's
//! handle is kept among the [`OPEN_AT_MOST`] most recently read and opened
//! again when a read needs it; the file opened again must be the one first
//! opened (the same device and inode), else the read is refused by name.

use crate::error::{Error, Result};
use std::collections::HashMap;
use std::fs::File;
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

/// Handles the pool keeps open at once: far below the usual limit of
/// 1024 descriptors a process, which scans, outputs and threads share.
pub const OPEN_AT_MOST: usize = 128;

/// A file read through the pool.
#[derive(Debug)]
pub struct PooledFile {
    path: PathBuf,
    id: u64,
    /// Device and inode: the file, whatever its name comes to point at.
    identity: (u64, u64),
}

struct Pool {
    open: HashMap<u64, (Arc<File>, u64)>,
    clock: u64,
}

fn pool() -> &'static Mutex<Pool> {
    static POOL: OnceLock<Mutex<Pool>> = OnceLock::new();
    POOL.get_or_init(|| Mutex::new(Pool { open: HashMap::new(), clock: 0 }))
}

impl Pool {
    /// Keeps `file` as `id`'s handle, letting go of the least recently
    /// used beyond [`OPEN_AT_MOST`].
    fn keep(&mut self, id: u64, file: Arc<File>) {
        self.clock += 1;
        self.open.insert(id, (file, self.clock));
        while self.open.len() > OPEN_AT_MOST {
            let Some((&oldest, _)) = self.open.iter().min_by_key(|(_, (_, used))| *used) else { break };
            self.open.remove(&oldest);
        }
    }

    fn take(&mut self, id: u64) -> Option<Arc<File>> {
        self.clock += 1;
        let clock = self.clock;
        self.open.get_mut(&id).map(|(f, used)| {
            *used = clock;
            f.clone()
        })
    }
}

impl PooledFile {
    /// Opens `path` (an error names it) and keeps its handle in the pool.
    pub fn open(path: &Path) -> Result<PooledFile> {
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        let meta = file.metadata().map_err(|e| Error::io(path, e))?;
        let pooled = PooledFile { path: path.to_path_buf(), id: NEXT.fetch_add(1, Ordering::Relaxed), identity: (meta.dev(), meta.ino()) };
        lock().keep(pooled.id, Arc::new(file));
        Ok(pooled)
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// `read` on the file's handle, opened again if the pool let go of it.
    pub fn with<R>(&self, read: impl FnOnce(&File) -> Result<R>) -> Result<R> {
        let held = lock().take(self.id);
        let file = match held {
            Some(f) => f,
            None => {
                let f = File::open(&self.path).map_err(|e| Error::io(&self.path, e))?;
                let meta = f.metadata().map_err(|e| Error::io(&self.path, e))?;
                if (meta.dev(), meta.ino()) != self.identity {
                    return Err(Error::format(&self.path, "was replaced by another file while the run read it"));
                }
                let f = Arc::new(f);
                lock().keep(self.id, f.clone());
                f
            }
        };
        read(&file)
    }
}

impl Drop for PooledFile {
    fn drop(&mut self) {
        lock().open.remove(&self.id);
    }
}

/// The pool, even after a reader panicked holding it (its map is whole
/// between statements).
fn lock() -> std::sync::MutexGuard<'static, Pool> {
    pool().lock().unwrap_or_else(|e| e.into_inner())
}

#[cfg(test)]
/// Handles the pool holds now.
pub fn open_now() -> usize {
    lock().open.len()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn many_files_are_read_through_few_handles_and_a_replaced_one_is_refused() {
        let dir = tempfile::tempdir().expect("a temporary folder");
        let n = OPEN_AT_MOST * 3;
        let files: Vec<PooledFile> = (0..n)
            .map(|k| {
                let p = dir.path().join(format!("{k}.bin"));
                std::fs::write(&p, (k as u32).to_le_bytes()).expect("written");
                PooledFile::open(&p).expect("opened")
            })
            .collect();
        // (Other tests may hold pooled files of their own meanwhile.)
        assert!(open_now() <= OPEN_AT_MOST);
        let read = |f: &PooledFile| {
            f.with(|file| {
                use std::os::unix::fs::FileExt;
                let mut b = [0u8; 4];
                file.read_exact_at(&mut b, 0).map_err(|e| Error::io(f.path(), e))?;
                Ok(u32::from_le_bytes(b))
            })
        };
        for round in 0..2 {
            for (k, f) in files.iter().enumerate() {
                assert_eq!(read(f).expect("read"), k as u32, "round {round}");
                assert!(open_now() <= OPEN_AT_MOST);
            }
        }
        // A file whose handle was let go of (read before the 383 others),
        // replaced under its name.
        let first = &files[0];
        // (Written beside and renamed over it: a new inode, as an editor saves.)
        let beside = dir.path().join("new.bin");
        std::fs::write(&beside, 7u32.to_le_bytes()).expect("written anew");
        std::fs::rename(&beside, first.path()).expect("renamed over");
        let e = read(first).expect_err("another file").to_string();
        assert!(e.contains("0.bin") && e.contains("replaced"), "{e}");
        drop(files);
    }
}
