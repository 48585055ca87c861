//! A block's points with those around it, and what is true of the whole
//! point set there. A Delaunay triangle found among the points loaded is
//! the whole set's when its circumcircle holds no point that was left
//! unloaded ([`Settle`]): the circle's bins are all loaded or empty, or
//! lie outside the points kept. Where one is not, the neighbourhood grows
//! and the block is done again, so that a block's cells do not depend on
//! where the blocks fall (nor on the tile size).

use super::bins::{Bins, Rect, Stored};
use crate::error::Result;
use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

/// A triangulation's vertex: a point (local coordinates) and its height.
#[derive(Clone, Copy, Debug)]
pub struct Post {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

impl HasPosition for Post {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        Point2::new(self.x, self.y)
    }
}

pub type Tin = DelaunayTriangulation<Post>;

/// The points within a region of the ground (`[x0, y0, x1, y1]`, edges
/// included), in one order whatever the order they were read in, points at
/// one place merged (their mean height).
pub struct Loaded {
    pub posts: Vec<Post>,
}

/// Whether `(x, y)` lies in `r` (edges included).
fn holds(r: &[f64; 4], x: f64, y: f64) -> bool {
    x >= r[0] && x <= r[2] && y >= r[1] && y <= r[3]
}

impl Loaded {
    pub fn read(bins: &Bins, region: [f64; 4]) -> Result<Loaded> {
        let mut raw: Vec<Stored> = Vec::new();
        if let Some(rect) = bins.grid.bins_over(region[0], region[1], region[2], region[3]) {
            // Filtered as read: the bins around hold several times the
            // points kept.
            bins.read(rect, |p| holds(&region, p[0], p[1]), &mut raw)?;
        }
        Ok(Loaded { posts: merged(raw) })
    }

    /// The Delaunay triangulation of the posts (`None` where they are fewer
    /// than three or all on one line: no triangle).
    pub fn tin(&self) -> Option<Tin> {
        let tin = Tin::bulk_load(self.posts.clone()).ok()?;
        (tin.num_inner_faces() > 0).then_some(tin)
    }
}

/// Points sorted by place, then height; those at one place made one, at
/// their mean height (summed in order of height: the same whatever the
/// order read).
pub fn merged(mut raw: Vec<Stored>) -> Vec<Post> {
    raw.sort_unstable_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])).then(a[2].total_cmp(&b[2])));
    let mut posts = Vec::with_capacity(raw.len());
    let mut i = 0;
    while i < raw.len() {
        let mut j = i + 1;
        while j < raw.len() && raw[j][0] == raw[i][0] && raw[j][1] == raw[i][1] {
            j += 1;
        }
        let z = if j == i + 1 { raw[i][2] } else { raw[i..j].iter().map(|p| p[2]).sum::<f64>() / (j - i) as f64 };
        posts.push(Post { x: raw[i][0], y: raw[i][1], z });
        i = j;
    }
    posts
}

/// The circumcircle of a triangle: centre and radius (infinite for three
/// points on a line).
pub fn circumcircle(a: Point2<f64>, b: Point2<f64>, c: Point2<f64>) -> (f64, f64, f64) {
    let (bx, by) = (b.x - a.x, b.y - a.y);
    let (cx, cy) = (c.x - a.x, c.y - a.y);
    let d = 2.0 * (bx * cy - by * cx);
    let (b2, c2) = (bx * bx + by * by, cx * cx + cy * cy);
    let ux = (cy * b2 - by * c2) / d;
    let uy = (bx * c2 - cx * b2) / d;
    let r = (ux * ux + uy * uy).sqrt();
    (a.x + ux, a.y + uy, if r.is_finite() { r } else { f64::INFINITY })
}

/// Which triangles used are the whole set's, and the ground that would
/// settle those that may not be.
pub struct Settle<'a> {
    bins: &'a Bins,
    region: [f64; 4],
    /// Ground to load as well.
    pub need: Option<[f64; 4]>,
    /// Triangles used whose circle reaches too far to load.
    pub unsettled: u64,
}

/// The most bins one circle may call for: past that the triangle is taken
/// as it is (a sliver along the data's edge) and counted.
const MAX_CIRCLE_BINS: u64 = 1 << 12;

impl<'a> Settle<'a> {
    pub fn new(bins: &'a Bins, region: [f64; 4]) -> Settle<'a> {
        Settle { bins, region, need: None, unsettled: 0 }
    }

    /// Whether the triangle `a, b, c` is the whole point set's; where it
    /// may not be, the ground that would tell is noted in `need`.
    pub fn check(&mut self, a: Point2<f64>, b: Point2<f64>, c: Point2<f64>) -> bool {
        let (cx, cy, r) = circumcircle(a, b, c);
        let g = self.region;
        let bbox = [cx - r, cy - r, cx + r, cy + r];
        if bbox[0] >= g[0] && bbox[2] <= g[2] && bbox[1] >= g[1] && bbox[3] <= g[3] {
            return true;
        }
        if !r.is_finite() {
            self.unsettled += 1;
            return false;
        }
        // A circle outside every bin holds no point kept.
        let Some(over) = self.bins.grid.bins_over(bbox[0], bbox[1], bbox[2], bbox[3]) else { return true };
        if over.bins() > MAX_CIRCLE_BINS {
            self.unsettled += 1;
            return false;
        }
        // Settled where every bin it meets is empty or was read whole.
        let grid = &self.bins.grid;
        let whole = |c: u32, r: u32| {
            let b = grid.ground_of(Rect { c0: c, r0: r, c1: c, r1: r });
            b[0] >= g[0] && b[2] <= g[2] && b[1] >= g[1] && b[3] <= g[3]
        };
        let settled = (over.r0..=over.r1).all(|r| (over.c0..=over.c1).all(|c| self.bins.count(c, r) == 0 || whole(c, r)));
        if !settled {
            self.need = Some(match self.need {
                None => bbox,
                Some(n) => [n[0].min(bbox[0]), n[1].min(bbox[1]), n[2].max(bbox[2]), n[3].max(bbox[3])],
            });
        }
        settled
    }
}

/// Posts by place, for the neighbours within a radius of a point.
pub struct Buckets<'a> {
    posts: &'a [Post],
    x0: f64,
    y0: f64,
    side: f64,
    cols: usize,
    rows: usize,
    /// Each bucket's first post in `order`, and one past the last bucket's.
    starts: Vec<u32>,
    order: Vec<u32>,
}

impl<'a> Buckets<'a> {
    pub fn new(posts: &'a [Post], side: f64) -> Buckets<'a> {
        let (mut x0, mut y0, mut x1, mut y1) = (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
        for p in posts {
            x0 = x0.min(p.x);
            y0 = y0.min(p.y);
            x1 = x1.max(p.x);
            y1 = y1.max(p.y);
        }
        if posts.is_empty() {
            return Buckets { posts, x0: 0.0, y0: 0.0, side: 1.0, cols: 1, rows: 1, starts: vec![0, 0], order: Vec::new() };
        }
        // No more buckets than a few a post.
        let mut side = side.max(f64::MIN_POSITIVE);
        while ((x1 - x0) / side + 1.0) * ((y1 - y0) / side + 1.0) > 4.0 * posts.len() as f64 + 16.0 {
            side *= 2.0;
        }
        let cols = ((x1 - x0) / side) as usize + 1;
        let rows = ((y1 - y0) / side) as usize + 1;
        let key = |p: &Post| ((p.y - y0) / side) as usize * cols + ((p.x - x0) / side) as usize;
        let mut starts = vec![0u32; cols * rows + 1];
        for p in posts {
            starts[key(p) + 1] += 1;
        }
        for i in 1..starts.len() {
            starts[i] += starts[i - 1];
        }
        let mut fill = starts.clone();
        let mut order = vec![0u32; posts.len()];
        for (i, p) in posts.iter().enumerate() {
            let k = key(p);
            order[fill[k] as usize] = i as u32;
            fill[k] += 1;
        }
        Buckets { posts, x0, y0, side, cols, rows, starts, order }
    }

    /// The posts within `radius` of `(x, y)`, each with its squared
    /// distance, nearest first (ties by place: one order wherever the
    /// posts were loaded from).
    pub fn within(&self, x: f64, y: f64, radius: f64, out: &mut Vec<(f64, u32)>) {
        out.clear();
        if self.order.is_empty() {
            return;
        }
        let span = |v: f64, o: f64, n: usize| {
            let a = ((v - radius - o) / self.side).floor().max(0.0) as usize;
            let b = ((v + radius - o) / self.side).floor();
            (a, if b < 0.0 { None } else { Some((b as usize).min(n - 1)) })
        };
        let (c0, c1) = span(x, self.x0, self.cols);
        let (r0, r1) = span(y, self.y0, self.rows);
        let (Some(c1), Some(r1)) = (c1, r1) else { return };
        let r2 = radius * radius;
        for r in r0..=r1 {
            if c0 > c1 {
                break;
            }
            let (a, b) = (self.starts[r * self.cols + c0] as usize, self.starts[r * self.cols + c1 + 1] as usize);
            for &i in &self.order[a..b] {
                let p = &self.posts[i as usize];
                let d2 = (p.x - x) * (p.x - x) + (p.y - y) * (p.y - y);
                if d2 <= r2 {
                    out.push((d2, i));
                }
            }
        }
        // Posts are sorted by place, so their index orders ties by place.
        out.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    }
}

fn coord(p: &Post) -> robust::Coord<f64> {
    robust::Coord { x: p.x, y: p.y }
}

/// Whether `d` lies exactly on the circle through `a, b, c`: the
/// determinant in floating point where it is clearly not zero, else
/// exactly (Shewchuk's adaptive predicate).
fn cocircular(a: &Post, b: &Post, c: &Post, d: &Post) -> bool {
    let (adx, ady, bdx, bdy, cdx, cdy) = (a.x - d.x, a.y - d.y, b.x - d.x, b.y - d.y, c.x - d.x, c.y - d.y);
    let (alift, blift, clift) = (adx * adx + ady * ady, bdx * bdx + bdy * bdy, cdx * cdx + cdy * cdy);
    let det = alift * (bdx * cdy - cdx * bdy) + blift * (cdx * ady - adx * cdy) + clift * (adx * bdy - bdx * ady);
    let permanent =
        alift * ((bdx * cdy).abs() + (cdx * bdy).abs()) + blift * ((cdx * ady).abs() + (adx * cdy).abs()) + clift * ((adx * bdy).abs() + (bdx * ady).abs());
    // Far above the predicate's own error bound (about 1.1e-15).
    if det.abs() > 1e-12 * permanent {
        return false;
    }
    robust::incircle(coord(a), coord(b), coord(c), coord(d)) == 0.0
}

/// For each face of `tin` (by index), whether a neighbour's far corner
/// lies exactly on its circumcircle: its Delaunay cell is more than
/// itself. One test an edge (four points on one circle are so whichever
/// three make it).
pub fn joined_faces(tin: &Tin) -> Vec<bool> {
    let mut joined = vec![false; tin.num_all_faces()];
    for e in tin.undirected_edges() {
        let e = e.as_directed();
        let (Some(f), Some(g)) = (e.face().as_inner(), e.rev().face().as_inner()) else { continue };
        let [a, b, c] = f.vertices().map(|v| *v.data());
        let Some(o) = e.rev().opposite_vertex() else { continue };
        if cocircular(&a, &b, &c, o.data()) {
            joined[f.fix().index()] = true;
            joined[g.fix().index()] = true;
        }
    }
    joined
}

/// The Delaunay cell holding face `f`: the faces whose corners lie exactly
/// on its circumcircle with it (a regular lattice's squares), as the
/// corners of that polygon in one order whatever diagonals the
/// triangulation happened to draw: counter-clockwise from the least corner
/// (by x, then y), into `out`. Three corners where the face is alone.
pub fn delaunay_cell(tin: &Tin, f: spade::handles::FixedFaceHandle<spade::handles::InnerTag>, out: &mut Vec<Post>) {
    let face = tin.face(f);
    let [a, b, c] = face.vertices().map(|v| *v.data());
    out.clear();
    out.extend([a, b, c]);
    // Most faces are alone: their neighbours' far corners lie outside.
    let cocircular = |e: spade::handles::DirectedEdgeHandle<Post, (), (), ()>| {
        let g = e.rev().face().as_inner()?.fix();
        let o = *e.rev().opposite_vertex()?.data();
        cocircular(&a, &b, &c, &o).then_some((g, o))
    };
    if face.adjacent_edges().into_iter().any(|e| cocircular(e).is_some()) {
        let mut faces = vec![f];
        let mut k = 0;
        while k < faces.len() {
            for e in tin.face(faces[k]).adjacent_edges() {
                if let Some((g, o)) = cocircular(e) {
                    if !faces.contains(&g) {
                        faces.push(g);
                        if !out.iter().any(|q| q.x == o.x && q.y == o.y) {
                            out.push(o);
                        }
                    }
                }
            }
            k += 1;
        }
    }
    out.sort_unstable_by(|p, q| p.x.total_cmp(&q.x).then(p.y.total_cmp(&q.y)));
    let first = out[0];
    if out.len() > 3 {
        // Round a convex polygon from one of its corners, the angle is
        // told exactly by the side each corner lies on of another.
        out[1..].sort_unstable_by(|p, q| 0.0_f64.total_cmp(&robust::orient2d(coord(&first), coord(p), coord(q))));
    } else if robust::orient2d(coord(&first), coord(&out[1]), coord(&out[2])) < 0.0 {
        out.swap(1, 2);
    }
}

/// The triangle of the fan from `cell[0]` that holds `(x, y)` (the first,
/// on a side two share), if any.
pub fn fan_triangle(cell: &[Post], x: f64, y: f64) -> Option<[Post; 3]> {
    let q = robust::Coord { x, y };
    let v0 = cell[0];
    (1..cell.len() - 1).map(|i| [v0, cell[i], cell[i + 1]]).find(|[a, b, c]| {
        robust::orient2d(coord(a), coord(b), q) >= 0.0 && robust::orient2d(coord(b), coord(c), q) >= 0.0 && robust::orient2d(coord(c), coord(a), q) >= 0.0
    })
}
