//! What a run is made of, resolved once from its options, each concern by
//! its own constructor: the camera (its file in any format, the fiducial
//! marks found where the file asks for them), the terrain (the DEM, the
//! geoid), the output grid (CRS, GSD, bounds, limits, the terrain plane)
//! and the checks that the inputs belong together, and what the output is
//! made from (its key). `rectify`, each image of
//! `mosaic`, `accuracy` and `batch`'s checks build them here.

pub mod camera;
pub mod checks;
pub mod grid;
pub mod made_from;
pub mod terrain;
