//! A sensor model seen from another ground CRS: the orthophoto's (X, Y)
//! are converted to the camera's CRS, then the camera projects. A frame
//! camera whose exterior orientation is in one CRS (a national grid, UTM)
//! then makes an orthophoto in any other; the conversion is part of the
//! exact model `T`, so the GCM's corrections absorb what of it is not
//! projective, as they do for an RPC.

use super::SensorModel;
use crate::geodesy::{Crs, Reprojection};
use crate::geom::{OutputGrid, Plane};
use nalgebra::Matrix3;

pub struct Reprojected<M: SensorModel> {
    pub inner: M,
    /// The CRS `inner` works in.
    own: Crs,
    to_camera: Reprojection,
    from_camera: Reprojection,
    /// Output ground units per camera ground unit near the scene.
    scale: f64,
}

impl<M: SensorModel> Reprojected<M> {
    /// `inner` (in the CRS `camera`) seen from the CRS `ground`, about the
    /// camera ground point `near` (for the finite-difference step).
    pub fn new(inner: M, camera: &Crs, ground: &Crs, near: (f64, f64)) -> Result<Reprojected<M>, String> {
        let to_camera = Reprojection::new(ground, camera)?;
        let from_camera = Reprojection::new(camera, ground)?;
        let (x, _) =
            from_camera.apply(near.0, near.1).ok_or_else(|| format!("the camera's position ({:.3}, {:.3}) has no place in {ground}", near.0, near.1))?;
        let (x2, _) = from_camera.apply(near.0 + 100.0, near.1).ok_or_else(|| format!("the camera's surroundings have no place in {ground}"))?;
        let scale = ((x2 - x).abs() / 100.0).max(1e-12);
        Ok(Reprojected { inner, own: camera.clone(), to_camera, from_camera, scale })
    }

    pub fn own_crs(&self) -> &Crs {
        &self.own
    }

    /// A point of the camera's CRS in the ground CRS.
    pub fn to_ground(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        self.from_camera.apply(x, y)
    }
}

impl<M: SensorModel> SensorModel for Reprojected<M> {
    #[inline]
    fn project(&self, x: f64, y: f64, z: f64) -> Option<(f64, f64)> {
        let (cx, cy) = self.to_camera.apply(x, y)?;
        self.inner.project(cx, cy, z)
    }

    fn project_many(&self, x: &[f64], y: &[f64], z: &[f64], col: &mut [f64], row: &mut [f64]) {
        let (mut cx, mut cy) = (vec![f64::NAN; x.len()], vec![f64::NAN; x.len()]);
        for k in 0..x.len() {
            if let Some((a, b)) = self.to_camera.apply(x[k], y[k]) {
                (cx[k], cy[k]) = (a, b);
            }
        }
        self.inner.project_many(&cx, &cy, z, col, row);
    }

    fn locate_approx(&self, col: f64, row: f64, z: f64) -> Option<(f64, f64)> {
        let (cx, cy) = self.inner.locate_approx(col, row, z)?;
        self.from_camera.apply(cx, cy)
    }

    fn plane_homography(&self, grid: &OutputGrid, plane: &Plane) -> Option<Matrix3<f64>> {
        super::fitted_plane_homography(self, grid, plane)
    }

    fn ground_step(&self) -> f64 {
        self.inner.ground_step() * self.scale
    }

    fn image_area(&self) -> Option<crate::geom::ImageArea> {
        self.inner.image_area()
    }
}
