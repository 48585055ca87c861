//! Each image's low-resolution orthophoto and where in its scan it sees
//! each cell, on its box of the plan's cells: the plan's largest part
//! (about 10 B a box cell, as much as the mosaic's cells times the images
//! that see each), kept in an unnamed temporary file once sampled and read
//! back a few rows at a time — an overlap, a seam's zone, a band of the
//! mosaic's cells, a tile — so that the plan's memory does not grow with
//! the number of images. In memory each image keeps a bit a box cell:
//! whether it sees it ([`Seen`]).

use super::plan::{Pixel, Thumbnail};
use crate::error::{Error, Result};
use std::fs::File;
use std::ops::Range;
use std::os::unix::fs::FileExt;
use std::sync::atomic::{AtomicU64, Ordering};

/// The unnamed file every image's box is appended to (by several threads
/// at once: each takes its own stretch of the file).
pub struct BoxStore {
    file: File,
    end: AtomicU64,
}

/// Where one image's box lies in the store, and its shape.
#[derive(Clone, Copy, Debug, Default)]
pub struct Stored {
    at: u64,
    /// The box, cells: `[x0, y0, x1, y1)`.
    cells: [usize; 4],
    bands: usize,
    /// How its values are kept: 16-bit levels (and a level's unit's
    /// count), f32, or none (a plan read back needs only the distances).
    values: Kept,
}

#[derive(Clone, Copy, Debug, Default)]
enum Kept {
    #[default]
    None,
    Levels(f32),
    Floats,
}

impl Kept {
    fn bytes(self) -> usize {
        match self {
            Kept::None => 0,
            Kept::Levels(_) => 2,
            Kept::Floats => 4,
        }
    }
}

/// An image's box, or some rows of it, in memory.
pub struct BoxCells {
    /// `[x0, y0, x1, y1)`: the box's columns, these rows.
    cells: [usize; 4],
    bands: usize,
    /// Distance from the scan's centre over its half-diagonal (NaN: not seen).
    radius: Vec<f32>,
    /// Band after band inside each cell; empty where not read.
    values: Thumbnail,
}

impl BoxCells {
    #[inline]
    fn at(&self, x: usize, y: usize) -> Option<usize> {
        let [x0, y0, x1, y1] = self.cells;
        (x >= x0 && x < x1 && y >= y0 && y < y1).then(|| (y - y0) * (x1 - x0) + (x - x0))
    }

    /// Where in the scan it sees cell (x, y) (see `radius`), if it does and
    /// the cell is among these rows.
    #[inline]
    pub fn radius(&self, x: usize, y: usize) -> Option<f32> {
        self.radius.get(self.at(x, y)?).copied().filter(|r| r.is_finite())
    }

    /// Its low-resolution pixel at cell (x, y), where it sees it (and its
    /// values were read).
    #[inline]
    pub fn value(&self, x: usize, y: usize) -> Option<Pixel<'_>> {
        let k = self.at(x, y)?;
        if !self.radius.get(k)?.is_finite() {
            return None;
        }
        let nb = self.bands;
        match &self.values {
            Thumbnail::Levels { v, per_unit } => Some(Pixel::Levels(v.get(k * nb..(k + 1) * nb)?, 1.0 / per_unit)),
            Thumbnail::Floats(v) => Some(Pixel::Floats(v.get(k * nb..(k + 1) * nb)?)),
        }
    }

    /// The distances row by row, the box's width a row.
    pub fn radius_rows(&self) -> std::slice::ChunksExact<'_, f32> {
        self.radius.chunks_exact((self.cells[2] - self.cells[0]).max(1))
    }
}

/// Which cells of its box an image sees, a bit each.
#[derive(Clone, Debug, Default)]
pub struct Seen {
    cells: [usize; 4],
    bits: Vec<u64>,
}

impl Seen {
    fn of(cells: [usize; 4], radius: &[f32]) -> Seen {
        let mut bits = vec![0u64; radius.len().div_ceil(64)];
        for (k, r) in radius.iter().enumerate() {
            if r.is_finite() {
                bits[k / 64] |= 1 << (k % 64);
            }
        }
        Seen { cells, bits }
    }

    #[inline]
    pub fn sees(&self, x: usize, y: usize) -> bool {
        let [x0, y0, x1, y1] = self.cells;
        if !(x >= x0 && x < x1 && y >= y0 && y < y1) {
            return false;
        }
        let k = (y - y0) * (x1 - x0) + (x - x0);
        self.bits.get(k / 64).is_some_and(|b| b >> (k % 64) & 1 == 1)
    }

    #[cfg(any(test, feature = "internals"))]
    /// Cells it sees.
    pub fn count(&self) -> usize {
        self.bits.iter().map(|b| b.count_ones() as usize).sum()
    }

    pub fn bytes(&self) -> u64 {
        self.bits.len() as u64 * 8
    }
}

impl BoxStore {
    pub fn new() -> Result<BoxStore> {
        let file = tempfile::tempfile().map_err(io_error)?;
        Ok(BoxStore { file, end: AtomicU64::new(0) })
    }

    /// Keeps a box of `cells`, `bands` values a cell: its distances row by
    /// row (the box's width a row), its values (none, or band after band
    /// inside each cell). Returns where, and which cells it sees.
    pub fn put(&self, cells: [usize; 4], bands: usize, radius: &[f32], values: &Thumbnail) -> Result<(Stored, Seen)> {
        let (values, kept): (&[u8], Kept) = match values {
            Thumbnail::Levels { v, per_unit } if !v.is_empty() => (bytemuck::cast_slice(v), Kept::Levels(*per_unit)),
            Thumbnail::Floats(v) if !v.is_empty() => (bytemuck::cast_slice(v), Kept::Floats),
            _ => (&[], Kept::None),
        };
        let radius_bytes: &[u8] = bytemuck::cast_slice(radius);
        let at = self.end.fetch_add((radius_bytes.len() + values.len()) as u64, Ordering::Relaxed);
        self.file.write_all_at(radius_bytes, at).map_err(io_error)?;
        self.file.write_all_at(values, at + radius_bytes.len() as u64).map_err(io_error)?;
        Ok((Stored { at, cells, bands, values: kept }, Seen::of(cells, radius)))
    }

    /// Rows `rows` of a stored box (clipped to it), whole, with the values
    /// where `values` asks and the box has them.
    pub fn rows(&self, s: &Stored, rows: Range<usize>, values: bool) -> Result<BoxCells> {
        let [x0, y0, x1, y1] = s.cells;
        let (r0, r1) = (rows.start.clamp(y0, y1), rows.end.clamp(y0, y1).max(rows.start.clamp(y0, y1)));
        let (w, h, n) = (x1 - x0, y1 - y0, (x1 - x0) * (r1 - r0));
        let mut radius = vec![0f32; n];
        self.file.read_exact_at(bytemuck::cast_slice_mut(&mut radius), s.at + ((r0 - y0) * w * 4) as u64).map_err(io_error)?;
        let values_at = s.at + (w * h * 4) as u64 + ((r0 - y0) * w * s.bands * s.values.bytes()) as u64;
        let values = match (values, s.values) {
            (true, Kept::Levels(per_unit)) => {
                let mut v = vec![0u16; n * s.bands];
                self.file.read_exact_at(bytemuck::cast_slice_mut(&mut v), values_at).map_err(io_error)?;
                Thumbnail::Levels { v, per_unit }
            }
            (true, Kept::Floats) => {
                let mut v = vec![0f32; n * s.bands];
                self.file.read_exact_at(bytemuck::cast_slice_mut(&mut v), values_at).map_err(io_error)?;
                Thumbnail::Floats(v)
            }
            _ => Thumbnail::default(),
        };
        Ok(BoxCells { cells: [x0, r0, x1, r1], bands: s.bands, radius, values })
    }
}

fn io_error(source: std::io::Error) -> Error {
    let mut path = std::env::temp_dir();
    path.push("(the mosaic plan's unnamed temporary file)");
    Error::Io { path, source }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Boxes put by several threads come back row for row as they went
    /// in, distances and values; the bits say what is seen.
    #[test]
    fn boxes_come_back_as_they_were_put() {
        let store = BoxStore::new().unwrap();
        let boxes: Vec<([usize; 4], Vec<f32>, Thumbnail)> = (0..6)
            .map(|k| {
                let cells = [k, 2 * k, k + 7 + k % 3, 2 * k + 5 + k];
                let n = (cells[2] - cells[0]) * (cells[3] - cells[1]);
                let radius: Vec<f32> = (0..n).map(|i| if (i + k) % 5 == 0 { f32::NAN } else { (i * 3 + k) as f32 / 100.0 }).collect();
                let values = match k % 3 {
                    0 => Thumbnail::Levels { v: (0..2 * n).map(|i| (i * 37 + k) as u16).collect(), per_unit: 256.0 },
                    1 => Thumbnail::Floats((0..2 * n).map(|i| i as f32 * 0.5 - k as f32).collect()),
                    _ => Thumbnail::default(),
                };
                (cells, radius, values)
            })
            .collect();
        let stored: Vec<(Stored, Seen)> = std::thread::scope(|s| {
            let handles: Vec<_> = boxes.iter().map(|(c, r, v)| s.spawn(|| store.put(*c, 2, r, v).unwrap())).collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        for ((cells, radius, values), (at, seen)) in boxes.iter().zip(&stored) {
            let [x0, y0, x1, y1] = *cells;
            let whole = BoxCells { cells: *cells, bands: 2, radius: radius.clone(), values: values.clone() };
            for rows in [y0..y1, y0 + 1..y1 - 1, 0..y0 + 2, y1 - 1..y1 + 9] {
                let got = store.rows(at, rows.clone(), true).unwrap();
                for y in 0..y1 + 2 {
                    for x in 0..x1 + 2 {
                        let inside = rows.contains(&y);
                        let want = whole.radius(x, y).filter(|_| inside);
                        assert_eq!(got.radius(x, y), want, "box {cells:?} rows {rows:?} cell ({x}, {y})");
                        let bands = |p: Option<Pixel>| p.map(|p| p.bands().collect::<Vec<_>>());
                        assert_eq!(bands(got.value(x, y)), bands(whole.value(x, y)).filter(|_| inside));
                        assert_eq!(seen.sees(x, y), whole.radius(x, y).is_some());
                    }
                }
            }
            let none = store.rows(at, y0..y1, false).unwrap();
            assert!(none.value(x0, y0 + 1).is_none() && none.radius_rows().count() == y1 - y0);
        }
    }
}
