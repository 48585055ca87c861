//! Tile layout of the output raster: tiles of `tile × tile` pixels, a band is
//! one row of tiles (the unit of work of the pipeline; one column of tiles
//! where the pipeline walks the grid transposed).

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileLayout {
    pub width: u32,
    pub height: u32,
    pub tile: u32,
}

impl TileLayout {
    pub fn tiles_across(&self) -> u32 {
        self.width.div_ceil(self.tile)
    }
    pub fn tiles_down(&self) -> u32 {
        self.height.div_ceil(self.tile)
    }
    pub fn tile_count(&self) -> u64 {
        self.tiles_across() as u64 * self.tiles_down() as u64
    }
    /// Output rows `[start, end)` of band `b` (clipped to the image).
    pub fn band_rows(&self, b: u32) -> (u32, u32) {
        let s = b * self.tile;
        (s, (s + self.tile).min(self.height))
    }
}
