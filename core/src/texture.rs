//! Material textures: the base-colour texture, which the beauty multiplies into its base colour
//! at each hit's UV, and the roughness and metallic textures, one channel of which multiplies
//! the material's factor (glTF's `metallicRoughnessTexture`: roughness in green, metallic in
//! blue).
//!
//! A loader records where the texture is (`TextureRef`, cheap); `ColorMap::load` decodes it
//! (PNG or JPEG) only when a beauty render needs it. Texels are stored linear (a colour
//! texture's sRGB codes decoded, a data texture's codes as they are: `ColorSpace`), row 0 at
//! the top of the image, and sampled with the height
//! map's conventions (`HeightMap::texel_coords`: texel centres at `(i + 0.5) / N`, `v` up), with
//! the glTF sampler's wrap modes per axis and its magnification filter (bilinear unless it
//! asks for nearest). There is no mip chain: a minified texture aliases per sample, and the
//! pixel's samples average it. The GPU mirror is `shaders/texture.wgsl`, function by function.

use crate::error::{Error, Result};
use glam::{Vec2, Vec3};
use std::path::{Path, PathBuf};

/// Largest texture side accepted (the height map's bound, `load::image::MAX_MAP_DIMENSION`).
pub const MAX_TEXTURE_DIMENSION: u32 = crate::load::image::MAX_MAP_DIMENSION;
/// Most texels a texture may have: 16k², 3 GiB of linear texels.
pub const MAX_TEXTURE_TEXELS: u64 = 1 << 28;
/// Texels a JPEG may declare per byte of its file (beyond the first 2^20): even a flat one
/// spends about a bit per 8 × 8 block on its DC scan (a flat 16k² image: 0.5 MB or more), while
/// a corrupt header declaring 30k² texels in 600 bytes is refused before anything is decoded.
const JPEG_TEXELS_PER_BYTE: u64 = 1024;

/// Bound on continuous texel coordinates before they become integers (the GPU's
/// `TEXEL_COORD_BOUND`).
const TEXEL_COORD_BOUND: f32 = 1.0e7;

/// How texel coordinates outside the image wrap, per axis (glTF sampler `wrapS`/`wrapT`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TexWrap {
    #[default]
    Repeat,
    Clamp,
    Mirror,
}

impl TexWrap {
    /// The code the GPU mirror reads (`shaders/texture.wgsl`).
    pub fn code(self) -> u32 {
        match self {
            TexWrap::Repeat => 0,
            TexWrap::Clamp => 1,
            TexWrap::Mirror => 2,
        }
    }

    /// Texel index `i` of an axis of `n` texels, wrapped into `0..n`.
    #[inline]
    pub fn index(self, i: i32, n: i32) -> i32 {
        match self {
            TexWrap::Repeat => i.rem_euclid(n),
            TexWrap::Clamp => i.clamp(0, n - 1),
            TexWrap::Mirror => {
                let m = i.rem_euclid(2 * n);
                if m >= n {
                    2 * n - 1 - m
                } else {
                    m
                }
            }
        }
    }
}

/// How a texture is filtered: the glTF sampler's wrap modes and magnification filter.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sampler {
    /// `wrapS` (u) and `wrapT` (v).
    pub wrap: [TexWrap; 2],
    /// Nearest texel instead of bilinear (`magFilter` NEAREST).
    pub nearest: bool,
}

/// How a texture's stored codes become linear values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ColorSpace {
    /// sRGB-encoded colour (glTF's base-colour texture, an `.mtl`'s `map_Kd`).
    #[default]
    Srgb,
    /// Data, read as stored (glTF's metallic-roughness texture, USD's `raw`).
    Raw,
    /// USD's `auto`: sRGB for an 8-bit image of 3 or 4 channels, else raw (UsdUVTexture's
    /// rule where the file carries no colour-space metadata).
    Auto,
    /// The image's alpha channel, as stored (1 where it has none, as Blender's Image Texture
    /// node gives), in all three channels: a material's alpha (glTF's base-colour texture's
    /// alpha, a USD `UsdUVTexture`'s `a` output).
    Alpha,
}

/// Which material input a texture feeds: names it in messages and the flag that overrides it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TextureSlot {
    BaseColor,
    Roughness,
    Metallic,
    /// A tangent-space normal map (`NormalMapRef`).
    Normal,
    /// Emitted radiance, multiplied into the emission colour.
    Emission,
    /// One channel multiplied into the clearcoat's weight, or its roughness.
    Clearcoat,
    ClearcoatRoughness,
    /// A tangent-space normal map of the clearcoat's own (`NormalMapRef`).
    ClearcoatNormal,
    /// The alpha that cuts the surface away (`mesh::AlphaMode`).
    Alpha,
}

impl TextureSlot {
    /// "base-colour", "roughness", "metallic", "normal", "emission", "clearcoat",
    /// "clearcoat-roughness", "clearcoat-normal", "alpha".
    pub fn name(self) -> &'static str {
        match self {
            TextureSlot::BaseColor => "base-colour",
            TextureSlot::Roughness => "roughness",
            TextureSlot::Metallic => "metallic",
            TextureSlot::Normal => "normal",
            TextureSlot::Emission => "emission",
            TextureSlot::Clearcoat => "clearcoat",
            TextureSlot::ClearcoatRoughness => "clearcoat-roughness",
            TextureSlot::ClearcoatNormal => "clearcoat-normal",
            TextureSlot::Alpha => "alpha",
        }
    }

    /// The command-line setting that replaces the input, texture and all.
    pub fn flag(self) -> &'static str {
        match self {
            TextureSlot::BaseColor => "--base-color R,G,B",
            TextureSlot::Roughness => "--roughness R",
            TextureSlot::Metallic => "--metallic M",
            TextureSlot::Normal => "--no-normal-maps",
            TextureSlot::Emission => "--no-emission",
            TextureSlot::Clearcoat => "--clearcoat W",
            TextureSlot::ClearcoatRoughness => "--clearcoat-roughness R",
            TextureSlot::ClearcoatNormal => "--no-normal-maps",
            TextureSlot::Alpha => "--no-alpha",
        }
    }
}

/// An affine map of texture coordinates (the project's, v up) applied before a texture is
/// sampled: `u' = m[0]·u + m[1]·v + m[2]`, `v' = m[3]·u + m[4]·v + m[5]` (glTF's
/// `KHR_texture_transform`, an `.mtl` map's `-o`/`-s`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform(pub [f32; 6]);

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform::IDENTITY
    }
}

impl UvTransform {
    pub const IDENTITY: UvTransform = UvTransform([1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);

    /// `KHR_texture_transform`'s `offset`, `rotation` (radians) and `scale`, which act on
    /// glTF's coordinates (v down: `(u, 1 − v)` of ours) as translation · rotation · scale,
    /// the rotation's rows `(cos, sin)` and `(−sin, cos)`; rewritten for ours.
    pub fn gltf(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> Self {
        let (sin, cos) = rotation.sin_cos();
        let (a, b) = (cos * scale[0], sin * scale[1]);
        let (c, d) = (-sin * scale[0], cos * scale[1]);
        // u' = a u + b (1 − v) + ox; 1 − v' = c u + d (1 − v) + oy.
        UvTransform([a, -b, b + offset[0], -c, d, 1.0 - d - offset[1]])
    }

    /// `UsdTransform2d`'s `scale`, `rotation` (degrees, counter-clockwise) and `translation`,
    /// which act on `st` (v up, as ours) as translation · rotation · scale.
    pub fn usd(scale: [f32; 2], rotation_deg: f32, translation: [f32; 2]) -> Self {
        let (sin, cos) = rotation_deg.to_radians().sin_cos();
        UvTransform([
            cos * scale[0],
            -sin * scale[1],
            translation[0],
            sin * scale[0],
            cos * scale[1],
            translation[1],
        ])
    }

    /// This map after `inner`: `uv ↦ self(inner(uv))`.
    pub fn after(&self, inner: &UvTransform) -> Self {
        let (a, b) = (&self.0, &inner.0);
        UvTransform([
            a[0] * b[0] + a[1] * b[3],
            a[0] * b[1] + a[1] * b[4],
            a[0] * b[2] + a[1] * b[5] + a[2],
            a[3] * b[0] + a[4] * b[3],
            a[3] * b[1] + a[4] * b[4],
            a[3] * b[2] + a[4] * b[5] + a[5],
        ])
    }

    /// Scale, then offset, per axis (an `.mtl` map's `-s` and `-o`; OBJ's v is already up).
    pub fn scale_offset(scale: [f32; 2], offset: [f32; 2]) -> Self {
        UvTransform([scale[0], 0.0, offset[0], 0.0, scale[1], offset[1]])
    }

    #[inline]
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let m = &self.0;
        Vec2::new(
            m[0] * uv.x + m[1] * uv.y + m[2],
            m[3] * uv.x + m[4] * uv.y + m[5],
        )
    }

    pub fn is_identity(&self) -> bool {
        *self == UvTransform::IDENTITY
    }
}

/// Where a texture's encoded image is.
#[derive(Clone, Debug, PartialEq)]
pub enum TextureData {
    /// In the asset file itself (a `.glb` buffer view or a `data:` URI).
    Embedded(Vec<u8>),
    /// A file next to the asset.
    File(PathBuf),
}

/// A material's texture as the asset file refers to it.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureRef {
    /// For messages: the image's name, else its URI, else `image N`.
    pub name: String,
    pub data: TextureData,
    pub sampler: Sampler,
    /// The UV set it is read with (glTF `texCoord`).
    pub tex_coord: u32,
    /// How the file transforms its UVs for this texture (`KHR_texture_transform`, `-o`/`-s`).
    pub transform: UvTransform,
    pub color_space: ColorSpace,
    /// Per channel, a scale and a bias applied to the decoded texels, `texel · scale + bias`
    /// (USD's `UsdUVTexture` `inputs:scale` and `inputs:bias`); `None`: as decoded.
    pub scale_bias: Option<([f32; 3], [f32; 3])>,
}

/// A tangent-space normal map: the normal in the tangent frame (`tangent::frame_at`: x along
/// the tangent, y along the bitangent, z along the surface normal) is the texel times `scale`
/// plus `bias`, normalised, then blended with the surface's own normal by `strength` as
/// Blender's Normal Map node does. glTF's `normalTexture` and an `.mtl`'s `map_Bump` are
/// `NormalMapRef::unit`; a USD `UsdUVTexture` on `normal` gives its own `scale` and `bias`.
#[derive(Clone, Debug, PartialEq)]
pub struct NormalMapRef {
    pub texture: TextureRef,
    pub scale: [f32; 3],
    pub bias: [f32; 3],
    /// Blender's Normal Map Strength: 1 is the map as it is; otherwise the shading normal is
    /// normalize(N + (M − N) · max(strength, 0)), N the surface's normal without the map and
    /// M the map's (Cycles' `svm_node_normal_map`).
    pub strength: f32,
}

impl NormalMapRef {
    /// A map of 0..1 codes for -1..1, `2c − 1`, of Normal Map Strength `strength` (glTF's
    /// `normalTexture.scale` and an `.mtl`'s `-bm`, which Blender's importers make the
    /// node's Strength).
    pub fn unit(texture: TextureRef, strength: f32) -> Self {
        NormalMapRef {
            texture,
            scale: [2.0; 3],
            bias: [-1.0; 3],
            strength,
        }
    }

    /// For messages: "strength S" for a map `unit` makes, else its scale and bias (and its
    /// strength, where not 1).
    pub fn describe_mapping(&self) -> String {
        if *self == NormalMapRef::unit(self.texture.clone(), self.strength) {
            return format!("strength {}", self.strength);
        }
        let [a, b, c] = self.scale;
        let [d, e, f] = self.bias;
        let strength = match self.strength == 1.0 {
            true => String::new(),
            false => format!(", strength {}", self.strength),
        };
        format!("scale ({a}, {b}, {c}), bias ({d}, {e}, {f}){strength}")
    }
}

/// A scalar material input read from one channel of a texture (0 red, 1 green, 2 blue).
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelRef {
    pub texture: TextureRef,
    pub channel: u8,
}

impl ChannelRef {
    /// "r", "g" or "b".
    pub fn channel_name(&self) -> &'static str {
        channel_name(self.channel)
    }
}

/// Channel `c`'s name: "r", "g" or "b".
pub fn channel_name(c: u8) -> &'static str {
    ["r", "g", "b"][c.min(2) as usize]
}

/// A decoded texture: linear RGB texels, row-major, row 0 at the top of the image.
#[derive(Clone, Debug, PartialEq)]
pub struct ColorMap {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<Vec3>,
    pub sampler: Sampler,
    /// Applied to a UV before it is sampled (`TextureRef::transform`).
    pub transform: UvTransform,
    pub name: String,
}

/// `texels` times a texture's per-channel scale plus its bias (`TextureRef::scale_bias`).
fn scaled(mut texels: Vec<Vec3>, scale_bias: Option<([f32; 3], [f32; 3])>) -> Vec<Vec3> {
    if let Some((scale, bias)) = scale_bias {
        let (scale, bias) = (Vec3::from_array(scale), Vec3::from_array(bias));
        for t in &mut texels {
            *t = *t * scale + bias;
        }
    }
    texels
}

/// The largest texel magnitude a float texture may hold: blends of two stay finite.
const MAX_TEXEL: f32 = 1e30;

/// Why the first texel of `texels` (rows of `width`) that is not a number, or past
/// `MAX_TEXEL`, cannot be shaded with, if there is one.
fn out_of_range_texel(texels: &[Vec3], width: u32) -> Option<String> {
    let i = texels
        .iter()
        .position(|c| !c.is_finite() || c.abs().max_element() > MAX_TEXEL)?;
    let (x, y) = (i as u32 % width, i as u32 / width);
    Some(format!(
        "texel ({x}, {y}) is {}, not a number or past ±{MAX_TEXEL:e}",
        texels[i]
    ))
}

/// The first bytes of an OpenEXR file.
const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// The linear value of each 8-bit sRGB code: what an 8-bit colour texture's texels are made of
/// (the GPU keeps such a texture as its codes and this table, `gpu::beauty::TextureLayout`).
pub fn srgb8_table() -> [f32; 256] {
    std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0))
}

/// The value of each 8-bit code of a data texture, `code / 255` (`ColorSpace::Raw`).
pub fn raw8_table() -> [f32; 256] {
    std::array::from_fn(|i| i as f32 / 255.0)
}

/// sRGB transfer function, decoded: an encoded value in [0, 1] to linear.
#[inline]
pub fn srgb_to_linear(x: f32) -> f32 {
    if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

impl ColorMap {
    /// Decode `texture` of the asset `asset`, which feeds `slot` (for messages): PNG, JPEG or
    /// TIFF, any bit depth, grey or colour, or an OpenEXR file (`load_exr`); alpha is dropped,
    /// grey becomes three equal channels, and the codes become linear values by the texture's
    /// `ColorSpace`.
    pub fn load(asset: &Path, texture: &TextureRef, slot: TextureSlot) -> Result<ColorMap> {
        use ::image::{ImageReader, Limits};
        let name = &texture.name;
        let bad = |what: String| {
            Error::invalid(
                asset,
                format!(
                    "{} texture '{name}': {what} (fix or re-export the texture, or pass {} to \
                     shade without it)",
                    slot.name(),
                    slot.flag()
                ),
            )
        };
        let bytes = match &texture.data {
            TextureData::Embedded(b) => std::borrow::Cow::Borrowed(b.as_slice()),
            TextureData::File(p) => std::borrow::Cow::Owned(
                crate::load::read_named_file(p)
                    .map_err(|e| bad(format!("cannot read '{}': {e}", p.display())))?,
            ),
        };
        if bytes.starts_with(&EXR_MAGIC) {
            let TextureData::File(p) = &texture.data else {
                return Err(bad(
                    "is an OpenEXR image inside the asset file; OpenEXR textures are read \
                     from files of their own"
                        .into(),
                ));
            };
            return Self::load_exr(p, texture).map_err(|e| bad(e.to_string()));
        }
        let reader = || -> Result<ImageReader<std::io::Cursor<&[u8]>>> {
            let mut reader = ImageReader::new(std::io::Cursor::new(&bytes[..]))
                .with_guessed_format()
                .map_err(|e| bad(e.to_string()))?;
            use ::image::ImageFormat::{Jpeg, Png, Tiff};
            match reader.format() {
                Some(Png | Jpeg | Tiff) => {}
                Some(f) => {
                    return Err(bad(format!(
                        "is {f:?}; material textures are read from PNG, JPEG, TIFF or OpenEXR"
                    )))
                }
                None => return Err(bad("is not PNG, JPEG, TIFF or OpenEXR".into())),
            }
            let mut limits = Limits::default();
            limits.max_image_width = Some(MAX_TEXTURE_DIMENSION);
            limits.max_image_height = Some(MAX_TEXTURE_DIMENSION);
            // The decoded image: 4 GiB covers 16k² RGBA8 (and 16-bit RGB up to 26k²).
            limits.max_alloc = Some(4 << 30);
            reader.limits(limits);
            Ok(reader)
        };
        // The header's size first: the JPEG decoder fills in missing image data, so a corrupt
        // few hundred bytes can declare (and decode to) 30k² texels (found by fuzzing). PNG's
        // fails on missing data instead, and a flat palette PNG may well hold 8k texels a byte.
        let head = reader()?;
        let jpeg = head.format() == Some(::image::ImageFormat::Jpeg);
        let (width, height) = head
            .into_dimensions()
            .map_err(|e| bad(format!("cannot decode: {e}")))?;
        let count = width as u64 * height as u64;
        if count == 0 {
            return Err(bad(format!("is {width}x{height} texels")));
        }
        if count > MAX_TEXTURE_TEXELS {
            return Err(bad(format!(
                "is {width}x{height} texels, more than the {MAX_TEXTURE_TEXELS} supported \
                 (downsample it)"
            )));
        }
        if jpeg && count > JPEG_TEXELS_PER_BYTE * bytes.len() as u64 + (1 << 20) {
            return Err(bad(format!(
                "its header says {width}x{height} texels, more than its {} bytes can hold: it \
                 is truncated or corrupt",
                bytes.len()
            )));
        }
        // A decoder panic (zune-jpeg 0.5.15 on some corrupt JPEGs, found by fuzzing) is this
        // texture's error, not the program's.
        let image = reader()?;
        let image = crate::load::catch_quietly(|| image.decode())
            .ok_or_else(|| bad("the image decoder crashed on it: it is corrupt".into()))?
            .map_err(|e| bad(format!("cannot decode: {e}")))?;
        if (image.width(), image.height()) != (width, height) {
            return Err(bad("decodes to another size than its header says".into()));
        }
        // Straight to linear texels: 8-bit images (grey or colour, with or without alpha)
        // through a table, others through f32.
        let kind = image.color();
        let eight_bit = kind.bits_per_pixel() == 8 * u16::from(kind.channel_count());
        let srgb = match texture.color_space {
            ColorSpace::Srgb => true,
            ColorSpace::Raw | ColorSpace::Alpha => false,
            ColorSpace::Auto => eight_bit && kind.channel_count() >= 3,
        };
        let texels: Vec<Vec3> = if texture.color_space == ColorSpace::Alpha {
            match eight_bit {
                true => (image.to_rgba8().pixels())
                    .map(|p| Vec3::splat(raw8_table()[p.0[3] as usize]))
                    .collect(),
                false => (image.to_rgba32f().pixels())
                    .map(|p| Vec3::splat(p.0[3]))
                    .collect(),
            }
        } else if eight_bit {
            let lut = if srgb { srgb8_table() } else { raw8_table() };
            let converted;
            let rgb8 = match &image {
                ::image::DynamicImage::ImageRgb8(b) => b,
                other => {
                    converted = other.to_rgb8();
                    &converted
                }
            };
            rgb8.pixels()
                .map(|p| Vec3::from_array(p.0.map(|c| lut[c as usize])))
                .collect()
        } else {
            let decode: fn(f32) -> f32 = if srgb { srgb_to_linear } else { |x| x };
            image
                .to_rgb32f()
                .pixels()
                .map(|p| Vec3::from_array(p.0.map(decode)))
                .collect()
        };
        // A float TIFF may hold anything, and so may any texel past a scale and bias.
        let texels = scaled(texels, texture.scale_bias);
        if let Some(why) = out_of_range_texel(&texels, width) {
            return Err(bad(why));
        }
        Ok(ColorMap {
            width,
            height,
            texels,
            sampler: texture.sampler,
            transform: texture.transform,
            name: name.clone(),
        })
    }

    /// An OpenEXR texture file: its first flat layer's R, G and B (else Y, else its first
    /// channel, as grey), linear unless the texture says sRGB. The header is checked before
    /// any pixel (the sides, the texel count, what its bytes can expand to); a NaN or
    /// infinite texel is an error.
    fn load_exr(path: &Path, texture: &TextureRef) -> Result<ColorMap> {
        use crate::load::image::{check_exr_size, exr_flat_header, exr_rgb_channels};
        let header = exr_flat_header(path)?;
        let (w, h) = (header.layer_size.width(), header.layer_size.height());
        let side = MAX_TEXTURE_DIMENSION as usize;
        if w == 0 || h == 0 || w > side || h > side || (w * h) as u64 > MAX_TEXTURE_TEXELS {
            return Err(Error::invalid(
                path,
                format!(
                    "is {w}x{h} texels; a texture's sides must be 1..={side} and its texels at \
                     most {MAX_TEXTURE_TEXELS} (downsample it)"
                ),
            ));
        }
        check_exr_size(path, &header)?;
        let alpha = texture.color_space == ColorSpace::Alpha;
        // The alpha: the layer's A (or *.A) channel, else 1 everywhere.
        let alpha_name = (header.channels.list.iter())
            .map(|c| c.name.to_string())
            .find(|n| n == "A" || n.ends_with(".A"));
        let names = match (alpha, alpha_name) {
            (true, Some(a)) => vec![a],
            (true, None) => vec![],
            (false, _) => exr_rgb_channels(path, &header, "the texture")?,
        };
        let texels: Vec<Vec3> = if names.is_empty() {
            vec![Vec3::ONE; w * h]
        } else {
            let (w, h, planes) =
                crate::load::image::read_exr_channels(path, &names, "the texture")?;
            let channel = |k: usize| &planes[k.min(planes.len() - 1)];
            let decode: fn(f32) -> f32 = match texture.color_space {
                ColorSpace::Srgb => srgb_to_linear,
                ColorSpace::Raw | ColorSpace::Auto | ColorSpace::Alpha => |x| x,
            };
            (0..w * h)
                .map(|i| Vec3::new(channel(0)[i], channel(1)[i], channel(2)[i]).map(decode))
                .collect()
        };
        let texels = scaled(texels, texture.scale_bias);
        if let Some(why) = out_of_range_texel(&texels, w as u32) {
            return Err(Error::invalid(path, why));
        }
        Ok(ColorMap {
            width: w as u32,
            height: h as u32,
            texels,
            sampler: texture.sampler,
            transform: texture.transform,
            name: texture.name.clone(),
        })
    }

    /// One texel (x, y), wrapped.
    #[inline]
    pub fn texel(&self, x: i32, y: i32) -> Vec3 {
        let (w, h) = (self.width as i32, self.height as i32);
        let [wu, wv] = self.sampler.wrap;
        self.texels[(wv.index(y, h) * w + wu.index(x, w)) as usize]
    }

    /// The texture's colour at `uv` (its `transform` applied): bilinear over the four nearest
    /// texel centres, or the nearest texel (`Sampler::nearest`).
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        let uv = self.transform.apply(uv);
        // HeightMap::texel_coords, bounded so that the integer texel index cannot overflow;
        // non-finite coordinates become 0 (as the GPU's `texel_safe`).
        let safe = |x: f32| {
            if x.is_finite() {
                x.clamp(-TEXEL_COORD_BOUND, TEXEL_COORD_BOUND)
            } else {
                0.0
            }
        };
        let p = Vec2::new(
            safe(uv.x * self.width as f32),
            safe((1.0 - uv.y) * self.height as f32),
        );
        if self.sampler.nearest {
            let f = p.floor();
            return self.texel(f.x as i32, f.y as i32);
        }
        let q = p - Vec2::splat(0.5);
        let f = q.floor();
        let t = q - f;
        let (x, y) = (f.x as i32, f.y as i32);
        let top = self.texel(x, y).lerp(self.texel(x + 1, y), t.x);
        let bottom = self.texel(x, y + 1).lerp(self.texel(x + 1, y + 1), t.x);
        top.lerp(bottom, t.y)
    }

    /// Whether every texel is grey (its three channels equal): a grey image, which no
    /// tangent-space normal map is (it would hold normals along (1, 1, 1) or its opposite).
    pub fn is_grey(&self) -> bool {
        self.texels.iter().all(|c| c.x == c.y && c.y == c.z)
    }

    /// For logs: "name, W x H, wrapS/wrapT, filter".
    pub fn describe(&self) -> String {
        let wrap = |w: TexWrap| match w {
            TexWrap::Repeat => "repeat",
            TexWrap::Clamp => "clamp",
            TexWrap::Mirror => "mirror",
        };
        format!(
            "{}, {}x{}, {}/{}, {}",
            self.name,
            self.width,
            self.height,
            wrap(self.sampler.wrap[0]),
            wrap(self.sampler.wrap[1]),
            if self.sampler.nearest {
                "nearest"
            } else {
                "bilinear"
            }
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_usd_transform_scales_then_turns_counter_clockwise_then_translates() {
        let t = UvTransform::usd([2.0, 1.0], 90.0, [0.5, 0.0]);
        let uv = t.apply(Vec2::new(1.0, 0.0));
        assert!((uv - Vec2::new(0.5, 2.0)).length() < 1e-6, "{uv}");
        let uv = t.apply(Vec2::new(0.0, 1.0));
        assert!((uv - Vec2::new(-0.5, 0.0)).length() < 1e-6, "{uv}");
        // Composition: `after` applies its argument first.
        let shift = UvTransform::scale_offset([1.0; 2], [0.0, 1.0]);
        let uv = t.after(&shift).apply(Vec2::new(1.0, 0.0));
        assert!((uv - t.apply(Vec2::new(1.0, 1.0))).length() < 1e-6, "{uv}");
        assert_eq!(t.after(&UvTransform::IDENTITY), t);
    }

    fn map(w: u32, h: u32, texels: Vec<Vec3>, sampler: Sampler) -> ColorMap {
        ColorMap {
            width: w,
            height: h,
            texels,
            sampler,
            transform: UvTransform::IDENTITY,
            name: "t".into(),
        }
    }

    #[test]
    fn wrap_modes_fold_indices_into_the_image() {
        let n = 4;
        let got = |w: TexWrap| (-5..9).map(|i| w.index(i, n)).collect::<Vec<_>>();
        assert_eq!(
            got(TexWrap::Repeat),
            [3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0]
        );
        assert_eq!(
            got(TexWrap::Clamp),
            [0, 0, 0, 0, 0, 0, 1, 2, 3, 3, 3, 3, 3, 3]
        );
        assert_eq!(
            got(TexWrap::Mirror),
            [3, 3, 2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0]
        );
    }

    #[test]
    fn sampling_follows_the_height_maps_texel_conventions() {
        // 2x2, row 0 at the top: v = 0.75 is the top row's centre, v = 0.25 the bottom's.
        let (a, b, c, d) = (
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 1.0, 1.0),
        );
        let clamp = Sampler {
            wrap: [TexWrap::Clamp; 2],
            nearest: false,
        };
        let m = map(2, 2, vec![a, b, c, d], clamp);
        assert_eq!(m.sample(Vec2::new(0.25, 0.75)), a);
        assert_eq!(m.sample(Vec2::new(0.75, 0.75)), b);
        assert_eq!(m.sample(Vec2::new(0.25, 0.25)), c);
        assert_eq!(m.sample(Vec2::new(0.75, 0.25)), d);
        assert_eq!(m.sample(Vec2::new(0.5, 0.75)), (a + b) * 0.5);
        assert_eq!(m.sample(Vec2::new(0.5, 0.5)), (a + b + c + d) * 0.25);
        // Clamped past the edge; repeat blends the far column in.
        assert_eq!(m.sample(Vec2::new(-3.0, 0.75)), a);
        let r = map(2, 2, vec![a, b, c, d], Sampler::default());
        assert_eq!(r.sample(Vec2::new(0.0, 0.75)), (a + b) * 0.5);
        assert_eq!(r.sample(Vec2::new(1.25, 0.75)), a);
        // Nearest: the texel the point lies in.
        let n = map(
            2,
            2,
            vec![a, b, c, d],
            Sampler {
                nearest: true,
                ..clamp
            },
        );
        assert_eq!(n.sample(Vec2::new(0.49, 0.51)), a);
        assert_eq!(n.sample(Vec2::new(0.51, 0.49)), d);
        // Far off or NaN UVs stay in the image.
        assert!(r.sample(Vec2::new(f32::NAN, 1e30)).is_finite());
    }

    #[test]
    fn decoding_turns_srgb_into_linear_and_keeps_the_top_row_first() {
        let dir = std::env::temp_dir().join(format!("prismbake-texture-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.png");
        let img = ::image::RgbImage::from_fn(2, 2, |x, y| match (x, y) {
            (0, 0) => ::image::Rgb([255, 0, 0]),
            (1, 0) => ::image::Rgb([0, 128, 0]),
            _ => ::image::Rgb([0, 0, 0]),
        });
        img.save(&path).unwrap();
        let t = TextureRef {
            name: "t.png".into(),
            data: TextureData::File(path.clone()),
            sampler: Sampler::default(),
            tex_coord: 0,
            transform: UvTransform::IDENTITY,
            color_space: ColorSpace::Srgb,
            scale_bias: None,
        };
        let m = ColorMap::load(Path::new("a.gltf"), &t, TextureSlot::BaseColor).unwrap();
        assert_eq!((m.width, m.height), (2, 2));
        assert_eq!(m.texels[0], Vec3::new(1.0, 0.0, 0.0));
        assert!((m.texels[1].y - 0.2158605).abs() < 1e-6, "{}", m.texels[1]);
        // The same bytes embedded decode alike.
        let e = TextureRef {
            data: TextureData::Embedded(std::fs::read(&path).unwrap()),
            ..t.clone()
        };
        assert_eq!(
            ColorMap::load(Path::new("a.glb"), &e, TextureSlot::BaseColor).unwrap(),
            m
        );
    }

    #[test]
    fn gltf_texture_transforms_act_in_gltfs_coordinates() {
        let close = |a: Vec2, b: Vec2| (a - b).abs().max_element() < 1e-6;
        // KHR_texture_transform's example: offset (0, 1), 90°, scale 0.5 reads the lower-left
        // quadrant of the image (glTF's u < 0.5, v > 0.5: ours u < 0.5, v < 0.5), turned.
        let t = UvTransform::gltf([0.0, 1.0], std::f32::consts::FRAC_PI_2, [0.5, 0.5]);
        for (uv, want) in [
            // Ours (0, 1) is glTF's (0, 0), which goes to glTF (0, 1): ours (0, 0).
            ((0.0, 1.0), (0.0, 0.0)),
            // Ours (1, 1) is glTF's (1, 0), which goes to glTF (0, 0.5): ours (0, 0.5).
            ((1.0, 1.0), (0.0, 0.5)),
            // glTF (0, 1) → glTF (0.5, 1): ours (0.5, 0).
            ((0.0, 0.0), (0.5, 0.0)),
        ] {
            let got = t.apply(Vec2::new(uv.0, uv.1));
            assert!(
                close(got, Vec2::new(want.0, want.1)),
                "{uv:?} → {got}, want {want:?}"
            );
        }
        // Its second example, offset (0, 1) and scale (1, −1), flips glTF's v: ours too.
        let flip = UvTransform::gltf([0.0, 1.0], 0.0, [1.0, -1.0]);
        assert!(close(
            flip.apply(Vec2::new(0.25, 0.2)),
            Vec2::new(0.25, 0.8)
        ));
        // A scale alone stretches about glTF's origin, ours (0, 1).
        let s = UvTransform::gltf([0.0, 0.0], 0.0, [2.0, 2.0]);
        assert!(close(s.apply(Vec2::new(0.5, 1.0)), Vec2::new(1.0, 1.0)));
        assert!(close(s.apply(Vec2::new(0.5, 0.5)), Vec2::new(1.0, 0.0)));
        assert!(UvTransform::gltf([0.0; 2], 0.0, [1.0; 2]).is_identity());
        // Sampling applies it: a 2 x 1 texture read through a half-width offset.
        let m = ColorMap {
            transform: UvTransform::scale_offset([1.0, 1.0], [0.5, 0.0]),
            ..map(
                2,
                1,
                vec![Vec3::X, Vec3::Y],
                Sampler {
                    nearest: true,
                    ..Sampler::default()
                },
            )
        };
        assert_eq!(m.sample(Vec2::new(0.25, 0.5)), Vec3::Y);
        assert_eq!(m.sample(Vec2::new(0.75, 0.5)), Vec3::X);
    }

    #[test]
    fn data_textures_keep_their_codes_and_grey_fills_every_channel() {
        let encode = |img: ::image::DynamicImage| {
            let mut png = Vec::new();
            img.write_to(
                &mut std::io::Cursor::new(&mut png),
                ::image::ImageFormat::Png,
            )
            .unwrap();
            png
        };
        let rgb8 = encode(::image::DynamicImage::ImageRgb8(
            ::image::RgbImage::from_pixel(1, 1, ::image::Rgb([0, 128, 255])),
        ));
        let grey8 = encode(::image::DynamicImage::ImageLuma8(
            ::image::GrayImage::from_pixel(1, 1, ::image::Luma([51])),
        ));
        let rgb16 = encode(::image::DynamicImage::ImageRgb16(
            ::image::ImageBuffer::from_pixel(1, 1, ::image::Rgb([0u16, 32768, 65535])),
        ));
        let load = |png: &Vec<u8>, color_space| {
            let t = TextureRef {
                name: "orm".into(),
                data: TextureData::Embedded(png.clone()),
                sampler: Sampler::default(),
                tex_coord: 0,
                transform: UvTransform::IDENTITY,
                color_space,
                scale_bias: None,
            };
            ColorMap::load(Path::new("a.glb"), &t, TextureSlot::Roughness)
                .unwrap()
                .texels[0]
        };
        let raw = Vec3::new(0.0, 128.0 / 255.0, 1.0);
        assert_eq!(load(&rgb8, ColorSpace::Raw), raw);
        assert_eq!(load(&grey8, ColorSpace::Raw), Vec3::splat(0.2));
        assert_eq!(
            load(&grey8, ColorSpace::Srgb),
            Vec3::splat(srgb8_table()[51])
        );
        // USD's auto: an 8-bit colour image is sRGB, a grey or 16-bit one raw.
        assert_eq!(load(&rgb8, ColorSpace::Auto), load(&rgb8, ColorSpace::Srgb));
        assert_eq!(load(&grey8, ColorSpace::Auto), Vec3::splat(0.2));
        let wide = load(&rgb16, ColorSpace::Auto);
        assert!(
            (wide - Vec3::new(0.0, 32768.0 / 65535.0, 1.0))
                .abs()
                .max_element()
                < 1e-6
        );
        // The raw table is the codes over 255, as the GPU's packed data textures read them.
        assert_eq!(raw8_table()[128], 128.0 / 255.0);
    }

    #[test]
    fn jpeg_textures_decode() {
        // A flat 16x8 JPEG (baseline, as glTF exporters write them): lossy, but a flat colour
        // survives within a step or two of 8 bits.
        let mut jpeg = Vec::new();
        ::image::RgbImage::from_pixel(16, 8, ::image::Rgb([200, 100, 50]))
            .write_to(
                &mut std::io::Cursor::new(&mut jpeg),
                ::image::ImageFormat::Jpeg,
            )
            .unwrap();
        let t = TextureRef {
            name: "albedo.jpg".into(),
            data: TextureData::Embedded(jpeg),
            sampler: Sampler::default(),
            tex_coord: 0,
            transform: UvTransform::IDENTITY,
            color_space: ColorSpace::Srgb,
            scale_bias: None,
        };
        let m = ColorMap::load(Path::new("a.glb"), &t, TextureSlot::BaseColor).unwrap();
        assert_eq!((m.width, m.height), (16, 8));
        let want = Vec3::new(200.0, 100.0, 50.0).map(|c| srgb_to_linear(c / 255.0));
        let worst = m
            .texels
            .iter()
            .map(|c| (*c - want).abs().max_element())
            .fold(0.0, f32::max);
        assert!(worst < 0.02, "{worst}");
    }

    #[test]
    fn openexr_and_tiff_textures_decode_as_stored() {
        let dir = std::env::temp_dir().join(format!("pb-texture-formats-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let t = |path: &Path, color_space| TextureRef {
            name: path.file_name().unwrap().to_string_lossy().into_owned(),
            data: TextureData::File(path.into()),
            sampler: Sampler::default(),
            tex_coord: 0,
            transform: UvTransform::IDENTITY,
            color_space,
            scale_bias: None,
        };
        // A 2 x 1 float EXR: values outside 0..1 (a tangent-space normal's -0.25, an emission
        // of 2) are kept as stored; `Auto` (USD's default) and `Raw` read it linear, `Srgb`
        // decodes it.
        let exr = dir.join("n.exr");
        let data = [0.5, -0.25, 2.0, 0.0, 0.25, 1.0]; // R G B of texel 0, then texel 1
        crate::render::output::write_exr(&exr, 2, 1, &["R", "G", "B"], &data).unwrap();
        for space in [ColorSpace::Auto, ColorSpace::Raw] {
            let m =
                ColorMap::load(Path::new("a.usda"), &t(&exr, space), TextureSlot::Normal).unwrap();
            assert_eq!((m.width, m.height), (2, 1));
            assert_eq!(
                m.texels,
                [Vec3::new(0.5, -0.25, 2.0), Vec3::new(0.0, 0.25, 1.0)]
            );
        }
        let m = ColorMap::load(
            Path::new("a.usda"),
            &t(&exr, ColorSpace::Srgb),
            TextureSlot::BaseColor,
        )
        .unwrap();
        assert_eq!(m.texels[0].x, srgb_to_linear(0.5));
        // A scale and bias (USD's) apply per channel to the decoded texels, EXR or not.
        let inverted = TextureRef {
            scale_bias: Some(([1.0, -2.0, 1.0], [0.0, 1.0, 0.5])),
            ..t(&exr, ColorSpace::Raw)
        };
        let m = ColorMap::load(Path::new("a.usda"), &inverted, TextureSlot::Roughness).unwrap();
        assert_eq!(
            m.texels,
            [Vec3::new(0.5, 1.5, 2.5), Vec3::new(0.0, 0.5, 1.5)]
        );
        // Inside the asset file it cannot be read by path: an error that says so.
        let embedded = TextureRef {
            data: TextureData::Embedded(std::fs::read(&exr).unwrap()),
            ..t(&exr, ColorSpace::Raw)
        };
        let e = ColorMap::load(Path::new("a.glb"), &embedded, TextureSlot::Emission)
            .unwrap_err()
            .to_string();
        assert!(e.contains("OpenEXR") && e.contains("--no-emission"), "{e}");
        // A NaN texel is an error naming the texel.
        let nan = dir.join("nan.exr");
        let bad = [0.5, f32::NAN, 0.0, 0.0, 0.0, 0.0];
        crate::render::output::write_exr(&nan, 2, 1, &["R", "G", "B"], &bad).unwrap();
        let e = ColorMap::load(
            Path::new("a.usda"),
            &t(&nan, ColorSpace::Raw),
            TextureSlot::BaseColor,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("texel (0, 0)") && e.contains("nan.exr"), "{e}");
        // A 16-bit TIFF keeps its codes over 65535 as data.
        let tif = dir.join("r.tif");
        ::image::ImageBuffer::<::image::Rgb<u16>, _>::from_pixel(
            3,
            2,
            ::image::Rgb([65535, 32768, 0]),
        )
        .save(&tif)
        .unwrap();
        let m = ColorMap::load(
            Path::new("a.usda"),
            &t(&tif, ColorSpace::Auto),
            TextureSlot::Roughness,
        )
        .unwrap();
        assert_eq!((m.width, m.height), (3, 2));
        assert_eq!(m.texels[5], Vec3::new(1.0, 32768.0 / 65535.0, 0.0));
        let tif_inverted = TextureRef {
            scale_bias: Some(([-1.0; 3], [1.0; 3])),
            ..t(&tif, ColorSpace::Raw)
        };
        let m = ColorMap::load(Path::new("a.usda"), &tif_inverted, TextureSlot::Roughness).unwrap();
        assert_eq!(m.texels[0], Vec3::new(0.0, 1.0 - 32768.0 / 65535.0, 1.0));
    }

    #[test]
    fn bad_textures_are_named_with_the_fix() {
        let t = |data| TextureRef {
            name: "albedo".into(),
            data,
            sampler: Sampler::default(),
            tex_coord: 0,
            transform: UvTransform::IDENTITY,
            color_space: ColorSpace::Srgb,
            scale_bias: None,
        };
        let cases = [
            t(TextureData::Embedded(b"not an image".to_vec())),
            t(TextureData::Embedded(b"\x89PNG\r\n\x1a\n\0\0".to_vec())),
            t(TextureData::File("/nonexistent/albedo.png".into())),
            // A device, which a read would never finish.
            t(TextureData::File("/dev/zero".into())),
        ];
        for case in &cases {
            let e = ColorMap::load(Path::new("asset.glb"), case, TextureSlot::BaseColor)
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("asset.glb")
                    && e.contains("base-colour texture 'albedo'")
                    && e.contains("--base-color"),
                "{e}"
            );
        }
        // A data texture's message names its input and the flag that replaces it.
        let e = ColorMap::load(Path::new("asset.glb"), &cases[0], TextureSlot::Metallic)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("metallic texture 'albedo'") && e.contains("--metallic M"),
            "{e}"
        );
    }
}
