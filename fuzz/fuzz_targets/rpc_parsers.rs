//! Every RPC reader (text, OSSIM .geom, RPB, DIMAP / WorldView XML, NITF
//! TRE) and the .gtx geoid reader on arbitrary bytes; models that parse are
//! evaluated and inverted.
#![no_main]
use gcm_ortho::camera::rpc::Rpc;
use gcm_ortho::geodesy::Geoid;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let p = Path::new("fuzz.rpc");
    let mut parsed = vec![Rpc::parse_nitf(data, p)];
    if let Ok(text) = std::str::from_utf8(data) {
        parsed.push(Rpc::parse_text(text, p));
        parsed.push(Rpc::parse_geom(text, p));
        parsed.push(Rpc::parse_rpb(text, p));
        parsed.push(Rpc::parse_xml(text, p));
    }
    for rpc in parsed.into_iter().flatten() {
        if let Some((c, r)) = rpc.project(rpc.long_off, rpc.lat_off, rpc.height_off) {
            let _ = rpc.locate(c + 10.0, r - 10.0, rpc.height_off, 1e-3);
        }
        let _ = rpc.pixels_per_degree();
    }
    if let Ok(g) = Geoid::parse(data, Path::new("fuzz.gtx")) {
        let _ = g.undulation(5.0, 44.0);
        let _ = g.undulation(-200.0, 91.0);
    }
});
