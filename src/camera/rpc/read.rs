//! Readers of RPC00B metadata in the formats found in the wild. Every reader
//! ends in `Rpc::from_map` with GDAL's metadata names, so one place checks
//! that all 90 numbers are there and finite. Pixel conventions are brought to
//! GDAL's (0, 0) = centre of the first pixel here, at the boundary:
//! DIMAP's (1, 1) is shifted by one.
//!
//! | format | recognised by | where the numbers are |
//! |---|---|---|
//! | GeoTIFF RPCCoefficientTag (50844) | TIFF magic | the tag's 92 doubles |
//! | IKONOS `rpc.txt`, GDAL `_RPC.TXT`, Planet | `LINE_OFF:` lines | `KEY: value`, `*_COEFF_1..20` |
//! | GDAL / DigitalGlobe `.RPB` | `lineOffset =` | `key = value;`, `( … )` lists |
//! | OSSIM `.geom` keyword list | `line_off:` with `_coeff_00` | `key: value`, `*_coeff_00..19` |
//! | Pléiades / SPOT DIMAP v2 XML | `<Inverse_Model>` | `<SAMP_NUM_COEFF_1>`…, 1-based pixels |
//! | WorldView / DigitalGlobe XML | `<RPB>` | `<LINEOFFSET>`…, space-separated lists |
//! | NITF | `NITF` magic | the RPC00B TRE, fixed-width text |
//! | Orthority `rpc_param.yaml` | `line_num_coeff:` | image name → `rpc:` → lower-case GDAL names, lists |

use super::Rpc;
use crate::error::{Error, Result};
use crate::io::bounded_read::{read_bounded, read_head, read_text_bounded, SMALL};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

type Numbers = HashMap<String, Vec<f64>>;

/// The ten offsets and scales, in the order of the GeoTIFF tag and the NITF TRE.
pub(super) const SCALARS: [&str; 10] =
    ["LINE_OFF", "SAMP_OFF", "LAT_OFF", "LONG_OFF", "HEIGHT_OFF", "LINE_SCALE", "SAMP_SCALE", "LAT_SCALE", "LONG_SCALE", "HEIGHT_SCALE"];
/// The four coefficient sets, in the same order.
pub(super) const SETS: [&str; 4] = ["LINE_NUM_COEFF", "LINE_DEN_COEFF", "SAMP_NUM_COEFF", "SAMP_DEN_COEFF"];

/// The headers of a NITF file, where its TREs are: the file header and the
/// first image's subheader (its length, LISH001, is in the file header),
/// never the pixels after them.
fn nitf_headers(path: &Path) -> Result<Vec<u8>> {
    let head = read_head(path, 1 << 16)?;
    let num = |a: usize, b: usize| std::str::from_utf8(head.get(a..b)?).ok()?.trim().parse::<u64>().ok();
    // NITF 2.1 / NSIF: HL at 354..360, NUMI at 360..363, LISH001 at 363..369.
    let end = match (num(354, 360), num(360, 363), num(363, 369)) {
        (Some(hl), Some(numi), Some(lish)) if numi > 0 => hl + lish,
        (Some(hl), _, _) => hl,
        _ => return Err(Error::format(path, "a NITF file header cut short")),
    };
    if end > SMALL {
        return Err(Error::format(path, format!("NITF headers of {end} bytes: not a NITF file this reads")));
    }
    read_head(path, end.max(head.len() as u64))
}

impl Rpc {
    /// Reads an RPC model from any supported file, recognising the format
    /// by its content (not its name).
    pub fn read(path: &Path) -> Result<Rpc> {
        Rpc::read_for(path, None)
    }

    /// As [`Rpc::read`]; where the file holds the RPCs of several images
    /// (Orthority's YAML), the one of the image named `image` (its file
    /// name).
    pub fn read_for(path: &Path, image: Option<&str>) -> Result<Rpc> {
        // An image carrying its RPC may be of any size: only its header is read.
        let head = read_head(path, 8)?;
        if head.starts_with(b"II*\0") || head.starts_with(b"MM\0*") || head.starts_with(b"II+\0") || head.starts_with(b"MM\0+") {
            return Rpc::from_geotiff(path);
        }
        if head.starts_with(b"NITF") || head.starts_with(b"NSIF") {
            return Rpc::parse_nitf(&nitf_headers(path)?, path);
        }
        let bytes = read_bounded(path, "an RPC file", SMALL)?;
        let text = std::str::from_utf8(&bytes).map_err(|_| Error::unsupported(path, "not an RPC file: neither TIFF, NITF nor text"))?;
        let head = text.trim_start();
        if head.starts_with('<') {
            return Rpc::parse_xml(text, path);
        }
        if head.starts_with('{') {
            return Rpc::parse_json(text, path);
        }
        if text.contains("lineOffset") {
            return Rpc::parse_rpb(text, path);
        }
        if text.contains("line_num_coeff_00") {
            return Rpc::parse_geom(text, path);
        }
        if text.contains("line_num_coeff:") {
            return Rpc::parse_orthority_yaml(text, path, image);
        }
        Rpc::parse_text(text, path)
    }

    /// Reads a text RPC file (`KEY: value` lines).
    pub fn read_text(path: &Path) -> Result<Rpc> {
        let text = read_text_bounded(path, "an RPC file", SMALL)?;
        Rpc::parse_text(&text, path)
    }

    /// "KEY: value [unit]" lines (IKONOS rpc.txt, GDAL _RPC.TXT, Planet):
    /// coefficients as LINE_NUM_COEFF_1 … LINE_NUM_COEFF_20.
    pub fn parse_text(text: &str, path: &Path) -> Result<Rpc> {
        let map = keyword_list(text, ':', 1, path)?;
        if !map.contains_key("LINE_OFF") {
            return Err(Error::unsupported(path, "not an RPC file (no LINE_OFF)"));
        }
        Rpc::from_numbers(&map, path)
    }

    /// rpcm's JSON (`row_offset`, …, `row_num` of 20 coefficients in the
    /// RPC00B order), as it stands or under `"rpc"` (the IEEE GRSS data
    /// fusion contest's image files, SatNeRF's).
    pub fn parse_json(text: &str, path: &Path) -> Result<Rpc> {
        let doc: serde_json::Value = serde_json::from_str(text).map_err(|e| Error::format(path, format!("JSON: {e}")))?;
        let model = if doc.get("row_offset").is_some() { &doc } else { doc.get("rpc").filter(|r| r.get("row_offset").is_some()).unwrap_or(&doc) };
        if model.get("row_offset").is_none() {
            return Err(Error::unsupported(path, "JSON without an RPC (rpcm's row_offset, …, row_num, … as they stand or under \"rpc\")"));
        }
        const NAMES: [(&str, &str); 14] = [
            ("row_offset", "LINE_OFF"),
            ("col_offset", "SAMP_OFF"),
            ("lat_offset", "LAT_OFF"),
            ("lon_offset", "LONG_OFF"),
            ("alt_offset", "HEIGHT_OFF"),
            ("row_scale", "LINE_SCALE"),
            ("col_scale", "SAMP_SCALE"),
            ("lat_scale", "LAT_SCALE"),
            ("lon_scale", "LONG_SCALE"),
            ("alt_scale", "HEIGHT_SCALE"),
            ("row_num", "LINE_NUM_COEFF"),
            ("row_den", "LINE_DEN_COEFF"),
            ("col_num", "SAMP_NUM_COEFF"),
            ("col_den", "SAMP_DEN_COEFF"),
        ];
        let mut map = Numbers::new();
        for (key, name) in NAMES {
            let numbers = match model.get(key) {
                Some(serde_json::Value::Array(a)) => a.iter().map(|v| v.as_f64().unwrap_or(f64::NAN)).collect(),
                Some(v) => vec![v.as_f64().unwrap_or(f64::NAN)],
                None => continue,
            };
            map.insert(name.to_string(), numbers);
        }
        Rpc::from_numbers(&map, path)
    }

    /// Orthority's RPC parameters: a YAML mapping of image file names, each
    /// with `im_size` and an `rpc` mapping of the GDAL names in lower case
    /// (coefficient sets as lists of 20). The entry of `image` where the
    /// file holds several; the only one otherwise.
    pub fn parse_orthority_yaml(text: &str, path: &Path, image: Option<&str>) -> Result<Rpc> {
        use serde_yaml_ng::Value;
        // A YAML tree takes tens of times its text: one image's RPC is some
        // 3 KB, a file of a few hundred images under 4 MB.
        const MOST: usize = 4 << 20;
        if text.len() > MOST {
            return Err(Error::format(path, format!("an Orthority RPC YAML of {} bytes: more than the {MOST} its images' RPCs could take", text.len())));
        }
        let doc = crate::camera::formats::orthority::parse_yaml(text).map_err(|e| Error::format(path, format!("YAML: {e}")))?;
        let Value::Mapping(images) = doc else { return Err(Error::format(path, "Orthority RPC YAML: not a mapping of image names")) };
        let names: Vec<String> = images.keys().map(|k| k.as_str().map_or_else(|| format!("{k:?}"), str::to_string)).collect();
        let entry = match (images.len(), image) {
            (1, _) => images.values().next(),
            (_, Some(name)) => images.get(name),
            (_, None) => None,
        };
        let Some(entry) = entry else {
            let listed = names.iter().take(5).cloned().collect::<Vec<_>>().join(", ");
            let which = image.map_or_else(|| ": which is the image's is not known".to_string(), |n| format!(", none for {n}"));
            return Err(Error::format(path, format!("holds the RPCs of {} images ({listed}){which}", names.len())));
        };
        let rpc = entry.get("rpc").ok_or_else(|| Error::format(path, "Orthority RPC YAML: an image without its `rpc` mapping"))?;
        let Value::Mapping(fields) = rpc else { return Err(Error::format(path, "Orthority RPC YAML: `rpc` is not a mapping")) };
        let mut map = Numbers::new();
        for (key, value) in fields {
            let Some(key) = key.as_str() else { continue };
            let numbers = match value {
                Value::Sequence(a) => a.iter().map(|v| v.as_f64().unwrap_or(f64::NAN)).collect(),
                v => vec![v.as_f64().unwrap_or(f64::NAN)],
            };
            map.insert(key.to_ascii_uppercase(), numbers);
        }
        Rpc::from_numbers(&map, path)
    }

    /// OSSIM keyword list (`.geom`): lower-case keys, coefficients numbered
    /// from 00. Only `polynomial_format: B` (RPC00B) is read.
    pub fn parse_geom(text: &str, path: &Path) -> Result<Rpc> {
        for line in text.lines() {
            if let Some(("polynomial_format", v)) = line.split_once(':').map(|(k, v)| (k.trim(), v.trim())) {
                if v != "B" {
                    return Err(Error::unsupported(path, format!("OSSIM polynomial_format {v} (only B, RPC00B, is read)")));
                }
            }
        }
        Rpc::from_numbers(&keyword_list(text, ':', 0, path)?, path)
    }

    /// GDAL / DigitalGlobe `.RPB`: `lineOffset = 1234;`, coefficient lists
    /// `lineNumCoef = ( a, b, … );`.
    pub fn parse_rpb(text: &str, path: &Path) -> Result<Rpc> {
        let names = rpb_names();
        let mut map = Numbers::new();
        for stmt in text.split(';') {
            let Some((k, v)) = stmt.split_once('=') else { continue };
            let Some(name) = names.get(k.trim().to_ascii_lowercase().as_str()) else { continue };
            let nums = v.trim().trim_start_matches('(').trim_end_matches(')');
            let parsed: std::result::Result<Vec<f64>, _> = nums.split([',', ' ', '\n', '\r', '\t']).filter(|s| !s.is_empty()).map(str::parse::<f64>).collect();
            let parsed = parsed.map_err(|_| Error::format(path, format!("RPB: {} is not a number list", k.trim())))?;
            map.insert(name.to_string(), parsed);
        }
        Rpc::from_numbers(&map, path)
    }

    /// XML metadata: DIMAP v2 (Pléiades, SPOT 6/7) or DigitalGlobe's `<RPB>`.
    pub fn parse_xml(text: &str, path: &Path) -> Result<Rpc> {
        let doc = roxmltree::Document::parse(text).map_err(|e| Error::format(path, format!("XML: {e}")))?;
        let find = |name: &str| doc.descendants().find(|n| n.has_tag_name(name));
        if let Some(model) = find("Inverse_Model") {
            return Rpc::from_dimap(model, path);
        }
        if let Some(rpb) = find("RPB") {
            return Rpc::from_digitalglobe(rpb, path);
        }
        let root = doc.root_element().tag_name().name().to_string();
        // EnMAP's metadata: an RPC for each band, under <RPC><bandID>.
        if find("RPC").is_some_and(|n| n.descendants().any(|c| c.has_tag_name("bandID"))) {
            return Err(Error::unsupported(
                path,
                format!("XML <{root}> holds an RPC for each band (<RPC><bandID>, as EnMAP's): per-band RPCs are not read here"),
            ));
        }
        Err(Error::unsupported(path, format!("XML <{root}> holds no RPC this reader knows (DIMAP <Inverse_Model> or DigitalGlobe <RPB>)")))
    }

    fn from_dimap(model: roxmltree::Node<'_, '_>, path: &Path) -> Result<Rpc> {
        let mut map = Numbers::new();
        // The offsets and scales sit beside the model in <RFM_Validity>.
        let scope = model.parent().unwrap_or(model);
        for n in scope.descendants().filter(|n| n.is_element()) {
            let name = n.tag_name().name().to_ascii_uppercase();
            let Some(v) = n.text().and_then(|t| t.trim().parse::<f64>().ok()) else { continue };
            if SCALARS.contains(&name.as_str()) {
                map.insert(name, vec![v]);
            } else if let Some((base, i)) = numbered(&name, 1) {
                map.entry(base.to_string()).or_insert_with(|| vec![f64::NAN; 20])[i] = v;
            }
        }
        let mut rpc = Rpc::from_numbers(&map, path)?;
        // DIMAP: the centre of the first pixel is (1, 1).
        rpc.line_off -= 1.0;
        rpc.samp_off -= 1.0;
        Ok(rpc)
    }

    fn from_digitalglobe(rpb: roxmltree::Node<'_, '_>, path: &Path) -> Result<Rpc> {
        let names = rpb_names();
        let mut map = Numbers::new();
        for n in rpb.descendants().filter(|n| n.is_element()) {
            let Some(name) = names.get(n.tag_name().name().to_ascii_lowercase().as_str()) else { continue };
            let Some(text) = n.text() else { continue };
            let parsed: std::result::Result<Vec<f64>, _> = text.split_whitespace().map(str::parse::<f64>).collect();
            let parsed = parsed.map_err(|_| Error::format(path, format!("<{}> is not a number list", n.tag_name().name())))?;
            map.insert(name.to_string(), parsed);
        }
        Rpc::from_numbers(&map, path)
    }

    /// The RPC00B tagged record extension of a NITF file (STDI-0002 App. E):
    /// fixed-width text after the tag name and its 5-digit length.
    pub fn parse_nitf(bytes: &[u8], path: &Path) -> Result<Rpc> {
        let at = bytes.windows(6).position(|w| w == b"RPC00B").ok_or_else(|| Error::format(path, "NITF without an RPC00B TRE"))?;
        let widths = [6usize, 5, 8, 9, 5, 6, 5, 8, 9, 5];
        // tag (6) + length (5) + SUCCESS (1) + ERR_BIAS (7) + ERR_RAND (7)
        let mut pos = at + 6 + 5 + 1 + 7 + 7;
        let need = pos + widths.iter().sum::<usize>() + 80 * 12;
        if bytes.len() < need {
            return Err(Error::format(path, "the RPC00B TRE is cut short"));
        }
        let mut field = |w: usize| -> Result<f64> {
            let s = std::str::from_utf8(&bytes[pos..pos + w]).unwrap_or("");
            pos += w;
            s.trim().parse::<f64>().map_err(|_| Error::format(path, format!("RPC00B TRE: '{s}' is not a number")))
        };
        let mut map = Numbers::new();
        for (name, w) in SCALARS.iter().zip(widths) {
            map.insert(name.to_string(), vec![field(w)?]);
        }
        for set in SETS {
            let v = (0..20).map(|_| field(12)).collect::<Result<Vec<f64>>>()?;
            map.insert(set.to_string(), v);
        }
        Rpc::from_numbers(&map, path)
    }

    /// The GeoTIFF RPCCoefficientTag (50844): ERR_BIAS, ERR_RAND, the ten
    /// offsets and scales, then the four sets of 20 coefficients.
    pub fn from_geotiff(path: &Path) -> Result<Rpc> {
        let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let mut dec = tiff::decoder::Decoder::new(std::io::BufReader::new(f)).map_err(|e| Error::from_tiff(path, e))?;
        let v = dec.find_tag(tiff::tags::Tag::Unknown(50844)).map_err(|e| Error::from_tiff(path, e))?.ok_or_else(|| no_tag(path))?;
        let v: Vec<f64> = match v {
            tiff::decoder::ifd::Value::List(items) => items.into_iter().filter_map(|x| x.into_f64().ok()).collect(),
            _ => Vec::new(),
        };
        if v.len() != 92 {
            return Err(Error::format(path, format!("the RPC tag holds {} numbers, not 92", v.len())));
        }
        let mut map = Numbers::new();
        for (i, name) in SCALARS.iter().enumerate() {
            map.insert(name.to_string(), vec![v[2 + i]]);
        }
        for (s, name) in SETS.iter().enumerate() {
            map.insert(name.to_string(), v[12 + 20 * s..32 + 20 * s].to_vec());
        }
        Rpc::from_numbers(&map, path)
    }

    /// Where a DigitalGlobe XML records the image as one tile of the
    /// scene: the (ULCOLOFFSET, ULROWOFFSET) of the `<TILE>` whose
    /// `<FILENAME>` is `image_name` (case-insensitive), to shift the RPC by.
    pub fn tile_offset(xml: &str, image_name: &str) -> Option<[f64; 2]> {
        let doc = roxmltree::Document::parse(xml).ok()?;
        let tile = doc
            .descendants()
            .filter(|n| n.has_tag_name("TILE"))
            .find(|t| t.children().any(|c| c.has_tag_name("FILENAME") && c.text().is_some_and(|f| f.trim().eq_ignore_ascii_case(image_name))))?;
        let get = |name: &str| tile.children().find(|c| c.has_tag_name(name))?.text()?.trim().parse::<f64>().ok();
        Some([get("ULCOLOFFSET")?, get("ULROWOFFSET")?])
    }

    fn from_numbers(map: &Numbers, path: &Path) -> Result<Rpc> {
        Rpc::from_map(&|k| map.get(k).cloned(), path)
    }
}

/// No RPC tag in a GeoTIFF: where GDAL would find the RPC beside it (an
/// `.RPB` or `_RPC.TXT` sidecar), that file is named.
fn no_tag(path: &Path) -> Error {
    let stem = path.with_extension("");
    let beside = ["RPB", "rpb"]
        .iter()
        .map(|e| path.with_extension(e))
        .chain(["_RPC.TXT", "_rpc.txt"].iter().map(|t| PathBuf::from(format!("{}{t}", stem.display()))))
        .find(|p| p.is_file());
    match beside {
        Some(p) => Error::format(path, format!("no RPC tag (50844); its RPC is beside it: give ‹rpc› {}", p.display())),
        None => Error::format(path, "no RPC tag (50844)"),
    }
}

/// `base_N` with N counted from `first` → (base, 0-based index < 20).
fn numbered(key: &str, first: usize) -> Option<(&str, usize)> {
    let (base, idx) = key.rsplit_once('_')?;
    if !SETS.contains(&base) {
        return None;
    }
    let i: usize = idx.parse().ok()?;
    (first..first + 20).contains(&i).then(|| (base, i - first))
}

/// `KEY<sep> value [unit]` lines; keys upper-cased; numbered coefficients
/// (`LINE_NUM_COEFF_7`, counted from `first`) gathered into lists of 20.
/// A coefficient numbered past the 20 of its kind (`LINE_NUM_COEFF_21`)
/// is refused: a file of another model, or damaged.
fn keyword_list(text: &str, sep: char, first: usize, path: &Path) -> Result<Numbers> {
    let mut map = Numbers::new();
    for line in text.lines() {
        let Some((k, v)) = line.split_once(sep) else { continue };
        let k = k.trim().to_ascii_uppercase();
        let Some(x) = v.split_whitespace().next().and_then(|s| s.parse::<f64>().ok()) else { continue };
        match numbered(&k, first) {
            Some((base, i)) => map.entry(base.to_string()).or_insert_with(|| vec![f64::NAN; 20])[i] = x,
            None if k.rsplit_once('_').is_some_and(|(base, n)| SETS.contains(&base) && n.parse::<usize>().is_ok()) => {
                return Err(Error::format(
                    path,
                    format!("RPC: {} has no place among the 20 coefficients of its kind, numbered {first} to {}", k.trim(), first + 19),
                ));
            }
            None => {
                map.insert(k, vec![x]);
            }
        }
    }
    Ok(map)
}

/// DigitalGlobe's names (RPB and XML, lower-cased) → GDAL's.
fn rpb_names() -> HashMap<&'static str, &'static str> {
    [
        ("lineoffset", "LINE_OFF"),
        ("sampoffset", "SAMP_OFF"),
        ("latoffset", "LAT_OFF"),
        ("longoffset", "LONG_OFF"),
        ("heightoffset", "HEIGHT_OFF"),
        ("linescale", "LINE_SCALE"),
        ("sampscale", "SAMP_SCALE"),
        ("latscale", "LAT_SCALE"),
        ("longscale", "LONG_SCALE"),
        ("heightscale", "HEIGHT_SCALE"),
        ("linenumcoef", "LINE_NUM_COEFF"),
        ("linedencoef", "LINE_DEN_COEFF"),
        ("sampnumcoef", "SAMP_NUM_COEFF"),
        ("sampdencoef", "SAMP_DEN_COEFF"),
    ]
    .into_iter()
    .collect()
}
