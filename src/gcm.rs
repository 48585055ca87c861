//! The generalized correction matrix (GCM, thesis §2.4, eq. 2.4.15): exact
//! corrections `c = T − A` at sparse nodes every `k` output pixels, so that
//! `T ≈ A + c` costs one reciprocal per pixel plus `1/k²` exact evaluations.
//!
//! Nodes sit at continuous output coordinates `(k(i+½), k(j+½))`. In `cell`
//! mode (the thesis) a node's value serves its whole k×k cell, node indices
//! `0..⌈W/k⌉`. In `bilinear` mode corrections are interpolated between the
//! four surrounding nodes; node indices run from −1 to ⌈W/k⌉ so that every
//! pixel lies between nodes and nothing is extrapolated. Where the DEM is a
//! grid aligned with the output (same CRS, north-up) and posted at least `k`
//! output pixels apart, its post lines become node lines too (uniform lines
//! within k/4 of one give way; all of them where the posts are less than
//! 1.5 k apart): a bilinear DEM bends only along those
//! lines, so between nodes the terrain is smooth and so are the
//! corrections. This halves the worst error on posted DEMs for a few more
//! nodes.
//!
//! With `max_error` (bilinear only) every cell between four nodes is held to
//! the bound at every pixel, by two estimates that see what a few check
//! points cannot:
//!
//! * the terrain's part, complete: within a cell the DEM is piecewise
//!   bilinear, bending only along its post lines, so its greatest departure
//!   from the plane of the cell's four corners is at the posts inside the
//!   cell or where post lines cross its edges. That height error times the
//!   image's displacement per metre of height (the relief rate, at the
//!   cell) bounds what the corrections' interpolation can miss of the
//!   terrain: a wall or a roof edge between the nodes shows there, however
//!   thin;
//! * the smooth part (the lens, `A`'s curvature, slopes): from the second
//!   differences of the corrections at the nodes around the cell.
//!
//! A cell over the bound is split as a quadtree — at the DEM's own lines
//! where one crosses it (the pieces are then smooth), else in the middle —
//! and pieces that would cost more to split than to compute (≤ 52 px) are
//! evaluated exactly; inside one DEM column (height linear along a row)
//! such pieces, and those far over the bound, row by row as quadratics
//! through the exact model, checked between.
//!
//! Everything is computed a band of rows at a time (`prepare`), so a caller
//! never holds the whole matrix.

mod quadtree;
pub mod self_check;

use crate::dem::{Height, Lookup};
use crate::geom::Span;
use crate::transform::{Approx, Mapped, Transform};
use quadtree::{Frame, Node, Piece};

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CorrectionMode {
    Cell,
    Bilinear,
}

/// What the caller chose: sparsity, mode, optional error bound (source px).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct GcmSpec {
    pub k: u32,
    pub mode: CorrectionMode,
    pub max_error: Option<f64>,
}

/// One row of nodes: corrections in scan pixels, NaN where `T` or `A` has no
/// value (those pixels fall back to `T`).
#[derive(Clone, Debug)]
pub struct NodeRow {
    pub j: i64,
    pub dc: Vec<f64>,
    pub dr: Vec<f64>,
    /// The terrain's height at each node, NaN where it has none.
    pub z: Vec<f64>,
    /// Under an error bound: how the image moves a metre of height up at
    /// each node (scan pixels, column and row); empty without one.
    pub tz: Vec<[f64; 2]>,
    /// Under an error bound, a DEM not aligned with the output: where each
    /// node falls among the DEM's samples (NaN where it does not).
    pub dp: Vec<[f64; 2]>,
}

/// Heights at the nodes of a node row, and, where the DEM (in EPSG:4326)
/// and the sensor model (an RPC) convert ground points to WGS84
/// longitude/latitude alike, the longitude and latitude of each node
/// (`None` where the conversion failed): the camera then projects from
/// them instead of converting again (~10 % of an RPC run's CPU time).
#[derive(Clone, Debug)]
pub struct NodeHeights {
    pub heights: Vec<Height>,
    pub lonlat: Option<Vec<Option<(f64, f64)>>>,
}

/// A piece of a cell being refined, with what the refinement weighs
/// (kept as [`Node`]s: where pieces meet, the leaves' corrections).
#[derive(Clone, Debug)]
struct Quad {
    u0: f64,
    v0: f64,
    du: f64,
    dv: f64,
    /// Corrections (dc, dr) at the corners (u0,v0), (u0+du,v0), (u0,v0+dv), (u0+du,v0+dv).
    corners: [[f64; 2]; 4],
    /// The estimated interpolation error of the corrections' smooth part
    /// over this cell, scan pixels.
    smooth: f64,
    /// The terrain's height at the corners, in the order of `corners`.
    z: [f64; 4],
    /// Scan pixels a metre of height moves the image here, with a margin
    /// (from the corner nodes); NaN where not known.
    rate: f64,
    /// A DEM not aligned with the output: where the corners fall among its
    /// samples (NaN where not known).
    dp: [[f64; 2]; 4],
}

/// Counters for the report: how much the GCM cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct GcmStats {
    /// Exact evaluations of `T` at nodes.
    pub nodes: u64,
    /// Exact evaluations of `T` to check and refine cells.
    pub checks: u64,
    pub cells: u64,
    pub refined_cells: u64,
    /// Pixels filled by `T` itself (invalid nodes, or refined to the bottom).
    pub exact_pixels: u64,
}

impl GcmStats {
    pub fn add(&mut self, o: &GcmStats) {
        self.nodes += o.nodes;
        self.checks += o.checks;
        self.cells += o.cells;
        self.refined_cells += o.refined_cells;
        self.exact_pixels += o.exact_pixels;
    }
}

/// The node rows (and refined cells) covering a band of output rows.
pub struct BandGcm {
    first_j: i64,
    rows: Vec<NodeRow>,
    /// `cells[n][i]`: the refinement of the cell between node rows n, n+1
    /// and node columns i, i+1 (index from the first node): its root in
    /// `quads`.
    cells: Vec<Vec<Option<u32>>>,
    quads: Vec<Node>,
    pub stats: GcmStats,
    /// The first DEM miss met under the `error` policy.
    pub miss: Option<(f64, f64, Lookup)>,
    /// Under `--occlusion`: which of the band's pixels the sensor sees.
    pub seen: Option<std::sync::Arc<crate::transform::visibility::Seen>>,
}

/// The GCM for one output grid.
pub struct Gcm<'a> {
    pub t: &'a Transform<'a>,
    pub a: Approx,
    pub spec: GcmSpec,
    first_node: i64,
    nodes_x: usize,
    /// Node lines in output pixels, increasing: columns `xs[i − first_node]`,
    /// rows `ys[j − first_node]`, and the reciprocals of the gaps between
    /// neighbouring columns.
    xs: Vec<f64>,
    ys: Vec<f64>,
    inv_dx: Vec<f64>,
    /// The first pixel whose centre lies at or right of each node column,
    /// the widest gap between node columns, and 0, 1, 2, … as wide.
    first_px: Vec<usize>,
    /// From each node column to its first pixel's centre (a span's anchor).
    anchor_off: Vec<f64>,
    max_gap: f64,
    ramp: Vec<f64>,
    /// The DEM's bilinear kinks in output coordinates, where the DEM grid is
    /// aligned with the output grid: lines u = au + bu·i and v = av + bv·j.
    kinks: Option<[f64; 4]>,
    /// Where the DEM is a grid not aligned with the output (another CRS, or
    /// turned): the spacing, output pixels, at which a cell's heights are
    /// sampled for its terrain error (half the DEM's posting).
    dem_sampling: Option<f64>,
    /// Over the grid, with a margin: the most scan pixels a metre of height
    /// moves the image (R), and the most its rate changes a metre (|∂²T/∂Z²|).
    relief: (f64, f64),
}

/// How near (output pixels) a DEM line may be to a cell's edge and be that
/// edge: node lines are DEM lines, and both are worked out in floating point.
const EDGE: f64 = 1e-6;

/// How far (in scan pixels) a stepped span (a straight line or a
/// quadratic) between node columns may stray from `A` itself for
/// [`Gcm::row_spans`] to stand in for it: a quarter of the 1/1024 pixel
/// the bilinear kernel's weights resolve.
pub const A_LINEAR_TOLERANCE: f64 = 1.0 / 4096.0;

/// The most quadratic pieces [`Gcm::row_spans`] cuts a gap between node
/// columns into where `A` curves: beyond, pieces of a few pixels cost more
/// in set-up than working every position out.
pub const MAX_SPANS_A_GAP: usize = 4;

/// Scan pixels the widest resampling kernel reaches from its centre
/// (Lanczos-3), plus one: a position further off the scan takes nothing.
const OFF_SCAN_REACH: f64 = 4.0;

/// The forward differences (first step, and its step) of the quadratic
/// through `f` at pixels `p0` (where it is `f0`), the middle one and
/// `p1 − 1`: the span from `p0` steps `f0, f0 + d, f0 + 2d + dd, …`.
/// Straight for two pixels, nothing for one.
fn quadratic_steps(f0: (f64, f64), p0: usize, p1: usize, f: impl Fn(usize) -> (f64, f64)) -> ([f64; 2], [f64; 2]) {
    let l = p1.saturating_sub(p0 + 1);
    if l == 0 {
        return ([0.0; 2], [0.0; 2]);
    }
    let fl = f(p1 - 1);
    if l == 1 {
        return ([fl.0 - f0.0, fl.1 - f0.1], [0.0; 2]);
    }
    let m = l / 2;
    steps_through(f0, f(p0 + m), fl, m, l)
}

/// [`quadratic_steps`] from the values `f0`, `fm`, `fl` at pixels 0, `m`
/// and `l` of the span (0 < m < l).
fn steps_through(f0: (f64, f64), fm: (f64, f64), fl: (f64, f64), m: usize, l: usize) -> ([f64; 2], [f64; 2]) {
    let (l, m) = (l as f64, m as f64);
    // Divided differences: f = f0 + b·t + q·t², then d = b + q, dd = 2q.
    let one = |f0: f64, fm: f64, fl: f64| {
        let (left, right) = ((fm - f0) / m, (fl - fm) / (l - m));
        let q = (right - left) / l;
        (left - q * m + q, 2.0 * q)
    };
    let ((dc, ddc), (dr, ddr)) = (one(f0.0, fm.0, fl.0), one(f0.1, fm.1, fl.1));
    ([dc, dr], [ddc, ddr])
}

impl<'a> Gcm<'a> {
    pub fn new(t: &'a Transform<'a>, a: Approx, spec: GcmSpec) -> Gcm<'a> {
        assert!(spec.k >= 1);
        let k = spec.k as usize;
        let w = t.grid.width as usize;
        let h = t.grid.height as usize;
        // A bilinear DEM bends only along the lines through its samples;
        // when they are lines of the output grid too (same CRS, north-up),
        // refinement splits cells there, leaving smooth pieces.
        let kinks = match &t.dem.model {
            crate::dem::HeightModel::Grid(g) if t.dem.to_dem.is_none() && g.transform[2] == 0.0 && g.transform[4] == 0.0 => {
                let gt = g.transform;
                let grid = &t.grid;
                let u = [(gt[0] + 0.5 * gt[1] - grid.x0) / grid.gsd.x, gt[1] / grid.gsd.x];
                let v = [(grid.y0 - gt[3] - 0.5 * gt[5]) / grid.gsd.y, -gt[5] / grid.gsd.y];
                // Walked by columns, the DEM's columns are lines of v.
                let [u, v] = if t.is_transposed() { [v, u] } else { [u, v] };
                Some([u[0], u[1], v[0], v[1]])
            }
            _ => None,
        };
        let uniform = |n: usize, first: i64| -> Vec<f64> { (0..n).map(|i| k as f64 * ((first + i as i64) as f64 + 0.5)).collect() };
        let (first_node, xs, ys) = match spec.mode {
            CorrectionMode::Cell => (0, uniform(w.div_ceil(k), 0), uniform(h.div_ceil(k), 0)),
            CorrectionMode::Bilinear => {
                let (mut xs, mut ys) = (uniform(w.div_ceil(k) + 2, -1), uniform(h.div_ceil(k) + 2, -1));
                if let Some([au, bu, av, bv]) = kinks {
                    xs = with_dem_lines(xs, au, bu, k as f64);
                    ys = with_dem_lines(ys, av, bv, k as f64);
                }
                (-1, xs, ys)
            }
        };
        let inv_dx = xs.windows(2).map(|p| 1.0 / (p[1] - p[0])).collect();
        let first_px: Vec<usize> = xs.iter().map(|&x| (x - 0.5).ceil().max(0.0) as usize).collect();
        let anchor_off = first_px.iter().zip(&xs).map(|(&p, &x)| p as f64 + 0.5 - x).collect();
        let max_gap = xs.windows(2).map(|p| p[1] - p[0]).fold(k as f64, f64::max);
        let ramp = (0..=max_gap.ceil() as usize + 1).map(|m| m as f64).collect();
        let dem_sampling = match &t.dem.model {
            crate::dem::HeightModel::Grid(g) if kinks.is_none() => {
                // The posting in metres: degrees count their shortest, at 60° of latitude.
                let deg = g.crs.as_ref().is_some_and(|c| c.is_geographic());
                let m = if deg { 111_320.0 * 0.5 } else { 1.0 };
                let posting = g.transform[1].abs().hypot(g.transform[2].abs()).min(g.transform[5].abs().hypot(g.transform[4].abs())) * m;
                Some((posting / t.grid.gsd.max() / 2.0).max(1.0))
            }
            _ => None,
        };
        let relief = relief_rates(t);
        Gcm { t, a, spec, first_node, nodes_x: xs.len(), xs, ys, inv_dx, first_px, anchor_off, max_gap, ramp, kinks, dem_sampling, relief }
    }

    /// Nodes in a node row.
    pub fn nodes_per_row(&self) -> usize {
        self.nodes_x
    }

    /// Whether the DEM's own lines were added to the node lines (bilinear
    /// mode, DEM aligned with the output grid and posted at least `k` apart).
    pub fn dem_aligned_lines(&self) -> bool {
        self.spec.mode == CorrectionMode::Bilinear && self.xs.len() != self.t.grid.width.div_ceil(self.spec.k) as usize + 2
    }

    /// Where to split `[lo, lo + d]`: the DEM line nearest the middle when
    /// one crosses it (however near an end: the piece past it is then
    /// inside one DEM column), else the middle.
    fn split_at(&self, lo: f64, d: f64, axis: usize) -> f64 {
        let mid = lo + d / 2.0;
        if let Some(k) = self.kinks {
            let (a, b) = (k[2 * axis], k[2 * axis + 1]);
            if b > 0.0 {
                let i = ((mid - a) / b).round();
                let line = a + b * i;
                let near = [line, line - b, line + b]
                    .into_iter()
                    .filter(|&x| x > lo + EDGE && x < lo + d - EDGE)
                    .min_by(|x, y| (x - mid).abs().total_cmp(&(y - mid).abs()));
                if let Some(x) = near {
                    return x;
                }
            }
        }
        mid
    }

    /// Output row of node row `j`.
    #[inline]
    fn node_v(&self, j: i64) -> f64 {
        self.ys[(j - self.first_node) as usize]
    }

    /// The box of the cell between node rows `a`, `b` (the next) and node
    /// columns `i`, `i + 1` (from the first node).
    #[inline]
    fn cell_frame(&self, a: i64, b: i64, i: usize) -> Frame {
        let (v0, v1) = (self.node_v(a), self.node_v(b));
        Frame { u0: self.xs[i], v0, du: self.xs[i + 1] - self.xs[i], dv: v1 - v0 }
    }

    /// Whether (u, v) lies among the grid's pixel centres. Only there is a
    /// height the DEM lacks an error (under that policy): the nodes past
    /// them (half a spacing beyond the edge) make no pixel, and without a
    /// value their cells are filled by the exact model, pixel by pixel.
    #[inline]
    fn among_pixels(&self, u: f64, v: f64) -> bool {
        let (w, h) = (self.t.grid.width as f64, self.t.grid.height as f64);
        (0.5..=w - 0.5).contains(&u) && (0.5..=h - 0.5).contains(&v)
    }

    /// Whether no pixel of the piece `q` can take a value from the scan:
    /// its four corners lie beyond one side of it by more than twice the
    /// piece's estimated error and the widest resampling kernel's reach.
    /// The interpolated positions inside are then outside too, as the
    /// exact ones are: refining there (the empty corners of a panoramic
    /// strip's north-up grid, an oblique frame's far side) would cost
    /// exact evaluations for pixels that stay empty either way.
    fn off_the_scan(&self, q: &Quad, error: f64) -> bool {
        let Some((sw, sh)) = self.t.scan else { return false };
        if !error.is_finite() {
            return false;
        }
        let margin = 2.0 * error + OFF_SCAN_REACH;
        let (u1, v1) = (q.u0 + q.du, q.v0 + q.dv);
        let mut at = [[0.0; 2]; 4];
        for (k, (u, v)) in [(q.u0, q.v0), (u1, q.v0), (q.u0, v1), (u1, v1)].into_iter().enumerate() {
            let Some((ac, ar)) = self.a.at(u, v) else { return false };
            at[k] = [ac + q.corners[k][0], ar + q.corners[k][1]];
        }
        let all = |f: &dyn Fn(&[f64; 2]) -> bool| at.iter().all(f);
        all(&|p| p[0] < -margin) || all(&|p| p[0] > sw + margin) || all(&|p| p[1] < -margin) || all(&|p| p[1] > sh + margin)
    }

    /// Correction `T − A` at (u, v), NaN where either has no value.
    #[inline]
    fn correction(&self, u: f64, v: f64, miss: &mut Option<(f64, f64, Lookup)>) -> [f64; 2] {
        match (self.t.exact(u, v), self.a.at(u, v)) {
            (Mapped::Px(c, r), Some((ac, ar))) => [c - ac, r - ar],
            (Mapped::DemMiss(x, y, l), _) => {
                if self.among_pixels(u, v) {
                    miss.get_or_insert((x, y, l));
                }
                [f64::NAN; 2]
            }
            _ => [f64::NAN; 2],
        }
    }

    /// Heights at the nodes of node row `j` (the pipeline's DEM stage).
    pub fn node_heights(&self, j: i64) -> NodeHeights {
        let v = self.node_v(j);
        let ground = |u: f64| self.t.ground(u, v);
        // A DEM in EPSG:4326 under an RPC camera converts each node to
        // longitude/latitude as the camera would: kept for the camera.
        let from = self.t.model.lonlat_from();
        if from.is_some() && from == self.t.dem.lonlat_from() {
            let (heights, lonlat) = self
                .xs
                .iter()
                .map(|&u| {
                    let (x, y) = ground(u);
                    self.t.dem.height_and_lonlat(x, y)
                })
                .unzip();
            return NodeHeights { heights, lonlat: Some(lonlat) };
        }
        let heights = self
            .xs
            .iter()
            .map(|&u| {
                let (x, y) = ground(u);
                self.t.dem.height(x, y)
            })
            .collect();
        NodeHeights { heights, lonlat: None }
    }

    /// Node row `j` from its heights (the pipeline's GCM stage).
    pub fn node_row(&self, j: i64, nodes: &NodeHeights, miss: &mut Option<(f64, f64, Lookup)>) -> NodeRow {
        let heights = &nodes.heights;
        let v = self.node_v(j);
        let mut dc = vec![f64::NAN; self.nodes_x];
        let mut dr = vec![f64::NAN; self.nodes_x];
        // The ground points of the nodes that have a height, projected in
        // one call (`project_many`: the numbers of `project`, in passes the
        // compiler vectorises).
        let (mut at, mut gx, mut gy, mut gz) =
            (Vec::with_capacity(heights.len()), Vec::with_capacity(heights.len()), Vec::with_capacity(heights.len()), Vec::with_capacity(heights.len()));
        for (i, h) in heights.iter().enumerate() {
            let (x, y) = self.t.ground(self.xs[i], v);
            match *h {
                Height::Value(z) => {
                    at.push(i);
                    gx.push(x);
                    gy.push(y);
                    gz.push(z);
                }
                Height::Nodata => {}
                Height::Missing(l) => {
                    if self.among_pixels(self.xs[i], v) {
                        miss.get_or_insert((x, y, l));
                    }
                }
            }
        }
        let (mut col, mut row) = (vec![0.0; at.len()], vec![0.0; at.len()]);
        match &nodes.lonlat {
            Some(lonlat) => {
                // Where the conversion failed the camera's own fails too: NaN.
                let (lon, lat): (Vec<f64>, Vec<f64>) = at.iter().map(|&i| lonlat[i].unwrap_or((f64::NAN, f64::NAN))).unzip();
                self.t.model.project_many_lonlat(&lon, &lat, &gz, &mut col, &mut row);
            }
            None => self.t.model.project_many(&gx, &gy, &gz, &mut col, &mut row),
        }
        // Under a bound, where the image goes a metre higher: the refinement
        // tells the terrain's part of the corrections from the rest by it.
        let mut tz = Vec::new();
        if self.spec.max_error.is_some() {
            let up: Vec<f64> = gz.iter().map(|z| z + 1.0).collect();
            let (mut c1, mut r1) = (vec![0.0; at.len()], vec![0.0; at.len()]);
            match &nodes.lonlat {
                Some(lonlat) => {
                    let (lon, lat): (Vec<f64>, Vec<f64>) = at.iter().map(|&i| lonlat[i].unwrap_or((f64::NAN, f64::NAN))).unzip();
                    self.t.model.project_many_lonlat(&lon, &lat, &up, &mut c1, &mut r1);
                }
                None => self.t.model.project_many(&gx, &gy, &up, &mut c1, &mut r1),
            }
            tz = vec![[f64::NAN; 2]; self.nodes_x];
            for (k, &i) in at.iter().enumerate() {
                tz[i] = [c1[k] - col[k], r1[k] - row[k]];
            }
        }
        for ((&i, c), r) in at.iter().zip(col).zip(row) {
            // NaN where the point is not imaged, as A where it is behind.
            if let (false, Some((ac, ar))) = (c.is_nan(), self.a.at(self.xs[i], v)) {
                dc[i] = c - ac;
                dr[i] = r - ar;
            }
        }
        let z = heights
            .iter()
            .map(|h| match *h {
                Height::Value(z) => z,
                _ => f64::NAN,
            })
            .collect();
        let dp =
            if self.spec.max_error.is_some() && self.dem_sampling.is_some() { self.xs.iter().map(|&u| self.dem_coords(u, v)).collect() } else { Vec::new() };
        NodeRow { j, dc, dr, z, tz, dp }
    }

    /// Node rows `(j0, j1)` and the weight of `j1` for output row `y`.
    #[inline]
    pub fn rows_for(&self, y: u32) -> (i64, i64, f64) {
        match self.spec.mode {
            CorrectionMode::Cell => {
                let j = (y / self.spec.k) as i64;
                (j, j, 0.0)
            }
            CorrectionMode::Bilinear => {
                let v = y as f64 + 0.5;
                let n = line_left_of(&self.ys, v);
                let (a, b) = (self.ys[n], self.ys[n + 1]);
                let j0 = n as i64 + self.first_node;
                (j0, j0 + 1, (v - a) / (b - a))
            }
        }
    }

    /// The node rows a band of output rows `[y0, y1)` needs: those it
    /// interpolates between, and under an error bound one more each side,
    /// so that the curvature at its edge rows is measured as in the middle
    /// of a band (the result must not depend on where bands begin).
    pub fn node_rows_for(&self, y0: u32, y1: u32) -> (i64, i64) {
        let (j0, _, _) = self.rows_for(y0);
        let (_, j1, _) = self.rows_for(y1 - 1);
        if self.spec.max_error.is_some() && self.spec.mode == CorrectionMode::Bilinear {
            let last = self.first_node + self.ys.len() as i64 - 1;
            ((j0 - 1).max(self.first_node), (j1 + 1).min(last))
        } else {
            (j0, j1)
        }
    }

    /// Everything needed to fill output rows `[y0, y1)`.
    pub fn prepare(&self, y0: u32, y1: u32) -> BandGcm {
        let (j_first, j_last) = self.node_rows_for(y0, y1);
        let mut miss = None;
        let rows: Vec<NodeRow> = (j_first..=j_last)
            .map(|j| {
                let h = self.node_heights(j);
                self.node_row(j, &h, &mut miss)
            })
            .collect();
        self.finish_band(j_first, rows, miss)
    }

    /// Builds the band from prepared node rows (refines cells if asked).
    pub fn finish_band(&self, first_j: i64, rows: Vec<NodeRow>, mut miss: Option<(f64, f64, Lookup)>) -> BandGcm {
        let mut stats = GcmStats { nodes: (rows.len() * self.nodes_x) as u64, ..Default::default() };
        let mut cells = Vec::new();
        let mut quads = Vec::new();
        if let (Some(bound), CorrectionMode::Bilinear) = (self.spec.max_error, self.spec.mode) {
            let curvature = self.smooth_curvature(&rows);
            if self.band_within(&rows, &curvature, bound) {
                stats.cells = (rows.len().saturating_sub(1) * (self.nodes_x - 1)) as u64;
                return BandGcm { first_j, rows, cells, quads, stats, miss, seen: None };
            }
            for n in 0..rows.len().saturating_sub(1) {
                let (a, b) = (&rows[n], &rows[n + 1]);
                let row_cells = (0..self.nodes_x - 1)
                    .map(|i| {
                        stats.cells += 1;
                        let corners = [[a.dc[i], a.dr[i]], [a.dc[i + 1], a.dr[i + 1]], [b.dc[i], b.dr[i]], [b.dc[i + 1], b.dr[i + 1]]];
                        if corners.iter().flatten().any(|v| v.is_nan()) {
                            return None;
                        }
                        let Frame { u0, v0, du, dv } = self.cell_frame(a.j, b.j, i);
                        let smooth = self.smooth_error(&curvature, n, i, du, dv);
                        let z = [a.z[i], a.z[i + 1], b.z[i], b.z[i + 1]];
                        // The image moves with height about alike at the four
                        // corners; a quarter again for the change between them.
                        let rate = [a.tz.get(i), a.tz.get(i + 1), b.tz.get(i), b.tz.get(i + 1)]
                            .into_iter()
                            .map(|t| t.map_or(f64::NAN, |t| (t[0] * t[0] + t[1] * t[1]).sqrt()))
                            .fold(0.0f64, |m, r| if r.is_nan() || m.is_nan() { f64::NAN } else { m.max(r) })
                            * 1.25;
                        let dp = |row: &NodeRow, m: usize| row.dp.get(m).copied().unwrap_or([f64::NAN; 2]);
                        let dp = [dp(a, i), dp(a, i + 1), dp(b, i), dp(b, i + 1)];
                        let q = Quad { u0, v0, du, dv, corners, smooth, z, rate, dp };
                        match self.refine(&q, bound, &mut stats, &mut miss, &mut quads) {
                            Node::Leaf(_) => None,
                            root => {
                                stats.refined_cells += 1;
                                quads.push(root);
                                Some((quads.len() - 1) as u32)
                            }
                        }
                    })
                    .collect();
                cells.push(row_cells);
            }
        }
        // Held while the band's rows are made: not twice what it needs.
        quads.shrink_to_fit();
        BandGcm { first_j, rows, cells, quads, stats, miss, seen: None }
    }

    /// Whether every cell of the band is within `bound` without a look at
    /// each: where no DEM line runs inside a cell (a flat DEM, or its post
    /// lines among the node lines), the band's largest curvature over its
    /// widest cell and its largest height span hold the bound for all.
    fn band_within(&self, rows: &[NodeRow], (uu, vv): &(Vec<Vec<f64>>, Vec<Vec<f64>>), bound: f64) -> bool {
        let flat = matches!(self.t.dem.model, crate::dem::HeightModel::Flat(_));
        if !(flat || self.dem_aligned_lines()) || rows.len() < 2 {
            return false;
        }
        // A height a policy gives meets the DEM's own in a step off its
        // post lines (its edge is half a posting past them): each cell is
        // looked at.
        if !flat && self.policy_heights() {
            return false;
        }
        let n = self.nodes_x;
        // The first and last node columns have no second difference.
        let most = |g: &Vec<Vec<f64>>| -> f64 {
            let mut m = 0.0f64;
            for row in g {
                for &x in &row[1..n - 1] {
                    m = if x.is_nan() { f64::INFINITY } else { m.max(x) };
                }
            }
            m
        };
        let (cu, cv) = (most(uu), most(vv));
        let du = self.max_gap;
        let dv = rows.windows(2).map(|p| self.node_v(p[1].j) - self.node_v(p[0].j)).fold(0.0, f64::max);
        let mut span = 0.0f64;
        if !flat {
            for p in rows.windows(2) {
                for i in 0..n - 1 {
                    let z = [p[0].z[i], p[0].z[i + 1], p[1].z[i], p[1].z[i + 1]];
                    let (lo, hi) = z.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
                    // Cells without heights are the nodata cells, filled by T.
                    if lo.is_finite() {
                        span = span.max(hi - lo);
                    }
                }
            }
        }
        let h = span / 2.0;
        (du * du * cu + dv * dv * cv) / 8.0 + 0.5 * self.relief.1 * h * h <= bound
    }

    /// The second derivatives of the corrections' smooth part at every
    /// node of `rows` (scan pixels a pixel²), along u and along v: from
    /// their second differences with the neighbouring nodes, the terrain's
    /// part taken out first (the height's change from the node times the
    /// image's movement a metre there), so that what is measured is the
    /// lens, `A`'s curvature and the slopes; the terrain's kinks are
    /// `terrain_error`'s. NaN where a neighbour has no value; along v, a
    /// band's first and last rows take their neighbour's.
    fn smooth_curvature(&self, rows: &[NodeRow]) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
        let n = self.nodes_x;
        // |f''| at the middle of three nodes `a`, `b`, `c` (the terrain's
        // part, as the middle node sees it, taken out), their spacings `d1`,
        // `d2`: one division for both coordinates.
        #[inline(always)]
        fn curvature(d1: f64, d2: f64, (ac, ar, az): (f64, f64, f64), (bc, br, bz, [tc, tr]): (f64, f64, f64, [f64; 2]), (cc, cr, cz): (f64, f64, f64)) -> f64 {
            let k = 2.0 / (d1 * d2 * (d1 + d2));
            let (tc, tr) = if tc.is_nan() { (0.0, 0.0) } else { (tc, tr) };
            let (ac, ar) = (ac - tc * (az - bz), ar - tr * (az - bz));
            let (cc, cr) = (cc - tc * (cz - bz), cr - tr * (cz - bz));
            let sc = ((cc - bc) * d1 - (bc - ac) * d2) * k;
            let sr = ((cr - br) * d1 - (br - ar) * d2) * k;
            (sc * sc + sr * sr).sqrt()
        }
        let tz = |row: &NodeRow, m: usize| row.tz.get(m).copied().unwrap_or([0.0; 2]);
        let uu: Vec<Vec<f64>> = rows
            .iter()
            .map(|row| {
                let mut out = vec![f64::NAN; n];
                let (dc, dr, z, xs) = (&row.dc[..n], &row.dr[..n], &row.z[..n], &self.xs[..n]);
                for m in 1..n - 1 {
                    out[m] = curvature(
                        xs[m] - xs[m - 1],
                        xs[m + 1] - xs[m],
                        (dc[m - 1], dr[m - 1], z[m - 1]),
                        (dc[m], dr[m], z[m], tz(row, m)),
                        (dc[m + 1], dr[m + 1], z[m + 1]),
                    );
                }
                out
            })
            .collect();
        let mut vv: Vec<Vec<f64>> = (0..rows.len())
            .map(|r| {
                if r == 0 || r + 1 == rows.len() {
                    return Vec::new();
                }
                let (p, c, q) = (&rows[r - 1], &rows[r], &rows[r + 1]);
                let (d1, d2) = (self.node_v(c.j) - self.node_v(p.j), self.node_v(q.j) - self.node_v(c.j));
                (0..n).map(|m| curvature(d1, d2, (p.dc[m], p.dr[m], p.z[m]), (c.dc[m], c.dr[m], c.z[m], tz(c, m)), (q.dc[m], q.dr[m], q.z[m]))).collect()
            })
            .collect();
        let last = rows.len() - 1;
        if rows.len() >= 3 {
            vv[0] = vv[1].clone();
            vv[last] = vv[last - 1].clone();
        } else {
            // Too few rows for a difference across them: as steep as along u.
            vv = uu.clone();
        }
        (uu, vv)
    }

    /// The interpolation error over a cell of `du`×`dv` pixels between node
    /// rows `n`, `n + 1` and columns `i`, `i + 1`, of the corrections'
    /// smooth part (bilinear interpolation misses at most h²/8 of the second
    /// derivative along each side of length h): the largest curvature at the
    /// cell's nodes and their neighbours along each axis. Infinite where a
    /// node has no value.
    fn smooth_error(&self, (uu, vv): &(Vec<Vec<f64>>, Vec<Vec<f64>>), n: usize, i: usize, du: f64, dv: f64) -> f64 {
        let most = |g: &Vec<Vec<f64>>| {
            let mut m = f64::NEG_INFINITY;
            for row in &g[n..n + 2] {
                for &x in &row[i.saturating_sub(1)..(i + 3).min(row.len())] {
                    if !x.is_nan() {
                        m = m.max(x);
                    }
                }
            }
            m
        };
        let (cu, cv) = (most(uu), most(vv));
        let e = (du * du * cu + dv * dv * cv) / 8.0;
        if e.is_finite() && e >= 0.0 {
            e
        } else {
            f64::INFINITY
        }
    }

    /// Where output position (u, v) falls among the DEM's samples.
    fn dem_coords(&self, u: f64, v: f64) -> [f64; 2] {
        let (x, y) = self.t.ground(u, v);
        self.t.dem.sample_coords(x, y).map_or([f64::NAN; 2], |(c, r)| [c, r])
    }

    /// The greatest departure of a DEM not aligned with the output from the
    /// plane through `q`'s corner heights, and the range of heights met:
    /// at the DEM's samples inside the cell and where its sample lines
    /// cross the edges (the cell is a near-parallelogram among the samples,
    /// mapped by its corners). `None` where the corners' places are unknown.
    fn unaligned_departure(&self, q: &Quad, plane: &dyn Fn(f64, f64) -> f64) -> Option<(f64, f64, f64)> {
        let crate::dem::HeightModel::Grid(g) = &self.t.dem.model else { return None };
        let p = q.dp;
        if p.iter().flatten().any(|v| !v.is_finite()) {
            return None;
        }
        // (fu, fv) in the cell → sample coordinates, bilinear in the corners.
        let at = |fu: f64, fv: f64| {
            let top = [p[0][0] + fu * (p[1][0] - p[0][0]), p[0][1] + fu * (p[1][1] - p[0][1])];
            let bottom = [p[2][0] + fu * (p[3][0] - p[2][0]), p[2][1] + fu * (p[3][1] - p[2][1])];
            [top[0] + fv * (bottom[0] - top[0]), top[1] + fv * (bottom[1] - top[1])]
        };
        let (mut worst, mut lo, mut hi) = (0.0f64, f64::INFINITY, f64::NEG_INFINITY);
        let mut look = |fu: f64, fv: f64, z: f64| {
            let d = (z - plane(q.u0 + fu * q.du, q.v0 + fv * q.dv)).abs();
            worst = if d.is_nan() { f64::INFINITY } else { worst.max(d) };
            (lo, hi) = (lo.min(z), hi.max(z));
        };
        // Where sample lines cross the four edges.
        for (a, b, fixed_u) in [(0usize, 1usize, None), (2, 3, None), (0, 2, Some(0.0)), (1, 3, Some(1.0))] {
            for (s0, s1) in [(p[a][0], p[b][0]), (p[a][1], p[b][1])] {
                let (first, last) = (s0.min(s1).floor() as i64 + 1, s0.max(s1).ceil() as i64 - 1);
                if last - first > 4096 {
                    return None;
                }
                for line in first..=last {
                    let t = (line as f64 - s0) / (s1 - s0);
                    let (fu, fv) = match fixed_u {
                        None => (t, if a == 0 { 0.0 } else { 1.0 }),
                        Some(u) => (u, t),
                    };
                    let [c, r] = at(fu, fv);
                    look(fu, fv, g.height_at_sample(c, r));
                }
            }
        }
        // The samples inside: found in sample space, placed in the cell by
        // inverting the corners' map (nearly affine over a cell: a few
        // Newton steps).
        let (ilo, ihi) = (p.iter().map(|c| c[0]).fold(f64::INFINITY, f64::min), p.iter().map(|c| c[0]).fold(f64::NEG_INFINITY, f64::max));
        let (jlo, jhi) = (p.iter().map(|c| c[1]).fold(f64::INFINITY, f64::min), p.iter().map(|c| c[1]).fold(f64::NEG_INFINITY, f64::max));
        let (i0, i1, j0, j1) = (ilo.floor() as i64 + 1, ihi.ceil() as i64 - 1, jlo.floor() as i64 + 1, jhi.ceil() as i64 - 1);
        // More samples than pixels: the pixel centres say as much, for less.
        if ((i1 - i0 + 1).max(0) * (j1 - j0 + 1).max(0)) as f64 > q.du * q.dv {
            return None;
        }
        for j in j0..=j1 {
            for i in i0..=i1 {
                let target = [i as f64, j as f64];
                let (mut fu, mut fv) = (0.5, 0.5);
                for _ in 0..4 {
                    let c = at(fu, fv);
                    let (e, h) = (1e-3, 1e-3);
                    let (cu, cv) = (at(fu + e, fv), at(fu, fv + h));
                    let (a11, a21) = ((cu[0] - c[0]) / e, (cu[1] - c[1]) / e);
                    let (a12, a22) = ((cv[0] - c[0]) / h, (cv[1] - c[1]) / h);
                    let det = a11 * a22 - a12 * a21;
                    if det == 0.0 {
                        break;
                    }
                    let (rx, ry) = (target[0] - c[0], target[1] - c[1]);
                    fu += (a22 * rx - a12 * ry) / det;
                    fv += (a11 * ry - a21 * rx) / det;
                }
                if (0.0..=1.0).contains(&fu) && (0.0..=1.0).contains(&fv) {
                    look(fu, fv, g.post(i, j));
                }
            }
        }
        Some((worst, lo, hi))
    }

    /// The height at output position (u, v), NaN where there is none.
    fn height_at(&self, u: f64, v: f64) -> f64 {
        let (x, y) = self.t.ground(u, v);
        match self.t.dem.height(x, y) {
            Height::Value(z) => z,
            _ => f64::NAN,
        }
    }

    /// Whether the DEM's hole or outside policy gives heights of its own.
    fn policy_heights(&self) -> bool {
        [self.t.dem.on_hole, self.t.dem.on_outside].iter().any(|m| matches!(m, crate::dem::Miss::Height(_)))
    }

    /// Whether the DEM has a height of its own under output position
    /// (u, v), not one its hole or outside policy gives.
    fn own_height(&self, u: f64, v: f64) -> bool {
        let (x, y) = self.t.ground(u, v);
        matches!(self.t.dem.lookup(x, y), Lookup::Height(_))
    }

    /// The terrain's part of `q`'s interpolation error, scan pixels. The
    /// DEM departs from the plane through the heights at the cell's corners
    /// at most where it bends: at its posts inside the cell and where its
    /// post lines cross the edges (or, a DEM not aligned with the output,
    /// on a lattice of half its posting); that departure moves the image by
    /// at most R a metre. And the image moves with height not quite
    /// linearly: over the cell's span of heights 2h, by up to |∂²T/∂Z²|·h²/2
    /// off the line (a wall seen from the side).
    fn terrain_error(&self, q: &Quad) -> f64 {
        if matches!(self.t.dem.model, crate::dem::HeightModel::Flat(_)) {
            return 0.0;
        }
        let (global_rate, bend) = self.relief;
        let rate = if q.rate.is_finite() { q.rate } else { global_rate };
        let (u1, v1) = (q.u0 + q.du, q.v0 + q.dv);
        let corners = q.z;
        let plane = |u: f64, v: f64| {
            let (fu, fv) = ((u - q.u0) / q.du, (v - q.v0) / q.dv);
            let top = corners[0] + fu * (corners[1] - corners[0]);
            let bottom = corners[2] + fu * (corners[3] - corners[2]);
            top + fv * (bottom - top)
        };
        let (mut lo, mut hi) = corners.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &z| (a.min(z), b.max(z)));
        let mut off_plane = 0.0f64;
        // The lines a + b·i strictly inside (lo, hi): (a, b, first i, last i).
        let lines = |a: f64, b: f64, lo: f64, hi: f64| {
            let (mut first, mut last) = (((lo - a) / b).floor() as i64 + 1, ((hi - a) / b).ceil() as i64 - 1);
            while first <= last && !(a + b * first as f64 > lo) {
                first += 1;
            }
            while first <= last && !((a + b * last as f64) < hi) {
                last -= 1;
            }
            (a, b, first, last)
        };
        let none = (0.0, 1.0, 0, -1);
        // The bound is at pixel centres: a DEM posted finer than the
        // pixels is looked at there (no more lookups than pixels).
        let centres = |b: f64| if b < 1.0 { (0.5, 1.0) } else { (f64::NAN, b) };
        let (us, vs) = match (self.kinks, self.dem_sampling) {
            (Some([au, bu, av, bv]), _) if bu > 0.0 && bv > 0.0 => {
                let ((cu, bu2), (cv, bv2)) = (centres(bu), centres(bv));
                let (au, av) = (if cu.is_nan() { au } else { cu }, if cv.is_nan() { av } else { cv });
                (lines(au, bu2, q.u0, u1), lines(av, bv2, q.v0, v1))
            }
            (_, Some(s)) => match self.unaligned_departure(q, &plane) {
                Some((d, zl, zh)) => {
                    (off_plane, lo, hi) = (d, lo.min(zl), hi.max(zh));
                    (none, none)
                }
                // Where the corners' places are unknown: a lattice of half
                // the DEM's posting, and at least three lines a side.
                None => {
                    let s = s.min(q.du / 4.0).min(q.dv / 4.0).floor().max(1.0);
                    (lines(0.5, s, q.u0, u1), lines(0.5, s, q.v0, v1))
                }
            },
            _ => (none, none),
        };
        // A height the hole or outside policy gives meets the DEM's own
        // in a step (at the DEM's edge, half a posting past its last
        // posts, or around a hole), which no plane holds: a cell with
        // both, at its corners or where it is looked at, is not proved.
        let policy_heights = self.policy_heights();
        let mut kinds = [false; 2];
        if policy_heights {
            for (u, v) in [(q.u0, q.v0), (u1, q.v0), (q.u0, v1), (u1, v1)] {
                kinds[usize::from(self.own_height(u, v))] = true;
            }
        }
        let mut look = |u: f64, v: f64| {
            let z = self.height_at(u, v);
            let d = (z - plane(u, v)).abs();
            off_plane = if d.is_nan() { f64::INFINITY } else { off_plane.max(d) };
            (lo, hi) = (lo.min(z), hi.max(z));
            if policy_heights {
                kinds[usize::from(self.own_height(u, v))] = true;
            }
        };
        // Inside one piece of the DEM it is bilinear, reproduced exactly:
        // only where its lines cross the cell can it depart from the plane.
        let at = |(a, b, _, _): (f64, f64, i64, i64), i: i64| a + b * i as f64;
        for i in us.2..=us.3 {
            let u = at(us, i);
            look(u, q.v0);
            look(u, v1);
            for j in vs.2..=vs.3 {
                look(u, at(vs, j));
            }
        }
        for j in vs.2..=vs.3 {
            let v = at(vs, j);
            look(q.u0, v);
            look(u1, v);
        }
        if kinds == [true, true] {
            return f64::INFINITY;
        }
        let h = (hi - lo) / 2.0;
        let e = off_plane * rate + 0.5 * bend * h * h;
        if e.is_nan() {
            f64::INFINITY
        } else {
            e
        }
    }

    /// Whether `q` lies inside one column of cells of a DEM aligned with
    /// the output and posted at least a pixel apart (none of its post
    /// lines across the rows inside): there the height along each output
    /// row is linear (the DEM is bilinear in each of its cells).
    fn inside_one_dem_column(&self, q: &Quad) -> bool {
        let Some([au, bu, _, _]) = self.kinks else { return false };
        // Node lines are DEM lines: one on an edge is not inside.
        bu >= 1.0 && !(au + bu * (((q.u0 + EDGE - au) / bu).floor() + 1.0) < q.u0 + q.du - EDGE)
    }

    /// Row `v`'s run `[l0, l1)` of a [`quadtree::Node::Rows`] piece as a
    /// quadratic through the exact model at its first, middle and last
    /// pixels (its first position, column and row, and their forward
    /// differences, first and second), where it holds
    /// within half the bound at the pixel a quarter of the way along
    /// (along a row inside one DEM column the interpolation's error is
    /// cubic in the pixel: it peaks near a quarter and three quarters of
    /// the way, alike); `None` where it does not, a point has no value,
    /// or the run is too short to be worth four evaluations.
    fn row_quadratic(&self, v: f64, l0: usize, l1: usize) -> Option<[f64; 6]> {
        const SHORTEST: usize = 6;
        let bound = self.spec.max_error?;
        if l1 < l0 + SHORTEST {
            return None;
        }
        // The span's last pixel, its middle (as `quadratic_steps` takes
        // it) and the check a quarter of the way.
        let (l, q) = (l1 - 1 - l0, (l1 - 1 - l0) / 4);
        let [f0, (ec, er), fm, fl] = self.t.exact_all(v, [l0, l0 + q, l0 + l / 2, l0 + l])?;
        let (d, dd) = steps_through(f0, fm, fl, l / 2, l);
        let t = q as f64;
        let step = |f: f64, d: f64, dd: f64| f + t * d + 0.5 * t * (t - 1.0) * dd;
        let off = (ec - step(f0.0, d[0], dd[0])).hypot(er - step(f0.1, d[1], dd[1]));
        (off <= bound / 2.0).then_some([f0.0, f0.1, d[0], d[1], dd[0], dd[1]])
    }

    /// Holds `q` to `bound` at every pixel: splits it where its smooth or
    /// its terrain error may miss it. Returns its node: a leaf where it is
    /// within the bound, else a split (its pieces put into `quads`), rows
    /// (inside one DEM column) or exact.
    fn refine(&self, q: &Quad, bound: f64, stats: &mut GcmStats, miss: &mut Option<(f64, f64, Lookup)>, quads: &mut Vec<Node>) -> Node {
        let error = q.smooth + self.terrain_error(q);
        if error <= bound || self.off_the_scan(q, error) {
            return Node::Leaf(q.corners);
        }
        // Splitting costs 5 exact evaluations and the pieces' checks; below
        // about 52 pixels, computing every pixel exactly is cheaper (and exact).
        let small = q.du * q.dv <= 52.0;
        // A split quarters the error at best: a piece far over the bound
        // would be split down to pieces too small to split. Inside one DEM
        // column its rows are smooth, each one quadratic (a few exact
        // evaluations a row, not one a pixel).
        if error.is_finite() && (small || error > 4.0 * bound) && self.inside_one_dem_column(q) {
            return Node::Rows;
        }
        if small {
            return Node::Exact;
        }
        // Split at the DEM's lines where they cross the cell (the pieces are
        // then smooth), else in the middle. New corners: four edge points and
        // the centre.
        let (su, sv) = (self.split_at(q.u0, q.du, 0), self.split_at(q.v0, q.dv, 1));
        let (u1, v1) = (q.u0 + q.du, q.v0 + q.dv);
        let mut at = |u: f64, v: f64| {
            stats.checks += 1;
            self.correction(u, v, miss)
        };
        let (top, left, right, bottom, centre) = (at(su, q.v0), at(q.u0, sv), at(u1, sv), at(su, v1), at(su, sv));
        let [c00, c10, c01, c11] = q.corners;
        let [z00, z10, z01, z11] = q.z;
        let [p00, p10, p01, p11] = q.dp;
        let (pt, pl, pr, pb, pc) = if self.dem_sampling.is_some() {
            (self.dem_coords(su, q.v0), self.dem_coords(q.u0, sv), self.dem_coords(u1, sv), self.dem_coords(su, v1), self.dem_coords(su, sv))
        } else {
            ([f64::NAN; 2], [f64::NAN; 2], [f64::NAN; 2], [f64::NAN; 2], [f64::NAN; 2])
        };
        let (zt, zl, zr, zb, zc) = (self.height_at(su, q.v0), self.height_at(q.u0, sv), self.height_at(u1, sv), self.height_at(su, v1), self.height_at(su, sv));
        // A piece's smooth error shrinks with the square of its size.
        let mk = |u0: f64, v0: f64, du: f64, dv: f64, corners: [[f64; 2]; 4], z: [f64; 4], dp: [[f64; 2]; 4]| {
            let shrink = (du / q.du).max(dv / q.dv);
            Quad { u0, v0, du, dv, corners, smooth: q.smooth * shrink * shrink, z, rate: q.rate, dp }
        };
        let kids = [
            mk(q.u0, q.v0, su - q.u0, sv - q.v0, [c00, top, left, centre], [z00, zt, zl, zc], [p00, pt, pl, pc]),
            mk(su, q.v0, u1 - su, sv - q.v0, [top, c10, centre, right], [zt, z10, zc, zr], [pt, p10, pc, pr]),
            mk(q.u0, sv, su - q.u0, v1 - sv, [left, centre, c01, bottom], [zl, zc, z01, zb], [pl, pc, p01, pb]),
            mk(su, sv, u1 - su, v1 - sv, [centre, right, bottom, c11], [zc, zr, zb, z11], [pc, pr, pb, p11]),
        ];
        // The four children side by side, theirs after them.
        let first = quads.len();
        quads.extend(std::iter::repeat_n(Node::Exact, 4));
        for (k, kid) in kids.iter().enumerate() {
            if !kid.corners.iter().flatten().any(|v| v.is_nan()) {
                quads[first + k] = self.refine(kid, bound, stats, miss, quads);
            }
        }
        Node::Split { at: (su, sv), first: first as u32 }
    }

    /// The node columns (indices from the first node, inclusive) that output
    /// columns `[x0, x0 + len)` interpolate between.
    fn node_span(&self, x0: u32, len: usize) -> (usize, usize) {
        let k = self.spec.k as usize;
        let x1 = x0 as usize + len.max(1) - 1;
        match self.spec.mode {
            CorrectionMode::Cell => (x0 as usize / k, x1 / k),
            CorrectionMode::Bilinear => {
                let seg = |x: usize| (self.segment(x) - self.first_node) as usize;
                (seg(x0 as usize), seg(x1) + 1)
            }
        }
    }

    /// Output row `y`'s columns `x0..x0+len` as [`Span`]s, one per gap
    /// between node columns (in a refined cell, one per leaf the row
    /// crosses; a leaf marked exact not stepped), into `spans`; `false` (and `spans` empty)
    /// where the row cannot have stepped spans: cell mode, A behind the
    /// camera anywhere along the row, or A, whose denominator is linear in
    /// u, curving so much that a gap would need more than
    /// [`MAX_SPANS_A_GAP`] quadratic pieces to stay within
    /// [`A_LINEAR_TOLERANCE`] of it. Where A's deviation from a chord
    /// across the widest gap (|A''|·L²/8) is within the tolerance, each gap
    /// is one straight span; elsewhere every gap is cut into as many equal
    /// quadratic pieces as bring the widest within it (the interpolating
    /// quadratic's error, at most |A'''|·L³/48), each through `A + c` at
    /// its first, middle and last pixels. The tests look at the whole row
    /// or the gap alone, and each piece is anchored at its gap's (or
    /// piece's) first pixel, so a pixel's position does not depend on which
    /// piece of the row is asked for.
    pub fn row_spans(&self, band: &BandGcm, y: u32, x0: u32, len: usize, spans: &mut Vec<Span>) -> bool {
        spans.clear();
        if self.spec.mode != CorrectionMode::Bilinear || len == 0 {
            return false;
        }
        let (j0, j1, fy) = self.rows_for(y);
        let ra = self.a.row(y as f64 + 0.5);
        let (da, db) = (ra.e * self.xs[0] + ra.f, ra.e * self.xs[self.nodes_x - 1] + ra.f);
        let d = da.min(db);
        if !(d > 0.0) {
            return false;
        }
        // The largest |A''| of either coordinate, at the smallest
        // denominator, and |A'''| = 3·|e|/d·|A''| there.
        let bend = 2.0 * ra.e.abs() * (ra.m * ra.f - ra.e * ra.n).abs().max((ra.p * ra.f - ra.e * ra.q).abs()) / (d * d * d);
        let twist = 3.0 * ra.e.abs() / d * bend;
        let straight = bend * self.max_gap * self.max_gap / 8.0 <= A_LINEAR_TOLERANCE;
        let cuts = if straight { 1.0 } else { (self.max_gap * (twist / (48.0 * A_LINEAR_TOLERANCE)).cbrt()).ceil().max(1.0) };
        if !(cuts <= MAX_SPANS_A_GAP as f64) {
            return false;
        }
        let cuts = cuts as usize;
        let (a, b) = (&band.rows[(j0 - band.first_j) as usize], &band.rows[(j1 - band.first_j) as usize]);
        let (lo, hi) = self.node_span(x0, len);
        // Node columns lo..=hi and the gaps lo..hi between them, cut out
        // once (no bounds checks per gap below).
        let nodes = lo..hi + 1;
        let (xs, first_px) = (&self.xs[nodes.clone()], &self.first_px[nodes.clone()]);
        let (adc, adr, bdc, bdr) = (&a.dc[nodes.clone()], &a.dr[nodes.clone()], &b.dc[nodes.clone()], &b.dr[nodes]);
        let (inv_dx, anchor_off) = (&self.inv_dx[lo..hi], &self.anchor_off[lo..hi]);
        // Refined cells (only with --max-error: then every gap has its entry).
        let refined = band.cells.get((j0 - band.first_j) as usize).map(|c| &c[lo..hi]);
        let x_end = x0 as usize + len;
        let last_gap = self.nodes_x - 2;
        let mut x = x0 as usize;
        // Node columns a block at a time: first the position at each (A
        // there plus the correction; the divisions of a block independent
        // of each other, two at a time), then the block's gaps.
        const BLOCK: usize = 32;
        let (mut pc, mut pr) = ([0.0f64; BLOCK + 1], [0.0f64; BLOCK + 1]);
        // A alone at the nodes, and A + c at the gaps' middles (quadratic spans only).
        let (mut acs, mut ars) = ([0.0f64; BLOCK + 1], [0.0f64; BLOCK + 1]);
        let (mut mc, mut mr) = ([0.0f64; BLOCK], [0.0f64; BLOCK]);
        let n_gaps = xs.len() - 1;
        // A refined cell's leaves along the row (reused from cell to cell).
        let mut leaf_runs = Vec::new();
        let mut g0 = 0;
        while g0 < n_gaps {
            // Nodes g0..=g0+m (the first one is the last of the block before).
            let m = (n_gaps - g0).min(BLOCK);
            let nodes = g0..g0 + m + 1;
            let (xs, adc, adr, bdc, bdr) = (&xs[nodes.clone()], &adc[nodes.clone()], &adr[nodes.clone()], &bdc[nodes.clone()], &bdr[nodes]);
            for (((&u, (&adc, &adr)), (&bdc, &bdr)), (oc, or)) in
                xs.iter().zip(adc.iter().zip(adr)).zip(bdc.iter().zip(bdr)).zip(pc.iter_mut().zip(pr.iter_mut()))
            {
                let (ac, ar) = ra.at(u);
                (*oc, *or) = (ac + adc + fy * (bdc - adc), ar + adr + fy * (bdr - adr));
            }
            if !straight && cuts == 1 {
                // A alone at the nodes (again: the loop above stays as the
                // straight rows, nearly all, want it).
                for ((&u, a_c), a_r) in xs.iter().zip(acs.iter_mut()).zip(ars.iter_mut()) {
                    (*a_c, *a_r) = ra.at(u);
                }
                // At each gap's middle: A there, and the mean of its nodes' corrections.
                for (k, (oc, or)) in mc.iter_mut().zip(mr.iter_mut()).enumerate().take(m) {
                    let (ac, ar) = ra.at(0.5 * (xs[k] + xs[k + 1]));
                    *oc = ac + 0.5 * ((pc[k] - acs[k]) + (pc[k + 1] - acs[k + 1]));
                    *or = ar + 0.5 * ((pr[k] - ars[k]) + (pr[k + 1] - ars[k + 1]));
                }
            }
            for k in 0..m {
                let g = g0 + k;
                let (left, right) = ((pc[k], pr[k]), (pc[k + 1], pr[k + 1]));
                // (max, min rather than clamp: no check that x ≤ x_end, which holds.)
                let end = if lo + g >= last_gap { x_end } else { first_px[g + 1].max(x).min(x_end) };
                // Within what the fixed point's conversion holds exactly
                // (positions ·2³² below 2⁵¹: a scan of 2¹⁸ pixels a side).
                const FIXED: f64 = (1u64 << 18) as f64;
                let leaves = refined.and_then(|q| q[g]);
                let fits = |c: f64, r: f64, d: [f64; 4]| c.abs() < FIXED && r.abs() < FIXED && d.iter().all(|d| d.abs() * 1024.0 < FIXED);
                let stepped = |c: f64, r: f64, d: [f64; 4]| leaves.is_none() && fits(c, r, d);
                if let (Some(q), true) = (leaves, end > x) {
                    // A refined cell: a span for each leaf's run of
                    // pixels along the row (A and the leaf's correction,
                    // linear along it, as one quadratic: a piece of a gap
                    // A fits within the tolerance across), anchored at the
                    // run's first pixel in the whole gap; a leaf marked
                    // exact, pixel by pixel.
                    let v = y as f64 + 0.5;
                    let (gap_first, gap_end) = (first_px[g], first_px[g + 1].max(end));
                    leaf_runs.clear();
                    quadtree::runs(&band.quads, q, self.cell_frame(j0, j1, lo + g), v, gap_first, gap_end, &mut leaf_runs);
                    for &(l0, l1, piece) in &leaf_runs {
                        let (first, stop) = (l0.max(x), l1.min(end));
                        if first >= stop {
                            continue;
                        }
                        let exact = Span { stepped: false, first, end: stop, anchor: l0, c: 0.0, r: 0.0, dc: 0.0, dr: 0.0, ddc: 0.0, ddr: 0.0 };
                        let leaf = match piece {
                            // Where A curves too much along the row for one
                            // quadratic a leaf, A + c at each pixel.
                            Piece::Leaf(_) if cuts > 1 => {
                                spans.push(exact);
                                continue;
                            }
                            Piece::Leaf(leaf) => leaf,
                            Piece::Rows => {
                                // Anchored at the run's first pixel, whatever piece of the row is asked for.
                                spans.push(match self.row_quadratic(v, l0, l1) {
                                    Some([c, r, dc, dr, ddc, ddr]) => Span { stepped: fits(c, r, [dc, dr, ddc, ddr]), c, r, dc, dr, ddc, ddr, ..exact },
                                    None => exact,
                                });
                                continue;
                            }
                            Piece::Exact => {
                                spans.push(exact);
                                continue;
                            }
                        };
                        let fv = leaf.fv(v);
                        let at = |px: usize| {
                            let u = px as f64 + 0.5;
                            let (ac, ar) = ra.at(u);
                            let [dc, dr] = leaf.at(u, fv);
                            (ac + dc, ar + dr)
                        };
                        let (c, r) = at(l0);
                        let ([dc, dr], [ddc, ddr]) = quadratic_steps((c, r), l0, l1, at);
                        spans.push(Span { stepped: fits(c, r, [dc, dr, ddc, ddr]), first, end: stop, anchor: l0, c, r, dc, dr, ddc, ddr });
                    }
                } else if end > x && straight {
                    let inv = inv_dx[g];
                    let (dc, dr) = ((right.0 - left.0) * inv, (right.1 - left.1) * inv);
                    let off = anchor_off[g];
                    let (c, r) = (left.0 + off * dc, left.1 + off * dr);
                    spans.push(Span { stepped: stepped(c, r, [dc, dr, 0.0, 0.0]), first: x, end, anchor: first_px[g], c, r, dc, dr, ddc: 0.0, ddr: 0.0 });
                } else if end > x && cuts == 1 {
                    // The quadratic through A + c at the gap's nodes and
                    // middle, s = u − u_left: f = fl + b·s + q·s²; stepped
                    // from the gap's first pixel (s = off).
                    let (half, off) = (0.5 / inv_dx[g], anchor_off[g]);
                    let steps = |fl: f64, fm: f64, fr: f64| {
                        let q = (fl - 2.0 * fm + fr) / (2.0 * half * half);
                        let b = (fm - fl) / half - q * half;
                        (fl + off * (b + q * off), b + q * (2.0 * off + 1.0), 2.0 * q)
                    };
                    let ((c, dc, ddc), (r, dr, ddr)) = (steps(left.0, mc[k], right.0), steps(left.1, mr[k], right.1));
                    spans.push(Span { stepped: stepped(c, r, [dc, dr, ddc, ddr]), first: x, end, anchor: first_px[g], c, r, dc, dr, ddc, ddr });
                } else if end > x {
                    // The gap's pixels (all of them, wherever the asked
                    // piece of the row begins and ends) in `cuts` pieces.
                    let (gap_first, gap_end) = (first_px[g], first_px[g + 1].max(end));
                    let n = gap_end - gap_first;
                    let (u0, inv) = (xs[k], inv_dx[g]);
                    // The correction at either node (linear in between).
                    let correction = |(c, r): (f64, f64), u: f64| {
                        let (ac, ar) = ra.at(u);
                        (c - ac, r - ar)
                    };
                    let (cl, cr) = (correction(left, u0), correction(right, xs[k + 1]));
                    let at = |px: usize| {
                        let u = px as f64 + 0.5;
                        let (ac, ar) = ra.at(u);
                        let t = (u - u0) * inv;
                        (ac + cl.0 + t * (cr.0 - cl.0), ar + cl.1 + t * (cr.1 - cl.1))
                    };
                    for i in 0..cuts {
                        let (p0, p1) = (gap_first + n * i / cuts, gap_first + n * (i + 1) / cuts);
                        let (first, stop) = (p0.max(x), p1.min(end));
                        if first >= stop {
                            continue;
                        }
                        let (c, r) = at(p0);
                        let ([dc, dr], [ddc, ddr]) = quadratic_steps((c, r), p0, p1, at);
                        spans.push(Span { stepped: stepped(c, r, [dc, dr, ddc, ddr]), first, end: stop, anchor: p0, c, r, dc, dr, ddc, ddr });
                    }
                }
                x = end;
            }
            g0 += m;
        }
        true
    }

    /// Fills output row `y` (columns `x0..x0+cols.len()`) with scan
    /// coordinates `A + c`, NaN where there is no value. Returns the number
    /// of pixels that fell back to `T`. Where the row is straight lines
    /// between node columns ([`Gcm::row_spans`]), two multiply-adds a
    /// pixel; elsewhere one reciprocal (for `A`) and a few multiply-adds.
    pub fn fill_row(&self, band: &BandGcm, y: u32, x0: u32, cols: &mut [f64], rows: &mut [f64], miss: &mut Option<(f64, f64, Lookup)>) -> u64 {
        let mut spans = Vec::new();
        if !self.row_spans(band, y, x0, cols.len(), &mut spans) {
            return self.fill_exact(band, y, x0, cols, rows, miss);
        }
        let mut fallback = 0;
        for s in &spans {
            let (a, b) = (s.first - x0 as usize, s.end - x0 as usize);
            if s.stepped {
                s.fill(&self.ramp, &mut cols[a..b], &mut rows[a..b]);
            } else {
                fallback += self.fill_exact(band, y, s.first as u32, &mut cols[a..b], &mut rows[a..b], miss);
            }
        }
        fallback
    }

    /// [`Gcm::fill_row`] without stepped spans: A itself at every pixel.
    pub fn fill_exact(&self, band: &BandGcm, y: u32, x0: u32, cols: &mut [f64], rows: &mut [f64], miss: &mut Option<(f64, f64, Lookup)>) -> u64 {
        self.fill_exact_at(band, y, y as f64 + 0.5, x0, cols, rows, miss)
    }

    /// [`Gcm::fill_exact`] at `v` within output row `y` (its top edge `y`,
    /// its bottom edge `y + 1`: an area kernel's footprints), from the node
    /// rows row `y` takes (carried on straight past them).
    #[allow(clippy::too_many_arguments)] // fill_exact's, and where in the row
    pub fn fill_exact_at(&self, band: &BandGcm, y: u32, v: f64, x0: u32, cols: &mut [f64], rows: &mut [f64], miss: &mut Option<(f64, f64, Lookup)>) -> u64 {
        let (j0, j1, fy) = self.rows_for(y);
        let a = &band.rows[(j0 - band.first_j) as usize];
        let b = &band.rows[(j1 - band.first_j) as usize];
        let fy = match self.spec.mode {
            CorrectionMode::Bilinear if v != y as f64 + 0.5 => {
                let (ya, yb) = (self.ys[(j0 - self.first_node) as usize], self.ys[(j1 - self.first_node) as usize]);
                (v - ya) / (yb - ya)
            }
            _ => fy,
        };
        let ra = self.a.row(v);
        let cells = band.cells.get((j0 - band.first_j) as usize);
        // The correction along this row at the node columns this segment
        // uses (indices relative to `lo`).
        let n = self.nodes_x;
        let (lo, hi_node) = self.node_span(x0, cols.len());
        let mut cc = Vec::with_capacity(hi_node - lo + 1);
        let mut cr = Vec::with_capacity(hi_node - lo + 1);
        for i in lo..=hi_node {
            cc.push(a.dc[i] + fy * (b.dc[i] - a.dc[i]));
            cr.push(a.dr[i] + fy * (b.dr[i] - a.dr[i]));
        }
        let k = self.spec.k as usize;
        let len = cols.len();
        let x_end = x0 as usize + len;
        // Pass 1, segment by segment (a cell, or the stretch between two
        // nodes): A plus the linearly varying correction. No branches inside,
        // so the compiler can vectorise it.
        let mut p = 0usize;
        // The gap between node columns that holds the current pixel.
        let mut gap = (self.segment(x0 as usize) - self.first_node) as usize;
        while p < len {
            let x = x0 as usize + p;
            let (i, seg_end, base) = match self.spec.mode {
                CorrectionMode::Cell => (x / k, ((x / k + 1) * k).min(x_end), 0.0),
                CorrectionMode::Bilinear => {
                    // Gaps only move right (skipping any no pixel centre falls in).
                    while gap + 2 < n && self.xs[gap + 1] <= x as f64 + 0.5 {
                        gap += 1;
                    }
                    let il = gap;
                    // First pixel of the next gap: its centre at or past the line.
                    let next = if il + 2 >= n { x_end } else { self.first_px[il + 1].clamp(x + 1, x_end) };
                    (il, next, self.xs[il])
                }
            };
            let il = i - lo;
            let refined = cells.and_then(|c| c.get(i)).is_some_and(|q| q.is_some());
            let (oc, or) = (&mut cols[p..seg_end - x0 as usize], &mut rows[p..seg_end - x0 as usize]);
            if refined {
                let q = cells.and_then(|c| c[i]).expect("refined cell");
                // The corrections leaf by leaf along the row, then A.
                quadtree::row(&band.quads, q, self.cell_frame(j0, j1, i), v, x, oc, or);
                for (m, (oc, or)) in oc.iter_mut().zip(or.iter_mut()).enumerate() {
                    let (ac, ar) = ra.at((x + m) as f64 + 0.5);
                    *oc += ac;
                    *or += ar;
                }
            } else {
                let (c0, r0) = (cc[il], cr[il]);
                let (sc, sr) = match self.spec.mode {
                    CorrectionMode::Cell => (0.0, 0.0),
                    CorrectionMode::Bilinear => (cc[il + 1] - c0, cr[il + 1] - r0),
                };
                let inv_w = match self.spec.mode {
                    CorrectionMode::Cell => 0.0,
                    CorrectionMode::Bilinear => self.inv_dx[i],
                };
                for (m, (oc, or)) in oc.iter_mut().zip(or.iter_mut()).enumerate() {
                    let u = (x + m) as f64 + 0.5;
                    let inv = 1.0 / (ra.e * u + ra.f);
                    let fx = (u - base) * inv_w;
                    *oc = (ra.m * u + ra.n) * inv + c0 + fx * sc;
                    *or = (ra.p * u + ra.q) * inv + r0 + fx * sr;
                }
            }
            p = seg_end - x0 as usize;
        }
        // Pass 2: where a node had no value, or the plane of A is behind the
        // camera (its denominator is linear in u: check the ends first),
        // fall back to T itself.
        let den = |x: usize| ra.e * (x as f64 + 0.5) + ra.f;
        let den_ok = den(x0 as usize) > 0.0 && den(x_end.saturating_sub(1)) > 0.0;
        let exact: Vec<usize> = (0..len).filter(|&m| cols[m].is_nan() || rows[m].is_nan() || (!den_ok && !(den(x0 as usize + m) > 0.0))).collect();
        self.t.exact_at(v, x0 as f64 + 0.5, &exact, cols, rows, miss);
        exact.len() as u64
    }

    /// The bilinear segment (absolute index of its left node) of column `x`.
    #[inline]
    fn segment(&self, x: usize) -> i64 {
        line_left_of(&self.xs, x as f64 + 0.5) as i64 + self.first_node
    }
}

/// Index `n` of the gap `[lines[n], lines[n+1])` holding `p`, clamped to
/// the first and last gaps.
#[inline]
fn line_left_of(lines: &[f64], p: f64) -> usize {
    lines.partition_point(|&l| l <= p).saturating_sub(1).min(lines.len() - 2)
}

/// Node lines `uniform` (spacing `k`) with the DEM's lines `a + b·i` that
/// fall between the first and last added, where the DEM is posted at least
/// `k` output pixels apart: then every cell between nodes lies inside one
/// DEM cell, where the bilinear DEM has no kink, and interpolating the
/// corrections bilinearly follows the terrain. A uniform line closer than
/// `k/4` to a DEM line gives way to it (no slivers).
fn with_dem_lines(uniform: Vec<f64>, a: f64, b: f64, k: f64) -> Vec<f64> {
    if !(b >= k && a.is_finite()) || uniform.len() < 2 {
        return uniform;
    }
    let (lo, hi) = (uniform[0], uniform[uniform.len() - 1]);
    let first = ((lo - a) / b).ceil() as i64;
    let last = ((hi - a) / b).floor() as i64;
    let dem: Vec<f64> = (first..=last).map(|i| a + b * i as f64).filter(|&l| l > lo && l < hi).collect();
    // DEM lines less than 1.5 k apart are node lines enough (the uniform
    // ones between would halve the gaps and double the spans to step).
    let only_dem = b < 1.5 * k;
    let near_dem = |u: f64| {
        let i = ((u - a) / b).round();
        only_dem || (u - (a + b * i)).abs() < k / 4.0
    };
    let mut lines: Vec<f64> = uniform.iter().enumerate().filter(|&(n, &u)| n == 0 || n == uniform.len() - 1 || !near_dem(u)).map(|(_, &u)| u).collect();
    lines.extend(dem);
    lines.sort_by(f64::total_cmp);
    lines.dedup();
    lines
}

/// Over `t`'s grid where it images the scan, with half again as margin:
/// the most scan pixels a metre of height moves the image (R), and the most
/// that rate changes a metre (|∂²T/∂Z²|), from projections at a 13×13
/// lattice of the grid at the DEM's mean height, ±50 m. Points that the
/// camera puts well outside the scan (an oblique frame's grid reaches far
/// beyond its footprint, where the lens polynomial runs wild) are left out:
/// nothing there is resampled. All count where the scan is not known or
/// none is inside.
fn relief_rates(t: &Transform<'_>) -> (f64, f64) {
    const N: usize = 13;
    let z = t.dem.mean_height().unwrap_or(0.0);
    let (w, h) = (t.grid.width as f64, t.grid.height as f64);
    let near_scan = |(c, r): (f64, f64)| t.scan.is_none_or(|(sw, sh)| c >= -0.1 * sw && r >= -0.1 * sh && c <= 1.1 * sw && r <= 1.1 * sh);
    let rates = |only_near: bool| {
        let (mut rate, mut bend, mut seen) = (0.0f64, 0.0f64, false);
        for i in 0..N {
            for j in 0..N {
                let (x, y) = t.ground(w * i as f64 / (N - 1) as f64, h * j as f64 / (N - 1) as f64);
                if let (Some(a), Some(b), Some(c)) = (t.model.project(x, y, z - 50.0), t.model.project(x, y, z), t.model.project(x, y, z + 50.0)) {
                    if only_near && !near_scan(b) {
                        continue;
                    }
                    seen = true;
                    rate = rate.max((c.0 - a.0).hypot(c.1 - a.1) / 100.0);
                    bend = bend.max((c.0 + a.0 - 2.0 * b.0).hypot(c.1 + a.1 - 2.0 * b.1) / 2500.0);
                }
            }
        }
        seen.then_some((1.5 * rate, 1.5 * bend))
    };
    rates(true).or_else(|| rates(false)).unwrap_or((0.0, 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadratic_steps_reproduce_a_quadratic_and_bound_a_fractional_linear_one() {
        // A quadratic in the pixel: its forward differences, exactly.
        let f = |p: usize| {
            let t = p as f64;
            (3.0 + 0.7 * t - 0.004 * t * t, -2.0 + 0.1 * t + 0.0125 * t * t)
        };
        for (p0, p1) in [(10, 27), (0, 3), (5, 6), (5, 7), (100, 112)] {
            let (d, dd) = quadratic_steps(f(p0), p0, p1, f);
            let span = Span { stepped: true, first: p0, end: p1, anchor: p0, c: f(p0).0, r: f(p0).1, dc: d[0], dr: d[1], ddc: dd[0], ddr: dd[1] };
            for p in p0..p1 {
                let (a, b) = (span.at(p), f(p));
                assert!((a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9, "{p0}..{p1} at {p}: {a:?} {b:?}");
            }
            let bounds = span.bounds();
            assert!((p0..p1).all(|p| {
                let (c, r) = f(p);
                c >= bounds[0] && r >= bounds[1] && c <= bounds[2] && r <= bounds[3]
            }));
        }
        // A fractional-linear A across 16 pixels: within |A'''|·L³/48.
        let (m, n, e, ff) = (0.93, 12.0, -2.0e-3, 1.4);
        let a = |p: usize| {
            let u = p as f64 + 0.5;
            ((m * u + n) / (e * u + ff), 0.0)
        };
        let (d, dd) = quadratic_steps(a(0), 0, 17, a);
        let span = Span { stepped: true, first: 0, end: 17, anchor: 0, c: a(0).0, r: 0.0, dc: d[0], dr: d[1], ddc: dd[0], ddr: dd[1] };
        let dmin = e * 16.5 + ff;
        let third = 6.0 * e * e * (m * ff - e * n).abs() / dmin.powi(4);
        let worst = (0..17).map(|p| (span.at(p).0 - a(p).0).abs()).fold(0.0, f64::max);
        assert!(worst > 0.0 && worst <= third * 16f64.powi(3) / 48.0, "{worst} {}", third * 16f64.powi(3) / 48.0);
    }

    #[test]
    fn dem_lines_less_than_one_and_a_half_spacings_apart_are_the_node_lines() {
        let uniform = |k: f64, n: usize| (0..n).map(|i| k * (i as f64 - 0.5)).collect::<Vec<_>>();
        // Posts 11.65 px apart, k = 11: the posts, and the outer lines that
        // hold every pixel between nodes.
        let lines = with_dem_lines(uniform(11.0, 12), 3.0, 11.65, 11.0);
        let (first, last) = (lines[0], lines[lines.len() - 1]);
        assert_eq!((first, last), (-5.5, 115.5));
        assert!(lines[1..lines.len() - 1].iter().all(|&u| ((u - 3.0) / 11.65 - ((u - 3.0) / 11.65).round()).abs() < 1e-9), "{lines:?}");
        assert_eq!(lines.len(), 2 + 10);
        // Posts 40 px apart, k = 16: uniform lines stay between them,
        // except those within k/4 of a post.
        let lines = with_dem_lines(uniform(16.0, 12), 3.0, 40.0, 16.0);
        assert!(lines.contains(&24.0) && lines.contains(&43.0) && !lines.contains(&40.0), "{lines:?}");
    }

    #[test]
    fn spans_are_cut_at_every_tile_edge_and_nowhere_else() {
        let span = |first, end, c| Span { stepped: true, first, end, anchor: first, c, r: 0.0, dc: 1.0, dr: 0.0, ddc: 0.0, ddr: 0.0 };
        // Spans of 13 to 171 pixels from column 100, tiles of 16 from 100.
        let bounds = [100, 113, 129, 300, 301, 333];
        let spans: Vec<Span> = bounds.windows(2).map(|w| span(w[0], w[1], w[0] as f64)).collect();
        let pieces: Vec<(usize, Span)> = Span::by_tile(&spans, 100, 16).collect();
        // The same cut worked out pixel by pixel: a new piece where the
        // tile or the span changes.
        let mut want: Vec<(usize, usize, usize, f64)> = Vec::new();
        for s in &spans {
            for x in s.first..s.end {
                let t = (x - 100) / 16;
                match want.last_mut() {
                    Some(p) if p.0 == t && p.2 == x && p.3 == s.c => p.2 = x + 1,
                    _ => want.push((t, x, x + 1, s.c)),
                }
            }
        }
        let got: Vec<(usize, usize, usize, f64)> = pieces.iter().map(|(t, p)| (*t, p.first, p.end, p.c)).collect();
        assert_eq!(got, want);
        // Each piece keeps its span's line.
        assert!(pieces.iter().all(|(_, p)| p.anchor == p.c as usize && p.dc == 1.0 && p.stepped));
        assert_eq!(Span::by_tile(&[], 0, 16).count(), 0);
    }
}
