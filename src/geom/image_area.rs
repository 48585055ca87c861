//! The part of a scan that holds the image: for a film scan, the camera's
//! calibrated format (the frame), a parallelogram in scan pixels — the
//! affine image of the format's rectangle in photo millimetres. Outside it
//! (the film's margin, the fiducial marks, the data strip) no output pixel
//! takes a value.

/// A parallelogram in scan pixel coordinates (column, row; pixel (0, 0)
/// covers [0, 1)²): the points `p0 + s·du + t·dv` with s, t in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageArea {
    /// (s, t) of a point, as `[a, b, c]` with s = a·col + b·row + c.
    s: [f64; 3],
    t: [f64; 3],
    corners: [(f64, f64); 4],
}

impl ImageArea {
    /// The parallelogram at `p0` spanned by `du` and `dv`; `None` where
    /// they are (nearly) parallel or not finite.
    pub fn parallelogram(p0: (f64, f64), du: (f64, f64), dv: (f64, f64)) -> Option<ImageArea> {
        let det = du.0 * dv.1 - du.1 * dv.0;
        let scale = (du.0.hypot(du.1) * dv.0.hypot(dv.1)).max(f64::MIN_POSITIVE);
        if !(det.abs() > 1e-9 * scale) || !det.is_finite() || ![p0.0, p0.1].iter().all(|v| v.is_finite()) {
            return None;
        }
        // (c, r) − p0 = s·du + t·dv, solved by Cramer's rule.
        let s = [dv.1 / det, -dv.0 / det, (dv.0 * p0.1 - dv.1 * p0.0) / det];
        let t = [-du.1 / det, du.0 / det, (du.1 * p0.0 - du.0 * p0.1) / det];
        let corners = [p0, (p0.0 + du.0, p0.1 + du.1), (p0.0 + du.0 + dv.0, p0.1 + du.1 + dv.1), (p0.0 + dv.0, p0.1 + dv.1)];
        Some(ImageArea { s, t, corners })
    }

    /// Whether scan position (c, r) lies in the area (its edges included, to
    /// rounding).
    #[inline(always)]
    pub fn contains(&self, c: f64, r: f64) -> bool {
        let s = self.s[0] * c + self.s[1] * r + self.s[2];
        let t = self.t[0] * c + self.t[1] * r + self.t[2];
        (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t)
    }

    /// Whether the whole rectangle `[x0, x1] × [y0, y1]` lies in the area
    /// (it is convex: the rectangle's corners tell).
    pub fn contains_rect(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> bool {
        [(x0, y0), (x1, y0), (x1, y1), (x0, y1)].iter().all(|&(c, r)| self.contains(c, r))
    }

    /// Whether the whole rectangle lies in the area with room to spare (a
    /// billionth of the area's size on every side): every point of it then
    /// passes [`ImageArea::contains`] whatever its rounding.
    pub fn holds_rect_with_room(&self, x0: f64, y0: f64, x1: f64, y1: f64) -> bool {
        const ROOM: f64 = 1e-9;
        [(x0, y0), (x1, y0), (x1, y1), (x0, y1)].iter().all(|&(c, r)| {
            let s = self.s[0] * c + self.s[1] * r + self.s[2];
            let t = self.t[0] * c + self.t[1] * r + self.t[2];
            (ROOM..=1.0 - ROOM).contains(&s) && (ROOM..=1.0 - ROOM).contains(&t)
        })
    }

    /// The four corners, in order around the area.
    pub fn corners(&self) -> [(f64, f64); 4] {
        self.corners
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_turned_parallelogram_holds_its_inside_and_edges_only() {
        // A 100 × 60 rectangle turned by 30°, at (50, 20).
        let (cs, sn) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let a = ImageArea::parallelogram((50.0, 20.0), (100.0 * cs, 100.0 * sn), (-60.0 * sn, 60.0 * cs)).unwrap();
        let at = |s: f64, t: f64| (50.0 + s * 100.0 * cs - t * 60.0 * sn, 20.0 + s * 100.0 * sn + t * 60.0 * cs);
        for (s, t, inside) in
            [(0.5, 0.5, true), (0.001, 0.001, true), (0.999, 0.999, true), (0.999, 0.001, true), (1.001, 0.5, false), (0.5, -0.001, false), (-0.2, 1.2, false)]
        {
            let (c, r) = at(s, t);
            assert_eq!(a.contains(c, r), inside, "{s} {t}");
        }
        let (c, r) = at(0.5, 0.5);
        assert!(a.contains_rect(c - 5.0, r - 5.0, c + 5.0, r + 5.0));
        assert!(!a.contains_rect(c - 70.0, r - 5.0, c + 70.0, r + 5.0));
        assert!(a.holds_rect_with_room(c - 5.0, r - 5.0, c + 5.0, r + 5.0));
        // A corner on the edge: held (`contains`), but with no room.
        let (ec, er) = at(1.0, 0.5);
        assert!(a.contains_rect(ec - 1e-3, er, ec, er) && !a.holds_rect_with_room(ec - 1e-3, er, ec, er));
        assert_eq!(a.corners()[2], at(1.0, 1.0));
        assert!(ImageArea::parallelogram((0.0, 0.0), (1.0, 2.0), (2.0, 4.0)).is_none(), "degenerate");
    }
}
