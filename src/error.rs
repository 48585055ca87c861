//! Typed errors of the library. Every variant that concerns a file names it, so
//! the binary can print one readable line; the binary maps them to exit codes.

use crate::setting_names::name_settings;
use std::path::{Path, PathBuf};

/// Everything that can go wrong inside gcm-ortho. A message names a
/// setting by its key between ‹ and › ([`crate::setting_names`]): shown as
/// the key (`Display`), or as its caller gives it ([`Error::naming_settings`]).
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// The operating system refused a read or a write.
    Io { path: PathBuf, source: std::io::Error },
    /// A file is not what its format promises (truncated, inconsistent, corrupt).
    Format { path: PathBuf, msg: String },
    /// A well-formed file uses a feature we do not support.
    Unsupported { path: PathBuf, msg: String },
    /// A configuration file (camera, manifest) has a bad or missing field.
    Config { path: PathBuf, field: String, msg: String },
    /// A size or count is beyond what we accept (protects memory).
    Limits { path: PathBuf, msg: String },
    /// The geometry cannot be solved (degenerate camera, empty footprint, ...).
    Geometry(String),
    /// A setting out of range or contradicting another, named by its key
    /// (`tile`, `dem_hole`: the manifest's key; the binary prints the flag).
    Setting { setting: &'static str, msg: String },
    /// Arguments that contradict each other or are out of range.
    Usage(String),
    /// Problems of a file whose message names it (a manifest's, each with
    /// its line).
    Named(String),
    /// A fault of gcm-ortho itself, not of any input or setting (a bug to
    /// report).
    Internal(String),
    /// The run was cancelled (signal, or another stage failed first).
    Cancelled,
}

impl Error {
    /// The message, each setting it names said by `name` (given its key):
    /// the command line says `--dem-hole` where Python says `dem_hole`.
    pub fn naming_settings(&self, name: &dyn Fn(&str) -> String) -> String {
        let said = |msg: &str| name_settings(msg, name);
        match self {
            Error::Io { path, source } => format!("{}: {}", path.display(), in_words(source)),
            Error::Format { path, msg } => format!("{}: {}", path.display(), said(msg)),
            Error::Unsupported { path, msg } => format!("{}: unsupported: {}", path.display(), said(msg)),
            Error::Config { path, field, msg } => format!("{}: {field}: {}", path.display(), said(msg)),
            Error::Limits { path, msg } => format!("{}: limit exceeded: {}", path.display(), said(msg)),
            Error::Geometry(msg) => format!("geometry: {}", said(msg)),
            Error::Setting { setting, msg } => format!("{}: {}", name(setting), said(msg)),
            Error::Usage(msg) | Error::Named(msg) => said(msg),
            Error::Internal(msg) => format!("internal error (a fault of gcm-ortho, not of the inputs): {}", said(msg)),
            Error::Cancelled => "cancelled".into(),
        }
    }

    /// The message with its settings still marked, for a message of the
    /// library that quotes it: its caller then names them.
    pub fn marked(&self) -> String {
        self.naming_settings(&|key| format!("‹{key}›"))
    }
}

impl std::fmt::Display for Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.naming_settings(&|key| key.to_string()))
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// What the operating system said, as a user reads it: the common kinds
/// in words of our own, the rest without its "(os error N)".
pub(crate) fn in_words(e: &std::io::Error) -> String {
    use std::io::ErrorKind::*;
    match e.kind() {
        NotFound => "no such file or folder".into(),
        PermissionDenied => "permission denied".into(),
        StorageFull => "no space left on the disk".into(),
        _ => {
            let text = e.to_string();
            match text.rfind(" (os error ") {
                Some(k) if text.ends_with(')') => text[..k].to_string(),
                _ => text,
            }
        }
    }
}

impl Error {
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io { path: path.as_ref().to_path_buf(), source }
    }
    pub fn format(path: impl AsRef<Path>, msg: impl Into<String>) -> Self {
        Error::Format { path: path.as_ref().to_path_buf(), msg: msg.into() }
    }
    pub fn unsupported(path: impl AsRef<Path>, msg: impl Into<String>) -> Self {
        Error::Unsupported { path: path.as_ref().to_path_buf(), msg: msg.into() }
    }
    pub fn config(path: impl AsRef<Path>, field: impl Into<String>, msg: impl Into<String>) -> Self {
        Error::Config { path: path.as_ref().to_path_buf(), field: field.into(), msg: msg.into() }
    }
    /// A problem at `origin` (a file and line, an image) of the file
    /// `path`: the file named once, also where `origin` names it already.
    pub fn at(path: impl AsRef<Path>, origin: &str, msg: impl std::fmt::Display) -> Self {
        let path = path.as_ref();
        if origin.starts_with(&*path.to_string_lossy()) {
            Error::Named(format!("{origin}: {msg}"))
        } else {
            Error::format(path, format!("{origin}: {msg}"))
        }
    }
    pub fn setting(setting: &'static str, msg: impl Into<String>) -> Self {
        Error::Setting { setting, msg: msg.into() }
    }
    pub fn limits(path: impl AsRef<Path>, msg: impl Into<String>) -> Self {
        Error::Limits { path: path.as_ref().to_path_buf(), msg: msg.into() }
    }

    /// Converts an error of the `tiff` crate met while reading `path`.
    pub fn from_tiff(path: impl AsRef<Path>, e: tiff::TiffError) -> Self {
        use tiff::TiffError as T;
        match e {
            T::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => Error::format(path, "file is truncated (unexpected end of file)"),
            T::IoError(io) => Error::io(path, io),
            T::UnsupportedError(u) => Error::unsupported(path, u.to_string()),
            T::LimitsExceeded => Error::limits(path, "the TIFF decoder's memory limits"),
            T::IntSizeError => Error::limits(path, "a size does not fit the platform's integers"),
            other => Error::format(path, other.to_string()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The OS's words are a user's: no "(os error N)".
    #[test]
    fn io_errors_read_as_words() {
        let missing = Error::io("cam.toml", std::io::Error::from_raw_os_error(2)).to_string();
        assert_eq!(missing, "cam.toml: no such file or folder");
        let denied = Error::io("out.tif", std::io::Error::from_raw_os_error(13)).to_string();
        assert_eq!(denied, "out.tif: permission denied");
        let other = Error::io("x", std::io::Error::from_raw_os_error(21)).to_string();
        assert!(other.starts_with("x: ") && !other.contains("os error"), "{other}");
    }
}

/// A number for a message: as written where it is of everyday size, in
/// exponent form where `{}` would print hundreds of digits (1e-300).
pub fn short_number(v: f64) -> String {
    match v == 0.0 || !v.is_finite() || (1e-4..1e7).contains(&v.abs()) {
        true => format!("{v}"),
        false => {
            // Five significant figures: a height read from Float32 has no more.
            let text = format!("{v:.4e}");
            let (mantissa, exponent) = text.split_once('e').expect("exponent form");
            let mantissa = if mantissa.contains('.') { mantissa.trim_end_matches('0').trim_end_matches('.') } else { mantissa };
            format!("{mantissa}e{exponent}")
        }
    }
}

#[cfg(test)]
mod number_tests {
    #[test]
    fn numbers_in_messages_are_short() {
        use super::short_number as n;
        assert_eq!(n(152.0), "152");
        assert_eq!(n(1e-300), "1e-300");
        assert_eq!(n(f64::from(3.5e32f32)), "3.5e32");
        assert_eq!(n(-35079270.8), "-3.5079e7");
        assert_eq!(n(0.0), "0");
    }
}
