//! A CRS as GeoTIFF keys and back: EPSG codes where there is one, else the
//! user-defined keys of GeoTIFF 1.1 (the projection method and its
//! parameters, the ellipsoid, GDAL's TOWGS84 key), written so that GDAL
//! reads back the same CRS; read as GDAL writes them, and GDAL's
//! `ESRI PE String` citations.

use super::crs::Crs;
use super::vertical::Vertical;
use crate::io::geotiff::{GeoKeyValue, GeoKeys};

const MODEL_TYPE: u16 = 1024;
const CITATION: u16 = 1026;
const GEOGRAPHIC_TYPE: u16 = 2048;
const GEOG_CITATION: u16 = 2049;
const GEOG_DATUM: u16 = 2050;
const GEOG_ANGULAR_UNITS: u16 = 2054;
const GEOG_ELLIPSOID: u16 = 2056;
const GEOG_SEMI_MAJOR: u16 = 2057;
const GEOG_SEMI_MINOR: u16 = 2058;
const GEOG_INV_FLATTENING: u16 = 2059;
const GEOG_PRIME_MERIDIAN_LONG: u16 = 2061;
/// GDAL's key for a datum shift to WGS84 (3 or 7 parameters).
const GEOG_TOWGS84: u16 = 2062;
const PROJECTED_TYPE: u16 = 3072;
const PCS_CITATION: u16 = 3073;
const PROJECTION: u16 = 3074;
const COORD_TRANS: u16 = 3075;
const LINEAR_UNITS: u16 = 3076;
const LINEAR_UNIT_SIZE: u16 = 3077;
const STD_PARALLEL_1: u16 = 3078;
const STD_PARALLEL_2: u16 = 3079;
const NAT_ORIGIN_LONG: u16 = 3080;
const NAT_ORIGIN_LAT: u16 = 3081;
const FALSE_EASTING: u16 = 3082;
const FALSE_NORTHING: u16 = 3083;
const FALSE_ORIGIN_LONG: u16 = 3084;
const FALSE_ORIGIN_LAT: u16 = 3085;
const FALSE_ORIGIN_EASTING: u16 = 3086;
const FALSE_ORIGIN_NORTHING: u16 = 3087;
const CENTER_LONG: u16 = 3088;
const CENTER_LAT: u16 = 3089;
const SCALE_AT_NAT_ORIGIN: u16 = 3092;
const SCALE_AT_CENTER: u16 = 3093;
const AZIMUTH: u16 = 3094;
const STRAIGHT_VERT_POLE_LONG: u16 = 3095;
const RECTIFIED_GRID_ANGLE: u16 = 3096;
const VERTICAL_TYPE: u16 = 4096;
const VERTICAL_CITATION: u16 = 4097;
const VERTICAL_UNITS: u16 = 4099;

const USER_DEFINED: u16 = 32767;
const MODEL_PROJECTED: u16 = 1;
const MODEL_GEOGRAPHIC: u16 = 2;

/// GeoTIFF's coordinate transformation codes and the PROJ methods they
/// are.
const CT_TRANSVERSE_MERCATOR: u16 = 1;
const CT_OBLIQUE_MERCATOR: u16 = 3;
const CT_MERCATOR: u16 = 7;
const CT_LCC_2SP: u16 = 8;
const CT_LCC_1SP: u16 = 9;
const CT_LAEA: u16 = 10;
const CT_ALBERS: u16 = 11;
const CT_AZIMUTHAL_EQUIDISTANT: u16 = 12;
const CT_STEREOGRAPHIC: u16 = 14;
const CT_POLAR_STEREOGRAPHIC: u16 = 15;
const CT_OBLIQUE_STEREOGRAPHIC: u16 = 16;
const CT_EQUIRECTANGULAR: u16 = 17;
const CT_CASSINI: u16 = 18;
const CT_POLYCONIC: u16 = 22;
const CT_SINUSOIDAL: u16 = 24;
const CT_EQUIDISTANT_CONIC: u16 = 13;
const CT_GNOMONIC: u16 = 19;
const CT_MILLER: u16 = 20;
const CT_ORTHOGRAPHIC: u16 = 21;
const CT_ROBINSON: u16 = 23;
const CT_CYLINDRICAL_EQUAL_AREA: u16 = 28;
/// Hotine oblique Mercator, variant B (the natural origin at the centre
/// of the projection; PROJ's `omerc` without `+no_uoff`).
const CT_HOTINE_AZIMUTH_CENTER: u16 = 9815;

/// The CRS the keys name; `None` when they name none (no keys, or only a
/// raster type). A CRS they name in a way this build cannot follow is an
/// error saying what was found.
pub fn crs_of(keys: &GeoKeys) -> Result<Option<Crs>, String> {
    let code = |id: u16| keys.short(id).filter(|&c| c != 0 && c != USER_DEFINED);
    let vertical = match code(VERTICAL_TYPE) {
        Some(v) => Some(Vertical::from_epsg(u32::from(v)).map_err(|m| format!("VerticalCSTypeGeoKey: {m}"))?),
        // User-defined: told by its citation, or the vertical half of the
        // compound CRS's ("… + EGM2008 height"), as GDAL writes them.
        None if keys.short(VERTICAL_TYPE) == Some(USER_DEFINED) => keys
            .ascii(VERTICAL_CITATION)
            .and_then(Vertical::from_name)
            .or_else(|| keys.ascii(CITATION).and_then(|c| c.rsplit_once(" + ")).and_then(|(_, v)| Vertical::from_name(v))),
        None => None,
    };
    let with_vertical = |c: Crs| if vertical.is_some() { c.with_vertical(vertical.clone()) } else { c };
    for citation in [PCS_CITATION, CITATION, GEOG_CITATION] {
        if let Some(wkt) = keys.ascii(citation).and_then(|t| t.strip_prefix("ESRI PE String = ")) {
            return Crs::from_wkt(wkt).map(|c| Some(with_vertical(c))).map_err(|m| format!("the ESRI PE String citation: {m}"));
        }
    }
    let model = keys.short(MODEL_TYPE);
    if let Some(c) = code(PROJECTED_TYPE) {
        return Crs::from_epsg(u32::from(c)).map(|c| Some(with_vertical(c))).map_err(|m| format!("ProjectedCSTypeGeoKey: {m}"));
    }
    let projected = model == Some(MODEL_PROJECTED) || keys.short(PROJECTED_TYPE) == Some(USER_DEFINED) || keys.get(COORD_TRANS).is_some();
    if !projected {
        if let Some(c) = code(GEOGRAPHIC_TYPE) {
            return Crs::from_epsg(u32::from(c)).map(|c| Some(with_vertical(c))).map_err(|m| format!("GeographicTypeGeoKey: {m}"));
        }
        if model != Some(MODEL_GEOGRAPHIC) {
            return match model {
                Some(m) if m != 0 => Err(format!("GTModelTypeGeoKey {m} (neither projected nor geographic) is not read")),
                _ => Ok(None),
            };
        }
        let proj4 = format!("+proj=longlat {}", datum_of(keys)?);
        return Crs::from_proj4(&proj4).map(|c| Some(with_vertical(c)));
    }
    let method = projection_of(keys)?;
    let proj4 = format!("{method} {} {}", datum_of(keys)?, units_of(keys)?);
    Crs::from_proj4(proj4.trim()).map(|c| Some(with_vertical(c)))
}

/// The datum part of a PROJ string: from the geographic CRS's code, or
/// the user-defined datum, ellipsoid and GDAL's TOWGS84 key.
fn datum_of(keys: &GeoKeys) -> Result<String, String> {
    let code = |id: u16| keys.short(id).filter(|&c| c != 0 && c != USER_DEFINED);
    if let Some(g) = code(GEOGRAPHIC_TYPE) {
        let def = crs_definitions::from_code(g).ok_or_else(|| format!("GeographicTypeGeoKey: EPSG:{g} is not a CRS this build knows"))?;
        return Ok(def.proj4.split_whitespace().filter(|t| !t.starts_with("+proj=") && *t != "+no_defs").collect::<Vec<_>>().join(" "));
    }
    let mut out = match (keys.double(GEOG_SEMI_MAJOR), keys.double(GEOG_INV_FLATTENING), keys.double(GEOG_SEMI_MINOR)) {
        (Some(a), Some(rf), _) if rf > 0.0 => format!("+a={a} +rf={rf}"),
        (Some(a), _, Some(b)) => format!("+a={a} +b={b}"),
        (Some(a), _, _) => format!("+R={a}"),
        _ => match code(GEOG_ELLIPSOID) {
            Some(e) => format!("+ellps={}", ellipsoid_name(e).ok_or_else(|| format!("GeogEllipsoidGeoKey: ellipsoid EPSG:{e} is not one this build knows"))?),
            None => match code(GEOG_DATUM).and_then(|d| super::datum::shift_of(None, Some(u32::from(d)))) {
                Some(shift) if shift.starts_with("+datum=") => return Ok(shift),
                _ => return Err("the GeoTIFF keys name no geographic CRS, ellipsoid or datum".into()),
            },
        },
    };
    if let Some(t) = keys.doubles(GEOG_TOWGS84) {
        out.push_str(&format!(" +towgs84={}", t.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(",")));
    } else if let Some(shift) = code(GEOG_DATUM).and_then(|d| super::datum::shift_of(None, Some(u32::from(d)))) {
        if shift.starts_with("+towgs84=") {
            out.push_str(&format!(" {shift}"));
        }
    }
    if let Some(pm) = keys.double(GEOG_PRIME_MERIDIAN_LONG).filter(|&p| p != 0.0) {
        out.push_str(&format!(" +pm={pm}"));
    }
    Ok(out)
}

/// The common ellipsoids by EPSG code, as PROJ names them.
fn ellipsoid_name(code: u16) -> Option<&'static str> {
    Some(match code {
        7030 => "WGS84",
        7019 => "GRS80",
        7001 => "airy",
        7002 => "mod_airy",
        7004 => "bessel",
        7008 => "clrk66",
        7012 => "clrk80",
        7022 => "intl",
        7024 => "krass",
        7043 => "WGS72",
        _ => return None,
    })
}

/// The linear unit of a projected CRS.
fn units_of(keys: &GeoKeys) -> Result<String, String> {
    Ok(match keys.short(LINEAR_UNITS) {
        None | Some(9001) => "+units=m".into(),
        Some(9002) => "+units=ft".into(),
        Some(9003) => "+units=us-ft".into(),
        Some(9036) => "+units=km".into(),
        Some(USER_DEFINED) => {
            format!("+to_meter={}", keys.double(LINEAR_UNIT_SIZE).ok_or("ProjLinearUnitsGeoKey is user-defined without ProjLinearUnitSizeGeoKey")?)
        }
        Some(u) => return Err(format!("ProjLinearUnitsGeoKey {u} is not a unit this build knows")),
    })
}

/// The projection method and its parameters, from the Projection key (a
/// UTM zone) or the coordinate transformation and its parameter keys, as
/// GDAL reads them.
fn projection_of(keys: &GeoKeys) -> Result<String, String> {
    if let Some(p) = keys.short(PROJECTION).filter(|&p| p != USER_DEFINED) {
        return match p {
            16001..=16060 => Ok(format!("+proj=utm +zone={}", p - 16000)),
            16101..=16160 => Ok(format!("+proj=utm +zone={} +south", p - 16100)),
            _ => Err(format!("ProjectionGeoKey {p} is not a projection this build knows (UTM zones are)")),
        };
    }
    let ct = keys.short(COORD_TRANS).ok_or("a user-defined projected CRS without ProjCoordTransGeoKey")?;
    let v = |ids: &[u16]| ids.iter().find_map(|&id| keys.double(id)).unwrap_or(0.0);
    let fe = v(&[FALSE_EASTING, FALSE_ORIGIN_EASTING]);
    let fnorth = v(&[FALSE_NORTHING, FALSE_ORIGIN_NORTHING]);
    let k = || ids_or(keys, &[SCALE_AT_NAT_ORIGIN, SCALE_AT_CENTER], 1.0);
    let lon0 = v(&[NAT_ORIGIN_LONG, FALSE_ORIGIN_LONG, CENTER_LONG]);
    let lat0 = v(&[NAT_ORIGIN_LAT, FALSE_ORIGIN_LAT, CENTER_LAT]);
    let xy = format!("+x_0={fe} +y_0={fnorth}");
    Ok(match ct {
        CT_TRANSVERSE_MERCATOR => format!("+proj=tmerc +lat_0={lat0} +lon_0={lon0} +k={} {xy}", k()),
        CT_MERCATOR => match keys.double(STD_PARALLEL_1) {
            Some(ts) => format!("+proj=merc +lat_ts={ts} +lon_0={lon0} {xy}"),
            None => format!("+proj=merc +lon_0={lon0} +k={} {xy}", k()),
        },
        CT_LCC_2SP => format!("+proj=lcc +lat_1={} +lat_2={} +lat_0={lat0} +lon_0={lon0} {xy}", v(&[STD_PARALLEL_1]), v(&[STD_PARALLEL_2])),
        CT_LCC_1SP => format!("+proj=lcc +lat_1={lat0} +lat_0={lat0} +lon_0={lon0} +k_0={} {xy}", k()),
        CT_LAEA => format!("+proj=laea +lat_0={} +lon_0={} {xy}", v(&[CENTER_LAT, NAT_ORIGIN_LAT]), v(&[CENTER_LONG, NAT_ORIGIN_LONG])),
        CT_ALBERS => format!("+proj=aea +lat_1={} +lat_2={} +lat_0={lat0} +lon_0={lon0} {xy}", v(&[STD_PARALLEL_1]), v(&[STD_PARALLEL_2])),
        CT_AZIMUTHAL_EQUIDISTANT => format!("+proj=aeqd +lat_0={} +lon_0={} {xy}", v(&[CENTER_LAT, NAT_ORIGIN_LAT]), v(&[CENTER_LONG, NAT_ORIGIN_LONG])),
        CT_STEREOGRAPHIC => format!("+proj=stere +lat_0={} +lon_0={} +k={} {xy}", v(&[CENTER_LAT, NAT_ORIGIN_LAT]), v(&[CENTER_LONG, NAT_ORIGIN_LONG]), k()),
        CT_POLAR_STEREOGRAPHIC => {
            let lat_ts = v(&[NAT_ORIGIN_LAT]);
            let pole = if lat_ts < 0.0 { -90 } else { 90 };
            let lon = v(&[STRAIGHT_VERT_POLE_LONG, NAT_ORIGIN_LONG]);
            match keys.double(SCALE_AT_NAT_ORIGIN) {
                Some(k) if (lat_ts.abs() - 90.0).abs() < 1e-9 || k != 1.0 => format!("+proj=stere +lat_0={pole} +lon_0={lon} +k={k} {xy}"),
                _ => format!("+proj=stere +lat_0={pole} +lat_ts={lat_ts} +lon_0={lon} {xy}"),
            }
        }
        CT_OBLIQUE_STEREOGRAPHIC => format!("+proj=sterea +lat_0={lat0} +lon_0={lon0} +k={} {xy}", k()),
        CT_EQUIRECTANGULAR => format!("+proj=eqc +lat_ts={} +lat_0={lat0} +lon_0={lon0} {xy}", v(&[STD_PARALLEL_1])),
        CT_CASSINI => format!("+proj=cass +lat_0={lat0} +lon_0={lon0} {xy}"),
        CT_POLYCONIC => format!("+proj=poly +lat_0={lat0} +lon_0={lon0} {xy}"),
        CT_SINUSOIDAL => format!("+proj=sinu +lon_0={} {xy}", v(&[CENTER_LONG, NAT_ORIGIN_LONG])),
        // Variant A (GeoTIFF's CT 3) has its false origin at the natural
        // origin of the uv grid: PROJ's +no_uoff.
        CT_OBLIQUE_MERCATOR | CT_HOTINE_AZIMUTH_CENTER => {
            let alpha = v(&[AZIMUTH]);
            format!(
                "+proj=omerc{} +lat_0={} +lonc={} +alpha={alpha} +gamma={} +k={} {xy}",
                if ct == CT_OBLIQUE_MERCATOR { " +no_uoff" } else { "" },
                v(&[CENTER_LAT, NAT_ORIGIN_LAT]),
                v(&[CENTER_LONG, NAT_ORIGIN_LONG]),
                ids_or(keys, &[RECTIFIED_GRID_ANGLE], alpha),
                ids_or(keys, &[SCALE_AT_CENTER, SCALE_AT_NAT_ORIGIN], 1.0)
            )
        }
        CT_EQUIDISTANT_CONIC => format!("+proj=eqdc +lat_1={} +lat_2={} +lat_0={lat0} +lon_0={lon0} {xy}", v(&[STD_PARALLEL_1]), v(&[STD_PARALLEL_2])),
        CT_CYLINDRICAL_EQUAL_AREA => format!("+proj=cea +lat_ts={} +lon_0={lon0} {xy}", v(&[STD_PARALLEL_1])),
        CT_GNOMONIC | CT_ORTHOGRAPHIC | CT_MILLER => {
            let name = match ct {
                CT_GNOMONIC => "gnom",
                CT_ORTHOGRAPHIC => "ortho",
                _ => "mill",
            };
            format!("+proj={name} +lat_0={} +lon_0={} {xy}", v(&[CENTER_LAT, NAT_ORIGIN_LAT]), v(&[CENTER_LONG, NAT_ORIGIN_LONG]))
        }
        CT_ROBINSON => format!("+proj=robin +lon_0={} {xy}", v(&[CENTER_LONG, NAT_ORIGIN_LONG])),
        other => return Err(format!("ProjCoordTransGeoKey {other} is not a projection method this build reads")),
    })
}

fn ids_or(keys: &GeoKeys, ids: &[u16], default: f64) -> f64 {
    ids.iter().find_map(|&id| keys.double(id)).unwrap_or(default)
}

/// The GeoTIFF keys of a CRS: its EPSG code, or user-defined keys GDAL
/// reads back as the same CRS. A projection GeoTIFF has no keys for is an
/// error naming it.
pub fn keys_of(crs: &Crs) -> Result<GeoKeys, String> {
    let mut keys = GeoKeys::default();
    let short = |k: &mut GeoKeys, id, v| k.set(id, GeoKeyValue::Short(v));
    let geographic = crs.is_geographic();
    short(&mut keys, MODEL_TYPE, if geographic { MODEL_GEOGRAPHIC } else { MODEL_PROJECTED });
    if let Some(code) = crs.epsg().and_then(|c| u16::try_from(c).ok()).filter(|&c| c < USER_DEFINED) {
        short(&mut keys, if geographic { GEOGRAPHIC_TYPE } else { PROJECTED_TYPE }, code);
    } else {
        let tokens = Tokens::of(crs.proj4());
        user_defined_datum(&mut keys, crs, &tokens)?;
        if !geographic {
            user_defined_projection(&mut keys, &tokens, crs)?;
        }
        let citation = format!("{}", crs).chars().take(400).collect::<String>();
        keys.set(CITATION, GeoKeyValue::Ascii(citation));
    }
    if let Some(v) = crs.vertical().and_then(|v| v.epsg).and_then(|c| u16::try_from(c).ok()) {
        short(&mut keys, VERTICAL_TYPE, v);
        short(&mut keys, VERTICAL_UNITS, 9001);
    }
    Ok(keys)
}

#[cfg(any(test, feature = "internals"))]
/// The GeoTIFF keys of an EPSG code.
pub fn keys_of_epsg(code: u32) -> Result<GeoKeys, String> {
    keys_of(&Crs::from_epsg(code)?)
}

/// A PROJ string's `+key=value` parameters.
struct Tokens<'a>(Vec<(&'a str, &'a str)>);

impl<'a> Tokens<'a> {
    fn of(s: &'a str) -> Tokens<'a> {
        Tokens(s.split_whitespace().filter_map(|t| t.strip_prefix('+')).map(|t| t.split_once('=').unwrap_or((t, ""))).collect())
    }

    fn get(&self, k: &str) -> Option<&'a str> {
        self.0.iter().find(|(key, _)| *key == k).map(|(_, v)| *v)
    }

    fn num(&self, k: &str) -> Result<Option<f64>, String> {
        self.get(k).map(|v| v.parse::<f64>().map_err(|_| format!("+{k}={v} is not a number"))).transpose()
    }

    fn num_or(&self, k: &str, default: f64) -> Result<f64, String> {
        Ok(self.num(k)?.unwrap_or(default))
    }
}

/// The geographic part: WGS84's code where the datum is WGS84, the code
/// of the geographic CRS spelled the same, else ellipsoid and shift.
fn user_defined_datum(keys: &mut GeoKeys, crs: &Crs, t: &Tokens) -> Result<(), String> {
    let datum_part: Vec<String> =
        t.0.iter()
            .filter(|(k, _)| matches!(*k, "datum" | "ellps" | "towgs84" | "a" | "b" | "rf" | "R" | "f" | "pm"))
            .map(|(k, v)| format!("+{k}={v}"))
            .collect();
    let longlat = format!("+proj=longlat {} +no_defs", datum_part.join(" "));
    let wgs84 = t.get("datum") == Some("WGS84")
        || (t.get("ellps") == Some("WGS84") && t.get("towgs84").is_none_or(|s| s.split(',').all(|v| v.parse::<f64>() == Ok(0.0))));
    let code = if wgs84 { Some(4326) } else { super::datum::identify(&longlat) };
    if let Some(c) = code.and_then(|c| u16::try_from(c).ok()) {
        keys.set(GEOGRAPHIC_TYPE, GeoKeyValue::Short(c));
        return Ok(());
    }
    let (a, b) = crs.proj()?.ellipse_parameters();
    keys.set(GEOGRAPHIC_TYPE, GeoKeyValue::Short(USER_DEFINED));
    keys.set(GEOG_CITATION, GeoKeyValue::Ascii(longlat.clone()));
    keys.set(GEOG_DATUM, GeoKeyValue::Short(USER_DEFINED));
    keys.set(GEOG_ELLIPSOID, GeoKeyValue::Short(USER_DEFINED));
    keys.set(GEOG_ANGULAR_UNITS, GeoKeyValue::Short(9102));
    keys.set(GEOG_SEMI_MAJOR, GeoKeyValue::Doubles(vec![a]));
    if (a - b).abs() < 1e-9 {
        keys.set(GEOG_SEMI_MINOR, GeoKeyValue::Doubles(vec![b]));
    } else {
        keys.set(GEOG_INV_FLATTENING, GeoKeyValue::Doubles(vec![a / (a - b)]));
    }
    let towgs84 = match t.get("towgs84") {
        Some(s) => Some(s.to_string()),
        None => t.get("datum").and_then(|d| super::datum::shift_of(Some(d), None)).and_then(|s| s.strip_prefix("+towgs84=").map(str::to_string)),
    };
    if let Some(s) = towgs84 {
        let v: Vec<f64> = s.split(',').map(|x| x.parse::<f64>().map_err(|_| format!("+towgs84={s} is not a list of numbers"))).collect::<Result<_, _>>()?;
        keys.set(GEOG_TOWGS84, GeoKeyValue::Doubles(v));
    }
    Ok(())
}

/// The projection as GeoTIFF's coordinate transformation and parameters.
fn user_defined_projection(keys: &mut GeoKeys, t: &Tokens, crs: &Crs) -> Result<(), String> {
    let d = |k: &mut GeoKeys, id, v: f64| k.set(id, GeoKeyValue::Doubles(vec![v]));
    keys.set(PROJECTED_TYPE, GeoKeyValue::Short(USER_DEFINED));
    keys.set(PROJECTION, GeoKeyValue::Short(USER_DEFINED));
    keys.set(PCS_CITATION, GeoKeyValue::Ascii(crs.proj4().chars().take(400).collect()));
    let unit = match (t.get("units"), t.num("to_meter")?) {
        (_, Some(m)) if (m - 1.0).abs() > 1e-12 => {
            d(keys, LINEAR_UNIT_SIZE, m);
            USER_DEFINED
        }
        (None | Some("m"), _) => 9001,
        (Some("ft"), _) => 9002,
        (Some("us-ft"), _) => 9003,
        (Some("km"), _) => 9036,
        (Some(u), _) => return Err(format!("{crs}: the unit +units={u} has no GeoTIFF key this build writes")),
    };
    keys.set(LINEAR_UNITS, GeoKeyValue::Short(unit));
    let (x0, y0) = (t.num_or("x_0", 0.0)?, t.num_or("y_0", 0.0)?);
    let (lat0, lon0) = (t.num_or("lat_0", 0.0)?, t.num_or("lon_0", 0.0)?);
    let k = t.num("k")?.or(t.num("k_0")?).unwrap_or(1.0);
    let proj = t.get("proj").unwrap_or("");
    let natural = |keys: &mut GeoKeys, ct| {
        keys.set(COORD_TRANS, GeoKeyValue::Short(ct));
        d(keys, NAT_ORIGIN_LAT, lat0);
        d(keys, NAT_ORIGIN_LONG, lon0);
        d(keys, FALSE_EASTING, x0);
        d(keys, FALSE_NORTHING, y0);
    };
    // Methods GeoTIFF parametrises by their centre.
    let centred = |keys: &mut GeoKeys, ct| {
        keys.set(COORD_TRANS, GeoKeyValue::Short(ct));
        d(keys, CENTER_LAT, lat0);
        d(keys, CENTER_LONG, lon0);
        d(keys, FALSE_EASTING, x0);
        d(keys, FALSE_NORTHING, y0);
    };
    match proj {
        "utm" => {
            let zone: u16 = t.get("zone").and_then(|z| z.parse().ok()).filter(|z| (1..=60).contains(z)).ok_or_else(|| format!("{crs}: +proj=utm without a zone 1–60"))?;
            let south = t.0.iter().any(|(k, _)| *k == "south");
            natural(keys, CT_TRANSVERSE_MERCATOR);
            d(keys, NAT_ORIGIN_LAT, 0.0);
            d(keys, NAT_ORIGIN_LONG, f64::from(zone) * 6.0 - 183.0);
            d(keys, FALSE_EASTING, 500_000.0);
            d(keys, FALSE_NORTHING, if south { 10_000_000.0 } else { 0.0 });
            d(keys, SCALE_AT_NAT_ORIGIN, 0.9996);
        }
        "tmerc" | "etmerc" => {
            natural(keys, CT_TRANSVERSE_MERCATOR);
            d(keys, SCALE_AT_NAT_ORIGIN, k);
        }
        "sterea" => {
            natural(keys, CT_OBLIQUE_STEREOGRAPHIC);
            d(keys, SCALE_AT_NAT_ORIGIN, k);
        }
        "cass" => natural(keys, CT_CASSINI),
        "poly" => natural(keys, CT_POLYCONIC),
        "merc" => {
            natural(keys, CT_MERCATOR);
            match t.num("lat_ts")? {
                Some(ts) => d(keys, STD_PARALLEL_1, ts),
                None => d(keys, SCALE_AT_NAT_ORIGIN, k),
            }
        }
        "lcc" => {
            let lat1 = t.num_or("lat_1", lat0)?;
            match t.num("lat_2")? {
                Some(lat2) if (lat2 - lat1).abs() > 1e-12 => {
                    keys.set(COORD_TRANS, GeoKeyValue::Short(CT_LCC_2SP));
                    d(keys, STD_PARALLEL_1, lat1);
                    d(keys, STD_PARALLEL_2, lat2);
                    d(keys, FALSE_ORIGIN_LAT, lat0);
                    d(keys, FALSE_ORIGIN_LONG, lon0);
                    d(keys, FALSE_ORIGIN_EASTING, x0);
                    d(keys, FALSE_ORIGIN_NORTHING, y0);
                }
                _ => {
                    natural(keys, CT_LCC_1SP);
                    d(keys, NAT_ORIGIN_LAT, lat1);
                    d(keys, SCALE_AT_NAT_ORIGIN, k);
                }
            }
        }
        "aea" => {
            natural(keys, CT_ALBERS);
            d(keys, STD_PARALLEL_1, t.num_or("lat_1", 0.0)?);
            d(keys, STD_PARALLEL_2, t.num_or("lat_2", 0.0)?);
        }
        "laea" => centred(keys, CT_LAEA),
        "aeqd" => centred(keys, CT_AZIMUTHAL_EQUIDISTANT),
        "stere" if lat0.abs() == 90.0 => {
            keys.set(COORD_TRANS, GeoKeyValue::Short(CT_POLAR_STEREOGRAPHIC));
            match t.num("lat_ts")? {
                Some(ts) => d(keys, NAT_ORIGIN_LAT, ts),
                None => {
                    d(keys, NAT_ORIGIN_LAT, lat0);
                    d(keys, SCALE_AT_NAT_ORIGIN, k);
                }
            }
            d(keys, STRAIGHT_VERT_POLE_LONG, lon0);
            d(keys, FALSE_EASTING, x0);
            d(keys, FALSE_NORTHING, y0);
        }
        "stere" => {
            centred(keys, CT_STEREOGRAPHIC);
            d(keys, SCALE_AT_NAT_ORIGIN, k);
        }
        "eqc" => {
            natural(keys, CT_EQUIRECTANGULAR);
            d(keys, STD_PARALLEL_1, t.num_or("lat_ts", 0.0)?);
        }
        "sinu" | "robin" => {
            keys.set(COORD_TRANS, GeoKeyValue::Short(if proj == "sinu" { CT_SINUSOIDAL } else { CT_ROBINSON }));
            d(keys, CENTER_LONG, lon0);
            d(keys, FALSE_EASTING, x0);
            d(keys, FALSE_NORTHING, y0);
        }
        "gnom" => centred(keys, CT_GNOMONIC),
        "ortho" => centred(keys, CT_ORTHOGRAPHIC),
        "mill" => centred(keys, CT_MILLER),
        "eqdc" => {
            natural(keys, CT_EQUIDISTANT_CONIC);
            d(keys, STD_PARALLEL_1, t.num_or("lat_1", 0.0)?);
            d(keys, STD_PARALLEL_2, t.num_or("lat_2", t.num_or("lat_1", 0.0)?)?);
        }
        "cea" => {
            keys.set(COORD_TRANS, GeoKeyValue::Short(CT_CYLINDRICAL_EQUAL_AREA));
            d(keys, STD_PARALLEL_1, t.num_or("lat_ts", 0.0)?);
            d(keys, NAT_ORIGIN_LONG, lon0);
            d(keys, FALSE_EASTING, x0);
            d(keys, FALSE_NORTHING, y0);
        }
        "omerc" => {
            let no_uoff = t.0.iter().any(|(k, _)| matches!(*k, "no_uoff" | "no_off"));
            let alpha = t.num("alpha")?.ok_or_else(|| format!("{crs}: +proj=omerc without +alpha (the two-point form) has no GeoTIFF keys this build writes"))?;
            keys.set(COORD_TRANS, GeoKeyValue::Short(if no_uoff { CT_OBLIQUE_MERCATOR } else { CT_HOTINE_AZIMUTH_CENTER }));
            d(keys, CENTER_LAT, lat0);
            d(keys, CENTER_LONG, t.num_or("lonc", 0.0)?);
            d(keys, AZIMUTH, alpha);
            d(keys, RECTIFIED_GRID_ANGLE, t.num_or("gamma", alpha)?);
            d(keys, SCALE_AT_CENTER, k);
            d(keys, FALSE_EASTING, x0);
            d(keys, FALSE_NORTHING, y0);
        }
        // GeoTIFF has no method keys for these: GDAL writes (and reads) them
        // as an ESRI PE String citation, which carries the datum too.
        "moll" | "eqearth" => {
            // (Spherical methods: the ellipsoid is told by name, not by `Proj`.)
            let on_wgs84 = t.get("datum") == Some("WGS84") || matches!(t.get("ellps"), Some("WGS84" | "GRS80"));
            let shifted = t.get("towgs84").is_some_and(|s| s.split(',').any(|v| v.parse::<f64>() != Ok(0.0))) || t.get("nadgrids").is_some();
            if !on_wgs84 || shifted || unit != 9001 {
                return Err(format!("{crs}: +proj={proj} is written (as GDAL does) only on WGS84 or GRS80 and in metres; give the output an EPSG CRS"));
            }
            // As GDAL writes it: the model user-defined, no projection keys.
            keys.set(MODEL_TYPE, GeoKeyValue::Short(USER_DEFINED));
            keys.0.retain(|(k, _)| !matches!(*k, PROJECTED_TYPE | PROJECTION));
            let method = if proj == "moll" { "Mollweide" } else { "Equal_Earth" };
            let name: String = crs.to_string().chars().filter(|c| *c != '"' && *c != '[' && *c != ']').take(80).collect();
            keys.set(
                PCS_CITATION,
                GeoKeyValue::Ascii(format!(
                    "ESRI PE String = PROJCS[\"{name}\",GEOGCS[\"GCS_WGS_1984\",DATUM[\"D_WGS_1984\",SPHEROID[\"WGS_1984\",6378137.0,298.257223563]],PRIMEM[\"Greenwich\",0.0],UNIT[\"Degree\",0.0174532925199433]],PROJECTION[\"{method}\"],PARAMETER[\"False_Easting\",{x0:?}],PARAMETER[\"False_Northing\",{y0:?}],PARAMETER[\"Central_Meridian\",{lon0:?}],UNIT[\"Meter\",1.0]]"
                )),
            );
        }
        other => return Err(format!("{crs}: +proj={other} has no GeoTIFF keys this build writes; give the output an EPSG CRS or one of tmerc, utm, lcc, aea, laea, aeqd, stere, sterea, merc, eqc, cass, poly, sinu, robin, gnom, ortho, mill, eqdc, cea, omerc, moll, eqearth")),
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn round_trip(s: &str) -> Crs {
        let crs = Crs::parse(s, Path::new(".")).unwrap();
        let keys = keys_of(&crs).unwrap_or_else(|e| panic!("{s}: {e}"));
        crs_of(&keys).unwrap_or_else(|e| panic!("{s}: {e} in {keys:?}")).unwrap()
    }

    /// The same ground point converts to the same longitude/latitude
    /// through a CRS and through its keys read back.
    fn same_geometry(a: &Crs, b: &Crs, points: &[(f64, f64)]) {
        let (ga, gb) = (super::super::GroundCrs::new(a).unwrap(), super::super::GroundCrs::new(b).unwrap());
        for &(lon, lat) in points {
            let (x, y) = ga.lonlat_to_ground(lon, lat).unwrap();
            let (x2, y2) = gb.lonlat_to_ground(lon, lat).unwrap();
            assert!((x - x2).abs() < 1e-6 && (y - y2).abs() < 1e-6, "{a} vs {b}: ({x}, {y}) vs ({x2}, {y2})");
        }
    }

    #[test]
    fn codes_stay_codes() {
        let c = round_trip("EPSG:2154");
        assert_eq!(c.epsg(), Some(2154));
        let v = round_trip("EPSG:32631+5773");
        assert_eq!(v.vertical().and_then(|v| v.epsg), Some(5773));
    }

    #[test]
    fn user_defined_projections_round_trip() {
        for (s, pts) in [
            ("+proj=tmerc +lon_0=25 +k=1 +x_0=0 +datum=WGS84", vec![(18.4, -33.9), (28.0, -26.2)]),
            ("+proj=lcc +lat_1=44 +lat_2=49 +lat_0=46.5 +lon_0=3 +x_0=700000 +y_0=6600000 +ellps=GRS80 +units=m", vec![(2.35, 48.85), (5.0, 43.3)]),
            ("+proj=laea +lat_0=52 +lon_0=10 +x_0=4321000 +y_0=3210000 +ellps=GRS80", vec![(10.0, 50.0), (-3.0, 40.0)]),
            ("+proj=aea +lat_1=29.5 +lat_2=45.5 +lat_0=23 +lon_0=-96 +x_0=0 +y_0=0 +datum=NAD83", vec![(-100.0, 40.0)]),
            ("+proj=stere +lat_0=-90 +lat_ts=-71 +lon_0=0 +x_0=0 +y_0=0 +datum=WGS84", vec![(45.0, -80.0)]),
            ("+proj=sterea +lat_0=52.15616055555555 +lon_0=5.38763888888889 +k=0.9999079 +x_0=155000 +y_0=463000 +ellps=bessel +towgs84=565.417,50.3319,465.552,-0.398957,0.343988,-1.8774,4.0725", vec![(5.0, 52.0)]),
            ("+proj=tmerc +lat_0=49 +lon_0=-2 +k=0.9996012717 +x_0=400000 +y_0=-100000 +ellps=airy +towgs84=446.448,-125.157,542.06,0.15,0.247,0.842,-20.489 +units=ft", vec![(-1.0, 52.0)]),
            ("+proj=merc +lat_ts=41 +lon_0=10 +datum=WGS84", vec![(12.0, 42.0)]),
        ] {
            let a = Crs::parse(s, Path::new(".")).unwrap();
            same_geometry(&a, &round_trip(s), &pts);
        }
    }

    #[test]
    fn projections_without_keys_are_refused_by_name() {
        let c = Crs::parse("+proj=geos +h=35785831 +lon_0=0 +datum=WGS84", Path::new(".")).unwrap();
        assert!(keys_of(&c).unwrap_err().contains("+proj=geos"));
    }

    #[test]
    fn gdal_style_keys_read() {
        // As GDAL writes a UTM zone on an odd datum: Projection = 16031.
        let mut k = GeoKeys::default();
        k.set(MODEL_TYPE, GeoKeyValue::Short(1));
        k.set(PROJECTED_TYPE, GeoKeyValue::Short(USER_DEFINED));
        k.set(PROJECTION, GeoKeyValue::Short(16031));
        k.set(GEOGRAPHIC_TYPE, GeoKeyValue::Short(4326));
        let c = crs_of(&k).unwrap().unwrap();
        same_geometry(&c, &Crs::from_epsg(32631).unwrap(), &[(3.0, 45.0), (5.0, 44.0)]);
        assert_eq!(crs_of(&GeoKeys::default()).unwrap(), None);
    }
}
