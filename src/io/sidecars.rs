//! The files other tools keep beside a raster or a table, which a run
//! reads with it: a `.prj`, GDAL's `.aux.xml`, RPC files, world files, an
//! XMP sidecar, external overviews. Each is an input, never an output.

use std::path::{Path, PathBuf};

/// Endings put in place of a file's extension.
const REPLACING: [&str; 16] = ["prj", "PRJ", "RPB", "rpb", "geom", "tfw", "tifw", "tiffw", "wld", "jgw", "pgw", "j2w", "xmp", "XMP", "hdr", "rpc"];
/// Endings put after a file's whole name.
const APPENDED: [&str; 4] = [".aux.xml", ".ovr", ".xmp", ".msk"];
/// Endings put after a file's stem.
const AFTER_STEM: [&str; 2] = ["_RPC.TXT", "_rpc.txt"];

/// The sidecars beside `file` that exist (none for a folder).
pub fn of(file: &Path) -> Vec<PathBuf> {
    if !file.is_file() {
        return Vec::new();
    }
    let name = file.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let stem = file.file_stem().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let dir = file.parent().unwrap_or(Path::new(""));
    let mut found: Vec<PathBuf> = REPLACING
        .iter()
        .map(|e| file.with_extension(e))
        .chain(APPENDED.iter().map(|e| dir.join(format!("{name}{e}"))))
        .chain(AFTER_STEM.iter().map(|e| dir.join(format!("{stem}{e}"))))
        .filter(|p| p != file && p.is_file())
        .collect();
    found.sort();
    found.dedup();
    found
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_sidecars_that_exist_are_found_and_no_others() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        for f in ["ext.csv", "ext.prj", "scan.tif", "scan.tif.aux.xml", "scan_RPC.TXT", "scan.tfw", "scan.xmp", "other.prj"] {
            std::fs::write(d.join(f), "x").unwrap();
        }
        assert_eq!(super::of(&d.join("ext.csv")), vec![d.join("ext.prj")]);
        let names: Vec<String> = super::of(&d.join("scan.tif")).iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
        assert_eq!(names, ["scan.tfw", "scan.tif.aux.xml", "scan.xmp", "scan_RPC.TXT"]);
        assert!(super::of(d).is_empty());
    }
}
