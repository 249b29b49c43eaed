//! Repair, specified by small procedural meshes. Each test says what would break.

use super::*;
use crate::mesh::{FACE_INSERTED, FACE_UV_DEGENERATE};
use glam::{Vec2, Vec3};
use std::collections::HashMap;

use crate::test_util::fixture_mesh as mesh;

/// Unit quad in z = 0 as two triangles, normals +z, sharing vertices 0 and 2.
fn quad() -> BaseMesh {
    let p = vec![
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ];
    let uv = p.iter().map(|q| q.truncate()).collect();
    mesh(p, vec![Vec3::Z; 4], uv, vec![[0, 1, 2], [0, 2, 3]])
}

/// Cube [-1,1]³ with per-face normals and UVs: 24 vertices, every edge a hard edge in the file.
fn split_normal_cube() -> BaseMesh {
    let faces = [
        (Vec3::X, Vec3::Y, Vec3::Z),
        (Vec3::NEG_X, Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::Z, Vec3::X),
        (Vec3::NEG_Y, Vec3::X, Vec3::Z),
        (Vec3::Z, Vec3::X, Vec3::Y),
        (Vec3::NEG_Z, Vec3::Y, Vec3::X),
    ];
    let (mut p, mut n, mut uv, mut tris) = (vec![], vec![], vec![], vec![]);
    for (nf, u, v) in faces {
        assert_eq!(u.cross(v), nf);
        let base = p.len() as u32;
        for (s, t) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            p.push(nf + u * s + v * t);
            n.push(nf);
            uv.push(Vec2::new(0.5 + 0.5 * s, 0.5 + 0.5 * t));
        }
        tris.push([base, base + 1, base + 2]);
        tris.push([base, base + 2, base + 3]);
    }
    mesh(p, n, uv, tris)
}

/// Double cone ("lens") around z: rim of `rim` vertices at radius 1, apexes at ±h, smooth
/// angle-weighted normals shared across the rim. Interior angle at the rim ≈ 2 atan(h).
fn lens(rim: u32, h: f32) -> BaseMesh {
    let mut p: Vec<Vec3> = (0..rim)
        .map(|i| {
            let a = std::f32::consts::TAU * i as f32 / rim as f32;
            Vec3::new(a.cos(), a.sin(), 0.0)
        })
        .collect();
    p.push(Vec3::new(0.0, 0.0, h));
    p.push(Vec3::new(0.0, 0.0, -h));
    let (top, bot) = (rim, rim + 1);
    let mut tris = vec![];
    for i in 0..rim {
        let j = (i + 1) % rim;
        tris.push([top, i, j]);
        tris.push([bot, j, i]);
    }
    let n = BaseMesh::angle_weighted_normals(&p, &tris);
    let uv = p
        .iter()
        .map(|q| Vec2::new(0.5 + 0.4 * q.x, 0.5 + 0.4 * q.y + 0.1 * q.z))
        .collect();
    mesh(p, n, uv, tris)
}

/// Icosphere (unit radius, `levels` subdivisions), smooth normals, a generic linear UV
/// projection (no face is edge-on to it). Vertices are shared: no seams.
fn icosphere(levels: u32) -> BaseMesh {
    let phi = (1.0 + 5f32.sqrt()) / 2.0;
    let mut p: Vec<Vec3> = [
        (-1.0, phi, 0.0),
        (1.0, phi, 0.0),
        (-1.0, -phi, 0.0),
        (1.0, -phi, 0.0),
        (0.0, -1.0, phi),
        (0.0, 1.0, phi),
        (0.0, -1.0, -phi),
        (0.0, 1.0, -phi),
        (phi, 0.0, -1.0),
        (phi, 0.0, 1.0),
        (-phi, 0.0, -1.0),
        (-phi, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = vec![];
        for [a, b, c] in tris {
            let mut m = |x: u32, y: u32| {
                *mid.entry((x.min(y), x.max(y))).or_insert_with(|| {
                    p.push(((p[x as usize] + p[y as usize]) * 0.5).normalize());
                    (p.len() - 1) as u32
                })
            };
            let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    let uv = p
        .iter()
        .map(|q| {
            Vec2::new(
                0.5 + 0.31 * q.x + 0.13 * q.y + 0.07 * q.z,
                0.5 - 0.05 * q.x + 0.29 * q.y + 0.17 * q.z,
            )
        })
        .collect();
    mesh(p.clone(), p, uv, tris)
}

/// UV sphere with the usual seam column (u = 0 and u = 1 duplicated) and one pole vertex per
/// segment: UV seams, smooth normals, nothing to repair.
fn uv_sphere(segments: u32, rings: u32) -> BaseMesh {
    let (mut p, mut uv) = (vec![], vec![]);
    let at = |r: u32, s: u32| {
        let th = std::f32::consts::PI * r as f32 / rings as f32;
        let ph = std::f32::consts::TAU * s as f32 / segments as f32;
        Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos())
    };
    for r in 1..rings {
        for s in 0..=segments {
            p.push(at(r, s % segments));
            uv.push(Vec2::new(
                s as f32 / segments as f32,
                1.0 - r as f32 / rings as f32,
            ));
        }
    }
    let ring = |r: u32, s: u32| (r - 1) * (segments + 1) + s;
    let mut tris = vec![];
    for r in 1..rings - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (
                ring(r, s),
                ring(r, s + 1),
                ring(r + 1, s + 1),
                ring(r + 1, s),
            );
            tris.push([a, d, c]);
            tris.push([a, c, b]);
        }
    }
    for s in 0..segments {
        let u = (s as f32 + 0.5) / segments as f32;
        let north = p.len() as u32;
        p.push(Vec3::Z);
        uv.push(Vec2::new(u, 1.0));
        tris.push([north, ring(1, s), ring(1, s + 1)]);
        let south = p.len() as u32;
        p.push(Vec3::NEG_Z);
        uv.push(Vec2::new(u, 0.0));
        tris.push([south, ring(rings - 1, s + 1), ring(rings - 1, s)]);
    }
    mesh(p.clone(), p, uv, tris)
}

/// Every directed edge appears once and its reverse once: closed and consistently oriented.
/// Returns the number of directed edges without a reverse partner (0 when closed).
fn open_half_edges(m: &BaseMesh) -> usize {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    for tri in &m.triangles {
        for k in 0..3 {
            *directed.entry((tri[k], tri[(k + 1) % 3])).or_default() += 1;
        }
    }
    assert!(
        directed.values().all(|&c| c == 1),
        "an edge is used twice in the same direction"
    );
    directed
        .keys()
        .filter(|&&(a, b)| !directed.contains_key(&(b, a)))
        .count()
}

/// Canonical displaced point on the edge a→b of a mesh at parameter s, constant displacement.
fn displaced_on_edge(m: &BaseMesh, a: u32, b: u32, s: f32, d: f32) -> Vec3 {
    let (a, b) = (a as usize, b as usize);
    let p = m.positions[a].lerp(m.positions[b], s);
    let n = m.normals[a].lerp(m.normals[b], s).normalize();
    p + n * d
}

/// Largest gap of the displaced surface `V + d·n` across edges: each directed edge a→b is
/// compared with the best reversed edge at the same positions (by index first, else by
/// position); an edge without any partner counts as infinite.
fn max_displaced_gap(m: &BaseMesh, d: f32) -> f32 {
    let key = |v: u32| m.positions[v as usize].to_array().map(f32::to_bits);
    let mut by_pos: HashMap<_, Vec<(u32, u32)>> = HashMap::new();
    for tri in &m.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            by_pos.entry((key(a), key(b))).or_default().push((a, b));
        }
    }
    let mut worst = 0.0f32;
    for tri in &m.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let best = by_pos
                .get(&(key(b), key(a)))
                .into_iter()
                .flatten()
                .map(|&(b2, a2)| {
                    (0..=8)
                        .map(|i| {
                            let s = i as f32 / 8.0;
                            (displaced_on_edge(m, a, b, s, d) - displaced_on_edge(m, a2, b2, s, d))
                                .length()
                        })
                        .fold(0.0, f32::max)
                })
                .fold(f32::INFINITY, f32::min);
            worst = worst.max(best);
        }
    }
    worst
}

fn assert_sized(m: &BaseMesh) {
    assert_eq!(m.normals.len(), m.positions.len());
    assert_eq!(m.uvs.len(), m.positions.len());
    assert_eq!(m.face_group.len(), m.triangles.len());
    assert_eq!(m.face_flags.len(), m.triangles.len());
    let used: std::collections::HashSet<u32> = m.triangles.iter().flatten().copied().collect();
    assert_eq!(
        used.len(),
        m.positions.len(),
        "vertex arrays are not compact"
    );
}

/// Smallest accepted spread of an inserted triangle's normals: the bake's lower bound
/// `min n_i·ĉ` of `|Σ b_i n_i|` over the triangle. `m(b)` then never comes near zero (no
/// folded prism) and the λ range is at most `|D| / MIN_SPREAD`. A 90° edge's single quad
/// (two normals of one side, one of the other) has `1/√5 = 0.447`; strip triangles, whose
/// normals are at most 60° apart, 0.75.
const MIN_SPREAD: f32 = 0.44;

/// Every inserted triangle of `m` has well-spread normals (`MIN_SPREAD`), and baked over a
/// map with `|D| ≤ d` its prism is not flagged `PRISM_DEGENERATE_NORMALS` and has
/// `|λ| ≤ d / MIN_SPREAD`. Returns the smallest spread (1 if nothing was inserted).
fn assert_inserted_prisms_sane(m: &BaseMesh, d: f32) -> f32 {
    use crate::bake::{bake_prism, PRISM_DEGENERATE_NORMALS, PRISM_INSERTED};
    use crate::heightmap::{DisplaceParams, HeightMap, Wrap};
    let map = HeightMap::new(2, 2, vec![0.0, 1.0, 0.3, 0.8], Wrap::Repeat);
    let params = DisplaceParams {
        scale: 2.0 * d,
        midlevel: 0.5,
    };
    let mut worst = 1.0f32;
    for t in 0..m.triangles.len() {
        if m.face_flags[t] & FACE_INSERTED == 0 {
            continue;
        }
        let n = m.corner_normals(t);
        let c = (n[0] + n[1] + n[2]).normalize_or_zero();
        let spread = n.iter().map(|ni| ni.dot(c)).fold(f32::INFINITY, f32::min);
        assert!(
            spread >= MIN_SPREAD,
            "inserted face {t}: normals {n:?} nearly cancel (spread {spread})"
        );
        worst = worst.min(spread);
        let p = bake_prism(m, &map, &params, t);
        assert_ne!(p.flags & PRISM_INSERTED, 0);
        assert_eq!(p.flags & PRISM_DEGENERATE_NORMALS, 0, "face {t}: {p:?}");
        let bound = d / MIN_SPREAD * 1.001;
        assert!(
            p.lambda_lo >= -bound && p.lambda_hi <= bound,
            "face {t}: λ range {p:?} beyond ±{bound}"
        );
    }
    worst
}

// Would break if the weld key ignored an attribute or triangles were not remapped.
#[test]
fn weld_merges_duplicated_quad_vertices() {
    let q = quad();
    let p = vec![0, 1, 2, 0, 2, 3]
        .into_iter()
        .map(|i| q.positions[i])
        .collect::<Vec<_>>();
    let uv = p.iter().map(|v: &Vec3| v.truncate()).collect();
    let dup = mesh(p, vec![Vec3::Z; 6], uv, vec![[0, 1, 2], [3, 4, 5]]);
    let (out, rep) = repair(dup, &RepairOptions::default());
    assert_eq!(rep.welded_vertices, 2);
    assert_eq!(out.positions.len(), 4);
    assert_eq!(out.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert!(rep.is_clean(), "{}", rep.to_text());
    assert_sized(&out);

    // A UV difference keeps vertices apart (weld must not eat UV seams).
    let q2 = {
        let mut m = mesh(
            out.positions.clone(),
            out.normals.clone(),
            out.uvs.clone(),
            out.triangles.clone(),
        );
        m.positions.push(m.positions[0]);
        m.normals.push(Vec3::Z);
        m.uvs.push(Vec2::new(0.5, 0.5));
        m.triangles[1][0] = 4;
        m
    };
    let (out2, rep2) = repair(q2, &RepairOptions::default());
    assert_eq!((rep2.welded_vertices, out2.positions.len()), (0, 5));
}

/// A quad written with a normal per face corner, the copies of its shared corners differing by
/// 1e-5 (an exporter's noise): the normals are made one, the copies weld, and nothing is
/// stitched; copies 0.01 apart (a real, if slight, hard edge) stay apart and are stitched.
#[test]
fn normals_within_the_snap_are_one_normal_and_others_stay_hard() {
    let q = quad();
    let p: Vec<Vec3> = [0, 1, 2, 0, 2, 3].iter().map(|&i| q.positions[i]).collect();
    let uv: Vec<Vec2> = p.iter().map(|v| v.truncate()).collect();
    let tilted = |d: f32| {
        let n = |k: usize| match k {
            3..=5 => (Vec3::Z + Vec3::new(d, -d, 0.0)).normalize(),
            _ => Vec3::Z,
        };
        mesh(
            p.clone(),
            (0..6).map(n).collect(),
            uv.clone(),
            vec![[0, 1, 2], [3, 4, 5]],
        )
    };
    let (out, rep) = repair(tilted(1e-5), &RepairOptions::default());
    assert_eq!(
        (rep.unified_normals, rep.welded_vertices),
        (4, 2),
        "{}",
        rep.to_text()
    );
    assert_eq!(out.positions.len(), 4);
    assert_eq!(rep.inserted_triangles, 0, "{}", rep.to_text());
    let (_, rep) = repair(tilted(1e-2), &RepairOptions::default());
    assert_eq!((rep.unified_normals, rep.welded_vertices), (0, 0));
    assert!(rep.inserted_triangles > 0, "{}", rep.to_text());
}

// Would break if degenerate faces reached the bake (NaN face normals, zero texel sizes).
#[test]
fn zero_area_and_repeated_index_faces_are_dropped_and_listed() {
    let mut m = quad();
    m.positions
        .extend([Vec3::new(2.0, 0.0, 0.0), Vec3::new(3.0, 0.0, 0.0)]);
    m.normals.extend([Vec3::Z; 2]);
    m.uvs.extend([Vec2::new(0.2, 0.7), Vec2::new(0.9, 0.1)]);
    // Face 2: collinear corners; face 3: repeated index.
    m.triangles.extend([[1, 4, 5], [0, 1, 1]]);
    m.face_group.extend([0, 0]);
    m.face_flags.extend([0, 0]);
    let (out, rep) = repair(m, &RepairOptions::default());
    assert_eq!(rep.zero_area_faces, vec![2, 3]);
    assert_eq!(out.triangles.len(), 2);
    assert_eq!(rep.unreferenced_vertices, 2);
    assert!(!rep.is_clean());
    assert_sized(&out);
}

// Would break if UV-degenerate faces were dropped (they are real geometry) or not flagged
// (bake divides by their UV area).
#[test]
fn uv_degenerate_face_is_flagged_and_kept() {
    let mut m = quad();
    m.uvs[3] = m.uvs[0].lerp(m.uvs[2], 0.25); // face 1's UVs become collinear
    let (out, rep) = repair(m, &RepairOptions::default());
    assert_eq!(rep.uv_degenerate_faces, vec![1]);
    assert_eq!(out.face_flags, vec![0, FACE_UV_DEGENERATE]);
    assert_eq!(out.triangles.len(), 2);
}

// Would break if a flipped normal went unreported: its prism extrudes into the surface.
#[test]
fn inverted_corner_is_reported_and_left_unresolved() {
    let mut m = quad();
    m.normals[3] = Vec3::NEG_Z;
    let (out, rep) = repair(m, &RepairOptions::default());
    let c = CornerFinding {
        face: 1,
        corner: 2,
        vertex: 3,
        dot: -1.0,
    };
    assert_eq!(rep.inverted_corners, vec![c]);
    assert_eq!(rep.sharp_corners, vec![c]);
    // No crease edge ends there (a flat quad), so there is nothing to split: unresolved.
    assert!(rep.crease_edges.is_empty());
    assert_eq!(rep.unresolved_crease_corners, vec![c]);
    assert_eq!(out.normals[3], Vec3::NEG_Z);
    assert!(rep.to_text().contains("face 1 corner 2 (vertex 3)"));
}

// Would break if repair changed clean meshes (every asset would be rewritten and re-baked).
#[test]
fn smooth_spheres_need_no_changes() {
    for m in [icosphere(2), uv_sphere(16, 8)] {
        let before = m.clone();
        let (out, rep) = repair(m, &RepairOptions::default());
        assert!(rep.is_clean(), "{}", rep.to_text());
        assert_eq!(rep.welded_vertices, 0);
        assert_eq!(out.positions, before.positions);
        assert_eq!(out.normals, before.normals);
        assert_eq!(out.uvs, before.uvs);
        assert_eq!(out.triangles, before.triangles);
        assert_eq!(out.face_flags, before.face_flags);
    }
    let (ico, _) = repair(icosphere(2), &RepairOptions::default());
    assert_eq!(open_half_edges(&ico), 0);
    // The UV sphere's seam column and pole fans are UV seams: counted, left open.
    let (_, rep) = repair(uv_sphere(16, 8), &RepairOptions::default());
    assert_eq!(rep.uv_seam_edges, (8 - 2) + 16 * 2);
    assert_eq!(rep.open_boundary_edges, 2 * rep.uv_seam_edges);
}

// Would break if stitching were dropped or mis-oriented: the displaced cube tears open along
// every edge by D·√2 and at every corner.
#[test]
fn split_normal_cube_is_closed_by_stitching() {
    const D: f32 = 0.1;
    let cube = split_normal_cube();
    assert!(
        max_displaced_gap(&cube, D) > 0.05,
        "the input's hard edges tear when displaced"
    );
    let (out, rep) = repair(cube, &RepairOptions::default());
    assert_sized(&out);
    assert!(rep.sharp_corners.is_empty() && rep.split_vertices.is_empty());
    assert_eq!(rep.stitched_edges.len(), 12);
    assert_eq!(rep.corner_fans.len(), 8);
    assert!(rep.corner_fans.iter().all(|f| !f.against_normals));
    // Every edge is also a UV seam (per-face UVs) except at the ends where the two faces'
    // UVs happen to match: there a 90° edge keeps one step, elsewhere it turns in two 45°
    // steps with seam twins on the middle rung (`Ladders::ladder`), and the halves of the
    // strip meet at a UV seam. The corners whose loops pass through those rungs are fanned
    // around a centre vertex.
    assert!(rep
        .stitched_edges
        .iter()
        .all(|e| e.segments.iter().all(|&s| s == 1 || s == 2)));
    assert!(rep.stitched_edges.iter().any(|e| e.segments == [2, 2]));
    assert_eq!(rep.inserted_triangles, 80);
    assert_eq!(out.triangles.len(), 12 + 80);
    assert_eq!(
        out.face_flags
            .iter()
            .filter(|&&f| f == FACE_INSERTED)
            .count(),
        80
    );
    assert_eq!(rep.open_boundary_edges, 2 * out.seams.len());
    assert_eq!(out.seams.len(), 30);
    assert_eq!(
        open_edges_not_seams(&out),
        vec![],
        "every edge shared by exactly two faces, or a UV seam edge with a twin"
    );
    assert_no_uv_jump_at_one_position(&out, &rep);
    assert_eq!(max_displaced_gap(&out, D), 0.0);
    assert_inserted_prisms_sane(&out, D);
    // Each corner fan, displaced, faces the way its copies' normals point.
    for fan in &rep.corner_fans {
        let t = out.triangles[fan.inserted[0] as usize];
        let q = t.map(|i| out.positions[i as usize] + out.normals[i as usize] * D);
        let n: Vec3 = t.iter().map(|&i| out.normals[i as usize]).sum();
        assert!((q[1] - q[0]).cross(q[2] - q[0]).dot(n) > 0.0);
    }
    // Idempotent: the repaired cube needs nothing more.
    let (again, rep2) = repair(out.clone(), &RepairOptions::default());
    assert!(rep2.is_clean(), "{}", rep2.to_text());
    assert_eq!(again.triangles, out.triangles);
}

// Would break if knife edges were not split (PDM's 1/(n·N_g) blows up) or the split left the
// two sides of the rim apart.
#[test]
fn knife_edge_lens_is_split_and_stitched_closed() {
    const D: f32 = 0.1;
    let rim = 12;
    let m = lens(rim, 0.02); // interior rim angle ≈ 2.3° < 5°
    assert_eq!(
        open_half_edges(&m),
        0,
        "the input itself is closed (smooth normals)"
    );
    let (out, rep) = repair(m, &RepairOptions::default());
    assert_sized(&out);
    assert_eq!(
        rep.sharp_corners.len(),
        4 * rim as usize,
        "both rim corners of every face"
    );
    assert_eq!(rep.crease_edges.len(), rim as usize);
    assert_eq!(rep.split_vertices.len(), rim as usize);
    assert!(rep.split_vertices.iter().all(|s| s.copies.len() == 2));
    assert!(
        rep.unresolved_crease_corners.is_empty(),
        "{}",
        rep.to_text()
    );
    assert_eq!(rep.stitched_edges.len(), rim as usize);
    assert!(
        rep.corner_fans.is_empty(),
        "only two copies meet at each rim point"
    );
    // The rim's sides are ~178° apart: a strip of three quads per edge, the normal turning
    // in 60° steps through two inserted copies per rim vertex.
    assert!(rep.stitched_edges.iter().all(|e| e.segments == [3, 3]));
    assert_eq!(rep.inserted_triangles, 6 * rim as usize);
    assert_eq!(rep.inserted_vertices, 2 * rim as usize);
    assert_eq!(out.positions.len(), 4 * rim as usize + 2);
    assert_eq!(open_half_edges(&out), 0);
    assert_eq!(max_displaced_gap(&out, D), 0.0);
    assert!(assert_inserted_prisms_sane(&out, D) > 0.7);
    // The strip rounds the rim through the outside: every inserted normal points outwards
    // (it would fold through the fin if it turned the other way).
    for v in out.positions.len() - rep.inserted_vertices..out.positions.len() {
        let radial = out.positions[v].normalize();
        assert!(
            out.normals[v].dot(radial) > 0.8,
            "vertex {v}: {}",
            out.normals[v]
        );
    }
    // Every original corner now sees its own side's normal.
    for t in 0..out.triangles.len() {
        if out.face_flags[t] & FACE_INSERTED == 0 {
            let ng = out.face_cross(t).normalize();
            assert!(out.corner_normals(t).iter().all(|n| n.dot(ng) > 0.9));
        }
    }
}

// Would break if someone "simplified" repair to split-only: the lens opens along its rim.
#[test]
fn edge_split_without_stitching_leaves_the_surface_open() {
    const D: f32 = 0.1;
    let opts = RepairOptions {
        stitch_hard_edges: false,
        ..Default::default()
    };
    let (out, rep) = repair(lens(12, 0.02), &opts);
    assert_eq!(rep.split_vertices.len(), 12);
    assert_eq!(rep.unstitched_hard_edges, 12);
    assert_eq!(rep.open_boundary_edges, 24);
    assert!(open_half_edges(&out) > 0);
    assert!(
        max_displaced_gap(&out, D) > 0.05,
        "rim copies separate by ≈ 2D"
    );
    assert!(!rep.is_clean());
}

// Would break without the 60° rule: a rim of 20° (not a crease by angle) whose smooth normal
// lies in the top face's plane is just as singular for PDM.
#[test]
fn bad_smooth_normal_on_a_moderate_rim_is_split() {
    let h = 10f32.to_radians().tan();
    let (_, clean) = repair(lens(12, h), &RepairOptions::default());
    assert!(
        clean.is_clean(),
        "good normals on a 20° rim are fine: {}",
        clean.to_text()
    );
    let mut m = lens(12, h);
    for i in 0..12 {
        let radial = m.positions[i].normalize();
        m.normals[i] = (radial - Vec3::Z * (1.3 * h)).normalize(); // below the top face's plane
    }
    let (out, rep) = repair(m, &RepairOptions::default());
    assert!(!rep.inverted_corners.is_empty());
    assert_eq!(rep.crease_edges.len(), 12);
    assert!(
        rep.unresolved_crease_corners.is_empty(),
        "{}",
        rep.to_text()
    );
    assert_eq!(open_half_edges(&out), 0);
    // The split rim's sides are 160° apart: strips, not single quads.
    assert!(rep.stitched_edges.iter().all(|e| e.segments == [3, 3]));
    assert_inserted_prisms_sane(&out, 0.1);
}

// Would break if the report stopped being valid JSON for the CLI and the Blender add-on.
#[test]
fn report_serialises_to_json() {
    let mut cube = split_normal_cube();
    cube.normals[0] = -cube.normals[0];
    let (_, rep) = repair(cube, &RepairOptions::default());
    let text = serde_json::to_string(&rep).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(
        v["stitched_edges"].as_array().unwrap().len(),
        rep.stitched_edges.len()
    );
    assert_eq!(v["inverted_corners"][0]["vertex"], 0);
    assert_eq!(v, serde_json::to_value(&rep).unwrap());
    assert!(rep.to_text().contains("hard edges stitched"));
}

/// Closed cylinder: smooth shared side normals, flat caps with their own rim copies (hard
/// edges in the file), `seg` segments, radius 1, z in [−1, 1].
fn capped_cylinder(seg: u32) -> BaseMesh {
    let (mut p, mut n, mut uv, mut tris) = (vec![], vec![], vec![], vec![]);
    let ring = |i: u32, z: f32| {
        let a = std::f32::consts::TAU * i as f32 / seg as f32;
        Vec3::new(a.cos(), a.sin(), z)
    };
    for z in [-1.0, 1.0] {
        for i in 0..seg {
            let q = ring(i, z);
            p.push(q);
            n.push(Vec3::new(q.x, q.y, 0.0));
            uv.push(Vec2::new(0.5 + 0.2 * q.x, 0.3 + 0.2 * q.y + 0.1 * z));
        }
    }
    for i in 0..seg {
        let j = (i + 1) % seg;
        tris.push([i, j, seg + j]);
        tris.push([i, seg + j, seg + i]);
    }
    for (z, flip) in [(-1.0f32, true), (1.0, false)] {
        let c = p.len() as u32;
        p.push(Vec3::new(0.0, 0.0, z));
        n.push(Vec3::Z * z);
        uv.push(Vec2::new(0.5, 0.5 + 0.4 * z));
        for i in 0..seg {
            let q = ring(i, z);
            p.push(q);
            n.push(Vec3::Z * z);
            uv.push(Vec2::new(0.5 + 0.2 * q.x, 0.5 + 0.4 * z + 0.1 * q.y));
        }
        for i in 0..seg {
            let (a, b) = (c + 1 + i, c + 1 + (i + 1) % seg);
            tris.push(if flip { [c, b, a] } else { [c, a, b] });
        }
    }
    mesh(p, n, uv, tris)
}

// Would break if stitching only handled all-hard meshes: a cylinder mixes smooth sides with
// hard cap rims, the usual case in real assets.
#[test]
fn cylinder_cap_rims_are_stitched_closed() {
    let seg = 10;
    let m = capped_cylinder(seg);
    assert!(max_displaced_gap(&m, 0.1) > 0.05);
    let (out, rep) = repair(m, &RepairOptions::default());
    assert!(rep.sharp_corners.is_empty() && rep.split_vertices.is_empty());
    assert_eq!(rep.stitched_edges.len(), 2 * seg as usize);
    assert!(rep.corner_fans.is_empty() && rep.unclosed_corners == 0);
    // The caps' UVs are not the sides': each 90° rim edge turns in two 45° steps with seam
    // twins on the middle rung, and the strip's halves meet at a UV seam.
    assert_eq!(out.seams.len(), 2 * seg as usize);
    assert_eq!(open_edges_not_seams(&out), vec![]);
    assert_no_uv_jump_at_one_position(&out, &rep);
    assert_eq!(max_displaced_gap(&out, 0.1), 0.0);
    assert!(rep.stitched_edges.iter().all(|e| e.segments == [2, 2]));
    assert_inserted_prisms_sane(&out, 0.1);
}

// Would break if a crease that ends inside the mesh (its end vertex keeps one copy) left a
// crack: the edge next to the end is closed by a single triangle (the quad's other half would
// repeat the shared end vertex).
#[test]
fn crease_ending_inside_the_mesh_is_closed_with_single_triangles() {
    let mut m = lens(24, 0.05);
    let (top, bot) = (24, 25);
    // Move both apexes next to the rim at x = −1: the rim is blunt there and a knife edge
    // (≈ 3° interior angle) on the far side, so the crease runs along part of the rim only.
    m.positions[top] = Vec3::new(-0.9, 0.0, 0.05);
    m.positions[bot] = Vec3::new(-0.9, 0.0, -0.05);
    m.normals = BaseMesh::angle_weighted_normals(&m.positions, &m.triangles);
    let (out, rep) = repair(m, &RepairOptions::default());
    assert!(!rep.crease_edges.is_empty() && rep.crease_edges.len() < 24);
    assert!(!rep.split_vertices.is_empty());
    // At the crease's end the normals agree: the strip is a fan of its other end's steps.
    assert!(
        rep.stitched_edges.iter().any(|e| e.segments.contains(&0)
            && e.inserted.len() == e.segments[0].max(e.segments[1]) as usize),
        "{}",
        rep.to_text()
    );
    assert_eq!(open_half_edges(&out), 0, "{}", rep.to_text());
    assert_eq!(max_displaced_gap(&out, 0.1), 0.0);
    assert_inserted_prisms_sane(&out, 0.1);
}

/// Directed edges a→b with no reverse b→a (by vertex index) that are NOT a UV seam: a seam
/// edge has a reversed twin b'→a' at the same positions with the same normals and different
/// UVs. Returns the offending edges (empty when the mesh is closed up to UV seams).
/// No inserted strip triangle carries two UVs at one position: a strip does not squeeze the
/// atlas between two UV islands into its rounded edge (corner fans excepted: a centre takes
/// the mean UV of its loop).
fn assert_no_uv_jump_at_one_position(m: &BaseMesh, rep: &RepairReport) {
    let fans: Vec<u32> = rep
        .corner_fans
        .iter()
        .flat_map(|f| f.inserted.iter().copied())
        .collect();
    for t in 0..m.triangles.len() {
        if m.face_flags[t] & FACE_INSERTED == 0 || fans.contains(&(t as u32)) {
            continue;
        }
        let tri = m.triangles[t];
        for (i, j) in [(0, 1), (1, 2), (2, 0)] {
            let (a, b) = (tri[i] as usize, tri[j] as usize);
            if m.positions[a] == m.positions[b] {
                assert_eq!(m.uvs[a], m.uvs[b], "inserted triangle {t}: {tri:?}");
            }
        }
    }
}

fn open_edges_not_seams(m: &BaseMesh) -> Vec<(u32, u32)> {
    let key = |v: u32| m.positions[v as usize].to_array().map(f32::to_bits);
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    let mut by_pos: HashMap<_, Vec<(u32, u32)>> = HashMap::new();
    for tri in &m.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            *directed.entry((a, b)).or_default() += 1;
            by_pos.entry((key(a), key(b))).or_default().push((a, b));
        }
    }
    assert!(
        directed.values().all(|&c| c == 1),
        "an edge is used twice in the same direction"
    );
    let (n, uv) = (|v: u32| m.normals[v as usize], |v: u32| m.uvs[v as usize]);
    let mut bad: Vec<(u32, u32)> = directed
        .keys()
        .filter(|&&(a, b)| !directed.contains_key(&(b, a)))
        .filter(|&&(a, b)| {
            let twin = by_pos
                .get(&(key(b), key(a)))
                .into_iter()
                .flatten()
                .any(|&(b2, a2)| {
                    n(a2) == n(a) && n(b2) == n(b) && (uv(a2) != uv(a) || uv(b2) != uv(b))
                });
            !twin
        })
        .copied()
        .collect();
    bad.sort_unstable();
    bad
}

/// The knife-edge lens with its top cap cut into two UV islands: top faces `i ≥ rim/2` use
/// their own copies of the apex and of rim vertices `rim/2..rim` and 0 (same positions and
/// normals, UVs shifted), so half of the rim crease is a UV seam by vertex index, and the
/// seam between the islands crosses the rim at vertices 0 and rim/2.
fn lens_with_split_top_cap(rim: u32, h: f32) -> BaseMesh {
    let mut m = lens(rim, h);
    let mut copy_of: HashMap<u32, u32> = HashMap::new();
    let mut dup = |m: &mut BaseMesh, v: u32| {
        *copy_of.entry(v).or_insert_with(|| {
            m.positions.push(m.positions[v as usize]);
            m.normals.push(m.normals[v as usize]);
            m.uvs.push(m.uvs[v as usize] + Vec2::new(0.37, 0.0));
            (m.positions.len() - 1) as u32
        })
    };
    for i in rim / 2..rim {
        let t = 2 * i as usize; // [top, i, j]
        let tri = m.triangles[t];
        m.triangles[t] = [
            dup(&mut m, tri[0]),
            dup(&mut m, tri[1]),
            dup(&mut m, tri[2]),
        ];
    }
    m
}

// Would break if crease detection went back to edges by vertex index: across a UV seam it
// sees two boundary edges, no crease, and the knife edge's corners stay singular.
#[test]
fn knife_edge_crossing_a_uv_seam_is_split_and_stitched() {
    const D: f32 = 0.1;
    let rim = 12usize;
    let m = lens_with_split_top_cap(rim as u32, 0.02);
    assert!(
        open_half_edges(&m) > 0,
        "the input has seams by vertex index"
    );
    assert!(
        open_edges_not_seams(&m).is_empty(),
        "but is closed up to them"
    );
    let (out, rep) = repair(m, &RepairOptions::default());
    assert_sized(&out);
    assert_eq!(rep.sharp_corners.len(), 4 * rim, "{}", rep.to_text());
    assert_eq!(rep.crease_edges.len(), rim, "the whole rim, seam or not");
    assert!(
        rep.unresolved_crease_corners.is_empty(),
        "{}",
        rep.to_text()
    );
    // Rim records used by both sides are copied; the top island's own copies and the bottom's
    // records on the seam half take their side's normal in place.
    let copied = rep
        .split_vertices
        .iter()
        .filter(|s| s.copies.len() == 2)
        .count();
    let in_place = rep
        .split_vertices
        .iter()
        .filter(|s| s.copies.len() == 1)
        .count();
    assert_eq!(copied, rim / 2 + 1, "{}", rep.to_text());
    assert_eq!(in_place, 2 * (rim / 2 + 1) - 2, "{}", rep.to_text());
    assert_eq!(rep.stitched_edges.len(), rim);
    assert_eq!(rep.unclosed_corners, 0, "{}", rep.to_text());
    assert!(rep.corner_fans.is_empty());
    // The cap seam's two edges stay plain UV seams (their twins keep equal normals). Along the
    // rim's half where the top and bottom records differ in UV, each strip is split into a
    // top half and a bottom half that meet at a seam (the twins on its middle rung): 6. Where
    // the cap seam crosses the rim, the two top islands' ladders meet at a zero-length seam
    // edge where their rungs differ in UV: the ladders share the rungs past the twins (the
    // same normal and UV, one record), so 1 of the 3 steps differs at each crossing.
    assert_eq!(rep.uv_seam_edges, 2 + 6 + 2, "{}", rep.to_text());
    assert_no_uv_jump_at_one_position(&out, &rep);
    assert_eq!(out.seams.len(), rep.uv_seam_edges);
    assert_eq!(rep.open_boundary_edges, 2 * rep.uv_seam_edges);
    assert_eq!(open_edges_not_seams(&out), vec![], "{}", rep.to_text());
    assert_eq!(max_displaced_gap(&out, D), 0.0);
    for t in 0..out.triangles.len() {
        if out.face_flags[t] & FACE_INSERTED == 0 {
            let ng = out.face_cross(t).normalize();
            assert!(out.corner_normals(t).iter().all(|n| n.dot(ng) > 0.9));
        }
    }
    // Two rungs at each of the rim's positions, a seam twin at each of the 5 positions inside
    // the rim's seam half, and where the seam crosses the rim, the other top island's first
    // rung (its UV differs, its normal is the same: the strips meet as a UV seam).
    assert!(rep.stitched_edges.iter().all(|e| e.segments == [3, 3]));
    assert_eq!(rep.inserted_vertices, 2 * rim + (rim / 2 - 1) + 2);
    assert_inserted_prisms_sane(&out, D);
}

// Would break if crease repair ignored UV seams on a real asset: the rock's knife-edge fin
// runs along the seams of its box-projected UV islands.
#[test]
fn rock_fin_crease_is_repaired_across_uv_seams() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/rock/rock.glb");
    let m = crate::load::load_mesh(&path, &Default::default()).unwrap();
    let input = m.clone();
    let (out, rep) = repair(m, &RepairOptions::default());
    assert_sized(&out);
    assert!(!rep.sharp_corners.is_empty());
    assert!(
        (10..=14).contains(&rep.crease_edges.len()),
        "{}",
        rep.to_text()
    );
    assert!(!rep.split_vertices.is_empty());
    assert!(
        rep.unresolved_crease_corners.is_empty(),
        "{}",
        rep.to_text()
    );
    // Every crease edge (by position) is stitched.
    let key = |p: Vec3| p.to_array().map(f32::to_bits);
    let stitched: std::collections::HashSet<_> = rep
        .stitched_edges
        .iter()
        .map(|e| {
            let (a, b) = (
                key(out.positions[e.vertices[0] as usize]),
                key(out.positions[e.vertices[1] as usize]),
            );
            (a.min(b), a.max(b))
        })
        .collect();
    for &[a, b] in &rep.crease_edges {
        let (a, b) = (
            key(input.positions[a as usize]),
            key(input.positions[b as usize]),
        );
        assert!(
            stitched.contains(&(a.min(b), a.max(b))),
            "crease {a:?}-{b:?} not stitched"
        );
    }
    assert_eq!(rep.unclosed_corners, 0, "{}", rep.to_text());
    assert_eq!(open_edges_not_seams(&out), vec![], "{}", rep.to_text());
    assert_eq!(max_displaced_gap(&out, 0.02), 0.0);
    // The fin's sides are nearly opposite: its stitches are strips, and no inserted prism
    // folds (they all did with one quad per edge: `PRISM_DEGENERATE_NORMALS`, λ ≈ ±23).
    assert!(
        rep.stitched_edges.iter().any(|e| e.segments[0] >= 3),
        "{}",
        rep.to_text()
    );
    let spread = assert_inserted_prisms_sane(&out, 0.025);
    eprintln!(
        "{}min spread of inserted normals: {spread:.3}",
        rep.to_text()
    );
}

// Would break if the bake of the real asset still had a prism whose normals cancel: the rock
// with its own map and scale, every prism (inserted or not) unflagged and its λ range within
// max |D| / MIN_SPREAD.
#[test]
fn rock_bakes_without_degenerate_prisms() {
    use crate::bake::{PRISM_DEGENERATE_NORMALS, PRISM_INSERTED};
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/rock/rock.glb");
    let spec = crate::asset::resolve(&path, &Default::default()).unwrap();
    let folded = |opts: &RepairOptions| {
        let p = crate::asset::prepare(&spec, opts).unwrap();
        let reach = p
            .table
            .prisms
            .iter()
            .map(|q| q.d_min.abs().max(q.d_max.abs()));
        let reach = reach.fold(0.0, f32::max);
        let inserted = p
            .table
            .prisms
            .iter()
            .filter(|q| q.flags & PRISM_INSERTED != 0);
        let worst = inserted
            .clone()
            .map(|q| q.lambda_lo.abs().max(q.lambda_hi.abs()))
            .fold(0.0, f32::max);
        let degenerate = p
            .table
            .prisms
            .iter()
            .filter(|q| q.flags & PRISM_DEGENERATE_NORMALS != 0)
            .count();
        eprintln!(
            "strip step {:.0}°: {} inserted prisms, {degenerate} degenerate, largest |λ| {worst:.3} (max |D| {reach:.4})",
            opts.strip_step_angle.to_degrees(),
            inserted.count()
        );
        (degenerate, worst / reach)
    };
    let (degenerate, ratio) = folded(&RepairOptions::default());
    assert_eq!(degenerate, 0);
    assert!(ratio <= 1.0 / MIN_SPREAD, "{ratio}");
    // Asked for one step per hard edge (the single quads that folded here, λ ≈ ±23, before
    // strips): the fin runs along UV seams, so its quads get seam twins on a middle rung at
    // the arc's midpoint, two 90° steps each, and do not fold either.
    let single = RepairOptions {
        strip_step_angle: std::f32::consts::PI,
        ..Default::default()
    };
    let (degenerate, ratio) = folded(&single);
    assert!(
        degenerate == 0 && ratio <= 1.0 / MIN_SPREAD,
        "{degenerate} {ratio}"
    );
}

/// A thin wedge (knife edge along z at x = 1, back face at x = 0, 2° between top and bottom)
/// with flat ends at z = ±1 and per-face normals, UVs and vertices: every edge a hard edge in
/// the file, like the cube, but the rim's sides are ~178° apart.
fn knife_wedge() -> BaseMesh {
    let t = 1f32.to_radians().tan();
    let rim = |z: f32| Vec3::new(1.0, 0.0, z);
    let top = |z: f32| Vec3::new(0.0, t, z);
    let bot = |z: f32| Vec3::new(0.0, -t, z);
    // Counter-clockwise seen from outside.
    let quads: [[Vec3; 4]; 3] = [
        [rim(1.0), rim(-1.0), top(-1.0), top(1.0)],
        [rim(-1.0), rim(1.0), bot(1.0), bot(-1.0)],
        [top(1.0), top(-1.0), bot(-1.0), bot(1.0)],
    ];
    let ends: [[Vec3; 3]; 2] = [
        [rim(1.0), top(1.0), bot(1.0)],
        [rim(-1.0), bot(-1.0), top(-1.0)],
    ];
    let (mut p, mut n, mut uv, mut tris) = (vec![], vec![], vec![], vec![]);
    let mut face = |corners: &[Vec3], tris: &mut Vec<[u32; 3]>| {
        let base = p.len() as u32;
        let ng = (corners[1] - corners[0])
            .cross(corners[2] - corners[0])
            .normalize();
        for &c in corners {
            p.push(c);
            n.push(ng);
            uv.push(Vec2::new(
                0.3 + 0.2 * c.x + 0.1 * c.z,
                0.5 + 0.2 * c.y + 0.15 * c.z,
            ));
        }
        for k in 1..corners.len() as u32 - 1 {
            tris.push([base, base + k, base + k + 1]);
        }
    };
    for q in &quads {
        face(q, &mut tris);
    }
    for e in &ends {
        face(e, &mut tris);
    }
    let m = mesh(p, n, uv, tris);
    let out = [
        m.face_cross(0).y,
        -m.face_cross(4).x,
        m.face_cross(6).z,
        -m.face_cross(7).z,
    ];
    assert!(out.iter().all(|&c| c > 0.0), "outward normals");
    m
}

// Would break if the corner fans ignored the strips: where the knife edge meets the flat ends,
// the hole between the copies runs through the strip's inserted normals, and a fan from one
// copy would put three normals of one great circle in a triangle (a flat prism) or span the
// nearly opposite sides (a folded one).
#[test]
fn knife_wedge_corners_are_fanned_around_a_centre() {
    const D: f32 = 0.1;
    let m = knife_wedge();
    assert!(max_displaced_gap(&m, D) > 0.05);
    let (out, rep) = repair(m, &RepairOptions::default());
    assert_sized(&out);
    assert!(rep.sharp_corners.is_empty() && rep.split_vertices.is_empty());
    assert_eq!(rep.stitched_edges.len(), 9, "{}", rep.to_text());
    let segments = |s: [u32; 2]| {
        rep.stitched_edges
            .iter()
            .filter(|e| e.segments == s)
            .count()
    };
    // The rim (178°) turns in three steps, the back edges (91°) in two, the ends' 90° edges
    // keep one quad.
    assert_eq!(
        (segments([3, 3]), segments([2, 2]), segments([1, 1])),
        (1, 2, 6),
        "{}",
        rep.to_text()
    );
    // All six corners touch a strip: every fan has a centre.
    assert_eq!(rep.corner_fans.len(), 6, "{}", rep.to_text());
    assert!(rep.corner_fans.iter().all(|f| f.centre.is_some()));
    let rim_ends: Vec<_> = rep
        .corner_fans
        .iter()
        .filter(|f| f.vertices.len() == 5)
        .collect();
    assert_eq!(rim_ends.len(), 2, "{}", rep.to_text());
    for f in &rim_ends {
        // top, two strip normals, bottom, end: five around the centre, which points out of
        // the rim's end (not into the blade).
        assert_eq!(f.inserted.len(), 5);
        let c = out.normals[f.centre.unwrap() as usize];
        assert!(c.x > 0.5, "{c}");
    }
    assert!(rep.corner_fans.iter().all(|f| !f.against_normals));
    assert_eq!(rep.unclosed_corners, 0);
    // Two per rim end, one per back edge end, one centre per corner.
    assert_eq!(rep.inserted_vertices, 2 * 2 + 4 + 6);
    assert_eq!(open_half_edges(&out), 0, "{}", rep.to_text());
    assert_eq!(max_displaced_gap(&out, D), 0.0);
    assert_inserted_prisms_sane(&out, D);
    // Idempotent: the repaired wedge needs no more stitching (its 2° rim is still listed as a
    // crease edge by angle, with nothing to split).
    let (again, rep2) = repair(out.clone(), &RepairOptions::default());
    assert!(rep2.split_vertices.is_empty() && rep2.inserted_triangles == 0);
    assert_eq!(again.triangles, out.triangles);
}
