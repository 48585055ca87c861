//! The default output grid of a scan: its footprint on the DEM (thesis
//! 2.4.3–2.4.4: corners and points along the edges intersected with the
//! terrain) snapped outward to the GSD, and the scan's mean ground sample
//! distance over that footprint.

use super::inverse::RayCaster;
use crate::camera::SensorModel;
use crate::dem::{Dem, HeightModel, Lookup, Miss};
use crate::error::{Error, Result};
use crate::geom::{ImageArea, OutputGrid};

/// The outline's spacing, scan pixels. On a DSM the edge's rays land
/// farther out where they meet the ground between buildings than on the
/// roofs: sparse points (32 an edge) missed streets, and the default
/// bounds cut off part of the image.
const EDGE_STEP_PX: f64 = 4.0;

/// Ground bounds `[minx, miny, maxx, maxy]` of a `w × h` scan on the DEM:
/// of the part of it that holds the image, where the model says so (a
/// film's format).
pub fn footprint(model: &(dyn SensorModel + Sync), dem: &Dem, w: u32, h: u32, z_guess: f64) -> Result<[f64; 4]> {
    footprint_on(model, dem, w, h, z_guess).map(|f| f.bounds)
}

/// A scan's footprint and how much of its edge meets the DEM.
#[derive(Clone, Copy, Debug)]
pub struct Footprint {
    /// Ground bounds `[minx, miny, maxx, maxy]`.
    pub bounds: [f64; 4],
    /// Points of the scan's outline whose rays pass the DEM's edge (met
    /// by no height, or by the plane `--dem-outside HEIGHT` puts past
    /// it), of `edge_points`.
    pub past_edge: usize,
    /// Points whose rays meet no height where the DEM has none (its
    /// nodata collar).
    pub on_holes: usize,
    pub edge_points: usize,
    /// Of points spread over the scan inside its outline, those over the
    /// DEM's holes, of `inner_points`: a void in the middle of its ground.
    pub inner_holes: usize,
    pub inner_points: usize,
}

impl Footprint {
    /// A DEM that does not reach past the whole scan under `--dem-outside
    /// error`: an error naming the DEM and the image (else, under
    /// `nodata` or a height, the orthophoto stops or goes on, as
    /// [`Footprint::partial_warning`] says).
    pub fn check_covered(&self, image: &std::path::Path, dem: &Dem) -> Result<()> {
        if self.past_edge == 0 || dem.on_outside != Miss::Error {
            return Ok(());
        }
        Err(Error::format(
            &dem.path,
            format!(
                "covers only part of {} ({} % of its edge meets it), and ‹dem_outside› error asks for heights under all of it: give a DEM that covers it, or ‹dem_outside› nodata to stop the orthophoto at the DEM's edge, or ‹dem_outside› HEIGHT to go on at a height",
                image.display(),
                100 * (self.edge_points - self.past_edge - self.on_holes) / self.edge_points.max(1)
            ),
        ))
    }

    /// The warning for a DEM that covers only part of the scan, where the
    /// orthophoto stops at the DEM's edge or its nodata (not where a
    /// height past it is given).
    pub fn partial_warning(&self, image: &std::path::Path, dem: &Dem) -> Option<String> {
        let share = |n: usize| 100 * (self.edge_points - n) / self.edge_points.max(1);
        let outside = self.past_edge > 0 && !matches!(dem.on_outside, Miss::Height(_));
        let holes = self.on_holes > 0 && !matches!(dem.on_hole, Miss::Height(_));
        let (image, path) = (image.display(), dem.path.display());
        // What the policy does there: under `error` the run stops at the
        // first output pixel that needs such a height.
        let (edge, hole) = match (dem.on_outside, dem.on_hole) {
            (Miss::Error, _) if outside => ("the orthophoto stops at the DEM's edge, and where its extent reaches past it (given ‹bounds›) the run fails", ""),
            (_, Miss::Error) if holes && !outside => ("", "the orthophoto stops there, and where its extent still meets them (a gap between tiles, given ‹bounds›) the run fails (‹dem_hole› nodata leaves them empty; "),
            _ => ("the orthophoto stops at the DEM's edge", "the orthophoto stops there ("),
        };
        match (outside, holes) {
            (true, _) => Some(format!(
                "{image}: the DEM {path} covers only part of the image ({} % of its edge meets it): {edge} (‹dem_outside› HEIGHT goes on at that height)",
                share(self.past_edge + self.on_holes)
            )),
            (false, true) => Some(format!(
                "{image}: the DEM {path} has no heights (nodata) under part of the image ({} % of its edge meets heights): {hole}‹dem_hole› HEIGHT goes on at that height)",
                share(self.on_holes)
            )),
            // Holes inside the ground alone, left empty as asked: how much.
            (false, false) if self.inner_holes > 0 && dem.on_hole == Miss::Nodata => {
                let share = 100.0 * self.inner_holes as f64 / self.inner_points.max(1) as f64;
                Some(format!(
                    "{image}: the DEM {path} has no heights (nodata) under about {share:.0} % of the image's ground, inside its edges: the orthophoto is empty there (‹dem_hole› HEIGHT goes on at that height)"
                ))
            }
            (false, false) => None,
        }
    }
}

/// Outline points a caster walks in turn.
const OUTLINE_RUN: usize = 32;

/// [`footprint`] with how much of the scan's edge meets the DEM.
pub fn footprint_on(model: &(dyn SensorModel + Sync), dem: &Dem, w: u32, h: u32, z_guess: f64) -> Result<Footprint> {
    use rayon::prelude::*;
    let outline = image_outline(model.image_area(), w as f64, h as f64);
    let range = dem.height_range();
    let joined = |a: [f64; 4], b: [f64; 4]| [a[0].min(b[0]), a[1].min(b[1]), a[2].max(b[2]), a[3].max(b[3])];
    let none = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
    // Past the DEM, where a height is given for it, the image reaches the
    // plane at that height.
    let beyond = match dem.on_outside {
        Miss::Height(z) => Some(Dem::flat(z)),
        _ => None,
    };
    // The outline's points on the pool (thousands of rays on a large
    // frame, walked through a DSM): the bounds of each point's ground
    // points, and whether its ray met the DEM.
    // A ray that misses the DEM is past its edge where it meets the plane
    // at the guessed height outside the grid (not one lost on a wall).
    // Where it lands on the DEM's nodata instead, it is on a hole.
    let past_edge = |c: f64, r: f64| match model.locate_approx(c, r, z_guess).map(|(x, y)| dem.lookup(x, y)) {
        Some(Lookup::Outside) => (1, 0),
        Some(Lookup::Hole) => (0, 1),
        _ => (0, 0),
    };
    // In fixed runs of points, each run's casters new: a caster keeps the
    // partials of its last ray, so what it finds (where a lens folds, which
    // of two solutions) must not depend on which points a thread took
    // before (a folding fisheye once met the DEM in 2 runs of 30).
    let centre = (f64::from(w) / 2.0, f64::from(h) / 2.0);
    let (b, hits, past) = outline
        .par_chunks(OUTLINE_RUN)
        .flat_map_iter(|run| {
            let mut caster = RayCaster::new(model, dem);
            let mut flat = beyond.as_ref().map(|flat| RayCaster::new(model, flat));
            run.iter().map(move |&(c, r)| {
                // (Points on the plane count as none: the DEM must meet the scan.)
                let Some(p) = caster.cast(c, r, None, z_guess, 1e-3) else {
                    let past = past_edge(c, r);
                    return match flat.as_mut().and_then(|f| f.cast(c, r, None, z_guess, 1e-3)) {
                        Some(p) => ([p[0], p[1], p[0], p[1]], 0, past),
                        None if past != (0, 0) => match inward_edge(&mut caster, (c, r), centre, z_guess) {
                            Some(p) => ([p[0], p[1], p[0], p[1]], 0, past),
                            None => (none, 0, past),
                        },
                        None => (none, 0, past),
                    };
                };
                let mut b = [p[0], p[1], p[0], p[1]];
                // Down to the lowest height and up to the highest: where the
                // camera's nadir lies outside the image (an oblique frame), an
                // edge's rays rise outward.
                for end in range.map_or(vec![], |(lo, hi)| vec![lo, hi]) {
                    for q in other_crossings(&mut caster, (c, r), p, end) {
                        b = joined(b, [q[0], q[1], q[0], q[1]]);
                    }
                }
                (b, 1, (0, 0))
            })
        })
        .reduce(|| (none, 0, (0, 0)), |(a, m, p), (b, n, q)| (joined(a, b), m + n, (p.0 + q.0, p.1 + q.1)));
    if hits < 4 {
        let n = outline.len();
        // Most of the edge over the DEM's holes: the DEM is there, its
        // heights are not.
        // Past the edge but within the grid's rectangle: its collar of
        // nodata around the data, no heights as in a hole.
        let in_collar = outline
            .iter()
            .filter(|&&(c, r)| model.locate_approx(c, r, z_guess).is_some_and(|(x, y)| matches!(dem.lookup(x, y), Lookup::Outside) && dem.in_rectangle(x, y)))
            .count();
        let past = (past.0 - in_collar.min(past.0), past.1 + in_collar);
        let why = if past.1 > past.0 {
            format!(
                "{} of them fall in its nodata (holes, or the void around its data): no heights under the scan; ‹dem_hole› HEIGHT (‹dem_outside› HEIGHT around the data) goes on at that height",
                past.1
            )
        } else {
            // Both boxes in the DEM's CRS, so that the user sees which of
            // the two (the DEM, or the scan's camera or RPC) is elsewhere.
            let in_dem = |(x, y): (f64, f64)| match &dem.to_dem {
                Some(r) => r.apply(x, y),
                None => Some((x, y)),
            };
            let (sw, sh) = (w as f64, h as f64);
            let corners: Vec<(f64, f64)> =
                [(0.0, 0.0), (sw, 0.0), (0.0, sh), (sw, sh)].iter().filter_map(|&(c, r)| model.locate_approx(c, r, z_guess).and_then(in_dem)).collect();
            let scan = corners.iter().fold(none, |b, &(x, y)| joined(b, [x, y, x, y]));
            match (&dem.model, corners.len()) {
                (HeightModel::Grid(g), 4) => {
                    let d = g.bounds();
                    format!(
                        "the scan's corners at {z_guess:.0} m lie in [{:.6}, {:.6}, {:.6}, {:.6}], the DEM covers [{:.6}, {:.6}, {:.6}, {:.6}] (both in the DEM's CRS): is the DEM, or the scan's camera or RPC, of another place?",
                        scan[0], scan[1], scan[2], scan[3], d[0], d[1], d[2], d[3]
                    )
                }
                _ => "does the DEM cover the scan?".to_string(),
            }
        };
        return Err(Error::Geometry(format!("only {hits} of {n} points on the image's edges meet the DEM: {why}")));
    }
    // Points over the scan on a grid (inside its image area): a void
    // under its middle, which no edge point meets.
    const INNER: usize = 24;
    let area = model.image_area();
    let inner: Vec<(f64, f64)> = (0..INNER * INNER)
        .map(|k| (((k % INNER) as f64 + 0.5) * w as f64 / INNER as f64, ((k / INNER) as f64 + 0.5) * h as f64 / INNER as f64))
        .filter(|&(c, r)| area.is_none_or(|a| a.contains(c, r)))
        .collect();
    let inner_holes = inner.par_iter().filter(|&&(c, r)| past_edge(c, r).1 == 1).count();
    Ok(Footprint { bounds: b, past_edge: past.0, on_holes: past.1, edge_points: outline.len(), inner_holes, inner_points: inner.len() })
}

/// Steps of [`inward_edge`]'s walk towards the scan's centre, and halvings
/// after it: the DEM's edge to 1/16384 of the way.
const INWARD_STEPS: usize = 16;
const INWARD_HALVINGS: usize = 10;

/// Where the ray of outline point `(c, r)` meets no height (past the
/// DEM's edge, in the nodata collar of a DSM cut to its data), the ground
/// nearest it on the way to the scan's centre `(cc, rc)` that the DEM
/// does hold: where the DEM's edge crosses the scan. The hits on the
/// outline alone bound the footprint short of the data that bulges past
/// the line between them (a frame lost 1.9 % of its ground on ODM's own
/// DSM).
fn inward_edge<M: SensorModel + ?Sized>(caster: &mut RayCaster<'_, M>, (c, r): (f64, f64), (cc, rc): (f64, f64), z_guess: f64) -> Option<[f64; 3]> {
    // Near the edge a ray started at the guessed height steps off the
    // DEM before it meets the ground there (tens of metres on a DSM's
    // roofs and trees): the halvings start from the last ground found.
    let mut cast = |t: f64, from: Option<[f64; 3]>| caster.cast(c + t * (cc - c), r + t * (rc - r), from.map(|p| (p[0], p[1])), z_guess, 1e-3);
    let mut miss = 0.0;
    let (mut hit, mut p) = (1..=INWARD_STEPS).find_map(|k| {
        let t = k as f64 / INWARD_STEPS as f64;
        let p = cast(t, None);
        if p.is_none() {
            miss = t;
        }
        p.map(|p| (t, p))
    })?;
    for _ in 0..INWARD_HALVINGS {
        let t = (miss + hit) / 2.0;
        match cast(t, Some(p)) {
            Some(q) => (hit, p) = (t, q),
            None => miss = t,
        }
    }
    Some(p)
}

/// Where the ray of scan point `(c, r)`, beyond its ground point `hit`,
/// meets the DEM again on its way to the height `low` (below it or above):
/// on a DSM it passes walls and meets streets and roofs elsewhere, and
/// every ground point on it is imaged at `(c, r)` (hidden or not). The
/// ray is walked at half the DEM's posting; each crossing is polished by
/// the caster.
fn other_crossings<M: SensorModel + ?Sized>(caster: &mut RayCaster<'_, M>, (c, r): (f64, f64), hit: [f64; 3], low: f64) -> Vec<[f64; 3]> {
    let mut found = Vec::new();
    if hit[2] == low || !low.is_finite() {
        return found;
    }
    let (dem, model) = (caster.dem, caster.model);
    let Some(end) = model.locate_approx(c, r, low) else { return found };
    let (Some(s0), Some(s1)) = (dem.sample_coords(hit[0], hit[1]), dem.sample_coords(end.0, end.1)) else { return found };
    let n = (2.0 * (s1.0 - s0.0).abs().max((s1.1 - s0.1).abs())).ceil().clamp(1.0, 4096.0) as usize;
    let at = |t: f64| (hit[0] + t * (end.0 - hit[0]), hit[1] + t * (end.1 - hit[1]), hit[2] + t * (low - hit[2]));
    // Above the surface (+) or below (−), by how much.
    let above = |(x, y, z): (f64, f64, f64)| dem.surface_height(x, y).map(|h| z - h);
    let mut before = (0.0, f64::NAN);
    for k in 1..=n {
        let t = k as f64 / n as f64;
        let Some(d) = above(at(t)) else {
            before = (t, f64::NAN);
            continue;
        };
        let (t0, d0) = before;
        before = (t, d);
        if d0.is_nan() || (d0 > 0.0) == (d > 0.0) {
            continue;
        }
        let tc = t0 + (t - t0) * d0 / (d0 - d);
        let (x, y, z) = at(tc);
        found.push(caster.cast(c, r, Some((x, y)), z, 1e-3).unwrap_or([x, y, z]));
    }
    found
}

/// Points along the edge of the scan's image, every [`EDGE_STEP_PX`]
/// scan pixels: the scan's edges where no `area` limits it; else the edges
/// of the scan and of the area, each kept where it lies inside the other,
/// and the points where they cross.
fn image_outline(area: Option<ImageArea>, w: f64, h: f64) -> Vec<(f64, f64)> {
    let scan = [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)];
    let along = |poly: [(f64, f64); 4]| -> Vec<(f64, f64)> {
        (0..4)
            .flat_map(|e| {
                let (p, q) = (poly[e], poly[(e + 1) % 4]);
                let n = ((q.0 - p.0).hypot(q.1 - p.1) / EDGE_STEP_PX).ceil().clamp(32.0, 4096.0) as usize;
                (0..n).map(move |k| {
                    let t = k as f64 / n as f64;
                    (p.0 + t * (q.0 - p.0), p.1 + t * (q.1 - p.1))
                })
            })
            .collect()
    };
    let Some(area) = area else { return along(scan) };
    let in_scan = |&(c, r): &(f64, f64)| (0.0..=w).contains(&c) && (0.0..=h).contains(&r);
    let mut points: Vec<(f64, f64)> = along(scan).into_iter().filter(|&(c, r)| area.contains(c, r)).collect();
    points.extend(along(area.corners()).into_iter().filter(in_scan));
    // Where the area's edges cross the scan's.
    let corners = area.corners();
    for e in 0..4 {
        let (p, q) = (corners[e], corners[(e + 1) % 4]);
        for (axis, at) in [(0, 0.0), (0, w), (1, 0.0), (1, h)] {
            let (a, b) = if axis == 0 { (p.0, q.0) } else { (p.1, q.1) };
            if (a - at) * (b - at) <= 0.0 && a != b {
                let t = (at - a) / (b - a);
                let x = (p.0 + t * (q.0 - p.0), p.1 + t * (q.1 - p.1));
                let x = if axis == 0 { (at, x.1) } else { (x.0, at) };
                if in_scan(&x) {
                    points.push(x);
                }
            }
        }
    }
    points
}

/// Cells a side of the lattice over which [`footprint_gsd`] measures the
/// ground: 33² rays, a fraction of what the footprint's outline casts.
const GSD_CELLS: usize = 32;

/// The scan's mean ground sample distance over its footprint: the square
/// root of the ground area its image covers over the number of its
/// pixels, rounded to 4 significant digits. The area is summed over a
/// 32 × 32 lattice of scan cells whose corners' rays reach the DEM (cells
/// past its edge or outside a film's format count neither ground nor
/// pixels); signed, so that on a DSM the strips a roof's displacement
/// adds on one side and hides on the other cancel, and the sum is the
/// area inside the outline. One point under the scan's centre (a roof, a
/// valley) no longer sets the GSD of the whole scan. Where no cell meets
/// the DEM, the GSD at the centre ([`centre_gsd`]).
pub fn footprint_gsd(model: &(dyn SensorModel + Sync), dem: &Dem, w: u32, h: u32, z_guess: f64) -> Result<f64> {
    use rayon::prelude::*;
    let n = GSD_CELLS;
    let (cw, ch) = (f64::from(w) / n as f64, f64::from(h) / n as f64);
    let at = |i: usize, j: usize| (j as f64 * cw, i as f64 * ch);
    // A caster a row of points: what a ray finds may not depend on which
    // rows a thread cast before. A ray that finds no single ground point
    // over the DEM (a wall, a hole) still counts, at the guessed height:
    // a point inside the counted cells cancels from the sum, so where it
    // lies matters not, but a cell left out would take its share with it.
    let ground: Vec<Vec<Option<(f64, f64)>>> = (0..=n)
        .into_par_iter()
        .map(|i| {
            let mut caster = RayCaster::new(model, dem);
            (0..=n)
                .map(|j| {
                    let (c, r) = at(i, j);
                    caster.cast(c, r, None, z_guess, 1e-4).map(|p| (p[0], p[1])).or_else(|| {
                        let (x, y) = model.locate_approx(c, r, z_guess)?;
                        (!matches!(dem.lookup(x, y), Lookup::Outside)).then_some((x, y))
                    })
                })
                .collect()
        })
        .collect();
    let area = model.image_area();
    let (mut signed, mut cells) = (0.0, 0usize);
    for i in 0..n {
        for j in 0..n {
            let corners = [(i, j), (i, j + 1), (i + 1, j + 1), (i + 1, j)];
            if area.is_some_and(|a| corners.iter().any(|&(i, j)| !a.contains(at(i, j).0, at(i, j).1))) {
                continue;
            }
            let Some(q) = corners.iter().map(|&(i, j)| ground[i][j]).collect::<Option<Vec<_>>>() else { continue };
            signed += (0..4).map(|k| q[k].0 * q[(k + 1) % 4].1 - q[(k + 1) % 4].0 * q[k].1).sum::<f64>() / 2.0;
            cells += 1;
        }
    }
    if cells == 0 {
        return centre_gsd(model, dem, w, h, z_guess);
    }
    rounded_gsd((signed.abs() / (cells as f64 * cw * ch)).sqrt())
}

/// The scan's ground sample distance at its centre, rounded to 4
/// significant digits: the scale of a synthetic scene's texture, and what
/// a given GSD is held against before the footprint is known.
pub fn centre_gsd(model: &dyn SensorModel, dem: &Dem, w: u32, h: u32, z_guess: f64) -> Result<f64> {
    let (c, r) = (w as f64 / 2.0, h as f64 / 2.0);
    let d = 8.0;
    let three = |dem: &Dem| {
        let mut cs = RayCaster::new(model, dem);
        let mut p = |c: f64, r: f64| cs.cast(c, r, None, z_guess, 1e-4);
        (p(c, r), p(c + d, r), p(c, r + d))
    };
    let (o, a, b) = match three(dem) {
        (Some(o), Some(a), Some(b)) => (o, a, b),
        // A ray that finds no single ground point (a DSM's wall or roof
        // edge under the centre of an oblique frame): the plane at the
        // height the centre's ray met, or the mean height.
        (o, _, _) => match three(&Dem::flat(o.map_or(z_guess, |o| o[2]))) {
            (Some(o), Some(a), Some(b)) => (o, a, b),
            _ => return Err(Error::Geometry("the scan's centre does not meet the DEM".into())),
        },
    };
    let area = ((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])).abs() / (d * d);
    rounded_gsd(area.sqrt())
}

/// A GSD to 4 significant digits, through decimal text so that 11.54 is
/// the double nearest 11.54; refused where not a positive number.
fn rounded_gsd(gsd: f64) -> Result<f64> {
    if !(gsd > 0.0) || !gsd.is_finite() {
        return Err(Error::Geometry("cannot compute the scan's ground sample distance".into()));
    }
    Ok(format!("{gsd:.3e}").parse().expect("a formatted float parses"))
}

/// The default grid: footprint snapped to `gsd`. Where heights outside
/// the DEM are an error, the grid stays within the DEM's edge: snapped
/// outward, the footprint's last pixel centres would fall up to half a
/// pixel past it.
pub fn auto_grid(model: &(dyn SensorModel + Sync), dem: &Dem, w: u32, h: u32, z_guess: f64, gsd: crate::geom::Gsd) -> Result<(OutputGrid, Footprint)> {
    let fp = footprint_on(model, dem, w, h, z_guess)?;
    let mut b = fp.bounds;
    if let (Miss::Error, HeightModel::Grid(g), None) = (dem.on_outside, &dem.model, &dem.to_dem) {
        let e = g.bounds();
        let (hx, hy) = (gsd.x * 0.5001, gsd.y * 0.5001);
        b = [b[0].max(e[0] + hx), b[1].max(e[1] + hy), b[2].min(e[2] - hx), b[3].min(e[3] - hy)];
    }
    let grid = OutputGrid::snapped(b[0], b[1], b[2], b[3], gsd).ok_or_else(|| {
        Error::setting("gsd", format!("the footprint of {:.0} × {:.0} m at GSD {gsd} {}", b[2] - b[0], b[3] - b[1], OutputGrid::no_grid_because(b, gsd)))
    })?;
    Ok((grid, fp))
}
