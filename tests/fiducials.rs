//! Fiducial marks found without hand work: synthetic film scans of every
//! mark shape (positives and negatives, grain, dust, scratches, films
//! turned a few degrees, by quarter turns, mirrored; scanner scales that
//! differ by 0.08 %) against the marks' true places, which the generator
//! writes from its scanner's map; the interior orientation against the
//! true one at the frame's corners; refusals; the command's outputs; and a
//! rectification whose marks are found, against the one with the true marks.

mod common;

use common::{run, s};
use gcm_ortho::camera::file::CameraFile;
use gcm_ortho::camera::interior::InteriorOrientation;
use gcm_ortho::fiducials::camera::{detect_for, Overrides};
use gcm_ortho::fiducials::Detection;
use gcm_ortho::io::source::SourceImage;
use gcm_ortho::synth::film_marks::{marks_only, FilmMarks};
use gcm_ortho::synth::SynthOptions;
use std::path::{Path, PathBuf};

/// A marks-only film scan in `dir`: (scan, camera file without the marks'
/// places, the true places).
fn film(dir: &Path, size: u32, fiducials: u32, marks: FilmMarks) -> (PathBuf, PathBuf, Vec<[f64; 2]>) {
    film_of_bits(dir, size, fiducials, marks, 8)
}

/// [`film`] with samples of `bits`.
fn film_of_bits(dir: &Path, size: u32, fiducials: u32, marks: FilmMarks, bits: u32) -> (PathBuf, PathBuf, Vec<[f64; 2]>) {
    let mut o = SynthOptions::default();
    (o.out, o.width, o.height, o.bands, o.bits, o.fiducials, o.marks) = (dir.to_path_buf(), size, size, 1, bits, fiducials, marks);
    let (scan, camera) = marks_only(&o).expect("synth works");
    let mut file = CameraFile::read(&camera).unwrap();
    let truth = file.interior.as_mut().unwrap().fiducials_px.take().unwrap();
    let bare = dir.join("bare.toml");
    std::fs::write(&bare, file.to_toml()).unwrap();
    (scan, bare, truth)
}

fn detect(scan: &Path, camera: &Path, over: &Overrides) -> gcm_ortho::error::Result<Detection> {
    let file = CameraFile::read(camera).unwrap();
    detect_for(&file, camera, &SourceImage::open(scan, 1 << 20).unwrap(), over)
}

/// Every mark used lies within 0.25 px of its truth, and the interior
/// orientation within 0.3 px at the 23 cm frame's corners.
fn assert_found(name: &str, det: &Detection, truth: &[[f64; 2]], used: usize) {
    assert_found_within(name, det, truth, used, 0.3);
}

fn assert_found_within(name: &str, det: &Detection, truth: &[[f64; 2]], used: usize, corners_px: f64) {
    let mut worst: f64 = 0.0;
    for m in det.marks.iter().filter(|m| m.used) {
        let p = m.px.unwrap();
        let t = truth[m.mark - 1];
        worst = worst.max((p[0] - t[0]).hypot(p[1] - t[1]));
    }
    assert_eq!(det.marks.iter().filter(|m| m.used).count(), used, "{name}: marks used: {:#?}", det.marks);
    assert!(worst < 0.25, "{name}: a mark {worst:.3} px off its truth: {:#?}", det.marks);
    let all_mm: Vec<[f64; 2]> = det.marks.iter().map(|m| m.mm).collect();
    let truth_io = InteriorOrientation::from_fiducials(&all_mm, truth, [0.0, 0.0]).unwrap();
    let (mm, px) = det.used();
    let io = InteriorOrientation::from_fiducials(&mm, &px, [0.0, 0.0]).unwrap();
    for (x, y) in [(-115.0, -115.0), (115.0, 115.0), (-115.0, 115.0), (115.0, -115.0)] {
        let (a, b) = (io.mm_to_px(x, y), truth_io.mm_to_px(x, y));
        let off = (a.0 - b.0).hypot(a.1 - b.1);
        assert!(off < corners_px, "{name}: the interior orientation is {off:.3} px off at ({x}, {y})");
    }
}

fn marks(shape: &str) -> FilmMarks {
    FilmMarks { shape: shape.into(), ..Default::default() }
}

#[test]
fn every_shape_positive_and_negative_is_found_to_a_quarter_pixel() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, u32, u32, FilmMarks); 7] = [
        ("cross", 4000, 4, marks("cross")),
        ("cross, negative, 8 marks", 4000, 8, FilmMarks { negative: true, ..marks("cross") }),
        ("dot", 4000, 4, marks("dot")),
        ("zeiss-rmk (circle and dot), negative", 4000, 4, FilmMarks { negative: true, ..marks("zeiss-rmk") }),
        ("wild-rc (cross with a dot)", 4000, 4, marks("wild-rc")),
        ("fairchild (wings), 8 marks", 4000, 8, marks("fairchild")),
        ("afa (the thesis' dark corner with a light dot), negative", 6000, 4, FilmMarks { negative: true, ..marks("afa") }),
    ];
    for (k, (name, size, n, look)) in cases.into_iter().enumerate() {
        let negative = look.negative;
        let (scan, camera, truth) = film(&dir.path().join(k.to_string()), size, n, look);
        let det = detect(&scan, &camera, &Overrides::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_found(name, &det, &truth, n as usize);
        let want = if negative { gcm_ortho::fiducials::Polarity::Dark } else { gcm_ortho::fiducials::Polarity::Light };
        // The synthetic negative has dark marks on a light base.
        assert_eq!(det.polarity, want, "{name}");
        assert!(det.turn_ambiguous, "{name}: marks alike all round cannot tell a turn");
        // The scanner's scales: 60 µm across, 0.08 % longer down.
        let ratio = det.pixel_mm[1] / det.pixel_mm[0];
        assert!((ratio - 1.0008).abs() < 2e-4, "{name}: scale ratio {ratio}");
    }
}

/// 16-bit scans: a template of thousands of taps over tones near 65535
/// (a negative's base) sums past what f32 holds to the coefficient's
/// precision; such marks were not found (coefficients of 5.7 said).
#[test]
fn sixteen_bit_scans_positive_and_negative_are_found_as_eight_bit_ones() {
    let dir = tempfile::tempdir().unwrap();
    for (k, (name, look)) in
        [("cross, negative, 16-bit", FilmMarks { negative: true, ..marks("cross") }), ("dot, 16-bit", marks("dot"))].into_iter().enumerate()
    {
        let (scan, camera, truth) = film_of_bits(&dir.path().join(k.to_string()), 4000, 4, look, 16);
        let det = detect(&scan, &camera, &Overrides::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_found_within(name, &det, &truth, 4, 0.3);
        assert!(det.marks.iter().all(|m| m.score <= 1.0 + 1e-6), "{name}: {:#?}", det.marks);
    }
}

#[test]
fn films_turned_a_few_degrees_by_quarter_turns_or_mirrored_are_found_and_said() {
    use gcm_ortho::fiducials::Turn;
    let dir = tempfile::tempdir().unwrap();
    // Two marks unlike the others tell every turn and a mirror.
    let odd4 = "circle-dot,cross,dot,cross";
    let odd8 = "corner-dot,cross,cross,cross,dot,cross,cross,cross";
    let cases = [
        ("+3°", 4, FilmMarks { scan_turn_deg: 3.0, ..marks("cross") }, Turn::NONE),
        ("−3°, negative", 4, FilmMarks { scan_turn_deg: -3.0, negative: true, ..marks("zeiss-rmk") }, Turn::NONE),
        ("90°", 4, FilmMarks { quarters: 1, ..marks(odd4) }, Turn { quarters: 1, mirrored: false }),
        ("180°", 4, FilmMarks { quarters: 2, ..marks(odd4) }, Turn { quarters: 2, mirrored: false }),
        ("mirrored", 4, FilmMarks { mirrored: true, ..marks(odd4) }, Turn { quarters: 0, mirrored: true }),
        ("270°, mirrored, 8 marks", 8, FilmMarks { quarters: 3, mirrored: true, ..marks(odd8) }, Turn { quarters: 3, mirrored: true }),
    ];
    for (k, (name, n, look, turn)) in cases.into_iter().enumerate() {
        let small = look.scan_turn_deg;
        let (scan, camera, truth) = film(&dir.path().join(k.to_string()), 4000, n, look);
        let det = detect(&scan, &camera, &Overrides::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_found(name, &det, &truth, n as usize);
        assert_eq!(det.turn, turn, "{name}");
        assert!((det.rotation_deg + small).abs() < 0.02, "{name}: {}°", det.rotation_deg);
    }
    // A turned film whose marks look alike: refused, not guessed; told, it is found.
    let (scan, camera, truth) = film(&dir.path().join("alike"), 4000, 4, FilmMarks { quarters: 1, ..marks("circle-dot,cross,cross,cross") });
    let e = detect(&scan, &camera, &Overrides::default()).unwrap_err().to_string();
    assert!(e.contains("give turn"), "{e}");
    let told = Overrides { turn: Some(Turn { quarters: 1, mirrored: false }), ..Default::default() };
    assert_found("told", &detect(&scan, &camera, &told).unwrap(), &truth, 4);
}

#[test]
fn grain_dust_and_a_scratched_out_mark_give_a_right_fit_or_a_clear_refusal() {
    let dir = tempfile::tempdir().unwrap();
    // Grain and dust, some of it on the marks.
    let (scan, camera, truth) = film(&dir.path().join("dust"), 4000, 8, FilmMarks { grain: 0.12, dust: 60, ..marks("cross") });
    assert_found("dust", &detect(&scan, &camera, &Overrides::default()).unwrap(), &truth, 8);
    // One of eight scratched out: seven used, the eighth said.
    let (scan, camera, truth) = film(&dir.path().join("seven"), 4000, 8, FilmMarks { hidden_mark: 6, dust: 30, ..marks("cross") });
    let det = detect(&scan, &camera, &Overrides::default()).unwrap();
    assert_found("seven", &det, &truth, 7);
    assert!(!det.marks[5].used && det.warnings.iter().any(|w| w.contains("mark 6 not found")), "{:#?}", det);
    // One of four: three fit, without a check, said. The lost mark's
    // corner is extrapolated from the other three's errors (0.1–0.2 px).
    let (scan, camera, truth) = film(&dir.path().join("three"), 4000, 4, FilmMarks { hidden_mark: 2, ..marks("cross") });
    let det = detect(&scan, &camera, &Overrides::default()).unwrap();
    assert_found_within("three", &det, &truth, 3, 0.5);
    assert!(det.warnings.iter().any(|w| w.contains("no check")), "{:?}", det.warnings);
    // The wrong shape: nothing found, refused by name.
    let wrong = Overrides { shape: Some("corner-dot".into()), ..Default::default() };
    let (scan, camera, _) = film(&dir.path().join("wrong"), 4000, 4, marks("dot"));
    let e = detect(&scan, &camera, &wrong).unwrap_err().to_string();
    assert!(e.contains("scan.tif") && (e.contains("found") || e.contains("no fiducial marks")), "{e}");
    // A calibration wrong for one mark (3 mm off): that mark is not used,
    // and said, the other three giving the right orientation; or, the
    // layout no longer symmetric, a refusal naming the scan.
    let (scan, camera, truth) = film(&dir.path().join("miscalibrated"), 4000, 4, marks("cross"));
    let mut file = CameraFile::read(&camera).unwrap();
    let i = file.interior.as_mut().unwrap();
    i.fiducials_mm = Some(i.fiducials_mm.take().unwrap().into_iter().enumerate().map(|(k, [x, y])| if k == 0 { [x - 3.0, y] } else { [x, y] }).collect());
    let other = dir.path().join("other.toml");
    std::fs::write(&other, file.to_toml()).unwrap();
    match detect(&scan, &other, &Overrides::default()) {
        Ok(det) => {
            assert!(!det.marks[0].used && det.warnings.iter().any(|w| w.contains("mark 1")), "{det:#?}");
            assert_found_within("miscalibrated", &det, &truth, 3, 0.5);
        }
        Err(e) => assert!(e.to_string().contains("scan.tif"), "{e}"),
    }
    // A mark's coordinate mistyped (117.5 → 171.5): it is not used and
    // said, or the refusal points at the layout and that mark.
    let mut file = CameraFile::read(&camera).unwrap();
    let i = file.interior.as_mut().unwrap();
    let typo = i.fiducials_mm.as_ref().unwrap()[3];
    i.fiducials_mm.as_mut().unwrap()[3] = [typo[0] + 54.0 * typo[0].signum(), typo[1]];
    let typed = dir.path().join("typed.toml");
    std::fs::write(&typed, file.to_toml()).unwrap();
    match detect(&scan, &typed, &Overrides::default()) {
        Ok(det) => assert!(!det.marks[3].used && det.warnings.iter().any(|w| w.contains("mark 4")), "{det:#?}"),
        Err(e) => {
            let e = e.to_string();
            assert!(e.contains("scan.tif") && e.contains("fiducials_mm") && e.contains("4 at"), "{e}");
        }
    }
}

#[test]
fn the_command_writes_the_camera_file_a_sheet_and_json_and_never_over_its_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let (scan, camera, truth) = film(&dir.path().join("f"), 3000, 4, FilmMarks { shape: "cross-dot".into(), ..Default::default() });
    // The user's comments and layout are kept.
    let text = format!("# our RC-10, calibrated 1994\n{}", std::fs::read_to_string(&camera).unwrap());
    std::fs::write(&camera, &text).unwrap();
    let (out, sheet) = (dir.path().join("measured.toml"), dir.path().join("marks.png"));
    let r = run(&["fiducials", "--image", s(&scan), "--camera", s(&camera), "--write", s(&out), "--sheet", s(&sheet), "--json"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let report: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(report["marks"].as_array().unwrap().len(), 4);
    let written = std::fs::read_to_string(&out).unwrap();
    assert!(written.starts_with("# our RC-10, calibrated 1994\n"), "{written}");
    let measured = CameraFile::read(&out).unwrap();
    for (p, t) in measured.interior.as_ref().unwrap().fiducials_px.as_ref().unwrap().iter().zip(&truth) {
        assert!((p[0] - t[0]).hypot(p[1] - t[1]) < 0.25, "{p:?} vs {t:?}");
    }
    measured.build(&out).expect("the written camera file makes a camera");
    let png = png::Decoder::new(std::fs::File::open(&sheet).unwrap()).read_info().unwrap();
    assert_eq!((png.info().width, png.info().height), (4 * 160 + 5 * 6, 160 + 2 * 6));
    // Over its own inputs: refused, the camera file untouched.
    let r = run(&["fiducials", "--image", s(&scan), "--camera", s(&camera), "--write", s(&camera)]);
    assert_eq!(r.status.code(), Some(2), "{}", String::from_utf8_lossy(&r.stderr));
    assert_eq!(std::fs::read_to_string(&camera).unwrap(), text);
    // Absurd numbers: refused by the option's name, nothing written.
    for (flag, value) in [("--max-residual-px", "nan"), ("--scan-pixel-mm", "0"), ("--size-mm", "1e9"), ("--turn", "45"), ("--shape", "blob")] {
        let r = run(&["fiducials", "--image", s(&scan), "--camera", s(&camera), flag, value, "--write", s(&dir.path().join("no.toml"))]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.code() == Some(2) && err.contains(flag) && err.lines().count() == 1, "{flag} {value}: {err}");
        assert!(!dir.path().join("no.toml").exists());
    }
    // A shape it does not know: named, with the shapes it knows, and not
    // the camera file, which is not at fault.
    let r = run(&["fiducials", "--image", s(&scan), "--camera", s(&camera), "--shape", "star"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("--shape: unknown mark shape 'star'") && err.contains("cross-dot") && !err.contains("template"), "{err}");
    assert!(!err.contains(&*camera.to_string_lossy()), "{err}");
    // A folder that is not there: named as given, not as its temporary.
    let r = run(&["fiducials", "--image", s(&scan), "--camera", s(&camera), "--write", s(&dir.path().join("gone/m.toml"))]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.code() == Some(1) && err.contains("gone/m.toml") && !err.contains("partial") && err.lines().count() == 1, "{err}");
}

#[test]
fn a_film_rectified_without_measured_marks_finds_them_and_matches_the_true_marks() {
    let dir = tempfile::tempdir().unwrap();
    let rep = common::scene(&dir.path().join("scene"), 2400, |_| {});
    let mut file = CameraFile::read(&rep.camera).unwrap();
    file.interior.as_mut().unwrap().fiducials_px = None;
    let bare = dir.path().join("bare.toml");
    std::fs::write(&bare, file.to_toml()).unwrap();
    let (a, b) = (dir.path().join("true.tif"), dir.path().join("found.tif"));
    for (cam, out) in [(&rep.camera, &a), (&bare, &b)] {
        let r = run(&["rectify", "--image", s(&rep.scan), "--camera", s(cam), "--dem", s(&rep.dem), "-o", s(out), "--quiet"]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(r.status.success(), "{err}");
        // Four like marks cannot tell a film scanned turned: the run says
        // it took the scan as it lies (measured marks say nothing).
        assert_eq!(err.contains("look the same turned"), cam == &bare, "{err}");
    }
    let (pa, _) = common::whole_image(&a);
    let (pb, _) = common::whole_image(&b);
    assert_eq!(pa.len(), pb.len(), "the same grid");
    // Marks found within a fraction of a pixel move the image by as much:
    // tones differ little, on average by well under a grey level's few.
    let diff: f64 = pa.iter().zip(&pb).map(|(x, y)| (*x as f64 - *y as f64).abs()).sum::<f64>() / pa.len() as f64;
    assert!(diff < 1.5, "mean difference {diff:.2} grey levels");
    assert_ne!(pa, pb, "the marks were measured, not copied");
}

/// A mark the scan's edge cuts off (a small scan of a film turned a
/// quarter, its corner mark on the last column) is not found, and the
/// warning says where the other marks put it and that the edge cut it.
#[test]
fn a_mark_cut_off_by_the_scans_edge_is_said_to_be() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = common::run(&[
        "synth",
        "--out",
        common::s(d),
        "--camera",
        "film",
        "--size",
        "1600x1600",
        "--bands",
        "1",
        "--scan-quarters",
        "1",
        "--marks-only",
        "--quiet",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let camera = std::fs::read_to_string(d.join("camera.toml")).unwrap();
    let bare: String = camera.lines().filter(|l| !l.starts_with("fiducials_px")).map(|l| format!("{l}\n")).collect();
    std::fs::write(d.join("bare.toml"), bare).unwrap();
    let out = common::run(&["fiducials", "--image", common::s(&d.join("scan.tif")), "--camera", common::s(&d.join("bare.toml")), "--turn", "90"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.lines().any(|l| l.contains("mark 1 not found") && l.contains("scan's edge cuts it off")), "{err}");
}

/// Real side marks (a USGS EarthExplorer camera's notches, cut from a
/// scanned film; fixtures/fiducial_chips) pasted whole into a textured,
/// noisy scan at known places, one template a mark (its chip's middle 160
/// px): every mark is found within a tenth of a pixel of where its template's
/// centre was put, in the scan as it is, as a negative, and turned a
/// quarter (the turn found, not given).
#[test]
fn real_notch_marks_pasted_into_a_scan_are_found_where_they_were_put() {
    real_marks_pasted_into_a_scan_are_found("ee_notch", "tif", 110.0, 160);
}

/// Another style of real side marks (EarthExplorer's blocks, JPEG chips
/// as cut), as the notches are.
#[test]
fn real_block_marks_pasted_into_a_scan_are_found_where_they_were_put() {
    // (100 mm from the centre: the chips are 390 px across.)
    real_marks_pasted_into_a_scan_are_found("ee_block", "jpg", 100.0, 160);
}

/// NAGAP's curve marks: long thin chips (167 × 672 px), a step and a
/// curve off the template's centre — found 3.7 px off when turned a
/// quarter while the templates were drawn with a black frame and the
/// coarse level's turn.
#[test]
fn real_curve_marks_pasted_into_a_scan_are_found_where_they_were_put() {
    real_marks_pasted_into_a_scan_are_found("nagap_curve", "jpg", 100.0, 160);
}

/// NAGAP's block marks: a plain body whose edges lie far from the
/// template's centre (templates of 400 px; the middle 200 px are one
/// tone, which the second template must look past).
#[test]
fn real_nagap_block_marks_pasted_into_a_scan_are_found_where_they_were_put() {
    real_marks_pasted_into_a_scan_are_found("nagap_block", "jpg", 100.0, 400);
}

fn real_marks_pasted_into_a_scan_are_found(style: &str, ext: &str, reach_mm: f64, template_px: usize) {
    use gcm_ortho::camera::file::{MarkSetting, OneOrMany};
    use gcm_ortho::io::source::SampleType;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let chips = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/fiducial_chips").join(style);
    let (n, pixel_mm) = (4800usize, 0.05);
    let r = reach_mm;
    let sides = [("L", [-r, 0.0]), ("T", [0.0, r]), ("R", [r, 0.0]), ("B", [0.0, -r])];
    let px_of = |mm: [f64; 2]| [n as f64 / 2.0 + mm[0] / pixel_mm, n as f64 / 2.0 - mm[1] / pixel_mm];
    // Texture and grain: a deterministic mix of waves and noise.
    let mut seed = 7u64;
    let mut noise = move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((seed >> 33) % 17) as f64 - 8.0
    };
    let mut scan: Vec<u8> = (0..n * n).map(|i| (110.0 + 40.0 * ((i % n) as f64 * 0.013).sin() * ((i / n) as f64 * 0.021).cos()) as u8).collect();
    let mut templates = Vec::new();
    let mut truth = Vec::new();
    for (k, (side, mm)) in sides.iter().enumerate() {
        let (chip, info) = common::whole_image(&chips.join(format!("{side}.{ext}")));
        let (w, h) = (info.width as usize, info.height as usize);
        assert_eq!(info.bands, 1, "{style} {side}");
        let at = px_of(*mm);
        let (x0, y0) = (at[0] as usize - w / 2, at[1] as usize - h / 2);
        for y in 0..h {
            scan[(y0 + y) * n + x0..(y0 + y) * n + x0 + w].copy_from_slice(&chip[y * w..(y + 1) * w]);
        }
        // The template: the chip's middle square, `template_px` a side at
        // most.
        let t = template_px.min(w & !1).min(h & !1);
        let crop: Vec<u8> = (0..t).flat_map(|y| chip[(h / 2 - t / 2 + y) * w + w / 2 - t / 2..][..t].to_vec()).collect();
        let path = d.join(format!("template_{k}.tif"));
        gcm_ortho::io::tiff_out::write_raster(&path, &common::plain_spec((t as u32, t as u32), 1, SampleType::U8, None), |y0, y1, buf| {
            buf.copy_from_slice(&crop[y0 as usize * t..y1 as usize * t]);
        })
        .unwrap();
        templates.push(path.file_name().unwrap().to_str().unwrap().to_string());
        truth.push([(x0 + w / 2) as f64, (y0 + h / 2) as f64]);
    }
    for v in scan.iter_mut() {
        *v = (*v as f64 + noise()).clamp(0.0, 255.0) as u8;
    }
    // A camera file with the marks' calibrated places and their templates.
    let (_, base, _) = film(&d.join("base"), 400, 4, marks("cross"));
    let mut file = CameraFile::read(&base).unwrap();
    let interior = file.interior.as_mut().unwrap();
    interior.fiducials_mm = Some(sides.iter().map(|s| s.1).collect());
    interior.scan_pixel_mm = Some(pixel_mm);
    interior.fiducial_mark = Some(MarkSetting { template: Some(OneOrMany::Many(templates)), template_pixel_mm: Some(pixel_mm), ..Default::default() });
    let camera = d.join("camera.toml");
    std::fs::write(&camera, file.to_toml()).unwrap();
    let turned = |img: &[u8]| -> Vec<u8> { (0..n * n).map(|i| img[(i % n) * n + (n - 1 - i / n)]).collect() };
    // A case's name, its scan's pixels, where its marks were put.
    type Case = (&'static str, Vec<u8>, Vec<[f64; 2]>);
    let cases: [Case; 3] = [
        ("as cut", scan.clone(), truth.clone()),
        ("negative", scan.iter().map(|v| 255 - v).collect(), truth.clone()),
        // Turned a quarter: scan (x, y) shows the film's (n − 1 − y, x)
        // pixel; a point (x, y) moves to (y, n − x).
        ("turned a quarter", turned(&scan), truth.iter().map(|p| [p[1], n as f64 - p[0]]).collect()),
    ];
    for (name, pixels, want) in cases {
        let path = d.join("scan.tif");
        gcm_ortho::io::tiff_out::write_raster(&path, &common::plain_spec((n as u32, n as u32), 1, SampleType::U8, None), |y0, y1, buf| {
            buf.copy_from_slice(&pixels[y0 as usize * n..y1 as usize * n]);
        })
        .unwrap();
        let det = detect(&path, &camera, &Overrides::default()).unwrap_or_else(|e| panic!("{style} {name}: {e}"));
        assert_eq!(det.marks.len(), 4, "{style} {name}");
        for m in &det.marks {
            let p = m.px.unwrap_or_else(|| panic!("{style} {name}: mark {} not found: {:#?}", m.mark, det.marks));
            let t = want[m.mark - 1];
            let off = (p[0] - t[0]).hypot(p[1] - t[1]);
            eprintln!("{style} {name}: mark {} {off:.3} px", m.mark);
            assert!(m.used && off < 0.1, "{style} {name}: mark {} found {off:.3} px from where it was put ({p:?} against {t:?})", m.mark);
        }
    }
}
