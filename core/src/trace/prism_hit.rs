//! Ray vs prism: the parameter interval where a ray is inside one prism.
//!
//! A prism here is any solid `{Σ b_i (lo_i + s (hi_i − lo_i)) : b in the triangle, s ∈ [0, 1]}`
//! given by its six corners: planar caps `lo` and `hi`, and three walls that are bilinear
//! patches between a bottom edge and the matching top edge. Both constructions fit:
//! DESIGN.md's shared-wall prism (`lo_i = V_i + λlo n_i`, `hi_i = V_i + λhi n_i`,
//! `PrismTable::shared_wall_corners`) and the paper's parallel-offset prism (§4,
//! `PrismTable::parallel_offset_corners`).
//!
//! Walls follow Reshetov 2019 ("Cool Patches", Ray Tracing Gems ch. 8; pbrt-v4's
//! `IntersectBilinearPatch` reads the same way): for a patch `Q(u, s) = L(u) + s E(u)` the ray
//! meets the ruling line at `u` iff `det(L(u) − o, d, E(u)) = 0`, a quadratic in `u`, solved
//! with the cancellation-free form and an FMA difference of products for the discriminant.
//! Each crossing is classified by the outward normal as an entry or an exit (paper eq. 8).
//! Walls may be curved, so a ray can enter and leave more than once: we return the hull
//! `[first entry, last exit]` and leave samples outside the triangle to the marcher.
//! Departures from the paper: the hull replaces the paper's single min/max, a ray starting
//! inside (first crossing an exit) gets `t_enter = t_min`, and crossings are searched on the
//! whole half-line so that a short ray wholly inside is recognised without a point test.

use glam::Vec3;

/// Barycentric / patch-parameter slack so a ray through an edge or corner between two faces
/// is seen by at least one of them (seen twice is harmless for a hull).
const PARAM_EPS: f32 = 1e-5;

/// Inside interval of a ray in a prism, clipped to the ray's `[t_min, t_max]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    pub t_enter: f32,
    pub t_exit: f32,
}

/// `a·b − c·d` with one rounding error less (Kahan's algorithm via FMA; pbrt-v4 util/math.h).
#[inline]
pub fn difference_of_products(a: f32, b: f32, c: f32, d: f32) -> f32 {
    let cd = c * d;
    let err = (-c).mul_add(d, cd);
    let dop = a.mul_add(b, -cd);
    dop + err
}

/// Real roots of `a x² + b x + c = 0` (`r0 <= r1` when both are finite), without the
/// cancellation of the textbook formula. Degenerate `a` gives one finite and one infinite
/// root; callers filter roots by range, so infinities and NaN are simply never in range.
#[inline]
pub fn quadratic(a: f32, b: f32, c: f32) -> Option<(f32, f32)> {
    if a == 0.0 {
        if b == 0.0 {
            return None;
        }
        let r = -c / b;
        return Some((r, r));
    }
    let discrim = difference_of_products(b, b, 4.0 * a, c);
    if discrim < 0.0 {
        return None;
    }
    let root = discrim.sqrt();
    let q = -0.5 * (b + root.copysign(b));
    let (r0, r1) = if q == 0.0 {
        // b == 0 and c == 0: double root at zero.
        (0.0, 0.0)
    } else {
        (q / a, c / q)
    };
    Some(if r0 <= r1 { (r0, r1) } else { (r1, r0) })
}

/// Running record of boundary crossings: earliest/latest entry and exit.
#[derive(Clone, Copy)]
struct Crossings {
    first_entry: f32,
    last_entry: f32,
    first_exit: f32,
    last_exit: f32,
}

impl Crossings {
    fn new() -> Self {
        Crossings {
            first_entry: f32::INFINITY,
            last_entry: f32::NEG_INFINITY,
            first_exit: f32::INFINITY,
            last_exit: f32::NEG_INFINITY,
        }
    }
    #[inline]
    fn add(&mut self, t: f32, outward_dot_dir: f32) {
        if outward_dot_dir < 0.0 {
            self.first_entry = self.first_entry.min(t);
            self.last_entry = self.last_entry.max(t);
        } else if outward_dot_dir > 0.0 {
            self.first_exit = self.first_exit.min(t);
            self.last_exit = self.last_exit.max(t);
        }
        // Exactly tangent (dot == 0): touches without crossing.
    }
    fn any(&self) -> bool {
        self.first_entry.is_finite() || self.first_exit.is_finite()
    }
}

/// Ray vs triangle `(p0, p1, p2)` with slack on the edges; reports `t` and the orientation of
/// `sign * (p1−p0)×(p2−p0)` against the ray.
#[inline]
fn cap(o: Vec3, d: Vec3, t_min: f32, t_max: f32, p: &[Vec3; 3], sign: f32, acc: &mut Crossings) {
    let e1 = p[1] - p[0];
    let e2 = p[2] - p[0];
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det == 0.0 {
        return;
    }
    let inv = 1.0 / det;
    let tv = o - p[0];
    let b1 = tv.dot(pv) * inv;
    if !(-PARAM_EPS..=1.0 + PARAM_EPS).contains(&b1) {
        return;
    }
    let qv = tv.cross(e1);
    let b2 = d.dot(qv) * inv;
    if b2 < -PARAM_EPS || b1 + b2 > 1.0 + PARAM_EPS {
        return;
    }
    let t = e2.dot(qv) * inv;
    if t >= t_min && t <= t_max {
        acc.add(t, sign * e1.cross(e2).dot(d));
    }
}

/// Ray vs the bilinear wall `Q(u, s) = (1−s) lerp(a, b, u) + s lerp(c, e, u)`, bottom edge
/// `a→b`, top edge `c→e`; `∂Q/∂u × ∂Q/∂s` points out of the prism for a counter-clockwise base.
#[inline]
#[allow(clippy::too_many_arguments)]
fn wall(
    o: Vec3,
    d: Vec3,
    t_min: f32,
    t_max: f32,
    a: Vec3,
    b: Vec3,
    c: Vec3,
    e: Vec3,
    acc: &mut Crossings,
) {
    let q0 = a - o;
    let q1 = b - o;
    let eb = b - a;
    let e0 = c - a;
    let e1 = e - b;
    // f(u) = det(q(u), d, E(u)) with q(u) = q0 + u eb, E(u) = e0 + u (e1 − e0).
    let f0 = q0.cross(d).dot(e0);
    let f1 = q1.cross(d).dot(e1);
    let c2 = d.dot((e1 - e0).cross(eb));
    let c1 = f1 - f0 - c2;
    let Some((u0, u1)) = quadratic(c2, c1, f0) else {
        return;
    };
    for (k, u) in [u0, u1].into_iter().enumerate() {
        if k == 1 && u1 == u0 {
            break;
        }
        if !(-PARAM_EPS..=1.0 + PARAM_EPS).contains(&u) {
            continue;
        }
        let q = q0 + eb * u;
        let ed = e0 + (e1 - e0) * u;
        let n = d.cross(ed);
        let n2 = n.dot(n);
        if n2 == 0.0 {
            continue; // ray parallel to the ruling line
        }
        // o + t d = L(u) + s E(u)  ⇒  s = (q × d)·n / |n|², t = (q × E)·n / |n|².
        let s = q.cross(d).dot(n) / n2;
        if !(-PARAM_EPS..=1.0 + PARAM_EPS).contains(&s) {
            continue;
        }
        let t = q.cross(ed).dot(n) / n2;
        if t >= t_min && t <= t_max {
            let du = eb + ((e - c) - eb) * s;
            acc.add(t, du.cross(ed).dot(d));
        }
    }
}

/// Is `x` inside the prism? Newton on `Σ b_i (lo_i + s (hi_i − lo_i)) = x` for `(b1, b2, s)`.
/// A slow, robust point test for callers and tests (the interval itself does not need it).
pub fn point_in_prism(x: Vec3, lo: &[Vec3; 3], hi: &[Vec3; 3]) -> bool {
    let e = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    let scale = (lo[1] - lo[0]).length() + (lo[2] - lo[0]).length() + e[0].length();
    let (mut b1, mut b2, mut s) = (1.0 / 3.0, 1.0 / 3.0, 0.5_f32);
    for _ in 0..24 {
        let b0 = 1.0 - b1 - b2;
        let c = |i: usize| lo[i] + e[i] * s;
        let f = c(0) * b0 + c(1) * b1 + c(2) * b2 - x;
        if f.length() <= 1e-6 * scale {
            let tol = 1e-5;
            return b0 >= -tol && b1 >= -tol && b2 >= -tol && (-tol..=1.0 + tol).contains(&s);
        }
        let jac =
            glam::Mat3::from_cols(c(1) - c(0), c(2) - c(0), e[0] * b0 + e[1] * b1 + e[2] * b2);
        if jac.determinant().abs() < 1e-30 {
            return false;
        }
        let delta = jac.inverse() * f;
        b1 -= delta.x;
        b2 -= delta.y;
        s -= delta.z;
        if !(b1.is_finite() && b2.is_finite() && s.is_finite()) {
            return false;
        }
    }
    false
}

/// Where a ray leaves the box of the six corners (a bound for a lost exit crossing).
fn box_exit(o: Vec3, d: Vec3, lo: &[Vec3; 3], hi: &[Vec3; 3]) -> f32 {
    let (mn, mx) = lo
        .iter()
        .chain(hi.iter())
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &c| {
            (a.min(c), b.max(c))
        });
    let inv = d.recip();
    let t0 = (mn - o) * inv;
    let t1 = (mx - o) * inv;
    let far = t0.max(t1);
    // f32::min ignores a NaN operand (o on a slab plane with d parallel to it).
    far.x.min(far.y).min(far.z)
}

/// Box of the base triangle `v` grown by `reach` on every side. With `reach` the prism's
/// largest `|D|` it holds the prism's part of the canonical surface: every surface point is
/// `P(b) + D m̂(b)` with a unit `m̂` (`PrismTable::prism_aabb` cuts the BVH box to the same).
#[inline]
pub fn surface_box(v: &[Vec3; 3], reach: f32) -> (Vec3, Vec3) {
    let r = Vec3::splat(reach);
    (v[0].min(v[1]).min(v[2]) - r, v[0].max(v[1]).max(v[2]) + r)
}

/// `[t0, t1]` cut to where the ray `o + t d` is inside the box `[lo, hi]` (slab test), or
/// `None` if nothing is left. Every method clips its march interval with this to the
/// `surface_box`: where the normals nearly cancel, a prism's λ range (and so its walls' hull)
/// can be far larger than the region the surface can reach.
#[inline]
pub fn clip_to_box(o: Vec3, d: Vec3, t0: f32, t1: f32, lo: Vec3, hi: Vec3) -> Option<(f32, f32)> {
    let inv = d.recip();
    let a = (lo - o) * inv;
    let b = (hi - o) * inv;
    let (near, far) = (a.min(b), a.max(b));
    // f32::max / min ignore a NaN operand (o on a slab plane with d parallel to it); an axis
    // the ray is parallel to and outside of gives +∞ or −∞ on both sides and empties it.
    let t_near = t0.max(near.x).max(near.y).max(near.z);
    let t_far = t1.min(far.x).min(far.y).min(far.z);
    (t_near <= t_far).then_some((t_near, t_far))
}

/// `[t0, t1]` cut to where the ray is within `reach` of the plane through `p` with unit
/// normal `n`, or `None`; a zero `n` (a zero-area base) keeps everything.
#[inline]
pub fn clip_to_slab(
    o: Vec3,
    d: Vec3,
    (t0, t1): (f32, f32),
    p: Vec3,
    n: Vec3,
    reach: f32,
) -> Option<(f32, f32)> {
    let s0 = (o - p).dot(n);
    let sd = d.dot(n);
    if sd == 0.0 {
        return (s0.abs() <= reach).then_some((t0, t1));
    }
    let (ta, tb) = ((-reach - s0) / sd, (reach - s0) / sd);
    let (a, b) = (t0.max(ta.min(tb)), t1.min(ta.max(tb)));
    (a <= b).then_some((a, b))
}

/// `[t0, t1]` cut to where the prism's part of the canonical surface can be: within `reach`
/// (the prism's largest `|D|`, plus any padding) of the base triangle `v`, so inside both its
/// `surface_box` and the slab of half-width `reach` around its plane. Every method clips its
/// march interval with this: the walls' hull follows the λ range, and where the normals
/// nearly cancel that range (and the hull) is far larger than the region the surface can
/// reach; the slab also keeps a tilted triangle's march to its thickness, not its box.
#[inline]
pub fn clip_to_surface_bounds(
    o: Vec3,
    d: Vec3,
    t0: f32,
    t1: f32,
    v: &[Vec3; 3],
    reach: f32,
) -> Option<(f32, f32)> {
    let (lo, hi) = surface_box(v, reach);
    let range = clip_to_box(o, d, t0, t1, lo, hi)?;
    match base_plane_normal(v) {
        Some(ng) => clip_to_slab(o, d, range, v[0], ng, reach),
        None => Some(range),
    }
}

/// Smallest sine of the base triangle's angle at `v[0]` for which its plane bounds the
/// surface: the cross product's rounding (~1e-7 of |e1||e2|) then tilts the plane by at most
/// ~1e-4 rad, within `INTERVAL_PAD`'s widening of the slab over the triangle's length.
pub const PLANE_MIN_SINE: f32 = 1e-3;

/// The unit normal of base triangle `v`, or `None` where its corners are (nearly) collinear
/// — the zero-area prisms crease repair inserts, whose cross product is rounding noise: a
/// plane from it points anywhere, and its slab would cut the strip's surface off (by a
/// different plane on every device: a GPU's cross product rounds otherwise).
#[inline]
pub fn base_plane_normal(v: &[Vec3; 3]) -> Option<Vec3> {
    let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
    let c = e1.cross(e2);
    let floor = PLANE_MIN_SINE * PLANE_MIN_SINE * e1.length_squared() * e2.length_squared();
    (c.length_squared() > floor).then(|| c / c.length())
}

/// Cheap early-out before the walls: `true` if the segment `[t_min, t_max]` lies wholly
/// outside the plane of one cap, on the side away from the prism. A cap plane bounds the
/// prism only if the other cap's corners are on its inner side (walls lie in the hull of
/// their corners); a flipped cap or folded prism is simply not culled by that plane.
#[inline]
fn cap_planes_reject(
    o: Vec3,
    d: Vec3,
    (t_min, t_max): (f32, f32),
    lo: &[Vec3; 3],
    hi: &[Vec3; 3],
    extent: f32,
) -> bool {
    for (cap, other, sign) in [(hi, lo, 1.0f32), (lo, hi, -1.0)] {
        // Outward normal of this cap (counter-clockwise base: `hi` up, `lo` down).
        let n = (cap[1] - cap[0]).cross(cap[2] - cap[0]) * sign;
        let tol = 1e-5 * n.length() * extent;
        if other.iter().any(|&c| (c - cap[0]).dot(n) > -tol) {
            continue;
        }
        let s0 = (o - cap[0]).dot(n);
        let sd = d.dot(n);
        if s0 + t_min * sd > tol && (sd >= 0.0 || s0 + t_max * sd > tol) {
            return true;
        }
    }
    false
}

/// The same early-out for the three walls. The wall over the base edge `lo_i lo_j` is a
/// bilinear patch, so it lies in the hull of its corners: on the inner side of the plane
/// through `lo_i, lo_j, hi_i` shifted outwards by the fourth corner's distance `δ`. Every level
/// triangle has its edge on the wall and its third corner between `lo_k` and `hi_k`; if those
/// are on the inner side, the whole prism is. A segment wholly beyond the shifted plane then
/// misses the prism (the walls' quadratics are the interval's main cost, and most candidate
/// prisms of a ray are missed).
#[inline]
fn wall_planes_reject(
    o: Vec3,
    d: Vec3,
    (t_min, t_max): (f32, f32),
    lo: &[Vec3; 3],
    hi: &[Vec3; 3],
    extent: f32,
) -> bool {
    for i in 0..3 {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        let a = lo[i];
        // Outward for a counter-clockwise base (as in `wall`).
        let n = (lo[j] - a).cross(hi[i] - a);
        let tol = 1e-5 * n.length() * extent;
        if (lo[k] - a).dot(n) > -tol || (hi[k] - a).dot(n) > -tol {
            continue;
        }
        let bound = (hi[j] - a).dot(n).max(0.0) + tol;
        let s0 = (o - a).dot(n);
        let sd = d.dot(n);
        if s0 + t_min * sd > bound && (sd >= 0.0 || s0 + t_max * sd > bound) {
            return true;
        }
    }
    false
}

/// The hull `[first entry, last exit]` of the ray's inside set in `[t_min, t_max]`, or `None`
/// if the ray misses the prism. `d` need not be unit length (t is in units of `d`).
pub fn ray_prism_interval(
    o: Vec3,
    d: Vec3,
    t_min: f32,
    t_max: f32,
    lo: &[Vec3; 3],
    hi: &[Vec3; 3],
) -> Option<Interval> {
    let extent = (hi[0] - lo[0]).length() + (lo[1] - lo[0]).length() + (lo[2] - lo[0]).length();
    if cap_planes_reject(o, d, (t_min, t_max), lo, hi, extent)
        || wall_planes_reject(o, d, (t_min, t_max), lo, hi, extent)
    {
        return None;
    }
    // Crossings are gathered over [t_min, ∞) and clipped afterwards: a crossing past t_max
    // still tells whether the ray starts inside, so no point-in-prism test is needed when a
    // closer hit has already shortened the ray (the common case in a closest-hit traversal).
    let far = f32::INFINITY;
    let mut acc = Crossings::new();
    cap(o, d, t_min, far, lo, -1.0, &mut acc);
    cap(o, d, t_min, far, hi, 1.0, &mut acc);
    for i in 0..3 {
        let j = (i + 1) % 3;
        wall(o, d, t_min, far, lo[i], lo[j], hi[i], hi[j], &mut acc);
    }
    if !acc.any() {
        // A bounded solid is always left again: no crossing on a half-line is a miss.
        return None;
    }
    // First crossing an exit (or no entry): the ray starts inside.
    let t_enter = if acc.first_exit < acc.first_entry {
        t_min
    } else {
        acc.first_entry
    };
    // Last crossing an entry (no exit after it): an exit was lost to rounding; bound it by
    // the corners' box.
    let t_exit = if acc.last_entry > acc.last_exit {
        box_exit(o, d, lo, hi).max(acc.last_entry)
    } else {
        acc.last_exit
    }
    .min(t_max);
    (t_enter <= t_exit).then_some(Interval { t_enter, t_exit })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canonical::{project_to_prism, PrismGeom};
    use crate::rng::{pcg_hash, to_unit_float};
    use glam::Vec2;

    struct Rng(u32);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 = pcg_hash(self.0);
            to_unit_float(self.0)
        }
        fn range(&mut self, a: f32, b: f32) -> f32 {
            a + (b - a) * self.next()
        }
        fn unit(&mut self) -> Vec3 {
            loop {
                let v = Vec3::new(
                    self.range(-1., 1.),
                    self.range(-1., 1.),
                    self.range(-1., 1.),
                );
                if v.length_squared() > 0.01 && v.length_squared() <= 1.0 {
                    return v.normalize();
                }
            }
        }
    }

    /// A shared-wall prism with strongly diverging normals, so the walls are visibly curved.
    fn curved_prism(scale: f32) -> (PrismGeom, f32, f32) {
        let v = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.1),
            Vec3::new(0.2, 0.9, -0.05),
        ]
        .map(|p| p * scale);
        let n = [
            Vec3::new(-0.5, -0.4, 1.0).normalize(),
            Vec3::new(0.6, -0.2, 1.0).normalize(),
            Vec3::new(0.1, 0.7, 1.0).normalize(),
        ];
        let g = PrismGeom {
            v,
            n,
            uv: [Vec2::ZERO; 3],
        };
        (g, -0.2 * scale, 0.3 * scale)
    }

    fn corners(g: &PrismGeom, lo: f32, hi: f32) -> ([Vec3; 3], [Vec3; 3]) {
        (
            std::array::from_fn(|i| g.v[i] + g.n[i] * lo),
            std::array::from_fn(|i| g.v[i] + g.n[i] * hi),
        )
    }

    /// Brute force: `x` is inside iff it projects to `b` in the triangle and `λ` in range.
    fn inside(g: &PrismGeom, lo: f32, hi: f32, x: Vec3) -> bool {
        let start = [Vec3::splat(1.0 / 3.0), Vec3::X, Vec3::Y, Vec3::Z];
        start.iter().any(|&b0| {
            project_to_prism(g, x, b0, 0.5 * (lo + hi))
                .is_some_and(|(b, l)| b.min_element() >= 0.0 && l >= lo && l <= hi)
        })
    }

    /// Random rays through the prism's neighbourhood: every sampled inside point lies in the
    /// hull, and both hull ends are (within tolerance) on the boundary with inside points
    /// just past them. Breaks if a wall root, cap test or orientation is wrong.
    fn check_random_rays(scale: f32, seed: u32) {
        let (g, lo, hi) = curved_prism(scale);
        let (cl, ch) = corners(&g, lo, hi);
        let centre = (cl.iter().chain(ch.iter()).copied().sum::<Vec3>()) / 6.0;
        let mut rng = Rng(seed);
        let mut hits = 0;
        for _ in 0..600 {
            let target = centre + rng.unit() * 0.6 * scale * rng.next();
            let d = rng.unit();
            let o = target - d * 3.0 * scale;
            let interval = ray_prism_interval(o, d, 0.0, f32::INFINITY, &cl, &ch);
            // Brute-force scan of the ray.
            let n = 800;
            let (mut first, mut last) = (f32::INFINITY, f32::NEG_INFINITY);
            for k in 0..=n {
                let t = 6.0 * scale * k as f32 / n as f32;
                if inside(&g, lo, hi, o + d * t) {
                    first = first.min(t);
                    last = last.max(t);
                }
            }
            let step = 6.0 * scale / n as f32;
            // A random piece of the same ray (the early-outs cull by the segment's ends): it
            // must keep every inside sample it contains.
            let (ka, kb) = (
                (rng.next() * n as f32) as usize,
                (rng.next() * n as f32) as usize,
            );
            let (ka, kb) = (ka.min(kb), ka.max(kb));
            let (t0, t1) = (step * ka as f32, step * kb as f32);
            let piece = ray_prism_interval(o, d, t0, t1, &cl, &ch);
            for k in ka..=kb {
                let t = step * k as f32;
                if inside(&g, lo, hi, o + d * t) {
                    let iv = piece.unwrap_or_else(|| panic!("piece [{t0}, {t1}] lost t={t}"));
                    assert!(iv.t_enter <= t + 1e-4 * scale && iv.t_exit >= t - 1e-4 * scale);
                }
            }
            match interval {
                None => assert!(
                    !first.is_finite(),
                    "missed prism: inside at t={first}..{last}, scale {scale}"
                ),
                Some(iv) => {
                    assert!(iv.t_enter.is_finite() && iv.t_exit.is_finite());
                    if first.is_finite() {
                        hits += 1;
                        assert!(
                            iv.t_enter <= first + 1e-4 * scale && iv.t_exit >= last - 1e-4 * scale,
                            "hull [{}, {}] misses inside samples [{first}, {last}]",
                            iv.t_enter,
                            iv.t_exit
                        );
                        assert!(
                            iv.t_enter >= first - step * 1.01 && iv.t_exit <= last + step * 1.01,
                            "hull [{}, {}] too wide for [{first}, {last}]",
                            iv.t_enter,
                            iv.t_exit
                        );
                    }
                }
            }
        }
        assert!(hits > 100, "too few rays met the prism ({hits})");
    }

    #[test]
    fn random_rays_match_brute_force_inside_test() {
        check_random_rays(1.0, 1);
    }

    #[test]
    fn quadratic_is_robust_at_small_and_large_scales() {
        // Same geometry at 1e-3 and 1e4: same verdicts, no NaN.
        check_random_rays(1e-3, 2);
        check_random_rays(1e4, 3);
        // Near-degenerate quadratics.
        assert_eq!(quadratic(0.0, 2.0, -4.0), Some((2.0, 2.0)));
        let (r0, r1) = quadratic(1e-30, 1.0, -1.0).unwrap();
        assert!((r0 - 1.0).abs() < 1e-6 || (r1 - 1.0).abs() < 1e-6);
        let (r0, r1) = quadratic(1.0, -2e4, 1.0).unwrap();
        assert!(
            (r0 - 5e-5).abs() < 1e-9 && (r1 - 2e4).abs() < 1.0,
            "{r0} {r1}"
        );
        assert_eq!(quadratic(1.0, 0.0, 1.0), None);
    }

    #[test]
    fn ray_starting_inside_enters_at_t_min() {
        let (g, lo, hi) = curved_prism(1.0);
        let (cl, ch) = corners(&g, lo, hi);
        let x = g.position(Vec3::splat(1.0 / 3.0)) + g.normal_dir(Vec3::splat(1.0 / 3.0)) * 0.05;
        assert!(inside(&g, lo, hi, x));
        let mut rng = Rng(9);
        for _ in 0..100 {
            let d = rng.unit();
            let iv = ray_prism_interval(x, d, 0.0, f32::INFINITY, &cl, &ch).expect("inside");
            assert_eq!(iv.t_enter, 0.0);
            assert!(iv.t_exit > 0.0 && iv.t_exit < 3.0);
            // A short ray wholly inside: no crossing at all.
            let iv = ray_prism_interval(x, d, 0.0, 1e-4, &cl, &ch).expect("wholly inside");
            assert_eq!((iv.t_enter, iv.t_exit), (0.0, 1e-4));
        }
    }

    #[test]
    fn grazing_rays_near_the_base_plane() {
        // Rays within 1° of the base plane, at heights inside the prism: they must find an
        // interval that contains their inside samples (no NaN, no lost prism).
        let (g, lo, hi) = curved_prism(1.0);
        let (cl, ch) = corners(&g, lo, hi);
        let ng = g.base_normal();
        let tangent = (g.v[1] - g.v[0]).normalize();
        let bitangent = ng.cross(tangent);
        let mut rng = Rng(5);
        for _ in 0..300 {
            let phi = rng.range(0.0, std::f32::consts::TAU);
            let elev = rng.range(-1.0, 1.0).to_radians();
            let d = ((tangent * phi.cos() + bitangent * phi.sin()) * elev.cos() + ng * elev.sin())
                .normalize();
            let b = Vec3::new(rng.next(), rng.next(), rng.next());
            let b = b / (b.x + b.y + b.z);
            let x = g.position(b) + g.normal_dir(b) * rng.range(lo * 0.9, hi * 0.9);
            let o = x - d * 3.0;
            let iv = ray_prism_interval(o, d, 0.0, f32::INFINITY, &cl, &ch)
                .expect("a ray through an inside point meets the prism");
            assert!(iv.t_enter.is_finite() && iv.t_exit.is_finite());
            assert!(
                iv.t_enter <= 3.0 + 1e-4 && iv.t_exit >= 3.0 - 1e-4,
                "inside point t=3 outside [{}, {}]",
                iv.t_enter,
                iv.t_exit
            );
        }
    }

    #[test]
    fn parallel_offset_prism_is_the_same_kind_of_solid() {
        // The paper's corners V_i + w n_i/(n_i·N_g): same routine, planar caps parallel to the
        // base. A ray straight down the geometric normal enters at the top cap's height.
        let (g, _, _) = curved_prism(1.0);
        let ng = g.base_normal();
        let a = g.n.map(|n| n / n.dot(ng));
        let lo: [Vec3; 3] = std::array::from_fn(|i| g.v[i] - a[i] * 0.1);
        let hi: [Vec3; 3] = std::array::from_fn(|i| g.v[i] + a[i] * 0.2);
        let p = g.position(Vec3::splat(1.0 / 3.0));
        let iv = ray_prism_interval(p + ng * 1.0, -ng, 0.0, f32::INFINITY, &lo, &hi).unwrap();
        assert!(
            (iv.t_enter - 0.8).abs() < 1e-5 && (iv.t_exit - 1.1).abs() < 1e-5,
            "{iv:?}"
        );
    }

    // Would break if the box clip dropped a part of the ray inside the box (the march would
    // lose surface) or kept a ray parallel to a slab and outside it.
    #[test]
    fn clip_to_box_keeps_exactly_the_inside_part() {
        let (lo, hi) = (Vec3::new(-1.0, -2.0, 0.0), Vec3::new(1.0, 2.0, 0.5));
        let mut rng = Rng(17);
        for _ in 0..2000 {
            let o = Vec3::new(rng.range(-3., 3.), rng.range(-3., 3.), rng.range(-3., 3.));
            let mut d = rng.unit();
            if rng.next() < 0.2 {
                d.x = 0.0; // parallel to the x slabs, inside or outside them
                d = d.normalize();
            }
            let (t0, t1) = (rng.range(-1.0, 2.0), rng.range(2.0, 8.0));
            let inside = |t: f32| {
                let x = o + d * t;
                x.cmpge(lo - 1e-5).all() && x.cmple(hi + 1e-5).all()
            };
            let clip = clip_to_box(o, d, t0, t1, lo, hi);
            for k in 0..=200 {
                let t = t0 + (t1 - t0) * k as f32 / 200.0;
                let kept = clip.is_some_and(|(a, b)| t >= a - 1e-5 && t <= b + 1e-5);
                assert_eq!(inside(t), kept, "o {o} d {d} t {t}: {clip:?}");
            }
        }
        // The surface box is the base triangle's box grown by the reach on every side.
        let v = [Vec3::ZERO, Vec3::X, Vec3::new(0.2, 1.0, -0.5)];
        assert_eq!(
            surface_box(&v, 0.1),
            (Vec3::new(-0.1, -0.1, -0.6), Vec3::new(1.1, 1.1, 0.1))
        );
        // ... and the slab around the plane: a ray down the base normal through the triangle
        // keeps only the `2 × reach` around the base, whatever its box allows.
        let ng = (v[1] - v[0]).cross(v[2] - v[0]).normalize();
        let c = (v[0] + v[1] + v[2]) / 3.0;
        let (a, b) = clip_to_surface_bounds(c + ng * 5.0, -ng, 0.0, 10.0, &v, 0.1).unwrap();
        assert!((a - 4.9).abs() < 1e-5 && (b - 5.1).abs() < 1e-5, "{a} {b}");
        // A zero-area base has no plane: the box alone.
        let flat = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        let r = clip_to_surface_bounds(Vec3::new(0.5, 3.0, 0.0), Vec3::NEG_Y, 0.0, 9.0, &flat, 0.1);
        assert_eq!(r, Some((2.9, 3.1)));
    }
}
