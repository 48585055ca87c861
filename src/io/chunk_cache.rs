//! Decoded chunks kept for the next look, least recently used first out,
//! bounded in bytes: the compressed scan's strips or tiles, and a large
//! DEM's.

use std::collections::HashMap;
use std::sync::Arc;

/// Chunks `Arc<Vec<T>>` by number, at most `budget` bytes of them (and
/// always the last one put, however large).
pub struct ChunkCache<T> {
    map: HashMap<usize, (Arc<Vec<T>>, u64)>,
    bytes: usize,
    budget: usize,
    tick: u64,
    /// Chunks put out that nothing else held, for the next to be read into
    /// ([`SPARES`] at most).
    spares: Vec<Vec<T>>,
}

/// Evicted chunks kept to be read into again: each miss puts one out as
/// it puts one in.
const SPARES: usize = 2;

impl<T> ChunkCache<T> {
    pub fn new(budget: usize) -> ChunkCache<T> {
        ChunkCache { map: HashMap::new(), bytes: 0, budget, tick: 0, spares: Vec::new() }
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
        while self.bytes > self.budget && self.map.len() > 1 {
            let (&oldest, _) = self.map.iter().min_by_key(|(_, e)| e.1).expect("non-empty");
            let (v, _) = self.map.remove(&oldest).expect("present");
            self.bytes -= std::mem::size_of_val(v.as_slice());
            // Still looked at by a thread, it goes when that thread lets go.
            if let (Ok(v), true) = (Arc::try_unwrap(v), self.spares.len() < SPARES) {
                self.spares.push(v);
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
}
