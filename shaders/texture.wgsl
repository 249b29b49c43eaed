// texture.wgsl — the materials as the beauty shades them: the mirror of
// `BeautyScene::material_at`, `emission_at` and `shade_hit`, and of core/src/tangent.rs
// (`frame_at`). The materials' records and their textures' sampling are material.wgsl's.

// BeautyScene::material_at: the material at a hit on prism `prism` with texture coordinates
// `uv`: its prism's, the base colour times the texture at `uv`, the roughness and metallic
// times their texture channels there (one lookup where both read the same texture), and the
// clearcoat's weight and roughness times theirs (the same).
fn material_at(prism: u32, uv: vec2f) -> Material {
    let s = materials[material_index(prism)];
    var m = Material(s.base_color, s.roughness, s.metallic, s.specular, s.specular_tint,
        s.clearcoat, s.clearcoat_roughness);
    if (s.color_tex.width != 0u) {
        m.base_color *= texture_sample(s.color_tex, uv);
    }
    let rm = channel_pair(s.roughness_tex, s.metallic_tex, uv);
    m.roughness *= rm.x;
    m.metallic *= rm.y;
    let coat = channel_pair(s.clearcoat_tex, s.clearcoat_roughness_tex, uv);
    m.clearcoat *= coat.x;
    m.clearcoat_roughness *= coat.y;
    return m;
}

// BeautyScene::channel_pair: two texture channels at `uv` (1 where absent), one lookup where
// both read the same texture.
fn channel_pair(a: MaterialTexture, b: MaterialTexture, uv: vec2f) -> vec2f {
    var out = vec2f(1.0);
    var first = vec3f(1.0);
    let has_a = a.width != 0u;
    if (has_a) {
        first = texture_sample(a, uv);
        out.x = first[min(a.channel, 2u)];
    }
    if (b.width != 0u) {
        var v = first;
        if (!has_a || b.offset != a.offset) {
            v = texture_sample(b, uv);
        }
        out.y = v[min(b.channel, 2u)];
    }
    return out;
}

// BeautyScene::emission_at: the radiance the surface of prism `prism` emits at `uv` towards
// -dir, under what its clearcoat lets through at that angle (about `coat_normal`, the hit's
// clearcoat_normal, turned by facing_normals with `geometric`).
fn emission_at(prism: u32, uv: vec2f, geometric: vec3f, coat_normal: vec3f, dir: vec3f) -> vec3f {
    let s = materials[material_index(prism)];
    var glow = s.emission;
    if (s.emission_tex.width != 0u) {
        glow = s.emission * texture_sample(s.emission_tex, uv);
    }
    if (s.clearcoat <= 0.0 || all(glow == vec3f(0.0))) {
        return glow;
    }
    let mu = dot(facing_normals(geometric, coat_normal, dir).ns, -dir);
    return glow * clearcoat_through(material_at(prism, uv), mu);
}

// The tangent of corner `k` of prism `prism` (tangent::corner_tangents: xyz and the
// bitangent's sign), from texture_texels at lighting.tangent_offset.
fn corner_tangent(prism: u32, k: u32) -> vec4f {
    let i = lighting.tangent_offset + (prism * 3u + k) * 4u;
    return vec4f(texture_texels[i], texture_texels[i + 1u], texture_texels[i + 2u],
        texture_texels[i + 3u]);
}

// BeautyScene::bent_normal: the normal the normal map `tex` gives at the hit (texel times
// `scale` plus `bias`, in the tangent frame of the base mesh: its interpolated normal, on the
// shading normal's side, and tangent::frame_at's tangent about it, as Cycles reads the
// undisplaced normal), blended with the hit's shading normal by `strength` where it is not
// 1; the zero vector where the frame or the mapped normal degenerates.
fn bent_normal(hit: Hit, tex: MaterialTexture, scale: vec3f, bias: vec3f, strength: f32)
    -> vec3f {
    let b = hit.bary;
    let t4 = corner_tangent(hit.prism, 0u) * b.x + corner_tangent(hit.prism, 1u) * b.y
        + corner_tangent(hit.prism, 2u) * b.z;
    let tri = prisms[hit.prism].tri;
    var n = normalize_or_zero(vertices[tri[0]].normal * b.x + vertices[tri[1]].normal * b.y
        + vertices[tri[2]].normal * b.z);
    if (dot(n, hit.shading_normal) < 0.0) {
        n = -n;
    }
    if (all(n == vec3f(0.0))) {
        return vec3f(0.0);
    }
    let t = normalize_or_zero(t4.xyz - n * dot(n, t4.xyz));
    if (all(t == vec3f(0.0))) {
        return vec3f(0.0);
    }
    let bt = cross(n, t) * select(1.0, -1.0, t4.w < 0.0);
    let c = texture_sample(tex, hit.uv) * scale + bias;
    let mapped = normalize_or_zero(t * c.x + bt * c.y + n * c.z);
    if (strength == 1.0 || all(mapped == vec3f(0.0))) {
        return mapped;
    }
    let s = hit.shading_normal;
    return normalize_or_zero(s + (mapped - s) * strength);
}

// BeautyScene::shade_hit: the hit's shading normal bent by its material's normal map, left as
// it is where that degenerates.
fn shade_hit(found: Hit) -> Hit {
    var hit = found;
    // One word read where the material has no normal map (most hits, every scene without).
    let mi = material_index(hit.prism);
    if (materials[mi].normal_tex.width == 0u || hit.prism >= arrayLength(&prisms)) {
        return hit;
    }
    let s = materials[mi];
    let mapped = bent_normal(hit, s.normal_tex, s.normal_scale, s.normal_bias,
        s.normal_strength);
    if (any(mapped != vec3f(0.0))) {
        hit.shading_normal = mapped;
    }
    return hit;
}

// BeautyScene::clearcoat_normal: the normal a hit's clearcoat lies on (the hit as traversal
// found it): its shading normal bent by the material's clearcoat normal map, if any.
fn clearcoat_normal(hit: Hit) -> vec3f {
    let mi = material_index(hit.prism);
    if (materials[mi].clearcoat_normal_tex.width == 0u || hit.prism >= arrayLength(&prisms)) {
        return hit.shading_normal;
    }
    let s = materials[mi];
    let mapped = bent_normal(hit, s.clearcoat_normal_tex, s.clearcoat_normal_scale,
        s.clearcoat_normal_bias, s.clearcoat_normal_strength);
    if (any(mapped != vec3f(0.0))) {
        return mapped;
    }
    return hit.shading_normal;
}
