//! Decoded chunks kept for the next look, least recently used first out,
//! bounded in bytes: the compressed scan's strips or tiles, and a large
//! DEM's.

use std::collections::HashMap;
use std::sync::{Arc, Weak};

/// Chunks `Arc<Vec<T>>` by number, at most `budget` bytes of them with
/// those put out but still looked at and the spares (and always the
/// `least` most recent, however large).
pub struct ChunkCache<T> {
    map: HashMap<usize, (Arc<Vec<T>>, u64)>,
    bytes: usize,
    budget: usize,
    least: usize,
    tick: u64,
    /// Chunks put out that nothing else held, for the next to be read into
    /// ([`SPARES`] at most, within the budget).
    spares: Vec<Vec<T>>,
    /// Chunks put out while a thread still looked at them: alive until it
    /// lets go, so counted against the budget (a DEM's strips as wide as
    /// the DEM, one a thread, passed a panoramic strip's plan by megabytes).
    out: Vec<Weak<Vec<T>>>,
}

/// Evicted chunks kept to be read into again: each miss puts one out as
/// it puts one in.
const SPARES: usize = 2;

impl<T> ChunkCache<T> {
    pub fn new(budget: usize) -> ChunkCache<T> {
        ChunkCache { map: HashMap::new(), bytes: 0, budget, least: 1, tick: 0, spares: Vec::new(), out: Vec::new() }
    }

    /// Keeps at least the `least` most recent chunks whatever the budget
    /// (a DEM's bilinear look needs up to four at once).
    #[must_use]
    pub fn keeping(mut self, least: usize) -> ChunkCache<T> {
        self.least = least.max(1);
        self
    }

    /// An evicted chunk's room to read the next into (its contents are
    /// stale), or an empty vector.
    pub fn spare(&mut self) -> Vec<T> {
        self.spares.pop().unwrap_or_default()
    }

    /// The most it holds, bytes.
    pub fn budget(&self) -> usize {
        self.budget
    }

    pub fn get(&mut self, k: usize) -> Option<Arc<Vec<T>>> {
        self.tick += 1;
        let t = self.tick;
        self.map.get_mut(&k).map(|e| {
            e.1 = t;
            e.0.clone()
        })
    }

    pub fn put(&mut self, k: usize, v: Arc<Vec<T>>) {
        self.tick += 1;
        self.bytes += std::mem::size_of_val(v.as_slice());
        if let Some(old) = self.map.insert(k, (v, self.tick)) {
            self.bytes -= std::mem::size_of_val(old.0.as_slice());
        }
        self.out.retain(|w| w.strong_count() > 0);
        let mut out: usize = self.out.iter().filter_map(Weak::upgrade).map(|v| std::mem::size_of_val(v.as_slice())).sum();
        let mut spare: usize = self.spares.iter().map(|v| v.capacity() * std::mem::size_of::<T>()).sum();
        while self.bytes + out + spare > self.budget && self.map.len() > self.least {
            let (&oldest, _) = self.map.iter().min_by_key(|(_, e)| e.1).expect("non-empty");
            let (v, _) = self.map.remove(&oldest).expect("present");
            let size = std::mem::size_of_val(v.as_slice());
            self.bytes -= size;
            match Arc::try_unwrap(v) {
                Ok(v) => {
                    let room = v.capacity() * std::mem::size_of::<T>();
                    if self.spares.len() < SPARES && self.bytes + out + spare + room <= self.budget {
                        spare += room;
                        self.spares.push(v);
                    }
                }
                // Still looked at by a thread: it goes when that thread lets go.
                Err(v) => {
                    out += size;
                    self.out.push(Arc::downgrade(&v));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_least_recently_used_go_first_within_the_budget() {
        // Three chunks of 4 f32 (16 bytes) fit 48 bytes.
        let mut c = ChunkCache::<f32>::new(48);
        for k in 0..3 {
            c.put(k, Arc::new(vec![k as f32; 4]));
        }
        assert!(c.get(0).is_some(), "0 is now the most recent");
        c.put(3, Arc::new(vec![3.0; 4]));
        assert!(c.get(1).is_none(), "1 was the least recently used");
        assert_eq!(c.get(0).as_deref(), Some(&vec![0.0; 4]));
        assert!(c.get(2).is_some() && c.get(3).is_some());
        // A chunk larger than the budget stays, alone.
        c.put(9, Arc::new(vec![9.0; 100]));
        assert!(c.get(9).is_some() && c.get(0).is_none() && c.get(3).is_none());
    }

    #[test]
    fn chunks_put_out_but_still_looked_at_count_against_the_budget() {
        // Three chunks of 16 bytes fit 48; a thread still holds chunk 0.
        let mut c = ChunkCache::<f32>::new(48).keeping(2);
        let held = {
            c.put(0, Arc::new(vec![0.0; 4]));
            c.get(0).unwrap()
        };
        for k in 1..=3 {
            c.put(k, Arc::new(vec![k as f32; 4]));
        }
        // 0 went out but lives: the cache keeps two, not three.
        assert!(c.get(0).is_none() && c.get(1).is_none());
        assert!(c.get(2).is_some() && c.get(3).is_some());
        drop(held);
        c.put(4, Arc::new(vec![4.0; 4]));
        assert!(c.get(2).is_some() && c.get(3).is_some() && c.get(4).is_some(), "let go of, it no longer counts");
        // However small the budget, the least stay.
        let mut c = ChunkCache::<f32>::new(0).keeping(2);
        for k in 0..3 {
            c.put(k, Arc::new(vec![0.0; 4]));
        }
        assert!(c.get(1).is_some() && c.get(2).is_some() && c.get(0).is_none());
    }
}
