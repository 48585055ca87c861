//! `grid`: a DEM from irregular points. Analytic surfaces sampled at random
//! points (planes exact, a paraboloid, a box city), GDAL's `gdal_grid` on
//! the same points, LAS and LAZ written here read as the CSV is, the DEM
//! independent of the block it is made in, blunders found, bad input named.

mod common;
use common::*;
use std::path::{Path, PathBuf};

/// Points from a fixed seed (xorshift), uniform on `[0, size)²` from
/// (500000, 4000000).
fn random_points(n: usize, size: f64, seed: u64, z: impl Fn(f64, f64) -> f64) -> Vec<[f64; 3]> {
    let mut s = seed.max(1);
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let (u, v) = (next() * size, next() * size);
            [500000.0 + u, 4000000.0 + v, z(u, v)]
        })
        .collect()
}

fn write_csv(path: &Path, pts: &[[f64; 3]]) {
    let mut text = String::from("x,y,z\n");
    for p in pts {
        // Shortest round-trip: the file holds the points exactly.
        text.push_str(&format!("{:?},{:?},{:?}\n", p[0], p[1], p[2]));
    }
    std::fs::write(path, text).unwrap();
}

fn plane(u: f64, v: f64) -> f64 {
    100.0 + 0.02 * u - 0.013 * v
}

fn bowl(u: f64, v: f64) -> f64 {
    50.0 + ((u - 500.0).powi(2) + (v - 500.0).powi(2)) / 5000.0
}

/// The DEM's cells (NaN where it has none) and its size.
fn cells(path: &Path) -> (u32, u32, Vec<f64>) {
    let (w, h, _, v) = read_f32(path);
    (w, h, v.into_iter().map(|z| if z == -9999.0 { f64::NAN } else { z as f64 }).collect())
}

fn grid(dir: &Path, name: &str, args: &[&str]) -> (PathBuf, std::process::Output) {
    let out = dir.join(name);
    let mut all = vec!["grid", "-o", s(&out), "--quiet"];
    all.extend_from_slice(args);
    let o = run(&all);
    (out, o)
}

fn ok(o: &std::process::Output) {
    assert!(o.status.success(), "grid failed: {}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn a_tin_of_points_on_a_plane_is_the_plane_at_every_cell() {
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("plane.csv");
    write_csv(&csv, &random_points(20000, 1000.0, 7, plane));
    let (dem, o) = grid(d.path(), "plane.tif", &[s(&csv), "--gsd", "2", "--crs", "EPSG:32631", "--json", s(&d.path().join("r.json"))]);
    ok(&o);
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.path().join("r.json")).unwrap()).unwrap();
    assert_eq!(r["blunders"], 0, "a plane has no blunders: {r}");
    assert_eq!(r["points_used"], 20000);
    let (w, h, z) = cells(&dem);
    assert_eq!((w, h), (500, 500));
    let mut valid = 0;
    for j in 0..h {
        for i in 0..w {
            let v = z[(j * w + i) as usize];
            if v.is_nan() {
                continue;
            }
            valid += 1;
            let t = plane((i as f64 + 0.5) * 2.0, 1000.0 - (j as f64 + 0.5) * 2.0);
            // Exact but for the file's Float32.
            assert!((v - t).abs() <= t.abs() * f64::from(f32::EPSILON) * 0.5 + 1e-9, "cell {i},{j}: {v} against {t}");
        }
    }
    // Only cells outside the points' hull, along the edges, have none.
    assert!(valid as f64 > 0.99 * (w * h) as f64, "{valid} cells with a height");
}

#[test]
fn linear_interpolation_in_a_triangle_is_exact_on_a_plane_in_double() {
    use gcm_ortho::gridding::methods::linear;
    use gcm_ortho::gridding::neighbourhood::Post;
    let f = |x: f64, y: f64| 1234.5 + 0.37 * x - 0.21 * y;
    let v = [(3.1, 7.7), (250.9, 11.3), (97.2, 301.4)].map(|(x, y)| Post { x, y, z: f(x, y) });
    for (x, y) in [(100.0, 100.0), (50.0, 20.0), (120.5, 200.25)] {
        assert!((linear(x, y, v) - f(x, y)).abs() <= 1e-9);
    }
}

#[test]
fn the_tin_matches_gdal_grid_linear_and_idw_matches_gdal_grid_invdist() {
    if !have("gdal_grid") {
        eprintln!("skipped: GDAL is not installed");
        return;
    }
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("bowl.csv");
    let pts = random_points(5000, 1000.0, 11, bowl);
    write_csv(&csv, &pts);
    // GDAL reads the CSV through a VRT naming its columns.
    let vrt = d.path().join("bowl.vrt");
    std::fs::write(
        &vrt,
        format!(
            "<OGRVRTDataSource><OGRVRTLayer name=\"bowl\"><SrcDataSource>{}</SrcDataSource><GeometryType>wkbPoint</GeometryType><GeometryField encoding=\"PointFromColumns\" x=\"x\" y=\"y\" z=\"z\"/></OGRVRTLayer></OGRVRTDataSource>",
            s(&csv)
        ),
    )
    .unwrap();
    let extent = ["-txe", "500000", "501000", "-tye", "4001000", "4000000", "-outsize", "200", "200", "-ot", "Float64"];
    let bounds = "500000,4000000,501000,4001000";
    for (name, algo, ours) in [
        ("linear", "linear:radius=0:nodata=-9999", vec!["--method", "tin", "--max-edge", "2000"]),
        (
            "invdist",
            "invdist:power=2:smoothing=0:radius1=40:radius2=40:angle=0:max_points=0:min_points=1:nodata=-9999",
            vec!["--method", "idw", "--radius", "40"],
        ),
    ] {
        let theirs = d.path().join(format!("gdal_{name}.tif"));
        let mut args = vec!["-q", "-l", "bowl", "-a", algo];
        args.extend_from_slice(&extent);
        args.extend_from_slice(&[s(&vrt), s(&theirs)]);
        let g = std::process::Command::new("gdal_grid").args(&args).output().unwrap();
        assert!(g.status.success(), "gdal_grid: {}", String::from_utf8_lossy(&g.stderr));
        let mut a = vec![s(&csv), "--gsd", "5", "--crs", "EPSG:32631", "--bounds", bounds, "--blunders", "none"];
        a.extend(ours.iter().copied());
        let (dem, o) = grid(d.path(), &format!("ours_{name}.tif"), &a);
        ok(&o);
        let (w, h, z) = cells(&dem);
        let (gw, gh, _, t) = read_f64(&theirs);
        assert_eq!((w, h), (gw, gh));
        let (mut compared, mut beyond, mut worst) = (0, 0, 0.0f64);
        for k in 0..z.len() {
            if z[k].is_nan() || t[k] == -9999.0 {
                assert_eq!(z[k].is_nan(), t[k] == -9999.0 || name == "linear", "{name}: cell {k} has a height in one and not the other ({} / {})", z[k], t[k]);
                continue;
            }
            compared += 1;
            // Ours is Float32; GDAL's Float64.
            let e = (z[k] - t[k]).abs() - t[k].abs() * f64::from(f32::EPSILON) * 0.5;
            worst = worst.max(e);
            beyond += usize::from(e > 1e-6);
        }
        assert!(compared > 35000, "{name}: {compared} cells compared");
        // Where four points are all but on one circle, GDAL's triangulation
        // (qhull, in floating point) may take the other diagonal than ours
        // (exact predicates): a cell in ten thousand, off by micrometres.
        assert!(beyond <= compared / 10000 && worst <= 1e-4, "{name}: {beyond} cells beyond 1e-6 m of gdal_grid (Float32 rounding aside), the worst {worst} m");
    }
}

/// A LAS file of `pts` (format 1, scale 1 mm), compressed (LAZ) where asked,
/// every tenth point classed as noise (7) and every other one ground (2).
fn write_las(path: &Path, pts: &[[f64; 3]], laz: bool) {
    let mut b = las::Builder::from((1, 2));
    b.point_format = las::point::Format::new(1).unwrap();
    b.point_format.is_compressed = laz;
    b.transforms = las::Vector {
        x: las::Transform { scale: 0.001, offset: 500000.0 },
        y: las::Transform { scale: 0.001, offset: 4000000.0 },
        z: las::Transform { scale: 0.001, offset: 0.0 },
    };
    let mut w = las::Writer::from_path(path, b.into_header().unwrap()).unwrap();
    for (k, p) in pts.iter().enumerate() {
        let class = if k % 10 == 9 {
            7
        } else if k % 2 == 0 {
            2
        } else {
            1
        };
        w.write_point(las::Point {
            x: p[0],
            y: p[1],
            z: p[2],
            classification: las::point::Classification::new(class).unwrap(),
            gps_time: Some(0.0),
            ..Default::default()
        })
        .unwrap();
    }
    w.close().unwrap();
}

#[test]
fn las_laz_and_csv_of_the_same_points_make_the_same_dem_and_classes_filter() {
    let d = tempfile::tempdir().unwrap();
    // Millimetres, as the LAS holds them.
    let pts: Vec<[f64; 3]> = random_points(6000, 500.0, 5, bowl).into_iter().map(|p| p.map(|v| (v * 1000.0).round() / 1000.0)).collect();
    let (las_path, laz_path, csv) = (d.path().join("p.las"), d.path().join("p.laz"), d.path().join("p.csv"));
    write_las(&las_path, &pts, false);
    write_las(&laz_path, &pts, true);
    // The CSV holds what the LAS keeps by default: noise (class 7) left out.
    let kept: Vec<[f64; 3]> = pts.iter().enumerate().filter(|(k, _)| k % 10 != 9).map(|(_, p)| *p).collect();
    write_csv(&csv, &kept);
    let common = ["--gsd", "2", "--crs", "EPSG:32631"];
    let mut made = Vec::new();
    for (name, input) in [("las.tif", &las_path), ("laz.tif", &laz_path), ("csv.tif", &csv)] {
        let mut a = vec![s(input)];
        a.extend_from_slice(&common);
        let (dem, o) = grid(d.path(), name, &a);
        ok(&o);
        made.push(cells(&dem).2);
    }
    let same = |a: &[f64], b: &[f64]| a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()));
    assert!(same(&made[0], &made[1]), "LAZ differs from LAS");
    assert!(same(&made[0], &made[2]), "LAS differs from the CSV of its points");
    // Ground only (class 2): the even points.
    let ground: Vec<[f64; 3]> = pts.iter().step_by(2).copied().collect();
    let gcsv = d.path().join("g.csv");
    write_csv(&gcsv, &ground);
    let (a, o) =
        grid(d.path(), "ground_las.tif", &[s(&laz_path), "--class", "2", "--gsd", "2", "--crs", "EPSG:32631", "--bounds", "500000,4000000,500500,4000500"]);
    ok(&o);
    let (b, o) = grid(d.path(), "ground_csv.tif", &[s(&gcsv), "--gsd", "2", "--crs", "EPSG:32631", "--bounds", "500000,4000000,500500,4000500"]);
    ok(&o);
    assert!(same(&cells(&a).2, &cells(&b).2), "--class 2 is not the ground points' DEM");
}

#[test]
fn the_dem_does_not_depend_on_the_block_it_is_made_in() {
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("city.csv");
    // A box city on a bowl, clustered and gappy: most points in the west.
    let pts: Vec<[f64; 3]> = random_points(30000, 800.0, 3, |u, v| bowl(u, v) + if u % 100.0 < 40.0 && v % 100.0 < 40.0 { 20.0 } else { 0.0 })
        .into_iter()
        .filter(|p| (p[0] - 500000.0) < 300.0 || (p[0] as u64 + p[1] as u64).is_multiple_of(5))
        .collect();
    write_csv(&csv, &pts);
    for method in ["tin", "idw", "nearest", "max"] {
        let mut files = Vec::new();
        for block in ["16", "64", "256"] {
            let (dem, o) = grid(
                d.path(),
                &format!("{method}_{block}.tif"),
                &[s(&csv), "--gsd", "1", "--crs", "EPSG:32631", "--method", method, "--block", block, "--radius", "6"],
            );
            ok(&o);
            files.push(std::fs::read(dem).unwrap());
        }
        assert!(files[0] == files[1] && files[1] == files[2], "{method}: the DEM changes with the block");
    }
    // Natural neighbours: the same to the bit, but where a triangle whose
    // circle holds a cell's centre is a sliver's along the points' hull,
    // its circle spanning more bins than a block checks (measured: 2 cells
    // in 800,000, by under a centimetre, both beside the hull, at blocks
    // of 16 against 64 or 256).
    let mut natural = Vec::new();
    for block in ["16", "64", "256"] {
        let (dem, o) =
            grid(d.path(), &format!("natural_{block}.tif"), &[s(&csv), "--gsd", "1", "--crs", "EPSG:32631", "--method", "natural", "--block", block]);
        ok(&o);
        natural.push(cells(&dem).2);
    }
    assert!(natural[1].iter().zip(&natural[2]).all(|(x, y)| x.to_bits() == y.to_bits()), "natural: the DEM changes between blocks of 64 and 256");
    let differ: Vec<f64> = natural[0].iter().zip(&natural[2]).filter(|(x, y)| x.to_bits() != y.to_bits()).map(|(x, y)| x - y).collect();
    assert!(
        differ.len() <= 4 && differ.iter().all(|d| d.abs() < 0.02),
        "natural: {} cells change with the block: {:?}",
        differ.len(),
        &differ[..differ.len().min(8)]
    );
    // Another tile size: the same cells.
    let (a, o) = grid(d.path(), "t128.tif", &[s(&csv), "--gsd", "1", "--crs", "EPSG:32631", "--tile", "128"]);
    ok(&o);
    let (b, o) = grid(d.path(), "t512.tif", &[s(&csv), "--gsd", "1", "--crs", "EPSG:32631", "--tile", "512", "--block", "32"]);
    ok(&o);
    let (za, zb) = (cells(&a).2, cells(&b).2);
    assert!(za.iter().zip(&zb).all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan())), "the cells change with the tile size");
}

#[test]
fn a_lattice_of_points_grids_the_same_whatever_diagonals_the_triangulation_draws() {
    // An XYZ export of another DEM: every square's four corners on one
    // circle, so that either diagonal is Delaunay; with spikes to drop.
    let d = tempfile::tempdir().unwrap();
    let mut text = String::from("x y z\n");
    let mut planted = 0;
    for i in 0..150u32 {
        for j in 0..150u32 {
            let (u, v) = (f64::from(i) * 5.0, f64::from(j) * 5.0);
            let mut z = bowl(u, v) + f64::from((i * 7 + j * 3) % 5) * 0.1;
            if (i * 31 + j * 17) % 97 == 0 {
                z += 30.0;
                planted += 1;
            }
            text.push_str(&format!("{} {} {z:?}\n", 500000.0 + u, 4000000.0 + v));
        }
    }
    let xyz = d.path().join("lattice.xyz");
    std::fs::write(&xyz, text).unwrap();
    for method in ["tin", "natural"] {
        let mut files = Vec::new();
        for block in ["16", "64", "256"] {
            let json = d.path().join(format!("r{block}.json"));
            let (dem, o) = grid(
                d.path(),
                &format!("lattice_{method}_{block}.tif"),
                &[s(&xyz), "--gsd", "2", "--crs", "EPSG:32631", "--block", block, "--method", method, "--json", s(&json)],
            );
            ok(&o);
            let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
            let dropped = r["blunders"].as_u64().unwrap();
            assert!(dropped <= planted && dropped + planted / 20 >= planted, "{dropped} dropped of {planted}");
            files.push(std::fs::read(dem).unwrap());
        }
        assert!(files[0] == files[1] && files[1] == files[2], "{method}: the lattice's DEM changes with the block");
    }
}

#[test]
fn a_blunder_hidden_by_two_others_beside_it_is_found_once_they_are_dropped() {
    // A lattice (each point's ring its eight neighbours) with three spikes
    // in a row: the two outer ones have one spike among their neighbours
    // (left out as the highest), the middle one two, so it is within its
    // ring's heights until they are dropped. Elsewhere a lone spike.
    let d = tempfile::tempdir().unwrap();
    let mut text = String::from("x y z\n");
    for i in 0..60u32 {
        for j in 0..60u32 {
            let (u, v) = (f64::from(i) * 5.0, f64::from(j) * 5.0);
            let spike = (j == 30 && (29..=31).contains(&i)) || (i, j) == (10, 45);
            let z = bowl(u, v) + if spike { 25.0 } else { 0.0 };
            text.push_str(&format!("{} {} {z:?}\n", 500000.0 + u, 4000000.0 + v));
        }
    }
    let xyz = d.path().join("spikes.xyz");
    std::fs::write(&xyz, text).unwrap();
    let json = d.path().join("r.json");
    let (dem, o) = grid(d.path(), "spikes.tif", &[s(&xyz), "--gsd", "1", "--crs", "EPSG:32631", "--json", s(&json)]);
    ok(&o);
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(r["blunders"].as_u64().unwrap(), 4, "the three spikes in a row and the lone one");
    // The middle spike's place has the bowl's height back (the TIN of a
    // lattice is within a few centimetres of the bowl).
    let (w, _, z) = cells(&dem);
    let b: Vec<f64> = r["bounds"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let (i, j) = ((150.0 - (b[0] - 500000.0)).floor(), ((b[3] - 4000000.0) - 150.0).floor());
    let (u, v) = (b[0] - 500000.0 + i + 0.5, b[3] - 4000000.0 - j - 0.5);
    let got = z[(j as u32 * w + i as u32) as usize];
    assert!((got - bowl(u, v)).abs() < 0.1, "the middle spike left: {got} against the bowl's {}", bowl(u, v));
}

#[test]
fn pieces_made_apart_and_assembled_are_the_single_run_byte_for_byte() {
    let d = tempfile::tempdir().unwrap();
    let mut pts = random_points(20000, 600.0, 8, bowl);
    for p in pts.iter_mut().step_by(97) {
        p[2] += 25.0;
    }
    let csv = d.path().join("p.csv");
    write_csv(&csv, &pts);
    let common = [s(&csv), "--gsd", "1", "--crs", "EPSG:32631", "--tile", "128"];
    let (whole, o) = grid(d.path(), "whole.tif", &common);
    ok(&o);
    let mut pieces = Vec::new();
    for shard in ["1/3", "2/3", "3/3"] {
        let mut a = common.to_vec();
        a.extend_from_slice(&["--shard", shard]);
        let (piece, o) = grid(d.path(), &format!("piece{}.tif", &shard[..1]), &a);
        ok(&o);
        pieces.push(piece);
    }
    let joined = d.path().join("joined.tif");
    let mut a = vec!["assemble", "-o", s(&joined)];
    a.extend(pieces.iter().map(|p| s(p)));
    let o = run(&a);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::read(&joined).unwrap() == std::fs::read(&whole).unwrap(), "the assembled DEM is not the single run's");
    // A piece of another DEM (other settings) is refused.
    let mut a = common.to_vec();
    a.extend_from_slice(&["--shard", "3/3", "--method", "idw"]);
    let (other, o) = grid(d.path(), "other.tif", &a);
    ok(&o);
    let o = run(&["assemble", "-o", s(&d.path().join("mixed.tif")), s(&pieces[0]), s(&pieces[1]), s(&other)]);
    assert!(!o.status.success(), "pieces of two DEMs were joined");
}

#[test]
fn one_percent_blunders_are_dropped_and_the_clean_surface_comes_back() {
    let d = tempfile::tempdir().unwrap();
    let mut pts = random_points(40000, 1000.0, 9, bowl);
    let mut planted = 0;
    for (k, p) in pts.iter_mut().enumerate() {
        if k % 100 == 37 {
            p[2] += if k % 200 == 37 { 1.0 } else { -1.0 } * (3.0 + (k % 4700) as f64 / 100.0);
            planted += 1;
        }
    }
    let csv = d.path().join("b.csv");
    write_csv(&csv, &pts);
    let json = d.path().join("r.json");
    let (dem, o) = grid(d.path(), "b.tif", &[s(&csv), "--gsd", "2", "--crs", "EPSG:32631", "--json", s(&json)]);
    ok(&o);
    assert!(String::from_utf8_lossy(&o.stderr).contains("dropped as blunders"), "the drop is said");
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let dropped = r["blunders"].as_u64().unwrap();
    assert!(dropped >= planted && dropped <= planted + planted / 5, "{dropped} dropped of {planted} planted");
    let (w, h, z) = cells(&dem);
    let mut off = 0;
    for j in 0..h {
        for i in 0..w {
            let v = z[(j * w + i) as usize];
            if !v.is_nan() && (v - bowl((i as f64 + 0.5) * 2.0, 1000.0 - (j as f64 + 0.5) * 2.0)).abs() > 0.05 {
                off += 1;
            }
        }
    }
    // A TIN of the clean points is within 0.05 m of the bowl everywhere;
    // a blunder left (on the hull, beside another) spoils a few cells.
    assert!(off < (w * h / 500) as usize, "{off} cells off the clean surface");
}

#[test]
fn bad_points_are_refused_naming_the_file_and_leaving_no_dem() {
    let d = tempfile::tempdir().unwrap();
    let p = |n: &str| d.path().join(n);
    std::fs::write(p("empty.csv"), "x,y,z\n").unwrap();
    std::fs::write(p("line.csv"), "x,y,z\n0,0,1\n1,1,2\n2,2,3\n3,3,4\n").unwrap();
    std::fs::write(p("nan.csv"), "x,y,z\n0,0,1\n5,0,nan\n0,5,2\n").unwrap();
    std::fs::write(p("degrees.csv"), "x,y,z\n2.35,48.85,35\n2.36,48.86,40\n2.35,48.86,41\n").unwrap();
    std::fs::write(p("nocrs.csv"), "x,y,z\n0,0,1\n5,0,2\n0,5,3\n").unwrap();
    std::fs::write(p("header.csv"), "a,b,c\n0,0,1\n").unwrap();
    std::fs::write(p("far.csv"), "x,y,z\n0,0,1\n1e300,1e300,2\n5,0,3\n").unwrap();
    std::fs::write(p("high.csv"), "x,y,z\n0,0,1\n10,0,1e300\n0,10,3\n").unwrap();
    // A LAS header claiming 10^12 points in a file of a few hundred bytes.
    let las_path = p("huge.las");
    write_las(&las_path, &random_points(3, 10.0, 1, plane), false);
    let mut bytes = std::fs::read(&las_path).unwrap();
    bytes[107..111].copy_from_slice(&u32::MAX.to_le_bytes());
    if bytes[24] == 1 && bytes[25] >= 4 {
        bytes[247..255].copy_from_slice(&1_000_000_000_000u64.to_le_bytes());
    }
    std::fs::write(&las_path, &bytes).unwrap();
    // A header whose z scale is NaN, and one whose x offset is infinite.
    for (name, at, value) in [("nanscale.las", 147, f64::NAN), ("infoffset.las", 155, f64::INFINITY)] {
        write_las(&p(name), &random_points(3, 10.0, 1, plane), false);
        let mut bytes = std::fs::read(p(name)).unwrap();
        bytes[at..at + 8].copy_from_slice(&value.to_le_bytes());
        std::fs::write(p(name), &bytes).unwrap();
    }
    // LAZ (chunks of 50,000 points: three for 120,000) whose header counts
    // half or twice its points, and one whose chunk table counts 4·10⁹
    // chunks (the decoder reserved them: an abort).
    write_las(&p("good.laz"), &random_points(120_000, 300.0, 3, plane), true);
    let good = std::fs::read(p("good.laz")).unwrap();
    let data_start = u32::from_le_bytes(good[96..100].try_into().unwrap()) as usize;
    let table = i64::from_le_bytes(good[data_start..data_start + 8].try_into().unwrap()) as usize;
    assert_eq!(u32::from_le_bytes(good[table + 4..table + 8].try_into().unwrap()), 3, "chunks of the LAZ written");
    for (name, at, value) in [("half.laz", 107, 60_000u32), ("twice.laz", 107, 240_000), ("chunks.laz", table + 4, 0xffff_fff0)] {
        let mut bytes = good.clone();
        bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
        std::fs::write(p(name), &bytes).unwrap();
    }
    // And one whose LASzip record lists no fields of a point (the decoder
    // panicked): the item count, 32 bytes into the record's data.
    let vlr = good.windows(14).position(|w| w == b"laszip encoded").unwrap() - 2;
    let mut bytes = good.clone();
    bytes[vlr + 54 + 32..vlr + 54 + 34].copy_from_slice(&0u16.to_le_bytes());
    std::fs::write(p("noitems.laz"), &bytes).unwrap();
    // The table's count past the file, behind a header size field of 21
    // (the records are read after the version's header all the same).
    let mut bytes = good.clone();
    bytes[table + 4..table + 8].copy_from_slice(&0x5480_0000u32.to_le_bytes());
    bytes[94..96].copy_from_slice(&21u16.to_le_bytes());
    std::fs::write(p("small.laz"), &bytes).unwrap();
    // Records shorter than the compressed fields (the decoder panicked).
    let mut bytes = good.clone();
    bytes[105..107].copy_from_slice(&20u16.to_le_bytes());
    std::fs::write(p("short.laz"), &bytes).unwrap();
    for (input, crs, said) in [
        ("half.laz", "EPSG:32631", "the header counts 60000 points, but its 3 compressed chunks hold 100001 to 150000"),
        ("twice.laz", "EPSG:32631", "the header counts 240000 points"),
        ("chunks.laz", "EPSG:32631", "its chunk table counts 4294967280 chunks, more than the"),
        ("noitems.laz", "EPSG:32631", "its LASzip record lists no fields of a point"),
        ("small.laz", "EPSG:32631", "its chunk table counts 1417674752 chunks, more than the"),
        ("short.laz", "EPSG:32631", "bytes a point, its header's records 20"),
        ("empty.csv", "EPSG:32631", "no points"),
        ("line.csv", "EPSG:32631", "on one line"),
        ("nan.csv", "EPSG:32631", "line 3"),
        ("degrees.csv", "EPSG:32631", "look like longitudes and latitudes"),
        ("nocrs.csv", "", "give --crs"),
        ("header.csv", "EPSG:32631", "nor a header naming x, y and z columns"),
        ("far.csv", "EPSG:32631", "that is no grid"),
        ("high.csv", "EPSG:32631", "line 3: the height 1e300 is past any terrain"),
        ("huge.las", "EPSG:32631", "more than the file"),
        ("nanscale.las", "EPSG:32631", "the header's z scale NaN"),
        ("infoffset.las", "EPSG:32631", "the header's x scale 0.001 and offset inf make no coordinates"),
    ] {
        let out = p("dem.tif");
        let input_path = d.path().join(input);
        let mut args = vec!["grid", s(&input_path), "-o", s(&out), "--gsd", "1", "--quiet"];
        if !crs.is_empty() {
            args.extend_from_slice(&["--crs", crs]);
        }
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{input} was taken");
        assert!(err.contains(input) && err.contains(said), "{input}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{input}: one line: {err}");
        assert!(!out.exists(), "{input}: a DEM was left");
        assert!(files_containing(d.path(), ".tmp").is_empty() && files_containing(d.path(), "dem.tif").is_empty(), "{input}: a temporary was left");
    }
}

#[test]
fn a_gridded_dem_reads_back_as_a_dem_with_its_crs_and_nodata() {
    let d = tempfile::tempdir().unwrap();
    let csv = d.path().join("p.csv");
    write_csv(&csv, &random_points(3000, 300.0, 4, plane));
    let (dem, o) = grid(d.path(), "dem.tif", &[s(&csv), "--gsd", "3", "--crs", "EPSG:32631"]);
    ok(&o);
    let src = gcm_ortho::io::source::SourceImage::open(&dem, 1 << 20).unwrap();
    let geo = src.info.georef.as_ref().expect("georeferenced");
    assert_eq!(geo.transform[1], 3.0);
    assert_eq!(src.info.nodata, Some(-9999.0));
    let crs = gcm_ortho::geodesy::Crs::from_epsg(32631).unwrap();
    let dem = gcm_ortho::dem::Dem::open(&dem, &crs).expect("rectify's DEM reader takes it");
    let (x, y) = (500150.5, 4000150.25);
    let gcm_ortho::dem::Height::Value(z) = dem.height(x, y) else { panic!("no height in the middle") };
    assert!((z - plane(x - 500000.0, y - 4000000.0)).abs() < 1e-3, "{z}");
}

#[test]
fn a_dem_gridded_from_points_of_a_scene_rectifies_its_scan_as_the_scene_dem_does() {
    let d = tempfile::tempdir().unwrap();
    let sc = scene(&d.path().join("scene"), 800, |_| {});
    // Points at random on the scene's DEM, one for every two posts.
    let src = gcm_ortho::io::source::SourceImage::open(&sc.dem, 1 << 20).unwrap();
    let gt = src.info.georef.as_ref().unwrap().transform;
    let (w, h) = (src.info.width as f64, src.info.height as f64);
    let crs = gcm_ortho::geodesy::Crs::from_epsg(32631).unwrap();
    let dem = gcm_ortho::dem::Dem::open(&sc.dem, &crs).unwrap();
    let n = (w * h / 2.0) as usize;
    let unit = random_points(n, 1.0, 21, |_, _| 0.0);
    let mut pts = Vec::with_capacity(n);
    for p in unit {
        let (u, v) = (p[0] - 500000.0, p[1] - 4000000.0);
        let (x, y) = (gt[0] + gt[1] * (1.0 + u * (w - 2.0)), gt[3] + gt[5] * (1.0 + v * (h - 2.0)));
        if let gcm_ortho::dem::Height::Value(z) = dem.height(x, y) {
            pts.push([x, y, z]);
        }
    }
    let csv = d.path().join("points.csv");
    write_csv(&csv, &pts);
    let gsd = gt[1].to_string();
    let (gridded, o) = grid(d.path(), "gridded.tif", &[s(&csv), "--gsd", &gsd, "--crs", "EPSG:32631"]);
    ok(&o);
    // The gridded DEM against the scene's at the gridded cells.
    let (gw, gh, z) = cells(&gridded);
    let ggt = gcm_ortho::io::source::SourceImage::open(&gridded, 1 << 20).unwrap().info.georef.unwrap().transform;
    let (mut sum2, mut k) = (0.0, 0);
    for j in 0..gh {
        for i in 0..gw {
            let v = z[(j * gw + i) as usize];
            let (x, y) = (ggt[0] + ggt[1] * (i as f64 + 0.5), ggt[3] + ggt[5] * (j as f64 + 0.5));
            if let (false, gcm_ortho::dem::Height::Value(t)) = (v.is_nan(), dem.height(x, y)) {
                sum2 += (v - t).powi(2);
                k += 1;
            }
        }
    }
    let rms = (sum2 / k as f64).sqrt();
    eprintln!("gridded DEM: {k} cells, {rms:.3} m RMS from the scene DEM");
    assert!(k > (gw * gh) as usize * 9 / 10 && rms < 0.5, "{k} cells, {rms} m RMS from the scene's DEM");
    // The scan rectified on each, on one grid.
    let a = d.path().join("on_scene_dem.tif");
    let b = d.path().join("on_gridded.tif");
    let o = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(&a), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = run(&[
        "rectify",
        "--image",
        s(&sc.scan),
        "--camera",
        s(&sc.camera),
        "--dem",
        s(&gridded),
        "--like",
        s(&a),
        "--dem-outside",
        "nodata",
        "-o",
        s(&b),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (pa, _) = whole_image(&a);
    let (pb, _) = whole_image(&b);
    assert_eq!(pa.len(), pb.len());
    let (mut diff, mut both) = (0u64, 0u64);
    for (x, y) in pa.iter().zip(&pb) {
        if *x != 0 && *y != 0 {
            diff += (*x as i32 - *y as i32).unsigned_abs() as u64;
            both += 1;
        }
    }
    let mean = diff as f64 / both as f64;
    eprintln!("orthophotos: {mean:.3} DN apart over {both} samples");
    assert!(both as usize > pa.len() / 2 && mean < 2.0, "{mean} DN apart over {both} samples");
}

#[test]
fn cells_past_what_the_points_resolve_or_the_memory_holds_are_refused_by_gsd() {
    let d = tempfile::tempdir().unwrap();
    let pts = d.path().join("p.csv");
    // 2,500 points on 50 m × 50 m: about 1 m apart.
    write_csv(&pts, &random_points(2500, 50.0, 7, plane));
    let args = |gsd: &'static str| vec![s(&pts), "--crs", "EPSG:32631", "--gsd", gsd, "--memory", "64M"];
    // A thousandth of the spacing and finer (a slip of units): refused.
    let (out, o) = grid(d.path(), "fine.tif", &args("0.0005"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--gsd: 0.0005 is finer than a 1000th of the points' typical spacing (1.0"), "{err}");
    assert!(!out.exists());
    // Ten times finer: made, with a warning (said even with --quiet).
    let (out, o) = grid(d.path(), "fine.tif", &args("0.05"));
    ok(&o);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--gsd 0.05 is more than ten times finer than the points' typical spacing"), "{err}");
    assert!(out.exists());
    // At the spacing: no word.
    let (_, o) = grid(d.path(), "one.tif", &args("1"));
    ok(&o);
    assert!(!String::from_utf8_lossy(&o.stderr).contains("finer"));
    // 10^12 cells asked by their bounds: refused before a bin is made.
    let mut wide = args("1");
    wide.extend(["--bounds", "0,3500000,1000000,4500000"]);
    let (out, o) = grid(d.path(), "wide.tif", &wide);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--gsd: 1000000×1000000 cells need") && err.contains("--memory"), "{err}");
    assert!(!out.exists());
    // One cell of a thousand kilometres, its centre outside the points:
    // a DEM without a height is refused, not published with a warning.
    let (out, o) = grid(d.path(), "coarse.tif", &args("1e9"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("no cell of the 1×1 DEM has a height") && err.contains("--gsd 1e9"), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(!out.exists() && files_containing(d.path(), "coarse").is_empty());
}
