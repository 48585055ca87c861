//! Bad input never panics, never leaves a file behind, and is answered by
//! one clear line naming the file and the problem, with a non-zero exit.
//!
//! The corpus lives in `tests/malformed/<what>/<kind>.<ext>`: one folder per
//! input (scan, camera, dem, rpc, rpc_camera, geoid) and one for scans whose
//! compressed chunks are damaged (corrupt), one file per kind of failure. It is made from the small scene in `fixtures/mini` and the real
//! files in `fixtures/rpc` and `fixtures/ventoux` by `regenerate_corpus`
//! below (run it with `cargo test --test malformed -- --ignored` after
//! changing it).

mod common;
use common::*;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn mini(name: &str) -> PathBuf {
    root().join("fixtures/mini").join(name)
}

/// Little-endian classic TIFF: the first IFD's entries as (entry offset, tag, type, count, value/offset).
fn entries(b: &[u8]) -> Vec<(usize, u16, u16, u32, u32)> {
    let u16at = |o: usize| u16::from_le_bytes([b[o], b[o + 1]]);
    let u32at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    let ifd = u32at(4) as usize;
    (0..u16at(ifd) as usize)
        .map(|k| {
            let e = ifd + 2 + 12 * k;
            (e, u16at(e), u16at(e + 2), u32at(e + 4), u32at(e + 8))
        })
        .collect()
}

/// Sets the first value of `tag` (SHORT or LONG; inline or in an array).
fn patch(b: &mut [u8], tag: u16, value: u32) {
    let (e, _, ty, count, v) = *entries(b).iter().find(|x| x.1 == tag).unwrap_or_else(|| panic!("tag {tag} present"));
    let inline = (ty == 3 && count <= 2) || (ty == 4 && count <= 1);
    let at = if inline { e + 8 } else { v as usize };
    match ty {
        3 => b[at..at + 2].copy_from_slice(&(value as u16).to_le_bytes()),
        4 => b[at..at + 4].copy_from_slice(&value.to_le_bytes()),
        _ => panic!("tag {tag} has type {ty}"),
    }
}

fn tag_value(b: &[u8], tag: u16) -> u32 {
    let (_, _, ty, count, v) = *entries(b).iter().find(|x| x.1 == tag).unwrap();
    if (ty == 3 && count <= 2) || (ty == 4 && count <= 1) {
        if ty == 3 {
            v & 0xffff
        } else {
            v
        }
    } else {
        u32::from_le_bytes(b[v as usize..v as usize + 4].try_into().unwrap())
    }
}

#[test]
#[ignore = "writes the corpus into the source tree"]
fn regenerate_corpus() {
    let dir = root().join("tests/malformed");
    let scan = std::fs::read(mini("scan.tif")).unwrap();
    let w = |sub: &str, name: &str, data: &[u8]| {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
        std::fs::write(dir.join(sub).join(name), data).unwrap();
    };
    // --- scans ---
    w("scan", "empty.tif", b"");
    w("scan", "not_a_tiff.tif", b"This is a text file, not an image.\n");
    w("scan", "header_only.tif", &scan[..8]);
    let strip0 = tag_value(&scan, 273) as usize;
    w("scan", "cut_in_strip.tif", &scan[..strip0 + 1000]);
    w("scan", "cut_in_ifd.tif", &scan[..scan.len() - 40]);
    let mut b = scan.clone();
    b[4..8].copy_from_slice(&0x7fff_fff0u32.to_le_bytes());
    w("scan", "ifd_offset_past_end.tif", &b);
    let mut b = scan.clone();
    b[4..8].copy_from_slice(&8u32.to_le_bytes()); // IFD read from pixel data
    w("scan", "ifd_points_into_pixels.tif", &b);
    let mut b = scan.clone();
    patch(&mut b, 256, 0xffff_ffff);
    patch(&mut b, 257, 0xffff_ffff);
    w("scan", "absurd_size.tif", &b);
    let mut b = scan.clone();
    patch(&mut b, 279, 0x7fff_0000);
    w("scan", "strip_bytes_past_end.tif", &b);
    let mut b = scan.clone();
    patch(&mut b, 339, 2);
    w("scan", "signed_samples.tif", &b);
    let mut b = scan.clone();
    patch(&mut b, 258, 1);
    w("scan", "one_bit.tif", &b);
    let mut b = scan.clone();
    patch(&mut b, 262, 3);
    w("scan", "palette.tif", &b);
    let mut b = scan.clone();
    patch(&mut b, 259, 8); // claims deflate, holds raw pixels
    w("scan", "strip_does_not_decompress.tif", &b);
    let mut b = scan.clone();
    patch(&mut b, 278, 1); // one row per strip, but only the original strip table
    w("scan", "strip_table_too_short.tif", &b);

    // --- scans whose compressed chunks are damaged (the codecs' own checks) ---
    let (pixels, info) = whole_image(&mini("scan.tif"));
    let coded = |compression| {
        use gcm_ortho::io::tiff_out::{write_raster, Chunking, OutputSpec};
        let t = tempfile::tempdir().unwrap();
        let path = t.path().join("c.tif");
        let spec = OutputSpec {
            overviews: 0,
            cog: false,
            width: info.width,
            height: info.height,
            bands: info.bands,
            sample: info.sample,
            chunking: Chunking::Strips(16),
            compression,
            level: None,
            overview_level: None,
            bigtiff: false,
            photometric: info.photometric,
            alpha: false,
            mask: false,
            geo: None,
        };
        let row = info.width as usize * info.pixel_bytes();
        write_raster(&path, &spec, |y0, y1, buf| buf.copy_from_slice(&pixels[y0 as usize * row..y1 as usize * row])).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let src = gcm_ortho::io::source::SourceImage::open(&path, 1 << 20).unwrap();
        let (o, c) = src.info.chunk_table();
        (bytes, o[2] as usize, c[2] as usize)
    };
    use gcm_ortho::io::tiff_out::Compression;
    let (mut b, at, len) = coded(Compression::Deflate);
    b[at + len - 1] ^= 1; // the last byte of strip 2's Adler-32
    w("corrupt", "deflate_bad_checksum.tif", &b);
    let (mut b, at, len) = coded(Compression::Deflate);
    b[at + len / 2..at + len / 2 + 8].fill(0xff);
    w("corrupt", "deflate_damaged_stream.tif", &b);
    let (mut b, at, len) = coded(Compression::Zstd);
    b[at + len / 2..at + len / 2 + 8].fill(0xff);
    w("corrupt", "zstd_damaged_stream.tif", &b);
    let (mut b, at, len) = coded(Compression::Lzw);
    b[at + len / 2..at + len / 2 + 8].fill(0xff);
    w("corrupt", "lzw_damaged_stream.tif", &b);

    // --- cameras ---
    let cam = std::fs::read_to_string(mini("camera.toml")).unwrap();
    let c = |name: &str, text: String| w("camera", name, text.as_bytes());
    let drop_line = |key: &str| cam.lines().filter(|l| !l.trim_start().starts_with(key)).collect::<Vec<_>>().join("\n");
    c("missing_crs.toml", drop_line("crs ="));
    c("missing_focal.toml", drop_line("focal_length_mm"));
    c("missing_position.toml", drop_line("position"));
    c("missing_angles.toml", drop_line("angles_deg"));
    c("missing_convention.toml", drop_line("convention"));
    c("missing_fiducials_px.toml", drop_line("fiducials_px"));
    c("unknown_field.toml", cam.replace("focal_length_mm", "focal_lenght_mm"));
    c("wrong_type.toml", cam.replace("focal_length_mm = 152.0", "focal_length_mm = \"152\""));
    c("nan_focal.toml", cam.replace("focal_length_mm = 152.0", "focal_length_mm = nan"));
    let pos_line = cam.lines().find(|l| l.starts_with("position")).unwrap().to_string();
    c("inf_position.toml", cam.replace(&pos_line, "position = [inf, 4890000.0, 1820.0]"));
    c("negative_focal.toml", cam.replace("focal_length_mm = 152.0", "focal_length_mm = -152.0"));
    c("unknown_convention.toml", cam.replace("alpha-omega-kappa", "kappa-phi-omega"));
    c("bad_crs.toml", cam.replace("EPSG:32631", "UTM31"));
    c("unknown_model.toml", cam.replace("model = \"frame\"", "model = \"pushbroom\""));
    let fid_line = cam.lines().find(|l| l.starts_with("fiducials_mm")).unwrap().to_string();
    c("collinear_fiducials.toml", cam.replace(&fid_line, "fiducials_mm = [[-117.5, -117.5], [0.0, 0.0], [117.5, 117.5], [50.0, 50.0]]"));
    c("not_toml.toml", "this is [not toml\n".into());
    let angles_line = cam.lines().find(|l| l.starts_with("angles_deg")).unwrap().to_string();
    c("looks_up.toml", cam.replace(&angles_line, "angles_deg = [0.0, 180.0, 0.0]"));
    c("focal_in_micrometres.toml", cam.replace("focal_length_mm = 152.0", "focal_length_mm = 152000.0"));
    c("principal_point_outside.toml", cam.replace("principal_point_mm = [0.004, -0.009]", "principal_point_mm = [400.0, -0.009]"));
    c("misplaced_mark.toml", cam.replace("[[14.896953853290603, 190.54974293054275]", "[[44.896953853290603, 190.54974293054275]"));

    // --- DEMs ---
    let dem = std::fs::read(mini("dem.tif")).unwrap();
    let mut b = dem.clone();
    patch(&mut b, 339, 2); // 32-bit signed integers are fine; make it 1-bit instead
    patch(&mut b, 258, 1);
    w("dem", "one_bit.tif", &b);
    w("dem", "three_bands.tif", &std::fs::read(mini("scan.tif")).map(|_| rgb_dem()).unwrap());
    w("dem", "truncated.tif", &dem[..dem.len() / 2]);
    w("dem", "no_georeferencing.tif", &std::fs::read(mini("scan.tif")).unwrap());
    let keys = dem_with_epsg(&dem, 4326);
    w("dem", "other_crs.tif", &keys);
    w("dem", "all_nodata.tif", &dem_all_nodata(&dem));
    w("dem", "far_away.tif", &dem_shifted(&dem, 50_000.0));
    w("dem", "one_post.tif", &small_dem(1, 1, |_| 300.0));

    // --- RPC files (for the Ventoux crop) ---
    let rpc_txt = std::fs::read_to_string(root().join("fixtures/rpc/rpc_IKONOS.txt")).unwrap();
    let r = |name: &str, data: &[u8]| w("rpc", name, data);
    let without = |t: &str, key: &str| t.lines().filter(|l| !l.trim_start().starts_with(key)).map(|l| format!("{l}\n")).collect::<String>();
    let with = |t: &str, key: &str, v: &str| {
        t.lines().map(|l| if l.trim_start().starts_with(key) { format!("{key} {v}\n") } else { format!("{l}\n") }).collect::<String>()
    };
    r("empty.txt", b"");
    r("binary_junk.bin", &[0xff, 0xfe, 0x00, 0x01, 0x80, 0x81, 0x82, 0xc3, 0x28]);
    r("missing_coefficient.txt", without(&rpc_txt, "SAMP_DEN_COEFF_7:").as_bytes());
    r("missing_line_off.txt", without(&rpc_txt, "LINE_OFF:").as_bytes());
    r("nan_coefficient.txt", with(&rpc_txt, "LINE_NUM_COEFF_3:", "nan").as_bytes());
    r("zero_scale.txt", with(&rpc_txt, "LAT_SCALE:", "0").as_bytes());
    let mut zero_den = rpc_txt.clone();
    for i in 1..=20 {
        zero_den = with(&zero_den, &format!("LINE_DEN_COEFF_{i}:"), "0");
    }
    r("zero_denominator.txt", zero_den.as_bytes());
    let dimap = std::fs::read_to_string(root().join("fixtures/ventoux/RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML")).unwrap();
    r("dimap_truncated.xml", &dimap.as_bytes()[..dimap.len() / 2]);
    r("dimap_missing_samp_off.xml", without(&dimap, "<SAMP_OFF>").as_bytes());
    r("xml_without_rpc.xml", b"<?xml version=\"1.0\"?>\n<Dimap_Document><Metadata_Identification/></Dimap_Document>\n");
    let wv = std::fs::read_to_string(root().join("fixtures/rpc/rpc_WV2.xml")).unwrap();
    r("worldview_bad_number.xml", wv.replacen("<LINENUMCOEF>1.594159000000000e-03", "<LINENUMCOEF>1.59x", 1).as_bytes());
    r("worldview_19_coefficients.xml", wv.replacen("<SAMPDENCOEF>1.000000000000000e+00 ", "<SAMPDENCOEF>", 1).as_bytes());
    let geom = std::fs::read_to_string(root().join("fixtures/ventoux/left_image.geom")).unwrap();
    r("rpc00a.geom", geom.replace("polynomial_format:  B", "polynomial_format:  A").as_bytes());
    r("geom_missing_coefficient.geom", without(&geom, "samp_num_coeff_19:").as_bytes());
    let lat_line = geom.lines().find(|l| l.starts_with("lat_off:")).unwrap().to_string();
    r("lat_off_95.geom", geom.replace(&lat_line, "lat_off:  95.0").as_bytes());
    let rpb = std::fs::read_to_string(root().join("fixtures/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.RPB")).unwrap();
    r("rpb_bad_number.RPB", rpb.replacen("lineOffset = 11469.5;", "lineOffset = 11469.5.5;", 1).as_bytes());
    let ntf = std::fs::read(root().join("fixtures/rpc/wv3_20.NTF")).unwrap();
    let at = ntf.windows(6).position(|x| x == b"RPC00B").unwrap();
    r("nitf_cut_in_tre.ntf", &ntf[..at + 200]);
    r("nitf_without_rpc.ntf", b"NITF02.10 a header and nothing else");
    r("tiff_without_rpc_tag.tif", &std::fs::read(mini("scan.tif")).unwrap());
    r("gdal_vrt.xml", &std::fs::read(root().join("fixtures/rpc/rpc_unsupported.xml")).unwrap());

    // --- camera files with model = "rpc" ---
    let rc = |name: &str, text: &str| w("rpc_camera", name, text.as_bytes());
    let good = "crs = \"EPSG:32631\"\n[camera]\nmodel = \"rpc\"\n[rpc]\nfile = \"../../../fixtures/ventoux/left_image.geom\"\noffset_px = [5000, 5000]\n";
    rc("missing_rpc_section.toml", "crs = \"EPSG:32631\"\n[camera]\nmodel = \"rpc\"\n");
    rc("file_and_inline.toml", &format!("{good}line_off = 3.0\n"));
    rc("unknown_inline_key.toml", "crs = \"auto\"\n[camera]\nmodel = \"rpc\"\n[rpc]\nlin_off = 3.0\n");
    rc("inline_short_list.toml", &inline_rpc(&rpc_txt).replace("line_num_coeff = [", "line_num_coeff = [1.0, "));
    rc("focal_length_in_rpc.toml", &good.replace("model = \"rpc\"", "model = \"rpc\"\nfocal_length_mm = 152.0"));
    rc("nan_offset.toml", &good.replace("[5000, 5000]", "[nan, 5000]"));
    rc("bad_crs.toml", &good.replace("EPSG:32631", "UTM31"));
    rc("unknown_epsg.toml", &good.replace("EPSG:32631", "EPSG:999999"));
    rc("exterior_in_rpc.toml", &format!("{good}[exterior]\nposition = [0.0, 0.0, 0.0]\nangles_deg = [0.0, 0.0, 0.0]\nconvention = \"omega-phi-kappa\"\n"));

    // --- geoid grids ---
    let gtx = std::fs::read(root().join("fixtures/ventoux/egm96_15_ventoux.gtx")).unwrap();
    w("geoid", "truncated.gtx", &gtx[..gtx.len() - 100]);
    w("geoid", "header_only.gtx", &gtx[..40]);
    let mut b = gtx.clone();
    b[16..24].copy_from_slice(&(-0.25f64).to_be_bytes());
    w("geoid", "negative_step.gtx", &b);
    w("geoid", "not_a_grid.gtx", b"geoid heights, but as text\n");
    let mut b = gtx.clone();
    b[0..8].copy_from_slice(&60.0f64.to_be_bytes()); // the grid moved north of the scene
    w("geoid", "not_covering.gtx", &b);
}

/// An RPC text file written inline in a camera file.
fn inline_rpc(rpc_txt: &str) -> String {
    let rpc = gcm_ortho::camera::rpc::Rpc::parse_text(rpc_txt, Path::new("x")).unwrap();
    let list = |v: &[f64; 20]| v.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(", ");
    format!(
        "crs = \"auto\"\n[camera]\nmodel = \"rpc\"\n[rpc]\nline_off = {:?}\nsamp_off = {:?}\nlat_off = {:?}\nlong_off = {:?}\nheight_off = {:?}\nline_scale = {:?}\nsamp_scale = {:?}\nlat_scale = {:?}\nlong_scale = {:?}\nheight_scale = {:?}\nline_num_coeff = [{}]\nline_den_coeff = [{}]\nsamp_num_coeff = [{}]\nsamp_den_coeff = [{}]\n",
        rpc.line_off, rpc.samp_off, rpc.lat_off, rpc.long_off, rpc.height_off, rpc.line_scale, rpc.samp_scale, rpc.lat_scale, rpc.long_scale, rpc.height_scale,
        list(&rpc.line_num), list(&rpc.line_den), list(&rpc.samp_num), list(&rpc.samp_den)
    )
}

/// A 3-band GeoTIFF where a DEM is expected.
fn rgb_dem() -> Vec<u8> {
    use gcm_ortho::io::tiff_out::*;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("rgb.tif");
    let spec = OutputSpec {
        overviews: 0,
        cog: false,
        width: 8,
        height: 8,
        bands: 3,
        sample: gcm_ortho::io::source::SampleType::U8,
        chunking: Chunking::Strips(8),
        compression: Compression::None,
        level: None,
        overview_level: None,
        bigtiff: false,
        photometric: 2,
        alpha: false,
        mask: false,
        geo: Some(GeoTags {
            x0: 649000.0,
            y0: 4891000.0,
            gsd: gcm_ortho::geom::Gsd::square(100.0),
            keys: gcm_ortho::geodesy::geokeys::keys_of_epsg(32631).unwrap(),
            nodata: None,
        }),
    };
    write_raster(&p, &spec, |_, _, buf| buf.fill(100)).unwrap();
    std::fs::read(&p).unwrap()
}

/// A Float32 DEM of `w`×`h` posts over the mini scene, no nodata tag,
/// sample `k` (row-major) `height(k)`.
fn small_dem(w: u32, h: u32, height: impl Fn(usize) -> f32 + Sync) -> Vec<u8> {
    use gcm_ortho::io::tiff_out::*;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("dem.tif");
    let spec = OutputSpec {
        overviews: 0,
        cog: false,
        width: w,
        height: h,
        bands: 1,
        sample: gcm_ortho::io::source::SampleType::F32,
        chunking: Chunking::Strips(h),
        compression: Compression::None,
        level: None,
        overview_level: None,
        bigtiff: false,
        photometric: 1,
        alpha: false,
        mask: false,
        geo: Some(GeoTags {
            x0: 649000.0,
            y0: 4893000.0,
            gsd: gcm_ortho::geom::Gsd::square(4000.0 / w as f64),
            keys: gcm_ortho::geodesy::geokeys::keys_of_epsg(32631).unwrap(),
            nodata: None,
        }),
    };
    write_raster(&p, &spec, |y0, _, buf| {
        for (i, v) in buf.chunks_exact_mut(4).enumerate() {
            v.copy_from_slice(&height(y0 as usize * w as usize + i).to_le_bytes());
        }
    })
    .unwrap();
    std::fs::read(&p).unwrap()
}

fn dem_with_epsg(dem: &[u8], epsg: u16) -> Vec<u8> {
    let mut b = dem.to_vec();
    let (_, _, _, _, off) = *entries(&b).iter().find(|x| x.1 == 34735).unwrap();
    let off = off as usize;
    // keys: header (4 shorts), then (id, location, count, value) × 3:
    // model type, raster type, CRS. Make it a geographic CRS.
    b[off + 2 * 7..off + 2 * 8].copy_from_slice(&2u16.to_le_bytes());
    b[off + 2 * 12..off + 2 * 13].copy_from_slice(&2048u16.to_le_bytes());
    b[off + 2 * 15..off + 2 * 16].copy_from_slice(&epsg.to_le_bytes());
    b
}

fn dem_all_nodata(dem: &[u8]) -> Vec<u8> {
    // Every sample NaN (Float32 nodata by definition).
    let mut b = dem.to_vec();
    let offs = tag_value(&b, 273) as usize;
    let es = entries(&b);
    let (_, _, _, count, table) = *es.iter().find(|x| x.1 == 273).unwrap();
    let (_, _, _, _, counts) = *es.iter().find(|x| x.1 == 279).unwrap();
    let u32at = |b: &[u8], o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap()) as usize;
    for k in 0..count as usize {
        let (o, n) = if count == 1 { (offs, u32at(&b, counts as usize)) } else { (u32at(&b, table as usize + 4 * k), u32at(&b, counts as usize + 4 * k)) };
        for s in (o..o + n).step_by(4) {
            b[s..s + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        }
    }
    b
}

fn dem_shifted(dem: &[u8], dx: f64) -> Vec<u8> {
    let mut b = dem.to_vec();
    let (_, _, _, _, off) = *entries(&b).iter().find(|x| x.1 == 33922).unwrap();
    let o = off as usize + 3 * 8;
    let x = f64::from_le_bytes(b[o..o + 8].try_into().unwrap());
    b[o..o + 8].copy_from_slice(&(x + dx).to_le_bytes());
    b
}

/// Runs rectify with one bad input and the rest from `fixtures/mini`.
fn check(what: &str, file: &Path) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.tif");
    let ventoux = |n: &str| root().join("fixtures/ventoux").join(n);
    let (image, vdem, geom) = (ventoux("left_image.tif"), ventoux("srtm_N44E005_crop.tif"), ventoux("left_image.geom"));
    let satellite = |extra: Vec<&str>| -> Vec<String> {
        let mut a = vec!["rectify", "--image", s(&image), "--dem", s(&vdem), "-o", s(&out), "--quiet"];
        a.extend(extra);
        a.into_iter().map(String::from).collect()
    };
    let args: Vec<String> = match what {
        "scan" | "corrupt" | "camera" | "dem" => {
            let (scan, cam, dem) = match what {
                "scan" | "corrupt" => (file.to_path_buf(), mini("camera.toml"), mini("dem.tif")),
                "camera" => (mini("scan.tif"), file.to_path_buf(), mini("dem.tif")),
                _ => (mini("scan.tif"), mini("camera.toml"), file.to_path_buf()),
            };
            ["rectify", "--image", s(&scan), "--camera", s(&cam), "--dem", s(&dem), "-o", s(&out), "--quiet"].map(String::from).to_vec()
        }
        "rpc" => satellite(vec!["--rpc", s(file), "--rpc-offset", "5000,5000"]),
        "rpc_camera" => satellite(vec!["--camera", s(file)]),
        _ => satellite(vec!["--rpc", s(&geom), "--rpc-offset", "5000,5000", "--geoid", s(file)]),
    };
    let t = std::time::Instant::now();
    let r = run(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let err = String::from_utf8_lossy(&r.stderr);
    let name = file.file_name().unwrap().to_str().unwrap();
    assert!(!r.status.success(), "{what}/{name}: succeeded");
    assert_eq!(r.status.code(), Some(1), "{what}/{name}: {err}");
    assert!(!err.contains("panicked"), "{what}/{name}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{what}/{name}: not one line: {err}");
    assert!(err.contains(name), "{what}/{name}: the message does not name the file: {err}");
    assert!(!out.exists(), "{what}/{name}: an output was left");
    assert!(files_containing(dir.path(), "partial").is_empty(), "{what}/{name}: a temporary file was left");
    assert!(t.elapsed().as_secs() < 20, "{what}/{name}: took {:?}", t.elapsed());
}

#[test]
fn every_malformed_input_fails_cleanly() {
    let mut n = 0;
    for what in ["scan", "corrupt", "camera", "dem", "rpc", "rpc_camera", "geoid"] {
        let dir = root().join("tests/malformed").join(what);
        let mut files: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
        files.sort();
        for f in files {
            check(what, &f);
            n += 1;
        }
    }
    assert!(n >= 70, "only {n} malformed files");
}

#[test]
fn the_good_fixture_works() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.tif");
    let r = run(&["rectify", "--image", s(&mini("scan.tif")), "--camera", s(&mini("camera.toml")), "--dem", s(&mini("dem.tif")), "-o", s(&out), "--quiet"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(out.exists());
}

#[test]
fn unwritable_output_folder_fails_before_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("no/such/folder/out.tif");
    let r = run(&["rectify", "--image", s(&mini("scan.tif")), "--camera", s(&mini("camera.toml")), "--dem", s(&mini("dem.tif")), "-o", s(&out), "--quiet"]);
    let err = String::from_utf8_lossy(&r.stderr);
    // A path that cannot be an output is a bad argument, told before work.
    assert_eq!(r.status.code(), Some(2));
    assert!(err.contains("no/such/folder") && err.contains("does not exist") && err.trim_end().lines().count() == 1, "{err}");
}

#[test]
fn usage_errors_exit_2() {
    let r = run(&["rectify", "--image", "a.tif", "--camera", "c.toml", "-o", "o.tif"]);
    assert_eq!(r.status.code(), Some(2), "{}", String::from_utf8_lossy(&r.stderr));
    let r = run(&["rectify", "--image", "a.tif", "--camera", "c.toml", "--height", "10", "--memory", "lots", "-o", "o.tif"]);
    assert_eq!(r.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&r.stderr).contains("--memory"));
}

/// Problems that used to say "the scan's centre does not meet the
/// DEM": each is told as what it is.
#[test]
fn each_cause_has_its_own_message() {
    let m = |what: &str, name: &str| root().join("tests/malformed").join(what).join(name);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.tif");
    for (what, name, cause) in [
        ("camera", "looks_up.toml", "above the horizon"),
        ("camera", "focal_in_micrometres.toml", "field of view"),
        ("camera", "pixel_size_in_micrometres.toml", "pixel_size_mm is in millimetres"),
        ("camera", "principal_point_outside.toml", "principal point"),
        ("camera", "misplaced_mark.toml", "placed wrong"),
        ("dem", "one_post.tif", "at least 2×2"),
        ("rpc", "lat_off_95.geom", "LAT_OFF"),
    ] {
        let f = m(what, name);
        let ventoux = |n: &str| root().join("fixtures/ventoux").join(n);
        let args: Vec<String> = match what {
            "camera" => ["rectify", "--image", s(&mini("scan.tif")), "--camera", s(&f), "--dem", s(&mini("dem.tif"))].map(String::from).to_vec(),
            "dem" => ["rectify", "--image", s(&mini("scan.tif")), "--camera", s(&mini("camera.toml")), "--dem", s(&f)].map(String::from).to_vec(),
            _ => ["rectify", "--image", s(&ventoux("left_image.tif")), "--rpc", s(&f), "--rpc-offset", "5000,5000", "--height", "1000"]
                .map(String::from)
                .to_vec(),
        };
        let mut args: Vec<&str> = args.iter().map(String::as_str).collect();
        args.extend(["-o", s(&out), "--quiet"]);
        let r = run(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(1), "{name}: {err}");
        assert!(err.contains(name) && err.contains(cause) && !err.contains("does not meet"), "{name}: {err}");
    }
}
