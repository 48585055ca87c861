//! A block's points with those around it, and what is true of the whole
//! point set there. A Delaunay triangle found among the points loaded is
//! the whole set's when its circumcircle holds no point that was left
//! unloaded ([`Settle`]): the circle's bins are all loaded or empty, or
//! lie outside the points kept. Where one is not, the neighbourhood grows
//! and the block is done again, so that a block's cells do not depend on
//! where the blocks fall (nor on the tile size).

use super::bins::{BinGrid, Bins, Rect, Stored};
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

/// The points of the bins in `rect`, in one order whatever the order they
/// were read in, points at one place merged (their mean height).
pub struct Loaded {
    pub rect: Rect,
    pub posts: Vec<Post>,
}

impl Loaded {
    pub fn read(bins: &Bins, rect: Rect) -> Result<Loaded> {
        let mut raw: Vec<Stored> = Vec::new();
        bins.read(rect, &mut raw)?;
        Ok(Loaded { rect, posts: merged(raw) })
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

/// Which triangles used are the whole set's, and the bins that would
/// settle those that may not be.
pub struct Settle<'a> {
    bins: &'a Bins,
    rect: Rect,
    ground: [f64; 4],
    /// Bins to load as well.
    pub need: Option<Rect>,
    /// Triangles used whose circle reaches too far to load.
    pub unsettled: u64,
}

/// The most bins one circle may call for: past that the triangle is taken
/// as it is (a sliver along the data's edge) and counted.
const MAX_CIRCLE_BINS: u64 = 1 << 12;

impl<'a> Settle<'a> {
    pub fn new(bins: &'a Bins, rect: Rect) -> Settle<'a> {
        Settle { bins, rect, ground: bins.grid.ground_of(rect), need: None, unsettled: 0 }
    }

    pub fn grid(&self) -> &BinGrid {
        &self.bins.grid
    }

    /// Whether the triangle `a, b, c` is the whole point set's; where it
    /// may not be, the bins that would tell are noted in `need`.
    pub fn check(&mut self, a: Point2<f64>, b: Point2<f64>, c: Point2<f64>) -> bool {
        let (cx, cy, r) = circumcircle(a, b, c);
        let g = self.ground;
        if cx - r >= g[0] && cx + r <= g[2] && cy - r >= g[1] && cy + r <= g[3] {
            return true;
        }
        if !r.is_finite() {
            self.unsettled += 1;
            return false;
        }
        // A circle outside every bin holds no point kept.
        let Some(over) = self.bins.grid.bins_over(cx - r, cy - r, cx + r, cy + r) else { return true };
        if self.rect.contains(&over) {
            return true;
        }
        if over.bins() > MAX_CIRCLE_BINS {
            self.unsettled += 1;
            return false;
        }
        let empty = (over.r0..=over.r1).all(|r| (over.c0..=over.c1).all(|c| self.rect.holds(c, r) || self.bins.count(c, r) == 0));
        if !empty {
            self.need = Some(self.need.map_or(over, |n| n.union(over)));
        }
        empty
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

/// The Delaunay cell holding face `f`: the faces whose corners lie exactly
/// on its circumcircle with it (a regular lattice's squares), as the
/// corners of that polygon in one order whatever diagonals the
/// triangulation happened to draw: counter-clockwise from the least corner
/// (by x, then y). Three corners where the face is alone.
pub fn delaunay_cell(tin: &Tin, f: spade::handles::FixedFaceHandle<spade::handles::InnerTag>) -> Vec<Post> {
    let face = tin.face(f);
    let [a, b, c] = face.vertices().map(|v| *v.data());
    let (ca, cb, cc) = (coord(&a), coord(&b), coord(&c));
    let mut faces = vec![f];
    let mut corners = face.vertices().map(|v| v.fix()).to_vec();
    let mut k = 0;
    while k < faces.len() {
        for e in tin.face(faces[k]).adjacent_edges() {
            let Some(other) = e.rev().face().as_inner() else { continue };
            if faces.contains(&other.fix()) {
                continue;
            }
            let Some(o) = e.rev().opposite_vertex() else { continue };
            if robust::incircle(ca, cb, cc, coord(o.data())) == 0.0 {
                faces.push(other.fix());
                if !corners.contains(&o.fix()) {
                    corners.push(o.fix());
                }
            }
        }
        k += 1;
    }
    let mut posts: Vec<Post> = corners.iter().map(|&v| *tin.vertex(v).data()).collect();
    posts.sort_unstable_by(|p, q| p.x.total_cmp(&q.x).then(p.y.total_cmp(&q.y)));
    if posts.len() > 3 {
        let first = posts[0];
        // Round a convex polygon from one of its corners, the angle is
        // told exactly by the side each corner lies on of another.
        posts[1..].sort_unstable_by(|p, q| 0.0_f64.total_cmp(&robust::orient2d(coord(&first), coord(p), coord(q))));
    } else {
        let first = posts[0];
        if robust::orient2d(coord(&first), coord(&posts[1]), coord(&posts[2])) < 0.0 {
            posts.swap(1, 2);
        }
    }
    posts
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
