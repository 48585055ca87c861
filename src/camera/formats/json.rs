//! Camera and pose files in JSON, parsed to a tree without what no camera
//! needs. Most of a real OpenSfM `reconstruction.json` is its sparse
//! points (OpenDroneMap's of a few hundred images run to tens of MB): they
//! are skipped unread. Any other JSON is held as a tree only up to
//! [`MAX_ITEMS`] items.

use serde::de::IgnoredAny;
use serde_json::{Map, Value};

/// How many items (commas) a JSON object file may hold: its tree takes
/// some 80 bytes an item (a 14.6 MB text of 300,000 small objects peaked
/// at 342 MiB). An Orthority GeoJSON takes about twenty a photo.
pub const MAX_ITEMS: usize = 1_000_000;

/// Why a text could not be held as a tree.
#[derive(Debug)]
pub enum Problem {
    /// Not JSON at all: the parser's complaint.
    Syntax(String),
    /// JSON, but larger than any camera or pose file.
    TooLarge(String),
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Problem::Syntax(m) | Problem::TooLarge(m) => f.write_str(m),
        }
    }
}

/// One record of a reconstruction: the fields a camera is made of.
#[derive(serde::Deserialize)]
struct Record {
    cameras: Option<Value>,
    shots: Option<Value>,
    reference_lla: Option<Value>,
}

/// The tree of a camera or pose file's JSON text. A list is read as
/// OpenSfM records (`cameras`, `shots`, `reference_lla`; the rest skipped);
/// a list of anything else is valid JSON of no form read here: `Null`.
pub fn parse(text: &str) -> Result<Value, Problem> {
    let t = text.trim_start_matches('\u{feff}').trim_start();
    if t.starts_with('[') {
        return match serde_json::from_str::<Vec<Record>>(t) {
            Ok(records) => Ok(Value::Array(records.into_iter().map(Record::into_value).collect())),
            Err(e) if e.is_data() && serde_json::from_str::<IgnoredAny>(t).is_ok() => Ok(Value::Null),
            Err(e) => Err(Problem::Syntax(e.to_string())),
        };
    }
    let items = t.bytes().filter(|&b| b == b',').count();
    if items > MAX_ITEMS {
        return Err(Problem::TooLarge(format!("{items} items (commas): more than the {MAX_ITEMS} a camera or pose file could hold")));
    }
    serde_json::from_str(t).map_err(|e| Problem::Syntax(e.to_string()))
}

impl Record {
    fn into_value(self) -> Value {
        let mut m = Map::new();
        for (key, v) in [("cameras", self.cameras), ("shots", self.shots), ("reference_lla", self.reference_lla)] {
            if let Some(v) = v {
                m.insert(key.to_string(), v);
            }
        }
        Value::Object(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reconstruction_keeps_its_cameras_and_shots_and_drops_its_points() {
        let text = r#"[{"cameras": {"c": {"focal": 0.8}}, "shots": {"a.jpg": {"camera": "c"}},
            "points": {"1": {"coordinates": [1, 2, 3]}}, "reference_lla": {"latitude": 1}}, {"points": {}}]"#;
        let v = parse(text).unwrap();
        assert_eq!(v[0]["cameras"]["c"]["focal"], 0.8);
        assert_eq!(v[0]["shots"]["a.jpg"]["camera"], "c");
        assert_eq!(v[0]["reference_lla"]["latitude"], 1);
        assert!(v[0].get("points").is_none() && v[1].as_object().unwrap().is_empty());
    }

    #[test]
    fn other_json_is_a_tree_up_to_its_size_and_non_json_is_a_syntax_error() {
        assert!(matches!(parse("[1, 2]"), Ok(Value::Null)));
        assert_eq!(parse(r#"{"type": "FeatureCollection"}"#).unwrap()["type"], "FeatureCollection");
        assert!(matches!(parse("[camera]\nfocal = 1"), Err(Problem::Syntax(_))));
        assert!(matches!(parse("[1, 2"), Err(Problem::Syntax(_))));
        let big = format!("{{\"a\": [{}]}}", vec!["0"; MAX_ITEMS + 2].join(","));
        assert!(matches!(parse(&big), Err(Problem::TooLarge(m)) if m.contains("1000001 items")));
    }
}
