//! obvhs's binary hierarchy (`Bvh2`) collapsed to four-wide nodes for the walk: every node
//! holds up to four children's boxes by axis (`lo` and `hi` rows, a lane per child), so one
//! 4-lane test finds where the ray enters all of them, and a ray visits about half the nodes.
//! A node takes its binary node's two children and opens the inner child of largest surface
//! until it has four (or only leaves). obvhs tests a binary node's two children one after
//! the other, each box through two 3-lane vectors and two horizontal reductions.
//!
//! Measured under the same walk (the same tree and hits), instructions in `Pdm::intersect` at
//! 128² (callgrind) and PDM's bytes per triangle (cells and their hierarchy):
//!
//! | layout | sphere | torus | rock | B/tri sphere / torus / rock |
//! |---|---|---|---|---|
//! | obvhs's nodes (48 bytes) | 73.06M | 32.17M | 45.35M | 11 467 / 11 691 / 3 046 |
//! | binary, both children's boxes in the parent (64 bytes per pair) | 69.28M | 30.29M | 44.28M | 10 352 / 10 522 / 2 799 |
//! | four-wide (144 bytes with a child count), inner children opened | 66.97M | 28.85M | 42.76M | 10 623 / 10 819 / 2 854 |
//! | the same, largest child opened first | 66.82M | 28.79M | 42.74M | 10 555 / 10 779 / 2 818 |
//! | the same, 128 bytes, unused slots marked (this) | 67.53M | 29.15M | 43.09M | 10 292 / 10 491 / 2 761 |
//!
//! The march steps per hit are the same to ±0.1 (the children's order differs). The torus at
//! 512², one thread pinned to one core, eight interleaved runs each: median 461 ns/ray for
//! the binary pair layout, 430 for the four-wide one; against obvhs's nodes, six runs, fastest
//! 364 → 324 ns/ray (the medians, 384 and 415, are within this machine's noise).

use glam::Vec4;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::fast_stack;
use obvhs::faststack::FastStack;

/// A child as its parent stores it: a leaf's items `items[index..index + count]`, or, with
/// `count == 0`, an inner node `quads[index]` (obvhs's leaves are never empty); `count ==
/// u32::MAX` marks a node's unused child slots (`Child::NONE`).
#[derive(Clone, Copy, Default, Debug, PartialEq, Eq)]
pub(super) struct Child {
    pub(super) index: u32,
    pub(super) count: u32,
}

impl Child {
    pub(super) const INNER0: Child = Child { index: 0, count: 0 };
    /// An unused child slot.
    const NONE: Child = Child {
        index: 0,
        count: u32::MAX,
    };

    pub(super) fn leaf(index: u32, count: u32) -> Self {
        Child { index, count }
    }

    pub(super) fn inner(index: u32) -> Self {
        Child { index, count: 0 }
    }

    #[inline(always)]
    pub(super) fn is_leaf(self) -> bool {
        self.count != 0
    }
}

/// What a walk does at the nodes and leaves it reaches (`QuadBvh::walk`).
pub(super) trait Visitor {
    /// The ray's current end: nodes it enters at or beyond are skipped.
    fn t_max(&self) -> f32;
    /// The walk has reached a node (taken it from the stack or descended to it) that the ray
    /// enters at `t`, before it is skipped or opened.
    #[inline(always)]
    fn reach(&mut self, _t: f32) {}
    /// The items of a leaf the ray enters at `t`; `false` ends the walk.
    fn leaf(&mut self, items: &[u32], t: f32) -> bool;
}

/// Up to four children: their boxes by axis and their references, the used ones first (128
/// bytes).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
struct Quad {
    lo: [Vec4; 3],
    hi: [Vec4; 3],
    child: [Child; 4],
}

impl Quad {
    const EMPTY: Quad = Quad {
        lo: [Vec4::ZERO; 3],
        hi: [Vec4::ZERO; 3],
        child: [Child::NONE; 4],
    };

    /// How many children the node has.
    fn count(&self) -> usize {
        self.child.iter().take_while(|c| **c != Child::NONE).count()
    }

    fn aabb(&self, k: usize) -> Aabb {
        let lane = |v: Vec4| v.to_array()[k];
        Aabb::new(
            glam::vec3a(lane(self.lo[0]), lane(self.lo[1]), lane(self.lo[2])),
            glam::vec3a(lane(self.hi[0]), lane(self.hi[1]), lane(self.hi[2])),
        )
    }

    /// Where the ray enters each child's box (`INFINITY` where it misses): obvhs's
    /// `Aabb::intersect_ray` per lane. Lanes of unused slots are meaningless; callers read
    /// only those of children.
    #[inline(always)]
    fn enter(&self, r: &QuadRay) -> [f32; 4] {
        let mut near = Vec4::NEG_INFINITY;
        let mut far = Vec4::INFINITY;
        for a in 0..3 {
            let t1 = (self.lo[a] - r.origin[a]) * r.inv[a];
            let t2 = (self.hi[a] - r.origin[a]) * r.inv[a];
            near = near.max(t1.min(t2));
            far = far.min(t1.max(t2));
        }
        let hit = far.cmpge(near) & far.cmpge(Vec4::ZERO);
        Vec4::select(hit, near, Vec4::INFINITY).to_array()
    }
}

/// A ray splatted for the 4-lane test (obvhs's `safe_inverse` direction: finite).
struct QuadRay {
    origin: [Vec4; 3],
    inv: [Vec4; 3],
}

impl QuadRay {
    #[inline(always)]
    fn new(r: &obvhs::ray::Ray) -> Self {
        QuadRay {
            origin: [r.origin.x, r.origin.y, r.origin.z].map(Vec4::splat),
            inv: [r.inv_direction.x, r.inv_direction.y, r.inv_direction.z].map(Vec4::splat),
        }
    }
}

/// The hierarchy: the root's box and reference, the four-wide nodes (the root's first), and
/// obvhs's leaf-to-item list.
pub(super) struct QuadBvh {
    quads: Vec<Quad>,
    root: Child,
    root_box: Aabb,
    pub(super) items: Vec<u32>,
    depth: usize,
}

impl QuadBvh {
    pub(super) fn new(b: Bvh2) -> Self {
        let nodes = &b.nodes;
        let root = &nodes[0];
        let mut out = QuadBvh {
            quads: Vec::with_capacity(nodes.len() / 3),
            root: Child::leaf(root.first_index, root.prim_count),
            root_box: *root.aabb(),
            items: Vec::new(),
            depth: 1,
        };
        if !root.is_leaf() {
            out.root = Child::inner(0);
            out.quads.push(Quad::EMPTY);
            // (obvhs index of an inner node, its quad's slot, depth)
            let mut todo = vec![(0usize, 0usize, 2usize)];
            while let Some((node, slot, depth)) = todo.pop() {
                out.depth = out.depth.max(depth * 3);
                let mut quad = Quad::EMPTY;
                let (mut lo, mut hi) = ([[0.0f32; 4]; 3], [[0.0f32; 4]; 3]);
                let first = nodes[node].first_index as usize;
                let mut kids = vec![first, first + 1];
                // Open the inner child of largest surface (the likeliest to be entered) until
                // there are four.
                while kids.len() < 4 {
                    let Some(i) = (0..kids.len())
                        .filter(|&i| !nodes[kids[i]].is_leaf())
                        .max_by(|&i, &j| {
                            let area = |k: usize| nodes[kids[k]].aabb().half_area();
                            area(i).total_cmp(&area(j))
                        })
                    else {
                        break;
                    };
                    let f = nodes[kids[i]].first_index as usize;
                    kids[i] = f;
                    kids.push(f + 1);
                }
                for (k, &c) in kids.iter().enumerate() {
                    let n = &nodes[c];
                    for a in 0..3 {
                        lo[a][k] = n.aabb().min[a];
                        hi[a][k] = n.aabb().max[a];
                    }
                    quad.child[k] = if n.is_leaf() {
                        Child::leaf(n.first_index, n.prim_count)
                    } else {
                        let s = out.quads.len();
                        out.quads.push(Quad::EMPTY);
                        todo.push((c, s, depth + 1));
                        Child::inner(s as u32)
                    };
                }
                quad.lo = lo.map(Vec4::from_array);
                quad.hi = hi.map(Vec4::from_array);
                out.quads[slot] = quad;
            }
        }
        out.items = b.primitive_indices;
        out
    }

    pub(super) fn bytes(&self) -> usize {
        std::mem::size_of_val(&self.quads[..])
            + std::mem::size_of::<(Child, Aabb)>()
            + self.items.len() * 4
    }

    pub(super) fn validate(&self, aabbs: &[Aabb]) {
        let mut seen = vec![0u32; aabbs.len()];
        let holds = |outer: &Aabb, inner: &Aabb| {
            outer.min.cmple(inner.min).all() && inner.max.cmple(outer.max).all()
        };
        let mut todo = vec![(self.root, self.root_box)];
        while let Some((c, b)) = todo.pop() {
            if c.is_leaf() {
                for &item in &self.items[c.index as usize..(c.index + c.count) as usize] {
                    let id = item as usize;
                    assert!(holds(&b, &aabbs[id]), "leaf box does not hold item {id}");
                    seen[id] += 1;
                }
            } else {
                let q = &self.quads[c.index as usize];
                for k in 0..q.count() {
                    let cb = q.aabb(k);
                    assert!(holds(&b, &cb), "node box does not hold its child");
                    todo.push((q.child[k], cb));
                }
            }
        }
        assert!(
            seen.iter().all(|&n| n == 1),
            "an item is in no leaf or in two"
        );
    }

    #[inline(always)]
    pub(super) fn walk<V: Visitor>(&self, ray: &obvhs::ray::Ray, v: &mut V) {
        let t_root = self.root_box.intersect_ray(ray);
        if t_root >= v.t_max() {
            return;
        }
        let r = QuadRay::new(ray);
        fast_stack!((Child, f32), (48, 96, 192), self.depth, stack, {
            let mut current = (self.root, t_root);
            loop {
                let (node, t) = current;
                v.reach(t);
                let mut next = None;
                if t < v.t_max() {
                    if node.is_leaf() {
                        let first = node.index as usize;
                        if !v.leaf(&self.items[first..first + node.count as usize], t) {
                            return;
                        }
                    } else {
                        let q = &self.quads[node.index as usize];
                        let ts = q.enter(&r);
                        let t_max = v.t_max();
                        // The children the ray enters before t_max, farthest first.
                        let mut hits = [(Child::INNER0, 0.0f32); 4];
                        let mut n = 0;
                        for (&c, tk) in q.child.iter().zip(ts) {
                            if c.count == Child::NONE.count {
                                break;
                            }
                            if tk < t_max {
                                let mut j = n;
                                while j > 0 && hits[j - 1].1 < tk {
                                    hits[j] = hits[j - 1];
                                    j -= 1;
                                }
                                hits[j] = (c, tk);
                                n += 1;
                            }
                        }
                        if n > 0 {
                            for h in &hits[..n - 1] {
                                stack.push(*h);
                            }
                            next = Some(hits[n - 1]);
                        }
                    }
                }
                current = match next {
                    Some(n) => n,
                    None => match stack.pop() {
                        Some(n) => n,
                        None => return,
                    },
                };
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Vec3, Vec3A};
    use obvhs::bvh2::builder::build_bvh2;
    use obvhs::BvhBuildParams;
    use std::time::Duration;

    fn randoms(seed: u32) -> impl FnMut() -> f32 {
        let mut h = seed;
        move || {
            h = crate::rng::pcg_hash(h);
            crate::rng::to_unit_float(h) * 2.0 - 1.0
        }
    }

    /// Random small boxes in the unit cube, some of them flat along an axis.
    fn boxes(n: usize, seed: u32) -> Vec<Aabb> {
        let mut r = randoms(seed);
        (0..n)
            .map(|i| {
                let c = Vec3A::new(r(), r(), r());
                let mut e = Vec3A::new(r().abs(), r().abs(), r().abs()) * 0.2;
                if i % 7 == 0 {
                    e[i % 3] = 0.0;
                }
                Aabb::new(c - e, c + e)
            })
            .collect()
    }

    /// The 4-lane test gives obvhs's verdict and entry for every child, bit for bit, on random
    /// rays and on axis-aligned ones (a zero direction component: obvhs's `safe_inverse`),
    /// origins inside boxes included.
    #[test]
    fn four_lane_test_equals_obvhs_box_test() {
        let aabbs = boxes(64, 7);
        let mut r = randoms(11);
        let mut rays = Vec::new();
        for k in 0..4000 {
            let aim = aabbs[k % aabbs.len()].center();
            // Some origins inside a box.
            let o = if k % 11 == 0 {
                aim
            } else {
                Vec3A::new(r(), r(), r()) * 1.5
            };
            let mut d = aim + Vec3A::new(r(), r(), r()) * 0.1 - o;
            if k % 3 == 0 {
                d[k % 3] = 0.0;
            }
            if k % 5 == 0 {
                d = [Vec3A::X, Vec3A::NEG_Y, Vec3A::Z][k % 3];
            }
            rays.push(obvhs::ray::Ray::new_inf(o, d.normalize()));
        }
        let (mut compared, mut hits) = (0, 0);
        // Full nodes, and nodes of two and three children (their unused lanes ignored).
        for (k, four) in aabbs.chunks_exact(4).enumerate() {
            let count = [4, 3, 2][k % 3];
            let row = |f: fn(&Aabb) -> Vec3A, a: usize| {
                Vec4::from_array(std::array::from_fn(|i| f(&four[i.min(count - 1)])[a]))
            };
            let q = Quad {
                lo: [0, 1, 2].map(|a| row(|b| b.min, a)),
                hi: [0, 1, 2].map(|a| row(|b| b.max, a)),
                child: std::array::from_fn(|i| {
                    if i < count {
                        Child::leaf(i as u32, 1)
                    } else {
                        Child::NONE
                    }
                }),
            };
            for ray in &rays {
                let ts = q.enter(&QuadRay::new(ray));
                for (t, b) in ts.into_iter().zip(&four[..count]) {
                    let want = b.intersect_ray(ray);
                    assert_eq!(
                        t.to_bits(),
                        want.to_bits(),
                        "{t} vs {want} for {b:?}, {ray:?}"
                    );
                    compared += 1;
                    hits += want.is_finite() as usize;
                }
            }
        }
        // Each ray is aimed at one of the 64 boxes.
        assert!(
            hits > compared / 100 && hits < compared,
            "{hits} of {compared}"
        );
    }

    /// The layout holds obvhs's tree: every box and item under its node (`validate`), and a
    /// walk reaches exactly the leaves whose boxes the ray enters, nearer child first.
    #[test]
    fn four_wide_layout_walks_the_leaves_the_ray_enters() {
        let aabbs = boxes(500, 3);
        let mut t = Duration::default();
        let params = BvhBuildParams {
            max_prims_per_leaf: 2,
            ..BvhBuildParams::medium_build()
        };
        let b = build_bvh2(&aabbs, params, &mut t);
        let pb = QuadBvh::new(b.clone());
        pb.validate(&aabbs);
        // A node's children are obvhs's leaves and the inner nodes that head nodes of their
        // own (every node but the root), the opened ones gone.
        let children: usize = pb.quads.iter().map(|q| q.count()).sum();
        let (mut leaves, mut todo) = (0, vec![0usize]);
        while let Some(i) = todo.pop() {
            let n = &b.nodes[i];
            if n.is_leaf() {
                leaves += 1;
            } else {
                todo.extend([n.first_index as usize, n.first_index as usize + 1]);
            }
        }
        assert_eq!(children, pb.quads.len() - 1 + leaves);
        assert!(pb.quads.len() * 3 < leaves * 2, "few nodes opened");
        assert_eq!(pb.bytes(), pb.quads.len() * 128 + 48 + aabbs.len() * 4);
        struct Leaves(Vec<u32>);
        impl Visitor for Leaves {
            fn t_max(&self) -> f32 {
                f32::INFINITY
            }
            fn leaf(&mut self, items: &[u32], _t: f32) -> bool {
                self.0.extend_from_slice(items);
                true
            }
        }
        let mut r = randoms(5);
        for _ in 0..300 {
            let o = Vec3::new(r(), r(), r()).normalize() * 2.0;
            let d = (Vec3::new(r(), r(), r()) * 0.8 - o).normalize();
            let ray = obvhs::ray::Ray::new_inf(o.into(), d.into());
            let mut v = Leaves(Vec::new());
            pb.walk(&ray, &mut v);
            // Every item the ray's line enters is reached (a leaf's other items come along).
            for (i, a) in aabbs.iter().enumerate() {
                if a.intersect_ray(&ray).is_finite() {
                    assert!(v.0.contains(&(i as u32)), "item {i} not reached");
                }
            }
            let mut sorted = v.0.clone();
            sorted.sort();
            sorted.dedup();
            assert_eq!(sorted.len(), v.0.len(), "an item reached twice");
        }
    }
}
