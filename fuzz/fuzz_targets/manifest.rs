//! The batch manifest's reader and validator on arbitrary text: no panic,
//! every problem an error with its line; jobs whose files do not exist
//! come back with their problem set.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let path = dir.path().join("manifest.toml");
    std::fs::write(&path, data).expect("written");
    if let Ok(jobs) = gcm_ortho::batch::manifest::load(&path) {
        let _ = gcm_ortho::batch::manifest::files(&jobs);
        for j in &jobs {
            let _ = j.config.validate();
        }
    }
});
