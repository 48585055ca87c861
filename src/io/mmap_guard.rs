//! The memory map's last line of defence. Sizes are checked before mapping
//! and before every window, but another process may still truncate a scan
//! while a page is being copied; the kernel then raises SIGBUS. This guard
//! turns that into what every other failure looks like: one line naming the
//! file, no half-written output (the temporary files registered here are
//! removed), exit code 1.

use std::ffi::CString;
use std::path::Path;
use std::sync::atomic::{AtomicPtr, Ordering};
use std::sync::Once;

const SLOTS: usize = 8;
static MAPPED: AtomicPtr<libc::c_char> = AtomicPtr::new(std::ptr::null_mut());
static CLEANUP: [AtomicPtr<libc::c_char>; SLOTS] = [const { AtomicPtr::new(std::ptr::null_mut()) }; SLOTS];
static INSTALL: Once = Once::new();

fn leak(p: &Path) -> *mut libc::c_char {
    CString::new(p.as_os_str().as_encoded_bytes()).map(CString::into_raw).unwrap_or(std::ptr::null_mut())
}

/// Remembers the file being mapped (for the message) and installs the handler.
pub fn watch_mapped(path: &Path) {
    MAPPED.store(leak(path), Ordering::SeqCst);
    INSTALL.call_once(|| {
        // SAFETY: `on_sigbus` only calls async-signal-safe functions (write,
        // unlink, _exit) on data that is never freed (leaked CStrings).
        unsafe {
            let mut sa: libc::sigaction = std::mem::zeroed();
            sa.sa_sigaction = on_sigbus as *const () as usize;
            libc::sigemptyset(&mut sa.sa_mask);
            libc::sigaction(libc::SIGBUS, &sa, std::ptr::null_mut());
        }
    });
}

/// A temporary file to remove if the process dies of SIGBUS.
pub fn register_cleanup(path: &Path) {
    let p = leak(path);
    for slot in &CLEANUP {
        if slot.compare_exchange(std::ptr::null_mut(), p, Ordering::SeqCst, Ordering::SeqCst).is_ok() {
            return;
        }
    }
}

/// The temporary file is gone (published or removed): forget it.
pub fn unregister_cleanup(path: &Path) {
    let want = path.as_os_str().as_encoded_bytes();
    for slot in &CLEANUP {
        let p = slot.load(Ordering::SeqCst);
        // SAFETY: non-null slots hold leaked, NUL-terminated CStrings.
        if !p.is_null() && unsafe { std::ffi::CStr::from_ptr(p) }.to_bytes() == want {
            slot.store(std::ptr::null_mut(), Ordering::SeqCst);
        }
    }
}

extern "C" fn on_sigbus(_: libc::c_int) {
    let write = |s: &[u8]| {
        // SAFETY: write(2) is async-signal-safe; the buffer is valid.
        unsafe { libc::write(2, s.as_ptr().cast(), s.len()) };
    };
    write(b"gcm-ortho: error: ");
    let m = MAPPED.load(Ordering::SeqCst);
    if !m.is_null() {
        // SAFETY: a leaked CString; strlen is async-signal-safe.
        let n = unsafe { libc::strlen(m) };
        // SAFETY: `m` points to `n` valid bytes.
        write(unsafe { std::slice::from_raw_parts(m.cast::<u8>(), n) });
        write(b": ");
    }
    write(b"the input file was truncated while being read (SIGBUS on its memory map)\n");
    for slot in &CLEANUP {
        let p = slot.load(Ordering::SeqCst);
        if !p.is_null() {
            // SAFETY: unlink(2) is async-signal-safe; `p` is a leaked CString.
            unsafe { libc::unlink(p) };
        }
    }
    // SAFETY: _exit(2) is async-signal-safe and never returns.
    unsafe { libc::_exit(1) };
}
