//! Beauty on the GPU: the mirror of `prismbake::render::beauty::render_beauty`, returning the
//! same `BeautyImage` (so `render::output::write_beauty` writes it: linear RGBA EXR, filmic PNG).
//!
//! * `GpuBeautyScene::upload` — the lighting uniform (`GpuLighting`, from the CPU's
//!   `BeautyScene`) and the environment: its texels and the CPU's own sampling tables, value
//!   for value, so importance sampling picks the texels the CPU picks. They go up as three
//!   textures (`EnvTextures`: bounded by the device's largest texture side, not by a storage
//!   binding); the material textures' linear texels in a buffer of their own
//!   (`TextureLayout`), which the materials (`GpuMaterial`) locate.
//! * `render_beauty` — per tile: clear the running sums, one submission per sample (each
//!   pixel's sample is added to its sums when its path ends, the CPU's order of
//!   accumulation), read the sums back and resolve them with `PixelSums::resolve`. A sample
//!   is one dispatch of the fused kernel, or in the wavefront schedule those of
//!   `sample_stages` (`BeautySchedule`).
//!
//! One sample per submission keeps an invocation's loop iterations (BVH walk, march, Newton)
//! far below lavapipe's 65535 per invocation (docs/gpu.md) at any `--spp`.

use crate::context::{BeautyKernel, BeautySchedule, GpuContext, Output};
use crate::layout::{
    texture_sampler_code, GpuBeautySums, GpuLight, GpuLighting, GpuMaterial, GpuMaterialTexture,
    ALPHA_BLEND, ALPHA_MASK, ALPHA_OPAQUE,
};
use crate::render::{frame_uniform, FrameJob, Kernel, Stage, TileRect};
use crate::scene::GpuScene;
use crate::GpuError;
use glam::Vec3;
use prismbake::mesh::AlphaMode;
use prismbake::render::beauty::{
    BeautyCounters, BeautyImage, BeautyScene, Guides, PixelSums, TexChannel,
};
use prismbake::render::camera::Camera;
use prismbake::render::cutout::AlphaCut;
use prismbake::render::env::{EnvFrame, EnvMap};
use prismbake::render::lights::{Light, LightShape, MAX_LIGHTS};
use prismbake::render::RenderSettings;
use prismbake::texture::{raw8_table, srgb8_table, ColorMap};
use prismbake::trace::pdm::PdmOptions;
use std::sync::Mutex;
use wgpu::util::DeviceExt;

/// The lighting uniform of a beauty scene (everything but the environment's tables and the
/// materials) whose textures `layout` lays out (the tangents follow them).
pub fn lighting_uniform(s: &BeautyScene, layout: &TextureLayout) -> GpuLighting {
    let ground = s.ground;
    let mut lights = [GpuLight::default(); MAX_LIGHTS];
    for (l, slot) in s.lights.lights().iter().zip(&mut lights) {
        *slot = gpu_light(l);
    }
    GpuLighting {
        light_count: s.lights.len() as u32,
        lights,
        ground_up: ground.map_or([0.0, 1.0, 0.0], |g| g.up.to_array()),
        ground_height: ground.map_or(0.0, |g| g.height),
        eps: s.eps,
        bounces: s.bounces,
        has_ground: ground.is_some() as u32,
        env_lights: s.env_lights as u32,
        exposure: s.exposure,
        tangent_offset: layout.len as u32,
        emissive: s.emissive as u32,
        ..env_lighting(s.env, s.env_frame)
    }
}

/// One light as the kernel reads it (`GpuLight`).
pub fn gpu_light(l: &Light) -> GpuLight {
    let base = GpuLight {
        color: l.color.to_array(),
        power: l.power,
        ..Default::default()
    };
    match l.shape {
        LightShape::Distant { dir, cos_radius } => GpuLight {
            pos: dir.to_array(),
            kind: 0,
            size: cos_radius,
            ..base
        },
        LightShape::Area { pos, u, v, disk } => GpuLight {
            pos: pos.to_array(),
            kind: if disk { 4 } else { 3 },
            axis: u.to_array(),
            size: v.x,
            cos_inner: v.y,
            cos_outer: v.z,
            ..base
        },
        LightShape::Local { pos, radius, spot } => match spot {
            None => GpuLight {
                pos: pos.to_array(),
                kind: 1,
                size: radius,
                ..base
            },
            Some(s) => GpuLight {
                pos: pos.to_array(),
                kind: 2,
                size: radius,
                axis: s.axis.to_array(),
                cos_inner: s.cos_inner,
                cos_outer: s.cos_outer,
                ..base
            },
        },
    }
}

/// The environment's part of the lighting uniform (its size, weight and `frame`), the rest at
/// its defaults.
pub fn env_lighting(env: &EnvMap, frame: EnvFrame) -> GpuLighting {
    let (to_sin, to_cos) = (-frame.rotation).sin_cos();
    let (from_sin, from_cos) = frame.rotation.sin_cos();
    GpuLighting {
        env_z_up: frame.z_up as u32,
        env_width: env.width,
        env_height: env.height,
        env_total_weight: env.total_weight,
        env_to_sin: to_sin,
        env_to_cos: to_cos,
        env_from_sin: from_sin,
        env_from_cos: from_cos,
        ..Default::default()
    }
}

/// Where the material textures lie in `texture_texels`, in order. A texture whose every channel
/// is a value of an 8-bit code table (`texture::srgb8_table`: every 8-bit colour PNG and JPEG;
/// `texture::raw8_table`: every 8-bit data texture) is kept as its codes, one word a texel
/// (`pack8`), with its table once before the textures: a third of its 3 floats a texel, and
/// the same texels (texture.wgsl's `tex_texel` looks them up in the CPU's own table).
#[derive(Clone, Debug, PartialEq)]
pub struct TextureLayout {
    /// First float of each code table, sRGB then raw (unused without a texture it packs).
    pub tables: [u32; 2],
    /// Per texture: its first float, and the table it is packed with, if any.
    pub textures: Vec<(u32, Option<usize>)>,
    /// Floats of the whole buffer.
    pub len: usize,
}

/// Bit 5 of `GpuMaterialTexture::sampler`: the texture is packed (`TextureLayout`).
pub const TEX_PACKED: u32 = 1 << 5;

/// A packed texel's word as the float `texture_texels` holds: codes r, g, b in bits 0–23 and 0x40
/// above them, so that the float is a normal number (no GPU flushes it on the way).
const PACKED_TAG: u32 = 0x40 << 24;

/// The 8-bit sRGB code whose table value is exactly `v`, if any. The table rises with the code,
/// and so do its values' bits: `first[k]` is the first code whose value's upper 16 bits are at
/// least `k`, and at most two codes share those bits (adjacent values differ by more than
/// 2⁻⁷ of themselves), so one lookup and two comparisons decide. (`linear_to_srgb` would take a
/// `powf` per channel: seconds over a 4096² texture.)
fn srgb8_code(v: f32, table: &[f32; 256]) -> Option<u32> {
    static FIRST: std::sync::OnceLock<Vec<u16>> = std::sync::OnceLock::new();
    let first = FIRST.get_or_init(|| {
        let table = srgb8_table();
        let mut first = vec![256u16; 1 << 16];
        let mut code = 256usize;
        for k in (0..1usize << 16).rev() {
            while code > 0 && (table[code - 1].to_bits() >> 16) as usize >= k {
                code -= 1;
            }
            first[k] = code as u16;
        }
        first
    });
    let bits = v.to_bits();
    let c = first[(bits >> 16) as usize] as usize;
    (c..(c + 2).min(256))
        .find(|&k| table[k].to_bits() == bits)
        .map(|k| k as u32)
}

/// The 8-bit code whose raw table value (`code / 255`) is exactly `v`, if any.
fn raw8_code(v: f32, table: &[f32; 256]) -> Option<u32> {
    let c = (v * 255.0).round();
    (0.0..=255.0)
        .contains(&c)
        .then_some(c as usize)
        .filter(|&c| table[c].to_bits() == v.to_bits())
        .map(|c| c as u32)
}

/// The code tables a texture may be packed with, in `TextureLayout::tables`' order, and how a
/// value finds its code in each.
type CodeOf = fn(f32, &[f32; 256]) -> Option<u32>;
fn code_tables() -> [([f32; 256], CodeOf); 2] {
    [(srgb8_table(), srgb8_code), (raw8_table(), raw8_code)]
}

/// Texel `c`'s packed word as a float, if all three channels are values of `table`.
fn pack8(c: Vec3, (table, code): &([f32; 256], CodeOf)) -> Option<f32> {
    let [r, g, b] = c.to_array().map(|v| code(v, table));
    Some(f32::from_bits(PACKED_TAG | r? | (g? << 8) | (b? << 16)))
}

/// The layout of `textures` in `texture_texels`.
pub fn texture_layout(textures: &[ColorMap]) -> TextureLayout {
    let tables = code_tables();
    let packed: Vec<Option<usize>> = textures
        .iter()
        .map(|t| {
            (0..tables.len()).find(|&k| t.texels.iter().all(|&c| pack8(c, &tables[k]).is_some()))
        })
        .collect();
    let mut next = 0;
    let mut table_at = [0u32; 2];
    for (k, at) in table_at.iter_mut().enumerate() {
        if packed.contains(&Some(k)) {
            *at = next as u32;
            next += 256;
        }
    }
    let textures = textures
        .iter()
        .zip(packed)
        .map(|(t, packed)| {
            let at = next;
            next += t.texels.len() * if packed.is_some() { 1 } else { 3 };
            (at as u32, packed)
        })
        .collect();
    TextureLayout {
        tables: table_at,
        textures,
        len: next,
    }
}

/// `texture_texels` as `layout` lays it out: the tables a texture is packed with, then each
/// texture, packed or 3 floats a texel.
pub fn texel_buffer(textures: &[ColorMap], layout: &TextureLayout) -> Vec<f32> {
    let tables = code_tables();
    let mut out = Vec::with_capacity(layout.len);
    for (k, (table, _)) in tables.iter().enumerate() {
        if layout.textures.iter().any(|&(_, p)| p == Some(k)) {
            debug_assert_eq!(out.len(), layout.tables[k] as usize);
            out.extend_from_slice(table);
        }
    }
    for (t, &(at, packed)) in textures.iter().zip(&layout.textures) {
        debug_assert_eq!(out.len(), at as usize);
        match packed {
            Some(k) => out.extend(
                t.texels
                    .iter()
                    .map(|&c| pack8(c, &tables[k]).expect("texture_layout checked every texel")),
            ),
            None => out.extend(t.texels.iter().flat_map(|c| c.to_array())),
        }
    }
    debug_assert_eq!(out.len(), layout.len);
    out
}

/// Texture `i` of `textures` as a material reads it, where `layout` puts it, reading `channel`.
pub fn material_texture(
    textures: &[ColorMap],
    layout: &TextureLayout,
    i: u32,
    channel: u8,
) -> GpuMaterialTexture {
    let t = &textures[i as usize];
    let (offset, packed) = layout.textures[i as usize];
    GpuMaterialTexture {
        width: t.width,
        height: t.height,
        offset,
        sampler: texture_sampler_code(&t.sampler) | if packed.is_some() { TEX_PACKED } else { 0 },
        table: packed.map_or(0, |k| layout.tables[k]),
        channel: channel as u32,
        uv_u: [t.transform.0[0], t.transform.0[1]],
        uv_v: [t.transform.0[3], t.transform.0[4]],
        uv_offset: [t.transform.0[2], t.transform.0[5]],
    }
}

/// The materials of a beauty scene as the kernel reads them (`shaders/texture.wgsl`), their
/// textures where `layout` puts them.
pub fn material_records(s: &BeautyScene, layout: &TextureLayout) -> Vec<GpuMaterial> {
    let tex = |i, channel| material_texture(s.textures, layout, i, channel);
    let channel =
        |c: Option<TexChannel>| c.map_or(Default::default(), |c| tex(c.texture, c.channel));
    s.materials
        .iter()
        .map(|m| GpuMaterial {
            base_color: m.material.base_color.to_array(),
            roughness: m.material.roughness,
            metallic: m.material.metallic,
            specular: m.material.specular,
            color_tex: m.texture.map_or(Default::default(), |i| tex(i, 0)),
            roughness_tex: channel(m.roughness_texture),
            metallic_tex: channel(m.metallic_texture),
            // A normal map needs the tangents (`BeautyScene::tangents`) to be read in.
            normal_tex: m
                .normal_texture
                .filter(|_| !s.tangents.is_empty())
                .map_or(Default::default(), |n| tex(n.texture, 0)),
            normal_scale: m.normal_texture.map_or([0.0; 3], |n| n.scale.to_array()),
            normal_bias: m.normal_texture.map_or([0.0; 3], |n| n.bias.to_array()),
            normal_strength: m.normal_texture.map_or(1.0, |n| n.strength),
            emission: m.emission.to_array(),
            emission_tex: m.emission_texture.map_or(Default::default(), |i| tex(i, 0)),
            specular_tint: m.material.specular_tint.to_array(),
            clearcoat: m.material.clearcoat,
            clearcoat_roughness: m.material.clearcoat_roughness,
            clearcoat_tex: channel(m.clearcoat_texture),
            clearcoat_roughness_tex: channel(m.clearcoat_roughness_texture),
            clearcoat_normal_tex: m
                .clearcoat_normal_texture
                .filter(|_| !s.tangents.is_empty())
                .map_or(Default::default(), |n| tex(n.texture, 0)),
            clearcoat_normal_scale: (m.clearcoat_normal_texture)
                .map_or([0.0; 3], |n| n.scale.to_array()),
            clearcoat_normal_bias: (m.clearcoat_normal_texture)
                .map_or([0.0; 3], |n| n.bias.to_array()),
            clearcoat_normal_strength: (m.clearcoat_normal_texture).map_or(1.0, |n| n.strength),
            ..alpha_record(&m.cut, s.eps, &tex)
        })
        .collect()
}

/// The alpha fields of a material record (`material.wgsl`'s `alpha_coverage`), its texture
/// located by `tex` (texture index, channel), the rest default.
fn alpha_record(
    cut: &AlphaCut,
    eps: f32,
    tex: &dyn Fn(u32, u8) -> GpuMaterialTexture,
) -> GpuMaterial {
    let (alpha_mode, alpha_cutoff) = match cut.mode {
        AlphaMode::Opaque => (ALPHA_OPAQUE, 0.0),
        AlphaMode::Mask(cutoff) => (ALPHA_MASK, cutoff),
        AlphaMode::Blend => (ALPHA_BLEND, 0.0),
    };
    GpuMaterial {
        alpha: cut.alpha,
        alpha_mode,
        alpha_cutoff,
        alpha_eps: eps,
        alpha_tex: cut
            .texture
            .map_or(Default::default(), |c| tex(c.texture, c.channel)),
        ..Default::default()
    }
}

/// The AOV kernels' materials (`GpuScene::cut_out`): each material's alpha (`cuts`, their
/// textures indices into `textures`) and the texels of the textures, `eps` the step past a
/// cut-away hit.
pub fn alpha_records(
    cuts: &[AlphaCut],
    textures: &[ColorMap],
    eps: f32,
) -> (Vec<GpuMaterial>, Vec<f32>) {
    let layout = texture_layout(textures);
    let tex = |i, channel| material_texture(textures, &layout, i, channel);
    let records = cuts.iter().map(|c| alpha_record(c, eps, &tex)).collect();
    let mut texels = texel_buffer(textures, &layout);
    if texels.is_empty() {
        texels.push(0.0); // a binding is never empty
    }
    (records, texels)
}

/// Floats of the prisms' corner tangents at the end of `texture_texels` (12 a prism).
fn tangent_floats(s: &BeautyScene) -> usize {
    s.tangents.len() * 12
}

/// The environment's per-row arrays as `env_rows` (`shaders/env.wgsl`) holds them: texel y
/// the CPU's `marginal_cdf[y + 1]` (entry 0 is 0 and is not stored) and `row_weight[y]`.
pub fn env_rows(env: &EnvMap) -> Vec<[f32; 2]> {
    env.marginal_cdf[1..]
        .iter()
        .zip(&env.row_weight)
        .map(|(&c, &w)| [c, w])
        .collect()
}

/// The environment as `shaders/env.wgsl` reads it, texel (x, y) rows top to bottom:
/// `radiance` (rgba32float) the texel's radiance in rgb and its `texel_weight` in a;
/// `conditional` (r32float) its row's `conditional_cdf` entry x + 1 (entry 0 is 0 in every row
/// and is not stored, so both are w × h); `rows` (rg32float, h × 1) `env_rows`.
pub struct EnvTextures {
    pub radiance: wgpu::Texture,
    pub conditional: wgpu::Texture,
    pub rows: wgpu::Texture,
}

/// Rows of the environment written to its textures at a time (the rgba rows are built on the
/// host: a band, not the whole map, is held twice).
const ENV_BAND_TEXELS: usize = 1 << 20;

/// `env`'s radiance and weights, interleaved as `EnvTextures::radiance` holds them, rows
/// `rows` (for a band's upload, and for the tests).
pub fn env_radiance_rows(env: &EnvMap, rows: std::ops::Range<u32>) -> Vec<[f32; 4]> {
    let w = env.width as usize;
    let span = rows.start as usize * w..rows.end as usize * w;
    env.texels[span.clone()]
        .iter()
        .zip(&env.texel_weight[span])
        .map(|(c, &wt)| [c.x, c.y, c.z, wt])
        .collect()
}

impl EnvTextures {
    /// Create and fill the three textures (the caller checks the sides: `check_lighting_fits`).
    pub fn upload(ctx: &GpuContext, env: &EnvMap) -> EnvTextures {
        Self::upload_in_bands(ctx, env, ENV_BAND_TEXELS)
    }

    /// `upload`, writing whole rows of about `band_texels` texels at a time.
    pub fn upload_in_bands(ctx: &GpuContext, env: &EnvMap, band_texels: usize) -> EnvTextures {
        use wgpu::TextureFormat::{R32Float, Rg32Float, Rgba32Float};
        let (w, h) = (env.width, env.height);
        let radiance = ctx.load_texture("environment radiance", Rgba32Float, w, h);
        let conditional = ctx.load_texture("environment conditional cdf", R32Float, w, h);
        let rows = ctx.load_texture("environment rows", Rg32Float, h, 1);
        ctx.write_texture_rows(&rows, 0, 1, bytemuck::cast_slice(&env_rows(env)), 0, 8 * h);
        let band = (band_texels / w as usize).max(1) as u32;
        let f32s = std::mem::size_of::<f32>() as u32;
        for y0 in (0..h).step_by(band as usize) {
            let n = band.min(h - y0);
            let texels = env_radiance_rows(env, y0..y0 + n);
            ctx.write_texture_rows(
                &radiance,
                y0,
                n,
                bytemuck::cast_slice(&texels),
                0,
                4 * f32s * w,
            );
            // Each row's w + 1 entries, from the second on: the array as it is, no copy.
            let first = (y0 * (w + 1)) as usize;
            let cdf = &env.conditional_cdf[first..first + (n * (w + 1)) as usize];
            ctx.write_texture_rows(
                &conditional,
                y0,
                n,
                bytemuck::cast_slice(cdf),
                f32s as u64,
                f32s * (w + 1),
            );
        }
        EnvTextures {
            radiance,
            conditional,
            rows,
        }
    }

    /// Bytes on the device.
    fn bytes(env: &EnvMap) -> u64 {
        (env.width as u64 * env.height as u64) * (16 + 4) + env.height as u64 * 8
    }
}

/// What to do when the lighting does not fit the device.
const LIGHTING_FIX: &str =
    "use a smaller --env map or material textures, or --device auto or cpu (the CPU renderer has no such limit)";

/// Whether an environment (`None`: the one-texel black a render without `--env` lights with)
/// and the material textures fit `ctx` as `GpuBeautyScene::upload` lays them out: the
/// environment's sides within the device's largest texture side, the textures' texels within a
/// storage binding; counted without building them. The check a job makes before its first
/// frame, and `upload`'s own.
pub fn check_lighting_fits(
    ctx: &GpuContext,
    env: Option<&EnvMap>,
    textures: &[ColorMap],
) -> Result<(), GpuError> {
    let layout = texture_layout(textures);
    check_lighting_sizes(ctx, env, &layout, 0)
}

/// `check_lighting_fits` for a layout already made (each makes it once: a pass over every
/// texture's texels).
fn check_lighting_sizes(
    ctx: &GpuContext,
    env: Option<&EnvMap>,
    layout: &TextureLayout,
    tangent_floats: usize,
) -> Result<(), GpuError> {
    if let Some(e) = env {
        ctx.check_texture_side("environment map", e.width, e.height, LIGHTING_FIX)?;
    }
    let limit = ctx.max_binding_bytes();
    let bytes = (layout.len + tangent_floats) as u64 * std::mem::size_of::<f32>() as u64;
    if bytes > limit {
        return Err(GpuError::TooLarge {
            what: "material texture texels",
            bytes,
            limit,
            fix: LIGHTING_FIX,
        });
    }
    Ok(())
}

/// A `BeautyScene` on the GPU: bind group 2 of the beauty kernel.
pub struct GpuBeautyScene {
    pub(crate) group: wgpu::BindGroup,
    uniform: wgpu::Buffer,
    materials: wgpu::Buffer,
    /// Address and size of the `EnvMap` the tables came from, and of the textures the texels
    /// end with (what `serves` compares).
    env_id: (usize, u32, u32),
    texture_id: (usize, usize, usize, usize),
    material_count: usize,
    /// Where the textures went (`update` rewrites the materials that point there).
    layout: TextureLayout,
    bytes: u64,
    /// What the uniform holds now (the bounces and lights decide a sample's dispatches).
    current: Mutex<GpuLighting>,
}

impl GpuBeautyScene {
    /// Upload the lighting, the environment, the materials and their textures.
    /// Fails with `GpuError::TooLarge` if the environment's and the textures' texels together,
    /// or the
    /// environment's tables, exceed one storage binding (128 MiB on WebGPU defaults: about
    /// 11 M texels, e.g. a 4096 × 2048 environment; hardware adapters allow more).
    pub fn upload(ctx: &GpuContext, s: &BeautyScene) -> Result<GpuBeautyScene, GpuError> {
        let layout = texture_layout(s.textures);
        check_lighting_sizes(ctx, Some(s.env), &layout, tangent_floats(s))?;
        let mut bytes = EnvTextures::bytes(s.env);
        let mut storage = |what: &'static str, data: &[f32]| {
            let data: &[u8] = bytemuck::cast_slice(data);
            bytes += data.len() as u64;
            ctx.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(what),
                    contents: data,
                    usage: wgpu::BufferUsages::STORAGE,
                })
        };
        let mut texels = texel_buffer(s.textures, &layout);
        // The tangents normal maps are read in, after the textures (`GpuLighting::tangent_offset`).
        texels.extend(s.tangents.iter().flatten().flat_map(|t| t.to_array()));
        if texels.is_empty() {
            texels.push(0.0); // a binding is never empty
        }
        let texels = storage("material texture texels", &texels);
        let env = EnvTextures::upload(ctx, s.env);
        let view = |t: &wgpu::Texture| t.create_view(&wgpu::TextureViewDescriptor::default());
        let (radiance, conditional, rows) =
            (view(&env.radiance), view(&env.conditional), view(&env.rows));
        let records = material_records(s, &layout);
        let materials = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("materials"),
                contents: bytemuck::cast_slice(&records),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            });
        let uniform = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("lighting"),
                contents: bytemuck::bytes_of(&lighting_uniform(s, &layout)),
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            });
        let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("lighting"),
            layout: &ctx.lighting_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniform.as_entire_binding(),
                }, // lighting
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: texels.as_entire_binding(),
                }, // texture_texels
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(&rows),
                }, // env_rows
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: materials.as_entire_binding(),
                }, // materials
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: wgpu::BindingResource::TextureView(&radiance),
                }, // env_radiance_map
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: wgpu::BindingResource::TextureView(&conditional),
                }, // env_conditional
                wgpu::BindGroupEntry {
                    binding: 6,
                    resource: ctx.bsdf_tables().as_entire_binding(),
                }, // bsdf_tables
            ],
        });
        // A buffer the driver refused (out of memory) shows here, not as a panic.
        ctx.check()?;
        Ok(GpuBeautyScene {
            group,
            uniform,
            env_id: env_id(s.env),
            texture_id: texture_id(s),
            material_count: records.len(),
            current: Mutex::new(lighting_uniform(s, &layout)),
            layout,
            materials,
            bytes,
        })
    }

    /// Whether these tables and texels were uploaded from `s`'s environment and textures, for
    /// as many materials (a renderer rewrites only the uniform and the materials for the
    /// frames of one job).
    pub fn serves(&self, s: &BeautyScene) -> bool {
        self.env_id == env_id(s.env)
            && self.texture_id == texture_id(s)
            && self.material_count == s.materials.len()
    }

    /// Rewrite the lighting uniform (key light, ground, bounces) and the materials for `s`,
    /// whose environment and textures must be the ones uploaded (`serves`).
    pub fn update(&self, ctx: &GpuContext, s: &BeautyScene) {
        debug_assert!(self.serves(s));
        let lighting = lighting_uniform(s, &self.layout);
        ctx.queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&lighting));
        ctx.queue.write_buffer(
            &self.materials,
            0,
            bytemuck::cast_slice(&material_records(s, &self.layout)),
        );
        *self.current.lock().unwrap_or_else(|e| e.into_inner()) = lighting;
    }

    /// The lighting uniform as last written.
    pub fn uniform(&self) -> GpuLighting {
        *self.current.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Bytes uploaded (environment texels and tables).
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}

fn env_id(env: &EnvMap) -> (usize, u32, u32) {
    (env as *const EnvMap as usize, env.width, env.height)
}

fn texture_id(s: &BeautyScene) -> (usize, usize, usize, usize) {
    let (t, n) = (s.textures, s.tangents);
    (t.as_ptr() as usize, t.len(), n.as_ptr() as usize, n.len())
}

/// Render one beauty frame on the GPU: the CPU's `render_beauty` for the same scene, camera,
/// settings and seed, up to float rounding. `opts` are the PDM options of the intersector
/// (as `render_aovs` takes them). `progress` is called with rows finished, scaled over the
/// samples of every tile. The context's schedule (`GpuContext::beauty_schedule`).
pub fn render_beauty(
    ctx: &GpuContext,
    scene: &GpuScene,
    lighting: &GpuBeautyScene,
    cam: &Camera,
    s: &RenderSettings,
    opts: &PdmOptions,
    progress: &dyn Fn(usize),
) -> Result<BeautyImage, GpuError> {
    let schedule = ctx.beauty_schedule();
    render_beauty_scheduled(ctx, schedule, scene, lighting, cam, s, opts, progress)
}

/// `render_beauty` in the given schedule (both give the same image).
#[allow(clippy::too_many_arguments)]
pub fn render_beauty_scheduled(
    ctx: &GpuContext,
    schedule: BeautySchedule,
    scene: &GpuScene,
    lighting: &GpuBeautyScene,
    cam: &Camera,
    s: &RenderSettings,
    opts: &PdmOptions,
    progress: &dyn Fn(usize),
) -> Result<BeautyImage, GpuError> {
    crate::render::check_render(s, opts)?;
    let once = |pipeline| Stage {
        pipeline,
        layers: 1,
        across: 1,
    };
    let (stages, tonemap) = match schedule {
        BeautySchedule::Fused => {
            let k = ctx.beauty_fused()?;
            (vec![once(&k.render)], once(&k.tonemap))
        }
        BeautySchedule::Wavefront => {
            let k = ctx.beauty_wavefront()?;
            let stages = sample_stages(k, &lighting.uniform(), ctx.trace_pixels());
            (stages, once(&k.tonemap))
        }
    };
    let dispatch = Kernel {
        stages: &stages,
        finish: &[tonemap],
        output: Output::BeautySums,
        groups: &[&lighting.group],
        paths: schedule == BeautySchedule::Wavefront,
        label: "render_beauty",
    };
    let n = s.width as usize * s.height as usize;
    let blank = || BeautyImage {
        width: s.width,
        height: s.height,
        rgba: vec![[0.0; 4]; n],
        background: vec![Vec3::ZERO; n],
        guides: vec![Guides::default(); n],
        counters: BeautyCounters::default(),
        preview: Some(vec![[0; 3]; n]),
        exposure: lighting.uniform().exposure,
    };
    let frame = FrameJob {
        ctx,
        scene,
        kernel: &dispatch,
        base: frame_uniform(cam, s, opts),
    };
    frame.render(blank, resolve_tile, progress)
}

/// The dispatches of one sample under lighting `l`: `beauty_start` (camera rays), then a
/// trace and a shading step for each step of the longest path: the camera's, then one per
/// surface event (`bounces`), or the ground's. The camera step traces one ray slot; the
/// others the slots their rays can take (`beauty_trace`: the continuation, the environment's
/// shadow ray if the environment lights, the key light's if there is one), each invocation
/// for `trace_pixels` pixels of a row (`GpuContext::trace_pixels`).
fn sample_stages<'k>(k: &'k BeautyKernel, l: &GpuLighting, trace_pixels: u32) -> Vec<Stage<'k>> {
    let stage = |pipeline, layers| Stage {
        pipeline,
        layers,
        across: 1,
    };
    let trace = |layers| Stage {
        pipeline: &k.trace,
        layers,
        across: trace_pixels,
    };
    let slots = match (l.light_count != 0, l.env_lights != 0) {
        (true, _) => 3,
        (false, true) => 2,
        (false, false) => 1,
    };
    let mut stages = vec![stage(&k.start, 1), trace(1), stage(&k.shade, 1)];
    for _ in 0..l.bounces.max(1) {
        stages.extend([trace(slots), stage(&k.shade, 1)]);
    }
    stages
}

/// Resolve a tile of the kernel's sums into `image` exactly as the CPU resolves its own
/// (`PixelSums::resolve`), on all cores and straight from the read-back; the preview's codes
/// as `tonemap.wgsl` left them.
fn resolve_tile(image: &mut BeautyImage, rect: TileRect, tile: &[GpuBeautySums], spp: u32) {
    use rayon::prelude::*;
    let resolve = |g: &GpuBeautySums| PixelSums {
        radiance: Vec3::from_array(g.radiance),
        surface: g.surface,
        background: Vec3::from_array(g.background),
        ground_background: Vec3::from_array(g.ground_background),
        ground_samples: g.ground_samples,
        ground_lit: g.ground_lit,
        ground_unshadowed: g.ground_unshadowed,
        normal: Vec3::from_array(g.normal),
        albedo: Vec3::from_array(g.albedo),
    };
    // One pass over the tile: its pixels resolved into the frame, its rays counted.
    let pixels = image.rgba.len();
    let preview = image.preview.get_or_insert_with(|| vec![[0; 3]; pixels]);
    let (rays, key, env) = rect
        .frame_rows(&mut image.rgba)
        .zip(rect.frame_rows(&mut image.background))
        .zip(rect.frame_rows(&mut image.guides))
        .zip(rect.frame_rows(preview))
        .zip(rect.tile_rows(tile))
        .map(|((((rgba, background), guides), preview), src)| {
            let dst = rect
                .span(rgba)
                .iter_mut()
                .zip(rect.span(background))
                .zip(rect.span(guides))
                .zip(rect.span(preview));
            let mut counts = (0u64, 0u64, 0u64);
            for ((((c, b), f), p), g) in dst.zip(src) {
                let sums = resolve(g);
                (*c, *b) = sums.resolve(spp);
                *f = sums.guides(spp);
                *p = [
                    g.preview as u8,
                    (g.preview >> 8) as u8,
                    (g.preview >> 16) as u8,
                ];
                counts.0 += g.rays as u64;
                counts.1 += g.key_shadow_rays as u64;
                counts.2 += g.env_shadow_rays as u64;
            }
            counts
        })
        .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
    let c = &mut image.counters;
    c.rays += rays;
    c.key_shadow_rays += key;
    c.env_shadow_rays += env;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_srgb8_value_and_no_other_float_finds_its_code() {
        let table = srgb8_table();
        for (code, &v) in table.iter().enumerate() {
            assert_eq!(srgb8_code(v, &table), Some(code as u32), "{v}");
            // Its neighbouring floats are no code's value (the table's are > 1 ulp apart).
            for near in [
                f32::from_bits(v.to_bits() + 1),
                f32::from_bits(v.to_bits().max(1) - 1),
            ] {
                if near != v && !table.contains(&near) {
                    assert_eq!(srgb8_code(near, &table), None, "{near} next to code {code}");
                }
            }
        }
        for v in [-0.5, 1.5, 0.123_456, f32::NAN, f32::INFINITY, -0.0] {
            assert_eq!(srgb8_code(v, &table), None, "{v}");
        }
        // A colour of codes packs and unpacks to them; one other channel keeps it in floats.
        let tables = code_tables();
        let c = Vec3::new(table[3], table[200], table[255]);
        let word = pack8(c, &tables[0]).unwrap().to_bits();
        assert_eq!(word & 0xff_ffff, 3 | (200 << 8) | (255 << 16));
        assert!(f32::from_bits(word).is_normal());
        assert_eq!(pack8(Vec3::new(table[3], 0.3, table[1]), &tables[0]), None);
    }

    #[test]
    fn raw_codes_are_found_exactly() {
        let table = raw8_table();
        for (code, &v) in table.iter().enumerate() {
            assert_eq!(raw8_code(v, &table), Some(code as u32), "{v}");
            let near = f32::from_bits(v.to_bits() + 1);
            assert_eq!(raw8_code(near, &table), None, "{near} next to code {code}");
        }
        for v in [
            -0.5,
            1.5,
            0.123_456,
            f32::NAN,
            f32::INFINITY,
            -0.0,
            -1.0 / 255.0,
        ] {
            assert_eq!(raw8_code(v, &table), None, "{v}");
        }
        let tables = code_tables();
        let word = pack8(Vec3::new(table[0], table[128], table[255]), &tables[1]).unwrap();
        assert_eq!(word.to_bits() & 0xff_ffff, (128 << 8) | (255 << 16));
        // A texture of raw codes goes up with the raw table alone; one of sRGB codes and one of
        // other floats beside it lay out as before.
        let map = |texels: Vec<Vec3>| ColorMap {
            width: texels.len() as u32,
            height: 1,
            texels,
            sampler: Default::default(),
            transform: Default::default(),
            name: "t".into(),
        };
        let srgb = srgb8_table();
        let layout = texture_layout(&[
            map(vec![Vec3::new(table[1], table[2], table[3])]),
            map(vec![Vec3::splat(0.3); 2]),
            map(vec![Vec3::new(srgb[9], srgb[10], srgb[11])]),
        ]);
        assert_eq!(layout.tables, [0, 256]);
        assert_eq!(
            layout.textures,
            [(512, Some(1)), (513, None), (519, Some(0))]
        );
        assert_eq!(layout.len, 520);
    }
}
