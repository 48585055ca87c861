//! What an orthophoto is made from, as a key: its inputs by their contents
//! and the settings that change its pixels. The key is written into every
//! output ("made from"), so that pieces of one whole are known by it, and
//! kept beside finished batch outputs.

use crate::identity::{content_stamp, fnv};
use crate::options::{DemSource, ModelSource, RectifyOptions};
use std::path::PathBuf;

/// What an orthophoto is made from, the same for each of its pieces and
/// whatever layout they are put together in: its inputs by their contents
/// (not their paths or times: pieces made on nodes that staged the inputs
/// elsewhere join), and every setting of the batch's job key but the piece
/// (window), the file's name and layout (codec, overviews,
/// Cloud-Optimized, BigTIFF, band order) and how the run was resourced.
pub fn source_key(c: &RectifyOptions) -> String {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut whole = c.clone();
    for (_, input) in c.inputs() {
        content_stamp(&mut h, &input);
    }
    if let Some(f) = c.inputs.model.inline() {
        fnv(&mut h, f.to_toml().as_bytes());
    }
    // The inputs' paths out of the settings.
    whole.inputs.image = PathBuf::new();
    whole.inputs.camera = PathBuf::new();
    whole.grid.like = None;
    if let DemSource::File(p) = &mut whole.inputs.dem {
        *p = PathBuf::new();
    }
    if let Some(g) = &mut whole.inputs.gcps {
        g.file = PathBuf::new();
    }
    match &mut whole.inputs.model {
        ModelSource::WithPoses { poses, .. } => *poses = PathBuf::new(),
        ModelSource::Rpc { geoid: Some(g), .. } => *g = PathBuf::new(),
        // Hashed above, as its file would be.
        m @ ModelSource::Inline(_) => *m = ModelSource::CameraFile,
        _ => {}
    }
    whole.file.path = std::path::PathBuf::new();
    whole.grid.window = None;
    whole.file.overviews = crate::options::Overviews::Auto;
    whole.file.overview_level = None;
    // The codec is the file's, not what its pixels are made from: lossless
    // pieces coded anew by `assemble --compress` make the single run's file.
    whole.file.compress = crate::options::Compression::Deflate;
    whole.file.level = None;
    whole.file.quality = None;
    whole.file.overview_resampling = crate::options::OverviewResampling::Average;
    whole.file.cog = false;
    whole.file.bigtiff = crate::options::BigTiff::Auto;
    whole.resources.band_order = crate::options::BandOrder::Auto;
    whole.grid.max_output_pixels = None;
    whole.file.sync = true;
    whole.resources.threads = 0;
    whole.resources.memory = 0;
    whole.resources.geometry_memory = None;
    // (Every setting serializes once an inline camera is out of them.)
    fnv(&mut h, serde_json::to_string(&whole).unwrap_or_default().as_bytes());
    format!("{h:016x}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn the_key_tells_settings_of_the_pixels_apart_and_not_those_of_the_file() {
        let base = RectifyOptions::new("s.tif".into(), "s_RPC.TXT".into(), DemSource::Height(0.0), "o.tif".into());
        let key = |f: &dyn Fn(&mut RectifyOptions)| {
            let mut o = base.clone();
            f(&mut o);
            source_key(&o)
        };
        let plain = key(&|_| {});
        // The sensor's own settings are the pixels': an RPC's crop offset.
        let rpc = |offset| ModelSource::Rpc { offset, geoid: None };
        assert_ne!(key(&|o| o.inputs.model = rpc(Some([0.0, 0.0]))), key(&|o| o.inputs.model = rpc(Some([5000.0, 0.0]))));
        assert_ne!(plain, key(&|o| o.geometry.gcm.k = 8));
        // The file's layout, the piece and the resources are not.
        for same in [
            key(&|o| o.file.path = "other.tif".into()),
            key(&|o| o.file.compress = crate::options::Compression::Zstd),
            key(&|o| o.grid.window = Some([1, 1, 2, 2])),
            key(&|o| (o.resources.memory, o.resources.threads, o.resources.geometry_memory) = (1 << 30, 1, Some(1 << 28))),
        ] {
            assert_eq!(same, plain);
        }
        // A mosaic's inline camera: its settings still count.
        let text = "crs = \"EPSG:32631\"\n[camera]\nmodel = \"frame\"\nfocal_length_mm = 100.0\n[interior]\npixel_size_mm = 0.0192\n\
                    principal_point_px = [1250.0, 1000.0]\n[exterior]\nposition = [650899.0, 4890786.0, 1300.0]\nangles_deg = [0.0, 0.0, 0.0]\nconvention = \"omega-phi-kappa\"\n";
        let cam = crate::camera::CameraFile::parse(text, Path::new("block.toml")).expect("a camera file");
        let with = |k| key(&|o| (o.inputs.model, o.geometry.gcm.k) = (ModelSource::Inline(cam.clone()), k));
        assert_ne!(with(8), with(16));
    }
}
