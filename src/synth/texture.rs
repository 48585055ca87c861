//! The ground's appearance as a function of (X, Y): fields of different
//! crops with dark boundaries (sharp lines), roads, fine texture noise and a
//! few unique landmarks. Features are sized from the GSD so that they are
//! resolved (no aliasing) yet sharp. Colours in [0, 1].

use super::noise::{fbm, hash, unit};

pub struct Texture {
    seed: u64,
    gsd: f64,
    /// Field size, metres.
    field: f64,
    /// Rotation of the field pattern (cos, sin).
    rot: (f64, f64),
    roads: Vec<Road>,
    landmarks: Vec<(f64, f64, f64)>,
}

struct Road {
    x: f64,
    y: f64,
    dx: f64,
    dy: f64,
    half: f64,
}

const PALETTE: [[f32; 3]; 6] = [
    [0.32, 0.45, 0.20],
    [0.55, 0.50, 0.28],
    [0.70, 0.62, 0.35],
    [0.25, 0.35, 0.18],
    [0.45, 0.38, 0.26],
    [0.60, 0.58, 0.40],
];

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
        let roads = (0..4)
            .map(|k| {
                let (c, s) = rational_rotation(u(10 + k) * 2.0 - 1.0);
                Road {
                    x: cx + (u(20 + k) - 0.5) * size * 0.6,
                    y: cy + (u(30 + k) - 0.5) * size * 0.6,
                    dx: c,
                    dy: s,
                    half: gsd * (2.0 + 3.0 * u(40 + k)),
                }
            })
            .collect();
        let landmarks = (0..12)
            .map(|k| (cx + (u(50 + k) - 0.5) * size * 0.8, cy + (u(70 + k) - 0.5) * size * 0.8, gsd * (6.0 + 10.0 * u(90 + k))))
            .collect();
        Texture { seed, gsd, field, rot, roads, landmarks }
    }

    /// Colour at ground (X, Y).
    pub fn rgb(&self, x: f64, y: f64) -> [f32; 3] {
        let g = self.gsd;
        // Fields on a rotated grid, rows 0.7 as tall as wide.
        let (c, s) = self.rot;
        let xr = (c * x + s * y) / self.field;
        let yr = (-s * x + c * y) / (0.7 * self.field);
        let (fi, fj) = (crate::resample::floor_i64(xr) as f64, crate::resample::floor_i64(yr) as f64);
        let base = PALETTE[(hash(fi as i64, fj as i64, self.seed) % PALETTE.len() as u64) as usize];
        // Fine texture: ±20 % brightness, wavelengths of 24 and 12 GSD.
        let n = fbm(x / (24.0 * g), y / (24.0 * g), 2, self.seed ^ 0x5eed) as f32;
        let mut col = base.map(|v| v * (0.8 + 0.4 * n));
        // Field boundaries: dark lines 2 GSD wide, anti-aliased over 1 GSD.
        let dx = (xr - fi).min(fi + 1.0 - xr) * self.field;
        let dy = (yr - fj).min(fj + 1.0 - yr) * 0.7 * self.field;
        let edge = coverage(dx.min(dy), g);
        col = mix(col, [0.12, 0.11, 0.10], 0.8 * edge);
        for r in &self.roads {
            let d = ((x - r.x) * r.dy - (y - r.y) * r.dx).abs() - r.half;
            let cov = coverage(d.max(0.0) + g, g);
            if cov > 0.0 {
                col = mix(col, [0.82, 0.80, 0.76], cov);
            }
        }
        for &(lx, ly, rad) in &self.landmarks {
            let d2 = (x - lx) * (x - lx) + (y - ly) * (y - ly);
            if d2 < (rad + 2.0 * g) * (rad + 2.0 * g) {
                let d = d2.sqrt();
                // White disc with a black ring at 0.6 of the radius.
                let disc = coverage((d - rad).max(0.0) + g, g);
                col = mix(col, [0.95, 0.95, 0.95], disc);
                let ring = coverage((d - 0.6 * rad).abs() + g - 0.1 * rad, g);
                col = mix(col, [0.05, 0.05, 0.05], ring * disc);
            }
        }
        col
    }
}

/// 1 within `g` of a line (distance `d`), falling linearly to 0 over one more `g`.
#[inline]
fn coverage(d: f64, g: f64) -> f32 {
    (2.0 - d / g).clamp(0.0, 1.0) as f32
}

#[inline]
fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2])]
}
