//! The matched points as a LAS file, written as tiles finish: what `grid`
//! reads to make the DSM, and what a user may keep (`--points`).

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

pub struct PointWriter {
    path: PathBuf,
    writer: las::Writer<std::io::BufWriter<std::fs::File>>,
    count: u64,
}

impl PointWriter {
    /// A LAS 1.2 file at `path`, coordinates kept to a thousandth of a
    /// `pixel` around `origin` (heights to the millimetre).
    pub fn create(path: &Path, origin: [f64; 2], pixel: f64) -> Result<PointWriter> {
        let mut b = las::Builder::from((1, 2));
        b.point_format = las::point::Format::new(0).expect("format 0");
        let scale = 10f64.powf((pixel / 1000.0).log10().floor()).min(0.001);
        b.transforms = las::Vector {
            x: las::Transform { scale, offset: origin[0].round() },
            y: las::Transform { scale, offset: origin[1].round() },
            z: las::Transform { scale: 0.001, offset: 0.0 },
        };
        let header = b.into_header().map_err(|e| Error::Internal(format!("a LAS header: {e}")))?;
        let writer = las::Writer::from_path(path, header).map_err(|e| Error::Format { path: path.into(), msg: format!("writing points: {e}") })?;
        Ok(PointWriter { path: path.into(), writer, count: 0 })
    }

    pub fn write(&mut self, x: f64, y: f64, z: f64) -> Result<()> {
        self.count += 1;
        self.writer
            .write_point(las::Point { x, y, z, ..Default::default() })
            .map_err(|e| Error::Format { path: self.path.clone(), msg: format!("writing points: {e}") })
    }

    pub fn count(&self) -> u64 {
        self.count
    }

    pub fn close(mut self) -> Result<()> {
        self.writer.close().map_err(|e| Error::Format { path: self.path.clone(), msg: format!("writing points: {e}") })
    }
}
