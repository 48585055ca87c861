//! Runs of scan positions along an output row that step by differences:
//! what the GCM hands the resampler where `A + c` is smooth between node
//! columns.

/// Output pixels `first..end` of a row, in one gap between node columns.
/// Where `stepped`, the scan position at pixel x is a quadratic in
/// m = x − anchor (`anchor` is the gap's, or the piece's, first pixel),
/// written in forward differences so that it steps by additions:
/// `c + m·dc + m(m − 1)/2·ddc` (and so for r). Straight spans have
/// `ddc = ddr = 0`. Where not stepped (a refined cell, a node without a
/// value), `Gcm::fill_exact` works the positions out pixel by pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    pub stepped: bool,
    pub first: usize,
    pub end: usize,
    pub anchor: usize,
    pub c: f64,
    pub r: f64,
    pub dc: f64,
    pub dr: f64,
    pub ddc: f64,
    pub ddr: f64,
}

impl Span {
    /// The positions of pixels `first..end`; `ramp` holds 0, 1, 2, … at
    /// least as many.
    #[inline]
    pub fn fill(&self, ramp: &[f64], cols: &mut [f64], rows: &mut [f64]) {
        let off = (self.first - self.anchor) as f64;
        if ramp.len() < cols.len() || self.ddc != 0.0 || self.ddr != 0.0 {
            for (j, (oc, or)) in cols.iter_mut().zip(rows.iter_mut()).enumerate() {
                (*oc, *or) = self.at(self.first + j);
            }
            return;
        }
        for ((oc, or), m) in cols.iter_mut().zip(rows.iter_mut()).zip(ramp) {
            *oc = self.c + (off + m) * self.dc;
            *or = self.r + (off + m) * self.dr;
        }
    }

    /// Consecutive spans (left to right, as `Gcm::row_spans` makes them)
    /// cut where they cross the edges of tiles `tile` columns wide that
    /// start at column `origin`: (tile index from `origin`, the piece). The
    /// tile is followed along the row, with no division per span.
    pub fn by_tile(spans: &[Span], origin: usize, tile: usize) -> impl Iterator<Item = (usize, Span)> + '_ {
        let mut rest = spans.iter();
        let mut current: Option<(&Span, usize)> = None;
        let (mut t, mut tile_end) = (0, origin + tile);
        std::iter::from_fn(move || loop {
            let (span, first) = match current {
                Some((s, first)) if first < s.end => (s, first),
                _ => {
                    let s = rest.next()?;
                    current = Some((s, s.first));
                    continue;
                }
            };
            while first >= tile_end {
                t += 1;
                tile_end += tile;
            }
            let end = tile_end.min(span.end);
            current = Some((span, end));
            return Some((t, Span { first, end, ..*span }));
        })
    }

    /// The scan position at output column `x`.
    #[inline]
    pub fn at(&self, x: usize) -> (f64, f64) {
        let m = x as f64 - self.anchor as f64;
        let t = 0.5 * m * (m - 1.0);
        (self.c + m * self.dc + t * self.ddc, self.r + m * self.dr + t * self.ddr)
    }

    /// A box (columns, rows: `[c_min, r_min, c_max, r_max]`) holding every
    /// position of pixels `first..end`: the ends', widened by the most a
    /// quadratic strays from its chord, |dd|·(n − 1)²/8.
    pub fn bounds(&self) -> [f64; 4] {
        let ((c0, r0), (c1, r1)) = (self.at(self.first), self.at(self.end.max(self.first + 1) - 1));
        let n = self.end.saturating_sub(self.first).max(1) as f64 - 1.0;
        let (sc, sr) = (self.ddc.abs() * n * n / 8.0, self.ddr.abs() * n * n / 8.0);
        [c0.min(c1) - sc, r0.min(r1) - sr, c0.max(c1) + sc, r0.max(r1) + sr]
    }
}
