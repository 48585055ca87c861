//! Settings by key: the one table that turns keys into a run's options,
//! for the batch manifest (`[defaults]` and each job) and for bindings
//! that pass settings by name (Python's keyword arguments). Keys are the
//! command line's option names with `_` for `-`.

use crate::error::{Error, Result};
use crate::gcm::GcmSpec;
use crate::options::{parse_bounds, parse_choice, parse_max_error, parse_miss, parse_nodata, parse_overviews, Nodata, RectifyOptions};
use serde::Deserialize;
use std::path::PathBuf;

/// `max_error = 0.1`, or `max_error = "none"`.
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum MaxError {
    Pixels(f64),
    Word(String),
}

/// A number, or a word: `nodata` (`"auto"` / `"mask"`), `dem_hole` and
/// `dem_outside` (a height, or `"error"` / `"nodata"`).
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum NumberOrWord {
    Value(f64),
    Word(String),
}

impl NumberOrWord {
    pub fn text(&self) -> String {
        match self {
            NumberOrWord::Value(v) => v.to_string(),
            NumberOrWord::Word(w) => w.clone(),
        }
    }
}

/// A setting given as its value (`[1.5, 2.0]`) or as the command line's
/// text for it (`"1.5,2"`): read by the command line's own parser either
/// way, so that both are checked alike.
#[derive(Clone, Debug)]
pub enum OrText<T> {
    Value(T),
    Text(String),
}

impl<'de, T: serde::de::DeserializeOwned> Deserialize<'de> for OrText<T> {
    /// A string is the text; anything else the value, whose own error says
    /// what is wrong with it (`invalid length 3, expected an array of
    /// length 4`), where an untagged enum would say only that it matched
    /// no variant.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        match serde_json::Value::deserialize(d)? {
            serde_json::Value::String(t) => Ok(OrText::Text(t)),
            v => serde_json::from_value(v).map(OrText::Value).map_err(serde::de::Error::custom),
        }
    }
}

impl<T: AsText> OrText<T> {
    /// The setting read by `parse` from its text (a value written as the
    /// command line would).
    pub fn read<R>(&self, parse: impl Fn(&str) -> Result<R>) -> Result<R> {
        match self {
            OrText::Text(t) => parse(t),
            OrText::Value(v) => parse(&v.as_text()),
        }
    }
}

/// A value as the command line writes it: its items joined by `,`.
pub trait AsText {
    fn as_text(&self) -> String;
}

impl<T: ToString, const N: usize> AsText for [T; N] {
    fn as_text(&self) -> String {
        self.iter().map(T::to_string).collect::<Vec<_>>().join(",")
    }
}

impl AsText for Vec<String> {
    fn as_text(&self) -> String {
        self.join(",")
    }
}

/// Every rectify option a manifest may set, in `[defaults]` or per job.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Options {
    pub dem: Option<String>,
    pub height: Option<f64>,
    pub dem_hole: Option<NumberOrWord>,
    pub dem_outside: Option<NumberOrWord>,
    /// A number, or `[x, y]` for non-square pixels.
    pub gsd: Option<crate::geom::Gsd>,
    /// `[minx, miny, maxx, maxy]`, or `"auto"`.
    pub bounds: Option<OrText<[f64; 4]>>,
    pub snap: Option<String>,
    /// A raster whose grid the orthophoto takes (relative to the manifest).
    pub like: Option<String>,
    /// The orthophoto's CRS, as `--crs` takes it (a `.prj` relative to the manifest).
    pub crs: Option<String>,
    pub sparsity: Option<u32>,
    pub max_error: Option<MaxError>,
    pub corrections: Option<String>,
    pub trend: Option<String>,
    pub resample: Option<String>,
    pub tile: Option<u32>,
    pub compress: Option<String>,
    pub level: Option<u8>,
    /// The overview tiles' level.
    pub overview_level: Option<u8>,
    /// JPEG's quality (1–100).
    pub quality: Option<u8>,
    pub bigtiff: Option<String>,
    /// `auto`, `none` or a list of factors.
    pub overviews: Option<String>,
    pub overview_resampling: Option<String>,
    pub cog: Option<bool>,
    pub nodata: Option<NumberOrWord>,
    pub alpha: Option<bool>,
    /// `none`, `nodata` or `mask` (a true orthophoto).
    pub occlusion: Option<String>,
    pub output_dir: Option<String>,
    /// Ground control points (each job takes those of its image).
    pub gcps: Option<String>,
    pub gcp_refine: Option<String>,
    pub gcp_max_residual: Option<f64>,
}

impl Options {
    /// `self` with unset fields taken from `base`.
    pub fn over(&self, base: &Options) -> Options {
        macro_rules! pick { ($($f:ident),*) => { Options { $($f: self.$f.clone().or_else(|| base.$f.clone()),)* } } }
        pick!(
            dem,
            height,
            dem_hole,
            dem_outside,
            gsd,
            bounds,
            snap,
            like,
            crs,
            sparsity,
            max_error,
            corrections,
            trend,
            resample,
            tile,
            compress,
            level,
            overview_level,
            quality,
            bigtiff,
            overviews,
            overview_resampling,
            cog,
            nodata,
            alpha,
            occlusion,
            output_dir,
            gcps,
            gcp_refine,
            gcp_max_residual
        )
    }
}

/// Sets on `c` every setting `o` gives (paths through `rel`); the DEM,
/// the output and the sensor are the caller's. Ranges are checked by
/// [`RectifyOptions::validate`].
pub fn apply(o: &Options, c: &mut RectifyOptions, rel: &dyn Fn(&str) -> PathBuf) -> Result<()> {
    if let Some(v) = &o.dem_hole {
        c.inputs.dem_hole = parse_miss("dem_hole", &v.text())?;
    }
    if let Some(v) = &o.dem_outside {
        c.inputs.dem_outside = parse_miss("dem_outside", &v.text())?;
    }
    c.grid.gsd = o.gsd;
    c.grid.bounds = o.bounds.as_ref().map(|b| b.read(|t| parse_bounds("bounds", t))).transpose()?.flatten();
    if let Some(s) = &o.snap {
        if o.like.is_some() {
            return Err(Error::setting("snap", "places bounds on the GSD; the reference grid (‹like›) is taken as it is"));
        }
        c.grid.snap = parse_choice("snap", s)?;
    }
    c.grid.like = o.like.as_deref().map(rel);
    if let Some(t) = &o.crs {
        // (A .prj relative to the manifest, or as given.)
        c.grid.crs = Some(crate::geodesy::Crs::parse(t, &rel("")).map_err(|m| Error::setting("crs", m))?);
    }
    if let Some(g) = &o.gcps {
        let model = parse_choice("gcp_refine", o.gcp_refine.as_deref().unwrap_or("auto"))?;
        let max_residual = o.gcp_max_residual.unwrap_or(2.0);
        if !(max_residual.is_finite() && max_residual > 0.0) {
            return Err(Error::setting("gcp_max_residual", "must be a positive number of pixels"));
        }
        c.inputs.gcps = Some(crate::options::GcpOptions { file: rel(g), model, max_residual });
    } else if o.gcp_refine.is_some() || o.gcp_max_residual.is_some() {
        return Err(Error::setting("gcp_refine", "goes with ‹gcps›"));
    }
    let mode = match &o.corrections {
        Some(m) => parse_choice("corrections", m)?,
        None => c.geometry.gcm.mode,
    };
    let max_error = match &o.max_error {
        Some(MaxError::Pixels(e)) => Some(*e),
        Some(MaxError::Word(w)) => parse_max_error("max_error", w)?,
        None => RectifyOptions::default_max_error(o.sparsity.is_some(), mode),
    };
    c.geometry.gcm = GcmSpec { k: o.sparsity.unwrap_or(16), mode, max_error };
    c.geometry.auto_sparsity = o.sparsity.is_none();
    if let Some(t) = &o.trend {
        c.geometry.trend = parse_choice("trend", t)?;
    }
    if let Some(k) = &o.resample {
        c.pixels.kernel = parse_choice("resample", k)?;
    }
    if let Some(t) = o.tile {
        c.file.tile = t;
    }
    if let Some(z) = &o.compress {
        c.file.compress = parse_choice("compress", z)?;
    }
    if o.level.is_some() {
        c.file.level = o.level;
    }
    if o.overview_level.is_some() {
        c.file.overview_level = o.overview_level;
    }
    if o.quality.is_some() {
        c.file.quality = o.quality;
    }
    if let Some(b) = &o.bigtiff {
        c.file.bigtiff = parse_choice("bigtiff", b)?;
    }
    if let Some(v) = &o.overviews {
        c.file.overviews = parse_overviews("overviews", v)?;
    }
    if let Some(r) = &o.overview_resampling {
        c.file.overview_resampling = parse_choice("overview_resampling", r)?;
    }
    c.file.cog = o.cog.unwrap_or(false);
    match &o.nodata {
        Some(NumberOrWord::Value(v)) => c.pixels.nodata = Nodata::Value(*v),
        Some(NumberOrWord::Word(w)) => c.pixels.nodata = parse_nodata("nodata", w)?,
        None => {}
    }
    c.pixels.alpha = o.alpha.unwrap_or(false);
    if let Some(v) = &o.occlusion {
        c.pixels.occlusion = parse_choice("occlusion", v)?;
    }
    Ok(())
}

/// `keys` (those not null) as `T`, a key at a time first so that a problem names its key:
/// `tile: invalid type: string "x", expected u32`; an unknown key with
/// the keys there are (`also`: others the caller takes).
pub(crate) fn by_key<T: serde::de::DeserializeOwned>(keys: serde_json::Map<String, serde_json::Value>, also: &[&str]) -> Result<T> {
    // None from a binding: the key is not set.
    let keys: serde_json::Map<_, _> = keys.into_iter().filter(|(_, v)| !v.is_null()).collect();
    for (k, v) in &keys {
        let one = serde_json::Value::Object(std::iter::once((k.clone(), v.clone())).collect());
        if let Err(e) = serde_json::from_value::<T>(one) {
            let e = e.to_string();
            if let Some(known) = e.strip_prefix(&format!("unknown field `{k}`, expected one of ")) {
                let more: String = also.iter().map(|a| format!(", `{a}`")).collect();
                return Err(Error::Usage(format!("{k}: not an option here (the options: {known}{more})")));
            }
            // A missing field is another key's problem; the whole says it.
            if !e.starts_with("missing field") {
                return Err(Error::Usage(format!("{k}: {e}")));
            }
        }
    }
    serde_json::from_value(serde_json::Value::Object(keys)).map_err(|e| Error::Usage(format!("options: {e}")))
}

/// A single run's keys beyond a manifest job's: its files, its sensor, the
/// piece of the grid it makes and the resources it may take (a batch
/// decides those for its jobs).
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunKeys {
    pub image: Option<PathBuf>,
    pub camera: Option<PathBuf>,
    /// The poses of many images (with `camera`: the lens alone).
    pub exterior: Option<PathBuf>,
    /// The unit of `exterior`'s angles.
    #[serde(default)]
    pub radians: bool,
    pub rpc: Option<PathBuf>,
    /// `"col,row"` or `[col, row]`: the image's place in the RPC's scene.
    pub rpc_offset: Option<OrText<[f64; 2]>>,
    pub geoid: Option<PathBuf>,
    pub output: Option<PathBuf>,
    /// Tiles `[col, row, width, height]` of the output grid.
    pub window: Option<OrText<[u32; 4]>>,
    pub band_order: Option<String>,
    pub threads: Option<usize>,
    /// Bytes, or text as the command line takes it (`"512M"`).
    pub memory: Option<NumberOrWord>,
    pub max_output_pixels: Option<NumberOrWord>,
    /// Put the output on disk before it gets its name (default true).
    pub sync: Option<bool>,
}

/// Keys of [`RunKeys`], told apart from a job's ([`Options`]).
const RUN_KEYS: [&str; 15] = [
    "image",
    "camera",
    "exterior",
    "radians",
    "rpc",
    "rpc_offset",
    "geoid",
    "output",
    "window",
    "band_order",
    "threads",
    "memory",
    "max_output_pixels",
    "sync",
    "json",
];

/// A single run's options from keys (`{"image": …, "camera": …, "dem": …,
/// "output": …, "sparsity": 8}`), relative paths as given: what a
/// binding's keyword arguments become. Unknown keys and keys of a
/// manifest only are refused by name; ranges are checked.
pub fn rectify_options(keys: serde_json::Map<String, serde_json::Value>) -> Result<RectifyOptions> {
    let (mut run, mut job) = (serde_json::Map::new(), serde_json::Map::new());
    for (k, v) in keys {
        // None from a binding: the key is not set.
        if v.is_null() {
            continue;
        }
        if k == "output_dir" {
            return Err(Error::setting("output_dir", "is a batch manifest's key: a single run takes output"));
        }
        if k == "json" {
            continue;
        }
        if RUN_KEYS.contains(&k.as_str()) {
            run.insert(k, v);
        } else {
            job.insert(k, v);
        }
    }
    let r: RunKeys = by_key(run, &[])?;
    let o: Options = by_key(job, &RUN_KEYS)?;
    let image = r.image.clone().ok_or_else(|| Error::setting("image", "is needed: the scan or frame to rectify"))?;
    let output = r.output.clone().ok_or_else(|| Error::setting("output", "is needed: the orthophoto's path"))?;
    let (camera, model) = match (&r.camera, &r.rpc) {
        (Some(_), None) if r.rpc_offset.is_some() => return Err(Error::setting("rpc_offset", "goes with ‹rpc›, not a camera file")),
        (Some(_), None) if r.geoid.is_some() => return Err(Error::setting("geoid", "goes with ‹rpc›, not a camera file")),
        (Some(c), None) => {
            let angles = if r.radians { crate::camera::formats::AngleUnit::Radians } else { crate::camera::formats::AngleUnit::Degrees };
            (c.clone(), r.exterior.clone().map_or(crate::options::ModelSource::CameraFile, |poses| crate::options::ModelSource::WithPoses { poses, angles }))
        }
        (None, Some(p)) => {
            let offset = r.rpc_offset.as_ref().map(|o| o.read(|t| crate::options::parse_offset("rpc_offset", t))).transpose()?;
            (p.clone(), crate::options::ModelSource::Rpc { offset, geoid: r.geoid.clone() })
        }
        (Some(_), Some(_)) => return Err(Error::setting("camera", "give a camera file or an RPC file, not both")),
        (None, None) => return Err(Error::setting("camera", "give a camera file or an RPC file")),
    };
    if r.exterior.is_none() && r.radians {
        return Err(Error::setting("radians", "goes with ‹exterior›"));
    }
    let dem = match (&o.dem, o.height) {
        (Some(d), None) => crate::options::DemSource::File(PathBuf::from(d)),
        (None, Some(h)) => crate::options::DemSource::Height(h),
        (None, None) if r.rpc.is_some() => crate::options::DemSource::ModelHeight,
        (Some(_), Some(_)) => return Err(Error::setting("dem", "give dem or height, not both")),
        (None, None) => return Err(Error::setting("dem", "give a DEM file or a constant height")),
    };
    let mut c = RectifyOptions::new(image, camera, dem, output);
    c.inputs.model = model;
    apply(&o, &mut c, &|p| PathBuf::from(p))?;
    c.grid.window = r.window.as_ref().map(|w| w.read(|t| crate::options::parse_window("window", t))).transpose()?;
    if let Some(b) = &r.band_order {
        c.resources.band_order = parse_choice("band_order", b)?;
    }
    if let Some(t) = r.threads {
        c.resources.threads = t;
    }
    if let Some(m) = &r.memory {
        c.resources.memory = crate::options::parse_bytes("memory", &m.text())?;
    }
    if let Some(m) = &r.max_output_pixels {
        c.grid.max_output_pixels = Some(crate::options::parse_count("max_output_pixels", &m.text())?);
    }
    c.file.sync = r.sync.unwrap_or(true);
    c.validate()?;
    Ok(c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn keys(v: serde_json::Value) -> serde_json::Map<String, serde_json::Value> {
        v.as_object().expect("an object").clone()
    }

    #[test]
    fn a_single_runs_keys_set_what_the_flags_set() {
        let o = rectify_options(keys(json!({
            "image": "scan.tif", "camera": "cam.toml", "dem": "dem.tif", "output": "o.tif",
            "sparsity": 8, "max_error": "none", "gsd": [0.5, 0.25], "compress": "zstd", "level": 9,
            "nodata": 0, "window": [1, 2, 3, 4], "memory": "512M", "threads": 1, "sync": false, "band_order": "columns",
        })))
        .expect("valid keys");
        assert_eq!((o.geometry.gcm.k, o.geometry.gcm.max_error, o.geometry.auto_sparsity), (8, None, false));
        assert_eq!((o.grid.gsd.map(|g| (g.x, g.y)), o.file.level, o.grid.window), (Some((0.5, 0.25)), Some(9), Some([1, 2, 3, 4])));
        assert_eq!((o.resources.memory, o.resources.threads, o.file.sync), (512 << 20, 1, false));
        assert!(matches!(o.pixels.nodata, Nodata::Value(v) if v == 0.0));
        assert!(matches!(o.resources.band_order, crate::options::BandOrder::Columns));
        assert!(matches!(o.inputs.dem, crate::options::DemSource::File(ref p) if p == std::path::Path::new("dem.tif")));
        // The defaults are RectifyOptions::new's.
        let d = rectify_options(keys(json!({"image": "s.tif", "camera": "c.toml", "height": 310.0, "output": "o.tif"}))).expect("valid");
        let n = RectifyOptions::new("s.tif".into(), "c.toml".into(), crate::options::DemSource::Height(310.0), "o.tif".into());
        assert_eq!(serde_json::to_value(&d).expect("json"), serde_json::to_value(&n).expect("json"));
    }

    #[test]
    fn an_rpc_without_a_dem_takes_its_own_height() {
        let o = rectify_options(keys(json!({"image": "i.tif", "rpc": "i_RPC.TXT", "rpc_offset": [5000, 4000], "output": "o.tif"}))).expect("valid");
        assert!(matches!(o.inputs.dem, crate::options::DemSource::ModelHeight));
        assert!(matches!(o.inputs.model, crate::options::ModelSource::Rpc { offset: Some([5000.0, 4000.0]), .. }));
    }

    #[test]
    fn a_problem_names_its_key() {
        let bad = |v: serde_json::Value| rectify_options(keys(v)).expect_err("refused").to_string();
        let base = json!({"image": "s.tif", "camera": "c.toml", "height": 0.0, "output": "o.tif"});
        let with = |k: &str, v: serde_json::Value| {
            let mut m = base.clone();
            m[k] = v;
            m
        };
        assert!(bad(with("sparsty", json!(8))).starts_with("sparsty: not an option here (the options: `dem`"), "{}", bad(with("sparsty", json!(8))));
        assert!(bad(with("sparsity", json!("x"))).starts_with("sparsity: invalid type"));
        assert!(bad(with("tile", json!(17))).starts_with("tile: 17 must be a multiple of 16"));
        assert!(bad(with("output_dir", json!("o/"))).starts_with("output_dir: is a batch manifest's key"));
        assert!(bad(with("radians", json!(true))).starts_with("radians: goes with exterior"));
        assert_eq!(bad(json!({"image": "s.tif", "camera": "c.toml", "output": "o.tif"})), "dem: give a DEM file or a constant height");
    }
}
