//! The same inputs and options give the same outcome and the same bytes,
//! whatever the threads and their timing: an oblique drone frame over a
//! building DSM 20 times at 1, 2 and 8 threads, and a fisheye lens whose
//! terms fold it (k1 = 1e6, k2 = −1e6: once exit 0 in 2 runs of 30 and exit
//! 1 in the others) as often.

mod common;
use common::*;
use std::collections::BTreeMap;
use std::path::Path;

const RUNS: usize = 20;

/// Each run's outcome: its exit code, its stderr, and its output's bytes.
type Outcome = (Option<i32>, String, Option<Vec<u8>>);

/// `rectify` of `sc` with `camera`, RUNS times at each of 1, 2 and 8
/// threads; the distinct outcomes and how often each came.
fn outcomes(sc: &gcm_ortho::synth::SynthReport, camera: &Path, dir: &Path) -> BTreeMap<String, usize> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut first: Option<Outcome> = None;
    for threads in ["1", "2", "8"] {
        for k in 0..RUNS {
            let out = dir.join(format!("o{threads}_{k}.tif"));
            let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(camera), "--dem", s(&sc.dem), "--threads", threads, "--quiet", "-o", s(&out)]);
            // (Messages that name the output name it as OUT; 8 threads on
            // fewer cores are said to be fewer.)
            let said: String = String::from_utf8_lossy(&r.stderr)
                .replace(s(&out), "OUT")
                .lines()
                .filter(|l| !l.contains("is more than the"))
                .map(|l| format!("{l}\n"))
                .collect();
            let outcome: Outcome = (r.status.code(), said, std::fs::read(&out).ok());
            let _ = std::fs::remove_file(&out);
            let key = match &first {
                Some(f) if *f == outcome => "as the first run".to_string(),
                _ => format!("exit {:?} at {threads} threads: {} ({} bytes)", outcome.0, outcome.1.trim(), outcome.2.as_ref().map_or(0, Vec::len)),
            };
            first.get_or_insert(outcome);
            *seen.entry(key).or_default() += 1;
        }
    }
    seen
}

#[test]
fn an_oblique_frame_over_buildings_is_the_same_bytes_at_any_threads() {
    let dir = tempfile::tempdir().unwrap();
    let sc = drone_scene(dir.path(), (480, 360), 12_000.0);
    let seen = outcomes(&sc, &sc.camera, dir.path());
    // One outcome (the first run's, counted under its own key) every time.
    assert_eq!(seen.len(), 2, "{seen:#?}");
    assert_eq!(seen.get("as the first run"), Some(&(3 * RUNS - 1)), "{seen:#?}");
    assert!(seen.keys().any(|k| k.starts_with("exit Some(0)")), "{seen:#?}");
}

#[test]
fn a_folding_fisheye_has_one_answer_at_any_threads() {
    let dir = tempfile::tempdir().unwrap();
    let sc = drone_scene(dir.path(), (480, 360), 12_000.0);
    let text = std::fs::read_to_string(&sc.camera).unwrap();
    let start = text.find("[distortion.").expect("a distortion table");
    let end = text[start..].find("\n\n").map_or(text.len(), |k| start + k);
    let fisheye = format!("{}[distortion.fisheye]\nk1 = 1e6\nk2 = -1e6\nk3 = 0.0\nk4 = 0.0{}", &text[..start], &text[end..]);
    let camera = dir.path().join("fisheye.toml");
    std::fs::write(&camera, fisheye).unwrap();
    let seen = outcomes(&sc, &camera, dir.path());
    assert_eq!(seen.len(), 2, "{seen:#?}");
    assert_eq!(seen.get("as the first run"), Some(&(3 * RUNS - 1)), "{seen:#?}");
    // The answer: such terms are no lens's, said by name.
    assert!(seen.keys().any(|k| k.starts_with("exit Some(1)") && k.contains("fisheye.toml: distortion: ")), "{seen:#?}");
}

/// The same bytes whatever kernels the processor runs: an RGB drone frame
/// (the kernels' three bands) with each kernel set `GCM_ORTHO_KERNELS`
/// asks for, each capped at what this processor has and named in the
/// report; a name it does not know is warned of and left aside.
#[test]
fn every_kernel_set_gives_the_same_bytes() {
    use gcm_ortho::processor::{best, Kernels};
    let dir = tempfile::tempdir().unwrap();
    let sc = drone_scene(dir.path(), (640, 480), 12_000.0);
    let rectify = |asked: &str| {
        let (out, json) = (dir.path().join(format!("o_{asked}.tif")), dir.path().join(format!("o_{asked}.json")));
        let r = std::process::Command::new(bin())
            .env("GCM_ORTHO_KERNELS", asked)
            .args(["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "--quiet", "-o", s(&out), "--json", s(&json)])
            .output()
            .unwrap();
        assert!(r.status.success(), "{asked}: {}", String::from_utf8_lossy(&r.stderr));
        let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        (std::fs::read(&out).unwrap(), report, String::from_utf8_lossy(&r.stderr).to_string())
    };
    let (want, _, _) = rectify("portable");
    for (asked, kernels) in [("portable", Kernels::Portable), ("ssse3", Kernels::Ssse3), ("avx2", Kernels::Avx2)] {
        let (bytes, report, _) = rectify(asked);
        assert_eq!(report["kernels"], kernels.min(best()).name(), "{asked}");
        assert!(bytes == want, "{asked}: the output differs from the portable kernels'");
    }
    let (bytes, report, said) = rectify("sse9");
    assert_eq!(report["kernels"], best().name());
    assert!(said.contains("GCM_ORTHO_KERNELS=\"sse9\"") && said.contains("left aside"), "{said}");
    assert!(bytes == want);
}
