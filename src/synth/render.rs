//! Rendering the scan: every pixel's ray cast onto the DEM and the
//! ground's colour taken there.
//!
//! Each band of rows is split into stripes of columns, rendered in
//! parallel, and each stripe remembers where the rays of its last two rows
//! met the ground. Extrapolated down the column, they are so close to the
//! next row's answers (well inside the 10⁻³ px tolerance, except where a ray
//! crosses a DEM cell's edge) that the row's pixels are checked all at once:
//! one DEM lookup each and one `project_many` for the run
//! (`RayCaster::cast_run`). A pixel the run leaves open, and every pixel of
//! a stripe's first two rows, is cast alone from its left neighbours'
//! answers, as before. The stripes are fixed, so the bytes do not depend on
//! the number of threads.

use super::{write_pixel, Scene, SynthOptions};
use crate::camera::SensorModel;
use crate::error::Result;
use crate::io::tiff_out::{write_raster, OutputSpec};
use crate::progress::{Progress, Task};
use crate::transform::inverse::{RayCaster, RunScratch};
use rayon::prelude::*;
use std::sync::Mutex;

/// Columns of a stripe.
const STRIPE: usize = 512;
/// How close (scan pixels) a ray's image must come to its pixel.
const TOL: f64 = 1e-3;
const UNKNOWN: (f64, f64) = (f64::NAN, f64::NAN);

/// A stripe of columns `x0 ..` and where its last two rows' rays met the
/// ground (NaN: no ray).
struct Stripe {
    x0: usize,
    last: Vec<(f64, f64)>,
    before: Vec<(f64, f64)>,
    run: Run,
}

/// One row's run of pixels with guesses from above.
#[derive(Default)]
struct Run {
    at: Vec<usize>,
    cols: Vec<f64>,
    guess: Vec<(f64, f64)>,
    found: Vec<Option<[f64; 3]>>,
    scratch: RunScratch,
}

impl Stripe {
    fn new(x0: usize, w: usize) -> Stripe {
        Stripe { x0, last: vec![UNKNOWN; w], before: vec![UNKNOWN; w], run: Run::default() }
    }
}

/// Renders the scan (see the module doc), a band of rows at a time.
pub(super) fn render_scan<M, C, I>(o: &SynthOptions, sc: &Scene<'_, M, C, I>, spec: &OutputSpec, path: &std::path::Path, progress: &dyn Progress) -> Result<()>
where
    M: SensorModel,
    C: Fn(f64, f64) -> [f32; 3] + Sync,
    I: Fn(f64, f64) -> bool + Sync,
{
    let pb = o.bands as usize * spec.sample.bytes();
    let width = o.width as usize;
    progress.start(&Task { name: "synth", units: o.height as u64, lines: o.height as u64, line_name: "rows", input_bytes: 0 });
    let stripes = Mutex::new((0..width.div_ceil(STRIPE)).map(|s| Stripe::new(s * STRIPE, STRIPE.min(width - s * STRIPE))).collect::<Vec<_>>());
    let written = write_raster(path, spec, |y0, y1, buf| {
        // Bands come one after the other: the lock is never contended.
        let mut stripes = stripes.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let mut parts: Vec<Vec<&mut [u8]>> = stripes.iter().map(|_| Vec::new()).collect();
        for row in buf.chunks_mut(width * pb) {
            for (s, seg) in row.chunks_mut(STRIPE * pb).enumerate() {
                parts[s].push(seg);
            }
        }
        stripes.par_iter_mut().zip(parts.into_par_iter()).for_each(|(stripe, rows)| {
            let mut caster = RayCaster::new(sc.model, sc.dem);
            for (k, seg) in rows.into_iter().enumerate() {
                render_row(o, sc, &mut caster, stripe, y0 as usize + k, seg, pb);
            }
        });
        progress.advance((y1 - y0) as u64);
    });
    progress.finish();
    written
}

/// Row `y` of one stripe into `out`.
fn render_row<M, C, I>(o: &SynthOptions, sc: &Scene<'_, M, C, I>, caster: &mut RayCaster<'_, M>, st: &mut Stripe, y: usize, out: &mut [u8], pb: usize)
where
    M: SensorModel,
    C: Fn(f64, f64) -> [f32; 3] + Sync,
    I: Fn(f64, f64) -> bool + Sync,
{
    let r = y as f64 + 0.5;
    let col = |j: usize| (st.x0 + j) as f64 + 0.5;
    // The run: pixels whose two rays above are known, guessed by
    // extrapolating them down the column.
    let run = &mut st.run;
    run.at.clear();
    run.cols.clear();
    run.guess.clear();
    for (j, (&a, &b)) in st.last.iter().zip(&st.before).enumerate() {
        if !(a.0.is_nan() || b.0.is_nan()) && (sc.inside)(col(j), r) {
            run.at.push(j);
            run.cols.push(col(j));
            run.guess.push((2.0 * a.0 - b.0, 2.0 * a.1 - b.1));
        }
    }
    run.found.resize(run.at.len(), None);
    caster.cast_run(&run.cols, r, &run.guess, TOL, &mut run.found, &mut run.scratch);
    // `before` takes the last row; `last` is overwritten pixel by pixel.
    std::mem::swap(&mut st.last, &mut st.before);

    // Then every pixel in order. The last two ground points two pixels
    // back predict a pixel the run left open; even and odd pixels form two
    // separate chains.
    let mut prev: [Option<(f64, f64)>; 2] = [None; 2];
    let mut step = [(0.0, 0.0); 2];
    let mut next = 0;
    for j in 0..st.last.len() {
        let c = col(j);
        let in_run = run.at.get(next) == Some(&j);
        let (chain, step) = (&mut prev[j & 1], &mut step[j & 1]);
        let hit = if in_run || (sc.inside)(c, r) {
            let found = if in_run { run.found[next] } else { None };
            let found = found.or_else(|| {
                let guess = chain.map(|p| (p.0 + step.0, p.1 + step.1)).or(in_run.then(|| run.guess[next]));
                caster.cast(c, r, guess, sc.mid_z, TOL)
            });
            if found.is_none() {
                *chain = None;
            }
            Some(found)
        } else {
            *chain = None;
            None
        };
        next += usize::from(in_run);
        let rgb = match hit {
            Some(Some(p)) => {
                if let Some(q) = *chain {
                    *step = (p[0] - q.0, p[1] - q.1);
                }
                *chain = Some((p[0], p[1]));
                st.last[j] = (p[0], p[1]);
                (sc.shade)(c, r, (sc.colour)(p[0], p[1]))
            }
            Some(None) => {
                st.last[j] = UNKNOWN;
                [0.0; 3]
            }
            None => {
                st.last[j] = UNKNOWN;
                (sc.margin)(c, r)
            }
        };
        write_pixel(rgb, o.bands, o.bits, &mut out[j * pb..(j + 1) * pb]);
    }
}
