//! `gcm_ortho._native`: the library's runs for Python. Settings arrive as
//! one JSON object of keys (the library's key table turns them into
//! options), reports leave as JSON; the Python half (gcm_ortho/) makes
//! keyword arguments, dicts, NumPy arrays and exceptions of them.
//!
//! Every run works on a thread of its own with the GIL released; the
//! calling thread wakes a few times a second to hand progress to the
//! callback, pass warnings on and see whether Python has a signal pending
//! (Ctrl-C): then the run is cancelled, cleans up, and the signal's
//! exception is raised.

mod watch;

use gcm_ortho::Progress;
use gcm_ortho::{Cancel, Error};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use std::path::PathBuf;
use watch::watched;

/// The settings object a call passes (JSON text).
fn keys_of(text: &str) -> PyResult<serde_json::Map<String, serde_json::Value>> {
    match serde_json::from_str(text) {
        Ok(serde_json::Value::Object(m)) => Ok(m),
        _ => Err(pyo3::exceptions::PyTypeError::new_err("options must be a JSON object")),
    }
}

/// A run's error as the exception of its kind (gcm_ortho.errors), the
/// message the command line would print.
fn raise(py: Python<'_>, e: Error) -> PyErr {
    let kind = match &e {
        Error::Io { .. } => "InputOutputError",
        Error::Format { .. } | Error::Config { .. } | Error::Named(_) => "InputError",
        Error::Unsupported { .. } => "UnsupportedError",
        Error::Limits { .. } => "LimitError",
        Error::Geometry(_) => "GeometryError",
        Error::Setting { .. } | Error::Usage(_) => "SettingError",
        Error::Internal(_) => "InternalError",
        Error::Cancelled => "CancelledError",
        _ => "GcmOrthoError",
    };
    let message = e.to_string().replace('\n', " ");
    match py.import("gcm_ortho.errors").and_then(|m| m.getattr(kind)).and_then(|class| class.call1((message.clone(),))) {
        Ok(exception) => PyErr::from_value(exception),
        Err(_) => pyo3::exceptions::PyRuntimeError::new_err(message),
    }
}

/// A report as JSON, the settings its warnings name said as keys.
fn json_text(py: Python<'_>, value: &impl serde::Serialize) -> PyResult<String> {
    let internal = |e: serde_json::Error| raise(py, Error::Internal(format!("the report does not serialize: {e}")));
    let mut v = serde_json::to_value(value).map_err(internal)?;
    if let Some(serde_json::Value::Array(ws)) = v.get_mut("warnings") {
        for w in ws.iter_mut() {
            if let serde_json::Value::String(text) = w {
                *text = gcm_ortho::settings_said_as_keys(text);
            }
        }
    }
    serde_json::to_string(&v).map_err(internal)
}

/// `rectify(options_json, progress, interval) -> report_json`
#[pyfunction]
#[pyo3(signature = (options, progress=None, interval=0.5))]
fn rectify(py: Python<'_>, options: &str, progress: Option<Py<PyAny>>, interval: f64) -> PyResult<String> {
    let opts = gcm_ortho::by_key::rectify_options(keys_of(options)?).map_err(|e| raise(py, e))?;
    let report = watched(py, progress, interval, |p: &dyn Progress, c: &Cancel| gcm_ortho::rectify(&opts, p, c))?;
    json_text(py, &report)
}

/// `plan(options_json) -> grid_json`: the output grid a run of these
/// options makes, in pixels and tiles, without rendering a pixel.
#[pyfunction]
fn plan(py: Python<'_>, options: &str) -> PyResult<String> {
    let opts = gcm_ortho::by_key::rectify_options(keys_of(options)?).map_err(|e| raise(py, e))?;
    let grid = watched(py, None, 0.5, |p: &dyn Progress, _c: &Cancel| gcm_ortho::plan(&opts, p))?;
    json_text(py, &grid)
}

/// `mosaic(options_json, progress, interval) -> report_json`
#[pyfunction]
#[pyo3(signature = (options, progress=None, interval=0.5))]
fn mosaic(py: Python<'_>, options: &str, progress: Option<Py<PyAny>>, interval: f64) -> PyResult<String> {
    let opts = gcm_ortho::by_key::mosaic_options(keys_of(options)?).map_err(|e| raise(py, e))?;
    let report = watched(py, progress, interval, |p: &dyn Progress, c: &Cancel| gcm_ortho::mosaic(&opts, p, c))?;
    json_text(py, &report)
}

/// `grid(options_json, progress, interval) -> report_json`: a DEM from points.
#[pyfunction]
#[pyo3(signature = (options, progress=None, interval=0.5))]
fn grid(py: Python<'_>, options: &str, progress: Option<Py<PyAny>>, interval: f64) -> PyResult<String> {
    let opts = gcm_ortho::by_key::grid_options(keys_of(options)?).map_err(|e| raise(py, e))?;
    let report = watched(py, progress, interval, |p: &dyn Progress, c: &Cancel| gcm_ortho::grid(&opts, p, c))?;
    json_text(py, &report)
}

/// `dem(options_json, progress, interval) -> report_json`: a DSM from a stereo pair.
#[pyfunction]
#[pyo3(signature = (options, progress=None, interval=0.5))]
fn dem(py: Python<'_>, options: &str, progress: Option<Py<PyAny>>, interval: f64) -> PyResult<String> {
    let opts = gcm_ortho::by_key::dem_options(keys_of(options)?).map_err(|e| raise(py, e))?;
    let report = watched(py, progress, interval, |p: &dyn Progress, c: &Cancel| gcm_ortho::dem(&opts, p, c))?;
    json_text(py, &report)
}

/// `assemble(pieces, output, options_json)`: pieces of one grid into the whole.
#[pyfunction]
fn assemble(py: Python<'_>, pieces: Vec<PathBuf>, output: PathBuf, options: &str) -> PyResult<()> {
    let opts = gcm_ortho::by_key::assemble_options(keys_of(options)?).map_err(|e| raise(py, e))?;
    watched(py, None, 0.5, |_p: &dyn Progress, c: &Cancel| gcm_ortho::assemble(&pieces, &output, &opts, c))
}

/// `read_raster(path) -> (pixels, width, height, bands, sample, mask, nodata)`:
/// an orthophoto (or a piece) whole, pixel-interleaved in native byte
/// order; `mask`: a byte a pixel (1: has a value) where the file has an
/// internal mask, else None.
#[pyfunction]
#[allow(clippy::type_complexity)]
fn read_raster<'py>(py: Python<'py>, path: PathBuf) -> PyResult<(Bound<'py, PyBytes>, u32, u32, u32, String, Option<Bound<'py, PyBytes>>, Option<f64>)> {
    let r = py.detach(|| gcm_ortho::read_raster(&path)).map_err(|e| raise(py, e))?;
    let sample = match r.sample {
        gcm_ortho::SampleType::U8 => "uint8",
        gcm_ortho::SampleType::U16 => "uint16",
        gcm_ortho::SampleType::F32 => "float32",
    }
    .to_string();
    Ok((PyBytes::new(py, &r.pixels), r.width, r.height, r.bands, sample, r.mask.map(|m| PyBytes::new(py, &m)), r.nodata))
}

/// `command(argv) -> exit code`: the `gcm-ortho` command itself.
#[pyfunction]
fn command(py: Python<'_>, argv: Vec<std::ffi::OsString>) -> u8 {
    py.detach(|| gcm_ortho::run_command_line(argv))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // A scan truncated underneath a run fails that run (its exception),
    // not the interpreter.
    gcm_ortho::install_sigbus_handler();
    m.add_function(wrap_pyfunction!(rectify, m)?)?;
    m.add_function(wrap_pyfunction!(plan, m)?)?;
    m.add_function(wrap_pyfunction!(mosaic, m)?)?;
    m.add_function(wrap_pyfunction!(grid, m)?)?;
    m.add_function(wrap_pyfunction!(dem, m)?)?;
    m.add_function(wrap_pyfunction!(assemble, m)?)?;
    m.add_function(wrap_pyfunction!(read_raster, m)?)?;
    m.add_function(wrap_pyfunction!(command, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
