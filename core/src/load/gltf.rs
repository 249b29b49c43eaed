//! glTF 2.0 (`.gltf` with external or `data:` buffers, and `.glb`) into a `BaseMesh`.
//!
//! Every triangle primitive of every mesh node under the default scene (else every scene's
//! roots) is appended with its node's world transform applied; v is flipped (`1 - v`) to the
//! project's v-up convention. The `gltf` crate parses and validates the JSON; accessors and
//! buffers are read here with checked arithmetic, because the crate's own readers panic on
//! `count: 0`, and its GLB header and URI code panic on some corrupt inputs.

use super::MeshOptions;
use crate::error::{Error, Result};
use crate::mesh::{AlphaMode, BaseMesh, MeshMaterial, Projection, SceneSun, UpAxis};
use crate::texture::{
    ChannelRef, ColorSpace, NormalMapRef, Sampler, TexWrap, TextureData, TextureRef, UvTransform,
};
use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::mesh::{Mode, Semantic};
use glam::{Mat3, Mat4, Vec2, Vec3};
use std::path::Path;

pub fn load(path: &Path, opts: &MeshOptions) -> Result<BaseMesh> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let is_glb = super::extension(path) == "glb" || bytes.starts_with(b"glTF");
    if is_glb {
        check_glb_header(path, &bytes)?;
    }
    let doc = parse_gltf(path, &bytes)?;
    let buffers = load_buffers(path, &doc)?;
    super::check_material_count(path, doc.materials().len())?;
    let mut loader = Loader {
        path,
        opts,
        buffers,
        mesh: BaseMesh {
            source: path.into(),
            up_axis: Some(UpAxis::Y),
            ..Default::default()
        },
        visited: vec![false; doc.nodes().len()],
        cameras: vec![],
        any_uv_missing: false,
        materials: doc.materials().len(),
    };
    for root in scene_roots(&doc) {
        loader.visit(root, Mat4::IDENTITY)?;
    }
    let mut mesh = loader.mesh;
    let loader_buffers = loader.buffers;
    mesh.missing_uvs = loader.any_uv_missing;
    mesh.face_flags = vec![0; mesh.triangles.len()];
    mesh.materials = doc
        .materials()
        .map(|m| {
            let pbr = m.pbr_metallic_roughness();
            // Roughness in its green channel, metallic in its blue, both linear.
            let metallic_roughness = pbr
                .metallic_roughness_texture()
                .map(|t| info_ref(path, &loader_buffers, &t, ColorSpace::Raw))
                .transpose()?;
            let base_color_texture = pbr
                .base_color_texture()
                .map(|t| info_ref(path, &loader_buffers, &t, ColorSpace::Srgb))
                .transpose()?;
            let channel = |channel| {
                metallic_roughness
                    .clone()
                    .map(|texture| ChannelRef { texture, channel })
            };
            Ok(MeshMaterial {
                name: m.name().map_or_else(
                    || format!("material {}", m.index().unwrap_or(0)),
                    str::to_string,
                ),
                base_color: pbr.base_color_factor(),
                roughness: pbr.roughness_factor(),
                metallic: pbr.metallic_factor(),
                base_color_texture: base_color_texture.clone(),
                // Blender's importer: the base-colour texture's alpha times the factor's, cut
                // at alphaCutoff (0.5 where absent) under MASK, as it is under BLEND.
                alpha_mode: match m.alpha_mode() {
                    ::gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
                    ::gltf::material::AlphaMode::Mask => {
                        AlphaMode::Mask(m.alpha_cutoff().unwrap_or(0.5))
                    }
                    ::gltf::material::AlphaMode::Blend => AlphaMode::Blend,
                },
                alpha_texture: base_color_texture.map(|texture| ChannelRef {
                    texture: TextureRef {
                        color_space: ColorSpace::Alpha,
                        ..texture
                    },
                    channel: 0,
                }),
                roughness_texture: channel(1),
                metallic_texture: channel(2),
                normal_texture: m
                    .normal_texture()
                    .map(|t| normal_ref(path, &loader_buffers, &t))
                    .transpose()?,
                emission: m
                    .emissive_factor()
                    .map(|c| c * m.emissive_strength().unwrap_or(1.0)),
                emission_texture: m
                    .emissive_texture()
                    .map(|t| info_ref(path, &loader_buffers, &t, ColorSpace::Srgb))
                    .transpose()?,
                // KHR_materials_ior's F0 (1.5: 0.04), scaled by KHR_materials_specular's
                // factor (its textures are not read); its colour is the tint.
                specular: match (m.ior(), m.specular().map(|s| s.specular_factor())) {
                    (None, None) => None,
                    (ior, factor) => crate::mesh::ior_f0(ior.unwrap_or(1.5))
                        .map(|f0| (f0 * factor.unwrap_or(1.0)).clamp(0.0, 1.0)),
                },
                specular_tint: m
                    .specular()
                    .map(|s| s.specular_color_factor())
                    .filter(|c| *c != [1.0; 3]),
                clearcoat: clearcoat_factor(&m, "clearcoatFactor"),
                clearcoat_roughness: clearcoat_factor(&m, "clearcoatRoughnessFactor"),
                // The weight in the red channel, the roughness in the green (the extension's).
                clearcoat_texture: clearcoat_channel(
                    path,
                    &doc,
                    &loader_buffers,
                    &m,
                    "clearcoatTexture",
                    0,
                )?,
                clearcoat_roughness_texture: clearcoat_channel(
                    path,
                    &doc,
                    &loader_buffers,
                    &m,
                    "clearcoatRoughnessTexture",
                    1,
                )?,
                clearcoat_normal_texture: clearcoat_texture(
                    path,
                    &doc,
                    &loader_buffers,
                    &m,
                    "clearcoatNormalTexture",
                )?
                .map(|(texture, scale)| NormalMapRef::unit(texture, scale)),
            })
        })
        .collect::<Result<_>>()?;
    if mesh.materials.is_empty() {
        mesh.group_material.clear();
    }
    for (names, world, projection) in loader.cameras {
        super::attach_camera(&mut mesh, names, world, projection, None, true);
    }
    Ok(mesh)
}

/// A factor of `m`'s `KHR_materials_clearcoat` (which the gltf crate has no accessor for),
/// clamped to [0, 1]; 0 where the extension or the factor is absent or not a number, as the
/// extension's defaults say.
fn clearcoat_factor(m: &gltf::Material, key: &str) -> f32 {
    m.extension_value("KHR_materials_clearcoat")
        .and_then(|e| e.get(key))
        .and_then(|v| v.as_f64())
        .map_or(0.0, |v| (v as f32).clamp(0.0, 1.0))
}

/// One channel of a texture of `m`'s `KHR_materials_clearcoat` (`clearcoat_texture`).
fn clearcoat_channel(
    path: &Path,
    doc: &::gltf::Document,
    buffers: &[Vec<u8>],
    m: &::gltf::Material,
    key: &str,
    channel: u8,
) -> Result<Option<ChannelRef>> {
    Ok(clearcoat_texture(path, doc, buffers, m, key)?
        .map(|(texture, _)| ChannelRef { texture, channel }))
}

/// The texture `key` of `m`'s `KHR_materials_clearcoat`, read from the extension's JSON (the
/// gltf crate has no accessor) with its `texCoord`, `KHR_texture_transform` and `scale` (a
/// normalTextureInfo's; 1 where absent); `None` where the extension or the texture is absent.
/// A malformed textureInfo or a texture index past the file's textures is an error naming
/// both.
fn clearcoat_texture(
    path: &Path,
    doc: &::gltf::Document,
    buffers: &[Vec<u8>],
    m: &::gltf::Material,
    key: &str,
) -> Result<Option<(TextureRef, f32)>> {
    let Some(v) = m
        .extension_value("KHR_materials_clearcoat")
        .and_then(|e| e.get(key))
    else {
        return Ok(None);
    };
    let name = m.name().unwrap_or("(unnamed)");
    let bad = |why: String| {
        Error::invalid(
            path,
            format!(
                "material '{name}': KHR_materials_clearcoat's {key} {why} (fix or re-export the \
                 asset, or override the clearcoat with --clearcoat and --clearcoat-roughness)"
            ),
        )
    };
    let info: ::gltf::json::texture::Info =
        serde_json::from_value(v.clone()).map_err(|e| bad(format!("is malformed: {e}")))?;
    let scale = match v.get("scale") {
        None => 1.0,
        Some(s) => s
            .as_f64()
            .filter(|s| s.is_finite())
            .ok_or_else(|| bad(format!("has a scale that is not a number ({s})")))?
            as f32,
    };
    let index = info.index.value();
    let texture = doc
        .textures()
        .nth(index)
        .ok_or_else(|| bad(format!("names texture #{index}, past the file's textures")))?;
    let transform = info
        .extensions
        .as_ref()
        .and_then(|e| e.texture_transform.as_ref())
        .map(|t| {
            (
                UvTransform::gltf(t.offset.0, t.rotation.0, t.scale.0),
                t.tex_coord,
            )
        });
    let texture = texture_ref(
        path,
        buffers,
        texture,
        info.tex_coord,
        transform,
        ColorSpace::Raw,
    )?;
    Ok(Some((texture, scale)))
}

/// A textureInfo's texture (`texture_ref`), with its `KHR_texture_transform`.
fn info_ref(
    path: &Path,
    buffers: &[Vec<u8>],
    info: &::gltf::texture::Info,
    color_space: ColorSpace,
) -> Result<TextureRef> {
    let transform = info.texture_transform().map(|t| {
        (
            UvTransform::gltf(t.offset(), t.rotation(), t.scale()),
            t.tex_coord(),
        )
    });
    texture_ref(
        path,
        buffers,
        info.texture(),
        info.tex_coord(),
        transform,
        color_space,
    )
}

/// A material's `normalTexture`: a raw texture of 0..1 codes for -1..1, its `scale` the
/// Normal Map Strength (`NormalMapRef::unit`, as Blender's importer reads it). gltf 1.4 reads no `KHR_texture_transform` on it: the extension's JSON is read
/// here.
fn normal_ref(
    path: &Path,
    buffers: &[Vec<u8>],
    info: &::gltf::material::NormalTexture,
) -> Result<NormalMapRef> {
    let transform = match info.extension_value("KHR_texture_transform") {
        Some(v) => {
            let t: ::gltf::json::extensions::texture::TextureTransform =
                serde_json::from_value(v.clone()).map_err(|e| {
                    Error::invalid(
                        path,
                        format!(
                            "a normalTexture (texture #{}) has a malformed KHR_texture_transform: \
                             {e} (re-export the asset)",
                            info.texture().index()
                        ),
                    )
                })?;
            Some((
                UvTransform::gltf(t.offset.0, t.rotation.0, t.scale.0),
                t.tex_coord,
            ))
        }
        None => None,
    };
    let texture = texture_ref(
        path,
        buffers,
        info.texture(),
        info.tex_coord(),
        transform,
        ColorSpace::Raw,
    )?;
    Ok(NormalMapRef::unit(texture, info.scale()))
}

/// Where a material's texture is and how it is sampled. An image in a buffer view is copied
/// out (decoded only if a beauty render needs it, `texture::ColorMap::load`); a `data:` URI is
/// decoded from base64; any other URI is a file next to the asset. `transform`: the
/// textureInfo's `KHR_texture_transform` and the `texCoord` it names in place of `tex_coord`.
fn texture_ref(
    path: &Path,
    buffers: &[Vec<u8>],
    texture: ::gltf::Texture,
    tex_coord: u32,
    transform: Option<(UvTransform, Option<u32>)>,
    color_space: ColorSpace,
) -> Result<TextureRef> {
    use ::gltf::texture::{MagFilter, WrappingMode};
    let image = texture.source();
    let name = match (image.name(), image.source()) {
        (Some(name), _) => name.to_string(),
        (None, ::gltf::image::Source::Uri { uri, .. }) if !uri.starts_with("data:") => {
            uri.to_string()
        }
        _ => format!("image {}", image.index()),
    };
    let what = format!("image #{} ('{name}')", image.index());
    let data = match image.source() {
        ::gltf::image::Source::View { view, .. } => {
            let buffer = &buffers[view.buffer().index()];
            let range = view
                .offset()
                .checked_add(view.length())
                .and_then(|end| buffer.get(view.offset()..end));
            let bytes = range.ok_or_else(|| {
                Error::invalid(
                    path,
                    format!(
                        "{what}: buffer view #{} runs past its buffer's {} bytes (re-export)",
                        view.index(),
                        buffer.len()
                    ),
                )
            })?;
            TextureData::Embedded(bytes.to_vec())
        }
        ::gltf::image::Source::Uri { uri, .. } => match uri.strip_prefix("data:") {
            Some(_) => TextureData::Embedded(read_uri(path, &what, uri)?),
            None => {
                let rel = percent_decode(uri).ok_or_else(|| {
                    Error::invalid(path, format!("{what} has a malformed URI '{uri}'"))
                })?;
                TextureData::File(path.parent().unwrap_or(Path::new(".")).join(rel))
            }
        },
    };
    let sampler = texture.sampler();
    let wrap = |w: WrappingMode| match w {
        WrappingMode::Repeat => TexWrap::Repeat,
        WrappingMode::ClampToEdge => TexWrap::Clamp,
        WrappingMode::MirroredRepeat => TexWrap::Mirror,
    };
    Ok(TextureRef {
        name,
        data,
        sampler: Sampler {
            wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
            nearest: sampler.mag_filter() == Some(MagFilter::Nearest),
        },
        // KHR_texture_transform's texCoord replaces the textureInfo's.
        tex_coord: transform.and_then(|t| t.1).unwrap_or(tex_coord),
        transform: transform.map_or(UvTransform::IDENTITY, |t| t.0),
        color_space,
        scale_bias: None,
    })
}

/// `Gltf::from_slice`, but gltf-json 1.4's validation indexes a primitive's POSITION
/// accessor before checking the index (a panic on `"POSITION": 0` with no accessors, found
/// by fuzzing; see docs/fuzzing.md): parse without validation, check that index and each
/// image's source, then validate.
fn parse_gltf(path: &Path, bytes: &[u8]) -> Result<::gltf::Gltf> {
    let invalid = |what: String| {
        Error::invalid(
            path,
            format!(
                "is not valid glTF 2.0: {what} (the file is truncated or corrupt; re-export it)"
            ),
        )
    };
    let unchecked =
        ::gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| invalid(e.to_string()))?;
    let root = unchecked.document.as_json();
    let position =
        ::gltf::json::validation::Checked::Valid(::gltf::json::mesh::Semantic::Positions);
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(a) = primitive.attributes.get(&position) {
                if a.value() >= root.accessors.len() {
                    return Err(invalid(format!(
                        "mesh {m} primitive {p}: POSITION names accessor {} but there are {}",
                        a.value(),
                        root.accessors.len()
                    )));
                }
            }
        }
    }
    // gltf 1.4's `Image::source` unwraps the image's URI where it has no buffer view, and its
    // MIME type where it has one (a panic on an image with neither, found by fuzzing).
    for (i, image) in root.images.iter().enumerate() {
        match (&image.buffer_view, &image.uri, &image.mime_type) {
            (Some(_), _, None) => {
                return Err(invalid(format!(
                    "image {i} is in a buffer view but has no mimeType"
                )))
            }
            (None, None, _) => {
                return Err(invalid(format!(
                    "image {i} has neither a uri nor a bufferView"
                )))
            }
            _ => {}
        }
    }
    ::gltf::Gltf::from_slice(bytes).map_err(|e| invalid(e.to_string()))
}

/// The default scene's roots, else the roots of every scene, else every parentless node.
fn scene_roots(doc: &::gltf::Document) -> Vec<::gltf::Node<'_>> {
    if let Some(scene) = doc.default_scene() {
        return scene.nodes().collect();
    }
    let mut roots: Vec<::gltf::Node> = Vec::new();
    if doc.scenes().len() > 0 {
        for node in doc.scenes().flat_map(|s| s.nodes()) {
            if !roots.iter().any(|r| r.index() == node.index()) {
                roots.push(node);
            }
        }
    } else {
        let mut is_child = vec![false; doc.nodes().len()];
        for node in doc.nodes() {
            for c in node.children() {
                is_child[c.index()] = true;
            }
        }
        roots = doc.nodes().filter(|n| !is_child[n.index()]).collect();
    }
    roots
}

/// The crate subtracts the header size from the declared length unchecked: check first.
fn check_glb_header(path: &Path, bytes: &[u8]) -> Result<()> {
    let bad = |what: String| Error::invalid(path, format!("{what} (re-export the .glb)"));
    if bytes.len() < 12 || !bytes.starts_with(b"glTF") {
        return Err(bad(format!(
            "is not binary glTF: {} bytes without the 12-byte 'glTF' header",
            bytes.len()
        )));
    }
    let word = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    let (version, length) = (word(4), word(8) as usize);
    if version != 2 {
        return Err(bad(format!(
            "is binary glTF version {version}, only 2 is supported"
        )));
    }
    if length < 20 || length > bytes.len() {
        return Err(bad(format!(
            "is truncated or corrupt: its header declares {length} bytes, the file has {}",
            bytes.len()
        )));
    }
    Ok(())
}

fn load_buffers(path: &Path, doc: &::gltf::Gltf) -> Result<Vec<Vec<u8>>> {
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let i = buffer.index();
        let data = match buffer.source() {
            ::gltf::buffer::Source::Bin => doc.blob.clone().ok_or_else(|| {
                Error::invalid(
                    path,
                    format!(
                        "buffer #{i} refers to the GLB binary chunk, which is missing (re-export)"
                    ),
                )
            })?,
            ::gltf::buffer::Source::Uri(uri) => read_uri(path, &format!("buffer #{i}"), uri)?,
        };
        if data.len() < buffer.length() {
            return Err(Error::invalid(
                path,
                format!(
                    "buffer #{i} declares {} bytes but only {} are present (the file or its .bin \
                     is truncated; re-export it)",
                    buffer.length(),
                    data.len()
                ),
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// The bytes behind a URI of `what` (e.g. `buffer #0`): a base64 `data:` URI or a relative file.
fn read_uri(path: &Path, what: &str, uri: &str) -> Result<Vec<u8>> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let payload = rest.split_once(";base64,").map(|(_, p)| p).ok_or_else(|| {
            Error::invalid(
                path,
                format!("{what}: only base64 data: URIs are supported"),
            )
        })?;
        return decode_base64(payload).ok_or_else(|| {
            Error::invalid(
                path,
                format!("{what}: its data: URI is not valid base64 (re-export)"),
            )
        });
    }
    if uri.contains(':') {
        return Err(Error::invalid(
            path,
            format!(
                "{what} has URI '{uri}': only relative file paths and data: URIs are supported"
            ),
        ));
    }
    let rel = percent_decode(uri)
        .ok_or_else(|| Error::invalid(path, format!("{what} has a malformed URI '{uri}'")))?;
    let file = path.parent().unwrap_or(Path::new(".")).join(rel);
    super::read_named_file(&file).map_err(|e| {
        Error::invalid(
            path,
            format!(
                "{what}: cannot read '{}': {e} (keep the .bin next to the .gltf)",
                file.display()
            ),
        )
    })
}

fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut k = 0;
    while k < b.len() {
        if b[k] == b'%' {
            let hex = std::str::from_utf8(b.get(k + 1..k + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            k += 3;
        } else {
            out.push(b[k]);
            k += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Standard or URL-safe base64, padding optional; `None` on any other character.
fn decode_base64(s: &str) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(s.len() / 4 * 3);
    let (mut acc, mut bits) = (0u32, 0u32);
    for c in s.bytes().take_while(|&c| c != b'=') {
        let v = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            b' ' | b'\n' | b'\r' | b'\t' => continue,
            _ => return None,
        };
        acc = (acc << 6) | v as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    Some(out)
}

struct Loader<'p> {
    path: &'p Path,
    opts: &'p MeshOptions,
    buffers: Vec<Vec<u8>>,
    mesh: BaseMesh,
    visited: Vec<bool>,
    /// Names, world transform and projection of each camera, in the order the scene's nodes
    /// are visited.
    cameras: Vec<(Vec<String>, Mat4, Projection)>,
    any_uv_missing: bool,
    /// The file's material count: the index of "no material".
    materials: usize,
}

impl Loader<'_> {
    fn visit(&mut self, node: ::gltf::Node, parent: Mat4) -> Result<()> {
        let i = node.index();
        if std::mem::replace(&mut self.visited[i], true) {
            return Err(Error::invalid(
                self.path,
                format!(
                    "node #{i} is reached twice: the node hierarchy has a cycle or a node with two \
                     parents (glTF requires a tree; re-export)"
                ),
            ));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(cam) = node.camera() {
            let index = format!("node #{i}");
            let names: Vec<String> = [node.name(), Some(&index), cam.name()]
                .into_iter()
                .flatten()
                .map(str::to_string)
                .collect();
            let projection = match cam.projection() {
                ::gltf::camera::Projection::Perspective(p) => Projection::Perspective {
                    yfov_deg: p.yfov().to_degrees(),
                },
                // The larger of `xmag` and `ymag`: half the image's larger side
                // (`SceneCamera::larger_side`), as Blender imports it. Either not positive:
                // no view (`camera_fault` leaves the camera out).
                ::gltf::camera::Projection::Orthographic(o) => {
                    let (x, y) = (o.xmag(), o.ymag());
                    Projection::Orthographic {
                        height: match x > 0.0 && y > 0.0 {
                            true => 2.0 * x.max(y),
                            false => 0.0,
                        },
                    }
                }
            };
            self.cameras.push((names, world, projection));
        }
        if let Some(light) = node.light() {
            self.light(&node, &light, world);
        }
        if let Some(mesh) = node.mesh() {
            let node_name = node
                .name()
                .map_or_else(|| format!("node #{i}"), str::to_string);
            let mesh_name = mesh
                .name()
                .map_or_else(|| format!("mesh #{}", mesh.index()), str::to_string);
            for prim in mesh.primitives() {
                let group = format!("{node_name}/{mesh_name}/{}", prim.index());
                self.primitive(&prim, world, group)?;
            }
        }
        for child in node.children() {
            self.visit(child, world)?;
        }
        Ok(())
    }

    /// A `KHR_lights_punctual` light. The first directional one is the key light
    /// (`SceneSun`): towards its node's +Z (it shines down −Z), its intensity in lux over 683
    /// lm/W (as Blender imports it: a sun of that many W/m²) times its colour's luminance, its
    /// colour, and Blender's default sun width, 0.526°. Later directional lights, point and
    /// spot lights are `BaseMesh::lights`: a point at its node's origin, of intensity candela
    /// over 683 (W/sr, as Blender's importer makes a lamp of 4π × that many watts), a spot
    /// also shining down −Z within `outerConeAngle` (default π/4), its edge fading as the
    /// Cycles spot Blender's importer makes of it (a blend of 1 − `innerConeAngle` / outer;
    /// `Spot::blended`), not by glTF's own ramp. A light whose numbers are not usable is left
    /// out with a warning.
    fn light(
        &mut self,
        node: &::gltf::Node,
        light: &::gltf::khr_lights_punctual::Light,
        world: Mat4,
    ) {
        use crate::render::lights::{Light, LightShape, Spot};
        use ::gltf::khr_lights_punctual::Kind;
        let name = node
            .name()
            .or(light.name())
            .map_or_else(|| format!("node #{}", node.index()), str::to_string);
        let [r, g, b] = light.color();
        let (luminance, color) =
            crate::mesh::split_color(Vec3::new(r, g, b)).unwrap_or((f32::NAN, [1.0; 3]));
        let power = light.intensity() / 683.0 * luminance;
        let toward = world.transform_vector3(Vec3::Z).normalize_or_zero();
        let pos = world.transform_point3(Vec3::ZERO);
        if toward == Vec3::ZERO || !pos.is_finite() || !(power.is_finite() && power >= 0.0) {
            self.warn(&format!(
                "light '{name}': its direction, intensity or colour ({r}, {g}, {b}) is not usable; left out"
            ));
            return;
        }
        let color_v = Vec3::from_array(color);
        let shape = match light.kind() {
            Kind::Directional if self.mesh.sun.is_none() => {
                self.mesh.sun = Some(SceneSun {
                    name,
                    key: [
                        toward.x.atan2(toward.z).to_degrees(),
                        toward.y.clamp(-1.0, 1.0).asin().to_degrees(),
                        power,
                    ],
                    color,
                    angle_deg: 0.526,
                });
                return;
            }
            Kind::Directional => LightShape::Distant {
                dir: toward,
                cos_radius: (0.5f32 * 0.526).to_radians().cos(),
            },
            Kind::Point => LightShape::Local {
                pos,
                radius: 0.0,
                spot: None,
            },
            Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                let (inner, outer) = (inner_cone_angle, outer_cone_angle);
                if !(inner.is_finite() && outer.is_finite() && 0.0 <= inner && inner < outer) {
                    self.warn(&format!(
                        "light '{name}': its cone ({inner} to {outer} radians) is not one (inner below outer, both >= 0); left out"
                    ));
                    return;
                }
                LightShape::Local {
                    pos,
                    radius: 0.0,
                    spot: Some(Spot::blended(-toward, outer, 1.0 - inner / outer)),
                }
            }
        };
        self.mesh.lights.push(crate::mesh::SceneLight {
            name,
            light: Light {
                shape,
                power,
                color: color_v,
            },
        });
    }

    fn warn(&self, what: &str) {
        eprintln!("warning: {}: {what}", self.path.display());
    }

    fn primitive(&mut self, prim: &::gltf::Primitive, world: Mat4, group: String) -> Result<()> {
        let path = self.path;
        let mode = prim.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            self.warn(&format!(
                "primitive '{group}' is {mode:?}, not triangles; skipped"
            ));
            return Ok(());
        }
        let linear = Mat3::from_mat4(world);
        let det = linear.determinant();
        if det == 0.0 || !det.is_finite() {
            self.warn(&format!(
                "primitive '{group}' has a singular node transform; skipped"
            ));
            return Ok(());
        }
        let acc_pos = prim.get(&Semantic::Positions).ok_or_else(|| {
            Error::invalid(
                path,
                format!("primitive '{group}' has no POSITION attribute (re-export)"),
            )
        })?;
        let positions: Vec<Vec3> = self
            .read_floats::<3>(&acc_pos, &group, "POSITION")?
            .into_iter()
            .map(|p| world.transform_point3(Vec3::from(p)))
            .collect();
        let n = positions.len();

        let indices: Vec<u32> = match prim.indices() {
            Some(acc) => self.read_indices(&acc, &group)?,
            None => (0..n as u32).collect(),
        };
        if let Some((k, &bad)) = indices.iter().enumerate().find(|(_, &i)| i as usize >= n) {
            return Err(Error::invalid(
                path,
                format!(
                    "primitive '{group}': index {k} is {bad} but there are only {n} vertices \
                     (re-export the mesh)"
                ),
            ));
        }
        let mut tris = assemble_triangles(mode, &indices);
        if mode == Mode::Triangles && !indices.len().is_multiple_of(3) {
            self.warn(&format!(
                "primitive '{group}' has {} indices, not a multiple of 3; the last {} ignored",
                indices.len(),
                indices.len() % 3
            ));
        }
        // A mirroring transform turns counter-clockwise into clockwise: swap to restore it.
        if det < 0.0 {
            for t in &mut tris {
                t.swap(1, 2);
            }
        }

        let uvs = self.read_uvs(prim, &group, n)?;
        let normals = match prim.get(&Semantic::Normals) {
            Some(acc) => {
                let file = self.read_floats::<3>(&acc, &group, "NORMAL")?;
                if file.len() != n {
                    return Err(count_mismatch(path, &group, "NORMAL", file.len(), n));
                }
                let to_world = linear.inverse().transpose();
                let derived = BaseMesh::angle_weighted_normals(&positions, &tris);
                file.into_iter()
                    .zip(derived)
                    .map(|(v, d)| (to_world * Vec3::from(v)).try_normalize().unwrap_or(d))
                    .collect()
            }
            None => BaseMesh::angle_weighted_normals(&positions, &tris),
        };

        let base = self.mesh.positions.len() as u32;
        let g = self.mesh.groups.len() as u32;
        self.mesh.groups.push(group);
        self.mesh.positions.extend(positions);
        self.mesh.normals.extend(normals);
        self.mesh.uvs.extend(uvs);
        // No material: the slot after the file's (`BaseMesh::group_material`).
        self.mesh.group_material.push(
            prim.material()
                .index()
                .map_or(self.materials as u32, |i| i as u32),
        );
        for t in tris {
            self.mesh.triangles.push(t.map(|i| i + base));
            self.mesh.face_group.push(g);
        }
        Ok(())
    }

    /// TEXCOORD_<uv_set> with v flipped to point up; zeros (and `missing_uvs`) when the
    /// primitive has no TEXCOORD at all.
    fn read_uvs(&mut self, prim: &::gltf::Primitive, group: &str, n: usize) -> Result<Vec<Vec2>> {
        let set = self.opts.uv_set;
        let Some(acc) = prim.get(&Semantic::TexCoords(set)) else {
            let mut present: Vec<u32> = prim
                .attributes()
                .filter_map(|(s, _)| match s {
                    Semantic::TexCoords(k) => Some(k),
                    _ => None,
                })
                .collect();
            if present.is_empty() {
                self.any_uv_missing = true;
                return Ok(vec![Vec2::ZERO; n]);
            }
            present.sort();
            let names: Vec<String> = present.iter().map(|k| format!("TEXCOORD_{k}")).collect();
            return Err(Error::invalid(
                self.path,
                format!(
                    "primitive '{group}' has no TEXCOORD_{set}; it has {} (choose one with --uv-set)",
                    names.join(", ")
                ),
            ));
        };
        let attr = format!("TEXCOORD_{set}");
        let uvs = self.read_floats::<2>(&acc, group, &attr)?;
        if uvs.len() != n {
            return Err(count_mismatch(self.path, group, &attr, uvs.len(), n));
        }
        Ok(uvs
            .into_iter()
            .map(|[u, v]| Vec2::new(u, 1.0 - v))
            .collect())
    }

    /// The bytes of an accessor's elements, with every offset checked against its buffer.
    fn accessor_layout(
        &self,
        acc: &::gltf::Accessor,
        group: &str,
        attr: &str,
    ) -> Result<(&[u8], usize, usize)> {
        let path = self.path;
        let fail = |what: String| {
            Error::invalid(
                path,
                format!(
                    "primitive '{group}', {attr} (accessor #{}): {what}",
                    acc.index()
                ),
            )
        };
        if acc.sparse().is_some() {
            return Err(fail(
                "sparse accessors are not supported (re-export without sparse data)".into(),
            ));
        }
        let view = acc.view().ok_or_else(|| {
            fail(
                "has no bufferView (compressed meshes are not supported; re-export uncompressed)"
                    .into(),
            )
        })?;
        let buffer = &self.buffers[view.buffer().index()];
        let view_bytes = view
            .offset()
            .checked_add(view.length())
            .and_then(|end| buffer.get(view.offset()..end))
            .ok_or_else(|| {
                fail(format!(
                    "bufferView #{} lies outside its buffer (truncated file?)",
                    view.index()
                ))
            })?;
        let elem = acc.size();
        let stride = view.stride().unwrap_or(elem);
        if stride < elem {
            return Err(fail(format!(
                "byteStride {stride} is smaller than an element ({elem} bytes)"
            )));
        }
        let count = acc.count();
        let needed = match count {
            0 => Some(0),
            _ => (count - 1)
                .checked_mul(stride)
                .and_then(|x| x.checked_add(elem))
                .and_then(|x| x.checked_add(acc.offset())),
        };
        let data = needed
            .and_then(|end| view_bytes.get(acc.offset().min(end)..end))
            .ok_or_else(|| {
                fail(format!(
                    "{count} elements do not fit in bufferView #{} (truncated file?)",
                    view.index()
                ))
            })?;
        Ok((data, stride, count))
    }

    /// N components per element, converted to f32 (normalised integers mapped to [0,1] / [-1,1]).
    fn read_floats<const N: usize>(
        &self,
        acc: &::gltf::Accessor,
        group: &str,
        attr: &str,
    ) -> Result<Vec<[f32; N]>> {
        let want = match N {
            2 => Dimensions::Vec2,
            3 => Dimensions::Vec3,
            _ => Dimensions::Scalar,
        };
        if acc.dimensions() != want {
            return Err(Error::invalid(
                self.path,
                format!(
                    "primitive '{group}', {attr} is {:?}, expected {want:?} (re-export)",
                    acc.dimensions()
                ),
            ));
        }
        let (data, stride, count) = self.accessor_layout(acc, group, attr)?;
        let (ty, norm) = (acc.data_type(), acc.normalized());
        let size = ty.size();
        Ok((0..count)
            .map(|e| std::array::from_fn(|c| component(&data[e * stride + c * size..], ty, norm)))
            .collect())
    }

    fn read_indices(&self, acc: &::gltf::Accessor, group: &str) -> Result<Vec<u32>> {
        let ty = acc.data_type();
        if acc.dimensions() != Dimensions::Scalar
            || !matches!(ty, DataType::U8 | DataType::U16 | DataType::U32)
        {
            return Err(Error::invalid(
                self.path,
                format!(
                    "primitive '{group}': indices are {:?} {ty:?}, expected unsigned integer scalars (re-export)",
                    acc.dimensions()
                ),
            ));
        }
        let (data, stride, count) = self.accessor_layout(acc, group, "indices")?;
        Ok((0..count)
            .map(|e| {
                let b = &data[e * stride..];
                match ty {
                    DataType::U8 => b[0] as u32,
                    DataType::U16 => u16::from_le_bytes([b[0], b[1]]) as u32,
                    _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                }
            })
            .collect())
    }
}

/// One component at the start of `b` (the caller guarantees its bytes are there).
fn component(b: &[u8], ty: DataType, normalized: bool) -> f32 {
    let (raw, scale) = match ty {
        DataType::I8 => (b[0] as i8 as f32, 127.0),
        DataType::U8 => (b[0] as f32, 255.0),
        DataType::I16 => (i16::from_le_bytes([b[0], b[1]]) as f32, 32767.0),
        DataType::U16 => (u16::from_le_bytes([b[0], b[1]]) as f32, 65535.0),
        DataType::U32 => (u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32, 1.0),
        DataType::F32 => return f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
    };
    if normalized {
        (raw / scale).max(-1.0)
    } else {
        raw
    }
}

/// Triangles of a list, strip or fan (glTF 2.0 §3.7.2.1 orders the corners of each).
fn assemble_triangles(mode: Mode, idx: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::TriangleStrip => (0..idx.len().saturating_sub(2))
            .map(|i| match i % 2 {
                0 => [idx[i], idx[i + 1], idx[i + 2]],
                _ => [idx[i + 1], idx[i], idx[i + 2]],
            })
            .collect(),
        Mode::TriangleFan => (1..idx.len().saturating_sub(1))
            .map(|i| [idx[0], idx[i], idx[i + 1]])
            .collect(),
        _ => idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
    }
}

fn count_mismatch(path: &Path, group: &str, attr: &str, got: usize, n: usize) -> Error {
    Error::invalid(
        path,
        format!("primitive '{group}': {attr} has {got} elements but POSITION has {n} (re-export)"),
    )
}
