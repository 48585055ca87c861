//! gcm-ortho: orthorectification of huge scans on small machines by the
//! generalized correction matrix (Beloshapkin's thesis; see README and
//! METHOD.md). The library is the whole program; `main.rs` only parses
//! arguments and prints errors.

pub mod accuracy;
pub mod batch;
pub mod camera;
pub mod compare;
pub mod dem;
pub mod error;
pub mod gcm;
pub mod geodesy;
pub mod geom;
pub mod io;
pub mod pipeline;
pub mod progress;
pub mod resample;
pub mod rpcgrid;
pub mod synth;
pub mod transform;

pub use error::{Error, Result};
