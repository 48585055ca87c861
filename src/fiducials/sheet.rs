//! A PNG sheet of the marks for a quick look: each mark's surroundings
//! (stretched to full contrast), its number, and a diagonal cross where its
//! centre was found (green: used, red: left out); a grey square for a
//! mark not found at all.

use super::gray::Gray;
use super::Detection;
use crate::error::{Error, Result};
use crate::io::source::SourceImage;
use std::path::Path;

/// Side of a mark's square on the sheet, pixels.
const CELL: usize = 160;
const GAP: usize = 6;

/// The sheet's pixels (RGB) and size.
pub fn render(src: &SourceImage, det: &Detection) -> Result<(usize, usize, Vec<u8>)> {
    let n = det.marks.len();
    let cols = n.min(4);
    let rows = n.div_ceil(cols);
    let (w, h) = (cols * CELL + (cols + 1) * GAP, rows * CELL + (rows + 1) * GAP);
    let mut rgb = vec![40u8; w * h * 3];
    let scale = 1.0 / det.pixel_mm[0].min(det.pixel_mm[1]);
    for (k, m) in det.marks.iter().enumerate() {
        let (ox, oy) = (GAP + (k % cols) * (CELL + GAP), GAP + (k / cols) * (CELL + GAP));
        let mut put = |x: usize, y: usize, c: [u8; 3]| {
            if x < CELL && y < CELL {
                let o = ((oy + y) * w + ox + x) * 3;
                rgb[o..o + 3].copy_from_slice(&c);
            }
        };
        if let Some(at) = m.px {
            // The mark's square at a whole reduction that fits the cell.
            let side = (2.0 * m.radius_mm * scale * 1.2).max(24.0);
            let f = (side / CELL as f64).ceil().max(1.0) as u32;
            let reach = if f == 1 { side / 2.0 } else { (CELL as f64 * f as f64) / 2.0 };
            let x0 = (at[0] - reach).floor().max(0.0) as u32;
            let y0 = (at[1] - reach).floor().max(0.0) as u32;
            let g = Gray::read(src, (x0, y0, (2.0 * reach) as u32, (2.0 * reach) as u32), f)?;
            let (lo, hi) = g.data.iter().fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
            let span = (hi - lo).max(1e-6);
            // Magnified when the mark is small.
            let zoom = (CELL / g.width.max(1)).max(1);
            for y in 0..CELL {
                for x in 0..CELL {
                    let (i, j) = (x / zoom, y / zoom);
                    if i < g.width && j < g.height {
                        let v = ((g.at(i, j) - lo) / span * 255.0) as u8;
                        put(x, y, [v, v, v]);
                    }
                }
            }
            let colour = if m.used { [0, 230, 0] } else { [240, 0, 0] };
            let cx = ((at[0] - x0 as f64) / f as f64 * zoom as f64) as i64;
            let cy = ((at[1] - y0 as f64) / f as f64 * zoom as f64) as i64;
            for d in -12i64..=12 {
                if d.abs() > 3 {
                    for (x, y) in [(cx + d, cy + d), (cx + d, cy - d)] {
                        if x >= 0 && y >= 0 {
                            put(x as usize, y as usize, colour);
                        }
                    }
                }
            }
        } else {
            for y in 0..CELL {
                for x in 0..CELL {
                    put(x, y, [90, 90, 90]);
                }
            }
        }
        // The mark's number, top left.
        crate::study::maps::draw_text(&mut rgb, w, (ox + 4, oy + 4), &m.mark.to_string(), 3, [255, 220, 0]);
    }
    Ok((w, h, rgb))
}

/// Writes the sheet as a PNG to `path` (through a temporary beside it).
pub fn write(path: &Path, (w, h, rgb): (usize, usize, Vec<u8>)) -> Result<()> {
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, w as u32, h as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut wr = enc.write_header().map_err(|e| Error::format(path, e.to_string()))?;
        wr.write_image_data(&rgb).map_err(|e| Error::format(path, e.to_string()))?;
    }
    crate::io::publish::write_file(path, &bytes)
}
