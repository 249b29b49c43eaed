// prism_hit.wgsl — ray vs prism, the mirror of core/src/trace/prism_hit.rs: the hull
// [first entry, last exit] of the ray's inside set in a prism with planar caps and bilinear
// walls (Reshetov 2019 "Cool Patches"; the quadratic in the ruling parameter with an FMA
// difference of products). ±∞ of the CPU are ±T_FAR here.

// Barycentric / patch-parameter slack (prism_hit::PARAM_EPS).
const PARAM_EPS: f32 = 1e-5;
// prism_hit::PLANE_MIN_SINE: the base triangle's plane bounds the surface above this sine.
const PLANE_MIN_SINE: f32 = 1e-3;

// Inside interval of a ray in a prism, clipped to [t_min, t_max]; ok = false: missed.
struct Interval {
    ok: bool,
    t_enter: f32,
    t_exit: f32,
}

// a·b − c·d with one rounding error less (Kahan via FMA).
fn difference_of_products(a: f32, b: f32, c: f32, d: f32) -> f32 {
    let cd = c * d;
    let err = fma(-c, d, cd);
    let dop = fma(a, b, -cd);
    return dop + err;
}

// Real roots of a x² + b x + c (r0 <= r1), cancellation-free.
struct Roots {
    ok: bool,
    r0: f32,
    r1: f32,
}

fn copysign(mag: f32, sgn: f32) -> f32 {
    return select(abs(mag), -abs(mag), (bitcast<u32>(sgn) & 0x80000000u) != 0u);
}

fn quadratic(a: f32, b: f32, c: f32) -> Roots {
    if (a == 0.0) {
        if (b == 0.0) {
            return Roots(false, 0.0, 0.0);
        }
        let r = -c / b;
        return Roots(true, r, r);
    }
    let discrim = difference_of_products(b, b, 4.0 * a, c);
    if (discrim < 0.0) {
        return Roots(false, 0.0, 0.0);
    }
    let root = sqrt(discrim);
    let q = -0.5 * (b + copysign(root, b));
    var r0 = 0.0;
    var r1 = 0.0;
    if (q != 0.0) {
        r0 = q / a;
        r1 = c / q;
    }
    if (r0 <= r1) {
        return Roots(true, r0, r1);
    }
    return Roots(true, r1, r0);
}

// Running record of boundary crossings.
struct Crossings {
    first_entry: f32,
    last_entry: f32,
    first_exit: f32,
    last_exit: f32,
}

fn crossings_add(acc: ptr<function, Crossings>, t: f32, outward_dot_dir: f32) {
    if (outward_dot_dir < 0.0) {
        (*acc).first_entry = min((*acc).first_entry, t);
        (*acc).last_entry = max((*acc).last_entry, t);
    } else if (outward_dot_dir > 0.0) {
        (*acc).first_exit = min((*acc).first_exit, t);
        (*acc).last_exit = max((*acc).last_exit, t);
    }
    // Exactly tangent: touches without crossing.
}

// Ray vs triangle p with slack on the edges; orientation of sign·(p1−p0)×(p2−p0).
fn cap(o: vec3f, d: vec3f, t_min: f32, t_max: f32, p: array<vec3f, 3>, sign: f32, acc: ptr<function, Crossings>) {
    let e1 = p[1] - p[0];
    let e2 = p[2] - p[0];
    let pv = cross(d, e2);
    let det = dot(e1, pv);
    if (det == 0.0) {
        return;
    }
    let inv = 1.0 / det;
    let tv = o - p[0];
    let b1 = dot(tv, pv) * inv;
    if (!(b1 >= -PARAM_EPS && b1 <= 1.0 + PARAM_EPS)) {
        return;
    }
    let qv = cross(tv, e1);
    let b2 = dot(d, qv) * inv;
    if (b2 < -PARAM_EPS || b1 + b2 > 1.0 + PARAM_EPS) {
        return;
    }
    let t = dot(e2, qv) * inv;
    if (t >= t_min && t <= t_max) {
        crossings_add(acc, t, sign * dot(cross(e1, e2), d));
    }
}

// Ray vs the bilinear wall with bottom edge a→b and top edge c→e.
fn wall(o: vec3f, d: vec3f, t_min: f32, t_max: f32, a: vec3f, b: vec3f, c: vec3f, e: vec3f, acc: ptr<function, Crossings>) {
    let q0 = a - o;
    let q1 = b - o;
    let eb = b - a;
    let e0 = c - a;
    let e1 = e - b;
    let f0 = dot(cross(q0, d), e0);
    let f1 = dot(cross(q1, d), e1);
    let c2 = dot(d, cross(e1 - e0, eb));
    let c1 = f1 - f0 - c2;
    let roots = quadratic(c2, c1, f0);
    if (!roots.ok) {
        return;
    }
    for (var k = 0; k < 2; k++) {
        if (k == 1 && roots.r1 == roots.r0) {
            break;
        }
        let u = select(roots.r0, roots.r1, k == 1);
        if (!(u >= -PARAM_EPS && u <= 1.0 + PARAM_EPS)) {
            continue;
        }
        let q = q0 + eb * u;
        let ed = e0 + (e1 - e0) * u;
        let n = cross(d, ed);
        let n2 = dot(n, n);
        if (n2 == 0.0) {
            continue; // ray parallel to the ruling line
        }
        let s = dot(cross(q, d), n) / n2;
        if (!(s >= -PARAM_EPS && s <= 1.0 + PARAM_EPS)) {
            continue;
        }
        let t = dot(cross(q, ed), n) / n2;
        if (t >= t_min && t <= t_max) {
            let du = eb + ((e - c) - eb) * s;
            crossings_add(acc, t, dot(cross(du, ed), d));
        }
    }
}

// Where a ray leaves the box of the six corners. An axis with d = 0 bounds nothing if the
// origin lies in its slab and excludes everything otherwise (the CPU's ±∞).
fn box_exit(o: vec3f, d: vec3f, lo: array<vec3f, 3>, hi: array<vec3f, 3>) -> f32 {
    var mn = min(min(lo[0], lo[1]), min(lo[2], hi[0]));
    mn = min(mn, min(hi[1], hi[2]));
    var mx = max(max(lo[0], lo[1]), max(lo[2], hi[0]));
    mx = max(mx, max(hi[1], hi[2]));
    var far = T_FAR;
    for (var k = 0; k < 3; k++) {
        if (d[k] == 0.0) {
            if (o[k] < mn[k] || o[k] > mx[k]) {
                far = min(far, -T_FAR);
            }
            continue;
        }
        let inv = 1.0 / d[k];
        let t0 = (mn[k] - o[k]) * inv;
        let t1 = (mx[k] - o[k]) * inv;
        far = min(far, max(t0, t1));
    }
    return far;
}

// prism_hit::clip_to_surface_bounds: [t0, t1] cut to where the prism's surface can be, within
// `reach` of the base triangle v — its box grown by `reach` and the slab of that half-width
// around its plane (a (nearly) zero-area base has no plane: the box alone). An axis with d = 0
// keeps everything if the origin lies in its slab and nothing otherwise (the CPU's ±∞).
fn clip_to_surface_bounds(o: vec3f, d: vec3f, t0: f32, t1: f32, v: array<vec3f, 3>, reach: f32) -> Interval {
    let lo = min(min(v[0], v[1]), v[2]) - vec3f(reach);
    let hi = max(max(v[0], v[1]), v[2]) + vec3f(reach);
    var a = t0;
    var b = t1;
    for (var k = 0; k < 3; k++) {
        if (d[k] == 0.0) {
            if (o[k] < lo[k] || o[k] > hi[k]) {
                return Interval(false, 0.0, 0.0);
            }
            continue;
        }
        let inv = 1.0 / d[k];
        let ta = (lo[k] - o[k]) * inv;
        let tb = (hi[k] - o[k]) * inv;
        a = max(a, min(ta, tb));
        b = min(b, max(ta, tb));
    }
    let e1 = v[1] - v[0];
    let e2 = v[2] - v[0];
    let c = cross(e1, e2);
    // prism_hit::base_plane_normal: no plane where the corners are (nearly) collinear.
    let floor = PLANE_MIN_SINE * PLANE_MIN_SINE * dot(e1, e1) * dot(e2, e2);
    if (!(dot(c, c) > floor)) {
        return Interval(a <= b, a, b);
    }
    let ng = c / length(c);
    let s0 = dot(o - v[0], ng);
    let sd = dot(d, ng);
    if (sd == 0.0) {
        if (abs(s0) > reach) {
            return Interval(false, 0.0, 0.0);
        }
    } else {
        let ta = (-reach - s0) / sd;
        let tb = (reach - s0) / sd;
        a = max(a, min(ta, tb));
        b = min(b, max(ta, tb));
    }
    return Interval(a <= b, a, b);
}

// prism_hit::cap_planes_reject: true if [t_min, t_max] lies wholly outside one cap's plane,
// on the side away from the prism. A cap plane bounds the prism only if the other cap's
// corners are on its inner side (walls lie in the hull of their corners).
fn cap_plane_rejects(o: vec3f, d: vec3f, t_min: f32, t_max: f32, face: array<vec3f, 3>, other: array<vec3f, 3>, sign: f32, extent: f32) -> bool {
    let n = cross(face[1] - face[0], face[2] - face[0]) * sign;
    let tol = 1e-5 * length(n) * extent;
    if (dot(other[0] - face[0], n) > -tol || dot(other[1] - face[0], n) > -tol || dot(other[2] - face[0], n) > -tol) {
        return false;
    }
    let s0 = dot(o - face[0], n);
    let sd = dot(d, n);
    // t_max = T_FAR stands for +∞: with sd < 0 the ray comes back inside the plane.
    return s0 + t_min * sd > tol && (sd >= 0.0 || (t_max < T_FAR && s0 + t_max * sd > tol));
}

fn cap_planes_reject(o: vec3f, d: vec3f, t_min: f32, t_max: f32, lo: array<vec3f, 3>, hi: array<vec3f, 3>) -> bool {
    let extent = length(hi[0] - lo[0]) + length(lo[1] - lo[0]) + length(lo[2] - lo[0]);
    // Outward normals: counter-clockwise base, `hi` up, `lo` down (no loop: Mesa's lavapipe
    // counts every loop iteration of an invocation against one cap, docs/gpu.md).
    return cap_plane_rejects(o, d, t_min, t_max, hi, lo, 1.0, extent)
        || cap_plane_rejects(o, d, t_min, t_max, lo, hi, -1.0, extent);
}

// prism_hit::ray_prism_interval: crossings are gathered on the whole half-line [t_min, ∞)
// and clipped afterwards, so a ray that starts inside is recognised without a point test.
fn ray_prism_interval(o: vec3f, d: vec3f, t_min: f32, t_max: f32, lo: array<vec3f, 3>, hi: array<vec3f, 3>) -> Interval {
    if (cap_planes_reject(o, d, t_min, t_max, lo, hi)) {
        return Interval(false, 0.0, 0.0);
    }
    let far = T_FAR;
    var acc = Crossings(T_FAR, -T_FAR, T_FAR, -T_FAR);
    cap(o, d, t_min, far, lo, -1.0, &acc);
    cap(o, d, t_min, far, hi, 1.0, &acc);
    wall(o, d, t_min, far, lo[0], lo[1], hi[0], hi[1], &acc);
    wall(o, d, t_min, far, lo[1], lo[2], hi[1], hi[2], &acc);
    wall(o, d, t_min, far, lo[2], lo[0], hi[2], hi[0], &acc);
    if (!(acc.first_entry < T_FAR || acc.first_exit < T_FAR)) {
        // A bounded solid is always left again: no crossing on a half-line is a miss.
        return Interval(false, 0.0, 0.0);
    }
    // First crossing an exit (or no entry): the ray starts inside.
    var t_enter = acc.first_entry;
    if (acc.first_exit < acc.first_entry) {
        t_enter = t_min;
    }
    // Last crossing an entry (no exit after it): an exit was lost to rounding; bound it by
    // the corners' box.
    var t_exit = acc.last_exit;
    if (acc.last_entry > acc.last_exit) {
        t_exit = max(box_exit(o, d, lo, hi), acc.last_entry);
    }
    t_exit = min(t_exit, t_max);
    return Interval(t_enter <= t_exit, t_enter, t_exit);
}
