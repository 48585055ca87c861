//! Input rasters.

/// The `tiff` decoder limits we use everywhere: generous for real scans,
/// but a header claiming an absurd size must not allocate.
pub fn decoder_limits() -> tiff::decoder::Limits {
    let mut l = tiff::decoder::Limits::default();
    l.decoding_buffer_size = 1 << 30;
    l.ifd_value_size = 64 << 20;
    l.intermediate_buffer_size = 256 << 20;
    l
}
