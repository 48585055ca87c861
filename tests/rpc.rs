//! The RPC model and its readers on real files (fixtures/rpc, from the rpcm
//! and shareloc projects; see the licences there), against GDAL's RPC
//! transformer.

mod common;
use common::*;
use gcm_ortho::camera::rpc::Rpc;
use std::path::{Path, PathBuf};
use std::process::Command;

fn fx(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/rpc").join(name)
}

/// Golden values from `gdaltransform -rpc -i` (GDAL 3.6) on the Pléiades
/// GeoTIFF's RPC tag: (lon, lat, h) → (pixel, line), GDAL pixel coordinates
/// with the first pixel's centre at 0.5.
#[test]
fn geotiff_rpc_tag_matches_gdal() {
    let rpc = Rpc::from_geotiff(&fx("PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif")).unwrap();
    for ((lon, lat, h), (c, r)) in [
        ((7.18, 43.68, 670.0), (20465.1950262905, 10884.1657995612)),
        ((7.1, 43.65, 300.0), (8077.18283485928, 16910.7743255159)),
        ((7.25, 43.70, 1000.0), (31281.7116323, 6940.38433821241)),
    ] {
        let (pc, pr) = rpc.project(lon, lat, h).unwrap();
        assert!((pc - c).abs() < 1e-6 && (pr - r).abs() < 1e-6, "{pc} {pr} vs {c} {r}");
    }
}

/// Runs `gdaltransform args` with `input` on stdin: (stdout, stderr).
fn gdaltransform(args: &[&str], input: &str) -> (String, String) {
    let mut child = Command::new("gdaltransform")
        .args(args)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::io::Write::write_all(child.stdin.as_mut().unwrap(), input.as_bytes()).unwrap();
    drop(child.stdin.take());
    let out = child.wait_with_output().unwrap();
    (String::from_utf8_lossy(&out.stdout).into_owned(), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// The text readers: the file as a GDAL `_RPC.TXT` sidecar of a dummy image,
/// projected by GDAL and by us.
fn text_matches_gdal(name: &str, points: &[(f64, f64, f64)]) {
    let rpc = Rpc::read_text(&fx(name)).unwrap();
    if !have("gdaltransform") {
        eprintln!("skipped the GDAL comparison: gdaltransform not installed");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // A plain TIFF of ours (no RPC tag) with the file beside it as a sidecar.
    let plain = dir.path().join("plain.tif");
    std::fs::copy(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini/scan.tif"), &plain).unwrap();
    std::fs::copy(fx(name), dir.path().join("plain_RPC.TXT")).unwrap();
    let input: String = points.iter().map(|(a, b, c)| format!("{a} {b} {c}\n")).collect();
    let (text, err) = gdaltransform(&["-rpc", "-i", s(&plain)], &input);
    let got: Vec<Vec<f64>> = text.lines().map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect()).collect();
    assert_eq!(got.len(), points.len(), "{text} {err}");
    for (p, g) in points.iter().zip(&got) {
        let (c, r) = rpc.project(p.0, p.1, p.2).unwrap();
        assert!((c - g[0]).abs() < 1e-6 && (r - g[1]).abs() < 1e-6, "{name}: ours ({c}, {r}) GDAL ({}, {})", g[0], g[1]);
    }
}

#[test]
fn ikonos_text_matches_gdal() {
    text_matches_gdal("rpc_IKONOS.txt", &[(-56.1722, -34.903, 28.0), (-56.2, -34.88, 60.0), (-56.14, -34.95, 0.0)]);
}

#[test]
fn skysat_rpc_txt_matches_gdal() {
    text_matches_gdal("20191015_073816_ssc1d3_0011_basic_l1a_panchromatic_dn_RPC.TXT", &[(49.6688, 25.9286, 3287.0), (49.66, 25.93, 3000.0)]);
}

#[test]
fn a_crop_shifts_the_offsets() {
    let rpc = Rpc::read_text(&fx("rpc_IKONOS.txt")).unwrap();
    let crop = rpc.cropped(1000.0, 2000.0);
    let (a, b) = (rpc.project(-56.17, -34.9, 28.0).unwrap(), crop.project(-56.17, -34.9, 28.0).unwrap());
    assert!((a.0 - 1000.0 - b.0).abs() < 1e-9 && (a.1 - 2000.0 - b.1).abs() < 1e-9);
}

#[test]
fn broken_rpc_files_are_clear_errors() {
    let e = Rpc::read_text(&fx("rpc_unsupported.xml")).unwrap_err().to_string();
    assert!(e.contains("rpc_unsupported.xml"), "{e}");
    let text = std::fs::read_to_string(fx("rpc_IKONOS.txt")).unwrap();
    let cut: String = text.lines().filter(|l| !l.starts_with("SAMP_DEN_COEFF_7:")).map(|l| format!("{l}\n")).collect();
    let e = Rpc::parse_text(&cut, Path::new("cut.txt")).unwrap_err().to_string();
    assert!(e.contains("cut.txt") && e.contains("SAMP_DEN_COEFF_7") && e.contains("missing"), "{e}");
    let cut: String = text.lines().filter(|l| !l.starts_with("LAT_SCALE")).map(|l| format!("{l}\n")).collect();
    let e = Rpc::parse_text(&cut, Path::new("cut.txt")).unwrap_err().to_string();
    assert!(e.contains("LAT_SCALE missing"), "{e}");
    // A 21st coefficient: not silently dropped.
    let extra = format!("{text}\nLINE_NUM_COEFF_21: 0.5\n");
    let e = Rpc::parse_text(&extra, Path::new("extra.txt")).unwrap_err().to_string();
    assert!(e.contains("extra.txt") && e.contains("LINE_NUM_COEFF_21") && e.contains("numbered 1 to 20"), "{e}");
}

fn ventoux(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/ventoux").join(name)
}

fn close(rpc: &Rpc, p: (f64, f64, f64), want: (f64, f64), tol: f64, what: &str) {
    let (c, r) = rpc.project(p.0, p.1, p.2).unwrap();
    assert!((c - want.0).abs() < tol && (r - want.1).abs() < tol, "{what}: ({c}, {r}) vs ({}, {})", want.0, want.1);
}

/// The same Pléiades scene as an OSSIM keyword list (0-based pixels) and as
/// DIMAP XML ((1, 1) = first pixel): after the DIMAP shift both give the
/// same pixel, to the precision the .geom prints its numbers with.
#[test]
fn dimap_and_ossim_geom_of_one_scene_agree() {
    let geom = Rpc::read(&ventoux("left_image.geom")).unwrap();
    let dimap = Rpc::read(&ventoux("RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML")).unwrap();
    assert_eq!(geom.line_off, 21109.5);
    assert!((dimap.line_off - 21109.5).abs() < 1e-9 && (dimap.samp_off - 19207.5).abs() < 1e-9);
    for p in [(5.2846, 44.137, 1075.0), (5.20, 44.20, 600.0), (5.40, 44.05, 1800.0)] {
        let want = dimap.project(p.0, p.1, p.2).unwrap();
        close(&geom, p, want, 1e-6, "geom vs DIMAP");
    }
}

/// Golden values from the rpcm project's reader and model (an independent
/// implementation; its pixel centres are at 0, ours at ½).
/// A reader's name, its file, a ground point (lon, lat, h) and its image position.
type Golden = (&'static str, PathBuf, (f64, f64, f64), (f64, f64));

#[test]
fn xml_readers_match_rpcm() {
    let cases: [Golden; 4] = [
        ("WorldView-2", fx("rpc_WV2.xml"), (-0.3248, 45.6543, 97.0), (14104.1695925412, 10125.381115577)),
        ("WorldView-2", fx("rpc_WV2.xml"), (-0.30, 45.67, 150.0), (19601.075744337348, 6556.053249899548)),
        ("Pléiades DIMAP", ventoux("RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML"), (5.2846, 44.137, 1075.0), (19113.19782004122, 21147.052657720364)),
        ("SPOT 6 DIMAP", fx("rpc_SPOT6.xml"), (-72.26, 18.57, 500.0), (11478.129935618585, 12764.211207623881)),
    ];
    for (what, path, p, (c, r)) in cases {
        let rpc = Rpc::read(&path).unwrap();
        close(&rpc, p, (c + 0.5, r + 0.5), 1e-6, what);
    }
}

/// The RPB sidecar GDAL wrote for the Pléiades GeoTIFF (`gdal_translate -co
/// RPB=YES`) holds the same model as the file's RPC tag.
#[test]
fn rpb_sidecar_equals_the_geotiff_tag() {
    let tag = Rpc::read(&fx("PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif")).unwrap();
    let rpb = Rpc::read(&fx("PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.RPB")).unwrap();
    for p in [(7.18, 43.68, 670.0), (7.1, 43.65, 300.0)] {
        close(&rpb, p, tag.project(p.0, p.1, p.2).unwrap(), 1e-6, "RPB vs tag");
    }
    // A GeoTIFF without the tag but with the RPB beside it (as GDAL keeps
    // it): the error names the sidecar to give.
    let dir = tempfile::tempdir().unwrap();
    let bare = dir.path().join("bare.tif");
    std::fs::copy(Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini/scan.tif"), &bare).unwrap();
    std::fs::copy(fx("PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.RPB"), dir.path().join("bare.RPB")).unwrap();
    let e = Rpc::read(&bare).unwrap_err().to_string();
    assert!(e.contains("no RPC tag") && e.contains("give rpc ") && e.contains("bare.RPB"), "{e}");
}

/// The NITF RPC00B TRE, against GDAL's RPC transformer on the same file
/// (GDAL 3.6, pixel centres at ½).
#[test]
fn nitf_rpc00b_tre_matches_gdal() {
    let rpc = Rpc::read(&fx("wv3_20.NTF")).unwrap();
    close(&rpc, (-58.6024, -34.5043, 31.0), (20856.0501775, 17538.717519972), 1e-6, "NITF");
    close(&rpc, (-58.5924, -34.5143, 81.0), (18195.08183080436, 14131.091302820176), 1e-6, "NITF");
}

/// `locate` inverts `project` to the asked tolerance.
#[test]
fn locate_inverts_project() {
    let rpc = Rpc::read(&fx("rpc_WV2.xml")).unwrap();
    for (c, r, h) in [(100.0, 200.0, 97.0), (14000.0, 10000.0, 300.0), (28000.0, 21000.0, 0.0)] {
        let (lon, lat) = rpc.locate(c, r, h, 1e-6).unwrap();
        close(&rpc, (lon, lat, h), (c, r), 1e-6, "locate");
    }
}

/// Files that are not RPC, or hold an RPC of a kind we do not read, say so.
#[test]
fn unsupported_formats_are_named() {
    let e = Rpc::read(&fx("rpc_unsupported.xml")).unwrap_err().to_string();
    assert!(e.contains("rpc_unsupported.xml") && e.contains("VRTDataset"), "{e}");
    let e = Rpc::read(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini/scan.tif")).unwrap_err().to_string();
    assert!(e.contains("scan.tif") && e.contains("no RPC tag"), "{e}");
    let geom = std::fs::read_to_string(ventoux("left_image.geom")).unwrap().replace("polynomial_format:  B", "polynomial_format:  A");
    let e = Rpc::parse_geom(&geom, Path::new("a.geom")).unwrap_err().to_string();
    assert!(e.contains("a.geom") && e.contains("polynomial_format A"), "{e}");
    let e = Rpc::parse_nitf(b"NITF02.10 no tre here", Path::new("x.ntf")).unwrap_err().to_string();
    assert!(e.contains("x.ntf") && e.contains("RPC00B"), "{e}");
    // EnMAP's metadata: an RPC for each band, said as such.
    let enmap = "<level_X><specific><bandCharacterisation/></specific><product><navigation><RPC><bandID number=\"1\"><ROW_OFF>500</ROW_OFF></bandID></RPC></navigation></product></level_X>";
    let e = Rpc::parse_xml(enmap, Path::new("ENMAP-METADATA.XML")).unwrap_err().to_string();
    assert!(e.contains("ENMAP-METADATA.XML") && e.contains("per-band RPCs are not read here"), "{e}");
}

/// The Ventoux output grid: 256×240 px at 0.5 m in UTM 31N inside the crop.
const VENTOUX_GRID: (f64, f64, f64, u32, u32) = (675_240.0, 4_897_330.0, 0.5, 256, 240);

/// The real Pléiades crop over Mont Ventoux (500×500 at offset 5000,5000 of
/// the full scene; its RPC shifted accordingly) with SRTM in EPSG:4326 and
/// optionally the EGM96 geoid, into UTM 31N: gcm-ortho's orthophoto of a
/// coordinate image, and with `gdal` also gdalwarp's (`-rpc -et 0`, exact
/// at every pixel) onto the same grid. Returns the folder and both paths.
fn ventoux_maps(geoid: bool, extra: &[&str], gdal: bool) -> (tempfile::TempDir, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_path_buf();
    let coords = d.join("coords.tif");
    coordinate_image(&coords, 500, 500);
    let rpc = Rpc::read(&ventoux("left_image.geom")).unwrap().cropped(5000.0, 5000.0);
    let sidecar = d.join("coords_RPC.TXT");
    std::fs::write(&sidecar, rpc.to_gdal_text()).unwrap();
    let dem = ventoux("srtm_N44E005_crop.tif");
    let gtx = ventoux("egm96_15_ventoux.gtx");
    let (x0, y0, gsd, w, h) = VENTOUX_GRID;
    let (x1, y1) = (x0 + w as f64 * gsd, y0 - h as f64 * gsd);
    let bounds = format!("{x0},{y1},{x1},{y0}");
    let ours = d.join("ours.tif");
    let mut args = vec!["rectify", "--image", s(&coords), "--rpc", s(&sidecar), "--dem", s(&dem), "--crs", "EPSG:32631"];
    args.extend(["--bounds", &bounds, "--gsd", "0.5", "--nodata", "-1", "--compress", "none", "--quiet", "-o", s(&ours)]);
    if geoid {
        args.extend(["--geoid", s(&gtx)]);
    }
    args.extend(extra);
    let out = run(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let theirs = d.join("gdal.tif");
    if gdal {
        let dem_opt = format!("RPC_DEM={}", s(&dem));
        let dem_srs = format!("RPC_DEM_SRS=+proj=longlat +datum=WGS84 +geoidgrids={} +type=crs", s(&gtx));
        let te = [x0, y1, x1, y0].map(|v| v.to_string());
        let tr = gsd.to_string();
        let mut g = vec!["-q", "-rpc", "-to", &dem_opt];
        if geoid {
            g.extend(["-to", &dem_srs]);
        }
        g.extend(["-et", "0", "-r", "bilinear", "-t_srs", "EPSG:32631", "-dstnodata", "-1", "-te", &te[0], &te[1], &te[2], &te[3], "-tr", &tr, &tr]);
        g.extend([s(&coords), s(&theirs)]);
        let out = Command::new("gdalwarp").args(&g).output().unwrap();
        assert!(out.status.success(), "gdalwarp: {}", String::from_utf8_lossy(&out.stderr));
    }
    (dir, ours, theirs)
}

/// The exact model (`--sparsity 1`) against GDAL's RPC transformer, point
/// by point (`gdaltransform -rpc -to RPC_DEM=… -t_srs EPSG:32631 -i`):
/// UTM → WGS84, the DEM in EPSG:4326 looked up bilinearly, the geoid, the
/// RPC and the crop offset all agree to float32 precision.
fn ventoux_model_matches_gdal_transformer(geoid: bool) {
    let (dir, ours, _) = ventoux_maps(geoid, &["--sparsity", "1"], false);
    let (w, _, _, v) = read_f32(&ours);
    let (x0, y0, gsd, gw, gh) = VENTOUX_GRID;
    let pixels: Vec<(u32, u32)> = (0..60).map(|k| ((k * 37 + 11) % gw, (k * 53 + 7) % gh)).collect();
    let input: String = pixels.iter().map(|&(c, r)| format!("{} {} 0\n", x0 + (c as f64 + 0.5) * gsd, y0 - (r as f64 + 0.5) * gsd)).collect();
    let mut args = vec!["-rpc".to_string(), "-to".into(), format!("RPC_DEM={}", s(&ventoux("srtm_N44E005_crop.tif")))];
    if geoid {
        args.extend(["-to".into(), format!("RPC_DEM_SRS=+proj=longlat +datum=WGS84 +geoidgrids={} +type=crs", s(&ventoux("egm96_15_ventoux.gtx")))]);
    }
    args.extend(["-t_srs".into(), "EPSG:32631".into(), "-i".into(), s(&dir.path().join("coords.tif")).into()]);
    let (text, _) = gdaltransform(&args.iter().map(String::as_str).collect::<Vec<_>>(), &input);
    let mut worst = 0f64;
    let mut compared = 0;
    for (&(c, r), line) in pixels.iter().zip(text.lines()) {
        let g: Vec<f64> = line.split_whitespace().map(|t| t.parse().unwrap()).collect();
        let k = 2 * (r * w + c) as usize;
        if v[k] < 0.0 {
            continue;
        }
        worst = worst.max((v[k] as f64 - g[0]).abs().max((v[k + 1] as f64 - g[1]).abs()));
        compared += 1;
    }
    eprintln!("Ventoux model vs GDAL's RPC transformer (geoid {geoid}): {compared} points, max {worst:.2e} px");
    assert!(compared >= 50 && worst < 1e-3, "{compared} points, worst {worst}");
}

#[test]
fn ventoux_model_matches_gdal_transformer_without_geoid() {
    if !have("gdaltransform") {
        eprintln!("skipped: gdaltransform not installed");
        return;
    }
    ventoux_model_matches_gdal_transformer(false);
}

#[test]
fn ventoux_model_matches_gdal_transformer_with_egm96() {
    if !have("gdaltransform") {
        eprintln!("skipped: gdaltransform not installed");
        return;
    }
    ventoux_model_matches_gdal_transformer(true);
}

/// The orthophotos of gcm-ortho (A + GCM, error-bounded at 0.02 px) and of
/// gdalwarp (exact at every pixel) onto the same grid: no geometric offset
/// between them (mean displacement < 0.005 px), and per pixel within
/// 0.07 px: our 0.02 px bound (held at every pixel, see
/// `ventoux_error_bound_holds_at_every_pixel`) and gdalwarp's own doing
/// beyond it: its warp-time DEM heights depart from its own RPC
/// transformer's by up to ~15 cm here (the previous test shows our model
/// equals that transformer), zero on average.
#[test]
fn ventoux_orthophoto_matches_gdalwarp() {
    if !have("gdalwarp") {
        eprintln!("skipped: gdalwarp not installed");
        return;
    }
    for geoid in [false, true] {
        let (_dir, ours, theirs) = ventoux_maps(geoid, &["--max-error", "0.02"], true);
        let m = coordinate_map_difference(&ours, &theirs, 500, 500);
        eprintln!(
            "Ventoux vs gdalwarp (geoid {geoid}): {} px, offset ({:.4}, {:.4}) px, mean {:.4} px, max {:.4} px",
            m.pixels, m.offset[0], m.offset[1], m.mean, m.max
        );
        assert!(m.pixels > 50_000, "{} px compared", m.pixels);
        assert!(m.offset[0].hypot(m.offset[1]) < 0.005 && m.max < 0.07, "offset {:?}, max {}", m.offset, m.max);
    }
}

/// A synthetic satellite scene (`synth --camera rpc`, 25° off-nadir, hilly
/// relief in EPSG:4326): gcm-ortho at its defaults (A + GCM, k = 16) and
/// gdalwarp exact at every pixel (`-et 0`), through a coordinate image on
/// the same grid: an offset far under the 0.05 px asked (the GCM's mean
/// error at k = 16 is ~0.007 px and has a sign), per pixel within 0.06 px.
#[test]
fn synthetic_rpc_scene_matches_gdalwarp() {
    if !have("gdalwarp") {
        eprintln!("skipped: gdalwarp not installed");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rep = scene(d, 1000, |o| {
        o.camera = gcm_ortho::synth::CameraKind::Rpc;
        o.off_nadir_deg = 25.0;
        o.kappa_deg = 0.0;
    });
    coordinate_image(&d.join("coords.tif"), 1000, 1000);
    std::fs::copy(d.join("scan_RPC.TXT"), d.join("coords_RPC.TXT")).unwrap();
    let ours = d.join("ours.tif");
    let out = run(&[
        "rectify",
        "--image",
        s(&d.join("coords.tif")),
        "--camera",
        s(&rep.camera),
        "--dem",
        s(&rep.dem),
        "--nodata",
        "-1",
        "--compress",
        "none",
        "--quiet",
        "-o",
        s(&ours),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (gt, w, h) = georef(&ours);
    let theirs = d.join("gdal.tif");
    let coords = d.join("coords.tif");
    let te = [gt[0], gt[3] + gt[5] * h as f64, gt[0] + gt[1] * w as f64, gt[3]].map(|v| v.to_string());
    let tr = gt[1].to_string();
    let dem_opt = format!("RPC_DEM={}", s(&rep.dem));
    let args = [
        "-q",
        "-rpc",
        "-to",
        &dem_opt,
        "-et",
        "0",
        "-r",
        "bilinear",
        "-t_srs",
        "EPSG:32631",
        "-dstnodata",
        "-1",
        "-te",
        &te[0],
        &te[1],
        &te[2],
        &te[3],
        "-tr",
        &tr,
        &tr,
        s(&coords),
        s(&theirs),
    ];
    let out = Command::new("gdalwarp").args(args).output().unwrap();
    assert!(out.status.success(), "gdalwarp: {}", String::from_utf8_lossy(&out.stderr));
    let m = coordinate_map_difference(&ours, &theirs, 1000, 1000);
    eprintln!("synthetic RPC vs gdalwarp: {} px, offset ({:.4}, {:.4}) px, mean {:.4} px, max {:.4} px", m.pixels, m.offset[0], m.offset[1], m.mean, m.max);
    assert!(m.pixels > 900_000, "{} px compared", m.pixels);
    assert!(m.offset[0].hypot(m.offset[1]) < 0.02 && m.max < 0.06, "offset {:?}, max {}", m.offset, m.max);

    // The scene's own pixels: the two orthophotos differ by what a few
    // hundredths of a pixel of bilinear resampling explain.
    let (ours_img, gdal_img) = (d.join("ours_img.tif"), d.join("gdal_img.tif"));
    let out = run(&["rectify", "--image", s(&rep.scan), "--camera", s(&rep.camera), "--dem", s(&rep.dem), "--quiet", "-o", s(&ours_img)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let args = [
        "-q",
        "-rpc",
        "-to",
        &dem_opt,
        "-et",
        "0",
        "-r",
        "bilinear",
        "-t_srs",
        "EPSG:32631",
        "-te",
        &te[0],
        &te[1],
        &te[2],
        &te[3],
        "-tr",
        &tr,
        &tr,
        s(&rep.scan),
        s(&gdal_img),
    ];
    let out = Command::new("gdalwarp").args(args).output().unwrap();
    assert!(out.status.success(), "gdalwarp: {}", String::from_utf8_lossy(&out.stderr));
    let c = gcm_ortho::study::compare::compare(
        &gcm_ortho::study::compare::read_grey(&ours_img, 0.0).unwrap(),
        &gcm_ortho::study::compare::read_grey(&gdal_img, 0.0).unwrap(),
        48,
    );
    eprintln!("synthetic RPC pixel values vs gdalwarp: {} px, mean |diff| {:.3} DN", c.pixels, c.mean_abs_diff);
    assert!(c.pixels > 900_000 && c.mean_abs_diff < 0.25, "{} px, mean |diff| {}", c.pixels, c.mean_abs_diff);
}

/// Geotransform and size of a GeoTIFF of ours.
fn georef(path: &Path) -> ([f64; 6], u32, u32) {
    let f = std::fs::File::open(path).unwrap();
    let mut dec = tiff::decoder::Decoder::new(std::io::BufReader::new(f)).unwrap();
    let (w, h) = dec.dimensions().unwrap();
    let g = gcm_ortho::io::geotiff::read_georef(&mut dec, path).unwrap().unwrap();
    (g.transform, w, h)
}

/// `rpc-grid` (Chibunichev and Sonyushkin) on a synthetic satellite scene: GDAL reads the
/// geolocation arrays as we meant them (its geolocation transformer gives
/// our node values at node pixels), the grid between nodes matches the
/// scene's checkpoints (truth) to centimetres, and the accuracy table
/// grows with the step.
#[test]
fn rpc_grid_is_read_by_gdal_and_matches_the_checkpoints() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rep = scene(d, 600, |o| {
        o.camera = gcm_ortho::synth::CameraKind::Rpc;
        o.off_nadir_deg = 25.0;
        o.bands = 1;
    });
    let grid = d.join("grid.tif");
    let json = d.join("acc.json");
    let out = run(&[
        "rpc-grid",
        "--image",
        s(&rep.scan),
        "--camera",
        s(&rep.camera),
        "--dem",
        s(&rep.dem),
        "--step",
        "8",
        "--accuracy",
        "4,32",
        "--sample",
        "3",
        "--json",
        s(&json),
        "-o",
        s(&grid),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (gw, gh, bands, v) = read_f64(&grid);
    assert_eq!((gw, gh, bands), (76, 76, 3));
    // Checkpoints: ground (UTM) and their exact image positions.
    let utm = gcm_ortho::geodesy::GroundCrs::from_epsg(32631).unwrap();
    let text = std::fs::read_to_string(&rep.checkpoints).unwrap();
    let mut worst = 0f64;
    for line in text.lines().skip(1) {
        let f: Vec<f64> = line.split(',').map(|t| t.parse().unwrap()).collect();
        let (lon, lat) = utm.to_lonlat(f[1], f[2]).unwrap();
        let (c, r) = (f[4], f[5]);
        // Bilinear between the four nodes around (c, r).
        let (x, y) = ((c - 0.5) / 8.0, (r - 0.5) / 8.0);
        let (i, j) = (x.floor() as usize, y.floor() as usize);
        let (fx, fy) = (x - i as f64, y - j as f64);
        let at = |i: usize, j: usize, b: usize| v[3 * (j * gw as usize + i) + b];
        let bl = |b: usize| (at(i, j, b) * (1.0 - fx) + at(i + 1, j, b) * fx) * (1.0 - fy) + (at(i, j + 1, b) * (1.0 - fx) + at(i + 1, j + 1, b) * fx) * fy;
        let e = ((bl(0) - lon) * 111_320.0 * lat.to_radians().cos()).hypot((bl(1) - lat) * 111_320.0);
        worst = worst.max(e);
    }
    assert!(worst < 0.05, "checkpoints off by up to {worst} m");
    let rows: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let (fine, coarse) = (rows[0]["rms_m"].as_f64().unwrap(), rows[1]["rms_m"].as_f64().unwrap());
    assert!(fine < coarse && coarse < 0.5, "RMS {fine} m at step 4, {coarse} m at step 32");
    if !have("gdaltransform") {
        eprintln!("skipped the GDAL part: gdaltransform not installed");
        return;
    }
    // Three bands of values, not an RGB picture (as QGIS would show it).
    let info = std::process::Command::new("gdalinfo").arg(&grid).output().unwrap();
    let info = String::from_utf8_lossy(&info.stdout);
    assert!(info.contains("ColorInterp=Gray") && !info.contains("ColorInterp=Red") && !info.contains("ColorInterp=Blue"), "{info}");
    let vrt = grid.with_extension("vrt");
    let nodes = [(0usize, 0usize), (10, 20), (75, 75), (40, 3)];
    let input: String = nodes.iter().map(|&(i, j)| format!("{} {}\n", i as f64 * 8.0 + 0.5, j as f64 * 8.0 + 0.5)).collect();
    let (text, _) = gdaltransform(&["-geoloc", s(&vrt)], &input);
    for (&(i, j), line) in nodes.iter().zip(text.lines()) {
        let g: Vec<f64> = line.split_whitespace().map(|t| t.parse().unwrap()).collect();
        let k = 3 * (j * gw as usize + i);
        assert!((g[0] - v[k]).abs() < 1e-9 && (g[1] - v[k + 1]).abs() < 1e-9, "node ({i}, {j}): GDAL ({}, {}) ours ({}, {})", g[0], g[1], v[k], v[k + 1]);
    }
}

/// Without a DEM of its place, an RPC's grid at a constant height: every
/// node at that height, and projected back by the RPC onto its own pixel.
#[test]
fn rpc_grid_at_a_constant_height() {
    let dir = tempfile::tempdir().unwrap();
    let (tif, grid) = (fx("PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif"), dir.path().join("g.tif"));
    let out = run(&["rpc-grid", "--image", s(&tif), "--rpc", s(&tif), "--height", "300", "--step", "8", "-o", s(&grid)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (gw, gh, bands, v) = read_f64(&grid);
    assert_eq!((gw, gh, bands), (17, 17, 3));
    let rpc = Rpc::read(&tif).unwrap();
    for (i, j) in [(0usize, 0usize), (16, 3), (8, 16)] {
        let k = 3 * (j * gw as usize + i);
        assert_eq!(v[k + 2], 300.0);
        close(&rpc, (v[k], v[k + 1], 300.0), (i as f64 * 8.0 + 0.5, j as f64 * 8.0 + 0.5), 0.03, "node");
    }
}

/// At 35° off-nadir over mountains some nodes fall in dead zones and fail
/// the back-check; every one of them is replaced (no NaN left).
#[test]
fn rpc_grid_corrects_dead_zone_nodes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rep = scene(d, 2000, |o| {
        o.camera = gcm_ortho::synth::CameraKind::Rpc;
        o.off_nadir_deg = 35.0;
        o.relief = gcm_ortho::synth::Relief::Mountain;
        o.kappa_deg = 0.0;
        o.bands = 1;
        o.no_scan = true;
    });
    let dem = gcm_ortho::dem::Dem::open(&rep.dem, &gcm_ortho::geodesy::Crs::wgs84()).unwrap();
    let cam = gcm_ortho::camera::file::Camera::read(&rep.camera).unwrap();
    let gcm_ortho::camera::file::Sensor::Rpc(r) = &cam.sensor else { panic!("an RPC camera") };
    let model = gcm_ortho::camera::RpcCamera::new(r.rpc.clone(), gcm_ortho::geodesy::GroundCrs::from_epsg(4326).unwrap(), None);
    let g = gcm_ortho::rpcgrid::build(&model, &dem, 2000, 2000, 8, dem.mean_height().unwrap()).unwrap();
    assert!(g.bad > 0 && g.corrected == g.bad, "bad {} corrected {}", g.bad, g.corrected);
    assert!(g.lon.iter().chain(&g.lat).chain(&g.h).all(|v| v.is_finite()));
}

/// A DigitalGlobe XML lists the product's tiles with their offsets in the
/// scene; the tile's file name finds its offset.
#[test]
fn digitalglobe_tile_offsets_are_read() {
    let xml = std::fs::read_to_string(fx("rpc_WV2.xml")).unwrap();
    let name = xml.split("<FILENAME>").nth(1).unwrap().split('<').next().unwrap().trim().to_string();
    assert_eq!(Rpc::tile_offset(&xml, &name), Some([0.0, 0.0]));
    assert_eq!(Rpc::tile_offset(&xml, &name.to_lowercase()), Some([0.0, 0.0]));
    let moved = xml.replacen("<ULCOLOFFSET>0</ULCOLOFFSET>", "<ULCOLOFFSET>8192</ULCOLOFFSET>", 1).replacen(
        "<ULROWOFFSET>0</ULROWOFFSET>",
        "<ULROWOFFSET>4096</ULROWOFFSET>",
        1,
    );
    assert_eq!(Rpc::tile_offset(&moved, &name), Some([8192.0, 4096.0]));
    assert_eq!(Rpc::tile_offset(&xml, "another.tif"), None);
}

/// A DEM in EPSG:4326 under an RPC camera: the DEM stage's conversion of
/// each node to longitude/latitude is the camera's own, handed over rather
/// than made twice. Node rows from it equal those the camera makes from
/// ground (X, Y), bit for bit, with and without a geoid (real Pléiades
/// crop over Mont Ventoux, SRTM, EGM96).
#[test]
fn nodes_projected_from_the_dems_longitude_latitude_equal_the_cameras_own() {
    use gcm_ortho::gcm::{CorrectionMode, Gcm, GcmSpec, NodeHeights};
    let rpc = Rpc::read(&ventoux("left_image.geom")).unwrap().cropped(5000.0, 5000.0);
    let dem = gcm_ortho::dem::Dem::open(&ventoux("srtm_N44E005_crop.tif"), &gcm_ortho::geodesy::Crs::from_epsg(32631).unwrap()).unwrap();
    assert_eq!(dem.lonlat_from().and_then(|c| c.epsg()), Some(32631));
    let (x0, y0, gsd, w, h) = VENTOUX_GRID;
    let grid = gcm_ortho::geom::OutputGrid { x0, y0, gsd: gcm_ortho::geom::Gsd::square(gsd), width: w, height: h };
    for geoid in [None, Some(gcm_ortho::geodesy::Geoid::read(&ventoux("egm96_15_ventoux.gtx")).unwrap())] {
        let with_geoid = geoid.is_some();
        let model = gcm_ortho::camera::RpcCamera::new(rpc.clone(), gcm_ortho::geodesy::GroundCrs::from_epsg(32631).unwrap(), geoid);
        let t = gcm_ortho::transform::Transform::new(&model, &dem, grid);
        let plane = dem.trend_plane([x0, y0 - h as f64 * gsd, x0 + w as f64 * gsd, y0]).unwrap();
        let a = gcm_ortho::transform::Approx::new(&model, &grid, plane).unwrap();
        let gcm = Gcm::new(&t, a, GcmSpec { k: 8, mode: CorrectionMode::Bilinear, max_error: None });
        let mut valid = 0;
        for j in -1..=h.div_ceil(8) as i64 {
            let shared = gcm.node_heights(j);
            let lonlat = shared.lonlat.as_ref().expect("longitudes and latitudes kept");
            assert_eq!(lonlat.len(), shared.heights.len());
            let own = NodeHeights { heights: shared.heights.clone(), lonlat: None };
            let mut miss = None;
            let (a, b) = (gcm.node_row(j, &shared, &mut miss), gcm.node_row(j, &own, &mut miss));
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!((bits(&a.dc), bits(&a.dr)), (bits(&b.dc), bits(&b.dr)), "node row {j}, geoid {with_geoid}");
            valid += a.dc.iter().filter(|v| v.is_finite()).count();
        }
        assert!(valid > 900, "{valid} nodes with a value");
    }
}

/// The default error bound holds at every pixel on real data: the Ventoux
/// crop over SRTM (a DEM in EPSG:4326 under a UTM orthophoto, so its posts
/// are not the output's lines), against the exact model (`--sparsity 1`).
#[test]
fn ventoux_error_bound_holds_at_every_pixel() {
    for (geoid, extra) in [(false, &[][..]), (true, &[][..]), (false, &["--max-error", "0.02"][..])] {
        let bound = if extra.is_empty() { 0.1 } else { 0.02 };
        let (_d1, bounded, _) = ventoux_maps(geoid, extra, false);
        let (_d2, exact, _) = ventoux_maps(geoid, &["--sparsity", "1", "--corrections", "cell"], false);
        let m = coordinate_map_difference(&bounded, &exact, 500, 500);
        eprintln!("Ventoux at the bound {bound} (geoid {geoid}): {} px, max {:.4} px", m.pixels, m.max);
        assert!(m.pixels > 50_000 && m.max <= bound, "{} px, max {}", m.pixels, m.max);
    }
}

/// The Pléiades crop's RPC with its line denominator `c0 + c1·L` (the rest
/// 0), in `dir/folding.geom`.
fn folding_rpc(dir: &Path, c0: f64, c1: f64) -> PathBuf {
    let geom = std::fs::read_to_string(ventoux("left_image.geom")).unwrap();
    let bad: String = geom
        .lines()
        .map(|l| match l.split(':').next().unwrap_or("") {
            "line_den_coeff_00" => format!("line_den_coeff_00:  {c0}\n"),
            "line_den_coeff_01" => format!("line_den_coeff_01:  {c1}\n"),
            k if k.starts_with("line_den_coeff_") => format!("{k}:  0\n"),
            _ => format!("{l}\n"),
        })
        .collect();
    let rpc = dir.join("folding.geom");
    std::fs::write(&rpc, bad).unwrap();
    rpc
}

/// `rectify --quiet` of the Pléiades crop with `rpc` on `dem` into `out`.
fn pleiades_rectify(rpc: &Path, dem: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let image = ventoux("left_image.tif");
    let mut args = vec!["rectify", "--image", s(&image), "--rpc", s(rpc), "--rpc-offset", "5000,5000", "--dem", s(dem), "--quiet", "-o", s(out)];
    args.extend_from_slice(extra);
    run(&args)
}

/// `rectify` of the Pléiades crop with `rpc` and `extra` into `dir/o.tif`,
/// which must be refused naming the RPC file and its line denominator.
fn refused_as_folding(dir: &Path, rpc: &Path, extra: &[&str]) {
    let out = dir.join("o.tif");
    let r = pleiades_rectify(rpc, &ventoux("srtm_N44E005_crop.tif"), &out, extra);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.contains("folding.geom") && err.contains("LINE_DEN_COEFF changes sign"), "{err}");
    assert!(!out.exists());
}

/// An RPC whose line denominator passes through zero inside the scene (the
/// image would go to infinity and fold there) is refused, naming the file.
#[test]
fn an_rpc_whose_denominator_changes_sign_over_the_scene_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (x0, y0, gsd, w, h) = VENTOUX_GRID;
    let crs = gcm_ortho::geodesy::GroundCrs::from_epsg(32631).unwrap();
    let (lon, _) = crs.to_lonlat(x0 + w as f64 * gsd / 2.0, y0 - h as f64 * gsd / 2.0).unwrap();
    // den = L − L0: zero at the grid's middle longitude.
    let l0 = (lon - 5.28464655928485) / 0.12870115852264;
    let rpc = folding_rpc(d, -l0, 1.0);
    let (x1, y1) = (x0 + w as f64 * gsd, y0 - h as f64 * gsd);
    let bounds = format!("{x0},{y1},{x1},{y0}");
    refused_as_folding(d, &rpc, &["--crs", "EPSG:32631", "--bounds", &bounds, "--gsd", "0.5"]);
}

/// An RPC whose denominator passes through zero within its own validity
/// box but off the crop's ground (1 + 2.5·L: zero at L = −0.4) is refused at
/// the defaults too (it was taken, blamed on the DEM's coverage).
#[test]
fn an_rpc_whose_denominator_changes_sign_in_its_validity_box_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    refused_as_folding(dir.path(), &folding_rpc(dir.path(), 1.0, 2.5), &[]);
}

/// A geoid grid that does not cover the scene is an error naming the grid,
/// what it covers and what the scene spans — not half a scene of nodata.
#[test]
fn a_geoid_grid_short_of_the_scene_is_refused_with_both_extents() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Longitudes 5.0..5.3, latitudes 44.10..44.17: the RPC's scene centre
    // (5.28°E, 44.14°N) but not the crop, at ~44.2°N.
    let mut gtx = Vec::new();
    for v in [44.1f64, 5.0, 0.07, 0.1] {
        gtx.extend_from_slice(&v.to_be_bytes());
    }
    gtx.extend_from_slice(&2i32.to_be_bytes());
    gtx.extend_from_slice(&4i32.to_be_bytes());
    for _ in 0..8 {
        gtx.extend_from_slice(&50.0f32.to_be_bytes());
    }
    let geoid = d.join("west.gtx");
    std::fs::write(&geoid, gtx).unwrap();
    let out = d.join("o.tif");
    let r = run(&[
        "rectify",
        "--image",
        s(&ventoux("left_image.tif")),
        "--rpc",
        s(&ventoux("left_image.geom")),
        "--rpc-offset",
        "5000,5000",
        "--dem",
        s(&ventoux("srtm_N44E005_crop.tif")),
        "--geoid",
        s(&geoid),
        "--quiet",
        "-o",
        s(&out),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.contains("west.gtx") && err.contains("latitudes 44.100..44.170") && err.contains("the image spans"), "{err}");
    assert!(!out.exists());
}

/// A DEM whose GeoTIFF keys say its heights are EGM96 heights (EPSG:4326 +
/// 5773, as GDAL writes a compound CRS) gets the EGM96 geoid from where
/// PROJ keeps its grids, with no --geoid: the orthophoto of --geoid with
/// that grid, byte for byte. Without the grid there, refused naming it.
#[test]
fn a_dem_in_egm96_heights_gets_its_geoid_from_projs_grids() {
    if !have("gdal_translate") {
        eprintln!("skipped: GDAL is not installed");
        return;
    }
    let (dir, with_geoid, _) = ventoux_maps(true, &[], false);
    let d = dir.path();
    let dem = d.join("dem-egm96.tif");
    let out = Command::new("gdal_translate").args(["-q", "-a_srs", "EPSG:4326+5773", s(&ventoux("srtm_N44E005_crop.tif")), s(&dem)]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (proj, empty) = (d.join("proj"), d.join("empty"));
    std::fs::create_dir_all(&proj).unwrap();
    std::fs::create_dir_all(&empty).unwrap();
    std::fs::copy(ventoux("egm96_15_ventoux.gtx"), proj.join("egm96_15.gtx")).unwrap();
    let (x0, y0, gsd, w, h) = VENTOUX_GRID;
    let bounds = format!("{x0},{},{},{y0}", y0 - h as f64 * gsd, x0 + w as f64 * gsd);
    let rectify = |proj_data: &Path, out: &Path| {
        Command::new(bin())
            .args(["rectify", "--image", s(&d.join("coords.tif")), "--rpc", s(&d.join("coords_RPC.TXT")), "--dem", s(&dem), "--crs", "EPSG:32631"])
            .args(["--bounds", &bounds, "--gsd", "0.5", "--nodata", "-1", "--compress", "none", "--quiet", "-o", s(out)])
            .env("PROJ_DATA", proj_data)
            .env("HOME", d)
            .output()
            .unwrap()
    };
    let found = d.join("found.tif");
    let r = rectify(&proj, &found);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(whole_image(&found).0 == whole_image(&with_geoid).0, "the geoid found is not applied as --geoid applies it");
    let missing = d.join("missing.tif");
    let r = rectify(&empty, &missing);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(err.contains("EGM96") && err.contains("egm96_15.gtx") && err.contains("--geoid"), "{err}");
    assert!(!missing.exists());
}

/// Geoid grids in PROJ's GeoTIFF form (Float32, deflate with the floating
/// point predictor, tiled, pixel-is-point, as `us_nga_egm96_15.tif`) give
/// the undulations of the same grid as `.gtx`; a grid packed as Int16 with
/// GDAL's scale and offset gives them within its quantum. A DEM in EGM96
/// heights finds the GeoTIFF under PROJ's name when no `.gtx` is there.
#[test]
fn geoid_grids_in_geotiff_form_read_as_the_gtx() {
    if !have("gdal_translate") {
        assert!(std::env::var_os("CI").is_none(), "GDAL is needed under CI");
        eprintln!("skipped: GDAL is not installed");
        return;
    }
    use gcm_ortho::geodesy::Geoid;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let gtx = ventoux("egm96_15_ventoux.gtx");
    let float = d.join("us_nga_egm96_15.tif");
    let packed = d.join("packed.tif");
    let translate = |args: &[&str]| {
        let out = Command::new("gdal_translate").arg("-q").args(args).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    };
    translate(&[
        "-co",
        "COMPRESS=DEFLATE",
        "-co",
        "PREDICTOR=3",
        "-co",
        "TILED=YES",
        "-co",
        "BLOCKXSIZE=16",
        "-co",
        "BLOCKYSIZE=16",
        "-mo",
        "AREA_OR_POINT=Point",
        s(&gtx),
        s(&float),
    ]);
    // N = stored · 0.001 + 50: the stored value is (N − 50) · 1000.
    translate(&["-ot", "Int16", "-scale", "0", "100", "-50000", "50000", "-a_scale", "0.001", "-a_offset", "50", s(&gtx), s(&packed)]);
    let reference = Geoid::read(&gtx).unwrap();
    let (as_float, as_packed) = (Geoid::read(&float).unwrap(), Geoid::read(&packed).unwrap());
    // Read a tile at a time, as a grid too large to hold is.
    let (tiled_float, tiled_packed) = (Geoid::read_geotiff(&float, 0).unwrap(), Geoid::read_geotiff(&packed, 0).unwrap());
    let (mut worst_float, mut worst_packed, mut n) = (0.0f64, 0.0f64, 0);
    for k in 0..400 {
        let (lon, lat) = (3.0 + 4.0 * (k % 20) as f64 / 19.0, 43.0 + 3.0 * (k / 20) as f64 / 19.0);
        let want = reference.undulation(lon, lat).unwrap();
        for (float, packed) in [(&as_float, &as_packed), (&tiled_float, &tiled_packed)] {
            worst_float = worst_float.max((float.undulation(lon, lat).unwrap() - want).abs());
            worst_packed = worst_packed.max((packed.undulation(lon, lat).unwrap() - want).abs());
        }
        n += 1;
    }
    assert_eq!(n, 400);
    assert!(worst_float < 1e-9, "the GeoTIFF grid: {worst_float} m from the .gtx");
    assert!(worst_packed < 0.001, "the packed grid: {worst_packed} m from the .gtx");
    assert_eq!(as_float.undulation(10.0, 44.0), None, "outside the grid");

    // Found in PROJ's folder under PROJ's current name.
    let (dir2, with_geoid, _) = ventoux_maps(true, &[], false);
    let d2 = dir2.path();
    let dem = d2.join("dem-egm96.tif");
    translate(&["-a_srs", "EPSG:4326+5773", s(&ventoux("srtm_N44E005_crop.tif")), s(&dem)]);
    let proj = d2.join("proj");
    std::fs::create_dir_all(&proj).unwrap();
    std::fs::copy(&float, proj.join("us_nga_egm96_15.tif")).unwrap();
    let (x0, y0, gsd, w, h) = VENTOUX_GRID;
    let bounds = format!("{x0},{},{},{y0}", y0 - h as f64 * gsd, x0 + w as f64 * gsd);
    let found = d2.join("found.tif");
    let r = Command::new(bin())
        .args(["rectify", "--image", s(&d2.join("coords.tif")), "--rpc", s(&d2.join("coords_RPC.TXT")), "--dem", s(&dem), "--crs", "EPSG:32631"])
        .args(["--bounds", &bounds, "--gsd", "0.5", "--nodata", "-1", "--compress", "none", "--quiet", "-o", s(&found)])
        .env("PROJ_DATA", &proj)
        .env("HOME", d2)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let (a, b) = (whole_image(&found).0, whole_image(&with_geoid).0);
    assert_eq!(a.len(), b.len());
    let floats = |v: &[u8]| v.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect::<Vec<_>>();
    let worst = floats(&a).iter().zip(&floats(&b)).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
    assert!(worst < 1e-3, "the GeoTIFF geoid found: {worst} px from --geoid with the .gtx");
}

/// The SRTM crop as the `.hgt` tile it was cut from (N44E005: 1201² posts
/// of 3″ on whole degrees, voids elsewhere): GDAL places and reads the
/// tile as we do, and the orthophoto over it — alone or in a folder of
/// tiles — is the crop's, byte for byte.
#[test]
fn an_hgt_tile_reads_as_gdal_reads_it_and_gives_the_crops_orthophoto() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let crop = ventoux("srtm_N44E005_crop.tif");
    let posts = gcm_ortho::dem::GridDem::read(&crop).unwrap();
    assert_eq!((posts.width, posts.height), (80, 80));
    // The crop's first post is 5° + 200·3″ east, 45° − 920·3″ north.
    let mut tile = vec![-32768i16; 1201 * 1201];
    for j in 0..80 {
        for i in 0..80 {
            tile[(920 + j) * 1201 + 200 + i] = posts.sample(i, j) as i16;
        }
    }
    let tiles = d.join("srtm");
    std::fs::create_dir(&tiles).unwrap();
    let hgt = tiles.join("N44E005.hgt");
    std::fs::write(&hgt, tile.iter().flat_map(|v| v.to_be_bytes()).collect::<Vec<u8>>()).unwrap();
    // A neighbour without data: the folder is a mosaic of two tiles.
    std::fs::write(tiles.join("N44E004.hgt"), [0x80u8, 0x00].repeat(1201 * 1201)).unwrap();

    let ours = gcm_ortho::dem::GridDem::read(&hgt).unwrap();
    assert_eq!(ours.sample(200 + 17, 920 + 33), posts.sample(17, 33));
    assert!(ours.sample(200 + 17, 920 + 33) > 50.0);
    if have("gdalinfo") {
        let out = Command::new("gdalinfo").args(["-json", s(&hgt)]).output().unwrap();
        let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let gt: Vec<f64> = j["geoTransform"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        for (a, b) in gt.iter().zip(ours.transform) {
            assert!((a - b).abs() < 1e-12, "GDAL's geotransform {gt:?}, ours {:?}", ours.transform);
        }
        assert_eq!(j["driverShortName"], "SRTMHGT");
    } else {
        assert!(std::env::var_os("CI").is_none(), "GDAL is needed under CI");
    }

    let (x0, y0, gsd, w, h) = VENTOUX_GRID;
    let bounds = format!("{x0},{},{},{y0}", y0 - h as f64 * gsd, x0 + w as f64 * gsd);
    let image = d.join("coords.tif");
    coordinate_image(&image, 500, 500);
    let sidecar = d.join("coords_RPC.TXT");
    std::fs::write(&sidecar, Rpc::read(&ventoux("left_image.geom")).unwrap().cropped(5000.0, 5000.0).to_gdal_text()).unwrap();
    let rectify = |dem: &Path, name: &str| {
        let out = d.join(name);
        let r = run(&[
            "rectify",
            "--image",
            s(&image),
            "--rpc",
            s(&sidecar),
            "--dem",
            s(dem),
            "--crs",
            "EPSG:32631",
            "--bounds",
            &bounds,
            "--gsd",
            "0.5",
            "--nodata",
            "-1",
            "--compress",
            "none",
            "--quiet",
            "-o",
            s(&out),
        ]);
        assert!(r.status.success(), "{name}: {}", String::from_utf8_lossy(&r.stderr));
        whole_image(&out).0
    };
    let want = rectify(&crop, "crop.tif");
    assert!(rectify(&hgt, "hgt.tif") == want, "the .hgt tile's orthophoto differs from the crop's");
    assert!(rectify(&tiles, "folder.tif") == want, "the folder of .hgt tiles gives another orthophoto");
}

/// Ground far outside the heights an RPC was fitted over (HEIGHT_OFF ±
/// HEIGHT_SCALE) is extrapolated: warned of, even with --quiet; the
/// Ventoux scene over its own DEM is not.
#[test]
fn ground_far_from_the_rpcs_heights_is_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let said = "its RPC was fitted over heights";
    let (image, rpc, dem, geoid) = (ventoux("left_image.tif"), ventoux("left_image.geom"), ventoux("srtm_N44E005_crop.tif"), ventoux("egm96_15_ventoux.gtx"));
    let base = ["rectify", "--image", s(&image), "--rpc", s(&rpc), "--rpc-offset", "5000,5000", "--quiet"];
    let r = common::run(&[&base[..], &["--dem", s(&dem), "--geoid", s(&geoid), "-o", s(&d.join("a.tif"))]].concat());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success() && !err.contains(said), "{err}");
    let r = common::run(&[&base[..], &["--height", "9000", "-o", s(&d.join("b.tif"))]].concat());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success() && err.contains("left_image.tif") && err.contains(said), "{err}");
}

/// A crop whose GeoTIFF keeps its offset in the scene as a "geotransform"
/// of pixels (the Ventoux crops: origin 5000, 5000, pixels of 1, no CRS)
/// is told to give --rpc-offset when it does not (else the orthophoto lands
/// kilometres off without a word); given, nothing is said.
#[test]
fn a_crop_that_keeps_its_offset_is_told_to_give_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (image, rpc, dem, geoid) = (ventoux("left_image.tif"), ventoux("left_image.geom"), ventoux("srtm_N44E005_crop.tif"), ventoux("egm96_15_ventoux.gtx"));
    let base = ["rectify", "--image", s(&image), "--rpc", s(&rpc), "--dem", s(&dem), "--geoid", s(&geoid), "--quiet"];
    let r = common::run(&[&base[..], &["-o", s(&d.join("a.tif"))]].concat());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("left_image.tif") && err.contains("give --rpc-offset 5000,5000"), "{err}");
    let r = common::run(&[&base[..], &["--rpc-offset", "5000,5000", "-o", s(&d.join("b.tif"))]].concat());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success() && !err.contains("--rpc-offset"), "{err}");
}

/// rpcm's JSON (its names, 20 coefficients a list in the RPC00B order),
/// nested under "rpc" as the IEEE GRSS data fusion contest's image files
/// hold it: the IKONOS fixture written so reads as the same model.
#[test]
fn rpcm_json_reads_as_the_text_it_was_written_from() {
    let text = std::fs::read_to_string(fx("rpc_IKONOS.txt")).unwrap();
    let value = |key: &str| -> f64 {
        let line = text.lines().find(|l| l.starts_with(&format!("{key}:"))).unwrap_or_else(|| panic!("{key}"));
        line.split_whitespace().nth(1).unwrap().parse().unwrap()
    };
    let coefficients = |base: &str| -> Vec<f64> { (1..=20).map(|i| value(&format!("{base}_{i}"))).collect() };
    let scalars = [
        ("row_offset", "LINE_OFF"),
        ("col_offset", "SAMP_OFF"),
        ("lat_offset", "LAT_OFF"),
        ("lon_offset", "LONG_OFF"),
        ("alt_offset", "HEIGHT_OFF"),
        ("row_scale", "LINE_SCALE"),
        ("col_scale", "SAMP_SCALE"),
        ("lat_scale", "LAT_SCALE"),
        ("lon_scale", "LONG_SCALE"),
        ("alt_scale", "HEIGHT_SCALE"),
    ];
    let mut rpc = serde_json::Map::new();
    for (json, key) in scalars {
        rpc.insert(json.into(), value(key).into());
    }
    for (json, key) in [("row_num", "LINE_NUM_COEFF"), ("row_den", "LINE_DEN_COEFF"), ("col_num", "SAMP_NUM_COEFF"), ("col_den", "SAMP_DEN_COEFF")] {
        rpc.insert(json.into(), coefficients(key).into());
    }
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("image.json");
    std::fs::write(&json, serde_json::json!({ "img": "image.tif", "rpc": rpc }).to_string()).unwrap();
    let (a, b) = (Rpc::read(&fx("rpc_IKONOS.txt")).unwrap(), Rpc::read(&json).unwrap());
    for (lon, lat, h) in [(-56.1722, -34.903, 28.0), (-56.2, -34.88, 60.0), (-56.14, -34.95, 0.0)] {
        assert_eq!(a.project(lon, lat, h), b.project(lon, lat, h), "({lon}, {lat}, {h})");
    }
    // JSON of no RPC is named so.
    std::fs::write(&json, "{\"img\": \"image.tif\"}").unwrap();
    let e = Rpc::read(&json).unwrap_err().to_string();
    assert!(e.contains("image.json") && e.contains("row_offset"), "{e}");
}

/// A DEM tagged EPSG:4979 (WGS 84 with ellipsoidal heights, as
/// `gdal_translate -a_srs EPSG:4979` writes it for RPC work) holds the
/// heights an RPC expects: read, no geoid applied and nothing doubted,
/// the orthophoto of the same heights tagged plain WGS 84 (it was refused:
/// "EPSG:4979 is a horizontal CRS").
#[test]
fn a_dem_of_ellipsoidal_heights_tagged_epsg_4979_is_taken_as_it_is() {
    if !have("gdal_translate") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let crop = ventoux("srtm_N44E005_crop.tif");
    for (code, name) in [("EPSG:4979", "dem4979.tif"), ("EPSG:4326", "dem4326.tif")] {
        let out = Command::new("gdal_translate").args(["-q", "-a_srs", code]).arg(&crop).arg(d.join(name)).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let ortho = |dem: &str, out: &str| {
        let r = pleiades_rectify(&ventoux("left_image.geom"), &d.join(dem), &d.join(out), &[]);
        let err = String::from_utf8_lossy(&r.stderr).into_owned();
        assert!(r.status.success(), "{dem}: {err}");
        err
    };
    let said = ortho("dem4979.tif", "a.tif");
    assert!(said.trim().is_empty(), "nothing to doubt: {said}");
    ortho("dem4326.tif", "b.tif");
    assert_eq!(whole_image(&d.join("a.tif")).0, whole_image(&d.join("b.tif")).0);
}

/// Real RPCs keep their denominators' sign over their whole validity box:
/// the box check that refuses a folding RPC refuses none of them.
#[test]
fn real_rpcs_keep_their_denominators_sign_over_their_validity_box() {
    let files = [
        "20191015_073816_ssc1d3_0011_basic_l1a_panchromatic_dn_RPC.TXT",
        "PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.RPB",
        "rpc_IKONOS.txt",
        "rpc_SPOT6.xml",
        "rpc_WV2.xml",
        "wv3_20.NTF",
    ];
    let mut paths: Vec<PathBuf> = files.iter().map(|f| fx(f)).collect();
    paths.push(ventoux("left_image.geom"));
    for p in paths {
        let r = Rpc::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        let mut signs = std::collections::BTreeSet::new();
        for i in 0..=8 {
            for j in 0..=8 {
                for k in [-1.0, 0.0, 1.0] {
                    let (lon, lat) = (r.long_off + r.long_scale * (i as f64 / 4.0 - 1.0), r.lat_off + r.lat_scale * (j as f64 / 4.0 - 1.0));
                    let (ld, sd) = r.denominators(lon, lat, r.height_off + k * r.height_scale);
                    signs.insert((ld > 0.0, sd > 0.0));
                }
            }
        }
        assert_eq!(signs.len(), 1, "{}: {signs:?}", p.display());
    }
}

/// A DEM whose vertical CRS is user-defined but named (GeoTIFF's vertical
/// citation "EGM2008 height", as a compound CRS's WKT leaves it) holds
/// heights above that geoid: its grid is looked for and, not found,
/// named in the refusal (the heights were taken as ellipsoidal without a
/// word, about 1 px off on this scene).
#[test]
fn a_vertical_datum_named_only_by_its_citation_is_applied_or_its_grid_named() {
    use gcm_ortho::io::geotiff::GeoKeyValue;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let srtm = gcm_ortho::dem::GridDem::read(&ventoux("srtm_N44E005_crop.tif")).unwrap();
    let mut keys = gcm_ortho::geodesy::geokeys::keys_of_epsg(4326).unwrap();
    keys.set(4096, GeoKeyValue::Short(32767));
    keys.set(4097, GeoKeyValue::Ascii("EGM2008 height".into()));
    let dem = d.join("named.tif");
    let t = srtm.transform;
    f32_raster_with_keys(&dem, (srtm.width as u32, srtm.height as u32), (t[0], t[3], t[1]), keys, |c, r| srtm.sample(c as usize, r as usize));
    let r = pleiades_rectify(&ventoux("left_image.geom"), &dem, &d.join("o.tif"), &[]);
    let err = String::from_utf8_lossy(&r.stderr);
    // (A machine with PROJ's EGM2008 grid applies it; none of CI's has it.)
    let folders = [
        std::env::var("PROJ_DATA").unwrap_or_default(),
        std::env::var("PROJ_LIB").unwrap_or_default(),
        "/usr/share/proj".into(),
        "/usr/local/share/proj".into(),
    ];
    let has_grid = folders.iter().any(|f| ["egm08_25.gtx", "us_nga_egm08_25.tif"].iter().any(|g| !f.is_empty() && Path::new(f).join(g).is_file()));
    if has_grid {
        assert!(r.status.success(), "{err}");
    } else {
        assert!(err.contains("EGM2008") && err.contains("egm08_25"), "{err}");
        assert!(!d.join("o.tif").exists());
    }
}

/// `rpc` written as Orthority writes `rpc_param.yaml`: image names, each
/// with `im_size` and an `rpc` mapping of lower-case GDAL names, the
/// coefficient lists wrapped over lines, integers where a value is whole,
/// and Orthority's extra error terms.
fn orthority_rpc_entry(name: &str, rpc: &Rpc) -> String {
    let mut t = format!("{name}:\n    im_size: [1000, 1000]\n    rpc:\n");
    for line in rpc.to_gdal_text().lines() {
        let (key, value) = line.split_once(": ").unwrap();
        if let Some((set, k)) = key.rsplit_once('_').filter(|(set, _)| set.ends_with("COEFF")) {
            let sep = if k == "1" {
                format!("        {}: [", set.to_lowercase())
            } else if k == "11" {
                ",\n            ".to_string()
            } else {
                ", ".to_string()
            };
            t += &format!("{sep}{value}{}", if k == "20" { "]\n" } else { "" });
        } else {
            let v: f64 = value.parse().unwrap();
            let v = if v.fract() == 0.0 { format!("{}", v as i64) } else { value.to_string() };
            t += &format!("        {}: {v}\n", key.to_lowercase());
        }
    }
    t + "        err_bias: 12.15\n        err_rand: 0.3\n"
}

/// Orthority's `rpc_param.yaml`: the model read equals the file it was
/// written from; of several images' entries, the image's own is taken
/// (`--rpc` with `--image` of that name: the same orthophoto, byte for
/// byte, as from the OSSIM `.geom`); without its name, refused listing them.
#[test]
fn orthority_rpc_yaml_reads_the_images_own_entry() {
    let dir = tempfile::tempdir().unwrap();
    let geom = ventoux("left_image.geom");
    let rpc = Rpc::read(&geom).unwrap();
    let other = rpc.cropped(10.0, 0.0);
    let one = dir.path().join("one.yaml");
    std::fs::write(&one, orthority_rpc_entry("anything.tif", &rpc)).unwrap();
    assert_eq!(Rpc::read(&one).unwrap(), rpc);
    let many = dir.path().join("rpc_param.yaml");
    std::fs::write(&many, orthority_rpc_entry("other.tif", &other) + &orthority_rpc_entry("left_image.tif", &rpc)).unwrap();
    assert_eq!(Rpc::read_for(&many, Some("left_image.tif")).unwrap(), rpc);
    assert_eq!(Rpc::read_for(&many, Some("other.tif")).unwrap(), other);
    let e = Rpc::read(&many).unwrap_err().to_string();
    assert!(e.contains("rpc_param.yaml") && e.contains("2 images") && e.contains("other.tif, left_image.tif"), "{e}");
    let e = Rpc::read_for(&many, Some("third.tif")).unwrap_err().to_string();
    assert!(e.contains("none for third.tif"), "{e}");
    // A list of millions of numbers (its tree some 50 times the text) is
    // refused by its size before it is parsed.
    let huge = dir.path().join("huge.yaml");
    std::fs::write(&huge, format!("a:\n  rpc:\n    line_num_coeff: [{}]\n", vec!["1.0"; 1_500_000].join(","))).unwrap();
    let e = Rpc::read(&huge).unwrap_err().to_string();
    assert!(e.contains("huge.yaml") && e.contains("Orthority RPC YAML of"), "{e}");
    let dem = ventoux("srtm_N44E005_crop.tif");
    let (a, b) = (dir.path().join("a.tif"), dir.path().join("b.tif"));
    let extra = ["--gsd", "4", "--compress", "none"];
    for (rpc, out) in [(&many, &a), (&geom, &b)] {
        let r = pleiades_rectify(rpc, &dem, out, &extra);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    }
    // (The files differ in the source's identity, which names the RPC file.)
    let ((pa, ia), (pb, ib)) = (whole_image(&a), whole_image(&b));
    assert!((ia.width, ia.height) == (ib.width, ib.height) && pa == pb, "the orthophotos differ");
}
