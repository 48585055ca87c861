//! Every option parser on arbitrary text, the key table on arbitrary JSON,
//! and the options they make checked: no panic, an error naming the
//! setting instead; options that are valid read back from their serialized
//! form as they were.
#![no_main]
use gcm_ortho::options::*;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let mut o = RectifyOptions::new("scan.tif".into(), "camera.toml".into(), DemSource::Height(0.0), "out.tif".into());
    if let Ok(b) = parse_bytes("memory", text) {
        o.resources.memory = b;
    }
    if let Ok(n) = parse_count("max_output_pixels", text) {
        o.grid.max_output_pixels = Some(n);
    }
    if let Ok(b) = parse_bounds("bounds", text) {
        o.grid.bounds = b;
    }
    if let Ok(w) = parse_window("window", text) {
        o.grid.window = Some(w);
    }
    if let Ok(m) = parse_miss("dem_hole", text) {
        o.inputs.dem_hole = m;
    }
    let _ = parse_offset("rpc_offset", text);
    let _ = parse_size("size", text);
    if let Ok(k) = parse_choice("resample", text) {
        o.pixels.kernel = k;
    }
    if let Ok(c) = parse_choice("compress", text) {
        o.file.compress = c;
    }
    if let Some(n) = text.split(',').next().and_then(|t| t.trim().parse::<u32>().ok()) {
        o.file.tile = n;
        o.geometry.gcm.k = n;
        o.resources.threads = n as usize;
    }
    let _ = o.validate();
    // Settings by key, as a binding passes them.
    if let Ok(serde_json::Value::Object(keys)) = serde_json::from_str::<serde_json::Value>(text) {
        if let Ok(o) = gcm_ortho::by_key::rectify_options(keys) {
            let json = serde_json::to_string(&o).expect("valid options serialize");
            let back: RectifyOptions = serde_json::from_str(&json).expect("and read back");
            assert_eq!(serde_json::to_string(&back).expect("serialize"), json);
        }
    }
});
