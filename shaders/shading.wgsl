// shading.wgsl — the material and MIS weights, the mirror of core/src/render/shading.rs
// function by function (and of render::ggx_tables' lookups): a Lambert base under a dielectric
// GGX layer and a GGX metal, an optional clearcoat over both (Smith height-correlated G2,
// multiple-scattering energy from the tables, visible-normal sampling, Heitz 2018), a perfect
// mirror below MIRROR_ROUGHNESS, the power heuristic
// and the ray-origin offset. Directions are in the local shading frame (z = shading normal,
// `onb`), `wo` towards the viewer, `wi` towards the light. The filmic tonemap and the sRGB
// curve are applied on the host by the CPU's own writer (render::output::write_beauty).

const PI: f32 = 3.14159265358979323846;
const INV_PI: f32 = 0.318309886183790671538;
// shading::MIRROR_ROUGHNESS.
const MIRROR_ROUGHNESS: f32 = 0.02;

// shading::Material (from the Lighting uniform).
struct Material {
    base_color: vec3f,
    roughness: f32,
    metallic: f32,
    specular: f32,
    specular_tint: vec3f,
    clearcoat: f32,
    clearcoat_roughness: f32,
}

// shading::CLEARCOAT_IOR.
const CLEARCOAT_IOR: f32 = 1.5;

// shading::luminance (Rec. 709).
fn luminance(c: vec3f) -> f32 {
    return dot(c, vec3f(0.2126, 0.7152, 0.0722));
}

fn max_element(v: vec3f) -> f32 {
    return max(max(v.x, v.y), v.z);
}

// shading::onb: tangent and bitangent completing n (Duff et al. 2017).
struct Basis {
    t: vec3f,
    b: vec3f,
}

fn onb(n: vec3f) -> Basis {
    let sign = copysign(1.0, n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return Basis(
        vec3f(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        vec3f(b, sign + n.y * n.y * a, -n.y),
    );
}

fn to_local(v: vec3f, t: vec3f, b: vec3f, n: vec3f) -> vec3f {
    return vec3f(dot(v, t), dot(v, b), dot(v, n));
}

fn from_local(v: vec3f, t: vec3f, b: vec3f, n: vec3f) -> vec3f {
    return t * v.x + b * v.y + n * v.z;
}

// glam's normalize: v × (1 / |v|).
fn normalize_glam(v: vec3f) -> vec3f {
    return v * (1.0 / length(v));
}

fn ggx_alpha(roughness: f32) -> f32 {
    return max(roughness * roughness, 1e-4);
}

fn is_mirror(m: Material) -> bool {
    return m.roughness < MIRROR_ROUGHNESS;
}

fn ggx_d(h: vec3f, alpha: f32) -> f32 {
    if (h.z <= 0.0) {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let d = h.z * h.z * (a2 - 1.0) + 1.0;
    return a2 / (PI * d * d);
}

// Smith Λ(w); the CPU's +∞ at grazing angles is T_FAR (G1, G2 → 0 either way).
fn smith_lambda(w: vec3f, alpha: f32) -> f32 {
    let c2 = w.z * w.z;
    if (c2 <= 0.0) {
        return T_FAR;
    }
    let t2 = max(1.0 - c2, 0.0) / c2;
    return 0.5 * (-1.0 + sqrt(1.0 + alpha * alpha * t2));
}

fn smith_g1(w: vec3f, alpha: f32) -> f32 {
    return 1.0 / (1.0 + smith_lambda(w, alpha));
}

fn smith_g2(wo: vec3f, wi: vec3f, alpha: f32) -> f32 {
    return 1.0 / (1.0 + smith_lambda(wo, alpha) + smith_lambda(wi, alpha));
}

fn fresnel_schlick(f0: vec3f, cos_theta: f32) -> vec3f {
    // powi(5) as Rust evaluates it: (x²)² · x.
    let x = 1.0 - clamp(cos_theta, 0.0, 1.0);
    let x2 = x * x;
    let k = x2 * x2 * x;
    return f0 + (vec3f(1.0) - f0) * k;
}

// shading::ior_from_f0.
fn ior_from_f0(f0: f32) -> f32 {
    let s = sqrt(clamp(f0, 0.0, 0.99));
    return (1.0 + s) / (1.0 - s);
}

// shading::fresnel_dielectric: unpolarised, from outside a medium of index eta ≥ 1.
fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let c = clamp(cos_i, 0.0, 1.0);
    let g = sqrt(max(eta * eta - 1.0 + c * c, 0.0));
    let a = (g - c) / max(g + c, 1e-20);
    let b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    return 0.5 * a * a * (1.0 + b * b);
}

// shading::fresnel_blend: where f lies between f0 and 1, in [0, 1].
fn fresnel_blend(f: f32, f0: f32) -> f32 {
    return clamp((f - f0) / (1.0 - f0), 0.0, 1.0);
}

// shading::fresnel_dielectric_mean (Kulla & Conty's fit).
fn fresnel_dielectric_mean(eta: f32) -> f32 {
    return (eta - 1.0) / (4.08567 + 1.00071 * eta);
}

fn reflect_about(wo: vec3f, n: vec3f) -> vec3f {
    return n * (2.0 * dot(wo, n)) - wo;
}

// shading::ggx_eval: D G2 / (4 cos θo), without the Fresnel.
fn ggx_eval(wo: vec3f, wi: vec3f, alpha: f32) -> f32 {
    if (wo.z <= 0.0 || wi.z <= 0.0) {
        return 0.0;
    }
    let h = normalize_glam(wo + wi);
    return ggx_d(h, alpha) * smith_g2(wo, wi, alpha) / (4.0 * wo.z);
}

// shading::ggx_pdf: G1(wo) D(h) / (4 cos θo).
fn ggx_pdf(wo: vec3f, wi: vec3f, alpha: f32) -> f32 {
    if (wo.z <= 0.0 || wi.z <= 0.0) {
        return 0.0;
    }
    let h = normalize_glam(wo + wi);
    return smith_g1(wo, alpha) * ggx_d(h, alpha) / (4.0 * wo.z);
}

// shading::ggx_sample: a visible normal (Heitz 2018, listing 1), wo reflected about it.
fn ggx_sample(wo: vec3f, alpha: f32, u: vec2f) -> vec3f {
    let vh = normalize_glam(vec3f(alpha * wo.x, alpha * wo.y, wo.z));
    let lensq = vh.x * vh.x + vh.y * vh.y;
    var t1 = vec3f(1.0, 0.0, 0.0);
    if (lensq > 0.0) {
        t1 = vec3f(-vh.y, vh.x, 0.0) / sqrt(lensq);
    }
    let t2 = cross(vh, t1);
    let r = sqrt(u.x);
    let phi = 2.0 * PI * u.y;
    let p1 = r * cos(phi);
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * r * sin(phi);
    let nh = t1 * p1 + t2 * p2 + vh * sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0));
    let ne = normalize_glam(vec3f(alpha * nh.x, alpha * nh.y, max(nh.z, 0.0)));
    return reflect_about(wo, ne);
}

// shading::cosine_sample (density z / π).
fn cosine_sample(u: vec2f) -> vec3f {
    let r = sqrt(u.x);
    let phi = 2.0 * PI * u.y;
    return vec3f(r * cos(phi), r * sin(phi), sqrt(max(1.0 - u.x, 0.0)));
}

// ggx_tables: E (32 × 32), its mean (32) and s (16 × 16 × 16), four values a vec4 (a uniform
// array's stride is 16 bytes); layout::GpuBsdfTables.
struct BsdfTables {
    e: array<vec4f, 256>,
    e_avg: array<vec4f, 8>,
    s: array<vec4f, 1024>,
}

@group(2) @binding(6) var<uniform> bsdf_tables: BsdfTables;

// ggx_tables::cell: the grid points either side of x ∈ [0, 1] on n points, and the fraction.
struct Cell {
    i: u32,
    j: u32,
    t: f32,
}

fn cell(x: f32, n: u32) -> Cell {
    let xs = clamp(x, 0.0, 1.0) * f32(n - 1u);
    let i = min(u32(xs), n - 1u);
    return Cell(i, min(i + 1u, n - 1u), xs - f32(i));
}

fn lerp1(a: f32, b: f32, t: f32) -> f32 {
    return a + (b - a) * t;
}

fn table_e(i: u32) -> f32 {
    return bsdf_tables.e[i >> 2u][i & 3u];
}

fn table_s(i: u32) -> f32 {
    return bsdf_tables.s[i >> 2u][i & 3u];
}

// ggx_tables::ggx_e.
fn ggx_e(rough: f32, mu: f32) -> f32 {
    let x = cell(rough, 32u);
    let y = cell(mu, 32u);
    let lo = lerp1(table_e(y.i * 32u + x.i), table_e(y.i * 32u + x.j), x.t);
    let hi = lerp1(table_e(y.j * 32u + x.i), table_e(y.j * 32u + x.j), x.t);
    return lerp1(lo, hi, y.t);
}

// ggx_tables::ggx_e_avg.
fn ggx_e_avg(rough: f32) -> f32 {
    let x = cell(rough, 32u);
    return lerp1(bsdf_tables.e_avg[x.i >> 2u][x.i & 3u], bsdf_tables.e_avg[x.j >> 2u][x.j & 3u], x.t);
}

fn s_plane(x: Cell, y: Cell, z: u32) -> f32 {
    let lo = lerp1(table_s((z * 16u + y.i) * 16u + x.i), table_s((z * 16u + y.i) * 16u + x.j), x.t);
    let hi = lerp1(table_s((z * 16u + y.j) * 16u + x.i), table_s((z * 16u + y.j) * 16u + x.j), x.t);
    return lerp1(lo, hi, y.t);
}

// ggx_tables::ggx_s.
fn ggx_s(rough: f32, mu: f32, zf: f32) -> f32 {
    let x = cell(rough, 16u);
    let y = cell(mu, 16u);
    let z = cell(zf, 16u);
    return lerp1(s_plane(x, y, z.i), s_plane(x, y, z.j), z.t);
}

// shading::f82_b: the F82-tint term that takes Schlick's curve of f0 to tint times itself at
// cos θ = 1/7.
fn f82_b(f0: vec3f, tint: vec3f) -> vec3f {
    let mu = 1.0 / 7.0;
    let f = 1.0 - mu;
    let f5 = (f * f) * (f * f) * f;
    let schlick = f0 + (vec3f(1.0) - f0) * f5;
    return schlick * (1.0 / (mu * f5 * f)) * (vec3f(1.0) - tint);
}

// shading::fresnel_f82: Schlick's less b cos θ (1 − cos θ)⁶, at least 0.
fn fresnel_f82(f0: vec3f, b: vec3f, cos_theta: f32) -> vec3f {
    let c = clamp(cos_theta, 0.0, 1.0);
    let x = 1.0 - c;
    let x3 = x * x * x;
    return max(fresnel_schlick(f0, c) - b * (c * x3 * x3), vec3f(0.0));
}

// shading::Lobes: a material seen at one angle.
struct Lobes {
    diffuse: vec3f,
    metal_f0: vec3f,
    metal_b: vec3f,
    metal: vec3f,
    eta: f32,
    f0: f32,
    dielectric_f0: vec3f,
    dielectric: vec3f,
    dielectric_albedo: vec3f,
    alpha: f32,
    mirror: bool,
    p_specular: f32,
    specular_t: vec3f,
    specular_b: vec3f,
    specular_n: vec3f,
    clearcoat: f32,
    clearcoat_alpha: f32,
    clearcoat_mirror: bool,
    clearcoat_t: vec3f,
    clearcoat_b: vec3f,
    clearcoat_n: vec3f,
    p_clearcoat: f32,
    // The normal before a normal map bent the shading normal, local; +z: none.
    unbent_n: vec3f,
}

// Lobes::to_specular: a local direction in the specular lobe's frame.
fn to_specular(l: Lobes, v: vec3f) -> vec3f {
    return to_local(v, l.specular_t, l.specular_b, l.specular_n);
}

// Lobes::to_clearcoat: a local direction in the clearcoat's frame.
fn to_clearcoat(l: Lobes, v: vec3f) -> vec3f {
    return to_local(v, l.clearcoat_t, l.clearcoat_b, l.clearcoat_n);
}

// shading::clearcoat_albedo: the clearcoat's albedo estimate at cos θ = mu, per unit weight.
fn clearcoat_albedo(roughness: f32, mu: f32) -> f32 {
    let r = (CLEARCOAT_IOR - 1.0) / (CLEARCOAT_IOR + 1.0);
    let f0 = r * r;
    return f0 + (1.0 - f0) * ggx_s(clamp(roughness, 0.0, 1.0), mu, sqrt(sqrt(f0)));
}

// shading::clearcoat_through: what m's clearcoat lets through at cos θ = mu.
fn clearcoat_through(m: Material, mu: f32) -> f32 {
    let w = clamp(m.clearcoat, 0.0, 1.0);
    if (w <= 0.0) {
        return 1.0;
    }
    return clamp(1.0 - w * clearcoat_albedo(m.clearcoat_roughness, clamp(mu, 0.0, 1.0)), 0.0, 1.0);
}

// shading::multiple_scattering: 1 + Fms (1 − E)/E.
fn multiple_scattering(fss: vec3f, e: f32, e_avg: f32) -> vec3f {
    let missing = (1.0 - e) / max(e, 1e-4);
    let fms = fss * e_avg / (vec3f(1.0) - fss * (1.0 - e_avg));
    return vec3f(1.0) + fms * missing;
}

// shading::dielectric_blend.
fn dielectric_blend(dielectric_f0: vec3f, s: f32) -> vec3f {
    return dielectric_f0 + (vec3f(1.0) - dielectric_f0) * s;
}

// shading::share: the chance of sampling a lobe of albedo a against one of b.
fn share(a: f32, b: f32) -> f32 {
    if (a <= 0.0) {
        return 0.0;
    }
    if (b <= 0.0) {
        return 1.0;
    }
    return clamp(a / (a + b), 0.1, 0.9);
}

// shading::lobes: the lobes of m seen at cos θo = mu, all about the shading normal.
fn lobes(m: Material, mu: f32) -> Lobes {
    let z = vec3f(0.0, 0.0, 1.0);
    return lobes_about(m, z, mu, z, mu);
}

// shading::lobes_framed: the lobes of m seen from wo, the specular lobe about specular_n, the
// clearcoat about clearcoat_n, the diffuse about the shading normal.
fn lobes_framed(m: Material, wo: vec3f, specular_n: vec3f, clearcoat_n: vec3f) -> Lobes {
    return lobes_about(m, specular_n, dot(wo, specular_n), clearcoat_n, dot(wo, clearcoat_n));
}

// shading::lobes_about.
fn lobes_about(m: Material, specular_n: vec3f, mu_in: f32, clearcoat_n: vec3f, mu_c: f32) -> Lobes {
    let rough = clamp(m.roughness, 0.0, 1.0);
    let mu = clamp(mu_in, 0.0, 1.0);
    let e = ggx_e(rough, mu);
    let e_avg = ggx_e_avg(rough);
    let tint = clamp(m.specular_tint, vec3f(0.0), vec3f(1.0));
    let metal_f0 = clamp(m.base_color, vec3f(0.0), vec3f(1.0));
    let metal_b = f82_b(metal_f0, tint);
    let metal_mean = metal_f0 + (vec3f(1.0) - metal_f0) / 21.0 - metal_b / 126.0;
    let metal = multiple_scattering(metal_mean, e, e_avg) * m.metallic;
    let f0 = clamp(m.specular, 0.0, 0.99);
    let dielectric_f0 = tint * f0;
    var eta = 1.0;
    var dielectric = vec3f(0.0);
    var dielectric_albedo = vec3f(0.0);
    if (f0 > 0.0) {
        eta = ior_from_f0(f0);
        let s_mean = fresnel_blend(fresnel_dielectric_mean(eta), f0);
        let k = multiple_scattering(dielectric_blend(dielectric_f0, s_mean), e, e_avg);
        let s = ggx_s(rough, mu, sqrt(sqrt(f0)));
        dielectric = k * (1.0 - m.metallic);
        dielectric_albedo = k * dielectric_blend(dielectric_f0, s) * e;
    }
    let through = clamp(1.0 - max_element(dielectric_albedo), 0.0, 1.0);
    let diffuse = m.base_color * ((1.0 - m.metallic) * through);
    let s = luminance(metal * metal_f0) * e + (1.0 - m.metallic) * luminance(dielectric_albedo);
    let d = luminance(diffuse);
    let p_specular = share(s, d);
    let clearcoat = clamp(m.clearcoat, 0.0, 1.0);
    let under = clearcoat_through(m, mu_c);
    let p_clearcoat = share(1.0 - under, under * (s + d));
    let basis = onb(clearcoat_n);
    let sb = onb(specular_n);
    return Lobes(diffuse * under, metal_f0, metal_b, metal * under, eta, f0, dielectric_f0,
        dielectric * under, dielectric_albedo, ggx_alpha(m.roughness), is_mirror(m), p_specular,
        sb.t, sb.b, specular_n, clearcoat, ggx_alpha(m.clearcoat_roughness), m.clearcoat_roughness < MIRROR_ROUGHNESS,
        basis.t, basis.b, clearcoat_n, p_clearcoat, vec3f(0.0, 0.0, 1.0));
}

// shading::specular_fresnel: the metal's and the dielectric's Fresnel at cos θh = c, each
// weighted.
fn specular_fresnel(l: Lobes, c: f32) -> vec3f {
    let s = fresnel_blend(fresnel_dielectric(c, l.eta), l.f0);
    return l.metal * fresnel_f82(l.metal_f0, l.metal_b, c) + l.dielectric * dielectric_blend(l.dielectric_f0, s);
}

// shading::guide_albedo: the denoiser's albedo guide.
fn guide_albedo(m: Material) -> vec3f {
    let l = lobes(m, 1.0);
    let clearcoat = l.clearcoat * fresnel_dielectric(1.0, CLEARCOAT_IOR);
    return min(l.diffuse + specular_fresnel(l, 1.0) + vec3f(clearcoat), vec3f(1.0));
}

// shading::bump_shadowing: the diffuse's shadowing about the unbent normal unbent_n, for a
// local direction wi (the bent normal is +z).
fn bump_shadowing(unbent_n: vec3f, wi: vec3f) -> f32 {
    let cos_si = dot(unbent_n, wi);
    if (cos_si * unbent_n.z * wi.z < 0.0) {
        return 0.0;
    }
    let cos_i = abs(cos_si);
    let cos_d = abs(unbent_n.z);
    if (cos_d >= 1.0 || cos_i >= 1.0) {
        return 1.0;
    }
    if (cos_i < 1e-6) {
        return 0.0;
    }
    let alpha2 = clamp(0.125 * (1.0 / (cos_d * cos_d) - 1.0), 0.0, 1.0);
    let tan2_i = 1.0 / (cos_i * cos_i) - 1.0;
    return 2.0 / (1.0 + sqrt(1.0 + alpha2 * tan2_i));
}

// shading::base_eval: BSDF × cos θi of the layers under the clearcoat (non-delta lobes), the
// diffuse about the shading normal (shadowed about the unbent one), the specular about its
// own.
fn base_eval(l: Lobes, wo: vec3f, wi: vec3f) -> vec3f {
    var diffuse = vec3f(0.0);
    if (wi.z > 0.0) {
        diffuse = l.diffuse * (INV_PI * wi.z);
        if (any(l.unbent_n != vec3f(0.0, 0.0, 1.0))) {
            diffuse *= bump_shadowing(l.unbent_n, wi);
        }
    }
    if (l.mirror) {
        return diffuse;
    }
    let wo_s = to_specular(l, wo);
    let wi_s = to_specular(l, wi);
    if (wo_s.z <= 0.0 || wi_s.z <= 0.0) {
        return diffuse;
    }
    let c = dot(wo_s, normalize_glam(wo_s + wi_s));
    return diffuse + specular_fresnel(l, c) * ggx_eval(wo_s, wi_s, l.alpha);
}

// shading::clearcoat_eval: the clearcoat's lobe × cos θi, directions in its frame.
fn clearcoat_eval(l: Lobes, wo_c: vec3f, wi_c: vec3f) -> f32 {
    if (l.clearcoat <= 0.0 || l.clearcoat_mirror || wo_c.z <= 0.0 || wi_c.z <= 0.0) {
        return 0.0;
    }
    let c = dot(wo_c, normalize_glam(wo_c + wi_c));
    return l.clearcoat * fresnel_dielectric(c, CLEARCOAT_IOR) * ggx_eval(wo_c, wi_c, l.clearcoat_alpha);
}

// shading::bsdf_eval: BSDF × cos θi of the non-delta lobes.
fn bsdf_eval(l: Lobes, wo: vec3f, wi: vec3f) -> vec3f {
    let f = base_eval(l, wo, wi);
    if (l.clearcoat <= 0.0) {
        return f;
    }
    return f + vec3f(clearcoat_eval(l, to_clearcoat(l, wo), to_clearcoat(l, wi)));
}

// shading::base_pdf.
fn base_pdf(l: Lobes, wo: vec3f, wi: vec3f) -> f32 {
    let ps = l.p_specular;
    var diffuse = 0.0;
    if (wi.z > 0.0) {
        diffuse = (1.0 - ps) * wi.z * INV_PI;
    }
    if (l.mirror) {
        return diffuse;
    }
    let wo_s = to_specular(l, wo);
    let wi_s = to_specular(l, wi);
    if (wo_s.z <= 0.0 || wi_s.z <= 0.0) {
        return diffuse;
    }
    return diffuse + ps * ggx_pdf(wo_s, wi_s, l.alpha);
}

// shading::bsdf_pdf.
fn bsdf_pdf(l: Lobes, wo: vec3f, wi: vec3f) -> f32 {
    let pc = l.p_clearcoat;
    let base = (1.0 - pc) * base_pdf(l, wo, wi);
    if (pc <= 0.0 || l.clearcoat_mirror) {
        return base;
    }
    let wo_c = to_clearcoat(l, wo);
    let wi_c = to_clearcoat(l, wi);
    if (wo_c.z <= 0.0 || wi_c.z <= 0.0) {
        return base;
    }
    return base + pc * ggx_pdf(wo_c, wi_c, l.clearcoat_alpha);
}

// shading::BsdfSample (`ok` false: the CPU's None).
struct BsdfSample {
    ok: bool,
    wi: vec3f,
    weight: vec3f,
    pdf: f32,
    delta: bool,
}

// shading::glossy_direction: a glossy lobe's direction in its own frame: wo's mirror image
// for a mirror, else a GGX sample of roughness alpha.
fn glossy_direction(wo: vec3f, alpha: f32, mirror: bool, u: vec2f) -> vec3f {
    if (mirror) {
        return vec3f(-wo.x, -wo.y, wo.z);
    }
    return ggx_sample(wo, alpha, u);
}

// shading::bsdf_sample: u_lobe picks the lobe (the clearcoat below p_clearcoat, then the
// specular or the diffuse under it), u the direction in it.
fn bsdf_sample(l: Lobes, wo: vec3f, u_lobe: f32, u: vec2f) -> BsdfSample {
    let none = BsdfSample(false, vec3f(0.0), vec3f(0.0), 0.0, false);
    let pc = l.p_clearcoat;
    var wi: vec3f;
    if (u_lobe < pc) {
        let wo_c = to_clearcoat(l, wo);
        if (wo_c.z <= 0.0) {
            return none;
        }
        let wi_c = glossy_direction(wo_c, l.clearcoat_alpha, l.clearcoat_mirror, u);
        wi = from_local(wi_c, l.clearcoat_t, l.clearcoat_b, l.clearcoat_n);
        if (l.clearcoat_mirror) {
            let f = l.clearcoat * fresnel_dielectric(wo_c.z, CLEARCOAT_IOR);
            return BsdfSample(true, wi, vec3f(f / pc), 0.0, true);
        }
    } else {
        let ps = l.p_specular;
        let specular = (u_lobe - pc) < ps * (1.0 - pc);
        if (specular) {
            let wo_s = to_specular(l, wo);
            if (wo_s.z <= 0.0) {
                return none;
            }
            let wi_s = glossy_direction(wo_s, l.alpha, l.mirror, u);
            wi = from_local(wi_s, l.specular_t, l.specular_b, l.specular_n);
            if (l.mirror) {
                return BsdfSample(true, wi, specular_fresnel(l, wo_s.z) / (ps * (1.0 - pc)), 0.0, true);
            }
        } else {
            wi = cosine_sample(u);
        }
    }
    let pdf = bsdf_pdf(l, wo, wi);
    if (pdf <= 0.0) {
        return none;
    }
    return BsdfSample(true, wi, bsdf_eval(l, wo, wi) / pdf, pdf, false);
}

// shading::power_heuristic (β = 2).
fn power_heuristic(a: f32, b: f32) -> f32 {
    let a2 = a * a;
    let b2 = b * b;
    if (a2 + b2 > 0.0) {
        return a2 / (a2 + b2);
    }
    return 0.0;
}

// shading::valid_reflection_normal: n turned towards ng, in their plane, just far enough that
// its mirror reflection of wo rises min(0.9 wo·ng, 0.01) above the surface; n where it does.
fn valid_reflection_normal(ng: vec3f, wo: vec3f, n: vec3f) -> vec3f {
    let iz = dot(wo, ng);
    let t = min(0.9 * iz, 0.01);
    if (iz <= 0.0 || dot(reflect_about(wo, n), ng) >= t) {
        return n;
    }
    let x = normalize_or_zero(n - ng * dot(n, ng));
    if (all(x == vec3f(0.0))) {
        return n;
    }
    let ix = dot(wo, x);
    let a = sqrt(ix * ix + iz * iz);
    let two_theta = atan2(ix, iz) + acos(clamp(t / a, -1.0, 1.0));
    let theta0 = atan2(dot(n, x), dot(n, ng));
    let theta = clamp(0.5 * two_theta, 0.0, max(theta0, 0.0));
    return normalize_glam(x * sin(theta) + ng * cos(theta));
}

// shading::offset_origin: eps along the geometric normal, to the side dir leaves from.
fn offset_origin(p: vec3f, ng: vec3f, dir: vec3f, eps: f32) -> vec3f {
    if (dot(dir, ng) >= 0.0) {
        return p + ng * eps;
    }
    return p - ng * eps;
}
