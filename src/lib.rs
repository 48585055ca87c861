//! gcm-ortho: orthorectification of huge scans on small machines by the
//! generalized correction matrix (Beloshapkin's thesis on the digital
//! orthorectification of aerial photographs; see `docs/METHOD.md`).
//!
//! The library is the whole program: [`rectify`] takes [`RectifyOptions`],
//! a [`Progress`] to report to and a [`Cancel`] to stop it; the binary
//! parses arguments into options, draws the progress bar, installs the
//! signal handlers and prints errors. `docs/ARCHITECTURE.md` maps the
//! modules.

pub mod assemble;
pub mod batch;
pub mod camera;
pub mod command_keys;
pub mod dem;
pub mod error;
pub mod fiducials;
pub mod gcm;
pub mod geodesy;
pub mod geom;
pub mod gridding;
pub mod identity;
pub mod io;
pub mod keys;
pub mod mosaic;
pub mod options;
pub mod overview;
pub mod pipeline;
pub mod points;
pub mod progress;
pub mod resample;
pub mod rpcgrid;
pub mod scene;
pub mod setting_names;
pub mod stereo;
pub mod study;
pub mod synth;
pub mod transform;

pub use error::{Error, Result};
pub use options::RectifyOptions;
pub use pipeline::{rectify, Report};
pub use progress::{Cancel, NoProgress, Progress};
