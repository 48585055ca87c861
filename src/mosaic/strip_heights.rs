//! The DEM posts a strip's images look up, held a *cohort* at a time: the
//! images whose first band lies in one block of tile rows (as tall as the
//! median image) share a DEM of the posts under their grids, read when the
//! first of them starts and let go when the last of them ends. A strip
//! then holds about four images' height of posts however tall the block,
//! and each post is read about twice (a cohort's images reach into the
//! next block).

use super::plan::Plan;
use super::render::ImageWork;
use crate::dem::Dem;
use crate::error::Result;
use std::collections::BTreeMap;
use std::sync::Arc;

/// One cohort: the tiles its images' grids cover (first column, first row,
/// end column, end row: the bands it is alive through), its images not yet
/// started.
struct Cohort {
    tiles: [u32; 4],
    waiting: usize,
}

pub struct StripHeights {
    /// A cohort's block, tile rows.
    rows: u32,
    cohorts: BTreeMap<u32, Cohort>,
    /// The DEMs of the cohorts some image of which is still to start.
    held: BTreeMap<u32, Vec<Arc<Dem>>>,
    given: Vec<bool>,
    /// How the posts are held, once settled for a budget.
    how: Holding,
}

impl StripHeights {
    pub fn new(works: &[ImageWork]) -> StripHeights {
        let span = |w: &ImageWork| {
            let (first, last) = (w.bands.keys().next().copied().unwrap_or(0), w.bands.keys().last().copied().unwrap_or(0));
            (first, last + 1)
        };
        let mut heights: Vec<u32> = works.iter().map(|w| span(w).1 - span(w).0).collect();
        heights.sort_unstable();
        let rows = heights.get(heights.len() / 2).copied().unwrap_or(1).max(1);
        let mut cohorts: BTreeMap<u32, Cohort> = BTreeMap::new();
        for w in works {
            let (r0, r1) = span(w);
            let c0 = w.bands.values().map(|c| c.0).min().unwrap_or(0);
            let c1 = w.bands.values().map(|c| c.1).max().unwrap_or(0);
            let c = cohorts.entry(r0 / rows).or_insert(Cohort { tiles: [c0, r0, c1, r1], waiting: 0 });
            c.tiles = [c.tiles[0].min(c0), c.tiles[1].min(r0), c.tiles[2].max(c1), c.tiles[3].max(r1)];
            c.waiting += 1;
        }
        StripHeights { rows, cohorts, held: BTreeMap::new(), given: vec![false; works.len()], how: Holding { hold: false, cache: 0, bytes: 0 } }
    }

    /// The mosaic's pixels under tiles `[c0, r0, c1, r1)`.
    fn pixels(plan: &Plan, [c0, r0, c1, r1]: [u32; 4], tile: u32) -> [u32; 4] {
        [c0 * tile, r0 * tile, (c1 * tile).min(plan.grid.width), (r1 * tile).min(plan.grid.height)]
    }

    /// How the strip's cohorts hold their heights within `memory`: the
    /// posts of the cohorts alive at once, where they fit the DEMs' share
    /// of it, else a cache each (their share of that share, up to 16 MB);
    /// and the most bytes that takes at once (the plan's own caches too).
    pub fn holding(&self, plan: &Plan, tile: u32, memory: u64) -> Holding {
        let posts: Vec<([u32; 4], u64)> = self.cohorts.values().map(|c| (c.tiles, plan.dem_posts_under(Self::pixels(plan, c.tiles, tile)))).collect();
        let alive = |b: u32| posts.iter().filter(move |(t, _)| t[1] <= b + 1 && b < t[3]);
        let most_posts = posts.iter().map(|(t, _)| alive(t[1]).map(|(_, n)| n).sum::<u64>()).max().unwrap_or(0);
        let most_alive = posts.iter().map(|(t, _)| alive(t[1]).count() as u64).max().unwrap_or(1).max(1);
        let share = memory / super::plan::DEM_SHARE;
        let caches = plan.dems.iter().map(|d| d.held_bytes()).sum::<u64>();
        let grids = plan.dems.iter().filter(|d| d.is_grid()).count() as u64;
        match most_posts <= share {
            true => Holding { hold: true, cache: 0, bytes: most_posts + caches },
            false => {
                let cache = (share / most_alive).min(16 << 20);
                Holding { hold: false, cache, bytes: most_alive * grids * cache + caches }
            }
        }
    }

    /// Holds the posts as [`StripHeights::holding`] says for `memory`.
    pub fn settle(&mut self, plan: &Plan, tile: u32, memory: u64) {
        self.how = self.holding(plan, tile, memory);
    }

    /// Gives each image that starts at band `b` (its first band `b + 1`
    /// at most) its cohort's DEMs, held as settled; returns which were
    /// given, whose DEMs the caller takes back once their threads hold
    /// their own.
    pub fn give(&mut self, plan: &Plan, works: &mut [ImageWork], b: u32, tile: u32) -> Result<Vec<usize>> {
        let mut now = Vec::new();
        for (j, w) in works.iter_mut().enumerate() {
            let first = w.bands.keys().next().copied().unwrap_or(u32::MAX);
            if self.given[j] || first > b + 1 {
                continue;
            }
            let key = first / self.rows;
            let Some(cohort) = self.cohorts.get_mut(&key) else { continue };
            let dems = match self.held.get(&key) {
                Some(d) => d.clone(),
                None => {
                    let d = plan.dems_for(Self::pixels(plan, cohort.tiles, tile), self.how.hold, self.how.cache)?;
                    self.held.insert(key, d.clone());
                    d
                }
            };
            w.dem = Some((dems[plan.images[w.image].dem].clone(), plan.crs.clone()));
            self.given[j] = true;
            now.push(j);
            cohort.waiting -= 1;
            if cohort.waiting == 0 {
                // Its images' threads hold it now, and let go of it as they end.
                self.held.remove(&key);
            }
        }
        Ok(now)
    }
}

/// How a strip's cohorts hold their heights ([`StripHeights::holding`]).
pub struct Holding {
    /// Their posts in memory (else through a cache each).
    pub hold: bool,
    /// Each one's cache, bytes, where not.
    pub cache: u64,
    /// The most they take at once, bytes.
    pub bytes: u64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{Gsd, OutputGrid};

    fn work(image: usize, rows: std::ops::Range<u32>, cols: (u32, u32)) -> ImageWork {
        ImageWork {
            image,
            origin: (cols.0, rows.start),
            bands: rows.map(|b| (b, cols)).collect(),
            opts: crate::options::RectifyOptions::new("s".into(), "c".into(), crate::options::DemSource::Height(0.0), "o".into()),
            grid: OutputGrid { x0: 0.0, y0: 0.0, gsd: Gsd::square(1.0), width: 1, height: 1 },
            dem: None,
        }
    }

    /// Images grouped by the block of tile rows their first band lies in,
    /// blocks as tall as the median image; each cohort covers its images'
    /// tiles and waits for all of them.
    #[test]
    fn images_are_grouped_by_the_block_their_first_band_lies_in() {
        let works = [work(0, 0..4, (0, 3)), work(1, 1..5, (2, 6)), work(2, 4..8, (0, 3)), work(3, 7..10, (4, 8)), work(4, 9..13, (1, 2))];
        let h = StripHeights::new(&works);
        assert_eq!(h.rows, 4, "the median image is 4 bands tall");
        let got: Vec<(u32, [u32; 4], usize)> = h.cohorts.iter().map(|(&k, c)| (k, c.tiles, c.waiting)).collect();
        assert_eq!(got, vec![(0, [0, 0, 6, 5], 2), (1, [0, 4, 8, 10], 2), (2, [1, 9, 2, 13], 1)]);
        assert_eq!(h.given, vec![false; 5]);
    }
}
