//! Datums by name and code, from the EPSG definitions of the
//! `crs-definitions` crate: the shift to WGS84 a WKT without TOWGS84 leaves
//! out, and the EPSG code a PROJ string spells out.

use super::crs::proj_tokens;
use std::sync::OnceLock;

/// A geographic CRS's datum: its name made comparable, its EPSG datum code,
/// and its PROJ shift parameter (`+towgs84=…` or `+datum=…`).
struct KnownDatum {
    name: String,
    code: Option<u32>,
    shift: String,
}

fn known_datums() -> &'static [KnownDatum] {
    static DATUMS: OnceLock<Vec<KnownDatum>> = OnceLock::new();
    DATUMS.get_or_init(|| {
        (4000u16..5000)
            .filter_map(crs_definitions::from_code)
            .filter(|d| d.wkt.starts_with("GEOGCS[") || d.wkt.starts_with("GEOGCRS["))
            .filter_map(|d| {
                let tree = super::wkt::parse(d.wkt).ok()?;
                let datum = tree.datum()?;
                // The WKT's TOWGS84 first: the PROJ string may name the
                // datum only (`+datum=OSGB36`).
                let towgs84 = datum.find(&["TOWGS84"]).map(|t| {
                    let v: Vec<&str> = t.items.iter().filter_map(|i| if let super::wkt::Item::Number(n) = i { Some(n.as_str()) } else { None }).collect();
                    format!("+towgs84={}", v.join(","))
                });
                let shift =
                    towgs84.or_else(|| d.proj4.split_whitespace().find(|t| t.starts_with("+towgs84=") || t.starts_with("+datum=")).map(str::to_string))?;
                Some(KnownDatum { name: comparable(datum.name()?), code: datum.epsg(), shift })
            })
            .collect()
    })
}

/// A datum name without case, punctuation or ESRI's `D_` prefix:
/// `D_OSGB_1936` and `OSGB_1936` are one datum.
fn comparable(name: &str) -> String {
    let lower = name.to_ascii_lowercase();
    let bare = lower.strip_prefix("d_").unwrap_or(&lower);
    bare.chars().filter(|c| c.is_ascii_alphanumeric()).collect()
}

/// The PROJ shift parameter of a datum known by EPSG datum code or name.
pub fn shift_of(name: Option<&str>, code: Option<u32>) -> Option<String> {
    let known = known_datums();
    if let Some(c) = code {
        if let Some(d) = known.iter().find(|d| d.code == Some(c)) {
            return Some(d.shift.clone());
        }
    }
    let n = comparable(name?);
    known.iter().find(|d| d.name == n).map(|d| d.shift.clone())
}

/// WGS84's or GRS80's ellipsoid: datums on it (WGS84, ETRS89, NAD83,
/// GDA, …) are taken as WGS84 without a shift, as PROJ's ballpark does.
pub fn is_wgs84_compatible(a: f64, b: f64) -> bool {
    (a - 6_378_137.0).abs() < 1e-3 && [6_356_752.314_245, 6_356_752.314_140].iter().any(|w| (b - w).abs() < 1e-3)
}

/// The EPSG code whose definition is this PROJ string, parameter for
/// parameter (`+proj=utm +zone=31 +datum=WGS84 +units=m` is EPSG:32631).
pub fn identify(proj4: &str) -> Option<u32> {
    static INDEX: OnceLock<Vec<(u16, &'static str)>> = OnceLock::new();
    let index = INDEX.get_or_init(|| (1024u16..=u16::MAX).filter_map(crs_definitions::from_code).map(|d| (d.code, d.proj4)).collect());
    let want = proj_tokens(proj4);
    let proj = want.iter().find(|t| t.starts_with("+proj="))?;
    index.iter().find(|(_, p)| p.contains(proj) && proj_tokens(p) == want).map(|(c, _)| u32::from(*c))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn datums_by_name_and_code() {
        assert!(shift_of(Some("D_OSGB_1936"), None).unwrap().contains("446.448"));
        assert!(shift_of(None, Some(6277)).unwrap().contains("446.448"));
        assert!(shift_of(Some("Deutsches_Hauptdreiecksnetz"), None).is_some());
        assert_eq!(shift_of(Some("No such datum"), None), None);
    }

    #[test]
    fn codes_from_proj_strings() {
        assert_eq!(identify("+proj=utm +zone=31 +datum=WGS84 +units=m +no_defs"), Some(32631));
        assert_eq!(identify("+units=m +datum=WGS84 +zone=33 +proj=utm"), Some(32633));
        assert_eq!(identify("+proj=tmerc +lon_0=25 +k=1 +x_0=0 +datum=WGS84"), None);
    }
}
