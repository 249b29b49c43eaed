// beauty.wgsl — the beauty kernel, the mirror of core/src/render/beauty.rs: one invocation per
// pixel of a tile renders ONE sample (`frame.sample_index`) of the path tracer and adds it to
// the pixel's running sums (`PixelSums` on the CPU), so samples accumulate across dispatches
// in the CPU's order (sample 0 of every pixel, then sample 1, ...) and an invocation's loop
// iterations stay far below lavapipe's cap of 65535 (docs/gpu.md). The host resolves the sums
// with the CPU's own `PixelSums::resolve` and writes them with `render::output::write_beauty`.
//
// Lighting: the environment (env.wgsl, next-event estimation combined with BSDF sampling by
// the power heuristic) and an optional directional key light (shadow rays only); material:
// shading.wgsl; an optional shadow-catcher ground seen by camera rays only. Random numbers are
// `random(pixel, sample, bounce * DIMS + k, purpose, seed)`, as on the CPU.
//
// Departure from a literal transcription, and why: the CPU's `trace_sample`,
// `surface_radiance` and `ground_light` trace rays at seven call sites. Mesa (lavapipe)
// inlines every function call, so each site would be a full copy of the BVH walk and the PDM
// march. Here the same functions are steps of one loop: each step states the rays it needs
// (`Query`: at most two shadow rays and one continuation ray, in the CPU's order), one call
// site traces them (`trace`), and the step then uses the answers exactly as the CPU does,
// adding the same terms in the same order.

@group(1) @binding(1) var<storage, read_write> beauty_sums: array<BeautySums>;
@group(2) @binding(0) var<uniform> lighting: Lighting;

// beauty::DIMS: random dimensions per bounce.
const DIMS: u32 = 8u;

// The path's next step.
const STEP_CAMERA: u32 = 0u;
const STEP_GROUND: u32 = 1u;
const STEP_SURFACE: u32 = 2u;
const STEP_DONE: u32 = 3u;

// beauty::BeautyCounters of one sample.
struct Counters {
    rays: u32,
    key_shadow_rays: u32,
    env_shadow_rays: u32,
}

// beauty::SampleResult (`ground`: the CPU's Some((lit, all))).
struct SampleResult {
    radiance: vec3f,
    surface: bool,
    background: vec3f,
    ground: bool,
    ground_lit: f32,
    ground_all: f32,
}

// One ray a step needs: closest hit (with surface data) or `any` (occlusion only).
struct Query {
    live: bool,
    any: bool,
    ray: Ray,
    ctx: RayContext,
}

fn no_query() -> Query {
    return Query(false, false, Ray(vec3f(0.0), vec3f(0.0, 0.0, 1.0), 0.0, 0.0), RayContext(0u, 0u, 0u, 0u));
}

fn material() -> Material {
    return Material(lighting.base_color, lighting.roughness, lighting.metallic, lighting.specular);
}

// beauty::rand2.
fn rand2(ctx: RayContext, bounce: u32, k: u32, purpose: u32) -> vec2f {
    let d = bounce * DIMS + k;
    return vec2f(
        random(ctx.pixel, ctx.sample, d, purpose, ctx.seed),
        random(ctx.pixel, ctx.sample, d + 1u, purpose, ctx.seed),
    );
}

// beauty::shadow_ray (t_max = +∞).
fn shadow_ray(origin: vec3f, dir: vec3f) -> Ray {
    return Ray(origin, dir, 0.0, T_FAR);
}

// beauty::ground_hit: distance to the catcher plane, if in front and the ray goes down.
struct GroundHit {
    ok: bool,
    t: f32,
}

fn ground_hit(ray: Ray) -> GroundHit {
    let up = lighting.ground_up;
    let denom = dot(ray.dir, up);
    if (denom >= 0.0) {
        return GroundHit(false, 0.0);
    }
    let t = (lighting.ground_height - dot(ray.origin, up)) / denom;
    return GroundHit(t > ray.t_min && t < ray.t_max, t);
}

// The kernel's only traversal: Pdm::intersect (closest hit + surface data) or Pdm::occluded.
fn trace(q: Query) -> Hit {
    var hit = traverse(q.ray, q.ctx, q.any);
    if (!q.any && hit.prism != NO_PRISM) {
        fill_surface(&hit);
    }
    return hit;
}

// beauty::trace_sample with ground_light and surface_radiance as its steps.
fn trace_sample(camera: Ray, ctx: RayContext, n: ptr<function, Counters>) -> SampleResult {
    var res = SampleResult(vec3f(0.0), false, vec3f(0.0), false, 0.0, 0.0);
    let m = material();
    let eps = lighting.eps;
    let env_lights = lighting.env_lights != 0u;
    var step = STEP_CAMERA;
    // surface_radiance's state.
    var hit = no_hit();
    var dir = camera.dir;
    var throughput = vec3f(1.0);
    var bounce = 0u;
    // ground_light's point.
    var ground_p = vec3f(0.0);
    loop {
        if (step == STEP_DONE) {
            break;
        }
        // 1. The step's rays: q0 key light, q1 environment, q2 continuation.
        var q0 = no_query();
        var q1 = no_query();
        var q2 = no_query();
        // What each shadow ray adds if unoccluded, and the continuation's context.
        var key_term = vec3f(0.0);
        var env_term = vec3f(0.0);
        var key_e = 0.0;
        var env_e = 0.0;
        var bs = BsdfSample(false, vec3f(0.0), vec3f(0.0), 0.0, false);
        var wi = vec3f(0.0);
        var last = false;
        if (step == STEP_CAMERA) {
            (*n).rays += 1u;
            q2 = Query(true, false, camera, ctx);
        } else if (step == STEP_GROUND) {
            // beauty::ground_light (the camera sample's context: bounce 0).
            let up = lighting.ground_up;
            let origin = ground_p + up * eps;
            if (lighting.has_key != 0u) {
                let cos_k = dot(lighting.key_dir, up);
                if (cos_k > 0.0) {
                    key_e = lighting.key_irradiance * cos_k;
                    res.ground_all += key_e;
                    (*n).key_shadow_rays += 1u;
                    q0 = Query(true, true, shadow_ray(origin, lighting.key_dir), ctx);
                }
            }
            if (env_lights) {
                let es = env_sample(rand2(ctx, 0u, 0u, PURPOSE_LIGHT));
                let cos_e = dot(es.dir, up);
                if (cos_e > 0.0 && es.pdf > 0.0) {
                    env_e = luminance(env_radiance(es.dir)) * cos_e / es.pdf;
                    res.ground_all += env_e;
                    (*n).env_shadow_rays += 1u;
                    q1 = Query(true, true, shadow_ray(origin, es.dir), ctx);
                }
            }
        } else {
            // beauty::surface_radiance, event `bounce`.
            let wo = -dir;
            var ng = hit.geometric_normal;
            var ns = hit.shading_normal;
            if (dot(wo, ng) < 0.0) {
                ng = -ng;
                ns = -ns;
            }
            if (dot(wo, ns) <= 0.0) {
                ns = ng;
            }
            let basis = onb(ns);
            let wo_l = to_local(wo, basis.t, basis.b, ns);
            let p = hit.position;
            let bctx = RayContext(ctx.pixel, ctx.sample, bounce + 1u, ctx.seed);
            if (lighting.has_key != 0u) {
                let kd = lighting.key_dir;
                let wi_l = to_local(kd, basis.t, basis.b, ns);
                var f = vec3f(0.0);
                if (dot(kd, ng) > 0.0) {
                    f = bsdf_eval(m, wo_l, wi_l);
                }
                if (max_element(f) > 0.0) {
                    (*n).key_shadow_rays += 1u;
                    q0 = Query(true, true, shadow_ray(offset_origin(p, ng, kd, eps), kd), bctx);
                    key_term = throughput * f * lighting.key_irradiance;
                }
            }
            if (env_lights) {
                let es = env_sample(rand2(ctx, bounce, 0u, PURPOSE_LIGHT));
                if (es.pdf > 0.0 && dot(es.dir, ng) > 0.0) {
                    let wi_l = to_local(es.dir, basis.t, basis.b, ns);
                    let f = bsdf_eval(m, wo_l, wi_l);
                    if (max_element(f) > 0.0) {
                        (*n).env_shadow_rays += 1u;
                        q1 = Query(true, true, shadow_ray(offset_origin(p, ng, es.dir, eps), es.dir), bctx);
                        let w = power_heuristic(es.pdf, bsdf_pdf(m, wo_l, wi_l));
                        env_term = throughput * f * env_radiance(es.dir) * (w / es.pdf);
                    }
                }
            }
            let u_lobe = random(ctx.pixel, ctx.sample, bounce * DIMS + 2u, PURPOSE_BSDF, ctx.seed);
            bs = bsdf_sample(m, wo_l, u_lobe, rand2(ctx, bounce, 3u, PURPOSE_BSDF));
            if (bs.ok) {
                wi = from_local(bs.wi, basis.t, basis.b, ns);
                if (dot(wi, ng) <= 0.0) {
                    bs.ok = false;
                }
            }
            if (bs.ok) {
                last = bounce + 1u == lighting.bounces;
                let ray = shadow_ray(offset_origin(p, ng, wi, eps), wi);
                if (last) {
                    // Last event: only whether the ray escapes matters.
                    if (env_lights) {
                        (*n).env_shadow_rays += 1u;
                        q2 = Query(true, true, ray, bctx);
                    }
                } else {
                    (*n).rays += 1u;
                    q2 = Query(true, false, ray, bctx);
                }
            }
        }

        // 2. Trace them, in the CPU's order, through one call site; only the live ones: the
        // loop runs as long as some lane has a live query left, so a lock-step implementation
        // (lavapipe) does not trace a masked ray for every query slot a step leaves empty
        // (no key light: the first slot is never live).
        var answers = array<Hit, 3>(no_hit(), no_hit(), no_hit());
        var live = array<u32, 3>(0u, 0u, 0u);
        var live_n = 0u;
        if (q0.live) {
            live[live_n] = 0u;
            live_n += 1u;
        }
        if (q1.live) {
            live[live_n] = 1u;
            live_n += 1u;
        }
        if (q2.live) {
            live[live_n] = 2u;
            live_n += 1u;
        }
        for (var j = 0u; j < 3u; j++) {
            if (j >= live_n) {
                break;
            }
            let k = live[j];
            var q = q2;
            if (k == 0u) {
                q = q0;
            } else if (k == 1u) {
                q = q1;
            }
            answers[k] = trace(q);
        }
        let seen0 = answers[0].prism != NO_PRISM;
        let seen1 = answers[1].prism != NO_PRISM;
        let next = answers[2];

        // 3. Use the answers as the CPU does.
        if (step == STEP_CAMERA) {
            var gt = GroundHit(false, 0.0);
            if (lighting.has_ground != 0u) {
                gt = ground_hit(camera);
            }
            if (next.prism != NO_PRISM && (!gt.ok || next.t <= gt.t)) {
                res.surface = true;
                hit = next;
                step = STEP_SURFACE;
            } else if (gt.ok) {
                res.background = env_radiance_smooth(camera.dir);
                res.ground = true;
                ground_p = ray_at(camera, gt.t);
                step = STEP_GROUND;
            } else {
                res.background = env_radiance_smooth(camera.dir);
                step = STEP_DONE;
            }
        } else if (step == STEP_GROUND) {
            if (q0.live && !seen0) {
                res.ground_lit += key_e;
            }
            if (q1.live && !seen1) {
                res.ground_lit += env_e;
            }
            step = STEP_DONE;
        } else {
            if (q0.live && !seen0) {
                res.radiance += key_term;
            }
            if (q1.live && !seen1) {
                res.radiance += env_term;
            }
            step = STEP_DONE;
            if (bs.ok) {
                throughput *= bs.weight;
                var env_weight = 1.0;
                if (!bs.delta && env_lights) {
                    env_weight = power_heuristic(bs.pdf, env_pdf(wi));
                }
                if (last) {
                    if (q2.live && next.prism == NO_PRISM) {
                        res.radiance += throughput * env_radiance(wi) * env_weight;
                    }
                } else if (next.prism != NO_PRISM) {
                    hit = next;
                    dir = wi;
                    bounce += 1u;
                    step = STEP_SURFACE;
                } else if (env_lights) {
                    res.radiance += throughput * env_radiance(wi) * env_weight;
                }
            }
        }
    }
    return res;
}

// Workgroup edge = gpu::layout::WORKGROUP (the host dispatches div_ceil(tile, 8) groups).
@compute @workgroup_size(8, 8, 1)
fn render_beauty(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= frame.tile_size.x || gid.y >= frame.tile_size.y) {
        return;
    }
    let x = frame.tile_origin.x + gid.x;
    let y = frame.tile_origin.y + gid.y;
    let pixel = y * frame.width + x;
    let sample = frame.sample_index;
    let jitter = pixel_jitter(pixel, sample);
    let ray = camera_ray(vec2f(f32(x), f32(y)) + jitter);
    let ctx = RayContext(pixel, sample, 0u, frame.seed);
    var n = Counters(0u, 0u, 0u);
    let r = trace_sample(ray, ctx, &n);
    let i = gid.y * frame.tile_size.x + gid.x;
    var acc = beauty_sums[i];
    acc.radiance += r.radiance;
    acc.surface += select(0.0, 1.0, r.surface);
    if (r.ground) {
        acc.ground_samples += 1.0;
        acc.ground_lit += r.ground_lit;
        acc.ground_unshadowed += r.ground_all;
        acc.ground_background += r.background;
    } else {
        acc.background += r.background;
    }
    acc.rays += n.rays;
    acc.key_shadow_rays += n.key_shadow_rays;
    acc.env_shadow_rays += n.env_shadow_rays;
    beauty_sums[i] = acc;
}
