//! Plane geometry shared by every stage: the orthophoto grid (ground ↔ output
//! pixel), 2-D affine maps (interior orientation, GeoTIFF transforms) and
//! tile/band layout of the output.

mod affine;
mod grid;
mod tiles;

pub use affine::Affine2;
pub use grid::OutputGrid;
pub use tiles::TileLayout;
