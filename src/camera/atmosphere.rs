//! Atmospheric refraction and earth curvature (thesis §2.3, eq. 2.3.5–2.3.13).
//!
//! Refraction bends the ray so that the image point moves *away* from the
//! nadir point by `Δr = λ·f·(1 + tan²ζ)` (the thesis' `λ(f + r²/f)` for a
//! vertical photo), with the deviation angle `λ` from
//! * Aschenbrenner (2.3.5): `λ″ = 3.1·L·(1 − 0.035·(3·Ha − H))`, L the
//!   horizontal distance from the nadir to the point, H the flying height
//!   above the point, Ha above sea level (km) — for Ha up to ~5 km;
//! * Kushtin (2.3.6) for 5–11 km and (2.3.7) for 11–70 km (ICAO standard
//!   atmosphere: −56.5 °C above 11 km).
//!
//! Earth curvature lowers a point at horizontal distance D from the nadir by
//! `D²/2R` in the camera's tangent frame; we apply it in object space, which
//! for vertical photos is the thesis' image-space term and stays right for
//! tilted ones.

use super::lanes::Lanes;
use serde::{Deserialize, Serialize};

/// Mean earth radius, metres.
pub const EARTH_RADIUS_M: f64 = 6_371_000.0;
const ARCSEC: f64 = std::f64::consts::PI / (180.0 * 3600.0);
/// ICAO standard-atmosphere temperature above 11 km, kelvin.
const T_STRATOSPHERE_K: f64 = 216.65;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Refraction {
    None,
    Aschenbrenner,
    Kushtin,
    /// Aschenbrenner up to 5 km flying height, Kushtin above (as the thesis).
    Auto,
}

/// Aschenbrenner (2.3.5), arc seconds. All heights and `l_km` in km; one
/// number or two in SIMD lanes.
#[must_use]
#[inline(always)]
pub fn aschenbrenner_arcsec<T: Lanes>(ha_km: T, h_km: T, l_km: T) -> T {
    T::splat(3.1) * l_km * (T::splat(1.0) - T::splat(0.035) * (T::splat(3.0) * ha_km - h_km))
}

/// Kushtin, arc seconds: (2.3.6) below 11 km, (2.3.7) from 11 to 70 km.
/// `ha_km` camera and `hg_km` ground heights above sea level.
#[must_use]
pub fn kushtin_arcsec(ha_km: f64, hg_km: f64, tan_zeta: f64) -> f64 {
    let dh = ha_km - hg_km;
    let ground = (1.0 - 0.02257 * hg_km).powf(5.253);
    if ha_km <= 11.0 {
        let air = (1.0 + 34.14 * dh / (288.0 - 6.5 * ha_km)) * (1.0 - 0.02257 * ha_km).powf(5.253);
        481.3 * tan_zeta / dh * (ground - air)
    } else {
        let (t, ts) = (T_STRATOSPHERE_K, T_STRATOSPHERE_K);
        tan_zeta * (481.3 / dh * ground - (108.0 / dh + 3686.0 / ts) * (-34.15 * (ha_km - 11.0) / t).exp())
    }
}

impl Refraction {
    /// The ray's deviation angle (radians) for a camera at `ha_m`, a ground
    /// point at `hg_m` (metres above sea level) seen at nadir angle ζ.
    #[must_use]
    #[inline]
    pub fn angle(self, ha_m: f64, hg_m: f64, tan_zeta: f64) -> f64 {
        tan_zeta * self.angle_per_tan(ha_m, hg_m)
    }

    /// `angle / tan ζ`: every formula is linear in tan ζ (Aschenbrenner's
    /// L is the height difference times tan ζ), so a projection can fold
    /// tan ζ into its other square roots and divisions.
    #[must_use]
    #[inline]
    pub fn angle_per_tan(self, ha_m: f64, hg_m: f64) -> f64 {
        if self.is_aschenbrenner_at(ha_m) {
            return Refraction::aschenbrenner_per_tan(ha_m, hg_m);
        }
        let (ha, hg) = (ha_m * 1e-3, hg_m * 1e-3);
        if ha <= hg || self == Refraction::None {
            return 0.0;
        }
        kushtin_arcsec(ha, hg, 1.0) * ARCSEC
    }

    /// Does a camera at `ha_m` use Aschenbrenner's formula?
    #[must_use]
    #[inline]
    pub fn is_aschenbrenner_at(self, ha_m: f64) -> bool {
        match self {
            Refraction::Aschenbrenner => true,
            Refraction::Auto => ha_m * 1e-3 <= 5.0,
            Refraction::None | Refraction::Kushtin => false,
        }
    }

    /// Aschenbrenner's λ / tanζ (radians), without a branch: 0 for a ground
    /// point at or above the camera.
    #[must_use]
    #[inline(always)]
    pub fn aschenbrenner_per_tan<T: Lanes>(ha_m: T, hg_m: T) -> T {
        let (ha, hg) = (ha_m * T::splat(1e-3), hg_m * T::splat(1e-3));
        let arcsec = aschenbrenner_arcsec(ha, ha - hg, ha - hg);
        T::if_greater(ha, hg, arcsec * T::splat(ARCSEC), T::splat(0.0))
    }
}

/// How much lower a point at horizontal distance `d_m` from the nadir lies
/// in the camera's tangent frame, metres.
#[inline]
#[must_use]
pub fn curvature_drop(d2_m2: f64) -> f64 {
    d2_m2 * (0.5 / EARTH_RADIUS_M)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn aschenbrenner_matches_thesis_2_3_8() {
        // 2.3.8: Δr[µm] = 0.0151·H·r·(1 + r²/f²)·(1 − 0.035(3Ha − H)),
        // the thesis' own reduction of 2.3.5 for a vertical photo, H in km,
        // r and f in mm. Check our λ·f·(1 + tan²ζ) against it.
        let (f, r, ha, hg) = (152.0_f64, 100.0_f64, 3000.0_f64, 200.0_f64);
        let h = (ha - hg) / 1000.0;
        let tan_z = r / f;
        let lambda = Refraction::Aschenbrenner.angle(ha, hg, tan_z);
        let dr_um = lambda * f * (1.0 + tan_z * tan_z) * 1000.0;
        let thesis = 0.0151 * h * r * (1.0 + r * r / (f * f)) * (1.0 - 0.035 * (3.0 * ha / 1000.0 - h));
        // 0.0151 is 3.1/206.265 rounded: agree to 0.5 %.
        assert!((dr_um / thesis - 1.0).abs() < 5e-3, "{dr_um} vs {thesis}");
    }

    #[test]
    fn kushtin_hand_values() {
        // Ha = 8 km, Hg = 0: (1) − (1 + 34.14·8/236)·(0.81944)^5.253
        // = 1 − 2.1572881·0.3513222 = 0.2421 (to 7 digits: 0.24210...);
        // λ″ = 481.3·0.24210/8 = 14.5651 tanζ.
        let l = kushtin_arcsec(8.0, 0.0, 1.0);
        assert!((l - 14.5651).abs() < 1e-3, "{l}");
        // The two branches meet at 11 km within 1 % (thesis: "незначительное
        // несовпадение" at the 5 km seam only).
        let below = kushtin_arcsec(11.0, 0.0, 1.0);
        let above = kushtin_arcsec(11.0 + 1e-9, 0.0, 1.0);
        assert!((below / above - 1.0).abs() < 0.01, "{below} {above}");
    }

    #[test]
    fn auto_switches_at_5_km() {
        let a = Refraction::Auto.angle(4000.0, 0.0, 0.5);
        assert_eq!(a, Refraction::Aschenbrenner.angle(4000.0, 0.0, 0.5));
        let k = Refraction::Auto.angle(9000.0, 0.0, 0.5);
        assert_eq!(k, Refraction::Kushtin.angle(9000.0, 0.0, 0.5));
        assert_eq!(Refraction::None.angle(9000.0, 0.0, 0.5), 0.0);
    }

    #[test]
    fn curvature_drop_one_km() {
        // 1 km from the nadir: 1e6 / (2·6371000) = 0.078480 m.
        assert!((curvature_drop(1e6) - 0.0784806).abs() < 1e-6);
    }
}
