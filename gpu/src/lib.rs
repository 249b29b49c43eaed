//! prismbake on the GPU: wgpu compute kernels that trace the same displaced surface as the CPU
//! renderer, with the same hit records and the same random numbers.
//!
//! * `GpuContext::new()` — adapter, device, the AOV pipeline of its walk and persistent
//!   buffers, built once (the other walk's and the beauty pipelines on first use). Any wgpu
//!   adapter works, software ones included (Mesa's lavapipe is what CI uses).
//! * `GpuScene::upload(&ctx, &scene)` — prisms, vertices, a BVH2 over the CPU's prism boxes,
//!   the height map, and the seam stitch records when the scene stitches (`SeamMode`).
//! * `render_aovs(&ctx, &gpu_scene, &camera, &settings, &pdm_options, progress)` — one frame of
//!   AOVs as `prismbake::render::AovImage`, so `render::output::write_frame` writes it; the
//!   BVH is walked per ray or per subgroup packet (`AovWalk`, `render_aovs_walked`).
//! * `GpuBeautyScene::upload(&ctx, &beauty_scene)` and `render_beauty(..)` — one beauty frame
//!   as `prismbake::render::beauty::BeautyImage` (`render::output::write_beauty`).
//! * `GpuContext::take_kernel_seconds()` — the kernels' own time (GPU timestamps around every
//!   dispatch) since the last call, where the adapter has timestamp queries.
//! * `job::run` — a whole lookdev job (AOVs, beauty, turntables, contact sheets, the table
//!   cache) through `prismbake::render::lookdev`, with `job::GpuFrames` as its renderer.
//!
//! The shaders (`shaders/*.wgsl`, one per stage) mirror the CPU function by function under the
//! same names: `pcg_hash`/`hash_counters` (rng), `camera_ray` (`Camera::ray`), `sample_map`
//! (`HeightMap::sample`), `band_weight`, `displacement_at` (`PrismDisplacement::at`),
//! `displacement_at_grad` (`at_grad`) (seam), `surface_point`, `project_to_prism` (canonical),
//! `ray_prism_interval`, `cap_planes_reject` (prism_hit), `intersect_prism`, `march_levels`,
//! `level_cubic`, `level_at`, `level_track`, `level_sample`, `level_crossing`,
//! `refine_levels`, `flat_hit`, `fill_surface`, `intersect`, `occluded` (pdm),
//! `closest_hit`, `any_hit` (accel), `env_sample`, `env_pdf`, `env_radiance` (env),
//! `bsdf_sample`, `bsdf_eval`, `bsdf_pdf`, `power_heuristic` (shading), `trace_sample`,
//! `ground_hit` (beauty) and the entry points `render_aovs` and `render_beauty`. Parity is
//! tested image against image (`tests/parity.rs`, `tests/beauty.rs`); see docs/gpu.md.

pub mod beauty;
pub mod context;
pub mod job;
pub mod layout;
pub mod render;
pub mod scene;
pub mod shaders;
mod timer;

pub use beauty::{render_beauty, render_beauty_scheduled, GpuBeautyScene};
pub use context::{AovWalk, BeautySchedule, GpuContext};
pub use render::{render_aovs, render_aovs_walked};
pub use scene::GpuScene;

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No wgpu adapter at all (no GPU driver, no software Vulkan such as lavapipe).
    #[error("no GPU adapter found ({0}); install a Vulkan driver (Debian: mesa-vulkan-drivers for the lavapipe software rasteriser) or use --device cpu")]
    NoAdapter(String),
    /// The device could not be opened, or reported an error while rendering (a lost device,
    /// a refused resource).
    #[error("GPU device error: {0}")]
    Device(String),
    #[error("shader or pipeline rejected by wgpu: {0}")]
    Shader(String),
    #[error(
        "{what}: {bytes} bytes exceed this GPU's storage-binding limit of {limit} bytes; {fix}"
    )]
    TooLarge {
        what: &'static str,
        bytes: u64,
        limit: u64,
        /// What to do about it.
        fix: &'static str,
    },
    /// A texture (the environment map, the height map as stored) wider or taller than the
    /// device's largest 2D texture.
    #[error(
        "{what}: {width} × {height} texels, over this GPU's largest texture side of {side}; {fix}"
    )]
    TextureTooLarge {
        what: &'static str,
        width: u32,
        height: u32,
        side: u32,
        fix: &'static str,
    },
    #[error("not supported on the GPU: {0}")]
    Unsupported(String),
    /// A setting of the GPU path (an environment variable) that cannot be used.
    #[error("{0}")]
    Setting(String),
    /// The driver refused memory (or `PRISMBAKE_GPU_MEMORY`'s share of it ran out). A frame
    /// meets it only once its tiles cannot shrink further (`GpuContext::shrink_tile`).
    #[error("{adapter}: out of GPU memory ({detail}); free GPU memory (other applications), render a smaller --res, or raise PRISMBAKE_GPU_MEMORY if it is set")]
    OutOfMemory { adapter: String, detail: String },
}

impl GpuError {
    /// The adapter cannot hold the scene (an array over its storage-binding limit, a map over
    /// its largest texture, or memory the driver refused): the CPU renderer can still render it (`job::run_or_cpu`).
    pub fn is_capacity(&self) -> bool {
        matches!(
            self,
            GpuError::TooLarge { .. }
                | GpuError::TextureTooLarge { .. }
                | GpuError::OutOfMemory { .. }
        )
    }
}
