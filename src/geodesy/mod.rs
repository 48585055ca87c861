//! Coordinate reference systems and vertical datums: the ground CRS of an
//! orthophoto ↔ WGS84 longitude/latitude (through the `proj4rs` crate and
//! the EPSG definitions of `crs-definitions`), and geoid grids that turn
//! heights above the geoid (SRTM, most DEMs) into the ellipsoidal heights
//! an RPC model expects.

mod geoid;
mod projection;

pub use geoid::Geoid;
pub use projection::{utm_zone_epsg, GroundCrs, Reprojection};
