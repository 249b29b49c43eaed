//! The `reference` method: the canonical surface tessellated at `k`× the texel rate
//! (`tessellate`) and traced with an obvhs triangle BVH. Exact up to `k`; the ground truth of
//! every error figure (the depth error against a finer `k` shrinks as `k` grows, see tests).
//!
//! Departures from a plain obvhs trace, each for watertightness (a leak here would be blamed
//! on the surface):
//! * triangles are tested with the watertight ray-triangle test of Woop, Benthin & Wald 2013
//!   ("Watertight Ray/Triangle Intersection", JCGT 2(1)), including its double-precision
//!   fallback for edge functions that round to zero. obvhs's `Triangle::intersect` is
//!   Möller–Trumbore with its own edge vectors per triangle and a sign-bit test that rejects
//!   `-0.0`: a ray through a shared edge or vertex can miss both triangles (the
//!   `rays_at_vertices_and_edges_never_leak` test counts such misses);
//! * leaf boxes are padded by `BOX_PAD` of the scene diagonal, because obvhs's slab test has
//!   no rounding allowance (Ize 2013, "Robust BVH Ray Traversal") and a ray through a vertex
//!   on a box corner can miss the box. Measured on the leak test (138 k rays at micro-vertices
//!   and edge midpoints of a closed displaced sphere): unpadded 4 leaks, padded 0; obvhs's
//!   `Triangle::intersect` in place of the watertight test: ~8 000 misses (5.8 %).
//!
//! The hit's `t` and `position = ray.at(t)` are those of the micro-triangle (the tessellated
//! depth is the ground truth); `bary` interpolates the micro-corners' base barycentrics, and
//! uv and normals are those of the canonical surface at `bary` (`canonical::surface_point`).
//!
//! BVH: obvhs BVH2 or CWBVH (`AccelKind`). Measured once on the tessellated test sphere
//! (see `DEFAULT_ACCEL`); the faster is the default.

use super::{Hit, Intersector, NormalMode, Ray, RayContext};
use crate::canonical::{surface_point, PrismGeom, Surface};
use crate::tessellate::{tessellate, tessellation_size, TessMesh, TessSize};
use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::{builder::build_bvh2, Bvh2};
use obvhs::cwbvh::{builder::build_cwbvh, CwBvh};
use obvhs::ray::RayHit;
use obvhs::BvhBuildParams;
use std::time::Duration;

/// Default tessellation rate (micro-vertices per texel along an edge).
pub const DEFAULT_K: f32 = 2.0;

/// Leaf boxes grow by this fraction of the scene diagonal on every side. Far above the
/// slab test's rounding (a few ulps of the coordinates) and far below a micro-triangle of
/// any sane asset (an 8k map at k = 8 gives micro-edges near 2e-5 of the asset).
pub const BOX_PAD: f32 = 1e-6;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AccelKind {
    Bvh2,
    CwBvh,
}

/// Which BVH `Reference::new` builds: CWBVH, measured faster. On the 2-subdivision test
/// sphere (release, one thread, 50 k rays from outside, same padded boxes, same watertight
/// triangle test): k = 8 (297 k micro-triangles) CWBVH 66–91 ms vs BVH2 112–120 ms, 5.0 vs
/// 10.4 triangle tests per hit, 29.8 vs 33.5 MB; k = 2 (20 k) 39–60 ms vs 45–89 ms. CWBVH
/// builds ~1.5× slower (260–300 ms vs 165–180 ms at k = 8), which a ground truth can afford.
pub const DEFAULT_ACCEL: AccelKind = AccelKind::CwBvh;

/// Peak bytes per micro-triangle while `Reference::new` builds: the tessellated mesh, the
/// padded boxes, obvhs's build and the reordered copies live at once. Measured as the VmHWM of
/// `render --method reference --aov depth` less that of the same render at k = 0.01 (10–15
/// MB), over the micro-triangles (2 threads): release: rock k = 8 (3.88 M) 371 B, sphere
/// k = 1 (4.88 M) 387 B and k = 2 (19.60 M) 377 B, torus k = 2 (13.55 M) 372 B; debug (the
/// tests'): rock k = 8 388 B, k = 2.7 (0.45 M) 397 B, sphere k = 1 375 B. Set 13% above the
/// largest.
pub const BUILD_BYTES_PER_MICRO_TRIANGLE: u64 = 450;

/// The memory budget when none is given: 80% of what the system has available
/// (`sysmem::available_bytes`), or `FALLBACK_BUDGET` where that cannot be read.
pub fn default_budget() -> u64 {
    crate::sysmem::available_bytes().map_or(FALLBACK_BUDGET, |b| b / 5 * 4)
}

/// The budget where the available memory cannot be read (no `/proc/meminfo`).
pub const FALLBACK_BUDGET: u64 = 8 << 30;

/// Bytes building a reference of `size` takes at its peak.
pub fn build_bytes(size: TessSize) -> u64 {
    size.triangles
        .saturating_mul(BUILD_BYTES_PER_MICRO_TRIANGLE)
}

fn gib(bytes: u64) -> f64 {
    bytes as f64 / (1u64 << 30) as f64
}

/// Why a reference at `k` does not fit in `budget`, and the density that does (if any).
fn too_large(surface: &Surface, k: f32, size: TessSize, budget: u64) -> String {
    let need = build_bytes(size);
    let mut msg = format!(
        "the reference at --ref-density {k} is {:.2} M micro-triangles, about {:.2} GiB to \
         build, over the {:.2} GiB it may take (--ref-memory GIB; by default 80% of the \
         memory available)",
        size.triangles as f64 * 1e-6,
        gib(need),
        gib(budget),
    );
    // The count grows as k² (edge counts are proportional to k): start just under the root of
    // the ratio, round to two digits, and step down until the exact count fits.
    let mut fit = k * (budget as f32 / need as f32).sqrt() * 0.98;
    for _ in 0..64 {
        let digits = 10f32.powf(1.0 - fit.log10().floor());
        fit = (fit * digits).floor() / digits;
        if fit.is_nan() || fit <= 1e-3 {
            break;
        }
        let size = tessellation_size(surface, fit, None);
        if build_bytes(size) <= budget {
            msg += &format!(
                "; --ref-density {fit} fits ({:.2} M micro-triangles, about {:.2} GiB), or \
                 raise --ref-memory",
                size.triangles as f64 * 1e-6,
                gib(build_bytes(size)),
            );
            return msg;
        }
        fit *= 0.9;
    }
    msg + "; no density fits: even one micro-triangle a face is too many (raise --ref-memory)"
}

enum Accel {
    Bvh2(Bvh2),
    CwBvh(CwBvh),
}

/// Ground-truth intersector over one displaced surface (table, map and seam treatment,
/// borrowed, not copied).
pub struct Reference<'a> {
    pub surface: Surface<'a>,
    pub k: f32,
    pub normal_mode: NormalMode,
    accel: Accel,
    /// Micro-triangles in BVH primitive order (`tris[i]` is BVH primitive `i`).
    tris: Vec<[Vec3A; 3]>,
    tri_prism: Vec<u32>,
    tri_bary: Vec<[Vec3; 3]>,
    /// Base edges clamped by `tessellate::MAX_SEGMENTS` (the reference is coarser there).
    pub capped_edges: usize,
}

impl<'a> Reference<'a> {
    pub fn new(surface: Surface<'a>, k: f32) -> Self {
        Self::with_accel(surface, k, DEFAULT_ACCEL)
    }

    /// `new`, unless building it would take more than `budget` bytes
    /// (`BUILD_BYTES_PER_MICRO_TRIANGLE`): then a message with the size, the budget and a
    /// density that fits (the count's k² scaling, rounded down to two digits and checked),
    /// before any memory is taken.
    pub fn within_budget(surface: Surface<'a>, k: f32, budget: u64) -> Result<Self, String> {
        let size = tessellation_size(&surface, k, None);
        if build_bytes(size) > budget {
            return Err(too_large(&surface, k, size, budget));
        }
        Ok(Self::new(surface, k))
    }

    pub fn with_accel(surface: Surface<'a>, k: f32, kind: AccelKind) -> Self {
        let mesh = tessellate(&surface, k);
        Self::from_mesh(surface, k, &mesh, kind)
    }

    /// Trace an already tessellated surface (e.g. to compare BVH kinds on one mesh).
    pub fn from_mesh(surface: Surface<'a>, k: f32, mesh: &TessMesh, kind: AccelKind) -> Self {
        let tris: Vec<[Vec3A; 3]> = mesh
            .triangles
            .iter()
            .map(|t| t.map(|i| Vec3A::from(mesh.positions[i as usize])))
            .collect();
        let (lo, hi) = mesh
            .positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
                (a.min(p), b.max(p))
            });
        let pad = Vec3A::splat(BOX_PAD * (hi - lo).length().max(f32::MIN_POSITIVE));
        let boxes: Vec<Aabb> = tris
            .iter()
            .map(|t| {
                let b = Aabb::from_points(t);
                Aabb::new(b.min - pad, b.max + pad)
            })
            .collect();
        let params = BvhBuildParams::medium_build();
        let mut build_time = Duration::default();
        let (accel, order) = match kind {
            AccelKind::Bvh2 => {
                let bvh = build_bvh2(&boxes, params, &mut build_time);
                let order = bvh.primitive_indices.clone();
                (Accel::Bvh2(bvh), order)
            }
            AccelKind::CwBvh => {
                let bvh = build_cwbvh(&boxes, params, &mut build_time);
                let order = bvh.primitive_indices.clone();
                (Accel::CwBvh(bvh), order)
            }
        };
        Reference {
            surface,
            k,
            normal_mode: NormalMode::default(),
            accel,
            tris: order.iter().map(|&i| tris[i as usize]).collect(),
            tri_prism: order.iter().map(|&i| mesh.tri_prism[i as usize]).collect(),
            tri_bary: order.iter().map(|&i| mesh.tri_bary[i as usize]).collect(),
            capped_edges: mesh.capped_edges,
        }
    }

    pub fn accel_kind(&self) -> AccelKind {
        match self.accel {
            Accel::Bvh2(_) => AccelKind::Bvh2,
            Accel::CwBvh(_) => AccelKind::CwBvh,
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Generalised winding number of `p` with respect to the micro-triangle mesh (the solid
    /// angle of every triangle, van Oosterom and Strackee 1983, summed over 4π): 1 inside the
    /// closed displaced surface, 0 outside, 2 where it overlaps itself (a displaced crease
    /// folding over). Exact up to rounding away from the mesh. Brute force over every
    /// micro-triangle, in parallel: for the few points a leak count asks about.
    pub fn winding_number(&self, p: Vec3) -> f64 {
        use rayon::prelude::*;
        let p = p.as_dvec3();
        let sum: f64 = self
            .tris
            .par_iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| Vec3::from(v).as_dvec3() - p);
                let (la, lb, lc) = (a.length(), b.length(), c.length());
                let num = a.dot(b.cross(c));
                let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
                2.0 * num.atan2(den)
            })
            .sum();
        sum / (4.0 * std::f64::consts::PI)
    }

    /// Closest micro-triangle hit: (BVH primitive, t, triangle tests).
    fn closest(&self, ray: &Ray) -> Option<(usize, f32, u32)> {
        let wray = WatertightRay::new(ray.origin, ray.dir);
        let oray = obvhs::ray::Ray::new(
            Vec3A::from(ray.origin),
            Vec3A::from(ray.dir),
            ray.t_min,
            ray.t_max,
        );
        let mut tests = 0u32;
        let mut hit = RayHit::none();
        let mut test = |r: &obvhs::ray::Ray, id: usize| {
            tests += 1;
            match wray.intersect(&self.tris[id]) {
                Some((t, _)) if t >= r.tmin && t <= r.tmax => t,
                _ => f32::INFINITY,
            }
        };
        let found = match &self.accel {
            Accel::Bvh2(b) => b.ray_traverse(oray, &mut hit, &mut test),
            Accel::CwBvh(b) => b.ray_traverse(oray, &mut hit, &mut test),
        };
        found.then_some((hit.primitive_id as usize, hit.t, tests))
    }
}

impl Intersector for Reference<'_> {
    fn name(&self) -> &'static str {
        "reference"
    }

    fn intersect(&self, ray: &Ray, _ctx: &RayContext) -> Option<Hit> {
        let (id, t, steps) = self.closest(ray)?;
        // Same inputs, same arithmetic: the winning test hits again.
        let (_, w) = WatertightRay::new(ray.origin, ray.dir).intersect(&self.tris[id])?;
        let corners = &self.tri_bary[id];
        let bary = corners[0] * w[0] + corners[1] * w[1] + corners[2] * w[2];
        let prism = self.tri_prism[id];
        let table = self.surface.table;
        let geom = PrismGeom::new(table, &table.prisms[prism as usize]);
        let sp = surface_point(&geom, &self.surface.prism_displacement(prism), bary);
        Some(Hit {
            t,
            prism,
            bary,
            uv: sp.uv,
            position: ray.at(t),
            geometric_normal: sp.geometric_normal,
            shading_normal: match self.normal_mode {
                NormalMode::Smooth => sp.smooth_normal,
                NormalMode::Geometric => sp.geometric_normal,
            },
            steps,
        })
    }

    fn occluded(&self, ray: &Ray, _ctx: &RayContext) -> bool {
        let wray = WatertightRay::new(ray.origin, ray.dir);
        let oray = obvhs::ray::Ray::new(
            Vec3A::from(ray.origin),
            Vec3A::from(ray.dir),
            ray.t_min,
            ray.t_max,
        );
        let test = |r: &obvhs::ray::Ray, id: usize| match wray.intersect(&self.tris[id]) {
            Some((t, _)) if t >= r.tmin && t <= r.tmax => t,
            _ => f32::INFINITY,
        };
        let miss = match &self.accel {
            Accel::Bvh2(b) => b.ray_traverse_miss(oray, test),
            Accel::CwBvh(b) => b.ray_traverse_miss(oray, test),
        };
        !miss
    }

    fn memory_bytes(&self) -> usize {
        let nodes = match &self.accel {
            Accel::Bvh2(b) => {
                b.nodes.len() * std::mem::size_of::<obvhs::bvh2::node::Bvh2Node>()
                    + b.primitive_indices.len() * 4
            }
            Accel::CwBvh(b) => {
                b.nodes.len() * std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>()
                    + b.primitive_indices.len() * 4
            }
        };
        nodes
            + self.tris.len() * std::mem::size_of::<[Vec3A; 3]>()
            + self.tri_prism.len() * std::mem::size_of::<u32>()
            + self.tri_bary.len() * std::mem::size_of::<[Vec3; 3]>()
    }
}

/// A ray prepared for the watertight test (Woop, Benthin & Wald 2013, §3): the axis where
/// the direction is largest becomes z, and the shear that maps the ray to +z.
#[derive(Clone, Copy, Debug)]
pub struct WatertightRay {
    org: Vec3A,
    k: [usize; 3],
    shear: Vec3A,
}

impl WatertightRay {
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        let d = Vec3A::from(dir);
        let a = d.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding: a negative z swaps x and y.
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        WatertightRay {
            org: Vec3A::from(origin),
            k: [kx, ky, kz],
            shear: Vec3A::new(d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]),
        }
    }

    /// `(t, [w0, w1, w2])` where the ray meets the triangle (edges and corners included), `w`
    /// the barycentrics of the three corners. `t` may be negative: the caller clips it.
    #[inline]
    pub fn intersect(&self, tri: &[Vec3A; 3]) -> Option<(f32, [f32; 3])> {
        let [kx, ky, kz] = self.k;
        let (sx, sy, sz) = (self.shear.x, self.shear.y, self.shear.z);
        let a = tri[0] - self.org;
        let b = tri[1] - self.org;
        let c = tri[2] - self.org;
        let (ax, ay) = (a[kx] - sx * a[kz], a[ky] - sy * a[kz]);
        let (bx, by) = (b[kx] - sx * b[kz], b[ky] - sy * b[kz]);
        let (cx, cy) = (c[kx] - sx * c[kz], c[ky] - sy * c[kz]);
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        // An edge function that rounds to zero decides which side the ray passes; redo it in
        // double, where products of floats are exact, so both faces of the edge agree.
        if u == 0.0 || v == 0.0 || w == 0.0 {
            let (ax, ay, bx, by, cx, cy) = (
                ax as f64, ay as f64, bx as f64, by as f64, cx as f64, cy as f64,
            );
            u = (cx * by - cy * bx) as f32;
            v = (ax * cy - ay * cx) as f32;
            w = (bx * ay - by * ax) as f32;
        }
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 {
            return None;
        }
        let (az, bz, cz) = (sz * a[kz], sz * b[kz], sz * c[kz]);
        let t = (u * az + v * bz + w * cz) / det;
        let inv = 1.0 / det;
        Some((t, [u * inv, v * inv, w * inv]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{random, Purpose};
    use crate::test_util::test_sphere_table;

    fn rnd(i: u32, dim: u32) -> f32 {
        random(i, dim, 0, Purpose::Bench, 0x7e57)
    }

    fn unit_vector(i: u32, dim: u32) -> Vec3 {
        let z = 2.0 * rnd(i, dim) - 1.0;
        let phi = std::f32::consts::TAU * rnd(i, dim + 1);
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Rays from a sphere of radius 3 towards random points near the unit sphere's surface.
    fn random_rays(count: u32) -> Vec<Ray> {
        (0..count)
            .map(|i| {
                let origin = unit_vector(i, 0) * 3.0;
                let target = unit_vector(i, 2) * 0.9;
                Ray::new(origin, (target - origin).normalize())
            })
            .collect()
    }

    fn ctx() -> RayContext {
        RayContext::default()
    }

    #[test]
    fn watertight_test_includes_shared_edges_and_corners() {
        // Breaks if a ray through an edge or vertex shared by two triangles slips between
        // them. A fan of six triangles around an interior vertex; rays at the centre, at the
        // spokes and near them, from many directions.
        let ring: Vec<Vec3A> = (0..6)
            .map(|i| {
                let a = i as f32 * std::f32::consts::TAU / 6.0 + 0.1;
                Vec3A::new(
                    a.cos() * 0.7 + 0.31,
                    a.sin() * 0.7 - 0.17,
                    0.05 * a.sin() + 0.4,
                )
            })
            .collect();
        let centre = Vec3A::new(0.31, -0.17, 0.4);
        let fan: Vec<[Vec3A; 3]> = (0..6)
            .map(|i| [centre, ring[i], ring[(i + 1) % 6]])
            .collect();
        let mut misses = 0;
        for i in 0..20_000u32 {
            let spoke = ring[(i % 6) as usize];
            let s = if i % 7 == 0 { 0.0 } else { rnd(i, 0) };
            let target = Vec3::from(centre + (spoke - centre) * s);
            let mut dir = unit_vector(i, 1);
            if dir.z.abs() < 0.2 {
                dir.z = 0.2f32.copysign(dir.z);
                dir = dir.normalize();
            }
            let origin = target - dir * (1.0 + 10.0 * rnd(i, 3));
            let r = WatertightRay::new(origin, dir);
            match fan.iter().find_map(|t| r.intersect(t)) {
                Some((_, w)) => assert!((w[0] + w[1] + w[2] - 1.0).abs() < 1e-5),
                None => misses += 1,
            }
        }
        assert_eq!(misses, 0);
    }

    #[test]
    fn both_bvh_kinds_agree() {
        let (table, map) = test_sphere_table(1, 16, 0.1);
        let mesh = tessellate(&Surface::open(&table, &map), 2.0);
        let a = Reference::from_mesh(Surface::open(&table, &map), 2.0, &mesh, AccelKind::Bvh2);
        let b = Reference::from_mesh(Surface::open(&table, &map), 2.0, &mesh, AccelKind::CwBvh);
        for ray in random_rays(2000) {
            let (ha, hb) = (a.intersect(&ray, &ctx()), b.intersect(&ray, &ctx()));
            assert_eq!(ha.is_some(), hb.is_some(), "{ray:?}");
            if let (Some(ha), Some(hb)) = (ha, hb) {
                assert!((ha.t - hb.t).abs() < 1e-6, "{ray:?}: {} vs {}", ha.t, hb.t);
            }
            assert_eq!(a.occluded(&ray, &ctx()), ha.is_some());
        }
        assert!(a.memory_bytes() > mesh.triangle_count() * 48);
    }

    #[test]
    fn t_interval_is_respected() {
        let (table, map) = test_sphere_table(1, 16, 0.1);
        let r = Reference::new(Surface::open(&table, &map), 1.0);
        let ray = Ray::new(Vec3::new(0.0, 0.0, 3.0), Vec3::new(0.0, 0.0, -1.0));
        let near = r.intersect(&ray, &ctx()).expect("front hit");
        let mut beyond = ray;
        beyond.t_min = near.t + 1e-3;
        let far = r.intersect(&beyond, &ctx()).expect("back hit");
        assert!(far.t > 3.8 && far.t < 4.2, "{}", far.t);
        let mut short = ray;
        short.t_max = near.t - 1e-3;
        assert!(r.intersect(&short, &ctx()).is_none() && !r.occluded(&short, &ctx()));
    }

    #[test]
    fn rays_at_vertices_and_edges_never_leak() {
        // Breaks if the tessellation has a crack or the triangle / box tests let a ray slip
        // between two micro-triangles: every ray aimed at a point of a closed surface hits it.
        let (table, map) = test_sphere_table(2, 32, 0.15);
        let mesh = tessellate(&Surface::open(&table, &map), 2.0);
        let reference =
            Reference::from_mesh(Surface::open(&table, &map), 2.0, &mesh, DEFAULT_ACCEL);
        let mut targets: Vec<Vec3> = mesh.positions.clone();
        for t in &mesh.triangles {
            let p = t.map(|i| mesh.positions[i as usize]);
            targets.extend([
                (p[0] + p[1]) * 0.5,
                (p[1] + p[2]) * 0.5,
                (p[2] + p[0]) * 0.5,
            ]);
        }
        let (mut leaks, mut obvhs_misses, mut rays) = (0, 0, 0);
        let obvhs_tris: Vec<obvhs::triangle::Triangle> = reference
            .tris
            .iter()
            .map(|t| obvhs::triangle::Triangle {
                v0: t[0],
                v1: t[1],
                v2: t[2],
            })
            .collect();
        for (i, &target) in targets.iter().enumerate() {
            // From inside (the centre), and from outside within 60° of the outward normal:
            // both cross the surface at the target, so neither can miss it by grazing.
            let out = target.normalize();
            let mut side = unit_vector(i as u32, 10);
            side = (side - out * side.dot(out)).normalize_or_zero();
            let cone = 60f32.to_radians() * rnd(i as u32, 12).sqrt();
            let outside = target + (out * cone.cos() + side * cone.sin()) * 3.0;
            for origin in [Vec3::ZERO, outside] {
                let ray = Ray::new(origin, (target - origin).normalize());
                rays += 1;
                if reference.intersect(&ray, &ctx()).is_none() {
                    leaks += 1;
                }
                // The same traversal with obvhs's own triangle test, for the record.
                let oray = obvhs::ray::Ray::new_inf(origin.into(), ray.dir.into());
                let mut hit = RayHit::none();
                let found = match &reference.accel {
                    Accel::Bvh2(b) => {
                        b.ray_traverse(oray, &mut hit, |r, id| obvhs_tris[id].intersect(r))
                    }
                    Accel::CwBvh(b) => {
                        b.ray_traverse(oray, &mut hit, |r, id| obvhs_tris[id].intersect(r))
                    }
                };
                if !found {
                    obvhs_misses += 1;
                }
            }
        }
        eprintln!("{rays} rays at vertices/edge midpoints: {leaks} leaks (watertight test), {obvhs_misses} with obvhs Triangle::intersect");
        assert!(rays >= 100_000, "{rays}");
        assert_eq!(leaks, 0);
    }

    /// Median |Δt| in texel units of `coarse` against `fine`, over rays both hit.
    fn median_depth_error(coarse: &Reference, fine: &Reference, rays: &[Ray]) -> (f32, usize) {
        let mut errs = Vec::new();
        let mut mismatches = 0;
        for ray in rays {
            match (coarse.intersect(ray, &ctx()), fine.intersect(ray, &ctx())) {
                (Some(c), Some(f)) => {
                    let texel = fine.surface.table.prisms[f.prism as usize].texel_world;
                    errs.push((c.t - f.t).abs() / texel);
                }
                (None, None) => {}
                _ => mismatches += 1,
            }
        }
        errs.sort_by(f32::total_cmp);
        (errs[errs.len() / 2], mismatches)
    }

    #[test]
    fn depth_error_converges_as_k_grows() {
        // Breaks if the reference is not a convergent discretisation of the canonical surface.
        let (table, map) = test_sphere_table(2, 32, 0.15);
        let rays = random_rays(2000);
        let fine = Reference::new(Surface::open(&table, &map), 8.0);
        let errs: Vec<(f32, usize)> = [1.0, 2.0, 4.0]
            .iter()
            .map(|&k| {
                median_depth_error(
                    &Reference::new(Surface::open(&table, &map), k),
                    &fine,
                    &rays,
                )
            })
            .collect();
        eprintln!(
            "median |Δt| / texel vs k = 8 (and hit/miss mismatches): k=1 {:?}, k=2 {:?}, k=4 {:?}",
            errs[0], errs[1], errs[2]
        );
        assert!(errs[0].0 > errs[1].0 && errs[1].0 > errs[2].0, "{errs:?}");
        assert!(errs[2].1 <= 5, "{errs:?}");
    }

    /// Would fail if the solid angles were summed with a wrong sign or branch: the winding
    /// number is 1 at the centre of the closed displaced sphere and just under the surface
    /// along a random ray's first hit, and 0 far outside and just above that hit.
    #[test]
    fn winding_number_tells_inside_from_outside() {
        let (table, map) = test_sphere_table(2, 32, 0.15);
        let r = Reference::new(Surface::open(&table, &map), 1.0);
        assert!((r.winding_number(Vec3::ZERO) - 1.0).abs() < 1e-6);
        assert!(r.winding_number(Vec3::splat(5.0)).abs() < 1e-6);
        let mut checked = 0;
        for ray in random_rays(50) {
            let Some(h) = r.intersect(&ray, &ctx()) else {
                continue;
            };
            let eps = 1e-3;
            let before = r.winding_number(ray.at(h.t - eps));
            let after = r.winding_number(ray.at(h.t + eps));
            assert!(
                before.abs() < 1e-3 && (after - 1.0).abs() < 1e-3,
                "{before} {after}"
            );
            checked += 1;
        }
        assert!(checked >= 10, "{checked} rays hit");
    }

    #[test]
    fn hits_lie_on_the_canonical_surface() {
        // Breaks if `bary` does not locate the hit over its base triangle, or the micro-triangles
        // stray from S(b) by more than the interpolation error of their size.
        let (table, map) = test_sphere_table(2, 32, 0.15);
        let rays = random_rays(1000);
        let mut worst = Vec::new();
        for k in [1.0, 2.0, 4.0] {
            let r = Reference::new(Surface::open(&table, &map), k);
            let mut max_err = 0.0f32;
            for ray in &rays {
                let Some(h) = r.intersect(ray, &ctx()) else {
                    continue;
                };
                let p = &table.prisms[h.prism as usize];
                let sp = surface_point(
                    &PrismGeom::new(&table, p),
                    &Surface::open(&table, &map).prism_displacement(h.prism),
                    h.bary,
                );
                assert!(h.bary.min_element() > -1e-5, "{:?}", h.bary);
                assert!((sp.uv - h.uv).length() < 1e-6 && h.position == ray.at(h.t));
                assert!(h.shading_normal.is_normalized() && h.geometric_normal.is_normalized());
                max_err = max_err.max((sp.position - h.position).length() / p.texel_world);
            }
            worst.push(max_err);
        }
        eprintln!(
            "max |S(bary) − hit| / texel: k=1 {}, k=2 {}, k=4 {}",
            worst[0], worst[1], worst[2]
        );
        // Height within a micro-triangle varies by at most (map slope) × (its size, 1/k texel).
        for (i, k) in [1.0f32, 2.0, 4.0].iter().enumerate() {
            assert!(worst[i] < 1.0 / k, "k = {k}: {}", worst[i]);
        }
        assert!(worst[2] < worst[0]);
    }
}
