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

use crate::heightmap::{DisplaceParams, HeightMap, Wrap};
use crate::mesh::{BaseMesh, SeamEdge, UpAxis, FACE_INSERTED};
use crate::seam::StitchField;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use serde::Serialize;

mod rebake;
pub use rebake::{rebake_for_map, RebakeStats};

/// The prism's displacement range is a single value: trace it as a plain triangle.
pub const PRISM_FLAT: u32 = 1;
/// The prism stitches a hard edge or corner (inserted by repair; zero base area).
pub const PRISM_INSERTED: u32 = 2;
/// `m_lo` fell to the floor value: a normal points (nearly) away from the face.
pub const PRISM_DEGENERATE_NORMALS: u32 = 4;

/// `Prism::flags` from this bit up hold the prism's material: an index into the asset's
/// materials (`BaseMesh::materials`, its length meaning none), 0 without any.
pub const PRISM_MATERIAL_SHIFT: u32 = 8;

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
    /// The prism's material (`PRISM_MATERIAL_SHIFT`).
    pub fn material(&self) -> u32 {
        self.flags >> PRISM_MATERIAL_SHIFT
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
    /// UV seams (repair's `SeamEdge`, faces = prisms): what stitching needs, on disk.
    pub seams: Vec<SeamEdge>,
    /// The mesh file the table was baked from, for what the table does not keep.
    pub source: TableSource,
}

/// Where a table came from: the mesh file whose cameras, materials and lights a render of the
/// table reads (the table keeps only the geometry), and the frame it was authored in.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TableSource {
    /// The mesh file, relative to the table's folder when possible; empty where unknown (a
    /// version-2 table).
    pub mesh_path: String,
    /// The UV set the table's UVs (and so the materials' textures it can read) come from.
    pub uv_set: u32,
    /// blake3 of the mesh file and the external buffers it names (`asset::mesh_hash`): a
    /// render reads the file's scene only while it still matches.
    pub mesh_hash: [u8; 32],
    /// The asset's up axis (turntables turn about it, framing stands on it).
    pub up_axis: UpAxis,
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

    /// Box that holds the prism's part of the displaced surface: the box of the six
    /// shared-wall corners (bilinear walls lie in the hull of their corners), cut down to the
    /// base triangle's box grown by `max |D|` — every surface point is `P(b) + D m̂` with a
    /// unit `m̂`, so it is within `|D|` of the base. The second box matters where normals
    /// nearly cancel (crease-repair prisms across a knife edge): there `|m|` → 0 makes the λ
    /// range, and the corner box, huge although the surface stays within `|D|` of the base.
    pub fn prism_aabb(&self, p: &Prism) -> (Vec3, Vec3) {
        let (lo, hi) = self.shared_wall_corners(p);
        let (clo, chi) = lo
            .iter()
            .chain(hi.iter())
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &c| {
                (a.min(c), b.max(c))
            });
        let (v, _) = self.prism_corners(p);
        let reach = Vec3::splat(p.d_min.abs().max(p.d_max.abs()));
        let blo = v[0].min(v[1]).min(v[2]) - reach;
        let bhi = v[0].max(v[1]).max(v[2]) + reach;
        (clo.max(blo), chi.min(bhi))
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
    let row_hi = ((ymax - 0.5).floor() as i64).saturating_add(1);
    // A footprint covering the whole map (or more) in both directions reads everything.
    let (w, h) = (map.width as f32, map.height as f32);
    let xmin = p.iter().map(|q| q.x).fold(f32::INFINITY, f32::min);
    let xmax = p.iter().map(|q| q.x).fold(f32::NEG_INFINITY, f32::max);
    if (xmax - xmin) >= w + 1.0 && (ymax - ymin) >= h + 1.0 {
        return map.value_range();
    }
    // Rows past 64 of the map's heights: the bands repeat it (or, clamped, read its edge
    // rows), so every row over the triangle's whole column extent is a superset of what they
    // read, found without walking them: a UV of 10¹⁹ was 10²⁰ bands (the `pipeline` fuzz
    // target's hang). Below that the exact walk stays (tables do not change).
    if row_hi.saturating_sub(row_lo) > 64 * map.height as i64 + 2 {
        let c0 = (xmin - 0.5).floor() as i64;
        let c1 = ((xmax - 0.5).floor() as i64).saturating_add(1);
        let (wi, hi) = (map.width as i64, map.height as i64);
        let (c0, c1) = match map.wrap {
            Wrap::Clamp => (c0.clamp(0, wi - 1), c1.clamp(0, wi - 1)),
            Wrap::Repeat => (c0, c1),
        };
        return map.texel_range(c0, c1, 0, hi - 1);
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
        let (a, b) = row_range(map, c0, c1, j);
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

/// `map.texel_range(c0, c1, j, j)` read as at most two contiguous slices of row `j`: the
/// wrap is applied once per row, not per texel (the bake's inner loop; see
/// docs/benchmarks.md).
fn row_range(map: &HeightMap, c0: i64, c1: i64, j: i64) -> (f32, f32) {
    let (w, h) = (map.width as i64, map.height as i64);
    let (y, x0, x1) = match map.wrap {
        // Columns `c0..=c1` clamp to `clamp(c0)..=clamp(c1)`.
        Wrap::Clamp => (j.clamp(0, h - 1), c0.clamp(0, w - 1), c1.clamp(0, w - 1)),
        Wrap::Repeat if c1 - c0 + 1 >= w => (j.rem_euclid(h), 0, w - 1),
        // Narrower than the map: one run, or two when it wraps past the last column.
        Wrap::Repeat => (j.rem_euclid(h), c0.rem_euclid(w), c1.rem_euclid(w)),
    };
    let row = &map.data[(y * w) as usize..((y + 1) * w) as usize];
    let (x0, x1) = (x0 as usize, x1 as usize);
    if x0 <= x1 {
        slice_range(&row[x0..=x1])
    } else {
        let (a, b) = slice_range(&row[x0..]);
        let (c, d) = slice_range(&row[..=x1]);
        (a.min(c), b.max(d))
    }
}

/// Min and max of a slice, eight lanes at a time so that the compiler vectorises it.
fn slice_range(s: &[f32]) -> (f32, f32) {
    let mut lo = [f32::INFINITY; 8];
    let mut hi = [f32::NEG_INFINITY; 8];
    let chunks = s.chunks_exact(8);
    let rest = chunks.remainder();
    for c in chunks {
        for k in 0..8 {
            lo[k] = lo[k].min(c[k]);
            hi[k] = hi[k].max(c[k]);
        }
    }
    for (k, &v) in rest.iter().enumerate() {
        lo[k] = lo[k].min(v);
        hi[k] = hi[k].max(v);
    }
    (
        lo.into_iter().fold(f32::INFINITY, f32::min),
        hi.into_iter().fold(f32::NEG_INFINITY, f32::max),
    )
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

/// World size of one texel over an inserted (zero-area) prism's part of the displaced
/// surface: the smallest, over its edges, of the edge's extent on the surface
/// (`|ΔP| + reach |Δn|`, `reach` = max |D|) per texel of the edge's UV length, and at most
/// `texel_world_size`. A crease strip's zero-length edges turn the normal through up to 60°
/// while their UVs may cross many texels (from one side's UV island to the other's): the
/// relief there is squeezed far below the base mesh's texel size, and the march step
/// (`dt = auto`, a fraction of this) has to follow it. A zero-length rung also bounds it by
/// `STRIP_TEXELS_PER_RUNG` of the rung's arc `reach |Δn|`: the strip is a sliver that wide,
/// and a ray crosses it within about that.
pub fn inserted_texel_world(
    map: &HeightMap,
    pos: &[Vec3; 3],
    n: &[Vec3; 3],
    uv: &[Vec2; 3],
    reach: f32,
) -> f32 {
    let size = Vec2::new(map.width as f32, map.height as f32);
    let mut best = texel_world_size(map, pos, uv);
    let mut take = |w: f32| best = if best > 0.0 { best.min(w) } else { w };
    let extent = (pos[1] - pos[0])
        .length()
        .max((pos[2] - pos[1]).length())
        .max((pos[0] - pos[2]).length());
    for i in 0..3 {
        let j = (i + 1) % 3;
        let texels = ((uv[j] - uv[i]) * size).length();
        let edge = (pos[j] - pos[i]).length();
        let world = edge + reach * (n[j] - n[i]).length();
        if texels > 1e-3 && world > 0.0 {
            take(world / texels);
        }
        // A rung (a zero-length edge whose normals differ): the strip is a sliver as wide as
        // the rung's displaced arc, `reach |Δn|` at most, and a ray crosses it within about
        // that; a march step of a texel would step over it.
        let rung = reach * (n[j] - n[i]).length();
        if edge <= 1e-6 * extent && rung > 0.0 {
            take(STRIP_TEXELS_PER_RUNG * rung);
        }
    }
    best
}

/// An inserted prism's texel size is at most this fraction of its widest rung arc
/// (`inserted_texel_world`): at the default step (half a texel) a ray crossing the sliver
/// where it is widest takes about eight samples in it. Measured on the rock's 10⁶ leak rays
/// (`core/examples/leak_probe.rs`): rays into the solid that PDM let through went 48 → 20 at
/// 0.5 and → 11 at 0.25, for +9.8% and +17.5% of PDM's instructions on the rock's camera
/// view (the strips on the fin's edge march finer).
pub const STRIP_TEXELS_PER_RUNG: f32 = 0.25;

/// Bake one prism record for triangle `t` of `mesh` (its own footprint; `bake` widens the
/// range of stitched prisms afterwards).
pub fn bake_prism(mesh: &BaseMesh, map: &HeightMap, params: &DisplaceParams, t: usize) -> Prism {
    let tri = mesh.triangles[t];
    let pos = mesh.corners(t);
    let n = mesh.corner_normals(t);
    let uv = mesh.corner_uvs(t);
    let (hmin, hmax) = footprint_range(map, &uv);
    let mut flags = mesh.face_material(t) << PRISM_MATERIAL_SHIFT;
    if mesh
        .face_flags
        .get(t)
        .is_some_and(|f| f & FACE_INSERTED != 0)
    {
        flags |= PRISM_INSERTED;
    }
    let (d_min, d_max) = params.displacement_range(hmin, hmax);
    let texel_world = if flags & PRISM_INSERTED != 0 {
        inserted_texel_world(map, &pos, &n, &uv, d_min.abs().max(d_max.abs()))
    } else {
        texel_world_size(map, &pos, &uv)
    };
    let p = Prism {
        tri,
        texel_world,
        flags,
        ..Prism::default()
    };
    with_height_range(p, &n, params, hmin, hmax)
}

/// `p` with its displacement range set from the raw map range `[hmin, hmax]`: `d` range,
/// λ range from the normals `n`, and the flat / degenerate-normal flags.
pub fn with_height_range(
    mut p: Prism,
    n: &[Vec3; 3],
    params: &DisplaceParams,
    hmin: f32,
    hmax: f32,
) -> Prism {
    let (d_min, d_max) = params.displacement_range(hmin, hmax);
    let raw_m_lo = {
        let c = (n[0] + n[1] + n[2]).normalize_or_zero();
        n.iter().map(|ni| ni.dot(c)).fold(f32::INFINITY, f32::min)
    };
    let m_lo = mean_normal_lower_bound(n);
    (p.lambda_lo, p.lambda_hi) = lambda_range(d_min, d_max, m_lo);
    (p.d_min, p.d_max) = (d_min, d_max);
    p.flags &= !(PRISM_FLAT | PRISM_DEGENERATE_NORMALS);
    if d_min == d_max {
        p.flags |= PRISM_FLAT;
    }
    if raw_m_lo < M_LO_FLOOR {
        p.flags |= PRISM_DEGENERATE_NORMALS;
    }
    p
}

/// The raw map range prism `i` of `table` must bound: its own UV footprint, and with
/// stitched edges the neighbours' band footprints too (`seam::band_footprint_range`).
pub fn prism_height_range(
    table: &PrismTable,
    field: &StitchField,
    map: &HeightMap,
    i: usize,
) -> (f32, f32) {
    let (lo, hi) = footprint_range(map, &table.prism_uvs(&table.prisms[i]));
    match field.get(i as u32) {
        Some(s) => (lo.min(s.band_h.0), hi.max(s.band_h.1)),
        None => (lo, hi),
    }
}

/// Bake every prism (in parallel; the result does not depend on the thread count). The
/// ranges of prisms next to stitched seams include what stitching reads across them, so one
/// table serves `--seams stitch` and `--seams open`.
pub fn bake(mesh: &BaseMesh, map: &HeightMap, opts: &BakeOptions) -> PrismTable {
    let prisms = (0..mesh.triangle_count())
        .into_par_iter()
        .map(|t| bake_prism(mesh, map, &opts.params, t))
        .collect();
    let mut table = PrismTable {
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
        seams: mesh.seams.clone(),
        source: TableSource {
            mesh_path: mesh.source.to_string_lossy().into_owned(),
            up_axis: mesh.up_axis.unwrap_or_default(),
            ..TableSource::default()
        },
    };
    let field = StitchField::build(&table, map);
    for i in 0..table.prisms.len() {
        if field.get(i as u32).is_some() {
            let (hmin, hmax) = prism_height_range(&table, &field, map, i);
            let (_, n) = table.prism_corners(&table.prisms[i]);
            table.prisms[i] = with_height_range(table.prisms[i], &n, &opts.params, hmin, hmax);
        }
    }
    table
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::BaseMesh;
    use crate::rng::{pcg_hash, to_unit_float};

    struct Rng(u32);
    impl Rng {
        fn unit(&mut self) -> f32 {
            self.0 = pcg_hash(self.0);
            to_unit_float(self.0)
        }
        fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * self.unit()
        }
        fn below(&mut self, n: u32) -> u32 {
            self.0 = pcg_hash(self.0);
            self.0 % n
        }
    }

    /// A crease strip's sliver (A, B, B with the normal turning 60° along the rung B–B) is
    /// marched at a quarter of its widest rung arc, not at the texel of its long edge: would
    /// fail if the rung (zero length, zero UV length) were skipped again, and a half-texel
    /// step crossed the sliver between two samples.
    #[test]
    fn strip_texel_follows_the_rung_arc() {
        let map = HeightMap::new(64, 64, vec![0.5; 64 * 64], Wrap::Repeat);
        let (a, b) = (Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0));
        let n1 = Vec3::Z;
        let n2 = Vec3::new(0.0, -(60f32.to_radians().sin()), 60f32.to_radians().cos());
        let pos = [a, b, b];
        let n = [n1, n1, n2];
        let uv = [
            Vec2::new(0.1, 0.5),
            Vec2::new(0.6, 0.5),
            Vec2::new(0.6, 0.5),
        ];
        let reach = 0.02;
        let long_edge = texel_world_size(&map, &pos, &uv);
        let strip = inserted_texel_world(&map, &pos, &n, &uv, reach);
        let rung = reach * (n2 - n1).length();
        assert!(long_edge > 0.0 && strip < long_edge, "{strip} {long_edge}");
        assert!(
            (strip - STRIP_TEXELS_PER_RUNG * rung).abs() < 1e-6 * rung,
            "{strip} {rung}"
        );
        // A face with no zero-length edge keeps its texel size.
        let face = [a, b, Vec3::new(0.0, 1.0, 0.0)];
        let uvf = [
            Vec2::new(0.1, 0.5),
            Vec2::new(0.6, 0.5),
            Vec2::new(0.1, 1.0),
        ];
        let plain = inserted_texel_world(&map, &face, &[n1; 3], &uvf, reach);
        assert_eq!(plain, texel_world_size(&map, &face, &uvf));
    }

    /// A small map of raw values in [-0.5, 1.5] (float maps may leave [0, 1]), odd sizes so
    /// that texel rows and columns do not line up with UV fractions.
    fn random_map(rng: &mut Rng, wrap: Wrap) -> HeightMap {
        let (w, h) = (1 + rng.below(13), 1 + rng.below(11));
        let data = (0..w * h).map(|_| rng.range(-0.5, 1.5)).collect();
        HeightMap::new(w, h, data, wrap)
    }

    /// A UV triangle from sub-texel to several map widths across, centred anywhere in
    /// [-1.5, 2.5]² so that repeat wrap-around and clamped borders are both exercised.
    fn random_uv_triangle(rng: &mut Rng, map: &HeightMap) -> [Vec2; 3] {
        let centre = Vec2::new(rng.range(-1.5, 2.5), rng.range(-1.5, 2.5));
        let texel = 1.0 / map.width.max(map.height) as f32;
        let size = texel * 0.05 * (60.0 / texel).powf(rng.unit()); // log-uniform, up to ~3 UV units
        std::array::from_fn(|_| {
            centre + Vec2::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)) * size
        })
    }

    /// Dense barycentric lattice plus random interior points of the triangle.
    fn samples(rng: &mut Rng, uv: &[Vec2; 3]) -> Vec<(Vec3, Vec2)> {
        let n = 24;
        let mut out = Vec::new();
        for i in 0..=n {
            for j in 0..=n - i {
                let b = Vec3::new(i as f32, j as f32, (n - i - j) as f32) / n as f32;
                out.push(b);
            }
        }
        for _ in 0..200 {
            let (a, c) = (rng.unit(), rng.unit());
            let (a, c) = if a + c > 1.0 {
                (1.0 - a, 1.0 - c)
            } else {
                (a, c)
            };
            out.push(Vec3::new(1.0 - a - c, a, c));
        }
        out.into_iter()
            .map(|b| (b, uv[0] * b.x + uv[1] * b.y + uv[2] * b.z))
            .collect()
    }

    /// The footprint bound is what every intersector's prism extent rests on: a bilinear
    /// sample inside the UV triangle that escapes `[hmin, hmax]` is a surface point outside
    /// its prism, i.e. a hole. Brute force: sample the triangle densely, for both wraps.
    #[test]
    fn footprint_range_contains_every_bilinear_sample() {
        let mut rng = Rng(0x5eed);
        for case in 0..600 {
            let wrap = if case % 2 == 0 {
                Wrap::Repeat
            } else {
                Wrap::Clamp
            };
            let map = random_map(&mut rng, wrap);
            let uv = random_uv_triangle(&mut rng, &map);
            let (lo, hi) = footprint_range(&map, &uv);
            assert!(lo <= hi, "case {case}: empty range for {uv:?}");
            for (_, p) in samples(&mut rng, &uv) {
                let s = map.sample(p);
                // Bilinear interpolation may round one ulp past its corner values.
                let tol = 1e-6 * s.abs().max(1.0);
                assert!(
                    s >= lo - tol && s <= hi + tol,
                    "case {case} ({wrap:?}, {}x{}): sample {s} at {p} outside [{lo}, {hi}] for {uv:?}",
                    map.width,
                    map.height
                );
            }
        }
    }

    /// A footprint many map heights tall but narrow is not walked band by band (a UV of
    /// 10¹⁹ was 10²⁰ bands, a hang): it takes every row over its column extent, a superset
    /// that still holds every sample, for both wraps.
    #[test]
    fn a_footprint_many_maps_tall_is_bounded_without_walking_it() {
        let mut rng = Rng(0x7a11);
        for wrap in [Wrap::Repeat, Wrap::Clamp] {
            let map = random_map(&mut rng, wrap);
            let uv = [
                Vec2::new(0.3, 0.2),
                Vec2::new(0.35, 0.2),
                Vec2::new(0.3, 1e7),
            ];
            let t0 = std::time::Instant::now();
            let (lo, hi) = footprint_range(&map, &uv);
            assert!(
                t0.elapsed().as_secs_f32() < 1.0,
                "{wrap:?}: walked the bands"
            );
            for (_, p) in samples(&mut rng, &uv) {
                let s = map.sample(p);
                assert!(
                    s >= lo - 1e-6 && s <= hi + 1e-6,
                    "{wrap:?}: {s} at {p} outside [{lo}, {hi}]"
                );
            }
        }
    }

    /// The pre-optimisation scan (wrap applied per texel through `HeightMap::texel_range`):
    /// the row-slice version must give the very same range, so tables do not change.
    fn footprint_range_per_texel(map: &HeightMap, uv: &[Vec2; 3]) -> (f32, f32) {
        let p = uv.map(|t| map.texel_coords(t));
        let ymin = p.iter().map(|q| q.y).fold(f32::INFINITY, f32::min);
        let ymax = p.iter().map(|q| q.y).fold(f32::NEG_INFINITY, f32::max);
        let (w, h) = (map.width as f32, map.height as f32);
        let xmin = p.iter().map(|q| q.x).fold(f32::INFINITY, f32::min);
        let xmax = p.iter().map(|q| q.x).fold(f32::NEG_INFINITY, f32::max);
        if (xmax - xmin) >= w + 1.0 && (ymax - ymin) >= h + 1.0 {
            return map.value_range();
        }
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for j in (ymin - 0.5).floor() as i64..=(ymax - 0.5).floor() as i64 + 1 {
            let Some((x0, x1)) = triangle_band_x_extent(&p, (j as f32 - 0.5, j as f32 + 1.5))
            else {
                continue;
            };
            let (a, b) = map.texel_range(
                (x0 - 0.5).floor() as i64,
                (x1 - 0.5).floor() as i64 + 1,
                j,
                j,
            );
            lo = lo.min(a);
            hi = hi.max(b);
        }
        if lo > hi {
            let q = p[0] - Vec2::splat(0.5);
            let (x, y) = (q.x.floor() as i64, q.y.floor() as i64);
            return map.texel_range(x, x + 1, y, y + 1);
        }
        (lo, hi)
    }

    #[test]
    fn row_slices_give_the_per_texel_range() {
        let mut rng = Rng(0x0dd5);
        for case in 0..3000 {
            let wrap = if case % 2 == 0 {
                Wrap::Repeat
            } else {
                Wrap::Clamp
            };
            let mut map = random_map(&mut rng, wrap);
            if case % 5 == 0 {
                // Wide rows, so that the eight-lane loop and its remainder both run.
                let w = 8 + rng.below(40);
                map = HeightMap::new(
                    w,
                    3,
                    (0..w * 3).map(|_| rng.range(-0.5, 1.5)).collect(),
                    wrap,
                );
            }
            let uv = random_uv_triangle(&mut rng, &map);
            assert_eq!(
                footprint_range(&map, &uv),
                footprint_range_per_texel(&map, &uv),
                "case {case}: {uv:?}"
            );
        }
    }

    /// The whole prism: the canonical surface `P + D m/|m|` sits at `λ = D/|m|` on the line
    /// `P + λ m`; for random normals tilted off the face (up to the floor of `m_lo`), negative
    /// scales (displacement below the base) and midlevels, every sampled point's `D` is in
    /// `[d_min, d_max]` and its `λ` in `[lambda_lo, lambda_hi]`.
    #[test]
    fn bake_prism_extent_contains_the_canonical_surface() {
        let mut rng = Rng(0xba4e);
        for case in 0..400 {
            let wrap = if case % 3 == 0 {
                Wrap::Clamp
            } else {
                Wrap::Repeat
            };
            let map = random_map(&mut rng, wrap);
            let uv = random_uv_triangle(&mut rng, &map);
            let positions = vec![
                Vec3::ZERO,
                Vec3::new(1.0, 0.1, 0.0),
                Vec3::new(0.2, 0.9, 0.0),
            ];
            let tilt = rng.range(0.0, 1.2);
            let normals: Vec<Vec3> = (0..3)
                .map(|_| {
                    (Vec3::Z + Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 0.0) * tilt)
                        .normalize()
                })
                .collect();
            let mesh = BaseMesh {
                positions,
                normals: normals.clone(),
                uvs: uv.to_vec(),
                triangles: vec![[0, 1, 2]],
                face_group: vec![0],
                face_flags: vec![0],
                ..Default::default()
            };
            let params = DisplaceParams {
                scale: rng.range(-0.3, 0.3),
                midlevel: rng.range(-0.2, 1.2),
            };
            let p = bake_prism(&mesh, &map, &params, 0);
            assert!(
                p.d_min <= p.d_max && p.lambda_lo <= p.lambda_hi,
                "case {case}: {p:?}"
            );
            for (b, t) in samples(&mut rng, &uv) {
                let d = params.displacement(map.sample(t));
                let tol = 1e-5 * d.abs().max(1e-3);
                assert!(
                    d >= p.d_min - tol && d <= p.d_max + tol,
                    "case {case}: D = {d} outside {p:?}"
                );
                let m = (normals[0] * b.x + normals[1] * b.y + normals[2] * b.z).length();
                if p.flags & PRISM_DEGENERATE_NORMALS != 0 || m < M_LO_FLOOR {
                    continue; // the λ range is clamped there by design (and flagged)
                }
                let lambda = d / m;
                let tol = 1e-4 * lambda.abs().max(1e-3);
                assert!(
                    lambda >= p.lambda_lo - tol && lambda <= p.lambda_hi + tol,
                    "case {case}: λ = {lambda} outside {p:?} (|m| = {m})"
                );
            }
        }
    }

    /// An inserted strip triangle's relief is squeezed into its rounded edge: its texel size
    /// must be measured on the displaced strip (else `dt = auto` steps over whole bumps).
    /// Would break if inserted prisms took the base edge's texel size again.
    #[test]
    fn inserted_strip_texel_size_follows_its_squeezed_uvs() {
        let map = HeightMap::new(
            64,
            64,
            (0..64 * 64).map(|i| (i % 7) as f32 / 7.0).collect(),
            Wrap::Repeat,
        );
        let (p, q) = (Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0));
        let n0 = Vec3::Y;
        let n1 = Vec3::new(0.0, 0.5, 3f32.sqrt() / 2.0); // 60° from n0: |n1 − n0| = 1
        let texel = 1.0 / 64.0;
        // The zero-length edge (slots 0–1) crosses 40 texels of UV; the real edge 8.
        let mesh = BaseMesh {
            positions: vec![p, p, q],
            normals: vec![n0, n1, n0],
            uvs: vec![
                Vec2::new(0.1, 0.5),
                Vec2::new(0.1 + 40.0 * texel, 0.5),
                Vec2::new(0.1, 0.5 + 8.0 * texel),
            ],
            triangles: vec![[0, 1, 2]],
            face_group: vec![0],
            face_flags: vec![FACE_INSERTED],
            ..Default::default()
        };
        let params = DisplaceParams {
            scale: 0.1,
            midlevel: 0.5,
        };
        let prism = bake_prism(&mesh, &map, &params, 0);
        let reach = prism.d_min.abs().max(prism.d_max.abs());
        assert!(reach > 0.04);
        let want = reach * 1.0 / 40.0;
        assert!(
            (prism.texel_world - want).abs() < 1e-3 * want,
            "{} vs {want}",
            prism.texel_world
        );
        // The estimate it replaces (longest world edge over longest UV edge) is ~20× larger.
        let base = texel_world_size(&map, &[p, p, q], &[mesh.uvs[0], mesh.uvs[1], mesh.uvs[2]]);
        assert!(base > 4.0 * prism.texel_world, "{base}");
        // Regular faces keep the area-ratio texel size.
        let mut regular = mesh.clone();
        regular.positions[1] = Vec3::new(0.0, 0.0, 1.0);
        regular.face_flags = vec![0];
        let r = bake_prism(&regular, &map, &params, 0);
        let pos = [
            regular.positions[0],
            regular.positions[1],
            regular.positions[2],
        ];
        assert_eq!(
            r.texel_world,
            texel_world_size(&map, &pos, &[mesh.uvs[0], mesh.uvs[1], mesh.uvs[2]])
        );
    }
}
