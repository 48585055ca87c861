//! A synthetic drone frame whose camera we know, written by `cameras` in
//! each form (ours, Orthority's, OpenSfM's) and read back: the camera
//! images every point where our own file's does, and the orthophoto of a
//! coordinate image is the same.

mod common;

use common::{coordinate_image, coordinate_map_difference, run, s, scene};
use gcm_ortho::camera::file::Camera;
use std::path::{Path, PathBuf};

const W: u32 = 600;
const H: u32 = 400;

/// The oblique drone frame (Brown distortion, 25° off nadir) over buildings.
fn drone(dir: &Path) -> gcm_ortho::synth::SynthReport {
    common::drone_scene(dir, (W, H), 12_000.0)
}

/// `cameras --to target` of the scene's camera for `image` into `out`; the
/// arguments that give rectify the written camera.
fn convert(camera: &Path, image: &Path, out: &Path, target: &str) -> Vec<String> {
    std::fs::create_dir_all(out).unwrap();
    let r = run(&["cameras", "--camera", s(camera), s(image), "--out-dir", s(out), "--to", target]);
    assert!(r.status.success(), "{target}: {}", String::from_utf8_lossy(&r.stderr));
    let table = String::from_utf8_lossy(&r.stdout);
    let name = image.file_name().unwrap().to_string_lossy();
    let info = gcm_ortho::io::source::SourceImage::open(image, 1 << 20).unwrap().info;
    assert!(table.contains(&*name) && table.contains(&format!("{}x{}", info.width, info.height)) && table.contains("brown"), "{table}");
    let p = |n: &str| out.join(n).to_string_lossy().into_owned();
    match target {
        "toml" => vec!["--camera".into(), p("scan.toml")],
        "orthority" => vec!["--camera".into(), p("int_param.yaml"), "--exterior".into(), p("ext_param.csv")],
        _ => vec!["--camera".into(), p("reconstruction.json")],
    }
}

fn camera_of(image: &Path, args: &[String]) -> Camera {
    let exterior = args.get(3).map(PathBuf::from);
    gcm_ortho::scene::camera::read_for(image, Path::new(&args[1]), exterior.as_deref(), Default::default(), None).unwrap_or_else(|e| panic!("{args:?}: {e}"))
}

#[test]
fn every_written_form_reads_back_as_the_same_camera() {
    let dir = tempfile::tempdir().unwrap();
    let sc = drone(dir.path());
    let truth = Camera::read(&sc.camera).unwrap();
    let image = sc.scan.clone();
    for target in ["toml", "orthority", "opensfm"] {
        let args = convert(&sc.camera, &image, &dir.path().join(target), target);
        let cam = camera_of(&image, &args);
        // Points over the whole frame, from the ground to roof height.
        let mut worst = 0f64;
        for j in 0..=8 {
            for i in 0..=12 {
                let (c, r) = (i as f64 * W as f64 / 12.0, j as f64 * H as f64 / 8.0);
                let z = 150.0 + 10.0 * ((i + j) % 4) as f64;
                let (x, y) = gcm_ortho::camera::locate(truth.model(), c, r, z, 1e-9).expect("the frame sees the ground");
                let (x2, y2) = if cam.crs == truth.crs { (x, y) } else { panic!("{target}: read back in {:?}, not {:?}", cam.crs, truth.crs) };
                let (c2, r2) = cam.model().project(x2, y2, z).expect("imaged");
                worst = worst.max((c2 - c).hypot(r2 - r));
            }
        }
        assert!(worst < 1e-6, "{target}: {worst} px from our own camera");
    }
}

#[test]
fn the_orthophoto_from_each_written_form_is_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let sc = drone(dir.path());
    // The coordinate image in the scan's place, under the scan's name.
    let coords = dir.path().join("coords").join("scan.tif");
    std::fs::create_dir_all(coords.parent().unwrap()).unwrap();
    coordinate_image(&coords, W, H);
    // The exact model at every pixel: no refinement decision to differ.
    let exact = ["--sparsity", "1", "--corrections", "cell", "--memory", "1G", "--nodata", "-1", "--compress", "none", "--quiet"];
    let rectify = |camera_args: &[String], out: &Path, like: Option<&Path>| {
        let mut a: Vec<String> = ["rectify", "--image", s(&coords), "--dem", s(&sc.dem)].iter().map(|x| x.to_string()).collect();
        a.extend(camera_args.iter().cloned());
        a.extend(exact.iter().map(|x| x.to_string()));
        if let Some(l) = like {
            a.extend(["--like".to_string(), s(l).to_string()]);
        }
        a.extend(["-o".to_string(), s(out).to_string()]);
        let refs: Vec<&str> = a.iter().map(String::as_str).collect();
        let r = run(&refs);
        assert!(r.status.success(), "{a:?}: {}", String::from_utf8_lossy(&r.stderr));
    };
    let reference = dir.path().join("ours.tif");
    rectify(&["--camera".to_string(), s(&sc.camera).to_string()], &reference, None);
    for target in ["toml", "orthority", "opensfm"] {
        let args = convert(&sc.camera, &coords, &dir.path().join(target), target);
        let out = dir.path().join(format!("{target}.tif"));
        rectify(&args, &out, Some(&reference));
        let d = coordinate_map_difference(&reference, &out, W, H);
        assert!(d.pixels > 50_000, "{target}: {} pixels compared", d.pixels);
        // Float32 positions below 1000 are good to 6e-5 px.
        assert!(d.max < 2e-4, "{target}: max {} px, offset {:?}", d.max, d.offset);
    }
}

#[test]
fn what_other_forms_cannot_hold_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("film"), 300, |_| {});
    for target in ["orthority", "opensfm"] {
        let out = dir.path().join(target);
        std::fs::create_dir_all(&out).unwrap();
        let r = run(&["cameras", "--camera", s(&sc.camera), s(&sc.scan), "--out-dir", s(&out), "--to", target]);
        let e = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && e.contains("interior") && e.contains("fiducial"), "{target}: {e}");
        assert_eq!(std::fs::read_dir(&out).unwrap().count(), 0, "{target}: nothing written");
    }
    // Refraction and the earth's curvature: neither form models them, so
    // they are refused by name, not dropped.
    let dr = drone(&dir.path().join("drone"));
    let text = std::fs::read_to_string(&dr.camera).unwrap();
    let (head, _) = text.split_once("[corrections]").expect("the synthetic camera has corrections");
    for (corrections, word) in [("refraction = \"auto\"\n", "refraction = \"auto\""), ("earth_curvature = true\n", "earth_curvature = true")] {
        let cam = dir.path().join("corrected.toml");
        std::fs::write(&cam, format!("{head}[corrections]\n{corrections}")).unwrap();
        for target in ["orthority", "opensfm"] {
            let out = dir.path().join(format!("c-{target}"));
            let r = run(&["cameras", "--camera", s(&cam), s(&dr.scan), "--out-dir", s(&out), "--to", target]);
            let e = String::from_utf8_lossy(&r.stderr);
            assert_eq!(r.status.code(), Some(1), "{target}: {e}");
            assert!(e.contains("[corrections]") && e.contains(word) && e.contains("corrected.toml"), "{target}: {e}");
            assert!(!out.exists() || std::fs::read_dir(&out).unwrap().count() == 0, "{target}: nothing written");
        }
    }
    // Never over an input: the camera file is scan.toml, where the
    // image's camera would be written.
    let own = sc.scan.with_extension("toml");
    std::fs::copy(&sc.camera, &own).unwrap();
    let before = std::fs::read(&own).unwrap();
    let r = run(&["cameras", "--camera", s(&own), s(&sc.scan), "--out-dir", s(own.parent().unwrap()), "--to", "toml"]);
    let e = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && e.contains("refusing to write over an input"), "{e}");
    assert_eq!(std::fs::read(&own).unwrap(), before);
    // A folder not there yet is made (as the README's example expects).
    let fresh = dir.path().join("cams/new");
    let r = run(&["cameras", "--camera", s(&sc.camera), s(&sc.scan), "--out-dir", s(&fresh), "--to", "toml"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(fresh.join("scan.toml").is_file());
}

#[test]
fn a_block_given_by_orthority_files_runs_in_batch() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = drone(d);
    std::fs::create_dir_all(d.join("scans")).unwrap();
    std::fs::copy(&sc.scan, d.join("scans/DJI_0001.tif")).unwrap();
    let oty = d.join("oty");
    convert(&sc.camera, &d.join("scans/DJI_0001.tif"), &oty, "orthority");
    // Names as exports write them: with the extension, a folder in front.
    let csv = std::fs::read_to_string(oty.join("ext_param.csv")).unwrap().replace("DJI_0001.tif,", "images/DJI_0001.tif,");
    std::fs::write(oty.join("ext_param.csv"), csv).unwrap();
    std::fs::write(
        d.join("manifest.toml"),
        "[defaults]\ndem = \"scene/dem.tif\"\noutput_dir = \"ortho\"\n\n[block]\ninterior = \"oty/int_param.yaml\"\nexterior = \"oty/ext_param.csv\"\nimages = \"scans/{name}.tif\"\n",
    )
    .unwrap();
    let o = run(&["batch", s(&d.join("manifest.toml")), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let single = d.join("single.tif");
    let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(&single), "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let a = gcm_ortho::study::compare::read_grey(&single, 0.0).unwrap();
    let b = gcm_ortho::study::compare::read_grey(&d.join("ortho/DJI_0001.tif"), 0.0).unwrap();
    assert_eq!(a.v.len(), b.v.len(), "one grid");
    let diff = a.v.iter().zip(&b.v).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
    assert!(diff <= 1.0, "the block's orthophoto differs by {diff}");
}

/// The drone scene's camera as a Metashape export would hold it: the
/// calibration in Metashape's terms, the camera in a chunk frame that a
/// similarity (`scale`, rotation, shift) carries to geocentric coordinates.
fn metashape_xml(truth: &gcm_ortho::camera::CameraFile, size: (u32, u32), reference: &str, label: &str) -> String {
    use gcm_ortho::camera::rotation::AngleConvention;
    use gcm_ortho::geodesy::ecef::{enu_axes, to_ecef};
    use gcm_ortho::geodesy::{Crs, GroundCrs};
    use nalgebra::{Matrix3, Vector3};
    let interior = truth.interior.clone().unwrap();
    let ps = interior.pixel_size_mm.unwrap().sides()[0];
    let f = truth.camera.focal_length_mm.unwrap() / ps;
    let pp = interior.principal_point_px.unwrap();
    let b = truth.distortion.clone().unwrap().brown.unwrap();
    let ext = truth.exterior.clone().unwrap();
    let ground = GroundCrs::new(&Crs::parse(&truth.crs, Path::new("")).unwrap()).unwrap();
    let (lon, lat) = ground.to_lonlat(ext.position[0], ext.position[1]).unwrap();
    let c = to_ecef(lon, lat, ext.position[2]);
    // Grid → geocentric directions: east-north-up turned by the grid's
    // convergence θ (true north is θ east of grid north).
    let (n1, n2) = (ground.lonlat_to_ground(lon, lat + 1e-5).unwrap(), ground.lonlat_to_ground(lon, lat - 1e-5).unwrap());
    let theta = (n1.0 - n2.0).atan2(n1.1 - n2.1);
    let q = Matrix3::new(theta.cos(), -theta.sin(), 0.0, theta.sin(), theta.cos(), 0.0, 0.0, 0.0, 1.0);
    let r_photo = ext.convention.matrix(ext.angles_deg.map(f64::to_radians));
    let r_cv_ecef = enu_axes(lon, lat) * q * r_photo * Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
    // The chunk's frame: scale 12.3, turned, 2 km off the camera.
    let (s0, r0, t0) = (12.3, AngleConvention::OmegaPhiKappa.matrix([0.3, -0.5, 1.1]), c + Vector3::new(1500.0, -900.0, 1200.0));
    let cam_r = r0.transpose() * r_cv_ecef;
    let cam_t = r0.transpose() * (c - t0) / s0;
    let row = |m: &Matrix3<f64>, t: &Vector3<f64>| {
        (0..3).map(|i| format!("{:?} {:?} {:?} {:?}", m[(i, 0)], m[(i, 1)], m[(i, 2)], t[i])).collect::<Vec<_>>().join(" ") + " 0 0 0 1"
    };
    let r9 = (0..3).flat_map(|i| (0..3).map(move |j| (i, j))).map(|(i, j)| format!("{:?}", r0[(i, j)])).collect::<Vec<_>>().join(" ");
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<document version="2.0.0">
  <chunk label="Chunk 1" enabled="true">
    <sensors next_id="1">
      <sensor id="0" label="drone" type="frame">
        <resolution width="{w}" height="{h}"/>
        <calibration type="frame" class="initial">
          <resolution width="{w}" height="{h}"/>
          <f>1000</f>
        </calibration>
        <calibration type="frame" class="adjusted">
          <resolution width="{w}" height="{h}"/>
          <f>{f:?}</f>
          <cx>{cx:?}</cx>
          <cy>{cy:?}</cy>
          <k1>{k1:?}</k1>
          <k2>{k2:?}</k2>
          <k3>{k3:?}</k3>
          <p1>{p1:?}</p1>
          <p2>{p2:?}</p2>
        </calibration>
      </sensor>
    </sensors>
    <components next_id="1" active_id="0">
      <component id="0" label="Component 1">
        <transform>
          <rotation locked="true">{r9}</rotation>
          <translation locked="true">{tx:?} {ty:?} {tz:?}</translation>
          <scale locked="true">{s0:?}</scale>
        </transform>
      </component>
    </components>
    <cameras next_id="2" next_group_id="1">
      <group id="0" label="Group 1" type="folder">
        <camera id="0" sensor_id="0" component_id="0" label="{label}">
          <transform>{cam}</transform>
        </camera>
        <camera id="1" sensor_id="0" component_id="0" label="not_aligned.JPG"/>
      </group>
    </cameras>
    <reference>{reference}</reference>
  </chunk>
</document>
"#,
        w = size.0,
        h = size.1,
        cx = pp[0] - size.0 as f64 / 2.0,
        cy = pp[1] - size.1 as f64 / 2.0,
        k1 = b.k1,
        k2 = b.k2,
        k3 = b.k3,
        // Metashape's P1 is OpenCV's p2.
        p1 = b.p2,
        p2 = b.p1,
        tx = t0.x,
        ty = t0.y,
        tz = t0.z,
        cam = row(&cam_r, &cam_t),
    )
}

const UTM31_WKT: &str = r#"PROJCS["WGS 84 / UTM zone 31N",GEOGCS["WGS 84",DATUM["World Geodetic System 1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",0],PARAMETER["central_meridian",3],PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",500000],PARAMETER["false_northing",0],UNIT["metre",1],AUTHORITY["EPSG","32631"]]"#;
const WGS84_WKT: &str = r#"GEOGCS["WGS 84",DATUM["World Geodetic System 1984",SPHEROID["WGS 84",6378137,298.257223563]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]]"#;

#[test]
fn a_metashape_export_reads_as_the_camera_it_describes() {
    let dir = tempfile::tempdir().unwrap();
    let sc = drone(dir.path());
    let truth_file = gcm_ortho::camera::CameraFile::read(&sc.camera).unwrap();
    let truth = Camera::read(&sc.camera).unwrap();
    for (reference, label) in [(UTM31_WKT, "scan"), (WGS84_WKT, "C:\\flights\\day1\\scan.tif")] {
        let xml = dir.path().join("cameras.xml");
        std::fs::write(&xml, metashape_xml(&truth_file, (W, H), reference, label)).unwrap();
        let set = gcm_ortho::camera::formats::read(&xml, None, None).unwrap();
        assert!(set.warnings.iter().any(|w| w.contains("1 of 2 cameras are not aligned")), "{:?}", set.warnings);
        let cam = gcm_ortho::scene::camera::read_for(&sc.scan, &xml, None, Default::default(), None).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(cam.crs.epsg(), Some(32631), "a geographic chunk goes to its UTM zone");
        let mut worst = 0f64;
        for j in 0..=8 {
            for i in 0..=12 {
                let (c, r) = (i as f64 * W as f64 / 12.0, j as f64 * H as f64 / 8.0);
                let z = 150.0 + 10.0 * ((i + j) % 4) as f64;
                let (x, y) = gcm_ortho::camera::locate(truth.model(), c, r, z, 1e-9).unwrap();
                let (c2, r2) = cam.model().project(x, y, z).unwrap();
                worst = worst.max((c2 - c).hypot(r2 - r));
            }
        }
        assert!(worst < 1e-4, "{label}: {worst} px from the camera the export describes");
    }
}

/// The export with its component's shift taken out: a frame that is not
/// geocentric (a local one under a geographic label).
fn without_translation(xml: &str) -> String {
    let start = xml.find("<translation locked=\"true\">").unwrap() + "<translation locked=\"true\">".len();
    let end = start + xml[start..].find("</translation>").unwrap();
    format!("{}0 0 0{}", &xml[..start], &xml[end..])
}

#[test]
fn metashape_exports_we_cannot_use_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let sc = drone(dir.path());
    let truth_file = gcm_ortho::camera::CameraFile::read(&sc.camera).unwrap();
    let good = metashape_xml(&truth_file, (W, H), UTM31_WKT, "scan");
    let cases = [
        ("fisheye", good.replace(r#"label="drone" type="frame""#, r#"label="drone" type="fisheye""#), "'fisheye' (only frame sensors)"),
        ("fx", good.replace("<f>1000</f>", "<fx>1000</fx>"), "PhotoScan's older form"),
        ("chunks", good.replace("</chunk>", "</chunk><chunk label=\"2\"></chunk>"), "2 chunks"),
        ("local", good.replace(UTM31_WKT, r#"LOCAL_CS["Local Coordinates (m)",LOCAL_DATUM["Local Datum",0],UNIT["metre",1]]"#), "local coordinate system"),
        ("origin", without_translation(&good), "not near the earth's surface"),
    ];
    for (name, text, want) in cases {
        let xml = dir.path().join(format!("{name}.xml"));
        std::fs::write(&xml, text).unwrap();
        let e = gcm_ortho::camera::formats::read(&xml, None, None).map(|_| ()).err().unwrap_or_else(|| panic!("{name}: read")).to_string();
        assert!(e.contains(&format!("{name}.xml")) && e.contains(want), "{name}: {e}");
    }
}

/// Lenses in pixel units (OpenSfM's, Orthority's without a sensor size:
/// pixel_size_mm = 1) over 1000 px across: their "mm" are pixels, not a
/// pixel size in the wrong unit, and the frame is rectified as our own
/// camera file has it.
#[test]
fn a_lens_in_pixel_units_on_a_large_frame_is_taken() {
    let dir = tempfile::tempdir().unwrap();
    let sc = common::drone_scene(dir.path(), (1200, 1000), 12_000.0);
    let rectify = |camera_args: &[String], out: &Path| {
        let mut a: Vec<String> = ["rectify", "--image", s(&sc.scan), "--dem", s(&sc.dem), "--quiet", "-o", s(out)].iter().map(|x| x.to_string()).collect();
        a.extend(camera_args.iter().cloned());
        let refs: Vec<&str> = a.iter().map(String::as_str).collect();
        let r = run(&refs);
        assert!(r.status.success(), "{a:?}: {}", String::from_utf8_lossy(&r.stderr));
        gcm_ortho::io::source::SourceImage::open(out, 1 << 20).unwrap().info
    };
    let ours = rectify(&["--camera".to_string(), s(&sc.camera).to_string()], &dir.path().join("ours.tif"));
    for target in ["opensfm", "orthority"] {
        let args = convert(&sc.camera, &sc.scan, &dir.path().join(target), target);
        let got = rectify(&args, &dir.path().join(format!("{target}.tif")));
        assert_eq!((got.width, got.height), (ours.width, ours.height), "{target}");
    }
}
