//! Stage 5: intersect rays with the displaced surface.
//!
//! One closed set of methods (`Method`), one file each, all behind `Intersector` and all
//! returning the same `Hit`, so renders and error metrics compare like with like. As in
//! pbrt, `intersect` is the cheap test (t, prism, barycentrics, steps); `Hit::surface` then
//! builds the full surface data on the canonical surface (`canonical::surface_point`).

pub mod reference;

use glam::{Vec2, Vec3};

pub mod cells;
pub mod nonlinear;
pub mod pdm;
pub mod prism_hit;
pub mod rmip;

#[cfg(test)]
mod closed_meshes;

/// Miss / no-prism sentinels (mirrored in WGSL).
pub const NO_PRISM: u32 = u32::MAX;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
    pub t_min: f32,
    pub t_max: f32,
}

impl Ray {
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Ray {
            origin,
            dir,
            t_min: 0.0,
            t_max: f32::INFINITY,
        }
    }
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// Counters that seed every random number a ray uses (see `rng`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayContext {
    pub pixel: u32,
    pub sample: u32,
    pub bounce: u32,
    pub seed: u32,
}

/// The hit record every method returns.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub prism: u32,
    /// Barycentrics (b0, b1, b2) in the prism's base triangle.
    pub bary: Vec3,
    pub uv: Vec2,
    pub position: Vec3,
    /// Unit normal of the displaced surface.
    pub geometric_normal: Vec3,
    /// Shading normal: the smoothed normal (paper §5.1) or the geometric one (`NormalMode`).
    pub shading_normal: Vec3,
    /// Marching / traversal steps taken for this ray (heat-map AOV, bench).
    pub steps: u32,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum NormalMode {
    #[default]
    Smooth,
    Geometric,
}

/// One ray-tracing method over one scene. Implementations: `reference` (tessellated ground
/// truth) and `pdm` (projective displacement mapping); `rmip` and `nonlinear` follow.
pub trait Intersector: Sync {
    fn name(&self) -> &'static str;
    /// Closest hit with `t` in `[ray.t_min, ray.t_max]`, as a full record.
    fn intersect(&self, ray: &Ray, ctx: &RayContext) -> Option<Hit>;
    /// Any hit in the interval (shadow rays).
    fn occluded(&self, ray: &Ray, ctx: &RayContext) -> bool {
        self.intersect(ray, ctx).is_some()
    }
    /// Bytes this method holds beyond the base mesh and the height map (BVHs, tables).
    fn memory_bytes(&self) -> usize;
}
