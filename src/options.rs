//! What a run is asked to do, typed and checked in one place for every
//! caller: the CLI and the batch manifest build a [`RectifyOptions`] with
//! the parsers here, and [`RectifyOptions::validate`] checks the ranges, so
//! that both give the same message for the same mistake. Errors name the
//! setting by its manifest key (`tile`, `dem_hole`); the binary turns the
//! key into its flag.

use crate::error::{Error, Result};
use crate::io::overwrite::{check_outputs, check_writable, Role};
use crate::io::source::SampleType;

// The types of the options' fields, for a caller who sets them.
pub use crate::camera::formats::AngleUnit;
pub use crate::camera::gcp::BiasModel;
pub use crate::camera::CameraFile;
pub use crate::dem::Miss;
pub use crate::gcm::{CorrectionMode, GcmSpec};
pub use crate::geodesy::Crs;
pub use crate::geom::{Gsd, Snap};
pub use crate::io::tiff_out::Compression;
pub use crate::overview::OverviewResampling;
pub use crate::resample::Kernel;
pub use crate::transform::Trend;
use std::path::PathBuf;

/// A setting chosen by name from a fixed list.
pub trait Choice: Sized + Copy + Send + Sync + 'static {
    /// The names, in the order `--help` lists them.
    const NAMES: &'static [&'static str];
    fn from_name(name: &str) -> Option<Self>;
}

macro_rules! choice {
    ($t:ty: $($name:literal => $v:expr),* $(,)?) => {
        impl Choice for $t {
            const NAMES: &'static [&'static str] = &[$($name),*];
            fn from_name(name: &str) -> Option<Self> {
                match name {
                    $($name => Some($v),)*
                    _ => None,
                }
            }
        }
    };
}

choice!(Kernel: "nearest" => Kernel::Nearest, "bilinear" => Kernel::Bilinear, "cubic" => Kernel::Cubic, "lanczos3" => Kernel::Lanczos3, "average" => Kernel::Average, "mode" => Kernel::Mode);
choice!(Compression: "none" => Compression::None, "deflate" => Compression::Deflate, "lzw" => Compression::Lzw, "zstd" => Compression::Zstd, "jpeg" => Compression::Jpeg);
choice!(CorrectionMode: "bilinear" => CorrectionMode::Bilinear, "cell" => CorrectionMode::Cell);
choice!(Trend: "plane" => Trend::Plane, "mean" => Trend::Mean);
choice!(BandOrder: "auto" => BandOrder::Auto, "rows" => BandOrder::Rows, "columns" => BandOrder::Columns);
choice!(BigTiff: "auto" => BigTiff::Auto, "yes" => BigTiff::Yes, "no" => BigTiff::No);
choice!(Snap: "tap" => Snap::Tap, "outward" => Snap::Outward, "none" => Snap::None);
choice!(Occlusion: "none" => Occlusion::None, "nodata" => Occlusion::Nodata, "mask" => Occlusion::Mask);
choice!(BiasModel: "auto" => BiasModel::Auto, "shift" => BiasModel::Shift, "affine" => BiasModel::Affine, "interior" => BiasModel::Interior);
choice!(OverviewResampling: "average" => OverviewResampling::Average, "nearest" => OverviewResampling::Nearest, "mode" => OverviewResampling::Mode);

/// `name` as one of `T`'s choices.
pub fn parse_choice<T: Choice>(setting: &'static str, name: &str) -> Result<T> {
    T::from_name(name.trim()).ok_or_else(|| Error::setting(setting, format!("'{name}' is not one of {}", T::NAMES.join(", "))))
}

/// What becomes of output pixels the sensor does not see on the DSM (a
/// true orthophoto): ground hidden behind a building otherwise takes the
/// building's pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Occlusion {
    /// Not looked for: every pixel takes what the scan shows there.
    None,
    /// Hidden pixels have no value (nodata, the mask or alpha say so).
    Nodata,
    /// Hidden pixels keep what the scan shows there, and the internal mask
    /// (or alpha) says they have no value.
    Mask,
}

/// How the output marks pixels without a value.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Nodata {
    /// A value outside the data's range where the samples have one (NaN
    /// for floating point); else the internal mask: a black pixel of the
    /// image is never a hole.
    Auto,
    /// A 1-bit internal mask (GDAL's `Mask Flags: PER_DATASET`); no nodata value.
    Mask,
    /// This value, tagged as the nodata value (a sample of the image that
    /// holds it is made the next value, as GDAL's warper does).
    Value(#[serde(with = "number_or_nan")] f64),
}

/// A number that may be NaN, serialized as `"nan"` then (JSON has no NaN).
mod number_or_nan {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_nan() {
            s.serialize_str("nan")
        } else {
            s.serialize_f64(*v)
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Said {
            Number(f64),
            Text(String),
        }
        match Said::deserialize(d)? {
            Said::Number(v) => Ok(v),
            Said::Text(t) if t.eq_ignore_ascii_case("nan") => Ok(f64::NAN),
            Said::Text(t) => Err(serde::de::Error::custom(format!("'{t}' is neither a number nor nan"))),
        }
    }
}

impl Nodata {
    /// What `auto` means for these samples: NaN (outside any data) for
    /// floating point; for integers, whose every value may be data, the mask.
    pub fn resolved(self, sample: SampleType) -> Nodata {
        match (self, sample) {
            (Nodata::Auto, SampleType::F32) => Nodata::Value(f64::NAN),
            (Nodata::Auto, _) => Nodata::Mask,
            (n, _) => n,
        }
    }

    /// Refuses a nodata value the output's samples cannot hold (they take
    /// the scan's type): it would be written as another value than the tag
    /// says.
    pub fn check_value(nodata: f64, sample: SampleType) -> Result<()> {
        let (lo, hi, what) = match sample {
            SampleType::U8 => (0.0, 255.0, "8-bit samples (0 to 255)"),
            SampleType::U16 => (0.0, 65535.0, "16-bit samples (0 to 65535)"),
            SampleType::F32 => {
                if nodata.is_nan() || (nodata as f32).is_finite() {
                    return Ok(());
                }
                return Err(Error::setting("nodata", format!("{nodata} is beyond 32-bit floating-point samples")));
            }
        };
        if nodata.fract() == 0.0 && (lo..=hi).contains(&nodata) {
            Ok(())
        } else {
            Err(Error::setting("nodata", format!("{nodata} is not a value of the output's {what}, which are the scan's")))
        }
    }
}

/// `auto`, `mask` or a number.
pub fn parse_nodata(setting: &'static str, s: &str) -> Result<Nodata> {
    match s.trim() {
        "auto" => Ok(Nodata::Auto),
        "mask" => Ok(Nodata::Mask),
        t => match t.parse::<f64>() {
            Ok(v) if v.is_finite() || v.is_nan() => Ok(Nodata::Value(v)),
            _ => Err(Error::setting(setting, format!("'{s}' is neither auto, mask nor a number a raster can hold"))),
        },
    }
}

/// An error bound in scan pixels, or `none`.
pub fn parse_max_error(setting: &'static str, s: &str) -> Result<Option<f64>> {
    match s.trim() {
        "none" => Ok(None),
        t => match t.parse::<f64>() {
            Ok(e) if e > 0.0 && e.is_finite() => Ok(Some(e)),
            _ => Err(Error::setting(setting, format!("'{s}' is neither a positive number of scan pixels nor none"))),
        },
    }
}

/// What to do where the DEM has no height: `error`, `nodata` or a height.
pub fn parse_miss(setting: &'static str, s: &str) -> Result<Miss> {
    match s.trim() {
        "error" => Ok(Miss::Error),
        "nodata" => Ok(Miss::Nodata),
        h => h
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .map(Miss::Height)
            .ok_or_else(|| Error::setting(setting, format!("'{s}' is neither error, nodata nor a height"))),
    }
}

/// A size like `128M`, `1.5G`, `64k` or a byte count.
pub fn parse_bytes(setting: &'static str, s: &str) -> Result<u64> {
    let t = s.trim();
    let (num, mult) = match t.chars().last() {
        Some('K' | 'k') => (&t[..t.len() - 1], 1u64 << 10),
        Some('M' | 'm') => (&t[..t.len() - 1], 1 << 20),
        Some('G' | 'g') => (&t[..t.len() - 1], 1 << 30),
        Some('T' | 't') => (&t[..t.len() - 1], 1 << 40),
        _ => (t, 1),
    };
    let v: f64 = num.parse().map_err(|_| Error::setting(setting, format!("'{s}' is not a size like 128M")))?;
    if !(v > 0.0) {
        return Err(Error::setting(setting, format!("'{s}' must be positive")));
    }
    let bytes = v * mult as f64;
    if !(bytes < u64::MAX as f64) {
        return Err(Error::setting(setting, format!("'{s}' is beyond any machine")));
    }
    Ok(bytes as u64)
}

/// A count like `2000000000`, `2G`, `500M` or `64k` (powers of 1000).
pub fn parse_count(setting: &'static str, s: &str) -> Result<u64> {
    let t = s.trim();
    let (num, mult) = match t.chars().last() {
        Some('K' | 'k') => (&t[..t.len() - 1], 1e3),
        Some('M' | 'm') => (&t[..t.len() - 1], 1e6),
        Some('G' | 'g') => (&t[..t.len() - 1], 1e9),
        Some('T' | 't') => (&t[..t.len() - 1], 1e12),
        _ => (t, 1.0),
    };
    let v: f64 = num.parse().map_err(|_| Error::setting(setting, format!("'{s}' is not a count like 2G")))?;
    let n = v * mult;
    if !(n >= 1.0 && n < u64::MAX as f64) {
        return Err(Error::setting(setting, format!("'{s}' must be a count from 1 on")));
    }
    Ok(n as u64)
}

/// `minx,miny,maxx,maxy`, or `auto` (None).
pub fn parse_bounds(setting: &'static str, s: &str) -> Result<Option<[f64; 4]>> {
    if s.trim() == "auto" {
        return Ok(None);
    }
    let bad = || Error::setting(setting, format!("'{s}' is not minx,miny,maxx,maxy with min < max"));
    let v: Vec<f64> = s.split(',').map(|p| p.trim().parse::<f64>()).collect::<std::result::Result<_, _>>().map_err(|_| bad())?;
    if v.len() != 4 {
        return Err(Error::setting(setting, format!("'{s}' has {} numbers: minx,miny,maxx,maxy are four", v.len())));
    }
    match v[..] {
        [x0, y0, x1, y1] if v.iter().all(|x| x.is_finite()) && x1 > x0 && y1 > y0 => Ok(Some([x0, y0, x1, y1])),
        _ => Err(bad()),
    }
}

/// `col,row,width,height` in output tiles, width and height above zero.
pub fn parse_window(setting: &'static str, s: &str) -> Result<[u32; 4]> {
    let bad = || Error::setting(setting, format!("'{s}' is not col,row,width,height (tiles, width and height > 0)"));
    let v: Vec<u32> = s.split(',').map(|p| p.trim().parse::<u32>()).collect::<std::result::Result<_, _>>().map_err(|_| bad())?;
    match v[..] {
        [c, r, w, h] if w > 0 && h > 0 => Ok([c, r, w, h]),
        _ => Err(bad()),
    }
}

/// The codec's level for the output: `level` for deflate and zstd,
/// `quality` for JPEG; each refused, by its name, where the codec has no
/// such setting or out of its range.
pub fn codec_level(compression: Compression, level: Option<u8>, quality: Option<u8>) -> Result<Option<u8>> {
    let name = format!("{compression:?}").to_lowercase();
    let jpeg = compression == Compression::Jpeg;
    let (given, other) = if jpeg { (quality, level.map(|l| ("level", l))) } else { (level, quality.map(|q| ("quality", q))) };
    if let Some((setting, v)) = other {
        return Err(Error::setting(
            setting,
            if jpeg { format!("{v}: jpeg compression takes a quality (1–100), not a level") } else { format!("{v}: only jpeg compression has a quality") },
        ));
    }
    let Some(l) = given else { return Ok(None) };
    let setting = compression.level_name();
    match compression.levels() {
        None => Err(Error::setting(setting, format!("{l}: {name} compression has no levels"))),
        Some((r, _)) if !r.contains(&l) => Err(Error::setting(setting, format!("{l}: {name} takes {} to {}", r.start(), r.end()))),
        Some(_) => Ok(Some(l)),
    }
}

/// `--overview-level` checked against the codec: the levels `level`
/// takes; JPEG's overviews keep the full level's quality.
pub fn overview_codec_level(compression: Compression, level: Option<u8>) -> Result<Option<u8>> {
    let Some(l) = level else { return Ok(None) };
    let name = format!("{compression:?}").to_lowercase();
    let why = match compression.levels() {
        _ if compression == Compression::Jpeg => "jpeg overviews take the full level's quality (‹quality›)".to_string(),
        None => format!("{name} compression has no levels"),
        Some((r, _)) if !r.contains(&l) => format!("{name} takes {} to {}", r.start(), r.end()),
        Some(_) => return Ok(Some(l)),
    };
    Err(Error::setting("overview_level", format!("{l}: {why}")))
}

/// Which overview levels a tiled output gets.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Overviews {
    /// 2×, 4×, … until one tile holds the level (GDAL's rule).
    #[default]
    Auto,
    None,
    /// 2×, 4×, … 2ⁿ×: this many levels.
    Levels(u32),
}

impl Overviews {
    /// The levels an output of `width`×`height` in `tile`-pixel tiles gets.
    pub fn levels(self, width: u32, height: u32, tile: u32) -> u32 {
        match self {
            Overviews::Auto => crate::io::tiff_out::OutputSpec::auto_overviews(width, height, tile),
            Overviews::None => 0,
            Overviews::Levels(n) => n,
        }
    }
}

/// `auto`, `none`, or the reduction factors `2,4,8,…`: each level is made
/// from the one before, so the factors are the powers of two from 2 on.
pub fn parse_overviews(setting: &'static str, s: &str) -> Result<Overviews> {
    match s.trim() {
        "auto" => return Ok(Overviews::Auto),
        "none" | "0" => return Ok(Overviews::None),
        _ => {}
    }
    let factors: Vec<u32> = s
        .split(',')
        .map(|p| p.trim().parse::<u32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| Error::setting(setting, format!("'{s}' is not auto, none or a list of reduction factors like 2,4,8")))?;
    let n = factors.len() as u32;
    if n > 30 || factors.iter().enumerate().any(|(i, &f)| f != 2 << i) {
        return Err(Error::setting(
            setting,
            format!("'{s}': the levels are made each from the one before, so the factors are 2,4,8,… in order, none left out"),
        ));
    }
    Ok(Overviews::Levels(n))
}

/// `col,row` of a crop's offset in its scene.
pub fn parse_offset(setting: &'static str, s: &str) -> Result<[f64; 2]> {
    let bad = || Error::setting(setting, format!("'{s}' is not col,row"));
    let v: Vec<f64> = s.split(',').map(|p| p.trim().parse::<f64>()).collect::<std::result::Result<_, _>>().map_err(|_| bad())?;
    match v[..] {
        [c, r] if c.is_finite() && r.is_finite() => Ok([c, r]),
        _ => Err(bad()),
    }
}

/// `I/N`: the I-th of N shares, I from 1 to N.
pub fn parse_shard(setting: &'static str, s: &str) -> Result<(u32, u32)> {
    let bad = || Error::setting(setting, format!("'{s}' is not I/N"));
    let (i, n) = s.split_once(['/', ',']).ok_or_else(bad)?;
    Ok((i.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?))
}

/// `WxH` in pixels.
pub fn parse_size(setting: &'static str, s: &str) -> Result<(u32, u32)> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| Error::setting(setting, format!("'{s}' is not WxH")))?;
    let w = w.trim().parse().map_err(|_| Error::setting(setting, format!("'{s}': bad width")))?;
    let h = h.trim().parse().map_err(|_| Error::setting(setting, format!("'{s}': bad height")))?;
    Ok((w, h))
}

/// This machine's memory, bytes (None where it cannot be told).
pub fn physical_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let kib: u64 = info.lines().find_map(|l| l.strip_prefix("MemTotal:"))?.trim().trim_end_matches("kB").trim().parse().ok()?;
    Some(kib << 10)
}

/// How the `camera` path of a run becomes its sensor model.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
#[allow(clippy::large_enum_variant)] // one a run
pub enum ModelSource {
    /// A camera file (TOML).
    #[default]
    CameraFile,
    /// An RPC file in any supported format (or the image itself).
    Rpc {
        /// The image is a crop from this column, row of the RPC's scene;
        /// None: the tile offset a DigitalGlobe XML records for the image's
        /// file name, else none.
        offset: Option<[f64; 2]>,
        /// The DEM's heights are above this geoid (PROJ .gtx or GeoTIFF grid).
        geoid: Option<PathBuf>,
    },
    /// Built already (a block's interior file with one row of exterior
    /// orientations); `camera` names where it came from. A mosaic's own:
    /// not serialized (the block's files say it).
    #[serde(skip)]
    Inline(CameraFile),
    /// The camera file (any format `camera::formats` reads) with the
    /// exterior orientations of many images in this file: the image's own
    /// is found by its name; `angles`: the unit of a CSV's angles.
    WithPoses { poses: PathBuf, angles: crate::camera::formats::AngleUnit },
}

impl ModelSource {
    /// The camera file it stands for, where there is one without reading `origin`.
    pub fn inline(&self) -> Option<&CameraFile> {
        match self {
            ModelSource::Inline(f) => Some(f),
            _ => None,
        }
    }
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub enum DemSource {
    File(PathBuf),
    /// A constant height, metres.
    Height(f64),
    /// The sensor model's own: an RPC's HEIGHT_OFF (in the DEM datum, so
    /// less the geoid's undulation when there is one); an error for frame
    /// cameras, which have none.
    ModelHeight,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
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
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BandOrder {
    /// Whichever of the two crosses fewer scan rows a band.
    Auto,
    Rows,
    Columns,
}

/// Ground control points that refine the sensor model.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct GcpOptions {
    pub file: PathBuf,
    pub model: crate::camera::gcp::BiasModel,
    /// The most any point may sit off the refined model, image pixels.
    pub max_residual: f64,
}

/// What a run is asked to do, in groups by what each setting decides.
/// Built by [`RectifyOptions::new`] with the documented defaults (or by
/// key, [`crate::by_key::rectify_options`]), then set field by field;
/// [`RectifyOptions::validate`] checks the ranges. Serialized (serde) the
/// groups are flattened into one object, as a run's report has it; read
/// back it is the same run.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub struct RectifyOptions {
    /// The files read and how they become the sensor and the terrain.
    #[serde(flatten)]
    pub inputs: Inputs,
    /// Where the orthophoto's pixels lie on the ground.
    #[serde(flatten)]
    pub grid: Grid,
    /// How closely the sensor model is followed.
    #[serde(flatten)]
    pub geometry: Geometry,
    /// How each output pixel's value is made.
    #[serde(flatten)]
    pub pixels: Pixels,
    /// The output file: its path, layout and codec.
    #[serde(flatten)]
    pub file: OutputFile,
    /// What the run may take of the machine.
    #[serde(flatten)]
    pub resources: Resources,
}

/// The files a run reads and how they become its sensor and terrain.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub struct Inputs {
    pub image: PathBuf,
    /// The camera file, the RPC file, or where an inline camera came from
    /// (named in messages).
    pub camera: PathBuf,
    /// How `camera` becomes the sensor model.
    pub model: ModelSource,
    /// Ground control points refining the model.
    pub gcps: Option<GcpOptions>,
    pub dem: DemSource,
    pub dem_hole: Miss,
    pub dem_outside: Miss,
}

/// Where the orthophoto's pixels lie: its CRS, pixel size and extent.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub struct Grid {
    /// Output pixel size, ground units (across, down); `None`: the scan's
    /// mean GSD, square.
    pub gsd: Option<Gsd>,
    /// `[minx, miny, maxx, maxy]`; `None`: the scan's footprint on the DEM.
    pub bounds: Option<[f64; 4]>,
    /// How the bounds become a grid.
    pub snap: Snap,
    /// The grid (CRS, origin, pixel size, size) of this raster, instead of
    /// `gsd` and `bounds`.
    pub like: Option<PathBuf>,
    /// The orthophoto's CRS; `None`: the reference grid's (`like`), else
    /// the camera's (an RPC's: its scene's UTM zone).
    #[serde(with = "crate::geodesy::optional_crs_definition")]
    pub crs: Option<Crs>,
    /// Only this piece of the output grid, in tiles: `[col, row, w, h]`.
    /// Pieces made separately assemble into the whole, pixel for pixel.
    pub window: Option<[u32; 4]>,
    /// The most output pixels the run may make; `None`: 16 times the
    /// scan's pixels (at least 2²⁸), which a GSD or bounds typo passes.
    pub max_output_pixels: Option<u64>,
}

/// How closely the sensor model is followed: the GCM's node spacing,
/// its corrections and error bound, and the approximation's trend.
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub struct Geometry {
    pub gcm: GcmSpec,
    /// Choose `gcm.k` from the DEM (see `rectify`); off when the user gives
    /// the sparsity.
    pub auto_sparsity: bool,
    pub trend: Trend,
}

/// How each output pixel's value is made, and how pixels without one are
/// marked.
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub struct Pixels {
    pub kernel: Kernel,
    /// How pixels without a value are marked (ignored with `alpha`).
    pub nodata: Nodata,
    /// An alpha band instead of nodata or the mask.
    pub alpha: bool,
    /// Pixels the sensor does not see on the DSM.
    pub occlusion: Occlusion,
}

/// The output file: its path, tiles, codec and overviews.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub struct OutputFile {
    /// The orthophoto (`output`).
    #[serde(rename = "output")]
    pub path: PathBuf,
    pub tile: u32,
    pub compress: Compression,
    /// The codec's level (`None`: its default).
    pub level: Option<u8>,
    /// The overview tiles' level (`None`: `level`, else the fastest).
    pub overview_level: Option<u8>,
    /// JPEG's quality (`None`: its default).
    pub quality: Option<u8>,
    pub bigtiff: BigTiff,
    /// Internal overviews, and how their pixels are made.
    pub overviews: Overviews,
    pub overview_resampling: OverviewResampling,
    /// The Cloud-Optimized layout (GDAL's COG).
    pub cog: bool,
    /// Put the output on disk (fsync) before it gets its name, so that not
    /// even a power failure leaves an incomplete file under that name. Off
    /// (`no_sync`): the kernel writes it back in its own time, as after
    /// `cat` or `gdalwarp`.
    pub sync: bool,
}

/// What the run may take of the machine, and the order it works in.
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub struct Resources {
    /// Worker threads (0 = all cores; 1 = every step one after the other).
    pub threads: usize,
    /// Memory budget, bytes.
    pub memory: u64,
    /// The budget the geometry's choices are made for, where not `memory`
    /// (a mosaic's images get shares that differ from window to window;
    /// their node spacing must not, or pieces would differ from the whole).
    #[serde(default)]
    pub geometry_memory: Option<u64>,
    pub band_order: BandOrder,
}

impl RectifyOptions {
    /// The error bound by default, scan pixels: `A + c` is held within it
    /// of the exact model at every output pixel.
    pub const DEFAULT_MAX_ERROR: f64 = 0.1;

    /// The bound a run takes unless the user chose one: the default, but
    /// none for a fixed node spacing or cell corrections (the thesis'
    /// method as it stands, its error reported), which ask for the matrix
    /// as given.
    pub fn default_max_error(sparsity_given: bool, mode: CorrectionMode) -> Option<f64> {
        (!sparsity_given && mode == CorrectionMode::Bilinear).then_some(Self::DEFAULT_MAX_ERROR)
    }

    /// Tile sizes: multiples of 16 (the TIFF rule) up to this.
    pub const MAX_TILE: u32 = 4096;
    /// The least memory budget a run can keep to.
    pub const MIN_MEMORY: u64 = 16 << 20;
    /// Threads beyond this are a typo, not a machine.
    pub const MAX_THREADS: usize = 1024;
    /// GCM node spacing beyond this (output pixels) is no approximation.
    pub const MAX_SPARSITY: u32 = 1024;

    /// Checks every setting's range and the settings against each other;
    /// the first problem, named by its setting.
    pub fn validate(&self) -> Result<()> {
        if self.file.tile == 0 || !self.file.tile.is_multiple_of(16) || self.file.tile > Self::MAX_TILE {
            return Err(Error::setting("tile", format!("{} must be a multiple of 16 up to {}", self.file.tile, Self::MAX_TILE)));
        }
        if self.geometry.gcm.k == 0 || self.geometry.gcm.k > Self::MAX_SPARSITY {
            return Err(Error::setting("sparsity", format!("{} is not 1 to {}", self.geometry.gcm.k, Self::MAX_SPARSITY)));
        }
        if self.resources.threads > Self::MAX_THREADS {
            return Err(Error::setting("threads", format!("{} is more than {} (0 takes every core)", self.resources.threads, Self::MAX_THREADS)));
        }
        if let Some(e) = self.geometry.gcm.max_error {
            if !(e > 0.0) || !e.is_finite() {
                return Err(Error::setting("max_error", format!("{e} must be a positive number")));
            }
            if self.geometry.gcm.mode == CorrectionMode::Cell {
                return Err(Error::setting("max_error", "works with bilinear corrections, not cell"));
            }
        }
        if self.resources.memory < Self::MIN_MEMORY {
            return Err(Error::setting("memory", "must be at least 16M"));
        }
        if let Some(ram) = physical_memory().filter(|&ram| self.resources.memory > ram) {
            return Err(Error::setting("memory", format!("{} MiB is more than this machine's {} MiB", self.resources.memory >> 20, ram >> 20)));
        }
        if let Nodata::Value(v) = self.pixels.nodata {
            if !v.is_finite() && !v.is_nan() {
                return Err(Error::setting("nodata", format!("{v} is not a number a raster can hold")));
            }
        }
        if let DemSource::Height(h) = self.inputs.dem {
            // The deepest trench to the highest peak, with a margin.
            if !(h.abs() <= 12_000.0) {
                return Err(Error::setting("height", format!("{h} m is not a height of the earth's surface (−12 000 to 12 000 m)")));
            }
        }
        if self.grid.max_output_pixels == Some(0) {
            return Err(Error::setting("max_output_pixels", "must be at least 1"));
        }
        if let Some(g) = self.grid.gsd {
            if !g.is_valid() {
                return Err(Error::setting("gsd", format!("{g} must be positive")));
            }
        }
        if let DemSource::Height(h) = self.inputs.dem {
            if !h.is_finite() {
                return Err(Error::setting("height", format!("{h} is not a finite number")));
            }
        }
        if let Some(b) = self.grid.bounds {
            if !(b.iter().all(|x| x.is_finite()) && b[2] > b[0] && b[3] > b[1]) {
                return Err(Error::setting("bounds", format!("{b:?} is not minx,miny,maxx,maxy with min < max")));
            }
        }
        if self.grid.like.is_some() && (self.grid.gsd.is_some() || self.grid.bounds.is_some()) {
            return Err(Error::setting("like", "gives the grid: drop the GSD and bounds"));
        }
        if self.grid.like.is_some() && self.grid.snap != Snap::Tap {
            return Err(Error::setting("snap", "places bounds on the GSD; the reference grid (‹like›) is taken as it is"));
        }
        self.codec_level()?;
        self.overview_codec_level()?;
        if self.pixels.occlusion != Occlusion::None && !matches!(self.inputs.dem, DemSource::File(_)) {
            return Err(Error::setting("occlusion", "needs a DSM to see buildings on (a constant height hides nothing)"));
        }
        if self.pixels.occlusion == Occlusion::Mask && !self.pixels.alpha && matches!(self.pixels.nodata, Nodata::Value(_)) {
            return Err(Error::setting(
                "occlusion",
                "mask keeps hidden pixels' values and marks them in the internal mask or alpha: drop ‹nodata› VALUE, or take ‹occlusion› nodata",
            ));
        }
        if let Some([_, _, w, h]) = self.grid.window {
            if w == 0 || h == 0 {
                return Err(Error::setting("window", "width and height must be above zero"));
            }
        }
        Ok(())
    }

    /// The output codec's level or quality (`None`: its default), checked.
    pub fn codec_level(&self) -> Result<Option<u8>> {
        codec_level(self.file.compress, self.file.level, self.file.quality)
    }

    /// The overview tiles' codec level (`None`: see `overview_level`), checked.
    pub fn overview_codec_level(&self) -> Result<Option<u8>> {
        overview_codec_level(self.file.compress, self.file.overview_level)
    }

    /// The files the run reads, each with what it is.
    pub fn inputs(&self) -> Vec<(&'static str, PathBuf)> {
        let mut v = vec![("image", self.inputs.image.clone())];
        let what = match self.inputs.model {
            ModelSource::Rpc { .. } => "RPC file",
            _ => "camera file",
        };
        v.push((what, self.inputs.camera.clone()));
        if matches!(self.inputs.model, ModelSource::CameraFile) {
            v.extend(crate::camera::file::CameraFile::files_named_in(&self.inputs.camera));
        }
        if let ModelSource::Rpc { geoid: Some(g), .. } = &self.inputs.model {
            v.push(("geoid grid", g.clone()));
        }
        if let ModelSource::WithPoses { poses, .. } = &self.inputs.model {
            v.push(("exterior orientations", poses.clone()));
        }
        if let Some(g) = &self.inputs.gcps {
            v.push(("GCP file", g.file.clone()));
        }
        if let DemSource::File(d) = &self.inputs.dem {
            v.push(("DEM", d.clone()));
            v.extend(crate::dem::Dem::tile_files(d).into_iter().map(|t| ("DEM tile", t)));
        }
        if let Some(l) = &self.grid.like {
            v.push(("reference grid", l.clone()));
        }
        // What other tools keep beside them (a CSV's .prj, an image's
        // .aux.xml or world file, RPC files, an XMP sidecar) is read too.
        let beside: Vec<PathBuf> = v.iter().flat_map(|(_, p)| crate::io::sidecars::of(p)).collect();
        v.extend(beside.into_iter().map(|p| ("file beside an input (read with it)", p)));
        v
    }

    /// Refuses an output that cannot be written, or that is one of the
    /// inputs or another of `also` (outputs beside the orthophoto).
    pub fn check_outputs(&self, also: &[Role]) -> Result<()> {
        let inputs = self.inputs();
        let ins: Vec<Role> = inputs.iter().map(|(w, p)| Role::new(w, p)).collect();
        let mut outs = vec![Role::new("output", &self.file.path)];
        outs.extend_from_slice(also);
        for o in &outs {
            check_writable(*o)?;
        }
        check_outputs(&ins, &outs)
    }

    /// A configuration with the documented defaults.
    pub fn new(image: PathBuf, camera: PathBuf, dem: DemSource, output: PathBuf) -> RectifyOptions {
        RectifyOptions {
            inputs: Inputs { image, camera, model: ModelSource::CameraFile, gcps: None, dem, dem_hole: Miss::Error, dem_outside: Miss::Nodata },
            grid: Grid { gsd: None, bounds: None, snap: Snap::Tap, like: None, crs: None, window: None, max_output_pixels: None },
            geometry: Geometry {
                gcm: GcmSpec { k: 16, mode: CorrectionMode::Bilinear, max_error: Some(Self::DEFAULT_MAX_ERROR) },
                auto_sparsity: true,
                trend: Trend::Plane,
            },
            pixels: Pixels { kernel: Kernel::Bilinear, nodata: Nodata::Auto, alpha: false, occlusion: Occlusion::None },
            file: OutputFile {
                path: output,
                tile: 256,
                compress: Compression::Deflate,
                level: None,
                overview_level: None,
                quality: None,
                bigtiff: BigTiff::Auto,
                overviews: Overviews::Auto,
                overview_resampling: OverviewResampling::Average,
                cog: false,
                sync: true,
            },
            resources: Resources { threads: 0, memory: 128 << 20, geometry_memory: None, band_order: BandOrder::Auto },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn parsers_take_what_the_help_says_and_name_the_setting_otherwise() {
        assert_eq!(parse_bytes("memory", "128M").unwrap(), 128 << 20);
        assert_eq!(parse_bytes("memory", "1.5g").unwrap(), 3 << 29);
        assert_eq!(parse_count("max_output_pixels", "2G").unwrap(), 2_000_000_000);
        assert_eq!(parse_bounds("bounds", "1,2,3,4").unwrap(), Some([1.0, 2.0, 3.0, 4.0]));
        assert_eq!(parse_bounds("bounds", "auto").unwrap(), None);
        // Three numbers: said as such, not as a min/max order.
        assert!(parse_bounds("bounds", "1,2,3").unwrap_err().to_string().contains("has 3 numbers: minx,miny,maxx,maxy are four"));
        assert_eq!(parse_window("window", "0, 1, 2, 3").unwrap(), [0, 1, 2, 3]);
        assert_eq!(parse_choice::<Kernel>("resample", "cubic").unwrap(), Kernel::Cubic);
        assert_eq!(parse_overviews("overviews", "2, 4,8").unwrap(), Overviews::Levels(3));
        assert_eq!(parse_overviews("overviews", "none").unwrap(), Overviews::None);
        assert_eq!(parse_overviews("overviews", "auto").unwrap().levels(40000, 300, 256), 8);
        for (e, key) in [
            (parse_bytes("memory", "1e20").unwrap_err(), "memory"),
            (parse_bytes("memory", "-5M").unwrap_err(), "memory"),
            (parse_bounds("bounds", "3,2,1,4").unwrap_err(), "bounds"),
            (parse_window("window", "0,0,0,1").unwrap_err(), "window"),
            (parse_choice::<Kernel>("resample", "bicubic").unwrap_err(), "resample"),
            (parse_overviews("overviews", "2,8").unwrap_err(), "overviews"),
            (parse_overviews("overviews", "4").unwrap_err(), "overviews"),
            (parse_miss("dem_hole", "zero").unwrap_err(), "dem_hole"),
        ] {
            assert!(matches!(&e, Error::Setting { setting, .. } if *setting == key), "{e}");
        }
        let mut o = RectifyOptions::new("s".into(), "c".into(), DemSource::Height(0.0), "o".into());
        o.validate().unwrap();
        o.file.tile = 100;
        assert!(o.validate().unwrap_err().to_string().starts_with("tile: 100"));
    }

    #[test]
    fn options_read_back_from_their_serialized_form_are_the_same_run() {
        let mut o = RectifyOptions::new("s.tif".into(), "c.txt".into(), DemSource::ModelHeight, "o.tif".into());
        o.inputs.model = ModelSource::Rpc { offset: Some([5000.0, 4000.0]), geoid: Some("g.gtx".into()) };
        o.inputs.gcps = Some(GcpOptions { file: "g.csv".into(), model: BiasModel::Affine, max_residual: 1.5 });
        o.inputs.dem_hole = Miss::Height(12.5);
        o.grid.gsd = Some(Gsd { x: 0.5, y: 0.25 });
        o.grid.bounds = Some([1.0, 2.0, 3.0, 4.0]);
        o.grid.crs = Some(Crs::parse("EPSG:32633+5773", std::path::Path::new("")).expect("a CRS"));
        o.geometry.gcm = GcmSpec { k: 8, mode: CorrectionMode::Bilinear, max_error: None };
        o.pixels.nodata = Nodata::Value(0.0);
        o.pixels.occlusion = Occlusion::Mask;
        o.file.overviews = Overviews::Levels(3);
        o.file.compress = Compression::Zstd;
        o.resources.band_order = BandOrder::Columns;
        let text = serde_json::to_string(&o).expect("serialized");
        let back: RectifyOptions = serde_json::from_str(&text).expect("read back");
        assert_eq!(serde_json::to_string(&back).expect("serialized"), text);
        assert_eq!(back.grid.crs.as_ref().and_then(Crs::epsg), Some(32633));
        assert!(back.grid.crs.as_ref().and_then(Crs::vertical).is_some_and(|v| v.epsg == Some(5773)));
        assert!(matches!(back.inputs.model, ModelSource::Rpc { offset: Some([c, r]), .. } if (c, r) == (5000.0, 4000.0)));
        assert!(matches!(back.pixels.nodata, Nodata::Value(v) if v == 0.0));
        // A CRS without a code goes as its PROJ string.
        o.grid.crs = Some(Crs::parse("+proj=tmerc +lat_0=0 +lon_0=39 +k=1 +x_0=500000 +y_0=0 +ellps=krass +units=m", std::path::Path::new("")).expect("a CRS"));
        let back: RectifyOptions = serde_json::from_str(&serde_json::to_string(&o).expect("serialized")).expect("read back");
        assert_eq!(back.grid.crs, o.grid.crs);
        // A mistyped choice is refused by name.
        // NaN, which JSON has no number for.
        o.pixels.nodata = Nodata::Value(f64::NAN);
        let back: RectifyOptions = serde_json::from_str(&serde_json::to_string(&o).expect("serialized")).expect("read back");
        assert!(matches!(back.pixels.nodata, Nodata::Value(v) if v.is_nan()));
        let bad = text.replace("\"zstd\"", "\"zstdd\"");
        assert!(serde_json::from_str::<RectifyOptions>(&bad).expect_err("no such codec").to_string().contains("zstdd"));
    }

    #[test]
    fn a_level_is_one_the_codec_takes() {
        for (compression, level, ok) in [
            (Compression::Deflate, 1, true),
            (Compression::Deflate, 12, true),
            (Compression::Deflate, 0, true),
            (Compression::Deflate, 13, false),
            (Compression::Zstd, 22, true),
            (Compression::Zstd, 0, false),
            (Compression::Zstd, 23, false),
            (Compression::Lzw, 1, false),
            (Compression::None, 1, false),
        ] {
            let r = codec_level(compression, Some(level), None);
            assert_eq!(r.is_ok(), ok, "{compression:?} {level}");
            match r {
                Ok(l) => assert_eq!(l, Some(level)),
                Err(e) => assert!(e.to_string().starts_with(&format!("level: {level}: {}", format!("{compression:?}").to_lowercase())), "{e}"),
            }
        }
        assert_eq!(codec_level(Compression::Lzw, None, None).unwrap(), None);
        // JPEG's is its quality, and only JPEG has one.
        assert_eq!(codec_level(Compression::Jpeg, None, Some(85)).unwrap(), Some(85));
        assert_eq!(codec_level(Compression::Jpeg, None, None).unwrap(), None);
        for (compression, level, quality, says) in [
            (Compression::Jpeg, None, Some(0), "quality: 0: jpeg takes 1 to 100"),
            (Compression::Jpeg, None, Some(101), "quality: 101: jpeg takes 1 to 100"),
            (Compression::Jpeg, Some(6), None, "level: 6: jpeg compression takes a quality"),
            (Compression::Deflate, None, Some(80), "quality: 80: only jpeg compression has a quality"),
            (Compression::Deflate, Some(6), Some(80), "quality: 80: only jpeg"),
        ] {
            let e = codec_level(compression, level, quality).unwrap_err().to_string();
            assert!(e.starts_with(says), "{e}");
        }
    }

    proptest! {
        #[test]
        fn no_text_makes_a_parser_panic(text in ".{0,40}") {
            let _ = parse_bytes("memory", &text);
            let _ = parse_count("max_output_pixels", &text);
            let _ = parse_bounds("bounds", &text);
            let _ = parse_window("window", &text);
            let _ = parse_offset("rpc_offset", &text);
            let _ = parse_size("size", &text);
            let _ = parse_miss("dem_hole", &text);
            let _ = parse_choice::<Compression>("compress", &text);
            let _ = parse_overviews("overviews", &text);
        }
    }
}
