//! Every output is born as a temporary file in the target folder, its
//! space reserved up front where it is large, and published under its final
//! name (synced first where asked) only when complete; a run that does not
//! finish removes it.

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

/// The end of every temporary output's name.
const SUFFIX: &str = ".gcm-partial";

/// This machine's name: temporaries on a shared disk are told apart by it.
fn host() -> String {
    let uname = rustix::system::uname();
    uname.nodename().to_string_lossy().replace(['~', '/'], "_")
}

/// `.NAME~PID@HOST~` — then tempfile's random letters, then [`SUFFIX`]:
/// whoever finds it later can tell whether the process that made it still
/// runs. NAME is cut to keep the whole under the 255 bytes a name may have.
fn temp_prefix(target_name: &str, pid: u32, host: &str) -> String {
    let mut cut = target_name.len().min(120);
    while !target_name.is_char_boundary(cut) {
        cut -= 1;
    }
    let host = &host[..host.len().min(64)];
    format!(".{}~{pid}@{host}~", &target_name[..cut])
}

/// The process and machine that made a temporary output named `name`.
fn temp_owner(name: &str) -> Option<(u32, &str)> {
    let body = name.strip_prefix('.')?.strip_suffix(SUFFIX)?;
    let (rest, _random) = body.rsplit_once('~')?;
    let (_, owner) = rest.rsplit_once('~')?;
    let (pid, host) = owner.split_once('@')?;
    Some((pid.parse().ok()?, host))
}

/// Removes the temporary outputs in `dir` left by processes of this machine
/// that are gone (killed, say by the out-of-memory killer, before they
/// could clean up). Those of other machines sharing the disk are left.
pub fn remove_dead_temporaries(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    let me = host();
    for e in entries.flatten() {
        let name = e.file_name();
        let Some((pid, host)) = name.to_str().and_then(temp_owner) else { continue };
        if host == me && !runs(pid) {
            // A folder of an output's parts (`pending_dir`), or a file.
            let _ = match e.file_type() {
                Ok(t) if t.is_dir() => std::fs::remove_dir_all(e.path()),
                _ => std::fs::remove_file(e.path()),
            };
        }
    }
}

/// Whether process `pid` of this machine still runs: not gone, and not a
/// zombie (a process killed with its parent, say by `timeout -s KILL`,
/// stays one until it is reaped, its temporaries long abandoned).
fn runs(pid: u32) -> bool {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else { return false };
    // `pid (command) state …`: the command may hold spaces and parentheses.
    let state = stat.rsplit_once(')').and_then(|(_, rest)| rest.trim_start().chars().next());
    !matches!(state, Some('Z' | 'X') | None)
}

/// The folder a file is (to be) in.
pub fn folder_of(target: &Path) -> PathBuf {
    match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A temporary folder beside `target` for the parts an output is made of
/// before they are put together into it; named as temporary outputs are,
/// so that one a killed run left is removed as theirs are. Dropped, it is
/// removed; a process ended by a signal's watchdog removes it too.
pub fn pending_dir(target: &Path) -> Result<PendingDir> {
    let (dir, prefix) = temporary_beside(target);
    let parts = tempfile::Builder::new().prefix(&prefix).suffix(SUFFIX).tempdir_in(&dir).map_err(|e| Error::io(&dir, e))?;
    crate::io::mmap_guard::register_cleanup(parts.path());
    Ok(PendingDir(parts))
}

/// See [`pending_dir`].
#[derive(Debug)]
pub struct PendingDir(tempfile::TempDir);

impl PendingDir {
    pub fn path(&self) -> &Path {
        self.0.path()
    }
}

impl Drop for PendingDir {
    fn drop(&mut self) {
        // (Then the folder itself goes, with its field.)
        crate::io::mmap_guard::unregister_cleanup(self.0.path());
    }
}

/// The folder of `target`, cleared of dead temporaries, and the prefix of
/// a temporary of ours for it there.
fn temporary_beside(target: &Path) -> (PathBuf, String) {
    let dir = folder_of(target);
    remove_dead_temporaries(&dir);
    let name = target.file_name().and_then(|n| n.to_str()).unwrap_or("out");
    (dir, temp_prefix(name, std::process::id(), &host()))
}

impl PendingFile {
    pub fn create(target: &Path) -> Result<PendingFile> {
        // Never a file renamed over a device or a pipe (`-o /dev/null`
        // would put a file in its place for every process after).
        if let Some(kind) = crate::io::overwrite::special_kind(target) {
            return Err(crate::io::overwrite::not_a_file(crate::io::overwrite::Role::new("output", target), kind));
        }
        crate::io::overwrite::check_not_read("output", target)?;
        // A symbolic link is written through: the file it names is the
        // one replaced, the link stays.
        let resolved = match std::fs::symlink_metadata(target) {
            Ok(m) if m.file_type().is_symlink() => std::fs::canonicalize(target).map_err(|e| Error::io(target, e))?,
            _ => target.to_path_buf(),
        };
        let target = resolved.as_path();
        let (dir, prefix) = temporary_beside(target);
        // Named by the file asked for: tempfile's own error names its
        // temporary, which the user never gave.
        let tmp = tempfile::Builder::new().prefix(&prefix).suffix(SUFFIX).tempfile_in(&dir).map_err(|e| Error::io(target, without_path(&e)))?;
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
        // Read since the file was made (a CRS file inside a camera file).
        crate::io::overwrite::check_not_read("output", &target)?;
        let tmp = self.tmp.take().expect("not yet published");
        let tmp_path = tmp.path().to_path_buf();
        crate::io::mmap_guard::unregister_cleanup(&tmp_path);
        tmp.persist(&target).map_err(|e| Error::io(&target, e.error))?;
        if let Some(ledger) = LEDGER.lock().unwrap_or_else(std::sync::PoisonError::into_inner).as_mut() {
            ledger.push(target);
        }
        Ok(())
    }
}

/// The files published since [`record_publications`], while it records.
static LEDGER: std::sync::Mutex<Option<Vec<PathBuf>>> = std::sync::Mutex::new(None);

/// From now on, every file this process publishes is noted, for
/// [`withdraw_publications`]: a command whose last step (its report) fails
/// takes back what it wrote before. Library callers that never ask keep no list.
pub fn record_publications() {
    *LEDGER.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(Vec::new());
}

/// Removes every file published since [`record_publications`]; the paths
/// that could not be removed come back.
pub fn withdraw_publications() -> Vec<PathBuf> {
    let published = LEDGER.lock().unwrap_or_else(std::sync::PoisonError::into_inner).as_mut().map(std::mem::take).unwrap_or_default();
    published.into_iter().filter(|p| std::fs::remove_file(p).is_err_and(|e| e.kind() != std::io::ErrorKind::NotFound)).collect()
}

/// Writes `bytes` to `path` as every output is written: a temporary file
/// beside it, synced, renamed into place.
/// `e` without the path `tempfile` puts in its message (a temporary's,
/// which the user never named): the system's error alone.
pub fn without_path(e: &std::io::Error) -> std::io::Error {
    e.raw_os_error().map_or_else(|| std::io::Error::from(e.kind()), std::io::Error::from_raw_os_error)
}

pub fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    match write_pending(path, bytes)? {
        Some(pending) => pending.publish(),
        None => Ok(()),
    }
}

/// [`write_file`] up to the rename: the file written under its temporary
/// name, for the caller to publish once the rest of its run is done (a
/// run stopped before leaves none of it). `None`: `path` is a stream or a
/// device, written into at once.
pub fn write_pending(path: &Path, bytes: &[u8]) -> Result<Option<PendingFile>> {
    use std::io::Write;
    // A report into a stream (`--json /dev/stdout`, a pipe, the file the
    // shell opened for it): written into it, after what the run printed.
    let std_stream = |names: [&str; 3]| names.iter().any(|n| path == Path::new(n));
    if std_stream(["/dev/stdout", "/dev/fd/1", "/proc/self/fd/1"]) {
        let mut out = std::io::stdout().lock();
        return out.write_all(bytes).and_then(|()| out.flush()).map(|()| None).map_err(|e| Error::io(path, e));
    }
    if std_stream(["/dev/stderr", "/dev/fd/2", "/proc/self/fd/2"]) {
        return std::io::stderr().lock().write_all(bytes).map(|()| None).map_err(|e| Error::io(path, e));
    }
    let descriptor = ["/dev/fd", "/proc/self/fd"].iter().any(|d| path.starts_with(d));
    if descriptor || crate::io::overwrite::special_kind(path).is_some() {
        let mut f = std::fs::OpenOptions::new().append(true).open(path).map_err(|e| Error::io(path, e))?;
        return f.write_all(bytes).map(|()| None).map_err(|e| Error::io(path, e));
    }
    let pending = PendingFile::create(path)?;
    pending.file()?.write_all(bytes).map_err(|e| Error::io(path, e))?;
    Ok(Some(pending))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_zombies_temporary_is_removed() {
        let dir = tempfile::tempdir().unwrap();
        // A child not reaped: once it has ended, a zombie.
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        for _ in 0..500 {
            if !runs(pid) {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        assert!(!runs(pid) && Path::new(&format!("/proc/{pid}")).exists(), "a zombie keeps its /proc entry");
        let t = dir.path().join(format!("{}abcdef{SUFFIX}", temp_prefix("x.tif", pid, &host())));
        std::fs::write(&t, b"").unwrap();
        remove_dead_temporaries(dir.path());
        assert!(!t.exists());
        child.wait().unwrap();
        assert!(runs(std::process::id()));
    }

    #[test]
    fn temporaries_of_dead_processes_are_found_and_removed() {
        let dir = tempfile::tempdir().unwrap();
        let me = host();
        // A long name still makes a temporary name a file system takes.
        let long = "a".repeat(250);
        let p = PendingFile::create(&dir.path().join(&long)).unwrap();
        let name = p.path().file_name().unwrap().to_str().unwrap().to_string();
        assert!(name.len() <= 255, "{}", name.len());
        assert_eq!(temp_owner(&name), Some((std::process::id(), me.as_str())));
        // One of a process that is gone (pid 0 is never a process's), one
        // of another machine, one not ours: only the first goes.
        let dead = dir.path().join(format!("{}abcdef{SUFFIX}", temp_prefix("x.tif", 0, &me)));
        let other = dir.path().join(format!("{}abcdef{SUFFIX}", temp_prefix("x.tif", 0, "elsewhere")));
        let user = dir.path().join(".x.tif~0@me~keep.partial");
        for f in [&dead, &other, &user] {
            std::fs::write(f, b"").unwrap();
        }
        // A folder of parts of a process that is gone, with a part in it;
        // one of this process stays.
        let dead_parts = dir.path().join(format!("{}ghijkl{SUFFIX}", temp_prefix("y.tif", 0, &me)));
        std::fs::create_dir(&dead_parts).unwrap();
        std::fs::write(dead_parts.join("strip-0000.tif"), b"part").unwrap();
        let parts = pending_dir(&dir.path().join("y.tif")).unwrap();
        assert_eq!(temp_owner(parts.path().file_name().unwrap().to_str().unwrap()), Some((std::process::id(), me.as_str())));
        remove_dead_temporaries(dir.path());
        assert!(!dead.exists() && other.exists() && user.exists() && p.path().exists());
        assert!(!dead_parts.exists() && parts.path().exists());
        p.publish().unwrap();
        assert!(dir.path().join(&long).exists());
    }
}
