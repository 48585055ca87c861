//! Every option parser on arbitrary text, and the options they make
//! checked: no panic, an error naming the setting instead.
#![no_main]
use gcm_ortho::options::*;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let mut o = RectifyOptions::new("scan.tif".into(), "camera.toml".into(), DemSource::Height(0.0), "out.tif".into());
    if let Ok(b) = parse_bytes("memory", text) {
        o.memory = b;
    }
    if let Ok(n) = parse_count("max_output_pixels", text) {
        o.max_output_pixels = Some(n);
    }
    if let Ok(b) = parse_bounds("bounds", text) {
        o.bounds = b;
    }
    if let Ok(w) = parse_window("window", text) {
        o.window = Some(w);
    }
    if let Ok(m) = parse_miss("dem_hole", text) {
        o.dem_hole = m;
    }
    let _ = parse_offset("rpc_offset", text);
    let _ = parse_size("size", text);
    if let Ok(k) = parse_choice("resample", text) {
        o.kernel = k;
    }
    if let Ok(c) = parse_choice("compress", text) {
        o.compress = c;
    }
    if let Some(n) = text.split(',').next().and_then(|t| t.trim().parse::<u32>().ok()) {
        o.tile = n;
        o.gcm.k = n;
        o.threads = n as usize;
    }
    let _ = o.validate();
});
