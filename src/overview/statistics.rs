//! Band statistics of the full-resolution pixels that have a value, summed
//! tile by tile while the tiles stream, written as GDAL's `STATISTICS_*`
//! metadata so that a viewer stretches the display without reading the
//! image first.

use super::reduce::{TileLayout, ValidBy};
use crate::io::format::SampleType;

/// Per band: how many samples, their sum and sum of squares, least and
/// most. Integer samples are summed exactly (so that the result does not
/// depend on the order tiles come in: pieces assembled give a single
/// run's), floating-point ones in f64.
#[derive(Clone, Debug, PartialEq)]
pub struct BandStats {
    pub count: u64,
    pub int_sum: u128,
    pub int_sum_sq: u128,
    pub float_sum: f64,
    pub float_sum_sq: f64,
    pub min: f64,
    pub max: f64,
}

impl Default for BandStats {
    fn default() -> Self {
        BandStats { count: 0, int_sum: 0, int_sum_sq: 0, float_sum: 0.0, float_sum_sq: 0.0, min: f64::INFINITY, max: f64::NEG_INFINITY }
    }
}

impl BandStats {
    fn sums(&self) -> (f64, f64) {
        (self.int_sum as f64 + self.float_sum, self.int_sum_sq as f64 + self.float_sum_sq)
    }
}

/// The statistics of every band, and of how many pixels the image has.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Statistics {
    pub bands: Vec<BandStats>,
    /// Pixels looked at (those of the image, with a value or not).
    pub pixels: u64,
}

impl Statistics {
    /// The statistics of one tile: its first `extent` columns and rows, the
    /// pixels that have a value (`valid` under a mask, else known `by`).
    pub fn of_tile(lay: TileLayout, by: ValidBy, pixels: &[u8], valid: Option<&[u8]>, extent: (usize, usize)) -> Statistics {
        let b = lay.bands;
        let mut bands = vec![BandStats::default(); b];
        let px = b * lay.sample.bytes();
        let mut sample = vec![0f64; b];
        for y in 0..extent.1 {
            for x in 0..extent.0 {
                let i = y * lay.tile + x;
                let p = &pixels[i * px..(i + 1) * px];
                for (k, s) in sample.iter_mut().enumerate() {
                    *s = match lay.sample {
                        SampleType::U8 => p[k] as f64,
                        SampleType::U16 => u16::from_ne_bytes([p[2 * k], p[2 * k + 1]]) as f64,
                        SampleType::F32 => f32::from_ne_bytes(p[4 * k..4 * k + 4].try_into().expect("4 bytes")) as f64,
                    };
                }
                let has = match by {
                    ValidBy::Mask => valid.is_some_and(|v| v[i] != 0),
                    ValidBy::Nodata(v) => sample.iter().any(|&s| s != v),
                    ValidBy::Nan => sample.iter().all(|s| !s.is_nan()),
                    ValidBy::Alpha => sample[b - 1] != 0.0,
                };
                if !has {
                    continue;
                }
                for (st, &s) in bands.iter_mut().zip(&sample) {
                    st.count += 1;
                    if lay.sample == SampleType::F32 {
                        st.float_sum += s;
                        st.float_sum_sq += s * s;
                    } else {
                        st.int_sum += s as u128;
                        st.int_sum_sq += (s as u128) * (s as u128);
                    }
                    st.min = st.min.min(s);
                    st.max = st.max.max(s);
                }
            }
        }
        Statistics { bands, pixels: (extent.0 * extent.1) as u64 }
    }

    /// Adds another tile's.
    pub fn add(&mut self, other: &Statistics) {
        if self.bands.is_empty() {
            self.bands = vec![BandStats::default(); other.bands.len()];
        }
        for (a, b) in self.bands.iter_mut().zip(&other.bands) {
            a.count += b.count;
            a.int_sum += b.int_sum;
            a.int_sum_sq += b.int_sum_sq;
            a.float_sum += b.float_sum;
            a.float_sum_sq += b.float_sum_sq;
            a.min = a.min.min(b.min);
            a.max = a.max.max(b.max);
        }
        self.pixels += other.pixels;
    }

    /// GDAL's metadata XML (its TIFF tag 42112) with each band's minimum,
    /// maximum, mean, standard deviation (of the population, as GDAL's)
    /// and the share of pixels with a value, in per cent. `None` when no
    /// pixel has a value.
    pub fn gdal_metadata(&self) -> Option<String> {
        let mut xml = String::from("<GDALMetadata>\n");
        for (k, b) in self.bands.iter().enumerate() {
            if b.count == 0 {
                return None;
            }
            let n = b.count as f64;
            let (sum, sum_sq) = b.sums();
            let mean = sum / n;
            let std = (sum_sq / n - mean * mean).max(0.0).sqrt();
            let valid = 100.0 * n / self.pixels.max(1) as f64;
            for (name, v) in [("MAXIMUM", b.max), ("MEAN", mean), ("MINIMUM", b.min), ("STDDEV", std), ("VALID_PERCENT", valid)] {
                xml += &format!("  <Item name=\"STATISTICS_{name}\" sample=\"{k}\">{v}</Item>\n");
            }
        }
        Some(xml + "</GDALMetadata>")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_add_up_to_the_image_and_skip_pixels_without_a_value() {
        // Two 2×2 grey tiles; the second's right column is padding.
        let lay = TileLayout { tile: 2, bands: 1, sample: SampleType::U8 };
        let a = Statistics::of_tile(lay, ValidBy::Mask, &[1, 2, 3, 200], Some(&[1, 1, 1, 0]), (2, 2));
        let b = Statistics::of_tile(lay, ValidBy::Mask, &[6, 99, 8, 99], Some(&[1, 1, 1, 1]), (1, 2));
        let mut all = Statistics::default();
        all.add(&a);
        all.add(&b);
        // Values 1, 2, 3, 6, 8 of 6 image pixels.
        assert_eq!(all.bands[0], BandStats { count: 5, int_sum: 20, int_sum_sq: 114, min: 1.0, max: 8.0, ..Default::default() });
        let xml = all.gdal_metadata().unwrap();
        assert!(xml.contains("<Item name=\"STATISTICS_MEAN\" sample=\"0\">4</Item>"), "{xml}");
        assert!(xml.contains("<Item name=\"STATISTICS_STDDEV\" sample=\"0\">2.6076809620810595</Item>"), "{xml}");
        assert!(xml.contains("STATISTICS_VALID_PERCENT\" sample=\"0\">83.33333333333333<"), "{xml}");
        // Float NaN and a nodata value.
        let lay = TileLayout { tile: 2, bands: 1, sample: SampleType::F32 };
        let v: Vec<f32> = vec![f32::NAN, 1.5, -2.0, 0.0];
        let s = Statistics::of_tile(lay, ValidBy::Nan, bytemuck::cast_slice(&v), None, (2, 2));
        assert_eq!((s.bands[0].count, s.bands[0].min, s.bands[0].max), (3, -2.0, 1.5));
        let s = Statistics::of_tile(lay, ValidBy::Nodata(0.0), bytemuck::cast_slice(&v[1..].iter().chain(&[0.0]).copied().collect::<Vec<_>>()), None, (2, 2));
        assert_eq!(s.bands[0].count, 2);
    }
}
