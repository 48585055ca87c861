//! Which images may make a band now: only those of the mosaic band being
//! composed and of the next (the composer holds the one, the images make
//! the other), a few at a time, the earlier band (then the leftmost image)
//! first. So the images' bands in hand and the scan windows in use grow
//! with the width of a band of the mosaic, not with how many images it
//! crosses, and two cores are not shared among a dozen renders.

use std::collections::BTreeSet;
use std::sync::{Condvar, Mutex, MutexGuard};

/// A render waiting for its turn: (mosaic band, first tile column, image).
pub type TurnKey = (u32, u32, usize);

pub struct Turns {
    state: Mutex<State>,
    changed: Condvar,
    at_once: usize,
}

#[derive(Default)]
struct State {
    /// Bands up to this one may be made (none before the first is opened).
    open: Option<u32>,
    running: usize,
    waiting: BTreeSet<TurnKey>,
    closed: bool,
}

/// A band being made; the turn passes on when it is dropped.
pub struct Turn<'a> {
    turns: &'a Turns,
}

impl Drop for Turn<'_> {
    fn drop(&mut self) {
        self.turns.lock().running -= 1;
        self.turns.changed.notify_all();
    }
}

impl Turns {
    /// Turns for `at_once` renders at a time (at least one).
    pub fn new(at_once: usize) -> Turns {
        Turns { state: Mutex::default(), changed: Condvar::new(), at_once: at_once.max(1) }
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // A render that panicked leaves the counts as they were: still
        // good to go on with (its thread reports the failure).
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Bands up to `band` may now be made.
    pub fn open_to(&self, band: u32) {
        let mut s = self.lock();
        s.open = Some(s.open.map_or(band, |o| o.max(band)));
        drop(s);
        self.changed.notify_all();
    }

    /// No more turns: every render waiting, or to wait, gets none.
    pub fn close(&self) {
        self.lock().closed = true;
        self.changed.notify_all();
    }

    /// Waits until `key`'s band is open, a turn is free and no earlier
    /// render waits; `None` once the turns are closed.
    pub fn wait(&self, key: TurnKey) -> Option<Turn<'_>> {
        let mut s = self.lock();
        s.waiting.insert(key);
        loop {
            if s.closed {
                s.waiting.remove(&key);
                return None;
            }
            let open = s.open.is_some_and(|o| key.0 <= o);
            if open && s.running < self.at_once && s.waiting.first() == Some(&key) {
                s.waiting.remove(&key);
                s.running += 1;
                drop(s);
                // The next in line may have a turn too.
                self.changed.notify_all();
                return Some(Turn { turns: self });
            }
            s = self.changed.wait(s).unwrap_or_else(|e| e.into_inner());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;
    use std::time::Duration;

    /// Renders of bands 0–2 from four threads at once, two turns: never
    /// more than two at a time, none before its band is open.
    #[test]
    fn turns_go_band_by_band_two_at_a_time() {
        let turns = Arc::new(Turns::new(2));
        let log = Arc::new(Mutex::new(Vec::new()));
        let running = Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let most = Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let threads: Vec<_> = (0..4)
            .map(|image| {
                let (turns, log, running, most) = (turns.clone(), log.clone(), running.clone(), most.clone());
                std::thread::spawn(move || {
                    for band in 0..3 {
                        let Some(_turn) = turns.wait((band, image as u32, image)) else { return };
                        let now = running.fetch_add(1, std::sync::atomic::Ordering::SeqCst) + 1;
                        most.fetch_max(now, std::sync::atomic::Ordering::SeqCst);
                        log.lock().unwrap().push(band);
                        std::thread::sleep(Duration::from_millis(5));
                        running.fetch_sub(1, std::sync::atomic::Ordering::SeqCst);
                    }
                })
            })
            .collect();
        std::thread::sleep(Duration::from_millis(30));
        assert!(log.lock().unwrap().is_empty(), "a band was made before any was open");
        turns.open_to(0);
        std::thread::sleep(Duration::from_millis(60));
        assert_eq!(*log.lock().unwrap(), vec![0, 0, 0, 0], "only band 0 is open");
        turns.open_to(2);
        for t in threads {
            t.join().unwrap();
        }
        assert_eq!(log.lock().unwrap().len(), 12);
        assert!(most.load(std::sync::atomic::Ordering::SeqCst) <= 2, "more than two at a time");
    }

    #[test]
    fn closed_turns_release_every_waiter() {
        let turns = Arc::new(Turns::new(1));
        let waiter = {
            let turns = turns.clone();
            std::thread::spawn(move || turns.wait((5, 0, 0)).is_none())
        };
        std::thread::sleep(Duration::from_millis(20));
        turns.close();
        assert!(waiter.join().unwrap(), "a closed queue gave a turn");
    }
}
