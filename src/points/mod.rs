//! Irregular height points as users have them: CSV/XYZ text (surveyed
//! heights, other tools' exports), LAS 1.0–1.4 and LAZ (lidar and drone
//! point clouds). Each file is read as a stream of batches, never whole.

pub mod las_file;
mod laz_chunks;
pub mod text;

use crate::error::{Error, Result};
use crate::geodesy::Crs;
use crate::progress::Cancel;
use std::path::{Path, PathBuf};

/// A point on the ground with its height.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// Which returns of a point cloud are kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Returns {
    #[default]
    All,
    /// The first return of each pulse (a DSM: what the pulse hit first).
    First,
    /// The last return (closest to the ground).
    Last,
}

impl crate::options::Choice for Returns {
    const NAMES: &'static [&'static str] = &["all", "first", "last"];
    fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "all" => Returns::All,
            "first" => Returns::First,
            "last" => Returns::Last,
            _ => return None,
        })
    }
}

/// Which points of a point cloud take part; text files have no classes
/// or returns, and every point of theirs does.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Filter {
    /// ASPRS classes kept (2 ground: a DTM); `None`: every class but noise
    /// (7 low noise, 18 high noise) and withheld points.
    pub classes: Option<Vec<u8>>,
    pub returns: Returns,
}

impl Filter {
    pub fn keeps(&self, class: u8, return_number: u8, returns: u8, withheld: bool) -> bool {
        let class_ok = match &self.classes {
            Some(c) => c.contains(&class),
            None => !withheld && class != 7 && class != 18,
        };
        class_ok
            && match self.returns {
                Returns::All => true,
                Returns::First => return_number <= 1,
                Returns::Last => return_number >= returns,
            }
    }
}

/// How a text file's columns are found.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Columns {
    /// From the header (x/easting/lon…, y/northing/lat…, z/height/elevation…),
    /// else the first three.
    #[default]
    Auto,
    /// Named in the header, or counted from 1.
    Given([String; 3]),
}

/// A file of points.
#[derive(Clone, Debug)]
pub struct PointFile {
    pub path: PathBuf,
    pub kind: Kind,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Text,
    Las,
}

impl PointFile {
    /// The file at `path`, told apart by its first bytes (LAS and LAZ begin
    /// with "LASF"), else text.
    pub fn open(path: &Path) -> Result<PointFile> {
        use std::io::Read;
        let mut head = [0u8; 4];
        let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        if !f.metadata().map_err(|e| Error::io(path, e))?.is_file() {
            return Err(Error::Format { path: path.into(), msg: "not a file of points".into() });
        }
        let n = f.read(&mut head).map_err(|e| Error::io(path, e))?;
        let kind = if n == 4 && &head == b"LASF" { Kind::Las } else { Kind::Text };
        Ok(PointFile { path: path.into(), kind })
    }

    /// The CRS the file says its points are in: a LAS file's WKT or GeoTIFF
    /// keys, a text file's `.prj` beside it; `None` where it says nothing.
    pub fn crs(&self) -> Result<Option<Crs>> {
        match self.kind {
            Kind::Las => las_file::crs(&self.path),
            Kind::Text => {
                let prj = self.path.with_extension("prj");
                if !prj.is_file() {
                    return Ok(None);
                }
                let text = crate::io::bounded_read::read_text_bounded(&prj, "a .prj file", 1 << 20)?;
                Crs::from_wkt(text.trim_start_matches('\u{feff}').trim()).map(Some).map_err(|msg| Error::Format { path: prj, msg })
            }
        }
    }

    /// Reads every point `filter` keeps, in the file's order, handing them
    /// to `each` in batches with the bytes read so far; returns the number
    /// of points the file holds (kept or not).
    pub fn read(&self, columns: &Columns, filter: &Filter, cancel: &Cancel, each: &mut dyn FnMut(&[Point], u64) -> Result<()>) -> Result<u64> {
        match self.kind {
            Kind::Text => text::read(&self.path, columns, cancel, each),
            Kind::Las => las_file::read(&self.path, filter, cancel, each),
        }
    }
}

/// The largest height taken, in the points' units: past it (ten thousand
/// kilometres) a height is a fault of the file, not terrain.
pub const MAX_HEIGHT: f64 = 1e7;

/// Points in a batch handed on at once.
pub const BATCH: usize = 1 << 16;
