//! Conversions between a ground CRS and WGS84 longitude/latitude, and
//! between two ground CRSs through it. Geographic CRSs use (longitude,
//! latitude) in degrees as (X, Y), the order GDAL's geotransforms use.

use super::crs::Crs;
use proj4rs::Proj;

/// A CRS able to convert its (X, Y) to and from WGS84 longitude/latitude.
#[derive(Clone)]
pub struct GroundCrs {
    pub crs: Crs,
    /// `None` for WGS84 longitude/latitude itself: no conversion at all.
    proj: Option<Proj>,
    wgs84: Proj,
    pub geographic: bool,
}

fn wgs84() -> Proj {
    Proj::from_proj_string("+proj=longlat +datum=WGS84 +no_defs").expect("the WGS84 definition parses")
}

impl GroundCrs {
    pub fn new(crs: &Crs) -> Result<GroundCrs, String> {
        let plain_wgs84 = crs.epsg() == Some(4326) || crate::geodesy::crs::same_tokens(crs.proj4(), "+proj=longlat +datum=WGS84 +no_defs");
        let proj = if plain_wgs84 { None } else { Some(crs.proj()?) };
        Ok(GroundCrs { crs: crs.clone(), proj, wgs84: wgs84(), geographic: crs.is_geographic() })
    }

    /// The CRS of an EPSG code, or why it cannot be used.
    pub fn from_epsg(epsg: u32) -> Result<GroundCrs, String> {
        GroundCrs::new(&Crs::from_epsg(epsg)?)
    }

    /// Ground (X, Y) → WGS84 (longitude °, latitude °).
    #[inline]
    pub fn to_lonlat(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let Some(p) = &self.proj else { return Some((x, y)) };
        let (mut a, mut b) = if self.geographic { (x.to_radians(), y.to_radians()) } else { (x, y) };
        let mut pt = (a, b, 0.0);
        proj4rs::transform::transform(p, &self.wgs84, &mut pt).ok()?;
        (a, b) = (pt.0.to_degrees(), pt.1.to_degrees());
        (a.is_finite() && b.is_finite()).then_some((a, b))
    }

    /// WGS84 (longitude °, latitude °) → ground (X, Y).
    #[inline]
    pub fn lonlat_to_ground(&self, lon: f64, lat: f64) -> Option<(f64, f64)> {
        let Some(p) = &self.proj else { return Some((lon, lat)) };
        let mut pt = (lon.to_radians(), lat.to_radians(), 0.0);
        proj4rs::transform::transform(&self.wgs84, p, &mut pt).ok()?;
        let (x, y) = if self.geographic { (pt.0.to_degrees(), pt.1.to_degrees()) } else { (pt.0, pt.1) };
        (x.is_finite() && y.is_finite()).then_some((x, y))
    }

    /// Ground units in one metre near latitude `lat` (1 for metric CRSs).
    pub fn units_per_metre(&self, lat: f64) -> f64 {
        if self.geographic {
            1.0 / (111_320.0 * lat.to_radians().cos().max(0.1))
        } else {
            1.0
        }
    }
}

/// The EPSG code of the WGS84 UTM zone holding (lon, lat): 326zz north,
/// 327zz south.
pub fn utm_zone_epsg(lon: f64, lat: f64) -> u32 {
    let zone = (((lon + 180.0) / 6.0).floor() as i64).rem_euclid(60) as u32 + 1;
    if lat >= 0.0 {
        32600 + zone
    } else {
        32700 + zone
    }
}

/// The WGS84 UTM zone holding (lon, lat).
pub fn utm_zone(lon: f64, lat: f64) -> Crs {
    Crs::from_epsg(utm_zone_epsg(lon, lat)).expect("every UTM zone is known")
}

/// Points of one CRS into another, through WGS84 (identity when both are
/// the same CRS).
#[derive(Clone)]
pub struct Reprojection {
    from: GroundCrs,
    to: GroundCrs,
    identity: bool,
}

impl Reprojection {
    pub fn new(from: &Crs, to: &Crs) -> Result<Reprojection, String> {
        Ok(Reprojection { from: GroundCrs::new(from)?, to: GroundCrs::new(to)?, identity: from == to })
    }

    #[inline]
    /// The CRS converted from, where the target is WGS84 itself: `apply`
    /// then gives that CRS's `to_lonlat` as it is.
    pub fn to_wgs84_from(&self) -> Option<&Crs> {
        (!self.identity && self.to.proj.is_none()).then_some(&self.from.crs)
    }

    pub fn apply(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        if self.identity {
            return Some((x, y));
        }
        let (lon, lat) = self.from.to_lonlat(x, y)?;
        self.to.lonlat_to_ground(lon, lat)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Golden values from `gdaltransform -s_srs EPSG:4326 -t_srs EPSG:32631`
    /// (PROJ 9): Mont Ventoux's summit and a point near the zone's edge.
    #[test]
    fn utm_matches_proj() {
        let utm = GroundCrs::from_epsg(32631).unwrap();
        for ((lon, lat), (x, y)) in
            [((5.2786, 44.1741), (682_151.139_274_756, 4_893_734.670_923_61)), ((0.5, 45.2), (303_648.799_038_255, 5_008_208.824_334_69))]
        {
            let (px, py) = utm.lonlat_to_ground(lon, lat).unwrap();
            assert!((px - x).abs() < 1e-3 && (py - y).abs() < 1e-3, "({px}, {py}) vs ({x}, {y})");
            let (l, p) = utm.to_lonlat(x, y).unwrap();
            assert!((l - lon).abs() < 1e-9 && (p - lat).abs() < 1e-9);
        }
    }

    #[test]
    fn zones() {
        assert_eq!(utm_zone_epsg(5.28, 44.1), 32631);
        assert_eq!(utm_zone_epsg(-56.2, -34.9), 32721);
        assert_eq!(utm_zone_epsg(179.9, 1.0), 32660);
        assert_eq!(utm_zone_epsg(-180.0, 1.0), 32601);
    }

    #[test]
    fn unknown_codes_are_refused() {
        assert!(GroundCrs::from_epsg(999_999).is_err());
    }
}
