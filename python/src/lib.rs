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

#[macro_use]
#[path = "../../src/quiet_print.rs"]
mod quiet_print;
#[path = "../../src/cli.rs"]
mod cli;
#[path = "../../src/command_line.rs"]
mod command_line;
#[path = "../../src/commands.rs"]
mod commands;
#[path = "../../src/flag_names.rs"]
mod flag_names;
#[path = "../../src/progress_bar.rs"]
mod progress_bar;

mod watch;

use gcm_ortho::progress::Progress;
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
                *text = gcm_ortho::setting_names::as_keys(text);
            }
        }
    }
    serde_json::to_string(&v).map_err(internal)
}

/// `rectify(options_json, progress, interval) -> report_json`
#[pyfunction]
#[pyo3(signature = (options, progress=None, interval=0.5))]
fn rectify(py: Python<'_>, options: &str, progress: Option<Py<PyAny>>, interval: f64) -> PyResult<String> {
    let opts = gcm_ortho::keys::rectify_options(keys_of(options)?).map_err(|e| raise(py, e))?;
    let report = watched(py, progress, interval, |p: &dyn Progress, c: &Cancel| {
        let not_tiff = warn_if_not_tiff(p, &opts.output);
        let mut report = gcm_ortho::rectify(&opts, p, c)?;
        report.warnings.extend(not_tiff);
        Ok(report)
    })?;
    json_text(py, &report)
}

/// `plan(options_json) -> grid_json`: the output grid a run of these
/// options makes, in pixels and tiles, without rendering a pixel.
#[pyfunction]
fn plan(py: Python<'_>, options: &str) -> PyResult<String> {
    let mut opts = gcm_ortho::keys::rectify_options(keys_of(options)?).map_err(|e| raise(py, e))?;
    // The whole grid: a window is what a piece of the plan renders.
    opts.window = None;
    let grid = watched(py, None, 0.5, |p: &dyn Progress, _c: &Cancel| {
        let plan = gcm_ortho::pipeline::RunPlan::new(&opts, p)?;
        let g = plan.grid;
        let t = opts.tile;
        Ok(serde_json::json!({
            "width": g.width,
            "height": g.height,
            "tile": t,
            "tiles_across": g.width.div_ceil(t),
            "tiles_down": g.height.div_ceil(t),
            "transform": [g.x0, g.gsd.x, 0.0, g.y0, 0.0, -g.gsd.y],
            "crs": plan.camera.crs.to_string(),
            "bands": plan.src.info.bands,
        }))
    })?;
    json_text(py, &grid)
}

/// `mosaic(options_json, progress, interval) -> report_json`
#[pyfunction]
#[pyo3(signature = (options, progress=None, interval=0.5))]
fn mosaic(py: Python<'_>, options: &str, progress: Option<Py<PyAny>>, interval: f64) -> PyResult<String> {
    let opts = gcm_ortho::command_keys::mosaic_options(keys_of(options)?).map_err(|e| raise(py, e))?;
    let report = watched(py, progress, interval, |p: &dyn Progress, c: &Cancel| gcm_ortho::mosaic::mosaic(&opts, p, c))?;
    json_text(py, &report)
}

/// `grid(options_json, progress, interval) -> report_json`: a DEM from points.
#[pyfunction]
#[pyo3(signature = (options, progress=None, interval=0.5))]
fn grid(py: Python<'_>, options: &str, progress: Option<Py<PyAny>>, interval: f64) -> PyResult<String> {
    let opts = gcm_ortho::command_keys::grid_options(keys_of(options)?).map_err(|e| raise(py, e))?;
    let report = watched(py, progress, interval, |p: &dyn Progress, c: &Cancel| {
        warn_if_not_tiff(p, &opts.output);
        gcm_ortho::gridding::grid(&opts, p, c)
    })?;
    json_text(py, &report)
}

/// `dem(options_json, progress, interval) -> report_json`: a DSM from a stereo pair.
#[pyfunction]
#[pyo3(signature = (options, progress=None, interval=0.5))]
fn dem(py: Python<'_>, options: &str, progress: Option<Py<PyAny>>, interval: f64) -> PyResult<String> {
    let opts = gcm_ortho::command_keys::dem_options(keys_of(options)?).map_err(|e| raise(py, e))?;
    let report = watched(py, progress, interval, |p: &dyn Progress, c: &Cancel| {
        warn_if_not_tiff(p, &opts.output);
        gcm_ortho::stereo::dem(&opts, p, c)
    })?;
    json_text(py, &report)
}

/// An output named as another format (`.png`) misleads whoever opens it
/// by its name: said first, as the command says it.
fn warn_if_not_tiff(p: &dyn Progress, output: &std::path::Path) -> Option<String> {
    let w = gcm_ortho::io::tiff_out::named_as_other_format(output)?;
    p.warn(&w);
    Some(w)
}

/// `assemble(pieces, output, options_json)`: pieces of one grid into the whole.
#[pyfunction]
fn assemble(py: Python<'_>, pieces: Vec<PathBuf>, output: PathBuf, options: &str) -> PyResult<()> {
    let opts = gcm_ortho::command_keys::assemble_options(keys_of(options)?).map_err(|e| raise(py, e))?;
    watched(py, None, 0.5, |_p: &dyn Progress, c: &Cancel| gcm_ortho::assemble::assemble(&pieces, &output, &opts, c))
}

/// `read_raster(path) -> (pixels, width, height, bands, sample, mask, nodata)`:
/// an orthophoto (or a piece) whole, pixel-interleaved in native byte
/// order; `mask`: a byte a pixel (1: has a value) where the file has an
/// internal mask, else None.
#[pyfunction]
#[allow(clippy::type_complexity)]
fn read_raster<'py>(py: Python<'py>, path: PathBuf) -> PyResult<(Bound<'py, PyBytes>, u32, u32, u32, String, Option<Bound<'py, PyBytes>>, Option<f64>)> {
    use gcm_ortho::io::source::{MaskRuns, SourceImage, Window};
    let (pixels, info, mask) = py
        .detach(|| -> gcm_ortho::Result<_> {
            let img = SourceImage::open(&path, 1 << 20)?;
            let mut win = Window::default();
            img.read_window(0, 0, img.info.width, img.info.height, &mut win)?;
            let mask = match img.info.mask {
                Some(_) => {
                    let runs = MaskRuns::read(&img)?;
                    let w = img.info.width as usize;
                    let mut bytes = vec![0u8; w * img.info.height as usize];
                    for (r, row) in bytes.chunks_exact_mut(w).enumerate() {
                        for &[a, b] in runs.row(r as u32) {
                            row[a as usize..b as usize].fill(1);
                        }
                    }
                    Some(bytes)
                }
                None => None,
            };
            Ok((win.bytes().to_vec(), img.info.clone(), mask))
        })
        .map_err(|e| raise(py, e))?;
    let sample = match info.sample {
        gcm_ortho::io::format::SampleType::U8 => "uint8",
        gcm_ortho::io::format::SampleType::U16 => "uint16",
        gcm_ortho::io::format::SampleType::F32 => "float32",
    }
    .to_string();
    Ok((PyBytes::new(py, &pixels), info.width, info.height, info.bands, sample, mask.map(|m| PyBytes::new(py, &m)), info.nodata))
}

/// `command(argv) -> exit code`: the `gcm-ortho` command itself.
#[pyfunction]
fn command(py: Python<'_>, argv: Vec<std::ffi::OsString>) -> u8 {
    py.detach(|| command_line::run(argv))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // A scan truncated underneath a run fails that run (its exception),
    // not the interpreter.
    gcm_ortho::io::mmap_guard::install_sigbus_handler();
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
