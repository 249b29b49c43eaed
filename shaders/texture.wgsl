// texture.wgsl — the materials and their base-colour textures, the mirror of
// core/src/texture.rs (`ColorMap`) and of `BeautyScene::material_at`. A texture is linear RGB,
// 3 floats per texel, or (packed) one word of 8-bit sRGB codes per texel and the CPU's table of
// their linear values (gpu::beauty::TextureLayout), rows top to bottom, stored in
// `texture_texels` (from its material's `tex_offset`), sampled with the height
// map's texel conventions and the glTF sampler's wrap modes and magnification filter
// (`tex_sampler`, gpu::layout::texture_sampler_code).

// The scene's materials (BeautyScene::materials): a prism's is its flags' upper bits
// (bake::PRISM_MATERIAL_SHIFT), the last one for an index past the end.
@group(2) @binding(3) var<storage, read> materials: array<SurfaceMaterial>;

// The base-colour textures' texels as gpu::beauty::TextureLayout lays them out.
@group(2) @binding(1) var<storage, read> texture_texels: array<f32>;

const PRISM_MATERIAL_SHIFT: u32 = 8u;

// GpuMaterial::tex_sampler's bit for a packed texture (gpu::beauty::TEX_PACKED).
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

// ColorMap::texel of material `m`'s texture.
fn tex_texel(m: SurfaceMaterial, x: i32, y: i32) -> vec3f {
    let w = i32(m.tex_width);
    let h = i32(m.tex_height);
    let code = m.tex_sampler;
    let i = u32(wrap_index(y, h, (code >> 2u) & 3u) * w + wrap_index(x, w, code & 3u));
    if ((code & TEX_PACKED) != 0u) {
        // One word a texel: its 8-bit sRGB codes, looked up in the CPU's table.
        let word = bitcast<u32>(texture_texels[m.tex_offset + i]);
        let t = m.tex_table;
        return vec3f(
            texture_texels[t + (word & 0xffu)],
            texture_texels[t + ((word >> 8u) & 0xffu)],
            texture_texels[t + ((word >> 16u) & 0xffu)],
        );
    }
    let k = m.tex_offset + 3u * i;
    return vec3f(texture_texels[k], texture_texels[k + 1u], texture_texels[k + 2u]);
}

// ColorMap::sample of material `m`'s texture: bilinear over the four nearest texel centres,
// or the nearest texel.
fn texture_sample(m: SurfaceMaterial, uv: vec2f) -> vec3f {
    // Non-finite coordinates become 0 and huge ones are bounded before they become integers
    // (`texel_safe`, heightmap.wgsl).
    let p = vec2f(
        texel_safe(uv.x * f32(m.tex_width)),
        texel_safe((1.0 - uv.y) * f32(m.tex_height)),
    );
    if ((m.tex_sampler & 16u) != 0u) {
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

// BeautyScene::material_at: the material at a hit on prism `prism` with texture coordinates
// `uv`: its prism's, the base colour times the texture at `uv`.
fn material_at(prism: u32, uv: vec2f) -> Material {
    let s = materials[material_index(prism)];
    var m = Material(s.base_color, s.roughness, s.metallic, s.specular);
    if (s.tex_width != 0u) {
        m.base_color *= texture_sample(s, uv);
    }
    return m;
}
