//! Edited seamlines (GeoJSON as a GIS saves them) on arbitrary bytes,
//! read into the plan of a small block: rings of any size and shape,
//! CRSs named or not, images named or indexed.
#![no_main]
use gcm_ortho::mosaic::plan::{Plan, PlanSettings};
use gcm_ortho::synth::{block::synth_block, CameraKind, SynthOptions};
use libfuzzer_sys::fuzz_target;
use std::sync::{Mutex, OnceLock};

/// A 2×2 block of small drone frames and its plan, made once before the
/// inputs (its making is no input's time); each input is read into it.
fn plan() -> &'static Mutex<(Plan, Vec<u16>, tempfile::TempDir)> {
    static PLAN: OnceLock<Mutex<(Plan, Vec<u16>, tempfile::TempDir)>> = OnceLock::new();
    PLAN.get_or_init(|| {
        let dir = tempfile::tempdir().expect("a temporary folder");
        let mut o = SynthOptions::default();
        (o.out, o.camera, o.width, o.height) = (dir.path().to_path_buf(), CameraKind::Drone, 400, 300);
        let block = synth_block(&o, 2, 2, &gcm_ortho::NoProgress).expect("the block");
        let jobs = gcm_ortho::batch::manifest::load(&block.manifest).expect("its manifest");
        let settings = PlanSettings { gsd: None, grid: None, bounds: None, crs: None, memory: 64 << 20, cell: None, thumbnails: false };
        let plan = Plan::make(jobs.iter().map(|j| (j.name.clone(), j.config.clone())).collect(), &settings, &gcm_ortho::NoProgress).expect("the plan");
        let label = plan.label.clone();
        Mutex::new((plan, label, dir))
    })
}

fuzz_target!(init: { plan(); }, |data: &[u8]| {
    let mut held = plan().lock().unwrap_or_else(|e| e.into_inner());
    let (plan, label, dir) = &mut *held;
    let file = dir.path().join("edited.geojson");
    std::fs::write(&file, data).expect("the file written");
    let _ = gcm_ortho::mosaic::seamlines::read(plan, &file);
    plan.label.clone_from(label);
});
