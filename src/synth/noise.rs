//! Deterministic noise for the scene generator: integer hashing and value
//! noise with a quintic fade. Only +, −, ×, ÷ and floor, so the same seed
//! gives the same bytes on every IEEE-754 machine (no libm calls).

use crate::geom::floor_split;

#[inline]
pub fn hash(a: i64, b: i64, seed: u64) -> u64 {
    // SplitMix64 over a mix of the inputs.
    let mut z = seed.wrapping_add((a as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)).wrapping_add((b as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Uniform in [0, 1).
#[inline]
pub fn unit(a: i64, b: i64, seed: u64) -> f64 {
    (hash(a, b, seed) >> 11) as f64 / (1u64 << 53) as f64
}

#[inline]
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// Value noise in [0, 1), one lattice cell per unit.
#[inline]
pub fn value(x: f64, y: f64, seed: u64) -> f64 {
    let ((i, fx), (j, fy)) = (floor_split(x), floor_split(y));
    let (u, v) = (fade(x - fx), fade(y - fy));
    let a = unit(i, j, seed);
    let b = unit(i + 1, j, seed);
    let c = unit(i, j + 1, seed);
    let d = unit(i + 1, j + 1, seed);
    let top = a + u * (b - a);
    let bot = c + u * (d - c);
    top + v * (bot - top)
}

/// Fractal sum of `octaves` value noises, halving the wavelength each time;
/// result roughly in [0, 1).
pub fn fbm(x: f64, y: f64, octaves: u32, seed: u64) -> f64 {
    let (mut sum, mut amp, mut norm, mut f) = (0.0, 1.0, 0.0, 1.0);
    for o in 0..octaves {
        sum += amp * value(x * f, y * f, seed.wrapping_add(o as u64 * 7919));
        norm += amp;
        amp *= 0.5;
        f *= 2.0;
    }
    sum / norm
}

/// Value noise read from a table of lattice values (periodic, 256 cells a
/// side) instead of hashing four lattice points per sample: the texture's
/// fine noise is sampled once per scan pixel, where hashing dominated.
pub struct Lattice {
    /// Row-major, `N` × `N`; a fixed size so that masked indices need no
    /// bounds checks.
    v: Box<[f32; Lattice::N * Lattice::N]>,
}

impl Lattice {
    const N: usize = 256;

    pub fn new(seed: u64) -> Lattice {
        let n = Self::N as i64;
        Lattice::from_fn(|k| unit(k as i64 % n, k as i64 / n, seed) as f32)
    }

    fn from_fn(f: impl Fn(usize) -> f32) -> Lattice {
        let v: Vec<f32> = (0..Self::N * Self::N).map(f).collect();
        Lattice { v: v.into_boxed_slice().try_into().expect("N × N values") }
    }

    /// Value noise in [0, 1), one lattice cell per unit.
    #[inline]
    pub fn value(&self, x: f64, y: f64) -> f64 {
        let ((i, fi), (j, fj)) = (floor_split(x), floor_split(y));
        let (u, v) = (fade(x - fi), fade(y - fj));
        let m = Self::N - 1;
        let (i0, j0) = (i as usize & m, j as usize & m);
        let (i1, j1) = ((i0 + 1) & m, (j0 + 1) & m);
        let at = |i: usize, j: usize| self.v[(j * Self::N + i) & (Self::N * Self::N - 1)] as f64;
        let (a, b, c, d) = (at(i0, j0), at(i1, j0), at(i0, j1), at(i1, j1));
        let top = a + u * (b - a);
        let bot = c + u * (d - c);
        top + v * (bot - top)
    }

    /// Two octaves in one table: lattice values at twice the frequency
    /// holding a coarse value noise (period 128 cells) plus half as much
    /// fine noise, interpolated once per sample. Roughly in [0, 1).
    pub fn fbm2(seed: u64) -> Lattice {
        let coarse = Lattice::new(seed);
        let fine = Lattice::new(seed.wrapping_add(7919));
        let n = Self::N;
        Lattice::from_fn(|k| {
            let (i, j) = ((k % n) as f64, (k / n) as f64);
            // The result is itself a lattice, so it wraps continuously.
            let c = coarse.value((i / 2.0) % 128.0, (j / 2.0) % 128.0);
            ((c + 0.5 * fine.v[k] as f64) / 1.5) as f32
        })
    }
}

/// Ridged noise: sharp crests where the value noise crosses ½.
pub fn ridged(x: f64, y: f64, octaves: u32, seed: u64) -> f64 {
    let (mut sum, mut amp, mut norm, mut f) = (0.0, 1.0, 0.0, 1.0);
    for o in 0..octaves {
        let n = value(x * f, y * f, seed.wrapping_add(o as u64 * 104_729));
        let r = 1.0 - (2.0 * n - 1.0).abs();
        sum += amp * r * r;
        norm += amp;
        amp *= 0.45;
        f *= 2.0;
    }
    sum / norm
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_continuous_and_in_range() {
        let a = value(3.999999, 7.5, 1);
        let b = value(4.000001, 7.5, 1);
        assert!((a - b).abs() < 1e-4);
        for k in 0..1000 {
            let v = fbm(k as f64 * 0.37, k as f64 * 0.11, 4, 9);
            assert!((0.0..1.0).contains(&v));
        }
    }

    #[test]
    fn golden_hash() {
        // Pinned so that a change of the generator (and so of every
        // synthetic scene) is a conscious one: SplitMix64 worked out
        // independently (Python's integers, masked to 64 bits).
        assert_eq!(hash(1, 2, 3), 0xd297_569f_612b_30a7);
        assert_eq!(hash(2, 1, 3), 0xf208_7f1c_6615_ab94);
        assert_eq!(hash(-5, 7, 1), 0xad4d_2456_3847_47f9);
        assert_eq!(hash(0, 0, 0), 0);
        assert_eq!(unit(-5, 7, 1), (0xad4d_2456_3847_47f9u64 >> 11) as f64 / 9_007_199_254_740_992.0);
    }

    #[test]
    fn lattice_noise_is_continuous_periodic_and_drawn_from_the_seed() {
        let l = Lattice::new(5);
        // At lattice points it is the table value, i.e. `unit` of that point.
        assert_eq!(l.value(3.0, 7.0), unit(3, 7, 5) as f32 as f64);
        assert!((l.value(3.999999, 7.5) - l.value(4.000001, 7.5)).abs() < 1e-4);
        assert!((l.value(255.999999, 7.5) - l.value(256.000001, 7.5)).abs() < 1e-4, "wraps smoothly");
        assert!((l.value(10.3, -4.6) - l.value(10.3 + 256.0, -4.6 - 512.0)).abs() < 1e-9);
        let two = Lattice::fbm2(5);
        assert!((two.value(255.999999, 3.3) - two.value(256.000001, 3.3)).abs() < 1e-4, "wraps smoothly");
        for k in 0..1000 {
            let v = two.value(k as f64 * 0.37 - 50.0, k as f64 * 0.11);
            assert!((0.0..1.0).contains(&v), "{v}");
        }
    }
}
