//! Cost per output pixel of the exact mapping `T` against filling rows from
//! `A` + GCM at several sparsities, and of the resampling kernels.
//! `cargo bench --bench gcm`; throughput is in output pixels.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use gcm_ortho::camera::atmosphere::Refraction;
use gcm_ortho::camera::distortion::Distortion;
use gcm_ortho::camera::interior::InteriorOrientation;
use gcm_ortho::camera::rotation::AngleConvention;
use gcm_ortho::camera::{FrameCamera, SensorModel};
use gcm_ortho::dem::{Dem, GridDem};
use gcm_ortho::gcm::{CorrectionMode, Gcm, GcmSpec};
use gcm_ortho::geom::OutputGrid;
use gcm_ortho::geom::Span;
use gcm_ortho::io::source::Window;
use gcm_ortho::resample::{resample_row, resample_span, resample_spans, Kernel, View};
use gcm_ortho::transform::{Approx, Transform};
use nalgebra::Vector3;
use std::path::Path;

const W: u32 = 2048;
const ROWS: u32 = 64;

fn scene() -> (FrameCamera, Dem, OutputGrid) {
    let io = InteriorOrientation::digital(0.012, [10000.0, 10000.0]).unwrap();
    let r = AngleConvention::AlphaOmegaKappa.matrix([0.01, -0.02, 0.5]);
    let cam = FrameCamera::new(152.0, Vector3::new(5000.0, 5000.0, 1800.0), r, io, Distortion::Radial([0.0, 1.5e-7, -2e-9]), Refraction::Auto, true);
    let (n, post) = (1000usize, 5.0);
    let data = (0..n * n)
        .map(|k| {
            let (x, y) = ((k % n) as f64 * post, (k / n) as f64 * post);
            (300.0 + 40.0 * ((x / 310.0).sin() * (y / 270.0).cos())) as f32
        })
        .collect();
    let dem = Dem::grid(GridDem::new(n, n, data, [2500.0, post, 0.0, 7500.0, 0.0, -post], None, None), Path::new("bench"));
    let grid = OutputGrid { x0: 4000.0, y0: 6000.0, gsd: gcm_ortho::geom::Gsd::square(0.12), width: W, height: ROWS };
    (cam, dem, grid)
}

fn mapping(c: &mut Criterion) {
    let (cam, dem, grid) = scene();
    let t = Transform::new(&cam, &dem, grid);
    let a = Approx::new(&cam, &grid, dem.trend_plane([4000.0, 5990.0, 4250.0, 6000.0]).unwrap()).unwrap();
    let mut g = c.benchmark_group("map_rows");
    g.throughput(Throughput::Elements((W * ROWS) as u64));
    let mut cols = vec![0.0; W as usize];
    let mut rows = vec![0.0; W as usize];
    g.bench_function("exact_T", |b| {
        b.iter(|| {
            for y in 0..ROWS {
                t.exact_row(y as f64 + 0.5, 0.5, &mut cols, &mut rows);
            }
        })
    });
    for k in [1u32, 4, 8, 16, 32] {
        for mode in [CorrectionMode::Cell, CorrectionMode::Bilinear] {
            let gcm = Gcm::new(&t, a, GcmSpec { k, mode, max_error: None });
            let name = format!("{mode:?}").to_lowercase();
            g.bench_with_input(BenchmarkId::new(name, k), &k, |b, _| {
                b.iter(|| {
                    let band = gcm.prepare(0, ROWS);
                    let mut miss = None;
                    for y in 0..ROWS {
                        gcm.fill_row(&band, y, 0, &mut cols, &mut rows, &mut miss);
                    }
                })
            });
        }
    }
    g.finish();
}

fn kernels(c: &mut Criterion) {
    let (w, h) = (1024u32, 1024u32);
    let bytes: Vec<u8> = (0..w * h * 3).map(|i| (i.wrapping_mul(2654435761) >> 24) as u8).collect();
    let win = Window::from_bytes(0, 0, w, h, &bytes);
    let view = View::<u8>::new(&win, 3, w, h);
    let n = 1000usize;
    // A rotated, slightly scaled walk through the window.
    let cols: Vec<f64> = (0..n).map(|i| 100.3 + i as f64 * 0.87).collect();
    let rows: Vec<f64> = (0..n).map(|i| 200.7 + i as f64 * 0.5).collect();
    let mut out = vec![0u8; n * 3];
    let mut valid = vec![false; n];
    let mut g = c.benchmark_group("resample_rgb8");
    g.throughput(Throughput::Elements(n as u64));
    for k in [Kernel::Nearest, Kernel::Bilinear, Kernel::Cubic, Kernel::Lanczos3] {
        g.bench_function(format!("{k:?}").to_lowercase(), |b| b.iter(|| resample_row(k, &view, &cols, &rows, &mut out, &mut valid, 0)));
    }
    // The same walk as straight spans of 16 pixels (what rectify does
    // where the GCM's positions are straight between node columns).
    let spans: Vec<Span> = (0..n / 16)
        .map(|s| {
            let first = s * 16;
            Span { stepped: true, first, end: first + 16, anchor: first, c: cols[first], r: rows[first], dc: 0.87, dr: 0.5, ddc: 0.0, ddr: 0.0 }
        })
        .collect();
    g.bench_function("bilinear_spans", |b| {
        b.iter(|| {
            for s in &spans {
                resample_span(&view, s, &mut out[s.first * 3..s.end * 3], &mut valid[s.first..s.end], 0);
            }
        })
    });
    // All of them in one call, as rectify hands over a row.
    let m = spans.len() * 16;
    g.bench_function("bilinear_span_run", |b| b.iter(|| resample_spans(&view, &spans, &mut out[..m * 3], &mut valid[..m], 0)));
    // Gaps cut where the DEM's kinks fall: lengths vary as in a real row.
    let mut varied = Vec::new();
    let mut x = 0;
    for len in [16usize, 9, 7, 16, 16, 12, 4, 16, 14, 2, 16, 11, 5].iter().cycle() {
        if x + len > m {
            break;
        }
        varied.push(Span {
            stepped: true,
            first: x,
            end: x + len,
            anchor: x,
            c: cols[0] + x as f64 * 0.87,
            r: rows[0] + x as f64 * 0.5,
            dc: 0.87,
            dr: 0.5,
            ddc: 0.0,
            ddr: 0.0,
        });
        x += len;
    }
    let mv = x;
    g.bench_function("bilinear_span_run_varied", |b| b.iter(|| resample_spans(&view, &varied, &mut out[..mv * 3], &mut valid[..mv], 0)));
    // The same pixels as one span: what the set-up of ~13-pixel spans costs.
    let long = [Span { stepped: true, first: 0, end: m, anchor: 0, c: cols[0], r: rows[0], dc: 0.87, dr: 0.5, ddc: 0.0, ddr: 0.0 }];
    g.bench_function("bilinear_one_long_span", |b| b.iter(|| resample_spans(&view, &long, &mut out[..m * 3], &mut valid[..m], 0)));
    g.finish();
}

/// The frame camera's projection of a row of ground points: one call per
/// point against one call for the whole row (what the scene generator's
/// ray caster uses).
fn projection(c: &mut Criterion) {
    let (cam, _, grid) = scene();
    let n = W as usize;
    let x: Vec<f64> = (0..n).map(|i| grid.x0 + (i as f64 + 0.5) * grid.gsd.x).collect();
    let y = vec![grid.y0 - 3.0; n];
    let z: Vec<f64> = (0..n).map(|i| 300.0 + (i as f64 * 0.01).sin() * 30.0).collect();
    let (mut col, mut row) = (vec![0.0; n], vec![0.0; n]);
    let mut g = c.benchmark_group("project_frame");
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("one_by_one", |b| {
        b.iter(|| {
            for k in 0..n {
                (col[k], row[k]) = cam.project(x[k], y[k], z[k]).unwrap_or((f64::NAN, f64::NAN));
            }
        })
    });
    g.bench_function("many", |b| b.iter(|| cam.project_many(&x, &y, &z, &mut col, &mut row)));
    g.finish();
}

/// An RGB tile of 256² reduced 2×2 for the overview above it (`average`,
/// every pixel with a value: nearly every tile of an orthophoto).
fn overview_reduce(c: &mut Criterion) {
    use gcm_ortho::io::format::SampleType;
    use gcm_ortho::overview::{reduce, OverviewResampling, TileLayout, ValidBy};
    let t = 256usize;
    let lay = TileLayout { tile: t, bands: 3, sample: SampleType::U8 };
    let px: Vec<u8> = (0..t * t * 3).map(|i| (i * 7 % 251) as u8).collect();
    let valid = vec![1u8; t * t];
    let mut g = c.benchmark_group("overview_reduce");
    g.throughput(Throughput::Bytes(px.len() as u64));
    g.bench_function("average_rgb_u8", |b| b.iter(|| reduce(OverviewResampling::Average, lay, ValidBy::Mask, 0.0, &px, Some(&valid), (t, t))));
    g.finish();
}

/// An overview tile's coding: a 256² RGB tile of a detailed photograph
/// after the horizontal predictor (differences spread like an overview's),
/// by deflate's level 0 (Huffman codes alone, the overviews' default)
/// and by libdeflate's level 1 (the full level's).
fn overview_code(c: &mut Criterion) {
    use gcm_ortho::io::tiff_out::zlib;
    let mut s = 1u64;
    let tile: Vec<u8> = (0..256 * 256 * 3)
        .map(|_| {
            s = s.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            // A two-sided spread of about ±12 grey levels, most near 0.
            let (a, b) = ((s >> 40) % 13, (s >> 20) % 13);
            (a as i32 - b as i32) as u8
        })
        .collect();
    let mut g = c.benchmark_group("overview_code");
    g.throughput(Throughput::Bytes(tile.len() as u64));
    for level in [0u8, 1] {
        g.bench_function(format!("deflate_level_{level}"), |b| b.iter(|| zlib(&tile, level)));
    }
    g.finish();
}

criterion_group!(benches, mapping, kernels, projection, overview_reduce, overview_code);
criterion_main!(benches);
