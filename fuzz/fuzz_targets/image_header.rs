//! Image readers' headers on arbitrary bytes: JPEG 2000 (its SIZ and COD
//! segments: sizes, tiles, components), JPEG, PNG and a GDAL VRT of an
//! image. The first byte picks the file's name; an image that opens has
//! its first window read.
#![no_main]
use gcm_ortho::io::source::SourceImage;
use libfuzzer_sys::fuzz_target;

const NAMES: [&str; 5] = ["scan.jp2", "scan.j2k", "scan.jpg", "scan.png", "scan.vrt"];

fuzz_target!(|data: &[u8]| {
    let Some((&pick, body)) = data.split_first() else { return };
    let dir = tempfile::tempdir().expect("a temporary folder");
    let file = dir.path().join(NAMES[pick as usize % NAMES.len()]);
    std::fs::write(&file, body).expect("the file written");
    if let Ok(src) = SourceImage::open_within(&file, 1 << 20, 64 << 20) {
        let (w, h) = (src.info.width.min(64), src.info.height.min(64));
        if w > 0 && h > 0 {
            let mut win = gcm_ortho::io::source::Window::default();
            let _ = src.read_window(0, 0, w, h, &mut win);
        }
    }
});
