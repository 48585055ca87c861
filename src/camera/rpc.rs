//! Rational polynomial camera model (RPC00B, GDAL's metadata names):
//! ground (longitude, latitude in degrees; ellipsoidal height in metres) →
//! scan pixel. Convention: (SAMP_OFF, LINE_OFF) = (0, 0) is the *centre* of
//! the first pixel, so our continuous scan coordinates (centres at +½) are
//! the RPC's sample and line plus ½ — as GDAL's RPC transformer reports them.
//!
//! Readers so far: the "KEY: value" text of IKONOS `rpc.txt`, GDAL
//! `_RPC.TXT` and Planet files, and the GeoTIFF RPCCoefficientTag (50844).
//! The rest (RPB, OSSIM .geom, DIMAP, WorldView XML) and rectification with
//! RPC are the satellite issue's work still to do.

use crate::error::{Error, Result};
use std::path::Path;

/// The 90 numbers of an RPC00B model.
#[derive(Clone, Debug, PartialEq)]
pub struct Rpc {
    pub line_off: f64,
    pub samp_off: f64,
    pub lat_off: f64,
    pub long_off: f64,
    pub height_off: f64,
    pub line_scale: f64,
    pub samp_scale: f64,
    pub lat_scale: f64,
    pub long_scale: f64,
    pub height_scale: f64,
    pub line_num: [f64; 20],
    pub line_den: [f64; 20],
    pub samp_num: [f64; 20],
    pub samp_den: [f64; 20],
}

/// The 20 RPC00B terms of normalised (L = longitude, P = latitude, H = height).
#[inline]
fn terms(l: f64, p: f64, h: f64) -> [f64; 20] {
    [
        1.0, l, p, h, l * p, l * h, p * h, l * l, p * p, h * h,
        p * l * h, l * l * l, l * p * p, l * h * h, l * l * p, p * p * p, p * h * h, l * l * h, p * p * h, h * h * h,
    ]
}

#[inline]
fn dot(a: &[f64; 20], t: &[f64; 20]) -> f64 {
    a.iter().zip(t).map(|(x, y)| x * y).sum()
}

impl Rpc {
    /// Ground (longitude °, latitude °, height m) → scan (column, row),
    /// continuous with pixel centres at +½. `None` where a denominator vanishes.
    pub fn project(&self, lon: f64, lat: f64, h: f64) -> Option<(f64, f64)> {
        let t = terms((lon - self.long_off) / self.long_scale, (lat - self.lat_off) / self.lat_scale, (h - self.height_off) / self.height_scale);
        let (ld, sd) = (dot(&self.line_den, &t), dot(&self.samp_den, &t));
        if ld.abs() < 1e-12 || sd.abs() < 1e-12 {
            return None;
        }
        let line = dot(&self.line_num, &t) / ld * self.line_scale + self.line_off;
        let samp = dot(&self.samp_num, &t) / sd * self.samp_scale + self.samp_off;
        Some((samp + 0.5, line + 0.5))
    }

    /// The model of a crop starting at scan (column, row) of the full scene.
    #[must_use]
    pub fn cropped(&self, col: f64, row: f64) -> Rpc {
        Rpc { samp_off: self.samp_off - col, line_off: self.line_off - row, ..self.clone() }
    }

    fn from_map(get: &dyn Fn(&str) -> Option<Vec<f64>>, path: &Path) -> Result<Rpc> {
        let one = |k: &str| -> Result<f64> {
            let v = get(k).ok_or_else(|| Error::format(path, format!("RPC: {k} missing")))?;
            match v[..] {
                [x] if x.is_finite() => Ok(x),
                _ => Err(Error::format(path, format!("RPC: {k} is not one finite number"))),
            }
        };
        let coeffs = |k: &str| -> Result<[f64; 20]> {
            let v = get(k).ok_or_else(|| Error::format(path, format!("RPC: {k} missing")))?;
            let arr: [f64; 20] = v.try_into().map_err(|v: Vec<f64>| Error::format(path, format!("RPC: {k} has {} coefficients, not 20", v.len())))?;
            if arr.iter().any(|x| !x.is_finite()) {
                return Err(Error::format(path, format!("RPC: {k} has a non-finite coefficient")));
            }
            Ok(arr)
        };
        let rpc = Rpc {
            line_off: one("LINE_OFF")?,
            samp_off: one("SAMP_OFF")?,
            lat_off: one("LAT_OFF")?,
            long_off: one("LONG_OFF")?,
            height_off: one("HEIGHT_OFF")?,
            line_scale: one("LINE_SCALE")?,
            samp_scale: one("SAMP_SCALE")?,
            lat_scale: one("LAT_SCALE")?,
            long_scale: one("LONG_SCALE")?,
            height_scale: one("HEIGHT_SCALE")?,
            line_num: coeffs("LINE_NUM_COEFF")?,
            line_den: coeffs("LINE_DEN_COEFF")?,
            samp_num: coeffs("SAMP_NUM_COEFF")?,
            samp_den: coeffs("SAMP_DEN_COEFF")?,
        };
        for (k, v) in [("LINE_SCALE", rpc.line_scale), ("SAMP_SCALE", rpc.samp_scale), ("LAT_SCALE", rpc.lat_scale), ("LONG_SCALE", rpc.long_scale), ("HEIGHT_SCALE", rpc.height_scale)] {
            if v == 0.0 {
                return Err(Error::format(path, format!("RPC: {k} is zero")));
            }
        }
        Ok(rpc)
    }

    /// "KEY: value [unit]" lines (IKONOS rpc.txt, GDAL _RPC.TXT, Planet):
    /// coefficients as LINE_NUM_COEFF_1 … LINE_NUM_COEFF_20.
    pub fn parse_text(text: &str, path: &Path) -> Result<Rpc> {
        let mut map = std::collections::HashMap::<String, Vec<f64>>::new();
        for line in text.lines() {
            let Some((k, v)) = line.split_once(':') else { continue };
            let k = k.trim().to_ascii_uppercase();
            let Some(first) = v.split_whitespace().next() else { continue };
            let Ok(x) = first.parse::<f64>() else { continue };
            // LINE_NUM_COEFF_7 → LINE_NUM_COEFF[6]
            if let Some((base, idx)) = k.rsplit_once('_').filter(|(b, _)| b.ends_with("_COEFF")) {
                if let Ok(i) = idx.parse::<usize>() {
                    if (1..=20).contains(&i) {
                        let e = map.entry(base.to_string()).or_insert_with(|| vec![f64::NAN; 20]);
                        e[i - 1] = x;
                        continue;
                    }
                }
            }
            map.insert(k, vec![x]);
        }
        if !map.contains_key("LINE_OFF") {
            return Err(Error::unsupported(path, "not an RPC text file (no LINE_OFF)"));
        }
        Rpc::from_map(&|k| map.get(k).cloned(), path)
    }

    /// Reads a text RPC file.
    pub fn read_text(path: &Path) -> Result<Rpc> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Rpc::parse_text(&text, path)
    }

    /// The GeoTIFF RPCCoefficientTag (50844): ERR_BIAS, ERR_RAND, the ten
    /// offsets and scales, then the four sets of 20 coefficients.
    pub fn from_geotiff(path: &Path) -> Result<Rpc> {
        let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let mut dec = tiff::decoder::Decoder::new(std::io::BufReader::new(f)).map_err(|e| Error::from_tiff(path, e))?;
        let v = dec
            .find_tag(tiff::tags::Tag::Unknown(50844))
            .map_err(|e| Error::from_tiff(path, e))?
            .ok_or_else(|| Error::format(path, "no RPC tag (50844)"))?;
        let v: Vec<f64> = match v {
            tiff::decoder::ifd::Value::List(items) => items.into_iter().filter_map(|x| x.into_f64().ok()).collect(),
            _ => Vec::new(),
        };
        if v.len() != 92 {
            return Err(Error::format(path, format!("the RPC tag holds {} numbers, not 92", v.len())));
        }
        let names = ["LINE_OFF", "SAMP_OFF", "LAT_OFF", "LONG_OFF", "HEIGHT_OFF", "LINE_SCALE", "SAMP_SCALE", "LAT_SCALE", "LONG_SCALE", "HEIGHT_SCALE"];
        let sets = ["LINE_NUM_COEFF", "LINE_DEN_COEFF", "SAMP_NUM_COEFF", "SAMP_DEN_COEFF"];
        let get = |k: &str| -> Option<Vec<f64>> {
            if let Some(i) = names.iter().position(|n| *n == k) {
                return Some(vec![v[2 + i]]);
            }
            sets.iter().position(|n| *n == k).map(|s| v[12 + 20 * s..32 + 20 * s].to_vec())
        };
        Rpc::from_map(&get, path)
    }
}
