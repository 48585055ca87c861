//! A height grid read from its file: a GeoTIFF (its georeferencing from
//! its tags, GDAL's `.aux.xml` or a `.prj` beside it), an SRTM `.hgt` tile,
//! or tiles of these; the collar of nodata around a DSM's data found.

use super::{check_north_up, collar, mosaic, Collar, GridDem, Samples};
use crate::error::{Error, Result};
use crate::geodesy::Crs;
use crate::io::cached_raster::{CachedRaster, Rescale};
use crate::io::chunked_raster::ChunkedRaster;
use crate::io::geotiff::{read_georef, GeoRef};
use std::path::{Path, PathBuf};

impl GridDem {
    /// Reads a single-band GeoTIFF (Int16, UInt16, Int32, Float32, Float64, ...),
    /// an SRTM `.hgt` tile, or tiles of these: a GDAL VRT mosaic or a folder.
    #[cfg(any(test, feature = "internals"))]
    pub fn read(path: &Path) -> Result<GridDem> {
        GridDem::read_within(path, super::IN_MEMORY_LIMIT)
    }

    /// As `read`, holding at most about `max_bytes` of heights in memory:
    /// a larger grid is read a chunk at a time into a cache of that size.
    pub fn read_within(path: &Path, max_bytes: u64) -> Result<GridDem> {
        let mut g = GridDem::read_posts(path, max_bytes)?;
        g.find_collar();
        Ok(g)
    }

    /// Finds the grid's [`Collar`]: the nodata cut around a DSM's data.
    /// A grid read a chunk at a time is read once for it, a band of chunk
    /// rows at a time (a DSM warped to another CRS, past the in-memory
    /// size, kept its collar as holes); a band that cannot be read leaves
    /// every nodata post a hole, as the lookups there will say.
    pub(super) fn find_collar(&mut self) {
        let collar = match &self.data {
            Samples::Memory(v) => Collar::find(self.width, self.height, |j, out| {
                collar::runs_of(v[j * self.width..(j + 1) * self.width].iter().copied(), |z| self.is_nodata(z), out)
            }),
            Samples::Hgt(_) => {
                Collar::find(self.width, self.height, |j, out| collar::runs_of((0..self.width).map(|i| self.sample(i, j)), |z| self.is_nodata(z), out))
            }
            Samples::Chunked(c) => {
                let (w, h) = (self.width, self.height);
                let ch = c.raster().chunk.1.max(1);
                // A band of whole chunk rows where it fits 16 MB, else fewer rows.
                let band = ch.min(((16usize << 20) / (w * 4).max(1)).max(1));
                // The band held: its first row, and its rows.
                let (mut rows, mut first, mut failed) = (Vec::new(), None, false);
                let collar = Collar::find(w, h, |j, out| {
                    if failed {
                        return;
                    }
                    if !first.is_some_and(|f| (f..f + band).contains(&j)) {
                        first = Some(j);
                        match c.read_window([0, j, w, band.min(h - j)]) {
                            Ok(v) => rows = v,
                            Err(_) => {
                                failed = true;
                                return;
                            }
                        }
                    }
                    let k = j - first.unwrap_or(j);
                    let row = &rows[k * w..(k + 1) * w];
                    collar::runs_of(row.iter().copied(), |z| self.is_nodata(z), out)
                });
                collar.filter(|_| !failed)
            }
            Samples::Window { .. } | Samples::Mosaic(_) => None,
        };
        self.collar = collar.map(std::sync::Arc::new);
    }

    #[cfg(test)]
    /// How many nodata posts are joined to the grid's edge (outside the
    /// DEM's data, not holes in it).
    pub fn collar_posts(&self) -> u64 {
        self.collar.as_ref().map_or(0, |c| c.posts())
    }

    /// As [`GridDem::read_within`], without looking for the collar (a
    /// mosaic's tile, a file read again for a window of it).
    pub(crate) fn read_posts(path: &Path, max_bytes: u64) -> Result<GridDem> {
        if mosaic::is_mosaic(path) {
            let (m, g) = mosaic::open(path, max_bytes)?;
            mosaic::check(path, &g)?;
            let t = g.transform;
            let dem = GridDem {
                width: g.width,
                height: g.height,
                data: Samples::Mosaic(m),
                transform: t,
                nodata: None,
                crs: g.crs,
                inv_step: (1.0 / t[1], 1.0 / t[5]),
                collar: None,
            };
            if dem.samples((dem.width * dem.height / 20_000).max(1)).iter().all(|v| v.is_nan()) {
                return Err(Error::format(path, "no tile of the DEM mosaic has a height"));
            }
            return Ok(dem);
        }
        if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("hgt")) {
            return read_hgt(path);
        }
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let mut dec =
            tiff::decoder::Decoder::new(std::io::BufReader::new(file)).map_err(|e| Error::from_tiff(path, e))?.with_limits(crate::io::format::decoder_limits());
        let raster = ChunkedRaster::open(&mut dec, path)?;
        let (w, h) = (raster.width as u32, raster.height as u32);
        let (geo, aux_crs) = match read_georef(&mut dec, path)? {
            Some(g) => (g, None),
            None => {
                let tiff_nodata = crate::io::geotiff::read_nodata(&mut dec, path)?;
                let (mut g, crs) = aux_xml_beside(path)?.ok_or_else(|| {
                    Error::format(path, "the DEM has no georeferencing (no ModelPixelScale/ModelTiepoint, nor a GeoTransform in an .aux.xml beside it)")
                })?;
                g.nodata = g.nodata.or(tiff_nodata);
                (g, crs)
            }
        };
        check_north_up(&geo, path)?;
        let crs = match crate::geodesy::geokeys::crs_of(&geo.keys).map_err(|m| Error::format(path, format!("its GeoTIFF keys: {m}")))? {
            Some(c) => Some(c),
            None => aux_crs.map_or_else(|| prj_beside(path), |c| Ok(Some(c)))?,
        };
        if w < 2 || h < 2 {
            return Err(Error::format(path, format!("a DEM of {w}×{h} posts: heights are interpolated between posts, so at least 2×2 are needed")));
        }
        let rescale = geo.scale_offset.map(|(scale, offset)| Rescale { scale, offset, nodata: geo.nodata });
        // Rescaled, holes are NaN: the stored nodata value is no height's.
        let nodata = if rescale.is_some() { None } else { geo.nodata };
        let pixels = (w as u64) * (h as u64);
        if pixels > 1 << 40 {
            return Err(Error::limits(path, format!("DEM of {w}×{h} samples is too large")));
        }
        if pixels * 4 > max_bytes {
            // Out of core: chunks decoded on demand into a cache of at most
            // 16 MB within the budget.
            // The first chunk's error, if any, names the problem now.
            raster.chunk(0)?;
            let (cw, ch) = raster.chunk;
            let cache = (max_bytes as usize).min(16 << 20);
            let chunk_bytes = cw * ch * 4;
            let keep = (cache / chunk_bytes).max(crate::io::cached_raster::least_chunks(&raster));
            let chunked = CachedRaster::new(raster, keep * chunk_bytes, rescale);
            let gt = geo.transform;
            let g = GridDem {
                width: w as usize,
                height: h as usize,
                data: Samples::Chunked(Box::new(chunked)),
                transform: gt,
                nodata,
                crs,
                inv_step: (1.0 / gt[1], 1.0 / gt[5]),
                collar: None,
            };
            // A readable first chunk, or a clear error now rather than NaNs later.
            if g.sample(0, 0).is_nan() && g.samples((pixels / 1000).max(1) as usize).iter().all(|v| v.is_nan()) {
                return Err(Error::format(path, "the DEM's data cannot be read (or is all NaN)"));
            }
            return Ok(g);
        }
        let mut data = raster.read_all()?;
        if let Some(r) = rescale {
            r.apply(&mut data);
        }
        let g = GridDem::new(w as usize, h as usize, data, geo.transform, nodata, crs);
        if g.samples(1).iter().all(|&v| g.is_nodata(v)) {
            return Err(Error::format(path, "every sample of the DEM is nodata"));
        }
        Ok(g)
    }
}

/// The georeferencing GDAL keeps beside a raster whose own tags hold none
/// (`FILE.aux.xml`, as a baseline TIFF profile writes it): the
/// geotransform, the first band's nodata, scale and offset, and the SRS.
fn aux_xml_beside(path: &Path) -> Result<Option<(GeoRef, Option<Crs>)>> {
    let mut name = path.as_os_str().to_owned();
    name.push(".aux.xml");
    let aux = PathBuf::from(name);
    if !aux.is_file() {
        return Ok(None);
    }
    let text = crate::io::bounded_read::read_text_bounded(&aux, "GDAL's .aux.xml", crate::io::bounded_read::SMALL)?;
    let doc = roxmltree::Document::parse(&text).map_err(|e| Error::format(&aux, format!("is not XML: {e}")))?;
    let root = doc.root_element();
    fn child<'a>(n: roxmltree::Node<'a, '_>, tag: &str) -> Option<&'a str> {
        n.children().find(|c| c.has_tag_name(tag)).and_then(|c| c.text()).map(str::trim)
    }
    let Some(gt) = child(root, "GeoTransform") else { return Ok(None) };
    let gt: Vec<f64> =
        gt.split(',').map(|v| v.trim().parse().map_err(|_| Error::format(&aux, format!("GeoTransform '{gt}' is not six numbers")))).collect::<Result<_>>()?;
    let transform: [f64; 6] = gt.try_into().map_err(|_| Error::format(&aux, "a GeoTransform of other than six numbers"))?;
    super::check_transform(&transform).map_err(|m| Error::format(&aux, format!("GeoTransform: {m}")))?;
    let crs = child(root, "SRS")
        .filter(|t| !t.is_empty())
        .map(|t| Crs::parse(t, path.parent().unwrap_or(Path::new("."))).map_err(|m| Error::format(&aux, format!("its SRS: {m}"))))
        .transpose()?;
    let band = root.children().find(|c| c.has_tag_name("PAMRasterBand") && c.attribute("band").is_none_or(|b| b.trim() == "1"));
    let number = |tag: &str| band.and_then(|b| child(b, tag)).and_then(|t| t.parse::<f64>().ok());
    let scale_offset = match (number("Scale"), number("Offset")) {
        (None, None) => None,
        (s, o) => Some((s.unwrap_or(1.0), o.unwrap_or(0.0))).filter(|&so| so != (1.0, 0.0)),
    };
    let geo = GeoRef { transform, keys: Default::default(), nodata: number("NoDataValue"), scale_offset, source: None };
    Ok(Some((geo, crs)))
}

/// The CRS of a `.prj` file beside a raster whose keys name none.
fn prj_beside(path: &Path) -> Result<Option<Crs>> {
    let prj = path.with_extension("prj");
    if !prj.is_file() {
        return Ok(None);
    }
    Crs::parse(&prj.to_string_lossy(), Path::new("")).map(Some).map_err(|m| Error::format(&prj, m))
}

/// An SRTM `.hgt` tile: big-endian Int16, 1201² (3″) or 3601² (1″) samples on
/// whole-degree lines, named after its south-west corner (e.g. N44E005).
fn read_hgt(path: &Path) -> Result<GridDem> {
    // The size says which tile it is: map only one that is a tile.
    let len = std::fs::metadata(path).map_err(|e| Error::io(path, e))?.len();
    let n = match len {
        l if l == 1201 * 1201 * 2 => 1201,
        l if l == 3601 * 3601 * 2 => 3601,
        l => return Err(Error::format(path, format!("{l} bytes is not the size of a 1201² or 3601² SRTM tile"))),
    };
    let name = path.file_stem().and_then(|s| s.to_str()).unwrap_or("").to_ascii_uppercase();
    let parse = || -> Option<(f64, f64)> {
        let (ns, rest) = name.split_at(1);
        let lat_end = rest.find(['E', 'W'])?;
        let lat: f64 = rest[..lat_end].parse().ok()?;
        let (ew, lon) = rest[lat_end..].split_at(1);
        let lon: f64 = lon.parse().ok()?;
        let lat = if ns == "S" {
            -lat
        } else if ns == "N" {
            lat
        } else {
            return None;
        };
        let lon = if ew == "W" { -lon } else { lon };
        Some((lat, lon))
    };
    let (lat, lon) = parse().ok_or_else(|| Error::format(path, "an .hgt file must be named like N44E005.hgt"))?;
    let d = 1.0 / (n - 1) as f64;
    let map = crate::io::mapped_file::MappedFile::open(path, len)?;
    let t = [lon - 0.5 * d, d, 0.0, lat + 1.0 + 0.5 * d, 0.0, -d];
    Ok(GridDem {
        width: n,
        height: n,
        data: Samples::Hgt(std::sync::Arc::new(map)),
        transform: t,
        nodata: Some(-32768.0),
        crs: Some(Crs::wgs84()),
        inv_step: (1.0 / t[1], 1.0 / t[5]),
        collar: None,
    })
}

/// A DEM without a nodata tag whose heights include a value that only a
/// void has (-32768, -32767, -9999, -99999, below -1e30): read as a height,
/// each void would pull the terrain kilometres down. That value becomes its
/// nodata, and the warning says so.
pub(super) fn tag_untagged_voids(g: &mut GridDem, path: &Path) -> Option<String> {
    if g.nodata.is_some() {
        return None;
    }
    let step = (g.width * g.height / 250_000).max(1);
    let void = g.samples(step).into_iter().find(|&v| [-32768.0, -32767.0, -9999.0, -99999.0].contains(&v) || v < -1.0e30)?;
    g.nodata = Some(void as f64);
    Some(format!(
        "{}: heights of {void} m and no nodata tag: taken as voids (holes), not heights; tag them to say so (gdal_edit.py -a_nodata {void})",
        path.display()
    ))
}
