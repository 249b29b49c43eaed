// canonical.wgsl — the canonical displaced surface, the mirror of core/src/canonical.rs:
// S(b) = P(b) + D(uv(b)) m(b)/|m(b)|, m(b) = Σ b_i n_i, and its inverse `project_to_prism`
// (Newton on P(b) + λ m(b) − x, RMIP §4.1).

// canonical::PrismGeom: base data of one prism.
struct PrismGeom {
    v: array<vec3f, 3>,
    n: array<vec3f, 3>,
    uv: array<vec2f, 3>,
}

// PrismGeom::new (world coordinates).
fn prism_geom(p: Prism) -> PrismGeom {
    let a = vertices[p.tri[0]];
    let b = vertices[p.tri[1]];
    let c = vertices[p.tri[2]];
    return PrismGeom(
        array<vec3f, 3>(a.position, b.position, c.position),
        array<vec3f, 3>(a.normal, b.normal, c.normal),
        array<vec2f, 3>(vec2f(a.u, a.v), vec2f(b.u, b.v), vec2f(c.u, c.v)),
    );
}

fn geom_position(g: PrismGeom, b: vec3f) -> vec3f {
    return g.v[0] * b.x + g.v[1] * b.y + g.v[2] * b.z;
}

fn geom_normal_dir(g: PrismGeom, b: vec3f) -> vec3f {
    return g.n[0] * b.x + g.n[1] * b.y + g.n[2] * b.z;
}

fn geom_uv(g: PrismGeom, b: vec3f) -> vec2f {
    return g.uv[0] * b.x + g.uv[1] * b.y + g.uv[2] * b.z;
}

// Unit geometric normal of the base triangle.
fn geom_base_normal(g: PrismGeom) -> vec3f {
    return normalize_or_zero(cross(g.v[1] - g.v[0], g.v[2] - g.v[0]));
}

// canonical::SurfacePoint.
struct SurfacePoint {
    position: vec3f,
    uv: vec2f,
    displacement: f32,
    geometric_normal: vec3f,
    smooth_normal: vec3f,
    base_normal: vec3f,
}

// canonical::surface_point: S(b), its analytic normal and the paper's smoothed normal
// N's = Ns − Ng + N' (§5.1), the height from `disp` (the map, or the stitched height next to
// UV seams: seam.wgsl).
fn surface_point(g: PrismGeom, disp: PrismDisplacement, b: vec3f) -> SurfacePoint {
    let p = geom_position(g, b);
    let m = geom_normal_dir(g, b);
    let len = max(length(m), 1e-12);
    let mh = m / len;
    let uv = geom_uv(g, b);
    // Height and its derivatives with respect to (b1, b2), b0 = 1 − b1 − b2.
    let dg = displacement_at_grad(disp, b);
    let d = dg.value;
    let dp0 = g.v[1] - g.v[0];
    let dp1 = g.v[2] - g.v[0];
    let dm0 = g.n[1] - g.n[0];
    let dm1 = g.n[2] - g.n[0];
    let dmh0 = (dm0 - mh * dot(mh, dm0)) / len;
    let dmh1 = (dm1 - mh * dot(mh, dm1)) / len;
    let ds0 = dp0 + mh * dg.grad.x + dmh0 * d;
    let ds1 = dp1 + mh * dg.grad.y + dmh1 * d;
    let ng = geom_base_normal(g);
    var ns = normalize_or_zero(cross(ds0, ds1));
    if (all(ns == vec3f(0.0))) {
        ns = mh;
    }
    if (all(ns == vec3f(0.0))) {
        ns = ng;
    }
    if (all(ns == vec3f(0.0))) {
        // A zero-area base face whose corner normals cancel here: any unit normal.
        ns = vec3f(0.0, 0.0, 1.0);
    }
    if (dot(ns, mh) < 0.0 && dot(ns, ng) < 0.0) {
        ns = -ns;
    }
    // glam's try_normalize(...).unwrap_or(ns).
    let s = ns - ng + mh;
    let sl = length(s);
    var smooth_n = ns;
    if (sl > TINY_LEN) {
        smooth_n = s * (1.0 / sl);
    }
    var base = mh;
    if (all(mh == vec3f(0.0))) {
        base = ns;
    }
    return SurfacePoint(p + mh * d, uv, d, ns, smooth_n, base);
}

// canonical::project_to_prism: solve P(b) + λ m(b) = x for (b, λ) from a starting guess.
// `ok` false: no convergence (singular Jacobian or divergence). b is not clamped.
struct Projection {
    ok: bool,
    b: vec3f,
    lambda: f32,
}

fn project_to_prism(g: PrismGeom, x: vec3f, b_init: vec3f, lambda_init: f32) -> Projection {
    var b1 = b_init.y;
    var b2 = b_init.z;
    var lambda = lambda_init;
    let dp1 = g.v[1] - g.v[0];
    let dp2 = g.v[2] - g.v[0];
    let dm1 = g.n[1] - g.n[0];
    let dm2 = g.n[2] - g.n[0];
    let scale = max(length(dp1) + length(dp2), 1e-20);
    for (var i = 0; i < 16; i++) {
        let b = vec3f(1.0 - b1 - b2, b1, b2);
        let m = geom_normal_dir(g, b);
        let f = geom_position(g, b) + m * lambda - x;
        if (length(f) <= 1e-6 * scale) {
            return Projection(true, b, lambda);
        }
        let s = solve3(dp1 + dm1 * lambda, dp2 + dm2 * lambda, m, f);
        if (!s.ok) {
            return Projection(false, b, lambda);
        }
        b1 -= s.x.x;
        b2 -= s.x.y;
        lambda -= s.x.z;
        if (!(finite(b1) && finite(b2) && finite(lambda))) {
            return Projection(false, b, lambda);
        }
    }
    let b = vec3f(1.0 - b1 - b2, b1, b2);
    let f = geom_position(g, b) + geom_normal_dir(g, b) * lambda - x;
    return Projection(length(f) <= 1e-4 * scale, b, lambda);
}
