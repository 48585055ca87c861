//! `batch`: many scans from one manifest, as a nightly job. Jobs run one
//! after another or N at a time within one memory budget; a failing job
//! does not stop the others; a finished output is recorded with a key of its
//! inputs and parameters so that a rerun skips it (and redoes it when
//! anything changed); `--shard I/N` (or Slurm / Kubernetes array variables)
//! takes a deterministic share of the jobs.

pub mod lock;
pub mod manifest;
pub mod shard;

use crate::identity::{file_stamp, fnv};

use crate::options::{DemSource, RectifyOptions};
use crate::pipeline::rectify;
use crate::progress::{Cancel, HostOnly, Progress};
use manifest::Job;
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct BatchOptions {
    /// Jobs at a time.
    pub jobs: usize,
    /// Memory budget of the whole batch, bytes.
    pub memory: u64,
    pub force: bool,
    /// (index, count), 0-based.
    pub shard: (usize, usize),
    pub threads: usize,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    Done,
    Skipped,
    /// Being made by another run (it holds the job's lock): left to it.
    Busy,
    Failed,
    Cancelled,
}

/// One line of the report.
#[derive(Clone, Debug, Serialize)]
pub struct JobResult {
    pub job: String,
    pub status: Status,
    pub error: Option<String>,
    pub output: PathBuf,
    pub seconds: f64,
    pub input_mb_per_s: Option<f64>,
    pub peak_rss_mib: Option<f64>,
    pub gcm_rms_px: Option<f64>,
    pub gcm_max_px: Option<f64>,
    /// The bound the job was held to, and whether the sample stayed in it.
    pub error_bound: Option<f64>,
    pub error_within: Option<bool>,
    pub warnings: Vec<String>,
    /// What ground control points did to the model, where given.
    pub gcps: Option<crate::camera::gcp::GcpFit>,
    /// Under `occlusion`: the ground the image's sensor does not see.
    pub occlusion: Option<crate::pipeline::Hidden>,
}

/// The key of a job: its inputs (path, size, modification time), its camera
/// and every parameter that changes the output.
pub fn job_key(c: &RectifyOptions) -> String {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    file_stamp(&mut h, &c.inputs.image);
    match c.inputs.model.inline() {
        Some(f) => fnv(&mut h, f.to_toml().as_bytes()),
        None => fnv(&mut h, &crate::io::bounded_read::read_bounded(&c.inputs.camera, "a camera file", crate::io::bounded_read::SMALL).unwrap_or_default()),
    }
    if let DemSource::File(p) = &c.inputs.dem {
        file_stamp(&mut h, p);
    }
    // What else refines the model: a new GCP or pose file redoes the job.
    if let Some(g) = &c.inputs.gcps {
        file_stamp(&mut h, &g.file);
    }
    if let crate::options::ModelSource::WithPoses { poses, angles } = &c.inputs.model {
        file_stamp(&mut h, poses);
        // (Degrees hash as before: a rerun of an earlier run is current.)
        if *angles == crate::camera::formats::AngleUnit::Radians {
            fnv(&mut h, b"angles in radians");
        }
    }
    let mut params = c.clone();
    params.resources.threads = 0;
    params.resources.memory = 0;
    fnv(&mut h, serde_json::to_string(&params).unwrap_or_default().as_bytes());
    format!("{h:016x}")
}

/// The record of a finished output.
pub fn sidecar(output: &Path) -> PathBuf {
    let mut s = output.as_os_str().to_owned();
    s.push(".done");
    PathBuf::from(s)
}

/// What a record says of a finished output: the job's key, and the
/// output's size and modification time, so that an output damaged or
/// replaced since is made again.
fn record(output: &Path, key: &str) -> Option<String> {
    let m = std::fs::metadata(output).ok()?;
    let t = m.modified().ok()?.duration_since(std::time::UNIX_EPOCH).ok()?;
    Some(format!("{key} {} {}", m.len(), t.as_nanos()))
}

fn is_current(c: &RectifyOptions, key: &str) -> bool {
    output_is_current(&c.file.path, key)
}

/// Whether `output` is whole and was made for `key` (its record says so).
pub fn output_is_current(output: &Path, key: &str) -> bool {
    let recorded = crate::io::bounded_read::read_text_bounded(&sidecar(output), "a record", 4096);
    matches!((recorded, record(output, key)), (Ok(r), Some(now)) if r.trim() == now)
}

/// Records that `output` is finished for `key` (beside it, `.done`).
pub fn write_sidecar(output: &Path, key: &str) -> crate::Result<()> {
    let r = record(output, key).ok_or_else(|| crate::Error::format(output, "the finished output cannot be read back"))?;
    crate::io::publish::write_file(&sidecar(output), format!("{r}\n").as_bytes())
}

/// How many of `jobs` can run at once within `memory`, each with the least
/// budget a run can keep to.
pub fn jobs_within(memory: u64, jobs: usize) -> usize {
    jobs.clamp(1, (memory / RectifyOptions::MIN_MEMORY).max(1) as usize)
}

/// Runs the share of `jobs` chosen by the shard; results in job order.
/// `host` answers for the process (its peak memory in the records).
pub fn run_jobs(jobs: &[Job], o: &BatchOptions, host: &dyn Progress, cancel: &Cancel, on_done: &(dyn Fn(&JobResult) + Sync)) -> Vec<JobResult> {
    let mine: Vec<&Job> = jobs.iter().enumerate().filter(|(i, _)| i % o.shard.1 == o.shard.0).map(|(_, j)| j).collect();
    let workers = jobs_within(o.memory, o.jobs).min(mine.len().max(1));
    let per_job_memory = (o.memory / workers as u64).max(RectifyOptions::MIN_MEMORY);
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let threads = if o.threads > 0 { o.threads } else { (cores / workers).max(1) };
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<JobResult>>> = Mutex::new(vec![None; mine.len()]);
    std::thread::scope(|s| {
        for _ in 0..workers {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::SeqCst);
                if i >= mine.len() {
                    break;
                }
                let job = mine[i];
                let r = run_one(job, o.force, per_job_memory, threads, host, cancel);
                on_done(&r);
                results.lock().expect("results")[i] = Some(r);
            });
        }
    });
    results.into_inner().expect("results").into_iter().flatten().collect()
}

fn run_one(job: &Job, force: bool, memory: u64, threads: usize, host: &dyn Progress, cancel: &Cancel) -> JobResult {
    let t = Instant::now();
    let mut res = JobResult {
        job: job.name.clone(),
        status: Status::Cancelled,
        error: None,
        output: job.config.file.path.clone(),
        seconds: 0.0,
        input_mb_per_s: None,
        peak_rss_mib: None,
        gcm_rms_px: None,
        gcm_max_px: None,
        error_bound: None,
        error_within: None,
        warnings: Vec::new(),
        gcps: None,
        occlusion: None,
    };
    if cancel.is_cancelled() {
        return res;
    }
    // A job that fails leaves no output of an earlier run marked finished
    // (its record no longer says what it is made of), and says it is there
    // where it was not made from these inputs (`current`: it was, and a
    // forced run failed to remake it).
    let earlier = job.config.file.path.exists();
    let failed = |res: &mut JobResult, e: String, current: bool| {
        res.status = Status::Failed;
        let record = sidecar(&job.config.file.path);
        let removed = std::fs::remove_file(&record).is_ok() || !record.exists();
        let stale = if earlier && !current && job.config.file.path.exists() {
            let removed = if removed { "; its .done record is removed" } else { "" };
            format!(" ({} is left from an earlier run, not made from these inputs{removed})", job.config.file.path.display())
        } else {
            String::new()
        };
        res.error = Some(format!("{e}{stale}"));
    };
    if let Some(p) = &job.problem {
        failed(&mut res, p.clone(), false);
        return res;
    }
    if let Some(dir) = job.config.file.path.parent().filter(|d| !d.as_os_str().is_empty()) {
        if let Err(e) = std::fs::create_dir_all(dir) {
            res.status = Status::Failed;
            res.error = Some(format!("{}: {}", dir.display(), crate::error::in_words(&e)));
            return res;
        }
    }
    // Held until the job is made (or not): another run of this manifest
    // leaves it alone meanwhile.
    let _lock = match lock::JobLock::take(&job.config.file.path) {
        Ok(Some(l)) => l,
        Ok(None) => {
            res.status = Status::Busy;
            res.error = Some(format!("another run is making it (it holds {})", lock::lock_path(&job.config.file.path).display()));
            return res;
        }
        Err(e) => {
            // Its folder's fault (not writable, say), not the lock's.
            let dir = crate::io::publish::folder_of(&job.config.file.path);
            res.status = Status::Failed;
            res.error = Some(format!("{}: {} (the folder of its output, where its lock is written)", dir.display(), crate::error::in_words(&e)));
            return res;
        }
    };
    let key = job_key(&job.config);
    let current = is_current(&job.config, &key);
    if !force && current {
        res.status = Status::Skipped;
        return res;
    }
    // The earlier record goes before the work: a run killed meanwhile
    // leaves no output marked finished for inputs it was not made from.
    let _ = std::fs::remove_file(sidecar(&job.config.file.path));
    let mut cfg = job.config.clone();
    cfg.resources.memory = memory;
    cfg.resources.threads = threads;
    // Nobody watches a job's steps; its warnings go to its record.
    match rectify(&cfg, &HostOnly(host), cancel) {
        Ok(r) => {
            res.status = Status::Done;
            res.input_mb_per_s = Some(r.input_mb_per_s);
            res.peak_rss_mib = r.peak_rss_mib;
            res.gcm_rms_px = Some(r.accuracy_estimate.rms);
            res.gcm_max_px = Some(r.accuracy_estimate.max);
            res.error_bound = r.error_bound;
            res.error_within = Some(r.error_within);
            res.warnings = r.warnings;
            res.gcps = r.gcps;
            res.occlusion = r.occlusion;
            if let Err(e) = write_sidecar(&cfg.file.path, &key) {
                res.status = Status::Failed;
                res.error = Some(e.to_string());
            }
        }
        Err(crate::Error::Cancelled) => res.status = Status::Cancelled,
        Err(e) => failed(&mut res, e.to_string(), current),
    }
    res.seconds = t.elapsed().as_secs_f64();
    res
}

/// Appends report lines as jobs finish, so a crash keeps what was done.
pub struct ReportWriter {
    file: Option<Mutex<std::fs::File>>,
}

impl ReportWriter {
    pub fn create(path: Option<&Path>) -> std::io::Result<ReportWriter> {
        let file = match path {
            Some(p) => Some(Mutex::new(std::fs::File::create(p)?)),
            None => None,
        };
        Ok(ReportWriter { file })
    }
    pub fn push(&self, r: &JobResult) {
        if let Some(f) = &self.file {
            let mut f = f.lock().expect("report");
            let _ = writeln!(f, "{}", serde_json::to_string(r).unwrap_or_default());
            let _ = f.flush();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_job_says_an_earlier_output_is_stale_only_where_it_is() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("o.tif");
        // An image that is not there: the job fails when it runs.
        let config = RectifyOptions::new(dir.path().join("gone.tif"), dir.path().join("gone.toml"), DemSource::Height(0.0), out.clone());
        let job = Job { name: "o".into(), config: config.clone(), problem: None };
        std::fs::write(&out, b"an earlier output").unwrap();
        // Made from these inputs (its record says so): a forced rerun that
        // fails leaves it, and says nothing of it being stale.
        write_sidecar(&out, &job_key(&config)).unwrap();
        assert_eq!(run_one(&job, false, 1 << 30, 1, &crate::progress::NoProgress, &Cancel::default()).status, Status::Skipped);
        let r = run_one(&job, true, 1 << 30, 1, &crate::progress::NoProgress, &Cancel::default());
        assert_eq!(r.status, Status::Failed);
        assert!(r.error.as_ref().is_some_and(|e| e.contains("gone") && !e.contains("earlier run")), "{:?}", r.error);
        // Not made from these inputs (another record): said, record removed.
        write_sidecar(&out, "0123456789abcdef").unwrap();
        let r = run_one(&job, false, 1 << 30, 1, &crate::progress::NoProgress, &Cancel::default());
        assert!(
            r.error.as_ref().is_some_and(|e| e.contains("left from an earlier run, not made from these inputs; its .done record is removed")),
            "{:?}",
            r.error
        );
        assert!(out.exists() && !sidecar(&out).exists());
    }
}
