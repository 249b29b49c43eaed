// shading.wgsl — the material and MIS weights, the mirror of core/src/render/shading.rs
// function by function: Lambert + GGX (Smith height-correlated G2, Schlick Fresnel, visible-
// normal sampling, Heitz 2018), a perfect mirror below MIRROR_ROUGHNESS, the power heuristic
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
}

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

fn reflect_about(wo: vec3f, n: vec3f) -> vec3f {
    return n * (2.0 * dot(wo, n)) - wo;
}

// shading::ggx_eval: D G2 F / (4 cos θo).
fn ggx_eval(wo: vec3f, wi: vec3f, alpha: f32, f0: vec3f) -> vec3f {
    if (wo.z <= 0.0 || wi.z <= 0.0) {
        return vec3f(0.0);
    }
    let h = normalize_glam(wo + wi);
    let d = ggx_d(h, alpha);
    let g = smith_g2(wo, wi, alpha);
    return fresnel_schlick(f0, dot(wo, h)) * (d * g / (4.0 * wo.z));
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

fn diffuse_albedo(m: Material) -> vec3f {
    return m.base_color * ((1.0 - m.metallic) * (1.0 - m.specular));
}

fn specular_f0(m: Material) -> vec3f {
    return lerp3(vec3f(m.specular), m.base_color, m.metallic);
}

// shading::guide_albedo: the denoiser's albedo guide.
fn guide_albedo(m: Material) -> vec3f {
    return min(diffuse_albedo(m) + specular_f0(m), vec3f(1.0));
}

fn specular_probability(m: Material) -> f32 {
    let s = luminance(specular_f0(m));
    let d = luminance(diffuse_albedo(m));
    if (s <= 0.0) {
        return 0.0;
    }
    if (d <= 0.0) {
        return 1.0;
    }
    return clamp(s / (s + d), 0.1, 0.9);
}

// shading::bsdf_eval: BSDF × cos θi of the non-delta lobes.
fn bsdf_eval(m: Material, wo: vec3f, wi: vec3f) -> vec3f {
    if (wo.z <= 0.0 || wi.z <= 0.0) {
        return vec3f(0.0);
    }
    let diffuse = diffuse_albedo(m) * (INV_PI * wi.z);
    if (is_mirror(m)) {
        return diffuse;
    }
    return diffuse + ggx_eval(wo, wi, ggx_alpha(m.roughness), specular_f0(m));
}

// shading::bsdf_pdf.
fn bsdf_pdf(m: Material, wo: vec3f, wi: vec3f) -> f32 {
    if (wo.z <= 0.0 || wi.z <= 0.0) {
        return 0.0;
    }
    let ps = specular_probability(m);
    let diffuse = (1.0 - ps) * wi.z * INV_PI;
    if (is_mirror(m)) {
        return diffuse;
    }
    return diffuse + ps * ggx_pdf(wo, wi, ggx_alpha(m.roughness));
}

// shading::BsdfSample (`ok` false: the CPU's None).
struct BsdfSample {
    ok: bool,
    wi: vec3f,
    weight: vec3f,
    pdf: f32,
    delta: bool,
}

// shading::bsdf_sample: u_lobe picks the lobe, u the direction in it.
fn bsdf_sample(m: Material, wo: vec3f, u_lobe: f32, u: vec2f) -> BsdfSample {
    let none = BsdfSample(false, vec3f(0.0), vec3f(0.0), 0.0, false);
    if (wo.z <= 0.0) {
        return none;
    }
    let ps = specular_probability(m);
    let specular = u_lobe < ps;
    if (specular && is_mirror(m)) {
        let wi = vec3f(-wo.x, -wo.y, wo.z);
        return BsdfSample(true, wi, fresnel_schlick(specular_f0(m), wo.z) / ps, 0.0, true);
    }
    var wi: vec3f;
    if (specular) {
        wi = ggx_sample(wo, ggx_alpha(m.roughness), u);
    } else {
        wi = cosine_sample(u);
    }
    let pdf = bsdf_pdf(m, wo, wi);
    if (wi.z <= 0.0 || pdf <= 0.0) {
        return none;
    }
    return BsdfSample(true, wi, bsdf_eval(m, wo, wi) / pdf, pdf, false);
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

// shading::offset_origin: eps along the geometric normal, to the side dir leaves from.
fn offset_origin(p: vec3f, ng: vec3f, dir: vec3f, eps: f32) -> vec3f {
    if (dot(dir, ng) >= 0.0) {
        return p + ng * eps;
    }
    return p - ng * eps;
}
