//! The geometry core against the formulas: conventions, `A + c = T` at k = 1,
//! zero corrections on flat terrain, round trips.

use gcm_ortho::camera::atmosphere::Refraction;
use gcm_ortho::camera::distortion::Distortion;
use gcm_ortho::camera::interior::InteriorOrientation;
use gcm_ortho::camera::rotation::AngleConvention;
use gcm_ortho::camera::{locate, FrameCamera, SensorModel};
use gcm_ortho::dem::{Dem, GridDem};
use gcm_ortho::gcm::{CorrectionMode, Gcm, GcmSpec};
use gcm_ortho::geom::OutputGrid;
use gcm_ortho::geom::Plane;
use gcm_ortho::transform::{Approx, Mapped, Transform};
use nalgebra::Vector3;
use proptest::prelude::*;
use std::path::Path;

fn film_interior() -> InteriorOrientation {
    let mm = [[-106.0, -106.0], [106.0, 106.0], [-106.0, 106.0], [106.0, -106.0]];
    let g = 0.2f64.to_radians();
    let px: Vec<[f64; 2]> = mm
        .iter()
        .map(|p: &[f64; 2]| {
            let (sx, sy) = (1.0 / 0.05, 1.0 / 0.0502);
            [2300.0 + sx * p[0] * g.cos() - sy * p[1] * g.sin(), 2300.0 - (sx * p[0] * g.sin() + sy * p[1] * g.cos())]
        })
        .collect();
    InteriorOrientation::from_fiducials(&mm, &px, [0.01, -0.02]).unwrap()
}

fn camera(conv: AngleConvention, angles_deg: [f64; 3], full: bool) -> FrameCamera {
    let (d, r, c) = if full { (Distortion::Radial([0.0, 2.1e-8, -3.0e-10]), Refraction::Auto, true) } else { (Distortion::None, Refraction::None, false) };
    FrameCamera::new(152.0, Vector3::new(5000.0, 5000.0, 1800.0), conv.matrix(angles_deg.map(f64::to_radians)), film_interior(), d, r, c)
}

fn grid() -> OutputGrid {
    OutputGrid { x0: 4000.0, y0: 6000.0, gsd: gcm_ortho::geom::Gsd::square(2.0), width: 1000, height: 1000 }
}

/// A hilly DEM: 20 m posting, smooth hills.
fn hills() -> Dem {
    hills_posted(20.0)
}

fn hills_posted(posting: f64) -> Dem {
    posted(posting, 0.0)
}

/// Smooth hills sampled every `posting` metres, plus up to ±`noise`/2 m of
/// deterministic noise at every post (then the bilinear surface bends
/// sharply along every post line).
fn posted(posting: f64, noise: f64) -> Dem {
    let (w, h) = ((4000.0 / posting) as usize, (4000.0 / posting) as usize);
    let data = (0..w * h)
        .map(|k| {
            let (i, j) = ((k % w) as f64, (k / w) as f64);
            let (x, y) = (i * posting, j * posting);
            let jitter = ((k as u64).wrapping_mul(2654435761) % 1000) as f64 / 1000.0 - 0.5;
            (200.0 + 60.0 * (x / 340.0).sin() * (y / 460.0).cos() + 0.015 * x + noise * jitter) as f32
        })
        .collect();
    Dem::grid(GridDem::new(w, h, data, [3000.0, posting, 0.0, 7000.0, 0.0, -posting], None, None), Path::new("hills"))
}

#[test]
fn one_camera_in_three_conventions_maps_identically() {
    let thesis = camera(AngleConvention::AlphaOmegaKappa, [1.3, -0.8, 31.0], true);
    for conv in [AngleConvention::OmegaPhiKappa, AngleConvention::OmegaAlphaChi] {
        let angles = conv.angles(&thesis.r).map(f64::to_degrees);
        let other = camera(conv, angles, true);
        for (x, y, z) in [(5000.0, 5000.0, 200.0), (4100.0, 5900.0, 310.0), (5800.0, 4300.0, 150.0)] {
            let a = thesis.project(x, y, z).unwrap();
            let b = other.project(x, y, z).unwrap();
            assert!((a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9, "{conv:?}: {a:?} vs {b:?}");
        }
    }
}

#[test]
fn cell_mode_at_k1_reproduces_t_exactly() {
    let cam = camera(AngleConvention::AlphaOmegaKappa, [1.3, -0.8, 31.0], true);
    let dem = hills();
    let g = OutputGrid { width: 300, height: 200, ..grid() };
    let t = Transform::new(&cam, &dem, g);
    let a = Approx::new(&cam, &g, dem.trend_plane([g.x0, g.y0 - 400.0, g.x0 + 600.0, g.y0]).unwrap()).unwrap();
    let gcm = Gcm::new(&t, a, GcmSpec { k: 1, mode: CorrectionMode::Cell, max_error: None });
    let band = gcm.prepare(0, g.height);
    let mut cols = vec![0.0; g.width as usize];
    let mut rows = vec![0.0; g.width as usize];
    let mut miss = None;
    let mut worst = 0.0f64;
    for y in 0..g.height {
        gcm.fill_row(&band, y, 0, &mut cols, &mut rows, &mut miss);
        for x in 0..g.width {
            let Mapped::Px(c, r) = t.exact(x as f64 + 0.5, y as f64 + 0.5) else { panic!("no T") };
            worst = worst.max((c - cols[x as usize]).abs()).max((r - rows[x as usize]).abs());
        }
    }
    assert!(worst < 1e-9, "{worst}");
}

#[test]
fn flat_terrain_without_corrections_needs_no_corrections() {
    let cam = camera(AngleConvention::OmegaPhiKappa, [2.0, -1.5, 75.0], false);
    let dem = Dem::flat(250.0);
    let g = grid();
    let t = Transform::new(&cam, &dem, g);
    let a = Approx::new(&cam, &g, Plane::flat(250.0)).unwrap();
    let gcm = Gcm::new(&t, a, GcmSpec { k: 16, mode: CorrectionMode::Bilinear, max_error: None });
    let band = gcm.prepare(0, 64);
    let mut miss = None;
    for j in -1..=4 {
        let h = gcm.node_heights(j);
        let row = gcm.node_row(j, &h, &mut miss);
        for (dc, dr) in row.dc.iter().zip(&row.dr) {
            assert!(dc.abs() < 1e-9 && dr.abs() < 1e-9, "{dc} {dr}");
        }
    }
    assert_eq!(band.stats.refined_cells, 0);
}

#[test]
fn bilinear_corrections_beat_cell_corrections_on_hills() {
    let cam = camera(AngleConvention::AlphaOmegaKappa, [1.3, -0.8, 31.0], true);
    let dem = hills();
    let g = grid();
    let t = Transform::new(&cam, &dem, g);
    let a = Approx::new(&cam, &g, dem.trend_plane([g.x0, g.y0 - 2000.0, g.x0 + 2000.0, g.y0]).unwrap()).unwrap();
    let run = |mode| {
        let gcm = Gcm::new(&t, a, GcmSpec { k: 8, mode, max_error: None });
        gcm_ortho::study::accuracy::evaluate(&gcm, 7, None).errors
    };
    let cell = run(CorrectionMode::Cell);
    let bil = run(CorrectionMode::Bilinear);
    assert!(bil.rms < cell.rms / 3.0, "bilinear {bil:?} cell {cell:?}");
    assert!(bil.max < 0.1, "{bil:?}");
}

#[test]
fn error_bound_holds_over_every_pixel() {
    let cam = camera(AngleConvention::AlphaOmegaKappa, [1.3, -0.8, 31.0], true);
    // DEM posted every 10 output pixels, as a 5 m DEM under a 0.5 m orthophoto.
    let dem = hills_posted(20.0);
    let g = OutputGrid { width: 600, height: 600, ..grid() };
    let t = Transform::new(&cam, &dem, g);
    let a = Approx::new(&cam, &g, dem.mean_plane([g.x0, g.y0 - 1200.0, g.x0 + 1200.0, g.y0]).unwrap()).unwrap();
    let gcm = Gcm::new(&t, a, GcmSpec { k: 32, mode: CorrectionMode::Bilinear, max_error: Some(0.05) });
    let ev = gcm_ortho::study::accuracy::evaluate(&gcm, 1, None);
    assert!(ev.errors.max <= 0.05, "{:?}", ev.errors);
    assert!(ev.gcm.refined_cells > 0, "the bound should force some refinement: {:?}", ev.gcm);
    // Fewer exact evaluations than pixels (k = 1 evaluates every pixel).
    let cost = ev.gcm.nodes + ev.gcm.checks + ev.gcm.exact_pixels;
    assert!(cost < g.pixel_count() / 2, "{:?}", ev.gcm);
}

#[test]
fn dem_post_lines_as_node_lines_follow_a_rough_dem() {
    // Posts every 25 output pixels (50 m at 2 m, ~4 scan pixels an output
    // pixel), nodes every 16: every DEM post line becomes a node line, so no
    // cell straddles a bend. Measured with uniform nodes alone (the DEM lines
    // removed): RMS 0.30 px, max 3.2 px; with them RMS 0.028, max 0.13 px
    // (what is left is the curvature of T within the smooth pieces).
    let cam = camera(AngleConvention::AlphaOmegaKappa, [1.3, -0.8, 31.0], true);
    let dem = posted(50.0, 8.0);
    let g = OutputGrid { width: 800, height: 800, ..grid() };
    let t = Transform::new(&cam, &dem, g);
    let a = Approx::new(&cam, &g, dem.trend_plane([g.x0, g.y0 - 1600.0, g.x0 + 1600.0, g.y0]).unwrap()).unwrap();
    let gcm = Gcm::new(&t, a, GcmSpec { k: 16, mode: CorrectionMode::Bilinear, max_error: None });
    assert!(gcm.dem_aligned_lines());
    let ev = gcm_ortho::study::accuracy::evaluate(&gcm, 1, None);
    assert!(ev.errors.rms < 0.05 && ev.errors.max < 0.2, "{:?}", ev.errors);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    #[test]
    fn ground_image_ground_round_trip(
        a in -3.0f64..3.0, w in -3.0f64..3.0, k in -180.0f64..180.0,
        x in 4200.0f64..5800.0, y in 4200.0f64..5800.0, z in 0.0f64..600.0,
    ) {
        let cam = camera(AngleConvention::AlphaOmegaKappa, [a, w, k], true);
        let (c, r) = cam.project(x, y, z).unwrap();
        let (bx, by) = locate(&cam, c, r, z, 1e-9).unwrap();
        prop_assert!((bx - x).abs() < 1e-5 && (by - y).abs() < 1e-5, "{} {}", bx - x, by - y);
    }
}

/// Rows of a 2000-pixel grid at `gsd` m as stepped spans: `None` where
/// the rows have none; else the longest span, the worst distance from
/// `A + c` itself over every 5th row, and whether any span is quadratic. Also checks that the spans cover the
/// row and that a piece of the row starting mid-gap gets the same spans,
/// bit for bit.
fn stepped_spans_at(gsd: f64) -> Option<(usize, f64, bool)> {
    let cam = camera(AngleConvention::AlphaOmegaKappa, [1.3, -0.8, 31.0], true);
    let dem = hills();
    let g = OutputGrid { x0: 4400.0, y0: 5600.0, gsd: gcm_ortho::geom::Gsd::square(gsd), width: 2000, height: 48 };
    let t = Transform::new(&cam, &dem, g);
    let a = Approx::new(&cam, &g, dem.trend_plane([g.x0, g.y0 - 48.0 * gsd, g.x0 + 2000.0 * gsd, g.y0]).unwrap()).unwrap();
    let gcm = Gcm::new(&t, a, GcmSpec { k: 16, mode: CorrectionMode::Bilinear, max_error: None });
    let band = gcm.prepare(0, g.height);
    let w = g.width as usize;
    let (mut cols, mut rows) = (vec![0.0; w], vec![0.0; w]);
    let (mut whole, mut piece) = (Vec::new(), Vec::new());
    let mut miss = None;
    let (mut worst, mut longest, mut bent) = (0.0f64, 0, false);
    for y in (0..g.height).step_by(5) {
        if !gcm.row_spans(&band, y, 0, w, &mut whole) {
            assert!(y == 0, "rows of one grid have spans or have none");
            return None;
        }
        assert!(whole.iter().all(|s| s.stepped), "{:?}", whole.iter().find(|s| !s.stepped));
        assert!(whole.windows(2).all(|p| p[0].end == p[1].first));
        assert_eq!((whole[0].first, whole.last().unwrap().end), (0, w));
        longest = longest.max(whole.iter().map(|s| s.end - s.first).max().unwrap());
        bent |= whole.iter().any(|s| s.ddc != 0.0 || s.ddr != 0.0);
        gcm.fill_exact(&band, y, 0, &mut cols, &mut rows, &mut miss);
        for s in &whole {
            for x in s.first..s.end {
                let (c, r) = s.at(x);
                worst = worst.max((c - cols[x]).abs()).max((r - rows[x]).abs());
            }
        }
        assert!(gcm.row_spans(&band, y, 701, 333, &mut piece));
        assert_eq!((piece[0].first, piece.last().unwrap().end), (701, 1034));
        for s in &piece {
            let same = whole.iter().find(|o| o.first <= s.first && s.first < o.end).unwrap();
            assert_eq!((s.anchor, s.c, s.r, s.dc, s.dr, s.ddc, s.ddr), (same.anchor, same.c, same.r, same.dc, same.dr, same.ddc, same.ddr));
        }
    }
    Some((longest, worst, bent))
}

#[test]
fn stepped_spans_stand_in_for_a_within_the_tolerance_in_any_piece() {
    let tol = gcm_ortho::gcm::A_LINEAR_TOLERANCE + 1e-9;
    // A fine output grid (0.25 m): A is straight to 1/4096 pixel across a
    // 16-pixel gap, one straight span a gap.
    let (longest, worst, bent) = stepped_spans_at(0.25).expect("stepped spans");
    assert!((longest == 16 || longest == 17) && !bent, "{longest} {bent}");
    assert!(worst <= tol && worst > 0.0, "{worst}: A is not affine here, the spans should differ from it a little");
    // Coarser grids: A curves more across a gap than a chord may stray, and
    // each gap is one quadratic span, far within the tolerance.
    for gsd in [0.35, 0.5, 1.0] {
        let (longest, worst, bent) = stepped_spans_at(gsd).expect("stepped spans");
        assert!(longest >= 16 && bent && worst <= 1e-5, "{gsd}: {longest} {worst} {bent}");
    }
}
