//! Putting pieces made with `rectify --window` back together: the pieces
//! share the whole run's tile grid, so their compressed tiles (and their
//! internal masks' tiles) are copied into one tiled GeoTIFF as they are —
//! no decoding, no seam, the same pixels as a single run.

use crate::error::{Error, Result};
use crate::io::overwrite::{check_outputs, check_writable, Role};
use crate::io::source::SourceImage;
use crate::io::tiff_out::{tiff_write_error, verify, write_placed, Chunking, Compression, GeoTags, OutputSpec, PendingFile, WriteError};
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

/// Assembles `pieces` into `out`. Every tile of the union must come from
/// exactly one piece.
pub fn assemble(pieces: &[PathBuf], out: &Path) -> Result<()> {
    if pieces.is_empty() {
        return Err(Error::Usage("assemble needs at least one piece".into()));
    }
    let ins: Vec<Role> = pieces.iter().map(|p| Role::new("piece", p)).collect();
    check_writable(Role::new("output", out))?;
    check_outputs(&ins, &[Role::new("output", out)])?;
    let srcs: Vec<SourceImage> = pieces.iter().map(|p| SourceImage::open(p, 1 << 20)).collect::<Result<_>>()?;
    let first = &srcs[0].info;
    let geo0 = first.georef.clone().ok_or_else(|| Error::format(&pieces[0], "has no georeferencing"))?;
    let gsd = geo0.transform[1];
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
        let same = i.tiled
            && i.chunk == first.chunk
            && i.bands == first.bands
            && i.sample == first.sample
            && i.compression == first.compression
            && i.predictor == first.predictor
            && i.photometric == first.photometric
            && i.has_alpha == first.has_alpha
            && i.mask.is_some() == first.mask.is_some()
            && (g.transform[1] - gsd).abs() < 1e-12 * gsd
            && g.epsg == geo0.epsg
            && g.nodata == geo0.nodata;
        if !same {
            return Err(Error::format(p, format!("is not a piece of the same orthophoto as {}", pieces[0].display())));
        }
        x_min = x_min.min(g.transform[0]);
        y_max = y_max.max(g.transform[3]);
    }
    let tile_m = tile as f64 * gsd;
    // (piece, tile column and row offset in the whole)
    let mut place = Vec::new();
    let (mut w, mut h) = (0u32, 0u32);
    for (k, s) in srcs.iter().enumerate() {
        let g = s.info.georef.as_ref().expect("checked");
        let (fc, fr) = ((g.transform[0] - x_min) / tile_m, (y_max - g.transform[3]) / tile_m);
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
                if slot.is_some() {
                    return Err(Error::format(&pieces[k], format!("overlaps another piece at tile ({}, {})", tc + c, tr + r)));
                }
                *slot = Some((k, (r * pa + c) as usize));
            }
        }
    }
    if let Some(missing) = owner.iter().position(Option::is_none) {
        return Err(Error::Usage(format!("no piece covers tile ({}, {}) of the whole", missing as u32 % ta, missing as u32 / ta)));
    }
    let compression = match first.compression {
        1 => Compression::None,
        5 => Compression::Lzw,
        8 => Compression::Deflate,
        50000 => Compression::Zstd,
        c => return Err(Error::unsupported(&pieces[0], format!("compression {c} in pieces"))),
    };
    let mut spec = OutputSpec {
        overviews: 0,
        cog: false,
        width: w,
        height: h,
        bands: first.bands,
        sample: first.sample,
        chunking: Chunking::Tiles(tile),
        compression,
        bigtiff: false,
        photometric: first.photometric,
        alpha: first.has_alpha,
        mask: first.mask.is_some(),
        geo: Some(GeoTags { x0: x_min, y0: y_max, gsd, epsg: geo0.epsg.unwrap_or(0), nodata: geo0.nodata }),
    };
    spec.bigtiff = spec.needs_bigtiff();
    let files: Vec<std::fs::File> = pieces.iter().map(|p| std::fs::File::open(p).map_err(|e| Error::io(p, e))).collect::<Result<_>>()?;
    let pending = PendingFile::create(out)?;
    let mut next = 0usize;
    let r = write_placed(pending.file()?, &spec, &crate::io::tiff_out::folder_of(out), || -> Result<Option<(usize, Vec<u8>)>> {
        // Each tile of the image, then its mask's (where the pieces have
        // one), as a single run writes them.
        let per_tile = if spec.mask { 2 } else { 1 };
        let (tile, of_mask) = (next / per_tile, next % per_tile == 1);
        let Some(Some((k, t))) = owner.get(tile).copied() else { return Ok(None) };
        next += 1;
        let at = if of_mask { spec.mask_tile(tile) } else { tile };
        let (offs, counts) = match (&srcs[k].info.mask, of_mask) {
            (Some((o, c)), true) => (&o[..], &c[..]),
            _ => srcs[k].info.chunk_table(),
        };
        let mut buf = vec![0u8; counts[t] as usize];
        files[k].read_exact_at(&mut buf, offs[t]).map_err(|e| Error::io(&pieces[k], e))?;
        Ok(Some((at, buf)))
    });
    match r {
        Ok(()) => {}
        Err(WriteError::Source(e)) => return Err(e),
        Err(WriteError::Tiff(e)) => return Err(tiff_write_error(out, e)),
    }
    verify(pending.path(), &spec)?;
    pending.publish()
}
