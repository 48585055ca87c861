//! Dense matching of one stereo tile, one thread: the `dem` command's
//! tile (512 px and 64 px of context each side) over a search of 166
//! disparities (the range of `benches/stereo.sh`'s pair), by each search.
//! `cargo bench --bench matching`; throughput is in left pixels.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use gcm_ortho::stereo::matching::{match_tile, MatchParams, Matcher};
use gcm_ortho::stereo::resample::Img;

const SIDE: usize = 640;
const CORE: usize = 512;
const DMIN: f64 = -74.0;
const DMAX: f64 = 92.0;

/// Ground texture: value noise of two scales, bilinear between the
/// lattice's samples (continuous, so a pair can be made from it exactly).
fn texture(x: f64, y: f64) -> f32 {
    let lattice = |i: i64, j: i64, seed: u64| -> f64 {
        let mut h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F) ^ seed;
        h ^= h >> 29;
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 32;
        (h % 1000) as f64 / 1000.0
    };
    let noise = |x: f64, y: f64, seed: u64| {
        let (i, j) = (x.floor(), y.floor());
        let (fx, fy) = (x - i, y - j);
        let (i, j) = (i as i64, j as i64);
        let a = lattice(i, j, seed) * (1.0 - fx) + lattice(i + 1, j, seed) * fx;
        let b = lattice(i, j + 1, seed) * (1.0 - fx) + lattice(i + 1, j + 1, seed) * fx;
        a * (1.0 - fy) + b * fy
    };
    (60.0 + 120.0 * noise(x / 6.0, y / 6.0, 1) + 50.0 * noise(x / 1.7, y / 1.7, 2)) as f32
}

/// The disparity of the ground at left pixel `(x, y)`: rolling relief.
fn truth(x: f64, y: f64) -> f64 {
    10.0 + 30.0 * (x / 150.0).sin() * (y / 110.0).cos()
}

fn pair() -> (Img, Img) {
    let left = Img { x0: 0, y0: 0, w: SIDE, h: SIDE, v: (0..SIDE * SIDE).map(|k| texture((k % SIDE) as f64, (k / SIDE) as f64)).collect() };
    // The right image at column x − d shows the left one's x.
    let rx0 = -(DMAX as i64) - 16;
    let rw = SIDE + (DMAX - DMIN) as usize + 32;
    let right = Img {
        x0: rx0,
        y0: 0,
        w: rw,
        h: SIDE,
        v: (0..rw * SIDE)
            .map(|k| {
                let (xr, y) = ((k % rw) as i64 + rx0, (k / rw) as f64);
                let mut xl = xr as f64 + 10.0;
                for _ in 0..30 {
                    xl = xr as f64 + truth(xl, y);
                }
                texture(xl, y)
            })
            .collect(),
    };
    (left, right)
}

fn matching(c: &mut Criterion) {
    let (left, right) = pair();
    let core = [64, 64, 64 + CORE, 64 + CORE];
    let mut g = c.benchmark_group("match_tile");
    g.sample_size(10);
    g.throughput(Throughput::Elements((CORE * CORE) as u64));
    for m in [Matcher::Sgm, Matcher::Ncc] {
        let p = MatchParams { matcher: m, ..Default::default() };
        let d = match_tile(&left, &right, DMIN, DMAX, &p, core).disparity;
        let matched = d.iter().filter(|v| !v.is_nan()).count();
        assert!(matched > CORE * CORE * 9 / 10, "{m:?} matched {matched}");
        g.bench_function(format!("{m:?}").to_lowercase(), |b| b.iter(|| match_tile(&left, &right, DMIN, DMAX, &p, core)));
    }
    g.finish();
}

criterion_group!(benches, matching);
criterion_main!(benches);
