//! Tiles made in bands of tile columns (`--band-order columns`) are made
//! transposed: each row the resampler makes is a column of the output's
//! tiles. A task makes a few such rows into a block, then writes them
//! across.

/// The distance in pixels between a block's rows of `w` pixels of `pixel`
/// bytes: at least `w`, and an odd number of 64-byte cache lines (or
/// nearly), so that the rows' lines at one column fall into different sets
/// of the L1 cache. Rows of 4096 8-bit RGB pixels lie 192 lines apart,
/// which put all sixteen in one set and made [`gather`] twice as slow.
pub fn block_stride(w: usize, pixel: usize) -> usize {
    let lines = (w * pixel).div_ceil(64) | 1;
    (lines * 64).div_ceil(pixel)
}

/// Gives `pieces[x]` pixel `x` of each of the first `rows` rows of `block`
/// (rows `stride` pixels apart), in row order: block row `j` becomes place
/// `j` of every piece. Pixels are `pixel` bytes; each piece holds `rows`.
pub fn gather<T: bytemuck::Pod>(block: &[u8], rows: usize, stride: usize, pixel: usize, pieces: &mut [&mut [T]]) {
    macro_rules! by_size {
        ($($n:literal)*) => {
            match pixel {
                $($n => {
                    let from: &[[u8; $n]] = bytemuck::cast_slice(block);
                    for (x, piece) in pieces.iter_mut().enumerate() {
                        let to: &mut [[u8; $n]] = bytemuck::cast_slice_mut(piece);
                        for (j, p) in to[..rows].iter_mut().enumerate() {
                            *p = from[j * stride + x];
                        }
                    }
                })*
                _ => {
                    for (x, piece) in pieces.iter_mut().enumerate() {
                        let to: &mut [u8] = bytemuck::cast_slice_mut(piece);
                        for (j, p) in to[..rows * pixel].chunks_exact_mut(pixel).enumerate() {
                            let at = (j * stride + x) * pixel;
                            p.copy_from_slice(&block[at..at + pixel]);
                        }
                    }
                }
            }
        };
    }
    if pixel == 3 {
        // 8-bit RGB (the common scan): four bytes moved a pixel, the
        // fourth written over by the next pixel's, but at the ends. Three
        // bytes at a time took two loads and two stores a pixel.
        for (x, piece) in pieces.iter_mut().enumerate() {
            let to: &mut [u8] = bytemuck::cast_slice_mut(piece);
            let to = &mut to[..rows * 3];
            for j in 0..rows {
                let (at, o) = ((j * stride + x) * 3, j * 3);
                match (block.get(at..at + 4), to.get_mut(o..o + 4)) {
                    (Some(from), Some(to)) => to.copy_from_slice(from),
                    _ => to[o..o + 3].copy_from_slice(&block[at..at + 3]),
                }
            }
        }
        return;
    }
    // Every pixel a scan can have: 1–4 samples of 1, 2 or 4 bytes.
    by_size!(1 2 4 6 8 12 16)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_become_columns_for_every_pixel_width() {
        // Widths of the sized and the byte-wise paths.
        for pixel in [1, 2, 3, 4, 5, 6, 8, 10, 12, 16] {
            let (w, rows) = (7, 5);
            let stride = block_stride(w, pixel);
            let block: Vec<u8> = (0..rows * stride * pixel).map(|i| (i * 7 + 3) as u8).collect();
            let mut store = vec![0u8; w * rows * pixel];
            let mut pieces: Vec<&mut [u8]> = store.chunks_exact_mut(rows * pixel).collect();
            gather(&block, rows, stride, pixel, &mut pieces);
            for x in 0..w {
                for j in 0..rows {
                    for k in 0..pixel {
                        assert_eq!(store[(x * rows + j) * pixel + k], block[(j * stride + x) * pixel + k], "pixel {pixel}, x {x}, row {j}");
                    }
                }
            }
        }
    }

    #[test]
    fn sixteen_block_rows_fall_into_sixteen_cache_sets() {
        // A 64-set L1 cache of 64-byte lines: the line under column 0 of
        // rows 0..16 is in a set of its own for each row. Rows right after
        // one another would share sets at widths like 4096 RGB pixels.
        for (w, pixel) in [(4096, 3), (4096, 1), (4352, 3), (7, 5), (1000, 8), (256, 4), (2048, 16)] {
            let s = block_stride(w, pixel);
            assert!(s >= w && (s - w) * pixel <= 64 + pixel, "{w} {pixel}: {s}");
            let mut sets: Vec<usize> = (0..16).map(|j| j * s * pixel / 64 % 64).collect();
            sets.sort();
            sets.dedup();
            assert_eq!(sets.len(), 16, "{w} {pixel}: stride {s}");
        }
        assert_eq!(block_stride(4096, 3), 4118);
    }
}
