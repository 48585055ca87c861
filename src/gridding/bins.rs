//! Points binned on disk in one pass, so that any number of them is
//! gridded in bounded memory: the ground cut into square bins (a block of
//! output cells each), each bin's points written in fixed chunks to one
//! unnamed file as they arrive, and read back a bin at a time.

use crate::error::{Error, Result};
use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::Path;

/// A point as stored: x and y from the output grid's origin (so that the
/// triangulation works on small numbers), and the height. A height of NaN
/// marks a point dropped as a blunder.
pub type Stored = [f64; 3];

const STORED: u64 = std::mem::size_of::<Stored>() as u64;

/// The bins' layout on the ground (local coordinates, y up).
#[derive(Clone, Copy, Debug)]
pub struct BinGrid {
    /// Bin (0, 0)'s lower-left corner.
    pub x0: f64,
    pub y0: f64,
    pub side_x: f64,
    pub side_y: f64,
    pub cols: u32,
    pub rows: u32,
}

impl BinGrid {
    /// The bin holding `(x, y)`, if any.
    pub fn bin_of(&self, x: f64, y: f64) -> Option<(u32, u32)> {
        let c = ((x - self.x0) / self.side_x).floor();
        let r = ((y - self.y0) / self.side_y).floor();
        (c >= 0.0 && r >= 0.0 && c < self.cols as f64 && r < self.rows as f64).then_some((c as u32, r as u32))
    }
    /// Bins whose ground meets `[x0, x1] × [y0, y1]`, clipped to the grid
    /// (`None`: none).
    pub fn bins_over(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> Option<Rect> {
        let c0 = ((x0 - self.x0) / self.side_x).floor().max(0.0);
        let r0 = ((y0 - self.y0) / self.side_y).floor().max(0.0);
        let c1 = ((x1 - self.x0) / self.side_x).floor().min(self.cols as f64 - 1.0);
        let r1 = ((y1 - self.y0) / self.side_y).floor().min(self.rows as f64 - 1.0);
        (c1 >= c0 && r1 >= r0).then_some(Rect { c0: c0 as u32, r0: r0 as u32, c1: c1 as u32, r1: r1 as u32 })
    }
    /// The ground of `rect`, `[x0, y0, x1, y1]`.
    pub fn ground_of(&self, rect: Rect) -> [f64; 4] {
        [
            self.x0 + rect.c0 as f64 * self.side_x,
            self.y0 + rect.r0 as f64 * self.side_y,
            self.x0 + (rect.c1 + 1) as f64 * self.side_x,
            self.y0 + (rect.r1 + 1) as f64 * self.side_y,
        ]
    }
}

/// Bins `[c0, c1] × [r0, r1]`, inclusive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    pub c0: u32,
    pub r0: u32,
    pub c1: u32,
    pub r1: u32,
}

impl Rect {
    pub fn bins(&self) -> u64 {
        (self.c1 - self.c0 + 1) as u64 * (self.r1 - self.r0 + 1) as u64
    }
}

/// The binned points.
pub struct Bins {
    pub grid: BinGrid,
    file: File,
    chunk: usize,
    /// Each bin's chunks: the index of their first point in the file, and
    /// how many they hold.
    chunks: Vec<Vec<(u64, u32)>>,
    counts: Vec<u64>,
    pending: Vec<Vec<Stored>>,
    /// Points pending in all bins, and the most that may be: past it every
    /// bin's are written (memory stays bounded however many bins there are).
    held: usize,
    max_held: usize,
    next: u64,
}

impl Bins {
    /// Empty bins of `grid`, their file in `dir`, each bin's points
    /// gathered `chunk` at a time before they are written, `max_held` at
    /// most in all.
    /// What a bin costs held, points apart: its chunks' list, count and pending list.
    pub const BYTES_A_BIN: u64 = (2 * std::mem::size_of::<Vec<Stored>>() + std::mem::size_of::<u64>()) as u64;

    pub fn new(grid: BinGrid, dir: &Path, chunk: usize, max_held: usize) -> Result<Bins> {
        let file = tempfile::tempfile_in(dir).map_err(|e| Error::io(dir, crate::io::publish::without_path(&e)))?;
        let n = grid.cols as usize * grid.rows as usize;
        Ok(Bins {
            grid,
            file,
            chunk: chunk.max(1),
            chunks: vec![Vec::new(); n],
            counts: vec![0; n],
            pending: (0..n).map(|_| Vec::new()).collect(),
            held: 0,
            max_held: max_held.max(chunk),
            next: 0,
        })
    }

    fn index(&self, c: u32, r: u32) -> usize {
        r as usize * self.grid.cols as usize + c as usize
    }

    /// Adds a point (local coordinates); one outside every bin is left out
    /// (returns false).
    pub fn push(&mut self, p: Stored, dir: &Path) -> Result<bool> {
        let Some((c, r)) = self.grid.bin_of(p[0], p[1]) else { return Ok(false) };
        let i = self.index(c, r);
        self.counts[i] += 1;
        let chunk = self.chunk;
        let pending = &mut self.pending[i];
        if pending.capacity() == 0 {
            pending.reserve_exact(chunk);
        }
        pending.push(p);
        self.held += 1;
        if pending.len() == chunk {
            self.spill(i, dir)?;
        }
        if self.held >= self.max_held {
            for i in 0..self.pending.len() {
                self.spill(i, dir)?;
            }
        }
        Ok(true)
    }

    fn spill(&mut self, i: usize, dir: &Path) -> Result<()> {
        if self.pending[i].is_empty() {
            return Ok(());
        }
        let pending = &mut self.pending[i];
        self.file.write_all_at(bytemuck::cast_slice(pending), self.next * STORED).map_err(|e| Error::io(dir, e))?;
        self.chunks[i].push((self.next, pending.len() as u32));
        self.next += pending.len() as u64;
        self.held -= pending.len();
        // Its room kept for the next: a bin that fills keeps filling.
        pending.clear();
        Ok(())
    }

    /// Writes what is still pending; the bins are then read only.
    pub fn finish(&mut self, dir: &Path) -> Result<()> {
        for i in 0..self.pending.len() {
            self.spill(i, dir)?;
            self.pending[i] = Vec::new();
        }
        Ok(())
    }

    pub fn count(&self, c: u32, r: u32) -> u64 {
        self.counts[self.index(c, r)]
    }

    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// Points of the bins in `rect` that `keep` takes, those dropped left
    /// out, appended to `out`.
    pub fn read(&self, rect: Rect, keep: impl Fn(&Stored) -> bool, out: &mut Vec<Stored>) -> Result<()> {
        for r in rect.r0..=rect.r1 {
            for c in rect.c0..=rect.c1 {
                self.read_bin(c, r, |p| {
                    if !p[2].is_nan() && keep(p) {
                        out.push(*p)
                    }
                })?;
            }
        }
        Ok(())
    }

    /// Each point of bin `(c, r)`, dropped ones included, in the order stored.
    pub fn read_bin(&self, c: u32, r: u32, mut each: impl FnMut(&Stored)) -> Result<()> {
        let i = self.index(c, r);
        let mut buf: Vec<Stored> = Vec::new();
        for &(at, n) in &self.chunks[i] {
            buf.resize(n as usize, [0.0; 3]);
            self.file
                .read_exact_at(bytemuck::cast_slice_mut(&mut buf), at * STORED)
                .map_err(|e| Error::Internal(format!("reading back binned points: {e}")))?;
            buf.iter().for_each(&mut each);
        }
        Ok(())
    }

    /// Marks the points of bin `(c, r)` at `positions` (their order in the
    /// bin) as dropped.
    pub fn drop_points(&self, c: u32, r: u32, positions: &[u64]) -> Result<()> {
        let i = self.index(c, r);
        // Each chunk's first position in the bin.
        let mut firsts = Vec::with_capacity(self.chunks[i].len());
        let mut k0 = 0u64;
        for &(_, n) in &self.chunks[i] {
            firsts.push(k0);
            k0 += u64::from(n);
        }
        for &k in positions {
            let c = firsts.partition_point(|&f| f <= k) - 1;
            let at = self.chunks[i][c].0 + (k - firsts[c]);
            self.file.write_all_at(&f64::NAN.to_ne_bytes(), at * STORED + 16).map_err(|e| Error::Internal(format!("marking a blunder: {e}")))?;
        }
        Ok(())
    }
}
