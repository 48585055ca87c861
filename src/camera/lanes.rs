//! One number or two in the lanes of a SIMD register, for the projection
//! formulas that `FrameCamera::project_many` runs two points at a time.
//! Both carry out the same IEEE operations in the same order, so a point
//! projects to the same bits either way.

use std::ops::{Add, Div, Mul, Sub};
use wide::{f64x2, CmpGt};

pub trait Lanes: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> {
    fn splat(v: f64) -> Self;
    fn sqrt(self) -> Self;
    /// `then` where `x > y`, else `otherwise` (NaN compares false).
    fn if_greater(x: Self, y: Self, then: Self, otherwise: Self) -> Self;
}

impl Lanes for f64 {
    #[inline(always)]
    fn splat(v: f64) -> f64 {
        v
    }
    #[inline(always)]
    fn sqrt(self) -> f64 {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn if_greater(x: f64, y: f64, then: f64, otherwise: f64) -> f64 {
        if x > y {
            then
        } else {
            otherwise
        }
    }
}

impl Lanes for f64x2 {
    #[inline(always)]
    fn splat(v: f64) -> f64x2 {
        f64x2::splat(v)
    }
    #[inline(always)]
    fn sqrt(self) -> f64x2 {
        f64x2::sqrt(self)
    }
    #[inline(always)]
    fn if_greater(x: f64x2, y: f64x2, then: f64x2, otherwise: f64x2) -> f64x2 {
        x.cmp_gt(y).blend(then, otherwise)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_lanes_compute_what_one_does() {
        let (a, b) = ([2.0, -3.5], [0.7, f64::NAN]);
        let (va, vb) = (f64x2::new(a), f64x2::new(b));
        let pick = <f64x2 as Lanes>::if_greater(va, vb, <f64x2 as Lanes>::sqrt(va * va + vb), va / vb).to_array();
        for k in 0..2 {
            let one = <f64 as Lanes>::if_greater(a[k], b[k], (a[k] * a[k] + b[k]).sqrt(), a[k] / b[k]);
            assert_eq!(one.to_bits(), pick[k].to_bits(), "lane {k}");
        }
        assert_eq!(pick[0], (4.0f64 + 0.7).sqrt());
        assert!(pick[1].is_nan(), "NaN compares false: the division");
    }
}
