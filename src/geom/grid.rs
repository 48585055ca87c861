//! The orthophoto grid: north-up, square pixels of size `gsd` (ground units),
//! origin at the north-west corner of pixel (0, 0). Conventions, stated once:
//! output pixel `(col, row)` covers ground `[x0 + gsd·col, x0 + gsd·(col+1)]`
//! × `[y0 − gsd·(row+1), y0 − gsd·row]` (GDAL's pixel-is-area); continuous
//! output coordinates `(u, v)` put the centre of pixel (col, row) at
//! `(col + ½, row + ½)`.

use serde::Serialize;

/// How bounds become a grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Snap {
    /// Edges outward to multiples of the GSD, covering the bounds
    /// (gdalwarp's `-tap`).
    #[default]
    Tap,
    /// The origin at the bounds' north-west corner as given; the size
    /// whole pixels outward, covering them.
    Outward,
    /// The origin as given, the size the nearest whole number of pixels
    /// (gdalwarp's `-te` with `-tr`).
    None,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct OutputGrid {
    /// Ground X (easting) of the west edge.
    pub x0: f64,
    /// Ground Y (northing) of the north edge.
    pub y0: f64,
    /// Pixel size in ground units.
    pub gsd: f64,
    pub width: u32,
    pub height: u32,
}

impl OutputGrid {
    /// Ground (X, Y) of continuous output coordinates (u, v).
    #[inline]
    #[must_use]
    pub fn ground(&self, u: f64, v: f64) -> (f64, f64) {
        (self.x0 + self.gsd * u, self.y0 - self.gsd * v)
    }

    /// Continuous output coordinates of ground (X, Y).
    #[inline]
    #[must_use]
    pub fn pixel(&self, x: f64, y: f64) -> (f64, f64) {
        ((x - self.x0) / self.gsd, (self.y0 - y) / self.gsd)
    }

    /// The grid covering `[minx, maxx] × [miny, maxy]`, its edges snapped
    /// outward to multiples of `gsd` (textbook §9.10.4; [`Snap::Tap`]).
    pub fn snapped(minx: f64, miny: f64, maxx: f64, maxy: f64, gsd: f64) -> Option<OutputGrid> {
        Self::from_bounds([minx, miny, maxx, maxy], gsd, Snap::Tap)
    }

    /// The grid of bounds `[minx, miny, maxx, maxy]` at `gsd`, placed as
    /// `snap` says. A value within a millionth of a pixel of a whole number
    /// of pixels is that number: bounds that are multiples of the GSD in
    /// decimal (2731039.8 at 0.2) are kept, whatever binary rounding makes
    /// of their quotient.
    pub fn from_bounds([minx, miny, maxx, maxy]: [f64; 4], gsd: f64, snap: Snap) -> Option<OutputGrid> {
        if !(gsd > 0.0) || !(maxx > minx) || !(maxy > miny) {
            return None;
        }
        const TOL: f64 = 1e-6;
        let down = |v: f64| (v / gsd + TOL).floor();
        let up = |v: f64| (v / gsd - TOL).ceil();
        let (x0, y0, w, h) = match snap {
            Snap::Tap => {
                let (i0, j0) = (down(minx), up(maxy));
                (i0 * gsd, j0 * gsd, up(maxx) - i0, j0 - down(miny))
            }
            Snap::Outward => (minx, maxy, ((maxx - minx) / gsd - TOL).ceil(), ((maxy - miny) / gsd - TOL).ceil()),
            Snap::None => (minx, maxy, ((maxx - minx) / gsd).round(), ((maxy - miny) / gsd).round()),
        };
        if !(w >= 1.0 && h >= 1.0 && w <= u32::MAX as f64 && h <= u32::MAX as f64) {
            return None;
        }
        Some(OutputGrid { x0, y0, gsd, width: w as u32, height: h as u32 })
    }

    /// GDAL geotransform `[x0, gsd, 0, y0, 0, −gsd]`.
    #[must_use]
    pub fn geotransform(&self) -> [f64; 6] {
        [self.x0, self.gsd, 0.0, self.y0, 0.0, -self.gsd]
    }

    pub fn pixel_count(&self) -> u64 {
        self.width as u64 * self.height as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_centres_at_half() {
        let g = OutputGrid { x0: 1000.0, y0: 2000.0, gsd: 0.5, width: 10, height: 10 };
        assert_eq!(g.ground(0.5, 0.5), (1000.25, 1999.75));
        assert_eq!(g.pixel(1000.25, 1999.75), (0.5, 0.5));
    }

    #[test]
    fn bounds_on_multiples_of_the_gsd_are_kept_exactly() {
        // 2731039.8 / 0.2 = 13655198.999999998 in binary: one row too many before.
        let b = [292546.4, 2731039.8, 292848.8, 2731224.4];
        for snap in [Snap::Tap, Snap::Outward, Snap::None] {
            let g = OutputGrid::from_bounds(b, 0.2, snap).unwrap();
            assert_eq!((g.width, g.height), (1512, 923), "{snap:?}");
            assert!((g.x0 - 292546.4).abs() < 1e-6 && (g.y0 - 2731224.4).abs() < 1e-6, "{snap:?}");
        }
        // Not multiples: aligned outward, or kept as given.
        let b = [-57094.61, 100.3, -57000.0, 200.0];
        let tap = OutputGrid::from_bounds(b, 5.0, Snap::Tap).unwrap();
        assert_eq!((tap.x0, tap.y0, tap.width, tap.height), (-57095.0, 200.0, 19, 20));
        let out = OutputGrid::from_bounds(b, 5.0, Snap::Outward).unwrap();
        assert_eq!((out.x0, out.y0, out.width, out.height), (-57094.61, 200.0, 19, 20));
        let none = OutputGrid::from_bounds(b, 5.0, Snap::None).unwrap();
        assert_eq!((none.x0, none.y0, none.width, none.height), (-57094.61, 200.0, 19, 20));
        let none = OutputGrid::from_bounds([0.0, 0.0, 12.4, 12.6], 1.0, Snap::None).unwrap();
        assert_eq!((none.width, none.height), (12, 13));
        let out = OutputGrid::from_bounds([0.0, 0.0, 12.4, 12.6], 1.0, Snap::Outward).unwrap();
        assert_eq!((out.width, out.height), (13, 13));
        assert!(OutputGrid::from_bounds([0.0, 0.0, 0.4, 0.4], 1.0, Snap::None).is_none(), "no whole pixel");
    }

    #[test]
    fn snapping_goes_outward() {
        let g = OutputGrid::snapped(10.2, 20.7, 19.9, 30.1, 1.0).unwrap();
        assert_eq!((g.x0, g.y0, g.width, g.height), (10.0, 31.0, 10, 11));
    }
}
