//! The camera-file parser and validator on arbitrary text.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(f) = gcm_ortho::camera::CameraFile::parse(text, Path::new("fuzz.toml")) {
            if let Ok(cam) = f.build(Path::new("fuzz.toml")) {
                let z = cam.height_hint();
                let model = cam.model();
                if let Some((x, y)) = model.locate_approx(10.0, 10.0, z) {
                    let _ = model.project(x + 100.0, y - 50.0, z);
                }
            }
        }
    }
});
