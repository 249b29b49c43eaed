//! The ray as a rational quadratic curve in a prism's canonical space (Ogaki 2023 §4.1–4.2).
//!
//! The prism is `X(b, λ) = Σ b_i (V_i + λ n_i)` (DESIGN.md's shared-wall prism; Ogaki's
//! `S(α, β, h)` with `h = λ`). Project everything onto the plane perpendicular to the ray:
//! the layer triangle at `λ` has 2-D corners `P_i(λ) = A_i + λ B_i`, linear in `λ`, and the
//! ray is the 2-D origin. Its barycentrics in that triangle are the signed areas
//! `w_i(λ) = P_j(λ) × P_k(λ)` over their sum `W(λ)` — quadratics over a quadratic, which is
//! the paper's eq. 7 written symmetrically (no choice of `e0`, `e1` or of a pivot vertex
//! enters the result). Texel coordinates are affine in `b`, so `x(λ) = Σ w_i x_i / W` (eq. 8)
//! with the same denominator.
//!
//! Along the ray, `t(λ) = s + Σ b_i(λ) (V_i·d + λ n_i·d)` where `s` shifts the origin to the
//! point of the ray nearest the prism's first vertex (so `A_i` are prism-sized, not
//! camera-distance-sized, which is what keeps `f32` usable).

// `!(a < b)` is deliberate: it is also true for NaN, which must be rejected.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

use super::cubic::quadratic;
use super::real::{diff_of_products, eval2, Real, V3};
use glam::Vec3;

/// Up to this many disjoint `λ` intervals per box (more are merged, conservatively).
pub const MAX_INTERVALS: usize = 4;

#[derive(Clone, Copy, Debug)]
pub struct Intervals<T> {
    pub n: usize,
    pub iv: [(T, T); MAX_INTERVALS],
}

impl<T: Real> Intervals<T> {
    fn push(&mut self, a: T, b: T) {
        if self.n > 0 && self.iv[self.n - 1].1 >= a {
            self.iv[self.n - 1].1 = b;
        } else if self.n < MAX_INTERVALS {
            self.iv[self.n] = (a, b);
            self.n += 1;
        } else {
            self.iv[self.n - 1].1 = b;
        }
    }
}

pub struct Curve<T> {
    /// `w_i(λ)`, low to high.
    pub w: [[T; 3]; 3],
    pub wsum: [T; 3],
    /// `Σ w_i x_i` and `Σ w_i y_i` for local texel coordinates `(x_i, y_i)`.
    pub xq: [T; 3],
    pub yq: [T; 3],
    /// Base corners (prism-local), unit normals, and their projections on the ray direction.
    pub v: [V3<T>; 3],
    pub n: [V3<T>; 3],
    vd: [T; 3],
    nd: [T; 3],
    shift: T,
}

#[inline]
fn cross2<T: Real>(a: (T, T), b: (T, T)) -> T {
    diff_of_products(a.0, b.1, a.1, b.0)
}

impl<T: Real> Curve<T> {
    /// `ro`: ray origin relative to `V_0`; `v`: corners relative to `V_0`; `tex`: the corners'
    /// texel coordinates relative to the footprint's origin cell.
    pub fn new(ro: Vec3, d: Vec3, v: &[Vec3; 3], n: &[Vec3; 3], tex: &[(f64, f64); 3]) -> Self {
        let (ro, d) = (V3::<T>::of(ro), V3::<T>::of(d));
        let shift = -ro.dot(d);
        let o = ro + d.scale(shift);
        // An orthonormal pair perpendicular to d (Duff et al. 2017, branchless).
        let sign = T::ONE.copysign(d.2);
        let a = -T::ONE / (sign + d.2);
        let b = d.0 * d.1 * a;
        let e0 = V3(T::ONE + sign * d.0 * d.0 * a, sign * b, -sign * d.0);
        let e1 = V3(b, sign + d.1 * d.1 * a, -d.1);
        let v = v.map(V3::of);
        let n = n.map(V3::of);
        let pa: [(T, T); 3] = std::array::from_fn(|i| {
            let q = v[i] - o;
            (q.dot(e0), q.dot(e1))
        });
        let pb: [(T, T); 3] = std::array::from_fn(|i| (n[i].dot(e0), n[i].dot(e1)));
        let w: [[T; 3]; 3] = std::array::from_fn(|i| {
            let (j, k) = ((i + 1) % 3, (i + 2) % 3);
            [
                cross2(pa[j], pa[k]),
                cross2(pa[j], pb[k]) + cross2(pb[j], pa[k]),
                cross2(pb[j], pb[k]),
            ]
        });
        let comb = |c: [T; 3]| -> [T; 3] {
            std::array::from_fn(|p| c[0].fma(w[0][p], c[1].fma(w[1][p], c[2] * w[2][p])))
        };
        let wsum = comb([T::ONE; 3]);
        let xq = comb(tex.map(|t| T::of(t.0)));
        let yq = comb(tex.map(|t| T::of(t.1)));
        Curve {
            w,
            wsum,
            xq,
            yq,
            vd: v.map(|vi| vi.dot(d)),
            nd: n.map(|ni| ni.dot(d)),
            v,
            n,
            shift,
        }
    }

    /// Barycentrics at `λ` (non-finite where the ray is parallel to the layer).
    #[inline]
    pub fn bary(&self, l: T) -> [T; 3] {
        let inv = T::ONE / eval2(&self.wsum, l);
        self.w.map(|c| eval2(&c, l) * inv)
    }

    /// Local texel coordinates at `λ`.
    #[inline]
    pub fn tex(&self, l: T) -> (T, T) {
        let inv = T::ONE / eval2(&self.wsum, l);
        (eval2(&self.xq, l) * inv, eval2(&self.yq, l) * inv)
    }

    /// Ray parameter of the curve point `(b, λ)`.
    #[inline]
    pub fn t_at(&self, b: &[T; 3], l: T) -> T {
        let mut t = self.shift;
        for i in 0..3 {
            t = b[i].fma(self.nd[i].fma(l, self.vd[i]), t);
        }
        t
    }

    /// `|m(b)|`, the length of the interpolated unnormalised normal.
    #[inline]
    pub fn m_len(&self, b: &[T; 3]) -> T {
        (self.n[0].scale(b[0]) + self.n[1].scale(b[1]) + self.n[2].scale(b[2])).length()
    }

    /// The `λ` intervals within `[l0, l1]` where the curve is inside the texel box
    /// `[x0, x1] × [y0, y1]`: between consecutive roots of `X − x_k W`, `Y − y_k W` and `W`
    /// the curve is wholly inside or outside, decided at the midpoint.
    pub fn box_intervals(&self, x: (T, T), y: (T, T), l0: T, l1: T) -> Intervals<T> {
        let mut out = Intervals {
            n: 0,
            iv: [(T::ZERO, T::ZERO); MAX_INTERVALS],
        };
        if !(l0 <= l1) {
            return out;
        }
        let ws = &self.wsum;
        let sub = |q: &[T; 3], s: T| -> [T; 3] { std::array::from_fn(|p| (-s).fma(ws[p], q[p])) };
        let polys = [
            *ws,
            sub(&self.xq, x.0),
            sub(&self.xq, x.1),
            sub(&self.yq, y.0),
            sub(&self.yq, y.1),
        ];
        let mut pts = [l0; 12];
        let mut np = 1;
        let mut r = [T::ZERO; 2];
        for q in &polys {
            let nr = quadratic(q[2], q[1], q[0], &mut r);
            for &root in &r[..nr] {
                if root > l0 && root < l1 {
                    pts[np] = root;
                    np += 1;
                }
            }
        }
        pts[np] = l1;
        np += 1;
        // Insertion sort of ≤ 12 values.
        for i in 1..np {
            let mut j = i;
            while j > 0 && pts[j - 1] > pts[j] {
                pts.swap(j - 1, j);
                j -= 1;
            }
        }
        let inside = |l: T| {
            let (xs, ys) = self.tex(l);
            xs >= x.0 && xs <= x.1 && ys >= y.0 && ys <= y.1
        };
        if np == 2 && l0 == l1 {
            if inside(l0) {
                out.push(l0, l1);
            }
            return out;
        }
        for i in 0..np - 1 {
            let (a, b) = (pts[i], pts[i + 1]);
            if b > a && inside(T::HALF * (a + b)) {
                out.push(a, b);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{pcg_hash, to_unit_float};

    #[test]
    fn curve_points_lie_on_the_ray() {
        // Breaks if the projected signed areas, the texel map or t(λ) are wrong: for random
        // rays and λ, the prism point X(b(λ), λ) must be o + t(λ) d, in f32 and f64.
        let v = [
            Vec3::ZERO,
            Vec3::new(1.0, 0.1, 0.0),
            Vec3::new(0.2, 0.9, 0.05),
        ];
        let n = [
            Vec3::new(-0.3, -0.2, 1.0).normalize(),
            Vec3::new(0.4, -0.1, 1.0).normalize(),
            Vec3::new(0.0, 0.5, 1.0).normalize(),
        ];
        let tex = [(0.0, 0.0), (10.0, 1.0), (2.0, 9.0)];
        let mut s = 11u32;
        let mut rnd = || {
            s = pcg_hash(s);
            to_unit_float(s) * 2.0 - 1.0
        };
        for _ in 0..500 {
            let o = Vec3::new(rnd(), rnd(), rnd() + 3.0);
            let d = (Vec3::new(rnd() * 0.5, rnd() * 0.5, -1.0)).normalize();
            let c64 = Curve::<f64>::new(o, d, &v, &n, &tex);
            let c32 = Curve::<f32>::new(o, d, &v, &n, &tex);
            let l = rnd() as f64 * 0.3;
            let b = c64.bary(l);
            let x: V3<f64> = (0..3).fold(V3(0.0, 0.0, 0.0), |acc, i| {
                acc + (c64.v[i] + c64.n[i].scale(l)).scale(b[i])
            });
            let t = c64.t_at(&b, l);
            let on_ray = V3::<f64>::of(o) + V3::<f64>::of(d).scale(t);
            assert!((x - on_ray).length() < 1e-5, "{x:?} vs {on_ray:?}");
            assert!((b[0] + b[1] + b[2] - 1.0).abs() < 1e-9);
            let (tx, ty) = c64.tex(l);
            let want = (0..3).fold((0.0, 0.0), |a, i| {
                (a.0 + b[i] * tex[i].0, a.1 + b[i] * tex[i].1)
            });
            assert!((tx - want.0).abs() < 1e-9 && (ty - want.1).abs() < 1e-9);
            let b32 = c32.bary(l as f32);
            assert!((c32.t_at(&b32, l as f32) as f64 - t).abs() < 1e-4);
        }
    }
}
