//! `grid`: irregular heights (surveyed points, lidar and drone point clouds)
//! to a regular DEM, streamed. The points are read twice: once for their
//! extent and count, once into bins on disk ([`bins`]); then blunders are
//! found and dropped ([`blunders`]), and the DEM is made a block of cells at
//! a time from its bin and the bins around it ([`neighbourhood`],
//! [`methods`]), band after band of tiles through the orthophoto's own
//! writer. Memory is bounded by `--memory` whatever the number of points.

pub mod bins;
mod blocks;
pub mod blunders;
pub mod methods;
pub mod neighbourhood;
mod options;

pub use options::{GridOptions, GridReport, Method, NODATA};

use crate::error::{Error, Result};
use crate::geodesy::Crs;
use crate::geodesy::Reprojection;
use crate::geom::{Gsd, OutputGrid, Snap};
use crate::io::tiff_out::{Chunking, GeoTags, OutputSpec};
use crate::pipeline::Raw;
use crate::points::{Point, PointFile};
use crate::progress::{Cancel, Progress, Task};
use bins::{BinGrid, Bins, Rect};
use blocks::{check_not_collinear, drop_blunders, drop_hidden_blunders, Ctx};
use methods::Cells;
use rayon::prelude::*;
use std::path::PathBuf;

/// Bytes a loaded point takes with its share of a triangulation.
const BYTES_A_POINT: u64 = 200;

/// Cells finer than this share of the points' typical spacing are refused.
const FINEST_SHARE: f64 = 1000.0;

/// The points of every file in the DEM's CRS, batch after batch.
struct Reader<'a> {
    files: Vec<(PointFile, Option<Reprojection>)>,
    o: &'a GridOptions,
    cancel: &'a Cancel,
}

impl Reader<'_> {
    /// Every point to `each`; returns (points in the files, points not
    /// brought into the CRS).
    fn each(&self, progress: &dyn Progress, mut each: impl FnMut(&Point)) -> Result<(u64, u64)> {
        let (mut read, mut lost) = (0, 0);
        for (file, reproject) in &self.files {
            let mut last = 0;
            read += file.read(&self.o.columns, &self.o.filter, self.cancel, &mut |batch, bytes| {
                for p in batch {
                    match reproject {
                        None => each(p),
                        Some(r) => match r.apply(p.x, p.y) {
                            Some((x, y)) => each(&Point { x, y, z: p.z }),
                            None => lost += 1,
                        },
                    }
                }
                progress.advance(bytes - last);
                last = bytes;
                Ok(())
            })?;
        }
        Ok((read, lost))
    }
}

/// Makes the DEM `o.output` from the points of `o.inputs`.
pub fn grid(o: &GridOptions, progress: &dyn Progress, cancel: &Cancel) -> Result<GridReport> {
    let started = std::time::Instant::now();
    let mut warnings: Vec<String> = crate::io::tiff_out::named_as_other_format(&o.output).into_iter().collect();
    check(o)?;
    let (reader, crs) = open(o, cancel, &mut warnings)?;
    let input_bytes: u64 = o.inputs.iter().filter_map(|p| std::fs::metadata(p).ok()).map(|m| m.len()).sum();

    // Pass 1: the points' extent and number.
    progress.start(&Task { name: "reading points", units: input_bytes, lines: 0, line_name: "", input_bytes });
    let (mut x0, mut y0, mut x1, mut y1, mut kept) = (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY, 0u64);
    let (read, unprojected) = reader.each(progress, |p| {
        x0 = x0.min(p.x);
        y0 = y0.min(p.y);
        x1 = x1.max(p.x);
        y1 = y1.max(p.y);
        kept += 1;
    })?;
    progress.finish();
    let files = o.inputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ");
    if kept == 0 {
        return Err(Error::Named(format!("{files}: no points{}", if read > 0 { " left after the class and return filters" } else { "" })));
    }
    plausible(&crs, [x0, y0, x1, y1], &files)?;
    let grid = match o.bounds {
        Some(b) => output_grid(b, o.gsd)?,
        // Points that make no grid at this cell size are named as the cause.
        None => output_grid([x0, y0, x1, y1], o.gsd).map_err(|_| {
            Error::Named(format!(
                "{files}: the points span {x0:e}…{x1:e} × {y0:e}…{y1:e}: at ‹gsd› {} × {} that is no grid (a point far from the others, or the wrong CRS?)",
                o.gsd.x, o.gsd.y
            ))
        })?,
    };
    let (gx, gy) = (o.gsd.x, o.gsd.y);
    let (w, h) = (grid.width, grid.height);

    // Bins: a block of cells each, and a ring around the DEM (the
    // neighbours of its edge cells); the points kept do not depend on the
    // block.
    let ring = if o.bounds.is_some() { 0.1 * (w as f64 * gx).max(h as f64 * gy) + 64.0 * gx.max(gy) + 2.0 * o.max_edge.unwrap_or(0.0) } else { 0.0 };
    let keep = [-ring, -(h as f64) * gy - ring, w as f64 * gx + ring, ring];
    let density = kept as f64 / (((keep[2] - keep[0]) / gx) * ((keep[3] - keep[1]) / gy)).max(1.0);
    let block = block_side(o, density);
    let (side_x, side_y) = (block as f64 * gx, block as f64 * gy);
    let ring_bins = (ring / side_x.min(side_y)).ceil() as u32 + 1;
    let (bc, br) = (w.div_ceil(block) + 2 * ring_bins, h.div_ceil(block) + 2 * ring_bins);
    // Each bin's lists, and each output tile's place in the file, are held
    // for the whole run: a quarter of the memory at most.
    let tiles = w.div_ceil(o.tile) as u64 * h.div_ceil(o.tile) as u64;
    let held = bc as u64 * br as u64 * Bins::BYTES_A_BIN + tiles * 16;
    if held > o.memory / 4 {
        return Err(Error::setting(
            "gsd",
            format!("{w}×{h} cells need {} MiB for their bins and tiles alone, more than a quarter of the memory given: a coarser ‹gsd›, smaller ‹bounds› or more ‹memory›", held >> 20),
        ));
    }
    let top = ring_bins as f64 * side_y;
    let bin_grid = BinGrid { x0: -(ring_bins as f64) * side_x, y0: top - br as f64 * side_y, side_x, side_y, cols: bc, rows: br };
    let nbins = bc as u64 * br as u64;
    // A quarter of the memory for points waiting to be written.
    let max_held = (o.memory / 4 / 24) as usize;
    let chunk = (max_held as u64 / nbins).clamp(64, 4096) as usize;
    let dir = crate::io::publish::folder_of(&o.output);
    let mut bins = Bins::new(bin_grid, &dir, chunk, max_held)?;

    // Pass 2: into the bins, and the points' density on a fixed lattice
    // (their typical spacing, whatever the blocks).
    // Cells of a few dozen points each, so that the median is a density.
    let lat = ((kept as f64 / 32.0).sqrt() as usize).clamp(1, 128);
    let mut lattice = vec![0u64; lat * lat];
    let (lw, lh) = (w as f64 * gx, h as f64 * gy);
    let mut outside = 0u64;
    let mut failed = None;
    progress.start(&Task { name: "binning points", units: input_bytes, lines: 0, line_name: "", input_bytes });
    reader.each(progress, |p| {
        let (x, y) = (p.x - grid.x0, p.y - grid.y0);
        if !(x >= keep[0] && x <= keep[2] && y >= keep[1] && y <= keep[3]) {
            outside += 1;
            return;
        }
        let (u, v) = (x / lw, -y / lh);
        if (0.0..1.0).contains(&u) && (0.0..1.0).contains(&v) {
            lattice[(v * lat as f64) as usize * lat + (u * lat as f64) as usize] += 1;
        }
        if failed.is_none() {
            match bins.push([x, y, p.z], &dir) {
                Ok(true) => {}
                Ok(false) => outside += 1,
                Err(e) => failed = Some(e),
            }
        }
    })?;
    if let Some(e) = failed {
        return Err(e);
    }
    bins.finish(&dir)?;
    progress.finish();
    if bins.total() == 0 {
        return Err(Error::Named(format!("{files}: none of the points lies within the bounds asked for")));
    }
    let spacing = typical_spacing(&lattice, lw * lh / (lat * lat) as f64);
    // Cells a thousand times finer than the points hold a million cells a
    // point: the points say nothing at that scale (a slip of units?).
    let finest = gx.max(gy);
    if finest < spacing / FINEST_SHARE {
        return Err(Error::setting("gsd", format!("{finest} is finer than a {FINEST_SHARE:.0}th of the points' typical spacing ({spacing:.4}): a cell size the points cannot resolve")));
    }
    if finest < spacing / 10.0 {
        warnings.push(format!("‹gsd› {finest} is more than ten times finer than the points' typical spacing ({spacing:.4}): most cells are interpolated"));
    }
    let max_edge = o.max_edge.unwrap_or_else(|| (10.0 * spacing).max(4.0 * gx.max(gy)));
    let radius = o.radius.unwrap_or(max_edge);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(o.threads)
        .build()
        .map_err(|e| Error::setting("threads", format!("cannot start {} threads: {e}", o.threads)))?;
    let cap = (o.memory / 2 / o.threads as u64 / BYTES_A_POINT).max(100_000);
    let ctx = Ctx { bins: &bins, max_edge, radius, cap, block, grid, o };

    // The tiles to make: all, or the piece asked for.
    let tile = o.tile;
    let [tc0, tr0, tcw, trh] = piece_window(o, &grid)?;
    let is_piece = o.window.is_some() || o.shard.is_some();

    // Blunders, each bin's found from the points as read, then dropped;
    // once more among those left, for a blunder that another beside it
    // hid (two neighbours of a point with three or four).
    // The second pass judges only the points near those the first dropped:
    // elsewhere no point's neighbours changed.
    let mut blunders = 0;
    if let Some(k) = o.blunders {
        let g = bins.grid;
        // A piece needs the blunders its blocks may see: those within a
        // few longest sides of it (a triangle reaching farther is rare).
        let near = is_piece.then(|| {
            let reach = 4.0 * max_edge + 2.0 * g.side_x.max(g.side_y);
            let (x0, y0) = ((tc0 * tile) as f64 * gx, -((tr0 * tile) as f64) * gy);
            [x0 - reach, y0 - (trh * tile) as f64 * gy - reach, x0 + (tcw * tile) as f64 * gx + reach, y0 + reach]
        });
        let held: Vec<(u32, u32)> = (0..g.rows)
            .flat_map(|r| (0..g.cols).map(move |c| (c, r)))
            .filter(|&(c, r)| bins.count(c, r) > 0)
            .filter(|&(c, r)| {
                near.is_none_or(|n| {
                    let b = g.ground_of(Rect { c0: c, r0: r, c1: c, r1: r });
                    b[2] >= n[0] && b[0] <= n[2] && b[3] >= n[1] && b[1] <= n[3]
                })
            })
            .collect();
        let (found, dropped) = pool.install(|| drop_blunders(&ctx, k, &held, progress, cancel))?;
        blunders += found;
        if !dropped.is_empty() {
            blunders += pool.install(|| drop_hidden_blunders(&ctx, k, &dropped, progress, cancel))?;
        }
    }
    check_not_collinear(&ctx, &files)?;

    // The DEM (or the piece of it asked for), band after band of tiles.
    let piece = {
        let (x0, y0) = grid.ground((tc0 * tile) as f64, (tr0 * tile) as f64);
        OutputGrid { x0, y0, gsd: grid.gsd, width: ((tc0 + tcw) * tile).min(w) - tc0 * tile, height: ((tr0 + trh) * tile).min(h) - tr0 * tile }
    };
    let key = source_key(o, &crs);
    let source = match is_piece {
        true => {
            crate::io::geotiff::piece_source(&key, &grid, &crate::assemble::layout_record(o.overviews, crate::overview::OverviewResampling::Average, o.cog))
        }
        false => key,
    };
    let spec = spec_of(o, &piece, &crs)?;
    let pending = crate::io::publish::PendingFile::create(&o.output)?;
    let across = strip_tiles(&spec, o.memory / 4);
    let strips: Vec<(u32, u32)> = (0..spec.tiles_across()).step_by(across as usize).map(|c| (c, (c + across).min(spec.tiles_across()))).collect();
    let writing = crate::pipeline::band_writer::BandWriting {
        spec: &spec,
        path: &o.output,
        threads: o.threads,
        overview_resampling: crate::overview::OverviewResampling::Average,
        fill: NODATA,
        sync: o.sync,
        progress,
        cancel,
        source: Some(&source),
    };
    progress.start(&Task {
        name: "grid",
        units: spec.tiles_across() as u64 * spec.tiles_down() as u64,
        lines: piece.height as u64,
        line_name: "rows",
        input_bytes: 0,
    });
    let unsettled = std::sync::atomic::AtomicU64::new(0);
    let (mut with, mut without) = (0u64, 0u64);
    let last_band = (strips.len() - 1, spec.tiles_down() - 1);
    let written = crate::pipeline::band_writer::write_bands(&writing, pending, &strips, |s, b| {
        let last = (s, b) == last_band;
        // The whole DEM's tile columns and band.
        let (c0, c1) = (strips[s].0 + tc0, strips[s].1 + tc0);
        let b = b + tr0;
        let tiles = (c1 - c0) as usize;
        let mut raw = vec![NODATA as f32; tiles * (tile * tile) as usize];
        let per_tile = tile / block;
        let blocks: Vec<(u32, u32)> = (0..per_tile)
            .flat_map(|bj| (c0 * per_tile..c1 * per_tile).map(move |bi| (bi, b * per_tile + bj)))
            .filter(|&(bi, bj)| bi * block < w && bj * block < h)
            .collect();
        let made: Vec<Result<(Cells, Vec<f32>, u64)>> = pool.install(|| blocks.par_iter().map(|&(bi, bj)| ctx.block_values(bi, bj, cancel)).collect());
        for m in made {
            let (cells, values, u) = m?;
            unsettled.fetch_add(u, std::sync::atomic::Ordering::Relaxed);
            for j in 0..cells.h {
                for i in 0..cells.w {
                    let v = values[(j * cells.w + i) as usize];
                    let (ci, cj) = (cells.i0 + i, cells.j0 + j);
                    let t = (ci / tile - c0) as usize;
                    let at = t * (tile * tile) as usize + ((cj % tile) * tile + ci % tile) as usize;
                    if v.is_nan() {
                        without += 1;
                    } else {
                        raw[at] = v;
                        with += 1;
                    }
                }
            }
        }
        // A whole DEM without one height is refused before it is
        // published (a piece of a sharded one may lie where no point is).
        if last && with == 0 && !is_piece {
            return Err(Error::Geometry(format!(
                "no cell of the {w}×{h} DEM has a height: the points are farther apart than ‹max_edge› (or ‹radius›) everywhere, or no cell's centre falls among them (‹gsd› {})",
                crate::error::short_number(gx)
            )));
        }
        Ok((Raw::F32(raw), None))
    });
    progress.finish();
    if cancel.is_cancelled() {
        return Err(Error::Cancelled);
    }
    written?;
    let unsettled = unsettled.into_inner();
    if with == 0 {
        warnings.push("no cell of this piece has a height: the points are farther apart than ‹max_edge› (or ‹radius›) everywhere here".into());
    }
    if blunders > 0 {
        warnings.push(format!("{blunders} points dropped as blunders (‹blunders› none keeps them)"));
    }
    for wmsg in &warnings {
        progress.warn(wmsg);
    }
    let used = bins.total() - blunders;
    Ok(GridReport {
        output: o.output.clone(),
        crs: crs.to_string(),
        width: w,
        height: h,
        gsd: [gx, gy],
        bounds: [grid.x0, grid.y0 - h as f64 * gy, grid.x0 + w as f64 * gx, grid.y0],
        method: o.method,
        points_read: read,
        points_filtered: read - kept - unprojected,
        points_outside: outside,
        points_unprojected: unprojected,
        blunders,
        points_used: used,
        spacing,
        max_edge,
        cells_with_height: with,
        cells_without: without,
        unsettled,
        block,
        seconds: started.elapsed().as_secs_f64(),
        warnings,
    })
}

/// The tiles to make, `[col, row, cols, rows]`: the window asked for (within
/// the whole's tiles), else all.
fn piece_window(o: &GridOptions, grid: &OutputGrid) -> Result<[u32; 4]> {
    let tile = o.tile;
    let (ta, td) = (grid.width.div_ceil(tile), grid.height.div_ceil(tile));
    if let Some((i, n)) = o.shard {
        let (r0, r1) = ((i - 1) as u64 * td as u64 / n as u64, i as u64 * td as u64 / n as u64);
        if r1 == r0 {
            return Err(Error::setting("shard", format!("{i}/{n} holds no row of tiles: the DEM has {td}")));
        }
        return Ok([0, r0 as u32, ta, (r1 - r0) as u32]);
    }
    match o.window {
        None => Ok([0, 0, ta, td]),
        Some([c, r, cw, rh]) => {
            if c >= ta || r >= td {
                return Err(Error::setting("window", format!("{c},{r},{cw},{rh} starts outside the DEM's {ta} × {td} tiles")));
            }
            Ok([c, r, cw.min(ta - c), rh.min(td - r)])
        }
    }
}

/// What a DEM is made from, as a key: the points' files by their contents
/// and every setting that changes a cell (pieces of one DEM share it).
fn source_key(o: &GridOptions, crs: &Crs) -> String {
    let settings = format!(
        "grid gsd={:?} bounds={:?} crs={crs} points_crs={:?} method={:?} max_edge={:?} radius={:?} power={:?} neighbours={:?} columns={:?} classes={:?} returns={:?} blunders={:?} tile={}",
        o.gsd,
        o.bounds,
        o.points_crs.as_ref().map(|c| c.to_string()),
        o.method,
        o.max_edge,
        o.radius,
        o.power,
        o.neighbours,
        o.columns,
        o.filter.classes,
        o.filter.returns,
        o.blunders,
        o.tile
    );
    let mut files: Vec<PathBuf> = o.inputs.clone();
    files.extend(o.inputs.iter().map(|p| p.with_extension("prj")).filter(|p| p.is_file()));
    let files: Vec<&std::path::Path> = files.iter().map(|p| p.as_path()).collect();
    crate::identity::content_key_of(&[settings.as_bytes()], &files)
}

/// The blunder threshold: a positive number of robust sigmas, or none.
pub fn check_blunders(k: Option<f64>) -> Result<()> {
    match k.is_some_and(|k| !(k > 0.0 && k.is_finite())) {
        true => Err(Error::setting("blunders", "must be a positive number of sigmas, or none")),
        false => Ok(()),
    }
}

/// Settings that cannot make a DEM.
fn check(o: &GridOptions) -> Result<()> {
    if o.inputs.is_empty() {
        return Err(Error::Usage("no point files given".into()));
    }
    if !(o.gsd.x > 0.0 && o.gsd.y > 0.0 && o.gsd.x.is_finite() && o.gsd.y.is_finite()) {
        return Err(Error::setting("gsd", "the cell size must be a positive number"));
    }
    for (setting, v) in [("max_edge", o.max_edge), ("radius", o.radius)] {
        if v.is_some_and(|v| !(v > 0.0 && v.is_finite())) {
            return Err(Error::setting(setting, "must be a positive length"));
        }
    }
    if !(o.power > 0.0 && o.power <= 16.0) {
        return Err(Error::setting("power", "must be over 0 and at most 16"));
    }
    check_blunders(o.blunders)?;
    if o.neighbours == Some(0) {
        return Err(Error::setting("neighbours", "must be 1 or more"));
    }
    if !(16..=4096).contains(&o.tile) || !o.tile.is_multiple_of(16) {
        return Err(Error::setting("tile", "must be a multiple of 16 from 16 to 4096"));
    }
    if let Some(b) = o.block {
        if b == 0 || !o.tile.is_multiple_of(b) {
            return Err(Error::setting("block", "must divide the tile size"));
        }
    }
    if let Some((i, n)) = o.shard {
        if n == 0 || i == 0 || i > n {
            return Err(Error::setting("shard", format!("{i}/{n}: give I/N with 1 ≤ I ≤ N")));
        }
        if o.window.is_some() {
            return Err(Error::setting("shard", "a shard is a window of its own: give one or the other"));
        }
    }
    if o.threads == 0 || o.threads > 1024 {
        return Err(Error::setting("threads", "must be from 1 to 1024"));
    }
    let mut inputs: Vec<crate::io::overwrite::Role> = o.inputs.iter().map(|p| crate::io::overwrite::Role::new("points", p)).collect();
    let sidecars: Vec<PathBuf> = o.inputs.iter().map(|p| p.with_extension("prj")).filter(|p| p.is_file()).collect();
    inputs.extend(sidecars.iter().map(|p| crate::io::overwrite::Role::new("points' .prj", p)));
    crate::io::overwrite::check_outputs(&inputs, &[crate::io::overwrite::Role::new("output", &o.output)])
}

/// The point files and the DEM's CRS, each file with what brings its points
/// into it.
fn open<'a>(o: &'a GridOptions, cancel: &'a Cancel, warnings: &mut Vec<String>) -> Result<(Reader<'a>, Crs)> {
    let mut files = Vec::new();
    let mut said = Vec::new();
    for p in &o.inputs {
        let f = PointFile::open(p)?;
        let crs = f.crs()?;
        said.push(crs.clone());
        files.push(f);
    }
    let first_said = said.iter().flatten().next().cloned();
    let crs = o
        .crs
        .clone()
        .or_else(|| o.points_crs.clone())
        .or(first_said)
        .ok_or_else(|| Error::Named(format!("{}: the points' CRS is not said (no .prj, no CRS in the LAS header): give ‹crs›", o.inputs[0].display())))?;
    let mut out = Vec::new();
    for (f, s) in files.into_iter().zip(said) {
        let from = match (s, &o.points_crs) {
            (Some(s), Some(given)) if s != *given => {
                warnings.push(format!("{}: its points are in {s}, not ‹points_crs› {given}: taken as the file says", f.path.display()));
                s
            }
            (Some(s), _) => s,
            (None, Some(given)) => given.clone(),
            (None, None) => crs.clone(),
        };
        let reproject = (from != crs)
            .then(|| Reprojection::new(&from, &crs))
            .transpose()
            .map_err(|m| Error::Named(format!("{}: its points cannot be brought into {crs}: {m}", f.path.display())))?;
        out.push((f, reproject));
    }
    Ok((Reader { files: out, o, cancel }, crs))
}

/// Refuses coordinates that cannot be in `crs`: degrees taken as metres.
fn plausible(crs: &Crs, [x0, y0, x1, y1]: [f64; 4], files: &str) -> Result<()> {
    if crs.is_geographic() {
        if x0 < -540.0 || x1 > 540.0 || y0 < -90.5 || y1 > 90.5 {
            return Err(Error::Named(format!("{files}: the points ({x0:.1}…{x1:.1}, {y0:.1}…{y1:.1}) are not longitudes and latitudes, but their CRS ({crs}) is geographic: give ‹points_crs›")));
        }
    } else if x0 >= -180.0 && x1 <= 180.0 && y0 >= -90.0 && y1 <= 90.0 && (x1 - x0) < 2.0 && (y1 - y0) < 2.0 && (x0.fract() != 0.0 || y0.fract() != 0.0) {
        return Err(Error::Named(format!("{files}: the points ({x0}…{x1}, {y0}…{y1}) look like longitudes and latitudes, but their CRS ({crs}) is projected: give ‹points_crs› EPSG:4326 (or theirs)")));
    }
    Ok(())
}

fn output_grid(bounds: [f64; 4], gsd: Gsd) -> Result<OutputGrid> {
    let [x0, y0, x1, y1] = bounds;
    if !bounds.iter().all(|v| v.is_finite()) {
        return Err(Error::setting("bounds", "not finite"));
    }
    // A single point, or points on one line across or down: a cell around them.
    let (x1, y1) = (if x1 > x0 { x1 } else { x0 + gsd.x }, if y1 > y0 { y1 } else { y0 + gsd.y });
    let grid = OutputGrid::from_bounds([x0, y0, x1, y1], gsd, Snap::Tap)
        .ok_or_else(|| Error::setting("bounds", format!("{x0},{y0},{x1},{y1} at {} × {} makes no grid", gsd.x, gsd.y)))?;
    if grid.width as u64 * grid.height as u64 > 1 << 40 {
        return Err(Error::setting("gsd", format!("{} × {} cells are too many: a coarser ‹gsd› or smaller ‹bounds›", grid.width, grid.height)));
    }
    Ok(grid)
}

/// A block's side in cells: the tile halved while a block with the ring of
/// blocks around it would hold more points than a thread's share of memory
/// triangulates (or as given).
fn block_side(o: &GridOptions, density: f64) -> u32 {
    if let Some(b) = o.block {
        return b;
    }
    let share = (o.memory / 2 / o.threads as u64).max(16 << 20) as f64;
    // A block loads its cells and the longest side around them (the
    // points are filtered as read). The longest side is not known before
    // the points are binned: the default's, from the mean spacing (which
    // is no less than the median the run takes).
    let cell = o.gsd.x.min(o.gsd.y);
    let spacing = (o.gsd.x * o.gsd.y / density.max(1e-12)).sqrt();
    let edge = o.max_edge.unwrap_or_else(|| (10.0 * spacing).max(4.0 * o.gsd.x.max(o.gsd.y))) / cell;
    let mut b = o.tile;
    while b.is_multiple_of(2) && b > 16 && (b as f64 + 2.0 * edge).powi(2) * density * BYTES_A_POINT as f64 > share {
        b /= 2;
    }
    b
}

/// The points' typical spacing: from the median density over the cells
/// of `lattice` that hold any (each `area` in size), so that voids and
/// clusters do not sway it.
fn typical_spacing(lattice: &[u64], area: f64) -> f64 {
    let mut held: Vec<u64> = lattice.iter().copied().filter(|&c| c > 0).collect();
    if held.is_empty() {
        return area.sqrt();
    }
    held.sort_unstable();
    let median = held[held.len() / 2] as f64;
    (area / median).sqrt()
}

/// How many tile columns a strip holds within `budget` bytes.
fn strip_tiles(spec: &OutputSpec, budget: u64) -> u32 {
    let mut across = spec.tiles_across();
    while across > 1 && crate::pipeline::band_writer::held_bytes(spec, across) > budget {
        across = across.div_ceil(2);
    }
    across
}

fn spec_of(o: &GridOptions, grid: &OutputGrid, crs: &Crs) -> Result<OutputSpec> {
    let mut spec = OutputSpec {
        overviews: 0,
        cog: false,
        width: grid.width,
        height: grid.height,
        bands: 1,
        sample: crate::io::source::SampleType::F32,
        chunking: Chunking::Tiles(o.tile),
        compression: o.compress,
        level: crate::options::codec_level(o.compress, o.level, None)?,
        overview_level: None,
        bigtiff: false,
        photometric: 1,
        alpha: false,
        mask: false,
        geo: Some(GeoTags {
            x0: grid.x0,
            y0: grid.y0,
            gsd: grid.gsd,
            keys: crate::geodesy::geokeys::keys_of(crs).map_err(|m| Error::setting("crs", m))?,
            nodata: Some(NODATA),
        }),
    };
    spec.check_codec().map_err(|m| Error::setting("compress", m))?;
    spec.overviews = o.overviews.levels(grid.width, grid.height, o.tile);
    spec.cog = o.cog;
    spec.bigtiff = spec.needs_bigtiff();
    Ok(spec)
}
