//! Reading scans and rasters, writing the tiled GeoTIFF.

pub mod bounded_read;
pub mod cached_raster;
pub mod chunk_cache;
pub mod chunk_codec;
pub mod chunked_raster;
pub mod file_pool;
pub mod format;
pub mod geotiff;
pub mod mapped_file;
pub mod mmap_guard;
pub mod overwrite;
pub mod publish;
pub mod read_raster;
pub mod sidecars;
pub mod source;
pub mod tiff_out;
pub mod toml_lengths;
