//! Stage 6, write: tiles appended to the output file as they come, in any
//! order, their places recorded; under `sync`, the written bytes are sent
//! on to the disk while the run goes on.

use super::encode::Tile;
use crate::error::{Error, Result};
use crate::io::tiff_out::{folder_of, tiff_write_error, TileWriter};
use crate::pipeline::context::Output;

/// Bytes of output between two background syncs.
const FLUSH_EVERY: usize = 64 << 20;

/// Writes the tiles `next` gives, in any order, into `out_file`, while
/// a thread of its own starts the write-back of what is written (under
/// `sync`) through `flush_file`, a second handle to the output: the sync
/// before the rename then has little left to wait for.
pub fn write(run: &Output, out_file: std::fs::File, flush_file: std::fs::File, mut next: impl FnMut() -> Result<Option<(usize, Tile)>>) -> Result<()> {
    let sync = run.sync;
    let (tx_flush, rx_flush) = crossbeam_channel::bounded::<()>(1);
    std::thread::scope(|s| {
        if sync {
            s.spawn(move || {
                // Errors show again, and are reported, at the final sync.
                for () in rx_flush.iter() {
                    let _ = flush_file.sync_data();
                }
            });
        }
        let mut unsynced = 0usize;
        let spec = run.spec;
        let tw = |e| run.stop.fail(tiff_write_error(run.path, e));
        let order = (run.in_strips && !spec.cog).then(|| crate::overview::Pyramid::band_order(spec));
        let mut writer = TileWriter::new_in_order(out_file, spec, &folder_of(run.path), order).map_err(|e| tw(e.into()))?;
        let written = (|| -> Result<()> {
            loop {
                if run.stop.cancelled() {
                    return Err(Error::Cancelled);
                }
                let Some((k, tile)) = next()? else { break };
                // (The mask's tiles come with the image's.)
                if k < spec.tile_count() {
                    run.progress.advance(1);
                }
                writer.put(k, tile.as_ref()).map_err(tw)?;
                unsynced += tile.as_ref().len();
                if sync && unsynced >= FLUSH_EVERY {
                    // Never waits: a sync still running takes this one too.
                    let _ = tx_flush.try_send(());
                    unsynced = 0;
                }
            }
            // The statistics are complete: the encoder has sent its last tile.
            let metadata = run.statistics.lock().ok().and_then(|s| s.total().gdal_metadata(run.source));
            writer.finish(metadata).map_err(tw)?;
            Ok(())
        })();
        drop(tx_flush);
        written.map_err(|e| run.stop.fail(e))
    })
}
