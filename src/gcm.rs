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
//! the bound at every pixel (`error_bound.rs`); a cell's rows become spans
//! of scan positions in `row_spans.rs`.
//!
//! Everything is computed a band of rows at a time (`prepare`), so a caller
//! never holds the whole matrix.

mod error_bound;
mod quadtree;
mod row_spans;
pub mod self_check;

use crate::dem::{Height, Lookup};
use crate::transform::{Approx, Mapped, Transform};
use quadtree::{Frame, Node};

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CorrectionMode {
    Cell,
    Bilinear,
}

/// What the caller chose: sparsity, mode, optional error bound (source px).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
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
    /// Each node's longitude and latitude (NaN where it has none).
    pub lonlat: Option<Vec<(f64, f64)>>,
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
    /// `quads`; a row with no refined cell is empty (most are: a strip's
    /// rows of entries held megabytes of None).
    cells: Vec<Vec<Option<u32>>>,
    quads: Vec<Node>,
    pub stats: GcmStats,
    /// The first DEM miss met under the `error` policy.
    pub miss: Option<(f64, f64, Lookup)>,
    /// Under `--occlusion`: which of the band's pixels the sensor sees.
    pub seen: Option<std::sync::Arc<crate::transform::visibility::Seen>>,
}

impl BandGcm {
    /// What the band holds on the heap (node rows, cells, refined cells),
    /// bytes: the pipeline counts the bands in flight by it.
    pub fn heap_bytes(&self) -> u64 {
        let row = |r: &NodeRow| (r.dc.capacity() + r.dr.capacity() + r.z.capacity()) * 8 + (r.tz.capacity() + r.dp.capacity()) * 16;
        let rows: usize = self.rows.iter().map(row).sum::<usize>() + self.rows.capacity() * std::mem::size_of::<NodeRow>();
        let cells: usize = self.cells.iter().map(|c| c.capacity() * std::mem::size_of::<Option<u32>>()).sum();
        (rows + cells + self.quads.capacity() * std::mem::size_of::<Node>()) as u64
    }
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
                    let (h, ll) = self.t.dem.height_and_lonlat(x, y);
                    (h, ll.unwrap_or((f64::NAN, f64::NAN)))
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
                let (lon, lat): (Vec<f64>, Vec<f64>) = at.iter().map(|&i| lonlat[i]).unzip();
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
                    let (lon, lat): (Vec<f64>, Vec<f64>) = at.iter().map(|&i| lonlat[i]).unzip();
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
        let dp = match (&nodes.lonlat, self.spec.max_error.is_some() && self.dem_sampling.is_some()) {
            (_, false) => Vec::new(),
            // The DEM's own coordinates of each node, converted once for
            // its height (one transverse Mercator inverse a node, not two).
            (Some(lonlat), true) => lonlat
                .iter()
                .map(|&(lon, lat)| if lon.is_nan() { None } else { self.t.dem.sample_coords_of_grid_point(lon, lat) }.map_or([f64::NAN; 2], |(c, r)| [c, r]))
                .collect(),
            (None, true) => self.xs.iter().map(|&u| self.dem_coords(u, v)).collect(),
        };
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
                    .collect::<Vec<_>>();
                cells.push(if row_cells.iter().all(Option::is_none) { Vec::new() } else { row_cells });
            }
        }
        // Held while the band's rows are made: not twice what it needs.
        quads.shrink_to_fit();
        BandGcm { first_j, rows, cells, quads, stats, miss, seen: None }
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
    use crate::geom::Span;

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
