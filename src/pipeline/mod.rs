//! `rectify`: a scan through a bounded streaming pipeline into a tiled
//! GeoTIFF. The set-up (`setup.rs`) turns the options into a [`RunPlan`];
//! the output is then made a band (one row of tiles, or one column) at a
//! time by the stages in `stages/` — DEM, GCM, read, resample, encode,
//! write — so that a few bands at most are in flight and memory, planned in
//! `budget.rs`, does not grow with the image.
//!
//! Bands run along the output's rows, or along its columns where that
//! reads the scan along its rows (a scan turned ~90°): the stages then walk
//! a transposed grid, whose rows the resampler writes across, as columns,
//! into the tiles.
//!
//! With two threads or more each stage runs on a thread of its own, joined
//! to the next by a bounded channel (`threaded.rs`); with one, the same
//! stages run one after the other, pulled by the writer (`sequential.rs`),
//! so that the run keeps one processor busy. Both write the same file.
//!
//! The first error anywhere cancels every stage; the output is a temporary
//! file that is removed unless the whole run succeeds.

mod band_bytes;
pub mod band_render;
pub mod band_writer;
mod budget;
mod context;
mod output_plan;
mod rectify;
mod report;
mod sequential;
mod setup;
mod stages;
mod threaded;

pub use output_plan::{plan, OutputPlan};
pub use rectify::rectify;
pub use report::{Hidden, Report};
pub use setup::{tiles_memory, RunPlan};
pub use stages::resample::{Made, Raw};
