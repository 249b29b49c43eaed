//! Tessellate the canonical displaced surface `S(b) = P(b) + D(uv(b)) m̂(b)` (DESIGN.md) at
//! `k`× the texel rate: the geometry of the `reference` intersector, the ground truth of every
//! error figure. In: a `PrismTable` and its `HeightMap`; out: a `TessMesh` of micro-triangles,
//! each tagged with its source prism and its corners' barycentrics in that prism's triangle.
//!
//! Watertight by construction, so a leak found by the reference is a leak of the surface:
//! * every base edge (keyed by its two vertex indices, unordered) gets one segment count
//!   `n_e = max(1, ceil(k · edge length in texels))` (or more where its normals turn far:
//!   `TURN_PER_SEGMENT`), the same for both of its faces, and is
//!   split into exactly those `n_e` segments on both sides (no T-junctions);
//! * a face whose three edges agree on `n` is the plain `n × n` barycentric grid; otherwise
//!   (`n = max n_e`) the grid's interior points form an inner triangle and each base edge is
//!   zipped to the inner side parallel to it (a centroid fan when `n = 2`). Snapping the
//!   grid's boundary points onto the coarser edges instead would fold micro-triangles over
//!   near the corners (a boundary point can move by half a coarse segment);
//! * edge vertices are evaluated once, from the canonical orientation (lower vertex index
//!   first), and shared by index; corners are the base vertices themselves.
//!
//! On a stitched surface (`SeamMode::Stitch`) the two sides of a UV seam are one edge: seam
//! twins (records linked by seams) share one representative index, so a seam edge has one
//! segment count and one set of points, evaluated through the first face that has it (both
//! faces agree there: `seam`'s construction); a twin group's corner is one micro-vertex at the
//! mean of its records' heights (the stitched surface pinches there, so any one height closes
//! it).

use crate::bake::{Prism, PrismTable};
use crate::canonical::{surface_point, PrismGeom, Surface};
use crate::heightmap::HeightMap;
use crate::seam::SeamMode;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::collections::{BTreeMap, HashMap};

/// Most segments along one base edge (and so across one face). A 4096² grid is ~33 M
/// micro-triangles per base face (1.7 GB with their records); anything finer is a unit
/// error, not a request.
pub const MAX_SEGMENTS: u32 = 4096;

/// The tessellated surface. Vertex order: the base vertices (same indices as the table), then
/// the interior vertices of every edge in `(vmin, vmax)` order, then each face's interior.
#[derive(Clone, Debug, Default)]
pub struct TessMesh {
    pub positions: Vec<Vec3>,
    /// Counter-clockwise seen from the side the base normals point to, like the base faces.
    pub triangles: Vec<[u32; 3]>,
    /// Source prism of each micro-triangle.
    pub tri_prism: Vec<u32>,
    /// Barycentrics in the source prism's base triangle of each micro-triangle's corners: a hit
    /// with micro-barycentrics `w` lies over `Σ w_i tri_bary[i]`.
    pub tri_bary: Vec<[Vec3; 3]>,
    /// Base edges whose segment count was clamped to `MAX_SEGMENTS`.
    pub capped_edges: usize,
}

impl TessMesh {
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }
    /// Heap bytes held by the mesh.
    pub fn memory_bytes(&self) -> usize {
        self.positions.len() * std::mem::size_of::<Vec3>()
            + self.triangles.len() * std::mem::size_of::<[u32; 3]>()
            + self.tri_prism.len() * std::mem::size_of::<u32>()
            + self.tri_bary.len() * std::mem::size_of::<[Vec3; 3]>()
    }
}

/// One base edge's segmentation: `n` segments, interior vertices at `start .. start + n - 1`.
#[derive(Clone, Copy, Debug)]
struct EdgeSplit {
    n: u32,
    start: u32,
}

#[inline]
fn edge_key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// `k ·` the length of edge a–b in texels, or `k ·` its normals' turn over `TURN_PER_SEGMENT`
/// where that is more, unclamped. A UV-degenerate edge (zero length in UV) reads one texel
/// all along, so its displaced image is the base edge pushed out by one height along the
/// turning normal: straight where the normals agree, and otherwise an arc of the prism's
/// largest `|D|` times the normal's turn, which it follows at the prism's world texel size
/// (as `bake::inserted_texel_world` measures a crease strip), so that a strip's rung, a
/// zero-length edge whose normals differ, is that arc instead of one chord of it. The base
/// edge's own length does not count: a long edge of a strip whose UVs meet is one straight
/// segment, and counting it at a rung-sized texel (a micrometre) asked for 4096 segments, a
/// 4096² grid of 1.8 GB for one face of a three-triangle mesh (the `pipeline` fuzz target).
/// Nor does an arc take more than `MAX_ARC_TEXELS` texels: a strip's texel is a quarter of
/// its narrowest rung's arc (`bake::STRIP_TEXELS_PER_RUNG`), and a rung that barely turns
/// (10⁻⁸ rad) made every other rung's arc hundreds of millions of texels long, the same
/// 4096² grid.
fn edge_segments_wanted(
    table: &PrismTable,
    map: &HeightMap,
    p: &Prism,
    a: u32,
    b: u32,
    k: f32,
) -> f32 {
    let texel_scale = Vec2::new(map.width as f32, map.height as f32);
    let texels = ((table.uvs[b as usize] - table.uvs[a as usize]) * texel_scale).length();
    // Below a millionth of a texel the UV edge is a point: its length says nothing.
    let texels = if texels > 1e-6 {
        texels
    } else if p.texel_world > 0.0 {
        let reach = p.d_min.abs().max(p.d_max.abs());
        let (a, b) = (a as usize, b as usize);
        let arc = reach * (table.normals[b] - table.normals[a]).length();
        arc / p.texel_world.max(arc / MAX_ARC_TEXELS)
    } else {
        0.0
    };
    let turn = normal_turn(table.normals[a as usize], table.normals[b as usize]);
    (k * texels).max(k * turn / TURN_PER_SEGMENT).ceil()
}

/// The most texels a UV-degenerate edge's arc is counted as (`edge_segments_wanted`): 16
/// times the four a strip's narrowest rung spans, so that the rungs of a strip whose turns
/// differ that much are tessellated as finely as before the cap (the rock's reference keeps
/// its size, 30 730 B a triangle, and PDM's errors against it), and one that barely turns
/// cannot ask for millions.
pub const MAX_ARC_TEXELS: f32 = 64.0;

/// At `k = 1`, the most a base edge's normal turns per segment (`k` divides it): the chord
/// of a displaced arc of radius `|D|` turning by `θ` lies `|D| θ²/8` inside it, so a crease
/// strip's rung (a zero-length edge that turns the normal by up to 60°, whose displaced
/// image is a sub-texel arc) is not one chord; at `k = 2`, 5° per segment: `1e-3 |D|`.
pub const TURN_PER_SEGMENT: f32 = 10.0 * std::f32::consts::PI / 180.0;

/// The angle between two unit normals (atan2: accurate near 0 and π).
fn normal_turn(a: Vec3, b: Vec3) -> f32 {
    a.cross(b).length().atan2(a.dot(b))
}

/// Segment count per base edge: the max over the edge's faces (they differ only on the
/// UV-degenerate fallback), clamped to `[1, MAX_SEGMENTS]`. Returns the map and how many
/// edges were clamped from above.
fn edge_segment_counts(
    table: &PrismTable,
    map: &HeightMap,
    rep: &[u32],
    k: f32,
) -> (BTreeMap<(u32, u32), u32>, usize) {
    let mut wanted: BTreeMap<(u32, u32), f32> = BTreeMap::new();
    for p in &table.prisms {
        for e in 0..3 {
            let (a, b) = (p.tri[e], p.tri[(e + 1) % 3]);
            let w = edge_segments_wanted(table, map, p, a, b, k);
            let w = if w.is_nan() { 1.0 } else { w };
            let slot = wanted
                .entry(edge_key(rep[a as usize], rep[b as usize]))
                .or_insert(1.0);
            *slot = slot.max(w);
        }
    }
    let mut capped = 0;
    let counts = wanted
        .into_iter()
        .map(|(key, w)| {
            if w > MAX_SEGMENTS as f32 {
                capped += 1;
            }
            (key, w.clamp(1.0, MAX_SEGMENTS as f32) as u32)
        })
        .collect();
    (counts, capped)
}

/// The raw displacement along the edge `a`–`b` (slots as in `edge_geom`).
fn edge_displacement<'a>(
    surface: &Surface<'a>,
    a: u32,
    b: u32,
) -> crate::seam::PrismDisplacement<'a> {
    let uv = &surface.table.uvs;
    crate::seam::PrismDisplacement {
        map: surface.map,
        params: surface.table.params,
        uv: [uv[a as usize], uv[b as usize], uv[a as usize]],
        stitch: None,
    }
}

/// The raw height `D(uv)` at vertex record `v`.
fn surface_raw_height(surface: &Surface, v: u32) -> f32 {
    edge_displacement(surface, v, v).raw(surface.table.uvs[v as usize])
}

/// A degenerate prism geometry whose every barycentric combination of slots 0 and 1 is the
/// segment between base vertices `a` and `b`: evaluating edge points through it makes them
/// independent of which face asks.
fn edge_geom(table: &PrismTable, a: u32, b: u32) -> PrismGeom {
    let (a, b) = (a as usize, b as usize);
    PrismGeom {
        v: [table.positions[a], table.positions[b], table.positions[a]],
        n: [table.normals[a], table.normals[b], table.normals[a]],
        uv: [table.uvs[a], table.uvs[b], table.uvs[a]],
    }
}

/// How a face is triangulated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FaceLayout {
    /// Every edge has `n` segments: the plain `n × n` barycentric grid.
    Grid,
    /// Mixed edge counts, `n ≥ 3`: the grid's interior points (an inner triangle with `n − 3`
    /// segments a side), each base edge zipped to the inner side parallel to it.
    Zipped,
    /// Mixed edge counts, `n = 2`: no interior grid point, so a fan around the centroid.
    Fan,
}

impl FaceLayout {
    /// The face's `n` (its largest edge count) and layout, from its edges' segment counts.
    fn of(counts: [u32; 3]) -> (u32, FaceLayout) {
        let n = counts.into_iter().max().unwrap_or(1);
        let layout = if counts.iter().all(|&c| c == n) {
            FaceLayout::Grid
        } else if n == 2 {
            FaceLayout::Fan
        } else {
            FaceLayout::Zipped
        };
        (n, layout)
    }

    fn interior_count(self, n: u32) -> usize {
        match self {
            FaceLayout::Fan => 1,
            _ if n < 3 => 0,
            _ => (n as usize - 1) * (n as usize - 2) / 2,
        }
    }

    /// Micro-triangles `tessellate_face` emits for edge counts `counts` (fewer only where the
    /// base face repeats a vertex): the grid's `n²`; the inner grid's `(n − 3)²` and, per
    /// edge, one triangle per outer and per inner segment; a fan's one per boundary segment.
    fn triangle_count(self, n: u32, counts: [u32; 3]) -> u64 {
        let (n, sum) = (n as u64, counts.iter().map(|&c| c as u64).sum::<u64>());
        match self {
            FaceLayout::Grid => n * n,
            FaceLayout::Zipped => (n - 3) * (n - 3) + sum + 3 * (n - 3),
            FaceLayout::Fan => sum,
        }
    }
}

/// Per vertex, the representative of its seam-twin group (the smallest record linked to it
/// by seams, itself if none); the identity on an open surface.
fn seam_representatives(surface: &Surface) -> Vec<u32> {
    let table = surface.table;
    let mut rep: Vec<u32> = (0..table.positions.len() as u32).collect();
    if surface.mode != SeamMode::Stitch {
        return rep;
    }
    fn root(rep: &mut [u32], mut v: u32) -> u32 {
        while rep[v as usize] != v {
            let up = rep[rep[v as usize] as usize];
            rep[v as usize] = up;
            v = up;
        }
        v
    }
    for seam in &table.seams {
        let [i0, j0] = seam.corners(0);
        let [i1, j1] = seam.corners(1);
        let (t0, t1) = (
            table.prisms[seam.faces[0] as usize].tri,
            table.prisms[seam.faces[1] as usize].tri,
        );
        for (a, b) in [(t0[i0], t1[j1]), (t0[j0], t1[i1])] {
            let (ra, rb) = (root(&mut rep, a), root(&mut rep, b));
            if ra != rb {
                rep[ra.max(rb) as usize] = ra.min(rb);
            }
        }
    }
    for v in 0..rep.len() as u32 {
        rep[v as usize] = root(&mut rep, v);
    }
    rep
}

/// One face's segmentation and where its vertices live.
struct FaceGrid<'a> {
    prism: &'a Prism,
    /// The prism's corners as micro-vertex indices (seam representatives).
    corners: [u32; 3],
    n: u32,
    /// Per edge `e` (slot `e` → slot `e + 1`): its split and whether slot `e` is the lower index.
    edges: [(EdgeSplit, bool); 3],
    layout: FaceLayout,
    interior_start: u32,
}

/// A micro-vertex: index into `TessMesh::positions` and barycentrics in the face.
type Corner = (u32, Vec3);

impl FaceGrid<'_> {
    fn new(
        prism: &Prism,
        corners: [u32; 3],
        edges: [(EdgeSplit, bool); 3],
        interior_start: u32,
    ) -> FaceGrid<'_> {
        let (n, layout) = FaceLayout::of(edges.map(|(s, _)| s.n));
        FaceGrid {
            prism,
            corners,
            n,
            edges,
            layout,
            interior_start,
        }
    }

    fn interior_count(&self) -> usize {
        self.layout.interior_count(self.n)
    }

    /// Point `i` of `n_e` along edge `e`, counted from slot `e`; shared with the other face.
    fn edge_point(&self, e: usize, i: u32) -> Corner {
        let (split, from_is_low) = self.edges[e];
        let (from, to) = (e, (e + 1) % 3);
        let (lo, hi, j) = if from_is_low {
            (from, to, i)
        } else {
            (to, from, split.n - i)
        };
        let s = j as f32 / split.n as f32;
        let mut bary = [0.0f32; 3];
        bary[lo] = 1.0 - s;
        bary[hi] = s;
        let index = if j == 0 {
            self.corners[lo]
        } else if j == split.n {
            self.corners[hi]
        } else {
            split.start + j - 1
        };
        (index, Vec3::from(bary))
    }

    /// Interior grid point `(a, b)`: weights `(n − a − b, a, b) / n`, all three ≥ 1.
    fn interior(&self, a: u32, b: u32) -> Corner {
        let n = self.n;
        // Rows 1 .. b hold n − 1 − row interior points each.
        let (nu, bu) = (n as usize, b as usize);
        let local = (bu - 1) * (nu - 1) - (bu - 1) * bu / 2 + (a as usize - 1);
        (
            self.interior_start + local as u32,
            Vec3::new((n - a - b) as f32, a as f32, b as f32) / n as f32,
        )
    }

    /// Any point `(a, b)` of the plain grid (only for `FaceLayout::Grid`, where `n_e = n`).
    fn grid_point(&self, a: u32, b: u32) -> Corner {
        let c = self.n - a - b;
        if b == 0 {
            self.edge_point(0, a)
        } else if c == 0 {
            self.edge_point(1, b)
        } else if a == 0 {
            self.edge_point(2, c)
        } else {
            self.interior(a, b)
        }
    }

    /// The interior point at slot weights `w` (slot order, summing to `n`).
    fn interior_at_slots(&self, w: [u32; 3]) -> Corner {
        self.interior(w[1], w[2])
    }

    /// Zip edge `e` (its `n_e + 1` points) to the inner triangle's side parallel to it (the
    /// `n − 2` interior points one grid row in). Both chains lie on parallel lines, so every
    /// triangle with two corners on one chain and one on the other has the face's winding,
    /// and advancing whichever chain lags keeps them well shaped.
    fn zip_edge(&self, e: usize, emit: &mut impl FnMut([Corner; 3])) {
        let n = self.n;
        let ne = self.edges[e].0.n;
        let inner = |alpha: u32| {
            let mut w = [0u32; 3];
            w[e] = n - 1 - alpha;
            w[(e + 1) % 3] = alpha;
            w[(e + 2) % 3] = 1;
            self.interior_at_slots(w)
        };
        let m = n - 3; // inner segments; inner point j has alpha = j + 1
        let (mut i, mut j) = (0u32, 0u32);
        while i < ne || j < m {
            // Position along the edge: outer point i at i/ne, inner point j at (j + 1.5)/n.
            // Compare the next points in integers: (i+1)/ne <= (j+2.5)/n.
            let outer_next = j == m
                || (i < ne && 2 * (i as u64 + 1) * n as u64 <= (2 * j as u64 + 5) * ne as u64);
            if outer_next {
                emit([
                    self.edge_point(e, i),
                    self.edge_point(e, i + 1),
                    inner(j + 1),
                ]);
                i += 1;
            } else {
                emit([self.edge_point(e, i), inner(j + 2), inner(j + 1)]);
                j += 1;
            }
        }
    }
}

/// Everything one face contributes, in its own order.
struct FaceTess {
    interior: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    bary: Vec<[Vec3; 3]>,
}

fn tessellate_face(surface: &Surface, prism: u32, grid: &FaceGrid) -> FaceTess {
    let n = grid.n;
    let geom = PrismGeom::new(surface.table, grid.prism);
    let disp = surface.prism_displacement(prism);
    let eval = |w: Vec3| surface_point(&geom, &disp, w).position;
    let mut interior = Vec::with_capacity(grid.interior_count());
    if grid.layout == FaceLayout::Fan {
        interior.push(eval(Vec3::splat(1.0 / 3.0)));
    } else {
        for b in 1..n {
            for a in 1..n - b {
                interior.push(eval(grid.interior(a, b).1));
            }
        }
    }
    let mut triangles = Vec::with_capacity((n * n) as usize);
    let mut bary = Vec::with_capacity((n * n) as usize);
    let mut emit = |c: [Corner; 3]| {
        let idx = c.map(|(i, _)| i);
        // A base face with a repeated vertex index gives micro-triangles without area.
        if idx[0] != idx[1] && idx[1] != idx[2] && idx[0] != idx[2] {
            triangles.push(idx);
            bary.push(c.map(|(_, w)| w));
        }
    };
    match grid.layout {
        FaceLayout::Grid => {
            for b in 0..n {
                for a in 0..n - b {
                    let p = |a, b| grid.grid_point(a, b);
                    emit([p(a, b), p(a + 1, b), p(a, b + 1)]);
                    if a + b + 1 < n {
                        emit([p(a + 1, b), p(a + 1, b + 1), p(a, b + 1)]);
                    }
                }
            }
        }
        FaceLayout::Zipped => {
            // The inner grid: micro-triangles of the n-grid with all corners interior.
            for b in 1..n {
                for a in 1..n - b {
                    let p = |a, b| grid.interior(a, b);
                    if a + b + 2 <= n {
                        emit([p(a, b), p(a + 1, b), p(a, b + 1)]);
                    }
                    if a + b + 3 <= n {
                        emit([p(a + 1, b), p(a + 1, b + 1), p(a, b + 1)]);
                    }
                }
            }
            for e in 0..3 {
                grid.zip_edge(e, &mut emit);
            }
        }
        FaceLayout::Fan => {
            let centre = (grid.interior_start, Vec3::splat(1.0 / 3.0));
            let ring: Vec<Corner> = (0..3)
                .flat_map(|e| (0..grid.edges[e].0.n).map(move |i| (e, i)))
                .map(|(e, i)| grid.edge_point(e, i))
                .collect();
            for k in 0..ring.len() {
                emit([ring[k], ring[(k + 1) % ring.len()], centre]);
            }
        }
    }
    FaceTess {
        interior,
        triangles,
        bary,
    }
}

/// How large `tessellate_prisms(surface, k, keep)` comes out, from the segment counts alone
/// (no surface point is evaluated, no mesh allocated): what a caller checks against a memory
/// budget before asking for the mesh.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TessSize {
    /// Micro-triangles: exact, but for base faces with a repeated vertex (then fewer).
    pub triangles: u64,
    /// Micro-vertices (the base vertices, the kept faces' edge and interior points).
    pub vertices: u64,
}

/// Whether prism `i` is tessellated (`keep` as in `tessellate_prisms`).
fn is_kept(keep: Option<&[bool]>, i: usize) -> bool {
    keep.is_none_or(|keep| keep.get(i).copied().unwrap_or(false))
}

/// The size of `tessellate_prisms(surface, k, keep)` (see `TessSize`).
pub fn tessellation_size(surface: &Surface, k: f32, keep: Option<&[bool]>) -> TessSize {
    let table = surface.table;
    let kept = |i: usize| is_kept(keep, i);
    let rep = seam_representatives(surface);
    let (counts, _) = edge_segment_counts(table, surface.map, &rep, k);
    let mut used = std::collections::HashSet::new();
    let mut size = TessSize {
        triangles: 0,
        vertices: table.positions.len() as u64,
    };
    for (_, prism) in table.prisms.iter().enumerate().filter(|(i, _)| kept(*i)) {
        let corners = prism.tri.map(|v| rep[v as usize]);
        let keys: [(u32, u32); 3] =
            std::array::from_fn(|e| edge_key(corners[e], corners[(e + 1) % 3]));
        let ns = keys.map(|key| counts[&key]);
        let (n, layout) = FaceLayout::of(ns);
        size.triangles += layout.triangle_count(n, ns);
        size.vertices += layout.interior_count(n) as u64;
        for (key, n_e) in keys.into_iter().zip(ns) {
            if used.insert(key) {
                size.vertices += n_e as u64 - 1;
            }
        }
    }
    size
}

/// Tessellate every prism of `surface` at `k`× the texel rate (see the module doc). The
/// output does not depend on the thread count. Warns on stderr when an edge needs more than
/// `MAX_SEGMENTS` segments (the count is also in `capped_edges`).
pub fn tessellate(surface: &Surface, k: f32) -> TessMesh {
    tessellate_prisms(surface, k, None)
}

/// `tessellate`, but only the prisms with `keep[prism]` (all with `None`): the same
/// micro-vertices and micro-triangles over them as the whole tessellation has (the segment
/// counts are still every edge's), at a fraction of the cost — a local check at a higher `k`
/// (the bench's leak confirmation). `tri_prism` keeps the table's prism indices.
pub fn tessellate_prisms(surface: &Surface, k: f32, keep: Option<&[bool]>) -> TessMesh {
    let (table, map) = (surface.table, surface.map);
    let kept = |i: usize| is_kept(keep, i);
    let rep = seam_representatives(surface);
    let (counts, capped_edges) = edge_segment_counts(table, map, &rep, k);
    if capped_edges > 0 {
        eprintln!(
            "warning: tessellate: {capped_edges} base edges need more than {MAX_SEGMENTS} \
             segments at k = {k}; clamped (check the mesh units and the map size)"
        );
    }

    // Base vertices keep their indices; a seam-twin group is one vertex at the mean height.
    let mut group_height: HashMap<u32, (f32, u32)> = HashMap::new();
    for v in 0..rep.len() as u32 {
        let r = rep[v as usize];
        if r != v {
            let slot = group_height
                .entry(r)
                .or_insert_with(|| (surface_raw_height(surface, r), 1));
            slot.0 += surface_raw_height(surface, v);
            slot.1 += 1;
        }
    }
    let mut positions: Vec<Vec3> = (0..table.positions.len() as u32)
        .into_par_iter()
        .map(|v| match group_height.get(&v) {
            Some(&(sum, count)) => {
                let (p, n) = (table.positions[v as usize], table.normals[v as usize]);
                p + n.normalize_or_zero() * (sum / count as f32)
            }
            None => {
                let raw = Surface::open(table, map);
                surface_point(
                    &edge_geom(table, v, v),
                    &edge_displacement(&raw, v, v),
                    Vec3::X,
                )
                .position
            }
        })
        .collect();

    // Edge interiors, in key order, evaluated from the lower representative through the
    // first face that has the edge.
    let mut owner: HashMap<(u32, u32), (u32, usize)> = HashMap::with_capacity(counts.len());
    // The edges the kept faces use.
    let mut used: std::collections::HashSet<(u32, u32)> = std::collections::HashSet::new();
    for (i, p) in table.prisms.iter().enumerate() {
        for e in 0..3 {
            if kept(i) {
                used.insert(edge_key(
                    rep[p.tri[e] as usize],
                    rep[p.tri[(e + 1) % 3] as usize],
                ));
            }
            let key = edge_key(rep[p.tri[e] as usize], rep[p.tri[(e + 1) % 3] as usize]);
            owner.entry(key).or_insert((i as u32, e));
        }
    }
    let mut splits: HashMap<(u32, u32), EdgeSplit> = HashMap::with_capacity(counts.len());
    let mut edge_list = Vec::with_capacity(counts.len());
    let mut next = positions.len() as u32;
    for (&key, &n) in counts.iter().filter(|(key, _)| used.contains(key)) {
        splits.insert(key, EdgeSplit { n, start: next });
        edge_list.push((key, n));
        next += n - 1;
    }
    let edge_points: Vec<Vec3> = edge_list
        .par_iter()
        .flat_map_iter(|&(key, n)| {
            let (prism, e) = owner[&key];
            let p = &table.prisms[prism as usize];
            let geom = PrismGeom::new(table, p);
            let disp = surface.prism_displacement(prism);
            let (from, to) = (e, (e + 1) % 3);
            let (lo, hi) = if rep[p.tri[from] as usize] == key.0 {
                (from, to)
            } else {
                (to, from)
            };
            (1..n).map(move |j| {
                let s = j as f32 / n as f32;
                let mut b = [0.0f32; 3];
                b[lo] = 1.0 - s;
                b[hi] = s;
                surface_point(&geom, &disp, Vec3::from(b)).position
            })
        })
        .collect();
    positions.extend(edge_points);

    // Faces: segment counts and interior offsets first (a prefix sum keeps indices stable).
    let mut grids = Vec::with_capacity(table.prisms.len());
    let mut next = positions.len() as u32;
    for (i, prism) in table.prisms.iter().enumerate() {
        if !kept(i) {
            continue;
        }
        let corners = prism.tri.map(|v| rep[v as usize]);
        let edges: [(EdgeSplit, bool); 3] = std::array::from_fn(|e| {
            let (a, b) = (corners[e], corners[(e + 1) % 3]);
            (splits[&edge_key(a, b)], a <= b)
        });
        let grid = FaceGrid::new(prism, corners, edges, next);
        next += grid.interior_count() as u32;
        grids.push((i as u32, grid));
    }
    let faces: Vec<(u32, FaceTess)> = grids
        .par_iter()
        .map(|(i, g)| (*i, tessellate_face(surface, *i, g)))
        .collect();

    let tri_total = faces.iter().map(|(_, f)| f.triangles.len()).sum();
    let mut mesh = TessMesh {
        positions,
        triangles: Vec::with_capacity(tri_total),
        tri_prism: Vec::with_capacity(tri_total),
        tri_bary: Vec::with_capacity(tri_total),
        capped_edges,
    };
    for (p, face) in faces {
        mesh.positions.extend(face.interior);
        mesh.tri_prism
            .extend(std::iter::repeat_n(p, face.triangles.len()));
        mesh.triangles.extend(face.triangles);
        mesh.tri_bary.extend(face.bary);
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_util::test_sphere_table;

    fn identity(table: &PrismTable) -> Vec<u32> {
        (0..table.positions.len() as u32).collect()
    }

    /// Undirected edge → how many micro-triangles use it, plus directed-edge uniqueness.
    fn edge_use(mesh: &TessMesh) -> (HashMap<(u32, u32), u32>, bool) {
        let mut undirected = HashMap::new();
        let mut directed = std::collections::HashSet::new();
        let mut consistent = true;
        for t in &mesh.triangles {
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                *undirected.entry(edge_key(a, b)).or_insert(0) += 1;
                consistent &= directed.insert((a, b));
            }
        }
        (undirected, consistent)
    }

    /// A subset's micro-triangles are the whole tessellation's over those prisms, corner for
    /// corner (the local check in the bench relies on it); the other prisms get none.
    #[test]
    fn a_subset_is_the_whole_tessellation_over_its_prisms() {
        let (table, map) = test_sphere_table(2, 32, 0.15);
        let surface = Surface::open(&table, &map);
        let whole = tessellate(&surface, 2.0);
        let keep: Vec<bool> = (0..table.prisms.len()).map(|i| i % 3 == 1).collect();
        let part = tessellate_prisms(&surface, 2.0, Some(&keep));
        let corners = |m: &TessMesh, p: u32| -> Vec<[Vec3; 3]> {
            m.triangles
                .iter()
                .zip(&m.tri_prism)
                .filter(|(_, &q)| q == p)
                .map(|(t, _)| t.map(|v| m.positions[v as usize]))
                .collect()
        };
        let mut compared = 0;
        for p in 0..table.prisms.len() as u32 {
            let got = corners(&part, p);
            if keep[p as usize] {
                assert_eq!(got, corners(&whole, p), "prism {p}");
                compared += got.len();
            } else {
                assert!(got.is_empty(), "prism {p} was not asked for");
            }
        }
        assert!(compared > whole.triangle_count() / 4, "{compared}");
        assert!(part.positions.len() < whole.positions.len());
    }

    #[test]
    fn tessellated_sphere_is_closed_and_consistently_wound() {
        // Breaks if an edge split leaves a T-junction, a crack or a fold between two faces.
        let (table, map) = test_sphere_table(2, 32, 0.15);
        for k in [0.3, 1.0, 2.0, 3.7] {
            let mesh = tessellate(&Surface::open(&table, &map), k);
            let (undirected, consistent) = edge_use(&mesh);
            let open: Vec<_> = undirected.iter().filter(|(_, &c)| c != 2).take(5).collect();
            assert!(
                open.is_empty(),
                "k = {k}: edges not shared by exactly two faces: {open:?}"
            );
            assert!(
                consistent,
                "k = {k}: some directed edge is used twice (flipped face)"
            );
            // Euler characteristic of a sphere, over the vertices the triangles use.
            let used: std::collections::HashSet<u32> =
                mesh.triangles.iter().flatten().copied().collect();
            let chi = used.len() as i64 - undirected.len() as i64 + mesh.triangles.len() as i64;
            assert_eq!(chi, 2, "k = {k}");
            assert_eq!(used.len(), mesh.positions.len(), "k = {k}: unused vertices");
        }
    }

    #[test]
    fn micro_triangles_tile_each_face_without_folds() {
        // Breaks if a micro-triangle is flipped or two overlap in the base face: in (b1, b2)
        // every micro-triangle must have positive area and together exactly the face's 1/2.
        let (table, map) = test_sphere_table(2, 32, 0.15);
        for k in [0.3, 1.0, 2.5, 3.7] {
            let mesh = tessellate(&Surface::open(&table, &map), k);
            let mut area = vec![0.0f64; table.prisms.len()];
            for (t, b) in mesh.tri_bary.iter().enumerate() {
                let d1 = (b[1] - b[0]).as_dvec3();
                let d2 = (b[2] - b[0]).as_dvec3();
                let a = 0.5 * (d1.y * d2.z - d1.z * d2.y);
                assert!(a > 0.0, "k = {k}: micro-triangle {t} folded: {b:?}");
                area[mesh.tri_prism[t] as usize] += a;
            }
            for (p, a) in area.iter().enumerate() {
                assert!(
                    (a - 0.5).abs() < 1e-5,
                    "k = {k}: prism {p} covered {a} of 0.5"
                );
            }
        }
    }

    #[test]
    fn micro_barycentrics_reproduce_vertex_positions() {
        // Breaks if tri_bary does not describe where each micro-corner sits in its base face.
        let (table, map) = test_sphere_table(1, 16, 0.1);
        let mesh = tessellate(&Surface::open(&table, &map), 2.0);
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let prism = &table.prisms[mesh.tri_prism[t] as usize];
            let geom = PrismGeom::new(&table, prism);
            for (c, (&b, &v)) in mesh.tri_bary[t].iter().zip(tri).enumerate() {
                assert!((b.x + b.y + b.z - 1.0).abs() < 1e-6 && b.min_element() >= 0.0);
                let want = surface_point(
                    &geom,
                    &Surface::open(&table, &map).prism_displacement(mesh.tri_prism[t]),
                    b,
                )
                .position;
                let got = mesh.positions[v as usize];
                assert!(
                    (want - got).length() < 1e-5,
                    "tri {t} corner {c}: {want} vs {got}"
                );
            }
        }
    }

    #[test]
    fn segment_counts_follow_k_and_the_texel_rate() {
        // Breaks if the resolution is not k× the texel rate along every edge.
        let (table, map) = test_sphere_table(1, 16, 0.1);
        for k in [1.0, 2.0, 4.0] {
            let (counts, capped) = edge_segment_counts(&table, &map, &identity(&table), k);
            assert_eq!(capped, 0);
            for (&(a, b), &n) in &counts {
                let texels = ((table.uvs[b as usize] - table.uvs[a as usize]) * 16.0).length();
                let turn = normal_turn(table.normals[a as usize], table.normals[b as usize]);
                let want = (k * texels).max(k * turn / TURN_PER_SEGMENT);
                assert!(n as f32 >= want && (n as f32) < want + 1.0, "{n} {texels}");
            }
        }
        let (_, capped) = edge_segment_counts(&table, &map, &identity(&table), 1e6);
        assert!(capped > 0);
    }

    /// The size a budget is checked against is the mesh's, for every layout (k = 0.3 mixes
    /// fans and zipped faces in), on a subset, and across stitched seams (the examples).
    #[test]
    fn the_predicted_size_is_the_meshes() {
        let size_of = |m: &TessMesh| TessSize {
            triangles: m.triangle_count() as u64,
            vertices: m.positions.len() as u64,
        };
        let (table, map) = test_sphere_table(2, 32, 0.15);
        let surface = Surface::open(&table, &map);
        let keep: Vec<bool> = (0..table.prisms.len()).map(|i| i % 3 == 1).collect();
        for k in [0.3, 1.0, 2.5, 3.7] {
            let whole = tessellate(&surface, k);
            assert_eq!(
                tessellation_size(&surface, k, None),
                size_of(&whole),
                "k = {k}"
            );
            let part = tessellate_prisms(&surface, k, Some(&keep));
            let want = tessellation_size(&surface, k, Some(&keep));
            assert_eq!(
                want.triangles,
                part.triangle_count() as u64,
                "k = {k}, subset"
            );
            // The subset keeps every base vertex and only its own edges' points.
            assert_eq!(
                want.vertices,
                part.positions.len() as u64,
                "k = {k}, subset"
            );
        }
        let (_, reference) = crate::test_util::example_with_reference("rock/rock.glb");
        let surface = reference.surface;
        let rep = seam_representatives(&surface);
        assert!(
            (0..rep.len()).any(|v| rep[v] != v as u32),
            "no seam twins to merge"
        );
        for k in [0.5, 1.0] {
            assert_eq!(
                tessellation_size(&surface, k, None),
                size_of(&tessellate(&surface, k)),
                "rock, k = {k}"
            );
        }
    }

    #[test]
    fn output_is_deterministic() {
        let (table, map) = test_sphere_table(2, 32, 0.15);
        let a = tessellate(&Surface::open(&table, &map), 2.0);
        let b = tessellate(&Surface::open(&table, &map), 2.0);
        assert_eq!(a.triangles, b.triangles);
        assert_eq!(a.positions, b.positions);
    }
}
