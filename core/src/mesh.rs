//! `BaseMesh`: the one in-memory form every loader produces and every later stage reads.
//!
//! Positions are world space (node transforms applied), normals are unit length, and UVs follow
//! the single convention of the project: `v` points *up* the image (OBJ, Blender, USD). The glTF
//! loader flips `v` on load. Triangles are counter-clockwise seen from outside.

use glam::{Vec2, Vec3};
use serde::Serialize;
use std::path::PathBuf;

/// Up axis of the asset's own frame; glTF is Y-up, OBJ is taken as Y-up, USD says so itself.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum UpAxis {
    #[default]
    Y,
    Z,
}

impl UpAxis {
    /// The axis as a unit vector.
    pub fn vector(self) -> glam::Vec3 {
        match self {
            UpAxis::Y => glam::Vec3::Y,
            UpAxis::Z => glam::Vec3::Z,
        }
    }
}

/// How a camera maps the scene to the image.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(tag = "projection", rename_all = "lowercase")]
pub enum Projection {
    /// A pinhole with this vertical field of view, in degrees.
    Perspective { yfov_deg: f32 },
    /// Parallel rays along the view from a plane through the camera; the view is `height`
    /// scene units tall (USD: `verticalAperture` / 10; Blender: the orthographic scale of a
    /// square or portrait image; glTF: `SceneCamera::larger_side`).
    Orthographic { height: f32 },
}

/// A camera found in the scene file (a glTF or USD camera), in world space.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SceneCamera {
    pub from: Vec3,
    pub to: Vec3,
    pub up: Vec3,
    /// The view's height: a pinhole's vertical field of view, an orthographic view's size.
    pub projection: Projection,
    /// The film back's width over its height (USD: `horizontalAperture / verticalAperture`):
    /// an image narrower than that widens the view so that the whole film back stays in it
    /// (`Camera::from_scene`; USD's default `expandAperture` conform policy). `None` (glTF):
    /// the projection's height whatever the image's shape.
    pub film_aspect: Option<f32>,
    /// An orthographic view whose `height` spans the image's larger side, not its height (a
    /// glTF camera: twice the larger of `xmag` and `ymag`, as Blender's importer makes its
    /// orthographic scale, which Blender's automatic sensor fit lays along the larger side).
    pub larger_side: bool,
}

/// A USD `DomeLight` (or `DomeLight_1`): the environment a beauty lights with where `--env` is
/// not given.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneDome {
    /// The prim's path.
    pub name: String,
    /// Its latitude-longitude texture (`inputs:texture:file`), resolved; `None`: a dome of
    /// constant colour.
    pub texture: Option<PathBuf>,
    /// `inputs:color × inputs:intensity × 2^inputs:exposure`, linear RGB.
    pub tint: [f32; 3],
    /// Its turn about the stage's up axis from OpenEXR's latitude-longitude orientation (the
    /// dome's default), degrees, counter-clockwise seen from above.
    pub turn_deg: f32,
}

/// A light's linear RGB colour split into its luminance and the colour of unit luminance
/// (`SceneSun::color`); white for a black light. `None` where a component is negative or not
/// finite.
pub fn split_color(rgb: glam::Vec3) -> Option<(f32, [f32; 3])> {
    if !(rgb.is_finite() && rgb.min_element() >= 0.0) {
        return None;
    }
    let luminance = crate::render::shading::luminance(rgb);
    let unit = match luminance > 0.0 {
        true => rgb / luminance,
        false => glam::Vec3::ONE,
    };
    unit.is_finite().then_some((luminance, unit.to_array()))
}

/// A directional light (a USD `DistantLight`, a glTF `KHR_lights_punctual` directional light):
/// the beauty's key light where `--key-light` is not given.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneSun {
    /// The USD prim's path, or the glTF node's name (else `node #N`).
    pub name: String,
    /// `--key-light`'s azimuth, elevation (degrees, towards the light: the prim's +Z, as it
    /// shines down its −Z) and irradiance (`inputs:intensity × 2^inputs:exposure`, times the
    /// disc's solid angle unless `inputs:normalize`, times the luminance of `inputs:color`).
    pub key: [f32; 3],
    /// Its colour (`inputs:color`, glTF's `color`) over its luminance: white is (1, 1, 1), and
    /// the irradiance above is the light's luminance.
    pub color: [f32; 3],
    /// Its angular diameter (`inputs:angle`, USD's default 0.53°), `--key-angle`'s.
    pub angle_deg: f32,
}

/// A light of the scene file besides its first directional light (`BaseMesh::lights`), in the
/// mesh's own frame, as the beauty samples it.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneLight {
    /// The USD prim's path, or the glTF node's name (else `node #N`).
    pub name: String,
    pub light: crate::render::lights::Light,
}

impl SceneLight {
    /// "point '/Bulb' at (0, 3, 0), intensity 7.96, colour (…)", for the summary and `inspect`.
    pub fn describe(&self) -> String {
        use crate::render::lights::LightShape;
        let l = &self.light;
        let v = |v: glam::Vec3| format!("({:.3}, {:.3}, {:.3})", v.x, v.y, v.z);
        // A size to four decimals, without f32's noise (1.4999999) or trailing zeros.
        let size = |x: f32| {
            let s = format!("{x:.4}");
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        };
        let tint = match l.color == glam::Vec3::ONE {
            true => String::new(),
            false => format!(", colour {}", v(l.color)),
        };
        match l.shape {
            LightShape::Distant { dir, cos_radius } => format!(
                "directional '{}' towards {}, irradiance {}{tint}, {:.3}° across",
                self.name,
                v(dir),
                l.power,
                2.0 * cos_radius.clamp(-1.0, 1.0).acos().to_degrees()
            ),
            LightShape::Area {
                pos,
                u,
                v: side,
                disk,
            } => {
                let (w, h) = (size(2.0 * u.length()), size(2.0 * side.length()));
                let size = match disk {
                    true => format!("{w} × {h} across"),
                    false => format!("{w} × {h}"),
                };
                format!(
                    "{} '{}' at {}, {size}, shining along {}, radiance {}{tint}",
                    if disk { "disk" } else { "rect" },
                    self.name,
                    v(pos),
                    v(crate::render::lights::area_and_normal(u, side, disk).1),
                    l.power
                )
            }
            LightShape::Local { pos, radius, spot } => {
                let what = match (spot, radius > 0.0) {
                    (Some(_), _) => "spot",
                    (None, true) => "sphere",
                    (None, false) => "point",
                };
                let size = match radius > 0.0 {
                    true => format!(", radius {}", size(radius)),
                    false => String::new(),
                };
                let cone = spot.map_or(String::new(), |s| {
                    format!(
                        ", cone {:.1}° to {:.1}° about {}",
                        s.cos_inner.clamp(-1.0, 1.0).acos().to_degrees(),
                        s.cos_outer.clamp(-1.0, 1.0).acos().to_degrees(),
                        v(s.axis)
                    )
                });
                format!(
                    "{what} '{}' at {}{size}, intensity {}{tint}{cone}",
                    self.name,
                    v(pos),
                    l.power
                )
            }
        }
    }
}

impl SceneSun {
    /// "'/Sun' (azimuth 30.0°, elevation 45.0°, irradiance 3, colour (1.2, 0.9, 0.8), 0.53°
    /// across)", the colour left out for white, at angular diameter `angle_deg`.
    pub fn describe(&self, angle_deg: f32) -> String {
        let [az, el, irradiance] = self.key;
        let tint = match self.color == [1.0; 3] {
            true => String::new(),
            false => {
                let [r, g, b] = self.color;
                format!(", colour ({r:.3}, {g:.3}, {b:.3})")
            }
        };
        format!(
            "'{}' (azimuth {az:.1}°, elevation {el:.1}°, irradiance {irradiance}{tint}, \
             {angle_deg}° across)",
            self.name
        )
    }
}

/// A scene camera with the names `--camera` finds it by.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedCamera {
    /// The first is the one messages show (a glTF node's name, else `node #N`; a USD prim's
    /// path); the others also pick it (glTF: `node #N` and the camera's own name; USD: the
    /// prim's name).
    pub names: Vec<String>,
    pub camera: SceneCamera,
}

#[derive(Clone, Debug, Default)]
pub struct BaseMesh {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle: index into `groups` (the source node/primitive or OBJ group name).
    pub face_group: Vec<u32>,
    pub groups: Vec<String>,
    /// Per triangle, flags from repair (see `FACE_*`).
    pub face_flags: Vec<u8>,
    pub source: PathBuf,
    pub up_axis: Option<UpAxis>,
    /// The file's perspective cameras that can be rendered through, in file order.
    pub cameras: Vec<NamedCamera>,
    /// The scene file's dome light (USD), the first if there are several.
    pub dome: Option<SceneDome>,
    /// The scene file's directional light (USD, glTF), the first if there are several.
    pub sun: Option<SceneSun>,
    /// The file's other lights the beauty renders: later directional lights, points, spheres
    /// and spots, in the file's order.
    pub lights: Vec<SceneLight>,
    /// True when the file carried no UVs at all (every UV is then zero).
    pub missing_uvs: bool,
    /// The file's materials (glTF's metallic-roughness), in its order.
    pub materials: Vec<MeshMaterial>,
    /// Per group (`groups`: a glTF primitive has one material): index into `materials`, or
    /// `materials.len()` for none (the beauty's default grey). Empty: no group has one.
    pub group_material: Vec<u32>,
    /// UV seams found by repair (empty straight from a loader): pairs of triangle edges with
    /// the same positions and normals but different UVs.
    pub seams: Vec<SeamEdge>,
}

/// A material of the asset file as the beauty reads it (glTF's metallic-roughness model).
#[derive(Clone, Debug, PartialEq)]
pub struct MeshMaterial {
    /// For messages: its name, else `material N`.
    pub name: String,
    /// Base colour factor, linear RGBA.
    pub base_color: [f32; 4],
    /// `roughnessFactor`, `metallicFactor` (1 where the file leaves them out, as glTF says).
    pub roughness: f32,
    pub metallic: f32,
    /// The base-colour texture, multiplied into `base_color` (decoded when a beauty render
    /// needs it, `texture::ColorMap::load`).
    pub base_color_texture: Option<crate::texture::TextureRef>,
    /// A texture channel multiplied into `roughness` (glTF's metallic-roughness texture's
    /// green).
    pub roughness_texture: Option<crate::texture::ChannelRef>,
    /// A texture channel multiplied into `metallic` (the metallic-roughness texture's blue).
    pub metallic_texture: Option<crate::texture::ChannelRef>,
    /// A tangent-space normal map that bends the shading normal (glTF's `normalTexture`).
    pub normal_texture: Option<crate::texture::NormalMapRef>,
    /// Emitted radiance, linear RGB (glTF's `emissiveFactor` times its
    /// `KHR_materials_emissive_strength`); zero for a surface that does not glow.
    pub emission: [f32; 3],
    /// A colour texture multiplied into `emission` (glTF's `emissiveTexture`).
    pub emission_texture: Option<crate::texture::TextureRef>,
    /// The dielectric reflectance at normal incidence (F0) the file's index of refraction
    /// gives (`ior_f0`; glTF's `KHR_materials_ior` times `KHR_materials_specular`'s factor,
    /// USD's `ior`, an `.mtl`'s `Ni`); `None`: the renderer's default.
    pub specular: Option<f32>,
    /// The specular layer's tint (glTF `KHR_materials_specular`'s `specularColorFactor`, which
    /// Blender imports as the Principled BSDF's Specular Tint): the dielectric's F0 times it,
    /// a metal's reflectance at grazing angles towards it (F82); `None`: white.
    pub specular_tint: Option<[f32; 3]>,
    /// The clearcoat's weight in [0, 1] (glTF `KHR_materials_clearcoat`'s `clearcoatFactor`,
    /// USD's `clearcoat`, an `.mtl`'s `Pc`; 0: none) and its roughness (`clearcoatRoughness…`,
    /// `Pcr`).
    pub clearcoat: f32,
    pub clearcoat_roughness: f32,
    /// Texture channels multiplied into them (glTF's `clearcoatTexture`'s red,
    /// `clearcoatRoughnessTexture`'s green).
    pub clearcoat_texture: Option<crate::texture::ChannelRef>,
    pub clearcoat_roughness_texture: Option<crate::texture::ChannelRef>,
    /// The clearcoat's own tangent-space normal map (glTF's `clearcoatNormalTexture`), which
    /// bends its normal (the surface's before `normal_texture` bends it); `None`: it lies on
    /// that unbent surface.
    pub clearcoat_normal_texture: Option<crate::texture::NormalMapRef>,
    /// How the alpha (`base_color[3]` times `alpha_texture`) cuts the surface away.
    pub alpha_mode: AlphaMode,
    /// A texture channel multiplied into the alpha (glTF's base-colour texture's alpha, a USD
    /// `opacity` texture's).
    pub alpha_texture: Option<crate::texture::ChannelRef>,
}

/// How a material's alpha cuts its surface away, as Blender's importers wire the Principled
/// BSDF's Alpha and Cycles renders it (a ray passes through where the surface is not there).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AlphaMode {
    /// The alpha is not read (glTF's `OPAQUE`, the default).
    #[default]
    Opaque,
    /// There where the alpha is at least the cutoff, else not (glTF's `MASK` and
    /// `alphaCutoff`, USD's `opacityThreshold` above 0).
    Mask(f32),
    /// There with the alpha's probability: a ray passes through with 1 − alpha (glTF's
    /// `BLEND`, an `.mtl`'s `d`, USD's `opacity`).
    Blend,
}

/// The reflectance at normal incidence of a dielectric of index of refraction `ior` in air,
/// `((ior − 1) / (ior + 1))²`; `None` for an index below 1 or not a number.
pub fn ior_f0(ior: f32) -> Option<f32> {
    (ior >= 1.0 && ior.is_finite()).then(|| ((ior - 1.0) / (ior + 1.0)).powi(2))
}

impl MeshMaterial {
    /// A material of these factors without textures.
    pub fn plain(name: String, base_color: [f32; 4], roughness: f32, metallic: f32) -> Self {
        MeshMaterial {
            name,
            base_color,
            roughness,
            metallic,
            base_color_texture: None,
            roughness_texture: None,
            metallic_texture: None,
            normal_texture: None,
            emission: [0.0; 3],
            emission_texture: None,
            specular: None,
            specular_tint: None,
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
            clearcoat_texture: None,
            clearcoat_roughness_texture: None,
            clearcoat_normal_texture: None,
            alpha_mode: AlphaMode::Opaque,
            alpha_texture: None,
        }
    }

    /// Whether the alpha may cut its surface away anywhere: a mode other than opaque with an
    /// alpha texture or a factor that the mode does not make 1.
    pub fn cuts_out(&self) -> bool {
        let a = self.base_color[3];
        match self.alpha_mode {
            AlphaMode::Opaque => false,
            AlphaMode::Mask(cutoff) => self.alpha_texture.is_some() || a < cutoff || a.is_nan(),
            AlphaMode::Blend => self.alpha_texture.is_some() || a < 1.0 || a.is_nan(),
        }
    }

    /// Its textures, each with the input it feeds, in the order base colour, roughness,
    /// metallic, normal, emission, clearcoat, clearcoat roughness, clearcoat normal, alpha
    /// (one image may feed two).
    pub fn textures(&self) -> Vec<(crate::texture::TextureSlot, &crate::texture::TextureRef)> {
        use crate::texture::TextureSlot;
        let mut out = vec![];
        if let Some(t) = &self.base_color_texture {
            out.push((TextureSlot::BaseColor, t));
        }
        if let Some(c) = &self.roughness_texture {
            out.push((TextureSlot::Roughness, &c.texture));
        }
        if let Some(c) = &self.metallic_texture {
            out.push((TextureSlot::Metallic, &c.texture));
        }
        if let Some(n) = &self.normal_texture {
            out.push((TextureSlot::Normal, &n.texture));
        }
        if let Some(t) = &self.emission_texture {
            out.push((TextureSlot::Emission, t));
        }
        if let Some(c) = &self.clearcoat_texture {
            out.push((TextureSlot::Clearcoat, &c.texture));
        }
        if let Some(c) = &self.clearcoat_roughness_texture {
            out.push((TextureSlot::ClearcoatRoughness, &c.texture));
        }
        if let Some(n) = &self.clearcoat_normal_texture {
            out.push((TextureSlot::ClearcoatNormal, &n.texture));
        }
        if let Some(c) = &self.alpha_texture.as_ref().filter(|_| self.cuts_out()) {
            out.push((TextureSlot::Alpha, &c.texture));
        }
        out
    }

    /// Read every texture through UV set `set` (USD: the mesh's own primvar, whichever set
    /// it is loaded as).
    pub fn set_tex_coord(&mut self, set: u32) {
        let refs = [
            self.base_color_texture.as_mut(),
            self.roughness_texture.as_mut().map(|c| &mut c.texture),
            self.metallic_texture.as_mut().map(|c| &mut c.texture),
            self.normal_texture.as_mut().map(|n| &mut n.texture),
            self.emission_texture.as_mut(),
            self.clearcoat_texture.as_mut().map(|c| &mut c.texture),
            self.clearcoat_roughness_texture
                .as_mut()
                .map(|c| &mut c.texture),
            self.clearcoat_normal_texture
                .as_mut()
                .map(|n| &mut n.texture),
            self.alpha_texture.as_mut().map(|c| &mut c.texture),
        ];
        for t in refs.into_iter().flatten() {
            t.tex_coord = set;
        }
    }

    /// Its distinct textures, each with the inputs it feeds (`textures`, an image that feeds
    /// two once).
    pub fn texture_uses(
        &self,
    ) -> Vec<(
        Vec<crate::texture::TextureSlot>,
        &crate::texture::TextureRef,
    )> {
        let mut out: Vec<(Vec<_>, &crate::texture::TextureRef)> = vec![];
        for (slot, t) in self.textures() {
            match out.iter_mut().find(|(_, u)| *u == t) {
                Some((slots, _)) => slots.push(slot),
                None => out.push((vec![slot], t)),
            }
        }
        out
    }
}

/// Most materials a mesh may have: a prism keeps its material's index in the upper 24 bits of
/// its flags (`bake::Prism::material`).
pub const MAX_MATERIALS: usize = (1 << 24) - 1;

/// A UV seam: edge `edges[0]` of triangle `faces[0]` and edge `edges[1]` of `faces[1]` lie on
/// the same positions with the same normals, but their vertex records carry different UVs.
/// Edge `k` of a triangle is the one opposite its corner `k` (corners `k+1 → k+2`, mod 3); the
/// two edges run in opposite directions, so corner `k0+1` of face 0 sits where corner `k1+2`
/// of face 1 does, and `k0+2` where `k1+1` does. Triangles and prisms are numbered alike,
/// so the prism table stores the same records.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct SeamEdge {
    pub faces: [u32; 2],
    pub edges: [u8; 2],
}

impl SeamEdge {
    /// The two corners of face `side`'s edge, in that face's order (`k+1`, `k+2`).
    pub fn corners(&self, side: usize) -> [usize; 2] {
        let k = self.edges[side] as usize;
        [(k + 1) % 3, (k + 2) % 3]
    }
}

/// A triangle inserted by crease repair to stitch a hard edge: zero base area by construction.
pub const FACE_INSERTED: u8 = 1;
/// A triangle whose UV area is (nearly) zero: the map is sampled along a line across it.
pub const FACE_UV_DEGENERATE: u8 = 2;

/// `'a', 'b'`: names quoted for a message, joined by `sep`.
fn quoted<S: AsRef<str>>(names: impl IntoIterator<Item = S>, sep: &str) -> String {
    let names: Vec<String> = names
        .into_iter()
        .map(|n| format!("'{}'", n.as_ref()))
        .collect();
    names.join(sep)
}

impl BaseMesh {
    /// The scene camera `--camera NAME` picks (any of a camera's `names`), else the file's
    /// first; `None` when the file has none. A name no camera has, or several have, is an
    /// error listing the file's cameras.
    pub fn pick_camera(&self, name: Option<&str>) -> crate::error::Result<Option<SceneCamera>> {
        Ok(self.pick_named_camera(name)?.map(|c| c.camera))
    }

    /// `pick_camera`, with the camera's names.
    pub fn pick_named_camera(
        &self,
        name: Option<&str>,
    ) -> crate::error::Result<Option<&NamedCamera>> {
        let Some(name) = name else {
            return Ok(self.cameras.first());
        };
        let found: Vec<&NamedCamera> = self
            .cameras
            .iter()
            .filter(|c| c.names.iter().any(|n| n == name))
            .collect();
        match found[..] {
            [one] => Ok(Some(one)),
            [] => Err(crate::error::Error::invalid(
                &self.source,
                match self.cameras.is_empty() {
                    true => format!(
                        "has no perspective camera to pick '{name}' from (leave --camera out: \
                         the view is then framed from the bounds)"
                    ),
                    false => format!(
                        "has no camera named '{name}' that can be rendered through; its \
                         cameras: {} (pass one of them to --camera, or leave --camera out)",
                        quoted(self.cameras.iter().map(|c| &c.names[0]), ", ")
                    ),
                },
            )),
            _ => Err(crate::error::Error::invalid(
                &self.source,
                format!(
                    "has {} cameras named '{name}': {} (pass another of the names of the one you \
                     mean)",
                    found.len(),
                    found
                        .iter()
                        .map(|c| quoted(&c.names, " or "))
                        .collect::<Vec<_>>()
                        .join("; ")
                ),
            )),
        }
    }

    /// Triangle `t`'s material: an index into `materials`, or `materials.len()` for none.
    pub fn face_material(&self, t: usize) -> u32 {
        let none = self.materials.len() as u32;
        let group = self.face_group.get(t).copied().unwrap_or(0) as usize;
        self.group_material
            .get(group)
            .copied()
            .unwrap_or(none)
            .min(none)
    }

    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }
    pub fn corners(&self, t: usize) -> [Vec3; 3] {
        self.triangles[t].map(|i| self.positions[i as usize])
    }
    pub fn corner_normals(&self, t: usize) -> [Vec3; 3] {
        self.triangles[t].map(|i| self.normals[i as usize])
    }
    pub fn corner_uvs(&self, t: usize) -> [Vec2; 3] {
        self.triangles[t].map(|i| self.uvs[i as usize])
    }
    /// Unnormalised geometric normal (twice the area vector).
    pub fn face_cross(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.corners(t);
        (b - a).cross(c - a)
    }
    /// Human name of a face for messages: `face 12 (group 'Sphere/0')`.
    pub fn face_name(&self, t: usize) -> String {
        match self
            .face_group
            .get(t)
            .and_then(|&g| self.groups.get(g as usize))
        {
            Some(g) => format!("face {t} (group '{g}')"),
            None => format!("face {t}"),
        }
    }
    /// World-space bounds of the base positions.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
    }

    /// Angle-weighted vertex normals from the faces (used where a file has none).
    pub fn angle_weighted_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
        let mut acc = vec![Vec3::ZERO; positions.len()];
        for tri in triangles {
            let p = tri.map(|i| positions[i as usize]);
            let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            for k in 0..3 {
                let e1 = (p[(k + 1) % 3] - p[k]).normalize_or_zero();
                let e2 = (p[(k + 2) % 3] - p[k]).normalize_or_zero();
                let angle = e1.dot(e2).clamp(-1.0, 1.0).acos();
                acc[tri[k] as usize] += n * angle;
            }
        }
        acc.into_iter()
            .map(|n| n.try_normalize().unwrap_or(Vec3::Z))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::texture::*;

    #[test]
    fn set_tex_coord_reaches_every_texture_of_a_material() {
        let t = |name: &str| TextureRef {
            name: name.into(),
            data: TextureData::File(name.into()),
            sampler: Sampler::default(),
            tex_coord: 0,
            transform: UvTransform::IDENTITY,
            color_space: ColorSpace::Raw,
            scale_bias: None,
        };
        let channel = |name| {
            Some(ChannelRef {
                texture: t(name),
                channel: 1,
            })
        };
        let mut m = MeshMaterial {
            base_color_texture: Some(t("colour")),
            roughness_texture: channel("rough"),
            metallic_texture: channel("metal"),
            normal_texture: Some(NormalMapRef::unit(t("normal"), 1.0)),
            emission_texture: Some(t("glow")),
            clearcoat_texture: channel("coat"),
            clearcoat_roughness_texture: channel("coat roughness"),
            clearcoat_normal_texture: Some(NormalMapRef::unit(t("coat normal"), 1.0)),
            alpha_mode: AlphaMode::Mask(0.5),
            alpha_texture: channel("alpha"),
            ..MeshMaterial::plain("m".into(), [1.0; 4], 0.5, 0.0)
        };
        m.set_tex_coord(2);
        let sets: Vec<(TextureSlot, u32)> = m
            .textures()
            .iter()
            .map(|(slot, t)| (*slot, t.tex_coord))
            .collect();
        assert_eq!(sets.len(), 9, "{sets:?}");
        assert!(sets.iter().all(|&(_, set)| set == 2), "{sets:?}");
    }
}
