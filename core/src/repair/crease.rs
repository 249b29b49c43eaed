//! Steps 3–4: inverted and sharp corners, crease edges, and the edge split.
//!
//! PDM (Hoetzlein 2025, §5.4) extrudes corner `i` by `w/(n_i·N_g)`, which blows up as the
//! normal turns into the face's plane; the paper inserts two triangles at edges whose interior
//! angle is below ~5°. Here the crease is first *split* (each side of it gets its own vertex
//! copies with their own normals, so every corner sees a normal close to its face's) and the
//! split is then closed by the inserted triangles of `stitch`, which is where the paper's
//! triangles end up. Departure from the paper: it names the edge test only; we also mark edges
//! through the position of a sharp corner whose faces differ by more than 60°
//! (`KNIFE_EDGE_MIN_ANGLE_COS`), because a bad smooth normal across a moderately sharp rim
//! produces the same singularity, and a knife-edge rim that opens to just over 5° must not end
//! the crease at a vertex whose corners are still sharp.
//!
//! Everything here works on the mesh's topology BY POSITION (the quantised position keys of
//! `weld`), not by vertex index: real assets are split into UV islands, so a rim edge is often
//! a UV seam (two faces, same positions and normals, different vertex records). An edge is a
//! pair of positions; two faces sharing it are neighbours whatever records they use. At a
//! position touching a crease, the corners are grouped into sectors (joined across non-crease
//! edges whose records agree in normal there, so UV seams join and authored hard edges stay
//! apart); each sector gets its angle-weighted normal. A vertex record used by one sector only
//! takes that normal in place (seam twins in one sector keep equal normals: still a plain UV
//! seam); a record used by several sectors is copied, one copy per sector.

use super::weld::Quantizer;
use super::{CornerFinding, RepairReport, VertexSplit, Work};
use glam::Vec3;
use std::collections::{BTreeMap, HashMap, HashSet};

/// Faces meeting at a sharp corner are split apart when their normals differ by more than this
/// (60°): well beyond the smooth shading of ordinary meshes, well short of a knife edge.
const KNIFE_EDGE_MIN_ANGLE_COS: f32 = 0.5;

/// An undirected edge as a pair of position ids, smaller first.
type PosEdge = (u32, u32);

fn edge_key(a: u32, b: u32) -> PosEdge {
    (a.min(b), a.max(b))
}

/// Normals equal up to the weld grid (the same test as `stitch`'s).
fn same_normal(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() <= 1e-6
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

/// The position topology of the original (not inserted) faces.
struct PosTopology {
    /// Position id of every vertex record (dense, numbered in order of first record).
    pos: Vec<u32>,
    /// Original faces on each position edge, ascending.
    edge_faces: HashMap<PosEdge, Vec<u32>>,
}

impl PosTopology {
    fn new(w: &Work, quant: &Quantizer) -> Self {
        let mut ids: HashMap<[i64; 3], u32> = HashMap::new();
        let pos: Vec<u32> = w
            .positions
            .iter()
            .map(|&p| {
                let fresh = ids.len() as u32;
                *ids.entry(quant.position_key(p)).or_insert(fresh)
            })
            .collect();
        let mut edge_faces: HashMap<PosEdge, Vec<u32>> = HashMap::new();
        for (t, tri) in w.triangles.iter().enumerate() {
            if w.is_inserted(t) {
                continue;
            }
            for k in 0..3 {
                let (a, b) = (pos[tri[k] as usize], pos[tri[(k + 1) % 3] as usize]);
                if a != b {
                    edge_faces.entry(edge_key(a, b)).or_default().push(t as u32);
                }
            }
        }
        PosTopology { pos, edge_faces }
    }
    /// Position id of corner `k` of face `t`.
    fn corner(&self, w: &Work, t: usize, k: usize) -> u32 {
        self.pos[w.triangles[t][k] as usize]
    }
}

/// Step 4: find sharp corners and crease edges, split vertices by sector, and list the corners
/// still below `threshold` afterwards.
pub(super) fn split_creases(
    w: &mut Work,
    quant: &Quantizer,
    threshold: f32,
    report: &mut RepairReport,
) {
    let sharp = corners_where(w, |d| d >= threshold);
    for &(t, k, d) in &sharp {
        report.sharp_corners.push(finding(w, t, k, d));
    }
    let face_n: Vec<Vec3> = (0..w.triangles.len()).map(|t| w.face_normal(t)).collect();
    let topo = PosTopology::new(w, quant);
    let creases = find_crease_edges(w, &topo, threshold, &sharp, &face_n);
    let mut sorted: Vec<PosEdge> = creases.iter().copied().collect();
    sorted.sort_unstable();
    for e in &sorted {
        // Named by the records of the edge's first face.
        let t = topo.edge_faces[e][0] as usize;
        let origin = |p: u32| {
            let k = (0..3)
                .find(|&k| topo.corner(w, t, k) == p)
                .expect("edge of face");
            w.vertex_origin[w.triangles[t][k] as usize]
        };
        let (oa, ob) = (origin(e.0), origin(e.1));
        report.crease_edges.push([oa.min(ob), oa.max(ob)]);
    }
    if !creases.is_empty() {
        split_vertices(w, &topo, &creases, &face_n, report);
    }
    for (t, k, d) in corners_where(w, |d| d >= threshold) {
        report.unresolved_crease_corners.push(finding(w, t, k, d));
    }
}

/// Crease edges (edges with two faces by position): interior dihedral angle below the
/// threshold's angle `θ = 2 asin(threshold)` (`N̂_1·N̂_2 < −cos θ`), or through the position
/// of a sharp corner with faces more than 60° apart.
fn find_crease_edges(
    w: &Work,
    topo: &PosTopology,
    threshold: f32,
    sharp: &[(usize, usize, f32)],
    face_n: &[Vec3],
) -> HashSet<PosEdge> {
    let theta = 2.0 * threshold.clamp(-1.0, 1.0).asin();
    let dihedral_limit = -theta.cos();
    let pair_dot = |e: &PosEdge| -> Option<f32> {
        match topo.edge_faces.get(e).map(Vec::as_slice) {
            Some(&[f1, f2]) => Some(face_n[f1 as usize].dot(face_n[f2 as usize])),
            _ => None,
        }
    };
    let mut creases: HashSet<PosEdge> = topo
        .edge_faces
        .keys()
        .filter(|e| pair_dot(e).is_some_and(|d| d < dihedral_limit))
        .copied()
        .collect();
    // The 60° rule, by position: a sharp corner's normal is shared by the whole fan at its
    // position (smooth shading), so every fold through that position can make it singular,
    // not only the edges of the sharp corner's own face. (A knife-edge rim that opens to just
    // over 5° still folds far beyond 60°: this carries the crease on to the first position
    // with no sharp corner, where it can end without leaving a corner unresolved.)
    let sharp_pos: HashSet<u32> = sharp
        .iter()
        .map(|&(t, k, _)| topo.corner(w, t, k))
        .collect();
    creases.extend(
        topo.edge_faces
            .keys()
            .filter(|e| sharp_pos.contains(&e.0) || sharp_pos.contains(&e.1))
            .filter(|e| pair_dot(e).is_some_and(|d| d < KNIFE_EDGE_MIN_ANGLE_COS)),
    );
    creases
}

/// Interior angle of face `t` at its corner `k`.
fn corner_angle(w: &Work, t: usize, k: usize) -> f32 {
    let p = w.triangles[t].map(|i| w.positions[i as usize]);
    let e1 = (p[(k + 1) % 3] - p[k]).normalize_or_zero();
    let e2 = (p[(k + 2) % 3] - p[k]).normalize_or_zero();
    e1.dot(e2).clamp(-1.0, 1.0).acos()
}

/// The edge split: at each position touching a crease, partition its corners into sectors;
/// with ≥ 2 sectors every sector gets the angle-weighted normal of its faces. A record whose
/// corners all lie in one sector takes that normal in place; a record in several sectors keeps
/// its slot for the first and gets a copy (same position and UV) for each further one.
/// Sectors are computed on the unsplit mesh and applied afterwards, so the order of positions
/// does not matter. Reported: every record that was copied or whose normal changed.
fn split_vertices(
    w: &mut Work,
    topo: &PosTopology,
    creases: &HashSet<PosEdge>,
    face_n: &[Vec3],
    report: &mut RepairReport,
) {
    let crease_pos: HashSet<u32> = creases.iter().flat_map(|&(a, b)| [a, b]).collect();
    // Corners (face, slot) at each crease position, in face order.
    let mut fan: BTreeMap<u32, Vec<(u32, u8)>> = BTreeMap::new();
    for (t, tri) in w.triangles.iter().enumerate() {
        if w.is_inserted(t) {
            continue;
        }
        for (k, &v) in tri.iter().enumerate() {
            let p = topo.pos[v as usize];
            if crease_pos.contains(&p) {
                fan.entry(p).or_default().push((t as u32, k as u8));
            }
        }
    }
    // (face, corner slot, new vertex) for every corner that moves to a copy.
    let mut moves: Vec<(usize, usize, u32)> = Vec::new();
    let mut new_normals: Vec<(u32, Vec3)> = Vec::new();
    let mut splits: Vec<VertexSplit> = Vec::new();
    for (&p, corners) in &fan {
        let sectors = fan_sectors(w, topo, p, corners, creases);
        if sectors.len() < 2 {
            continue;
        }
        let sector_n: Vec<Vec3> = sectors
            .iter()
            .map(|sector| {
                sector
                    .iter()
                    .map(|&(t, k)| face_n[t as usize] * corner_angle(w, t as usize, k as usize))
                    .sum::<Vec3>()
                    .try_normalize()
                    .unwrap_or(Vec3::ZERO)
            })
            .collect();
        // Sectors of each record at p, in sector order.
        let mut record_sectors: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
        for (s, sector) in sectors.iter().enumerate() {
            for &(t, k) in sector {
                let v = w.triangles[t as usize][k as usize];
                let list = record_sectors.entry(v).or_default();
                if !list.contains(&s) {
                    list.push(s);
                }
            }
        }
        for (&v, secs) in &record_sectors {
            let own = w.normals[v as usize];
            let normal_of = |s: usize| {
                if sector_n[s] == Vec3::ZERO {
                    own
                } else {
                    sector_n[s]
                }
            };
            let mut copies = Vec::with_capacity(secs.len());
            for (i, &s) in secs.iter().enumerate() {
                let n = normal_of(s);
                let id = if i == 0 {
                    new_normals.push((v, n));
                    v
                } else {
                    w.positions.push(w.positions[v as usize]);
                    w.normals.push(n);
                    w.uvs.push(w.uvs[v as usize]);
                    w.vertex_origin.push(w.vertex_origin[v as usize]);
                    let id = (w.positions.len() - 1) as u32;
                    for &(t, k) in &sectors[s] {
                        if w.triangles[t as usize][k as usize] == v {
                            moves.push((t as usize, k as usize, id));
                        }
                    }
                    id
                };
                copies.push(id);
            }
            if copies.len() > 1 || !same_normal(normal_of(secs[0]), own) {
                splits.push(VertexSplit {
                    vertex: w.vertex_origin[v as usize],
                    copies,
                });
            }
        }
    }
    for (v, n) in new_normals {
        w.normals[v as usize] = n;
    }
    for (t, k, id) in moves {
        w.triangles[t][k] = id;
    }
    report.split_vertices.extend(splits);
}

/// Corners at position `p` grouped into sectors: two corners are joined when their faces share
/// a non-crease edge (by position) at `p` and their records there agree in normal (a UV seam
/// joins, an authored hard edge does not). Each sector's corners in face order, sectors
/// ordered by their first corner.
fn fan_sectors(
    w: &Work,
    topo: &PosTopology,
    p: u32,
    corners: &[(u32, u8)],
    creases: &HashSet<PosEdge>,
) -> Vec<Vec<(u32, u8)>> {
    let local: HashMap<u32, usize> = corners
        .iter()
        .enumerate()
        .map(|(i, &(t, _))| (t, i))
        .collect();
    let mut parent: Vec<usize> = (0..corners.len()).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    let record = |i: usize| {
        let (t, k) = corners[i];
        w.triangles[t as usize][k as usize]
    };
    for (i, &(t, k)) in corners.iter().enumerate() {
        let (t, k) = (t as usize, k as usize);
        for j in [(k + 1) % 3, (k + 2) % 3] {
            let other = topo.corner(w, t, j);
            if other == p {
                continue;
            }
            let e = edge_key(p, other);
            if creases.contains(&e) {
                continue;
            }
            for f in topo.edge_faces.get(&e).into_iter().flatten() {
                let Some(&j) = local.get(f) else { continue };
                let (ni, nj) = (w.normals[record(i) as usize], w.normals[record(j) as usize]);
                if !same_normal(ni, nj) {
                    continue;
                }
                let (a, b) = (find(&mut parent, i), find(&mut parent, j));
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut groups: Vec<Vec<(u32, u8)>> = Vec::new();
    let mut root_group: HashMap<usize, usize> = HashMap::new();
    for (i, &c) in corners.iter().enumerate() {
        let r = find(&mut parent, i);
        let g = *root_group.entry(r).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[g].push(c);
    }
    groups
}
