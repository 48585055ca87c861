//! Seamlines: each stretch of the first partition's boundary between two
//! images is moved, within a corridor of the overlap around it, onto the
//! least-cost path between its two ends (Dijkstra on the cells). A cell
//! costs more where the two images (balanced) differ and much more on a
//! height edge of the DSM, so that cuts run along streets and open ground,
//! not through buildings and trees. The cells between the old and the new
//! boundary then change sides.

use super::balance::Correction;
use super::plan::{Plan, NONE};
use pathfinding::prelude::dijkstra;
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
pub fn refine(plan: &mut Plan, corr: &[Correction], corridor: usize, edges: &[bool]) -> SeamStats {
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
            if let Some(moved) = refine_stretch(plan, corr, corridor, edges, (i, j), &stretch) {
                stats.refined += 1;
                stats.cells_moved += moved;
            }
        }
    }
    stats
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
    let cells: HashSet<usize> = (0..cw * ch).filter(|&k| on(k % cw, k / cw)).collect();
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

/// One stretch moved onto its least-cost path; the cells that changed
/// image, or `None` where it stays as it was.
fn refine_stretch(plan: &mut Plan, corr: &[Correction], corridor: usize, edges: &[bool], (i, j): (u16, u16), stretch: &[usize]) -> Option<usize> {
    let (cw, ch) = (plan.cw, plan.ch);
    let (a, b) = (&plan.images[i as usize], &plan.images[j as usize]);
    let both = |k: usize| a.sees(k % cw, k / cw) && b.sees(k % cw, k / cw);
    let pair = |k: usize| {
        let l = plan.label[k];
        (l == i || l == j) && both(k)
    };
    let ends: Vec<usize> = stretch.iter().copied().filter(|&k| both(k)).collect();
    if ends.len() < 2 {
        return None;
    }
    // The stretch's two ends: the cell farthest from any, and the one
    // farthest from that.
    let end_set: HashSet<usize> = ends.iter().copied().collect();
    let along = |from: usize| reach(cw, ch, &[from], usize::MAX, |k| end_set.contains(&k));
    let far = |d: &HashMap<usize, usize>| d.iter().max_by_key(|(k, d)| (**d, std::cmp::Reverse(**k))).map(|(k, _)| *k);
    let e0 = far(&along(ends[0]))?;
    let e1 = far(&along(e0))?;
    if e0 == e1 {
        return None;
    }
    let zone = reach(cw, ch, &ends, corridor, pair);
    // Each cell's cost: where the balanced images differ, relative to
    // their mean difference over the zone, and height edges.
    let nb = a.bands as usize;
    let diff = |k: usize| -> f64 {
        let (x, y) = (k % cw, k / cw);
        match (a.value(x, y), b.value(x, y)) {
            (Some(p), Some(q)) => {
                (0..nb)
                    .map(|c| {
                        let (ca, cb) = (&corr[i as usize], &corr[j as usize]);
                        ((ca.gain[c] * p[c] as f64 + ca.offset[c]) - (cb.gain[c] * q[c] as f64 + cb.offset[c])).abs()
                    })
                    .sum::<f64>()
                    / nb as f64
            }
            _ => 0.0,
        }
    };
    let mean = zone.keys().map(|&k| diff(k)).sum::<f64>() / zone.len() as f64;
    let cost = |k: usize| 1.0 + DIFFERENCE * diff(k) / mean.max(1e-9) + if edges[k] { HEIGHT_EDGE } else { 0.0 };
    let (path, _) = dijkstra(
        &e0,
        |&k| {
            let ck = cost(k);
            neighbours8(k % cw, k / cw, cw, ch)
                .map(|(x, y)| y * cw + x)
                .filter(|n| zone.contains_key(n))
                .map(|n| {
                    let len = if n % cw != k % cw && n / cw != k / cw { std::f64::consts::SQRT_2 } else { 1.0 };
                    (n, (0.5 * (ck + cost(n)) * len * RESOLUTION).round() as u64)
                })
                .collect::<Vec<_>>()
        },
        |&k| k == e1,
    )?;
    let on_path: HashSet<usize> = path.iter().copied().collect();
    // The zone's cells off the path, in 4-connected parts; each part goes
    // to the image its outside neighbours all belong to.
    let mut part_of: HashMap<usize, usize> = HashMap::default();
    let mut parts: Vec<(Vec<usize>, bool, bool)> = Vec::new();
    let mut keys: Vec<usize> = zone.keys().copied().filter(|k| !on_path.contains(k)).collect();
    keys.sort_unstable();
    for &start in &keys {
        if part_of.contains_key(&start) {
            continue;
        }
        let id = parts.len();
        part_of.insert(start, id);
        let (mut cells, mut to_i, mut to_j) = (vec![start], false, false);
        let mut queue = VecDeque::from([start]);
        while let Some(k) = queue.pop_front() {
            for (x, y) in neighbours4(k % cw, k / cw, cw, ch) {
                let n = y * cw + x;
                if on_path.contains(&n) {
                    continue;
                }
                if zone.contains_key(&n) {
                    if let std::collections::hash_map::Entry::Vacant(e) = part_of.entry(n) {
                        e.insert(id);
                        cells.push(n);
                        queue.push_back(n);
                    }
                } else {
                    to_i |= plan.label[n] == i;
                    to_j |= plan.label[n] == j;
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
    Some(moved)
}
