//! Loader specifications. Every fixture is written in code to its own temp folder, so the
//! tests say exactly which bytes they feed in. Bad input must come back as `Err` naming the
//! file, never as a panic.

use super::{load_height_map, load_mesh, MapOptions, MeshOptions};
use crate::mesh::{BaseMesh, Projection};
use crate::texture::{Sampler, TexWrap, TextureData, UvTransform};
use glam::{Vec2, Vec3};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

// ---------------------------------------------------------------------------------------------
// Fixture helpers

fn temp_dir(name: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "prismbake-load-{name}-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The error text of a load that must fail, checked to name the file.
fn err_naming_file<T: std::fmt::Debug>(result: crate::Result<T>, path: &Path) -> String {
    let msg = result.expect_err("loading must fail").to_string();
    let name = path.file_name().unwrap().to_str().unwrap();
    assert!(msg.contains(name), "error does not name '{name}': {msg}");
    msg
}

fn base64(bytes: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let b = [c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0)];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A glTF document under construction: one buffer, a view per accessor.
#[derive(Default)]
struct GltfDoc {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl GltfDoc {
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.views
            .push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}));
        self.views.len() - 1
    }

    /// Float accessor of `n` components (min/max over finite values, as POSITION requires).
    fn floats(&mut self, data: &[f32], n: usize) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.view(&bytes);
        let (mut lo, mut hi) = (vec![0.0f32; n], vec![0.0f32; n]);
        for c in 0..n {
            let finite = data.iter().skip(c).step_by(n).filter(|v| v.is_finite());
            lo[c] = finite.clone().fold(f32::INFINITY, |a, &b| a.min(b));
            hi[c] = finite.fold(f32::NEG_INFINITY, |a, &b| a.max(b));
        }
        let ty = ["SCALAR", "VEC2", "VEC3", "VEC4"][n - 1];
        self.accessors.push(json!({
            "bufferView": view, "componentType": 5126, "count": data.len() / n,
            "type": ty, "min": lo, "max": hi
        }));
        self.accessors.len() - 1
    }

    fn indices(&mut self, data: &[u16]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.accessors.push(json!({
            "bufferView": view, "componentType": 5123, "count": data.len(), "type": "SCALAR"
        }));
        self.accessors.len() - 1
    }

    /// The JSON with `rest` (nodes, meshes, scenes, ...) merged in; `uri` None for GLB.
    fn json(&self, rest: &Value, uri: Option<String>) -> Value {
        let mut buffer = json!({"byteLength": self.bin.len()});
        if let Some(uri) = uri {
            buffer["uri"] = json!(uri);
        }
        let mut doc = json!({
            "asset": {"version": "2.0"},
            "buffers": [buffer],
            "bufferViews": self.views,
            "accessors": self.accessors,
        });
        for (k, v) in rest.as_object().unwrap() {
            doc[k] = v.clone();
        }
        doc
    }

    fn write_gltf(&self, path: &Path, rest: &Value) {
        let uri = format!("data:application/octet-stream;base64,{}", base64(&self.bin));
        std::fs::write(path, self.json(rest, Some(uri)).to_string()).unwrap();
    }

    fn glb(&self, rest: &Value) -> Vec<u8> {
        let mut json = self.json(rest, None).to_string().into_bytes();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let mut bin = self.bin.clone();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + json.len() + 8 + bin.len();
        let mut out = Vec::new();
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }
}

/// One mesh with one primitive, on one node, in one default scene.
fn single_node_scene(node: Value, primitive: Value) -> Value {
    let mut node = node;
    node["mesh"] = json!(0);
    json!({
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [node],
        "meshes": [{"name": "Tri", "primitives": [primitive]}],
    })
}

/// The triangle (0,0,0) (1,0,0) (0,1,0): counter-clockwise seen from +Z.
const TRI: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

fn load_gltf_doc(
    dir: &Path,
    name: &str,
    doc: &GltfDoc,
    rest: &Value,
    opts: &MeshOptions,
) -> crate::Result<BaseMesh> {
    let path = dir.join(name);
    doc.write_gltf(&path, rest);
    load_mesh(&path, opts)
}

fn approx(a: Vec3, b: Vec3) -> bool {
    (a - b).length() < 1e-5
}

// ---------------------------------------------------------------------------------------------
// 1. UV origin: the same image pixel under the same (u, v) from glTF and from OBJ.

/// 2x2 grey PNG, every texel different: top row 10, 20; bottom row 30, 40.
fn write_asymmetric_png(path: &Path) -> [[f32; 2]; 2] {
    let pixels = [[10u8, 20], [30, 40]];
    let raw: Vec<u8> = pixels.iter().flatten().copied().collect();
    image::GrayImage::from_raw(2, 2, raw)
        .unwrap()
        .save(path)
        .unwrap();
    pixels.map(|row| row.map(|p| p as f32 / 255.0))
}

/// A unit quad in the XY plane as a 4x4 vertex grid at x, y in {0, 1/4, 3/4, 1}: the corners
/// are the image corners, the inner vertices sit on the 2x2 texel centres. In the project's
/// convention (v up) the UV of each vertex equals its (x, y).
fn uv_grid() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let xs = [0.0, 0.25, 0.75, 1.0];
    let mut p = Vec::new();
    for y in xs {
        for x in xs {
            p.push(Vec3::new(x, y, 0.0));
        }
    }
    let mut t = Vec::new();
    for j in 0..3u32 {
        for i in 0..3u32 {
            let a = j * 4 + i;
            t.push([a, a + 1, a + 5]);
            t.push([a, a + 5, a + 4]);
        }
    }
    (p, t)
}

#[test]
fn uv_origin_is_the_same_image_pixel_for_gltf_and_obj() {
    let dir = temp_dir("uv-origin");
    let map_path = dir.join("asym.png");
    let texels = write_asymmetric_png(&map_path);
    let map = load_height_map(&map_path, &MapOptions::default()).unwrap();
    assert_eq!(
        map.data[0], texels[0][0],
        "row 0 of the map is the image's top row"
    );

    let (positions, tris) = uv_grid();
    // OBJ: vt = (x, y), v up.
    let mut obj = String::new();
    for p in &positions {
        obj += &format!("v {} {} 0\nvt {} {}\n", p.x, p.y, p.x, p.y);
    }
    for t in &tris {
        let [a, b, c] = t.map(|i| i + 1);
        obj += &format!("f {a}/{a} {b}/{b} {c}/{c}\n");
    }
    let obj_path = dir.join("quad.obj");
    std::fs::write(&obj_path, obj).unwrap();
    let from_obj = load_mesh(&obj_path, &MeshOptions::default()).unwrap();

    // glTF: the exporter writes v down the image, v_gltf = 1 - y.
    let mut doc = GltfDoc::default();
    let pos: Vec<f32> = positions.iter().flat_map(|p| p.to_array()).collect();
    let uv: Vec<f32> = positions.iter().flat_map(|p| [p.x, 1.0 - p.y]).collect();
    let idx: Vec<u16> = tris.iter().flatten().map(|&i| i as u16).collect();
    let (a_pos, a_uv, a_idx) = (doc.floats(&pos, 3), doc.floats(&uv, 2), doc.indices(&idx));
    let rest = single_node_scene(
        json!({}),
        json!({"attributes": {"POSITION": a_pos, "TEXCOORD_0": a_uv}, "indices": a_idx}),
    );
    let from_gltf = load_gltf_doc(&dir, "quad.gltf", &doc, &rest, &MeshOptions::default()).unwrap();

    for mesh in [&from_obj, &from_gltf] {
        assert!(!mesh.missing_uvs);
        let mut checked = 0;
        for (i, p) in mesh.positions.iter().enumerate() {
            let on_centre = |c: f32| c == 0.25 || c == 0.75;
            if !(on_centre(p.x) && on_centre(p.y)) {
                continue;
            }
            // v up: y = 3/4 is the top image row.
            let (col, row) = ((p.x * 2.0) as usize, ((1.0 - p.y) * 2.0) as usize);
            assert_eq!(
                map.sample(mesh.uvs[i]),
                texels[row][col],
                "{}: vertex at {p} must sample texel ({col}, {row})",
                mesh.source.display()
            );
            checked += 1;
        }
        assert_eq!(checked, 4);
        // The literal that pins the convention: upper-left quarter of the quad = top-left texel.
        let i = mesh
            .positions
            .iter()
            .position(|p| *p == Vec3::new(0.25, 0.75, 0.0))
            .unwrap();
        assert_eq!(mesh.uvs[i], Vec2::new(0.25, 0.75));
        assert_eq!(map.sample(mesh.uvs[i]), 10.0 / 255.0);
    }
    // Same pixel, same (u, v): vertex by vertex, matched by position.
    for (p, uv) in from_gltf.positions.iter().zip(&from_gltf.uvs) {
        let j = from_obj.positions.iter().position(|q| q == p).unwrap();
        assert!(
            (from_obj.uvs[j] - *uv).length() < 1e-6,
            "at {p}: {uv} vs {}",
            from_obj.uvs[j]
        );
    }
}

// ---------------------------------------------------------------------------------------------
// 2. glTF scene graph, winding, attributes

/// `TRI` facing +Z in `doc`: its POSITION, NORMAL and index accessors.
fn flat_triangle(doc: &mut GltfDoc) -> (usize, usize, usize) {
    let normals = [0.0, 0.0, 1.0].repeat(3);
    (
        doc.floats(&TRI, 3),
        doc.floats(&normals, 3),
        doc.indices(&[0, 1, 2]),
    )
}

#[test]
fn gltf_parent_translation_and_child_scale_are_applied() {
    let dir = temp_dir("gltf-hierarchy");
    let mut doc = GltfDoc::default();
    let (a_pos, a_n, a_idx) = flat_triangle(&mut doc);
    let rest = json!({
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"name": "parent", "translation": [10.0, 0.0, 0.0], "children": [1]},
            {"scale": [2.0, 2.0, 2.0], "mesh": 0},
        ],
        "meshes": [{"name": "Tri", "primitives": [
            {"attributes": {"POSITION": a_pos, "NORMAL": a_n}, "indices": a_idx}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 1.0, 1.0]}}],
    });
    let m = load_gltf_doc(&dir, "tree.gltf", &doc, &rest, &MeshOptions::default()).unwrap();
    assert_eq!(
        m.positions,
        vec![
            Vec3::new(10., 0., 0.),
            Vec3::new(12., 0., 0.),
            Vec3::new(10., 2., 0.)
        ]
    );
    assert!(
        m.normals.iter().all(|&n| approx(n, Vec3::Z)),
        "{:?}",
        m.normals
    );
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
    assert_eq!(m.groups, vec!["node #1/Tri/0".to_string()]);
    assert_eq!(
        (m.face_group.clone(), m.face_flags.clone()),
        (vec![0], vec![0])
    );
    assert_eq!(m.materials[0].base_color, [0.5, 0.25, 1.0, 1.0]);
    // The primitive names no material: the slot after the file's.
    assert_eq!((m.group_material.clone(), m.face_material(0)), (vec![1], 1));
    assert_eq!(m.up_axis, Some(crate::mesh::UpAxis::Y));
    assert!(m.missing_uvs, "no TEXCOORD at all: flagged, not an error");
    assert!(m.uvs.iter().all(|&uv| uv == Vec2::ZERO));
}

#[test]
fn gltf_materials_per_primitive_and_their_textures_are_recorded() {
    let dir = temp_dir("gltf-texture");
    let mut doc = GltfDoc::default();
    let (a_pos, a_n, a_idx) = flat_triangle(&mut doc);
    let rest = json!({
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": a_pos, "NORMAL": a_n}, "indices": a_idx, "material": 1},
            {"attributes": {"POSITION": a_pos, "NORMAL": a_n}, "indices": a_idx},
            {"attributes": {"POSITION": a_pos, "NORMAL": a_n}, "indices": a_idx, "material": 0}]}],
        "materials": [
            {"name": "paint", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.8, 0.7, 1.0],
                                      "baseColorTexture": {"index": 0}},
             "emissiveFactor": [1.0, 0.5, 0.25], "emissiveTexture": {"index": 0},
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}},
            {"pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.2, 0.3, 1.0],
                                      "roughnessFactor": 0.25, "metallicFactor": 0.5,
                                      "metallicRoughnessTexture": {"index": 1}},
             "normalTexture": {"index": 2, "scale": 0.5, "extensions":
                 {"KHR_texture_transform": {"offset": [0.5, 0.0], "texCoord": 0}}},
             "extensions": {"KHR_materials_ior": {"ior": 2.0},
                            "KHR_materials_specular": {"specularFactor": 0.5,
                                                       "specularColorFactor": [1.0, 0.5, 0.2]},
                            "KHR_materials_clearcoat": {"clearcoatFactor": 0.75,
                                                        "clearcoatRoughnessFactor": 0.125,
                                                        "clearcoatTexture": {"index": 1},
                                                        "clearcoatRoughnessTexture": {"index": 1,
                                                            "extensions": {"KHR_texture_transform": {"scale": [2.0, 2.0]}}},
                                                        "clearcoatNormalTexture": {"index": 2, "scale": 0.5}}}},
        ],
        "textures": [{"source": 0, "sampler": 0}, {"source": 1}, {"source": 2}],
        "samplers": [{"magFilter": 9728, "wrapS": 33648, "wrapT": 33071}],
        "images": [{"uri": "my%20albedo.png"}, {"uri": "orm.png"}, {"uri": "normal.png"}],
    });
    let m = load_gltf_doc(&dir, "textured.gltf", &doc, &rest, &MeshOptions::default()).unwrap();
    // One group per primitive, each with its material (2: none, the slot after the file's).
    assert_eq!(m.group_material, vec![1, 2, 0]);
    let per_face: Vec<u32> = (0..3).map(|t| m.face_material(t)).collect();
    assert_eq!(per_face, vec![1, 2, 0]);
    assert_eq!(m.materials.len(), 2);
    let (paint, other) = (&m.materials[0], &m.materials[1]);
    assert_eq!(
        (paint.name.as_str(), other.name.as_str()),
        ("paint", "material 1")
    );
    assert_eq!(paint.base_color, [0.9, 0.8, 0.7, 1.0]);
    // Factors the file leaves out are 1, as glTF says.
    assert_eq!((paint.roughness, paint.metallic), (1.0, 1.0));
    assert_eq!((other.roughness, other.metallic), (0.25, 0.5));
    assert_eq!(other.base_color_texture, None);
    let t = paint.base_color_texture.clone().unwrap();
    assert_eq!(t.name, "my%20albedo.png");
    // A file next to the asset, its URI percent-decoded; the sampler as the file gives it.
    assert_eq!(t.data, TextureData::File(dir.join("my albedo.png")));
    assert_eq!(
        t.sampler,
        Sampler {
            wrap: [TexWrap::Mirror, TexWrap::Clamp],
            nearest: true
        }
    );
    assert_eq!((t.tex_coord, t.transform), (0, UvTransform::IDENTITY));
    // A colour texture is sRGB; the metallic-roughness texture is data, its green the
    // roughness and its blue the metallic, each times its factor.
    assert_eq!(t.color_space, crate::texture::ColorSpace::Srgb);
    assert_eq!(
        (
            paint.roughness_texture.clone(),
            paint.metallic_texture.clone()
        ),
        (None, None)
    );
    let (r, mt) = (
        other.roughness_texture.clone().unwrap(),
        other.metallic_texture.clone().unwrap(),
    );
    assert_eq!((r.channel, mt.channel), (1, 2));
    assert_eq!(r.texture, mt.texture);
    assert_eq!(r.texture.name, "orm.png");
    assert_eq!(r.texture.data, TextureData::File(dir.join("orm.png")));
    assert_eq!(r.texture.color_space, crate::texture::ColorSpace::Raw);
    // The normal map: data, its scale the Normal Map Strength (as Blender's importer reads
    // it), its own KHR_texture_transform (which gltf 1.4 leaves in the JSON).
    let n = other.normal_texture.clone().unwrap();
    assert_eq!(n.texture.data, TextureData::File(dir.join("normal.png")));
    assert_eq!(n.texture.color_space, crate::texture::ColorSpace::Raw);
    assert_eq!((n.scale, n.bias, n.strength), ([2.0; 3], [-1.0; 3], 0.5));
    assert_eq!(
        n.texture.transform,
        UvTransform::gltf([0.5, 0.0], 0.0, [1.0, 1.0])
    );
    assert_eq!(paint.normal_texture, None);
    // Emission: the factor times the strength, and its (sRGB) texture.
    assert_eq!(paint.emission, [4.0, 2.0, 1.0]);
    assert_eq!(paint.emission_texture.as_ref(), Some(&t));
    assert_eq!(
        (other.emission, other.emission_texture.clone()),
        ([0.0; 3], None)
    );
    // The dielectric reflectance: F0 of IOR 2 (1/9) times the specular factor; none given.
    assert!(
        (other.specular.unwrap() - 0.5 / 9.0).abs() < 1e-7,
        "{:?}",
        other.specular
    );
    assert_eq!(paint.specular, None);
    // The specular colour is the tint (Blender's Specular Tint); none is white.
    assert_eq!(other.specular_tint, Some([1.0, 0.5, 0.2]));
    assert_eq!(paint.specular_tint, None);
    // KHR_materials_clearcoat's factors (the crate has no accessor: read from its JSON).
    assert_eq!((other.clearcoat, other.clearcoat_roughness), (0.75, 0.125));
    assert_eq!((paint.clearcoat, paint.clearcoat_roughness), (0.0, 0.0));
    // Its textures: the weight in the red channel, the roughness in the green, each data
    // with its own KHR_texture_transform.
    let (cw, cr) = (
        other.clearcoat_texture.clone().unwrap(),
        other.clearcoat_roughness_texture.clone().unwrap(),
    );
    assert_eq!((cw.channel, cr.channel), (0, 1));
    assert_eq!(cw.texture.data, TextureData::File(dir.join("orm.png")));
    assert_eq!(cw.texture.color_space, crate::texture::ColorSpace::Raw);
    assert_eq!(cw.texture.transform, UvTransform::IDENTITY);
    assert_eq!(
        cr.texture.transform,
        UvTransform::gltf([0.0, 0.0], 0.0, [2.0, 2.0])
    );
    assert_eq!(paint.clearcoat_texture, None);
    // Its normal map: data, its scale (a normalTextureInfo's) the strength.
    let cn = other.clearcoat_normal_texture.clone().unwrap();
    assert_eq!(cn.texture.data, TextureData::File(dir.join("normal.png")));
    assert_eq!((cn.scale, cn.bias, cn.strength), ([2.0; 3], [-1.0; 3], 0.5));
    assert_eq!(paint.clearcoat_normal_texture, None);
    assert_eq!(
        other.texture_uses().len(),
        4,
        "one image, three inputs (roughness, metallic, clearcoat); the same image scaled (the \
         clearcoat's roughness); the normal map, offset; the same image as the clearcoat's"
    );
    use crate::render::lookdev::material_warning;
    // Read through UV set 0: nothing to say.
    assert_eq!(material_warning(&m, 0, &|_| true), None);
    // Loaded with another UV set than the texture's: not read, and said so.
    let w = material_warning(&m, 1, &|_| true).unwrap();
    for part in [
        "material 'paint'",
        "(my%20albedo.png) reads TEXCOORD_0",
        "UV set 1",
        "(0.9, 0.8, 0.7)",
        "uv_set = 0",
        "--base-color",
        // The metallic-roughness texture, also the clearcoat's: one note for its inputs, their
        // factors, their flags.
        "material 'material 1': its roughness and metallic and clearcoat texture (orm.png) \
         reads TEXCOORD_0",
        "roughness factor 0.25 and metallic factor 0.5 and clearcoat factor 0.75",
        "--roughness R, --metallic M, --clearcoat W",
        "its clearcoat-roughness texture (orm.png)",
        "clearcoat roughness factor 0.125",
    ] {
        assert!(w.contains(part), "no '{part}' in: {w}");
    }
}

/// A clearcoat texture the gltf crate does not validate (it reads no KHR_materials_clearcoat):
/// an index past the file's textures, or a textureInfo that is not one, is an error naming
/// the material, the input and the flags that override it; never a panic.
#[test]
fn a_gltf_clearcoat_texture_past_the_files_textures_is_an_error() {
    let dir = temp_dir("gltf-clearcoat-texture");
    for (name, info, needle) in [
        (
            "past",
            json!({"index": 3}),
            "names texture #3, past the file's textures",
        ),
        ("malformed", json!({"texCoord": 0}), "is malformed"),
        (
            "scale",
            json!({"index": 0, "scale": "big"}),
            "has a scale that is not a number",
        ),
    ] {
        let mut doc = GltfDoc::default();
        let (a_pos, a_n, a_idx) = flat_triangle(&mut doc);
        let mut rest = single_node_scene(
            json!({}),
            json!({"attributes": {"POSITION": a_pos, "NORMAL": a_n}, "indices": a_idx,
                   "material": 0}),
        );
        rest["materials"] = json!([{"name": "lacquer",
            "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0,
                                                        "clearcoatRoughnessTexture": info}}}]);
        let e = load_gltf_doc(
            &dir,
            &format!("{name}.gltf"),
            &doc,
            &rest,
            &MeshOptions::default(),
        )
        .unwrap_err()
        .to_string();
        for part in [
            &format!("{name}.gltf"),
            "material 'lacquer'",
            "clearcoatRoughnessTexture",
            needle,
            "--clearcoat-roughness",
        ] {
            assert!(e.contains(part), "no '{part}' in: {e}");
        }
    }
}

#[test]
fn gltf_texture_in_a_data_uri_with_a_transform_is_decoded_and_transformed() {
    let dir = temp_dir("gltf-texture-data");
    let mut png = Vec::new();
    ::image::RgbImage::from_pixel(2, 1, ::image::Rgb([255, 255, 0]))
        .write_to(
            &mut std::io::Cursor::new(&mut png),
            ::image::ImageFormat::Png,
        )
        .unwrap();
    let mut doc = GltfDoc::default();
    let (a_pos, a_n, a_idx) = flat_triangle(&mut doc);
    let rest = json!({
        "extensionsUsed": ["KHR_texture_transform"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": a_pos, "NORMAL": a_n}, "indices": a_idx, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {
            "index": 0, "extensions": {"KHR_texture_transform": {
                "offset": [0.25, 0.5], "rotation": 0.5, "scale": [2.0, 3.0], "texCoord": 1}}}}}],
        "textures": [{"source": 0}],
        "images": [{"uri": format!("data:image/png;base64,{}", base64(&png))}],
    });
    let m = load_gltf_doc(&dir, "data.gltf", &doc, &rest, &MeshOptions::default()).unwrap();
    let t = m.materials[0].base_color_texture.clone().unwrap();
    assert_eq!(t.name, "image 0");
    assert_eq!(t.data, TextureData::Embedded(png));
    assert_eq!(t.sampler, Sampler::default());
    // The extension's transform, and its texCoord in place of the textureInfo's.
    assert_eq!(t.transform, UvTransform::gltf([0.25, 0.5], 0.5, [2.0, 3.0]));
    assert_eq!(t.tex_coord, 1);
    let c = crate::texture::ColorMap::load(&m.source, &t, crate::texture::TextureSlot::BaseColor)
        .unwrap();
    assert_eq!(c.texels, vec![glam::Vec3::new(1.0, 1.0, 0.0); 2]);
    assert_eq!(c.transform, t.transform);
    // Loaded with UV set 0, the texture (now on set 1) is not read, and said so.
    let w = crate::render::lookdev::material_warning(&m, 0, &|_| true).unwrap();
    assert!(
        w.contains("reads TEXCOORD_1") && w.contains("(image 0)"),
        "{w}"
    );
}

#[test]
fn gltf_mirroring_scale_flips_winding_to_keep_normals_outward() {
    let dir = temp_dir("gltf-mirror");
    let mut doc = GltfDoc::default();
    let s = std::f32::consts::FRAC_1_SQRT_2;
    // Tilted normals show the inverse-transpose: x is mirrored with the geometry.
    let normals = [s, 0.0, s].repeat(3);
    let (a_pos, a_n) = (doc.floats(&TRI, 3), doc.floats(&normals, 3));
    let rest = single_node_scene(
        json!({"name": "mirror", "scale": [-1.0, 1.0, 1.0]}),
        json!({"attributes": {"POSITION": a_pos, "NORMAL": a_n}}), // non-indexed
    );
    let m = load_gltf_doc(&dir, "mirror.gltf", &doc, &rest, &MeshOptions::default()).unwrap();
    assert_eq!(m.triangle_count(), 1);
    assert!(
        m.face_cross(0).dot(Vec3::Z) > 0.0,
        "winding flipped back to face +Z"
    );
    for n in &m.normals {
        assert!(approx(*n, Vec3::new(-s, 0.0, s)), "{n}");
        assert!(
            m.face_cross(0).dot(*n) > 0.0,
            "geometric and vertex normals agree"
        );
    }
    assert_eq!(m.groups, vec!["mirror/Tri/0".to_string()]);
}

#[test]
fn gltf_without_normals_gets_angle_weighted_ones() {
    let dir = temp_dir("gltf-normals");
    let mut doc = GltfDoc::default();
    let a_pos = doc.floats(&TRI, 3);
    let rest = single_node_scene(json!({}), json!({"attributes": {"POSITION": a_pos}}));
    let m = load_gltf_doc(&dir, "bare.gltf", &doc, &rest, &MeshOptions::default()).unwrap();
    assert!(
        m.normals.iter().all(|&n| approx(n, Vec3::Z)),
        "{:?}",
        m.normals
    );
}

#[test]
fn gltf_uv_set_selects_texcoord_n_and_names_the_sets_when_missing() {
    let dir = temp_dir("gltf-uvset");
    let mut doc = GltfDoc::default();
    let a_pos = doc.floats(&TRI, 3);
    let a_uv0 = doc.floats(&[0.0; 6], 2);
    let a_uv1 = doc.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 0.25], 2);
    let rest = single_node_scene(
        json!({}),
        json!({"attributes": {"POSITION": a_pos, "TEXCOORD_0": a_uv0, "TEXCOORD_1": a_uv1}}),
    );
    let m = load_gltf_doc(
        &dir,
        "two-sets.gltf",
        &doc,
        &rest,
        &MeshOptions { uv_set: 1 },
    )
    .unwrap();
    // v flipped: v = 1 - v_gltf.
    assert_eq!(
        m.uvs,
        vec![Vec2::new(0., 1.), Vec2::new(1., 1.), Vec2::new(0., 0.75)]
    );
    assert!(!m.missing_uvs);
    let path = dir.join("two-sets.gltf");
    let msg = err_naming_file(load_mesh(&path, &MeshOptions { uv_set: 2 }), &path);
    assert!(
        msg.contains("TEXCOORD_2") && msg.contains("TEXCOORD_0, TEXCOORD_1"),
        "{msg}"
    );
}

#[test]
fn gltf_glb_and_external_bin_load_like_the_embedded_form() {
    let dir = temp_dir("gltf-forms");
    let mut doc = GltfDoc::default();
    let a_pos = doc.floats(&TRI, 3);
    let rest = single_node_scene(
        json!({"name": "n"}),
        json!({"attributes": {"POSITION": a_pos}}),
    );
    let embedded = load_gltf_doc(&dir, "a.gltf", &doc, &rest, &MeshOptions::default()).unwrap();

    let glb_path = dir.join("a.glb");
    std::fs::write(&glb_path, doc.glb(&rest)).unwrap();
    let glb = load_mesh(&glb_path, &MeshOptions::default()).unwrap();

    let ext_path = dir.join("ext.gltf");
    std::fs::write(dir.join("ext data.bin"), &doc.bin).unwrap();
    let json = doc.json(&rest, Some("ext%20data.bin".into()));
    std::fs::write(&ext_path, json.to_string()).unwrap();
    let external = load_mesh(&ext_path, &MeshOptions::default()).unwrap();

    for m in [&glb, &external] {
        assert_eq!(m.positions, embedded.positions);
        assert_eq!(m.triangles, embedded.triangles);
        assert_eq!(m.groups, embedded.groups);
    }
    std::fs::remove_file(dir.join("ext data.bin")).unwrap();
    let msg = err_naming_file(load_mesh(&ext_path, &MeshOptions::default()), &ext_path);
    assert!(msg.contains("ext data.bin"), "{msg}");
    // A device is refused, not read forever.
    let dev = dir.join("dev.gltf");
    std::fs::write(&dev, doc.json(&rest, Some("/dev/zero".into())).to_string()).unwrap();
    let msg = err_naming_file(load_mesh(&dev, &MeshOptions::default()), &dev);
    assert!(
        msg.contains("/dev/zero") && msg.contains("regular file"),
        "{msg}"
    );
}

#[test]
fn gltf_skips_points_and_converts_strips_and_fans() {
    let dir = temp_dir("gltf-modes");
    let mut doc = GltfDoc::default();
    // Four vertices of the unit square, counter-clockwise from +Z in strip order.
    let strip = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0];
    let fan = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0];
    let (a_strip, a_fan, a_pts) = (
        doc.floats(&strip, 3),
        doc.floats(&fan, 3),
        doc.floats(&TRI, 3),
    );
    let rest = json!({
        "scenes": [{"nodes": [0]}], // no default scene: every scene's roots
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": a_strip}, "mode": 5},
            {"attributes": {"POSITION": a_fan}, "mode": 6},
            {"attributes": {"POSITION": a_pts}, "mode": 0},
        ]}],
    });
    let m = load_gltf_doc(&dir, "modes.gltf", &doc, &rest, &MeshOptions::default()).unwrap();
    assert_eq!(m.triangle_count(), 4);
    assert_eq!(
        m.groups,
        vec![
            "node #0/mesh #0/0".to_string(),
            "node #0/mesh #0/1".to_string()
        ]
    );
    for t in 0..4 {
        assert!(
            m.face_cross(t).dot(Vec3::Z) > 0.0,
            "triangle {t} keeps its winding"
        );
    }
}

#[test]
fn gltf_perspective_camera_becomes_the_scene_camera() {
    let dir = temp_dir("gltf-camera");
    let mut doc = GltfDoc::default();
    let a_pos = doc.floats(&TRI, 3);
    let rest = json!({
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0.0, 0.0, 5.0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": a_pos}}]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}}],
    });
    let m = load_gltf_doc(&dir, "cam.gltf", &doc, &rest, &MeshOptions::default()).unwrap();
    let cam = m.pick_camera(None).unwrap().expect("camera");
    assert!(approx(cam.from, Vec3::new(0.0, 0.0, 5.0)));
    // Bounds centre (0.5, 0.5, 0) projected on the -Z view axis: 5 units ahead.
    assert!(approx(cam.to, Vec3::ZERO), "{}", cam.to);
    assert!(approx(cam.up, Vec3::Y));
    assert_eq!(
        cam.projection,
        Projection::Perspective {
            yfov_deg: 0.5f32.to_degrees()
        }
    );
    assert_eq!(
        m.cameras[0].names,
        ["node #1"],
        "an unnamed node and camera"
    );
}

/// Every camera is kept, in the order the scene's nodes are visited, under its node's name,
/// `node #N` and its camera's name; `--camera` picks any of them by one of those, the first is
/// the default, and a name that is missing or shared is an error listing them. An
/// orthographic camera's view spans twice the larger of its `xmag` and `ymag` across the
/// image's larger side, scaled with its node, as Blender imports it (ortho scale 2 max(xmag,
/// ymag), sensor fit Auto; checked with bpy 5.0.1): 6 units square, 6 × 3 in a 2:1 image,
/// 3 × 6 in a 1:2 one. A perspective camera keeps its vertical field of view.
#[test]
fn gltf_cameras_are_picked_by_node_or_camera_name() {
    let dir = temp_dir("gltf-cameras");
    let mut doc = GltfDoc::default();
    let a_pos = doc.floats(&TRI, 3);
    let rest = json!({
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2, 3, 4]}],
        "nodes": [
            {"mesh": 0},
            {"name": "Wide", "camera": 0, "translation": [0.0, 0.0, 5.0]},
            {"name": "Close", "camera": 1, "translation": [0.0, 0.0, 2.0]},
            {"name": "Top", "camera": 2, "translation": [0.0, 0.0, 9.0], "scale": [3.0, 3.0, 3.0]},
            {"name": "Close", "camera": 0, "translation": [0.0, 0.0, 3.0]},
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": a_pos}}]}],
        "cameras": [
            {"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}},
            {"name": "macro", "type": "perspective", "perspective": {"yfov": 0.2, "znear": 0.1}},
            {"type": "orthographic", "orthographic": {"xmag": 1.0, "ymag": 0.75, "znear": 0.1, "zfar": 10.0}},
        ],
    });
    let m = load_gltf_doc(&dir, "cams.gltf", &doc, &rest, &MeshOptions::default()).unwrap();
    let names: Vec<&str> = m.cameras.iter().map(|c| c.names[0].as_str()).collect();
    assert_eq!(names, ["Wide", "Close", "Top", "Close"]);
    let top = m.pick_camera(Some("Top")).unwrap().expect("Top");
    assert_eq!(top.projection, Projection::Orthographic { height: 6.0 });
    assert!(top.larger_side);
    let tall =
        |aspect: f32| match crate::render::camera::Camera::from_scene(&top, aspect).projection {
            Projection::Orthographic { height } => height,
            p => panic!("{p:?}"),
        };
    assert_eq!((tall(1.0), tall(2.0), tall(0.5)), (6.0, 3.0, 6.0));
    let wide = m.pick_camera(Some("Wide")).unwrap().expect("Wide");
    assert!(!wide.larger_side);
    assert_eq!(
        crate::render::camera::Camera::from_scene(&wide, 2.0).projection,
        Projection::Perspective {
            yfov_deg: 0.5f32.to_degrees()
        }
    );
    let z = |name: Option<&str>| m.pick_camera(name).map(|c| c.expect("a camera").from.z);
    assert_eq!(z(None).unwrap(), 5.0, "the first is the default");
    assert_eq!(z(Some("Wide")).unwrap(), 5.0);
    assert_eq!(z(Some("macro")).unwrap(), 2.0, "by the camera's own name");
    assert_eq!(z(Some("node #4")).unwrap(), 3.0, "by the node's index");
    let shared = z(Some("Close")).unwrap_err().to_string();
    assert!(
        shared.contains("cams.gltf") && shared.contains("2 cameras named 'Close'"),
        "{shared}"
    );
    assert!(
        shared.contains("'node #2'") && shared.contains("'node #4'"),
        "{shared}"
    );
    let missing = z(Some("Side")).unwrap_err().to_string();
    assert!(
        missing.contains("no camera named 'Side'")
            && missing.contains("its cameras: 'Wide', 'Close', 'Top', 'Close'"),
        "{missing}"
    );
}

/// A `KHR_lights_punctual` directional light is the key light: towards its node's +Z (turned
/// 45° up: elevation 45°, azimuth 0, toward +Z), lux / 683 as Blender imports it, times its
/// colour's luminance, in its colour (of unit luminance). A point light before it and a second
/// directional light light beside it (candela or lux over 683, at the node's origin or towards
/// its +Z); a spot shines down its node's −Z within its cone; a light of an unknown type is an
/// error, not a panic.
#[test]
fn a_gltf_directional_light_is_the_key_light() {
    let dir = temp_dir("gltf-light");
    let lights = |types: [&str; 3]| {
        let mut doc = GltfDoc::default();
        let a_pos = doc.floats(&TRI, 3);
        let light = |t: &str, i: f32| match t {
            "spot" => json!({"type": t, "intensity": i, "color": [1.0, 0.5, 0.25],
                             "spot": {"innerConeAngle": 0.25, "outerConeAngle": 0.5}}),
            _ => json!({"type": t, "intensity": i, "color": [1.0, 0.5, 0.25]}),
        };
        let rest = json!({
            "extensionsUsed": ["KHR_lights_punctual"],
            "extensions": {"KHR_lights_punctual": {"lights": [
                light(types[0], 10.0), light(types[1], 1366.0), light(types[2], 5.0),
            ]}},
            "scene": 0,
            "scenes": [{"nodes": [0, 1, 2, 3]}],
            "nodes": [
                {"mesh": 0},
                {"name": "Bulb", "extensions": {"KHR_lights_punctual": {"light": 0}}},
                {"name": "Sun", "rotation": [-0.38268343, 0.0, 0.0, 0.92387953],
                 "extensions": {"KHR_lights_punctual": {"light": 1}}},
                {"name": "Moon", "extensions": {"KHR_lights_punctual": {"light": 2}}},
            ],
            "meshes": [{"primitives": [{"attributes": {"POSITION": a_pos}}]}],
        });
        load_gltf_doc(&dir, "lights.gltf", &doc, &rest, &MeshOptions::default())
    };
    let m = lights(["point", "directional", "directional"]).unwrap();
    let sun = m.sun.expect("the key light");
    assert_eq!(sun.name, "Sun");
    let [az, el, irradiance] = sun.key;
    assert!(az.abs() < 1e-3 && (el - 45.0).abs() < 1e-3, "{:?}", sun.key);
    let luminance = 0.2126 + 0.7152 * 0.5 + 0.0722 * 0.25;
    assert!((irradiance - 2.0 * luminance).abs() < 1e-5, "{irradiance}");
    let want = [1.0, 0.5, 0.25].map(|c| c / luminance);
    assert!(
        (0..3).all(|i| (sun.color[i] - want[i]).abs() < 1e-5),
        "{:?}",
        sun.color
    );
    use crate::render::lights::LightShape;
    let names: Vec<&str> = m.lights.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, ["Bulb", "Moon"]);
    let [bulb, moon] = [&m.lights[0].light, &m.lights[1].light];
    assert!(
        matches!(bulb.shape, LightShape::Local { pos, radius: 0.0, spot: None } if pos == Vec3::ZERO)
    );
    assert!(
        (bulb.power - 10.0 / 683.0 * luminance).abs() < 1e-6,
        "{bulb:?}"
    );
    assert!(
        matches!(moon.shape, LightShape::Distant { dir, .. } if (dir - Vec3::Z).length() < 1e-6)
    );
    assert!(
        (moon.power - 5.0 / 683.0 * luminance).abs() < 1e-6,
        "{moon:?}"
    );
    let m = lights(["spot", "directional", "directional"]).unwrap();
    let LightShape::Local {
        spot: Some(spot), ..
    } = m.lights[0].light.shape
    else {
        panic!("{:?}", m.lights[0])
    };
    assert!((spot.axis - Vec3::NEG_Z).length() < 1e-6, "{spot:?}");
    assert!(
        (spot.cos_inner - (0.5f32.cos() + 0.5 * (1.0 - 0.5f32.cos()))).abs() < 1e-6
            && (spot.cos_outer - 0.5f32.cos()).abs() < 1e-6
    );
    let e = lights(["point", "flashlight", "directional"])
        .unwrap_err()
        .to_string();
    assert!(e.contains("lights.gltf"), "{e}");
}

/// A camera `--fov` would refuse (a yfov of 0 sends every ray one way, a negative one turns
/// the picture over, one past 179° folds it), an orthographic one of no or negative height,
/// or one placed at an infinite position is left out, with a warning, and the view is framed
/// from the bounds; the mesh still loads.
#[test]
fn a_gltf_camera_that_cannot_be_rendered_through_is_left_out() {
    let dir = temp_dir("gltf-bad-camera");
    for (xmag, ymag) in [(1.0, 0.0), (1.0, -1.0), (0.0, 1.0), (-2.0, 1.0)] {
        let mut doc = GltfDoc::default();
        let a_pos = doc.floats(&TRI, 3);
        let rest = json!({
            "scene": 0,
            "scenes": [{"nodes": [0, 1]}],
            "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0.0, 0.0, 5.0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": a_pos}}]}],
            "cameras": [{"type": "orthographic", "orthographic": {"xmag": xmag, "ymag": ymag, "znear": 0.1, "zfar": 10.0}}],
        });
        let m = load_gltf_doc(&dir, "ortho.gltf", &doc, &rest, &MeshOptions::default()).unwrap();
        assert!(
            m.cameras.is_empty(),
            "xmag {xmag}, ymag {ymag}: {:?}",
            m.cameras
        );
    }
    for (i, (yfov, z)) in [(0.0, 5.0), (-0.5, 5.0), (3.2, 5.0), (0.5, 1e39)]
        .into_iter()
        .enumerate()
    {
        let mut doc = GltfDoc::default();
        let a_pos = doc.floats(&TRI, 3);
        let rest = json!({
            "scene": 0,
            "scenes": [{"nodes": [0, 1]}],
            "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0.0, 0.0, z]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": a_pos}}]}],
            "cameras": [{"type": "perspective", "perspective": {"yfov": yfov, "znear": 0.1}}],
        });
        let name = format!("cam{i}.gltf");
        let m = load_gltf_doc(&dir, &name, &doc, &rest, &MeshOptions::default()).unwrap();
        assert!(m.cameras.is_empty(), "yfov {yfov}, z {z}: {:?}", m.cameras);
    }
}

// ---------------------------------------------------------------------------------------------
// 3. OBJ

#[test]
fn obj_quads_are_triangulated_and_groups_kept() {
    let dir = temp_dir("obj-groups");
    let path = dir.join("two.obj");
    let obj = "# two groups\n\
        v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
        v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
        g first\nf 1 2 3 4\n\
        g second\nf 5 6 7 8\nf -3 -2 -1\n";
    std::fs::write(&path, obj).unwrap();
    let m = load_mesh(&path, &MeshOptions::default()).unwrap();
    assert_eq!(m.triangle_count(), 5);
    assert_eq!(m.groups, vec!["first".to_string(), "second".to_string()]);
    assert_eq!(m.face_group, vec![0, 0, 1, 1, 1]);
    assert_eq!(m.face_flags, vec![0; 5]);
    assert!(m.missing_uvs, "no vt: flagged, not an error");
    assert!(
        m.normals.iter().all(|&n| approx(n, Vec3::Z)),
        "generated from CCW faces"
    );
    assert_eq!(m.up_axis, Some(crate::mesh::UpAxis::Y));
}

#[test]
fn obj_materials_come_from_the_mtllib_per_usemtl() {
    let dir = temp_dir("obj-mtl");
    let path = dir.join("m.obj");
    // A device (never-ending) is skipped like a missing file.
    let obj = "mtllib m.mtl missing.mtl /dev/zero\n\
        v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
        f 1 2 3\n\
        g body\nusemtl paint\nf 1 2 3\n\
        usemtl rust metal\nf 1 3 4\n\
        usemtl nowhere\nf 1 2 4\n\
        usemtl paint\nf 2 3 4\n";
    let mtl = "# two materials\n\
        newmtl paint\nKd 0.5 0.25 0.125\nKe 0.1 0.2 0.3\nNi 2\nNs 250\nPr 0.3\nPc 0.6\nPcr 0.2\nKs 0.25\n\
        newmtl rust metal\nKd 0.2 0.2 0.2\nPm 0.5\nmap_Kd -clamp on -s 2 2 1 tex/rust.png\n\
        map_Pr -o 0.5 rough.png\nmap_Pm -imfchan b orm.png\nmap_Bump -bm 0.5 normal.png\nmap_Ke glow.png\n";
    std::fs::write(&path, obj).unwrap();
    std::fs::write(dir.join("m.mtl"), mtl).unwrap();
    let m = load_mesh(&path, &MeshOptions::default()).unwrap();
    // One group per name and material: default (none), body/paint, body/rust, body/nowhere.
    assert_eq!(m.groups, ["default", "body", "body", "body"]);
    assert_eq!(m.face_group, [0, 1, 2, 3, 1]);
    assert_eq!(m.materials.len(), 2);
    let per_face: Vec<u32> = (0..5).map(|t| m.face_material(t)).collect();
    // No usemtl and an undefined name: the default (index 2).
    assert_eq!(per_face, [2, 0, 1, 2, 0]);
    let (paint, rust) = (&m.materials[0], &m.materials[1]);
    assert_eq!(paint.name, "paint");
    assert_eq!(paint.base_color, [0.5, 0.25, 0.125, 1.0]);
    assert_eq!((paint.roughness, paint.metallic), (0.3, 0.0));
    // Pc is four times Blender's Coat Weight.
    assert_eq!((paint.clearcoat, paint.clearcoat_roughness), (0.15, 0.2));
    assert_eq!(paint.base_color_texture, None);
    assert_eq!(rust.name, "rust metal");
    // map_Kd replaces Kd (as Blender's importer does); -clamp on clamps; -s is a transform.
    // So do map_Pr and map_Pm their values (data textures: red unless -imfchan says).
    assert_eq!(
        (rust.base_color, rust.roughness, rust.metallic),
        ([1.0; 4], 1.0, 1.0)
    );
    let t = rust.base_color_texture.as_ref().unwrap();
    assert_eq!(t.name, "tex/rust.png");
    assert_eq!(t.data, TextureData::File(dir.join("tex/rust.png")));
    assert_eq!(t.sampler.wrap, [TexWrap::Clamp; 2]);
    // -s 2 2 1: scaled (w ignored), no offset.
    assert_eq!(
        t.transform,
        UvTransform::scale_offset([2.0, 2.0], [0.0, 0.0])
    );
    assert_eq!(t.color_space, crate::texture::ColorSpace::Srgb);
    let (r, mt) = (
        rust.roughness_texture.as_ref().unwrap(),
        rust.metallic_texture.as_ref().unwrap(),
    );
    assert_eq!((r.texture.name.as_str(), r.channel), ("rough.png", 0));
    assert_eq!((mt.texture.name.as_str(), mt.channel), ("orm.png", 2));
    assert_eq!(r.texture.data, TextureData::File(dir.join("rough.png")));
    assert_eq!(r.texture.color_space, crate::texture::ColorSpace::Raw);
    // -o 0.5: both axes offset by it.
    assert_eq!(
        r.texture.transform,
        UvTransform::scale_offset([1.0; 2], [0.5; 2])
    );
    assert!(mt.texture.transform.is_identity());
    // map_Bump is a tangent-space normal map (Blender's use of it), -bm its strength.
    let n = rust.normal_texture.as_ref().unwrap();
    assert_eq!(n.texture.data, TextureData::File(dir.join("normal.png")));
    assert_eq!(n.texture.color_space, crate::texture::ColorSpace::Raw);
    assert_eq!((n.scale, n.bias, n.strength), ([2.0; 3], [-1.0; 3], 0.5));
    assert_eq!(n.describe_mapping(), "strength 0.5");
    assert_eq!(paint.normal_texture, None);
    // Ni is the index of refraction: F0 1/9 for 2, times twice Ks's mean 0.25.
    assert!((paint.specular.unwrap() - 0.5 / 9.0).abs() < 1e-7);
    // Neither Ks nor illum 2: Blender's Specular IOR Level 0, no specular at all.
    assert_eq!(rust.specular, Some(0.0));
    // Ke is the emission; map_Ke replaces it (an sRGB colour texture).
    assert_eq!(
        (paint.emission, paint.emission_texture.clone()),
        ([0.1, 0.2, 0.3], None)
    );
    let glow = rust.emission_texture.as_ref().unwrap();
    assert_eq!((rust.emission, glow.name.as_str()), ([1.0; 3], "glow.png"));
    assert_eq!(glow.color_space, crate::texture::ColorSpace::Srgb);
    // Without any mtllib: no materials, every face the default.
    let bare = dir.join("bare.obj");
    std::fs::write(
        &bare,
        obj.replace("mtllib m.mtl missing.mtl /dev/zero\n", ""),
    )
    .unwrap();
    let b = load_mesh(&bare, &MeshOptions::default()).unwrap();
    assert!(b.materials.is_empty() && (0..5).all(|t| b.face_material(t) == 0));
    // A bad number in the .mtl is an error naming it and its line.
    std::fs::write(dir.join("m.mtl"), "newmtl x\nKd 1 one 1\n").unwrap();
    let e = load_mesh(&path, &MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("m.mtl") && e.contains("line 2") && e.contains("'one'"),
        "{e}"
    );
    // So is a map's -s or -o without its number.
    std::fs::write(dir.join("m.mtl"), "newmtl x\n\nmap_Pr -s rough.png\n").unwrap();
    let e = load_mesh(&path, &MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("m.mtl") && e.contains("line 3") && e.contains("map_Pr -s takes a number"),
        "{e}"
    );
}

/// The classic `.mtl` model (`illum`, `Ka`, `Ks`, `Ns`, `Ni`) and the PBR extension over it
/// resolve as Blender's OBJ importer resolves them; each row's values are what bpy 5.0.1's
/// `wm.obj_import` gave the Principled BSDF (roughness, metallic, IOR, Specular IOR Level),
/// F0 being Cycles' `((n − 1) / (n + 1))² · 2 · level`.
#[test]
fn an_mtls_classic_model_resolves_as_blenders_importer_does() {
    let dir = temp_dir("obj-mtl-classic");
    let f0 = |n: f32, level: f32| ((n - 1.0) / (n + 1.0)).powi(2) * 2.0 * level;
    // (statements, roughness, metallic, F0)
    let rows: &[(&str, f32, f32, f32)] = &[
        ("Kd 0.8 0.2 0.1", 1.0, 0.0, 0.0),
        (
            "Ns 250\nKa 1 1 1\nKs 0.5 0.5 0.5\nNi 1.45\nillum 2",
            0.5,
            0.0,
            f0(1.45, 0.5),
        ),
        (
            "Ns 900\nKs 1 1 1\nillum 2",
            1.0 - 0.9f32.sqrt(),
            0.0,
            f0(1.5, 1.0),
        ),
        ("Ns 10\nKs 0 0 0\nillum 1", 0.9, 0.0, 0.0),
        (
            "Ns 500\nKs 0.2 0.2 0.2\nillum 3",
            1.0 - 0.5f32.sqrt(),
            1.0,
            f0(1.5, 0.2),
        ),
        ("Ka 0.3 0.3 0.3\nillum 3", 1.0, 0.3, 0.0),
        ("Ka 0.3 0.3 0.3\nillum 2", 0.0, 0.0, f0(1.5, 1.0)),
        ("Ns 1500\nKs 2 0.5 0.5", 0.0, 0.0, f0(1.5, 1.0)),
        ("Ns -5\nillum 1", 1.0, 0.0, 0.0),
        ("illum 7\nNi 1.33", 1.0, 1.0, 0.0),
        ("illum 6\nKs 1 1 1", 1.0, 1.0, 0.0),
        ("illum 4\nKs 1 1 1", 1.0, 1.0, f0(1.5, 1.0)),
        ("Ka 0.4 0.5 0.6\nillum 5\nPm 0.1", 1.0, 0.1, 0.0),
        (
            "Ns 1000\nKs 0.5 0.5 0.5\nPr 0.3\nPm 0.7",
            0.3,
            0.7,
            f0(1.5, 0.5),
        ),
        (
            "Ns 100\nillum 0\nKs 1 1 1",
            1.0 - 0.1f32.sqrt(),
            0.0,
            f0(1.5, 1.0),
        ),
        ("Ni 0.5\nKs 0.5 0.5 0.5", 1.0, 0.0, f0(2.0, 0.5)),
        ("Ni 0\nKs 1 1 1", 1.0, 0.0, f0(1.5, 1.0)),
        // In any order; one number is grey (the format's reading: Blender's reads `Ks 0.3`
        // as (0.3, 0.5, 0.5)).
        ("illum 3\nKs 0.3\nNs 360\nKa 0.25", 0.4, 0.25, f0(1.5, 0.3)),
    ];
    let obj: String = (0..rows.len())
        .map(|i| format!("usemtl m{i}\nf 1 2 3\n"))
        .collect();
    let path = dir.join("classic.obj");
    std::fs::write(
        &path,
        format!("mtllib a.mtl b.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n{obj}"),
    )
    .unwrap();
    // The rows over two files; the second's statements before its first newmtl belong to no
    // entry (not to the first file's last).
    let entries: Vec<String> = rows
        .iter()
        .enumerate()
        .map(|(i, (statements, ..))| format!("newmtl m{i}\n{statements}\n"))
        .collect();
    let half = rows.len() / 2;
    std::fs::write(dir.join("a.mtl"), entries[..half].concat()).unwrap();
    std::fs::write(
        dir.join("b.mtl"),
        format!("Ks 1 1 1\nillum 2\n{}", entries[half..].concat()),
    )
    .unwrap();
    let m = load_mesh(&path, &MeshOptions::default()).unwrap();
    assert_eq!(m.materials.len(), rows.len());
    for (material, &(statements, roughness, metallic, specular)) in m.materials.iter().zip(rows) {
        let got = (
            material.roughness,
            material.metallic,
            material.specular.unwrap(),
        );
        assert!(
            (got.0 - roughness).abs() < 1e-6
                && (got.1 - metallic).abs() < 1e-6
                && (got.2 - specular).abs() < 1e-6,
            "{statements:?}: {got:?}, Blender's ({roughness}, {metallic}, {specular})"
        );
    }
    // Two numbers are neither grey nor a colour.
    std::fs::write(dir.join("a.mtl"), "newmtl m0\nKs 0.5 0.5\n").unwrap();
    let e = load_mesh(&path, &MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("a.mtl") && e.contains("line 2") && e.contains("1 or 3 numbers"),
        "{e}"
    );
}

#[test]
fn obj_file_normals_are_read_and_normalised() {
    let dir = temp_dir("obj-normals");
    let path = dir.join("n.obj");
    std::fs::write(
        &path,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 2\nf 1/1/1 2/1/1 3/1/1\n",
    )
    .unwrap();
    let m = load_mesh(&path, &MeshOptions::default()).unwrap();
    assert!(!m.missing_uvs);
    assert_eq!(m.normals, vec![Vec3::Z; 3]);
    assert_eq!(m.groups, vec!["default".to_string()]);
}

// ---------------------------------------------------------------------------------------------
// 4. Height maps

fn write_exr(path: &Path, w: usize, h: usize, channels: Vec<(&str, exr::prelude::FlatSamples)>) {
    use exr::prelude::*;
    let list: Vec<AnyChannel<FlatSamples>> = channels
        .into_iter()
        .map(|(n, s)| AnyChannel::new(n, s))
        .collect();
    Image::from_channels((w, h), AnyChannels::sort(list.into()))
        .write()
        .to_file(path)
        .unwrap();
}

#[test]
fn exr_half_and_float_channels_are_picked_by_name() {
    use exr::prelude::{f16, FlatSamples};
    let dir = temp_dir("exr");
    // 3x2, row-major from the top: value = 10 * row + column.
    let values: Vec<f32> = (0..6).map(|i| (10 * (i / 3) + i % 3) as f32).collect();
    let half = |k: f32| FlatSamples::F16(values.iter().map(|v| f16::from_f32(v + k)).collect());
    let rgb = dir.join("rgb.exr");
    write_exr(
        &rgb,
        3,
        2,
        vec![("R", half(0.0)), ("G", half(100.0)), ("B", half(200.0))],
    );
    let m = load_height_map(&rgb, &MapOptions::default()).unwrap();
    assert_eq!(
        (m.width, m.height, m.channel.as_str()),
        (3, 2, "R"),
        "no Y: falls back to R"
    );
    assert_eq!(m.data, values);
    assert_eq!(m.source, rgb);
    let g = load_height_map(
        &rgb,
        &MapOptions {
            channel: Some("G".into()),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(g.data[4], 111.0);
    let msg = err_naming_file(
        load_height_map(
            &rgb,
            &MapOptions {
                channel: Some("Z".into()),
                ..Default::default()
            },
        ),
        &rgb,
    );
    assert!(msg.contains("'Z'") && msg.contains("B, G, R"), "{msg}");

    let float = dir.join("float.exr");
    let f32s = |k: f32| FlatSamples::F32(values.iter().map(|v| v + k).collect());
    write_exr(&float, 3, 2, vec![("height", f32s(0.5)), ("Y", f32s(0.0))]);
    let opts = MapOptions {
        wrap: crate::Wrap::Clamp,
        ..Default::default()
    };
    let y = load_height_map(&float, &opts).unwrap();
    assert_eq!(
        (y.channel.as_str(), y.wrap),
        ("Y", crate::Wrap::Clamp),
        "Y preferred"
    );
    assert_eq!(y.data, values);
    let named = load_height_map(
        &float,
        &MapOptions {
            channel: Some("height".into()),
            ..Default::default()
        },
    );
    assert_eq!(named.unwrap().data[5], 12.5);

    let other = dir.join("other.exr");
    write_exr(
        &other,
        3,
        2,
        vec![("zeta", f32s(1.0)), ("alpha", f32s(2.0))],
    );
    let first = load_height_map(&other, &MapOptions::default()).unwrap();
    assert_eq!(
        (first.channel.as_str(), first.data[0]),
        ("alpha", 2.0),
        "first alphabetically"
    );
}

/// A PNG whose header states more pixels than its deflate data can expand to (fuzzed: the
/// decoder allocated 2.3 GB for a 56-byte file before it failed) is refused before decoding;
/// the same file with its real size loads.
#[test]
fn a_png_header_larger_than_its_data_is_an_error() {
    let dir = temp_dir("png-huge");
    let path = dir.join("small.png");
    image::GrayImage::from_raw(4, 4, vec![7; 16])
        .unwrap()
        .save(&path)
        .unwrap();
    assert!(load_height_map(&path, &MapOptions::default()).is_ok());
    // IHDR: 8-byte signature, 4-byte length, "IHDR", width and height, ..., CRC at 29.
    let mut bytes = std::fs::read(&path).unwrap();
    assert_eq!(&bytes[12..16], b"IHDR");
    bytes[16..20].copy_from_slice(&30_000u32.to_be_bytes());
    bytes[20..24].copy_from_slice(&30_000u32.to_be_bytes());
    let crc = crc32(&bytes[12..29]);
    bytes[29..33].copy_from_slice(&crc.to_be_bytes());
    let huge = dir.join("huge.png");
    std::fs::write(&huge, &bytes).unwrap();
    let e = load_height_map(&huge, &MapOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("huge.png") && e.contains("30000x30000") && e.contains("truncated or corrupt"),
        "{e}"
    );
}

/// An EXR height map whose header states more pixel bytes than its file can hold under its
/// compression is refused from the header, before the reader allocates storage for every
/// channel (a 480 KB file once asked for 14.4 GB and aborted); the same writer's whole image
/// loads.
#[test]
fn an_exr_header_larger_than_its_data_is_an_error() {
    use crate::test_util::exr_header_only;
    let dir = temp_dir("exr-huge");
    let whole = dir.join("whole.exr");
    std::fs::write(&whole, exr_header_only(4, 1, &["Y"], 0)).unwrap();
    let map = load_height_map(&whole, &MapOptions::default()).unwrap();
    assert_eq!(
        (map.width, map.height, map.data.as_slice()),
        (4, 1, &[1.0; 4][..])
    );
    // 20 000² texels of four floats: 6.4 GB stated, in under half a megabyte.
    for (name, compression) in [("none.exr", 0u8), ("zip.exr", 3), ("piz.exr", 4)] {
        let path = dir.join(name);
        std::fs::write(
            &path,
            exr_header_only(20_000, 20_000, &["A", "B", "G", "R"], compression),
        )
        .unwrap();
        let e = err_naming_file(load_height_map(&path, &MapOptions::default()), &path);
        assert!(
            e.contains("20000x20000 texels in 4 channels") && e.contains("truncated or corrupt"),
            "{e}"
        );
    }
}

#[test]
fn png_and_tiff_integers_are_normalised() {
    let dir = temp_dir("png16");
    let raw16 = vec![0u16, 65535, 32768, 1];
    let img16 = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(2, 2, raw16).unwrap();
    for name in ["h16.png", "h16.tif"] {
        let path = dir.join(name);
        img16.save(&path).unwrap();
        let m = load_height_map(&path, &MapOptions::default()).unwrap();
        assert_eq!(
            (m.channel.as_str(), m.data[0], m.data[1]),
            ("L", 0.0, 1.0),
            "{name}"
        );
        assert!((m.data[2] - 32768.0 / 65535.0).abs() < 1e-7);
    }
    let rgb = dir.join("rgb8.png");
    image::RgbImage::from_raw(2, 1, vec![255, 0, 0, 51, 255, 255])
        .unwrap()
        .save(&rgb)
        .unwrap();
    let m = load_height_map(&rgb, &MapOptions::default()).unwrap();
    assert_eq!(
        (m.channel.as_str(), m.data.clone()),
        ("R", vec![1.0, 0.2]),
        "red channel of RGB"
    );
}

#[test]
fn nan_texels_load_for_validate_to_report() {
    use exr::prelude::FlatSamples;
    let dir = temp_dir("exr-nan");
    let path = dir.join("nan.exr");
    write_exr(
        &path,
        2,
        1,
        vec![("Y", FlatSamples::F32(vec![0.0, f32::NAN]))],
    );
    let m = load_height_map(&path, &MapOptions::default()).unwrap();
    assert_eq!(m.first_non_finite(), Some((1, 0)));
}

// ---------------------------------------------------------------------------------------------
// 5. Bad input: an error naming the file, never a panic.

#[test]
fn every_truncated_prefix_of_a_glb_is_an_error() {
    let dir = temp_dir("glb-truncated");
    let mut doc = GltfDoc::default();
    let (a_pos, a_idx) = (doc.floats(&TRI, 3), doc.indices(&[0, 1, 2]));
    let rest = single_node_scene(
        json!({}),
        json!({"attributes": {"POSITION": a_pos}, "indices": a_idx}),
    );
    let glb = doc.glb(&rest);
    let path = dir.join("cut.glb");
    std::fs::write(&path, &glb).unwrap();
    load_mesh(&path, &MeshOptions::default()).expect("the whole file loads");
    for len in 0..glb.len() {
        std::fs::write(&path, &glb[..len]).unwrap();
        err_naming_file(load_mesh(&path, &MeshOptions::default()), &path);
    }
    // Any single corrupted byte: a result either way, never a panic.
    for k in 0..glb.len() {
        let mut bad = glb.clone();
        bad[k] ^= 0xff;
        std::fs::write(&path, &bad).unwrap();
        let _ = load_mesh(&path, &MeshOptions::default());
    }
}

#[test]
fn gltf_bad_contents_are_errors() {
    let dir = temp_dir("gltf-bad");
    let opts = MeshOptions::default();
    let check = |name: &str, doc: &GltfDoc, rest: &Value, expect: &str| {
        let path = dir.join(name);
        doc.write_gltf(&path, rest);
        let msg = err_naming_file(load_mesh(&path, &opts), &path);
        assert!(msg.contains(expect), "{name}: {msg}");
    };

    let mut doc = GltfDoc::default();
    let (a_pos, a_idx) = (doc.floats(&TRI, 3), doc.indices(&[0, 1, 5]));
    let rest = single_node_scene(
        json!({}),
        json!({"attributes": {"POSITION": a_pos}, "indices": a_idx}),
    );
    check("index.gltf", &doc, &rest, "5");

    let mut doc = GltfDoc::default();
    let mut nan = TRI;
    nan[4] = f32::NAN;
    let a_pos = doc.floats(&nan, 3);
    let rest = single_node_scene(json!({}), json!({"attributes": {"POSITION": a_pos}}));
    check("nan.gltf", &doc, &rest, "NaN");

    let mut doc = GltfDoc::default();
    let a_pos = doc.floats(&TRI, 3);
    let rest = single_node_scene(
        json!({}),
        json!({"attributes": {"POSITION": a_pos}, "mode": 1}),
    );
    check("lines-only.gltf", &doc, &rest, "zero triangles");

    // count 0 panics inside the gltf crate's own reader; ours must not.
    let mut doc = GltfDoc::default();
    let a_pos = doc.floats(&TRI, 3);
    doc.accessors[a_pos]["count"] = json!(0);
    let rest = single_node_scene(json!({}), json!({"attributes": {"POSITION": a_pos}}));
    check("empty.gltf", &doc, &rest, "zero triangles");

    // An accessor claiming more elements than its view holds.
    let mut doc = GltfDoc::default();
    let a_pos = doc.floats(&TRI, 3);
    doc.accessors[a_pos]["count"] = json!(1_000_000_000u64);
    let rest = single_node_scene(json!({}), json!({"attributes": {"POSITION": a_pos}}));
    check("huge.gltf", &doc, &rest, "do not fit");

    let path = dir.join("garbage.gltf");
    std::fs::write(&path, "{ not json").unwrap();
    err_naming_file(load_mesh(&path, &opts), &path);

    // A node that is its own child.
    let mut doc = GltfDoc::default();
    let a_pos = doc.floats(&TRI, 3);
    let rest = json!({
        "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "children": [0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": a_pos}}]}],
    });
    let path = dir.join("cycle.gltf");
    doc.write_gltf(&path, &rest);
    err_naming_file(load_mesh(&path, &opts), &path);
}

#[test]
fn obj_bad_contents_are_errors() {
    let dir = temp_dir("obj-bad");
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    for (name, text, expect) in [
        ("range.obj", format!("{tri}f 1 2 9\n"), "line 4"),
        (
            "zero.obj",
            format!("{tri}vt 0 0\nf 1/0 2/1 3/1\n"),
            "texture coordinate 0",
        ),
        ("relative.obj", format!("{tri}f -5 1 2\n"), "vertex -5"),
        // tobj 4.0.5 panics on this one (multiply overflow resolving the relative vt).
        (
            "relative-vt.obj",
            format!("{tri}vt 0 0\nf 1/-5 2/1 3/1\n"),
            "texture coordinate -5",
        ),
        (
            "nan.obj",
            "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_string(),
            "NaN",
        ),
        ("faceless.obj", tri.to_string(), "zero triangles"),
        ("word.obj", format!("{tri}v 1 x 0\n"), "'x' is not a number"),
        ("twocorner.obj", format!("{tri}f 1 2\n"), "at least 3"),
        // A UV past ±65536 (the `pipeline` fuzz target's 2 × 10¹⁹ hung the bake).
        (
            "far-uv.obj",
            format!("{tri}vt 0 0\nvt 1 1e19\nf 1/1 2/2 3/1\n"),
            "vertex 1 has the UV (1, 10000000000000000000), past ±65536",
        ),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        let msg = err_naming_file(load_mesh(&path, &MeshOptions::default()), &path);
        assert!(msg.contains(expect), "{name}: {msg}");
    }
}

/// CRC-32 (PNG's) to hand-craft a header that the encoder refuses to write.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

#[test]
fn bad_maps_are_errors() {
    let dir = temp_dir("map-bad");
    let opts = MapOptions::default();
    let good = dir.join("good.png");
    write_asymmetric_png(&good);
    let png = std::fs::read(&good).unwrap();

    // Every truncated prefix of a valid PNG fails, except those that lose only (part of) the
    // 12-byte IEND trailer: the png decoder accepts them, and every pixel is then intact.
    let cut = dir.join("cut.png");
    let iend = png.len() - 12;
    assert_eq!(&png[iend + 4..iend + 8], b"IEND");
    for len in 0..png.len() {
        std::fs::write(&cut, &png[..len]).unwrap();
        if len < iend {
            err_naming_file(load_height_map(&cut, &opts), &cut);
        } else if let Ok(m) = load_height_map(&cut, &opts) {
            assert_eq!(
                m.data,
                load_height_map(&good, &opts).unwrap().data,
                "prefix {len}"
            );
        }
    }

    // 0x0: IHDR (bytes 8..33: length, type, 13 data bytes, CRC) patched to width = height = 0.
    let mut zero = png.clone();
    zero[16..24].fill(0);
    let crc = crc32(&zero[12..29]);
    zero[29..33].copy_from_slice(&crc.to_be_bytes());
    let path = dir.join("zero.png");
    std::fs::write(&path, &zero).unwrap();
    err_naming_file(load_height_map(&path, &opts), &path);

    // 40000 x 1 declared: refused from the header, before decoding.
    let mut wide = png.clone();
    wide[16..20].copy_from_slice(&40000u32.to_be_bytes());
    let crc = crc32(&wide[12..29]);
    wide[29..33].copy_from_slice(&crc.to_be_bytes());
    let path = dir.join("wide.png");
    std::fs::write(&path, &wide).unwrap();
    let msg = err_naming_file(load_height_map(&path, &opts), &path);
    assert!(msg.contains("32768"), "{msg}");

    let path = dir.join("noise.png");
    std::fs::write(&path, b"definitely not a png").unwrap();
    err_naming_file(load_height_map(&path, &opts), &path);

    let path = dir.join("folder.png");
    std::fs::create_dir_all(&path).unwrap();
    err_naming_file(load_height_map(&path, &opts), &path);

    let path = dir.join("map.jpg");
    std::fs::write(&path, &png).unwrap();
    let msg = err_naming_file(load_height_map(&path, &opts), &path);
    assert!(msg.contains(".exr, .png, .tif or .tiff"), "{msg}");

    let path = dir.join("mesh.fbx");
    std::fs::write(&path, b"x").unwrap();
    err_naming_file(load_mesh(&path, &MeshOptions::default()), &path);

    // Every truncated prefix of a valid EXR.
    let exr_path = dir.join("good.exr");
    write_exr(
        &exr_path,
        2,
        2,
        vec![(
            "Y",
            exr::prelude::FlatSamples::F32(vec![1.0, 2.0, 3.0, 4.0]),
        )],
    );
    let exr_bytes = std::fs::read(&exr_path).unwrap();
    let cut = dir.join("cut.exr");
    for len in 0..exr_bytes.len() {
        std::fs::write(&cut, &exr_bytes[..len]).unwrap();
        err_naming_file(load_height_map(&cut, &opts), &cut);
    }
}

#[test]
fn float_tiff_is_read_raw() {
    let dir = temp_dir("tiff-float");
    let path = dir.join("f.tif");
    let raw = vec![0.5f32, 9.0, 9.0, -2.0, 9.0, 9.0];
    image::Rgb32FImage::from_raw(2, 1, raw)
        .unwrap()
        .save(&path)
        .unwrap();
    let m = load_height_map(&path, &MapOptions::default()).unwrap();
    assert_eq!(
        (m.channel.as_str(), m.data.clone()),
        ("R", vec![0.5, -2.0]),
        "not normalised"
    );
}

#[test]
fn grey_float_and_32_bit_tiffs_are_read() {
    // The 32-bit displacement export of sculpting tools: one float channel, which `image` has
    // no layout for. Float is read raw (negative and > 1 kept), 32-bit integers normalised.
    use tiff::encoder::{colortype, TiffEncoder};
    let dir = temp_dir("tiff-grey32");
    let raw = [0.5f32, -2.0, 9.0, 0.25, 1.5, -0.125];
    let write = |name: &str, f: &dyn Fn(&mut TiffEncoder<std::fs::File>)| {
        let path = dir.join(name);
        let mut enc = TiffEncoder::new(std::fs::File::create(&path).unwrap()).unwrap();
        f(&mut enc);
        path
    };
    let f32_path = write("f32.tif", &|e| {
        e.write_image::<colortype::Gray32Float>(3, 2, &raw).unwrap()
    });
    let f64_path = write("f64.tif", &|e| {
        let v: Vec<f64> = raw.iter().map(|&x| x as f64).collect();
        e.write_image::<colortype::Gray64Float>(3, 2, &v).unwrap()
    });
    let u32_path = write("u32.tif", &|e| {
        e.write_image::<colortype::Gray32>(2, 1, &[0, u32::MAX])
            .unwrap()
    });
    for path in [&f32_path, &f64_path] {
        let m = load_height_map(path, &MapOptions::default()).unwrap();
        assert_eq!((m.width, m.height, m.channel.as_str()), (3, 2, "L"));
        assert_eq!(m.data, raw.to_vec(), "{}", path.display());
    }
    let m = load_height_map(&u32_path, &MapOptions::default()).unwrap();
    assert_eq!(m.data, vec![0.0, 1.0]);
    // A channel other than L is refused with the fix.
    let opts = MapOptions {
        channel: Some("R".into()),
        ..MapOptions::default()
    };
    let msg = load_height_map(&f32_path, &opts).unwrap_err().to_string();
    assert!(msg.contains("f32.tif") && msg.contains("'L' here"), "{msg}");
    // Truncated: a clean error naming the file, for every prefix.
    let bytes = std::fs::read(&f32_path).unwrap();
    for n in 0..bytes.len() {
        let cut = dir.join("cut.tif");
        std::fs::write(&cut, &bytes[..n]).unwrap();
        err_naming_file(load_height_map(&cut, &MapOptions::default()), &cut);
    }
}
