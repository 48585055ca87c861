//! Rotation matrices of the exterior orientation in the three conventions the
//! camera file accepts, and the way back from a matrix to angles.
//!
//! Every convention produces the same object: `R`, which rotates photo-system
//! vectors `(x, y, −f)` into the ground frame (X east, Y north, Z up), so that
//! `(x − x0, y − y0, −f) ∝ Rᵀ (ΔX, ΔY, ΔZ)`. Written with the thesis' names,
//! the rows of `R` are `(a1 a2 a3)`, `(b1 b2 b3)`, `(c1 c2 c3)`.
//!
//! * `alpha-omega-kappa` (thesis eq. 2.1.1): `R = A_α A_ω A_κ` with
//!   `A_α = R_y(−α)`, `A_ω = R_x(ω)`, `A_κ = R_z(κ)`.
//! * `omega-phi-kappa` (western): `R = R_x(ω) R_y(φ) R_z(κ)`.
//! * `omega-alpha-chi` (Dobrynin and Pimshina, eq. 1): multiplying out its nine direction
//!   cosines gives exactly `R_x(ω) R_y(α) R_z(χ)` — the ω-φ-κ matrix with
//!   φ = α and κ = χ. The two are the same convention under other names.
//!
//! with `R_x(t) = [[1,0,0],[0,c,−s],[0,s,c]]`, `R_y(t) = [[c,0,s],[0,1,0],[−s,0,c]]`,
//! `R_z(t) = [[c,−s,0],[s,c,0],[0,0,1]]`.

use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

/// Which angles the camera file's `angles_deg` are.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AngleConvention {
    AlphaOmegaKappa,
    OmegaAlphaChi,
    OmegaPhiKappa,
}

fn rx(t: f64) -> Matrix3<f64> {
    let (s, c) = t.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}
fn ry(t: f64) -> Matrix3<f64> {
    let (s, c) = t.sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}
fn rz(t: f64) -> Matrix3<f64> {
    let (s, c) = t.sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

impl AngleConvention {
    /// The rotation matrix `R` of three angles (radians) given in this
    /// convention's order: (α, ω, κ), (ω, α, χ) or (ω, φ, κ).
    #[must_use]
    pub fn matrix(self, angles: [f64; 3]) -> Matrix3<f64> {
        match self {
            AngleConvention::AlphaOmegaKappa => ry(-angles[0]) * rx(angles[1]) * rz(angles[2]),
            AngleConvention::OmegaAlphaChi | AngleConvention::OmegaPhiKappa => rx(angles[0]) * ry(angles[1]) * rz(angles[2]),
        }
    }

    /// The angles (radians, this convention's order) of a rotation matrix.
    /// At the gimbal lock (middle angle ±90°) the first angle is set to 0.
    #[must_use]
    pub fn angles(self, r: &Matrix3<f64>) -> [f64; 3] {
        match self {
            AngleConvention::AlphaOmegaKappa => {
                // b3 = −sin ω; a3 = −sin α cos ω, c3 = cos α cos ω;
                // b1 = cos ω sin κ, b2 = cos ω cos κ.
                let omega = (-r[(1, 2)]).clamp(-1.0, 1.0).asin();
                if r[(1, 2)].abs() > 1.0 - 1e-12 {
                    // cos ω = 0: α and κ rotate about the same axis; take α = 0,
                    // then R = R_x(ω) R_z(κ) and its first row is (cκ, −sκ, 0).
                    let kappa = (-r[(0, 1)]).atan2(r[(0, 0)]);
                    return [0.0, omega, kappa];
                }
                let alpha = (-r[(0, 2)]).atan2(r[(2, 2)]);
                let kappa = r[(1, 0)].atan2(r[(1, 1)]);
                [alpha, omega, kappa]
            }
            AngleConvention::OmegaAlphaChi | AngleConvention::OmegaPhiKappa => {
                // a3 = sin φ; b3 = −sin ω cos φ, c3 = cos ω cos φ;
                // a1 = cos φ cos κ, a2 = −cos φ sin κ.
                let phi = r[(0, 2)].clamp(-1.0, 1.0).asin();
                if r[(0, 2)].abs() > 1.0 - 1e-12 {
                    let kappa = r[(1, 0)].atan2(r[(1, 1)]);
                    return [0.0, phi, kappa];
                }
                let omega = (-r[(1, 2)]).atan2(r[(2, 2)]);
                let kappa = (-r[(0, 1)]).atan2(r[(0, 0)]);
                [omega, phi, kappa]
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The thesis' nine direction cosines, typed from Beloshapkin's thesis (eq. 2.1.1).
    fn thesis(alpha: f64, omega: f64, kappa: f64) -> Matrix3<f64> {
        let (sa, ca) = alpha.sin_cos();
        let (sw, cw) = omega.sin_cos();
        let (sk, ck) = kappa.sin_cos();
        Matrix3::new(ca * ck - sa * sw * sk, -ca * sk - sa * sw * ck, -sa * cw, cw * sk, cw * ck, -sw, sa * ck + ca * sw * sk, -sa * sk + ca * sw * ck, ca * cw)
    }

    /// Dobrynin and Pimshina, eq. (1), typed from their paper.
    fn seed001(omega: f64, alpha: f64, chi: f64) -> Matrix3<f64> {
        let (sa, ca) = alpha.sin_cos();
        let (sw, cw) = omega.sin_cos();
        let (sk, ck) = chi.sin_cos();
        Matrix3::new(ca * ck, -ca * sk, sa, sw * sa * ck + cw * sk, -sw * sa * sk + cw * ck, -sw * ca, -cw * sa * ck + sw * sk, cw * sa * sk + sw * ck, cw * ca)
    }

    #[test]
    fn thesis_matrix_matches_its_direction_cosines() {
        let (a, w, k) = (0.03, -0.02, 1.2);
        let m = AngleConvention::AlphaOmegaKappa.matrix([a, w, k]);
        assert!((m - thesis(a, w, k)).norm() < 1e-15);
    }

    #[test]
    fn seed001_is_omega_phi_kappa() {
        let (w, a, x) = (0.05, -0.07, 2.5);
        let m = AngleConvention::OmegaAlphaChi.matrix([w, a, x]);
        assert!((m - seed001(w, a, x)).norm() < 1e-15);
        assert!((m - AngleConvention::OmegaPhiKappa.matrix([w, a, x])).norm() < 1e-15);
    }

    #[test]
    fn angles_round_trip_in_every_convention() {
        for conv in [AngleConvention::AlphaOmegaKappa, AngleConvention::OmegaAlphaChi, AngleConvention::OmegaPhiKappa] {
            for angles in [[0.01, -0.02, 0.3], [0.2, 0.1, -2.9], [-0.4, 0.3, 1.5]] {
                let m = conv.matrix(angles);
                let back = conv.angles(&m);
                assert!((conv.matrix(back) - m).norm() < 1e-12, "{conv:?} {angles:?}");
                for i in 0..3 {
                    assert!((back[i] - angles[i]).abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn conversion_between_conventions_keeps_the_matrix() {
        let m = AngleConvention::AlphaOmegaKappa.matrix([0.02, -0.015, 0.52]);
        let opk = AngleConvention::OmegaPhiKappa.angles(&m);
        assert!((AngleConvention::OmegaPhiKappa.matrix(opk) - m).norm() < 1e-14);
    }
}
