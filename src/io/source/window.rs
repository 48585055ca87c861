//! A window of the scan, copied or decoded: its place and its bytes.

/// A window of the scan, chunky (band-interleaved), native-endian samples.
/// The bytes live in a `u64` buffer so that they can be viewed as any
/// sample type without misalignment.
#[derive(Default)]
pub struct Window {
    pub x0: u32,
    pub y0: u32,
    pub w: u32,
    pub h: u32,
    buf: Vec<u64>,
    len: usize,
}

impl Window {
    /// A window holding `bytes` (for tests and small rasters).
    #[cfg(any(test, feature = "internals"))]
    pub fn from_bytes(x0: u32, y0: u32, w: u32, h: u32, bytes: &[u8]) -> Window {
        let mut win = Window { x0, y0, w, h, ..Default::default() };
        win.resize(bytes.len());
        win.bytes_mut().copy_from_slice(bytes);
        win
    }
    /// Room for `len` bytes, whatever they held: every caller writes them
    /// all (the chunks a window meets tile it). Zeroing a reused window
    /// first took ~4 % of the CPU time of runs that copy their windows.
    pub(super) fn resize(&mut self, len: usize) {
        // Exactly: grown by doubling, the four windows in flight held up
        // to twice their share each (37 MB where the plan gives 22).
        self.buf.reserve_exact(len.div_ceil(8).saturating_sub(self.buf.len()));
        self.buf.resize(len.div_ceil(8), 0);
        self.len = len;
    }
    pub fn bytes(&self) -> &[u8] {
        &bytemuck::cast_slice(&self.buf[..])[..self.len]
    }
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        &mut bytemuck::cast_slice_mut(&mut self.buf[..])[..self.len]
    }
}
