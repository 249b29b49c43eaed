//! The ray projected into one prism's texture space (RMIP §4.2), in f64.
//!
//! Coordinates: positions relative to the base triangle's first vertex `V0`, the ray origin
//! moved to the prism entry, and texture space in *map texels* relative to the first corner's
//! texel coordinates `s0` (`σ = texel_coords(uv) − s0`), so every quantity is prism-sized
//! whatever the asset's scale or position and a texel is one unit. In these coordinates
//! `P(σ) = Px σx + Py σy` and the unnormalised direction `M(σ) = M0 + Mx σx + My σy` are affine.
//!
//! The lines `P(σ) + λ M(σ)` meeting the ray `O + t D` are the zero set of the quadric
//! `ψ(σ) = det(P(σ) − O, M(σ), D)` (eq. 3), here expanded once per prism into
//! `a x² + b xy + c y² + d x + e y + f`. On a curve point the ray parameter is closed form:
//! `O + tD = P + λM` crossed with `M` gives `t = ((P − O) × M)·(D × M) / |D × M|²`.

use glam::{DVec2, DVec3, Vec2, Vec3};

/// Real roots of `a x² + b x + c` (cancellation-free form), `n` of them valid.
#[inline]
pub fn quadratic(a: f64, b: f64, c: f64) -> ([f64; 2], usize) {
    if a == 0.0 {
        if b == 0.0 {
            return ([0.0; 2], 0);
        }
        return ([-c / b, 0.0], 1);
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return ([0.0; 2], 0);
    }
    let q = -0.5 * (b + disc.sqrt().copysign(b));
    if q == 0.0 {
        return ([0.0, 0.0], 1);
    }
    ([q / a, c / q], 2)
}

/// `ψ(σ) = a x² + b xy + c y² + d x + e y + f`.
#[derive(Clone, Copy, Debug)]
pub struct Conic {
    pub a: f64,
    pub b: f64,
    pub c: f64,
    pub d: f64,
    pub e: f64,
    pub f: f64,
}

impl Conic {
    #[inline]
    pub fn eval(&self, p: DVec2) -> f64 {
        (self.a * p.x + self.b * p.y + self.d) * p.x + (self.c * p.y + self.e) * p.y + self.f
    }
    #[inline]
    pub fn grad(&self, p: DVec2) -> DVec2 {
        DVec2::new(
            2.0 * self.a * p.x + self.b * p.y + self.d,
            self.b * p.x + 2.0 * self.c * p.y + self.e,
        )
    }
    /// Points of the conic on the line `p0 + τ u`.
    #[inline]
    pub fn on_line(&self, p0: DVec2, u: DVec2) -> ([DVec2; 2], usize) {
        let qa = self.a * u.x * u.x + self.b * u.x * u.y + self.c * u.y * u.y;
        let qb = self.grad(p0).dot(u);
        let qc = self.eval(p0);
        let (r, n) = quadratic(qa, qb, qc);
        ([p0 + u * r[0], p0 + u * r[1]], n)
    }
}

/// One prism and one ray, ready for the texture-space traversal.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// Ray origin (at the prism entry, relative to `V0`) and unit direction.
    pub o: DVec3,
    pub d: DVec3,
    pub px: DVec3,
    pub py: DVec3,
    pub m0: DVec3,
    pub mx: DVec3,
    pub my: DVec3,
    /// Rows of the map `σ → (b1, b2)`.
    pub to_b: [DVec2; 2],
    /// The base triangle's corners in σ (the first is the origin).
    pub tri: [DVec2; 3],
    pub conic: Conic,
    /// Accepted `λ` of curve points (the prism's range, widened): the quadric also holds
    /// points whose lines meet the ray far outside the shell, on another branch.
    pub lambda_range: (f64, f64),
}

fn d3(v: Vec3) -> DVec3 {
    DVec3::new(v.x as f64, v.y as f64, v.z as f64)
}

impl Frame {
    /// `v`: base corners relative to `V0` (`v[0] = 0`), `n`: unit vertex normals, `s`: corner
    /// texel coordinates relative to `s0` (`s[0] = 0`), `o`/`d`: the ray in the same frame.
    /// `None` if the UV triangle is degenerate (no texture-space parametrisation).
    pub fn new(v: &[Vec3; 3], n: &[Vec3; 3], s: &[Vec2; 3], o: Vec3, d: Vec3) -> Option<Self> {
        let (s1, s2) = (
            DVec2::new(s[1].x as f64, s[1].y as f64),
            DVec2::new(s[2].x as f64, s[2].y as f64),
        );
        let det = s1.perp_dot(s2);
        let scale = s1.length_squared().max(s2.length_squared());
        // Negated so that NaN is rejected too.
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        if !(det.abs() > 1e-9 * scale) || scale == 0.0 {
            return None;
        }
        // [b1 b2]ᵀ = J⁻¹ σ with J = [s1 s2].
        let to_b = [DVec2::new(s2.y, -s2.x) / det, DVec2::new(-s1.y, s1.x) / det];
        let (v1, v2) = (d3(v[1]), d3(v[2]));
        let n0 = d3(n[0]);
        let (dn1, dn2) = (d3(n[1]) - n0, d3(n[2]) - n0);
        let px = v1 * to_b[0].x + v2 * to_b[1].x;
        let py = v1 * to_b[0].y + v2 * to_b[1].y;
        let mx = dn1 * to_b[0].x + dn2 * to_b[1].x;
        let my = dn1 * to_b[0].y + dn2 * to_b[1].y;
        let (o, d) = (d3(o), d3(d));
        // ψ = A·C with A = P − O (affine), C = M × D (affine).
        let (a0, c0, cx, cy) = (-o, n0.cross(d), mx.cross(d), my.cross(d));
        let conic = Conic {
            a: px.dot(cx),
            b: px.dot(cy) + py.dot(cx),
            c: py.dot(cy),
            d: px.dot(c0) + a0.dot(cx),
            e: py.dot(c0) + a0.dot(cy),
            f: a0.dot(c0),
        };
        Some(Frame {
            o,
            d,
            px,
            py,
            m0: n0,
            mx,
            my,
            to_b,
            tri: [DVec2::ZERO, s1, s2],
            conic,
            lambda_range: (f64::NEG_INFINITY, f64::INFINITY),
        })
    }

    #[inline]
    pub fn position(&self, p: DVec2) -> DVec3 {
        self.px * p.x + self.py * p.y
    }
    #[inline]
    pub fn dir(&self, p: DVec2) -> DVec3 {
        self.m0 + self.mx * p.x + self.my * p.y
    }
    #[inline]
    pub fn bary(&self, p: DVec2) -> Vec3 {
        let (b1, b2) = (self.to_b[0].dot(p), self.to_b[1].dot(p));
        Vec3::new((1.0 - b1 - b2) as f32, b1 as f32, b2 as f32)
    }
    #[inline]
    pub fn sigma_of_bary(&self, b: Vec3) -> DVec2 {
        self.tri[1] * b.y as f64 + self.tri[2] * b.z as f64
    }

    /// Ray parameter of the curve point `p` (where its line meets the ray); `None` when the
    /// line is parallel to the ray (within 1e-7 rad: the curve degenerates to a point there).
    #[inline]
    pub fn t_of(&self, p: DVec2) -> Option<f64> {
        let m = self.dir(p);
        let dm = self.d.cross(m);
        let den = dm.length_squared();
        // Negated so that NaN is rejected too.
        #[allow(clippy::neg_cmp_op_on_partial_ord)]
        if !(den > 1e-14 * m.length_squared()) {
            return None;
        }
        Some((self.position(p) - self.o).cross(m).dot(dm) / den)
    }

    /// `t_of(p)` if the ray meets the line through `p` inside the accepted `λ` range.
    #[inline]
    pub fn t_on_branch(&self, p: DVec2) -> Option<f64> {
        let t = self.t_of(p)?;
        let m = self.dir(p);
        let l = (self.o + self.d * t - self.position(p)).dot(m) / m.length_squared();
        (l >= self.lambda_range.0 && l <= self.lambda_range.1).then_some(t)
    }

    /// Height of the ray point `O + tD` above the base along the unit direction at `p`
    /// (`λ|M|` of the line through `p`); the surface is where it equals `D(p)`.
    #[inline]
    pub fn ray_height(&self, p: DVec2, t: f64) -> f64 {
        let m = self.dir(p);
        let len = m.length().max(1e-300);
        (self.o + self.d * t - self.position(p)).dot(m) / len
    }

    /// Turning points of the curve: where `∂ψ/∂x = 0` or `∂ψ/∂y = 0` (the curve's tangent is
    /// axis-aligned), as `(t, σ)` with `t` strictly inside `(t0, t1)`, sorted by `t`.
    pub fn turning_points(&self, t0: f64, t1: f64) -> ([(f64, DVec2); 4], usize) {
        let k = &self.conic;
        let mut out = [(0.0, DVec2::ZERO); 4];
        let mut n = 0;
        // ψx = 2a x + b y + d = 0 and ψy = b x + 2c y + e = 0, as normal·σ + offset = 0.
        for (normal, offset) in [
            (DVec2::new(2.0 * k.a, k.b), k.d),
            (DVec2::new(k.b, 2.0 * k.c), k.e),
        ] {
            let nn = normal.length_squared();
            // Negated so that NaN is rejected too.
            #[allow(clippy::neg_cmp_op_on_partial_ord)]
            if !(nn > 0.0) {
                continue;
            }
            let p0 = -normal * (offset / nn);
            let u = normal.perp();
            let (pts, m) = self.conic.on_line(p0, u);
            for p in &pts[..m] {
                if let Some(t) = self.t_on_branch(*p) {
                    let eps = 1e-9 * (t1 - t0).abs().max(1e-30);
                    if t > t0 + eps && t < t1 - eps && n < 4 {
                        out[n] = (t, *p);
                        n += 1;
                    }
                }
            }
        }
        out[..n].sort_by(|a, b| a.0.total_cmp(&b.0));
        (out, n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canonical::{project_to_prism, PrismGeom};

    /// A curved prism (diverging normals) with a skewed UV triangle, and a ray across it.
    fn frame() -> (Frame, PrismGeom, Vec3, Vec3) {
        let v = [
            Vec3::ZERO,
            Vec3::new(1.0, 0.0, 0.1),
            Vec3::new(0.2, 0.9, -0.05),
        ];
        let n = [
            Vec3::new(-0.5, -0.4, 1.0).normalize(),
            Vec3::new(0.6, -0.2, 1.0).normalize(),
            Vec3::new(0.1, 0.7, 1.0).normalize(),
        ];
        let s = [Vec2::ZERO, Vec2::new(40.0, 5.0), Vec2::new(-8.0, 30.0)];
        let o = Vec3::new(-0.3, 0.1, 0.4);
        let d = Vec3::new(1.0, 0.5, -0.35).normalize();
        let f = Frame::new(&v, &n, &s, o, d).unwrap();
        let g = PrismGeom { v, n, uv: s };
        (f, g, o, d)
    }

    #[test]
    fn projected_ray_points_lie_on_the_conic_and_invert_to_their_t() {
        // Newton-projected ray points must satisfy ψ = 0 (relative to the gradient scale) and
        // t_of must give back their t: breaks if a quadric coefficient or the parametrisation
        // σ → (P, M) is wrong.
        let (f, g, o, d) = frame();
        for k in 0..20 {
            let t = 0.1 + 0.06 * k as f32;
            let (b, _) = project_to_prism(&g, o + d * t, Vec3::splat(1.0 / 3.0), 0.0).unwrap();
            let p = f.sigma_of_bary(b);
            let psi = f.conic.eval(p) / f.conic.grad(p).length();
            assert!(psi.abs() < 1e-4, "ψ = {psi} texels at t {t}");
            let back = f.t_of(p).unwrap();
            assert!((back - t as f64).abs() < 1e-4, "{back} vs {t}");
            assert!((f.bary(p) - b).abs().max_element() < 1e-5);
        }
    }

    #[test]
    fn turning_points_have_axis_aligned_tangents() {
        let (f, ..) = frame();
        let (tp, n) = f.turning_points(-10.0, 10.0);
        assert!(n >= 1, "this ray's curve turns");
        for (t, p) in &tp[..n] {
            let gr = f.conic.grad(*p);
            assert!(gr.x.abs().min(gr.y.abs()) < 1e-9 * gr.length(), "{gr}");
            assert!((f.t_of(*p).unwrap() - t).abs() < 1e-9);
        }
    }
}
