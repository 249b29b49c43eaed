//! Steps 1–2: weld equal vertices, drop faces with no area, flag faces with no UV area.
//!
//! Equality is exact equality of quantised keys: positions on a grid of 1e-6 of the bounds'
//! diagonal, normals and UVs on a grid of 1e-6 (they are O(1) quantities). Values that straddle
//! a grid line stay apart; loaders write duplicated vertices bit-identically, which is the case
//! this is for. Before that, normals at one position that differ by less than `NORMAL_SNAP` in
//! every component are made their mean: exporters that write a normal per face corner (Blender's
//! USD export) leave ~1e-5 of noise between the copies of one smooth vertex, which would
//! otherwise be stitched as hundreds of hard edges of no angle (and marched slowly).

use super::{RepairReport, Work, INSERTED_ORIGIN};
use crate::mesh::{BaseMesh, FACE_INSERTED, FACE_UV_DEGENERATE};
use glam::{Vec2, Vec3};
use std::collections::HashMap;

/// Relative size of a weld cell (of the bounds' diagonal for positions, absolute for normals
/// and UVs): far below any modelled feature, far above f32 noise of copied values.
const WELD_CELL: f32 = 1e-6;
/// A face is zero-area below this fraction of the squared bounds' diagonal; f32 cross
/// products of a unit-sized mesh are accurate to ~1e-7, so only true degeneracies fall below.
const ZERO_AREA_REL: f32 = 1e-12;
/// UV area below which a face samples the map along a line (UV space is O(1)).
const ZERO_UV_AREA: f32 = 1e-12;

/// Normals at one position closer than this in every component (about 0.006°) are one normal.
pub const NORMAL_SNAP: f32 = 1e-4;

/// Each vertex's normal, the mean of those within `NORMAL_SNAP` of it at its position (by
/// `quant`'s grid); how many changed.
fn unified_normals(mesh: &BaseMesh, quant: &Quantizer) -> (Vec<Vec3>, usize) {
    let normal = |i: usize| mesh.normals.get(i).copied().unwrap_or(Vec3::ZERO);
    let mut at: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, p) in mesh.positions.iter().enumerate() {
        if p.is_finite() {
            at.entry(quant.position_key(*p)).or_default().push(i);
        }
    }
    let mut out: Vec<Vec3> = (0..mesh.positions.len()).map(normal).collect();
    let mut changed = 0;
    for group in at.values().filter(|g| g.len() > 1) {
        // Greedy clusters around their first member.
        let mut clusters: Vec<(Vec3, Vec<usize>)> = vec![];
        for &i in group {
            let n = normal(i);
            match clusters
                .iter_mut()
                .find(|(first, _)| (*first - n).abs().max_element() < NORMAL_SNAP)
            {
                Some((_, members)) => members.push(i),
                None => clusters.push((n, vec![i])),
            }
        }
        for (first, members) in clusters.iter().filter(|(_, m)| m.len() > 1) {
            // Copies that already match to the weld grid (a UV seam's, bit for bit or an ulp
            // apart) are left as they are: a clean mesh comes out unchanged.
            if members
                .iter()
                .all(|&i| (normal(i) - *first).abs().max_element() <= WELD_CELL)
            {
                continue;
            }
            let mean = members
                .iter()
                .map(|&i| normal(i))
                .sum::<Vec3>()
                .normalize_or_zero();
            if mean == Vec3::ZERO {
                continue;
            }
            for &i in members {
                if out[i] != mean {
                    out[i] = mean;
                    changed += 1;
                }
            }
        }
    }
    (out, changed)
}

/// Maps positions to integer cells relative to the mesh bounds.
#[derive(Clone, Copy, Debug)]
pub(super) struct Quantizer {
    lo: Vec3,
    inv_cell: f32,
    /// Squared bounds' diagonal (area scale).
    pub diag2: f32,
}

impl Quantizer {
    pub fn for_positions(positions: &[Vec3]) -> Self {
        let (lo, hi) = positions
            .iter()
            .filter(|p| p.is_finite())
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            });
        let diag = if lo.x <= hi.x {
            (hi - lo).length()
        } else {
            0.0
        };
        let diag = if diag > 0.0 { diag } else { 1.0 };
        Quantizer {
            lo: if lo.is_finite() { lo } else { Vec3::ZERO },
            inv_cell: 1.0 / (diag * WELD_CELL),
            diag2: diag * diag,
        }
    }
    pub fn position_key(&self, p: Vec3) -> [i64; 3] {
        ((p - self.lo) * self.inv_cell)
            .to_array()
            .map(|x| x.round() as i64)
    }
}

fn unit_key(v: &[f32]) -> impl Iterator<Item = i64> + '_ {
    v.iter().map(|x| (x / WELD_CELL).round() as i64)
}

/// Step 1: merge vertices with equal (quantised) position, normal and UV; remap triangles.
/// Welded vertices are numbered in order of first occurrence, so a mesh without duplicates is
/// unchanged. With `enabled == false` the arrays are copied as they are.
pub(super) fn weld(
    mesh: &BaseMesh,
    quant: &Quantizer,
    enabled: bool,
    report: &mut RepairReport,
) -> Work {
    let nv = mesh.positions.len();
    let (normals, changed) = match enabled {
        true => unified_normals(mesh, quant),
        false => (
            (0..nv)
                .map(|i| mesh.normals.get(i).copied().unwrap_or(Vec3::ZERO))
                .collect(),
            0,
        ),
    };
    report.unified_normals = changed;
    let normal = |i: usize| normals[i];
    let uv = |i: usize| mesh.uvs.get(i).copied().unwrap_or(Vec2::ZERO);
    let mut remap = Vec::with_capacity(nv);
    let mut w = Work {
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        vertex_origin: Vec::new(),
        triangles: Vec::new(),
        face_origin: Vec::new(),
        face_group: Vec::new(),
        face_flags: Vec::new(),
    };
    let mut seen: HashMap<[i64; 8], u32> = HashMap::new();
    for i in 0..nv {
        let (p, n, t) = (mesh.positions[i], normal(i), uv(i));
        let mut key = [0i64; 8];
        for (k, v) in quant
            .position_key(p)
            .into_iter()
            .chain(unit_key(&n.to_array()))
            .chain(unit_key(&t.to_array()))
            .enumerate()
        {
            key[k] = v;
        }
        let fresh = w.positions.len() as u32;
        let id = if enabled && p.is_finite() {
            *seen.entry(key).or_insert(fresh)
        } else {
            fresh
        };
        if id == fresh {
            w.positions.push(p);
            w.normals.push(n);
            w.uvs.push(t);
            w.vertex_origin.push(i as u32);
        } else {
            report.welded_vertices += 1;
        }
        remap.push(id);
    }
    for (f, tri) in mesh.triangles.iter().enumerate() {
        let valid = tri
            .iter()
            .all(|&i| (i as usize) < nv && mesh.positions[i as usize].is_finite());
        if !valid {
            report.invalid_faces.push(f as u32);
            continue;
        }
        w.triangles.push(tri.map(|i| remap[i as usize]));
        w.face_origin.push(f as u32);
        w.face_group
            .push(mesh.face_group.get(f).copied().unwrap_or(0));
        w.face_flags
            .push(mesh.face_flags.get(f).copied().unwrap_or(0));
    }
    w
}

/// Step 2: drop faces with a repeated index or zero area; flag (and keep) UV-degenerate ones.
/// Faces repair inserted on an earlier run have zero area by design and are kept as they are.
pub(super) fn drop_degenerate_faces(w: &mut Work, quant: &Quantizer, report: &mut RepairReport) {
    let min_area = ZERO_AREA_REL * quant.diag2;
    let mut keep = vec![true; w.triangles.len()];
    for (t, tri) in w.triangles.iter().enumerate() {
        if w.face_flags[t] & FACE_INSERTED != 0 {
            continue;
        }
        let [a, b, c] = tri.map(|i| w.positions[i as usize]);
        let repeated = tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2];
        let area = 0.5 * (b - a).cross(c - a).length();
        // NaN areas (non-finite input) count as zero area.
        if repeated || area.is_nan() || area < min_area {
            keep[t] = false;
            report.zero_area_faces.push(w.face_origin[t]);
            continue;
        }
        let [ua, ub, uc] = tri.map(|i| w.uvs[i as usize]);
        let uv_area = 0.5 * (ub - ua).perp_dot(uc - ua).abs();
        if uv_area.is_nan() || uv_area < ZERO_UV_AREA {
            w.face_flags[t] |= FACE_UV_DEGENERATE;
            report.uv_degenerate_faces.push(w.face_origin[t]);
        }
    }
    retain_faces(w, &keep);
}

fn retain_faces(w: &mut Work, keep: &[bool]) {
    let mut k = 0;
    for (t, &kept) in keep.iter().enumerate() {
        if kept {
            w.triangles[k] = w.triangles[t];
            w.face_origin[k] = w.face_origin[t];
            w.face_group[k] = w.face_group[t];
            w.face_flags[k] = w.face_flags[t];
            k += 1;
        }
    }
    w.triangles.truncate(k);
    w.face_origin.truncate(k);
    w.face_group.truncate(k);
    w.face_flags.truncate(k);
    debug_assert!(w.face_origin.iter().all(|&o| o != INSERTED_ORIGIN));
}

/// Remove vertices no face references (in order, so indices only shift down).
pub(super) fn compact_vertices(w: &mut Work, report: &mut RepairReport) {
    let mut used = vec![false; w.positions.len()];
    for tri in &w.triangles {
        for &i in tri {
            used[i as usize] = true;
        }
    }
    let mut remap = vec![u32::MAX; used.len()];
    let mut k = 0usize;
    for i in 0..used.len() {
        if used[i] {
            remap[i] = k as u32;
            w.positions[k] = w.positions[i];
            w.normals[k] = w.normals[i];
            w.uvs[k] = w.uvs[i];
            w.vertex_origin[k] = w.vertex_origin[i];
            k += 1;
        }
    }
    report.unreferenced_vertices = used.len() - k;
    w.positions.truncate(k);
    w.normals.truncate(k);
    w.uvs.truncate(k);
    w.vertex_origin.truncate(k);
    for tri in &mut w.triangles {
        *tri = tri.map(|i| remap[i as usize]);
    }
}
