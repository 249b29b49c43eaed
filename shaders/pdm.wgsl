// pdm.wgsl — projective displacement mapping (Hoetzlein 2025, Algorithm 1), the mirror of
// core/src/trace/pdm.rs function by function: the ray's interval in the shared-wall prism
// (prism_hit.wgsl), a march with step dt from the entry whose first step is jittered by R·dt
// (§5.3, the same counter-based R as the CPU), scanning-triangle barycentrics by Ericson's five
// dot products (App. C), and the crossing refined onto the canonical surface (Illinois regula
// falsi on λ|m| − D(uv(b)) with `project_to_prism`). Flat prisms meet the triangle V_i + D n_i
// and are moved onto the canonical surface by Newton (`flat_hit`). See pdm.rs for why each
// departure from the paper is there. Only the shared-wall construction is built on the GPU
// (the paper's parallel-offset prism is a CPU-only measurement mode).

const EDGE_TOL: f32 = 1e-5;
const DETECT_TOL: f32 = 0.05;
const INTERVAL_PAD: f32 = 1e-4;
const MAX_STEPS: u32 = 16384u;
const REFINE_ITERS: u32 = 12u;
const F32_MIN_POSITIVE: f32 = 1.17549435e-38;

// pdm::Local: one prism in a local frame (origin at V_0).
struct Local {
    origin: vec3f,
    geom: PrismGeom,
    // Scanning directions n_i / (n_i·N_g).
    a: array<vec3f, 3>,
    ng: vec3f,
    // Longest base edge.
    scale: f32,
}

// Local::new.
fn local_frame(p: Prism) -> Local {
    let va = vertices[p.tri[0]];
    let vb = vertices[p.tri[1]];
    let vc = vertices[p.tri[2]];
    let origin = va.position;
    let v1 = vb.position - origin;
    let v2 = vc.position - origin;
    let n = array<vec3f, 3>(va.normal, vb.normal, vc.normal);
    let ng = normalize_or_zero(cross(v1, v2));
    let a = array<vec3f, 3>(
        n[0] / max(dot(n[0], ng), M_LO_FLOOR),
        n[1] / max(dot(n[1], ng), M_LO_FLOOR),
        n[2] / max(dot(n[2], ng), M_LO_FLOOR),
    );
    let scale = max(max(max(length(v1), length(v2)), length(v2 - v1)), F32_MIN_POSITIVE);
    let geom = PrismGeom(
        array<vec3f, 3>(vec3f(0.0), v1, v2),
        n,
        array<vec2f, 3>(vec2f(va.u, va.v), vec2f(vb.u, vb.v), vec2f(vc.u, vc.v)),
    );
    return Local(origin, geom, a, ng, scale);
}

// Barycentrics of s in triangle c by five dot products (Ericson 2004; paper App. C).
fn triangle_barycentric(s: vec3f, c: array<vec3f, 3>) -> vec3f {
    let x0 = c[1] - c[0];
    let x1 = c[2] - c[0];
    let x2 = s - c[0];
    let d00 = dot(x0, x0);
    let d01 = dot(x0, x1);
    let d11 = dot(x1, x1);
    let d20 = dot(x2, x0);
    let d21 = dot(x2, x1);
    let inv = 1.0 / (d00 * d11 - d01 * d01);
    let b1 = (d11 * d20 - d01 * d21) * inv;
    let b2 = (d00 * d21 - d01 * d20) * inv;
    return vec3f(1.0 - b1 - b2, b1, b2);
}

// A march sample: height difference (ray minus surface) and the scanning barycentrics.
struct Sample {
    t: f32,
    g: f32,
    b: vec3f,
}

// A prism-local hit: ray parameter and barycentrics (the CPU's Option<(f32, Vec3)>).
struct PrismHit {
    ok: bool,
    t: f32,
    b: vec3f,
}

fn no_prism_hit() -> PrismHit {
    return PrismHit(false, 0.0, vec3f(0.0));
}

// Pdm::displacement: D at uv.
fn displacement(uv: vec2f) -> f32 {
    return displacement_of(sample_map(uv));
}

// Pdm::intersect_prism: the cheap record for one prism (surface data not filled); `steps`
// accumulates the samples taken, hit or miss.
fn intersect_prism(ray: Ray, ctx: RayContext, prism: u32, steps: ptr<function, u32>) -> Hit {
    let p = prisms[prism];
    let local = local_frame(p);
    let ro = ray.origin - local.origin;
    var r: PrismHit;
    if ((p.flags & PRISM_FLAT) != 0u) {
        r = flat_hit(local, p.d_min, ro, ray);
    } else {
        r = march(local, p, prism, ro, ray, ctx, steps);
    }
    if (!r.ok) {
        return no_hit();
    }
    return Hit(r.t, prism, r.b, vec2f(0.0), ray_at(ray, r.t), vec3f(0.0), vec3f(0.0), 0u);
}

// Pdm::fill_surface: uv, position and normals from the canonical surface.
fn fill_surface(hit: ptr<function, Hit>) {
    let g = prism_geom(prisms[(*hit).prism]);
    let sp = surface_point(g, (*hit).bary);
    (*hit).uv = sp.uv;
    (*hit).position = sp.position;
    (*hit).geometric_normal = sp.geometric_normal;
    if (frame.normal_mode == 0u) {
        (*hit).shading_normal = sp.smooth_normal;
    } else {
        (*hit).shading_normal = sp.geometric_normal;
    }
}

// Pdm::intersect: closest hit over the BVH, then the surface data of the winner.
fn intersect(ray: Ray, ctx: RayContext) -> Hit {
    var hit = closest_hit(ray, ctx);
    if (hit.prism != NO_PRISM) {
        fill_surface(&hit);
    }
    return hit;
}

// Pdm::step_size.
fn step_size(p: Prism, local: Local) -> f32 {
    var dt = frame.dt_value;
    if (frame.dt_auto != 0u) {
        dt = frame.dt_value * p.texel_world;
    }
    if (finite(dt) && dt > 0.0) {
        return dt;
    }
    // No texel size (UV-degenerate face): a sixteenth of the prism's thickness.
    return max(abs(p.lambda_hi - p.lambda_lo), local.scale * 1e-3) / 16.0;
}

// Pdm::scan: sample at local point s with scanning triangle c at height h.
fn scan(local: Local, t: f32, s: vec3f, c: array<vec3f, 3>, h: f32) -> Sample {
    let b = triangle_barycentric(s, c);
    let a = local.a[0] * b.x + local.a[1] * b.y + local.a[2] * b.z;
    let uv = geom_uv(local.geom, b);
    return Sample(t, h * length(a) - displacement(uv), b);
}

fn inside_detect(b: vec3f) -> bool {
    return min_element(b) >= -DETECT_TOL;
}

// Pdm::march (shared-wall construction).
fn march(local: Local, p: Prism, prism: u32, ro: vec3f, ray: Ray, ctx: RayContext, steps: ptr<function, u32>) -> PrismHit {
    let d = ray.dir;
    let g = local.geom;
    let lo = array<vec3f, 3>(g.v[0] + g.n[0] * p.lambda_lo, g.v[1] + g.n[1] * p.lambda_lo, g.v[2] + g.n[2] * p.lambda_lo);
    let hi = array<vec3f, 3>(g.v[0] + g.n[0] * p.lambda_hi, g.v[1] + g.n[1] * p.lambda_hi, g.v[2] + g.n[2] * p.lambda_hi);
    let iv = ray_prism_interval(ro, d, ray.t_min, ray.t_max, lo, hi);
    if (!iv.ok) {
        return no_prism_hit();
    }
    let pad = INTERVAL_PAD * local.scale;
    let te = max(iv.t_enter - pad, ray.t_min);
    let tx = min(iv.t_exit + pad, ray.t_max);
    let dt = max(step_size(p, local), (tx - te) / f32(MAX_STEPS));

    // Entry sample and the scanning triangle at its height.
    var s = ro + d * te;
    var h = dot(s, local.ng);
    var c = array<vec3f, 3>(g.v[0] + local.a[0] * h, g.v[1] + local.a[1] * h, g.v[2] + local.a[2] * h);
    var prev = scan(local, te, s, c, h);
    var has_prev = inside_detect(prev.b);
    var r = 0.0;
    if (frame.jitter != 0u) {
        r = random(ctx.pixel, ctx.sample, ctx.bounce, PURPOSE_MARCH_JITTER, ctx.seed ^ prism);
    }
    var t = te;
    var t_next = te + select(dt, r * dt, r > 0.0);
    var n = 0u;
    loop {
        t_next = min(t_next, tx);
        s = ro + d * t_next;
        let h_next = dot(s, local.ng);
        let dh = h_next - h;
        c[0] += local.a[0] * dh;
        c[1] += local.a[1] * dh;
        c[2] += local.a[2] * dh;
        h = h_next;
        t = t_next;
        n += 1u;
        let cur = scan(local, t, s, c, h);
        if (inside_detect(cur.b)) {
            if (has_prev && ((prev.g > 0.0) != (cur.g > 0.0))) {
                let hit = crossing(local, ro, ray, prev, cur, te, tx, dt);
                if (hit.ok) {
                    *steps += n;
                    return hit;
                }
            }
            prev = cur;
            has_prev = true;
        }
        if (t >= tx || n >= MAX_STEPS) {
            break;
        }
        t_next = t + dt;
    }
    *steps += n;
    return no_prism_hit();
}

// Pdm::crossing: resolve a sign change between samples a and b into a hit (or reject it).
fn crossing(local: Local, ro: vec3f, ray: Ray, a: Sample, b: Sample, te: f32, tx: f32, dt: f32) -> PrismHit {
    if (frame.refine == 0u) {
        // The paper's interpolateCrossing, barycentrics from a fresh scanning triangle.
        let t = a.t + (b.t - a.t) * (a.g / (a.g - b.g));
        let s = ro + ray.dir * t;
        let h = dot(s, local.ng);
        let g = local.geom;
        let c = array<vec3f, 3>(g.v[0] + local.a[0] * h, g.v[1] + local.a[1] * h, g.v[2] + local.a[2] * h);
        let bary = triangle_barycentric(s, c);
        let ok = min_element(bary) >= -EDGE_TOL && t >= te && t <= tx;
        return PrismHit(ok, t, bary);
    }
    return refine_canonical(local, ro, ray, a, b, te, tx, dt);
}

// Pdm::canonical_g: λ|m| − D(uv(b)) at local point x, (b, λ) projected from a guess.
struct CanonicalG {
    ok: bool,
    g: f32,
    b: vec3f,
    lambda: f32,
}

fn canonical_g(local: Local, x: vec3f, guess_b: vec3f, guess_lambda: f32) -> CanonicalG {
    let g = local.geom;
    var pr = project_to_prism(g, x, guess_b, guess_lambda);
    if (!pr.ok) {
        pr = project_to_prism(g, x, vec3f(1.0 / 3.0), guess_lambda);
        if (!pr.ok) {
            return CanonicalG(false, 0.0, vec3f(0.0), 0.0);
        }
    }
    let m = length(geom_normal_dir(g, pr.b));
    return CanonicalG(true, pr.lambda * m - displacement(geom_uv(g, pr.b)), pr.b, pr.lambda);
}

// The λ of a sample's ray point on the line through P(b) along m(b) (refine_canonical's guess).
fn lambda_guess(local: Local, ro: vec3f, d: vec3f, s: Sample) -> f32 {
    let x = ro + d * s.t;
    let m = geom_normal_dir(local.geom, s.b);
    return dot(x - geom_position(local.geom, s.b), m) / max(dot(m, m), 1e-12);
}

// Pdm::refine_canonical: Illinois regula falsi on the canonical height difference.
fn refine_canonical(local: Local, ro: vec3f, ray: Ray, a: Sample, b: Sample, te: f32, tx: f32, dt: f32) -> PrismHit {
    let d = ray.dir;
    var t0 = a.t;
    var t1 = b.t;
    var e0 = canonical_g(local, ro + d * t0, a.b, lambda_guess(local, ro, d, a));
    if (!e0.ok) {
        return no_prism_hit();
    }
    var e1 = canonical_g(local, ro + d * t1, b.b, lambda_guess(local, ro, d, b));
    if (!e1.ok) {
        return no_prism_hit();
    }
    if ((e0.g > 0.0) == (e1.g > 0.0)) {
        // The scanning and canonical surfaces disagree about this bracket: widen it once.
        t0 = max(t0 - dt, te);
        t1 = min(t1 + dt, tx);
        e0 = canonical_g(local, ro + d * t0, e0.b, e0.lambda);
        if (!e0.ok) {
            return no_prism_hit();
        }
        e1 = canonical_g(local, ro + d * t1, e1.b, e1.lambda);
        if (!e1.ok) {
            return no_prism_hit();
        }
        if ((e0.g > 0.0) == (e1.g > 0.0)) {
            return no_prism_hit();
        }
    }
    let tol_g = 1e-6 * local.scale;
    let tol_t = 1e-7 * (abs(t0) + abs(t1) + local.scale);
    var side = 0;
    for (var i = 0u; i < REFINE_ITERS; i++) {
        if (abs(e0.g) <= tol_g || abs(e1.g) <= tol_g || abs(t1 - t0) <= tol_t) {
            break;
        }
        let t = (t0 * e1.g - t1 * e0.g) / (e1.g - e0.g);
        var near_b = e1.b;
        var near_l = e1.lambda;
        if (abs(t - t0) < abs(t - t1)) {
            near_b = e0.b;
            near_l = e0.lambda;
        }
        let e = canonical_g(local, ro + d * t, near_b, near_l);
        if (!e.ok) {
            break;
        }
        if ((e.g > 0.0) == (e1.g > 0.0)) {
            t1 = t;
            e1 = e;
            if (side == -1) {
                e0.g *= 0.5;
            }
            side = -1;
        } else {
            t0 = t;
            e0 = e;
            if (side == 1) {
                e1.g *= 0.5;
            }
            side = 1;
        }
    }
    var t = t1;
    var bary = e1.b;
    if (abs(e0.g) <= abs(e1.g)) {
        t = t0;
        bary = e0.b;
    }
    let ok = min_element(bary) >= -EDGE_TOL && t >= te && t <= tx && t >= ray.t_min && t <= ray.t_max;
    return PrismHit(ok, t, bary);
}

// Pdm::flat_hit: constant displacement D — meet the triangle V_i + D n_i, then Newton on
// P(b) + D m̂(b) = o + t d for (b1, b2, t).
fn flat_hit(local: Local, dval: f32, ro: vec3f, ray: Ray) -> PrismHit {
    let g = local.geom;
    let d = ray.dir;
    let q0 = g.v[0] + g.n[0] * dval;
    let q1 = g.v[1] + g.n[1] * dval;
    let q2 = g.v[2] + g.n[2] * dval;
    let e1 = q1 - q0;
    let e2 = q2 - q0;
    let pv = cross(d, e2);
    let det = dot(e1, pv);
    if (det == 0.0) {
        return no_prism_hit();
    }
    let tv = ro - q0;
    let qv = cross(tv, e1);
    var b1 = dot(tv, pv) / det;
    var b2 = dot(d, qv) / det;
    var t = dot(e2, qv) / det;
    // The surface bulges past the flat triangle by D(1/|m| − 1): allow a margin.
    if (b1 < -0.25 || b2 < -0.25 || b1 + b2 > 1.25 || !finite(t)) {
        return no_prism_hit();
    }
    let dp0 = g.v[1] - g.v[0];
    let dp1 = g.v[2] - g.v[0];
    let dm0 = g.n[1] - g.n[0];
    let dm1 = g.n[2] - g.n[0];
    let tol = 1e-6 * local.scale;
    var converged = false;
    for (var i = 0; i < 8; i++) {
        let b = vec3f(1.0 - b1 - b2, b1, b2);
        let m = geom_normal_dir(g, b);
        let len = max(length(m), 1e-12);
        let mh = m / len;
        let f = geom_position(g, b) + mh * dval - (ro + d * t);
        if (length(f) <= tol) {
            converged = true;
            break;
        }
        let ds0 = dp0 + (dm0 - mh * dot(mh, dm0)) * (dval / len);
        let ds1 = dp1 + (dm1 - mh * dot(mh, dm1)) * (dval / len);
        let sol = solve3(ds0, ds1, -d, f);
        if (!sol.ok) {
            return no_prism_hit();
        }
        b1 -= sol.x.x;
        b2 -= sol.x.y;
        t -= sol.x.z;
        if (!(finite(b1) && finite(b2) && finite(t))) {
            return no_prism_hit();
        }
    }
    let b = vec3f(1.0 - b1 - b2, b1, b2);
    if (!converged) {
        let f = geom_position(g, b) + normalize_or_zero(geom_normal_dir(g, b)) * dval - (ro + d * t);
        converged = length(f) <= 1e-4 * local.scale;
    }
    let ok = converged && min_element(b) >= -EDGE_TOL && t >= ray.t_min && t <= ray.t_max;
    return PrismHit(ok, t, b);
}
