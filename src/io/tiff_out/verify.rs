//! The written file read back before it is published: its directory and
//! tile tables must say what was meant to be written.

use super::{Chunking, OutputSpec};
use crate::error::{Error, Result};
use std::path::Path;
use tiff::tags::Tag;

/// Re-reads a written file's directory and checks its tile tables against
/// the spec and the file length, so that a writer bug never publishes a
/// broken file.
pub fn verify(path: &Path, spec: &OutputSpec) -> Result<()> {
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let len = f.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut dec =
        tiff::decoder::Decoder::new(std::io::BufReader::new(f)).map_err(|e| Error::from_tiff(path, e))?.with_limits(crate::io::format::decoder_limits());
    let bad = |m: String| Error::format(path, format!("written file failed verification: {m}"));
    let (w, h) = dec.dimensions().map_err(|e| Error::from_tiff(path, e))?;
    if (w, h) != (spec.width, spec.height) {
        return Err(bad(format!("size {w}×{h}")));
    }
    let (ot, ct) = match spec.chunking {
        Chunking::Tiles(_) => (Tag::TileOffsets, Tag::TileByteCounts),
        Chunking::Strips(_) => (Tag::StripOffsets, Tag::StripByteCounts),
    };
    let offsets = dec.get_tag_u64_vec(ot).map_err(|e| Error::from_tiff(path, e))?;
    let counts = dec.get_tag_u64_vec(ct).map_err(|e| Error::from_tiff(path, e))?;
    let n = (spec.tiles_across() * spec.tiles_down()) as usize;
    if offsets.len() != n || counts.len() != n {
        return Err(bad(format!("{} tiles, expected {n}", offsets.len())));
    }
    if let Some(k) = offsets.iter().zip(&counts).position(|(&o, &c)| c == 0 || o + c > len) {
        return Err(bad(format!("tile {k} lies outside the file")));
    }
    Ok(())
}
