//! Geoid undulation grids in PROJ's two forms: `.gtx` (a 40-byte
//! big-endian header — latitude and longitude of the south-west sample,
//! the two steps in degrees, rows, columns — and rows × columns big-endian
//! f32, south row first) and GeoTIFF (PROJ's current grids, e.g.
//! `us_nga_egm96_15.tif`: one band on longitude/latitude). Ellipsoidal
//! height h = H + N(φ, λ), N interpolated bilinearly (as PROJ's
//! `vgridshift`). A `.gtx` is memory-mapped and a large GeoTIFF read a
//! tile at a time: a scene reads the few pages under it, also of a global
//! grid at 1′ (900 MB).

use crate::error::{Error, Result};
use crate::io::cached_raster::{CachedRaster, Rescale};
use crate::io::chunked_raster::ChunkedRaster;
use crate::io::geotiff::read_georef;
use std::path::{Path, PathBuf};

/// GeoTIFF grids up to this size are read whole.
const IN_MEMORY: u64 = 64 << 20;

/// PROJ's "no value" for `.gtx` grids.
const GTX_NODATA: f32 = -88.8888;

#[derive(Clone, Debug)]
pub struct Geoid {
    lat0: f64,
    lon0: f64,
    dlat: f64,
    dlon: f64,
    rows: usize,
    cols: usize,
    /// Whether the columns go once around the globe (longitudes wrap).
    global: bool,
    n: Samples,
    pub path: PathBuf,
}

/// The grid's samples, south row first: decoded, big-endian in the mapped
/// `.gtx` (after its 40-byte header), or a GeoTIFF's (north row first).
#[derive(Clone, Debug)]
enum Samples {
    Owned(Vec<f32>),
    Mapped(std::sync::Arc<crate::io::mapped_file::MappedFile>),
    Raster(Raster),
}

/// A large GeoTIFF grid, read a tile at a time (north row first; holes NaN).
#[derive(Clone)]
struct Raster(std::sync::Arc<CachedRaster>);

impl std::fmt::Debug for Raster {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Raster({}×{})", self.0.raster().width, self.0.raster().height)
    }
}

impl Samples {
    /// Sample `k` counted from the south-west, row by row; NaN for no value.
    #[inline]
    fn at(&self, k: usize, cols: usize) -> f32 {
        match self {
            Samples::Owned(v) => v[k],
            Samples::Mapped(m) => f32::from_be_bytes(m[40 + 4 * k..44 + 4 * k].try_into().expect("4 bytes")),
            Samples::Raster(Raster(g)) => g.get(k % cols, g.raster().height - 1 - k / cols),
        }
    }
}

impl Geoid {
    /// An error naming a mapped `.gtx` grid truncated while it was read.
    pub fn check_intact(&self) -> crate::error::Result<()> {
        match &self.n {
            Samples::Mapped(m) => m.check_intact(),
            _ => Ok(()),
        }
    }

    /// A `.gtx` or GeoTIFF geoid grid.
    pub fn read(path: &Path) -> Result<Geoid> {
        let head = crate::io::bounded_read::read_head(path, 40)?;
        if [b"II*\0", b"MM\0*", b"II+\0", b"MM\0+"].iter().any(|m| head.starts_with(m.as_slice())) {
            return Geoid::read_geotiff(path, IN_MEMORY);
        }
        // The header says how large the grid is: a file of another size is
        // refused before it is read.
        let len = std::fs::metadata(path).map_err(|e| Error::io(path, e))?.len();
        if head.len() == 40 {
            let rows = i32::from_be_bytes(head[32..36].try_into().expect("4 bytes")) as i64;
            let cols = i32::from_be_bytes(head[36..40].try_into().expect("4 bytes")) as i64;
            let want = rows.checked_mul(cols).and_then(|n| n.checked_mul(4)).and_then(|n| n.checked_add(40));
            if rows < 2 || cols < 2 || want != Some(len as i64) {
                return Err(Error::format(path, format!("not a .gtx geoid grid: a header of {rows}×{cols} in a file of {len} bytes")));
            }
        }
        if head.len() < 40 {
            return Err(Error::format(path, "not a .gtx geoid grid: shorter than its 40-byte header"));
        }
        let map = crate::io::mapped_file::MappedFile::open(path, len)?;
        let mut g = Geoid::parse_header(&map, path)?;
        g.n = Samples::Mapped(std::sync::Arc::new(map));
        Ok(g)
    }

    /// A GeoTIFF grid (PROJ's form since PROJ 7): one band of undulations
    /// on WGS84 (or another geographic CRS on its ellipsoid) longitude and
    /// latitude, north-up; held whole up to `max_bytes`, else read a tile
    /// at a time.
    pub fn read_geotiff(path: &Path, max_bytes: u64) -> Result<Geoid> {
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let mut dec =
            tiff::decoder::Decoder::new(std::io::BufReader::new(file)).map_err(|e| Error::from_tiff(path, e))?.with_limits(crate::io::format::decoder_limits());
        let raster = ChunkedRaster::open(&mut dec, path)?;
        let geo = read_georef(&mut dec, path)?.ok_or_else(|| Error::format(path, "a geoid grid without georeferencing (no ModelPixelScale/ModelTiepoint)"))?;
        if let Some(crs) = super::geokeys::crs_of(&geo.keys).map_err(|m| Error::format(path, format!("its GeoTIFF keys: {m}")))? {
            if !crs.is_geographic() {
                return Err(Error::format(path, format!("a geoid grid must be on longitude and latitude; its GeoTIFF keys say {crs}")));
            }
        }
        let gt = geo.transform;
        if gt[2] != 0.0 || gt[4] != 0.0 || !(gt[1] > 0.0) || !(gt[5] < 0.0) {
            return Err(Error::unsupported(path, format!("a geoid grid must be north-up (geotransform {gt:?})")));
        }
        let (cols, rows) = (raster.width, raster.height);
        if cols < 2 || rows < 2 {
            return Err(Error::format(path, format!("a geoid grid of {cols}×{rows} samples: at least 2×2 are needed")));
        }
        // Stored values to undulations, holes to NaN (as a .gtx's no-value).
        let rescale = Rescale { scale: geo.scale_offset.map_or(1.0, |s| s.0), offset: geo.scale_offset.map_or(0.0, |s| s.1), nodata: geo.nodata };
        // Sample centres: the south-west one and the steps, as a .gtx says them.
        let (dlon, dlat) = (gt[1], -gt[5]);
        let lon0 = gt[0] + 0.5 * dlon;
        let lat0 = gt[3] + gt[5] * (rows as f64 - 0.5);
        if !(lat0 >= -90.5 && lat0 + dlat * (rows - 1) as f64 <= 90.5) {
            return Err(Error::format(
                path,
                format!("a geoid grid must be on longitude and latitude; its latitudes run {lat0}..{}", lat0 + dlat * (rows - 1) as f64),
            ));
        }
        let global = (dlon * cols as f64 - 360.0).abs() < dlon * 1.01;
        let n = if (cols * rows) as u64 * 4 <= max_bytes {
            // Small (a national grid, EGM96 at 15′): whole, south row first.
            let mut v = raster.read_all()?;
            rescale.apply(&mut v);
            Samples::Owned(v.chunks_exact(cols).rev().flatten().copied().collect())
        } else {
            // A few tiles of cache: the lookups of a scene fall in a few.
            let (cw, ch) = raster.chunk;
            let cache = (16usize << 20).max(4 * cw * ch * 4);
            Samples::Raster(Raster(std::sync::Arc::new(CachedRaster::new(raster, cache, Some(rescale)))))
        };
        Ok(Geoid { lat0, lon0, dlat, dlon, rows, cols, global, n, path: path.to_path_buf() })
    }

    /// A grid from the bytes of a `.gtx` file.
    pub fn parse(bytes: &[u8], path: &Path) -> Result<Geoid> {
        let mut g = Geoid::parse_header(bytes, path)?;
        g.n = Samples::Owned(bytes[40..].chunks_exact(4).map(|b| f32::from_be_bytes([b[0], b[1], b[2], b[3]])).collect());
        Ok(g)
    }

    /// The grid `bytes` (a whole file) describes, its samples not yet taken.
    fn parse_header(bytes: &[u8], path: &Path) -> Result<Geoid> {
        if bytes.len() < 40 {
            return Err(Error::format(path, "not a .gtx geoid grid: shorter than its 40-byte header"));
        }
        let f = |i: usize| f64::from_be_bytes(bytes[8 * i..8 * i + 8].try_into().expect("8 bytes"));
        let (lat0, lon0, dlat, dlon) = (f(0), f(1), f(2), f(3));
        let rows = i32::from_be_bytes(bytes[32..36].try_into().expect("4 bytes"));
        let cols = i32::from_be_bytes(bytes[36..40].try_into().expect("4 bytes"));
        let sane =
            [lat0, lon0, dlat, dlon].iter().all(|v| v.is_finite()) && dlat > 0.0 && dlon > 0.0 && (-90.0..=90.0).contains(&lat0) && rows >= 2 && cols >= 2;
        if !sane {
            return Err(Error::format(path, format!("not a .gtx geoid grid: header {lat0} {lon0} {dlat} {dlon} {rows}×{cols}")));
        }
        let (rows, cols) = (rows as usize, cols as usize);
        let want = rows.checked_mul(cols).and_then(|n| n.checked_mul(4)).and_then(|n| n.checked_add(40));
        if want != Some(bytes.len()) {
            return Err(Error::format(
                path,
                format!(".gtx grid of {rows}×{cols} needs {} bytes, the file has {}", want.map_or("too many".into(), |w| w.to_string()), bytes.len()),
            ));
        }
        let global = (dlon * cols as f64 - 360.0).abs() < dlon * 1.01;
        Ok(Geoid { lat0, lon0, dlat, dlon, rows, cols, global, n: Samples::Owned(Vec::new()), path: path.to_path_buf() })
    }

    /// N (metres) at (longitude °, latitude °), or `None` outside the grid
    /// or next to a sample without value.
    /// What the grid covers: west, south, east, north, degrees.
    pub fn extent(&self) -> [f64; 4] {
        let east = if self.global { self.lon0 + 360.0 } else { self.lon0 + self.dlon * (self.cols - 1) as f64 };
        [self.lon0, self.lat0, east, self.lat0 + self.dlat * (self.rows - 1) as f64]
    }

    pub fn undulation(&self, lon: f64, lat: f64) -> Option<f64> {
        let y = (lat - self.lat0) / self.dlat;
        let mut x = (lon - self.lon0) / self.dlon;
        if self.global {
            x = x.rem_euclid(self.cols as f64);
        }
        if !(y >= 0.0 && y <= (self.rows - 1) as f64 && x >= 0.0) {
            return None;
        }
        let (i, j) = (x.floor() as usize, (y.floor() as usize).min(self.rows - 2));
        let i1 = if i + 1 < self.cols {
            i + 1
        } else if self.global {
            (i + 1) % self.cols
        } else if x <= (self.cols - 1) as f64 {
            i
        } else {
            return None;
        };
        let (fx, fy) = (x - i as f64, y - j as f64);
        let at = |c: usize, r: usize| self.n.at(r * self.cols + c, self.cols);
        let v = [at(i, j), at(i1, j), at(i, j + 1), at(i1, j + 1)];
        if v.iter().any(|&s| s == GTX_NODATA || !s.is_finite()) {
            return None;
        }
        let [a, b, c, d] = v.map(f64::from);
        Some((a * (1.0 - fx) + b * fx) * (1.0 - fy) + (c * (1.0 - fx) + d * fx) * fy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(lon0: f64, cols: i32, dlon: f64) -> Vec<u8> {
        let mut b = Vec::new();
        for v in [10.0f64, lon0, 1.0, dlon] {
            b.extend_from_slice(&v.to_be_bytes());
        }
        b.extend_from_slice(&2i32.to_be_bytes());
        b.extend_from_slice(&cols.to_be_bytes());
        // N = column + 10·row
        for r in 0..2 {
            for c in 0..cols {
                b.extend_from_slice(&((c + 10 * r) as f32).to_be_bytes());
            }
        }
        b
    }

    #[test]
    fn bilinear_and_edges() {
        let g = Geoid::parse(&grid(0.0, 3, 1.0), Path::new("g.gtx")).unwrap();
        assert_eq!(g.undulation(0.5, 10.5), Some(5.5));
        assert_eq!(g.undulation(2.0, 11.0), Some(12.0));
        assert_eq!(g.undulation(2.5, 10.5), None);
        assert_eq!(g.undulation(1.0, 9.9), None);
    }

    #[test]
    fn global_grids_wrap_in_longitude() {
        let g = Geoid::parse(&grid(-180.0, 4, 90.0), Path::new("g.gtx")).unwrap();
        // Between the last column (90°E, N = 3) and the first (180°W = 180°E, N = 0).
        assert!((g.undulation(135.0, 10.0).unwrap() - 1.5).abs() < 1e-12);
        assert!((g.undulation(-225.0, 10.0).unwrap() - 1.5).abs() < 1e-12);
    }

    #[test]
    fn broken_headers_are_refused() {
        let mut b = grid(0.0, 3, 1.0);
        b.truncate(50);
        let e = Geoid::parse(&b, Path::new("cut.gtx")).unwrap_err().to_string();
        assert!(e.contains("cut.gtx") && e.contains("bytes"), "{e}");
        assert!(Geoid::parse(&[0u8; 12], Path::new("x.gtx")).is_err());
    }
}
