//! A plane in ground coordinates: the DEM's trend, the terrain of `A`.

/// A plane `Z = a + b·X + c·Y` in ground coordinates (the trend of the DEM).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Plane {
    pub a: f64,
    pub b: f64,
    pub c: f64,
}

impl Plane {
    pub fn flat(z: f64) -> Plane {
        Plane { a: z, b: 0.0, c: 0.0 }
    }
    #[inline]
    pub fn height(&self, x: f64, y: f64) -> f64 {
        self.a + self.b * x + self.c * y
    }
}
