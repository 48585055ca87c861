//! Where PROJ keeps its grids (geoid models, datum shift grids): the
//! user's folder, then `PROJ_DATA` or `PROJ_LIB` where set, else the
//! system's. A grid a CRS names is looked for there, as PROJ does.

use std::path::{Path, PathBuf};

/// PROJ's grid folders, in the order it searches them.
fn grid_dirs() -> Vec<PathBuf> {
    let user = std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/share/proj"));
    let set: Vec<PathBuf> = ["PROJ_DATA", "PROJ_LIB"].iter().filter_map(std::env::var_os).flat_map(|v| std::env::split_paths(&v).collect::<Vec<_>>()).collect();
    let system = if set.is_empty() { vec![PathBuf::from("/usr/local/share/proj"), PathBuf::from("/usr/share/proj")] } else { set };
    user.into_iter().chain(system).collect()
}

/// The grid file `name`: itself where it is a path to a file, else the
/// first of PROJ's folders holding it.
pub fn find_grid(name: &str) -> Option<PathBuf> {
    let given = Path::new(name);
    if given.components().count() > 1 || given.is_absolute() {
        return given.is_file().then(|| given.to_path_buf());
    }
    grid_dirs().into_iter().map(|d| d.join(name)).find(|p| p.is_file())
}

/// The folders searched, for a message saying a grid was not found.
pub fn searched() -> String {
    grid_dirs().iter().map(|d| d.display().to_string()).collect::<Vec<_>>().join(", ")
}
