// env.wgsl — the environment light, the mirror of core/src/render/env.rs: an equirect radiance
// map rotated about the asset's up axis, read nearest-texel for lighting (`env_radiance`) and
// bilinearly for the camera's background (`env_radiance_smooth`), importance sampled with the
// CPU's own tables (`EnvMap::{marginal_cdf, conditional_cdf, row_weight, texel_weight}`,
// uploaded value for value: gpu/src/beauty.rs), so that `env_sample` picks the texel the CPU
// picks.
//
// The rotation's sine and cosine come from the host, computed as the CPU computes them
// (`(-rotation).sin_cos()` one way, `rotation.sin_cos()` the other).

// The environment goes up in three textures, so that its size is bounded by the device's
// largest texture side, not by one storage binding (128 MiB on lavapipe: a 4K × 2K map, where
// a 6K or 8K one is what a lookdev artist lights with). Texel (x, y), rows top (zenith) to
// bottom: `env_radiance_map` holds the radiance × intensity in rgb and the CPU's
// `texel_weight[y w + x]` in a; `env_conditional` holds `conditional_cdf[y (w + 1) + x + 1]`
// (a row's first entry is 0, which is never stored); texel (y, 0) of `env_rows` holds
// `marginal_cdf[y + 1]` (its first entry is 0 too) and `row_weight[y]`. rgba32float, r32float
// and rg32float, read with textureLoad: the CPU's floats bit for bit.
@group(2) @binding(4) var env_radiance_map: texture_2d<f32>;
@group(2) @binding(5) var env_conditional: texture_2d<f32>;
@group(2) @binding(2) var env_rows: texture_2d<f32>;

const FRAC_1_PI: f32 = 0.318309886183790671538;

// marginal_cdf, entry i in 0..=h.
fn env_marginal_cdf(i: u32) -> f32 {
    if (i == 0u) {
        return 0.0;
    }
    return textureLoad(env_rows, vec2<u32>(i - 1u, 0u), 0).x;
}

fn env_row_weight(y: u32) -> f32 {
    return textureLoad(env_rows, vec2<u32>(y, 0u), 0).y;
}

// conditional_cdf of row y, entry i in 0..=w.
fn env_conditional_cdf(y: u32, i: u32) -> f32 {
    if (i == 0u) {
        return 0.0;
    }
    return textureLoad(env_conditional, vec2<u32>(i - 1u, y), 0).x;
}

fn env_texel_weight(x: u32, y: u32) -> f32 {
    return textureLoad(env_radiance_map, vec2<u32>(x, y), 0).w;
}

fn env_texel(x: u32, y: u32) -> vec3f {
    return textureLoad(env_radiance_map, vec2<u32>(x, y), 0).xyz;
}

// env::world_to_env.
fn world_to_env(d: vec3f) -> vec3f {
    var v = d;
    if (lighting.env_z_up != 0u) {
        v = vec3f(d.x, d.z, -d.y);
    }
    let s = lighting.env_to_sin;
    let c = lighting.env_to_cos;
    return vec3f(c * v.x + s * v.z, v.y, -s * v.x + c * v.z);
}

// env::env_to_world.
fn env_to_world(d: vec3f) -> vec3f {
    let s = lighting.env_from_sin;
    let c = lighting.env_from_cos;
    let v = vec3f(c * d.x + s * d.z, d.y, -s * d.x + c * d.z);
    if (lighting.env_z_up != 0u) {
        return vec3f(v.x, -v.z, v.y);
    }
    return v;
}

// env::env_dir_to_uv.
fn env_dir_to_uv(d: vec3f) -> vec2f {
    let u = 0.5 + atan2(d.z, d.x) * (0.5 * FRAC_1_PI);
    let v = acos(clamp(d.y, -1.0, 1.0)) * FRAC_1_PI;
    return vec2f(u, v);
}

// env::env_uv_to_dir.
fn env_uv_to_dir(uv: vec2f) -> vec3f {
    let phi = (uv.x - 0.5) * 2.0 * PI;
    let theta = uv.y * PI;
    return vec3f(sin(theta) * cos(phi), cos(theta), sin(theta) * sin(phi));
}

// A finite texel coordinate for i32(): NaN → 0 (Rust's `as i64`), huge values clamped
// (an out-of-range f32→i32 conversion is undefined in SPIR-V; see heightmap.wgsl).
fn env_coord(x: f32) -> i32 {
    if (!finite(x)) {
        return 0;
    }
    return i32(clamp(x, -1.0e7, 1.0e7));
}

// env::texel_index: nearest texel, u wraps, v clamps.
fn texel_index(uv: vec2f) -> vec2<u32> {
    let w = i32(lighting.env_width);
    let h = i32(lighting.env_height);
    let x = wrap_repeat(env_coord(uv.x * f32(lighting.env_width)), w);
    let y = clamp(env_coord(uv.y * f32(lighting.env_height)), 0, h - 1);
    return vec2<u32>(u32(x), u32(y));
}

// env::env_radiance: radiance from world direction d (nearest texel; what lighting uses).
fn env_radiance(d: vec3f) -> vec3f {
    let xy = texel_index(env_dir_to_uv(world_to_env(d)));
    return env_texel(xy.x, xy.y);
}

fn env_texel_wrapped(x: i32, y: i32) -> vec3f {
    let w = i32(lighting.env_width);
    let xx = wrap_repeat(x, w);
    let yy = clamp(y, 0, i32(lighting.env_height) - 1);
    return env_texel(u32(xx), u32(yy));
}

// env::env_radiance_smooth: the camera's view of the environment (bilinear).
fn env_radiance_smooth(d: vec3f) -> vec3f {
    let uv = env_dir_to_uv(world_to_env(d));
    let p = uv * vec2f(f32(lighting.env_width), f32(lighting.env_height)) - 0.5;
    let x0 = floor(p.x);
    let y0 = floor(p.y);
    let fx = p.x - x0;
    let fy = p.y - y0;
    let xi = env_coord(x0);
    let yi = env_coord(y0);
    let top = lerp3(env_texel_wrapped(xi, yi), env_texel_wrapped(xi + 1, yi), fx);
    let bottom = lerp3(env_texel_wrapped(xi, yi + 1), env_texel_wrapped(xi + 1, yi + 1), fx);
    return lerp3(top, bottom, fy);
}

// env::find_interval over `len` entries of a cdf: the last i with cdf[i] <= u. Row `y` of
// the conditional cdf, or the marginal cdf where `y` is MARGINAL.
const MARGINAL: u32 = 0xffffffffu;

fn cdf_entry(y: u32, i: u32) -> f32 {
    if (y == MARGINAL) {
        return env_marginal_cdf(i);
    }
    return env_conditional_cdf(y, i);
}

fn find_interval(y: u32, len: u32, u: f32) -> u32 {
    var lo = 0u;
    var hi = len - 1u;
    loop {
        if (hi - lo <= 1u) {
            break;
        }
        let mid = (lo + hi) / 2u;
        if (cdf_entry(y, mid) <= u) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

// env::EnvSample.
struct EnvSample {
    dir: vec3f,
    pdf: f32,
}

// env::env_sample: a direction with density ∝ luminance × sin θ.
fn env_sample(u: vec2f) -> EnvSample {
    let w = lighting.env_width;
    let h = lighting.env_height;
    let y = min(find_interval(MARGINAL, h + 1u, u.y), h - 1u);
    let c0 = env_marginal_cdf(y);
    let c1 = env_marginal_cdf(y + 1u);
    var fy = 0.5;
    if (c1 > c0) {
        fy = clamp((u.y - c0) / (c1 - c0), 0.0, 1.0);
    }
    let x = min(find_interval(y, w + 1u, u.x), w - 1u);
    let r0 = env_conditional_cdf(y, x);
    let r1 = env_conditional_cdf(y, x + 1u);
    var fx = 0.5;
    if (r1 > r0) {
        fx = clamp((u.x - r0) / (r1 - r0), 0.0, 1.0);
    }
    let uv = vec2f((f32(x) + fx) / f32(w), (f32(y) + fy) / f32(h));
    let dir = env_to_world(env_uv_to_dir(uv));
    return EnvSample(dir, env_pdf(dir));
}

// env::pdf_of_texel.
fn pdf_of_texel(x: u32, y: u32, v: f32) -> f32 {
    let sin_theta = sin(v * PI);
    if (sin_theta <= 0.0 || lighting.env_total_weight <= 0.0) {
        return 0.0;
    }
    let p_uv = env_row_weight(y) * f32(lighting.env_height) * env_texel_weight(x, y) * f32(lighting.env_width);
    return p_uv / (2.0 * PI * PI * sin_theta);
}

// env::env_pdf: solid-angle density of env_sample producing world direction d.
fn env_pdf(d: vec3f) -> f32 {
    let uv = env_dir_to_uv(world_to_env(d));
    let xy = texel_index(uv);
    return pdf_of_texel(xy.x, xy.y, uv.y);
}
