//! The mosaic made band by band straight from the scans: each image runs
//! `rectify`'s stages on a thread of its own over just the tiles the seams
//! give it (and a blend's width beyond), one band ahead at most; each band
//! of the mosaic is composed from the images' bands, pixel by pixel
//! weighted as the cells say (balanced), and goes on to `rectify`'s
//! encoder and writer. An image's thread starts a band before its first
//! and ends with its last, so its scan is open only while bands need it.

use super::balance::Correction;
use super::box_store::BoxCells;
use super::plan::{Plan, NONE};
use super::turns::Turns;
use super::weights::Weights;
use crate::error::{Error, Result};
use crate::geom::Snap;
use crate::io::tiff_out::OutputSpec;
use crate::options::RectifyOptions;
use crate::pipeline::band_render::{render_bands, BandPixels, BandRequest, Shared};
use crate::pipeline::{Made, Raw};
use crate::progress::{Cancel, Progress};
use crossbeam_channel::{bounded, Receiver};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::sync::Arc;

/// The part of the mosaic an image is made over.
#[derive(Clone)]
pub struct ImageWork {
    pub image: usize,
    /// Its grid's first tile in the mosaic (column, row).
    pub origin: (u32, u32),
    /// Mosaic tile columns `[c0, c1)` needed in each mosaic band.
    pub bands: BTreeMap<u32, (u32, u32)>,
    pub opts: RectifyOptions,
    pub grid: crate::geom::OutputGrid,
    /// The plan's DEM for it and the CRS it was opened in (the render takes
    /// it rather than reading the file again).
    pub dem: crate::pipeline::band_render::SharedDem,
}

impl ImageWork {
    fn requests(&self) -> Vec<BandRequest> {
        self.bands.iter().map(|(&b, &(c0, c1))| (b - self.origin.1, (c0 - self.origin.0, c1 - self.origin.0))).collect()
    }
}

/// The cells where an image may not see the ground (under occlusion): a
/// surface within reach stands higher than the cell by enough to hide half
/// a pixel along lines of sight up to 56° off nadir (reach: the block's
/// height range along such a line, in cells). Elsewhere every image sees
/// it, and only the cell's own image is made there.
pub fn occlusion_prone(plan: &Plan) -> Vec<bool> {
    const TAN: f64 = 1.5;
    let (cw, ch) = (plan.cw, plan.ch);
    let h = &plan.heights;
    let (lo, hi) = h.iter().filter(|v| v.is_finite()).fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return vec![false; cw * ch];
    }
    let cell = plan.cell as f64 * plan.grid.gsd.min();
    let reach = ((hi - lo) as f64 * TAN / cell).ceil().clamp(1.0, 256.0) as usize;
    // The highest cell within `reach` of each (a square max filter, one
    // axis after the other).
    let filter = |src: &[f32], across: bool| -> Vec<f32> {
        let mut out = vec![f32::NEG_INFINITY; cw * ch];
        for y in 0..ch {
            for x in 0..cw {
                let (a, n, at) = if across { (x, cw, y * cw) } else { (y, ch, x) };
                let step = if across { 1 } else { cw };
                let (s, e) = (a.saturating_sub(reach), (a + reach + 1).min(n));
                out[y * cw + x] = (s..e).map(|k| src[at + k * step]).filter(|v| v.is_finite()).fold(f32::NEG_INFINITY, f32::max);
            }
        }
        out
    };
    let near = filter(&filter(h, true), false);
    let rise = 0.5 * plan.grid.gsd.min() / TAN;
    (0..cw * ch).map(|k| h[k].is_finite() && (near[k] - h[k]) as f64 > rise).collect()
}

/// Which images each tile of the mosaic needs: those with a weight in the
/// cells it touches (and one around, for the ramp), and where a cell's own
/// image ends inside the tile (its footprint's edge), or may not see the
/// ground (`prone`), every image that sees the cell, so that no pixel any
/// image has is left empty.
pub fn work(plan: &Plan, weights: &Weights, tile: u32, prone: Option<&[bool]>, opts_of: impl Fn(usize) -> RectifyOptions) -> Vec<ImageWork> {
    let (tx, ty) = (plan.grid.width.div_ceil(tile), plan.grid.height.div_ceil(tile));
    let c = plan.cell as usize;
    let (cw, ch) = (plan.cw, plan.ch);
    let mut needs: Vec<BTreeMap<u32, (u32, u32)>> = vec![BTreeMap::new(); plan.images.len()];
    for ty_ in 0..ty {
        for tx_ in 0..tx {
            let x0 = ((tx_ * tile) as usize / c).saturating_sub(1);
            let y0 = ((ty_ * tile) as usize / c).saturating_sub(1);
            let x1 = ((((tx_ + 1) * tile) as usize).div_ceil(c) + 1).min(cw);
            let y1 = ((((ty_ + 1) * tile) as usize).div_ceil(c) + 1).min(ch);
            let mut set = std::collections::BTreeSet::new();
            for y in y0..y1 {
                for x in x0..x1 {
                    let l = plan.label_at(x, y);
                    for i in weights.images(l, x, y) {
                        if i != NONE {
                            set.insert(i);
                        }
                    }
                    let edge = l != NONE
                        && [(x.wrapping_sub(1), y), (x + 1, y), (x, y.wrapping_sub(1)), (x, y + 1)]
                            .into_iter()
                            .any(|(a, b)| a < cw && b < ch && !plan.images[l as usize].sees(a, b));
                    // Where the cell's image may not see the ground, any
                    // image that sees the cell may have to fill it.
                    let hides = prone.is_some_and(|p| p[y * cw + x]);
                    if edge || hides {
                        set.extend((0..plan.images.len()).filter(|&i| plan.images[i].sees(x, y)).map(|i| i as u16));
                    }
                }
            }
            for i in set {
                let e = needs[i as usize].entry(ty_).or_insert((tx_, tx_ + 1));
                e.0 = e.0.min(tx_);
                e.1 = e.1.max(tx_ + 1);
            }
        }
    }
    let g = plan.grid;
    needs
        .into_iter()
        .enumerate()
        .filter(|(_, b)| !b.is_empty())
        .map(|(i, bands)| {
            let c0 = bands.values().map(|r| r.0).min().unwrap_or(0);
            let c1 = bands.values().map(|r| r.1).max().unwrap_or(0);
            let (r0, r1) = (*bands.keys().next().unwrap_or(&0), bands.keys().last().map_or(0, |r| r + 1));
            // The image's grid: those tiles of the mosaic's, clipped to it.
            let (x0, y0) = g.ground((c0 * tile) as f64, (r0 * tile) as f64);
            let (w, h) = (((c1 * tile).min(g.width) - c0 * tile) as f64, ((r1 * tile).min(g.height) - r0 * tile) as f64);
            let bounds = [x0, y0 - h * g.gsd.y, x0 + w * g.gsd.x, y0];
            let mut opts = opts_of(i);
            opts.grid = crate::options::Grid {
                gsd: Some(g.gsd),
                bounds: Some(bounds),
                snap: Snap::None,
                like: None,
                crs: Some(plan.crs.clone()),
                window: opts.grid.window,
                max_output_pixels: Some(u64::MAX),
            };
            opts.file.tile = tile;
            let grid = crate::geom::OutputGrid { x0, y0, gsd: g.gsd, width: w as u32, height: h as u32 };
            ImageWork { image: i, origin: (c0, r0), bands, opts, grid, dem: Some((plan.dems[plan.images[i].dem].clone(), plan.crs.clone())) }
        })
        .collect()
}

/// A render the memory does not hold: what the rest takes, and the
/// memory that holds it all (bytes).
#[derive(Clone, Copy, Debug)]
pub struct Short {
    pub fixed: u64,
    /// What a render needs (more with large tiles).
    pub share: u64,
    pub enough: u64,
}

impl From<Short> for Error {
    fn from(s: Short) -> Error {
        Error::setting(
            "memory",
            format!(
                "the mosaic's bands, its plan and the images at work take {} MiB, and a render needs {} MiB more: give ‹memory› {}M or more",
                s.fixed.div_ceil(1 << 20),
                s.share.div_ceil(1 << 20),
                s.enough.div_ceil(1 << 20)
            ),
        )
    }
}

/// How a render fits its memory: images making a band at once, and the
/// memory of each.
pub type Fit = (usize, u64);

/// The least memory an image's render in a mosaic runs in: its scan's rows
/// read in place (no copy) for frames a few thousand pixels wide.
const MIN_SHARE: u64 = 24 << 20;
/// What an image's thread holds between its turns: its GCM's node rows,
/// its threads' stacks (about 1 MiB measured on 2000² frames).
const IDLE_IMAGE: u64 = 1 << 20;

/// What each image keeps through the render, whether at work or not: its
/// entry in the plan (its options) and its works (the mosaic's and a
/// strip's): about 4 KB, 18 MB for 4000 frames.
const PER_IMAGE: u64 = (std::mem::size_of::<super::plan::PlanImage>() + 2 * std::mem::size_of::<ImageWork>()) as u64;

/// The least memory an image's render is given: [`MIN_SHARE`], or what
/// its tiles in flight take as `rectify`'s do (the manifest's `tile` may
/// be large). Its geometry is planned for this much whatever it gets, so
/// that every window and strip makes the same choices.
pub fn least_share(spec: &OutputSpec) -> u64 {
    let tile = spec.chunk().0 as u64;
    MIN_SHARE.max(crate::pipeline::tiles_memory(spec.tile_bytes() as u64 + tile * tile, u64::MAX))
}

/// The render's memory for the mosaic bands `b0..b0 + n` of `spec`, in a
/// strip `across` tile columns wide: the writer's bands in flight and
/// unfinished overview tiles; the plan's arrays (and the blend's `weights`
/// bytes), DEMs and images; the images'
/// bands in hand, of a band of the mosaic and the next (see [`Turns`]), a
/// tile and its mask for each of their tile columns; the images alive
/// between turns. What is left goes to the renders that run at once, as
/// many as it holds at [`MIN_SHARE`] each, up to all the images those two
/// bands need (more at once keep the cores busy through each one's serial
/// stages). Returns how many at once, and each one's memory.
pub fn budget(plan: &Plan, weights: u64, works: &[ImageWork], spec: &OutputSpec, strip: [u32; 4], memory: u64) -> std::result::Result<Fit, Short> {
    let [_, b0, across, n] = strip;
    let tile = spec.chunk().0 as u64;
    let band_bytes = crate::pipeline::band_writer::held_bytes(spec, across);
    let heights = super::strip_heights::StripHeights::new(works);
    let dems = heights.holding(plan, tile as u32, memory).bytes;
    let arrays = plan.cell_bytes() + weights;
    let images = plan.images.len() as u64 * PER_IMAGE;
    let plan_bytes = arrays + dems + images;
    let image_tile = spec.tile_bytes() as u64 + tile * tile;
    let columns = |b: u32| works.iter().filter_map(|w| w.bands.get(&b)).map(|&(c0, c1)| (c1 - c0) as u64).sum::<u64>();
    let held = (b0..b0 + n).map(|b| columns(b) + columns(b + 1)).max().unwrap_or(0) * image_tile;
    let alive = |b: u32| works.iter().filter(|w| w.bands.contains_key(&b) || w.bands.contains_key(&(b + 1))).count();
    let most = (b0..b0 + n).map(alive).max().unwrap_or(1).max(1);
    let fixed = band_bytes + plan_bytes + held + most as u64 * IDLE_IMAGE;
    let room = memory.saturating_sub(fixed);
    let min_share = least_share(spec);
    if room < min_share {
        // The figure that does: more memory lets the plan hold more of its
        // DEMs (a share of the budget each, up to the whole) and take
        // more cells. A plan of cells a tile wide or more (an absurd
        // budget's) says little of which images a tile needs: then every
        // image whose footprint meets a band is taken at work in it (a
        // bound).
        let [c0, ..] = strip;
        let boxes: Vec<[u32; 4]> = plan
            .images
            .iter()
            .map(|im| {
                let [x0, y0, x1, y1] = im.pixels.map(|p| p as u64);
                [((x0 / tile) as u32).max(c0), (y0 / tile) as u32, (x1.div_ceil(tile) as u32).min(c0 + across), y1.div_ceil(tile) as u32]
            })
            .filter(|b| b[0] < b[2])
            .collect();
        let meets = |b: u32| boxes.iter().filter(move |x| x[1] <= b + 1 && b < x[3]);
        let held_then = (b0..b0 + n).map(|b| meets(b).map(|x| 2 * (x[2] - x[0]) as u64).sum::<u64>()).max().unwrap_or(0) * image_tile;
        let most_then = (b0..b0 + n).map(|b| meets(b).count()).max().unwrap_or(1).max(most) as u64;
        let other = match plan.cell as u64 >= tile {
            true => band_bytes + held.max(held_then) + most_then * IDLE_IMAGE,
            false => fixed - plan_bytes,
        };
        let px = plan.grid.width as u64 * plan.grid.height as u64;
        let cells = (plan.cw * plan.ch).max(1) as u64;
        // The cells' count is estimated (boxes round up to whole cells):
        // a sixteenth more, so that the figure given does run. The plan's
        // cells and DEMs are taken at the figure itself (a little more
        // memory may double the cells across and down), until it holds;
        // in whole MiB, as the figure is given (a figure rounded up may
        // be the one that doubles them).
        let mib = |b: u64| b.next_multiple_of(1 << 20);
        let mut enough = mib(fixed + min_share);
        for _ in 0..16 {
            let side = super::plan::cell_side(px, enough) as u64;
            // Another plan's cells: a label and blend weights each, and a
            // bit for each image whose box holds it (16 deep at most).
            let arrays_then = if side == plan.cell as u64 { arrays } else { (px / (side * side)).max(cells) * 14 };
            let dems_then = heights.holding(plan, tile as u32, enough).bytes;
            let need = other + min_share + arrays_then + dems_then + images;
            let need = need + need / 16;
            if need <= enough {
                break;
            }
            enough = mib(need);
        }
        return Err(Short { fixed, share: min_share, enough });
    }
    let at_once = (room / min_share).clamp(1, most as u64);
    Ok((at_once as usize, room / at_once))
}

/// A sample of the output's type, composed in f64.
trait Px: Copy + Send + Sync + bytemuck::Pod {
    /// The values a sample takes, where few enough for a correction to be
    /// tabulated (u8); 0: none.
    const LEVELS: usize;
    fn get(self) -> f64;
    fn put(v: f64) -> Self;
    /// Its index in a table of [`Px::LEVELS`].
    fn level(self) -> usize;
}
impl Px for u8 {
    const LEVELS: usize = 256;
    fn get(self) -> f64 {
        self as f64
    }
    fn put(v: f64) -> u8 {
        v.round().clamp(0.0, 255.0) as u8
    }
    fn level(self) -> usize {
        self as usize
    }
}
impl Px for u16 {
    const LEVELS: usize = 0;
    fn get(self) -> f64 {
        self as f64
    }
    fn put(v: f64) -> u16 {
        v.round().clamp(0.0, 65535.0) as u16
    }
    fn level(self) -> usize {
        0
    }
}
impl Px for f32 {
    const LEVELS: usize = 0;
    fn get(self) -> f64 {
        self as f64
    }
    fn put(v: f64) -> f32 {
        v as f32
    }
    fn level(self) -> usize {
        0
    }
}

/// A correction without a radial term on samples of few values, as
/// tables of each band's values: the corrected sample, and the corrected
/// value for blending.
struct Table<T> {
    sample: Vec<T>,
    value: Vec<f64>,
}

impl<T: Px> Table<T> {
    fn of(c: &Correction, bands: usize) -> Option<Table<T>> {
        if T::LEVELS == 0 || c.has_radial() {
            return None;
        }
        let value: Vec<f64> = (0..bands).flat_map(|band| (0..T::LEVELS).map(move |v| c.apply(band, v as f64, 0.0))).collect();
        Some(Table { sample: value.iter().map(|&v| T::put(v)).collect(), value })
    }

    /// Pixel `from` corrected into `pixel`.
    #[inline]
    fn put(&self, pixel: &mut [T], from: &[T]) {
        for (band, (v, s)) in pixel.iter_mut().zip(from).enumerate() {
            *v = self.sample[band * T::LEVELS + s.level()];
        }
    }
}

/// One image's tile of a band, as the compositor reads it.
struct Piece<'a> {
    image: u16,
    bytes: &'a [u8],
    valid: &'a [u8],
    /// Under occlusion: what it sees, and the tile's first pixel on its grid.
    seen: Option<(&'a crate::transform::visibility::Seen, u32, u32)>,
}

/// How the compositor weighs and corrects.
pub struct Compose<'a> {
    pub plan: &'a Plan,
    pub weights: &'a Weights,
    pub corrections: &'a [Correction],
    pub tile: u32,
    pub bands: usize,
    pub fill: f64,
    /// Under occlusion: pixels some image images, and of them those every
    /// image that images them hides.
    pub covered: std::sync::atomic::AtomicU64,
    pub unseen: std::sync::atomic::AtomicU64,
}

impl Compose<'_> {
    /// Mosaic tile (tc, b) from the pieces of the images that have it.
    fn tile<T: Px>(&self, tc: u32, b: u32, pieces: &[Piece], held: &[(u16, BoxCells)], out: &mut [T], valid: &mut [u8]) {
        let (t, nb, c) = (self.tile as usize, self.bands, self.plan.cell as f64);
        let (gx0, gy0) = ((tc * self.tile) as usize, (b * self.tile) as usize);
        let (w, h) = (self.plan.grid.width as usize, self.plan.grid.height as usize);
        // The cells the tile's pixels weigh by (bilinearly between their
        // centres, or the nearest one), and each piece's weight in them.
        let first = |g: usize| ((g as f64 + 0.5) / c - 0.5).floor() as i64;
        let (cx0, cy0) = (first(gx0), first(gy0));
        let (nx, ny) = ((first(gx0 + t - 1) - cx0 + 2) as usize, (first(gy0 + t - 1) - cy0 + 2) as usize);
        let (cw, ch) = (self.plan.cw as i64, self.plan.ch as i64);
        let grids: Vec<Vec<f32>> = pieces
            .iter()
            .map(|p| {
                (0..nx * ny)
                    .map(|k| {
                        let (x, y) = ((cx0 + (k % nx) as i64).clamp(0, cw - 1), (cy0 + (k / nx) as i64).clamp(0, ch - 1));
                        let (x, y) = (x as usize, y as usize);
                        self.weights.weight(self.plan.label_at(x, y), x, y, p.image)
                    })
                    .collect()
            })
            .collect();
        // Each column's (cell, fraction) and each row's.
        let along = |g0: usize, c0: i64| -> Vec<(usize, f64, usize)> {
            (0..t)
                .map(|k| {
                    let u = ((g0 + k) as f64 + 0.5) / c - 0.5;
                    let near = ((g0 + k) as f64 / c).floor() as i64 - c0;
                    ((u.floor() as i64 - c0) as usize, u - u.floor(), near.max(0) as usize)
                })
                .collect()
        };
        let (cols, rows) = (along(gx0, cx0), along(gy0, cy0));
        let blends = self.weights.blends();
        let samples: Vec<&[T]> = pieces.iter().map(|p| bytemuck::cast_slice::<u8, T>(p.bytes)).collect();
        let corrections: Vec<&Correction> = pieces.iter().map(|p| &self.corrections[p.image as usize]).collect();
        // Where a correction has a radial term: each piece's ρ (where in its
        // scan it sees each cell) on the same cells, NaN where unseen.
        let radii: Vec<Option<Vec<f32>>> = pieces
            .iter()
            .zip(&corrections)
            .map(|(p, corr)| {
                let im = held.iter().find(|(k, _)| *k == p.image).map(|(_, cells)| cells)?;
                corr.has_radial().then(|| {
                    (0..nx * ny)
                        .map(|k| {
                            let (x, y) = ((cx0 + (k % nx) as i64).clamp(0, cw - 1), (cy0 + (k / nx) as i64).clamp(0, ch - 1));
                            im.radius(x as usize, y as usize).unwrap_or(f32::NAN)
                        })
                        .collect()
                })
            })
            .collect();
        // ρ² of piece j at the tile's pixel (px, py): bilinear between the
        // cells' centres (ρ is smooth), else the nearest cell's, else the
        // mean of those there are.
        let rho2 = |j: usize, px: usize, py: usize| -> f64 {
            let Some(r) = &radii[j] else { return 0.0 };
            let ((iu, fu, nu), (iv, fv, nv)) = (cols[px], rows[py]);
            let at = |x: usize, y: usize| r[(y * nx + x).min(r.len() - 1)] as f64;
            let b = (at(iu, iv) * (1.0 - fu) + at(iu + 1, iv) * fu) * (1.0 - fv) + (at(iu, iv + 1) * (1.0 - fu) + at(iu + 1, iv + 1) * fu) * fv;
            let rho = if b.is_finite() {
                b
            } else if at(nu, nv).is_finite() {
                at(nu, nv)
            } else {
                let near: Vec<f64> = [at(iu, iv), at(iu + 1, iv), at(iu, iv + 1), at(iu + 1, iv + 1)].into_iter().filter(|v| v.is_finite()).collect();
                if near.is_empty() {
                    0.0
                } else {
                    near.iter().sum::<f64>() / near.len() as f64
                }
            };
            rho * rho
        };
        let tables: Vec<Option<Table<T>>> = corrections.iter().map(|c| Table::of(c, nb)).collect();
        let identity: Vec<bool> = corrections.iter().map(|c| c.is_identity()).collect();
        // Pixel k (at px, py) of piece j, corrected, into `pixel`.
        let corrected = |pixel: &mut [T], j: usize, k: usize, px: usize, py: usize| {
            let from = &samples[j][k * nb..(k + 1) * nb];
            if let Some(t) = &tables[j] {
                return t.put(pixel, from);
            }
            let r2 = rho2(j, px, py);
            for (band, (v, s)) in pixel.iter_mut().zip(from).enumerate() {
                *v = T::put(corrections[j].apply(band, s.get(), r2));
            }
        };
        // Sample `s` of `band` of piece j seen at ρ² `r2`, corrected.
        let value = |j: usize, band: usize, s: T, r2: f64| match &tables[j] {
            Some(t) => t.value[band * T::LEVELS + s.level()],
            None => corrections[j].apply(band, s.get(), r2),
        };
        // One image with all the weight over the whole tile: its pixels as
        // they are (corrected), others only where it has none.
        let sole =
            (0..pieces.len()).find(|&i| grids[i].iter().all(|&v| v == 1.0) && grids.iter().enumerate().all(|(j, g)| j == i || g.iter().all(|&v| v == 0.0)));
        let mut acc = vec![0f64; nb];
        let mut spare = vec![0f64; nb];
        // Between four cell centres where one piece has all the weight and
        // the others none (most of a tile a seam crosses), a pixel that
        // piece has is that piece's, corrected.
        let one_piece: Vec<Option<usize>> = (0..nx * ny)
            .map(|q| {
                let (x, y) = (q % nx, q / nx);
                if x + 1 >= nx || y + 1 >= ny {
                    return None;
                }
                let corners = [q, q + 1, q + nx, q + nx + 1];
                let full = |g: &Vec<f32>| corners.iter().all(|&c| g[c] == 1.0);
                let empty = |g: &Vec<f32>| corners.iter().all(|&c| g[c] == 0.0);
                let j = grids.iter().position(full)?;
                grids.iter().enumerate().all(|(i, g)| i == j || empty(g)).then_some(j)
            })
            .collect();
        for (py, &(iv, fv, nv)) in rows.iter().enumerate() {
            if let Some(i) = sole {
                // Pixels of the row inside the mosaic.
                let inside = if gy0 + py < h { t.min(w.saturating_sub(gx0)) } else { 0 };
                let row = py * t..py * t + inside;
                if inside == t && pieces[i].valid[row.clone()].iter().all(|&v| v != 0) {
                    // The image has the whole row (most rows of most
                    // tiles): copied, or through its table, at once.
                    let (from, to) = (&samples[i][row.start * nb..row.end * nb], &mut out[row.start * nb..row.end * nb]);
                    match &tables[i] {
                        _ if identity[i] => to.copy_from_slice(from),
                        Some(table) => to.chunks_exact_mut(nb).zip(from.chunks_exact(nb)).for_each(|(p, f)| table.put(p, f)),
                        None => {
                            for px in 0..t {
                                let k = py * t + px;
                                corrected(&mut out[k * nb..(k + 1) * nb], i, k, px, py);
                            }
                        }
                    }
                    valid[row].fill(1);
                    continue;
                }
                for px in 0..t {
                    let k = py * t + px;
                    let pixel = &mut out[k * nb..(k + 1) * nb];
                    let from = if px >= inside {
                        None
                    } else if pieces[i].valid[k] != 0 {
                        Some(i)
                    } else {
                        (0..pieces.len()).find(|&j| pieces[j].valid[k] != 0)
                    };
                    match from {
                        Some(j) if identity[j] => pixel.copy_from_slice(&samples[j][k * nb..(k + 1) * nb]),
                        Some(j) => corrected(pixel, j, k, px, py),
                        None => pixel.iter_mut().for_each(|v| *v = T::put(self.fill)),
                    }
                    valid[k] = u8::from(from.is_some());
                }
                continue;
            }
            for (px, &(iu, fu, nu)) in cols.iter().enumerate() {
                let k = py * t + px;
                let pixel = &mut out[k * nb..(k + 1) * nb];
                if gx0 + px >= w || gy0 + py >= h {
                    pixel.iter_mut().for_each(|v| *v = T::put(self.fill));
                    valid[k] = 0;
                    continue;
                }
                let quad = if blends { iv * nx + iu } else { nv * nx + nu };
                if let Some(j) = one_piece.get(quad).copied().flatten().filter(|&j| pieces[j].valid[k] != 0) {
                    corrected(pixel, j, k, px, py);
                    valid[k] = 1;
                    continue;
                }
                let (mut wsum, mut spare_n) = (0f64, 0f64);
                acc.iter_mut().for_each(|a| *a = 0.0);
                for (j, ((p, s), g)) in pieces.iter().zip(&samples).zip(&grids).enumerate() {
                    if p.valid[k] == 0 {
                        continue;
                    }
                    let r2 = if tables[j].is_some() { 0.0 } else { rho2(j, px, py) };
                    let wt = if blends {
                        let at = |x: usize, y: usize| g[y * nx + x] as f64;
                        (at(iu, iv) * (1.0 - fu) + at(iu + 1, iv) * fu) * (1.0 - fv) + (at(iu, iv + 1) * (1.0 - fu) + at(iu + 1, iv + 1) * fu) * fv
                    } else {
                        g[nv * nx + nu] as f64
                    };
                    let px_in = &s[k * nb..(k + 1) * nb];
                    if wt > 0.0 {
                        wsum += wt;
                        for (band, a) in acc.iter_mut().enumerate() {
                            *a += wt * value(j, band, px_in[band], r2);
                        }
                    } else if spare_n == 0.0 {
                        // No weight here (a footprint's edge inside the
                        // cell): the first image that has the pixel.
                        spare_n = 1.0;
                        for (band, a) in spare.iter_mut().enumerate() {
                            *a = value(j, band, px_in[band], r2);
                        }
                    }
                }
                let (sum, n) = if wsum > 0.0 { (&acc, wsum) } else { (&spare, spare_n) };
                if n > 0.0 {
                    for (v, a) in pixel.iter_mut().zip(sum.iter()) {
                        *v = T::put(a / n);
                    }
                    valid[k] = 1;
                } else {
                    pixel.iter_mut().for_each(|v| *v = T::put(self.fill));
                    valid[k] = 0;
                }
            }
        }
    }

    /// Under occlusion, counts the tile's pixels that some piece images
    /// (`valid`: the composed tile's) and those no piece sees.
    fn count_unseen(&self, pieces: &[Piece], valid: &[u8]) {
        use std::sync::atomic::Ordering;
        if pieces.iter().all(|p| p.seen.is_none()) {
            return;
        }
        let t = self.tile;
        let (mut covered, mut unseen) = (0u64, 0u64);
        for (k, &v) in valid.iter().enumerate() {
            let (px, py) = (k as u32 % t, k as u32 / t);
            if v != 0 {
                covered += 1;
            } else if pieces.iter().any(|p| p.seen.is_some_and(|(s, x0, y0)| !s.at(x0 + px, y0 + py))) {
                covered += 1;
                unseen += 1;
            }
        }
        self.covered.fetch_add(covered, Ordering::Relaxed);
        self.unseen.fetch_add(unseen, Ordering::Relaxed);
    }

    /// Tile columns `cols` of band `b` of the mosaic from the images' bands.
    fn band<T: Px>(&self, b: u32, cols: (u32, u32), got: &[(&ImageWork, &BandPixels)], pool: &rayon::ThreadPool) -> Result<(Vec<T>, Vec<u8>)> {
        let tpx = (self.tile * self.tile) as usize;
        // Where a correction has a radial term: where its image sees the
        // band's cells (and one around).
        let c = self.plan.cell as usize;
        let rows = ((b * self.tile) as usize / c).saturating_sub(1)..((b + 1) * self.tile) as usize / c + 2;
        let held: Vec<(u16, BoxCells)> = got
            .iter()
            .map(|(w, _)| w.image)
            .filter(|&k| self.corrections[k].has_radial())
            .map(|k| Ok((k as u16, self.plan.radius_rows_of(k, rows.clone())?)))
            .collect::<Result<_>>()?;
        let tx = cols.1 - cols.0;
        let mut out = vec![T::put(self.fill); tx as usize * tpx * self.bands];
        let mut valid = vec![0u8; tx as usize * tpx];
        pool.install(|| {
            out.par_chunks_mut(tpx * self.bands).zip(valid.par_chunks_mut(tpx)).enumerate().for_each(|(k, (o, v))| {
                let tc = cols.0 + k as u32;
                let pieces: Vec<Piece> =
                    got.iter().filter_map(|(w, band)| piece(w, band, tc, self.tile, tpx * self.bands * std::mem::size_of::<T>(), tpx)).collect();
                self.tile::<T>(tc, b, &pieces, &held, o, v);
                self.count_unseen(&pieces, v);
            })
        });
        Ok((out, valid))
    }

    /// Tile columns `cols` of band `b` in the output's sample type.
    pub fn make_band(
        &self,
        b: u32,
        cols: (u32, u32),
        got: &[(&ImageWork, &BandPixels)],
        pool: &rayon::ThreadPool,
        sample: crate::io::source::SampleType,
    ) -> Result<(Raw, Option<Vec<u8>>)> {
        use crate::io::source::SampleType;
        Ok(match sample {
            SampleType::U8 => {
                let (o, v) = self.band::<u8>(b, cols, got, pool)?;
                (Raw::U8(o), Some(v))
            }
            SampleType::U16 => {
                let (o, v) = self.band::<u16>(b, cols, got, pool)?;
                (Raw::U16(o), Some(v))
            }
            SampleType::F32 => {
                let (o, v) = self.band::<f32>(b, cols, got, pool)?;
                (Raw::F32(o), Some(v))
            }
        })
    }
}

/// The tile of mosaic column `tc` in an image's band, where it made it.
fn piece<'a>(w: &ImageWork, band: &'a BandPixels, tc: u32, tile: u32, tile_bytes: usize, tile_px: usize) -> Option<Piece<'a>> {
    let own = tc.checked_sub(w.origin.0)?;
    let seen = band.seen.as_deref().map(|s| (s, own * tile, band.band * tile));
    band.chunks.iter().find_map(|m: &Made| {
        let k = own.checked_sub(m.first_col)? as usize;
        let bytes = m.raw.bytes().get(k * tile_bytes..(k + 1) * tile_bytes)?;
        let valid = m.valid.as_ref()?.get(k * tile_px..(k + 1) * tile_px)?;
        Some(Piece { image: w.image as u16, bytes, valid, seen })
    })
}

/// The images' threads: started a band before their first, each sending
/// its bands in order, each band made in its turn (see [`Turns`]).
pub struct Feeds<'scope, 'env> {
    receivers: Vec<Option<Receiver<Result<BandPixels>>>>,
    started: Vec<bool>,
    turns: Arc<Turns>,
    scope: &'scope std::thread::Scope<'scope, 'env>,
    /// The workers the images resample on (the composer's).
    pool: &'env rayon::ThreadPool,
}

impl<'scope, 'env> Feeds<'scope, 'env> {
    /// Feeds for `n` images, `at_once` of them making a band at a time,
    /// resampling on `pool`.
    pub fn new(scope: &'scope std::thread::Scope<'scope, 'env>, n: usize, at_once: usize, pool: &'env rayon::ThreadPool) -> Feeds<'scope, 'env> {
        Feeds { receivers: (0..n).map(|_| None).collect(), started: vec![false; n], turns: Arc::new(Turns::new(at_once)), scope, pool }
    }

    /// The bands of band `b` from the images that have it (starting those
    /// whose first band is `b` or the next, and letting the next band's
    /// be made meanwhile).
    pub fn band(&mut self, works: &[ImageWork], b: u32, cancel: &'env Cancel, warn: &'env dyn Progress) -> Result<Vec<(usize, BandPixels)>> {
        for (k, w) in works.iter().enumerate() {
            let first = *w.bands.keys().next().unwrap_or(&u32::MAX);
            if !self.started[k] && first <= b + 1 {
                self.started[k] = true;
                let (tx, rx) = bounded(1);
                self.receivers[k] = Some(rx);
                let (turns, w, pool) = (self.turns.clone(), w.clone(), self.pool);
                self.scope.spawn(move || {
                    let requests = w.requests();
                    let (x0, y0) = w.origin;
                    let turn = |&(band, cols): &BandRequest| turns.wait((band + y0, cols.0 + x0, k));
                    let r = render_bands(&w.opts, w.dem.clone(), &requests, &Shared { pool, cancel, warn }, turn, |band| tx.send(band).is_ok());
                    if let Err(e) = r {
                        let _ = tx.send(Err(e));
                    }
                });
            }
        }
        self.turns.open_to(b + 1);
        let mut got = Vec::new();
        for (k, w) in works.iter().enumerate() {
            if !w.bands.contains_key(&b) {
                continue;
            }
            let rx = self.receivers[k].as_ref().ok_or_else(|| Error::Internal("an image's band was asked before its thread started".into()))?;
            let band = rx.recv().map_err(|_| Error::Cancelled)??;
            got.push((k, band));
            if w.bands.keys().last() == Some(&b) {
                // Its last band: the thread ends, the scan is closed.
                self.receivers[k] = None;
            }
        }
        Ok(got)
    }
}

impl Drop for Feeds<'_, '_> {
    /// The composer is done (or failed): renders still waiting end.
    fn drop(&mut self) {
        self.turns.close();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table of a gain and offset on bytes gives what the correction
    /// gives, rounded and clamped; a radial term or wider samples get none.
    #[test]
    fn tabled_corrections_equal_the_correction() {
        let c = Correction { gain: vec![0.93, 1.2], offset: vec![-13.5, 4.25], radial: Vec::new() };
        let t = Table::<u8>::of(&c, 2).expect("bytes without a radial term are tabled");
        for v in 0..=255u8 {
            let mut pixel = [0u8; 2];
            t.put(&mut pixel, &[v, v]);
            assert_eq!(pixel, [u8::put(c.apply(0, v as f64, 0.0)), u8::put(c.apply(1, v as f64, 0.0))]);
            assert_eq!(t.value[256 + v as usize], 1.2 * v as f64 + 4.25);
        }
        let mut p = [0u8; 2];
        t.put(&mut p, &[0, 255]);
        assert_eq!(p, [0, 255], "clamped at both ends");
        let radial = Correction { radial: vec![[0.1, 0.0], [0.0, 0.0]], ..c.clone() };
        assert!(Table::<u8>::of(&radial, 2).is_none());
        assert!(Table::<u16>::of(&c, 2).is_none());
    }
}
