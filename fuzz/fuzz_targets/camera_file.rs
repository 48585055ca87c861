//! The camera-file parser and validator on arbitrary text.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        if let Ok(f) = gcm_ortho::camera::CameraFile::parse(text, Path::new("fuzz.toml")) {
            if let Ok(cam) = f.build(Path::new("fuzz.toml")) {
                use gcm_ortho::camera::SensorModel;
                let c = cam.frame.centre;
                let _ = cam.frame.project(c.x + 100.0, c.y - 50.0, c.z - 1000.0);
                let _ = cam.frame.locate_approx(10.0, 10.0, c.z - 1000.0);
            }
        }
    }
});
