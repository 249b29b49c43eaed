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
    var w: Walk;
    walk_begin(&w, ray, ctx, stop_at_first);
    loop {
        if (!walk_step(&w)) {
            break;
        }
    }
    return walk_result(w);
}

// A traversal in progress, so that a kernel can run it step by step (`walk_step`) and start
// another ray in the same loop when one ends (`beauty_trace`): an invocation whose ray ends
// early then takes its next ray instead of idling until the longest ray of its SIMD group ends.
struct Walk {
    ray: Ray,
    ctx: RayContext,
    inv_d: vec3f,
    t_best: f32,
    best: Hit,
    steps: u32,
    sp: u32,
    current: u32,
    // 1: `current` is a node to visit; 0: the ray is done.
    visit: u32,
    stop_at_first: u32,
    stack_node: array<u32, BVH_STACK>,
    stack_t: array<f32, BVH_STACK>,
}

// Start `ray` on the walk (the stack's contents are left as they are: `sp` is 0).
fn walk_begin(w: ptr<function, Walk>, ray: Ray, ctx: RayContext, stop_at_first: bool) {
    (*w).ray = ray;
    (*w).ctx = ctx;
    (*w).best = no_hit();
    (*w).steps = 0u;
    (*w).sp = 0u;
    (*w).current = 0u;
    (*w).stop_at_first = select(0u, 1u, stop_at_first);
    (*w).inv_d = safe_inverse(ray.dir);
    (*w).t_best = ray.t_max;
    var visit = false;
    if (scene.node_count != 0u) {
        visit = ray_box(ray.origin, (*w).inv_d, ray.t_min, ray.t_max, nodes[0]) < T_FAR;
    }
    (*w).visit = select(0u, 1u, visit);
}

// The walk's hit (no_hit if none), with the marching steps it took.
fn walk_result(w: Walk) -> Hit {
    var best = w.best;
    best.steps = w.steps;
    return best;
}

// One step of a walk: descend to the next leaf whose box the ray enters before the closest
// hit so far and test its prisms. False when the ray is done (no node left, or the first hit
// found with `stop_at_first`).
//
// "While-while" (Aila & Laine 2009): descend through inner nodes until this invocation holds
// a leaf, and only then test the leaf's prisms. The prism test is by far the larger body; an
// implementation that runs invocations in lock-step (lavapipe's SIMD lanes, GPU warps) then
// runs it with most lanes holding a leaf, instead of alternating box tests and prism tests
// lane by lane.
fn walk_step(w: ptr<function, Walk>) -> bool {
    if ((*w).visit == 0u) {
        return false;
    }
    let o = (*w).ray.origin;
    let inv_d = (*w).inv_d;
    let t_min = (*w).ray.t_min;
    var current = (*w).current;
    var visit = true;
    loop {
        let node = nodes[current];
        if (node.prim_count != 0u) {
            break;
        }
        let l = node.first_index;
        let tl = ray_box(o, inv_d, t_min, (*w).t_best, nodes[l]);
        let tr = ray_box(o, inv_d, t_min, (*w).t_best, nodes[l + 1u]);
        if (tl < T_FAR && tr < T_FAR) {
            // Near child next, far one on the stack (dropped if the stack is full).
            let near_is_left = tl <= tr;
            let sp = (*w).sp;
            if (sp < BVH_STACK) {
                (*w).stack_node[sp] = select(l, l + 1u, near_is_left);
                (*w).stack_t[sp] = select(tl, tr, near_is_left);
                (*w).sp = sp + 1u;
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
        visit = walk_pop(w, &current);
        if (!visit) {
            break;
        }
    }
    if (visit) {
        // `current` is a leaf.
        let leaf = nodes[current];
        let stop_at_first = (*w).stop_at_first != 0u;
        for (var i = 0u; i < leaf.prim_count; i++) {
            let prism = prim_indices[leaf.first_index + i];
            let clipped = Ray(o, (*w).ray.dir, t_min, (*w).t_best);
            var steps = (*w).steps;
            let h = intersect_prism_kept(clipped, (*w).ctx, prism, &steps);
            (*w).steps = steps;
            if (h.prism != NO_PRISM && (stop_at_first || h.t < (*w).t_best)) {
                (*w).best = h;
                (*w).t_best = h.t;
                if (stop_at_first) {
                    (*w).visit = 0u;
                    return false;
                }
            }
        }
        visit = walk_pop(w, &current);
    }
    (*w).current = current;
    (*w).visit = select(0u, 1u, visit);
    return visit;
}

// Pop the next node whose box entry is still before the closest hit into `current`; false
// when the stack has none left.
fn walk_pop(w: ptr<function, Walk>, current: ptr<function, u32>) -> bool {
    loop {
        let sp = (*w).sp;
        if (sp == 0u) {
            return false;
        }
        (*w).sp = sp - 1u;
        if ((*w).stack_t[sp - 1u] <= (*w).t_best) {
            *current = (*w).stack_node[sp - 1u];
            return true;
        }
    }
    return false;
}
