// seam.wgsl — the stitched displaced surface next to UV seams, the mirror of core/src/seam/mod.rs
// (its module doc is the construction). A prism with stitched edges (`Prism::stitch` indexes
// `stitches`) has the height
//     D*(b) = D_A(b) + ½ Σ_k W_k(b) (D_k(b) − D_A(b)),
//     W_k(b) = S(1 − b_k/β_k) · Π_{j≠k} S(b_j / (b_j + b_k)),   S(x) = x²(3 − 2x) on [0, 1],
// D_A its own D(uv(b)), D_k the neighbour's chart across edge k continued into it. Every other
// prism (all of them under `--seams open`) has D(uv(b)) and takes no other load.
//
// Departure from a literal transcription: the CPU's loops over the three edges (and over the
// two other edges in `band_weight`) are three (two) calls, as `cap_planes_reject` is: every
// loop iteration counts against lavapipe's cap (docs/gpu.md), and these run per march sample.

// seam::PrismDisplacement: how every method evaluates one prism's height — its own UVs and
// its stitch record (the map and the displacement parameters are the scene's).
struct PrismDisplacement {
    uv: array<vec2f, 3>,
    stitch: u32,
}

// Surface::prism_displacement, from the prism record and its corners' UVs.
fn prism_displacement(p: Prism, uv: array<vec2f, 3>) -> PrismDisplacement {
    return PrismDisplacement(uv, p.stitch);
}

// seam::uv_at: the UV of barycentrics b in a chart.
fn uv_at(uv: array<vec2f, 3>, b: vec3f) -> vec2f {
    return uv[0] * b.x + uv[1] * b.y + uv[2] * b.z;
}

// seam::smooth (`smooth` is a WGSL reserved word): S(x) = x²(3 − 2x) clamped to [0, 1], and
// its derivative.
struct Smooth {
    s: f32,
    ds: f32,
}

fn smooth_step(x: f32) -> Smooth {
    if (x <= 0.0) {
        return Smooth(0.0, 0.0);
    }
    if (x >= 1.0) {
        return Smooth(1.0, 0.0);
    }
    return Smooth(x * x * (3.0 - 2.0 * x), 6.0 * x * (1.0 - x));
}

// One of band_weight's two other-edge factors, S(b_j / (b_j + b_k)) — 1 on edge k, 0 on edge
// j — and its derivatives with respect to b_j and b_k (the body of the CPU's inner loop).
struct EdgeFactor {
    s: f32,
    dj: f32,
    dk: f32,
}

fn edge_factor(b_j: f32, b_k: f32) -> EdgeFactor {
    let bj = max(b_j, 0.0);
    let bk = max(b_k, 0.0);
    let sum = bj + bk;
    if (sum <= 0.0) {
        // At the vertex itself (measure zero): 1.
        return EdgeFactor(1.0, 0.0, 0.0);
    }
    let sm = smooth_step(bj / sum);
    var dj = 0.0;
    var dk = 0.0;
    if (sm.ds != 0.0) {
        if (b_j > 0.0) {
            dj = sm.ds * bk / (sum * sum);
        }
        if (b_k > 0.0) {
            dk = -sm.ds * bj / (sum * sum);
        }
    }
    return EdgeFactor(sm.s, dj, dk);
}

// The unit vector along barycentric k.
fn unit3(k: u32) -> vec3f {
    return vec3f(select(0.0, 1.0, k == 0u), select(0.0, 1.0, k == 1u), select(0.0, 1.0, k == 2u));
}

// seam::band_weight: W_k(b) and its derivatives with respect to b_0, b_1, b_2 taken as
// independent.
struct BandWeight {
    w: f32,
    grad: vec3f,
}

fn band_weight(b: vec3f, k: u32, band: f32) -> BandWeight {
    let sm = smooth_step(1.0 - b[k] / band);
    if (sm.s == 0.0) {
        return BandWeight(0.0, vec3f(0.0));
    }
    let grad = unit3(k) * (-sm.ds / band);
    let j0 = (k + 1u) % 3u;
    let j1 = (k + 2u) % 3u;
    let f0 = edge_factor(b[j0], b[k]);
    let f1 = edge_factor(b[j1], b[k]);
    let g0 = unit3(j0) * f0.dj + unit3(k) * f0.dk;
    let g1 = unit3(j1) * f1.dj + unit3(k) * f1.dk;
    return BandWeight(sm.s * (f0.s * f1.s), grad * f0.s * f1.s + sm.s * (g0 * f1.s + f0.s * g1));
}

// PrismDisplacement::raw: the displacement at a UV.
fn displacement_raw(uv: vec2f) -> f32 {
    return displacement_of(sample_map(uv));
}

// PrismDisplacement::at: D (or D*) at barycentrics b.
//
// One loop over the charts: the prism's own (k = 0), then each edge's other chart (k = 1..3)
// where the prism has a stitch record, so every height comes from one sample_map call site.
// An implementation that runs invocations in lock-step under masks (lavapipe) runs an `if`
// body whether any lane takes it or not, but a loop only while some lane is in it: a group of
// unstitched prisms then runs the own chart's pass alone. Per march sample. An edge outside
// its band is sampled and weighted 0 (the CPU skips it): the same D.
fn displacement_at(disp: PrismDisplacement, b: vec3f) -> f32 {
    var own = 0.0;
    var d = 0.0;
    var k = 0u;
    loop {
        var uv = disp.uv;
        var w = 0.0;
        if (k > 0u) {
            let e = k - 1u;
            let band = stitches[disp.stitch].band[e];
            if (band > 0.0 && b[e] < band) {
                w = band_weight(b, e, band).w;
            }
            uv = stitches[disp.stitch].other_uv[e];
        }
        let h = displacement_raw(uv_at(uv, b));
        if (k == 0u) {
            own = h;
            d = h;
        } else if (w > 0.0) {
            d += 0.5 * w * (h - own);
        }
        k += 1u;
        if (disp.stitch == NO_STITCH || k > 3u) {
            break;
        }
    }
    return d;
}

// A height and its gradient with respect to (b0, b1, b2) taken as independent (at_grad's
// `chart` closure, and the terms it sums).
struct ChartHeight {
    d: f32,
    g: vec3f,
}

// at_grad's `chart`: D over one UV chart and ∂D/∂b_m = ∇D · uv_m.
fn chart_height(uv: array<vec2f, 3>, b: vec3f) -> ChartHeight {
    let sg = sample_grad(uv_at(uv, b));
    let g = sg.grad * scene.disp_scale;
    return ChartHeight(displacement_of(sg.value), vec3f(dot(g, uv[0]), dot(g, uv[1]), dot(g, uv[2])));
}

// PrismDisplacement::at_grad's result: D (or D*) and its derivatives with respect to (b1, b2),
// b0 = 1 − b1 − b2.
struct DisplacementGrad {
    value: f32,
    grad: vec2f,
}

// PrismDisplacement::at_grad. Every chart's height and gradient at one `sample_grad` call
// site, in a loop over the own chart and then a stitched prism's three other charts, for the
// reason given at displacement_at (an edge outside its band, or with no weight, adds 0).
fn displacement_at_grad(disp: PrismDisplacement, b: vec3f) -> DisplacementGrad {
    var own = ChartHeight(0.0, vec3f(0.0));
    var d = 0.0;
    var g = vec3f(0.0);
    var k = 0u;
    loop {
        var uv = disp.uv;
        var bw = BandWeight(0.0, vec3f(0.0));
        if (k > 0u) {
            let e = k - 1u;
            let band = stitches[disp.stitch].band[e];
            if (band > 0.0 && b[e] < band) {
                bw = band_weight(b, e, band);
            }
            uv = stitches[disp.stitch].other_uv[e];
        }
        let c = chart_height(uv, b);
        if (k == 0u) {
            own = c;
            d = c.d;
            g = c.g;
        } else if (bw.w > 0.0 || any(bw.grad != vec3f(0.0))) {
            let diff = c.d - own.d;
            d += 0.5 * bw.w * diff;
            g += 0.5 * (bw.grad * diff + bw.w * (c.g - own.g));
        }
        k += 1u;
        if (disp.stitch == NO_STITCH || k > 3u) {
            break;
        }
    }
    return DisplacementGrad(d, vec2f(g.y - g.x, g.z - g.x));
}
