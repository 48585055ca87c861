//! Images whose content does not match their neighbours' where they
//! overlap: a wrong camera or pose (another image's, a heading turned, a
//! position in the wrong CRS) still gives a plausible mosaic, with the
//! image's ground in the wrong place. Told from the thumbnails' overlaps
//! (the balance's sums): an image none of whose overlaps correlates.

use super::balance::Pair;
use super::plan::Plan;
use crate::io::format::SampleType;

/// Below this correlation with every image it overlaps, an image is
/// doubted. Overlaps of one ground correlate at 0.8–1 on the plan's cells
/// (relief and exposure lower it little); a frame shifted by a tenth of
/// its side, or turned, falls near 0.
const LEAST: f64 = 0.5;

/// One line per doubted image: its best correlation, and with whom.
pub fn doubted(plan: &Plan, pairs: &[Pair]) -> Vec<String> {
    let n = plan.images.len();
    // Integer samples vary by a level at least where anything is there.
    let least_sd = match plan.images.first().map(|i| i.sample) {
        Some(SampleType::F32) | None => 0.0,
        _ => 1.0,
    };
    let mut best: Vec<Option<(f64, usize)>> = vec![None; n];
    for (i, j, sums) in pairs {
        let rs: Vec<f64> = sums.iter().filter_map(|s| s.correlation(least_sd)).collect();
        if rs.is_empty() {
            continue;
        }
        let r = rs.iter().sum::<f64>() / rs.len() as f64;
        for (k, other) in [(*i, *j), (*j, *i)] {
            if best[k].is_none_or(|(b, _)| r > b) {
                best[k] = Some((r, other));
            }
        }
    }
    let name = |k: usize| plan.images[k].opts.inputs.image.display().to_string();
    best.iter()
        .enumerate()
        .filter_map(|(k, b)| {
            let (r, other) = b.filter(|(r, _)| *r < LEAST)?;
            Some(format!(
                "{}: where it overlaps its neighbours it does not show what they show (correlation {r:.2} at best, with {}): a wrong camera or pose? (water or moving things alone can do this)",
                name(k),
                name(other)
            ))
        })
        .collect()
}
