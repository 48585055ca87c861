//! `rectify`: a scan through a bounded streaming pipeline into a tiled
//! GeoTIFF. Output is made a band (one row of tiles, or one column) at a
//! time by stages joined by bounded channels, so a few bands at most are in
//! flight and memory does not grow with the image:
//!
//! 1. DEM lookup — heights at the GCM nodes of the next band;
//! 2. GCM — exact `T` at the nodes (and refinement under `--max-error`);
//! 3. read — plan the band's chunks and read their scan windows;
//! 4. resample — rows of a chunk in parallel (rayon), two chunks at once so
//!    that a worker done with one starts on the next;
//! 5. encode — the chunk's tiles compressed in parallel;
//! 6. write — one thread appends tiles as they come, recording where.
//!
//! Bands run along the output's rows, or along its columns where that
//! reads the scan along its rows (a scan turned ~90°; see `BandOrder`): the
//! stages then walk a transposed grid, whose rows the resampler writes
//! across, as columns, into the tiles.
//!
//! With two threads or more each stage runs on a thread of its own
//! (`threaded.rs`); with one, the same steps (`steps.rs`) run one after the
//! other, pulled by the writer (`sequential.rs`), so that the run keeps one
//! processor busy. Both write the same file.
//!
//! The first error anywhere cancels every stage; the output is a temporary
//! file that is removed unless the whole run succeeds.

mod chunk;
mod config;
mod plan;
mod rectify;
mod report;
mod sequential;
mod steps;
mod threaded;
mod transpose;

pub use config::{BandOrder, BigTiff, DemSource, RectifyConfig};
pub use plan::{plan_band, Chunk};
pub use rectify::rectify;
pub use report::{Report, StageTimes};
