//! Faults during a run: signals, a full disk. Nothing half-written is ever
//! left at the output path; an older file there stays as it was.

mod common;
use common::*;
use std::process::{Command, Stdio};
use std::time::Duration;

/// Starts a long rectify of `sc` into `out` and returns it 0.7 s in, still
/// running: a small GSD makes ≈ 100 Mpx of output.
fn long_run(sc: &gcm_ortho::synth::SynthReport, out: &std::path::Path) -> std::process::Child {
    let mut child = Command::new(bin())
        .args(["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(out), "--quiet", "--gsd", "0.25", "--threads", "1"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(700));
    assert!(child.try_wait().unwrap().is_none(), "the run ended too early");
    child
}

/// Sends `signal` (a number, as `kill -N` takes it) mid-run.
fn interrupt(signal: i32, expect: i32) {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 1000, |_| {});
    let out = dir.path().join("ortho.tif");
    std::fs::write(&out, b"an older orthophoto").unwrap();
    let child = long_run(&sc, &out);
    let sent = Command::new("kill").args([format!("-{signal}"), child.id().to_string()]).status().unwrap();
    assert!(sent.success());
    let status = wait_deadline(child, 10);
    assert_eq!(status.status.code(), Some(expect), "{}", String::from_utf8_lossy(&status.stderr));
    assert_eq!(std::fs::read(&out).unwrap(), b"an older orthophoto");
    assert!(files_containing(dir.path(), "partial").is_empty(), "temporary file left behind");
}

#[test]
fn sigterm_mid_run_removes_the_temporary_and_keeps_the_old_file() {
    interrupt(15, 143);
}

#[test]
fn sigint_mid_run_exits_130() {
    interrupt(2, 130);
}

/// SIGTERM while the run reads its inputs (4·10⁶ poses, two seconds of
/// parsing that polls no cancel flag): the command ends within a second,
/// its temporary output removed, an older file at the output kept.
#[test]
fn sigterm_while_parsing_ends_the_run_within_a_second() {
    use std::io::Write as _;
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 300, |_| {});
    let poses = dir.path().join("poses.csv");
    let mut w = std::io::BufWriter::new(std::fs::File::create(&poses).unwrap());
    writeln!(w, "filename,x,y,z,omega,phi,kappa").unwrap();
    for i in 0..4_000_000 {
        writeln!(w, "img{i:07}.tif,{},{},1500.5,0.1,0.2,{}", 640000 + i % 1000, 4800000 + i / 1000, i % 360).unwrap();
    }
    w.flush().unwrap();
    let image = dir.path().join("img3999999.tif");
    std::fs::copy(&sc.scan, &image).unwrap();
    let out = dir.path().join("ortho.tif");
    std::fs::write(&out, b"an older orthophoto").unwrap();
    let child = Command::new(bin())
        .args(["rectify", "--image", s(&image), "--camera", s(&sc.camera), "--exterior", s(&poses), "--height", "0", "-o", s(&out), "--quiet"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let sent = std::time::Instant::now();
    assert!(Command::new("kill").args(["-15", &child.id().to_string()]).status().unwrap().success());
    let o = wait_deadline(child, 10);
    let took = sent.elapsed();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(143), "{err}");
    assert_eq!(err.trim(), "gcm-ortho: interrupted; no unfinished output was left behind");
    // (A loaded machine wakes the watchdog late: a margin over the second.)
    assert!(took < Duration::from_millis(1500), "SIGTERM took {took:?}");
    assert_eq!(std::fs::read(&out).unwrap(), b"an older orthophoto");
    assert!(files_containing(dir.path(), "partial").is_empty(), "temporary file left behind");
}

/// A full disk: a 2 MiB tmpfs, where root may mount one (CI runs as root).
#[test]
fn full_disk_is_a_clear_error_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let mnt = dir.path().join("small");
    std::fs::create_dir(&mnt).unwrap();
    let ok = Command::new("mount").args(["-t", "tmpfs", "-o", "size=2m", "tmpfs", s(&mnt)]).status().map(|s| s.success()).unwrap_or(false);
    if !ok {
        eprintln!("skipped: cannot mount a small tmpfs here (needs root)");
        return;
    }
    let sc = scene(&dir.path().join("scene"), 600, |_| {});
    let out = mnt.join("ortho.tif");
    // With and without waiting for the disk, one thread and two: the error
    // comes from the writes either way.
    let mut results = Vec::new();
    for sync in [&[][..], &["--no-sync"][..]] {
        for threads in ["1", "2"] {
            let mut args = vec![
                "rectify",
                "--image",
                s(&sc.scan),
                "--camera",
                s(&sc.camera),
                "--dem",
                s(&sc.dem),
                "-o",
                s(&out),
                "--quiet",
                "--compress",
                "none",
                "--gsd",
                "2",
                "--threads",
                threads,
            ];
            args.extend(sync);
            let r = run(&args);
            results.push((r, files_containing(&mnt, "")));
        }
    }
    let _ = Command::new("umount").arg(&mnt).status();
    for (r, left) in results {
        let err = String::from_utf8_lossy(&r.stderr).to_string();
        assert_eq!(r.status.code(), Some(1), "{err}");
        assert!(err.to_lowercase().contains("no space left"), "{err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(left.is_empty(), "left behind: {left:?}");
    }
}

#[test]
fn without_sync_the_output_is_the_same_file() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 500, |_| {});
    let mut outs = Vec::new();
    for (name, extra) in [("synced.tif", &[][..]), ("unsynced.tif", &["--no-sync"][..])] {
        let out = dir.path().join(name);
        let mut args = vec!["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(&out), "--quiet"];
        args.extend(extra);
        let r = run(&args);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        outs.push(std::fs::read(&out).unwrap());
    }
    assert!(outs[0] == outs[1]);
    assert!(files_containing(dir.path(), "partial").is_empty());
}

/// Another process truncates the memory-mapped scan mid-run: a clear error,
/// not a bare SIGBUS, and nothing left behind.
#[test]
fn scan_truncated_underneath_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let sc = scene(&dir.path().join("scene"), 1000, |_| {});
    let out = dir.path().join("ortho.tif");
    let child = long_run(&sc, &out);
    std::fs::OpenOptions::new().write(true).open(&sc.scan).unwrap().set_len(4096).unwrap();
    let o = wait_deadline(child, 30);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("scan.tif") && err.contains("truncated"), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(!out.exists());
    assert!(files_containing(dir.path(), "partial").is_empty());
}
