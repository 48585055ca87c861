//! A failed `synth` leaves nothing behind: what it made in its output
//! folder (or the folder itself, when it made that too) is removed.

use std::collections::HashSet;
use std::ffi::OsString;
use std::path::{Path, PathBuf};

/// What was at the output folder before a run.
pub struct Leftovers {
    /// The first folder on the way to `out` that did not exist.
    made_folder: Option<PathBuf>,
    out: PathBuf,
    present: HashSet<OsString>,
}

impl Leftovers {
    pub fn before(out: &Path) -> Leftovers {
        let made_folder = out.ancestors().take_while(|p| !p.as_os_str().is_empty() && !p.exists()).last().map(Path::to_path_buf);
        let present = std::fs::read_dir(out).map(|d| d.filter_map(|e| e.ok().map(|e| e.file_name())).collect()).unwrap_or_default();
        Leftovers { made_folder, out: out.to_path_buf(), present }
    }

    /// Removes what the run added; best effort, as the run has failed already.
    pub fn remove(&self) {
        if let Some(folder) = &self.made_folder {
            let _ = std::fs::remove_dir_all(folder);
            return;
        }
        let Ok(entries) = std::fs::read_dir(&self.out) else { return };
        for e in entries.flatten() {
            if self.present.contains(&e.file_name()) {
                continue;
            }
            let path = e.path();
            let _ = if e.file_type().is_ok_and(|t| t.is_dir()) { std::fs::remove_dir_all(&path) } else { std::fs::remove_file(&path) };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_what_the_run_added_is_removed() {
        let dir = std::env::temp_dir().join(format!("gcm-leftovers-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("mine.txt"), "kept").unwrap();
        let before = Leftovers::before(&dir);
        std::fs::write(dir.join("camera.toml"), "new").unwrap();
        std::fs::create_dir_all(dir.join("scans/a")).unwrap();
        before.remove();
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(left, vec![OsString::from("mine.txt")]);

        let fresh = dir.join("new/deeper");
        let before = Leftovers::before(&fresh);
        std::fs::create_dir_all(&fresh).unwrap();
        std::fs::write(fresh.join("scan.tif"), "x").unwrap();
        before.remove();
        assert!(!dir.join("new").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
