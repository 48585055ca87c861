//! Bands of tile columns (`--band-order columns`, chosen by `auto` for a
//! scan turned ~90°) against bands of tile rows: the same orthophoto, the
//! scan read in place, pieces that assemble into the whole.

mod common;
use common::*;
use std::path::Path;

/// Every sample of an image, as bytes, with its width, height and georeferencing.
fn samples(path: &Path) -> (Vec<u8>, u32, u32, String) {
    let (bytes, info) = whole_image(path);
    (bytes, info.width, info.height, format!("{:?}", info.georef))
}

/// Runs rectify on `sc` with `extra` arguments; returns the report.
fn rectify(sc: &gcm_ortho::synth::SynthReport, out: &Path, extra: &[&str]) -> serde_json::Value {
    let json = out.with_extension("json");
    let mut a = vec!["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(out), "--json", s(&json)];
    a.extend_from_slice(extra);
    let r = run(&a);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap()
}

/// The two orders agree: same grid, and samples equal but for rounding
/// (by up to a 255th of the sample's range, in under 2 % of them) and the
/// rare pixel at the scan's edge that one order finds inside the scan and
/// the other just outside. Both walks interpolate the same corrections
/// from the same nodes bilinearly; where `A` curves along the walk, its
/// straight pieces stay within 1/4096 px of it, a quarter of the 1/1024 px
/// the kernel's weights resolve, so a weight moves by one step now and
/// then (in 16-bit samples, a step can move a value by tens of levels).
fn assert_same_orthophoto(rows: &Path, columns: &Path, bytes_per_sample: usize) {
    let (a, wa, ha, ga) = samples(rows);
    let (b, wb, hb, gb) = samples(columns);
    assert_eq!((wa, ha, &ga), (wb, hb, &gb));
    assert_eq!(a.len(), b.len());
    type Samples = fn(&[u8]) -> Vec<u64>;
    let (value, unit): (Samples, u64) = match bytes_per_sample {
        1 => (|v| v.iter().map(|&x| x as u64).collect(), 1),
        _ => (|v| v.chunks_exact(2).map(|p| u16::from_le_bytes([p[0], p[1]]) as u64).collect(), 257),
    };
    let (a, b) = (value(&a), value(&b));
    let rounding = a.iter().zip(&b).filter(|(x, y)| x != y && x.abs_diff(**y) <= unit).count();
    let more = a.iter().zip(&b).filter(|(x, y)| x.abs_diff(**y) > unit).count();
    assert!(rounding * 50 < a.len(), "{rounding} of {} samples differ by rounding", a.len());
    assert!(more * 10_000 < a.len(), "{more} of {} samples differ by more", a.len());
}

#[test]
fn a_scan_turned_90_degrees_is_made_in_bands_of_tile_columns_read_in_place() {
    let dir = tempfile::tempdir().unwrap();
    // 5 MB of scan: more than the rows `--memory 16M` lets a chunk read in
    // place (six 24ths of it).
    let sc = scene(&dir.path().join("scene"), 1300, |o| o.kappa_deg = 90.0);
    let auto = dir.path().join("auto.tif");
    // Without the error bound both walks interpolate the very same nodes;
    // under it each refines its own cells (each within the bound).
    let rep = rectify(&sc, &auto, &["--compress", "none", "--tile", "64", "--memory", "16M", "--max-error", "none"]);
    assert_eq!(rep["config"]["band_order"], "columns");
    // Every window lies in a few scan rows: all read in place.
    let (chunks, in_place) = (rep["chunks"].as_u64().unwrap(), rep["chunks_in_place"].as_u64().unwrap());
    assert!(chunks > 4 && in_place == chunks, "{in_place} of {chunks} chunks in place");
    let rows = dir.path().join("rows.tif");
    let rep = rectify(&sc, &rows, &["--compress", "none", "--tile", "64", "--memory", "16M", "--band-order", "rows", "--max-error", "none"]);
    assert_eq!(rep["config"]["band_order"], "rows");
    // Across the scan's rows every window is tall: copied.
    assert_eq!(rep["chunks_in_place"], 0);
    assert_same_orthophoto(&rows, &auto, 1);
    // The GCM's sampled error is as small either way (a walk whose `A`
    // were not turned with it would miss by pixels between the nodes).
    let est = |r: &serde_json::Value| r["accuracy_estimate"]["max"].as_f64().unwrap();
    let rep_auto = rectify(&sc, &dir.path().join("auto2.tif"), &["--tile", "64"]);
    assert!(est(&rep_auto) < 0.5 && est(&rep) < 0.5, "{} {}", est(&rep_auto), est(&rep));
}

#[test]
fn a_scan_not_turned_keeps_bands_of_tile_rows() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 400, |o| o.kappa_deg = 20.0);
    let rep = rectify(&sc, &dir.path().join("o.tif"), &[]);
    assert_eq!(rep["config"]["band_order"], "rows");
    let sc = scene(&dir.path().join("scene-minus"), 400, |o| o.kappa_deg = -100.0);
    let rep = rectify(&sc, &dir.path().join("o2.tif"), &[]);
    assert_eq!(rep["config"]["band_order"], "columns");
}

#[test]
fn every_pixel_layout_agrees_between_the_two_orders() {
    let dir = tempfile::tempdir().unwrap();
    // Grey, RGB, RGBA-like four bands, 16-bit RGB, and an added alpha band
    // (the tiles' pixels are then wider than the scan's); tiles of 48 take
    // tasks of 16 columns, of 128 tasks of 128.
    for (name, bands, bits, extra) in [
        ("grey8", 1, 8, &["--tile", "48"][..]),
        ("rgb8-alpha", 3, 8, &["--alpha", "--tile", "128"][..]),
        ("four8", 4, 8, &["--tile", "64"][..]),
        ("rgb16", 3, 16, &["--tile", "48"][..]),
        ("grey16-alpha", 1, 16, &["--alpha", "--tile", "64"][..]),
    ] {
        let sc = scene(&dir.path().join(name), 300, |o| {
            o.kappa_deg = 75.0;
            o.bands = bands;
            o.bits = bits;
        });
        let mut outs = Vec::new();
        for order in ["rows", "columns"] {
            let out = dir.path().join(format!("{name}-{order}.tif"));
            let mut a = vec!["--band-order", order, "--compress", "deflate", "--max-error", "none"];
            a.extend_from_slice(extra);
            let rep = rectify(&sc, &out, &a);
            assert_eq!(rep["config"]["band_order"], order);
            outs.push(out);
        }
        assert_same_orthophoto(&outs[0], &outs[1], bits as usize / 8);
    }
}

#[test]
fn pieces_made_in_bands_of_tile_columns_assemble_into_the_whole() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("scene"), 600, |o| o.kappa_deg = 95.0);
    let whole = d.join("whole.tif");
    let rep = rectify(&sc, &whole, &["--tile", "64"]);
    assert_eq!(rep["config"]["band_order"], "columns");
    let (ta, td) = (rep["grid"]["width"].as_u64().unwrap().div_ceil(64) as u32, rep["grid"]["height"].as_u64().unwrap().div_ceil(64) as u32);
    // Three uneven pieces: the first two tile columns, and the rest split.
    let r = td / 2;
    let windows = [[0, 0, 2, td], [2, 0, ta - 2, r], [2, r, ta - 2, td - r]];
    let mut pieces = Vec::new();
    for (k, w) in windows.iter().enumerate() {
        let p = d.join(format!("piece{k}.tif"));
        rectify(&sc, &p, &["--tile", "64", "--window", &format!("{},{},{},{}", w[0], w[1], w[2], w[3])]);
        pieces.push(p);
    }
    let joined = d.join("joined.tif");
    let mut a = vec!["assemble", "-o", s(&joined)];
    a.extend(pieces.iter().map(|p| s(p)));
    let o = run(&a);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The whole run's tiles lie in the file column by column, the
    // assembled ones row by row: the same pixels, in other places.
    assert!(samples(&whole) == samples(&joined), "assembled pieces differ from the single run");
}
