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

use common::{coordinate_image, f32_raster, read_f32, run, s};
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
