//! Lookdev: a `RenderJob` plus beauty settings → AOV and beauty frames, contact sheets for
//! turntables, a cached prism table, and `watch` (re-render when the height map changes,
//! re-baking only the prisms whose bounds no longer hold).
//!
//! Frames are rendered by a `FrameRenderer`: the CPU intersectors here (`run`), or the GPU
//! renderer (`prismbake-gpu`), which opens the same `Session` (loading, cache, camera,
//! environment) and hands its renderer to the same `render_all` (frames, files, sheets).
//!
//! Only what the outputs need is computed: an AOV-only job builds no environment and shades
//! nothing; a beauty job without `--key-light` casts no key-light shadow rays and a black
//! environment casts no environment rays; the bake is skipped when the table cache holds a
//! table made from the same inputs (`table_cache`, keyed by `asset::input_hash`).

use super::beauty::{
    self, BeautyCounters, BeautyImage, BeautyScene, Ground, KeyLight, NormalTex, SurfaceMaterial,
    TexChannel,
};
use super::camera::Camera;
use super::cutout::{AlphaCut, Cutout};
use super::denoise::{Denoiser, Quality};
use super::env::{EnvFrame, EnvMap};
use super::job::{
    base_camera, prepare_out_dir, with_intersector, FrameStats, Input, Loaded, RenderJob,
    RenderSummary,
};
use super::lights::{Light, LightSet, MAX_LIGHTS};
use super::shading::{Material, DEFAULT_CLEARCOAT_ROUGHNESS};
use super::{contact_sheet, output, render_aovs, Aov, AovImage, RenderSettings};
use crate::accel::Scene;
use crate::asset;
use crate::bake::{self, BakeOptions, RebakeStats};
use crate::error::{Error, Result};
use crate::heightmap::HeightMap;
use crate::load::{self, MapOptions};
use crate::mesh::{AlphaMode, MeshMaterial, SceneLight, SceneSun, UpAxis};
use crate::repair;
use crate::table_cache;
use crate::texture::{ColorMap, TextureRef, TextureSlot};
use crate::trace::Intersector;
use glam::Vec3;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime};

/// The largest `--exposure`, either way, in stops (2^±32 still keeps every f32 radiance a
/// finite number, and no display needs more).
pub const MAX_EXPOSURE_EV: f32 = 32.0;

/// The widest `--key-angle`, degrees: a disc a quarter of the sky across.
pub const MAX_KEY_ANGLE_DEG: f32 = 90.0;

/// Beauty and caching settings (the part of a render the AOV job does not have).
#[derive(Clone, Debug)]
pub struct LookdevOptions {
    /// Equirect EXR; `None` = the built-in neutral sky.
    pub env: Option<PathBuf>,
    pub env_rotate_deg: f32,
    pub env_intensity: f32,
    /// (azimuth°, elevation°, irradiance).
    pub key_light: Option<[f32; 3]>,
    /// The key light's angular diameter in degrees (`--key-angle`): 0 is a point-like sun
    /// with hard shadows, more a disc with soft ones.
    pub key_angle_deg: f32,
    /// The key light's colour (`--key-color`, linear RGB), whichever light is the key; `None`:
    /// white for `key_light`, the file's light's own.
    pub key_color: Option<Vec3>,
    /// Overrides the mesh's material colour and texture (linear RGB).
    pub base_color: Option<Vec3>,
    /// Override the mesh's material's factors (default: its own, else `DEFAULT_ROUGHNESS`,
    /// `DEFAULT_METALLIC`).
    pub roughness: Option<f32>,
    pub metallic: Option<f32>,
    /// Bend the shading normals by the materials' normal maps (`--no-normal-maps`: false).
    pub normal_maps: bool,
    /// Let the materials glow (`--no-emission`: false).
    pub emission: bool,
    /// Let the materials' alpha cut their surfaces away (`mesh::AlphaMode`; `--no-alpha`:
    /// false, every surface opaque).
    pub alpha: bool,
    /// Light with the scene file's dome and directional lights where the flags leave the
    /// environment and the key light to it (`--no-scene-lights`: false).
    pub scene_lights: bool,
    /// The dielectric reflectance F0 of every material (`--specular`); `None`: each
    /// material's own (its file's index of refraction), else `DEFAULT_SPECULAR`.
    pub specular: Option<f32>,
    /// The specular tint of every material (`--specular-tint`); `None`: each material's own
    /// (glTF `KHR_materials_specular`'s colour), else white.
    pub specular_tint: Option<Vec3>,
    /// The clearcoat weight and roughness of every material (`--clearcoat`,
    /// `--clearcoat-roughness`); `None`: each material's own (glTF `KHR_materials_clearcoat`,
    /// USD's `clearcoat`), else none and `DEFAULT_CLEARCOAT_ROUGHNESS`.
    pub clearcoat: Option<f32>,
    pub clearcoat_roughness: Option<f32>,
    pub bounces: u32,
    pub ground: bool,
    /// The previews' exposure in stops (`--exposure`): PNGs and contact sheets show the
    /// radiance times 2^EV before the filmic curve; the EXR is not scaled.
    pub exposure_ev: f32,
    /// Denoise the beauty with Open Image Denoise (`denoise`) at this quality; the library is
    /// loaded when the job opens.
    pub denoise: Option<Quality>,
    /// Folder of cached prism tables; `None` = do not cache.
    pub cache_dir: Option<PathBuf>,
}

impl Default for LookdevOptions {
    fn default() -> Self {
        LookdevOptions {
            env: None,
            env_rotate_deg: 0.0,
            env_intensity: 1.0,
            key_light: None,
            key_angle_deg: 0.0,
            key_color: None,
            base_color: None,
            roughness: None,
            metallic: None,
            normal_maps: true,
            emission: true,
            alpha: true,
            scene_lights: true,
            specular: None,
            specular_tint: None,
            clearcoat: None,
            clearcoat_roughness: None,
            bounces: 2,
            ground: false,
            exposure_ev: 0.0,
            denoise: None,
            cache_dir: table_cache::default_dir(),
        }
    }
}

impl LookdevOptions {
    pub fn validate(&self) -> Result<()> {
        let unit = |name: &str, v: f32| {
            if (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err(Error::Param(format!("{name} {v}: must be in [0, 1]")))
            }
        };
        for (name, v) in [
            ("--roughness", self.roughness),
            ("--metallic", self.metallic),
            ("--clearcoat", self.clearcoat),
            ("--clearcoat-roughness", self.clearcoat_roughness),
        ] {
            if let Some(v) = v {
                unit(name, v)?;
            }
        }
        if let Some(v) = self.specular {
            unit("--specular", v)?;
        }
        if let Some(t) = self.specular_tint {
            for v in t.to_array() {
                unit("--specular-tint", v)?;
            }
        }
        if !(1..=4).contains(&self.bounces) {
            return Err(Error::Param(format!(
                "--bounces {}: must be 1..=4",
                self.bounces
            )));
        }
        if !(self.env_intensity >= 0.0 && self.env_intensity.is_finite()) {
            return Err(Error::Param(format!(
                "--env-intensity {}: must be a finite number >= 0",
                self.env_intensity
            )));
        }
        if !(-MAX_EXPOSURE_EV..=MAX_EXPOSURE_EV).contains(&self.exposure_ev) {
            return Err(Error::Param(format!(
                "--exposure {}: must be a number of stops in [-{MAX_EXPOSURE_EV}, {MAX_EXPOSURE_EV}]",
                self.exposure_ev
            )));
        }
        if !self.env_rotate_deg.is_finite() {
            return Err(Error::Param("--env-rotate must be finite".into()));
        }
        if let Some([az, el, i]) = self.key_light {
            if !(az.is_finite() && (-90.0..=90.0).contains(&el) && i >= 0.0 && i.is_finite()) {
                return Err(Error::Param(format!(
                    "--key-light {az},{el},{i}: expected AZIMUTH,ELEVATION,INTENSITY with elevation in [-90, 90] and intensity >= 0"
                )));
            }
        }
        if !(0.0..=MAX_KEY_ANGLE_DEG).contains(&self.key_angle_deg) {
            return Err(Error::Param(format!(
                "--key-angle {}: must be an angular diameter in [0, {MAX_KEY_ANGLE_DEG}] degrees",
                self.key_angle_deg
            )));
        }
        if let Some(c) = self.key_color {
            if crate::mesh::split_color(c).is_none_or(|(luminance, _)| luminance <= 0.0) {
                return Err(Error::Param(format!(
                    "--key-color {},{},{}: give a linear R,G,B with components >= 0 and some \
                     brightness (e.g. 1,0.9,0.8 for a warm white)",
                    c.x, c.y, c.z
                )));
            }
        }
        if let Some(c) = self.base_color {
            if !(c.is_finite() && c.min_element() >= 0.0 && c.max_element() <= 1.0) {
                return Err(Error::Param(
                    "--base-color: each component must be in [0, 1]".into(),
                ));
            }
        }
        Ok(())
    }
}

/// What the table cache did.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "cache", content = "path")]
pub enum CacheUse {
    /// `--no-cache`, or a baked table given as input.
    Off,
    Reused(PathBuf),
    Stored(PathBuf),
    /// The bake worked but the cache could not be written (the reason).
    NotStored(String),
}

#[derive(Debug, Serialize)]
pub struct LookdevSummary {
    #[serde(flatten)]
    pub render: RenderSummary,
    pub table_cache: CacheUse,
    /// Where frame 0's camera comes from: "the file's camera 'Camera'", "framed from the
    /// bounds", and the flags that override it.
    pub camera: String,
    /// The beauty's environment: "--env PATH", "the file's dome light '/Lights/Dome' (…)" or
    /// "the built-in sky"; absent without beauty.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub environment: Option<String>,
    /// The beauty's key light: "--key-light" or "the file's directional light '/Sun' (…)";
    /// absent without one (or without beauty).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub key_light: Option<String>,
    /// The scene file's other lights the beauty renders (`SceneLight::describe`), with the
    /// key light: absent without any (or without beauty).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub lights: Vec<String>,
    /// Beauty rays over all frames; shadow rays by the light they test.
    pub beauty_rays: BeautyCounters,
    pub shadow_rays: u64,
    pub contact_sheets: Vec<PathBuf>,
    /// The denoiser that filtered the beauty frames ("Open Image Denoise 2.5.1, high quality
    /// (PATH)"); absent without `--denoise`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub denoiser: Option<String>,
    /// The materials the beauty shaded with, those some prism has; empty without beauty.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub materials: Vec<MaterialSummary>,
    /// The process's peak resident memory when the last frame was written (Linux `VmHWM`):
    /// what a farm's memory request must cover. Absent where the system does not say.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_memory_bytes: Option<u64>,
}

/// A material of the beauty as a summary states it: its name, how many prisms have it and
/// what it is.
#[derive(Clone, Debug, Serialize)]
pub struct MaterialSummary {
    /// The asset's name for it, or "default" (triangles without a material).
    pub name: String,
    pub prisms: usize,
    #[serde(flatten)]
    pub material: MaterialDescription,
}

/// A material's factors, each with the texture that multiplies it, as the render's summary
/// and `inspect` state them (the render names decoded textures by `ColorMap::describe`,
/// "rock_albedo, 256x256, repeat/repeat, bilinear"; `inspect` by their file names).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MaterialDescription {
    pub base_color: [f32; 3],
    pub roughness: f32,
    pub metallic: f32,
    /// The dielectric reflectance F0.
    pub specular: f32,
    /// The specular tint; absent when white.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub specular_tint: Option<[f32; 3]>,
    /// The clearcoat's weight and roughness; absent without one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub clearcoat: Option<[f32; 2]>,
    /// The texture channels multiplied into them; absent without one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub clearcoat_texture: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub clearcoat_roughness_texture: Option<String>,
    /// "coat_normal, ..., strength 1": the clearcoat's own normal map; absent without one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub clearcoat_normal_texture: Option<String>,
    /// The texture multiplied into `base_color`; absent without one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texture: Option<String>,
    /// "rock_orm, ..., channel g": the texture channel multiplied into `roughness`; absent
    /// without one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub roughness_texture: Option<String>,
    /// The same for `metallic`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub metallic_texture: Option<String>,
    /// "rock_normal, ..., strength 1": the normal map that bends the shading normal; absent
    /// without one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub normal_texture: Option<String>,
    /// Emitted radiance, linear RGB; absent for a material that does not glow.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub emission: Option<[f32; 3]>,
    /// The texture multiplied into `emission`; absent without one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub emission_texture: Option<String>,
    /// "mask at 0.5, alpha 1 x texture leaf.png, alpha channel": how the alpha cuts the
    /// surface away (`describe_alpha`); absent where it cuts nothing.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub alpha: Option<String>,
}

/// `m`'s alpha for people, where it cuts its surface away: "mask at C" or "blend", then the
/// factor and, if any, `texture` (the alpha texture as the caller names it) with the channel
/// it reads.
pub fn describe_alpha(m: &MeshMaterial, texture: Option<String>) -> Option<String> {
    let mode = match m.alpha_mode {
        _ if !m.cuts_out() => return None,
        AlphaMode::Opaque => return None,
        AlphaMode::Mask(cutoff) => format!("mask at {cutoff}"),
        AlphaMode::Blend => "blend".to_string(),
    };
    let channel =
        (m.alpha_texture.as_ref()).map_or(String::new(), |c| match c.texture.color_space {
            crate::texture::ColorSpace::Alpha => ", alpha channel".to_string(),
            _ => format!(", channel {}", c.channel_name()),
        });
    let times = texture.map_or(String::new(), |t| format!(" x texture {t}{channel}"));
    Some(format!("{mode}, alpha {}{times}", m.base_color[3]))
}

impl MaterialDescription {
    /// For people: "base colour (r, g, b) x texture T, roughness R x texture U, metallic M,
    /// specular S, normal map N, emission (r, g, b) x texture E": each factor with the texture
    /// that multiplies it, if any, then the normal map and the emission, if any.
    pub fn describe(&self) -> String {
        let [r, g, b] = self.base_color;
        let times = |t: &Option<String>| {
            t.as_ref()
                .map_or(String::new(), |t| format!(" x texture {t}"))
        };
        let normal =
            (self.normal_texture.as_ref()).map_or(String::new(), |t| format!(", normal map {t}"));
        let tint = self.specular_tint.map_or(String::new(), |[r, g, b]| {
            format!(" tinted ({r}, {g}, {b})")
        });
        let coat = self.clearcoat.map_or(String::new(), |[w, r]| {
            format!(
                ", clearcoat {w}{}, clearcoat roughness {r}{}{}",
                times(&self.clearcoat_texture),
                times(&self.clearcoat_roughness_texture),
                (self.clearcoat_normal_texture.as_ref())
                    .map_or(String::new(), |t| format!(", clearcoat normal map {t}"))
            )
        });
        let glow = self.emission.map_or(String::new(), |[r, g, b]| {
            format!(
                ", emission ({r}, {g}, {b}){}",
                times(&self.emission_texture)
            )
        });
        let alpha = (self.alpha.as_ref()).map_or(String::new(), |a| format!(", alpha {a}"));
        format!(
            "base colour ({r}, {g}, {b}){}, roughness {}{}, metallic {}{}, specular {}{tint}{coat}{normal}{glow}{alpha}",
            times(&self.texture),
            self.roughness,
            times(&self.roughness_texture),
            self.metallic,
            times(&self.metallic_texture),
            self.specular,
        )
    }
}

/// "name, W x H, wrapS/wrapT, filter, channel g" of a texture channel of `scene`.
fn describe_channel(scene: &BeautyScene, c: TexChannel) -> String {
    format!(
        "{}, channel {}",
        scene.textures[c.texture as usize].describe(),
        crate::texture::channel_name(c.channel)
    )
}

/// The summaries of the materials of `scene` some prism has, in their order.
fn material_summaries(scene: &BeautyScene, asset: &AssetMaterials) -> Vec<MaterialSummary> {
    let mut prisms = vec![0usize; scene.materials.len()];
    for i in 0..scene.prisms.len() {
        prisms[scene.material_index(i as u32)] += 1;
    }
    scene
        .materials
        .iter()
        .zip(&asset.list)
        .zip(prisms)
        .filter(|(_, n)| *n > 0)
        .map(|((m, a), prisms)| MaterialSummary {
            name: a.name.clone(),
            prisms,
            material: MaterialDescription {
                base_color: m.material.base_color.to_array(),
                roughness: m.material.roughness,
                metallic: m.material.metallic,
                specular: m.material.specular,
                specular_tint: (m.material.specular_tint != Vec3::ONE)
                    .then(|| m.material.specular_tint.to_array()),
                clearcoat: (m.material.clearcoat > 0.0)
                    .then_some([m.material.clearcoat, m.material.clearcoat_roughness]),
                clearcoat_texture: (m.clearcoat_texture)
                    .filter(|_| m.material.clearcoat > 0.0)
                    .map(|c| describe_channel(scene, c)),
                clearcoat_roughness_texture: (m.clearcoat_roughness_texture)
                    .filter(|_| m.material.clearcoat > 0.0)
                    .map(|c| describe_channel(scene, c)),
                clearcoat_normal_texture: (m.clearcoat_normal_texture)
                    .filter(|_| m.material.clearcoat > 0.0)
                    .zip(a.clearcoat_normal_mapping.as_deref())
                    .map(|(n, how)| {
                        format!("{}, {how}", scene.textures[n.texture as usize].describe())
                    }),
                texture: m.texture.map(|t| scene.textures[t as usize].describe()),
                roughness_texture: m.roughness_texture.map(|c| describe_channel(scene, c)),
                metallic_texture: m.metallic_texture.map(|c| describe_channel(scene, c)),
                emission: (m.emission != Vec3::ZERO).then(|| m.emission.to_array()),
                emission_texture: m
                    .emission_texture
                    .filter(|_| m.emission != Vec3::ZERO)
                    .map(|t| scene.textures[t as usize].describe()),
                normal_texture: m.normal_texture.zip(a.normal_mapping.as_deref()).map(
                    |(n, how)| format!("{}, {how}", scene.textures[n.texture as usize].describe()),
                ),
                alpha: a.alpha_summary.clone(),
            },
        })
        .collect()
}

/// What renders the frames of a lookdev job: the CPU (`CpuFrames`, any intersector) or a GPU.
/// Both get the same cameras, settings and `BeautyScene` from `render_all`, which traces a
/// frame while the last one's files are written (hence `Sync`).
pub trait FrameRenderer: Sync {
    /// "cpu (2 threads)", "gpu (adapter name ...)": the summary's `device`.
    fn device(&self) -> String;
    /// Bytes the method holds beyond mesh and map (`Intersector::memory_bytes`).
    fn memory_bytes(&self) -> usize;
    /// One frame of AOVs; `progress` gets the rows finished so far.
    fn render_aovs(
        &self,
        cam: &Camera,
        settings: &RenderSettings,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Result<AovImage>;
    /// One beauty frame; `progress` gets the rows finished so far (scaled over the samples).
    fn render_beauty(
        &self,
        cam: &Camera,
        settings: &RenderSettings,
        scene: &BeautyScene,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Result<BeautyImage>;
    /// The device's own time for the work rendered since the last call (GPU timestamp
    /// queries), reset by the call; `None` where there is no such clock (the CPU, an adapter
    /// without timestamp queries).
    fn take_device_seconds(&self) -> Option<f64> {
        None
    }
}

/// The CPU renderer over any intersector (rayon).
pub struct CpuFrames<'a>(pub &'a dyn Intersector);

impl FrameRenderer for CpuFrames<'_> {
    fn device(&self) -> String {
        format!("cpu ({} threads)", rayon::current_num_threads())
    }
    fn memory_bytes(&self) -> usize {
        self.0.memory_bytes()
    }
    fn render_aovs(
        &self,
        cam: &Camera,
        settings: &RenderSettings,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Result<AovImage> {
        Ok(render_aovs(self.0, cam, settings, progress))
    }
    fn render_beauty(
        &self,
        cam: &Camera,
        settings: &RenderSettings,
        scene: &BeautyScene,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Result<BeautyImage> {
        Ok(beauty::render_beauty(
            self.0, cam, settings, scene, progress,
        ))
    }
}

/// A loaded job (scene, camera, environment, cache outcome), kept between renders by `watch`.
pub struct Session {
    scene: Scene,
    cam0: Camera,
    /// Where `cam0` comes from (`job::describe_camera`).
    camera: String,
    up_axis: UpAxis,
    materials: AssetMaterials,
    env: Option<EnvMap>,
    /// Where `env` comes from (`environment`).
    environment: Option<String>,
    /// The key light: (azimuth°, elevation°, irradiance, angular diameter°) from
    /// `--key-light` and `--key-angle`, else the scene file's directional light (a USD
    /// `DistantLight`, a glTF `KHR_lights_punctual` one); and what the summary says of it.
    key: Option<([f32; 4], Vec3, String)>,
    /// The scene file's other lights (`BaseMesh::lights`; none with `--no-scene-lights`).
    lights: Vec<SceneLight>,
    denoiser: Option<Denoiser>,
    setup_seconds: f64,
    cache: CacheUse,
}

/// Whether the beauty reads a material's texture: only through the UV set the asset is loaded
/// with (`uv_set`), the one every hit carries.
pub fn texture_readable(texture: &TextureRef, uv_set: u32) -> bool {
    texture.tex_coord == uv_set
}

/// What the beauty does not take from material `m`'s textures: each texture feeding an input
/// it `reads` (the command line sets none of them) that reads another UV set than the asset's
/// (`uv_set`) (`render`'s warning, `validate`'s `textures` check).
pub fn texture_notes(
    m: &MeshMaterial,
    uv_set: u32,
    reads: &dyn Fn(TextureSlot) -> bool,
) -> Vec<String> {
    let mut notes = vec![];
    for (mut slots, t) in m.texture_uses() {
        slots.retain(|&slot| reads(slot));
        if slots.is_empty() {
            continue;
        }
        let what = slots
            .iter()
            .map(|s| s.name())
            .collect::<Vec<_>>()
            .join(" and ");
        if !texture_readable(t, uv_set) {
            let factors = slots
                .iter()
                .map(|slot| match slot {
                    TextureSlot::BaseColor => {
                        let c = m.base_color;
                        format!("colour factor ({}, {}, {})", c[0], c[1], c[2])
                    }
                    TextureSlot::Roughness => format!("roughness factor {}", m.roughness),
                    TextureSlot::Metallic => format!("metallic factor {}", m.metallic),
                    TextureSlot::Normal => "own normals".to_string(),
                    TextureSlot::Emission => {
                        let [r, g, b] = m.emission;
                        format!("emission ({r}, {g}, {b})")
                    }
                    TextureSlot::Clearcoat => format!("clearcoat factor {}", m.clearcoat),
                    TextureSlot::ClearcoatRoughness => {
                        format!("clearcoat roughness factor {}", m.clearcoat_roughness)
                    }
                    TextureSlot::ClearcoatNormal => "clearcoat on its unbent normal".to_string(),
                    TextureSlot::Alpha => format!("alpha factor {}", m.base_color[3]),
                })
                .collect::<Vec<_>>()
                .join(" and ");
            let flags = slots
                .iter()
                .map(|s| s.flag())
                .collect::<Vec<_>>()
                .join(", ");
            notes.push(format!(
                "material '{}': its {what} texture ({}) reads TEXCOORD_{} but the asset is \
                 loaded with UV set {uv_set}: it is not read, the beauty shades with its \
                 {factors} (the sidecar's uv_set = {} reads it; {flags} sets one value)",
                m.name, t.name, t.tex_coord, t.tex_coord
            ));
        }
    }
    // A strength of 0 or less: Blender's Normal Map node clamps it to 0, which leaves the
    // surface's own normal (glTF viewers flip the map's x and y for a negative scale).
    let maps = [
        (&m.normal_texture, TextureSlot::Normal),
        (&m.clearcoat_normal_texture, TextureSlot::ClearcoatNormal),
    ];
    for (n, slot) in maps {
        if let Some(n) = n.as_ref().filter(|n| n.strength <= 0.0 && reads(slot)) {
            notes.push(format!(
                "material '{}': its {} texture ({}) has strength {} (glTF's scale, Blender's \
                 Normal Map Strength), which Blender clamps to 0: it changes nothing (flip the \
                 image's channels for a mirrored map, or pass --no-normal-maps to silence this)",
                m.name,
                slot.name(),
                n.texture.name,
                n.strength
            ));
        }
    }
    notes
}

/// What the beauty does not take from the asset's materials, if anything (`texture_notes`).
pub fn material_warning(
    mesh: &crate::mesh::BaseMesh,
    uv_set: u32,
    reads: &dyn Fn(TextureSlot) -> bool,
) -> Option<String> {
    let notes: Vec<String> = mesh
        .materials
        .iter()
        .flat_map(|m| texture_notes(m, uv_set, reads))
        .collect();
    (!notes.is_empty()).then(|| notes.join("; "))
}

/// Roughness of a surface whose asset has no material and no `--roughness`.
pub const DEFAULT_ROUGHNESS: f32 = 0.5;
/// Metallic of a surface whose asset has no material and no `--metallic`.
pub const DEFAULT_METALLIC: f32 = 0.0;
/// Dielectric reflectance F0 of a surface whose material gives none and no `--specular`
/// (an index of refraction of 1.5).
pub const DEFAULT_SPECULAR: f32 = 0.04;
/// Base colour of a surface whose asset has no material and no `--base-color`.
pub const DEFAULT_BASE_COLOR: Vec3 = Vec3::splat(0.8);

/// One of the asset's materials as the beauty reads it (before the command line's overrides).
struct AssetMaterial {
    name: String,
    base_color: Vec3,
    roughness: f32,
    metallic: f32,
    /// Index into `AssetMaterials::textures`.
    texture: Option<u32>,
    roughness_texture: Option<TexChannel>,
    metallic_texture: Option<TexChannel>,
    normal_texture: Option<NormalTex>,
    /// How its normal map's texels become normals, for the summary ("strength 1").
    normal_mapping: Option<String>,
    /// The same for its clearcoat's normal map.
    clearcoat_normal_mapping: Option<String>,
    emission: Vec3,
    emission_texture: Option<u32>,
    specular: f32,
    specular_tint: Vec3,
    clearcoat: f32,
    clearcoat_roughness: f32,
    clearcoat_texture: Option<TexChannel>,
    clearcoat_roughness_texture: Option<TexChannel>,
    clearcoat_normal_texture: Option<NormalTex>,
    /// Its alpha (`AlphaCut::OPAQUE` where it cuts nothing away, or with `--no-alpha`), and
    /// what the summary says of it (`describe_alpha`).
    cut: AlphaCut,
    alpha_summary: Option<String>,
}

/// The asset's materials in file order, then the default one (for triangles without a
/// material: `BaseMesh::group_material`), and their base-colour textures, decoded.
struct AssetMaterials {
    list: Vec<AssetMaterial>,
    textures: Vec<ColorMap>,
}

impl AssetMaterial {
    /// The material of triangles without one.
    fn default_grey() -> Self {
        AssetMaterial {
            name: "default".into(),
            base_color: DEFAULT_BASE_COLOR,
            roughness: DEFAULT_ROUGHNESS,
            metallic: DEFAULT_METALLIC,
            texture: None,
            roughness_texture: None,
            metallic_texture: None,
            normal_texture: None,
            normal_mapping: None,
            clearcoat_normal_mapping: None,
            emission: Vec3::ZERO,
            emission_texture: None,
            specular: DEFAULT_SPECULAR,
            specular_tint: Vec3::ONE,
            clearcoat: 0.0,
            clearcoat_roughness: DEFAULT_CLEARCOAT_ROUGHNESS,
            clearcoat_texture: None,
            clearcoat_roughness_texture: None,
            clearcoat_normal_texture: None,
            cut: AlphaCut::OPAQUE,
            alpha_summary: None,
        }
    }
}

impl AssetMaterials {
    /// The default material alone (no asset materials, or no beauty to shade).
    fn plain() -> Self {
        AssetMaterials {
            list: vec![AssetMaterial::default_grey()],
            textures: vec![],
        }
    }
}

/// A material's values the beauty shades with must be numbers: a NaN or infinite base colour,
/// roughness or metallic (an `.mtl`'s `Kd nan …`, a USD `inf`) would make every pixel it shades
/// NaN. One the command line overrides is not read (`validate` passes the defaults: none).
pub fn check_material_values(
    mesh: &crate::mesh::BaseMesh,
    m: &crate::mesh::MeshMaterial,
    opts: &LookdevOptions,
) -> Result<()> {
    let c = m.base_color;
    let values = [
        (
            "base colour",
            "--base-color R,G,B",
            opts.base_color.is_none(),
            &c[..3],
        ),
        (
            "roughness",
            "--roughness R",
            opts.roughness.is_none(),
            &[m.roughness][..],
        ),
        (
            "metallic",
            "--metallic M",
            opts.metallic.is_none(),
            &[m.metallic][..],
        ),
        ("emission", "--no-emission", opts.emission, &m.emission[..]),
        (
            "clearcoat",
            "--clearcoat W --clearcoat-roughness R",
            opts.clearcoat.is_none() || opts.clearcoat_roughness.is_none(),
            &[m.clearcoat, m.clearcoat_roughness][..],
        ),
    ];
    for (what, flag, read, v) in values {
        if read && v.iter().any(|x| !x.is_finite()) {
            return Err(Error::invalid(
                &mesh.source,
                format!(
                    "material '{}' has a NaN or infinite {what} ({v:?}): fix it in the asset, or override it with {flag}",
                    m.name
                ),
            ));
        }
    }
    Ok(())
}

/// The asset's materials for `job`: the default alone unless it renders the beauty; no
/// texture is decoded for an input the command line sets (`--base-color`, `--roughness`,
/// `--metallic`), and each image once. A texture that cannot be decoded is an error.
fn asset_materials(
    mesh: &crate::mesh::BaseMesh,
    uv_set: u32,
    job: &RenderJob,
    opts: &LookdevOptions,
) -> Result<AssetMaterials> {
    // Without a beauty only the alpha is read, where some material cuts its surface away.
    let beauty = job.aovs.contains(&Aov::Beauty);
    let cuts = opts.alpha && mesh.materials.iter().any(MeshMaterial::cuts_out);
    if !beauty && !cuts {
        return Ok(AssetMaterials::plain());
    }
    let mut out = AssetMaterials {
        list: vec![],
        textures: vec![],
    };
    let reads = |slot: TextureSlot| {
        (beauty || slot == TextureSlot::Alpha)
            && match slot {
                TextureSlot::BaseColor => opts.base_color.is_none(),
                TextureSlot::Roughness => opts.roughness.is_none(),
                TextureSlot::Metallic => opts.metallic.is_none(),
                TextureSlot::Normal => opts.normal_maps,
                TextureSlot::Emission => opts.emission,
                TextureSlot::Clearcoat => opts.clearcoat.is_none(),
                TextureSlot::ClearcoatRoughness => opts.clearcoat_roughness.is_none(),
                TextureSlot::ClearcoatNormal => opts.normal_maps,
                TextureSlot::Alpha => opts.alpha,
            }
    };
    if let Some(w) = material_warning(mesh, uv_set, &reads) {
        eprintln!("warning: {}: {w}", mesh.source.display());
    }
    // The images decoded so far.
    let mut decoded: Vec<&TextureRef> = vec![];
    let mut decode = |t, slot| -> Result<Option<u32>> {
        if !reads(slot) || !texture_readable(t, uv_set) {
            return Ok(None);
        }
        decode_once(&mut decoded, &mut out.textures, &mesh.source, t, slot)
    };
    let mut list = vec![];
    for m in &mesh.materials {
        if beauty {
            check_material_values(mesh, m, opts)?;
        }
        let texture = match &m.base_color_texture {
            Some(t) => decode(t, TextureSlot::BaseColor)?,
            None => None,
        };
        let mut channels = [None; 4];
        let inputs = [
            (&m.roughness_texture, TextureSlot::Roughness),
            (&m.metallic_texture, TextureSlot::Metallic),
            (&m.clearcoat_texture, TextureSlot::Clearcoat),
            (
                &m.clearcoat_roughness_texture,
                TextureSlot::ClearcoatRoughness,
            ),
        ];
        for (out, (c, slot)) in channels.iter_mut().zip(inputs) {
            if let Some(c) = c {
                *out = decode(&c.texture, slot)?.map(|texture| TexChannel {
                    texture,
                    channel: c.channel,
                });
            }
        }
        let [roughness_texture, metallic_texture, clearcoat_texture, clearcoat_roughness_texture] =
            channels;
        let normal_texture = match &m.normal_texture {
            Some(n) => decode(&n.texture, TextureSlot::Normal)?.map(|t| NormalTex::of(t, n)),
            None => None,
        };
        let clearcoat_normal_texture = match &m.clearcoat_normal_texture {
            Some(n) => {
                decode(&n.texture, TextureSlot::ClearcoatNormal)?.map(|t| NormalTex::of(t, n))
            }
            None => None,
        };
        let emission_texture = match &m.emission_texture {
            Some(t) => decode(t, TextureSlot::Emission)?,
            None => None,
        };
        let cut = match opts.alpha && m.cuts_out() {
            false => AlphaCut::OPAQUE,
            true => AlphaCut {
                alpha: m.base_color[3],
                mode: m.alpha_mode,
                texture: match &m.alpha_texture {
                    Some(c) => decode(&c.texture, TextureSlot::Alpha)?.map(|texture| TexChannel {
                        texture,
                        channel: c.channel,
                    }),
                    None => None,
                },
            },
        };
        let c = m.base_color;
        list.push(AssetMaterial {
            cut,
            // Below, with the textures decoded.
            alpha_summary: None,
            name: m.name.clone(),
            base_color: Vec3::new(c[0], c[1], c[2]),
            roughness: m.roughness,
            metallic: m.metallic,
            texture,
            roughness_texture,
            metallic_texture,
            normal_mapping: normal_texture
                .and(m.normal_texture.as_ref())
                .map(|n| n.describe_mapping()),
            normal_texture,
            emission: Vec3::from_array(m.emission),
            emission_texture,
            specular: m.specular.unwrap_or(DEFAULT_SPECULAR),
            specular_tint: m.specular_tint.map_or(Vec3::ONE, Vec3::from),
            clearcoat: m.clearcoat,
            clearcoat_roughness: m.clearcoat_roughness,
            clearcoat_texture,
            clearcoat_roughness_texture,
            clearcoat_normal_mapping: clearcoat_normal_texture
                .and(m.clearcoat_normal_texture.as_ref())
                .map(|n| n.describe_mapping()),
            clearcoat_normal_texture,
        });
    }
    for (a, m) in list.iter_mut().zip(&mesh.materials) {
        // An alpha texture whose every texel keeps the surface (an opaque image under BLEND,
        // as exporters often write it) cuts nothing: no ray asks it.
        if let Some(c) = a.cut.texture {
            let texels = &out.textures[c.texture as usize].texels;
            let least = texels
                .iter()
                .map(|t| t[c.channel as usize])
                .fold(f32::INFINITY, f32::min);
            let full = match a.cut.mode {
                AlphaMode::Mask(cutoff) => a.cut.alpha * least >= cutoff,
                _ => a.cut.alpha * least >= 1.0,
            };
            if full {
                a.cut = AlphaCut::OPAQUE;
            }
        }
        if a.cut != AlphaCut::OPAQUE {
            let texture = (a.cut.texture).map(|c| out.textures[c.texture as usize].describe());
            a.alpha_summary = describe_alpha(m, texture);
        }
    }
    list.push(AssetMaterial::default_grey());
    out.list = list;
    Ok(out)
}

/// The index in `textures` of `t` decoded, decoding it (for `slot`) unless `decoded`, the
/// images in `textures`' order, already holds it. `None` for a normal map that is a grey image
/// (a bump map, which the beauty does not read: a warning says so).
fn decode_once<'m>(
    decoded: &mut Vec<&'m TextureRef>,
    textures: &mut Vec<ColorMap>,
    source: &Path,
    t: &'m TextureRef,
    slot: TextureSlot,
) -> Result<Option<u32>> {
    let found = decoded.iter().position(|d| *d == t);
    let decoding = match found {
        Some(_) => None,
        None => Some(ColorMap::load(source, t, slot)?),
    };
    let map = decoding.as_ref().or(found.map(|i| &textures[i]));
    let normal = matches!(slot, TextureSlot::Normal | TextureSlot::ClearcoatNormal);
    if normal && map.is_some_and(ColorMap::is_grey) {
        eprintln!("warning: {}: {}", source.display(), grey_normal_map(t));
        return Ok(None);
    }
    if let Some(map) = decoding {
        textures.push(map);
        decoded.push(t);
    }
    Ok(Some(found.unwrap_or(decoded.len() - 1) as u32))
}

/// Why a grey normal map is not read (`render`'s warning, `validate`'s `textures` check).
pub fn grey_normal_map(t: &TextureRef) -> String {
    format!(
        "normal map '{}' is a grey image, a bump (height) map rather than a tangent-space normal \
         map: the beauty does not read it (bake it to a normal map, e.g. with Blender's Bump \
         node, or pass --no-normal-maps to silence this)",
        t.name
    )
}

/// Load the input (asset: load → [cache] → repair → bake; or a baked table).
fn load_cached(
    job: &RenderJob,
    opts: &LookdevOptions,
) -> Result<(Loaded, AssetMaterials, CacheUse)> {
    let spec = match &job.input {
        Input::Asset(spec) => spec,
        Input::Table {
            path,
            disp,
            channel,
        } => {
            let (mut loaded, mesh) = super::job::load_table(
                path,
                disp.as_deref(),
                channel.clone(),
                job.camera.name.as_deref(),
            )?;
            let materials = match &mesh {
                Some(mesh) => asset_materials(mesh, loaded.table.source.uv_set, job, opts)?,
                None => AssetMaterials::plain(),
            };
            if !opts.scene_lights {
                (loaded.dome, loaded.sun) = (None, None);
                loaded.lights.clear();
            }
            return Ok((loaded, materials, CacheUse::Off));
        }
    };
    let (mesh, map) = asset::load(spec)?;
    let materials = asset_materials(&mesh, spec.uv_set, job, opts)?;
    let scene_camera = mesh.pick_named_camera(job.camera.name.as_deref())?.cloned();
    let (dome, sun, lights) = match opts.scene_lights {
        true => (mesh.dome.clone(), mesh.sun.clone(), mesh.lights.clone()),
        false => (None, None, vec![]),
    };
    let up_axis = mesh.up_axis.unwrap_or_default();
    let hash = match &opts.cache_dir {
        Some(_) => Some(asset::input_hash(spec, &job.repair)?),
        None => None,
    };
    if let (Some(dir), Some(h)) = (&opts.cache_dir, &hash) {
        if let Some((table, path)) = table_cache::load(dir, h, &map) {
            return Ok((
                Loaded {
                    table,
                    map,
                    scene_camera,
                    dome,
                    sun,
                    lights,
                    up_axis,
                },
                materials,
                CacheUse::Reused(path),
            ));
        }
    }
    let (mesh, _report) = repair::repair(mesh, &job.repair);
    let mut table = bake::bake(
        &mesh,
        &map,
        &BakeOptions {
            params: spec.params,
        },
    );
    let cache = match (&opts.cache_dir, hash) {
        (Some(dir), Some(h)) => {
            table.input_hash = h;
            match table_cache::store(dir, &table) {
                Ok(p) => CacheUse::Stored(p),
                Err(e) => CacheUse::NotStored(e.to_string()),
            }
        }
        _ => CacheUse::Off,
    };
    Ok((
        Loaded {
            table,
            map,
            scene_camera,
            dome,
            sun,
            lights,
            up_axis,
        },
        materials,
        cache,
    ))
}

impl Session {
    /// Whether some material's alpha cuts its surface away (`render::cutout`).
    pub fn cuts_out(&self) -> bool {
        self.materials
            .list
            .iter()
            .any(|m| m.cut != AlphaCut::OPAQUE)
    }

    /// The scene to trace (what a GPU renderer uploads).
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The environment a beauty lights with (`None`: black, the key light and ground only).
    pub fn env(&self) -> Option<&EnvMap> {
        self.env.as_ref()
    }

    /// The base-colour textures a beauty reads (what a GPU renderer uploads beside the
    /// environment).
    pub fn textures(&self) -> &[ColorMap] {
        &self.materials.textures
    }

    /// Each material's alpha (`AlphaCut::OPAQUE` where it cuts nothing), the default last:
    /// what `render::cutout::Cutout` reads, its textures `textures`'.
    pub fn alpha_cuts(&self) -> Vec<AlphaCut> {
        self.materials.list.iter().map(|m| m.cut).collect()
    }

    /// How far past a cut-away hit a ray goes on (`beauty::scene_epsilon` of the surface's
    /// bounds, as the beauty's ray offsets).
    pub fn epsilon(&self) -> f32 {
        let (lo, hi) = surface_bounds(&self.scene.table);
        beauty::scene_epsilon(lo, hi)
    }
}

/// Validate the job, prepare the output folder, load the input through the table cache and
/// build the camera and (for beauty) the environment.
pub fn open(job: &RenderJob, opts: &LookdevOptions) -> Result<Session> {
    job.validate()?;
    opts.validate()?;
    // The denoiser is loaded before anything is rendered: a job that cannot denoise fails
    // at once, not after its frames.
    const NO_BEAUTY: &str =
        "--denoise filters the beauty only: add beauty to --aov, or leave out --denoise";
    let denoiser = match (opts.denoise, job.aovs.contains(&Aov::Beauty)) {
        (None, _) => None,
        (Some(_), false) => return Err(Error::Param(NO_BEAUTY.into())),
        (Some(q), true) => Some(Denoiser::load(q)?),
    };
    prepare_out_dir(&job.out_dir)?;
    let t0 = Instant::now();
    let (loaded, materials, cache) = load_cached(job, opts)?;
    let cam0 = base_camera(
        &loaded,
        &job.camera,
        job.settings.width as f32 / job.settings.height as f32,
        job.orbiting_frames(),
    );
    let camera = super::job::describe_camera(&loaded, &job.camera);
    let up_axis = loaded.up_axis;
    let (env, environment) = match job.aovs.contains(&Aov::Beauty) {
        true => {
            let (env, said) = environment(opts, &loaded, job.input.path())?;
            (Some(env), Some(said))
        }
        false => (None, None),
    };
    let sun = loaded.sun;
    let key = key_light(opts, &sun)?;
    let mut lights = loaded.lights;
    let room = MAX_LIGHTS - key.is_some() as usize;
    if lights.len() > room && job.aovs.contains(&Aov::Beauty) {
        let left: Vec<&str> = lights[room..].iter().map(|l| l.name.as_str()).collect();
        eprintln!(
            "warning: {}: the beauty renders {MAX_LIGHTS} lights, the key light and the first \
             {room} others; left out: {}",
            job.input.path().display(),
            left.join(", ")
        );
    }
    lights.truncate(room);
    let scene = Scene::new(loaded.table, loaded.map).with_seam_mode(job.method.seams);
    Ok(Session {
        scene,
        cam0,
        camera,
        up_axis,
        materials,
        env,
        environment,
        key,
        lights,
        denoiser,
        setup_seconds: t0.elapsed().as_secs_f64(),
        cache,
    })
}

/// The beauty's environment and what the summary says of it: `--env`, else the scene file's
/// dome light (its texture or colour, tinted, turned from OpenEXR's orientation as its prim
/// turns it, then by `--env-rotate`, and scaled by `--env-intensity`), else the built-in sky.
fn environment(opts: &LookdevOptions, loaded: &Loaded, source: &Path) -> Result<(EnvMap, String)> {
    let frame = EnvFrame {
        z_up: loaded.up_axis == UpAxis::Z,
        rotation: opts.env_rotate_deg.to_radians(),
    };
    let k = opts.env_intensity;
    Ok(match (&opts.env, &loaded.dome) {
        (Some(p), _) => (EnvMap::load(p, k, frame)?, format!("--env {}", p.display())),
        (None, Some(dome)) => {
            let frame = frame.dome(dome.turn_deg);
            let tint = Vec3::from(dome.tint);
            let (env, what) = match &dome.texture {
                Some(t) => {
                    let env = EnvMap::load(t, k, frame).map_err(|e| {
                        Error::invalid(
                            source,
                            format!(
                                "dome light {}: its texture: {e} (fix the texture, or give --env)",
                                dome.name
                            ),
                        )
                    })?;
                    (env.tinted(tint), t.display().to_string())
                }
                None => (EnvMap::constant(tint * k, frame), "no texture".into()),
            };
            if !env.total_weight.is_finite() {
                return Err(Error::invalid(
                    source,
                    format!(
                        "dome light {}: its radiance (tint {tint} × --env-intensity {k}) sums past \
                         f32's range (lower its intensity or exposure)",
                        dome.name
                    ),
                ));
            }
            let said = format!(
                "the file's dome light '{}' ({what}, tint {}, {}, {}, turned {}°)",
                dome.name, tint.x, tint.y, tint.z, dome.turn_deg
            );
            (env, said)
        }
        (None, None) => (EnvMap::default_sky(k, frame), "the built-in sky".into()),
    })
}

/// The key light: `--key-light` (with `--key-angle`), else the scene file's directional light
/// (as wide as `--key-angle` where it is given, else its own width); `--key-angle` without
/// either is an error.
fn key_light(
    opts: &LookdevOptions,
    sun: &Option<SceneSun>,
) -> Result<Option<([f32; 4], Vec3, String)>> {
    // --key-color, as a colour of unit luminance (validated: it has some).
    let hue = opts
        .key_color
        .and_then(crate::mesh::split_color)
        .map(|(_, c)| Vec3::from_array(c));
    Ok(match (opts.key_light, sun) {
        (Some([az, el, i]), _) => Some((
            [az, el, i, opts.key_angle_deg],
            hue.unwrap_or(Vec3::ONE),
            match hue {
                Some(c) => format!("--key-light, colour ({:.3}, {:.3}, {:.3})", c.x, c.y, c.z),
                None => "--key-light".into(),
            },
        )),
        (None, Some(s)) => {
            let [az, el, i] = s.key;
            let angle = match opts.key_angle_deg > 0.0 {
                true => opts.key_angle_deg,
                false => s.angle_deg,
            };
            let s = SceneSun {
                color: hue.map_or(s.color, |c| c.to_array()),
                ..s.clone()
            };
            let said = format!("the file's directional light {}", s.describe(angle));
            Some(([az, el, i, angle], Vec3::from_array(s.color), said))
        }
        (None, None) if opts.key_angle_deg > 0.0 || opts.key_color.is_some() => {
            return Err(Error::Param(
                "--key-angle and --key-color need --key-light AZ,EL,INTENSITY or a directional \
                 light in the scene file (the light they change)"
                    .into(),
            ))
        }
        (None, None) => None,
    })
}

/// Bounds of the displaced surface: the base positions grown by the largest |D|. Tighter than
/// the prism boxes, whose λ ranges grow as 1/m_lo on prisms with nearly opposed normals.
pub(crate) fn surface_bounds(t: &crate::bake::PrismTable) -> (Vec3, Vec3) {
    let d = t
        .prisms
        .iter()
        .map(|p| p.d_min.abs().max(p.d_max.abs()))
        .fold(0.0f32, f32::max);
    let (lo, hi) = t
        .positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    (lo - d, hi + d)
}

/// The frames a job renders (`None` = a still).
pub fn frame_list(job: &RenderJob) -> Vec<Option<u32>> {
    match job.turntable {
        None => vec![None],
        Some(n) => {
            let (a, b) = job.frames.unwrap_or((0, n - 1));
            (a..=b).map(Some).collect()
        }
    }
}

/// A frame traced and not yet written: its images and its figures so far (`stats.frame`
/// names it).
struct TracedFrame {
    aovs: Option<AovImage>,
    beauty: Option<BeautyImage>,
    stats: FrameStats,
}

/// Trace one frame: the AOVs (if any are asked for), then beauty (if `beauty` is given).
fn trace_frame(
    renderer: &dyn FrameRenderer,
    cam: &Camera,
    frame: Option<u32>,
    job: &RenderJob,
    aov_list: &[Aov],
    beauty: Option<&BeautyScene>,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<TracedFrame> {
    // Time in the renderer's calls; the frame's files are timed by `TracedFrame::write`.
    let mut trace_seconds = 0.0;
    let (mut rays, mut steps, mut coverage) = (0u64, 0u64, 0.0f64);
    let mut aovs = None;
    if !aov_list.is_empty() {
        let report = |rows: usize| {
            if beauty.is_none() {
                progress(rows)
            }
        };
        let traced = Instant::now();
        let img = renderer.render_aovs(cam, &job.settings, &report)?;
        trace_seconds += traced.elapsed().as_secs_f64();
        rays += img.rays;
        steps += img.total_steps;
        coverage = img.mask.iter().map(|&m| m as f64).sum::<f64>() / img.mask.len() as f64;
        aovs = Some(img);
    }
    let mut beauty_img = None;
    if let Some(scene) = beauty {
        let traced = Instant::now();
        let img = renderer.render_beauty(cam, &job.settings, scene, progress)?;
        trace_seconds += traced.elapsed().as_secs_f64();
        rays += img.counters.rays + img.counters.shadow_rays();
        if aov_list.is_empty() {
            coverage = img.rgba.iter().map(|c| c[3] as f64).sum::<f64>() / img.rgba.len() as f64;
        }
        beauty_img = Some(img);
    }
    Ok(TracedFrame {
        aovs,
        beauty: beauty_img,
        stats: FrameStats {
            frame,
            seconds: trace_seconds,
            trace_seconds,
            write_seconds: 0.0,
            denoise_seconds: None,
            device_seconds: renderer.take_device_seconds(),
            rays,
            mrays_per_s: rays as f64 / trace_seconds / 1e6,
            steps_per_ray: steps as f64 / rays.max(1) as f64,
            coverage,
        },
    })
}

/// A frame's figures complete, its files, and the previews of a turntable's contact sheets.
type FrameDone = (FrameStats, Vec<PathBuf>, Vec<(Aov, Vec<u8>)>);

impl TracedFrame {
    /// Denoise the beauty (with `denoise`), then
    /// write the frame's EXR and PNG files into `dir` (and keep each image's preview for the
    /// contact sheets when `sheets`); the denoising and write times complete its figures.
    fn write(
        mut self,
        dir: &Path,
        aov_list: &[Aov],
        sheets: bool,
        denoise: Option<&Denoiser>,
    ) -> Result<FrameDone> {
        if let (Some(img), Some(d)) = (&mut self.beauty, denoise) {
            let t = Instant::now();
            d.denoise_beauty(img).map_err(|e| {
                Error::Param(format!(
                    "denoising {}: {e}",
                    self.stats
                        .frame
                        .map_or("the frame".to_string(), |f| format!("frame {f}"))
                ))
            })?;
            self.stats.denoise_seconds = Some(t.elapsed().as_secs_f64());
        }
        let t = Instant::now();
        let mut files = vec![];
        let mut previews = vec![];
        // The PNGs' pixels are the contact sheets' cells: computed once.
        let mut take = |w: output::WrittenFrame| {
            files.extend(w.files);
            if sheets {
                previews.extend(w.previews);
            }
        };
        if let Some(img) = &self.aovs {
            take(output::write_frame(dir, img, aov_list, self.stats.frame)?);
        }
        if let Some(img) = &self.beauty {
            take(output::write_beauty(dir, img, self.stats.frame)?);
        }
        let mut stats = self.stats;
        stats.write_seconds = t.elapsed().as_secs_f64();
        stats.seconds =
            stats.trace_seconds + stats.denoise_seconds.unwrap_or(0.0) + stats.write_seconds;
        Ok((stats, files, previews))
    }
}

/// Render every frame of the job from a loaded session with `renderer` and write its files
/// (frames, contact sheets).
pub fn render_all(
    job: &RenderJob,
    opts: &LookdevOptions,
    s: &Session,
    renderer: &dyn FrameRenderer,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<LookdevSummary> {
    let frames = frame_list(job);
    let aov_list: Vec<Aov> = job
        .aovs
        .iter()
        .copied()
        .filter(|a| *a != Aov::Beauty)
        .collect();
    let want_beauty = job.aovs.contains(&Aov::Beauty);
    let (lo, hi) = surface_bounds(&s.scene.table);
    let up = s.up_axis.vector();
    // The asset's materials (and the default), the command line's settings in place of theirs.
    let materials: Vec<SurfaceMaterial> = s
        .materials
        .list
        .iter()
        .map(|m| SurfaceMaterial {
            material: Material {
                base_color: opts.base_color.unwrap_or(m.base_color),
                roughness: opts.roughness.unwrap_or(m.roughness),
                metallic: opts.metallic.unwrap_or(m.metallic),
                specular: opts.specular.unwrap_or(m.specular),
                specular_tint: opts.specular_tint.unwrap_or(m.specular_tint),
                clearcoat: opts.clearcoat.unwrap_or(m.clearcoat),
                // A clearcoat the material does not have gets Blender's default roughness.
                clearcoat_roughness: opts.clearcoat_roughness.unwrap_or(match m.clearcoat > 0.0 {
                    true => m.clearcoat_roughness,
                    false => DEFAULT_CLEARCOAT_ROUGHNESS,
                }),
            },
            texture: m.texture.filter(|_| opts.base_color.is_none()),
            roughness_texture: m.roughness_texture.filter(|_| opts.roughness.is_none()),
            metallic_texture: m.metallic_texture.filter(|_| opts.metallic.is_none()),
            clearcoat_texture: m.clearcoat_texture.filter(|_| opts.clearcoat.is_none()),
            clearcoat_roughness_texture: m
                .clearcoat_roughness_texture
                .filter(|_| opts.clearcoat_roughness.is_none()),
            clearcoat_normal_texture: m.clearcoat_normal_texture.filter(|_| opts.normal_maps),
            normal_texture: m.normal_texture.filter(|_| opts.normal_maps),
            emission: match opts.emission {
                true => m.emission,
                false => Vec3::ZERO,
            },
            emission_texture: m.emission_texture.filter(|_| opts.emission),
            cut: m.cut,
        })
        .collect();
    // The tangent frames normal maps are read in, where some material has one.
    let tangents = match (materials.iter())
        .any(|m| m.normal_texture.is_some() || m.clearcoat_normal_texture.is_some())
    {
        true => crate::tangent::corner_tangents(&s.scene.table),
        false => vec![],
    };
    let base_normals = match tangents.is_empty() {
        true => vec![],
        false => crate::tangent::corner_normals(&s.scene.table),
    };
    let env_fallback;
    let env = match &s.env {
        Some(e) => e,
        None => {
            env_fallback = EnvMap::constant(
                Vec3::ZERO,
                EnvFrame {
                    z_up: false,
                    rotation: 0.0,
                },
            );
            &env_fallback
        }
    };
    let bscene = BeautyScene {
        env,
        env_frame: env.frame,
        env_lights: env.total_weight > 0.0,
        lights: LightSet::new(
            &s.key
                .iter()
                .map(|([az, el, i, angle], color, _)| {
                    Light::from(
                        KeyLight::from_angles(*az, *el, *i, s.up_axis == UpAxis::Z)
                            .with_angle(*angle)
                            .with_color(*color),
                    )
                })
                .chain(s.lights.iter().map(|l| l.light))
                .collect::<Vec<_>>(),
        ),
        materials: &materials,
        emissive: materials.iter().any(|m| m.emission != Vec3::ZERO),
        textures: &s.materials.textures,
        tangents: &tangents,
        base_normals: &base_normals,
        prisms: &s.scene.table.prisms,
        ground: opts.ground.then(|| Ground {
            up,
            height: lo.dot(up).min(hi.dot(up)),
        }),
        bounces: opts.bounces,
        eps: beauty::scene_epsilon(lo, hi),
        exposure: opts.exposure_ev.exp2(),
    };
    let mut summary = LookdevSummary {
        render: RenderSummary {
            method: job.method.method,
            device: renderer.device(),
            prisms: s.scene.table.prisms.len(),
            setup_seconds: s.setup_seconds,
            method_memory_bytes: renderer.memory_bytes(),
            frames: vec![],
            frames_seconds: 0.0,
            files: vec![],
            gpu_tile: None,
            gpu_walk: None,
            gpu_map_encoding: None,
            gpu_fallback: None,
        },
        table_cache: s.cache.clone(),
        camera: s.camera.clone(),
        environment: s.environment.clone(),
        key_light: s
            .key
            .as_ref()
            .filter(|_| want_beauty)
            .map(|(_, _, said)| said.clone()),
        lights: match want_beauty {
            true => s.lights.iter().map(SceneLight::describe).collect(),
            false => vec![],
        },
        beauty_rays: BeautyCounters::default(),
        shadow_rays: 0,
        contact_sheets: vec![],
        denoiser: s.denoiser.as_ref().map(Denoiser::describe),
        materials: match want_beauty {
            true => material_summaries(&bscene, &s.materials),
            false => vec![],
        },
        peak_memory_bytes: None,
    };
    let denoise = s.denoiser.as_ref();
    let mut previews: Vec<(Aov, Vec<Vec<u8>>)> =
        job.aovs.iter().map(|a| (*a, Vec::new())).collect();
    let (w, h) = (job.settings.width, job.settings.height);
    let sheets = job.turntable.is_some();
    // Frame i's files are written while frame i + 1 traces (`rayon::join`, in the job's own
    // pool: with one thread they simply take turns), and taken in frame order. On a GPU a
    // frame's files are most of its time (docs/gpu.md, "Frame times").
    let loop_start = Instant::now();
    let mut traced: Option<TracedFrame> = None;
    for next in frames.iter().enumerate().map(Some).chain([None]) {
        let previous = traced.take();
        let (written, now) = rayon::join(
            || previous.map(|f| f.write(&job.out_dir, &aov_list, sheets, denoise)),
            || {
                next.map(|(i, frame)| {
                    let (cam, turn) = match (frame, job.turntable) {
                        (Some(f), Some(n)) => job.turntable_mode.frame(&s.cam0, up, *f, n),
                        _ => (s.cam0, 0.0),
                    };
                    let lights = bscene.turned(up, s.cam0.to, turn);
                    trace_frame(
                        renderer,
                        &cam,
                        *frame,
                        job,
                        &aov_list,
                        want_beauty.then_some(&lights),
                        &|rows| progress(i, rows),
                    )
                })
            },
        );
        if let Some(written) = written {
            let (stats, files, frame_previews) = written?;
            summary.render.files.extend(files);
            summary.render.frames.push(stats);
            for (aov, preview) in frame_previews {
                if let Some((_, list)) = previews.iter_mut().find(|(a, _)| *a == aov) {
                    list.push(preview);
                }
            }
        }
        if let Some(now) = now {
            let now = now?;
            if let Some(b) = &now.beauty {
                summary.beauty_rays.rays += b.counters.rays;
                summary.beauty_rays.key_shadow_rays += b.counters.key_shadow_rays;
                summary.beauty_rays.env_shadow_rays += b.counters.env_shadow_rays;
            }
            traced = Some(now);
        }
    }
    summary.render.frames_seconds = loop_start.elapsed().as_secs_f64();
    summary.shadow_rays = summary.beauty_rays.shadow_rays();
    if job.turntable.is_some() {
        for (aov, list) in &previews {
            let path = job
                .out_dir
                .join(format!("{}_contact_sheet.png", aov.name()));
            contact_sheet::write_contact_sheet(&path, list, w, h)?;
            summary.contact_sheets.push(path);
        }
    }
    summary.peak_memory_bytes = crate::sysmem::peak_resident_bytes();
    Ok(summary)
}

/// Render every frame of a loaded session on the CPU, with the intersector the job names
/// (also where a GPU cannot hold the session's scene and `--device auto` falls back).
pub fn render_all_cpu(
    job: &RenderJob,
    opts: &LookdevOptions,
    s: &Session,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<LookdevSummary> {
    let t0 = std::time::Instant::now();
    let cuts = s.alpha_cuts();
    with_intersector(&job.method, &s.scene, &job.input, |isect| {
        // The intersector's own set-up (PDM's cells, RMIP's pyramid) is set-up time too.
        let build = t0.elapsed().as_secs_f64();
        let cutout = Cutout {
            inner: isect,
            cuts: &cuts,
            textures: &s.materials.textures,
            prisms: &s.scene.table.prisms,
            eps: s.epsilon(),
        };
        let isect: &dyn Intersector = match s.cuts_out() {
            true => &cutout,
            false => isect,
        };
        let mut summary = render_all(job, opts, s, &CpuFrames(isect), progress)?;
        summary.render.setup_seconds += build;
        Ok(summary)
    })
}

/// Run a job once.
pub fn run(
    job: &RenderJob,
    opts: &LookdevOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<LookdevSummary> {
    let session = open(job, opts)?;
    render_all_cpu(job, opts, &session, progress)
}

/// The height map a job's input reads (what `watch` polls).
pub fn map_source(input: &Input) -> Result<(PathBuf, MapOptions)> {
    match input {
        Input::Asset(spec) => Ok((spec.require_disp()?.to_path_buf(), spec.map_options())),
        Input::Table {
            path,
            disp,
            channel,
        } => {
            let table = crate::prism_file::read(path)?;
            let map = match disp {
                Some(d) => d.clone(),
                None => asset::table_map_path(&table, path),
            };
            Ok((
                map,
                MapOptions {
                    channel: channel.clone(),
                    wrap: table.wrap,
                },
            ))
        }
    }
}

/// What identifies a version of a file for polling: modification time and size.
fn stamp(path: &Path) -> Option<(SystemTime, u64)> {
    let m = std::fs::metadata(path).ok()?;
    Some((m.modified().ok()?, m.len()))
}

/// One re-render of `watch`.
#[derive(Debug, Serialize)]
pub struct WatchEvent {
    pub rebake: RebakeStats,
    /// "kept", or "rebuilt" when some prism's box grew.
    pub bvh: &'static str,
    /// Change detected → every file written.
    pub latency_ms: f64,
    pub rebake_ms: f64,
}

/// Poll interval of `watch`.
pub const WATCH_POLL: Duration = Duration::from_millis(200);

/// Run the job, then re-render whenever the height map file changes (its mtime or size),
/// `max_rerenders` times (forever if `None`). Each change: reload the map, `rebake_for_map`,
/// rebuild the BVH only if a box grew, render all frames. A map that fails to load (e.g. caught
/// half-written) is reported through `log` and waited out. `on_event` gets every re-render.
pub fn watch(
    job: &RenderJob,
    opts: &LookdevOptions,
    max_rerenders: Option<u32>,
    log: &dyn Fn(&str),
    on_event: &dyn Fn(&WatchEvent, &LookdevSummary),
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<LookdevSummary> {
    watch_with(job, opts, max_rerenders, log, on_event, &mut |s, _| {
        render_all_cpu(job, opts, s, progress)
    })
}

/// `watch` with another renderer: `render(session, change)` renders every frame of the
/// session, first with `change` `None`, then after each change with its re-bake (whether the
/// BVH was rebuilt: a GPU renderer keeps its uploaded scene when it was not).
pub fn watch_with(
    job: &RenderJob,
    opts: &LookdevOptions,
    max_rerenders: Option<u32>,
    log: &dyn Fn(&str),
    on_event: &dyn Fn(&WatchEvent, &LookdevSummary),
    render: &mut dyn FnMut(&Session, Option<&RebakeStats>) -> Result<LookdevSummary>,
) -> Result<LookdevSummary> {
    let (map_path, map_opts) = map_source(&job.input)?;
    // Taken before loading, so that an edit made while the first frame renders is not missed.
    let mut last = stamp(&map_path);
    let mut session = open(job, opts)?;
    let mut summary = render(&session, None)?;
    log(&format!(
        "watching {} for changes (Ctrl-C to stop)",
        map_path.display()
    ));
    let mut count = 0;
    while max_rerenders.is_none_or(|m| count < m) {
        std::thread::sleep(WATCH_POLL);
        let now = stamp(&map_path);
        if now == last || now.is_none() {
            continue;
        }
        last = now;
        let detected = Instant::now();
        let map: HeightMap = match load::load_height_map(&map_path, &map_opts) {
            Ok(m) if m.first_non_finite().is_none() => m,
            Ok(_) => {
                log(&format!(
                    "{}: has NaN or infinite texels; waiting for the next change",
                    map_path.display()
                ));
                continue;
            }
            Err(e) => {
                log(&format!("{e}; waiting for the next change"));
                continue;
            }
        };
        let rebake = bake::rebake_for_map(&mut session.scene.table, &map);
        let bvh = if rebake.bvh_rebuild_needed {
            let mode = session.scene.seam_mode();
            session.scene =
                Scene::new(std::mem::take(&mut session.scene.table), map).with_seam_mode(mode);
            "rebuilt"
        } else {
            session.scene.replace_map(map);
            "kept"
        };
        let rebake_ms = detected.elapsed().as_secs_f64() * 1e3;
        summary = render(&session, Some(&rebake))?;
        count += 1;
        let event = WatchEvent {
            rebake,
            bvh,
            latency_ms: detected.elapsed().as_secs_f64() * 1e3,
            rebake_ms,
        };
        on_event(&event, &summary);
    }
    Ok(summary)
}
