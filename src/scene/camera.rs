//! A run's camera: the model source of its options read (our camera file,
//! other tools' files, the image's own tags, an RPC), with the fiducial
//! marks found in the scan where the file gives them calibrated but not
//! measured. The camera module reads files; finding marks needs the scan,
//! and is joined to it here.

use crate::camera::file::Camera;
use crate::camera::formats::{self, AngleUnit};
use crate::error::Result;
use crate::geodesy::Crs;
use crate::options::ModelSource;
use std::path::Path;

/// The sensor model of `image` described at `origin`.
/// `crs`: the orthophoto's CRS where given, taken as the positions'
/// where the camera's files give none.
pub fn load(model: &ModelSource, image: &Path, origin: &Path, crs: Option<&Crs>) -> Result<Camera> {
    match model {
        ModelSource::CameraFile => read_for(image, origin, None, AngleUnit::Degrees, crs),
        ModelSource::WithPoses { poses, angles } => read_for(image, origin, Some(poses), *angles, crs),
        ModelSource::Inline(f) => {
            let (file, found) = crate::fiducials::camera::measured(f.clone(), origin, image)?;
            let mut cam = file.build(origin)?;
            cam.warnings.extend(found);
            Ok(cam)
        }
        ModelSource::Rpc { offset, geoid } => {
            let offset = offset.or_else(|| {
                let xml = crate::io::bounded_read::read_text_bounded(origin, "an RPC file", crate::io::bounded_read::SMALL).ok()?;
                crate::camera::rpc::Rpc::tile_offset(&xml, image.file_name()?.to_str()?)
            });
            Camera::rpc_file(origin, offset, geoid.as_deref(), image.file_name().and_then(|n| n.to_str())).build(origin)
        }
    }
}

/// The camera of `image` from a camera file in any format
/// [`formats::read_for`] reads, with the exterior orientations of many
/// images in `poses` where given. Doubtful things the files hold are in
/// [`Camera::warnings`].
/// `crs`: the positions' CRS where the files give none; `angles`: the
/// unit of a pose CSV's angles.
pub fn read_for(image: &Path, camera: &Path, poses: Option<&Path>, angles: AngleUnit, crs: Option<&Crs>) -> Result<Camera> {
    let set = formats::read_for_with(image, camera, poses, angles, crs)?;
    let (mut file, found) = crate::fiducials::camera::measured(set.camera_for(image)?, camera, image)?;
    let crs_text = |c: &Crs| c.epsg().map_or_else(|| c.proj4().to_string(), |e| format!("EPSG:{e}"));
    if let (true, Some(c)) = (file.crs.trim().is_empty(), crs) {
        file.crs = crs_text(c);
    }
    if file.crs.trim().is_empty() && set.crs_of_image {
        if let Some(c) = image_crs(image)? {
            file.crs = crs_text(&c);
        }
    }
    let origin = if formats::is_exif(camera) { image } else { poses.unwrap_or(camera) };
    let mut cam = file.build(origin)?;
    cam.warnings = set.warnings;
    cam.warnings.extend(found);
    cam.relative_altitude = set.relative_altitude;
    Ok(cam)
}

/// The CRS `image`'s GeoTIFF keys name, if any.
fn image_crs(image: &Path) -> Result<Option<Crs>> {
    let info = crate::io::source::SourceImage::info_of(image)?;
    let Some(g) = info.georef else { return Ok(None) };
    crate::geodesy::geokeys::crs_of(&g.keys).map_err(|m| crate::error::Error::format(image, format!("its GeoTIFF keys: {m}")))
}

/// What [`read_for`] would refuse, short of finding fiducial marks in the
/// scan (a batch's check of its jobs: the marks are found once, when the
/// job runs).
pub fn check_for(image: &Path, camera: &Path) -> Result<()> {
    let set = formats::read_for(image, camera, None, None)?;
    if set.camera_for(image)?.needs_marks() {
        return Ok(());
    }
    read_for(image, camera, None, AngleUnit::Degrees, None).map(|_| ())
}

/// The ground control points a run's options name, read for its image.
pub type Control<'a> = (&'a crate::options::GcpOptions, Vec<crate::camera::gcp::Gcp>);

/// The camera of a run, as `rectify` and each image of a mosaic take it:
/// loaded ([`load`], in `crs` where the files give none) and, for a frame
/// camera, its pose refined by the run's GCPs in its own CRS before
/// anything else uses it, so that a mosaic's seams and footprints come
/// from the pose its pixels do. Returns the GCPs read (an RPC's bias is
/// fitted once its heights' geoid is known) and the frame's fit.
pub fn of_run<'a>(
    opts: &'a crate::options::RectifyOptions,
    crs: Option<&Crs>,
    progress: &dyn crate::progress::Progress,
) -> Result<(Camera, Option<Control<'a>>, Option<crate::camera::gcp::GcpFit>)> {
    let mut camera = load(&opts.inputs.model, &opts.inputs.image, &opts.inputs.camera, crs)?;
    for w in &camera.warnings {
        progress.warn(w);
    }
    let gcps = opts.inputs.gcps.as_ref().map(|g| crate::camera::gcp::read(&g.file, &opts.inputs.image).map(|p| (g, p))).transpose()?;
    let mut fit = None;
    if let (Some((g, points)), crate::camera::file::Sensor::Frame(_) | crate::camera::file::Sensor::Panoramic(_)) = (&gcps, &camera.sensor) {
        if points.iter().any(|p| p.ellipsoidal) {
            progress.warn(&format!(
                "{}: the GCPs' heights are ellipsoidal (Orthority's form) and are taken as the DEM's: where its heights are above a geoid they are off by its undulation; give a CSV with heights in the DEM's datum",
                g.file.display()
            ));
        }
        fit = Some(crate::camera::gcp::refine(&mut camera, points, g.model, g.max_residual, &g.file)?);
        if let Some(w) = fit.as_ref().and_then(|f| f.outlier.as_ref()) {
            progress.warn(&format!("{}: {w}", g.file.display()));
        }
    }
    Ok((camera, gcps, fit))
}
