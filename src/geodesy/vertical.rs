//! The vertical part of a compound CRS: which heights a DEM holds. Heights
//! above a geoid (EGM96, EGM2008, national height systems) differ from the
//! ellipsoidal heights an RPC model expects by the geoid's undulation; the
//! grids PROJ uses for the common ones are named here, so that a DEM that
//! says it holds EGM96 heights gets its geoid without `--geoid`.

use std::path::PathBuf;

#[derive(Clone, Debug, PartialEq)]
pub struct Vertical {
    pub epsg: Option<u32>,
    pub name: String,
    /// Geoid grid files, in PROJ's names, any one of which gives this
    /// height's undulation.
    pub grids: Vec<String>,
}

/// Vertical CRSs by EPSG code: name, PROJ's geoid grids for them.
const KNOWN: &[(u32, &str, &[&str])] = &[
    (5773, "EGM96 height", &["egm96_15.gtx", "us_nga_egm96_15.tif"]),
    (3855, "EGM2008 height", &["egm08_25.gtx", "us_nga_egm08_25.tif"]),
    (5798, "EGM84 height", &["egm84-15.gtx", "us_nga_egm84_15.tif"]),
    (5703, "NAVD88 height", &["us_noaa_g2018u0.tif"]),
    (5701, "ODN height", &["uk_os_OSGM15_GB.tif"]),
    (5714, "MSL height", &[]),
    (5705, "Baltic 1977 height", &[]),
    (7837, "DHHN2016 height", &["de_bkg_gcg2016.tif"]),
    (5720, "NGF-IGN69 height", &["fr_ign_RAF18.tif"]),
    (9287, "NZVD2016 height", &["nz_linz_nzgeoid2016.tif"]),
    (5711, "AHD height", &["au_ga_AUSGeoid2020_20180201.tif"]),
];

/// Geographic 3D CRSs: as the vertical key of a GeoTIFF (as GDAL writes
/// `-a_srs EPSG:4979` for RPC work), heights above their ellipsoid.
const GEOGRAPHIC_3D: &[(u32, &str)] = &[
    (4979, "WGS 84"),
    (4327, "WGS 84 (geographic 3D)"),
    (4937, "ETRS89"),
    (4939, "GDA94"),
    (7843, "GDA2020"),
    (4959, "NZGD2000"),
    (6319, "NAD83(2011)"),
    (7912, "ITRF2014"),
    (9989, "ITRF2020"),
];

impl Vertical {
    /// The vertical CRS of an EPSG code. Codes not in the table are kept
    /// (with no grid named) unless they are a horizontal CRS; a geographic
    /// 3D CRS's are ellipsoidal heights.
    pub fn from_epsg(code: u32) -> Result<Vertical, String> {
        if let Some((c, name, grids)) = KNOWN.iter().find(|(c, ..)| *c == code) {
            return Ok(Vertical { epsg: Some(*c), name: name.to_string(), grids: grids.iter().map(|g| g.to_string()).collect() });
        }
        if let Some((c, name)) = GEOGRAPHIC_3D.iter().find(|(c, _)| *c == code) {
            return Ok(Vertical { epsg: Some(*c), name: format!("ellipsoidal heights ({name}, EPSG:{c})"), grids: Vec::new() });
        }
        if u16::try_from(code).ok().and_then(crs_definitions::from_code).is_some() {
            return Err(format!("EPSG:{code} is a horizontal CRS, not the vertical part of a compound one"));
        }
        Ok(Vertical { epsg: Some(code), name: format!("EPSG:{code}"), grids: Vec::new() })
    }

    /// Heights above the ellipsoid (a geographic 3D CRS's), as an RPC
    /// takes them: no geoid to apply.
    pub fn is_ellipsoidal(&self) -> bool {
        self.epsg.is_some_and(|code| GEOGRAPHIC_3D.iter().any(|(c, _)| *c == code))
    }

    /// The height system a name (a WKT's VERT_CS, a GeoTIFF's vertical
    /// citation, the vertical half of a compound CRS's name) says, as
    /// GDAL/PROJ identify it: the first word of one of [`KNOWN`]'s names
    /// among the name's words ("EGM2008 height", "EGM2008_Geoid", "WGS 84 +
    /// EGM96 height"); `None` for a name it does not hold.
    pub fn from_name(name: &str) -> Option<Vertical> {
        let words: Vec<String> = name.split(|c: char| !c.is_ascii_alphanumeric()).filter(|w| !w.is_empty()).map(str::to_ascii_lowercase).collect();
        let joined: String = words.concat();
        let (code, ..) = KNOWN.iter().find(|(_, known, _)| {
            let key: String =
                known.split_whitespace().next().unwrap_or("").chars().filter(char::is_ascii_alphanumeric).collect::<String>().to_ascii_lowercase();
            // A short key (AHD, ODN, MSL) only as a word of its own.
            words.contains(&key) || (key.len() >= 6 && joined.contains(&key))
        })?;
        Vertical::from_epsg(*code).ok()
    }

    /// The height system whose geoid a grid file gives, by the name PROJ
    /// gives that grid (a crop that keeps the name's start too:
    /// `egm96_15_ventoux.gtx`); `None` for a grid it does not know.
    pub fn of_grid_file(path: &std::path::Path) -> Option<Vertical> {
        let name = path.file_name()?.to_str()?.to_ascii_lowercase();
        let stem = |g: &str| g.rsplit_once('.').map_or(g, |(s, _)| s).to_string();
        let (code, ..) = KNOWN.iter().find(|(_, _, grids)| grids.iter().any(|g| name.starts_with(&stem(g))))?;
        Vertical::from_epsg(*code).ok()
    }

    /// Whether this code is a vertical CRS this build names.
    pub fn is_known(code: u32) -> bool {
        KNOWN.iter().any(|(c, ..)| *c == code)
    }

    /// The `+geoidgrids=` of a PROJ string.
    pub fn from_proj4(s: &str) -> Option<Vertical> {
        let grids = s.split_whitespace().find_map(|t| t.strip_prefix("+geoidgrids="))?;
        let grids: Vec<String> = grids.split(',').map(|g| g.trim_start_matches('@').to_string()).filter(|g| !g.is_empty()).collect();
        Some(Vertical { epsg: None, name: format!("heights above the geoid of {}", grids.join(" or ")), grids })
    }

    /// A WKT `VERT_CS` / `VERTCRS`: its code, or its name and any grid
    /// GDAL names in `EXTENSION["PROJ4_GRIDS", …]` or WKT2's `GEOIDMODEL`.
    pub fn from_wkt(node: &super::wkt::Node) -> Result<Vertical, String> {
        if let Some(code) = node.epsg() {
            return Vertical::from_epsg(code);
        }
        let name = node.name().unwrap_or("unnamed vertical CRS").to_string();
        // A user-defined vertical CRS named as a known one (no code, no grid).
        if node.find(&["EXTENSION", "GEOIDMODEL"]).is_none() {
            if let Some(known) = Vertical::from_name(&name) {
                return Ok(known);
            }
        }
        let mut grids = Vec::new();
        if let Some(ext) = node.find(&["EXTENSION"]) {
            if ext.name() == Some("PROJ4_GRIDS") {
                if let Some(super::wkt::Item::Text(g)) = ext.items.get(1) {
                    grids.extend(g.split(',').map(|s| s.trim_start_matches('@').to_string()));
                }
            }
        }
        if let Some(model) = node.find(&["GEOIDMODEL"]) {
            if let Some(code) = model.epsg() {
                if let Some((_, _, g)) = KNOWN.iter().find(|(c, ..)| *c == code) {
                    grids.extend(g.iter().map(|s| s.to_string()));
                }
            }
        }
        Ok(Vertical { epsg: None, name, grids })
    }

    /// The first of this height's geoid grids found where PROJ looks for
    /// its grids, in a format this build reads (`.gtx`, GeoTIFF).
    pub fn find_grid(&self) -> Option<PathBuf> {
        self.grids.iter().find_map(|g| super::proj_data::find_grid(g))
    }
}

impl std::fmt::Display for Vertical {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.epsg {
            Some(c) if self.name != format!("EPSG:{c}") => write!(f, "EPSG:{c} ({})", self.name),
            _ => f.write_str(&self.name),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Vertical;

    #[test]
    fn a_geoid_grid_names_its_height_system_by_its_file_name() {
        let code = |n: &str| Vertical::of_grid_file(std::path::Path::new(n)).and_then(|v| v.epsg);
        assert_eq!(code("/g/egm96_15.gtx"), Some(5773));
        assert_eq!(code("egm96_15_ventoux.gtx"), Some(5773));
        assert_eq!(code("us_nga_egm08_25.tif"), Some(3855));
        assert_eq!(code("my_geoid.gtx"), None);
    }

    #[test]
    fn a_height_system_is_told_by_its_name() {
        for (name, code) in [
            ("EGM2008 height", 3855),
            ("EGM2008_Geoid", 3855),
            ("WGS 84 / UTM zone 35S + EGM96 height", 5773),
            ("NGF-IGN69 height", 5720),
            ("AHD height", 5711),
        ] {
            assert_eq!(Vertical::from_name(name).and_then(|v| v.epsg), Some(code), "{name}");
        }
        for name in ["Lo29 height above sea", "London datum", "unnamed vertical CRS"] {
            assert!(Vertical::from_name(name).is_none(), "{name}");
        }
    }
}
