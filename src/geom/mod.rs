//! Plane geometry shared by every stage: the orthophoto grid (ground ↔ output
//! pixel), 2-D affine maps (interior orientation, GeoTIFF transforms), the
//! terrain plane, the part of a scan that holds the image, stepped spans
//! of scan positions, and fast floors.

mod affine;
mod floor;
mod grid;
mod image_area;
mod plane;
mod span;

pub use affine::Affine2;
pub use floor::{floor_i64, floor_split};
pub use grid::{cut_window, Gsd, OutputGrid, Snap};
pub use image_area::ImageArea;
pub use plane::Plane;
pub use span::Span;
