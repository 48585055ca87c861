//! Sensor models: each maps a ground point (X east, Y north, Z up, in the
//! ground CRS) to a scan pixel (column, row; continuous, pixel centres at +½).

pub mod atmosphere;
pub mod distortion;
pub mod file;
pub mod formats;
pub mod frame;
pub mod gcp;
pub mod gcp_points;
pub mod interior;
pub mod lanes;
pub mod panoramic;
pub mod panoramic_file;
pub mod panoramic_resection;
pub mod reprojected;
pub mod rotation;
pub mod rpc;
pub mod satellite;

pub use file::CameraFile;
pub use frame::FrameCamera;
pub use satellite::RpcCamera;

use crate::geom::{OutputGrid, Plane};
use nalgebra::Matrix3;

/// The mapping `T` from ground to image, without the DEM.
pub trait SensorModel: Send + Sync {
    /// Ground (X, Y, Z) → scan pixel (column, row), `None` where the point
    /// cannot be imaged (behind the camera, outside the model's domain).
    fn project(&self, x: f64, y: f64, z: f64) -> Option<(f64, f64)>;

    /// `project` for many points: `(col[k], row[k])` of `(x[k], y[k], z[k])`,
    /// NaN where the point cannot be imaged. All slices of one length.
    fn project_many(&self, x: &[f64], y: &[f64], z: &[f64], col: &mut [f64], row: &mut [f64]) {
        assert!(y.len() == x.len() && z.len() == x.len() && col.len() == x.len() && row.len() == x.len(), "project_many: arrays of one length");
        for k in 0..x.len() {
            (col[k], row[k]) = self.project(x[k], y[k], z[k]).unwrap_or((f64::NAN, f64::NAN));
        }
    }

    /// For a model whose `project` starts by converting ground (X, Y) to
    /// WGS84 longitude/latitude (an RPC): the EPSG code of the ground CRS it
    /// converts from. A caller holding that conversion's result for its
    /// points (a DEM in EPSG:4326 looked them up) hands it to
    /// [`SensorModel::project_many_lonlat`] instead of converting again.
    fn lonlat_from(&self) -> Option<&crate::geodesy::Crs> {
        None
    }

    /// `project_many` from the points' WGS84 (longitude, latitude), as the
    /// CRS of [`SensorModel::lonlat_from`] converts them: the same numbers.
    /// NaN for models without it.
    fn project_many_lonlat(&self, lon: &[f64], lat: &[f64], z: &[f64], col: &mut [f64], row: &mut [f64]) {
        let _ = (lon, lat, z);
        col.fill(f64::NAN);
        row.fill(f64::NAN);
    }

    /// An approximate inverse: ground (X, Y) at height `z` seen at the scan
    /// pixel (column, row). Within a few pixels of the truth is enough; the
    /// callers refine it against `project`.
    fn locate_approx(&self, col: f64, row: f64, z: f64) -> Option<(f64, f64)>;

    /// The homography `H` with scan ≈ H·(u, v, 1) for output pixels (u, v) on
    /// `plane`: the analytic approximation `A` of thesis 2.4.5–2.4.7 for
    /// every output row at once.
    fn plane_homography(&self, grid: &OutputGrid, plane: &Plane) -> Option<Matrix3<f64>>;

    /// A ground distance small against one scan pixel, for finite
    /// differences (ground units: metres, or degrees in a geographic CRS).
    fn ground_step(&self) -> f64 {
        0.01
    }

    /// The part of the scan that holds the image (a film camera's format),
    /// where it is less than the whole scan: no output pixel takes a value
    /// from outside it.
    fn image_area(&self) -> Option<crate::geom::ImageArea> {
        None
    }
}

/// The homography that best fits `model` on `plane` over a 9 × 9 lattice
/// of the output grid (normalised DLT): `A` for models that are not
/// central projections of the ground CRS (an RPC, a camera in another CRS).
pub fn fitted_plane_homography(model: &dyn SensorModel, grid: &OutputGrid, plane: &Plane) -> Option<Matrix3<f64>> {
    let n = 9;
    let mut pairs = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let u = grid.width as f64 * i as f64 / (n - 1) as f64;
            let v = grid.height as f64 * j as f64 / (n - 1) as f64;
            let (x, y) = grid.ground(u, v);
            if let Some(p) = model.project(x, y, plane.height(x, y)) {
                pairs.push(((u, v), p));
            }
        }
    }
    satellite::fit_homography(&pairs)
}

/// Refines `locate_approx` by Newton steps on `project`: ground (X, Y) at
/// height `z` whose image is (col, row), to `tol_px`.
pub fn locate(model: &dyn SensorModel, col: f64, row: f64, z: f64, tol_px: f64) -> Option<(f64, f64)> {
    let (mut x, mut y) = model.locate_approx(col, row, z)?;
    for _ in 0..20 {
        let (c, r) = model.project(x, y, z)?;
        let (ec, er) = (col - c, row - r);
        if ec.hypot(er) < tol_px {
            return Some((x, y));
        }
        let h = model.ground_step();
        let (cx, rx) = model.project(x + h, y, z)?;
        let (cy, ry) = model.project(x, y + h, z)?;
        let j = nalgebra::Matrix2::new((cx - c) / h, (cy - c) / h, (rx - r) / h, (ry - r) / h);
        let step = j.try_inverse()? * nalgebra::Vector2::new(ec, er);
        x += step.x;
        y += step.y;
    }
    None
}
