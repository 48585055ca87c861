//! Putting pieces made with `rectify --window` back together: the pieces
//! share the whole run's tile grid, so their compressed tiles (and their
//! internal masks' tiles) are copied into one tiled GeoTIFF as they are —
//! no seam, the same pixels as a single run. The whole's overviews and band
//! statistics are made anew from the full-resolution tiles (decoded a row
//! of tiles at a time), as a single run makes them; the pieces' own are
//! not used.

use crate::error::{Error, Result};
use crate::io::overwrite::{check_outputs, check_writable, Role};
use crate::io::source::{SourceImage, Window};
use crate::io::tiff_out::{
    decode_mask, encode_mask, encode_tile, folder_of, tiff_write_error, verify, Chunking, Compression, GeoTags, OutputSpec, PendingFile, TileWriter,
};
use crate::options::{codec_level, overview_codec_level, Overviews};
use crate::overview::{ByTileRow, OverviewResampling, Pyramid, Quarter, Statistics, ValidBy};
use crate::progress::Cancel;
use rayon::prelude::*;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

/// How the whole is written.
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub struct AssembleOptions {
    /// Overviews, their resampling and the Cloud-Optimized layout; `None`:
    /// as the pieces record their whole's (see [`layout_record`]), else
    /// auto, average, plain.
    pub overviews: Option<Overviews>,
    pub overview_resampling: Option<OverviewResampling>,
    pub cog: Option<bool>,
    /// The codec level of the overview tiles (the pieces' own tiles are
    /// copied as they are), unless `overview_level` is given.
    pub level: Option<u8>,
    pub overview_level: Option<u8>,
    /// Code the full-resolution tiles anew in this codec (`None`, or the
    /// pieces' own: their tiles are copied as they are). From lossless
    /// pieces, the bytes of a single run in that codec.
    pub compress: Option<Compression>,
    /// The JPEG quality of the overview tiles, for JPEG pieces (of every tile, coded anew).
    pub quality: Option<u8>,
    /// BigTIFF or not (`None`: as the size needs).
    pub bigtiff: Option<bool>,
    /// What overview pixels without a value hold (`None`: the pieces'
    /// nodata value, else 0): NaN for a float mosaic, as its own run writes.
    pub fill: Option<f64>,
    /// Sync the file before it takes its name.
    pub sync: bool,
    /// The pieces may make up part of the whole their source names (a
    /// mosaic piece's strips): not refused for it, and the file keeps
    /// their source. Otherwise they must make up that whole, and the file
    /// is the whole's.
    pub partial: bool,
}

impl Default for AssembleOptions {
    fn default() -> Self {
        AssembleOptions {
            overviews: None,
            overview_resampling: None,
            cog: None,
            level: None,
            overview_level: None,
            quality: None,
            compress: None,
            bigtiff: None,
            fill: None,
            sync: true,
            partial: false,
        }
    }
}

/// The record of the layout a whole is to have that its pieces carry (in
/// their source): what `assemble` makes unless told otherwise.
pub fn layout_record(overviews: Overviews, resampling: OverviewResampling, cog: bool) -> String {
    let o = match overviews {
        Overviews::Auto => "auto".to_string(),
        Overviews::None => "none".to_string(),
        Overviews::Levels(n) => n.to_string(),
    };
    format!("overviews={o} resampling={} cog={cog}", format!("{resampling:?}").to_lowercase())
}

/// What a [`layout_record`] says (each part that it says legibly).
fn read_layout(record: &str) -> (Option<Overviews>, Option<OverviewResampling>, Option<bool>) {
    use crate::options::Choice;
    let mut out = (None, None, None);
    for (k, v) in record.split_whitespace().filter_map(|kv| kv.split_once('=')) {
        match k {
            "overviews" => {
                out.0 = match v {
                    "auto" => Some(Overviews::Auto),
                    "none" => Some(Overviews::None),
                    n => n.parse().ok().map(Overviews::Levels),
                }
            }
            "resampling" => out.1 = OverviewResampling::from_name(v),
            "cog" => out.2 = v.parse().ok(),
            _ => {}
        }
    }
    out
}

/// Assembles `pieces` into `out`. Every tile of the union must come from
/// exactly one piece.
/// A cancelled run stops between rows of tiles and leaves nothing.
pub fn assemble(pieces: &[PathBuf], out: &Path, opts: &AssembleOptions, cancel: &Cancel) -> Result<()> {
    if pieces.is_empty() {
        return Err(Error::Usage("assemble needs at least one piece".into()));
    }
    let ins: Vec<Role> = pieces.iter().map(|p| Role::new("piece", p)).collect();
    check_writable(Role::new("output", out))?;
    check_outputs(&ins, &[Role::new("output", out)])?;
    let srcs: Vec<SourceImage> = pieces.iter().map(|p| SourceImage::open(p, 1 << 20)).collect::<Result<_>>()?;
    let first = &srcs[0].info;
    let geo0 = first.georef.clone().ok_or_else(|| Error::format(&pieces[0], "has no georeferencing"))?;
    let gsd = crate::geom::Gsd { x: geo0.transform[1], y: -geo0.transform[5] };
    let tile = first.chunk.0;
    if !first.tiled || first.chunk.0 != first.chunk.1 {
        return Err(Error::format(&pieces[0], "is not made of square tiles"));
    }
    // Every piece like the first; positions in whole tiles.
    let mut x_min = f64::INFINITY;
    let mut y_max = f64::NEG_INFINITY;
    for (s, p) in srcs.iter().zip(pieces) {
        let i = &s.info;
        let g = i.georef.as_ref().ok_or_else(|| Error::format(p, "has no georeferencing"))?;
        // The first way it differs from the first piece, said.
        let codec = |c: u16| match c {
            1 => "none".to_string(),
            5 => "lzw".into(),
            7 => "jpeg".into(),
            8 | 32946 => "deflate".into(),
            50000 => "zstd".into(),
            c => format!("code {c}"),
        };
        let yes_no = |b: bool| if b { "one" } else { "none" };
        let differs = [
            (i.tiled, "is not tiled".to_string()),
            (i.chunk == first.chunk, format!("tiles of {}×{}, the first piece's {}×{}", i.chunk.0, i.chunk.1, first.chunk.0, first.chunk.1)),
            (i.bands == first.bands, format!("{} bands, the first piece {}", i.bands, first.bands)),
            (i.sample == first.sample, format!("{:?} samples, the first piece's {:?}", i.sample, first.sample)),
            (i.compression == first.compression, format!("compression {}, the first piece's {}", codec(i.compression), codec(first.compression))),
            (i.predictor == first.predictor, format!("predictor {}, the first piece's {}", i.predictor, first.predictor)),
            (i.photometric == first.photometric, format!("photometric {}, the first piece's {}", i.photometric, first.photometric)),
            (i.has_alpha == first.has_alpha, format!("an alpha band: {}, the first piece {}", yes_no(i.has_alpha), yes_no(first.has_alpha))),
            (
                i.mask.is_some() == first.mask.is_some(),
                format!("an internal mask: {}, the first piece {}", yes_no(i.mask.is_some()), yes_no(first.mask.is_some())),
            ),
            (
                (g.transform[1] - gsd.x).abs() < 1e-12 * gsd.x && (-g.transform[5] - gsd.y).abs() < 1e-12 * gsd.y,
                format!("pixels of {}×{}, the first piece's {}×{}", g.transform[1], -g.transform[5], gsd.x, gsd.y),
            ),
            (g.keys == geo0.keys, "another CRS than the first piece's".to_string()),
            (same_nodata(g.nodata, geo0.nodata), format!("nodata {:?}, the first piece's {:?}", g.nodata, geo0.nodata)),
        ]
        .into_iter()
        .find(|(same, _)| !same);
        // Pieces that are not of one orthophoto are a fault of the set
        // given (as a gap or an overlap is): one wording, one exit code.
        let not_one = |how: String| Error::Usage(format!("{} is not a piece of the same orthophoto as {}: {how}", p.display(), pieces[0].display()));
        if let Some((_, how)) = differs {
            return Err(not_one(how));
        }
        // Made from the same image, camera, DEM and settings (a piece of
        // another run on the same grid would join without a seam to see).
        if g.source.as_deref().map(crate::io::geotiff::without_layout) != geo0.source.as_deref().map(crate::io::geotiff::without_layout) {
            return Err(not_one("made from other inputs or settings (image, camera, DEM, resampling; a mosaic's seams, balance or blend…)".into()));
        }
        // And for a whole of one layout, unless this run says which: else
        // the first piece named would choose it.
        let layout = |g: &crate::io::geotiff::GeoRef| g.source.as_deref().and_then(crate::io::geotiff::whole_layout).map_or((None, None, None), read_layout);
        let ((o, r, c), (o0, r0, c0)) = (layout(g), layout(&geo0));
        let unsaid = [
            (opts.overviews.is_none() && o != o0, "overviews"),
            (opts.overview_resampling.is_none() && r != r0, "overview resampling"),
            (opts.cog.is_none() && c != c0, "Cloud-Optimized layout"),
        ];
        if let Some((_, what)) = unsaid.iter().find(|(differs, _)| *differs) {
            return Err(not_one(format!(
                "its run asked for another {what} of the whole; say which to assemble (‹cog›, ‹overviews›, ‹overview_resampling›), or join pieces made alike"
            )));
        }
        x_min = x_min.min(g.transform[0]);
        y_max = y_max.max(g.transform[3]);
    }
    let tile_m = gsd.scaled(tile as f64);
    // (piece, tile column and row offset in the whole)
    let mut place = Vec::new();
    let (mut w, mut h) = (0u32, 0u32);
    for (k, s) in srcs.iter().enumerate() {
        let g = s.info.georef.as_ref().expect("checked");
        let (fc, fr) = ((g.transform[0] - x_min) / tile_m.x, (y_max - g.transform[3]) / tile_m.y);
        if (fc - fc.round()).abs() > 1e-6 || (fr - fr.round()).abs() > 1e-6 {
            return Err(Error::format(&pieces[k], "does not start on the tile grid of the others"));
        }
        let (tc, tr) = (fc.round() as u32, fr.round() as u32);
        w = w.max(tc * tile + s.info.width);
        h = h.max(tr * tile + s.info.height);
        place.push((tc, tr));
    }
    let (ta, td) = (w.div_ceil(tile), h.div_ceil(tile));
    // Which piece holds each tile of the whole.
    let mut owner: Vec<Option<(usize, usize)>> = vec![None; (ta * td) as usize];
    for (k, s) in srcs.iter().enumerate() {
        let (tc, tr) = place[k];
        let (pa, pd) = (s.info.width.div_ceil(tile), s.info.height.div_ceil(tile));
        // A piece's partial edge tiles must be edges of the whole.
        if (s.info.width % tile != 0 && tc * tile + s.info.width != w) || (s.info.height % tile != 0 && tr * tile + s.info.height != h) {
            return Err(Error::format(&pieces[k], "ends inside the whole but not on a tile boundary"));
        }
        for r in 0..pd {
            for c in 0..pa {
                let slot = &mut owner[((tr + r) * ta + tc + c) as usize];
                if let Some((other, _)) = *slot {
                    // Like a gap, a fault of the pieces given, not of a file.
                    let same = std::fs::canonicalize(&pieces[other]).ok().is_some_and(|a| std::fs::canonicalize(&pieces[k]).ok() == Some(a));
                    return Err(Error::Usage(match same {
                        true => format!("{} is given twice", pieces[k].display()),
                        false => format!("{} and {} both cover tile ({}, {}) of the whole", pieces[other].display(), pieces[k].display(), tc + c, tr + r),
                    }));
                }
                *slot = Some((k, (r * pa + c) as usize));
            }
        }
    }
    if let Some(missing) = owner.iter().position(Option::is_none) {
        let gaps = owner.iter().filter(|o| o.is_none()).count();
        return Err(Error::Usage(format!(
            "no piece covers tile ({}, {}) of the whole's {ta}×{} tiles ({gaps} tiles uncovered): a piece is missing",
            missing as u32 % ta,
            missing as u32 / ta,
            owner.len() as u32 / ta
        )));
    }
    // Pieces name the whole they are pieces of: a set that leaves out its
    // edge (a last shard that failed) would make a smaller file, not a gap.
    let (key, whole) = match geo0.source.as_deref() {
        Some(s) => crate::io::geotiff::whole_of(s),
        None => ("", None),
    };
    if let (Some((ww, wh, wx0, wy0)), false) = (whole, opts.partial) {
        let at_origin = (x_min - wx0).abs() <= 1e-6 * gsd.x && (y_max - wy0).abs() <= 1e-6 * gsd.y;
        if !at_origin || (w, h) != (ww, wh) {
            let (c0, r0) = (((x_min - wx0) / tile_m.x).round() as i64, ((wy0 - y_max) / tile_m.y).round() as i64);
            return Err(Error::Usage(format!(
                "the pieces make tiles {c0}..{} across and {r0}..{} down of a whole of {} × {} tiles ({ww} × {wh} px): pieces at its edges are missing",
                c0 + ta as i64,
                r0 + td as i64,
                ww.div_ceil(tile),
                wh.div_ceil(tile)
            )));
        }
    }
    let source = if opts.partial || whole.is_none() { geo0.source.clone() } else { Some(key.to_string()) };
    let compression = match first.compression {
        1 => Compression::None,
        5 => Compression::Lzw,
        8 => Compression::Deflate,
        50000 => Compression::Zstd,
        7 => Compression::Jpeg,
        c => return Err(Error::unsupported(&pieces[0], format!("compression {c} in pieces"))),
    };
    let pieces_codec = compression;
    let compression = opts.compress.unwrap_or(compression);
    let recode = compression != pieces_codec;
    let mut level = codec_level(compression, opts.level, opts.quality)?;
    // JPEG pieces' chunks are abbreviated streams: they keep their pieces'
    // tables (all alike), and the overviews are coded at the pieces'
    // quality unless another is asked for.
    let tables = match compression {
        Compression::Jpeg if !recode => {
            let t = first.jpeg_tables.clone().ok_or_else(|| Error::format(&pieces[0], "JPEG chunks without their JPEGTables"))?;
            if let Some(k) = srcs.iter().position(|s| s.info.jpeg_tables.as_ref() != Some(&t)) {
                // Like other settings, a fault of the pieces given.
                return Err(Error::Usage(format!(
                    "{} is coded with other JPEG tables (another quality) than {}: not pieces of one file",
                    pieces[k].display(),
                    pieces[0].display()
                )));
            }
            Some(t)
        }
        _ => None,
    };
    let mut spec = OutputSpec {
        width: w,
        height: h,
        bands: first.bands,
        sample: first.sample,
        chunking: Chunking::Tiles(tile),
        compression,
        level,
        overview_level: overview_codec_level(compression, opts.overview_level)?,
        bigtiff: false,
        photometric: first.photometric,
        alpha: first.has_alpha,
        mask: first.mask.is_some(),
        geo: Some(GeoTags { x0: x_min, y0: y_max, gsd, keys: geo0.keys.clone(), nodata: geo0.nodata }),
        overviews: 0,
        cog: false,
    };
    if let (Some(t), None) = (&tables, level) {
        level = crate::io::tiff_out::jpeg_quality_of(&spec, t);
        spec.level = level;
    }
    if recode {
        spec.check_codec().map_err(|m| Error::Usage(format!("‹compress›: {m}")))?;
    }
    // What the user does not say, as the pieces' run had it.
    let (o, r, c) = geo0.source.as_deref().and_then(crate::io::geotiff::whole_layout).map_or((None, None, None), read_layout);
    let (overviews, resampling) = (opts.overviews.or(o).unwrap_or_default(), opts.overview_resampling.or(r).unwrap_or_default());
    spec.cog = opts.cog.or(c).unwrap_or(false);
    spec.overviews = overviews.levels(w, h, tile);
    spec.bigtiff = opts.bigtiff.unwrap_or_else(|| spec.needs_bigtiff());
    let by = ValidBy::of(&spec);
    let mut pyramid = Pyramid::new(&spec, resampling, by, opts.fill.or(geo0.nodata).unwrap_or(0.0));
    let files: Vec<std::fs::File> = pieces.iter().map(|p| std::fs::File::open(p).map_err(|e| Error::io(p, e))).collect::<Result<_>>()?;
    let pending = PendingFile::create(out)?;
    let mut writer = TileWriter::new(pending.file()?, &spec, &folder_of(out)).map_err(|e| Error::io(pending.path(), e))?;
    if let Some(t) = tables {
        writer.full_level_jpeg_tables(t);
    }
    let tw = |e| tiff_write_error(pending.path(), e);
    let mask_compression = |k: usize| srcs[k].info.mask_compression;
    let mut statistics = ByTileRow::default();
    // A row of tiles at a time: each tile's stored bytes (and its mask's)
    // read, and under overviews its pixels decoded and reduced, in parallel.
    for row in 0..td {
        if cancel.is_cancelled() {
            return Err(Error::Cancelled);
        }
        let tiles: Vec<Result<StoredTile>> = (0..ta)
            .into_par_iter()
            .map(|col| {
                let (k, t) = owner[(row * ta + col) as usize].expect("every tile owned");
                let read = |o: u64, c: u64| -> Result<Vec<u8>> {
                    let mut buf = vec![0u8; c as usize];
                    files[k].read_exact_at(&mut buf, o).map_err(|e| Error::io(&pieces[k], e))?;
                    Ok(buf)
                };
                let (offs, counts) = srcs[k].info.chunk_table();
                let image = read(offs[t], counts[t])?;
                let mask = match &srcs[k].info.mask {
                    Some((o, c)) => Some(read(o[t], c[t])?),
                    None => None,
                };
                // Decoded for the statistics and the overviews.
                let valid = match &mask {
                    Some(m) => Some(decode_mask(m, mask_compression(k), tile as usize, tile as usize).map_err(|e| Error::format(&pieces[k], e))?),
                    None => None,
                };
                let pixels = tile_pixels(&srcs[k], &spec, t)?;
                // Coded anew: as a run writing this codec codes them.
                let (image, mask) = match (recode, &valid) {
                    (false, _) => (image, mask),
                    (true, v) => (encode_tile(&spec, 0, pixels.clone(), v.as_deref())?, v.as_deref().map(|v| encode_mask(&spec, v)).transpose()?),
                };
                let stats = Statistics::of_output_tile(&spec, by, &pixels, valid.as_deref(), spec.tile_extent(0, (row * ta + col) as usize));
                let quarter = pyramid.as_ref().map(|p| p.reduce(0, (row * ta + col) as usize, &pixels, valid.as_deref()));
                Ok((image, mask, quarter, stats))
            })
            .collect();
        let mut finished = Vec::new();
        for (col, t) in tiles.into_iter().enumerate() {
            let (image, mask, quarter, stats) = t?;
            statistics.add(row as usize, &stats);
            let k = (row * ta) as usize + col;
            writer.put(k, &image).map_err(tw)?;
            if let Some(m) = mask {
                writer.put(spec.mask_tile(k), &m).map_err(tw)?;
            }
            if let (Some(p), Some(q)) = (pyramid.as_mut(), quarter) {
                finished.extend(p.place(0, k, q));
            }
        }
        if let Some(p) = pyramid.as_mut() {
            let mut made = Vec::new();
            p.cascade(
                finished,
                |t| (encode_tile(&spec, t.level, t.pixels, Some(&t.valid)), spec.mask.then(|| encode_mask(&spec, &t.valid))),
                |l, k, r| made.push((l, k, r)),
            );
            for (l, k, (image, mask)) in made {
                writer.put(spec.chunk_index(l, k, false), &image?).map_err(tw)?;
                if let Some(m) = mask {
                    writer.put(spec.chunk_index(l, k, true), &m?).map_err(tw)?;
                }
            }
        }
    }
    writer.finish(statistics.total().gdal_metadata(source.as_deref())).map_err(tw)?;
    verify(pending.path(), &spec)?;
    pending.publish_synced(opts.sync)
}

/// Do two pieces say "no value" alike? (NaN is, to them, NaN.)
fn same_nodata(a: Option<f64>, b: Option<f64>) -> bool {
    match (a, b) {
        (Some(x), Some(y)) => x == y || (x.is_nan() && y.is_nan()),
        (a, b) => a.is_none() && b.is_none(),
    }
}

/// A tile's stored bytes, its mask's, its quarter for the overview and its
/// statistics.
type StoredTile = (Vec<u8>, Option<Vec<u8>>, Option<Quarter>, Statistics);

/// Tile `t` of a piece, decoded: a whole tile of `spec`'s, the part beyond
/// the piece's edge zero.
fn tile_pixels(src: &SourceImage, spec: &OutputSpec, t: usize) -> Result<Vec<u8>> {
    let tile = spec.chunk().0;
    let across = src.info.width.div_ceil(tile) as usize;
    let (x0, y0) = ((t % across) as u32 * tile, (t / across) as u32 * tile);
    let (w, h) = ((src.info.width - x0).min(tile), (src.info.height - y0).min(tile));
    let mut win = Window::default();
    src.read_window(x0, y0, w, h, &mut win)?;
    let px = spec.bands as usize * spec.sample.bytes();
    if (w, h) == (tile, tile) {
        return Ok(win.bytes().to_vec());
    }
    let mut pixels = vec![0u8; spec.tile_bytes()];
    for (y, row) in win.bytes().chunks_exact(w as usize * px).enumerate() {
        pixels[y * tile as usize * px..][..row.len()].copy_from_slice(row);
    }
    Ok(pixels)
}
