//! The memory map's last line of defence, installed by the program (the
//! binary, the Python module). Sizes are checked before mapping and before
//! every window, but another process may still truncate a scan while a
//! page is being copied; the kernel then raises SIGBUS.
//!
//! A fault inside a range registered with [`watch_range`] (a scan's
//! mapping) is survived: the pages from the fault to the range's end are
//! replaced by zeros, the read goes on, and the range is marked; the run
//! checks the mark ([`Watched::truncated`]) before it publishes and fails
//! as every other failure does, with one line naming the file. A host
//! process (Python) lives on. Any other SIGBUS ends the process with one
//! line naming the mapped files, its temporary outputs removed, exit code 1.
//!
//! Paths live in fixed static buffers of atomics: nothing is allocated (or
//! leaked) per file, and the handler reads them without locks.

use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicUsize, Ordering};
use std::sync::Once;

const LEN: usize = 1024;
const SLOTS: usize = 8;

/// A NUL-terminated path in atomics.
struct PathBuf0 {
    bytes: [AtomicU8; LEN],
    used: AtomicBool,
}

impl PathBuf0 {
    const fn new() -> Self {
        PathBuf0 { bytes: [const { AtomicU8::new(0) }; LEN], used: AtomicBool::new(false) }
    }
    fn set(&self, p: &[u8]) {
        let n = p.len().min(LEN - 1);
        for (a, b) in self.bytes.iter().zip(&p[..n]) {
            a.store(*b, Ordering::Relaxed);
        }
        self.bytes[n].store(0, Ordering::Release);
    }
    fn equals(&self, p: &[u8]) -> bool {
        p.len() < LEN && p.iter().enumerate().all(|(i, b)| self.bytes[i].load(Ordering::Relaxed) == *b) && self.bytes[p.len()].load(Ordering::Relaxed) == 0
    }
    /// Copies into `out` (NUL-terminated); the length without the NUL.
    fn copy(&self, out: &mut [u8; LEN]) -> usize {
        let mut n = 0;
        while n < LEN - 1 {
            let b = self.bytes[n].load(Ordering::Acquire);
            if b == 0 {
                break;
            }
            out[n] = b;
            n += 1;
        }
        out[n] = 0;
        n
    }
}

static MAPPED: PathBuf0 = PathBuf0::new();
static ALSO: PathBuf0 = PathBuf0::new();
static CLEANUP: [PathBuf0; SLOTS] = [const { PathBuf0::new() }; SLOTS];
static INSTALL: Once = Once::new();

/// A mapped range whose faults are survived.
struct Range {
    start: AtomicUsize,
    end: AtomicUsize,
    used: AtomicBool,
    hit: AtomicBool,
}

const RANGES: usize = 16;
static WATCHED: [Range; RANGES] =
    [const { Range { start: AtomicUsize::new(0), end: AtomicUsize::new(0), used: AtomicBool::new(false), hit: AtomicBool::new(false) } }; RANGES];
static PAGE: AtomicUsize = AtomicUsize::new(4096);

/// A mapping registered with [`watch_range`]; forgotten when dropped
/// (before the mapping is unmapped).
#[derive(Debug)]
pub struct Watched(usize);

impl Watched {
    /// Whether a read of the mapping met the end of a file truncated
    /// underneath it (what was read from there on is zeros).
    pub fn truncated(&self) -> bool {
        WATCHED[self.0].hit.load(Ordering::Acquire)
    }
}

impl Drop for Watched {
    fn drop(&mut self) {
        let r = &WATCHED[self.0];
        r.end.store(0, Ordering::Release);
        r.start.store(0, Ordering::Release);
        r.hit.store(false, Ordering::Release);
        r.used.store(false, Ordering::Release);
    }
}

/// Registers the mapping `map` (read-only): a fault in it is survived
/// where the handler is installed. `None` when all slots are taken (its
/// faults then end the process, as unregistered ones do).
pub fn watch_range(map: &[u8]) -> Option<Watched> {
    let (start, end) = (map.as_ptr() as usize, map.as_ptr() as usize + map.len());
    for (k, r) in WATCHED.iter().enumerate() {
        if r.used.compare_exchange(false, true, Ordering::AcqRel, Ordering::Relaxed).is_ok() {
            r.hit.store(false, Ordering::Release);
            r.start.store(start, Ordering::Release);
            r.end.store(end, Ordering::Release);
            return Some(Watched(k));
        }
    }
    None
}

/// The faulting page to the end of a watched range holding `addr`, made
/// zeros; whether it was.
fn survive(addr: usize) -> bool {
    let page = PAGE.load(Ordering::Relaxed);
    for r in &WATCHED {
        let (start, end) = (r.start.load(Ordering::Acquire), r.end.load(Ordering::Acquire));
        if !(r.used.load(Ordering::Acquire) && (start..end).contains(&addr)) {
            continue;
        }
        let from = addr & !(page - 1);
        let len = end.div_ceil(page) * page - from;
        // SAFETY: the pages replaced lie within a read-only private
        // mapping of ours (registered, still mapped: a slot is released
        // before its mapping is unmapped); mmap with MAP_FIXED swaps them
        // for zero pages in one system call, which a SIGBUS handler may
        // make (it takes no lock of this process).
        let p = unsafe { libc::mmap(from as *mut libc::c_void, len, libc::PROT_READ, libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_FIXED, -1, 0) };
        if p == libc::MAP_FAILED {
            return false;
        }
        r.hit.store(true, Ordering::Release);
        return true;
    }
    false
}

/// Remembers the file being mapped, for the message.
pub fn watch_mapped(path: &Path) {
    MAPPED.set(path.as_os_str().as_encoded_bytes());
}

/// Remembers a second mapped file (a geoid grid), named beside the first.
pub fn watch_also(path: &Path) {
    ALSO.set(path.as_os_str().as_encoded_bytes());
}

/// Installs the process-wide SIGBUS handler: a program's choice, not a
/// library's, so the binary (and the Python module) call it; without it
/// SIGBUS kills the process as usual (and leaves the temporary output
/// behind).
pub fn install_sigbus_handler() {
    INSTALL.call_once(|| {
        // SAFETY: sysconf only reads a system constant.
        let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
        if page > 0 && (page as usize).is_power_of_two() {
            PAGE.store(page as usize, Ordering::Relaxed);
        }
        // SAFETY: `on_sigbus` reads static atomics and only calls mmap on
        // a watched range of ours, or async-signal-safe functions (write,
        // unlink, _exit) on static buffers.
        unsafe {
            let mut sa: libc::sigaction = std::mem::zeroed();
            sa.sa_sigaction = on_sigbus as *const () as usize;
            sa.sa_flags = libc::SA_SIGINFO;
            libc::sigemptyset(&mut sa.sa_mask);
            libc::sigaction(libc::SIGBUS, &sa, std::ptr::null_mut());
        }
    });
}

/// A temporary file to remove if the process dies of SIGBUS (the first
/// eight at a time are remembered).
pub fn register_cleanup(path: &Path) {
    for slot in &CLEANUP {
        if slot.used.compare_exchange(false, true, Ordering::AcqRel, Ordering::Relaxed).is_ok() {
            slot.set(path.as_os_str().as_encoded_bytes());
            return;
        }
    }
}

/// The temporary file is gone (published or removed): forget it.
pub fn unregister_cleanup(path: &Path) {
    let want = path.as_os_str().as_encoded_bytes();
    for slot in &CLEANUP {
        if slot.used.load(Ordering::Acquire) && slot.equals(want) {
            slot.set(b"");
            slot.used.store(false, Ordering::Release);
        }
    }
}

/// Removes the registered temporary files and folders (a process ending
/// on a signal before its run could clean up).
pub fn remove_registered_temporaries() {
    let mut buf = [0u8; LEN];
    for slot in &CLEANUP {
        if slot.used.load(Ordering::Acquire) {
            let n = slot.copy(&mut buf);
            if n > 0 {
                use std::os::unix::ffi::OsStrExt as _;
                let path = std::path::Path::new(std::ffi::OsStr::from_bytes(&buf[..n]));
                // A folder of an output's parts, or a file.
                let _ = if path.is_dir() { std::fs::remove_dir_all(path) } else { std::fs::remove_file(path) };
            }
        }
    }
}

extern "C" fn on_sigbus(_: libc::c_int, info: *mut libc::siginfo_t, _: *mut libc::c_void) {
    // SAFETY: the kernel passes a valid siginfo_t to an SA_SIGINFO handler;
    // a SIGBUS's names the faulting address.
    let addr = unsafe { info.as_ref().map_or(0, |i| i.si_addr() as usize) };
    if addr != 0 && survive(addr) {
        return;
    }
    let write = |s: &[u8]| {
        // SAFETY: write(2) is async-signal-safe; the buffer is valid.
        unsafe { libc::write(2, s.as_ptr().cast(), s.len()) };
    };
    let mut buf = [0u8; LEN];
    write(b"gcm-ortho: error: ");
    let n = MAPPED.copy(&mut buf);
    if n > 0 {
        write(&buf[..n]);
    }
    let m = ALSO.copy(&mut buf);
    if m > 0 {
        write(if n > 0 { b" or " } else { b"" });
        write(&buf[..m]);
    }
    if n + m > 0 {
        write(b": ");
    }
    write(b"an input file was truncated while being read (SIGBUS on its memory map)\n");
    for slot in &CLEANUP {
        if slot.used.load(Ordering::Acquire) && slot.copy(&mut buf) > 0 {
            // SAFETY: unlink(2) is async-signal-safe; `buf` is NUL-terminated.
            unsafe { libc::unlink(buf.as_ptr().cast()) };
        }
    }
    // SAFETY: _exit(2) is async-signal-safe and never returns.
    unsafe { libc::_exit(1) };
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write as _;

    /// A file truncated under its mapping: the read past the new end gives
    /// zeros instead of ending the process, and the mapping says so.
    #[test]
    fn a_fault_in_a_watched_mapping_reads_zeros_and_is_marked() {
        install_sigbus_handler();
        let dir = tempfile::tempdir().expect("a folder");
        let path = dir.path().join("scan.raw");
        std::fs::File::create(&path).and_then(|mut f| f.write_all(&[0xAB; 65536])).expect("written");
        let file = std::fs::File::open(&path).expect("opened");
        // SAFETY: a read-only mapping of a file of this test's; its
        // truncation below is what the guard is for.
        let map = unsafe { memmap2::Mmap::map(&file) }.expect("mapped");
        let guard = watch_range(&map).expect("a slot");
        assert_eq!(map[40000], 0xAB);
        assert!(!guard.truncated());
        std::fs::OpenOptions::new().write(true).open(&path).and_then(|f| f.set_len(4096)).expect("truncated");
        // Dropped from the page cache with the file's end: this read faults.
        assert_eq!(std::hint::black_box(&map[..])[50000], 0);
        assert!(guard.truncated());
        assert_eq!(map[100], 0xAB, "the pages before the fault stay");
        drop(guard);
        assert!(WATCHED.iter().all(|r| !r.used.load(Ordering::Acquire) || r.start.load(Ordering::Acquire) != map.as_ptr() as usize));
    }
}
