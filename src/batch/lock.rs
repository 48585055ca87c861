//! One run at a time on a job: two batches started on one manifest (a
//! nightly job still running when the next starts, a job array given the
//! same shard twice) would both make it. A job's run holds an exclusive
//! lock on a file beside its output while it makes it, and removes the
//! file when done; a run that finds it held leaves the job to the holder.

use std::fs::{File, OpenOptions, TryLockError};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// The lock of the job writing an output, held until dropped.
#[derive(Debug)]
pub struct JobLock {
    path: PathBuf,
    // Closed (the lock let go) after the file is removed.
    _file: File,
}

/// Where the lock of the job writing `output` is: beside it, `.lock`.
pub fn lock_path(output: &Path) -> PathBuf {
    let mut s = output.as_os_str().to_owned();
    s.push(".lock");
    PathBuf::from(s)
}

impl JobLock {
    /// The lock of the job writing `output`; `None` where another run holds it.
    pub fn take(output: &Path) -> std::io::Result<Option<JobLock>> {
        let path = lock_path(output);
        loop {
            let file = OpenOptions::new().create(true).write(true).truncate(false).open(&path)?;
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => return Ok(None),
                Err(TryLockError::Error(e)) => return Err(e),
            }
            // The holder before removes the file as it lets go: a lock on
            // a file no longer at the path locks nothing; open it anew.
            let (held, there) = (file.metadata()?, std::fs::metadata(&path));
            if there.is_ok_and(|m| m.dev() == held.dev() && m.ino() == held.ino()) {
                return Ok(Some(JobLock { path, _file: file }));
            }
        }
    }
}

impl Drop for JobLock {
    fn drop(&mut self) {
        // Removed while still held: no other run can have locked it meanwhile.
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_job_is_locked_once_and_let_go_with_its_file_removed() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("a.tif");
        let first = JobLock::take(&out).unwrap().expect("free");
        assert!(lock_path(&out).is_file());
        assert!(JobLock::take(&out).unwrap().is_none(), "held by the first");
        drop(first);
        assert!(!lock_path(&out).exists());
        let again = JobLock::take(&out).unwrap();
        assert!(again.is_some());
    }
}
