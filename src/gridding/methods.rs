//! A block's cells from the points around them, by each method: linear in
//! each Delaunay triangle (the textbook's §9.10, eq. 9.34–9.35), natural
//! neighbour (Sibson), inverse distance (Shepard), the nearest point, and
//! the highest, lowest or mean point in each cell.

use super::neighbourhood::{delaunay_cell, fan_triangle, Buckets, Post, Settle, Tin};
use spade::{HasPosition, Point2, PositionInTriangulation, Triangulation};

/// The output cells of a block: `w`×`h` from column `i0`, row `j0` of a
/// grid of pixel size `gx`×`gy` whose origin is the local (0, 0).
#[derive(Clone, Copy, Debug)]
pub struct Cells {
    pub i0: u32,
    pub j0: u32,
    pub w: u32,
    pub h: u32,
    pub gx: f64,
    pub gy: f64,
}

impl Cells {
    /// Cell `(i, j)`'s centre (the block's own numbering), local.
    pub fn centre(&self, i: u32, j: u32) -> (f64, f64) {
        ((self.i0 + i) as f64 * self.gx + 0.5 * self.gx, -((self.j0 + j) as f64 * self.gy + 0.5 * self.gy))
    }
}

/// The three corners in one order whatever the order the triangulation
/// keeps them in, so that a cell's value does not depend on it.
fn sorted(mut v: [Post; 3]) -> [Post; 3] {
    v.sort_unstable_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    v
}

/// The height at `(x, y)` on the plane through `a, b, c`.
pub fn linear(x: f64, y: f64, [a, b, c]: [Post; 3]) -> f64 {
    let d = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    let wb = ((x - a.x) * (c.y - a.y) - (y - a.y) * (c.x - a.x)) / d;
    let wc = ((b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x)) / d;
    a.z + wb * (b.z - a.z) + wc * (c.z - a.z)
}

fn short(v: &[Post; 3], l2: f64) -> bool {
    let d2 = |p: &Post, q: &Post| (p.x - q.x) * (p.x - q.x) + (p.y - q.y) * (p.y - q.y);
    d2(&v[0], &v[1]) <= l2 && d2(&v[1], &v[2]) <= l2 && d2(&v[0], &v[2]) <= l2
}

fn pos(p: &Post) -> Point2<f64> {
    p.position()
}

/// Cells by the TIN (`natural`: by natural neighbours within it); a cell
/// whose triangle has a side over `max_edge` has none (NaN).
pub fn by_tin(tin: &Tin, settle: &mut Settle, cells: &Cells, max_edge: f64, natural: bool, out: &mut [f32]) {
    let l2 = max_edge * max_edge;
    let nn = natural.then(|| tin.natural_neighbor());
    let mut hint = None;
    let (mut cell, mut last) = (Vec::with_capacity(8), None);
    for j in 0..cells.h {
        for i in 0..cells.w {
            let (x, y) = cells.centre(i, j);
            let q = Point2::new(x, y);
            let at = match hint {
                Some(h) => tin.locate_with_hint(q, h),
                None => tin.locate(q),
            };
            // A cell's triangle is the fan's of its Delaunay cell (a lattice's
            // square cut one way whatever the triangulation drew), linear
            // on it; natural neighbours over the whole triangulation.
            let mut face_value = |settle: &mut Settle, f: spade::handles::FixedFaceHandle<spade::handles::InnerTag>| -> Option<f64> {
                // Cells in a row fall in one triangle by twos and threes.
                if last != Some(f) {
                    delaunay_cell(tin, f, &mut cell);
                    last = Some(f);
                }
                let v = sorted(fan_triangle(&cell, x, y)?);
                if !short(&v, l2) {
                    return None;
                }
                settle.check(pos(&cell[0]), pos(&cell[1]), pos(&cell[2]));
                match &nn {
                    Some(nn) => nn.interpolate(|v| v.data().z, q),
                    None => Some(linear(x, y, v)),
                }
            };
            let value = match at {
                PositionInTriangulation::OnVertex(v) => {
                    hint = Some(v);
                    Some(tin.vertex(v).data().z)
                }
                PositionInTriangulation::OnFace(f) => {
                    let face = tin.face(f);
                    let vs = face.vertices();
                    hint = Some(vs[0].fix());
                    if nn.is_some() {
                        // Natural neighbours reach the triangles around the
                        // corners: those must be the whole set's too.
                        for v in vs {
                            for e in v.out_edges() {
                                if let Some(f) = e.face().as_inner() {
                                    let [a, b, c] = f.vertices().map(|v| v.position());
                                    settle.check(a, b, c);
                                }
                            }
                        }
                    }
                    face_value(settle, f)
                }
                PositionInTriangulation::OnEdge(e) => {
                    let edge = tin.directed_edge(e);
                    hint = Some(edge.from().fix());
                    // Either side's triangle gives the edge's line; the
                    // first whose sides are short enough.
                    [edge, edge.rev()].into_iter().find_map(|e| e.face().as_inner().and_then(|f| face_value(settle, f.fix())))
                }
                PositionInTriangulation::OutsideOfConvexHull(_) | PositionInTriangulation::NoTriangulation => None,
            };
            out[(j * cells.w + i) as usize] = value.map_or(f32::NAN, |v| v as f32);
        }
    }
}

/// Which points a cell takes by distance, and how.
pub struct Distance {
    pub radius: f64,
    pub power: f64,
    /// At most this many nearest.
    pub neighbours: Option<usize>,
    /// The nearest point's height alone.
    pub nearest: bool,
}

/// Cells by inverse distance to the power `power` over the points within
/// `radius` (the `neighbours` nearest of them where given); `nearest`: the
/// nearest point's height.
pub fn by_distance(buckets: &Buckets, posts: &[Post], cells: &Cells, by: &Distance, out: &mut [f32]) {
    let Distance { radius, power, neighbours, nearest } = *by;
    let mut near = Vec::new();
    for j in 0..cells.h {
        for i in 0..cells.w {
            let (x, y) = cells.centre(i, j);
            buckets.within(x, y, radius, &mut near);
            let value = if near.is_empty() {
                f64::NAN
            } else if nearest || near[0].0 == 0.0 {
                posts[near[0].1 as usize].z
            } else {
                let take = neighbours.unwrap_or(usize::MAX).min(near.len());
                let (mut num, mut den) = (0.0, 0.0);
                for &(d2, k) in &near[..take] {
                    let w = 1.0 / d2.powf(0.5 * power);
                    num += w * posts[k as usize].z;
                    den += w;
                }
                num / den
            };
            out[(j * cells.w + i) as usize] = value as f32;
        }
    }
}

/// What each cell takes of the points inside it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CellStat {
    Max,
    Min,
    Mean,
}

/// Cells by the points inside each (a cell without one has none).
pub fn by_cell(posts: &[Post], cells: &Cells, stat: CellStat, out: &mut [f32]) {
    let n = (cells.w * cells.h) as usize;
    let mut acc = vec![(0.0f64, 0u32); n];
    for p in posts {
        let i = (p.x / cells.gx).floor() - cells.i0 as f64;
        let j = (-p.y / cells.gy).floor() - cells.j0 as f64;
        if !(i >= 0.0 && j >= 0.0 && i < cells.w as f64 && j < cells.h as f64) {
            continue;
        }
        let a = &mut acc[j as usize * cells.w as usize + i as usize];
        a.0 = match (stat, a.1) {
            (_, 0) => p.z,
            (CellStat::Max, _) => a.0.max(p.z),
            (CellStat::Min, _) => a.0.min(p.z),
            (CellStat::Mean, _) => a.0 + p.z,
        };
        a.1 += 1;
    }
    for (o, (v, k)) in out.iter_mut().zip(acc) {
        *o = match (k, stat) {
            (0, _) => f32::NAN,
            (_, CellStat::Mean) => (v / k as f64) as f32,
            _ => v as f32,
        };
    }
}
