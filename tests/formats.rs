//! Scans in the formats users have: the orthophoto of a PNG is the TIFF's,
//! pixel for pixel; a JPEG's is the one made from GDAL's decoding of the
//! same JPEG, pixel for pixel (both libjpeg); what cannot be read is
//! refused by name. GDAL writes the JPEG and PNG files (under CI it must
//! be there).

mod common;
use common::*;
use gcm_ortho::synth::{CameraKind, Relief, SynthReport};
use std::path::Path;
use std::process::Command;

fn gdal_translate(args: &[&str]) {
    let out = Command::new("gdal_translate").arg("-q").args(args).output().expect("gdal_translate runs");
    assert!(out.status.success(), "gdal_translate {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

fn rectify(sc: &SynthReport, image: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut a = vec!["rectify", "--image", s(image), "--camera", s(&sc.camera), "--dem", s(&sc.dem), "-o", s(out), "--quiet"];
    a.extend_from_slice(extra);
    run(&a)
}

fn rectified(sc: &SynthReport, image: &Path, out: &Path) -> Vec<u8> {
    let r = rectify(sc, image, out, &[]);
    assert!(r.status.success(), "{}: {}", image.display(), String::from_utf8_lossy(&r.stderr));
    whole_image(out).0
}

/// A drone frame over buildings, RGB (or one 16-bit band).
fn drone(dir: &Path, bands: u32, bits: u32) -> SynthReport {
    scene(dir, 600, |o| {
        o.camera = CameraKind::Drone;
        o.relief = Relief::Urban;
        o.width = 800;
        o.bands = bands;
        o.bits = bits;
        o.kappa_deg = 17.0;
    })
}

#[test]
fn a_png_gives_the_tiffs_orthophoto_pixel_for_pixel() {
    if !have("gdal_translate") {
        eprintln!("skipped: GDAL is not installed");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (name, bands, bits) in [("rgb8", 3, 8), ("grey16", 1, 16)] {
        let sc = drone(&dir.path().join(name), bands, bits);
        let png = dir.path().join(format!("{name}.png"));
        gdal_translate(&["-of", "PNG", s(&sc.scan), s(&png)]);
        let want = rectified(&sc, &sc.scan, &dir.path().join(format!("{name}-tif.tif")));
        let got = rectified(&sc, &png, &dir.path().join(format!("{name}-png.tif")));
        assert!(got == want, "{name}: the PNG's orthophoto differs from the TIFF's");
    }
    // An interlaced PNG is decoded whole, to the same pixels.
    let sc = drone(&dir.path().join("rgb8"), 3, 8);
    let adam7 = dir.path().join("adam7.png");
    let plain = std::fs::read(dir.path().join("rgb8.png")).unwrap();
    interlace_png(&plain, &adam7);
    assert!(png::Decoder::new(std::fs::File::open(&adam7).unwrap()).read_info().unwrap().info().interlaced);
    let want = whole_image(&dir.path().join("rgb8-tif.tif")).0;
    assert!(rectified(&sc, &adam7, &dir.path().join("adam7.tif")) == want, "interlaced PNG");
}

#[test]
fn a_jpeg_2000_scan_gives_the_tiffs_orthophoto_when_lossless_and_gdals_when_lossy() {
    if !have("gdal_translate") {
        eprintln!("skipped: GDAL is not installed");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rgb = drone(&d.join("rgb8"), 3, 8);
    let wide = drone(&d.join("grey16"), 1, 16);
    let reversible = ["-of", "JP2OpenJPEG", "-co", "REVERSIBLE=YES", "-co", "QUALITY=100"];
    // Codestream tiles of 256 (chunks), one tile of the whole image (read
    // in areas of at most 512), 16-bit samples.
    for (name, sc, blocks) in [("tiles256", &rgb, "256"), ("one-tile", &rgb, "1024"), ("u16", &wide, "256")] {
        let jp2 = d.join(format!("{name}.jp2"));
        let (bx, by) = (format!("BLOCKXSIZE={blocks}"), format!("BLOCKYSIZE={blocks}"));
        let mut args = reversible.to_vec();
        args.extend(["-co", &bx, "-co", &by, s(&sc.scan), s(&jp2)]);
        gdal_translate(&args);
        let want = rectified(sc, &sc.scan, &d.join(format!("{name}-tif.tif")));
        assert!(rectified(sc, &jp2, &d.join(format!("{name}-jp2.tif"))) == want, "{name}: a lossless JPEG 2000 gives the TIFF's orthophoto");
        if name == "one-tile" {
            // On a small budget its one 800×600 chunk is decoded on one
            // thread at a time rather than refused.
            let out = d.join("one-tile-small.tif");
            let r = rectify(sc, &jp2, &out, &["--memory", "40M"]);
            assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
            assert!(whole_image(&out).0 == want, "one decoder at a time gives the same orthophoto");
            let r = rectify(sc, &jp2, &out, &["--memory", "20M"]);
            let e = String::from_utf8_lossy(&r.stderr);
            assert!(r.status.code() == Some(2) && e.contains("--memory") && e.contains("800×600 chunks") && e.contains("give 44M"), "{e}");
        }
    }
    // Lossy: the same as the orthophoto of GDAL's decoding of it.
    let jp2 = d.join("lossy.jp2");
    gdal_translate(&["-of", "JP2OpenJPEG", "-co", "QUALITY=10", "-co", "BLOCKXSIZE=256", "-co", "BLOCKYSIZE=256", s(&rgb.scan), s(&jp2)]);
    let by_gdal = d.join("lossy-by-gdal.tif");
    gdal_translate(&["-of", "GTiff", s(&jp2), s(&by_gdal)]);
    let ours = rectified(&rgb, &jp2, &d.join("lossy-ours.tif"));
    let gdals = rectified(&rgb, &by_gdal, &d.join("lossy-gdals.tif"));
    let original = whole_image(&d.join("tiles256-tif.tif")).0;
    assert!(ours != original, "the lossy JPEG 2000 differs from the original");
    let most = ours.iter().zip(&gdals).map(|(&a, &b)| a.abs_diff(b)).max().unwrap();
    assert!(most <= 1, "our decoding is up to {most} from GDAL's");
}

/// Re-encodes an 8-bit RGB PNG interlaced (Adam7), written here chunk by
/// chunk: each pass's rows, filter type 0, deflated together.
fn interlace_png(plain: &[u8], out: &Path) {
    let mut reader = png::Decoder::new(plain).read_info().unwrap();
    let mut px = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut px).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let (w, h) = (info.width as usize, info.height as usize);
    // Adam7: (first column, first row, column step, row step) per pass.
    let passes = [(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)];
    let mut raw = Vec::new();
    for (x0, y0, dx, dy) in passes {
        if x0 >= w || y0 >= h {
            continue;
        }
        for y in (y0..h).step_by(dy) {
            raw.push(0);
            for x in (x0..w).step_by(dx) {
                raw.extend_from_slice(&px[(y * w + x) * 3..][..3]);
            }
        }
    }
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    std::io::Write::write_all(&mut z, &raw).unwrap();
    let idat = z.finish().unwrap();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&(w as u32).to_be_bytes());
    ihdr.extend_from_slice(&(h as u32).to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 1]); // 8-bit RGB, interlaced
    let mut file = b"\x89PNG\r\n\x1a\n".to_vec();
    for (kind, data) in [(b"IHDR", &ihdr[..]), (b"IDAT", &idat[..]), (b"IEND", &[][..])] {
        file.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut crc = flate2::Crc::new();
        crc.update(kind);
        crc.update(data);
        file.extend_from_slice(kind);
        file.extend_from_slice(data);
        file.extend_from_slice(&crc.sum().to_be_bytes());
    }
    std::fs::write(out, file).unwrap();
}

#[test]
fn a_jpegs_orthophoto_is_that_of_gdals_decoding_and_a_sequential_one_streams() {
    if !have("gdal_translate") {
        eprintln!("skipped: GDAL is not installed");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = drone(&d.join("scene"), 3, 8);
    let jpg = d.join("frame.jpg");
    gdal_translate(&["-of", "JPEG", "-co", "QUALITY=90", s(&sc.scan), s(&jpg)]);
    // The same JPEG decoded by GDAL (libjpeg), kept as a TIFF.
    let by_gdal = d.join("frame-by-gdal.tif");
    gdal_translate(&["-of", "GTiff", s(&jpg), s(&by_gdal)]);
    let original = rectified(&sc, &sc.scan, &d.join("original.tif"));
    let ours = rectified(&sc, &jpg, &d.join("ours.tif"));
    let gdals = rectified(&sc, &by_gdal, &d.join("gdals.tif"));
    let mean_diff = |a: &[u8], b: &[u8]| a.iter().zip(b).map(|(&x, &y)| (x as f64 - y as f64).abs()).sum::<f64>() / a.len() as f64;
    let codec = mean_diff(&gdals, &original);
    assert!(codec > 0.2, "the JPEG is lossy: {codec}");
    // Both decode with libjpeg(-turbo): the same pixels, the same orthophoto.
    assert!(ours == gdals, "our decoding is {} from GDAL's", mean_diff(&ours, &gdals));

    // EXIF that says the rows are shown turned is refused by name;
    // orientation 1 is read.
    for (orientation, ok) in [(1u16, true), (6, false)] {
        let turned = d.join(format!("exif-{orientation}.jpg"));
        std::fs::write(&turned, with_exif_orientation(&std::fs::read(&jpg).unwrap(), orientation)).unwrap();
        let out = d.join(format!("exif-{orientation}.tif"));
        let r = rectify(&sc, &turned, &out, &[]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.success(), ok, "orientation {orientation}: {err}");
        if !ok {
            assert!(err.contains(s(&turned)) && err.contains("EXIF orientation is 6"), "{err}");
            assert_eq!(err.trim().lines().count(), 1, "{err}");
            assert!(!out.exists());
        }
    }

    // A sequential JPEG is decoded a few rows at a time, whatever the
    // budget: 4000 × 3000 under 24 MiB gives the orthophoto of GDAL's
    // decoding. A progressive one is decoded whole and must fit the
    // budget; the refusal names the file and the option. A cut file is
    // refused, not filled with grey.
    let big = d.join("big.jpg");
    gdal_translate(&["-of", "JPEG", "-outsize", "4000", "3000", s(&sc.scan), s(&big)]);
    let big_by_gdal = d.join("big-by-gdal.tif");
    gdal_translate(&["-of", "GTiff", s(&big), s(&big_by_gdal)]);
    // (The camera is the small frame's: a coarse grid keeps the output small.)
    let small = ["--memory", "24M", "--gsd", "2", "--overviews", "none"];
    let (ours, gdals) = (d.join("big-ours.tif"), d.join("big-gdals.tif"));
    for (image, out) in [(&big, &ours), (&big_by_gdal, &gdals)] {
        let r = rectify(&sc, image, out, &small);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    }
    assert!(whole_image(&ours).0 == whole_image(&gdals).0);
    let progressive = d.join("progressive.jpg");
    gdal_translate(&["-of", "JPEG", "-co", "PROGRESSIVE=ON", "-outsize", "4000", "3000", s(&sc.scan), s(&progressive)]);
    let out = d.join("progressive.tif");
    let r = rectify(&sc, &progressive, &out, &small);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("--memory") && err.contains(s(&progressive)) && err.contains("decoded whole"), "{err}");
    assert!(!out.exists());
    let p_by_gdal = d.join("progressive-by-gdal.tif");
    gdal_translate(&["-of", "GTiff", s(&progressive), s(&p_by_gdal)]);
    let (ours, gdals) = (d.join("p-ours.tif"), d.join("p-gdals.tif"));
    for (image, out) in [(&progressive, &ours), (&p_by_gdal, &gdals)] {
        let r = rectify(&sc, image, out, &["--gsd", "2"]);
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    }
    assert!(whole_image(&ours).0 == whole_image(&gdals).0);
    let cut = d.join("cut.jpg");
    let bytes = std::fs::read(&big).unwrap();
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let r = rectify(&sc, &cut, &out, &[]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.contains(s(&cut)) && err.contains("truncated"), "{err}");
    assert!(!out.exists());
}

/// `jpeg` with an APP1 EXIF segment holding only an Orientation tag, put
/// right after its start-of-image marker (little-endian TIFF structure).
fn with_exif_orientation(jpeg: &[u8], orientation: u16) -> Vec<u8> {
    let mut tiff = b"II*\0\x08\0\0\0".to_vec();
    tiff.extend_from_slice(&1u16.to_le_bytes()); // one entry
    tiff.extend_from_slice(&0x0112u16.to_le_bytes()); // Orientation
    tiff.extend_from_slice(&3u16.to_le_bytes()); // SHORT
    tiff.extend_from_slice(&1u32.to_le_bytes());
    tiff.extend_from_slice(&orientation.to_le_bytes());
    tiff.extend_from_slice(&[0, 0]);
    tiff.extend_from_slice(&0u32.to_le_bytes()); // no next directory
    let mut app1 = b"Exif\0\0".to_vec();
    app1.extend_from_slice(&tiff);
    let mut out = jpeg[..2].to_vec();
    out.extend_from_slice(&[0xFF, 0xE1]);
    out.extend_from_slice(&((app1.len() + 2) as u16).to_be_bytes());
    out.extend_from_slice(&app1);
    out.extend_from_slice(&jpeg[2..]);
    out
}

#[test]
fn files_that_are_not_images_we_read_are_refused_saying_what_they_are() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = drone(&d.join("scene"), 3, 8);
    for (name, bytes, found) in [
        ("a.gif", b"GIF89a\x01\x00\x01\x00".to_vec(), "a GIF"),
        ("a.vrt", b"<VRTDataset rasterXSize=\"10\">".to_vec(), "XML or HTML text"),
        ("empty.tif", Vec::new(), "an empty file"),
        ("noise.tif", vec![0x13, 0x37, 0, 1, 2, 3, 4, 5, 6, 7], "first bytes 13 37"),
    ] {
        let p = d.join(name);
        std::fs::write(&p, bytes).unwrap();
        let out = d.join("out.tif");
        let r = rectify(&sc, &p, &out, &[]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(1), "{name}: {err}");
        assert!(err.contains(s(&p)) && err.contains(found) && err.contains("TIFF or BigTIFF, JPEG, PNG"), "{name}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(!out.exists());
    }
}

#[test]
fn a_dem_in_tiles_as_a_vrt_a_folder_or_a_list_gives_the_merged_dems_orthophoto() {
    if !have("gdal_translate") || !have("gdalbuildvrt") {
        eprintln!("skipped: GDAL is not installed");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = drone(&d.join("scene"), 3, 8);
    let (_, info) = whole_image(&sc.dem);
    let (w, h) = (info.width, info.height);
    let (hw, hh) = (w / 2, h / 2);
    // Four tiles that share their edge posts, as SRTM tiles do.
    let tiles = d.join("tiles");
    std::fs::create_dir(&tiles).unwrap();
    for (name, x, y, tw, th) in [("a", 0, 0, hw + 1, hh + 1), ("b", hw, 0, w - hw, hh + 1), ("c", 0, hh, hw + 1, h - hh), ("d", hw, hh, w - hw, h - hh)] {
        let (x, y, tw, th) = (x.to_string(), y.to_string(), tw.to_string(), th.to_string());
        gdal_translate(&["-srcwin", &x, &y, &tw, &th, s(&sc.dem), s(&tiles.join(format!("{name}.tif")))]);
    }
    let vrt = d.join("dem.vrt");
    let mut args = vec!["-q".to_string(), s(&vrt).to_string()];
    args.extend(["a", "b", "c", "d"].map(|n| s(&tiles.join(format!("{n}.tif"))).to_string()));
    assert!(Command::new("gdalbuildvrt").args(&args).status().unwrap().success());
    let want = rectified(&sc, &sc.scan, &d.join("merged.tif"));
    // A list of the tiles (relative to the list; a comment, a blank line).
    let list = d.join("tiles.txt");
    std::fs::write(&list, "# SRTM-like tiles\ntiles/a.tif\n\ntiles/b.tif\ntiles/c.tif\ntiles/d.tif\n").unwrap();
    for (what, dem) in [("VRT", &vrt), ("folder", &tiles), ("list", &list)] {
        let out = d.join(format!("{what}.tif"));
        let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(dem), "-o", s(&out), "--quiet"]);
        assert!(r.status.success(), "{what}: {}", String::from_utf8_lossy(&r.stderr));
        assert!(whole_image(&out).0 == want, "{what}: the orthophoto differs from the merged DEM's");
    }
    // A list naming a file that is not there is refused by its line.
    let bad_list = d.join("bad-list.txt");
    std::fs::write(&bad_list, "tiles/a.tif\ntiles/e.tif\n").unwrap();
    let out = d.join("bad.tif");
    let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&bad_list), "-o", s(&out), "--quiet"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.contains(s(&bad_list)) && err.contains("line 2 names no file: \"tiles/e.tif\""), "{err}");
    assert!(!out.exists());
    // What a VRT may hold beyond placed sources is refused by name.
    let text = std::fs::read_to_string(&vrt).unwrap();
    let at = text.find("<DstRect").unwrap();
    let end = at + text[at..].find("/>").unwrap() + 2;
    for (name, changed, said) in [
        ("resampled", format!("{}<DstRect xOff=\"0\" yOff=\"0\" xSize=\"7\" ySize=\"7\" />{}", &text[..at], &text[end..]), "resampled"),
        ("kernel", text.replace("ComplexSource>", "KernelFilteredSource>").replace("SimpleSource>", "KernelFilteredSource>"), "<KernelFilteredSource>"),
        ("derived", text.replace("<VRTRasterBand ", "<VRTRasterBand subClass=\"VRTDerivedRasterBand\" "), "VRTDerivedRasterBand"),
        (
            "other-srs",
            {
                let (a, b) = (text.find("<SRS").unwrap(), text.find("</SRS>").unwrap() + 6);
                format!("{}<SRS>EPSG:32632</SRS>{}", &text[..a], &text[b..])
            },
            "EPSG:32632",
        ),
    ] {
        let bad = d.join(format!("{name}.vrt"));
        std::fs::write(&bad, changed).unwrap();
        let out = d.join("bad.tif");
        let r = run(&["rectify", "--image", s(&sc.scan), "--camera", s(&sc.camera), "--dem", s(&bad), "-o", s(&out), "--quiet"]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && err.contains(s(&bad)) && err.contains(said), "{name}: {err}");
        assert!(!out.exists());
    }
}

/// A 12-bit image (GDAL's NBITS=12, as raw satellite products come: bits
/// packed, striped or tiled and deflated, or 11-bit) is read as 16-bit
/// samples: the orthophoto is the 16-bit file's, pixel for pixel.
#[test]
fn packed_twelve_bit_images_give_the_sixteen_bit_orthophoto() {
    if !have("gdal_translate") {
        assert!(std::env::var_os("CI").is_none(), "CI must compare with GDAL (install gdal-bin)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sc = drone(&d.join("rgb"), 3, 8);
    let wide = d.join("u16.tif");
    gdal_translate(&["-ot", "UInt16", "-scale", "0", "255", "0", "2047", s(&sc.scan), s(&wide)]);
    let want = rectified(&sc, &wide, &d.join("u16-ortho.tif"));
    for (name, bits, options) in [
        ("12-striped", 12, &["-co", "NBITS=12"][..]),
        ("12-tiled-deflate", 12, &["-co", "NBITS=12", "-co", "TILED=YES", "-co", "COMPRESS=DEFLATE"]),
        ("11-band-planar", 11, &["-co", "NBITS=11", "-co", "INTERLEAVE=BAND", "-co", "COMPRESS=LZW"]),
        // Bits have no byte order: a big-endian file's are the same.
        ("12-big-endian", 12, &["-co", "NBITS=12", "-co", "ENDIANNESS=BIG"]),
        ("12-big-endian-tiled", 12, &["-co", "NBITS=12", "-co", "ENDIANNESS=BIG", "-co", "TILED=YES", "-co", "COMPRESS=DEFLATE"]),
    ] {
        let packed = d.join(format!("{name}.tif"));
        gdal_translate(&[options, &[s(&wide), s(&packed)]].concat());
        let info = gcm_ortho::io::source::SourceImage::info_of(&packed).unwrap();
        assert_eq!(info.packed_bits, bits, "{name}");
        assert!(rectified(&sc, &packed, &d.join(format!("{name}-ortho.tif"))) == want, "{name}");
    }
}
