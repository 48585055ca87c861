//! synth → rectify → compare with the truth orthophoto, from opposite
//! directions: synth casts every scan pixel's ray onto the DEM, rectify maps
//! every output pixel into the scan through A + GCM.

mod common;
use common::*;
use gcm_ortho::io::source::SourceImage;
use gcm_ortho::study::compare::{compare, read_grey};

/// synth (with `tweak`) → rectify at the defaults → compare with the truth.
fn rectifies_onto_its_truth(size: u32, tweak: impl FnOnce(&mut gcm_ortho::synth::SynthOptions)) -> (gcm_ortho::synth::SynthReport, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), size, tweak);
    let out = dir.path().join("ortho.tif");
    let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(&out), "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    // The default grid is the truth's grid: same georeferencing.
    let o = SourceImage::open(&out, 1 << 20).unwrap();
    let t = SourceImage::open(sc.truth.as_ref().unwrap(), 1 << 20).unwrap();
    assert_eq!((o.info.width, o.info.height), (t.info.width, t.info.height));
    let (og, tg) = (o.info.georef.clone().unwrap(), t.info.georef.clone().unwrap());
    assert_eq!((og.transform, &og.keys), (tg.transform, &tg.keys));
    // No nodata value: an internal mask says where the image is.
    assert!(og.nodata.is_none() && o.info.mask.is_some(), "{og:?}");
    let c = compare(&read_grey(&out, 0.0).unwrap(), &read_grey(sc.truth.as_ref().unwrap(), 0.0).unwrap(), 48);
    // Read a band of rows at a time (as `demo` compares), the same figures.
    let streamed = gcm_ortho::study::compare::compare_files(&out, sc.truth.as_ref().unwrap(), 0.0, 48).unwrap();
    assert_eq!(format!("{streamed:?}"), format!("{c:?}"));
    // Bilinear resampling of a scan at the orthophoto's own GSD smooths
    // only the 1-GSD ramps of edges and lines (a tenth of the pixels); the
    // texture between them is smooth. So the mean difference stays at a few
    // grey levels; a geometric error of ½ px would raise it past 5 (edges of
    // up to 200 levels moving by half a pixel).
    assert!(c.pixels > (size as u64 * size as u64) / 3, "{c:?}");
    assert!(c.mean_abs_diff < 2.0, "{c:?}");
    // The sharp lines land where they should: correlation in windows finds
    // offsets far under ½ px.
    assert!(c.windows > 100, "{c:?}");
    assert!(c.mean_shift < 0.1, "{c:?}");
    assert!(c.p95_shift < 0.25, "{c:?}");
    (sc, dir)
}

#[test]
fn film_scene_rectifies_onto_its_truth() {
    rectifies_onto_its_truth(1500, |_| {});
}

#[test]
fn an_18_cm_frame_with_eight_marks_rectifies_onto_its_truth() {
    let (sc, _dir) = rectifies_onto_its_truth(1200, |o| {
        o.frame_mm = 180.0;
        o.fiducials = 8;
        o.kappa_deg = -12.0;
    });
    // Eight marks 2.5 mm outside the 18 cm frame, found again by the
    // fiducial fit to a fraction of a pixel.
    let text = std::fs::read_to_string(&sc.camera).unwrap();
    assert!(text.contains("[-92.5, -92.5]") && text.contains("[0.0, -92.5]"), "{text}");
    let cam = gcm_ortho::camera::file::Camera::read(&sc.camera).unwrap();
    let frame = cam.frame(&sc.camera).unwrap();
    let px = frame.interior.pixel_size_mm();
    assert!((px - 190.0 / 1200.0).abs() < 1e-3 * px, "{px}");
}

#[test]
fn checkpoints_agree_to_a_quarter_pixel_at_k16() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 1200, |o| o.kappa_deg = 31.0);
    let json = dir.path().join("accuracy.json");
    let map = dir.path().join("error.tif");
    let r = run(&["accuracy", "--scene", s(&dir.path().join("scene")), "--sparsity", "16", "--step", "4", "--json", s(&json), "--error-map", s(&map)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    // The error map has values where the scan is, NaN (its nodata) past it:
    // a frame swung 31° leaves the grid's corners empty.
    let (mw, mh, _, errors) = read_f32(&map);
    let info = gcm_ortho::io::source::SourceImage::info_of(&map).unwrap();
    assert!(info.georef.unwrap().nodata.is_some_and(|v| v.is_nan()));
    let corner = |x: u32, y: u32| errors[(y * mw + x) as usize];
    assert!(corner(0, 0).is_nan() && corner(mw - 1, mh - 1).is_nan() && !corner(mw / 2, mh / 2).is_nan());
    let valid = errors.iter().filter(|e| !e.is_nan()).count();
    assert!(valid > errors.len() / 2 && valid < errors.len() * 95 / 100, "{valid} of {}", errors.len());
    let table: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let row = table["rows"].as_array().unwrap().iter().find(|r| r.get("checkpoints").is_some()).expect("a checkpoint row");
    let written = std::fs::read_to_string(&sc.checkpoints).unwrap().lines().filter(|l| l.starts_with(|c: char| c.is_ascii_digit())).count();
    assert_eq!((row["checkpoints"].as_u64(), written), (Some(50), 50), "{row}");
    assert_eq!(row["k"].as_u64(), Some(16));
    let rms = row["rms_px"].as_f64().unwrap();
    assert!(rms > 0.0 && rms <= 0.25, "{row}");
    drop(sc);
}

#[test]
fn synth_is_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    let hash = |p: &std::path::Path| {
        use std::hash::{Hash, Hasher};
        let mut h = std::collections::hash_map::DefaultHasher::new();
        std::fs::read(p).unwrap().hash(&mut h);
        h.finish()
    };
    let a = scene(&dir.path().join("a"), 300, |o| o.seed = 7);
    let b = scene(&dir.path().join("b"), 300, |o| o.seed = 7);
    let c = scene(&dir.path().join("c"), 300, |o| o.seed = 8);
    assert_eq!(hash(&a.scan), hash(&b.scan));
    assert_eq!(hash(&a.dem), hash(&b.dem));
    assert_eq!(std::fs::read(&a.camera).unwrap(), std::fs::read(&b.camera).unwrap());
    assert_ne!(hash(&a.scan), hash(&c.scan));
}

#[test]
fn every_input_layout_gives_the_same_orthophoto() {
    use gcm_ortho::io::tiff_out::Compression;
    let dir = tempfile::tempdir().unwrap();
    let mut outputs = Vec::new();
    for (name, tiled, comp) in [
        ("strips-none", false, Compression::None),
        ("tiles-none", true, Compression::None),
        ("strips-lzw", false, Compression::Lzw),
        ("tiles-deflate", true, Compression::Deflate),
    ] {
        let sc = scene(&dir.path().join(name), 700, |o| {
            o.tiled = tiled;
            o.compress = comp;
            o.kappa_deg = 90.0;
            o.bits = 16;
        });
        let out = dir.path().join(format!("{name}.tif"));
        let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(&out), "--quiet", "--resample", "cubic"]);
        assert!(r.status.success(), "{name}: {}", String::from_utf8_lossy(&r.stderr));
        // The pixels, mask and grid (the files differ in the metadata
        // naming their source, a file each).
        outputs.push((name, content(&out)));
    }
    for (name, made) in &outputs[1..] {
        assert!(made == &outputs[0].1, "{name} differs from {}", outputs[0].0);
    }
}

#[test]
fn small_memory_budget_and_many_chunks_change_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 800, |o| o.kappa_deg = 45.0);
    let mut outs = Vec::new();
    for (mem, tile, threads) in [("512M", "256", "2"), ("16M", "64", "1")] {
        let out = dir.path().join(format!("o{mem}.tif"));
        let json = dir.path().join(format!("r{mem}.json"));
        let r = run(&[
            "rectify",
            "--image",
            s(&sc.scan),
            "--camera",
            s(&sc.camera),
            "--dem",
            s(&sc.dem),
            "-o",
            s(&out),
            "--quiet",
            "--memory",
            mem,
            "--tile",
            tile,
            "--threads",
            threads,
            "--compress",
            "none",
            "--json",
            s(&json),
        ]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        outs.push(read_grey(&out, 0.0).unwrap());
        // The striped, uncompressed scan is read in place from its mapping.
        let rep: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        let (all, in_place) = (rep["chunks"].as_u64().unwrap(), rep["chunks_in_place"].as_u64().unwrap());
        assert!(all > 1 && in_place > 0 && in_place <= all, "{mem}: {in_place} of {all} chunks in place");
    }
    assert_eq!(outs[0].v, outs[1].v);
}

#[test]
fn a_dem_too_large_for_memory_is_read_in_chunks_with_the_same_result() {
    use gcm_ortho::dem::{GridDem, IN_MEMORY_LIMIT};
    use gcm_ortho::io::tiff_out::*;
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 400, |o| o.dem_posting = 20.0);
    let small = GridDem::read(&sc.dem).unwrap();
    assert!(!small.is_chunked());
    // The same heights resampled onto a grid 20× finer in each direction:
    // ~4.7 K² Float32 samples ≈ 89 MB, past the in-memory limit. Written
    // tiled and deflated; its bilinear heights equal the coarse DEM's at the
    // coarse posts and in between (bilinear of bilinear on a refined grid).
    let f = 20usize;
    let (w, h) = (small.width * f, small.height * f);
    assert!((w * h * 4) as u64 > IN_MEMORY_LIMIT);
    let gt = small.transform;
    let big = dir.path().join("big_dem.tif");
    let spec = OutputSpec {
        overviews: 0,
        cog: false,
        width: w as u32,
        height: h as u32,
        bands: 1,
        sample: gcm_ortho::io::source::SampleType::F32,
        chunking: Chunking::Tiles(256),
        compression: Compression::Deflate,
        level: None,
        overview_level: None,
        bigtiff: false,
        photometric: 1,
        alpha: false,
        mask: false,
        geo: Some(GeoTags {
            x0: gt[0],
            y0: gt[3],
            gsd: gcm_ortho::geom::Gsd::square(gt[1] / f as f64),
            keys: gcm_ortho::geodesy::geokeys::keys_of_epsg(32631).unwrap(),
            nodata: None,
        }),
    };
    write_raster(&big, &spec, |y0, y1, buf| {
        let out: &mut [f32] = bytemuck::cast_slice_mut(buf);
        for y in y0..y1 {
            for x in 0..w {
                let (gx, gy) = (gt[0] + (x as f64 + 0.5) * gt[1] / f as f64, gt[3] + (y as f64 + 0.5) * gt[5] / f as f64);
                out[(y - y0) as usize * w + x] = match small.lookup(gx, gy) {
                    gcm_ortho::dem::Lookup::Height(z) => z as f32,
                    _ => f32::NAN,
                };
            }
        }
    })
    .unwrap();
    let chunked = GridDem::read(&big).unwrap();
    assert!(chunked.is_chunked());
    for (x, y) in [(649800.3, 4890500.7), (650321.0, 4889900.2), (650999.9, 4890011.1)] {
        let (a, b) = (small.lookup(x, y), chunked.lookup(x, y));
        if let (gcm_ortho::dem::Lookup::Height(a), gcm_ortho::dem::Lookup::Height(b)) = (a, b) {
            assert!((a - b).abs() < 0.05, "{a} {b}");
        }
    }
    // And rectify runs on it, in bounded memory.
    let out = dir.path().join("o.tif");
    let r = run(&[
        "rectify",
        "--image",
        s(&sc.scan),
        "--camera",
        s(&sc.camera),
        "--dem",
        s(&big),
        "-o",
        s(&out),
        "--quiet",
        "--json",
        s(&dir.path().join("r.json")),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let rep: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("r.json")).unwrap()).unwrap();
    // Less than the DEM alone would take in memory (89 MB).
    assert!(rep["peak_rss_mib"].as_f64().unwrap() < 85.0, "{}", rep["peak_rss_mib"]);
}
