//! True orthophotos (`--occlusion`): the pixels we hide against the truth
//! worked out here, independently, by intersecting each output pixel's line
//! of sight with the scene's boxes (ray–box, slab method).
//!
//! The scene: flat-roofed boxes of known heights on a tilted plane, posted
//! as a DSM at half the output pixel; a coordinate image as the scan, so
//! that a NaN in the output is a pixel without a value. Each camera —
//! vertical frame, oblique frame, an RPC 25° off nadir — is rectified with
//! and without `--occlusion nodata`; pixels imaged without it and NaN with
//! it are the hidden ones.

mod common;

use common::{content, coordinate_image, f32_raster, read_f32, run, s};
use std::path::Path;

const X0: f64 = 500_000.0;
const Y0: f64 = 4_500_100.0;
/// The scene: 100 m × 100 m.
const SIDE: f64 = 100.0;
/// DSM posts, and the output's pixel.
const POST: f64 = 0.1;
const GSD: f64 = 0.2;

/// A box: west, south, east, north, roof height.
type Block = [f64; 5];

/// Ground: a plane rising 2 m over the scene to the east and 1 m to the north.
fn terrain(x: f64, y: f64) -> f64 {
    100.0 + 0.02 * (x - X0) + 0.01 * (y - (Y0 - SIDE))
}

/// Boxes with edges halfway between posts (so that the DSM's wall, one
/// post wide, stands where the box's does), towers and long blocks.
fn blocks() -> Vec<Block> {
    // (Posts stand at odd multiples of 5 cm: whole decimetres are halfway.)
    let b = |x0: f64, y0: f64, w: f64, h: f64, top: f64| [X0 + x0, Y0 - SIDE + y0, X0 + x0 + w, Y0 - SIDE + y0 + h, top];
    vec![
        b(20.0, 20.0, 12.0, 8.0, 118.0),
        b(45.0, 60.0, 6.0, 6.0, 135.0),
        b(60.0, 25.0, 20.0, 5.0, 110.0),
        b(25.0, 65.0, 4.0, 18.0, 125.0),
        b(70.0, 70.0, 10.0, 10.0, 121.0),
        b(48.0, 40.0, 3.0, 3.0, 128.0),
    ]
}

/// The scene's surface (the truth's, and the DSM's at posts).
fn surface(x: f64, y: f64, blocks: &[Block]) -> f64 {
    blocks.iter().find(|b| x > b[0] && x < b[2] && y > b[1] && y < b[3]).map_or(terrain(x, y), |b| b[4])
}

/// Does the ray from `p` along `d` (per unit of height, toward the sensor)
/// pass through a box before it is above them all?
fn hidden(p: [f64; 3], d: [f64; 2], blocks: &[Block]) -> bool {
    blocks.iter().any(|b| {
        // The ray p + t (d, 1), t > 0 (t: height gained), against the slab.
        let (mut lo, mut hi) = (1e-6, b[4] - p[2]);
        if hi <= lo {
            return false;
        }
        for (k, (a, c)) in [(b[0], b[2]), (b[1], b[3])].into_iter().enumerate() {
            if d[k].abs() < 1e-12 {
                if p[k] <= a || p[k] >= c {
                    return false;
                }
            } else {
                let (t1, t2) = ((a - p[k]) / d[k], (c - p[k]) / d[k]);
                lo = lo.max(t1.min(t2));
                hi = hi.min(t1.max(t2));
            }
        }
        lo < hi
    })
}

fn write_dsm(path: &Path) {
    let n = (SIDE / POST) as u32;
    let blocks = blocks();
    f32_raster(path, (n, n), (X0, Y0, POST, 32631), |c, r| {
        let (x, y) = (X0 + (c as f64 + 0.5) * POST, Y0 - (r as f64 + 0.5) * POST);
        surface(x, y, &blocks) as f32
    });
}

/// A frame camera over the scene's middle at `height` above it, tilted by
/// `phi_deg` about the north axis (looking east when positive).
fn frame_camera(path: &Path, height: f64, phi_deg: f64, east_offset: f64) -> [f64; 3] {
    let c = [X0 + SIDE / 2.0 - east_offset, Y0 - SIDE / 2.0, 101.5 + height];
    std::fs::write(
        path,
        format!(
            "crs = \"EPSG:32631\"\n[camera]\nmodel = \"frame\"\nfocal_length_mm = 16.0\n[interior]\npixel_size_mm = 0.005\nprincipal_point_px = [1000.0, 1000.0]\n[exterior]\nposition = [{}, {}, {}]\nangles_deg = [0.0, {phi_deg}, 0.0]\nconvention = \"omega-phi-kappa\"\n",
            c[0], c[1], c[2]
        ),
    )
    .unwrap();
    c
}

/// What `--occlusion nodata` hides, against the truth, over every imaged
/// output pixel: (imaged, truly hidden, false hidden, false seen, errors
/// more than a pixel from the true boundary).
fn compare(dir: &Path, sensor: &[&str], sight: impl Fn(f64, f64, f64) -> [f64; 2]) -> [usize; 5] {
    let (scan, dsm) = (dir.join("scan.tif"), dir.join("dsm.tif"));
    let bounds = format!("{},{},{},{}", X0 + 5.0, Y0 - SIDE + 5.0, X0 + SIDE - 5.0, Y0 - 5.0);
    let common = |out: &Path, extra: &[&str]| {
        let mut a = vec!["rectify", "--image", s(&scan), "--dem", s(&dsm), "--gsd", "0.2", "--bounds", &bounds, "--quiet", "-o", s(out)];
        a.extend_from_slice(sensor);
        a.extend_from_slice(extra);
        let o = run(&a);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    let (plain, occ) = (dir.join("plain.tif"), dir.join("occ.tif"));
    common(&plain, &[]);
    common(&occ, &["--occlusion", "nodata"]);
    let (w, h, _, a) = read_f32(&plain);
    let (_, _, _, b) = read_f32(&occ);
    let blocks = blocks();
    let (x0, y0) = (X0 + 5.0, Y0 - 5.0);
    let truth: Vec<Option<bool>> = (0..(w * h) as usize)
        .map(|k| {
            if a[2 * k].is_nan() {
                return None;
            }
            let (x, y) = (x0 + ((k % w as usize) as f64 + 0.5) * GSD, y0 - ((k / w as usize) as f64 + 0.5) * GSD);
            let z = surface(x, y, &blocks);
            Some(hidden([x, y, z], sight(x, y, z), &blocks))
        })
        .collect();
    let mut n = [0usize; 5];
    for k in 0..(w * h) as usize {
        let Some(t) = truth[k] else { continue };
        let ours = b[2 * k].is_nan();
        n[0] += 1;
        n[1] += usize::from(t);
        if ours != t {
            n[if ours { 2 } else { 3 }] += 1;
            // Near the true boundary: the truth changes within a pixel of
            // the pixel's centre (on circles of ½ and 1 pixel).
            let (x, y) = (x0 + ((k % w as usize) as f64 + 0.5) * GSD, y0 - ((k / w as usize) as f64 + 0.5) * GSD);
            let near = [0.5, 1.0].into_iter().flat_map(|r| (0..16).map(move |i| (r, i as f64 * std::f64::consts::PI / 8.0))).any(|(r, a)| {
                let (xx, yy) = (x + r * GSD * a.cos(), y + r * GSD * a.sin());
                let z = surface(xx, yy, &blocks);
                hidden([xx, yy, z], sight(xx, yy, z), &blocks) != t
            });
            n[4] += usize::from(!near);
        }
    }
    n
}

fn assert_true_ortho(what: &str, n: [usize; 5]) {
    let [imaged, hidden, false_hidden, false_seen, far] = n;
    eprintln!("{what}: {imaged} imaged, {hidden} hidden, {false_hidden} falsely hidden, {false_seen} falsely seen, {far} off the boundary");
    assert!(imaged > 100_000, "{what}: the scene is imaged");
    assert!(hidden as f64 > 0.02 * imaged as f64, "{what}: the boxes hide ground");
    assert!(false_hidden as f64 <= 0.005 * imaged as f64, "{what}: {false_hidden} of {imaged} falsely hidden");
    assert!(false_seen as f64 <= 0.005 * imaged as f64, "{what}: {false_seen} of {imaged} falsely seen");
    assert_eq!(far, 0, "{what}: errors more than a pixel from the true boundary");
}

fn scene(dir: &Path) {
    write_dsm(&dir.join("dsm.tif"));
    coordinate_image(&dir.join("scan.tif"), 2000, 2000);
}

#[test]
fn vertical_frame_hides_what_the_boxes_hide() {
    let dir = tempfile::tempdir().unwrap();
    scene(dir.path());
    let cam = dir.path().join("cam.toml");
    let c = frame_camera(&cam, 150.0, 0.0, 0.0);
    let n = compare(dir.path(), &["--camera", s(&cam)], |x, y, z| [(c[0] - x) / (c[2] - z), (c[1] - y) / (c[2] - z)]);
    assert_true_ortho("vertical frame", n);
}

#[test]
fn oblique_frame_hides_what_the_boxes_hide() {
    let dir = tempfile::tempdir().unwrap();
    scene(dir.path());
    let cam = dir.path().join("cam.toml");
    // 30° east of nadir, from 120 m up and 69 m to the west.
    let c = frame_camera(&cam, 120.0, -30.0, 120.0 * 30f64.to_radians().tan());
    let n = compare(dir.path(), &["--camera", s(&cam)], |x, y, z| [(c[0] - x) / (c[2] - z), (c[1] - y) / (c[2] - z)]);
    assert_true_ortho("oblique frame", n);
}

/// A satellite 25° off nadir to the west, as a linear RPC at the central
/// meridian of UTM zone 31 (no grid convergence): a point `h` metres up
/// is imaged where the ground `h tan 25°` east of it is.
#[test]
fn rpc_25_degrees_off_nadir_hides_what_the_boxes_hide() {
    let dir = tempfile::tempdir().unwrap();
    scene(dir.path());
    // UTM's metres per degree at the scene (WGS84, k0 = 0.9996).
    let (a, e2, k0) = (6_378_137.0f64, 0.006_694_379_990_14f64, 0.9996);
    let lat0 = 40.6513f64;
    let phi = lat0.to_radians();
    let nu = a / (1.0 - e2 * phi.sin().powi(2)).sqrt();
    let rho = a * (1.0 - e2) / (1.0 - e2 * phi.sin().powi(2)).powf(1.5);
    let (kx, ky) = (k0 * nu * phi.cos() * std::f64::consts::PI / 180.0, k0 * rho * std::f64::consts::PI / 180.0);
    let tan = 25f64.to_radians().tan();
    let (gsd, off, scale_px) = (0.06, 1000.0, 1000.0);
    let (lon_scale, lat_scale, h_off, h_scale) = (0.002, 0.002, 110.0, 50.0);
    let mut text = format!(
        "LINE_OFF: {off}\nSAMP_OFF: {off}\nLAT_OFF: {lat0}\nLONG_OFF: 3.0\nHEIGHT_OFF: {h_off}\nLINE_SCALE: {scale_px}\nSAMP_SCALE: {scale_px}\nLAT_SCALE: {lat_scale}\nLONG_SCALE: {lon_scale}\nHEIGHT_SCALE: {h_scale}\n"
    );
    // RPC00B order: 1, L, P, H, …; sample = east + h tan, line = south.
    let mut line = [0.0; 20];
    let mut samp = [0.0; 20];
    let mut den = [0.0; 20];
    den[0] = 1.0;
    samp[1] = lon_scale * kx / gsd / scale_px;
    samp[3] = h_scale * tan / gsd / scale_px;
    line[2] = -lat_scale * ky / gsd / scale_px;
    for (name, c) in [("LINE_NUM", line), ("LINE_DEN", den), ("SAMP_NUM", samp), ("SAMP_DEN", den)] {
        for (i, v) in c.iter().enumerate() {
            text.push_str(&format!("{name}_COEFF_{}: {v:e}\n", i + 1));
        }
    }
    let rpc = dir.path().join("scene_rpc.txt");
    std::fs::write(&rpc, text).unwrap();
    // The scene's latitude: the RPC is centred near the DSM.
    let n = compare(dir.path(), &["--rpc", s(&rpc), "--crs", "EPSG:32631"], |_, _, _| [-tan, 0.0]);
    assert_true_ortho("RPC 25° off nadir", n);
}

/// Two vertical frames 40 m apart over the boxes: with `--occlusion`, the
/// mosaic takes every pixel from a frame that sees its ground (none is
/// double-mapped where the other frame sees it), and what neither sees is
/// left without a value and reported.
#[test]
fn a_true_orthomosaic_fills_what_one_frame_hides_from_the_other() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_dsm(&d.join("dsm.tif"));
    let mut centres = Vec::new();
    for (k, east) in [(0, 20.0), (1, -20.0)] {
        common::coordinate_image_from(&d.join(format!("f{k}.tif")), 2000, 2000, 10_000.0 * k as f32);
        centres.push(frame_camera(&d.join(format!("f{k}.toml")), 150.0, 0.0, east));
    }
    let manifest = "[defaults]\ndem = \"dsm.tif\"\ngsd = 0.2\nnodata = \"nan\"\n\n[[job]]\nimage = \"f0.tif\"\ncamera = \"f0.toml\"\n\n[[job]]\nimage = \"f1.tif\"\ncamera = \"f1.toml\"\n";
    std::fs::write(d.join("manifest.toml"), manifest).unwrap();
    let bounds = format!("{},{},{},{}", X0 + 5.0, Y0 - SIDE + 5.0, X0 + SIDE - 5.0, Y0 - 5.0);
    let mosaic = |out: &str, extra: &[&str]| {
        let o = std::process::Command::new(common::bin())
            .current_dir(d)
            .args(["mosaic", "manifest.toml", "-o", out, "--bounds", &bounds, "--gsd", "0.2", "--balance", "none", "--blend", "0", "--quiet"])
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        read_f32(&d.join(out))
    };
    let (w, h, _, px) = mosaic("true.tif", &["--occlusion", "nodata", "--json", "true.json"]);
    let (_, _, _, plain) = mosaic("plain.tif", &[]);
    let blocks = blocks();
    let (x0, y0) = (X0 + 5.0, Y0 - 5.0);
    let hidden_from = |c: [f64; 3], x: f64, y: f64| {
        let z = surface(x, y, &blocks);
        hidden([x, y, z], [(c[0] - x) / (c[2] - z), (c[1] - y) / (c[2] - z)], &blocks)
    };
    // Within a pixel of where the truth changes (circles of ½ and 1 px).
    let near_boundary = |c: [f64; 3], x: f64, y: f64| {
        let t = hidden_from(c, x, y);
        [0.5, 1.0]
            .into_iter()
            .flat_map(|r| (0..16).map(move |i| (r, i as f64 * std::f64::consts::PI / 8.0)))
            .any(|(r, a)| hidden_from(c, x + r * GSD * a.cos(), y + r * GSD * a.sin()) != t)
    };
    let (mut from_hiding, mut far, mut unseen_truth, mut valued, mut plain_doubled) = (0, 0, 0, 0, 0);
    for k in 0..(w * h) as usize {
        let (x, y) = (x0 + ((k % w as usize) as f64 + 0.5) * GSD, y0 - ((k / w as usize) as f64 + 0.5) * GSD);
        let seen_by: Vec<bool> = centres.iter().map(|&c| !hidden_from(c, x, y)).collect();
        if !seen_by.iter().any(|&s| s) {
            unseen_truth += 1;
        }
        // The ordinary mosaic paints what its frame hides.
        let plain_frame = usize::from(plain[2 * k] >= 10_000.0);
        plain_doubled += usize::from(!seen_by[plain_frame] && seen_by[1 - plain_frame]);
        let col = px[2 * k];
        if col.is_nan() {
            continue;
        }
        valued += 1;
        let frame = usize::from(col >= 10_000.0);
        if !seen_by[frame] && seen_by[1 - frame] {
            // Double-mapped: the frame it came from does not see this ground, the other does.
            from_hiding += 1;
            far += usize::from(!near_boundary(centres[frame], x, y));
        }
    }
    eprintln!("mosaic: {valued} px with a value, {from_hiding} from a frame that hides them ({far} off the boundary), {unseen_truth} seen by neither; without --occlusion {plain_doubled} double-mapped");
    assert!(plain_doubled > 20 * from_hiding.max(50), "the scene double-maps without occlusion");
    assert!(valued > 150_000);
    assert_eq!(far, 0, "double-mapped pixels where the other frame sees the ground");
    assert!(from_hiding as f64 <= 0.002 * valued as f64);
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("true.json")).unwrap()).unwrap();
    let unseen = report["unseen"]["unseen_px"].as_u64().expect("the report counts what no image sees");
    assert!(
        unseen_truth > 0 && (unseen as f64 - unseen_truth as f64).abs() <= 0.2 * unseen_truth as f64 + 50.0,
        "unseen: reported {unseen}, truth {unseen_truth}"
    );
    for im in report["images"].as_array().unwrap() {
        assert!(im["hidden_share"].as_f64().unwrap() > 0.01, "each frame hides some ground: {im}");
    }
}

/// The same hidden pixels whichever way the run goes: one thread or two,
/// bands of tile rows or of tile columns (the transposed walk).
#[test]
fn occlusion_is_the_same_on_one_thread_and_walked_by_columns() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scene(d);
    let cam = d.join("cam.toml");
    frame_camera(&cam, 120.0, -30.0, 120.0 * 30f64.to_radians().tan());
    let bounds = format!("{},{},{},{}", X0 + 5.0, Y0 - SIDE + 5.0, X0 + SIDE - 5.0, Y0 - 5.0);
    let (scan, dsm) = (d.join("scan.tif"), d.join("dsm.tif"));
    let make = |out: &str, extra: &[&str]| {
        let p = d.join(out);
        let mut a = vec!["rectify", "--image", s(&scan), "--camera", s(&cam), "--dem", s(&dsm), "--gsd", "0.2"];
        a.extend_from_slice(&["--bounds", &bounds, "--occlusion", "nodata", "--quiet", "-o", s(&p)]);
        a.extend_from_slice(extra);
        let o = run(&a);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        read_f32(&p).3
    };
    let base = make("a.tif", &[]);
    assert!(base.iter().filter(|v| v.is_nan()).count() > 10_000, "ground is hidden");
    // One thread writes the same bytes.
    let other = make("b.tif", &["--threads", "1"]);
    assert!(base.iter().zip(&other).all(|(a, b)| a.to_bits() == b.to_bits()), "one thread: the same pixels");
    // Walked by columns the GCM's nodes lie otherwise (positions agree
    // within its bound, 0.1 px): hidden pixels may differ at the boundary.
    let other = make("c.tif", &["--band-order", "columns"]);
    let hidden = base.chunks_exact(2).filter(|p| p[0].is_nan()).count();
    let flipped = base.chunks_exact(2).zip(other.chunks_exact(2)).filter(|(a, b)| a[0].is_nan() != b[0].is_nan()).count();
    assert!(flipped as f64 <= 0.002 * hidden as f64, "columns: {flipped} of {hidden} hidden pixels differ");
}

/// `--occlusion mask` keeps what the scan shows at hidden pixels and says
/// in the internal mask that they have no value (GDAL reads it so); the
/// settings that cannot work are refused by name.
#[test]
fn occlusion_mask_keeps_values_under_the_mask_and_bad_settings_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scene(d);
    let cam = d.join("cam.toml");
    frame_camera(&cam, 150.0, 0.0, 0.0);
    let bounds = format!("{},{},{},{}", X0 + 5.0, Y0 - SIDE + 5.0, X0 + SIDE - 5.0, Y0 - 5.0);
    let scan = d.join("scan.tif");
    let make = |out: &str, extra: &[&str]| {
        let p = d.join(out);
        let mut a = vec!["rectify", "--image", s(&scan), "--camera", s(&cam), "--gsd", "0.2", "--bounds", &bounds, "--quiet", "-o", s(&p)];
        a.extend_from_slice(extra);
        run(&a)
    };
    let dsm = d.join("dsm.tif");
    for (extra, want) in [
        (vec!["--height", "100", "--occlusion", "nodata"], "--occlusion"),
        (vec!["--dem", s(&dsm), "--occlusion", "mask", "--nodata", "0"], "--occlusion"),
        (vec!["--dem", s(&dsm), "--occlusion", "sometimes"], "--occlusion"),
    ] {
        let o = make("bad.tif", &extra);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(want) && !err.contains("panicked"), "{extra:?}: {err}");
        assert!(!d.join("bad.tif").exists());
    }
    assert!(make("plain.tif", &["--dem", s(&dsm)]).status.success());
    let o = make("mask.tif", &["--dem", s(&dsm), "--occlusion", "mask", "--json", s(&d.join("mask.json"))]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The values are those of the ordinary orthophoto, every one.
    let (plain, masked) = (read_f32(&d.join("plain.tif")).3, read_f32(&d.join("mask.tif")).3);
    assert!(plain.iter().zip(&masked).all(|(a, b)| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())));
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("mask.json")).unwrap()).unwrap();
    let hidden = report["occlusion"]["hidden_px"].as_u64().unwrap();
    assert!(hidden > 5000);
    // GDAL's mask: 0 at the hidden pixels and where there is no image.
    let Some(python) = common::python_with("osgeo.gdal", "python3-gdal") else { return };
    let out = std::process::Command::new(python)
        .args(["-c", "import sys; from osgeo import gdal; ds = gdal.Open(sys.argv[1]); b = ds.GetRasterBand(1); m = b.GetMaskBand().ReadAsArray(); print(int((m == 0).sum()), b.GetMaskFlags())", s(&d.join("mask.tif"))])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let mut it = text.split_whitespace().map(|v| v.parse::<u64>().unwrap());
    let (zeros, flags) = (it.next().unwrap(), it.next().unwrap());
    let outside = plain.chunks_exact(2).filter(|p| p[0].is_nan()).count() as u64;
    assert_eq!(flags, 2, "a per-dataset mask");
    assert_eq!(zeros, hidden + outside, "the mask's empty pixels are the hidden ones and those outside the image");
}

/// Real data: the Pléiades crop over Mont Ventoux on an SRTM crop (EPSG:4326,
/// reprojected on the fly, 90 m posts). A satellite looking down on
/// mountain slopes hides nothing: `--occlusion nodata` writes the same
/// file as none and reports nothing hidden.
#[test]
fn a_real_satellite_crop_over_srtm_hides_nothing() {
    let fx = |n: &str| Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/ventoux").join(n);
    let dir = tempfile::tempdir().unwrap();
    let make = |mode: &str| {
        let out = dir.path().join(format!("{mode}.tif"));
        let json = dir.path().join(format!("{mode}.json"));
        let o = run(&[
            "rectify",
            "--image",
            s(&fx("left_image.tif")),
            "--rpc",
            s(&fx("left_image.geom")),
            "--rpc-offset",
            "5000,5000",
            "--dem",
            s(&fx("srtm_N44E005_crop.tif")),
            "--geoid",
            s(&fx("egm96_15_ventoux.gtx")),
            "--occlusion",
            mode,
            "--json",
            s(&json),
            "--quiet",
            "-o",
            s(&out),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        // What it shows (the metadata names the settings, --occlusion too).
        (content(&out), serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(&json).unwrap()).unwrap())
    };
    let ((plain, _), (occ, report)) = (make("none"), make("nodata"));
    assert_eq!(report["occlusion"]["hidden_px"].as_u64(), Some(0));
    assert!(report["occlusion"]["imaged_px"].as_u64().unwrap() > 200_000);
    assert!(plain == occ, "the same orthophoto");
}
