//! RMIP: displacement ray tracing via inversion and oblong bounding (Thonat, Georgiev, Beaune
//! & Boubekeur 2023), on the prism BVH shared with PDM.
//!
//! Per candidate prism (`traverse`, the paper's Algorithm 1): the ray's interval in the
//! shared-wall prism (`prism_hit`), its ends projected to texture space by Newton inverse
//! displacement (§4.1, `canonical::project_to_prism`), the projected curve split at the
//! turning points of its implicit quadric `ψ = det(P − O, M, D)` (§4.2, `curve`), then a
//! front-to-back stack of texture-space rectangles: each is culled by the ray against a 3D
//! box built from the rectangular min-max pyramid's displacement range over it (§5,
//! `pyramid`), tightened by projecting the box interval's ends, and split at the midline of its
//! longer side with the crossing taken from the quadric (§4.3); rectangles whose longer side
//! is at most `marching_scale` texels are texel-marched (§4.4), cell edge to cell edge along
//! the quadric, and the first sign change of the ray's height above the surface is refined.
//!
//! The surface is DESIGN.md's canonical `S(b) = P(b) + D(uv(b)) m̂(b)`: the paper's eq. 1
//! (`P + h N/|N|`) is the same surface and its eq. 2/3 project along the same lines
//! `P + λ m`, so no reconciliation of the surface is needed. What differs is the shell: the
//! paper bounds each triangle with its own prism (supplement; built from the normalised
//! direction's range), we use the shared-wall prisms of the bake (`V_i + λ n_i`, one λ range),
//! so neighbours share walls exactly and the paper's guarantee — every point of the prism
//! projects into the triangle — holds for the same reason. Measured deviation against
//! `reference` (k = 2) is in the tests (`tests.rs`) and the report.
//!
//! Departures from the paper, each for a stated reason:
//! * Pyramid compression: built over `cell × cell`-texel cells sized to `width × height`
//!   entries (the supplement's scheme is not public; see `pyramid`). No fractional LoD.
//! * 3D bounds: instead of TFDM's affine arithmetic, the exact box of `P(σ) + λ M(σ)` over
//!   the rectangle ∩ base triangle (a clipped polygon) × the λ range that contains `D/|M|`
//!   (`|M|` bounded over the polygon). Tighter, and as cheap.
//! * Marching reconstructs no micro-triangles: the texel cells are walked on the quadric and a
//!   sign change of `λ|M| − D` between cell edges is refined by regula falsi on the canonical
//!   surface, so hits lie on the same surface as PDM's and the reference's. A ray that enters
//!   and leaves a bump inside one cell (both crossings within a texel) is missed, as a
//!   one-sample-per-cell march would.
//! * Precision: the quadric, its roots and `t` are evaluated in f64 in a prism-local frame
//!   (positions from `V0`, ray origin at the prism entry, texture space in texels from the
//!   first corner), so the method is scale-free; Newton stays in f32 like `canonical`.
//! * UV-degenerate faces have no texture-space parametrisation; they are marched in `t` at
//!   half a texel.
//! * Next to stitched UV seams (`seam`) the height is the stitched `D*`, not the map's: where
//!   a rectangle reaches a seam band its pyramid range is widened by the band's range
//!   (`PrismStitch::band_h`), and the march and refinement evaluate `D*` at the point's
//!   barycentrics. Everything else is unchanged.
//!
//! * Newton's inversion starts from the `λ` of the point's projection on the guess's line,
//!   not the prism's middle `λ`: in a zero-area crease prism that middle is ≈ 0, where the
//!   Jacobian is singular.
//!
//! Open: on `examples/rock` the bench's leak rays (aimed half a texel below the surface)
//! find 37 / 100 000 misses where the reference hits (k = 2; it was 162 with the folded
//! single-quad crease prisms, 53 with crease strips before the inversion start). About half
//! are next to UV seams (the surface tears there, see docs/watertightness.md); the other
//! half are in the crease strips, whose interpolated UVs squeeze the relief into the rounded
//! edge. The closed procedural spheres do not leak.

mod curve;
pub mod pyramid;
mod traverse;

#[cfg(test)]
mod tests;

use crate::accel::Scene;
use crate::bake::Prism;
use crate::canonical::{surface_point, PrismGeom};
use crate::trace::{Hit, Intersector, NormalMode, Ray, RayContext};
use glam::{Vec2, Vec3};
use pyramid::Pyramid;
use std::time::Instant;
use traverse::{march_degenerate, PrismTrace, Setup};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RmipOptions {
    /// Switch from bound subdivision to texel marching when a bound's longer side is at most
    /// this many map texels (the paper's marching scale, §4.4 / Fig. 10).
    pub marching_scale: f32,
    /// RMIP resolution in cells along the map's longer side; `None` = the compressed
    /// `width × height`-entry pyramid (`pyramid::auto_cell`). The map's own size is exact.
    pub resolution: Option<u32>,
    /// Project tightened interval ends during traversal (Alg. 1 line 15; optional, §6).
    pub inversion: bool,
    pub normal_mode: NormalMode,
}

impl Default for RmipOptions {
    fn default() -> Self {
        RmipOptions {
            marching_scale: 8.0,
            resolution: None,
            inversion: true,
            normal_mode: NormalMode::Smooth,
        }
    }
}

pub struct Rmip<'a> {
    scene: &'a Scene,
    opts: RmipOptions,
    pyramid: Pyramid,
    build_seconds: f64,
}

impl<'a> Rmip<'a> {
    /// Build the pyramid over the scene's map (timed: `build_seconds`).
    pub fn new(scene: &'a Scene, opts: RmipOptions) -> Self {
        let t = Instant::now();
        let map = &scene.map;
        let cell = match opts.resolution {
            Some(r) if r > 0 => map.width.max(map.height).div_ceil(r).max(1),
            _ => pyramid::auto_cell(map.width, map.height),
        };
        let pyramid = Pyramid::build(map, cell);
        Rmip {
            scene,
            opts,
            pyramid,
            build_seconds: t.elapsed().as_secs_f64(),
        }
    }

    pub fn options(&self) -> &RmipOptions {
        &self.opts
    }

    pub fn pyramid(&self) -> &Pyramid {
        &self.pyramid
    }

    /// Seconds spent building the pyramid.
    pub fn build_seconds(&self) -> f64 {
        self.build_seconds
    }

    /// The cheap record for one prism (t, prism, barycentrics); `steps` accumulates bounds
    /// popped plus texels marched.
    pub fn intersect_prism(&self, ray: &Ray, prism: u32, steps: &mut u32) -> Option<Hit> {
        let p: &Prism = &self.scene.table.prisms[prism as usize];
        let (t, bary) = match PrismTrace::setup(self, ray, p, prism)? {
            Setup::Traverse(mut tr) => {
                let r = tr.run();
                *steps += tr.steps;
                r?
            }
            Setup::Degenerate {
                local,
                te,
                tx,
                geom,
            } => march_degenerate(self, p, prism, &local, te, tx, &geom, steps)?,
        };
        Some(Hit {
            t,
            prism,
            bary,
            uv: Vec2::ZERO,
            position: ray.at(t),
            geometric_normal: Vec3::ZERO,
            shading_normal: Vec3::ZERO,
            steps: 0,
        })
    }

    /// Fill uv, position and normals from the canonical surface (as PDM does).
    pub fn fill_surface(&self, hit: &mut Hit) {
        let table = &self.scene.table;
        let g = PrismGeom::new(table, &table.prisms[hit.prism as usize]);
        let sp = surface_point(&g, &self.scene.prism_displacement(hit.prism), hit.bary);
        hit.uv = sp.uv;
        hit.position = sp.position;
        hit.geometric_normal = sp.geometric_normal;
        hit.shading_normal = match self.opts.normal_mode {
            NormalMode::Smooth => sp.smooth_normal,
            NormalMode::Geometric => sp.geometric_normal,
        };
    }
}

impl Intersector for Rmip<'_> {
    fn name(&self) -> &'static str {
        "rmip"
    }

    fn intersect(&self, ray: &Ray, _ctx: &RayContext) -> Option<Hit> {
        let mut steps = 0;
        let mut hit = self
            .scene
            .closest_hit(ray, |r, prism| self.intersect_prism(r, prism, &mut steps))?;
        hit.steps = steps;
        self.fill_surface(&mut hit);
        Some(hit)
    }

    fn occluded(&self, ray: &Ray, _ctx: &RayContext) -> bool {
        let mut steps = 0;
        self.scene.any_hit(ray, |r, prism| {
            self.intersect_prism(r, prism, &mut steps).is_some()
        })
    }

    /// The pyramid, BVH nodes and leaf indices, and the prism records.
    fn memory_bytes(&self) -> usize {
        self.pyramid.memory_bytes()
            + self.scene.bvh_bytes()
            + self.scene.table.prisms.len() * std::mem::size_of::<Prism>()
    }
}
