//! The seamlines as GeoJSON: one feature per image, its part of the mosaic
//! as a MultiPolygon traced along the plan's cell edges (outer rings
//! counter-clockwise, holes clockwise), attributes `image` (its job's
//! name) and `index` (1-based, in manifest order). GDAL and QGIS
//! read it; the old-style `crs` member names the CRS where it has an EPSG
//! code.

use super::plan::Plan;
use crate::error::{Error, Result};
use std::collections::HashMap;

type Vertex = (i64, i64);

/// Writes the seamlines of `plan` to `path` (a temporary beside it,
/// renamed when complete).
pub fn write(plan: &Plan, path: &std::path::Path) -> Result<()> {
    let mut features = Vec::new();
    for (k, im) in plan.images.iter().enumerate() {
        let rings = rings_of(plan, k as u16);
        if rings.is_empty() {
            continue;
        }
        let polygons = polygons(rings);
        let g = plan.grid;
        let c = plan.cell as f64;
        let ground = |(x, y): Vertex| {
            let u = (x as f64 * c).min(g.width as f64);
            let v = (y as f64 * c).min(g.height as f64);
            let (gx, gy) = g.ground(u, v);
            serde_json::json!([gx, gy])
        };
        let coords: Vec<serde_json::Value> = polygons
            .into_iter()
            .map(|rings| serde_json::Value::Array(rings.into_iter().map(|r| serde_json::Value::Array(r.into_iter().map(ground).collect())).collect()))
            .collect();
        features.push(serde_json::json!({
            "type": "Feature",
            "properties": { "image": im.name, "index": k + 1, "file": im.opts.image.display().to_string() },
            "geometry": { "type": "MultiPolygon", "coordinates": coords },
        }));
    }
    let mut doc = serde_json::json!({ "type": "FeatureCollection", "name": "seamlines", "features": features });
    if let Some(code) = plan.crs.epsg() {
        doc["crs"] = serde_json::json!({ "type": "name", "properties": { "name": format!("urn:ogc:def:crs:EPSG::{code}") } });
    }
    let text = serde_json::to_string(&doc).map_err(|e| Error::Geometry(e.to_string()))?;
    crate::io::publish::write_file(path, text.as_bytes())
}

/// The closed rings around the cells of image `l`, in cell corners,
/// clockwise on the screen (rows down), so counter-clockwise on the ground
/// for outer rings.
fn rings_of(plan: &Plan, l: u16) -> Vec<Vec<Vertex>> {
    let (cw, ch) = (plan.cw as i64, plan.ch as i64);
    let is = |x: i64, y: i64| x >= 0 && y >= 0 && x < cw && y < ch && plan.label[(y * cw + x) as usize] == l;
    let mut out: HashMap<Vertex, Vec<Vertex>> = HashMap::new();
    for y in 0..ch {
        for x in 0..cw {
            if !is(x, y) {
                continue;
            }
            let mut edge = |a: Vertex, b: Vertex| {
                out.entry(a).or_default().push(b);
            };
            if !is(x, y - 1) {
                edge((x, y), (x + 1, y));
            }
            if !is(x + 1, y) {
                edge((x + 1, y), (x + 1, y + 1));
            }
            if !is(x, y + 1) {
                edge((x + 1, y + 1), (x, y + 1));
            }
            if !is(x - 1, y) {
                edge((x, y + 1), (x, y));
            }
        }
    }
    let mut starts: Vec<Vertex> = out.keys().copied().collect();
    starts.sort_unstable();
    let mut rings = Vec::new();
    for s in starts {
        while out.get(&s).is_some_and(|v| !v.is_empty()) {
            let mut ring = vec![s];
            let mut at = s;
            let mut dir: Option<Vertex> = None;
            loop {
                let next = out.get_mut(&at).expect("an edge leaves every ring vertex");
                // Where two ways leave (cells meeting at a corner), turn
                // towards the cell being walked round: right, then straight.
                let pick = match dir {
                    Some((dx, dy)) if next.len() > 1 => {
                        let right = (at.0 - dy, at.1 + dx);
                        let straight = (at.0 + dx, at.1 + dy);
                        next.iter().position(|&v| v == right).or_else(|| next.iter().position(|&v| v == straight)).unwrap_or(0)
                    }
                    _ => 0,
                };
                let to = next.swap_remove(pick);
                dir = Some((to.0 - at.0, to.1 - at.1));
                at = to;
                if at == s {
                    break;
                }
                ring.push(at);
            }
            rings.push(simplify(ring));
        }
    }
    rings
}

/// Drops the corners where a ring goes straight on; closes it.
fn simplify(ring: Vec<Vertex>) -> Vec<Vertex> {
    let n = ring.len();
    let mut out: Vec<Vertex> = (0..n)
        .filter(|&i| {
            let (p, q, r) = (ring[(i + n - 1) % n], ring[i], ring[(i + 1) % n]);
            (q.0 - p.0) * (r.1 - q.1) != (q.1 - p.1) * (r.0 - q.0)
        })
        .map(|i| ring[i])
        .collect();
    if let Some(&f) = out.first() {
        out.push(f);
    }
    out
}

/// Twice the signed area on the screen (rows down): positive clockwise.
fn area2(r: &[Vertex]) -> i64 {
    r.windows(2).map(|w| w[0].0 * w[1].1 - w[1].0 * w[0].1).sum()
}

fn contains(r: &[Vertex], p: (f64, f64)) -> bool {
    let mut inside = false;
    for w in r.windows(2) {
        let ((x0, y0), (x1, y1)) = ((w[0].0 as f64, w[0].1 as f64), (w[1].0 as f64, w[1].1 as f64));
        if (y0 > p.1) != (y1 > p.1) && p.0 < x0 + (p.1 - y0) / (y1 - y0) * (x1 - x0) {
            inside = !inside;
        }
    }
    inside
}

/// Outer rings (clockwise on the screen) each with the holes inside it
/// (counter-clockwise), the smallest outer ring holding a hole taking it;
/// every ring then reversed: on the ground (rows run down the screen, north
/// up the ground) outer rings turn counter-clockwise and holes clockwise,
/// as GeoJSON asks.
fn polygons(rings: Vec<Vec<Vertex>>) -> Vec<Vec<Vec<Vertex>>> {
    let (outer, holes): (Vec<_>, Vec<_>) = rings.into_iter().partition(|r| area2(r) > 0);
    let mut polys: Vec<Vec<Vec<Vertex>>> = outer.into_iter().map(|r| vec![r]).collect();
    for h in holes {
        // A point just inside the hole's first edge.
        let p = (
            h[0].0 as f64 + 0.5 * (h[1].0 - h[0].0) as f64 + 0.25 * (h[1].1 - h[0].1) as f64,
            h[0].1 as f64 + 0.5 * (h[1].1 - h[0].1) as f64 - 0.25 * (h[1].0 - h[0].0) as f64,
        );
        let owner = polys.iter().enumerate().filter(|(_, p_)| contains(&p_[0], p)).min_by_key(|(_, p_)| area2(&p_[0]).abs()).map(|(k, _)| k);
        if let Some(k) = owner {
            polys[k].push(h);
        }
    }
    for p in &mut polys {
        p.iter_mut().for_each(|r| r.reverse());
    }
    polys
}
