//! How the film lay on the scanner: turned by a quarter turn (or none) and
//! perhaps mirrored (scanned through its base). The eight turns map the
//! photo's axes onto the scan's; a layout of marks that looks the same
//! under several of them cannot tell them apart.

use nalgebra::Matrix2;

/// One of the eight ways a film can lie on the scanner.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Turn {
    /// Quarter turns counter-clockwise of the photo in the scan (0–3).
    pub quarters: u8,
    /// Mirrored (the film scanned through its base).
    pub mirrored: bool,
}

impl Turn {
    pub const NONE: Turn = Turn { quarters: 0, mirrored: false };

    /// All eight, the one "as scanned" first.
    #[must_use]
    pub fn all() -> [Turn; 8] {
        let mut out = [Turn::NONE; 8];
        for (k, t) in out.iter_mut().enumerate() {
            *t = Turn { quarters: (k % 4) as u8, mirrored: k >= 4 };
        }
        out
    }

    /// Photo mm (x right, y up) → scan directions (column right, row
    /// down) at one pixel a millimetre.
    #[must_use]
    pub fn matrix(self) -> Matrix2<f64> {
        let flip = Matrix2::new(1.0, 0.0, 0.0, -1.0);
        let (s, c) = match self.quarters % 4 {
            0 => (0.0, 1.0),
            1 => (1.0, 0.0),
            2 => (0.0, -1.0),
            _ => (-1.0, 0.0),
        };
        let rot = Matrix2::new(c, -s, s, c);
        let mirror = if self.mirrored { Matrix2::new(-1.0, 0.0, 0.0, 1.0) } else { Matrix2::identity() };
        flip * rot * mirror
    }

    /// The turn a fitted photo → scan map (linear part) is nearest to.
    #[must_use]
    pub fn nearest(m: &Matrix2<f64>) -> Turn {
        let unit = m / m.determinant().abs().sqrt();
        Turn::all().into_iter().min_by(|a, b| (a.matrix() - unit).norm().total_cmp(&(b.matrix() - unit).norm())).expect("eight turns")
    }

    /// As the report says it.
    #[must_use]
    pub fn describe(self) -> String {
        let q = match self.quarters {
            0 => "not turned",
            1 => "turned 90° counter-clockwise",
            2 => "turned 180°",
            _ => "turned 90° clockwise",
        };
        if self.mirrored {
            format!("{q}, mirrored")
        } else {
            q.to_string()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_eight_turns_are_distinct_and_found_again() {
        let all = Turn::all();
        for (i, a) in all.iter().enumerate() {
            assert_eq!(Turn::nearest(&(a.matrix() * 47.6)), *a);
            for b in &all[i + 1..] {
                assert!((a.matrix() - b.matrix()).norm() > 1.0);
            }
        }
        // Photo +y (up) is scan row −1 (up) as scanned.
        let up = Turn::NONE.matrix() * nalgebra::Vector2::new(0.0, 1.0);
        assert_eq!((up.x, up.y), (0.0, -1.0));
    }
}
