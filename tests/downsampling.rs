//! Downsampling without aliasing: the area kernels (`--resample average`,
//! `mode`) against a box filter and a mode worked out here, and `average`
//! against gdalwarp's, on a flat scene seen straight down (where every
//! output pixel's footprint is a rectangle of the scan).

mod common;
use common::*;
use std::path::Path;

/// A vertical frame camera 1000 m over flat ground: 0.1 m a scan pixel,
/// scan columns east, rows south, no distortion or refraction.
const CAMERA: &str = r#"crs = "EPSG:32631"

[camera]
model = "frame"
focal_length_mm = 100.0

[interior]
pixel_size_mm = 0.01
principal_point_px = [600.0, 500.0]

[exterior]
position = [500000.0, 4000000.0, 1000.0]
angles_deg = [0.0, 0.0, 0.0]
convention = "omega-phi-kappa"

[corrections]
refraction = "none"
earth_curvature = false
"#;

const W: u32 = 1200;
const H: u32 = 1000;

/// A one-band 8-bit scan of `value(col, row)`, georeferenced if `geo`.
fn u8_scan(path: &Path, geo: Option<[f64; 4]>, value: impl Fn(u32, u32) -> u8 + Sync) {
    use gcm_ortho::io::tiff_out::{write_raster, GeoTags};
    let geo = geo.map(|[x0, y0, gx, gy]| GeoTags {
        x0,
        y0,
        gsd: gcm_ortho::geom::Gsd { x: gx, y: gy },
        keys: gcm_ortho::geodesy::geokeys::keys_of_epsg(32631).unwrap(),
        nodata: None,
    });
    let spec = plain_spec((W, H), 1, gcm_ortho::io::source::SampleType::U8, geo);
    write_raster(path, &spec, |r0, _, buf| {
        for (k, v) in buf.iter_mut().enumerate() {
            *v = value(k as u32 % W, r0 + k as u32 / W);
        }
    })
    .expect("the scan is written");
}

/// A checkerboard of 3-pixel squares: at 10× reduction a point kernel
/// samples it at random phases.
fn checker(c: u32, r: u32) -> u8 {
    if (c / 3 + r / 3).is_multiple_of(2) {
        40
    } else {
        220
    }
}

struct Scene {
    dir: tempfile::TempDir,
}

impl Scene {
    fn new() -> Scene {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("camera.toml"), CAMERA).unwrap();
        coordinate_image(&dir.path().join("coords.tif"), W, H);
        Scene { dir }
    }

    fn path(&self, name: &str) -> std::path::PathBuf {
        self.dir.path().join(name)
    }

    /// `rectify` of `image` at `gsd` over flat ground with `kernel`.
    fn rectify(&self, image: &str, out: &str, gsd: &str, kernel: &str) -> std::path::PathBuf {
        self.rectify_saying(image, out, gsd, kernel).0
    }

    /// [`Scene::rectify`], and what it said on stderr.
    fn rectify_saying(&self, image: &str, out: &str, gsd: &str, kernel: &str) -> (std::path::PathBuf, String) {
        let o = self.path(out);
        let r = run(&[
            "rectify",
            "--image",
            s(&self.path(image)),
            "--camera",
            s(&self.path("camera.toml")),
            "--height",
            "0",
            "--gsd",
            gsd,
            "--resample",
            kernel,
            "--quiet",
            "-o",
            s(&o),
        ]);
        assert!(r.status.success(), "{out}: {}", String::from_utf8_lossy(&r.stderr));
        (o, String::from_utf8_lossy(&r.stderr).into_owned())
    }
}

/// Each output pixel's footprint in the scan, `[c0, r0, c1, r1]`, from the
/// coordinate image rectified at the same grid (its centre; the pixel's
/// extent from the neighbours' centres), and the grid's size.
fn footprints(sc: &Scene, gsd: &str) -> (u32, u32, Vec<Option<[f64; 4]>>) {
    let (w, h, _, p) = read_f32(&sc.rectify("coords.tif", &format!("coords_{gsd}.tif"), gsd, "bilinear"));
    let at = |x: u32, y: u32| (p[2 * (y * w + x) as usize] as f64, p[2 * (y * w + x) as usize + 1] as f64);
    // The map is a scale along each axis: columns go with x alone, rows with y.
    let (sx, sy) = ((at(w - 2, h / 2).0 - at(1, h / 2).0) / (w - 3) as f64, (at(w / 2, h - 2).1 - at(w / 2, 1).1) / (h - 3) as f64);
    assert!((at(w / 2, 1).0 - at(w / 2, h - 2).0).abs() < 1e-3 && (at(1, h / 2).1 - at(w - 2, h / 2).1).abs() < 1e-3, "not axis-aligned");
    let feet = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let (c, r) = at(x, y);
            let f = [c - sx.abs() / 2.0, r - sy.abs() / 2.0, c + sx.abs() / 2.0, r + sy.abs() / 2.0];
            (c.is_finite() && f[0] >= 0.0 && f[1] >= 0.0 && f[2] <= W as f64 && f[3] <= H as f64).then_some(f)
        })
        .collect();
    (w, h, feet)
}

/// The box filter: the mean of `value` over `[c0, c1] × [r0, r1]`, each
/// scan pixel weighted by the share of it inside.
fn box_mean(f: [f64; 4], value: impl Fn(u32, u32) -> u8) -> f64 {
    let share = |i: u32, a: f64, b: f64| ((i + 1) as f64).min(b) - (i as f64).max(a);
    let (mut sum, mut weight) = (0.0, 0.0);
    for r in f[1].floor() as u32..f[3].ceil() as u32 {
        for c in f[0].floor() as u32..f[2].ceil() as u32 {
            let a = share(c, f[0], f[2]).max(0.0) * share(r, f[1], f[3]).max(0.0);
            sum += a * value(c, r) as f64;
            weight += a;
        }
    }
    sum / weight
}

/// The largest and mean difference of an 8-bit orthophoto from `want`
/// over the pixels whose footprint lies in the scan.
fn against(out: &Path, feet: &[Option<[f64; 4]>], want: impl Fn([f64; 4]) -> f64) -> (f64, f64) {
    let (px, _) = whole_image(out);
    let d: Vec<f64> = feet.iter().zip(&px).filter_map(|(f, &v)| f.map(|f| (v as f64 - want(f)).abs())).collect();
    assert!(d.len() > feet.len() / 2, "{} of {}", d.len(), feet.len());
    (d.iter().copied().fold(0.0, f64::max), d.iter().sum::<f64>() / d.len() as f64)
}

#[test]
fn average_is_the_box_filter_where_bilinear_aliases() {
    let sc = Scene::new();
    u8_scan(&sc.path("checker.tif"), None, checker);
    // 10× (footprints on whole scan pixels), 7.3× (cut pixels) and 10 × 20
    // (non-square output pixels).
    for gsd in ["1", "0.73", "1,2"] {
        let (_, _, feet) = footprints(&sc, gsd);
        let (avg, quiet) = sc.rectify_saying("checker.tif", &format!("avg_{gsd}.tif"), gsd, "average");
        let (bil, warned) = sc.rectify_saying("checker.tif", &format!("bil_{gsd}.tif"), gsd, "bilinear");
        // Said even under --quiet: the point kernel aliases here.
        assert!(warned.contains("warning") && warned.contains("--resample average"), "{warned}");
        assert!(quiet.is_empty(), "{quiet}");
        let (worst, mean) = against(&avg, &feet, |f| box_mean(f, checker));
        let (_, aliased) = against(&bil, &feet, |f| box_mean(f, checker));
        println!("{gsd} m: average vs box filter max {worst:.2}, mean {mean:.3} DN; bilinear mean {aliased:.1} DN");
        assert!(worst <= 1.0, "{gsd}: average {worst} DN from the box filter");
        assert!(aliased > 20.0, "{gsd}: bilinear should alias here ({aliased})");
    }
}

#[test]
fn mode_takes_the_class_covering_most_of_each_pixel() {
    let sc = Scene::new();
    // Classes in patches of uneven size, so most 10×10 blocks hold several.
    let class = |c: u32, r: u32| ((c / 7 + 3 * (r / 4) + (c / 13) * (r / 9)) % 5 + 1) as u8;
    u8_scan(&sc.path("classes.tif"), None, class);
    let (_, _, feet) = footprints(&sc, "1");
    let out = sc.rectify("classes.tif", "mode.tif", "1", "mode");
    let (px, _) = whole_image(&out);
    let mut checked = 0;
    for (f, &v) in feet.iter().zip(&px) {
        let Some(f) = f else { continue };
        // Whole pixels at 10×: count them; of equal counts, the smaller class.
        let mut n = [0u32; 6];
        for r in f[1].round() as u32..f[3].round() as u32 {
            for c in f[0].round() as u32..f[2].round() as u32 {
                n[class(c, r) as usize] += 1;
            }
        }
        let best = (1..6).fold(1, |b, k| if n[k] > n[b] { k } else { b });
        assert_eq!(v as usize, best, "footprint {f:?}: counts {n:?}");
        checked += 1;
    }
    assert!(checked > 5000, "{checked}");
}

#[test]
fn average_agrees_with_gdalwarp_on_a_flat_scene() {
    if !have("gdalwarp") && std::env::var_os("CI").is_none() {
        eprintln!("gdalwarp missing: comparison skipped (it fails under CI)");
        return;
    }
    let sc = Scene::new();
    u8_scan(&sc.path("checker.tif"), None, checker);
    let gsd = "0.73";
    let ours = sc.rectify("checker.tif", "ours.tif", gsd, "average");
    let (w, h, _) = footprints(&sc, gsd);
    // The same pixels georeferenced as the camera sees them (0.1 m, the
    // principal point (600, 500) under the camera), for gdalwarp.
    u8_scan(&sc.path("geo.tif"), Some([500000.0 - 60.0, 4000000.0 + 50.0, 0.1, 0.1]), checker);
    let info = gcm_ortho::io::source::SourceImage::open(&ours, 1 << 20).unwrap().info;
    let gt = info.georef.unwrap().transform;
    let te = [gt[0], gt[3] + gt[5] * h as f64, gt[0] + gt[1] * w as f64, gt[3]].map(|v| v.to_string());
    let theirs = sc.path("gdal.tif");
    let out = std::process::Command::new("gdalwarp")
        .args(["-q", "-r", "average", "-tr", gsd, gsd, "-te"])
        .args(&te)
        .args([s(&sc.path("geo.tif")), s(&theirs)])
        .output()
        .expect("gdalwarp runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let ((a, _), (b, _)) = (whole_image(&ours), whole_image(&theirs));
    assert_eq!(a.len(), b.len());
    // Away from the scan's edges (where gdalwarp's pixels are cut).
    let (mut worst, mut n) = (0i32, 0);
    for y in 2..h as usize - 2 {
        for x in 2..w as usize - 2 {
            let k = y * w as usize + x;
            worst = worst.max((a[k] as i32 - b[k] as i32).abs());
            n += 1;
        }
    }
    println!("average vs gdalwarp -r average at {gsd} m: {n} px, max {worst} DN");
    assert!(worst <= 1, "{worst} DN from gdalwarp");
}
