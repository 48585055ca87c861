//! What the stages of one run share, split by concern: the inputs, the grid
//! as walked, the memory budget, the counters, and the stop.

use super::budget::MemoryBudget;
use crate::dem::Dem;
use crate::error::Error;
use crate::gcm::{Gcm, GcmStats};
use crate::geom::OutputGrid;
use crate::io::source::SourceImage;
use crate::io::tiff_out::OutputSpec;
use crate::progress::{Cancel, Progress};
use crate::resample::Kernel;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Mutex;

/// What the per-pixel code needs to know of the options.
#[derive(Clone, Copy, Debug)]
pub struct PixelOptions {
    pub kernel: Kernel,
    /// Output tile side, pixels.
    pub tile: u32,
    /// Written where there is no image (0 under an alpha band).
    pub fill: f64,
    /// Bands written: the scan's, and the alpha band.
    pub bands_out: u32,
    /// The part of the scan that holds the image, where less than all of it
    /// (a film's format): outside it, no value.
    pub area: Option<crate::geom::ImageArea>,
    /// Say which pixels have a value, for the output's internal mask.
    pub mask: bool,
    /// What becomes of pixels the sensor does not see (with `visibility`).
    pub occlusion: crate::options::Occlusion,
    /// Under an area kernel: how far, scan pixels, an output pixel's
    /// footprint reaches from its centre (0 for the point kernels).
    pub footprint: u32,
    /// How the scan marks pixels without image, if it does.
    pub holes: Option<crate::io::source::HoleMark>,
    /// A nodata value the image's own samples can take (`--nodata V`): a
    /// sample of a pixel with a value that holds it is moved to the next
    /// value, as GDAL's warper does, so that it does not read as a hole.
    pub nudge: bool,
}

/// The run's inputs, ready.
pub struct Inputs<'a> {
    pub gcm: &'a Gcm<'a>,
    pub src: &'a SourceImage,
    pub dem: &'a Dem,
    pub spec: &'a OutputSpec,
    pub pixels: PixelOptions,
    /// The output's final name (for messages).
    pub output: &'a Path,
    /// Write back the output as it is written (see the write stage).
    pub sync: bool,
    /// Under `--occlusion`: what the sensor sees on the DSM.
    pub visibility: Option<&'a crate::transform::visibility::Visibility<'a>>,
}

impl Inputs<'_> {
    /// Bytes of one tile of a resampled chunk: the output's, and a byte a
    /// pixel where it says which have a value (for the mask).
    pub fn chunk_tile_bytes(&self) -> usize {
        let (w, h) = self.spec.chunk();
        self.spec.tile_bytes() + if self.pixels.mask { w as usize * h as usize } else { 0 }
    }
}

/// The piece of the grid being made, as the stages walk it: bands of tile
/// rows of the grid, or of tile columns, walking the transposed grid.
#[derive(Clone, Copy, Debug)]
pub struct Walk {
    /// The grid as walked (transposed for bands of tile columns).
    pub grid: OutputGrid,
    pub tile: u32,
    /// Bands `bands.0..bands.1` of walked tile columns `cols.0..cols.1`.
    pub bands: (u32, u32),
    pub cols: (u32, u32),
    /// Bands of the output's tile columns.
    pub columns: bool,
    /// The piece's first tile (column, row) and its width in tiles.
    pub piece: (u32, u32, u32),
}

impl Walk {
    /// Walked rows of band `b`: a band is a row of tiles of the walked grid.
    pub fn band_rows(&self, b: u32) -> (u32, u32) {
        (b * self.tile, ((b + 1) * self.tile).min(self.grid.height))
    }

    /// Where the tile of band `band` and walked tile column `col` goes in
    /// the file, row-major.
    pub fn tile_index(&self, band: u32, col: u32) -> usize {
        let (tc0, tr0, tcw) = self.piece;
        let (row, col) = if self.columns { (col, band) } else { (band, col) };
        ((row - tr0) * tcw + (col - tc0)) as usize
    }
}

/// What the run counts as it goes.
#[derive(Default)]
pub struct Counters {
    pub chunks_done: AtomicU64,
    /// Chunks read in place from the mapped scan.
    pub chunks_in_place: AtomicU64,
    pub gcm: Mutex<GcmStats>,
    /// Output pixels whose positions were worked out by `T` itself (the
    /// refinement's exact leaves, nodes without a value).
    pub exact_pixels: AtomicU64,
    /// Samples of pixels with a value that held the nodata value, moved
    /// off it ([`PixelOptions::nudge`]).
    pub nudged: AtomicU64,
    /// Under `--occlusion`: output pixels the scan images, and of them those
    /// the sensor does not see.
    pub imaged: AtomicU64,
    pub hidden: AtomicU64,
    /// The report's sample of the GCM's error, band by band (`None`: no
    /// report wants it, as a mosaic's images).
    pub sampled: Option<Mutex<crate::gcm::self_check::Acc>>,
}

/// Cancelled from outside, or failed in one stage (the others then stop).
pub struct Stop<'a> {
    cancel: &'a Cancel,
    failed: AtomicBool,
}

impl<'a> Stop<'a> {
    pub fn new(cancel: &'a Cancel) -> Stop<'a> {
        Stop { cancel, failed: AtomicBool::new(false) }
    }

    pub fn cancelled(&self) -> bool {
        self.cancel.is_cancelled()
    }

    /// Cancelled, or failed in another stage.
    pub fn now(&self) -> bool {
        self.cancel.is_cancelled() || self.failed.load(Ordering::Relaxed)
    }

    /// Records `e` as the run's failure (the other stages stop).
    pub fn fail(&self, e: Error) -> Error {
        self.failed.store(true, Ordering::Relaxed);
        e
    }
}

/// What the encoder and the writer need of a run: its output's side alone
/// (a mosaic's output has no one scan behind it).
pub struct Output<'a> {
    pub spec: &'a OutputSpec,
    /// The output's final name (for messages).
    pub path: &'a Path,
    pub sync: bool,
    pub walk: Walk,
    pub pool: &'a rayon::ThreadPool,
    pub stop: &'a Stop<'a>,
    pub progress: &'a dyn Progress,
    pub spare_masks: &'a crossbeam_channel::Sender<Vec<u8>>,
    pub pyramid: Option<&'a Mutex<crate::overview::Pyramid>>,
    pub valid_by: crate::overview::ValidBy,
    pub statistics: &'a Mutex<crate::overview::ByTileRow>,
    /// What the output is made from (its metadata's source item).
    pub source: Option<&'a str>,
    /// Its tiles come in strips of tile columns, not band by band: the
    /// file is laid out as a band-by-band run's at the end.
    pub in_strips: bool,
}

/// Everything one run's stages share.
pub struct Run<'a> {
    pub inputs: Inputs<'a>,
    pub walk: Walk,
    pub budget: MemoryBudget,
    pub counters: Counters,
    pub stop: Stop<'a>,
    /// The workers of resampling and encoding (a mosaic's images share
    /// one pool: threads of their own each would sit idle between turns).
    pub pool: &'a rayon::ThreadPool,
    pub progress: &'a dyn Progress,
    /// Chunks' mask bytes, handed back by the encoder for the next chunk
    /// (as the pixels' buffers are: fresh multi-MB buffers on every chunk
    /// cost page faults and leave the allocator's arenas holding MBs).
    pub spare_masks: (crossbeam_channel::Sender<Vec<u8>>, crossbeam_channel::Receiver<Vec<u8>>),
    /// The overview levels being made, by the encoder alone (the lock is
    /// never contended).
    pub pyramid: Option<Mutex<crate::overview::Pyramid>>,
    /// How the output's pixels say they have none, for the statistics and
    /// the overviews.
    pub valid_by: crate::overview::ValidBy,
    /// The full level's band statistics, tile by tile (the encoder's).
    pub statistics: Mutex<crate::overview::ByTileRow>,
    /// What the output is made from, the same for every piece of it.
    pub source: Option<String>,
}

impl Run<'_> {
    /// The run's output side, for the encoder and the writer.
    pub fn output(&self) -> Output<'_> {
        Output {
            spec: self.inputs.spec,
            path: self.inputs.output,
            sync: self.inputs.sync,
            walk: self.walk,
            pool: self.pool,
            stop: &self.stop,
            progress: self.progress,
            spare_masks: &self.spare_masks.0,
            pyramid: self.pyramid.as_ref(),
            valid_by: self.valid_by,
            statistics: &self.statistics,
            source: self.source.as_deref(),
            in_strips: false,
        }
    }
}
