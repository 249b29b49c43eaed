//! Stage 4: a BVH over the prism boxes (obvhs), shared by every intersector.
//!
//! In: a baked `PrismTable` and its `HeightMap`. Out: a `Scene` whose `closest_hit` /
//! `any_hit` walk the BVH and hand each candidate prism to a method-specific closure, so the
//! BVH knows only boxes (obvhs's design) and PDM, RMIP and the nonlinear method reuse one
//! traversal. Boxes are the six shared-wall corners (`PrismTable::prism_aabb`; bilinear walls
//! lie in the hull of their corners), padded by a relative 1e-4 so that hits a method accepts
//! with its edge tolerance, and zero-thickness prisms of a flat mesh, stay inside their box.
//!
//! BVH choice, measured (see `BvhKind`): BVH2 (PLOC, Meister & Bittner 2018, with reinsertion
//! and collapse) against CWBVH (Ylitie et al. 2017, 8-wide, 80-byte nodes, SIMD node tests on
//! the CPU), both built with obvhs's `medium_build` preset. The binary tree is walked in our
//! own four-wide layout (`quads`: up to four children's boxes per node, one 4-lane test).

use crate::bake::PrismTable;
use crate::canonical::Surface;
use crate::heightmap::HeightMap;
use crate::seam::{PrismDisplacement, SeamMode, StitchField};
use crate::trace::{Hit, Ray};
use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::builder::build_bvh2;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::RayHit;
use obvhs::BvhBuildParams;
use quads::{QuadBvh, Visitor};
use std::time::Duration;

mod quads;

/// Relative padding of every prism box (fraction of its diagonal).
const AABB_PAD: f32 = 1e-4;

/// Which obvhs hierarchy traverses the prisms (and PDM's cells).
///
/// First measured with PDM over whole prisms (defaults: dt = auto 0.5 texel, jitter, refine)
/// on a displaced icosphere (5120 prisms, 512² relief map, amplitude ±0.07), 512² primary rays
/// from one thread, release build, on a 2-core machine shared with other builds, two runs
/// each:
///
/// | kind   | Mray/s      | march steps / hit ray | hierarchy bytes |
/// |--------|-------------|-----------------------|-----------------|
/// | Binary | 0.29, 0.27  | 10.4                  | 119 696         |
/// | Wide   | 0.33, 0.27  | 14.1                  |  62 240         |
///
/// Wide was as fast and half the memory, so it was the default. Measured again once PDM marched
/// sub-prism cells (`trace::cells`), on the examples, 512² through their cameras, one thread
/// (`core/examples/trace_primary.rs`), two or three interleaved runs, ns/ray:
///
/// | asset  | method            | Wide        | Binary      | steps / hit    |
/// |--------|-------------------|-------------|-------------|----------------|
/// | sphere | PDM, cells        | 1 053–1 154 | 862–911     | 13.1 → 9.0     |
/// | sphere | PDM, whole prisms | 1 963–2 022 | 1 387–1 483 | 29.3 → 18.2    |
/// | sphere | RMIP              | 2 549–2 631 | 1 893–1 981 | 16.7 → 10.5    |
/// | torus  | PDM, cells        | 568–762     | 414–535     | 5.9 → 4.2      |
/// | torus  | PDM, whole prisms | 644–779     | 652–758     | 11.3 → 9.5     |
/// | torus  | RMIP              | 834–1 129   | 914–936     | 7.4 → 6.2      |
/// | rock   | PDM, cells        | 684–709     | 597–604     | 12.4 → 10.4    |
/// | rock   | PDM, whole prisms | 1 650–1 662 | 1 409–1 495 | 49.3 → 48.1    |
/// | rock   | RMIP              | 2 652–2 667 | 2 455–2 516 | 48.0 → 47.0    |
///
/// The binary hierarchy visits candidates nearer to front-to-back order (fewer marches before
/// the hit), which now outweighs the wider node test: Binary is the default, for every method,
/// at ~10% more memory with cells (sphere 8 685 → 9 499 bytes per triangle). The same hits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BvhKind {
    /// obvhs `Bvh2`, collapsed to four-wide nodes for the walk (`quads`).
    #[default]
    Binary,
    /// obvhs `CwBvh`: compressed 8-wide, 80-byte nodes.
    Wide,
}

enum Bvh {
    Binary(QuadBvh),
    Wide(CwBvh),
}

/// An obvhs hierarchy over boxes whose leaves are `u32` items (prisms, or any finer
/// primitive a method bounds itself: `trace::cells`); it knows only the boxes, and the
/// caller's closure intersects each candidate item.
pub struct BoxBvh {
    /// `None` without boxes (every ray misses).
    bvh: Option<Bvh>,
    kind: BvhKind,
}

/// obvhs's leaf-collapse cost of a node visit relative to one item test. Its presets' 3.0 suits
/// triangles; an item here (a prism's or a cell's interval and march) costs far more than a box
/// test, so fewer items per leaf pay. Instructions in `Pdm::intersect` at 128² (callgrind),
/// 3.0 → 1.0: sphere 81.7M → 76.6M, torus 36.7M → 34.0M, rock 56.3M → 53.6M; 0.3 or one item
/// per leaf was no better. One thread, 512², two runs: PDM sphere 602–647 → 579–582 ns/ray,
/// torus 298–305 → 285–298, rock 408–444 → 395–406; RMIP sphere 1 100–1 172 → 1 057–1 059,
/// torus 548–552 → 487–499, rock 1 610–1 627 → 1 604–1 757 (every method walks this BVH).
/// More nodes: PDM's bytes per triangle (cells and their BVH) 9 499 → 11 436 on the sphere,
/// 9 586 → 11 691 torus, 2 648 → 3 046 rock.
const COLLAPSE_TRAVERSAL_COST: f32 = 1.0;

impl BoxBvh {
    pub fn build(aabbs: &[Aabb], kind: BvhKind) -> Self {
        let bvh = (!aabbs.is_empty()).then(|| {
            let params = BvhBuildParams {
                collapse_traversal_cost: COLLAPSE_TRAVERSAL_COST,
                ..BvhBuildParams::medium_build()
            };
            let mut build_time = Duration::default();
            match kind {
                BvhKind::Binary => {
                    Bvh::Binary(QuadBvh::new(build_bvh2(aabbs, params, &mut build_time)))
                }
                BvhKind::Wide => Bvh::Wide(build_cwbvh(aabbs, params, &mut build_time)),
            }
        });
        BoxBvh { bvh, kind }
    }

    pub fn kind(&self) -> BvhKind {
        self.kind
    }

    /// Number the items in the order the leaves hold them: returns, per new number, the item's
    /// old one (`order[new] = old`), for the caller to reorder its records alike. A leaf's
    /// items are then next to each other in memory, and nearby leaves' mostly too.
    pub fn into_leaf_order(&mut self) -> Vec<u32> {
        let indices = match &mut self.bvh {
            None => return Vec::new(),
            Some(Bvh::Binary(b)) => &mut b.items,
            Some(Bvh::Wide(b)) => &mut b.primitive_indices,
        };
        let identity = (0..indices.len() as u32).collect();
        std::mem::replace(indices, identity)
    }

    /// Bytes of the hierarchy: nodes plus the leaf-to-item index list.
    pub fn bytes(&self) -> usize {
        match &self.bvh {
            None => 0,
            Some(Bvh::Binary(b)) => b.bytes(),
            Some(Bvh::Wide(b)) => {
                b.nodes.len() * std::mem::size_of_val(&b.nodes[0]) + b.primitive_indices.len() * 4
            }
        }
    }

    /// Panics (obvhs asserts) if the hierarchy is malformed or does not bound `aabbs`.
    pub fn validate(&self, aabbs: &[Aabb]) {
        match &self.bvh {
            None => assert!(aabbs.is_empty()),
            Some(Bvh::Binary(b)) => b.validate(aabbs),
            Some(Bvh::Wide(b)) => {
                b.validate(aabbs, false);
            }
        }
    }

    /// Closest hit over all items. `f(ray, item)` intersects one item with the ray clipped
    /// to the closest hit so far (`ray.t_max`) and returns the cheap record.
    #[inline]
    pub fn closest_hit<F: FnMut(&Ray, u32) -> Option<Hit>>(
        &self,
        ray: &Ray,
        mut f: F,
    ) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        let oray = to_obvhs(ray);
        match bvh {
            Bvh::Binary(b) => {
                // Each leaf's items in turn, the ray clipped to the best hit so far.
                struct Closest<F> {
                    ray: Ray,
                    best: Option<Hit>,
                    f: F,
                }
                impl<F: FnMut(&Ray, u32) -> Option<Hit>> Visitor for Closest<F> {
                    #[inline(always)]
                    fn t_max(&self) -> f32 {
                        self.ray.t_max
                    }
                    #[inline(always)]
                    fn leaf(&mut self, items: &[u32], _t: f32) -> bool {
                        for &item in items {
                            if let Some(h) = (self.f)(&self.ray, item) {
                                if h.t < self.ray.t_max {
                                    self.ray.t_max = h.t;
                                    self.best = Some(h);
                                }
                            }
                        }
                        true
                    }
                }
                let mut v = Closest {
                    ray: *ray,
                    best: None,
                    f,
                };
                b.walk(&oray, &mut v);
                v.best
            }
            Bvh::Wide(b) => {
                let mut best: Option<Hit> = None;
                let mut hit = RayHit::none();
                let idx = &b.primitive_indices;
                b.ray_traverse(oray, &mut hit, |r, id| {
                    let clipped = Ray {
                        t_max: r.tmax,
                        ..*ray
                    };
                    match f(&clipped, idx[id]) {
                        Some(h) if h.t < r.tmax => {
                            best = Some(h);
                            h.t
                        }
                        _ => f32::INFINITY,
                    }
                });
                best
            }
        }
    }

    /// Closest hit over items whose test has a cheap first phase and a costly second one.
    /// `enter(ray, item, t_leaf)` is the first: where along the ray the full test would start
    /// (at least `t_leaf`, the entry of the leaf box that holds the item) and what it needs, or
    /// `None` to reject the item; `finish(ray, item, state)` is the full test, the ray clipped
    /// to the best hit so far. Entered items wait in a short list sorted by their start, and
    /// each is finished once the walk pops a node whose box the ray enters after the item
    /// starts: nearly front to back by start, and an item that starts beyond the best hit is
    /// never finished. obvhs's walks (`closest_hit`) finish every item as they reach its leaf,
    /// in the order of the leaves' boxes, so an item whose box the ray enters early but whose
    /// own interval starts late ran in full before a nearer one ended the ray. Popped nodes
    /// are skipped once a hit is nearer than their box.
    ///
    /// Waiting until no node at all is left nearer than the item (the least entry of the whole
    /// stack, an exact front-to-back order) was measured too and is slower: the hits that
    /// shorten the ray come later, and more of the hierarchy is walked before them (PDM's
    /// instructions at 128²: sphere 75.1M → 79.9M, torus 33.1M → 35.8M, rock 46.3M → 52.9M).
    ///
    /// The wide hierarchy finishes each item as its leaf is reached (`closest_hit`).
    #[inline]
    pub fn closest_hit_ordered<S, E, F>(
        &self,
        ray: &Ray,
        mut enter: E,
        mut finish: F,
    ) -> Option<Hit>
    where
        S: Copy,
        E: FnMut(&Ray, u32, f32) -> Option<(f32, S)>,
        F: FnMut(&Ray, u32, S) -> Option<Hit>,
    {
        let b = match self.bvh.as_ref()? {
            Bvh::Binary(b) => b,
            Bvh::Wide(_) => {
                return self.closest_hit(ray, |r, item| {
                    let (_, state) = enter(r, item, r.t_min)?;
                    finish(r, item, state)
                })
            }
        };
        /// The waiting list, the ray clipped to the best hit and the two phases.
        struct Ordered<S, E, F> {
            ray: Ray,
            best: Option<Hit>,
            waiting: Waiting<S>,
            enter: E,
            finish: F,
        }
        impl<S: Copy, E, F> Ordered<S, E, F>
        where
            F: FnMut(&Ray, u32, S) -> Option<Hit>,
        {
            /// Finish one waiting item: the hit, if nearer, ends the ray there.
            #[inline(always)]
            fn run(&mut self, item: u32, state: S) {
                if let Some(h) = (self.finish)(&self.ray, item, state) {
                    if h.t < self.ray.t_max {
                        self.ray.t_max = h.t;
                        self.best = Some(h);
                    }
                }
            }
        }
        impl<S: Copy, E, F> Visitor for Ordered<S, E, F>
        where
            E: FnMut(&Ray, u32, f32) -> Option<(f32, S)>,
            F: FnMut(&Ray, u32, S) -> Option<Hit>,
        {
            #[inline(always)]
            fn t_max(&self) -> f32 {
                self.ray.t_max
            }
            #[inline(always)]
            fn reach(&mut self, t: f32) {
                while let Some((item, state)) = self.waiting.pop_before(t.min(self.ray.t_max)) {
                    self.run(item, state);
                }
            }
            #[inline(always)]
            fn leaf(&mut self, items: &[u32], t: f32) -> bool {
                for &item in items {
                    if let Some((t0, state)) = (self.enter)(&self.ray, item, t) {
                        if t0 < self.ray.t_max {
                            if let Some((i, s)) = self.waiting.insert(t0, item, state) {
                                self.run(i, s);
                            }
                        }
                    }
                }
                true
            }
        }
        let mut v = Ordered {
            ray: *ray,
            best: None,
            waiting: Waiting::<S>::new(),
            enter,
            finish,
        };
        b.walk(&to_obvhs(ray), &mut v);
        v.reach(f32::INFINITY);
        v.best
    }

    /// Whether `f` reports a hit for any candidate item (shadow rays); stops at the first.
    pub fn any_hit<F: FnMut(&Ray, u32) -> bool>(&self, ray: &Ray, mut f: F) -> bool {
        let Some(bvh) = self.bvh.as_ref() else {
            return false;
        };
        let oray = to_obvhs(ray);
        let mut visit = |item: u32| -> f32 {
            if f(ray, item) {
                ray.t_min
            } else {
                f32::INFINITY
            }
        };
        let missed = match bvh {
            Bvh::Binary(b) => {
                // Stops at the first leaf with a hit.
                struct Any<V> {
                    t_max: f32,
                    hit: bool,
                    visit: V,
                }
                impl<V: FnMut(u32) -> f32> Visitor for Any<V> {
                    #[inline(always)]
                    fn t_max(&self) -> f32 {
                        self.t_max
                    }
                    #[inline(always)]
                    fn leaf(&mut self, items: &[u32], _t: f32) -> bool {
                        self.hit = items.iter().any(|&i| (self.visit)(i) < self.t_max);
                        !self.hit
                    }
                }
                let mut v = Any {
                    t_max: ray.t_max,
                    hit: false,
                    visit: &mut visit,
                };
                b.walk(&oray, &mut v);
                !v.hit
            }
            Bvh::Wide(b) => {
                let idx = &b.primitive_indices;
                b.ray_traverse_miss(oray, |_, id| visit(idx[id]))
            }
        };
        !missed
    }
}

/// Everything a ray needs: the prism table, the height map and the BVH over the prisms.
pub struct Scene {
    pub table: PrismTable,
    pub map: HeightMap,
    bvh: BoxBvh,
    seam_mode: SeamMode,
    /// The seam stitch data when `seam_mode` is `Stitch` (empty otherwise).
    stitch: StitchField,
}

impl Scene {
    /// Build with the faster hierarchy for PDM (`BvhKind::default()`).
    pub fn new(table: PrismTable, map: HeightMap) -> Self {
        Self::with_bvh(table, map, BvhKind::default())
    }

    pub fn with_bvh(table: PrismTable, map: HeightMap, kind: BvhKind) -> Self {
        let bvh = BoxBvh::build(&prism_aabbs(&table), kind);
        let stitch = StitchField::build(&table, &map);
        Scene {
            table,
            map,
            bvh,
            seam_mode: SeamMode::Stitch,
            stitch,
        }
    }

    /// Trace the stitched surface (the default) or the raw one with its seam cracks. The
    /// prism boxes bound both (the bake includes the stitch bands), so the BVH stays.
    pub fn with_seam_mode(mut self, mode: SeamMode) -> Self {
        self.seam_mode = mode;
        self.stitch = match mode {
            SeamMode::Stitch => StitchField::build(&self.table, &self.map),
            SeamMode::Open => StitchField::default(),
        };
        self
    }

    /// A new version of the height map over the same prisms (`render --watch`, after
    /// `bake::rebake_for_map` kept every box): the stitch bands' ranges are re-read.
    pub fn replace_map(&mut self, map: HeightMap) {
        self.map = map;
        if self.seam_mode == SeamMode::Stitch {
            self.stitch = StitchField::build(&self.table, &self.map);
        }
    }

    pub fn seam_mode(&self) -> SeamMode {
        self.seam_mode
    }

    pub fn stitch(&self) -> &StitchField {
        &self.stitch
    }

    /// The displaced surface this scene traces (table, map, seam treatment).
    pub fn surface(&self) -> Surface<'_> {
        Surface {
            table: &self.table,
            map: &self.map,
            mode: self.seam_mode,
            stitch: &self.stitch,
        }
    }

    /// How every method evaluates the height of prism `prism`.
    #[inline]
    pub fn prism_displacement(&self, prism: u32) -> PrismDisplacement<'_> {
        self.surface().prism_displacement(prism)
    }

    pub fn bvh_kind(&self) -> BvhKind {
        self.bvh.kind()
    }

    /// Bytes of the hierarchy: nodes plus the leaf-to-prism index list.
    pub fn bvh_bytes(&self) -> usize {
        self.bvh.bytes()
    }

    /// Panics (obvhs asserts) if the hierarchy is malformed or does not bound its prisms.
    pub fn validate(&self) {
        self.bvh.validate(&prism_aabbs(&self.table));
    }

    /// Closest hit over all prisms. `f(ray, prism)` intersects one prism with the ray clipped
    /// to the closest hit so far (`ray.t_max`) and returns the cheap record (t, prism,
    /// barycentrics; surface data may be filled later, once, for the winner).
    #[inline]
    pub fn closest_hit<F: FnMut(&Ray, u32) -> Option<Hit>>(&self, ray: &Ray, f: F) -> Option<Hit> {
        self.bvh.closest_hit(ray, f)
    }

    /// Whether any prism reports a hit (shadow rays); stops at the first.
    pub fn any_hit<F: FnMut(&Ray, u32) -> bool>(&self, ray: &Ray, f: F) -> bool {
        self.bvh.any_hit(ray, f)
    }
}

/// Entered items waiting to be finished (`BoxBvh::closest_hit_ordered`), nearest start first.
struct Waiting<S> {
    items: [(f32, u32, Option<S>); WAITING],
    len: usize,
}

/// Items that may wait at once; when the list is full the nearest is finished to make room.
const WAITING: usize = 8;

impl<S: Copy> Waiting<S> {
    fn new() -> Self {
        Waiting {
            items: [(0.0, 0, None); WAITING],
            len: 0,
        }
    }

    /// Add an item that starts at `t0`; if the list was full, the nearest item comes back to be
    /// finished now.
    #[inline]
    fn insert(&mut self, t0: f32, item: u32, state: S) -> Option<(u32, S)> {
        let out = if self.len == WAITING {
            self.pop_before(f32::INFINITY)
        } else {
            None
        };
        let mut i = self.len;
        while i > 0 && self.items[i - 1].0 > t0 {
            self.items[i] = self.items[i - 1];
            i -= 1;
        }
        self.items[i] = (t0, item, Some(state));
        self.len += 1;
        out
    }

    /// The nearest waiting item, if it starts at or before `t`.
    #[inline]
    fn pop_before(&mut self, t: f32) -> Option<(u32, S)> {
        if self.len == 0 || self.items[0].0 > t {
            return None;
        }
        let (_, item, state) = self.items[0];
        self.items.copy_within(1..self.len, 0);
        self.len -= 1;
        Some((item, state?))
    }
}

/// `-0.0` components become `+0.0`: obvhs takes the ray octant from `d < 0` but the inverse
/// from `signum(d)`, which disagree for `-0.0`; CWBVH then tests the wrong box planes and an
/// axis-aligned ray such as `-Vec3::Z` (= `(-0, -0, -1)`) misses everything.
#[inline]
fn to_obvhs(ray: &Ray) -> obvhs::ray::Ray {
    obvhs::ray::Ray::new(
        Vec3A::from(ray.origin),
        Vec3A::from(ray.dir + Vec3::ZERO),
        ray.t_min,
        ray.t_max,
    )
}

/// The padded box of every prism, in table order.
pub fn prism_aabbs(table: &PrismTable) -> Vec<Aabb> {
    table
        .prisms
        .iter()
        .map(|p| {
            let (lo, hi) = table.prism_aabb(p);
            padded_box(lo, hi)
        })
        .collect()
}

/// The box `[lo, hi]` padded by `AABB_PAD` of its diagonal (what every leaf box gets).
pub fn padded_box(lo: Vec3, hi: Vec3) -> Aabb {
    let pad = Vec3::splat((hi - lo).length() * AABB_PAD + f32::MIN_POSITIVE);
    Aabb::new(Vec3A::from(lo - pad), Vec3A::from(hi + pad))
}

/// Procedural test assets: a closed, seam-free displaced sphere.
#[cfg(test)]
pub(crate) mod fixtures {
    use crate::bake::{bake, BakeOptions, PrismTable};
    use crate::heightmap::{DisplaceParams, HeightMap, Wrap};
    use crate::mesh::BaseMesh;
    use crate::rng::{pcg_hash, to_unit_float};
    use glam::{Vec2, Vec3};

    /// Icosphere of radius 1 after `subdiv` 4-to-1 splits, every vertex moved tangentially by
    /// up to `jitter` (× edge length) so that no two faces are congruent (a regular mesh hides
    /// construction errors by symmetry). Smooth normals = unit position; UVs a linear
    /// projection of the position, so a continuous function without seams: with a repeat map
    /// the displaced surface is closed.
    pub fn sphere_mesh(subdiv: u32, jitter: f32) -> BaseMesh {
        let (mut pos, tris) = crate::test_util::icosphere(subdiv, 1.0);
        let edge = 1.1 / (1 << subdiv) as f32;
        let mut h = 0x1234_5678u32;
        let mut rnd = || {
            h = pcg_hash(h);
            to_unit_float(h) * 2.0 - 1.0
        };
        for p in pos.iter_mut() {
            let r = Vec3::new(rnd(), rnd(), rnd()) * jitter * edge;
            *p = (*p + r - *p * r.dot(*p)).normalize();
        }
        let uvs = pos
            .iter()
            .map(|p| {
                Vec2::new(
                    0.5 + 0.37 * (p.x + 0.4 * p.z),
                    0.5 + 0.37 * (p.y - 0.3 * p.z),
                )
            })
            .collect();
        BaseMesh {
            normals: pos.clone(),
            positions: pos,
            uvs,
            face_group: vec![0; tris.len()],
            face_flags: vec![0; tris.len()],
            triangles: tris,
            groups: vec!["sphere".into()],
            ..Default::default()
        }
    }

    /// A smooth periodic relief in [0, 1]: a few sinusoids, seamless under repeat wrap.
    pub fn relief_map(n: u32) -> HeightMap {
        let tau = std::f32::consts::TAU;
        let data = (0..n * n)
            .map(|i| {
                let (x, y) = ((i % n) as f32 + 0.5, (i / n) as f32 + 0.5);
                let (u, v) = (x / n as f32, y / n as f32);
                0.5 + 0.25 * (tau * 3.0 * u).sin() * (tau * 2.0 * v).cos()
                    + 0.2 * (tau * (5.0 * u + 4.0 * v)).sin()
            })
            .collect();
        HeightMap::new(n, n, data, Wrap::Repeat)
    }

    pub fn constant_map(value: f32) -> HeightMap {
        HeightMap::new(4, 4, vec![value; 16], Wrap::Repeat)
    }

    pub fn table(mesh: &BaseMesh, map: &HeightMap, scale: f32) -> PrismTable {
        let params = DisplaceParams {
            scale,
            midlevel: 0.5,
        };
        bake(mesh, map, &BakeOptions { params })
    }

    /// Tilt every vertex normal by up to `amount` (radians, roughly), deterministically. On a
    /// mesh inscribed in a sphere with radial normals `n_i·N_g` is the same at the three
    /// corners of a face, which makes the paper's prisms coincide with the shared-wall ones;
    /// tilted normals break that coincidence, as real assets do.
    pub fn tilt_normals(mut mesh: BaseMesh, amount: f32) -> BaseMesh {
        let mut h = 0x9e37_79b9u32;
        let mut rnd = || {
            h = pcg_hash(h);
            to_unit_float(h) * 2.0 - 1.0
        };
        for n in mesh.normals.iter_mut() {
            *n = (*n + Vec3::new(rnd(), rnd(), rnd()) * amount).normalize();
        }
        mesh
    }

    /// The closed displaced spheres that every method's leak test runs on, with the normal
    /// tilt of each: 320 faces with relief ±0.07 and radial normals (where the paper's prisms
    /// coincide with the shared-wall ones), the same with normals tilted by up to ~0.3 rad (where
    /// they do not, docs/watertightness.md), a coarse 80-face one with relief ±0.27 and tilted
    /// normals, and the coarse one with stronger tangential jitter and radial normals.
    pub fn leak_spheres() -> Vec<(f32, super::Scene)> {
        [
            (2, 0.15, 0.3, 0.0),
            (2, 0.15, 0.3, 0.3),
            (1, 0.6, 0.3, 0.3),
            (1, 0.6, 0.4, 0.0),
        ]
        .into_iter()
        .map(|(subdiv, scale, jitter, tilt)| {
            let mesh = tilt_normals(sphere_mesh(subdiv, jitter), tilt);
            let map = relief_map(64);
            (tilt, super::Scene::new(table(&mesh, &map, scale), map))
        })
        .collect()
    }

    /// The jittered icosphere at `size` with `map` displaced by `scale × size`.
    pub fn sphere_scene(subdiv: u32, map: HeightMap, scale: f32, size: f32) -> super::Scene {
        let mesh = scaled(sphere_mesh(subdiv, 0.25), size);
        let table = table(&mesh, &map, scale * size);
        super::Scene::new(table, map)
    }

    /// Scale every position of a mesh (normals and UVs unchanged).
    pub fn scaled(mut mesh: BaseMesh, s: f32) -> BaseMesh {
        for p in mesh.positions.iter_mut() {
            *p *= s;
        }
        mesh
    }
}

#[cfg(test)]
mod tests {
    use super::fixtures::*;
    use super::*;
    use crate::canonical::PrismGeom;

    fn scene(kind: BvhKind) -> Scene {
        let mesh = sphere_mesh(2, 0.2);
        let map = relief_map(64);
        let table = table(&mesh, &map, 0.1);
        Scene::with_bvh(table, map, kind)
    }

    /// `n` rays from a sphere of radius 3 aimed at random points within 0.9 of the centre.
    fn rays_through_sphere(n: usize, seed: u32) -> Vec<Ray> {
        let mut h = seed;
        let mut r = || {
            h = crate::rng::pcg_hash(h);
            crate::rng::to_unit_float(h) * 2.0 - 1.0
        };
        (0..n)
            .map(|_| {
                let o = Vec3::new(r(), r(), r()).normalize() * 3.0;
                let target = Vec3::new(r(), r(), r()) * 0.9;
                Ray::new(o, (target - o).normalize())
            })
            .collect()
    }

    /// A stand-in intersector: the prism's base triangle.
    fn base_triangle_hit(s: &Scene, ray: &Ray, prism: u32) -> Option<Hit> {
        let g = PrismGeom::new(&s.table, &s.table.prisms[prism as usize]);
        let (e1, e2) = (g.v[1] - g.v[0], g.v[2] - g.v[0]);
        let p = ray.dir.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            return None;
        }
        let tv = ray.origin - g.v[0];
        let b1 = tv.dot(p) / det;
        let q = tv.cross(e1);
        let b2 = ray.dir.dot(q) / det;
        let t = e2.dot(q) / det;
        (b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0 && t >= ray.t_min && t <= ray.t_max).then(|| {
            Hit {
                t,
                prism,
                bary: Vec3::new(1.0 - b1 - b2, b1, b2),
                uv: Default::default(),
                position: ray.at(t),
                geometric_normal: Vec3::Z,
                shading_normal: Vec3::Z,
                steps: 0,
            }
        })
    }

    #[test]
    fn both_hierarchies_validate() {
        // obvhs's own validation: every node bounds its children and prisms, every prism is
        // reachable exactly once. Breaks if the boxes or the build parameters are wrong.
        for kind in [BvhKind::Binary, BvhKind::Wide] {
            let s = scene(kind);
            s.validate();
            assert!(s.bvh_bytes() > 0);
        }
    }

    #[test]
    fn traversal_finds_the_closest_box_hit_like_brute_force() {
        // A stand-in intersector: the prism's base triangle. The traversal must agree with a
        // loop over all prisms, for both hierarchies.
        let tri_hit = base_triangle_hit;
        for kind in [BvhKind::Binary, BvhKind::Wide] {
            let s = scene(kind);
            for ray in rays_through_sphere(500, 7) {
                let got = s.closest_hit(&ray, |ray, p| tri_hit(&s, ray, p));
                let want = (0..s.table.prisms.len() as u32)
                    .filter_map(|p| tri_hit(&s, &ray, p))
                    .min_by(|a, b| a.t.total_cmp(&b.t));
                assert_eq!(got.map(|h| h.prism), want.map(|h| h.prism), "{kind:?}");
                assert_eq!(
                    s.any_hit(&ray, |ray, p| tri_hit(&s, ray, p).is_some()),
                    want.is_some()
                );
            }
        }
    }

    // Breaks if the ordered walk finished items in the order of their leaves (as obvhs's walk
    // does), finished one that starts beyond the best hit, or lost the closest hit.
    #[test]
    fn ordered_traversal_finishes_front_to_back_and_stops_at_the_hit() {
        for kind in [BvhKind::Binary, BvhKind::Wide] {
            let s = scene(kind);
            let (mut finished, mut hits, mut unordered) = (0, 0, 0);
            for ray in rays_through_sphere(500, 11) {
                let want = (0..s.table.prisms.len() as u32)
                    .filter_map(|p| base_triangle_hit(&s, &ray, p))
                    .min_by(|a, b| a.t.total_cmp(&b.t));
                // Each item starts exactly at its hit: the nearest is nearly always finished
                // first, and then no other (the closed sphere's far side starts beyond it).
                let mut n = 0;
                let got = s.bvh.closest_hit_ordered(
                    &ray,
                    |r, p, t_leaf| {
                        let hit = base_triangle_hit(&s, r, p)?;
                        assert!(hit.t >= t_leaf - 1e-4, "{} before its leaf {t_leaf}", hit.t);
                        Some((hit.t, hit))
                    },
                    |r, _, hit| {
                        assert!(hit.t < r.t_max, "finished beyond the best hit");
                        n += 1;
                        Some(hit)
                    },
                );
                assert_eq!(got.map(|h| h.prism), want.map(|h| h.prism), "{kind:?}");
                finished += n;
                hits += want.is_some() as usize;
                // The same items in the leaves' order (`closest_hit`): every item reached that
                // the (clipped) ray hits is a full test.
                s.closest_hit(&ray, |r, p| {
                    let hit = base_triangle_hit(&s, r, p);
                    unordered += hit.is_some() as usize;
                    hit
                });
            }
            assert!(hits > 100, "{hits}");
            eprintln!(
                "{kind:?}: {finished} items finished for {hits} hits ({unordered} unordered)"
            );
            if kind == BvhKind::Binary {
                assert!(
                    finished * 100 <= hits * 105,
                    "{finished} finished for {hits} hits"
                );
                assert!(finished < unordered, "{finished} vs {unordered}");
            }
        }
    }

    #[test]
    fn axis_aligned_rays_with_negative_zero_components_traverse() {
        // Regression: `-Vec3::Z` is (-0, -0, -1); CWBVH missed every box for it.
        for kind in [BvhKind::Binary, BvhKind::Wide] {
            let s = scene(kind);
            for d in [-Vec3::Z, -Vec3::X, -Vec3::Y, Vec3::Z, Vec3::X, Vec3::Y] {
                let ray = Ray::new(d * -3.0 + Vec3::splat(0.05), d);
                let mut visited = 0;
                s.closest_hit(&ray, |_, _| {
                    visited += 1;
                    None
                });
                assert!(visited > 0, "{kind:?} {d}");
            }
        }
    }

    #[test]
    fn empty_table_misses() {
        let s = Scene::new(PrismTable::default(), constant_map(0.5));
        s.validate();
        assert!(s
            .closest_hit(&Ray::new(Vec3::ZERO, Vec3::X), |_, _| unreachable!())
            .is_none());
    }
}
