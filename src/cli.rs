//! Command-line arguments (clap) and their validation into the library's
//! option structs. Raw flags stop here.

use clap::{Args, Parser, Subcommand};
use gcm_ortho::dem::Miss;
use gcm_ortho::gcm::{CorrectionMode, GcmSpec};
use gcm_ortho::io::tiff_out::Compression;
use gcm_ortho::pipeline::{BigTiff, DemSource, RectifyConfig};
use gcm_ortho::resample::Kernel;
use gcm_ortho::synth::{CameraKind, Relief, SynthOptions};
use gcm_ortho::transform::Trend;
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(name = "gcm-ortho", version, about = "Orthorectification of huge scans on small machines by the generalized correction matrix")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Generate a synthetic scene: scan, camera file, DEM, truth orthophoto, checkpoints.
    Synth(SynthArgs),
    /// Orthorectify a scan.
    Rectify(Box<RectifyArgs>),
    /// Accuracy of A + GCM against the exact model, per sparsity and mode.
    Accuracy(AccuracyArgs),
    /// Generate a scene in a temporary folder, rectify it and report accuracy and speed.
    Demo(DemoArgs),
    /// Run many rectify jobs from a manifest: resumable, shardable.
    Batch(BatchArgs),
    /// Put pieces made with `rectify --window` together into one GeoTIFF.
    Assemble(AssembleArgs),
    /// The image → ground regular grid of an RPC image (seed 004), as GDAL
    /// geolocation arrays, with its accuracy table.
    RpcGrid(RpcGridArgs),
}

/// The image and its sensor model: a camera file, or an RPC file with
/// what goes with it (shared by `rectify` and `rpc-grid`).
#[derive(Args, Debug)]
pub struct SensorArgs {
    /// The scan or image (TIFF or BigTIFF).
    #[arg(long)]
    pub image: PathBuf,
    /// The camera file (TOML): a frame camera, or model = "rpc" (which
    /// rpc-grid needs).
    #[arg(long, required_unless_present = "rpc", conflicts_with = "rpc")]
    pub camera: Option<PathBuf>,
    /// An RPC model instead of a camera file, in any supported format
    /// (GeoTIFF RPC tag, NITF, _RPC.TXT, RPB, OSSIM .geom, DIMAP or
    /// WorldView XML); the image itself when it carries one.
    #[arg(long)]
    pub rpc: Option<PathBuf>,
    /// With --rpc: the image is a crop starting at this column,row of the
    /// scene the RPC describes (default: the tile offset a DigitalGlobe XML
    /// records for the image's file name, else none).
    #[arg(long, requires = "rpc")]
    pub rpc_offset: Option<String>,
    /// With --rpc: the DEM's heights are above this geoid (PROJ .gtx grid,
    /// e.g. egm96_15.gtx for SRTM); RPCs expect ellipsoidal heights.
    #[arg(long, requires = "rpc")]
    pub geoid: Option<PathBuf>,
}

impl SensorArgs {
    /// The camera file or RPC file named, and with --rpc the camera file
    /// made from it (`crs`: the ground CRS, None for the scene's UTM zone).
    pub fn model(&self, crs: Option<u32>) -> Result<(PathBuf, Option<gcm_ortho::camera::CameraFile>), String> {
        match (&self.camera, &self.rpc) {
            (Some(c), None) => Ok((c.clone(), None)),
            (None, Some(r)) => {
                let offset = match self.rpc_offset.as_deref() {
                    Some(o) => Some(parse_offset(o)?),
                    // A tile of a DigitalGlobe product: its offset is in the XML.
                    None => std::fs::read_to_string(r).ok().and_then(|xml| {
                        let name = self.image.file_name()?.to_str()?;
                        gcm_ortho::camera::rpc::Rpc::tile_offset(&xml, name)
                    }),
                };
                Ok((r.clone(), Some(gcm_ortho::camera::file::Camera::rpc_file(r, crs, offset, self.geoid.as_deref()))))
            }
            _ => Err("give --camera FILE or --rpc FILE".into()),
        }
    }
}

#[derive(Args, Debug)]
pub struct RpcGridArgs {
    #[command(flatten)]
    pub sensor: SensorArgs,
    /// DEM (any EPSG CRS; heights above the geoid with --geoid).
    #[arg(long)]
    pub dem: PathBuf,
    /// Grid step, image pixels.
    #[arg(long, default_value_t = 8)]
    pub step: u32,
    /// Also print seed 004's accuracy table for these steps, e.g. 2,4,8,16,32.
    #[arg(long)]
    pub accuracy: Option<String>,
    /// Accuracy over every N-th pixel of each row and column.
    #[arg(long, default_value_t = 4)]
    pub sample: u32,
    /// Write the accuracy table here as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// The grid: a 3-band Float64 TIFF (longitude, latitude, height); a VRT
    /// of the image with GEOLOCATION metadata is written beside it.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
}

#[derive(Args, Debug)]
pub struct AssembleArgs {
    /// The pieces (GeoTIFFs written by `rectify --window`).
    #[arg(required = true)]
    pub pieces: Vec<PathBuf>,
    /// The assembled orthophoto
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
}

#[derive(Args, Debug)]
pub struct BatchArgs {
    /// The manifest (TOML).
    pub manifest: PathBuf,
    /// Jobs to run at a time, sharing --memory.
    #[arg(long, default_value_t = 1)]
    pub jobs: usize,
    /// Memory budget of the whole batch.
    #[arg(long, default_value = "256M")]
    pub memory: String,
    /// Redo jobs whose outputs are current.
    #[arg(long)]
    pub force: bool,
    /// Write one JSON line per job here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Run the I-th of N shares of the jobs (1-based), e.g. 2/8.
    #[arg(long)]
    pub shard: Option<String>,
    /// The number of shares when the index comes from JOB_COMPLETION_INDEX.
    #[arg(long)]
    pub shard_count: Option<usize>,
    /// Worker threads per job (0: the cores shared among the jobs; a job of
    /// one thread runs its steps one after the other, one processor busy).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Only validate the manifest and list the jobs of this shard.
    #[arg(long)]
    pub dry_run: bool,
    /// No progress bar (there is none anyway when stderr is not a terminal)
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct SynthArgs {
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Scan size WxH in pixels.
    #[arg(long, default_value = "4000x4000")]
    pub size: String,
    /// Bands of the scan: 1 (grey), 3 (RGB) or 4 (RGB + near infrared)
    #[arg(long, default_value_t = 3)]
    pub bands: u32,
    /// Bits a sample: 8 or 16
    #[arg(long, default_value_t = 8)]
    pub bits: u32,
    /// Terrain of the generated DEM
    #[arg(long, default_value = "hilly", value_parser = ["flat", "hilly", "mountain"])]
    pub relief: String,
    /// A film scan with fiducial marks, a digital frame, or a satellite image with RPCs
    #[arg(long, default_value = "film", value_parser = ["film", "digital", "rpc"])]
    pub camera: String,
    /// Off-nadir angle of an RPC (satellite) scene, degrees: 2 to 35.
    #[arg(long, default_value_t = 25.0)]
    pub off_nadir: f64,
    /// Swing of the camera, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub kappa: f64,
    /// The scan file's layout
    #[arg(long, default_value = "strips", value_parser = ["strips", "tiles"])]
    pub layout: String,
    /// The scan file's compression
    #[arg(long, default_value = "none", value_parser = ["none", "deflate", "lzw"])]
    pub compress: String,
    /// DEM posting, metres.
    #[arg(long, default_value_t = 5.0)]
    pub dem_posting: f64,
    /// Photo scale denominator.
    #[arg(long, default_value_t = 10000.0)]
    pub scale: f64,
    /// Fiducial marks on film: 4 (corners) or 8.
    #[arg(long, default_value_t = 4)]
    pub fiducials: u32,
    /// Film image frame, mm: 230 (23 × 23 cm) or 180 (18 × 18 cm).
    #[arg(long, default_value_t = 230.0)]
    pub frame: f64,
    /// Seed of the scene's texture and relief: the same seed, the same files
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// No progress bar (there is none anyway when stderr is not a terminal)
    #[arg(long)]
    pub quiet: bool,
    /// Write only camera.toml, dem.tif and checkpoints.csv (no scan, no
    /// truth): for `accuracy --size` studies of very large scans.
    #[arg(long)]
    pub no_scan: bool,
}

/// `col,row` of `--rpc-offset`.
pub fn parse_offset(o: &str) -> Result<[f64; 2], String> {
    let v: Vec<f64> = o.split(',').map(|p| p.trim().parse::<f64>()).collect::<Result<_, _>>().map_err(|_| format!("--rpc-offset '{o}' is not col,row"))?;
    match v[..] {
        [c, r] if c.is_finite() && r.is_finite() => Ok([c, r]),
        _ => Err(format!("--rpc-offset '{o}' is not col,row")),
    }
}

pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("--size '{s}' is not WxH"))?;
    let w = w.trim().parse().map_err(|_| format!("--size '{s}': bad width"))?;
    let h = h.trim().parse().map_err(|_| format!("--size '{s}': bad height"))?;
    Ok((w, h))
}

impl SynthArgs {
    pub fn options(&self) -> Result<SynthOptions, String> {
        let (width, height) = parse_size(&self.size)?;
        Ok(SynthOptions {
            out: self.out.clone(),
            width,
            height,
            bands: self.bands,
            bits: self.bits,
            relief: match self.relief.as_str() {
                "flat" => Relief::Flat,
                "mountain" => Relief::Mountain,
                _ => Relief::Hilly,
            },
            camera: match self.camera.as_str() {
                "digital" => CameraKind::Digital,
                "rpc" => CameraKind::Rpc,
                _ => CameraKind::Film,
            },
            kappa_deg: self.kappa,
            tiled: self.layout == "tiles",
            compress: self.compress.parse::<Compression>()?,
            dem_posting: self.dem_posting,
            scale: self.scale,
            fiducials: self.fiducials,
            frame_mm: self.frame,
            off_nadir_deg: self.off_nadir,
            seed: self.seed,
            quiet: self.quiet,
            no_scan: self.no_scan,
        })
    }
}

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Keep the generated files in this folder instead of a temporary one.
    #[arg(long)]
    pub keep: Option<PathBuf>,
    /// Scan size of the demo scene.
    #[arg(long, default_value = "6000x6000")]
    pub size: String,
    /// No progress bar (there is none anyway when stderr is not a terminal)
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct RectifyArgs {
    #[command(flatten)]
    pub sensor: SensorArgs,
    /// With --rpc: the orthophoto's CRS, EPSG:<code> (default: the WGS84
    /// UTM zone of the scene's centre).
    #[arg(long, requires = "rpc")]
    pub crs: Option<String>,
    /// DEM (GeoTIFF or SRTM .hgt), in the orthophoto's CRS or any other
    /// (it is then reprojected on the fly).
    #[arg(long, conflicts_with = "height")]
    pub dem: Option<PathBuf>,
    /// A constant terrain height instead of a DEM, metres.
    #[arg(long, allow_negative_numbers = true)]
    pub height: Option<f64>,
    /// What to do in DEM holes: error, nodata, or a height.
    #[arg(long, default_value = "error")]
    pub dem_hole: String,
    /// What to do outside the DEM: error, nodata, or a height.
    #[arg(long, default_value = "nodata")]
    pub dem_outside: String,
    /// Output pixel size (default: the scan's mean GSD).
    #[arg(long)]
    pub gsd: Option<f64>,
    /// minx,miny,maxx,maxy or auto (the scan's footprint on the DEM).
    #[arg(long, default_value = "auto", allow_hyphen_values = true)]
    pub bounds: String,
    /// Only a piece of the output: col,row,width,height in output tiles.
    #[arg(long)]
    pub window: Option<String>,
    /// GCM node spacing k, output pixels (default: 16, or the DEM's posting
    /// in output pixels where finer, but at least 12).
    #[arg(long)]
    pub sparsity: Option<u32>,
    /// Error bound of the GCM in scan pixels (refines cells that miss it).
    #[arg(long)]
    pub max_error: Option<f64>,
    /// How the corrections between GCM nodes are found: interpolated
    /// bilinearly from the four nodes around, or one per cell (thesis)
    #[arg(long, default_value = "bilinear", value_parser = ["bilinear", "cell"])]
    pub corrections: String,
    /// The terrain plane of the approximation A: the DEM's least-squares
    /// trend plane over the output area, or its mean height
    #[arg(long, default_value = "plane", value_parser = ["plane", "mean"])]
    pub trend: String,
    /// Resampling kernel
    #[arg(long, default_value = "bilinear", value_parser = ["nearest", "bilinear", "cubic", "lanczos3"])]
    pub resample: String,
    /// Output tile size in pixels (a multiple of 16)
    #[arg(long, default_value_t = 256)]
    pub tile: u32,
    /// Make the output in bands of tile rows or of tile columns (auto: the
    /// one that reads the scan along its rows; columns for a scan turned
    /// ~90°). The pixels agree to the GCM's accuracy either way.
    #[arg(long, default_value = "auto", value_parser = ["auto", "rows", "columns"])]
    pub band_order: String,
    /// Tile compression (with the horizontal predictor for integer samples)
    #[arg(long, default_value = "deflate", value_parser = ["none", "deflate", "lzw", "zstd"])]
    pub compress: String,
    /// BigTIFF output (auto: when the output may pass 4 GB)
    #[arg(long, default_value = "auto", value_parser = ["auto", "yes", "no"])]
    pub bigtiff: String,
    /// Nodata value of the output.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, conflicts_with = "alpha")]
    pub nodata: f64,
    /// Add an alpha band instead of a nodata value.
    #[arg(long)]
    pub alpha: bool,
    /// Worker threads (0: all cores; 1: every step one after the other,
    /// one processor busy).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Memory budget, e.g. 128M or 1G.
    #[arg(long, default_value = "128M")]
    pub memory: String,
    /// No progress bar (there is none anyway when stderr is not a terminal)
    #[arg(long)]
    pub quiet: bool,
    /// Do not wait for the output to reach the disk before renaming it into
    /// place (faster where the disk is slower than the run; a power failure
    /// soon after may leave an incomplete file under the output's name).
    #[arg(long)]
    pub no_sync: bool,
    /// Write the run report here as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// The output orthophoto.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
}

pub fn parse_bytes(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let (num, mult) = match t.chars().last() {
        Some('K' | 'k') => (&t[..t.len() - 1], 1u64 << 10),
        Some('M' | 'm') => (&t[..t.len() - 1], 1 << 20),
        Some('G' | 'g') => (&t[..t.len() - 1], 1 << 30),
        _ => (t, 1),
    };
    let v: f64 = num.parse().map_err(|_| format!("'{s}' is not a size like 128M"))?;
    if !(v > 0.0) {
        return Err(format!("'{s}' must be positive"));
    }
    Ok((v * mult as f64) as u64)
}

fn parse_bounds(s: &str) -> Result<Option<[f64; 4]>, String> {
    if s == "auto" {
        return Ok(None);
    }
    let v: Vec<f64> =
        s.split(',').map(|p| p.trim().parse::<f64>()).collect::<Result<_, _>>().map_err(|_| format!("--bounds '{s}' is not minx,miny,maxx,maxy"))?;
    if v.len() != 4 || v.iter().any(|x| !x.is_finite()) || v[2] <= v[0] || v[3] <= v[1] {
        return Err(format!("--bounds '{s}' is not minx,miny,maxx,maxy with min < max"));
    }
    Ok(Some([v[0], v[1], v[2], v[3]]))
}

impl RectifyArgs {
    pub fn config(&self) -> Result<RectifyConfig, String> {
        let dem = match (&self.dem, self.height) {
            (Some(p), None) => DemSource::File(p.clone()),
            (None, Some(h)) if h.is_finite() => DemSource::Height(h),
            (None, Some(h)) => return Err(format!("--height {h} is not a finite number")),
            // An RPC has a height of its own (HEIGHT_OFF).
            (None, None) if self.sensor.rpc.is_some() => DemSource::ModelHeight,
            _ => return Err("give --dem FILE or --height METRES".into()),
        };
        if let Some(e) = self.max_error {
            if !(e > 0.0) || !e.is_finite() {
                return Err(format!("--max-error {e} must be a positive number"));
            }
        }
        let crs = match &self.crs {
            None => None,
            Some(c) => Some(gcm_ortho::camera::Crs::parse(c).ok_or_else(|| format!("--crs '{c}' is not of the form EPSG:<code>"))?.epsg),
        };
        let (camera, file) = self.sensor.model(crs)?;
        let mut cfg = RectifyConfig::new(self.sensor.image.clone(), camera, dem, self.output.clone());
        cfg.camera_file = file;
        cfg.dem_hole = self.dem_hole.parse::<Miss>().map_err(|e| format!("--dem-hole: {e}"))?;
        cfg.dem_outside = self.dem_outside.parse::<Miss>().map_err(|e| format!("--dem-outside: {e}"))?;
        cfg.gsd = self.gsd;
        cfg.bounds = parse_bounds(&self.bounds)?;
        cfg.window = match &self.window {
            None => None,
            Some(w) => {
                let v: Vec<u32> = w
                    .split(',')
                    .map(|p| p.trim().parse::<u32>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| format!("--window '{w}' is not col,row,width,height"))?;
                match v[..] {
                    [c, r, ww, hh] if ww > 0 && hh > 0 => Some([c, r, ww, hh]),
                    _ => return Err(format!("--window '{w}' is not col,row,width,height (tiles, width and height > 0)")),
                }
            }
        };
        cfg.gcm = GcmSpec { k: self.sparsity.unwrap_or(16), mode: self.corrections.parse::<CorrectionMode>()?, max_error: self.max_error };
        cfg.auto_sparsity = self.sparsity.is_none();
        if self.max_error.is_some() && cfg.gcm.mode == CorrectionMode::Cell {
            return Err("--max-error works with --corrections bilinear".into());
        }
        cfg.trend = if self.trend == "mean" { Trend::Mean } else { Trend::Plane };
        cfg.kernel = self.resample.parse::<Kernel>()?;
        cfg.tile = self.tile;
        cfg.band_order = self.band_order.parse()?;
        cfg.compress = self.compress.parse::<Compression>()?;
        cfg.bigtiff = match self.bigtiff.as_str() {
            "yes" => BigTiff::Yes,
            "no" => BigTiff::No,
            _ => BigTiff::Auto,
        };
        cfg.nodata = self.nodata;
        cfg.alpha = self.alpha;
        cfg.threads = self.threads;
        cfg.memory = parse_bytes(&self.memory).map_err(|e| format!("--memory: {e}"))?;
        cfg.quiet = self.quiet;
        cfg.sync = !self.no_sync;
        Ok(cfg)
    }
}

#[derive(Args, Debug)]
pub struct AccuracyArgs {
    /// A scene folder made by `synth` (scan.tif, camera.toml, dem.tif, checkpoints.csv).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// The scan (instead of --scene)
    #[arg(long)]
    pub image: Option<PathBuf>,
    /// The camera file (instead of --scene)
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// The DEM (instead of --scene)
    #[arg(long)]
    pub dem: Option<PathBuf>,
    /// Scan size WxH, when there is no scan file (`synth --no-scan`).
    #[arg(long)]
    pub size: Option<String>,
    /// Sparsities to tabulate.
    #[arg(long, default_value = "1,2,4,8,16,32", value_delimiter = ',')]
    pub sparsity: Vec<u32>,
    /// Error bounds to tabulate (bilinear, at the largest sparsity).
    #[arg(long, value_delimiter = ',')]
    pub max_error: Vec<f64>,
    /// The terrain plane of the approximation A: the DEM's trend plane, or its mean height
    #[arg(long, default_value = "plane", value_parser = ["plane", "mean"])]
    pub trend: String,
    /// Count only pixels where the terrain is at most this steep (degrees).
    #[arg(long)]
    pub max_slope: Option<f64>,
    /// Evaluate every Nth row and column (1: all pixels).
    #[arg(long, default_value_t = 1)]
    pub step: u32,
    /// Write the per-pixel error of this k (bilinear) as a GeoTIFF.
    #[arg(long)]
    pub error_map: Option<PathBuf>,
    /// ... and as a colour-mapped PNG with a legend.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Picture the correction matrix (x and y) as a PNG.
    #[arg(long)]
    pub gcm_png: Option<PathBuf>,
    /// The k of the maps.
    #[arg(long, default_value_t = 16)]
    pub map_sparsity: u32,
    /// Also rectify and check the checkpoints (needs an output path).
    #[arg(long)]
    pub ortho: Option<PathBuf>,
    /// Write the table here as JSON
    #[arg(long)]
    pub json: Option<PathBuf>,
}
