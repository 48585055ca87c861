//! A LAZ file's point count held against its chunk table, before the
//! `las` crate opens it: the decoder reserves the table's entries as the
//! file counts them (a count of 4·10⁹ chunks aborted the process asking
//! for 64 GB), and a header counting fewer points than the chunks hold
//! had the rest dropped unsaid (more: a bare "failed to fill whole
//! buffer" at the end).

use crate::error::{Error, Result};
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

/// What the LAS header says of where and how many points there are.
struct Header {
    points: u64,
    /// Bytes a point record takes.
    record: u16,
    data_start: u64,
    /// The laszip VLR's data, if the points are compressed.
    laszip: Option<Vec<u8>>,
}

fn header(f: &mut std::fs::File) -> std::io::Result<Option<Header>> {
    let mut h = [0u8; 375];
    let n = f.read(&mut h)?;
    if n < 227 || &h[..4] != b"LASF" {
        // (Not LAS: the `las` crate says so.)
        return Ok(None);
    }
    let u16_at = |i: usize| u16::from_le_bytes([h[i], h[i + 1]]);
    let u32_at = |i: usize| u32::from_le_bytes(h[i..i + 4].try_into().expect("4 bytes"));
    let (header_size, data_start, vlrs, format, record) = (u16_at(94) as u64, u32_at(96) as u64, u32_at(100), h[104], u16_at(105));
    let legacy = u32_at(107) as u64;
    let points = match h[25] >= 4 && n >= 255 {
        true => Some(u64::from_le_bytes(h[247..255].try_into().expect("8 bytes"))).filter(|&p| p != 0).unwrap_or(legacy),
        false => legacy,
    };
    // Bit 7 of the point format marks compressed points (LASzip).
    if format & 0x80 == 0 {
        return Ok(Some(Header { points, record, data_start, laszip: None }));
    }
    // The records follow the header as the version sizes it, or the
    // header's own size where that is larger (the `las` crate reads them
    // there: a smaller size field must not send this scan elsewhere).
    let version_size = match (h[24], h[25]) {
        (1, 0..=2) | (0, _) => 227,
        (1, 3) => 235,
        _ => 375,
    };
    let mut at = header_size.max(version_size);
    let mut laszip = None;
    for _ in 0..vlrs.min(10_000) {
        let mut v = [0u8; 54];
        f.seek(SeekFrom::Start(at))?;
        if f.read_exact(&mut v).is_err() {
            break;
        }
        let len = u16::from_le_bytes([v[20], v[21]]) as u64;
        if v[2..18].starts_with(b"laszip encoded") && u16::from_le_bytes([v[18], v[19]]) == 22204 {
            let mut data = vec![0u8; len as usize];
            f.read_exact(&mut data)?;
            laszip = Some(data);
            break;
        }
        at += 54 + len;
    }
    Ok(Some(Header { points, record, data_start, laszip }))
}

/// Refuses a LAZ file whose header counts other than the points its
/// chunks hold, or whose chunk table counts more chunks than its bytes
/// can hold; passes anything else to the `las` crate's own checks.
pub fn check(path: &Path) -> Result<()> {
    let io = |e: std::io::Error| Error::io(path, e);
    let mut f = std::fs::File::open(path).map_err(io)?;
    let len = f.metadata().map_err(io)?.len();
    let Some(h) = header(&mut f).map_err(io)? else { return Ok(()) };
    let Some(vlr_bytes) = h.laszip else { return Ok(()) };
    let Ok(vlr) = laz::LazVlr::from_buffer(&vlr_bytes) else { return Ok(()) };
    let bad = |msg: String| Err(Error::Format { path: path.into(), msg });
    // (The decoder takes the first item for granted: a panic without one.)
    if vlr.items().is_empty() {
        return bad("its LASzip record lists no fields of a point".into());
    }
    // (It decodes the fields into a record of the header's size: a panic
    // where they take more.)
    if vlr.items_size() != u64::from(h.record) {
        return bad(format!("its LASzip record's fields take {} bytes a point, its header's records {}", vlr.items_size(), h.record));
    }
    // Compressor 1: one chunk of every point, no table.
    if u16::from_le_bytes([vlr_bytes[0], vlr_bytes[1]]) < 2 {
        return Ok(());
    }
    // The table's place: the first 8 bytes of the point data, or (where
    // the writer could not go back to them) the file's last 8.
    let mut word = [0u8; 8];
    f.seek(SeekFrom::Start(h.data_start)).map_err(io)?;
    if f.read_exact(&mut word).is_err() {
        return bad("the file ends before its point data".into());
    }
    let mut table = i64::from_le_bytes(word);
    if table <= h.data_start as i64 && len >= 8 {
        f.seek(SeekFrom::End(-8)).map_err(io)?;
        f.read_exact(&mut word).map_err(io)?;
        table = i64::from_le_bytes(word);
    }
    let Some(table) = u64::try_from(table).ok().filter(|&t| t > h.data_start + 8 && t + 8 <= len) else {
        // No table found: the decoder reads chunk by chunk (fixed sizes)
        // or refuses (variable ones).
        return Ok(());
    };
    f.seek(SeekFrom::Start(table + 4)).map_err(io)?;
    let mut count = [0u8; 4];
    f.read_exact(&mut count).map_err(io)?;
    let chunks = u32::from_le_bytes(count) as u64;
    // Each chunk takes bytes of its own between the table's place and the table.
    let room = table - h.data_start - 8;
    if chunks > room {
        return bad(format!("its chunk table counts {chunks} chunks, more than the {room} bytes of its point data hold"));
    }
    let (least, most) = if vlr.uses_variable_size_chunks() {
        f.seek(SeekFrom::Start(table)).map_err(io)?;
        let entries = laz::laszip::ChunkTable::read(&mut std::io::BufReader::new(&mut f), true)
            .map_err(|e| Error::Format { path: path.into(), msg: format!("its chunk table does not read: {e}") })?;
        let sum = entries.as_ref().iter().try_fold(0u64, |s, e| s.checked_add(e.point_count)).unwrap_or(u64::MAX);
        (sum, sum)
    } else {
        let size = vlr.chunk_size() as u64;
        (chunks.saturating_sub(1) * size + u64::from(chunks > 0), chunks * size)
    };
    if h.points < least || h.points > most {
        let held = if least == most { format!("{least}") } else { format!("{least} to {most}") };
        return bad(format!("the header counts {} points, but its {chunks} compressed chunks hold {held}", h.points));
    }
    Ok(())
}
