//! No command writes over one of its own inputs, nor writes two of its
//! outputs to one file. Every command names its inputs and outputs before
//! any work, and [`check_outputs`] compares them as files, not as
//! spellings: an existing file by device and inode (so `dir/../scan.tif`, a
//! symbolic link and a hard link are all caught), a file still to be made
//! by its folder's real path and its name.

use crate::error::{Error, Result};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// A file a command reads or writes, and what it is to the command
/// (`image`, `DEM`, `output`): named in the message.
#[derive(Clone, Copy, Debug)]
pub struct Role<'a> {
    pub what: &'a str,
    pub path: &'a Path,
}

impl<'a> Role<'a> {
    pub fn new(what: &'a str, path: &'a Path) -> Role<'a> {
        Role { what, path }
    }
}

/// What makes two paths one file.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Identity {
    Inode(u64, u64),
    /// Not there yet: the real path of its folder, and its name.
    Planned(PathBuf),
}

fn identity(path: &Path) -> Option<Identity> {
    if let Ok(m) = std::fs::metadata(path) {
        return Some(Identity::Inode(m.dev(), m.ino()));
    }
    path.file_name()?;
    // The nearest folder that exists, by its real path, and the rest as
    // spelt (folders a batch makes on its way: `out/x.tif` twice is one
    // file before `out` exists too).
    let abs = std::path::absolute(path).ok()?;
    let base = abs.ancestors().skip(1).find(|a| a.is_dir())?;
    let mut planned = std::fs::canonicalize(base).ok()?;
    for part in abs.strip_prefix(base).ok()?.components() {
        match part {
            std::path::Component::ParentDir => {
                planned.pop();
            }
            std::path::Component::Normal(p) => planned.push(p),
            _ => {}
        }
    }
    Some(Identity::Planned(planned))
}

/// The real path of the folder `path` is in.
fn folder_of(path: &Path) -> Option<PathBuf> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    std::fs::canonicalize(dir).ok()
}

/// Refuses, naming both paths, an output that is the same file as an input
/// or as another output, or that would be made inside an input that is a
/// folder (a DEM folder takes what is put into it as a tile). Inputs that
/// do not exist are left to their readers to report.
pub fn check_outputs(inputs: &[Role], outputs: &[Role]) -> Result<()> {
    let ins: Vec<(Role, Identity)> = inputs.iter().filter_map(|r| Some((*r, identity(r.path).filter(|i| matches!(i, Identity::Inode(..)))?))).collect();
    let folders: Vec<(Role, PathBuf)> = inputs.iter().filter(|r| r.path.is_dir()).filter_map(|r| Some((*r, std::fs::canonicalize(r.path).ok()?))).collect();
    let mut outs: Vec<(Role, Identity)> = Vec::with_capacity(outputs.len());
    for out in outputs {
        let Some(id) = identity(out.path) else { continue };
        if let Some((input, _)) = folders.iter().find(|(_, f)| folder_of(out.path).as_ref() == Some(f)) {
            return Err(Error::Usage(format!(
                "the {} {} is inside the {} {}, a folder the run reads: refusing to write into an input",
                out.what,
                out.path.display(),
                input.what,
                input.path.display()
            )));
        }
        if let Some((input, _)) = ins.iter().find(|(_, i)| *i == id) {
            return Err(Error::Usage(format!(
                "the {} {} is the {} {}: refusing to write over an input",
                out.what,
                out.path.display(),
                input.what,
                input.path.display()
            )));
        }
        if let Some((other, _)) = outs.iter().find(|(_, o)| *o == id) {
            return Err(Error::Usage(format!("the {} {} and the {} {} are one file", other.what, other.path.display(), out.what, out.path.display())));
        }
        outs.push((*out, id));
    }
    Ok(())
}

/// Files read as a part of another input or of an option's value (a CRS
/// file named by `--crs`, a camera file's `crs`, a batch job's): not named
/// among a command's inputs, so checked where an output is made and
/// published. By device, inode and change time (an inode freed is given
/// to the next file made: a test's temporary folder gone, another's
/// output took its CRS file's number), with the path and kind to say.
static READ_WITHIN: std::sync::Mutex<Vec<(ReadFile, PathBuf, &'static str)>> = std::sync::Mutex::new(Vec::new());

type ReadFile = (u64, u64, i64, i64);

fn read_file(m: &std::fs::Metadata) -> ReadFile {
    (m.dev(), m.ino(), m.ctime(), m.ctime_nsec())
}

/// Notes `path`, `what` it is (`CRS file`), as read by this process (kept
/// for the process's life: the last 4096).
pub fn note_read(what: &'static str, path: &Path) {
    let Ok(m) = std::fs::metadata(path) else { return };
    let mut read = READ_WITHIN.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    if !read.iter().any(|(f, ..)| *f == read_file(&m)) {
        if read.len() >= 4096 {
            read.remove(0);
        }
        read.push((read_file(&m), path.to_path_buf(), what));
    }
}

/// Refuses an output `target` that is a file noted by [`note_read`].
pub fn check_not_read(what: &str, target: &Path) -> Result<()> {
    let Ok(m) = std::fs::metadata(target) else { return Ok(()) };
    let read = READ_WITHIN.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    match read.iter().find(|(f, ..)| *f == read_file(&m)) {
        Some((_, input, kind)) => Err(Error::Usage(format!(
            "the {what} {} is the {kind} {} this run read: refusing to write over an input",
            target.display(),
            input.display()
        ))),
        None => Ok(()),
    }
}

/// What an existing output path is, where it is not a plain file (a
/// symbolic link followed): `/dev/null`, a named pipe.
pub fn special_kind(path: &Path) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    let t = std::fs::metadata(path).ok()?.file_type();
    Some(if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_fifo() {
        "a named pipe"
    } else if t.is_socket() {
        "a socket"
    } else {
        return None;
    })
}

/// The refusal of an output that is a device or pipe (`kind`).
pub fn not_a_file(out: Role, kind: &str) -> Error {
    Error::Usage(format!("the {} {} is {kind}, not a file: give the path of a file to write", out.what, out.path.display()))
}

/// Whether an output of this kind may be a stream (`--json /dev/stdout`):
/// reports are written straight into a device or pipe; every other output
/// is a file made beside its target and renamed onto it, which would put a
/// file in the place of the device.
pub fn streams(what: &str) -> bool {
    matches!(what, "report" | "table")
}

/// Refuses an output path that cannot become a file: a folder, a path
/// whose folder does not exist, a device or pipe (but for reports), a
/// symbolic link to nothing. A link to a file is written through: the
/// file it names is replaced, as GDAL does.
pub fn check_writable(out: Role) -> Result<()> {
    if out.path.is_dir() {
        return Err(Error::Usage(format!("the {} {} is a folder, not a file", out.what, out.path.display())));
    }
    if let Some(kind) = special_kind(out.path) {
        if streams(out.what) {
            return Ok(());
        }
        return Err(not_a_file(out, kind));
    }
    check_not_read(out.what, out.path)?;
    let linked;
    let path = match std::fs::symlink_metadata(out.path) {
        Ok(m) if m.file_type().is_symlink() => match std::fs::canonicalize(out.path) {
            Ok(p) => {
                linked = p;
                linked.as_path()
            }
            Err(_) => {
                let to = std::fs::read_link(out.path).map(|t| t.display().to_string()).unwrap_or_default();
                return Err(Error::Usage(format!("the {} {} is a symbolic link to {to}, which does not exist", out.what, out.path.display())));
            }
        },
        _ => out.path,
    };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(Error::Usage(format!("the {} {}: the folder {} does not exist", out.what, out.path.display(), dir.display())));
    }
    // A file made and removed there: permissions, a read-only or immutable
    // folder, a file system that takes no files, found before the work.
    if let Err(e) = tempfile::Builder::new().prefix(".gcm-ortho-probe").tempfile_in(dir) {
        return Err(Error::io(out.path, crate::io::publish::without_path(&e)));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_file_under_any_spelling_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("sub")).unwrap();
        std::fs::write(d.join("scan.tif"), b"x").unwrap();
        std::os::unix::fs::symlink(d.join("scan.tif"), d.join("link.tif")).unwrap();
        std::fs::hard_link(d.join("scan.tif"), d.join("hard.tif")).unwrap();
        let scan = d.join("scan.tif");
        let inputs = [Role::new("image", &scan)];
        for spelling in [d.join("scan.tif"), d.join("sub/../scan.tif"), d.join("link.tif"), d.join("hard.tif")] {
            let e = check_outputs(&inputs, &[Role::new("output", &spelling)]).unwrap_err().to_string();
            assert!(e.contains("refusing to write over an input") && e.contains(&*scan.to_string_lossy()), "{e}");
        }
        // A new file is fine; two outputs that are one new file are not.
        let (a, b) = (d.join("ortho.tif"), d.join("sub/../ortho.tif"));
        check_outputs(&inputs, &[Role::new("output", &a)]).unwrap();
        let e = check_outputs(&inputs, &[Role::new("output", &a), Role::new("report", &b)]).unwrap_err().to_string();
        assert!(e.contains("are one file"), "{e}");
    }

    /// Outputs in folders still to be made (a batch's `output_dir`) are
    /// told apart by their paths from the nearest folder that exists.
    #[test]
    fn outputs_in_folders_still_to_be_made_are_compared_too() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let inputs: [Role; 0] = [];
        for (a, b) in [("out/x.tif", "out/x.tif"), ("out/x.tif", "out/deeper/../x.tif"), ("a/b/x.tif", "a/./b/x.tif")] {
            let (a, b) = (d.join(a), d.join(b));
            let e = check_outputs(&inputs, &[Role::new("output", &a), Role::new("output", &b)]).unwrap_err().to_string();
            assert!(e.contains("are one file"), "{e}");
        }
        check_outputs(&inputs, &[Role::new("output", &d.join("out/x.tif")), Role::new("output", &d.join("out/y.tif"))]).unwrap();
        check_outputs(&inputs, &[Role::new("output", &d.join("out/x.tif")), Role::new("output", &d.join("other/x.tif"))]).unwrap();
        assert!(!d.join("out").exists(), "the check made a folder");
    }

    #[test]
    fn an_output_inside_an_input_folder_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::create_dir(d.join("dem")).unwrap();
        std::fs::write(d.join("dem/a.tif"), b"x").unwrap();
        let dem = d.join("dem");
        let inputs = [Role::new("DEM", &dem)];
        for out in [d.join("dem/a.tif"), d.join("dem/new.tif"), d.join("dem/../dem/new.json")] {
            let e = check_outputs(&inputs, &[Role::new("output", &out)]).unwrap_err().to_string();
            assert!(e.contains("inside the DEM") && e.contains("refusing to write into an input"), "{e}");
        }
        check_outputs(&inputs, &[Role::new("output", &d.join("ortho.tif"))]).unwrap();
    }

    #[test]
    fn folders_and_missing_folders_are_not_outputs() {
        let dir = tempfile::tempdir().unwrap();
        assert!(check_writable(Role::new("output", dir.path())).unwrap_err().to_string().contains("is a folder"));
        let missing = dir.path().join("no/such/out.tif");
        assert!(check_writable(Role::new("output", &missing)).unwrap_err().to_string().contains("does not exist"));
        check_writable(Role::new("output", &dir.path().join("out.tif"))).unwrap();
    }
}
