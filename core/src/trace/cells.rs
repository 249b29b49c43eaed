//! Sub-prism cells: every marched prism split in barycentric space into `4^k` sub-triangles
//! (midpoint subdivision), each with the λ range of its own footprint and its own box, in
//! one BVH. PDM marches a candidate cell only over the part of the ray inside it.
//!
//! A prism's λ range bounds the surface over the whole triangle, so a ray marches the whole
//! relief amplitude (at half a texel per step) wherever it crosses the prism, even where the
//! relief under it is low. A cell is a prism of the same kind: over the sub-triangle with
//! corners `b_j`, the shared-wall prism points `P(b) + λ m(b)` (with `P` and `m` affine in
//! `b`) form the shared-wall prism of the base corners `P(b_j)` and directions `m(b_j)`, so
//! `prism_hit::ray_prism_interval` finds the ray's part in it unchanged. The march inside
//! still tracks the *parent* prism's exact level cubic and accepts hits anywhere in the
//! parent triangle: cells only decide where to march.
//!
//! Why no crossing is lost: the first crossing `x* = P(b*) + λ* m(b*)` has `b*` in some
//! closed cell and `λ*` in that cell's range (the range bounds the surface over the closed
//! sub-triangle, edges included), so the ray is inside that cell at `t*`; before `t*` it is
//! above the surface, so that cell's march (entry sample at or before `t*`, exit sample at or
//! after) sees the sign change as the whole prism's march would.
//!
//! Ranges: the raw map range over the sub-triangle's UV footprint (`bake::footprint_range`,
//! every texel bilinear sampling can read), widened by the prism's seam band range where a
//! stitched band reaches the cell (`PrismStitch::in_band` at its corners), then `D → λ` with
//! the cell's own `|m|` lower bound, and intersected with the parent's range.
//!
//! Which prisms are split: every marched prism (not flat ones, and not prisms whose normals
//! fall below the floor, where the λ range is clamped), down to `TARGET_TEXELS` along the
//! longest UV edge, at most `MAX_LEVEL`, where the quarters' thinner λ ranges pay for the
//! split (`prism_cells`). A prism left whole is a cell too: it is clipped by its slabs like
//! any other, not by the exact walls (but for a crease strip, `Cell::exact`). That includes
//! the zero-area crease strips (`PRISM_INSERTED`), whose UVs ran from one UV island to the
//! other before they kept each side's UV: their relief was squeezed into the strip, and
//! before they were split they took 89% of the rock's march steps. Their slab directions that vanish with the zero-area base (the face
//! normal, zero-length edges) are replaced by the coordinate axes (the cell's corner box).

use crate::accel::{padded_box, BoxBvh, BvhKind};
use crate::bake::{
    footprint_range, lambda_range, PrismTable, M_LO_FLOOR, PRISM_DEGENERATE_NORMALS, PRISM_FLAT,
    PRISM_INSERTED,
};
use crate::heightmap::HeightMap;
use crate::seam::StitchField;
use glam::{Vec2, Vec3, Vec4};
use obvhs::aabb::Aabb;
use rayon::prelude::*;

/// Cells are split until their longest UV edge spans at most this many texels.
pub const TARGET_TEXELS: f32 = 4.0;
/// Deepest split: `4^MAX_LEVEL` cells per prism.
pub const MAX_LEVEL: u32 = 3;

/// One cell's bounds as built: a sub-triangle of prism `prism` (corners as barycentrics of
/// the prism's base triangle), its λ range and its largest `|D|`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellBounds {
    pub prism: u32,
    pub corners: [Vec3; 3],
    pub lambda_lo: f32,
    pub lambda_hi: f32,
    /// Largest `|D|` over the cell (the surface is within it of the sub-triangle).
    pub reach: f32,
}

/// A slab `lo ≤ x·n ≤ hi` (prism-local frame, origin at the prism's first base corner).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Slab {
    n: Vec3,
    lo: f32,
    hi: f32,
}

/// What the march reads per candidate cell: its prism and seven slabs that hold it.
///
/// The slabs replace the exact ray–prism interval (two caps, three bilinear walls: the
/// costliest part of a candidate) by a superset, which is all a cell needs: the march in it
/// evaluates the parent prism's exact level, so samples outside the cell are only wasted,
/// never wrong. A point of the cell is `P(b) + λ m(b)`, affine in `b` for fixed `λ` and in `λ`
/// for fixed `b`, so its distance to any plane is extreme at one of the six corners: each slab
/// is the corners' range along a direction. The directions: the base normal (also cut to
/// `±reach`, where the surface can be), and per side the plane through the side's base edge
/// and its mean direction (tight where the normals are near the face normal) and the plane
/// through the edge square to the face (the lateral bound where the normals lean far over:
/// the first plane then lies nearly in the face). A slab along the cell's own cap normal was
/// measured too: no faster, 12% more memory.
///
/// The slabs are stored by component (`Slabs`), eight lanes with the eighth repeating the
/// first, so that `clip` tests four at a time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    pub prism: u32,
    /// An unsplit crease strip (`PRISM_INSERTED`): the march takes the exact prism interval
    /// cut to the slabs (`pdm::Part::Exact`), not the strict march on the slabs. Its zero-area
    /// base leaves the slabs mostly the corners' box, and the strict march on that superset
    /// found no crossing on three of the 285 strip rays of
    /// `pdm::tests::rays_at_the_rock_strips_hit_where_the_reference_does`, where the exact
    /// interval finds them. Every other cell, a prism left whole included, is clipped by its
    /// slabs, a fraction of the cost of the exact walls.
    pub exact: bool,
    slabs: Slabs,
}

/// Slabs `lo ≤ x·n ≤ hi` by component: lane `k` is slab `k`. The directions are stored as
/// integer vectors (`i16`, `|n| ≈ QUANT`), and `lo`, `hi` are the corners' range along that
/// very vector, so the quantised slab holds the cell exactly as the unit one would, in 2/3
/// of the bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Slabs {
    nx: [i16; LANES],
    ny: [i16; LANES],
    nz: [i16; LANES],
    lo: [f32; LANES],
    hi: [f32; LANES],
}

/// Seven slabs padded to two groups of four.
const LANES: usize = 8;
/// The length of a quantised slab direction.
const QUANT: f32 = i16::MAX as f32;

impl Slab {
    /// The direction quantised to `i16` components.
    fn quantised(n: Vec3) -> [i16; 3] {
        (n * QUANT).round().to_array().map(|c| c as i16)
    }

    fn direction(q: [i16; 3]) -> Vec3 {
        Vec3::new(q[0] as f32, q[1] as f32, q[2] as f32)
    }
}

impl Slabs {
    /// From slabs whose directions are already quantised (`Slab::quantised`).
    fn new(slabs: [Slab; 7]) -> Self {
        let lane = |k: usize| slabs[k % 7];
        let q = |k: usize, c: usize| lane(k).n[c] as i16;
        Slabs {
            nx: std::array::from_fn(|k| q(k, 0)),
            ny: std::array::from_fn(|k| q(k, 1)),
            nz: std::array::from_fn(|k| q(k, 2)),
            lo: std::array::from_fn(|k| lane(k).lo),
            hi: std::array::from_fn(|k| lane(k).hi),
        }
    }
}

/// Slab padding relative to the prism's longest base edge (as the march's interval pad): a
/// crossing on a cell's boundary is then inside it.
const SLAB_PAD: f32 = 1e-4;

impl Cell {
    /// The part `[t0, t1]` of the ray `ro + t d` (prism-local origin) inside the cell's
    /// slabs, if any. Four slabs at a time: a ray parallel to a slab gets `±∞` for both of
    /// its ends (no cut inside it, an empty interval outside), and a NaN (the ray exactly on
    /// a padded face, parallel to it: outside the unpadded slab) rejects the cell.
    #[inline]
    pub fn clip(&self, ro: Vec3, d: Vec3, t0: f32, t1: f32) -> Option<(f32, f32)> {
        let s = &self.slabs;
        let (mut enter, mut exit) = (Vec4::splat(t0), Vec4::splat(t1));
        for k in (0..LANES).step_by(4) {
            let lane = |x: &[f32; LANES]| Vec4::from_slice(&x[k..k + 4]);
            let int = |x: &[i16; LANES]| {
                Vec4::new(
                    x[k] as f32,
                    x[k + 1] as f32,
                    x[k + 2] as f32,
                    x[k + 3] as f32,
                )
            };
            let (nx, ny, nz) = (int(&s.nx), int(&s.ny), int(&s.nz));
            let s0 = nx * ro.x + ny * ro.y + nz * ro.z;
            let inv = (nx * d.x + ny * d.y + nz * d.z).recip();
            let ta = (lane(&s.lo) - s0) * inv;
            let tb = (lane(&s.hi) - s0) * inv;
            enter = enter.max(ta.min(tb));
            exit = exit.min(ta.max(tb));
            // Most candidates fall outside the first four (the face-normal slab and the
            // walls' mean planes): stop there.
            if k == 0 && enter.max_element() > exit.min_element() {
                return None;
            }
        }
        let (t0, t1) = (enter.max_element(), exit.min_element());
        (t0 <= t1).then_some((t0, t1))
    }
}

/// Every prism's cells and the hierarchy over their boxes.
pub struct Cells {
    pub cells: Vec<Cell>,
    bvh: BoxBvh,
}

/// Midpoint subdivision of the barycentric triangle `t`, `level` times (`4^level` pieces,
/// same orientation as `t`).
fn subdivide(t: [Vec3; 3], level: u32, out: &mut Vec<[Vec3; 3]>) {
    if level == 0 {
        out.push(t);
        return;
    }
    let [a, b, c] = t;
    let (ab, bc, ca) = ((a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5);
    for s in [[a, ab, ca], [ab, b, bc], [ca, bc, c], [bc, ca, ab]] {
        subdivide(s, level - 1, out);
    }
}

/// How many times prism `i` is split (0: one cell, the prism itself).
fn split_level(table: &PrismTable, map: &HeightMap, i: usize) -> u32 {
    let p = &table.prisms[i];
    // Crease strips stay whole: their march needs the exact interval (on slabs a few strip
    // rays were missed), and their step, a fraction of the sliver's width
    // (`bake::inserted_texel_world`), would make every split look like it pays.
    if p.flags & (PRISM_FLAT | PRISM_DEGENERATE_NORMALS | PRISM_INSERTED) != 0 {
        return 0;
    }
    let uv = table.prism_uvs(p);
    let size = Vec2::new(map.width as f32, map.height as f32);
    let longest = (0..3)
        .map(|k| ((uv[(k + 1) % 3] - uv[k]) * size).length())
        .fold(0.0f32, f32::max);
    if !longest.is_finite() {
        return 0;
    }
    let mut level = 0;
    while level < MAX_LEVEL && longest / (1u32 << level) as f32 > TARGET_TEXELS {
        level += 1;
    }
    level
}

/// The box of some points.
fn box_of(points: &[Vec3]) -> (Vec3, Vec3) {
    points
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        })
}

#[inline]
fn combine<T>(b: Vec3, x: &[T; 3]) -> T
where
    T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
{
    x[0] * b.x + x[1] * b.y + x[2] * b.z
}

/// A split's cost per ray through the piece: one more level of the walk and a second cell
/// where the ray crosses from one quarter into another, in march steps of one texel.
/// Measured (instructions of PDM's primary rays at 128², docs/benchmarks.md): 0.25 traces
/// within 2% of splitting everything on the three examples (rock +2%, torus +0.3%, sphere
/// −2.2%) at 0.31 (rock), 0.74 (torus) and 0.96 (sphere) of the cells' memory; 0.5 and 1
/// save more memory but trace the torus 5% and 11% slower.
const SPLIT_COST_STEPS: f32 = 0.25;

/// The cells of prism `i`: the prism's triangle split by midpoint subdivision down to
/// `TARGET_TEXELS` (at most `MAX_LEVEL` times), where splitting pays.
///
/// A piece is split only where its children's λ ranges are enough thinner to pay for the
/// extra cells: a ray through a piece marches its thickness (in steps of one texel), so a
/// piece stays whole when its thickness is at most `SPLIT_COST_STEPS` plus the mean cost of
/// its quarters, each at its own best (decided bottom-up, so a dip that only the
/// grandchildren isolate still counts; a fixed cost per visited cell cancels out, as the
/// quarters of a piece share its rays). Smooth relief, whose range halves with the size, is
/// split to the target; texel noise, where a quarter of a piece spans nearly the whole
/// range, is not, and costs no memory for cells that would not shorten the march.
pub(crate) fn prism_cells(
    table: &PrismTable,
    map: &HeightMap,
    stitch: &StitchField,
    i: usize,
) -> Vec<CellBounds> {
    let p = &table.prisms[i];
    let whole = CellBounds {
        prism: i as u32,
        corners: [Vec3::X, Vec3::Y, Vec3::Z],
        lambda_lo: p.lambda_lo,
        lambda_hi: p.lambda_hi,
        reach: p.d_min.abs().max(p.d_max.abs()),
    };
    let level = split_level(table, map, i);
    if level == 0 {
        return vec![whole];
    }
    let (_, n) = table.prism_corners(p);
    let uv = table.prism_uvs(p);
    let band = stitch.get(i as u32);
    let bounds_of = |corners: [Vec3; 3]| {
        let (mut hmin, mut hmax) = footprint_range(map, &corners.map(|b| combine(b, &uv)));
        if let Some(s) = band {
            if corners.iter().any(|&b| s.in_band(b)) {
                hmin = hmin.min(s.band_h.0);
                hmax = hmax.max(s.band_h.1);
            }
        }
        let (d_min, d_max) = table.params.displacement_range(hmin, hmax);
        let m = corners.map(|b| combine(b, &n));
        let c = (m[0] + m[1] + m[2]).normalize_or_zero();
        let m_lo = m
            .iter()
            .map(|mj| mj.dot(c))
            .fold(f32::INFINITY, f32::min)
            .max(M_LO_FLOOR);
        let (lo, hi) = lambda_range(d_min, d_max, m_lo);
        CellBounds {
            prism: i as u32,
            corners,
            lambda_lo: lo.max(p.lambda_lo),
            lambda_hi: hi.min(p.lambda_hi),
            reach: d_min.abs().max(d_max.abs()),
        }
    };
    let step = p.texel_world.max(f32::MIN_POSITIVE);
    let cost = |c: &CellBounds| (c.lambda_hi - c.lambda_lo).max(0.0) / step;
    let (cells, _) = best_split(whole, level, &bounds_of, &cost);
    cells
}

/// The cheapest tiling of `cell` by at most `levels` midpoint splits, and its cost per ray
/// through the cell (`prism_cells`).
fn best_split(
    cell: CellBounds,
    levels: u32,
    bounds_of: &dyn Fn([Vec3; 3]) -> CellBounds,
    cost: &dyn Fn(&CellBounds) -> f32,
) -> (Vec<CellBounds>, f32) {
    let whole = cost(&cell);
    if levels == 0 {
        return (vec![cell], whole);
    }
    let mut quarters = Vec::with_capacity(4);
    subdivide(cell.corners, 1, &mut quarters);
    let mut cells = Vec::new();
    let mut split = SPLIT_COST_STEPS;
    for q in quarters {
        let (c, k) = best_split(bounds_of(q), levels - 1, bounds_of, cost);
        cells.extend(c);
        split += 0.25 * k;
    }
    if split < whole {
        (cells, split)
    } else {
        (vec![cell], whole)
    }
}

impl CellBounds {
    /// The cell's base corners `P(b_j)` and directions `m(b_j)` from the prism's corners.
    #[inline]
    pub fn base(&self, v: &[Vec3; 3], n: &[Vec3; 3]) -> ([Vec3; 3], [Vec3; 3]) {
        (
            self.corners.map(|b| combine(b, v)),
            self.corners.map(|b| combine(b, n)),
        )
    }

    /// The six corners `P(b_j) + λ m(b_j)`, bottom then top, from the cell's base corners
    /// `pv` and directions `pn` (`base`).
    fn solid_corners(&self, pv: &[Vec3; 3], pn: &[Vec3; 3]) -> [Vec3; 6] {
        std::array::from_fn(|k| {
            let l = if k < 3 {
                self.lambda_lo
            } else {
                self.lambda_hi
            };
            pv[k % 3] + pn[k % 3] * l
        })
    }

    /// The cell's box in the table's frame: its six corners, cut to the sub-triangle's box
    /// grown by `reach` (as `PrismTable::prism_aabb`).
    fn aabb(&self, table: &PrismTable) -> Aabb {
        let (v, n) = table.prism_corners(&table.prisms[self.prism as usize]);
        let (pv, pn) = self.base(&v, &n);
        let (lo, hi) = box_of(&self.solid_corners(&pv, &pn));
        let (blo, bhi) = box_of(&pv);
        let reach = Vec3::splat(self.reach);
        padded_box(lo.max(blo - reach), hi.min(bhi + reach))
    }

    /// The march's record: the seven slabs in the prism's local frame.
    fn cell(&self, table: &PrismTable) -> Cell {
        let p = &table.prisms[self.prism as usize];
        let (v, n) = table.prism_corners(p);
        let origin = v[0];
        let local: [Vec3; 3] = v.map(|x| x - origin);
        let (pv, pn) = self.base(&local, &n);
        let c = self.solid_corners(&pv, &pn);
        // Relative to the longest base edge, or to the cell's extent where the base is a
        // point (a crease fan).
        let scale = (0..3)
            .map(|k| (local[(k + 1) % 3] - local[k]).length())
            .fold(f32::MIN_POSITIVE, f32::max);
        let (clo, chi) = box_of(&c);
        let pad = SLAB_PAD * scale.max((chi - clo).length());
        let ng = (local[1] - local[0])
            .cross(local[2] - local[0])
            .normalize_or_zero();
        let side = |i: usize| {
            let j = (i + 1) % 3;
            (pv[j] - pv[i]).cross(pn[i] + pn[j]).normalize_or_zero()
        };
        let across = |i: usize| (pv[(i + 1) % 3] - pv[i]).cross(ng).normalize_or_zero();
        let slab = |dir: Vec3| {
            // The range along the quantised direction the clip tests (`Slabs`), the pad
            // scaled with it.
            let dir = Slab::direction(Slab::quantised(dir));
            let pad = pad * dir.length();
            let (lo, hi) = c
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), x| {
                    let s = x.dot(dir);
                    (a.min(s), b.max(s))
                });
            Slab {
                n: dir,
                lo: lo - pad,
                hi: hi + pad,
            }
        };
        // A direction that vanishes with a zero-area base takes the next coordinate axis.
        let mut axis = 0;
        let mut slab = |dir: Vec3| {
            if dir == Vec3::ZERO {
                axis += 1;
                slab([Vec3::X, Vec3::Y, Vec3::Z][(axis - 1) % 3])
            } else {
                slab(dir)
            }
        };
        let mut base = slab(ng);
        // The surface is within `reach` of the base plane (through the local origin); along
        // the quantised normal, `reach |n|` (its tilt from the face normal, ≤ 3e-5, moves
        // points within the prism by less than the pad).
        if ng != Vec3::ZERO {
            let reach = (self.reach + pad) * base.n.length();
            base.lo = base.lo.max(-reach);
            base.hi = base.hi.min(reach);
        }
        Cell {
            prism: self.prism,
            exact: self.corners == [Vec3::X, Vec3::Y, Vec3::Z] && p.flags & PRISM_INSERTED != 0,
            slabs: Slabs::new([
                base,
                slab(side(0)),
                slab(side(1)),
                slab(side(2)),
                slab(across(0)),
                slab(across(1)),
                slab(across(2)),
            ]),
        }
    }
}

impl Cells {
    pub fn build(table: &PrismTable, map: &HeightMap, stitch: &StitchField) -> Cells {
        let bounds: Vec<CellBounds> = (0..table.prisms.len())
            .into_par_iter()
            .flat_map_iter(|i| prism_cells(table, map, stitch, i))
            .collect();
        let aabbs: Vec<Aabb> = bounds.par_iter().map(|c| c.aabb(table)).collect();
        let mut bvh = BoxBvh::build(&aabbs, BvhKind::default());
        // Records in leaf order: the cells a ray tests one after another sit together.
        let order = bvh.into_leaf_order();
        Cells {
            bvh,
            cells: order
                .par_iter()
                .map(|&i| bounds[i as usize].cell(table))
                .collect(),
        }
    }

    pub fn bvh(&self) -> &BoxBvh {
        &self.bvh
    }

    /// Cell records plus the hierarchy.
    pub fn bytes(&self) -> usize {
        self.cells.len() * std::mem::size_of::<Cell>() + self.bvh.bytes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canonical::PrismGeom;
    use crate::test_util::Rng;

    /// Every cell holds its part of the canonical surface (the stitched one next to seams):
    /// at random points of each sub-triangle, `λ = D*/|m|` is in the cell's range and the
    /// surface point is inside its slabs and its box. The examples cover seam bands (sphere),
    /// crease strips and normals leaning far off their faces (rock), and a smooth map (torus).
    #[test]
    fn cells_bound_the_canonical_surface() {
        let mut rng = Rng(0xce11);
        for name in ["sphere/sphere.glb", "rock/rock.glb", "torus/torus.obj"] {
            let (scene, _) = crate::test_util::example_with_reference(name);
            let table = &scene.table;
            let mut split = 0;
            for i in 0..table.prisms.len() {
                let p = &table.prisms[i];
                if p.flags & PRISM_DEGENERATE_NORMALS != 0 {
                    continue; // the λ range is clamped there by design (and flagged)
                }
                let g = PrismGeom::new(table, p);
                let disp = scene.prism_displacement(i as u32);
                let origin = g.v[0];
                for cb in prism_cells(table, &scene.map, scene.stitch(), i) {
                    split += (cb.corners != [Vec3::X, Vec3::Y, Vec3::Z]) as usize;
                    let cell = cb.cell(table);
                    let aabb = cb.aabb(table);
                    for _ in 0..16 {
                        let w = rng.barycentric();
                        let b = combine(w, &cb.corners);
                        let m = g.normal_dir(b);
                        let d = disp.at(b);
                        let lambda = d / m.length();
                        let tol = 1e-4 * lambda.abs().max(1e-3);
                        assert!(
                            lambda >= cb.lambda_lo - tol && lambda <= cb.lambda_hi + tol,
                            "{name} prism {i}: λ = {lambda} outside {cb:?}"
                        );
                        let x = g.position(b) + m * lambda;
                        let local = x - origin;
                        assert!(
                            cell.clip(local, Vec3::X, 0.0, 0.0).is_some(),
                            "{name} prism {i}: surface point outside the slabs of {cb:?}"
                        );
                        let xa = glam::Vec3A::from(x);
                        assert!(
                            xa.cmpge(aabb.min).all() && xa.cmple(aabb.max).all(),
                            "{name} prism {i}: surface point outside the box of {cb:?}"
                        );
                    }
                }
            }
            // Split cells are covered on every example: the sphere and torus split nearly
            // everywhere, the rock where its scales pay for it (662 split cells of 936 prisms).
            assert!(
                split > table.prisms.len() / 2,
                "{name}: {split} split cells"
            );
        }
    }

    /// Cells split where the quarters' ranges shrink and stay whole where they do not: a
    /// smooth relief (range proportional to the size) is split to the target, texel noise (every
    /// quarter spans nearly the whole range) leaves prisms whole. Either way a prism's cells
    /// tile its triangle. Breaks if the cost comparison is turned around or the bottom-up
    /// choice drops or repeats a piece.
    #[test]
    fn cells_split_only_where_their_ranges_shrink() {
        use crate::accel::fixtures::{relief_map, sphere_mesh, table};
        use crate::rng::{pcg_hash, to_unit_float};
        let noise = HeightMap::new(
            64,
            64,
            (0..64 * 64u32)
                .map(|i| to_unit_float(pcg_hash(i)))
                .collect(),
            crate::heightmap::Wrap::Repeat,
        );
        let mesh = sphere_mesh(1, 0.3);
        let area = |t: &[Vec3; 3]| (t[1] - t[0]).cross(t[2] - t[0]).length() / 2.0;
        let whole = area(&[Vec3::X, Vec3::Y, Vec3::Z]);
        let mut counts = vec![];
        for map in [relief_map(64), noise] {
            let table = table(&mesh, &map, 0.1);
            let stitch = StitchField::empty();
            let mut cells = 0;
            for i in 0..table.prisms.len() {
                // Room to split: at least 16 cells per prism.
                assert!(split_level(&table, &map, i) >= 2, "prism {i}: footprint");
                let c = prism_cells(&table, &map, &stitch, i);
                let covered: f32 = c.iter().map(|c| area(&c.corners)).sum();
                assert!(
                    (covered - whole).abs() < 1e-5 * whole,
                    "prism {i}: {covered}"
                );
                cells += c.len();
            }
            counts.push((table.prisms.len(), cells));
        }
        let [(prisms, smooth), (_, noisy)] = counts[..] else {
            unreachable!()
        };
        assert!(
            smooth > 8 * prisms,
            "smooth relief: {smooth} cells for {prisms} prisms"
        );
        eprintln!("{prisms} prisms: {smooth} cells on smooth relief, {noisy} on noise");
        assert!(
            noisy < prisms + prisms / 4,
            "noise: {noisy} cells for {prisms} prisms"
        );
    }

    /// Midpoint subdivision tiles the triangle: `4^k` pieces of equal area, same orientation.
    #[test]
    fn subdivision_tiles_the_triangle() {
        for level in 0..=MAX_LEVEL {
            let mut out = Vec::new();
            subdivide([Vec3::X, Vec3::Y, Vec3::Z], level, &mut out);
            assert_eq!(out.len(), 1 << (2 * level));
            let area = |t: &[Vec3; 3]| {
                let (a, b) = (t[1] - t[0], t[2] - t[0]);
                a.y * b.z - a.z * b.y
            };
            let whole = area(&[Vec3::X, Vec3::Y, Vec3::Z]);
            let total: f32 = out.iter().map(area).sum();
            assert!(
                (total - whole).abs() < 1e-5,
                "level {level}: {total} vs {whole}"
            );
            for t in &out {
                assert!((area(t) * out.len() as f32 - whole).abs() < 1e-4, "{t:?}");
            }
        }
    }
}
