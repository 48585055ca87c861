//! What `grid` is asked to do, and what it reports.

use crate::geodesy::Crs;
use crate::geom::Gsd;
use crate::io::tiff_out::Compression;
use crate::options::Overviews;
use crate::points::{Columns, Filter};
use std::path::PathBuf;

/// How cells get their heights.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Linear in each Delaunay triangle.
    Tin,
    /// Natural neighbour (Sibson): smooth, without the TIN's facets.
    Natural,
    /// Inverse distance to a power (Shepard).
    Idw,
    /// The nearest point's height.
    Nearest,
    /// The highest point in the cell (a DSM from a point cloud).
    Max,
    /// The lowest point in the cell.
    Min,
    /// The mean of the points in the cell.
    Mean,
}

impl crate::options::Choice for Method {
    const NAMES: &'static [&'static str] = &["tin", "natural", "idw", "nearest", "max", "min", "mean"];
    fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "tin" => Method::Tin,
            "natural" => Method::Natural,
            "idw" => Method::Idw,
            "nearest" => Method::Nearest,
            "max" => Method::Max,
            "min" => Method::Min,
            "mean" => Method::Mean,
            _ => return None,
        })
    }
}

/// What `grid` is asked to do (serde: the same object read back).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub struct GridOptions {
    pub inputs: Vec<PathBuf>,
    pub output: PathBuf,
    pub gsd: Gsd,
    /// `[minx, miny, maxx, maxy]` in the output CRS (default: the points'),
    /// snapped outward to multiples of the GSD.
    pub bounds: Option<[f64; 4]>,
    /// The DEM's CRS (default: the points').
    #[serde(with = "crate::geodesy::optional_crs_definition")]
    pub crs: Option<Crs>,
    /// The points' CRS where their files say none (default: `crs`).
    #[serde(with = "crate::geodesy::optional_crs_definition")]
    pub points_crs: Option<Crs>,
    pub method: Method,
    /// The longest triangle side (tin, natural) gridded across; beyond it,
    /// no height (default: ten times the points' typical spacing).
    pub max_edge: Option<f64>,
    /// Points within this distance take part (idw, nearest; default: the
    /// longest side's).
    pub radius: Option<f64>,
    pub power: f64,
    /// At most this many nearest points (idw).
    pub neighbours: Option<usize>,
    pub columns: Columns,
    pub filter: Filter,
    /// Drop points outside their neighbours' heights by more than this many
    /// robust sigmas (`None`: keep every point).
    pub blunders: Option<f64>,
    pub memory: u64,
    pub threads: usize,
    pub tile: u32,
    /// Cells a block's side (default: from the points' density and the
    /// memory); the DEM does not depend on it.
    pub block: Option<u32>,
    /// Only these tiles of the whole DEM: first column, first row,
    /// columns, rows (a piece for `assemble`).
    pub window: Option<[u32; 4]>,
    /// The `i`th of `n` pieces (1-based): bands of whole tile rows.
    pub shard: Option<(u32, u32)>,
    pub compress: Compression,
    pub level: Option<u8>,
    pub overviews: Overviews,
    pub cog: bool,
    pub sync: bool,
}

impl GridOptions {
    pub fn new(inputs: Vec<PathBuf>, output: PathBuf, gsd: Gsd) -> GridOptions {
        GridOptions {
            inputs,
            output,
            gsd,
            bounds: None,
            crs: None,
            points_crs: None,
            method: Method::Tin,
            max_edge: None,
            radius: None,
            power: 2.0,
            neighbours: None,
            columns: Columns::Auto,
            filter: Filter::default(),
            blunders: Some(DEFAULT_BLUNDER_SIGMAS),
            memory: 512 << 20,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            tile: 256,
            block: None,
            window: None,
            shard: None,
            compress: Compression::Deflate,
            level: None,
            overviews: Overviews::Auto,
            cog: false,
            sync: true,
        }
    }
}

/// A blunder's least distance outside its neighbours, in their robust sigmas.
pub const DEFAULT_BLUNDER_SIGMAS: f64 = 8.0;

/// Where a DEM cell has no height.
pub const NODATA: f64 = -9999.0;

/// What a `grid` run did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GridReport {
    pub output: PathBuf,
    pub crs: String,
    pub width: u32,
    pub height: u32,
    pub gsd: [f64; 2],
    pub bounds: [f64; 4],
    pub method: Method,
    /// Points the files hold.
    pub points_read: u64,
    /// Left out by class or return (point clouds).
    pub points_filtered: u64,
    /// Outside the DEM and the ring of neighbours around it.
    pub points_outside: u64,
    /// Could not be brought into the DEM's CRS.
    pub points_unprojected: u64,
    /// Dropped as blunders.
    pub blunders: u64,
    /// Gridded.
    pub points_used: u64,
    /// The points' typical spacing (the median over the area they cover).
    pub spacing: f64,
    pub max_edge: f64,
    pub cells_with_height: u64,
    pub cells_without: u64,
    /// Triangles whose circumcircle reached too far to be sure of (counted,
    /// used as found).
    pub unsettled: u64,
    /// Cells a block's side.
    pub block: u32,
    pub seconds: f64,
    pub warnings: Vec<String>,
}
