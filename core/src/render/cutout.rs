//! Materials whose alpha cuts their surface away (`mesh::AlphaMode`): `Cutout` wraps any
//! intersector and passes rays through the parts of its hits that the alpha takes away, as
//! Cycles passes them through a Principled BSDF's Alpha (a transparent closure of weight
//! 1 − alpha).
//!
//! A hit where the surface is there with probability c (`AlphaCut::coverage`: 1 or 0 under a
//! mask, the alpha itself when blended) is kept when a random number keyed by the ray's
//! counters and the hit's prism is below c; otherwise the ray goes on from just past it
//! (`t_min` moved by the scene's epsilon) to the next hit, up to `MAX_CUTS` times. Camera,
//! bounce and shadow rays alike, so shadows and the `mask` AOV see the same cut-outs as the
//! beauty, and every method (the wrapped intersector is any).

use crate::bake::Prism;
use crate::mesh::AlphaMode;
use crate::rng::{self, Purpose};
use crate::texture::ColorMap;
use crate::trace::{Hit, Intersector, Ray, RayContext};
use glam::Vec2;

use super::beauty::TexChannel;

/// Surfaces a ray may pass through before it counts as stopped (Blender's default Max
/// Transparent Bounces is 8; cut-out foliage stacks deeper).
pub const MAX_CUTS: u32 = 64;

/// One material's alpha as the render reads it: the factor, times a texture channel if any,
/// under `mode`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlphaCut {
    pub alpha: f32,
    pub mode: AlphaMode,
    /// Into the textures `Cutout::textures` holds.
    pub texture: Option<TexChannel>,
}

impl Default for AlphaCut {
    fn default() -> Self {
        AlphaCut::OPAQUE
    }
}

impl AlphaCut {
    /// An opaque material's.
    pub const OPAQUE: AlphaCut = AlphaCut {
        alpha: 1.0,
        mode: AlphaMode::Opaque,
        texture: None,
    };

    /// The probability that the surface is there at `uv`: under a mask 1 where the alpha is at
    /// least the cutoff and 0 elsewhere (Blender's importer: `1 − (alpha < cutoff)`), blended
    /// the alpha clamped to [0, 1] (a NaN texel: not there).
    #[inline]
    pub fn coverage(&self, textures: &[ColorMap], uv: Vec2) -> f32 {
        let alpha = || {
            self.alpha
                * self.texture.map_or(1.0, |c| {
                    textures[c.texture as usize].sample(uv)[c.channel as usize]
                })
        };
        match self.mode {
            AlphaMode::Opaque => 1.0,
            AlphaMode::Mask(cutoff) => (alpha() >= cutoff) as u32 as f32,
            // A NaN alpha: not there.
            AlphaMode::Blend => match alpha() {
                a if a.is_nan() => 0.0,
                a => a.clamp(0.0, 1.0),
            },
        }
    }
}

/// `inner`'s hits less the cut-away ones. `cuts[prism.material()]` is a prism's material's
/// alpha (the last one past the end, as `BeautyScene::material_index`).
pub struct Cutout<'a> {
    pub inner: &'a dyn Intersector,
    pub cuts: &'a [AlphaCut],
    pub textures: &'a [ColorMap],
    pub prisms: &'a [Prism],
    /// How far past a cut-away hit the ray goes on (`beauty::scene_epsilon`).
    pub eps: f32,
}

impl Cutout<'_> {
    /// Whether the surface is there at hit `h` of the ray of `ctx`.
    #[inline]
    pub fn keeps(&self, h: &Hit, ctx: &RayContext) -> bool {
        let last = self.cuts.len() - 1;
        let m =
            (self.prisms.get(h.prism as usize)).map_or(last, |p| (p.material() as usize).min(last));
        let c = self.cuts[m].coverage(self.textures, h.uv);
        c >= 1.0
            || (c > 0.0
                && rng::random_keyed(
                    ctx.pixel,
                    ctx.sample,
                    ctx.bounce,
                    Purpose::Alpha,
                    ctx.seed,
                    h.prism,
                ) < c)
    }
}

impl Intersector for Cutout<'_> {
    fn name(&self) -> &'static str {
        self.inner.name()
    }

    fn intersect(&self, ray: &Ray, ctx: &RayContext) -> Option<Hit> {
        let mut r = *ray;
        let mut steps = 0;
        for _ in 0..MAX_CUTS {
            let mut h = self.inner.intersect(&r, ctx)?;
            steps += h.steps;
            if self.keeps(&h, ctx) {
                h.steps = steps;
                return Some(h);
            }
            r.t_min = h.t.max(r.t_min) + self.eps;
            if r.t_min >= r.t_max || r.t_min.is_nan() {
                return None;
            }
        }
        None
    }

    fn memory_bytes(&self) -> usize {
        self.inner.memory_bytes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::pdm::{Pdm, PdmOptions};
    use glam::Vec3;

    /// A blended alpha a stops a ray at the front with probability a, else at the back with
    /// a again: a + (1 − a)·a of them, the back taking (1 − a)·a. A mask stops all of them at
    /// the front where the alpha reaches the cutoff, and none below it. Opaque: every one.
    #[test]
    fn rays_pass_through_what_the_alpha_cuts_away() {
        let (scene, _) = crate::test_util::example_with_reference("sphere/sphere.glb");
        let pdm = Pdm::new(scene, PdmOptions::default());
        let (lo, hi) = crate::render::lookdev::surface_bounds(&scene.table);
        let c = (lo + hi) * 0.5;
        let n = 4000;
        // Rays through the example sphere (a closed surface: each meets its front and its
        // back): how many the cut-out sphere stops, and how many of those at its back.
        let stopped = |cut: AlphaCut| {
            let cuts = [cut];
            let cutout = Cutout {
                inner: &pdm,
                cuts: &cuts,
                textures: &[],
                prisms: &scene.table.prisms,
                eps: crate::render::beauty::scene_epsilon(lo, hi),
            };
            let hits: Vec<f32> = (0..n)
                .filter_map(|i| {
                    let a = i as f32 * 2.399;
                    let dir = Vec3::new(0.2 * a.cos(), 0.2 * a.sin(), 1.0).normalize();
                    let ctx = RayContext {
                        pixel: i,
                        ..Default::default()
                    };
                    cutout
                        .intersect(&Ray::new(c - dir * 10.0, dir), &ctx)
                        .map(|h| h.t)
                })
                .collect();
            let back = hits.iter().filter(|&&t| t > 10.0).count();
            (hits.len(), back, n as f32)
        };
        let blend = |alpha| AlphaCut {
            alpha,
            mode: AlphaMode::Blend,
            texture: None,
        };
        for a in [0.25f32, 0.5, 0.8] {
            let (hit, back, n) = stopped(blend(a));
            let (hit, back) = (hit as f32 / n, back as f32 / n);
            eprintln!("blend {a}: {hit:.3} stopped, {back:.3} at the back");
            assert!((hit - (a + (1.0 - a) * a)).abs() < 0.03, "{a}: {hit}");
            assert!((back - (1.0 - a) * a).abs() < 0.03, "{a}: {back}");
        }
        let mask = |alpha| AlphaCut {
            alpha,
            mode: AlphaMode::Mask(0.6),
            texture: None,
        };
        assert_eq!(stopped(mask(0.5)).0, 0);
        let (hit, back, n) = stopped(mask(0.6));
        assert_eq!((hit, back), (n as usize, 0));
        assert_eq!(stopped(AlphaCut::OPAQUE).0, n as usize);
        // Past MAX_CUTS surfaces a ray counts as stopped by none: a blend of 0 lets all through.
        assert_eq!(stopped(blend(0.0)).0, 0);
    }

    /// The coverage of a texture's alpha: the factor times the texel, cut at the mask's cutoff
    /// or clamped when blended; a NaN alpha is not there.
    #[test]
    fn coverage_reads_the_factor_times_the_texture() {
        let map = ColorMap {
            width: 2,
            height: 1,
            texels: vec![Vec3::splat(0.2), Vec3::splat(0.9)],
            sampler: crate::texture::Sampler {
                nearest: true,
                ..Default::default()
            },
            transform: crate::texture::UvTransform::IDENTITY,
            name: "alpha".into(),
        };
        let textures = [map];
        let cut = |alpha, mode| AlphaCut {
            alpha,
            mode,
            texture: Some(TexChannel {
                texture: 0,
                channel: 0,
            }),
        };
        let (left, right) = (Vec2::new(0.25, 0.5), Vec2::new(0.75, 0.5));
        let at = |c: AlphaCut| (c.coverage(&textures, left), c.coverage(&textures, right));
        assert_eq!(at(cut(1.0, AlphaMode::Mask(0.5))), (0.0, 1.0));
        assert_eq!(at(cut(0.5, AlphaMode::Mask(0.5))), (0.0, 0.0));
        let (l, r) = at(cut(0.5, AlphaMode::Blend));
        assert!((l - 0.1).abs() < 1e-6 && (r - 0.45).abs() < 1e-6, "{l} {r}");
        assert_eq!(at(cut(2.0, AlphaMode::Blend)).1, 1.0);
        assert_eq!(at(cut(0.3, AlphaMode::Opaque)), (1.0, 1.0));
        assert_eq!(
            cut(f32::NAN, AlphaMode::Blend).coverage(&textures, left),
            0.0
        );
    }
}
