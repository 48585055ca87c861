//! The inverse mapping of orthorectification: output pixel (u, v) → ground
//! (X, Y) → height Z from the DEM → scan pixel. `exact` is the operator `T`
//! of Beloshapkin's eq. 2.1.1; `Approx` is its analytic approximation `A`
//! (2.4.5–2.4.7): collinearity on a plane, fractional-linear along each row.
//!
//! Coordinates: (u, v) are continuous output coordinates (pixel centres at
//! +½, see `geom::grid`); scan coordinates are continuous (column, row),
//! pixel centres at +½.

pub mod footprint;
pub mod inverse;
pub mod visibility;

use crate::camera::SensorModel;
use crate::dem::{Dem, Height, Lookup};
use crate::geom::OutputGrid;
use crate::geom::Plane;
use nalgebra::{Matrix3, Vector3};

/// Result of the exact mapping of one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mapped {
    Px(f64, f64),
    /// Not imaged, or no height and the policy says nodata.
    Nodata,
    /// No height and the policy says stop: the ground point and what was found.
    DemMiss(f64, f64, Lookup),
}

/// The exact operator `T` for one output grid, walked by rows, or by
/// columns (`transposed`).
pub struct Transform<'a> {
    pub model: &'a dyn SensorModel,
    pub dem: &'a Dem,
    /// The grid as walked: the output grid itself, or, transposed, the same
    /// ground with its width and height swapped. Its ground coordinates come
    /// from [`Transform::ground`].
    pub grid: OutputGrid,
    transposed: bool,
    /// The scan's size (columns, rows), where known: what lies outside it
    /// is never resampled.
    pub scan: Option<(f64, f64)>,
    /// The DEM and the model convert ground points to WGS84 longitude and
    /// latitude alike (an RPC or a panoramic camera over a DEM in
    /// EPSG:4326): the DEM's conversion serves the model too.
    share_lonlat: bool,
}

/// Whether `dem` and `model` convert ground points to longitude and
/// latitude alike.
fn shares_lonlat(model: &dyn SensorModel, dem: &Dem) -> bool {
    let from = model.lonlat_from();
    from.is_some() && from == dem.lonlat_from()
}

impl<'a> Transform<'a> {
    pub fn new(model: &'a dyn SensorModel, dem: &'a Dem, grid: OutputGrid) -> Self {
        Transform { model, dem, grid, transposed: false, scan: None, share_lonlat: shares_lonlat(model, dem) }
    }

    /// The same, knowing the scan is `size` (columns, rows).
    pub fn with_scan(self, size: (u32, u32)) -> Self {
        Transform { scan: Some((size.0 as f64, size.1 as f64)), ..self }
    }

    /// `T` of `grid` walked by columns: its (u, v) is (v, u) of `grid`, so
    /// that its rows are `grid`'s columns. A scan turned ~90° against the
    /// output then reads scan rows along each of them.
    pub fn transposed(model: &'a dyn SensorModel, dem: &'a Dem, grid: OutputGrid) -> Self {
        let walked = OutputGrid { width: grid.height, height: grid.width, ..grid };
        Transform { model, dem, grid: walked, transposed: true, scan: None, share_lonlat: shares_lonlat(model, dem) }
    }

    pub fn is_transposed(&self) -> bool {
        self.transposed
    }

    /// Ground (X, Y) of walked coordinates (u, v).
    #[inline]
    pub fn ground(&self, u: f64, v: f64) -> (f64, f64) {
        if self.transposed {
            self.grid.ground(v, u)
        } else {
            self.grid.ground(u, v)
        }
    }

    /// `T(u, v)`.
    #[inline]
    pub fn exact(&self, u: f64, v: f64) -> Mapped {
        let (x, y) = self.ground(u, v);
        if self.share_lonlat {
            return match self.dem.height_and_lonlat(x, y) {
                (Height::Value(z), Some((lon, lat))) => {
                    let (mut c, mut r) = ([0.0], [0.0]);
                    self.model.project_many_lonlat(&[lon], &[lat], &[z], &mut c, &mut r);
                    if c[0].is_nan() || r[0].is_nan() {
                        Mapped::Nodata
                    } else {
                        Mapped::Px(c[0], r[0])
                    }
                }
                (Height::Value(z), None) => match self.model.project(x, y, z) {
                    Some((c, r)) => Mapped::Px(c, r),
                    None => Mapped::Nodata,
                },
                (Height::Nodata, _) => Mapped::Nodata,
                (Height::Missing(l), _) => Mapped::DemMiss(x, y, l),
            };
        }
        match self.dem.height(x, y) {
            Height::Value(z) => match self.model.project(x, y, z) {
                Some((c, r)) => Mapped::Px(c, r),
                None => Mapped::Nodata,
            },
            Height::Nodata => Mapped::Nodata,
            Height::Missing(l) => Mapped::DemMiss(x, y, l),
        }
    }

    /// `T` at the centres of pixels `px` of row `v`, the projections at
    /// once ([`SensorModel::project_many`]: the numbers of `exact`);
    /// `None` where any of them has no value.
    pub fn exact_all<const N: usize>(&self, v: f64, px: [usize; N]) -> Option<[(f64, f64); N]> {
        let (mut x, mut y, mut z) = ([0.0; N], [0.0; N], [0.0; N]);
        for (k, &p) in px.iter().enumerate() {
            let (gx, gy) = self.ground(p as f64 + 0.5, v);
            let Height::Value(h) = self.dem.height(gx, gy) else { return None };
            (x[k], y[k], z[k]) = (gx, gy, h);
        }
        let (mut c, mut r) = ([0.0; N], [0.0; N]);
        self.model.project_many(&x, &y, &z, &mut c, &mut r);
        let mut out = [(0.0, 0.0); N];
        for (o, (c, r)) in out.iter_mut().zip(c.into_iter().zip(r)) {
            if !(c.is_finite() && r.is_finite()) {
                return None;
            }
            *o = (c, r);
        }
        Some(out)
    }

    /// `T` at `(u0 + i, v)` for each `i` of `at`, into `cols[i]`/`rows[i]`
    /// (NaN where there is no value), the projections a batch at a time
    /// ([`SensorModel::project_many`]: the same numbers as `exact`, fewer
    /// steps a point). The first DEM miss goes into `miss`.
    pub fn exact_at(&self, v: f64, u0: f64, at: &[usize], cols: &mut [f64], rows: &mut [f64], miss: &mut Option<(f64, f64, Lookup)>) {
        const BATCH: usize = 64;
        let (mut x, mut y, mut z) = ([0.0; BATCH], [0.0; BATCH], [0.0; BATCH]);
        let (mut c, mut r) = ([0.0; BATCH], [0.0; BATCH]);
        let mut which = [0usize; BATCH];
        // With the DEM's longitude and latitude for the model (x, y hold
        // them then): every point of a batch has them, or none has.
        let mut lonlat = self.share_lonlat;
        for batch in at.chunks(BATCH) {
            let mut n = 0;
            for &i in batch {
                let (gx, gy) = self.ground(u0 + i as f64, v);
                (cols[i], rows[i]) = (f64::NAN, f64::NAN);
                let (height, ll) = if lonlat { self.dem.height_and_lonlat(gx, gy) } else { (self.dem.height(gx, gy), None) };
                match height {
                    Height::Value(h) => {
                        let (px, py) = match ll {
                            Some(ll) => ll,
                            None if lonlat => {
                                // (A point without them: the batches go on
                                // from ground coordinates.)
                                lonlat = false;
                                for k in 0..n {
                                    (x[k], y[k]) = self.ground(u0 + which[k] as f64, v);
                                }
                                (gx, gy)
                            }
                            None => (gx, gy),
                        };
                        (x[n], y[n], z[n], which[n]) = (px, py, h, i);
                        n += 1;
                    }
                    Height::Nodata => {}
                    Height::Missing(l) => {
                        miss.get_or_insert((gx, gy, l));
                    }
                }
            }
            if lonlat {
                self.model.project_many_lonlat(&x[..n], &y[..n], &z[..n], &mut c[..n], &mut r[..n]);
            } else {
                self.model.project_many(&x[..n], &y[..n], &z[..n], &mut c[..n], &mut r[..n]);
            }
            for k in 0..n {
                (cols[which[k]], rows[which[k]]) = (c[k], r[k]);
            }
        }
    }

    #[cfg(any(test, feature = "internals"))]
    /// `T` over one output row `v` for the columns `u0 + i` (i < out.len()),
    /// scan columns/rows into `cols`/`rows`, NaN where there is no value.
    /// Returns the first DEM miss, if any.
    pub fn exact_row(&self, v: f64, u0: f64, cols: &mut [f64], rows: &mut [f64]) -> Option<(f64, f64, Lookup)> {
        let mut miss = None;
        for (i, (c, r)) in cols.iter_mut().zip(rows.iter_mut()).enumerate() {
            match self.exact(u0 + i as f64, v) {
                Mapped::Px(x, y) => {
                    *c = x;
                    *r = y;
                }
                Mapped::Nodata => {
                    *c = f64::NAN;
                    *r = f64::NAN;
                }
                Mapped::DemMiss(x, y, l) => {
                    *c = f64::NAN;
                    *r = f64::NAN;
                    miss.get_or_insert((x, y, l));
                }
            }
        }
        miss
    }
}

/// How the plane of `A` is chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Trend {
    /// Least-squares trend plane of the DEM (thesis 2.4.8–2.4.12).
    Plane,
    /// Horizontal plane at the mean height.
    Mean,
}

/// Coefficients of `A` along one output row `v`:
/// `col = (M u + N)/(E u + F)`, `row = (P u + Q)/(E u + F)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowApprox {
    pub m: f64,
    pub n: f64,
    pub p: f64,
    pub q: f64,
    pub e: f64,
    pub f: f64,
}

impl RowApprox {
    #[inline]
    pub fn at(&self, u: f64) -> (f64, f64) {
        let inv = 1.0 / (self.e * u + self.f);
        ((self.m * u + self.n) * inv, (self.p * u + self.q) * inv)
    }
}

/// The analytic approximation `A`: a plane homography output → scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Approx {
    pub h: Matrix3<f64>,
    pub plane: Plane,
}

impl Approx {
    /// `A` for `grid` on `plane`, normalised so that its denominator is
    /// positive at the grid centre.
    pub fn new(model: &dyn SensorModel, grid: &OutputGrid, plane: Plane) -> Option<Approx> {
        let mut h = model.plane_homography(grid, &plane)?;
        let centre = h * Vector3::new(grid.width as f64 / 2.0, grid.height as f64 / 2.0, 1.0);
        if !(centre.z.abs() > 0.0) || !h.iter().all(|v| v.is_finite()) {
            return None;
        }
        // Scale to a unit denominator at the centre: keeps the numbers O(1).
        h /= centre.z;
        Some(Approx { h, plane })
    }

    /// `A` with its output axes swapped: `transposed().at(v, u) == at(u, v)`
    /// (for a [`Transform::transposed`] walk).
    #[must_use]
    pub fn transposed(&self) -> Approx {
        let mut h = self.h;
        h.swap_columns(0, 1);
        Approx { h, plane: self.plane }
    }

    /// The six coefficients of row `v` (2.4.5–2.4.7): `M, P, E` are the same
    /// for every row, `N, Q, F` change.
    #[inline]
    pub fn row(&self, v: f64) -> RowApprox {
        let h = &self.h;
        RowApprox { m: h[(0, 0)], n: h[(0, 1)] * v + h[(0, 2)], p: h[(1, 0)], q: h[(1, 1)] * v + h[(1, 2)], e: h[(2, 0)], f: h[(2, 1)] * v + h[(2, 2)] }
    }

    /// `A(u, v)`; `None` where the denominator is not positive (the plane
    /// point is behind the camera).
    #[inline]
    pub fn at(&self, u: f64, v: f64) -> Option<(f64, f64)> {
        let r = self.row(v);
        if r.e * u + r.f <= 0.0 {
            return None;
        }
        Some(r.at(u))
    }
}
