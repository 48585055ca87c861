//! A raster read whole into memory: for a caller that wants an
//! orthophoto's (or a piece's) pixels as an array, not for the pipeline,
//! which streams.

use super::format::SampleType;
use super::source::{MaskRuns, SourceImage, Window};
use crate::Result;
use std::path::Path;

/// A raster's pixels, interleaved by pixel in native byte order.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct Raster {
    pub pixels: Vec<u8>,
    pub width: u32,
    pub height: u32,
    pub bands: u32,
    pub sample: SampleType,
    /// A byte a pixel, 1 where it has a value, when the file has an
    /// internal mask.
    pub mask: Option<Vec<u8>>,
    pub nodata: Option<f64>,
}

/// Reads `path` whole (any format the pipeline reads as a scan).
pub fn read_raster(path: &Path) -> Result<Raster> {
    let img = SourceImage::open(path, 1 << 20)?;
    let mut win = Window::default();
    img.read_window(0, 0, img.info.width, img.info.height, &mut win)?;
    let mask = match img.info.mask {
        Some(_) => {
            let runs = MaskRuns::read(&img)?;
            let w = img.info.width as usize;
            let mut bytes = vec![0u8; w * img.info.height as usize];
            for (r, row) in bytes.chunks_exact_mut(w).enumerate() {
                for &[a, b] in runs.row(r as u32) {
                    row[a as usize..b as usize].fill(1);
                }
            }
            Some(bytes)
        }
        None => None,
    };
    let info = &img.info;
    Ok(Raster { pixels: win.bytes().to_vec(), width: info.width, height: info.height, bands: info.bands, sample: info.sample, mask, nodata: info.nodata })
}
