// heightmap.wgsl — the mirror of prismbake::heightmap::HeightMap: bilinear sampling with
// texel centres at (i + 0.5) / N, row 0 at the top (v up), repeat or clamp wrap, its words read
// with textureLoad from an r32uint texture (no filtering, no conversion) so every texel and
// weight is the CPU's.

// The 16-bit code q's texel q / 65535, correctly rounded, as the CPU's loader divides:
// q / 65535 = a (1 + 2⁻¹⁶ + 2⁻³² + …) with a = q 2⁻¹⁶, summed as a + (b + c), b = a 2⁻¹⁶,
// c = a 2⁻³². Every term is exact, and the two additions round to the quotient for every code
// (checked exhaustively on the CPU, layout::tests, and on the adapter, tests/heightmap.rs).
// b and c are made from a's exponent bits: written as products, Mesa's GL compiler folds the
// sum back into q times the rounded reciprocal, which is one ulp low for 512 of the codes.
fn unorm16_texel(q: u32) -> f32 {
    let a = f32(q) * (1.0 / 65536.0);
    let bits = bitcast<u32>(a);
    let b = bitcast<f32>(bits - (16u << 23u));
    let c = bitcast<f32>(bits - (32u << 23u));
    return select(a + (b + c), 0.0, q == 0u);
}

// The half float h (zero or normal: the encoder admits no other) as f32, by its bits: exact,
// and without unpack2x16float, which some adapters lack (wgpu's SHADER_F16_IN_F32).
fn f16_texel(h: u32) -> f32 {
    let sign = (h & 0x8000u) << 16u;
    let exp = (h >> 10u) & 0x1fu;
    return bitcast<f32>(select(sign | ((exp + 112u) << 23u) | ((h & 0x3ffu) << 13u), sign, exp == 0u));
}

// Texel (x, y) of the map, as GpuSceneParams::map_encoding stores it (layout::EncodedMap): one
// f32 per word, or two 16-bit codes per word of its row (texel 2k in the low half of word k),
// unorm16 or half float. One load and selects, no branch: a lock-step implementation would
// run every branch.
fn map_texel(x: u32, y: u32) -> f32 {
    let packed = scene.map_encoding != 0u;
    let word = textureLoad(height_map, vec2<u32>(select(x, x >> 1u, packed), y), 0).x;
    let code = (word >> ((x & 1u) << 4u)) & 0xffffu;
    let half = select(unorm16_texel(code), f16_texel(code), scene.map_encoding == 2u);
    return select(bitcast<f32>(word), half, packed);
}

// The texel indices of integer coordinates x and x + 1 along an axis of n texels, wrap mode
// applied: repeat (rem_euclid) wraps x once and steps to its neighbour, clamp clamps both.
fn axis_pair(x: i32, n: i32) -> vec2<i32> {
    if (scene.wrap == 0u) {
        let i = wrap_repeat(x, n);
        return vec2<i32>(i, select(i + 1, 0, i + 1 == n));
    }
    return vec2<i32>(clamp(x, 0, n - 1), clamp(x + 1, 0, n - 1));
}

// The four texels of the bilinear footprint whose top-left texel is (x, y) (any integers),
// wrap mode applied: (x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1), the texels the CPU's
// HeightMap::texel reads. Each axis is wrapped once, not once per texel.
fn footprint(x: i32, y: i32) -> vec4f {
    let w = i32(scene.map_width);
    let h = i32(scene.map_height);
    let xs = axis_pair(x, w);
    let ys = axis_pair(y, h);
    let cols = vec2<u32>(xs);
    let rows = vec2<u32>(ys);
    return vec4f(
        map_texel(cols.x, rows.x),
        map_texel(cols.y, rows.x),
        map_texel(cols.x, rows.y),
        map_texel(cols.y, rows.y),
    );
}

// Bound on continuous texel coordinates before they become integers. A NaN, infinite or huge
// coordinate must not reach i32(): the conversion is undefined in SPIR-V, and an optimising
// driver compiler (lavapipe's LLVM) may then drop the rest of the shader. Non-finite values
// become 0 (what Rust's `NaN as i64` gives the CPU), huge ones are clamped (far outside any
// footprint, where the CPU's i64 indices give the same wrapped texel up to f32 precision).
const TEXEL_COORD_BOUND: f32 = 1.0e7;

fn texel_safe(x: f32) -> f32 {
    if (!finite(x)) {
        return 0.0;
    }
    return clamp(x, -TEXEL_COORD_BOUND, TEXEL_COORD_BOUND);
}

// Continuous texel coordinates of a UV: texel (i, j) has its centre at (i + 0.5, j + 0.5).
fn texel_coords(uv: vec2f) -> vec2f {
    return vec2f(texel_safe(uv.x * f32(scene.map_width)), texel_safe((1.0 - uv.y) * f32(scene.map_height)));
}

// Bilinear sample of the raw map value at `uv`.
fn sample_map(uv: vec2f) -> f32 {
    let p = texel_coords(uv) - vec2f(0.5);
    let fx = floor(p.x);
    let fy = floor(p.y);
    let tx = p.x - fx;
    let ty = p.y - fy;
    let x = i32(fx);
    let y = i32(fy);
    let q = footprint(x, y);
    let a = q.x;
    let b = q.y;
    let c = q.z;
    let d = q.w;
    let top = a + (b - a) * tx;
    let bottom = c + (d - c) * tx;
    return top + (bottom - top) * ty;
}

// Bilinear sample and its gradient with respect to (u, v) (HeightMap::sample_grad).
struct SampleGrad {
    value: f32,
    grad: vec2f,
}

fn sample_grad(uv: vec2f) -> SampleGrad {
    let p = texel_coords(uv) - vec2f(0.5);
    let fx = floor(p.x);
    let fy = floor(p.y);
    let tx = p.x - fx;
    let ty = p.y - fy;
    let x = i32(fx);
    let y = i32(fy);
    let q = footprint(x, y);
    let a = q.x;
    let b = q.y;
    let c = q.z;
    let d = q.w;
    let top = a + (b - a) * tx;
    let bottom = c + (d - c) * tx;
    let value = top + (bottom - top) * ty;
    let d_dx = (b - a) + ((d - c) - (b - a)) * ty;
    let d_dy = bottom - top;
    // x grows with u; y (rows) grows as v falls.
    let grad = vec2f(d_dx * f32(scene.map_width), -d_dy * f32(scene.map_height));
    return SampleGrad(value, grad);
}

// DisplaceParams::displacement: D = scale (h − midlevel).
fn displacement_of(h: f32) -> f32 {
    return scene.disp_scale * (h - scene.disp_midlevel);
}
