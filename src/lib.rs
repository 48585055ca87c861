//! gcm-ortho: orthorectification of huge scans on small machines by the
//! generalized correction matrix (Beloshapkin's thesis on the digital
//! orthorectification of aerial photographs; see `docs/METHOD.md`).
//!
//! The API is what this file exports: each command as a function of its
//! options, a [`Progress`] to report to and a [`Cancel`] to stop it
//! ([`rectify`], [`mosaic`], [`assemble`], [`grid`], [`dem`], [`synth`]),
//! the options and reports, the key tables that make options of settings
//! by name ([`keys`]), and the command line itself ([`run_command_line`]).
//! Every other module is the crate's own; the `internals` feature opens
//! them to the project's own tests and benches, with no promise that they
//! stay as they are. `docs/ARCHITECTURE.md` maps the modules.

/// The crate's inner modules: `pub(crate)`, or `pub` for the project's
/// own tests and benches (feature `internals`).
macro_rules! inner_modules {
    ($($module:ident),* $(,)?) => {$(
        #[cfg(feature = "internals")]
        pub mod $module;
        #[cfg(not(feature = "internals"))]
        pub(crate) mod $module;
    )*};
}

inner_modules! {
    assemble,
    batch,
    camera,
    command_keys,
    dem,
    error,
    fiducials,
    gcm,
    geodesy,
    geom,
    gridding,
    identity,
    keys,
    io,
    mosaic,
    overview,
    pipeline,
    points,
    processor,
    progress,
    resample,
    rpcgrid,
    scene,
    setting_names,
    stereo,
    study,
    synth,
    transform,
}
mod command_line;

pub mod options;

pub use command_line::run as run_command_line;
pub use error::{Error, Result};
pub use progress::{Cancel, NoProgress, Progress, Recording, Task};

pub use options::RectifyOptions;
pub use pipeline::{plan, rectify, OutputPlan, Report};

pub use mosaic::{mosaic, MosaicOptions, MosaicReport};

pub use assemble::{assemble, AssembleOptions};

pub use gridding::{grid, GridOptions, GridReport};

pub use stereo::{dem, StereoOptions as DemOptions, StereoReport as DemReport};

pub use synth::{synth, SynthOptions, SynthReport};

pub use io::format::SampleType;
pub use io::read_raster::{read_raster, Raster};

/// Turns a process's SIGBUS on a mapped input cut short under a run into
/// that run's error: a host's choice (the command line makes it), as
/// without it SIGBUS ends the process as usual.
pub use io::mmap_guard::install_sigbus_handler;

/// Messages mark settings `‹key›`; said by key for a caller that passes
/// settings by name.
pub use setting_names::as_keys as settings_said_as_keys;

/// Options made of settings by name (a manifest's job, a binding's
/// keyword arguments): the one key table the command line uses too.
pub mod by_key {
    pub use crate::command_keys::{assemble_options, dem_options, grid_options, mosaic_options};
    pub use crate::keys::rectify_options;
}
