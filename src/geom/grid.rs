//! The orthophoto grid: north-up pixels `gsd.x` wide and `gsd.y` tall
//! (ground units; square unless asked), origin at the north-west corner of
//! pixel (0, 0). Conventions, stated once: output pixel `(col, row)` covers
//! ground `[x0 + gsd.x·col, x0 + gsd.x·(col+1)]` × `[y0 − gsd.y·(row+1),
//! y0 − gsd.y·row]` (GDAL's pixel-is-area); continuous output coordinates
//! `(u, v)` put the centre of pixel (col, row) at `(col + ½, row + ½)`.

use serde::{Deserialize, Serialize};

/// A window of tiles (first column, first row, columns, rows) cut at the
/// edge of a grid of `tiles` (across, down): one reaching past the edge is
/// cut there, so that shards may ask for bands of a fixed height and the
/// last one gets what is left; one that starts past it, or holds no tile,
/// is refused (as written, for the message).
pub fn cut_window([c0, r0, w, h]: [u32; 4], (across, down): (u32, u32)) -> Result<[u32; 4], String> {
    if w == 0 || h == 0 || c0 >= across || r0 >= down {
        return Err(format!("{c0},{r0},{w},{h}"));
    }
    Ok([c0, r0, w.min(across - c0), h.min(down - r0)])
}

/// An output pixel's size in ground units: across (X, east) and down
/// (Y, south), both positive. Written `0.2` when square, `5,6` when not
/// (gdalwarp's `-tr 5 6`); JSON and manifests: a number or `[x, y]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gsd {
    pub x: f64,
    pub y: f64,
}

impl Gsd {
    #[must_use]
    pub fn square(g: f64) -> Gsd {
        Gsd { x: g, y: g }
    }

    #[must_use]
    pub fn is_square(self) -> bool {
        self.x == self.y
    }

    /// The side of a square pixel of the same area.
    #[must_use]
    pub fn mean(self) -> f64 {
        (self.x * self.y).sqrt()
    }

    #[must_use]
    pub fn min(self) -> f64 {
        self.x.min(self.y)
    }

    #[must_use]
    pub fn max(self) -> f64 {
        self.x.max(self.y)
    }

    /// A pixel's ground area.
    #[must_use]
    pub fn area(self) -> f64 {
        self.x * self.y
    }

    /// Both sides times `f`.
    #[must_use]
    pub fn scaled(self, f: f64) -> Gsd {
        Gsd { x: self.x * f, y: self.y * f }
    }

    /// Both sides positive and finite.
    #[must_use]
    pub fn is_valid(self) -> bool {
        self.x > 0.0 && self.x.is_finite() && self.y > 0.0 && self.y.is_finite()
    }
}

impl std::fmt::Display for Gsd {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.is_square() {
            write!(f, "{}", self.x)
        } else {
            write!(f, "{},{}", self.x, self.y)
        }
    }
}

impl std::str::FromStr for Gsd {
    type Err = String;
    /// `X` (square pixels) or `X,Y`.
    fn from_str(s: &str) -> Result<Gsd, String> {
        let num = |t: &str| t.trim().parse::<f64>().map_err(|_| format!("{s:?} is not a pixel size (X, or X,Y in ground units)"));
        let g = match s.split_once(',') {
            None => Gsd::square(num(s)?),
            Some((x, y)) => Gsd { x: num(x)?, y: num(y)? },
        };
        if !g.is_valid() {
            return Err(format!("{s} must be positive"));
        }
        Ok(g)
    }
}

impl Serialize for Gsd {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if self.is_square() {
            s.serialize_f64(self.x)
        } else {
            [self.x, self.y].serialize(s)
        }
    }
}

impl<'de> Deserialize<'de> for Gsd {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Gsd, D::Error> {
        struct Visit;
        impl<'de> serde::de::Visitor<'de> for Visit {
            type Value = Gsd;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a pixel size: a number, or [x, y] for pixels x wide and y tall")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<Gsd, E> {
                Ok(Gsd::square(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<Gsd, E> {
                Ok(Gsd::square(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<Gsd, E> {
                Ok(Gsd::square(v as f64))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Gsd, A::Error> {
                let mut next = || seq.next_element::<f64>();
                match (next()?, next()?, next()?) {
                    (Some(x), Some(y), None) => Ok(Gsd { x, y }),
                    _ => Err(serde::de::Error::custom("a pixel size is a number, or [x, y]: two numbers")),
                }
            }
        }
        d.deserialize_any(Visit)
    }
}

/// How bounds become a grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
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
    pub gsd: Gsd,
    pub width: u32,
    pub height: u32,
}

impl OutputGrid {
    /// Ground (X, Y) of continuous output coordinates (u, v).
    #[inline]
    #[must_use]
    pub fn ground(&self, u: f64, v: f64) -> (f64, f64) {
        (self.x0 + self.gsd.x * u, self.y0 - self.gsd.y * v)
    }

    /// Continuous output coordinates of ground (X, Y).
    #[inline]
    #[must_use]
    pub fn pixel(&self, x: f64, y: f64) -> (f64, f64) {
        ((x - self.x0) / self.gsd.x, (self.y0 - y) / self.gsd.y)
    }

    /// The grid covering `[minx, maxx] × [miny, maxy]`, its edges snapped
    /// outward to multiples of `gsd` (textbook §9.10.4; [`Snap::Tap`]).
    pub fn snapped(minx: f64, miny: f64, maxx: f64, maxy: f64, gsd: Gsd) -> Option<OutputGrid> {
        Self::from_bounds([minx, miny, maxx, maxy], gsd, Snap::Tap)
    }

    /// The grid of bounds `[minx, miny, maxx, maxy]` at `gsd`, placed as
    /// `snap` says. A value within a millionth of a pixel of a whole number
    /// of pixels is that number: bounds that are multiples of the GSD in
    /// decimal (2731039.8 at 0.2) are kept, whatever binary rounding makes
    /// of their quotient.
    pub fn from_bounds([minx, miny, maxx, maxy]: [f64; 4], gsd: Gsd, snap: Snap) -> Option<OutputGrid> {
        if !(gsd.x > 0.0 && gsd.y > 0.0 && maxx > minx && maxy > miny) {
            return None;
        }
        const TOL: f64 = 1e-6;
        let down = |v: f64, g: f64| (v / g + TOL).floor();
        let up = |v: f64, g: f64| (v / g - TOL).ceil();
        let (x0, y0, w, h) = match snap {
            Snap::Tap => {
                let (i0, j0) = (down(minx, gsd.x), up(maxy, gsd.y));
                (i0 * gsd.x, j0 * gsd.y, up(maxx, gsd.x) - i0, j0 - down(miny, gsd.y))
            }
            Snap::Outward => (minx, maxy, ((maxx - minx) / gsd.x - TOL).ceil(), ((maxy - miny) / gsd.y - TOL).ceil()),
            Snap::None => (minx, maxy, ((maxx - minx) / gsd.x).round(), ((maxy - miny) / gsd.y).round()),
        };
        if !(w >= 1.0 && h >= 1.0 && w <= u32::MAX as f64 && h <= u32::MAX as f64) {
            return None;
        }
        Some(OutputGrid { x0, y0, gsd, width: w as u32, height: h as u32 })
    }

    /// Why `from_bounds` gave no grid, for a message after "BOUNDS at GSD G".
    pub fn no_grid_because([minx, miny, maxx, maxy]: [f64; 4], gsd: Gsd) -> &'static str {
        let (w, h) = ((maxx - minx) / gsd.x, (maxy - miny) / gsd.y);
        if !(w > 0.0 && h > 0.0) {
            "is empty"
        } else if w.max(h) > u32::MAX as f64 {
            "is more pixels a side than a raster holds"
        } else {
            "is less than one pixel a side"
        }
    }

    /// GDAL geotransform `[x0, gsd.x, 0, y0, 0, −gsd.y]`.
    #[must_use]
    pub fn geotransform(&self) -> [f64; 6] {
        [self.x0, self.gsd.x, 0.0, self.y0, 0.0, -self.gsd.y]
    }

    /// Ground `[minx, miny, maxx, maxy]` the grid covers.
    #[must_use]
    pub fn bounds(&self) -> [f64; 4] {
        [self.x0, self.y0 - self.gsd.y * self.height as f64, self.x0 + self.gsd.x * self.width as f64, self.y0]
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
        let g = OutputGrid { x0: 1000.0, y0: 2000.0, gsd: Gsd::square(0.5), width: 10, height: 10 };
        assert_eq!(g.ground(0.5, 0.5), (1000.25, 1999.75));
        assert_eq!(g.pixel(1000.25, 1999.75), (0.5, 0.5));
    }

    #[test]
    fn bounds_on_multiples_of_the_gsd_are_kept_exactly() {
        // 2731039.8 / 0.2 = 13655198.999999998 in binary: one row too many before.
        let b = [292546.4, 2731039.8, 292848.8, 2731224.4];
        for snap in [Snap::Tap, Snap::Outward, Snap::None] {
            let g = OutputGrid::from_bounds(b, Gsd::square(0.2), snap).unwrap();
            assert_eq!((g.width, g.height), (1512, 923), "{snap:?}");
            assert!((g.x0 - 292546.4).abs() < 1e-6 && (g.y0 - 2731224.4).abs() < 1e-6, "{snap:?}");
        }
        // Not multiples: aligned outward, or kept as given.
        let b = [-57094.61, 100.3, -57000.0, 200.0];
        let tap = OutputGrid::from_bounds(b, Gsd::square(5.0), Snap::Tap).unwrap();
        assert_eq!((tap.x0, tap.y0, tap.width, tap.height), (-57095.0, 200.0, 19, 20));
        let out = OutputGrid::from_bounds(b, Gsd::square(5.0), Snap::Outward).unwrap();
        assert_eq!((out.x0, out.y0, out.width, out.height), (-57094.61, 200.0, 19, 20));
        let none = OutputGrid::from_bounds(b, Gsd::square(5.0), Snap::None).unwrap();
        assert_eq!((none.x0, none.y0, none.width, none.height), (-57094.61, 200.0, 19, 20));
        let none = OutputGrid::from_bounds([0.0, 0.0, 12.4, 12.6], Gsd::square(1.0), Snap::None).unwrap();
        assert_eq!((none.width, none.height), (12, 13));
        let out = OutputGrid::from_bounds([0.0, 0.0, 12.4, 12.6], Gsd::square(1.0), Snap::Outward).unwrap();
        assert_eq!((out.width, out.height), (13, 13));
        assert!(OutputGrid::from_bounds([0.0, 0.0, 0.4, 0.4], Gsd::square(1.0), Snap::None).is_none(), "no whole pixel");
    }

    #[test]
    fn non_square_pixels_snap_each_axis_to_its_own_size() {
        let g = OutputGrid::from_bounds([10.2, 20.7, 29.9, 30.1], Gsd { x: 5.0, y: 2.0 }, Snap::Tap).unwrap();
        assert_eq!((g.x0, g.y0, g.width, g.height), (10.0, 32.0, 4, 6));
        assert_eq!(g.geotransform(), [10.0, 5.0, 0.0, 32.0, 0.0, -2.0]);
        assert_eq!(g.ground(1.0, 1.0), (15.0, 30.0));
        assert_eq!(g.bounds(), [10.0, 20.0, 30.0, 32.0]);
        assert_eq!("5,6".parse::<Gsd>().unwrap(), Gsd { x: 5.0, y: 6.0 });
        assert_eq!("0.2".parse::<Gsd>().unwrap(), Gsd::square(0.2));
        assert!("5,-6".parse::<Gsd>().is_err() && "5,".parse::<Gsd>().is_err() && "nan".parse::<Gsd>().is_err());
        assert_eq!(serde_json::to_string(&Gsd { x: 5.0, y: 6.0 }).unwrap(), "[5.0,6.0]");
        assert_eq!(serde_json::to_string(&Gsd::square(0.5)).unwrap(), "0.5");
        assert_eq!(serde_json::from_str::<Gsd>("[5, 6]").unwrap(), Gsd { x: 5.0, y: 6.0 });
        assert_eq!(serde_json::from_str::<Gsd>("0.5").unwrap(), Gsd::square(0.5));
    }

    #[test]
    fn snapping_goes_outward() {
        let g = OutputGrid::snapped(10.2, 20.7, 19.9, 30.1, Gsd::square(1.0)).unwrap();
        assert_eq!((g.x0, g.y0, g.width, g.height), (10.0, 31.0, 10, 11));
    }
}
