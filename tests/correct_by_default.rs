//! At its default settings `rectify` holds the GCM within 0.1 scan px of
//! the exact model at every output pixel, on scenes like the real ones
//! where the old defaults were pixels off: an oblique drone frame with
//! strong distortion over a DSM of buildings, and a film scan on a coarse
//! DEM. Checked with coordinate images (every output pixel holds the scan
//! position it sampled) against `--sparsity 1 --corrections cell`, the
//! exact model at every pixel, over every pixel.

mod common;
use common::*;
use gcm_ortho::synth::Relief;
use std::path::Path;

/// `sc`'s coordinate image (made once) rectified with `extra` into `name`;
/// and the run's report.
fn rectify_coords(dir: &Path, sc: &gcm_ortho::synth::SynthReport, (w, h): (u32, u32), name: &str, extra: &[&str]) -> (std::path::PathBuf, serde_json::Value) {
    rectify_coords_on(dir, sc, &sc.dem, (w, h), name, extra)
}

/// [`rectify_coords`] on the DEM `dem`.
fn rectify_coords_on(
    dir: &Path,
    sc: &gcm_ortho::synth::SynthReport,
    dem: &Path,
    (w, h): (u32, u32),
    name: &str,
    extra: &[&str],
) -> (std::path::PathBuf, serde_json::Value) {
    let coords = dir.join("coords.tif");
    if !coords.exists() {
        coordinate_image(&coords, w, h);
    }
    let out = dir.join(name);
    let json = out.with_extension("json");
    let mut a = vec!["rectify", "--image", s(&coords), "--camera", s(&sc.camera), "--dem", s(dem), "--nodata", "-1", "--compress", "none", "--quiet"];
    a.extend_from_slice(extra);
    a.extend(["-o", s(&out), "--json", s(&json)]);
    let r = run(&a);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    (out, report)
}

/// The default run and the exact one on `sc`'s coordinate image, compared
/// position by position; and the default run's report.
fn default_against_exact(dir: &Path, sc: &gcm_ortho::synth::SynthReport, w: u32, h: u32) -> (MapDifference, serde_json::Value) {
    let (default, report) = rectify_coords(dir, sc, (w, h), "default.tif", &[]);
    let (exact, _) = rectify_coords(dir, sc, (w, h), "exact.tif", &["--sparsity", "1", "--corrections", "cell", "--memory", "1G"]);
    (coordinate_map_difference(&default, &exact, w, h), report)
}

#[test]
fn an_oblique_drone_frame_over_buildings_is_within_the_bound_at_every_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (900, 600);
    // 0.33 m pixels from 160 m over a DSM posted at 1 m (3 px): walls
    // 4–30 m high, trees, 25° off nadir, barrel distortion.
    let sc = drone_scene(dir.path(), (w, h), 18_000.0);
    let (m, report) = default_against_exact(dir.path(), &sc, w, h);
    eprintln!("drone over buildings: {} px, max {:.4} px, mean {:.5} px", m.pixels, m.max, m.mean);
    assert!(m.pixels > 200_000, "{} px compared", m.pixels);
    assert!(m.max <= 0.1, "max {} px", m.max);
    assert_eq!(report["config"]["gcm"]["max_error"], 0.1);
    // The bound is not kept by refining everything.
    let g = &report["gcm"];
    assert!(g["refined_cells"].as_u64().unwrap() < g["cells"].as_u64().unwrap(), "{g}");
    // Walls' cells refined to the bottom are worked out pixel by pixel, and
    // the report counts those pixels: some, and far from all.
    let exact = g["exact_pixels"].as_u64().unwrap();
    assert!(exact > 0 && exact < (m.pixels / 2) as u64, "{exact} exact of {} px", m.pixels);
}

#[test]
fn walls_inside_dem_cells_are_held_to_the_bound_row_by_row_not_pixel_by_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (900, 600);
    // The DSM posted at 3 m, 9 output px: a wall inside one DSM cell is a
    // steep ramp there, smooth along each row (one quadratic through a
    // few exact points), not a cell to be worked out pixel by pixel.
    let sc = common::drone_scene_posted(dir.path(), (w, h), 18_000.0, 3.0);
    let (m, report) = default_against_exact(dir.path(), &sc, w, h);
    eprintln!("drone over a DSM of 9 px: {} px, max {:.4} px, mean {:.5} px; {}", m.pixels, m.max, m.mean, report["gcm"]);
    assert!(m.pixels > 200_000, "{} px compared", m.pixels);
    assert!(m.max <= 0.1, "max {} px", m.max);
    let g = &report["gcm"];
    assert!(g["refined_cells"].as_u64().unwrap() > 100, "{g}");
    let exact = g["exact_pixels"].as_u64().unwrap();
    assert!(exact < (m.pixels / 50) as u64, "{exact} exact of {} px", m.pixels);
}

#[test]
fn a_film_scan_on_a_coarse_dem_is_within_the_bound_at_every_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let w = 1000;
    // 9.6 m pixels on a DEM posted at 48 m (5 px), hills of 20°.
    let sc = scene(&dir.path().join("scene"), w, |o| {
        o.relief = Relief::Hilly;
        o.dem_posting = 48.0;
        o.scale = 40_000.0;
        o.kappa_deg = 12.0;
    });
    let (m, report) = default_against_exact(dir.path(), &sc, w, w);
    eprintln!("film on a coarse DEM: {} px, max {:.4} px, mean {:.5} px", m.pixels, m.max, m.mean);
    assert!(m.pixels > 500_000, "{} px compared", m.pixels);
    assert!(m.max <= 0.1, "max {} px", m.max);
    // The DEM's posts set the node spacing, so no cell needs refining.
    assert_eq!(report["config"]["gcm"]["k"], 5);
    assert_eq!(report["gcm"]["refined_cells"], 0);
}

/// A digital frame over hills on a DEM posted at 5 m, north up (its post
/// lines are node lines, the case where bands were passed whole), `w`×`h`
/// px in `dir/scene`; and its DEM read whole.
fn digital_over_hills(dir: &Path, (w, h): (u32, u32)) -> (gcm_ortho::synth::SynthReport, gcm_ortho::dem::GridDem) {
    let sc = scene(&dir.join("scene"), w, |o| {
        o.height = h;
        o.camera = gcm_ortho::synth::CameraKind::Digital;
        o.kappa_deg = 0.0;
    });
    let g = gcm_ortho::dem::GridDem::read_within(&sc.dem, u64::MAX).unwrap();
    (sc, g)
}

/// Where the DEM stops (or has a hole) and `--dem-outside` (or
/// `--dem-hole`) gives a height near its own, the heights step at its
/// edge, half a posting past its last posts, and round the hole: cells
/// across the step are not proved by a plane and are worked out to the
/// bound (they were up to 4 px off, the bound said missed).
#[test]
fn a_height_the_dem_policy_gives_is_within_the_bound_at_every_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h) = (1200, 800);
    let (sc, g) = digital_over_hills(d, (w, h));
    let (gw, gh, gt) = (g.width as u32, g.height as u32, g.transform);
    // The west half, and the whole with a hole in the middle.
    let half = d.join("half.tif");
    f32_raster(&half, (gw / 2, gh), (gt[0], gt[3], gt[1], 32631), |c, r| g.sample(c as usize, r as usize));
    let holed = d.join("holed.tif");
    let hole = |c: u32, r: u32| c.abs_diff(gw / 2) < 6 && r.abs_diff(gh / 2) < 6;
    f32_raster(&holed, (gw, gh), (gt[0], gt[3], gt[1], 32631), |c, r| if hole(c, r) { f32::NAN } else { g.sample(c as usize, r as usize) });
    // A height within a few metres of the DEM's own where it stops.
    let mut edge: Vec<f32> = (0..gh).map(|r| g.sample((gw / 2 - 1) as usize, r as usize)).collect();
    edge.sort_by(f32::total_cmp);
    let near = format!("{:.1}", edge[edge.len() / 2] + 3.0);
    for (dem, flag) in [(&half, "--dem-outside"), (&holed, "--dem-hole")] {
        let (default, report) = rectify_coords_on(d, &sc, dem, (w, h), "default.tif", &[flag, &near]);
        let (exact, _) = rectify_coords_on(d, &sc, dem, (w, h), "exact.tif", &[flag, &near, "--sparsity", "1", "--corrections", "cell", "--memory", "1G"]);
        let m = coordinate_map_difference(&default, &exact, w, h);
        eprintln!("{flag} {near}: {} px, max {:.4} px", m.pixels, m.max);
        assert!(m.pixels > 300_000, "{} px compared", m.pixels);
        assert!(m.max <= 0.1, "{flag} {near}: max {} px", m.max);
        assert_eq!(report["error_within"], true, "{}", report["accuracy_estimate"]);
    }
}

/// A DSM cut to its data, as OpenDroneMap writes it: nodata all round,
/// joined to the raster's edge. That collar is outside the DEM (the
/// `--dem-outside` default: nodata), not a hole: the defaults run, the
/// pixels over the data are the full DEM's to the bound, those over the
/// collar empty. A hole inside the data is still a hole (an error).
#[test]
fn a_dsm_cut_to_its_data_runs_at_the_defaults_and_a_hole_inside_is_still_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h) = (1200, 800);
    let (sc, g) = digital_over_hills(d, (w, h));
    let (gw, gh, gt) = (g.width as u32, g.height as u32, g.transform);
    // A ragged edge across the footprint, as a DSM's data ends.
    let edge = |r: u32| gw as f64 * 0.55 + 6.0 * (r as f64 / 5.0).sin();
    let cut = d.join("cut.tif");
    f32_raster(&cut, (gw, gh), (gt[0], gt[3], gt[1], 32631), |c, r| if c as f64 > edge(r) { f32::NAN } else { g.sample(c as usize, r as usize) });
    let full = rectify_coords_on(d, &sc, &sc.dem, (w, h), "full.tif", &[]).0;
    // On the full run's grid (the automatic one stops where the data does).
    let (cut_out, report) = rectify_coords_on(d, &sc, &cut, (w, h), "cut_out.tif", &["--like", s(&full)]);
    let m = coordinate_map_difference(&cut_out, &full, w, h);
    assert!(m.pixels > 200_000, "{} px compared", m.pixels);
    assert!(m.max <= 0.1, "max {} px", m.max);
    assert_eq!(report["error_within"], true, "{}", report["accuracy_estimate"]);
    let filled = |p: &Path| read_f32(p).3.iter().filter(|&&v| v != -1.0).count();
    let (on_cut, on_full) = (filled(&cut_out), filled(&full));
    assert!(on_cut < on_full * 9 / 10 && on_cut > on_full / 3, "{on_cut} px with a value on the cut DSM, {on_full} on the whole");
    // A hole inside the data, under the footprint: still refused by default.
    let holed = d.join("holed.tif");
    // Under the west half of the image (the full run's grid).
    let info = gcm_ortho::io::source::SourceImage::open(&full, 1 << 20).unwrap().info;
    let ft = info.georef.unwrap().transform;
    let (hx, hy) = (ft[0] + ft[1] * info.width as f64 * 0.3, ft[3] + ft[5] * info.height as f64 * 0.5);
    let (hc, hr) = (((hx - gt[0]) / gt[1]) as u32, ((hy - gt[3]) / gt[5]) as u32);
    assert!((hc as f64) < edge(hr) - 10.0, "the hole inside the data");
    let hole = |c: u32, r: u32| c.abs_diff(hc) < 4 && r.abs_diff(hr) < 4;
    f32_raster(
        &holed,
        (gw, gh),
        (gt[0], gt[3], gt[1], 32631),
        |c, r| {
            if c as f64 > edge(r) || hole(c, r) {
                f32::NAN
            } else {
                g.sample(c as usize, r as usize)
            }
        },
    );
    let out = d.join("holed_out.tif");
    let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&holed), "--quiet", "-o", s(&out)]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("hole"), "{err}");
    assert!(!out.exists());
}

#[test]
fn the_old_defaults_missed_on_these_scenes() {
    // What the bound is for: the same drone scene with a fixed spacing of 16
    // and no bound is pixels off (it would pass the tests above otherwise).
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (600, 400);
    let sc = drone_scene(dir.path(), (w, h), 12_000.0);
    let (k16, _) = rectify_coords(dir.path(), &sc, (w, h), "k16.tif", &["--sparsity", "16"]);
    let (exact, _) = rectify_coords(dir.path(), &sc, (w, h), "exact.tif", &["--sparsity", "1", "--corrections", "cell", "--memory", "1G"]);
    let m = coordinate_map_difference(&k16, &exact, w, h);
    assert!(m.max > 1.0, "max {} px", m.max);
}

#[test]
fn dem_voids_without_a_nodata_tag_are_holes_with_a_warning_not_heights() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini");
    let dem = gcm_ortho::dem::GridDem::read(&root.join("dem.tif")).unwrap();
    // The mini DEM with three voids of -32768 and no nodata tag.
    let voids = [(30usize, 40usize), (50, 50), (61, 33)];
    let path = d.join("voids.tif");
    let georef = (dem.transform[0], dem.transform[3], dem.transform[1], 32631);
    f32_raster(&path, (dem.width as u32, dem.height as u32), georef, |i, j| {
        let (i, j) = (i as usize, j as usize);
        if voids.contains(&(i, j)) {
            -32768.0
        } else {
            dem.sample(i, j)
        }
    });
    let out = d.join("o.tif");
    let r = run(&[
        "rectify",
        "--image",
        s(&root.join("scan.tif")),
        "--camera",
        s(&root.join("camera.toml")),
        "--dem",
        s(&path),
        "--dem-hole",
        "nodata",
        "--quiet",
        "-o",
        s(&out),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{err}");
    assert!(err.contains("warning") && err.contains("voids.tif") && err.contains("-32768") && err.contains("no nodata tag"), "{err}");
}

/// A void under the middle of the image (no point of its edge meets it),
/// left empty under `--dem-hole nodata`: said, with about how much of the
/// ground it takes; a DEM without one draws no such warning.
#[test]
fn a_void_under_the_middle_of_the_image_is_said_with_its_share() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini");
    let dem = gcm_ortho::dem::GridDem::read(&root.join("dem.tif")).unwrap();
    let georef = (dem.transform[0], dem.transform[3], dem.transform[1], 32631);
    let (cw, ch) = (dem.width, dem.height);
    // A fifth of the DEM across and down, in its middle.
    let void = |i: usize, j: usize| (2 * cw / 5..3 * cw / 5).contains(&i) && (2 * ch / 5..3 * ch / 5).contains(&j);
    let rectify = |name: &str, holed: bool| {
        let path = d.join(name);
        f32_raster(
            &path,
            (cw as u32, ch as u32),
            georef,
            |i, j| if holed && void(i as usize, j as usize) { f32::NAN } else { dem.sample(i as usize, j as usize) },
        );
        let (scan, camera, out) = (root.join("scan.tif"), root.join("camera.toml"), d.join(format!("{name}.out.tif")));
        let r = run(&["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&path), "--dem-hole", "nodata", "--quiet", "-o", s(&out)]);
        let err = String::from_utf8_lossy(&r.stderr).to_string();
        assert!(r.status.success(), "{err}");
        err
    };
    let err = rectify("void.tif", true);
    let share: f64 =
        err.split("under about ").nth(1).and_then(|t| t.split(" %").next()).and_then(|v| v.parse().ok()).unwrap_or_else(|| panic!("no share said: {err}"));
    assert!(err.contains("void.tif") && err.contains("inside its edges") && (1.0..=20.0).contains(&share), "{err}");
    let err = rectify("whole.tif", false);
    assert!(!err.contains("no heights"), "{err}");
}

#[test]
fn an_unbounded_run_far_off_the_exact_model_says_so_even_when_quiet() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini");
    let json = dir.path().join("r.json");
    let (scan, camera, dem, out) = (root.join("scan.tif"), root.join("camera.toml"), root.join("dem.tif"), dir.path().join("o.tif"));
    let base = ["rectify", "--image", s(&scan), "--camera", s(&camera), "--dem", s(&dem), "--quiet"];
    let with = |extra: &[&str]| {
        let mut a = base.to_vec();
        a.extend_from_slice(extra);
        a.extend(["-o", s(&out), "--json", s(&json)]);
        let r = run(&a);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        (String::from_utf8_lossy(&r.stderr).into_owned(), report)
    };
    // A fixed spacing of 64 px: no bound, well over half a pixel off.
    let (err, report) = with(&["--sparsity", "64"]);
    assert!(err.contains("warning") && err.contains("off the exact model") && err.contains("--max-error"), "{err}");
    assert_eq!((report["error_bound"].clone(), report["error_within"].clone()), (serde_json::Value::Null, false.into()));
    assert_eq!(report["warnings"].as_array().unwrap().len(), 1);
    // The default: bounded, held, nothing to say.
    let (err, report) = with(&[]);
    assert!(err.is_empty(), "{err}");
    assert_eq!((report["error_bound"].as_f64(), report["error_within"].as_bool()), (Some(0.1), Some(true)));
}

#[test]
fn a_film_scans_margin_is_masked_to_its_format() {
    use gcm_ortho::camera::file::Camera;
    let dir = tempfile::tempdir().unwrap();
    let w = 800;
    // Marks at ±117.5 mm: the 23 cm format, ±115 mm, the scan reaching
    // past it into the film's margin.
    let sc = scene(&dir.path().join("scene"), w, |o| o.kappa_deg = 12.0);
    let area = Camera::read(&sc.camera).unwrap().model().image_area().expect("a film camera has a format");
    // The same camera with the whole scan as image.
    let whole = dir.path().join("whole.toml");
    let text = std::fs::read_to_string(&sc.camera).unwrap().replace("[interior]\n", "[interior]\nformat_mm = \"scan\"\n");
    std::fs::write(&whole, text).unwrap();
    assert!(Camera::read(&whole).unwrap().model().image_area().is_none());
    let unmasked = gcm_ortho::synth::SynthReport { camera: whole, ..sc.clone() };
    // The unmasked run's grid for both, so that they compare pixel by pixel.
    let (open, report) = rectify_coords(dir.path(), &unmasked, (w, w), "whole.tif", &[]);
    let g = &report["grid"];
    let (x0, y0, gsd) = (g["x0"].as_f64().unwrap(), g["y0"].as_f64().unwrap(), g["gsd"].as_f64().unwrap());
    let (gw, gh) = (g["width"].as_f64().unwrap(), g["height"].as_f64().unwrap());
    // (a quarter pixel inside: snapped outward, they give the same grid)
    let q = gsd / 4.0;
    let bounds = format!("{},{},{},{}", x0 + q, y0 - gh * gsd + q, x0 + gw * gsd - q, y0 - q);
    let gsd = gsd.to_string();
    let (masked, _) = rectify_coords(dir.path(), &sc, (w, w), "masked.tif", &["--bounds", &bounds, "--gsd", &gsd]);
    let ((_, _, _, m), (_, _, _, o)) = (read_f32(&masked), read_f32(&open));
    // Positions a hundredth of a pixel inside or outside the format (the
    // coordinate image's Float32 rounding), by the corners' mean.
    let corners = area.corners();
    let centre = corners.iter().fold((0.0, 0.0), |a, c| (a.0 + c.0 / 4.0, a.1 + c.1 / 4.0));
    let nudged = |c: f64, r: f64, by: f64| {
        let (dc, dr) = (centre.0 - c, centre.1 - r);
        let d = dc.hypot(dr).max(1e-9);
        (c + by * dc / d, r + by * dr / d)
    };
    let (mut kept, mut cut, mut near_edge) = (0, 0, [false; 4]);
    for k in 0..m.len() / 2 {
        let (mc, mr, oc, or) = (m[2 * k] as f64, m[2 * k + 1] as f64, o[2 * k] as f64, o[2 * k + 1] as f64);
        if mc != -1.0 {
            // A masked pixel's value comes from inside the format ...
            let (c, r) = nudged(mc, mr, 0.01);
            assert!(area.contains(c, r), "({mc}, {mr}) lies outside the format");
            assert_eq!((mc, mr), (oc, or), "the mask changes no position");
            kept += 1;
            for (e, near) in near_edge.iter_mut().enumerate() {
                let (p, q) = (corners[e], corners[(e + 1) % 4]);
                let (ex, ey) = (q.0 - p.0, q.1 - p.1);
                let dist = ((mc - p.0) * ey - (mr - p.1) * ex).abs() / ex.hypot(ey);
                *near |= dist < 1.5;
            }
        } else if oc != -1.0 {
            // ... and only the margin's pixels are cut.
            let (c, r) = nudged(oc, or, -0.01);
            assert!(!area.contains(c, r), "({oc}, {or}) is inside the format but masked");
            cut += 1;
        }
    }
    assert!(kept > 300_000 && cut > 5_000, "{kept} kept, {cut} cut");
    assert_eq!(near_edge, [true; 4], "image reaches every edge of the format");
    // Floating-point samples: by default the holes are NaN, a value no
    // data holds, and tagged so.
    let nan = dir.path().join("nan.tif");
    let r = run(&["rectify", "--image", s(&dir.path().join("coords.tif")), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(&nan)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let info = gcm_ortho::io::source::SourceImage::open(&nan, 1 << 20).unwrap().info;
    assert!(info.georef.unwrap().nodata.is_some_and(f64::is_nan) && info.mask.is_none());
    let (_, _, _, v) = read_f32(&nan);
    let holes = v.chunks_exact(2).filter(|p| p[0].is_nan()).count();
    assert!(holes > 5_000 && v.chunks_exact(2).all(|p| p[0].is_nan() == p[1].is_nan() && (p[0].is_nan() || p[0] >= 0.0)), "{holes} holes");
}

/// An oblique drone frame whose centre looks at a building's wall in the
/// DSM (no single ground point there): the default GSD is taken on the
/// plane at the height the ray met, not refused ("the scan's centre does
/// not meet the DEM" before), and the error bound holds.
#[test]
fn an_oblique_frame_looking_at_a_wall_gets_its_default_gsd() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let out = common::run(&[
        "synth",
        "--out",
        common::s(d),
        "--camera",
        "drone",
        "--relief",
        "urban",
        "--size",
        "2000x1500",
        "--dem-posting",
        "0.8",
        "--scale",
        "19000",
        "--off-nadir",
        "25",
        "--kappa",
        "17",
        "--block",
        "1x2",
        "--quiet",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json = d.join("r.json");
    let out = common::run(&[
        "rectify",
        "--image",
        common::s(&d.join("scans/002.tif")),
        "--camera",
        common::s(&d.join("scans/002.toml")),
        "--dem",
        common::s(&d.join("dem.tif")),
        "-o",
        common::s(&d.join("o.tif")),
        "--json",
        common::s(&json),
        "--quiet",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
    let gsd = r["grid"]["gsd"].as_f64().unwrap();
    // 13.2 mm / 2000 px at 8.8 mm from ~167 m, looking 25° down-forward.
    assert!((0.12..0.16).contains(&gsd), "{gsd}");
    assert_eq!(r["error_within"], true);
}

/// The error bound holds with OpenCV's full model (fx ≠ fy, rational and
/// thin-prism terms) and with a fisheye lens, whose distortion reaches
/// tens of pixels at the corners: the drone over buildings again.
#[test]
fn opencv_and_fisheye_lenses_are_within_the_bound_at_every_pixel() {
    let lenses = [
        ("opencv", "pixel_size_mm = [0.0146, 0.0149]", "[distortion.opencv]\nk1 = -0.11\nk2 = 0.035\nk3 = -0.004\nk4 = 0.02\nk5 = -0.005\nk6 = 0.012\np1 = 4e-4\np2 = -2.5e-4\ns1 = 1.5e-3\ns2 = -1.6e-3\ns3 = -1.1e-3\ns4 = 1.4e-3\n"),
        ("fisheye", "pixel_size_mm = 0.014666666666666666", "[distortion.fisheye]\nk1 = 0.052\nk2 = -0.013\nk3 = 0.0021\nk4 = -3e-4\n"),
    ];
    for (name, pixel, lens) in lenses {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (900, 600);
        let mut sc = drone_scene(dir.path(), (w, h), 18_000.0);
        let text = std::fs::read_to_string(&sc.camera).unwrap();
        let start = text.find("[distortion.brown]").unwrap();
        let end = text.find("[exterior]").unwrap();
        let text = format!("{}{lens}\n{}", &text[..start], &text[end..]).replace("pixel_size_mm = 0.014666666666666666", pixel);
        sc.camera = dir.path().join(format!("{name}.toml"));
        std::fs::write(&sc.camera, text).unwrap();
        let (m, _) = default_against_exact(dir.path(), &sc, w, h);
        eprintln!("{name}: {} px, max {:.4} px, mean {:.5} px", m.pixels, m.max, m.mean);
        assert!(m.pixels > 200_000, "{name}: {} px compared", m.pixels);
        assert!(m.max <= 0.1, "{name}: max {} px", m.max);
    }
}

#[test]
fn the_default_extent_holds_every_ground_point_the_frame_sees_over_buildings() {
    // An oblique frame over buildings: its edge rays pass walls and meet
    // the streets behind them farther out (or, on the side of its nadir,
    // roofs nearer), and each of those ground points is imaged. A run on
    // bounds 40 px wider finds no pixel with a value outside the default
    // grid (a footprint from each edge ray's first ground point alone, 32
    // an edge, left 1 586 of them out here).
    let dir = tempfile::tempdir().unwrap();
    // synth's drone frame over buildings as it comes (1200×900 px).
    let (w, h) = (1200, 900);
    let out = dir.path().join("scene");
    let r = run(&["synth", "--out", s(&out), "--camera", "drone", "--relief", "urban", "--size", "1200x900", "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    // What rectify_coords reads of it: the camera and the DEM.
    let sc = gcm_ortho::synth::SynthReport {
        scan: out.join("scan.tif"),
        camera: out.join("camera.toml"),
        dem: out.join("dem.tif"),
        truth: None,
        checkpoints: out.join("checkpoints.csv"),
        gsd: 0.0,
        flying_height: 0.0,
        relief_range: [0.0; 2],
        max_slope_deg: 0.0,
    };
    let (_, report) = rectify_coords(dir.path(), &sc, (w, h), "default.tif", &[]);
    let g = &report["grid"];
    let (x0, y0, gsd) = (g["x0"].as_f64().unwrap(), g["y0"].as_f64().unwrap(), g["gsd"].as_f64().unwrap());
    let (dw, dh) = (g["width"].as_u64().unwrap() as i64, g["height"].as_u64().unwrap() as i64);
    let m = 40.0 * gsd;
    let bounds = format!("{},{},{},{}", x0 - m, y0 - dh as f64 * gsd - m, x0 + dw as f64 * gsd + m, y0 + m);
    let (wide, _) = rectify_coords(dir.path(), &sc, (w, h), "wide.tif", &["--bounds", &bounds, "--gsd", &gsd.to_string()]);
    let (ww, wh, bands, px) = read_f32(&wide);
    assert_eq!((ww as i64, wh as i64), (dw + 80, dh + 80));
    let inside = |x: i64, y: i64| (40..40 + dw).contains(&x) && (40..40 + dh).contains(&y);
    let outside = (0..wh as i64)
        .flat_map(|y| (0..ww as i64).map(move |x| (x, y)))
        .filter(|&(x, y)| !inside(x, y) && px[((y * ww as i64 + x) * bands as i64) as usize] != -1.0)
        .count();
    assert_eq!(outside, 0, "pixels with a value outside the default grid");
}

/// The default GSD is the scan's over its whole footprint (the ground
/// area its image covers over its pixel count), not the one under its
/// centre: a tower under the centre of a nadir frame, half as high as the
/// camera, made the default GSD half the flat ground's (ODM's frames whose
/// centre fell on a roof got pixels a third finer than their
/// neighbours'). With it, the GSD is the flat ground's to its rounding.
#[test]
fn the_default_gsd_is_the_footprints_not_the_one_under_the_centre() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h) = (1200, 800);
    let sc = scene(&d.join("scene"), w, |o| {
        o.height = h;
        o.camera = gcm_ortho::synth::CameraKind::Digital;
        o.kappa_deg = 0.0;
        o.relief = Relief::Flat;
    });
    let g = gcm_ortho::dem::GridDem::read_within(&sc.dem, u64::MAX).unwrap();
    let (gw, gh, gt) = (g.width as u32, g.height as u32, g.transform);
    let gsd_of = |dem: &Path, name: &str| -> (f64, [f64; 6], (u32, u32)) {
        let out = d.join(name);
        let json = out.with_extension("json");
        let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(dem), "--quiet", "-o", s(&out), "--json", s(&json)]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        let info = gcm_ortho::io::source::SourceImage::open(&out, 1 << 20).unwrap().info;
        (report["grid"]["gsd"].as_f64().unwrap(), info.georef.unwrap().transform, (info.width, info.height))
    };
    let (flat, ft, (ow, oh)) = gsd_of(&sc.dem, "flat.tif");
    // The flat ground's GSD is the camera's pixel over its scale.
    assert!((flat / sc.gsd - 1.0).abs() < 0.01, "{flat} against the scene's {}", sc.gsd);
    // A tower a quarter of the footprint across under its middle.
    let (cx, cy) = (ft[0] + ft[1] * ow as f64 / 2.0, ft[3] + ft[5] * oh as f64 / 2.0);
    let half = ft[1] * ow.min(oh) as f64 / 8.0;
    let ground = g.sample(0, 0);
    let top = ground + (sc.flying_height / 2.0) as f32;
    let tower = d.join("tower.tif");
    f32_raster(&tower, (gw, gh), (gt[0], gt[3], gt[1], 32631), |c, r| {
        let (x, y) = (gt[0] + (c as f64 + 0.5) * gt[1], gt[3] + (r as f64 + 0.5) * gt[5]);
        if (x - cx).abs() < half && (y - cy).abs() < half {
            top
        } else {
            ground
        }
    });
    let (on_tower, _, _) = gsd_of(&tower, "tower_out.tif");
    assert!((on_tower / flat - 1.0).abs() < 0.005, "{on_tower} with the tower against {flat} without");
}

/// ODM's DSM is cut to its data, a nodata collar round it: where the
/// collar takes a side of the frame's footprint and the data bulges into
/// it, the default extent holds every pixel the DEM gives heights for
/// (the hits on the footprint's outline alone bound it short of the
/// bulge: a frame lost 1.9 % of its ground).
#[test]
fn the_default_extent_holds_the_data_that_bulges_into_a_dsms_collar() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (w, h) = (1200, 800);
    let (sc, g) = digital_over_hills(d, (w, h));
    let (gw, gh, gt) = (g.width as u32, g.height as u32, g.transform);
    let full = rectify_coords_on(d, &sc, &sc.dem, (w, h), "full.tif", &[]).0;
    let info = gcm_ortho::io::source::SourceImage::open(&full, 1 << 20).unwrap().info;
    let ft = info.georef.unwrap().transform;
    let (fw, fh) = (ft[1] * info.width as f64, -ft[5] * info.height as f64);
    // The collar takes the footprint's east quarter, and the data bulges
    // into it by a tenth of the footprint's width at its middle.
    let (x_edge, y_mid) = (ft[0] + 0.75 * fw, ft[3] - 0.5 * fh);
    let data_ends = |y: f64| x_edge + 0.1 * fw * (1.0 - ((y - y_mid) / (0.5 * fh)).powi(2)).max(0.0);
    let cut = d.join("cut.tif");
    f32_raster(&cut, (gw, gh), (gt[0], gt[3], gt[1], 32631), |c, r| {
        let (x, y) = (gt[0] + (c as f64 + 0.5) * gt[1], gt[3] + (r as f64 + 0.5) * gt[5]);
        if x > data_ends(y) {
            f32::NAN
        } else {
            g.sample(c as usize, r as usize)
        }
    });
    let (default, _) = rectify_coords_on(d, &sc, &cut, (w, h), "default.tif", &[]);
    let (whole, _) = rectify_coords_on(d, &sc, &cut, (w, h), "whole.tif", &["--like", s(&full)]);
    let di = gcm_ortho::io::source::SourceImage::open(&default, 1 << 20).unwrap().info;
    let dt = di.georef.unwrap().transform;
    let (dx1, dy0) = (dt[0] + dt[1] * di.width as f64, dt[3] + dt[5] * di.height as f64);
    let (ww, _, bands, values) = read_f32(&whole);
    let (mut valued, mut outside) = (0usize, 0usize);
    for (k, v) in values.chunks_exact(bands as usize).enumerate() {
        if v[0] == -1.0 {
            continue;
        }
        valued += 1;
        let (x, y) = (ft[0] + ((k as u32 % ww) as f64 + 0.5) * ft[1], ft[3] + ((k as u32 / ww) as f64 + 0.5) * ft[5]);
        if x > dx1 || x < dt[0] || y < dy0 || y > dt[3] {
            outside += 1;
        }
    }
    assert!(valued > 100_000, "{valued} px with a value");
    assert_eq!(outside, 0, "of {valued} px with a value on the whole footprint's grid, {outside} lie outside the default extent");
}
