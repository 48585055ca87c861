//! CRSs as users write them, checked against GDAL (PROJ underneath): each
//! spelling converts points as GDAL's reading of it does; the GeoTIFF keys
//! written for a CRS without a code read back in GDAL as the same CRS, and
//! GDAL's user-defined keys read here as GDAL reads them; a frame camera
//! orthorectifies into a CRS that is not its own (a national transverse
//! Mercator), every pixel where GDAL's conversion puts it. GDAL's Python
//! bindings are the reference (under CI they must be there).

mod common;
use common::*;
use gcm_ortho::geodesy::{Crs, GroundCrs};
use std::path::Path;
use std::process::Command;

fn python(script: &str, args: &[&str]) -> String {
    let py = python_with("osgeo.gdal", "python3-gdal").expect("checked by the caller");
    let out = Command::new(py).arg("-c").arg(script).args(args).output().expect("python runs");
    assert!(out.status.success(), "python: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

/// GDAL's projection of WGS84 (lon, lat) points into the CRS `definition`
/// (any text `SetFromUserInput` takes), traditional GIS axis order.
const GDAL_PROJECT: &str = r#"
import sys
from osgeo import osr
osr.UseExceptions()
src = osr.SpatialReference(); src.ImportFromEPSG(4326); src.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
dst = osr.SpatialReference(); dst.SetFromUserInput(open(sys.argv[1]).read()); dst.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
ct = osr.CoordinateTransformation(src, dst)
for line in sys.stdin.read().split("\n"):
    if line.strip():
        lon, lat = map(float, line.split())
        x, y = ct.TransformPoint(lon, lat)[:2]
        print(f"{x:.6f} {y:.6f}")
"#;

/// GDAL's WKT of a CRS in one of its formats (wkt1, wkt2, esri).
const GDAL_WKT: &str = r#"
import sys
from osgeo import osr
osr.UseExceptions()
s = osr.SpatialReference(); s.SetFromUserInput(sys.argv[1])
f = sys.argv[2]
if f == "wkt1": print(s.ExportToWkt())
elif f == "wkt2": print(s.ExportToWkt(["FORMAT=WKT2_2019"]))
else: s.MorphToESRI(); print(s.ExportToWkt())
"#;

fn gdal_project(dir: &Path, definition: &str, points: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let f = dir.join("crs.txt");
    std::fs::write(&f, definition).unwrap();
    let py = python_with("osgeo.gdal", "python3-gdal").unwrap();
    let mut child = Command::new(py)
        .arg("-c")
        .arg(GDAL_PROJECT)
        .arg(&f)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write;
    let input: String = points.iter().map(|(a, b)| format!("{a} {b}\n")).collect();
    child.stdin.take().unwrap().write_all(input.as_bytes()).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            (v[0], v[1])
        })
        .collect()
}

fn lattice((lon0, lon1, lat0, lat1): (f64, f64, f64, f64)) -> Vec<(f64, f64)> {
    (0..64).map(|k| (lon0 + (lon1 - lon0) * (k % 8) as f64 / 7.0, lat0 + (lat1 - lat0) * (k / 8) as f64 / 7.0)).collect()
}

/// The largest distance between our projection of the points and GDAL's.
fn worst_against_gdal(dir: &Path, ours: &Crs, gdal_definition: &str, points: &[(f64, f64)]) -> f64 {
    let g = GroundCrs::new(ours).unwrap();
    let want = gdal_project(dir, gdal_definition, points);
    points.iter().zip(&want).map(|(&(lon, lat), &(x, y))| g.lonlat_to_ground(lon, lat).map_or(f64::INFINITY, |(a, b)| (a - x).hypot(b - y))).fold(0.0, f64::max)
}

#[test]
fn every_spelling_of_a_crs_converts_as_gdal_does() {
    if python_with("osgeo.gdal", "python3-gdal").is_none() {
        eprintln!("skipped: GDAL's Python bindings are not installed");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // (what the user writes, area of use), with datum shifts where the
    // code's definition carries them (OSGB36, RD, CH1903+).
    let cases = [
        ("EPSG:32631", (0.5, 5.5, 40.0, 50.0)),
        ("EPSG:2154", (-4.0, 8.0, 42.0, 51.0)),
        ("EPSG:27700", (-6.0, 1.5, 50.0, 58.0)),
        ("EPSG:3035", (-10.0, 30.0, 35.0, 65.0)),
        ("EPSG:28992", (3.5, 7.0, 51.0, 53.4)),
        ("EPSG:2056", (6.0, 10.0, 45.9, 47.7)),
        ("EPSG:3031", (-180.0, 180.0, -88.0, -65.0)),
        ("EPSG:5070", (-120.0, -75.0, 25.0, 48.0)),
        ("EPSG:2193", (166.0, 178.0, -47.0, -34.0)),
        ("ESRI:102022", (0.0, 50.0, -33.0, 33.0)),
        ("ESRI:102003", (-120.0, -75.0, 25.0, 48.0)),
        ("+proj=tmerc +lon_0=25 +k=1 +x_0=0 +datum=WGS84", (17.0, 33.0, -35.0, -22.0)),
        ("+proj=tmerc +lat_0=0 +lon_0=19 +k=0.9993 +x_0=500000 +y_0=-5300000 +ellps=GRS80 +units=m", (14.0, 24.0, 49.0, 55.0)),
    ];
    for (definition, area) in cases {
        let pts = lattice(area);
        let mut spellings = vec![("as written".to_string(), definition.to_string())];
        for format in ["wkt1", "wkt2", "esri"] {
            spellings.push((format.to_string(), python(GDAL_WKT, &[definition, format]).trim().to_string()));
        }
        for (how, text) in spellings {
            let ours = Crs::parse(&text, dir.path()).unwrap_or_else(|e| panic!("{definition} as {how}: {e}"));
            let worst = worst_against_gdal(dir.path(), &ours, definition, &pts);
            // PROJ picks a newer Helmert for OSGB36 and RD than their
            // codes' TOWGS84: millimetres.
            assert!(worst < 0.01, "{definition} as {how}: {worst} m from GDAL ({})", ours.proj4());
        }
    }
    // An ESRI code on ED50 takes ED50's shift by the datum's name: within
    // metres of PROJ, which picks regional ED50 transformations (as for
    // DHDN in docs/CRS.md).
    let ed50 = Crs::parse("ESRI:102013", dir.path()).unwrap();
    assert!(ed50.proj4().contains("+towgs84=-87,-98,-121") && ed50.unknown_datum().is_none(), "{}", ed50.proj4());
    let worst = worst_against_gdal(dir.path(), &ed50, "ESRI:102013", &[(10.0, 50.0), (2.0, 47.0), (15.0, 45.0)]);
    assert!(worst < 3.0, "ESRI:102013: {worst} m from GDAL");
    // A .prj beside the data, URNs and compound codes.
    std::fs::write(dir.path().join("lo25.prj"), python(GDAL_WKT, &["+proj=tmerc +lon_0=25 +k=1 +x_0=0 +datum=WGS84", "esri"])).unwrap();
    let prj = Crs::parse("lo25.prj", dir.path()).unwrap();
    assert!(worst_against_gdal(dir.path(), &prj, "+proj=tmerc +lon_0=25 +k=1 +x_0=0 +datum=WGS84", &lattice((17.0, 33.0, -35.0, -22.0))) < 1e-3);
    for (urn, code) in [("urn:ogc:def:crs:EPSG::2154", 2154), ("http://www.opengis.net/def/crs/EPSG/0/3035", 3035), ("EPSG:32631+5773", 32631)] {
        assert_eq!(Crs::parse(urn, dir.path()).unwrap().epsg(), Some(code), "{urn}");
    }
}

/// GDAL reads the CRS of a GeoTIFF and converts the points to it.
const GDAL_FILE_PROJECT: &str = r#"
import sys
from osgeo import gdal, osr
gdal.UseExceptions(); osr.UseExceptions()
ds = gdal.Open(sys.argv[1])
dst = ds.GetSpatialRef(); dst.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
src = osr.SpatialReference(); src.ImportFromEPSG(4326); src.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
ct = osr.CoordinateTransformation(src, dst)
for a in sys.argv[2:]:
    lon, lat = map(float, a.split(","))
    x, y = ct.TransformPoint(lon, lat)[:2]
    print(f"{x:.6f} {y:.6f}")
"#;

#[test]
fn user_defined_geotiff_keys_read_back_in_gdal_and_gdals_here() {
    if python_with("osgeo.gdal", "python3-gdal").is_none() || !have("gdal_translate") {
        eprintln!("skipped: GDAL is not installed");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("+proj=tmerc +lon_0=25 +k=1 +x_0=0 +datum=WGS84", (18.0, 32.0, -34.0, -23.0)),
        ("+proj=lcc +lat_1=44 +lat_2=49 +lat_0=46.5 +lon_0=3 +x_0=700000 +y_0=6600000 +ellps=GRS80 +units=m", (-4.0, 8.0, 42.0, 51.0)),
        ("+proj=laea +lat_0=52 +lon_0=10 +x_0=4321000 +y_0=3210000 +ellps=GRS80 +units=m", (-10.0, 30.0, 35.0, 65.0)),
        ("+proj=aea +lat_1=29.5 +lat_2=45.5 +lat_0=23 +lon_0=-96 +x_0=0 +y_0=0 +datum=WGS84 +units=m", (-120.0, -75.0, 25.0, 48.0)),
        ("+proj=stere +lat_0=-90 +lat_ts=-71 +lon_0=0 +x_0=0 +y_0=0 +datum=WGS84 +units=m", (-180.0, 180.0, -88.0, -65.0)),
        ("+proj=sterea +lat_0=52.1561605555556 +lon_0=5.38763888888889 +k=0.9999079 +x_0=155000 +y_0=463000 +ellps=bessel +towgs84=565.417,50.3319,465.552,-0.398957,0.343988,-1.8774,4.0725 +units=m", (3.5, 7.0, 51.0, 53.4)),
        ("+proj=tmerc +lat_0=49 +lon_0=-2 +k=0.9996012717 +x_0=400000 +y_0=-100000 +ellps=airy +towgs84=446.448,-125.157,542.06,0.15,0.247,0.842,-20.489 +units=m", (-6.0, 1.5, 50.0, 58.0)),
        ("+proj=robin +lon_0=10 +x_0=1000 +y_0=-500 +datum=WGS84 +units=m", (-150.0, 150.0, -70.0, 70.0)),
        ("+proj=eqdc +lat_0=40 +lon_0=-96 +lat_1=20 +lat_2=60 +x_0=0 +y_0=0 +datum=WGS84 +units=m", (-120.0, -75.0, 25.0, 48.0)),
        ("+proj=cea +lat_ts=30 +lon_0=0 +x_0=0 +y_0=0 +datum=WGS84 +units=m", (-170.0, 170.0, -80.0, 80.0)),
        ("+proj=mill +lat_0=0 +lon_0=20 +x_0=0 +y_0=0 +R=6371000 +units=m", (-150.0, 150.0, -70.0, 70.0)),
        ("+proj=ortho +lat_0=45 +lon_0=5 +x_0=0 +y_0=0 +datum=WGS84 +units=m", (-5.0, 15.0, 38.0, 52.0)),
        ("+proj=gnom +lat_0=45 +lon_0=5 +x_0=0 +y_0=0 +R=6371000 +units=m", (-5.0, 15.0, 38.0, 52.0)),
        // Malaysia's RSO (variant A) and a Hotine variant B, as national grids use them.
        (
            "+proj=omerc +no_uoff +lat_0=4 +lonc=102.25 +alpha=323.0257905 +gamma=323.1301023611111 +k=0.99984 +x_0=804670.24 +y_0=0 +datum=WGS84 +units=m",
            (100.5, 104.0, 1.5, 6.5),
        ),
        // No method keys in GeoTIFF: an ESRI PE String citation, as GDAL writes.
        ("+proj=moll +lon_0=10 +x_0=100 +y_0=0 +datum=WGS84 +units=m", (-150.0, 150.0, -70.0, 70.0)),
        ("+proj=eqearth +lon_0=-20 +x_0=0 +y_0=0 +ellps=GRS80 +units=m", (-150.0, 150.0, -70.0, 70.0)),
        ("+proj=omerc +lat_0=57 +lonc=-133.6666666666667 +alpha=323.1301023611111 +k=0.9999 +x_0=5000000 +y_0=-5000000 +datum=WGS84 +units=m", (-141.0, -129.0, 54.0, 60.0)),
    ];
    for (k, (definition, area)) in cases.into_iter().enumerate() {
        let crs = Crs::parse(definition, dir.path()).unwrap();
        let pts = lattice(area);
        let args: Vec<String> = pts.iter().map(|(a, b)| format!("{a},{b}")).collect();
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let ground = GroundCrs::new(&crs).unwrap();
        // Ours written, GDAL reading.
        let ours = dir.path().join(format!("ours{k}.tif"));
        let keys = gcm_ortho::geodesy::geokeys::keys_of(&crs).unwrap();
        raster_with_keys(&ours, keys);
        let mut all = vec![s(&ours)];
        all.extend(&args);
        let got = python(GDAL_FILE_PROJECT, &all);
        for (line, &(lon, lat)) in got.lines().zip(&pts) {
            let v: Vec<f64> = line.split_whitespace().map(|x| x.parse().unwrap()).collect();
            let (x, y) = ground.lonlat_to_ground(lon, lat).unwrap();
            assert!((v[0] - x).hypot(v[1] - y) < 0.01, "{definition}: GDAL reads our keys as another CRS: ({}, {}) vs ({x}, {y})", v[0], v[1]);
        }
        // GDAL written, ours reading (GDAL 3.6 writes no keys for Equal
        // Earth: a local CRS in its .aux.xml).
        if definition.contains("eqearth") {
            continue;
        }
        let theirs = dir.path().join(format!("theirs{k}.tif"));
        let out = Command::new("gdal_translate").args(["-q", "-a_srs", definition, s(&ours), s(&theirs)]).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let info = gcm_ortho::io::source::SourceImage::info_of(&theirs).unwrap();
        let read = gcm_ortho::geodesy::geokeys::crs_of(&info.georef.unwrap().keys)
            .unwrap_or_else(|e| panic!("{definition}: {e}"))
            .unwrap_or_else(|| panic!("{definition}: GDAL's keys read as no CRS"));
        let g2 = GroundCrs::new(&read).unwrap();
        for &(lon, lat) in &pts {
            let (a, b) = (ground.lonlat_to_ground(lon, lat).unwrap(), g2.lonlat_to_ground(lon, lat).unwrap());
            assert!((a.0 - b.0).hypot(a.1 - b.1) < 0.01, "{definition}: GDAL's keys read as {} ({})", read, read.proj4());
        }
    }
}

fn raster_with_keys(path: &Path, keys: gcm_ortho::io::geotiff::GeoKeys) {
    f32_raster_with_keys(path, (4, 4), (1000.0, 2000.0, 10.0), keys, |_, _| 7.0);
}

/// For every pixel of orthophoto `b` (a coordinate image's, in any CRS),
/// GDAL converts its centre into the CRS of orthophoto `a` and samples `a`
/// bilinearly there: the largest and mean distance between the two scan
/// positions, and the pixels compared.
const GDAL_CROSS_CRS: &str = r#"
import sys
import numpy as np
from osgeo import gdal, osr
gdal.UseExceptions(); osr.UseExceptions()
a = gdal.Open(sys.argv[1]); b = gdal.Open(sys.argv[2])
A = a.ReadAsArray().astype(np.float64); B = b.ReadAsArray().astype(np.float64)
ga, gb = a.GetGeoTransform(), b.GetGeoTransform()
sa, sb = a.GetSpatialRef(), b.GetSpatialRef()
for s in (sa, sb): s.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
ct = osr.CoordinateTransformation(sb, sa)
h, w = B.shape[1:]
jj, ii = np.mgrid[0:h, 0:w]
x = gb[0] + (ii + 0.5) * gb[1]; y = gb[3] + (jj + 0.5) * gb[5]
p = np.array(ct.TransformPoints(np.c_[x.ravel(), y.ravel()]))
u = (p[:, 0] - ga[0]) / ga[1] - 0.5; v = (p[:, 1] - ga[3]) / ga[5] - 0.5
i0 = np.floor(u).astype(int); j0 = np.floor(v).astype(int); fu = u - i0; fv = v - j0
ha, wa = A.shape[1:]
ok = (i0 >= 0) & (j0 >= 0) & (i0 < wa - 1) & (j0 < ha - 1)
i0c, j0c = np.clip(i0, 0, wa - 2), np.clip(j0, 0, ha - 2)
def at(band):
    q = A[band]
    c = [q[j0c, i0c], q[j0c, i0c + 1], q[j0c + 1, i0c], q[j0c + 1, i0c + 1]]
    ok_all = np.all([ci >= 0 for ci in c], axis=0)
    return (c[0] * (1 - fu) * (1 - fv) + c[1] * fu * (1 - fv) + c[2] * (1 - fu) * fv + c[3] * fu * fv), ok_all
ca, oka = at(0); ra, okr = at(1)
cb, rb = B[0].ravel(), B[1].ravel()
edge = 2.0
inside = (cb > edge) & (rb > edge) & (cb < float(sys.argv[3]) - edge) & (rb < float(sys.argv[4]) - edge)
m = ok & oka & okr & (cb >= 0) & inside & (ca > edge) & (ra > edge)
d = np.hypot(ca[m] - cb[m], ra[m] - rb[m])
print(f"{d.max():.6f} {d.mean():.6f} {m.sum()}")
"#;

#[test]
fn a_frame_camera_orthorectifies_into_a_national_transverse_mercator() {
    if python_with("osgeo.gdal", "python3-gdal").is_none() {
        eprintln!("skipped: GDAL's Python bindings are not installed");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let w = 1000;
    // A film frame over hills; its exterior orientation is in UTM 31N.
    let sc = scene(&dir.path().join("s"), w, |o| {
        o.bands = 1;
        o.kappa_deg = 20.0;
    });
    let coords = dir.path().join("coords.tif");
    coordinate_image(&coords, w, w);
    let rectify = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut a = vec!["rectify", "--image", s(&coords), "--camera", s(&sc.camera), "--nodata", "-1", "--compress", "none", "--quiet", "-o", s(&out)];
        // The scene's DEM unless another is given.
        if !extra.contains(&"--dem") {
            a.extend(["--dem", s(&sc.dem)]);
        }
        a.extend_from_slice(extra);
        let r = run(&a);
        assert!(r.status.success(), "{name}: {}", String::from_utf8_lossy(&r.stderr));
        out
    };
    let utm = rectify("utm.tif", &["--sparsity", "1", "--corrections", "cell", "--memory", "1G"]);
    // A national grid 2° west of the scene, scale 1 on its meridian and
    // no false easting (grid convergence ≈ 1.4°), as a PROJ string and as
    // the ESRI .prj GDAL writes for it; by default and exactly (every
    // pixel a node).
    let tm = "+proj=tmerc +lat_0=0 +lon_0=1 +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m";
    std::fs::write(dir.path().join("lo1.prj"), python(GDAL_WKT, &[tm, "esri"])).unwrap();
    for (name, crs) in [("tm.tif", tm.to_string()), ("tm-prj.tif", s(&dir.path().join("lo1.prj")).to_string()), ("tm-exact.tif", tm.to_string())] {
        let exact = ["--crs", &crs, "--sparsity", "1", "--corrections", "cell", "--memory", "1G"];
        let out = rectify(name, if name.contains("exact") { &exact[..] } else { &exact[..2] });
        let got = python(GDAL_CROSS_CRS, &[s(&utm), s(&out), &w.to_string(), &w.to_string()]);
        let v: Vec<f64> = got.split_whitespace().map(|x| x.parse().unwrap()).collect();
        eprintln!("{name}: max {} mean {} over {} px", v[0], v[1], v[2]);
        assert!(v[2] > 500_000.0, "{name}: {} pixels compared", v[2]);
        if name.contains("exact") {
            // The exact model in another CRS is the exact model: within
            // 0.01 px of GDAL's conversion of the UTM orthophoto.
            assert!(v[0] < 0.01, "{name}: {got}");
        } else {
            // The default error bound (0.1 px) and the reference's own
            // bilinear interpolation.
            assert!(v[0] < 0.15 && v[1] < 0.03, "{name}: {got}");
        }
    }
    // A manifest's `crs` (in [defaults]) is --crs: the same orthophoto.
    let m = dir.path().join("block.toml");
    std::fs::write(
        &m,
        format!(
            "[defaults]\ncrs = \"{tm}\"\ndem = \"s/dem.tif\"\nnodata = -1\ncompress = \"none\"\n\n[[job]]\nimage = \"coords.tif\"\ncamera = \"s/camera.toml\"\noutput = \"tm-batch.tif\"\n"
        ),
    )
    .unwrap();
    let r = run(&["batch", s(&m), "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(content(&dir.path().join("tm-batch.tif")) == content(&dir.path().join("tm.tif")), "the manifest's crs is --crs");
    // The same DEM warped by GDAL into the national grid (user-defined
    // GeoTIFF keys, as an NGI block's DEM comes) gives the orthophoto of
    // the UTM DEM, within what resampling the DEM twice changes.
    if have("gdalwarp") {
        let dem_tm = dir.path().join("dem-tm.tif");
        let out = Command::new("gdalwarp").args(["-q", "-t_srs", tm, "-r", "cubic", s(&sc.dem), s(&dem_tm)]).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let plain = rectify("utm-default.tif", &[]);
        let a = rectify("utm-dem-tm.tif", &["--dem", s(&dem_tm)]);
        let d = coordinate_map_difference(&plain, &a, w, w);
        eprintln!("DEM in the national grid: max {} mean {} over {} px", d.max, d.mean, d.pixels);
        assert!(d.pixels > 500_000 && d.max < 0.1 && d.mean < 0.01, "max {} mean {}", d.max, d.mean);
    }
}

#[test]
fn crs_refusals_name_what_is_read() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.tif");
    for (crs, want) in [
        ("UTM31", "PROJ string"),
        ("ESRI:999999", "ESRI codes"),
        ("+proj=moll +lon_0=0 +ellps=bessel +towgs84=1,2,3 +units=m", "+proj=moll"),
        ("EPSG:5773", "vertical"),
        ("missing.prj", "missing.prj"),
    ] {
        let r = run(&[
            "rectify",
            "--image",
            s(&root.join("scan.tif")),
            "--camera",
            s(&root.join("camera.toml")),
            "--dem",
            s(&root.join("dem.tif")),
            "--crs",
            crs,
            "-o",
            s(&out),
        ]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{crs}: {err}");
        assert!(err.contains("--crs") && err.contains(want), "{crs}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(!out.exists());
    }
}

#[test]
fn a_dem_without_keys_takes_the_prj_beside_it() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini");
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let g = gcm_ortho::dem::GridDem::read_within(&root.join("dem.tif"), 1 << 30).unwrap();
    let bare = d.join("bare.tif");
    let t = g.transform;
    f32_raster_with_keys(&bare, (g.width as u32, g.height as u32), (t[0], t[3], t[1]), Default::default(), |c, r| g.sample(c as usize, r as usize));
    let rectify = |dem: &Path, out: &Path| {
        run(&["rectify", "--image", s(&root.join("scan.tif")), "--camera", s(&root.join("camera.toml")), "--dem", s(dem), "--quiet", "-o", s(out)])
    };
    let want = d.join("want.tif");
    assert!(rectify(&root.join("dem.tif"), &want).status.success());
    // UTM 31N as ESRI writes it.
    let utm = r#"PROJCS["WGS_1984_UTM_Zone_31N",GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["False_Easting",500000.0],PARAMETER["False_Northing",0.0],PARAMETER["Central_Meridian",3.0],PARAMETER["Scale_Factor",0.9996],PARAMETER["Latitude_Of_Origin",0.0],UNIT["Meter",1.0]]"#;
    std::fs::write(d.join("bare.prj"), utm).unwrap();
    let got = d.join("got.tif");
    let r = rectify(&bare, &got);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(whole_image(&got).0 == whole_image(&want).0);
    // A .prj that is not a CRS is read, and refused by name.
    std::fs::write(d.join("bare.prj"), "not a CRS").unwrap();
    let bad = d.join("bad.tif");
    let r = rectify(&bare, &bad);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("bare.prj"), "{err}");
    assert!(!bad.exists());
}

/// An NTv2 grid rewritten as PROJ's GeoTIFF grids are (its
/// `ntv2_to_gtiff.py`): latitude and longitude offsets in arc-seconds,
/// longitudes positive east (NTv2's are positive west).
const NTV2_TO_GEOTIFF: &str = r#"
import sys
from osgeo import gdal
gdal.UseExceptions()
src = gdal.Open(sys.argv[1])
dst = gdal.GetDriverByName("GTiff").Create(sys.argv[2], src.RasterXSize, src.RasterYSize, 2, gdal.GDT_Float32, ["COMPRESS=DEFLATE", "PREDICTOR=3", "INTERLEAVE=PIXEL"])
dst.SetGeoTransform(src.GetGeoTransform())
dst.SetProjection(src.GetProjection())
dst.SetMetadataItem("TYPE", "HORIZONTAL_OFFSET")
for k, (name, sign) in enumerate([("latitude_offset", 1), ("longitude_offset", -1)]):
    b = dst.GetRasterBand(k + 1)
    b.WriteArray(sign * src.GetRasterBand(k + 1).ReadAsArray())
    b.SetDescription(name)
    b.SetUnitType("arc-second")
    if name == "longitude_offset":
        b.SetMetadataItem("positive_value", "east")
dst = None
"#;

/// Datum shift grids (`+nadgrids=`): NTv2 grids of France (NTF → RGF93),
/// Germany (DHDN → ETRS89, BETA2007) and New Zealand (NZGD49 → NZGD2000)
/// convert points as PROJ does with the same grid.
#[test]
fn datum_shift_grids_convert_as_proj_does() {
    if python_with("osgeo.gdal", "python3-gdal").is_none() {
        eprintln!("skipped: GDAL's Python bindings are not installed");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "+proj=lcc +lat_1=46.8 +lat_0=46.8 +lon_0=0 +k_0=0.99987742 +x_0=600000 +y_0=2200000 +a=6378249.2 +b=6356515 +pm=paris +units=m +nadgrids=ntf_r93.gsb",
            (-4.5, 7.5, 42.5, 50.5),
        ),
        ("+proj=tmerc +lat_0=0 +lon_0=9 +k=1 +x_0=3500000 +y_0=0 +ellps=bessel +nadgrids=BETA2007.gsb +units=m", (6.0, 14.5, 47.5, 54.5)),
        (
            "+proj=tmerc +lat_0=-36.87986527777778 +lon_0=174.7643393611111 +k=0.9999 +x_0=300000 +y_0=700000 +ellps=intl +nadgrids=nzgd2kgrid0005.gsb +units=m",
            (173.0, 176.5, -38.0, -35.0),
        ),
    ];
    for (definition, area) in cases {
        let grid = ["ntf_r93.gsb", "BETA2007.gsb", "nzgd2kgrid0005.gsb"].into_iter().find(|g| definition.contains(g)).unwrap();
        if gcm_ortho::geodesy::find_proj_grid(grid).is_none() {
            assert!(std::env::var_os("CI").is_none(), "PROJ's grid {grid} (Debian's proj-data) is missing");
            eprintln!("skipped {definition}: PROJ's grid {grid} is not installed");
            continue;
        }
        let ours = Crs::parse(definition, dir.path()).unwrap_or_else(|e| panic!("{definition}: {e}"));
        let worst = worst_against_gdal(dir.path(), &ours, definition, &lattice(area));
        eprintln!("{grid}: {worst:.2e} m from PROJ");
        assert!(worst < 0.01, "{definition}: {worst} m from PROJ ({})", ours.proj4());
    }
    // The French grid as PROJ's GeoTIFF grids hold it (two Float32 bands,
    // arc-seconds, longitudes positive east), made by GDAL from the NTv2.
    if let Some(gsb) = gcm_ortho::geodesy::find_proj_grid("ntf_r93.gsb") {
        let tif = dir.path().join("fr_ntf_r93.tif");
        python(NTV2_TO_GEOTIFF, &[gsb.to_str().unwrap(), tif.to_str().unwrap()]);
        let lcc = "+proj=lcc +lat_1=46.8 +lat_0=46.8 +lon_0=0 +k_0=0.99987742 +x_0=600000 +y_0=2200000 +a=6378249.2 +b=6356515 +pm=paris +units=m";
        let ours = Crs::parse(&format!("{lcc} +nadgrids={}", tif.display()), dir.path()).unwrap();
        let worst = worst_against_gdal(dir.path(), &ours, &format!("{lcc} +nadgrids=ntf_r93.gsb"), &lattice((-4.5, 7.5, 42.5, 50.5)));
        eprintln!("ntf_r93 as GeoTIFF: {worst:.2e} m from PROJ with the NTv2");
        assert!(worst < 0.01, "the GeoTIFF grid: {worst} m from PROJ with the NTv2");
    }
    // Without the grid's shift the same points are metres to a hundred
    // metres away: the comparison above sees the grid.
    let no_grid = Crs::parse("+proj=tmerc +lat_0=0 +lon_0=9 +k=1 +x_0=3500000 +y_0=0 +ellps=bessel +towgs84=0,0,0 +units=m", dir.path()).unwrap();
    let with_grid = "+proj=tmerc +lat_0=0 +lon_0=9 +k=1 +x_0=3500000 +y_0=0 +ellps=bessel +nadgrids=BETA2007.gsb +units=m";
    if gcm_ortho::geodesy::find_proj_grid("BETA2007.gsb").is_some() {
        assert!(worst_against_gdal(dir.path(), &no_grid, with_grid, &lattice((6.0, 14.5, 47.5, 54.5))) > 50.0);
    }
    // A grid that is nowhere is refused naming it and where it was looked for.
    let e = Crs::parse("+proj=longlat +ellps=intl +nadgrids=no_such_grid.gsb", dir.path()).unwrap_err();
    assert!(e.contains("no_such_grid.gsb") && e.contains("PROJ_DATA"), "{e}");
}
