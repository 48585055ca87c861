//! Stage 6, write: tiles appended to the output file as they come, in any
//! order, their places recorded; under `sync`, the written bytes are sent
//! on to the disk while the run goes on.

use super::encode::Tile;
use crate::error::{Error, Result};
use crate::io::tiff_out::{tiff_write_error, write_placed, WriteError};
use crate::pipeline::context::Run;

/// Bytes of output between two background syncs.
const FLUSH_EVERY: usize = 64 << 20;

/// Writes the tiles `next` gives, in any order, into `out_file`, while
/// a thread of its own starts the write-back of what is written (under
/// `sync`) through `flush_file`, a second handle to the output: the sync
/// before the rename then has little left to wait for.
pub fn write(run: &Run, out_file: std::fs::File, flush_file: std::fs::File, mut next: impl FnMut() -> Result<Option<(usize, Tile)>>) -> Result<()> {
    let sync = run.inputs.sync;
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
        let r = write_placed(out_file, run.inputs.spec, &crate::io::tiff_out::folder_of(run.inputs.output), || -> Result<Option<(usize, Tile)>> {
            if run.stop.cancelled() {
                return Err(Error::Cancelled);
            }
            let next = next()?;
            if let Some((k, tile)) = &next {
                // (The mask's tiles come with the image's.)
                if *k < run.inputs.spec.tile_count() {
                    run.progress.advance(1);
                }
                unsynced += tile.as_ref().len();
                if sync && unsynced >= FLUSH_EVERY {
                    // Never waits: a sync still running takes this one too.
                    let _ = tx_flush.try_send(());
                    unsynced = 0;
                }
            }
            Ok(next)
        });
        drop(tx_flush);
        match r {
            Ok(()) => Ok(()),
            Err(WriteError::Source(e)) => Err(run.stop.fail(e)),
            Err(WriteError::Tiff(e)) => Err(run.stop.fail(tiff_write_error(run.inputs.output, e))),
        }
    })
}
