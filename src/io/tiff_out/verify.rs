//! The written file read back before it is published: its directories and
//! tile tables must say what was meant to be written.

use super::{Chunking, OutputSpec};
use crate::error::{Error, Result};
use std::path::Path;
use tiff::tags::Tag;

/// Re-reads a written file's directories (each level's and its mask's)
/// and checks their sizes, kinds and tile tables against the spec and the
/// file length, so that a writer bug never publishes a broken file.
pub fn verify(path: &Path, spec: &OutputSpec) -> Result<()> {
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let len = f.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut dec =
        tiff::decoder::Decoder::new(std::io::BufReader::new(f)).map_err(|e| Error::from_tiff(path, e))?.with_limits(crate::io::format::decoder_limits());
    let bad = |m: String| Error::format(path, format!("written file failed verification: {m}"));
    let tf = |e| Error::from_tiff(path, e);
    let mut first = true;
    for l in 0..=spec.overviews {
        for mask in [false, true] {
            if mask && !spec.mask {
                continue;
            }
            if !std::mem::take(&mut first) {
                if !dec.more_images() {
                    return Err(bad(format!("no directory for level {l}{}", if mask { "'s mask" } else { "" })));
                }
                dec.next_image().map_err(tf)?;
            }
            let kind = dec.find_tag_unsigned::<u32>(Tag::NewSubfileType).map_err(tf)?.unwrap_or(0);
            let want = u32::from(l > 0) | if mask { 4 } else { 0 };
            if kind != want {
                return Err(bad(format!("level {l}: NewSubfileType {kind}, not {want}")));
            }
            check_directory(&mut dec, spec, l, len, path).map_err(|m| bad(format!("level {l}{}: {m}", if mask { " mask" } else { "" })))?;
        }
    }
    if dec.more_images() {
        return Err(bad("more directories than levels".into()));
    }
    Ok(())
}

/// The current directory's size and chunk table against level `l` of `spec`.
fn check_directory(
    dec: &mut tiff::decoder::Decoder<std::io::BufReader<std::fs::File>>,
    spec: &OutputSpec,
    l: u32,
    len: u64,
    path: &Path,
) -> std::result::Result<(), String> {
    let tf = |e| Error::from_tiff(path, e).to_string();
    let (w, h) = dec.dimensions().map_err(tf)?;
    if (w, h) != spec.level_size(l) {
        return Err(format!("size {w}×{h}"));
    }
    let (ot, ct) = match spec.chunking {
        Chunking::Tiles(_) => (Tag::TileOffsets, Tag::TileByteCounts),
        Chunking::Strips(_) => (Tag::StripOffsets, Tag::StripByteCounts),
    };
    let offsets = dec.get_tag_u64_vec(ot).map_err(tf)?;
    let counts = dec.get_tag_u64_vec(ct).map_err(tf)?;
    let n = spec.level_tile_count(l);
    if offsets.len() != n || counts.len() != n {
        return Err(format!("{} tiles, expected {n}", offsets.len()));
    }
    if let Some(k) = offsets.iter().zip(&counts).position(|(&o, &c)| c == 0 || o + c > len) {
        return Err(format!("tile {k} lies outside the file"));
    }
    Ok(())
}
