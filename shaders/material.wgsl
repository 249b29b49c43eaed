// material.wgsl — the materials' records and their textures, read by every kernel: the
// mirror of core/src/texture.rs (`ColorMap`) and of core/src/render/cutout.rs (a material's
// alpha, which the traversals ask before they keep a hit). A texture is linear RGB, 3 floats
// per texel, or (packed) one word of 8-bit codes per texel and the CPU's table of their
// values, sRGB or raw (gpu::beauty::TextureLayout), rows top to bottom, stored in
// `texture_texels` (from its `offset`), sampled with the height map's texel conventions and
// the sampler's wrap modes and magnification filter (`sampler`,
// gpu::layout::texture_sampler_code). The beauty binds them in its lighting group, the AOV
// kernels in a group of their own (gpu::scene::GpuScene's cut-out group).

// The scene's materials (BeautyScene::materials): a prism's is its flags' upper bits
// (bake::PRISM_MATERIAL_SHIFT), the last one for an index past the end.
@group(2) @binding(3) var<storage, read> materials: array<SurfaceMaterial>;

// The material textures' texels as gpu::beauty::TextureLayout lays them out.
@group(2) @binding(1) var<storage, read> texture_texels: array<f32>;

const PRISM_MATERIAL_SHIFT: u32 = 8u;

// MaterialTexture::sampler's bit for a packed texture (gpu::beauty::TEX_PACKED).
const TEX_PACKED: u32 = 32u;

// TexWrap codes.
const WRAP_REPEAT: u32 = 0u;
const WRAP_CLAMP: u32 = 1u;

// TexWrap::index: texel index `i` of an axis of `n` texels, wrapped into 0..n (remainders of
// non-negative operands only: `wrap_repeat`, common.wgsl).
fn wrap_index(i: i32, n: i32, mode: u32) -> i32 {
    if (mode == WRAP_REPEAT) {
        return wrap_repeat(i, n);
    }
    if (mode == WRAP_CLAMP) {
        return clamp(i, 0, n - 1);
    }
    // Mirrored repeat.
    let m = wrap_repeat(i, 2 * n);
    return select(m, 2 * n - 1 - m, m >= n);
}

// ColorMap::texel of texture `m`.
fn tex_texel(m: MaterialTexture, x: i32, y: i32) -> vec3f {
    let w = i32(m.width);
    let h = i32(m.height);
    let code = m.sampler;
    let i = u32(wrap_index(y, h, (code >> 2u) & 3u) * w + wrap_index(x, w, code & 3u));
    if ((code & TEX_PACKED) != 0u) {
        // One word a texel: its 8-bit codes, looked up in the CPU's table.
        let word = bitcast<u32>(texture_texels[m.offset + i]);
        let t = m.table;
        return vec3f(
            texture_texels[t + (word & 0xffu)],
            texture_texels[t + ((word >> 8u) & 0xffu)],
            texture_texels[t + ((word >> 16u) & 0xffu)],
        );
    }
    let k = m.offset + 3u * i;
    return vec3f(texture_texels[k], texture_texels[k + 1u], texture_texels[k + 2u]);
}

// ColorMap::sample of texture `m` (its UV transform applied, UvTransform::apply): bilinear
// over the four nearest texel centres, or the nearest texel.
fn texture_sample(m: MaterialTexture, uv_in: vec2f) -> vec3f {
    let uv = vec2f(
        m.uv_u.x * uv_in.x + m.uv_u.y * uv_in.y + m.uv_offset.x,
        m.uv_v.x * uv_in.x + m.uv_v.y * uv_in.y + m.uv_offset.y,
    );
    // Non-finite coordinates become 0 and huge ones are bounded before they become integers
    // (`texel_safe`, heightmap.wgsl).
    let p = vec2f(
        texel_safe(uv.x * f32(m.width)),
        texel_safe((1.0 - uv.y) * f32(m.height)),
    );
    if ((m.sampler & 16u) != 0u) {
        let f = floor(p);
        return tex_texel(m, i32(f.x), i32(f.y));
    }
    let q = p - vec2f(0.5);
    let f = floor(q);
    let t = q - f;
    let x = i32(f.x);
    let y = i32(f.y);
    let top = lerp3(tex_texel(m, x, y), tex_texel(m, x + 1, y), t.x);
    let bottom = lerp3(tex_texel(m, x, y + 1), tex_texel(m, x + 1, y + 1), t.x);
    return lerp3(top, bottom, t.y);
}

// BeautyScene::material_index: the index into `materials` of prism `prism`'s material.
fn material_index(prism: u32) -> u32 {
    let last = arrayLength(&materials) - 1u;
    if (prism >= arrayLength(&prisms)) {
        return last;
    }
    return min(prisms[prism].flags >> PRISM_MATERIAL_SHIFT, last);
}

// glam's Vec3::lerp.
fn lerp3(a: vec3f, b: vec3f, s: f32) -> vec3f {
    return a * (1.0 - s) + b * s;
}

// mesh::AlphaMode as SurfaceMaterial::alpha_mode holds it.
const ALPHA_OPAQUE: u32 = 0u;
const ALPHA_MASK: u32 = 1u;

// Cutout's limit on the surfaces one prism may let a ray through (render::cutout::MAX_CUTS).
const MAX_CUTS: u32 = 64u;

// AlphaCut::coverage of material `mi` at `uv`: the probability that its surface is there
// (its fields read one by one: a traversal asks this for every prism hit).
fn alpha_coverage(mi: u32, uv: vec2f) -> f32 {
    var a = materials[mi].alpha;
    if (materials[mi].alpha_tex.width != 0u) {
        let t = materials[mi].alpha_tex;
        a *= texture_sample(t, uv)[min(t.channel, 2u)];
    }
    if (materials[mi].alpha_mode == ALPHA_MASK) {
        return select(0.0, 1.0, a >= materials[mi].alpha_cutoff);
    }
    // A NaN alpha: not there.
    return select(clamp(a, 0.0, 1.0), 0.0, a != a);
}

// Cutout::keeps: whether the surface of material `mi` is there at hit `h` of the ray of `ctx`
// (a record of intersect_prism's, whose uv is not filled yet: the canonical surface's is
// found from its barycentrics where a texture reads it, as fill_surface finds it).
fn alpha_keeps(mi: u32, h: Hit, ctx: RayContext) -> bool {
    var uv = vec2f(0.0);
    if (materials[mi].alpha_tex.width != 0u) {
        uv = geom_uv(prism_geom(prisms[h.prism]), h.bary);
    }
    let c = alpha_coverage(mi, uv);
    let u = random_keyed(ctx.pixel, ctx.sample, ctx.bounce, PURPOSE_ALPHA, ctx.seed, h.prism);
    return c >= 1.0 || (c > 0.0 && u < c);
}

// intersect_prism less what the prism's material's alpha cuts away (Cutout::intersect, one
// prism at a time): its first hit the alpha keeps, the march going on from just past each
// one it does not (one call site: Mesa inlines each). An opaque material's costs one read.
fn intersect_prism_kept(ray: Ray, ctx: RayContext, prism: u32, steps: ptr<function, u32>)
    -> Hit {
    let mi = material_index(prism);
    let opaque = materials[mi].alpha_mode == ALPHA_OPAQUE;
    var r = ray;
    var found = no_hit();
    for (var k = 0u; k < MAX_CUTS; k++) {
        let h = intersect_prism(r, ctx, prism, steps);
        if (h.prism == NO_PRISM || opaque || alpha_keeps(mi, h, ctx)) {
            found = h;
            break;
        }
        r.t_min = max(h.t, r.t_min) + materials[mi].alpha_eps;
        if (!(r.t_min < r.t_max)) {
            break;
        }
    }
    return found;
}
