//! The GCM bands in flight, counted by their bytes. A band's node rows are
//! planned (`budget.rs`), but the cells refined under the error bound come
//! on top, as many as the terrain and the camera ask: on a panoramic strip
//! 100,000 px wide the bands queued, being read and being resampled held
//! 50 MB. The GCM stage makes the next band only once those still in use
//! leave it room (or none is in use).

use crate::error::{Error, Result};
use crate::pipeline::context::Stop;
use std::collections::VecDeque;
use std::sync::{Arc, Weak};
use std::time::Duration;

pub struct BandBytes<T> {
    /// Bands sent on, oldest first, with their bytes.
    sent: VecDeque<(Weak<T>, u64)>,
    limit: u64,
    /// The last band's bytes: what the next will likely take.
    last: u64,
}

impl<T> BandBytes<T> {
    pub fn new(limit: u64) -> BandBytes<T> {
        BandBytes { sent: VecDeque::new(), limit, last: 0 }
    }

    /// Waits until the bands still in use and one more like the last fit
    /// the limit, or none is in use (polled: a band is let go a few times
    /// a second at most).
    pub fn wait_for_room(&mut self, stop: &Stop) -> Result<()> {
        loop {
            self.sent.retain(|(band, _)| band.strong_count() > 0);
            let used: u64 = self.sent.iter().map(|(_, b)| b).sum();
            if self.sent.is_empty() || used + self.last <= self.limit {
                return Ok(());
            }
            if stop.now() {
                return Err(Error::Cancelled);
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// `band`, of `bytes`, goes on down the pipeline.
    pub fn send(&mut self, band: &Arc<T>, bytes: u64) {
        self.last = bytes;
        self.sent.push_back((Arc::downgrade(band), bytes));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::Cancel;
    use std::time::Instant;

    #[test]
    fn a_band_waits_for_room_until_one_in_use_is_let_go() {
        let cancel = Cancel::default();
        let stop = Stop::new(&cancel);
        let mut gate = BandBytes::new(100);
        gate.wait_for_room(&stop).unwrap();
        let (a, b) = (Arc::new(1u8), Arc::new(2u8));
        gate.send(&a, 60);
        // 60 in use and another 60 to come: over 100, so it waits until `a`
        // is dropped elsewhere.
        let held = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(50));
            drop(a);
        });
        let t = Instant::now();
        gate.wait_for_room(&stop).unwrap();
        assert!(t.elapsed() >= Duration::from_millis(40), "{:?}", t.elapsed());
        held.join().unwrap();
        // One band larger than the limit still goes when none is in use.
        gate.send(&b, 500);
        drop(b);
        gate.wait_for_room(&stop).unwrap();
        // A stop ends the wait.
        let c = Arc::new(3u8);
        gate.send(&c, 90);
        cancel.cancel();
        assert!(matches!(gate.wait_for_room(&stop), Err(Error::Cancelled)));
    }
}
