//! The mosaic's plan, cheap and for all images at once: each image's
//! footprint and GSD, the mosaic grid, and on a coarse lattice of *cells*
//! (a few pixels each, at most [`MAX_CELLS`], fewer on a small budget) the heights, each image's
//! low-resolution orthophoto, and the first partition: each cell to the
//! image that sees it nearest its centre (least relief displacement and
//! lens falloff), computed on the DEM, not from the image centres alone.

use super::box_store::{BoxCells, BoxStore, Seen, Stored};
use crate::camera::file::Camera;
use crate::dem::{Dem, Height};
use crate::error::{Error, Result};
use crate::geodesy::Crs;
use crate::geom::{Gsd, OutputGrid, Snap};
use crate::io::source::{HoleMark, SampleType, SourceImage, Window};
use crate::options::{DemSource, RectifyOptions};
use crate::progress::{Progress, Task};
use crate::transform::footprint::{footprint_gsd, footprint_on};
use rayon::prelude::*;
use std::collections::HashMap;
use std::path::PathBuf;

/// No image sees the cell.
pub const NONE: u16 = u16::MAX;
/// The plan's cells are at most this many: its arrays stay a few tens of
/// MB whatever the mosaic's size.
pub const MAX_CELLS: u64 = 2_000_000;
/// And at most one for this many bytes of the memory budget: a cell costs
/// about 40 (its label, height and weights, and each image's thumbnail and
/// distance where its box holds it), so the plan takes under half of it.
pub const BUDGET_PER_CELL: u64 = 128;

/// A DEM is held whole when it takes at most this share of the memory
/// budget, else read through its chunk cache (a render reads heights at
/// every wall pixel: through the cache a sixth slower).
pub const DEM_SHARE: u64 = 4;

/// The plan holds at most this much of a DEM: the posts under the mosaic
/// where they fit, else a cache of this size. Its passes look heights up
/// box by box, row by row, a few chunks at a time, so a small cache serves
/// them about as fast as posts in memory, and the plan of 64 frames holds
/// no more DEM than the plan of 4.
const PLAN_POSTS: u64 = 4 << 20;

/// Images said one by one to give nothing on a grid too coarse for them;
/// more are said in one line.
const COARSE_ONE_BY_ONE: usize = 3;

/// Bytes of the partition's nearest distances at a time.
const PARTITION_BAND: usize = 1 << 20;

/// Posts held around the mosaic's ground: a render's last nodes may lie a
/// little past its edge.
const DEM_MARGIN: usize = 8;

/// One image as the plan sees it.
pub struct PlanImage {
    pub name: String,
    pub opts: RectifyOptions,
    /// Its camera, while the plan samples it (let go after: the render
    /// loads its own).
    pub camera: Option<Box<Camera>>,
    /// Index of its DEM in [`Plan::dems`].
    pub dem: usize,
    pub width: u32,
    pub height: u32,
    pub bands: u32,
    pub sample: SampleType,
    pub photometric: u16,
    /// Ground size of its pixels at the centre (mean of the two axes).
    pub gsd: f64,
    /// The box of cells that may see it: `[x0, y0, x1, y1)`.
    pub cells: [usize; 4],
    /// The box of the mosaic's pixels its footprint spans: `[x0, y0, x1, y1)`.
    pub pixels: [u32; 4],
    /// Its low-resolution orthophoto on the cells of the box and where in
    /// the scan it sees each, in the plan's store ([`Plan::rows_of`]).
    pub stored: Stored,
    /// Which cells of the box it sees.
    pub seen: Seen,
}

impl PlanImage {
    #[inline]
    pub fn sees(&self, x: usize, y: usize) -> bool {
        self.seen.sees(x, y)
    }
}

/// An image's low-resolution orthophoto, at the precision of its samples:
/// 8- and 16-bit ones as 16-bit levels (a 256th of an 8-bit level, a
/// 16-bit one's level: finer than balancing and seams can tell), others as
/// f32 — half the memory of f32 on the common images.
#[derive(Clone)]
pub enum Thumbnail {
    /// Values times `per_unit`, rounded.
    Levels {
        v: Vec<u16>,
        per_unit: f32,
    },
    Floats(Vec<f32>),
}

impl Default for Thumbnail {
    fn default() -> Thumbnail {
        Thumbnail::Floats(Vec::new())
    }
}

impl Thumbnail {
    /// Room for `n` values of samples of `sample`.
    fn new(n: usize, sample: SampleType) -> Thumbnail {
        match sample {
            SampleType::U8 => Thumbnail::Levels { v: vec![0; n], per_unit: 256.0 },
            SampleType::U16 => Thumbnail::Levels { v: vec![0; n], per_unit: 1.0 },
            SampleType::F32 => Thumbnail::Floats(vec![f32::NAN; n]),
        }
    }

    /// Rows of `cells` cells of `bands` values, in parallel, with the same
    /// rows of `per_cell` (one value a cell): `f(row, values, per_cell's
    /// row)` fills a row's values as f32 (none where the thumbnail is
    /// empty), stored as the thumbnail keeps them.
    fn fill_rows(&mut self, per_cell: &mut [f32], cells: usize, bands: usize, f: impl Fn(usize, &mut [f32], &mut [f32]) + Sync) {
        let (cells, row) = (cells.max(1), (cells * bands).max(1));
        let rows = per_cell.par_chunks_mut(cells).enumerate();
        match self {
            Thumbnail::Levels { v, per_unit } if !v.is_empty() => {
                let (per_unit, top) = (*per_unit, u16::MAX as f32);
                rows.zip(v.par_chunks_mut(row)).for_each(|((j, cell), out)| {
                    let mut vals = vec![f32::NAN; out.len()];
                    f(j, &mut vals, cell);
                    for (o, &x) in out.iter_mut().zip(&vals) {
                        // NaN (not seen, as its `per_cell` says) is 0.
                        *o = (x * per_unit).round().clamp(0.0, top) as u16;
                    }
                })
            }
            Thumbnail::Floats(v) if !v.is_empty() => rows.zip(v.par_chunks_mut(row)).for_each(|((j, cell), out)| f(j, out, cell)),
            _ => rows.for_each(|(j, cell)| f(j, &mut [], cell)),
        }
    }
}

/// An image's thumbnail pixel: its bands' values at one cell.
#[derive(Clone, Copy)]
pub enum Pixel<'a> {
    /// Levels, and a unit a level.
    Levels(&'a [u16], f32),
    Floats(&'a [f32]),
}

impl Pixel<'_> {
    #[inline]
    pub fn band(&self, b: usize) -> f32 {
        match *self {
            Pixel::Levels(v, unit) => v[b] as f32 * unit,
            Pixel::Floats(v) => v[b],
        }
    }

    pub fn bands(&self) -> impl Iterator<Item = f32> + '_ {
        let n = match self {
            Pixel::Levels(v, _) => v.len(),
            Pixel::Floats(v) => v.len(),
        };
        (0..n).map(|b| self.band(b))
    }
}

/// The side of the plan's cells over `px` output pixels on a budget of
/// `memory` bytes: 4 pixels or more, doubled until there are at most
/// [`MAX_CELLS`] and one for each [`BUDGET_PER_CELL`] bytes.
pub fn cell_side(px: u64, memory: u64) -> u32 {
    let most = MAX_CELLS.min(memory / BUDGET_PER_CELL).max(1);
    let mut cell = 4u32;
    while px / (cell as u64 * cell as u64) > most {
        cell *= 2;
    }
    cell
}

/// The mosaic's grid and its cells.
pub struct Plan {
    pub grid: OutputGrid,
    pub crs: Crs,
    /// A cell's side, output pixels.
    pub cell: u32,
    /// Cells across and down.
    pub cw: usize,
    pub ch: usize,
    /// The DEM's height at each cell's centre (NaN: none).
    pub heights: Vec<f32>,
    /// The image each cell is taken from ([`NONE`]: none sees it); empty
    /// once the render has them as [`Plan::runs`].
    pub label: Vec<u16>,
    /// The same as runs along each row, for the render.
    pub runs: Option<super::label_runs::LabelRuns>,
    pub images: Vec<PlanImage>,
    /// The images' DEMs, each opened once (renders share them).
    pub dems: Vec<std::sync::Arc<Dem>>,
    /// Each image's thumbnail and distances on its box of cells.
    pub store: BoxStore,
    /// Images a grid too coarse for them gives nothing (an absurd budget's
    /// cells): said once the run goes on, not before its refusal.
    pub coarse_notes: Vec<String>,
}

/// What the plan is made from.
pub struct PlanSettings {
    pub gsd: Option<Gsd>,
    /// The grid itself (a reference raster's), instead of `gsd` and
    /// `bounds`.
    pub grid: Option<OutputGrid>,
    pub bounds: Option<[f64; 4]>,
    pub crs: Option<Crs>,
    /// Memory for the DEMs and one scan's thumbnail, bytes.
    pub memory: u64,
    /// The cells' side, where a plan file fixes it.
    pub cell: Option<u32>,
    /// Read each scan's thumbnail (what balancing and the least-cost seams
    /// weigh); without, [`PlanImage::values`] only say where it sees (0),
    /// as rendering from a plan file needs.
    pub thumbnails: bool,
}

impl Plan {
    /// Ground (X, Y) of cell (x, y)'s centre.
    pub fn cell_centre(&self, x: usize, y: usize) -> (f64, f64) {
        let s = self.cell as f64;
        self.grid.ground((x as f64 + 0.5) * s, (y as f64 + 0.5) * s)
    }

    /// Rows `rows` of image `k`'s box: its thumbnail and where it sees
    /// each cell.
    pub fn rows_of(&self, k: usize, rows: std::ops::Range<usize>) -> Result<BoxCells> {
        self.store.rows(&self.images[k].stored, rows, true)
    }

    /// The same, where it sees each cell only.
    pub fn radius_rows_of(&self, k: usize, rows: std::ops::Range<usize>) -> Result<BoxCells> {
        self.store.rows(&self.images[k].stored, rows, false)
    }

    /// Drops what the render does not read, before the images' works are
    /// made from it: the cells' heights, and the DEMs' posts (each strip
    /// of the render holds its own, [`Plan::dems_for`]); the labels are
    /// kept as runs.
    pub fn forget_for_render(&mut self) -> Result<()> {
        self.heights = Vec::new();
        self.runs = Some(super::label_runs::LabelRuns::new(&self.label, self.cw));
        self.label = Vec::new();
        // The plan's lookups ran on this thread and the global pool's,
        // each of which still holds the DEM chunk it looked into last.
        crate::io::cached_raster::let_go_of_last_look();
        rayon::broadcast(|_| crate::io::cached_raster::let_go_of_last_look());
        for d in &mut self.dems {
            if let Some(d) = std::sync::Arc::get_mut(d) {
                d.let_go_of_posts()?;
            }
        }
        Ok(())
    }

    /// Each DEM as a render of the mosaic's pixels `px` (`[x0, y0, x1,
    /// y1)`) looks it up: with `hold`, the posts under them in memory, else
    /// through a cache of `cache` bytes (a DEM not one grid file: the
    /// plan's own).
    pub fn dems_for(&self, px: [u32; 4], hold: bool, cache: u64) -> Result<Vec<std::sync::Arc<Dem>>> {
        let b = ground_box(&self.grid, px);
        let most = if hold { u64::MAX } else { 0 };
        self.dems.iter().map(|d| Ok(d.posts_for(b, DEM_MARGIN, most, cache)?.map_or_else(|| d.clone(), std::sync::Arc::new))).collect()
    }

    /// The bytes of the DEMs' posts under the mosaic's pixels `px`.
    pub fn dem_posts_under(&self, px: [u32; 4]) -> u64 {
        let b = ground_box(&self.grid, px);
        self.dems.iter().map(|d| d.bytes_under(b, DEM_MARGIN)).sum()
    }

    /// The bytes the plan holds a cell: the images' bits of where they
    /// see, the labels (or their runs), the heights (till the render).
    pub fn cell_bytes(&self) -> u64 {
        let labels = self.runs.as_ref().map_or(self.label.len() as u64 * 2, |r| r.bytes());
        self.images.iter().map(|i| i.seen.bytes()).sum::<u64>() + labels + self.heights.len() as u64 * 4
    }

    #[inline]
    pub fn label_at(&self, x: usize, y: usize) -> u16 {
        match &self.runs {
            Some(runs) => runs.at(x, y),
            None => self.label[y * self.cw + x],
        }
    }

    /// Ground size of a cell's side (of a square cell of the same area,
    /// where pixels are not square).
    pub fn cell_metres(&self) -> f64 {
        self.cell as f64 * self.grid.gsd.mean()
    }

    pub fn make(jobs: Vec<(String, RectifyOptions)>, s: &PlanSettings, progress: &dyn Progress) -> Result<Plan> {
        if jobs.len() >= NONE as usize {
            return Err(Error::setting("manifest", format!("{} images, more than the {} a mosaic takes", jobs.len(), NONE - 1)));
        }
        let mut dems: Vec<std::sync::Arc<Dem>> = Vec::new();
        let mut dem_of: HashMap<PathBuf, usize> = HashMap::new();
        let mut images = Vec::new();
        // Images whose edge leaves their DEM (said already).
        let mut partial_dem = Vec::new();
        let mut crs = s.crs.clone();
        for (name, opts) in jobs {
            // The pose the image's render will take (GCPs applied), so that
            // its footprint and seams are where its pixels land.
            let (camera, _, _) = crate::scene::camera::of_run(&opts, s.crs.as_ref(), progress)?;
            let ground = crs.get_or_insert_with(|| camera.crs.clone()).clone();
            let camera = camera.in_crs(&ground).map_err(|m| Error::setting("crs", format!("{name}: {m}")))?;
            // Read whole only when small: of a larger DEM only the posts
            // under the mosaic, once its grid is known (before, the
            // footprints look it up through a cache). One file, read once.
            let file = match &opts.inputs.dem {
                DemSource::File(p) => Some(p),
                _ => None,
            };
            let dem = match file.and_then(|p| dem_of.get(p)) {
                Some(&k) => k,
                None => {
                    dems.push(crate::scene::terrain::dem_of_run(&opts, &camera, None, plan_posts(s.memory), progress)?);
                    if let Some(p) = file {
                        dem_of.insert(p.clone(), dems.len() - 1);
                    }
                    dems.len() - 1
                }
            };
            let info = SourceImage::info_of(&opts.inputs.image)?;
            let d = &dems[dem];
            let z = d.mean_height().unwrap_or_else(|| camera.height_hint());
            let on_dem = |e: Error| match e {
                Error::Geometry(m) => Error::format(&opts.inputs.image, m),
                e => e,
            };
            // An image wholly off its DEM gives nothing (said once the plan
            // is made), unless the manifest makes that an error.
            let (fp, gsd) = match footprint_on(camera.model(), d, info.width, info.height, z) {
                Err(Error::Geometry(_)) if opts.inputs.dem_outside != crate::dem::Miss::Error => (None, f64::NAN),
                fp => {
                    let fp = fp.map_err(on_dem)?;
                    // Within bounds, an image past the DEM may still give
                    // only ground on it (refused where it does not).
                    if s.bounds.is_none() && s.grid.is_none() {
                        fp.check_covered(&opts.inputs.image, d)?;
                    }
                    if let Some(w) = fp.partial_warning(&opts.inputs.image, d) {
                        progress.warn(&w);
                    }
                    (Some(fp), footprint_gsd(camera.model(), d, info.width, info.height, z).map_err(on_dem)?)
                }
            };
            images.push((
                PlanImage {
                    name,
                    opts,
                    camera: Some(Box::new(camera)),
                    dem,
                    width: info.width,
                    height: info.height,
                    bands: info.bands,
                    sample: info.sample,
                    photometric: info.photometric,
                    gsd,
                    cells: [0; 4],
                    pixels: [0; 4],
                    stored: Stored::default(),
                    seen: Seen::default(),
                },
                fp.map(|f| f.bounds),
            ));
            partial_dem.push(fp.is_none_or(|f| f.past_edge + f.on_holes > 0));
        }
        let crs = crs.ok_or_else(|| Error::setting("manifest", "no image".to_string()))?;
        if let Some(first) = images.first().map(|(i, _)| (i.bands, i.sample, i.name.clone())) {
            for (im, _) in &images {
                if (im.bands, im.sample) != (first.0, first.1) {
                    return Err(Error::format(
                        &im.opts.inputs.image,
                        format!(
                            "{} band(s) of {:?}, but {} has {} of {:?}: a mosaic's images share bands and sample type",
                            im.bands, im.sample, first.2, first.0, first.1
                        ),
                    ));
                }
            }
        }
        if let Some((im, _)) = images.first().filter(|_| images.iter().all(|(_, f)| f.is_none())) {
            return Err(Error::format(&dems[im.dem].path, "none of the mosaic's images meets this DEM: does it cover the block?"));
        }
        let gsd = s.gsd.unwrap_or_else(|| {
            let mut g: Vec<f64> = images.iter().map(|(i, _)| i.gsd).filter(|g| g.is_finite()).collect();
            g.sort_by(f64::total_cmp);
            Gsd::square(g[g.len() / 2])
        });
        let union = images.iter().filter_map(|(_, f)| f.as_ref()).fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |b, f| {
            [b[0].min(f[0]), b[1].min(f[1]), b[2].max(f[2]), b[3].max(f[3])]
        });
        let bounds = s.bounds.unwrap_or(union);
        if !gsd.is_valid() {
            return Err(Error::setting("gsd", format!("{gsd} is not a pixel size")));
        }
        let grid = match s.grid {
            Some(g) => g,
            None => OutputGrid::from_bounds(bounds, gsd, Snap::Tap).ok_or_else(|| {
                Error::setting(
                    if s.bounds.is_some() { "bounds" } else { "gsd" },
                    format!("{bounds:?} at GSD {gsd} {}", OutputGrid::no_grid_because(bounds, gsd)),
                )
            })?,
        };
        // A GSD or bounds typo makes a mosaic of days: refused before any
        // work, as rectify refuses one (16 times the scans' pixels at most).
        let scans: u64 = images.iter().map(|(i, _)| i.width as u64 * i.height as u64).sum();
        let pixels = grid.width as u64 * grid.height as u64;
        if pixels > (16 * scans).max(1 << 28) {
            return Err(Error::setting(
                "gsd",
                format!("a mosaic of {}×{} pixels at GSD {gsd} is more than 16 times its scans' pixels; check the GSD and bounds", grid.width, grid.height),
            ));
        }
        // A plan file's cells, else as many as the budget holds (the
        // default 256 MiB holds MAX_CELLS).
        let cell = s.cell.unwrap_or_else(|| cell_side(grid.width as u64 * grid.height as u64, s.memory));
        let (cw, ch) = (grid.width.div_ceil(cell) as usize, grid.height.div_ceil(cell) as usize);
        // Of a DEM, the posts under the mosaic in memory where they fit the
        // plan's share, else a cache of that size.
        let whole = ground_box(&grid, [0, 0, grid.width, grid.height]);
        for d in &mut dems {
            if let Some(d) = std::sync::Arc::get_mut(d) {
                d.hold_window(whole, DEM_MARGIN, plan_posts(s.memory))?;
            }
        }
        let mut plan = Plan {
            grid,
            crs,
            cell,
            cw,
            ch,
            heights: Vec::new(),
            label: vec![NONE; cw * ch],
            runs: None,
            images: Vec::new(),
            dems,
            store: BoxStore::new()?,
            coarse_notes: Vec::new(),
        };
        // Heights of the first image's DEM: the seams' height edges.
        if let Some((im, _)) = images.first() {
            let dem = &plan.dems[im.dem];
            let heights: Vec<f32> = (0..cw * ch)
                .into_par_iter()
                .map(|k| {
                    let (x, y) = plan.cell_centre(k % cw, k / cw);
                    match dem.height(x, y) {
                        Height::Value(z) => z as f32,
                        _ => f32::NAN,
                    }
                })
                .collect();
            plan.heights = heights;
        }
        progress.start(&Task { name: "plan", units: images.len() as u64, lines: images.len() as u64, line_name: "images", input_bytes: 0 });
        // Each image's low-resolution orthophoto, several at once (each
        // reads its own scan); the partition then in the images' order.
        let sampled: Vec<PlanImage> = images
            .into_par_iter()
            .map(|(mut im, fp)| {
                let camera = im.camera.take().ok_or_else(|| Error::Internal(format!("{}: its camera was let go before the plan sampled it", im.name)))?;
                let Some(fp) = fp else {
                    progress.advance(1);
                    return Ok(im);
                };
                let (u0, v0) = plan.grid.pixel(fp[0], fp[3]);
                let (u1, v1) = plan.grid.pixel(fp[2], fp[1]);
                let c = plan.cell as f64;
                let clampc = |v: f64, n: usize| (v / c).floor().clamp(0.0, n as f64) as usize;
                im.cells = [clampc(u0, cw), clampc(v0, ch), (clampc(u1, cw) + 1).min(cw), (clampc(v1, ch) + 1).min(ch)];
                let (gw, gh) = (plan.grid.width as f64, plan.grid.height as f64);
                im.pixels = [u0.clamp(0.0, gw) as u32, v0.clamp(0.0, gh) as u32, u1.ceil().clamp(0.0, gw) as u32, v1.ceil().clamp(0.0, gh) as u32];
                // How far from its centre the image sees each cell (a
                // fraction of its half-diagonal): the partition's measure.
                sample_image(&plan, &mut im, &camera, s.memory, s.thumbnails)?;
                progress.advance(1);
                Ok(im)
            })
            .collect::<Result<_>>()?;
        plan.images = sampled;
        // A band of cell rows at a time (the nearest distance so far is a
        // float a cell: over the whole mosaic, twice its labels).
        let band = (PARTITION_BAND / (4 * cw)).max(1);
        let mut best = Vec::new();
        for r0 in (0..ch).step_by(band) {
            let r1 = (r0 + band).min(ch);
            best.clear();
            best.resize(cw * (r1 - r0), f32::INFINITY);
            for k in 0..plan.images.len() {
                let [x0, y0, _, y1] = plan.images[k].cells;
                let (a, b) = (y0.max(r0), y1.min(r1));
                if a >= b {
                    continue;
                }
                let seen = plan.radius_rows_of(k, a..b)?;
                for (j, row) in seen.radius_rows().enumerate() {
                    for (i, &d) in row.iter().enumerate() {
                        let at = (a + j) * cw + x0 + i;
                        if d < best[at - r0 * cw] {
                            (best[at - r0 * cw], plan.label[at]) = (d, k as u16);
                        }
                    }
                }
            }
        }
        progress.finish();
        // A mosaic no image sees is a mistake in the bounds or the GSD,
        // never a result.
        if plan.label.iter().all(|&l| l == NONE) {
            let [x0, y0, x1, y1] = union;
            let what = format!(
                "no image sees any of the mosaic's {}×{} px at GSD {gsd}; the images cover [{x0:.0}, {y0:.0}, {x1:.0}, {y1:.0}]",
                plan.grid.width, plan.grid.height
            );
            return Err(match s.bounds {
                Some(b) => Error::setting("bounds", format!("{b:?}: {what}")),
                None => Error::setting("gsd", what),
            });
        }
        plan.coarse_notes = plan.check_each_image_gives(&partial_dem, s.bounds.is_some() || s.grid.is_some(), progress)?;
        Ok(plan)
    }
}

impl Plan {
    /// An image the mosaic takes nothing of is a mistake to say: outside
    /// its DEM (an error under `--dem-outside error`), or seen nearer its
    /// centre everywhere by another image — the same image twice, or
    /// another's camera. (`bounded`: the grid is a box of the block's.)
    /// Returns what it has to say of images a grid too coarse for them
    /// gives nothing, for the run to say once it goes on.
    fn check_each_image_gives(&self, partial_dem: &[bool], bounded: bool, progress: &dyn Progress) -> Result<Vec<String>> {
        let mut taken = vec![0usize; self.images.len()];
        let mut coarse = Vec::new();
        for &l in self.label.iter().filter(|&&l| l != NONE) {
            taken[l as usize] += 1;
        }
        for (k, im) in self.images.iter().enumerate() {
            // Within bounds, images beside the box are expected to give
            // nothing (where one image hides another is judged on the
            // whole block, not a box of it).
            if taken[k] > 0 || (bounded && !partial_dem[k]) {
                continue;
            }
            let [x0, y0, x1, y1] = im.cells;
            // The image that took most of what it sees.
            let mut by = vec![0usize; self.images.len()];
            for (x, y) in (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))).filter(|&(x, y)| im.sees(x, y)) {
                if let Some(&l) = Some(&self.label[y * self.cw + x]).filter(|&&l| l != NONE) {
                    by[l as usize] += 1;
                }
            }
            let other = (0..by.len()).filter(|&j| by[j] > 0).max_by_key(|&j| by[j]).map(|j| self.images[j].opts.inputs.image.display().to_string());
            let dem = self.dems[im.dem].path.display();
            // An image a cell or two across at this GSD: the grid is coarse
            // for it, whatever else is true.
            let (across, down) = (x1 - x0, im.cells[3] - im.cells[1]);
            let why = match (other, partial_dem[k]) {
                _ if (1..=2).contains(&across.min(down)) => {
                    format!("at GSD {} it spans only {across}×{down} of the plan's cells ({} px each): the grid is coarse for it", self.grid.gsd, self.cell)
                }
                (None, true) => format!("it sees none of the mosaic's ground on the DEM {dem}"),
                (None, false) => "it sees none of the mosaic's ground (its own holes, or the DEM's)".to_string(),
                (Some(o), true) => format!("what of it lies on the DEM {dem} is seen nearer their centres by other images (most by {o})"),
                (Some(o), false) => {
                    format!("all it sees is seen nearer their centres by other images (most by {o}): the same image twice, or another image's camera?")
                }
            };
            let what = format!("the mosaic takes nothing of it: {why}");
            if partial_dem[k] && im.opts.inputs.dem_outside == crate::dem::Miss::Error {
                return Err(Error::format(&im.opts.inputs.image, format!("{what} (dem_outside = \"error\")")));
            }
            if (1..=2).contains(&across.min(down)) {
                coarse.push((im.opts.inputs.image.display().to_string(), what));
            } else {
                progress.warn(&format!("{}: {what}", im.opts.inputs.image.display()));
            }
        }
        // Images a grid too coarse for them gives nothing: one line for
        // them all where there are many (a budget far too small makes
        // cells as wide as the frames).
        Ok(match coarse.len() {
            0..=COARSE_ONE_BY_ONE => coarse.iter().map(|(image, what)| format!("{image}: {what}")).collect(),
            n => vec![format!(
                "{n} images (first {}) span only one or two of the plan's cells ({} px each) at GSD {}: the grid is coarse for them, and the mosaic takes nothing of them",
                coarse.iter().take(COARSE_ONE_BY_ONE).map(|(image, _)| image.as_str()).collect::<Vec<_>>().join(", "),
                self.cell,
                self.grid.gsd
            )],
        })
    }
}

/// The most of a DEM the plan holds on a budget of `memory` bytes.
fn plan_posts(memory: u64) -> u64 {
    PLAN_POSTS.min(memory / (2 * DEM_SHARE))
}

/// The ground box `[x0, y0, x1, y1]` of the grid's pixels `[x0, y0, x1,
/// y1)` (columns, rows).
fn ground_box(grid: &OutputGrid, [c0, r0, c1, r1]: [u32; 4]) -> [f64; 4] {
    let (ax, ay) = grid.ground(c0 as f64, r0 as f64);
    let (bx, by) = grid.ground(c1 as f64, r1 as f64);
    [ax.min(bx), ay.min(by), ax.max(bx), ay.max(by)]
}

/// The image's low-resolution orthophoto on the cells of its box: its scan
/// reduced to about a cell a pixel (one row of each block of rows read,
/// averaged across), then sampled bilinearly where each cell's centre is
/// seen, and how far from the scan's centre each cell is seen, over its
/// half-diagonal (NaN: not seen).
fn sample_image(plan: &Plan, im: &mut PlanImage, camera: &Camera, memory: u64, thumbnails: bool) -> Result<()> {
    let (w, h, nb) = (im.width as usize, im.height as usize, im.bands as usize);
    let f = ((plan.cell_metres() / im.gsd).floor() as usize).clamp(1, w.min(h));
    let (tw, th) = if thumbnails { (w.div_ceil(f), h.div_ceil(f)) } else { (1, 1) };
    let mut thumb = vec![0f32; tw * th * nb];
    // Thumbnail pixels mostly of the scan's own holes (its mask, nodata
    // value or alpha): the image does not see the cells there, so that
    // another image's pixels fill them.
    let mut holed = vec![false; tw * th];
    let mut win = Window::default();
    let src = if thumbnails { Some(SourceImage::open_within(&im.opts.inputs.image, (memory / 8) as usize, memory)?) } else { None };
    let mark = src.as_ref().map(|s| s.hole_mark()).transpose()?.flatten();
    for tr in 0..th * usize::from(src.is_some()) {
        let Some(src) = &src else { break };
        let row = (tr * f + f / 2).min(h - 1);
        src.read_window(0, row as u32, w as u32, 1, &mut win)?;
        let line = as_f32(win.bytes(), im.sample);
        let hole = |c: usize| match (mark, src.mask_runs()) {
            (Some(HoleMark::Mask), Some(runs)) => !runs.all_set(row as u32, c as u32, c as u32),
            (Some(m), _) => m.is_hole(|band| line[c * nb + band], nb),
            (None, _) => false,
        };
        let mut image = Vec::with_capacity(f);
        for tc in 0..tw {
            let (a, b) = (tc * f, ((tc + 1) * f).min(w));
            // The mean of the image's pixels (of all, where none is).
            image.clear();
            image.extend((a..b).filter(|&c| !hole(c)));
            holed[tr * tw + tc] = 2 * image.len() < b - a;
            if image.is_empty() {
                image.extend(a..b);
            }
            for band in 0..nb {
                let sum: f32 = image.iter().map(|&c| line[c * nb + band]).sum();
                thumb[(tr * tw + tc) * nb + band] = sum / image.len() as f32;
            }
        }
    }
    let [x0, y0, x1, y1] = im.cells;
    let model = camera.model();
    let area = model.image_area();
    let dem = &plan.dems[im.dem];
    let bw = x1 - x0;
    let side = (w as f64 / 2.0).hypot(h as f64 / 2.0);
    let mut from_centre = vec![f32::NAN; bw * (y1 - y0)];
    let mut values = Thumbnail::new(if thumbnails { bw * (y1 - y0) * nb } else { 0 }, im.sample);
    values.fill_rows(&mut from_centre, bw, nb, |j, out, dist| {
        for i in 0..bw {
            let (gx, gy) = plan.cell_centre(x0 + i, y0 + j);
            let Height::Value(z) = dem.height(gx, gy) else { continue };
            let Some((c, r)) = model.project(gx, gy, z) else { continue };
            if !(c >= 0.0 && r >= 0.0 && c < w as f64 && r < h as f64) || area.is_some_and(|a| !a.contains(c, r)) {
                continue;
            }
            let nearest = ((r / f as f64) as usize).min(th - 1) * tw + ((c / f as f64) as usize).min(tw - 1);
            if holed.get(nearest).copied().unwrap_or(false) {
                continue;
            }
            dist[i] = ((c - w as f64 / 2.0).hypot(r - h as f64 / 2.0) / side) as f32;
            if out.is_empty() {
                continue;
            }
            // Bilinear between thumbnail pixel centres.
            let (u, v) = ((c / f as f64 - 0.5).clamp(0.0, (tw - 1) as f64), (r / f as f64 - 0.5).clamp(0.0, (th - 1) as f64));
            let (iu, iv) = ((u as usize).min(tw.saturating_sub(2)), (v as usize).min(th.saturating_sub(2)));
            let (fu, fv) = ((u - iu as f64) as f32, (v - iv as f64) as f32);
            let (iu1, iv1) = ((iu + 1).min(tw - 1), (iv + 1).min(th - 1));
            for band in 0..nb {
                let p = |a: usize, b: usize| thumb[(b * tw + a) * nb + band];
                let top = p(iu, iv) * (1.0 - fu) + p(iu1, iv) * fu;
                let bot = p(iu, iv1) * (1.0 - fu) + p(iu1, iv1) * fu;
                out[i * nb + band] = top * (1.0 - fv) + bot * fv;
            }
        }
    });
    (im.stored, im.seen) = plan.store.put(im.cells, nb, &from_centre, &values)?;
    Ok(())
}

/// Samples of a row of the scan as f32.
fn as_f32(bytes: &[u8], sample: SampleType) -> Vec<f32> {
    match sample {
        SampleType::U8 => bytes.iter().map(|&v| v as f32).collect(),
        SampleType::U16 => bytes.chunks_exact(2).map(|b| u16::from_ne_bytes([b[0], b[1]]) as f32).collect(),
        SampleType::F32 => bytes.chunks_exact(4).map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A thumbnail of 8-bit samples keeps its values to a 512th of a level
    /// in half the memory of f32; 16-bit ones to half a level; floats as
    /// they are. Every row and band lands where it was written.
    #[test]
    fn thumbnails_keep_their_values_at_their_samples_precision() {
        let (cells, bands, rows) = (5, 3, 4);
        let value = |j: usize, k: usize| ((j * 61 + k * 7) % 250) as f32 * 1.017 + 0.3;
        for (sample, tolerance) in [(SampleType::U8, 1.0 / 512.0), (SampleType::U16, 0.5), (SampleType::F32, 0.0)] {
            let mut t = Thumbnail::new(cells * bands * rows, sample);
            let mut seen = vec![f32::NAN; cells * rows];
            t.fill_rows(&mut seen, cells, bands, |j, out, dist| {
                dist.fill(j as f32);
                for (k, v) in out.iter_mut().enumerate() {
                    *v = value(j, k);
                }
            });
            assert_eq!(seen, (0..cells * rows).map(|k| (k / cells) as f32).collect::<Vec<_>>());
            let bytes = match &t {
                Thumbnail::Levels { v, .. } => v.len() * 2,
                Thumbnail::Floats(v) => v.len() * 4,
            };
            assert_eq!(bytes, cells * bands * rows * if sample == SampleType::F32 { 4 } else { 2 });
            for j in 0..rows {
                for c in 0..cells {
                    let k = (j * cells + c) * bands;
                    let px = match &t {
                        Thumbnail::Levels { v, per_unit } => Pixel::Levels(&v[k..k + bands], 1.0 / per_unit),
                        Thumbnail::Floats(v) => Pixel::Floats(&v[k..k + bands]),
                    };
                    for (b, got) in px.bands().enumerate() {
                        let want = value(j, c * bands + b);
                        assert!((got - want).abs() <= tolerance * 1.0001, "{sample:?} row {j} cell {c} band {b}: {got} for {want}");
                    }
                }
            }
        }
    }

    /// The default budget plans on up to MAX_CELLS cells; a small one on
    /// coarser cells, one for each BUDGET_PER_CELL bytes at most.
    #[test]
    fn the_cells_grow_as_the_budget_shrinks() {
        let px = 7954 * 12297;
        assert_eq!(cell_side(px, 256 << 20), 8, "1.53 million cells of 8 px fit the default");
        assert_eq!(cell_side(px, 100 << 20), 16, "0.82 million at most on 100 MiB");
        assert_eq!(cell_side(1000 * 1000, 256 << 20), 4, "never under 4 px");
        for memory in [32u64 << 20, 100 << 20, 1 << 30] {
            let side = cell_side(px, memory) as u64;
            assert!(px / (side * side) <= (memory / BUDGET_PER_CELL).min(MAX_CELLS));
        }
    }
}
