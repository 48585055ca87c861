//! Other tools' camera files on arbitrary bytes: Orthority's interior
//! parameters (YAML), OpenSfM / OpenDroneMap reconstructions (JSON),
//! Metashape's cameras (XML), exterior orientations (CSV, GeoJSON). The
//! first byte picks the kind (by the file's name, as the reader tells
//! them); a set that reads gives each image's camera.
#![no_main]
use gcm_ortho::camera::formats::{read_with, AngleUnit};
use libfuzzer_sys::fuzz_target;

const NAMES: [&str; 6] = ["int_param.yaml", "reconstruction.json", "cameras.xml", "ext_param.csv", "ext_param.geojson", "calibrated_camera_parameters.txt"];

fuzz_target!(|data: &[u8]| {
    let Some((&pick, body)) = data.split_first() else { return };
    let dir = tempfile::tempdir().expect("a temporary folder");
    let name = NAMES[pick as usize % NAMES.len()];
    let file = dir.path().join(name);
    std::fs::write(&file, body).expect("the file written");
    let image = dir.path().join("IMG_0001.JPG");
    // Exterior files are read beside an interior one, as rectify reads them.
    let (camera, exterior) = if name.starts_with("ext_") {
        let interior = dir.path().join("int_param.yaml");
        std::fs::write(&interior, "cam:\n  type: pinhole\n  im_size: [4000, 3000]\n  focal_len: 0.8\n  sensor_size: [1.333, 1.0]\n").expect("written");
        (interior, Some(file))
    } else {
        (file, None)
    };
    for angles in [AngleUnit::Degrees, AngleUnit::Radians] {
        if let Ok(set) = read_with(&camera, exterior.as_deref(), Some(&image), angles) {
            let _ = set.camera_for(&image);
            let _ = set.all();
        }
    }
});
