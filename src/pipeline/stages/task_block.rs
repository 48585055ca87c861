//! A resampling task's block of rows, zeroed, from its thread's spare.
//!
//! Each task of a chunk made transposed writes its rows into a block of
//! some 2 MB before gathering them into tiles. Allocated afresh a task,
//! each block past glibc's 1 MiB mmap threshold (held there so that freed
//! buffers go back: the panoramic strip's peak) was a new mapping whose
//! pages faulted in one by one: 340,000 faults and a fifth of the CPU of
//! the lean run on a scan turned 90°. A thread keeps one block and zeroes
//! it again instead.

use std::cell::RefCell;

thread_local! {
    /// The block a thread's last task gave back.
    static SPARE: RefCell<Vec<u64>> = const { RefCell::new(Vec::new()) };
}

/// `len` samples of `T`, all zero; given back to the thread when dropped.
pub struct TaskBlock<T> {
    words: Vec<u64>,
    len: usize,
    kind: std::marker::PhantomData<T>,
}

impl<T: bytemuck::Pod> TaskBlock<T> {
    pub fn zeroed(len: usize) -> Self {
        let mut words = SPARE.with_borrow_mut(std::mem::take);
        let n = (len * std::mem::size_of::<T>()).div_ceil(8);
        words.clear();
        words.resize(n, 0);
        TaskBlock { words, len, kind: std::marker::PhantomData }
    }

    pub fn as_mut_slice(&mut self) -> &mut [T] {
        &mut bytemuck::cast_slice_mut(&mut self.words[..])[..self.len]
    }
}

impl<T> Drop for TaskBlock<T> {
    fn drop(&mut self) {
        let words = std::mem::take(&mut self.words);
        // (A thread between runs of other sizes keeps the larger.)
        SPARE.with_borrow_mut(|spare| {
            if words.capacity() > spare.capacity() {
                *spare = words;
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block comes back zeroed whatever its last task left in it, at
    /// the length asked, and a thread reuses its buffer.
    #[test]
    fn a_block_is_zeroed_and_reused() {
        let first = {
            let mut b = TaskBlock::<u16>::zeroed(1000);
            assert!(b.as_mut_slice().iter().all(|&v| v == 0) && b.as_mut_slice().len() == 1000);
            b.as_mut_slice().fill(7);
            b.words.as_ptr()
        };
        let mut again = TaskBlock::<u16>::zeroed(999);
        assert_eq!(again.words.as_ptr(), first, "the thread's block is taken again");
        assert!(again.as_mut_slice().iter().all(|&v| v == 0) && again.as_mut_slice().len() == 999);
        let mut floats = TaskBlock::<f32>::zeroed(3);
        assert_eq!(floats.as_mut_slice(), [0.0; 3]);
    }
}
