//! Step 5: close hard edges and the corner holes between them with zero-area triangles.
//!
//! A hard edge is a boundary edge (one face, by vertex index) a→b of face F1 whose *positions*
//! match the reversed edge b'→a' of another face F2 while the vertex records differ in their
//! normals. With displacement the two sides trace different curves `V + D n`, and the wedge
//! between them belongs to no prism. The quad b→a→a'→b' fills it: triangles (b,a,a') and
//! (b,a',b') use a→b and b'→a' in the opposite direction, so the mesh stays consistently
//! oriented. After all quads, the zero-length boundary edges between copies of one position
//! form loops (k ≥ 3 copies, e.g. a cube corner); each loop is closed by a fan over it, wound
//! against the loop, which is the one orientation consistent with its neighbours.
//!
//! Edges whose positions and normals match but UVs differ are UV seams: their walls coincide,
//! only the height can jump. They are counted, not stitched (the seams issue handles them).
//! Crease repair (`crease`) works by position, so its hard edges may lie on UV seams and cross
//! them: the two sides of a stitched edge may differ in UV as well as normal, and where only
//! one end differs in normal (a crease ending there) only the half of the quad that spans the
//! normal jump is inserted. Corner loops are followed by normal (see `close_corners`). The
//! result is closed up to UV seams: every edge, by vertex index, has two faces or is a UV seam
//! edge with a twin (same positions and normals, other UVs).

use super::weld::Quantizer;
use super::{CornerFan, RepairReport, StitchedEdge, Work, INSERTED_ORIGIN};
use crate::mesh::FACE_INSERTED;
use glam::Vec3;
use std::collections::HashMap;

type EdgeKey = (u32, u32);
type PosKey = [i64; 3];

fn edge_key(a: u32, b: u32) -> EdgeKey {
    (a.min(b), a.max(b))
}

/// Normals equal up to the weld grid (they are unit vectors: an absolute grid).
fn same_normal(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() <= 1e-6
}

/// Number of faces on each undirected edge, by vertex index.
fn edge_counts(triangles: &[[u32; 3]]) -> HashMap<EdgeKey, u32> {
    let mut counts = HashMap::new();
    for tri in triangles {
        for k in 0..3 {
            *counts
                .entry(edge_key(tri[k], tri[(k + 1) % 3]))
                .or_insert(0) += 1;
        }
    }
    counts
}

/// Directed boundary edges `(face, a, b)` in face order.
fn boundary_half_edges(triangles: &[[u32; 3]]) -> Vec<(usize, u32, u32)> {
    let counts = edge_counts(triangles);
    let mut out = Vec::new();
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if a != b && counts[&edge_key(a, b)] == 1 {
                out.push((t, a, b));
            }
        }
    }
    out
}

pub(super) fn stitch(w: &mut Work, quant: &Quantizer, enabled: bool, report: &mut RepairReport) {
    let pos: Vec<PosKey> = w.positions.iter().map(|&p| quant.position_key(p)).collect();
    stitch_edges(w, &pos, enabled, report);
    if enabled {
        close_corners(w, &pos, report);
    }
    report.open_boundary_edges = edge_counts(&w.triangles)
        .values()
        .filter(|&&c| c == 1)
        .count();
}

fn push_inserted(w: &mut Work, tri: [u32; 3], group: u32) -> Option<u32> {
    if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
        return None;
    }
    w.triangles.push(tri);
    w.face_origin.push(INSERTED_ORIGIN);
    w.face_group.push(group);
    w.face_flags.push(FACE_INSERTED);
    Some((w.triangles.len() - 1) as u32)
}

/// Pair every boundary edge with a reversed boundary edge at the same positions; stitch hard
/// ones, count UV seams. Pairing is greedy in face order (first unmatched candidate).
fn stitch_edges(w: &mut Work, pos: &[PosKey], enabled: bool, report: &mut RepairReport) {
    let half = boundary_half_edges(&w.triangles);
    let mut by_pos: HashMap<(PosKey, PosKey), Vec<usize>> = HashMap::new();
    for (h, &(_, a, b)) in half.iter().enumerate() {
        if pos[a as usize] != pos[b as usize] {
            by_pos
                .entry((pos[a as usize], pos[b as usize]))
                .or_default()
                .push(h);
        }
    }
    let mut matched = vec![false; half.len()];
    for h in 0..half.len() {
        let (t1, a, b) = half[h];
        if matched[h] || pos[a as usize] == pos[b as usize] {
            continue;
        }
        let Some(cands) = by_pos.get(&(pos[b as usize], pos[a as usize])) else {
            continue;
        };
        let Some(&h2) = cands.iter().find(|&&c| !matched[c] && half[c].0 != t1) else {
            continue;
        };
        matched[h] = true;
        matched[h2] = true;
        let (t2, b2, a2) = half[h2];
        let n = |i: u32| w.normals[i as usize];
        let (same_a, same_b) = (same_normal(n(a), n(a2)), same_normal(n(b), n(b2)));
        if same_a && same_b {
            let uv = |i: u32| w.uvs[i as usize];
            if uv(a) != uv(a2) || uv(b) != uv(b2) {
                report.uv_seam_edges += 1;
            }
            continue;
        }
        if !enabled {
            report.unstitched_hard_edges += 1;
            continue;
        }
        let group = w.face_group[t1];
        // Where one end agrees in normal (a crease ending there, possibly on a UV seam) only
        // the other half of the quad is needed; its zero-length edge would join seam twins.
        let inserted: Vec<u32> = [(!same_a, [b, a, a2]), (!same_b, [b, a2, b2])]
            .into_iter()
            .filter(|&(needed, _)| needed)
            .filter_map(|(_, tri)| push_inserted(w, tri, group))
            .collect();
        report.inserted_triangles += inserted.len();
        report.stitched_edges.push(StitchedEdge {
            faces: [w.face_origin[t1], w.face_origin[t2]],
            vertices: [a, b, a2, b2],
            inserted,
        });
    }
}

/// Close the loops of zero-length boundary edges left at positions where ≥ 3 copies meet.
///
/// The loop is followed over the copies' NORMALS, not their records: where a UV seam crosses
/// the crease, one normal has several records (seam twins), and the loop passes from one twin
/// to the other across the seam. A loop of two normals (a crease crossing a UV seam) is already
/// closed up to the seam: nothing to fill. A loop of k ≥ 3 normals is filled by a fan over one
/// record per normal (the tail of its outgoing edge); where that record differs from a twin
/// the fan's edge is again a UV seam edge.
fn close_corners(w: &mut Work, pos: &[PosKey], report: &mut RepairReport) {
    let mut groups: HashMap<PosKey, Vec<(u32, u32)>> = HashMap::new();
    for (_, a, b) in boundary_half_edges(&w.triangles) {
        if pos[a as usize] == pos[b as usize] {
            groups.entry(pos[a as usize]).or_default().push((a, b));
        }
    }
    let mut keys: Vec<PosKey> = groups.keys().copied().collect();
    keys.sort_unstable();
    for key in keys {
        let edges = &groups[&key];
        // Normal class of each record: the smallest record at this position with its normal.
        let mut records: Vec<u32> = edges.iter().flat_map(|&(a, b)| [a, b]).collect();
        records.sort_unstable();
        records.dedup();
        let class = |v: u32| -> u32 {
            let n = w.normals[v as usize];
            *records
                .iter()
                .find(|&&r| same_normal(w.normals[r as usize], n))
                .expect("v is among the records")
        };
        // Class → (next class, tail record).
        let mut next: HashMap<u32, (u32, u32)> = HashMap::new();
        let mut ambiguous = false;
        for &(a, b) in edges {
            let (ca, cb) = (class(a), class(b));
            ambiguous |= ca == cb || next.insert(ca, (cb, a)).is_some();
        }
        if ambiguous {
            report.unclosed_corners += 1;
            continue;
        }
        let mut starts: Vec<u32> = next.keys().copied().collect();
        starts.sort_unstable();
        let mut visited: Vec<u32> = Vec::new();
        let mut open = false;
        for s in starts {
            if visited.contains(&s) {
                continue;
            }
            let mut cycle = vec![s];
            let mut cur = s;
            let closed = loop {
                match next.get(&cur) {
                    Some(&(n, _)) if n == s => break true,
                    Some(&(n, _)) if !cycle.contains(&n) => {
                        cycle.push(n);
                        cur = n;
                    }
                    _ => break false,
                }
            };
            visited.extend_from_slice(&cycle);
            if closed && cycle.len() >= 3 {
                let tails: Vec<u32> = cycle.iter().map(|c| next[c].1).collect();
                fan(w, &tails, report);
            } else if !closed {
                open = true;
            }
        }
        if open {
            report.unclosed_corners += 1;
        }
    }
}

/// Fill the boundary loop `u0→u1→…→u(k−1)→u0` with triangles `(u0, u(i+1), u(i))`.
fn fan(w: &mut Work, cycle: &[u32], report: &mut RepairReport) {
    let group = w
        .triangles
        .iter()
        .position(|tri| tri.contains(&cycle[0]))
        .map_or(0, |t| w.face_group[t]);
    let mut inserted = Vec::new();
    for i in 1..cycle.len() - 1 {
        if let Some(t) = push_inserted(w, [cycle[0], cycle[i + 1], cycle[i]], group) {
            inserted.push(t);
        }
    }
    // The fan's polygon, in its own winding: u0, u(k−1), …, u1.
    let order: Vec<u32> = std::iter::once(cycle[0])
        .chain(cycle[1..].iter().rev().copied())
        .collect();
    let displaced: Vec<Vec3> = order
        .iter()
        .map(|&i| w.positions[i as usize] + w.normals[i as usize])
        .collect();
    let area: Vec3 = (0..displaced.len())
        .map(|i| displaced[i].cross(displaced[(i + 1) % displaced.len()]))
        .sum();
    let mean_normal: Vec3 = order.iter().map(|&i| w.normals[i as usize]).sum();
    report.inserted_triangles += inserted.len();
    report.corner_fans.push(CornerFan {
        vertices: order,
        inserted,
        against_normals: area.dot(mean_normal) < 0.0,
    });
}
