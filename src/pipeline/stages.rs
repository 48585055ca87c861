//! The stages of `rectify` and the threads that run them (see `mod.rs`).

use super::config::{BandOrder, BigTiff, DemSource, RectifyConfig};
use super::plan::{band_scan_rows, plan_band, read_ahead_rows, Chunk};
use super::report::{peak_rss_mib, Report, ScanInfo, StageTimes};
use crate::accuracy;
use crate::camera::file::Camera;
use crate::dem::{Dem, Lookup};
use crate::error::{Error, Result};
use crate::gcm::{BandGcm, Gcm, NodeHeights};
use crate::geom::OutputGrid;
use crate::io::source::{SampleType, SourceImage, Window};
use crate::io::tiff_out::{encode_tile, reserve, tiff_write_error, verify, write_placed, Chunking, Compression, GeoTags, OutputSpec, PendingFile, WriteError};
use crate::resample::{resample_row, resample_spans, span_position, Kernel, Sample, SpanOutcome, View};
use crate::transform::footprint::{auto_grid, mean_gsd};
use crate::transform::{Approx, Transform, Trend};
use crossbeam_channel::bounded;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The output pixels of one chunk, tile by tile, in the output sample type.
enum Raw {
    U8(Vec<u8>),
    U16(Vec<u16>),
    F32(Vec<f32>),
}

/// Output buffers handed back by the encoder for the next chunk: allocating
/// and freeing multi-MB buffers on different threads leaves the allocator's
/// per-thread arenas holding tens of MB nobody uses.
trait Recycle: Sized {
    fn take(raw: Option<Raw>) -> Vec<Self>;
}

macro_rules! recycle {
    ($t:ty, $v:ident) => {
        impl Recycle for $t {
            fn take(raw: Option<Raw>) -> Vec<$t> {
                match raw {
                    Some(Raw::$v(v)) => v,
                    _ => Vec::new(),
                }
            }
        }
    };
}
recycle!(u8, U8);
recycle!(u16, U16);
recycle!(f32, F32);

impl Raw {
    fn bytes(&self) -> &[u8] {
        match self {
            Raw::U8(v) => v,
            Raw::U16(v) => bytemuck::cast_slice(v),
            Raw::F32(v) => bytemuck::cast_slice(v),
        }
    }
}

/// An encoded tile on its way to the writer: compressed bytes of its own, or
/// (uncompressed output) a piece of the resampled chunk, written from there;
/// the chunk's buffer goes back to the resampler when its last tile is
/// written.
enum Tile {
    Owned(Vec<u8>),
    Shared { chunk: Option<Arc<Raw>>, range: std::ops::Range<usize>, free: crossbeam_channel::Sender<Raw> },
}

impl AsRef<[u8]> for Tile {
    fn as_ref(&self) -> &[u8] {
        match self {
            Tile::Owned(v) => v,
            Tile::Shared { chunk, range, .. } => &chunk.as_ref().expect("held until dropped").bytes()[range.clone()],
        }
    }
}

impl Drop for Tile {
    fn drop(&mut self) {
        if let Tile::Shared { chunk, free, .. } = self {
            if let Some(Ok(raw)) = chunk.take().map(Arc::try_unwrap) {
                let _ = free.try_send(raw);
            }
        }
    }
}

struct DemMsg {
    first_j: i64,
    heights: Vec<NodeHeights>,
}

/// The node rows of the band before, kept for the next: neighbouring bands
/// share the node rows at their edge (two of 18 a band of 256 rows at
/// k = 16, two of 23 at k = 12), which need not be worked out again.
struct SharedRows<T> {
    first_j: i64,
    rows: Vec<T>,
}

impl<T> Default for SharedRows<T> {
    fn default() -> Self {
        SharedRows { first_j: 0, rows: Vec::new() }
    }
}

impl<T: Clone> SharedRows<T> {
    /// Rows `j0..=j1`: those of the band before as they were, the others
    /// from `make`; and how many were the band before's.
    fn rows(&mut self, j0: i64, j1: i64, mut make: impl FnMut(i64) -> T) -> (Vec<T>, usize) {
        let mut reused = 0;
        let rows: Vec<T> = (j0..=j1)
            .map(|j| match usize::try_from(j - self.first_j).ok().and_then(|k| self.rows.get(k)) {
                Some(row) => {
                    reused += 1;
                    row.clone()
                }
                None => make(j),
            })
            .collect();
        self.first_j = j0;
        self.rows.clone_from(&rows);
        (rows, reused)
    }
}

struct ReadMsg<'a> {
    band: u32,
    gcm: Arc<BandGcm>,
    chunk: Chunk,
    win: Window,
    /// The window's rows in place in the mapped scan (then `win` only
    /// carries the position), and their stride in bytes.
    in_place: Option<(&'a [u8], usize)>,
}

impl ReadMsg<'_> {
    fn view<'v, T: Sample>(&'v self, info: &crate::io::source::SourceInfo) -> View<'v, T> {
        let w = &self.win;
        match self.in_place {
            Some((bytes, stride)) => {
                let data = bytemuck::try_cast_slice(bytes).expect("mapped_rows checks alignment");
                View::in_place(data, w.x0, w.y0, w.w, w.h, stride / info.pixel_bytes(), info.bands, info.width, info.height)
            }
            None => View::new(w, info.bands, info.width, info.height),
        }
    }
}


fn dem_miss_error(dem: &Dem, (x, y, l): (f64, f64, Lookup)) -> Error {
    let what = match l {
        Lookup::Hole => "a hole (nodata) in the DEM",
        _ => "outside the DEM",
    };
    Error::format(
        &dem.path,
        format!("no height at ground point ({x:.2}, {y:.2}), {what}; choose --dem-hole / --dem-outside nodata or a height"),
    )
}

/// Output row band `b` of a grid cut in `tile`-row bands.
fn band_rows(grid: &OutputGrid, tile: u32, b: u32) -> (u32, u32) {
    (b * tile, ((b + 1) * tile).min(grid.height))
}

/// Runs `f`, adding its wall time to `acc`.
fn timed<R>(acc: &mut Duration, f: impl FnOnce() -> R) -> R {
    let t = Instant::now();
    let r = f();
    *acc += t.elapsed();
    r
}

/// Rows of a transposed chunk made by one task: the most of 128, 64, 32
/// and 16 (a tile is a multiple of 16) that divides the tile. Each task
/// writes its rows across the whole chunk, so fewer, larger tasks sweep it
/// fewer times: on a 1 GiB scan turned 90°, user time 2.1 s with 128 rows
/// against 2.4–2.7 s with 64 and 2.9–3.5 s with 16 (3 runs each); 256, one
/// task a chunk, 2.7–3.2 s.
fn column_group(tile: usize) -> usize {
    [128, 64, 32, 16].into_iter().find(|g| tile % g == 0).unwrap_or(1)
}

/// Bytes of output between two background syncs.
const FLUSH_EVERY: usize = 64 << 20;

/// Orthorectifies `cfg.image` into `cfg.output`. `cancel` may be set from
/// another thread (a signal handler) to stop the run; the output is then
/// not created.
pub fn rectify(cfg: &RectifyConfig, cancel: &AtomicBool) -> Result<Report> {
    let wall = Instant::now();
    if cfg.tile == 0 || cfg.tile % 16 != 0 || cfg.tile > 4096 {
        return Err(Error::Usage(format!("--tile {} must be a multiple of 16 up to 4096", cfg.tile)));
    }
    if cfg.gcm.k == 0 {
        return Err(Error::Usage("--sparsity must be at least 1".into()));
    }
    if cfg.memory < 16 << 20 {
        return Err(Error::Usage("--memory must be at least 16M".into()));
    }
    // The output folder must take a file before any work starts.
    let pending = PendingFile::create(&cfg.output)?;

    let camera = match &cfg.camera_file {
        Some(f) => f.clone().build(&cfg.camera)?,
        None => Camera::read(&cfg.camera)?,
    };
    let model = camera.model();
    let src = SourceImage::open(&cfg.image, (cfg.memory / 12) as usize)?;
    let mut dem = match &cfg.dem {
        // The DEM's share of the budget (see the memory plan below).
        DemSource::File(p) => Dem::open_within(p, camera.crs.epsg, cfg.memory / 8)?,
        DemSource::Height(h) => Dem::flat(*h),
        DemSource::ModelHeight => match &camera.sensor {
            crate::camera::file::Sensor::Rpc(r) => Dem::flat(r.height_hint()),
            crate::camera::file::Sensor::Frame(_) => return Err(Error::Usage("give --dem FILE or --height METRES".into())),
        },
    };
    dem.on_hole = cfg.dem_hole;
    dem.on_outside = cfg.dem_outside;
    let (sw, sh) = (src.info.width, src.info.height);
    let z_guess = dem.mean_height().unwrap_or_else(|| camera.height_hint());
    // Where the scan and the DEM do not meet, the DEM is the file to name.
    let on_dem = |e: Error| match e {
        Error::Geometry(m) => Error::format(&dem.path, m),
        e => e,
    };
    let gsd = match cfg.gsd {
        Some(g) if g > 0.0 && g.is_finite() => g,
        Some(g) => return Err(Error::Usage(format!("--gsd {g} must be positive"))),
        None => mean_gsd(model, &dem, sw, sh, z_guess).map_err(on_dem)?,
    };
    let grid = match cfg.bounds {
        Some(b) => OutputGrid::snapped(b[0], b[1], b[2], b[3], gsd)
            .ok_or_else(|| Error::Usage(format!("--bounds {b:?} at GSD {gsd} is empty")))?,
        None => auto_grid(model, &dem, sw, sh, z_guess, gsd).map_err(on_dem)?,
    };
    if grid.width > 1 << 21 || grid.height > 1 << 21 {
        return Err(Error::Usage(format!("output of {}×{} pixels is beyond 2M pixels a side", grid.width, grid.height)));
    }
    let area = [grid.x0, grid.y0 - grid.gsd * grid.height as f64, grid.x0 + grid.gsd * grid.width as f64, grid.y0];
    let plane = match cfg.trend {
        Trend::Plane => dem.trend_plane(area),
        Trend::Mean => dem.mean_plane(area),
    }
    .ok_or_else(|| Error::format(&dem.path, "no height anywhere inside the output area"))?;
    let approx = Approx::new(model, &grid, plane)
        .ok_or_else(|| Error::Geometry("the terrain plane is not in front of the camera".into()))?;
    let band_order = match cfg.band_order {
        BandOrder::Auto => fewer_scan_rows(&approx, &grid, cfg.tile),
        order => order,
    };
    // Bands of tile columns walk the transposed grid: its rows are the
    // output's columns.
    let columns = band_order == BandOrder::Columns;
    let (t, approx) = if columns {
        (Transform::transposed(model, &dem, grid), approx.transposed())
    } else {
        (Transform::new(model, &dem, grid), approx)
    };
    let mut spec_gcm = cfg.gcm;
    if cfg.auto_sparsity {
        spec_gcm.k = auto_sparsity(&dem, &grid, camera.crs.epsg);
    }
    let gcm = Gcm::new(&t, approx, spec_gcm);

    // The piece of the grid to make, in tiles (everything by default). All
    // geometry stays that of the whole grid, so pieces equal the whole.
    let (tx_all, ty_all) = (grid.width.div_ceil(cfg.tile), grid.height.div_ceil(cfg.tile));
    let [tc0, tr0, tcw, trh] = cfg.window.unwrap_or([0, 0, tx_all, ty_all]);
    if tcw == 0 || trh == 0 || tc0 + tcw > tx_all || tr0 + trh > ty_all {
        return Err(Error::Usage(format!(
            "--window {tc0},{tr0},{tcw},{trh} is not inside the output's {tx_all}×{ty_all} tiles"
        )));
    }
    let (tc1, tr1) = (tc0 + tcw, tr0 + trh);
    // The piece as walked: bands `wr0..wr1` of tile columns `wc0..wc1`
    // (transposed, bands of the output's tile columns); and where the tile
    // of a band and a walked tile column goes in the file, row-major.
    let walked = t.grid;
    let (wc0, wc1, wr0, wr1) = if columns { (tr0, tr1, tc0, tc1) } else { (tc0, tc1, tr0, tr1) };
    let tile_index = |band: u32, col: u32| -> usize {
        let (row, col) = if columns { (col, band) } else { (band, col) };
        ((row - tr0) * tcw + (col - tc0)) as usize
    };
    let piece_w = (tc1 * cfg.tile).min(grid.width) - tc0 * cfg.tile;
    let piece_h = (tr1 * cfg.tile).min(grid.height) - tr0 * cfg.tile;
    let bands_in = src.info.bands;
    let bands_out = bands_in + u32::from(cfg.alpha);
    let photometric = if src.info.photometric == 2 && bands_in >= 3 { 2 } else { 1 };
    let mut spec = OutputSpec {
        width: piece_w,
        height: piece_h,
        bands: bands_out,
        sample: src.info.sample,
        chunking: Chunking::Tiles(cfg.tile),
        compression: cfg.compress,
        bigtiff: false,
        photometric,
        alpha: cfg.alpha || src.info.has_alpha,
        geo: Some(GeoTags {
            x0: grid.x0 + (tc0 * cfg.tile) as f64 * grid.gsd,
            y0: grid.y0 - (tr0 * cfg.tile) as f64 * grid.gsd,
            gsd: grid.gsd,
            epsg: camera.crs.epsg,
            nodata: (!cfg.alpha).then_some(cfg.nodata),
        }),
    };
    spec.bigtiff = match cfg.bigtiff {
        BigTiff::Yes => true,
        BigTiff::No => false,
        BigTiff::Auto => spec.needs_bigtiff(),
    };

    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(cfg.threads)
        .build()
        .map_err(|e| Error::Usage(format!("cannot start {} threads: {e}", cfg.threads)))?;
    let mut times = StageTimes { setup: wall.elapsed().as_secs_f64(), ..Default::default() };
    let n_bands = wr1 - wr0;
    let (lines, what) = if columns { (piece_w, "columns") } else { (piece_h, "rows") };
    let progress = crate::progress::rows_bar(spec.tiles_across() as u64 * spec.tiles_down() as u64, lines as u64, what, src.info.data_bytes(), cfg.quiet);
    let failed = AtomicBool::new(false);
    let stop = || cancel.load(Ordering::Relaxed) || failed.load(Ordering::Relaxed);
    let chunks_done = AtomicU64::new(0);
    let chunks_in_place = AtomicU64::new(0);
    let stats = std::sync::Mutex::new(crate::gcm::GcmStats::default());
    let out_file = pending.file()?;
    // A second handle to the output, to start its write-back while tiles
    // are still being made: the sync before the rename then has little
    // left to wait for (0.6 s at the end of a 1 GiB output without it).
    let flush_file = out_file.try_clone().map_err(|e| Error::io(pending.path(), e))?;
    if cfg.compress == Compression::None {
        // The padding before the tiles and the tiles' bytes, all of which the
        // file will hold.
        let pad = crate::io::tiff_out::page_padding(&spec).unwrap_or(0) as u64;
        reserve(&out_file, pad + spec.tile_bytes() as u64 * spec.tiles_across() as u64 * spec.tiles_down() as u64);
    }

    // Stage results: each returns its busy time or an error.
    let (tx_dem, rx_dem) = bounded::<DemMsg>(2);
    let (tx_gcm, rx_gcm) = bounded::<Arc<BandGcm>>(2);
    let (tx_read, rx_read) = bounded::<ReadMsg>(1);
    // The memory plan: four scan windows in flight (being read, queued, two
    // being resampled; read in place instead, up to eight shares of mapped
    // scan rows, see below), four output chunks (two being made, queued,
    // being encoded) and the encoded tiles (in hand and queued), each a 24th
    // of the budget; the DEM an eighth (larger ones are read a chunk at a
    // time). What is left (~45 %) covers the GCM rows, the threads, the
    // program and the allocator's per-thread arenas (20–30 MB measured on
    // 1 GiB scans), so that the peak resident size stays under the budget
    // (measured at 128 MiB: 76–85 MiB on a 1 GiB scan, 66 MiB with the scan
    // turned 90°, where every window is copied, 76–81 MiB on a 4 GiB scan).
    let share = cfg.memory / 24;
    let budget_px = share / src.info.pixel_bytes().max(1) as u64;
    let max_tiles = (share / spec.tile_bytes() as u64).max(1) as u32;
    let (tx_raw, rx_raw) = bounded::<Made>(1);
    // Buffers going back up the pipeline to be used again.
    let (tx_free_win, rx_free_win) = bounded::<Window>(4);
    let (tx_free_raw, rx_free_raw) = bounded::<Raw>(4);
    let (tx_enc, rx_enc) = bounded::<(usize, Tile)>(max_tiles.max(4) as usize);

    let fail = |e: Error| {
        failed.store(true, Ordering::Relaxed);
        e
    };
    let results: Vec<Result<Duration>> = std::thread::scope(|s| {
        let h_dem = s.spawn(|| {
            let mut busy = Duration::ZERO;
            let mut before = SharedRows::default();
            for b in wr0..wr1 {
                if stop() {
                    return Err(Error::Cancelled);
                }
                let msg = timed(&mut busy, || {
                    let (y0, y1) = band_rows(&walked, cfg.tile, b);
                    let (j0, _, _) = gcm.rows_for(y0);
                    let (_, j1, _) = gcm.rows_for(y1 - 1);
                    DemMsg { first_j: j0, heights: before.rows(j0, j1, |j| gcm.node_heights(j)).0 }
                });
                if tx_dem.send(msg).is_err() {
                    return Err(Error::Cancelled);
                }
            }
            drop(tx_dem);
            Ok(busy)
        });
        let h_gcm = s.spawn(|| {
            // Owned, so that it is dropped (and the stage before it stops)
            // as soon as this stage returns, by success or by error.
            let rx_dem = rx_dem;
            let mut busy = Duration::ZERO;
            let mut before = SharedRows::default();
            for msg in rx_dem.iter() {
                if stop() {
                    return Err(Error::Cancelled);
                }
                let band = timed(&mut busy, || {
                    let mut miss = None;
                    let last_j = msg.first_j + msg.heights.len() as i64 - 1;
                    let (rows, reused) = before.rows(msg.first_j, last_j, |j| gcm.node_row(j, &msg.heights[(j - msg.first_j) as usize], &mut miss));
                    let mut band = gcm.finish_band(msg.first_j, rows, miss);
                    // Nodes worked out for this band, not those it shares with the one before.
                    band.stats.nodes -= (reused * gcm.nodes_per_row()) as u64;
                    band
                });
                if let Some(m) = band.miss {
                    return Err(fail(dem_miss_error(&dem, m)));
                }
                stats.lock().expect("stats").add(&band.stats);
                if tx_gcm.send(Arc::new(band)).is_err() {
                    return Err(Error::Cancelled);
                }
            }
            drop(tx_gcm);
            Ok(busy)
        });
        let h_read = s.spawn(|| {
            let rx_gcm = rx_gcm;
            let mut busy = Duration::ZERO;
            let margin = cfg.kernel.radius() + 2;
            // Scan windows are copied from here on (see below).
            let mut copying = false;
            // The scan rows of the band before (for the read-ahead below).
            let mut band_rows_before: Option<(u32, u32)> = None;
            for (b, band) in rx_gcm.iter().enumerate() {
                let b = wr0 + b as u32;
                let (y0, y1) = band_rows(&walked, cfg.tile, b);
                let chunks = timed(&mut busy, || plan_band(&gcm, &band, y0, y1, cfg.tile, (sw, sh), margin, budget_px, max_tiles, (wc0, wc1)));
                // The band's scan rows, and as many again the way the bands
                // move through the scan, asked for at once where they will
                // be read in place: a scan that is not in memory yet then
                // comes in large reads ahead of the workers, instead of
                // small ones that each hold up a worker's fault. Nothing is
                // read where the rows are in memory.
                let rows = band_scan_rows(&chunks);
                if let Some(rows) = rows.filter(|&(r0, r1)| !copying && (r1 - r0) as u64 * sw as u64 * src.info.pixel_bytes() as u64 <= 8 * share) {
                    let (a, b) = read_ahead_rows(rows, band_rows_before, sh);
                    src.will_need_rows(a, b - a);
                }
                band_rows_before = rows;
                for chunk in chunks {
                    if stop() {
                        return Err(Error::Cancelled);
                    }
                    let [c0, r0, c1, r1] = chunk.win;
                    // In place when the rows it spans fit six shares (a
                    // quarter of the budget): no window is copied (the
                    // windows' four shares are free) and the only scan pages
                    // resident are the rows of the chunks being resampled
                    // (at most whole rows: the kernel maps pages around each
                    // fault); the other two shares come from the budget's
                    // slack. A tall, narrow window of a turned scan would map
                    // far more pages than it uses: copy those. Once one
                    // chunk is copied, the rest of the run is copied too:
                    // mapped rows on top of the copies' buffers went past the
                    // budget (a 4 GiB scan whose bands' rows lie about at the
                    // bound peaked at 115–150 MiB; copied throughout, 76–82).
                    let span = (r1 - r0) as u64 * sw as u64 * src.info.pixel_bytes() as u64;
                    let in_place = if span <= 6 * share && !copying { src.mapped_rows(c0, r0, c1 - c0, r1 - r0).map_err(fail)? } else { None };
                    let mut win = rx_free_win.try_recv().unwrap_or_default();
                    match in_place {
                        Some(_) => {
                            (win.x0, win.y0, win.w, win.h) = (c0, r0, c1 - c0, r1 - r0);
                            chunks_in_place.fetch_add(1, Ordering::Relaxed);
                        }
                        None => {
                            // A chunk that sees no pixel of the scan decides nothing.
                            copying |= c1 > c0 && r1 > r0;
                            timed(&mut busy, || src.read_window(c0, r0, c1 - c0, r1 - r0, &mut win)).map_err(fail)?
                        }
                    }
                    if tx_read.send(ReadMsg { band: b, gcm: band.clone(), chunk, win, in_place }).is_err() {
                        return Err(Error::Cancelled);
                    }
                }
            }
            drop(tx_read);
            Ok(busy)
        });
        let h_resample = s.spawn(|| {
            let rx_read = rx_read;
            // Two chunks are resampled at once: when a worker runs out of
            // rows of the older one it starts on the newer one instead of
            // waiting for the other worker to finish (and for the pool to be
            // woken again). Measured on a 1 GiB scan with one chunk at a time:
            // the second worker started its first row 2–6 ms late in many
            // chunks, and both workers together idled ~1.4 s of 14.
            const IN_FLIGHT: usize = 2;
            let row_bytes = sw as u64 * src.info.pixel_bytes() as u64;
            let (tx_done, rx_done) = crossbeam_channel::unbounded::<Resampled>();
            let mut chunks = InFlight::default();
            let result = pool.in_place_scope(|scope| -> Result<()> {
                // Waits for the oldest chunk in flight and passes it on.
                let forward_oldest = |chunks: &mut InFlight| -> Result<()> {
                    let done = chunks.finish_oldest(&rx_done)?;
                    let _ = tx_free_win.try_send(done.win);
                    let raw = done.raw.map_err(|m| fail(dem_miss_error(&dem, m)))?;
                    chunks_done.fetch_add(1, Ordering::Relaxed);
                    tx_raw.send(Made { band: done.band, first_col: done.first_col, raw }).map_err(|_| Error::Cancelled)
                };
                for (seq, msg) in rx_read.iter().enumerate() {
                    let seq = seq as u64;
                    if stop() {
                        return Err(Error::Cancelled);
                    }
                    let rows_now = msg.in_place.map(|_| (msg.win.y0, msg.win.y0 + msg.win.h));
                    // Mapped rows stay within eight shares (the windows' four,
                    // unused when chunks are read in place, and four of the
                    // budget's slack): where the chunks in flight and this
                    // one would map more together (the first chunk of a band
                    // beside the last of the one before), the older ones are
                    // finished first, and the workers idle through the
                    // older one's last rows. With six shares, the bound of
                    // one chunk, that happened at 52 of 75 band edges of a
                    // 1 GiB scan (its chunks span ~400 rows); with eight the
                    // run took 0.976× the time, and its peak grew from
                    // 71–75 to 76–85 MiB (6 runs each).
                    while !chunks.is_empty() && chunks.rows_hull(rows_now).is_some_and(|(a, b)| (b - a) as u64 * row_bytes > 8 * share) {
                        forward_oldest(&mut chunks)?;
                    }
                    chunks.release_finished_rows(&src, rows_now);
                    let spare = rx_free_raw.try_recv().ok();
                    let tx_done = tx_done.clone();
                    let (gcm, src, walked) = (&gcm, &src, &walked);
                    chunks.start(seq, rows_now);
                    scope.spawn(move |_| {
                        let (y0, y1) = band_rows(walked, cfg.tile, msg.band);
                        let raw = match src.info.sample {
                            SampleType::U8 => resample_chunk::<u8>(gcm, src, &msg, y0, y1, cfg, bands_out, spare).map(Raw::U8),
                            SampleType::U16 => resample_chunk::<u16>(gcm, src, &msg, y0, y1, cfg, bands_out, spare).map(Raw::U16),
                            SampleType::F32 => resample_chunk::<f32>(gcm, src, &msg, y0, y1, cfg, bands_out, spare).map(Raw::F32),
                        };
                        let (band, first_col) = (msg.band, msg.chunk.x0 / cfg.tile);
                        let _ = tx_done.send(Resampled { seq, raw, win: msg.win, band, first_col });
                    });
                    while chunks.len() >= IN_FLIGHT {
                        forward_oldest(&mut chunks)?;
                    }
                }
                while !chunks.is_empty() {
                    forward_oldest(&mut chunks)?;
                }
                Ok(())
            });
            chunks.release_finished_rows(&src, None);
            result?;
            drop(tx_raw);
            Ok(chunks.busy)
        });
        let h_encode = s.spawn(|| {
            let rx_raw = rx_raw;
            let mut busy = Duration::ZERO;
            let tb = spec.tile_bytes();
            let plain = spec.compression == Compression::None;
            for Made { band, first_col, raw } in rx_raw.iter() {
                if stop() {
                    return Err(Error::Cancelled);
                }
                // The chunk holds whole tiles, one after the other (padded).
                let n = raw.bytes().len() / tb;
                let tiles: Vec<Result<Tile>> = if plain {
                    // Uncompressed: the writer writes straight from the chunk.
                    let shared = Arc::new(raw);
                    (0..n).map(|k| Ok(Tile::Shared { chunk: Some(shared.clone()), range: k * tb..(k + 1) * tb, free: tx_free_raw.clone() })).collect()
                } else {
                    let tiles = timed(&mut busy, || {
                        let bytes = raw.bytes();
                        pool.install(|| (0..n).into_par_iter().map(|k| encode_tile(&spec, bytes[k * tb..(k + 1) * tb].to_vec()).map(Tile::Owned)).collect())
                    });
                    let _ = tx_free_raw.try_send(raw);
                    tiles
                };
                for (k, tile) in tiles.into_iter().enumerate() {
                    let at = tile_index(band, first_col + k as u32);
                    if tx_enc.send((at, tile.map_err(fail)?)).is_err() {
                        return Err(Error::Cancelled);
                    }
                }
            }
            drop(tx_enc);
            Ok(busy)
        });
        let (tx_flush, rx_flush) = bounded::<()>(1);
        s.spawn(move || {
            // Errors show again, and are reported, at the final sync.
            for () in rx_flush.iter() {
                let _ = flush_file.sync_data();
            }
        });
        let h_write = s.spawn(|| {
            let (rx_enc, tx_flush) = (rx_enc, tx_flush);
            let mut unsynced = 0usize;
            let r = write_placed(out_file, &spec, || -> Result<Option<(usize, Tile)>> {
                if cancel.load(Ordering::Relaxed) {
                    return Err(Error::Cancelled);
                }
                let next = rx_enc.recv().ok();
                if let Some((_, tile)) = &next {
                    progress.inc(1);
                    unsynced += tile.as_ref().len();
                    if cfg.sync && unsynced >= FLUSH_EVERY {
                        // Never waits: a sync still running takes this one too.
                        let _ = tx_flush.try_send(());
                        unsynced = 0;
                    }
                }
                Ok(next)
            });
            drop(tx_flush);
            match r {
                // The writer's share shows as the wall time after setup.
                Ok(()) => Ok(Duration::ZERO),
                Err(WriteError::Source(e)) => Err(fail(e)),
                Err(WriteError::Tiff(e)) => Err(fail(tiff_write_error(&cfg.output, e))),
            }
        });
        [h_dem, h_gcm, h_read, h_resample, h_encode, h_write]
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|_| Err(Error::Geometry("a pipeline stage panicked".into()))))
            .collect()
    });
    progress.finish_and_clear();
    if cancel.load(Ordering::Relaxed) {
        return Err(Error::Cancelled);
    }
    // The root cause: the first error that is not a consequence of another.
    if let Some(e) = results.iter().find_map(|r| match r {
        Err(e) if !matches!(e, Error::Cancelled) => Some(e),
        _ => None,
    }) {
        return Err(clone_error(e));
    }
    if results.iter().any(|r| r.is_err()) {
        return Err(Error::Cancelled);
    }
    let d = |k: usize| results[k].as_ref().map(|d| d.as_secs_f64()).unwrap_or(0.0);
    times.dem = d(0);
    times.gcm = d(1);
    times.read = d(2);
    times.resample = d(3);
    times.encode = d(4);
    verify(pending.path(), &spec)?;
    let output_bytes = std::fs::metadata(pending.path()).map(|m| m.len()).unwrap_or(0);
    pending.publish_synced(cfg.sync)?;
    let wall_s = wall.elapsed().as_secs_f64();
    times.write = (wall_s - times.setup).max(0.0);
    let mut estimate = accuracy::sample_errors(&gcm, (walked.height / 64).max(1), 7);
    if columns {
        // Where the largest error is, on the output grid.
        estimate.argmax.swap(0, 1);
    }
    let gcm_stats = *stats.lock().expect("stats");
    Ok(Report {
        config: RectifyConfig { gcm: spec_gcm, auto_sparsity: false, band_order, ..cfg.clone() },
        grid,
        crs: camera.crs.to_string(),
        scan: ScanInfo {
            width: sw,
            height: sh,
            bands: bands_in,
            sample: src.info.sample,
            tiled: src.info.tiled,
            compression: src.info.compression,
            memory_mapped: src.is_mapped(),
            bytes: src.info.data_bytes(),
        },
        bands: n_bands,
        chunks: chunks_done.load(Ordering::Relaxed),
        chunks_in_place: chunks_in_place.load(Ordering::Relaxed),
        stage_seconds: times,
        wall_seconds: wall_s,
        input_mb_per_s: src.info.data_bytes() as f64 / 1e6 / wall_s,
        output_mpx_per_s: piece_w as f64 * piece_h as f64 / 1e6 / wall_s,
        peak_rss_mib: peak_rss_mib(),
        gcm: gcm_stats,
        accuracy_estimate: estimate,
        output_bytes,
    })
}

/// The band order that crosses fewer scan rows a band (rows on a tie): a
/// band of tile rows crosses the scan rows that `A` meets along the grid's
/// width and down a tile; a band of tile columns, down the grid's height and
/// across a tile. Measured with `A`'s rates at the grid's centre.
fn fewer_scan_rows(approx: &Approx, grid: &OutputGrid, tile: u32) -> BandOrder {
    let (u, v) = (grid.width as f64 / 2.0, grid.height as f64 / 2.0);
    let (Some((_, r)), Some((_, ru)), Some((_, rv))) = (approx.at(u, v), approx.at(u + 1.0, v), approx.at(u, v + 1.0)) else {
        return BandOrder::Rows;
    };
    let (along_u, along_v) = ((ru - r).abs(), (rv - r).abs());
    let rows = along_u * grid.width as f64 + along_v * tile as f64;
    let columns = along_v * grid.height as f64 + along_u * tile as f64;
    if columns < rows {
        BandOrder::Columns
    } else {
        BandOrder::Rows
    }
}

/// The default node spacing: 16 output pixels, or the DEM's posting in
/// output pixels where that is finer, but not under 12. Between nodes the
/// corrections are interpolated bilinearly while the DEM bends at its own
/// posts; seed 004 likewise asks for grid nodes no sparser than the DEM.
fn auto_sparsity(dem: &Dem, grid: &OutputGrid, ground_epsg: u32) -> u32 {
    let crate::dem::HeightModel::Grid(g) = &dem.model else { return 16 };
    let metres = |epsg: Option<u32>, v: f64, lat_scale: f64| {
        if epsg.and_then(crate::io::geotiff::is_geographic).unwrap_or(false) {
            v * 111_320.0 * lat_scale
        } else {
            v
        }
    };
    let (lat_mid, _) = {
        let (x, y) = grid.ground(grid.width as f64 / 2.0, grid.height as f64 / 2.0);
        match crate::geodesy::GroundCrs::from_epsg(ground_epsg).ok().and_then(|c| c.to_lonlat(x, y)) {
            Some((lon, lat)) => (lat, lon),
            None => (0.0, 0.0),
        }
    };
    let cos = lat_mid.to_radians().cos();
    let post = metres(g.epsg, g.transform[1].abs(), cos).min(metres(g.epsg, g.transform[5].abs(), 1.0));
    let gsd = metres(Some(ground_epsg), grid.gsd, 1.0);
    if !(post > 0.0 && gsd > 0.0) {
        return 16;
    }
    ((post / gsd).floor() as u32).clamp(12, 16)
}

/// Our errors hold `io::Error`s, which do not clone: rebuild one with the same text.
fn clone_error(e: &Error) -> Error {
    match e {
        Error::Io { path, source } => Error::io(path, std::io::Error::new(source.kind(), source.to_string())),
        Error::Format { path, msg } => Error::format(path, msg.clone()),
        Error::Unsupported { path, msg } => Error::unsupported(path, msg.clone()),
        Error::Config { path, field, msg } => Error::config(path, field.clone(), msg.clone()),
        Error::Limits { path, msg } => Error::limits(path, msg.clone()),
        Error::Geometry(m) => Error::Geometry(m.clone()),
        Error::Usage(m) => Error::Usage(m.clone()),
        Error::Cancelled => Error::Cancelled,
    }
}

/// Resamples the rows of one chunk; returns a DEM miss under the `error` policy.
#[allow(clippy::too_many_arguments)]
fn resample_chunk<T: Sample + Recycle>(
    gcm: &Gcm<'_>,
    src: &SourceImage,
    msg: &ReadMsg,
    y0: u32,
    y1: u32,
    cfg: &RectifyConfig,
    bands_out: u32,
    spare: Option<Raw>,
) -> std::result::Result<Vec<T>, (f64, f64, Lookup)> {
    let info = &src.info;
    let bands_in = info.bands as usize;
    let bo = bands_out as usize;
    let (x0, x1) = (msg.chunk.x0, msg.chunk.x1);
    let w = (x1 - x0) as usize;
    let view = msg.view::<T>(info);
    // Where the kernel stays inside the window (or the window reaches the
    // scan's edge, where clamping is the intended behaviour).
    let r = cfg.kernel.radius() as f64 + 1.0;
    let [c0, r0, c1, r1] = msg.chunk.win;
    let safe = [
        if c0 == 0 { f64::NEG_INFINITY } else { c0 as f64 + r },
        if r0 == 0 { f64::NEG_INFINITY } else { r0 as f64 + r },
        if c1 == info.width { f64::INFINITY } else { c1 as f64 - r },
        if r1 == info.height { f64::INFINITY } else { r1 as f64 - r },
    ];
    let fill = T::from_f32(if cfg.alpha { 0.0 } else { cfg.nodata as f32 });
    let opaque = T::from_f32(match T::TYPE {
        SampleType::U8 => 255.0,
        SampleType::U16 => 65535.0,
        SampleType::F32 => 1.0,
    });
    // Every sample is written below: keep what the buffer holds.
    let mut out = T::take(spare);
    // Tile-major: the chunk's tiles one after the other, each `tile` rows
    // of `tile` pixels; what lies beyond the grid's right or bottom edge is
    // zero (the writer sends tiles as they are).
    let t = cfg.tile as usize;
    let rows = (y1 - y0) as usize;
    let n_tiles = w.div_ceil(t);
    out.resize(n_tiles * t * t * bo, T::default());
    // Made row by row across the whole chunk, so that the kernel walks the
    // scan's rows in long runs (~10 % faster than tile by tile on a 1 GiB
    // scan). In bands of tile rows each task makes one row, and its pieces
    // are that row of each tile. Walked transposed (bands of tile columns),
    // the rows made are the tiles' columns: each task makes `column_group`
    // of them, and its pieces are their stretch of every tile row, one
    // piece for each pixel of the rows made, which goes into it at the
    // row's place.
    let transposed = gcm.t.is_transposed();
    let (group, piece_len) = if transposed { (column_group(t), column_group(t) * bo) } else { (1, t * bo) };
    let groups = t / group;
    // A task's rows (of `w` pixels) lie `stride` pixels apart.
    let stride = if transposed { super::transpose::block_stride(w, bands_in * std::mem::size_of::<T>()) } else { w };
    let mut pieces: Vec<Vec<&mut [T]>> = (0..groups).map(|_| Vec::with_capacity(out.len() / piece_len / groups)).collect();
    for (k, piece) in out.chunks_exact_mut(piece_len).enumerate() {
        pieces[k % groups].push(piece);
    }
    let direct = bo == bands_in;
    // Row `r` of the chunk into `px` (and `valid`, where the alpha band
    // needs it); scan positions (`cols`, `rws`) only where a row is not all
    // straight spans: made on first need, not zeroed for every split of the
    // chunk (1.6 % of the instructions).
    let make_row = |r: usize, cols: &mut Vec<f64>, rws: &mut Vec<f64>, px: &mut [T], valid: &mut [bool], spans: &mut Vec<crate::gcm::Span>, miss: &mut Option<(f64, f64, Lookup)>| {
        let positions = |cols: &mut Vec<f64>, rws: &mut Vec<f64>| {
            cols.resize(w, 0.0);
            rws.resize(w, 0.0);
        };
        let y = y0 + r as u32;
        // Pixels whose kernel would leave the window: read their
        // neighbourhood on their own (rare; the plan adds a margin).
        let is_safe = |(c, rr): (f64, f64)| c >= safe[0] && rr >= safe[1] && c < safe[2] && rr < safe[3];
        let reread = |at: (f64, f64), out: &mut [T]| {
            if !is_safe(at) {
                single_pixel(src, cfg, at.0, at.1, out, fill);
            }
        };
        let x0 = x0 as usize;
        if cfg.kernel == Kernel::Bilinear && gcm.row_spans(&msg.gcm, y, x0 as u32, w, spans) {
            // Straight spans: positions step in fixed point, runs
            // of them in one call; the rest (refined cells) pixel
            // by pixel.
            for run in spans.chunk_by(|p, q| p.linear == q.linear) {
                let (first, end) = (run[0].first, run[run.len() - 1].end);
                let (a, b) = (first - x0, end - x0);
                let out: &mut [T] = &mut px[a * bands_in..b * bands_in];
                let valid = &mut valid[a..b];
                let linear = run[0].linear;
                let outcome = if linear {
                    resample_spans(&view, run, out, valid, fill)
                } else {
                    positions(cols, rws);
                    gcm.fill_exact(&msg.gcm, y, first as u32, &mut cols[a..b], &mut rws[a..b], miss);
                    SpanOutcome::Checked { clamped: resample_row(cfg.kernel, &view, &cols[a..b], &rws[a..b], out, valid, fill) }
                };
                if outcome == SpanOutcome::Inside && !direct {
                    // The alpha band below reads it.
                    valid.fill(true);
                }
                if outcome == (SpanOutcome::Checked { clamped: true }) {
                    for s in run {
                        // A straight span whose ends are safe is safe throughout.
                        if linear && is_safe(span_position(s, s.first)) && is_safe(span_position(s, s.end - 1)) {
                            continue;
                        }
                        for x in s.first..s.end {
                            let j = x - first;
                            if valid[j] {
                                let at = if linear { span_position(s, x) } else { (cols[x - x0], rws[x - x0]) };
                                reread(at, &mut out[j * bands_in..(j + 1) * bands_in]);
                            }
                        }
                    }
                }
            }
        } else {
            positions(cols, rws);
            gcm.fill_row(&msg.gcm, y, x0 as u32, cols, rws, miss);
            if resample_row(cfg.kernel, &view, cols, rws, px, valid, fill) {
                for (i, p) in px.chunks_exact_mut(bands_in).enumerate().filter(|(i, _)| valid[*i]) {
                    reread((cols[i], rws[i]), p);
                }
            }
        }
    };
    let misses: Vec<Option<(f64, f64, Lookup)>> = pieces
        .par_iter_mut()
        .with_min_len((8 / group).max(1))
        .enumerate()
        .map_init(
            // The rows of a task, one after the other.
            || (Vec::new(), Vec::new(), vec![T::default(); group * stride * bands_in], vec![false; group * w], Vec::new()),
            |(cols, rws, block, valid_block, spans), (g, row_pieces)| {
                let mut miss = None;
                if transposed {
                    for j in 0..group {
                        let at = j * stride * bands_in;
                        let (px, valid) = (&mut block[at..at + w * bands_in], &mut valid_block[j * w..(j + 1) * w]);
                        if g * group + j < rows {
                            make_row(g * group + j, cols, rws, px, valid, spans, &mut miss);
                        } else {
                            // Beyond the grid's edge: zero.
                            px.fill(T::default());
                            valid.fill(false);
                        }
                    }
                    // Piece x takes pixel x of each row made.
                    let (seen, pad) = row_pieces.split_at_mut(w);
                    if direct {
                        super::transpose::gather(bytemuck::cast_slice(block), group, stride, bands_in * std::mem::size_of::<T>(), seen);
                    } else {
                        for (x, piece) in seen.iter_mut().enumerate() {
                            for (j, to) in piece.chunks_exact_mut(bo).enumerate() {
                                let at = (j * stride + x) * bands_in;
                                to[..bands_in].copy_from_slice(&block[at..at + bands_in]);
                                to[bands_in] = if valid_block[j * w + x] { opaque } else { T::default() };
                            }
                        }
                    }
                    pad.iter_mut().for_each(|p| p.fill(T::default()));
                    return miss;
                }
                let (px, valid) = (block, valid_block);
                for j in 0..group {
                    let r = g * group + j;
                    if r >= rows {
                        // Below the grid's edge.
                        row_pieces.iter_mut().for_each(|p| p.fill(T::default()));
                        continue;
                    }
                    make_row(r, cols, rws, px, valid, spans, &mut miss);
            for (tx, piece) in row_pieces.iter_mut().enumerate() {
                let xs = tx * t;
                let n = t.min(w - xs);
                let (seg_out, pad) = piece.split_at_mut(n * bo);
                pad.fill(T::default());
                if direct {
                    seg_out.copy_from_slice(&px[xs * bands_in..(xs + n) * bands_in]);
                } else {
                    for i in 0..n {
                        let s = (xs + i) * bands_in;
                        seg_out[i * bo..i * bo + bands_in].copy_from_slice(&px[s..s + bands_in]);
                        seg_out[i * bo + bands_in] = if valid[xs + i] { opaque } else { T::default() };
                    }
                }
            }
                }
                miss
            },
        )
        .collect();
    match misses.into_iter().flatten().next() {
        Some(m) => Err(m),
        None => Ok(out),
    }
}

/// A chunk resampled by a pool worker, with its number in the band order
/// and the window buffer to use again.
struct Resampled {
    seq: u64,
    raw: std::result::Result<Raw, (f64, f64, Lookup)>,
    win: Window,
    band: u32,
    first_col: u32,
}

/// A chunk's tiles on their way to the encoder: band `band`, walked tile
/// columns from `first_col`.
struct Made {
    band: u32,
    first_col: u32,
    raw: Raw,
}

/// The chunks being resampled, oldest first, with the scan rows each reads
/// in place; the scan rows of finished chunks not yet given back; and the
/// stage's busy time (while any chunk is in flight).
#[derive(Default)]
struct InFlight {
    chunks: std::collections::VecDeque<(u64, Option<(u32, u32)>)>,
    /// Chunks finished before an older one.
    early: std::collections::BTreeMap<u64, Resampled>,
    finished_rows: Vec<(u32, u32)>,
    busy_since: Option<Instant>,
    busy: Duration,
}

impl InFlight {
    fn len(&self) -> usize {
        self.chunks.len()
    }

    fn is_empty(&self) -> bool {
        self.chunks.is_empty()
    }

    fn start(&mut self, seq: u64, rows: Option<(u32, u32)>) {
        self.busy_since.get_or_insert_with(Instant::now);
        self.chunks.push_back((seq, rows));
    }

    /// Waits for the oldest chunk (the others may finish first).
    fn finish_oldest(&mut self, done: &crossbeam_channel::Receiver<Resampled>) -> Result<Resampled> {
        let (seq, rows) = self.chunks.pop_front().expect("a chunk in flight");
        let chunk = loop {
            if let Some(d) = self.early.remove(&seq) {
                break d;
            }
            let d = done.recv().map_err(|_| Error::Cancelled)?;
            self.early.insert(d.seq, d);
        };
        if self.chunks.is_empty() {
            if let Some(t) = self.busy_since.take() {
                self.busy += t.elapsed();
            }
        }
        self.finished_rows.extend(rows);
        Ok(chunk)
    }

    /// The scan rows from the first to the last mapped by the chunks in
    /// flight and `extra`.
    fn rows_hull(&self, extra: Option<(u32, u32)>) -> Option<(u32, u32)> {
        self.chunks.iter().filter_map(|c| c.1).chain(extra).reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
    }

    /// Gives back the rows of finished chunks that neither a chunk in
    /// flight nor `next` reads.
    fn release_finished_rows(&mut self, src: &SourceImage, next: Option<(u32, u32)>) {
        let keep = self.rows_hull(next);
        for rows in self.finished_rows.drain(..) {
            release_outside(src, rows, keep);
        }
    }
}

/// Gives back the mapped scan rows `rows` except those inside `keep`.
fn release_outside(src: &SourceImage, rows: (u32, u32), keep: Option<(u32, u32)>) {
    let (a, b) = rows;
    match keep {
        Some((ka, kb)) if ka < b && kb > a => {
            if ka > a {
                src.release_rows(a, ka - a);
            }
            if kb < b {
                src.release_rows(kb, b - kb);
            }
        }
        _ => src.release_rows(a, b - a),
    }
}

/// Resamples one pixel from a window read just for it.
fn single_pixel<T: Sample>(src: &SourceImage, cfg: &RectifyConfig, c: f64, r: f64, out: &mut [T], fill: T) {
    let info = &src.info;
    let rad = cfg.kernel.radius() as i64 + 1;
    let (ci, ri) = (c.floor() as i64, r.floor() as i64);
    let c0 = (ci - rad).clamp(0, info.width as i64) as u32;
    let r0 = (ri - rad).clamp(0, info.height as i64) as u32;
    let c1 = (ci + rad + 1).clamp(0, info.width as i64) as u32;
    let r1 = (ri + rad + 1).clamp(0, info.height as i64) as u32;
    let mut win = Window::default();
    if src.read_window(c0, r0, c1 - c0, r1 - r0, &mut win).is_err() {
        out.fill(fill);
        return;
    }
    let view = View::<T>::new(&win, info.bands, info.width, info.height);
    let mut valid = [false];
    resample_row(cfg.kernel, &view, &[c], &[r], out, &mut valid, fill);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bands_take_the_rows_they_share_with_the_band_before() {
        let mut made = Vec::new();
        let mut before = SharedRows::default();
        let mut rows = |j0, j1, made: &mut Vec<i64>| {
            before.rows(j0, j1, |j| {
                made.push(j);
                j * 10
            })
        };
        assert_eq!(rows(-1, 3, &mut made), (vec![-10, 0, 10, 20, 30], 0));
        // Two rows shared at the edge.
        assert_eq!(rows(2, 6, &mut made), (vec![20, 30, 40, 50, 60], 2));
        // None shared (a jump), then one.
        assert_eq!(rows(9, 10, &mut made), (vec![90, 100], 0));
        assert_eq!(rows(10, 11, &mut made), (vec![100, 110], 1));
        assert_eq!(made, [-1, 0, 1, 2, 3, 4, 5, 6, 9, 10, 11]);
    }
}
