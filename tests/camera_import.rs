//! Camera and pose files of other tools, read into our cameras: every
//! number checked against the tool's own reading of the same file (values
//! computed with Orthority 0.7.0, whose pixel centres are at integers —
//! ours at +½), and the file-name matching, delimiters and refusals users
//! meet.

mod common;

use gcm_ortho::camera::file::Camera;
use gcm_ortho::camera::formats;
use gcm_ortho::camera::rotation::AngleConvention;
use std::path::{Path, PathBuf};

fn fixture(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures").join(rel)
}

/// World points (EPSG:32633) and where Orthority's camera of each kind
/// images them (Orthority's pixels), the pose at (500100, 4100200, 700)
/// with ω, φ, κ = 2.5°, −1.5°, 30°.
const WORLD: [[f64; 3]; 4] = [[500150.0, 4100260.0, 120.0], [500020.0, 4100150.0, 80.0], [500100.0, 4100200.0, 100.0], [500300.0, 4100500.0, 150.0]];
const BROWN: [[f64; 2]; 4] =
    [[356.472180131158, 240.794927637208], [209.103056864945, 268.448273361109], [289.397865204992, 265.489676514034], [578.118930817846, 125.129622292244]];
const OPENCV: [[f64; 2]; 4] =
    [[356.472900690984, 240.796502589524], [209.167150397126, 268.446174919734], [289.399865599715, 265.489611487563], [577.375687255787, 125.64151590563]];
const FISHEYE: [[f64; 2]; 4] =
    [[345.473575129344, 232.581518590754], [256.72797783225, 249.09813168557], [305.263611011869, 247.409291099661], [475.659770750591, 162.962594273833]];
const PINHOLE_MM: [[f64; 2]; 4] =
    [[92.012332580039, 98.25926306718], [24.982255876275, 110.82622957381], [61.816249261672, 109.485019713817], [198.610695262985, 41.175239392837]];

fn camera(image: &str, cameras: &str, poses: &str) -> Camera {
    gcm_ortho::scene::camera::read_for(Path::new(image), &fixture(cameras), Some(&fixture(poses)), Default::default(), None)
        .unwrap_or_else(|e| panic!("{image}: {e}"))
}

fn assert_projects(cam: &Camera, expected: &[[f64; 2]; 4], what: &str) {
    for (p, e) in WORLD.iter().zip(expected) {
        let (c, r) = cam.model().project(p[0], p[1], p[2]).expect("imaged");
        let (dc, dr) = (c - (e[0] + 0.5), r - (e[1] + 0.5));
        assert!(dc.abs() < 1e-6 && dr.abs() < 1e-6, "{what}: {p:?} → ({c}, {r}), Orthority ({}, {}) + ½", e[0], e[1]);
    }
}

#[test]
fn orthority_interior_and_csv_project_as_orthority_does() {
    let csv = "orthority/ext_param.csv";
    let yaml = "orthority/int_param.yaml";
    assert_projects(&camera("img_a.tif", yaml, csv), &BROWN, "brown");
    assert_projects(&camera("img_opencv.tif", yaml, csv), &OPENCV, "opencv");
    assert_projects(&camera("img_fisheye.tif", yaml, csv), &FISHEYE, "fisheye");
    assert_projects(&camera("img_pinhole.tif", yaml, csv), &PINHOLE_MM, "pinhole with sensor_size");
}

#[test]
fn orthority_geojson_as_it_writes_it() {
    // Written by Orthority's own exporter: ω, φ, κ in radians, world_crs.
    let cam = camera("img_a.tif", "orthority/int_param.yaml", "orthority/ext_param.geojson");
    assert_projects(&cam, &BROWN, "GeoJSON");
    assert_eq!(cam.crs.epsg(), Some(32633));
}

#[test]
fn the_portrait_reading_of_focal_len_is_warned_about() {
    let set = formats::read(&fixture("orthority/int_param.yaml"), None, None).unwrap();
    assert_eq!(set.lenses.len(), 5);
    assert!(set.warnings.iter().any(|w| w.contains("portrait cam") && w.contains("width")), "{:?}", set.warnings);
    // pinhole with sensor_size: fx = 120·150/75, fy = 121·200/100; the
    // principal point (w−1)/2 + max(w,h)·cx, + ½ for our pixel centres.
    let (_, lens) = set.lenses.iter().find(|(id, _)| id == "pinhole mm cam").unwrap();
    assert_eq!(lens.focal_px, [240.0, 242.0]);
    assert!((lens.principal_point_px[0] - 73.0).abs() < 1e-12 && (lens.principal_point_px[1] - 104.0).abs() < 1e-12, "{:?}", lens.principal_point_px);
    assert_eq!(lens.focal_mm, Some(120.0));
}

#[test]
fn latitude_longitude_with_roll_pitch_yaw_as_orthority_converts_them() {
    let csv = "orthority/ext_lla_rpy.csv";
    let set = formats::read(&fixture("orthority/int_param.yaml"), Some(&fixture(csv)), None).unwrap();
    // No .prj: the UTM zone of the positions' mean (longitude 16.3°).
    assert_eq!(set.crs.as_deref(), Some("EPSG:32633"));
    let pose = |n: &str| set.poses.iter().find(|p| p.name == n).unwrap();
    // Level, heading north: κ is the meridian convergence at 45°N 17°E
    // (Orthority's figure is a finite difference itself, good to ~3e-7°:
    // the series for the convergence gives 1.4145037°).
    let k0 = AngleConvention::OmegaPhiKappa.angles(&pose("img_r0.tif").r).map(f64::to_degrees);
    assert!(k0[0].abs() < 1e-9 && k0[1].abs() < 1e-9 && (k0[2] - 1.4145039543935882).abs() < 1e-6, "{k0:?}");
    let r1 = pose("img_r1.tif");
    let opk = AngleConvention::OmegaPhiKappa.angles(&r1.r).map(f64::to_degrees);
    let expected = [-1.6776010028735668, 3.1913805433155784, -28.591136513721036];
    for k in 0..3 {
        assert!((opk[k] - expected[k]).abs() < 1e-6, "{opk:?} vs {expected:?}");
    }
    let xyz = [657630.6407299513, 4984896.171271757, 500.0];
    for k in 0..3 {
        assert!((r1.position[k] - xyz[k]).abs() < 1e-4, "{:?} vs {xyz:?}", r1.position);
    }
}

#[test]
fn an_image_finds_its_pose_by_name_with_or_without_extension() {
    let set = formats::read(&fixture("orthority/int_param.yaml"), Some(&fixture("orthority/ext_param.csv")), None).unwrap();
    let at = |image: &str| set.camera_for(Path::new(image)).map(|c| c.exterior.unwrap().position);
    assert_eq!(at("/data/img_a.tif").unwrap(), [500100.0, 4100200.0, 700.0]);
    assert_eq!(at("img_a.jpg").unwrap(), [500100.0, 4100200.0, 700.0], "by the stem");
    assert_eq!(at("img_nadir.tif").unwrap(), [500000.0, 4100000.0, 600.0], "a pose named without extension");
    assert_eq!(at("img_c.jpg").unwrap(), [500000.0, 4100000.0, 600.0], "a directory in the pose's name");
    let missing = at("img_zz.tif").unwrap_err().to_string();
    assert!(missing.contains("img_zz.tif") && missing.contains("ext_param.csv"), "{missing}");

    let dir = tempfile::tempdir().unwrap();
    let twice = dir.path().join("twice.csv");
    std::fs::write(&twice, "name,x,y,z,omega,phi,kappa\nimg1.tif,1,2,3,0,0,0\nimg1.jpg,1,2,3,0,0,0\n").unwrap();
    std::fs::write(dir.path().join("twice.prj"), "EPSG:32633").unwrap();
    let one = dir.path().join("one.yaml");
    std::fs::write(&one, "cam:\n  type: pinhole\n  im_size: [640, 480]\n  focal_len: 0.8\n").unwrap();
    let set = formats::read(&one, Some(&twice), None).unwrap();
    assert!(set.camera_for(Path::new("img1.tif")).is_ok(), "the exact file name wins");
    let e = set.camera_for(Path::new("img1.png")).unwrap_err().to_string();
    assert!(e.contains("2 exterior orientations match") && e.contains("twice.csv:2") && e.contains("twice.csv:3"), "{e}");
}

#[test]
fn csv_dialects_users_write() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("comma.csv", "Filename, X, Y, Z, Omega, Phi, Kappa\nimg1.tif, 1.0, 2.0, 3.0, 0.1, 0.2, 0.3\n"),
        ("semi.csv", "filename;x;y;z;omega;phi;kappa;camera\nimg1;1.0;2.0;3.0;0.1;0.2;0.3;brown cam\n"),
        ("tab.txt", "filename\tx\ty\tz\tomega\tphi\tkappa\nimg1\t1.0\t2.0\t3.0\t0.1\t0.2\t0.3\n"),
        ("spaces.txt", "img1.tif 1.0 2.0  3.0 0.1 0.2 0.3\nimg2.tif 1.5 2.5 3.5 0.1 0.2 0.3\n"),
        ("block.csv", "name,X,Y,Z,omega,phi,kappa\nimg1,1.0,2.0,3.0,0.1,0.2,0.3\n"),
        // Pix4D's calibrated external camera parameters.
        ("pix4d.txt", "imageName X Y Z Omega Phi Kappa\nimg1.JPG 1.0 2.0 3.0 0.1 0.2 0.3\n"),
    ];
    for (name, text) in cases {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        std::fs::write(path.with_extension("prj"), "EPSG:32633").unwrap();
        let set = formats::read(&fixture("orthority/int_param.yaml"), Some(&path), None).unwrap_or_else(|e| panic!("{name}: {e}"));
        let p = &set.poses[0];
        assert_eq!((p.name.trim_end_matches(".tif").trim_end_matches(".JPG"), p.position), ("img1", [1.0, 2.0, 3.0]), "{name}");
        let opk = AngleConvention::OmegaPhiKappa.angles(&p.r).map(f64::to_degrees);
        assert!((opk[0] - 0.1).abs() < 1e-12 && (opk[1] - 0.2).abs() < 1e-12 && (opk[2] - 0.3).abs() < 1e-12, "{name}: {opk:?}");
    }
}

#[test]
fn bad_files_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let unknown = write("int.yaml", "cam:\n  type: brown\n  im_size: [640, 480]\n  focal_len: 0.8\n  k9: 0.1\n");
    let e = formats::read(&unknown, None, None).unwrap_err().to_string();
    assert!(e.contains("int.yaml") && e.contains("cam.k9") && e.contains("unknown"), "{e}");

    let tilt = write("tilt.yaml", "cam:\n  type: opencv\n  im_size: [640, 480]\n  focal_len: 0.8\n  tx: 0.01\n");
    let e = formats::read(&tilt, None, None).unwrap_err().to_string();
    assert!(e.contains("cam.tx") && e.contains("tilted"), "{e}");

    let not_number = write("bad.csv", "filename,x,y,z,omega,phi,kappa\nimg1,1,2,x,0,0,0\n");
    let e = formats::read(&fixture("orthority/int_param.yaml"), Some(&not_number), None).unwrap_err().to_string();
    assert!(e.contains("bad.csv") && e.contains("line 2") && e.contains("z is not a number"), "{e}");

    // Omega/phi/kappa need the CRS they are in; without a .prj it is refused
    // when the camera is built, naming the ways to give it.
    let one = write("one.yaml", "cam:\n  type: pinhole\n  im_size: [640, 480]\n  focal_len: 0.8\n");
    let no_prj = write("noprj.csv", "filename,x,y,z,omega,phi,kappa\nimg1,500000,4100000,600,0,0,0\n");
    let Err(e) = gcm_ortho::scene::camera::read_for(Path::new("img1.tif"), &one, Some(&no_prj), Default::default(), None) else {
        panic!("built without a CRS")
    };
    let e = e.to_string();
    assert!(e.contains("crs") && e.contains(".prj") && e.ends_with(", or crs"), "{e}");

    let json = write("other.json", "{\"a\": 1}");
    let e = formats::read(&json, None, None).unwrap_err().to_string();
    assert!(e.contains("other.json") && e.contains("OpenSfM"), "{e}");
}

#[test]
fn opensfm_shots_in_the_topocentric_frame_are_placed_rigorously() {
    // Outside an OpenDroneMap project: east-north-up metres at reference_lla,
    // through geocentric coordinates into its UTM zone (the centre computed
    // independently with PROJ: ENU → ECEF → EPSG:32633).
    let set = formats::read(&fixture("opensfm/reconstruction.json"), None, None).unwrap();
    assert_eq!(set.crs.as_deref(), Some("EPSG:32633"));
    let p = &set.poses[0];
    assert_eq!(p.name, "img_o.jpg");
    let expected = [657651.0898140, 4984921.154559, 250.8556134468];
    for k in 0..3 {
        assert!((p.position[k] - expected[k]).abs() < 2e-3, "{:?} vs {expected:?}", p.position);
    }
    // OpenSfM's normalised camera: focal · max(w, h), the principal point
    // from the centre by max(w, h), "v2 " dropped from the id.
    let (id, lens) = &set.lenses[0];
    assert_eq!(id, "dji fc6310r 640 480 brown 0.6666");
    assert!((lens.focal_px[0] - 544.0).abs() < 1e-9 && (lens.focal_px[1] - 550.4).abs() < 1e-9, "{:?}", lens.focal_px);
    assert!((lens.principal_point_px[0] - 326.4).abs() < 1e-9 && (lens.principal_point_px[1] - 227.2).abs() < 1e-9, "{:?}", lens.principal_point_px);
}

/// A real reconstruction is mostly its sparse points: they are skipped
/// unread (a 14.6 MB one took 342 MiB as a tree, now 21 MiB), and the
/// cameras and shots are those of the file without them.
#[test]
fn an_opensfm_reconstruction_s_points_are_skipped_unread() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(fixture("opensfm/reconstruction.json")).unwrap();
    let points: Vec<String> = (0..300_000).map(|i| format!("\"{i}\": {{\"color\": [1, 2, 3], \"coordinates\": [{i}.5, -2.25, 31.0]}}")).collect();
    let with_points = text.replace("\"points\": {}", &format!("\"points\": {{{}}}", points.join(",")));
    assert!(with_points.len() > 15 << 20);
    let path = dir.path().join("reconstruction.json");
    std::fs::write(&path, with_points).unwrap();
    let big = formats::read(&path, None, None).unwrap();
    let small = formats::read(&fixture("opensfm/reconstruction.json"), None, None).unwrap();
    assert_eq!((big.poses.len(), big.lenses.len()), (small.poses.len(), small.lenses.len()));
    assert_eq!(big.poses[0].position, small.poses[0].position);
    assert_eq!(big.poses[0].r, small.poses[0].r);
    assert_eq!(big.lenses[0].1.focal_px, small.lenses[0].1.focal_px);
}

#[test]
fn opendronemap_reconstructions_are_utm_less_an_offset() {
    // Beside reconstruction.topocentric.json the file is ODM's georeferenced
    // one: read as Orthority's `oty odm` reads it.
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(fixture("opensfm/reconstruction.json")).unwrap();
    std::fs::write(dir.path().join("reconstruction.json"), &text).unwrap();
    std::fs::write(dir.path().join("reconstruction.topocentric.json"), &text).unwrap();
    let set = formats::read(&dir.path().join("reconstruction.json"), None, None).unwrap();
    let p = &set.poses[0];
    let expected = [657651.7031179434, 4984920.645428927, 250.85553169477427];
    for k in 0..3 {
        assert!((p.position[k] - expected[k]).abs() < 1e-4, "{:?} vs {expected:?}", p.position);
    }
    let opk = AngleConvention::OmegaPhiKappa.angles(&p.r);
    let expected = [0.04091436096298284, 0.013557313833687693, 0.031977880328755405];
    for k in 0..3 {
        assert!((opk[k] - expected[k]).abs() < 1e-9, "{opk:?} vs {expected:?}");
    }
}

/// Where Orthority 0.7.0 (`oty exif`'s reading of the same file) images
/// three world points through `fixtures/exif/dji_oblique.jpg`'s camera.
const DJI_WORLD: [[f64; 3]; 3] =
    [[657832.8578308772, 4985113.565288285, 230.0], [657862.8578308772, 4985133.565288285, 240.0], [657852.8578308772, 4985163.565288285, 235.0]];
const DJI_PIXELS: [[f64; 2]; 3] = [[58.00579068376169, 31.5610853493057], [69.21946866721512, 10.353449058661191], [54.2453789966269, 3.6970060835692067]];

#[test]
fn a_dji_image_is_its_own_camera_as_orthority_reads_it() {
    // Gimbal pitch −60°, yaw 30.5°, roll 0; DewarpData (Brown); XMP position.
    let image = fixture("exif/dji_oblique.jpg");
    let cam = gcm_ortho::scene::camera::read_for(&image, Path::new("exif"), None, Default::default(), None).unwrap();
    assert_eq!(cam.crs.epsg(), Some(32633), "the UTM zone of the position");
    for (p, e) in DJI_WORLD.iter().zip(DJI_PIXELS) {
        let (c, r) = cam.model().project(p[0], p[1], p[2]).unwrap();
        assert!((c - e[0] - 0.5).abs() < 1e-6 && (r - e[1] - 0.5).abs() < 1e-6, "{p:?} → ({c}, {r}), Orthority {e:?} + ½");
    }
    assert!(cam.warnings.is_empty(), "{:?}", cam.warnings);
}

/// The same XMP in a TIFF's tag 700 written as ASCII (as some firmware
/// writes it; BYTE is the specification's), or in a `.xmp` sidecar beside
/// a TIFF with none, gives the JPEG's pose.
#[test]
fn a_dji_tiffs_xmp_is_read_from_tag_700_or_its_sidecar() {
    let jpeg = formats::read_for(&fixture("exif/dji_oblique.jpg"), Path::new("exif"), None, None).unwrap();
    let want = &jpeg.poses[0];
    for tif in ["exif/dji_xmp_ascii.tif", "exif/dji_sidecar.tif"] {
        let set = formats::read_for(&fixture(tif), Path::new("exif"), None, None).unwrap_or_else(|e| panic!("{tif}: {e}"));
        let pose = &set.poses[0];
        assert!((0..3).all(|k| (pose.position[k] - want.position[k]).abs() < 1e-6), "{tif}: {:?} vs {:?}", pose.position, want.position);
        assert!((pose.r - want.r).abs().max() < 1e-12, "{tif}: {} vs {}", pose.r, want.r);
        assert_eq!(set.relative_altitude, jpeg.relative_altitude, "{tif}");
    }
}

#[test]
fn a_nadir_dji_frame_tagged_roll_180_looks_down() {
    // Pitch −90°, roll +180°, yaw −149.5°: the frame turned in its own
    // plane, the same view as roll 0 and yaw 30.5° (Orthority #36: read as
    // a roll about a level axis it looks up). Only the 35 mm equivalent.
    let image = fixture("exif/dji_nadir_roll180.jpg");
    let set = formats::read_for(&image, Path::new("exif"), None, None).unwrap();
    let pose = &set.poses[0];
    let ground = gcm_ortho::geodesy::GroundCrs::new(&gcm_ortho::geodesy::Crs::from_epsg(32633).unwrap()).unwrap();
    let (lat, lon) = (45.0012, 17.0021);
    let level = formats::exif::gimbal_rotation([30.5f64.to_radians(), -90f64.to_radians(), 0.0], (lon, lat), &ground).unwrap();
    assert!((pose.r - level).abs().max() < 1e-5, "{} vs {level}", pose.r);
    assert!(pose.r[(2, 2)] > 0.999, "photo z (back from the view) is up: the camera looks down");
    // EXIF GPS (DMS rationals) when the XMP has no position.
    assert!((pose.position[2] - 350.5).abs() < 1e-9);
    let (x, y) = ground.lonlat_to_ground(lon, lat).unwrap();
    assert!((pose.position[0] - x).abs() < 0.01 && (pose.position[1] - y).abs() < 0.01, "{:?}", pose.position);
    // The 35 mm equivalent is by the diagonal: 24 mm · 150 px / 43.27 mm.
    let f = set.lenses[0].1.focal_px[0];
    assert!((f - 24.0 * 150.0 / 36f64.hypot(24.0)).abs() < 1e-9, "{f}");
    assert!(set.warnings.iter().any(|w| w.contains("35 mm equivalent") && w.contains("calibrate")), "{:?}", set.warnings);
}

/// An EXIF GPS position without GPSAltitude (and no XMP height) is refused
/// naming the tag: it was taken as 0 m and blamed on the DEM below.
#[test]
fn a_gps_position_without_an_altitude_is_refused_by_its_tag() {
    let dir = tempfile::tempdir().unwrap();
    let mut jpeg = std::fs::read(fixture("exif/dji_nadir_roll180.jpg")).unwrap();
    // The GPS directory's GPSAltitude entry (big-endian: tag 6, RATIONAL,
    // one value) renamed to a tag no reader knows.
    let entry = [0u8, 6, 0, 5, 0, 0, 0, 1];
    let at = jpeg.windows(8).position(|w| w == entry).expect("a GPSAltitude entry");
    assert_eq!(jpeg.windows(8).filter(|w| *w == entry).count(), 1);
    jpeg[at + 1] = 0xEE;
    let image = dir.path().join("no_altitude.jpg");
    std::fs::write(&image, jpeg).unwrap();
    let e = formats::read_for(&image, Path::new("exif"), None, None).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("no_altitude.jpg") && e.contains("GPSAltitude") && e.contains("camera file"), "{e}");
}

#[test]
fn an_image_without_camera_tags_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let tif = dir.path().join("plain.tif");
    common::f32_raster(&tif, (8, 8), (500000.0, 4100000.0, 1.0, 32633), |_, _| 7.0);
    let Err(e) = gcm_ortho::scene::camera::read_for(&tif, Path::new("exif"), None, Default::default(), None) else { panic!("a camera from no tags") };
    let e = e.to_string();
    assert!(e.contains("plain.tif") && e.contains("focal length") && e.contains("camera file"), "{e}");
}

#[test]
fn a_drone_height_far_from_its_relative_altitude_is_warned_about() {
    // The DJI fixture flew 120.3 m over its take-off point and is tagged at
    // 350.5 m: over ground at 230 m that agrees; over ground at 280 m the
    // camera would be 70 m up, and the run says so (even with --quiet).
    let dir = tempfile::tempdir().unwrap();
    let image = fixture("exif/dji_oblique.jpg");
    for (ground, warned) in [(230.0f32, false), (280.0, true)] {
        let dem = dir.path().join(format!("dem{ground}.tif"));
        common::f32_raster(&dem, (200, 200), (657700.0, 4985300.0, 1.0, 32633), |_, _| ground);
        let out = dir.path().join(format!("o{ground}.tif"));
        let r = common::run(&["rectify", "--image", common::s(&image), "--camera", "exif", "--dem", common::s(&dem), "--quiet", "-o", common::s(&out)]);
        let e = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.success(), "{e}");
        assert_eq!(e.contains("take-off point"), warned, "ground {ground}: {e}");
    }
}

#[test]
fn opensfm_radial_cameras_carry_their_principal_point() {
    // OpenSfM's `radial` camera: focal_x, focal_y, c_x, c_y normalised by
    // the larger side, k1, k2 radial (Brown's with no tangential terms).
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("cameras.json");
    std::fs::write(
        &file,
        r#"{"cam": {"projection_type": "radial", "width": 800, "height": 600, "focal_x": 0.9, "focal_y": 0.91, "c_x": 0.01, "c_y": -0.02, "k1": -0.05, "k2": 0.01}}"#,
    )
    .unwrap();
    let set = formats::read(&file, None, None).unwrap();
    let (_, lens) = &set.lenses[0];
    assert_eq!(lens.focal_px, [720.0, 728.0]);
    // (w − 1)/2 + 800·0.01 = 407.5, (h − 1)/2 − 800·0.02 = 283.5; + ½ ours.
    assert!((lens.principal_point_px[0] - 408.0).abs() < 1e-12 && (lens.principal_point_px[1] - 284.0).abs() < 1e-12, "{:?}", lens.principal_point_px);
    let b = lens.distortion.brown.unwrap();
    assert_eq!((b.k1, b.k2, b.p1, b.p2), (-0.05, 0.01, 0.0, 0.0));
}

/// Pix4D's calibrated camera parameters of a real project (EasyIDP's maize
/// field, DJI FC550): the camera as the file's P-matrix (`K [R | −Rt]`, in
/// the project's local frame, the offset beside) images the ground, to
/// the P-matrix's printed precision; the lens is OpenCV's Brown with
/// p1, p2 = T1, T2 (as Pix4D's own tools map them); the `.cam` in mm gives
/// the same lens on the image's 4608 pixels.
#[test]
fn pix4d_calibrated_parameters_image_the_ground_as_their_p_matrix() {
    let dir = fixture("pix4d");
    let ccp = dir.join("maize_calibrated_camera_parameters.txt");
    let set = formats::read(&ccp, None, None).unwrap();
    let mut file = set.camera_for(Path::new("DJI_0954.JPG")).unwrap();
    let brown = file.distortion.as_ref().and_then(|d| d.brown).expect("Brown's model");
    assert_eq!(
        [brown.k1, brown.k2, brown.k3, brown.p1, brown.p2],
        ["0.03833474118270804865", "-0.01750917966495743258", "0.02049798716391852335", "0.00240851666319534747", "0.00292562392135245920"]
            .map(|v| v.parse::<f64>().unwrap())
    );
    // The P-matrix leaves the lens out.
    file.distortion = None;
    file.crs = "EPSG:32654".into();
    let cam = file.build(&ccp).unwrap();
    let p: Vec<f64> = std::fs::read_to_string(dir.join("maize_pmatrix.txt")).unwrap().split_whitespace().skip(1).map(|v| v.parse().unwrap()).collect();
    let offset = [368009.0, 3955854.0, 97.0];
    let mut seen = 0;
    for local in [[0.0, 0.0, 0.0], [25.0, -35.0, 1.0], [15.0, -20.0, -0.5], [30.0, -25.0, 0.3]] {
        let x = [local[0], local[1], local[2], 1.0];
        let m: Vec<f64> = (0..3).map(|i| (0..4).map(|j| p[4 * i + j] * x[j]).sum()).collect();
        let (want_c, want_r) = (m[0] / m[2], m[1] / m[2]);
        let (c, r) = cam.model().project(local[0] + offset[0], local[1] + offset[1], local[2] + offset[2]).expect("imaged");
        assert!((c - want_c).abs() < 0.02 && (r - want_r).abs() < 0.02, "{local:?}: ({c}, {r}) vs the P-matrix's ({want_c}, {want_r})");
        seen += usize::from((0.0..4608.0).contains(&c) && (0.0..3456.0).contains(&r));
    }
    assert!(seen >= 3, "the points lie in the frame");
    // The .cam (mm) on an image 4608 × 3456 px: the same lens.
    let tmp = tempfile::tempdir().unwrap();
    let image = tmp.path().join("DJI_0954.tif");
    write_blank_tiff(&image, 4608, 3456);
    let cam_file = formats::read(&dir.join("maize_pix4d_calibrated_internal_camera_parameters.cam"), None, Some(&image)).unwrap();
    let (mm, px) = (&cam_file.lenses[0].1, &set.lenses[0].1);
    for (a, b) in [(mm.focal_px[0], px.focal_px[0]), (mm.principal_point_px[0], px.principal_point_px[0]), (mm.principal_point_px[1], px.principal_point_px[1])]
    {
        assert!((a - b).abs() < 1e-6, "{a} vs {b}");
    }
    assert_eq!(mm.distortion, px.distortion);
    // Without the image its pixels are unknown: refused by name.
    let e = formats::read(&dir.join("maize_pix4d_calibrated_internal_camera_parameters.cam"), None, None).unwrap_err().to_string();
    assert!(e.contains("maize_pix4d_calibrated_internal_camera_parameters.cam") && e.contains("mm"), "{e}");
}

/// The two Pix4D files of one real image (a Nikon frame): the calibrated
/// camera parameters' R (world → OpenCV camera) and the external
/// parameters' ω, φ, κ (Pix4D's convention, read as any exterior CSV) are
/// one rotation, to the digits the external file prints; the calibrated
/// file used as the lens with the external file as the poses needs no
/// offset; a calibrated file without its offset is refused by name.
#[test]
fn pix4d_calibrated_and_external_parameters_agree() {
    let dir = fixture("pix4d");
    let ccp = dir.join("nikon_calibrated_camera_parameters.txt");
    let ext = dir.join("nikon_calibrated_external_camera_parameters.txt");
    let image = Path::new("DSC_0157.JPG");
    let alone = formats::read(&ccp, None, None).unwrap().camera_for(image).unwrap();
    let with_ext = formats::read(&ccp, Some(&ext), None).unwrap().camera_for(image).unwrap();
    let (a, b) = (alone.exterior.unwrap(), with_ext.exterior.unwrap());
    let ra = a.convention.matrix(a.angles_deg.map(f64::to_radians));
    let rb = b.convention.matrix(b.angles_deg.map(f64::to_radians));
    // ω, φ, κ printed to 1e-6°: 2e-8 rad.
    assert!((ra - rb).abs().max() < 5e-8, "{ra} vs {rb}");
    for i in 0..3 {
        assert!((a.position[i] - b.position[i]).abs() < 1e-6, "{:?} vs {:?}", a.position, b.position);
    }
    assert_eq!(alone.interior, with_ext.interior);
    // The same calibrated file away from its offset.
    let tmp = tempfile::tempdir().unwrap();
    let lone = tmp.path().join("p_calibrated_camera_parameters.txt");
    std::fs::copy(&ccp, &lone).unwrap();
    let e = formats::read(&lone, None, None).unwrap_err().to_string();
    assert!(e.contains("p_calibrated_camera_parameters.txt") && e.contains("offset.xyz") && e.contains("with exterior "), "{e}");
    assert!(formats::read(&lone, Some(&ext), None).is_ok());
}

/// A grey 8-bit TIFF of `w`×`h` zeros, deflated (small on disk).
fn write_blank_tiff(path: &Path, w: u32, h: u32) {
    let f = std::fs::File::create(path).unwrap();
    let mut enc = tiff::encoder::TiffEncoder::new(f).unwrap().with_compression(tiff::encoder::Compression::Deflate(tiff::encoder::DeflateLevel::Fast));
    enc.write_image::<tiff::encoder::colortype::Gray8>(w, h, &vec![0u8; (w * h) as usize]).unwrap();
}

/// The tags as GDAL writes them: its JPEG driver ends the EXIF directories
/// with a next-directory pointer that is not zero (a strict reader gives up
/// on the whole block), and `gdal_translate` to a TIFF keeps a JPEG's EXIF
/// as `EXIF_*` items of its own metadata (tag 42112). Both are read as the
/// tags they hold; and a camera is made from them with DJI's attitude in
/// the TIFF's XMP.
#[test]
fn exif_tags_as_gdal_writes_them_are_read() {
    let Some(py) = common::python_with("osgeo.gdal", "python3-gdal") else { return };
    let dir = tempfile::tempdir().unwrap();
    let script = r#"
import sys
import numpy as np
from osgeo import gdal
d = sys.argv[1]
ds = gdal.GetDriverByName('MEM').Create('', 120, 90, 3)
for b in range(3):
    ds.GetRasterBand(b + 1).WriteArray((np.arange(120 * 90).reshape(90, 120) % 251).astype('uint8'))
ds.SetMetadata({'EXIF_Make': 'DJI', 'EXIF_Model': 'FC6310', 'EXIF_FocalLength': '(8.8)', 'EXIF_FocalLengthIn35mmFilm': '24',
                'EXIF_GPSLatitude': '(45) (30) (36)', 'EXIF_GPSLatitudeRef': 'N', 'EXIF_GPSLongitude': '(5) (15) (0)',
                'EXIF_GPSLongitudeRef': 'W', 'EXIF_GPSAltitude': '(512.5)', 'EXIF_GPSAltitudeRef': '0x00'})
xmp = ('<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">'
       '<rdf:Description xmlns:drone-dji="http://www.dji.com/drone-dji/1.0/" drone-dji:GimbalYawDegree="30.0" '
       'drone-dji:GimbalPitchDegree="-90.0" drone-dji:GimbalRollDegree="0.0"/></rdf:RDF></x:xmpmeta>')
ds.SetMetadata([xmp], 'xml:XMP')
gdal.GetDriverByName('JPEG').CreateCopy(d + '/gdal.jpg', ds)
gdal.GetDriverByName('GTiff').CreateCopy(d + '/gdal.tif', ds)
"#;
    let out = std::process::Command::new(py).args(["-c", script, common::s(dir.path())]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for name in ["gdal.jpg", "gdal.tif"] {
        let tags = formats::exif::Tags::read(&dir.path().join(name)).unwrap();
        assert_eq!((tags.make.as_deref(), tags.model.as_deref()), (Some("DJI"), Some("FC6310")), "{name}");
        // (8.8 is a rational of GDAL's choosing in the JPEG.)
        assert!(tags.focal_mm.is_some_and(|f| (f - 8.8).abs() < 1e-6) && tags.focal_35mm == Some(24.0), "{name}: {:?} {:?}", tags.focal_mm, tags.focal_35mm);
        let [lat, lon, alt] = tags.gps.unwrap_or_else(|| panic!("{name}: no position"));
        assert!((lat - 45.51).abs() < 1e-12 && (lon + 5.25).abs() < 1e-12 && (alt - 512.5).abs() < 1e-3, "{name}: {:?}", tags.gps);
        assert!(tags.unreadable.is_none(), "{name}: {:?}", tags.unreadable);
    }
    // The TIFF keeps the XMP (tag 700): a whole camera, nadir, at the tags' place.
    let set = formats::read_for(&dir.path().join("gdal.tif"), Path::new("exif"), None, None).unwrap();
    let pose = &set.poses[0];
    assert!((pose.position[2] - 512.5).abs() < 1e-3, "{:?}", pose.position);
    let f = set.lenses[0].1.focal_px[0];
    assert!((f - 24.0 * 150.0 / 36f64.hypot(24.0)).abs() < 1e-9, "{f}");
}

/// Files of another tool's form that lack a field are read as that form
/// and say which field; text of no form read here says so, not a TOML
/// error alone.
#[test]
fn incomplete_files_name_what_they_lack() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let no_size = write("i.yaml", "cam1:\n  type: brown\n  focal_len: 2.08\n  cx: 0\n  cy: 0\n");
    let e = formats::read(&no_size, None, None).unwrap_err().to_string();
    assert!(e.contains("i.yaml") && e.contains("cam1.im_size"), "{e}");
    let no_z = write("e.csv", "filename,x,y,omega,phi,kappa\nimg1,500000,4100000,0,0,0\n");
    let e = formats::read(&fixture("orthority/int_param.yaml"), Some(&no_z), None).unwrap_err().to_string();
    assert!(e.contains("e.csv") && e.contains("x, y, z"), "{e}");
    let junk = write("junk.yaml", "hello: [\n");
    let e = formats::read(&junk, None, None).unwrap_err().to_string();
    // Named as YAML: YAML's complaint, where it is (not TOML's).
    assert!(e.contains("junk.yaml") && e.contains("not a camera file of a form read here") && e.contains("as YAML") && e.contains("line 2"), "{e}");
    assert!(!e.contains("TOML,"), "{e}");
}

/// Numbers in another unit than the form's are read as the form says, and
/// warned of: a focal length in mm where Orthority wants a fraction of the
/// image (a lens seeing a tenth of a degree), angles in degrees where
/// Orthority's GeoJSON and OpenSfM want radians, a CSV angle past a turn.
#[test]
fn numbers_in_the_wrong_unit_are_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let said = |set: &formats::Imported, words: &[&str]| set.warnings.iter().any(|w| words.iter().all(|x| w.contains(x)));
    let mm = write("mm.yaml", "cam1:\n  type: pinhole\n  im_size: [1000, 800]\n  focal_len: 100.0\n");
    let set = formats::read(&mm, None, None).unwrap();
    assert!(said(&set, &["mm.yaml", "cam1", "wrong unit"]), "{:?}", set.warnings);
    // The fixtures themselves draw no such warning.
    let set = formats::read(&fixture("orthority/int_param.yaml"), Some(&fixture("orthority/ext_param.geojson")), None).unwrap();
    assert!(!said(&set, &["wrong unit"]) && !said(&set, &["degrees?"]), "{:?}", set.warnings);

    let geojson = std::fs::read_to_string(fixture("orthority/ext_param.geojson")).unwrap();
    let degrees = write("deg.geojson", &geojson.replace("0.5235987755982988", "30.0"));
    let set = formats::read(&fixture("orthority/int_param.yaml"), Some(&degrees), None).unwrap();
    assert!(said(&set, &["deg.geojson", "opk", "2π", "degrees?"]), "{:?}", set.warnings);

    let turn = write("turn.csv", "filename,x,y,z,omega,phi,kappa\nimg1,500000,4100000,600,0,0,400\n");
    std::fs::copy(fixture("orthority/ext_param.prj"), dir.path().join("turn.prj")).unwrap();
    let set = formats::read(&fixture("orthority/int_param.yaml"), Some(&turn), None).unwrap();
    assert!(said(&set, &["turn.csv", "line 2", "past 360°"]), "{:?}", set.warnings);

    let recon = std::fs::read_to_string(fixture("opensfm/reconstruction.json")).unwrap();
    let set = formats::read(&fixture("opensfm/reconstruction.json"), None, None).unwrap();
    assert!(!said(&set, &["degrees?"]), "{:?}", set.warnings);
    let (from, to) = ("     3.1,\n     0.05,\n     -0.02", "     177.6,\n     2.9,\n     -1.1");
    assert!(recon.contains(from));
    let turned = write("reconstruction.json", &recon.replacen(from, to, 1));
    let set = formats::read(&turned, None, None).unwrap();
    assert!(said(&set, &["reconstruction.json", "img_o.jpg", "rotation", "degrees?"]), "{:?}", set.warnings);
}

/// `cameras --quiet` prints neither the table nor the files written, as
/// every command takes --quiet; its warnings still show.
#[test]
fn cameras_quiet_keeps_only_the_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let mm = dir.path().join("mm.yaml");
    std::fs::write(&mm, "cam1:\n  type: pinhole\n  im_size: [1000, 800]\n  focal_len: 100.0\n").unwrap();
    let csv = dir.path().join("e.csv");
    std::fs::write(&csv, "filename,x,y,z,omega,phi,kappa\nimg1.tif,500000,4100000,600,0,0,0\n").unwrap();
    std::fs::write(dir.path().join("e.prj"), "EPSG:32633").unwrap();
    let args = |quiet: bool| {
        let mut a = vec!["cameras", "--camera", common::s(&mm), "--exterior", common::s(&csv)];
        if quiet {
            a.push("--quiet");
        }
        common::run(&a)
    };
    let (loud, quiet) = (args(false), args(true));
    assert!(loud.status.success() && quiet.status.success(), "{}", String::from_utf8_lossy(&quiet.stderr));
    assert!(!loud.stdout.is_empty() && quiet.stdout.is_empty(), "{}", String::from_utf8_lossy(&quiet.stdout));
    assert!(String::from_utf8_lossy(&quiet.stderr).contains("wrong unit"), "{}", String::from_utf8_lossy(&quiet.stderr));
}

/// ODM's and Orthority's `odm_xyz_opk.csv` form: space-delimited, every
/// field in single quotes (the camera id holding spaces), `easting northing
/// altitude`, angles in radians. Read with `--radians` (as Orthority reads
/// it), the poses are those of the same poses in degrees in a plain CSV;
/// read without, the file is doubtful and said to be.
#[test]
fn odm_single_quoted_radians_csv_reads_with_radians() {
    let dir = tempfile::tempdir().unwrap();
    let poses = [
        ("im_a", [292710.25, 2731048.75, 186.5], [0.5032, 0.0164, 0.0311]),
        ("im_b", [292746.5, 2731093.5, 186.6], [-0.0476, -0.5250, -1.6359]),
        ("im_c", [292742.0, 2731079.0, 186.7], [-0.5248, 0.0328, 3.0715]),
    ];
    let mut odm = "'filename' 'easting' 'northing' 'altitude' 'omega' 'phi' 'kappa' 'camera'\n".to_string();
    let mut plain = "filename,x,y,z,omega,phi,kappa,camera\n".to_string();
    for (name, p, a) in poses {
        odm += &format!("'{name}' {} {} {} {} {} {} 'brown cam'\n", p[0], p[1], p[2], a[0], a[1], a[2]);
        let d = a.map(f64::to_degrees);
        plain += &format!("{name},{},{},{},{},{},{},brown cam\n", p[0], p[1], p[2], d[0], d[1], d[2]);
    }
    let (odm_path, plain_path) = (dir.path().join("odm_xyz_opk.csv"), dir.path().join("plain.csv"));
    for (path, text) in [(&odm_path, &odm), (&plain_path, &plain)] {
        std::fs::write(path, text).unwrap();
        std::fs::write(path.with_extension("prj"), "EPSG:32735").unwrap();
    }
    let int = fixture("orthority/int_param.yaml");
    let got = formats::read_with(&int, Some(&odm_path), None, formats::AngleUnit::Radians).unwrap();
    let want = formats::read(&int, Some(&plain_path), None).unwrap();
    assert_eq!(got.poses.len(), 3);
    for (g, w) in got.poses.iter().zip(&want.poses) {
        assert_eq!((&g.name, g.position, &g.camera), (&w.name, w.position, &w.camera));
        assert!((g.r - w.r).abs().max() < 1e-12, "{}: {} against {}", g.name, g.r, w.r);
    }
    // (The interior file's own warning about its portrait camera aside.)
    let about_angles = |w: &Vec<String>| w.iter().filter(|w| w.contains("‹radians›") || w.contains("past")).count();
    assert_eq!(about_angles(&got.warnings), 0, "{:?}", got.warnings);
    // Without --radians: read as degrees (as Orthority would), with a warning.
    let doubtful = formats::read(&int, Some(&odm_path), None).unwrap();
    assert!(doubtful.warnings.iter().any(|w| w.contains("odm_xyz_opk.csv") && w.contains("give ‹radians›")), "{:?}", doubtful.warnings);
    assert_eq!(about_angles(&want.warnings), 0, "degrees past π are not doubtful: {:?}", want.warnings);
}

/// simple-ortho's `config.yaml` (what NGI hands out beside its aerial
/// scans, which Orthority still reads): its one camera under `camera`,
/// the CRS of the positions under `ortho.crs`, the poses in a text file
/// without a header (`name x y z omega phi kappa`, degrees). The camera
/// and pose give Orthority's projections of the same lens; its other run
/// settings are named in a warning, not taken.
#[test]
fn a_simple_ortho_config_and_its_pose_file_project_as_orthority_does() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("config.yaml");
    std::fs::write(
        &config,
        "# Legacy simple-ortho configuration\ncamera:\n  name: brown cam\n  type: brown\n  im_size: [ 640, 480 ]\n  focal_len: 0.8333\n  cx: -0.01\n  cy: 0.02\n  k1: -0.25\n  k2: 0.2\n  p1: 0.01\n  p2: 0.01\n  k3: -0.1\n\northo:\n  crs: EPSG:32633\n  dem_interp: cubic\n  interp: cubic\n  resolution: [ 5., 5. ]\n  compress:\n",
    )
    .unwrap();
    let ori = dir.path().join("camera_pos_ori.txt");
    std::fs::write(&ori, "img_a 500100.0 4100200.0 700.0 2.5 -1.5 30.0\nimg_b 500000.0 4100000.0 600.0 0.0 0.0 0.0\n").unwrap();
    let cam = gcm_ortho::scene::camera::read_for(Path::new("img_a.tif"), &config, Some(&ori), Default::default(), None).unwrap_or_else(|e| panic!("{e}"));
    assert_projects(&cam, &BROWN, "simple-ortho");
    assert_eq!(cam.crs.epsg(), Some(32633));
    let set = formats::read(&config, Some(&ori), None).unwrap();
    let warned: Vec<&String> = set.warnings.iter().filter(|w| w.contains("simple-ortho's run settings")).collect();
    assert_eq!(warned.len(), 1, "{:?}", set.warnings);
    assert!(
        warned[0].contains("ortho.resolution") && warned[0].contains("ortho.interp") && !warned[0].contains("ortho.crs") && !warned[0].contains("compress"),
        "{}",
        warned[0]
    );
    // An empty `ortho.crs` (NGI's): the image's own CRS, as the file's
    // comment says simple-ortho took it; an image without one: refused
    // naming the CRS.
    let text = std::fs::read_to_string(&config).unwrap().replace("crs: EPSG:32633", "crs:");
    std::fs::write(&config, text).unwrap();
    let image = dir.path().join("img_a.tif");
    common::f32_raster(&image, (640, 480), (500000.0, 4100500.0, 1.0, 32633), |_, _| 0.0);
    let cam = gcm_ortho::scene::camera::read_for(&image, &config, Some(&ori), Default::default(), None).unwrap_or_else(|e| panic!("{e}"));
    assert_projects(&cam, &BROWN, "simple-ortho, the image's CRS");
    assert_eq!(cam.crs.epsg(), Some(32633));
    let bare = dir.path().join("img_b.tif");
    write_blank_tiff(&bare, 640, 480);
    let err = match gcm_ortho::scene::camera::read_for(&bare, &config, Some(&ori), Default::default(), None) {
        Ok(_) => panic!("an image without a CRS took one"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("crs") && err.contains("not given"), "{err}");
}
