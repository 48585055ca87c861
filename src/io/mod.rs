//! Reading scans and rasters, writing the tiled GeoTIFF.

pub mod assemble;
pub mod geotiff;
pub mod maps;
pub mod mmap_guard;
pub mod source;
pub mod tiff_out;
