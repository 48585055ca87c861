//! TIFF directories as bytes, laid out by us rather than by an encoder:
//! a Cloud-Optimized file needs every directory *before* the tiles, at
//! offsets fixed before any tile's place is known, and a directory's
//! out-of-line values *after* its entries (GDAL's validator wants the first
//! directory right behind the header). A directory's size does not depend
//! on the values of its offsets, so it can be measured first and filled in
//! later.

use std::collections::BTreeMap;

/// A tag's values, in the TIFF field type they are written as.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    Short(Vec<u16>),
    Long(Vec<u32>),
    /// Offsets and byte counts: LONG in classic TIFF, LONG8 in BigTIFF.
    Offsets(Vec<u64>),
    Double(Vec<f64>),
    Ascii(String),
    /// Bytes of no stated kind (JPEGTables).
    Undefined(Vec<u8>),
}

impl Value {
    /// (field type, count, bytes of one value).
    fn kind(&self, big: bool) -> (u16, u64, usize) {
        match self {
            Value::Short(v) => (3, v.len() as u64, 2),
            Value::Long(v) => (4, v.len() as u64, 4),
            Value::Offsets(v) if big => (16, v.len() as u64, 8),
            Value::Offsets(v) => (4, v.len() as u64, 4),
            Value::Double(v) => (12, v.len() as u64, 8),
            Value::Ascii(s) => (2, s.len() as u64 + 1, 1),
            Value::Undefined(v) => (7, v.len() as u64, 1),
        }
    }

    fn bytes(&self, big: bool) -> Vec<u8> {
        match self {
            Value::Short(v) => v.iter().flat_map(|x| x.to_ne_bytes()).collect(),
            Value::Long(v) => v.iter().flat_map(|x| x.to_ne_bytes()).collect(),
            Value::Offsets(v) if big => v.iter().flat_map(|x| x.to_ne_bytes()).collect(),
            Value::Offsets(v) => v.iter().flat_map(|&x| (x as u32).to_ne_bytes()).collect(),
            Value::Double(v) => v.iter().flat_map(|x| x.to_ne_bytes()).collect(),
            Value::Ascii(s) => s.bytes().chain([0]).collect(),
            Value::Undefined(v) => v.clone(),
        }
    }
}

/// One image file directory: its entries by tag.
#[derive(Clone, Debug, Default)]
pub struct Ifd {
    entries: BTreeMap<u16, Value>,
}

impl Ifd {
    pub fn set(&mut self, tag: u16, value: Value) {
        self.entries.insert(tag, value);
    }

    /// Bytes of the entries (with the count and the next directory's offset).
    fn table_len(&self, big: bool) -> u64 {
        let (count, entry, next) = if big { (8, 20, 8) } else { (2, 12, 4) };
        count + entry * self.entries.len() as u64 + next
    }

    /// Bytes the directory takes with its out-of-line values (each starting
    /// on an even byte), written at an even offset.
    pub fn len(&self, big: bool) -> u64 {
        let inline = if big { 8 } else { 4 };
        let values: u64 = self
            .entries
            .values()
            .map(|v| {
                let (_, n, size) = v.kind(big);
                let b = n * size as u64;
                if b > inline {
                    b + b % 2
                } else {
                    0
                }
            })
            .sum();
        self.table_len(big) + values
    }

    /// The directory as it lies at `at` (even), its out-of-line values right
    /// after its entries; `next` is the next directory's offset (0: none).
    /// Exactly [`Ifd::len`] bytes.
    pub fn encode(&self, at: u64, next: u64, big: bool) -> Vec<u8> {
        assert!(at.is_multiple_of(2), "directories start on even bytes");
        let inline = if big { 8 } else { 4 };
        let mut table = Vec::with_capacity(self.table_len(big) as usize);
        let mut values = Vec::new();
        let mut far = at + self.table_len(big);
        let put = |to: &mut Vec<u8>, x: u64| {
            if big {
                to.extend_from_slice(&x.to_ne_bytes());
            } else {
                to.extend_from_slice(&(x as u32).to_ne_bytes());
            }
        };
        if big {
            table.extend_from_slice(&(self.entries.len() as u64).to_ne_bytes());
        } else {
            table.extend_from_slice(&(self.entries.len() as u16).to_ne_bytes());
        }
        for (&tag, value) in &self.entries {
            let (kind, count, _) = value.kind(big);
            let mut bytes = value.bytes(big);
            table.extend_from_slice(&tag.to_ne_bytes());
            table.extend_from_slice(&kind.to_ne_bytes());
            put(&mut table, count);
            if bytes.len() as u64 <= inline {
                bytes.resize(inline as usize, 0);
                table.extend_from_slice(&bytes);
            } else {
                put(&mut table, far);
                if bytes.len() % 2 == 1 {
                    bytes.push(0);
                }
                far += bytes.len() as u64;
                values.extend_from_slice(&bytes);
            }
        }
        put(&mut table, next);
        table.extend_from_slice(&values);
        debug_assert_eq!(table.len() as u64, self.len(big));
        table
    }
}

/// The file's header: byte order (this machine's: samples are written as
/// they lie in memory), the magic number and the first directory's offset.
pub fn header(first_ifd: u64, big: bool) -> Vec<u8> {
    let mut h = Vec::with_capacity(16);
    h.extend_from_slice(if cfg!(target_endian = "little") { b"II" } else { b"MM" });
    if big {
        h.extend_from_slice(&43u16.to_ne_bytes());
        h.extend_from_slice(&8u16.to_ne_bytes());
        h.extend_from_slice(&0u16.to_ne_bytes());
        h.extend_from_slice(&first_ifd.to_ne_bytes());
    } else {
        h.extend_from_slice(&42u16.to_ne_bytes());
        h.extend_from_slice(&(first_ifd as u32).to_ne_bytes());
    }
    h
}

/// Bytes of the header.
pub fn header_len(big: bool) -> u64 {
    if big {
        16
    } else {
        8
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tiff::tags::Tag;

    #[test]
    fn directories_chain_and_read_back_with_the_tiff_crate() {
        // Two directories after a header and some bytes, in classic TIFF and
        // BigTIFF: values inline and out of line, odd-sized ASCII.
        for big in [false, true] {
            let mut a = Ifd::default();
            a.set(256, Value::Long(vec![3]));
            a.set(257, Value::Long(vec![2]));
            a.set(258, Value::Short(vec![8, 8, 8]));
            a.set(259, Value::Short(vec![1]));
            a.set(262, Value::Short(vec![2]));
            a.set(273, Value::Offsets(vec![0, 0]));
            a.set(277, Value::Short(vec![3]));
            a.set(278, Value::Long(vec![1]));
            a.set(279, Value::Offsets(vec![9, 9]));
            a.set(33550, Value::Double(vec![0.5, 0.5, 0.0]));
            a.set(42113, Value::Ascii("-9999".into()));
            let mut b = a.clone();
            b.set(254, Value::Long(vec![1]));
            let data_at = header_len(big);
            let data: Vec<u8> = (0..18).collect();
            let a_at = data_at + 18;
            a.set(273, Value::Offsets(vec![data_at, data_at + 9]));
            let b_at = a_at + a.len(big);
            b.set(273, Value::Offsets(vec![data_at + 9, data_at]));
            let mut file = header(a_at, big);
            file.extend_from_slice(&data);
            file.extend(a.encode(a_at, b_at, big));
            file.extend(b.encode(b_at, 0, big));
            assert_eq!(file.len() as u64, b_at + b.len(big));
            let mut dec = tiff::decoder::Decoder::new(std::io::Cursor::new(&file)).unwrap();
            assert_eq!(dec.dimensions().unwrap(), (3, 2));
            let tiff::decoder::DecodingResult::U8(px) = dec.read_image().unwrap() else { panic!() };
            assert_eq!(px, data);
            assert_eq!(dec.get_tag_ascii_string(Tag::GdalNodata).unwrap(), "-9999");
            assert_eq!(dec.get_tag_f64_vec(Tag::ModelPixelScaleTag).unwrap(), [0.5, 0.5, 0.0]);
            dec.next_image().unwrap();
            assert_eq!(dec.get_tag_u32(Tag::NewSubfileType).unwrap(), 1);
            let tiff::decoder::DecodingResult::U8(px) = dec.read_image().unwrap() else { panic!() };
            assert_eq!(px[..9], data[9..]);
            assert!(!dec.more_images());
        }
    }
}
