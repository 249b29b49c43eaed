// pdm.wgsl — projective displacement mapping (Hoetzlein 2025, Algorithm 1), the mirror of
// core/src/trace/pdm.rs function by function for the shared-wall construction: the ray's
// interval in the prism (prism_hit.wgsl), a march with step dt from the entry whose first
// step is jittered by R·dt (§5.3, the CPU's counter-based R), each sample on the exact
// canonical sign — its level λ by Newton on the level cubic (`level_cubic`, `level_at`,
// warm-started from the paper's scanning-triangle estimate), barycentrics in the level
// triangle T(λ) by Ericson's five dot products (App. C), g = λ|m(b)| − D(b) (stitched next to
// UV seams: seam.wgsl) — and the crossing refined by Illinois regula falsi on the same g
// (`refine_levels`; on the GPU these are states of `march_levels`, one sample per pass). Flat prisms meet the triangle V_i + D n_i and are moved onto the
// canonical surface by Newton (`flat_hit`; a flat prism's stitched height is its constant:
// the bake's range includes the stitch bands).
// pdm.rs documents each departure from the paper. The paper's parallel-offset prism
// (`march_scan`) is a CPU-only measurement mode and is not built here.

const EDGE_TOL: f32 = 1e-5;
const DETECT_TOL: f32 = 0.05;
// The entry sample on a wall may miss the triangle by this much before other levels are tried
// (pdm::ENTRY_TOL: a folded prism's ghost level).
const ENTRY_TOL: f32 = 1e-3;
// How far past the prism's λ range (relative to its longest edge) the entry's level may lie
// before other levels are tried (pdm::ENTRY_LEVEL_PAD: a ghost level can hold the point inside
// its triangle too).
const ENTRY_LEVEL_PAD: f32 = 1e-3;
const INTERVAL_PAD: f32 = 1e-4;
const MAX_STEPS: u32 = 16384u;
const REFINE_ITERS: u32 = 24u;
const LEVEL_ITERS: u32 = 8u;
const DOMAIN_EDGE_ITERS: u32 = 10u;
// Pdm::cross_boundary: secant steps at most, and the margin just outside the boundary it
// aims at.
const EDGE_ITERS: u32 = 6u;
const EDGE_SAMPLE: f32 = 0.01;
// march_levels' states.
const MODE_ENTRY: u32 = 0u;
const MODE_MARCH: u32 = 1u;
const MODE_EDGE: u32 = 2u;
const MODE_REFINE: u32 = 3u;
const MODE_BOUNDARY: u32 = 4u;
const MODE_DIP: u32 = 5u;
// Pdm's SECANT_MIN_STEP: the shortest step the secant cut leaves (a fraction of dt).
const SECANT_MIN_STEP: f32 = 0.125;
// Pdm's NEAR_SLOPE: near the surface a step is at most |g| / NEAR_SLOPE.
const NEAR_SLOPE: f32 = 0.3;
// Pdm::dip_probe: samples at most in one gap between march samples.
const DIP_PROBES: u32 = 4u;
const F32_MIN_POSITIVE: f32 = 1.17549435e-38;

// pdm::Local: one prism in a local frame (origin at V_0).
struct Local {
    origin: vec3f,
    // The prism's height: the map, or the stitched height next to UV seams.
    disp: PrismDisplacement,
    geom: PrismGeom,
    // Scanning directions n_i / (n_i·N_g).
    a: array<vec3f, 3>,
    ng: vec3f,
    // Longest base edge.
    scale: f32,
    // The corner the barycentrics are solved from (widest_corner).
    apex: u32,
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
    let uv = array<vec2f, 3>(vec2f(va.u, va.v), vec2f(vb.u, vb.v), vec2f(vc.u, vc.v));
    let geom = PrismGeom(array<vec3f, 3>(vec3f(0.0), v1, v2), n, uv);
    return Local(origin, prism_displacement(p, uv), geom, a, ng, scale, widest_corner(geom.v));
}

// The corner opposite the longest edge of triangle v (triangle_barycentric).
fn widest_corner(v: array<vec3f, 3>) -> u32 {
    let e0 = dot(v[2] - v[1], v[2] - v[1]);
    let e1 = dot(v[0] - v[2], v[0] - v[2]);
    let e2 = dot(v[1] - v[0], v[1] - v[0]);
    var best = 0u;
    var longest = e0;
    if (e1 > longest) {
        best = 1u;
        longest = e1;
    }
    if (e2 > longest) {
        best = 2u;
    }
    return best;
}

// Barycentrics of s in triangle c by five dot products (Ericson 2004; paper App. C), with the
// two edges taken from corner `apex`: from a sliver's sharp corner the Gram determinant
// cancels in f32 (the CPU's triangle_barycentric).
fn triangle_barycentric(s: vec3f, c: array<vec3f, 3>, apex: u32) -> vec3f {
    var ck = c[0];
    var ci = c[1];
    var cj = c[2];
    if (apex == 1u) {
        ck = c[1];
        ci = c[2];
        cj = c[0];
    } else if (apex == 2u) {
        ck = c[2];
        ci = c[0];
        cj = c[1];
    }
    let x0 = ci - ck;
    let x1 = cj - ck;
    let x2 = s - ck;
    let d00 = dot(x0, x0);
    let d01 = dot(x0, x1);
    let d11 = dot(x1, x1);
    let d20 = dot(x2, x0);
    let d21 = dot(x2, x1);
    let denom = d00 * d11 - d01 * d01;
    if (denom == 0.0) {
        // Degenerate scanning triangle (the zero-area prisms crease repair inserts): the CPU
        // gets NaN barycentrics, which no inside test accepts. GPU compilers may assume that
        // no NaN occurs, so say "outside" explicitly, with values that keep uv(b) finite.
        return vec3f(-1.0);
    }
    let inv = 1.0 / denom;
    let bi = (d11 * d20 - d01 * d21) * inv;
    let bj = (d00 * d21 - d01 * d20) * inv;
    let bk = 1.0 - bi - bj;
    if (apex == 1u) {
        return vec3f(bj, bk, bi);
    } else if (apex == 2u) {
        return vec3f(bi, bj, bk);
    }
    return vec3f(bk, bi, bj);
}

// A march sample (pdm::Sample; `ok` false stands for the CPU's None): ray parameter, the
// canonical height difference g (ray above the surface: g > 0), barycentrics, level λ.
struct Sample {
    ok: bool,
    t: f32,
    g: f32,
    b: vec3f,
    lambda: f32,
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
        r = march_levels(local, p, prism, ro, ray, ctx, steps);
    }
    if (!r.ok) {
        return no_hit();
    }
    return Hit(r.t, prism, r.b, vec2f(0.0), ray_at(ray, r.t), vec3f(0.0), vec3f(0.0), 0u);
}

// Pdm::fill_surface: uv, position and normals from the canonical surface.
fn fill_surface(hit: ptr<function, Hit>) {
    let p = prisms[(*hit).prism];
    let g = prism_geom(p);
    let sp = surface_point(g, prism_displacement(p, g.uv), (*hit).bary);
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

// Pdm::occluded: any hit (shadow rays), no surface data.
fn occluded(ray: Ray, ctx: RayContext) -> bool {
    return any_hit(ray, ctx);
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

// Pdm::jitter: the first step's jitter (paper §5.3), in [0, 1).
fn jitter(ctx: RayContext, prism: u32) -> f32 {
    if (frame.jitter != 0u) {
        return random(ctx.pixel, ctx.sample, ctx.bounce, PURPOSE_MARCH_JITTER, ctx.seed ^ prism);
    }
    return 0.0;
}

// pdm::LevelCubic: the level λ of a ray point solves f(λ, t) = (a0 + a1 t) + (b0 + b1 t) λ
// + (c0 + c1 t) λ² + d3 λ³ = 0 (the level sets of the shared-wall prism are the planar
// triangles T(λ) = {v_i + λ n_i}); `deflate`: zero-area base, solve f/λ instead.
struct LevelCubic {
    a0: f32,
    a1: f32,
    b0: f32,
    b1: f32,
    c0: f32,
    c1: f32,
    d3: f32,
    deflate: bool,
}

// pdm::level_cubic: the level cubic of prism g (local frame) along ro + t d; `lam` is the
// prism's largest |λ|.
fn level_cubic(g: PrismGeom, lam: f32, ro: vec3f, d: vec3f) -> LevelCubic {
    let e1 = g.v[1] - g.v[0];
    let e2 = g.v[2] - g.v[0];
    let d1 = g.n[1] - g.n[0];
    let d2 = g.n[2] - g.n[0];
    var n0 = cross(e1, e2);
    var n1 = cross(e1, d2) + cross(d1, e2);
    var n2 = cross(d1, d2);
    let l0 = length(n0);
    let l1 = length(n1) * lam;
    let l2 = length(n2) * lam * lam;
    let inv = 1.0 / max(l0 + l1 + l2, F32_MIN_POSITIVE);
    n0 *= inv;
    n1 *= inv;
    n2 *= inv;
    let deflate = l0 <= 1e-6 * (l0 + l1 + l2);
    let q = ro - g.v[0];
    return LevelCubic(
        dot(q, n0),
        dot(d, n0),
        dot(q, n1) - dot(g.n[0], n0),
        dot(d, n1),
        dot(q, n2) - dot(g.n[0], n1),
        dot(d, n2),
        -dot(g.n[0], n2),
        deflate,
    );
}

// The CPU's Option<f32> for a level.
struct Level {
    ok: bool,
    l: f32,
}

// pdm::level_at: Newton on the level cubic at t from `guess`; fails if it does not converge
// or leaves [lo, hi]. (df = 0 is tested explicitly: the CPU's non-finite step.)
fn level_at(c: LevelCubic, t: f32, guess: f32, tol: f32, lo: f32, hi: f32) -> Level {
    let a = c.a0 + c.a1 * t;
    let b = c.b0 + c.b1 * t;
    let q = c.c0 + c.c1 * t;
    var l = guess;
    var step = T_FAR;
    for (var i = 0u; i < LEVEL_ITERS; i++) {
        var f: f32;
        var df: f32;
        if (c.deflate) {
            f = b + l * (q + l * c.d3);
            df = q + l * 2.0 * c.d3;
        } else {
            f = a + l * (b + l * (q + l * c.d3));
            df = b + l * (2.0 * q + l * 3.0 * c.d3);
        }
        if (df == 0.0) {
            return Level(false, l);
        }
        step = f / df;
        if (!finite(step)) {
            return Level(false, l);
        }
        l -= step;
        if (!(l >= lo && l <= hi)) {
            return Level(false, l);
        }
        if (abs(step) <= tol) {
            return Level(true, l);
        }
    }
    // Rounding noise above `tol`: accept a small last step.
    return Level(abs(step) <= 1e3 * tol, l);
}

// Pdm::entry_sample's order of the entry's tries: a level in the prism's range (lo, hi) before
// one outside it, then the more inside b; true if `s` is not worse than `best` (the last of
// equals wins, as the CPU's max_by).
fn entry_not_worse(s: Sample, best: Sample, lo: f32, hi: f32) -> bool {
    if (!best.ok) {
        return true;
    }
    let s_in = s.lambda >= lo && s.lambda <= hi;
    let best_in = best.lambda >= lo && best.lambda <= hi;
    if (s_in != best_in) {
        return s_in;
    }
    return min_element(s.b) >= min_element(best.b);
}

// pdm::LevelTrack: the level cubic along the ray rebased at its entry point base = o + t0 d
// (its coefficients are then of the prism's size and rounding stays far below the Newton
// tolerance), the tolerance, and a padded λ range (a root outside it is another branch).
struct LevelTrack {
    cubic: LevelCubic,
    base: vec3f,
    t0: f32,
    tol: f32,
    lo: f32,
    hi: f32,
    mid: f32,
}

// LevelTrack::new.
fn level_track(local: Local, p: Prism, ro: vec3f, d: vec3f, t0: f32) -> LevelTrack {
    let span = 0.5 * (p.lambda_hi - p.lambda_lo) + 1e-3 * local.scale;
    let base = ro + d * t0;
    return LevelTrack(
        level_cubic(local.geom, max(abs(p.lambda_lo), abs(p.lambda_hi)), base, d),
        base,
        t0,
        1e-6 * local.scale,
        p.lambda_lo - span,
        p.lambda_hi + span,
        0.5 * (p.lambda_lo + p.lambda_hi),
    );
}

// Pdm::scan_level_estimate: the paper's scanning-triangle estimate of the level of x (only
// the starting guess of level_at).
fn scan_level_estimate(local: Local, x: vec3f) -> f32 {
    let h = dot(x, local.ng);
    let g = local.geom;
    let c = array<vec3f, 3>(g.v[0] + local.a[0] * h, g.v[1] + local.a[1] * h, g.v[2] + local.a[2] * h);
    let b = triangle_barycentric(x, c, local.apex);
    let mn = dot(geom_normal_dir(g, b), local.ng);
    if (mn > M_LO_FLOOR) {
        return h / mn;
    }
    return h;
}

// Pdm::level_sample: the exact canonical sample at t — level λ (Newton from `guess`, retried
// from the middle of the prism), barycentrics in T(λ), g = λ|m(b)| − D(b) (D* next to
// stitched seams).
fn level_sample(local: Local, lt: LevelTrack, d: vec3f, t: f32, guess: f32, given: Given) -> Sample {
    let g = local.geom;
    if (given.ok) {
        // The boundary machine's wall sample: its level and barycentrics are its own.
        let b = given.b;
        return Sample(true, t, given.l * length(geom_normal_dir(g, b)) - displacement_at(local.disp, b), b, given.l);
    }
    let u = t - lt.t0;
    // Newton from `guess`, then from the middle: one call site in a loop that a lane leaves
    // once it has a level (a lock-step implementation then runs the retry only for groups
    // that need it; see seam.wgsl's displacement_at).
    var lv = Level(false, guess);
    var start = guess;
    for (var k = 0u; k < 2u; k++) {
        lv = level_at(lt.cubic, u, start, lt.tol, lt.lo, lt.hi);
        if (lv.ok) {
            break;
        }
        start = lt.mid;
    }
    if (!lv.ok) {
        return Sample(false, t, 0.0, vec3f(0.0), 0.0);
    }
    let l = lv.l;
    let c = array<vec3f, 3>(g.v[0] + g.n[0] * l, g.v[1] + g.n[1] * l, g.v[2] + g.n[2] * l);
    let b = triangle_barycentric(lt.base + d * u, c, local.apex);
    return Sample(true, t, l * length(geom_normal_dir(g, b)) - displacement_at(local.disp, b), b, l);
}

// A sample asked for at a level and barycentrics of its own, not at a ray parameter (ok false:
// the usual sample at t).
struct Given {
    ok: bool,
    l: f32,
    b: vec3f,
}

// The boundary point of Pdm::wall_crossing: where the segment from `outside` to `inside`
// enters the triangle, in homogeneous barycentrics (inside_span: nearly affine along a short
// segment, where b has a pole), its ray parameter and level interpolated.
struct WallPoint {
    ok: bool,
    t: f32,
    l: f32,
    b: vec3f,
}

fn wall_point(local: Local, outside: Sample, inside: Sample) -> WallPoint {
    let none = WallPoint(false, 0.0, 0.0, vec3f(0.0));
    let s_in = level_area(local, inside.lambda);
    let h0 = outside.b * level_area(local, outside.lambda);
    let h1 = inside.b * s_in;
    if (!(finite3(h0) && finite3(h1)) || s_in == 0.0) {
        return none;
    }
    // The last wall crossed: the largest fraction at which a component that is outside at
    // `outside` (of the other sign than the area) reaches zero.
    let a = h0 * sign(s_in);
    let c = h1 * sign(s_in);
    var k = 3u;
    var f = 0.0;
    for (var i = 0u; i < 3u; i++) {
        if (a[i] < 0.0 && c[i] >= 0.0) {
            let fi = a[i] / (a[i] - c[i]);
            if (k == 3u || fi > f) {
                k = i;
                f = fi;
            }
        }
    }
    if (k == 3u) {
        return none;
    }
    let h = h0 + (h1 - h0) * f;
    let sum = h.x + h.y + h.z;
    if (sum == 0.0 || !finite(sum)) {
        return none;
    }
    var bw = h / sum;
    bw[k] = 0.0;
    if (min_element(bw) < -EDGE_TOL) {
        return none;
    }
    return WallPoint(true, outside.t + (inside.t - outside.t) * f, outside.lambda + (inside.lambda - outside.lambda) * f, bw);
}

fn inside_detect(b: vec3f) -> bool {
    return min_element(b) >= -DETECT_TOL;
}

fn no_sample() -> Sample {
    return Sample(false, 0.0, 0.0, vec3f(0.0), 0.0);
}

// Local::level_area: twice the signed area of the level triangle T(λ) along the sum of the
// corner directions (negative where T(λ) has flipped over, zero where it collapses).
fn level_area(local: Local, l: f32) -> f32 {
    let g = local.geom;
    let c0 = g.v[0] + g.n[0] * l;
    let c1 = g.v[1] + g.n[1] * l;
    let c2 = g.v[2] + g.n[2] * l;
    return dot(cross(c1 - c0, c2 - c0), g.n[0] + g.n[1] + g.n[2]);
}

// The CPU's Option<(f32, f32)> of a span of a segment.
struct Span {
    ok: bool,
    lo: f32,
    hi: f32,
}

// pdm::nonnegative_span: on the segment from h0 to h1, the part where every component is ≥ 0
// (as fractions of the segment).
fn nonnegative_span(h0: vec3f, h1: vec3f) -> Span {
    var lo = 0.0;
    var hi = 1.0;
    for (var k = 0; k < 3; k++) {
        let a = h0[k];
        let slope = h1[k] - a;
        if (slope == 0.0) {
            if (a < 0.0) {
                return Span(false, 0.0, 0.0);
            }
        } else if (slope > 0.0) {
            lo = max(lo, -a / slope);
        } else {
            hi = min(hi, -a / slope);
        }
    }
    return Span(lo < hi, lo, hi);
}

fn finite3(v: vec3f) -> bool {
    return finite(v.x) && finite(v.y) && finite(v.z);
}

// pdm::inside_span: the middle of the first part of the straight segment between two samples
// inside the triangle (a fraction of the segment; ok false: none), on the homogeneous
// barycentrics b·S(λ), which stay smooth where b has a pole (a crease strip's collapsing
// level triangle).
fn inside_span(local: Local, a: Sample, b: Sample) -> Span {
    var h0 = a.b * level_area(local, a.lambda);
    var h1 = b.b * level_area(local, b.lambda);
    if (!(finite3(h0) && finite3(h1) && any(h0 != vec3f(0.0)) && any(h1 != vec3f(0.0)))) {
        h0 = a.b;
        h1 = b.b;
    }
    let pos = nonnegative_span(h0, h1);
    let neg = nonnegative_span(-h0, -h1);
    var best = pos;
    if (neg.ok && (!pos.ok || neg.lo < pos.lo)) {
        best = neg;
    }
    let mid = 0.5 * (best.lo + best.hi);
    return Span(best.ok, mid, mid);
}

// The boundary search's work list: cross the boundary between two samples (Pdm::cross_boundary)
// or detect one sample (Pdm::detect).
const OP_CROSS: u32 = 1u;
const OP_DETECT: u32 = 2u;

// An operation's samples, by index: the segment's two ends and the inside sample.
const AT_PV: u32 = 0u;
const AT_CUR: u32 = 1u;
const AT_INSIDE: u32 = 2u;

// Why the boundary search detects a sample, and so what follows when it finds no hit: the next
// operation (an OP_DETECT, a cross step just outside the boundary, the cross's nearest
// sample), or the cross's next step (a cross step inside).
const DETECT_OP: u32 = 0u;
const DETECT_STEP: u32 = 1u;
const DETECT_STEP_OUTSIDE: u32 = 2u;
const DETECT_NEAREST: u32 = 3u;

// The boundary cases of Pdm::feed, run before the next sample with a level, `cur`, is
// detected, with the latest such sample `pv` (Pdm::feed's `last`). Where the segment from `pv`
// to `cur` crosses the triangle's boundary, cuts across a corner of the triangle with both
// ends outside, or passes through a sliver between an end just outside and one far outside,
// the inside part is sampled (Pdm::inside_sample) and the boundary crossed
// (Pdm::cross_boundary), detecting crossings of the surface on the way (Pdm::detect, with
// level_crossing and refine_levels), so that none between them is stepped over. The CPU's
// functions call one another; here they are the states of a machine (`Boundary`) that asks
// march_levels for one sample at a time: march_levels takes it on its own pass, with its one
// level_sample call site (MODE_BOUNDARY). Transcribed as calls, the kernel inlined ~28 copies
// of level_sample and lavapipe took 49 s to compile it; as a loop of its own, with one more
// copy, Mesa 22's lavapipe ran that loop, masked, after every march sample (rock frames 2×,
// sphere 3× slower there).
struct Boundary {
    pv: Sample,
    cur: Sample,
    // Pdm::inside_sample's sample.
    m: Sample,
    both_out: bool,
    leaving: bool,
    // feed's chain of or_else: at most cross, detect, cross; `oi` the next. Each is (kind, its
    // first sample, its second) with the samples as AT_* indices; three fields, not an array:
    // indexed by a variable, an array would keep the whole state in memory.
    op0: vec3<u32>,
    op1: vec3<u32>,
    op2: vec3<u32>,
    nops: u32,
    oi: u32,
    // Pdm::inside_sample still to take.
    inside_pending: bool,
    // Pdm::cross_boundary: the secant bracket, the direction, the nearest sample inside, the
    // steps taken, the step being detected.
    crossing: bool,
    c0: Sample,
    c1: Sample,
    c_leaving: bool,
    nearest: Sample,
    ci: u32,
    // Pdm::wall_crossing once the cross is over, entering: 0 not asked, 1 its wall sample
    // asked for (`wall`: where), 2 answered (`wall_hit`).
    wall_state: u32,
    wall: WallPoint,
    wall_hit: PrismHit,
    // Pdm::detect: the sample (with DETECT_STEP also the cross step), why, and its refinement (refine_levels' bracket; `rlin` the
    // one linear sample without refinement).
    detecting: bool,
    dx: Sample,
    why: u32,
    refining: bool,
    r0: Sample,
    r1: Sample,
    rg0: f32,
    rg1: f32,
    rside: i32,
    ri: u32,
    rlin: Sample,
    // The sample asked for: whether, where, Newton's start.
    need: bool,
    ts: f32,
    gs: f32,
}

// The sample an operation names (AT_*).
fn boundary_sample(q: Boundary, at: u32) -> Sample {
    if (at == AT_PV) {
        return q.pv;
    }
    if (at == AT_CUR) {
        return q.cur;
    }
    return q.m;
}

// min b_i of the end near the triangle (detectable, or the entering end when neither is).
fn boundary_near_min(q: Boundary) -> f32 {
    if (q.leaving) {
        return min_element(q.pv.b);
    }
    return min_element(q.cur.b);
}

// Start the machine for the segment from pv to cur (pv has a level; not both detectable).
fn boundary_begin(pv: Sample, cur: Sample) -> Boundary {
    var q: Boundary;
    q.pv = pv;
    q.cur = cur;
    let pv_in = inside_detect(pv.b);
    q.both_out = !pv_in && !inside_detect(cur.b);
    q.leaving = pv_in;
    q.nops = 0u;
    q.oi = 0u;
    q.inside_pending = q.both_out || boundary_near_min(q) < 0.0;
    if (!q.inside_pending) {
        q.op0 = vec3<u32>(OP_CROSS, AT_PV, AT_CUR);
        q.nops = 1u;
    }
    q.crossing = false;
    q.detecting = false;
    q.refining = false;
    q.need = false;
    q.wall_state = 0u;
    return q;
}

// Move the machine through the states that take no sample, up to the next sample it asks for
// (`need`, `ts`, `gs`) or its end (`need` false). Returns the hit if a detection found one.
fn boundary_settle(b: ptr<function, Boundary>, local: Local, ray: Ray, prev: ptr<function, Sample>, te: f32, tx: f32, n: ptr<function, u32>) -> PrismHit {
    var q = *b;
    var hit = no_prism_hit();
    let refine = frame.refine != 0u;
    let tol_g = 1e-6 * local.scale;
    q.need = false;
    loop {
        if (q.inside_pending) {
            let span = inside_span(local, q.pv, q.cur);
            if (span.ok) {
                q.ts = q.pv.t + (q.cur.t - q.pv.t) * span.lo;
                q.gs = 0.5 * (q.pv.lambda + q.cur.lambda);
                *n += 1u;
                q.need = true;
                break;
            }
            q.inside_pending = false;
            if (!q.both_out) {
                q.op0 = vec3<u32>(OP_CROSS, AT_PV, AT_CUR);
                q.nops = 1u;
            }
            continue;
        }
        if (q.detecting) {
            if (!q.refining) {
                let pvs = *prev;
                if (q.dx.ok && inside_detect(q.dx.b) && pvs.ok && ((pvs.g > 0.0) != (q.dx.g > 0.0))) {
                    q.r0 = pvs;
                    q.r1 = q.dx;
                    q.rg0 = pvs.g;
                    q.rg1 = q.dx.g;
                    q.rside = 0;
                    q.ri = 0u;
                    q.rlin = no_sample();
                    q.refining = true;
                    continue;
                }
            } else {
                if (!refine && q.ri == 0u) {
                    q.ts = q.r0.t + (q.r1.t - q.r0.t) * (q.r0.g / (q.r0.g - q.r1.g));
                    q.gs = lambda_between(q.r0, q.r1, q.ts);
                    q.need = true;
                    break;
                }
                if (refine && q.ri < REFINE_ITERS && !bracket_converged(q.r0, q.r1, tol_g, local.scale)) {
                    q.ts = (q.r0.t * q.rg1 - q.r1.t * q.rg0) / (q.rg1 - q.rg0);
                    q.gs = lambda_between(q.r0, q.r1, q.ts);
                    q.need = true;
                    break;
                }
                // The refinement is over: Pdm::level_crossing's test.
                var res = q.rlin;
                if (refine) {
                    res = refine_result(local, q.r0, q.r1, tol_g);
                }
                if (res.ok && min_element(res.b) >= -EDGE_TOL && res.t >= te && res.t <= tx && res.t >= ray.t_min && res.t <= ray.t_max) {
                    hit = PrismHit(true, res.t, res.b);
                    break;
                }
                q.refining = false;
            }
            // No hit: a detectable sample becomes the previous one.
            if (q.dx.ok && inside_detect(q.dx.b)) {
                *prev = q.dx;
            }
            q.detecting = false;
            if (q.why == DETECT_STEP) {
                // Pdm::cross_boundary goes on after the sample it detected.
                if (inside_detect(q.dx.b)) {
                    q.nearest = q.dx;
                }
                if ((min_element(q.dx.b) + EDGE_SAMPLE > 0.0) == (min_element(q.c0.b) + EDGE_SAMPLE > 0.0)) {
                    q.c0 = q.dx;
                } else {
                    q.c1 = q.dx;
                }
            } else {
                q.crossing = false;
                q.oi += 1u;
            }
            continue;
        }
        if (q.oi >= q.nops) {
            break;
        }
        var op = q.op2;
        if (q.oi == 0u) {
            op = q.op0;
        } else if (q.oi == 1u) {
            op = q.op1;
        }
        if (op.x == OP_DETECT) {
            q.dx = boundary_sample(q, op.y);
            q.why = DETECT_OP;
            q.detecting = true;
            continue;
        }
        if (!q.crossing) {
            q.c0 = boundary_sample(q, op.y);
            q.c1 = boundary_sample(q, op.z);
            q.c_leaving = inside_detect(q.c0.b);
            q.nearest = no_sample();
            q.ci = 0u;
            q.wall_state = 0u;
            q.crossing = true;
        }
        let f0 = min_element(q.c0.b) + EDGE_SAMPLE;
        let f1 = min_element(q.c1.b) + EDGE_SAMPLE;
        if (q.ci < EDGE_ITERS && (f0 > 0.0) != (f1 > 0.0)) {
            q.ts = q.c0.t + (q.c1.t - q.c0.t) * (f0 / (f0 - f1));
            q.gs = lambda_between(q.c0, q.c1, q.ts);
            q.ci += 1u;
            *n += 1u;
            q.need = true;
            break;
        }
        // The cross is over: entering, the crossing between the wall and its nearest sample
        // inside (Pdm::wall_crossing, from the wall's own sample), else that sample is
        // detected.
        if (q.nearest.ok && !q.c_leaving) {
            if (q.wall_state == 0u) {
                q.wall_state = 2u;
                q.wall_hit = no_prism_hit();
                q.wall = wall_point(local, q.c0, q.nearest);
                if (q.wall.ok) {
                    q.wall_state = 1u;
                    q.ts = q.wall.t;
                    q.gs = q.wall.l;
                    q.need = true;
                    break;
                }
            }
            let w = q.wall_hit;
            if (w.ok && min_element(w.b) >= -EDGE_TOL && w.t >= max(te, ray.t_min) && w.t <= min(tx, ray.t_max)) {
                hit = w;
                break;
            }
            q.dx = q.nearest;
            q.nearest = no_sample();
            q.why = DETECT_NEAREST;
            q.detecting = true;
            continue;
        }
        q.crossing = false;
        q.oi += 1u;
    }
    *b = q;
    return hit;
}

// Take the sample the machine asked for.
fn boundary_consume(b: ptr<function, Boundary>, s: Sample) {
    var q = *b;
    if (q.wall_state == 1u) {
        // The wall's sample: a sign other than the nearest sample's is a crossing between.
        q.wall_state = 2u;
        let i = q.nearest;
        if (s.ok && finite(s.g) && s.g != 0.0 && (s.g > 0.0) != (i.g > 0.0)) {
            let w = i.g / (i.g - s.g);
            q.wall_hit = PrismHit(true, i.t + (q.wall.t - i.t) * w, i.b + (q.wall.b - i.b) * w);
        }
    } else if (q.inside_pending) {
        // Pdm::inside_sample's sample: the work list of feed's case.
        q.inside_pending = false;
        q.m = s;
        let m_ok = s.ok && inside_detect(s.b);
        if (q.both_out) {
            if (m_ok) {
                q.op0 = vec3<u32>(OP_CROSS, AT_PV, AT_INSIDE);
                q.op1 = vec3<u32>(OP_DETECT, AT_INSIDE, AT_INSIDE);
                q.op2 = vec3<u32>(OP_CROSS, AT_INSIDE, AT_CUR);
                q.nops = 3u;
            }
        } else if (m_ok && min_element(s.b) > boundary_near_min(q)) {
            if (q.leaving) {
                q.op0 = vec3<u32>(OP_DETECT, AT_INSIDE, AT_INSIDE);
                q.op1 = vec3<u32>(OP_CROSS, AT_INSIDE, AT_CUR);
            } else {
                q.op0 = vec3<u32>(OP_CROSS, AT_PV, AT_INSIDE);
                q.op1 = vec3<u32>(OP_DETECT, AT_INSIDE, AT_INSIDE);
            }
            q.nops = 2u;
        } else {
            q.op0 = vec3<u32>(OP_CROSS, AT_PV, AT_CUR);
            q.nops = 1u;
        }
    } else if (q.refining) {
        // refine_levels' Illinois step, or level_crossing's one linear sample.
        if (frame.refine == 0u) {
            q.rlin = s;
            q.ri = 1u;
        } else if (!s.ok) {
            q.ri = REFINE_ITERS;
        } else {
            if ((s.g > 0.0) == (q.r1.g > 0.0)) {
                q.r1 = s;
                q.rg1 = s.g;
                if (q.rside == -1) {
                    q.rg0 *= 0.5;
                }
                q.rside = -1;
            } else {
                q.r0 = s;
                q.rg0 = s.g;
                if (q.rside == 1) {
                    q.rg1 *= 0.5;
                }
                q.rside = 1;
            }
            q.ri += 1u;
        }
    } else if (!s.ok) {
        // A step of Pdm::cross_boundary without a level ends its steps.
        q.ci = EDGE_ITERS;
    } else {
        let m = min_element(s.b);
        let just_outside = m >= -DETECT_TOL && m < 0.0;
        if ((q.c_leaving && inside_detect(s.b)) || just_outside) {
            q.dx = s;
            q.why = select(DETECT_STEP, DETECT_STEP_OUTSIDE, just_outside);
            q.detecting = true;
        } else {
            if (inside_detect(s.b)) {
                q.nearest = s;
            }
            if ((m + EDGE_SAMPLE > 0.0) == (min_element(q.c0.b) + EDGE_SAMPLE > 0.0)) {
                q.c0 = s;
            } else {
                q.c1 = s;
            }
        }
    }
    *b = q;
}

// Pdm::march_levels: PDM in the shared-wall prism on the exact canonical sign.
fn march_levels(local: Local, p: Prism, prism: u32, ro: vec3f, ray: Ray, ctx: RayContext, steps: ptr<function, u32>) -> PrismHit {
    let d = ray.dir;
    let g = local.geom;
    let lo = array<vec3f, 3>(g.v[0] + g.n[0] * p.lambda_lo, g.v[1] + g.n[1] * p.lambda_lo, g.v[2] + g.n[2] * p.lambda_lo);
    let hi = array<vec3f, 3>(g.v[0] + g.n[0] * p.lambda_hi, g.v[1] + g.n[1] * p.lambda_hi, g.v[2] + g.n[2] * p.lambda_hi);
    let pad = INTERVAL_PAD * local.scale;
    // Cut to the surface bounds first, then the walls on the cut segment only.
    let cl = clip_to_surface_bounds(ro, d, ray.t_min, ray.t_max, g.v, max(abs(p.d_min), abs(p.d_max)) + pad);
    if (!cl.ok) {
        return no_prism_hit();
    }
    let iv = ray_prism_interval(ro, d, cl.t_enter, cl.t_exit, lo, hi);
    if (!iv.ok) {
        return no_prism_hit();
    }
    let te = max(iv.t_enter - pad, cl.t_enter);
    let tx = min(iv.t_exit + pad, cl.t_exit);
    let dt = max(step_size(p, local), (tx - te) / f32(MAX_STEPS));
    let lt = level_track(local, p, ro, d, te);

    var guess = scan_level_estimate(local, ro + d * te);
    var prev = Sample(false, 0.0, 0.0, vec3f(0.0), 0.0);
    // The latest sample with a level fed to the crossing test, domain edges included
    // (the boundary search, Boundary).
    var last = Sample(false, 0.0, 0.0, vec3f(0.0), 0.0);
    // The last sample with a level; whether (and where, last) a sample had none since then.
    var last_ok = Sample(false, 0.0, 0.0, vec3f(0.0), 0.0);
    var failed = false;
    var failed_at = 0.0;
    // The last two loop samples while each had a level (the next guess, as on the CPU).
    var trail0 = Sample(false, 0.0, 0.0, vec3f(0.0), 0.0);
    var trail1 = Sample(false, 0.0, 0.0, vec3f(0.0), 0.0);
    let r = jitter(ctx, prism);
    var t = te;
    var n = 1u;
    // One loop that takes one level_sample per pass, whatever the sample is for: the entry
    // sample's tries (Pdm::entry_sample), the next march sample, a bisection step towards the
    // edge of the region where a level exists (level_domain_edge), or a refinement step of a
    // crossing (refine_levels); the CPU's functions as the states of one machine, in its
    // order. An implementation that runs invocations in lock-step under masks (lavapipe's
    // SIMD lanes: every `if` body runs there, masked, whether any lane takes it or not, and a
    // loop at least once) then runs one sample per pass for all lanes, whatever state each
    // lane is in, instead of every kind of sample's code for each march sample; a GPU's warp
    // keeps its lanes on the same instructions.
    var mode = MODE_ENTRY;
    var sample = Sample(false, 0.0, 0.0, vec3f(0.0), 0.0);
    // The entry sample: which try, the first try and the best retry.
    var ek = 0u;
    var first = Sample(false, 0.0, 0.0, vec3f(0.0), 0.0);
    var ebest = Sample(false, 0.0, 0.0, vec3f(0.0), 0.0);
    let quarter = 0.25 * (lt.hi - lt.lo);
    // The levels an entry on the exact interval (the prism's boundary) can have.
    let entry_lo = p.lambda_lo - ENTRY_LEVEL_PAD * local.scale;
    let entry_hi = p.lambda_hi + ENTRY_LEVEL_PAD * local.scale;
    // The level domain's edge: the bisection's ends and steps, and the edge sample found.
    var good = sample;
    var bad = 0.0;
    var ei = 0u;
    var edge = sample;
    // Feeding the edge (0) then the main sample (1) to the crossing test: the next to feed.
    var feed_k = 0u;
    // The crossing's Illinois bracket.
    var s0 = sample;
    var s1 = sample;
    var g0 = 0.0;
    var g1 = 0.0;
    var side = 0;
    var ri = 0u;
    // The boundary search of the item being fed (Boundary), and whether it is over.
    var bnd: Boundary;
    var bnd_done = false;
    // Pdm::dip_probe: the three loop samples near the triangle before the current one
    // (oldest first; of the oldest only (t, g)) and how many came in a row. While a gap is
    // probed they hold it: between dip1 and dip2, the lines through dip0, dip1 and dip2, ds
    // (the march's current sample's (t, g) at first); then where its lines meet, the probes
    // taken, and whether the march's current sample has had its dip test.
    var dip0 = vec2f(0.0);
    var dip1 = sample;
    var dip2 = sample;
    var dip_count = 0u;
    var ds = vec2f(0.0);
    var dip_at = DipApex(false, 0.0, 0.0);
    var dip_k = 0u;
    var dip_tested = false;
    let refine = frame.refine != 0u;
    let tol_g = 1e-6 * local.scale;
    loop {
        // The sample this pass takes.
        var ts = t;
        var gs = guess;
        var given = Given(false, 0.0, vec3f(0.0));
        if (mode == MODE_ENTRY) {
            if (ek == 1u) {
                gs = lt.mid;
            } else if (ek == 2u) {
                gs = lt.mid - quarter;
            } else if (ek == 3u) {
                gs = lt.mid + quarter;
            }
        } else if (mode == MODE_EDGE) {
            ts = 0.5 * (good.t + bad);
            gs = good.lambda;
        } else if (mode == MODE_BOUNDARY) {
            ts = bnd.ts;
            gs = bnd.gs;
            given = Given(bnd.wall_state == 1u, bnd.wall.l, bnd.wall.b);
        } else if (mode == MODE_DIP) {
            ts = dip_at.t;
            gs = lambda_between(dip1, dip2, ts);
        } else if (mode == MODE_REFINE) {
            ts = (s0.t * g1 - s1.t * g0) / (g1 - g0);
            if (!refine) {
                ts = s0.t + (s1.t - s0.t) * (s0.g / (s0.g - s1.g));
            }
            gs = lambda_between(s0, s1, ts);
        }
        let s = level_sample(local, lt, d, ts, gs, given);

        // What it is for. `fresh`: a new main sample to feed; `feeding`: go on feeding.
        var fresh = false;
        var feeding = false;
        // A sign change between these two starts a refinement (Pdm::level_crossing).
        var bracketed = false;
        var lo_end = s;
        var hi_end = s;
        if (mode == MODE_ENTRY) {
            // The first try if it is inside and in the range, else the retries' best and then
            // the first try (the last of equals, as the CPU's max_by over [mid, mid - q,
            // mid + q, first]).
            if (ek == 0u) {
                first = s;
                fresh = s.ok && min_element(s.b) >= -ENTRY_TOL && s.lambda >= entry_lo && s.lambda <= entry_hi;
                sample = s;
            } else if (s.ok && entry_not_worse(s, ebest, entry_lo, entry_hi)) {
                ebest = s;
            }
            ek += 1u;
            if (!fresh && ek == 4u) {
                if (first.ok && entry_not_worse(first, ebest, entry_lo, entry_hi)) {
                    ebest = first;
                }
                sample = ebest;
                fresh = true;
            }
        } else if (mode == MODE_MARCH) {
            sample = s;
            fresh = true;
        } else if (mode == MODE_EDGE) {
            n += 1u;
            if (s.ok) {
                good = s;
            } else {
                bad = ts;
            }
            ei += 1u;
            if (ei == DOMAIN_EDGE_ITERS) {
                edge = good;
                feed_k = 0u;
                feeding = true;
            }
        } else if (mode == MODE_BOUNDARY) {
            // A sample of the boundary search; when it is over, the item it ran for is fed on.
            boundary_consume(&bnd, s);
            let crossed = boundary_settle(&bnd, local, ray, &prev, te, tx, &n);
            if (crossed.ok) {
                *steps += n;
                return crossed;
            }
            if (!bnd.need) {
                bnd_done = true;
                feeding = true;
            }
        } else if (mode == MODE_DIP) {
            // A probe of the gap (Pdm::dip_probe): on the other side, the crossing after dip1
            // (Pdm::level_crossing: the refinement below); on this side, on in the half whose
            // lines dip lower; else the march goes on.
            n += 1u;
            dip_k += 1u;
            let above = dip1.g > 0.0;
            var go_on = !(s.ok && inside_detect(s.b));
            if (!go_on && (s.g > 0.0) != above) {
                bracketed = true;
                lo_end = dip1;
                // Nothing left to feed if the crossing is not this prism's.
                feed_k = 2u;
            } else if (!go_on) {
                let al = dip_apex(dip0, tg(dip1), tg(s), tg(dip2));
                let ar = dip_apex(tg(dip1), tg(s), tg(dip2), ds);
                if (ar.ok && (!al.ok || ar.v < al.v)) {
                    dip0 = tg(dip1);
                    dip1 = s;
                    dip_at = ar;
                } else {
                    ds = tg(dip2);
                    dip2 = s;
                    dip_at = al;
                }
                go_on = !dip_at.ok || dip_k == DIP_PROBES;
            }
            if (go_on) {
                feed_k = 2u;
                feeding = true;
                mode = MODE_MARCH;
            }
        } else if (mode == MODE_REFINE) {
            // Illinois (refine_levels), or the one linear sample without `refine`.
            var done = !refine || !s.ok || bracket_converged(s0, s1, tol_g, local.scale);
            var res = s;
            if (refine && !done) {
                if ((s.g > 0.0) == (s1.g > 0.0)) {
                    s1 = s;
                    g1 = s.g;
                    if (side == -1) {
                        g0 *= 0.5;
                    }
                    side = -1;
                } else {
                    s0 = s;
                    g0 = s.g;
                    if (side == 1) {
                        g1 *= 0.5;
                    }
                    side = 1;
                }
                ri += 1u;
                done = ri == REFINE_ITERS || bracket_converged(s0, s1, tol_g, local.scale);
            }
            if (done) {
                if (refine) {
                    res = refine_result(local, s0, s1, tol_g);
                }
                // Pdm::level_crossing's test: a hit in this triangle and span.
                if (res.ok && min_element(res.b) >= -EDGE_TOL && res.t >= te && res.t <= tx && res.t >= ray.t_min && res.t <= ray.t_max) {
                    *steps += n;
                    return PrismHit(true, res.t, res.b);
                }
                feeding = true;
            }
        }
        if (fresh) {
            // The edge of the region where a level exists is a sample too.
            edge = Sample(false, 0.0, 0.0, vec3f(0.0), 0.0);
            let leaving = !sample.ok && last_ok.ok && !failed;
            if (leaving || (sample.ok && failed)) {
                good = sample;
                bad = failed_at;
                if (leaving) {
                    good = last_ok;
                    bad = t;
                }
                ei = 0u;
                mode = MODE_EDGE;
            } else {
                feed_k = 0u;
                feeding = true;
            }
        }
        if (feeding) {
            // The edge, then the main sample: the first sign change from `prev` starts a
            // refinement; past both, the next march sample.
            var found = false;
            var searching = false;
            var below = prev;
            var cur = sample;
            loop {
                if (feed_k >= 2u) {
                    break;
                }
                cur = sample;
                if (feed_k == 0u) {
                    cur = edge;
                }
                if (!cur.ok) {
                    feed_k += 1u;
                    continue;
                }
                if (!bnd_done) {
                    // Pdm::feed: the boundary cases between the latest sample and this one
                    // first (Boundary), on passes of their own if they need samples.
                    guess = cur.lambda;
                    let pv = last;
                    last = cur;
                    if (pv.ok && !(inside_detect(pv.b) && inside_detect(cur.b))) {
                        bnd = boundary_begin(pv, cur);
                        let crossed = boundary_settle(&bnd, local, ray, &prev, te, tx, &n);
                        if (crossed.ok) {
                            *steps += n;
                            return crossed;
                        }
                        if (bnd.need) {
                            searching = true;
                            break;
                        }
                    }
                }
                bnd_done = false;
                feed_k += 1u;
                if (inside_detect(cur.b)) {
                    below = prev;
                    prev = cur;
                    if (below.ok && ((below.g > 0.0) != (cur.g > 0.0))) {
                        found = true;
                        break;
                    }
                }
            }
            if (searching) {
                mode = MODE_BOUNDARY;
            } else if (found) {
                bracketed = true;
                lo_end = below;
                hi_end = cur;
            } else {
                if (sample.ok) {
                    last_ok = sample;
                    failed = false;
                    trail0 = trail1;
                    trail1 = sample;
                } else {
                    failed = true;
                    failed_at = t;
                    trail0.ok = false;
                    trail1.ok = false;
                }
                // Pdm::dip_probe, once per march sample: four in a row near the triangle, on
                // one side, falling into the middle gap and rising out of it.
                if (!dip_tested) {
                    dip_tested = true;
                    if (sample.ok && inside_detect(sample.b)) {
                        dip_count += 1u;
                        if (dip_count >= 4u && may_dip(dip0.y, dip1.g, dip2.g, sample.g)) {
                            dip_at = dip_apex(dip0, tg(dip1), tg(dip2), tg(sample));
                            if (dip_at.ok) {
                                ds = tg(sample);
                                dip_k = 0u;
                                mode = MODE_DIP;
                            }
                        }
                        if (mode == MODE_DIP) {
                            // The ring holds the gap now; it starts again after the probe.
                            dip_count = 0u;
                        } else {
                            dip0 = tg(dip1);
                            dip1 = dip2;
                            dip2 = sample;
                        }
                    } else {
                        dip_count = 0u;
                    }
                }
                if (mode != MODE_DIP) {
                    if (t >= tx || n >= MAX_STEPS) {
                        break;
                    }
                    t = next_march_t(t, n, r, dt, tx, trail0, trail1);
                    guess = extrapolated_level(trail0, trail1, t, guess);
                    n += 1u;
                    dip_tested = false;
                    mode = MODE_MARCH;
                }
            }
        }
        if (bracketed) {
            s0 = lo_end;
            s1 = hi_end;
            g0 = lo_end.g;
            g1 = hi_end.g;
            side = 0;
            ri = 0u;
            mode = MODE_REFINE;
        }
    }
    *steps += n;
    return no_prism_hit();
}

// Pdm::dip_probe's cheap test on four samples' g (Pdm::may_dip).
fn may_dip(a: f32, b: f32, c: f32, d: f32) -> bool {
    let above = b > 0.0;
    return (a > 0.0) == above && (c > 0.0) == above && (d > 0.0) == above && abs(b) < abs(a) && abs(d) > abs(c);
}

// Where the line through p, q (falling to q) meets the line through r, s (rising from r)
// between q and r, if it lies on the other side of the surface (dip_probe's `apex`): the
// ray parameter and the lines' value there (signed towards q's side).
struct DipApex {
    ok: bool,
    t: f32,
    v: f32,
}

// p, q, r, s: the samples' (t, g).
fn dip_apex(p: vec2f, q: vec2f, r: vec2f, s: vec2f) -> DipApex {
    let side = select(-1.0, 1.0, q.y > 0.0);
    let kl = side * (q.y - p.y) / (q.x - p.x);
    let kr = side * (s.y - r.y) / (s.x - r.x);
    if (!(kl < 0.0 && kr > 0.0 && finite(kl) && finite(kr))) {
        return DipApex(false, 0.0, 0.0);
    }
    let t = (side * (r.y - q.y) + kl * q.x - kr * r.x) / (kl - kr);
    let v = side * q.y + kl * (t - q.x);
    return DipApex(t > q.x && t < r.x && v < 0.0, t, v);
}

// A sample's (t, g): all dip_apex needs of it.
fn tg(s: Sample) -> vec2f {
    return vec2f(s.t, s.g);
}

// refine_levels' result: the end nearer the surface, or, where the bracket shrank to f32's
// resolution of t with both ends far from the surface (a crease strip's sliver at its pole,
// where b jumps across the triangle from one float to the next), the crossing between the
// two floats (Pdm::between_floats).
fn refine_result(local: Local, s0: Sample, s1: Sample, tol_g: f32) -> Sample {
    let tol_t = 1e-7 * (abs(s0.t) + abs(s1.t) + local.scale);
    if (min(abs(s0.g), abs(s1.g)) > tol_g && abs(s1.t - s0.t) <= tol_t) {
        return between_floats(local, s0, s1);
    }
    if (abs(s0.g) <= abs(s1.g)) {
        return s0;
    }
    return s1;
}

// Pdm::between_floats: t, the level and the homogeneous barycentrics (inside_span)
// interpolated by g between two samples on either side of the surface.
fn between_floats(local: Local, a: Sample, b: Sample) -> Sample {
    let w = a.g / (a.g - b.g);
    let h0 = a.b * level_area(local, a.lambda);
    let h1 = b.b * level_area(local, b.lambda);
    let h = h0 + (h1 - h0) * w;
    let sum = h.x + h.y + h.z;
    var bw = a.b + (b.b - a.b) * w;
    if (sum != 0.0 && finite3(h) && finite(sum)) {
        bw = h / sum;
    }
    return Sample(true, a.t + (b.t - a.t) * w, 0.0, bw, a.lambda + (b.lambda - a.lambda) * w);
}

// refine_levels' stopping test: an end on the surface (|g| ≤ tol_g) or the bracket shrunk to
// rounding.
fn bracket_converged(s0: Sample, s1: Sample, tol_g: f32, scale: f32) -> bool {
    let tol_t = 1e-7 * (abs(s0.t) + abs(s1.t) + scale);
    return abs(s0.g) <= tol_g || abs(s1.g) <= tol_g || abs(s1.t - s0.t) <= tol_t;
}

// The next march sample's t: a step (the first one jittered), cut to where the line through
// the last two loop samples `a`, `b` meets the surface when they approach it on one side
// (Pdm::approaching), at least SECANT_MIN_STEP of a step on.
fn next_march_t(t: f32, n: u32, r: f32, dt: f32, tx: f32, a: Sample, b: Sample) -> f32 {
    var t_next = t + dt;
    if (n == 1u && r > 0.0) {
        t_next = t + r * dt;
    }
    if (a.ok && b.ok && b.t == t && approaching(a, b)) {
        let t_star = b.t - b.g * ((b.t - a.t) / (b.g - a.g));
        if (t_star < t_next) {
            t_next = max(t_star, t + SECANT_MIN_STEP * dt);
        }
    }
    // Near the surface a step is at most |g| / NEAR_SLOPE (the CPU's march_levels).
    let near = abs(b.g) / NEAR_SLOPE;
    if (b.ok && b.t == t && near < t_next - t && inside_detect(b.b)) {
        t_next = t + max(near, SECANT_MIN_STEP * dt);
    }
    return min(t_next, tx);
}

// Pdm::approaching: two successive loop samples near the triangle, on one side, g shrinking
// towards the surface.
fn approaching(a: Sample, b: Sample) -> bool {
    return inside_detect(a.b) && inside_detect(b.b) && ((a.g > 0.0) == (b.g > 0.0))
        && abs(b.g) < abs(a.g) && b.t > a.t;
}

// Newton's start at t from the last two samples' line (the level is smooth along the ray),
// else `guess`.
fn extrapolated_level(a: Sample, b: Sample, t: f32, guess: f32) -> f32 {
    if (a.ok && b.ok && b.t > a.t) {
        return b.lambda + (b.lambda - a.lambda) * ((t - b.t) / (b.t - a.t));
    }
    return guess;
}

// trace::pdm::lambda_between: the level at t interpolated between two samples (Newton's start).
fn lambda_between(a: Sample, b: Sample, t: f32) -> f32 {
    var w = 0.5;
    if (b.t != a.t) {
        w = clamp((t - a.t) / (b.t - a.t), 0.0, 1.0);
    }
    return a.lambda + (b.lambda - a.lambda) * w;
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
