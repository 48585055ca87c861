//! Helpers shared by the integration tests: scenes, running the binary.
#![allow(dead_code)]

use gcm_ortho::synth::{synth, SynthOptions, SynthReport};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_gcm-ortho"))
}

/// Runs the binary with `args`.
pub fn run(args: &[&str]) -> Output {
    Command::new(bin()).args(args).output().expect("the binary runs")
}

/// The drone over buildings: an oblique frame (25° off nadir) with strong
/// barrel distortion over a DSM posted at 1 m, `w`×`h` px from `scale`, in
/// `dir/scene`.
pub fn drone_scene(dir: &Path, size: (u32, u32), scale: f64) -> SynthReport {
    drone_scene_posted(dir, size, scale, 1.0)
}

/// [`drone_scene`] with its DSM posted every `posting` metres.
pub fn drone_scene_posted(dir: &Path, (w, h): (u32, u32), scale: f64, posting: f64) -> SynthReport {
    scene(&dir.join("scene"), w, |o| {
        o.height = h;
        o.camera = gcm_ortho::synth::CameraKind::Drone;
        o.relief = gcm_ortho::synth::Relief::Urban;
        o.dem_posting = posting;
        o.scale = scale;
        o.off_nadir_deg = 25.0;
        o.kappa_deg = 17.0;
    })
}

/// A small film scene (hilly, swing 30°) in `dir`.
pub fn scene(dir: &Path, size: u32, f: impl FnOnce(&mut SynthOptions)) -> SynthReport {
    let mut o = SynthOptions::default();
    (o.out, o.width, o.height, o.kappa_deg) = (dir.to_path_buf(), size, size, 30.0);
    f(&mut o);
    synth(&o, &gcm_ortho::NoProgress).expect("synth works")
}

pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Is a reference tool (GDAL's) installed? Tests that compare with it
/// print why they are skipped when it is not; under CI (`CI` set), where
/// `.ci/run` installs it, a missing tool fails the test instead.
pub fn have(tool: &str) -> bool {
    let found = Command::new(tool).arg("--version").output().map(|o| o.status.success()).unwrap_or(false);
    assert!(found || std::env::var_os("CI").is_none(), "{tool} is missing, and CI must compare with it (install gdal-bin)");
    found
}

/// Files in `dir` whose names contain `part`.
pub fn files_containing(dir: &Path, part: &str) -> Vec<String> {
    std::fs::read_dir(dir)
        .map(|rd| rd.filter_map(|e| e.ok()).map(|e| e.file_name().to_string_lossy().into_owned()).filter(|n| n.contains(part)).collect())
        .unwrap_or_default()
}

/// Waits for a child at most `secs` seconds; a hang kills it and fails.
pub fn wait_deadline(mut child: std::process::Child, secs: u64) -> Output {
    let t = std::time::Instant::now();
    loop {
        if child.try_wait().expect("try_wait").is_some() {
            return child.wait_with_output().expect("output");
        }
        if t.elapsed().as_secs() >= secs {
            let _ = child.kill();
            panic!("the process hung for {secs} s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// Writes a 2-band Float32 "coordinate image": every pixel holds its own
/// continuous (column, row) centre. Warped with bilinear resampling (exact
/// on a linear ramp), an orthophoto of it is the map output pixel → scan
/// position of the warper, so two warpers' geometries compare pixel by
/// pixel, free of any image-matching noise.
pub fn coordinate_image(path: &Path, w: u32, h: u32) {
    coordinate_image_from(path, w, h, 0.0);
}

/// As [`coordinate_image`], its columns counted from `col0` (which of
/// several images a mosaic's pixel came from, and where in it).
pub fn coordinate_image_from(path: &Path, w: u32, h: u32, col0: f32) {
    use gcm_ortho::io::tiff_out::write_raster;
    let spec = plain_spec((w, h), 2, gcm_ortho::io::source::SampleType::F32, None);
    write_raster(path, &spec, |y0, y1, buf| {
        for y in y0..y1 {
            for x in 0..w {
                let k = 8 * ((y - y0) as usize * w as usize + x as usize);
                buf[k..k + 4].copy_from_slice(&(col0 + x as f32 + 0.5).to_ne_bytes());
                buf[k + 4..k + 8].copy_from_slice(&(y as f32 + 0.5).to_ne_bytes());
            }
        }
    })
    .expect("the coordinate image is written");
}

/// The bands of a Float32 raster, band-interleaved by pixel, and its size.
pub fn read_f32(path: &Path) -> (u32, u32, u32, Vec<f32>) {
    use gcm_ortho::io::source::{SourceImage, Window};
    let src = SourceImage::open(path, 64 << 20).expect("the raster opens");
    let (w, h, b) = (src.info.width, src.info.height, src.info.bands);
    let mut win = Window::default();
    src.read_window(0, 0, w, h, &mut win).expect("the raster reads");
    (w, h, b, win.bytes().chunks_exact(4).map(|c| f32::from_ne_bytes([c[0], c[1], c[2], c[3]])).collect())
}

/// The bands of a Float64 raster, band-interleaved by pixel, and its size.
pub fn read_f64(path: &Path) -> (u32, u32, u32, Vec<f64>) {
    let f = std::fs::File::open(path).expect("the raster opens");
    let mut dec = tiff::decoder::Decoder::new(std::io::BufReader::new(f)).expect("a TIFF");
    let (w, h) = dec.dimensions().expect("dimensions");
    let bands = match dec.colortype().expect("colour type") {
        tiff::ColorType::RGB(_) => 3,
        tiff::ColorType::Gray(_) => 1,
        tiff::ColorType::Multiband { num_samples, .. } => num_samples as u32,
        c => panic!("unexpected {c:?}"),
    };
    match dec.read_image().expect("pixels") {
        tiff::decoder::DecodingResult::F64(v) => (w, h, bands, v),
        _ => panic!("not Float64"),
    }
}

/// Every sample of an image file as bytes (chunky), with what the reader
/// found in it (size, georeferencing, …).
pub fn whole_image(path: &Path) -> (Vec<u8>, gcm_ortho::io::source::SourceInfo) {
    let img = gcm_ortho::io::source::SourceImage::open(path, 1 << 20).expect("the image opens");
    let mut win = gcm_ortho::io::source::Window::default();
    img.read_window(0, 0, img.info.width, img.info.height, &mut win).expect("the image reads");
    (win.bytes().to_vec(), img.info.clone())
}

/// What an orthophoto shows: its pixels, size, grid and whether it has a
/// mask; not its metadata (which names the files it was made from).
pub type Content = (Vec<u8>, u32, u32, Option<[f64; 6]>, bool);

pub fn content(path: &Path) -> Content {
    let (pixels, info) = whole_image(path);
    (pixels, info.width, info.height, info.georef.map(|g| g.transform), info.mask.is_some())
}

/// Per-pixel differences between two coordinate-image orthophotos where
/// both are valid and away from the scan's edge (where bilinear
/// resampling differs by design).
pub struct MapDifference {
    pub pixels: usize,
    /// Mean (column, row) displacement: the geometric offset between the two.
    pub offset: [f64; 2],
    pub mean: f64,
    pub max: f64,
}

pub fn coordinate_map_difference(a: &Path, b: &Path, w: u32, h: u32) -> MapDifference {
    let (aw, ah, _, va) = read_f32(a);
    let (bw, bh, _, vb) = read_f32(b);
    assert_eq!((aw, ah), (bw, bh), "same output grid");
    let inside = |c: f32, r: f32| c > 1.5 && r > 1.5 && c < w as f32 - 1.5 && r < h as f32 - 1.5;
    let (mut n, mut sum, mut max, mut off) = (0usize, 0f64, 0f64, [0f64; 2]);
    for k in 0..(aw * ah) as usize {
        let (ca, ra, cb, rb) = (va[2 * k], va[2 * k + 1], vb[2 * k], vb[2 * k + 1]);
        if inside(ca, ra) && inside(cb, rb) {
            let (dc, dr) = ((ca - cb) as f64, (ra - rb) as f64);
            n += 1;
            sum += dc.hypot(dr);
            max = max.max(dc.hypot(dr));
            off = [off[0] + dc, off[1] + dr];
        }
    }
    let m = n.max(1) as f64;
    MapDifference { pixels: n, offset: [off[0] / m, off[1] / m], mean: sum / m, max }
}

/// Debian's Python 3 when it can import `module` (`None` otherwise; under
/// CI a missing module fails the test: install the Debian `package`).
pub fn python_with(module: &str, package: &str) -> Option<&'static str> {
    // Debian's own interpreter: the GDAL and OpenCV bindings are its packages.
    let python = if Path::new("/usr/bin/python3").exists() { "/usr/bin/python3" } else { "python3" };
    let found = Command::new(python).args(["-c", &format!("import {module}")]).output().map(|o| o.status.success()).unwrap_or(false);
    assert!(found || std::env::var_os("CI").is_none(), "Python's {module} is missing, and CI must compare with it (install {package})");
    found.then_some(python)
}

/// A one-band Float32 GeoTIFF, `w`×`h`, striped and uncompressed, north-up
/// with its north-west corner at (x0, y0) and square pixels of `gsd` in
/// EPSG `epsg`, no nodata tag; pixel (col, row) holds `value(col, row)`.
pub fn f32_raster(path: &Path, (w, h): (u32, u32), (x0, y0, gsd, epsg): (f64, f64, f64, u32), value: impl Fn(u32, u32) -> f32 + Sync) {
    f32_raster_with_keys(path, (w, h), (x0, y0, gsd), gcm_ortho::geodesy::geokeys::keys_of_epsg(epsg).unwrap(), value)
}

/// As [`f32_raster`], its CRS given as GeoTIFF keys (none: empty keys).
pub fn f32_raster_with_keys(
    path: &Path,
    (w, h): (u32, u32),
    (x0, y0, gsd): (f64, f64, f64),
    keys: gcm_ortho::io::geotiff::GeoKeys,
    value: impl Fn(u32, u32) -> f32 + Sync,
) {
    use gcm_ortho::io::tiff_out::{write_raster, GeoTags};
    let geo = GeoTags { x0, y0, gsd: gcm_ortho::geom::Gsd::square(gsd), keys, nodata: None };
    let spec = plain_spec((w, h), 1, gcm_ortho::io::source::SampleType::F32, Some(geo));
    write_raster(path, &spec, |r0, _, buf| {
        for (k, v) in buf.chunks_exact_mut(4).enumerate() {
            let (col, row) = (k as u32 % w, r0 + k as u32 / w);
            v.copy_from_slice(&value(col, row).to_ne_bytes());
        }
    })
    .expect("the raster is written");
}

/// An uncompressed striped raster's layout: `bands` of `sample`, grey,
/// georeferenced by `geo` if given.
pub fn plain_spec(
    (w, h): (u32, u32),
    bands: u32,
    sample: gcm_ortho::io::source::SampleType,
    geo: Option<gcm_ortho::io::tiff_out::GeoTags>,
) -> gcm_ortho::io::tiff_out::OutputSpec {
    use gcm_ortho::io::tiff_out::{Chunking, Compression, OutputSpec};
    OutputSpec {
        overviews: 0,
        cog: false,
        width: w,
        height: h,
        bands,
        sample,
        chunking: Chunking::Strips(16),
        compression: Compression::None,
        level: None,
        overview_level: None,
        bigtiff: false,
        photometric: 1,
        alpha: false,
        mask: false,
        geo,
    }
}
