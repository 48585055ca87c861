//! The run's terrain: a height model with its policies for holes and
//! points outside, its windows of posts, its summaries and trend plane.

use super::read::tag_untagged_voids;
use super::{mosaic, Dem, GridDem, Height, HeightModel, Lookup, Miss, Samples, IN_MEMORY_LIMIT};
use crate::error::{Error, Result};
use crate::geodesy::{Crs, Reprojection};
use crate::geom::Plane;
use std::path::{Path, PathBuf};

impl Dem {
    /// See [`GridDem::check_intact`].
    pub fn check_intact(&self) -> Result<()> {
        match &self.model {
            HeightModel::Grid(g) => g.check_intact(),
            HeightModel::Flat(_) => Ok(()),
        }
    }

    /// The most its heights hold in memory, bytes.
    pub fn held_bytes(&self) -> u64 {
        match &self.model {
            HeightModel::Flat(_) => 0,
            HeightModel::Grid(g) => g.held_bytes(),
        }
    }

    /// Is it one grid file (what [`Dem::posts_for`] reads a window of)?
    pub fn is_grid(&self) -> bool {
        matches!(&self.model, HeightModel::Grid(g) if matches!(g.data, Samples::Memory(_) | Samples::Chunked(_) | Samples::Window { .. }))
    }

    /// The posts under the ground box `b` (ground CRS) and `margin` around
    /// it: `[i0, j0, width, height]`, where the DEM is one grid.
    pub(super) fn posts_under(&self, b: [f64; 4], margin: usize) -> Option<[usize; 4]> {
        const ALONG: usize = 32;
        let HeightModel::Grid(g) = &self.model else { return None };
        // The box's edge, densely, in the grid's samples.
        let mut edge = Vec::with_capacity(4 * (ALONG + 1));
        for k in 0..=ALONG {
            let t = k as f64 / ALONG as f64;
            let (x, y) = (b[0] + t * (b[2] - b[0]), b[1] + t * (b[3] - b[1]));
            edge.extend([(x, b[1]), (x, b[3]), (b[0], y), (b[2], y)]);
        }
        let mut span = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
        for (x, y) in edge {
            let (gx, gy) = self.in_grid_crs(x, y)?;
            let (c, r) = g.sample_coords(gx, gy);
            span = [span[0].min(c), span[1].min(r), span[2].max(c), span[3].max(r)];
        }
        if !span.iter().all(|v| v.is_finite()) {
            return None;
        }
        let m = margin as f64;
        let clamp = |v: f64, n: usize| v.clamp(0.0, n as f64) as usize;
        let (i0, j0) = (clamp(span[0].floor() - m, g.width), clamp(span[1].floor() - m, g.height));
        let (i1, j1) = (clamp(span[2].ceil() + 1.0 + m, g.width), clamp(span[3].ceil() + 1.0 + m, g.height));
        Some([i0, j0, i1.saturating_sub(i0), j1.saturating_sub(j0)])
    }

    /// The bytes of the posts under `b` (and `margin` around).
    pub fn bytes_under(&self, b: [f64; 4], margin: usize) -> u64 {
        self.posts_under(b, margin).map_or(0, |[_, _, w, h]| w as u64 * h as u64 * 4)
    }

    /// A DEM of the same file holding in memory only the posts under `b`
    /// (and `margin` around), read again from the file, the rest through a
    /// small cache: the heights of a strip of a mosaic, let go with it.
    /// Where the posts take more than `max_bytes`, all through a cache of
    /// `cache_bytes` (the least chunks at least). `None` where this DEM is not
    /// one grid file (this one then serves).
    pub fn posts_for(&self, b: [f64; 4], margin: usize, max_bytes: u64, cache_bytes: u64) -> Result<Option<Dem>> {
        let HeightModel::Grid(g) = &self.model else { return Ok(None) };
        if !matches!(g.data, Samples::Memory(_) | Samples::Chunked(_) | Samples::Window { .. }) {
            return Ok(None);
        }
        let Some(at @ [_, _, w, h]) = self.posts_under(b, margin) else { return Ok(None) };
        let bytes = w as u64 * h as u64 * 4;
        if w < 2 || h < 2 {
            return Ok(None);
        }
        // (Budget 0: read a chunk at a time, the least cache.)
        let Samples::Chunked(rest) = GridDem::read_posts(&self.path, 0)?.data else { return Ok(None) };
        let data = match bytes <= max_bytes {
            true => Samples::Window { at, data: rest.read_window(at)?, rest },
            false => Samples::Chunked(Box::new(rest.recached(cache_bytes as usize))),
        };
        let grid = GridDem { data, crs: g.crs.clone(), collar: g.collar.clone(), ..*g };
        Ok(Some(Dem {
            model: HeightModel::Grid(grid),
            on_hole: self.on_hole,
            on_outside: self.on_outside,
            path: self.path.clone(),
            to_dem: self.to_dem.clone(),
            warnings: Vec::new(),
            mean: self.mean.clone(),
            range: self.range.clone(),
        }))
    }

    /// Lets go of the posts held in memory (read whole, a window, or a
    /// large cache), the file then read through the least cache (where the
    /// DEM is one grid file): once a mosaic's strips hold their own
    /// ([`Dem::posts_for`]).
    pub fn let_go_of_posts(&mut self) -> Result<()> {
        let HeightModel::Grid(g) = &mut self.model else { return Ok(()) };
        match std::mem::replace(&mut g.data, Samples::Memory(Vec::new())) {
            // A grid read through a cache keeps the least one.
            Samples::Chunked(c) => g.data = Samples::Chunked(Box::new(c.recached(0))),
            held @ (Samples::Memory(_) | Samples::Window { .. }) => {
                g.data = held;
                if let Samples::Chunked(c) = GridDem::read_posts(&self.path, 0)?.data {
                    g.data = Samples::Chunked(c);
                }
            }
            other => g.data = other,
        }
        Ok(())
    }

    /// Holds in memory the posts under the ground box `b` (ground CRS)
    /// and `margin` posts around it, where they take at most `max_bytes`:
    /// a mosaic looks up its own ground, often a small part of a large
    /// DEM. Lookups elsewhere still find the file's heights, through a
    /// small cache. One whose box does not fit is read through a cache of
    /// up to 16 MB within `max_bytes` (read whole or not). Returns whether
    /// it holds them.
    pub fn hold_window(&mut self, b: [f64; 4], margin: usize, max_bytes: u64) -> Result<bool> {
        let Some([i0, j0, w, h]) = self.posts_under(b, margin) else { return Ok(false) };
        let bytes = w as u64 * h as u64 * 4;
        let HeightModel::Grid(g) = &mut self.model else { return Ok(false) };
        let at = [i0, j0, w, h];
        let whole = at == [0, 0, g.width, g.height];
        match g.data {
            Samples::Chunked(_) => {
                let Samples::Chunked(c) = std::mem::replace(&mut g.data, Samples::Memory(Vec::new())) else { unreachable!("matched above") };
                if bytes > max_bytes || w < 2 || h < 2 {
                    // As a grid larger than its budget is read: up to 16 MB of it.
                    g.data = Samples::Chunked(Box::new(c.recached((max_bytes as usize).min(16 << 20))));
                    return Ok(false);
                }
                let data = match c.read_window(at) {
                    Ok(d) => d,
                    Err(e) => {
                        g.data = Samples::Chunked(c);
                        return Err(e);
                    }
                };
                g.data = match whole {
                    true => Samples::Memory(data),
                    false => Samples::Window { at, data, rest: Box::new(c.recached(0)) },
                };
                Ok(true)
            }
            // Read whole, but its window past the budget: read again
            // through a cache of that size.
            Samples::Memory(_) if bytes > max_bytes || w < 2 || h < 2 => {
                let Samples::Chunked(c) = GridDem::read_posts(&self.path, 0)?.data else { return Ok(false) };
                g.data = Samples::Chunked(Box::new(c.recached((max_bytes as usize).min(16 << 20))));
                Ok(false)
            }
            // Read whole: the window kept, the rest read again from the
            // file where looked up.
            Samples::Memory(_) if !whole => {
                // (Budget 0: the least cache.)
                let rest = match GridDem::read_posts(&self.path, 0) {
                    Ok(GridDem { data: Samples::Chunked(c), .. }) => c,
                    _ => return Ok(false),
                };
                let Samples::Memory(all) = std::mem::replace(&mut g.data, Samples::Memory(Vec::new())) else { unreachable!("matched above") };
                let mut data = Vec::with_capacity(w * h);
                for j in j0..j0 + h {
                    data.extend_from_slice(&all[j * g.width + i0..j * g.width + i0 + w]);
                }
                g.data = Samples::Window { at, data, rest };
                Ok(true)
            }
            _ => Ok(false),
        }
    }

    pub(super) fn of(model: HeightModel, path: PathBuf) -> Dem {
        Dem {
            model,
            on_hole: Miss::Error,
            on_outside: Miss::Error,
            path,
            to_dem: None,
            warnings: Vec::new(),
            mean: std::sync::OnceLock::new(),
            range: std::sync::OnceLock::new(),
        }
    }

    pub fn flat(z: f64) -> Dem {
        Dem::of(HeightModel::Flat(z), PathBuf::from("(flat)"))
    }

    pub fn grid(g: GridDem, path: &Path) -> Dem {
        Dem::of(HeightModel::Grid(g), path.to_path_buf())
    }

    /// The files a DEM given as a folder, a list of tiles or a VRT reads
    /// (none for a single file): inputs no command may write over.
    pub fn tile_files(path: &Path) -> Vec<PathBuf> {
        mosaic::files_of(path)
    }

    /// Reads a DEM for an orthophoto in the CRS `ground`. A DEM in another CRS
    /// (SRTM in EPSG:4326 under a UTM orthophoto) is looked up through a
    /// reprojection; one without a CRS is taken to be in the ground CRS.
    pub fn open(path: &Path, ground: &Crs) -> Result<Dem> {
        Dem::open_within(path, ground, IN_MEMORY_LIMIT)
    }

    /// As `open`, holding at most about `max_bytes` of heights in memory.
    pub fn open_within(path: &Path, ground: &Crs, max_bytes: u64) -> Result<Dem> {
        let mut g = GridDem::read_within(path, max_bytes)?;
        let mut warnings: Vec<String> = tag_untagged_voids(&mut g, path).into_iter().collect();
        if let Some(unit) = crate::io::geotiff::foot_unit_of(path) {
            warnings.push(format!("{}: heights in {unit} (as the file says): taken into metres", path.display()));
        }
        if let Some(unit) = crate::io::geotiff::unknown_unit_of(path) {
            warnings.push(format!(
                "{}: heights in '{unit}' (as the file says), a unit not read here: taken as metres; if they are not, convert the DEM to metres",
                path.display()
            ));
        }
        let [bx0, by0, bx1, by1] = g.bounds();
        let centre = (0.5 * (bx0 + bx1), 0.5 * (by0 + by1));
        let to_dem = match &g.crs {
            // Not the ground CRS, nor that CRS spelled another way.
            Some(e) if !e.agrees_at(ground, centre.0, centre.1) => {
                let r = Reprojection::new(ground, e).map_err(|m| Error::format(path, format!("cannot reproject the DEM: {m}")))?;
                if e.is_geographic() {
                    let b = g.bounds();
                    if b[0] < -540.0 || b[2] > 540.0 || b[1] < -90.5 || b[3] > 90.5 {
                        return Err(Error::format(path, format!("the DEM says {e} (degrees), but its bounds {b:?} are not longitudes and latitudes")));
                    }
                }
                if let Some(d) = e.unknown_datum().or(ground.unknown_datum()) {
                    warnings.push(format!(
                        "{}: the datum '{d}' has no shift to WGS84 this build knows; it is taken as WGS84 between the DEM's CRS ({e}) and the ground CRS ({ground}), which may place heights up to hundreds of metres off",
                        path.display()
                    ));
                }
                Some(r)
            }
            Some(_) => None,
            None => {
                warnings.push(format!(
                    "{}: the DEM has no CRS; it is taken to be in the ground CRS ({ground}) — if it is not, heights are looked up in the wrong place",
                    path.display()
                ));
                None
            }
        };
        let mut dem = Dem::grid(g, path);
        dem.to_dem = to_dem;
        dem.warnings.extend(warnings);
        Ok(dem)
    }

    /// The mean of (at most ~20 000 of) the grid's valid heights; the
    /// height of a flat DEM; `None` for a grid without any.
    pub fn mean_height(&self) -> Option<f64> {
        *self.mean.get_or_init(|| match &self.model {
            HeightModel::Flat(z) => Some(*z),
            HeightModel::Grid(g) => {
                let step = (g.width * g.height / 20_000).max(1);
                let valid: Vec<f64> = g.samples(step).iter().filter(|&&v| !g.is_nodata(v)).map(|&v| f64::from(v)).collect();
                (!valid.is_empty()).then(|| valid.iter().sum::<f64>() / valid.len() as f64)
            }
        })
    }

    /// The lowest and highest of (at most ~4 million of) the grid's valid
    /// heights: every height of a DEM of that size, so that no street or
    /// roof is missed; the height of a flat DEM.
    pub fn height_range(&self) -> Option<(f64, f64)> {
        *self.range.get_or_init(|| match &self.model {
            HeightModel::Flat(z) => Some((*z, *z)),
            HeightModel::Grid(g) => {
                let step = (g.width * g.height / 4_000_000).max(1);
                // In f32, as stored, folded without a branch (vectorised).
                let heights = g.samples(step);
                let (lo, hi) = heights.iter().filter(|&&v| !g.is_nodata(v)).fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
                (lo <= hi).then(|| (f64::from(lo), f64::from(hi)))
            }
        })
    }

    /// Ground (X, Y) in the grid's own CRS.
    #[inline]
    /// Is ground (X, Y) within the grid's rectangle (where a lookup
    /// outside its data is its collar of nodata, not past its edge)?
    pub fn in_rectangle(&self, x: f64, y: f64) -> bool {
        match (&self.model, self.in_grid_crs(x, y)) {
            (HeightModel::Grid(g), Some((gx, gy))) => {
                let b = g.bounds();
                (b[0]..=b[2]).contains(&gx) && (b[1]..=b[3]).contains(&gy)
            }
            _ => false,
        }
    }

    pub(super) fn in_grid_crs(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        match &self.to_dem {
            None => Some((x, y)),
            Some(r) => r.apply(x, y),
        }
    }

    /// Where ground (X, Y) falls among a grid DEM's samples (continuous
    /// sample coordinates); `None` for a flat DEM or where the CRS
    /// conversion fails.
    pub fn sample_coords(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        match &self.model {
            HeightModel::Grid(g) => self.in_grid_crs(x, y).map(|(gx, gy)| g.sample_coords(gx, gy)),
            HeightModel::Flat(_) => None,
        }
    }

    /// [`Dem::sample_coords`] of a point already in the grid's CRS (as
    /// [`Dem::height_and_lonlat`] gives it back).
    pub fn sample_coords_of_grid_point(&self, gx: f64, gy: f64) -> Option<(f64, f64)> {
        match &self.model {
            HeightModel::Grid(g) => Some(g.sample_coords(gx, gy)),
            HeightModel::Flat(_) => None,
        }
    }

    /// What a lookup at ground (X, Y) finds, before the hole/outside
    /// policy.
    pub fn lookup(&self, x: f64, y: f64) -> Lookup {
        match &self.model {
            HeightModel::Flat(z) => Lookup::Height(*z),
            HeightModel::Grid(g) => self.in_grid_crs(x, y).map_or(Lookup::Outside, |(gx, gy)| g.lookup(gx, gy)),
        }
    }

    #[inline]
    pub fn height(&self, x: f64, y: f64) -> Height {
        let found = match &self.model {
            HeightModel::Flat(z) => return Height::Value(*z),
            HeightModel::Grid(g) => match self.in_grid_crs(x, y) {
                Some((gx, gy)) => g.lookup(gx, gy),
                None => Lookup::Outside,
            },
        };
        self.after_policy(found)
    }

    /// Where the DEM is in WGS84 longitude/latitude (EPSG:4326) under
    /// another ground CRS: that CRS. Its lookups then convert ground points
    /// with the CRS's `to_lonlat`, as an RPC camera does.
    pub fn lonlat_from(&self) -> Option<&Crs> {
        match (&self.model, &self.to_dem) {
            (HeightModel::Grid(_), Some(r)) => r.to_wgs84_from(),
            _ => None,
        }
    }

    /// `height` and, where [`Dem::lonlat_from`] is some, the point's WGS84
    /// (longitude, latitude) it looked up (`None` where it has none).
    #[inline]
    pub fn height_and_lonlat(&self, x: f64, y: f64) -> (Height, Option<(f64, f64)>) {
        match (&self.model, self.lonlat_from()) {
            (HeightModel::Grid(g), Some(_)) => {
                let ll = self.in_grid_crs(x, y);
                let found = ll.map_or(Lookup::Outside, |(lon, lat)| g.lookup(lon, lat));
                (self.after_policy(found), ll)
            }
            _ => (self.height(x, y), None),
        }
    }

    /// What a lookup's result becomes under the hole and outside policies.
    pub(super) fn after_policy(&self, found: Lookup) -> Height {
        let policy = match found {
            Lookup::Height(z) => return Height::Value(z),
            Lookup::Hole => self.on_hole,
            Lookup::Outside => self.on_outside,
        };
        match policy {
            Miss::Error => Height::Missing(found),
            Miss::Nodata => Height::Nodata,
            Miss::Height(z) => Height::Value(z),
        }
    }

    /// Height and gradient where there is a real height (no policy applied).
    #[inline]
    pub fn height_gradient(&self, x: f64, y: f64) -> Option<(f64, f64, f64)> {
        match &self.model {
            HeightModel::Flat(z) => Some((*z, 0.0, 0.0)),
            HeightModel::Grid(g) if self.to_dem.is_none() => g.lookup_gradient(x, y),
            HeightModel::Grid(g) => {
                // The chain rule through the reprojection's Jacobian, by
                // differences over a tenth of a DEM posting.
                let (px, py) = self.in_grid_crs(x, y)?;
                let (z, gx, gy) = g.lookup_gradient(px, py)?;
                let d = 0.1 * g.transform[1].abs();
                let h = {
                    let (ex, _) = self.in_grid_crs(x + 1.0, y)?;
                    d / (ex - px).abs().max(1e-300)
                };
                let (ax, ay) = self.in_grid_crs(x + h, y)?;
                let (bx, by) = self.in_grid_crs(x, y + h)?;
                let j = [[(ax - px) / h, (bx - px) / h], [(ay - py) / h, (by - py) / h]];
                Some((z, gx * j[0][0] + gy * j[1][0], gx * j[0][1] + gy * j[1][1]))
            }
        }
    }

    /// The height [`Dem::height_gradient`] gives, without its gradient:
    /// one conversion into the DEM's CRS where that takes three more (a
    /// ray walked across the DEM asks only whether it is above or below).
    #[inline]
    pub fn surface_height(&self, x: f64, y: f64) -> Option<f64> {
        match &self.model {
            HeightModel::Flat(z) => Some(*z),
            HeightModel::Grid(g) => {
                let (px, py) = self.in_grid_crs(x, y)?;
                g.lookup_gradient(px, py).map(|(z, _, _)| z)
            }
        }
    }

    /// `height_gradient` for many points (see `GridDem::lookup_gradient_many`):
    /// Z NaN where that gives `None`.
    pub fn height_gradient_many(&self, x: &[f64], y: &[f64], out: &mut [(f64, f64, f64)]) {
        match &self.model {
            HeightModel::Grid(g) if self.to_dem.is_none() => g.lookup_gradient_many(x, y, out),
            _ => {
                for ((o, &x), &y) in out.iter_mut().zip(x).zip(y) {
                    *o = self.height_gradient(x, y).unwrap_or((f64::NAN, 0.0, 0.0));
                }
            }
        }
    }

    /// Least-squares plane `Z = a + bX + cY` through the valid heights inside
    /// `[minx, miny, maxx, maxy]` (thesis 2.4.8), on at most ~65 000 samples.
    pub fn trend_plane(&self, b: [f64; 4]) -> Option<Plane> {
        self.fit(b, true)
    }

    /// The mean height inside the bounds, as a horizontal plane.
    pub fn mean_plane(&self, b: [f64; 4]) -> Option<Plane> {
        self.fit(b, false)
    }

    pub(super) fn fit(&self, b: [f64; 4], tilted: bool) -> Option<Plane> {
        let n = 256;
        let (cx, cy) = ((b[0] + b[2]) / 2.0, (b[1] + b[3]) / 2.0);
        let mut ata = nalgebra::Matrix3::<f64>::zeros();
        let mut atz = nalgebra::Vector3::<f64>::zeros();
        let mut count = 0usize;
        for j in 0..n {
            for i in 0..n {
                let x = b[0] + (b[2] - b[0]) * (i as f64 + 0.5) / n as f64;
                let y = b[1] + (b[3] - b[1]) * (j as f64 + 0.5) / n as f64;
                if let Height::Value(z) = self.height(x, y) {
                    let row = nalgebra::Vector3::new(1.0, x - cx, y - cy);
                    ata += row * row.transpose();
                    atz += row * z;
                    count += 1;
                }
            }
        }
        if count == 0 {
            return None;
        }
        if !tilted || count < 3 {
            let mean = atz[0] / count as f64;
            return Some(Plane::flat(mean));
        }
        let s = ata.try_inverse().map(|inv| inv * atz)?;
        Some(Plane { a: s[0] - s[1] * cx - s[2] * cy, b: s[1], c: s[2] })
    }
}
