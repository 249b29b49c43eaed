// common.wgsl — structs shared with the host (gpu/src/layout.rs mirrors each one; the layout
// test compares member offsets and sizes through naga), sentinels, scene bindings and small
// helpers. The other stage files are appended to this one into a single module
// (gpu/src/shaders.rs), so every declaration here is visible to them.

// Sentinels, mirrored from the host (prismbake::trace::NO_PRISM, gpu::layout::{T_FAR,
// NO_STITCH}).
const NO_PRISM: u32 = 0xffffffffu;
// Prism::stitch of a prism without stitched seam edges: the raw height D(uv(b)).
const NO_STITCH: u32 = 0xffffffffu;
// Stands for +infinity: WGSL lets an implementation assume no infinities at run time.
const T_FAR: f32 = 3.0e38;
// prismbake::bake::{PRISM_FLAT, M_LO_FLOOR}.
const PRISM_FLAT: u32 = 1u;
const M_LO_FLOOR: f32 = 1e-3;
// Smallest normal length (glam's normalize_or_zero gives zero where 1/len is not finite).
const TINY_LEN: f32 = 1e-30;

// GpuPrism, 40 bytes.
struct Prism {
    tri: array<u32, 3>,
    flags: u32,
    d_min: f32,
    d_max: f32,
    lambda_lo: f32,
    lambda_hi: f32,
    texel_world: f32,
    stitch: u32,         // index into `stitches`, NO_STITCH: none
}

// GpuPrismStitch, 88 bytes: seam::PrismStitch without band_h (seam.wgsl).
struct PrismStitch {
    other_uv: array<array<vec2f, 3>, 3>,   // per edge k: the neighbour's chart
    band: array<f32, 3>,                   // per edge k: β_k, 0 = not stitched
    _pad: u32,
}

// GpuVertex, 32 bytes.
struct Vertex {
    position: vec3f,
    u: f32,
    normal: vec3f,
    v: f32,
}

// GpuBvhNode, 32 bytes (obvhs Bvh2Node with small_bvh2_node).
struct BvhNode {
    min: vec3f,
    prim_count: u32,
    max: vec3f,
    first_index: u32,
}

// GpuSceneParams, 32 bytes.
struct SceneParams {
    map_width: u32,
    map_height: u32,
    wrap: u32,           // 0 repeat, 1 clamp
    node_count: u32,
    disp_scale: f32,
    disp_midlevel: f32,
    prism_count: u32,
    map_encoding: u32,   // 0 f32, 1 unorm16, 2 f16 (MapEncoding)
}

// GpuFrame, 112 bytes.
struct Frame {
    cam_from: vec3f,
    tan_half_fov: f32,
    cam_right: vec3f,
    aspect: f32,
    cam_up: vec3f,
    width: u32,
    cam_back: vec3f,
    height: u32,
    tile_origin: vec2<u32>,
    tile_size: vec2<u32>,
    spp: u32,
    seed: u32,
    dt_auto: u32,        // 1: dt_value × texel size (StepSize::Auto); 0: world units
    dt_value: f32,
    jitter: u32,
    refine: u32,
    normal_mode: u32,    // 0 smooth, 1 geometric
    sample_index: u32,   // the one sample a dispatch renders
    orthographic: u32,   // 1: tan_half_fov is half the view's height (scene units), rays parallel
    _pad0: u32,          // (a uniform's arrays need a 16-byte stride)
    _pad1: u32,
    _pad2: u32,
}

// GpuAovPixel, 48 bytes: one pixel's AOV sums over the samples rendered so far.
struct AovPixel {
    normal_sum: vec3f,
    depth_sum: f32,
    uv_sum: vec2f,
    hits: f32,
    steps_sum: f32,
    prism: u32,          // prism id + 1 of the first hit, 0 = miss
    _pad: array<u32, 3>,
}

// GpuLight, 64 bytes: one light (render::lights::Light) and its pick's chance. kind 0
// directional (pos: the unit direction towards it; size: cos of its disc's radius), 1 point or
// sphere (pos: its centre; size: its radius), 2 spot (also axis, cos_inner, cos_outer), 3
// rectangle and 4 disk (pos: its centre; axis: its u; size, cos_inner, cos_outer: its v).
struct Light {
    pos: vec3f,
    kind: u32,
    color: vec3f,        // of unit luminance
    power: f32,          // irradiance (directional) or intensity (local), luminance
    axis: vec3f,
    size: f32,
    cos_inner: f32,
    cos_outer: f32,
    _pad0: f32,
    _pad1: f32,
}

// lights::CHANCE_FLOOR: the share of an even chance every light keeps at any point.
const CHANCE_FLOOR: f32 = 0.05;

// GpuLighting, 1136 bytes: everything beauty needs besides the scene, the materials and the
// environment tables (render::beauty::BeautyScene).
struct Lighting {
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    _pad3: u32,
    ground_up: vec3f,
    ground_height: f32,
    eps: f32,            // ray origin offset (beauty::scene_epsilon)
    bounces: u32,
    light_count: u32,    // lights used in `lights` (0: no light samples)
    has_ground: u32,
    env_lights: u32,     // 0: black environment, no environment rays
    env_z_up: u32,
    env_width: u32,
    env_height: u32,
    env_total_weight: f32,
    env_to_sin: f32,     // sin, cos of −rotation (world_to_env)
    env_to_cos: f32,
    env_from_sin: f32,   // sin, cos of +rotation (env_to_world)
    env_from_cos: f32,
    exposure: f32,       // the preview's exposure factor (tonemap.wgsl)
    _pad4: u32,
    tangent_offset: u32, // the prisms' corner tangents in texture_texels (12 floats a prism)
    emissive: u32,       // 1: some material glows (BeautyScene::emissive)
    _pad5: u32,
    _pad6: u32,
    _pad7: u32,
    lights: array<Light, 16>, // render::lights::MAX_LIGHTS
}

// GpuMaterialTexture, 48 bytes: one texture of a material in texture_texels (texture.wgsl;
// 0 x 0: none).
struct MaterialTexture {
    width: u32,
    height: u32,
    offset: u32,    // its first float in texture_texels
    sampler: u32,   // gpu::layout::texture_sampler_code; bit 5: packed (beauty::TEX_PACKED)
    table: u32,     // a packed texture's 8-bit code table, its first float in texture_texels
    channel: u32,   // the channel a roughness or metallic texture is read from
    uv_u: vec2f,    // texture::UvTransform: u' = dot(uv_u, uv) + uv_offset.x
    uv_v: vec2f,    //                       v' = dot(uv_v, uv) + uv_offset.y
    uv_offset: vec2f,
}

// GpuMaterial, 576 bytes: beauty::SurfaceMaterial, its base-colour, roughness, metallic and
// normal textures, its normal map's scale, bias and strength (beauty::NormalTex), its
// emission and emission texture, its specular tint, and its clearcoat's weight and roughness,
// their textures, and its normal map with that map's scale, bias and strength; and its alpha
// (render::cutout::AlphaCut) with its texture.
struct SurfaceMaterial {
    base_color: vec3f,
    roughness: f32,
    metallic: f32,
    specular: f32,
    color_tex: MaterialTexture,
    roughness_tex: MaterialTexture,
    metallic_tex: MaterialTexture,
    normal_tex: MaterialTexture,
    // How far past a cut-away hit a ray goes on (the scene's epsilon, beauty::scene_epsilon).
    alpha_eps: f32,
    _pad: u32,
    normal_scale: vec3f,
    normal_strength: f32,
    normal_bias: vec3f,
    _pad2: u32,
    emission: vec3f,
    _pad3: u32,
    emission_tex: MaterialTexture,
    specular_tint: vec3f,
    clearcoat: f32,
    clearcoat_roughness: f32,
    // The alpha (render::cutout::AlphaCut): its factor, mode (ALPHA_*) and mask cutoff.
    alpha: f32,
    alpha_mode: u32,
    alpha_cutoff: f32,
    clearcoat_tex: MaterialTexture,
    clearcoat_roughness_tex: MaterialTexture,
    clearcoat_normal_tex: MaterialTexture,
    clearcoat_normal_scale: vec3f,
    clearcoat_normal_strength: f32,
    clearcoat_normal_bias: vec3f,
    _pad8: u32,
    alpha_tex: MaterialTexture,
}

// GpuBeautySums, 96 bytes: beauty::PixelSums of one pixel plus its ray counts.
struct BeautySums {
    radiance: vec3f,
    surface: f32,
    background: vec3f,
    ground_samples: f32,
    ground_background: vec3f,
    ground_lit: f32,
    ground_unshadowed: f32,
    rays: u32,
    key_shadow_rays: u32,
    env_shadow_rays: u32,
    normal: vec3f,
    preview: u32,        // tonemap_preview's 8-bit sRGB codes (red low), after the last sample
    albedo: vec3f,
    _pad2: u32,
}

// Group 0: the scene (GpuScene), shared by every kernel.
@group(0) @binding(0) var<uniform> scene: SceneParams;
@group(0) @binding(1) var<storage, read> prisms: array<Prism>;
@group(0) @binding(2) var<storage, read> vertices: array<Vertex>;
@group(0) @binding(3) var<storage, read> nodes: array<BvhNode>;
@group(0) @binding(4) var<storage, read> prim_indices: array<u32>;
// The map's words (layout::EncodedMap), a row of the texture a row of the map.
@group(0) @binding(5) var height_map: texture_2d<u32>;
@group(0) @binding(6) var<storage, read> stitches: array<PrismStitch>;

// prismbake::trace::Ray.
struct Ray {
    origin: vec3f,
    dir: vec3f,
    t_min: f32,
    t_max: f32,
}

fn ray_at(ray: Ray, t: f32) -> vec3f {
    return ray.origin + ray.dir * t;
}

// prismbake::trace::RayContext.
struct RayContext {
    pixel: u32,
    sample: u32,
    bounce: u32,
    seed: u32,
}

// prismbake::trace::Hit.
struct Hit {
    t: f32,
    prism: u32,
    bary: vec3f,
    uv: vec2f,
    position: vec3f,
    geometric_normal: vec3f,
    shading_normal: vec3f,
    steps: u32,
}

fn no_hit() -> Hit {
    return Hit(T_FAR, NO_PRISM, vec3f(0.0), vec2f(0.0), vec3f(0.0), vec3f(0.0), vec3f(0.0), 0u);
}

// glam's normalize_or_zero.
fn normalize_or_zero(v: vec3f) -> vec3f {
    let len = length(v);
    if (len > TINY_LEN) {
        return v * (1.0 / len);
    }
    return vec3f(0.0);
}

fn min_element(v: vec3f) -> f32 {
    return min(min(v.x, v.y), v.z);
}

// Solve J x = f for a 3×3 J given by its columns, as glam's `Mat3::inverse() * f` does it
// (adjugate from column cross products, times 1/det). `ok` is false for |det| < 1e-30.
struct Solve3 {
    ok: bool,
    x: vec3f,
}

fn solve3(c0: vec3f, c1: vec3f, c2: vec3f, f: vec3f) -> Solve3 {
    let t0 = cross(c1, c2);
    let t1 = cross(c2, c0);
    let t2 = cross(c0, c1);
    let det = dot(c2, t2);
    if (abs(det) < 1e-30) {
        return Solve3(false, vec3f(0.0));
    }
    let inv_det = 1.0 / det;
    // inverse = transpose(cols(t0, t1, t2)) / det, so (inverse * f)_k = t_k · f / det.
    return Solve3(true, vec3f(dot(t0, f), dot(t1, f), dot(t2, f)) * inv_det);
}

// f32::is_finite by the exponent bits: GPU compilers may assume that no NaN or infinity occurs
// (Vulkan without SignedZeroInfNanPreserve) and fold a float comparison such as
// `abs(x) <= MAX` to true; an integer test cannot be folded away.
fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

// i32::rem_euclid for n > 0 with one integer remainder (`((x % n) + n) % n` takes two). SIMD
// units have no integer division: lavapipe divides lane by lane, so per height sample the
// remainders cost more than the rest of the bilinear lookup (docs/gpu.md). The remainder is
// taken of non-negative operands only: GLSL leaves `%` of a negative operand undefined, and
// on wgpu's GL backend (Mesa's llvmpipe through OpenGL) `x % n` of a negative `x` read the
// wrong texel (x < 0 maps to n − 1 − ((−1 − x) mod n)).
fn wrap_repeat(x: i32, n: i32) -> i32 {
    let negative = x < 0;
    let r = select(x, -1 - x, negative) % n;
    return select(r, n - 1 - r, negative);
}
