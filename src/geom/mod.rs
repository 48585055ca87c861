//! Plane geometry shared by every stage: the orthophoto grid (ground ↔ output
//! pixel), 2-D affine maps (interior orientation, GeoTIFF transforms), the
//! terrain plane, stepped spans of scan positions, and fast floors.

mod affine;
mod floor;
mod grid;
mod plane;
mod span;

pub use affine::Affine2;
pub use floor::{floor_i64, floor_split};
pub use grid::OutputGrid;
pub use plane::Plane;
pub use span::Span;
