// packet.wgsl — the AOV kernel walked by subgroup packets (`AovWalk::Packet`): the invocations
// of a subgroup walk the BVH2 together, one node at a time, and test each leaf's prism
// together, each with its own ray and its own closest hit. Built only where the adapter has
// subgroup operations (wgpu::Features::SUBGROUP); the default on software adapters, whose
// SIMD lanes are a subgroup (docs/gpu.md, "Packets on lavapipe").
//
// Why: lavapipe runs a subgroup's invocations as the lanes of one SIMD register, in lock-step.
// In the per-ray walk (bvh.wgsl) each lane descends to a leaf of its own, so a group's prism
// tests are up to eight different prisms, each lane's node and prism loaded on its own; here a
// node is visited once per subgroup, and the lanes that enter a leaf march the same prism side
// by side. Primary rays through neighbouring pixels share most of their nodes, so the packet
// visits few nodes beyond each ray's own.

// Scene::closest_hit for the subgroup's rays: every invocation of the subgroup calls this
// (`live` false where it has no ray) and gets the closest hit of its own ray, the hit
// `closest_hit` gives it. A node is visited when some live ray enters its box before that
// ray's closest hit so far; a leaf's prism is tested by the rays that do.
fn closest_hit_packet(ray: Ray, ctx: RayContext, live: bool) -> Hit {
    var best = no_hit();
    var t_best = ray.t_max;
    var steps = 0u;
    let o = ray.origin;
    let inv_d = safe_inverse(ray.dir);
    let t_min = ray.t_min;
    // The subgroup's stack: the same nodes in every invocation, pushed and popped in uniform
    // control flow.
    var stack: array<u32, BVH_STACK>;
    var sp = 0u;
    var current = 0u;
    var go = false;
    if (scene.node_count != 0u) {
        go = subgroupAny(live && ray_box(o, inv_d, t_min, t_best, nodes[0]) < T_FAR);
    }
    while (go) {
        let node = nodes[current];
        if (node.prim_count != 0u) {
            let enters = live && ray_box(o, inv_d, t_min, t_best, node) < T_FAR;
            if (subgroupAny(enters)) {
                for (var i = 0u; i < node.prim_count; i++) {
                    let prism = prim_indices[node.first_index + i];
                    if (enters) {
                        let clipped = Ray(o, ray.dir, t_min, t_best);
                        let h = intersect_prism_kept(clipped, ctx, prism, &steps);
                        if (h.prism != NO_PRISM && h.t < t_best) {
                            best = h;
                            t_best = h.t;
                        }
                    }
                }
            }
        } else {
            let l = node.first_index;
            let tl = ray_box(o, inv_d, t_min, t_best, nodes[l]);
            let tr = ray_box(o, inv_d, t_min, t_best, nodes[l + 1u]);
            let in_l = live && tl < T_FAR;
            let in_r = live && tr < T_FAR;
            let any_l = subgroupAny(in_l);
            let any_r = subgroupAny(in_r);
            if (any_l && any_r) {
                // The nearer child first, as most of the rays that enter both see it (ties:
                // left); the other on the stack (dropped if the stack is full, as in `walk_step`).
                let vote = subgroupAdd(select(0i, select(-1i, 1i, tl <= tr), in_l && in_r));
                let left_first = vote >= 0i;
                if (sp < BVH_STACK) {
                    stack[sp] = select(l, l + 1u, left_first);
                    sp += 1u;
                }
                current = select(l + 1u, l, left_first);
                continue;
            } else if (any_l) {
                current = l;
                continue;
            } else if (any_r) {
                current = l + 1u;
                continue;
            }
        }
        if (sp == 0u) {
            break;
        }
        sp -= 1u;
        // Every invocation holds the same entry; taking the first one's tells the compiler so.
        current = subgroupBroadcastFirst(stack[sp]);
    }
    best.steps = steps;
    return best;
}

// render_aovs with the packet walk. The workgroup's 8 × 8 pixels are laid out so that each run
// of 8 invocations (a lavapipe subgroup) covers a 4 × 2 block and each run of 32 an 8 × 4 one;
// pixels outside the tile walk along without a ray, so that the whole subgroup takes part.
@compute @workgroup_size(8, 8, 1)
fn render_aovs_packet(
    @builtin(workgroup_id) group: vec3<u32>,
    @builtin(local_invocation_index) index: u32,
) {
    let block = index / 8u;
    let lane = index % 8u;
    let gid = vec2<u32>(
        group.x * 8u + (block % 2u) * 4u + lane % 4u,
        group.y * 8u + (block / 2u) * 2u + lane / 4u,
    );
    let live = gid.x < frame.tile_size.x && gid.y < frame.tile_size.y;
    let job = aov_ray(gid);
    var hit = closest_hit_packet(job.ray, job.ctx, live);
    if (live && hit.prism != NO_PRISM) {
        fill_surface(&hit);
        aov_add(gid.y * frame.tile_size.x + gid.x, hit);
    }
}
