//! Height maps from EXR (half, float or uint channels, read raw) and PNG / TIFF (8/16-bit
//! normalised to [0, 1]; TIFF also 32/64-bit float, grey or colour, read raw, and 32-bit grey
//! integers normalised), into a `HeightMap` with row 0 at the top.
//!
//! Colour images give their first channel (R), grey ones L. NaN texels are kept: the validate
//! command reports them (`HeightMap::first_non_finite`). Dimensions are checked from the header
//! before any pixel is decoded, so a hostile header cannot make us allocate gigabytes.

use super::MapOptions;
use crate::error::{Error, Result};
use crate::heightmap::HeightMap;
use std::path::Path;

/// Largest accepted width or height. 32768² f32 texels is already 4 GiB; anything larger in a
/// header is far more likely a corrupt or hostile file than a real height map.
pub const MAX_MAP_DIMENSION: u32 = 32768;

pub const MAP_EXTENSIONS: &str = ".exr, .png, .tif or .tiff";

pub fn load(path: &Path, opts: &MapOptions) -> Result<HeightMap> {
    let ext = super::extension(path);
    let (width, height, data, channel) = match ext.as_str() {
        "exr" => load_exr(path, opts.channel.as_deref())?,
        "png" => load_raster(path, ::image::ImageFormat::Png, opts.channel.as_deref())?,
        "tif" | "tiff" => load_tiff(path, opts.channel.as_deref())?,
        _ => {
            return Err(Error::UnsupportedFormat {
                path: path.into(),
                ext,
                expected: MAP_EXTENSIONS,
            })
        }
    };
    let mut map = HeightMap::new(width, height, data, opts.wrap);
    map.source = path.into();
    map.channel = channel;
    Ok(map)
}

fn check_dimensions(path: &Path, width: usize, height: usize) -> Result<(u32, u32)> {
    if width == 0 || height == 0 {
        return Err(Error::invalid(
            path,
            format!("image is {width}x{height} texels, nothing to sample (re-export the map)"),
        ));
    }
    let max = MAX_MAP_DIMENSION as usize;
    if width > max || height > max {
        return Err(Error::invalid(
            path,
            format!(
                "image is {width}x{height} texels, over the limit of {max} in either dimension \
                 (downsample the map, or check that the file is not corrupt)"
            ),
        ));
    }
    Ok((width as u32, height as u32))
}

type Decoded = (u32, u32, Vec<f32>, String);

/// EXR: the first layer, every channel read, then one picked by name.
fn load_exr(path: &Path, requested: Option<&str>) -> Result<Decoded> {
    // Header first: refuse absurd sizes before the reader allocates pixel storage.
    let header = exr_flat_header(path)?;
    check_dimensions(path, header.layer_size.width(), header.layer_size.height())?;
    check_exr_size(path, &header)?;
    let names: Vec<String> = header
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    let name = pick_exr_channel(path, &names, requested)?;

    let (w, h, mut planes) = read_exr_channels(path, std::slice::from_ref(&name), "the height")?;
    let (w, h) = check_dimensions(path, w, h)?;
    let data = planes.pop().unwrap_or_default();
    Ok((w, h, data, name))
}

/// An EXR's unreadable header or pixels, as the error of `path`.
fn exr_corrupt(path: &Path, e: exr::error::Error) -> Error {
    Error::invalid(
        path,
        format!("cannot read as OpenEXR: {e} (the file is truncated or corrupt; re-export it)"),
    )
}

/// Channels `names` of an EXR's first flat layer (after its header's checks: `exr_flat_header`,
/// `check_exr_size`), each as one f32 a texel, and the layer's width and height. A float
/// channel's samples move out of the decoded layer rather than being copied (a 4096² map is
/// 64 MiB of f32, and two copies at once doubled a load's peak memory). A subsampled channel
/// is an error whose fix names `what` ("the height").
pub(crate) fn read_exr_channels(
    path: &Path,
    names: &[String],
    what: &str,
) -> Result<(usize, usize, Vec<Vec<f32>>)> {
    use exr::prelude::{read, FlatSamples, ReadChannels, ReadLayers};
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| exr_corrupt(path, e))?;
    let layer = image.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let mut channels = layer.channel_data.list;
    let mut planes = Vec::with_capacity(names.len());
    for name in names {
        let i = (channels.iter())
            .position(|c| c.name.to_string() == *name)
            .ok_or_else(|| {
                Error::invalid(
                    path,
                    format!("channel '{name}' vanished between header and pixels"),
                )
            })?;
        let plane: Vec<f32> = match channels.swap_remove(i).sample_data {
            FlatSamples::F16(s) => s.iter().map(|v| v.to_f32()).collect(),
            FlatSamples::F32(s) => s,
            FlatSamples::U32(s) => s.iter().map(|&v| v as f32).collect(),
        };
        if plane.len() != w * h {
            return Err(Error::invalid(
                path,
                format!(
                    "channel '{name}' has {} samples for {w}x{h} texels (subsampled channels are \
                     not supported; write {what} at full resolution)",
                    plane.len()
                ),
            ));
        }
        planes.push(plane);
    }
    Ok((w, h, planes))
}

/// The colour channels of an EXR header to read as red, green and blue: `R`, `G`, `B` (or
/// `layer.R`, …), else `Y`, else the first channel (one name: grey). `what` names the image
/// for the error of a file without channels ("the environment").
pub(crate) fn exr_rgb_channels(
    path: &Path,
    header: &exr::meta::header::Header,
    what: &str,
) -> Result<Vec<String>> {
    let names: Vec<String> = (header.channels.list.iter())
        .map(|c| c.name.to_string())
        .collect();
    let find = |n: &str| {
        names
            .iter()
            .position(|c| c == n || c.ends_with(&format!(".{n}")))
    };
    let picked: Vec<usize> = match (find("R"), find("G"), find("B")) {
        (Some(r), Some(g), Some(b)) => vec![r, g, b],
        _ if names.is_empty() => {
            return Err(Error::invalid(
                path,
                format!("has no channels (write {what} as R, G, B or Y)"),
            ))
        }
        _ => vec![find("Y").unwrap_or(0)],
    };
    Ok(picked.into_iter().map(|i| names[i].clone()).collect())
}

/// The header of an EXR's first flat layer (the one `first_valid_layer` decodes), read
/// before any pixel.
pub(crate) fn exr_flat_header(path: &Path) -> Result<exr::meta::header::Header> {
    let meta =
        exr::meta::MetaData::read_from_file(path, false).map_err(|e| exr_corrupt(path, e))?;
    meta.headers
        .into_iter()
        .find(|h| !h.deep)
        .ok_or_else(|| Error::invalid(path, "has only deep-data layers (write a flat image)"))
}

/// The most an EXR compression expands its bytes to, with room to spare. Measured on the most
/// compressible image there is (constant 2048² RGB, half and float, written by OpenEXR 3.3):
/// RLE 61:1, ZIPS 389, ZIP 902, PIZ 399, PXR24 1 203, B44A 10.7, DWAA 4 146, DWAB 16 716.
fn exr_max_ratio(c: exr::compression::Compression) -> u64 {
    use exr::compression::Compression::*;
    match c {
        Uncompressed => 1,
        RLE => 128,
        // Deflate's limit is 1 032:1; PIZ's run-length codes stay under it.
        ZIP1 | ZIP16 | PIZ => 1_100,
        PXR24 => 1_500,
        B44 | B44A => 16,
        // A flat DWA block keeps one DC value an 8 × 8 block, then deflates those: a float
        // image's bytes can come from 128 × 1 032 times fewer.
        DWAA(_) | DWAB(_) | HTJ2K32 | HTJ2K256 => 262_144,
    }
}

/// An EXR's pixels come out of its bytes through its compression: a header stating more
/// pixel bytes than the file can expand to (`exr_max_ratio`) is corrupt, and is refused
/// before the reader allocates storage for every channel of it (by hand: a 480 KB file
/// stating 60 000² texels made the reader ask for 14.4 GB and abort).
pub(crate) fn check_exr_size(path: &Path, header: &exr::meta::header::Header) -> Result<()> {
    let file = std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len();
    let (w, h) = (
        header.layer_size.width() as u64,
        header.layer_size.height() as u64,
    );
    let per_texel: u64 = (header.channels.list.iter())
        .map(|c| c.sample_type.bytes_per_sample() as u64)
        .sum();
    let pixels = w.saturating_mul(h).saturating_mul(per_texel);
    let ratio = exr_max_ratio(header.compression);
    if states_more_than_it_holds(pixels, file, ratio) {
        return Err(Error::invalid(
            path,
            format!(
                "the header says {w}x{h} texels in {} channels ({pixels} bytes of pixels), more \
                 than a {file}-byte file with {} can hold: the file is truncated or corrupt \
                 (re-export it)",
                header.channels.list.len(),
                header.compression
            ),
        ));
    }
    Ok(())
}

/// The requested channel, else `Y`, else `R`, else the first alphabetically.
fn pick_exr_channel(path: &Path, names: &[String], requested: Option<&str>) -> Result<String> {
    let mut sorted = names.to_vec();
    sorted.sort();
    if let Some(want) = requested {
        return if names.iter().any(|n| n == want) {
            Ok(want.to_string())
        } else {
            Err(Error::invalid(
                path,
                format!(
                    "has no channel '{want}'; its channels are {} (pick one with --channel)",
                    sorted.join(", ")
                ),
            ))
        };
    }
    ["Y", "R"]
        .iter()
        .find(|c| names.iter().any(|n| n == *c))
        .map(|c| c.to_string())
        .or_else(|| sorted.first().cloned())
        .ok_or_else(|| Error::invalid(path, "has no channels (re-export the map)"))
}

/// TIFF: one-channel float and 32-bit integer TIFFs (what sculpting tools export as 32-bit
/// displacement) through the `tiff` decoder, which `image` has no layout for; every other
/// TIFF through `image` (`load_raster`).
fn load_tiff(path: &Path, requested: Option<&str>) -> Result<Decoded> {
    use tiff::decoder::{Decoder, DecodingResult, Limits};
    use tiff::ColorType;
    let corrupt = |e: tiff::TiffError| {
        Error::invalid(
            path,
            format!("cannot decode as TIFF: {e} (the file is truncated or corrupt; re-export it)"),
        )
    };
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let Ok(mut decoder) = Decoder::new(std::io::BufReader::new(file)) else {
        // Not even a TIFF header: let `image` word the error as for every raster.
        return load_raster(path, ::image::ImageFormat::Tiff, requested);
    };
    let bytes = match decoder.colortype() {
        Ok(ColorType::Gray(32)) => 4,
        Ok(ColorType::Gray(64)) => 8,
        _ => return load_raster(path, ::image::ImageFormat::Tiff, requested),
    };
    let (w, h) = decoder.dimensions().map_err(corrupt)?;
    let (w, h) = check_dimensions(path, w as usize, h as usize)?;
    first_channel_only(path, requested, "L")?;
    // The whole image at once, and no more than it needs.
    let mut limits = Limits::default();
    limits.decoding_buffer_size = w as usize * h as usize * bytes;
    let data: Vec<f32> = match decoder.with_limits(limits).read_image().map_err(corrupt)? {
        DecodingResult::F32(v) => v,
        DecodingResult::F64(v) => v.into_iter().map(|x| x as f32).collect(),
        // Integers normalised by their full range, as for 8- and 16-bit maps.
        DecodingResult::U32(v) => v.into_iter().map(|x| (x as f64 / u32::MAX as f64) as f32).collect(),
        DecodingResult::U64(v) => v.into_iter().map(|x| (x as f64 / u64::MAX as f64) as f32).collect(),
        DecodingResult::I32(v) => v.into_iter().map(|x| (x as f64 / i32::MAX as f64) as f32).collect(),
        DecodingResult::I64(v) => v.into_iter().map(|x| (x as f64 / i64::MAX as f64) as f32).collect(),
        _ => return Err(Error::invalid(path, "has a grey sample layout that is not 32/64-bit integer or float (convert the map to EXR)")),
    };
    if data.len() != w as usize * h as usize {
        return Err(Error::invalid(
            path,
            format!(
                "holds {} samples for {w}x{h} texels (re-export the map)",
                data.len()
            ),
        ));
    }
    Ok((w, h, data, "L".to_string()))
}

/// PNG and TIFF maps give their first channel, `name`: any other `--channel` is refused.
fn first_channel_only(path: &Path, requested: Option<&str>, name: &str) -> Result<()> {
    match requested {
        Some(want) if want != name => Err(Error::invalid(
            path,
            format!(
                "has no channel '{want}': PNG and TIFF maps are read from their first channel \
                 ('{name}' here); drop --channel or convert the map to EXR"
            ),
        )),
        _ => Ok(()),
    }
}

/// Whether a header stating `decoded` bytes of pixels asks for more than a `file`-byte file can
/// hold when its compression expands at most `ratio` times (with 64 KiB to spare for tiny
/// files): the check every image reader here makes before it allocates the pixels.
pub(crate) fn states_more_than_it_holds(decoded: u64, file: u64, ratio: u64) -> bool {
    decoded > file.saturating_mul(ratio).saturating_add(1 << 16)
}

/// Deflate's largest ratio of output to input (1032:1), with room for a PNG's chunks.
const DEFLATE_MAX_RATIO: u64 = 1100;

/// A PNG's pixels come from deflate streams, which expand at most `DEFLATE_MAX_RATIO` times:
/// a header stating more pixel bytes than the file can expand to is corrupt, and is refused
/// before the decoder allocates the whole image for it (fuzzed: 2.3 GB from a 95-byte file).
fn check_png_size(path: &Path, w: u32, h: u32, bytes_per_texel: u64) -> Result<()> {
    let file = std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len();
    let pixels = w as u64 * h as u64 * bytes_per_texel;
    if states_more_than_it_holds(pixels, file, DEFLATE_MAX_RATIO) {
        return Err(Error::invalid(
            path,
            format!(
                "the header says {w}x{h} texels ({pixels} bytes of pixels), more than a                  {file}-byte PNG can hold: the file is truncated or corrupt (re-export the map)"
            ),
        ));
    }
    Ok(())
}

/// PNG / TIFF through the `image` crate.
fn load_raster(
    path: &Path,
    format: ::image::ImageFormat,
    requested: Option<&str>,
) -> Result<Decoded> {
    use ::image::{DynamicImage, ImageReader, Limits};
    let open = || -> Result<ImageReader<std::io::BufReader<std::fs::File>>> {
        let mut reader = ImageReader::open(path).map_err(|e| Error::io(path, e))?;
        reader.set_format(format);
        let mut limits = Limits::no_limits();
        limits.max_image_width = Some(MAX_MAP_DIMENSION);
        limits.max_image_height = Some(MAX_MAP_DIMENSION);
        reader.limits(limits);
        Ok(reader)
    };
    let corrupt = |e: ::image::ImageError| match e {
        ::image::ImageError::Limits(_) => Error::invalid(
            path,
            format!(
                "image is larger than {MAX_MAP_DIMENSION} texels in a dimension (downsample the \
                 map, or check that the file is not corrupt)"
            ),
        ),
        e => Error::invalid(
            path,
            format!(
                "cannot decode as {format:?}: {e} (the file is truncated or corrupt; re-export it)"
            ),
        ),
    };
    let decoder = open()?.into_decoder().map_err(corrupt)?;
    let (w, h) = ::image::ImageDecoder::dimensions(&decoder);
    let bytes_per_texel = ::image::ImageDecoder::color_type(&decoder).bytes_per_pixel() as u64;
    drop(decoder);
    check_dimensions(path, w as usize, h as usize)?;
    if format == ::image::ImageFormat::Png {
        check_png_size(path, w, h, bytes_per_texel)?;
    }
    let image = open()?.decode().map_err(corrupt)?;
    let (w, h) = check_dimensions(path, image.width() as usize, image.height() as usize)?;

    let grey = matches!(
        image,
        DynamicImage::ImageLuma8(_)
            | DynamicImage::ImageLumaA8(_)
            | DynamicImage::ImageLuma16(_)
            | DynamicImage::ImageLumaA16(_)
    );
    let name = if grey { "L" } else { "R" };
    first_channel_only(path, requested, name)?;
    // First channel of every texel; integer formats normalised by their full range.
    let data: Vec<f32> = match &image {
        DynamicImage::ImageLuma8(b) => b.pixels().map(|p| p.0[0] as f32 / 255.0).collect(),
        DynamicImage::ImageLumaA8(b) => b.pixels().map(|p| p.0[0] as f32 / 255.0).collect(),
        DynamicImage::ImageRgb8(b) => b.pixels().map(|p| p.0[0] as f32 / 255.0).collect(),
        DynamicImage::ImageRgba8(b) => b.pixels().map(|p| p.0[0] as f32 / 255.0).collect(),
        DynamicImage::ImageLuma16(b) => b.pixels().map(|p| p.0[0] as f32 / 65535.0).collect(),
        DynamicImage::ImageLumaA16(b) => b.pixels().map(|p| p.0[0] as f32 / 65535.0).collect(),
        DynamicImage::ImageRgb16(b) => b.pixels().map(|p| p.0[0] as f32 / 65535.0).collect(),
        DynamicImage::ImageRgba16(b) => b.pixels().map(|p| p.0[0] as f32 / 65535.0).collect(),
        DynamicImage::ImageRgb32F(b) => b.pixels().map(|p| p.0[0]).collect(),
        DynamicImage::ImageRgba32F(b) => b.pixels().map(|p| p.0[0]).collect(),
        // A layout added to `image` after this was written: read through its f32 RGB view.
        other => other.to_rgb32f().pixels().map(|p| p.0[0]).collect(),
    };
    Ok((w, h, data, name.to_string()))
}
