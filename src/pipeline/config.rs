//! What `rectify` is asked to do, validated (the CLI builds it).

use crate::dem::Miss;
use crate::gcm::GcmSpec;
use crate::io::tiff_out::Compression;
use crate::resample::Kernel;
use crate::transform::Trend;
use std::path::PathBuf;

#[derive(Clone, Debug, serde::Serialize)]
pub enum DemSource {
    File(PathBuf),
    /// A constant height, metres.
    Height(f64),
    /// The sensor model's own: an RPC's HEIGHT_OFF (in the DEM datum, so
    /// less the geoid's undulation when there is one); an error for frame
    /// cameras, which have none.
    ModelHeight,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BigTiff {
    Auto,
    Yes,
    No,
}

/// Which way the output is made: bands of tile rows, or bands of tile
/// columns (the tiles then go to the file in that order). A band's pixels
/// read the scan rows it crosses; bands along the scan's rows read fewer of
/// them, in place from the mapped file, where bands across them (a scan
/// turned ~90° against the output) would copy tall windows a row at a time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BandOrder {
    /// Whichever of the two crosses fewer scan rows a band.
    Auto,
    Rows,
    Columns,
}

impl std::str::FromStr for BandOrder {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(BandOrder::Auto),
            "rows" => Ok(BandOrder::Rows),
            "columns" => Ok(BandOrder::Columns),
            _ => Err(format!("'{s}' is not auto, rows or columns")),
        }
    }
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct RectifyConfig {
    pub image: PathBuf,
    pub camera: PathBuf,
    /// The camera itself, when it does not come from `camera` (a batch
    /// block builds it from an interior file and a row of exterior
    /// orientations); `camera` then names its origin in messages.
    #[serde(skip)]
    pub camera_file: Option<crate::camera::CameraFile>,
    pub dem: DemSource,
    pub dem_hole: Miss,
    pub dem_outside: Miss,
    pub output: PathBuf,
    /// Output pixel size, ground units; `None`: the scan's mean GSD.
    pub gsd: Option<f64>,
    /// `[minx, miny, maxx, maxy]`; `None`: the scan's footprint on the DEM.
    pub bounds: Option<[f64; 4]>,
    /// Only this piece of the output grid, in tiles: `[col, row, w, h]`.
    /// Pieces made separately assemble into the whole, pixel for pixel.
    pub window: Option<[u32; 4]>,
    pub gcm: GcmSpec,
    /// Choose `gcm.k` from the DEM (see `rectify`); off when the user gives
    /// `--sparsity`.
    pub auto_sparsity: bool,
    pub trend: Trend,
    pub kernel: Kernel,
    pub tile: u32,
    pub band_order: BandOrder,
    pub compress: Compression,
    pub bigtiff: BigTiff,
    /// Nodata value written where there is no image (ignored with `alpha`).
    pub nodata: f64,
    pub alpha: bool,
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// Memory budget, bytes.
    pub memory: u64,
    pub quiet: bool,
    /// Put the output on disk (fsync) before it gets its name, so that not
    /// even a power failure leaves an incomplete file under that name. Off
    /// (`--no-sync`): the kernel writes it back in its own time, as after
    /// `cat` or `gdalwarp`.
    pub sync: bool,
}

impl RectifyConfig {
    /// A configuration with the documented defaults.
    pub fn new(image: PathBuf, camera: PathBuf, dem: DemSource, output: PathBuf) -> RectifyConfig {
        RectifyConfig {
            image,
            camera,
            camera_file: None,
            dem,
            dem_hole: Miss::Error,
            dem_outside: Miss::Nodata,
            output,
            gsd: None,
            bounds: None,
            window: None,
            gcm: GcmSpec { k: 16, mode: crate::gcm::CorrectionMode::Bilinear, max_error: None },
            auto_sparsity: true,
            trend: Trend::Plane,
            kernel: Kernel::Bilinear,
            tile: 256,
            band_order: BandOrder::Auto,
            compress: Compression::Deflate,
            bigtiff: BigTiff::Auto,
            nodata: 0.0,
            alpha: false,
            threads: 0,
            memory: 128 << 20,
            quiet: true,
            sync: true,
        }
    }
}
