//! Fixed-length arrays in TOML read strictly.
//!
//! The `toml` crate fills a `[f64; 3]` from the first three entries of a
//! longer array and drops the rest without a word (`radial_mm` of four
//! numbers read as three). What was read, written back, is set beside what
//! was given: an array given longer than it reads back was cut.

use serde::Serialize;
use toml::{Table, Value};

/// The first array given longer than `read` holds it: its key path (as
/// `distortion.radial_mm` or `interior.fiducials_px[2]`), and the two lengths.
pub fn first_cut_array<T: Serialize>(given: &str, read: &T) -> Option<(String, usize, usize)> {
    let given: Table = toml::from_str(given).ok()?;
    let read = Table::try_from(read).ok()?;
    cut_in_table(&given, &read, "")
}

fn cut_in_table(given: &Table, read: &Table, path: &str) -> Option<(String, usize, usize)> {
    given.iter().find_map(|(key, g)| {
        let r = read.get(key)?;
        let here = if path.is_empty() { key.clone() } else { format!("{path}.{key}") };
        cut_in_value(g, r, &here)
    })
}

fn cut_in_value(given: &Value, read: &Value, path: &str) -> Option<(String, usize, usize)> {
    match (given, read) {
        (Value::Table(g), Value::Table(r)) => cut_in_table(g, r, path),
        (Value::Array(g), Value::Array(r)) if g.len() > r.len() => Some((path.to_string(), g.len(), r.len())),
        (Value::Array(g), Value::Array(r)) => g.iter().zip(r).enumerate().find_map(|(i, (g, r))| cut_in_value(g, r, &format!("{path}[{}]", i + 1))),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize, serde::Deserialize)]
    struct Lens {
        radial_mm: [f64; 3],
        marks: Vec<[f64; 2]>,
        name: Option<String>,
    }

    #[derive(Serialize, serde::Deserialize)]
    struct File {
        distortion: Lens,
    }

    fn cut(text: &str) -> Option<(String, usize, usize)> {
        let read: File = toml::from_str(text).unwrap();
        first_cut_array(text, &read)
    }

    #[test]
    fn an_array_longer_than_its_field_is_found_by_its_path() {
        assert_eq!(cut("[distortion]\nradial_mm = [1, 2, 3]\nmarks = [[1, 2], [3, 4]]"), None);
        assert_eq!(cut("[distortion]\nradial_mm = [1, 2, 3, 7]\nmarks = []"), Some(("distortion.radial_mm".into(), 4, 3)));
        assert_eq!(cut("[distortion]\nradial_mm = [1, 2, 3]\nmarks = [[1, 2], [3, 4, 5]]"), Some(("distortion.marks[2]".into(), 3, 2)));
    }
}
