//! Points for `grid`: random places on a square of ground (from a seed,
//! the same every time), their heights from an analytic terrain — rolling
//! hills, a bowl, a town of flat-roofed boxes — written as a LAS or LAZ
//! file a batch at a time, so that any number fit in a little memory.

use crate::error::{Error, Result};
use crate::progress::{Progress, Task};
use std::path::Path;

/// The terrain at local `(u, v)` metres from the square's south-west corner.
pub fn height(u: f64, v: f64) -> f64 {
    let hills = 12.0 * (u / 730.0).sin() * (v / 910.0).cos() + 4.0 * ((u + 2.0 * v) / 170.0).sin();
    let town = if u.rem_euclid(120.0) < 45.0 && v.rem_euclid(150.0) < 60.0 { 15.0 + 5.0 * ((u / 120.0).floor() % 3.0) } else { 0.0 };
    200.0 + hills + town
}

/// Writes `n` points at `density` a square metre into `path` (LAZ where it
/// ends in .laz, text where .csv; millimetres), from (500000, 4000000) (UTM zone 31N); returns the
/// square's side.
pub fn write_points(path: &Path, n: u64, density: f64, seed: u64, progress: &dyn Progress) -> Result<f64> {
    if n == 0 || !(density > 0.0 && density.is_finite()) {
        return Err(Error::setting("points", "a number of points over 0 and a density over 0"));
    }
    let side = (n as f64 / density).sqrt();
    // LAS holds coordinates as 32-bit integers, here of millimetres.
    if side > 2.0e6 {
        return Err(Error::setting("points", format!("{n} points at {density} a square metre cover {side:.3e} m a side: more than the 2000 km a file of them holds")));
    }
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    // Millimetres, as the LAS holds them.
    let mm = |v: f64| (v * 1000.0).round() / 1000.0;
    progress.start(&Task { name: "points", units: n, lines: 0, line_name: "points", input_bytes: 0 });
    if ext == "csv" {
        use std::io::Write;
        // Under a temporary name, published when whole.
        let pending = crate::io::publish::PendingFile::create(path)?;
        let mut w = std::io::BufWriter::with_capacity(1 << 20, pending.file()?);
        let io = |e| Error::io(path, e);
        writeln!(w, "x,y,z").map_err(io)?;
        for k in 0..n {
            let (u, v) = (mm(next() * side), mm(next() * side));
            writeln!(w, "{:.3},{:.3},{:.3}", 500000.0 + u, 4000000.0 + v, height(u, v)).map_err(io)?;
            if k % 65536 == 65535 {
                progress.advance(65536);
            }
        }
        w.into_inner().map_err(|e| io(e.into_error()))?;
        pending.publish()?;
        progress.finish();
        return Ok(side);
    }
    let laz = ext == "laz";
    let mut b = las::Builder::from((1, 2));
    b.point_format = las::point::Format::new(0).expect("format 0");
    b.point_format.is_compressed = laz;
    b.transforms = las::Vector {
        x: las::Transform { scale: 0.001, offset: 500000.0 },
        y: las::Transform { scale: 0.001, offset: 4000000.0 },
        z: las::Transform { scale: 0.001, offset: 0.0 },
    };
    // No CRS record: `grid --crs EPSG:32631` says it.
    let header = b.into_header().map_err(|e| Error::Internal(format!("a LAS header: {e}")))?;
    let failed = |e: las::Error| Error::Format { path: path.into(), msg: format!("writing points: {e}") };
    let pending = crate::io::publish::PendingFile::create(path)?;
    let mut w = las::Writer::new(std::io::BufWriter::new(pending.file()?), header).map_err(failed)?;
    for k in 0..n {
        let (u, v) = (mm(next() * side), mm(next() * side));
        w.write_point(las::Point { x: 500000.0 + u, y: 4000000.0 + v, z: height(u, v), ..Default::default() }).map_err(failed)?;
        if k % 65536 == 65535 {
            progress.advance(65536);
        }
    }
    // (The buffer flushed here: dropped, it would swallow a full disk.)
    w.into_inner().map_err(failed)?.into_inner().map_err(|e| Error::io(path, e.into_error()))?;
    pending.publish()?;
    progress.finish();
    Ok(side)
}
