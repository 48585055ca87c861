//! The scan reader (header checks, memory-mapped and decoded paths) and the
//! DEM reader on arbitrary bytes: any answer but a panic, a hang or an
//! unbounded allocation is fine.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("in.tif");
    std::fs::write(&p, data).unwrap();
    if let Ok(src) = gcm_ortho::io::source::SourceImage::open(&p, 1 << 20) {
        let i = &src.info;
        let mut win = gcm_ortho::io::source::Window::default();
        // A corner, the middle and the last pixel, at most 64×64.
        let (w, h) = (i.width.min(64), i.height.min(64));
        let _ = src.read_window(0, 0, w, h, &mut win);
        let _ = src.read_window(i.width / 2, i.height / 2, 1, 1, &mut win);
        let _ = src.read_window(i.width - 1, i.height - 1, 1, 1, &mut win);
    }
    let _ = gcm_ortho::dem::GridDem::read(&p);
});
