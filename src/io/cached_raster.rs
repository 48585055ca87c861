//! A raster's samples (one band, as f32) read a chunk at a time into a
//! bounded cache, for lookups scattered over a file larger than memory:
//! DEMs and GeoTIFF geoid grids.

use crate::io::chunk_cache::ChunkCache;
use crate::io::chunked_raster::ChunkedRaster;
use std::cell::RefCell;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// Out-of-core samples: the file's strips or tiles, decoded on demand.
pub struct CachedRaster {
    raster: ChunkedRaster,
    cache: std::sync::Mutex<ChunkCache<f32>>,
    /// Buffers of a chunk's bytes as stored, used again by the reads.
    bytes: std::sync::Mutex<Vec<Vec<u8>>>,
    rescale: Option<Rescale>,
    /// Its own number, for the threads' last looks ([`LAST`]).
    id: u64,
}

/// Numbers for the rasters, never given twice.
static NEXT_ID: AtomicU64 = AtomicU64::new(0);

/// A thread's last look: (raster, chunk, samples).
type LastLook = Option<(u64, usize, Arc<Vec<f32>>)>;

thread_local! {
    /// The chunk this thread looked into last. Most looks fall in the chunk of the one before, and then need
    /// neither the cache's lock nor its hash: on a DEM of 5029² read
    /// through the cache, those took a fifth of a mosaic's CPU time.
    static LAST: RefCell<LastLook> = const { RefCell::new(None) };
}

/// Lets go of the chunk this thread looked into last: a thread about to
/// wait long (an image of a mosaic between its turns) would otherwise keep
/// it alive past the cache, a strip as wide as the DEM each.
pub fn let_go_of_last_look() {
    LAST.with(|last| *last.borrow_mut() = None);
}

/// Stored values to heights by the band's scale and offset (GDAL's
/// metadata); the stored nodata value becomes NaN first.
#[derive(Clone, Copy)]
pub struct Rescale {
    pub scale: f64,
    pub offset: f64,
    pub nodata: Option<f64>,
}

impl Rescale {
    pub fn apply(&self, v: &mut [f32]) {
        for s in v {
            *s = if s.is_nan() || self.nodata == Some(*s as f64) { f32::NAN } else { (*s as f64 * self.scale + self.offset) as f32 };
        }
    }
}

/// The fewest chunks a cache of `raster` holds: those the corners of a
/// cell may lie in (four tiles, or two strips).
pub fn least_chunks(raster: &ChunkedRaster) -> usize {
    if raster.chunk.0 >= raster.width {
        2
    } else {
        4
    }
}

impl CachedRaster {
    /// `raster`'s samples through a cache of about `cache_bytes`, each
    /// chunk rescaled as it is decoded.
    pub fn new(raster: ChunkedRaster, cache_bytes: usize, rescale: Option<Rescale>) -> CachedRaster {
        let least = least_chunks(&raster);
        CachedRaster {
            raster,
            cache: std::sync::Mutex::new(ChunkCache::new(cache_bytes).keeping(least)),
            bytes: Default::default(),
            rescale,
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
        }
    }

    /// The most its cache holds, bytes.
    pub fn cache_bytes(&self) -> usize {
        self.cache.lock().map_or(0, |c| c.budget())
    }

    /// The raster read.
    pub fn raster(&self) -> &ChunkedRaster {
        &self.raster
    }

    /// Samples of a window (see [`ChunkedRaster::read_window`]),
    /// rescaled; read past the cache.
    pub fn read_window(&self, at: [usize; 4]) -> crate::error::Result<Vec<f32>> {
        let mut v = self.raster.read_window(at)?;
        if let Some(r) = self.rescale {
            r.apply(&mut v);
        }
        Ok(v)
    }

    /// Every `step`-th sample, row-major (NaN where its chunk cannot be
    /// read), each chunk decoded at most once, past the cache: a summary's
    /// samples spread row by row over a file of tiles would decode each
    /// row of tiles again for every row sampled (a tiled 8272² DEM: minutes).
    pub fn samples(&self, step: usize) -> Vec<f32> {
        let step = step.max(1);
        let (w, h) = (self.raster.width, self.raster.height);
        let (cw, ch) = self.raster.chunk;
        let mut out = vec![f32::NAN; (w * h).div_ceil(step)];
        for ty in 0..h.div_ceil(ch) {
            for tx in 0..self.raster.across() {
                let (r0, r1, c0, c1) = (ty * ch, ((ty + 1) * ch).min(h), tx * cw, ((tx + 1) * cw).min(w));
                let mut chunk: Option<Option<Vec<f32>>> = None;
                for j in r0..r1 {
                    let mut k = (j * w + c0).div_ceil(step) * step;
                    while k < j * w + c1 {
                        let decoded = chunk.get_or_insert_with(|| {
                            let mut v = self.raster.chunk(ty * self.raster.across() + tx).ok()?;
                            if let Some(r) = self.rescale {
                                r.apply(&mut v);
                            }
                            Some(v)
                        });
                        if let Some(v) = decoded {
                            out[k / step] = v.get((j - r0) * cw + (k - j * w - c0)).copied().unwrap_or(f32::NAN);
                        }
                        k += step;
                    }
                }
            }
        }
        out
    }

    /// The same samples through a cache of about `cache_bytes` (at least
    /// the chunks the corners of a cell may lie in: four tiles, or two
    /// strips).
    pub fn recached(self, cache_bytes: usize) -> CachedRaster {
        let (cw, ch) = self.raster.chunk;
        let chunk = cw * ch * 4;
        let keep = (cache_bytes / chunk).max(least_chunks(&self.raster));
        CachedRaster::new(self.raster, keep * chunk, self.rescale)
    }

    fn chunk(&self, k: usize) -> Option<Arc<Vec<f32>>> {
        if let Some(c) = self.cache.lock().ok()?.get(k) {
            return Some(c);
        }
        // Read into an evicted chunk's room through a buffer used before:
        // a DEM larger than its cache is read strip by strip many times,
        // and fresh memory for each strip cost page faults and left the
        // allocator holding freed pieces.
        let mut v = self.cache.lock().ok()?.spare();
        let mut bytes = self.bytes.lock().ok()?.pop().unwrap_or_default();
        let read = self.raster.chunk_into(k, &mut bytes, &mut v);
        self.bytes.lock().ok()?.push(bytes);
        read.ok()?;
        if let Some(r) = self.rescale {
            r.apply(&mut v);
        }
        let v = Arc::new(v);
        self.cache.lock().ok()?.put(k, v.clone());
        Some(v)
    }

    /// `look` at chunk `k`'s samples: the thread's last chunk where it is
    /// that one, else from the cache (or the file), which then becomes the
    /// thread's last. `None` when the chunk cannot be read.
    fn with_chunk<R>(&self, k: usize, look: impl FnOnce(&[f32]) -> R) -> Option<R> {
        LAST.with(|last| {
            if let Some((id, kk, c)) = &*last.borrow() {
                if (*id, *kk) == (self.id, k) {
                    return Some(look(c));
                }
            }
            let c = self.chunk(k)?;
            let r = look(&c);
            *last.borrow_mut() = Some((self.id, k, c));
            Some(r)
        })
    }

    /// Sample (i, j); NaN when its chunk cannot be read.
    pub fn get(&self, i: usize, j: usize) -> f32 {
        let (cw, ch) = self.raster.chunk;
        let (tx, ty) = (i / cw, j / ch);
        // Chunks come at their full width (strips span the image).
        self.with_chunk(ty * self.raster.across() + tx, |c| c.get((j - ty * ch) * cw + (i - tx * cw)).copied().unwrap_or(f32::NAN)).unwrap_or(f32::NAN)
    }

    /// Samples (i0, j0), (i1, j0), (i0, j1), (i1, j1): from one look into
    /// the cache where the four share a chunk (all but the cells on a
    /// chunk's edge). Four looks (lock, hash, reference count) for each
    /// bilinear height took ~9 % of a 1 GiB RPC run's CPU time.
    pub fn corners(&self, i0: usize, j0: usize, i1: usize, j1: usize) -> [f32; 4] {
        let (cw, ch) = self.raster.chunk;
        let (tx, ty) = (i0 / cw, j0 / ch);
        if i1 / cw != tx || j1 / ch != ty {
            return [self.get(i0, j0), self.get(i1, j0), self.get(i0, j1), self.get(i1, j1)];
        }
        self.with_chunk(ty * self.raster.across() + tx, |c| {
            let at = |i: usize, j: usize| c.get((j - ty * ch) * cw + (i - tx * cw)).copied().unwrap_or(f32::NAN);
            [at(i0, j0), at(i1, j0), at(i0, j1), at(i1, j1)]
        })
        .unwrap_or([f32::NAN; 4])
    }
}
