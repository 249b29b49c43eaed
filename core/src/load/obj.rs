//! Wavefront OBJ into a `BaseMesh`: `v`/`vt`/`vn`, polygons fan-triangulated, each distinct
//! `v/vt/vn` corner a vertex, `g`/`o` names kept as groups. OBJ's v already points up.
//!
//! A small parser of our own rather than `tobj`: with `single_index`, tobj 4.0.5 panics
//! (multiply overflow) on a relative index reaching before the first element
//! (`f 1/-5 2/1 3/1`), takes a zero index (`f 1/0 ...`) as "absent", and then, like any face
//! where only some corners carry `vt`, returns fewer UVs than positions, silently misaligned.
//! Its errors carry no line number; here every error names the line. Materials, smoothing
//! groups, points, lines and free-form geometry are ignored.

use super::MeshOptions;
use crate::error::{Error, Result};
use crate::mesh::{BaseMesh, UpAxis};
use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::path::Path;

/// A face corner: indices into the file's v, vt, vn lists (0-based, already resolved).
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
struct Corner {
    v: u32,
    vt: Option<u32>,
    vn: Option<u32>,
}

#[derive(Default)]
struct Parsed {
    v: Vec<Vec3>,
    vt: Vec<Vec2>,
    vn: Vec<Vec3>,
    /// Triangles of corners, with the group index of each.
    tris: Vec<([Corner; 3], u32)>,
    groups: Vec<String>,
}

pub fn load(path: &Path, _opts: &MeshOptions) -> Result<BaseMesh> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = String::from_utf8_lossy(&bytes);
    let parsed = parse(path, &text)?;
    build_mesh(path, parsed)
}

fn parse(path: &Path, text: &str) -> Result<Parsed> {
    let mut p = Parsed::default();
    let mut group: Option<u32> = None;
    let mut joined = String::new();
    let mut start_line = 0;
    for (i, raw) in text.lines().enumerate() {
        // A trailing backslash continues the statement on the next line.
        if joined.is_empty() {
            start_line = i + 1;
        }
        if let Some(head) = raw.strip_suffix('\\') {
            joined.push_str(head);
            joined.push(' ');
            continue;
        }
        joined.push_str(raw);
        let line = std::mem::take(&mut joined);
        let line = line.split('#').next().unwrap_or("");
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        let at = |what: String| Error::invalid(path, format!("line {start_line}: {what}"));
        match keyword {
            "v" => p.v.push(Vec3::from(floats::<3>(&mut words).map_err(at)?)),
            "vn" => p.vn.push(Vec3::from(floats::<3>(&mut words).map_err(at)?)),
            "vt" => p.vt.push(Vec2::from(floats::<2>(&mut words).map_err(at)?)),
            "g" | "o" => {
                let name = words.collect::<Vec<_>>().join(" ");
                let name = if name.is_empty() {
                    "default".to_string()
                } else {
                    name
                };
                group = Some(group_index(&mut p.groups, name));
            }
            "f" => {
                let mut corners = Vec::new();
                for w in words {
                    corners.push(corner(w, &p).map_err(at)?);
                }
                if corners.len() < 3 {
                    return Err(at(format!(
                        "face has {} corners, a face needs at least 3 (delete it or use 'l' for \
                         a line)",
                        corners.len()
                    )));
                }
                let g = *group.get_or_insert_with(|| group_index(&mut p.groups, "default".into()));
                for k in 1..corners.len() - 1 {
                    p.tris.push(([corners[0], corners[k], corners[k + 1]], g));
                }
            }
            _ => {}
        }
    }
    Ok(p)
}

fn group_index(groups: &mut Vec<String>, name: String) -> u32 {
    match groups.iter().position(|g| *g == name) {
        Some(i) => i as u32,
        None => {
            groups.push(name);
            groups.len() as u32 - 1
        }
    }
}

/// The first N numbers of a statement (a fourth `w` of `v`, or a third of `vt`, is ignored).
fn floats<const N: usize>(words: &mut std::str::SplitWhitespace) -> Result<[f32; N], String> {
    let mut out = [0.0; N];
    for (k, slot) in out.iter_mut().enumerate() {
        let w = words
            .next()
            .ok_or_else(|| format!("expected {N} numbers, found {k} (fix the line)"))?;
        *slot = w
            .parse()
            .map_err(|_| format!("'{w}' is not a number (fix the line)"))?;
    }
    Ok(out)
}

/// `v`, `v/vt`, `v//vn` or `v/vt/vn`, 1-based or negative (relative to the end so far).
fn corner(word: &str, p: &Parsed) -> Result<Corner, String> {
    let mut parts = word.split('/');
    let v = resolve(parts.next(), p.v.len(), "vertex", word)?
        .ok_or_else(|| format!("face corner '{word}' has no vertex index"))?;
    let vt = resolve(parts.next(), p.vt.len(), "texture coordinate", word)?;
    let vn = resolve(parts.next(), p.vn.len(), "normal", word)?;
    if parts.next().is_some() {
        return Err(format!("face corner '{word}' has more than three indices"));
    }
    Ok(Corner { v, vt, vn })
}

fn resolve(part: Option<&str>, len: usize, what: &str, word: &str) -> Result<Option<u32>, String> {
    let Some(s) = part.filter(|s| !s.is_empty()) else {
        return Ok(None);
    };
    let i: i64 = s
        .parse()
        .map_err(|_| format!("face corner '{word}': '{s}' is not an index"))?;
    // 1-based from the start, or negative from the end of what has been read so far.
    let zero_based = if i > 0 { i - 1 } else { len as i64 + i };
    if i == 0 || zero_based < 0 || zero_based >= len as i64 {
        return Err(format!(
            "face corner '{word}' references {what} {i} but only {len} are defined before this \
             line (re-export the mesh)"
        ));
    }
    Ok(Some(zero_based as u32))
}

fn build_mesh(path: &Path, p: Parsed) -> Result<BaseMesh> {
    let mut mesh = BaseMesh {
        source: path.into(),
        up_axis: Some(UpAxis::Y),
        groups: p.groups,
        ..Default::default()
    };
    let any_uv = p.tris.iter().any(|(c, _)| c.iter().any(|c| c.vt.is_some()));
    let all_uv = p.tris.iter().all(|(c, _)| c.iter().all(|c| c.vt.is_some()));
    let all_normals = p.tris.iter().all(|(c, _)| c.iter().all(|c| c.vn.is_some()));
    if any_uv && !all_uv {
        eprintln!(
            "warning: {}: some face corners have no texture coordinate; the mesh is treated as \
             having no UVs (give every face a vt)",
            path.display()
        );
    }
    mesh.missing_uvs = !all_uv;

    let mut index: HashMap<Corner, u32> = HashMap::new();
    let mut file_normals = Vec::new();
    for (corners, g) in &p.tris {
        let tri = corners.map(|c| {
            *index.entry(c).or_insert_with(|| {
                mesh.positions.push(p.v[c.v as usize]);
                let uv = match (all_uv, c.vt) {
                    (true, Some(t)) => p.vt[t as usize],
                    _ => Vec2::ZERO,
                };
                mesh.uvs.push(uv);
                file_normals.push(c.vn.map(|n| p.vn[n as usize]));
                mesh.positions.len() as u32 - 1
            })
        });
        mesh.triangles.push(tri);
        mesh.face_group.push(*g);
    }
    mesh.face_flags = vec![0; mesh.triangles.len()];
    mesh.normals = if all_normals {
        // File normals need not be unit length; a zero one is replaced by the face-derived one.
        let derived = BaseMesh::angle_weighted_normals(&mesh.positions, &mesh.triangles);
        file_normals
            .iter()
            .zip(derived)
            .map(|(n, d)| n.and_then(|n| n.try_normalize()).unwrap_or(d))
            .collect()
    } else {
        BaseMesh::angle_weighted_normals(&mesh.positions, &mesh.triangles)
    };
    Ok(mesh)
}
