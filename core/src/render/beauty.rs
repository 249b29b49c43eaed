//! The beauty pass: a progressive path tracer over any intersector. Lighting: the environment
//! (`env`) and up to `lights::MAX_LIGHTS` directional, point, sphere, spot and area lights
//! (one sampled an event, `lights::LightSet`); material: `shading::Material` (Lambert +
//! GGX, mirror below `MIRROR_ROUGHNESS`), one per material of the asset, its base colour,
//! roughness and metallic times optional textures at the hit's UV (`BeautyScene::material_at`),
//! its shading normal bent by an optional normal map (`shade_hit`), and an optional glow
//! (`emission_at`, met by camera and BSDF rays, not sampled as a light); `bounces` surface
//! events; next-event estimation of the environment and a light (directional discs, spheres
//! and area lights are met by BSDF samples too) combined with BSDF sampling by MIS (power
//! heuristic). An optional
//! shadow-catcher ground plane at the asset's lowest point records how much light the asset
//! takes away (alpha), nothing else.
//!
//! Samples are rendered in passes (sample 0 of every pixel, then sample 1, ...) and every
//! random number is `rng::random(pixel, sample, dimension, purpose, seed)`, so the image is the
//! same for any thread count and a run of N samples is the first N of a longer run. Secondary
//! rays are not traced when nothing needs them: no shadow rays without a light to sample, and
//! the last bounce's BSDF ray only asks whether it escapes to the environment (`occluded`),
//! unless some material glows (then it asks what it meets).
//!
//! Output: linear, premultiplied RGBA for the EXR (background alpha 0, RGB 0; shadow catcher
//! RGB 0, alpha = shadow), and a preview composited over the visible environment, filmic
//! tonemapped and sRGB encoded, for the PNG.

use super::camera::Camera;
use super::env::{env_pdf, env_radiance, env_radiance_smooth, env_sample, EnvFrame, EnvMap};
use super::lights::{LightSet, LightsAt};
use super::shading::{
    self, bsdf_eval, bsdf_pdf, bsdf_sample, offset_origin, onb, power_heuristic, Material,
};
use super::RenderSettings;
use crate::bake::Prism;
use crate::rng::{self, Purpose};
use crate::texture::ColorMap;
use crate::trace::{Hit, Intersector, Ray, RayContext};
use glam::{Vec2, Vec3, Vec4};
use rayon::prelude::*;
use serde::Serialize;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Random dimensions per bounce: `rng`'s `bounce` counter is `bounce * DIMS + k` (mirrored
/// in `shaders/beauty.wgsl`).
pub const DIMS: u32 = 8;

/// A directional light: unit direction towards the light and its irradiance at normal incidence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeyLight {
    pub dir: Vec3,
    pub irradiance: f32,
    /// Cosine of the light's angular radius: 1 for a point-like sun (one direction, hard
    /// shadows), below 1 for a disc whose directions each shadow ray draws from (soft
    /// shadows; `--key-angle`, Cycles' sun angle). The irradiance is the disc's whole; a disc
    /// is also found by BSDF samples (`radiance_along`, `escape_radiance`), MIS-weighted.
    pub cos_radius: f32,
    /// The light's colour of unit luminance (`mesh::split_color`; white (1, 1, 1)): what it
    /// casts is `irradiance × color`. The shadow catcher's ratio takes the luminance alone.
    pub color: Vec3,
}

impl KeyLight {
    /// From azimuth/elevation in degrees about the up axis: azimuth 0 = the side the default
    /// camera looks from (+Z for Y-up, −Y for Z-up), 90 = +X; elevation 90 = straight above.
    pub fn from_angles(azimuth_deg: f32, elevation_deg: f32, irradiance: f32, z_up: bool) -> Self {
        let (az, el) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
        let (x, up, front) = (az.sin() * el.cos(), el.sin(), az.cos() * el.cos());
        let dir = if z_up {
            Vec3::new(x, -front, up)
        } else {
            Vec3::new(x, up, front)
        };
        KeyLight {
            dir: dir.normalize(),
            irradiance,
            cos_radius: 1.0,
            color: Vec3::ONE,
        }
    }

    /// The same light in `color` (of unit luminance; `mesh::split_color`).
    pub fn with_color(self, color: Vec3) -> Self {
        KeyLight { color, ..self }
    }

    /// The same light as a disc `diameter_deg` degrees across (0: point-like).
    pub fn with_angle(self, diameter_deg: f32) -> Self {
        KeyLight {
            cos_radius: (0.5 * diameter_deg).to_radians().cos(),
            ..self
        }
    }

    /// The direction a shadow ray towards the light takes for random numbers `u`: `dir`
    /// itself for a point-like light, else uniform in solid angle over the disc's cone.
    #[inline]
    pub fn sample_dir(&self, u: Vec2) -> Vec3 {
        if self.cos_radius >= 1.0 {
            return self.dir;
        }
        let cos = 1.0 - u.x * (1.0 - self.cos_radius);
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let phi = 2.0 * std::f32::consts::PI * u.y;
        let (t, b) = shading::onb(self.dir);
        (t * (sin * phi.cos()) + b * (sin * phi.sin()) + self.dir * cos).normalize()
    }

    /// Density in solid angle of `sample_dir`'s directions, `1 / (2π(1 − cos_radius))`, for a
    /// disc; `None` for a point-like light (a delta no sampled direction meets).
    #[inline]
    pub fn pdf(&self) -> Option<f32> {
        (self.cos_radius < 1.0)
            .then(|| 1.0 / (2.0 * std::f32::consts::PI * (1.0 - self.cos_radius)))
    }

    /// The disc's radiance along a direction `d` from a surface, if `d` lies within its cone:
    /// the irradiance spread evenly over the cone's solid angle (`irradiance × pdf`), so that
    /// a BSDF sample that meets the disc sees what its shadow rays sample.
    #[inline]
    pub fn radiance_along(&self, d: Vec3) -> Option<Vec3> {
        let pdf = self.pdf()?;
        (d.dot(self.dir) >= self.cos_radius).then_some(self.color * (self.irradiance * pdf))
    }
}

/// Random dimension (`rand2`'s `k`, purpose `Light`) of the key light's direction; the
/// environment's sample takes 0 and 1.
pub const KEY_DIM: u32 = 2;

/// Shadow-catcher ground: the plane `p·up = height`, seen only by camera rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ground {
    pub up: Vec3,
    pub height: f32,
}

/// Everything the beauty pass needs besides the intersector and the camera.
#[derive(Clone, Copy)]
pub struct BeautyScene<'a> {
    pub env: &'a EnvMap,
    /// How world directions map into `env` for this frame: its own frame (`EnvMap::frame`),
    /// turned by a turntable that turns the lights (`BeautyScene::turned`).
    pub env_frame: EnvFrame,
    /// Whether the environment lights the scene (false when it is black: no env rays).
    pub env_lights: bool,
    /// The directional and local lights (`lights::LightSet`): one is sampled an event.
    pub lights: LightSet,
    /// The surface's materials: a prism's is `materials[prism.material()]`, the last one for
    /// an index past the end (an asset's triangles without a material, tables without any).
    /// At least one.
    pub materials: &'a [SurfaceMaterial],
    /// Whether some material emits (`SurfaceMaterial::emission`): then a path's last bounce
    /// ray looks for the surface it meets, to count its glow, instead of only testing whether
    /// it escapes.
    pub emissive: bool,
    /// The textures `SurfaceMaterial`'s texture indices index.
    pub textures: &'a [ColorMap],
    /// Per prism, its corners' tangents (`tangent::corner_tangents`), which a material's normal
    /// map is read in; empty where no material has one.
    pub tangents: &'a [[Vec4; 3]],
    /// Per prism, its corners' normals on the base mesh (the undisplaced surface's,
    /// `tangent::corner_normals`), which a normal map bends; empty where no material has one.
    pub base_normals: &'a [[Vec3; 3]],
    /// The traced table's prisms (their material indices).
    pub prisms: &'a [Prism],
    pub ground: Option<Ground>,
    /// Surface events per path, 1..=4 (1 = direct light only).
    pub bounces: u32,
    /// Ray origin offset (world units), from the scene's size.
    pub eps: f32,
    /// The previews' exposure, a factor (2^EV of `--exposure EV`): a display setting, the
    /// linear EXR stays the scene's radiance.
    pub exposure: f32,
}

/// One material of a beauty scene: the BSDF's parameters, the base-colour texture that
/// multiplies its base colour, if any (an index into `BeautyScene::textures`), and the texture
/// channels that multiply its roughness and metallic.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SurfaceMaterial {
    pub material: Material,
    pub texture: Option<u32>,
    pub roughness_texture: Option<TexChannel>,
    pub metallic_texture: Option<TexChannel>,
    /// Texture channels that multiply the clearcoat's weight and roughness.
    pub clearcoat_texture: Option<TexChannel>,
    pub clearcoat_roughness_texture: Option<TexChannel>,
    /// The clearcoat's own normal map, which bends its normal (the shading normal before
    /// `normal_texture` bends it).
    pub clearcoat_normal_texture: Option<NormalTex>,
    pub normal_texture: Option<NormalTex>,
    /// Emitted radiance, linear RGB, times `emission_texture` at the hit if any (an index
    /// into `BeautyScene::textures`).
    pub emission: Vec3,
    pub emission_texture: Option<u32>,
    /// Its alpha (its texture an index into `BeautyScene::textures`), which the GPU's
    /// traversal reads (`render::cutout`; the CPU's `Cutout` holds its own list).
    pub cut: super::cutout::AlphaCut,
}

/// A tangent-space normal map (`texture::NormalMapRef`): one of `BeautyScene::textures`, whose
/// texel times `scale` plus `bias` is the normal in the tangent frame, blended with the
/// surface's normal by `strength` (≥ 0; 1: the map's normal as it is).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NormalTex {
    pub texture: u32,
    pub scale: Vec3,
    pub bias: Vec3,
    pub strength: f32,
}

impl NormalTex {
    /// The map `n` describes, decoded as `BeautyScene::textures[texture]`; a strength below 0
    /// is 0, as Blender clamps it.
    pub fn of(texture: u32, n: &crate::texture::NormalMapRef) -> Self {
        NormalTex {
            texture,
            scale: Vec3::from_array(n.scale),
            bias: Vec3::from_array(n.bias),
            strength: n.strength.max(0.0),
        }
    }
}

/// One channel (0 red, 1 green, 2 blue) of one of `BeautyScene::textures`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TexChannel {
    pub texture: u32,
    pub channel: u8,
}

impl From<Material> for SurfaceMaterial {
    fn from(material: Material) -> Self {
        SurfaceMaterial {
            material,
            ..Default::default()
        }
    }
}

impl BeautyScene<'_> {
    /// The same scene with its environment and lights turned by `angle` radians about `up`
    /// (the asset's up axis, the environment frame's up) through `pivot` (where local lights
    /// turn about: the camera's orbit centre), counter-clockwise seen from above: what a
    /// turntable whose camera orbits by `angle` does to the lights that turn with it. The
    /// ground is a plane across `up` and does not change.
    pub fn turned(&self, up: Vec3, pivot: Vec3, angle: f32) -> Self {
        if angle == 0.0 {
            return *self;
        }
        BeautyScene {
            env_frame: self.env_frame.turned(angle),
            lights: self.lights.turned(up, pivot, angle),
            ..*self
        }
    }

    /// The index into `materials` of prism `prism`'s material.
    #[inline]
    pub fn material_index(&self, prism: u32) -> usize {
        let last = self.materials.len() - 1;
        self.prisms
            .get(prism as usize)
            .map_or(last, |p| (p.material() as usize).min(last))
    }

    /// The material at a hit: its prism's, the base colour times the texture at its UV, the
    /// roughness and metallic times their texture channels there (one lookup where both read
    /// the same texture, as glTF's metallic-roughness texture does), and the clearcoat's
    /// weight and roughness times theirs (the same).
    #[inline]
    pub fn material_at(&self, hit: &Hit) -> Material {
        let s = &self.materials[self.material_index(hit.prism)];
        let mut m = s.material;
        let sample = |t: u32| self.textures[t as usize].sample(hit.uv);
        if let Some(t) = s.texture {
            m.base_color *= sample(t);
        }
        let (r, k) = self.channel_pair(s.roughness_texture, s.metallic_texture, hit.uv);
        (m.roughness, m.metallic) = (m.roughness * r, m.metallic * k);
        let (w, r) = self.channel_pair(s.clearcoat_texture, s.clearcoat_roughness_texture, hit.uv);
        (m.clearcoat, m.clearcoat_roughness) = (m.clearcoat * w, m.clearcoat_roughness * r);
        m
    }

    /// The values of two texture channels at `uv` (1 for a channel that is absent), with one
    /// lookup where both read the same texture (glTF's metallic-roughness texture, or its
    /// clearcoat's two).
    #[inline]
    fn channel_pair(&self, a: Option<TexChannel>, b: Option<TexChannel>, uv: Vec2) -> (f32, f32) {
        let sample = |t: u32| self.textures[t as usize].sample(uv);
        let first = a.map(|c| (c, sample(c.texture)));
        let second = b.map(|c| match first {
            Some((f, v)) if f.texture == c.texture => v[c.channel as usize],
            _ => sample(c.texture)[c.channel as usize],
        });
        (
            first.map_or(1.0, |(c, v)| v[c.channel as usize]),
            second.unwrap_or(1.0),
        )
    }

    /// The radiance a hit's surface emits (either side) towards `-dir`: its material's
    /// emission times its emission texture there, under what its clearcoat (if any) lets
    /// through at that angle (`shading::clearcoat_through`, about `clearcoat_normal`).
    #[inline]
    pub fn emission_at(&self, hit: &Hit, dir: Vec3) -> Vec3 {
        let s = &self.materials[self.material_index(hit.prism)];
        let glow = match s.emission_texture {
            Some(t) => s.emission * self.textures[t as usize].sample(hit.uv),
            None => s.emission,
        };
        if s.material.clearcoat <= 0.0 || glow == Vec3::ZERO {
            return glow;
        }
        let coat = Hit {
            shading_normal: self.clearcoat_normal(hit),
            ..*hit
        };
        let mu = facing_normals(&coat, dir).1.dot(-dir);
        glow * shading::clearcoat_through(&self.material_at(hit), mu)
    }

    /// The hit as the beauty shades it: its shading normal bent by its material's normal map,
    /// if any (`bent_normal`).
    #[inline]
    pub fn shade_hit(&self, mut hit: Hit) -> Hit {
        // No material has a normal map (the tangents are made only where one has).
        if self.tangents.is_empty() {
            return hit;
        }
        let s = &self.materials[self.material_index(hit.prism)];
        if let Some(n) = s.normal_texture.and_then(|nm| self.bent_normal(&hit, nm)) {
            hit.shading_normal = n;
        }
        hit
    }

    /// The normal a hit's clearcoat lies on (as the intersector found the hit): its shading
    /// normal bent by the material's clearcoat normal map, if any, else that normal unbent.
    #[inline]
    pub fn clearcoat_normal(&self, hit: &Hit) -> Vec3 {
        if self.tangents.is_empty() {
            return hit.shading_normal;
        }
        let s = &self.materials[self.material_index(hit.prism)];
        (s.clearcoat_normal_texture)
            .and_then(|nm| self.bent_normal(hit, nm))
            .unwrap_or(hit.shading_normal)
    }

    /// The normal the normal map `nm` gives at a hit: the map's texel, times its scale plus its
    /// bias, is the normal in the tangent frame of the base mesh there (its interpolated
    /// normal, `base_normals`, on the displaced shading normal's side, and the prism's
    /// MikkTSpace tangent made perpendicular to it, `tangent::frame_at`). As in Cycles, whose
    /// Normal Map node reads the undisplaced normal: a map baked against the low-poly mesh
    /// holds all the detail's tilt, so it replaces the displaced surface's normal rather than
    /// bending it again. A strength other than 1 blends it with the hit's shading normal N,
    /// normalize(N + (M − N) · strength), as Cycles' Normal Map node blends it with the
    /// (displaced) surface's normal: 0 leaves the surface's normal. `None` where the frame or
    /// the mapped normal degenerates (a tangent along the normal, a texel that maps to zero).
    #[inline]
    fn bent_normal(&self, hit: &Hit, nm: NormalTex) -> Option<Vec3> {
        let corners = self.tangents.get(hit.prism as usize)?;
        let base = self.base_normals.get(hit.prism as usize)?;
        let b = hit.bary;
        let n = (base[0] * b.x + base[1] * b.y + base[2] * b.z).normalize_or_zero();
        let n = match n.dot(hit.shading_normal) < 0.0 {
            true => -n,
            false => n,
        };
        if n == Vec3::ZERO {
            return None;
        }
        let (t, b) = crate::tangent::frame_at(corners, hit.bary, n)?;
        let c = self.textures[nm.texture as usize].sample(hit.uv) * nm.scale + nm.bias;
        let mut mapped = (t * c.x + b * c.y + n * c.z).normalize_or_zero();
        if nm.strength != 1.0 && mapped != Vec3::ZERO {
            let s = hit.shading_normal;
            mapped = (s + (mapped - s) * nm.strength).normalize_or_zero();
        }
        (mapped != Vec3::ZERO).then_some(mapped)
    }
}

/// Ray counts of a beauty frame (shadow rays by the light they test).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct BeautyCounters {
    /// Closest-hit rays (camera and bounce rays).
    pub rays: u64,
    /// Occlusion rays towards the key light.
    pub key_shadow_rays: u64,
    /// Occlusion rays towards the environment (light samples and last-bounce escapes).
    pub env_shadow_rays: u64,
}

impl BeautyCounters {
    fn add(&mut self, o: &BeautyCounters) {
        self.rays += o.rays;
        self.key_shadow_rays += o.key_shadow_rays;
        self.env_shadow_rays += o.env_shadow_rays;
    }
    pub fn shadow_rays(&self) -> u64 {
        self.key_shadow_rays + self.env_shadow_rays
    }
}

/// One frame: premultiplied linear RGBA and the background seen behind it (for previews).
#[derive(Clone, Debug, PartialEq)]
pub struct BeautyImage {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<[f32; 4]>,
    /// What shows where alpha is below 1 (environment, darkened by catcher shadows).
    pub background: Vec<Vec3>,
    /// What the denoiser needs of each pixel beyond its colour (`Guides`).
    pub guides: Vec<Guides>,
    pub counters: BeautyCounters,
    /// The PNG preview's pixels (`beauty_preview`'s sRGB codes) where the device that rendered
    /// the frame tonemapped it too (the GPU's `tonemap.wgsl`); `None` on the CPU, and cleared
    /// by whatever changes the pixels after the render (the denoiser).
    pub preview: Option<Vec<[u8; 3]>>,
    /// What the previews multiply the radiance by before the filmic curve
    /// (`BeautyScene::exposure`); the EXR's pixels are not scaled.
    pub exposure: f32,
}

/// One pixel's denoising guides and the parts its alpha and background are made of.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Guides {
    /// The first hit's shading normal (facing the camera) summed over the pixel's samples
    /// that hit the asset, divided by all its samples.
    pub normal: Vec3,
    /// The first hit's reflectance (`shading::guide_albedo`), averaged the same way.
    pub albedo: Vec3,
    /// The asset's coverage (alpha without the catcher's shadow).
    pub coverage: f32,
    /// The shadow catcher's share of the pixel (its samples that saw the ground).
    pub ground: f32,
    /// The catcher's shadow there, in [0, 1] (alpha = coverage + ground · shadow).
    pub shadow: f32,
    /// The environment behind the ground's samples, over all samples (the background is the
    /// rest plus this times 1 − shadow).
    pub ground_background: Vec3,
}

/// Per-pixel running sums over samples (the GPU renderer accumulates the same sums and
/// resolves them with `resolve`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelSums {
    pub radiance: Vec3,
    pub surface: f32,
    pub background: Vec3,
    pub ground_background: Vec3,
    pub ground_samples: f32,
    pub ground_lit: f32,
    pub ground_unshadowed: f32,
    /// Sum of the first hits' camera-facing shading normals (`facing_normals`).
    pub normal: Vec3,
    /// Sum of the first hits' reflectances (`shading::guide_albedo`).
    pub albedo: Vec3,
}

impl PixelSums {
    /// The pixel after `spp` samples: premultiplied linear RGBA (alpha = coverage plus the
    /// catcher's shadow) and the background seen behind it.
    pub fn resolve(&self, spp: u32) -> ([f32; 4], Vec3) {
        let k = 1.0 / spp as f32;
        let shadow = self.shadow();
        let alpha = (self.surface + self.ground_samples * shadow) * k;
        let c = self.radiance * k;
        let bg = (self.background + self.ground_background * (1.0 - shadow)) * k;
        ([c.x, c.y, c.z, alpha], bg)
    }

    /// The catcher's shadow: the share of the light its samples lost to the asset.
    fn shadow(&self) -> f32 {
        if self.ground_unshadowed > 0.0 {
            (1.0 - self.ground_lit / self.ground_unshadowed).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// The pixel's guides after `spp` samples (`BeautyImage::guides`).
    pub fn guides(&self, spp: u32) -> Guides {
        let k = 1.0 / spp as f32;
        Guides {
            normal: self.normal * k,
            albedo: self.albedo * k,
            coverage: self.surface * k,
            ground: self.ground_samples * k,
            shadow: self.shadow(),
            ground_background: self.ground_background * k,
        }
    }
}

/// A hit's geometric and shading normals turned to the side `dir` arrives from (the shading
/// normal replaced by the geometric one where it faces away): what the path tracer shades.
#[inline]
pub fn facing_normals(hit: &Hit, dir: Vec3) -> (Vec3, Vec3) {
    let wo = -dir;
    let (mut ng, mut ns) = (hit.geometric_normal, hit.shading_normal);
    if wo.dot(ng) < 0.0 {
        ng = -ng;
        ns = -ns;
    }
    if wo.dot(ns) <= 0.0 {
        ns = ng;
    }
    (ng, ns)
}

/// What one camera sample saw.
#[derive(Clone, Copy, Default)]
struct SampleResult {
    radiance: Vec3,
    surface: bool,
    /// The camera hit's shading normal (`facing_normals`), zero without one.
    normal: Vec3,
    /// The camera hit's reflectance (`shading::guide_albedo`), zero without one.
    albedo: Vec3,
    background: Vec3,
    ground: Option<(f32, f32)>,
}

#[inline]
fn rand2(ctx: &RayContext, bounce: u32, k: u32, purpose: Purpose) -> Vec2 {
    let d = bounce * DIMS + k;
    Vec2::new(
        rng::random(ctx.pixel, ctx.sample, d, purpose, ctx.seed),
        rng::random(ctx.pixel, ctx.sample, d + 1, purpose, ctx.seed),
    )
}

#[inline]
fn shadow_ray(origin: Vec3, dir: Vec3) -> Ray {
    shadow_ray_to(origin, dir, f32::INFINITY)
}

/// A shadow ray that stops `eps` short of `t_max` (a local light's distance: what lies
/// beyond it does not shadow it).
#[inline]
fn shadow_ray_to(origin: Vec3, dir: Vec3, t_max: f32) -> Ray {
    Ray {
        origin,
        dir,
        t_min: 0.0,
        t_max,
    }
}

/// Distance along `ray` to the ground plane, if it is in front and the ray goes down to it.
#[inline]
pub fn ground_hit(g: &Ground, ray: &Ray) -> Option<f32> {
    let denom = ray.dir.dot(g.up);
    if denom >= 0.0 {
        return None;
    }
    let t = (g.height - ray.origin.dot(g.up)) / denom;
    (t > ray.t_min && t < ray.t_max).then_some(t)
}

/// Light reaching a ground point with and without the asset in the way (luminance):
/// (lit, unshadowed). Their ratio is the catcher's visibility.
fn ground_light(
    isect: &dyn Intersector,
    s: &BeautyScene,
    p: Vec3,
    ctx: &RayContext,
    n: &mut BeautyCounters,
) -> (f32, f32) {
    let Some(g) = s.ground else { return (0.0, 0.0) };
    let origin = p + g.up * s.eps;
    let (mut lit, mut all) = (0.0, 0.0);
    // No random numbers are drawn for lights there are none of.
    let light = (!s.lights.is_empty())
        .then(|| {
            s.lights
                .at(origin, g.up)
                .sample(origin, rand2(ctx, 0, KEY_DIM, Purpose::Light))
        })
        .flatten();
    if let Some(ls) = light {
        let cos = ls.dir.dot(g.up);
        if cos > 0.0 && ls.e > 0.0 {
            all += ls.e * cos;
            n.key_shadow_rays += 1;
            if !isect.occluded(&shadow_ray_to(origin, ls.dir, ls.t_max - s.eps), ctx) {
                lit += ls.e * cos;
            }
        }
    }
    if s.env_lights {
        let es = env_sample(s.env, s.env_frame, rand2(ctx, 0, 0, Purpose::Light));
        let cos = es.dir.dot(g.up);
        if cos > 0.0 && es.pdf > 0.0 {
            let e = shading::luminance(env_radiance(s.env, s.env_frame, es.dir)) * cos / es.pdf;
            all += e;
            n.env_shadow_rays += 1;
            if !isect.occluded(&shadow_ray(origin, es.dir), ctx) {
                lit += e;
            }
        }
    }
    (lit, all)
}

/// Light a BSDF sample `bs` (direction `wi`) meets when it leaves the scene: the environment
/// and the directional discs `wi` lies within, each weighted by MIS against its own light
/// samples (weight 1 for a delta lobe, which light samples never find; `lights`: the event's
/// chances).
fn escape_radiance(s: &BeautyScene, lights: &LightsAt, wi: Vec3, bs: &shading::BsdfSample) -> Vec3 {
    let mut l = Vec3::ZERO;
    if s.env_lights {
        let w = if bs.delta {
            1.0
        } else {
            power_heuristic(bs.pdf, env_pdf(s.env, s.env_frame, wi))
        };
        l += env_radiance(s.env, s.env_frame, wi) * w;
    }
    l + lights.escape(wi, (!bs.delta).then_some(bs.pdf))
}

/// What a camera sample's path returns: the radiance towards the camera and the first hit's
/// denoising guides (its facing shading normal and `shading::guide_albedo`), read where the
/// first event shades the hit rather than looked up again.
struct PathResult {
    radiance: Vec3,
    normal: Vec3,
    albedo: Vec3,
}

/// Radiance leaving a camera hit (as the intersector found it: `shade_hit` applies its normal
/// map here) towards the camera: the path tracer proper.
fn surface_radiance(
    isect: &dyn Intersector,
    s: &BeautyScene,
    first: Hit,
    first_dir: Vec3,
    ctx: &RayContext,
    n: &mut BeautyCounters,
) -> PathResult {
    let mut hit = first;
    let mut dir = first_dir;
    let mut throughput = Vec3::ONE;
    let mut radiance = Vec3::ZERO;
    let (mut guide_normal, mut guide_albedo) = (Vec3::ZERO, Vec3::ZERO);
    for bounce in 0..s.bounces {
        if s.emissive {
            radiance += throughput * s.emission_at(&hit, dir);
        }
        let m = &s.material_at(&hit);
        let wo = -dir;
        // The diffuse lies on the shading normal; the specular lobe on that normal turned back
        // where its mirror direction would point into the surface (`valid_reflection_normal`:
        // a normal-mapped or smoothed normal); the clearcoat on the surface before its normal
        // map bends it (or bent by its own), turned back alike.
        let shaded = s.shade_hit(hit);
        let (ng, mut ns) = facing_normals(&shaded, dir);
        if bounce == 0 {
            // The denoiser's normal guide faces the camera.
            (guide_normal, guide_albedo) = (ns, shading::guide_albedo(m));
        }
        // The normal before the normal map bent it: the diffuse is shadowed about it.
        let mut unbent = ns;
        if shaded.shading_normal != hit.shading_normal {
            unbent = facing_normals(&hit, dir).1;
            // A normal map's normal is kept where it faces away from the view, as Cycles
            // keeps it: the diffuse is lit about it (the specular and the clearcoat are
            // turned back below); the surface's own normal gives way to the geometric one
            // there as before.
            let n = shaded.shading_normal;
            ns = if ng.dot(shaded.geometric_normal) < 0.0 {
                -n
            } else {
                n
            };
        }
        let (t, b) = onb(ns);
        let wo_l = shading::to_local(wo, t, b, ns);
        let spec_n = shading::valid_reflection_normal(ng, wo, ns);
        let coat_n = match m.clearcoat > 0.0 {
            true => s.clearcoat_normal(&hit),
            false => shaded.shading_normal,
        };
        let l = &match spec_n != ns || coat_n != shaded.shading_normal || unbent != ns {
            true => {
                let coat = Hit {
                    shading_normal: coat_n,
                    ..hit
                };
                let nc = shading::valid_reflection_normal(ng, wo, facing_normals(&coat, dir).1);
                let local = |n: Vec3| match n == ns {
                    true => Vec3::Z,
                    false => shading::to_local(n, t, b, ns),
                };
                shading::Lobes {
                    unbent_n: local(unbent),
                    ..shading::lobes_framed(m, wo_l, local(spec_n), local(nc))
                }
            }
            false => shading::lobes(m, wo_l.z),
        };
        let p = hit.position;
        let bctx = RayContext {
            bounce: bounce + 1,
            ..*ctx
        };

        // The lights' chances at the point the event's rays leave from (towards ng's side).
        let lights = s.lights.at(offset_origin(p, ng, ng, s.eps), ng);
        let light = (!s.lights.is_empty())
            .then(|| lights.sample(p, rand2(ctx, bounce, KEY_DIM, Purpose::Light)))
            .flatten();
        if let Some(ls) = light {
            let kd = ls.dir;
            let wi_l = shading::to_local(kd, t, b, ns);
            let f = if kd.dot(ng) > 0.0 && ls.e > 0.0 {
                bsdf_eval(l, wo_l, wi_l)
            } else {
                Vec3::ZERO
            };
            if f.max_element() > 0.0 {
                n.key_shadow_rays += 1;
                let ray = shadow_ray_to(offset_origin(p, ng, kd, s.eps), kd, ls.t_max - s.eps);
                if !isect.occluded(&ray, &bctx) {
                    // A disc is also met by BSDF samples (below): the two share it by MIS.
                    let w = ls
                        .mis_pdf
                        .map_or(1.0, |pdf| power_heuristic(pdf, bsdf_pdf(l, wo_l, wi_l)));
                    radiance += throughput * f * ls.color * (ls.e * w);
                }
            }
        }
        if s.env_lights {
            let es = env_sample(s.env, s.env_frame, rand2(ctx, bounce, 0, Purpose::Light));
            if es.pdf > 0.0 && es.dir.dot(ng) > 0.0 {
                let wi_l = shading::to_local(es.dir, t, b, ns);
                let f = bsdf_eval(l, wo_l, wi_l);
                if f.max_element() > 0.0 {
                    n.env_shadow_rays += 1;
                    if !isect.occluded(
                        &shadow_ray(offset_origin(p, ng, es.dir, s.eps), es.dir),
                        &bctx,
                    ) {
                        let w = power_heuristic(es.pdf, bsdf_pdf(l, wo_l, wi_l));
                        radiance += throughput
                            * f
                            * env_radiance(s.env, s.env_frame, es.dir)
                            * (w / es.pdf);
                    }
                }
            }
        }

        let u_lobe = rng::random(
            ctx.pixel,
            ctx.sample,
            bounce * DIMS + 2,
            Purpose::Bsdf,
            ctx.seed,
        );
        let Some(bs) = bsdf_sample(l, wo_l, u_lobe, rand2(ctx, bounce, 3, Purpose::Bsdf)) else {
            break;
        };
        let wi = shading::from_local(bs.wi, t, b, ns);
        if wi.dot(ng) <= 0.0 {
            break;
        }
        throughput *= bs.weight;
        let ray = shadow_ray(offset_origin(p, ng, wi, s.eps), wi);
        let key_seen = s.lights.seen_along(wi);
        // The spheres and area lights the ray meets before the surface count by MIS.
        let meets_local = s.lights.meets_local(ray.origin, wi);
        let met = |t: f32| match meets_local {
            true => lights.met(ray.origin, wi, t, (!bs.delta).then_some(bs.pdf)),
            false => Vec3::ZERO,
        };
        if bounce + 1 == s.bounces {
            if s.emissive || meets_local {
                // Last event: the surface the ray meets counts with its glow, and the lights
                // before it.
                n.rays += 1;
                radiance += throughput
                    * match isect.intersect(&ray, &bctx) {
                        Some(h) if s.emissive => s.emission_at(&h, wi) + met(h.t),
                        Some(h) => met(h.t),
                        None => escape_radiance(s, &lights, wi, &bs) + met(f32::INFINITY),
                    };
                break;
            }
            // Last event: only whether the ray escapes matters.
            if s.env_lights || key_seen {
                if s.env_lights {
                    n.env_shadow_rays += 1;
                } else {
                    n.key_shadow_rays += 1;
                }
                if !isect.occluded(&ray, &bctx) {
                    radiance += throughput * escape_radiance(s, &lights, wi, &bs);
                }
            }
            break;
        }
        n.rays += 1;
        match isect.intersect(&ray, &bctx) {
            Some(h) => {
                radiance += throughput * met(h.t);
                hit = h;
                dir = wi;
            }
            None => {
                radiance +=
                    throughput * (escape_radiance(s, &lights, wi, &bs) + met(f32::INFINITY));
                break;
            }
        }
    }
    PathResult {
        radiance,
        normal: guide_normal,
        albedo: guide_albedo,
    }
}

fn trace_sample(
    isect: &dyn Intersector,
    s: &BeautyScene,
    ray: &Ray,
    ctx: &RayContext,
    n: &mut BeautyCounters,
) -> SampleResult {
    n.rays += 1;
    let hit = isect.intersect(ray, ctx);
    let ground_t = s.ground.as_ref().and_then(|g| ground_hit(g, ray));
    match (hit, ground_t) {
        (Some(h), gt) if gt.is_none_or(|g| h.t <= g) => {
            let path = surface_radiance(isect, s, h, ray.dir, ctx, n);
            SampleResult {
                radiance: path.radiance,
                surface: true,
                normal: path.normal,
                albedo: path.albedo,
                ..Default::default()
            }
        }
        (_, Some(gt)) => SampleResult {
            background: env_radiance_smooth(s.env, s.env_frame, ray.dir),
            ground: Some(ground_light(isect, s, ray.at(gt), ctx, n)),
            ..Default::default()
        },
        _ => SampleResult {
            background: env_radiance_smooth(s.env, s.env_frame, ray.dir),
            ..Default::default()
        },
    }
}

/// Render one beauty frame. `progress` is called with rows finished, scaled to `height`
/// (samples are rendered in passes over the whole image).
pub fn render_beauty(
    isect: &dyn Intersector,
    cam: &Camera,
    settings: &RenderSettings,
    scene: &BeautyScene,
    progress: &(dyn Fn(usize) + Sync),
) -> BeautyImage {
    let (w, h, spp) = (
        settings.width as usize,
        settings.height as usize,
        settings.spp,
    );
    let mut sums = vec![PixelSums::default(); w * h];
    let mut counters = BeautyCounters::default();
    let done = AtomicUsize::new(0);
    let raster = cam.raster(w as u32, h as u32);
    for sample in 0..spp {
        let row_counters: Vec<BeautyCounters> = sums
            .par_chunks_mut(w)
            .enumerate()
            .map(|(y, row)| {
                let mut n = BeautyCounters::default();
                for (x, acc) in row.iter_mut().enumerate() {
                    let pixel = (y * w + x) as u32;
                    let jitter = if spp == 1 {
                        Vec2::splat(0.5)
                    } else {
                        Vec2::new(
                            rng::random(pixel, sample, 0, Purpose::PixelJitter, settings.seed),
                            rng::random(pixel, sample, 1, Purpose::PixelJitter, settings.seed),
                        )
                    };
                    let ray = raster.ray(Vec2::new(x as f32, y as f32) + jitter);
                    let ctx = RayContext {
                        pixel,
                        sample,
                        bounce: 0,
                        seed: settings.seed,
                    };
                    let r = trace_sample(isect, scene, &ray, &ctx, &mut n);
                    acc.radiance += r.radiance;
                    acc.surface += r.surface as u32 as f32;
                    acc.normal += r.normal;
                    acc.albedo += r.albedo;
                    match r.ground {
                        Some((lit, all)) => {
                            acc.ground_samples += 1.0;
                            acc.ground_lit += lit;
                            acc.ground_unshadowed += all;
                            acc.ground_background += r.background;
                        }
                        None => acc.background += r.background,
                    }
                }
                let rows = done.fetch_add(1, Ordering::Relaxed) + 1;
                progress(rows / spp as usize);
                n
            })
            .collect();
        for c in &row_counters {
            counters.add(c);
        }
    }
    let (rgba, background) = sums.iter().map(|a| a.resolve(spp)).unzip();
    BeautyImage {
        width: w as u32,
        height: h as u32,
        rgba,
        background,
        guides: sums.iter().map(|a| a.guides(spp)).collect(),
        counters,
        preview: None,
        exposure: scene.exposure,
    }
}

/// The sRGB preview: radiance plus the background where the asset does not cover the pixel,
/// filmic tonemapped (`preview_pixel`), on all cores; the device's own where it made one
/// (`BeautyImage::preview`).
pub fn beauty_preview(img: &BeautyImage) -> Vec<u8> {
    if let Some(p) = &img.preview {
        return p.iter().flatten().copied().collect();
    }
    let mut rgb = vec![0u8; img.rgba.len() * 3];
    rgb.par_chunks_mut(3 * 1024)
        .zip(
            img.rgba
                .par_chunks(1024)
                .zip(img.background.par_chunks(1024)),
        )
        .for_each(|(out, (rgba, bg))| {
            for ((o, c), b) in out.chunks_exact_mut(3).zip(rgba).zip(bg) {
                o.copy_from_slice(&preview_pixel(*c, *b, img.exposure));
            }
        });
    rgb
}

/// One pixel of the preview (premultiplied RGBA over its background), as 8-bit sRGB codes:
/// scaled by `exposure`, the filmic curve, then the sRGB curve rounded half away from zero.
/// `tonemap.wgsl` mirrors it.
#[inline]
pub fn preview_pixel(c: [f32; 4], background: Vec3, exposure: f32) -> [u8; 3] {
    let lin = (Vec3::new(c[0], c[1], c[2]) + background) * exposure;
    let t = shading::tonemap_filmic(lin);
    t.to_array()
        .map(|v| (shading::linear_to_srgb(v) * 255.0).round() as u8)
}

/// Offset for ray origins: a relative 1e-4 of the scene diagonal clears PDM's refined hit
/// error (about 1e-5 relative) and f32 rounding of coordinates far from the origin.
pub fn scene_epsilon(lo: Vec3, hi: Vec3) -> f32 {
    let diag = (hi - lo).length();
    let far = lo.abs().max(hi.abs()).max_element();
    (1e-4 * diag).max(32.0 * f32::EPSILON * far).max(1e-6)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::{Sampler, UvTransform};

    /// A normal map is read about the base mesh's normal, not the displaced surface's: a map
    /// of flat texels (0, 0, 1) gives the undisplaced normal wherever the displacement tilts
    /// the surface (Cycles' Normal Map node; a map baked against the low-poly mesh holds the
    /// detail's whole tilt). The same for the clearcoat's own map; without a map the coat lies
    /// on the displaced normal.
    #[test]
    fn a_normal_map_is_read_about_the_undisplaced_normal() {
        let flat = ColorMap {
            width: 1,
            height: 1,
            texels: vec![Vec3::new(0.5, 0.5, 1.0)],
            sampler: Sampler::default(),
            transform: UvTransform::IDENTITY,
            name: "flat".into(),
        };
        let map = NormalTex {
            texture: 0,
            scale: Vec3::splat(2.0),
            bias: Vec3::splat(-1.0),
            strength: 1.0,
        };
        let env = EnvMap::constant(
            Vec3::ONE,
            EnvFrame {
                z_up: false,
                rotation: 0.0,
            },
        );
        let base = Vec3::new(0.0, 0.3, 1.0).normalize();
        let materials = [
            SurfaceMaterial {
                normal_texture: Some(map),
                clearcoat_normal_texture: Some(map),
                ..Default::default()
            },
            SurfaceMaterial {
                normal_texture: Some(map),
                ..Default::default()
            },
        ];
        let tangents = [[Vec4::new(1.0, 0.0, 0.0, 1.0); 3]];
        let base_normals = [[base; 3]];
        let scene = |m: usize| BeautyScene {
            env: &env,
            env_frame: env.frame,
            env_lights: true,
            lights: LightSet::none(),
            materials: &materials[m..m + 1],
            emissive: false,
            textures: std::slice::from_ref(&flat),
            tangents: &tangents,
            base_normals: &base_normals,
            prisms: &[],
            ground: None,
            bounces: 1,
            eps: 1e-4,
            exposure: 1.0,
        };
        let displaced = Vec3::new(0.5, -0.2, 1.0).normalize();
        let hit = Hit {
            t: 1.0,
            prism: 0,
            bary: Vec3::new(0.2, 0.3, 0.5),
            uv: Vec2::new(0.5, 0.5),
            position: Vec3::ZERO,
            geometric_normal: displaced,
            shading_normal: displaced,
            steps: 0,
        };
        let s = scene(0);
        let shaded = s.shade_hit(hit).shading_normal;
        assert!((shaded - base).length() < 1e-5, "{shaded} vs {base}");
        assert!((s.clearcoat_normal(&hit) - base).length() < 1e-5);
        assert_eq!(scene(1).clearcoat_normal(&hit), displaced);

        // A Normal Map Strength other than 1 blends the map's normal with the displaced
        // surface's, normalize(N + (M − N) s), as Cycles does: 0 leaves the surface's, 2 goes
        // past the map's; the clearcoat's map the same.
        for strength in [0.0, 0.5, 2.0] {
            let blended = [SurfaceMaterial {
                normal_texture: Some(NormalTex { strength, ..map }),
                clearcoat_normal_texture: Some(NormalTex { strength, ..map }),
                ..Default::default()
            }];
            let s = BeautyScene {
                materials: &blended,
                ..scene(0)
            };
            let want = (displaced + (base - displaced) * strength).normalize();
            let shaded = s.shade_hit(hit).shading_normal;
            assert!(
                (shaded - want).length() < 1e-5,
                "{strength}: {shaded} vs {want}"
            );
            let coat = s.clearcoat_normal(&hit);
            assert!(
                (coat - want).length() < 1e-5,
                "{strength}: {coat} vs {want}"
            );
        }
    }
}
