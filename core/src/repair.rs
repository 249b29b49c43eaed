//! Stage 2: repair — make a loaded `BaseMesh` safe to extrude into prisms, and say what changed.
//!
//! In: a `BaseMesh` straight from a loader. Out: the repaired `BaseMesh` (compact vertex arrays,
//! `face_group` and `face_flags` sized to the triangles) and a `RepairReport` naming every change
//! and finding by input face/vertex index (output indices for what repair inserted).
//!
//! Steps, in order (each one a submodule):
//! 1. `weld` — merge vertices equal in position, normal and UV (quantised keys), drop vertices no
//!    face uses.
//! 2. `weld` — drop zero-area faces (and faces with repeated or out-of-range indices); flag
//!    UV-degenerate faces `FACE_UV_DEGENERATE` and keep them.
//! 3. `crease` — report corners whose normal faces away from the face (`n_i·N_g ≤ 0`).
//! 4. `crease` — sharp creases (PDM paper §5.4: the extrusion `1/(n_i·N_g)` blows up where
//!    `n_i·N_g` is small): mark crease edges, split vertices into one copy per sector of their fan.
//!    Both work on the topology BY POSITION (weld's quantised keys), so a crease that is also a
//!    UV seam (different vertex records on its two sides) is found and split like any other.
//! 5. `stitch` — close hard edges (same positions, different normals) with zero-area triangles
//!    (`FACE_INSERTED`), and the k-gon holes where k ≥ 3 copies meet (cube corners). The result
//!    is closed up to UV seams: every edge is shared by two triangles or has a seam twin.
//!    Where the two sides' normals are more than 90° apart (a knife edge: nearly opposite) the
//!    edge gets a strip of quads whose inserted vertices turn the normal from one side to the
//!    other through the outside in steps of at most 60° (`strip`), so that no inserted prism
//!    has normals that cancel.
//! 6. `seams` — find the UV seams (same positions and normals, other UVs), record them in the
//!    mesh for the bake (and the stitched surface, `crate::seam`), and snap each group of seam
//!    twins to one position and normal bit for bit.
//!
//! Why stitch and not only split (the paper inserts triangles; a plain normal split is the
//! other option DESIGN.md names): the canonical displaced surface
//! `S(b) = P(b) + D(uv(b)) normalize(Σ b_i n_i)` restricted to an edge (one `b_i` zero) depends
//! only on that edge's two vertex records (position, normal, UV). So if every edge, by vertex
//! index, is shared by exactly two triangles, both triangles trace the *same* curve along it and
//! the displaced surface is closed, whatever `D` is. Splitting a vertex gives the two sides of a
//! crease different normals, so with `D ≠ 0` their displaced edges separate (by
//! `D |n_1 − n_2|`) and the surface tears; the inserted zero-area triangles span exactly that
//! gap — their displaced image is the wall between the two offsets — and restore the
//! "every edge shared twice" property. The tests check both: split-only leaves boundary edges,
//! split + stitch leaves none.

mod crease;
mod report;
mod seams;
mod stitch;
mod strip;
mod weld;

#[cfg(test)]
mod tests;

pub use report::{CornerFan, CornerFinding, RepairReport, SeamFinding, StitchedEdge, VertexSplit};

use crate::mesh::BaseMesh;
use glam::{Vec2, Vec3};

/// Knobs of `repair`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RepairOptions {
    /// Smallest allowed `n_i·N̂_g` of a triangle corner. The default `sin(2.5°)` is the paper's
    /// 5° interior angle (§5.4): at a symmetric knife edge of interior angle θ the smooth normal
    /// makes `n·N_g = sin(θ/2)` with each face.
    pub crease_threshold: f32,
    /// Merge vertices equal in position, normal and UV.
    pub weld: bool,
    /// Insert zero-area triangles along hard edges (and at corners where ≥ 3 copies meet).
    pub stitch_hard_edges: bool,
    /// Largest turn of the normal (radians) between neighbouring copies in the strip that
    /// stitches a hard edge whose sides are more than 90° apart (default 60°). `π` or more
    /// inserts one quad per hard edge whatever its angle (the construction before strips,
    /// whose prisms fold across a knife edge: kept to measure what strips fix).
    pub strip_step_angle: f32,
}

impl Default for RepairOptions {
    fn default() -> Self {
        RepairOptions {
            crease_threshold: 2.5f32.to_radians().sin(),
            weld: true,
            stitch_hard_edges: true,
            strip_step_angle: std::f32::consts::FRAC_PI_3,
        }
    }
}

/// Marks a face that repair inserted (no input face): `Work::face_origin` sentinel.
const INSERTED_ORIGIN: u32 = u32::MAX;

/// The mesh while it is being repaired, with the input index of every vertex and face so that
/// the report can speak in the user's indices.
#[derive(Clone, Debug)]
struct Work {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    /// Input index of each vertex (for welded vertices, the first of the merged ones; for split
    /// copies, the vertex they were split from).
    vertex_origin: Vec<u32>,
    triangles: Vec<[u32; 3]>,
    /// Input index of each face, `INSERTED_ORIGIN` for faces repair inserted.
    face_origin: Vec<u32>,
    face_group: Vec<u32>,
    face_flags: Vec<u8>,
}

impl Work {
    fn face_normal(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.triangles[t].map(|i| self.positions[i as usize]);
        (b - a).cross(c - a).normalize_or_zero()
    }
    fn is_inserted(&self, t: usize) -> bool {
        self.face_flags[t] & crate::mesh::FACE_INSERTED != 0
    }
}

/// Repair `mesh` (see the module docs for the steps) and report every change and finding.
pub fn repair(mesh: BaseMesh, opts: &RepairOptions) -> (BaseMesh, RepairReport) {
    let mut report = RepairReport {
        input_vertices: mesh.positions.len(),
        input_triangles: mesh.triangles.len(),
        ..Default::default()
    };
    let quant = weld::Quantizer::for_positions(&mesh.positions);
    let mut work = weld::weld(&mesh, &quant, opts.weld, &mut report);
    weld::drop_degenerate_faces(&mut work, &quant, &mut report);
    weld::compact_vertices(&mut work, &mut report);
    crease::report_inverted_corners(&work, &mut report);
    crease::split_creases(&mut work, &quant, opts.crease_threshold, &mut report);
    stitch::stitch(&mut work, &quant, opts, &mut report);
    let seams = seams::find_seams(&mut work, &quant, &mut report);
    report.output_vertices = work.positions.len();
    report.output_triangles = work.triangles.len();
    let out = BaseMesh {
        positions: work.positions,
        normals: work.normals,
        uvs: work.uvs,
        triangles: work.triangles,
        face_group: work.face_group,
        face_flags: work.face_flags,
        seams,
        ..mesh
    };
    (out, report)
}
