//! Steps 3–4: inverted and sharp corners, crease edges, and the edge split.
//!
//! PDM (Hoetzlein 2025, §5.4) extrudes corner `i` by `w/(n_i·N_g)`, which blows up as the
//! normal turns into the face's plane; the paper inserts two triangles at edges whose interior
//! angle is below ~5°. Here the crease is first *split* (each side of it gets its own vertex
//! copies with their own normals, so every corner sees a normal close to its face's) and the
//! split is then closed by the inserted triangles of `stitch`, which is where the paper's
//! triangles end up. Departure from the paper: it names the edge test only; we also mark edges
//! next to a sharp corner whose faces differ by more than `KNIFE_EDGE_MIN_ANGLE`, because a bad
//! smooth normal across a moderately sharp rim produces the same singularity.

use super::{CornerFinding, RepairReport, VertexSplit, Work};
use glam::Vec3;
use std::collections::{HashMap, HashSet};

/// Faces meeting at a sharp corner are split apart when their normals differ by more than this
/// (60°): well beyond the smooth shading of ordinary meshes, well short of a knife edge.
const KNIFE_EDGE_MIN_ANGLE_COS: f32 = 0.5;

type EdgeKey = (u32, u32);

fn edge_key(a: u32, b: u32) -> EdgeKey {
    (a.min(b), a.max(b))
}

/// `n_i·N̂_g` of corner `k` of face `t` (the normal renormalised; NaN if it is not finite).
fn corner_dot(w: &Work, t: usize, k: usize, ng: Vec3) -> f32 {
    let n = w.normals[w.triangles[t][k] as usize];
    if !n.is_finite() {
        return f32::NAN;
    }
    n.normalize_or_zero().dot(ng)
}

fn finding(w: &Work, t: usize, k: usize, dot: f32) -> CornerFinding {
    CornerFinding {
        face: w.face_origin[t],
        corner: k as u8,
        vertex: w.vertex_origin[w.triangles[t][k] as usize],
        dot,
    }
}

/// Corners `(t, k)` of original faces with `n·N̂_g` failing `ok`, with their dot products.
fn corners_where(w: &Work, ok: impl Fn(f32) -> bool) -> Vec<(usize, usize, f32)> {
    let mut out = Vec::new();
    for t in 0..w.triangles.len() {
        if w.is_inserted(t) {
            continue;
        }
        let ng = w.face_normal(t);
        for k in 0..3 {
            let d = corner_dot(w, t, k, ng);
            if !ok(d) {
                out.push((t, k, d));
            }
        }
    }
    out
}

/// Step 3: corners whose normal faces away from the face (`n·N̂_g ≤ 0`, or not finite).
pub(super) fn report_inverted_corners(w: &Work, report: &mut RepairReport) {
    for (t, k, d) in corners_where(w, |d| d > 0.0) {
        report.inverted_corners.push(finding(w, t, k, d));
    }
}

/// Step 4: find sharp corners and crease edges, split vertices by sector, and list the corners
/// still below `threshold` afterwards.
pub(super) fn split_creases(w: &mut Work, threshold: f32, report: &mut RepairReport) {
    let sharp = corners_where(w, |d| d >= threshold);
    for &(t, k, d) in &sharp {
        report.sharp_corners.push(finding(w, t, k, d));
    }
    let face_n: Vec<Vec3> = (0..w.triangles.len()).map(|t| w.face_normal(t)).collect();
    let mut edge_faces: HashMap<EdgeKey, Vec<u32>> = HashMap::new();
    for (t, tri) in w.triangles.iter().enumerate() {
        if w.is_inserted(t) {
            continue;
        }
        for k in 0..3 {
            edge_faces
                .entry(edge_key(tri[k], tri[(k + 1) % 3]))
                .or_default()
                .push(t as u32);
        }
    }
    let creases = find_crease_edges(w, threshold, &sharp, &face_n, &edge_faces);
    let mut sorted: Vec<EdgeKey> = creases.iter().copied().collect();
    sorted.sort_unstable();
    for &(a, b) in &sorted {
        let (oa, ob) = (w.vertex_origin[a as usize], w.vertex_origin[b as usize]);
        report.crease_edges.push([oa.min(ob), oa.max(ob)]);
    }
    if !creases.is_empty() {
        split_vertices(w, &creases, &face_n, &edge_faces, report);
    }
    for (t, k, d) in corners_where(w, |d| d >= threshold) {
        report.unresolved_crease_corners.push(finding(w, t, k, d));
    }
}

/// Crease edges (manifold edges only): interior dihedral angle below the threshold's angle
/// `θ = 2 asin(threshold)` (`N̂_1·N̂_2 < −cos θ`), or next to a sharp corner with faces more
/// than 60° apart.
fn find_crease_edges(
    w: &Work,
    threshold: f32,
    sharp: &[(usize, usize, f32)],
    face_n: &[Vec3],
    edge_faces: &HashMap<EdgeKey, Vec<u32>>,
) -> HashSet<EdgeKey> {
    let theta = 2.0 * threshold.clamp(-1.0, 1.0).asin();
    let dihedral_limit = -theta.cos();
    let pair_dot = |e: &EdgeKey| -> Option<f32> {
        match edge_faces.get(e).map(Vec::as_slice) {
            Some(&[f1, f2]) => Some(face_n[f1 as usize].dot(face_n[f2 as usize])),
            _ => None,
        }
    };
    let mut creases: HashSet<EdgeKey> = edge_faces
        .keys()
        .filter(|e| pair_dot(e).is_some_and(|d| d < dihedral_limit))
        .copied()
        .collect();
    for &(t, k, _) in sharp {
        let tri = w.triangles[t];
        let v = tri[k];
        for other in [tri[(k + 1) % 3], tri[(k + 2) % 3]] {
            let e = edge_key(v, other);
            if pair_dot(&e).is_some_and(|d| d < KNIFE_EDGE_MIN_ANGLE_COS) {
                creases.insert(e);
            }
        }
    }
    creases
}

/// Interior angle of face `t` at its corner `k`.
fn corner_angle(w: &Work, t: usize, k: usize) -> f32 {
    let p = w.triangles[t].map(|i| w.positions[i as usize]);
    let e1 = (p[(k + 1) % 3] - p[k]).normalize_or_zero();
    let e2 = (p[(k + 2) % 3] - p[k]).normalize_or_zero();
    e1.dot(e2).clamp(-1.0, 1.0).acos()
}

/// The edge split: at each vertex touching a crease, partition its fan into sectors joined
/// across non-crease edges; with ≥ 2 sectors every sector gets its own copy (same position and
/// UV) carrying the angle-weighted normal of that sector's faces. Sectors are computed on the
/// unsplit mesh and applied afterwards, so the order of vertices does not matter.
fn split_vertices(
    w: &mut Work,
    creases: &HashSet<EdgeKey>,
    face_n: &[Vec3],
    edge_faces: &HashMap<EdgeKey, Vec<u32>>,
    report: &mut RepairReport,
) {
    let mut crease_vertices: Vec<u32> = creases.iter().flat_map(|&(a, b)| [a, b]).collect();
    crease_vertices.sort_unstable();
    crease_vertices.dedup();
    let mut fan: HashMap<u32, Vec<u32>> = HashMap::new();
    for (t, tri) in w.triangles.iter().enumerate() {
        if w.is_inserted(t) {
            continue;
        }
        for &v in tri {
            if crease_vertices.binary_search(&v).is_ok() {
                fan.entry(v).or_default().push(t as u32);
            }
        }
    }
    // (face, corner slot, new vertex) for every corner that moves to a copy.
    let mut moves: Vec<(usize, usize, u32)> = Vec::new();
    let mut new_normals: Vec<(u32, Vec3)> = Vec::new();
    for &v in &crease_vertices {
        let faces = &fan[&v];
        let sectors = fan_sectors(w, v, faces, creases, edge_faces);
        if sectors.len() < 2 {
            continue;
        }
        let mut copies = Vec::with_capacity(sectors.len());
        for (s, sector) in sectors.iter().enumerate() {
            let mut n = Vec3::ZERO;
            for &t in sector {
                let k = slot_of(w, t, v);
                n += face_n[t as usize] * corner_angle(w, t as usize, k);
            }
            let n = n.try_normalize().unwrap_or(w.normals[v as usize]);
            let id = if s == 0 {
                v
            } else {
                w.positions.push(w.positions[v as usize]);
                w.normals.push(n);
                w.uvs.push(w.uvs[v as usize]);
                w.vertex_origin.push(w.vertex_origin[v as usize]);
                (w.positions.len() - 1) as u32
            };
            if s == 0 {
                new_normals.push((v, n));
            }
            for &t in sector {
                moves.push((t as usize, slot_of(w, t, v), id));
            }
            copies.push(id);
        }
        report.split_vertices.push(VertexSplit {
            vertex: w.vertex_origin[v as usize],
            copies,
        });
    }
    for (v, n) in new_normals {
        w.normals[v as usize] = n;
    }
    for (t, k, id) in moves {
        w.triangles[t][k] = id;
    }
}

fn slot_of(w: &Work, t: u32, v: u32) -> usize {
    w.triangles[t as usize]
        .iter()
        .position(|&i| i == v)
        .expect("face is in the vertex's fan")
}

/// Faces around `v` grouped into sectors (connected across non-crease edges), each sector's
/// faces ascending, sectors ordered by their first face.
fn fan_sectors(
    w: &Work,
    v: u32,
    faces: &[u32],
    creases: &HashSet<EdgeKey>,
    edge_faces: &HashMap<EdgeKey, Vec<u32>>,
) -> Vec<Vec<u32>> {
    let local: HashMap<u32, usize> = faces.iter().enumerate().map(|(i, &t)| (t, i)).collect();
    let mut parent: Vec<usize> = (0..faces.len()).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for (i, &t) in faces.iter().enumerate() {
        let tri = w.triangles[t as usize];
        for &other in tri.iter().filter(|&&o| o != v) {
            let e = edge_key(v, other);
            if creases.contains(&e) {
                continue;
            }
            for f in edge_faces.get(&e).into_iter().flatten() {
                if let Some(&j) = local.get(f) {
                    let (a, b) = (find(&mut parent, i), find(&mut parent, j));
                    parent[a.max(b)] = a.min(b);
                }
            }
        }
    }
    let mut groups: Vec<Vec<u32>> = Vec::new();
    let mut root_group: HashMap<usize, usize> = HashMap::new();
    for (i, &t) in faces.iter().enumerate() {
        let r = find(&mut parent, i);
        let g = *root_group.entry(r).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[g].push(t);
    }
    groups
}
