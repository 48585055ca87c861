//! The CRS reader (EPSG and ESRI codes, URNs, PROJ strings, WKT1, WKT2,
//! ESRI WKT) on arbitrary text; a CRS that parses is used as a run would:
//! its projection, and a point taken to it from WGS 84 and back.
#![no_main]
use gcm_ortho::geodesy::{Crs, Reprojection};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    // A name that looks like a file is looked for in an empty folder.
    let dir = tempfile::tempdir().expect("a temporary folder");
    let Ok(crs) = Crs::parse(text, dir.path()) else { return };
    let _ = crs.to_string();
    let _ = Crs::parse(&crs.definition(), dir.path());
    if let Ok(r) = Reprojection::new(&Crs::wgs84(), &crs) {
        if let Some((x, y)) = r.apply(2.35, 48.85) {
            if let Ok(back) = Reprojection::new(&crs, &Crs::wgs84()) {
                let _ = back.apply(x, y);
            }
        }
    }
});
