//! How long work tells its caller how far it has come, and how the caller
//! stops it. The library draws nothing: the binary gives a terminal bar
//! (indicatif), a service might log, a test counts.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// A piece of work about to start.
#[derive(Clone, Copy, Debug)]
pub struct Task<'a> {
    /// What is done, e.g. `rectify`.
    pub name: &'a str,
    /// Units of work in all (tiles written, rows made).
    pub units: u64,
    /// What the units stand for to a person: `lines` output rows (or
    /// columns), named `line_name`.
    pub lines: u64,
    pub line_name: &'a str,
    /// Bytes of input the whole task reads (0: not a reading task).
    pub input_bytes: u64,
}

/// Receives the progress of long work; called from the work's threads.
pub trait Progress: Sync {
    fn start(&self, task: &Task);
    /// `units` more are done.
    fn advance(&self, units: u64);
    /// The work ended (done, failed or cancelled).
    fn finish(&self);
    /// Something doubtful was met (and how it was taken): to be shown even
    /// where progress is not. The run's report lists them too.
    fn warn(&self, _message: &str) {}
    /// The process's peak resident memory so far, MiB, for the run's
    /// report: the host's to tell, where it owns the process and the
    /// figure means something (the command line does); `None` otherwise.
    fn peak_memory_mib(&self) -> Option<f64> {
        None
    }
    /// Much of what the run held was just freed (between a mosaic's
    /// phases and strips): a host may hand free pages back to the system
    /// (the command line trims glibc's heap, which never does by itself).
    fn memory_freed(&self) {}
}

/// Only the host's side of a progress (its memory): the steps of work
/// nobody watches (a batch job's).
pub struct HostOnly<'a>(pub &'a dyn Progress);

impl Progress for HostOnly<'_> {
    fn start(&self, _: &Task) {}
    fn advance(&self, _: u64) {}
    fn finish(&self) {}
    fn peak_memory_mib(&self) -> Option<f64> {
        self.0.peak_memory_mib()
    }
    fn memory_freed(&self) {
        self.0.memory_freed();
    }
}

/// Passes progress on and keeps every warning: what a run said on its way
/// is what its report lists (a batch job's and a mosaic image's too, whose
/// progress nobody watches).
pub struct Recording<'a> {
    inner: &'a dyn Progress,
    said: std::sync::Mutex<Vec<String>>,
    /// Each distinct warning passed on once only.
    once: bool,
}

impl<'a> Recording<'a> {
    pub fn new(inner: &'a dyn Progress) -> Recording<'a> {
        Recording { inner, said: Default::default(), once: false }
    }

    /// As `new`, passing each distinct warning on once (a mosaic's images
    /// and strips meet the same camera or DEM again and again).
    pub fn once(inner: &'a dyn Progress) -> Recording<'a> {
        Recording { once: true, ..Recording::new(inner) }
    }

    /// The warnings said so far, in order.
    pub fn said(&self) -> Vec<String> {
        self.said.lock().map(|s| s.clone()).unwrap_or_default()
    }
}

impl Progress for Recording<'_> {
    fn start(&self, task: &Task) {
        self.inner.start(task);
    }
    fn advance(&self, units: u64) {
        self.inner.advance(units);
    }
    fn finish(&self) {
        self.inner.finish();
    }
    fn warn(&self, message: &str) {
        if let Ok(mut s) = self.said.lock() {
            if self.once && s.iter().any(|m| m == message) {
                return;
            }
            s.push(message.to_string());
        }
        self.inner.warn(message);
    }
    fn peak_memory_mib(&self) -> Option<f64> {
        self.inner.peak_memory_mib()
    }
    fn memory_freed(&self) {
        self.inner.memory_freed();
    }
}

/// Progress nobody watches.
pub struct NoProgress;

impl Progress for NoProgress {
    fn start(&self, _: &Task) {}
    fn advance(&self, _: u64) {}
    fn finish(&self) {}
}

/// A stop request, set from another thread (a signal handler, a service's
/// cancel call) and polled by the work between pieces of it.
#[derive(Clone, Debug, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    pub fn new() -> Cancel {
        Cancel::default()
    }
    /// The flag itself, for a signal handler to set.
    pub fn flag(&self) -> Arc<AtomicBool> {
        self.0.clone()
    }
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}
