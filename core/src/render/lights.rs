//! The beauty's lights besides the environment: directional lights (a direction, or a disc as
//! wide as the sun), points, spheres, spots and one-sided rectangles and disks, up to
//! `MAX_LIGHTS`. Each surface event samples one of them, picked by what each casts on that
//! point across its surface (`LightSet::at`), so that a rig of several lights costs one shadow
//! ray an event, as one light does, and the shadow ray goes where the light is.
//!
//! A light with a surface is also met by BSDF samples: a directional disc by those that leave
//! the scene (`LightsAt::escape`), a sphere or an area light by those that reach it before the
//! surface they meet (`LightsAt::met`), so a mirror reflects them. The two estimates share
//! each such light by MIS (power heuristic, the pick's chance in the light sample's density).
//! Points and point spots have no surface: their shadow rays alone find them. Lights cast no
//! shadow on the asset or on each other (a ray passes through them), as in Cycles, and camera
//! rays do not see them.
//!
//! Mirrored in `shaders/beauty.wgsl` (`Light`, `light_sample`, `lights_escape`, `lights_met`),
//! which reads the same numbers from the lighting uniform (`gpu::layout::GpuLight`).

use super::beauty::KeyLight;
use super::shading::{self, power_heuristic};
use glam::{Quat, Vec2, Vec3};

/// The most lights a beauty samples (the GPU's lighting uniform holds this many).
pub const MAX_LIGHTS: usize = 16;

/// Where a light is and what shape it has.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightShape {
    /// Infinitely far, towards the unit direction `dir`: a point-like sun (`cos_radius` 1) or
    /// a disc of that angular radius (`KeyLight`).
    Distant { dir: Vec3, cos_radius: f32 },
    /// At `pos`: a point (`radius` 0) or a sphere of even radiance; a spot where `spot` gives
    /// its cone.
    Local {
        pos: Vec3,
        radius: f32,
        spot: Option<Spot>,
    },
    /// A one-sided emitter of even radiance centred on `pos`: the rectangle `pos ± u ± v`, or
    /// (`disk`) the ellipse `pos + cos φ u + sin φ v`, shining on the side `v × u` points to
    /// (a USD `RectLight`'s or `DiskLight`'s −Z, with `u` along its X and `v` along its Y).
    Area {
        pos: Vec3,
        u: Vec3,
        v: Vec3,
        disk: bool,
    },
}

/// A spot's cone: full intensity within `cos_inner` of `axis` (the unit direction it shines),
/// none past `cos_outer`, between them a smoothstep in the cosine: Cycles' spot, whose blend
/// `b` puts `cos_inner` at `cos_outer + b (1 − cos_outer)` (`Spot::blended`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spot {
    pub axis: Vec3,
    pub cos_inner: f32,
    pub cos_outer: f32,
}

impl Spot {
    /// A cone of half-angle `outer` radians about `axis` whose edge fades over `blend` (0..1)
    /// of the cosine's range, as Blender's spot blend: glTF's inner cone angle `i` is a blend
    /// of `1 − i / outer` (Blender's importer), USD's `shaping:cone:softness` the blend itself.
    pub fn blended(axis: Vec3, outer: f32, blend: f32) -> Self {
        let cos_outer = outer.cos();
        Spot {
            axis,
            cos_inner: cos_outer + blend.clamp(0.0, 1.0) * (1.0 - cos_outer),
            cos_outer,
        }
    }

    /// The cone's factor for light leaving along the unit direction `d`.
    #[inline]
    pub fn falloff(&self, d: Vec3) -> f32 {
        let t = ((d.dot(self.axis) - self.cos_outer) / (self.cos_inner - self.cos_outer).max(1e-6))
            .clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    }
}

/// One light: its shape, what it casts (a directional light's irradiance at normal incidence;
/// a local light's intensity, the irradiance it casts at normal incidence one unit away, along
/// a spot's axis; an area light's radiance), as luminance, and its colour of unit luminance
/// (`mesh::split_color`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    pub shape: LightShape,
    pub power: f32,
    pub color: Vec3,
}

impl From<KeyLight> for Light {
    fn from(k: KeyLight) -> Self {
        Light {
            shape: LightShape::Distant {
                dir: k.dir,
                cos_radius: k.cos_radius,
            },
            power: k.irradiance,
            color: k.color,
        }
    }
}

impl Default for Light {
    fn default() -> Self {
        Light {
            shape: LightShape::Distant {
                dir: Vec3::Y,
                cos_radius: 1.0,
            },
            power: 0.0,
            color: Vec3::ONE,
        }
    }
}

/// A sampled direction towards a light from a surface point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    pub dir: Vec3,
    /// How far the shadow ray goes (+∞ for a directional light).
    pub t_max: f32,
    /// The irradiance at normal incidence it brings, over the pick's chance (luminance; times
    /// `color` for RGB).
    pub e: f32,
    pub color: Vec3,
    /// The sample's density in solid angle times the pick's chance, for MIS against BSDF
    /// samples; `None` where BSDF samples do not meet the light (a point-like sun, a point,
    /// a point spot).
    pub mis_pdf: Option<f32>,
}

/// Where a ray meets a light's surface (`Light::met`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightMet {
    /// Distance along the ray.
    pub t: f32,
    /// The radiance towards the ray's origin (luminance; times the light's `color` for RGB).
    pub radiance: f32,
    /// The density in solid angle of the light's own samples from the ray's origin in the
    /// ray's direction (not yet times the pick's chance).
    pub pdf: f32,
}

impl Light {
    /// A directional light as the `KeyLight` whose sampling and disc it shares; `None` for
    /// another shape.
    fn as_key(&self) -> Option<KeyLight> {
        match self.shape {
            LightShape::Distant { dir, cos_radius } => Some(KeyLight {
                dir,
                irradiance: self.power,
                cos_radius,
                color: self.color,
            }),
            _ => None,
        }
    }

    /// What the light's centre casts on a point at `p` across a surface of unit normal `n`, as
    /// luminance: the weight it is picked by there (`LightSet::at`).
    fn weight_at(&self, p: Vec3, n: Vec3) -> f32 {
        match self.shape {
            LightShape::Distant { dir, .. } => self.power * n.dot(dir).max(0.0),
            LightShape::Area { pos, u, v, disk } => {
                let (area, normal) = area_and_normal(u, v, disk);
                let to = p - pos;
                let d2 = to.length_squared().max(area).max(1e-12);
                let d = d2.sqrt();
                let cosines = (to.dot(normal) / d).max(0.0) * (-to.dot(n) / d).max(0.0);
                self.power * area * cosines / d2
            }
            LightShape::Local { pos, radius, spot } => {
                let to = p - pos;
                let d2 = to.length_squared().max(radius * radius).max(1e-12);
                let d = d2.sqrt();
                let cone = spot.map_or(1.0, |s| s.falloff(to / d));
                self.power * cone * (-to.dot(n) / d).max(0.0) / d2
            }
        }
    }

    /// A direction towards the light from `p` for random numbers `u`, and what it brings (not
    /// yet over the pick's chance); `None` from inside a sphere light.
    fn sample(&self, p: Vec3, u2: Vec2) -> Option<LightSample> {
        match self.shape {
            LightShape::Distant { .. } => {
                let k = self.as_key()?;
                Some(LightSample {
                    dir: k.sample_dir(u2),
                    t_max: f32::INFINITY,
                    e: self.power,
                    color: self.color,
                    mis_pdf: k.pdf(),
                })
            }
            LightShape::Area { pos, u, v, disk } => {
                // A point uniform over the shape: its radiance times the shape's area and its
                // cosine over the squared distance (the density's inverse in solid angle).
                let q = match disk {
                    false => pos + u * (2.0 * u2.x - 1.0) + v * (2.0 * u2.y - 1.0),
                    true => {
                        let (r, phi) = (u2.x.sqrt(), 2.0 * std::f32::consts::PI * u2.y);
                        pos + (u * phi.cos() + v * phi.sin()) * r
                    }
                };
                let (area, n) = area_and_normal(u, v, disk);
                let to = q - p;
                let d2 = to.length_squared();
                let d = d2.sqrt();
                if d.is_nan() || d <= 0.0 {
                    return None;
                }
                let dir = to / d;
                let cos_light = (-dir).dot(n).max(0.0);
                Some(LightSample {
                    dir,
                    t_max: d,
                    e: self.power * area * cos_light / d2,
                    color: self.color,
                    // A uniform point's density in solid angle: d² / (A cos) (∞ edge on,
                    // where it brings nothing).
                    mis_pdf: Some(d2 / (area * cos_light)),
                })
            }
            LightShape::Local { pos, radius, spot } => {
                let to = pos - p;
                let d2 = to.length_squared();
                let d = d2.sqrt();
                if !(d > radius && d > 0.0) {
                    return None;
                }
                let centre = to / d;
                let cone = spot.map_or(1.0, |s| s.falloff(-centre));
                if radius <= 0.0 {
                    return Some(LightSample {
                        dir: centre,
                        t_max: d,
                        e: self.power * cone / d2,
                        color: self.color,
                        mis_pdf: None,
                    });
                }
                // Uniform over the cone the sphere fills.
                let one_minus_cos = cone_one_minus_cos(radius * radius, d2);
                let cos = 1.0 - u2.x * one_minus_cos;
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                let phi = 2.0 * std::f32::consts::PI * u2.y;
                let (t, b) = shading::onb(centre);
                let dir =
                    (t * (sin * phi.cos()) + b * (sin * phi.sin()) + centre * cos).normalize();
                // The sphere's radiance (intensity over its disc's area) over the cone's solid
                // angle; the shadow ray stops at the sphere's near side.
                let radiance = self.power / (std::f32::consts::PI * radius * radius);
                let solid_angle = 2.0 * std::f32::consts::PI * one_minus_cos;
                let b_half = dir.dot(to);
                let near = b_half - (b_half * b_half - (d2 - radius * radius)).max(0.0).sqrt();
                Some(LightSample {
                    dir,
                    t_max: near.max(0.0),
                    e: radiance * solid_angle * cone,
                    color: self.color,
                    mis_pdf: Some(1.0 / solid_angle),
                })
            }
        }
    }

    /// Where a ray from `o` along the unit direction `d` meets the light's surface, for BSDF
    /// samples: the near side of a sphere (`None` from inside it, as `sample` gives nothing
    /// there), the front of a rectangle or disk (`None` from behind); points, point spots and
    /// directional lights have no surface here.
    pub fn met(&self, o: Vec3, d: Vec3) -> Option<LightMet> {
        match self.shape {
            LightShape::Distant { .. } => None,
            LightShape::Local { pos, radius, spot } => {
                if radius <= 0.0 {
                    return None;
                }
                let to = pos - o;
                let d2 = to.length_squared();
                let r2 = radius * radius;
                let b_half = d.dot(to);
                let disc = b_half * b_half - (d2 - r2);
                if !(d2 > r2 && b_half > 0.0 && disc >= 0.0) {
                    return None;
                }
                let t = b_half - disc.sqrt();
                let one_minus_cos = cone_one_minus_cos(r2, d2);
                let cone = spot.map_or(1.0, |s| s.falloff(-to / d2.sqrt()));
                Some(LightMet {
                    t: t.max(0.0),
                    radiance: self.power / (std::f32::consts::PI * r2) * cone,
                    pdf: 1.0 / (2.0 * std::f32::consts::PI * one_minus_cos),
                })
            }
            LightShape::Area { pos, u, v, disk } => {
                let (area, n) = area_and_normal(u, v, disk);
                let cos_light = -d.dot(n);
                if cos_light.is_nan() || cos_light <= 0.0 {
                    return None;
                }
                let t = (o - pos).dot(n) / cos_light;
                if !(t > 0.0 && t.is_finite()) {
                    return None;
                }
                // Where on the shape, in its half-extents (its sides are at right angles).
                let local = o + d * t - pos;
                let a = local.dot(u) / u.length_squared();
                let b = local.dot(v) / v.length_squared();
                let inside = match disk {
                    true => a * a + b * b <= 1.0,
                    false => a.abs() <= 1.0 && b.abs() <= 1.0,
                };
                inside.then(|| LightMet {
                    t,
                    radiance: self.power,
                    pdf: t * t / (area * cos_light),
                })
            }
        }
    }

    /// The same light turned by `rot` about `pivot` (a turntable that turns the lights).
    fn turned(&self, rot: Quat, pivot: Vec3) -> Self {
        let shape = match self.shape {
            LightShape::Distant { dir, cos_radius } => LightShape::Distant {
                dir: (rot * dir).normalize(),
                cos_radius,
            },
            LightShape::Local { pos, radius, spot } => LightShape::Local {
                pos: pivot + rot * (pos - pivot),
                radius,
                spot: spot.map(|s| Spot {
                    axis: (rot * s.axis).normalize(),
                    ..s
                }),
            },
            LightShape::Area { pos, u, v, disk } => LightShape::Area {
                pos: pivot + rot * (pos - pivot),
                u: rot * u,
                v: rot * v,
                disk,
            },
        };
        Light { shape, ..*self }
    }
}

/// 1 − cos of the half-angle of the cone a sphere of squared radius `r2` fills seen from
/// squared distance `d2`, without the cancellation of 1 − √(1 − s²) for a small, far sphere.
#[inline]
fn cone_one_minus_cos(r2: f32, d2: f32) -> f32 {
    let s2 = r2 / d2;
    s2 / (1.0 + (1.0 - s2).max(0.0).sqrt())
}

/// An area light's area and the unit normal of the side it shines on (`LightShape::Area`).
pub fn area_and_normal(u: Vec3, v: Vec3, disk: bool) -> (f32, Vec3) {
    let c = v.cross(u);
    let area = match disk {
        true => std::f32::consts::PI * c.length(),
        false => 4.0 * c.length(),
    };
    (area, c.normalize_or_zero())
}

/// The colour of a black body at `kelvin` (clamped to 1 000–10 000 K, as UsdLux's table is), in
/// linear Rec. 709 of unit luminance: Planck's law over 360–830 nm weighed by the CIE 1931
/// colour matching functions in Wyman, Sloan and Shirley's analytic fit (2013). Within 2% of
/// `UsdLuxBlackbodyTemperatureAsRgb` per channel (which is not white at 6 500 K either:
/// about 1.04, 0.98, 1.03).
pub fn blackbody(kelvin: f32) -> Vec3 {
    let t = kelvin.clamp(1000.0, 10_000.0) as f64;
    // g(λ; μ, σ below μ, σ above μ).
    let g = |l: f64, mu: f64, s1: f64, s2: f64| {
        let s = if l < mu { s1 } else { s2 };
        (-0.5 * ((l - mu) / s).powi(2)).exp()
    };
    // h c / k in m·K.
    const C2: f64 = 6.626_070_15e-34 * 2.997_924_58e8 / 1.380_649e-23;
    let mut xyz = [0.0f64; 3];
    for nm in 360..=830 {
        let l = nm as f64;
        let m = l * 1e-9;
        let planck = 1.0 / (m.powi(5) * ((C2 / (m * t)).exp() - 1.0));
        let x = 1.056 * g(l, 599.8, 37.9, 31.0) + 0.362 * g(l, 442.0, 16.0, 26.7)
            - 0.065 * g(l, 501.1, 20.4, 26.2);
        let y = 0.821 * g(l, 568.8, 46.9, 40.5) + 0.286 * g(l, 530.9, 16.3, 31.1);
        let z = 1.217 * g(l, 437.0, 11.8, 36.0) + 0.681 * g(l, 459.0, 26.0, 13.8);
        for (acc, w) in xyz.iter_mut().zip([x, y, z]) {
            *acc += planck * w;
        }
    }
    let [x, y, z] = xyz;
    let rgb = Vec3::new(
        (3.240_454_2 * x - 1.537_138_5 * y - 0.498_531_4 * z) as f32,
        (-0.969_266 * x + 1.876_010_8 * y + 0.041_556 * z) as f32,
        (0.055_643_4 * x - 0.204_025_9 * y + 1.057_225_2 * z) as f32,
    )
    .max(Vec3::ZERO);
    rgb / shading::luminance(rgb)
}

/// The lights a beauty samples.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LightSet {
    lights: [Light; MAX_LIGHTS],
    count: usize,
}

/// The share of an even chance every light keeps at any point (`LightSet::at`), so that a light
/// that seems to cast nothing there (its centre below the horizon, a spot's axis aimed past)
/// still lights what it reaches.
pub const CHANCE_FLOOR: f32 = 0.05;

impl LightSet {
    /// No lights.
    pub fn none() -> Self {
        Self::default()
    }

    /// `lights`, the first `MAX_LIGHTS` of them.
    pub fn new(lights: &[Light]) -> Self {
        let mut set = Self::default();
        let lights = &lights[..lights.len().min(MAX_LIGHTS)];
        set.count = lights.len();
        set.lights[..lights.len()].copy_from_slice(lights);
        set
    }

    /// One light, always picked.
    pub fn one(light: impl Into<Light>) -> Self {
        Self::new(&[light.into()])
    }

    pub fn len(&self) -> usize {
        self.count
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The lights, in order.
    pub fn lights(&self) -> &[Light] {
        &self.lights[..self.count]
    }

    /// The lights as seen from a surface event at `q` (the point its rays leave from: the hit
    /// lifted off the surface) whose geometric normal is `n`: each picked with a chance in
    /// proportion to what it casts on `q` across a surface of normal `n` (its centre's
    /// cosine there, and a spot's cone, an area light's own cosine, the inverse square), but
    /// at least `CHANCE_FLOOR` of an even share; an even chance where none casts anything.
    /// Light samples and the MIS weights of the BSDF samples that meet a light both take
    /// their chances from here.
    #[inline]
    pub fn at(&self, q: Vec3, n: Vec3) -> LightsAt<'_> {
        let mut prob = [0.0; MAX_LIGHTS];
        let mut total = 0.0;
        for (w, l) in prob.iter_mut().zip(self.lights()) {
            let x = l.weight_at(q, n);
            *w = if x.is_finite() { x.max(0.0) } else { 0.0 };
            total += *w;
        }
        let count = self.count as f32;
        let floor = CHANCE_FLOOR / count;
        let mut sum = 0.0;
        for w in prob[..self.count].iter_mut() {
            *w = match total > 0.0 {
                true => (*w / total).max(floor),
                false => 1.0,
            };
            sum += *w;
        }
        for w in prob[..self.count].iter_mut() {
            *w /= sum;
        }
        LightsAt { set: self, prob }
    }

    /// Whether a BSDF sample leaving the scene along `wi` meets some directional disc.
    pub fn seen_along(&self, wi: Vec3) -> bool {
        self.lights().iter().any(|l| match l.shape {
            LightShape::Distant { dir, cos_radius } => {
                cos_radius < 1.0 && wi.dot(dir) >= cos_radius
            }
            LightShape::Local { .. } | LightShape::Area { .. } => false,
        })
    }

    /// Whether a BSDF sample from `o` along `wi` meets a sphere or an area light at all: then
    /// the last event's ray must find how far the surface is, not only whether there is one.
    pub fn meets_local(&self, o: Vec3, wi: Vec3) -> bool {
        self.lights().iter().any(|l| l.met(o, wi).is_some())
    }

    /// The same lights turned by `angle` radians about `up` through `pivot`.
    pub fn turned(&self, up: Vec3, pivot: Vec3, angle: f32) -> Self {
        let rot = Quat::from_axis_angle(up, angle);
        let mut set = *self;
        for l in set.lights[..self.count].iter_mut() {
            *l = l.turned(rot, pivot);
        }
        set
    }
}

/// A light set with each light's chance of being picked at one surface event (`LightSet::at`).
#[derive(Clone, Copy, Debug)]
pub struct LightsAt<'a> {
    set: &'a LightSet,
    prob: [f32; MAX_LIGHTS],
}

impl LightsAt<'_> {
    /// Light `i`'s chance of being picked.
    pub fn chance(&self, i: usize) -> f32 {
        self.prob[i]
    }

    /// The light a random number `u` picks, its chance, and `u` stretched back over [0, 1)
    /// within its share (so one light leaves `u` as it is).
    #[inline]
    pub fn pick(&self, u: f32) -> (usize, f32, f32) {
        let n = self.set.count;
        let (mut i, mut start) = (0, 0.0);
        while i + 1 < n && u >= start + self.prob[i] {
            start += self.prob[i];
            i += 1;
        }
        let p = self.prob[i];
        let v = ((u - start) / p).clamp(0.0, 1.0 - f32::EPSILON / 2.0);
        (i, p, v)
    }

    /// A sample of one light, picked by `u.x`, towards it from `p`: what it brings is over
    /// the pick's chance, and so is its density for MIS.
    #[inline]
    pub fn sample(&self, p: Vec3, u: Vec2) -> Option<LightSample> {
        if self.set.count == 0 {
            return None;
        }
        let (i, prob, ux) = self.pick(u.x);
        let s = self.set.lights[i].sample(p, Vec2::new(ux, u.y))?;
        Some(LightSample {
            e: s.e / prob,
            mis_pdf: s.mis_pdf.map(|pdf| pdf * prob),
            ..s
        })
    }

    /// Radiance of the directional discs a BSDF sample leaving the scene along `wi` meets,
    /// each weighted by MIS against its light samples (`bsdf_pdf`: the BSDF sample's density;
    /// `None` for a delta lobe, which light samples never find: weight 1).
    pub fn escape(&self, wi: Vec3, bsdf_pdf: Option<f32>) -> Vec3 {
        let mut l = Vec3::ZERO;
        for (i, light) in self.set.lights().iter().enumerate() {
            let Some(k) = light.as_key() else {
                continue;
            };
            if let (Some(radiance), Some(pdf)) = (k.radiance_along(wi), k.pdf()) {
                let w = bsdf_pdf.map_or(1.0, |b| power_heuristic(b, pdf * self.prob[i]));
                l += radiance * w;
            }
        }
        l
    }

    /// Radiance of the spheres and area lights a BSDF sample from `o` along `wi` meets before
    /// `t_max` (the surface it meets; +∞ if none), each weighted by MIS against its light
    /// samples (`bsdf_pdf` as in `escape`). Lights do not hide one another.
    pub fn met(&self, o: Vec3, wi: Vec3, t_max: f32, bsdf_pdf: Option<f32>) -> Vec3 {
        let mut l = Vec3::ZERO;
        for (i, light) in self.set.lights().iter().enumerate() {
            let Some(m) = light.met(o, wi) else {
                continue;
            };
            if m.t < t_max {
                let w = bsdf_pdf.map_or(1.0, |b| power_heuristic(b, m.pdf * self.prob[i]));
                l += light.color * (m.radiance * w);
            }
        }
        l
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against `UsdLuxBlackbodyTemperatureAsRgb` (usd-core 25.x), per channel within 2% (or
    /// 0.01 where a channel is near 0), and of unit luminance.
    #[test]
    fn a_black_body_has_usd_luxs_colour() {
        for (kelvin, usd) in [
            (1000.0, [4.3055043, 0.11835831, 0.0]),
            (3000.0, [1.7710284, 0.84429353, 0.27203175]),
            (6500.0, [1.0433334, 0.98362446, 1.0346133]),
            (10000.0, [0.8718413, 0.9946879, 1.4299959]),
            (20000.0, [0.8718413, 0.9946879, 1.4299959]),
        ] {
            let ours = blackbody(kelvin);
            for (o, u) in ours.to_array().into_iter().zip(usd) {
                assert!(
                    (o - u).abs() <= (0.02 * u).max(0.01),
                    "{kelvin} K: {ours} against {usd:?}"
                );
            }
            assert!((shading::luminance(ours) - 1.0).abs() < 1e-5);
        }
    }

    /// A point light's sample: straight at it, the inverse square, the shadow ray stopping
    /// there; a sphere far away casts what a point of the same intensity casts; a spot casts
    /// nothing past its cone and all of it within; from inside a sphere, nothing.
    #[test]
    fn local_lights_cast_the_inverse_square() {
        let p = Vec3::ZERO;
        let point = Light {
            shape: LightShape::Local {
                pos: Vec3::new(0.0, 4.0, 0.0),
                radius: 0.0,
                spot: None,
            },
            power: 32.0,
            color: Vec3::ONE,
        };
        let s = point.sample(p, Vec2::new(0.3, 0.7)).unwrap();
        assert_eq!((s.dir, s.t_max, s.e), (Vec3::Y, 4.0, 2.0));
        let sphere = Light {
            shape: LightShape::Local {
                pos: Vec3::new(0.0, 400.0, 0.0),
                radius: 0.5,
                spot: None,
            },
            ..point
        };
        let s = sphere.sample(p, Vec2::new(0.3, 0.7)).unwrap();
        let want = 32.0 / 400.0f32.powi(2);
        assert!((s.e / want - 1.0).abs() < 1e-4, "{} against {want}", s.e);
        assert!(s.t_max > 399.4 && s.t_max < 399.6, "{}", s.t_max);
        let spot = |axis: Vec3| Light {
            shape: LightShape::Local {
                pos: Vec3::new(0.0, 4.0, 0.0),
                radius: 0.0,
                spot: Some(Spot {
                    axis,
                    cos_inner: 0.9,
                    cos_outer: 0.8,
                }),
            },
            ..point
        };
        assert_eq!(spot(Vec3::NEG_Y).sample(p, Vec2::ZERO).unwrap().e, 2.0);
        assert_eq!(spot(Vec3::X).sample(p, Vec2::ZERO).unwrap().e, 0.0);
        assert!(sphere
            .sample(Vec3::new(0.0, 400.2, 0.0), Vec2::ZERO)
            .is_none());
    }

    /// An area light casts its radiance times its area and its cosine over the squared
    /// distance: far off, a rectangle facing the point is a point of that intensity whatever
    /// the sample; seen from behind, nothing; up close under a disk, the mean of its samples is
    /// the disk's irradiance, π L R² / (h² + R²).
    #[test]
    fn area_lights_cast_their_radiance_over_their_area() {
        let rect = Light {
            shape: LightShape::Area {
                pos: Vec3::new(0.0, 100.0, 0.0),
                u: Vec3::new(0.5, 0.0, 0.0),
                v: Vec3::new(0.0, 0.0, -0.25),
                disk: false,
            },
            power: 3.0,
            color: Vec3::ONE,
        };
        // v × u = −Y: it shines down on the origin.
        for u in [Vec2::new(0.1, 0.9), Vec2::new(0.7, 0.3)] {
            let s = rect.sample(Vec3::ZERO, u).unwrap();
            assert!((s.e / (3.0 * 0.5 / 1e4) - 1.0).abs() < 1e-4, "{}", s.e);
        }
        let above = rect
            .sample(Vec3::new(0.0, 200.0, 0.0), Vec2::splat(0.5))
            .unwrap();
        assert_eq!(above.e, 0.0);
        let disk = Light {
            shape: LightShape::Area {
                pos: Vec3::new(0.0, 2.0, 0.0),
                u: Vec3::X,
                v: Vec3::NEG_Z,
                disk: true,
            },
            power: 4.0,
            color: Vec3::ONE,
        };
        let n = 256;
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let s = disk.sample(Vec3::ZERO, u).unwrap();
                sum += s.e * s.dir.y;
            }
        }
        let want = std::f32::consts::PI * 4.0 / 5.0;
        let got = sum / (n * n) as f32;
        assert!((got / want - 1.0).abs() < 1e-3, "{got} against {want}");
    }

    /// A turntable turns local lights about the pivot and directional ones (and a spot's axis,
    /// an area light's sides) about the up axis.
    #[test]
    fn lights_turn_about_the_pivot() {
        let spot = Light {
            shape: LightShape::Local {
                pos: Vec3::new(2.0, 1.0, 0.0),
                radius: 0.0,
                spot: Some(Spot::blended(Vec3::NEG_X, 0.5, 0.2)),
            },
            power: 1.0,
            color: Vec3::ONE,
        };
        let sun = Light::from(KeyLight::from_angles(90.0, 0.0, 1.0, false));
        let set = LightSet::new(&[spot, sun]);
        let turned = set.turned(
            Vec3::Y,
            Vec3::new(1.0, 0.0, 0.0),
            std::f32::consts::FRAC_PI_2,
        );
        let LightShape::Local {
            pos, spot: Some(s), ..
        } = turned.lights()[0].shape
        else {
            unreachable!()
        };
        assert!((pos - Vec3::new(1.0, 1.0, -1.0)).length() < 1e-6, "{pos}");
        assert!((s.axis - Vec3::Z).length() < 1e-6, "{}", s.axis);
        let LightShape::Distant { dir, .. } = turned.lights()[1].shape else {
            unreachable!()
        };
        assert!((dir - Vec3::NEG_Z).length() < 1e-6, "{dir}");
    }

    /// Picks follow the chances at the point (by what each light casts there across the
    /// surface, floored), `u` is stretched back over its share, and one light is always picked
    /// with `u` as it is.
    #[test]
    fn lights_are_picked_by_what_they_cast_on_the_point() {
        let sun = |power| Light {
            power,
            ..Light::default()
        };
        let up = Vec3::Y;
        let set = LightSet::new(&[sun(3.0), sun(1.0)]);
        let at = set.at(Vec3::ZERO, up);
        assert_eq!((at.chance(0), at.chance(1)), (0.75, 0.25));
        assert_eq!(at.pick(0.375), (0, 0.75, 0.5));
        let (i, p, v) = at.pick(0.875);
        assert_eq!((i, p), (1, 0.25));
        assert!((v - 0.5).abs() < 1e-6);
        let one = LightSet::one(sun(1.0));
        assert_eq!(one.at(Vec3::ZERO, up).pick(0.123), (0, 1.0, 0.123));
        // A light that casts nothing keeps a floor of 1/20 of an even share.
        let floored = |at: LightsAt| {
            let (p0, p1) = (at.chance(0), at.chance(1));
            (p1 - 0.025 / 1.025).abs() < 1e-6 && (p0 + p1 - 1.0).abs() < 1e-6
        };
        assert!(floored(
            LightSet::new(&[sun(1.0), sun(0.0)]).at(Vec3::ZERO, up)
        ));
        // A surface facing away from a light: its chance is the floor there, and no light
        // casting anything leaves even chances.
        let towards = |dir: Vec3| Light {
            shape: LightShape::Distant {
                dir,
                cos_radius: 1.0,
            },
            ..sun(1.0)
        };
        let sides = LightSet::new(&[towards(Vec3::Y), towards(Vec3::NEG_Y)]);
        assert!(floored(sides.at(Vec3::ZERO, up)));
        let below = set.at(Vec3::ZERO, Vec3::NEG_Y);
        assert_eq!((below.chance(0), below.chance(1)), (0.5, 0.5));
        // Two equal points: the nearer one is picked by the inverse square, and a spot aimed
        // away keeps the floor.
        let point = |y: f32, spot| Light {
            shape: LightShape::Local {
                pos: Vec3::new(0.0, y, 0.0),
                radius: 0.0,
                spot,
            },
            power: 1.0,
            color: Vec3::ONE,
        };
        let two = LightSet::new(&[point(1.0, None), point(2.0, None)]);
        let at = two.at(Vec3::ZERO, up);
        assert!((at.chance(0) - 0.8).abs() < 1e-6, "{}", at.chance(0));
        let aside = Some(Spot::blended(Vec3::X, 0.3, 0.0));
        assert!(floored(
            LightSet::new(&[point(1.0, None), point(1.0, aside)]).at(Vec3::ZERO, up)
        ));
    }

    /// A BSDF sample along a light sample's direction meets the light where the shadow ray
    /// stops, sees the radiance the sample brought over its density, and the two MIS weights
    /// sum to one: for a sphere, a spot on a sphere, a rectangle and a disk. Points have no
    /// surface to meet; area lights are not met from behind nor spheres from inside.
    #[test]
    fn bsdf_samples_meet_spheres_and_area_lights() {
        let p = Vec3::new(0.3, -0.2, 0.1);
        let sphere = |pos, spot| Light {
            shape: LightShape::Local {
                pos,
                radius: 0.4,
                spot,
            },
            power: 5.0,
            color: Vec3::new(1.2, 1.0, 0.8),
        };
        let area = |pos, disk| Light {
            shape: LightShape::Area {
                pos,
                u: Vec3::new(0.6, 0.0, 0.0),
                v: Vec3::new(0.0, 0.3, -0.4),
                disk,
            },
            power: 2.0,
            color: Vec3::ONE,
        };
        let lights = [
            sphere(Vec3::new(0.5, 3.0, -1.0), None),
            sphere(
                Vec3::new(3.0, 1.0, 2.0),
                Some(Spot::blended(
                    Vec3::new(-1.0, -0.3, -0.5).normalize(),
                    0.6,
                    0.5,
                )),
            ),
            area(Vec3::new(-1.0, 2.0, 0.5), false),
            area(Vec3::new(-2.0, 1.0, 3.0), true),
        ];
        let set = LightSet::new(&lights);
        let at = set.at(p, Vec3::new(0.0, 0.6, 0.8));
        for (i, light) in lights.iter().enumerate() {
            for u in [
                Vec2::new(0.1, 0.2),
                Vec2::new(0.8, 0.55),
                Vec2::new(0.45, 0.95),
            ] {
                let s = light.sample(p, u).unwrap();
                let m = light
                    .met(p, s.dir)
                    .unwrap_or_else(|| panic!("light {i}, {u}"));
                assert!((m.t / s.t_max - 1.0).abs() < 1e-3, "light {i}: {m:?} {s:?}");
                assert!(
                    (m.radiance / m.pdf / s.e - 1.0).abs() < 1e-3,
                    "light {i}: {m:?} {s:?}"
                );
                let prob = at.chance(i);
                let bsdf = 0.37;
                let nee = power_heuristic(s.mis_pdf.unwrap() * prob, bsdf);
                let seen = at.met(p, s.dir, f32::INFINITY, Some(bsdf));
                // Only this light lies along the direction.
                let bsdf_w = seen.x / (light.color.x * m.radiance);
                assert!(
                    (nee + bsdf_w - 1.0).abs() < 1e-4,
                    "light {i}: {nee} + {bsdf_w}"
                );
                assert_eq!(at.met(p, s.dir, m.t * 0.99, Some(bsdf)), Vec3::ZERO);
                assert_eq!(
                    at.met(p, s.dir, f32::INFINITY, None),
                    light.color * m.radiance
                );
            }
        }
        let point = Light {
            shape: LightShape::Local {
                pos: Vec3::Y,
                radius: 0.0,
                spot: None,
            },
            ..lights[0]
        };
        assert_eq!(point.met(Vec3::ZERO, Vec3::Y), None);
        // The rectangle shines along v × u: down and towards +Z; from above it is dark.
        let behind = Vec3::new(-1.0, 3.0, 0.5);
        assert_eq!(lights[2].met(behind, Vec3::NEG_Y), None);
        assert!(lights[2].met(Vec3::new(-1.0, 1.0, 0.5), Vec3::Y).is_some());
        assert_eq!(lights[0].met(Vec3::new(0.5, 3.1, -1.0), Vec3::Y), None);
        assert!(!set.meets_local(p, Vec3::NEG_Y));
    }

    /// The NEE and BSDF weights of a disc sum to one for any direction within it, with the
    /// pick's chance in the light's density.
    #[test]
    fn a_discs_two_estimates_share_it() {
        let disc = Light::from(KeyLight::from_angles(0.0, 60.0, 2.0, false).with_angle(10.0));
        let set = LightSet::new(&[disc, Light::default()]);
        let at = set.at(Vec3::ZERO, Vec3::Y);
        let s = at.sample(Vec3::ZERO, Vec2::new(0.2, 0.4)).unwrap();
        let bsdf = 0.7;
        let nee = power_heuristic(s.mis_pdf.unwrap(), bsdf);
        let radiance = at.escape(s.dir, Some(bsdf));
        let LightShape::Distant { cos_radius, .. } = disc.shape else {
            unreachable!()
        };
        let full = 2.0 / (2.0 * std::f32::consts::PI * (1.0 - cos_radius));
        assert!((radiance.x / full + nee - 1.0).abs() < 1e-5);
    }
}
