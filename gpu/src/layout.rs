//! Host mirrors of the structs the shaders read and write (`shaders/common.wgsl`).
//!
//! Every struct is `#[repr(C)]` + bytemuck, its byte size is in its doc comment and asserted
//! at compile time, and `tests/layout.rs` parses the WGSL with naga (wgpu's own copy,
//! `wgpu::naga`) and compares every member offset and struct size with `offset_of!` here.
//! Sentinels are defined once here and mirrored as WGSL constants (also tested).

use bytemuck::{Pod, Zeroable};

/// "No prism" in the `prism` member of `GpuAovPixel` (= `prismbake::trace::NO_PRISM`).
pub const NO_PRISM: u32 = prismbake::trace::NO_PRISM;
/// The shaders' stand-in for `f32::INFINITY` (WGSL lets an implementation assume that no
/// infinities occur at run time, so `t_max = ∞` is this large finite value on the GPU).
pub const T_FAR: f32 = 3.0e38;
/// "No stitch record" in `GpuPrism::stitch`: the prism has no stitched seam edge (every prism
/// of a scene traced with `SeamMode::Open`), so the shaders evaluate the raw `D(uv(b))`.
pub const NO_STITCH: u32 = u32::MAX;
/// Compute workgroup edge: both kernels run `@workgroup_size(8, 8)`; the host dispatches
/// `div_ceil(tile, WORKGROUP)` groups per axis.
pub const WORKGROUP: u32 = 8;

/// Bytes of one pixel's path record in the beauty kernels' work buffer (`PathRecord` in
/// `shaders/beauty.wgsl`: the path's state between dispatches, its three ray slots and their
/// answers). Only the GPU reads it; the host sizes the buffer (tile² records) and the layout
/// test checks this against the WGSL.
pub const PATH_RECORD_BYTES: u64 = 464;

/// One prism record, 40 bytes: `prismbake::bake::Prism` as the shader reads it, plus the
/// index of its stitch record (`StitchField::record_index`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuPrism {
    pub tri: [u32; 3],
    pub flags: u32,
    pub d_min: f32,
    pub d_max: f32,
    pub lambda_lo: f32,
    pub lambda_hi: f32,
    pub texel_world: f32,
    /// Index into the `stitches` array, or `NO_STITCH`.
    pub stitch: u32,
}

/// The stitch data of one prism with stitched seam edges, 88 bytes:
/// `prismbake::seam::PrismStitch` without `band_h` (a bound the bake has already folded into
/// the prism's range).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuPrismStitch {
    /// Per edge `k`: the neighbour's UV chart over this prism's corners.
    pub other_uv: [[[f32; 2]; 3]; 3],
    /// Per edge `k`: the band width `β_k` (barycentric), 0 where edge `k` is not stitched.
    pub band: [f32; 3],
    pub _pad: u32,
}

impl From<&prismbake::seam::PrismStitch> for GpuPrismStitch {
    fn from(s: &prismbake::seam::PrismStitch) -> Self {
        GpuPrismStitch {
            other_uv: s.other_uv.map(|chart| chart.map(|uv| uv.to_array())),
            band: s.band,
            _pad: 0,
        }
    }
}

/// One base vertex, 32 bytes: position, unit normal and UV (u and v fill the vec3 padding).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuVertex {
    pub position: [f32; 3],
    pub u: f32,
    pub normal: [f32; 3],
    pub v: f32,
}

/// One BVH2 node, 32 bytes: obvhs's `Bvh2Node` layout with feature `small_bvh2_node`
/// (`prim_count == 0`: inner node, children at `first_index` and `first_index + 1`; else a
/// leaf whose prisms are `prim_indices[first_index .. first_index + prim_count]`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuBvhNode {
    pub min: [f32; 3],
    pub prim_count: u32,
    pub max: [f32; 3],
    pub first_index: u32,
}

/// Scene-wide constants, 32 bytes (uniform).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuSceneParams {
    pub map_width: u32,
    pub map_height: u32,
    /// 0 = repeat, 1 = clamp (`prismbake::Wrap`).
    pub wrap: u32,
    pub node_count: u32,
    pub disp_scale: f32,
    pub disp_midlevel: f32,
    pub prism_count: u32,
    /// How the height-map buffer holds the texels (`MapEncoding`).
    pub map_encoding: u32,
}

/// `GpuSceneParams::wrap` of a map's wrap mode (heightmap.wgsl's `scene.wrap`).
pub fn wrap_code(wrap: prismbake::Wrap) -> u32 {
    match wrap {
        prismbake::Wrap::Repeat => 0,
        prismbake::Wrap::Clamp => 1,
    }
}

/// How the height map's texels are stored on the GPU (`GpuSceneParams::map_encoding`,
/// heightmap.wgsl's `map_texel`). Every encoding gives back the CPU's f32 texels exactly:
/// `encode_height_map` picks the narrowest one that does for every texel of the map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapEncoding {
    /// One f32 per word: any map.
    F32 = 0,
    /// Two 16-bit codes `q` per word, the texel `q / 65535`: a 16-bit PNG or TIFF as the
    /// loader decodes it, and an 8-bit one too (`q₈ / 255 = 257 q₈ / 65535`, the same f32).
    Unorm16 = 1,
    /// Two IEEE half floats per word (no subnormals, which a GPU may flush): a half-float EXR.
    F16 = 2,
}

impl MapEncoding {
    pub fn name(self) -> &'static str {
        match self {
            MapEncoding::F32 => "f32",
            MapEncoding::Unorm16 => "unorm16",
            MapEncoding::F16 => "f16",
        }
    }
}

/// A height map as the GPU stores it: its encoding and the words of its r32uint texture, row
/// after row, `row_words` a row (an f32 map's own texels, borrowed: no copy of a map that may
/// be hundreds of megabytes).
pub struct EncodedMap<'a> {
    pub encoding: MapEncoding,
    pub words: std::borrow::Cow<'a, [u32]>,
    /// Words a row: the map's width in f32, half of it (rounded up) packed.
    pub row_words: u32,
}

impl EncodedMap<'_> {
    /// Rows (the map's height; 1 for an empty map, as its texture has one).
    pub fn rows(&self) -> u32 {
        (self.words.len() / self.row_words.max(1) as usize).max(1) as u32
    }
}

/// The 16-bit code `q` whose texel `q / 65535` (f32, as the loader divides) is `v`, if any.
/// The shader's decode (`unorm16_texel`) gives that quotient, correctly rounded, for every code.
fn unorm16_code(v: f32) -> Option<u16> {
    let q = (v * 65535.0).round();
    ((0.0..=65535.0).contains(&q) && q / 65535.0 == v && v.to_bits() != (-0.0f32).to_bits())
        .then_some(q as u16)
}

/// The IEEE half float equal to `v`, if there is one that is zero or normal.
fn f16_code(v: f32) -> Option<u16> {
    let bits = v.to_bits();
    let sign = ((bits >> 16) & 0x8000) as u16;
    if v == 0.0 {
        return Some(sign);
    }
    // A half has 10 mantissa bits (the f32's low 13 must be zero) and exponents −14 to 15.
    let exp = ((bits >> 23) & 0xff) as i32 - 127;
    if bits & 0x1fff != 0 || !(-14..=15).contains(&exp) {
        return None;
    }
    Some(sign | (((exp + 15) as u16) << 10) | ((bits >> 13) & 0x3ff) as u16)
}

/// Every texel's 16-bit code (`code`), two per word in each row of `width` texels: texel
/// `(2k, y)` in the low half of the row's word `k`, `(2k + 1, y)` in the high half (an odd
/// row's last word has its high half 0). `None` at the first texel without one. One pass: a
/// map that packs is read once, and one that does not usually stops at its first texel.
fn pack_halves(data: &[f32], width: usize, code: fn(f32) -> Option<u16>) -> Option<Vec<u32>> {
    let row_words = width.div_ceil(2);
    let mut words = vec![0u32; data.len().div_ceil(width.max(1)) * row_words];
    for (row, out) in data
        .chunks(width.max(1))
        .zip(words.chunks_mut(row_words.max(1)))
    {
        for (pair, word) in row.chunks(2).zip(out) {
            for (k, &v) in pair.iter().enumerate() {
                *word |= (code(v)? as u32) << (16 * k);
            }
        }
    }
    Some(words)
}

/// The narrowest encoding that gives back every texel of `data` (rows of `width` texels)
/// exactly, halving the GPU's copy of a 16-bit, 8-bit or half-float map (an 8192² map is
/// 128 MiB instead of 256 MiB), and the texture's words.
pub fn encode_height_map(data: &[f32], width: u32) -> EncodedMap<'_> {
    let packed = [
        (MapEncoding::Unorm16, unorm16_code as fn(f32) -> Option<u16>),
        (MapEncoding::F16, f16_code),
    ]
    .into_iter()
    .find_map(|(encoding, code)| Some((encoding, pack_halves(data, width as usize, code)?)));
    match packed {
        Some((encoding, words)) => EncodedMap {
            encoding,
            words: words.into(),
            row_words: width.div_ceil(2),
        },
        None => EncodedMap {
            encoding: MapEncoding::F32,
            words: bytemuck::cast_slice(data).into(),
            row_words: width,
        },
    }
}

/// Per-dispatch constants, 112 bytes (uniform): the camera basis (computed on the host,
/// exactly as `Camera::ray` does), the tile, sampling and PDM options.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuFrame {
    pub cam_from: [f32; 3],
    pub tan_half_fov: f32,
    pub cam_right: [f32; 3],
    pub aspect: f32,
    pub cam_up: [f32; 3],
    pub width: u32,
    pub cam_back: [f32; 3],
    pub height: u32,
    pub tile_origin: [u32; 2],
    pub tile_size: [u32; 2],
    pub spp: u32,
    pub seed: u32,
    /// 1: `dt_value` is a fraction of the prism's texel size (`StepSize::Auto`); 0: world.
    pub dt_auto: u32,
    pub dt_value: f32,
    pub jitter: u32,
    pub refine: u32,
    /// 0 = smooth, 1 = geometric (`NormalMode`).
    pub normal_mode: u32,
    /// The one sample a dispatch renders (both kernels accumulate over dispatches).
    pub sample_index: u32,
    /// 1: an orthographic view, `tan_half_fov` is half its height in scene units (rays start
    /// on the plane through `cam_from`, along −`cam_back`); 0: a pinhole.
    pub orthographic: u32,
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
}

/// One pixel of AOV sums over the samples rendered so far, 48 bytes (the CPU's per-pixel
/// accumulator); the host divides and normalises them as the CPU does.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuAovPixel {
    pub normal_sum: [f32; 3],
    pub depth_sum: f32,
    pub uv_sum: [f32; 2],
    /// Samples that hit (the CPU's `hits`; a float, exact below 2^24).
    pub hits: f32,
    pub steps_sum: f32,
    /// Prism id + 1 of the first sample that hit, 0 = miss (the `prism` AOV's convention).
    pub prism: u32,
    pub _pad: [u32; 3],
}

/// One light of the beauty (`prismbake::render::lights::Light`, with its pick's chance), 64
/// bytes: `kind` 0 directional (`pos` the unit direction towards it, `size` the cosine of its
/// disc's radius), 1 a point or sphere (`pos` its centre, `size` its radius), 2 a spot (also
/// `axis`, `cos_inner`, `cos_outer`), 3 a rectangle and 4 a disk (`pos` its centre, `axis` its
/// `u`, and `size`, `cos_inner`, `cos_outer` the three components of its `v`); `power`,
/// `color` as `Light`'s. Its chance of being picked is the kernel's to find at each surface
/// event (`LightSet::at`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLight {
    pub pos: [f32; 3],
    pub kind: u32,
    pub color: [f32; 3],
    pub power: f32,
    pub axis: [f32; 3],
    pub size: f32,
    pub cos_inner: f32,
    pub cos_outer: f32,
    pub _pad0: f32,
    pub _pad1: f32,
}

/// Everything the beauty kernel needs besides the scene, the materials and the environment
/// tables, 1136 bytes
/// (uniform): `prismbake::render::beauty::BeautyScene` with its `Material` and its lights
/// (`lights::MAX_LIGHTS` slots, `light_count` used), and the
/// environment's size, total weight and frame (the rotation's sine and cosine computed on the
/// host, as `env::world_to_env` / `env_to_world` compute them).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuLighting {
    pub _pad0: u32,
    pub _pad1: u32,
    pub _pad2: u32,
    pub _pad3: u32,
    pub ground_up: [f32; 3],
    pub ground_height: f32,
    /// Ray origin offset (`beauty::scene_epsilon`).
    pub eps: f32,
    pub bounces: u32,
    /// The lights in `lights` (0: none, no light samples).
    pub light_count: u32,
    pub has_ground: u32,
    /// 0: the environment is black (`BeautyScene::env_lights`), no environment rays.
    pub env_lights: u32,
    pub env_z_up: u32,
    pub env_width: u32,
    pub env_height: u32,
    pub env_total_weight: f32,
    /// `(-rotation).sin_cos()`, for `world_to_env`.
    pub env_to_sin: f32,
    pub env_to_cos: f32,
    /// `rotation.sin_cos()`, for `env_to_world`.
    pub env_from_sin: f32,
    pub env_from_cos: f32,
    /// The preview's exposure factor (`BeautyScene::exposure`), for `tonemap.wgsl`.
    pub exposure: f32,
    pub _pad4: u32,
    /// The first float of the prisms' corner tangents in `texture_texels`
    /// (`BeautyScene::tangents`, 12 floats a prism), which normal maps are read in.
    pub tangent_offset: u32,
    /// 1: some material glows (`BeautyScene::emissive`).
    pub emissive: u32,
    pub _pad5: u32,
    pub _pad6: u32,
    pub _pad7: u32,
    pub lights: [GpuLight; prismbake::render::lights::MAX_LIGHTS],
}

/// One texture of a material as the kernel reads it, 48 bytes: its size (0 × 0: none), its
/// first float in `texture_texels`, its sampler (`texture_sampler_code`; bit 5 packed), the
/// first float of the code table a packed texture's texels index (`beauty::TextureLayout`),
/// the channel a roughness or metallic texture is read from, and its UV transform
/// (`texture::UvTransform`: `u' = uv_u · uv + uv_offset.x`, `v' = uv_v · uv + uv_offset.y`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMaterialTexture {
    pub width: u32,
    pub height: u32,
    pub offset: u32,
    pub sampler: u32,
    pub table: u32,
    pub channel: u32,
    pub uv_u: [f32; 2],
    pub uv_v: [f32; 2],
    pub uv_offset: [f32; 2],
}

/// One material of a beauty scene, 576 bytes: `prismbake::render::beauty::SurfaceMaterial`,
/// its base-colour, roughness, metallic and normal textures (if any) located in the texel
/// buffer, its normal map's scale, bias and strength (`beauty::NormalTex`), its emission and
/// emission texture, its specular tint, and its clearcoat's weight and roughness, their
/// textures, and its normal map with that map's scale, bias and strength; and its alpha
/// (`render::cutout::AlphaCut`) with its texture, which every kernel's traversal reads.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMaterial {
    pub base_color: [f32; 3],
    pub roughness: f32,
    pub metallic: f32,
    pub specular: f32,
    pub color_tex: GpuMaterialTexture,
    pub roughness_tex: GpuMaterialTexture,
    pub metallic_tex: GpuMaterialTexture,
    pub normal_tex: GpuMaterialTexture,
    /// How far past a cut-away hit a ray goes on (`BeautyScene::eps`).
    pub alpha_eps: f32,
    pub _pad: u32,
    pub normal_scale: [f32; 3],
    /// `beauty::NormalTex::strength`.
    pub normal_strength: f32,
    pub normal_bias: [f32; 3],
    pub _pad2: u32,
    pub emission: [f32; 3],
    pub _pad3: u32,
    pub emission_tex: GpuMaterialTexture,
    pub specular_tint: [f32; 3],
    pub clearcoat: f32,
    pub clearcoat_roughness: f32,
    /// `render::cutout::AlphaCut`: the factor, the mode (`ALPHA_OPAQUE`, `ALPHA_MASK`,
    /// `ALPHA_BLEND`) and a mask's cutoff.
    pub alpha: f32,
    pub alpha_mode: u32,
    pub alpha_cutoff: f32,
    pub clearcoat_tex: GpuMaterialTexture,
    pub clearcoat_roughness_tex: GpuMaterialTexture,
    pub clearcoat_normal_tex: GpuMaterialTexture,
    pub clearcoat_normal_scale: [f32; 3],
    pub clearcoat_normal_strength: f32,
    pub clearcoat_normal_bias: [f32; 3],
    pub _pad8: u32,
    pub alpha_tex: GpuMaterialTexture,
}

/// `GpuMaterial::alpha_mode` codes (`shaders/material.wgsl`).
pub const ALPHA_OPAQUE: u32 = 0;
pub const ALPHA_MASK: u32 = 1;
pub const ALPHA_BLEND: u32 = 2;

/// A texture sampler as `GpuMaterialTexture::sampler` holds it: `wrapS`'s code in bits
/// 0–1, `wrapT`'s in bits 2–3 (`TexWrap::code`), nearest filtering in bit 4
/// (`shaders/texture.wgsl`; bit 5, a packed texture, is `beauty::TEX_PACKED`).
pub fn texture_sampler_code(s: &prismbake::texture::Sampler) -> u32 {
    s.wrap[0].code() | (s.wrap[1].code() << 2) | ((s.nearest as u32) << 4)
}

/// The GGX tables (`prismbake::render::ggx_tables`) as `shading.wgsl`'s `BsdfTables` uniform,
/// 20 608 bytes: four values a `vec4` (a uniform array's stride is 16 bytes), in the tables'
/// own order.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct GpuBsdfTables {
    pub e: [[f32; 4]; 256],
    pub e_avg: [[f32; 4]; 8],
    pub s: [[f32; 4]; 1024],
}

impl GpuBsdfTables {
    pub fn new() -> Box<GpuBsdfTables> {
        use prismbake::render::ggx_tables::{GGX_E, GGX_E_AVG, GGX_S};
        let mut t: Box<GpuBsdfTables> = bytemuck::zeroed_box();
        bytemuck::cast_slice_mut::<_, f32>(&mut t.e).copy_from_slice(&GGX_E);
        bytemuck::cast_slice_mut::<_, f32>(&mut t.e_avg).copy_from_slice(&GGX_E_AVG);
        bytemuck::cast_slice_mut::<_, f32>(&mut t.s).copy_from_slice(&GGX_S);
        t
    }
}

/// One pixel's running beauty sums as the kernel accumulates them over samples, 96 bytes:
/// `prismbake::render::beauty::PixelSums` plus the pixel's ray counts (`BeautyCounters`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuBeautySums {
    pub radiance: [f32; 3],
    pub surface: f32,
    pub background: [f32; 3],
    pub ground_samples: f32,
    pub ground_background: [f32; 3],
    pub ground_lit: f32,
    pub ground_unshadowed: f32,
    pub rays: u32,
    pub key_shadow_rays: u32,
    pub env_shadow_rays: u32,
    pub normal: [f32; 3],
    /// The pixel's preview, `beauty::preview_pixel`'s codes (red in the low byte), written by
    /// `tonemap.wgsl` after the tile's last sample.
    pub preview: u32,
    pub albedo: [f32; 3],
    pub _pad2: u32,
}

const _: () = {
    assert!(std::mem::size_of::<GpuPrism>() == 40);
    assert!(std::mem::size_of::<GpuPrismStitch>() == 88);
    assert!(std::mem::size_of::<GpuVertex>() == 32);
    assert!(std::mem::size_of::<GpuBvhNode>() == 32);
    assert!(std::mem::size_of::<GpuSceneParams>() == 32);
    assert!(std::mem::size_of::<GpuFrame>() == 128);
    assert!(std::mem::size_of::<GpuAovPixel>() == 48);
    assert!(std::mem::size_of::<GpuLighting>() == 1136);
    assert!(std::mem::size_of::<GpuLight>() == 64);
    assert!(std::mem::size_of::<GpuMaterialTexture>() == 48);
    assert!(std::mem::size_of::<GpuMaterial>() == 576);
    assert!(std::mem::size_of::<GpuBeautySums>() == 96);
    assert!(std::mem::size_of::<GpuBsdfTables>() == 20_608);
};

/// One shared struct as the layout test sees it: WGSL name, Rust size, `(member, offset)`s.
pub type StructLayout = (&'static str, usize, Vec<(&'static str, usize)>);

/// Every shared struct, in the form the layout test compares against naga's view of the WGSL.
pub fn shared_layouts() -> Vec<StructLayout> {
    macro_rules! layout {
        ($wgsl:literal, $ty:ty { $($field:ident),* $(,)? }) => {
            ($wgsl, std::mem::size_of::<$ty>(), vec![$((stringify!($field), std::mem::offset_of!($ty, $field))),*])
        };
    }
    vec![
        layout!(
            "Prism",
            GpuPrism {
                tri,
                flags,
                d_min,
                d_max,
                lambda_lo,
                lambda_hi,
                texel_world,
                stitch
            }
        ),
        layout!(
            "PrismStitch",
            GpuPrismStitch {
                other_uv,
                band,
                _pad
            }
        ),
        layout!(
            "Vertex",
            GpuVertex {
                position,
                u,
                normal,
                v
            }
        ),
        layout!(
            "BvhNode",
            GpuBvhNode {
                min,
                prim_count,
                max,
                first_index
            }
        ),
        layout!(
            "SceneParams",
            GpuSceneParams {
                map_width,
                map_height,
                wrap,
                node_count,
                disp_scale,
                disp_midlevel,
                prism_count,
                map_encoding
            }
        ),
        layout!(
            "Frame",
            GpuFrame {
                cam_from,
                tan_half_fov,
                cam_right,
                aspect,
                cam_up,
                width,
                cam_back,
                height,
                tile_origin,
                tile_size,
                spp,
                seed,
                dt_auto,
                dt_value,
                jitter,
                refine,
                normal_mode,
                sample_index,
                orthographic,
                _pad0,
                _pad1,
                _pad2
            }
        ),
        layout!(
            "AovPixel",
            GpuAovPixel {
                normal_sum,
                depth_sum,
                uv_sum,
                hits,
                steps_sum,
                prism,
                _pad
            }
        ),
        layout!(
            "Light",
            GpuLight {
                pos,
                kind,
                color,
                power,
                axis,
                size,
                cos_inner,
                cos_outer,
                _pad0,
                _pad1
            }
        ),
        layout!(
            "Lighting",
            GpuLighting {
                _pad0,
                _pad1,
                _pad2,
                _pad3,
                ground_up,
                ground_height,
                eps,
                bounces,
                light_count,
                has_ground,
                env_lights,
                env_z_up,
                env_width,
                env_height,
                env_total_weight,
                env_to_sin,
                env_to_cos,
                env_from_sin,
                env_from_cos,
                exposure,
                _pad4,
                tangent_offset,
                emissive,
                _pad5,
                _pad6,
                _pad7,
                lights
            }
        ),
        layout!(
            "MaterialTexture",
            GpuMaterialTexture {
                width,
                height,
                offset,
                sampler,
                table,
                channel,
                uv_u,
                uv_v,
                uv_offset
            }
        ),
        layout!(
            "SurfaceMaterial",
            GpuMaterial {
                base_color,
                roughness,
                metallic,
                specular,
                color_tex,
                roughness_tex,
                metallic_tex,
                normal_tex,
                alpha_eps,
                _pad,
                normal_scale,
                normal_strength,
                normal_bias,
                _pad2,
                emission,
                _pad3,
                emission_tex,
                specular_tint,
                clearcoat,
                clearcoat_roughness,
                alpha,
                alpha_mode,
                alpha_cutoff,
                clearcoat_tex,
                clearcoat_roughness_tex,
                clearcoat_normal_tex,
                clearcoat_normal_scale,
                clearcoat_normal_strength,
                clearcoat_normal_bias,
                _pad8,
                alpha_tex
            }
        ),
        layout!("BsdfTables", GpuBsdfTables { e, e_avg, s }),
        layout!(
            "BeautySums",
            GpuBeautySums {
                radiance,
                surface,
                background,
                ground_samples,
                ground_background,
                ground_lit,
                ground_unshadowed,
                rays,
                key_shadow_rays,
                env_shadow_rays,
                normal,
                preview,
                albedo,
                _pad2
            }
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::offset_of;

    #[test]
    fn sizes_and_offsets_match_the_wgsl_rules() {
        // vec3<f32> has 16-byte alignment in WGSL: a scalar after each vec3 fills its padding.
        // A reordering here without the same change in common.wgsl breaks this test.
        assert_eq!(offset_of!(GpuVertex, normal), 16);
        assert_eq!(offset_of!(GpuBvhNode, max), 16);
        assert_eq!(offset_of!(GpuFrame, cam_back), 48);
        assert_eq!(offset_of!(GpuFrame, tile_origin), 64);
        assert_eq!(offset_of!(GpuFrame, spp), 80);
        assert_eq!(offset_of!(GpuFrame, jitter), 96);
        assert_eq!(offset_of!(GpuFrame, orthographic), 112);
        assert_eq!(offset_of!(GpuAovPixel, uv_sum), 16);
        assert_eq!(offset_of!(GpuAovPixel, prism), 32);
        assert_eq!(offset_of!(GpuPrism, texel_world), 32);
        // vec2<f32> aligns to 8: the nested UV arrays pack at stride 8 and 24, and the struct
        // rounds up to 88.
        assert_eq!(offset_of!(GpuPrismStitch, band), 72);
        assert_eq!(offset_of!(GpuLighting, ground_up), 16);
        assert_eq!(offset_of!(GpuLighting, eps), 32);
        assert_eq!(offset_of!(GpuMaterial, color_tex), 24);
        // vec2<f32> aligns to 8: each texture record's transform and the records pack.
        assert_eq!(offset_of!(GpuMaterialTexture, uv_u), 24);
        assert_eq!(offset_of!(GpuMaterial, metallic_tex), 120);
        assert_eq!(offset_of!(GpuMaterial, normal_scale), 224);
        assert_eq!(offset_of!(GpuMaterial, normal_bias), 240);
        assert_eq!(offset_of!(GpuMaterial, emission_tex), 272);
        assert_eq!(offset_of!(GpuBeautySums, background), 16);
        assert_eq!(offset_of!(GpuBeautySums, ground_background), 32);
        assert_eq!(offset_of!(GpuBeautySums, ground_unshadowed), 48);
        assert_eq!(offset_of!(GpuBeautySums, normal), 64);
        assert_eq!(offset_of!(GpuBeautySums, albedo), 80);
    }

    /// Texel `(x, y)`, from its row's word `x / 2`'s half, decoded as heightmap.wgsl's
    /// `map_texel` does (`unorm16_texel`: the series of q / 65535 in powers of 2⁻¹⁶, two
    /// additions).
    fn decode(e: &EncodedMap, x: usize, y: usize) -> f32 {
        let row = y * e.row_words as usize;
        if e.encoding == MapEncoding::F32 {
            return f32::from_bits(e.words[row + x]);
        }
        let code = (e.words[row + x / 2] >> (16 * (x % 2))) & 0xffff;
        match e.encoding {
            MapEncoding::F32 => unreachable!(),
            MapEncoding::Unorm16 => {
                // The shader takes b and c from a's exponent bits: the same exact values.
                let a = code as f32 / 65536.0;
                let (b, c) = (a / 65536.0, a / 65536.0 / 65536.0);
                a + (b + c)
            }
            MapEncoding::F16 => {
                // IEEE half to f32 (normal or zero: the encoder admits no other).
                let sign = (code & 0x8000) << 16;
                let exp = (code >> 10) & 0x1f;
                let bits = match exp {
                    0 => sign,
                    _ => sign | ((exp + 127 - 15) << 23) | ((code & 0x3ff) << 13),
                };
                f32::from_bits(bits)
            }
        }
    }

    /// Encoded in rows of `width` texels and decoded again, texel by texel.
    fn round_trip_rows(data: &[f32], width: usize) -> MapEncoding {
        let e = encode_height_map(data, width as u32);
        for (i, v) in data.iter().enumerate() {
            assert_eq!(
                decode(&e, i % width, i / width).to_bits(),
                v.to_bits(),
                "texel {i} ({v}) as {:?}",
                e.encoding
            );
        }
        let rows = data.len().div_ceil(width.max(1));
        let words = match e.encoding {
            MapEncoding::F32 => data.len(),
            _ => rows * width.div_ceil(2),
        };
        assert_eq!(e.words.len(), words);
        e.encoding
    }

    fn round_trip(data: &[f32]) -> MapEncoding {
        round_trip_rows(data, data.len().max(1))
    }

    #[test]
    fn height_maps_are_packed_only_where_every_texel_comes_back_exactly() {
        // Every 16-bit code as the loader divides it, and every 8-bit one: unorm16.
        let all16: Vec<f32> = (0..=65535u32).map(|q| q as f32 / 65535.0).collect();
        assert_eq!(round_trip(&all16), MapEncoding::Unorm16);
        let all8: Vec<f32> = (0..=255u32).rev().map(|q| q as f32 / 255.0).collect();
        assert_eq!(round_trip(&all8), MapEncoding::Unorm16);
        // Halves (both signs, the extreme exponents, an odd count): f16.
        let halves = [
            0.5f32,
            -0.0,
            1.5,
            -2.75,
            65504.0,
            6.103_515_6e-5,
            -3.0e-2_f32,
        ];
        let halves: Vec<f32> = halves
            .iter()
            .map(|&v| {
                // Round to a half's 10 mantissa bits.
                f32::from_bits(v.to_bits() & !0x1fff)
            })
            .collect();
        assert_eq!(round_trip(&halves), MapEncoding::F16);
        // One texel that neither keeps (a 16-bit value off its code, a half subnormal, a
        // 24-bit mantissa) keeps the whole map in f32.
        for odd in [0.1f32 + 1e-6, 3.0e-6, 0.3] {
            let mut map = all8.clone();
            map.push(odd);
            assert_eq!(round_trip(&map), MapEncoding::F32, "{odd}");
        }
        assert_eq!(round_trip(&[-0.0, 0.25]), MapEncoding::F16);
        assert_eq!(round_trip(&[]), MapEncoding::Unorm16);
        // Rows of an odd width pack on their own: each row's last word holds one texel.
        let rows: Vec<f32> = (0..5 * 7)
            .map(|q| (q * 997 % 65536) as f32 / 65535.0)
            .collect();
        assert_eq!(round_trip_rows(&rows, 7), MapEncoding::Unorm16);
        assert_eq!(encode_height_map(&rows, 7).row_words, 4);
        assert_eq!(encode_height_map(&rows, 7).rows(), 5);
    }
}
