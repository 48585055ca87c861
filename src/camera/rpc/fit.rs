//! Fitting an RPC00B model to a sensor, the way image providers make them
//! ("terrain-independent" RPCs): image positions of a 3-D grid of ground
//! points over the scene's height range, and for each of line and sample
//! the 39 unknowns of `num − value·den = 0` (den₁ = 1) by least squares.

use super::Rpc;

/// One fitting point: ground (longitude °, latitude °, height m) and its
/// scan position (column, row; pixel centres at +½).
pub type Correspondence = ((f64, f64, f64), (f64, f64));

/// What the fit left: the largest residual over the fitting points, pixels.
pub struct Fitted {
    pub rpc: Rpc,
    pub max_residual_px: f64,
}

/// Fits an RPC to `points` (at least 39, spread over the image and at
/// several heights). `None` when the system is singular.
pub fn fit_rpc(points: &[Correspondence]) -> Option<Fitted> {
    if points.len() < 39 {
        return None;
    }
    let range = |f: &dyn Fn(&Correspondence) -> f64| {
        let (lo, hi) = points.iter().map(f).fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
        ((lo + hi) / 2.0, ((hi - lo) / 2.0).max(1e-9))
    };
    let (long_off, long_scale) = range(&|p| p.0 .0);
    let (lat_off, lat_scale) = range(&|p| p.0 .1);
    let (height_off, height_scale) = range(&|p| p.0 .2);
    // Offsets and scales of the image in RPC (0-based centre) coordinates.
    let (samp_off, samp_scale) = range(&|p| p.1 .0 - 0.5);
    let (line_off, line_scale) = range(&|p| p.1 .1 - 0.5);
    let terms: Vec<[f64; 20]> =
        points.iter().map(|p| super::terms((p.0 .0 - long_off) / long_scale, (p.0 .1 - lat_off) / lat_scale, (p.0 .2 - height_off) / height_scale)).collect();
    // Ridge rows hold the denominator's 19 free coefficients near zero (den
    // near 1, as providers' RPCs are): unregularised, the fit trades the
    // denominator against the numerator and lets both pass through zero
    // over the scene, where the model folds.
    const RIDGE: f64 = 1e-3;
    let solve = |value: &dyn Fn(&Correspondence) -> f64| -> Option<([f64; 20], [f64; 20])> {
        let n = points.len();
        let mut a = nalgebra::DMatrix::<f64>::zeros(n + 19, 39);
        let mut b = nalgebra::DVector::<f64>::zeros(n + 19);
        let ridge = RIDGE * (n as f64).sqrt();
        for i in 0..19 {
            a[(n + i, 20 + i)] = ridge;
        }
        for (k, (p, t)) in points.iter().zip(&terms).enumerate() {
            let v = value(p);
            for i in 0..20 {
                a[(k, i)] = t[i];
            }
            for i in 1..20 {
                a[(k, 19 + i)] = -v * t[i];
            }
            b[k] = v;
        }
        let x = a.svd(true, true).solve(&b, 1e-15).ok()?;
        let mut num = [0.0; 20];
        let mut den = [0.0; 20];
        num.copy_from_slice(&x.as_slice()[..20]);
        den[0] = 1.0;
        den[1..].copy_from_slice(&x.as_slice()[20..39]);
        Some((num, den))
    };
    let (line_num, line_den) = solve(&|p| (p.1 .1 - 0.5 - line_off) / line_scale)?;
    let (samp_num, samp_den) = solve(&|p| (p.1 .0 - 0.5 - samp_off) / samp_scale)?;
    let rpc = Rpc {
        line_off,
        samp_off,
        lat_off,
        long_off,
        height_off,
        line_scale,
        samp_scale,
        lat_scale,
        long_scale,
        height_scale,
        line_num,
        line_den,
        samp_num,
        samp_den,
    };
    let mut worst = 0f64;
    for p in points {
        let (c, r) = rpc.project(p.0 .0, p.0 .1, p.0 .2)?;
        worst = worst.max((c - p.1 .0).hypot(r - p.1 .1));
    }
    Some(Fitted { rpc, max_residual_px: worst })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A real RPC, sampled and fitted again, comes back to the same
    /// mapping.
    #[test]
    fn refitting_a_real_rpc_reproduces_it() {
        let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/rpc/rpc_IKONOS.txt")).unwrap();
        let truth = Rpc::parse_text(&text, std::path::Path::new("rpc_IKONOS.txt")).unwrap();
        let mut pts = Vec::new();
        for i in 0..11 {
            for j in 0..11 {
                for k in 0..5 {
                    let lon = truth.long_off + truth.long_scale * (i as f64 / 5.0 - 1.0) * 0.8;
                    let lat = truth.lat_off + truth.lat_scale * (j as f64 / 5.0 - 1.0) * 0.8;
                    let h = truth.height_off + truth.height_scale * (k as f64 / 2.0 - 1.0) * 0.8;
                    pts.push(((lon, lat, h), truth.project(lon, lat, h).unwrap()));
                }
            }
        }
        let f = fit_rpc(&pts).unwrap();
        assert!(f.max_residual_px < 1e-3, "{}", f.max_residual_px);
        let p = (truth.long_off + 0.1 * truth.long_scale, truth.lat_off - 0.2 * truth.lat_scale, truth.height_off);
        let (a, b) = (truth.project(p.0, p.1, p.2).unwrap(), f.rpc.project(p.0, p.1, p.2).unwrap());
        assert!((a.0 - b.0).abs() < 1e-3 && (a.1 - b.1).abs() < 1e-3, "{a:?} {b:?}");
    }
}
