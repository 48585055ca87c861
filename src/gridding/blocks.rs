//! A block of the DEM made from its bin and the points around it, growing
//! the ground read until every triangle used is the whole set's; the
//! blunders of each bin found and marked; points on one line refused.

use super::bins::{Bins, Rect};
use super::methods::{self, CellStat, Cells};
use super::neighbourhood::{Buckets, Loaded, Post, Settle};
use super::{blunders, GridOptions, Method};
use crate::error::{Error, Result};
use crate::geom::OutputGrid;
use crate::progress::{Cancel, Progress, Task};
use rayon::prelude::*;

/// What every block of a run shares.
pub(super) struct Ctx<'a> {
    pub(super) bins: &'a Bins,
    pub(super) max_edge: f64,
    pub(super) radius: f64,
    /// The most points a neighbourhood grows to.
    pub(super) cap: u64,
    pub(super) block: u32,
    pub(super) grid: OutputGrid,
    pub(super) o: &'a GridOptions,
}

impl Ctx<'_> {
    /// The bin of block `(bi, bj)` (columns right, rows down from the DEM's
    /// top-left).
    fn bin_of_block(&self, bi: u32, bj: u32) -> (u32, u32) {
        let g = &self.bins.grid;
        let ring = ((-g.x0) / g.side_x).round() as u32;
        (bi + ring, g.rows - 1 - (bj + ring))
    }

    /// The ground of bin `core` and `reach` around it.
    fn around(&self, core: (u32, u32), reach: f64) -> [f64; 4] {
        let g = self.bins.grid.ground_of(Rect { c0: core.0, r0: core.1, c1: core.0, r1: core.1 });
        [g[0] - reach, g[1] - reach, g[2] + reach, g[3] + reach]
    }

    /// Points in the bins over `region` (those just outside it too).
    fn points_over(&self, region: [f64; 4]) -> u64 {
        let Some(rect) = self.bins.grid.bins_over(region[0], region[1], region[2], region[3]) else { return 0 };
        (rect.r0..=rect.r1).map(|r| (rect.c0..=rect.c1).map(|c| self.bins.count(c, r)).sum::<u64>()).sum()
    }

    /// Runs `f` on the points over `region`, growing the ground read while
    /// a triangle it used may not be the whole set's; returns `f`'s last
    /// result and the triangles left unsettled.
    fn settled<T>(&self, mut region: [f64; 4], cancel: &Cancel, mut f: impl FnMut(&Loaded, &mut Settle) -> T) -> Result<(T, u64)> {
        loop {
            if cancel.is_cancelled() {
                return Err(Error::Cancelled);
            }
            let loaded = Loaded::read(self.bins, region)?;
            let mut settle = Settle::new(self.bins, region);
            let out = f(&loaded, &mut settle);
            match settle.need {
                Some(n) => {
                    let grown = [region[0].min(n[0]), region[1].min(n[1]), region[2].max(n[2]), region[3].max(n[3])];
                    if grown != region && self.points_over(grown) <= self.cap {
                        region = grown;
                        continue;
                    }
                    return Ok((out, settle.unsettled + 1));
                }
                None => return Ok((out, settle.unsettled)),
            }
        }
    }

    /// The cells of block `(bi, bj)` (NaN: no height) and its unsettled
    /// triangles.
    pub(super) fn block_values(&self, bi: u32, bj: u32, cancel: &Cancel) -> Result<(Cells, Vec<f32>, u64)> {
        let b = self.block;
        let (i0, j0) = (bi * b, bj * b);
        let cells = Cells { i0, j0, w: b.min(self.grid.width - i0), h: b.min(self.grid.height - j0), gx: self.grid.gsd.x, gy: self.grid.gsd.y };
        let mut out = vec![f32::NAN; (cells.w * cells.h) as usize];
        let core = self.bin_of_block(bi, bj);
        let o = self.o;
        let unsettled = match o.method {
            Method::Tin | Method::Natural => {
                self.settled(self.around(core, self.max_edge), cancel, |loaded, settle| {
                    out.fill(f32::NAN);
                    if let Some(tin) = loaded.tin() {
                        methods::by_tin(&tin, settle, &cells, self.max_edge, o.method == Method::Natural, &mut out);
                    }
                })?
                .1
            }
            Method::Idw | Method::Nearest => {
                let loaded = Loaded::read(self.bins, self.around(core, self.radius))?;
                let buckets = Buckets::new(&loaded.posts, self.radius);
                methods::by_distance(
                    &buckets,
                    &loaded.posts,
                    &cells,
                    &methods::Distance { radius: self.radius, power: o.power, neighbours: o.neighbours, nearest: o.method == Method::Nearest },
                    &mut out,
                );
                0
            }
            Method::Max | Method::Min | Method::Mean => {
                let loaded = Loaded::read(self.bins, self.around(core, self.grid.gsd.x.max(self.grid.gsd.y)))?;
                let stat = match o.method {
                    Method::Max => CellStat::Max,
                    Method::Min => CellStat::Min,
                    _ => CellStat::Mean,
                };
                methods::by_cell(&loaded.posts, &cells, stat, &mut out);
                0
            }
        };
        Ok((cells, out, unsettled))
    }
}

/// Where blunders are looked for: the points of a bin that a test takes,
/// with the triangles over the ground they lie in.
struct Look<'a> {
    bin: (u32, u32),
    ground: [f64; 4],
    judged: Box<dyn Fn(&Post) -> bool + Sync + 'a>,
}

/// Finds the blunders of the bins `held` from the points as read, then
/// marks them dropped; returns how many points, and their places.
pub(super) fn drop_blunders(ctx: &Ctx, k: f64, held: &[(u32, u32)], progress: &dyn Progress, cancel: &Cancel) -> Result<(u64, Vec<(f64, f64)>)> {
    let g = ctx.bins.grid;
    let looks: Vec<Look> = held
        .iter()
        .map(|&(c, r)| Look {
            bin: (c, r),
            ground: g.ground_of(Rect { c0: c, r0: r, c1: c, r1: r }),
            judged: Box::new(move |p: &Post| g.bin_of(p.x, p.y) == Some((c, r))),
        })
        .collect();
    look_for_blunders(ctx, k, &looks, progress, cancel)
}

/// Finds the blunders that the points `dropped` hid, and marks them
/// dropped; returns how many points. Only a point whose Delaunay
/// neighbourhood lost one can be judged otherwise than before: a
/// neighbour of a dropped point (which was judged, so its neighbours lie
/// within the longest side of it), or a point of a triangle beside such
/// a neighbourhood (within two longest sides). Those are judged again.
pub(super) fn drop_hidden_blunders(ctx: &Ctx, k: f64, dropped: &[(f64, f64)], progress: &dyn Progress, cancel: &Cancel) -> Result<u64> {
    let g = ctx.bins.grid;
    let reach = 2.0 * ctx.max_edge;
    // The dropped points by square of side `reach`.
    let mut near: rustc_hash::FxHashMap<(i64, i64), Vec<(f64, f64)>> = rustc_hash::FxHashMap::default();
    let square = |x: f64, y: f64| ((x / reach).floor() as i64, (y / reach).floor() as i64);
    // Each bin's ground within reach of a dropped point.
    let mut grounds: std::collections::BTreeMap<(u32, u32), [f64; 4]> = std::collections::BTreeMap::new();
    for &(x, y) in dropped {
        near.entry(square(x, y)).or_default().push((x, y));
        let around = [x - reach, y - reach, x + reach, y + reach];
        let Some(over) = g.bins_over(around[0], around[1], around[2], around[3]) else { continue };
        for r in over.r0..=over.r1 {
            for c in over.c0..=over.c1 {
                if ctx.bins.count(c, r) == 0 {
                    continue;
                }
                let bin = g.ground_of(Rect { c0: c, r0: r, c1: c, r1: r });
                let part = [around[0].max(bin[0]), around[1].max(bin[1]), around[2].min(bin[2]), around[3].min(bin[3])];
                grounds
                    .entry((c, r))
                    .and_modify(|e| *e = [e[0].min(part[0]), e[1].min(part[1]), e[2].max(part[2]), e[3].max(part[3])])
                    .or_insert(part);
            }
        }
    }
    let near = &near;
    let looks: Vec<Look> = grounds
        .into_iter()
        .map(|((c, r), ground)| Look {
            bin: (c, r),
            ground,
            judged: Box::new(move |p: &Post| {
                if g.bin_of(p.x, p.y) != Some((c, r)) {
                    return false;
                }
                let (i, j) = square(p.x, p.y);
                (i - 1..=i + 1).any(|i| {
                    (j - 1..=j + 1).any(|j| near.get(&(i, j)).is_some_and(|d| d.iter().any(|&(x, y)| (p.x - x).abs() <= reach && (p.y - y).abs() <= reach)))
                })
            }),
        })
        .collect();
    Ok(look_for_blunders(ctx, k, &looks, progress, cancel)?.0)
}

/// Judges the points of each look, marks the blunders dropped; returns
/// how many points, and their places.
fn look_for_blunders(ctx: &Ctx, k: f64, looks: &[Look], progress: &dyn Progress, cancel: &Cancel) -> Result<(u64, Vec<(f64, f64)>)> {
    progress.start(&Task { name: "blunders", units: looks.len() as u64, lines: 0, line_name: "bins", input_bytes: 0 });
    let found: Vec<Result<Vec<(f64, f64)>>> = looks
        .par_iter()
        .map(|look| {
            let m = ctx.max_edge;
            let region = [look.ground[0] - m, look.ground[1] - m, look.ground[2] + m, look.ground[3] + m];
            let (places, _) = ctx.settled(region, cancel, |loaded, settle| match loaded.tin() {
                Some(tin) => blunders::find(&tin, settle, &*look.judged, m, k),
                None => Vec::new(),
            })?;
            progress.advance(1);
            Ok(places)
        })
        .collect();
    progress.finish();
    let (mut dropped, mut all) = (0, Vec::new());
    for (look, f) in looks.iter().zip(found) {
        let places = f?;
        if places.is_empty() {
            continue;
        }
        let (c, r) = look.bin;
        let set: rustc_hash::FxHashSet<(u64, u64)> = places.iter().map(|&(x, y)| (x.to_bits(), y.to_bits())).collect();
        let mut positions = Vec::new();
        let mut k = 0u64;
        ctx.bins.read_bin(c, r, |p| {
            if set.contains(&(p[0].to_bits(), p[1].to_bits())) {
                positions.push(k);
            }
            k += 1;
        })?;
        dropped += positions.len() as u64;
        ctx.bins.drop_points(c, r, &positions)?;
        all.extend(places);
    }
    Ok((dropped, all))
}

/// Refuses points that make no surface (all on one line) for the methods
/// that triangulate.
pub(super) fn check_not_collinear(ctx: &Ctx, files: &str) -> Result<()> {
    if !matches!(ctx.o.method, Method::Tin | Method::Natural) {
        return Ok(());
    }
    // Three points not on one line among the first of each bin decide it.
    let g = ctx.bins.grid;
    let mut some: Vec<[f64; 3]> = Vec::new();
    for r in 0..g.rows {
        for c in 0..g.cols {
            if ctx.bins.count(c, r) > 0 {
                let mut n = 0;
                ctx.bins.read_bin(c, r, |p| {
                    if n < 64 && !p[2].is_nan() {
                        some.push(*p);
                        n += 1;
                    }
                })?;
            }
        }
    }
    if some.len() < 3 {
        return Err(Error::Named(format!("{files}: {} point(s): a surface needs three not on one line", some.len())));
    }
    let (a, b) = (some[0], some.iter().copied().max_by(|p, q| dist2(p, &some[0]).total_cmp(&dist2(q, &some[0]))).expect("three"));
    let len = dist2(&a, &b).sqrt();
    let off = some.iter().map(|p| ((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])).abs() / len.max(f64::MIN_POSITIVE)).fold(0.0, f64::max);
    if !(off > 1e-9 * len.max(1.0)) {
        return Err(Error::Named(format!("{files}: all the points lie on one line: they make no surface")));
    }
    Ok(())
}

fn dist2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
}
