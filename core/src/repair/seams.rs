//! Step 6: find UV seams — edges where two faces meet on the same positions with the same
//! normals but different UVs — and make the twins bit-identical in position and normal.
//!
//! glTF and OBJ split vertices wherever the UV layout has a seam (USD's faceVarying `st`
//! becomes the same split on load), so a seam edge is two boundary edges by vertex index whose
//! positions match in reverse. Only the UVs differ, so the two faces sample the map at
//! different places along the same curve and the displaced surface tears by the height jump.
//! Positions are matched by the weld grid (1e-6 of the bounds' diagonal), normals by the
//! stitch step's test. Zero-length edges (between copies of one position with different
//! normals, which crease repair's inserted triangles have) are seams too when a reversed twin
//! with the same normals exists: their displaced image is the wall between two offsets.
//!
//! After matching, every group of seam-linked records (union-find over the matched corners)
//! takes its first record's position and normal bit for bit, so that the two sides of a seam
//! evaluate exactly the same base point and direction: stitching (`crate::seam`) then only has
//! to agree on the height.

use super::weld::Quantizer;
use super::{RepairReport, SeamFinding, Work};
use crate::mesh::SeamEdge;
use glam::Vec3;
use std::collections::HashMap;

/// Normals equal up to the weld grid (the same test as `stitch`'s).
fn same_normal(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() <= 1e-6
}

fn find(parent: &mut [u32], mut v: u32) -> u32 {
    while parent[v as usize] != v {
        let up = parent[parent[v as usize] as usize];
        parent[v as usize] = up;
        v = up;
    }
    v
}

/// Find the seams of `w` (see the module doc), snap the twins, and report them.
pub(super) fn find_seams(
    w: &mut Work,
    quant: &Quantizer,
    report: &mut RepairReport,
) -> Vec<SeamEdge> {
    let key = |v: u32| quant.position_key(w.positions[v as usize]);
    let mut faces_on_edge: HashMap<(u32, u32), u32> = HashMap::new();
    for tri in &w.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            *faces_on_edge.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    // Boundary half-edges by vertex index: (face, edge k, a = corner k+1, b = corner k+2).
    let mut half = Vec::new();
    for (t, tri) in w.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
            if a != b && faces_on_edge[&(a.min(b), a.max(b))] == 1 {
                half.push((t, k, a, b));
            }
        }
    }
    let mut by_pos: HashMap<([i64; 3], [i64; 3]), Vec<usize>> = HashMap::new();
    for (h, &(_, _, a, b)) in half.iter().enumerate() {
        by_pos.entry((key(a), key(b))).or_default().push(h);
    }
    let n = |v: u32| w.normals[v as usize];
    let uv = |v: u32| w.uvs[v as usize];
    let mut matched = vec![false; half.len()];
    let mut seams = Vec::new();
    let mut parent: Vec<u32> = (0..w.positions.len() as u32).collect();
    for h in 0..half.len() {
        let (t1, k1, a, b) = half[h];
        if matched[h] || (key(a) == key(b) && same_normal(n(a), n(b))) {
            continue;
        }
        let Some(cands) = by_pos.get(&(key(b), key(a))) else {
            continue;
        };
        // The twin runs b' → a': same positions reversed, same normals at matching ends,
        // another face, and a different UV at one end at least (else it would be welded).
        let twin = cands.iter().copied().find(|&c| {
            let (t2, _, b2, a2) = half[c];
            !matched[c]
                && c != h
                && t2 != t1
                && same_normal(n(a), n(a2))
                && same_normal(n(b), n(b2))
                && (uv(a) != uv(a2) || uv(b) != uv(b2))
        });
        let Some(c) = twin else { continue };
        matched[h] = true;
        matched[c] = true;
        let (t2, k2, b2, a2) = half[c];
        for (x, y) in [(a, a2), (b, b2)] {
            let (rx, ry) = (find(&mut parent, x), find(&mut parent, y));
            if rx != ry {
                parent[rx.max(ry) as usize] = rx.min(ry);
            }
        }
        seams.push(SeamEdge {
            faces: [t1 as u32, t2 as u32],
            edges: [k1 as u8, k2 as u8],
        });
        report.seams.push(SeamFinding {
            faces: [w.face_origin[t1], w.face_origin[t2]],
            vertices: [w.vertex_origin[a as usize], w.vertex_origin[b as usize]],
        });
    }
    for v in 0..w.positions.len() as u32 {
        let r = find(&mut parent, v);
        if r != v {
            w.positions[v as usize] = w.positions[r as usize];
            w.normals[v as usize] = w.normals[r as usize];
        }
    }
    report.uv_seam_edges = seams.len();
    seams
}
