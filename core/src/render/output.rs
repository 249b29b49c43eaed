//! Writing AOV frames: linear EXR (for compositing and comparison) and a PNG preview of each
//! (normals mapped to colour, depth normalised, steps as a heat map). Every file is written
//! to a temporary name in the same folder and renamed, so a crash never leaves half a file.

use super::{Aov, AovImage};
use crate::error::{Error, Result};
use crate::prism_file::write_atomic;
use exr::prelude::*;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

fn tmp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp{}", std::process::id()))
}

/// Write float channels as a single-layer EXR (ZIP compressed) atomically.
pub fn write_exr(path: &Path, width: u32, height: u32, names: &[&str], data: &[f32]) -> Result<()> {
    let n = (width * height) as usize;
    let k = names.len();
    assert_eq!(data.len(), n * k);
    let channels: Vec<AnyChannel<FlatSamples>> = names
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let plane: Vec<f32> = (0..n).map(|i| data[i * k + c]).collect();
            AnyChannel::new(*name, FlatSamples::F32(plane))
        })
        .collect();
    let layer = Layer::new(
        (width as usize, height as usize),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    let tmp = tmp_path(path);
    let result = Image::from_layer(layer).write().to_file(&tmp);
    match result {
        Ok(()) => std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e)),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(Error::invalid(path, format!("could not write EXR: {e}")))
        }
    }
}

/// Write 8-bit RGB pixels as PNG atomically.
pub fn write_png_rgb(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new(&mut bytes)
        .write_image(rgb, width, height, image::ExtendedColorType::Rgb8)
        .map_err(|e| Error::invalid(path, format!("could not encode PNG: {e}")))?;
    write_atomic(path, &bytes)
}

use image::ImageEncoder;

/// EXR channel names of an AOV.
pub fn exr_channels(aov: Aov) -> &'static [&'static str] {
    match aov {
        Aov::Normal => &["R", "G", "B"],
        Aov::Uv => &["R", "G"],
        Aov::Beauty => &["R", "G", "B", "A"],
        _ => &["Y"],
    }
}

/// A perceptual heat map (black → blue → magenta → orange → yellow-white) for `t` in [0, 1].
pub fn heat(t: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [0.1, 0.1, 0.6],
        [0.7, 0.1, 0.6],
        [1.0, 0.55, 0.1],
        [1.0, 1.0, 0.75],
    ];
    let x = t.clamp(0.0, 1.0) * 4.0;
    let i = (x.floor() as usize).min(3);
    let f = x - i as f32;
    let c = |k: usize| STOPS[i][k] + (STOPS[i + 1][k] - STOPS[i][k]) * f;
    [0, 1, 2].map(|k| (c(k) * 255.0).round() as u8)
}

fn to_u8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// The preview picture of an AOV (RGB8).
pub fn preview(img: &AovImage, aov: Aov) -> Vec<u8> {
    let n = img.mask.len();
    let mut rgb = Vec::with_capacity(n * 3);
    match aov {
        Aov::Normal => {
            for (i, nrm) in img.normal.iter().enumerate() {
                let c = if img.mask[i] > 0.0 {
                    *nrm * 0.5 + 0.5
                } else {
                    glam::Vec3::ZERO
                };
                rgb.extend(c.to_array().map(to_u8));
            }
        }
        Aov::Depth => {
            let hits = || {
                img.depth
                    .iter()
                    .zip(&img.mask)
                    .filter(|(_, m)| **m > 0.0)
                    .map(|(d, _)| *d)
            };
            let lo = hits().fold(f32::INFINITY, f32::min);
            let hi = hits().fold(f32::NEG_INFINITY, f32::max);
            let span = (hi - lo).max(1e-12);
            for (d, m) in img.depth.iter().zip(&img.mask) {
                let v = if *m > 0.0 {
                    1.0 - 0.85 * (d - lo) / span
                } else {
                    0.0
                };
                rgb.extend([to_u8(v); 3]);
            }
        }
        Aov::Mask => rgb.extend(img.mask.iter().flat_map(|m| [to_u8(*m); 3])),
        Aov::Uv => {
            for (uv, m) in img.uv.iter().zip(&img.mask) {
                let c = if *m > 0.0 {
                    [uv.x.rem_euclid(1.0), uv.y.rem_euclid(1.0), 0.0]
                } else {
                    [0.0; 3]
                };
                rgb.extend(c.map(to_u8));
            }
        }
        Aov::Steps => {
            let mut sorted: Vec<f32> = img.steps.clone();
            sorted.sort_by(|a, b| a.total_cmp(b));
            let p99 = sorted
                .get((sorted.len() * 99) / 100)
                .copied()
                .unwrap_or(1.0)
                .max(1.0);
            rgb.extend(img.steps.iter().flat_map(|s| heat(s / p99)));
        }
        // Written by `beauty::beauty_preview` from a `BeautyImage`, never from AOVs.
        Aov::Beauty => rgb.resize(n * 3, 0),
        Aov::Prism => {
            for p in &img.prism {
                let c = if *p > 0.0 {
                    let h = crate::rng::pcg_hash(*p as u32);
                    [
                        (h & 0xff) as u8 / 2 + 64,
                        ((h >> 8) & 0xff) as u8 / 2 + 64,
                        ((h >> 16) & 0xff) as u8 / 2 + 64,
                    ]
                } else {
                    [0, 0, 0]
                };
                rgb.extend(c);
            }
        }
    }
    rgb
}

/// File stem of an AOV in a frame: `depth` for a still, `depth_0003` in a turntable.
pub fn stem(aov: Aov, frame: Option<u32>) -> String {
    match frame {
        Some(f) => format!("{}_{f:04}", aov.name()),
        None => aov.name().to_string(),
    }
}

/// Files written for a frame (in the order of the AOVs asked for) and each AOV's preview (the
/// PNG's RGB pixels, which a turntable's contact sheet reuses).
pub struct WrittenFrame {
    pub files: Vec<PathBuf>,
    pub previews: Vec<(Aov, Vec<u8>)>,
}

/// Write `DIR/<stem>.exr` and `DIR/<stem>.png` for every requested AOV; returns the paths and
/// the previews. `Beauty` is skipped: `write_beauty` writes it.
pub fn write_frame(
    dir: &Path,
    img: &AovImage,
    aovs: &[Aov],
    frame: Option<u32>,
) -> Result<WrittenFrame> {
    // Each AOV's two files are independent: encoded side by side (ZIP and deflate are most of
    // a frame's writing time), listed in the order of `aovs`.
    let written: Vec<_> = aovs
        .par_iter()
        .filter(|a| **a != Aov::Beauty)
        .map(|&aov| {
            let stem = stem(aov, frame);
            let exr_path = dir.join(format!("{stem}.exr"));
            write_exr(
                &exr_path,
                img.width,
                img.height,
                exr_channels(aov),
                &img.channel_data(aov),
            )?;
            let png_path = dir.join(format!("{stem}.png"));
            let rgb = preview(img, aov);
            write_png_rgb(&png_path, img.width, img.height, &rgb)?;
            Ok(([exr_path, png_path], (aov, rgb)))
        })
        .collect::<Result<Vec<([PathBuf; 2], (Aov, Vec<u8>))>>>()?;
    let (files, previews): (Vec<_>, Vec<_>) = written.into_iter().unzip();
    Ok(WrittenFrame {
        files: files.into_iter().flatten().collect(),
        previews,
    })
}

/// Write `DIR/beauty[_NNNN].exr` (linear premultiplied RGBA) and `.png` (the tonemapped
/// preview over the environment); returns the paths and the preview.
pub fn write_beauty(
    dir: &Path,
    img: &super::beauty::BeautyImage,
    frame: Option<u32>,
) -> Result<WrittenFrame> {
    let stem = stem(Aov::Beauty, frame);
    let exr_path = dir.join(format!("{stem}.exr"));
    let data: Vec<f32> = img.rgba.iter().flatten().copied().collect();
    write_exr(
        &exr_path,
        img.width,
        img.height,
        exr_channels(Aov::Beauty),
        &data,
    )?;
    let png_path = dir.join(format!("{stem}.png"));
    let rgb = super::beauty::beauty_preview(img);
    write_png_rgb(&png_path, img.width, img.height, &rgb)?;
    Ok(WrittenFrame {
        files: vec![exr_path, png_path],
        previews: vec![(Aov::Beauty, rgb)],
    })
}

/// Read the first channels of an EXR back (tests, comparisons): (width, height, names, data
/// interleaved in the order of `names`).
pub fn read_exr(path: &Path) -> Result<(u32, u32, Vec<String>, Vec<f32>)> {
    let image = read_all_flat_layers_from_file(path)
        .map_err(|e| Error::invalid(path, format!("could not read EXR: {e}")))?;
    let layer = image
        .layer_data
        .first()
        .ok_or_else(|| Error::invalid(path, "EXR has no layers"))?;
    let size = layer.size;
    let names: Vec<String> = layer
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    let n = size.0 * size.1;
    let k = names.len();
    let mut data = vec![0f32; n * k];
    for (c, ch) in layer.channel_data.list.iter().enumerate() {
        for i in 0..n {
            data[i * k + c] = ch.sample_data.value_by_flat_index(i).to_f32();
        }
    }
    Ok((size.0 as u32, size.1 as u32, names, data))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::beauty::{preview_pixel, BeautyCounters, BeautyImage, Guides};
    use glam::Vec3;

    fn png_pixels(path: &Path) -> Vec<u8> {
        image::open(path).unwrap().to_rgb8().into_raw()
    }

    #[test]
    fn the_beauty_png_is_the_devices_preview_where_it_made_one_else_the_hosts() {
        let dir = std::env::temp_dir().join(format!("prismbake-preview-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // Dark, mid, bright past the curve's knee, linear-segment dark, a background only.
        let rgba = vec![
            [0.0, 0.0, 0.0, 1.0],
            [0.18, 0.18, 0.18, 1.0],
            [4.0, 2.0, 0.5, 1.0],
            [0.001, 0.0005, 0.002, 1.0],
            [0.0, 0.0, 0.0, 0.0],
            [0.3, 0.1, 0.0, 0.5],
        ];
        let background = vec![
            Vec3::ZERO,
            Vec3::ZERO,
            Vec3::ZERO,
            Vec3::ZERO,
            Vec3::ONE,
            Vec3::splat(0.2),
        ];
        let mut img = BeautyImage {
            width: 3,
            height: 2,
            guides: vec![Guides::default(); 6],
            counters: BeautyCounters::default(),
            preview: None,
            rgba,
            background,
            exposure: 1.0,
        };
        let host: Vec<u8> = img
            .rgba
            .iter()
            .zip(&img.background)
            .flat_map(|(c, b)| preview_pixel(*c, *b, 1.0))
            .collect();
        assert_eq!(
            &host[..6],
            &[0, 0, 0, 141, 141, 141],
            "the filmic curve moved"
        );
        let written = write_beauty(dir.as_path(), &img, None).unwrap();
        assert_eq!(png_pixels(&dir.as_path().join("beauty.png")), host);
        assert_eq!(written.previews, vec![(Aov::Beauty, host.clone())]);
        // A device's preview is written as it is, not tonemapped again.
        let device: Vec<[u8; 3]> = (0..6u8).map(|i| [i, 100 + i, 200 + i]).collect();
        img.preview = Some(device.clone());
        write_beauty(dir.as_path(), &img, Some(7)).unwrap();
        let flat: Vec<u8> = device.iter().flatten().copied().collect();
        assert_eq!(png_pixels(&dir.as_path().join("beauty_0007.png")), flat);
        // One stop up: the preview of 0.18 grey is that of 0.36 at no exposure; the EXR's
        // pixels are the radiance still.
        img.preview = None;
        img.exposure = 2.0;
        write_beauty(dir.as_path(), &img, Some(8)).unwrap();
        let brighter = png_pixels(&dir.as_path().join("beauty_0008.png"));
        let grey = preview_pixel([0.36, 0.36, 0.36, 1.0], Vec3::ZERO, 1.0);
        assert_eq!(&brighter[3..6], &grey[..]);
        assert!(brighter[3] > host[3]);
        let exr = |name: &str| std::fs::read(dir.as_path().join(name)).unwrap();
        assert_eq!(exr("beauty_0008.exr"), exr("beauty.exr"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
