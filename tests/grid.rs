//! The output grid users ask for: bounds kept exactly where they are
//! multiples of the GSD, or as given (`--snap`), and the grid of a
//! reference raster (`--like`), pixel for pixel.

mod common;
use common::*;
use std::path::Path;

/// The orthophoto's geotransform and size, as our reader and GDAL's see it.
fn grid_of(path: &Path) -> ([f64; 6], u32, u32) {
    let info = gcm_ortho::io::source::SourceImage::open(path, 1 << 20).unwrap().info;
    (info.georef.unwrap().transform, info.width, info.height)
}

/// A Float32 raster of `w`×`h` with geotransform `gt` in `epsg`.
fn reference(path: &Path, gt: [f64; 6], w: u32, h: u32, epsg: u32) {
    assert!(gt[5] == -gt[1], "this writer makes square pixels");
    f32_raster(path, (w, h), (gt[0], gt[3], gt[1], epsg), |_, _| 0.0);
}

#[test]
fn bounds_on_multiples_of_the_gsd_are_kept_and_others_as_asked() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 400, |_| {});
    let run_with = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut a = vec!["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(&out)];
        a.extend_from_slice(extra);
        let r = run(&a);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        grid_of(&out)
    };
    // 4890039.8 / 0.2 is 24450198.999999996 in binary: one row too many before.
    let b = "649546.4,4890039.8,649848.8,4890224.4";
    let (gt, w, h) = run_with("tap.tif", &["--bounds", b, "--gsd", "0.2"]);
    assert_eq!((w, h), (1512, 923));
    assert!((gt[0] - 649546.4).abs() < 1e-6 && (gt[3] - 4890224.4).abs() < 1e-6, "{gt:?}");
    // Not multiples of 3 m: aligned outward by default; kept with --snap none.
    let b = "649546.4,4890039.8,649848.8,4890224.4";
    let (gt, w, h) = run_with("tap3.tif", &["--bounds", b, "--gsd", "3"]);
    assert_eq!((gt[0], gt[3], w, h), (649545.0, 4890225.0, 102, 62));
    let (gt, w, h) = run_with("none3.tif", &["--bounds", b, "--gsd", "3", "--snap", "none"]);
    assert_eq!((gt[0], gt[3], w, h), (649546.4, 4890224.4, 101, 62));
    let (gt, w, h) = run_with("out3.tif", &["--bounds", b, "--gsd", "3", "--snap", "outward"]);
    assert_eq!((gt[0], gt[3], w, h), (649546.4, 4890224.4, 101, 62));
}

#[test]
fn like_takes_a_reference_rasters_grid_pixel_for_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("scene"), 400, |_| {});
    // An origin on no multiple of the pixel size, an odd size.
    let gt = [649321.37, 1.7, 0.0, 4891103.91, 0.0, -1.7];
    let like = d.join("ref.tif");
    reference(&like, gt, 517, 389, 32631);
    let out = d.join("o.tif");
    let base = ["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(&out)];
    let r = run(&[&base[..], &["--like", s(&like)]].concat());
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(grid_of(&out), (gt, 517, 389));
    if have("gdalinfo") {
        let j: serde_json::Value = serde_json::from_slice(&std::process::Command::new("gdalinfo").args(["-json", s(&out)]).output().unwrap().stdout).unwrap();
        assert_eq!(j["geoTransform"], serde_json::json!(gt));
        assert_eq!(j["size"], serde_json::json!([517, 389]));
    }
    // A grid in another CRS than the camera's (the same place in UTM 32N):
    // the orthophoto is made in that CRS; against another --crs, refused
    // by name; with --gsd, refused.
    let (u31, u32) = (gcm_ortho::geodesy::GroundCrs::from_epsg(32631).unwrap(), gcm_ortho::geodesy::GroundCrs::from_epsg(32632).unwrap());
    let (lon, lat) = u31.to_lonlat(gt[0], gt[3]).unwrap();
    let (x, y) = u32.lonlat_to_ground(lon, lat).unwrap();
    let gt32 = [x.round(), 1.7, 0.0, y.round(), 0.0, -1.7];
    let other = d.join("other.tif");
    reference(&other, gt32, 517, 389, 32632);
    let out32 = d.join("o32.tif");
    let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(&out32), "--like", s(&other)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(grid_of(&out32), (gt32, 517, 389));
    let keys = whole_image(&out32).1.georef.unwrap().keys;
    assert_eq!(gcm_ortho::geodesy::geokeys::crs_of(&keys).unwrap().and_then(|c| c.epsg()), Some(32632));
    let r = run(&[&base[..], &["--like", s(&other), "--crs", "EPSG:32631"]].concat());
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(err.contains("--crs") && err.contains("other.tif") && err.contains("EPSG:32632"), "{err}");
    let r = run(&[&base[..], &["--like", s(&like), "--gsd", "2"]].concat());
    assert_eq!(r.status.code(), Some(2));
    // --snap places bounds; with a reference grid it is refused, not ignored.
    for snap in ["none", "tap"] {
        let r = run(&[&base[..], &["--like", s(&like), "--snap", snap]].concat());
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.code() == Some(2) && err.contains("--snap"), "{snap}: {err}");
    }
    // A GDAL VRT as the reference (its sources are not needed): the same grid.
    let vrt = d.join("ref.vrt");
    let wkt = r#"PROJCS["WGS 84 / UTM zone 31N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",0],PARAMETER["central_meridian",3],PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",500000],PARAMETER["false_northing",0],UNIT["metre",1],AUTHORITY["EPSG","32631"]]"#;
    std::fs::write(
        &vrt,
        format!(
            "<VRTDataset rasterXSize=\"517\" rasterYSize=\"389\">\n  <SRS dataAxisToSRSAxisMapping=\"1,2\">{}</SRS>\n  <GeoTransform> {}, {}, 0.0, {}, 0.0, {}</GeoTransform>\n  <VRTRasterBand dataType=\"Float32\" band=\"1\"><SimpleSource><SourceFilename relativeToVRT=\"1\">gone.tif</SourceFilename></SimpleSource></VRTRasterBand>\n</VRTDataset>\n",
            wkt.replace('"', "&quot;"),
            gt[0],
            gt[1],
            gt[3],
            gt[5]
        ),
    )
    .unwrap();
    let out_vrt = d.join("o_vrt.tif");
    let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(&out_vrt), "--like", s(&vrt)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(grid_of(&out_vrt), (gt, 517, 389));
    assert!(whole_image(&out_vrt).0 == whole_image(&out).0, "the VRT's grid gives the TIFF's orthophoto");
    // The same in a batch manifest, relative to it.
    let m = d.join("block.toml");
    let job = "[[job]]\nimage = \"scene/scan.tif\"\ncamera = \"scene/camera.toml\"\ndem = \"scene/dem.tif\"\nlike = \"ref.tif\"\noutput = \"b.tif\"\n";
    std::fs::write(&m, job).unwrap();
    let r = run(&["batch", s(&m), "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(grid_of(&d.join("b.tif")), (gt, 517, 389));
}

#[test]
fn non_square_pixels_sample_where_their_centres_lie() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("scene"), 400, |_| {});
    let coords = d.join("coords.tif");
    coordinate_image(&coords, 400, 400);
    let rectify = |name: &str, extra: &[&str]| {
        let out = d.join(name);
        let mut a = vec!["rectify", "--image", s(&coords), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(&out)];
        a.extend_from_slice(extra);
        let r = run(&a);
        assert!(r.status.success(), "{name}: {}", String::from_utf8_lossy(&r.stderr));
        out
    };
    // Inside the scene's footprint: the middle half of its default grid.
    let (gt, w, h) = grid_of(&rectify("default.tif", &[]));
    let (x0, y0) = ((gt[0] + gt[1] * w as f64 / 4.0).round(), (gt[3] + gt[5] * h as f64 / 4.0).round());
    let (cols, rows) = ((gt[1] * w as f64 / 2.0 / 2.0) as u32, (gt[1] * h as f64 / 2.0 / 3.0) as u32);
    let bounds = format!("{x0},{},{},{y0}", y0 - 3.0 * rows as f64, x0 + 2.0 * cols as f64);
    let ns = rectify("ns.tif", &["--gsd", "2,3", "--bounds", &bounds, "--snap", "none"]);
    let want = [x0, 2.0, 0.0, y0, 0.0, -3.0];
    assert_eq!(grid_of(&ns), (want, cols, rows));
    if have("gdalinfo") || std::env::var_os("CI").is_some() {
        let j: serde_json::Value = serde_json::from_slice(&std::process::Command::new("gdalinfo").args(["-json", s(&ns)]).output().unwrap().stdout).unwrap();
        assert_eq!(j["geoTransform"], serde_json::json!(want), "GDAL reads the pixel size as written");
        assert_eq!(j["size"], serde_json::json!([cols, rows]));
    }
    // A side absurdly small: refused by name, nothing written.
    let r = run(&["rectify", "--image", s(&coords), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--gsd", "1e-7,3", "-o", s(&d.join("absurd.tif"))]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.code() == Some(2) && err.contains("--gsd"), "{err}");
    assert!(!d.join("absurd.tif").exists());
    // Its grid reproduced by --like, non-square pixels included.
    assert_eq!(grid_of(&rectify("like.tif", &["--like", s(&ns)])), (want, cols, rows));
    // A square 1 m grid whose pixel centres include every 2 × 3 m pixel's
    // centre: (x0 + 2c + 1, y0 − 3r − 1.5) is its pixel (2c, 3r).
    let fine = format!("{},{},{},{}", x0 + 0.5, y0 - 1.0 - 3.0 * rows as f64, x0 + 0.5 + 2.0 * cols as f64, y0 - 1.0);
    let sq = rectify("sq.tif", &["--gsd", "1", "--bounds", &fine, "--snap", "none"]);
    let (a, b) = (read_f32(&ns), read_f32(&sq));
    let (fw, _, _, fine_px) = (b.0, b.1, b.2, b.3);
    let (mut worst, mut valued) = (0f32, 0usize);
    for r in 0..rows as usize {
        for c in 0..cols as usize {
            let p = &a.3[2 * (r * cols as usize + c)..][..2];
            let q = &fine_px[2 * (3 * r * fw as usize + 2 * c)..][..2];
            assert_eq!(p[0].is_nan(), q[0].is_nan(), "({c}, {r}) valued in one grid only");
            if !p[0].is_nan() {
                valued += 1;
                worst = worst.max((p[0] - q[0]).abs()).max((p[1] - q[1]).abs());
            }
        }
    }
    assert!(valued > (cols * rows) as usize * 9 / 10, "{valued}");
    // Each within the 0.1 px bound of the exact model.
    assert!(worst < 0.2, "{worst} scan px apart");
    println!("2 × 3 m pixels against their centres on a 1 m grid: {valued} px, max {worst:.4} scan px apart");
}

#[test]
fn a_manifest_takes_non_square_pixels_as_a_pair() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = scene(&d.join("scene"), 300, |_| {});
    let manifest = d.join("m.toml");
    let job = format!("[[job]]\nimage = {:?}\ncamera = {:?}\noutput = \"o.tif\"\n", s(&sc.scan), s(&sc.camera));
    std::fs::write(&manifest, format!("[defaults]\ndem = {:?}\ngsd = [2.0, 3.0]\nresample = \"average\"\n\n{job}", s(&sc.dem))).unwrap();
    let r = run(&["batch", s(&manifest), "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let (gt, _, _) = grid_of(&d.join("o.tif"));
    assert_eq!((gt[1], gt[5]), (2.0, -3.0));
    // A third number is no pixel size: refused, naming the line.
    std::fs::write(&manifest, format!("[defaults]\ndem = {:?}\ngsd = [2.0, 3.0, 4.0]\n\n{job}", s(&sc.dem))).unwrap();
    let r = run(&["batch", s(&manifest), "--quiet", "--force"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("line 3") && err.contains("[x, y]"), "{err}");
}

#[test]
fn a_mosaic_lands_on_a_reference_grid() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let block = d.join("block");
    let r = run(&["synth", "--out", s(&block), "--camera", "digital", "--size", "600x400", "--block", "2x1", "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let manifest = block.join("manifest.toml");
    let first = d.join("first.tif");
    let r = run(&["mosaic", s(&manifest), "-o", s(&first), "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    // Inside the block: an origin on no multiple of its pixel size, other
    // pixels, an odd size.
    let (gt, w, h) = grid_of(&first);
    let want = [gt[0] + 7.31, 1.37, 0.0, gt[3] - 5.19, 0.0, -1.37];
    let (rw, rh) = ((w as f64 * gt[1] / 1.37 * 0.8) as u32 | 1, (h as f64 * gt[1] / 1.37 * 0.8) as u32 | 1);
    let like = d.join("ref.tif");
    reference(&like, want, rw, rh, 32631);
    let out = d.join("like.tif");
    let r = run(&["mosaic", s(&manifest), "-o", s(&out), "--like", s(&like), "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(grid_of(&out), (want, rw, rh));
    // With --gsd: refused.
    let r = run(&["mosaic", s(&manifest), "-o", s(&d.join("x.tif")), "--like", s(&like), "--gsd", "2"]);
    assert_eq!(r.status.code(), Some(2), "{}", String::from_utf8_lossy(&r.stderr));
}

/// The default grid follows what `--dem-outside` says of the ground past
/// the DEM: cut to the DEM (`nodata`); the whole footprint, past the DEM
/// on the plane at the given height (`HEIGHT`); refused, naming the DEM
/// and the image, nothing written (`error`: heights under all of it).
#[test]
fn the_default_grid_follows_what_dem_outside_says_of_the_ground_past_the_dem() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 400, |_| {});
    // The DEM's middle half each way: the scan sees past it on every side.
    let g = gcm_ortho::dem::GridDem::read(&sc.dem).unwrap();
    let keys = gcm_ortho::io::source::SourceImage::info_of(&sc.dem).unwrap().georef.unwrap().keys;
    let (i0, j0, w, h) = (g.width / 4, g.height / 4, g.width / 2, g.height / 2);
    let gt = g.transform;
    let mid = g.sample(g.width / 2, g.height / 2);
    let cropped = dir.path().join("dem_middle.tif");
    f32_raster_with_keys(&cropped, (w as u32, h as u32), (gt[0] + i0 as f64 * gt[1], gt[3] + j0 as f64 * gt[5], gt[1]), keys.clone(), |c, r| {
        g.sample(i0 + c as usize, j0 + r as usize)
    });
    let dem_box = gcm_ortho::dem::GridDem::read(&cropped).unwrap().bounds();
    // Rectified on `dem` under `--dem-outside outside` into `name`.
    let rectify_with = |dem: &Path, name: &str, outside: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let args = ["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(dem), "--dem-outside", outside, "--quiet", "-o", s(&out)];
        (run(&[&args[..], extra].concat()), out)
    };
    let rectify_on = |dem: &Path, name: &str, outside: &str| rectify_with(dem, name, outside, &[]);
    // A DEM 100 km away meets no edge of the scan: refused, a height for
    // outside it or not (the plane does not stand in for a wrong DEM).
    let far = dir.path().join("dem_far.tif");
    f32_raster_with_keys(&far, (w as u32, h as u32), (gt[0] + 1e5, gt[3], gt[1]), keys, |_, _| mid);
    for outside in ["nodata", "300"] {
        let (r, _) = rectify_on(&far, "far.tif", outside);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.code() == Some(1) && err.contains("the DEM covers [") && err.contains("of another place?"), "--dem-outside {outside}: {err}");
    }
    let ortho_on = |dem: &Path, name: &str, outside: &str| {
        let (r, out) = rectify_on(dem, name, outside);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.success(), "--dem-outside {outside}: {err}");
        // A DEM that stops short of the scan is said (under --quiet): the
        // orthophoto stops there too, unless a height is given past it.
        let stops_short = dem == cropped.as_path() && outside.parse::<f64>().is_err();
        assert_eq!(err.contains("covers only part of the image"), stops_short, "{name}: {err}");
        let (gt, w, h) = grid_of(&out);
        let (bytes, info) = whole_image(&out);
        let valid = bytes.chunks_exact(info.pixel_bytes()).filter(|p| p.iter().any(|&v| v != 0)).count();
        ([gt[0], gt[3] + gt[5] * h as f64, gt[0] + gt[1] * w as f64, gt[3]], gt[1], valid)
    };
    let ortho = |name: &str, outside: &str| ortho_on(&cropped, name, outside);
    let (whole, _, whole_valid) = ortho_on(&sc.dem, "whole.tif", "nodata");
    let (cut, gsd, cut_valid) = ortho("nodata.tif", "nodata");
    let (wide, _, wide_valid) = ortho("height.tif", &format!("{mid}"));
    let (r, strict) = rectify_on(&cropped, "error.tif", "error");
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.lines().count() == 1 && err.contains("dem_middle.tif") && err.contains("covers only part of") && err.contains("scan.tif"), "{err}");
    assert!(!strict.exists());
    // Within bounds on the DEM, `error` runs: it asks for heights where
    // the orthophoto is, not under the whole scan.
    let inner = format!("{},{},{},{}", dem_box[0] + 20.0, dem_box[1] + 20.0, dem_box[2] - 20.0, dem_box[3] - 20.0);
    let (r, out) = rectify_with(&cropped, "error_within.tif", "error", &["--bounds", &inner]);
    assert!(r.status.success() && out.exists(), "{}", String::from_utf8_lossy(&r.stderr));
    let area = |b: [f64; 4]| (b[2] - b[0]) * (b[3] - b[1]);
    assert!(area(whole) > 1.3 * area(cut) && whole_valid as f64 > 1.05 * cut_valid as f64, "the DEM's middle cuts the footprint");
    // Past the DEM on the plane: the footprint is the scan's whole one
    // (on the whole DEM, within the plane's relief displacement), and it
    // holds image.
    for k in 0..4 {
        assert!((wide[k] - whole[k]).abs() <= 10.0 * gsd, "{wide:?} vs the whole DEM's {whole:?}");
    }
    assert!((wide_valid as f64 - whole_valid as f64).abs() < 0.02 * whole_valid as f64, "{wide_valid} vs {whole_valid} pixels");
    // Snapped outward, the cut grid reaches up to a pixel past the DEM.
    for k in 0..2 {
        assert!(cut[k] + gsd >= dem_box[k] && cut[k + 2] - gsd <= dem_box[k + 2], "{cut:?} within a pixel of {dem_box:?}");
    }
    // The same middle as heights in a DEM of the whole extent, nodata
    // around it joined to its edge (a collar, as a DSM cut to its data):
    // past the DEM, not holes in it, whatever --dem-hole says; the
    // orthophoto stops where the middle does.
    let collar = dir.path().join("dem_collar.tif");
    f32_raster_with_keys(&collar, (g.width as u32, g.height as u32), (gt[0], gt[3], gt[1]), keys_of(&sc.dem), |c, r| {
        let (c, r) = (c as usize, r as usize);
        if (i0..i0 + w).contains(&c) && (j0..j0 + h).contains(&r) {
            g.sample(c, r)
        } else {
            f32::NAN
        }
    });
    let out = dir.path().join("collar.tif");
    let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&collar), "--dem-hole", "nodata", "--quiet", "-o", s(&out)]);
    let err = String::from_utf8_lossy(&r.stderr);
    let past_edge = |err: &str| err.contains("covers only part of the image") && err.contains("dem_collar.tif") && err.contains("stops at the DEM's edge");
    assert!(r.status.success() && past_edge(&err), "{err}");
    // At the defaults the same: the collar is no hole.
    let stops = dir.path().join("stops.tif");
    let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&collar), "--quiet", "-o", s(&stops)]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success() && past_edge(&err) && !err.contains("hole"), "{err}");
    assert_eq!(grid_of(&stops), grid_of(&out));
    let (gt_c, wc, hc) = grid_of(&out);
    let on_collar = [gt_c[0], gt_c[3] + gt_c[5] * hc as f64, gt_c[0] + gt_c[1] * wc as f64, gt_c[3]];
    // (Within a few DEM posts: a point half a post from a hole has no
    // height to interpolate.)
    for k in 0..4 {
        assert!((on_collar[k] - cut[k]).abs() <= 4.0 * gt[1], "{on_collar:?} ≈ {cut:?}");
    }
}

fn keys_of(raster: &Path) -> gcm_ortho::io::geotiff::GeoKeys {
    gcm_ortho::io::source::SourceImage::info_of(raster).unwrap().georef.unwrap().keys
}
