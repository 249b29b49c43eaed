//! Pure shading functions of the beauty renderer: Blender's Principled BSDF without its
//! extras (a Lambert base under a dielectric GGX layer, a GGX metal, an optional clearcoat over
//! both, Smith height-correlated masking, multiple-scattering energy, visible-normal
//! sampling; `Lobes`), MIS weights and the
//! filmic tonemap. Each takes plain data (f32, glam vectors, `Material`) and allocates nothing,
//! so that the WGSL mirror can follow it function by function under the same names.
//!
//! Directions given to the BSDF functions are in the local shading frame (`z` = shading
//! normal, see `onb`); `wo` points towards the viewer, `wi` towards the light; both unit.
//!
//! References: Heitz 2014 "Understanding the Masking-Shadowing Function" (Λ, G2); Heitz 2018
//! "Sampling the GGX Distribution of Visible Normals" (VNDF sampling, `ggx_sample`); Duff et
//! al. 2017 "Building an Orthonormal Basis, Revisited" (`onb`); Narkowicz 2015 "ACES Filmic
//! Tone Mapping Curve" (`tonemap_filmic`).

use super::ggx_tables;
use glam::{Vec2, Vec3};

pub const PI: f32 = std::f32::consts::PI;
pub const INV_PI: f32 = std::f32::consts::FRAC_1_PI;

/// Below this roughness the specular lobe is a perfect mirror (a delta lobe): GGX with
/// α = roughness² < 4e-4 is numerically a spike that sampling finds but evaluation never does.
pub const MIRROR_ROUGHNESS: f32 = 0.02;

/// The surface material: base colour (linear), roughness and metallic as in glTF's
/// metallic-roughness model, and the dielectric reflectance at normal incidence (F0; 0.04 is
/// the usual IOR 1.5; 0 gives a pure Lambert surface).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub base_color: Vec3,
    pub roughness: f32,
    pub metallic: f32,
    pub specular: f32,
    /// The specular layer's tint (Blender's Specular Tint; white: none): the dielectric's F0
    /// times it, and the metal's reflectance near grazing (at cos θ = 1/7, about 82°) the
    /// tint times Schlick's there (the F82-tint model).
    pub specular_tint: Vec3,
    /// The clearcoat's weight in [0, 1] (glTF `KHR_materials_clearcoat`, Blender's Coat
    /// Weight; 0: none): a dielectric GGX layer of index `CLEARCOAT_IOR` over everything else,
    /// which it darkens by what it reflects.
    pub clearcoat: f32,
    /// The clearcoat's perceptual roughness (α = roughness²).
    pub clearcoat_roughness: f32,
}

/// The clearcoat's index of refraction (glTF's `KHR_materials_clearcoat` fixes it; Blender's
/// Coat IOR default).
pub const CLEARCOAT_IOR: f32 = 1.5;

/// The clearcoat roughness where a material names none but asks for a clearcoat
/// (`--clearcoat` alone): Blender's Coat Roughness default.
pub const DEFAULT_CLEARCOAT_ROUGHNESS: f32 = 0.03;

impl Default for Material {
    fn default() -> Self {
        Material {
            base_color: Vec3::splat(0.8),
            roughness: 0.5,
            metallic: 0.0,
            specular: 0.04,
            specular_tint: Vec3::ONE,
            clearcoat: 0.0,
            clearcoat_roughness: DEFAULT_CLEARCOAT_ROUGHNESS,
        }
    }
}

/// Rec. 709 luminance of linear RGB.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// Tangent and bitangent completing `n` to a right-handed orthonormal basis (Duff et al.).
#[inline]
pub fn onb(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

#[inline]
pub fn to_local(v: Vec3, t: Vec3, b: Vec3, n: Vec3) -> Vec3 {
    Vec3::new(v.dot(t), v.dot(b), v.dot(n))
}

#[inline]
pub fn from_local(v: Vec3, t: Vec3, b: Vec3, n: Vec3) -> Vec3 {
    t * v.x + b * v.y + n * v.z
}

/// GGX α from perceptual roughness, floored so that D stays finite in f32.
#[inline]
pub fn ggx_alpha(roughness: f32) -> f32 {
    (roughness * roughness).max(1e-4)
}

#[inline]
pub fn is_mirror(m: &Material) -> bool {
    m.roughness < MIRROR_ROUGHNESS
}

/// GGX normal distribution D(h) for a local half vector.
#[inline]
pub fn ggx_d(h: Vec3, alpha: f32) -> f32 {
    if h.z <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let d = h.z * h.z * (a2 - 1.0) + 1.0;
    a2 / (PI * d * d)
}

/// Smith Λ(w) of GGX.
#[inline]
pub fn smith_lambda(w: Vec3, alpha: f32) -> f32 {
    let c2 = w.z * w.z;
    if c2 <= 0.0 {
        return f32::INFINITY;
    }
    let t2 = (1.0 - c2).max(0.0) / c2;
    0.5 * (-1.0 + (1.0 + alpha * alpha * t2).sqrt())
}

#[inline]
pub fn smith_g1(w: Vec3, alpha: f32) -> f32 {
    1.0 / (1.0 + smith_lambda(w, alpha))
}

/// Height-correlated masking-shadowing G2(wo, wi).
#[inline]
pub fn smith_g2(wo: Vec3, wi: Vec3, alpha: f32) -> f32 {
    1.0 / (1.0 + smith_lambda(wo, alpha) + smith_lambda(wi, alpha))
}

#[inline]
pub fn fresnel_schlick(f0: Vec3, cos_theta: f32) -> Vec3 {
    let k = (1.0 - cos_theta.clamp(0.0, 1.0)).powi(5);
    f0 + (Vec3::ONE - f0) * k
}

/// Relative index of refraction of a dielectric whose reflectance at normal incidence is `f0`.
#[inline]
pub fn ior_from_f0(f0: f32) -> f32 {
    let s = f0.clamp(0.0, 0.99).sqrt();
    (1.0 + s) / (1.0 - s)
}

/// Fresnel reflectance of unpolarised light meeting a dielectric of relative index `eta` ≥ 1
/// from outside, at cosine `cos_i` (Walter et al. 2007, eq. 22; 0 for `eta` = 1).
#[inline]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let c = cos_i.clamp(0.0, 1.0);
    let g = (eta * eta - 1.0 + c * c).max(0.0).sqrt();
    let a = (g - c) / (g + c).max(1e-20);
    let b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    0.5 * a * a * (1.0 + b * b)
}

/// Where a dielectric's reflectance `f` lies between its F0 `f0` and 1, in [0, 1]: the blend
/// that carries its curve over to another F0 (Cycles' generalized Schlick of a true Fresnel).
#[inline]
pub fn fresnel_blend(f: f32, f0: f32) -> f32 {
    ((f - f0) / (1.0 - f0)).clamp(0.0, 1.0)
}

/// The cosine-weighted mean of `fresnel_dielectric` over the hemisphere, for `eta` ≥ 1 (Kulla
/// & Conty's fit, the one Cycles uses: within 0.006 of the integral for F0 from 0.02 to 0.25,
/// 0.0023 at the usual 0.04).
#[inline]
pub fn fresnel_dielectric_mean(eta: f32) -> f32 {
    (eta - 1.0) / (4.085_67 + 1.000_71 * eta)
}

#[inline]
pub fn reflect(wo: Vec3, n: Vec3) -> Vec3 {
    n * (2.0 * wo.dot(n)) - wo
}

/// The GGX lobe times cos θi without its Fresnel: `D G2 / (4 cos θo)`.
#[inline]
pub fn ggx_eval(wo: Vec3, wi: Vec3, alpha: f32) -> f32 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    let h = (wo + wi).normalize();
    ggx_d(h, alpha) * smith_g2(wo, wi, alpha) / (4.0 * wo.z)
}

/// Solid-angle density of `ggx_sample` producing `wi`: `G1(wo) D(h) / (4 cos θo)`.
#[inline]
pub fn ggx_pdf(wo: Vec3, wi: Vec3, alpha: f32) -> f32 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    let h = (wo + wi).normalize();
    smith_g1(wo, alpha) * ggx_d(h, alpha) / (4.0 * wo.z)
}

/// Sample a visible normal (Heitz 2018, listing 1) and reflect `wo` about it. The result may
/// lie below the horizon; callers reject it (`ggx_pdf` is zero there).
#[inline]
pub fn ggx_sample(wo: Vec3, alpha: f32, u: Vec2) -> Vec3 {
    let vh = Vec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let t1 = if lensq > 0.0 {
        Vec3::new(-vh.y, vh.x, 0.0) / lensq.sqrt()
    } else {
        Vec3::X
    };
    let t2 = vh.cross(t1);
    let r = u.x.sqrt();
    let phi = 2.0 * PI * u.y;
    let p1 = r * phi.cos();
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
    let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    let ne = Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(0.0)).normalize();
    reflect(wo, ne)
}

/// Cosine-weighted hemisphere direction (density `z / π`).
#[inline]
pub fn cosine_sample(u: Vec2) -> Vec3 {
    let r = u.x.sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u.x).max(0.0).sqrt())
}

/// The F82-tint model's b (Kutz et al. 2021, "Novel aspects of the Adobe Standard
/// Material"; as Cycles has it): the term that takes Schlick's curve of `f0` to `tint` times
/// itself at cos θ = 1/7, about 82° (`fresnel_f82`). Zero for a white tint.
#[inline]
pub fn f82_b(f0: Vec3, tint: Vec3) -> Vec3 {
    const MU: f32 = 1.0 / 7.0;
    let f = 1.0 - MU;
    let f5 = (f * f) * (f * f) * f;
    let schlick = f0 + (Vec3::ONE - f0) * f5;
    schlick * (1.0 / (MU * f5 * f)) * (Vec3::ONE - tint)
}

/// Schlick's Fresnel of `f0` less the F82-tint term `b` cos θ (1 − cos θ)⁶, at least 0.
#[inline]
pub fn fresnel_f82(f0: Vec3, b: Vec3, cos_theta: f32) -> Vec3 {
    let c = cos_theta.clamp(0.0, 1.0);
    let x = 1.0 - c;
    let x3 = x * x * x;
    (fresnel_schlick(f0, c) - b * (c * x3 * x3)).max(Vec3::ZERO)
}

/// A material seen from one direction: the weights of its lobes, which depend on the view's
/// angle. As in Blender's Principled BSDF, the metal (weight `metallic`, Schlick's Fresnel of
/// the base colour, bent by the specular tint at 82°) and the dielectric coat (weight
/// 1 − metallic, the dielectric Fresnel of the index F0 stands for, rescaled to start from
/// F0 times the tint) share one GGX lobe, each scaled up by the energy that single scattering
/// leaves out (Kulla & Conty: 1 + Fms (1 − E)/E, Fms from the mean Fresnel); the Lambert base
/// gets what the coat lets through at this angle, 1 − E (1 + …) × its mean Fresnel over the
/// lobe (`ggx_tables`), in its brightest channel. A clearcoat (Blender's Coat) lies over all
/// three: its own GGX lobe about its own normal (the surface's before a normal map bends it),
/// the dielectric Fresnel of `CLEARCOAT_IOR`, no multiple-scattering scale, and the layers
/// under it (and the surface's glow) darkened by its albedo estimate at the view's angle
/// (`clearcoat_through`), as Cycles layers it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lobes {
    /// Reflectance of the Lambert lobe.
    pub diffuse: Vec3,
    /// The metal's F0 (the base colour), its F82-tint term (`f82_b`) and its weight.
    pub metal_f0: Vec3,
    pub metal_b: Vec3,
    pub metal: Vec3,
    /// The dielectric layer's index (1: none), the F0 it gives, its tinted F0 and its weight.
    pub eta: f32,
    pub f0: f32,
    pub dielectric_f0: Vec3,
    pub dielectric: Vec3,
    /// The dielectric layer's albedo at this angle (what it takes from the diffuse, per unit
    /// weight).
    pub dielectric_albedo: Vec3,
    pub alpha: f32,
    /// A perfect mirror (a delta lobe: only sampled).
    pub mirror: bool,
    /// Probability of sampling the specular lobe rather than the diffuse, when the layers
    /// under the clearcoat are sampled.
    pub p_specular: f32,
    /// The specular lobe's frame in the local shading frame (`specular_n` its normal, the
    /// diffuse's turned by `valid_reflection_normal`; `Vec3::Z` where it is the shading
    /// normal, which makes the frame the identity).
    pub specular_t: Vec3,
    pub specular_b: Vec3,
    pub specular_n: Vec3,
    /// The clearcoat's weight (0: none), α, whether it is a perfect mirror, and its frame in
    /// the local shading frame (`clearcoat_n` its normal; `Vec3::Z` where it is the shading
    /// normal, which makes the frame the identity).
    pub clearcoat: f32,
    pub clearcoat_alpha: f32,
    pub clearcoat_mirror: bool,
    pub clearcoat_t: Vec3,
    pub clearcoat_b: Vec3,
    pub clearcoat_n: Vec3,
    /// Probability of sampling the clearcoat's lobe.
    pub p_clearcoat: f32,
    /// The surface's normal before a normal map bent the shading normal (Cycles' `sd->N`),
    /// in the local shading frame; `Vec3::Z` where nothing bent it. The diffuse is shadowed
    /// about it (`bump_shadowing`).
    pub unbent_n: Vec3,
}

impl Lobes {
    /// A local direction in the specular lobe's frame.
    #[inline]
    pub fn to_specular(&self, v: Vec3) -> Vec3 {
        to_local(v, self.specular_t, self.specular_b, self.specular_n)
    }

    /// A local direction in the clearcoat's frame.
    #[inline]
    pub fn to_clearcoat(&self, v: Vec3) -> Vec3 {
        to_local(v, self.clearcoat_t, self.clearcoat_b, self.clearcoat_n)
    }
}

/// The clearcoat's albedo estimate seen at cos θ = `mu`, per unit weight: its Fresnel's mean
/// over the lobe, F0 + (1 − F0) s (`ggx_tables::ggx_s`), as Cycles estimates a dielectric
/// lobe's albedo (without the lobe's own single-scattering loss).
#[inline]
pub fn clearcoat_albedo(roughness: f32, mu: f32) -> f32 {
    let f0 = ((CLEARCOAT_IOR - 1.0) / (CLEARCOAT_IOR + 1.0)).powi(2);
    f0 + (1.0 - f0) * ggx_tables::ggx_s(roughness.clamp(0.0, 1.0), mu, f0.sqrt().sqrt())
}

/// What `m`'s clearcoat lets through to the layers under it (and to the surface's glow) seen
/// at cos θ = `mu` from its normal: 1 − weight × its albedo; 1 without a clearcoat.
#[inline]
pub fn clearcoat_through(m: &Material, mu: f32) -> f32 {
    let w = m.clearcoat.clamp(0.0, 1.0);
    if w <= 0.0 {
        return 1.0;
    }
    (1.0 - w * clearcoat_albedo(m.clearcoat_roughness, mu.clamp(0.0, 1.0))).clamp(0.0, 1.0)
}

/// 1 + Fms (1 − E)/E: the scale that gives a lobe of mean Fresnel `fss` the energy single
/// scattering misses, E and its mean `e_avg` from `ggx_tables`.
#[inline]
pub fn multiple_scattering(fss: Vec3, e: f32, e_avg: f32) -> Vec3 {
    let missing = (1.0 - e) / e.max(1e-4);
    let fms = fss * e_avg / (Vec3::ONE - fss * (1.0 - e_avg));
    Vec3::ONE + fms * missing
}

/// The dielectric layer's Fresnel from the blend `s` between its tinted F0 and 1.
#[inline]
fn dielectric_blend(dielectric_f0: Vec3, s: f32) -> Vec3 {
    dielectric_f0 + (Vec3::ONE - dielectric_f0) * s
}

/// The lobes of `m` seen at cos θo = `mu`, all about the shading normal.
#[inline]
pub fn lobes(m: &Material, mu: f32) -> Lobes {
    lobes_about(m, Vec3::Z, mu, Vec3::Z, mu)
}

/// The lobes of `m` seen from the local direction `wo`: the specular lobe about the local
/// normal `specular_n` (the shading normal turned by `valid_reflection_normal`), the
/// clearcoat about `clearcoat_n` (the shading normal before a normal map bent it, or its own
/// map's), the diffuse about the shading normal.
#[inline]
pub fn lobes_framed(m: &Material, wo: Vec3, specular_n: Vec3, clearcoat_n: Vec3) -> Lobes {
    lobes_about(
        m,
        specular_n,
        wo.dot(specular_n),
        clearcoat_n,
        wo.dot(clearcoat_n),
    )
}

/// The lobes of `m` seen at cos θo = `mu` from the specular lobe's normal `specular_n` and
/// `mu_c` from the clearcoat's normal `clearcoat_n`.
#[inline]
fn lobes_about(m: &Material, specular_n: Vec3, mu: f32, clearcoat_n: Vec3, mu_c: f32) -> Lobes {
    let rough = m.roughness.clamp(0.0, 1.0);
    let mu = mu.clamp(0.0, 1.0);
    let (e, e_avg) = (ggx_tables::ggx_e(rough, mu), ggx_tables::ggx_e_avg(rough));
    let tint = m.specular_tint.clamp(Vec3::ZERO, Vec3::ONE);
    let metal_f0 = m.base_color.clamp(Vec3::ZERO, Vec3::ONE);
    let metal_b = f82_b(metal_f0, tint);
    let metal_mean = metal_f0 + (Vec3::ONE - metal_f0) / 21.0 - metal_b / 126.0;
    let metal = multiple_scattering(metal_mean, e, e_avg) * m.metallic;
    let f0 = m.specular.clamp(0.0, 0.99);
    let dielectric_f0 = tint * f0;
    let (eta, dielectric, dielectric_albedo) = if f0 > 0.0 {
        let eta = ior_from_f0(f0);
        let s_mean = fresnel_blend(fresnel_dielectric_mean(eta), f0);
        let k = multiple_scattering(dielectric_blend(dielectric_f0, s_mean), e, e_avg);
        let s = ggx_tables::ggx_s(rough, mu, f0.sqrt().sqrt());
        (
            eta,
            k * (1.0 - m.metallic),
            k * dielectric_blend(dielectric_f0, s) * e,
        )
    } else {
        (1.0, Vec3::ZERO, Vec3::ZERO)
    };
    let through = (1.0 - dielectric_albedo.max_element()).clamp(0.0, 1.0);
    let diffuse = m.base_color * ((1.0 - m.metallic) * through);
    // Sample the lobes by their albedos, keeping each pair in [0.1, 0.9] where both exist.
    let s = luminance(metal * metal_f0) * e + (1.0 - m.metallic) * luminance(dielectric_albedo);
    let d = luminance(diffuse);
    let p_specular = share(s, d);
    // The clearcoat over them, and what it lets through.
    let clearcoat = m.clearcoat.clamp(0.0, 1.0);
    let under = clearcoat_through(m, mu_c);
    let p_clearcoat = share(1.0 - under, under * (s + d));
    let (clearcoat_t, clearcoat_b) = onb(clearcoat_n);
    let (specular_t, specular_b) = onb(specular_n);
    Lobes {
        diffuse: diffuse * under,
        metal_f0,
        metal_b,
        metal: metal * under,
        eta,
        f0,
        dielectric_f0,
        dielectric: dielectric * under,
        dielectric_albedo,
        alpha: ggx_alpha(m.roughness),
        mirror: is_mirror(m),
        p_specular,
        specular_t,
        specular_b,
        specular_n,
        clearcoat,
        clearcoat_alpha: ggx_alpha(m.clearcoat_roughness),
        clearcoat_mirror: m.clearcoat_roughness < MIRROR_ROUGHNESS,
        clearcoat_t,
        clearcoat_b,
        clearcoat_n,
        p_clearcoat,
        unbent_n: Vec3::Z,
    }
}

/// The chance of sampling a lobe of albedo `a` against one of `b`: their shares, kept in
/// [0.1, 0.9] where both exist.
#[inline]
fn share(a: f32, b: f32) -> f32 {
    if a <= 0.0 {
        0.0
    } else if b <= 0.0 {
        1.0
    } else {
        (a / (a + b)).clamp(0.1, 0.9)
    }
}

/// The specular lobe's Fresnel at cos θh = `c`: the metal's and the dielectric's, each
/// weighted.
#[inline]
pub fn specular_fresnel(l: &Lobes, c: f32) -> Vec3 {
    let s = fresnel_blend(fresnel_dielectric(c, l.eta), l.f0);
    l.metal * fresnel_f82(l.metal_f0, l.metal_b, c)
        + l.dielectric * dielectric_blend(l.dielectric_f0, s)
}

/// The denoiser's albedo guide of a surface of `m`: what its lobes reflect at normal
/// incidence, at most 1 per channel (Open Image Denoise's albedo is a reflectance).
#[inline]
pub fn guide_albedo(m: &Material) -> Vec3 {
    let l = lobes(m, 1.0);
    let clearcoat = l.clearcoat * fresnel_dielectric(1.0, CLEARCOAT_IOR);
    (l.diffuse + specular_fresnel(&l, 1.0) + Vec3::splat(clearcoat)).min(Vec3::ONE)
}

/// The diffuse's shadowing where a normal map bent its normal away from the surface's
/// (Cycles' `bump_shadowing_term`, after Conty Estevez et al. 2019, "A Microfacet-Based
/// Shadowing Function to Solve the Bump Terminator Problem"), for a local direction `wi`
/// (the bent normal is `Vec3::Z`) and the surface's unbent normal `unbent_n`: 0 where `wi`
/// lies on the bent normal's side of the surface but not the unbent's (light through the
/// surface), else the GGX masking G1 at cos θ = |unbent_n · wi| of a roughness that grows
/// with the bend, α² = tan²(bend) / 8. 1 where nothing bent the normal.
#[inline]
pub fn bump_shadowing(unbent_n: Vec3, wi: Vec3) -> f32 {
    let cos_si = unbent_n.dot(wi);
    let cos_d = unbent_n.z;
    if cos_si * cos_d * wi.z < 0.0 {
        return 0.0;
    }
    let (cos_i, cos_d) = (cos_si.abs(), cos_d.abs());
    if cos_d >= 1.0 || cos_i >= 1.0 {
        return 1.0;
    }
    if cos_i < 1e-6 {
        return 0.0;
    }
    let alpha2 = (0.125 * (1.0 / (cos_d * cos_d) - 1.0)).clamp(0.0, 1.0);
    let tan2_i = 1.0 / (cos_i * cos_i) - 1.0;
    2.0 / (1.0 + (1.0 + alpha2 * tan2_i).sqrt())
}

/// The layers under the clearcoat: BSDF times cos θi of their non-delta lobes, the diffuse
/// about the shading normal (shadowed about the unbent one, `bump_shadowing`; lit from above
/// it whichever side the view is on, as Cycles' diffuse is: a normal map may face it away
/// from the view), the specular about its own.
#[inline]
fn base_eval(l: &Lobes, wo: Vec3, wi: Vec3) -> Vec3 {
    let diffuse = match wi.z > 0.0 {
        true if l.unbent_n == Vec3::Z => l.diffuse * (INV_PI * wi.z),
        true => l.diffuse * (INV_PI * wi.z * bump_shadowing(l.unbent_n, wi)),
        false => Vec3::ZERO,
    };
    if l.mirror {
        return diffuse;
    }
    let (wo_s, wi_s) = (l.to_specular(wo), l.to_specular(wi));
    if wo_s.z <= 0.0 || wi_s.z <= 0.0 {
        return diffuse;
    }
    let c = wo_s.dot((wo_s + wi_s).normalize());
    diffuse + specular_fresnel(l, c) * ggx_eval(wo_s, wi_s, l.alpha)
}

/// The clearcoat's lobe times cos θi, for directions in its frame (zero where it is a mirror).
#[inline]
fn clearcoat_eval(l: &Lobes, wo_c: Vec3, wi_c: Vec3) -> f32 {
    if l.clearcoat <= 0.0 || l.clearcoat_mirror || wo_c.z <= 0.0 || wi_c.z <= 0.0 {
        return 0.0;
    }
    let c = wo_c.dot((wo_c + wi_c).normalize());
    l.clearcoat * fresnel_dielectric(c, CLEARCOAT_IOR) * ggx_eval(wo_c, wi_c, l.clearcoat_alpha)
}

/// BSDF times cos θi for the non-delta lobes (a mirror lobe is a delta: only sampled).
#[inline]
pub fn bsdf_eval(l: &Lobes, wo: Vec3, wi: Vec3) -> Vec3 {
    let f = base_eval(l, wo, wi);
    if l.clearcoat <= 0.0 {
        return f;
    }
    f + Vec3::splat(clearcoat_eval(l, l.to_clearcoat(wo), l.to_clearcoat(wi)))
}

/// Density of the layers under the clearcoat producing `wi` through a non-delta lobe.
#[inline]
fn base_pdf(l: &Lobes, wo: Vec3, wi: Vec3) -> f32 {
    let ps = l.p_specular;
    let diffuse = match wi.z > 0.0 {
        true => (1.0 - ps) * wi.z * INV_PI,
        false => 0.0,
    };
    if l.mirror {
        return diffuse;
    }
    let (wo_s, wi_s) = (l.to_specular(wo), l.to_specular(wi));
    if wo_s.z <= 0.0 || wi_s.z <= 0.0 {
        return diffuse;
    }
    diffuse + ps * ggx_pdf(wo_s, wi_s, l.alpha)
}

/// Density of `bsdf_sample` producing `wi` through a non-delta lobe.
#[inline]
pub fn bsdf_pdf(l: &Lobes, wo: Vec3, wi: Vec3) -> f32 {
    let pc = l.p_clearcoat;
    let base = (1.0 - pc) * base_pdf(l, wo, wi);
    if pc <= 0.0 || l.clearcoat_mirror {
        return base;
    }
    let (wo_c, wi_c) = (l.to_clearcoat(wo), l.to_clearcoat(wi));
    if wo_c.z <= 0.0 || wi_c.z <= 0.0 {
        return base;
    }
    base + pc * ggx_pdf(wo_c, wi_c, l.clearcoat_alpha)
}

/// A sampled direction: `weight` = f·cos/pdf (the throughput factor), `pdf` the solid-angle
/// density (0 with `delta` for a mirror lobe, which MIS must not weight).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub weight: Vec3,
    pub pdf: f32,
    pub delta: bool,
}

/// A glossy lobe's direction in its own frame: `wo`'s mirror image for a mirror, else a GGX
/// sample of roughness `alpha`.
#[inline]
fn glossy_direction(wo: Vec3, alpha: f32, mirror: bool, u: Vec2) -> Vec3 {
    match mirror {
        true => Vec3::new(-wo.x, -wo.y, wo.z),
        false => ggx_sample(wo, alpha, u),
    }
}

/// Sample the lobes: `u_lobe` picks the lobe (the clearcoat below `p_clearcoat`, then the
/// specular or the diffuse under it), `u` the direction within it.
#[inline]
pub fn bsdf_sample(l: &Lobes, wo: Vec3, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
    let pc = l.p_clearcoat;
    let wi = if u_lobe < pc {
        let wo_c = l.to_clearcoat(wo);
        if wo_c.z <= 0.0 {
            return None;
        }
        let wi_c = glossy_direction(wo_c, l.clearcoat_alpha, l.clearcoat_mirror, u);
        let wi = from_local(wi_c, l.clearcoat_t, l.clearcoat_b, l.clearcoat_n);
        if l.clearcoat_mirror {
            let f = l.clearcoat * fresnel_dielectric(wo_c.z, CLEARCOAT_IOR);
            return Some(BsdfSample {
                wi,
                weight: Vec3::splat(f / pc),
                pdf: 0.0,
                delta: true,
            });
        }
        wi
    } else {
        let ps = l.p_specular;
        let specular = (u_lobe - pc) < ps * (1.0 - pc);
        if specular {
            let wo_s = l.to_specular(wo);
            if wo_s.z <= 0.0 {
                return None;
            }
            let wi_s = glossy_direction(wo_s, l.alpha, l.mirror, u);
            let wi = from_local(wi_s, l.specular_t, l.specular_b, l.specular_n);
            if l.mirror {
                let weight = specular_fresnel(l, wo_s.z) / (ps * (1.0 - pc));
                return Some(BsdfSample {
                    wi,
                    weight,
                    pdf: 0.0,
                    delta: true,
                });
            }
            wi
        } else {
            cosine_sample(u)
        }
    };
    let pdf = bsdf_pdf(l, wo, wi);
    if pdf <= 0.0 {
        return None;
    }
    Some(BsdfSample {
        wi,
        weight: bsdf_eval(l, wo, wi) / pdf,
        pdf,
        delta: false,
    })
}

/// Veach's power heuristic (β = 2) for a sample of density `a` against a rival density `b`.
#[inline]
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}

/// A shading normal `n` whose mirror reflection of `wo` stays above the surface of geometric
/// normal `ng` (both facing `wo`): `n` itself where the reflection rises at least
/// min(0.9 wo·ng, 0.01) above that surface, else `n` turned towards `ng`, in the plane of the
/// two, just far enough that it does (as Cycles bends a normal-mapped or smoothed normal
/// before its glossy lobes use it). Without it a normal map that tilts the normal past the
/// view's mirror angle sends every glossy reflection into the surface, and the pixel black.
///
/// With θ the angle of the turned normal from `ng` in that plane, the reflection's height
/// over the surface is (wo·X) sin 2θ + (wo·ng) cos 2θ = A cos(2θ − δ), X the plane's
/// direction across `ng`, A = |(wo·X, wo·ng)| and δ its angle from `ng`; it falls through
/// the threshold t where 2θ = δ + acos(t/A).
#[inline]
pub fn valid_reflection_normal(ng: Vec3, wo: Vec3, n: Vec3) -> Vec3 {
    let iz = wo.dot(ng);
    let t = (0.9 * iz).min(0.01);
    if iz <= 0.0 || reflect(wo, n).dot(ng) >= t {
        return n;
    }
    let x = (n - ng * n.dot(ng)).normalize_or_zero();
    if x == Vec3::ZERO {
        return n;
    }
    let ix = wo.dot(x);
    let a = (ix * ix + iz * iz).sqrt();
    let two_theta = ix.atan2(iz) + (t / a).clamp(-1.0, 1.0).acos();
    // Never past `n` itself (which fails) nor behind `ng`.
    let theta0 = n.dot(x).atan2(n.dot(ng));
    let theta = (0.5 * two_theta).clamp(0.0, theta0.max(0.0));
    (x * theta.sin() + ng * theta.cos()).normalize()
}

/// Start a ray off a surface point without hitting that surface again: move it by `eps`
/// along the geometric normal, to the side `dir` leaves from.
#[inline]
pub fn offset_origin(p: Vec3, ng: Vec3, dir: Vec3, eps: f32) -> Vec3 {
    if dir.dot(ng) >= 0.0 {
        p + ng * eps
    } else {
        p - ng * eps
    }
}

/// Narkowicz's ACES-fitted filmic curve (per channel), after `exposure`.
#[inline]
pub fn tonemap_filmic(c: Vec3) -> Vec3 {
    let f = |x: f32| {
        let x = x.max(0.0);
        ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
    };
    Vec3::new(f(c.x), f(c.y), f(c.z))
}

/// sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
#[inline]
pub fn linear_to_srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_albedo_guide_is_a_reflectance() {
        let grey = Material::default();
        let a = guide_albedo(&grey);
        assert!(a.min_element() > 0.5 && a.max_element() <= 1.0, "{a}");
        let gold = Material {
            base_color: Vec3::new(1.0, 0.8, 0.3),
            metallic: 1.0,
            ..Material::default()
        };
        // A metal reflects its colour through the specular lobe alone, brightened by what
        // single scattering misses (a few % at roughness 0.5, more where the colour is bright:
        // light bounces between facets more times there).
        let g = guide_albedo(&gold);
        assert_eq!(lobes(&gold, 1.0).diffuse, Vec3::ZERO);
        let ratio = g / Vec3::new(1.0, 0.8, 0.3);
        assert!(
            ratio.y > 1.0 && ratio.y < 1.1 && ratio.z > 1.0 && ratio.z < ratio.y && g.x == 1.0,
            "{g}"
        );
    }

    use crate::rng::{random, Purpose};

    fn rand2(i: u32, k: u32) -> Vec2 {
        Vec2::new(
            random(i, k, 0, Purpose::Bench, 11),
            random(i, k, 1, Purpose::Bench, 11),
        )
    }

    fn dir_from_angle(theta: f32, phi: f32) -> Vec3 {
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    #[test]
    fn onb_is_orthonormal_for_every_hemisphere() {
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.5, 0.81).normalize(),
            Vec3::new(1e-7, 0.0, -1.0).normalize(),
        ] {
            let (t, b) = onb(n);
            assert!((t.length() - 1.0).abs() < 1e-5 && (b.length() - 1.0).abs() < 1e-5);
            assert!(t.dot(b).abs() < 1e-5 && t.dot(n).abs() < 1e-5 && b.dot(n).abs() < 1e-5);
            let v = Vec3::new(0.2, 0.3, 0.9).normalize();
            assert!((from_local(to_local(v, t, b, n), t, b, n) - v).length() < 1e-5);
        }
    }

    /// A sample's weight must be exactly what evaluation says: f·cos/pdf from `bsdf_eval` and
    /// `bsdf_pdf` at the sampled direction. A mismatch (e.g. a VNDF pdf that forgets G1, or a
    /// lobe probability applied twice) biases every beauty render.
    #[test]
    fn ggx_sample_weight_matches_eval_over_pdf() {
        // The last two with a clearcoat, the last about a normal of its own.
        let nc = dir_from_angle(0.3, 0.8);
        for (k, (rough, clearcoat, n)) in [
            (0.05f32, 0.0, Vec3::Z),
            (0.3, 0.0, Vec3::Z),
            (0.7, 0.0, Vec3::Z),
            (1.0, 0.0, Vec3::Z),
            (0.4, 0.7, Vec3::Z),
            (0.01, 1.0, nc),
        ]
        .into_iter()
        .enumerate()
        {
            let m = Material {
                roughness: rough,
                metallic: 0.5,
                clearcoat,
                clearcoat_roughness: 0.2,
                ..Material::default()
            };
            for i in 0..2000u32 {
                let wo = dir_from_angle(
                    1.5 * random(i, k as u32, 2, Purpose::Bench, 3),
                    6.0 * random(i, 0, 3, Purpose::Bench, 3),
                );
                let l = lobes_framed(&m, wo, Vec3::Z, n);
                let Some(s) = bsdf_sample(
                    &l,
                    wo,
                    random(i, k as u32, 4, Purpose::Bench, 3),
                    rand2(i, k as u32),
                ) else {
                    continue;
                };
                if s.delta {
                    continue;
                }
                let want = bsdf_eval(&l, wo, s.wi) / bsdf_pdf(&l, wo, s.wi);
                assert!(
                    (s.weight - want).length() <= 1e-4 * want.length().max(1.0),
                    "rough {rough}: {:?} vs {want:?}",
                    s.weight
                );
                // The GGX lobe alone: its pdf is D_v(h) / (4 wo·h), written as G1 D / (4 cos θo).
                let a = ggx_alpha(rough);
                let h = (wo + s.wi).normalize();
                let dv = smith_g1(wo, a) * wo.dot(h).max(0.0) * ggx_d(h, a) / wo.z;
                assert!(
                    (ggx_pdf(wo, s.wi, a) - dv / (4.0 * wo.dot(h))).abs() <= 1e-3 * dv.max(1.0)
                );
            }
        }
    }

    /// The GGX pdf integrates to the fraction of reflected directions above the horizon (≤ 1;
    /// 0.94 here, at θo = 0.4 and α = 0.25), and the histogram of samples follows the pdf.
    #[test]
    fn ggx_pdf_integrates_and_matches_samples() {
        let alpha = ggx_alpha(0.5);
        let wo = dir_from_angle(0.4, 0.7);
        // Riemann sum over the hemisphere in (cos θ, φ): dω = d(cos θ) dφ.
        let (nc, np) = (400, 400);
        let mut integral = 0.0f64;
        let mut bins = vec![0.0f64; 8];
        for i in 0..nc {
            for j in 0..np {
                let c = (i as f32 + 0.5) / nc as f32;
                let phi = 2.0 * PI * (j as f32 + 0.5) / np as f32;
                let wi = dir_from_angle(c.acos(), phi);
                let p = ggx_pdf(wo, wi, alpha) as f64 * (2.0 * PI as f64) / (nc * np) as f64;
                integral += p;
                bins[((c * 8.0) as usize).min(7)] += p;
            }
        }
        assert!(integral > 0.9 && integral <= 1.001, "∫ pdf = {integral}");
        let n = 200_000;
        let mut hist = vec![0.0f64; 8];
        for i in 0..n {
            let wi = ggx_sample(wo, alpha, rand2(i, 9));
            if wi.z > 0.0 {
                hist[((wi.z * 8.0) as usize).min(7)] += 1.0 / n as f64;
            }
        }
        // The pdf's mass above the horizon is exactly the share of samples that land there.
        let above: f64 = hist.iter().sum();
        assert!(
            (above - integral).abs() < 0.005,
            "{above} of the samples above the horizon, ∫ pdf = {integral}"
        );
        for (h, b) in hist.iter().zip(&bins) {
            assert!((h - b).abs() < 0.01, "histogram {hist:?} vs pdf {bins:?}");
        }
    }

    #[test]
    fn lambert_white_furnace_and_mirror() {
        let m = Material {
            base_color: Vec3::ONE,
            roughness: 1.0,
            metallic: 0.0,
            specular: 0.0,
            ..Material::default()
        };
        let wo = dir_from_angle(0.8, 0.1);
        let n = 50_000;
        let mean: Vec3 = (0..n)
            .filter_map(|i| bsdf_sample(&lobes(&m, wo.z), wo, 0.5, rand2(i, 1)))
            .map(|s| s.weight)
            .sum::<Vec3>()
            / n as f32;
        assert!((mean - Vec3::ONE).abs().max_element() < 1e-3, "{mean:?}");
        let mirror = Material {
            roughness: 0.0,
            metallic: 1.0,
            base_color: Vec3::ONE,
            ..m
        };
        let s = bsdf_sample(&lobes(&mirror, wo.z), wo, 0.3, Vec2::ZERO).unwrap();
        assert!(
            s.delta
                && (s.wi - Vec3::new(-wo.x, -wo.y, wo.z)).length() < 1e-6
                && (s.weight - Vec3::ONE).length() < 1e-5
        );
    }

    /// The directional albedo of `m` seen at cos θo = `mu`: the mean of `bsdf_sample`'s weights.
    fn albedo(m: &Material, mu: f32, n: u32) -> Vec3 {
        let wo = dir_from_angle(mu.acos(), 0.3);
        let l = lobes(m, wo.z);
        (0..n)
            .filter_map(|i| {
                let u_lobe = random(i, 5, 9, Purpose::Bench, 21);
                bsdf_sample(&l, wo, u_lobe, rand2(i, 17))
            })
            .map(|s| s.weight)
            .sum::<Vec3>()
            / n as f32
    }

    /// White furnaces. A white metal reflects all the light at every roughness and angle: the
    /// multiple-scattering scale gives back what single scattering loses (up to 69% at
    /// roughness 1, head on). A white dielectric, its diffuse base under its dielectric layer,
    /// reflects all of it to within that layer's albedo estimate (Blender's layering).
    #[test]
    fn white_furnaces_keep_their_energy() {
        for rough in [0.1f32, 0.3, 0.6, 1.0] {
            for mu in [0.15f32, 0.5, 0.95] {
                let metal = Material {
                    base_color: Vec3::ONE,
                    roughness: rough,
                    metallic: 1.0,
                    specular: 0.04,
                    ..Material::default()
                };
                let a = albedo(&metal, mu, 40_000);
                assert!(
                    (a - Vec3::ONE).abs().max_element() < 0.015,
                    "white metal, roughness {rough}, cos θo {mu}: albedo {a}"
                );
                let plastic = Material {
                    metallic: 0.0,
                    ..metal
                };
                let a = albedo(&plastic, mu, 40_000);
                assert!(
                    a.x > 0.96 && a.x < 1.03,
                    "white dielectric, roughness {rough}, cos θo {mu}: albedo {a}"
                );
            }
        }
    }

    /// The specular tint (Blender's Specular Tint). A metal's Fresnel is Schlick's at normal
    /// incidence and the tint times Schlick's at cos θ = 1/7 (the F82-tint model); a white
    /// tint changes nothing. A dielectric's starts at F0 times the tint and still reaches 1 at
    /// grazing; its diffuse loses what its brightest channel reflects.
    #[test]
    fn the_specular_tint_colours_the_metals_edge_and_the_coat() {
        let gold = Material {
            base_color: Vec3::new(1.0, 0.8, 0.3),
            metallic: 1.0,
            ..Material::default()
        };
        let tint = Vec3::new(1.0, 0.5, 0.2);
        let tinted = Material {
            specular_tint: tint,
            ..gold
        };
        let (l, lt) = (lobes(&gold, 0.7), lobes(&tinted, 0.7));
        let f = |l: &Lobes, c: f32| fresnel_f82(l.metal_f0, l.metal_b, c);
        assert_eq!(l.metal_b, Vec3::ZERO);
        assert!((f(&lt, 1.0) - gold.base_color).abs().max_element() < 1e-6);
        let at82 = f(&lt, 1.0 / 7.0) / fresnel_schlick(gold.base_color, 1.0 / 7.0);
        assert!((at82 - tint).abs().max_element() < 1e-5, "{at82}");
        assert!((f(&lt, 0.0) - Vec3::ONE).abs().max_element() < 1e-6);
        // Less light at the edge, so less to scatter again: the weight drops where the tint does.
        assert!(lt.metal.x == l.metal.x && lt.metal.z < l.metal.z);

        let plastic = Material {
            specular_tint: tint,
            ..Material::default()
        };
        let (l, lt) = (lobes(&Material::default(), 0.7), lobes(&plastic, 0.7));
        let f = |l: &Lobes, c: f32| specular_fresnel(l, c);
        assert!(
            (f(&lt, 1.0) / lt.dielectric - tint * 0.04)
                .abs()
                .max_element()
                < 1e-6
        );
        assert!(
            (f(&lt, 0.0) / lt.dielectric - Vec3::ONE)
                .abs()
                .max_element()
                < 1e-6
        );
        assert!(
            (f(&l, 0.5) / l.dielectric - Vec3::splat(fresnel_dielectric(0.5, 1.5)))
                .abs()
                .max_element()
                < 1e-6
        );
        // The diffuse is layered under the dielectric's brightest channel (the untinted red).
        assert!((lt.diffuse - l.diffuse).abs().max_element() < 1e-6);
        assert!(lt.dielectric_albedo.z < lt.dielectric_albedo.x);
    }

    /// The clearcoat (Blender's Coat) over the other layers, about its own normal.
    #[test]
    fn the_clearcoat_layers_over_the_rest() {
        // Without a clearcoat nothing changes; its roughness alone does nothing.
        let plain = Material::default();
        let rough_only = Material {
            clearcoat_roughness: 0.7,
            ..plain
        };
        let (a, b) = (lobes(&plain, 0.6), lobes(&rough_only, 0.6));
        assert_eq!(a.p_clearcoat, 0.0);
        let wo = dir_from_angle(0.6f32.acos(), 0.0);
        for i in 0..200 {
            let wi = dir_from_angle(1.5 * random(i, 0, 0, Purpose::Bench, 5), i as f32);
            assert_eq!(bsdf_eval(&a, wo, wi), bsdf_eval(&b, wo, wi));
            assert_eq!(bsdf_pdf(&a, wo, wi), bsdf_pdf(&b, wo, wi));
        }

        // A white Lambert base under a smooth clearcoat keeps all the light: what the coat
        // reflects (F at this angle) is what it takes from the base. A rough one loses some
        // (Cycles' albedo estimate leaves out the lobe's own loss), never gains.
        let white = Material {
            base_color: Vec3::ONE,
            specular: 0.0,
            clearcoat: 1.0,
            clearcoat_roughness: 0.05,
            ..Material::default()
        };
        for mu in [0.2f32, 0.6, 0.95] {
            let a = albedo(&white, mu, 40_000);
            assert!(
                (a - Vec3::ONE).abs().max_element() < 0.01,
                "cos θo {mu}: {a}"
            );
            let rough = Material {
                clearcoat_roughness: 0.6,
                ..white
            };
            let a = albedo(&rough, mu, 40_000);
            assert!(a.x > 0.9 && a.x < 1.005, "rough coat, cos θo {mu}: {a}");
        }

        // A mirror coat over black: a delta lobe reflecting the dielectric Fresnel of 1.5
        // about the coat's normal, which may differ from the shading normal.
        let black = Material {
            base_color: Vec3::ZERO,
            specular: 0.0,
            clearcoat: 0.8,
            clearcoat_roughness: 0.0,
            ..Material::default()
        };
        let wo = dir_from_angle(0.5, 0.2);
        let nc = dir_from_angle(0.2, 1.9);
        let l = lobes_framed(&black, wo, Vec3::Z, nc);
        assert_eq!(l.p_clearcoat, 1.0);
        let s = bsdf_sample(&l, wo, 0.3, Vec2::new(0.4, 0.6)).unwrap();
        let want = 0.8 * fresnel_dielectric(wo.dot(nc), CLEARCOAT_IOR);
        assert!(s.delta && (s.weight - Vec3::splat(want)).abs().max_element() < 1e-6);
        assert!(
            (s.wi - reflect(wo, nc)).length() < 1e-5,
            "{} vs {}",
            s.wi,
            reflect(wo, nc)
        );
        assert_eq!(bsdf_eval(&l, wo, s.wi), Vec3::ZERO);

        // The base is darkened by the coat's albedo estimate at the view's angle.
        let coated = Material {
            clearcoat: 0.5,
            ..Material::default()
        };
        let (l0, l1) = (lobes(&plain, 0.4), lobes(&coated, 0.4));
        let under = clearcoat_through(&coated, 0.4);
        assert!(under < 1.0 - 0.5 * fresnel_dielectric(0.4, 1.5) + 1e-3 && under > 0.9);
        assert!((l1.diffuse - l0.diffuse * under).abs().max_element() < 1e-6);
        assert!((l1.dielectric - l0.dielectric * under).abs().max_element() < 1e-6);
    }

    /// The diffuse's shadowing about the unbent normal: 1 where nothing bent it, 0 for light
    /// that comes through the unbent surface, else GGX's G1 at the angle from the unbent
    /// normal with α² = tan²(bend) / 8, rising to 1 towards that normal; the diffuse lobe of a
    /// `Lobes` with an unbent normal carries it, and its samples' weights stay eval / pdf.
    #[test]
    fn a_bent_diffuse_is_shadowed_about_the_unbent_normal() {
        for i in 0..500u32 {
            let r = |k| random(i, k, 0, Purpose::Bench, 5);
            let wi = dir_from_angle(1.5 * r(0), 6.3 * r(1));
            assert_eq!(bump_shadowing(Vec3::Z, wi), 1.0);
        }
        // Bent 30° about x: the unbent normal in the bent one's frame.
        let bend = 30f32.to_radians();
        let unbent = Vec3::new(0.0, bend.sin(), bend.cos());
        // Above the bent surface, under the unbent one: no light.
        let through = Vec3::new(0.0, -0.8, 0.3).normalize();
        assert!(through.z > 0.0 && through.dot(unbent) < 0.0);
        assert_eq!(bump_shadowing(unbent, through), 0.0);
        let alpha = (bend.tan().powi(2) / 8.0).sqrt();
        let mut last = 0.0;
        for k in 1..=20 {
            // From grazing the unbent surface to along its normal, in the plane of the bend.
            let a = std::f32::consts::FRAC_PI_2 * (1.0 - k as f32 / 20.0);
            let wi = Vec3::new(0.0, bend.sin() * a.cos() - bend.cos() * a.sin(), 0.0)
                + Vec3::new(0.0, 0.0, bend.cos() * a.cos() + bend.sin() * a.sin());
            let g = bump_shadowing(unbent, wi);
            let want = smith_g1(Vec3::new(a.sin(), 0.0, a.cos()), alpha);
            assert!((g - want).abs() < 1e-5, "{a}: {g} vs G1 {want}");
            assert!(g >= last && g <= 1.0);
            last = g;
        }
        assert!(last > 0.999);
        // In the lobes: the diffuse's eval times the term, the samples' weights eval / pdf.
        let m = Material {
            base_color: Vec3::splat(0.7),
            roughness: 0.6,
            ..Material::default()
        };
        let wo = Vec3::new(0.3, -0.2, 0.9).normalize();
        let plain = lobes_framed(&m, wo, Vec3::Z, Vec3::Z);
        let bent = Lobes {
            unbent_n: unbent,
            ..plain
        };
        let wi = Vec3::new(-0.2, -0.6, 0.5).normalize();
        let diffuse = plain.diffuse * (wi.z / std::f32::consts::PI);
        let drop = bsdf_eval(&plain, wo, wi) - bsdf_eval(&bent, wo, wi);
        let want = diffuse * (1.0 - bump_shadowing(unbent, wi));
        assert!(want.x > 0.01 && (drop - want).abs().max_element() < 1e-5);
        // A view below the bent normal (a normal map may face it away) still sees the diffuse
        // lit from above it, as Cycles does; the samples' weights stay eval / pdf.
        let below = Vec3::new(0.2, 0.9, -0.1).normalize();
        let matte = Material { specular: 0.0, ..m };
        let away = Lobes {
            unbent_n: unbent,
            ..lobes_framed(
                &matte,
                below,
                valid_reflection_normal(unbent, below, Vec3::Z),
                Vec3::Z,
            )
        };
        let lit = away.diffuse * (wi.z / std::f32::consts::PI) * bump_shadowing(unbent, wi);
        assert!(lit.x > 0.01 && (bsdf_eval(&away, below, wi) - lit).abs().max_element() < 1e-3);
        for (l, wo) in [(bent, wo), (away, below)] {
            let mut sampled = 0;
            for i in 0..200u32 {
                let r = |k| random(i, k, 0, Purpose::Bench, 6);
                let Some(bs) = bsdf_sample(&l, wo, r(0), Vec2::new(r(1), r(2))) else {
                    continue;
                };
                sampled += 1;
                let f = bsdf_eval(&l, wo, bs.wi) / bs.pdf;
                assert!((bs.weight - f).abs().max_element() < 1e-4 * f.max_element().max(1.0));
            }
            assert!(sampled > 100, "{sampled} of 200 sampled");
        }
    }

    /// A normal tilted past the view's mirror angle is turned back towards the geometric one
    /// just far enough that its reflection clears the surface (by min(0.9 wo·ng, 0.01)); one
    /// whose reflection clears it already is kept.
    #[test]
    fn a_normal_past_the_mirror_angle_is_turned_back_just_enough() {
        let ng = Vec3::Z;
        for i in 0..2000u32 {
            let r = |k| random(i, k, 0, Purpose::Bench, 9);
            let wo = dir_from_angle(1.55 * r(0), 6.3 * r(1));
            let n = dir_from_angle(1.5 * r(2), 6.3 * r(3));
            let v = valid_reflection_normal(ng, wo, n);
            let t = (0.9 * wo.z).min(0.01);
            if reflect(wo, n).z >= t {
                assert_eq!(v, n);
                continue;
            }
            assert!((v.length() - 1.0).abs() < 1e-5 && v.z > 0.0, "{v}");
            let height = reflect(wo, v).z;
            assert!(
                (height - t).abs() < 2e-3,
                "wo {wo} n {n}: turned to {v}, reflection height {height}, wanted {t}"
            );
            // In the plane of n and ng, between them.
            assert!(
                v.dot(n.cross(ng)).abs() < 1e-4,
                "{v} off the plane of {n} and ng"
            );
            assert!(v.z >= n.z - 1e-5, "{v} not towards ng from {n}");
        }
    }

    /// The dielectric Fresnel: F0 at normal incidence, 1 at grazing, and its cosine-weighted
    /// mean (`fresnel_dielectric_mean`, a fit) against a midpoint sum.
    #[test]
    fn fresnel_dielectric_and_its_mean() {
        for f0 in [0.02f32, 0.04, 0.1, 0.25] {
            let eta = ior_from_f0(f0);
            assert!((fresnel_dielectric(1.0, eta) - f0).abs() < 1e-6);
            assert!((fresnel_dielectric(0.0, eta) - 1.0).abs() < 1e-6);
            let n = 20_000;
            let mean: f32 = (0..n)
                .map(|i| {
                    let mu = (i as f32 + 0.5) / n as f32;
                    2.0 * mu * fresnel_dielectric(mu, eta) / n as f32
                })
                .sum();
            assert!(
                (fresnel_dielectric_mean(eta) - mean).abs() < 0.0065,
                "η {eta}: fit {} vs {mean}",
                fresnel_dielectric_mean(eta)
            );
        }
        assert_eq!(fresnel_dielectric(0.5, 1.0), 0.0);
    }

    #[test]
    fn tonemap_is_monotone_and_bounded() {
        let mut last = -1.0;
        for i in 0..100 {
            let v = tonemap_filmic(Vec3::splat(i as f32 * 0.2)).x;
            assert!(v >= last && (0.0..=1.0).contains(&v));
            last = v;
        }
        assert_eq!(linear_to_srgb(0.0), 0.0);
        assert!((linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
    }
}
