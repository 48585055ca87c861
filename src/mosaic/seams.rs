//! Seamlines: each stretch of the first partition's boundary between two
//! images is moved, within a corridor of the overlap around it, onto the
//! least-cost path between its two ends (Dijkstra on the cells). A cell
//! costs more where the two images (balanced) differ and much more on a
//! height edge of the DSM, so that cuts run along streets and open ground,
//! not through buildings and trees. The cells between the old and the new
//! boundary then change sides.

use super::balance::Correction;
use super::plan::{Plan, NONE};
use crate::error::Result;
use rustc_hash::{FxHashMap as HashMap, FxHashSet as HashSet};
use std::collections::VecDeque;

/// Cost of a cell where the two images differ by their mean difference.
const DIFFERENCE: f64 = 2.0;
/// Cost of a cell on a height edge.
const HEIGHT_EDGE: f64 = 50.0;
/// Costs are whole numbers for the search: this many a unit.
const RESOLUTION: f64 = 1000.0;

/// What the refinement did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SeamStats {
    /// Stretches of boundary between two images, and those moved.
    pub stretches: usize,
    pub refined: usize,
    /// Cells that changed image.
    pub cells_moved: usize,
}

/// Whether each cell is on a height edge: a step to a neighbour steeper
/// than a 45° slope and more than a metre and a half.
pub fn height_edges(plan: &Plan) -> Vec<bool> {
    let (cw, ch) = (plan.cw, plan.ch);
    let limit = 1.5f64.max(plan.cell_metres());
    let mut edge = vec![false; cw * ch];
    for y in 0..ch {
        for x in 0..cw {
            let z = plan.heights[y * cw + x];
            if z.is_nan() {
                continue;
            }
            edge[y * cw + x] = neighbours8(x, y, cw, ch).any(|(a, b)| {
                let n = plan.heights[b * cw + a];
                !n.is_nan() && ((n - z).abs() as f64) > limit
            });
        }
    }
    edge
}

fn neighbours8(x: usize, y: usize, cw: usize, ch: usize) -> impl Iterator<Item = (usize, usize)> {
    let (x, y) = (x as i64, y as i64);
    (-1..=1i64)
        .flat_map(move |dy| (-1..=1i64).map(move |dx| (x + dx, y + dy)))
        .filter(move |&(a, b)| (a, b) != (x, y) && a >= 0 && b >= 0 && a < cw as i64 && b < ch as i64)
        .map(|(a, b)| (a as usize, b as usize))
}

fn neighbours4(x: usize, y: usize, cw: usize, ch: usize) -> impl Iterator<Item = (usize, usize)> {
    neighbours8(x, y, cw, ch).filter(move |&(a, b)| a == x || b == y)
}

/// Moves every stretch of boundary onto its least-cost path (see the
/// module doc); `corridor` is the half-width searched, in cells.
pub fn refine(plan: &mut Plan, corr: &[Correction], corridor: usize, edges: &[bool]) -> Result<SeamStats> {
    let (cw, ch) = (plan.cw, plan.ch);
    let mut stats = SeamStats::default();
    // The pairs that share a boundary, from the first partition.
    let mut pairs = std::collections::BTreeSet::new();
    for y in 0..ch {
        for x in 0..cw {
            let l = plan.label_at(x, y);
            if l == NONE {
                continue;
            }
            for (a, b) in neighbours4(x, y, cw, ch) {
                let m = plan.label_at(a, b);
                if m != NONE && m != l {
                    pairs.insert((l.min(m), l.max(m)));
                }
            }
        }
    }
    for (i, j) in pairs {
        for stretch in stretches(plan, i, j) {
            stats.stretches += 1;
            if let Some(moved) = refine_stretch(plan, corr, corridor, edges, (i, j), &stretch)? {
                stats.refined += 1;
                stats.cells_moved += moved;
            }
        }
    }
    Ok(stats)
}

/// The boundary cells between images `i` and `j` (either side), in
/// 8-connected stretches.
fn stretches(plan: &Plan, i: u16, j: u16) -> Vec<Vec<usize>> {
    let (cw, ch) = (plan.cw, plan.ch);
    let on = |x: usize, y: usize| {
        let l = plan.label_at(x, y);
        let other = if l == i {
            j
        } else if l == j {
            i
        } else {
            return false;
        };
        neighbours4(x, y, cw, ch).any(|(a, b)| plan.label_at(a, b) == other)
    };
    // A cell labelled i with a neighbour labelled j lies in i's box and
    // next to j's (and the other way round): only where the boxes meet,
    // a cell around, is looked at.
    let (bi, bj) = (plan.images[i as usize].cells, plan.images[j as usize].cells);
    let (x0, y0) = (bi[0].max(bj[0]).saturating_sub(1), bi[1].max(bj[1]).saturating_sub(1));
    let (x1, y1) = ((bi[2].min(bj[2]) + 1).min(cw), (bi[3].min(bj[3]) + 1).min(ch));
    let cells: HashSet<usize> = (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))).filter(|&(x, y)| on(x, y)).map(|(x, y)| y * cw + x).collect();
    let mut seen = HashSet::default();
    let mut out = Vec::new();
    let mut sorted: Vec<usize> = cells.iter().copied().collect();
    sorted.sort_unstable();
    for &start in &sorted {
        if !seen.insert(start) {
            continue;
        }
        let mut comp = vec![start];
        let mut queue = VecDeque::from([start]);
        while let Some(k) = queue.pop_front() {
            for (a, b) in neighbours8(k % cw, k / cw, cw, ch) {
                let n = b * cw + a;
                if cells.contains(&n) && seen.insert(n) {
                    comp.push(n);
                    queue.push_back(n);
                }
            }
        }
        out.push(comp);
    }
    out
}

/// Breadth-first distances (8-connected steps) from `from` over the cells
/// `inside` admits, up to `limit`.
fn reach(cw: usize, ch: usize, from: &[usize], limit: usize, inside: impl Fn(usize) -> bool) -> HashMap<usize, usize> {
    let mut dist: HashMap<usize, usize> = from.iter().map(|&k| (k, 0)).collect();
    let mut queue: VecDeque<usize> = from.iter().copied().collect();
    while let Some(k) = queue.pop_front() {
        let d = dist[&k];
        if d == limit {
            continue;
        }
        for (a, b) in neighbours8(k % cw, k / cw, cw, ch) {
            let n = b * cw + a;
            if !dist.contains_key(&n) && inside(n) {
                dist.insert(n, d + 1);
                queue.push_back(n);
            }
        }
    }
    dist
}

/// A zone's cells on a dense grid of their box (the search and the flood
/// fill after it look cells up there, not in hash maps).
struct ZoneGrid {
    x0: usize,
    y0: usize,
    w: usize,
    h: usize,
    /// The mosaic's cells a row.
    cw: usize,
    /// Each cell's cost, NaN off the zone.
    cost: Vec<f64>,
}

impl ZoneGrid {
    /// The cells `inside` admits within `corridor` 8-connected steps of
    /// `from` (mosaic cells of a `cw` × `ch` grid), on the grid of the
    /// box that reach allows; their cost 0 until set.
    fn around(from: &[usize], corridor: usize, (cw, ch): (usize, usize), inside: impl Fn(usize) -> bool) -> ZoneGrid {
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for &k in from {
            let (x, y) = (k % cw, k / cw);
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x + 1), y1.max(y + 1));
        }
        let (x0, y0) = (x0.saturating_sub(corridor), y0.saturating_sub(corridor));
        let (x1, y1) = ((x1 + corridor).min(cw), (y1 + corridor).min(ch));
        let (w, h) = (x1 - x0, y1 - y0);
        let mut zone = ZoneGrid { x0, y0, w, h, cw, cost: vec![f64::NAN; w * h] };
        let mut dist = vec![usize::MAX; w * h];
        let mut queue = VecDeque::new();
        for &k in from {
            let l = zone.local(k).expect("in the box");
            if dist[l] == usize::MAX {
                (dist[l], zone.cost[l]) = (0, 0.0);
                queue.push_back(l);
            }
        }
        while let Some(l) = queue.pop_front() {
            if dist[l] == corridor {
                continue;
            }
            for (x, y) in neighbours8(l % w, l / w, w, h) {
                let n = y * w + x;
                if dist[n] == usize::MAX && inside(zone.global(n)) {
                    (dist[n], zone.cost[n]) = (dist[l] + 1, 0.0);
                    queue.push_back(n);
                }
            }
        }
        zone
    }

    /// The zone's cells (local indices).
    fn cells(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.cost.len()).filter(|&l| !self.cost[l].is_nan())
    }

    /// The local index of mosaic cell `k`, if it is in the box.
    #[inline]
    fn local(&self, k: usize) -> Option<usize> {
        let (x, y) = ((k % self.cw).wrapping_sub(self.x0), (k / self.cw).wrapping_sub(self.y0));
        (x < self.w && y < self.h).then(|| y * self.w + x)
    }

    /// Is mosaic cell `k` in the zone?
    #[inline]
    fn holds(&self, k: usize) -> Option<usize> {
        self.local(k).filter(|&l| !self.cost[l].is_nan())
    }

    #[inline]
    fn global(&self, l: usize) -> usize {
        (self.y0 + l / self.w) * self.cw + self.x0 + l % self.w
    }

    /// The least-cost 8-connected path from cell `e0` to `e1` (mosaic
    /// indices) over the zone (a cell's cost a unit of length; a step
    /// costs the mean of its two cells' times its length): Dijkstra's
    /// search, whole-number costs, ties to the lower cell. `None` where
    /// `e1` cannot be reached.
    fn least_cost_path(&self, e0: usize, e1: usize) -> Option<Vec<usize>> {
        let (start, goal) = (self.holds(e0)?, self.holds(e1)?);
        let (w, h, c) = (self.w, self.h, &self.cost);
        let mut dist = vec![u64::MAX; w * h];
        let mut prev = vec![u32::MAX; w * h];
        let mut heap = std::collections::BinaryHeap::new();
        dist[start] = 0;
        heap.push(std::cmp::Reverse((0u64, start as u32)));
        while let Some(std::cmp::Reverse((d, k))) = heap.pop() {
            let k = k as usize;
            if k == goal {
                break;
            }
            if d > dist[k] {
                continue;
            }
            let (x, y) = (k % w, k / w);
            for (nx, ny) in neighbours8(x, y, w, h) {
                let n = ny * w + nx;
                if c[n].is_nan() {
                    continue;
                }
                let len = if nx != x && ny != y { std::f64::consts::SQRT_2 } else { 1.0 };
                let nd = d + (0.5 * (c[k] + c[n]) * len * RESOLUTION).round() as u64;
                if nd < dist[n] {
                    dist[n] = nd;
                    prev[n] = k as u32;
                    heap.push(std::cmp::Reverse((nd, n as u32)));
                }
            }
        }
        if dist[goal] == u64::MAX {
            return None;
        }
        let mut path = vec![goal];
        while let Some(&k) = path.last().filter(|&&k| k != start) {
            path.push(prev[k] as usize);
        }
        path.reverse();
        Some(path.into_iter().map(|l| self.global(l)).collect())
    }
}

/// One stretch moved onto its least-cost path; the cells that changed
/// image, or `None` where it stays as it was.
fn refine_stretch(plan: &mut Plan, corr: &[Correction], corridor: usize, edges: &[bool], (i, j): (u16, u16), stretch: &[usize]) -> Result<Option<usize>> {
    let (cw, ch) = (plan.cw, plan.ch);
    let (a, b) = (&plan.images[i as usize], &plan.images[j as usize]);
    let both = |k: usize| a.sees(k % cw, k / cw) && b.sees(k % cw, k / cw);
    let pair = |k: usize| {
        let l = plan.label[k];
        (l == i || l == j) && both(k)
    };
    let ends: Vec<usize> = stretch.iter().copied().filter(|&k| both(k)).collect();
    if ends.len() < 2 {
        return Ok(None);
    }
    // The stretch's two ends: the cell farthest from any, and the one
    // farthest from that.
    let end_set: HashSet<usize> = ends.iter().copied().collect();
    let along = |from: usize| reach(cw, ch, &[from], usize::MAX, |k| end_set.contains(&k));
    let far = |d: &HashMap<usize, usize>| d.iter().max_by_key(|(k, d)| (**d, std::cmp::Reverse(**k))).map(|(k, _)| *k);
    let (Some(e0), nb) = (far(&along(ends[0])), a.bands as usize) else { return Ok(None) };
    let Some(e1) = far(&along(e0)).filter(|&e1| e1 != e0) else { return Ok(None) };
    let mut zone = ZoneGrid::around(&ends, corridor, (cw, ch), pair);
    // Each cell's cost: where the balanced images differ, relative to
    // their mean difference over the zone, and height edges.
    let rows = zone.y0..zone.y0 + zone.h;
    let (a, b) = (plan.rows_of(i as usize, rows.clone())?, plan.rows_of(j as usize, rows)?);
    let diff = |k: usize| -> f64 {
        let (x, y) = (k % cw, k / cw);
        match (a.value(x, y), b.value(x, y)) {
            (Some(p), Some(q)) => {
                (0..nb)
                    .map(|c| {
                        let (ca, cb) = (&corr[i as usize], &corr[j as usize]);
                        ((ca.gain[c] * p.band(c) as f64 + ca.offset[c]) - (cb.gain[c] * q.band(c) as f64 + cb.offset[c])).abs()
                    })
                    .sum::<f64>()
                    / nb as f64
            }
            _ => 0.0,
        }
    };
    let cells: Vec<usize> = zone.cells().collect();
    for &l in &cells {
        zone.cost[l] = diff(zone.global(l));
    }
    let mean = cells.iter().map(|&l| zone.cost[l]).sum::<f64>() / cells.len() as f64;
    for &l in &cells {
        let k = zone.global(l);
        zone.cost[l] = 1.0 + DIFFERENCE * zone.cost[l] / mean.max(1e-9) + if edges[k] { HEIGHT_EDGE } else { 0.0 };
    }
    let Some(path) = zone.least_cost_path(e0, e1) else { return Ok(None) };
    // The zone's cells off the path, in 4-connected parts; each part goes
    // to the image its outside neighbours all belong to.
    const NO_PART: u32 = u32::MAX;
    let mut part_of = vec![NO_PART; zone.cost.len()];
    for &k in &path {
        part_of[zone.holds(k).expect("the path is in the zone")] = NO_PART - 1;
    }
    let mut parts: Vec<(Vec<usize>, bool, bool)> = Vec::new();
    // (Local order is the mosaic's order: rows of the box.)
    for start in 0..zone.cost.len() {
        if zone.cost[start].is_nan() || part_of[start] != NO_PART {
            continue;
        }
        let id = parts.len() as u32;
        part_of[start] = id;
        let start = zone.global(start);
        let (mut cells, mut to_i, mut to_j) = (vec![start], false, false);
        let mut queue = VecDeque::from([start]);
        while let Some(k) = queue.pop_front() {
            for (x, y) in neighbours4(k % cw, k / cw, cw, ch) {
                let n = y * cw + x;
                match zone.holds(n) {
                    // On the path: a border, not a neighbour.
                    Some(l) if part_of[l] == NO_PART - 1 => {}
                    Some(l) => {
                        if part_of[l] == NO_PART {
                            part_of[l] = id;
                            cells.push(n);
                            queue.push_back(n);
                        }
                    }
                    None => {
                        to_i |= plan.label[n] == i;
                        to_j |= plan.label[n] == j;
                    }
                }
            }
        }
        parts.push((cells, to_i, to_j));
    }
    let mut moved = 0;
    for (cells, to_i, to_j) in parts {
        let l = match (to_i, to_j) {
            (true, false) => i,
            (false, true) => j,
            _ => continue,
        };
        for k in cells {
            if plan.label[k] != l {
                plan.label[k] = l;
                moved += 1;
            }
        }
    }
    // The path's own cells: each to the side most of its neighbours are on.
    for &k in &path {
        let (ni, nj) = neighbours4(k % cw, k / cw, cw, ch).fold((0, 0), |(p, q), (x, y)| {
            let l = plan.label[y * cw + x];
            (p + usize::from(l == i), q + usize::from(l == j))
        });
        let l = if ni >= nj { i } else { j };
        if plan.label[k] != l {
            plan.label[k] = l;
            moved += 1;
        }
    }
    Ok(Some(moved))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 7 × 5 zone of cost 1 crossed by a wall of cost 100 at column 3,
    /// open at the bottom row (or, `closed`, not in the zone at all).
    fn walled(closed: bool) -> ZoneGrid {
        let (cw, ch) = (7, 5);
        let mut zone = ZoneGrid::around(&[0], 10, (cw, ch), |_| true);
        for y in 0..ch {
            for x in 0..cw {
                let l = zone.local(y * cw + x).expect("in the box");
                zone.cost[l] = match (x, y) {
                    (3, 4) if closed => f64::NAN,
                    (3, 4) => 1.0,
                    (3, _) if closed => f64::NAN,
                    (3, _) => 100.0,
                    _ => 1.0,
                };
            }
        }
        zone
    }

    #[test]
    fn the_least_cost_path_goes_round_a_costly_wall() {
        let zone = walled(false);
        assert_eq!((zone.w, zone.h), (7, 5), "the whole grid is within reach");
        let path = zone.least_cost_path(0, 6).expect("a path");
        // Through the gap at (3, 4): down the diagonal and up again, 8
        // steps (the straight way over the wall would cost 100 a step).
        assert_eq!((path[0], *path.last().unwrap()), (0, 6));
        assert!(path.contains(&(4 * 7 + 3)), "{path:?}");
        assert_eq!(path.len(), 9, "{path:?}");
        assert!(path.windows(2).all(|p| (p[0] % 7).abs_diff(p[1] % 7) <= 1 && (p[0] / 7).abs_diff(p[1] / 7) <= 1));
        // With the wall out of the zone, no way across.
        assert_eq!(walled(true).least_cost_path(0, 6), None);
    }

    #[test]
    fn the_corridor_reaches_so_many_steps_through_the_cells_admitted() {
        // From the middle of a 9 × 9 grid, 2 steps, column 5 not admitted.
        let zone = ZoneGrid::around(&[4 * 9 + 4], 2, (9, 9), |k| k % 9 != 5);
        let cells: Vec<usize> = zone.cells().map(|l| zone.global(l)).collect();
        // 5 × 5 around the middle, less column 5 and what lies past it.
        assert_eq!(cells.len(), 15, "{cells:?}");
        assert!(cells.iter().all(|&k| (2..5).contains(&(k % 9)) && (2..7).contains(&(k / 9))));
    }
}
