//! The memory map's last line of defence, installed by the binary. Sizes are checked before mapping
//! and before every window, but another process may still truncate a scan
//! while a page is being copied; the kernel then raises SIGBUS. This guard
//! turns that into what every other failure looks like: one line naming the
//! file, no half-written output (the temporary files registered here are
//! removed), exit code 1.
//!
//! Paths live in fixed static buffers of atomics: nothing is allocated (or
//! leaked) per file, and the handler reads them without locks.

use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
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

/// Remembers the file being mapped, for the message.
pub fn watch_mapped(path: &Path) {
    MAPPED.set(path.as_os_str().as_encoded_bytes());
}

/// Remembers a second mapped file (a geoid grid), named beside the first.
pub fn watch_also(path: &Path) {
    ALSO.set(path.as_os_str().as_encoded_bytes());
}

/// Installs the process-wide SIGBUS handler: a program's choice, not a
/// library's, so the binary calls it; without it SIGBUS kills the process
/// as usual (and leaves the temporary output behind).
pub fn install_sigbus_handler() {
    INSTALL.call_once(|| {
        // SAFETY: `on_sigbus` only calls async-signal-safe functions (write,
        // unlink, _exit) on static buffers.
        unsafe {
            let mut sa: libc::sigaction = std::mem::zeroed();
            sa.sa_sigaction = on_sigbus as *const () as usize;
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

extern "C" fn on_sigbus(_: libc::c_int) {
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
