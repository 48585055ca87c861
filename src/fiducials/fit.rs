//! The interior orientation from the marks found: a least-squares affine
//! map (textbook 9.27), marks that sit off it left out one at a time while
//! more remain than the map needs, and the checks that keep a bad fit from
//! passing silently: every residual within the limit, and a scanner's map
//! (nearly square pixels, nearly perpendicular axes).

use crate::geom::Affine2;

/// The fit over the kept marks.
#[derive(Clone, Debug)]
pub struct Fit {
    pub map: Affine2,
    /// Indices (into the marks given) of the marks kept.
    pub kept: Vec<usize>,
    /// Residual of every mark given (measured − fitted, px), kept or not.
    pub residuals_px: Vec<[f64; 2]>,
}

/// Fits photo mm → scan px through `marks` (index, mm, px), leaving out
/// the mark that sits worst off the map fitted without it while it sits
/// more than `limit_px` off and more than four marks remain.
#[must_use]
pub fn robust_affine(marks: &[(usize, [f64; 2], [f64; 2])], limit_px: f64) -> Option<Fit> {
    let mut kept: Vec<usize> = (0..marks.len()).collect();
    loop {
        let mm: Vec<[f64; 2]> = kept.iter().map(|&k| marks[k].1).collect();
        let px: Vec<[f64; 2]> = kept.iter().map(|&k| marks[k].2).collect();
        let map = Affine2::fit(&mm, &px)?;
        let off = |m: &Affine2, k: usize| {
            let (x, y) = m.apply(marks[k].1[0], marks[k].1[1]);
            [marks[k].2[0] - x, marks[k].2[1] - y]
        };
        let worst = kept.iter().map(|&k| (k, norm(off(&map, k)))).max_by(|a, b| a.1.total_cmp(&b.1))?;
        if worst.1 <= limit_px || kept.len() <= 4 {
            let residuals_px = (0..marks.len()).map(|k| off(&map, k)).collect();
            return Some(Fit { map, kept: kept.iter().map(|&k| marks[k].0).collect(), residuals_px });
        }
        // The mark that the others' map puts furthest from where it was found.
        let drop = kept
            .iter()
            .filter_map(|&k| {
                let rest: Vec<usize> = kept.iter().copied().filter(|&j| j != k).collect();
                let m = Affine2::fit(&rest.iter().map(|&j| marks[j].1).collect::<Vec<_>>(), &rest.iter().map(|&j| marks[j].2).collect::<Vec<_>>())?;
                Some((k, norm(off(&m, k))))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1))?
            .0;
        kept.retain(|&k| k != drop);
    }
}

fn norm(v: [f64; 2]) -> f64 {
    v[0].hypot(v[1])
}

/// What a scanner's map cannot be: pixels more than 2 % longer one way,
/// or axes more than 1° off perpendicular. None when it is plausible.
#[must_use]
pub fn implausible(map: &Affine2) -> Option<String> {
    let (a, b) = (map.m.column(0), map.m.column(1));
    let ratio = a.norm() / b.norm();
    let skew = (a.dot(&b) / (a.norm() * b.norm())).asin().to_degrees().abs();
    if (ratio - 1.0).abs() > 0.02 {
        return Some(format!("the marks make pixels {:.1} % longer one way than the other", (ratio.max(1.0 / ratio) - 1.0) * 100.0));
    }
    if skew > 1.0 {
        return Some(format!("the marks make the photo's axes {:.2}° off perpendicular", skew));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan(mm: [f64; 2]) -> [f64; 2] {
        [5000.0 + 47.6 * mm[0] + 0.1 * mm[1], 5000.0 - 47.7 * mm[1] + 0.1 * mm[0]]
    }

    #[test]
    fn a_mark_off_by_three_pixels_is_left_out_of_eight() {
        let d = 113.0;
        let mm = [[-d, -d], [d, d], [-d, d], [d, -d], [-d, 0.0], [d, 0.0], [0.0, d], [0.0, -d]];
        let mut marks: Vec<(usize, [f64; 2], [f64; 2])> = mm.iter().enumerate().map(|(k, &m)| (k, m, scan(m))).collect();
        marks[5].2[1] += 3.0;
        let fit = robust_affine(&marks, 0.5).unwrap();
        assert_eq!(fit.kept, vec![0, 1, 2, 3, 4, 6, 7]);
        assert!((fit.residuals_px[5][1] - 3.0).abs() < 1e-6);
        assert!(implausible(&fit.map).is_none());
        // Four marks cannot show which one is wrong: all are kept.
        let four = robust_affine(&marks[..4].iter().map(|m| (m.0, m.1, m.2)).collect::<Vec<_>>(), 0.5).unwrap();
        assert_eq!(four.kept.len(), 4);
    }

    #[test]
    fn a_sheared_map_is_implausible() {
        let map = Affine2 { m: nalgebra::Matrix2::new(47.6, 3.0, 0.0, -47.6), t: nalgebra::Vector2::zeros() };
        assert!(implausible(&map).unwrap().contains("perpendicular"));
    }
}
