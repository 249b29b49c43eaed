//! Stage 3: bake a `PrismTable` from a repaired mesh and a height map.
//!
//! The table stores what every intersector needs, not one construction's corners: base
//! vertices, unit vertex normals, UVs, and per prism the displacement range over the
//! triangle's whole UV footprint, the matching extrusion range `λ`, and the world texel size.
//! Corners are derived on demand:
//!
//! * `shared_wall_corners` — DESIGN.md's watertight prism `{Σ b_i (V_i + λ n_i)}` with one
//!   `λ ∈ [lambda_lo, lambda_hi]` per prism: neighbours share their bilinear walls exactly.
//! * `parallel_offset_corners` — the paper's eq. 4–6 prism `V_i + w n_i / (n_i·N_g)`, offset
//!   triangles parallel to the base, `w ∈ [w_lo, w_hi]` measured along `N_g`.
//!
//! Bounds: the canonical surface is `S(b) = P(b) + D(uv(b)) m(b)/|m(b)|` with `m = Σ b_i n_i`.
//! On the line `P + λ m` that is `λ = D / |m|`. `|m|` is at most 1 (convex combination of unit
//! vectors) and at least `m_lo = min_i n_i·ĉ` for the unit mean normal `ĉ` (a linear lower
//! bound of a convex function, minimised at a vertex). So `λ ∈ [min(dmin, dmin/m_lo),
//! max(dmax, dmax/m_lo)]` bounds the surface for any `D ∈ [dmin, dmax]`.

use crate::heightmap::{DisplaceParams, HeightMap};
use crate::mesh::{BaseMesh, FACE_INSERTED};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use serde::Serialize;

/// The prism's displacement range is a single value: trace it as a plain triangle.
pub const PRISM_FLAT: u32 = 1;
/// The prism stitches a hard edge or corner (inserted by repair; zero base area).
pub const PRISM_INSERTED: u32 = 2;
/// `m_lo` fell to the floor value: a normal points (nearly) away from the face.
pub const PRISM_DEGENERATE_NORMALS: u32 = 4;

/// Smallest `m_lo` accepted; below it the λ range is clamped (and the prism flagged).
pub const M_LO_FLOOR: f32 = 1e-3;

/// Per-prism record; 36 bytes on disk (see docs/prism-format.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Prism {
    pub tri: [u32; 3],
    /// Displacement range `D` over the footprint (world units, along the unit normal).
    pub d_min: f32,
    pub d_max: f32,
    /// Extrusion range along the unnormalised interpolated normal `m(b)`.
    pub lambda_lo: f32,
    pub lambda_hi: f32,
    /// World-space edge length of one texel over this triangle.
    pub texel_world: f32,
    pub flags: u32,
}

impl Prism {
    pub fn is_flat(&self) -> bool {
        self.flags & PRISM_FLAT != 0
    }
}

#[derive(Clone, Debug, Default)]
pub struct PrismTable {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    pub prisms: Vec<Prism>,
    pub params: DisplaceParams,
    pub map_width: u32,
    pub map_height: u32,
    /// blake3 of (mesh bytes, map bytes, parameters, options, format version).
    pub input_hash: [u8; 32],
    /// Path of the height map relative to the table file (as written), for standalone renders.
    pub map_path: String,
    pub wrap: crate::heightmap::Wrap,
}

#[derive(Clone, Copy, Debug)]
pub struct BakeOptions {
    pub params: DisplaceParams,
}

impl PrismTable {
    pub fn prism_corners(&self, p: &Prism) -> ([Vec3; 3], [Vec3; 3]) {
        (
            p.tri.map(|i| self.positions[i as usize]),
            p.tri.map(|i| self.normals[i as usize]),
        )
    }
    pub fn prism_uvs(&self, p: &Prism) -> [Vec2; 3] {
        p.tri.map(|i| self.uvs[i as usize])
    }

    /// DESIGN.md's watertight prism: bottom `V_i + λlo n_i`, top `V_i + λhi n_i`.
    pub fn shared_wall_corners(&self, p: &Prism) -> ([Vec3; 3], [Vec3; 3]) {
        let (v, n) = self.prism_corners(p);
        (
            std::array::from_fn(|i| v[i] + n[i] * p.lambda_lo),
            std::array::from_fn(|i| v[i] + n[i] * p.lambda_hi),
        )
    }

    /// The paper's parallel offset prism (eq. 4–6): level-`w` triangles `V_i + w n_i/(n_i·N_g)`
    /// lie in the plane at height `w` along `N_g`. The surface height `D (m̂·N_g)` is bounded
    /// with `m̂·N_g ∈ [min_i n_i·N_g, 1]`. Laterally the surface can leave this prism near its
    /// edges (the paper's construction is not watertight; see docs/watertightness.md).
    pub fn parallel_offset_corners(&self, p: &Prism) -> ([Vec3; 3], [Vec3; 3]) {
        let (v, n) = self.prism_corners(p);
        let ng = (v[1] - v[0]).cross(v[2] - v[0]).normalize_or_zero();
        let dots = n.map(|ni| ni.dot(ng).max(M_LO_FLOOR));
        let f_min = dots[0].min(dots[1]).min(dots[2]);
        let w_lo = if p.d_min < 0.0 {
            p.d_min
        } else {
            p.d_min * f_min
        };
        let w_hi = if p.d_max > 0.0 {
            p.d_max
        } else {
            p.d_max * f_min
        };
        (
            std::array::from_fn(|i| v[i] + n[i] * (w_lo / dots[i])),
            std::array::from_fn(|i| v[i] + n[i] * (w_hi / dots[i])),
        )
    }

    /// Box of the six shared-wall corners (bilinear walls lie in the hull of their corners).
    pub fn prism_aabb(&self, p: &Prism) -> (Vec3, Vec3) {
        let (lo, hi) = self.shared_wall_corners(p);
        lo.iter()
            .chain(hi.iter())
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &c| {
                (a.min(c), b.max(c))
            })
    }

    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.prisms
            .iter()
            .map(|p| self.prism_aabb(p))
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), (lo, hi)| {
                (a.min(lo), b.max(hi))
            })
    }

    pub fn flat_count(&self) -> usize {
        self.prisms.iter().filter(|p| p.is_flat()).count()
    }
}

/// `min_i n_i·ĉ` for the unit mean normal `ĉ`: a lower bound of `|Σ b_i n_i|` over the
/// triangle, floored at `M_LO_FLOOR`.
pub fn mean_normal_lower_bound(n: &[Vec3; 3]) -> f32 {
    let c = (n[0] + n[1] + n[2]).normalize_or_zero();
    n.iter()
        .map(|ni| ni.dot(c))
        .fold(f32::INFINITY, f32::min)
        .max(M_LO_FLOOR)
}

/// Extrusion range `[λlo, λhi]` that contains `λ = D/|m|` for all `D ∈ [d_min, d_max]`.
pub fn lambda_range(d_min: f32, d_max: f32, m_lo: f32) -> (f32, f32) {
    let lo = if d_min < 0.0 { d_min / m_lo } else { d_min };
    let hi = if d_max > 0.0 { d_max / m_lo } else { d_max };
    (lo, hi)
}

/// Raw map range `[hmin, hmax]` over every texel that bilinear sampling can read anywhere in
/// the UV triangle (wrap applied). Rasterises the triangle row by row in texel space: a sample
/// at continuous row coordinate `y` reads rows `floor(y - 0.5)` and the one after, so row `j`
/// is read by points with `y ∈ [j - 0.5, j + 1.5)`; the same holds for columns.
pub fn footprint_range(map: &HeightMap, uv: &[Vec2; 3]) -> (f32, f32) {
    let p = uv.map(|t| map.texel_coords(t));
    let ymin = p.iter().map(|q| q.y).fold(f32::INFINITY, f32::min);
    let ymax = p.iter().map(|q| q.y).fold(f32::NEG_INFINITY, f32::max);
    let row_lo = (ymin - 0.5).floor() as i64;
    let row_hi = (ymax - 0.5).floor() as i64 + 1;
    // A footprint covering the whole map (or more) in both directions reads everything.
    let (w, h) = (map.width as f32, map.height as f32);
    let xmin = p.iter().map(|q| q.x).fold(f32::INFINITY, f32::min);
    let xmax = p.iter().map(|q| q.x).fold(f32::NEG_INFINITY, f32::max);
    if (xmax - xmin) >= w + 1.0 && (ymax - ymin) >= h + 1.0 {
        return map.value_range();
    }
    let mut lo = f32::INFINITY;
    let mut hi = f32::NEG_INFINITY;
    for j in row_lo..=row_hi {
        let band = (j as f32 - 0.5, j as f32 + 1.5);
        let Some((x0, x1)) = triangle_band_x_extent(&p, band) else {
            continue;
        };
        let c0 = (x0 - 0.5).floor() as i64;
        let c1 = (x1 - 0.5).floor() as i64 + 1;
        let (a, b) = map.texel_range(c0, c1, j, j);
        lo = lo.min(a);
        hi = hi.max(b);
    }
    if lo > hi {
        // Degenerate footprint (a point): read its bilinear neighbourhood.
        let q = p[0] - Vec2::splat(0.5);
        let (x, y) = (q.x.floor() as i64, q.y.floor() as i64);
        return map.texel_range(x, x + 1, y, y + 1);
    }
    (lo, hi)
}

/// x-extent of a triangle clipped to the horizontal band `y ∈ [y0, y1]`, if they meet.
fn triangle_band_x_extent(p: &[Vec2; 3], (y0, y1): (f32, f32)) -> Option<(f32, f32)> {
    let mut lo = f32::INFINITY;
    let mut hi = f32::NEG_INFINITY;
    let mut add = |x: f32| {
        lo = lo.min(x);
        hi = hi.max(x);
    };
    for i in 0..3 {
        let (a, b) = (p[i], p[(i + 1) % 3]);
        if a.y >= y0 && a.y <= y1 {
            add(a.x);
        }
        // Edge crossings with the band's two lines.
        for y in [y0, y1] {
            if (a.y - y) * (b.y - y) < 0.0 {
                let t = (y - a.y) / (b.y - a.y);
                add(a.x + (b.x - a.x) * t);
            }
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// World-space size of one texel over a triangle (square root of the area ratio).
pub fn texel_world_size(map: &HeightMap, pos: &[Vec3; 3], uv: &[Vec2; 3]) -> f32 {
    let area_world = 0.5 * (pos[1] - pos[0]).cross(pos[2] - pos[0]).length();
    let d1 = (uv[1] - uv[0]) * Vec2::new(map.width as f32, map.height as f32);
    let d2 = (uv[2] - uv[0]) * Vec2::new(map.width as f32, map.height as f32);
    let area_texels = 0.5 * d1.perp_dot(d2).abs();
    if area_texels > 1e-12 && area_world > 0.0 {
        (area_world / area_texels).sqrt()
    } else {
        // UV-degenerate or inserted faces: use the longest edge over its texel length.
        let edge_world = (0..3)
            .map(|i| (pos[(i + 1) % 3] - pos[i]).length())
            .fold(0.0, f32::max);
        let edge_tex = (0..3)
            .map(|i| {
                ((uv[(i + 1) % 3] - uv[i]) * Vec2::new(map.width as f32, map.height as f32))
                    .length()
            })
            .fold(0.0, f32::max);
        if edge_tex > 1e-6 && edge_world > 0.0 {
            edge_world / edge_tex
        } else {
            0.0
        }
    }
}

/// Bake one prism record for triangle `t` of `mesh`.
pub fn bake_prism(mesh: &BaseMesh, map: &HeightMap, params: &DisplaceParams, t: usize) -> Prism {
    let tri = mesh.triangles[t];
    let pos = mesh.corners(t);
    let n = mesh.corner_normals(t);
    let uv = mesh.corner_uvs(t);
    let (hmin, hmax) = footprint_range(map, &uv);
    let (d_min, d_max) = params.displacement_range(hmin, hmax);
    let raw_m_lo = {
        let c = (n[0] + n[1] + n[2]).normalize_or_zero();
        n.iter().map(|ni| ni.dot(c)).fold(f32::INFINITY, f32::min)
    };
    let m_lo = mean_normal_lower_bound(&n);
    let (lambda_lo, lambda_hi) = lambda_range(d_min, d_max, m_lo);
    let mut flags = 0;
    if d_min == d_max {
        flags |= PRISM_FLAT;
    }
    if mesh
        .face_flags
        .get(t)
        .is_some_and(|f| f & FACE_INSERTED != 0)
    {
        flags |= PRISM_INSERTED;
    }
    if raw_m_lo < M_LO_FLOOR {
        flags |= PRISM_DEGENERATE_NORMALS;
    }
    Prism {
        tri,
        d_min,
        d_max,
        lambda_lo,
        lambda_hi,
        texel_world: texel_world_size(map, &pos, &uv),
        flags,
    }
}

/// Bake every prism (in parallel; the result does not depend on the thread count).
pub fn bake(mesh: &BaseMesh, map: &HeightMap, opts: &BakeOptions) -> PrismTable {
    let prisms = (0..mesh.triangle_count())
        .into_par_iter()
        .map(|t| bake_prism(mesh, map, &opts.params, t))
        .collect();
    PrismTable {
        positions: mesh.positions.clone(),
        normals: mesh.normals.clone(),
        uvs: mesh.uvs.clone(),
        prisms,
        params: opts.params,
        map_width: map.width,
        map_height: map.height,
        input_hash: [0; 32],
        map_path: map.source.to_string_lossy().into_owned(),
        wrap: map.wrap,
    }
}
