//! Wavefront OBJ into a `BaseMesh`: `v`/`vt`/`vn`, polygons fan-triangulated, each distinct
//! `v/vt/vn` corner a vertex, `g`/`o` names kept as groups (one per name and `usemtl`
//! material). OBJ's v already points up.
//!
//! Materials: the `mtllib` files' `newmtl` entries, in order, read as Blender's OBJ importer
//! reads them: `Kd` (the base colour), `map_Kd` (the base-colour texture, a file next to the
//! .mtl; it replaces `Kd`; `-clamp on` clamps it, `-s`/`-o` scale and offset its UVs), the
//! classic `illum`, `Ka`, `Ks`, `Ns` and `Ni` and the PBR extension's `Pr`/`Pm` over them
//! (roughness, metallic, reflectance: `MtlReflectance::resolve`), the maps `map_Pr`/`map_Ns`
//! and `map_Pm`/`refl` (data textures, one channel: `-imfchan`, else red), `Pc`/`Pcr` (the
//! clearcoat: four times its weight, its roughness), `Ke`/`map_Ke` (emission), `d`/`map_d`
//! (the alpha), and a
//! tangent-space normal map: `norm`, or
//! `map_Bump`/`bump` as Blender's exporter and importer use them (`-bm` its strength; a grey
//! bump map is not read, `render::lookdev::grey_normal_map`). A missing .mtl or an undefined
//! `usemtl` name is a warning (those faces get the default material), not an error.
//!
//! A small parser of our own rather than `tobj`: with `single_index`, tobj 4.0.5 panics
//! (multiply overflow) on a relative index reaching before the first element
//! (`f 1/-5 2/1 3/1`), takes a zero index (`f 1/0 ...`) as "absent", and then, like any face
//! where only some corners carry `vt`, returns fewer UVs than positions, silently misaligned.
//! Its errors carry no line number; here every error names the line. Smoothing groups, points,
//! lines and free-form geometry are ignored.

use super::MeshOptions;
use crate::error::{Error, Result};
use crate::mesh::{AlphaMode, BaseMesh, MeshMaterial, UpAxis};
use crate::texture::{
    ChannelRef, ColorSpace, NormalMapRef, Sampler, TexWrap, TextureData, TextureRef, UvTransform,
};
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
    /// Per group: its `usemtl` material name, if any.
    group_material: Vec<Option<String>>,
    /// `mtllib` file names, in order.
    mtllibs: Vec<String>,
}

pub fn load(path: &Path, _opts: &MeshOptions) -> Result<BaseMesh> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = String::from_utf8_lossy(&bytes);
    let parsed = parse(path, &text)?;
    let (materials, names) = load_materials(path, &parsed.mtllibs)?;
    let mut mesh = build_mesh(path, &parsed)?;
    if !materials.is_empty() {
        let none = materials.len() as u32;
        let mut undefined = vec![];
        mesh.group_material = parsed
            .group_material
            .iter()
            .map(|m| match m {
                None => none,
                Some(name) => match names.iter().position(|n| n == name) {
                    Some(i) => i as u32,
                    None => {
                        undefined.push(name.as_str());
                        none
                    }
                },
            })
            .collect();
        if !undefined.is_empty() {
            undefined.dedup();
            eprintln!(
                "warning: {}: usemtl names materials no mtllib defines ({}): those faces get \
                 the default material",
                path.display(),
                undefined.join(", ")
            );
        }
        mesh.materials = materials;
    }
    Ok(mesh)
}

/// The materials of the `mtllib` files (relative to the OBJ's folder), in order, and their
/// names. A file that cannot be read is a warning.
fn load_materials(path: &Path, libs: &[String]) -> Result<(Vec<MeshMaterial>, Vec<String>)> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let (mut materials, mut names) = (vec![], vec![]);
    for lib in libs {
        let file = dir.join(lib);
        let text = match super::read_named_file(&file) {
            Ok(b) => String::from_utf8_lossy(&b).into_owned(),
            Err(e) => {
                eprintln!(
                    "warning: {}: mtllib '{lib}' cannot be read ({e}): its materials are left \
                     out (keep the .mtl next to the .obj)",
                    path.display()
                );
                continue;
            }
        };
        parse_mtl(&file, &text, &mut materials, &mut names)?;
    }
    super::check_material_count(path, materials.len())?;
    Ok((materials, names))
}

/// A `map_*` statement of an `.mtl`: its texture, the channel `-imfchan` picks and the
/// strength `-bm` gives (1 without).
struct MtlMap {
    texture: TextureRef,
    channel: u8,
    strength: f32,
}

/// A `map_*` statement's texture (its last word, a file next to the `.mtl`) and the
/// channel its `-imfchan` option picks (red unless `g` or `b`: `l`, `m` and `z` read a grey
/// image's one channel); `-clamp on` clamps its UVs, `-s` scales and `-o` offsets them, `-bm`
/// is a normal map's strength.
fn mtl_map<'a>(
    keyword: &str,
    words: &mut impl Iterator<Item = &'a str>,
    dir: &Path,
    color_space: ColorSpace,
) -> std::result::Result<MtlMap, String> {
    let words: Vec<&str> = words.collect();
    let Some((name, options)) = words.split_last() else {
        return Err(format!("{keyword} names no file (fix the line)"));
    };
    let clamp = options.windows(2).any(|w| w == ["-clamp", "on"]);
    let wrap = if clamp {
        TexWrap::Clamp
    } else {
        TexWrap::Repeat
    };
    // `-s u [v [w]]` scales and `-o u [v [w]]` offsets the map's UVs (v as u's if absent).
    let vector = |flag: &str, default: f32| -> std::result::Result<[f32; 2], String> {
        let Some(at) = options.iter().position(|o| *o == flag) else {
            return Ok([default; 2]);
        };
        let mut v = options[at + 1..]
            .iter()
            .map_while(|w| w.parse::<f32>().ok())
            .filter(|x| x.is_finite());
        let u = v
            .next()
            .ok_or_else(|| format!("{keyword} {flag} takes a number (fix the line)"))?;
        Ok([u, v.next().unwrap_or(u)])
    };
    let transform = UvTransform::scale_offset(vector("-s", 1.0)?, vector("-o", 0.0)?);
    let strength = vector("-bm", 1.0)?[0];
    let channel = match options.windows(2).find(|w| w[0] == "-imfchan") {
        Some([_, "g"]) => 1,
        Some([_, "b"]) => 2,
        _ => 0,
    };
    let texture = TextureRef {
        name: name.to_string(),
        data: TextureData::File(dir.join(name)),
        sampler: Sampler {
            wrap: [wrap; 2],
            nearest: false,
        },
        tex_coord: 0,
        transform,
        color_space,
        scale_bias: None,
    };
    Ok(MtlMap {
        texture,
        channel,
        strength,
    })
}

/// What an `.mtl` entry says of its specular layer and metalness in the classic model
/// (`illum`, `Ka`, `Ks`, `Ns`, `Ni`) and the PBR extension (`Pr`, `Pm`), which may come in
/// any order: `resolve` turns them into the material's values when the entry ends.
#[derive(Default)]
struct MtlReflectance {
    illum: Option<i32>,
    ka: Option<[f32; 3]>,
    ks: Option<[f32; 3]>,
    ns: Option<f32>,
    ni: Option<f32>,
    pr: Option<f32>,
    pm: Option<f32>,
    /// `d`, the dissolve: Blender's importer makes it the Alpha (`Tr` it does not read).
    d: Option<f32>,
}

impl MtlReflectance {
    /// `m`'s roughness, metallic and F0, as Blender's OBJ importer sets the Principled BSDF
    /// (checked with bpy 5.0.1, `wm.obj_import`, against every case below):
    /// * roughness: `Pr`, else `1 − √(Ns / 1000)` (Ns clamped to [0, 1000]), else 0 under
    ///   `illum 2` (highlight on) and 1 otherwise;
    /// * metallic: `Pm`, else under `illum` 3 to 8 (reflection on) the mean of `Ka`, or 1
    ///   without one, else 0;
    /// * Specular IOR Level: the mean of `Ks`, else 1 under `illum 2` and 0 otherwise; Cycles
    ///   scales the index's F0 by twice it, so a plain `Kd` material has no specular at all;
    /// * the index: `Ni` (above 0), else 1.5, or 1 under `illum` 6 or 7 (refraction, no glass);
    /// * the alpha: `map_d`'s alpha channel, else `d`, which lets rays through
    ///   (`AlphaMode::Blend`).
    ///
    /// A texture in the roughness's or metallic's place makes its factor 1.
    fn resolve(&self, m: &mut MeshMaterial) {
        let mean = |c: [f32; 3]| (c[0] + c[1] + c[2]) / 3.0;
        let illum = self.illum.unwrap_or(-1);
        let highlight = illum == 2;
        let reflection = (3..=8).contains(&illum);
        let roughness = match (self.pr, self.ns) {
            (Some(pr), _) => pr,
            (None, Some(ns)) if ns >= 0.0 => 1.0 - (ns.min(1000.0) / 1000.0).sqrt(),
            _ if highlight => 0.0,
            _ => 1.0,
        };
        let metallic = match (self.pm, self.ka) {
            (Some(pm), _) => pm,
            _ if !reflection => 0.0,
            (None, Some(ka)) => mean(ka),
            (None, None) => 1.0,
        };
        let level = self
            .ks
            .map(mean)
            .unwrap_or(if highlight { 1.0 } else { 0.0 });
        let ior = match self.ni {
            Some(ni) if ni > 0.0 => ni,
            _ if matches!(illum, 6 | 7) => 1.0,
            _ => 1.5,
        };
        if m.roughness_texture.is_none() {
            m.roughness = roughness.clamp(0.0, 1.0);
        }
        if m.metallic_texture.is_none() {
            m.metallic = metallic.clamp(0.0, 1.0);
        }
        if m.alpha_texture.is_some() {
            (m.base_color[3], m.alpha_mode) = (1.0, AlphaMode::Blend);
        } else if let Some(d) = self.d {
            (m.base_color[3], m.alpha_mode) = (d.clamp(0.0, 1.0), AlphaMode::Blend);
        }
        // ((n − 1) / (n + 1))² is the same for n and 1 / n, as Cycles reads an index below 1.
        let f0 = ((ior - 1.0) / (ior + 1.0)).powi(2);
        m.specular = Some((f0 * 2.0 * level).clamp(0.0, 1.0));
    }
}

/// One .mtl file's `newmtl` entries, appended to `materials` (the statements the module's doc
/// names; the rest is ignored).
fn parse_mtl(
    file: &Path,
    text: &str,
    materials: &mut Vec<MeshMaterial>,
    names: &mut Vec<String>,
) -> Result<()> {
    let dir = file.parent().unwrap_or(Path::new("."));
    // This file's entries start at `first`: statements before its first `newmtl` belong to
    // none (not to another file's last entry).
    let first = materials.len();
    let mut reflectance = MtlReflectance::default();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("");
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        let at = |what: String| Error::invalid(file, format!("line {}: {what}", i + 1));
        if keyword == "newmtl" {
            if let Some(m) = materials[first..].last_mut() {
                std::mem::take(&mut reflectance).resolve(m);
            }
            let name = words.collect::<Vec<_>>().join(" ");
            names.push(name.clone());
            materials.push(MeshMaterial::plain(
                name,
                [0.8, 0.8, 0.8, 1.0],
                crate::render::lookdev::DEFAULT_ROUGHNESS,
                crate::render::lookdev::DEFAULT_METALLIC,
            ));
            continue;
        }
        let Some(m) = materials[first..].last_mut() else {
            continue;
        };
        let r = &mut reflectance;
        let one = |words: &mut std::str::SplitWhitespace| floats::<1>(words).map(|[x]| x);
        match keyword {
            "Kd" => {
                let [r, g, b] = color(&mut words).map_err(at)?;
                m.base_color = [r, g, b, 1.0];
            }
            "Ke" => m.emission = color(&mut words).map_err(at)?,
            "Ka" => r.ka = Some(color(&mut words).map_err(at)?),
            "Ks" => r.ks = Some(color(&mut words).map_err(at)?),
            "Ns" => r.ns = Some(one(&mut words).map_err(at)?),
            // The index of refraction (Blender's importer reads it as the IOR).
            "Ni" => r.ni = Some(one(&mut words).map_err(at)?),
            "illum" => r.illum = Some(one(&mut words).map_err(at)? as i32),
            "Pr" => r.pr = Some(one(&mut words).map_err(at)?),
            "Pm" => r.pm = Some(one(&mut words).map_err(at)?),
            // `d [-halo] factor` (the halo form's factor read as the plain one).
            "d" => {
                let w = words.find(|w| *w != "-halo").unwrap_or("");
                let d = w
                    .parse()
                    .map_err(|_| at(format!("d takes a number, not '{w}' (fix the line)")))?;
                r.d = Some(d);
            }
            // Blender's importer: the map replaces Ke's colour (its strength stays 1).
            "map_Ke" => {
                let t = mtl_map(keyword, &mut words, dir, ColorSpace::Srgb).map_err(at)?;
                m.emission = [1.0; 3];
                m.emission_texture = Some(t.texture);
            }
            // The clearcoat's weight and roughness, as Blender's importer reads them: Pc is
            // four times the Coat Weight (Blender's exporter writes the weight 0.2 as Pc 0.8).
            "Pc" => m.clearcoat = (one(&mut words).map_err(at)? / 4.0).clamp(0.0, 1.0),
            "Pcr" => m.clearcoat_roughness = one(&mut words).map_err(at)?.clamp(0.0, 1.0),
            // A map replaces its value (the factor becomes 1), as Kd's does.
            "map_Kd" => {
                let t = mtl_map(keyword, &mut words, dir, ColorSpace::Srgb).map_err(at)?;
                m.base_color = [1.0; 4];
                m.base_color_texture = Some(t.texture);
            }
            // Blender's importer links the image's alpha channel to the Alpha, in d's place
            // (a grey image without one: alpha 1).
            "map_d" => {
                let t = mtl_map(keyword, &mut words, dir, ColorSpace::Alpha).map_err(at)?;
                m.alpha_texture = Some(ChannelRef {
                    texture: t.texture,
                    channel: 0,
                });
            }
            "norm" | "map_Bump" | "bump" => {
                let t = mtl_map(keyword, &mut words, dir, ColorSpace::Raw).map_err(at)?;
                m.normal_texture = Some(NormalMapRef::unit(t.texture, t.strength));
            }
            // Blender's importer links `map_Ns` to the roughness and `refl` to the metallic,
            // as it does `map_Pr` and `map_Pm`.
            "map_Pr" | "map_Ns" | "map_Pm" | "refl" => {
                let MtlMap {
                    texture, channel, ..
                } = mtl_map(keyword, &mut words, dir, ColorSpace::Raw).map_err(at)?;
                let c = Some(ChannelRef { texture, channel });
                if matches!(keyword, "map_Pr" | "map_Ns") {
                    (m.roughness, m.roughness_texture) = (1.0, c);
                } else {
                    (m.metallic, m.metallic_texture) = (1.0, c);
                }
            }
            _ => {}
        }
    }
    if let Some(m) = materials[first..].last_mut() {
        reflectance.resolve(m);
    }
    Ok(())
}

/// An `.mtl` colour: `r g b`, or `r` alone for grey (the format leaves g and b optional).
fn color(words: &mut std::str::SplitWhitespace) -> Result<[f32; 3], String> {
    let words: Vec<&str> = words.collect();
    let number = |w: &str| {
        w.parse::<f32>()
            .map_err(|_| format!("'{w}' is not a number (fix the line)"))
    };
    match words.as_slice() {
        [r] => Ok([number(r)?; 3]),
        [r, g, b, ..] => Ok([number(r)?, number(g)?, number(b)?]),
        _ => Err(format!(
            "expected 1 or 3 numbers, found {} (fix the line)",
            words.len()
        )),
    }
}

fn parse(path: &Path, text: &str) -> Result<Parsed> {
    let mut p = Parsed::default();
    let mut group: Option<u32> = None;
    // The current `g`/`o` name and `usemtl` material: a face's group is the pair's.
    let mut name = "default".to_string();
    let mut material: Option<String> = None;
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
                let n = words.collect::<Vec<_>>().join(" ");
                name = if n.is_empty() {
                    "default".to_string()
                } else {
                    n
                };
                // Made at the next face: a name or material without faces is no group.
                group = None;
            }
            "usemtl" => {
                let m = words.collect::<Vec<_>>().join(" ");
                material = (!m.is_empty()).then_some(m);
                group = None;
            }
            "mtllib" => p.mtllibs.extend(words.map(str::to_string)),
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
                let g = *group.get_or_insert_with(|| group_index(&mut p, &name, &material));
                for k in 1..corners.len() - 1 {
                    p.tris.push(([corners[0], corners[k], corners[k + 1]], g));
                }
            }
            _ => {}
        }
    }
    Ok(p)
}

/// The group of faces named `name` with material `material` (one per pair).
fn group_index(p: &mut Parsed, name: &str, material: &Option<String>) -> u32 {
    let found = p
        .groups
        .iter()
        .zip(&p.group_material)
        .position(|(g, m)| g == name && m == material);
    match found {
        Some(i) => i as u32,
        None => {
            p.groups.push(name.to_string());
            p.group_material.push(material.clone());
            p.groups.len() as u32 - 1
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

fn build_mesh(path: &Path, p: &Parsed) -> Result<BaseMesh> {
    let mut mesh = BaseMesh {
        source: path.into(),
        up_axis: Some(UpAxis::Y),
        groups: p.groups.clone(),
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
