//! What a run is made of, resolved once from its options: so far the
//! camera (its file in any format, the fiducial marks found where the file
//! asks for them). `rectify`, each image of `mosaic`, `accuracy` and
//! `batch`'s checks build it here.

pub mod camera;
