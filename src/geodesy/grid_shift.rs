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
        check_ntv2_sizes(&path)?;
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

/// Subgrids a grid may claim: national grids have tens to a few hundred.
const MAX_SUBGRIDS: u64 = 100_000;

/// Refuses an NTv2 grid whose headers claim more records than the file
/// holds (the reader allocates what they claim: a 1 KB header claiming an
/// 8.6 GB grid would be read into memory, or abort). Other files pass to
/// the reader as they are.
fn check_ntv2_sizes(path: &std::path::Path) -> Result<(), String> {
    use std::io::{Read, Seek, SeekFrom};
    let bad = |m: String| format!("{}: {m}", path.display());
    let mut file = std::fs::File::open(path).map_err(|e| bad(e.to_string()))?;
    let len = file.metadata().map_err(|e| bad(e.to_string()))?.len();
    let mut head = [0u8; 11 * 16];
    if file.read_exact(&mut head).is_err() || &head[..8] != b"NUM_OREC" {
        return Ok(());
    }
    // Either byte order: the overview header has 11 records.
    let little = i32::from_le_bytes(head[8..12].try_into().expect("4 bytes")) == 11;
    let int = |b: &[u8]| {
        let v: [u8; 4] = b[..4].try_into().expect("4 bytes");
        i64::from(if little { i32::from_le_bytes(v) } else { i32::from_be_bytes(v) })
    };
    let (orec, srec, files) = (int(&head[8..]), int(&head[24..]), int(&head[40..]));
    if !(1..=64).contains(&orec) || !(1..=64).contains(&srec) || !(0..=MAX_SUBGRIDS as i64).contains(&files) {
        return Err(bad(format!("not an NTv2 grid this build reads: headers of {orec} and {srec} records, {files} subgrids")));
    }
    let mut at = orec as u64 * 16;
    let mut sub = vec![0u8; srec as usize * 16];
    for k in 0..files as u64 {
        if file.seek(SeekFrom::Start(at)).is_err() || file.read_exact(&mut sub).is_err() {
            return Err(bad(format!("its subgrid {} of {files} starts at byte {at}, past the end of the file ({len} bytes): truncated?", k + 1)));
        }
        // GS_COUNT: the subgrid's nodes, a 16-byte record each.
        let count = sub.chunks_exact(16).find(|r| r.starts_with(b"GS_COUNT")).map_or(-1, |r| int(&r[8..]));
        if count < 0 {
            return Err(bad(format!("its subgrid {} says no GS_COUNT", k + 1)));
        }
        // Its extent and spacing must give those nodes: the reader walks
        // the rows and columns they give (a damaged header spun it for good).
        let real = |key: &[u8]| {
            sub.chunks_exact(16).find(|r| r[..8].starts_with(key)).map(|r| {
                let v: [u8; 8] = r[8..16].try_into().expect("8 bytes");
                if little {
                    f64::from_le_bytes(v)
                } else {
                    f64::from_be_bytes(v)
                }
            })
        };
        let lines = |lo: &[u8], hi: &[u8], step: &[u8]| -> Option<f64> {
            let (lo, hi, step) = (real(lo)?, real(hi)?, real(step)?);
            let n = (hi - lo) / step + 1.0;
            (step > 0.0 && n.is_finite() && n >= 1.0 && (n - n.round()).abs() < 1e-6).then_some(n.round())
        };
        match (lines(b"S_LAT", b"N_LAT", b"LAT_INC"), lines(b"E_LONG", b"W_LONG", b"LONG_INC")) {
            (Some(rows), Some(cols)) if rows * cols == count as f64 => {}
            (Some(rows), Some(cols)) => {
                return Err(bad(format!("its subgrid {}: its extent and spacing give {rows} × {cols} nodes, its GS_COUNT {count}: damaged, or not an NTv2 grid", k + 1)));
            }
            _ => return Err(bad(format!("its subgrid {}: no whole number of rows and columns in its extent and spacing (S_LAT … LONG_INC): damaged, or not an NTv2 grid", k + 1))),
        }
        at += srec as u64 * 16 + count as u64 * 16;
        if at > len {
            return Err(bad(format!(
                "its subgrid {} claims {count} nodes, {:.1} MB, but the file holds {len} bytes: truncated, or not an NTv2 grid",
                k + 1,
                count as f64 * 16.0 / 1e6
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ntv2(subgrids: &[i32], nodes_written: usize) -> Vec<u8> {
        let rec = |key: &[u8], v: i32| {
            let mut r = key.to_vec();
            r.resize(8, b' ');
            r.extend_from_slice(&v.to_le_bytes());
            r.resize(16, 0);
            r
        };
        let mut f: Vec<u8> = [rec(b"NUM_OREC", 11), rec(b"NUM_SREC", 11), rec(b"NUM_FILE", subgrids.len() as i32)].concat();
        f.resize(11 * 16, b' ');
        let real = |key: &[u8], v: f64| {
            let mut r = key.to_vec();
            r.resize(8, b' ');
            r.extend_from_slice(&v.to_le_bytes());
            r
        };
        for &count in subgrids {
            // One row of `count` nodes, an arc-second apart.
            let mut h = vec![b' '; 4 * 16];
            for (key, v) in [(&b"S_LAT"[..], 0.0), (b"N_LAT", 0.0), (b"E_LONG", 0.0), (b"W_LONG", f64::from(count - 1)), (b"LAT_INC", 1.0), (b"LONG_INC", 1.0)] {
                h.extend(real(key, v));
            }
            h.extend(rec(b"GS_COUNT", count));
            f.extend(h);
            f.extend(vec![0u8; nodes_written * 16]);
        }
        f
    }

    /// A header claiming an 8.6 GB grid in a small file is refused by
    /// size, before the reader allocates what it claims.
    #[test]
    fn grids_claiming_more_than_their_file_are_refused() {
        let dir = std::env::temp_dir().join(format!("ntv2-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("claims.gsb");
        std::fs::write(&path, ntv2(&[537_000_000], 4)).unwrap();
        let e = check_ntv2_sizes(&path).unwrap_err();
        assert!(e.contains("claims.gsb") && e.contains("537000000 nodes") && e.contains("8592.0 MB"), "{e}");
        std::fs::write(&path, ntv2(&[4, 4], 4)).unwrap();
        check_ntv2_sizes(&path).unwrap();
        std::fs::write(&path, ntv2(&[4, 5], 4)).unwrap();
        assert!(check_ntv2_sizes(&path).unwrap_err().contains("subgrid 2 claims 5 nodes"));
        // A damaged extent: its nodes are not what GS_COUNT says (the
        // reader spun on such a header, found by fuzzing).
        let mut f = ntv2(&[4], 4);
        let w_long = 11 * 16 + 7 * 16 + 8;
        f[w_long..w_long + 8].copy_from_slice(&1e9f64.to_le_bytes());
        std::fs::write(&path, f).unwrap();
        let e = check_ntv2_sizes(&path).unwrap_err();
        assert!(e.contains("subgrid 1: its extent and spacing give 1 × 1000000001 nodes, its GS_COUNT 4"), "{e}");
        // Through a definition naming it: said by name, nothing read.
        std::fs::write(&path, ntv2(&[537_000_000], 4)).unwrap();
        let e = load_for(&format!("+proj=longlat +ellps=intl +nadgrids={}", path.display())).unwrap_err();
        assert!(e.contains("claims.gsb") && e.contains("claims 537000000 nodes"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
