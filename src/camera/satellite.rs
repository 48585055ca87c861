//! A satellite image with an RPC model as a `SensorModel`: ground (X, Y) in
//! the orthophoto's CRS → WGS84 longitude/latitude; the height Z of the DEM,
//! above the geoid when a geoid grid is given, → ellipsoidal height; then the
//! RPC. The approximation `A` of the GCM is the homography that best fits
//! the mapping on the terrain plane (docs/METHOD.md): corrections then hold
//! the relief and what of the RPC is not projective.

use super::rpc::Rpc;
use super::SensorModel;
use crate::geodesy::{Geoid, GroundCrs};
use crate::geom::Plane;
use crate::geom::{Affine2, OutputGrid};
use nalgebra::{DMatrix, Matrix3, Vector3};

pub struct RpcCamera {
    pub rpc: Rpc,
    pub crs: GroundCrs,
    /// DEM heights are above this geoid (h = H + N); `None`: ellipsoidal.
    pub geoid: Option<Geoid>,
    /// Ground units per scan pixel near the scene centre.
    ground_per_px: f64,
    /// The image-space bias correction ground control points found
    /// (Grodecki & Dial): the RPC's pixel → the image's. Identity without.
    bias: Affine2,
    unbias: Affine2,
}

impl RpcCamera {
    pub fn new(rpc: Rpc, crs: GroundCrs, geoid: Option<Geoid>) -> RpcCamera {
        let (per_deg_lat, _) = rpc.pixels_per_degree();
        let metres_per_px = 111_320.0 / per_deg_lat.max(1e-9);
        let ground_per_px = metres_per_px * crs.units_per_metre(rpc.lat_off);
        RpcCamera { rpc, crs, geoid, ground_per_px, bias: Affine2::identity(), unbias: Affine2::identity() }
    }

    /// Corrects the model's image coordinates by `bias` (RPC pixel → image
    /// pixel); false, and nothing changed, when `bias` cannot be inverted.
    pub fn set_bias(&mut self, bias: Affine2) -> bool {
        let Some(unbias) = bias.inverse() else { return false };
        (self.bias, self.unbias) = (bias, unbias);
        true
    }

    /// The image-space correction in use.
    pub fn bias(&self) -> &Affine2 {
        &self.bias
    }

    /// A height in the DEM's datum of an ellipsoidal height at (lon, lat).
    pub fn dem_height(&self, lon: f64, lat: f64, h: f64) -> Option<f64> {
        match &self.geoid {
            None => Some(h),
            Some(g) => Some(h - g.undulation(lon, lat)?),
        }
    }

    /// Ellipsoidal height of a height `z` in the DEM's vertical datum.
    #[inline]
    fn ellipsoidal(&self, lon: f64, lat: f64, z: f64) -> Option<f64> {
        match &self.geoid {
            None => Some(z),
            Some(g) => Some(z + g.undulation(lon, lat)?),
        }
    }

    /// A height to start from: the RPC's mid height, in the DEM's datum.
    pub fn height_hint(&self) -> f64 {
        let n = self.geoid.as_ref().and_then(|g| g.undulation(self.rpc.long_off, self.rpc.lat_off)).unwrap_or(0.0);
        self.rpc.height_off - n
    }
}

impl SensorModel for RpcCamera {
    #[inline]
    fn project(&self, x: f64, y: f64, z: f64) -> Option<(f64, f64)> {
        let (lon, lat) = self.crs.to_lonlat(x, y)?;
        let h = self.ellipsoidal(lon, lat, z)?;
        let (c, r) = self.rpc.project(lon, lat, h)?;
        Some(self.bias.apply(c, r))
    }

    fn lonlat_from(&self) -> Option<&crate::geodesy::Crs> {
        Some(&self.crs.crs)
    }

    fn project_many_lonlat(&self, lon: &[f64], lat: &[f64], z: &[f64], col: &mut [f64], row: &mut [f64]) {
        assert!(
            lat.len() == lon.len() && z.len() == lon.len() && col.len() == lon.len() && row.len() == lon.len(),
            "project_many_lonlat: arrays of one length"
        );
        for k in 0..lon.len() {
            let p = self.ellipsoidal(lon[k], lat[k], z[k]).and_then(|h| self.rpc.project(lon[k], lat[k], h)).map(|(c, r)| self.bias.apply(c, r));
            (col[k], row[k]) = p.unwrap_or((f64::NAN, f64::NAN));
        }
    }

    fn locate_approx(&self, col: f64, row: f64, z: f64) -> Option<(f64, f64)> {
        let n = self.geoid.as_ref().and_then(|g| g.undulation(self.rpc.long_off, self.rpc.lat_off)).unwrap_or(0.0);
        let (col, row) = self.unbias.apply(col, row);
        let (lon, lat) = self.rpc.locate(col, row, z + n, 0.01)?;
        self.crs.lonlat_to_ground(lon, lat)
    }

    fn plane_homography(&self, grid: &OutputGrid, plane: &Plane) -> Option<Matrix3<f64>> {
        super::fitted_plane_homography(self, grid, plane)
    }

    fn ground_step(&self) -> f64 {
        0.05 * self.ground_per_px
    }
}

/// Normalising similarity of a point set (Hartley): centroid to 0, mean
/// distance √2.
fn normaliser(pts: impl Iterator<Item = (f64, f64)> + Clone) -> Matrix3<f64> {
    let n = pts.clone().count() as f64;
    let (mx, my) = pts.clone().fold((0.0, 0.0), |a, p| (a.0 + p.0 / n, a.1 + p.1 / n));
    let d = pts.map(|p| (p.0 - mx).hypot(p.1 - my)).sum::<f64>() / n;
    let s = if d > 0.0 { std::f64::consts::SQRT_2 / d } else { 1.0 };
    Matrix3::new(s, 0.0, -s * mx, 0.0, s, -s * my, 0.0, 0.0, 1.0)
}

/// A point and where it goes: `((x, y), (x', y'))`.
pub type PointPair = ((f64, f64), (f64, f64));

/// The homography `H` with `to ≈ H·from` in the least-squares algebraic
/// sense (normalised DLT), from at least 4 point pairs.
pub fn fit_homography(pairs: &[PointPair]) -> Option<Matrix3<f64>> {
    if pairs.len() < 4 {
        return None;
    }
    let ta = normaliser(pairs.iter().map(|p| p.0));
    let tb = normaliser(pairs.iter().map(|p| p.1));
    let mut a = DMatrix::<f64>::zeros(2 * pairs.len(), 9);
    for (k, &((u, v), (c, r))) in pairs.iter().enumerate() {
        let p = ta * Vector3::new(u, v, 1.0);
        let q = tb * Vector3::new(c, r, 1.0);
        let (x, y) = (p.x / p.z, p.y / p.z);
        let (xc, yc) = (q.x / q.z, q.y / q.z);
        a.row_mut(2 * k).copy_from_slice(&[x, y, 1.0, 0.0, 0.0, 0.0, -xc * x, -xc * y, -xc]);
        a.row_mut(2 * k + 1).copy_from_slice(&[0.0, 0.0, 0.0, x, y, 1.0, -yc * x, -yc * y, -yc]);
    }
    // The right singular vector of the smallest singular value: the
    // eigenvector of AᵀA with the smallest eigenvalue.
    let ata = a.transpose() * &a;
    let eig = ata.symmetric_eigen();
    let (imin, _) = eig.eigenvalues.iter().enumerate().min_by(|x, y| x.1.total_cmp(y.1))?;
    let h = eig.eigenvectors.column(imin);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let out = tb.try_inverse()? * hn * ta;
    out.iter().all(|v| v.is_finite()).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_exact_homography_is_recovered() {
        let h = Matrix3::new(0.9, 0.1, 500.0, -0.05, 1.1, 300.0, 1e-5, -2e-5, 1.0);
        let pairs: Vec<_> = (0..25)
            .map(|k| {
                let (u, v) = ((k % 5) as f64 * 1000.0, (k / 5) as f64 * 800.0);
                let p = h * Vector3::new(u, v, 1.0);
                ((u, v), (p.x / p.z, p.y / p.z))
            })
            .collect();
        let g = fit_homography(&pairs).unwrap();
        for &((u, v), (c, r)) in &pairs {
            let p = g * Vector3::new(u, v, 1.0);
            assert!((p.x / p.z - c).abs() < 1e-6 && (p.y / p.z - r).abs() < 1e-6);
        }
    }
}
