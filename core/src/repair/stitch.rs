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
//! Where an end's two normals are more than 90° apart (a knife edge), the quad becomes a strip:
//! each end gets a ladder of inserted copies whose normals turn from one side to the other
//! (`strip::NormalArc`, shared by every strip that meets at that pair of records), and the two
//! ladders are zipped into triangles (`strip::zip`). Corner loops then run through the ladders'
//! copies and are fanned around an inserted centre vertex (`fan`).
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
use super::{strip, CornerFan, RepairOptions, RepairReport, StitchedEdge, Work, INSERTED_ORIGIN};
use crate::mesh::FACE_INSERTED;
use glam::{Vec2, Vec3};
use std::collections::{HashMap, HashSet};

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

pub(super) fn stitch(
    w: &mut Work,
    quant: &Quantizer,
    opts: &RepairOptions,
    report: &mut RepairReport,
) {
    let pos: Vec<PosKey> = w.positions.iter().map(|&p| quant.position_key(p)).collect();
    let first_inserted_vertex = w.positions.len();
    let enabled = opts.stitch_hard_edges;
    let hard = pair_hard_edges(w, &pos, enabled, report);
    if enabled {
        let mut ladders = Ladders::new(w, &pos, &hard, opts.strip_step_angle);
        for e in &hard {
            insert_strip(w, &mut ladders, e, report);
        }
        close_corners(w, quant, first_inserted_vertex, report);
    }
    report.inserted_vertices = w.positions.len() - first_inserted_vertex;
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

/// A hard edge: `a → b` of face `t1` and `b2 → a2` of face `t2`, same positions, and the
/// normals differ at one end at least.
struct HardEdge {
    t1: usize,
    t2: usize,
    a: u32,
    b: u32,
    a2: u32,
    b2: u32,
}

/// Pair every boundary edge with a reversed boundary edge at the same positions; return the
/// hard ones, count UV seams (and, with stitching off, the hard edges left open). Pairing is
/// greedy in face order (first unmatched candidate).
fn pair_hard_edges(
    w: &Work,
    pos: &[PosKey],
    enabled: bool,
    report: &mut RepairReport,
) -> Vec<HardEdge> {
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
    let mut hard = Vec::new();
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
        if same_normal(n(a), n(a2)) && same_normal(n(b), n(b2)) {
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
        hard.push(HardEdge {
            t1,
            t2,
            a,
            b,
            a2,
            b2,
        });
    }
    hard
}

/// Normal bits, for ordering a pair of normals the same way wherever it occurs.
fn normal_bits(n: Vec3) -> [u32; 3] {
    n.to_array().map(f32::to_bits)
}

/// The ladders of inserted vertices at the ends of hard edges: for a pair of records at one
/// position (the first face's, the second face's), the records whose normals turn from one to
/// the other (`strip::NormalArc`), both included. Made once per pair and shared by every strip
/// that meets there, so that neighbouring strips share their zero-length edges by index.
struct Ladders {
    /// Away-from-the-solid direction per (position, ordered normal pair): the sum of
    /// `strip::edge_hint` over the hard edges that end there with that pair of normals.
    hints: HashMap<(PosKey, [[u32; 3]; 2]), Vec3>,
    /// The (position, ordered normal pair) keys where some hard edge's two records differ in
    /// UV: their arcs take at least two steps (a single quad has no rung for seam twins), on
    /// every ladder of the key alike, so that they all have the same normals.
    seamed: HashSet<(PosKey, [[u32; 3]; 2])>,
    /// (record with the smaller normal bits, the other) → ladder from the first to the second.
    made: HashMap<(u32, u32), Vec<u32>>,
    /// Inserted records by (position, normal bits, UV bits).
    records: HashMap<(PosKey, [u32; 3], [u32; 2]), u32>,
    pos: Vec<PosKey>,
    step: f32,
}

impl Ladders {
    fn new(w: &Work, pos: &[PosKey], hard: &[HardEdge], step: f32) -> Self {
        let mut hints: HashMap<(PosKey, [[u32; 3]; 2]), Vec3> = HashMap::new();
        let mut seamed = HashSet::new();
        for e in hard {
            let p = |i: u32| w.positions[i as usize];
            let third = |t: usize, x: u32, y: u32| {
                let tri = w.triangles[t];
                p(*tri.iter().find(|&&v| v != x && v != y).expect("a triangle"))
            };
            let h = strip::edge_hint(
                p(e.a),
                p(e.b),
                third(e.t1, e.a, e.b),
                w.face_normal(e.t1),
                third(e.t2, e.a2, e.b2),
                w.face_normal(e.t2),
            );
            for (x, y) in [(e.a, e.a2), (e.b, e.b2)] {
                let (nx, ny) = (w.normals[x as usize], w.normals[y as usize]);
                if !same_normal(nx, ny) {
                    let (bx, by) = (normal_bits(nx), normal_bits(ny));
                    let key = (pos[x as usize], [bx.min(by), bx.max(by)]);
                    *hints.entry(key).or_insert(Vec3::ZERO) += h;
                    if w.uvs[x as usize] != w.uvs[y as usize] {
                        seamed.insert(key);
                    }
                }
            }
        }
        Ladders {
            hints,
            seamed,
            made: HashMap::new(),
            records: HashMap::new(),
            pos: pos.to_vec(),
            step,
        }
    }

    /// Records from `from` to `to` (one position). Equal normals: just `[to]` (a crease
    /// ending there), or `[from, to]` where their UVs differ (a UV seam ends the crease
    /// there: the seam twins, see `insert_strip`).
    ///
    /// Where the two records' UVs differ (the crease is also a UV seam), the inserted records
    /// do not interpolate the UVs, which would squeeze whatever the atlas holds between the
    /// two islands into the rounded edge: the first half of the ladder keeps `from`'s UV, the
    /// second half `to`'s, and the middle rung has two records, one with each (seam twins:
    /// same position and normal). The strip's two halves then carry each side's own relief
    /// along the edge and meet at a UV seam, which the seam stitch closes like any other.
    fn ladder(&mut self, w: &mut Work, from: u32, to: u32) -> Vec<u32> {
        let (nf, nt) = (w.normals[from as usize], w.normals[to as usize]);
        if same_normal(nf, nt) {
            return if w.uvs[from as usize] != w.uvs[to as usize] {
                vec![from, to]
            } else {
                vec![to]
            };
        }
        let swapped = normal_bits(nf) > normal_bits(nt);
        let (lo, hi) = if swapped { (to, from) } else { (from, to) };
        let mut rungs = match self.made.get(&(lo, hi)) {
            Some(r) => r.clone(),
            None => {
                let (nlo, nhi) = (w.normals[lo as usize], w.normals[hi as usize]);
                let key = (self.pos[lo as usize], [normal_bits(nlo), normal_bits(nhi)]);
                let hint = self.hints.get(&key).copied().unwrap_or(Vec3::ZERO);
                let mut arc = strip::NormalArc::new(nlo, nhi, hint, self.step);
                if self.seamed.contains(&key) {
                    // Rung 1 of 2 is the arc's midpoint.
                    arc.segments = arc.segments.max(2);
                }
                let (uv_lo, uv_hi) = (w.uvs[lo as usize], w.uvs[hi as usize]);
                let seam = uv_lo != uv_hi;
                let mut r = vec![lo];
                let mut push = |w: &mut Work, normal: Vec3, uv: Vec2| {
                    // One record per (position, normal, UV): where a UV seam crosses the
                    // crease, a half-strip on one side of it takes the other side's UV, and
                    // the two ladders then share those rungs by index.
                    let key = (
                        self.pos[lo as usize],
                        normal_bits(normal),
                        uv.to_array().map(f32::to_bits),
                    );
                    let v = *self.records.entry(key).or_insert_with(|| {
                        w.positions.push(w.positions[lo as usize]);
                        w.normals.push(normal);
                        w.uvs.push(uv);
                        w.vertex_origin.push(w.vertex_origin[lo as usize]);
                        self.pos.push(self.pos[lo as usize]);
                        (w.positions.len() - 1) as u32
                    });
                    r.push(v);
                };
                let segments = arc.segments;
                // The seam twins sit on the middle rung (one step short of it for an odd
                // count): on a rung, so that every ladder of the pair of normals has the same
                // normals, twins or not (where a UV seam crosses the crease, the two sides'
                // ladders meet as plain UV seams).
                let twin = seam.then_some(segments / 2);
                for j in 1..segments {
                    let uv = match twin {
                        // Equal UVs.
                        None => uv_lo,
                        Some(t) if j < t => uv_lo,
                        Some(t) if j == t => {
                            push(w, arc.point(j), uv_lo);
                            uv_hi
                        }
                        Some(_) => uv_hi,
                    };
                    push(w, arc.point(j), uv);
                }
                r.push(hi);
                self.made.insert((lo, hi), r.clone());
                r
            }
        };
        if swapped {
            rungs.reverse();
        }
        rungs
    }
}

/// Where a ladder's seam twins are (`Ladders::ladder`): the index of the first of two
/// consecutive records with one normal.
fn seam_twins(w: &Work, ladder: &[u32]) -> Option<usize> {
    ladder
        .windows(2)
        .position(|p| same_normal(w.normals[p[0] as usize], w.normals[p[1] as usize]))
}

/// Close one hard edge with the strip between its two ladders (`strip::zip`): one quad for
/// a narrow edge, the two halves of it where one end is a crease ending, several quads whose
/// normals turn through the outside of a wide edge.
fn insert_strip(w: &mut Work, ladders: &mut Ladders, e: &HardEdge, report: &mut RepairReport) {
    let la = ladders.ladder(w, e.a, e.a2);
    let lb = ladders.ladder(w, e.b, e.b2);
    let group = w.face_group[e.t1];
    let (ta, tb) = (seam_twins(w, &la), seam_twins(w, &lb));
    let triangles = match (ta, tb) {
        (None, None) => strip::zip(&la, &lb),
        (ta, tb) => {
            // A UV seam runs along the strip (`Ladders::ladder`): zip the two halves apart,
            // each ladder split at its seam twins or, without twins there, at its middle rung
            // (which both halves share).
            let halves = |l: &[u32], t: Option<usize>| {
                let (end, start) = t.map_or(((l.len() - 1) / 2, (l.len() - 1) / 2), |t| (t, t + 1));
                (l[..=end].to_vec(), l[start..].to_vec())
            };
            let (a1, a2) = halves(&la, ta);
            let (b1, b2) = halves(&lb, tb);
            let mut t = strip::zip(&a1, &b1);
            t.extend(strip::zip(&a2, &b2));
            t
        }
    };
    let inserted: Vec<u32> = triangles
        .into_iter()
        .filter_map(|tri| push_inserted(w, tri, group))
        .collect();
    report.inserted_triangles += inserted.len();
    // Steps of the normal arc (a seam twin is no step).
    let steps = |l: &[u32], t: Option<usize>| (l.len() - 1 - usize::from(t.is_some())) as u32;
    report.stitched_edges.push(StitchedEdge {
        faces: [w.face_origin[e.t1], w.face_origin[e.t2]],
        vertices: [e.a, e.b, e.a2, e.b2],
        segments: [steps(&la, ta), steps(&lb, tb)],
        inserted,
    });
}

/// Close the loops of zero-length boundary edges left at positions where ≥ 3 copies meet.
///
/// The loop is followed over the copies' NORMALS, not their records: where a UV seam crosses
/// the crease, one normal has several records (seam twins), and the loop passes from one twin
/// to the other across the seam. Two zero-length edges that are each other's reverse by
/// normal (the ladders of a crease crossing a UV seam, one on each side of it) are already
/// closed up to the seam and drop out. A loop of k ≥ 3 normals is filled by a fan over one
/// record per normal (the tail of its outgoing edge, `fan`); where that record differs from a
/// twin the fan's edge is again a UV seam edge.
fn close_corners(
    w: &mut Work,
    quant: &Quantizer,
    first_inserted_vertex: usize,
    report: &mut RepairReport,
) {
    let pos: Vec<PosKey> = w.positions.iter().map(|&p| quant.position_key(p)).collect();
    let mut groups: HashMap<PosKey, Vec<(u32, u32)>> = HashMap::new();
    for (_, a, b) in boundary_half_edges(&w.triangles) {
        if pos[a as usize] == pos[b as usize] {
            groups.entry(pos[a as usize]).or_default().push((a, b));
        }
    }
    let mut keys: Vec<PosKey> = groups.keys().copied().collect();
    keys.sort_unstable();
    let original_faces = w.triangles.len();
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
        let classed: Vec<(u32, u32, u32)> = edges
            .iter()
            .map(|&(a, b)| (class(a), class(b), a))
            .collect();
        // Drop edge pairs that are each other's reverse by class (closed up to a UV seam).
        let mut cancelled = vec![false; classed.len()];
        for i in 0..classed.len() {
            if cancelled[i] {
                continue;
            }
            let (ca, cb, _) = classed[i];
            if let Some(j) = (i + 1..classed.len())
                .find(|&j| !cancelled[j] && classed[j].0 == cb && classed[j].1 == ca)
            {
                cancelled[i] = true;
                cancelled[j] = true;
            }
        }
        // Class → (next class, tail record).
        let mut next: HashMap<u32, (u32, u32)> = HashMap::new();
        let mut ambiguous = false;
        for (i, &(ca, cb, a)) in classed.iter().enumerate() {
            if !cancelled[i] {
                ambiguous |= ca == cb || next.insert(ca, (cb, a)).is_some();
            }
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
                let laddered = tails.iter().any(|&v| v as usize >= first_inserted_vertex);
                fan(w, &pos, &tails, laddered, original_faces, report);
            } else if !closed {
                open = true;
            }
        }
        if open {
            report.unclosed_corners += 1;
        }
    }
}

/// A fan from the loop's first vertex is kept (a cube corner: one triangle) only if its
/// triangles' normals are this well spread: the bake's lower bound `min n_i·ĉ` of `|m|`.
const FAN_MIN_M_LO: f32 = 0.5;

/// The bake's lower bound of `|Σ b_i n_i|` over a triangle with normals `n` (no floor).
fn normal_spread(n: [Vec3; 3]) -> f32 {
    let c = (n[0] + n[1] + n[2]).normalize_or_zero();
    n.iter().map(|ni| ni.dot(c)).fold(f32::INFINITY, f32::min)
}

/// Fill the boundary loop `u0→u1→…→u(k−1)→u0`: with triangles `(u0, u(i+1), u(i))` where that
/// keeps every triangle's normals well spread (`FAN_MIN_M_LO`) and the loop has no ladder
/// vertices (three of those lie on one great circle: a flat prism); otherwise with a centre
/// vertex `c` and triangles `(c, u(i+1), u(i))`. `c`'s normal is the loop's mean normal, or
/// where the normals nearly cancel (a sharp apex) the direction away from the faces at the
/// corner; its UV is the loop's mean UV.
fn fan(
    w: &mut Work,
    pos: &[PosKey],
    cycle: &[u32],
    laddered: bool,
    original_faces: usize,
    report: &mut RepairReport,
) {
    let group = w
        .triangles
        .iter()
        .position(|tri| tri.contains(&cycle[0]))
        .map_or(0, |t| w.face_group[t]);
    let k = cycle.len();
    let nrm = |i: u32| w.normals[i as usize];
    let from_first = !laddered
        && (1..k - 1).all(|i| {
            normal_spread([nrm(cycle[0]), nrm(cycle[i + 1]), nrm(cycle[i])]) >= FAN_MIN_M_LO
        });
    let mut inserted = Vec::new();
    let mut centre = None;
    if from_first {
        for i in 1..k - 1 {
            if let Some(t) = push_inserted(w, [cycle[0], cycle[i + 1], cycle[i]], group) {
                inserted.push(t);
            }
        }
    } else {
        let c = push_centre(w, pos, cycle, original_faces);
        centre = Some(c);
        for i in 0..k {
            if let Some(t) = push_inserted(w, [c, cycle[(i + 1) % k], cycle[i]], group) {
                inserted.push(t);
            }
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
        centre,
        inserted,
        against_normals: area.dot(mean_normal) < 0.0,
    });
}

/// The centre vertex of a corner fan over `cycle` (all at one position).
fn push_centre(w: &mut Work, pos: &[PosKey], cycle: &[u32], original_faces: usize) -> u32 {
    let v0 = cycle[0] as usize;
    let p = w.positions[v0];
    let sum: Vec3 = cycle.iter().map(|&i| w.normals[i as usize]).sum();
    let normal = if sum.length() >= 0.25 * cycle.len() as f32 {
        sum.normalize()
    } else {
        // Away from the faces: minus the sum of their corner bisectors at p (a convex corner).
        let mut away = Vec3::ZERO;
        for t in 0..original_faces {
            if w.is_inserted(t) {
                continue;
            }
            let tri = w.triangles[t];
            let q = tri.map(|i| w.positions[i as usize]);
            for k in 0..3 {
                if pos[tri[k] as usize] == pos[v0] {
                    let e1 = (q[(k + 1) % 3] - q[k]).normalize_or_zero();
                    let e2 = (q[(k + 2) % 3] - q[k]).normalize_or_zero();
                    away -= (e1 + e2).normalize_or_zero();
                }
            }
        }
        away.try_normalize()
            .or_else(|| sum.try_normalize())
            .unwrap_or(w.normals[v0])
    };
    let uv = cycle.iter().map(|&i| w.uvs[i as usize]).sum::<glam::Vec2>() / cycle.len() as f32;
    w.positions.push(p);
    w.normals.push(normal);
    w.uvs.push(uv);
    w.vertex_origin.push(w.vertex_origin[v0]);
    (w.positions.len() - 1) as u32
}
