//! WGS84 geodetic ↔ earth-centred earth-fixed (ECEF) coordinates, and the
//! local east-north-up frame at a point: what turns a topocentric
//! reconstruction (OpenSfM's) into longitude, latitude and height.

use nalgebra::{Matrix3, Vector3};

const A: f64 = 6_378_137.0;
const F: f64 = 1.0 / 298.257_223_563;

/// ECEF (metres) of longitude, latitude (degrees) and ellipsoidal height (metres).
#[must_use]
pub fn to_ecef(lon: f64, lat: f64, h: f64) -> Vector3<f64> {
    let e2 = F * (2.0 - F);
    let (sl, cl) = lat.to_radians().sin_cos();
    let (so, co) = lon.to_radians().sin_cos();
    let n = A / (1.0 - e2 * sl * sl).sqrt();
    Vector3::new((n + h) * cl * co, (n + h) * cl * so, (n * (1.0 - e2) + h) * sl)
}

/// Longitude, latitude (degrees) and ellipsoidal height (metres) of an ECEF
/// point, by Bowring's start and Newton steps on the latitude (to far below
/// a millimetre anywhere near the earth's surface).
#[must_use]
pub fn from_ecef(p: Vector3<f64>) -> (f64, f64, f64) {
    let e2 = F * (2.0 - F);
    let lon = p.y.atan2(p.x);
    let r = p.x.hypot(p.y);
    let mut lat = p.z.atan2(r * (1.0 - e2));
    let mut h = 0.0;
    for _ in 0..6 {
        let s = lat.sin();
        let n = A / (1.0 - e2 * s * s).sqrt();
        h = if lat.cos().abs() > 1e-9 { r / lat.cos() - n } else { p.z.abs() - n * (1.0 - e2) };
        lat = p.z.atan2(r * (1.0 - e2 * n / (n + h)));
    }
    (lon.to_degrees(), lat.to_degrees(), h)
}

/// The matrix whose columns are the east, north and up unit vectors at
/// longitude, latitude (degrees), in ECEF: ENU → ECEF directions.
#[must_use]
pub fn enu_axes(lon: f64, lat: f64) -> Matrix3<f64> {
    let (sl, cl) = lat.to_radians().sin_cos();
    let (so, co) = lon.to_radians().sin_cos();
    Matrix3::new(-so, -sl * co, cl * co, co, -sl * so, cl * so, 0.0, cl, sl)
}

/// The rotation nearest `m` (its polar factor, by SVD): a frame's axes
/// with scale and shear taken out.
#[must_use]
pub fn nearest_rotation(m: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let svd = m.svd(true, true);
    Some(svd.u? * svd.v_t?)
}

/// How `map` turns directions at `p`: its Jacobian by unit steps, scale
/// removed (a grid's convergence, a tangent plane's tilt).
pub fn local_turn(map: impl Fn(Vector3<f64>) -> Option<Vector3<f64>>, p: Vector3<f64>) -> Option<Matrix3<f64>> {
    let here = map(p)?;
    let cols = [map(p + Vector3::x())? - here, map(p + Vector3::y())? - here, map(p + Vector3::z())? - here];
    nearest_rotation(&Matrix3::from_columns(&cols))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_known_values() {
        // The equator at the prime meridian is (a, 0, 0); the pole is (0, 0, b).
        let p = to_ecef(0.0, 0.0, 0.0);
        assert!((p - Vector3::new(A, 0.0, 0.0)).norm() < 1e-9);
        let b = A * (1.0 - F);
        assert!((to_ecef(0.0, 90.0, 10.0) - Vector3::new(0.0, 0.0, b + 10.0)).norm() < 1e-6);
        for (lon, lat, h) in [(17.0, 45.0, 100.0), (-71.3, -33.4, 2500.0), (151.2, 80.1, -30.0)] {
            let (a, b, c) = from_ecef(to_ecef(lon, lat, h));
            assert!((a - lon).abs() < 1e-11 && (b - lat).abs() < 1e-11 && (c - h).abs() < 1e-6, "{a} {b} {c}");
        }
        // Up is along the ellipsoid's normal: 1 m up changes the height by 1 m.
        let m = enu_axes(17.0, 45.0);
        let up = to_ecef(17.0, 45.0, 100.0) + m.column(2);
        assert!((from_ecef(up).2 - 101.0).abs() < 1e-9);
        let north = to_ecef(17.0, 45.0, 100.0) + m.column(1) * 100.0;
        assert!(from_ecef(north).1 > 45.0 && (from_ecef(north).0 - 17.0).abs() < 1e-12);
    }
}
