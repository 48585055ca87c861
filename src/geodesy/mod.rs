//! Coordinate reference systems and vertical datums: CRSs as users write
//! them (codes, PROJ strings, WKT, `.prj` files) and as GeoTIFF keys hold
//! them; the ground CRS of an orthophoto ↔ WGS84 longitude/latitude
//! (through the `proj4rs` crate and the EPSG definitions of
//! `crs-definitions`); and geoid grids that turn heights above the geoid
//! (SRTM, most DEMs) into the ellipsoidal heights an RPC model expects.

mod crs;
mod datum;
pub mod ecef;
mod esri;
mod geoid;
pub mod geokeys;
mod grid_shift;
mod proj_data;
mod projection;
mod vertical;
mod wkt;

pub use crs::{optional_definition as optional_crs_definition, Crs};
pub use geoid::Geoid;
#[cfg(feature = "internals")]
pub use proj_data::find_grid as find_proj_grid;
pub use projection::{utm_zone, GroundCrs, Reprojection};
pub use vertical::Vertical;
