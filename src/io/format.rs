//! What every TIFF reader and writer here shares: the sample types and the decoder's limits.

/// The `tiff` decoder limits we use everywhere: generous for real scans,
/// but a header claiming an absurd size must not allocate.
pub fn decoder_limits() -> tiff::decoder::Limits {
    let mut l = tiff::decoder::Limits::default();
    l.decoding_buffer_size = 1 << 30;
    l.ifd_value_size = 64 << 20;
    l.intermediate_buffer_size = 256 << 20;
    l
}

/// Sample types we read and write.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum SampleType {
    U8,
    U16,
    F32,
}

impl SampleType {
    pub fn bytes(self) -> usize {
        match self {
            SampleType::U8 => 1,
            SampleType::U16 => 2,
            SampleType::F32 => 4,
        }
    }

    /// The samples in words: "16-bit unsigned".
    pub fn describe(self) -> &'static str {
        match self {
            SampleType::U8 => "8-bit unsigned",
            SampleType::U16 => "16-bit unsigned",
            SampleType::F32 => "32-bit floating-point",
        }
    }
}
