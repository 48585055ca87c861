//! Ground control points, and the sensor model they refine (`--gcps`):
//!
//! * an RPC's bias in image space (Grodecki & Dial, "Block adjustment of
//!   high-resolution satellite images described by rational polynomials",
//!   2003): a shift, or an affine map with three or more points;
//! * a frame camera's exterior orientation by space resection (least
//!   squares on the collinearity of every point, the interior fixed), with
//!   three or more points; or with the focal length and the principal
//!   point too (`--gcp-refine interior`), with five or more points at
//!   heights that tell focal length from flying height.
//!
//! Files: Orthority's GCP GeoJSON (features with `ji` — pixel centres at
//! integers — `filename`, `id`, and a point in WGS 84 longitude, latitude,
//! ellipsoidal height), or a CSV `id,col,row,x,y,z` (pixel centres at +½,
//! as GDAL's GCPs; an optional `image` or `filename` column) whose CRS is a
//! `.prj` beside it.

use super::file::{Camera, Sensor};
use super::frame::FrameCamera;
use super::gcp_points::{condition, left_out_outlier, refuse_collinear, rms};
pub use super::gcp_points::{Gcp, GcpFit, GcpResidual};
use super::rotation::AngleConvention;
use super::SensorModel;
use crate::error::{Error, Result};
use crate::geodesy::{Crs, GroundCrs};
use crate::geom::Affine2;
use crate::io::bounded_read::{read_text_bounded, LIST};
use nalgebra::{DMatrix, DVector, Vector3};
use std::path::Path;

/// How an RPC's bias is modelled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum BiasModel {
    /// An affine map with three points or more, else a shift.
    Auto,
    Shift,
    Affine,
    /// A frame camera: its pose, focal length and principal point.
    Interior,
}

/// The GCPs of `image` in the file at `path`.
pub fn read(path: &Path, image: &Path) -> Result<Vec<Gcp>> {
    let text = read_text_bounded(path, "a GCP file", LIST)?;
    let t = text.trim_start_matches('\u{feff}').trim_start();
    let all = if t.starts_with('{') { read_geojson(path, t, image)? } else { read_csv(path, t, image)? };
    if all.is_empty() {
        let name = image.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
        return Err(Error::format(path, format!("no ground control point for the image {name}")));
    }
    refuse_repeats(path, &all)?;
    Ok(all)
}

/// Refuses a point given twice (the same image and ground position under
/// other ids): each copy would weigh the fit as an independent point, and
/// a wrong camera could then be "fitted" to 0 px on one point.
fn refuse_repeats(path: &Path, gcps: &[Gcp]) -> Result<()> {
    let key = |g: &Gcp| [g.col, g.row, g.lon * 1e5, g.lat * 1e5, g.height];
    let mut order: Vec<usize> = (0..gcps.len()).collect();
    order.sort_by(|&a, &b| key(&gcps[a]).partial_cmp(&key(&gcps[b])).unwrap_or(std::cmp::Ordering::Equal));
    // Within a millipixel on the image, a millimetre on the ground.
    let same = |a: &Gcp, b: &Gcp| {
        (a.col - b.col).abs() < 1e-3
            && (a.row - b.row).abs() < 1e-3
            && (a.lon - b.lon).abs() < 1e-8
            && (a.lat - b.lat).abs() < 1e-8
            && (a.height - b.height).abs() < 1e-3
    };
    for w in order.windows(2) {
        let (a, b) = (&gcps[w[0].min(w[1])], &gcps[w[0].max(w[1])]);
        if same(a, b) {
            let copies: Vec<&str> = gcps.iter().filter(|g| same(g, a)).map(|g| g.id.as_str()).collect();
            return Err(Error::format(path, format!("GCPs {} are one point (the same image and ground position): give each point once", copies.join(", "))));
        }
    }
    Ok(())
}

/// Does a GCP file's image name name `image` (by file name, else stem)?
fn names(entry: &str, image: &Path) -> bool {
    let entry = entry.rsplit(['/', '\\']).next().unwrap_or(entry);
    let file = image.file_name().and_then(|n| n.to_str()).unwrap_or("");
    let stem = |s: &str| Path::new(s).file_stem().and_then(|s| s.to_str()).unwrap_or(s).to_string();
    entry == file || stem(entry) == stem(file)
}

fn read_geojson(path: &Path, text: &str, image: &Path) -> Result<Vec<Gcp>> {
    let v = crate::camera::formats::json::parse(text).map_err(|e| Error::format(path, format!("JSON: {e}")))?;
    let features = v.get("features").and_then(|f| f.as_array()).ok_or_else(|| Error::config(path, "features", "missing: not a GCP FeatureCollection"))?;
    let mut out = Vec::new();
    for (k, f) in features.iter().enumerate() {
        let field = |n: &str| format!("features[{k}].{n}");
        let props = f.get("properties").ok_or_else(|| Error::config(path, field("properties"), "missing"))?;
        let file = props.get("filename").and_then(|n| n.as_str()).ok_or_else(|| Error::config(path, field("properties.filename"), "missing"))?;
        if !names(file, image) {
            continue;
        }
        let nums = |v: Option<&serde_json::Value>, n: usize, name: &str| -> Result<Vec<f64>> {
            let a: Option<Vec<f64>> =
                v.and_then(|a| a.as_array()).filter(|a| a.len() == n).and_then(|a| a.iter().map(|x| x.as_f64().filter(|x| x.is_finite())).collect());
            a.ok_or_else(|| Error::config(path, field(name), format!("expected {n} numbers")))
        };
        let ji = nums(props.get("ji"), 2, "properties.ji")?;
        let xyz = nums(f.get("geometry").and_then(|g| g.get("coordinates")), 3, "geometry.coordinates")?;
        let id = match props.get("id") {
            Some(serde_json::Value::String(s)) => s.clone(),
            Some(serde_json::Value::Null) | None => format!("{}", out.len() + 1),
            Some(other) => other.to_string(),
        };
        // Orthority's pixel centres are at integers; ours at +½.
        out.push(Gcp { id, col: ji[0] + 0.5, row: ji[1] + 0.5, lon: xyz[0], lat: xyz[1], height: xyz[2], ellipsoidal: true });
    }
    Ok(out)
}

fn read_csv(path: &Path, text: &str, image: &Path) -> Result<Vec<Gcp>> {
    let prj = path.with_extension("prj");
    if !prj.is_file() {
        return Err(Error::format(path, format!("the CRS of the GCPs' x, y, z is not given: put it in {}", prj.display())));
    }
    let crs = Crs::parse(read_text_bounded(&prj, "a .prj", LIST)?.trim(), Path::new("")).map_err(|m| Error::format(&prj, m))?;
    let ground = GroundCrs::new(&crs).map_err(|m| Error::format(&prj, m))?;
    let mut r = csv::ReaderBuilder::new().trim(csv::Trim::All).flexible(false).from_reader(text.as_bytes());
    let head: Vec<String> = r.headers().map_err(|e| Error::format(path, format!("line 1: {e}")))?.iter().map(str::to_ascii_lowercase).collect();
    let col = |k: &str| head.iter().position(|h| h == k);
    let need = |k: &str| col(k).ok_or_else(|| Error::format(path, format!("line 1: no {k} column (expected id,col,row,x,y,z)")));
    let (id, c, rw, x, y, z) = (need("id")?, need("col")?, need("row")?, need("x")?, need("y")?, need("z")?);
    let image_col = col("image").or_else(|| col("filename"));
    let mut out = Vec::new();
    for (n, rec) in r.records().enumerate() {
        let line = n + 2;
        let rec = rec.map_err(|e| Error::format(path, format!("line {line}: {e}")))?;
        if image_col.is_some_and(|k| !names(rec.get(k).unwrap_or(""), image)) {
            continue;
        }
        let num = |k: usize| -> Result<f64> {
            rec.get(k)
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| Error::format(path, format!("line {line}: {} is not a number", head[k])))
        };
        let (lon, lat) = ground.to_lonlat(num(x)?, num(y)?).ok_or_else(|| Error::format(path, format!("line {line}: outside {crs}")))?;
        out.push(Gcp { id: rec.get(id).unwrap_or("").to_string(), col: num(c)?, row: num(rw)?, lon, lat, height: num(z)?, ellipsoidal: false });
    }
    Ok(out)
}

/// Refines `camera` with `gcps`: an RPC's bias, a frame camera's exterior
/// orientation. Refuses, naming the worst point, a fit that leaves a
/// residual above `max_residual` image pixels.
pub fn refine(camera: &mut Camera, gcps: &[Gcp], model: BiasModel, max_residual: f64, source: &Path) -> Result<GcpFit> {
    let fit = match &mut camera.sensor {
        Sensor::Rpc(rpc) => refine_rpc(rpc, gcps, model, source)?,
        Sensor::Frame(f) => {
            if matches!(model, BiasModel::Shift | BiasModel::Affine) {
                return Err(Error::setting("gcp_refine", "shift and affine refine an RPC; a frame camera's pose is refined by resection (auto, or interior)"));
            }
            let (refined, mut fit) = resection(f, gcps, &camera.crs, model == BiasModel::Interior, source)?;
            fit.outlier = frame_outlier(f, gcps, &camera.crs, model == BiasModel::Interior, source);
            *f = refined;
            fit
        }
        Sensor::ReprojectedFrame(_) => return Err(Error::format(source, "GCPs refine a camera in its own CRS, before it is reprojected")),
        Sensor::Panoramic(p) => {
            let dynamics = match model {
                BiasModel::Shift | BiasModel::Affine => {
                    return Err(Error::setting(
                        "gcp_refine",
                        "shift and affine refine an RPC; a panoramic camera is refined by resection (auto, or interior for the scan's dynamics too)",
                    ))
                }
                BiasModel::Interior => Some(true),
                BiasModel::Auto => None,
            };
            let (bar, mut fit) = super::panoramic_resection::resection(p, gcps, dynamics, source)?;
            fit.outlier = super::panoramic_resection::outlier(p, gcps, dynamics, source);
            p.bar = bar;
            fit
        }
    };
    if let Some(worst) = fit.points.iter().max_by(|a, b| a.after[0].hypot(a.after[1]).total_cmp(&b.after[0].hypot(b.after[1]))) {
        let r = worst.after[0].hypot(worst.after[1]);
        if r > max_residual {
            return Err(Error::format(
                source,
                format!(
                    "GCP {} is {r:.2} px off the refined model (at most {max_residual} px: ‹gcp_max_residual›); RMS {:.2} px before, {:.2} px after",
                    worst.id, fit.rms_before, fit.rms_after
                ),
            ));
        }
    }
    Ok(fit)
}

fn refine_rpc(rpc: &mut super::satellite::RpcCamera, gcps: &[Gcp], model: BiasModel, source: &Path) -> Result<GcpFit> {
    if model == BiasModel::Interior {
        return Err(Error::setting("gcp_refine", "interior refines a frame camera; an RPC's bias is a shift or an affine map"));
    }
    let mut predicted = Vec::new();
    for g in gcps {
        let z = if g.ellipsoidal { rpc.dem_height(g.lon, g.lat, g.height) } else { Some(g.height) };
        let (x, y) = rpc.crs.lonlat_to_ground(g.lon, g.lat).ok_or_else(|| Error::format(source, format!("GCP {}: outside the CRS", g.id)))?;
        let p = z.and_then(|z| rpc.project(x, y, z)).ok_or_else(|| Error::format(source, format!("GCP {}: outside the RPC's domain", g.id)))?;
        predicted.push([p.0, p.1]);
    }
    let observed: Vec<[f64; 2]> = gcps.iter().map(|g| [g.col, g.row]).collect();
    let affine = match model {
        BiasModel::Affine => true,
        BiasModel::Shift => false,
        BiasModel::Auto | BiasModel::Interior => gcps.len() >= 3,
    };
    if affine && gcps.len() < 3 {
        return Err(Error::format(source, format!("{} GCPs: an affine bias needs 3 or more (or ‹gcp_refine› shift)", gcps.len())));
    }
    let fit_bias = |predicted: &[[f64; 2]], observed: &[[f64; 2]]| {
        if affine {
            Affine2::fit(predicted, observed)
        } else {
            let k = predicted.len() as f64;
            let t = predicted.iter().zip(observed).fold([0.0, 0.0], |a, (p, o)| [a[0] + (o[0] - p[0]) / k, a[1] + (o[1] - p[1]) / k]);
            Some(Affine2 { m: nalgebra::Matrix2::identity(), t: nalgebra::Vector2::new(t[0], t[1]) })
        }
    };
    let bias = fit_bias(&predicted, &observed).ok_or_else(|| Error::format(source, "the GCPs lie on one line: no affine bias can be fitted"))?;
    // Point k's residual (image − model) under a bias.
    let residual = |bias: &Affine2, k: usize| {
        let (c, r) = bias.apply(predicted[k][0], predicted[k][1]);
        [observed[k][0] - c, observed[k][1] - r]
    };
    // Each point against the bias the others give.
    let outlier = left_out_outlier(gcps, if affine { 3 } else { 1 }, |i| {
        let keep = |v: &[[f64; 2]]| -> Vec<[f64; 2]> { v.iter().enumerate().filter(|(k, _)| *k != i).map(|(_, p)| *p).collect() };
        let others = fit_bias(&keep(&predicted), &keep(&observed))?;
        let rest: Vec<[f64; 2]> = (0..gcps.len()).filter(|&k| k != i).map(|k| residual(&others, k)).collect();
        let own = residual(&others, i);
        Some((own[0].hypot(own[1]), rms(&rest)))
    });
    let before: Vec<[f64; 2]> = predicted.iter().zip(&observed).map(|(p, o)| [o[0] - p[0], o[1] - p[1]]).collect();
    let after: Vec<[f64; 2]> = (0..gcps.len()).map(|k| residual(&bias, k)).collect();
    let m = bias.m;
    let correction =
        format!("col' = {:.6}·col + {:.6}·row + {:.3}, row' = {:.6}·col + {:.6}·row + {:.3}", m[(0, 0)], m[(0, 1)], bias.t.x, m[(1, 0)], m[(1, 1)], bias.t.y);
    if !rpc.set_bias(bias) {
        return Err(Error::format(source, "the fitted bias is singular"));
    }
    let fit = GcpFit {
        method: if affine { "rpc affine" } else { "rpc shift" }.into(),
        points: gcps.iter().zip(before.iter().zip(&after)).map(|(g, (b, a))| GcpResidual { id: g.id.clone(), before: *b, after: *a }).collect(),
        rms_before: rms(&before),
        rms_after: rms(&after),
        correction,
        outlier,
    };
    Ok(fit)
}

/// Leave-one-out over a frame's GCPs: each point against the camera the
/// others give (twice as many resections).
fn frame_outlier(f: &FrameCamera, gcps: &[Gcp], crs: &Crs, interior: bool, source: &Path) -> Option<String> {
    left_out_outlier(gcps, if interior { 5 } else { 3 }, |i| {
        let rest: Vec<Gcp> = gcps.iter().enumerate().filter(|(k, _)| *k != i).map(|(_, g)| g.clone()).collect();
        let (without, fit) = resection(f, &rest, crs, interior, source).ok()?;
        // Its residual under that camera: the `before` of a fit from it.
        let (_, from) = resection(&without, gcps, crs, interior, source).ok()?;
        Some((from.points[i].before[0].hypot(from.points[i].before[1]), fit.rms_after))
    })
}

/// Space resection: the exterior orientation (with `interior`, also the
/// focal length and principal point) that best images `gcps`, from the
/// camera's own as the first guess (Gauss–Newton on the centre, a small
/// rotation and the interior's changes). A solution the points do not fix
/// — the interior from points near one plane seen square-on, where focal
/// length and flying height trade off — is refused.
fn resection(f: &FrameCamera, gcps: &[Gcp], crs: &Crs, interior: bool, source: &Path) -> Result<(FrameCamera, GcpFit)> {
    let least = if interior { 5 } else { 3 };
    if gcps.len() < least {
        let what = if interior { "a resection with the interior" } else { "a resection" };
        return Err(Error::format(source, format!("{} GCPs: {what} needs {least} or more", gcps.len())));
    }
    let ground = GroundCrs::new(crs).map_err(|m| Error::format(source, m))?;
    let points: Vec<Vector3<f64>> = gcps
        .iter()
        .map(|g| {
            ground
                .lonlat_to_ground(g.lon, g.lat)
                .map(|(x, y)| Vector3::new(x, y, g.height))
                .ok_or_else(|| Error::format(source, format!("GCP {}: outside {crs}", g.id)))
        })
        .collect::<Result<_>>()?;
    refuse_collinear(&points, source)?;
    // The unknowns' current values: centre, rotation, focal length (mm),
    // principal point's move (px).
    struct State {
        c: Vector3<f64>,
        r: nalgebra::Matrix3<f64>,
        focal: f64,
        pp: [f64; 2],
    }
    // The film's calibrated format stays where the marks put it on the
    // scan: the margins outside it stay out of the orthophoto.
    let camera_at = |s: &State| {
        FrameCamera::new(s.focal, s.c, s.r, f.interior.with_principal_point_moved(s.pp), f.distortion, f.refraction, f.earth_curvature).with_area_of(f)
    };
    let residuals = |cam: &FrameCamera| -> Option<Vec<[f64; 2]>> {
        points.iter().zip(gcps).map(|(p, g)| cam.project(p.x, p.y, p.z).map(|(c, r)| [g.col - c, g.row - r])).collect()
    };
    let left_view = || Error::format(source, "the resection left the GCPs' view");
    let before = residuals(f).ok_or_else(|| Error::format(source, "a GCP is behind the camera or off its lens model"))?;
    let mut s = State { c: f.centre, r: f.r, focal: f.focal_mm, pp: [0.0, 0.0] };
    let unknowns = if interior { 9 } else { 6 };
    let moved = |s: &State, d: &[f64]| State {
        c: s.c + Vector3::new(d[0], d[1], d[2]),
        r: AngleConvention::OmegaPhiKappa.matrix([d[3], d[4], d[5]]) * s.r,
        focal: s.focal + d.get(6).copied().unwrap_or(0.0),
        pp: [s.pp[0] + d.get(7).copied().unwrap_or(0.0), s.pp[1] + d.get(8).copied().unwrap_or(0.0)],
    };
    let mut current = before.clone();
    let scale = f.centre.z.abs().max(1.0) * 1e-6;
    let n = points.len();
    let mut j = DMatrix::<f64>::zeros(2 * n, unknowns);
    for _ in 0..30 {
        for k in 0..unknowns {
            let h = match k {
                0..=2 => scale.max(1e-3),
                3..=5 => 1e-7,
                6 => f.focal_mm * 1e-7,
                _ => 1e-4,
            };
            let mut d = vec![0.0; unknowns];
            d[k] = h;
            let shifted = residuals(&camera_at(&moved(&s, &d))).ok_or_else(left_view)?;
            for i in 0..n {
                j[(2 * i, k)] = -(shifted[i][0] - current[i][0]) / h;
                j[(2 * i + 1, k)] = -(shifted[i][1] - current[i][1]) / h;
            }
        }
        if interior {
            fixes_interior(&j, source)?;
        }
        let e = DVector::from_iterator(2 * n, current.iter().flat_map(|d| [d[0], d[1]]));
        let delta = j.clone().svd(true, true).solve(&e, 1e-12).map_err(|_| Error::format(source, "the GCPs do not fix the camera's pose"))?;
        s = moved(&s, delta.as_slice());
        current = residuals(&camera_at(&s)).ok_or_else(left_view)?;
        if delta.rows(0, 3).norm() < 1e-6 && delta.rows(3, 3).norm() < 1e-10 && delta.rows(6, unknowns - 6).norm() < 1e-7 {
            break;
        }
    }
    // Re-orthonormalised: many small turns multiplied.
    s.r = crate::geodesy::ecef::nearest_rotation(&s.r).unwrap_or(s.r);
    let refined = camera_at(&s);
    let after = residuals(&refined).ok_or_else(left_view)?;
    let opk = AngleConvention::OmegaPhiKappa.angles(&s.r).map(f64::to_degrees);
    let mut correction = format!("centre ({:.3}, {:.3}, {:.3}), omega-phi-kappa ({:.5}°, {:.5}°, {:.5}°)", s.c.x, s.c.y, s.c.z, opk[0], opk[1], opk[2]);
    if interior {
        let pp = refined.interior.principal_point_px();
        correction += &format!(
            ", focal length {:.4} mm (was {:.4}), principal point ({:.2}, {:.2}) px (moved {:+.2}, {:+.2})",
            s.focal, f.focal_mm, pp[0], pp[1], s.pp[0], s.pp[1]
        );
    }
    let fit = GcpFit {
        method: if interior { "resection with interior" } else { "resection" }.into(),
        points: gcps.iter().zip(before.iter().zip(&after)).map(|(g, (b, a))| GcpResidual { id: g.id.clone(), before: *b, after: *a }).collect(),
        rms_before: rms(&before),
        rms_after: rms(&after),
        correction,
        outlier: None,
    };
    Ok((refined, fit))
}

/// The least ratio of the smallest to the largest singular value of the
/// column-scaled Jacobian at which a resection with the interior is taken.
const INTERIOR_CONDITION: f64 = 1e-4;

/// Refuses a Jacobian `j` (residuals by pose and interior) whose columns,
/// each scaled to unit length, leave a near-zero singular value: a
/// combination of changes the points cannot see.
fn fixes_interior(j: &DMatrix<f64>, source: &Path) -> Result<()> {
    let ratio = condition(j);
    if ratio > INTERIOR_CONDITION {
        return Ok(());
    }
    Err(Error::format(
        source,
        format!(
            "the GCPs do not fix the focal length and principal point apart from the pose (condition {:.0e}): they need to spread in height over the frame (or keep the interior fixed: ‹gcp_refine› auto)",
            1.0 / ratio
        ),
    ))
}
