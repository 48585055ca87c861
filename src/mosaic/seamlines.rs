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

/// Writes the seamlines of `plan` for `path` under a temporary name
/// beside it, for the caller to publish when its run is done.
pub fn write(plan: &Plan, path: &std::path::Path) -> Result<Option<crate::io::publish::PendingFile>> {
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
            "properties": { "image": im.name, "index": k + 1, "file": im.opts.inputs.image.display().to_string() },
            "geometry": { "type": "MultiPolygon", "coordinates": coords },
        }));
    }
    let mut doc = serde_json::json!({ "type": "FeatureCollection", "name": "seamlines", "features": features });
    // A CRS without a code as its PROJ string: GDAL (and so QGIS) takes a
    // named CRS as any text its SetFromUserInput reads; none would be read
    // as WGS 84 longitude and latitude (RFC 7946) and land nowhere.
    let name = plan.crs.epsg().map_or_else(|| plan.crs.proj4().to_string(), |code| format!("urn:ogc:def:crs:EPSG::{code}"));
    doc["crs"] = serde_json::json!({ "type": "name", "properties": { "name": name } });
    let text = serde_json::to_string(&doc).map_err(|e| Error::Internal(format!("seamlines as JSON: {e}")))?;
    crate::io::publish::write_pending(path, text.as_bytes())
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

/// What honouring edited seamlines changed.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct EditedSeams {
    /// Cells the file gives to an image.
    pub cells_given: usize,
    /// Cells given to an image that does not see them, or to none where
    /// one does: they keep the plan's image.
    pub cells_kept: usize,
    /// Cells inside two features: the first one's.
    pub cells_overlapping: usize,
    /// What in the file looks like a slip of the editing (a ring of no
    /// area, an outline that crosses itself, a feature outside the
    /// mosaic): said as warnings.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub doubts: Vec<String>,
}

/// The first position of the features' geometries.
fn first_position(features: &[serde_json::Value]) -> Option<[f64; 2]> {
    fn dig(v: &serde_json::Value) -> Option<[f64; 2]> {
        let a = v.as_array()?;
        match (a.first().and_then(|x| x.as_f64()), a.get(1).and_then(|y| y.as_f64())) {
            (Some(x), Some(y)) => Some([x, y]),
            _ => a.iter().find_map(dig),
        }
    }
    features.iter().find_map(|f| dig(f.pointer("/geometry/coordinates")?))
}

/// Edited seamlines (as [`write`] writes them, moved about in a GIS):
/// each feature's polygons, in the mosaic's CRS (or WGS 84 longitude and
/// latitude where the file's `crs` says EPSG:4326 or CRS84, or where it
/// has no `crs` and its numbers are degrees), give their
/// cells to the image its `image` (else `index`, 1-based) names.
/// `v` as a GeoJSON array of `of`; anything else named by its kind (never
/// quoted: a string there may be anything).
fn array_of<'v>(v: &'v serde_json::Value, of: &str) -> std::result::Result<&'v Vec<serde_json::Value>, String> {
    let kind = match v {
        serde_json::Value::Array(a) => return Ok(a),
        serde_json::Value::Null => "null",
        serde_json::Value::Bool(_) => "true or false",
        serde_json::Value::Number(_) => "a number",
        serde_json::Value::String(_) => "a string",
        serde_json::Value::Object(_) => "an object",
    };
    Err(format!("expected an array of {of}, found {kind}"))
}

pub fn read(plan: &mut Plan, path: &std::path::Path) -> Result<EditedSeams> {
    let text = crate::io::bounded_read::read_text_bounded(path, "a seamlines file", crate::io::bounded_read::LIST)?;
    let doc: serde_json::Value = serde_json::from_str(&text).map_err(|e| Error::format(path, format!("JSON: {e}")))?;
    let features = doc.get("features").and_then(|f| f.as_array()).ok_or_else(|| Error::config(path, "features", "missing: not a GeoJSON FeatureCollection"))?;
    let named = doc.pointer("/crs/properties/name").and_then(|n| n.as_str()).unwrap_or("");
    // Without a `crs` member, GeoJSON (RFC 7946) is WGS 84 longitude and
    // latitude, as GIS tools save it; an older file without one in the
    // mosaic's own projected CRS is told by its numbers.
    let unnamed_lonlat =
        doc.get("crs").is_none() && !plan.crs.is_geographic() && first_position(features).is_some_and(|[x, y]| x.abs() <= 180.0 && y.abs() <= 90.0);
    let lonlat = named.ends_with("EPSG::4326") || named.ends_with("CRS84") || named == "EPSG:4326" || unnamed_lonlat;
    if named.starts_with('+') {
        let theirs = crate::geodesy::Crs::from_proj4(named).map_err(|m| Error::config(path, "crs", m))?;
        if theirs != plan.crs {
            return Err(Error::unsupported(path, format!("the seamlines are in {theirs}, the mosaic in {}: save them in the mosaic's CRS", plan.crs)));
        }
    }
    let to_plan = match (lonlat, named.rsplit(':').next().and_then(|c| c.parse::<u32>().ok())) {
        (true, _) => Some(crate::geodesy::GroundCrs::new(&plan.crs).map_err(|m| Error::format(path, m))?),
        (false, Some(code)) if plan.crs.epsg() != Some(code) => {
            return Err(Error::unsupported(path, format!("the seamlines are in EPSG:{code}, the mosaic in {}: save them in the mosaic's CRS", plan.crs)));
        }
        _ => None,
    };
    // Each feature's rings in cell coordinates, and its image.
    let (g, c) = (plan.grid, plan.cell as f64);
    // Each feature's polygons, each a ring list (outer and holes).
    let mut shapes: Vec<(u16, Vec<Rings>)> = Vec::new();
    // Each shape's feature, named as a warning names it.
    let mut feature_of: Vec<String> = Vec::new();
    let mut doubts = Vec::new();
    // The first feature with a geometry to name each image, and the first
    // feature of each image's each geometry (as text: linear in the file).
    let mut first_naming: Vec<Option<usize>> = vec![None; plan.images.len()];
    let mut shapes_seen: std::collections::HashMap<(usize, String), usize> = Default::default();
    for (k, f) in features.iter().enumerate() {
        let field = |n: &str| format!("features[{k}].{n}");
        let props = f.get("properties").cloned().unwrap_or_default();
        let image = match (props.get("image").and_then(|v| v.as_str()), props.get("index").and_then(|v| v.as_u64())) {
            (Some(name), _) => plan
                .images
                .iter()
                .position(|i| i.name == name)
                .ok_or_else(|| Error::config(path, field("properties.image"), format!("'{name}' is not an image of the manifest")))?,
            (None, Some(i)) if i >= 1 && (i as usize) <= plan.images.len() => i as usize - 1,
            (None, Some(i)) => {
                return Err(Error::config(path, field("properties.index"), format!("{i} is not an image of the manifest (1 to {})", plan.images.len())));
            }
            _ => return Err(Error::config(path, field("properties.image"), "missing: each feature names its image")),
        };
        // Properties that name another image than the one taken.
        let taken = &plan.images[image];
        if let Some(i) = props.get("index").and_then(|v| v.as_u64()).filter(|&i| i as usize != image + 1) {
            doubts.push(format!("features[{k}]: index {i} is not image '{}' (its index is {}): taken as '{}'", taken.name, image + 1, taken.name));
        }
        if let Some(file) = props.get("file").and_then(|v| v.as_str()).filter(|&f| std::path::Path::new(f) != taken.opts.inputs.image) {
            doubts.push(format!("features[{k}]: file {file} is not image '{}' ({}): taken as '{}'", taken.name, taken.opts.inputs.image.display(), taken.name));
        }
        // A feature whose parts were all deleted in a GIS gives nothing.
        let Some(geometry) = f.get("geometry").filter(|g| !g.is_null()) else { continue };
        // An image a feature before named too (a feature pasted twice, or
        // an image's part drawn apart): honoured as the union, and said.
        match (first_naming[image], shapes_seen.entry((image, geometry.to_string()))) {
            (_, std::collections::hash_map::Entry::Occupied(j)) => {
                doubts.push(format!("features[{k}] repeats features[{}] (image '{}', the same geometry): taken once", j.get(), taken.name));
            }
            (Some(j), std::collections::hash_map::Entry::Vacant(v)) => {
                doubts.push(format!("features[{k}] names image '{}' as features[{j}] does: the cells of both given to it", taken.name));
                v.insert(k);
            }
            (None, std::collections::hash_map::Entry::Vacant(v)) => {
                first_naming[image] = Some(k);
                v.insert(k);
            }
        }
        let coords = geometry.get("coordinates").ok_or_else(|| Error::config(path, field("geometry.coordinates"), "missing"))?;
        // Each level an array (RFC 7946 §3.1.6): anything else is refused,
        // never read as no rings.
        let at_coordinates = |m: String| Error::config(path, field("geometry.coordinates"), m);
        let polygons: Vec<&serde_json::Value> = match geometry.get("type").and_then(|t| t.as_str()) {
            Some("Polygon") => vec![coords],
            Some("MultiPolygon") => array_of(coords, "polygons").map_err(at_coordinates)?.iter().collect(),
            Some(other) => return Err(Error::config(path, field("geometry.type"), format!("'{other}': expected Polygon or MultiPolygon"))),
            None => return Err(Error::config(path, field("geometry.type"), "missing: expected Polygon or MultiPolygon")),
        };
        let what = format!("features[{k}] (image {})", plan.images[image].name);
        let mut parts = Vec::new();
        for poly in polygons {
            let mut rings = Vec::new();
            for ring in array_of(poly, "rings").map_err(at_coordinates)? {
                let mut pts = Vec::new();
                for p in array_of(ring, "positions").map_err(at_coordinates)? {
                    let (x, y) = match (p.get(0).and_then(|v| v.as_f64()), p.get(1).and_then(|v| v.as_f64())) {
                        (Some(x), Some(y)) if x.is_finite() && y.is_finite() => (x, y),
                        _ => return Err(Error::config(path, field("geometry.coordinates"), "expected [x, y] numbers")),
                    };
                    let (x, y) = match &to_plan {
                        Some(t) => t.lonlat_to_ground(x, y).ok_or_else(|| Error::config(path, field("geometry.coordinates"), "outside the mosaic's CRS"))?,
                        None => (x, y),
                    };
                    pts.push(((x - g.x0) / g.gsd.x / c, (g.y0 - y) / g.gsd.y / c));
                }
                // GeoJSON's rings are closed (RFC 7946 §3.1.6): one that is
                // not was cut by hand, and what it was to hold is unknown.
                if pts.len() > 1 && pts.first() != pts.last() {
                    return Err(Error::config(
                        path,
                        field("geometry.coordinates"),
                        format!("a ring of {} positions whose last is not its first: GeoJSON rings are closed", pts.len()),
                    ));
                }
                let mut distinct = pts.clone();
                distinct.dedup();
                if distinct.len() > 1 && distinct.first() == distinct.last() {
                    distinct.pop();
                }
                if distinct.len() < 3 {
                    doubts.push(format!("{what}: a ring of {} point(s), no area: left out", distinct.len()));
                    continue;
                }
                match crosses_itself(&distinct) {
                    Some(true) => {
                        doubts.push(format!("{what}: its outline crosses itself; cells are filled by the even-odd rule (where it loops over itself, left out)"))
                    }
                    Some(false) => {}
                    None => doubts.push(format!(
                        "{what}: a ring of {} points too dense to check for crossing itself; cells are filled by the even-odd rule",
                        distinct.len()
                    )),
                }
                rings.push(pts);
            }
            parts.push(rings);
        }
        shapes.push((image as u16, parts));
        feature_of.push(what);
    }
    let mut filled = vec![0usize; shapes.len()];
    // Cell centres, row by row: where a polygon's rings cross the row, the
    // even-odd rule fills between the crossings; a feature is the union of
    // its polygons. A cell cut by the grid's edge has its centre in the
    // part inside (as `write` traces it). A cell's claims come in the
    // features' and polygons' order, whatever the order of rows.
    let (wc, hc) = (g.width as f64 / c, g.height as f64 / c);
    let centre = |i: usize, n: f64| (i as f64 + (i as f64 + 1.0).min(n)) / 2.0;
    let mut given = vec![NONE_GIVEN; plan.cw * plan.ch];
    let mut report = EditedSeams::default();
    // Rows whose centre yc lies in [lo, hi): the rows an edge crosses (one
    // end strictly above yc, as the even-odd rule counts an end once).
    let below = |v: f64| first_index(plan.ch, |y| centre(y, hc) >= v);
    let rows_between = |lo: f64, hi: f64| below(lo)..below(hi);
    let mut crossings_left = MAX_CROSSINGS;
    for (n, (image, parts)) in shapes.iter().enumerate() {
        for rings in parts {
            // Each row's crossings, gathered edge by edge (work as the
            // crossings, not as rows × edges).
            let mut by_row: Vec<(u32, f64)> = Vec::new();
            for r in rings {
                for k in 0..r.len() {
                    let (a, b) = (r[k], r[(k + 1) % r.len()]);
                    if a.1 == b.1 {
                        continue;
                    }
                    // A row's centre yc is crossed where exactly one end lies above it.
                    let (lo, hi) = if a.1 < b.1 { (a.1, b.1) } else { (b.1, a.1) };
                    let rows = rows_between(lo, hi);
                    crossings_left = crossings_left
                        .checked_sub(rows.len())
                        .ok_or_else(|| Error::limits(path, format!("its rings cross the mosaic's rows of cells more than {MAX_CROSSINGS} times in all")))?;
                    for y in rows {
                        let yc = centre(y, hc);
                        by_row.push((y as u32, a.0 + (yc - a.1) / (b.1 - a.1) * (b.0 - a.0)));
                    }
                }
            }
            by_row.sort_by(|p, q| p.0.cmp(&q.0).then(p.1.total_cmp(&q.1)));
            for row in by_row.chunk_by(|p, q| p.0 == q.0) {
                let y = row[0].0 as usize;
                for pair in row.chunks_exact(2) {
                    let pair = [pair[0].1, pair[1].1];
                    // Cells whose centre lies in [pair[0], pair[1]).
                    let from = (pair[0] - 0.5).ceil().clamp(0.0, plan.cw as f64) as usize;
                    let to = (pair[1].ceil().max(0.0) as usize).min(plan.cw);
                    for x in from.saturating_sub(1)..to {
                        let xc = centre(x, wc);
                        if !(xc >= pair[0] && xc < pair[1]) {
                            continue;
                        }
                        filled[n] += 1;
                        let cell = &mut given[y * plan.cw + x];
                        if *cell == NONE_GIVEN {
                            *cell = *image;
                        } else if *cell != *image {
                            report.cells_overlapping += 1;
                        }
                    }
                }
            }
        }
    }
    for y in 0..plan.ch {
        for x in 0..plan.cw {
            let k = y * plan.cw + x;
            let planned = plan.label[k];
            match given[k] {
                NONE_GIVEN if planned == super::plan::NONE => {}
                NONE_GIVEN => report.cells_kept += 1,
                l if plan.images[l as usize].sees(x, y) => {
                    report.cells_given += 1;
                    plan.label[k] = l;
                }
                _ => report.cells_kept += usize::from(planned != super::plan::NONE),
            }
        }
    }
    if report.cells_given == 0 {
        return Err(Error::format(path, "its polygons give no cell of the mosaic to an image that sees it: are they in the mosaic's CRS?"));
    }
    for (what, _) in feature_of.iter().zip(&filled).filter(|(_, &n)| n == 0) {
        doubts.push(format!("{what}: holds no cell of the mosaic (outside it, or too thin to hold a cell's centre)"));
    }
    // A file of many slips: the first ones said, the rest counted.
    if doubts.len() > MAX_DOUBTS {
        let more = doubts.len() - MAX_DOUBTS;
        doubts.truncate(MAX_DOUBTS);
        doubts.push(format!("and {more} more such doubts"));
    }
    report.doubts = doubts;
    Ok(report)
}

/// The doubts about an edited file said one by one.
const MAX_DOUBTS: usize = 20;

/// Does the closed ring `pts` (no point repeated at its end) cross itself:
/// two edges that are not neighbours meet? `None` where it cannot be told
/// within [`MAX_PAIRS`] edge pairs. Edges are binned on a grid of about
/// one edge a bin, and only edges sharing a bin compared: near-linear for
/// the rings a GIS draws, however many points they hold.
fn crosses_itself(pts: &[(f64, f64)]) -> Option<bool> {
    let n = pts.len();
    let edge = |i: usize| (pts[i], pts[(i + 1) % n]);
    let side = |a: (f64, f64), b: (f64, f64), p: (f64, f64)| ((b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0)).signum();
    let neighbours = |i: usize, j: usize| i.abs_diff(j) <= 1 || (i.min(j) == 0 && i.max(j) == n - 1);
    let cross = |i: usize, j: usize| {
        let ((a, b), (c, d)) = (edge(i), edge(j));
        !neighbours(i, j) && side(a, b, c) * side(a, b, d) < 0.0 && side(c, d, a) * side(c, d, b) < 0.0
    };
    let (x0, x1) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p.0), hi.max(p.0)));
    let (y0, y1) = pts.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p.1), hi.max(p.1)));
    // Bins a few mean edges wide: a few edges each along the outline
    // (at most 2^20 a side).
    let mean_edge = (0..n).map(|i| (pts[(i + 1) % n].0 - pts[i].0).hypot(pts[(i + 1) % n].1 - pts[i].1)).sum::<f64>() / n as f64;
    let extent = (x1 - x0).max(y1 - y0);
    let step = (4.0 * mean_edge).max(extent / f64::from(1u32 << 20)).max(f64::MIN_POSITIVE);
    let bin = |v: f64, v0: f64| (((v - v0) / step) as u64).min((1 << 20) - 1);
    let mut entries: Vec<(u64, u32)> = Vec::new();
    for i in 0..n {
        let (a, b) = edge(i);
        let (bx0, bx1) = (bin(a.0.min(b.0), x0), bin(a.0.max(b.0), x0));
        let (by0, by1) = (bin(a.1.min(b.1), y0), bin(a.1.max(b.1), y0));
        if entries.len() as u64 + (bx1 - bx0 + 1) * (by1 - by0 + 1) > MAX_PAIRS as u64 {
            return None;
        }
        for by in by0..=by1 {
            for bx in bx0..=bx1 {
                entries.push((by << 20 | bx, i as u32));
            }
        }
    }
    entries.sort_unstable();
    let mut pairs = 0usize;
    for group in entries.chunk_by(|p, q| p.0 == q.0) {
        pairs += group.len() * (group.len() - 1) / 2;
        if pairs > MAX_PAIRS {
            return None;
        }
        for (k, &(_, i)) in group.iter().enumerate() {
            if group[k + 1..].iter().any(|&(_, j)| cross(i as usize, j as usize)) {
                return Some(true);
            }
        }
    }
    Some(false)
}

/// The most pairs of edges compared for a ring's crossing itself.
const MAX_PAIRS: usize = 50_000_000;

/// The first of `0..n` where `at_or_past` holds (it holds from there on).
fn first_index(n: usize, at_or_past: impl Fn(usize) -> bool) -> usize {
    let (mut lo, mut hi) = (0, n);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if at_or_past(mid) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

/// The most crossings of rings with rows of cells a seamlines file may
/// make (16 bytes each, held a polygon at a time): a polygon from a GIS
/// crosses each row a few times.
const MAX_CROSSINGS: usize = 8_000_000;

/// Closed rings in cell coordinates.
type Rings = Vec<Vec<(f64, f64)>>;

/// A cell no feature covers.
const NONE_GIVEN: u16 = u16::MAX;

#[cfg(test)]
mod tests {
    use super::crosses_itself;

    /// The pairs of edges one by one: the reference the binned search must agree with.
    fn crosses_by_pairs(pts: &[(f64, f64)]) -> bool {
        let n = pts.len();
        let edge = |i: usize| (pts[i], pts[(i + 1) % n]);
        let side = |a: (f64, f64), b: (f64, f64), p: (f64, f64)| ((b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0)).signum();
        (0..n).any(|i| {
            let (a, b) = edge(i);
            (i + 2..n).filter(|&j| !(i == 0 && j == n - 1)).any(|j| {
                let (c, d) = edge(j);
                side(a, b, c) * side(a, b, d) < 0.0 && side(c, d, a) * side(c, d, b) < 0.0
            })
        })
    }

    #[test]
    fn binned_crossing_search_agrees_with_every_pair_and_takes_a_million_points() {
        // Stars of every kind: a pentagram crosses itself, a regular polygon not.
        let mut seed = 7u64;
        let mut rand = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for n in [3usize, 4, 5, 7, 40, 300] {
            for step in [1usize, 2, 3] {
                let pts: Vec<(f64, f64)> = (0..n)
                    .map(|k| {
                        let t = std::f64::consts::TAU * (k * step % n) as f64 / n as f64;
                        (100.0 * t.cos() + rand() * 1e-3, 100.0 * t.sin())
                    })
                    .collect();
                assert_eq!(crosses_itself(&pts), Some(crosses_by_pairs(&pts)), "n {n} step {step}");
            }
            let random: Vec<(f64, f64)> = (0..n).map(|_| (rand() * 50.0, rand() * 50.0)).collect();
            assert_eq!(crosses_itself(&random), Some(crosses_by_pairs(&random)), "random {n}");
        }
        // A million-point circle is told within the pair budget (every pair
        // would be 5e11 of them).
        let n = 1_000_000;
        let circle: Vec<(f64, f64)> = (0..n).map(|k| (std::f64::consts::TAU * k as f64 / n as f64).sin_cos()).map(|(s, c)| (1e4 * c, 1e4 * s)).collect();
        assert_eq!(crosses_itself(&circle), Some(false));
    }
}
