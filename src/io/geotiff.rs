//! GeoTIFF georeferencing: reading the geotransform, GeoTIFF keys and
//! nodata of an input raster, and writing them for the orthophoto so that
//! GDAL and QGIS read it as it is (ModelPixelScale, ModelTiepoint,
//! GeoKeyDirectory with its double and ASCII parameters, GDAL_NODATA). What
//! the keys mean as a CRS is `geodesy::geokeys`.

use crate::error::{Error, Result};
use std::io::{Read, Seek};
use std::path::Path;
use tiff::decoder::{ifd::Value, Decoder};
use tiff::tags::Tag;

const GT_RASTER_TYPE: u16 = 1025;
const RASTER_PIXEL_IS_POINT: u16 = 2;
const RASTER_PIXEL_IS_AREA: u16 = 1;
const GEO_DOUBLE_PARAMS: u16 = 34736;
const GEO_ASCII_PARAMS: u16 = 34737;

/// A GeoTIFF key's value: a SHORT in the directory, or doubles or text in
/// the parameter tags.
#[derive(Clone, Debug, PartialEq)]
pub enum GeoKeyValue {
    Short(u16),
    Doubles(Vec<f64>),
    Ascii(String),
}

/// The keys of a GeoKeyDirectory, in the order read (or to write).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GeoKeys(pub Vec<(u16, GeoKeyValue)>);

impl GeoKeys {
    pub fn get(&self, id: u16) -> Option<&GeoKeyValue> {
        self.0.iter().find(|(k, _)| *k == id).map(|(_, v)| v)
    }

    pub fn short(&self, id: u16) -> Option<u16> {
        match self.get(id)? {
            GeoKeyValue::Short(v) => Some(*v),
            _ => None,
        }
    }

    pub fn double(&self, id: u16) -> Option<f64> {
        match self.get(id)? {
            GeoKeyValue::Doubles(v) => v.first().copied(),
            GeoKeyValue::Short(v) => Some(f64::from(*v)),
            GeoKeyValue::Ascii(_) => None,
        }
    }

    pub fn doubles(&self, id: u16) -> Option<&[f64]> {
        match self.get(id)? {
            GeoKeyValue::Doubles(v) => Some(v),
            _ => None,
        }
    }

    pub fn ascii(&self, id: u16) -> Option<&str> {
        match self.get(id)? {
            GeoKeyValue::Ascii(v) => Some(v),
            _ => None,
        }
    }

    pub fn set(&mut self, id: u16, value: GeoKeyValue) {
        self.0.retain(|(k, _)| *k != id);
        self.0.push((id, value));
    }
}

/// Georeferencing of a raster, in GDAL's terms.
#[derive(Clone, Debug, PartialEq)]
pub struct GeoRef {
    /// GDAL geotransform: X = gt0 + col·gt1 + row·gt2, Y = gt3 + col·gt4 + row·gt5,
    /// (col, row) continuous with the top-left *corner* of the raster at (0, 0).
    pub transform: [f64; 6],
    /// The GeoTIFF keys (the CRS), empty when the file has none.
    pub keys: GeoKeys,
    pub nodata: Option<f64>,
    /// The first band's scale and offset from GDAL's metadata (value =
    /// stored · scale + offset), where they are other than 1 and 0.
    pub scale_offset: Option<(f64, f64)>,
    /// What the file was made from, where gcm-ortho made it (GDAL metadata
    /// item [`SOURCE_ITEM`]): pieces of one orthophoto share it.
    pub source: Option<String>,
}

/// The GDAL metadata item naming an orthophoto's inputs and settings (a
/// hash; not its window): `assemble` joins only pieces that agree on it.
pub const SOURCE_ITEM: &str = "GCM_ORTHO_SOURCE";

/// A piece's source: its orthophoto's, and the whole grid it is a piece of
/// (its size and top-left corner), so that `assemble` can refuse a set of
/// pieces that leaves out an edge of the whole.
pub fn piece_source(source: &str, whole: &crate::geom::OutputGrid, layout: &str) -> String {
    format!("{source}{WHOLE}{}x{} at {},{}{LAYOUT}{layout}", whole.width, whole.height, whole.x0, whole.y0)
}

/// What joins a piece's source to its whole, and that to the whole's
/// layout (overviews, Cloud-Optimized: what `assemble` takes unless told).
const WHOLE: &str = " whole ";
const LAYOUT: &str = " layout ";

/// A piece's record of the layout its whole is to have (see
/// [`piece_source`]).
pub fn whole_layout(source: &str) -> Option<&str> {
    source.split_once(WHOLE)?.1.split_once(LAYOUT).map(|(_, l)| l)
}

/// A source without a piece's record of its whole's layout (pieces of one
/// whole made with other layouts are still its pieces).
pub fn without_layout(source: &str) -> &str {
    source.split_once(LAYOUT).map_or(source, |(s, _)| s)
}

/// A source's orthophoto part and, for a piece ([`piece_source`]), the
/// whole's width, height and top-left corner.
pub fn whole_of(source: &str) -> (&str, Option<(u32, u32, f64, f64)>) {
    let Some((key, whole)) = source.split_once(WHOLE) else { return (source, None) };
    let whole = whole.split_once(LAYOUT).map_or(whole, |(w, _)| w);
    let parsed = (|| {
        let (size, at) = whole.split_once(" at ")?;
        let (w, h) = size.split_once('x')?;
        let (x0, y0) = at.split_once(',')?;
        Some((w.parse().ok()?, h.parse().ok()?, x0.parse().ok()?, y0.parse().ok()?))
    })();
    (key, parsed)
}

/// The dataset item `name` of GDAL's metadata XML.
fn dataset_item(xml: &str, name: &str) -> Option<String> {
    let doc = roxmltree::Document::parse(xml.trim_matches(char::from(0))).ok()?;
    let item = doc.descendants().find(|n| n.has_tag_name("Item") && n.attribute("name") == Some(name) && n.attribute("sample").is_none())?;
    Some(item.text().unwrap_or("").trim().to_string())
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

/// GDAL's metadata tag: an XML of items, some per band.
const GDAL_METADATA: u16 = 42112;

/// The first band's `role="scale"` and `role="offset"` items of GDAL's
/// metadata XML (`gdal_translate -a_scale/-a_offset`, PROJ's packed grids):
/// `None` where they leave values as stored.
/// Heights in feet (the band's unit, `gdal_edit.py -units ft`) come out
/// in metres: the scale and offset take the foot's length.
fn band_scale_offset(xml: &str) -> std::result::Result<(Option<(f64, f64)>, bool), String> {
    let doc = roxmltree::Document::parse(xml.trim_matches(char::from(0))).map_err(|e| e.to_string())?;
    let (mut scale, mut offset) = (1.0, 0.0);
    for item in doc.descendants().filter(|n| n.has_tag_name("Item") && n.attribute("sample") == Some("0")) {
        let value =
            || item.text().unwrap_or("").trim().parse::<f64>().map_err(|_| format!("the band's {} is not a number", item.attribute("role").unwrap_or("item")));
        match item.attribute("role") {
            Some("scale") => scale = value()?,
            Some("offset") => offset = value()?,
            _ => {}
        }
    }
    let unit = band_unit(&doc);
    if let Some((_, metres)) = unit {
        (scale, offset) = (scale * metres, offset * metres);
    }
    if !(scale.is_finite() && offset.is_finite()) {
        return Err(format!("band scale {scale} and offset {offset}"));
    }
    Ok(((scale != 1.0 || offset != 0.0).then_some((scale, offset)), unit.is_some()))
}

/// GeoTIFF's VerticalCSTypeGeoKey and VerticalUnitsGeoKey.
const VERTICAL_CS: u16 = 4096;
const VERTICAL_UNITS: u16 = 4099;

/// Vertical CRSs of heights in feet (EPSG), by the foot they count in:
/// NGVD29, NAVD88 and MSL heights in US survey feet; NAVD88 and MSL
/// heights in international feet.
const US_FOOT_HEIGHTS: [u16; 3] = [5702, 6360, 8052];
const FOOT_HEIGHTS: [u16; 2] = [8228, 8050];

/// The heights' unit from the GeoTIFF keys where it is a foot: the units
/// key (EPSG 9002, 9003), else a vertical CRS in feet (GDAL writes only
/// the CRS for `EPSG:xxxx+6360`). Its name and length in metres.
fn vertical_foot(keys: &GeoKeys) -> Option<(&'static str, f64)> {
    let (foot, us_foot) = (("feet", 0.3048), ("US survey feet", 1200.0 / 3937.0));
    match (keys.short(VERTICAL_UNITS), keys.short(VERTICAL_CS)) {
        (Some(9002), _) => Some(foot),
        (Some(9003), _) => Some(us_foot),
        (Some(_), _) => None,
        (None, Some(c)) if US_FOOT_HEIGHTS.contains(&c) => Some(us_foot),
        (None, Some(c)) if FOOT_HEIGHTS.contains(&c) => Some(foot),
        _ => None,
    }
}

/// The first band's unit where it is a foot: its name and its length in
/// metres.
fn band_unit(doc: &roxmltree::Document) -> Option<(&'static str, f64)> {
    let unit = doc
        .descendants()
        .find(|n| n.has_tag_name("Item") && n.attribute("sample") == Some("0") && n.attribute("role") == Some("unittype"))?
        .text()?
        .trim()
        .to_ascii_lowercase();
    match unit.as_str() {
        "ft" | "foot" | "feet" | "international foot" | "ft_intl" => Some(("feet", 0.3048)),
        "us-ft" | "ftus" | "ft_us" | "us survey foot" | "us_survey_foot" | "foot_us" | "us-foot" => Some(("US survey feet", 1200.0 / 3937.0)),
        _ => None,
    }
}

/// The unit of a GeoTIFF's first band where it is not metres and is taken
/// into metres when read (feet): its name, for a warning.
pub fn foot_unit_of(path: &Path) -> Option<&'static str> {
    let file = std::fs::File::open(path).ok()?;
    let mut dec = Decoder::new(std::io::BufReader::new(file)).ok()?;
    if let Ok(Some(Value::Ascii(xml))) = dec.find_tag(Tag::Unknown(GDAL_METADATA)) {
        let doc = roxmltree::Document::parse(xml.trim_matches(char::from(0))).ok()?;
        if let Some((name, _)) = band_unit(&doc) {
            return Some(name);
        }
    }
    read_georef(&mut dec, path).ok().flatten().and_then(|g| vertical_foot(&g.keys)).map(|(name, _)| name)
}

/// The unit of a GeoTIFF's first band where the file names one that is
/// neither metres nor feet (read into metres): it is read as metres, and
/// the caller warns of it.
pub fn unknown_unit_of(path: &Path) -> Option<String> {
    let file = std::fs::File::open(path).ok()?;
    let mut dec = Decoder::new(std::io::BufReader::new(file)).ok()?;
    let Ok(Some(Value::Ascii(xml))) = dec.find_tag(Tag::Unknown(GDAL_METADATA)) else { return None };
    let doc = roxmltree::Document::parse(xml.trim_matches(char::from(0))).ok()?;
    if band_unit(&doc).is_some() {
        return None;
    }
    let unit =
        doc.descendants().find(|n| n.has_tag_name("Item") && n.attribute("sample") == Some("0") && n.attribute("role") == Some("unittype"))?.text()?.trim();
    let metres = ["", "m", "metre", "metres", "meter", "meters", "metre (m)", "meters (m)"];
    (!metres.contains(&unit.to_ascii_lowercase().as_str())).then(|| unit.to_string())
}

/// The current image's GDAL_NODATA value, if it has one.
pub fn read_nodata<R: Read + Seek>(dec: &mut Decoder<R>, path: &Path) -> Result<Option<f64>> {
    Ok(match dec.find_tag(Tag::GdalNodata).map_err(|e| Error::from_tiff(path, e))? {
        Some(Value::Ascii(s)) => {
            let s = s.trim_matches(char::from(0)).trim();
            Some(s.parse::<f64>().map_err(|_| Error::format(path, format!("GDAL_NODATA '{s}' is not a number")))?)
        }
        _ => None,
    })
}

/// Reads the georeferencing of the current image of `dec`. `None` if the
/// file has no geotransform at all.
pub fn read_georef<R: Read + Seek>(dec: &mut Decoder<R>, path: &Path) -> Result<Option<GeoRef>> {
    let tf = |e| Error::from_tiff(path, e);
    let scale = dec.find_tag(Tag::ModelPixelScaleTag).map_err(tf)?.and_then(as_f64_list);
    let tie = dec.find_tag(Tag::ModelTiepointTag).map_err(tf)?.and_then(as_f64_list);
    let matrix = dec.find_tag(Tag::ModelTransformationTag).map_err(tf)?.and_then(as_f64_list);
    let directory = dec.find_tag(Tag::GeoKeyDirectoryTag).map_err(tf)?.and_then(as_f64_list).unwrap_or_default();
    let doubles = dec.find_tag(Tag::GeoDoubleParamsTag).map_err(tf)?.and_then(as_f64_list).unwrap_or_default();
    let ascii = match dec.find_tag(Tag::GeoAsciiParamsTag).map_err(tf)? {
        Some(Value::Ascii(s)) => s,
        _ => String::new(),
    };
    let nodata = read_nodata(dec, path)?;
    let ((mut scale_offset, band_has_unit), source) = match dec.find_tag(Tag::Unknown(GDAL_METADATA)).map_err(tf)? {
        Some(Value::Ascii(xml)) => {
            (band_scale_offset(&xml).map_err(|m| Error::format(path, format!("its GDAL metadata: {m}")))?, dataset_item(&xml, SOURCE_ITEM))
        }
        _ => ((None, false), None),
    };
    let keys = geo_keys(&directory, &doubles, &ascii);
    // Heights in feet by the keys (the band's own unit, if any, rules).
    if let (false, Some((_, metres))) = (band_has_unit, vertical_foot(&keys)) {
        let (s, o) = scale_offset.unwrap_or((1.0, 0.0));
        scale_offset = Some((s * metres, o * metres));
    }
    let pixel_is_point = keys.short(GT_RASTER_TYPE) == Some(RASTER_PIXEL_IS_POINT);
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
    Ok(Some(GeoRef { transform: gt, keys, nodata, scale_offset, source }))
}

/// The keys of a GeoKeyDirectory (header of four SHORTs, then four a
/// key: id, where its value is, count, value or offset), their values taken
/// from the double and ASCII parameter tags. Keys whose value is out of
/// range are left out.
fn geo_keys(directory: &[f64], doubles: &[f64], ascii: &str) -> GeoKeys {
    let mut keys = GeoKeys::default();
    let n = directory.get(3).map_or(0, |&n| n as usize);
    for k in 0..n {
        let Some(e) = directory.get(4 + 4 * k..8 + 4 * k) else { break };
        let (id, loc, count, value) = (e[0] as u16, e[1] as u16, e[2] as usize, e[3] as usize);
        let v = match loc {
            0 => Some(GeoKeyValue::Short(value as u16)),
            GEO_DOUBLE_PARAMS => doubles.get(value..value + count).map(|d| GeoKeyValue::Doubles(d.to_vec())),
            GEO_ASCII_PARAMS => ascii.get(value..value + count).map(|t| GeoKeyValue::Ascii(t.trim_end_matches(['|', '\0']).to_string())),
            _ => None,
        };
        if let Some(v) = v {
            keys.0.push((id, v));
        }
    }
    keys
}

/// The tags of north-up georeferencing for a grid with origin (x0, y0)
/// (north-west corner) and square pixels `gsd`, with the CRS's GeoTIFF
/// `keys` (PixelIsArea is added): ModelPixelScale, ModelTiepoint,
/// GeoKeyDirectory and, where keys need them, GeoDoubleParams and
/// GeoAsciiParams.
pub fn georef_tags(x0: f64, y0: f64, gsd: crate::geom::Gsd, keys: &GeoKeys) -> Vec<(u16, crate::io::tiff_out::TagValue)> {
    use crate::io::tiff_out::TagValue;
    let mut all = keys.clone();
    all.set(GT_RASTER_TYPE, GeoKeyValue::Short(RASTER_PIXEL_IS_AREA));
    all.0.sort_by_key(|(k, _)| *k);
    let (mut directory, mut doubles, mut ascii) = (vec![1u16, 1, 0, all.0.len() as u16], Vec::<f64>::new(), String::new());
    for (id, v) in &all.0 {
        match v {
            GeoKeyValue::Short(s) => directory.extend([*id, 0, 1, *s]),
            GeoKeyValue::Doubles(d) => {
                directory.extend([*id, GEO_DOUBLE_PARAMS, d.len() as u16, doubles.len() as u16]);
                doubles.extend(d);
            }
            GeoKeyValue::Ascii(t) => {
                let t = format!("{}|", t.replace('|', "/"));
                directory.extend([*id, GEO_ASCII_PARAMS, t.len() as u16, ascii.len() as u16]);
                ascii.push_str(&t);
            }
        }
    }
    let mut tags = vec![
        (Tag::ModelPixelScaleTag.to_u16(), TagValue::Double(vec![gsd.x, gsd.y, 0.0])),
        (Tag::ModelTiepointTag.to_u16(), TagValue::Double(vec![0.0, 0.0, 0.0, x0, y0, 0.0])),
        (Tag::GeoKeyDirectoryTag.to_u16(), TagValue::Short(directory)),
    ];
    if !doubles.is_empty() {
        tags.push((GEO_DOUBLE_PARAMS, TagValue::Double(doubles)));
    }
    if !ascii.is_empty() {
        tags.push((GEO_ASCII_PARAMS, TagValue::Ascii(ascii)));
    }
    tags
}
