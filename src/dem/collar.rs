//! A DEM's collar: the nodata posts joined, side by side, to the grid's
//! edge. Tools that cut a DSM to the data's extent (OpenDroneMap,
//! gdalwarp with a cutline) leave the rest of the rectangle nodata: that
//! is where the DEM does not reach, not a hole in its data, and lookups
//! there fall under the policy for points outside the DEM.

/// The collar's posts, as runs of columns a row.
#[derive(Debug, Clone, PartialEq)]
pub struct Collar {
    /// Row `j`'s runs are `runs[row_start[j]..row_start[j + 1]]`.
    row_start: Vec<u32>,
    /// `[first, end)` columns.
    runs: Vec<(u32, u32)>,
}

/// The most runs of nodata a grid is searched with (some 50 MB of
/// bookkeeping): past it the nodata posts are all taken as holes.
const MAX_RUNS: usize = 4 << 20;

impl Collar {
    /// The collar of a `width`×`height` grid whose row `j`'s nodata runs
    /// `voids(j, runs)` appends; `None` where no nodata touches the edge
    /// (or the grid has more than [`MAX_RUNS`] runs of it).
    /// Runs are joined where they share a column in neighbouring rows (four
    /// neighbours: a diagonal gap between two posts of data does not
    /// join a hole inside to the collar), by union–find over the runs.
    pub fn find(width: usize, height: usize, mut voids: impl FnMut(usize, &mut Vec<(u32, u32)>)) -> Option<Collar> {
        let mut runs: Vec<(u32, u32)> = Vec::new();
        let mut row_start = vec![0u32];
        let mut parent: Vec<u32> = Vec::new();
        let mut edge: Vec<bool> = Vec::new();
        fn root(parent: &mut [u32], mut k: u32) -> u32 {
            while parent[k as usize] != k {
                parent[k as usize] = parent[parent[k as usize] as usize];
                k = parent[k as usize];
            }
            k
        }
        for j in 0..height {
            let start = runs.len();
            voids(j, &mut runs);
            if runs.len() > MAX_RUNS {
                return None;
            }
            for (k, &(a, b)) in runs.iter().enumerate().skip(start) {
                parent.push(k as u32);
                edge.push(j == 0 || j + 1 == height || a == 0 || b as usize == width);
            }
            // Join with the row above: runs that share a column.
            let above = if j == 0 { start..start } else { row_start[j - 1] as usize..start };
            let (mut p, mut q) = (above.start, start);
            while p < above.end && q < runs.len() {
                let (ra, rb) = (runs[p], runs[q]);
                if ra.0.max(rb.0) < ra.1.min(rb.1) {
                    let (x, y) = (root(&mut parent, p as u32), root(&mut parent, q as u32));
                    if x != y {
                        parent[x as usize] = y;
                        edge[y as usize] |= edge[x as usize];
                    }
                }
                if ra.1 <= rb.1 {
                    p += 1;
                } else {
                    q += 1;
                }
            }
            row_start.push(runs.len() as u32);
        }
        let mut collar = Collar { row_start: vec![0], runs: Vec::new() };
        for j in 0..height {
            let row = row_start[j] as usize..row_start[j + 1] as usize;
            for (k, &run) in runs.iter().enumerate().take(row.end).skip(row.start) {
                let r = root(&mut parent, k as u32);
                if edge[r as usize] {
                    collar.runs.push(run);
                }
            }
            collar.row_start.push(collar.runs.len() as u32);
        }
        (!collar.runs.is_empty()).then_some(collar)
    }

    /// Is post (i, j) in the collar?
    pub fn contains(&self, i: usize, j: usize) -> bool {
        let Some(&[from, to]) = self.row_start.get(j..j + 2).and_then(|s| <&[u32; 2]>::try_from(s).ok()) else { return false };
        let row = &self.runs[from as usize..to as usize];
        let k = row.partition_point(|r| (r.1 as usize) <= i);
        row.get(k).is_some_and(|r| r.0 as usize <= i)
    }

    #[cfg(test)]
    /// How many posts the collar holds.
    pub fn posts(&self) -> u64 {
        self.runs.iter().map(|r| u64::from(r.1 - r.0)).sum()
    }
}

/// Appends the runs of `row` whose samples `void` says are nodata.
pub fn runs_of<T: Copy>(row: impl Iterator<Item = T>, void: impl Fn(T) -> bool, out: &mut Vec<(u32, u32)>) {
    let mut open: Option<u32> = None;
    let mut n = 0u32;
    for (i, v) in row.enumerate() {
        let i = i as u32;
        match (void(v), open) {
            (true, None) => open = Some(i),
            (false, Some(a)) => {
                out.push((a, i));
                open = None;
            }
            _ => {}
        }
        n = i + 1;
    }
    if let Some(a) = open {
        out.push((a, n));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn collar_of(grid: &[&str]) -> Option<Collar> {
        let rows: Vec<Vec<bool>> = grid.iter().map(|r| r.chars().map(|c| c == '.').collect()).collect();
        Collar::find(rows[0].len(), rows.len(), |j, out| runs_of(rows[j].iter().copied(), |v| v, out))
    }

    #[test]
    fn nodata_joined_to_the_edge_is_the_collar_and_holes_inside_are_not() {
        // '.' nodata, '#' data: a collar reaching in by a winding bay (down,
        // right, then up again), a hole inside, a hole touching the collar
        // only at a corner.
        let c = collar_of(&[
            "..######", //
            ".#######", //
            ".#.###.#", //
            ".#.##.##", //
            "...#####", //
            "########",
        ])
        .expect("a collar");
        let inside = |i, j| c.contains(i, j);
        assert!(inside(0, 0) && inside(1, 0) && inside(0, 4) && inside(2, 4) && inside(2, 2), "the bay, down then up");
        assert!(!inside(6, 2) && !inside(5, 3), "a hole that meets the bay only at a corner");
        assert!(!inside(3, 3) && !inside(7, 5) && !inside(9, 0) && !inside(0, 9));
        assert_eq!(c.posts(), 10);
        assert!(collar_of(&["###", "#.#", "###"]).is_none(), "a hole inside only");
    }

    #[test]
    fn runs_are_read_to_the_row_end() {
        let mut out = Vec::new();
        runs_of([1.0f32, f32::NAN, f32::NAN, 2.0, f32::NAN].into_iter(), f32::is_nan, &mut out);
        assert_eq!(out, vec![(1, 3), (4, 5)]);
    }
}
