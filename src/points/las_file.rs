//! LAS 1.0–1.4 and LAZ point clouds, through the `las` crate (its `laz`
//! feature: laz-rs, LASzip in pure Rust, so no system library): read in
//! batches, each point's class and return kept or not by the filter.

use super::{Filter, Point, BATCH};
use crate::error::{Error, Result};
use crate::geodesy::Crs;
use crate::progress::Cancel;
use std::path::Path;

fn failed(path: &Path, e: las::Error) -> Error {
    match e {
        las::Error::Io(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            Error::Format { path: path.into(), msg: "the file ends before the points its header counts".into() }
        }
        las::Error::Io(e) => Error::io(path, e),
        e => Error::Format { path: path.into(), msg: format!("not a readable LAS/LAZ file: {e}") },
    }
}

fn open(path: &Path) -> Result<las::Reader> {
    super::laz_chunks::check(path)?;
    let reader = las::Reader::from_path(path).map_err(|e| failed(path, e))?;
    let h = reader.header();
    let format = h.point_format();
    // Every coordinate is an integer times the header's scale plus its
    // offset: a scale or offset that is no number makes every point none.
    let t = h.transforms();
    for (axis, t) in [("x", t.x), ("y", t.y), ("z", t.z)] {
        if !(t.scale.is_finite() && t.scale != 0.0 && t.offset.is_finite()) {
            return Err(Error::Format {
                path: path.into(),
                msg: format!("the header's {axis} scale {} and offset {} make no coordinates (a finite, non-zero scale and a finite offset)", t.scale, t.offset),
            });
        }
    }
    // An uncompressed file holds its points after the header: a count the
    // file cannot hold is refused before anything is read.
    if !format.is_compressed {
        let len = std::fs::metadata(path).map_err(|e| Error::io(path, e))?.len();
        let need = h.number_of_points().checked_mul(u64::from(format.len()));
        if need.is_none_or(|n| n > len) {
            return Err(Error::Format {
                path: path.into(),
                msg: format!("the header counts {} points, more than the file's {len} bytes hold", h.number_of_points()),
            });
        }
    }
    Ok(reader)
}

/// The CRS in the file's WKT record, else its GeoTIFF keys' EPSG code.
pub fn crs(path: &Path) -> Result<Option<Crs>> {
    let reader = open(path)?;
    let h = reader.header();
    if let Some(wkt) = h.get_wkt_crs_bytes() {
        let text = String::from_utf8_lossy(wkt);
        let text = text.trim_matches(char::from(0)).trim();
        if !text.is_empty() {
            return Crs::from_wkt(text).map(Some).map_err(|m| Error::Format { path: path.into(), msg: format!("its WKT CRS: {m}") });
        }
    }
    let keys = h.get_geotiff_crs().map_err(|e| failed(path, e))?;
    let Some(keys) = keys else { return Ok(None) };
    let code = keys.get_projected_crs_geo_key_value().or_else(|| keys.get_geodetic_crs_geo_key_value());
    match code {
        Some(c) if c != 0 && c != 32767 => {
            Crs::from_epsg(u32::from(c)).map(Some).map_err(|m| Error::Format { path: path.into(), msg: format!("its GeoTIFF CRS: {m}") })
        }
        _ => Ok(None),
    }
}

pub fn read(path: &Path, filter: &Filter, cancel: &Cancel, each: &mut dyn FnMut(&[Point], u64) -> Result<()>) -> Result<u64> {
    let mut reader = open(path)?;
    let total = reader.header().number_of_points();
    let record = u64::from(reader.header().point_format().len());
    let mut data = las::PointDataBuilder::new().for_header(reader.header()).build();
    let mut batch = Vec::with_capacity(BATCH);
    let mut done = 0u64;
    while done < total {
        if cancel.is_cancelled() {
            return Err(Error::Cancelled);
        }
        let n = reader.fill_points(BATCH as u64, &mut data).map_err(|e| failed(path, e))?;
        if n == 0 {
            break;
        }
        done += n;
        batch.clear();
        for (i, p) in data.points().enumerate() {
            let p = p.map_err(|e| failed(path, e))?;
            if !(p.z.abs() <= super::MAX_HEIGHT && p.x.is_finite() && p.y.is_finite()) {
                return Err(Error::Format {
                    path: path.into(),
                    msg: format!("point {}: the height {} is past any terrain's (its scale and offset?)", done - n + i as u64 + 1, p.z),
                });
            }
            if filter.keeps(u8::from(p.classification), p.return_number, p.number_of_returns, p.is_withheld) {
                batch.push(Point { x: p.x, y: p.y, z: p.z });
            }
        }
        each(&batch, done * record)?;
    }
    Ok(done)
}
