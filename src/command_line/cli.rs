//! Command-line arguments (clap) into the library's options. Choices are
//! typed here, by the library's own parsers; ranges are checked by the
//! library (`RectifyOptions::validate`), whose errors name the setting by
//! its key, which `flag` turns back into the flag. Raw flags stop here.

use crate::geom::Snap;
use crate::io::tiff_out::Compression;
use crate::mosaic::balance::Balance;
use crate::options::{parse_offset, parse_size, BandOrder, BiasModel, BigTiff, Choice, ModelSource, Occlusion, RectifyOptions};
use crate::overview::OverviewResampling;
use crate::resample::Kernel;
use crate::synth::{CameraKind, Relief, SynthOptions};
use crate::transform::Trend;
use crate::Result;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

/// A flag taking one of `T`'s names, parsed into `T` (clap lists the names
/// in `--help` and refuses others).
fn choice<T: Choice>() -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(T::NAMES).map(|s| T::from_name(&s).expect("a listed name"))
}

/// A count of 1 or more.
fn at_least_one(s: &str) -> std::result::Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        _ => Err(format!("'{s}' is not a whole number from 1 up")),
    }
}

/// A command's arguments as the library's keys: each field is named as
/// its key, so `grid` and `dem` read the command line as Python's keyword
/// arguments are read.
pub fn keys_of(args: &impl serde::Serialize) -> Result<serde_json::Map<String, serde_json::Value>> {
    match serde_json::to_value(args) {
        Ok(serde_json::Value::Object(keys)) => Ok(keys),
        Ok(_) => Err(crate::Error::Internal("the arguments are not an object of keys".into())),
        // (A path that is not UTF-8 has no key's text.)
        Err(e) => Err(crate::Error::Usage(match NOT_UTF8.get() {
            Some(which) => format!("{which} is not UTF-8 text, which a run's settings and report are kept in: rename it"),
            None => format!("the arguments: {e}"),
        })),
    }
}

/// The first argument that is not UTF-8, said with the option it was
/// given to (`--image 'scan\u{fffd}.tif'`), for [`keys_of`]'s refusal.
static NOT_UTF8: std::sync::OnceLock<String> = std::sync::OnceLock::new();

/// Notes the first argument of `args` (the program's name first) that is
/// not UTF-8, and the option it was given to.
pub fn note_not_utf8(args: &[std::ffi::OsString]) {
    let Some(i) = args.iter().skip(1).position(|a| a.to_str().is_none()).map(|i| i + 1) else { return };
    let lossy = args[i].to_string_lossy();
    let which = match (lossy.split_once('='), args[i - 1].to_str()) {
        (Some((flag, value)), _) if flag.starts_with('-') && !flag.contains('\u{fffd}') => format!("{flag}: '{value}'"),
        (_, Some(flag)) if flag.starts_with('-') && !flag.contains('=') => format!("{flag}: '{lossy}'"),
        _ => format!("the argument '{lossy}'"),
    };
    let _ = NOT_UTF8.set(which);
}

/// A number that is one: clap takes `nan` and `inf` as numbers, which
/// became null, the key's default, on their way through the keys
/// (`grid --power=nan` ran as power 2).
fn finite_f64(s: &str) -> std::result::Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(v) => Err(format!("{v} is not a finite number")),
        Err(e) => Err(e.to_string()),
    }
}

/// [`finite_f64`] for the settings kept as `f32`.
fn finite_f32(s: &str) -> std::result::Result<f32, String> {
    let v = finite_f64(s)?;
    Some(v as f32).filter(|f| f.is_finite()).ok_or_else(|| format!("{v} is past the range of this setting"))
}

/// A choice said by its name, as its key takes it.
fn by_name<T: Choice + PartialEq, S: serde::Serializer>(v: &T, s: S) -> std::result::Result<S::Ok, S::Error> {
    s.serialize_str(T::NAMES.iter().copied().find(|n| T::from_name(n).as_ref() == Some(v)).unwrap_or_default())
}

/// A flag that says no (`--no-sync`) as the key that says yes (`sync`).
fn not<S: serde::Serializer>(v: &bool, s: S) -> std::result::Result<S::Ok, S::Error> {
    s.serialize_bool(!v)
}

fn by_name_if_given<T: Choice + PartialEq, S: serde::Serializer>(v: &Option<T>, s: S) -> std::result::Result<S::Ok, S::Error> {
    match v {
        Some(v) => by_name(v, s),
        None => s.serialize_none(),
    }
}

/// The flag of a setting named by its key (`dem_hole` → `--dem-hole`).
pub fn flag(setting: &str) -> String {
    format!("--{}", setting.replace('_', "-"))
}

/// A setting as the user of `command` gives it: its flag, or (`batch`,
/// `mosaic`: settings only a manifest gives) its manifest key.
pub fn flag_of(command: &str, setting: &str) -> String {
    use clap::CommandFactory;
    let long = setting.replace('_', "-");
    let cli = Cli::command();
    match cli.find_subcommand(command) {
        Some(sub) if !sub.get_arguments().any(|a| a.get_long() == Some(long.as_str())) && matches!(command, "batch" | "mosaic") => {
            format!("{setting} (in the manifest)")
        }
        _ => flag(setting),
    }
}

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
    /// Put pieces made with `rectify --window` or `mosaic --window` together into one GeoTIFF.
    Assemble(AssembleArgs),
    /// One seamless orthomosaic of a batch manifest's images, straight from
    /// the scans: seamlines, radiometric balancing, blending.
    Mosaic(MosaicArgs),
    /// The image → ground regular grid of an RPC image (Chibunichev and
    /// Sonyushkin), as GDAL geolocation arrays, with its accuracy table.
    RpcGrid(RpcGridArgs),
    /// Show the cameras a set of camera and pose files gives each image,
    /// and write them as gcm-ortho camera files or in Orthority's or
    /// OpenSfM's form.
    Cameras(CamerasArgs),
    /// Find a film scan's fiducial marks (normalised correlation on an
    /// image pyramid, after Chibunichev): the marks' places, scores and
    /// residuals, the camera file with them (--write), a sheet to look at.
    Fiducials(FiducialsArgs),
    /// A DEM from irregular heights (CSV/XYZ, LAS, LAZ): a Delaunay TIN,
    /// natural neighbours, inverse distance, nearest, or the highest /
    /// lowest / mean point of each cell; blunders dropped; streamed.
    Grid(Box<GridArgs>),
    /// A DSM from a stereo pair (Nekrasov): the pair brought to epipolar
    /// geometry, matched densely (semi-global, or the thesis's
    /// correlation), each match intersected with the exact models, the
    /// points gridded by a TIN with blunders dropped; streamed in tiles.
    Dem(Box<DemArgs>),
}

#[derive(Args, Debug, serde::Serialize)]
pub struct DemArgs {
    /// The left image of the pair
    #[arg(long)]
    pub left: PathBuf,
    /// The right image of the pair
    #[arg(long)]
    pub right: PathBuf,
    /// The left image's camera file (any format rectify's --camera reads)
    #[arg(long, conflicts_with = "left_rpc")]
    pub left_camera: Option<PathBuf>,
    /// The right image's camera file
    #[arg(long, conflicts_with = "right_rpc")]
    pub right_camera: Option<PathBuf>,
    /// The left image's RPC file, in any format rectify's --rpc reads
    #[arg(long)]
    pub left_rpc: Option<PathBuf>,
    /// The right image's RPC file
    #[arg(long)]
    pub right_rpc: Option<PathBuf>,
    /// The left image is a crop from this column,row of its RPC's scene
    #[arg(long, requires = "left_rpc")]
    pub left_rpc_offset: Option<String>,
    /// The right image is a crop from this column,row of its RPC's scene
    #[arg(long, requires = "right_rpc")]
    pub right_rpc_offset: Option<String>,
    /// Heights above this geoid (PROJ .gtx or GeoTIFF grid) instead of
    /// the ellipsoid the RPCs use
    #[arg(long)]
    pub geoid: Option<PathBuf>,
    /// The DSM (a tiled GeoTIFF, Float32, nodata -9999)
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// The DSM's cell size: X, or X,Y
    #[arg(long, allow_negative_numbers = true)]
    pub gsd: crate::geom::Gsd,
    /// The DSM's CRS (default: the cameras', or the UTM zone of an RPC pair)
    #[arg(long)]
    pub crs: Option<String>,
    /// The heights searched: LOWEST,HIGHEST (default: --dem-init's, else
    /// the RPCs' range, else what a B/H of 0.1 to 1 puts below two frames)
    #[arg(long, allow_hyphen_values = true)]
    pub heights: Option<String>,
    /// A DEM of the area whose heights narrow the search
    #[arg(long)]
    pub dem_init: Option<PathBuf>,
    /// sgm (semi-global matching of census costs) or ncc (the thesis's
    /// sequential similarity search accepted by normalised correlation)
    #[arg(long, value_enum, default_value = "sgm")]
    pub matcher: crate::stereo::matching::Matcher,
    /// Correlation window side, pixels (odd, 3 to 21)
    #[arg(long, default_value_t = 9)]
    pub window: usize,
    /// Keep a match whose correlation reaches this (default: 0.5 for sgm;
    /// for ncc the window's threshold, 0.5 + 2.5/side)
    #[arg(value_parser = finite_f32, long)]
    pub min_correlation: Option<f32>,
    /// Also write the matched points (LAS) here
    #[arg(long)]
    pub points: Option<PathBuf>,
    /// Match only this share of the pair, I/N (rows of epipolar tiles, for
    /// N machines): -o is then the piece's matched points (LAS), and
    /// `grid` makes the DSM of all the pieces' points (the report says how)
    #[arg(long, conflicts_with_all = ["points", "cog"])]
    pub shard: Option<String>,
    /// Also write each cell's mean residual parallax of its matches
    /// (pixels; a GeoTIFF on the DSM's grid) here; with --shard, the
    /// piece's matches' residual parallaxes (LAS), gridded like its points
    #[arg(long)]
    pub quality: Option<PathBuf>,
    /// Also drop points whose height lies outside their Delaunay
    /// neighbours' by more than this many robust sigmas (matching drops
    /// its gross errors itself), or none
    #[arg(long, default_value = "none")]
    pub blunders: String,
    /// Memory budget
    #[arg(long, default_value = "512M")]
    pub memory: String,
    /// Worker threads (0: all cores)
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Write a Cloud-Optimized GeoTIFF
    #[arg(long)]
    pub cog: bool,
    /// A JSON report of the run here
    #[arg(long)]
    #[serde(skip)]
    pub json: Option<PathBuf>,
    /// No progress bar
    #[arg(long)]
    #[serde(skip)]
    pub quiet: bool,
}

#[derive(Args, Debug, serde::Serialize)]
pub struct GridArgs {
    /// The point files: CSV or XYZ text (a header `x,y,z` or
    /// easting/northing/height needs nothing more), LAS or LAZ.
    #[arg(required = true)]
    pub points: Vec<PathBuf>,
    /// The DEM (a tiled GeoTIFF, Float32, nodata -9999).
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
    /// Cell size: X, or X,Y
    #[arg(long, allow_negative_numbers = true)]
    pub gsd: crate::geom::Gsd,
    /// The DEM's extent: minx,miny,maxx,maxy, snapped outward to the cell
    /// size (default: the points')
    #[arg(long, allow_hyphen_values = true)]
    pub bounds: Option<String>,
    /// The DEM's CRS, in any form; points in another CRS are brought into
    /// it (default: the points')
    #[arg(long)]
    pub crs: Option<String>,
    /// The points' CRS where their files say none (no .prj beside a text
    /// file, no CRS in a LAS header; default: --crs)
    #[arg(long)]
    pub points_crs: Option<String>,
    /// tin (linear in each Delaunay triangle), natural (natural
    /// neighbour), idw (inverse distance), nearest, or max, min, mean (of
    /// the points in each cell: max makes a DSM from a point cloud)
    #[arg(long, default_value = "tin", value_parser = choice::<crate::gridding::Method>())]
    #[serde(serialize_with = "by_name")]
    pub method: crate::gridding::Method,
    /// The longest triangle side gridded across (tin, natural): cells in
    /// larger gaps get no height (default: ten times the points' typical
    /// spacing, at least four cells)
    #[arg(value_parser = finite_f64, long, allow_negative_numbers = true)]
    pub max_edge: Option<f64>,
    /// Points within this distance count (idw, nearest; default: --max-edge's)
    #[arg(value_parser = finite_f64, long, allow_negative_numbers = true)]
    pub radius: Option<f64>,
    /// Inverse distance's power (idw)
    #[arg(value_parser = finite_f64, long, default_value_t = 2.0, allow_negative_numbers = true)]
    pub power: f64,
    /// At most this many nearest points (idw; default: all within --radius)
    #[arg(long)]
    pub neighbours: Option<usize>,
    /// A text file's x, y and height columns: names from its header, or
    /// numbers counted from 1 (default: found by name, else the first three)
    #[arg(long)]
    pub columns: Option<String>,
    /// Point cloud classes kept, e.g. 2 for a DTM from ground points
    /// (default: all but noise, 7 and 18, and withheld points)
    #[arg(long, value_delimiter = ',')]
    pub class: Option<Vec<u8>>,
    /// Returns kept: all, first (a DSM) or last
    #[arg(long, default_value = "all", value_parser = choice::<crate::points::Returns>())]
    #[serde(serialize_with = "by_name")]
    pub returns: crate::points::Returns,
    /// Drop points whose height lies outside their Delaunay neighbours' by
    /// more than this many robust sigmas, or none
    #[arg(long, default_value = "8")]
    pub blunders: String,
    /// Memory budget
    #[arg(long, default_value = "512M")]
    pub memory: String,
    /// Worker threads (0: all cores)
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Tile size of the DEM, px
    #[arg(long, default_value_t = 256)]
    pub tile: u32,
    /// Cells a block's side (default: from the points' density and
    /// --memory; the DEM does not depend on it)
    #[arg(long, hide = true)]
    pub block: Option<u32>,
    /// Compression: none, deflate, lzw, zstd
    #[arg(long, default_value = "deflate", value_parser = choice::<Compression>())]
    #[serde(serialize_with = "by_name")]
    pub compress: Compression,
    /// Only these tiles: col,row,width,height (a piece for `assemble`)
    #[arg(long, conflicts_with = "shard")]
    pub window: Option<String>,
    /// The I-th of N pieces (rows of tiles), 1-based: I/N
    #[arg(long)]
    pub shard: Option<String>,
    #[command(flatten)]
    #[serde(flatten)]
    pub layout: LayoutArgs,
    /// Write the report (JSON) here
    #[arg(long)]
    #[serde(skip)]
    pub json: Option<PathBuf>,
    /// No progress bar, no summary (warnings still show)
    #[arg(long)]
    #[serde(skip)]
    pub quiet: bool,
}

#[derive(Args, Debug)]
pub struct FiducialsArgs {
    /// The film scan (TIFF, BigTIFF, JPEG, PNG, JPEG 2000).
    #[arg(long)]
    pub image: PathBuf,
    /// The camera file (TOML) with the calibrated marks: fiducials_mm or
    /// fiducial_distances_mm, and [interior.fiducial_mark] (default: a cross).
    #[arg(long)]
    pub camera: PathBuf,
    /// The marks' shape, over the camera file's: cross, dot, circle-dot,
    /// cross-dot, corner-dot, wings, or a camera family: wild-rc, zeiss-rmk,
    /// fairchild, afa.
    #[arg(long)]
    pub shape: Option<String>,
    /// The mark's overall size, mm (a cross's arm to arm, a ring's diameter).
    #[arg(value_parser = finite_f64, long)]
    pub size_mm: Option<f64>,
    /// The marks' tone on the film: light, dark, or auto (found).
    #[arg(long, value_parser = choice::<crate::fiducials::Polarity>())]
    pub polarity: Option<crate::fiducials::Polarity>,
    /// How the film lay on the scanner, where the marks cannot tell (a
    /// layout that looks the same turned): 0, 90, 180 or 270 (degrees
    /// counter-clockwise), "m" after it for a mirrored scan (90m).
    #[arg(long)]
    pub turn: Option<String>,
    /// The scanner's pixel size, mm (default: the camera file's
    /// scan_pixel_mm, the scan's resolution tags, else found).
    #[arg(value_parser = finite_f64, long)]
    pub scan_pixel_mm: Option<f64>,
    /// The most a mark may sit off the fitted interior orientation, px
    /// (default: the camera file's max_fiducial_residual_px, else 1).
    #[arg(value_parser = finite_f64, long)]
    pub max_residual_px: Option<f64>,
    /// Write the camera file with the marks found (fiducials_px) here; the
    /// rest of it as it was.
    #[arg(long)]
    pub write: Option<PathBuf>,
    /// A PNG of the marks with the centres found, to look at.
    #[arg(long)]
    pub sheet: Option<PathBuf>,
    /// The report as JSON on standard output.
    #[arg(long)]
    pub json: bool,
}

/// The image and its sensor model: a camera file, or an RPC file with
/// what goes with it (shared by `rectify` and `rpc-grid`).
#[derive(Args, Debug, serde::Serialize)]
pub struct SensorArgs {
    /// The scan or image: TIFF or BigTIFF (any layout), JPEG, PNG or JPEG 2000.
    #[arg(long)]
    pub image: PathBuf,
    /// The camera file: ours (TOML; a frame camera, model = "rpc", which
    /// rpc-grid needs, or model = "panoramic"), Orthority's interior
    /// parameters (YAML) or simple-ortho's config.yaml, an OpenSfM /
    /// OpenDroneMap reconstruction.json or a
    /// Metashape camera export (XML) (lenses and poses), Ames Stereo
    /// Pipeline's OPTICAL_BAR camera (Corona, KH-9 panoramic film), or
    /// "exif": the image's own EXIF/XMP tags. A satellite image gives its
    /// RPC with --rpc instead.
    #[arg(long, required_unless_present = "rpc", conflicts_with = "rpc")]
    pub camera: Option<PathBuf>,
    /// The exterior orientations of many images (Orthority's CSV or
    /// GeoJSON, our block CSV, an OpenSfM reconstruction.json): the image's
    /// own is found by its file name; --camera gives the lens.
    #[arg(long, requires = "camera")]
    pub exterior: Option<PathBuf>,
    /// The --exterior CSV's angles are in radians (default: degrees, as
    /// Orthority reads them)
    #[arg(long, requires = "exterior")]
    pub radians: bool,
    /// An RPC model instead of a camera file, in any supported format
    /// (GeoTIFF RPC tag, NITF, _RPC.TXT, RPB, OSSIM .geom, DIMAP or
    /// WorldView XML, rpcm JSON, Orthority's YAML: the entry of the image's
    /// name); the image itself when it carries one.
    #[arg(long)]
    pub rpc: Option<PathBuf>,
    /// With --rpc: the image is a crop starting at this column,row of the
    /// scene the RPC describes (default: the tile offset a DigitalGlobe XML
    /// records for the image's file name, else none).
    #[arg(long, requires = "rpc")]
    pub rpc_offset: Option<String>,
    /// With --rpc: the DEM's heights are above this geoid (PROJ's .gtx or
    /// GeoTIFF grid, e.g. us_nga_egm96_15.tif for SRTM); RPCs expect
    /// ellipsoidal heights.
    #[arg(long, requires = "rpc")]
    pub geoid: Option<PathBuf>,
}

/// The unit `--radians` says a pose CSV's angles are in.
fn angle_unit(radians: bool) -> crate::camera::formats::AngleUnit {
    if radians {
        crate::camera::formats::AngleUnit::Radians
    } else {
        crate::camera::formats::AngleUnit::Degrees
    }
}

impl SensorArgs {
    /// The camera file or RPC file named, and how it becomes the sensor
    /// model. No
    /// file is read here: the library does that when it sets up the run.
    pub fn model(&self) -> Result<(PathBuf, ModelSource)> {
        match (&self.camera, &self.rpc) {
            (Some(_), None) if self.rpc_offset.is_some() => Err(crate::Error::setting("rpc_offset", "goes with --rpc, not a camera file")),
            (Some(_), None) if self.geoid.is_some() => Err(crate::Error::setting("geoid", "goes with --rpc, not a camera file")),
            (Some(c), None) => Ok((
                c.clone(),
                self.exterior.clone().map_or(ModelSource::CameraFile, |poses| ModelSource::WithPoses { poses, angles: angle_unit(self.radians) }),
            )),
            (None, Some(r)) => {
                let offset = self.rpc_offset.as_deref().map(|o| parse_offset("rpc_offset", o)).transpose()?;
                Ok((r.clone(), ModelSource::Rpc { offset, geoid: self.geoid.clone() }))
            }
            _ => Err(crate::Error::setting("camera", "give a camera file or an RPC file")),
        }
    }
}

#[derive(Args, Debug)]
pub struct RpcGridArgs {
    #[command(flatten)]
    pub sensor: SensorArgs,
    /// DEM (any EPSG CRS; heights above the geoid with --geoid).
    #[arg(long, required_unless_present = "height", conflicts_with = "height")]
    pub dem: Option<PathBuf>,
    /// A constant height instead of a DEM (metres; with --geoid above the
    /// geoid): the grid of an RPC without a DEM of its place.
    #[arg(value_parser = finite_f64, long, allow_negative_numbers = true)]
    pub height: Option<f64>,
    /// Grid step, image pixels.
    #[arg(long, default_value_t = 8)]
    pub step: u32,
    /// Also print the grid's accuracy table for these steps, e.g. 2,4,8,16,32.
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
pub struct CamerasArgs {
    /// The camera file, in any form rectify reads (ours, Orthority's
    /// interior parameters, an OpenSfM / OpenDroneMap reconstruction.json,
    /// a Metashape camera export), or "exif": each image's own tags.
    #[arg(long)]
    pub camera: PathBuf,
    /// The exterior orientations of many images (Orthority's CSV or
    /// GeoJSON, our block CSV, a reconstruction.json).
    #[arg(long)]
    pub exterior: Option<PathBuf>,
    /// The --exterior CSV's angles are in radians (default: degrees)
    #[arg(long, requires = "exterior")]
    pub radians: bool,
    /// Only these images' cameras, their sizes read from the files
    /// (default: every pose the files hold).
    pub images: Vec<PathBuf>,
    /// The positions' CRS where the files give none.
    #[arg(long)]
    pub crs: Option<String>,
    /// Write the cameras into this folder.
    #[arg(long)]
    pub out_dir: Option<PathBuf>,
    /// The form to write: toml (one gcm-ortho camera file per image),
    /// orthority (int_param.yaml, ext_param.csv and .prj), opensfm
    /// (reconstruction.json).
    #[arg(long, value_enum, default_value_t = CameraTarget::Toml, requires = "out_dir")]
    pub to: CameraTarget,
    /// Print neither the table nor the files written (warnings still show).
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum CameraTarget {
    Toml,
    Orthority,
    Opensfm,
}

impl CamerasArgs {
    pub fn options(&self) -> Result<crate::camera::formats::convert::ConvertOptions> {
        use crate::camera::formats::convert::{ConvertOptions, Target};
        let crs =
            self.crs.as_deref().map(|c| crate::geodesy::Crs::parse(c, std::path::Path::new("")).map_err(|m| crate::Error::setting("crs", m))).transpose()?;
        let target = match self.to {
            CameraTarget::Toml => Target::Toml,
            CameraTarget::Orthority => Target::Orthority,
            CameraTarget::Opensfm => Target::OpenSfm,
        };
        Ok(ConvertOptions {
            camera: self.camera.clone(),
            exterior: self.exterior.clone(),
            angles: angle_unit(self.radians),
            images: self.images.clone(),
            crs,
            out_dir: self.out_dir.clone(),
            target,
        })
    }
}

/// `assemble`'s arguments: the pieces and the output, and the layout's
/// settings named as their keys (read by the library's key table).
#[derive(Args, Debug, serde::Serialize)]
pub struct AssembleArgs {
    /// The pieces (GeoTIFFs written by `rectify --window` or `mosaic --window`).
    #[arg(required = true)]
    #[serde(skip)]
    pub pieces: Vec<PathBuf>,
    /// The assembled orthophoto (its overviews made anew)
    #[arg(short = 'o', long = "output")]
    #[serde(skip)]
    pub output: PathBuf,
    /// Code the tiles anew in this codec (default: the pieces' own, whose
    /// tiles are copied as they are). Lossless pieces assembled into jpeg
    /// give the bytes of a single run in jpeg, overviews included.
    #[arg(long, value_parser = choice::<Compression>())]
    #[serde(serialize_with = "by_name_if_given")]
    pub compress: Option<Compression>,
    #[command(flatten)]
    #[serde(flatten)]
    pub layout: LayoutArgs,
}

/// The output's overviews and layout (rectify and assemble).
#[derive(Args, Debug, serde::Serialize)]
pub struct LayoutArgs {
    /// Internal overviews: auto (2×, 4×, … until one tile holds the
    /// level; one at least on an image over 512 px), none (or 0), or the
    /// factors 2,4,…,2ⁿ. Made while the tiles stream. Default: auto
    /// (assemble: as the pieces' run had them)
    #[arg(long)]
    pub overviews: Option<String>,
    /// How an overview pixel is made of the four below it: average (of
    /// those with a value), nearest (the top-left one) or mode (the most
    /// frequent), the last two for classified data. Default: average
    /// (assemble: as the pieces' run)
    #[arg(long, value_parser = choice::<OverviewResampling>())]
    #[serde(serialize_with = "by_name_if_given")]
    pub overview_resampling: Option<OverviewResampling>,
    /// Cloud-Optimized GeoTIFF (GDAL's COG layout: directories first,
    /// overviews before the full resolution; assemble: also where the
    /// pieces' run was)
    #[arg(long)]
    pub cog: bool,
    /// The compression level: deflate 0–12 (default 0, the fastest coder;
    /// 1 for floats; 1 and up ~12 % smaller, 3× the coding time), zstd
    /// 1–22 (default 1); higher packs tighter, slower
    #[arg(long)]
    pub level: Option<u8>,
    /// The overview tiles' level (default: --level when given, else the
    /// fastest coding, deflate 0)
    #[arg(long)]
    pub overview_level: Option<u8>,
    /// JPEG's quality, 1–100 (default 75, as GDAL's)
    #[arg(long)]
    pub quality: Option<u8>,
}

#[derive(Args, Debug)]
pub struct BatchArgs {
    /// The manifest (TOML).
    pub manifest: PathBuf,
    /// Jobs to run at a time (1 or more), sharing --memory.
    #[arg(long, default_value_t = 1, value_parser = at_least_one)]
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
    /// one thread runs its steps one after the other, one processor busy;
    /// more than the cores are cut to them, with a warning).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Only check the jobs of this shard and list them: their files, and
    /// each job's set-up (camera, DEM under the footprint, grid) short of
    /// making pixels; exit 3 where one would fail
    #[arg(long)]
    pub dry_run: bool,
    /// No progress bar (there is none anyway when stderr is not a terminal)
    #[arg(long)]
    pub quiet: bool,
}

/// `mosaic`'s arguments, each field named as its key (read by the
/// library's key table, as a binding's keyword arguments are).
#[derive(Args, Debug, serde::Serialize)]
pub struct MosaicArgs {
    /// The batch manifest of the block (jobs or a block, one DEM or per-job
    /// DEMs); its [defaults] give the output's tile, compression and
    /// overviews.
    pub manifest: PathBuf,
    /// The orthomosaic (GeoTIFF), or with --window a piece of it for
    /// `assemble`
    #[arg(short = 'o', long = "output", required_unless_present = "plan_out")]
    pub output: Option<PathBuf>,
    /// Write the plan (grid, seams, gains) here, for shards that render
    /// pieces of one mosaic with --plan and --window
    #[arg(long)]
    pub plan_out: Option<PathBuf>,
    /// Take the seams and gains from this plan (made by --plan-out from the
    /// same manifest and settings) instead of finding them
    #[arg(long, conflicts_with_all = ["seamlines", "seams", "balance"])]
    pub plan: Option<PathBuf>,
    /// Render only these tiles of the mosaic: col,row,width,height (a
    /// piece; `assemble` joins the pieces into the single run's mosaic);
    /// one reaching past the mosaic's edge is cut at it
    #[arg(long, requires = "output")]
    pub window: Option<String>,
    /// Remake the output even where its record says it is current (a rerun
    /// otherwise leaves a finished mosaic or piece as it is)
    #[arg(long)]
    pub force: bool,
    /// Render by pieces finished in this folder, so that a stopped run,
    /// run again, keeps its finished pieces (its own files are removed once
    /// the mosaic is made, and the folder where that leaves it empty; it
    /// holds about the mosaic's size meanwhile)
    #[arg(long, requires = "output", conflicts_with_all = ["window", "plan", "plan_out"])]
    #[serde(skip)]
    pub resume_dir: Option<PathBuf>,
    /// Pixel size of the mosaic: X, or X,Y for non-square pixels (default:
    /// the median of the images' mean GSDs over their footprints, square)
    #[arg(long, allow_negative_numbers = true)]
    pub gsd: Option<crate::geom::Gsd>,
    /// The mosaic's extent: minx,miny,maxx,maxy (default: all footprints)
    #[arg(long, allow_hyphen_values = true)]
    pub bounds: Option<String>,
    /// The grid of this raster (CRS, origin, pixel size and size), so the
    /// mosaic lands pixel for pixel on it; instead of --gsd and --bounds
    #[arg(long, conflicts_with_all = ["gsd", "bounds"])]
    pub like: Option<PathBuf>,
    /// The mosaic's CRS, in any form (default: the first camera's, or the
    /// --like raster's)
    #[arg(long)]
    pub crs: Option<String>,
    /// Radiometric balancing from the overlaps: none, gain, gain-offset, or
    /// gain-offset-vignetting (also each image's radial falloff)
    /// [default: gain-offset]
    #[arg(long, value_parser = choice::<Balance>())]
    #[serde(serialize_with = "by_name_if_given")]
    pub balance: Option<Balance>,
    /// Seamlines: least-cost (moved onto the cheapest path through the
    /// overlap, around buildings) or voronoi (the first partition, each
    /// ground point from the image that sees it nearest its centre)
    /// [default: least-cost]
    #[arg(long, value_parser = ["least-cost", "voronoi"], conflicts_with = "seamlines")]
    pub seams: Option<String>,
    /// Width of the blend across a seam, pixels (0: a sharp cut; never
    /// across a height edge of the DSM)
    #[arg(value_parser = finite_f64, long, default_value_t = 8.0, allow_hyphen_values = true)]
    pub blend: f64,
    /// Write the seamlines here as GeoJSON (one polygon per image)
    #[arg(long)]
    pub seamlines_out: Option<PathBuf>,
    /// Honour these seamlines (GeoJSON as --seamlines-out writes them,
    /// edited in a GIS) instead of finding them
    #[arg(long)]
    pub seamlines: Option<PathBuf>,
    /// Cloud-Optimized GeoTIFF (else as the manifest's `cog`)
    #[arg(long)]
    pub cog: bool,
    /// A true orthomosaic: ground an image does not see on the DSM is taken
    /// from another image that sees it, and what no image sees has no value
    /// (`nodata` and `mask` alike; else as each job's `occlusion`)
    #[arg(long, value_parser = choice::<Occlusion>())]
    #[serde(serialize_with = "by_name_if_given")]
    pub occlusion: Option<Occlusion>,
    /// Memory budget
    #[arg(long, default_value = "256M")]
    pub memory: String,
    /// Worker threads (0: all cores; more than the cores are cut to them,
    /// with a warning)
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Write the report (JSON) here
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// No progress bar (warnings still show)
    #[arg(long)]
    #[serde(skip)]
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
    #[arg(long, default_value = "hilly", value_parser = choice::<Relief>())]
    pub relief: Relief,
    /// A film scan with fiducial marks, a digital frame, or a satellite image with RPCs
    #[arg(long, default_value = "film", value_parser = choice::<CameraKind>())]
    pub camera: CameraKind,
    /// Off-nadir angle of an RPC (satellite) scene, degrees: 2 to 35.
    #[arg(value_parser = finite_f64, long, default_value_t = 25.0)]
    pub off_nadir: f64,
    /// Swing of the camera, degrees.
    #[arg(value_parser = finite_f64, long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub kappa: f64,
    /// The scan file's layout
    #[arg(long, default_value = "strips", value_parser = ["strips", "tiles"])]
    pub layout: String,
    /// The scan file's compression
    #[arg(long, default_value = "none", value_parser = PossibleValuesParser::new(["none", "deflate", "lzw"]).map(|s| Compression::from_name(&s).expect("a listed name")))]
    pub compress: Compression,
    /// DEM posting, metres.
    #[arg(value_parser = finite_f64, long, default_value_t = 5.0)]
    pub dem_posting: f64,
    /// Photo scale denominator.
    #[arg(value_parser = finite_f64, long, default_value_t = 10000.0)]
    pub scale: f64,
    /// Fiducial marks on film: 4 (corners) or 8.
    #[arg(long, default_value_t = 4)]
    pub fiducials: u32,
    /// Film image frame, mm: 230 (23 × 23 cm) or 180 (18 × 18 cm).
    #[arg(value_parser = finite_f64, long, default_value_t = 230.0)]
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
    /// A block of overlapping frames of one ground instead of one scan:
    /// COLSxROWS (60 % forward, 30 % side overlap; digital or drone
    /// cameras), each frame exposed differently, with a manifest for
    /// `mosaic` and the ground's true colours.
    #[arg(long)]
    pub block: Option<String>,
    /// An in-track stereo pair at this base-to-height ratio, for `dem`:
    /// RPC views (--camera rpc: left.tif, right.tif, their _RPC.TXT) or a
    /// panoramic fore/aft pair (--camera panoramic: left/right .tif, .toml,
    /// .tsai), and the true heights (dem.tif)
    #[arg(value_parser = finite_f64, long, conflicts_with = "block")]
    pub stereo: Option<f64>,
    /// Only points for `grid`: this many at random on rolling hills with a
    /// town of boxes, written as --out/points.las (points.laz with --laz,
    /// points.csv with --csv), streamed
    #[arg(long)]
    pub points: Option<u64>,
    /// Write the points as CSV (with --points)
    #[arg(long, conflicts_with = "laz")]
    pub csv: bool,
    /// Points a square metre (with --points)
    #[arg(value_parser = finite_f64, long, default_value_t = 1.0)]
    pub points_density: f64,
    /// Write the points as LAZ (with --points)
    #[arg(long)]
    pub laz: bool,
    /// Film: the fiducial marks' shape (as `fiducials --shape`).
    #[arg(long, default_value = "cross")]
    pub mark: String,
    /// Film: a negative (dark marks on a light base).
    #[arg(long)]
    pub negative: bool,
    /// Film: its small turn on the scanner, degrees.
    #[arg(value_parser = finite_f64, long, default_value_t = 0.3, allow_negative_numbers = true)]
    pub scan_turn: f64,
    /// Film: quarter turns counter-clockwise on the scanner (0–3).
    #[arg(long, default_value_t = 0)]
    pub scan_quarters: u8,
    /// Film: scanned through its base (mirrored).
    #[arg(long)]
    pub mirrored: bool,
    /// Film: specks of dust and scratches in the margin.
    #[arg(long, default_value_t = 0)]
    pub dust: u32,
    /// Film: this mark (1-based) scratched out.
    #[arg(long, default_value_t = 0)]
    pub hide_mark: u32,
    /// Film: grain, the margin's random spread of tone (0 to 1).
    #[arg(value_parser = finite_f64, long, default_value_t = 0.0)]
    pub grain: f64,
    /// Film: only the scan's marks and margin (a plain texture inside) and
    /// the camera file, no terrain: for trying `fiducials`.
    #[arg(long)]
    pub marks_only: bool,
}

impl SynthArgs {
    pub fn options(&self) -> Result<SynthOptions> {
        let (width, height) = parse_size("size", &self.size)?;
        Ok(SynthOptions {
            out: self.out.clone(),
            width,
            height,
            bands: self.bands,
            bits: self.bits,
            relief: self.relief,
            camera: self.camera,
            kappa_deg: self.kappa,
            tiled: self.layout == "tiles",
            compress: self.compress,
            dem_posting: self.dem_posting,
            scale: self.scale,
            fiducials: self.fiducials,
            frame_mm: self.frame,
            off_nadir_deg: self.off_nadir,
            seed: self.seed,
            no_scan: self.no_scan,
            marks: crate::synth::film_marks::FilmMarks {
                shape: self.mark.clone(),
                negative: self.negative,
                scan_turn_deg: self.scan_turn,
                quarters: self.scan_quarters,
                mirrored: self.mirrored,
                dust: self.dust,
                hidden_mark: self.hide_mark,
                grain: self.grain,
            },
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

/// `rectify`'s arguments, each field named as its key: the run's options
/// are read from them by the library's key table, as a manifest's job's
/// and a binding's keyword arguments are.
#[derive(Args, Debug, serde::Serialize)]
pub struct RectifyArgs {
    #[command(flatten)]
    #[serde(flatten)]
    pub sensor: SensorArgs,
    /// The orthophoto's CRS: EPSG:<code>, a PROJ string, WKT or a .prj
    /// file (default: the camera file's; an RPC's: the WGS84 UTM zone of
    /// the scene's centre).
    #[arg(long)]
    pub crs: Option<String>,
    /// Ground control points refining the model: Orthority's GCP GeoJSON,
    /// or a CSV id,col,row,x,y,z with a .prj beside it. An RPC's bias is
    /// corrected in image space; a frame or panoramic camera's pose by
    /// resection.
    #[arg(long)]
    pub gcps: Option<PathBuf>,
    /// auto: an RPC's bias (affine with 3 or more GCPs, else a shift), a
    /// frame camera's pose (interior fixed), a panoramic camera's pose (and
    /// its motion compensation where 6 or more GCPs fix it); shift, affine
    /// (RPC); interior: a frame camera's pose, focal length and principal
    /// point (5 or more GCPs spread in height), a panoramic camera's pose
    /// and motion compensation (6 or more).
    /// [default: auto]
    #[arg(long, value_parser = choice::<BiasModel>(), requires = "gcps")]
    #[serde(serialize_with = "by_name_if_given")]
    pub gcp_refine: Option<BiasModel>,
    /// The most any GCP may sit off the refined model, image pixels: past
    /// it the fit is refused. [default: 2]
    #[arg(value_parser = finite_f64, long, requires = "gcps")]
    pub gcp_max_residual: Option<f64>,
    /// DEM: a GeoTIFF, an SRTM .hgt, a GDAL VRT, or a folder or list of
    /// tiles; in the orthophoto's CRS or any other (it is then reprojected
    /// on the fly).
    #[arg(long, conflicts_with = "height")]
    pub dem: Option<PathBuf>,
    /// A constant terrain height instead of a DEM, metres.
    #[arg(value_parser = finite_f64, long, allow_negative_numbers = true)]
    pub height: Option<f64>,
    /// What to do in DEM holes: error, nodata, or a height.
    #[arg(long, default_value = "error", allow_negative_numbers = true)]
    pub dem_hole: String,
    /// What to do outside the DEM: error, nodata, or a height.
    #[arg(long, default_value = "nodata", allow_negative_numbers = true)]
    pub dem_outside: String,
    /// Output pixel size in ground units: X, or X,Y for pixels X wide and
    /// Y tall (default: the scan's mean GSD over its footprint, square: the
    /// square root of the ground area it covers over its pixel count).
    #[arg(long, allow_negative_numbers = true)]
    pub gsd: Option<crate::geom::Gsd>,
    /// minx,miny,maxx,maxy or auto (the scan's footprint on the DEM).
    #[arg(long, default_value = "auto", allow_hyphen_values = true)]
    pub bounds: String,
    /// How bounds become the grid: tap (edges on multiples of the GSD,
    /// outward), outward (the origin as given, whole pixels outward), none
    /// (the origin as given, the nearest whole number of pixels).
    /// [default: tap]
    #[arg(long, value_parser = choice::<Snap>())]
    #[serde(serialize_with = "by_name_if_given")]
    pub snap: Option<Snap>,
    /// The grid of this raster (CRS, origin, pixel size and size), so the
    /// orthophoto lands pixel for pixel on it; instead of --gsd and --bounds.
    #[arg(long, conflicts_with_all = ["gsd", "bounds"])]
    pub like: Option<PathBuf>,
    /// Only a piece of the output: col,row,width,height in output tiles
    /// (one reaching past the output's edge is cut at it).
    #[arg(long)]
    pub window: Option<String>,
    /// GCM node spacing k, output pixels (default: 16, or the DEM's posting
    /// in output pixels where finer, but at least 4).
    #[arg(long)]
    pub sparsity: Option<u32>,
    /// The most the GCM may be off the exact model at any output pixel,
    /// scan pixels, or `none` (default: 0.1, or none with a given
    /// --sparsity or --corrections cell; the error is reported either way).
    #[arg(long, allow_negative_numbers = true)]
    pub max_error: Option<String>,
    /// How the corrections between GCM nodes are found: interpolated
    /// bilinearly from the four nodes around, or one per cell (as in Beloshapkin's thesis)
    #[arg(long, default_value = "bilinear", value_parser = choice::<crate::gcm::CorrectionMode>())]
    #[serde(serialize_with = "by_name")]
    pub corrections: crate::gcm::CorrectionMode,
    /// The terrain plane of the approximation A: the DEM's least-squares
    /// trend plane over the output area, or its mean height
    #[arg(long, default_value = "plane", value_parser = choice::<Trend>())]
    #[serde(serialize_with = "by_name")]
    pub trend: Trend,
    /// Resampling kernel
    #[arg(long, default_value = "bilinear", value_parser = choice::<Kernel>())]
    #[serde(serialize_with = "by_name")]
    pub resample: Kernel,
    /// Output tile size in pixels (a multiple of 16)
    #[arg(long, default_value_t = 256)]
    pub tile: u32,
    /// Make the output in bands of tile rows or of tile columns (auto: the
    /// one that reads the scan along its rows; columns for a scan turned
    /// ~90°). The pixels agree to the GCM's accuracy either way.
    #[arg(long, default_value = "auto", value_parser = choice::<BandOrder>())]
    #[serde(serialize_with = "by_name")]
    pub band_order: BandOrder,
    /// Tile compression: lossless (with the horizontal predictor for
    /// integer samples), or jpeg for 8-bit grey or RGB (YCbCr, the
    /// internal mask for pixels without a value)
    #[arg(long, default_value = "deflate", value_parser = choice::<Compression>())]
    #[serde(serialize_with = "by_name")]
    pub compress: Compression,
    /// BigTIFF output (auto: when the output may pass 4 GB)
    #[arg(long, default_value = "auto", value_parser = choice::<BigTiff>())]
    #[serde(serialize_with = "by_name")]
    pub bigtiff: BigTiff,
    #[command(flatten)]
    #[serde(flatten)]
    pub layout: LayoutArgs,
    /// Pixels without a value: auto (NaN for floating-point samples, else
    /// the internal mask), mask (a 1-bit internal mask, GDAL's), or a
    /// nodata value (an image sample holding it is made the next value, as
    /// GDAL's warper does, and the count said).
    #[arg(long, default_value = "auto", allow_negative_numbers = true, conflicts_with = "alpha")]
    pub nodata: String,
    /// Add an alpha band instead of a nodata value.
    #[arg(long)]
    pub alpha: bool,
    /// True orthophoto: ground the sensor does not see on the DSM (behind
    /// buildings, trees, steep slopes) becomes nodata, or with `mask` keeps
    /// the scan's pixels but is marked in the internal mask (or alpha)
    #[arg(long, default_value = "none", value_parser = choice::<Occlusion>())]
    #[serde(serialize_with = "by_name")]
    pub occlusion: Occlusion,
    /// Worker threads (0: all cores; 1: every step one after the other,
    /// one processor busy; more than the cores are cut to them, with a
    /// warning).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Memory budget, e.g. 128M or 1G.
    #[arg(long, default_value = "128M")]
    pub memory: String,
    /// The most output pixels, e.g. 20G (default: 16 times the scan's,
    /// and 256M at least; only a GSD or bounds typo passes it).
    #[arg(long)]
    pub max_output_pixels: Option<String>,
    /// No progress bar (there is none anyway when stderr is not a terminal)
    #[arg(long)]
    #[serde(skip)]
    pub quiet: bool,
    /// Do not wait for the output to reach the disk before renaming it into
    /// place (faster where the disk is slower than the run; a power failure
    /// soon after may leave an incomplete file under the output's name).
    #[arg(long)]
    #[serde(rename = "sync", serialize_with = "not")]
    pub no_sync: bool,
    /// Write the run report here as JSON.
    #[arg(long)]
    #[serde(skip)]
    pub json: Option<PathBuf>,
    /// The output orthophoto.
    #[arg(short = 'o', long = "output")]
    pub output: PathBuf,
}

impl RectifyArgs {
    /// The run's options, read by the library's key table (as a
    /// manifest's job's are); it checks their ranges.
    pub fn options(&self) -> Result<RectifyOptions> {
        crate::by_key::rectify_options(keys_of(self)?)
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
    #[arg(value_parser = finite_f64, long, value_delimiter = ',')]
    pub max_error: Vec<f64>,
    /// The terrain plane of the approximation A: the DEM's trend plane, or its mean height
    #[arg(long, default_value = "plane", value_parser = choice::<Trend>())]
    pub trend: Trend,
    /// Count only pixels where the terrain is at most this steep (degrees).
    #[arg(value_parser = finite_f64, long)]
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
    /// Write the table here as JSON
    #[arg(long)]
    pub json: Option<PathBuf>,
}

#[cfg(test)]
mod flag_tests {
    use super::flag_of;

    /// A setting is named as its user gives it: the flag where the command
    /// has one, else the manifest's key.
    #[test]
    fn settings_are_named_by_the_flag_or_the_manifest_key() {
        assert_eq!(flag_of("rectify", "tile"), "--tile");
        assert_eq!(flag_of("rectify", "dem_outside"), "--dem-outside");
        assert_eq!(flag_of("mosaic", "tile"), "tile (in the manifest)");
        assert_eq!(flag_of("mosaic", "compress"), "compress (in the manifest)");
        assert_eq!(flag_of("mosaic", "memory"), "--memory");
        assert_eq!(flag_of("batch", "dem_outside"), "dem_outside (in the manifest)");
    }
}
