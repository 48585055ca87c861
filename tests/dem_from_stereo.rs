//! `dem`: a DSM from a stereo pair. A synthetic RPC pair (two pushbroom
//! views of one relief, B/H 0.5) against its true heights, the answer
//! independent of the memory and the threads, the real Pléiades pair over
//! Mont Ventoux against SRTM, the DSM straight into `rectify`, and bad
//! pairs named.

mod common;
use common::*;
use gcm_ortho::dem::{Dem, GridDem, Height};
use gcm_ortho::geodesy::Crs;
use std::path::{Path, PathBuf};

fn utm31() -> Crs {
    Crs::from_epsg(32631).unwrap()
}

/// A synthetic in-track pair at B/H `bh`, `size` pixels a side.
fn pair(dir: &Path, bh: f64, size: u32) {
    let o = run(&[
        "synth",
        "--out",
        s(dir),
        "--camera",
        "rpc",
        "--stereo",
        &bh.to_string(),
        "--size",
        &format!("{size}x{size}"),
        "--bands",
        "1",
        "--off-nadir",
        "5",
        "--quiet",
    ]);
    assert!(o.status.success(), "synth --stereo: {}", String::from_utf8_lossy(&o.stderr));
}

fn dem_of_pair(dir: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let (l, r) = (dir.join("left.tif"), dir.join("right.tif"));
    let (lr, rr) = (dir.join("left_RPC.TXT"), dir.join("right_RPC.TXT"));
    let mut args = vec!["dem", "--left", s(&l), "--right", s(&r), "--left-rpc", s(&lr), "--right-rpc", s(&rr), "-o", s(out), "--quiet"];
    args.extend_from_slice(extra);
    run(&args)
}

fn report(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Each cell of the DSM with a height, and the reference's height there;
/// `inner`: only cells whose neighbours this many cells around have
/// heights too (off the matched area's edges).
fn against(dsm: &Path, reference: &Path, inner: usize) -> Vec<(f64, f64)> {
    let g = GridDem::read(dsm).unwrap();
    let refd = Dem::open(reference, &utm31()).unwrap();
    let has = |i: usize, j: usize| g.sample(i, j) != -9999.0;
    let mut out = Vec::new();
    for j in inner..g.height.saturating_sub(inner) {
        for i in inner..g.width.saturating_sub(inner) {
            if !(j - inner..=j + inner).all(|jj| (i - inner..=i + inner).all(|ii| has(ii, jj))) {
                continue;
            }
            let t = g.transform;
            let (x, y) = (t[0] + (i as f64 + 0.5) * t[1], t[3] + (j as f64 + 0.5) * t[5]);
            if let Height::Value(h) = refd.height(x, y) {
                out.push((g.sample(i, j) as f64, h));
            }
        }
    }
    out
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Textured synthetic ground at B/H 0.5: the DSM's height RMSE against the
/// truth is at most half the theoretical precision (GSD × H/B × 0.3), almost
/// every pixel of the overlap is matched, none on the scene's flat lake
/// while the ground around it is, and the DSM does not depend on the
/// memory or the number of threads.
#[test]
fn synthetic_rpc_pair_meets_half_the_theoretical_precision() {
    let dir = tempfile::tempdir().unwrap();
    pair(dir.path(), 0.5, 800);
    let (out, json) = (dir.path().join("dsm.tif"), dir.path().join("dsm.json"));
    let pts = dir.path().join("points.las");
    let o = dem_of_pair(dir.path(), &out, &["--gsd", "2", "--json", s(&json), "--points", s(&pts)]);
    assert!(o.status.success(), "dem: {}", String::from_utf8_lossy(&o.stderr));
    let r = report(&json);
    // The lake: no point within it (3 m in from its shore), the cells of a
    // ring around it (3 to 20 m out) nearly all matched.
    let lake = std::fs::read_to_string(dir.path().join("lake.csv")).unwrap();
    let l: Vec<f64> = lake.lines().nth(1).unwrap().split(',').map(|v| v.parse().unwrap()).collect();
    let (mut inside, mut ring) = (0, 0);
    let data = las::Reader::from_path(&pts).unwrap().read_all().unwrap();
    for p in data.points() {
        let p = p.unwrap();
        let d = (p.x - l[0]).hypot(p.y - l[1]);
        inside += usize::from(d < l[2] - 3.0);
        ring += usize::from(d > l[2] + 3.0 && d < l[2] + 20.0);
    }
    let ring_cells = std::f64::consts::PI * ((l[2] + 20.0).powi(2) - (l[2] + 3.0).powi(2)) / 4.0;
    assert!(inside == 0 && ring as f64 > 0.9 * ring_cells, "{inside} points on the lake, {ring} of {ring_cells:.0} cells around it");
    let precision = r["height_precision_m"].as_f64().unwrap();
    // 0.3 px of disparity at 0.5 m pixels and B/H 0.5: 0.3 m.
    assert!((precision - 0.3).abs() < 0.02, "theoretical precision {precision}");
    assert!(r["matched_share"].as_f64().unwrap() > 0.95, "matched {}", r["matched_share"]);
    assert!(r["intersection_check_m"].as_f64().unwrap() < 1e-4);
    assert!((r["epipolar"]["base_to_height"].as_f64().unwrap() - 0.5).abs() < 0.01);
    // No geoid given: the RPCs' heights, above the WGS 84 ellipsoid, and
    // the file says so as GDAL writes it (EPSG:4979 as the vertical key),
    // which GDAL reads as ellipsoidal heights.
    let keys = gcm_ortho::io::source::SourceImage::open(&out, 1 << 20).unwrap().info.georef.unwrap().keys;
    let crs = gcm_ortho::geodesy::geokeys::crs_of(&keys).unwrap().unwrap();
    assert!(crs.vertical().is_some_and(|v| v.is_ellipsoidal() && v.epsg == Some(4979)), "{crs}");
    if let Some(python) = python_with("osgeo.gdal", "python3-gdal") {
        let script = format!(
            "from osgeo import gdal, osr\ns = gdal.Open({:?}).GetSpatialRef()\nprint(s.GetAxesCount(), s.GetAxisName(None, 2), s.GetUTMZone())",
            out.display().to_string()
        );
        let o = std::process::Command::new(python).args(["-c", &script]).output().unwrap();
        let said = String::from_utf8_lossy(&o.stdout);
        assert_eq!(said.trim(), "3 Ellipsoidal height 31", "GDAL reads the DSM's CRS as: {said} {}", String::from_utf8_lossy(&o.stderr));
    }
    let cells = against(&out, &dir.path().join("dem.tif"), 1);
    assert!(cells.len() > 30_000, "{} cells", cells.len());
    let rmse = (cells.iter().map(|(a, b)| (a - b).powi(2)).sum::<f64>() / cells.len() as f64).sqrt();
    assert!(rmse <= 0.5 * precision, "height RMSE {rmse:.3} m over {} cells, theoretical {precision:.3} m", cells.len());
    let bias = median(cells.iter().map(|(a, b)| a - b).collect());
    assert!(bias.abs() < 0.03, "bias {bias}");

    // Fewer tiles at once, one thread: the same bytes.
    let small = dir.path().join("small.tif");
    let o = dem_of_pair(dir.path(), &small, &["--gsd", "2", "--memory", "48M", "--threads", "1"]);
    assert!(o.status.success(), "dem: {}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(read_f32(&out).3, read_f32(&small).3, "the DSM depends on the memory or the threads");
}

/// The thesis's own search (SSDA, accepted by correlation) finds the same
/// ground on textured terrain: most cells within a few tenths of a metre.
#[test]
fn ncc_search_finds_the_ground_too() {
    let dir = tempfile::tempdir().unwrap();
    pair(dir.path(), 0.5, 500);
    let out = dir.path().join("ncc.tif");
    let o = dem_of_pair(dir.path(), &out, &["--gsd", "2", "--matcher", "ncc"]);
    assert!(o.status.success(), "dem: {}", String::from_utf8_lossy(&o.stderr));
    let cells = against(&out, &dir.path().join("dem.tif"), 2);
    let abs: Vec<f64> = cells.iter().map(|(a, b)| (a - b).abs()).collect();
    let within = abs.iter().filter(|&&e| e < 0.5).count() as f64 / abs.len() as f64;
    assert!(within > 0.95 && median(abs) < 0.15, "{:.3} of cells within 0.5 m", within);
}

fn ventoux(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/ventoux").join(name)
}

/// The real Pléiades pair over Mont Ventoux (the RPCs of the full scene,
/// shifted by each crop's offset; heights above EGM96) against the SRTM
/// tile: the matched area correlates with SRTM, without a bias past 5 m,
/// and the median difference is within 8 m (a DSM of scattered trees on a
/// steep slope against SRTM's 90 m posts, itself ±6 m). The two RPCs put
/// the same ground ~4.8 epipolar rows apart: measured and taken out.
#[test]
fn ventoux_pair_agrees_with_srtm() {
    let dir = tempfile::tempdir().unwrap();
    let (out, json) = (dir.path().join("ventoux.tif"), dir.path().join("v.json"));
    let (l, r, lg, rg, geoid) =
        (ventoux("left_image.tif"), ventoux("right_image.tif"), ventoux("left_image.geom"), ventoux("right_image.geom"), ventoux("egm96_15_ventoux.gtx"));
    #[rustfmt::skip]
    let o = run(&["dem", "--left", s(&l), "--right", s(&r), "--left-rpc", s(&lg), "--right-rpc", s(&rg),
        "--left-rpc-offset", "5000,5000", "--right-rpc-offset", "4915,5162", "--geoid", s(&geoid),
        "-o", s(&out), "--gsd", "2", "--json", s(&json), "--quiet"]);
    assert!(o.status.success(), "dem: {}", String::from_utf8_lossy(&o.stderr));
    let rep = report(&json);
    // Heights above EGM96 (the geoid given), and the file says so.
    assert_eq!(rep["crs"], "EPSG:32631+5773");
    let keys = gcm_ortho::io::source::SourceImage::open(&out, 1 << 20).unwrap().info.georef.unwrap().keys;
    let crs = gcm_ortho::geodesy::geokeys::crs_of(&keys).unwrap().unwrap();
    assert_eq!(crs.vertical().and_then(|v| v.epsg), Some(5773), "{crs}");
    let shift = rep["pointing"]["row_shift"].as_f64().unwrap();
    assert!((shift - 4.84).abs() < 0.3, "the pair's rows {shift} px apart");
    assert!(rep["matched_share"].as_f64().unwrap() > 0.8, "matched {}", rep["matched_share"]);
    let cells = against(&out, &ventoux("srtm_N44E005_crop.tif"), 2);
    assert!(cells.len() > 2500, "{} cells", cells.len());
    let d: Vec<f64> = cells.iter().map(|(a, b)| a - b).collect();
    let bias = median(d.clone());
    let med_abs = median(d.iter().map(|v| v.abs()).collect());
    let n = cells.len() as f64;
    let (ma, mb) = (cells.iter().map(|c| c.0).sum::<f64>() / n, cells.iter().map(|c| c.1).sum::<f64>() / n);
    let cov: f64 = cells.iter().map(|c| (c.0 - ma) * (c.1 - mb)).sum();
    let (va, vb): (f64, f64) = (cells.iter().map(|c| (c.0 - ma).powi(2)).sum(), cells.iter().map(|c| (c.1 - mb).powi(2)).sum());
    let corr = cov / (va * vb).sqrt();
    assert!(bias.abs() <= 5.0 && med_abs <= 8.0 && corr >= 0.8, "bias {bias:.2} m, median |diff| {med_abs:.2} m, correlation {corr:.3}");
}

/// The DSM goes straight into `rectify`: the synthetic left view
/// orthorectified on it matches the one on the true heights.
#[test]
fn dsm_feeds_rectify() {
    let dir = tempfile::tempdir().unwrap();
    pair(dir.path(), 0.5, 400);
    let dsm = dir.path().join("dsm.tif");
    assert!(dem_of_pair(dir.path(), &dsm, &["--gsd", "1"]).status.success());
    // A square of 80 m in the DSM's middle.
    let g = GridDem::read(&dsm).unwrap();
    let (cx, cy) = (g.transform[0] + g.width as f64 * g.transform[1] / 2.0, g.transform[3] + g.height as f64 * g.transform[5] / 2.0);
    let bounds = format!("{},{},{},{}", (cx - 40.0).round(), (cy - 40.0).round(), (cx + 40.0).round(), (cy + 40.0).round());
    let ortho = |dem: &Path, name: &str| {
        let out = dir.path().join(name);
        let (l, lr) = (dir.path().join("left.tif"), dir.path().join("left_RPC.TXT"));
        #[rustfmt::skip]
        let o = run(&["rectify", "--image", s(&l), "--rpc", s(&lr), "--dem", s(dem), "-o", s(&out), "--crs", "EPSG:32631",
            "--gsd", "0.5", "--bounds", &bounds, "--quiet", "--dem-hole", "nodata"]);
        assert!(o.status.success(), "rectify: {}", String::from_utf8_lossy(&o.stderr));
        read_f32_any(&out)
    };
    let (a, b) = (ortho(&dsm, "on_dsm.tif"), ortho(&dir.path().join("dem.tif"), "on_truth.tif"));
    let pairs: Vec<(f32, f32)> = a.iter().zip(&b).filter(|(x, y)| **x != 0.0 && **y != 0.0).map(|(x, y)| (*x, *y)).collect();
    assert!(pairs.len() > 20_000, "{} pixels", pairs.len());
    let mean = pairs.iter().map(|(x, y)| (x - y).abs() as f64).sum::<f64>() / pairs.len() as f64;
    assert!(mean < 1.0, "orthophotos {mean:.3} DN apart on average");
}

/// Samples of a one-band 8-bit orthophoto as f32.
fn read_f32_any(path: &Path) -> Vec<f32> {
    let (bytes, info) = whole_image(path);
    assert_eq!(info.bands, 1);
    bytes.iter().map(|&v| v as f32).collect()
}

/// Pairs that cannot make a DSM are refused, each named, with nothing
/// written.
#[test]
fn bad_pairs_are_named() {
    let dir = tempfile::tempdir().unwrap();
    pair(dir.path(), 0.5, 300);
    let out = dir.path().join("x.tif");
    let no_output = |o: &std::process::Output, says: &str| {
        assert!(!o.status.success());
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(says), "{e}");
        assert_eq!(e.lines().count(), 1, "{e}");
        assert!(!out.exists());
    };
    // Not overlapping: the right view placed 100 km along its scene.
    no_output(&dem_of_pair(dir.path(), &out, &["--gsd", "2", "--right-rpc-offset", "100000,0"]), "do not overlap");
    // Cells no match resolves (a thousandth of the ground pixel and finer).
    no_output(&dem_of_pair(dir.path(), &out, &["--gsd", "0.0001"]), "--gsd: 0.0001 is finer than a 1000th of the images' ground pixel");
    // Cells the gridding's memory cannot hold (4.5e10 cells at --memory 64M).
    no_output(&dem_of_pair(dir.path(), &out, &["--gsd", "0.001", "--memory", "64M"]), "more than a quarter of the memory given");
    // Settings refused before any reading: a DSM in degrees, no blunder sigma.
    no_output(&dem_of_pair(dir.path(), &out, &["--gsd", "2", "--crs", "EPSG:4326"]), "--crs: EPSG:4326 is in degrees");
    no_output(&dem_of_pair(dir.path(), &out, &["--gsd", "2", "--blunders", "0"]), "--blunders: must be a positive number");
    // One image twice.
    let (l, lr) = (dir.path().join("left.tif"), dir.path().join("left_RPC.TXT"));
    no_output(&run(&["dem", "--left", s(&l), "--right", s(&l), "--left-rpc", s(&lr), "--right-rpc", s(&lr), "-o", s(&out), "--gsd", "2"]), "same image");
    // The output over an input.
    let o = dem_of_pair(dir.path(), &dir.path().join("right.tif"), &["--gsd", "2"]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("input"));
    // A base too short.
    let low = dir.path().join("low");
    pair(&low, 0.03, 300);
    no_output(&dem_of_pair(&low, &out, &["--gsd", "2"]), "base-to-height ratio is 0.030");
    // Frame cameras in two CRSs.
    let blk = dir.path().join("blk");
    let o = run(&["synth", "--out", s(&blk), "--block", "2x1", "--camera", "digital", "--size", "300x200", "--bands", "1", "--quiet"]);
    assert!(o.status.success());
    let cam2 = std::fs::read_to_string(blk.join("scans/002.toml")).unwrap().replace("EPSG:32631", "EPSG:32632");
    std::fs::write(blk.join("scans/002b.toml"), cam2).unwrap();
    let p = |n: &str| blk.join("scans").join(n);
    let (a, b, ca, cb) = (p("001.tif"), p("002.tif"), p("001.toml"), p("002b.toml"));
    #[rustfmt::skip]
    let o = run(&["dem", "--left", s(&a), "--right", s(&b), "--left-camera", s(&ca), "--right-camera", s(&cb),
        "-o", s(&out), "--gsd", "2", "--heights", "100,400"]);
    no_output(&o, "different CRSs (EPSG:32631 and EPSG:32632)");
}

/// Two overlapping digital frames of a synthetic block (60 % forward
/// overlap, B/H 0.2, each exposed differently, flown 9 m apart in height,
/// so that the plane's epipolar rows leave up to 0.4 px of vertical
/// parallax): the DSM's median error within the matched area is at most
/// 0.6 of the theoretical precision (0.50 when measured) and its bias a
/// fifth of it (0.15).
#[test]
fn frame_pair_finds_the_ground() {
    let dir = tempfile::tempdir().unwrap();
    let blk = dir.path().join("blk");
    let o = run(&["synth", "--out", s(&blk), "--block", "2x1", "--camera", "digital", "--size", "900x600", "--bands", "1", "--quiet"]);
    assert!(o.status.success());
    let p = |n: &str| blk.join("scans").join(n);
    let (a, b, ca, cb) = (p("001.tif"), p("002.tif"), p("001.toml"), p("002.toml"));
    let (out, json) = (dir.path().join("dsm.tif"), dir.path().join("dsm.json"));
    // No heights given: the search spans what a B/H of 0.1 to 1 allows
    // below the cameras, and the pair's sparse matches narrow it.
    #[rustfmt::skip]
    let o = run(&["dem", "--left", s(&a), "--right", s(&b), "--left-camera", s(&ca), "--right-camera", s(&cb),
        "-o", s(&out), "--gsd", "2", "--json", s(&json), "--quiet"]);
    assert!(o.status.success(), "dem: {}", String::from_utf8_lossy(&o.stderr));
    assert!(o.stderr.is_empty(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = report(&json);
    let precision = r["height_precision_m"].as_f64().unwrap();
    assert!(r["matched_share"].as_f64().unwrap() > 0.85, "matched {}", r["matched_share"]);
    let cells = against(&out, &blk.join("dem.tif"), 3);
    assert!(cells.len() > 3000, "{} cells", cells.len());
    let d: Vec<f64> = cells.iter().map(|(a, b)| a - b).collect();
    let med_abs = median(d.iter().map(|v| v.abs()).collect());
    let bias = median(d);
    assert!(med_abs < 0.6 * precision && bias.abs() < 0.2 * precision, "median |error| {med_abs:.3} m, bias {bias:.3} m, theoretical {precision:.3} m");
}

/// SIGTERM while the tiles are matched: exit 143, nothing left in the
/// output's folder (the points, the DSM's temporary).
#[test]
fn stopped_run_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    pair(dir.path(), 0.5, 1500);
    let outdir = dir.path().join("out");
    std::fs::create_dir(&outdir).unwrap();
    let (l, r) = (dir.path().join("left.tif"), dir.path().join("right.tif"));
    let (lr, rr) = (dir.path().join("left_RPC.TXT"), dir.path().join("right_RPC.TXT"));
    let out = outdir.join("dsm.tif");
    #[rustfmt::skip]
    let mut child = std::process::Command::new(bin())
        .args(["dem", "--left", s(&l), "--right", s(&r), "--left-rpc", s(&lr), "--right-rpc", s(&rr), "-o", s(&out), "--gsd", "2", "--quiet"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Its temporary folder is made before the first tile.
    let t0 = std::time::Instant::now();
    while std::fs::read_dir(&outdir).unwrap().count() == 0 {
        assert!(child.try_wait().unwrap().is_none(), "the run ended before it began matching");
        assert!(t0.elapsed().as_secs() < 60);
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    assert!(std::process::Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap().success());
    let o = wait_deadline(child, 60);
    assert_eq!(o.status.code(), Some(143), "{}", String::from_utf8_lossy(&o.stderr));
    let left: Vec<_> = std::fs::read_dir(&outdir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

/// `dem --shard I/N` matches the I-th share of the epipolar tiles' rows and
/// writes their points; `grid` of the pieces' points in shard order, as
/// the report says, is the whole run's DSM value for value (for N
/// machines: matching is nearly all of the work). A shard past N, or one
/// asked for the DSM's quality raster, is refused by name.
#[test]
fn shards_points_gridded_together_are_the_whole_runs_dsm() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    pair(d, 0.5, 1200);
    let (single, single_q) = (d.join("single.tif"), d.join("single_q.tif"));
    let o = dem_of_pair(d, &single, &["--gsd", "2", "--quality", s(&single_q)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (mut pieces, mut qualities) = (Vec::new(), Vec::new());
    let mut then = String::new();
    for i in 1..=3 {
        let (piece, quality) = (d.join(format!("piece_{i}.las")), d.join(format!("quality_{i}.las")));
        let json = d.join(format!("piece_{i}.json"));
        let o = dem_of_pair(d, &piece, &["--gsd", "2", "--shard", &format!("{i}/3"), "--quality", s(&quality), "--json", s(&json)]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let r = report(&json);
        assert!(r["dsm"].is_null() && r["points_written"].as_u64().unwrap() > 1000, "{r}");
        then = r["then"].as_str().unwrap().to_string();
        pieces.push(piece);
        qualities.push(quality);
    }
    // The commands the report gives, with the pieces for PIECE_1 … PIECE_3
    // and QUALITY_1 … QUALITY_3: the whole run's DSM and quality raster.
    let (dsm_command, quality_command) = then.split_once("; ").expect("two commands");
    for (command, files, name, single) in [(dsm_command, &pieces, "DSM", &single), (quality_command, &qualities, "QUALITY", &single_q)] {
        let prefix = if name == "DSM" { "PIECE" } else { "QUALITY" };
        assert!(command.starts_with(&format!("gcm-ortho grid {prefix}_1 … {prefix}_3 (in shard order) ")), "{command}");
        let (_, options) = command.split_once("(in shard order) ").unwrap();
        let gridded = d.join(format!("gridded_{name}.tif"));
        let mut args: Vec<String> = vec!["grid".into()];
        args.extend(files.iter().map(|p| s(p).to_string()));
        args.extend(options.split_whitespace().map(|w| w.trim_matches('\'').to_string()).filter(|w| w != "-o" && w != name));
        args.extend(["-o".into(), s(&gridded).into(), "--quiet".into()]);
        let o = run(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let (a, b) = (read_f32(single).3, read_f32(&gridded).3);
        assert_eq!(a.len(), b.len(), "{name}");
        assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()), "the pieces' {name} differs from the whole run's");
        assert!(a.iter().filter(|v| **v != -9999.0).count() > 50_000, "{name}");
    }
    for (extra, named) in [(&["--shard", "4/3"][..], "--shard"), (&["--shard", "1/3", "--points", "p.las"][..], "--points")] {
        let out = d.join("refused.las");
        let mut e = vec!["--gsd", "2"];
        e.extend_from_slice(extra);
        let o = dem_of_pair(d, &out, &e);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(named), "{err}");
        assert!(!out.exists());
    }
}
