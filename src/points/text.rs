//! Points as text: CSV with a header (`x,y,z`, `easting,northing,height`,
//! …), or XYZ without one, the fields split by commas, semicolons, tabs or
//! spaces; quoted fields (as some tools write them) unquoted; `#` comments
//! and blank lines skipped.

use super::{Columns, Point, BATCH};
use crate::error::{Error, Result};
use crate::progress::Cancel;
use std::io::BufRead;
use std::path::Path;

/// The longest line taken: a point's line is short, and a file without
/// line ends must not be read whole.
const MAX_LINE: u64 = 64 << 10;

const X_NAMES: &[&str] = &["x", "easting", "east", "e", "lon", "long", "longitude"];
const Y_NAMES: &[&str] = &["y", "northing", "north", "n", "lat", "latitude"];
const Z_NAMES: &[&str] = &["z", "height", "elevation", "elev", "alt", "altitude", "h", "hgt", "heights"];

#[derive(Clone, Copy)]
enum Split {
    By(char),
    Blanks,
}

fn fields(line: &str, split: Split) -> Vec<&str> {
    fn unquote(f: &str) -> &str {
        let f = f.trim();
        f.strip_prefix('"').and_then(|g| g.strip_suffix('"')).or_else(|| f.strip_prefix('\'').and_then(|g| g.strip_suffix('\''))).unwrap_or(f).trim()
    }
    match split {
        Split::By(c) => line.split(c).map(unquote).collect(),
        Split::Blanks => line.split_whitespace().map(unquote).collect(),
    }
}

fn split_of(line: &str) -> Split {
    [',', ';', '\t'].into_iter().find(|&c| line.contains(c)).map_or(Split::Blanks, Split::By)
}

/// The three columns' indexes from the header's names (or `columns`).
fn resolve(path: &Path, header: Option<&[&str]>, columns: &Columns) -> Result<[usize; 3]> {
    let named = |names: &[&str]| header.and_then(|h| h.iter().position(|f| names.iter().any(|n| f.eq_ignore_ascii_case(n))));
    match columns {
        Columns::Auto => match header {
            None => Ok([0, 1, 2]),
            Some(h) => match (named(X_NAMES), named(Y_NAMES), named(Z_NAMES)) {
                (Some(x), Some(y), Some(z)) => Ok([x, y, z]),
                _ => Err(Error::Format {
                    path: path.into(),
                    // Not quoted: a file that is no list of points at all
                    // (a password file given by mistake) is never shown.
                    msg: format!(
                        "its first line ({} field{}) is neither three numbers nor a header naming x, y and z columns: name them (x/easting, y/northing, z/height) or give ‹columns›",
                        h.len(),
                        if h.len() == 1 { "" } else { "s" }
                    ),
                }),
            },
        },
        Columns::Given(names) => {
            let mut out = [0; 3];
            for (k, name) in names.iter().enumerate() {
                out[k] = match name.parse::<usize>() {
                    Ok(n) if n >= 1 => n - 1,
                    Ok(_) => return Err(Error::setting("columns", "columns are counted from 1")),
                    Err(_) => named(&[name.as_str()]).ok_or_else(|| Error::Format {
                        path: path.into(),
                        msg: match header {
                            Some(h) => format!("no column '{name}' among the header's {} fields", h.len()),
                            None => format!("no header to find column '{name}' in: give the columns by number"),
                        },
                    })?,
                };
            }
            Ok(out)
        }
    }
}

/// One line, at most [`MAX_LINE`] bytes; `None` at the end.
fn next_line<R: BufRead>(r: &mut R, buf: &mut Vec<u8>, path: &Path, line_no: u64) -> Result<Option<()>> {
    buf.clear();
    let n = std::io::Read::take(&mut *r, MAX_LINE + 1).read_until(b'\n', buf).map_err(|e| Error::io(path, e))?;
    if n == 0 {
        return Ok(None);
    }
    if n as u64 > MAX_LINE && buf.last() != Some(&b'\n') {
        return Err(Error::Format { path: path.into(), msg: format!("line {line_no} is longer than {} KiB: not a file of points", MAX_LINE >> 10) });
    }
    Ok(Some(()))
}

pub fn read(path: &Path, columns: &Columns, cancel: &Cancel, each: &mut dyn FnMut(&[Point], u64) -> Result<()>) -> Result<u64> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut r = std::io::BufReader::with_capacity(1 << 20, file);
    let mut buf = Vec::new();
    let mut batch = Vec::with_capacity(BATCH);
    let (mut line_no, mut bytes, mut count) = (0u64, 0u64, 0u64);
    let mut layout: Option<(Split, [usize; 3])> = None;
    let bad = |line_no: u64, msg: String| Error::Format { path: path.into(), msg: format!("line {line_no}: {msg}") };
    while next_line(&mut r, &mut buf, path, line_no + 1)?.is_some() {
        line_no += 1;
        bytes += buf.len() as u64;
        let text = std::str::from_utf8(&buf).map_err(|_| bad(line_no, "not text (UTF-8)".into()))?;
        let text = text.trim_start_matches('\u{feff}').trim();
        if text.is_empty() || text.starts_with('#') || text.starts_with("//") {
            continue;
        }
        let (split, cols) = match layout {
            Some(l) => l,
            None => {
                let split = split_of(text);
                let f = fields(text, split);
                let numeric = f.iter().take(3).all(|v| v.parse::<f64>().is_ok());
                let cols = resolve(path, (!numeric).then_some(&f[..]), columns)?;
                layout = Some((split, cols));
                if !numeric {
                    continue;
                }
                (split, cols)
            }
        };
        let f = fields(text, split);
        let mut v = [0.0; 3];
        for (k, &c) in cols.iter().enumerate() {
            let field = f.get(c).ok_or_else(|| bad(line_no, format!("{} fields, column {} asked for", f.len(), c + 1)))?;
            // Quoted once the file has shown itself a list of points.
            let what = ["x", "y", "the height"][k];
            v[k] = field.parse::<f64>().map_err(|_| match count {
                0 => bad(line_no, format!("{what} (field {}) is not a number", c + 1)),
                _ => bad(line_no, format!("{what} '{}' is not a number", field.chars().take(40).collect::<String>())),
            })?;
            if !v[k].is_finite() {
                return Err(bad(line_no, format!("{} is {}", ["x", "y", "the height"][k], field)));
            }
            if k == 2 && v[k].abs() > super::MAX_HEIGHT {
                return Err(bad(line_no, format!("the height {field} is past any terrain's")));
            }
        }
        batch.push(Point { x: v[0], y: v[1], z: v[2] });
        count += 1;
        if batch.len() == BATCH {
            if cancel.is_cancelled() {
                return Err(Error::Cancelled);
            }
            each(&batch, bytes)?;
            batch.clear();
        }
    }
    if !batch.is_empty() {
        each(&batch, bytes)?;
    }
    Ok(count)
}
