//! The environment light: an equirectangular radiance map (from an EXR, or a neutral built-in
//! sky), rotated about the asset's up axis and importance sampled by a 2D piecewise-constant
//! distribution over its texels (pbrt's `PiecewiseConstant2D`: a marginal CDF over rows,
//! one conditional CDF per row, weights = luminance × sin θ).
//!
//! Lighting reads texels nearest-neighbour so that radiance and `env_pdf` are constant over
//! the same texel; the camera's view of the background reads them bilinearly (`env_radiance_smooth`).
//! The env frame is Y-up: `u` = 0.5 + atan2(z, x)/2π, `v` = θ/π with v = 0 at the zenith
//! (row 0 of the image); Z-up assets map world (x, y, z) → env (x, z, −y). That is Blender's
//! orientation (Cycles' `direction_to_equirectangular` on the same asset imported there, glTF's
//! +Y becoming Blender's +Z): the image's centre column faces +X, its quarter column −Z
//! (glTF's forward, Blender's +Y), its three-quarter column +Z. An HDRI lights an asset here as
//! it does in Blender (`examples/scripts/compare_cycles_beauty.py` measures it). The OpenEXR
//! latitude-longitude convention, which USD's `DomeLight` follows, puts +Z at the centre: it is
//! this one turned by `--env-rotate -90`.

use super::shading::{luminance, PI};
use crate::error::{Error, Result};
use glam::{Vec2, Vec3};
use std::path::Path;

/// Largest environment accepted (texels per side), so a corrupt header cannot ask for gigabytes.
pub const MAX_ENV_SIDE: u32 = 16384;

/// Size of the built-in sky.
const DEFAULT_ENV_SIZE: (u32, u32) = (256, 128);

#[derive(Clone, Debug)]
pub struct EnvMap {
    pub width: u32,
    pub height: u32,
    /// Radiance × intensity, rows top (zenith) to bottom.
    pub texels: Vec<Vec3>,
    /// `height + 1` entries, 0 … 1.
    pub marginal_cdf: Vec<f32>,
    /// `height` rows of `width + 1` entries, 0 … 1 (uniform for a black row).
    pub conditional_cdf: Vec<f32>,
    /// Per row, its share of the total weight (the marginal pdf × height).
    pub row_weight: Vec<f32>,
    /// Per texel, its weight divided by its row's sum (the conditional pdf ÷ width).
    pub texel_weight: Vec<f32>,
    /// Sum of all weights; 0 = a black map (nothing to sample).
    pub total_weight: f32,
    pub frame: EnvFrame,
}

/// How world directions map into the env's Y-up frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvFrame {
    pub z_up: bool,
    /// Rotation about the up axis, radians (positive turns the map counter-clockwise seen from above).
    pub rotation: f32,
}

impl EnvFrame {
    /// The same frame turned by `angle` radians about the world's up axis (+Y, or +Z for a
    /// Z-up frame), counter-clockwise seen from above: the radiance that arrived from `d`
    /// arrives from the turned `d`. (In the Y-up frame a turn about the up axis is a change of
    /// `rotation`; the Z-up swap is a proper rotation taking +Y to +Z, so the same holds there.)
    pub fn turned(self, angle: f32) -> Self {
        EnvFrame {
            rotation: self.rotation + angle,
            ..self
        }
    }

    /// The frame of a USD dome light's map turned `turn_deg` about the up axis (`SceneDome`):
    /// OpenEXR's latitude-longitude orientation, which is this frame's turned by −90°, turned
    /// again as the dome's prim turns it. Its map's centre faces +Z turned by `turn_deg` (a
    /// Z-up stage's dome, pole lifted onto +Z: −Y turned).
    pub fn dome(self, turn_deg: f32) -> Self {
        self.turned((turn_deg - 90.0).to_radians())
    }
}

/// A direction drawn from the map and its solid-angle density.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvSample {
    pub dir: Vec3,
    pub pdf: f32,
}

#[inline]
pub fn world_to_env(d: Vec3, f: EnvFrame) -> Vec3 {
    let d = if f.z_up { Vec3::new(d.x, d.z, -d.y) } else { d };
    let (s, c) = (-f.rotation).sin_cos();
    Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
}

#[inline]
pub fn env_to_world(d: Vec3, f: EnvFrame) -> Vec3 {
    let (s, c) = f.rotation.sin_cos();
    let d = Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z);
    if f.z_up {
        Vec3::new(d.x, -d.z, d.y)
    } else {
        d
    }
}

/// Env-frame direction → equirect (u, v) in [0, 1]².
#[inline]
pub fn env_dir_to_uv(d: Vec3) -> Vec2 {
    let u = 0.5 + d.z.atan2(d.x) * (0.5 * std::f32::consts::FRAC_1_PI);
    let v = d.y.clamp(-1.0, 1.0).acos() * std::f32::consts::FRAC_1_PI;
    Vec2::new(u, v)
}

#[inline]
pub fn env_uv_to_dir(uv: Vec2) -> Vec3 {
    let phi = (uv.x - 0.5) * 2.0 * PI;
    let theta = uv.y * PI;
    Vec3::new(
        theta.sin() * phi.cos(),
        theta.cos(),
        theta.sin() * phi.sin(),
    )
}

#[inline]
fn texel_index(env: &EnvMap, uv: Vec2) -> (usize, usize) {
    let x = ((uv.x * env.width as f32) as i64).rem_euclid(env.width as i64) as usize;
    let y = ((uv.y * env.height as f32) as i64).clamp(0, env.height as i64 - 1) as usize;
    (x, y)
}

/// Radiance arriving from world direction `d` (nearest texel; what lighting uses).
#[inline]
pub fn env_radiance(env: &EnvMap, frame: EnvFrame, d: Vec3) -> Vec3 {
    let (x, y) = texel_index(env, env_dir_to_uv(world_to_env(d, frame)));
    env.texels[y * env.width as usize + x]
}

/// Radiance seen directly by the camera (bilinear; a smooth background).
pub fn env_radiance_smooth(env: &EnvMap, frame: EnvFrame, d: Vec3) -> Vec3 {
    let uv = env_dir_to_uv(world_to_env(d, frame));
    let p = uv * Vec2::new(env.width as f32, env.height as f32) - 0.5;
    let (x0, y0) = (p.x.floor(), p.y.floor());
    let (fx, fy) = (p.x - x0, p.y - y0);
    let w = env.width as i64;
    let at = |x: i64, y: i64| {
        let (x, y) = (x.rem_euclid(w), y.clamp(0, env.height as i64 - 1));
        env.texels[(y * w + x) as usize]
    };
    let (x0, y0) = (x0 as i64, y0 as i64);
    let top = at(x0, y0).lerp(at(x0 + 1, y0), fx);
    let bottom = at(x0, y0 + 1).lerp(at(x0 + 1, y0 + 1), fx);
    top.lerp(bottom, fy)
}

/// Index of the CDF interval containing `u`: the last `i` with `cdf[i] <= u`.
#[inline]
fn find_interval(cdf: &[f32], u: f32) -> usize {
    let (mut lo, mut hi) = (0usize, cdf.len() - 1);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if cdf[mid] <= u {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Draw a direction with density proportional to luminance (× sin θ, the equirect Jacobian).
#[inline]
pub fn env_sample(env: &EnvMap, frame: EnvFrame, u: Vec2) -> EnvSample {
    let (w, h) = (env.width as usize, env.height as usize);
    let y = find_interval(&env.marginal_cdf, u.y).min(h - 1);
    let (c0, c1) = (env.marginal_cdf[y], env.marginal_cdf[y + 1]);
    let fy = if c1 > c0 {
        ((u.y - c0) / (c1 - c0)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    let row = &env.conditional_cdf[y * (w + 1)..(y + 1) * (w + 1)];
    let x = find_interval(row, u.x).min(w - 1);
    let (r0, r1) = (row[x], row[x + 1]);
    let fx = if r1 > r0 {
        ((u.x - r0) / (r1 - r0)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    let uv = Vec2::new((x as f32 + fx) / w as f32, (y as f32 + fy) / h as f32);
    let dir = env_to_world(env_uv_to_dir(uv), frame);
    // The density of the texel `dir` maps back to, as `env_pdf` and `env_radiance` see it: on a
    // texel edge float rounding may pick the neighbour, and radiance / pdf must come from the
    // same texel there.
    EnvSample {
        dir,
        pdf: env_pdf(env, frame, dir),
    }
}

#[inline]
fn pdf_of_texel(env: &EnvMap, x: usize, y: usize, v: f32) -> f32 {
    let sin_theta = (v * PI).sin();
    if sin_theta <= 0.0 || env.total_weight <= 0.0 {
        return 0.0;
    }
    // p(u, v) = (row share × height) × (texel share × width); dω = 2π² sin θ du dv.
    let p_uv = env.row_weight[y]
        * env.height as f32
        * env.texel_weight[y * env.width as usize + x]
        * env.width as f32;
    p_uv / (2.0 * PI * PI * sin_theta)
}

/// Solid-angle density of `env_sample` producing world direction `d`.
#[inline]
pub fn env_pdf(env: &EnvMap, frame: EnvFrame, d: Vec3) -> f32 {
    let uv = env_dir_to_uv(world_to_env(d, frame));
    let (x, y) = texel_index(env, uv);
    pdf_of_texel(env, x, y, uv.y)
}

/// Radiance's older run-length scheme: at most 16 384 decoded texel bytes a file byte.
const HDR_MAX_RATIO: u64 = 16_384;

/// An environment's sides, from its header: each in `1..=MAX_ENV_SIDE`.
fn check_env_sides(path: &Path, w: usize, h: usize) -> Result<()> {
    if w == 0 || h == 0 || w > MAX_ENV_SIDE as usize || h > MAX_ENV_SIDE as usize {
        return Err(Error::invalid(
            path,
            format!("environment is {w}x{h}; each side must be 1..={MAX_ENV_SIDE}"),
        ));
    }
    Ok(())
}

impl EnvMap {
    /// Build the sampling tables for `texels` (radiance already scaled by the intensity).
    pub fn new(width: u32, height: u32, texels: Vec<Vec3>, frame: EnvFrame) -> Self {
        let (w, h) = (width as usize, height as usize);
        assert_eq!(texels.len(), w * h);
        let mut conditional_cdf = Vec::with_capacity(h * (w + 1));
        let mut texel_weight = Vec::with_capacity(w * h);
        let mut row_sums = Vec::with_capacity(h);
        for y in 0..h {
            // The row's solid angle (∫ sin θ dθ over its band), not sin θ at its centre: the
            // polar rows would otherwise be weighted wrongly by a large factor on small maps.
            let band = (y as f32 / h as f32 * PI).cos() - ((y + 1) as f32 / h as f32 * PI).cos();
            let row = &texels[y * w..(y + 1) * w];
            let weights: Vec<f32> = row.iter().map(|c| luminance(*c).max(0.0) * band).collect();
            let sum: f32 = weights.iter().sum();
            row_sums.push(sum);
            let mut acc = 0.0f32;
            conditional_cdf.push(0.0);
            for (x, wt) in weights.iter().enumerate() {
                // A black row is sampled uniformly (it is never chosen by the marginal anyway).
                let share = if sum > 0.0 { wt / sum } else { 1.0 / w as f32 };
                texel_weight.push(share);
                acc += share;
                conditional_cdf.push(if x + 1 == w { 1.0 } else { acc });
            }
        }
        let total: f32 = row_sums.iter().sum();
        let row_weight: Vec<f32> = row_sums
            .iter()
            .map(|s| {
                if total > 0.0 {
                    s / total
                } else {
                    1.0 / h as f32
                }
            })
            .collect();
        let mut marginal_cdf = Vec::with_capacity(h + 1);
        marginal_cdf.push(0.0);
        let mut acc = 0.0f32;
        for (y, r) in row_weight.iter().enumerate() {
            acc += r;
            marginal_cdf.push(if y + 1 == h { 1.0 } else { acc });
        }
        EnvMap {
            width,
            height,
            texels,
            marginal_cdf,
            conditional_cdf,
            row_weight,
            texel_weight,
            total_weight: total,
            frame,
        }
    }

    /// The built-in neutral studio sky: a soft grey gradient (cooler and darker towards the
    /// zenith), a bright horizon band and a darker warm-grey ground below it.
    pub fn default_sky(intensity: f32, frame: EnvFrame) -> Self {
        let (w, h) = DEFAULT_ENV_SIZE;
        let zenith = Vec3::new(0.55, 0.6, 0.68);
        let horizon = Vec3::new(0.9, 0.9, 0.88);
        let ground = Vec3::new(0.22, 0.21, 0.2);
        let texels = (0..w * h)
            .map(|i| {
                let v = ((i / w) as f32 + 0.5) / h as f32;
                let elevation = (0.5 - v) * PI; // +π/2 at the zenith
                let c = if elevation >= 0.0 {
                    horizon.lerp(zenith, (elevation / (0.5 * PI)).powf(0.6))
                } else {
                    horizon.lerp(ground, (-elevation / 0.15).min(1.0))
                };
                c * intensity
            })
            .collect();
        EnvMap::new(w, h, texels, frame)
    }

    /// The map with every texel times `tint` (a USD dome light's colour and intensity), its
    /// sampling tables rebuilt.
    pub fn tinted(self, tint: Vec3) -> Self {
        if tint == Vec3::ONE {
            return self;
        }
        let texels = self.texels.iter().map(|&t| t * tint).collect();
        EnvMap::new(self.width, self.height, texels, self.frame)
    }

    /// A constant-radiance environment (furnace tests, a dome light without a texture).
    pub fn constant(radiance: Vec3, frame: EnvFrame) -> Self {
        EnvMap::new(8, 4, vec![radiance; 32], frame)
    }

    /// Read an equirect HDRI, OpenEXR (`load_exr`) or Radiance RGBE (`load_hdr`) by its
    /// extension, scaled by `intensity`.
    pub fn load(path: &Path, intensity: f32, frame: EnvFrame) -> Result<Self> {
        match super::super::load::extension(path).as_str() {
            "exr" => Self::load_exr(path, intensity, frame),
            "hdr" => Self::load_hdr(path, intensity, frame),
            _ => Err(Error::invalid(
                path,
                "--env needs an equirectangular HDR map: .exr (OpenEXR) or .hdr (Radiance RGBE)",
            )),
        }
    }

    /// Read an equirect Radiance RGBE `.hdr` (the format most HDRI libraries offer beside
    /// EXR), scaled by `intensity`. Its size is checked from the header before any texel is
    /// decoded, as `load_exr` checks an EXR's.
    pub fn load_hdr(path: &Path, intensity: f32, frame: EnvFrame) -> Result<Self> {
        use image::ImageDecoder;
        let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let bytes = file.metadata().map_err(|e| Error::io(path, e))?.len();
        let corrupt = |e: image::ImageError| {
            Error::invalid(
                path,
                format!("cannot read as Radiance HDR: {e} (the file is truncated or corrupt; re-export it)"),
            )
        };
        let decoder =
            image::codecs::hdr::HdrDecoder::new(std::io::BufReader::new(file)).map_err(corrupt)?;
        let (w, h) = decoder.dimensions();
        check_env_sides(path, w as usize, h as usize)?;
        // Radiance's older run-length scheme fills a scanline from a pixel and two run
        // counts: 12 bytes give at most 16 384 texels of 12 decoded bytes.
        let decoded = w as u64 * h as u64 * 12;
        if crate::load::image::states_more_than_it_holds(decoded, bytes, HDR_MAX_RATIO) {
            return Err(Error::invalid(
                path,
                format!("the header says {w}x{h} texels, more than a {bytes}-byte Radiance file can hold: the file is truncated or corrupt (re-export it)"),
            ));
        }
        // The decoder writes RGB f32 texels as native-endian bytes.
        let mut raw = vec![0u8; decoder.total_bytes() as usize];
        decoder.read_image(&mut raw).map_err(corrupt)?;
        let float = |b: &[u8]| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]);
        let texels = raw
            .chunks_exact(12)
            .map(|t| Vec3::new(float(&t[0..4]), float(&t[4..8]), float(&t[8..12])));
        Self::from_radiance(path, w, h, texels, intensity, frame)
    }

    /// Read an equirect EXR (R, G, B; or a single channel as grey), scaled by `intensity`.
    pub fn load_exr(path: &Path, intensity: f32, frame: EnvFrame) -> Result<Self> {
        // The header first: sizes a hostile file states are refused before pixel storage.
        let header = crate::load::image::exr_flat_header(path)?;
        let (w, h) = (header.layer_size.width(), header.layer_size.height());
        check_env_sides(path, w, h)?;
        crate::load::image::check_exr_size(path, &header)?;
        let picked = crate::load::image::exr_rgb_channels(path, &header, "the environment")?;
        let (w, h, planes) =
            crate::load::image::read_exr_channels(path, &picked, "the environment")?;
        check_env_sides(path, w, h)?;
        let (w, h) = (w as u32, h as u32);
        let n = (w * h) as usize;
        let channel = |k: usize| &planes[k.min(planes.len() - 1)];
        let (r, g, b) = (channel(0), channel(1), channel(2));
        let texels = (0..n).map(|i| Vec3::new(r[i], g[i], b[i]));
        Self::from_radiance(path, w, h, texels, intensity, frame)
    }

    /// The environment of `texels` (row 0 at the top) read from `path`, times `intensity`:
    /// NaN or infinite texels are an error, negative ones count as 0, and the product and the
    /// sampling weights' sum must stay in f32's range.
    fn from_radiance(
        path: &Path,
        w: u32,
        h: u32,
        texels: impl Iterator<Item = Vec3>,
        intensity: f32,
        frame: EnvFrame,
    ) -> Result<Self> {
        let mut scaled = Vec::with_capacity((w * h) as usize);
        for (i, c) in texels.enumerate() {
            let (x, y) = (i as u32 % w, i as u32 / w);
            if !c.is_finite() {
                return Err(Error::invalid(
                    path,
                    format!("texel ({x}, {y}) is NaN or infinite; clamp the HDR before using it"),
                ));
            }
            let c = c.max(Vec3::ZERO) * intensity;
            if !c.is_finite() {
                return Err(Error::invalid(
                    path,
                    format!("texel ({x}, {y}) times the intensity {intensity} is past f32's range; lower --env-intensity"),
                ));
            }
            scaled.push(c);
        }
        let env = EnvMap::new(w, h, scaled, frame);
        // Sampling weighs each texel by its luminance and solid angle: their sum must be a
        // number, or every pdf is NaN and the beauty with it.
        if !env.total_weight.is_finite() {
            return Err(Error::invalid(
                path,
                format!(
                    "its radiance (times the intensity {intensity}) sums past f32's range; scale it down (--env-intensity) or clamp its brightest texels"
                ),
            ));
        }
        Ok(env)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{random, Purpose};

    /// A Radiance `.hdr` loads as the radiance it was written from, up to RGBE's 8-bit
    /// mantissas under a shared exponent; `load` picks the reader by extension and names both
    /// formats for any other; a header stating far more texels than the file holds, or more
    /// than the side limit, is refused before decoding.
    #[test]
    fn radiance_hdr_environments_load_like_exr_ones() {
        use image::codecs::hdr::HdrEncoder;
        let dir = std::env::temp_dir().join(format!("prismbake-env-hdr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let frame = frames()[0];
        let (w, h) = (16usize, 8usize);
        let texel = |i: usize| {
            let (x, y) = (i % w, i / w);
            [
                0.02 + x as f32 * 0.3,
                0.5 + y as f32 * 7.0,
                if (x, y) == (3, 2) { 5000.0 } else { 0.25 },
            ]
        };
        let rgb: Vec<image::Rgb<f32>> = (0..w * h).map(|i| image::Rgb(texel(i))).collect();
        let hdr = dir.join("sky.hdr");
        let mut bytes = Vec::new();
        HdrEncoder::new(&mut bytes).encode(&rgb, w, h).unwrap();
        std::fs::write(&hdr, &bytes).unwrap();
        let env = EnvMap::load(&hdr, 2.0, frame).unwrap();
        assert_eq!((env.width, env.height), (w as u32, h as u32));
        for (i, t) in env.texels.iter().enumerate() {
            let want = Vec3::from_array(texel(i)) * 2.0;
            // RGBE shares one exponent: each channel is within 1/128 of the largest.
            assert!(
                (*t - want).abs().max_element() <= want.max_element() / 128.0,
                "texel {i}: {t} against {want}"
            );
        }
        // The bright texel (row 2 from the top, column 3) takes most of its row's samples.
        let share = env.texel_weight[2 * w + 3];
        assert!(share > 0.5, "{share}");

        let e = EnvMap::load(&dir.join("sky.png"), 1.0, frame)
            .unwrap_err()
            .to_string();
        assert!(e.contains(".exr (OpenEXR) or .hdr (Radiance RGBE)"), "{e}");
        // The same header stating 16 000 × 8 000 texels over the same 16 × 8 texels' bytes.
        let text = String::from_utf8_lossy(&bytes).into_owned();
        let at = text.find("-Y 8 +X 16").expect("the dimension line");
        let mut huge = bytes[..at].to_vec();
        huge.extend_from_slice(b"-Y 8000 +X 16000");
        huge.extend_from_slice(&bytes[at + "-Y 8 +X 16".len()..]);
        for (name, data, says) in [
            ("huge.hdr", huge, "more than a"),
            ("wide.hdr", bytes.clone(), ""),
            (
                "cut.hdr",
                bytes[..bytes.len() / 2].to_vec(),
                "truncated or corrupt",
            ),
        ] {
            let data = if name == "wide.hdr" {
                let mut d = bytes[..at].to_vec();
                d.extend_from_slice(b"-Y 8 +X 20000");
                d.extend_from_slice(&bytes[at + "-Y 8 +X 16".len()..]);
                d
            } else {
                data
            };
            let path = dir.join(name);
            std::fs::write(&path, data).unwrap();
            let e = EnvMap::load(&path, 1.0, frame).unwrap_err().to_string();
            let says = if says.is_empty() {
                "each side must be 1..=16384"
            } else {
                says
            };
            assert!(e.contains(name) && e.contains(says), "{e}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// An environment EXR whose header states more than its file holds is refused before any
    /// pixel storage (by hand: a 480 KB file stating 60 000² texels aborted the render asking
    /// for 14.4 GB); one over the side limit too; a whole one of the same writer loads.
    #[test]
    fn an_environment_header_larger_than_its_data_is_an_error() {
        use crate::test_util::exr_header_only;
        let dir = std::env::temp_dir().join(format!("prismbake-env-huge-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let frame = frames()[0];
        let whole = dir.join("whole.exr");
        std::fs::write(&whole, exr_header_only(8, 1, &["R", "G", "B"], 0)).unwrap();
        let env = EnvMap::load_exr(&whole, 2.0, frame).unwrap();
        assert_eq!(
            (env.width, env.height, env.texels[7]),
            (8, 1, Vec3::splat(2.0))
        );
        for (name, w, h, compression, says) in [
            (
                "none.exr",
                16_000,
                8_000,
                0u8,
                "16000x8000 texels in 3 channels",
            ),
            ("zip.exr", 16_000, 8_000, 3, "truncated or corrupt"),
            ("wide.exr", 60_000, 60_000, 0, "each side must be 1..=16384"),
        ] {
            let path = dir.join(name);
            std::fs::write(&path, exr_header_only(w, h, &["R", "G", "B"], compression)).unwrap();
            let e = EnvMap::load_exr(&path, 1.0, frame).unwrap_err().to_string();
            assert!(e.contains(name) && e.contains(says), "{e}");
        }
        // Every texel finite, but their weights sum past f32's range: no NaN pdfs.
        let bright = dir.join("bright.exr");
        std::fs::write(&bright, exr_header_only(8, 1, &["R", "G", "B"], 0)).unwrap();
        let e = EnvMap::load_exr(&bright, 1e38, frame)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("bright.exr") && e.contains("sums past f32's range"),
            "{e}"
        );
        let e = EnvMap::load_exr(&bright, f32::MAX * 2.0, frame)
            .unwrap_err()
            .to_string();
        assert!(e.contains("texel (0, 0) times the intensity"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A lopsided map: one bright spot near the horizon, a dim gradient elsewhere.
    fn spot_map(frame: EnvFrame) -> EnvMap {
        let (w, h) = (32u32, 16u32);
        let texels = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if (x, y) == (20, 7) {
                    Vec3::new(200.0, 150.0, 100.0)
                } else {
                    Vec3::splat(0.1 + 0.05 * x as f32 / w as f32)
                }
            })
            .collect();
        EnvMap::new(w, h, texels, frame)
    }

    fn frames() -> [EnvFrame; 2] {
        [
            EnvFrame {
                z_up: false,
                rotation: 0.0,
            },
            EnvFrame {
                z_up: true,
                rotation: 1.1,
            },
        ]
    }

    #[test]
    fn direction_and_uv_round_trip() {
        for f in frames() {
            for i in 0..100 {
                let uv = Vec2::new(
                    random(i, 0, 0, Purpose::Bench, 1),
                    0.02 + 0.96 * random(i, 0, 1, Purpose::Bench, 1),
                );
                let d = env_to_world(env_uv_to_dir(uv), f);
                let back = env_dir_to_uv(world_to_env(d, f));
                assert!((back - uv).abs().max_element() < 1e-4, "{uv:?} -> {back:?}");
            }
        }
        // Zenith is the asset's up axis.
        assert!((env_to_world(Vec3::Y, frames()[1]) - Vec3::Z).length() < 1e-6);
    }

    /// The orientation is Blender's: in a glTF's Y-up frame (Blender's X, Z, −Y) the image's
    /// centre column faces +X, its quarter column −Z, its three-quarter column +Z, its top row
    /// the zenith; a Z-up asset's frame is Blender's own, the same directions. Turned by −90°,
    /// it is OpenEXR's latitude-longitude map (USD's `DomeLight`): +Z at the centre, +X at the
    /// quarter. `examples/scripts/compare_cycles_beauty.py` checks the first against Cycles.
    #[test]
    fn the_map_is_oriented_as_in_blender() {
        let u_of = |d: Vec3, f: EnvFrame| env_dir_to_uv(world_to_env(d, f));
        let y_up = EnvFrame {
            z_up: false,
            rotation: 0.0,
        };
        let z_up = EnvFrame {
            z_up: true,
            rotation: 0.0,
        };
        for (d_gltf, d_blender, u) in [
            (Vec3::X, Vec3::X, 0.5),
            (Vec3::NEG_Z, Vec3::Y, 0.25),
            (Vec3::Z, Vec3::NEG_Y, 0.75),
        ] {
            for (got, f) in [
                (u_of(d_gltf, y_up), "glTF"),
                (u_of(d_blender, z_up), "Blender"),
            ] {
                assert!(
                    (got - Vec2::new(u, 0.5)).length() < 1e-6,
                    "{f} {d_gltf}: {got}"
                );
            }
        }
        assert!(
            u_of(Vec3::Y, y_up).y < 1e-6 && u_of(Vec3::Z, z_up).y < 1e-6,
            "the zenith"
        );
        let exr = EnvFrame {
            z_up: false,
            rotation: (-90f32).to_radians(),
        };
        for (d, u) in [(Vec3::Z, 0.5), (Vec3::X, 0.25), (Vec3::NEG_X, 0.75)] {
            let got = u_of(d, exr).x.rem_euclid(1.0);
            assert!((got - u).abs() < 1e-6, "OpenEXR {d}: {got}");
        }
    }

    /// A dome light's map (one bright texel at its centre) faces the direction the dome's
    /// turn takes OpenEXR's centre to: +Z turned about +Y in a Y-up stage, −Y (the centre once
    /// the pole is lifted onto +Z) turned about +Z in a Z-up one; a quarter turn further is
    /// dark. The turn is counter-clockwise seen from above, as USD's rotations are.
    #[test]
    fn a_dome_lights_map_faces_where_its_turn_takes_openexrs_centre() {
        let (w, h) = (64u32, 32u32);
        let mut texels = vec![Vec3::splat(0.01); (w * h) as usize];
        for y in h / 2 - 1..h / 2 + 1 {
            for x in w / 2 - 1..w / 2 + 1 {
                texels[(y * w + x) as usize] = Vec3::splat(100.0);
            }
        }
        for (z_up, centre, up) in [(false, Vec3::Z, Vec3::Y), (true, Vec3::NEG_Y, Vec3::Z)] {
            let base = EnvFrame {
                z_up,
                rotation: 0.0,
            };
            for turn in [0.0f32, 30.0, -135.0] {
                let frame = base.dome(turn);
                let env = EnvMap::new(w, h, texels.clone(), frame);
                let at = |deg: f32| {
                    let d = glam::Quat::from_axis_angle(up, deg.to_radians()) * centre;
                    env_radiance(&env, frame, d).x
                };
                assert!(at(turn) > 50.0, "z_up {z_up}, turn {turn}: {}", at(turn));
                assert!(
                    at(turn + 90.0) < 1.0 && at(turn - 90.0) < 1.0,
                    "z_up {z_up}, turn {turn}"
                );
            }
        }
    }

    /// A frame turned by `a` about the up axis maps the turned direction where the frame
    /// mapped the direction (Y-up and Z-up, counter-clockwise seen from above): a turntable's
    /// lights turn with its camera. A turn of the wrong sign or about the wrong axis fails.
    #[test]
    fn a_turned_frame_maps_turned_directions_where_the_frame_mapped_them() {
        for f in frames() {
            let up = if f.z_up { Vec3::Z } else { Vec3::Y };
            for a in [0.4f32, -2.0, 3.0] {
                let rot = glam::Quat::from_axis_angle(up, a);
                let g = f.turned(a);
                for i in 0..50 {
                    let d = Vec3::new(
                        random(i, 0, 0, Purpose::Bench, 3) - 0.5,
                        random(i, 0, 1, Purpose::Bench, 3) - 0.5,
                        random(i, 0, 2, Purpose::Bench, 3) - 0.5,
                    )
                    .normalize();
                    let (x, y) = (world_to_env(rot * d, g), world_to_env(d, f));
                    assert!((x - y).length() < 1e-5, "{f:?} turned {a}: {x} against {y}");
                    let (x, y) = (env_to_world(d, g), rot * env_to_world(d, f));
                    assert!((x - y).length() < 1e-5, "{f:?} turned {a}: {x} against {y}");
                }
            }
        }
    }

    /// ∫ env_pdf dω = 1 (Riemann sum over the sphere), and the histogram of `env_sample`
    /// over texels matches pdf × texel solid angle. A wrong Jacobian (sin θ) or a CDF off by
    /// one shows up as a mismatch here before it shows up as noise or bias in renders.
    #[test]
    fn pdf_integrates_to_one_and_matches_the_histogram() {
        for f in frames() {
            let env = spot_map(f);
            let (nt, np) = (600, 1200);
            let mut integral = 0.0f64;
            for i in 0..nt {
                for j in 0..np {
                    let c = 1.0 - 2.0 * (i as f32 + 0.5) / nt as f32;
                    let phi = 2.0 * PI * (j as f32 + 0.5) / np as f32;
                    let s = (1.0 - c * c).sqrt();
                    let d = Vec3::new(s * phi.cos(), s * phi.sin(), c);
                    integral +=
                        env_pdf(&env, env.frame, d) as f64 * (4.0 * PI as f64) / (nt * np) as f64;
                }
            }
            assert!((integral - 1.0).abs() < 0.01, "∫ pdf = {integral}");

            let n = 400_000u32;
            let (w, h) = (env.width as usize, env.height as usize);
            let mut hist = vec![0u32; w * h];
            for i in 0..n {
                let s = env_sample(
                    &env,
                    env.frame,
                    Vec2::new(
                        random(i, 0, 0, Purpose::Light, 5),
                        random(i, 0, 1, Purpose::Light, 5),
                    ),
                );
                assert!(
                    (s.pdf - env_pdf(&env, env.frame, s.dir)).abs() <= 1e-3 * s.pdf.max(1.0),
                    "sample pdf disagrees with env_pdf"
                );
                let (x, y) = texel_index(&env, env_dir_to_uv(world_to_env(s.dir, f)));
                hist[y * w + x] += 1;
            }
            for y in 0..h {
                for x in 0..w {
                    let expected = env.row_weight[y] as f64 * env.texel_weight[y * w + x] as f64;
                    let got = hist[y * w + x] as f64 / n as f64;
                    let sigma = (expected / n as f64).sqrt();
                    assert!(
                        (got - expected).abs() < 5.0 * sigma + 1e-5,
                        "texel ({x}, {y}): {got} vs {expected}"
                    );
                }
            }
            // The spot dominates sampling.
            assert!(hist[7 * w + 20] as f64 / n as f64 > 0.5);
        }
    }

    /// E[1 / pdf] is the measure of the sphere for any density with full support: a constant
    /// map must cover every direction (4π), as the furnace test of the renderer assumes.
    #[test]
    fn constant_env_covers_the_sphere() {
        let env = EnvMap::constant(Vec3::ONE, frames()[0]);
        let n = 100_000;
        let mean: f64 = (0..n)
            .map(|i| {
                env_sample(
                    &env,
                    env.frame,
                    Vec2::new(
                        random(i, 0, 0, Purpose::Light, 2),
                        random(i, 0, 1, Purpose::Light, 2),
                    ),
                )
            })
            // Directions within ~1e-4 rad of a pole round to it (pdf 0, skipped by the renderer).
            .map(|s| if s.pdf > 0.0 { 1.0 / s.pdf as f64 } else { 0.0 })
            .sum::<f64>()
            / n as f64;
        assert!(
            (mean / (4.0 * PI as f64) - 1.0).abs() < 0.01,
            "E[1/pdf] = {mean}"
        );
    }
}
