//! GeoTIFF georeferencing: reading the geotransform, CRS and nodata of an
//! input raster, and writing them for the orthophoto so that GDAL and QGIS
//! read it as it is (ModelPixelScale, ModelTiepoint, GeoKeyDirectory,
//! GDAL_NODATA).

use crate::error::{Error, Result};
use std::io::{Read, Seek};
use std::path::Path;
use tiff::decoder::{ifd::Value, Decoder};
use tiff::tags::Tag;

const GT_MODEL_TYPE: u16 = 1024;
const GT_RASTER_TYPE: u16 = 1025;
const GEOGRAPHIC_TYPE: u16 = 2048;
const PROJECTED_CS_TYPE: u16 = 3072;
const RASTER_PIXEL_IS_POINT: u16 = 2;

/// Georeferencing of a raster, in GDAL's terms.
#[derive(Clone, Debug, PartialEq)]
pub struct GeoRef {
    /// GDAL geotransform: X = gt0 + col·gt1 + row·gt2, Y = gt3 + col·gt4 + row·gt5,
    /// (col, row) continuous with the top-left *corner* of the raster at (0, 0).
    pub transform: [f64; 6],
    pub epsg: Option<u32>,
    pub nodata: Option<f64>,
}

/// Is this EPSG code a geographic (longitude/latitude) CRS? Answered from
/// the EPSG definitions of the `crs-definitions` crate.
pub fn is_geographic(epsg: u32) -> Option<bool> {
    let def = crs_definitions::from_code(u16::try_from(epsg).ok()?)?;
    Some(def.proj4.contains("+proj=longlat"))
}

/// Any numeric tag value (or list of them) as f64s.
fn as_f64_list(v: Value) -> Option<Vec<f64>> {
    fn one(v: Value) -> Option<f64> {
        Some(match v {
            Value::Byte(x) => x as f64,
            Value::Short(x) => x as f64,
            Value::SignedByte(x) => x as f64,
            Value::SignedShort(x) => x as f64,
            Value::Signed(x) => x as f64,
            Value::SignedBig(x) => x as f64,
            Value::Unsigned(x) => x as f64,
            Value::UnsignedBig(x) => x as f64,
            Value::Float(x) => x as f64,
            Value::Double(x) => x,
            _ => return None,
        })
    }
    match v {
        Value::List(items) => items.into_iter().map(one).collect(),
        other => one(other).map(|x| vec![x]),
    }
}

/// Reads the georeferencing of the current image of `dec`. `None` if the
/// file has no geotransform at all.
pub fn read_georef<R: Read + Seek>(dec: &mut Decoder<R>, path: &Path) -> Result<Option<GeoRef>> {
    let tf = |e| Error::from_tiff(path, e);
    let scale = dec.find_tag(Tag::ModelPixelScaleTag).map_err(tf)?.and_then(as_f64_list);
    let tie = dec.find_tag(Tag::ModelTiepointTag).map_err(tf)?.and_then(as_f64_list);
    let matrix = dec.find_tag(Tag::ModelTransformationTag).map_err(tf)?.and_then(as_f64_list);
    let keys = dec.find_tag(Tag::GeoKeyDirectoryTag).map_err(tf)?.and_then(as_f64_list).unwrap_or_default();
    let nodata = match dec.find_tag(Tag::GdalNodata).map_err(tf)? {
        Some(Value::Ascii(s)) => {
            let s = s.trim_matches(char::from(0)).trim();
            Some(s.parse::<f64>().map_err(|_| Error::format(path, format!("GDAL_NODATA '{s}' is not a number")))?)
        }
        _ => None,
    };
    let mut epsg = None;
    let mut pixel_is_point = false;
    if keys.len() >= 4 {
        let n = keys[3] as usize;
        for k in 0..n {
            let Some(e) = keys.get(4 + 4 * k..8 + 4 * k) else { break };
            let (id, loc, value) = (e[0] as u16, e[1] as u16, e[3]);
            if loc != 0 {
                continue;
            }
            match id {
                GT_RASTER_TYPE => pixel_is_point = value as u16 == RASTER_PIXEL_IS_POINT,
                PROJECTED_CS_TYPE | GEOGRAPHIC_TYPE if (1.0..32767.0).contains(&value) => epsg = epsg.or(Some(value as u32)),
                _ => {}
            }
        }
    }
    let mut gt = if let Some(m) = matrix.filter(|m| m.len() >= 16) {
        [m[3], m[0], m[1], m[7], m[4], m[5]]
    } else if let (Some(s), Some(t)) = (scale, tie) {
        if s.len() < 2 || t.len() < 6 {
            return Err(Error::format(path, "ModelPixelScale/ModelTiepoint too short"));
        }
        [t[3] - t[0] * s[0], s[0], 0.0, t[4] + t[1] * s[1], 0.0, -s[1]]
    } else {
        return Ok(None);
    };
    if pixel_is_point {
        // The tiepoint names a pixel centre: move the origin to the corner,
        // as GDAL does.
        gt[0] -= 0.5 * gt[1] + 0.5 * gt[2];
        gt[3] -= 0.5 * gt[4] + 0.5 * gt[5];
    }
    if gt.iter().any(|v| !v.is_finite()) {
        return Err(Error::format(path, "geotransform has non-finite values"));
    }
    Ok(Some(GeoRef { transform: gt, epsg, nodata }))
}

/// The tags of north-up georeferencing for a grid with origin (x0, y0)
/// (north-west corner) and square pixels `gsd`, in the CRS `epsg`
/// (PixelIsArea): ModelPixelScale, ModelTiepoint, GeoKeyDirectory.
pub fn georef_tags(x0: f64, y0: f64, gsd: f64, epsg: u32) -> [(u16, crate::io::tiff_out::TagValue); 3] {
    use crate::io::tiff_out::TagValue;
    let geographic = is_geographic(epsg).unwrap_or(false);
    let (model, cs_key) = if geographic { (2u16, GEOGRAPHIC_TYPE) } else { (1u16, PROJECTED_CS_TYPE) };
    let keys: [u16; 16] = [
        1,
        1,
        0,
        3, //
        GT_MODEL_TYPE,
        0,
        1,
        model, //
        GT_RASTER_TYPE,
        0,
        1,
        1, // PixelIsArea
        cs_key,
        0,
        1,
        epsg as u16,
    ];
    [
        (Tag::ModelPixelScaleTag.to_u16(), TagValue::Double(vec![gsd, gsd, 0.0])),
        (Tag::ModelTiepointTag.to_u16(), TagValue::Double(vec![0.0, 0.0, 0.0, x0, y0, 0.0])),
        (Tag::GeoKeyDirectoryTag.to_u16(), TagValue::Short(keys.to_vec())),
    ]
}
