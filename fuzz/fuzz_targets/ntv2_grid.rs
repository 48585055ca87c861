//! The NTv2 grid-shift reader (`+nadgrids=`) on arbitrary bytes: headers
//! that claim more than the file holds, nested subgrids, absurd sizes.
#![no_main]
use gcm_ortho::geodesy::Crs;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let grid = dir.path().join("fuzz.gsb");
    std::fs::write(&grid, data).expect("the grid written");
    let def = format!("+proj=longlat +ellps=bessel +nadgrids={} +no_defs", grid.display());
    if let Ok(crs) = Crs::parse(&def, dir.path()) {
        if let Ok(r) = gcm_ortho::geodesy::Reprojection::new(&crs, &Crs::wgs84()) {
            let _ = r.apply(13.4, 52.5);
        }
    }
});
