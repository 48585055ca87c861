//! Settings by key for the commands beyond a single run (`mosaic`,
//! `assemble`, `grid`, `dem`): the command line's options, `_` for `-`,
//! with its defaults; what a binding's keyword arguments become.

use crate::error::{Error, Result};
use crate::keys::{by_key, NumberOrWord, OrText};
use crate::options::{parse_choice, parse_overviews};
use serde::Deserialize;
use std::path::PathBuf;

/// A mosaic's keys: the command line's `mosaic` options, `_` for `-`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct MosaicKeys {
    manifest: Option<PathBuf>,
    output: Option<PathBuf>,
    plan_out: Option<PathBuf>,
    plan: Option<PathBuf>,
    window: Option<OrText<[u32; 4]>>,
    gsd: Option<crate::geom::Gsd>,
    bounds: Option<OrText<[f64; 4]>>,
    crs: Option<String>,
    like: Option<PathBuf>,
    balance: Option<String>,
    seams: Option<String>,
    blend: Option<f64>,
    seamlines_out: Option<PathBuf>,
    seamlines: Option<PathBuf>,
    cog: Option<bool>,
    occlusion: Option<String>,
    memory: Option<NumberOrWord>,
    threads: Option<usize>,
    force: Option<bool>,
    json: Option<PathBuf>,
    sync: Option<bool>,
}

/// A mosaic's options from keys, with the command line's defaults.
pub fn mosaic_options(keys: serde_json::Map<String, serde_json::Value>) -> Result<crate::mosaic::MosaicOptions> {
    let k: MosaicKeys = by_key(keys, &[])?;
    let manifest = k.manifest.ok_or_else(|| Error::setting("manifest", "is needed: the block's manifest"))?;
    if k.output.is_none() && k.plan_out.is_none() {
        return Err(Error::setting("output", "is needed (or plan_out for the plan alone)"));
    }
    if k.like.is_some() && (k.gsd.is_some() || k.bounds.is_some()) {
        return Err(Error::setting("like", "gives the grid: drop the GSD and bounds"));
    }
    if k.plan.is_some() && (k.seamlines.is_some() || k.seams.is_some() || k.balance.is_some()) {
        return Err(Error::setting("plan", "holds the seams and gains: drop seamlines, seams and balance"));
    }
    let least_cost = match k.seams.as_deref() {
        None | Some("least-cost") | Some("least_cost") => true,
        Some("voronoi") => false,
        Some(other) => return Err(Error::setting("seams", format!("'{other}' (expected least-cost or voronoi)"))),
    };
    let crs = k.crs.as_deref().map(|c| crate::geodesy::Crs::parse(c, std::path::Path::new("."))).transpose().map_err(|m| Error::setting("crs", m))?;
    Ok(crate::mosaic::MosaicOptions {
        manifest,
        output: k.output,
        gsd: k.gsd,
        bounds: k.bounds.as_ref().map(|b| b.read(|t| crate::options::parse_bounds("bounds", t))).transpose()?.flatten(),
        crs,
        like: k.like,
        balance: k.balance.as_deref().map(|b| parse_choice("balance", b)).transpose()?.unwrap_or(crate::mosaic::balance::Balance::GainOffset),
        least_cost,
        blend: k.blend.unwrap_or(8.0),
        seamlines_out: k.seamlines_out,
        seamlines_in: k.seamlines,
        plan_out: k.plan_out,
        plan_in: k.plan,
        window: k.window.as_ref().map(|w| w.read(|t| crate::options::parse_window("window", t))).transpose()?,
        memory: match &k.memory {
            Some(m) => crate::options::parse_bytes("memory", &m.text())?,
            None => 256 << 20,
        },
        threads: k.threads.unwrap_or(0),
        cog: k.cog.filter(|&c| c),
        overviews: None,
        compress: None,
        force: k.force.unwrap_or(false),
        occlusion: k.occlusion.as_deref().map(|o| parse_choice("occlusion", o)).transpose()?,
        sync: k.sync.unwrap_or(true),
        report: k.json,
    })
}

/// `assemble`'s keys: the layout of the whole (`overviews`,
/// `overview_resampling`, `cog`, `level`, `overview_level`, `quality`) and
/// `compress` to code the tiles anew.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct AssembleKeys {
    overviews: Option<String>,
    overview_resampling: Option<String>,
    cog: Option<bool>,
    level: Option<u8>,
    overview_level: Option<u8>,
    quality: Option<u8>,
    compress: Option<String>,
}

/// `assemble`'s options from keys.
pub fn assemble_options(keys: serde_json::Map<String, serde_json::Value>) -> Result<crate::assemble::AssembleOptions> {
    let k: AssembleKeys = by_key(keys, &[])?;
    Ok(crate::assemble::AssembleOptions {
        overviews: k.overviews.as_deref().map(|o| parse_overviews("overviews", o)).transpose()?,
        overview_resampling: k.overview_resampling.as_deref().map(|r| parse_choice("overview_resampling", r)).transpose()?,
        cog: k.cog.filter(|&c| c),
        level: k.level,
        overview_level: k.overview_level,
        quality: k.quality,
        compress: k.compress.as_deref().map(|c| parse_choice("compress", c)).transpose()?,
        ..Default::default()
    })
}

/// `--threads 0`: every core (the commands that take all by default).
fn every_core(asked: usize) -> usize {
    match asked {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        t => t,
    }
}

/// `blunders`: a number of robust sigmas, or `"none"`.
fn blunders(v: Option<&NumberOrWord>, default: Option<f64>) -> Result<Option<f64>> {
    match v {
        None => Ok(default),
        Some(NumberOrWord::Value(k)) => Ok(Some(*k)),
        Some(NumberOrWord::Word(w)) => match w.trim() {
            "none" | "off" => Ok(None),
            k => k.parse().map(Some).map_err(|_| Error::setting("blunders", format!("'{k}' is not a number of sigmas or none"))),
        },
    }
}

/// `LOWEST,HIGHEST`: the heights a stereo search spans.
fn parse_heights(setting: &'static str, text: &str) -> Result<[f64; 2]> {
    let bad = || Error::setting(setting, format!("'{text}' is not LOWEST,HIGHEST"));
    let v: Vec<f64> = text.split(',').map(|s| s.trim().parse::<f64>()).collect::<std::result::Result<_, _>>().map_err(|_| bad())?;
    match v[..] {
        [lo, hi] => Ok([lo, hi]),
        _ => Err(bad()),
    }
}

fn crs_of(setting: &'static str, text: Option<&str>) -> Result<Option<crate::geodesy::Crs>> {
    text.map(|c| crate::geodesy::Crs::parse(c, std::path::Path::new("."))).transpose().map_err(|m| Error::setting(setting, m))
}

/// `grid`'s keys: the command line's options, `_` for `-`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct GridKeys {
    points: Option<Vec<PathBuf>>,
    output: Option<PathBuf>,
    gsd: Option<crate::geom::Gsd>,
    bounds: Option<OrText<[f64; 4]>>,
    crs: Option<String>,
    points_crs: Option<String>,
    method: Option<String>,
    max_edge: Option<f64>,
    radius: Option<f64>,
    power: Option<f64>,
    neighbours: Option<usize>,
    /// `"x,y,z"` or three names (or numbers from 1).
    columns: Option<OrText<Vec<String>>>,
    class: Option<Vec<u8>>,
    returns: Option<String>,
    blunders: Option<NumberOrWord>,
    memory: Option<NumberOrWord>,
    threads: Option<usize>,
    tile: Option<u32>,
    block: Option<u32>,
    compress: Option<String>,
    level: Option<u8>,
    overviews: Option<String>,
    /// Taken to say what a DEM's overviews cannot be.
    overview_resampling: Option<String>,
    overview_level: Option<u8>,
    quality: Option<u8>,
    cog: Option<bool>,
    window: Option<OrText<[u32; 4]>>,
    /// `[i, n]` or `"i/n"`: the i-th of n shares (from 1).
    shard: Option<OrText<[u32; 2]>>,
    sync: Option<bool>,
}

/// `grid`'s options from keys, with the command line's defaults.
pub fn grid_options(keys: serde_json::Map<String, serde_json::Value>) -> Result<crate::gridding::GridOptions> {
    let k: GridKeys = by_key(keys, &[])?;
    let points = k.points.filter(|p| !p.is_empty()).ok_or_else(|| Error::setting("points", "is needed: the point files"))?;
    let output = k.output.ok_or_else(|| Error::setting("output", "is needed: the DEM's path"))?;
    let gsd = k.gsd.ok_or_else(|| Error::setting("gsd", "is needed: the DEM's cell size"))?;
    let mut o = crate::gridding::GridOptions::new(points, output, gsd);
    o.bounds = k.bounds.map(|b| b.read(|t| crate::options::parse_bounds("bounds", t))).transpose()?.flatten();
    o.crs = crs_of("crs", k.crs.as_deref())?;
    o.points_crs = crs_of("points_crs", k.points_crs.as_deref())?;
    if let Some(m) = &k.method {
        o.method = parse_choice("method", m)?;
    }
    o.max_edge = k.max_edge;
    o.radius = k.radius;
    o.power = k.power.unwrap_or(2.0);
    o.neighbours = k.neighbours;
    if let Some(c) = k.columns {
        let parts: Vec<String> = c.read(|t| Ok(t.split(',').map(|s| s.trim().to_string()).collect()))?;
        let n = parts.len();
        let xyz: [String; 3] =
            parts.try_into().map_err(|_| Error::setting("columns", format!("{n} columns: give three, x, y, z (names or numbers from 1)")))?;
        o.columns = crate::points::Columns::Given(xyz);
    }
    o.filter = crate::points::Filter {
        classes: k.class,
        returns: k.returns.as_deref().map(|r| parse_choice("returns", r)).transpose()?.unwrap_or(crate::points::Returns::All),
    };
    o.blunders = blunders(k.blunders.as_ref(), Some(8.0))?;
    o.memory = crate::options::parse_bytes("memory", &k.memory.map_or("512M".into(), |m| m.text()))?;
    o.threads = every_core(k.threads.unwrap_or(0));
    o.tile = k.tile.unwrap_or(256);
    o.block = k.block;
    if let Some(c) = &k.compress {
        o.compress = parse_choice("compress", c)?;
    }
    o.level = k.level;
    if let Some(v) = &k.overviews {
        o.overviews = parse_overviews("overviews", v)?;
    }
    // A DEM's overviews are averages of its cells, coded as the DEM is.
    if let Some(r) = k.overview_resampling.filter(|r| r != "average") {
        return Err(Error::setting("overview_resampling", format!("{r}: a DEM's overviews are averages of its heights")));
    }
    if k.overview_level.is_some() {
        return Err(Error::setting("overview_level", "a DEM's overviews take its own level"));
    }
    if k.quality.is_some() {
        return Err(Error::setting("quality", "a DEM's heights are not coded as JPEG"));
    }
    o.cog = k.cog.unwrap_or(false);
    o.window = k.window.map(|w| w.read(|t| crate::options::parse_window("window", t))).transpose()?;
    o.shard = match k.shard {
        Some(OrText::Value([i, n])) => Some((i, n)),
        Some(OrText::Text(t)) => Some(crate::options::parse_shard("shard", &t)?),
        None => None,
    };
    o.sync = k.sync.unwrap_or(true);
    Ok(o)
}

/// `dem`'s keys (a stereo pair): the command line's options, `_` for `-`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct DemKeys {
    left: Option<PathBuf>,
    right: Option<PathBuf>,
    left_camera: Option<PathBuf>,
    right_camera: Option<PathBuf>,
    left_rpc: Option<PathBuf>,
    right_rpc: Option<PathBuf>,
    left_rpc_offset: Option<OrText<[f64; 2]>>,
    right_rpc_offset: Option<OrText<[f64; 2]>>,
    geoid: Option<PathBuf>,
    output: Option<PathBuf>,
    gsd: Option<crate::geom::Gsd>,
    crs: Option<String>,
    heights: Option<OrText<[f64; 2]>>,
    dem_init: Option<PathBuf>,
    matcher: Option<String>,
    window: Option<usize>,
    min_correlation: Option<f32>,
    points: Option<PathBuf>,
    quality: Option<PathBuf>,
    shard: Option<OrText<[u32; 2]>>,
    blunders: Option<NumberOrWord>,
    memory: Option<NumberOrWord>,
    threads: Option<usize>,
    cog: Option<bool>,
}

/// `dem`'s options from keys, with the command line's defaults.
pub fn dem_options(keys: serde_json::Map<String, serde_json::Value>) -> Result<crate::stereo::StereoOptions> {
    use crate::options::ModelSource;
    use crate::stereo::SideOptions;
    let k: DemKeys = by_key(keys, &[])?;
    let side = |image: &Option<PathBuf>,
                camera: &Option<PathBuf>,
                rpc: &Option<PathBuf>,
                offset: &Option<OrText<[f64; 2]>>,
                [which, offset_key]: [&'static str; 2]|
     -> Result<SideOptions> {
        let image = image.clone().ok_or_else(|| Error::setting(which, format!("is needed: the {which} image")))?;
        match (camera, rpc) {
            (Some(_), None) if k.geoid.is_some() => Err(Error::setting("geoid", "goes with RPC files (‹left_rpc›, ‹right_rpc›), not camera files")),
            (Some(c), None) => Ok(SideOptions { image, model: ModelSource::CameraFile, camera: c.clone() }),
            (None, Some(r)) => {
                let offset = offset.as_ref().map(|o| o.read(|t| crate::options::parse_offset(offset_key, t))).transpose()?;
                Ok(SideOptions { image, model: ModelSource::Rpc { offset, geoid: k.geoid.clone() }, camera: r.clone() })
            }
            _ => Err(Error::Usage(format!("the {which} image needs ‹{which}_camera› or ‹{which}_rpc›"))),
        }
    };
    let left = side(&k.left, &k.left_camera, &k.left_rpc, &k.left_rpc_offset, ["left", "left_rpc_offset"])?;
    let right = side(&k.right, &k.right_camera, &k.right_rpc, &k.right_rpc_offset, ["right", "right_rpc_offset"])?;
    let output = k.output.clone().ok_or_else(|| Error::setting("output", "is needed: the DSM's path"))?;
    let gsd = k.gsd.ok_or_else(|| Error::setting("gsd", "is needed: the DSM's cell size"))?;
    let mut o = crate::stereo::StereoOptions::new(left, right, output, gsd);
    o.crs = crs_of("crs", k.crs.as_deref())?;
    o.heights = k.heights.as_ref().map(|h| h.read(|t| parse_heights("heights", t))).transpose()?;
    o.dem_init = k.dem_init.clone();
    let window = k.window.unwrap_or(9);
    if !(3..=21).contains(&window) || window.is_multiple_of(2) {
        return Err(Error::setting("window", format!("{window} is not an odd side from 3 to 21")));
    }
    if let Some(c) = k.min_correlation {
        if !(-1.0..=1.0).contains(&c) {
            return Err(Error::setting("min_correlation", format!("{c} is not a correlation, -1 to 1")));
        }
    }
    let matcher = match k.matcher.as_deref() {
        None | Some("sgm") => crate::stereo::matching::Matcher::Sgm,
        Some("ncc") => crate::stereo::matching::Matcher::Ncc,
        Some(other) => return Err(Error::setting("matcher", format!("'{other}' (expected sgm or ncc)"))),
    };
    o.matching = crate::stereo::matching::MatchParams { matcher, window, min_correlation: k.min_correlation };
    o.points = k.points.clone();
    o.quality = k.quality.clone();
    o.shard = match &k.shard {
        Some(OrText::Value([i, n])) => Some((*i, *n)),
        Some(OrText::Text(t)) => Some(crate::options::parse_shard("shard", t)?),
        None => None,
    };
    o.blunders = blunders(k.blunders.as_ref(), None)?;
    o.memory = crate::options::parse_bytes("memory", &k.memory.as_ref().map_or("512M".into(), |m| m.text()))?;
    o.threads = every_core(k.threads.unwrap_or(0));
    o.cog = k.cog.unwrap_or(false);
    Ok(o)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn keys(v: serde_json::Value) -> serde_json::Map<String, serde_json::Value> {
        v.as_object().expect("an object").clone()
    }

    /// `o` serialized, read back and serialized again: the same text.
    fn round_trip<T: serde::Serialize + serde::de::DeserializeOwned>(o: &T) -> String {
        let text = serde_json::to_string(o).expect("serialized");
        let back: T = serde_json::from_str(&text).expect("read back");
        assert_eq!(serde_json::to_string(&back).expect("serialized"), text);
        text
    }

    #[test]
    fn each_commands_options_read_back_from_their_serialized_form() {
        let m = mosaic_options(keys(json!({"manifest": "m.toml", "output": "o.tif", "crs": "EPSG:32631", "balance": "gain", "window": "0,0,2,2"})))
            .expect("valid");
        assert!(round_trip(&m).contains("\"crs\":\"EPSG:32631\""));
        let g = grid_options(keys(json!({"points": ["p.las"], "output": "d.tif", "gsd": [2, 1], "class": [2, 6], "columns": "e,n,h", "method": "idw"})))
            .expect("valid");
        round_trip(&g);
        let s = dem_options(keys(json!({"left": "l.tif", "right": "r.tif", "left_rpc": "l.txt", "right_rpc": "r.txt", "output": "d.tif", "gsd": 2})))
            .expect("valid");
        round_trip(&s);
        let a = assemble_options(keys(json!({"overviews": "2,4", "compress": "zstd", "cog": true}))).expect("valid");
        round_trip(&a);
        round_trip(&crate::synth::SynthOptions::default());
    }

    #[test]
    fn mosaic_grid_and_dem_keys_take_the_commands_defaults() {
        let m = mosaic_options(keys(json!({"manifest": "m.toml", "output": "o.tif"}))).expect("valid");
        assert_eq!((m.blend, m.memory, m.least_cost, m.cog), (8.0, 256 << 20, true, None));
        assert!(mosaic_options(keys(json!({"manifest": "m.toml"}))).is_err());
        let g = grid_options(keys(json!({"points": ["p.las"], "output": "d.tif", "gsd": 2, "shard": [2, 4]}))).expect("valid");
        assert_eq!((g.blunders, g.memory, g.shard, g.tile), (Some(8.0), 512 << 20, Some((2, 4)), 256));
        let s = dem_options(keys(json!({"left": "l.tif", "right": "r.tif", "left_rpc": "l.txt", "right_rpc": "r.txt", "output": "d.tif", "gsd": 2})))
            .expect("valid");
        assert_eq!((s.blunders, s.matching.window), (None, 9));
        let e =
            dem_options(keys(json!({"left": "l.tif", "right": "r.tif", "left_camera": "l.toml", "output": "d.tif", "gsd": 2}))).expect_err("no right camera");
        assert_eq!(e.to_string(), "the right image needs right_camera or right_rpc");
    }

    /// The command line's text for a setting (`"1,2"`) is read as its
    /// value (`[1, 2]`) is, by the same parser: the CLI passes its
    /// arguments through these keys.
    #[test]
    fn text_and_value_forms_are_one_setting() {
        let grid = |extra: serde_json::Value| {
            let mut k = keys(json!({"points": ["p.las"], "output": "d.tif", "gsd": 2}));
            k.extend(keys(extra));
            grid_options(k)
        };
        let by_text = grid(json!({"bounds": "0,0,100,50", "window": "1,2,3,4", "columns": "e,n,h"})).expect("valid");
        let by_value = grid(json!({"bounds": [0, 0, 100, 50], "window": [1, 2, 3, 4], "columns": ["e", "n", "h"]})).expect("valid");
        assert_eq!((by_text.bounds, by_text.window), (Some([0.0, 0.0, 100.0, 50.0]), Some([1, 2, 3, 4])));
        assert_eq!((by_value.bounds, by_value.window), (by_text.bounds, by_text.window));
        assert_eq!(grid(json!({"shard": "2/4"})).expect("valid").shard, Some((2, 4)));
        // Checked alike: min above max, either way.
        for bad in [json!({"bounds": "100,0,0,50"}), json!({"bounds": [100, 0, 0, 50]})] {
            assert!(grid(bad).expect_err("min > max").to_string().starts_with("bounds: "));
        }
        assert!(grid(json!({"quality": 80})).expect_err("no jpeg DEM").to_string().starts_with("quality: "));
        let pair = |extra: serde_json::Value| {
            let mut k = keys(json!({"left": "l.tif", "right": "r.tif", "left_rpc": "l.txt", "right_rpc": "r.txt", "output": "d.tif", "gsd": 2}));
            k.extend(keys(extra));
            dem_options(k)
        };
        let s = pair(json!({"heights": "-10,250", "left_rpc_offset": "5,7"})).expect("valid");
        assert_eq!(s.heights, Some([-10.0, 250.0]));
        assert!(matches!(s.left.model, crate::options::ModelSource::Rpc { offset: Some([5.0, 7.0]), .. }));
        assert_eq!(pair(json!({"heights": [-10, 250]})).expect("valid").heights, s.heights);
        assert!(pair(json!({"heights": "x"})).expect_err("not two heights").to_string().starts_with("heights: "));
        // A value of the wrong shape says what is wrong with it.
        let e = grid(json!({"bounds": [0, 0, 100]})).expect_err("three numbers").to_string();
        assert!(e.starts_with("bounds: invalid length 3, expected an array of length 4"), "{e}");
    }
}
