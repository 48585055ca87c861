//! Point files for `grid` on arbitrary bytes: LAS, LAZ (its header, the
//! laszip record and the chunk table checked before the decoder opens
//! it) and text (CSV, XYZ). The first byte picks the file's name; a file
//! that opens has its CRS read and its points streamed to the end.
#![no_main]
use gcm_ortho::points::{Columns, Filter, PointFile};
use libfuzzer_sys::fuzz_target;

const NAMES: [&str; 4] = ["points.las", "points.laz", "points.csv", "points.xyz"];

fuzz_target!(|data: &[u8]| {
    let Some((&pick, body)) = data.split_first() else { return };
    let dir = tempfile::tempdir().expect("a temporary folder");
    let file = dir.path().join(NAMES[pick as usize % NAMES.len()]);
    std::fs::write(&file, body).expect("the file written");
    if let Ok(points) = PointFile::open(&file) {
        let _ = points.crs();
        let mut n = 0u64;
        let _ = points.read(&Columns::Auto, &Filter::default(), &gcm_ortho::Cancel::new(), &mut |batch, _| {
            n += batch.len() as u64;
            Ok(())
        });
    }
});
