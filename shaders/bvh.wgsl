// bvh.wgsl — closest-hit traversal of the flattened obvhs BVH2 over the prism boxes (the GPU
// counterpart of prismbake::accel::Scene::closest_hit). The boxes are the CPU's padded prism
// boxes (`accel::prism_aabbs`); the CPU walks a CWBVH over the same boxes, so the set of prisms
// tested can differ in order but every prism that contains the closest hit is tested with the
// ray clipped to the closest hit so far, as on the CPU.

// Traversal stack depth; obvhs BVH2s over prism boxes are far shallower.
const BVH_STACK: u32 = 64u;

// Entry parameter of the ray into a node's box in [t_min, t_max], or T_FAR if it misses.
fn ray_box(o: vec3f, inv_d: vec3f, t_min: f32, t_max: f32, node: BvhNode) -> f32 {
    let t0 = (node.min - o) * inv_d;
    let t1 = (node.max - o) * inv_d;
    let tn = min(t0, t1);
    let tf = max(t0, t1);
    let near = max(max(tn.x, tn.y), max(tn.z, t_min));
    let far = min(min(tf.x, tf.y), min(tf.z, t_max));
    return select(T_FAR, near, near <= far);
}

// 1/d without infinities: a zero component becomes 1/1e-30 (the slab test then sees an
// axis-parallel ray as inside or outside its slab, as with ∞). -0.0 counts as +0.0 (the CPU's
// `to_obvhs` does the same).
fn safe_inverse(d: vec3f) -> vec3f {
    let tiny = vec3f(1e-30);
    let dd = select(d, select(tiny, -tiny, d < vec3f(0.0)), abs(d) < tiny);
    return 1.0 / dd;
}

// Pop the next node whose box entry is still before the closest hit into `current`; false
// when the stack has none left.
fn pop_next(
    stack_node: ptr<function, array<u32, BVH_STACK>>,
    stack_t: ptr<function, array<f32, BVH_STACK>>,
    sp: ptr<function, u32>,
    t_best: f32,
    current: ptr<function, u32>,
) -> bool {
    loop {
        if (*sp == 0u) {
            return false;
        }
        *sp -= 1u;
        if ((*stack_t)[*sp] <= t_best) {
            *current = (*stack_node)[*sp];
            return true;
        }
    }
    return false;
}

// Scene::closest_hit with PDM's intersect_prism as the per-prism test.
fn closest_hit(ray: Ray, ctx: RayContext) -> Hit {
    return traverse(ray, ctx, false);
}

// Scene::any_hit: does any prism report a hit in [t_min, t_max] (shadow rays)?
fn any_hit(ray: Ray, ctx: RayContext) -> bool {
    return traverse(ray, ctx, true).prism != NO_PRISM;
}

// The traversal behind both: the closest hit, or with `stop_at_first` the first hit found
// (the CPU's any_hit gives each prism the whole ray and stops at the first that reports a
// hit; before any hit the clipped ray here is the whole ray, so the answer is the same).
// A kernel that traces both kinds calls this once (Mesa inlines every call site).
fn traverse(ray: Ray, ctx: RayContext, stop_at_first: bool) -> Hit {
    var best = no_hit();
    var steps = 0u;
    if (scene.node_count == 0u) {
        return best;
    }
    let inv_d = safe_inverse(ray.dir);
    var t_best = ray.t_max;
    var stack_node: array<u32, BVH_STACK>;
    var stack_t: array<f32, BVH_STACK>;
    var sp = 0u;
    var current = 0u;
    var visit = ray_box(ray.origin, inv_d, ray.t_min, t_best, nodes[0]) < T_FAR;
    // "While-while" (Aila & Laine 2009): descend through inner nodes until this invocation
    // holds a leaf, and only then test the leaf's prisms. The prism test is by far the
    // larger body; an implementation that runs invocations in lock-step (lavapipe's SIMD
    // lanes, GPU warps) then runs it with most lanes holding a leaf, instead of alternating
    // box tests and prism tests lane by lane.
    loop {
        loop {
            if (!visit) {
                break;
            }
            let node = nodes[current];
            if (node.prim_count != 0u) {
                break;
            }
            let l = node.first_index;
            let tl = ray_box(ray.origin, inv_d, ray.t_min, t_best, nodes[l]);
            let tr = ray_box(ray.origin, inv_d, ray.t_min, t_best, nodes[l + 1u]);
            if (tl < T_FAR && tr < T_FAR) {
                // Near child next, far one on the stack (dropped if the stack is full).
                let near_is_left = tl <= tr;
                if (sp < BVH_STACK) {
                    stack_node[sp] = select(l, l + 1u, near_is_left);
                    stack_t[sp] = select(tl, tr, near_is_left);
                    sp += 1u;
                }
                current = select(l + 1u, l, near_is_left);
                continue;
            } else if (tl < T_FAR) {
                current = l;
                continue;
            } else if (tr < T_FAR) {
                current = l + 1u;
                continue;
            }
            // Neither child: the next node on the stack.
            visit = pop_next(&stack_node, &stack_t, &sp, t_best, &current);
        }
        if (!visit) {
            break;
        }
        // `current` is a leaf.
        let leaf = nodes[current];
        for (var i = 0u; i < leaf.prim_count; i++) {
            let prism = prim_indices[leaf.first_index + i];
            let clipped = Ray(ray.origin, ray.dir, ray.t_min, t_best);
            let h = intersect_prism(clipped, ctx, prism, &steps);
            if (h.prism != NO_PRISM && (stop_at_first || h.t < t_best)) {
                best = h;
                t_best = h.t;
                if (stop_at_first) {
                    best.steps = steps;
                    return best;
                }
            }
        }
        visit = pop_next(&stack_node, &stack_t, &sp, t_best, &current);
        if (!visit) {
            break;
        }
    }
    best.steps = steps;
    return best;
}
