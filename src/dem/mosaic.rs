//! A DEM handed over in tiles: a GDAL VRT mosaic (`gdalbuildvrt`'s simple
//! and complex sources), or GeoTIFF / `.hgt` tiles on one grid given as a
//! folder or as a list (a text file, a path a line, as `gdalbuildvrt
//! -input_file_list` takes).
//! Each tile stays its own grid, read as any DEM is (whole when small, a
//! chunk at a time when large, within its share of the budget); a sample
//! of the mosaic is looked up in the tile that holds it, never copied into
//! one grid.

use super::{check_north_up, GridDem};
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// Side of the squares of the mosaic's grid that list the tiles over them.
const BIN: usize = 256;

/// One tile: where it lies in the mosaic's grid, where that part starts
/// in its own, and its own samples.
struct Tile {
    /// Columns `x0..x0+w`, rows `y0..y0+h` of the mosaic.
    dst: [usize; 4],
    /// The tile's own sample at the mosaic's (x0, y0).
    src: (usize, usize),
    grid: GridDem,
    /// A value the VRT says is nodata in this source (beside the tile's own).
    nodata: Option<f64>,
}

/// The tiles, and for each square of [`BIN`] samples the tiles over it,
/// the last given first (a later source is drawn over an earlier one).
pub(super) struct Mosaic {
    tiles: Vec<Tile>,
    bins: Vec<Vec<u32>>,
    bins_across: usize,
}

/// The grid a mosaic makes: size, geotransform, CRS.
pub(super) struct MosaicGrid {
    pub width: usize,
    pub height: usize,
    pub transform: [f64; 6],
    pub crs: Option<crate::geodesy::Crs>,
}

impl Mosaic {
    pub(super) fn check_intact(&self) -> Result<()> {
        self.tiles.iter().try_for_each(|t| t.grid.check_intact())
    }

    /// The most its tiles hold in memory, bytes.
    pub fn held_bytes(&self) -> u64 {
        self.tiles.iter().map(|t| t.grid.held_bytes()).sum()
    }

    /// Sample (i, j) of the mosaic: the last tile over it that has a value
    /// there; NaN where none has.
    pub fn get(&self, i: usize, j: usize) -> f32 {
        for &t in &self.bins[(j / BIN) * self.bins_across + i / BIN] {
            let t = &self.tiles[t as usize];
            let [x0, y0, w, h] = t.dst;
            if i >= x0 && j >= y0 && i < x0 + w && j < y0 + h {
                let v = t.grid.sample(t.src.0 + i - x0, t.src.1 + j - y0);
                if !t.grid.is_nodata(v) && t.nodata.is_none_or(|nd| v as f64 != nd) {
                    return v;
                }
            }
        }
        f32::NAN
    }

    fn new(width: usize, height: usize, tiles: Vec<Tile>) -> Mosaic {
        let bins_across = width.div_ceil(BIN);
        let mut bins = vec![Vec::new(); bins_across * height.div_ceil(BIN)];
        for (k, t) in tiles.iter().enumerate().rev() {
            let [x0, y0, w, h] = t.dst;
            for by in y0 / BIN..(y0 + h).div_ceil(BIN).min(height.div_ceil(BIN)) {
                for bx in x0 / BIN..(x0 + w).div_ceil(BIN).min(bins_across) {
                    bins[by * bins_across + bx].push(k as u32);
                }
            }
        }
        Mosaic { tiles, bins, bins_across }
    }
}

/// Is `path` a mosaic: a folder, a file that begins as a VRT does, or a
/// text file (a list of tiles)?
pub(super) fn is_mosaic(path: &Path) -> bool {
    path.is_dir() || matches!(kind_of(path), Some(Kind::Vrt | Kind::List))
}

enum Kind {
    Vrt,
    List,
}

/// A file that is a VRT or a list of tiles, told from its first bytes
/// (a VRT may open with an XML declaration and comments, as GDAL's own
/// writers and editors leave them).
fn kind_of(path: &Path) -> Option<Kind> {
    let head = crate::io::bounded_read::read_head(path, 4096).ok()?;
    if starts_as_vrt(&String::from_utf8_lossy(&head)) {
        return Some(Kind::Vrt);
    }
    let head = &head[..head.len().min(64)];
    let printable = !head.is_empty() && head.iter().all(|&b| b == b'\t' || b == b'\n' || b == b'\r' || b >= 0x20);
    printable.then_some(Kind::List)
}

/// Whether a text opens as a VRT: `<VRTDataset`, after any XML
/// declaration, comments and blank space.
fn starts_as_vrt(text: &str) -> bool {
    let mut rest = text.trim_start_matches('\u{feff}').trim_start();
    loop {
        if let Some(r) = rest.strip_prefix("<?") {
            let Some(end) = r.find("?>") else { return false };
            rest = r[end + 2..].trim_start();
        } else if let Some(r) = rest.strip_prefix("<!--") {
            let Some(end) = r.find("-->") else { return false };
            rest = r[end + 3..].trim_start();
        } else {
            return rest.starts_with("<VRTDataset");
        }
    }
}

/// How deep mosaics may name mosaics (a VRT of VRTs of tiles is two).
const MAX_NESTING: usize = 8;

thread_local! {
    /// The mosaics being opened on this thread, outermost first: a mosaic
    /// that names itself, directly or through others, is refused, not
    /// followed until the stack runs out.
    static OPENING: std::cell::RefCell<Vec<PathBuf>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Leaves the mosaic's place on [`OPENING`] when it is open (or failed).
struct Opening;

impl Drop for Opening {
    fn drop(&mut self) {
        OPENING.with(|o| o.borrow_mut().pop());
    }
}

/// Enters `path` on [`OPENING`], refusing a cycle or too deep a nesting.
fn enter(path: &Path) -> Result<Opening> {
    let key = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    OPENING.with(|o| {
        let mut o = o.borrow_mut();
        if let Some(first) = o.iter().position(|p| *p == key) {
            let chain: Vec<String> = o[first..].iter().chain(std::iter::once(&key)).map(|p| p.display().to_string()).collect();
            return Err(Error::format(path, format!("a DEM mosaic that names itself: {}", chain.join(" → "))));
        }
        if o.len() >= MAX_NESTING {
            return Err(Error::limits(path, format!("DEM mosaics (VRTs, lists, folders) nested more than {MAX_NESTING} deep")));
        }
        o.push(key);
        Ok(Opening)
    })
}

/// Opens the mosaic at `path` (a VRT file, a folder or a list of tiles),
/// its tiles holding at most about `max_bytes` of heights in memory
/// together.
pub(super) fn open(path: &Path, max_bytes: u64) -> Result<(Mosaic, MosaicGrid)> {
    let _opening = enter(path)?;
    if path.is_dir() {
        open_folder(path, max_bytes)
    } else if matches!(kind_of(path), Some(Kind::List)) {
        open_list(path, max_bytes)
    } else {
        open_vrt(path, max_bytes)
    }
}

/// The tile extensions a folder's files are taken by.
const TILE_EXTENSIONS: [&str; 3] = ["tif", "tiff", "hgt"];

/// Whether a file in a DEM folder is taken as one of its tiles.
pub(super) fn is_tile_name(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| TILE_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// A folder's tiles, in order.
fn folder_tiles(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> =
        std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| is_tile_name(p)).collect();
    files.sort();
    Ok(files)
}

/// The files the DEM mosaic at `path` reads (a folder's tiles, a list's
/// lines, a VRT's sources), as far as they can be told: the files no
/// command may write over. Empty where `path` is not a mosaic or cannot
/// be read (its reader says why).
pub(super) fn files_of(path: &Path) -> Vec<PathBuf> {
    if path.is_dir() {
        return folder_tiles(path).unwrap_or_default();
    }
    match kind_of(path) {
        Some(Kind::List) => list_lines(path).map(|l| l.into_iter().map(|(_, _, f)| f).collect()).unwrap_or_default(),
        Some(Kind::Vrt) => {
            let Ok(text) = crate::io::bounded_read::read_text_bounded(path, "VRT", 64 << 20) else { return Vec::new() };
            let Ok(doc) = roxmltree::Document::parse(&text) else { return Vec::new() };
            doc.descendants().filter(|n| n.has_tag_name("SourceFilename")).map(|f| source_path(path, f)).collect()
        }
        None => Vec::new(),
    }
}

/// A VRT source's file: relative to the VRT's folder where it says so.
fn source_path(vrt: &Path, file: roxmltree::Node) -> PathBuf {
    let name = file.text().unwrap_or("").trim();
    if file.attribute("relativeToVRT").is_some_and(|v| v.trim() == "1") {
        vrt.parent().unwrap_or(Path::new(".")).join(name)
    } else {
        PathBuf::from(name)
    }
}

/// A folder's `.tif`, `.tiff` and `.hgt` files, on one grid.
fn open_folder(dir: &Path, max_bytes: u64) -> Result<(Mosaic, MosaicGrid)> {
    let files = folder_tiles(dir)?;
    if files.is_empty() {
        return Err(Error::format(dir, "is a folder without DEM tiles (.tif, .tiff or .hgt)"));
    }
    open_tiles(dir, files, max_bytes)
}

/// A list of tiles: a path a line (relative to the list's folder), blank
/// lines and lines starting with `#` left out. A line naming no file is
/// refused by its number.
fn open_list(list: &Path, max_bytes: u64) -> Result<(Mosaic, MosaicGrid)> {
    let mut files = Vec::new();
    for (n, line, file) in list_lines(list)? {
        if !file.is_file() {
            // The line is shown only where it reads as a tile's name: the
            // text of a file that is no list at all is never echoed.
            let shown = if is_tile_name(Path::new(&line)) || line.to_ascii_lowercase().ends_with(".vrt") { format!(": {line:?}") } else { String::new() };
            return Err(Error::format(
                list,
                format!("read as a list of DEM tiles (a path a line, as gdalbuildvrt -input_file_list): line {} names no file{shown} (a DEM is a GeoTIFF, an .hgt, a GDAL VRT, or a folder or list of those)", n + 1),
            ));
        }
        files.push(file);
    }
    if files.is_empty() {
        return Err(Error::format(list, "read as a list of DEM tiles (a path a line): it names none"));
    }
    open_tiles(list, files, max_bytes)
}

/// A list's lines that name tiles: their index, text and path.
fn list_lines(list: &Path) -> Result<Vec<(usize, String, PathBuf)>> {
    let text = crate::io::bounded_read::read_text_bounded(list, "a list of DEM tiles", 1 << 20)?;
    let base = list.parent().unwrap_or(Path::new(""));
    Ok(text
        .lines()
        .enumerate()
        .map(|(n, l)| (n, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
        .map(|(n, l)| (n, l.to_string(), base.join(l)))
        .collect())
}

/// Tiles on one grid: the same CRS and pixel size, each placed a whole
/// number of samples from the others.
fn open_tiles(mosaic: &Path, files: Vec<PathBuf>, max_bytes: u64) -> Result<(Mosaic, MosaicGrid)> {
    tiles_within(mosaic, files.len(), 0, max_bytes)?;
    let share = max_bytes / files.len() as u64;
    let mut held = Held::new(mosaic, files.len(), max_bytes);
    let mut grids = Vec::with_capacity(files.len());
    for f in &files {
        let g = GridDem::read_posts(f, share)?;
        held.add(&g)?;
        grids.push(g);
    }
    let (step_x, step_y, first_epsg) = (grids[0].transform[1], grids[0].transform[5], grids[0].crs.clone());
    let x_min = grids.iter().map(|g| g.transform[0]).fold(f64::INFINITY, f64::min);
    let y_max = grids.iter().map(|g| g.transform[3]).fold(f64::NEG_INFINITY, f64::max);
    let mut tiles = Vec::new();
    let (mut width, mut height) = (0, 0);
    for (g, f) in grids.into_iter().zip(&files) {
        if g.crs != first_epsg {
            return Err(Error::format(f, format!("is in {}, the first tile in {}: the tiles of a DEM share one CRS", crs_name(&g.crs), crs_name(&first_epsg))));
        }
        if !same(g.transform[1], step_x) || !same(g.transform[5], step_y) {
            return Err(Error::format(
                f,
                format!("has samples of {} × {}, the first tile {} × {}: the tiles of a DEM share one grid", g.transform[1], -g.transform[5], step_x, -step_y),
            ));
        }
        let (cx, cy) = ((g.transform[0] - x_min) / step_x, (g.transform[3] - y_max) / step_y);
        let (x0, y0) = (cx.round(), cy.round());
        if (cx - x0).abs() > 1e-3 || (cy - y0).abs() > 1e-3 {
            return Err(Error::format(
                f,
                format!("lies {cx:.4}, {cy:.4} samples from the tiles' corner, not a whole number: the tiles of a DEM share one grid"),
            ));
        }
        let (x0, y0) = (x0 as usize, y0 as usize);
        width = width.max(x0 + g.width);
        height = height.max(y0 + g.height);
        tiles.push(Tile { dst: [x0, y0, g.width, g.height], src: (0, 0), grid: g, nodata: None });
    }
    let grid = MosaicGrid { width, height, transform: [x_min, step_x, 0.0, y_max, 0.0, step_y], crs: first_epsg };
    Ok((Mosaic::new(width, height, tiles), grid))
}

/// What a tile costs held open beside its heights (its chunk table, the
/// cache's bookkeeping, its place in the bins), bytes, with room.
const PER_TILE: u64 = 2 << 10;
/// A VRT's parsed tree over its text's size.
const XML_TREE_PER_BYTE: u64 = 4;

/// Refuses, before any tile is opened, a DEM of more tiles than the
/// budget holds: each tile costs [`PER_TILE`] of its own whatever its
/// size, so that 10⁶ tiles would take gigabytes before a height is read.
fn tiles_within(mosaic: &Path, tiles: usize, xml_bytes: usize, max_bytes: u64) -> Result<()> {
    let need = (tiles as u64).saturating_mul(PER_TILE).saturating_add((xml_bytes as u64).saturating_mul(XML_TREE_PER_BYTE));
    // As the tiles opened are held: the share and its slack.
    if need <= 2 * max_bytes {
        return Ok(());
    }
    Err(Error::limits(
        mosaic,
        format!(
            "a DEM of {tiles} tiles takes about {} MiB before a height is read, past twice the DEM's share of ‹memory› (2 × {} MiB): join the tiles into one tiled GeoTIFF (gdal_translate of the VRT), or give a larger ‹memory›",
            need.div_ceil(1 << 20),
            max_bytes >> 20
        ),
    ))
}

/// What the tiles opened so far hold, against the budget: a tile read a
/// chunk at a time keeps at least a few chunks, whatever its share, so
/// that many small shares can pass the whole (20 160 tiles of 95 × 16-row
/// strips held 300 MB where their share was 64 MiB).
struct Held<'a> {
    mosaic: &'a Path,
    tiles: usize,
    opened: usize,
    bytes: u64,
    max_bytes: u64,
}

impl<'a> Held<'a> {
    fn new(mosaic: &'a Path, tiles: usize, max_bytes: u64) -> Held<'a> {
        Held { mosaic, tiles, opened: 0, bytes: 0, max_bytes }
    }

    fn add(&mut self, tile: &GridDem) -> Result<()> {
        self.opened += 1;
        self.bytes += tile.held_bytes() + PER_TILE;
        // The share, and as much again of the budget's slack.
        if self.bytes <= 2 * self.max_bytes {
            return Ok(());
        }
        Err(Error::limits(
            self.mosaic,
            format!(
                "{} of its {} tiles hold {} MiB already (each read a chunk at a time keeps a few chunks), past twice the DEM's share of ‹memory› (2 × {} MiB): join the tiles into one tiled GeoTIFF (gdal_translate of the VRT), or give a larger ‹memory›",
                self.opened,
                self.tiles,
                self.bytes.div_ceil(1 << 20),
                self.max_bytes >> 20
            ),
        ))
    }
}

fn same(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs())
}

/// A GDAL VRT: its first band's simple and complex sources, each a tile
/// placed by its source and destination windows (of one size: no
/// resampling). What else a VRT may hold is refused by name.
/// Whether `path` is a GDAL VRT (told from its first bytes).
pub fn is_vrt(path: &Path) -> bool {
    matches!(kind_of(path), Some(Kind::Vrt))
}

/// A VRT's size and geotransform, as its `VRTDataset` says them.
fn vrt_size_and_transform(path: &Path, root: roxmltree::Node) -> Result<(usize, usize, [f64; 6])> {
    let bad = |m: String| Error::format(path, format!("VRT: {m}"));
    let size =
        |name: &str| -> Result<usize> { root.attribute(name).and_then(|v| v.trim().parse().ok()).ok_or_else(|| bad(format!("no {name} on VRTDataset"))) };
    let (width, height) = (size("rasterXSize")?, size("rasterYSize")?);
    let gt: Vec<f64> = child(root, "GeoTransform")
        .and_then(|n| n.text())
        .map(|t| t.split(',').filter_map(|v| v.trim().parse().ok()).collect())
        .ok_or_else(|| bad("no GeoTransform".into()))?;
    let transform: [f64; 6] = gt.try_into().map_err(|_| bad("a GeoTransform of other than six numbers".into()))?;
    super::check_transform(&transform).map_err(|m| bad(format!("GeoTransform: {m}")))?;
    Ok((width, height, transform))
}

/// A VRT's grid: its size, geotransform and SRS (for a reference grid;
/// its sources are not opened).
pub fn vrt_grid(path: &Path) -> Result<(usize, usize, [f64; 6], Option<crate::geodesy::Crs>)> {
    let text = crate::io::bounded_read::read_text_bounded(path, "VRT", 64 << 20)?;
    let doc = roxmltree::Document::parse(&text).map_err(|e| Error::format(path, format!("VRT: {e}")))?;
    let root = doc.root_element();
    let (width, height, transform) = vrt_size_and_transform(path, root)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let crs = match child(root, "SRS").and_then(|n| n.text()).map(str::trim).filter(|t| !t.is_empty()) {
        Some(srs) => Some(crate::geodesy::Crs::parse(srs, dir).map_err(|m| Error::format(path, format!("VRT: its SRS: {m}")))?),
        None => None,
    };
    Ok((width, height, transform, crs))
}

fn open_vrt(path: &Path, max_bytes: u64) -> Result<(Mosaic, MosaicGrid)> {
    let text = crate::io::bounded_read::read_text_bounded(path, "VRT", 64 << 20)?;
    // Counted before the document is parsed: its tree is what costs.
    let sources = text.matches("<SimpleSource").count() + text.matches("<ComplexSource").count();
    tiles_within(path, sources, text.len(), max_bytes)?;
    let doc = roxmltree::Document::parse(&text).map_err(|e| Error::format(path, format!("VRT: {e}")))?;
    let root = doc.root_element();
    let bad = |m: String| Error::format(path, format!("VRT: {m}"));
    let unsupported = |m: String| Error::unsupported(path, format!("VRT: {m}"));
    let (width, height, transform) = vrt_size_and_transform(path, root)?;
    let bands: Vec<_> = root.children().filter(|n| n.has_tag_name("VRTRasterBand")).collect();
    let band = bands.first().ok_or_else(|| bad("no VRTRasterBand".into()))?;
    if let Some(sub) = band.attribute("subClass") {
        return Err(unsupported(format!("a {sub} band (simple and complex sources are read)")));
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut sources = Vec::new();
    for n in band.children().filter(|n| n.is_element()) {
        match n.tag_name().name() {
            "SimpleSource" | "ComplexSource" => sources.push(n),
            "NoDataValue" | "ColorInterp" | "Description" | "Metadata" | "Offset" | "Scale" | "UnitType" | "Histograms" => {}
            other => return Err(unsupported(format!("<{other}> in a band (simple and complex sources are read)"))),
        }
    }
    if sources.is_empty() {
        return Err(bad("a band without sources".into()));
    }
    let share = max_bytes / sources.len() as u64;
    let mut held = Held::new(path, sources.len(), max_bytes);
    let mut tiles = Vec::new();
    let mut crs: Option<crate::geodesy::Crs> = None;
    for s in sources {
        let file = child(s, "SourceFilename").ok_or_else(|| bad("a source without SourceFilename".into()))?;
        let name = file.text().unwrap_or("").trim();
        let tile_path = source_path(path, file);
        let mut nodata = None;
        for e in s.children().filter(|n| n.is_element()) {
            match e.tag_name().name() {
                "SourceFilename" | "SourceProperties" | "SrcRect" | "DstRect" | "UseMaskBand" | "OpenOptions" => {}
                "SourceBand" if e.text().is_some_and(|t| t.trim() == "1") => {}
                "NODATA" => nodata = e.text().and_then(|t| t.trim().parse::<f64>().ok()),
                "ScaleOffset" if e.text().is_some_and(|t| t.trim().parse::<f64>() == Ok(0.0)) => {}
                "ScaleRatio" if e.text().is_some_and(|t| t.trim().parse::<f64>() == Ok(1.0)) => {}
                other => {
                    return Err(unsupported(format!(
                        "<{other}>{} in the source {name} (band 1, no scaling, no lookup table is read)",
                        e.text().map(|t| t.trim()).unwrap_or("")
                    )))
                }
            }
        }
        let grid = GridDem::read_posts(&tile_path, share).map_err(|e| bad(format!("its source: {}", e.marked())))?;
        held.add(&grid)?;
        let rect = |tag: &str, default: [f64; 4]| -> Result<[f64; 4]> {
            let Some(r) = child(s, tag) else { return Ok(default) };
            let a = |k: &str| r.attribute(k).and_then(|v| v.trim().parse::<f64>().ok()).ok_or_else(|| bad(format!("{tag} of {name} without {k}")));
            Ok([a("xOff")?, a("yOff")?, a("xSize")?, a("ySize")?])
        };
        let full = [0.0, 0.0, grid.width as f64, grid.height as f64];
        let (src, dst) = (rect("SrcRect", full)?, rect("DstRect", full)?);
        if !same(src[2], dst[2]) || !same(src[3], dst[3]) {
            return Err(unsupported(format!(
                "the source {name} is resampled ({}×{} to {}×{}): its windows must be of one size",
                src[2], src[3], dst[2], dst[3]
            )));
        }
        let whole = |v: f64| (v - v.round()).abs() < 1e-6;
        if !src.iter().chain(&dst).all(|&v| whole(v)) {
            return Err(unsupported(format!("the source {name} is placed at a fraction of a sample")));
        }
        // Clip to both grids.
        let [mut sx, mut sy, mut w, mut h] = src.map(|v| v.round() as i64);
        let [mut dx, mut dy, _, _] = dst.map(|v| v.round() as i64);
        for (s_, d_, len) in [(&mut sx, &mut dx, &mut w), (&mut sy, &mut dy, &mut h)] {
            let cut = (-*s_).max(-*d_).max(0);
            *s_ += cut;
            *d_ += cut;
            *len -= cut;
        }
        w = w.min(grid.width as i64 - sx).min(width as i64 - dx);
        h = h.min(grid.height as i64 - sy).min(height as i64 - dy);
        if w <= 0 || h <= 0 {
            continue;
        }
        if crs.is_some() && grid.crs.is_some() && grid.crs != crs {
            return Err(Error::format(&tile_path, format!("is in {}, another source of {} in {}", crs_name(&grid.crs), path.display(), crs_name(&crs))));
        }
        crs = crs.or(grid.crs.clone());
        tiles.push(Tile { dst: [dx as usize, dy as usize, w as usize, h as usize], src: (sx as usize, sy as usize), grid, nodata });
    }
    // The VRT's own SRS (the WKT gdalbuildvrt writes) is the mosaic's
    // CRS; its tiles', where they name one, must be the same.
    if let Some(srs) = child(root, "SRS").and_then(|n| n.text()).map(str::trim).filter(|t| !t.is_empty()) {
        let own = crate::geodesy::Crs::parse(srs, dir).map_err(|m| bad(format!("its SRS: {m}")))?;
        let (cx, cy) = (transform[0] + transform[1] * width as f64 / 2.0, transform[3] + transform[5] * height as f64 / 2.0);
        if let Some(t) = &crs {
            if !own.agrees_at(t, cx, cy) {
                return Err(bad(format!("its SRS is {own}, its tiles are in {t}")));
            }
        }
        crs = Some(own);
    }
    let grid = MosaicGrid { width, height, transform, crs };
    Ok((Mosaic::new(width, height, tiles), grid))
}

fn child<'a, 'i>(n: roxmltree::Node<'a, 'i>, name: &str) -> Option<roxmltree::Node<'a, 'i>> {
    n.children().find(|c| c.has_tag_name(name))
}

/// The mosaic's grid, checked as a DEM's is.
pub(super) fn check(path: &Path, g: &MosaicGrid) -> Result<()> {
    let geo = crate::io::geotiff::GeoRef { transform: g.transform, keys: Default::default(), nodata: None, scale_offset: None, source: None };
    check_north_up(&geo, path)?;
    if g.width < 2 || g.height < 2 {
        return Err(Error::format(path, format!("a DEM mosaic of {}×{} posts", g.width, g.height)));
    }
    Ok(())
}

/// A tile's CRS for messages.
fn crs_name(c: &Option<crate::geodesy::Crs>) -> String {
    c.as_ref().map_or_else(|| "no CRS".to_string(), |c| c.to_string())
}
