//! The template generator (thesis §2.6): a mark's shape rendered at a
//! pyramid level's scale and the scan's turn, each pixel the shape's
//! coverage of it (so a template reduced 5 times looks like the scan
//! reduced 5 times), centred and scaled for the correlation (2.6.11).

use super::shape::Shape;
use nalgebra::Matrix2;

/// A rendered template: `size × size` pixels; the mark's centre at
/// `(half + ½ + offset)` in template pixels (pixel k covers [k, k+1)).
/// `weights` are the tones minus their mean, over their norm; `nonzero`
/// lists the pixels whose tone is not the background's, for a sparse sum.
#[derive(Clone, Debug)]
pub struct Template {
    pub size: usize,
    pub half: usize,
    /// Tone (0..1) minus the mean tone, divided by the norm.
    pub weights: Vec<f32>,
    /// Index and raw tone of every pixel whose tone is not zero.
    pub nonzero: Vec<(u32, f32)>,
    /// Mean raw tone and the norm of the centred tones.
    pub mean: f32,
    pub norm: f32,
}

/// Sub-samples a template pixel along each axis.
const SUPER: usize = 5;

impl Template {
    /// `to_px`: mark mm (x right, y up) → level pixels (column right, row
    /// down); `radius_mm` the half side covered; `offset` the centre's
    /// fractional place in level pixels.
    #[must_use]
    pub fn render(shape: &Shape, to_px: &Matrix2<f64>, radius_mm: f64, offset: [f64; 2]) -> Option<Template> {
        let inv = to_px.try_inverse()?;
        let scale = to_px.determinant().abs().sqrt();
        let half = (radius_mm * scale).ceil().max(1.0) as usize;
        let size = 2 * half + 1;
        let mut tones = vec![0f32; size * size];
        let step = 1.0 / SUPER as f64;
        for j in 0..size {
            for i in 0..size {
                let mut s = 0.0f32;
                for b in 0..SUPER {
                    for a in 0..SUPER {
                        // Sample position relative to the mark's centre.
                        let u = i as f64 + (a as f64 + 0.5) * step - (half as f64 + 0.5 + offset[0]);
                        let v = j as f64 + (b as f64 + 0.5) * step - (half as f64 + 0.5 + offset[1]);
                        let mm = inv * nalgebra::Vector2::new(u, v);
                        s += shape.tone(mm.x, mm.y);
                    }
                }
                tones[j * size + i] = s / (SUPER * SUPER) as f32;
            }
        }
        Self::from_tones(size, half, tones)
    }

    fn from_tones(size: usize, half: usize, tones: Vec<f32>) -> Option<Template> {
        let n = tones.len() as f64;
        let mean = tones.iter().map(|&t| t as f64).sum::<f64>() / n;
        let var: f64 = tones.iter().map(|&t| (t as f64 - mean).powi(2)).sum();
        if !(var > 1e-9) {
            return None;
        }
        let norm = var.sqrt();
        let weights = tones.iter().map(|&t| ((t as f64 - mean) / norm) as f32).collect();
        let nonzero = tones.iter().enumerate().filter(|(_, &t)| t != 0.0).map(|(k, &t)| (k as u32, t)).collect();
        Some(Template { size, half, weights, nonzero, mean: mean as f32, norm: norm as f32 })
    }
}
