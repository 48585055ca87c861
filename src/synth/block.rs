//! A block of overlapping frames of one ground (`synth --block CxR`):
//! flight lines along X, 60 % forward and 30 % side overlap, one DEM (with
//! buildings under `--relief urban`) and one texture for all, each frame
//! with a camera of its own (a little tilt) and an exposure of its own
//! (gain, offset and vignetting, as real frames differ). Writes the scans,
//! their camera files, the DEM, a batch manifest of the block, the ground's
//! true colours on the mosaic's grid (`truth.tif`) and each frame's
//! exposure (`exposures.csv`).

use super::{camera_file, noise, relief, render_scan, scan_spec, truth_spec, write_dem, write_pixel, CameraKind, Scene, SynthOptions, BASE_HEIGHT};
use crate::dem::{Dem, Height};
use crate::error::{Error, Result};
use crate::geom::OutputGrid;
use crate::io::tiff_out::write_raster;
use crate::progress::Progress;
use crate::transform::footprint::{centre_gsd, footprint, footprint_gsd};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::PathBuf;

/// What `synth --block` wrote.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BlockReport {
    pub manifest: PathBuf,
    pub dem: PathBuf,
    pub truth: PathBuf,
    pub frames: usize,
    /// The mosaic's grid as `mosaic` chooses it by default.
    pub grid: OutputGrid,
}

/// One frame's exposure: `v' = (gain · v + offset) · (1 − vignetting · r²)`,
/// r the distance from the scan's centre over its half-diagonal.
#[derive(Clone, Copy, Debug)]
pub struct Exposure {
    pub gain: f32,
    pub offset: f32,
    pub vignetting: f32,
}

pub fn synth_block(o: &SynthOptions, cols: u32, rows: u32, progress: &dyn Progress) -> Result<BlockReport> {
    if !matches!(o.camera, CameraKind::Digital | CameraKind::Drone) || cols == 0 || rows == 0 || cols * rows > 400 {
        return Err(Error::setting("block", "a block is 1 to 400 digital or drone frames (‹camera› digital|drone)"));
    }
    std::fs::create_dir_all(o.out.join("scans")).map_err(|e| Error::io(&o.out, e))?;
    // The first frame's camera gives the footprint's size on the ground.
    let base = camera_file(o, BASE_HEIGHT);
    let first = base.clone().build(&o.out.join("camera.toml"))?;
    let cam0 = first.frame(&o.out)?;
    let flat = Dem::flat(BASE_HEIGHT);
    let fp = footprint(cam0, &flat, o.width, o.height, BASE_HEIGHT)?;
    let (fw, fh) = (fp[2] - fp[0], fp[3] - fp[1]);
    let (step_x, step_y) = (0.4 * fw, 0.7 * fh);
    let pos0 = base.exterior.as_ref().expect("synth writes exterior").position;
    let centre = |i: u32, j: u32| (pos0[0] + i as f64 * step_x, pos0[1] - j as f64 * step_y);
    let (mx, my) = (pos0[0] + (cols - 1) as f64 * step_x / 2.0, pos0[1] - (rows - 1) as f64 * step_y / 2.0);
    let half = ((cols - 1) as f64 * step_x + fw).max((rows - 1) as f64 * step_y + fh) / 2.0 + 0.5 * fw.max(fh) + 100.0;
    let flying = pos0[2] - BASE_HEIGHT;
    let grid_dem = relief(o, mx, my, half, flying)?;
    let dem_path = o.out.join("dem.tif");
    write_dem(&dem_path, &grid_dem)?;
    let dem = Dem::grid(grid_dem, &dem_path);
    let mid_z = dem.mean_height().unwrap_or(BASE_HEIGHT);

    let gsd0 = centre_gsd(cam0, &dem, o.width, o.height, mid_z)?;
    let tex = super::texture::Texture::new(o.seed, gsd0, mx, my, 2.0 * half);
    let colour = |x: f64, y: f64| tex.rgb(x, y);
    let spec = scan_spec(o);
    let mut manifest = String::from("# A synthetic block: gcm-ortho mosaic manifest.toml -o mosaic.tif\n[defaults]\ndem = \"dem.tif\"\n\n");
    let mut exposures = String::from("frame,gain,offset,vignetting\n");
    let (mut gsds, mut bounds) = (Vec::new(), [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY]);
    let mut k = 0u64;
    for j in 0..rows {
        for i in 0..cols {
            k += 1;
            let name = format!("{k:03}");
            let u = |n: i64| noise::unit(n, k as i64, o.seed ^ 0xb10c);
            let mut file = camera_file(&SynthOptions { seed: o.seed.wrapping_add(k), ..o.clone() }, BASE_HEIGHT);
            let (cx, cy) = centre(i, j);
            if let Some(e) = file.exterior.as_mut() {
                e.position = [cx + (u(1) - 0.5) * 0.02 * fw, cy + (u(2) - 0.5) * 0.02 * fh, pos0[2] + (u(3) - 0.5) * 0.02 * flying];
            }
            let cam_path = o.out.join(format!("scans/{name}.toml"));
            crate::io::publish::write_file(&cam_path, file.to_toml().as_bytes())?;
            let camera = crate::camera::file::Camera::read(&cam_path)?;
            let cam = camera.frame(&cam_path)?;
            let ex = Exposure { gain: 0.8 + 0.4 * u(4) as f32, offset: (u(5) as f32 - 0.5) * 0.12, vignetting: 0.05 + 0.2 * u(6) as f32 };
            let _ = writeln!(exposures, "{name},{},{},{}", ex.gain, ex.offset, ex.vignetting);
            let (w2, h2) = (o.width as f64 / 2.0, o.height as f64 / 2.0);
            let diag2 = w2 * w2 + h2 * h2;
            let shade = move |c: f64, r: f64, rgb: [f32; 3]| {
                let fall = 1.0 - ex.vignetting * (((c - w2).powi(2) + (r - h2).powi(2)) / diag2) as f32;
                rgb.map(|v| (ex.gain * v + ex.offset) * fall)
            };
            let (w, h) = (o.width as f64, o.height as f64);
            let inside = |c: f64, r: f64| c >= 0.0 && r >= 0.0 && c < w && r < h;
            let scene = Scene { model: cam, dem: &dem, colour: &colour, inside: &inside, margin: &|_, _| [0.0; 3], shade: &shade, mid_z };
            let scan_path = o.out.join(format!("scans/{name}.tif"));
            render_scan(o, &scene, &spec, &scan_path, progress)?;
            gsds.push(footprint_gsd(cam, &dem, o.width, o.height, mid_z)?);
            let f = footprint(cam, &dem, o.width, o.height, mid_z)?;
            bounds = [bounds[0].min(f[0]), bounds[1].min(f[1]), bounds[2].max(f[2]), bounds[3].max(f[3])];
            let _ = writeln!(manifest, "[[job]]\nimage = \"scans/{name}.tif\"\ncamera = \"scans/{name}.toml\"\n");
        }
    }
    gsds.sort_by(f64::total_cmp);
    let gsd = gsds[gsds.len() / 2];
    let grid = OutputGrid::snapped(bounds[0], bounds[1], bounds[2], bounds[3], crate::geom::Gsd::square(gsd))
        .ok_or_else(|| Error::Geometry("the block's footprint is empty".into()))?;
    let truth = o.out.join("truth.tif");
    write_truth(o, &dem, &colour, &grid, &truth)?;
    let manifest_path = o.out.join("manifest.toml");
    crate::io::publish::write_file(&manifest_path, manifest.as_bytes())?;
    let ex_path = o.out.join("exposures.csv");
    crate::io::publish::write_file(&ex_path, exposures.as_bytes())?;
    Ok(BlockReport { manifest: manifest_path, dem: dem_path, truth, frames: (cols * rows) as usize, grid })
}

/// The ground's true colour at every pixel of `grid` (no camera: what a
/// perfectly exposed mosaic would show), 0 where the DEM has no height.
fn write_truth(o: &SynthOptions, dem: &Dem, colour: &(dyn Fn(f64, f64) -> [f32; 3] + Sync), grid: &OutputGrid, path: &std::path::Path) -> Result<()> {
    let scan = scan_spec(o);
    let pb = o.bands as usize * scan.sample.bytes();
    let spec = truth_spec(&scan, grid)?;
    write_raster(path, &spec, |y0, _y1, buf| {
        buf.par_chunks_mut(grid.width as usize * pb).enumerate().for_each(|(k, row)| {
            let v = (y0 as usize + k) as f64 + 0.5;
            for i in 0..grid.width as usize {
                let (x, y) = grid.ground(i as f64 + 0.5, v);
                let px = &mut row[i * pb..(i + 1) * pb];
                match dem.height(x, y) {
                    Height::Value(_) => write_pixel(colour(x, y), o.bands, o.bits, px),
                    _ => px.fill(0),
                }
            }
        });
    })
}
