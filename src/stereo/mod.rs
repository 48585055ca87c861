//! `dem`: a DSM from a stereo pair, as Nekrasov's thesis builds one from
//! satellite pairs (ch. 2–3). The pair brought to epipolar geometry on the
//! ground (epipolar.rs, resample.rs), matched densely a tile at a time
//! (matching/), each match intersected with the cameras' exact models
//! (triangulate.rs), the points written as a LAS file and gridded by
//! `grid`'s TIN with its blunder removal into the DSM and, from the
//! matches' residual parallaxes, a quality raster.
//!
//! Tiles are fixed squares of the epipolar grid with fixed margins, so
//! the DSM does not depend on `--memory` or the number of threads: the
//! memory only says how many tiles are matched at once.

pub mod epipolar;
pub mod matching;
pub mod pointing;
mod points_out;
pub mod resample;
pub mod triangulate;

use crate::camera::file::Camera;
use crate::error::{Error, Result};
use crate::geodesy::Crs;
use crate::geom::Gsd;
use crate::gridding::{GridOptions, GridReport};
use crate::io::source::SourceImage;
use crate::options::ModelSource;
use crate::progress::{Cancel, Progress, Task};
use epipolar::{EpipolarFrame, View};
use matching::MatchParams;
use rayon::prelude::*;
use resample::{resample, Side};
use std::path::PathBuf;

/// A tile's side in epipolar pixels, and the context matched around it
/// (a multiple of the pyramid's largest factor, 2⁶).
const TILE: i64 = 512;
const MARGIN: i64 = 64;

/// One image of the pair and how its model is given (as `rectify` takes
/// them).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub struct SideOptions {
    pub image: PathBuf,
    pub model: ModelSource,
    /// The camera file, or the RPC file (the image itself where it holds
    /// its RPC).
    pub camera: PathBuf,
}

/// What `dem` is asked to do (serde: the same object read back).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub struct StereoOptions {
    pub left: SideOptions,
    pub right: SideOptions,
    pub output: PathBuf,
    /// The DSM's cell size.
    pub gsd: Gsd,
    /// The DSM's CRS (default: the cameras', or an RPC's UTM zone).
    #[serde(with = "crate::geodesy::optional_crs_definition")]
    pub crs: Option<Crs>,
    /// Heights searched, `[lowest, highest]` (default: `dem_init`'s, else
    /// the RPCs' range).
    pub heights: Option<[f64; 2]>,
    /// A DEM whose heights narrow the search.
    pub dem_init: Option<PathBuf>,
    pub matching: MatchParams,
    /// Keep the matched points here (LAS; else they are gridded and let go).
    pub points: Option<PathBuf>,
    /// The residual parallax of the matches, gridded as the DSM (pixels).
    pub quality: Option<PathBuf>,
    pub blunders: Option<f64>,
    /// Match only rows of epipolar tiles `(I, N)`: the I-th of N shares;
    /// `output` is then the piece's matched points (LAS), no DSM is made.
    pub shard: Option<(u32, u32)>,
    pub memory: u64,
    pub threads: usize,
    pub cog: bool,
}

impl StereoOptions {
    pub fn new(left: SideOptions, right: SideOptions, output: PathBuf, gsd: Gsd) -> StereoOptions {
        StereoOptions {
            left,
            right,
            output,
            gsd,
            crs: None,
            heights: None,
            dem_init: None,
            matching: MatchParams::default(),
            points: None,
            quality: None,
            // Matching drops its gross errors itself (the left-right
            // check, the correlation, the neighbourhood's median): the
            // grid's own search costs six times the gridding.
            blunders: None,
            shard: None,
            memory: 512 << 20,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
            cog: false,
        }
    }
}

/// Quantiles of a measure over the matches.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Spread {
    pub median: f64,
    pub p95: f64,
}

/// What `dem` did and measured.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StereoReport {
    pub output: PathBuf,
    pub crs: String,
    pub heights_searched: [f64; 2],
    pub epipolar: EpipolarFrame,
    pub pointing: pointing::Pointing,
    pub matcher: matching::Matcher,
    pub tiles: usize,
    /// Left pixels of the overlap that both images show.
    pub pixels_seen: u64,
    pub pixels_matched: u64,
    pub matched_share: f64,
    /// Matches whose intersection failed (a model undefined there).
    pub not_intersected: u64,
    /// Points written for the DSM (a cell's matches averaged where cells
    /// are larger than the matching's pixels).
    pub points_written: u64,
    /// The largest distance between a ground point interpolated from the
    /// lattice of exact intersections and the exact one, of a sample of
    /// one match in 61, metres.
    pub intersection_check_m: f64,
    pub residual_parallax_px: Spread,
    pub correlation: Spread,
    /// Theoretical height precision, metres: 0.3 px of disparity at the
    /// pair's base-to-height ratio (GSD × H/B × 0.3).
    pub height_precision_m: f64,
    pub heights: &'static str,
    pub points: Option<PathBuf>,
    pub quality: Option<PathBuf>,
    /// The DSM gridded (none for a shard: its output is its points).
    pub dsm: Option<GridReport>,
    /// For a shard: how the pieces' points make the DSM the whole run
    /// makes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub then: Option<String>,
    pub seconds: f64,
    pub warnings: Vec<String>,
}

/// Makes the DSM. See the module doc.
pub fn dem(o: &StereoOptions, progress: &dyn Progress, cancel: &Cancel) -> Result<StereoReport> {
    let started = std::time::Instant::now();
    // (A shard's output is its points, a LAS file.)
    let mut warnings: Vec<String> = if o.shard.is_some() { vec![] } else { crate::io::tiff_out::named_as_other_format(&o.output).into_iter().collect() };
    warnings.iter().for_each(|w| progress.warn(w));
    check_files(o)?;
    check_shard(o)?;
    check_settings(o)?;
    let (left_cam, right_cam, crs) = cameras(o)?;
    for w in left_cam.warnings.iter().chain(&right_cam.warnings) {
        progress.warn(w);
        warnings.push(w.clone());
    }
    let cache = (o.memory / 8).clamp(4 << 20, 256 << 20) as usize;
    let left_scan = SourceImage::open_within(&o.left.image, cache, o.memory / 4)?;
    let right_scan = SourceImage::open_within(&o.right.image, cache, o.memory / 4)?;
    let (lm, rm) = (left_cam.model(), right_cam.model());
    let [zlo, zhi] = search_heights(o, &left_cam, &right_cam, &crs)?;
    let lv = View { model: lm, width: left_scan.info.width, height: left_scan.info.height };
    let rv = View { model: rm, width: right_scan.info.width, height: right_scan.info.height };
    let mut frame = EpipolarFrame::new(&lv, &rv, zlo, zhi, 0.0).map_err(|e| match e {
        Error::Geometry(m) => Error::Named(format!("{} and {}: {m}", o.left.image.display(), o.right.image.display())),
        e => e,
    })?;
    if frame.base_to_height < 0.05 {
        return Err(Error::Named(format!(
            "{} and {}: their base-to-height ratio is {:.3}, below 0.05: heights from this pair would be no better than {:.0} m",
            o.left.image.display(),
            o.right.image.display(),
            frame.base_to_height,
            0.3 * frame.pixel / frame.base_to_height
        )));
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(o.threads.max(1)).build().map_err(|e| Error::Internal(format!("a thread pool: {e}")))?;
    // Matches come a pixel or more apart: cells a thousand times finer
    // (the rule `grid` applies to points) are refused before matching.
    if o.gsd.x.max(o.gsd.y) < frame.pixel / 1000.0 {
        return Err(Error::setting("gsd", format!("{} is finer than a 1000th of the images' ground pixel ({:.4}): a cell size no match resolves", o.gsd.x.max(o.gsd.y), frame.pixel)));
    }
    // A DSM of the overlap at `--gsd` that no file could hold is refused
    // before any matching.
    let side = frame.pixel * f64::from(frame.width.max(frame.height)) * std::f64::consts::SQRT_2;
    if side / o.gsd.x * side / o.gsd.y > 1e11 {
        return Err(Error::setting(
            "gsd",
            format!("{} × {} over the pair's overlap of about {side:.0} ground units a side is past 10^11 cells", o.gsd.x, o.gsd.y),
        ));
    }
    // Nor one whose tiles' table and bins (a bin a tile at the least) the
    // gridding could not hold in its quarter of the memory.
    let tile = f64::from(GridOptions::new(Vec::new(), std::path::PathBuf::new(), o.gsd).tile);
    let held = (side / o.gsd.x / tile).ceil() * (side / o.gsd.y / tile).ceil() * (16 + crate::gridding::bins::Bins::BYTES_A_BIN) as f64;
    if held > (o.memory / 4) as f64 {
        return Err(Error::setting(
            "gsd",
            format!("{} × {} over the pair's overlap of about {side:.0} ground units a side needs {:.0} MiB for its bins and tiles alone, more than a quarter of the memory given: a coarser ‹gsd› or more ‹memory›", o.gsd.x, o.gsd.y, held / 1048576.0),
        ));
    }
    // The pair's relative pointing, and the disparities its points span.
    let (ls, rs) = (Side { scan: &left_scan, model: lm }, Side { scan: &right_scan, model: rm });
    let pointing = pool.install(|| pointing::estimate(&frame, &ls, &rs))?;
    // Over two frames' guessed heights (kilometres) the figure says
    // nothing of the ground: only a search the user or the RPCs bounded.
    let guessed = o.heights.is_none()
        && o.dem_init.is_none()
        && !matches!(left_cam.sensor, crate::camera::file::Sensor::Rpc(_) | crate::camera::file::Sensor::Panoramic(_));
    if frame.vertical_parallax_px > 1.0 && !guessed {
        let w = format!(
            "the pair's epipolar rows leave {:.2} px of parallax across them somewhere in the heights searched: matches there may be missed",
            frame.vertical_parallax_px
        );
        progress.warn(&w);
        warnings.push(w);
    }
    if pointing.matched < 5 {
        let w = format!(
            "only {} of {} points spread over the overlap matched well: the pair's relative pointing is not corrected, and matching may fail where the images' rows are apart",
            pointing.matched, pointing.tried
        );
        progress.warn(&w);
        warnings.push(w);
    }
    frame.right_row_shift = pointing.row_shift;
    if let Some(d) = pointing.disparity {
        frame.disparity = d;
    }

    // Tiles of the epipolar grid, row by row.
    let (tw, th) = ((frame.width as i64).div_euclid(TILE) + 1, (frame.height as i64).div_euclid(TILE) + 1);
    // A shard's rows of tiles: the same tiles, in the same order, as the
    // whole run matches them, so that the pieces' points gridded together
    // are the whole run's.
    let rows = match o.shard {
        Some((i, n)) => (th * i64::from(i - 1) / i64::from(n))..(th * i64::from(i) / i64::from(n)),
        None => 0..th,
    };
    let tiles: Vec<(i64, i64)> = rows.flat_map(|j| (0..tw).map(move |i| (i * TILE, j * TILE))).collect();
    let (dlo, dhi) = (frame.disparity[0], frame.disparity[1]);
    let per_tile = tile_bytes(dhi - dlo);
    let at_once = ((o.memory / 2) / per_tile).clamp(1, 4 * o.threads.max(1) as u64) as usize;

    let pending = crate::io::publish::pending_dir(&o.output)?;
    // Points kept (a shard's output, or `points`) are written under a
    // temporary name beside where they go, and renamed there at the end.
    let kept = if o.shard.is_some() { Some(&o.output) } else { o.points.as_ref() };
    let kept_points = kept.map(|p| crate::io::publish::PendingFile::create(p)).transpose()?;
    let points_path = kept_points.as_ref().map_or_else(|| pending.path().join("points.las"), |p| p.path().to_path_buf());
    // A shard's quality is its matches' residual parallaxes, a point file
    // the pieces' quality raster is gridded from, like its DSM.
    let kept_quality = o.quality.as_ref().filter(|_| o.shard.is_some()).map(|q| crate::io::publish::PendingFile::create(q)).transpose()?;
    let quality_path = kept_quality.as_ref().map_or_else(|| pending.path().join("quality.las"), |q| q.path().to_path_buf());
    let mut pw = points_out::PointWriter::create(&points_path, frame.origin, frame.pixel)?;
    let mut qw = points_out::PointWriter::create(&quality_path, frame.origin, frame.pixel)?;
    progress.start(&Task { name: "matching", units: tiles.len() as u64, lines: 0, line_name: "", input_bytes: 0 });
    let (mut seen, mut matched, mut failed, mut check_m) = (0u64, 0u64, 0u64, 0.0f64);
    // Matches averaged a DSM cell at a time where a cell holds several.
    let cell = (o.gsd.x.min(o.gsd.y) >= 1.5 * frame.pixel).then_some((o.gsd.x, o.gsd.y));
    let (mut residuals, mut correlations) = (Vec::new(), Vec::new());
    for batch in tiles.chunks(at_once) {
        if cancel.is_cancelled() {
            progress.finish();
            return Err(Error::Cancelled);
        }
        let done: Vec<Result<TileOut>> =
            pool.install(|| batch.par_iter().map(|&(i0, j0)| match_one(&frame, (&left_scan, lm), (&right_scan, rm), i0, j0, &o.matching, cell)).collect());
        for t in done {
            let t = match t {
                Err(e) => {
                    progress.finish();
                    return Err(e);
                }
                Ok(t) => t,
            };
            seen += t.seen;
            matched += t.matches;
            failed += t.failed;
            check_m = check_m.max(t.check_m);
            for p in &t.points {
                pw.write(p.x, p.y, p.z)?;
                qw.write(p.x, p.y, p.residual_px as f64)?;
                // A sample of the spreads, enough for quantiles.
                if (pw.count() % 7) == 0 {
                    residuals.push(p.residual_px);
                }
            }
            correlations.extend(t.correlation.iter().step_by(7));
            progress.advance(1);
        }
    }
    progress.finish();
    let points_written = pw.count();
    pw.close()?;
    qw.close()?;
    if matched == 0 && o.shard.is_none() {
        return Err(Error::Named(format!(
            "{} and {}: no point matched (no texture in the overlap, or the images do not show the same ground at the heights {zlo:.0} to {zhi:.0})",
            o.left.image.display(),
            o.right.image.display()
        )));
    }

    // The DSM's file says the height system of a geoid the run was given.
    let dsm_crs = with_heights_system(o, crs.clone());
    let crs_text = dsm_crs.definition();
    // A shard: its points are its output.
    let then = o.shard.map(|(_, n)| {
        let dsm = format!(
            "gcm-ortho grid PIECE_1 … PIECE_{n} (in shard order) --points-crs '{crs_text}' --crs '{crs_text}' --gsd {},{} --blunders {} -o DSM",
            o.gsd.x,
            o.gsd.y,
            o.blunders.map_or("none".to_string(), |b| b.to_string())
        );
        // The quality raster on the DSM's grid: the same points' places.
        match o.quality {
            Some(_) => {
                let crs = crs.definition();
                format!(
                    "{dsm}; gcm-ortho grid QUALITY_1 … QUALITY_{n} (in shard order) --points-crs '{crs}' --crs '{crs}' --gsd {},{} --method mean --blunders none -o QUALITY",
                    o.gsd.x, o.gsd.y
                )
            }
            None => dsm,
        }
    });
    let dsm = match o.shard {
        Some(_) => None,
        None => Some(grid_dsm(o, &dsm_crs, &points_path, progress, cancel)?),
    };
    if let (Some(q), Some(dsm)) = (&o.quality, &dsm) {
        let mut g = GridOptions::new(vec![quality_path.clone()], q.clone(), o.gsd);
        g.crs = Some(crs.clone());
        g.points_crs = Some(crs.clone());
        g.method = crate::gridding::Method::Mean;
        g.bounds = Some(dsm.bounds);
        g.blunders = None;
        g.memory = o.memory;
        g.threads = o.threads;
        crate::gridding::grid(&g, progress, cancel)?;
    }
    if let Some(p) = kept_points {
        p.publish()?;
    }
    if let Some(q) = kept_quality {
        q.publish()?;
    }
    let q = |v: &mut Vec<f32>, f: f64| -> f64 {
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_by(f32::total_cmp);
        v[((v.len() - 1) as f64 * f) as usize] as f64
    };
    Ok(StereoReport {
        output: o.output.clone(),
        crs: crs_text,
        heights_searched: [zlo, zhi],
        matcher: o.matching.matcher,
        tiles: tiles.len(),
        pixels_seen: seen,
        pixels_matched: matched,
        matched_share: matched as f64 / seen.max(1) as f64,
        not_intersected: failed,
        points_written,
        intersection_check_m: check_m,
        residual_parallax_px: Spread { median: q(&mut residuals, 0.5), p95: q(&mut residuals, 0.95) },
        correlation: Spread { median: q(&mut correlations, 0.5), p95: q(&mut correlations, 0.05) },
        height_precision_m: 0.3 / frame.px_per_m,
        heights: heights_kind(o),
        points: o.points.clone(),
        quality: o.quality.clone(),
        epipolar: frame,
        pointing,
        dsm,
        then,
        seconds: started.elapsed().as_secs_f64(),
        warnings,
    })
}

/// The DSM: the matches at `points` gridded by `grid`'s TIN.
fn grid_dsm(o: &StereoOptions, crs: &Crs, points: &std::path::Path, progress: &dyn Progress, cancel: &Cancel) -> Result<GridReport> {
    let mut g = GridOptions::new(vec![points.to_path_buf()], o.output.clone(), o.gsd);
    g.crs = Some(crs.clone());
    g.points_crs = Some(crs.clone());
    g.blunders = o.blunders;
    g.memory = o.memory;
    g.threads = o.threads;
    g.cog = o.cog;
    crate::gridding::grid(&g, progress, cancel)
}

/// The DSM's CRS with the height system of its heights, so that GDAL and
/// the DSM's next user read what they are: the geoid's given (a grid PROJ
/// names, by its file's name), else an RPC's own, above the WGS 84
/// ellipsoid (said as GeoTIFF 1.1 and GDAL say it, a geographic 3D CRS as
/// the vertical key); as it is where the CRS says its heights already, or
/// the grid is not one PROJ names, or the cameras' datum is unknown.
fn with_heights_system(o: &StereoOptions, crs: Crs) -> Crs {
    if crs.vertical().is_some() {
        return crs;
    }
    let vertical = match &o.left.model {
        ModelSource::Rpc { geoid: Some(g), .. } => crate::geodesy::Vertical::of_grid_file(g),
        ModelSource::Rpc { geoid: None, .. } => crate::geodesy::Vertical::from_epsg(4979).ok(),
        _ => None,
    };
    match vertical {
        Some(v) => crs.with_vertical(Some(v)),
        None => crs,
    }
}

/// Where the heights are measured from.
fn heights_kind(o: &StereoOptions) -> &'static str {
    let geoid = |s: &SideOptions| matches!(&s.model, ModelSource::Rpc { geoid: Some(_), .. });
    match (&o.left.model, geoid(&o.left)) {
        (ModelSource::Rpc { .. }, true) => "above the geoid given",
        (ModelSource::Rpc { .. }, false) => "ellipsoidal (WGS84)",
        _ => "in the cameras' height datum",
    }
}

/// The matches of one tile.
struct TileOut {
    /// Each DSM cell's mean of the matches (or each match where cells are
    /// not much larger than the matching's pixels).
    points: Vec<triangulate::GroundPoint>,
    correlation: Vec<f32>,
    seen: u64,
    matches: u64,
    failed: u64,
    /// The largest difference between an interpolated ground point and the
    /// exact intersection, of those checked.
    check_m: f64,
}

/// Left pixels of the tile's core the right image shows at the expected
/// disparity (a tile without matches).
fn count_seen(li: &resample::Img, ri: &resample::Img, expected: &[i32], lx0: i64, ly0: i64, side: usize, core: &dyn Fn(usize, usize) -> bool) -> u64 {
    (0..side * side)
        .filter(|&k| core(k % side, k / side) && !li.v[k].is_nan() && !ri.at((k % side) as i64 + lx0 - expected[k] as i64, (k / side) as i64 + ly0).is_nan())
        .count() as u64
}

/// Memory a tile takes while it is matched, for a search of `range`
/// disparities: its two images and their pyramids, the finest level's
/// costs and sums (9 disparities, 5 bytes each), the census words.
fn tile_bytes(range: f64) -> u64 {
    let side = (TILE + 2 * MARGIN) as u64;
    let left = side * side;
    let right = side * (side + range as u64 + 16);
    (left + right) * 4 * 2 + left * 9 * 5 + (left + right) * 16 + left * 16
}

/// Matches the tile at `(i0, j0)`; `cell`: the DSM's cell where its
/// matches are averaged a cell at a time.
#[allow(clippy::too_many_arguments)]
fn match_one(
    frame: &EpipolarFrame,
    left: (&SourceImage, &dyn crate::camera::SensorModel),
    right: (&SourceImage, &dyn crate::camera::SensorModel),
    i0: i64,
    j0: i64,
    p: &MatchParams,
    cell: Option<(f64, f64)>,
) -> Result<TileOut> {
    let (lx0, ly0) = (i0 - MARGIN, j0 - MARGIN);
    let side = (TILE + 2 * MARGIN) as usize;
    let ls = Side { scan: left.0, model: left.1 };
    let li = resample(frame, &ls, lx0, ly0, side, side, 0.0)?;
    let mut out = TileOut { points: Vec::new(), correlation: Vec::new(), seen: 0, matches: 0, failed: 0, check_m: 0.0 };
    let core = |x: usize, y: usize| {
        let (gx, gy) = (x as i64 + lx0, y as i64 + ly0);
        gx >= i0 && gy >= j0 && gx < i0 + TILE && gy < j0 + TILE && gx < frame.width as i64 && gy < frame.height as i64
    };
    if !li.v.iter().any(|v| !v.is_nan()) {
        return Ok(out);
    }
    let (dlo, dhi) = (frame.disparity[0], frame.disparity[1]);
    let align = |v: i64, up: bool| if up { (v + MARGIN - 1).div_euclid(MARGIN) * MARGIN } else { v.div_euclid(MARGIN) * MARGIN };
    let rx0 = align(lx0 - dhi.ceil() as i64 - 8, false);
    let rx1 = align(lx0 + side as i64 - dlo.floor() as i64 + 8, true);
    let rs = Side { scan: right.0, model: right.1 };
    let ri = resample(frame, &rs, rx0, ly0, (rx1 - rx0) as usize, side, frame.right_row_shift)?;
    let m = matching::match_tile(&li, &ri, dlo, dhi, p, [MARGIN as usize, MARGIN as usize, (MARGIN + TILE) as usize, (MARGIN + TILE) as usize]);
    let (disp, corr) = (&m.disparity, &m.correlation);
    // The ground points: from the lattice of exact intersections, a
    // sample of them checked against the exact one.
    let (mut mn, mut mx) = (f32::INFINITY, f32::NEG_INFINITY);
    for (k, &d) in disp.iter().enumerate() {
        if !d.is_nan() && core(k % side, k / side) {
            (mn, mx) = (mn.min(d), mx.max(d));
        }
    }
    if !mn.is_finite() {
        out.seen = count_seen(&li, &ri, &m.expected, lx0, ly0, side, &core);
        return Ok(out);
    }
    let w = (frame.width as i64 - i0).min(TILE) as f64;
    let h = (frame.height as i64 - j0).min(TILE) as f64;
    let lattice = triangulate::Lattice::new(frame, left.1, right.1, (i0 as f64 + 0.5, j0 as f64 + 0.5), (w, h), (mn as f64, mx as f64));
    let mut cells: std::collections::BTreeMap<(i64, i64), [f64; 5]> = Default::default();
    let mut n = 0u64;
    for y in 0..side {
        for x in 0..side {
            if !core(x, y) {
                continue;
            }
            let k = y * side + x;
            if li.v[k].is_nan() {
                continue;
            }
            // Seen by both: the right image is there at the disparity
            // the coarser levels expected.
            let (gx, gy) = (x as i64 + lx0, y as i64 + ly0);
            if ri.at(gx - m.expected[k] as i64, gy).is_nan() {
                continue;
            }
            out.seen += 1;
            let d = disp[k];
            if d.is_nan() {
                continue;
            }
            let (i, j) = (gx as f64 + 0.5, gy as f64 + 0.5);
            let Some(pt) = lattice.at(i, j, d as f64) else {
                out.failed += 1;
                continue;
            };
            n += 1;
            if n.is_multiple_of(61) {
                if let Some(e) = triangulate::intersect(frame, left.1, right.1, i, j, d as f64) {
                    out.check_m = out.check_m.max((e.x - pt.x).hypot(e.y - pt.y).max((e.z - pt.z).abs()));
                }
            }
            out.correlation.push(corr[k]);
            match cell {
                Some((cw, ch)) => {
                    let c = cells.entry(((pt.x / cw).floor() as i64, (pt.y / ch).floor() as i64)).or_default();
                    for (s, v) in c.iter_mut().zip([pt.x, pt.y, pt.z, f64::from(pt.residual_px), 1.0]) {
                        *s += v;
                    }
                }
                None => out.points.push(pt),
            }
        }
    }
    out.matches = n + out.failed;
    // A DSM cell's matches as one point: their mean (the noise of a
    // match's height falls as the root of their number).
    for (_, [x, y, z, r, k]) in cells {
        out.points.push(triangulate::GroundPoint { x: x / k, y: y / k, z: z / k, residual_px: (r / k) as f32 });
    }
    Ok(out)
}

/// Settings refused before anything is read: those the gridding would
/// refuse only after the matching, and an output CRS in degrees (the
/// pair's base, heights and cells are measured in its units).
fn check_settings(o: &StereoOptions) -> Result<()> {
    crate::gridding::check_blunders(o.blunders)?;
    if let Some(c) = o.crs.as_ref().filter(|c| c.is_geographic()) {
        return Err(Error::setting(
            "crs",
            format!("{} is in degrees: a DSM is made in a projected CRS (metres), as UTM; warp it after (gdalwarp -t_srs) for one in degrees", crs_name(c)),
        ));
    }
    Ok(())
}

/// The files named exist, are not one image twice, and no output is an
/// input.
fn check_files(o: &StereoOptions) -> Result<()> {
    use crate::io::overwrite::{check_outputs, Role};
    for (what, p) in [("left image", &o.left.image), ("right image", &o.right.image), ("left camera", &o.left.camera), ("right camera", &o.right.camera)] {
        if !p.exists() {
            return Err(Error::Named(format!("{}: the {what} does not exist", p.display())));
        }
    }
    if let Some(d) = &o.dem_init {
        if !d.exists() {
            return Err(Error::Named(format!("{}: the initial DEM does not exist", d.display())));
        }
    }
    let same = match (std::fs::canonicalize(&o.left.image), std::fs::canonicalize(&o.right.image)) {
        (Ok(a), Ok(b)) => a == b || crate::identity::content_key_of(&[], &[&a]) == crate::identity::content_key_of(&[], &[&b]),
        _ => false,
    };
    if same {
        return Err(Error::Named(format!(
            "{} and {}: the left and right images are the same image: a stereo pair is two views",
            o.left.image.display(),
            o.right.image.display()
        )));
    }
    let mut inputs = vec![
        Role::new("left image", &o.left.image),
        Role::new("right image", &o.right.image),
        Role::new("left camera", &o.left.camera),
        Role::new("right camera", &o.right.camera),
    ];
    if let Some(d) = &o.dem_init {
        inputs.push(Role::new("initial DEM", d));
    }
    let mut outputs = vec![Role::new("output", &o.output)];
    if let Some(q) = &o.quality {
        outputs.push(Role::new(if o.shard.is_some() { "quality points" } else { "quality raster" }, q));
    }
    if let Some(p) = &o.points {
        outputs.push(Role::new("points file", p));
    }
    check_outputs(&inputs, &outputs)
}

/// A shard names one of its N shares, and asks nothing of the DSM it
/// does not make (its quality is its matches' residuals, a point file).
fn check_shard(o: &StereoOptions) -> Result<()> {
    let Some((i, n)) = o.shard else { return Ok(()) };
    if !(1..=n).contains(&i) {
        return Err(Error::setting("shard", format!("{i}/{n}: give I/N with 1 ≤ I ≤ N")));
    }
    let with = [("points", o.points.is_some()), ("cog", o.cog)];
    match with.iter().find(|w| w.1) {
        Some((name, _)) => Err(Error::setting(name, "goes with the DSM, which a shard does not make (its output is its matched points)")),
        None => Ok(()),
    }
}

/// Both cameras, in one ground CRS: `--crs`, else the left's (the right's
/// must agree).
fn cameras(o: &StereoOptions) -> Result<(Camera, Camera, Crs)> {
    let load = |s: &SideOptions| crate::scene::camera::load(&s.model, &s.image, &s.camera, o.crs.as_ref());
    let (l, r) = (load(&o.left)?, load(&o.right)?);
    let crs = match &o.crs {
        Some(c) => c.clone(),
        None => {
            let (lc, rc) = (l.crs.clone(), r.crs.clone());
            // (An RPC's or a panoramic camera's CRS is only where its
            // orthophoto goes: the right's is brought into the left's.)
            use crate::camera::file::Sensor::{Panoramic, Rpc};
            let frames = !matches!(l.sensor, Rpc(_) | Panoramic(_)) && !matches!(r.sensor, Rpc(_) | Panoramic(_));
            if frames && lc != rc {
                return Err(Error::Named(format!(
                    "{} and {}: the cameras' positions are in different CRSs ({} and {}): give ‹crs› for the DSM and both are brought into it",
                    o.left.camera.display(),
                    o.right.camera.display(),
                    crs_name(&lc),
                    crs_name(&rc)
                )));
            }
            lc
        }
    };
    let into = |c: Camera, s: &SideOptions| c.in_crs(&crs).map_err(|m| Error::config(&s.camera, "crs", m));
    Ok((into(l, &o.left)?, into(r, &o.right)?, crs))
}

fn crs_name(c: &Crs) -> String {
    c.epsg().map_or_else(|| c.proj4().to_string(), |e| format!("EPSG:{e}"))
}

/// The heights searched: given, or the initial DEM's (widened by 50 m for
/// what stands on the ground), or the RPCs' common range, or for two
/// frames the heights a base-to-height ratio of 0.1 to 1 allows.
fn search_heights(o: &StereoOptions, l: &Camera, r: &Camera, crs: &Crs) -> Result<[f64; 2]> {
    if let Some([a, b]) = o.heights {
        if !(a.is_finite() && b.is_finite() && b > a) {
            return Err(Error::setting("heights", format!("{a},{b} is not a lowest and a higher highest height")));
        }
        return Ok([a, b]);
    }
    if let Some(d) = &o.dem_init {
        let dem = crate::dem::Dem::open(d, crs)?;
        let (a, b) = dem.height_range().ok_or_else(|| Error::Named(format!("{}: the initial DEM has no heights", d.display())))?;
        return Ok([a - 50.0, b + 50.0]);
    }
    use crate::camera::file::Sensor;
    match (&l.sensor, &r.sensor) {
        (Sensor::Rpc(a), Sensor::Rpc(b)) => {
            let range = |c: &crate::camera::RpcCamera| (c.rpc.height_off - c.rpc.height_scale, c.rpc.height_off + c.rpc.height_scale);
            let ((a0, a1), (b0, b1)) = (range(a), range(b));
            let (lo, hi) = (a0.max(b0), a1.min(b1));
            if hi > lo {
                // Heights above a geoid differ from the RPC's by its undulation.
                return Ok([lo - 100.0, hi + 100.0]);
            }
            Ok([a0.min(b0), a1.max(b1)])
        }
        (Sensor::Panoramic(a), Sensor::Panoramic(b)) => {
            // The files' mean surface, 2 km below and 3 km above: the pair's
            // sparse matches then narrow the search to the overlap's heights.
            let (ha, hb) = (a.height_hint(), b.height_hint());
            Ok([ha.min(hb) - 2000.0, ha.max(hb) + 3000.0])
        }
        (a, b) => {
            // Two frames: the ground lies somewhere below them at the
            // distance a base-to-height ratio of 0.1 to 1 puts it; the
            // pair's sparse matches then narrow the search to the heights
            // the overlap holds.
            let centre = |s: &Sensor| match s {
                Sensor::Frame(f) => Some(f.centre),
                Sensor::ReprojectedFrame(r) => Some(r.inner.centre),
                Sensor::Rpc(_) | Sensor::Panoramic(_) => None,
            };
            let (Some(ca), Some(cb)) = (centre(a), centre(b)) else {
                return Err(Error::setting("heights", "two cameras of different kinds: give ‹heights› LOWEST,HIGHEST or ‹dem_init›"));
            };
            let base = (ca - cb).norm();
            let top = ca.z.min(cb.z);
            if !(base > 0.0) || l.crs.is_geographic() {
                return Err(Error::setting("heights", "the two cameras' positions give no base: give ‹heights› LOWEST,HIGHEST or ‹dem_init›"));
            }
            Ok([top - 10.0 * base, top - base])
        }
    }
}
