//! Pictures for people: the per-pixel error of the GCM as a GeoTIFF and as a
//! colour-mapped PNG with a legend, and the correction matrix itself in x
//! and y (the thesis' Fig. 3.12).

use crate::error::{Error, Result};
use crate::gcm::Gcm;
use crate::geom::OutputGrid;
use crate::io::source::SampleType;
use crate::io::tiff_out::{write_raster, Chunking, Compression, GeoTags, OutputSpec};
use std::path::Path;

/// Float32 GeoTIFF of the sampled error (NaN, its nodata, where not evaluated).
pub fn write_error_map(path: &Path, map: &[f32], w: u32, h: u32, grid: &OutputGrid, step: u32, crs: &crate::geodesy::Crs) -> Result<()> {
    let spec = OutputSpec {
        overviews: 0,
        cog: false,
        width: w,
        height: h,
        bands: 1,
        sample: SampleType::F32,
        chunking: Chunking::Tiles(256),
        compression: Compression::Deflate,
        level: None,
        overview_level: None,
        bigtiff: false,
        photometric: 1,
        alpha: false,
        mask: false,
        geo: Some(GeoTags {
            x0: grid.x0,
            y0: grid.y0,
            gsd: grid.gsd.scaled(step as f64),
            keys: crate::geodesy::geokeys::keys_of(crs).map_err(Error::Geometry)?,
            nodata: Some(f64::NAN),
        }),
    };
    write_raster(path, &spec, |y0, y1, buf| {
        let src = &map[(y0 * w) as usize..(y1 * w) as usize];
        buf.copy_from_slice(bytemuck::cast_slice(src));
    })
}

/// A blue → green → yellow → red ramp over [0, 1].
fn ramp(t: f32) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    let stops = [[49.0, 54.0, 149.0], [69.0, 117.0, 180.0], [116.0, 173.0, 209.0], [254.0, 224.0, 144.0], [244.0, 109.0, 67.0], [165.0, 0.0, 38.0]];
    let x = t * (stops.len() - 1) as f32;
    let i = (x.floor() as usize).min(stops.len() - 2);
    let f = x - i as f32;
    let c = |k: usize| (stops[i][k] + f * (stops[i + 1][k] - stops[i][k])) as u8;
    [c(0), c(1), c(2)]
}

fn save_png(path: &Path, w: u32, h: u32, rgb: &[u8]) -> Result<()> {
    let mut bytes = Vec::new();
    let mut enc = png::Encoder::new(&mut bytes, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut wr = enc.write_header().map_err(|e| Error::format(path, e.to_string()))?;
    wr.write_image_data(rgb).map_err(|e| Error::format(path, e.to_string()))?;
    wr.finish().map_err(|e| Error::format(path, e.to_string()))?;
    crate::io::publish::write_file(path, &bytes)
}

/// Draws digits 0-9 and '.' from a 3×5 font, scaled `s` times, in
/// `colour` on an RGB image `iw` pixels wide.
pub(crate) fn draw_text(img: &mut [u8], iw: usize, (x, y): (usize, usize), text: &str, s: usize, colour: [u8; 3]) {
    const FONT: [[u8; 5]; 11] = [
        [7, 5, 5, 5, 7],
        [2, 6, 2, 2, 7],
        [7, 1, 7, 4, 7],
        [7, 1, 7, 1, 7],
        [5, 5, 7, 1, 1],
        [7, 4, 7, 1, 7],
        [7, 4, 7, 5, 7],
        [7, 1, 1, 1, 1],
        [7, 5, 7, 5, 7],
        [7, 5, 7, 1, 7],
        [0, 0, 0, 0, 2],
    ];
    for (n, ch) in text.chars().enumerate() {
        let g = match ch {
            '0'..='9' => FONT[ch as usize - '0' as usize],
            '.' => FONT[10],
            _ => continue,
        };
        for (r, bits) in g.iter().enumerate() {
            for c in 0..3 {
                if bits & (4 >> c) != 0 {
                    for dy in 0..s {
                        for dx in 0..s {
                            let px = x + (n * 4 + c) * s + dx;
                            let py = y + r * s + dy;
                            if px < iw && (py * iw + px) * 3 + 2 < img.len() {
                                img[(py * iw + px) * 3..][..3].copy_from_slice(&colour);
                            }
                        }
                    }
                }
            }
        }
    }
}

/// The error map as a PNG, scaled to at most 1024 px wide, with a legend
/// bar (0 … max error, in scan pixels) along the bottom.
pub fn write_error_png(path: &Path, map: &[f32], w: u32, h: u32) -> Result<()> {
    let max = map.iter().copied().filter(|v| v.is_finite()).fold(0.0f32, f32::max).max(1e-6);
    let scale = (w.max(h) as f32 / 1024.0).max(1.0);
    let (ow, oh) = (((w as f32 / scale) as usize).max(1), ((h as f32 / scale) as usize).max(1));
    let legend = 60;
    let ih = oh + legend;
    let mut img = vec![255u8; ow * ih * 3];
    for y in 0..oh {
        for x in 0..ow {
            let v = map[((y as f32 * scale) as usize).min(h as usize - 1) * w as usize + ((x as f32 * scale) as usize).min(w as usize - 1)];
            let c = if v.is_finite() { ramp(v / max) } else { [255, 255, 255] };
            img[(y * ow + x) * 3..][..3].copy_from_slice(&c);
        }
    }
    let bar_w = ow.saturating_sub(40).max(1);
    for y in oh + 8..oh + 28 {
        for x in 0..bar_w {
            let c = ramp(x as f32 / bar_w as f32);
            img[(y * ow + 20 + x.min(ow - 21)) * 3..][..3].copy_from_slice(&c);
        }
    }
    draw_text(&mut img, ow, (20, oh + 34), "0", 3, [0, 0, 0]);
    draw_text(&mut img, ow, (ow.saturating_sub(20 + 4 * 3 * 6), oh + 34), &format!("{max:.3}"), 3, [0, 0, 0]);
    save_png(path, ow as u32, ih as u32, &img)
}

/// The correction matrix of a cell-mode GCM: x corrections left, y right,
/// each on a diverging ramp scaled to its largest magnitude.
pub fn write_gcm_png(path: &Path, gcm: &Gcm<'_>) -> Result<()> {
    let grid = gcm.t.grid;
    let band = gcm.prepare(0, grid.height);
    let k = gcm.spec.k;
    let (nx, ny) = (grid.width.div_ceil(k) as usize, grid.height.div_ceil(k) as usize);
    let mut dc = vec![f64::NAN; nx * ny];
    let mut dr = vec![f64::NAN; nx * ny];
    let mut miss = None;
    for j in 0..ny {
        let h = gcm.node_heights(j as i64);
        let row = gcm.node_row(j as i64, &h, &mut miss);
        dc[j * nx..(j + 1) * nx].copy_from_slice(&row.dc[..nx]);
        dr[j * nx..(j + 1) * nx].copy_from_slice(&row.dr[..nx]);
    }
    drop(band);
    let scale = ((2 * nx).max(ny) as f32 / 1024.0).max(1.0);
    let (pw, ph) = (((nx as f32 / scale) as usize).max(1), ((ny as f32 / scale) as usize).max(1));
    let ow = 2 * pw + 10;
    let mut img = vec![255u8; ow * ph * 3];
    for (p, data) in [dc, dr].iter().enumerate() {
        let m = data.iter().copied().filter(|v| v.is_finite()).fold(0.0f64, |a, v| a.max(v.abs())).max(1e-9);
        for y in 0..ph {
            for x in 0..pw {
                let v = data[((y as f32 * scale) as usize).min(ny - 1) * nx + ((x as f32 * scale) as usize).min(nx - 1)];
                let c = if v.is_finite() { ramp((0.5 + 0.5 * v / m) as f32) } else { [255, 255, 255] };
                img[(y * ow + p * (pw + 10) + x) * 3..][..3].copy_from_slice(&c);
            }
        }
    }
    save_png(path, ow as u32, ph as u32, &img)
}
