//! A DEM given as a GDAL VRT or a list of tiles, on arbitrary bytes:
//! sources that name themselves or files outside, absurd sizes and
//! transforms, many sources. A DEM that opens is looked up.
#![no_main]
use gcm_ortho::dem::Dem;
use gcm_ortho::geodesy::Crs;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, body)) = data.split_first() else { return };
    let dir = tempfile::tempdir().expect("a temporary folder");
    // A real tile beside it, under the names the seeds give their sources
    // (read once; written whole, as `fs::copy` gave up on a signal the
    // fuzzer's own timer sent: EINTR).
    static TILE: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    let tile = TILE.get_or_init(|| std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/mini/dem.tif")).expect("the tile read"));
    for name in ["a.tif", "b.tif"] {
        std::fs::write(dir.path().join(name), tile).expect("the tile written");
    }
    let file = dir.path().join(if pick % 2 == 0 { "dem.vrt" } else { "tiles.txt" });
    std::fs::write(&file, body).expect("the file written");
    let ground = Crs::from_epsg(32631).expect("UTM 31N");
    if let Ok(dem) = Dem::open_within(&file, &ground, 64 << 20) {
        let _ = dem.height_range();
        let _ = dem.height(500_000.0, 4_000_000.0);
    }
});
