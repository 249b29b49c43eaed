//! Projective displacement mapping (Hoetzlein 2025, Algorithm 1, §4–5) over the prism BVH.
//!
//! Per candidate prism: the ray's inside interval from `prism_hit` (bilinear walls, §4.1),
//! then a march with step `dt` from the entry, the first step jittered by `R·dt` (§5.3). Each
//! sample's barycentrics come from the *scanning triangle* `c_i = V_i + h n_i/(n_i·N_g)` at the
//! sample's height `h` along `N_g` (§4.2), advanced by `δh` per step and solved by Ericson's
//! five dot products (Appendix C); `uv → D(uv)` is compared with the sample's height along the
//! scanning direction, and a sign change in either direction is a crossing.
//!
//! Departures from the paper, each for a stated reason:
//! * The default prism is DESIGN.md's shared-wall prism (`V_i + λ n_i`, one `λ` range per
//!   prism), not the paper's per-triangle scaled corners: neighbours then share their walls
//!   exactly. `Construction::ParallelOffset` keeps the paper's prism for the before/after
//!   watertightness measurement (docs/watertightness.md).
//! * In the shared-wall prism the march follows the *exact* canonical sign (`march_levels`).
//!   The prism's level sets are the planar triangles `T(λ) = {V_i + λ n_i}`; each sample
//!   tracks its level `λ` by Newton on a cubic (`level_cubic`, `level_at`; warm-started from
//!   the previous sample, the first from the paper's scanning-triangle estimate) and takes
//!   its barycentrics in `T(λ)` with the same five dot products: the paper's scanning triangle
//!   made exact for this prism. `g = λ|m(b)| − D(uv(b))` is the canonical above/below test, so
//!   two prisms see the same sign at their common wall and a crossing is never lost between
//!   them. The crossing is refined by regula falsi (Illinois) on the same `g` (always a
//!   bracket). A hit is accepted only if its `b` is in the triangle (within `EDGE_TOL`, so
//!   neighbours overlap instead of leaving a crack). `ParallelOffset` keeps the paper's
//!   approximate scanning march and `interpolateCrossing` (`march_scan`).
//! * The entry and the exit are samples too (the paper starts at `t_min + R dt` and stops
//!   before `t_max`), and the shared-wall interval is widened by a hair on both ends: a
//!   crossing right at a wall is then seen by at least one of the two prisms. It is also cut
//!   to where the surface can be, within max|D| of the base triangle (its box and the slab
//!   around its plane, `prism_hit::clip_to_surface_bounds`): a prism whose λ range is large
//!   relative to |D| never marches far.
//! * Samples whose barycentrics fall outside the triangle (curved walls make the interval a
//!   hull) are skipped for crossing detection. Where the ray leaves (or re-enters) the part of
//!   the interval in which the level cubic has a root in range (a grazing exit, the level
//!   planes folding just past a wall), the edge of that part is found by bisection and is a
//!   sample too (`level_domain_edge`): the crossing before it would be lost otherwise.
//! * Flat prisms (one displacement value) are not marched: the ray meets the triangle
//!   `V_i + D n_i`, then Newton moves the hit onto `P(b) + D m̂(b)`.
//! * The march runs in sub-prism cells (`trace::cells`), not whole prisms: each cell marches
//!   only the part of the ray in its own λ range, with the parent prism's exact level cubic
//!   (`march_shared_wall`; whole prisms with `cells: false`). Where the ray crosses the
//!   triangle's boundary between two samples a sample just outside it is added
//!   (`cross_boundary`), so a cell's interval (a superset) cannot step over a wall. Cells are
//!   marched nearly front to back by where the ray enters their slabs
//!   (`accel::BoxBvh::closest_hit_ordered`), so one that starts beyond the hit is not
//!   marched, and a cell whose interval an earlier march in its prism already covered is
//!   skipped (`Covered`).
//! * Normals come from the analytic derivative of the canonical surface
//!   (`canonical::surface_point`), not the paper's finite differences; the smoothed normal is
//!   the paper's `N's = N_s − N_g + N'` (§5.1).

use crate::accel::Scene;
use crate::bake::{Prism, PrismTable};
use crate::canonical::{surface_point, PrismGeom};
use crate::rng::{self, Purpose};
use crate::seam::PrismDisplacement;
use crate::trace::cells::{Cell, Cells};
use crate::trace::prism_hit::{clip_to_surface_bounds, ray_prism_interval};
use crate::trace::{Hit, Intersector, NormalMode, Ray, RayContext};
use glam::{Mat3, Vec2, Vec3};

/// A refined hit may lie this far outside its triangle (barycentric units): adjacent prisms
/// overlap by a hair rather than leaving a crack for rays through their common wall.
const EDGE_TOL: f32 = 1e-5;
/// Scanning barycentrics only approximate the canonical ones (different direction field);
/// samples this far outside still take part in crossing detection in shared-wall prisms.
const DETECT_TOL: f32 = 0.05;
/// A detectable sample farther than this outside the triangle (barycentric units) and its
/// neighbour inside, with the same sign: the march adds a sample on the wall between them
/// (`Pdm::wall_sample`). Above the exact interval's pad, so walls marched exactly take none.
const WALL_SAMPLE_TOL: f32 = 1e-3;
/// Where the ray crosses the triangle's boundary the march adds a sample this far outside
/// it (barycentric units; well inside `DETECT_TOL`).
const EDGE_SAMPLE: f32 = 0.01;
/// How far outside the triangle the entry sample of a march on the exact interval (whose
/// entry is on a wall, within the pad) may be before other levels are tried
/// (`Pdm::entry_sample`). Where a prism folds, the point on the wall can also lie on another
/// level whose triangle it misses by less than `DETECT_TOL`; that ghost level started the
/// march on the wrong branch (rock, bench seed 0: rays 750 213 and 840 067, `b` −0.015 on the
/// ghost against −0.0007 on the level that continues the neighbour's). A strict march's entry
/// is on a cell's slab, mostly outside the triangle, and keeps `DETECT_TOL`.
const ENTRY_TOL: f32 = 1e-3;
/// How far past the prism's λ range (relative to its longest edge) the level of an entry
/// on the exact interval may lie before other levels are tried (`Pdm::entry_sample`): ten
/// times `INTERVAL_PAD`, the interval's own widening.
const ENTRY_LEVEL_PAD: f32 = 1e-3;
/// Secant steps placing that sample.
const EDGE_ITERS: u32 = 6;
/// Shared-wall interval widening, relative to the prism's longest edge.
const INTERVAL_PAD: f32 = 1e-4;
/// Upper bound on samples per prism (a guard against `dt` far below the prism size).
const MAX_STEPS: u32 = 1 << 14;
/// Regula falsi iterations for the canonical refinement.
const REFINE_ITERS: u32 = 24;
/// Newton iterations for a sample's level `λ` (warm-started: one or two in practice).
const LEVEL_ITERS: u32 = 8;
/// Bisections locating where the ray leaves the region in which a level exists (to 1/1024
/// of the step there).
const DOMAIN_EDGE_ITERS: u32 = 10;
/// Samples `dip_probe` takes at most in one gap between march samples.
const DIP_PROBES: u32 = 4;
/// The shortest step the secant cut leaves (a fraction of `dt`).
const SECANT_MIN_STEP: f32 = 0.125;
/// Near the surface a step is at most |g| / `NEAR_SLOPE` (and at least `SECANT_MIN_STEP`
/// of a step): the surface may turn towards the ray within a step of a sample just above it
/// and leave it again before the next (rock leak ray 707 579 of seed 0: `g` at 0.036 texel,
/// rising, then a dip 0.53 steps long and 0.028 texel deep between two samples). 0.3 is
/// about the slope of `g` along that ray's dip.
const NEAR_SLOPE: f32 = 0.3;

/// March step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StepSize {
    /// World units along the (unit) ray direction.
    World(f32),
    /// Fraction of the prism's world-space texel size (`Prism::texel_world`).
    Auto(f32),
}

impl Default for StepSize {
    fn default() -> Self {
        StepSize::Auto(0.5)
    }
}

/// Which prism the march runs in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Construction {
    /// DESIGN.md's watertight prism with canonical refinement.
    #[default]
    SharedWall,
    /// The paper's parallel-offset prism, hits on the paper's surface (no canonical
    /// refinement): only for measuring what the shared-wall construction fixes.
    ParallelOffset,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PdmOptions {
    pub dt: StepSize,
    /// Stochastic thin-feature sampling (paper §5.3).
    pub jitter: bool,
    pub normal_mode: NormalMode,
    pub construction: Construction,
    /// Refine the crossing onto the canonical surface (shared-wall only).
    pub refine: bool,
    /// March sub-prism cells (`trace::cells`) instead of whole prisms (shared-wall only).
    pub cells: bool,
}

impl Default for PdmOptions {
    fn default() -> Self {
        PdmOptions {
            dt: StepSize::default(),
            jitter: true,
            normal_mode: NormalMode::Smooth,
            construction: Construction::SharedWall,
            refine: true,
            cells: true,
        }
    }
}

pub struct Pdm<'a> {
    scene: &'a Scene,
    opts: PdmOptions,
    /// The sub-prism cells the march runs in (`opts.cells`, shared-wall prisms).
    cells: Option<Cells>,
    /// Every prism's constants, in table order.
    frames: Vec<Frame>,
}

/// One prism's ray-independent constants in a local frame (origin at `V_0`, so that f32
/// keeps its precision at any distance from the world origin): built once per `Pdm` for
/// every prism (`frames`), not per candidate.
#[derive(Clone, Copy)]
struct Frame {
    origin: Vec3,
    /// Base triangle relative to `origin`, normals and UVs (for `project_to_prism`).
    geom: PrismGeom,
    /// Scanning directions `n_i / (n_i·N_g)`: the level-`h` triangle is `v_i + h a_i`.
    a: [Vec3; 3],
    ng: Vec3,
    /// Longest base edge: the length scale of tolerances.
    scale: f32,
    /// The ray-independent part of the level cubic (`level_cubic`).
    cubic: CubicBasis,
    /// The corner the barycentrics are solved from (`triangle_barycentric`).
    apex: u8,
}

/// One prism in its local frame, with its height (the map, or the stitched height next to
/// UV seams).
struct Local<'s> {
    f: &'s Frame,
    disp: PrismDisplacement<'s>,
}

/// The shared-wall prism's level sets are the planar triangles `T(λ) = {v_i + λ n_i}`. A point
/// `x` is on level `λ` iff `f(λ) = (x − c_0(λ))·N(λ) = 0` with `N(λ) = e_1(λ) × e_2(λ) =
/// N_0 + λ N_1 + λ² N_2`: a cubic in `λ`. Along a ray `x = o + t d` its coefficients are linear
/// in `t`: `f(λ, t) = (a0 + a1 t) + (b0 + b1 t) λ + (c0 + c1 t) λ² + d3 λ³` (scaled to avoid
/// overflow; Newton does not care). A zero-area base (`PRISM_INSERTED` crease prisms) has
/// `N_0 = 0`: every point is on the degenerate `T(0)`, so `f = λ f̃` and `deflate` solves the
/// quadratic `f̃` instead.
#[derive(Clone, Copy)]
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

/// The level cubic's normals `N_0, N_1, N_2` of prism `g` (local frame), scaled together
/// to avoid overflow (`lam`, the prism's largest `|λ|`, is the scale of the `N_1`, `N_2`
/// terms), and their products with `n_0`.
#[derive(Clone, Copy)]
struct CubicBasis {
    n0: Vec3,
    n1: Vec3,
    n2: Vec3,
    k0: f32,
    k1: f32,
    k2: f32,
    deflate: bool,
}

impl CubicBasis {
    fn new(g: &PrismGeom, lam: f32) -> Self {
        let e1 = g.v[1] - g.v[0];
        let e2 = g.v[2] - g.v[0];
        let d1 = g.n[1] - g.n[0];
        let d2 = g.n[2] - g.n[0];
        let n0 = e1.cross(e2);
        let n1 = e1.cross(d2) + d1.cross(e2);
        let n2 = d1.cross(d2);
        let (l0, l1, l2) = (n0.length(), n1.length() * lam, n2.length() * lam * lam);
        let inv = 1.0 / (l0 + l1 + l2).max(f32::MIN_POSITIVE);
        let (n0, n1, n2) = (n0 * inv, n1 * inv, n2 * inv);
        CubicBasis {
            n0,
            n1,
            n2,
            k0: g.n[0].dot(n0),
            k1: g.n[0].dot(n1),
            k2: g.n[0].dot(n2),
            deflate: l0 <= 1e-6 * (l0 + l1 + l2),
        }
    }
}

/// The level cubic of a prism (its `CubicBasis`, local frame, base corner `v_0`) along the
/// ray `ro + t d`.
#[inline]
fn level_cubic(c: &CubicBasis, v0: Vec3, ro: Vec3, d: Vec3) -> LevelCubic {
    let q = ro - v0;
    LevelCubic {
        a0: q.dot(c.n0),
        a1: d.dot(c.n0),
        b0: q.dot(c.n1) - c.k0,
        b1: d.dot(c.n1),
        c0: q.dot(c.n2) - c.k1,
        c1: d.dot(c.n2),
        d3: -c.k2,
        deflate: c.deflate,
    }
}

/// The level `λ` of the ray point at `t`: Newton on the level cubic from `guess` (the previous
/// sample's level). `None` if it does not converge or leaves `[lo, hi]` (a padded λ range).
#[inline]
fn level_at(c: &LevelCubic, t: f32, guess: f32, tol: f32, lo: f32, hi: f32) -> Option<f32> {
    let a = c.a0 + c.a1 * t;
    let b = c.b0 + c.b1 * t;
    let q = c.c0 + c.c1 * t;
    let mut l = guess;
    let mut step = f32::INFINITY;
    for _ in 0..LEVEL_ITERS {
        let (f, df) = if c.deflate {
            (b + l * (q + l * c.d3), q + l * 2.0 * c.d3)
        } else {
            (
                a + l * (b + l * (q + l * c.d3)),
                b + l * (2.0 * q + l * 3.0 * c.d3),
            )
        };
        step = f / df;
        if !step.is_finite() {
            return None;
        }
        l -= step;
        if !(lo..=hi).contains(&l) {
            return None;
        }
        if step.abs() <= tol {
            return Some(l);
        }
    }
    // Rounding noise above `tol` (a ray origin far from the prism): accept a small last step.
    (step.abs() <= 1e3 * tol).then_some(l)
}

impl Frame {
    fn new(table: &PrismTable, p: &Prism) -> Self {
        let [i0, i1, i2] = p.tri.map(|i| i as usize);
        let origin = table.positions[i0];
        let v = [
            Vec3::ZERO,
            table.positions[i1] - origin,
            table.positions[i2] - origin,
        ];
        let n = [table.normals[i0], table.normals[i1], table.normals[i2]];
        let uv = [table.uvs[i0], table.uvs[i1], table.uvs[i2]];
        let ng = v[1].cross(v[2]).normalize_or_zero();
        // The same floor as the baker's `parallel_offset_corners`.
        let a = n.map(|ni| ni / ni.dot(ng).max(crate::bake::M_LO_FLOOR));
        let scale = v[1]
            .length()
            .max(v[2].length())
            .max((v[2] - v[1]).length())
            .max(f32::MIN_POSITIVE);
        let geom = PrismGeom { v, n, uv };
        Frame {
            origin,
            cubic: CubicBasis::new(&geom, p.lambda_lo.abs().max(p.lambda_hi.abs())),
            apex: widest_corner(&geom.v),
            geom,
            a,
            ng,
            scale,
        }
    }
}

impl<'s> Local<'s> {
    /// The signed area of the level triangle `T(λ)` (twice it), measured along the sum of the
    /// corner directions: positive where `T(λ)` faces the way the base does, negative where it
    /// has flipped over (a crease strip below its base), zero where it collapses.
    fn level_area(&self, l: f32) -> f32 {
        let g = &self.f.geom;
        let c: [Vec3; 3] = std::array::from_fn(|i| g.v[i] + g.n[i] * l);
        (c[1] - c[0])
            .cross(c[2] - c[0])
            .dot(g.n[0] + g.n[1] + g.n[2])
    }

    #[inline]
    fn new(scene: &'s Scene, f: &'s Frame, prism: u32) -> Self {
        Local {
            f,
            disp: PrismDisplacement {
                map: &scene.map,
                params: scene.table.params,
                uv: f.geom.uv,
                stitch: scene.stitch().get(prism),
            },
        }
    }
}

/// What `level_sample` needs per ray and prism: the level cubic along the ray rebased at its
/// entry point `base = o + t0 d` (so that the cubic's coefficients are of the prism's size
/// and rounding stays far below the Newton tolerance), the tolerance, and a padded λ range (a
/// root outside it is another branch of the cubic).
struct LevelTrack {
    cubic: LevelCubic,
    base: Vec3,
    t0: f32,
    tol: f32,
    lo: f32,
    hi: f32,
    mid: f32,
}

impl LevelTrack {
    #[inline]
    fn new(local: &Local, p: &Prism, ro: Vec3, d: Vec3, t0: f32) -> Self {
        let span = 0.5 * (p.lambda_hi - p.lambda_lo) + 1e-3 * local.f.scale;
        let base = ro + d * t0;
        LevelTrack {
            cubic: level_cubic(&local.f.cubic, local.f.geom.v[0], base, d),
            base,
            t0,
            tol: 1e-6 * local.f.scale,
            lo: p.lambda_lo - span,
            hi: p.lambda_hi + span,
            mid: 0.5 * (p.lambda_lo + p.lambda_hi),
        }
    }
}

/// Barycentrics of `s` in triangle `c` by five dot products (Ericson 2004; paper App. C),
/// with the two edges taken from corner `apex` (`Frame::apex`). Their Gram determinant
/// `|e_1|²|e_2|² − (e_1·e_2)²` cancels catastrophically in f32 when the edges are nearly
/// parallel: from the sharp corner of a sliver (a crease strip's level triangle near its
/// zero-length rung, a few 10⁻⁴ wide and 0.05 long), `b` came out in steps of about 1/8. From
/// the corner opposite the longest edge (the widest angle, ≥ 60°) the edges are far from
/// parallel.
#[inline]
fn triangle_barycentric(s: Vec3, c: &[Vec3; 3], apex: u8) -> Vec3 {
    // Corners `k, i, j` in cyclic order from the apex.
    const CYCLE: [[usize; 3]; 3] = [[0, 1, 2], [1, 2, 0], [2, 0, 1]];
    let [k, i, j] = CYCLE[apex as usize % 3];
    let x0 = c[i] - c[k];
    let x1 = c[j] - c[k];
    let x2 = s - c[k];
    let d00 = x0.dot(x0);
    let d01 = x0.dot(x1);
    let d11 = x1.dot(x1);
    let d20 = x2.dot(x0);
    let d21 = x2.dot(x1);
    let inv = 1.0 / (d00 * d11 - d01 * d01);
    let bi = (d11 * d20 - d01 * d21) * inv;
    let bj = (d00 * d21 - d01 * d20) * inv;
    let mut b = [0.0; 3];
    b[k] = 1.0 - bi - bj;
    b[i] = bi;
    b[j] = bj;
    Vec3::from_array(b)
}

/// The corner opposite the longest edge of triangle `v` (`triangle_barycentric`).
fn widest_corner(v: &[Vec3; 3]) -> u8 {
    let edge = |k: usize| (v[(k + 2) % 3] - v[(k + 1) % 3]).length_squared();
    (0..3u8).fold(0, |best, k| {
        if edge(k as usize) > edge(best as usize) {
            k
        } else {
            best
        }
    })
}

/// On the straight segment from `h0` to `h1`, the part where every component is `≥ 0` (as
/// fractions of the segment), if it has one.
#[inline]
fn nonnegative_span(h0: Vec3, h1: Vec3) -> Option<(f32, f32)> {
    let (mut lo, mut hi) = (0.0f32, 1.0f32);
    for (a, b) in h0.to_array().into_iter().zip(h1.to_array()) {
        // a + s (b − a) ≥ 0
        let slope = b - a;
        if slope == 0.0 {
            if a < 0.0 {
                return None;
            }
        } else if slope > 0.0 {
            lo = lo.max(-a / slope);
        } else {
            hi = hi.min(-a / slope);
        }
    }
    (lo < hi).then_some((lo, hi))
}

/// Between two samples, the middle of the first part of the straight segment inside the
/// triangle (as a fraction of the segment), if it has one. The barycentrics are interpolated
/// homogeneously: `β = b S(λ)`, with `S` the level triangle's signed area (`Local::level_area`),
/// are the sub-triangles' signed areas, polynomial in the point and `λ` and so nearly affine
/// along a short segment, where `b` itself has a pole wherever the level triangle collapses (a
/// crease strip at `λ = 0`, whose level triangles flip over there). A point is inside where
/// every `β_i` has the sign of `S = Σ β_i`.
#[inline]
fn inside_span(local: &Local, a: &Sample, b: &Sample) -> Option<f32> {
    let (h0, h1) = (
        a.b * local.level_area(a.lambda),
        b.b * local.level_area(b.lambda),
    );
    let (h0, h1) = if h0.is_finite() && h1.is_finite() && h0 != Vec3::ZERO && h1 != Vec3::ZERO {
        (h0, h1)
    } else {
        (a.b, b.b)
    };
    let (lo, hi) = [nonnegative_span(h0, h1), nonnegative_span(-h0, -h1)]
        .into_iter()
        .flatten()
        .min_by(|a, b| a.0.total_cmp(&b.0))?;
    Some(0.5 * (lo + hi))
}

/// The level at `t` interpolated between two samples: Newton's start there (the level is
/// smooth along the ray; the nearer end's level can be on the far side of a fold of the
/// cubic, from where Newton leaves the range).
#[inline]
fn lambda_between(a: &Sample, b: &Sample, t: f32) -> f32 {
    let w = if b.t != a.t {
        ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    a.lambda + (b.lambda - a.lambda) * w
}

/// The part of a ray a candidate prism is marched on.
#[derive(Clone, Copy, Debug)]
enum Part {
    /// The whole prism's exact interval (`intersect_prism`, the prism BVH).
    Prism,
    /// A cell's slab interval: marched strictly first, then on the exact interval cut to it
    /// (`march_shared_wall`).
    Slabs(f32, f32),
    /// An exact cell's slab interval (`Cell::exact`, a crease strip): the exact interval cut
    /// to it.
    Exact(f32, f32),
}

impl Part {
    /// Where the ray enters the part: no hit in it is nearer.
    fn t0(&self) -> f32 {
        match *self {
            Part::Slabs(t0, _) | Part::Exact(t0, _) => t0,
            Part::Prism => f32::NEG_INFINITY,
        }
    }
}

/// A strict march (over a cell's slabs) met a sample away from the triangle.
struct LeftTheTriangle;

/// A march sample: height difference (ray minus surface, along the scanning direction) and
/// the scanning barycentrics.
#[derive(Clone, Copy, Default)]
struct Sample {
    t: f32,
    g: f32,
    b: Vec3,
    /// The sample's level `λ` (shared-wall march; 0 in the scanning march).
    lambda: f32,
}

impl<'a> Pdm<'a> {
    pub fn new(scene: &'a Scene, opts: PdmOptions) -> Self {
        let cells = (opts.cells && opts.construction == Construction::SharedWall)
            .then(|| Cells::build(&scene.table, &scene.map, scene.stitch()));
        let frames = scene
            .table
            .prisms
            .iter()
            .map(|p| Frame::new(&scene.table, p))
            .collect();
        Pdm {
            scene,
            opts,
            cells,
            frames,
        }
    }

    /// The cells the march runs in, if any.
    pub fn cells(&self) -> Option<&Cells> {
        self.cells.as_ref()
    }

    pub fn options(&self) -> &PdmOptions {
        &self.opts
    }

    /// The cheap hit record for one prism (t, prism, barycentrics, steps; surface data not
    /// filled). `steps` accumulates the samples taken, hit or miss.
    pub fn intersect_prism(
        &self,
        ray: &Ray,
        ctx: &RayContext,
        prism: u32,
        steps: &mut u32,
    ) -> Option<Hit> {
        self.intersect_part(ray, ctx, prism, Part::Prism, steps)
    }

    /// A candidate cell's first test: the part of the ray inside its slabs (`None` if the ray
    /// misses them). They reject most candidates before the prism is set up.
    #[inline]
    fn cell_part(&self, c: &Cell, ray: &Ray) -> Option<Part> {
        let origin = self.frames[c.prism as usize].origin;
        let (t0, t1) = c.clip(ray.origin - origin, ray.dir, ray.t_min, ray.t_max)?;
        Some(if c.exact {
            Part::Exact(t0, t1)
        } else {
            Part::Slabs(t0, t1)
        })
    }

    /// `intersect_prism` over a part of the ray (`Part`).
    fn intersect_part(
        &self,
        ray: &Ray,
        ctx: &RayContext,
        prism: u32,
        part: Part,
        steps: &mut u32,
    ) -> Option<Hit> {
        let p = &self.scene.table.prisms[prism as usize];
        let frame = &self.frames[prism as usize];
        let local = Local::new(self.scene, frame, prism);
        let ro = ray.origin - local.f.origin;
        let (t, b) = if p.is_flat() {
            self.flat_hit(&local, p.d_min, ro, ray)?
        } else {
            match self.opts.construction {
                Construction::SharedWall => {
                    self.march_shared_wall(&local, p, prism, part, ro, ray, ctx, steps)?
                }
                Construction::ParallelOffset => {
                    self.march_scan(&local, p, prism, ro, ray, ctx, steps)?
                }
            }
        };
        Some(Hit {
            t,
            prism,
            bary: b,
            uv: Vec2::ZERO,
            position: ray.at(t),
            geometric_normal: Vec3::ZERO,
            shading_normal: Vec3::ZERO,
            steps: 0,
        })
    }

    /// Fill uv, position and normals of a cheap record from the canonical surface.
    pub fn fill_surface(&self, hit: &mut Hit) {
        let table = &self.scene.table;
        let g = PrismGeom::new(table, &table.prisms[hit.prism as usize]);
        let sp = surface_point(&g, &self.scene.prism_displacement(hit.prism), hit.bary);
        hit.uv = sp.uv;
        if self.opts.construction == Construction::SharedWall {
            // The paper-exact mode keeps the ray point: its hit is on the paper's surface.
            hit.position = sp.position;
        }
        hit.geometric_normal = sp.geometric_normal;
        hit.shading_normal = match self.opts.normal_mode {
            NormalMode::Smooth => sp.smooth_normal,
            NormalMode::Geometric => sp.geometric_normal,
        };
    }

    fn step_size(&self, p: &Prism, local: &Local) -> f32 {
        let dt = match self.opts.dt {
            StepSize::World(w) => w,
            StepSize::Auto(f) => f * p.texel_world,
        };
        if dt.is_finite() && dt > 0.0 {
            dt
        } else {
            // No texel size (UV-degenerate face): a sixteenth of the prism's thickness.
            ((p.lambda_hi - p.lambda_lo).abs().max(local.f.scale * 1e-3)) / 16.0
        }
    }

    /// Scanning sample at point `s` (local) with scanning triangle `c` at height `h`.
    #[inline]
    fn scan(&self, local: &Local, t: f32, s: Vec3, c: &[Vec3; 3], h: f32) -> Sample {
        let b = triangle_barycentric(s, c, local.f.apex);
        let a = local.f.a[0] * b.x + local.f.a[1] * b.y + local.f.a[2] * b.z;
        Sample {
            t,
            g: h * a.length() - local.disp.at(b),
            b,
            lambda: 0.0,
        }
    }

    /// Jitter of the first step (paper §5.3), in `[0, 1)`.
    #[inline]
    fn jitter(&self, ctx: &RayContext, prism: u32) -> f32 {
        if self.opts.jitter {
            rng::random(
                ctx.pixel,
                ctx.sample,
                ctx.bounce,
                Purpose::MarchJitter,
                ctx.seed ^ prism,
            )
        } else {
            0.0
        }
    }

    /// The paper's march in its own parallel-offset prism (`Construction::ParallelOffset`):
    /// scanning triangle, sign change, `interpolateCrossing`. Kept as the "before" of
    /// docs/watertightness.md.
    #[allow(clippy::too_many_arguments)]
    fn march_scan(
        &self,
        local: &Local,
        p: &Prism,
        prism: u32,
        ro: Vec3,
        ray: &Ray,
        ctx: &RayContext,
        steps: &mut u32,
    ) -> Option<(f32, Vec3)> {
        let d = ray.dir;
        let (lo, hi) = self.scene.table.parallel_offset_corners(p);
        let (lo, hi) = (
            lo.map(|c| c - local.f.origin),
            hi.map(|c| c - local.f.origin),
        );
        let iv = ray_prism_interval(ro, d, ray.t_min, ray.t_max, &lo, &hi)?;
        let (te, tx) = (iv.t_enter, iv.t_exit);
        let dt = self.step_size(p, local).max((tx - te) / MAX_STEPS as f32);
        let inside = |b: Vec3| b.min_element() >= -EDGE_TOL;

        // Entry sample and the scanning triangle at its height.
        let mut s = ro + d * te;
        let mut h = s.dot(local.f.ng);
        let mut c: [Vec3; 3] = std::array::from_fn(|i| local.f.geom.v[i] + local.f.a[i] * h);
        let first = self.scan(local, te, s, &c, h);
        let mut prev = inside(first.b).then_some(first);
        let r = self.jitter(ctx, prism);
        let mut t;
        let mut t_next = te + if r > 0.0 { r * dt } else { dt };
        let mut n = 0;
        loop {
            t_next = t_next.min(tx);
            s = ro + d * t_next;
            let h_next = s.dot(local.f.ng);
            let dh = h_next - h;
            for (ci, ai) in c.iter_mut().zip(&local.f.a) {
                *ci += *ai * dh;
            }
            h = h_next;
            t = t_next;
            n += 1;
            let cur = self.scan(local, t, s, &c, h);
            if inside(cur.b) {
                if let Some(pv) = prev {
                    if (pv.g > 0.0) != (cur.g > 0.0) {
                        if let Some(hit) = self.scan_crossing(local, ro, ray, pv, cur, te, tx) {
                            *steps += n;
                            return Some(hit);
                        }
                    }
                }
                prev = Some(cur);
            }
            if t >= tx || n >= MAX_STEPS {
                break;
            }
            t_next = t + dt;
        }
        *steps += n;
        None
    }

    /// The paper's `interpolateCrossing`, barycentrics from a fresh scanning triangle.
    #[allow(clippy::too_many_arguments)]
    fn scan_crossing(
        &self,
        local: &Local,
        ro: Vec3,
        ray: &Ray,
        a: Sample,
        b: Sample,
        te: f32,
        tx: f32,
    ) -> Option<(f32, Vec3)> {
        let t = a.t + (b.t - a.t) * (a.g / (a.g - b.g));
        let s = ro + ray.dir * t;
        let h = s.dot(local.f.ng);
        let c = std::array::from_fn(|i| local.f.geom.v[i] + local.f.a[i] * h);
        let bary = triangle_barycentric(s, &c, local.f.apex);
        let ok = bary.min_element() >= -EDGE_TOL && t >= te && t <= tx;
        ok.then_some((t, bary))
    }

    /// The paper's scanning-triangle estimate of the level of the local point `x`: its height
    /// `h` along `N_g`, scanning barycentrics `b`, and `λ = h / (m(b)·N_g)` (the canonical
    /// point `P(b) + λ m(b)` has height `λ m(b)·N_g`). Only a starting guess for `level_at`.
    #[inline]
    fn scan_level_estimate(local: &Local, x: Vec3) -> f32 {
        let h = x.dot(local.f.ng);
        let c = std::array::from_fn(|i| local.f.geom.v[i] + local.f.a[i] * h);
        let b = triangle_barycentric(x, &c, local.f.apex);
        let mn = local.f.geom.normal_dir(b).dot(local.f.ng);
        if mn > crate::bake::M_LO_FLOOR {
            h / mn
        } else {
            h
        }
    }

    /// The march's first sample, at the prism entry. Its guess is only the scanning-triangle
    /// estimate, and the level cubic can have another root in the padded range whose level
    /// triangle misses the point (a ghost level, `b` far outside); every later sample is
    /// warm-started from this one, so the march would stay on that branch and skip a crossing.
    /// If `b` is outside by more than `tol`, or (`range`: an entry on the exact interval, on
    /// the prism's walls or caps) the level lies outside the prism's λ range, retry from the
    /// middle and the quarters of the range and keep the level in the range, then the one
    /// whose `b` is most inside. (A ghost can also hold the point inside its triangle: rock
    /// prism 330, seed 0x1ea4 ray 864 980, entered on its wall with 331 at λ −0.048, outside
    /// the range [−0.027, 0.024], where the level that continues 331's is −0.015.)
    #[allow(clippy::too_many_arguments)]
    fn entry_sample(
        &self,
        local: &Local,
        lt: &LevelTrack,
        d: Vec3,
        t: f32,
        guess: f32,
        tol: f32,
        range: Option<(f32, f32)>,
    ) -> Option<Sample> {
        let in_range = |s: &Sample| range.is_none_or(|(lo, hi)| (lo..=hi).contains(&s.lambda));
        let first = self.level_sample(local, lt, d, t, guess);
        if first.is_some_and(|s| s.b.min_element() >= -tol && in_range(&s)) {
            return first;
        }
        let quarter = 0.25 * (lt.hi - lt.lo);
        [lt.mid, lt.mid - quarter, lt.mid + quarter]
            .into_iter()
            .filter_map(|g0| self.level_sample(local, lt, d, t, g0))
            .chain(first)
            .max_by(|a, b| {
                in_range(a)
                    .cmp(&in_range(b))
                    .then(a.b.min_element().total_cmp(&b.b.min_element()))
            })
    }

    /// Exact canonical sample at `t`: the level `λ` of the ray point (Newton on the level
    /// cubic from `guess`, retried from the middle of the prism), `b` its barycentrics in the
    /// level triangle `T(λ)` (the scanning triangle made exact), and `g = λ|m(b)| − D(uv(b))`:
    /// positive above the canonical surface, negative below.
    #[inline]
    fn level_sample(
        &self,
        local: &Local,
        lt: &LevelTrack,
        d: Vec3,
        t: f32,
        guess: f32,
    ) -> Option<Sample> {
        let u = t - lt.t0;
        let l = level_at(&lt.cubic, u, guess, lt.tol, lt.lo, lt.hi)
            .or_else(|| level_at(&lt.cubic, u, lt.mid, lt.tol, lt.lo, lt.hi))?;
        let g = &local.f.geom;
        let c: [Vec3; 3] = std::array::from_fn(|i| g.v[i] + g.n[i] * l);
        let b = triangle_barycentric(lt.base + d * u, &c, local.f.apex);
        Some(Sample {
            t,
            g: l * g.normal_dir(b).length() - local.disp.at(b),
            b,
            lambda: l,
        })
    }

    /// The shared-wall march over the whole prism (its exact interval), or over a cell: first
    /// on the cell's slab interval, a superset of the cell, which is fine as long as every
    /// sample stays at the triangle; if one leaves it (or has no level), the cell is marched
    /// again on the prism's exact interval cut to the slabs, as the whole prism would be: the
    /// walls are then samples, and no part of the triangle between two samples outside it is
    /// stepped over. An exact cell (a crease strip) takes that second march at once.
    #[allow(clippy::too_many_arguments)]
    fn march_shared_wall(
        &self,
        local: &Local,
        p: &Prism,
        prism: u32,
        part: Part,
        ro: Vec3,
        ray: &Ray,
        ctx: &RayContext,
        steps: &mut u32,
    ) -> Option<(f32, Vec3)> {
        let cut = match part {
            Part::Prism => None,
            Part::Slabs(t0, t1) => {
                let strict =
                    self.march_levels(local, p, prism, (t0, t1), true, ro, ray, ctx, steps);
                if let Ok(hit) = strict {
                    return hit;
                }
                Some((t0, t1))
            }
            Part::Exact(t0, t1) => Some((t0, t1)),
        };
        let (mut te, mut tx) = Self::prism_interval(local, p, ro, ray)?;
        if let Some((t0, t1)) = cut {
            (te, tx) = (te.max(t0), tx.min(t1));
            if te > tx {
                return None;
            }
        }
        self.march_levels(local, p, prism, (te, tx), false, ro, ray, ctx, steps)
            .unwrap_or(None)
    }

    /// The padded part of the ray inside the whole shared-wall prism, cut to the surface
    /// bounds (`prism_hit`).
    fn prism_interval(local: &Local, p: &Prism, ro: Vec3, ray: &Ray) -> Option<(f32, f32)> {
        let g = &local.f.geom;
        let d = ray.dir;
        let lo = std::array::from_fn(|i| g.v[i] + g.n[i] * p.lambda_lo);
        let hi = std::array::from_fn(|i| g.v[i] + g.n[i] * p.lambda_hi);
        let pad = INTERVAL_PAD * local.f.scale;
        // Cut to the surface bounds first: most candidate prisms of a ray are rejected here,
        // before the walls, and the walls' crossings are searched on the cut segment only.
        let reach = p.d_min.abs().max(p.d_max.abs()) + pad;
        let (t0, t1) = clip_to_surface_bounds(ro, d, ray.t_min, ray.t_max, &g.v, reach)?;
        let iv = ray_prism_interval(ro, d, t0, t1, &lo, &hi)?;
        Some(((iv.t_enter - pad).max(t0), (iv.t_exit + pad).min(t1)))
    }

    /// PDM in the shared-wall prism, on the exact canonical sign: every sample is a
    /// `level_sample`, so a sign change between two samples always brackets a crossing of the
    /// canonical surface, and neighbouring prisms see the same sign at their common wall.
    #[allow(clippy::too_many_arguments)]
    fn march_levels(
        &self,
        local: &Local,
        p: &Prism,
        prism: u32,
        (te, tx): (f32, f32),
        strict: bool,
        ro: Vec3,
        ray: &Ray,
        ctx: &RayContext,
        steps: &mut u32,
    ) -> Result<Option<(f32, Vec3)>, LeftTheTriangle> {
        let d = ray.dir;
        let dt = self.step_size(p, local).max((tx - te) / MAX_STEPS as f32);
        let lt = LevelTrack::new(local, p, ro, d, te);

        let mut guess = Self::scan_level_estimate(local, ro + d * te);
        let mut prev: Option<Sample> = None;
        // The last sample with a level, and where the latest sample without one since then was.
        let mut last_ok: Option<Sample> = None;
        let mut failed_at: Option<f32> = None;
        // The latest sample with a level, domain edges included (for `feed`).
        let mut last: Option<Sample> = None;
        // The last two loop samples, while each had a level (the next guess).
        let mut trail: [Option<Sample>; 2] = [None, None];
        // The latest loop samples near the triangle (`dip_probe`), a ring of four, and how
        // many of them came in a row.
        let mut dips = [Sample::default(); 4];
        let mut dip_count = 0usize;
        let r = self.jitter(ctx, prism);
        let mut t = te;
        let mut n = 0;
        // Whether a sample lay inside the triangle (a strict march with none is redone on the
        // exact interval).
        let mut seen_inside = false;
        loop {
            n += 1;
            let sample = if n == 1 {
                // An entry on the exact interval lies on the prism's boundary, so at a level
                // in its range; a strict march's entry is on a cell's slab, anywhere.
                let (tol, range) = if strict {
                    (DETECT_TOL, None)
                } else {
                    let pad = ENTRY_LEVEL_PAD * local.f.scale;
                    (ENTRY_TOL, Some((p.lambda_lo - pad, p.lambda_hi + pad)))
                };
                self.entry_sample(local, &lt, d, t, guess, tol, range)
            } else {
                self.level_sample(local, &lt, d, t, guess)
            };
            if strict && !sample.is_some_and(|s| Self::detectable(&s)) {
                *steps += n;
                return Err(LeftTheTriangle);
            }
            seen_inside |= sample.is_some_and(|s| s.b.min_element() >= 0.0);
            // Where the ray leaves (or re-enters) the region in which a level exists, the
            // edge of that region is a sample too: a crossing between the last sample with a
            // level and the first without one would be lost otherwise (a grazing exit, where
            // the level planes fold just past the wall).
            let edge = match (sample, failed_at) {
                (None, None) => {
                    last_ok.map(|ok| self.level_domain_edge(local, &lt, d, ok, t, &mut n))
                }
                (Some(cur), Some(bad)) => {
                    Some(self.level_domain_edge(local, &lt, d, cur, bad, &mut n))
                }
                _ => None,
            };
            if let Some(e) = edge {
                guess = e.lambda;
                if let Some(hit) =
                    self.feed(local, &lt, ray, &mut prev, &mut last, e, (te, tx), &mut n)
                {
                    *steps += n;
                    return Ok(Some(hit));
                }
            }
            match sample {
                Some(cur) => {
                    guess = cur.lambda;
                    last_ok = Some(cur);
                    failed_at = None;
                    if let Some(hit) =
                        self.feed(local, &lt, ray, &mut prev, &mut last, cur, (te, tx), &mut n)
                    {
                        *steps += n;
                        return Ok(Some(hit));
                    }
                    trail = [trail[1], Some(cur)];
                    if Self::detectable(&cur) {
                        dips[dip_count & 3] = cur;
                        dip_count += 1;
                        // The last four, oldest first.
                        let g = |i: usize| dips[(dip_count + i) & 3].g;
                        if dip_count >= 4 && Self::may_dip([g(0), g(1), g(2), g(3)]) {
                            let last4 = std::array::from_fn(|i| dips[(dip_count + i) & 3]);
                            let before = n;
                            if let Some(hit) =
                                self.dip_probe(local, &lt, ray, last4, (te, tx), &mut n)
                            {
                                *steps += n;
                                return Ok(Some(hit));
                            }
                            if n > before {
                                // After a probe the ring starts again (the GPU's march keeps
                                // the gap in it while it probes).
                                dip_count = 0;
                            }
                        }
                    } else {
                        dip_count = 0;
                    }
                }
                None => {
                    failed_at = Some(t);
                    trail = [None, None];
                    dip_count = 0;
                }
            }
            if t >= tx || n >= MAX_STEPS {
                break;
            }
            let mut t_next = if n == 1 && r > 0.0 {
                t + r * dt
            } else {
                t + dt
            };
            if let [Some(a), Some(b)] = trail {
                if b.t == t && Self::approaching(&a, &b) {
                    let t_star = b.t - b.g * ((b.t - a.t) / (b.g - a.g));
                    if t_star < t_next {
                        t_next = t_star.max(t + SECANT_MIN_STEP * dt);
                    }
                }
            }
            if let Some(b) = trail[1] {
                let near = b.g.abs() / NEAR_SLOPE;
                if b.t == t && near < t_next - t && Self::detectable(&b) {
                    t_next = t + near.max(SECANT_MIN_STEP * dt);
                }
            }
            t = t_next.min(tx);
            // The level is smooth along the ray: Newton starts from the last two samples'
            // line, which leaves it one iteration from converged.
            if let [Some(a), Some(b)] = trail {
                if b.t > a.t {
                    guess = b.lambda + (b.lambda - a.lambda) * ((t - b.t) / (b.t - a.t));
                }
            }
        }
        *steps += n;
        if strict && !seen_inside {
            // Every sample lay outside the triangle (within `DETECT_TOL`): either the ray
            // passes beside it, or the march followed a ghost level whose triangle the ray
            // misses while the level that continues the neighbours' holds a crossing inside
            // (rock leak ray 674 471 of seed 0: b₁ ≈ −0.019 at every sample on the ghost, a
            // hit at b₁ = 0.0012 on the other level). The exact interval settles it: its
            // entry tries the other levels (`entry_sample`).
            return Err(LeftTheTriangle);
        }
        Ok(None)
    }

    /// Two successive loop samples near the triangle, on one side, `g` shrinking towards the
    /// surface: the line through them meets it ahead (the next step is cut to there).
    #[inline(always)]
    fn approaching(a: &Sample, b: &Sample) -> bool {
        Self::detectable(a)
            && Self::detectable(b)
            && (a.g > 0.0) == (b.g > 0.0)
            && b.g.abs() < a.g.abs()
            && b.t > a.t
    }

    /// Take the next sample with a level, `cur`. Where the ray crossed the triangle's
    /// boundary since the latest one (one `detectable`, the other not), a sample just outside
    /// the boundary is taken first (`cross_boundary`): the crossing between the last sample
    /// inside and the wall would be lost otherwise (the march's interval may reach past the
    /// walls: the hull of curved walls, or a cell's slabs).
    #[allow(clippy::too_many_arguments)]
    fn feed(
        &self,
        local: &Local,
        lt: &LevelTrack,
        ray: &Ray,
        prev: &mut Option<Sample>,
        last: &mut Option<Sample>,
        cur: Sample,
        (te, tx): (f32, f32),
        n: &mut u32,
    ) -> Option<(f32, Vec3)> {
        let span = (te, tx);
        if let Some(pv) = last.replace(cur) {
            match (Self::detectable(&pv), Self::detectable(&cur)) {
                (true, true) => {
                    // Both near the triangle, one of them outside it: that one sampled the
                    // prism's surface continued past its wall, where the neighbour's may lie
                    // on the other side of the ray. With the same sign at both ends, a
                    // crossing inside the triangle between the inside one and the wall would
                    // be lost (a strict march's last sample past a corner of the fan around a
                    // vertex): sample the wall first.
                    if let Some(w) = self.wall_sample(local, lt, ray, &pv, &cur, n) {
                        if let Some(hit) = self.detect(local, lt, ray, prev, w, te, tx) {
                            return Some(hit);
                        }
                    }
                }
                (false, false) => {
                    // Both outside: the segment may still cut across a corner of the
                    // triangle, between two other edges. Sample the middle of its part
                    // inside, then cross the boundary into it and out of it again.
                    if let Some(m) = self.inside_sample(local, lt, ray, &pv, &cur, n) {
                        let hit = self
                            .cross_boundary(local, lt, ray, prev, pv, m, span, n)
                            .or_else(|| self.detect(local, lt, ray, prev, m, te, tx))
                            .or_else(|| self.cross_boundary(local, lt, ray, prev, m, cur, span, n));
                        if hit.is_some() {
                            return hit;
                        }
                    }
                }
                (leaving, _) => {
                    // One end is near the triangle. If that end is itself outside (within
                    // `DETECT_TOL`), the segment can pass through the inside between the two
                    // and out again (a sliver of a crease strip, thinner than the step):
                    // sample that inside part as above, and cross the boundary from it.
                    let near = if leaving { &pv } else { &cur };
                    let through = (near.b.min_element() < 0.0)
                        .then(|| self.inside_sample(local, lt, ray, &pv, &cur, n))
                        .flatten()
                        .filter(|m| m.b.min_element() > near.b.min_element());
                    let hit = match through {
                        Some(m) if leaving => self
                            .detect(local, lt, ray, prev, m, te, tx)
                            .or_else(|| self.cross_boundary(local, lt, ray, prev, m, cur, span, n)),
                        Some(m) => self
                            .cross_boundary(local, lt, ray, prev, pv, m, span, n)
                            .or_else(|| self.detect(local, lt, ray, prev, m, te, tx)),
                        None => self.cross_boundary(local, lt, ray, prev, pv, cur, span, n),
                    };
                    if hit.is_some() {
                        return hit;
                    }
                }
            }
        }
        self.detect(local, lt, ray, prev, cur, te, tx)
    }

    /// Four successive samples `[a, b, c, d]` on one side of the surface whose values fall from
    /// `a` to `b` and rise from `c` to `d`: the surface may reach the ray between `b` and `c`
    /// and leave it again before `c` (a fold or a ridge thinner than a step). Where the lines
    /// through `a, b` and `c, d` meet between `b` and `c` on the other side, that point is
    /// sampled; a sign change there is resolved into the crossing after `b`; `n` counts it.
    #[cold]
    #[inline(never)]
    fn dip_probe(
        &self,
        local: &Local,
        lt: &LevelTrack,
        ray: &Ray,
        [a, b, c, d]: [Sample; 4],
        (te, tx): (f32, f32),
        n: &mut u32,
    ) -> Option<(f32, Vec3)> {
        // All four on this side (`may_dip`).
        let above = b.g > 0.0;
        let side = if above { 1.0 } else { -1.0 };
        // Where the line through `p, q` (falling to `q`) meets the line through `r, s` (rising
        // from `r`) between `q` and `r`, if it lies on the other side of the surface.
        let apex = |p: &Sample, q: &Sample, r: &Sample, s: &Sample| -> Option<(f32, f32)> {
            let kl = side * (q.g - p.g) / (q.t - p.t);
            let kr = side * (s.g - r.g) / (s.t - r.t);
            if !(kl < 0.0 && kr > 0.0 && kl.is_finite() && kr.is_finite()) {
                return None;
            }
            let t = (side * (r.g - q.g) + kl * q.t - kr * r.t) / (kl - kr);
            let v = side * q.g + kl * (t - q.t);
            (t > q.t && t < r.t && v < 0.0).then_some((t, v))
        };
        // The gap between the middle two of four samples, and where its lines meet.
        let mut gap = (a, b, c, d);
        let mut at = apex(&a, &b, &c, &d);
        for _ in 0..DIP_PROBES {
            let (t, _) = at?;
            let (p, q, r, s) = gap;
            *n += 1;
            let m = self
                .level_sample(local, lt, ray.dir, t, lambda_between(&q, &r, t))
                .filter(Self::detectable)?;
            if (m.g > 0.0) != above {
                return self.level_crossing(local, lt, ray, q, m, te, tx);
            }
            // Still on this side: go on in the half whose lines dip lower.
            let (left, right) = ((p, q, m, r), (q, m, r, s));
            let (al, ar) = (apex(&p, &q, &m, &r), apex(&q, &m, &r, &s));
            (gap, at) = match (al, ar) {
                (Some(l), Some(r)) if r.1 < l.1 => (right, ar),
                (None, Some(_)) => (right, ar),
                _ => (left, al),
            };
        }
        None
    }

    /// `dip_probe`'s cheap test on four samples' `g`: all on one side, falling into the middle
    /// gap and rising out of it.
    #[inline(always)]
    fn may_dip([a, b, c, d]: [f32; 4]) -> bool {
        let above = b > 0.0;
        (a > 0.0) == above
            && (c > 0.0) == above
            && (d > 0.0) == above
            && b.abs() < a.abs()
            && d.abs() > c.abs()
    }

    /// Where one of two successive samples with the same sign lies inside the triangle and the
    /// other past a wall by more than `WALL_SAMPLE_TOL`: the sample where the ray meets that
    /// wall (the outside one's most negative barycentric interpolated to 0 along the
    /// segment: nearly affine there); `n` counts it.
    fn wall_sample(
        &self,
        local: &Local,
        lt: &LevelTrack,
        ray: &Ray,
        a: &Sample,
        b: &Sample,
        n: &mut u32,
    ) -> Option<Sample> {
        if (a.g > 0.0) != (b.g > 0.0) {
            return None;
        }
        let outside = |s: &Sample| s.b.min_element() < -WALL_SAMPLE_TOL;
        let out = match (outside(a), outside(b)) {
            (false, true) => b,
            (true, false) => a,
            _ => return None,
        };
        let k = (0..3)
            .min_by(|&i, &j| out.b[i].total_cmp(&out.b[j]))
            .expect("three barycentrics");
        let (fa, fb) = (a.b[k], b.b[k]);
        if (fa >= 0.0) == (fb >= 0.0) {
            return None;
        }
        let t = a.t + (b.t - a.t) * (fa / (fa - fb));
        *n += 1;
        self.level_sample(local, lt, ray.dir, t, lambda_between(a, b, t))
            .filter(Self::detectable)
    }

    /// A sample in the middle of the part of the segment from `a` to `b` inside the triangle
    /// (`inside_span`), if it has one and the sample is `detectable`; `n` counts it.
    fn inside_sample(
        &self,
        local: &Local,
        lt: &LevelTrack,
        ray: &Ray,
        a: &Sample,
        b: &Sample,
        n: &mut u32,
    ) -> Option<Sample> {
        let s = inside_span(local, a, b)?;
        let t = a.t + (b.t - a.t) * s;
        *n += 1;
        self.level_sample(local, lt, ray.dir, t, 0.5 * (a.lambda + b.lambda))
            .filter(Self::detectable)
    }

    /// One march sample `cur`: a sign change of `g` from the previous sample inside the
    /// triangle (within `DETECT_TOL`) is resolved into a hit (`level_crossing`); otherwise
    /// `cur` becomes the previous sample if it is inside.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn detect(
        &self,
        local: &Local,
        lt: &LevelTrack,
        ray: &Ray,
        prev: &mut Option<Sample>,
        cur: Sample,
        te: f32,
        tx: f32,
    ) -> Option<(f32, Vec3)> {
        if !Self::detectable(&cur) {
            return None;
        }
        if let Some(pv) = *prev {
            if (pv.g > 0.0) != (cur.g > 0.0) {
                if let Some(hit) = self.level_crossing(local, lt, ray, pv, cur, te, tx) {
                    return Some(hit);
                }
            }
        }
        *prev = Some(cur);
        None
    }

    /// Whether a sample's `b` is near enough to the triangle to take part in detection.
    #[inline]
    fn detectable(s: &Sample) -> bool {
        s.b.min_element() >= -DETECT_TOL
    }

    /// Samples `a` then `b` lie on either side of the triangle's boundary (one `detectable`,
    /// the other not): add a sample just outside the boundary (`b` in `[−DETECT_TOL, 0)`,
    /// aiming at `−EDGE_SAMPLE`) by secant steps on `min_i b_i` (nearly affine along a short
    /// segment), so that a crossing between the last sample inside and the wall is
    /// bracketed. Leaving the triangle, every sample inside on the way is detected in order
    /// (they advance monotonically); entering, the one nearest the boundary.
    #[allow(clippy::too_many_arguments)]
    fn cross_boundary(
        &self,
        local: &Local,
        lt: &LevelTrack,
        ray: &Ray,
        prev: &mut Option<Sample>,
        a: Sample,
        b: Sample,
        (te, tx): (f32, f32),
        n: &mut u32,
    ) -> Option<(f32, Vec3)> {
        let leaving = Self::detectable(&a);
        let f = |s: &Sample| s.b.min_element() + EDGE_SAMPLE;
        let (mut s0, mut s1) = (a, b);
        let mut nearest: Option<Sample> = None;
        for _ in 0..EDGE_ITERS {
            let (f0, f1) = (f(&s0), f(&s1));
            if (f0 > 0.0) == (f1 > 0.0) {
                break;
            }
            let t = s0.t + (s1.t - s0.t) * (f0 / (f0 - f1));
            let guess = lambda_between(&s0, &s1, t);
            *n += 1;
            let Some(s) = self.level_sample(local, lt, ray.dir, t, guess) else {
                break;
            };
            let just_outside = (-DETECT_TOL..0.0).contains(&s.b.min_element());
            if leaving && Self::detectable(&s) || just_outside {
                if let Some(hit) = self.detect(local, lt, ray, prev, s, te, tx) {
                    return Some(hit);
                }
                if just_outside {
                    return None;
                }
            }
            if Self::detectable(&s) {
                nearest = Some(s);
            }
            if (f(&s) > 0.0) == (f0 > 0.0) {
                s0 = s;
            } else {
                s1 = s;
            }
        }
        match nearest {
            Some(s) if !leaving => {
                // Where the boundary lies within a few ulps of `t` (a crease strip's sliver
                // around its `λ = 0` pole, where `b` sweeps across the triangle in less than
                // one step of f32 `t`), no sample lands just outside it, and a crossing between
                // the wall and `s` would be lost: take the wall's own sample.
                let wall = self.wall_crossing(local, &s0, &s);
                if let Some((t, b)) = wall.filter(|&(t, b)| {
                    b.min_element() >= -EDGE_TOL && t >= te.max(ray.t_min) && t <= tx.min(ray.t_max)
                }) {
                    return Some((t, b));
                }
                self.detect(local, lt, ray, prev, s, te, tx)
            }
            _ => None,
        }
    }

    /// The crossing between the triangle's boundary and the sample `inside`, entering from
    /// `outside`, if the surface's sign on the boundary differs from `inside`'s: the boundary
    /// point found in homogeneous barycentrics (`inside_span`: nearly affine along a short
    /// segment, where `b` has a pole) with the level interpolated, and the crossing
    /// interpolated between it and `inside`. No level is solved at a ray parameter, so this
    /// holds where f32 `t` cannot resolve the boundary.
    #[cold]
    #[inline(never)]
    fn wall_crossing(
        &self,
        local: &Local,
        outside: &Sample,
        inside: &Sample,
    ) -> Option<(f32, Vec3)> {
        let (s_out, s_in) = (
            local.level_area(outside.lambda),
            local.level_area(inside.lambda),
        );
        let (h0, h1) = (outside.b * s_out, inside.b * s_in);
        if !(h0.is_finite() && h1.is_finite()) || s_in == 0.0 {
            return None;
        }
        // The last wall crossed: the largest fraction at which a component that is outside at
        // `outside` (of the other sign than the area) reaches zero.
        let (h0a, h1a) = (h0.to_array(), h1.to_array());
        let mut wall: Option<(usize, f32)> = None;
        for k in 0..3 {
            let (a, b) = (h0a[k] * s_in.signum(), h1a[k] * s_in.signum());
            if a < 0.0 && b >= 0.0 {
                let f = a / (a - b);
                if wall.is_none_or(|(_, g)| f > g) {
                    wall = Some((k, f));
                }
            }
        }
        let (k, f) = wall?;
        let h = h0 + (h1 - h0) * f;
        let sum = h.x + h.y + h.z;
        if sum == 0.0 || !sum.is_finite() {
            return None;
        }
        let mut bw = (h / sum).to_array();
        bw[k] = 0.0;
        let bw = Vec3::from_array(bw);
        if bw.min_element() < -EDGE_TOL {
            return None;
        }
        let lambda = outside.lambda + (inside.lambda - outside.lambda) * f;
        let tw = outside.t + (inside.t - outside.t) * f;
        let gw = lambda * local.f.geom.normal_dir(bw).length() - local.disp.at(bw);
        if !gw.is_finite() || gw == 0.0 || (gw > 0.0) == (inside.g > 0.0) {
            return None;
        }
        let w = inside.g / (inside.g - gw);
        Some((
            inside.t + (tw - inside.t) * w,
            inside.b + (bw - inside.b) * w,
        ))
    }

    /// The sample nearest to `bad` (a ray parameter with no level in range) on the segment
    /// from the sample `ok` towards it, by bisection; `n` counts the samples taken.
    fn level_domain_edge(
        &self,
        local: &Local,
        lt: &LevelTrack,
        d: Vec3,
        ok: Sample,
        bad: f32,
        n: &mut u32,
    ) -> Sample {
        let (mut good, mut bad) = (ok, bad);
        for _ in 0..DOMAIN_EDGE_ITERS {
            let t = 0.5 * (good.t + bad);
            *n += 1;
            match self.level_sample(local, lt, d, t, good.lambda) {
                Some(s) => good = s,
                None => bad = t,
            }
        }
        good
    }

    /// Resolve a sign change of the canonical `g` between samples `a` and `b` into a hit:
    /// regula falsi (Illinois) on `g(t)`, each evaluation a `level_sample` warm-started from
    /// the nearer end; without `refine`, the paper's linear interpolation. The hit is accepted
    /// if its `b` is in the triangle (within `EDGE_TOL`): a crossing in the neighbour is the
    /// neighbour's.
    #[allow(clippy::too_many_arguments)]
    fn level_crossing(
        &self,
        local: &Local,
        lt: &LevelTrack,
        ray: &Ray,
        a: Sample,
        b: Sample,
        te: f32,
        tx: f32,
    ) -> Option<(f32, Vec3)> {
        let d = ray.dir;
        let s = if self.opts.refine {
            self.refine_levels(local, lt, d, a, b)
        } else {
            let t = a.t + (b.t - a.t) * (a.g / (a.g - b.g));
            self.level_sample(local, lt, d, t, lambda_between(&a, &b, t))?
        };
        let ok = s.b.min_element() >= -EDGE_TOL
            && s.t >= te
            && s.t <= tx
            && s.t >= ray.t_min
            && s.t <= ray.t_max;
        ok.then_some((s.t, s.b))
    }

    /// Illinois regula falsi on the exact canonical `g(t)` in the bracket `[a, b]` (a sign
    /// change, so there is always a root); returns the end sample with the smaller `|g|`.
    #[allow(clippy::too_many_arguments)]
    fn refine_levels(
        &self,
        local: &Local,
        lt: &LevelTrack,
        d: Vec3,
        a: Sample,
        b: Sample,
    ) -> Sample {
        let (mut s0, mut s1) = (a, b);
        let (mut g0, mut g1) = (a.g, b.g);
        let tol_g = 1e-6 * local.f.scale;
        let tol_t = 1e-7 * (a.t.abs() + b.t.abs() + local.f.scale);
        let mut side = 0;
        for _ in 0..REFINE_ITERS {
            if s0.g.abs() <= tol_g || s1.g.abs() <= tol_g || (s1.t - s0.t).abs() <= tol_t {
                break;
            }
            let t = (s0.t * g1 - s1.t * g0) / (g1 - g0);
            let guess = lambda_between(&s0, &s1, t);
            let Some(s) = self.level_sample(local, lt, d, t, guess) else {
                break;
            };
            if (s.g > 0.0) == (s1.g > 0.0) {
                (s1, g1) = (s, s.g);
                if side == -1 {
                    g0 *= 0.5;
                }
                side = -1;
            } else {
                (s0, g0) = (s, s.g);
                if side == 1 {
                    g1 *= 0.5;
                }
                side = 1;
            }
        }
        if s0.g.abs().min(s1.g.abs()) > tol_g && (s1.t - s0.t).abs() <= tol_t {
            // The bracket shrank to f32's resolution of `t` with `g` still far from zero on
            // both sides: the surface is crossed between two neighbouring floats (a crease
            // strip's sliver at its `λ = 0` pole, where `b` jumps across the triangle from one
            // float to the next). The crossing is between the two samples: interpolated by `g`.
            return Self::between_floats(local, &s0, &s1);
        }
        if s0.g.abs() <= s1.g.abs() {
            s0
        } else {
            s1
        }
    }

    /// The crossing between two samples on either side of the surface at neighbouring ray
    /// parameters (`refine_levels`): `t`, the level and the homogeneous barycentrics
    /// (`inside_span`: smooth where `b` has a pole) interpolated by `g`.
    #[cold]
    #[inline(never)]
    fn between_floats(local: &Local, a: &Sample, b: &Sample) -> Sample {
        let w = a.g / (a.g - b.g);
        let (h0, h1) = (
            a.b * local.level_area(a.lambda),
            b.b * local.level_area(b.lambda),
        );
        let h = h0 + (h1 - h0) * w;
        let sum = h.x + h.y + h.z;
        let bw = if sum != 0.0 && h.is_finite() && sum.is_finite() {
            h / sum
        } else {
            a.b + (b.b - a.b) * w
        };
        Sample {
            t: a.t + (b.t - a.t) * w,
            g: 0.0,
            b: bw,
            lambda: a.lambda + (b.lambda - a.lambda) * w,
        }
    }

    /// Constant displacement `D`: meet the triangle `V_i + D n_i`, then Newton on
    /// `P(b) + D m̂(b) = o + t d` for `(b1, b2, t)`.
    fn flat_hit(&self, local: &Local, dval: f32, ro: Vec3, ray: &Ray) -> Option<(f32, Vec3)> {
        let g = &local.f.geom;
        let d = ray.dir;
        let q: [Vec3; 3] = std::array::from_fn(|i| g.v[i] + g.n[i] * dval);
        let (e1, e2) = (q[1] - q[0], q[2] - q[0]);
        let pv = d.cross(e2);
        let det = e1.dot(pv);
        if det == 0.0 {
            return None;
        }
        let tv = ro - q[0];
        let qv = tv.cross(e1);
        let mut b1 = tv.dot(pv) / det;
        let mut b2 = d.dot(qv) / det;
        let mut t = e2.dot(qv) / det;
        // The surface bulges past the flat triangle by D(1/|m| − 1): allow a margin, then
        // let Newton decide.
        if b1 < -0.25 || b2 < -0.25 || b1 + b2 > 1.25 || !t.is_finite() {
            return None;
        }
        let dp = [g.v[1] - g.v[0], g.v[2] - g.v[0]];
        let dm = [g.n[1] - g.n[0], g.n[2] - g.n[0]];
        let tol = 1e-6 * local.f.scale;
        let mut converged = false;
        for _ in 0..8 {
            let b = Vec3::new(1.0 - b1 - b2, b1, b2);
            let m = g.normal_dir(b);
            let len = m.length().max(1e-12);
            let mh = m / len;
            let f = g.position(b) + mh * dval - (ro + d * t);
            if f.length() <= tol {
                converged = true;
                break;
            }
            let ds = |k: usize| dp[k] + (dm[k] - mh * mh.dot(dm[k])) * (dval / len);
            let jac = Mat3::from_cols(ds(0), ds(1), -d);
            if jac.determinant().abs() < 1e-30 {
                return None;
            }
            let delta = jac.inverse() * f;
            b1 -= delta.x;
            b2 -= delta.y;
            t -= delta.z;
            if !(b1.is_finite() && b2.is_finite() && t.is_finite()) {
                return None;
            }
        }
        let b = Vec3::new(1.0 - b1 - b2, b1, b2);
        let ok = (converged || {
            let m = g.normal_dir(b);
            let f = g.position(b) + m.normalize_or_zero() * dval - (ro + d * t);
            f.length() <= 1e-4 * local.f.scale
        }) && b.min_element() >= -EDGE_TOL
            && t >= ray.t_min
            && t <= ray.t_max;
        ok.then_some((t, b))
    }
}

/// The part of a ray already marched in one prism (`[start, end]`, the latest prism whose cell
/// was marched). A cell's march detects every crossing of its *parent prism's* surface along
/// the part of the ray it covers (samples anywhere in the triangle count; `trace::cells`), so a
/// later cell of the same prism need only march what is left of its interval. Cells are
/// finished nearly front to back (`BoxBvh::closest_hit_ordered`), where the cells of a prism
/// that a ray crosses come one after another and their slab intervals overlap.
struct Covered {
    prism: u32,
    start: f32,
    end: f32,
}

impl Covered {
    const NONE: Covered = Covered {
        prism: u32::MAX,
        start: 0.0,
        end: 0.0,
    };

    /// What of the interval `[t0, t1]` of a cell of `prism` is still to march (`None`:
    /// nothing), recording that it will have been marched.
    #[inline]
    fn rest(&mut self, prism: u32, t0: f32, t1: f32) -> Option<(f32, f32)> {
        if prism == self.prism && t0 >= self.start && t0 <= self.end {
            if t1 <= self.end {
                return None;
            }
            self.end = t1;
            return Some((t0, t1));
        }
        *self = Covered {
            prism,
            start: t0,
            end: t1,
        };
        Some((t0, t1))
    }
}

impl Intersector for Pdm<'_> {
    fn name(&self) -> &'static str {
        "pdm"
    }

    fn intersect(&self, ray: &Ray, ctx: &RayContext) -> Option<Hit> {
        let mut steps = 0;
        let mut hit = match &self.cells {
            // Cells are marched front to back by where the ray enters their slabs.
            Some(cells) => {
                let mut covered = Covered::NONE;
                cells.bvh().closest_hit_ordered(
                    ray,
                    |r, i, _| {
                        let part = self.cell_part(&cells.cells[i as usize], r)?;
                        Some((part.t0(), part))
                    },
                    |r, i, part| {
                        let c = &cells.cells[i as usize];
                        // The best hit may have come nearer since the cell was entered.
                        let part = match part {
                            Part::Slabs(t0, t1) => {
                                let (t0, t1) = covered.rest(c.prism, t0, t1.min(r.t_max))?;
                                Part::Slabs(t0, t1)
                            }
                            Part::Exact(t0, t1) => Part::Exact(t0, t1.min(r.t_max)),
                            Part::Prism => Part::Prism,
                        };
                        self.intersect_part(r, ctx, c.prism, part, &mut steps)
                    },
                )
            }
            None => self.scene.closest_hit(ray, |r, prism| {
                self.intersect_prism(r, ctx, prism, &mut steps)
            }),
        }?;
        hit.steps = steps;
        self.fill_surface(&mut hit);
        Some(hit)
    }

    fn occluded(&self, ray: &Ray, ctx: &RayContext) -> bool {
        let mut steps = 0;
        match &self.cells {
            Some(cells) => cells.bvh().any_hit(ray, |r, i| {
                let c = &cells.cells[i as usize];
                self.cell_part(c, r).is_some_and(|part| {
                    self.intersect_part(r, ctx, c.prism, part, &mut steps)
                        .is_some()
                })
            }),
            None => self.scene.any_hit(ray, |r, prism| {
                self.intersect_prism(r, ctx, prism, &mut steps).is_some()
            }),
        }
    }

    /// The hierarchy (cells and their BVH, or the prism BVH), the prism records and the
    /// per-prism frames the march reads (base mesh and height map excluded).
    fn memory_bytes(&self) -> usize {
        let hierarchy = match &self.cells {
            Some(c) => c.bytes(),
            None => self.scene.bvh_bytes(),
        };
        hierarchy
            + self.scene.table.prisms.len() * std::mem::size_of::<Prism>()
            + self.frames.len() * std::mem::size_of::<Frame>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::fixtures::*;
    use crate::bake::PRISM_FLAT;
    use crate::heightmap::{HeightMap, Wrap};
    use crate::mesh::BaseMesh;

    use crate::test_util::{canonical_error_texels, rays_to_inner_points, Rng};

    fn ctx(pixel: u32, sample: u32) -> RayContext {
        RayContext {
            pixel,
            sample,
            bounce: 0,
            seed: 0,
        }
    }

    // Breaks if a cell were skipped that starts before the covered part, or belongs to another
    // prism, or reaches past it.
    #[test]
    fn barycentrics_of_a_sliver_are_solved_from_its_widest_corner() {
        // A crease strip's level triangle near its zero-length rung: 0.05 long, 4·10⁻⁵ wide.
        let (a, b) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.05, 0.01, 0.0));
        let c = [
            a,
            b + Vec3::new(0.0, 0.0, 2e-5),
            b - Vec3::new(0.0, 0.0, 2e-5),
        ];
        let truth = [0.3f64, 0.3, 0.4];
        let s = (0..3).fold(Vec3::ZERO, |acc, i| acc + c[i] * truth[i] as f32);
        let error = |apex: u8| {
            let got = triangle_barycentric(s, &c, apex);
            (0..3)
                .map(|i| (got[i] as f64 - truth[i]).abs())
                .fold(0.0, f64::max)
        };
        let widest = widest_corner(&c);
        assert_ne!(widest, 0, "the sharp corner is not the widest");
        assert!(
            error(widest) < 1e-3,
            "from the widest corner: {}",
            error(widest)
        );
        // From the sharp corner the Gram determinant cancels: what the strips' rays met.
        assert!(error(0) > 1e-2, "from the sharp corner: {}", error(0));
        // Every corner of a well-shaped triangle does.
        let fat = [Vec3::ZERO, Vec3::X, Vec3::new(0.3, 0.8, 0.1)];
        let s = fat[0] * 0.2 + fat[1] * 0.5 + fat[2] * 0.3;
        for apex in 0..3 {
            let got = triangle_barycentric(s, &fat, apex);
            assert!((got - Vec3::new(0.2, 0.5, 0.3)).abs().max_element() < 1e-6);
        }
    }

    #[test]
    fn covered_skips_only_cells_inside_an_earlier_march_of_their_prism() {
        let mut c = Covered::NONE;
        assert_eq!(c.rest(3, 1.0, 2.0), Some((1.0, 2.0)));
        assert_eq!(c.rest(3, 1.2, 1.9), None, "inside [1, 2] of prism 3");
        assert_eq!(c.rest(3, 1.5, 2.5), Some((1.5, 2.5)), "reaches past 2");
        assert_eq!(c.rest(3, 2.0, 2.4), None, "inside [1, 2.5] now");
        assert_eq!(c.rest(3, 0.5, 1.5), Some((0.5, 1.5)), "starts before 1");
        assert_eq!(c.rest(4, 0.6, 1.0), Some((0.6, 1.0)), "another prism");
        assert_eq!(
            c.rest(3, 0.7, 0.9),
            Some((0.7, 0.9)),
            "prism 3 again, its record gone"
        );
    }

    fn rays_through_centre(n: usize, size: f32, seed: u32) -> Vec<Ray> {
        rays_to_inner_points(n, size, seed)
            .into_iter()
            .map(|(r, _)| r)
            .collect()
    }

    // Would break if the march interval were not cut to the surface bounds: a prism whose λ range
    // is far larger than its |D| (as the clamped `M_LO_FLOOR` crease prisms were, ±23 on a
    // 3-unit rock) marched the whole hull of its walls, thousands of steps per ray.
    #[test]
    fn huge_lambda_ranges_do_not_lengthen_the_march() {
        let scene = sphere_scene(2, relief_map(64), 0.15, 1.0);
        let mut inflated = Scene::new(scene.table.clone(), scene.map.clone());
        for p in inflated.table.prisms.iter_mut() {
            p.lambda_lo -= 50.0;
            p.lambda_hi += 50.0;
        }
        let opts = PdmOptions {
            jitter: false,
            ..Default::default()
        };
        let (a, b) = (Pdm::new(&scene, opts), Pdm::new(&inflated, opts));
        let (mut steps_a, mut steps_b) = (0u64, 0u64);
        for (i, ray) in rays_through_centre(500, 1.0, 4).iter().enumerate() {
            let ha = a.intersect(ray, &ctx(i as u32, 0)).expect("closed sphere");
            let hb = b.intersect(ray, &ctx(i as u32, 0)).expect("closed sphere");
            assert!((ha.t - hb.t).abs() < 1e-4, "ray {i}: {} vs {}", ha.t, hb.t);
            steps_a += ha.steps as u64;
            steps_b += hb.steps as u64;
        }
        eprintln!("steps: {steps_a} with the baked λ, {steps_b} with λ ± 50");
        assert!(steps_b <= 2 * steps_a, "{steps_a} vs {steps_b}");
    }

    #[test]
    fn flat_map_hits_the_analytic_sphere() {
        // Constant D over an icosphere whose normals are its unit positions: m(b) = P(b), so
        // the canonical surface is x = P̂ (|P| + D) — exact, checked for the flat path (no
        // march) and for the march forced on the same prisms.
        let map = constant_map(0.8);
        let scene = sphere_scene(2, map, 0.1, 1.0);
        assert_eq!(scene.table.flat_count(), scene.table.prisms.len());
        let mut forced = Scene::new(scene.table.clone(), scene.map.clone());
        for p in forced.table.prisms.iter_mut() {
            p.flags &= !PRISM_FLAT;
        }
        let dval = 0.1 * (0.8 - 0.5);
        for s in [&scene, &forced] {
            let pdm = Pdm::new(s, PdmOptions::default());
            for (i, ray) in rays_through_centre(2000, 1.0, 11).iter().enumerate() {
                let hit = pdm
                    .intersect(ray, &ctx(i as u32, 0))
                    .expect("closed sphere");
                let g = PrismGeom::new(&s.table, &s.table.prisms[hit.prism as usize]);
                let base = g.position(hit.bary);
                let x = ray.at(hit.t);
                let want = base.normalize() * (base.length() + dval);
                assert!((x - want).length() < 1e-4, "{x} vs {want}");
                assert!((hit.position - x).length() < 1e-4);
                // Smooth sphere, constant D: both normals are the radial direction.
                assert!(hit.shading_normal.dot(x.normalize()) > 0.999);
            }
        }
    }

    /// Leaks of PDM with the given options (`test_util::leaks`).
    fn leaks(scene: &Scene, opts: PdmOptions, rays: &[(Ray, f32)]) -> usize {
        crate::test_util::leaks(&Pdm::new(scene, opts), rays)
    }

    #[test]
    fn closed_displaced_sphere_does_not_leak() {
        // The leak test of docs/watertightness.md: 10^5 rays through the centre of a closed
        // displaced sphere with irregular faces. Shared-wall prisms with canonical refinement
        // must let none through; the paper's parallel-offset prisms are reported (33 and 180
        // on the tilted assets when this was written; the scanning-sign march over shared walls
        // let 2 and 89 through, docs/watertightness.md).
        // The four spheres of `leak_spheres`, the same for every method.
        let rays = rays_to_inner_points(100_000, 1.0, 1);
        for (tilt, scene) in leak_spheres() {
            let shared = leaks(&scene, PdmOptions::default(), &rays);
            let whole = leaks(
                &scene,
                PdmOptions {
                    cells: false,
                    ..Default::default()
                },
                &rays,
            );
            let paper = leaks(
                &scene,
                PdmOptions {
                    construction: Construction::ParallelOffset,
                    ..Default::default()
                },
                &rays,
            );
            eprintln!(
                "{} faces, normal tilt {tilt}: leaks over {} rays: shared-wall+refine {shared}, \
                 parallel-offset {paper}",
                scene.table.prisms.len(),
                rays.len()
            );
            assert_eq!(shared, 0, "leaks through a closed surface");
            assert_eq!(whole, 0, "leaks through a closed surface (whole prisms)");
            assert!(tilt == 0.0 || paper > shared, "{paper}");
        }
    }

    #[test]
    fn rays_from_inside_hit_the_surface_from_below() {
        // Rays leaving the solid cross the surface from below; the hit is reported and the
        // geometric normal faces away from the ray (along it).
        let scene = sphere_scene(2, relief_map(64), 0.15, 1.0);
        let pdm = Pdm::new(&scene, PdmOptions::default());
        let mut rng = Rng(3);
        for i in 0..2000 {
            let ray = Ray::new(rng.unit() * 0.5 * rng.next(), rng.unit());
            let hit = pdm.intersect(&ray, &ctx(i, 0)).expect("from inside");
            assert!(hit.geometric_normal.dot(ray.dir) > 0.0);
            assert!(canonical_error_texels(&scene, &ray, &hit) < 1e-3);
        }
    }

    #[test]
    fn grazing_rays_keep_their_relative_error_across_scales() {
        // Rays within 1° of the base tangent plane, aimed at a point of the canonical surface,
        // on the same asset at sizes 1, 1e-3 and 1e4: every hit is finite and on the surface
        // (error in texels, so scale-free), and the share of rays stopped by nearer relief
        // or missed is the same at every size.
        let mut stats = vec![];
        for size in [1.0_f32, 1e-3, 1e4] {
            let scene = sphere_scene(2, relief_map(64), 0.15, size);
            let pdm = Pdm::new(&scene, PdmOptions::default());
            let mut rng = Rng(21);
            let (mut worst, mut reached, mut total) = (0.0_f32, 0, 0);
            for i in 0..3000u32 {
                let prism = (rng.next() * scene.table.prisms.len() as f32) as usize
                    % scene.table.prisms.len();
                let g = PrismGeom::new(&scene.table, &scene.table.prisms[prism]);
                let b = Vec3::new(rng.next() + 0.05, rng.next() + 0.05, rng.next() + 0.05);
                let b = b / (b.x + b.y + b.z);
                let sp = surface_point(&g, &scene.prism_displacement(prism as u32), b);
                let up = sp.base_normal;
                let tangent = up.cross(rng.unit()).normalize();
                let elev = (rng.next() * 2.0 - 1.0).to_radians();
                let d = (tangent * elev.cos() + up * elev.sin()).normalize();
                let dist = 0.2 * size;
                let ray = Ray::new(sp.position - d * dist, d);
                total += 1;
                if let Some(hit) = pdm.intersect(&ray, &ctx(i, 0)) {
                    assert!(hit.t.is_finite() && hit.position.is_finite());
                    assert!(hit.shading_normal.is_finite() && hit.bary.is_finite());
                    worst = worst.max(canonical_error_texels(&scene, &ray, &hit));
                    if hit.t <= dist * (1.0 + 1e-3) {
                        reached += 1;
                    }
                }
            }
            eprintln!("size {size}: worst {worst:.2e} texels, {reached}/{total} reached");
            assert!(worst < 1e-2, "size {size}: {worst}");
            stats.push(reached as f32 / total as f32);
        }
        assert!(
            stats
                .iter()
                .all(|&r| (r - stats[0]).abs() < 0.02 && r > 0.9),
            "{stats:?}"
        );
    }

    /// A unit plane (two triangles, normals +z, uv = xy) over a 32² clamp map at midlevel
    /// with one raised texel (column 10, row 16).
    fn spike_scene() -> Scene {
        let n = 32;
        let mut data = vec![0.5; n * n];
        data[16 * n + 10] = 1.0;
        let map = HeightMap::new(n as u32, n as u32, data, Wrap::Clamp);
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let mesh = BaseMesh {
            uvs: positions.iter().map(|p| Vec2::new(p.x, p.y)).collect(),
            normals: vec![Vec3::Z; 4],
            positions,
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            face_group: vec![0; 2],
            face_flags: vec![0; 2],
            ..Default::default()
        };
        let table = table(&mesh, &map, 0.1);
        Scene::new(table, map)
    }

    #[test]
    fn jitter_finds_a_spike_thinner_than_the_step() {
        // The spike is a bilinear tent 2 texels wide and 0.05 high. A horizontal ray at 90%
        // of its height meets it over 0.2 texel; samples one texel apart starting at the wall
        // x = 0 fall half a texel either side of the peak without jitter, every time. With
        // jitter, 64 frames (different `ctx.sample`) find it (probability 1 − 0.8^64).
        let scene = spike_scene();
        let texel = 1.0 / 32.0;
        let (x_peak, y_row) = (10.5 * texel, 15.5 * texel);
        let ray = Ray::new(Vec3::new(-0.5, y_row, 0.9 * 0.05), Vec3::X);
        let run = |jitter: bool| {
            let pdm = Pdm::new(
                &scene,
                PdmOptions {
                    dt: StepSize::World(texel),
                    jitter,
                    ..Default::default()
                },
            );
            (0..64)
                .filter_map(|s| pdm.intersect(&ray, &ctx(7, s)))
                .inspect(|h| assert!((h.position.x - x_peak).abs() < 0.11 * texel, "{h:?}"))
                .count()
        };
        assert_eq!(run(false), 0);
        assert!(run(true) >= 1);
    }

    #[test]
    fn march_error_shrinks_with_dt_and_refinement_removes_it() {
        // Without refinement the hit is the paper's linear interpolation of the crossing:
        // its distance from the canonical surface shrinks as dt falls. With refinement it is
        // at rounding level for every dt.
        let scene = sphere_scene(3, relief_map(64), 0.15, 1.0);
        let rays = rays_through_centre(3000, 1.0, 5);
        let mean_error = |dt: f32, refine: bool| {
            let pdm = Pdm::new(
                &scene,
                PdmOptions {
                    dt: StepSize::Auto(dt),
                    refine,
                    jitter: false,
                    ..Default::default()
                },
            );
            let errs: Vec<f32> = rays
                .iter()
                .filter_map(|r| {
                    pdm.intersect(r, &ctx(0, 0))
                        .map(|h| canonical_error_texels(&scene, r, &h))
                })
                .collect();
            assert!(errs.len() > rays.len() * 99 / 100);
            errs.iter().sum::<f32>() / errs.len() as f32
        };
        let coarse = mean_error(4.0, false);
        let medium = mean_error(1.0, false);
        let fine = mean_error(0.25, false);
        eprintln!("mean |λ|m| − D| in texels, no refine: dt 4: {coarse:.2e}, 1: {medium:.2e}, 0.25: {fine:.2e}");
        assert!(fine < medium && medium < coarse, "{coarse} {medium} {fine}");
        for dt in [4.0, 0.25] {
            let refined = mean_error(dt, true);
            eprintln!("refined, dt {dt}: {refined:.2e}");
            assert!(refined < 1e-4, "{refined}");
        }
    }

    #[test]
    fn hit_record_is_complete_and_memory_is_counted() {
        let scene = sphere_scene(2, relief_map(64), 0.15, 1.0);
        for mode in [NormalMode::Smooth, NormalMode::Geometric] {
            let pdm = Pdm::new(
                &scene,
                PdmOptions {
                    normal_mode: mode,
                    ..Default::default()
                },
            );
            assert_eq!(pdm.name(), "pdm");
            assert!(pdm.memory_bytes() >= scene.table.prisms.len() * 36);
            let ray = Ray::new(Vec3::new(0.1, 0.2, 3.0), -Vec3::Z);
            let hit = pdm.intersect(&ray, &ctx(0, 0)).unwrap();
            assert!(pdm.occluded(&ray, &ctx(0, 0)));
            assert!(hit.steps > 0);
            assert!((hit.shading_normal.length() - 1.0).abs() < 1e-4);
            assert!((hit.geometric_normal.length() - 1.0).abs() < 1e-4);
            assert!(hit.shading_normal.dot(Vec3::Z) > 0.5);
            assert!((hit.bary.element_sum() - 1.0).abs() < 1e-5);
            assert!((hit.position - ray.at(hit.t)).length() < 1e-5);
            if mode == NormalMode::Geometric {
                assert_eq!(hit.shading_normal, hit.geometric_normal);
            }
            let away = Ray::new(Vec3::new(0.0, 0.0, 3.0), Vec3::Z);
            assert!(pdm.intersect(&away, &ctx(0, 0)).is_none());
            assert!(!pdm.occluded(&away, &ctx(0, 0)));
        }
    }

    #[test]
    fn surfaces_at_shared_edges_canonical_meets_paper_steps() {
        // Why the paper's construction leaks: its surface P + D·unit(Σ b_i n_i/(n_i·N_g))
        // depends on the face's N_g, so two faces disagree along their common edge, while the
        // canonical P + D·m̂ agrees. Measured on the coarse test sphere, in texels.
        let mesh = tilt_normals(sphere_mesh(1, 0.3), 0.3);
        let map = relief_map(64);
        let scene = Scene::new(table(&mesh, &map, 0.6), map);
        let t = &scene.table;
        let mut edges: std::collections::HashMap<(u32, u32), Vec<usize>> = Default::default();
        for (f, p) in t.prisms.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (p.tri[k], p.tri[(k + 1) % 3]);
                edges.entry((a.min(b), a.max(b))).or_default().push(f);
            }
        }
        let (mut paper_step, mut canonical_step) = (0.0_f32, 0.0_f32);
        for ((va, vb), faces) in &edges {
            assert_eq!(faces.len(), 2, "closed mesh");
            for k in 0..=8 {
                let w = k as f32 / 8.0;
                let mut canon = [Vec3::ZERO; 2];
                let mut paper = [Vec3::ZERO; 2];
                for (slot, &f) in faces.iter().enumerate() {
                    let p = &t.prisms[f];
                    let g = PrismGeom::new(t, p);
                    let b = Vec3::from_array(p.tri.map(|i| {
                        if i == *va {
                            1.0 - w
                        } else if i == *vb {
                            w
                        } else {
                            0.0
                        }
                    }));
                    let sp = surface_point(&g, &scene.prism_displacement(f as u32), b);
                    canon[slot] = sp.position;
                    let ng = g.base_normal();
                    let a = g.n.map(|n| n / n.dot(ng));
                    let dir = (a[0] * b.x + a[1] * b.y + a[2] * b.z).normalize();
                    paper[slot] = g.position(b) + dir * sp.displacement;
                }
                let texel = t.prisms[faces[0]].texel_world;
                canonical_step = canonical_step.max((canon[0] - canon[1]).length() / texel);
                paper_step = paper_step.max((paper[0] - paper[1]).length() / texel);
            }
        }
        eprintln!("largest step across a shared edge: canonical {canonical_step:.1e} texels, paper {paper_step:.2e} texels");
        assert!(canonical_step < 1e-3);
        assert!(paper_step > 100.0 * canonical_step);
    }

    /// Regression: two rays (of 10^5) that passed through the 320-face sphere with tilted
    /// normals when the march detected crossings on the scanning (approximate) height and only
    /// refined on the canonical one. Both cross the canonical surface ~1e-4 past the wall
    /// of a prism they clip at a corner (interval ~0.006 long); the scanning sign had already
    /// flipped at that prism's entry, the canonical one had not at the neighbour's exit, so
    /// neither prism saw a sign change. The exact level-set march sees it.
    #[test]
    fn former_leaks_with_tilted_normals() {
        let mesh = tilt_normals(sphere_mesh(2, 0.3), 0.3);
        let map = relief_map(64);
        let scene = Scene::new(table(&mesh, &map, 0.15), map);
        let pdm = Pdm::new(&scene, PdmOptions::default());
        let rays = [
            (
                25760,
                Vec3::new(-1.8905144, -0.36751714, 2.3001924),
                Vec3::new(0.66299117, 0.05766392, -0.7464032),
            ),
            (
                49137,
                Vec3::new(2.0083191, 0.41006666, -2.1905475),
                Vec3::new(-0.7008182, -0.21714243, 0.67948735),
            ),
        ];
        for (pixel, o, d) in rays {
            let hit = pdm
                .intersect(&Ray::new(o, d), &ctx(pixel, 0))
                .expect("closed surface");
            assert!(hit.t < 2.7, "ray {pixel} passed the surface: t = {}", hit.t);
        }
    }

    /// Regression: three leak rays of `examples/rock` (`bench::leak_rays`, seed 0, rays 458,
    /// 5554 and 6417 of 10^5) that passed through regular prisms once the crease strips were
    /// in. Each grazes out of a prism through a wall just where the level planes fold: past
    /// the last sample with a level (`g > 0`), the exit sample has no level in range, so the
    /// sign change to `g < 0` was never seen and the next prism starts below the surface. The
    /// march now samples the edge of the region where a level exists.
    #[test]
    fn former_rock_leaks_at_a_grazing_exit() {
        let (scene, _) = crate::test_util::example_with_reference("rock/rock.glb");
        let pdm = Pdm::new(scene, PdmOptions::default());
        let rays = [
            (
                458,
                Vec3::new(-2.8676052, 2.628653, -1.1067853),
                Vec3::new(0.7025751, -0.7079846, -0.07173594),
                3.5975957,
            ),
            (
                5554,
                Vec3::new(0.27264884, -3.218831, -2.6625793),
                Vec3::new(-0.13171001, 0.9239466, 0.35913128),
                3.5975955,
            ),
            (
                6417,
                Vec3::new(1.8435394, -1.8580118, -3.6530547),
                Vec3::new(-0.5437362, 0.5496773, 0.63419694),
                3.5975957,
            ),
        ];
        for (pixel, origin, dir, t_max) in rays {
            let ray = Ray {
                origin,
                dir,
                t_min: 0.0,
                t_max,
            };
            let hit = pdm.intersect(&ray, &ctx(pixel, 0));
            assert!(hit.is_some(), "ray {pixel} passed through the rock");
        }
    }

    /// Regression: leak rays of the tests' seed through the slivers of the rock's crease strips,
    /// each found by one of the march's ways into a sliver: 1281 and 29 332 by the homogeneous
    /// barycentrics across the `λ = 0` pole (`inside_span`), 281 894 by the search between a
    /// sample just outside the triangle and one far outside (`Pdm::inside_sample`), 328 502
    /// by barycentrics solved from the level triangle's widest corner (`widest_corner`).
    #[test]
    fn rays_through_the_rock_strips_slivers_are_stopped() {
        rock_leak_rays_are_stopped(0x1ea4, &[1281, 29_332, 281_894, 328_502]);
    }

    /// Regression: a strict march (a cell's slabs) whose last sample lay past a wall, within
    /// `DETECT_TOL`, with the same sign as the sample inside before it: the surface continued
    /// past the wall hid a crossing inside the triangle (`Pdm::wall_sample`). Rays of the
    /// bench's and the tests' leak sets that ended inside the rock's solid (ray 285 485 past
    /// the corner of a vertex's fan: prism 466's slab exit at b = (−0.0008, −0.0018, 1.0026)).
    #[test]
    fn crossings_before_a_wall_sampled_past_are_found() {
        rock_leak_rays_are_stopped(0, &[77_262, 184_506, 285_485, 671_890]);
        rock_leak_rays_are_stopped(0x1ea4, &[298_170, 529_736]);
    }

    /// Regression: a strict march whose every sample lay outside the triangle (within
    /// `DETECT_TOL`) on a ghost level, while the other level holds the crossing inside; it
    /// is redone on the exact interval. A ray of the bench's leak set that ended inside the
    /// rock's solid.
    #[test]
    fn strict_marches_that_never_meet_the_triangle_are_redone_exactly() {
        rock_leak_rays_are_stopped(0, &[674_471]);
    }

    /// Regression: an entry on the exact interval whose first level lay far outside the
    /// prism's λ range with the point inside its triangle (a ghost the `b` test accepts); the
    /// march stayed on it, below the surface, and never crossed. The level in the range
    /// continues the neighbour's (`Pdm::entry_sample`). A ray of the tests' leak set that
    /// ended inside the rock's solid.
    #[test]
    fn entries_take_a_level_in_the_prisms_range() {
        rock_leak_rays_are_stopped(0x1ea4, &[864_980]);
    }

    /// Regression: rays that pass through a fold or ridge of the rock's surface thinner than
    /// a step (mostly at stitched seams): four samples on one side, falling into a gap and
    /// rising out of it, with no sign change (`Pdm::dip_probe`). Four rays of the bench's
    /// leak set (seed 0) that the reference (k = 2), RMIP and the nonlinear method hit, and
    /// PDM did not; the hit lies where a march at a tenth of the step finds it.
    #[test]
    fn folds_thinner_than_a_step_are_probed() {
        let indices = [5264, 130_250, 368_546, 487_821];
        rock_leak_rays_are_stopped(0, &indices);
        rock_leak_rays_hit_where_the_fine_march_does(&indices, |i| ctx(i as u32, 0));
    }

    /// Two rock leak rays of seed 0 (as pixel 0, the GPU test's centre rays) whose first
    /// crossing is a fold thinner than a step, 4.1 and 22.7 texels before the k = 2
    /// reference's hit (which misses the fold too; the nonlinear method and a march at a
    /// twentieth of the step find it). The march's samples fall towards the surface and step
    /// over it; cut to where the line through the last two meets the surface
    /// (`Pdm::approaching`), the next sample lands in the fold.
    #[test]
    fn approaches_cut_their_step_to_the_secant() {
        rock_leak_rays_hit_where_the_fine_march_does(&[10_160, 22_768], |_| ctx(0, 0));
    }

    /// Rock leak ray 707 579 of seed 0 grazes the surface across a prism boundary: in prism
    /// 318 `g` reads 0.036 texel, rising, and the next sample a step on lies past a dip 0.53
    /// steps long and 0.028 texel deep (no sign change, no falling samples for the secant or
    /// the dip probe). Near the surface a step is at most |g| / `NEAR_SLOPE`. Rays 2654 and
    /// 25 286 (as pixel 0, the GPU test's centre rays) stepped over thin folds the same way
    /// and hit 3.6 and 7.9 texels further on (the k = 2 reference misses those folds too; the
    /// k = 8 one and a march at a twenty-fifth of the step find them).
    #[test]
    fn grazes_just_above_the_surface_take_shorter_steps() {
        rock_leak_rays_hit_where_the_fine_march_does(&[707_579], |i| ctx(i as u32, 0));
        rock_leak_rays_hit_where_the_fine_march_does(&[2654, 25_286], |_| ctx(0, 0));
    }

    /// PDM (defaults) hits each of the rock's leak rays `indices` of seed 0 (traced with the
    /// context `ctx_of(index)`) within 0.05 texel of a march at a twentieth of the step.
    fn rock_leak_rays_hit_where_the_fine_march_does(
        indices: &[usize],
        ctx_of: impl Fn(usize) -> RayContext,
    ) {
        let (scene, _) = crate::test_util::example_with_reference("rock/rock.glb");
        let pdm = Pdm::new(scene, PdmOptions::default());
        let fine = Pdm::new(
            scene,
            PdmOptions {
                dt: StepSize::Auto(0.05),
                jitter: false,
                ..Default::default()
            },
        );
        let n = indices.iter().max().map_or(0, |&i| i + 1);
        let rays = crate::bench::leak_rays(scene, n, 0);
        for &i in indices {
            let c = ctx_of(i);
            let hit = pdm.intersect(&rays[i], &c).expect("hit");
            let truth = fine.intersect(&rays[i], &c).expect("the fine march hits");
            let texel = scene.table.prisms[truth.prism as usize].texel_world;
            assert!(
                (hit.t - truth.t).abs() <= 0.05 * texel,
                "ray {i}: PDM at t {} against the fine march's {} ({} texels)",
                hit.t,
                truth.t,
                (hit.t - truth.t) / texel
            );
        }
    }

    /// Regression: rock leak ray 693 287 of seed 0 (ending inside the solid) enters a crease
    /// strip's sliver around its `λ = 0` pole, where `b` sweeps across the triangle within a
    /// few ulps of `t` (b₀ from −1.9 to 0.11 in 8 ulps): no sample lands just outside the
    /// boundary, and the crossing between the wall and the first sample inside was lost
    /// (`Pdm::wall_crossing`).
    #[test]
    fn crossings_between_a_wall_and_the_next_ulp_are_found() {
        rock_leak_rays_are_stopped(0, &[693_287]);
    }

    /// Regression: rock leak ray 942 906 of seed 0 (ending inside the solid) passes the corner
    /// of crease strip 785 where its zero-length rung collapses the level triangles (`λ` ≈
    /// 0.0003): between two neighbouring floats of `t`, `g` jumps from +0.0044 to −0.0029 and
    /// `b₀` from +0.045 to −0.045, so the refinement's bracket shrinks to rounding with
    /// neither end on the surface, and its end sample lay outside the triangle
    /// (`Pdm::between_floats`).
    #[test]
    fn crossings_between_two_floats_are_interpolated() {
        rock_leak_rays_are_stopped(0, &[942_906]);
    }

    /// PDM (defaults) hits each of the rock's leak rays `indices` of `seed`
    /// (`bench::leak_rays`, with the ray index as the pixel and context seed 0: the bench's
    /// and `leak_probe`'s jitter for the rays of seed 0).
    fn rock_leak_rays_are_stopped(seed: u32, indices: &[usize]) {
        let (scene, _) = crate::test_util::example_with_reference("rock/rock.glb");
        let pdm = Pdm::new(scene, PdmOptions::default());
        let n = indices.iter().max().map_or(0, |&i| i + 1);
        let rays = crate::bench::leak_rays(scene, n, seed);
        for &i in indices {
            let hit = pdm.intersect(&rays[i], &ctx(i as u32, 0));
            assert!(
                hit.is_some(),
                "ray {i} of seed {seed:#x} passed through the rock"
            );
        }
    }

    /// Regression: where a rock prism folds, the entry on its wall also lies on a ghost level
    /// that misses the triangle by less than `DETECT_TOL`, and the march stayed on it
    /// (`ENTRY_TOL`). Two of the bench's leak rays (seed 0), ending inside the solid.
    #[test]
    fn entries_on_a_folded_wall_take_the_level_inside() {
        rock_leak_rays_are_stopped(0, &[750_213, 840_067]);
    }

    /// Regression: the rock's crease strips. Their relief once was the atlas between two UV
    /// islands squeezed into the rounded edge, and two leak rays crossed a dip of it within
    /// one `dt` (`bake::inserted_texel_world` now measures the step on the displaced strip).
    /// Rays aimed at points of every strip must find the reference's strip hits, at its `t`.
    #[test]
    fn rays_at_the_rock_strips_hit_where_the_reference_does() {
        let (scene, reference) = crate::test_util::example_with_reference("rock/rock.glb");
        let pdm = Pdm::new(scene, PdmOptions::default());
        crate::test_util::assert_strip_hits_match_reference(scene, reference, &pdm);
    }

    #[test]
    fn entry_on_a_ghost_level_is_retried() {
        // A rock leak ray (bench::leak_rays, 2·10⁵ rays, seed 0, ray 102 832) enters prism 331
        // where the level cubic's Newton, from the scanning estimate, lands on a ghost root
        // (λ ≈ −0.046, b.z ≈ −0.29); every later sample followed that branch and the crossing
        // at b.z ≈ 0.0097 was skipped at any dt. `entry_sample` retries the entry level.
        let (scene, _) = crate::test_util::example_with_reference("rock/rock.glb");
        let i = 102_832;
        let ray = crate::bench::leak_rays(scene, 200_000, 0)[i];
        let ctx = RayContext {
            pixel: i as u32,
            ..Default::default()
        };
        for dt in [0.5, 0.05] {
            let pdm = Pdm::new(
                scene,
                PdmOptions {
                    dt: StepSize::Auto(dt),
                    ..Default::default()
                },
            );
            let hit = pdm.intersect(&ray, &ctx).expect("the ray hits");
            assert_eq!(hit.prism, 331, "dt {dt}");
            assert!(canonical_error_texels(scene, &ray, &hit) < 1e-3, "dt {dt}");
        }
    }

    /// Marching cells instead of whole prisms changes where the march samples, not the
    /// surface: on the examples (seam bands, crease strips with their squeezed relief, tilted
    /// normals) the two agree on all but a few rays (near-tangent grazes and the strips' thin
    /// spikes, which the two sample differently), every hit that differs is on the surface,
    /// cells are no further from the reference than whole prisms, and they take fewer steps.
    /// Would fail if a cell's bounds or the march's triangle-edge samples lost surface.
    #[test]
    fn cells_trace_the_surface_of_whole_prisms() {
        use crate::render::camera::Camera;
        for (name, max_differ) in [("sphere/sphere.glb", 3), ("rock/rock.glb", 20)] {
            let (scene, reference) = crate::test_util::example_with_reference(name);
            let cells = Pdm::new(scene, PdmOptions::default());
            let whole = Pdm::new(
                scene,
                PdmOptions {
                    cells: false,
                    ..Default::default()
                },
            );
            let (lo, hi) = scene.table.bounds();
            let cam = Camera::frame_bounds(lo, hi, crate::mesh::UpAxis::Y, 40.0, 1.0);
            let res = 160;
            let (mut differ, mut hits, mut steps_cells, mut steps_whole) = (0, 0, 0u64, 0u64);
            let (mut off_cells, mut off_whole) = (0, 0);
            let same = |a: Option<Hit>, b: Option<Hit>| match (a, b) {
                (None, None) => true,
                (Some(x), Some(y)) => (x.t - y.t).abs() <= 1e-4 * y.t,
                _ => false,
            };
            for i in 0..res * res {
                let px = Vec2::new((i % res) as f32 + 0.5, (i / res) as f32 + 0.5);
                let ray = cam.ray(px, res, res);
                let c = ctx(i, 0);
                let (a, b) = (cells.intersect(&ray, &c), whole.intersect(&ray, &c));
                let r = reference.intersect(&ray, &c);
                steps_cells += a.map_or(0, |h| h.steps as u64);
                steps_whole += b.map_or(0, |h| h.steps as u64);
                hits += b.is_some() as u32;
                // Against the reference, at a looser tolerance (its chords are 1/k texel).
                let near = |h: Option<Hit>| match (h, r) {
                    (None, None) => true,
                    (Some(x), Some(y)) => (x.t - y.t).abs() <= 2e-3 * y.t,
                    _ => false,
                };
                off_cells += !near(a) as u32;
                off_whole += !near(b) as u32;
                if !same(a, b) {
                    differ += 1;
                    if let Some(x) = a {
                        let gap = (ray.at(x.t) - x.position).length();
                        assert!(gap < 1e-5 * x.t, "{name}: pixel {i}: {gap} off the surface");
                    }
                }
            }
            eprintln!(
                "{name}: {hits} hits, {differ} differ; off the reference: cells {off_cells}, \
                 whole {off_whole}; steps cells {steps_cells}, whole {steps_whole}"
            );
            assert!(hits > 1000, "{name}: {hits}");
            assert!(differ <= max_differ, "{name}: {differ} rays differ");
            assert!(
                off_cells <= off_whole + 2,
                "{name}: {off_cells} vs {off_whole}"
            );
            assert!(steps_cells < steps_whole, "{name}");
        }
    }
}
