//! The cells' labels as the render reads them: each row of cells as runs
//! of one image. A plan's labels are a few large regions, so a row holds a
//! handful of runs, and the render's labels take kilobytes, not two bytes
//! a cell (3 MB for a block of 64 frames at 256 MiB): the render's memory
//! then does not grow with the mosaic's area.

use super::plan::NONE;

pub struct LabelRuns {
    /// Row y's runs are `first[y]..first[y + 1]`.
    first: Vec<u32>,
    /// Each run's first cell across, and its label.
    start: Vec<u32>,
    label: Vec<u16>,
}

impl LabelRuns {
    /// The runs of `label`, rows of `cw` cells.
    pub fn new(label: &[u16], cw: usize) -> LabelRuns {
        let mut runs = LabelRuns { first: vec![0], start: Vec::new(), label: Vec::new() };
        for row in label.chunks(cw.max(1)) {
            let mut last = None;
            for (x, &l) in row.iter().enumerate() {
                if last != Some(l) {
                    runs.start.push(x as u32);
                    runs.label.push(l);
                    last = Some(l);
                }
            }
            runs.first.push(runs.start.len() as u32);
        }
        runs
    }

    /// The label of cell (x, y); [`NONE`] outside the rows.
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> u16 {
        let Some(&end) = self.first.get(y + 1) else { return NONE };
        let row = self.first[y] as usize..end as usize;
        let n = self.start[row.clone()].partition_point(|&s| s as usize <= x);
        if n == 0 {
            return NONE;
        }
        self.label[row.start + n - 1]
    }

    /// The bytes they take.
    pub fn bytes(&self) -> u64 {
        (self.first.len() * 4 + self.start.len() * 4 + self.label.len() * 2) as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every cell's label read back from the runs is the cell's own, on
    /// rows that start, end and change anywhere (and a row of one run).
    #[test]
    fn runs_give_back_every_label() {
        let (cw, ch) = (37, 23);
        let label: Vec<u16> = (0..cw * ch)
            .map(|k| {
                let (x, y) = (k % cw, k / cw);
                match y {
                    0 => 4,
                    _ if (x * 7 + y * 3) % 11 == 0 => NONE,
                    _ => ((x / (3 + y % 5)) % 3) as u16,
                }
            })
            .collect();
        let runs = LabelRuns::new(&label, cw);
        for y in 0..ch {
            for x in 0..cw {
                assert_eq!(runs.at(x, y), label[y * cw + x], "cell ({x}, {y})");
            }
        }
        assert_eq!(runs.at(0, ch), NONE, "below the rows");
    }

    /// Two images split by a slanting seam: two runs a row.
    #[test]
    fn regions_take_two_runs_a_row() {
        let (cw, ch) = (1000, 600);
        let label: Vec<u16> = (0..cw * ch).map(|k| u16::from(k % cw > 300 + k / cw / 2)).collect();
        let runs = LabelRuns::new(&label, cw);
        assert_eq!(runs.bytes(), (ch as u64 + 1) * 4 + ch as u64 * 2 * 6);
        assert_eq!((runs.at(300, 0), runs.at(301, 0), runs.at(599, 599), runs.at(600, 599)), (0, 1, 0, 1));
    }
}
