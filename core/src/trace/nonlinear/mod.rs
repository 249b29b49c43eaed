//! Nonlinear rays (Ogaki 2023, "Nonlinear Ray Tracing for Displacement and Shell Mapping",
//! SIGGRAPH Asia): per prism, the ray becomes a rational quadratic curve `(x(λ), y(λ), λ)` in
//! texture space (§4.1–4.2, `curve`), a min-max mipmap of the map is traversed with exact
//! curve–box tests (§4.4, `minmax`, `Curve::box_intervals`), and each texel's two
//! micro-triangles are met by solving a cubic in `λ` (§4.3) with Yuksel's solver (`cubic`, f32
//! with FMA or f64: `Precision`). The TLAS is the shared prism BVH (`accel::Scene`); the prism
//! entry/exit (`prism_hit`, shared-wall walls) bounds `t` for every root (range reduction,
//! §5.4). Root selection (§5.4): traversal starts at the coarsest level where the triangle's
//! texel footprint fits 2 × 2 nodes, and every node box is clipped to that footprint.
//!
//! **Reconciling the shell with the canonical surface.** Ogaki's shell `S_i(h) = P_i + h N_i`
//! is DESIGN.md's shared-wall prism with `h = λ` and `N_i = n_i` (unnormalised interpolation),
//! and his surface is `λ = D(uv)`. The canonical surface is `λ |m(b)| = D(uv(b))`. So each
//! micro-triangle is taken in `(x, y, D)` space and met where `λ |m(b)| = D_lin(x, y)`:
//! * `|m(b)|` is replaced by its tangent plane `Σ b_i (m̂*·n_i)` at a point `b*` (exact at
//!   `b*`, `|m|` being homogeneous of degree 1 in `b`). Then `λ Σ μ_i w_i(λ) = N(λ)` is still
//!   a cubic in `λ` — Ogaki's plane equation with his constant `n_h` replaced by a linear
//!   function of `b`. It is solved with `b*` at the middle of the curve's span in the cell,
//!   then again with `b*` at the root found, so the root lies on `λ|m(b)| = D_lin` up to a
//!   second-order term. That surface is continuous across cells and prisms (`m(b)` and
//!   `uv(b)` agree on a shared edge);
//! * a first attempt with `|m|` frozen at the span's middle leaked (3 in 2·10⁴ rays on the
//!   coarse test sphere, f32 and f64 alike: the frozen value differs between neighbouring
//!   cells, which opens slits for rays crossing the surface right at a cell edge). So, when
//!   no cubic root is accepted on a span whose two ends lie on opposite sides of the exact
//!   detection surface (`g_exact`), Illinois regula falsi on `g_exact` finds the crossing.
//!   Neighbouring spans share their end values, so no crossing can fall between them;
//! * `refine` (default on) then moves the hit along the ray onto the exact canonical surface
//!   (bilinear `D` instead of the two planes of the cell): a secant iteration on
//!   `g(λ) = λ|m(b(λ))| − D_bilinear(x(λ), y(λ))`. If it fails (leaves the triangle or the
//!   prism interval) the detection hit is kept, so refinement never opens a hole.
//!
//! Other departures from the paper, each for a stated reason:
//! * the curve is written with symmetric signed areas (`curve` module doc), not eq. 6 with a
//!   pivot vertex — the same rational function, no choice of basis enters it;
//! * a curve–box test returns the exact `λ` intervals inside the box (roots of the four face
//!   quadratics and of the denominator, midpoint tests), not just "does it cross a face";
//!   children are visited in increasing `t` of their first interval, and a node is culled
//!   when that `t` is beyond the closest hit so far (inside one prism `t(λ)` is monotonic:
//!   each layer is a plane, which the ray meets once);
//! * the paper's `h_in`/`h_out` range reduction is replaced by the per-node `λ` bounds (the
//!   mipmap's `D` range over `|m| ∈ [m_lo, 1]`, `bake::lambda_range`) and the `t` interval:
//!   `λ` need not be monotone between the two ends of the hull that `prism_hit` returns;
//! * flat nodes (min = max, paper §5.4 "LODs") are one plane `λ|m| = D` over the whole node;
//! * normals: `Canonical` (default) evaluates `canonical::surface_point` at the hit's `b`
//!   like every other method; `Adjugate` is the paper's eq. 13, `adj(M)ᵀ ∇F` with
//!   `M = [E_0(λ), E_1(λ), m(b)]` and `F = λ|m(b)| − D`, the `|m|` term differentiated too,
//!   so it is the canonical surface's normal without a matrix inverse.
//!
//! * next to stitched UV seams (`seam`) the height is the stitched `D*`: a mipmap node that
//!   reaches a seam band has its range widened by the band's (`PrismStitch::band_h`), and a
//!   leaf there is searched on the exact `λ|m(b)| − D*(b)` (`stitched_leaf`) instead of the
//!   cell's two planes.
//!
//! UV-degenerate base triangles (the paper's Fig. 4) need nothing special: `b(λ)` comes from
//! world-space geometry and `(x, y)` is only its affine image, so a triangle whose UVs
//! collapse to a line or a point still yields a curve (on that line or point) and roots.

// `!(a < b)` is deliberate throughout: it is also true for NaN, which must be rejected.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod cubic;
pub mod curve;
pub mod minmax;
pub mod real;
#[cfg(test)]
mod tests;

use crate::accel::Scene;
use crate::bake::{lambda_range, mean_normal_lower_bound, Prism};
use crate::canonical::{surface_point, PrismGeom};
use crate::seam::{PrismDisplacement, PrismStitch};
use crate::trace::prism_hit::{clip_to_surface_bounds, ray_prism_interval};
use crate::trace::{Hit, Intersector, NormalMode, Ray, RayContext};
use cubic::cubic_roots;
use curve::{Curve, Intervals};
use glam::{Vec2, Vec3};
use minmax::MinMaxMip;
use real::{Real, V3};

/// Accepted slack of a hit's barycentrics outside its base triangle: neighbours overlap by a
/// hair instead of leaving a crack for rays through their common wall.
const EDGE_TOL: f64 = 1e-5;
/// Slack of a root's texel position outside its cell / triangle half (texels).
const CELL_TOL: f64 = 1e-4;
/// Shared-wall `t` interval widening, relative to the prism's longest edge.
const INTERVAL_PAD: f32 = 1e-4;
/// Sign tests per curve span in a leaf next to a seam band (`Nonlinear::stitched_leaf`).
const STITCHED_SAMPLES: usize = 16;
/// Fixed stack: ≤ 3 siblings waiting per level plus the 4 roots.
const STACK: usize = 4 + 3 * 64;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Precision {
    /// `f32` with explicit FMA everywhere (the paper's default).
    #[default]
    F32,
    /// `f64` throughout the per-prism work (the paper's Fig. 8 fix for slipping rays).
    F64,
}

impl std::str::FromStr for Precision {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "f32" => Ok(Precision::F32),
            "f64" => Ok(Precision::F64),
            _ => Err(format!("unknown precision '{s}' (expected f32 or f64)")),
        }
    }
}

/// Where the hit's geometric normal comes from (see the module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum NormalSource {
    #[default]
    Canonical,
    Adjugate,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NonlinearOptions {
    pub precision: Precision,
    /// Move the micro-triangle hit onto the canonical (bilinear) surface.
    pub refine: bool,
    pub normal_mode: NormalMode,
    pub normals: NormalSource,
}

impl Default for NonlinearOptions {
    fn default() -> Self {
        NonlinearOptions {
            precision: Precision::F32,
            refine: true,
            normal_mode: NormalMode::Smooth,
            normals: NormalSource::Canonical,
        }
    }
}

pub struct Nonlinear<'a> {
    scene: &'a Scene,
    mip: MinMaxMip,
    opts: NonlinearOptions,
}

/// What a prism test keeps of its closest root (for refinement and the adjugate normal).
#[derive(Clone, Copy, Debug)]
struct Cand<T> {
    t: T,
    b: [T; 3],
    l: T,
    /// Displacement at the cell corners (00, 10, 01, 11); all equal for a flat node.
    d: [T; 4],
    /// The cell's origin in local texel coordinates.
    cell: (T, T),
    /// Which half of the cell (`fx ≥ fy`), or `None` for a flat node.
    lower: Option<bool>,
    /// The hit's position within its cell.
    f: (T, T),
}

/// A tested node: level, absolute block indices, the curve's `λ` intervals inside its box,
/// the smallest `t` at their ends, and its raw map range.
#[derive(Clone, Copy)]
struct Node<T> {
    k: u32,
    ix: i64,
    iy: i64,
    key: T,
    iv: Intervals<T>,
    h: (f32, f32),
}

/// The stitched height of a prism next to UV seams (`seam`): its evaluator, its bands, and
/// the affine map from local texel coordinates to barycentrics (`None` for UV-degenerate
/// faces, where every box counts as reaching a band).
struct StitchRay<'s> {
    disp: PrismDisplacement<'s>,
    rec: &'s PrismStitch,
    to_b: Option<[f64; 6]>,
}

impl StitchRay<'_> {
    /// Some point of the texel box `bx × by` may lie in a band (affine `b`: box corners).
    fn touches<T: Real>(&self, bx: (T, T), by: (T, T)) -> bool {
        let Some(m) = self.to_b else { return true };
        [(bx.0, by.0), (bx.1, by.0), (bx.0, by.1), (bx.1, by.1)]
            .iter()
            .any(|&(x, y)| {
                let (x, y) = (x.to_f64(), y.to_f64());
                let b1 = m[0] * x + m[1] * y + m[2];
                let b2 = m[3] * x + m[4] * y + m[5];
                self.rec
                    .in_band(Vec3::new((1.0 - b1 - b2) as f32, b1 as f32, b2 as f32))
            })
    }
}

/// Per-prism, per-ray state.
struct PrismRay<'s, T> {
    curve: Curve<T>,
    stitch: Option<StitchRay<'s>>,
    /// Footprint bbox in local texel coordinates, and its origin cell (absolute).
    fx: (T, T),
    fy: (T, T),
    cell0: (i64, i64),
    m_lo: f32,
    lam: (T, T),
    lam_pad: T,
    t_range: (T, T),
}

impl<'a> Nonlinear<'a> {
    pub fn new(scene: &'a Scene, opts: NonlinearOptions) -> Self {
        Nonlinear {
            scene,
            mip: MinMaxMip::new(&scene.map),
            opts,
        }
    }

    pub fn options(&self) -> &NonlinearOptions {
        &self.opts
    }

    #[inline]
    fn disp<T: Real>(&self, h: f32) -> T {
        T::of32(self.scene.table.params.displacement(h))
    }

    /// Closest root in one prism with `t < ray.t_max`, as (t, barycentrics, extra data).
    fn prism_hit<T: Real>(&self, ray: &Ray, prism: u32, steps: &mut u32) -> Option<Cand<T>> {
        let table = &self.scene.table;
        let p = &table.prisms[prism as usize];
        let [i0, i1, i2] = p.tri.map(|i| i as usize);
        let origin = table.positions[i0];
        let v = [
            Vec3::ZERO,
            table.positions[i1] - origin,
            table.positions[i2] - origin,
        ];
        let n = [table.normals[i0], table.normals[i1], table.normals[i2]];
        let scale = v[1].length().max(v[2].length()).max((v[2] - v[1]).length());
        let ro = ray.origin - origin;
        // Range reduction: the ray's hull inside the shared-wall prism.
        let lo: [Vec3; 3] = std::array::from_fn(|i| v[i] + n[i] * p.lambda_lo);
        let hi: [Vec3; 3] = std::array::from_fn(|i| v[i] + n[i] * p.lambda_hi);
        let pad = INTERVAL_PAD * scale.max(f32::MIN_POSITIVE);
        // Cut to where the surface can be first (a big λ range does not mean a long search,
        // and most candidate prisms are rejected here, before the walls).
        let reach = p.d_min.abs().max(p.d_max.abs()) + pad;
        let (t0, t1) = clip_to_surface_bounds(ro, ray.dir, ray.t_min, ray.t_max, &v, reach)?;
        let iv = ray_prism_interval(ro, ray.dir, t0, t1, &lo, &hi)?;
        let (te, tx) = ((iv.t_enter - pad).max(t0), (iv.t_exit + pad).min(t1));
        let t_range = (T::of32(te), T::of32(tx));
        // Texel footprint (shifted texel coordinates: cell (i, j) is [i, i+1] × [j, j+1]).
        let (w, h) = (self.scene.map.width as f64, self.scene.map.height as f64);
        let tex_abs = p.tri.map(|i| {
            let uv = table.uvs[i as usize];
            (uv.x as f64 * w - 0.5, (1.0 - uv.y as f64) * h - 0.5)
        });
        let fp = 1e-3;
        let xmin = tex_abs.iter().map(|t| t.0).fold(f64::INFINITY, f64::min) - fp;
        let xmax = tex_abs
            .iter()
            .map(|t| t.0)
            .fold(f64::NEG_INFINITY, f64::max)
            + fp;
        let ymin = tex_abs.iter().map(|t| t.1).fold(f64::INFINITY, f64::min) - fp;
        let ymax = tex_abs
            .iter()
            .map(|t| t.1)
            .fold(f64::NEG_INFINITY, f64::max)
            + fp;
        if !(xmin.is_finite() && xmax.is_finite() && ymin.is_finite() && ymax.is_finite()) {
            return None;
        }
        let cell0 = (xmin.floor() as i64, ymin.floor() as i64);
        let cell1 = (xmax.floor() as i64, ymax.floor() as i64);
        let tex = tex_abs.map(|t| (t.0 - cell0.0 as f64, t.1 - cell0.1 as f64));
        let lam_pad = T::of32(1e-5 * scale + 1e-4 * (p.lambda_hi - p.lambda_lo));
        let stitch = self.scene.stitch().get(prism).map(|rec| {
            let (e1, e2) = (
                (tex[1].0 - tex[0].0, tex[1].1 - tex[0].1),
                (tex[2].0 - tex[0].0, tex[2].1 - tex[0].1),
            );
            let det = e1.0 * e2.1 - e2.0 * e1.1;
            let to_b = (det.abs() > 1e-12).then(|| {
                let (a, b, c, d) = (e2.1 / det, -e2.0 / det, -e1.1 / det, e1.0 / det);
                [
                    a,
                    b,
                    -(a * tex[0].0 + b * tex[0].1),
                    c,
                    d,
                    -(c * tex[0].0 + d * tex[0].1),
                ]
            });
            StitchRay {
                disp: self.scene.prism_displacement(prism),
                rec,
                to_b,
            }
        });
        let pr = PrismRay {
            curve: Curve::new(ro, ray.dir, &v, &n, &tex),
            stitch,
            fx: (T::of(xmin - cell0.0 as f64), T::of(xmax - cell0.0 as f64)),
            fy: (T::of(ymin - cell0.1 as f64), T::of(ymax - cell0.1 as f64)),
            cell0,
            m_lo: mean_normal_lower_bound(&n),
            lam: (
                T::of32(p.lambda_lo) - lam_pad,
                T::of32(p.lambda_hi) + lam_pad,
            ),
            lam_pad,
            t_range,
        };
        // Root selection: the coarsest level whose 2 × 2 blocks hold the footprint.
        let mut k = 0u32;
        while k < 62 && ((cell1.0 >> k) - (cell0.0 >> k) > 1 || (cell1.1 >> k) - (cell0.1 >> k) > 1)
        {
            k += 1;
        }
        let mut best: Option<Cand<T>> = None;
        let mut best_t = t_range.1;
        let mut stack = [None::<Node<T>>; STACK];
        let mut sp = 0;
        let mut kids = [None::<Node<T>>; 4];
        let mut nk = 0;
        for iy in (cell0.1 >> k)..=(cell1.1 >> k) {
            for ix in (cell0.0 >> k)..=(cell1.0 >> k) {
                *steps += 1;
                if let Some(nd) = self.test_node(&pr, k, ix, iy) {
                    kids[nk] = Some(nd);
                    nk += 1;
                }
            }
        }
        push_sorted(&mut stack, &mut sp, &mut kids, nk);
        while sp > 0 {
            sp -= 1;
            let node = stack[sp].take().unwrap();
            if !(node.key < best_t) {
                continue;
            }
            if node.k == 0 || node.h.0 == node.h.1 {
                if let Some(c) = self.leaf(&pr, &node, best_t, steps) {
                    best_t = c.t;
                    best = Some(c);
                }
                continue;
            }
            nk = 0;
            for (dy, dx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                *steps += 1;
                if let Some(nd) =
                    self.test_node(&pr, node.k - 1, 2 * node.ix + dx, 2 * node.iy + dy)
                {
                    if nd.key < best_t {
                        kids[nk] = Some(nd);
                        nk += 1;
                    }
                }
            }
            push_sorted(&mut stack, &mut sp, &mut kids, nk);
        }
        let c = best?;
        Some(if self.opts.refine {
            self.refine(&pr, c).unwrap_or(c)
        } else {
            c
        })
    }

    /// Curve–box test of block `(ix, iy)` at level `k`, its box clipped to the footprint.
    fn test_node<T: Real>(&self, pr: &PrismRay<T>, k: u32, ix: i64, iy: i64) -> Option<Node<T>> {
        let s = 1i64 << k;
        let bx = (
            T::of(((ix * s) - pr.cell0.0) as f64).max(pr.fx.0),
            T::of((((ix + 1) * s) - pr.cell0.0) as f64).min(pr.fx.1),
        );
        let by = (
            T::of(((iy * s) - pr.cell0.1) as f64).max(pr.fy.0),
            T::of((((iy + 1) * s) - pr.cell0.1) as f64).min(pr.fy.1),
        );
        if !(bx.0 <= bx.1 && by.0 <= by.1) {
            return None;
        }
        let mut h = self.mip.range(k as usize, ix, iy);
        if let Some(st) = &pr.stitch {
            if st.touches(bx, by) {
                h = (h.0.min(st.rec.band_h.0), h.1.max(st.rec.band_h.1));
            }
        }
        let (dmin, dmax) = self.scene.table.params.displacement_range(h.0, h.1);
        let (la, lb) = lambda_range(dmin, dmax, pr.m_lo);
        let l0 = (T::of32(la) - pr.lam_pad).max(pr.lam.0);
        let l1 = (T::of32(lb) + pr.lam_pad).min(pr.lam.1);
        let pad = T::of(CELL_TOL);
        let iv = pr
            .curve
            .box_intervals((bx.0 - pad, bx.1 + pad), (by.0 - pad, by.1 + pad), l0, l1);
        if iv.n == 0 {
            return None;
        }
        let mut key = T::INFINITY;
        for &(a, b) in &iv.iv[..iv.n] {
            for l in [a, b] {
                let t = pr.curve.t_at(&pr.curve.bary(l), l);
                key = if t.is_finite() {
                    key.min(t)
                } else {
                    -T::INFINITY
                };
            }
        }
        Some(Node {
            k,
            ix,
            iy,
            key,
            iv,
            h,
        })
    }

    /// Micro-triangles of a level-0 cell, or one constant plane for a flat node.
    fn leaf<T: Real>(
        &self,
        pr: &PrismRay<T>,
        node: &Node<T>,
        best_t: T,
        steps: &mut u32,
    ) -> Option<Cand<T>> {
        let cell = (
            T::of((node.ix - pr.cell0.0) as f64),
            T::of((node.iy - pr.cell0.1) as f64),
        );
        if let Some(st) = &pr.stitch {
            let one = T::ONE;
            if st.touches((cell.0, cell.0 + one), (cell.1, cell.1 + one)) {
                return self.stitched_leaf(pr, st, node, cell, best_t, steps);
            }
        }
        let (d, halves): ([T; 4], &[Option<bool>]) = if node.h.0 == node.h.1 {
            ([self.disp(node.h.0); 4], &[None])
        } else {
            let map = &self.scene.map;
            let (x, y) = (node.ix, node.iy);
            (
                [
                    self.disp(map.texel(x, y)),
                    self.disp(map.texel(x + 1, y)),
                    self.disp(map.texel(x, y + 1)),
                    self.disp(map.texel(x + 1, y + 1)),
                ],
                &[Some(true), Some(false)],
            )
        };
        let mut best: Option<Cand<T>> = None;
        let mut best_t = best_t;
        for &(a, b) in &node.iv.iv[..node.iv.n] {
            let mut found = false;
            for &lower in halves {
                *steps += 1;
                let c = Cand {
                    t: T::ZERO,
                    b: [T::ZERO; 3],
                    l: T::ZERO,
                    d,
                    cell,
                    lower,
                    f: (T::ZERO, T::ZERO),
                };
                if let Some(h) = self.micro_triangle(pr, c, a, b, best_t) {
                    best_t = h.t;
                    best = Some(h);
                    found = true;
                }
            }
            if !found {
                let c = Cand {
                    t: T::ZERO,
                    b: [T::ZERO; 3],
                    l: T::ZERO,
                    d,
                    cell,
                    lower: halves[0],
                    f: (T::ZERO, T::ZERO),
                };
                if let Some(h) = self.bracket_root(pr, &c, a, b, best_t) {
                    best_t = h.t;
                    best = Some(h);
                }
            }
        }
        best
    }

    /// A leaf that reaches a seam band: the detection surface there is the micro-triangles
    /// stitched like the canonical height (`PrismDisplacement::at_by` over `micro_height`), so
    /// it meets the plain micro-triangles of the neighbouring cells and prisms without a slit.
    /// Each curve span is searched for sign changes of `λ|m(b)| − D*_micro(b)` at
    /// `STITCHED_SAMPLES` equal steps, each refined by Illinois regula falsi (a crossing pair
    /// closer than a step is missed, as in RMIP's march), then moved onto the exact stitched
    /// surface by the same secant step as `refine`.
    ///
    /// Testing the span's two ends alone let a ray of the example sphere through (the closed
    /// example meshes' test, ray 67437): next to a pole-fan seam the stitched surface dips
    /// below the ray for a tenth of a cell's span, right at the wall between two prisms. The
    /// span of the prism that holds the dip reached past the wall, where the ray is above the
    /// surface again, so both its ends were above; the neighbour's span found the crossing
    /// 1.3·10⁻⁴ outside its own triangle.
    #[allow(clippy::too_many_arguments)]
    fn stitched_leaf<T: Real>(
        &self,
        pr: &PrismRay<T>,
        st: &StitchRay,
        node: &Node<T>,
        cell: (T, T),
        best_t: T,
        steps: &mut u32,
    ) -> Option<Cand<T>> {
        let micro = |uv: Vec2| self.micro_height(uv);
        let g = |l: T| {
            let b = pr.curve.bary(l);
            let bv = Vec3::new(b[0].to_f32(), b[1].to_f32(), b[2].to_f32());
            l * pr.curve.m_len(&b) - T::of32(st.disp.at_by(bv, micro))
        };
        let c = Cand {
            t: T::ZERO,
            b: [T::ZERO; 3],
            l: T::ZERO,
            d: [T::ZERO; 4],
            cell,
            lower: None,
            f: (T::ZERO, T::ZERO),
        };
        let mut best: Option<Cand<T>> = None;
        let mut best_t = best_t;
        for &(a, b) in &node.iv.iv[..node.iv.n] {
            *steps += 1;
            let (mut l0, mut g0) = (a, g(a));
            for j in 1..=STITCHED_SAMPLES {
                let l1 = if j == STITCHED_SAMPLES {
                    b
                } else {
                    a + (b - a) * T::of(j as f64 / STITCHED_SAMPLES as f64)
                };
                let g1 = g(l1);
                let crossed = (g0 < T::ZERO) != (g1 < T::ZERO);
                let span = (l0, l1);
                (l0, g0) = (l1, g1);
                if !crossed {
                    continue;
                }
                let Some(l) = illinois(g, span.0, span.1) else {
                    continue;
                };
                if let Some(h) = self.accept(pr, &c, l, best_t) {
                    let h = if self.opts.refine {
                        self.refine_stitched(pr, st, h).unwrap_or(h)
                    } else {
                        h
                    };
                    best_t = h.t;
                    best = Some(h);
                }
            }
        }
        best
    }

    /// The map as the micro-triangles see it (displacement at `uv`): each texel cell of the
    /// shifted texel grid split along its diagonal into the two planes of `plane`.
    fn micro_height(&self, uv: Vec2) -> f32 {
        let map = &self.scene.map;
        let x = uv.x as f64 * map.width as f64 - 0.5;
        let y = (1.0 - uv.y as f64) * map.height as f64 - 0.5;
        if !(x.is_finite() && y.is_finite()) {
            return self.disp::<f32>(map.texel(0, 0));
        }
        let (cx, cy) = (x.floor().clamp(-1e9, 1e9), y.floor().clamp(-1e9, 1e9));
        let (fx, fy) = ((x - cx) as f32, (y - cy) as f32);
        let (ix, iy) = (cx as i64, cy as i64);
        let d00 = self.disp::<f32>(map.texel(ix, iy));
        let d10 = self.disp::<f32>(map.texel(ix + 1, iy));
        let d01 = self.disp::<f32>(map.texel(ix, iy + 1));
        let d11 = self.disp::<f32>(map.texel(ix + 1, iy + 1));
        if fx >= fy {
            d00 + (d10 - d00) * fx + (d11 - d10) * fy
        } else {
            d00 + (d11 - d01) * fx + (d01 - d00) * fy
        }
    }

    /// `refine` for a stitched leaf's hit: secant steps on `λ|m(b)| − D*(b)` with the exact
    /// (bilinear) stitched height; `None` (keep the detection hit) if it wanders off.
    fn refine_stitched<T: Real>(
        &self,
        pr: &PrismRay<T>,
        st: &StitchRay,
        c: Cand<T>,
    ) -> Option<Cand<T>> {
        let g = |l: T| {
            let b = pr.curve.bary(l);
            let bv = Vec3::new(b[0].to_f32(), b[1].to_f32(), b[2].to_f32());
            l * pr.curve.m_len(&b) - T::of32(st.disp.at(bv))
        };
        let span = (pr.lam.1 - pr.lam.0).abs().max(pr.lam_pad);
        let l1 = secant(g, c.l, span)?;
        if !((l1 - c.l).abs() <= span * T::of(0.25)) {
            return None;
        }
        self.accept(
            pr,
            &c,
            l1,
            pr.t_range.1 + (pr.t_range.1 - pr.t_range.0) * T::of(1e-3),
        )
    }

    /// The plane of one cell half in `(x, y, D)`: `D = D00 + a (x − cx) + c (y − cy)`.
    #[inline]
    fn plane<T: Real>(c: &Cand<T>) -> (T, T) {
        let [d00, d10, d01, d11] = c.d;
        match c.lower {
            None => (T::ZERO, T::ZERO),
            Some(true) => (d10 - d00, d11 - d10),
            Some(false) => (d11 - d01, d01 - d00),
        }
    }

    /// Roots of `λ (m̂*·m(b(λ))) = D_lin(x(λ), y(λ))` on `[a, b]`, cleared of the denominator
    /// `W`: `λ Σ μ_i w_i(λ) = N(λ)`, a cubic. `μ_i = m̂*·n_i` is the tangent plane of `|m(b)|`
    /// at the expansion point (exact there, `|m|` being homogeneous of degree 1 in `b`).
    #[inline]
    fn solve<T: Real>(
        pr: &PrismRay<T>,
        c: &Cand<T>,
        mu: &[T; 3],
        a: T,
        b: T,
        out: &mut [T; 3],
    ) -> usize {
        let (ga, gc) = Self::plane(c);
        let cv = &pr.curve;
        let k0 = c.d[0] - ga * c.cell.0 - gc * c.cell.1;
        let num: [T; 3] =
            std::array::from_fn(|p| k0.fma(cv.wsum[p], ga.fma(cv.xq[p], gc * cv.yq[p])));
        let m: [T; 3] = std::array::from_fn(|p| {
            mu[0].fma(cv.w[0][p], mu[1].fma(cv.w[1][p], mu[2] * cv.w[2][p]))
        });
        let coef = [num[0], num[1] - m[0], num[2] - m[1], -m[2]];
        let span = (b - a).abs().max(pr.lam_pad);
        let x_err = span * T::EPS * T::of(64.0);
        cubic_roots(&coef, a - pr.lam_pad, b + pr.lam_pad, x_err, out)
    }

    /// `λ|m(b(λ))| − D_lin(x(λ), y(λ))` on the curve: the detection surface without any
    /// frozen or linearised `|m|` (the half of the cell is chosen by the point itself).
    #[inline]
    fn g_exact<T: Real>(pr: &PrismRay<T>, c: &Cand<T>, l: T) -> T {
        let b = pr.curve.bary(l);
        let (x, y) = pr.curve.tex(l);
        let (fx, fy) = (x - c.cell.0, y - c.cell.1);
        let [d00, d10, d01, d11] = c.d;
        let dv = match c.lower {
            None => d00,
            Some(_) if fx >= fy => d00 + (d10 - d00) * fx + (d11 - d10) * fy,
            Some(_) => d00 + (d11 - d01) * fx + (d01 - d00) * fy,
        };
        l * pr.curve.m_len(&b) - dv
    }

    /// Tangent coefficients `μ_i = m̂·n_i` at the curve point `λ` (unit normal if degenerate).
    #[inline]
    fn tangent_mu<T: Real>(pr: &PrismRay<T>, l: T) -> Option<[T; 3]> {
        let b = pr.curve.bary(l);
        let n = &pr.curve.n;
        let m = n[0].scale(b[0]) + n[1].scale(b[1]) + n[2].scale(b[2]);
        let len = m.length();
        if !(len.is_finite() && len > T::of(1e-6)) {
            return None;
        }
        let mh = m.scale(T::ONE / len);
        Some([mh.dot(n[0]), mh.dot(n[1]), mh.dot(n[2])])
    }

    /// Fallback when no cubic root was accepted on a span whose ends lie on opposite sides
    /// of the exact detection surface: Illinois regula falsi on `g_exact`. This is what
    /// makes the detection surface crack-free between cells whatever the linearisation error.
    fn bracket_root<T: Real>(
        &self,
        pr: &PrismRay<T>,
        c: &Cand<T>,
        a: T,
        b: T,
        t_max: T,
    ) -> Option<Cand<T>> {
        let l = illinois(|l| Self::g_exact(pr, c, l), a, b)?;
        let (x, y) = pr.curve.tex(l);
        let lower = c.lower.map(|_| x - c.cell.0 >= y - c.cell.1);
        self.accept(pr, &Cand { lower, ..*c }, l, t_max)
    }

    /// Validate a root: finite, in the base triangle, in its cell half (or node box), `t` in
    /// range. Returns the candidate with `t` and `b` filled.
    #[inline]
    fn accept<T: Real>(&self, pr: &PrismRay<T>, c: &Cand<T>, l: T, t_max: T) -> Option<Cand<T>> {
        let b = pr.curve.bary(l);
        let tol = T::of(EDGE_TOL);
        if !(b[0] >= -tol && b[1] >= -tol && b[2] >= -tol) {
            return None;
        }
        let (x, y) = pr.curve.tex(l);
        let (fx, fy) = (x - c.cell.0, y - c.cell.1);
        let ct = T::of(CELL_TOL);
        if let Some(lower) = c.lower {
            if !(fx >= -ct && fx <= T::ONE + ct && fy >= -ct && fy <= T::ONE + ct) {
                return None;
            }
            if (lower && fx < fy - ct) || (!lower && fy < fx - ct) {
                return None;
            }
        }
        let t = pr.curve.t_at(&b, l);
        (t >= pr.t_range.0 && t < t_max).then_some(Cand {
            t,
            b,
            l,
            f: (fx, fy),
            ..*c
        })
    }

    /// Closest root on one micro-triangle over the curve span `[a, b]`, with `|m|` linearised
    /// at the span's middle, then re-linearised at the root (module doc).
    fn micro_triangle<T: Real>(
        &self,
        pr: &PrismRay<T>,
        c: Cand<T>,
        a: T,
        b: T,
        t_max: T,
    ) -> Option<Cand<T>> {
        let mu0 = Self::tangent_mu(pr, T::HALF * (a + b))?;
        let mut roots = [T::ZERO; 3];
        let n = Self::solve(pr, &c, &mu0, a, b, &mut roots);
        let mut best: Option<Cand<T>> = None;
        let mut t_best = t_max;
        for &r in &roots[..n] {
            // Re-linearise at the root; keep the new root nearest the first one.
            let r = match Self::tangent_mu(pr, r) {
                Some(mu1) => {
                    let mut again = [T::ZERO; 3];
                    let m = Self::solve(pr, &c, &mu1, a, b, &mut again);
                    let mut pick = r;
                    let mut dist = T::INFINITY;
                    for &s in &again[..m] {
                        if (s - r).abs() < dist {
                            dist = (s - r).abs();
                            pick = s;
                        }
                    }
                    pick
                }
                None => r,
            };
            if let Some(h) = self.accept(pr, &c, r, t_best) {
                t_best = h.t;
                best = Some(h);
            }
        }
        best
    }

    /// Secant iteration on `g(λ) = λ|m(b(λ))| − D_bilinear(x(λ), y(λ))` from the hit.
    fn refine<T: Real>(&self, pr: &PrismRay<T>, c: Cand<T>) -> Option<Cand<T>> {
        c.lower?;
        let [d00, d10, d01, d11] = c.d;
        let g = |l: T| {
            let b = pr.curve.bary(l);
            let (x, y) = pr.curve.tex(l);
            let (fx, fy) = (x - c.cell.0, y - c.cell.1);
            let top = d00 + (d10 - d00) * fx;
            let bottom = d01 + (d11 - d01) * fx;
            let dv = top + (bottom - top) * fy;
            l * pr.curve.m_len(&b) - dv
        };
        let span = (pr.lam.1 - pr.lam.0).abs().max(pr.lam_pad);
        let l1 = secant(g, c.l, span)?;
        // The refined point must stay near its cell (a root of the neighbour's patch is the
        // neighbour's business) and pass the usual checks.
        if !((l1 - c.l).abs() <= span * T::of(0.25)) {
            return None;
        }
        let loose = Cand { lower: None, ..c };
        let (x, y) = pr.curve.tex(l1);
        let (fx, fy) = (x - c.cell.0, y - c.cell.1);
        let m = T::of(0.01);
        if !(fx >= -m && fx <= T::ONE + m && fy >= -m && fy <= T::ONE + m) {
            return None;
        }
        let h = self.accept(
            pr,
            &loose,
            l1,
            pr.t_range.1 + (pr.t_range.1 - pr.t_range.0) * T::of(1e-3),
        )?;
        Some(Cand {
            lower: c.lower,
            ..h
        })
    }

    /// The paper's eq. 13 normal of the canonical surface at a candidate (module doc).
    fn adjugate_normal<T: Real>(&self, prism: &Prism, c: &Cand<T>) -> Vec3 {
        let table = &self.scene.table;
        let [i0, i1, i2] = prism.tri.map(|i| i as usize);
        let v = [i0, i1, i2].map(|i| V3::<T>::of(table.positions[i]));
        let n = [i0, i1, i2].map(|i| V3::<T>::of(table.normals[i]));
        let (w, h) = (self.scene.map.width as f64, self.scene.map.height as f64);
        let tex = [i0, i1, i2].map(|i| {
            let uv = table.uvs[i];
            (T::of(uv.x as f64 * w), T::of(-(uv.y as f64) * h))
        });
        let b = c.b;
        let m = n[0].scale(b[0]) + n[1].scale(b[1]) + n[2].scale(b[2]);
        let mu = m.length();
        let mh = m.scale(T::ONE / mu);
        // ∂D/∂x, ∂D/∂y at the hit: the bilinear patch's gradient (zero on a flat node).
        let [d00, d10, d01, d11] = c.d;
        let (gx, gy) = match c.lower {
            None => (T::ZERO, T::ZERO),
            Some(_) => {
                let (fx, fy) = c.f;
                (
                    (d10 - d00) * (T::ONE - fy) + (d11 - d01) * fy,
                    (d01 - d00) * (T::ONE - fx) + (d11 - d10) * fx,
                )
            }
        };
        // Texel coordinates: x = u W − ½, y = (1 − v) H − ½, so ∂x/∂b_i = u_i W, ∂y/∂b_i = −v_i H.
        let dx = [tex[1].0 - tex[0].0, tex[2].0 - tex[0].0];
        let dy = [tex[1].1 - tex[0].1, tex[2].1 - tex[0].1];
        let dn = [n[1] - n[0], n[2] - n[0]];
        let f_a = c.l * mh.dot(dn[0]) - (gx * dx[0] + gy * dy[0]);
        let f_b = c.l * mh.dot(dn[1]) - (gx * dx[1] + gy * dy[1]);
        let f_l = mu;
        let c0 = (v[1] - v[0]) + dn[0].scale(c.l);
        let c1 = (v[2] - v[0]) + dn[1].scale(c.l);
        let c2 = m;
        let nw = c1.cross(c2).scale(f_a) + c2.cross(c0).scale(f_b) + c0.cross(c1).scale(f_l);
        let det = c0.dot(c1.cross(c2));
        let nw = if det < T::ZERO { nw.scale(-T::ONE) } else { nw };
        nw.to_vec3().normalize_or_zero()
    }

    fn trace<T: Real>(&self, ray: &Ray) -> Option<Hit> {
        let mut steps = 0;
        let mut extra: Option<(u32, Cand<T>)> = None;
        let mut hit = self.scene.closest_hit(ray, |r, prism| {
            let c = self.prism_hit::<T>(r, prism, &mut steps)?;
            let t = c.t.to_f32();
            if !(t < r.t_max) {
                return None;
            }
            extra = Some((prism, c));
            Some(Hit {
                t,
                prism,
                bary: Vec3::new(c.b[0].to_f32(), c.b[1].to_f32(), c.b[2].to_f32()),
                uv: Vec2::ZERO,
                position: ray.at(t),
                geometric_normal: Vec3::ZERO,
                shading_normal: Vec3::ZERO,
                steps: 0,
            })
        })?;
        hit.steps = steps;
        let table = &self.scene.table;
        let p = &table.prisms[hit.prism as usize];
        let sp = surface_point(
            &PrismGeom::new(table, p),
            &self.scene.prism_displacement(hit.prism),
            hit.bary,
        );
        hit.uv = sp.uv;
        let (geo, smooth) = match (self.opts.normals, extra) {
            // The adjugate form differentiates the cell's planes: not the stitched height.
            (NormalSource::Adjugate, Some((prism, c)))
                if prism == hit.prism && self.scene.stitch().get(prism).is_none() =>
            {
                let ng = PrismGeom::new(table, p).base_normal();
                let na = self.adjugate_normal(p, &c);
                let na = if na == Vec3::ZERO {
                    sp.geometric_normal
                } else {
                    na
                };
                (na, (na - ng + sp.base_normal).try_normalize().unwrap_or(na))
            }
            _ => (sp.geometric_normal, sp.smooth_normal),
        };
        hit.geometric_normal = geo;
        hit.shading_normal = match self.opts.normal_mode {
            NormalMode::Smooth => smooth,
            NormalMode::Geometric => geo,
        };
        Some(hit)
    }
}

/// Illinois regula falsi on `g` over `[a, b]`, whose ends must lie on opposite sides (else
/// `None`): the middle of the final bracket.
fn illinois<T: Real>(g: impl Fn(T) -> T, a: T, b: T) -> Option<T> {
    let (mut l0, mut l1) = (a, b);
    let (mut g0, mut g1) = (g(l0), g(l1));
    if (g0 < T::ZERO) == (g1 < T::ZERO) || !(g0.is_finite() && g1.is_finite()) {
        return None;
    }
    let tol = (b - a).abs() * T::EPS * T::of(64.0);
    let mut side = 0;
    for _ in 0..60 {
        if (l1 - l0).abs() <= tol {
            break;
        }
        let mut l = (l0 * g1 - l1 * g0) / (g1 - g0);
        if !(l > l0.min(l1) && l < l0.max(l1)) {
            l = T::HALF * (l0 + l1);
        }
        let gl = g(l);
        if gl == T::ZERO {
            (l0, l1) = (l, l);
            break;
        }
        if (gl < T::ZERO) == (g1 < T::ZERO) {
            (l1, g1) = (l, gl);
            if side == -1 {
                g0 = g0 * T::HALF;
            }
            side = -1;
        } else {
            (l0, g0) = (l, gl);
            if side == 1 {
                g1 = g1 * T::HALF;
            }
            side = 1;
        }
    }
    Some(T::HALF * (l0 + l1))
}

/// Secant iterations on `g` from `l` (second point a thousandth of `span` on), at most 8:
/// the last iterate, `None` if one is not finite.
fn secant<T: Real>(g: impl Fn(T) -> T, l: T, span: T) -> Option<T> {
    let tol = span * T::EPS * T::of(16.0);
    let (mut l0, mut l1) = (l, l + span * T::of(1e-3));
    let (mut g0, mut g1) = (g(l0), g(l1));
    for _ in 0..8 {
        if g1 == g0 {
            break;
        }
        let l2 = l1 - g1 * (l1 - l0) / (g1 - g0);
        if !l2.is_finite() {
            return None;
        }
        (l0, g0) = (l1, g1);
        l1 = l2;
        g1 = g(l1);
        if (l1 - l0).abs() <= tol {
            break;
        }
    }
    Some(l1)
}

/// Push up to four tested children so that the one with the smallest `key` is popped first.
fn push_sorted<T: Real>(
    stack: &mut [Option<Node<T>>; STACK],
    sp: &mut usize,
    kids: &mut [Option<Node<T>>; 4],
    n: usize,
) {
    let key = |k: &Option<Node<T>>| k.as_ref().map_or(T::INFINITY, |n| n.key);
    for i in 1..n {
        let mut j = i;
        while j > 0 && key(&kids[j - 1]) < key(&kids[j]) {
            kids.swap(j - 1, j);
            j -= 1;
        }
    }
    for kid in kids.iter_mut().take(n) {
        if *sp < STACK {
            stack[*sp] = kid.take();
            *sp += 1;
        }
    }
}

impl Intersector for Nonlinear<'_> {
    fn name(&self) -> &'static str {
        "nonlinear"
    }

    fn intersect(&self, ray: &Ray, _ctx: &RayContext) -> Option<Hit> {
        match self.opts.precision {
            Precision::F32 => self.trace::<f32>(ray),
            Precision::F64 => self.trace::<f64>(ray),
        }
    }

    fn occluded(&self, ray: &Ray, _ctx: &RayContext) -> bool {
        let mut steps = 0;
        self.scene
            .any_hit(ray, |r, prism| match self.opts.precision {
                Precision::F32 => self.prism_hit::<f32>(r, prism, &mut steps).is_some(),
                Precision::F64 => self.prism_hit::<f64>(r, prism, &mut steps).is_some(),
            })
    }

    /// BVH nodes and leaf indices, the prism records, and the min-max mipmap.
    fn memory_bytes(&self) -> usize {
        self.scene.bvh_bytes()
            + self.scene.table.prisms.len() * std::mem::size_of::<Prism>()
            + self.mip.bytes()
    }
}
