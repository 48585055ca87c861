//! Datum shift grids (`+nadgrids=`, NTv2 `.gsb` and PROJ's GeoTIFF grids):
//! found in PROJ's folders and loaded into `proj4rs`'s catalog before a
//! definition naming them is parsed, so that a grid missing or unreadable
//! is refused naming the grid, not as "NAD grid not available".

use super::proj_data;
use std::io::BufReader;

/// Loads every grid of a PROJ definition's `+nadgrids=` list that the
/// catalog does not hold yet. Grids marked optional (`@name`) may be
/// missing; a mandatory one missing or unreadable is an error naming it.
pub fn load_for(definition: &str) -> Result<(), String> {
    let Some(list) = definition.split_whitespace().find_map(|t| t.strip_prefix("+nadgrids=")) else { return Ok(()) };
    for entry in list.split(',').map(str::trim).filter(|e| !e.is_empty()) {
        let (name, optional) = match entry.strip_prefix('@') {
            Some(n) => (n, true),
            None => (entry, false),
        };
        if name == "null" {
            break;
        }
        if loaded(name) {
            continue;
        }
        let Some(path) = proj_data::find_grid(name) else {
            if optional {
                continue;
            }
            return Err(format!(
                "the datum shift grid {name} (+nadgrids) is not in PROJ's folders ({}): install it there (projsync --file {name}, or from cdn.proj.org) or set PROJ_DATA",
                proj_data::searched()
            ));
        };
        let file = std::fs::File::open(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        let read = proj4rs::nadgrids::catalog::with_catalog(|cat| proj4rs::nadgrids::formats::read(cat, name, &mut BufReader::new(file)));
        if let Err(e) = read {
            // An optional grid that cannot be read is left out, as PROJ does.
            if !optional {
                return Err(format!("{}: not a datum shift grid this build reads (NTv2 .gsb or PROJ's GeoTIFF grids): {e}", path.display()));
            }
        }
    }
    Ok(())
}

fn loaded(name: &str) -> bool {
    proj4rs::nadgrids::catalog::with_catalog(|cat| cat.find(name).is_some())
}
