//! The stages of a run, in the order the data goes through them:
//!
//! 1. [`dem`] — heights at the GCM nodes of the next band;
//! 2. [`gcm`] — exact `T` at the nodes (and refinement under a bound);
//! 3. [`read`] — plan the band's chunks and read their scan windows;
//! 4. [`resample`] — the chunk's output pixels, tile by tile;
//! 5. [`encode`] — the chunk's tiles compressed;
//! 6. [`write`] — tiles appended to the file as they come.
//!
//! Each stage is a function of the run's context ([`super::context::Run`])
//! and the message of the stage before; the runners decide what runs when.

pub mod dem;
pub mod encode;
pub mod gcm;
mod holes;
pub mod read;
pub mod resample;
mod resample_row;
mod task_block;
mod transpose;
pub mod write;

use std::time::{Duration, Instant};

/// Busy time of each stage (the writer's share shows as the run's wall time).
#[derive(Default)]
pub struct Busy {
    pub dem: Duration,
    pub gcm: Duration,
    pub read: Duration,
    pub resample: Duration,
    pub encode: Duration,
}

/// Runs `f`, adding its wall time to `acc`.
pub fn timed<R>(acc: &mut Duration, f: impl FnOnce() -> R) -> R {
    let t = Instant::now();
    let r = f();
    *acc += t.elapsed();
    r
}

/// The node rows of the band before, kept for the next: neighbouring bands
/// share the node rows at their edge (two of 18 a band of 256 rows at
/// k = 16, two of 23 at k = 12), which need not be worked out again.
pub struct SharedRows<T> {
    first_j: i64,
    rows: Vec<T>,
}

/// The rows a band keeps for the next: those at its lower edge (the next
/// band's first rows, with the error bound's row of margin each side).
const SHARED: usize = 4;

impl<T> Default for SharedRows<T> {
    fn default() -> Self {
        SharedRows { first_j: 0, rows: Vec::new() }
    }
}

impl<T: Clone> SharedRows<T> {
    /// Rows `j0..=j1`: those of the band before as they were, the others
    /// from `make`; and how many were the band before's.
    pub fn rows(&mut self, j0: i64, j1: i64, mut make: impl FnMut(i64) -> T) -> (Vec<T>, usize) {
        let mut reused = 0;
        let rows: Vec<T> = (j0..=j1)
            .map(|j| match usize::try_from(j - self.first_j).ok().and_then(|k| self.rows.get(k)) {
                Some(row) => {
                    reused += 1;
                    row.clone()
                }
                None => make(j),
            })
            .collect();
        // Only the last few: a whole band's copy held as much again as the
        // band (its node heights and rows) for the two or three the next
        // one shares.
        let keep = rows.len().min(SHARED);
        self.first_j = j0 + (rows.len() - keep) as i64;
        self.rows.clear();
        self.rows.extend_from_slice(&rows[rows.len() - keep..]);
        (rows, reused)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bands_take_the_rows_they_share_with_the_band_before() {
        let mut made = Vec::new();
        let mut before = SharedRows::default();
        let mut rows = |j0, j1, made: &mut Vec<i64>| {
            before.rows(j0, j1, |j| {
                made.push(j);
                j * 10
            })
        };
        assert_eq!(rows(-1, 3, &mut made), (vec![-10, 0, 10, 20, 30], 0));
        // Two rows shared at the edge.
        assert_eq!(rows(2, 6, &mut made), (vec![20, 30, 40, 50, 60], 2));
        // None shared (a jump), then one.
        assert_eq!(rows(9, 10, &mut made), (vec![90, 100], 0));
        assert_eq!(rows(10, 11, &mut made), (vec![100, 110], 1));
        assert_eq!(made, [-1, 0, 1, 2, 3, 4, 5, 6, 9, 10, 11]);
        // A long band keeps its last rows only.
        let (rows, _) = before.rows(20, 40, |j| j);
        assert_eq!((rows.len(), before.first_j, before.rows.clone()), (21, 37, vec![37, 38, 39, 40]));
        assert_eq!(before.rows(37, 45, |j| j).1, 4);
    }
}
