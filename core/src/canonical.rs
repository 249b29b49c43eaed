//! The canonical displaced surface every method is measured against (DESIGN.md):
//! `S(b) = P(b) + D(uv(b)) m(b)/|m(b)|`, `m(b) = Σ b_i n_i`, barycentrics `b = (b0, b1, b2)`.
//!
//! Also the inverse: the point `x` on the line `P(b) + λ m(b)`, solved for `(b, λ)` by Newton's
//! method on `F(b1, b2, λ) = P(b) + λ m(b) − x` (RMIP §4.1's inverse displacement).

use crate::bake::{Prism, PrismTable};
use crate::heightmap::HeightMap;
use crate::seam::{PrismDisplacement, SeamMode, StitchField};
use glam::{Mat3, Vec2, Vec3};

/// Base data of one prism, gathered once per ray-prism test.
#[derive(Clone, Copy, Debug)]
pub struct PrismGeom {
    pub v: [Vec3; 3],
    pub n: [Vec3; 3],
    pub uv: [Vec2; 3],
}

impl PrismGeom {
    pub fn new(table: &PrismTable, p: &Prism) -> Self {
        let (v, n) = table.prism_corners(p);
        PrismGeom {
            v,
            n,
            uv: table.prism_uvs(p),
        }
    }
    #[inline]
    pub fn position(&self, b: Vec3) -> Vec3 {
        self.v[0] * b.x + self.v[1] * b.y + self.v[2] * b.z
    }
    #[inline]
    pub fn normal_dir(&self, b: Vec3) -> Vec3 {
        self.n[0] * b.x + self.n[1] * b.y + self.n[2] * b.z
    }
    #[inline]
    pub fn uv(&self, b: Vec3) -> Vec2 {
        self.uv[0] * b.x + self.uv[1] * b.y + self.uv[2] * b.z
    }
    /// Unit geometric normal of the base triangle.
    pub fn base_normal(&self) -> Vec3 {
        (self.v[1] - self.v[0])
            .cross(self.v[2] - self.v[0])
            .normalize_or_zero()
    }
}

/// The displaced surface of a table as every method evaluates it: the table, its map, and how
/// UV seams are treated (the stitch data; empty for `SeamMode::Open`).
#[derive(Clone, Copy)]
pub struct Surface<'a> {
    pub table: &'a PrismTable,
    pub map: &'a HeightMap,
    pub mode: SeamMode,
    pub stitch: &'a StitchField,
}

static NO_STITCH: StitchField = StitchField::empty();

impl<'a> Surface<'a> {
    /// The raw canonical surface (no seam stitching).
    pub fn open(table: &'a PrismTable, map: &'a HeightMap) -> Self {
        Surface {
            table,
            map,
            mode: SeamMode::Open,
            stitch: &NO_STITCH,
        }
    }

    /// The height of prism `prism`, stitched where it has stitched seam edges.
    #[inline]
    pub fn prism_displacement(&self, prism: u32) -> PrismDisplacement<'a> {
        let p = &self.table.prisms[prism as usize];
        PrismDisplacement {
            map: self.map,
            params: self.table.params,
            uv: self.table.prism_uvs(p),
            stitch: self.stitch.get(prism),
        }
    }
}

/// Full surface data at barycentrics `b` of a prism.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub position: Vec3,
    pub uv: Vec2,
    /// Displacement `D` at `uv` (world units along the unit normal).
    pub displacement: f32,
    /// Unit normal of the displaced surface, on the side of the base normals.
    pub geometric_normal: Vec3,
    /// The paper's smoothed normal `N's = N_s − N_g + N'` (§5.1), unit length.
    pub smooth_normal: Vec3,
    /// Unit interpolated base normal `N'`.
    pub base_normal: Vec3,
}

/// Evaluate `S(b)` and its normals, the height from `disp` (the map, or the stitched height
/// next to UV seams: `seam::PrismDisplacement`).
pub fn surface_point(g: &PrismGeom, disp: &PrismDisplacement, b: Vec3) -> SurfacePoint {
    let p = g.position(b);
    let m = g.normal_dir(b);
    let len = m.length().max(1e-12);
    let mh = m / len;
    let uv = g.uv(b);
    // Height and its derivatives with respect to (b1, b2), b0 = 1 − b1 − b2.
    let (d, dd) = disp.at_grad(b);
    let dp = [g.v[1] - g.v[0], g.v[2] - g.v[0]];
    let dm = [g.n[1] - g.n[0], g.n[2] - g.n[0]];
    let ds = |k: usize| {
        let dmh = (dm[k] - mh * mh.dot(dm[k])) / len;
        dp[k] + mh * dd[k] + dmh * d
    };
    let ng = g.base_normal();
    let mut ns = ds(0).cross(ds(1)).normalize_or_zero();
    if ns == Vec3::ZERO {
        ns = mh;
    }
    if ns == Vec3::ZERO {
        ns = ng;
    }
    if ns == Vec3::ZERO {
        // A zero-area base face whose corner normals cancel here (the `pipeline` fuzz target:
        // a face with a corner twice): no direction is the surface's, and any unit one keeps
        // the hit record's normals unit.
        ns = Vec3::Z;
    }
    if ns.dot(mh) < 0.0 && ns.dot(ng) < 0.0 {
        ns = -ns;
    }
    let smooth = (ns - ng + mh).try_normalize().unwrap_or(ns);
    SurfacePoint {
        position: p + mh * d,
        uv,
        displacement: d,
        geometric_normal: ns,
        smooth_normal: smooth,
        base_normal: if mh == Vec3::ZERO { ns } else { mh },
    }
}

/// Solve `P(b) + λ m(b) = x` for `(b, λ)` by Newton's method from a starting guess.
/// Returns `None` if the iteration does not converge (singular Jacobian or divergence).
/// `b` is not clamped to the triangle: callers test containment themselves.
pub fn project_to_prism(
    g: &PrismGeom,
    x: Vec3,
    b_init: Vec3,
    lambda_init: f32,
) -> Option<(Vec3, f32)> {
    let (mut b1, mut b2, mut lambda) = (b_init.y, b_init.z, lambda_init);
    let dp1 = g.v[1] - g.v[0];
    let dp2 = g.v[2] - g.v[0];
    let dm1 = g.n[1] - g.n[0];
    let dm2 = g.n[2] - g.n[0];
    let scale = (dp1.length() + dp2.length()).max(1e-20);
    for _ in 0..16 {
        let b = Vec3::new(1.0 - b1 - b2, b1, b2);
        let m = g.normal_dir(b);
        let f = g.position(b) + m * lambda - x;
        if f.length() <= 1e-6 * scale {
            return Some((b, lambda));
        }
        let jac = Mat3::from_cols(dp1 + dm1 * lambda, dp2 + dm2 * lambda, m);
        let det = jac.determinant();
        if det.abs() < 1e-30 {
            return None;
        }
        let delta = jac.inverse() * f;
        b1 -= delta.x;
        b2 -= delta.y;
        lambda -= delta.z;
        if !(b1.is_finite() && b2.is_finite() && lambda.is_finite()) {
            return None;
        }
    }
    let b = Vec3::new(1.0 - b1 - b2, b1, b2);
    let f = g.position(b) + g.normal_dir(b) * lambda - x;
    (f.length() <= 1e-4 * scale).then_some((b, lambda))
}
