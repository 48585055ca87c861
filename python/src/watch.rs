//! A run on a thread of its own, watched from Python's: the GIL released
//! while it works; progress, warnings and pending signals (Ctrl-C) handled
//! on the calling thread between naps.

use gcm_ortho::{Cancel, Error};
use gcm_ortho::{Progress, Task};
use pyo3::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// What the run's threads tell the watcher.
#[derive(Default)]
struct Shared {
    done: AtomicU64,
    total: AtomicU64,
    task: Mutex<String>,
    warnings: Mutex<Vec<String>>,
}

impl Progress for Shared {
    fn start(&self, task: &Task) {
        if let Ok(mut t) = self.task.lock() {
            *t = task.name.to_string();
        }
        self.done.store(0, Ordering::Relaxed);
        self.total.store(task.units, Ordering::Relaxed);
    }
    fn advance(&self, units: u64) {
        self.done.fetch_add(units, Ordering::Relaxed);
    }
    fn finish(&self) {}
    fn warn(&self, message: &str) {
        if let Ok(mut w) = self.warnings.lock() {
            w.push(message.to_string());
        }
    }
}

impl Shared {
    /// Warnings not yet passed on, as Python warnings
    /// (`gcm_ortho.errors.GcmOrthoWarning`, shown on stderr by default).
    fn pass_warnings(&self, py: Python<'_>) -> PyResult<()> {
        let said: Vec<String> = self.warnings.lock().map(|mut w| std::mem::take(&mut *w)).unwrap_or_default();
        if said.is_empty() {
            return Ok(());
        }
        let warn = py.import("gcm_ortho.errors")?.getattr("_warn")?;
        for message in said {
            warn.call1((gcm_ortho::settings_said_as_keys(&message),))?;
        }
        Ok(())
    }

    fn report(&self, py: Python<'_>, callback: &Py<PyAny>) -> PyResult<()> {
        let task = self.task.lock().map(|t| t.clone()).unwrap_or_default();
        callback.call1(py, (self.done.load(Ordering::Relaxed), self.total.load(Ordering::Relaxed), task))?;
        Ok(())
    }
}

/// Runs `work` with the GIL released; every `interval` seconds (at least
/// every 0.1 s for signals) the calling thread passes warnings on, calls
/// `callback(done, total, task)` and checks Python's signals. A signal's
/// exception (KeyboardInterrupt on Ctrl-C), or one the callback raises,
/// cancels the run, waits for it to clean up and is raised.
pub fn watched<T: Send>(
    py: Python<'_>,
    callback: Option<Py<PyAny>>,
    interval: f64,
    work: impl FnOnce(&dyn Progress, &Cancel) -> gcm_ortho::Result<T> + Send,
) -> PyResult<T> {
    let interval = Duration::from_secs_f64(if interval.is_finite() && interval > 0.0 { interval } else { 0.5 });
    let shared = Shared::default();
    let cancel = Cancel::new();
    let finished = AtomicBool::new(false);
    std::thread::scope(|s| {
        let worker = s.spawn(|| {
            let out = work(&shared, &cancel);
            finished.store(true, Ordering::Release);
            out
        });
        let mut last_report = Instant::now();
        let stopped: Option<PyErr> = loop {
            py.detach(|| {
                let nap = Instant::now();
                while !finished.load(Ordering::Acquire) && nap.elapsed() < interval.min(Duration::from_millis(100)) {
                    std::thread::sleep(Duration::from_millis(5));
                }
            });
            let done = finished.load(Ordering::Acquire);
            let mut step = || -> PyResult<()> {
                py.check_signals()?;
                shared.pass_warnings(py)?;
                if let Some(cb) = &callback {
                    if done || last_report.elapsed() >= interval {
                        last_report = Instant::now();
                        shared.report(py, cb)?;
                    }
                }
                Ok(())
            };
            if let Err(e) = step() {
                cancel.cancel();
                break Some(e);
            }
            if done {
                break None;
            }
        };
        // The run cleans up (its temporary output removed) before Python
        // goes on.
        let result = py.detach(|| worker.join());
        let result = match result {
            Ok(r) => r,
            Err(_) => Err(Error::Internal("the run panicked".into())),
        };
        if let Some(e) = stopped {
            return Err(e);
        }
        result.map_err(|e| super::raise(py, e))
    })
}
