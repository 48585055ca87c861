//! The orthophoto grid: north-up, square pixels of size `gsd` (ground units),
//! origin at the north-west corner of pixel (0, 0). Conventions, stated once:
//! output pixel `(col, row)` covers ground `[x0 + gsd·col, x0 + gsd·(col+1)]`
//! × `[y0 − gsd·(row+1), y0 − gsd·row]` (GDAL's pixel-is-area); continuous
//! output coordinates `(u, v)` put the centre of pixel (col, row) at
//! `(col + ½, row + ½)`.

use serde::Serialize;

#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
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
    /// outward to multiples of `gsd` (textbook §9.10.4).
    pub fn snapped(minx: f64, miny: f64, maxx: f64, maxy: f64, gsd: f64) -> Option<OutputGrid> {
        if !(gsd > 0.0) || !(maxx > minx) || !(maxy > miny) {
            return None;
        }
        let x0 = (minx / gsd).floor() * gsd;
        let y0 = (maxy / gsd).ceil() * gsd;
        let x1 = (maxx / gsd).ceil() * gsd;
        let y1 = (miny / gsd).floor() * gsd;
        let w = ((x1 - x0) / gsd).round();
        let h = ((y0 - y1) / gsd).round();
        if w < 1.0 || h < 1.0 || w > u32::MAX as f64 || h > u32::MAX as f64 {
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
    fn snapping_goes_outward() {
        let g = OutputGrid::snapped(10.2, 20.7, 19.9, 30.1, 1.0).unwrap();
        assert_eq!((g.x0, g.y0, g.width, g.height), (10.0, 31.0, 10, 11));
    }
}
