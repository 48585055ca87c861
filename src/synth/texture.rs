//! The ground's appearance as a function of (X, Y): fields of different
//! crops with dark boundaries (sharp lines), roads, fine texture noise and a
//! few unique landmarks. Features are sized from the GSD so that they are
//! resolved (no aliasing) yet sharp. Colours in [0, 1].

use super::noise::{hash, unit, Lattice};
use crate::geom::floor_split;

pub struct Texture {
    seed: u64,
    gsd: f64,
    /// 1 / gsd, and 1 / the fine noise's wavelength (24 GSD).
    inv_gsd: f64,
    inv_wave: f64,
    noise: Lattice,
    /// Field size, metres, and the reciprocals of its width and height.
    field: f64,
    inv_field: (f64, f64),
    /// Rotation of the field pattern (cos, sin).
    rot: (f64, f64),
    roads: Vec<Road>,
    landmarks: Vec<(f64, f64, f64)>,
    /// Which roads (bits 0–3) and landmarks (bits 4–15) can touch each cell
    /// of a coarse grid over the scene, so that a sample looks only at those.
    near: FeatureGrid,
}

/// A square grid of `n`² cells from (x0, y0) (south-west corner), each with
/// a bit mask of the features that reach into it; points outside it see all.
struct FeatureGrid {
    x0: f64,
    y0: f64,
    inv_cell: f64,
    n: usize,
    masks: Vec<u16>,
}

impl FeatureGrid {
    #[inline]
    fn mask(&self, x: f64, y: f64) -> u16 {
        let (i, j) = ((x - self.x0) * self.inv_cell, (y - self.y0) * self.inv_cell);
        if i >= 0.0 && j >= 0.0 && i < self.n as f64 && j < self.n as f64 {
            self.masks[j as usize * self.n + i as usize]
        } else {
            u16::MAX
        }
    }
}

struct Road {
    x: f64,
    y: f64,
    dx: f64,
    dy: f64,
    half: f64,
}

const PALETTE: [[f32; 3]; 6] = [[0.32, 0.45, 0.20], [0.55, 0.50, 0.28], [0.70, 0.62, 0.35], [0.25, 0.35, 0.18], [0.45, 0.38, 0.26], [0.60, 0.58, 0.40]];

/// (cos, sin) of the angle whose half-angle tangent is `t` (rational, so
/// exactly reproducible).
fn rational_rotation(t: f64) -> (f64, f64) {
    let d = 1.0 + t * t;
    ((1.0 - t * t) / d, 2.0 * t / d)
}

impl Texture {
    /// A texture for a scene centred at (cx, cy) with extent `size` metres.
    pub fn new(seed: u64, gsd: f64, cx: f64, cy: f64, size: f64) -> Texture {
        let u = |k: i64| unit(k, 17, seed);
        let field = 90.0 * gsd.max(0.02);
        let rot = rational_rotation(u(1) * 0.6 - 0.3);
        let roads: Vec<Road> = (0..4)
            .map(|k| {
                let (c, s) = rational_rotation(u(10 + k) * 2.0 - 1.0);
                Road { x: cx + (u(20 + k) - 0.5) * size * 0.6, y: cy + (u(30 + k) - 0.5) * size * 0.6, dx: c, dy: s, half: gsd * (2.0 + 3.0 * u(40 + k)) }
            })
            .collect();
        let landmarks: Vec<(f64, f64, f64)> =
            (0..12).map(|k| (cx + (u(50 + k) - 0.5) * size * 0.8, cy + (u(70 + k) - 0.5) * size * 0.8, gsd * (6.0 + 10.0 * u(90 + k)))).collect();
        // Cells of the feature grid: a 64×64 grid over twice the scene's size.
        let n = 64usize;
        let cell = 2.0 * size / n as f64;
        let (gx0, gy0) = (cx - size, cy - size);
        let half_diag = cell * std::f64::consts::FRAC_1_SQRT_2;
        let masks = (0..n * n)
            .map(|k| {
                let (mx, my) = (gx0 + ((k % n) as f64 + 0.5) * cell, gy0 + ((k / n) as f64 + 0.5) * cell);
                let mut m = 0u16;
                for (b, r) in roads.iter().enumerate() {
                    let d = ((mx - r.x) * r.dy - (my - r.y) * r.dx).abs();
                    if d <= half_diag + r.half + 2.0 * gsd {
                        m |= 1 << b;
                    }
                }
                for (b, &(lx, ly, rad)) in landmarks.iter().enumerate() {
                    if ((mx - lx).powi(2) + (my - ly).powi(2)).sqrt() <= half_diag + rad + 2.0 * gsd {
                        m |= 1 << (4 + b);
                    }
                }
                m
            })
            .collect();
        let near = FeatureGrid { x0: gx0, y0: gy0, inv_cell: 1.0 / cell, n, masks };
        Texture {
            near,
            seed,
            gsd,
            inv_gsd: 1.0 / gsd,
            inv_wave: 1.0 / (24.0 * gsd),
            noise: Lattice::fbm2(seed ^ 0x5eed),
            field,
            inv_field: (1.0 / field, 1.0 / (0.7 * field)),
            rot,
            roads,
            landmarks,
        }
    }

    /// Colour at ground (X, Y).
    pub fn rgb(&self, x: f64, y: f64) -> [f32; 3] {
        let (g, ig) = (self.gsd, self.inv_gsd);
        // Fields on a rotated grid, rows 0.7 as tall as wide.
        let (c, s) = self.rot;
        let xr = (c * x + s * y) * self.inv_field.0;
        let yr = (-s * x + c * y) * self.inv_field.1;
        let ((ki, fi), (kj, fj)) = (floor_split(xr), floor_split(yr));
        let base = PALETTE[(hash(ki, kj, self.seed) % PALETTE.len() as u64) as usize];
        // Fine texture: ±20 % brightness, wavelengths of 24 and 12 GSD.
        let n = self.noise.value(2.0 * x * self.inv_wave, 2.0 * y * self.inv_wave) as f32;
        let mut col = base.map(|v| v * (0.8 + 0.4 * n));
        // Field boundaries: dark lines 2 GSD wide, anti-aliased over 1 GSD.
        let dx = (xr - fi).min(fi + 1.0 - xr) * self.field;
        let dy = (yr - fj).min(fj + 1.0 - yr) * 0.7 * self.field;
        let edge = coverage(dx.min(dy) * ig);
        col = mix(col, [0.12, 0.11, 0.10], 0.8 * edge);
        let near = self.near.mask(x, y);
        for r in bits(near & 0xf).map(|b| &self.roads[b]) {
            let d = ((x - r.x) * r.dy - (y - r.y) * r.dx).abs() - r.half;
            let cov = coverage(d.max(0.0) * ig + 1.0);
            if cov > 0.0 {
                col = mix(col, [0.82, 0.80, 0.76], cov);
            }
        }
        for &(lx, ly, rad) in bits(near >> 4).map(|b| &self.landmarks[b]) {
            let reach = rad + 2.0 * g;
            let d2 = (x - lx) * (x - lx) + (y - ly) * (y - ly);
            if d2 < reach * reach {
                let d = d2.sqrt();
                // White disc with a black ring at 0.6 of the radius.
                let disc = coverage((d - rad).max(0.0) * ig + 1.0);
                col = mix(col, [0.95, 0.95, 0.95], disc);
                let ring = coverage(((d - 0.6 * rad).abs() - 0.1 * rad) * ig + 1.0);
                col = mix(col, [0.05, 0.05, 0.05], ring * disc);
            }
        }
        col
    }
}

/// The indices of the bits set in `m`, lowest first.
#[inline]
fn bits(mut m: u16) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (m != 0).then(|| {
            let b = m.trailing_zeros() as usize;
            m &= m - 1;
            b
        })
    })
}

/// 1 within one GSD of a line (`t`: the distance in GSD), falling linearly
/// to 0 over one more.
#[inline]
fn coverage(t: f64) -> f32 {
    (2.0 - t).clamp(0.0, 1.0) as f32
}

#[inline]
fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_feature_grid_names_every_feature_near_a_point() {
        let gsd = 0.12;
        let t = Texture::new(3, gsd, 650_000.0, 4_890_000.0, 2300.0);
        // On and just beside every road and landmark, its bit is set.
        for (b, r) in t.roads.iter().enumerate() {
            for s in -200..=200 {
                let along = s as f64 * 7.3;
                for off in [0.0, r.half + 1.5 * gsd, -(r.half + 1.5 * gsd)] {
                    let (x, y) = (r.x + along * r.dx - off * r.dy, r.y + along * r.dy + off * r.dx);
                    assert!(t.near.mask(x, y) & (1 << b) != 0, "road {b} at ({x}, {y})");
                }
            }
        }
        for (b, &(lx, ly, rad)) in t.landmarks.iter().enumerate() {
            for a in 0..16 {
                let ang = a as f64 * std::f64::consts::TAU / 16.0;
                let d = rad + 1.9 * gsd;
                assert!(t.near.mask(lx + d * ang.cos(), ly + d * ang.sin()) & (1 << (4 + b)) != 0, "landmark {b}");
            }
        }
        // Far from everything (outside the grid) every feature is checked.
        assert_eq!(t.near.mask(0.0, 0.0), u16::MAX);
        // And the grid does leave most cells with few features.
        let busy = t.near.masks.iter().filter(|m| m.count_ones() > 2).count();
        assert!(busy < t.near.masks.len() / 4, "{busy}");
    }
}
