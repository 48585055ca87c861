//! Rational polynomial camera model (RPC00B, GDAL's metadata names):
//! ground (longitude, latitude in degrees; ellipsoidal height in metres) →
//! scan pixel. Convention: (SAMP_OFF, LINE_OFF) = (0, 0) is the *centre* of
//! the first pixel, so our continuous scan coordinates (centres at +½) are
//! the RPC's sample and line plus ½ — as GDAL's RPC transformer reports them.
//!
//! The readers of the formats found in the wild are in `read`.

pub mod fit;
mod read;

/// GDAL's metadata names of the 14 RPC items (the other readers map onto them).
pub const GDAL_NAMES: [&str; 14] = [
    "LINE_OFF",
    "SAMP_OFF",
    "LAT_OFF",
    "LONG_OFF",
    "HEIGHT_OFF",
    "LINE_SCALE",
    "SAMP_SCALE",
    "LAT_SCALE",
    "LONG_SCALE",
    "HEIGHT_SCALE",
    "LINE_NUM_COEFF",
    "LINE_DEN_COEFF",
    "SAMP_NUM_COEFF",
    "SAMP_DEN_COEFF",
];

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
pub(crate) fn terms(l: f64, p: f64, h: f64) -> [f64; 20] {
    [
        1.0,
        l,
        p,
        h,
        l * p,
        l * h,
        p * h,
        l * l,
        p * p,
        h * h,
        p * l * h,
        l * l * l,
        l * p * p,
        l * h * h,
        l * l * p,
        p * p * p,
        p * h * h,
        l * l * h,
        p * p * h,
        h * h * h,
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

    /// The line and sample denominators at ground (longitude °, latitude °,
    /// height m): where one passes through zero the image goes to infinity
    /// and folds.
    pub fn denominators(&self, lon: f64, lat: f64, h: f64) -> (f64, f64) {
        let t = terms((lon - self.long_off) / self.long_scale, (lat - self.lat_off) / self.lat_scale, (h - self.height_off) / self.height_scale);
        (dot(&self.line_den, &t), dot(&self.samp_den, &t))
    }

    /// The model as GDAL's `_RPC.TXT` sidecar text (`KEY: value` lines).
    pub fn to_gdal_text(&self) -> String {
        let mut t = String::new();
        let scalars = [
            self.line_off,
            self.samp_off,
            self.lat_off,
            self.long_off,
            self.height_off,
            self.line_scale,
            self.samp_scale,
            self.lat_scale,
            self.long_scale,
            self.height_scale,
        ];
        for (name, v) in read::SCALARS.iter().zip(scalars) {
            t += &format!("{name}: {v:?}\n");
        }
        for (name, set) in read::SETS.iter().zip([&self.line_num, &self.line_den, &self.samp_num, &self.samp_den]) {
            for (i, v) in set.iter().enumerate() {
                t += &format!("{name}_{}: {v:?}\n", i + 1);
            }
        }
        t
    }

    /// The model of a crop starting at scan (column, row) of the full scene.
    #[must_use]
    pub fn cropped(&self, col: f64, row: f64) -> Rpc {
        Rpc { samp_off: self.samp_off - col, line_off: self.line_off - row, ..self.clone() }
    }

    /// Ground (longitude °, latitude °) at height `h` seen at scan (column,
    /// row): Newton's method from the model's centre, to `tol_px`.
    pub fn locate(&self, col: f64, row: f64, h: f64, tol_px: f64) -> Option<(f64, f64)> {
        let (mut lon, mut lat) = (self.long_off, self.lat_off);
        let (dl, dp) = (self.long_scale * 1e-6, self.lat_scale * 1e-6);
        for _ in 0..30 {
            let (c, r) = self.project(lon, lat, h)?;
            let (ec, er) = (col - c, row - r);
            if ec.hypot(er) < tol_px {
                return Some((lon, lat));
            }
            let (cl, rl) = self.project(lon + dl, lat, h)?;
            let (cp, rp) = self.project(lon, lat + dp, h)?;
            let j = nalgebra::Matrix2::new((cl - c) / dl, (cp - c) / dp, (rl - r) / dl, (rp - r) / dp);
            let step = j.try_inverse()? * nalgebra::Vector2::new(ec, er);
            lon += step.x;
            lat += step.y;
            if !(lon.is_finite() && lat.is_finite()) {
                return None;
            }
        }
        None
    }

    /// Scan pixels per degree of latitude and of longitude near the centre
    /// (for step sizes and ground sample distances).
    pub fn pixels_per_degree(&self) -> (f64, f64) {
        let (lon, lat, h) = (self.long_off, self.lat_off, self.height_off);
        let d = 1e-4;
        let at = |lo: f64, la: f64| self.project(lo, la, h).unwrap_or((f64::NAN, f64::NAN));
        let (c0, r0) = at(lon, lat);
        let (c1, r1) = at(lon, lat + d);
        let (c2, r2) = at(lon + d, lat);
        ((c1 - c0).hypot(r1 - r0) / d, (c2 - c0).hypot(r2 - r0) / d)
    }

    pub(crate) fn from_map(get: &dyn Fn(&str) -> Option<Vec<f64>>, path: &Path) -> Result<Rpc> {
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
            if let Some(i) = arr.iter().position(|x| !x.is_finite()) {
                return Err(Error::format(
                    path,
                    format!("RPC: {k}_{} (of 1..20; in OSSIM's files, counted from 0, {k}_{}) is missing or not finite", i + 1, i),
                ));
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
        for (k, den) in [("LINE_DEN_COEFF", &rpc.line_den), ("SAMP_DEN_COEFF", &rpc.samp_den)] {
            if den.iter().all(|&c| c == 0.0) {
                return Err(Error::format(path, format!("RPC: {k} is all zero (no denominator)")));
            }
        }
        for (k, v) in [
            ("LINE_SCALE", rpc.line_scale),
            ("SAMP_SCALE", rpc.samp_scale),
            ("LAT_SCALE", rpc.lat_scale),
            ("LONG_SCALE", rpc.long_scale),
            ("HEIGHT_SCALE", rpc.height_scale),
        ] {
            if v == 0.0 {
                return Err(Error::format(path, format!("RPC: {k} is zero")));
            }
        }
        // Offsets and scales outside the Earth: a unit or field mix-up, told
        // here rather than as a footprint that meets no DEM.
        let bad = |k: &str, v: f64, range: &str| Err(Error::format(path, format!("RPC: {k} {v} is not {range}")));
        if !(-90.0..=90.0).contains(&rpc.lat_off) {
            return bad("LAT_OFF", rpc.lat_off, "a latitude (-90 to 90 degrees)");
        }
        if !(-180.0..=360.0).contains(&rpc.long_off) {
            return bad("LONG_OFF", rpc.long_off, "a longitude (-180 to 360 degrees)");
        }
        if !(rpc.lat_scale.abs() <= 90.0) {
            return bad("LAT_SCALE", rpc.lat_scale, "a span of latitudes (up to 90 degrees)");
        }
        if !(rpc.long_scale.abs() <= 180.0) {
            return bad("LONG_SCALE", rpc.long_scale, "a span of longitudes (up to 180 degrees)");
        }
        if !(rpc.height_off.abs() <= 20_000.0 && rpc.height_scale.abs() <= 20_000.0) {
            return bad("HEIGHT_OFF / HEIGHT_SCALE", rpc.height_off.abs().max(rpc.height_scale.abs()), "a height on the Earth (within 20 km)");
        }
        if !(rpc.line_scale > 0.0 && rpc.samp_scale > 0.0) {
            return bad("LINE_SCALE / SAMP_SCALE", rpc.line_scale.min(rpc.samp_scale), "a positive number of pixels");
        }
        Ok(rpc)
    }
}
