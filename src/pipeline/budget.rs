//! The memory plan of a run, all in one place (as GDAL's warper keeps its
//! cost model in `CollectChunkListInternal`). The budget (`--memory`,
//! 128 MiB by default) is cut into 24 shares:
//!
//! * four scan windows in flight (being read, queued, two being
//!   resampled), a share each; read in place from the mapped scan instead,
//!   they hold no buffer, and the mapped rows may take up to eight shares
//!   (the windows' four and four of the slack below);
//! * four output chunks (two being made, queued, being encoded; three being
//!   made in bands of tile columns, whose windows are read in place) and
//!   the encoded tiles in hand and queued, a share each;
//! * the DEM, three shares (an eighth): larger DEMs are read a chunk at a
//!   time through a cache of that size;
//! * the decoded chunks of a compressed scan, two shares (a twelfth);
//! * the GCM's node rows of the bands in flight, up to three shares (an
//!   eighth); a spacing the user gives, or the default's DEM-aligned one,
//!   may take three more from the slack below ([`MemoryBudget::node_limit`]):
//!   beyond, the default grows to 16 px and a given one is refused; the
//!   bands in flight, node rows and refined cells, are held to five shares
//!   by their bytes ([`MemoryBudget::bands_in_flight`]);
//! * what is left (~45 %) covers the GCM rows, the threads, the program and
//!   the allocator's per-thread arenas (20–30 MB on 1 GiB scans), so that
//!   the peak resident size stays under the budget.
//!
//! The sequential runner (one thread) holds one window and one chunk at a
//! time, well inside the same plan.

/// The budget and its named shares, in bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryBudget {
    total: u64,
}

impl MemoryBudget {
    pub fn new(total: u64) -> MemoryBudget {
        MemoryBudget { total }
    }

    /// The whole budget, bytes.
    pub fn total(&self) -> u64 {
        self.total
    }

    /// One 24th: a scan window, an output chunk, the queued tiles.
    pub fn share(&self) -> u64 {
        self.total / 24
    }

    /// The cache of decoded chunks of a compressed (or JPEG) scan.
    pub fn scan_cache(&self) -> u64 {
        self.total / 12
    }

    /// A DEM up to this is read whole; a larger one through a cache this big.
    pub fn dem(&self) -> u64 {
        self.total / 8
    }

    /// The most the node rows of a spacing the user chose may hold: their
    /// share and three more of the slack (a quarter of the budget); past
    /// it, the peak passes the budget.
    pub fn node_limit(&self) -> u64 {
        6 * self.share()
    }

    /// Bytes of node rows of the four bands in flight at node spacing `k`,
    /// bands `tile` rows high, rows of up to `width` pixels, at
    /// `bytes_per_node` (heights, corrections and the image's movement with
    /// height, the refinement's curvatures: 50–60 measured, 100 at the most).
    pub fn node_rows(&self, k: u32, tile: u32, width: u32, bytes_per_node: u64) -> u64 {
        let rows = (tile / k.max(1) + 4) as u64;
        let across = (width / k.max(1) + 3) as u64;
        4 * rows * across * bytes_per_node
    }

    /// The bands the GCM stage has made and the later stages still hold,
    /// node rows and refined cells, are kept under this (the sixth share
    /// of [`MemoryBudget::node_limit`] for the node heights handed on and
    /// the rows two bands share): refined cells come on top of the node
    /// rows, and a 1 GB panoramic strip's bands in flight held 50 MB.
    pub fn bands_in_flight(&self) -> u64 {
        5 * self.share()
    }

    /// Scan pixels of `pixel_bytes` a chunk's window may hold.
    pub fn window_pixels(&self, pixel_bytes: usize) -> u64 {
        self.share() / pixel_bytes.max(1) as u64
    }

    /// Output tiles of `tile_bytes` a chunk may hold (at least one).
    pub fn chunk_tiles(&self, tile_bytes: usize) -> u32 {
        (self.share() / tile_bytes as u64).max(1) as u32
    }

    /// A chunk whose scan rows span at most this is read in place, with no
    /// copy (a quarter of the budget): the rows of the chunks being
    /// resampled are then all that is resident of the scan.
    pub fn in_place_rows(&self) -> u64 {
        6 * self.share()
    }

    /// The mapped scan rows of the chunks in flight together stay under
    /// this; and a band's rows are asked for ahead only up to it.
    pub fn mapped_rows(&self) -> u64 {
        8 * self.share()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_budget_in_its_shares() {
        let b = MemoryBudget::new(128 << 20);
        assert_eq!(b.share(), 5_592_405);
        assert_eq!(b.scan_cache(), 11_184_810);
        assert_eq!(b.dem(), 16 << 20);
        assert_eq!(b.window_pixels(3), 1_864_135);
        // 256×256 RGB tiles: 28 a chunk; a tile larger than a share: one.
        assert_eq!(b.chunk_tiles(256 * 256 * 3), 28);
        assert_eq!(b.chunk_tiles(8 << 20), 1);
        assert_eq!((b.in_place_rows(), b.mapped_rows()), (6 * 5_592_405, 8 * 5_592_405));
        assert_eq!((b.node_limit(), b.bands_in_flight()), (6 * 5_592_405, 5 * 5_592_405));
        // A 6743-px-wide output in 256-px bands at spacing 4: 4 bands of
        // 68 rows of 1688 nodes.
        assert_eq!(b.node_rows(4, 256, 6743, 60), 4 * 68 * 1688 * 60);
    }
}
