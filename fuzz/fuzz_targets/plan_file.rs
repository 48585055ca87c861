//! A mosaic's plan file (what shards render from) on arbitrary bytes:
//! its checksum, its grid, cells and gains range-checked on reading.
#![no_main]
use gcm_ortho::mosaic::plan_file::{cell_of, grid_of};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let file = dir.path().join("mosaic.plan");
    std::fs::write(&file, data).expect("the file written");
    let _ = grid_of(&file);
    let _ = cell_of(&file);
});
