//! Output pixels whose kernel would read a pixel the scan marks as holding
//! no image (its alpha, nodata value or internal mask: `HoleMark`) get no
//! value: nothing of a collar, a cut-out or a nodata fill is mixed into
//! the image's edge. The image's edge moves in by at most the kernel's
//! reach (a pixel under bilinear).

use crate::io::source::{HoleMark, MaskRuns, SourceImage, Window};
use crate::resample::{Kernel, Sample, View};

/// The scan's holes as the resampler asks about them.
pub struct ScanHoles<'a> {
    mark: HoleMark,
    runs: Option<&'a MaskRuns>,
    src: &'a SourceImage,
    /// The kernel's reach before and after the pixel below-left of a
    /// position (point kernels).
    before: i64,
    after: i64,
    nearest: bool,
}

impl<'a> ScanHoles<'a> {
    /// The scan's holes for `kernel`, where the scan marks any.
    pub fn of(src: &'a SourceImage, mark: Option<HoleMark>, kernel: Kernel) -> Option<ScanHoles<'a>> {
        let mark = mark?;
        let r = kernel.radius() as i64;
        Some(ScanHoles { mark, runs: src.mask_runs(), src, before: (r - 1).max(0), after: r, nearest: kernel == Kernel::Nearest })
    }

    /// Whether the point kernel at scan position `at` reads only image.
    #[inline]
    pub fn clear_at<T: Sample>(&self, view: &View<T>, (c, r): (f64, f64)) -> bool {
        if self.nearest {
            return self.clear_pixel(view, (c, r));
        }
        let (i, j) = ((c - 0.5).floor() as i64, (r - 0.5).floor() as i64);
        self.clear_box(view, [i - self.before, j - self.before, i + self.after, j + self.after])
    }

    /// Whether the scan pixel holding position `at` is image.
    pub fn clear_pixel<T: Sample>(&self, view: &View<T>, (c, r): (f64, f64)) -> bool {
        let (i, j) = (c.floor() as i64, r.floor() as i64);
        self.clear_box(view, [i, j, i, j])
    }

    /// Whether an area kernel's footprint `quad` covers only image (its
    /// bounding box of pixels, a little more than the footprint).
    pub fn clear_quad<T: Sample>(&self, view: &View<T>, quad: &[[f64; 2]; 4]) -> bool {
        let (lo, hi) = quad
            .iter()
            .fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(lo, hi), p| ([lo[0].min(p[0]), lo[1].min(p[1])], [hi[0].max(p[0]), hi[1].max(p[1])]));
        self.clear_box(view, [lo[0].floor() as i64, lo[1].floor() as i64, hi[0].floor() as i64, hi[1].floor() as i64])
    }

    /// Whether scan pixels `[i0, j0]..=[i1, j1]` (clipped to the scan) all
    /// hold image.
    fn clear_box<T: Sample>(&self, view: &View<T>, [i0, j0, i1, j1]: [i64; 4]) -> bool {
        let info = &self.src.info;
        let (i0, j0) = (i0.max(0), j0.max(0));
        let (i1, j1) = (i1.min(info.width as i64 - 1), j1.min(info.height as i64 - 1));
        if i0 > i1 || j0 > j1 {
            return true;
        }
        if let Some(runs) = self.runs.filter(|_| self.mark == HoleMark::Mask) {
            return (j0..=j1).all(|j| runs.all_set(j as u32, i0 as u32, i1 as u32));
        }
        let inside = i0 >= view.x0 && j0 >= view.y0 && i1 < view.x0 + view.w && j1 < view.y0 + view.h;
        if inside {
            return pixels_clear(self.mark, view, [i0, j0, i1, j1]);
        }
        // Past the window (rare: the plan reads a margin): read them alone.
        let mut win = Window::default();
        let (w, h) = ((i1 - i0 + 1) as u32, (j1 - j0 + 1) as u32);
        if self.src.read_window(i0 as u32, j0 as u32, w, h, &mut win).is_err() {
            return false;
        }
        pixels_clear(self.mark, &View::<T>::new(&win, info.bands, info.width, info.height), [i0, j0, i1, j1])
    }
}

/// Whether the pixels of the box, all inside `view`, hold image.
fn pixels_clear<T: Sample>(mark: HoleMark, view: &View<T>, [i0, j0, i1, j1]: [i64; 4]) -> bool {
    let bands = view.bands;
    (j0..=j1).all(|j| {
        (i0..=i1).all(|i| {
            let at = (((j - view.y0) * view.stride + (i - view.x0)) as usize) * bands;
            let px = &view.data[at..at + bands];
            !mark.is_hole(|b| px[b].to_f32(), bands)
        })
    })
}
