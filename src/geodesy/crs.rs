//! A coordinate reference system as users write it: an EPSG code (also
//! compound, `EPSG:32631+5773`), an OGC URN or URI, a PROJ string, WKT1,
//! WKT2 or ESRI WKT, or a `.prj` file holding one. Each becomes the PROJ
//! definition `proj4rs` works from, with its EPSG code when it has one, and
//! its vertical part when one is named.

use super::datum;
use super::vertical::Vertical;
use proj4rs::Proj;
use std::path::Path;
use std::sync::Arc;

/// A horizontal CRS (with its vertical part, if named). Cheap to clone.
#[derive(Clone, Debug)]
pub struct Crs {
    def: Arc<Definition>,
}

#[derive(Debug)]
struct Definition {
    /// How to name the horizontal part to a user: `EPSG:32631`, or the
    /// PROJ string, or the WKT's name.
    label: String,
    epsg: Option<u32>,
    proj4: String,
    geographic: bool,
    vertical: Option<Vertical>,
    /// The datum named without a shift to WGS84 this build knows.
    unknown_datum: Option<String>,
}

/// What is read, for refusals.
pub const ACCEPTED: &str =
    "EPSG:<code> (EPSG:<code>+<vertical code> for a compound CRS), ESRI:<code>, an OGC URN or URI, a PROJ string (+proj=…), WKT1, WKT2 or ESRI WKT, or a .prj file";

impl PartialEq for Crs {
    /// The same CRS: the same EPSG code, or the same PROJ definition.
    fn eq(&self, other: &Crs) -> bool {
        match (self.def.epsg, other.def.epsg) {
            (Some(a), Some(b)) => a == b,
            _ => same_tokens(&self.def.proj4, &other.def.proj4),
        }
    }
}

impl serde::Serialize for Crs {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// An optional CRS as its [`Crs::definition`], for settings that are read
/// back: `#[serde(with = "crate::geodesy::optional_crs_definition")]`.
pub mod optional_definition {
    use super::Crs;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(crs: &Option<Crs>, s: S) -> Result<S::Ok, S::Error> {
        match crs {
            Some(c) => s.serialize_some(&c.definition()),
            None => s.serialize_none(),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Crs>, D::Error> {
        match Option::<String>::deserialize(d)? {
            Some(t) => Crs::parse(&t, std::path::Path::new("")).map(Some).map_err(serde::de::Error::custom),
            None => Ok(None),
        }
    }
}

impl std::fmt::Display for Crs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match (self.def.epsg, &self.def.vertical) {
            (Some(h), Some(Vertical { epsg: Some(v), .. })) => write!(f, "EPSG:{h}+{v}"),
            (_, Some(v)) => write!(f, "{} + {v}", self.def.label),
            (_, None) => f.write_str(&self.def.label),
        }
    }
}

impl Crs {
    /// WGS84 longitude/latitude, EPSG:4326.
    pub fn wgs84() -> Crs {
        Crs::from_epsg(4326).expect("EPSG:4326 is known")
    }

    /// The CRS of an EPSG code, or why it cannot be used.
    pub fn from_epsg(code: u32) -> Result<Crs, String> {
        let def = u16::try_from(code).ok().and_then(crs_definitions::from_code);
        let Some(def) = def else {
            if Vertical::is_known(code) {
                return Err(format!("EPSG:{code} is a vertical CRS: give a horizontal one (EPSG:<code>+{code} for both)"));
            }
            return Err(format!("EPSG:{code} is not a CRS this build knows"));
        };
        if def.wkt.starts_with("VERT") {
            return Err(format!("EPSG:{code} is a vertical CRS: give a horizontal one (EPSG:<code>+{code} for both)"));
        }
        Crs::from_definition(def.proj4, Some(code))
    }

    /// Reads a CRS from text in any of the [`ACCEPTED`] forms. A relative
    /// `.prj` path is taken from `dir`.
    pub fn parse(text: &str, dir: &Path) -> Result<Crs, String> {
        let t = text.trim();
        if t.is_empty() {
            return Err(format!("an empty CRS: give {ACCEPTED}"));
        }
        if looks_like_file(t) {
            let path = dir.join(t);
            let inner = crate::io::bounded_read::read_text_bounded(&path, "CRS file", 1 << 20).map_err(|e| e.to_string())?;
            crate::io::overwrite::note_read("CRS file", &path);
            return Crs::parse_text(inner.trim_start_matches('\u{feff}').trim(), false).map_err(|m| format!("{}: {m}", path.display()));
        }
        Crs::parse_text(t, true)
    }

    /// A CRS from its text; `show` quotes the text in the refusal (what the
    /// user typed, never what a file holds: it may be no CRS file at all).
    fn parse_text(t: &str, show: bool) -> Result<Crs, String> {
        if t.starts_with('+') {
            return Crs::from_proj4(t);
        }
        if t.contains('[') {
            return Crs::from_wkt(t);
        }
        if let Some(rest) = t.strip_prefix("ESRI:").or_else(|| t.strip_prefix("esri:")) {
            return Crs::from_esri(rest);
        }
        if let Some((h, v)) = codes(t)? {
            let mut crs = Crs::from_epsg(h)?;
            if let Some(v) = v {
                let vertical = Vertical::from_epsg(v)?;
                Arc::get_mut(&mut crs.def).expect("just made").vertical = Some(vertical);
            }
            return Ok(crs);
        }
        if !show {
            return Err(format!("not a CRS: a CRS file holds {ACCEPTED}"));
        }
        let shown: String = t.chars().take(60).collect();
        Err(format!("'{shown}' is not a CRS: give {ACCEPTED}"))
    }

    /// An ESRI code's CRS, from the table of PROJ's database: its datum's
    /// shift taken by the datum's name where the definition has none.
    fn from_esri(code: &str) -> Result<Crs, String> {
        let n: u32 = code.trim().parse().map_err(|_| format!("ESRI:{code}: '{code}' is not an ESRI code"))?;
        let e = super::esri::lookup(n).ok_or_else(|| format!("ESRI:{n} is not a horizontal CRS in this build's table of ESRI codes (from PROJ's database)"))?;
        let mut proj4 = e.proj4.clone();
        if !names_datum_shift(&proj4) {
            if let Some(s) = datum::shift_of(Some(&e.datum), None) {
                proj4.push_str(&format!(" {s}"));
            }
        }
        let mut crs = Crs::from_definition(&proj4, None).map_err(|m| format!("ESRI:{n}: {m}"))?;
        let d = Arc::get_mut(&mut crs.def).expect("just made");
        d.label = format!("ESRI:{n} ({})", e.name);
        if d.unknown_datum.is_some() {
            d.unknown_datum = Some(e.datum);
        }
        Ok(crs)
    }

    /// A PROJ string (`+proj=…`). It keeps the EPSG code of the definition
    /// it spells out, where this build has one spelled the same.
    pub fn from_proj4(s: &str) -> Result<Crs, String> {
        let s = s.trim();
        Crs::from_definition(s, datum::identify(s))
    }

    /// A PROJ definition with its EPSG code, if known. (Looking the code
    /// up reads every EPSG definition: done only for users' PROJ strings.)
    fn from_definition(s: &str, epsg: Option<u32>) -> Result<Crs, String> {
        check_parameters(s)?;
        super::grid_shift::load_for(s).map_err(|m| match epsg {
            Some(c) => format!("EPSG:{c}: {m}"),
            None => m,
        })?;
        let proj = Proj::from_proj_string(s).map_err(|e| format!("'{s}': {e}"))?;
        let vertical = Vertical::from_proj4(s);
        let datum_given = names_datum_shift(s);
        let (a, b) = proj.ellipse_parameters();
        let unknown_datum = (!datum_given && !datum::is_wgs84_compatible(a, b)).then(|| format!("ellipsoid a = {a} m"));
        Ok(Crs {
            def: Arc::new(Definition {
                label: epsg.map_or_else(|| s.to_string(), |c| format!("EPSG:{c}")),
                epsg,
                proj4: s.to_string(),
                geographic: proj.is_latlong(),
                vertical,
                unknown_datum,
            }),
        })
    }

    /// WKT1 (OGC or GDAL's), WKT2 or ESRI WKT, compound too. A definition
    /// whose EPSG code this build knows is taken from the code (the WKT GDAL
    /// writes leaves out the datum shift the code's definition carries);
    /// another whose datum has no shift in the WKT takes the shift of the
    /// datum of that name or code.
    pub fn from_wkt(text: &str) -> Result<Crs, String> {
        let tree = super::wkt::parse(text)?;
        let horizontal = tree.horizontal().ok_or_else(|| format!("the WKT '{}' holds no horizontal CRS (PROJCS, GEOGCS or their WKT2 names)", tree.key))?;
        let vertical = match tree.vertical() {
            Some(v) => Some(Vertical::from_wkt(v)?),
            None => None,
        };
        let name = horizontal.name().unwrap_or("unnamed").to_string();
        let from_code = horizontal.epsg().and_then(|c| Crs::from_epsg(c).ok());
        let mut crs = match from_code {
            Some(c) => c,
            None => {
                let mut proj4 = proj4wkt::wkt_to_projstring(text).map_err(|e| format!("the WKT of '{name}': {e}"))?;
                let mut unknown = None;
                if !proj4.contains("+towgs84=") && !proj4.contains("+datum=") {
                    let d = horizontal.datum();
                    match d.and_then(|d| datum::shift_of(d.name(), d.epsg())) {
                        Some(shift) => proj4.push_str(&format!(" {shift}")),
                        None => unknown = Some(d.and_then(|d| d.name()).unwrap_or("unnamed").to_string()),
                    }
                }
                let mut crs = Crs::from_proj4(&proj4)?;
                let d = Arc::get_mut(&mut crs.def).expect("just made");
                d.unknown_datum = unknown;
                if d.epsg.is_none() {
                    d.label = format!("'{name}' ({proj4})");
                }
                crs
            }
        };
        Arc::get_mut(&mut crs.def).expect("just made").vertical = vertical;
        Ok(crs)
    }

    /// This CRS with another vertical part.
    pub fn with_vertical(&self, vertical: Option<Vertical>) -> Crs {
        let d = Definition {
            label: self.def.label.clone(),
            epsg: self.def.epsg,
            proj4: self.def.proj4.clone(),
            geographic: self.def.geographic,
            vertical,
            unknown_datum: self.def.unknown_datum.clone(),
        };
        Crs { def: Arc::new(d) }
    }

    /// Text that [`Crs::parse`] reads back as this CRS: `EPSG:h` (with
    /// `+v`, its vertical code) where it has a code, else its PROJ string.
    pub fn definition(&self) -> String {
        match (self.def.epsg, &self.def.vertical) {
            (Some(h), Some(Vertical { epsg: Some(v), .. })) => format!("EPSG:{h}+{v}"),
            (Some(h), _) => format!("EPSG:{h}"),
            (None, _) => self.def.proj4.clone(),
        }
    }

    pub fn epsg(&self) -> Option<u32> {
        self.def.epsg
    }

    pub fn proj4(&self) -> &str {
        &self.def.proj4
    }

    /// Longitude/latitude in degrees (X, Y), not a projection.
    pub fn is_geographic(&self) -> bool {
        self.def.geographic
    }

    pub fn vertical(&self) -> Option<&Vertical> {
        self.def.vertical.as_ref()
    }

    /// The datum's name where it is neither WGS84-compatible nor given a
    /// shift to WGS84: converting to another CRS may then be off by up to
    /// hundreds of metres.
    pub fn unknown_datum(&self) -> Option<&str> {
        self.def.unknown_datum.as_deref()
    }

    /// Whether `other` gives the point (x, y) of this CRS the same place
    /// (within a millimetre): the same CRS spelled another way, there.
    pub fn agrees_at(&self, other: &Crs, x: f64, y: f64) -> bool {
        if self == other {
            return true;
        }
        let (Ok(a), Ok(b)) = (super::GroundCrs::new(self), super::GroundCrs::new(other)) else { return false };
        let back = a.to_lonlat(x, y).and_then(|(lon, lat)| b.lonlat_to_ground(lon, lat));
        let tolerance = if self.is_geographic() { 1e-8 } else { 1e-3 };
        back.is_some_and(|(u, v)| (u - x).abs() < tolerance && (v - y).abs() < tolerance)
    }

    /// The `proj4rs` projection of this CRS.
    pub fn proj(&self) -> Result<Proj, String> {
        Proj::from_proj_string(&self.def.proj4).map_err(|e| format!("{}: {e}", self.def.label))
    }
}

/// Whether a PROJ definition says how its datum goes to WGS84.
fn names_datum_shift(s: &str) -> bool {
    ["+towgs84=", "+datum=", "+nadgrids="].iter().any(|k| s.contains(k))
}

/// A path rather than a definition: a file name ending in .prj or .wkt, or
/// anything with a path separator that is not a URN, URI or definition.
fn looks_like_file(t: &str) -> bool {
    let lower = t.to_ascii_lowercase();
    if t.starts_with('+') || t.contains('[') || lower.starts_with("http") || lower.starts_with("urn:") {
        return false;
    }
    lower.ends_with(".prj") || lower.ends_with(".wkt") || t.contains('/') || t.contains('\\')
}

/// EPSG codes written as `EPSG:h`, `EPSG:h+v`, a bare number, an OGC URN
/// (`urn:ogc:def:crs:EPSG::h`, compound `urn:ogc:def:crs,crs:EPSG::h,crs:EPSG::v`),
/// an OGC URI (`http://www.opengis.net/def/crs/EPSG/0/h`) or OGC's CRS84.
/// `None` when `t` is none of these.
fn codes(t: &str) -> Result<Option<(u32, Option<u32>)>, String> {
    let lower = t.to_ascii_lowercase();
    let number =
        |s: &str| -> Result<u32, String> { s.trim().parse::<u32>().ok().filter(|&c| c > 0).ok_or_else(|| format!("'{t}': '{s}' is not an EPSG code")) };
    if matches!(lower.as_str(), "ogc:crs84" | "crs:84" | "crs84" | "urn:ogc:def:crs:ogc:1.3:crs84" | "http://www.opengis.net/def/crs/ogc/1.3/crs84" | "wgs84") {
        return Ok(Some((4326, None)));
    }
    if let Some(rest) = lower.strip_prefix("epsg:") {
        let (h, v) = match rest.split_once('+') {
            Some((h, v)) => (number(h)?, Some(number(v)?)),
            None => (number(rest)?, None),
        };
        return Ok(Some((h, v)));
    }
    if let Some(rest) = lower.strip_prefix("urn:ogc:def:crs,") {
        let parts: Vec<u32> = rest.split(',').map(|p| urn_code(p.strip_prefix("crs:").unwrap_or(p), t)).collect::<Result<_, _>>()?;
        return match parts.as_slice() {
            [h, v] => Ok(Some((*h, Some(*v)))),
            _ => Err(format!("'{t}': a compound URN of two EPSG codes is read")),
        };
    }
    if let Some(rest) = lower.strip_prefix("urn:ogc:def:crs:") {
        return Ok(Some((urn_code(rest, t)?, None)));
    }
    for prefix in ["http://www.opengis.net/def/crs/epsg/", "https://www.opengis.net/def/crs/epsg/"] {
        if let Some(rest) = lower.strip_prefix(prefix) {
            let code = rest.rsplit('/').next().unwrap_or("");
            return Ok(Some((number(code)?, None)));
        }
    }
    if t.chars().all(|c| c.is_ascii_digit()) {
        return Ok(Some((number(t)?, None)));
    }
    Ok(None)
}

/// `EPSG:<version>:<code>` of an OGC URN.
fn urn_code(rest: &str, whole: &str) -> Result<u32, String> {
    let mut parts = rest.split(':');
    let authority = parts.next().unwrap_or("");
    let code = parts.next_back().unwrap_or("");
    if !authority.eq_ignore_ascii_case("epsg") {
        return Err(format!("'{whole}': only EPSG codes are read in URNs"));
    }
    code.parse::<u32>().map_err(|_| format!("'{whole}': '{code}' is not an EPSG code"))
}

/// The same PROJ definition, whatever the order of its parameters.
pub(super) fn same_tokens(a: &str, b: &str) -> bool {
    proj_tokens(a) == proj_tokens(b)
}

/// A PROJ string's parameters, sorted, without those that do not change
/// the definition.
pub(super) fn proj_tokens(s: &str) -> Vec<&str> {
    let mut t: Vec<&str> = s.split_whitespace().filter(|t| !matches!(*t, "+no_defs" | "+type=crs" | "+wktext")).collect();
    t.sort_unstable();
    t
}

/// Refuses a PROJ string's numeric parameter out of its range (a
/// longitude of 1e300, a scale factor of 0): PROJ would build the
/// projection, and every point would then fall nowhere, blamed on the DEM.
fn check_parameters(s: &str) -> Result<(), String> {
    for token in s.split_whitespace() {
        let Some((key, value)) = token.trim_start_matches('+').split_once('=') else { continue };
        let range: Option<(f64, f64, &str)> = match key {
            "lon_0" | "lonc" | "lon_1" | "lon_2" | "pm" => Some((-360.0, 360.0, "a longitude, degrees")),
            "lat_0" | "lat_1" | "lat_2" | "lat_ts" => Some((-90.0, 90.0, "a latitude, degrees")),
            "k" | "k_0" => Some((1e-3, 1e3, "a scale factor (near 1)")),
            "x_0" | "y_0" => Some((-1e9, 1e9, "a false easting or northing, metres")),
            "a" | "b" | "R" => Some((1.0, 1e9, "an ellipsoid's axis, metres")),
            "rf" => Some((1.0, 1e12, "an inverse flattening")),
            "alpha" | "gamma" => Some((-360.0, 360.0, "an angle, degrees")),
            _ => None,
        };
        let Some((lo, hi, what)) = range else { continue };
        // (Degrees may be written as PROJ's DMS, e.g. 3d30'E: left to PROJ.)
        let Ok(v) = value.parse::<f64>() else { continue };
        if !(lo..=hi).contains(&v) {
            return Err(format!("+{key}={value} in '{s}' is out of range for {what} ({lo} to {hi})"));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Crs {
        Crs::parse(s, Path::new(".")).unwrap_or_else(|e| panic!("{s}: {e}"))
    }

    #[test]
    fn codes_in_every_spelling() {
        for s in [
            "EPSG:32631",
            "epsg:32631",
            "32631",
            "urn:ogc:def:crs:EPSG::32631",
            "urn:ogc:def:crs:EPSG:9.8.1:32631",
            "http://www.opengis.net/def/crs/EPSG/0/32631",
        ] {
            assert_eq!(parse(s).epsg(), Some(32631), "{s}");
        }
        let c = parse("EPSG:32631+5773");
        assert_eq!(c.epsg(), Some(32631));
        assert_eq!(c.vertical().and_then(|v| v.epsg), Some(5773));
        assert_eq!(c.to_string(), "EPSG:32631+5773");
        let u = parse("urn:ogc:def:crs,crs:EPSG::32631,crs:EPSG::3855");
        assert_eq!(u.vertical().and_then(|v| v.epsg), Some(3855));
        assert_eq!(parse("OGC:CRS84").epsg(), Some(4326));
    }

    #[test]
    fn proj_strings_keep_the_code_they_spell() {
        let utm = parse("+proj=utm +zone=31 +datum=WGS84 +units=m +no_defs");
        assert_eq!(utm.epsg(), Some(32631));
        let ngi = parse("+proj=tmerc +lon_0=25 +k=1 +x_0=0 +datum=WGS84");
        assert_eq!(ngi.epsg(), None);
        assert!(!ngi.is_geographic());
        assert_eq!(ngi.to_string(), "+proj=tmerc +lon_0=25 +k=1 +x_0=0 +datum=WGS84");
    }

    #[test]
    fn refusals_say_what_is_read() {
        for (s, want) in [
            ("EPSG:999999", "not a CRS this build knows"),
            ("ESRI:999999", "table of ESRI codes"),
            ("ESRI:abc", "not an ESRI code"),
            ("UTM31", "is not a CRS: give EPSG"),
            ("", "empty"),
            ("EPSG:5773", "vertical"),
        ] {
            let e = Crs::parse(s, Path::new(".")).unwrap_err();
            assert!(e.contains(want), "{s}: {e}");
        }
    }

    #[test]
    fn wkt_with_a_code_takes_the_codes_datum_shift() {
        // GDAL's WKT1 of EPSG:27700 has no TOWGS84; the code's definition has.
        let wkt = r#"PROJCS["OSGB36 / British National Grid",GEOGCS["OSGB36",DATUM["Ordnance_Survey_of_Great_Britain_1936",SPHEROID["Airy 1830",6377563.396,299.3249646,AUTHORITY["EPSG","7001"]],AUTHORITY["EPSG","6277"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AUTHORITY["EPSG","4277"]],PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",49],PARAMETER["central_meridian",-2],PARAMETER["scale_factor",0.9996012717],PARAMETER["false_easting",400000],PARAMETER["false_northing",-100000],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AXIS["Northing",NORTH],AUTHORITY["EPSG","27700"]]"#;
        let c = parse(wkt);
        assert_eq!(c.epsg(), Some(27700));
        assert!(c.proj4().contains("OSGB36") || c.proj4().contains("towgs84"), "{}", c.proj4());
    }

    #[test]
    fn esri_wkt_without_codes_finds_its_datum_by_name() {
        let esri = r#"PROJCS["British_National_Grid",GEOGCS["GCS_OSGB_1936",DATUM["D_OSGB_1936",SPHEROID["Airy_1830",6377563.396,299.3249646]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["False_Easting",400000.0],PARAMETER["False_Northing",-100000.0],PARAMETER["Central_Meridian",-2.0],PARAMETER["Scale_Factor",0.9996012717],PARAMETER["Latitude_Of_Origin",49.0],UNIT["Meter",1.0]]"#;
        let c = parse(esri);
        assert!(c.unknown_datum().is_none(), "{}", c.proj4());
        assert!(c.proj4().contains("+towgs84=446.448"), "{}", c.proj4());
    }

    #[test]
    fn a_datum_without_a_known_shift_is_reported() {
        let wkt = r#"PROJCS["x",GEOGCS["g",DATUM["Nowhere_1900",SPHEROID["Odd",6378000,300]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],PARAMETER["central_meridian",10],PARAMETER["scale_factor",1],PARAMETER["false_easting",0],PARAMETER["false_northing",0],PARAMETER["latitude_of_origin",0],UNIT["metre",1]]"#;
        assert_eq!(parse(wkt).unknown_datum(), Some("Nowhere_1900"));
    }

    #[test]
    fn compound_wkt_keeps_its_vertical_part() {
        let wkt = r#"COMPD_CS["WGS 84 / UTM zone 31N + EGM96 height",PROJCS["WGS 84 / UTM zone 31N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AUTHORITY["EPSG","4326"]],PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",0],PARAMETER["central_meridian",3],PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",500000],PARAMETER["false_northing",0],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AXIS["Northing",NORTH],AUTHORITY["EPSG","32631"]],VERT_CS["EGM96 height",VERT_DATUM["EGM96 geoid",2005,AUTHORITY["EPSG","5171"]],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Gravity-related height",UP],AUTHORITY["EPSG","5773"]],AUTHORITY["EPSG","9705"]]"#;
        let c = parse(wkt);
        assert_eq!(c.epsg(), Some(32631));
        assert_eq!(c.vertical().and_then(|v| v.epsg), Some(5773));
    }

    #[test]
    fn a_prj_file_beside() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("block.prj"), "\u{feff}PROJCS[\"Lo25\",GEOGCS[\"GCS_WGS_1984\",DATUM[\"D_WGS_1984\",SPHEROID[\"WGS_1984\",6378137.0,298.257223563]],PRIMEM[\"Greenwich\",0.0],UNIT[\"Degree\",0.0174532925199433]],PROJECTION[\"Transverse_Mercator\"],PARAMETER[\"False_Easting\",0.0],PARAMETER[\"False_Northing\",0.0],PARAMETER[\"Central_Meridian\",25.0],PARAMETER[\"Scale_Factor\",1.0],PARAMETER[\"Latitude_Of_Origin\",0.0],UNIT[\"Meter\",1.0]]\n").unwrap();
        let c = Crs::parse("block.prj", dir.path()).unwrap();
        let ngi = parse("+proj=tmerc +lon_0=25 +k=1 +x_0=0 +datum=WGS84");
        let (p, q) = (c.proj().unwrap(), ngi.proj().unwrap());
        let wgs = Crs::wgs84().proj().unwrap();
        for (lon, lat) in [(18.4f64, -33.9f64), (28.0, -26.2)] {
            let mut a = (lon.to_radians(), lat.to_radians(), 0.0);
            let mut b = a;
            proj4rs::transform::transform(&wgs, &p, &mut a).unwrap();
            proj4rs::transform::transform(&wgs, &q, &mut b).unwrap();
            assert!((a.0 - b.0).abs() < 1e-6 && (a.1 - b.1).abs() < 1e-6);
        }
        assert!(Crs::parse("missing.prj", dir.path()).unwrap_err().contains("missing.prj"));
    }
}
