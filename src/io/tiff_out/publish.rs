//! The output's temporary file in the target folder, its space reserved
//! up front, and its publication under the final name (synced first where
//! asked), or its removal when the run does not finish.

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// Allocates the first `len` bytes of `file` on disk ahead of the writes
/// (its size stays as it is): ext4 and XFS then skip, for every page
/// written, the bookkeeping of delayed allocation. Where the file system
/// cannot, nothing happens; the writes allocate as usual. Not on tmpfs,
/// whose "disk" is memory: there it would take every page of the output up
/// front, on one thread before any tile is made, instead of page by page as
/// the writer writes them, beside the resampling.
pub fn reserve(file: &std::fs::File, len: u64) {
    const TMPFS_MAGIC: u64 = 0x0102_1994;
    if rustix::fs::fstatfs(file).is_ok_and(|s| s.f_type as u64 == TMPFS_MAGIC) {
        return;
    }
    let _ = rustix::fs::fallocate(file, rustix::fs::FallocateFlags::KEEP_SIZE, 0, len);
}

/// A temporary file next to the output that becomes the output only when
/// `publish` is called; dropped, it is removed.
pub struct PendingFile {
    /// `None` once published.
    tmp: Option<tempfile::NamedTempFile>,
    target: PathBuf,
}

impl Drop for PendingFile {
    fn drop(&mut self) {
        // The NamedTempFile removes itself right after this.
        if let Some(t) = &self.tmp {
            crate::io::mmap_guard::unregister_cleanup(t.path());
        }
    }
}

impl PendingFile {
    pub fn create(target: &Path) -> Result<PendingFile> {
        let dir = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let name = target.file_name().and_then(|n| n.to_str()).unwrap_or("out");
        let tmp = tempfile::Builder::new().prefix(&format!(".{name}.")).suffix(".partial").tempfile_in(&dir).map_err(|e| Error::io(&dir, e))?;
        crate::io::mmap_guard::register_cleanup(tmp.path());
        Ok(PendingFile { tmp: Some(tmp), target: target.to_path_buf() })
    }

    fn tmp(&self) -> &tempfile::NamedTempFile {
        self.tmp.as_ref().expect("not yet published")
    }

    pub fn file(&self) -> Result<std::fs::File> {
        self.tmp().reopen().map_err(|e| Error::io(self.tmp().path(), e))
    }

    pub fn path(&self) -> &Path {
        self.tmp().path()
    }

    /// Syncs, then renames onto the target (readable by all, as a plain
    /// new file would be; the temporary file was private).
    pub fn publish(self) -> Result<()> {
        self.publish_synced(true)
    }

    /// [`publish`](Self::publish), with the sync only when `sync` (without
    /// it, a power failure soon after may leave the target incomplete).
    pub fn publish_synced(mut self, sync: bool) -> Result<()> {
        use std::os::unix::fs::PermissionsExt;
        let f = self.tmp().as_file();
        f.set_permissions(std::fs::Permissions::from_mode(0o644)).map_err(|e| Error::io(&self.target, e))?;
        if sync {
            f.sync_all().map_err(|e| Error::io(&self.target, e))?;
        }
        let target = self.target.clone();
        let tmp = self.tmp.take().expect("not yet published");
        let tmp_path = tmp.path().to_path_buf();
        crate::io::mmap_guard::unregister_cleanup(&tmp_path);
        tmp.persist(&target).map_err(|e| Error::io(&target, e.error))?;
        Ok(())
    }
}
