//! UV seams: the stitched displaced surface every method traces (`--seams stitch`, the
//! default), the height jump `validate` measures, and the bounds the bake adds for them.
//!
//! Along a seam edge (repair's `SeamEdge`: same positions and normals on both sides, other
//! UVs) the two faces sample the map at different places, so the canonical surface
//! `P + D(uv(b)) m̂` has a step there: a crack under displacement. Stitching replaces the
//! height of face A by
//!
//! ```text
//! D*(b) = D_A(b) + ½ Σ_k W_k(b) (D_k(b) − D_A(b))
//! W_k(b) = S(1 − b_k/β_k) · Π_{j≠k} S(b_j / (b_j + b_k)),    S(x) = x²(3 − 2x) on [0, 1]
//! ```
//! over A's seam edges `k` (edge `k` is opposite corner `k`, where `b_k = 0`):
//! * `D_A(b) = D(uv_A(b))`, A's own height; `D_k(b) = D(uv'_k(b))` is the neighbour's height
//!   with the neighbour's UV chart continued into A: `uv'_k` takes the neighbour's UVs at the
//!   two shared corners and, at corner `k`, the UV the neighbour's affine chart gives A's apex
//!   once A is unfolded about the edge into the neighbour's plane (`unfolded_apex_uv`).
//! * On edge `k`, `W_k = 1` and `D* = ½(D_A + D_B)` on both sides: one agreed height. The
//!   neighbour's `D_k` continues it smoothly into A, so the cross-edge derivative on both
//!   sides is `½(∂D_A + ∂D_B)`: the surface is C¹ across the seam, shading normals have no
//!   crease there.
//! * `β_k` is one texel of A in world size over A's altitude on edge `k` (barycentric units,
//!   at most `BAND_MAX`): the correction fades to zero one texel inside, with `S'(0) = S'(1)
//!   = 0`, so no crease where it ends either.
//! * The second factor of `W_k` is 1 on edge `k` and 0 on A's other two edges: every edge of
//!   A carries exactly its own target (the mean on a seam, A's raw height elsewhere), which is
//!   also what the face across it computes, so the stitched surface is continuous across every
//!   edge, seam or not. Where two targets meet at a vertex with a height jump the surface
//!   pinches: near the vertex `D*` depends on the direction of approach, and the vertex
//!   itself spans a vertical segment — closed (no ray passes), steep within about a texel.
//! * `D*` is a convex combination of `D_A` and the `D_k` (`W_j + W_k ≤ 1` for any two edges,
//!   because `S(x) + S(1 − x) = 1`), so the prism bounds only need the band footprints
//!   (`band_footprint_range`).
//!
//! A seam whose two sides differ by the same whole number of map periods at both ends, under
//! repeat wrap, samples the same texels (the torus's and the UV sphere's u = 0/1 column): its
//! jump is zero and it is not stitched, so a seam-safe tiling renders identically in both modes.

use crate::bake::{footprint_range, PrismTable};
use crate::heightmap::{DisplaceParams, HeightMap, Wrap};
use crate::mesh::SeamEdge;
use glam::{Vec2, Vec3};
use serde::Serialize;

/// Widest band, in barycentric units: keeps the bands of one face from covering it.
pub const BAND_MAX: f32 = 0.2;
/// A prism without stitched edges (`StitchField::index` sentinel).
const NONE: u32 = u32::MAX;

/// How the displaced surface treats UV seams.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SeamMode {
    /// Continuous across seam edges (the module doc's `D*`).
    #[default]
    Stitch,
    /// The raw canonical surface: each face samples its own UVs, cracks and all.
    Open,
}

impl std::str::FromStr for SeamMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "stitch" => Ok(SeamMode::Stitch),
            "open" => Ok(SeamMode::Open),
            _ => Err(format!("unknown seam mode '{s}' (expected stitch or open)")),
        }
    }
}

impl SeamMode {
    pub fn name(self) -> &'static str {
        match self {
            SeamMode::Stitch => "stitch",
            SeamMode::Open => "open",
        }
    }
}

/// The stitch data of one prism with at least one stitched edge.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PrismStitch {
    /// Per edge `k`: the neighbour's UV chart over this prism's corners (its UVs at the two
    /// shared corners, the unfolded apex at corner `k`). Unused where `band[k] == 0`.
    pub other_uv: [[Vec2; 3]; 3],
    /// Per edge `k`: the band width `β_k` (barycentric), 0 where edge `k` is not stitched.
    pub band: [f32; 3],
    /// Raw map range over the bands' footprints in the neighbours' charts
    /// (`band_footprint_range`): what a method's own bounds must add inside a band.
    pub band_h: (f32, f32),
}

impl PrismStitch {
    /// Some stitched edge's band reaches the barycentrics `b` (a point, or an affine image's
    /// corner: the minimum of an affine `b_k` over a box is at a corner).
    #[inline]
    pub fn in_band(&self, b: Vec3) -> bool {
        let b = b.to_array();
        (0..3).any(|k| self.band[k] > 0.0 && b[k] < self.band[k])
    }
}

/// Stitch data of a whole table: which prisms have stitched edges, and their data.
#[derive(Clone, Debug, Default)]
pub struct StitchField {
    /// Per prism: index into `records`, or `NONE`. Empty when nothing is stitched.
    index: Vec<u32>,
    records: Vec<PrismStitch>,
    /// Seam edges stitched (seams of zero jump by construction are not).
    pub stitched_edges: usize,
}

impl StitchField {
    pub const fn empty() -> StitchField {
        StitchField {
            index: Vec::new(),
            records: Vec::new(),
            stitched_edges: 0,
        }
    }

    /// Build from the table's seam records and geometry (UVs, texel sizes, wrap mode); the
    /// map only gives the band ranges.
    pub fn build(table: &PrismTable, map: &HeightMap) -> StitchField {
        let mut field = StitchField::default();
        for seam in &table.seams {
            if is_wrap_seam(table, seam) {
                continue;
            }
            if field.index.is_empty() {
                field.index = vec![NONE; table.prisms.len()];
            }
            for side in 0..2 {
                let prism = seam.faces[side] as usize;
                let k = seam.edges[side] as usize;
                let (other_uv, band) = edge_stitch(table, seam, side);
                if field.index[prism] == NONE {
                    field.index[prism] = field.records.len() as u32;
                    field.records.push(PrismStitch::default());
                }
                let rec = &mut field.records[field.index[prism] as usize];
                rec.other_uv[k] = other_uv;
                rec.band[k] = band;
            }
            field.stitched_edges += 1;
        }
        for rec in &mut field.records {
            rec.band_h = band_footprint_range(map, rec).unwrap_or((0.0, 0.0));
        }
        field
    }

    #[inline]
    pub fn get(&self, prism: u32) -> Option<&PrismStitch> {
        let i = *self.index.get(prism as usize)?;
        (i != NONE).then(|| &self.records[i as usize])
    }

    /// Index of prism `prism`'s record in `records()`, `None` without stitched edges (what
    /// the GPU uploads as its per-prism index).
    #[inline]
    pub fn record_index(&self, prism: u32) -> Option<u32> {
        let i = *self.index.get(prism as usize)?;
        (i != NONE).then_some(i)
    }

    /// The records of the stitched prisms, in `record_index` order.
    pub fn records(&self) -> &[PrismStitch] {
        &self.records
    }

    /// Prisms with at least one stitched edge.
    pub fn stitched_prisms(&self) -> usize {
        self.records.len()
    }

    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Heap bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.index.len() * 4 + self.records.len() * std::mem::size_of::<PrismStitch>()
    }
}

/// The two sides of `seam` differ by the same whole number of periods at both ends under
/// repeat wrap: the same texels, no jump.
fn is_wrap_seam(table: &PrismTable, seam: &SeamEdge) -> bool {
    let (a, b) = matched_uvs(table, seam);
    is_wrap_offset(table.wrap, a, b)
}

/// Ends `b` are ends `a` shifted by one whole number of map periods, under repeat wrap.
fn is_wrap_offset(wrap: Wrap, a: [Vec2; 2], b: [Vec2; 2]) -> bool {
    if wrap != Wrap::Repeat {
        return false;
    }
    let (d0, d1) = (b[0] - a[0], b[1] - a[1]);
    let whole = |d: Vec2| (d - d.round()).abs().max_element() <= 1e-6;
    whole(d0) && (d0 - d1).abs().max_element() <= 1e-6
}

/// UVs at the seam's two ends as side 0 has them (`a`) and as side 1 has them (`b`), ends in
/// side 0's order.
fn matched_uvs(table: &PrismTable, seam: &SeamEdge) -> ([Vec2; 2], [Vec2; 2]) {
    let uv = |side: usize, corner: usize| {
        let p = &table.prisms[seam.faces[side] as usize];
        table.uvs[p.tri[corner] as usize]
    };
    let [i0, j0] = seam.corners(0);
    let [i1, j1] = seam.corners(1);
    // Side 1 runs the other way: its second corner sits on side 0's first.
    ([uv(0, i0), uv(0, j0)], [uv(1, j1), uv(1, i1)])
}

/// `other_uv` and `β` for edge `seam.edges[side]` of prism `seam.faces[side]`.
fn edge_stitch(table: &PrismTable, seam: &SeamEdge, side: usize) -> ([Vec2; 3], f32) {
    let other = 1 - side;
    let pa = &table.prisms[seam.faces[side] as usize];
    let pb = &table.prisms[seam.faces[other] as usize];
    let ka = seam.edges[side] as usize;
    let kb = seam.edges[other] as usize;
    let [ia, ja] = seam.corners(side);
    let [ib, jb] = seam.corners(other);
    // A's corner ia sits on B's corner jb, ja on ib.
    let pos = |p: &crate::bake::Prism, c: usize| table.positions[p.tri[c] as usize];
    let uv = |p: &crate::bake::Prism, c: usize| table.uvs[p.tri[c] as usize];
    let e0 = pos(pa, ia);
    let e1 = pos(pa, ja);
    let (uv_e0, uv_e1) = (uv(pb, jb), uv(pb, ib));
    let apex = unfolded_apex_uv(
        [e0, e1],
        pos(pa, ka),
        pos(pb, kb),
        [uv_e0, uv_e1, uv(pb, kb)],
    )
    .unwrap_or_else(|| {
        // No usable unfolding (a zero-length edge or a zero-area neighbour, as crease
        // repair inserts): translate A's own apex by the mean offset between the charts.
        let shift = 0.5 * ((uv_e0 - uv(pa, ia)) + (uv_e1 - uv(pa, ja)));
        uv(pa, ka) + shift
    });
    let mut other_uv = [Vec2::ZERO; 3];
    other_uv[ia] = uv_e0;
    other_uv[ja] = uv_e1;
    other_uv[ka] = apex;
    let (_, alt) = edge_frame([e0, e1], pos(pa, ka));
    let band = if pa.texel_world > 0.0 && alt > 0.0 {
        (pa.texel_world / alt).clamp(1e-6, BAND_MAX)
    } else {
        BAND_MAX
    };
    (other_uv, band)
}

/// Position of `apex` in the frame of the edge `e`: (fraction along the edge, distance off it).
fn edge_frame(e: [Vec3; 2], apex: Vec3) -> (f32, f32) {
    let d = e[1] - e[0];
    let len2 = d.length_squared();
    if len2 <= 0.0 {
        return (0.0, 0.0);
    }
    let q = apex - e[0];
    let s = q.dot(d) / len2;
    (s, (q - d * s).length())
}

/// The UV that B's affine chart gives A's apex once A is unfolded about their common edge
/// `e` into B's plane, on the side away from B's apex. `uv_b` = B's UVs at `e[0]`, `e[1]` and
/// at its own apex. `None` where the edge has no length or B no height over it.
fn unfolded_apex_uv(e: [Vec3; 2], apex_a: Vec3, apex_b: Vec3, uv_b: [Vec2; 3]) -> Option<Vec2> {
    let len = (e[1] - e[0]).length();
    let (sa, ha) = edge_frame(e, apex_a);
    let (sb, hb) = edge_frame(e, apex_b);
    if !(len > 0.0 && hb > 1e-6 * len) {
        return None;
    }
    // The unfolded apex (sa·L, +ha) in B's barycentrics, B's apex at (sb·L, −hb).
    let r = ha / hb;
    let beta_apex = -r;
    let beta1 = sa + r * sb;
    let beta0 = 1.0 - beta1 - beta_apex;
    Some(uv_b[0] * beta0 + uv_b[1] * beta1 + uv_b[2] * beta_apex)
}

/// `S(x) = x²(3 − 2x)` clamped to [0, 1], and its derivative.
#[inline]
fn smooth(x: f32) -> (f32, f32) {
    if x <= 0.0 {
        (0.0, 0.0)
    } else if x >= 1.0 {
        (1.0, 0.0)
    } else {
        (x * x * (3.0 - 2.0 * x), 6.0 * x * (1.0 - x))
    }
}

/// `W_k(b)` and its derivatives with respect to `b_0, b_1, b_2` taken as independent.
#[inline]
fn band_weight(b: [f32; 3], k: usize, band: f32) -> (f32, [f32; 3]) {
    let (w, dw) = smooth(1.0 - b[k] / band);
    if w == 0.0 {
        return (0.0, [0.0; 3]);
    }
    let mut grad = [0.0; 3];
    grad[k] = -dw / band;
    let mut value = w;
    // Factors for the other two edges: 1 on edge k, 0 on theirs.
    let mut factors = [(1.0f32, [0.0f32; 3]); 2];
    for (slot, j) in [(k + 1) % 3, (k + 2) % 3].into_iter().enumerate() {
        let (bj, bk) = (b[j].max(0.0), b[k].max(0.0));
        let sum = bj + bk;
        if sum <= 0.0 {
            continue; // at the vertex itself (measure zero): 1
        }
        let (s, ds) = smooth(bj / sum);
        let mut g = [0.0; 3];
        if ds != 0.0 {
            if b[j] > 0.0 {
                g[j] = ds * bk / (sum * sum);
            }
            if b[k] > 0.0 {
                g[k] = -ds * bj / (sum * sum);
            }
        }
        factors[slot] = (s, g);
    }
    let (f0, g0) = factors[0];
    let (f1, g1) = factors[1];
    for m in 0..3 {
        grad[m] = grad[m] * f0 * f1 + w * (g0[m] * f1 + f0 * g1[m]);
    }
    value *= f0 * f1;
    (value, grad)
}

/// The displacement of one prism as every intersector evaluates it: `D(uv(b))`, or the
/// stitched `D*(b)` where the prism has stitched edges.
#[derive(Clone, Copy)]
pub struct PrismDisplacement<'a> {
    pub map: &'a HeightMap,
    pub params: DisplaceParams,
    pub uv: [Vec2; 3],
    pub stitch: Option<&'a PrismStitch>,
}

#[inline]
fn uv_at(uv: &[Vec2; 3], b: Vec3) -> Vec2 {
    uv[0] * b.x + uv[1] * b.y + uv[2] * b.z
}

impl<'a> PrismDisplacement<'a> {
    /// The raw displacement at a UV.
    #[inline]
    pub fn raw(&self, uv: Vec2) -> f32 {
        self.params.displacement(self.map.sample(uv))
    }

    /// `D` (or `D*`) at barycentrics `b`.
    #[inline]
    pub fn at(&self, b: Vec3) -> f32 {
        self.at_by(b, |uv| self.raw(uv))
    }

    /// The same construction over another reconstruction of the map, `height(uv)` (a
    /// displacement): the nonlinear method's micro-triangles, say. Stitching any continuous
    /// reconstruction this way gives a surface continuous across every edge.
    #[inline]
    pub fn at_by(&self, b: Vec3, height: impl Fn(Vec2) -> f32) -> f32 {
        let own = height(uv_at(&self.uv, b));
        match self.stitch {
            None => own,
            Some(s) => {
                let ba = b.to_array();
                let mut d = own;
                for k in 0..3 {
                    if s.band[k] > 0.0 && ba[k] < s.band[k] {
                        let (w, _) = band_weight(ba, k, s.band[k]);
                        if w > 0.0 {
                            d += 0.5 * w * (height(uv_at(&s.other_uv[k], b)) - own);
                        }
                    }
                }
                d
            }
        }
    }

    /// `D` (or `D*`) at `b` and its derivatives with respect to `(b1, b2)` (`b0 = 1 − b1 − b2`).
    pub fn at_grad(&self, b: Vec3) -> (f32, Vec2) {
        // Gradient with respect to (b0, b1, b2) as independent, projected at the end.
        let chart = |uv: &[Vec2; 3]| -> (f32, [f32; 3]) {
            let (h, gh) = self.map.sample_grad(uv_at(uv, b));
            let g = gh * self.params.scale;
            (
                self.params.displacement(h),
                [g.dot(uv[0]), g.dot(uv[1]), g.dot(uv[2])],
            )
        };
        let (own, g_own) = chart(&self.uv);
        let (mut d, mut g) = (own, g_own);
        if let Some(s) = self.stitch {
            let ba = b.to_array();
            for k in 0..3 {
                if s.band[k] > 0.0 && ba[k] < s.band[k] {
                    let (w, gw) = band_weight(ba, k, s.band[k]);
                    if w > 0.0 || gw.iter().any(|&x| x != 0.0) {
                        let (dk, g_k) = chart(&s.other_uv[k]);
                        d += 0.5 * w * (dk - own);
                        for m in 0..3 {
                            g[m] += 0.5 * (gw[m] * (dk - own) + w * (g_k[m] - g_own[m]));
                        }
                    }
                }
            }
        }
        (d, Vec2::new(g[1] - g[0], g[2] - g[0]))
    }
}

/// Raw map range over the parts of the neighbours' charts a stitched prism reads: each
/// stitched edge's band `b_k ∈ [0, β_k]`, as two UV triangles of the neighbour's chart.
/// `None` for a prism without stitched edges.
pub fn band_footprint_range(map: &HeightMap, s: &PrismStitch) -> Option<(f32, f32)> {
    let mut range: Option<(f32, f32)> = None;
    for k in 0..3 {
        if s.band[k] <= 0.0 {
            continue;
        }
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        let uv = &s.other_uv[k];
        let inner = |c: usize| uv[c] + (uv[k] - uv[c]) * s.band[k];
        for tri in [[uv[i], uv[j], inner(j)], [uv[i], inner(j), inner(i)]] {
            let (lo, hi) = footprint_range(map, &tri);
            range = Some(match range {
                None => (lo, hi),
                Some((a, b)) => (a.min(lo), b.max(hi)),
            });
        }
    }
    range
}

/// The height jump along one seam edge, sampled at the map's texel rate (at least 2 points,
/// ends included): `|D|` of side 1 minus side 0 at matching points, in world units.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SeamJump {
    pub max: f32,
    pub sum_sq: f64,
    pub samples: u32,
}

/// `seam_jump` over triangles given as vertex-index triples (a mesh's or a table's).
pub fn seam_jump(
    uvs: &[Vec2],
    tris: [[u32; 3]; 2],
    seam: &SeamEdge,
    params: &DisplaceParams,
    map: &HeightMap,
) -> SeamJump {
    let [i0, j0] = seam.corners(0);
    let [i1, j1] = seam.corners(1);
    let uv = |t: usize, c: usize| uvs[tris[t][c] as usize];
    let (a, b) = ([uv(0, i0), uv(0, j0)], [uv(1, j1), uv(1, i1)]);
    let texels =
        |e: [Vec2; 2]| ((e[1] - e[0]) * Vec2::new(map.width as f32, map.height as f32)).length();
    let n = (texels(a).max(texels(b)).ceil().min(65536.0) as u32).max(1) + 1;
    let mut out = SeamJump {
        max: 0.0,
        sum_sq: 0.0,
        samples: n,
    };
    for s in 0..n {
        let t = s as f32 / (n - 1) as f32;
        let da = params.displacement(map.sample(a[0] + (a[1] - a[0]) * t));
        let db = params.displacement(map.sample(b[0] + (b[1] - b[0]) * t));
        let jump = (db - da).abs();
        out.max = out.max.max(jump);
        out.sum_sq += (jump as f64) * (jump as f64);
    }
    out
}

/// Every seam of a repaired mesh measured against a map: totals and the worst edges.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SeamReport {
    pub seam_edges: usize,
    /// Seams whose two sides read the same texels (whole periods apart under repeat wrap).
    pub wrap_seams: usize,
    /// Largest and RMS jump over all samples, world units.
    pub max_jump: f32,
    pub rms_jump: f32,
    /// `max_jump` over `|scale|`: the jump as a fraction of the displacement scale.
    pub max_jump_rel: f32,
    /// The worst edges, largest jump first: (seam index, its max jump).
    pub worst: Vec<(usize, f32)>,
}

pub fn measure_seams(
    uvs: &[Vec2],
    triangles: &[[u32; 3]],
    seams: &[SeamEdge],
    params: &DisplaceParams,
    map: &HeightMap,
    wrap: Wrap,
    worst: usize,
) -> SeamReport {
    let mut report = SeamReport {
        seam_edges: seams.len(),
        ..SeamReport::default()
    };
    let (mut sum_sq, mut samples) = (0.0f64, 0u64);
    let mut per_edge = Vec::with_capacity(seams.len());
    for (i, seam) in seams.iter().enumerate() {
        let tris = seam.faces.map(|f| triangles[f as usize]);
        let [i0, j0] = seam.corners(0);
        let [i1, j1] = seam.corners(1);
        let uv = |t: usize, c: usize| uvs[tris[t][c] as usize];
        if is_wrap_offset(wrap, [uv(0, i0), uv(0, j0)], [uv(1, j1), uv(1, i1)]) {
            report.wrap_seams += 1;
        }
        let j = seam_jump(uvs, tris, seam, params, map);
        report.max_jump = report.max_jump.max(j.max);
        sum_sq += j.sum_sq;
        samples += j.samples as u64;
        per_edge.push((i, j.max));
    }
    report.rms_jump = if samples > 0 {
        (sum_sq / samples as f64).sqrt() as f32
    } else {
        0.0
    };
    report.max_jump_rel = if params.scale != 0.0 {
        report.max_jump / params.scale.abs()
    } else {
        0.0
    };
    per_edge.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    per_edge.truncate(worst);
    report.worst = per_edge.into_iter().filter(|e| e.1 > 0.0).collect();
    report
}

#[cfg(test)]
mod tests;
