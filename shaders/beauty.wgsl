// beauty.wgsl — the beauty kernels, the mirror of core/src/render/beauty.rs. One submission
// renders one sample of every pixel of a tile (`frame.sample_index`) and adds it to the
// pixel's running sums (`PixelSums` on the CPU), so samples accumulate in the CPU's order
// (sample 0 of every pixel, then sample 1, ...) and an invocation's loop iterations stay far
// below lavapipe's cap of 65535 (docs/gpu.md).
//
// The CPU's `trace_sample` is split into steps: `ask` states the rays a step needs (`Queries`:
// at most two shadow rays and one continuation ray, in the CPU's order), `trace_query` traces
// one, `use_answers` uses the answers exactly as the CPU does and picks the next step. Two
// schedules run them (gpu::BeautySchedule):
//
//   fused      render_beauty: one invocation per pixel, the steps in a loop (software
//              adapters: lavapipe runs it 1.25× faster than the wavefront)
//   wavefront  beauty_start, then (beauty_trace, beauty_shade) × (bounces + 1) dispatches
//              over one path record per pixel (`paths`, group 3; hardware adapters: on an
//              NVIDIA H200 19–27% less time per sample than the fused kernel)
//
// Lighting: the environment (env.wgsl, next-event estimation combined with BSDF sampling by
// the power heuristic) and up to sixteen lights, one sampled an event (lights::LightSet; discs,
// spheres and area lights also met by BSDF samples, by MIS); material: shading.wgsl, its base
// colour times the base-colour texture at the hit (texture.wgsl); an optional shadow-catcher
// ground seen by camera rays only. Random numbers are
// `random(pixel, sample, bounce * DIMS + k, purpose, seed)`, as on the CPU.
//
// Departure from a literal transcription, and why: the CPU's `trace_sample`,
// `surface_radiance` and `ground_light` trace rays at seven call sites. Mesa (lavapipe)
// inlines every function call, so each site would be a full copy of the BVH walk and the PDM
// march: both schedules trace through one call site. The fused kernel keeps the whole
// shading state live across the traversal: on an NVIDIA H200 its camera rays alone took
// 2.3× the AOV kernel's time for the same rays; the wavefront's `beauty_trace` holds one ray.

@group(1) @binding(1) var<storage, read_write> beauty_sums: array<BeautySums>;
@group(2) @binding(0) var<uniform> lighting: Lighting;
@group(3) @binding(0) var<storage, read_write> paths: array<PathRecord>;

// beauty::DIMS: random dimensions per bounce.
const DIMS: u32 = 8u;
// beauty::KEY_DIM: the key light's direction's dimension (purpose Light).
const KEY_DIM: u32 = 2u;

// The path's next step.
const STEP_CAMERA: u32 = 0u;
const STEP_GROUND: u32 = 1u;
const STEP_SURFACE: u32 = 2u;
const STEP_DONE: u32 = 3u;

// PathState.flags.
const PATH_SURFACE: u32 = 1u;   // SampleResult::surface
const PATH_GROUND: u32 = 2u;    // SampleResult::ground is Some
const PATH_BSDF_OK: u32 = 4u;   // this step's BSDF sample is usable
const PATH_BSDF_DELTA: u32 = 8u;
const PATH_LAST: u32 = 16u;     // this step is the path's last surface event
const PATH_MEETS_LIGHT: u32 = 32u;  // this step's BSDF sample meets a sphere or area light

// Ray slots of a step: key-light shadow, environment shadow, continuation.
const SLOT_KEY: u32 = 0u;
const SLOT_ENV: u32 = 1u;
const SLOT_NEXT: u32 = 2u;

// One ray a step asks for (`live` 0: none), as `beauty_trace` reads it; its context is
// (pixel, frame.sample_index, bounce, frame.seed).
struct QueryRec {
    origin: vec3f,
    t_min: f32,
    dir: vec3f,
    t_max: f32,
    bounce: u32,
    any: u32,      // 1: occlusion only (Pdm::occluded), 0: closest hit with surface data
    live: u32,
    _pad: u32,
}

// The continuation slot's answer: what the next step reads of the hit.
struct Answer {
    position: vec3f,
    t: f32,
    geometric_normal: vec3f,
    prism: u32,    // NO_PRISM: missed
    shading_normal: vec3f,
    _pad: u32,
    uv: vec2f,     // the hit's texture coordinates (BeautyScene::material_at)
    // The normal the clearcoat lies on (BeautyScene::clearcoat_normal).
    coat_normal: vec3f,
    // The shading normal before the normal map bent it (the diffuse is shadowed about it).
    unbent_normal: vec3f,
}

// A path between dispatches: beauty::trace_sample's locals, the SampleResult so far, the
// sample's counters, and the terms the step's shadow rays add if unoccluded.
struct PathState {
    throughput: vec3f,
    step: u32,
    dir: vec3f,
    bounce: u32,
    // The camera ray's origin until the camera step's event, then where it met the ground.
    ground_p: vec3f,
    flags: u32,
    radiance: vec3f,
    ground_lit: f32,
    background: vec3f,
    ground_all: f32,
    key_term: vec3f,
    key_e: f32,
    env_term: vec3f,
    env_e: f32,
    bs_weight: vec3f,
    bs_pdf: f32,
    wi: vec3f,
    rays: u32,
    key_shadow_rays: u32,
    env_shadow_rays: u32,
    // The camera hit's shading normal (beauty::facing_normals), zero without one.
    normal: vec3f,
    // The camera hit's reflectance (shading::guide_albedo), zero without one.
    albedo: vec3f,
    // The surface event's geometric normal (facing its rays), for the lights' chances there
    // (lights::LightSet::at, at the continuation's origin).
    event_n: vec3f,
}

// One pixel's path record in the wavefront schedule (gpu::layout::PATH_RECORD_BYTES).
// `occluded_key`/`occluded_env`: the shadow slots' answers (1: occluded), apart so that their
// invocations write words of their own.
struct PathRecord {
    state: PathState,
    queries: Queries,
    next: Answer,
    occluded_key: u32,
    occluded_env: u32,
}

// beauty::rand2.
fn rand2(ctx: RayContext, bounce: u32, k: u32, purpose: u32) -> vec2f {
    let d = bounce * DIMS + k;
    return vec2f(
        random(ctx.pixel, ctx.sample, d, purpose, ctx.seed),
        random(ctx.pixel, ctx.sample, d + 1u, purpose, ctx.seed),
    );
}

// KeyLight::sample_dir: a directional light's direction for random numbers `u`, uniform over
// its disc's cone (the direction itself for a point-like light).
fn disc_sample_dir(d: vec3f, cos_r: f32, u: vec2f) -> vec3f {
    if (cos_r >= 1.0) {
        return d;
    }
    let c = 1.0 - u.x * (1.0 - cos_r);
    let s = sqrt(max(1.0 - c * c, 0.0));
    let phi = 2.0 * PI * u.y;
    let basis = onb(d);
    return normalize(basis.t * (s * cos(phi)) + basis.b * (s * sin(phi)) + d * c);
}

// KeyLight::pdf: the density in solid angle of a disc's directions; 0 for a point-like light.
fn disc_pdf(cos_r: f32) -> f32 {
    if (cos_r >= 1.0) {
        return 0.0;
    }
    return 1.0 / (2.0 * PI * (1.0 - cos_r));
}

// lights::Spot::falloff.
fn spot_falloff(l: Light, d: vec3f) -> f32 {
    let t = clamp((dot(d, l.axis) - l.cos_outer) / max(l.cos_inner - l.cos_outer, 1e-6), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

// lights::LightSample; mis_pdf 0: none (a point-like sun, a point, a point spot); ok false:
// no sample.
struct LightSample {
    dir: vec3f,
    t_max: f32,
    e: f32,
    color: vec3f,
    mis_pdf: f32,
    ok: bool,
}

// An area light's sides (its `u` in `axis`, its `v` in `size`, `cos_inner`, `cos_outer`),
// its area and the unit normal of the side it shines on (lights::area_and_normal).
struct AreaShape {
    u: vec3f,
    v: vec3f,
    area: f32,
    n: vec3f,
}

fn area_shape(l: Light) -> AreaShape {
    let u_vec = l.axis;
    let v_vec = vec3f(l.size, l.cos_inner, l.cos_outer);
    let c = cross(v_vec, u_vec);
    var area = 4.0 * length(c);
    if (l.kind == 4u) {
        area = PI * length(c);
    }
    var n = vec3f(0.0);
    if (length(c) > 0.0) {
        n = normalize(c);
    }
    return AreaShape(u_vec, v_vec, area, n);
}

// lights::cone_one_minus_cos: 1 − cos of the half-angle of the cone a sphere of squared radius
// `r2` fills seen from squared distance `d2`.
fn cone_one_minus_cos(r2: f32, d2: f32) -> f32 {
    let s2 = r2 / d2;
    return s2 / (1.0 + sqrt(max(1.0 - s2, 0.0)));
}

// lights::Light::sample: a direction towards light `l` from `p` (what it brings not yet over
// the pick's chance).
fn light_sample_one(l: Light, p: vec3f, u: vec2f) -> LightSample {
    var out = LightSample(vec3f(0.0, 1.0, 0.0), T_FAR, 0.0, l.color, 0.0, false);
    if (l.kind == 0u) {
        out.dir = disc_sample_dir(l.pos, l.size, u);
        out.e = l.power;
        out.mis_pdf = disc_pdf(l.size);
        out.ok = true;
        return out;
    }
    if (l.kind >= 3u) {
        // lights::Light::sample's area light: a point uniform over the rectangle or ellipse.
        let shape = area_shape(l);
        let area = shape.area;
        var q = l.pos + shape.u * (2.0 * u.x - 1.0) + shape.v * (2.0 * u.y - 1.0);
        if (l.kind == 4u) {
            let r = sqrt(u.x);
            let phi = 2.0 * PI * u.y;
            q = l.pos + (shape.u * cos(phi) + shape.v * sin(phi)) * r;
        }
        let to_q = q - p;
        let dq2 = dot(to_q, to_q);
        let dq = sqrt(dq2);
        if (!(dq > 0.0)) {
            return out;
        }
        out.dir = to_q / dq;
        out.t_max = dq;
        let cos_light = max(dot(-out.dir, shape.n), 0.0);
        out.e = l.power * area * cos_light / dq2;
        if (cos_light > 0.0) {
            out.mis_pdf = dq2 / (area * cos_light);
        }
        out.ok = true;
        return out;
    }
    let to = l.pos - p;
    let d2 = dot(to, to);
    let d = sqrt(d2);
    let radius = l.size;
    if (!(d > radius && d > 0.0)) {
        return out;
    }
    let centre = to / d;
    var cone = 1.0;
    if (l.kind == 2u) {
        cone = spot_falloff(l, -centre);
    }
    out.ok = true;
    if (radius <= 0.0) {
        out.dir = centre;
        out.t_max = d;
        out.e = l.power * cone / d2;
        return out;
    }
    let one_minus_cos = cone_one_minus_cos(radius * radius, d2);
    let c = 1.0 - u.x * one_minus_cos;
    let sn = sqrt(max(1.0 - c * c, 0.0));
    let phi = 2.0 * PI * u.y;
    let basis = onb(centre);
    let dir = normalize(basis.t * (sn * cos(phi)) + basis.b * (sn * sin(phi)) + centre * c);
    let radiance = l.power / (PI * radius * radius);
    let solid_angle = 2.0 * PI * one_minus_cos;
    let b_half = dot(dir, to);
    let near = b_half - sqrt(max(b_half * b_half - (d2 - radius * radius), 0.0));
    out.dir = dir;
    out.t_max = max(near, 0.0);
    out.e = radiance * solid_angle * cone;
    out.mis_pdf = 1.0 / solid_angle;
    return out;
}

// lights::LightMet; ok false: not met.
struct LightMet {
    t: f32,
    radiance: f32,
    pdf: f32,
    ok: bool,
}

// lights::Light::met: where a ray from `o` along `d` meets light `l`'s surface, the near side
// of a sphere or the front of a rectangle or disk.
fn light_met_one(l: Light, o: vec3f, d: vec3f) -> LightMet {
    var out = LightMet(0.0, 0.0, 0.0, false);
    if (l.kind == 1u || l.kind == 2u) {
        let radius = l.size;
        if (radius <= 0.0) {
            return out;
        }
        let to = l.pos - o;
        let d2 = dot(to, to);
        let r2 = radius * radius;
        let b_half = dot(d, to);
        let disc = b_half * b_half - (d2 - r2);
        if (!(d2 > r2 && b_half > 0.0 && disc >= 0.0)) {
            return out;
        }
        let one_minus_cos = cone_one_minus_cos(r2, d2);
        var cone = 1.0;
        if (l.kind == 2u) {
            cone = spot_falloff(l, -to / sqrt(d2));
        }
        out.t = max(b_half - sqrt(disc), 0.0);
        out.radiance = l.power / (PI * r2) * cone;
        out.pdf = 1.0 / (2.0 * PI * one_minus_cos);
        out.ok = true;
        return out;
    }
    if (l.kind >= 3u) {
        let shape = area_shape(l);
        let n = shape.n;
        let cos_light = -dot(d, n);
        if (!(cos_light > 0.0)) {
            return out;
        }
        let t = dot(o - l.pos, n) / cos_light;
        if (!(t > 0.0 && t < T_FAR)) {
            return out;
        }
        let local = o + d * t - l.pos;
        let a = dot(local, shape.u) / dot(shape.u, shape.u);
        let b = dot(local, shape.v) / dot(shape.v, shape.v);
        var inside = abs(a) <= 1.0 && abs(b) <= 1.0;
        if (l.kind == 4u) {
            inside = a * a + b * b <= 1.0;
        }
        if (inside) {
            out.t = t;
            out.radiance = l.power;
            out.pdf = t * t / (shape.area * cos_light);
            out.ok = true;
        }
    }
    return out;
}

// lights::Light::weight_at: what light `l`'s centre casts on `q` across a surface of normal
// `n` (luminance), the weight it is picked by there.
fn light_weight(l: Light, q: vec3f, n: vec3f) -> f32 {
    if (l.kind == 0u) {
        return l.power * max(dot(n, l.pos), 0.0);
    }
    if (l.kind >= 3u) {
        let shape = area_shape(l);
        let area = shape.area;
        let normal = shape.n;
        let to = q - l.pos;
        let d2 = max(max(dot(to, to), area), 1e-12);
        let d = sqrt(d2);
        let cosines = max(dot(to, normal) / d, 0.0) * max(-dot(to, n) / d, 0.0);
        return l.power * area * cosines / d2;
    }
    let to = q - l.pos;
    let d2 = max(max(dot(to, to), l.size * l.size), 1e-12);
    let d = sqrt(d2);
    var cone = 1.0;
    if (l.kind == 2u) {
        cone = spot_falloff(l, to / d);
    }
    return l.power * cone * max(-dot(to, n) / d, 0.0) / d2;
}

// lights::LightSet::at: each light's chance of being picked at a surface event whose rays leave
// from `q` across a surface of normal `n` (lights::CHANCE_FLOOR).
struct Chances {
    p: array<f32, 16>,  // render::lights::MAX_LIGHTS
}

fn light_chances(q: vec3f, n: vec3f) -> Chances {
    var c: Chances;
    let count = lighting.light_count;
    var total = 0.0;
    for (var i = 0u; i < count; i += 1u) {
        let x = light_weight(lighting.lights[i], q, n);
        // Not finite, or negative: no weight.
        var w = 0.0;
        if (x > 0.0 && x <= 3.4028235e38) {
            w = x;
        }
        c.p[i] = w;
        total += w;
    }
    let floor = CHANCE_FLOOR / f32(count);
    var sum = 0.0;
    for (var i = 0u; i < count; i += 1u) {
        var share = 1.0;
        if (total > 0.0) {
            share = max(c.p[i] / total, floor);
        }
        c.p[i] = share;
        sum += share;
    }
    for (var i = 0u; i < count; i += 1u) {
        c.p[i] = c.p[i] / sum;
    }
    return c;
}

// lights::LightsAt::sample: one light picked by u.x under the chances `c`
// (lights::LightsAt::pick), its sample with what it brings and its density over the pick's
// chance.
fn light_sample(c: Chances, p: vec3f, u: vec2f) -> LightSample {
    let n = lighting.light_count;
    var i = 0u;
    var start = 0.0;
    while (i + 1u < n && u.x >= start + c.p[i]) {
        start += c.p[i];
        i += 1u;
    }
    let l = lighting.lights[i];
    let prob = c.p[i];
    let ux = clamp((u.x - start) / prob, 0.0, 1.0 - 5.9604645e-8);
    var s = light_sample_one(l, p, vec2f(ux, u.y));
    s.e = s.e / prob;
    s.mis_pdf = s.mis_pdf * prob;
    return s;
}

// lights::LightsAt::escape: radiance of the directional discs a BSDF sample leaving along
// `wi` meets, each MIS-weighted against its light samples under the chances `c` (weight 1 for
// a delta lobe).
fn lights_escape(c: Chances, wi: vec3f, pdf: f32, delta: bool) -> vec3f {
    var l = vec3f(0.0);
    for (var i = 0u; i < lighting.light_count; i += 1u) {
        let li = lighting.lights[i];
        let lp = disc_pdf(li.size);
        if (li.kind != 0u || lp <= 0.0 || dot(wi, li.pos) < li.size) {
            continue;
        }
        var w = 1.0;
        if (!delta) {
            w = power_heuristic(pdf, lp * c.p[i]);
        }
        l += li.color * (li.power * lp * w);
    }
    return l;
}

// lights::LightSet::seen_along: whether a BSDF sample leaving along `wi` meets a disc.
fn lights_seen_along(wi: vec3f) -> bool {
    for (var i = 0u; i < lighting.light_count; i += 1u) {
        let li = lighting.lights[i];
        if (li.kind == 0u && li.size < 1.0 && dot(wi, li.pos) >= li.size) {
            return true;
        }
    }
    return false;
}

// lights::LightsAt::met: radiance of the spheres and area lights a BSDF sample from `o` along
// `wi` (density `pdf`, a delta lobe or not) meets before `t_max`, each MIS-weighted against
// its light samples under the chances `c`.
fn lights_met(c: Chances, o: vec3f, wi: vec3f, t_max: f32, pdf: f32, delta: bool) -> vec3f {
    var l = vec3f(0.0);
    for (var i = 0u; i < lighting.light_count; i += 1u) {
        let li = lighting.lights[i];
        let m = light_met_one(li, o, wi);
        if (!m.ok || m.t >= t_max) {
            continue;
        }
        var w = 1.0;
        if (!delta) {
            w = power_heuristic(pdf, m.pdf * c.p[i]);
        }
        l += li.color * (m.radiance * w);
    }
    return l;
}

// lights::LightSet::meets_local: whether a BSDF sample from `o` along `wi` meets a sphere or
// an area light at all.
fn lights_meet_local(o: vec3f, wi: vec3f) -> bool {
    for (var i = 0u; i < lighting.light_count; i += 1u) {
        if (light_met_one(lighting.lights[i], o, wi).ok) {
            return true;
        }
    }
    return false;
}

// beauty::escape_radiance: light a BSDF sample (direction `wi`, density `pdf`, a delta lobe
// or not) meets when it leaves the scene, the environment and the directional discs, each
// weighted by MIS against its own light samples.
fn escape_radiance(c: Chances, wi: vec3f, pdf: f32, delta: bool) -> vec3f {
    var l = vec3f(0.0);
    if (lighting.env_lights != 0u) {
        var w = 1.0;
        if (!delta) {
            w = power_heuristic(pdf, env_pdf(wi));
        }
        l += env_radiance(wi) * w;
    }
    return l + lights_escape(c, wi, pdf, delta);
}

// beauty::shadow_ray (t_max = +∞).
fn shadow_ray(origin: vec3f, dir: vec3f) -> Ray {
    return Ray(origin, dir, 0.0, T_FAR);
}

// beauty::shadow_ray_to: one that stops at t_max (a local light's distance).
fn shadow_ray_to(origin: vec3f, dir: vec3f, t_max: f32) -> Ray {
    return Ray(origin, dir, 0.0, t_max);
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

fn no_query() -> QueryRec {
    return QueryRec(vec3f(0.0), 0.0, vec3f(0.0, 0.0, 1.0), 0.0, 0u, 0u, 0u, 0u);
}

fn query(ray: Ray, bounce: u32, any: bool) -> QueryRec {
    return QueryRec(ray.origin, ray.t_min, ray.dir, ray.t_max, bounce, select(0u, 1u, any), 1u, 0u);
}

// beauty::facing_normals: the normals turned to the side `dir` arrives from, the shading
// normal replaced by the geometric one where it faces away.
struct Facing {
    ng: vec3f,
    ns: vec3f,
}

fn facing_normals(geometric: vec3f, shading: vec3f, dir: vec3f) -> Facing {
    let wo = -dir;
    var ng = geometric;
    var ns = shading;
    if (dot(wo, ng) < 0.0) {
        ng = -ng;
        ns = -ns;
    }
    if (dot(wo, ns) <= 0.0) {
        ns = ng;
    }
    return Facing(ng, ns);
}

// A normal in the local shading frame `basis` about `ns` (exactly z where it is `ns`).
fn local_normal(n: vec3f, ns: vec3f, basis: Basis) -> vec3f {
    if (all(n == ns)) {
        return vec3f(0.0, 0.0, 1.0);
    }
    return to_local(n, basis.t, basis.b, ns);
}

fn has(s: PathState, flag: u32) -> bool {
    return (s.flags & flag) != 0u;
}

// The pixel an invocation serves: its index in the tile (`paths`, `beauty_sums`) and the ray
// context of its sample (bounce 0).
struct PixelRef {
    x: u32,
    y: u32,
    i: u32,
    ctx: RayContext,
}

fn pixel_ref(gid: vec3<u32>) -> PixelRef {
    let x = frame.tile_origin.x + gid.x;
    let y = frame.tile_origin.y + gid.y;
    let pixel = y * frame.width + x;
    return PixelRef(x, y, gid.y * frame.tile_size.x + gid.x, RayContext(pixel, frame.sample_index, 0u, frame.seed));
}

fn in_tile(gid: vec3<u32>) -> bool {
    return gid.x < frame.tile_size.x && gid.y < frame.tile_size.y;
}

// The sample's camera ray (render_beauty's jittered primary ray), from the origin and
// direction `new_path` keeps in `ground_p` and `dir` until the camera step's event
// (camera_ray's range).
fn path_camera_ray(s: PathState) -> Ray {
    return Ray(s.ground_p, s.dir, 0.0, T_FAR);
}

// The three ray slots of a step (indexed by SLOT_*).
struct Queries {
    key: QueryRec,
    env: QueryRec,
    next: QueryRec,
}

fn no_queries() -> Queries {
    return Queries(no_query(), no_query(), no_query());
}

fn slot_query(qs: Queries, slot: u32) -> QueryRec {
    if (slot == SLOT_KEY) {
        return qs.key;
    }
    if (slot == SLOT_ENV) {
        return qs.env;
    }
    return qs.next;
}

// Step 1 of trace_sample's loop: the rays step `s.step` needs (at a surface step, at `hit`,
// the last continuation's answer), and what each shadow ray adds if unoccluded (kept in `s`
// for `use_answers`).
fn ask(s: ptr<function, PathState>, px: PixelRef, hit: Answer) -> Queries {
    let ctx = px.ctx;
    let eps = lighting.eps;
    let env_lights = lighting.env_lights != 0u;
    var q0 = no_query();
    var q1 = no_query();
    var q2 = no_query();
    (*s).key_term = vec3f(0.0);
    (*s).env_term = vec3f(0.0);
    (*s).key_e = 0.0;
    (*s).env_e = 0.0;
    (*s).flags &= ~(PATH_BSDF_OK | PATH_BSDF_DELTA | PATH_LAST | PATH_MEETS_LIGHT);
    if ((*s).step == STEP_CAMERA) {
        (*s).rays += 1u;
        q2 = query(path_camera_ray(*s), 0u, false);
    } else if ((*s).step == STEP_GROUND) {
        // beauty::ground_light (the camera sample's context: bounce 0).
        let up = lighting.ground_up;
        let origin = (*s).ground_p + up * eps;
        if (lighting.light_count != 0u) {
            let ls = light_sample(light_chances(origin, up), origin, rand2(ctx, 0u, KEY_DIM, PURPOSE_LIGHT));
            let cos_k = dot(ls.dir, up);
            if (ls.ok && cos_k > 0.0 && ls.e > 0.0) {
                (*s).key_e = ls.e * cos_k;
                (*s).ground_all += (*s).key_e;
                (*s).key_shadow_rays += 1u;
                q0 = query(shadow_ray_to(origin, ls.dir, ls.t_max - eps), 0u, true);
            }
        }
        if (env_lights) {
            let es = env_sample(rand2(ctx, 0u, 0u, PURPOSE_LIGHT));
            let cos_e = dot(es.dir, up);
            if (cos_e > 0.0 && es.pdf > 0.0) {
                (*s).env_e = luminance(env_radiance(es.dir)) * cos_e / es.pdf;
                (*s).ground_all += (*s).env_e;
                (*s).env_shadow_rays += 1u;
                q1 = query(shadow_ray(origin, es.dir), 0u, true);
            }
        }
    } else {
        // beauty::surface_radiance, event `bounce`, at the hit the last trace found.
        let bounce = (*s).bounce;
        let throughput = (*s).throughput;
        let m = material_at(hit.prism, hit.uv);
        if (bounce == 0u) {
            // The camera hit's reflectance (trace_sample's albedo guide), read here rather
            // than where the hit is found: one material lookup in the kernel, not two.
            (*s).albedo = guide_albedo(m);
        }
        let wo = -(*s).dir;
        let facing = facing_normals(hit.geometric_normal, hit.shading_normal, (*s).dir);
        let ng = facing.ng;
        var ns = facing.ns;
        // The normal before the normal map bent it: the diffuse is shadowed about it.
        var unbent = ns;
        if (any(hit.shading_normal != hit.unbent_normal)) {
            unbent = facing_normals(hit.geometric_normal, hit.unbent_normal, (*s).dir).ns;
            // beauty::surface_radiance: a normal map's normal is kept where it faces away
            // from the view, as Cycles keeps it.
            ns = hit.shading_normal * select(1.0, -1.0, dot(ng, hit.geometric_normal) < 0.0);
        }
        let basis = onb(ns);
        let wo_l = to_local(wo, basis.t, basis.b, ns);
        // beauty::surface_radiance: the diffuse on the shading normal, the specular lobe on it
        // turned back where its mirror direction would point into the surface, the clearcoat
        // on its own normal turned back alike.
        let spec_n = valid_reflection_normal(ng, wo, ns);
        let coated = m.clearcoat > 0.0 && any(hit.shading_normal != hit.coat_normal);
        var l: Lobes;
        if (any(spec_n != ns) || coated || any(unbent != ns)) {
            var nc = spec_n;
            if (coated) {
                nc = valid_reflection_normal(ng, wo, facing_normals(hit.geometric_normal, hit.coat_normal, (*s).dir).ns);
            }
            l = lobes_framed(m, wo_l, local_normal(spec_n, ns, basis), local_normal(nc, ns, basis));
            l.unbent_n = local_normal(unbent, ns, basis);
        } else {
            l = lobes(m, wo_l.z);
        }
        let p = hit.position;
        (*s).event_n = ng;
        if (lighting.light_count != 0u) {
            // The lights' chances at the point the event's rays leave from (towards ng's side).
            let chances = light_chances(offset_origin(p, ng, ng, eps), ng);
            let ls = light_sample(chances, p, rand2(ctx, bounce, KEY_DIM, PURPOSE_LIGHT));
            let kd = ls.dir;
            let wi_l = to_local(kd, basis.t, basis.b, ns);
            var f = vec3f(0.0);
            if (ls.ok && dot(kd, ng) > 0.0 && ls.e > 0.0) {
                f = bsdf_eval(l, wo_l, wi_l);
            }
            if (max_element(f) > 0.0) {
                (*s).key_shadow_rays += 1u;
                q0 = query(shadow_ray_to(offset_origin(p, ng, kd, eps), kd, ls.t_max - eps), bounce + 1u, true);
                // A disc is also met by BSDF samples: the two share it by MIS.
                var w = 1.0;
                if (ls.mis_pdf > 0.0) {
                    w = power_heuristic(ls.mis_pdf, bsdf_pdf(l, wo_l, wi_l));
                }
                (*s).key_term = throughput * f * ls.color * (ls.e * w);
            }
        }
        if (env_lights) {
            let es = env_sample(rand2(ctx, bounce, 0u, PURPOSE_LIGHT));
            if (es.pdf > 0.0 && dot(es.dir, ng) > 0.0) {
                let wi_l = to_local(es.dir, basis.t, basis.b, ns);
                let f = bsdf_eval(l, wo_l, wi_l);
                if (max_element(f) > 0.0) {
                    (*s).env_shadow_rays += 1u;
                    q1 = query(shadow_ray(offset_origin(p, ng, es.dir, eps), es.dir), bounce + 1u, true);
                    let w = power_heuristic(es.pdf, bsdf_pdf(l, wo_l, wi_l));
                    (*s).env_term = throughput * f * env_radiance(es.dir) * (w / es.pdf);
                }
            }
        }
        let u_lobe = random(ctx.pixel, ctx.sample, bounce * DIMS + 2u, PURPOSE_BSDF, ctx.seed);
        let bs = bsdf_sample(l, wo_l, u_lobe, rand2(ctx, bounce, 3u, PURPOSE_BSDF));
        var ok = bs.ok;
        var wi = vec3f(0.0);
        if (ok) {
            wi = from_local(bs.wi, basis.t, basis.b, ns);
            if (dot(wi, ng) <= 0.0) {
                ok = false;
            }
        }
        if (ok) {
            (*s).flags |= PATH_BSDF_OK | select(0u, PATH_BSDF_DELTA, bs.delta);
            (*s).bs_weight = bs.weight;
            (*s).bs_pdf = bs.pdf;
            (*s).wi = wi;
            let last = bounce + 1u == lighting.bounces;
            let ray = shadow_ray(offset_origin(p, ng, wi, eps), wi);
            // The spheres and area lights the ray meets before the surface count by MIS.
            let meets = lighting.light_count != 0u && lights_meet_local(ray.origin, wi);
            if (meets) {
                (*s).flags |= PATH_MEETS_LIGHT;
            }
            if (last) {
                (*s).flags |= PATH_LAST;
                if (lighting.emissive != 0u || meets) {
                    // Last event: the surface the ray meets counts with its glow, and the
                    // lights before it.
                    (*s).rays += 1u;
                    q2 = query(ray, bounce + 1u, false);
                } else if (env_lights) {
                    // Last event: only whether the ray escapes matters.
                    (*s).env_shadow_rays += 1u;
                    q2 = query(ray, bounce + 1u, true);
                } else if (lights_seen_along(wi)) {
                    (*s).key_shadow_rays += 1u;
                    q2 = query(ray, bounce + 1u, true);
                }
            } else {
                (*s).rays += 1u;
                q2 = query(ray, bounce + 1u, false);
            }
        }
    }
    return Queries(q0, q1, q2);
}

// Step 3 of trace_sample's loop: the answers to the step's rays `qs` (the continuation's
// `next`, whether each shadow ray was occluded), used as the CPU does; sets the next step.
fn use_answers(s: ptr<function, PathState>, px: PixelRef, qs: Queries, next: Answer, occluded_key: bool, occluded_env: bool) {
    let live_key = qs.key.live != 0u;
    let live_env = qs.env.live != 0u;
    let live_next = qs.next.live != 0u;
    let seen_key = live_key && occluded_key;
    let seen_env = live_env && occluded_env;
    var next_prism = NO_PRISM;
    var next_t = T_FAR;
    if (live_next) {
        next_prism = next.prism;
        next_t = next.t;
    }
    // The glow of the surface the continuation found (beauty::BeautyScene::emission_at),
    // counted below where the CPU counts it: at the start of the surface's event, or as the
    // last bounce's light. One lookup site in the kernel.
    let step = (*s).step;
    var glow = vec3f(0.0);
    if (lighting.emissive != 0u && next_prism != NO_PRISM) {
        // Seen along the camera ray, or the continuation's.
        var seen_along = (*s).wi;
        if (step == STEP_CAMERA) {
            seen_along = (*s).dir;
        }
        glow = emission_at(next_prism, next.uv, next.geometric_normal, next.coat_normal, seen_along);
    }
    if (step == STEP_CAMERA) {
        let camera = path_camera_ray(*s);
        var gt = GroundHit(false, 0.0);
        if (lighting.has_ground != 0u) {
            gt = ground_hit(camera);
        }
        if (next_prism != NO_PRISM && (!gt.ok || next_t <= gt.t)) {
            (*s).flags |= PATH_SURFACE;
            (*s).normal = facing_normals(next.geometric_normal, next.shading_normal, camera.dir).ns;
            // trace_sample's `for bounce in 0..bounces`: none at 0 bounces (BeautyScene::bounces
            // is 1..=4; the albedo guide is read at the first event).
            if (lighting.bounces > 0u) {
                (*s).radiance += glow;
            }
            (*s).step = select(STEP_DONE, STEP_SURFACE, lighting.bounces > 0u);
        } else if (gt.ok) {
            (*s).background = env_radiance_smooth(camera.dir);
            (*s).flags |= PATH_GROUND;
            (*s).ground_p = ray_at(camera, gt.t);
            (*s).step = STEP_GROUND;
        } else {
            (*s).background = env_radiance_smooth(camera.dir);
            (*s).step = STEP_DONE;
        }
    } else if (step == STEP_GROUND) {
        if (live_key && !seen_key) {
            (*s).ground_lit += (*s).key_e;
        }
        if (live_env && !seen_env) {
            (*s).ground_lit += (*s).env_e;
        }
        (*s).step = STEP_DONE;
    } else {
        if (live_key && !seen_key) {
            (*s).radiance += (*s).key_term;
        }
        if (live_env && !seen_env) {
            (*s).radiance += (*s).env_term;
        }
        (*s).step = STEP_DONE;
        if (has(*s, PATH_BSDF_OK)) {
            let wi = (*s).wi;
            (*s).throughput *= (*s).bs_weight;
            let throughput = (*s).throughput;
            let delta = has(*s, PATH_BSDF_DELTA);
            // The event's chances again, at the continuation's origin (where `ask` took them),
            // where a met light or an escape (a disc) weighs by them.
            var chances: Chances;
            if (lighting.light_count != 0u && (next_prism == NO_PRISM || has(*s, PATH_MEETS_LIGHT))) {
                chances = light_chances(qs.next.origin, (*s).event_n);
            }
            var met = vec3f(0.0);
            if (has(*s, PATH_MEETS_LIGHT)) {
                met = lights_met(chances, qs.next.origin, wi, select(next_t, T_FAR, next_prism == NO_PRISM), (*s).bs_pdf, delta);
            }
            if (has(*s, PATH_LAST)) {
                if (live_next && next_prism == NO_PRISM) {
                    (*s).radiance += throughput * (escape_radiance(chances, wi, (*s).bs_pdf, delta) + met);
                } else if (live_next) {
                    (*s).radiance += throughput * (glow + met);
                }
            } else if (next_prism != NO_PRISM) {
                (*s).radiance += throughput * met;
                (*s).radiance += throughput * glow;
                (*s).dir = wi;
                (*s).bounce += 1u;
                (*s).step = STEP_SURFACE;
            } else {
                (*s).radiance += throughput * (escape_radiance(chances, wi, (*s).bs_pdf, delta) + met);
            }
        }
    }
}

// render_beauty's accumulation of one finished sample into the pixel's sums.
fn accumulate(i: u32, s: PathState) {
    var acc = beauty_sums[i];
    acc.radiance += s.radiance;
    acc.surface += select(0.0, 1.0, has(s, PATH_SURFACE));
    acc.normal += s.normal;
    acc.albedo += s.albedo;
    if (has(s, PATH_GROUND)) {
        acc.ground_samples += 1.0;
        acc.ground_lit += s.ground_lit;
        acc.ground_unshadowed += s.ground_all;
        acc.ground_background += s.background;
    } else {
        acc.background += s.background;
    }
    acc.rays += s.rays;
    acc.key_shadow_rays += s.key_shadow_rays;
    acc.env_shadow_rays += s.env_shadow_rays;
    beauty_sums[i] = acc;
}

fn no_answer() -> Answer {
    return Answer(vec3f(0.0), T_FAR, vec3f(0.0), NO_PRISM, vec3f(0.0), 0u, vec2f(0.0), vec3f(0.0),
        vec3f(0.0));
}

// A new path: the camera step of the pixel's sample.
fn new_path(px: PixelRef) -> PathState {
    let camera = camera_ray(vec2f(f32(px.x), f32(px.y)) + pixel_jitter(px.ctx.pixel, px.ctx.sample));
    return PathState(vec3f(1.0), STEP_CAMERA, camera.dir, 0u, camera.origin, 0u,
        vec3f(0.0), 0.0, vec3f(0.0), 0.0, vec3f(0.0), 0.0, vec3f(0.0), 0.0, vec3f(0.0), 0.0,
        vec3f(0.0), 0u, 0u, 0u, vec3f(0.0), vec3f(0.0), vec3f(0.0));
}

// One ray of a step: Pdm::intersect with surface data (the continuation), or Pdm::occluded
// (`any`: shadow rays and the last event's continuation).
fn trace_query(q: QueryRec, px: PixelRef) -> Answer {
    let any = q.any != 0u;
    let ctx = RayContext(px.ctx.pixel, px.ctx.sample, q.bounce, px.ctx.seed);
    return query_answer(q, traverse(Ray(q.origin, q.dir, q.t_min, q.t_max), ctx, any));
}

// The answer to `q` from the hit its traversal `found`: with surface data if it asked for
// them.
fn query_answer(q: QueryRec, found: Hit) -> Answer {
    var hit = found;
    var coat = vec3f(0.0);
    var unbent = vec3f(0.0);
    if (q.any == 0u && hit.prism != NO_PRISM) {
        fill_surface(&hit);
        coat = clearcoat_normal(hit);
        unbent = hit.shading_normal;
        hit = shade_hit(hit);
    }
    return Answer(hit.position, hit.t, hit.geometric_normal, hit.prism, hit.shading_normal, 0u, hit.uv,
        coat, unbent);
}

// Workgroup edge = gpu::layout::WORKGROUP (the host dispatches div_ceil(tile, 8) groups).

// The fused schedule (software adapters, gpu::BeautySchedule::Fused): one invocation renders
// its pixel's whole sample, the steps in a loop, the rays of each through one call site of
// the traversal (Mesa inlines every call site, so each would be a full copy of the BVH walk
// and the PDM march), only the live ones: the loop runs as long as some lane has a live ray
// left, so a lock-step implementation does not trace a masked ray for every empty slot.
@compute @workgroup_size(8, 8, 1)
fn render_beauty(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (!in_tile(gid)) {
        return;
    }
    let px = pixel_ref(gid);
    var s = new_path(px);
    var next = no_answer();
    loop {
        let qs = ask(&s, px, next);
        var live = array<u32, 3>(0u, 0u, 0u);
        var live_n = 0u;
        for (var k = 0u; k < 3u; k++) {
            if (slot_query(qs, k).live != 0u) {
                live[live_n] = k;
                live_n += 1u;
            }
        }
        var occluded_key = false;
        var occluded_env = false;
        for (var j = 0u; j < 3u; j++) {
            if (j >= live_n) {
                break;
            }
            let k = live[j];
            let a = trace_query(slot_query(qs, k), px);
            if (k == SLOT_NEXT) {
                next = a;
            } else if (k == SLOT_KEY) {
                occluded_key = a.prism != NO_PRISM;
            } else {
                occluded_env = a.prism != NO_PRISM;
            }
        }
        use_answers(&s, px, qs, next, occluded_key, occluded_env);
        if (s.step == STEP_DONE) {
            break;
        }
    }
    accumulate(px.i, s);
}

// The wavefront schedule (hardware adapters, gpu::BeautySchedule::Wavefront): the same steps
// as dispatches over the tile's path records, so that the traversal runs in a kernel whose
// state is one ray.

// A new path per pixel: its camera ray.
@compute @workgroup_size(8, 8, 1)
fn beauty_start(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (!in_tile(gid)) {
        return;
    }
    let px = pixel_ref(gid);
    var s = new_path(px);
    paths[px.i].queries = ask(&s, px, no_answer());
    paths[px.i].state = s;
}
// The rays the paths asked for (the kernel's only traversal: Pdm::intersect with surface
// data, or Pdm::occluded). The host dispatches `layers` workgroup rows per row of the tile,
// one per slot that can be live in the step (1: the continuation; 2: and the environment's
// shadow ray; 3: and the key light's): workgroup row `wy` traces slot `SLOT_NEXT - wy %
// layers` of the pixels of tile row `wy / layers`. Interleaved rather than one grid layer
// per slot, so that a dispatch's live rays are spread over its whole grid: lavapipe hands
// each of its threads a contiguous share of the workgroups, and with a layer per slot the
// continuation rays of a camera step all fell to one thread (1.7× the time on 2 cores).
//
// An invocation traces its slot for the pixels x = gid.x, gid.x + width, gid.x + 2 width, …
// of its row (width: the grid's invocations across; the host makes the grid
// gpu::GpuContext::trace_pixels times narrower than the tile), one after another in one loop
// with the traversal's steps (`walk_step`): an invocation whose ray ends takes its next ray
// at once, instead of idling until the longest ray of its SIMD group ends.
@compute @workgroup_size(8, 8, 1)
fn beauty_trace(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let rows = (frame.tile_size.y + 7u) / 8u;
    let layers = groups.y / rows;
    let wy = gid.y / 8u;
    let slot = SLOT_NEXT - wy % layers;
    let y = (wy / layers) * 8u + gid.y % 8u;
    if (y >= frame.tile_size.y) {
        return;
    }
    let stride = groups.x * 8u;
    var x = gid.x;
    var walk: Walk;
    var job = trace_job(x, y, slot);
    loop {
        // The next live ray of this invocation's pixels, if the walk has none.
        loop {
            if (walk.visit != 0u || x >= frame.tile_size.x) {
                break;
            }
            if (job.q.live != 0u) {
                let ctx = RayContext(job.px.ctx.pixel, job.px.ctx.sample, job.q.bounce, job.px.ctx.seed);
                walk_begin(&walk, Ray(job.q.origin, job.q.dir, job.q.t_min, job.q.t_max), ctx, job.q.any != 0u);
                if (walk.visit != 0u) {
                    break;
                }
                // Missed the scene's box: done already.
                answer(job, slot, walk_result(walk));
            }
            x += stride;
            job = trace_job(x, y, slot);
        }
        if (walk.visit == 0u) {
            break;
        }
        if (!walk_step(&walk)) {
            answer(job, slot, walk_result(walk));
            x += stride;
            job = trace_job(x, y, slot);
        }
    }
}

// A ray `beauty_trace` is to trace: pixel (x, y) of the tile (x may be past its edge: then
// `q.live` is 0) and its query in `slot`.
struct TraceJob {
    px: PixelRef,
    q: QueryRec,
}

fn trace_job(x: u32, y: u32, slot: u32) -> TraceJob {
    let g = vec3<u32>(x, y, 0u);
    let px = pixel_ref(g);
    if (!in_tile(g)) {
        return TraceJob(px, no_query());
    }
    // The one slot this invocation traces (not the record's three).
    var q = paths[px.i].queries.next;
    if (slot == SLOT_KEY) {
        q = paths[px.i].queries.key;
    } else if (slot == SLOT_ENV) {
        q = paths[px.i].queries.env;
    }
    return TraceJob(px, q);
}

// Store the answer to `job`'s ray, whose traversal `found` a hit or none.
fn answer(job: TraceJob, slot: u32, found: Hit) {
    let a = query_answer(job.q, found);
    let i = job.px.i;
    if (slot == SLOT_NEXT) {
        paths[i].next = a;
    } else if (slot == SLOT_KEY) {
        paths[i].occluded_key = select(0u, 1u, a.prism != NO_PRISM);
    } else {
        paths[i].occluded_env = select(0u, 1u, a.prism != NO_PRISM);
    }
}

// The answers of the rays just traced, then the next step's rays; a path that ends adds its
// sample to the sums.
@compute @workgroup_size(8, 8, 1)
fn beauty_shade(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (!in_tile(gid)) {
        return;
    }
    let px = pixel_ref(gid);
    var s = paths[px.i].state;
    if (s.step == STEP_DONE) {
        return;
    }
    let r = paths[px.i];
    use_answers(&s, px, r.queries, r.next, r.occluded_key != 0u, r.occluded_env != 0u);
    if (s.step == STEP_DONE) {
        accumulate(px.i, s);
        // Nothing left to trace for this pixel in the dispatches that follow.
        paths[px.i].queries = no_queries();
    } else {
        paths[px.i].queries = ask(&s, px, r.next);
    }
    paths[px.i].state = s;
}
