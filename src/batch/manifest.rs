//! The batch manifest: defaults, jobs, or an aerotriangulation block (one
//! interior-orientation file plus a CSV of exterior orientations). Paths are
//! relative to the manifest. Everything is validated before any work
//! starts, and every problem is listed with its line.

use crate::camera::file::CameraFile;
use crate::error::Error;
use crate::io::bounded_read::{read_text_bounded, LIST};
use crate::io::overwrite::{check_outputs, Role};
use crate::keys::Options;
use crate::options::{DemSource, ModelSource, RectifyOptions};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use toml::Spanned;

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct JobEntry {
    image: String,
    camera: Option<String>,
    output: Option<String>,
    #[serde(flatten)]
    options: Options,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Block {
    /// The lens: our camera file, Orthority's interior parameters, or an
    /// OpenSfM reconstruction (which holds the poses as well).
    interior: String,
    /// The poses, in any form `camera::formats` reads.
    #[serde(alias = "exterior_csv")]
    exterior: Option<String>,
    /// The unit of the exterior CSV's angles (`--radians`).
    #[serde(default)]
    radians: bool,
    images: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ManifestFile {
    #[serde(default)]
    defaults: Options,
    #[serde(default)]
    job: Vec<Spanned<JobEntry>>,
    block: Option<Spanned<Block>>,
}

/// One job, ready to run — or, when `problem` is set, one that validation
/// already knows will fail (a missing file, a camera that does not parse):
/// it is reported as failed while the others run.
#[derive(Clone, Debug)]
pub struct Job {
    /// A stable name (the image's file stem), unique in the manifest.
    pub name: String,
    pub config: RectifyOptions,
    pub problem: Option<String>,
}

/// Problems found in a manifest, each with where it is (each names the
/// manifest).
#[derive(Debug)]
pub struct ManifestErrors {
    pub problems: Vec<String>,
    /// A job would write over an input: refused as arguments are.
    pub refusal: bool,
}

impl ManifestErrors {
    fn of(problems: Vec<String>) -> ManifestErrors {
        ManifestErrors { problems, refusal: false }
    }

    /// As a run's error: a refusal to write over an input is a usage error.
    pub fn into_error(self) -> Error {
        if self.refusal {
            Error::Usage(self.to_string())
        } else {
            Error::Named(self.to_string())
        }
    }
}

impl std::fmt::Display for ManifestErrors {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.problems.as_slice() {
            [one] => write!(f, "{one}"),
            all => write!(f, "{} problems: {}", all.len(), all.join("; ")),
        }
    }
}

/// The key an "unknown field `KEY`" message names.
fn unknown_key(message: &str) -> Option<&str> {
    message.strip_prefix("unknown field `")?.split('`').next()
}

/// The line of `text` within `span` where `key` is set (`key =`, its name
/// bare or quoted).
fn key_line(text: &str, span: std::ops::Range<usize>, key: &str) -> Option<usize> {
    let within = text.get(span.start..span.end.min(text.len()))?;
    let mut offset = span.start;
    for l in within.split_inclusive('\n') {
        let t = l.trim_start();
        let rest = [key.to_string(), format!("\"{key}\""), format!("'{key}'")].into_iter().find_map(|k| t.strip_prefix(k.as_str()).map(str::to_string));
        if rest.is_some_and(|r| r.trim_start().starts_with('=')) {
            return Some(line_of(text, offset));
        }
        offset += l.len();
    }
    None
}

/// The line (from 1) of `key` in the manifest's `[defaults]`, if there.
fn defaults_key_line(text: &str, key: &str) -> Option<usize> {
    let lines: Vec<&str> = text.lines().collect();
    let section = lines.iter().position(|l| l.trim() == "[defaults]")?;
    lines[section + 1..]
        .iter()
        .take_while(|l| !l.trim_start().starts_with('['))
        .position(|l| l.split('=').next().is_some_and(|k| k.trim().trim_matches(|c| c == '"' || c == '\'') == key))
        .map(|k| section + 2 + k)
}

/// The keys of the job table at `span` of `text` that no job takes.
fn stray_job_keys(text: &str, span: std::ops::Range<usize>) -> Vec<String> {
    // (The span starts at the table's `[[job]]` header.)
    let Some(Ok(table)) = text.get(span).map(|t| t.trim_start().strip_prefix("[[job]]").unwrap_or(t)).map(toml::from_str::<toml::Table>) else {
        return Vec::new();
    };
    let unknown = |key: &str| {
        let mut t = toml::Table::new();
        t.insert(key.to_string(), toml::Value::Integer(0));
        matches!(toml::Value::Table(t).try_into::<Options>(), Err(e) if e.to_string().contains("unknown field"))
    };
    table.keys().filter(|k| !["image", "camera", "output"].contains(&k.as_str()) && unknown(k)).cloned().collect()
}

/// ", expected one of …" for a job's unknown `key`: a job's own keys and
/// those of `[defaults]` (as serde lists them for `[defaults]`), the
/// nearest first where one is a slip of it.
fn job_keys_hint(key: &str) -> String {
    let mut table = toml::Table::new();
    table.insert(key.to_string(), toml::Value::Integer(0));
    let listed = match toml::Value::Table(table).try_into::<Options>() {
        Err(e) => e.to_string(),
        Ok(_) => return String::new(),
    };
    let mut keys: Vec<String> = ["image", "camera", "output"].into_iter().map(String::from).collect();
    if let Some((_, list)) = listed.split_once("expected one of ") {
        keys.extend(list.split(", ").map(|k| k.trim().trim_matches('`').to_string()).filter(|k| !k.is_empty()));
    }
    let near = keys.iter().min_by_key(|k| edits(k, key)).filter(|k| edits(k, key) <= 2);
    let all = keys.iter().map(|k| format!("`{k}`")).collect::<Vec<_>>().join(", ");
    match near {
        Some(k) => format!(" (did you mean `{k}`?), expected one of {all}"),
        None => format!(", expected one of {all}"),
    }
}

/// Levenshtein's distance between `a` and `b`, each letter a step.
fn edits(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let here = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != cb)).min(row[j] + 1).min(here + 1);
            prev = here;
        }
    }
    row[b.len()]
}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

/// Reads and validates a manifest; returns its jobs in manifest order. A
/// manifest that cannot be read as a whole is an error listing every
/// problem; a job with a bad input comes back with its `problem` set.
pub fn load(path: &Path) -> Result<Vec<Job>, ManifestErrors> {
    let text = read_text_bounded(path, "a manifest", LIST).map_err(|e| ManifestErrors::of(vec![e.to_string()]))?;
    let m: ManifestFile = toml::from_str(&text).map_err(|e| {
        let mut message = e.message().replace('\n', " ");
        let line = e.span().map(|s| {
            // A job's unknown key: its own line (the error spans the job's
            // table), and the keys a job takes (serde does not list them
            // through the job's flattened options).
            // A key a job lacks, where the job has one it does not take: a
            // slip of the one it lacks, named on its line.
            let slip = match message.starts_with("missing field") {
                true => stray_job_keys(&text, s.clone()).into_iter().next(),
                false => None,
            };
            if let Some(key) = slip {
                if let Some(l) = key_line(&text, s.clone(), &key) {
                    message = format!("{message}, and `{key}` is no key a job takes{}", job_keys_hint(&key));
                    return l;
                }
            }
            match unknown_key(&message).and_then(|k| key_line(&text, s.clone(), k).map(|l| (k.to_string(), l))) {
                Some((key, l)) => {
                    if !message.contains("expected") {
                        message = format!("{message}{}", job_keys_hint(&key));
                    }
                    l
                }
                None => line_of(&text, s.start),
            }
        });
        let line = line.map(|l| format!(" line {l}")).unwrap_or_default();
        ManifestErrors::of(vec![format!("{}:{line}: {message}", path.display())])
    })?;
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let rel = |p: &str| -> PathBuf {
        let p = Path::new(p);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            base.join(p)
        }
    };
    let mut errors = Vec::new();
    let mut jobs = Vec::new();
    let at = |line: usize| format!("{}: line {line}", path.display());

    // A bad setting in [defaults] that every job takes is said once, at
    // its own line (the manifest refused), not as every job's problem at
    // the job's line; one that holds with a job's own settings (gcp_refine
    // with each job's gcps) is no fault of [defaults].
    let mut settings = m.defaults.clone();
    (settings.dem, settings.height) = (None, Some(0.0));
    let defaults_fault = config("defaults", PathBuf::new(), PathBuf::new(), None, None, &settings, &rel).err();
    let mut config_faults: Vec<Option<String>> = Vec::new();
    let mut entries: Vec<Entry> = Vec::new();
    for j in &m.job {
        // A job is said at its image's line (its table begins a line above).
        let line = key_line(&text, j.span(), "image").unwrap_or_else(|| line_of(&text, j.span().start));
        let e = j.get_ref();
        let Some(cam) = &e.camera else {
            errors.push(format!("{}: [[job]] for {} has no camera", at(line), e.image));
            continue;
        };
        entries.push(Entry {
            image: rel(&e.image),
            camera: rel(cam),
            inline: None,
            output: e.output.as_deref().map(rel),
            options: e.options.over(&m.defaults),
            line,
            span: Some(j.span()),
        });
    }
    if let Some(b) = &m.block {
        let line = line_of(&text, b.span().start);
        let b = b.get_ref();
        let exterior = b.exterior.as_deref().map(&rel);
        let angles = if b.radians { crate::camera::formats::AngleUnit::Radians } else { crate::camera::formats::AngleUnit::Degrees };
        match crate::camera::formats::read_with(&rel(&b.interior), exterior.as_deref(), None, angles).and_then(|set| set.all()) {
            Ok(cams) => {
                for (name, cam, origin) in cams {
                    let image = rel(&image_of(&b.images, &name));
                    entries.push(Entry {
                        image,
                        camera: PathBuf::from(origin),
                        inline: Some(cam),
                        output: None,
                        options: m.defaults.clone(),
                        line,
                        span: None,
                    });
                }
            }
            Err(e) => errors.push(e.to_string()),
        }
    }
    if entries.is_empty() && errors.is_empty() {
        errors.push(format!("{}: no [[job]] and no [block]", path.display()));
    }
    let mut names = std::collections::HashSet::new();
    // Each image's first job's line: the same image twice is a mistake,
    // however spelt (two images of one name in two folders are not).
    let mut seen: std::collections::HashMap<PathBuf, usize> = std::collections::HashMap::new();
    for Entry { image, camera, inline, output, options: opts, line, span } in entries {
        let first = *seen.entry(std::fs::canonicalize(&image).unwrap_or_else(|_| image.clone())).or_insert(line);
        if first != line {
            errors.push(format!("{}: a second job for the image {} (the first at line {first})", at(line), image.display()));
            continue;
        }
        // The image's name; where two images share it (scan.tif in two
        // folders), its path from the manifest's folder.
        let stem = image.file_stem().and_then(|s| s.to_str()).unwrap_or("job").to_string();
        let longer = image.strip_prefix(&base).unwrap_or(&image).with_extension("").to_string_lossy().into_owned();
        let Some(name) = [stem, longer].into_iter().find(|n| !names.contains(n)) else {
            errors.push(format!("{}: a second job for the image {}", at(line), image.display()));
            continue;
        };
        names.insert(name.clone());
        let mut problems = Vec::new();
        if !image.is_file() {
            problems.push(format!("image {} does not exist", image.display()));
        }
        let cam = match &inline {
            // Marks to be found in the scan are found when the job runs.
            Some(cf) if cf.needs_marks() => Ok(()),
            Some(cf) => cf.clone().build(&camera).map(|_| ()),
            None => crate::scene::camera::check_for(&image, &camera),
        };
        if let Err(e) = cam {
            problems.push(e.to_string());
        }
        let cfg = config(&name, image.clone(), camera.clone(), inline.clone(), output.clone(), &opts, &rel);
        config_faults.push(cfg.as_ref().err().cloned());
        let cfg = match cfg {
            Ok(c) => c,
            Err(e) => {
                problems.push(e);
                RectifyOptions::new(image, camera, DemSource::Height(0.0), output_of(&name, output.clone(), &opts, &rel))
            }
        };
        // A bad value of the job's own: said at its key's line.
        let key = problems.first().and_then(|p| p.split(':').next()).map(str::trim);
        // (A key the job takes from [defaults]: said at that key's line.)
        let own = span.clone().zip(key).and_then(|(span, key)| key_line(&text, span, key)).or_else(|| key.and_then(|k| defaults_key_line(&text, k)));
        let problem = (!problems.is_empty()).then(|| format!("{}: {}", at(own.unwrap_or(line)), problems.join("; ")));
        jobs.push(Job { name, config: cfg, problem });
    }
    if let Some(e) = defaults_fault.filter(|e| !config_faults.is_empty() && config_faults.iter().all(|f| f.as_ref() == Some(e))) {
        // The key's own line where the message starts with it.
        let section = text.lines().position(|l| l.trim() == "[defaults]").unwrap_or(0);
        let own = defaults_key_line(&text, e.split(':').next().unwrap_or("").trim());
        errors.push(format!("{}: [defaults]: {e}", at(own.unwrap_or(section + 1))));
    }
    // No job may write over what any job reads, nor two jobs to one file.
    let mut refusal = false;
    if errors.is_empty() {
        let mut inputs = vec![("manifest".to_string(), path.to_path_buf())];
        if let Some(b) = &m.block {
            let b = b.get_ref();
            inputs.push(("interior file".into(), rel(&b.interior)));
            if let Some(e) = &b.exterior {
                inputs.push(("exterior orientations".into(), rel(e)));
            }
        }
        let (job_inputs, outputs) = files(&jobs);
        inputs.extend(job_inputs);
        let ins: Vec<Role> = inputs.iter().map(|(w, p)| Role::new(w, p)).collect();
        let outs: Vec<Role> = outputs.iter().map(|(w, p)| Role::new(w, p)).collect();
        if let Err(e) = check_outputs(&ins, &outs) {
            errors.push(format!("{}: {e}", path.display()));
            refusal = true;
        }
    }
    if errors.is_empty() {
        Ok(jobs)
    } else {
        Err(ManifestErrors { problems: errors, refusal })
    }
}

/// Files, each with what it is to its job.
pub type Files = Vec<(String, PathBuf)>;

/// What the jobs read and what they write (each output with its `.done`
/// record), each named by its job; jobs already known to fail (their
/// settings are not theirs) are left out.
pub fn files(jobs: &[Job]) -> (Files, Files) {
    let (mut ins, mut outs) = (Vec::new(), Vec::new());
    for j in jobs.iter().filter(|j| j.problem.is_none()) {
        for (what, p) in j.config.inputs() {
            ins.push((format!("{what} of job {}", j.name), p));
        }
        outs.push((format!("output of job {}", j.name), j.config.file.path.clone()));
        outs.push((format!("record of job {}", j.name), super::sidecar(&j.config.file.path)));
    }
    (ins, outs)
}

/// One job as written, before validation.
struct Entry {
    image: PathBuf,
    /// The camera file, or (for a block) where the exterior orientation came from.
    camera: PathBuf,
    inline: Option<CameraFile>,
    output: Option<PathBuf>,
    options: Options,
    line: usize,
    /// The job's table in the manifest's text (none for a block's images).
    span: Option<std::ops::Range<usize>>,
}

/// Where a job's orthophoto goes: as the job says, or named after the
/// image in `output_dir` or the manifest's folder.
fn output_of(name: &str, output: Option<PathBuf>, o: &Options, rel: &dyn Fn(&str) -> PathBuf) -> PathBuf {
    match (output, &o.output_dir) {
        (Some(p), _) => p,
        // A name with folders (two images of one name) as one file name.
        (None, Some(dir)) => rel(dir).join(format!("{}.tif", name.replace('/', "_"))),
        (None, None) => rel(&format!("{}.ortho.tif", name.replace('/', "_"))),
    }
}

fn config(
    name: &str,
    image: PathBuf,
    camera: PathBuf,
    inline: Option<CameraFile>,
    output: Option<PathBuf>,
    o: &Options,
    rel: &dyn Fn(&str) -> PathBuf,
) -> Result<RectifyOptions, String> {
    let dem = match (&o.dem, o.height) {
        (Some(d), None) => {
            let p = rel(d);
            // (A folder of tiles is a DEM too.)
            if !(p.is_file() || p.is_dir()) {
                return Err(format!("dem: {} does not exist", p.display()));
            }
            DemSource::File(p)
        }
        (None, Some(h)) if h.is_finite() => DemSource::Height(h),
        (None, Some(h)) => return Err(format!("height: {h} is not a number of metres")),
        (Some(_), Some(_)) => return Err("give dem or height, not both".into()),
        _ => return Err("no dem and no height".into()),
    };
    let output = output_of(name, output, o, rel);
    let mut c = RectifyOptions::new(image, camera, dem, output);
    c.inputs.model = inline.map_or(ModelSource::CameraFile, ModelSource::Inline);
    crate::keys::apply(o, &mut c, rel).and_then(|()| c.validate()).map_err(|e| match e {
        // The manifest's own key, as written.
        Error::Setting { setting, msg } => format!("{setting}: {msg}"),
        e => e.to_string(),
    })?;
    Ok(c)
}

/// A block image's path: the template with `{name}` replaced by the CSV's
/// name, less the name's own image extension where the template gives one
/// (`0182.tif` in `scans/{name}.tif` is `scans/0182.tif`).
fn image_of(template: &str, name: &str) -> String {
    const IMAGE: [&str; 7] = ["tif", "tiff", "jpg", "jpeg", "png", "jp2", "j2k"];
    let ext = Path::new(name).extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let stem = match ext {
        Some(e) if IMAGE.contains(&e.as_str()) && template.contains("{name}.") => &name[..name.len() - e.len() - 1],
        _ => name,
    };
    template.replace("{name}", stem)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::Miss;

    /// A height for the DEM's misses is taken as a number or as text, as
    /// the flag takes it; a word it does not know is refused naming the key.
    #[test]
    fn a_height_for_the_dems_misses_is_a_number_or_text() {
        let dir = tempfile::tempdir().unwrap();
        let m = dir.path().join("m.toml");
        let mini = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/mini");
        for f in ["scan.tif", "camera.toml", "dem.tif"] {
            std::fs::copy(mini.join(f), dir.path().join(f)).unwrap();
        }
        for (value, want) in [("110", Miss::Height(110.0)), ("110.5", Miss::Height(110.5)), ("\"110\"", Miss::Height(110.0)), ("\"nodata\"", Miss::Nodata)] {
            let text =
                format!("[defaults]\ndem = \"dem.tif\"\ndem_outside = {value}\ndem_hole = {value}\n[[job]]\nimage = \"scan.tif\"\ncamera = \"camera.toml\"\n");
            std::fs::write(&m, text).unwrap();
            let jobs = load(&m).unwrap_or_else(|e| panic!("{value}: {:?}", e.problems));
            assert_eq!((jobs[0].config.inputs.dem_outside, jobs[0].config.inputs.dem_hole), (want, want), "{value}: {:?}", jobs[0].problem);
        }
        // A bad value in [defaults]: the manifest refused once, at the key's
        // own line (not each job's, at the job's line); in a job, that job's.
        std::fs::write(&m, "[defaults]\ndem = \"dem.tif\"\ndem_outside = \"zero\"\n[[job]]\nimage = \"scan.tif\"\ncamera = \"camera.toml\"\n").unwrap();
        let problems = load(&m).err().map(|e| e.problems).unwrap_or_default();
        assert!(problems.len() == 1 && problems[0].contains("line 3: [defaults]: dem_outside"), "{problems:?}");
        std::fs::write(&m, "[defaults]\ndem = \"dem.tif\"\n[[job]]\nimage = \"scan.tif\"\ncamera = \"camera.toml\"\ndem_outside = \"zero\"\n").unwrap();
        let problem = load(&m).unwrap()[0].problem.clone().unwrap_or_default();
        assert!(problem.contains("line 6") && problem.contains("dem_outside"), "{problem}");
        // A default that holds with each job's own settings is no fault.
        std::fs::write(
            &m,
            "[defaults]\ndem = \"dem.tif\"\ngcp_refine = \"shift\"\n[[job]]\nimage = \"scan.tif\"\ncamera = \"camera.toml\"\ngcps = \"g.csv\"\n",
        )
        .unwrap();
        let jobs = load(&m).unwrap_or_else(|e| panic!("{:?}", e.problems));
        assert!(jobs[0].problem.is_none(), "{:?}", jobs[0].problem);
        // A height of nan or inf (TOML has both) is named as it is, not
        // taken for a missing one.
        for value in ["nan", "inf", "-inf"] {
            std::fs::write(&m, format!("[[job]]\nimage = \"scan.tif\"\ncamera = \"camera.toml\"\nheight = {value}\n")).unwrap();
            let problem = load(&m).map(|j| j[0].problem.clone().unwrap_or_default()).unwrap_or_else(|e| e.problems.join("; "));
            assert!(problem.contains("height") && problem.contains("is not a number of metres") && !problem.contains("no dem"), "{value}: {problem}");
        }
    }
}
