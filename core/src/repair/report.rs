//! `RepairReport`: every change repair made and every finding, by index, for people (`to_text`)
//! and machines (serde JSON). Face and vertex indices are those of the INPUT mesh unless a field
//! says "output" (inserted faces and split copies exist only in the output).

use serde::Serialize;
use std::fmt::Write;

/// One triangle corner: input face, corner slot 0..3, input vertex, and `n_i·N̂_g` there.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CornerFinding {
    pub face: u32,
    pub corner: u8,
    pub vertex: u32,
    /// `n_i·N̂_g` (NaN shows as `null` in JSON when the normal was not finite).
    pub dot: f32,
}

/// A vertex record changed by crease repair: one copy per sector (of the fan at its position)
/// that its corners lie in. A record in one sector only (e.g. one side of a crease that is
/// also a UV seam) keeps its slot and takes the sector's normal: one copy, itself.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VertexSplit {
    /// Input vertex index.
    pub vertex: u32,
    /// Output vertex indices of the copies (the first keeps the vertex's own slot).
    pub copies: Vec<u32>,
}

/// A hard edge closed by inserted triangles.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StitchedEdge {
    /// Input faces on the two sides (F1 has the edge a→b, F2 has b'→a').
    pub faces: [u32; 2],
    /// Output vertices `[a, b, a', b']`.
    pub vertices: [u32; 4],
    /// Steps of the normal's turn from one side to the other at `a` and at `b` (inserted
    /// vertices + 1; 1 for a narrow edge, one quad; 0 where the normals agree, a crease end).
    pub segments: [u32; 2],
    /// Output indices of the inserted triangles (`segments[0] + segments[1]`, less any
    /// with a repeated vertex).
    pub inserted: Vec<u32>,
}

/// A UV seam edge (same positions and normals on both sides, different UVs).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SeamFinding {
    /// Input faces on the two sides (`u32::MAX` for a triangle inserted by repair).
    pub faces: [u32; 2],
    /// Input vertices at the two ends, as the first face has them.
    pub vertices: [u32; 2],
}

/// A k-gon hole (k ≥ 3 copies of one position, e.g. a cube corner) closed by a fan.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CornerFan {
    /// Output vertices around the hole, in the fan's order.
    pub vertices: Vec<u32>,
    /// Output index of the inserted centre vertex, if the fan has one (then k triangles).
    pub centre: Option<u32>,
    /// Output indices of the inserted triangles (k − 2 from the first vertex, or k around
    /// the centre).
    pub inserted: Vec<u32>,
    /// The fan's orientation (fixed by its neighbours, so that the mesh stays consistently
    /// oriented) disagrees with the copies' mean normal, measured on the displaced positions
    /// `V + n`. Expected false on well-formed meshes; true points at inconsistent input winding.
    pub against_normals: bool,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RepairReport {
    pub input_vertices: usize,
    pub input_triangles: usize,
    pub output_vertices: usize,
    pub output_triangles: usize,
    /// Input vertices merged into an earlier equal one (position, normal and UV).
    pub welded_vertices: usize,
    /// Input vertices whose normal was made the mean of the normals within `NORMAL_SNAP` of
    /// it at the same position (an exporter's per-corner noise, not a hard edge).
    pub unified_normals: usize,
    /// Vertices no face referenced (after dropping faces), removed to keep arrays compact.
    pub unreferenced_vertices: usize,
    /// Input faces dropped because an index was out of range or a position not finite.
    pub invalid_faces: Vec<u32>,
    /// Input faces dropped: zero area or a repeated vertex index (after welding).
    pub zero_area_faces: Vec<u32>,
    /// Input faces flagged `FACE_UV_DEGENERATE` (UV area ≈ 0) and kept.
    pub uv_degenerate_faces: Vec<u32>,
    /// Corners with `n_i·N̂_g ≤ 0`: the normal faces away from its face.
    pub inverted_corners: Vec<CornerFinding>,
    /// Corners with `n_i·N̂_g` below the crease threshold (includes the inverted ones).
    pub sharp_corners: Vec<CornerFinding>,
    /// Crease edges (by position: a crease may be a UV seam), as input vertex index pairs (the
    /// records of the edge's first face).
    pub crease_edges: Vec<[u32; 2]>,
    /// Vertex records that were copied or whose normal changed at a crease.
    pub split_vertices: Vec<VertexSplit>,
    /// Corners still below the threshold after splitting (a crease ends at the vertex, or its
    /// normal is wrong on a smooth region): the bake clamps these prisms.
    pub unresolved_crease_corners: Vec<CornerFinding>,
    pub stitched_edges: Vec<StitchedEdge>,
    pub corner_fans: Vec<CornerFan>,
    /// Total triangles inserted (edge strips + corner fans), all flagged `FACE_INSERTED`.
    pub inserted_triangles: usize,
    /// Vertices inserted by stitching (output indices from `output_vertices −
    /// inserted_vertices` on): the intermediate normals of wide hard edges' strips and the
    /// centres of corner fans, each at the position of the vertex it was made for.
    pub inserted_vertices: usize,
    /// Hard edges found but left open because `stitch_hard_edges` was off.
    pub unstitched_hard_edges: usize,
    /// Edges whose positions and normals match another face's edge but whose UVs differ:
    /// the displaced surface can tear there by the height jump (`seams` lists them; the
    /// trace stage stitches them, `crate::seam`).
    pub uv_seam_edges: usize,
    pub seams: Vec<SeamFinding>,
    /// Edges of the output that still have one face: the mesh's own border, UV seams, and
    /// hard edges left unstitched.
    pub open_boundary_edges: usize,
    /// Positions where zero-length boundary edges between copies do not form a closed loop
    /// (e.g. a hard edge running into a UV seam or the mesh border): no fan inserted.
    pub unclosed_corners: usize,
}

impl RepairReport {
    /// Nothing needed fixing: welding and informational counts (UV seams, open borders) aside,
    /// no face was dropped, flagged or inserted and no corner or vertex needed attention.
    pub fn is_clean(&self) -> bool {
        self.invalid_faces.is_empty()
            && self.zero_area_faces.is_empty()
            && self.uv_degenerate_faces.is_empty()
            && self.inverted_corners.is_empty()
            && self.sharp_corners.is_empty()
            && self.crease_edges.is_empty()
            && self.split_vertices.is_empty()
            && self.unresolved_crease_corners.is_empty()
            && self.stitched_edges.is_empty()
            && self.corner_fans.is_empty()
            && self.unstitched_hard_edges == 0
    }

    /// Human-readable report: a summary line per finding, then the indices.
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "repair: {} vertices, {} triangles in -> {} vertices, {} triangles out{}",
            self.input_vertices,
            self.input_triangles,
            self.output_vertices,
            self.output_triangles,
            if self.is_clean() { " (clean)" } else { "" }
        );
        let _ = writeln!(s, "  welded vertices: {}", self.welded_vertices);
        if self.unified_normals > 0 {
            let _ = writeln!(
                s,
                "  normals unified (equal to {} at one position): {}",
                super::weld::NORMAL_SNAP,
                self.unified_normals
            );
        }
        if self.unreferenced_vertices > 0 {
            let _ = writeln!(
                s,
                "  unreferenced vertices removed: {}",
                self.unreferenced_vertices
            );
        }
        list(&mut s, "invalid faces dropped", &self.invalid_faces);
        list(&mut s, "zero-area faces dropped", &self.zero_area_faces);
        list(
            &mut s,
            "UV-degenerate faces flagged",
            &self.uv_degenerate_faces,
        );
        corners(
            &mut s,
            "inverted corners (n.Ng <= 0)",
            &self.inverted_corners,
        );
        corners(&mut s, "sharp-crease corners", &self.sharp_corners);
        if !self.crease_edges.is_empty() {
            let items: Vec<String> = self
                .crease_edges
                .iter()
                .map(|[a, b]| format!("{a}-{b}"))
                .collect();
            let _ = writeln!(
                s,
                "  crease edges: {} (vertices {})",
                items.len(),
                items.join(", ")
            );
        }
        if !self.split_vertices.is_empty() {
            let _ = writeln!(s, "  vertices split: {}", self.split_vertices.len());
            for v in &self.split_vertices {
                let _ = writeln!(s, "    vertex {} -> output {:?}", v.vertex, v.copies);
            }
        }
        corners(
            &mut s,
            "unresolved crease corners",
            &self.unresolved_crease_corners,
        );
        if !self.stitched_edges.is_empty() {
            let _ = writeln!(s, "  hard edges stitched: {}", self.stitched_edges.len());
            for e in &self.stitched_edges {
                let _ = writeln!(
                    s,
                    "    faces {} | {}: output vertices {:?}, steps {:?}, inserted triangles {:?}",
                    e.faces[0], e.faces[1], e.vertices, e.segments, e.inserted
                );
            }
        }
        if !self.corner_fans.is_empty() {
            let _ = writeln!(s, "  corner holes closed: {}", self.corner_fans.len());
            for f in &self.corner_fans {
                let _ = writeln!(
                    s,
                    "    output vertices {:?}{}: inserted triangles {:?}{}",
                    f.vertices,
                    f.centre
                        .map_or(String::new(), |c| format!(" around centre {c}")),
                    f.inserted,
                    if f.against_normals {
                        " (AGAINST the normals: check the input winding)"
                    } else {
                        ""
                    }
                );
            }
        }
        if self.inserted_triangles > 0 {
            let _ = writeln!(s, "  triangles inserted: {}", self.inserted_triangles);
        }
        if self.inserted_vertices > 0 {
            let _ = writeln!(
                s,
                "  vertices inserted (strip normals, fan centres): {}",
                self.inserted_vertices
            );
        }
        if self.unstitched_hard_edges > 0 {
            let _ = writeln!(
                s,
                "  hard edges left open (stitching off): {}",
                self.unstitched_hard_edges
            );
        }
        if self.uv_seam_edges > 0 {
            let _ = writeln!(s, "  UV seam edges: {}", self.uv_seam_edges);
        }
        if self.open_boundary_edges > 0 {
            let _ = writeln!(s, "  open boundary edges: {}", self.open_boundary_edges);
        }
        if self.unclosed_corners > 0 {
            let _ = writeln!(s, "  corners left open: {}", self.unclosed_corners);
        }
        s
    }
}

fn list(s: &mut String, what: &str, faces: &[u32]) {
    if !faces.is_empty() {
        let _ = writeln!(s, "  {what}: {} (faces {:?})", faces.len(), faces);
    }
}

fn corners(s: &mut String, what: &str, items: &[CornerFinding]) {
    if items.is_empty() {
        return;
    }
    let _ = writeln!(s, "  {what}: {}", items.len());
    for c in items {
        let _ = writeln!(
            s,
            "    face {} corner {} (vertex {}): n.Ng = {:.4}",
            c.face, c.corner, c.vertex, c.dot
        );
    }
}
