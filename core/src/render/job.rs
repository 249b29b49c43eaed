//! A render job: input (mesh + map, or a baked table), method, camera, frames, AOVs, output
//! folder — validated up front, then run frame by frame.

use super::camera::{Camera, Projection};
use super::{Aov, RenderSettings};
use crate::accel::Scene;
use crate::asset::{self, AssetSpec};
use crate::bake::PrismTable;
use crate::error::{Error, Result};
use crate::heightmap::HeightMap;
use crate::mesh::{BaseMesh, NamedCamera, SceneDome, SceneLight, SceneSun, UpAxis};
use crate::repair::RepairOptions;
use crate::seam::SeamMode;
use crate::trace::nonlinear::{Nonlinear, NonlinearOptions};
use crate::trace::pdm::{Pdm, PdmOptions};
use crate::trace::reference::{self, Reference};
use crate::trace::rmip::{Rmip, RmipOptions};
use crate::trace::{Intersector, NormalMode};
use glam::Vec3;
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    Pdm,
    Reference,
    Nonlinear,
    Rmip,
}

impl std::str::FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "pdm" => Ok(Method::Pdm),
            "reference" => Ok(Method::Reference),
            "rmip" => Ok(Method::Rmip),
            "nonlinear" => Ok(Method::Nonlinear),
            _ => Err(format!(
                "unknown method '{s}' (expected pdm, reference, rmip or nonlinear)"
            )),
        }
    }
}

/// What turns in a turntable (`--turntable-mode`), about the asset's up axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TurntableMode {
    /// The asset turns in front of the camera, under lights that stay where the camera sees
    /// them: every side of it passes through the key light (a studio turntable). Rendered as
    /// the camera orbiting with the environment and key light turning along.
    #[default]
    Asset,
    /// The camera orbits a still scene, lights included: the lighting stays on the asset's
    /// same side.
    Camera,
    /// The camera and the asset stay; the environment and key light turn about the asset.
    Lights,
}

impl TurntableMode {
    /// Frame `frame` of an `n`-frame turntable from `cam0`: its camera, and the angle
    /// (radians, counter-clockwise seen from above) by which the lights turn
    /// (`BeautyScene::turned`). Turning every frame about `up` through the look-at point.
    pub fn frame(self, cam0: &Camera, up: Vec3, frame: u32, n: u32) -> (Camera, f32) {
        let angle = turntable_angle(frame, n);
        match self {
            TurntableMode::Asset => (cam0.orbit(up, angle), angle),
            TurntableMode::Camera => (cam0.orbit(up, angle), 0.0),
            TurntableMode::Lights => (*cam0, angle),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            TurntableMode::Asset => "asset",
            TurntableMode::Camera => "camera",
            TurntableMode::Lights => "lights",
        }
    }
}

/// The turn of frame `frame` of an `n`-frame turntable, radians: `n` equal steps of a whole
/// turn.
pub fn turntable_angle(frame: u32, n: u32) -> f32 {
    if n <= 1 {
        0.0
    } else {
        std::f32::consts::TAU * frame as f32 / n as f32
    }
}

impl std::str::FromStr for TurntableMode {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        [
            TurntableMode::Asset,
            TurntableMode::Camera,
            TurntableMode::Lights,
        ]
        .into_iter()
        .find(|m| m.name() == s)
        .ok_or_else(|| format!("unknown turntable mode '{s}' (expected asset, camera or lights)"))
    }
}

/// Where the scene comes from.
#[derive(Clone, Debug)]
pub enum Input {
    Asset(AssetSpec),
    Table {
        path: PathBuf,
        disp: Option<PathBuf>,
        channel: Option<String>,
    },
}

impl Input {
    /// The file the input names: the asset's mesh, or the prism table.
    pub fn path(&self) -> &Path {
        match self {
            Input::Asset(spec) => &spec.mesh,
            Input::Table { path, .. } => path,
        }
    }
}

/// Camera overrides from the command line.
#[derive(Clone, Debug, Default)]
pub struct CameraOverride {
    /// `--camera NAME`: which of the scene file's cameras (`BaseMesh::pick_camera`).
    pub name: Option<String>,
    pub from: Option<Vec3>,
    pub to: Option<Vec3>,
    /// `--fov`: a pinhole with this field of view (an orthographic file camera too).
    pub fov_deg: Option<f32>,
    /// `--ortho HEIGHT|fit`: an orthographic view this tall, or (`Some(None)`, `fit`) as
    /// tall as the asset's bounds need from where the camera is.
    pub ortho: Option<Option<f32>>,
}

/// A method and every method's knobs (each method reads its own).
#[derive(Clone, Copy, Debug)]
pub struct MethodConfig {
    pub method: Method,
    pub normal_mode: NormalMode,
    pub pdm: PdmOptions,
    /// Reference tessellation density (micro-edges per texel).
    pub ref_density: f32,
    /// Most bytes the reference may take to build (`--ref-memory`); `None`: 80% of the
    /// memory available (`reference::default_budget`).
    pub ref_memory: Option<u64>,
    pub nonlinear: NonlinearOptions,
    pub rmip: RmipOptions,
    /// How UV seams are traced (stitched by default).
    pub seams: SeamMode,
}

impl Default for MethodConfig {
    fn default() -> Self {
        MethodConfig {
            method: Method::Pdm,
            normal_mode: NormalMode::Smooth,
            pdm: PdmOptions::default(),
            ref_density: 2.0,
            ref_memory: None,
            nonlinear: NonlinearOptions::default(),
            rmip: RmipOptions::default(),
            seams: SeamMode::Stitch,
        }
    }
}

#[derive(Clone, Debug)]
pub struct RenderJob {
    pub input: Input,
    pub method: MethodConfig,
    pub settings: RenderSettings,
    pub aovs: Vec<Aov>,
    /// `Some(n)`: an n-frame turntable; frames `frames` of it are rendered.
    pub turntable: Option<u32>,
    /// What turns in the turntable.
    pub turntable_mode: TurntableMode,
    pub frames: Option<(u32, u32)>,
    pub camera: CameraOverride,
    pub out_dir: PathBuf,
    pub repair: RepairOptions,
}

pub const MAX_RES: u32 = 16384;
pub const MAX_SPP: u32 = 65536;

impl RenderJob {
    /// Check everything that can be checked before loading anything.
    pub fn validate(&self) -> Result<()> {
        let s = &self.settings;
        if s.width == 0 || s.height == 0 || s.width > MAX_RES || s.height > MAX_RES {
            return Err(Error::Param(format!(
                "--res {}x{}: each side must be 1..={MAX_RES}",
                s.width, s.height
            )));
        }
        if s.spp == 0 || s.spp > MAX_SPP {
            return Err(Error::Param(format!(
                "--spp {}: must be 1..={MAX_SPP}",
                s.spp
            )));
        }
        if self.aovs.is_empty() {
            return Err(Error::Param("--aov: name at least one AOV".into()));
        }
        if let Some(n) = self.turntable {
            if n == 0 || n > 100_000 {
                return Err(Error::Param(format!(
                    "--turntable {n}: must be 1..=100000 frames"
                )));
            }
            if let Some((a, b)) = self.frames {
                if a > b || b >= n {
                    return Err(Error::Param(format!(
                        "--frames {a}-{b}: must lie within 0-{} of the turntable",
                        n - 1
                    )));
                }
            }
        } else if self.frames.is_some() {
            return Err(Error::Param("--frames needs --turntable N".into()));
        }
        if let Some(f) = self.camera.fov_deg {
            if !super::camera::usable_fov(f) {
                return Err(Error::Param(format!(
                    "--fov {f}: must be between 0 and {} degrees",
                    super::camera::MAX_FOV_DEG
                )));
            }
        }
        if let Some(Some(h)) = self.camera.ortho {
            if !(h.is_finite() && h > 0.0) {
                return Err(Error::Param(format!(
                    "--ortho {h}: the view's height must be a positive number of scene units \
                     (or `--ortho fit` to fit the asset)"
                )));
            }
        }
        if self.camera.ortho.is_some() && self.camera.fov_deg.is_some() {
            return Err(Error::Param(
                "--ortho and --fov: an orthographic view has no field of view (give one)".into(),
            ));
        }
        for v in [self.camera.from, self.camera.to].into_iter().flatten() {
            if !v.is_finite() {
                return Err(Error::Param(
                    "--camera-from/--camera-to must be finite".into(),
                ));
            }
        }
        if let (Some(a), Some(b)) = (self.camera.from, self.camera.to) {
            if (a - b).length() == 0.0 {
                return Err(Error::Param(
                    "--camera-from and --camera-to are the same point".into(),
                ));
            }
        }
        let rmip = &self.method.rmip;
        if !(rmip.marching_scale > 0.0 && rmip.marching_scale.is_finite()) {
            return Err(Error::Param(format!(
                "--marching-scale {}: must be a positive number of texels",
                rmip.marching_scale
            )));
        }
        if rmip.resolution == Some(0) {
            return Err(Error::Param(
                "--rmip-res 0: the pyramid needs at least one cell".into(),
            ));
        }
        check_reference_density("--ref-density", self.method.ref_density)
    }
}

/// A reference tessellation density (micro-edges per texel) given as `flag`: in (0, 64].
pub fn check_reference_density(flag: &str, k: f32) -> Result<()> {
    if k > 0.0 && k <= 64.0 {
        Ok(())
    } else {
        Err(Error::Param(format!("{flag} {k}: must be in (0, 64]")))
    }
}

/// Create the output folder and prove it writable before any work is done.
pub fn prepare_out_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let probe = dir.join(format!(".prismbake-write-test{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(|e| Error::io(dir, e))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

pub struct Loaded {
    pub table: PrismTable,
    pub map: HeightMap,
    /// The scene file's camera the render looks through (`--camera`, else its first).
    pub scene_camera: Option<NamedCamera>,
    /// The scene file's dome light (USD): the beauty's environment where `--env` is not given.
    pub dome: Option<SceneDome>,
    /// The scene file's directional light: the key light where `--key-light` is not given.
    pub sun: Option<SceneSun>,
    /// The scene file's other lights (`BaseMesh::lights`), which light the beauty beside the
    /// key light.
    pub lights: Vec<SceneLight>,
    pub up_axis: UpAxis,
}

pub fn load_input(input: &Input, repair: &RepairOptions) -> Result<Loaded> {
    match input {
        Input::Asset(spec) => {
            let p = asset::prepare(spec, repair)?;
            Ok(Loaded {
                scene_camera: p.mesh.pick_named_camera(None)?.cloned(),
                dome: p.mesh.dome.clone(),
                sun: p.mesh.sun.clone(),
                lights: p.mesh.lights.clone(),
                up_axis: p.mesh.up_axis.unwrap_or_default(),
                table: p.table,
                map: p.map,
            })
        }
        Input::Table {
            path,
            disp,
            channel,
        } => Ok(load_table(path, disp.as_deref(), channel.clone(), None)?.0),
    }
}

/// A baked table, its map, and from the mesh it was baked from (`asset::table_mesh`) what the
/// table does not keep: the camera `camera` names (else the file's first), the dome and
/// directional light, and the mesh itself (for its materials). Without that mesh a warning
/// says why, the view is framed from the bounds under the table's up axis, and `--camera` is
/// an error.
pub fn load_table(
    path: &Path,
    disp: Option<&Path>,
    channel: Option<String>,
    camera: Option<&str>,
) -> Result<(Loaded, Option<BaseMesh>)> {
    let (table, map) = asset::load_table(path, disp, channel)?;
    let mesh = match asset::table_mesh(&table, path) {
        Ok(mesh) => mesh,
        Err(why) => {
            if let Some(name) = camera {
                return Err(Error::invalid(
                    path,
                    format!(
                        "--camera {name}: a prism table keeps no cameras, and {why} (render \
                         the mesh file, or set the view with --camera-from, --camera-to and \
                         --fov)"
                    ),
                ));
            }
            eprintln!(
                "warning: {}: {why}; rendering without the mesh's cameras, materials and lights",
                path.display()
            );
            let up_axis = table.source.up_axis;
            let loaded = Loaded {
                table,
                map,
                scene_camera: None,
                dome: None,
                sun: None,
                lights: vec![],
                up_axis,
            };
            return Ok((loaded, None));
        }
    };
    let loaded = Loaded {
        scene_camera: mesh.pick_named_camera(camera)?.cloned(),
        dome: mesh.dome.clone(),
        sun: mesh.sun.clone(),
        lights: mesh.lights.clone(),
        up_axis: table.source.up_axis,
        table,
        map,
    };
    Ok((loaded, Some(mesh)))
}

/// For the summary: where frame 0's camera comes from ("the file's camera 'Camera'", "framed
/// from the bounds", and which flags override it).
pub fn describe_camera(loaded: &Loaded, o: &CameraOverride) -> String {
    let base = match &loaded.scene_camera {
        Some(c) => match c.camera.projection {
            Projection::Perspective { .. } => format!("the file's camera '{}'", c.names[0]),
            Projection::Orthographic { height } => format!(
                "the file's orthographic camera '{}' ({height} units {})",
                c.names[0],
                match c.camera.larger_side {
                    true => "across the image's larger side",
                    false => "tall",
                }
            ),
        },
        None => "framed from the bounds".to_string(),
    };
    let flags: Vec<&str> = [
        (o.from.is_some(), "--camera-from"),
        (o.to.is_some(), "--camera-to"),
        (o.fov_deg.is_some(), "--fov"),
        (o.ortho.is_some(), "--ortho"),
    ]
    .into_iter()
    .filter_map(|(set, flag)| set.then_some(flag))
    .collect();
    match flags.is_empty() {
        true => base,
        false => format!("{base}, with {}", flags.join(", ")),
    }
}

/// The camera of frame 0: the scene's, else framed from bounds; flags override (`--ortho`
/// without a height fits the bounds from wherever the camera ends up). What is fitted to the
/// bounds holds them on every frame of a turntable of `turns` frames whose camera orbits the
/// asset (1 where it does not: a still, or a turntable of the lights).
pub fn base_camera(loaded: &Loaded, o: &CameraOverride, aspect: f32, turns: u32) -> Camera {
    let fov = o.fov_deg;
    let (lo, hi) = loaded.table.bounds();
    let up = loaded.up_axis.vector();
    let mut cam = match &loaded.scene_camera {
        Some(c) => Camera::from_scene(&c.camera, aspect),
        None => {
            Camera::frame_bounds_turning(lo, hi, loaded.up_axis, fov.unwrap_or(40.0), aspect, turns)
        }
    };
    if let Some(f) = o.from {
        cam.from = f;
    }
    if let Some(t) = o.to {
        cam.to = t;
    }
    if let Some(yfov_deg) = fov {
        cam.projection = Projection::Perspective { yfov_deg };
    }
    match o.ortho {
        Some(Some(height)) => cam.projection = Projection::Orthographic { height },
        Some(None) => cam = cam.fit_orthographic_turning(lo, hi, aspect, up, turns),
        None => {}
    }
    cam
}

impl RenderJob {
    /// The frames of its turntable on which the camera orbits the asset (1: none does).
    pub fn orbiting_frames(&self) -> u32 {
        match self.turntable_mode {
            TurntableMode::Lights => 1,
            _ => self.turntable.unwrap_or(1),
        }
    }
}

/// One frame's figures. `seconds` is the frame's own work, `trace_seconds` (+
/// `denoise_seconds`) + `write_seconds`:
/// `trace_seconds` the renderer's call alone (rays traced, and on a GPU the uniforms written,
/// the dispatches waited for and the image read back), `write_seconds` its files and previews
/// (written while the next frame traces, so a job takes less than the sum of its frames'
/// `seconds`: `RenderSummary::frames_seconds`); `device_seconds` the GPU's own
/// timestamps summed over the frame's dispatches (kernel time alone), where the adapter has
/// timestamp queries (`null` on the CPU). `mrays_per_s` is over `trace_seconds`.
#[derive(Debug, Serialize)]
pub struct FrameStats {
    pub frame: Option<u32>,
    pub seconds: f64,
    pub trace_seconds: f64,
    pub write_seconds: f64,
    /// Time the denoiser took on the frame's beauty (`--denoise`), part of `seconds`;
    /// `null` without it.
    pub denoise_seconds: Option<f64>,
    pub device_seconds: Option<f64>,
    pub rays: u64,
    pub mrays_per_s: f64,
    pub steps_per_ray: f64,
    pub coverage: f64,
}

#[derive(Debug, Serialize)]
pub struct RenderSummary {
    pub method: Method,
    pub device: String,
    pub prisms: usize,
    pub setup_seconds: f64,
    pub method_memory_bytes: usize,
    pub frames: Vec<FrameStats>,
    /// Wall time of all the frames, files included (each frame's files are written while the
    /// next one traces).
    pub frames_seconds: f64,
    pub files: Vec<PathBuf>,
    /// GPU renders: the tile side (pixels) the last frame was dispatched in; smaller than the
    /// first frame's when the GPU ran out of memory and frames were rendered again in smaller
    /// tiles. Absent on the CPU.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gpu_tile: Option<u32>,
    /// GPU renders: how the AOV kernel walked the BVH (`ray` or `packet`). Absent on the CPU.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gpu_walk: Option<&'static str>,
    /// GPU renders: how the height map's texels are stored (`f32`, or two a word: `unorm16`,
    /// `f16`, where that gives back every texel exactly). Absent on the CPU.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gpu_map_encoding: Option<&'static str>,
    /// `--device auto` only: why the GPU could not hold the scene or run the job, so that the
    /// CPU rendered it instead. Absent where the device asked for rendered it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gpu_fallback: Option<String>,
}

/// The intersector a config names, built over `scene`; the reference is refused, with the
/// density that fits, where it would take more than `cfg.ref_memory`.
pub fn make_intersector<'s>(
    cfg: &MethodConfig,
    scene: &'s Scene,
) -> std::result::Result<Box<dyn Intersector + 's>, String> {
    Ok(match cfg.method {
        Method::Pdm => Box::new(Pdm::new(
            scene,
            PdmOptions {
                normal_mode: cfg.normal_mode,
                ..cfg.pdm
            },
        )),
        Method::Reference => {
            let budget = cfg.ref_memory.unwrap_or_else(reference::default_budget);
            let mut r = Reference::within_budget(scene.surface(), cfg.ref_density, budget)?;
            r.normal_mode = cfg.normal_mode;
            Box::new(r)
        }
        Method::Nonlinear => Box::new(Nonlinear::new(
            scene,
            NonlinearOptions {
                normal_mode: cfg.normal_mode,
                ..cfg.nonlinear
            },
        )),
        Method::Rmip => Box::new(Rmip::new(
            scene,
            RmipOptions {
                normal_mode: cfg.normal_mode,
                ..cfg.rmip
            },
        )),
    })
}

/// Build the intersector a config names and call `f` with it (an error naming the input
/// where it cannot be built).
pub fn with_intersector<R>(
    cfg: &MethodConfig,
    scene: &Scene,
    input: &Input,
    f: impl FnOnce(&dyn Intersector) -> Result<R>,
) -> Result<R> {
    let isect = make_intersector(cfg, scene)
        .map_err(|e| Error::Param(format!("{}: {e}", input.path().display())))?;
    f(isect.as_ref())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each mode's frame: where the camera is and how far the lights turn. The camera is
    /// pitched at the asset (its up leans off the asset's +Y), so an orbit about its own up
    /// would change its height.
    #[test]
    fn turntable_modes_turn_the_camera_or_the_lights_about_the_assets_up() {
        let from = Vec3::new(0.0, 2.0, 4.0);
        let back = from.normalize();
        let cam = Camera::perspective(
            from,
            Vec3::ZERO,
            back.cross(Vec3::Y.cross(back).normalize()),
            40.0,
        );
        let quarter = std::f32::consts::FRAC_PI_2;
        for (mode, moves, turn) in [
            (TurntableMode::Asset, true, quarter),
            (TurntableMode::Camera, true, 0.0),
            (TurntableMode::Lights, false, quarter),
        ] {
            let (c, t) = mode.frame(&cam, Vec3::Y, 1, 4);
            assert_eq!(t, turn, "{mode:?}");
            let want = if moves {
                Vec3::new(4.0, 2.0, 0.0)
            } else {
                from
            };
            assert!((c.from - want).length() < 1e-5, "{mode:?}: {}", c.from);
            assert_eq!(mode.frame(&cam, Vec3::Y, 0, 4), (cam, 0.0), "{mode:?}");
            assert_eq!(mode.name().parse::<TurntableMode>(), Ok(mode));
        }
        assert!("object".parse::<TurntableMode>().is_err());
    }
}
