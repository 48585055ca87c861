//! What an output is made from, as a key: its inputs by their contents (or
//! their path, size and time) and the settings that change its pixels. The
//! key is written into every output ("made from"), so that pieces of one
//! whole are known by it, and kept beside finished batch outputs.

use crate::options::{DemSource, RectifyOptions};
use std::path::{Path, PathBuf};

/// A 64-bit FNV-1a hash: stable across runs and machines.
pub(crate) fn fnv(h: &mut u64, bytes: &[u8]) {
    for b in bytes {
        *h ^= *b as u64;
        *h = h.wrapping_mul(0x100_0000_01b3);
    }
}

pub(crate) fn file_stamp(h: &mut u64, p: &Path) {
    fnv(h, p.as_os_str().as_encoded_bytes());
    if let Ok(m) = std::fs::metadata(p) {
        fnv(h, &m.len().to_le_bytes());
        if let Ok(t) = m.modified().and_then(|t| t.duration_since(std::time::UNIX_EPOCH).map_err(std::io::Error::other)) {
            fnv(h, &t.as_nanos().to_le_bytes());
        }
    }
}

/// A file as its contents tell it: its size and three samples of
/// [`CONTENT_SAMPLE`] bytes (start, middle, end), so that a copy, a moved
/// or touched file, or one reached by another path matches, and another
/// image, DEM or camera does not.
fn content_stamp(h: &mut u64, p: &Path) {
    use std::io::{Read, Seek, SeekFrom};
    let Ok(mut f) = std::fs::File::open(p) else { return fnv(h, p.as_os_str().as_encoded_bytes()) };
    let len = f.metadata().map_or(0, |m| m.len());
    fnv(h, &len.to_le_bytes());
    let n = CONTENT_SAMPLE.min(len);
    let mut buf = vec![0u8; n as usize];
    for at in [0, (len - n) / 2, len - n] {
        if f.seek(SeekFrom::Start(at)).is_ok() && f.read_exact(&mut buf).is_ok() {
            fnv(h, &buf);
        }
    }
}

/// Bytes of each of a file's samples in [`content_stamp`].
const CONTENT_SAMPLE: u64 = 64 << 10;

/// What an orthophoto is made from, the same for each of its pieces and
/// whatever layout they are put together in: its inputs by their contents
/// (not their paths or times: pieces made on nodes that staged the inputs
/// elsewhere join), and every setting of the batch's job key but the piece
/// (window), the file's name and layout (codec, overviews,
/// Cloud-Optimized, BigTIFF, band order) and how the run was resourced.
pub fn source_key(c: &RectifyOptions) -> String {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut whole = c.clone();
    for (_, input) in c.inputs() {
        content_stamp(&mut h, &input);
    }
    if let Some(f) = c.model.inline() {
        fnv(&mut h, f.to_toml().as_bytes());
    }
    // The inputs' paths out of the settings.
    whole.image = PathBuf::new();
    whole.camera = PathBuf::new();
    whole.like = None;
    if let DemSource::File(p) = &mut whole.dem {
        *p = PathBuf::new();
    }
    if let Some(g) = &mut whole.gcps {
        g.file = PathBuf::new();
    }
    match &mut whole.model {
        crate::options::ModelSource::WithPoses { poses, .. } => *poses = PathBuf::new(),
        crate::options::ModelSource::Rpc { geoid: Some(g), .. } => *g = PathBuf::new(),
        _ => {}
    }
    whole.output = std::path::PathBuf::new();
    whole.window = None;
    whole.overviews = crate::options::Overviews::Auto;
    whole.overview_level = None;
    // The codec is the file's, not what its pixels are made from: lossless
    // pieces coded anew by `assemble --compress` make the single run's file.
    whole.compress = crate::io::tiff_out::Compression::Deflate;
    whole.level = None;
    whole.quality = None;
    whole.overview_resampling = crate::overview::OverviewResampling::Average;
    whole.cog = false;
    whole.bigtiff = crate::options::BigTiff::Auto;
    whole.band_order = crate::options::BandOrder::Auto;
    whole.max_output_pixels = None;
    whole.sync = true;
    whole.threads = 0;
    whole.memory = 0;
    fnv(&mut h, serde_json::to_string(&whole).unwrap_or_default().as_bytes());
    format!("{h:016x}")
}

/// A key over byte strings and files (path, size, modification time).
pub fn key_of(bytes: &[&[u8]], files: &[&Path]) -> String {
    keyed(bytes, files, file_stamp)
}

/// [`key_of`] with the files told by their contents, not their paths or
/// times (see [`source_key`]).
pub fn content_key_of(bytes: &[&[u8]], files: &[&Path]) -> String {
    keyed(bytes, files, content_stamp)
}

fn keyed(bytes: &[&[u8]], files: &[&Path], stamp: fn(&mut u64, &Path)) -> String {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for b in bytes {
        fnv(&mut h, &(b.len() as u64).to_le_bytes());
        fnv(&mut h, b);
    }
    for f in files {
        stamp(&mut h, f);
    }
    format!("{h:016x}")
}
