//! The uncompressed backend's mapped rows: read in place, asked for ahead,
//! and given back to the kernel once used.

use super::{Backend, SourceImage};
use crate::error::Result;

impl SourceImage {
    /// Rows `[y0, y0+h)`, columns `[x0, x0+w)` in place in the mapped file,
    /// without copying: the bytes from the window's first pixel to its last,
    /// and the stride of a row in bytes. Only for uncompressed, chunky,
    /// striped files whose strips lie back to back (as most writers lay them
    /// out) and whose samples are aligned in the file; `None` otherwise (read
    /// a copy with `read_window`). Give the rows back with `release_rows`.
    pub fn mapped_rows(&self, x0: u32, y0: u32, w: u32, h: u32) -> Result<Option<(&[u8], usize)>> {
        let info = &self.info;
        let Backend::Raw { map: Some(m), .. } = &self.backend else { return Ok(None) };
        if info.planar || info.tiled || w == 0 || h == 0 || x0 + w > info.width || y0 + h > info.height {
            return Ok(None);
        }
        self.check_size()?;
        let pb = info.pixel_bytes();
        let row_bytes = info.width as usize * pb;
        let rps = info.chunk.1 as usize;
        let (k0, k1) = (y0 as usize / rps, (y0 + h - 1) as usize / rps);
        let first = info.offsets[k0] as usize;
        if (k0..=k1).any(|k| info.offsets[k] as usize != first + (k - k0) * rps * row_bytes) {
            return Ok(None);
        }
        let start = first + (y0 as usize - k0 * rps) * row_bytes + x0 as usize * pb;
        let end = start + (h as usize - 1) * row_bytes + w as usize * pb;
        if end > m.len() || !start.is_multiple_of(info.sample.bytes()) {
            return Ok(None);
        }
        Ok(Some((&m[start..end], row_bytes)))
    }

    /// The mapping and the whole pages that hold rows `[y0, y0+h)` of a
    /// striped, chunky uncompressed scan (from the first row's strip to the
    /// last one's: the strips between, where they lie back to back).
    pub(super) fn row_pages(&self, y0: u32, h: u32) -> Option<(&memmap2::Mmap, usize, usize)> {
        let Backend::Raw { map: Some(m), .. } = &self.backend else { return None };
        let info = &self.info;
        if info.planar || info.tiled || h == 0 || y0 as u64 + h as u64 > info.height as u64 {
            return None;
        }
        let row_bytes = info.width as u64 * info.pixel_bytes() as u64;
        let rps = info.chunk.1 as u64;
        let (k0, k1) = ((y0 as u64 / rps) as usize, ((y0 + h - 1) as u64 / rps) as usize);
        let start = info.offsets[k0] + (y0 as u64 - k0 as u64 * rps) * row_bytes;
        let end = info.offsets[k1] + ((y0 + h) as u64 - k1 as u64 * rps) * row_bytes;
        let page = 4096;
        let (s, e) = ((start / page * page) as usize, (end.div_ceil(page) * page).min(m.len() as u64) as usize);
        (e > s).then_some((m, s, e))
    }

    /// Asks the kernel to start reading rows `[y0, y0+h)` from disk now
    /// (`MADV_WILLNEED`: one large read ahead of the faults that would
    /// each wait for a small one); nothing where they are in memory.
    pub fn will_need_rows(&self, y0: u32, h: u32) {
        if let Some((m, s, e)) = self.row_pages(y0, h) {
            let _ = m.advise_range(memmap2::Advice::WillNeed, s, e - s);
        }
    }

    /// Gives the mapped pages of rows `[y0, y0+h)` back to the kernel (after
    /// `mapped_rows`); a later read of them faults the same bytes in again.
    pub fn release_rows(&self, y0: u32, h: u32) {
        if let Some((m, s, e)) = self.row_pages(y0, h) {
            // SAFETY: the range lies inside the mapping (`row_pages` clamps
            // it). The mapping is read-only and nothing ever writes the file
            // through it, so MADV_DONTNEED only drops our page-table entries: slices
            // still alive into these pages (another window of the same rows)
            // read the same bytes again, faulted in from the file.
            let _ = unsafe { m.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, s, e - s) };
        }
    }

    /// Gives the mapped pages of chunk row `cy` (columns cx0..=cx1) back.
    pub(super) fn release(&self, cy: u32, cx0: u32, cx1: u32) {
        let Backend::Raw { map: Some(m), .. } = &self.backend else { return };
        let info = &self.info;
        let planes = if info.planar { info.bands } else { 1 };
        for plane in 0..planes {
            let base = plane * info.chunks_per_plane() + cy * info.chunks_across();
            let (a, b) = ((base + cx0) as usize, (base + cx1) as usize);
            let start = info.offsets[a..=b].iter().min().copied().unwrap_or(0) as usize;
            let end = info.offsets[a..=b].iter().zip(&info.byte_counts[a..=b]).map(|(o, n)| o + n).max().unwrap_or(0) as usize;
            let page = 4096;
            let s = start / page * page;
            let e = end.div_ceil(page) * page;
            let e = e.min(m.len());
            if e > s {
                // SAFETY: the range lies inside the mapping (clamped above)
                // and no slice into it is alive: `copy_chunk` has finished
                // copying this chunk row. MADV_DONTNEED on a read-only file
                // mapping only drops our page-table entries; a later access
                // refaults the same bytes from the file.
                let _ = unsafe { m.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, s, e - s) };
            }
        }
    }
}
