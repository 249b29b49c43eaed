//! The GPU context, built once: instance → adapter → device, the bind-group layouts, the
//! compute pipelines and the per-dispatch buffers (frame uniform; one tile of output and its
//! read-back copy, sized on first use to the tiles rendered). Dispatches only write the
//! uniform, dispatch and read back.
//!
//! Bind groups: group 0 is the scene (`GpuScene`, shared by every kernel), group 1 the
//! dispatch (frame uniform + the kernel's output), group 2 the beauty kernels' lighting
//! (`GpuLighting`: uniform + environment tables), group 3 their path records (`TileBuffers::
//! work`). The beauty pipelines and their buffers are built on first use, so an AOV-only run
//! never compiles them.

use crate::layout::{
    GpuAovPixel, GpuBeautySums, GpuBsdfTables, GpuFrame, PATH_RECORD_BYTES, WORKGROUP,
};
use crate::timer::KernelTimer;
use crate::{shaders, GpuError};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use wgpu::util::DeviceExt;

/// Tile of one dispatch on a software adapter, in pixels per side: lavapipe's time does not
/// depend on it, so it keeps the buffers small (512² × 432 B = 108 MiB of beauty path records).
pub const MAX_TILE: u32 = 512;

/// Tile of one dispatch on a hardware adapter: a 2048² frame in one dispatch. Each dispatch
/// waits for its slowest lanes (the long marches of a few rays); on an NVIDIA H200 a 2048²
/// AOV frame took 6.4–11.7 ms in one dispatch against 10.7–18.6 ms in sixteen 512² ones
/// (docs/gpu.md, "A real GPU"). A 2048² frame costs 192 MiB of AOV tile, 256 MiB of
/// read-back and, once beauty runs, 384 MiB of sums and 1728 MiB of path records (smaller
/// frames only what they use, `TileBuffers`); `PRISMBAKE_GPU_TILE` lowers it for small GPUs.
pub const HARDWARE_TILE: u32 = 2048;

/// Storage buffers the beauty kernels bind in the compute stage: the scene's five (prisms,
/// vertices, BVH nodes and indices, seam stitch records), the sums, the base-colour textures'
/// texels, the materials, and in the wavefront schedule the path records. The height map and
/// the environment are textures. The fused schedule's 8 are WebGPU's default, so it runs on
/// every adapter that has WebGPU's limits; the wavefront's 9 are requested from the adapter (native Vulkan, Metal and
/// DX12 adapters allow far more), and where it has only 8 the beauty takes the fused schedule.
/// The AOV kernel binds 8 (its 6 and the materials' alpha, `cut_layout`).
pub const BEAUTY_STORAGE_BUFFERS: u32 = 9;

/// How a beauty sample is dispatched (`shaders/beauty.wgsl`); both render the same image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BeautySchedule {
    /// One invocation renders its pixel's whole sample (`render_beauty`). The default on
    /// software adapters (lavapipe runs it 1.25× faster than the wavefront) and on adapters
    /// that bind only WebGPU's 8 storage buffers a stage.
    Fused,
    /// Trace and shade as separate dispatches over per-pixel path records (`beauty_start`,
    /// `beauty_trace`, `beauty_shade`), `PATH_RECORD_BYTES` of GPU memory per pixel of a tile.
    /// The default on hardware adapters that bind its 9 storage buffers: 19–27% less time
    /// per sample on an NVIDIA H200.
    Wavefront,
}

impl BeautySchedule {
    /// Its name, as `PRISMBAKE_GPU_BEAUTY` takes it.
    pub fn name(self) -> &'static str {
        match self {
            BeautySchedule::Fused => "fused",
            BeautySchedule::Wavefront => "wavefront",
        }
    }

    /// Storage buffers its pipeline layout binds.
    fn storage_buffers(self) -> u32 {
        match self {
            BeautySchedule::Fused => BEAUTY_STORAGE_BUFFERS - 1,
            BeautySchedule::Wavefront => BEAUTY_STORAGE_BUFFERS,
        }
    }
}

/// How the AOV kernel walks the BVH; both find each ray's closest hit, so both render the same
/// AOVs (up to which of two prisms reports a hit on their shared wall).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AovWalk {
    /// Each invocation walks its own ray (`render_aovs`, bvh.wgsl). The default on hardware
    /// adapters and wherever subgroup operations are missing.
    Ray,
    /// A subgroup's invocations walk their rays together (`render_aovs_packet`,
    /// packet.wgsl); needs subgroup operations. The default on software adapters that have
    /// them: lavapipe's 512² AOV kernels take 8–15% less time (docs/gpu.md).
    Packet,
}

impl AovWalk {
    /// Its name, as `PRISMBAKE_GPU_WALK` takes it.
    pub fn name(self) -> &'static str {
        match self {
            AovWalk::Ray => "ray",
            AovWalk::Packet => "packet",
        }
    }
}

/// The wavefront schedule's pipelines (built on first use), the entry points of
/// `beauty.wgsl`: a sample is `start`, then (`trace`, `shade`) per step of the longest path;
/// `tonemap` (`tonemap.wgsl`) makes the tile's preview after its last sample.
pub(crate) struct BeautyKernel {
    pub(crate) start: wgpu::ComputePipeline,
    pub(crate) trace: wgpu::ComputePipeline,
    pub(crate) shade: wgpu::ComputePipeline,
    pub(crate) tonemap: wgpu::ComputePipeline,
}

/// The fused schedule's pipelines: `render_beauty` (a whole sample), then `tonemap`.
pub(crate) struct BeautyFused {
    pub(crate) render: wgpu::ComputePipeline,
    pub(crate) tonemap: wgpu::ComputePipeline,
}

/// Which kernel's output a dispatch writes (`GpuContext::output`; it indexes
/// `TileBuffers::outputs`).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(crate) enum Output {
    /// `array<AovPixel>`, group 1 of the AOV kernel.
    Aov = 0,
    /// `array<BeautySums>`, group 1 of the beauty kernel.
    BeautySums = 1,
}

/// A kernel's output buffer and its group-1 bind group (frame uniform + output).
pub(crate) struct TileOutput {
    pub(crate) buffer: wgpu::Buffer,
    pub(crate) group: wgpu::BindGroup,
}

/// The per-dispatch output and read-back buffers, sized to the largest tile rendered so far
/// rather than to the context's tile side: a 512² frame on a hardware adapter (tile 2048²)
/// holds 512² pixels of them, not 2048² (~700 MiB). They grow when a larger frame comes.
#[derive(Default)]
pub(crate) struct TileBuffers {
    /// Each kernel's output, indexed by `Output`.
    pub(crate) outputs: [Option<TileOutput>; 2],
    /// The read-back copy either kernel's output goes through.
    pub(crate) readback: Option<wgpu::Buffer>,
    /// The beauty kernels' path records (`PATH_RECORD_BYTES` per pixel) and their group 3.
    pub(crate) work: Option<TileOutput>,
}

impl TileBuffers {
    fn bytes(&self) -> u64 {
        let outputs = self.outputs.iter().flatten().chain(&self.work);
        outputs
            .map(|o| o.buffer.size())
            .chain(self.readback.as_ref().map(|b| b.size()))
            .sum()
    }
}

pub struct GpuContext {
    pub(crate) adapter_info: wgpu::AdapterInfo,
    pub(crate) device: wgpu::Device,
    pub(crate) queue: wgpu::Queue,
    pub(crate) scene_layout: wgpu::BindGroupLayout,
    /// The AOV kernel of each walk (`AovWalk as usize`), built on first use.
    aov_kernels: [OnceLock<Result<wgpu::ComputePipeline, String>>; 2],
    /// The walk `render_aovs` takes (`Packet` on software adapters with subgroup operations,
    /// else `Ray`, or `PRISMBAKE_GPU_WALK`).
    aov_walk: AovWalk,
    /// The limits the device was opened with (`PRISMBAKE_GPU_LIMITS`).
    limits: DeviceLimits,
    pub(crate) frame_buffer: wgpu::Buffer,
    aov_layout: wgpu::BindGroupLayout,
    /// Group 2 of the AOV kernels: the materials and their texels, which the traversal reads
    /// for their alpha (`GpuScene`'s cut-out group; the beauty binds them in its lighting).
    pub(crate) cut_layout: wgpu::BindGroupLayout,
    /// Group 2 of the beauty kernel (lighting uniform, environment texels and tables, materials).
    pub(crate) lighting_layout: wgpu::BindGroupLayout,
    /// The GGX tables every beauty binds (`GpuBsdfTables`), uploaded on the first beauty
    /// (`bsdf_tables`).
    bsdf_tables: OnceLock<wgpu::Buffer>,
    beauty_layout: wgpu::BindGroupLayout,
    /// Group 3 of the beauty kernels (their path records).
    work_layout: wgpu::BindGroupLayout,
    beauty_fused: OnceLock<Result<BeautyFused, String>>,
    beauty_wavefront: OnceLock<Result<BeautyKernel, String>>,
    /// The beauty schedule a render takes (`Wavefront` on hardware adapters, `Fused` on
    /// software ones, or `PRISMBAKE_GPU_BEAUTY`).
    beauty_schedule: BeautySchedule,
    /// The output and read-back buffers; they serve one frame at a time.
    pub(crate) busy: Mutex<TileBuffers>,
    /// The kernels' own time, where the adapter has timestamp queries.
    pub(crate) timer: Option<Mutex<KernelTimer>>,
    /// The first wgpu error that no error scope caught (validation, out of memory, a lost
    /// device: a GPU watchdog's reset, say), held for the next `check`/`wait` to return
    /// instead of wgpu's default of panicking.
    driver_error: Arc<Mutex<Option<DriverError>>>,
    /// Pixels per side of one dispatch's tile (`MAX_TILE` or `HARDWARE_TILE`, or
    /// `PRISMBAKE_GPU_TILE`), halved by `shrink_tile` when the GPU runs out of memory.
    tile: AtomicU32,
    /// Pixels of a row each invocation of the wavefront's `beauty_trace` serves
    /// (`TRACE_PIXELS`, or `PRISMBAKE_GPU_TRACE_PIXELS`).
    pub(crate) trace_pixels: u32,
    /// Where warnings go (`set_warning_sink`; stderr until one is set).
    warn: Mutex<WarningSink>,
}

/// Receives the context's warnings, one message per call.
type WarningSink = Arc<dyn Fn(&str) + Send + Sync>;

/// An error wgpu reported outside any error scope: its text, and whether it is the driver
/// (or the memory budget) refusing memory, which smaller tiles may cure.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct DriverError {
    text: String,
    out_of_memory: bool,
}

impl DriverError {
    fn of(e: &wgpu::Error) -> DriverError {
        // With its sources: wgpu's own text can be just "Validation Error" or "Out of Memory".
        let mut text = e.to_string().trim().to_string();
        let mut source = std::error::Error::source(e);
        while let Some(s) = source {
            let more = s.to_string();
            if !text.contains(more.trim()) {
                text = format!("{text}: {}", more.trim());
            }
            source = s.source();
        }
        // One line: wgpu's descriptions run over several ("…\n\nCaused by:\n  In …").
        let text = text.split_whitespace().collect::<Vec<_>>().join(" ");
        DriverError {
            text,
            out_of_memory: matches!(e, wgpu::Error::OutOfMemory { .. }),
        }
    }
}

/// Smallest tile side `shrink_tile` goes down to.
const MIN_TILE: u32 = 64;

/// Shares of the GPU's memory budget `PRISMBAKE_GPU_MEMORY` accepts, in percent.
const MEMORY_SETTING: std::ops::RangeInclusive<u8> = 1..=100;

/// The share of the GPU's memory budget `PRISMBAKE_GPU_MEMORY` allows (`None` unset or empty),
/// or why it cannot be used.
fn memory_setting(value: Option<&str>) -> Result<Option<u8>, GpuError> {
    number_setting(
        value,
        |v| {
            let p: u8 = v.trim_end_matches('%').trim().parse().ok()?;
            MEMORY_SETTING.contains(&p).then_some(p)
        },
        |v| {
            format!(
            "PRISMBAKE_GPU_MEMORY={v}: the share of the GPU's memory budget prismbake may allocate, a whole percentage from {} to {} (e.g. 50 beside another GPU application); unset it for no limit",
            MEMORY_SETTING.start(),
            MEMORY_SETTING.end()
        )
        },
    )
}

/// The tile side after `tile` ran out of memory: half of it, a multiple of the workgroup side,
/// or `None` below `MIN_TILE`.
fn smaller_tile(tile: u32) -> Option<u32> {
    let half = tile / 2 / WORKGROUP * WORKGROUP;
    (half >= MIN_TILE).then_some(half)
}

/// Pixels each `beauty_trace` invocation serves by default: one (a ray per invocation). With
/// more, an invocation whose ray ends takes its next pixel's ray in the same loop instead of
/// idling until the longest ray of its SIMD group ends (docs/gpu.md, "Rays per invocation");
/// on lavapipe that neither gains nor loses, and it has not been timed on a GPU yet.
pub const TRACE_PIXELS: u32 = 1;

/// Pixels per `beauty_trace` invocation `PRISMBAKE_GPU_TRACE_PIXELS` accepts.
const TRACE_PIXELS_SETTING: std::ops::RangeInclusive<u32> = 1..=64;

/// The pixels per trace invocation `PRISMBAKE_GPU_TRACE_PIXELS` asks for (`None` unset or
/// empty), or why it cannot be used.
fn trace_pixels_setting(value: Option<&str>) -> Result<Option<u32>, GpuError> {
    number_setting(
        value,
        |v| {
            let n: u32 = v.parse().ok()?;
            TRACE_PIXELS_SETTING.contains(&n).then_some(n)
        },
        |v| {
            format!(
            "PRISMBAKE_GPU_TRACE_PIXELS={v}: the pixels each invocation of the wavefront beauty's trace kernel serves, a whole number from {} to {}; unset it for the default ({TRACE_PIXELS})",
            TRACE_PIXELS_SETTING.start(),
            TRACE_PIXELS_SETTING.end()
        )
        },
    )
}

/// The schedule `PRISMBAKE_GPU_BEAUTY` asks for (`None` unset or empty), or why it cannot be
/// used.
fn schedule_setting(value: Option<&str>) -> Result<Option<BeautySchedule>, GpuError> {
    let choices = [
        ("fused", BeautySchedule::Fused),
        ("wavefront", BeautySchedule::Wavefront),
    ];
    choice_setting(value, &choices, |v| {
        format!(
            "PRISMBAKE_GPU_BEAUTY={v}: the beauty schedule is `fused` (one kernel per sample) or `wavefront` (trace and shade dispatches); unset it for the default (fused on a software adapter, wavefront on a GPU)"
        )
    })
}

/// The limits a context opens its device with (`PRISMBAKE_GPU_LIMITS`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum DeviceLimits {
    /// WebGPU's defaults, raised to what the adapter has for the storage-binding and buffer
    /// sizes and for storage buffers per stage up to beauty's `BEAUTY_STORAGE_BUFFERS`.
    Adapter,
    /// WebGPU's defaults alone (`wgpu::Limits::defaults()`: 128 MiB a storage binding, 256 MiB
    /// a buffer, 8 storage buffers per stage), the least an adapter wgpu takes has: a job is
    /// checked against the smallest GPUs of a farm on a larger one, or in CI.
    WebGpu,
}

/// The limits `PRISMBAKE_GPU_LIMITS` asks for (`None` unset or empty), or why it cannot be
/// used.
fn limits_setting(value: Option<&str>) -> Result<Option<DeviceLimits>, GpuError> {
    let choices = [
        ("adapter", DeviceLimits::Adapter),
        ("webgpu", DeviceLimits::WebGpu),
    ];
    choice_setting(value, &choices, |v| {
        format!(
            "PRISMBAKE_GPU_LIMITS={v}: the device's limits are `adapter` (what the adapter has where a scene needs it) or `webgpu` (WebGPU's defaults, the least any adapter has: to check that a job fits the smallest GPUs); unset it for the default (adapter)"
        )
    })
}

/// The limits a device is opened with under `limits` on an adapter that `supports` these.
fn device_limits(limits: DeviceLimits, supported: &wgpu::Limits) -> wgpu::Limits {
    match limits {
        DeviceLimits::WebGpu => wgpu::Limits::defaults(),
        DeviceLimits::Adapter => wgpu::Limits {
            // Use what the adapter has for the one limit a large scene meets first.
            max_storage_buffer_binding_size: supported.max_storage_buffer_binding_size,
            max_buffer_size: supported.max_buffer_size,
            // Beauty's 10 or 11 where the adapter has them; an 8-buffer adapter still renders
            // AOVs.
            max_storage_buffers_per_shader_stage: supported
                .max_storage_buffers_per_shader_stage
                .clamp(
                    wgpu::Limits::defaults().max_storage_buffers_per_shader_stage,
                    BEAUTY_STORAGE_BUFFERS,
                ),
            ..wgpu::Limits::defaults()
        },
    }
}

/// The walk `PRISMBAKE_GPU_WALK` asks for (`None` unset or empty), or why it cannot be used.
fn walk_setting(value: Option<&str>) -> Result<Option<AovWalk>, GpuError> {
    let choices = [("ray", AovWalk::Ray), ("packet", AovWalk::Packet)];
    choice_setting(value, &choices, |v| {
        format!(
            "PRISMBAKE_GPU_WALK={v}: the AOV kernel's BVH walk is `ray` (each invocation its own ray) or `packet` (a subgroup's rays together; needs subgroup operations); unset it for the default (packet on a software adapter that has subgroups, ray elsewhere)"
        )
    })
}

/// A setting that names one of `choices`: `None` when unset or empty, the named one, or
/// `GpuError::Setting` with `refuse`'s message for any other text.
fn choice_setting<T: Copy>(
    value: Option<&str>,
    choices: &[(&str, T)],
    refuse: impl FnOnce(&str) -> String,
) -> Result<Option<T>, GpuError> {
    let Some(v) = value.map(str::trim).filter(|v| !v.is_empty()) else {
        return Ok(None);
    };
    match choices.iter().find(|(name, _)| *name == v) {
        Some(&(_, choice)) => Ok(Some(choice)),
        None => Err(GpuError::Setting(refuse(v))),
    }
}

/// Tile sides `PRISMBAKE_GPU_TILE` accepts.
const TILE_SETTING: std::ops::RangeInclusive<u32> = 64..=4096;

/// The tile side `PRISMBAKE_GPU_TILE` asks for (`None` unset or empty), or why it cannot be
/// used: a multiple of the workgroup side in `TILE_SETTING`.
fn tile_setting(value: Option<&str>) -> Result<Option<u32>, GpuError> {
    number_setting(
        value,
        |v| {
            let t: u32 = v.parse().ok()?;
            (TILE_SETTING.contains(&t) && t.is_multiple_of(WORKGROUP)).then_some(t)
        },
        |v| {
            format!(
            "PRISMBAKE_GPU_TILE={v}: the tile side is pixels per side of one dispatch, a multiple of {WORKGROUP} from {} to {} (e.g. 1024 for a GPU with little memory); unset it for the default ({MAX_TILE} on a software adapter, {HARDWARE_TILE} on a GPU)",
            TILE_SETTING.start(),
            TILE_SETTING.end()
        )
        },
    )
}

/// A numeric setting's value: `None` when unset or empty, what `parse` makes of the trimmed
/// text, or `GpuError::Setting` with `refuse`'s message when `parse` takes none.
fn number_setting<N>(
    value: Option<&str>,
    parse: impl FnOnce(&str) -> Option<N>,
    refuse: impl FnOnce(&str) -> String,
) -> Result<Option<N>, GpuError> {
    let Some(v) = value.map(str::trim).filter(|v| !v.is_empty()) else {
        return Ok(None);
    };
    match parse(v) {
        Some(n) => Ok(Some(n)),
        None => Err(GpuError::Setting(refuse(v))),
    }
}

/// Bytes per pixel of the largest per-pixel buffer a dispatch binds (the beauty kernels' path
/// records).
fn largest_pixel_bytes() -> u64 {
    (std::mem::size_of::<GpuAovPixel>() as u64)
        .max(std::mem::size_of::<GpuBeautySums>() as u64)
        .max(PATH_RECORD_BYTES)
}

/// The tile side: `setting` (`PRISMBAKE_GPU_TILE`), else `MAX_TILE` on a software adapter and
/// `HARDWARE_TILE` on others, cut to the largest whose per-pixel buffers the device binds
/// (`limit` bytes).
fn tile_side(setting: Option<u32>, software: bool, limit: u64) -> u32 {
    let fits = ((limit / largest_pixel_bytes()) as f64).sqrt() as u32 / WORKGROUP * WORKGROUP;
    setting
        .unwrap_or(if software { MAX_TILE } else { HARDWARE_TILE })
        .min(fits.max(WORKGROUP))
}

/// 32-bit float textures (not filterable without a feature; nothing here filters).
const FLOAT: wgpu::TextureSampleType = wgpu::TextureSampleType::Float { filterable: false };

/// A 2D texture read with `textureLoad`.
fn texture_entry(binding: u32, sample_type: wgpu::TextureSampleType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

pub(crate) fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

pub(crate) fn uniform_entry(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl GpuContext {
    /// The GGX tables' uniform (`GpuBsdfTables`), uploaded on first use: an AOV-only run
    /// never makes it.
    pub(crate) fn bsdf_tables(&self) -> &wgpu::Buffer {
        self.bsdf_tables.get_or_init(|| {
            self.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("bsdf tables"),
                    contents: bytemuck::bytes_of(&*GpuBsdfTables::new()),
                    usage: wgpu::BufferUsages::UNIFORM,
                })
        })
    }

    /// Pick an adapter (any wgpu adapter, software ones such as lavapipe included; wgpu's
    /// `WGPU_BACKEND`, `WGPU_ADAPTER_NAME` and `WGPU_POWER_PREF` environment variables apply),
    /// open a device with WebGPU's default limits (the adapter's own storage-binding and buffer
    /// size limits) and build the pipelines.
    pub fn new() -> Result<GpuContext, GpuError> {
        pollster::block_on(Self::new_async())
    }

    async fn new_async() -> Result<GpuContext, GpuError> {
        // A setting that cannot be used is refused before any device is opened.
        let tile_wanted = tile_setting(std::env::var("PRISMBAKE_GPU_TILE").ok().as_deref())?;
        let schedule_wanted =
            schedule_setting(std::env::var("PRISMBAKE_GPU_BEAUTY").ok().as_deref())?;
        let trace_pixels =
            trace_pixels_setting(std::env::var("PRISMBAKE_GPU_TRACE_PIXELS").ok().as_deref())?
                .unwrap_or(TRACE_PIXELS);
        let memory = memory_setting(std::env::var("PRISMBAKE_GPU_MEMORY").ok().as_deref())?;
        let walk_wanted = walk_setting(std::env::var("PRISMBAKE_GPU_WALK").ok().as_deref())?;
        let limits = limits_setting(std::env::var("PRISMBAKE_GPU_LIMITS").ok().as_deref())?
            .unwrap_or(DeviceLimits::Adapter);
        let mut instance_desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        // Where the backend tracks a memory budget (Vulkan with VK_EXT_memory_budget, D3D12),
        // a buffer that would take the GPU's use past this share is refused as out of memory.
        instance_desc.memory_budget_thresholds.for_resource_creation = memory;
        let instance = wgpu::Instance::new(instance_desc);
        let adapter = match std::env::var("WGPU_ADAPTER_NAME") {
            // A named adapter (case-insensitive substring of its name), as wgpu's own helpers
            // read it, but an error instead of a panic when none matches.
            Ok(want) => {
                let want = want.to_lowercase();
                let adapters = instance.enumerate_adapters(wgpu::Backends::all()).await;
                let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
                adapters
                    .into_iter()
                    .find(|a| a.get_info().name.to_lowercase().contains(&want))
                    .ok_or_else(|| {
                        GpuError::NoAdapter(format!(
                            "WGPU_ADAPTER_NAME={want} matches none of {names:?}"
                        ))
                    })?
            }
            Err(_) => {
                let options = wgpu::RequestAdapterOptions {
                    power_preference: wgpu::PowerPreference::from_env()
                        .unwrap_or(wgpu::PowerPreference::HighPerformance),
                    force_fallback_adapter: false,
                    compatible_surface: None,
                    apply_limit_buckets: false,
                };
                instance
                    .request_adapter(&options)
                    .await
                    .map_err(|e| GpuError::NoAdapter(e.to_string()))?
            }
        };
        let adapter_info = adapter.get_info();
        let required_limits = device_limits(limits, &adapter.limits());
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("prismbake"),
                // The kernels' own time (`KernelTimer`) where the adapter can measure it.
                required_features: adapter.features()
                    & (wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::SUBGROUP),
                required_limits,
                ..Default::default()
            })
            .await
            .map_err(|e| {
                GpuError::Device(format!(
                    "{} ({:?}): {e}",
                    adapter_info.name, adapter_info.backend
                ))
            })?;

        let driver_error = Arc::new(Mutex::new(None::<DriverError>));
        let sink = Arc::clone(&driver_error);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            sink.lock()
                .unwrap_or_else(|p| p.into_inner())
                .get_or_insert_with(|| DriverError::of(&e));
        }));

        let scene_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("scene"),
            entries: &[
                uniform_entry(0),                                // scene: SceneParams
                storage_entry(1, true),                          // prisms: array<Prism>
                storage_entry(2, true),                          // vertices: array<Vertex>
                storage_entry(3, true),                          // nodes: array<BvhNode>
                storage_entry(4, true),                          // prim_indices: array<u32>
                texture_entry(5, wgpu::TextureSampleType::Uint), // height_map: texture_2d<u32>
                storage_entry(6, true),                          // stitches: array<PrismStitch>
            ],
        });
        let aov_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("aov dispatch"),
            entries: &[
                uniform_entry(0),        // frame: Frame
                storage_entry(1, false), // aov_out: array<AovPixel>
            ],
        });

        let cut_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("materials' alpha"),
            entries: &[
                storage_entry(1, true), // texture_texels: array<f32>
                storage_entry(3, true), // materials: array<SurfaceMaterial>
            ],
        });
        let beauty_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("beauty dispatch"),
            entries: &[
                uniform_entry(0),        // frame: Frame
                storage_entry(1, false), // beauty_sums: array<BeautySums>
            ],
        });
        let work_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("beauty paths"),
            entries: &[storage_entry(0, false)], // paths: array<PathRecord>
        });
        let lighting_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("lighting"),
            entries: &[
                uniform_entry(0),        // lighting: Lighting
                storage_entry(1, true),  // texture_texels: array<f32>
                texture_entry(2, FLOAT), // env_rows: texture_2d<f32> (rg32float)
                storage_entry(3, true),  // materials: array<SurfaceMaterial>
                texture_entry(4, FLOAT), // env_radiance_map: texture_2d<f32> (rgba32float)
                texture_entry(5, FLOAT), // env_conditional: texture_2d<f32> (r32float)
                uniform_entry(6),        // bsdf_tables: BsdfTables
            ],
        });

        let frame_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: std::mem::size_of::<GpuFrame>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let software = adapter_info.device_type == wgpu::DeviceType::Cpu;
        let subgroups = device.features().contains(wgpu::Features::SUBGROUP);
        // A packet walk asked for where there are no subgroups fails in `aov_kernel` below.
        let aov_walk = walk_wanted.unwrap_or(match software && subgroups {
            true => AovWalk::Packet,
            false => AovWalk::Ray,
        });
        // The wavefront where the device binds its path records too (and not on software
        // adapters, where the fused kernel is faster).
        let wavefront_fits = device.limits().max_storage_buffers_per_shader_stage
            >= BeautySchedule::Wavefront.storage_buffers();
        let beauty_schedule = schedule_wanted.unwrap_or(match software || !wavefront_fits {
            true => BeautySchedule::Fused,
            false => BeautySchedule::Wavefront,
        });
        let tile = tile_side(
            tile_wanted,
            software,
            device
                .limits()
                .max_storage_buffer_binding_size
                .min(device.limits().max_buffer_size),
        );
        debug_assert_eq!(tile % WORKGROUP, 0);
        let timer = KernelTimer::new(&device, &queue).map(Mutex::new);
        let ctx = GpuContext {
            adapter_info,
            device,
            queue,
            scene_layout,
            aov_kernels: Default::default(),
            aov_walk,
            limits,
            frame_buffer,
            aov_layout,
            cut_layout,
            lighting_layout,
            bsdf_tables: OnceLock::new(),
            beauty_layout,
            work_layout,
            beauty_fused: OnceLock::new(),
            beauty_wavefront: OnceLock::new(),
            beauty_schedule,
            busy: Mutex::new(TileBuffers::default()),
            timer,
            driver_error,
            tile: AtomicU32::new(tile),
            warn: Mutex::new(Arc::new(|w: &str| eprintln!("{w}"))),
            trace_pixels,
        };
        // The default walk's kernel now, so that a shader the driver rejects fails here and
        // the first frame's time holds no compilation.
        ctx.aov_kernel(aov_walk)?;
        Ok(ctx)
    }

    /// The adapter's name, as the driver reports it (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)").
    pub fn adapter_name(&self) -> &str {
        &self.adapter_info.name
    }

    /// "name (backend, device type, driver version)", for logs: the driver version tells
    /// lavapipes apart, whose names only carry the LLVM version (docs/gpu.md, "lavapipe
    /// versions"). A device held to WebGPU's default limits says so.
    pub fn adapter_description(&self) -> String {
        let info = &self.adapter_info;
        let driver = info.driver_info.trim();
        let limits = match self.limits {
            DeviceLimits::Adapter => "",
            DeviceLimits::WebGpu => ", WebGPU's default limits",
        };
        if driver.is_empty() {
            format!(
                "{} ({:?}, {:?}{limits})",
                info.name, info.backend, info.device_type
            )
        } else {
            format!(
                "{} ({:?}, {:?}, {driver}{limits})",
                info.name, info.backend, info.device_type
            )
        }
    }

    /// Pixels per side of one dispatch's tile (frames larger than it take several dispatches).
    pub fn tile(&self) -> u32 {
        self.tile.load(Ordering::Relaxed)
    }

    /// After a frame ran out of GPU memory: free the tile buffers and halve the tile side for
    /// this and every later frame. `Some((old, new))`, or `None` when the tile is already the
    /// smallest (`MIN_TILE`) and the error stands.
    pub fn shrink_tile(&self) -> Option<(u32, u32)> {
        *self.busy.lock().unwrap_or_else(|e| e.into_inner()) = TileBuffers::default();
        let old = self.tile();
        let new = smaller_tile(old)?;
        self.tile.store(new, Ordering::Relaxed);
        Some((old, new))
    }

    /// Send the context's warnings to `sink` instead of stderr: a command line drawing a
    /// progress bar prints them between its redraws, where a bare `eprintln!` would be
    /// overdrawn.
    pub fn set_warning_sink(&self, sink: impl Fn(&str) + Send + Sync + 'static) {
        *self.warn.lock().unwrap_or_else(|e| e.into_inner()) = Arc::new(sink);
    }

    /// Say `message` through the warning sink (stderr unless `set_warning_sink` moved it).
    pub fn warn(&self, message: &str) {
        let sink = self.warn.lock().unwrap_or_else(|e| e.into_inner()).clone();
        sink(message);
    }

    /// Run `attempt` (one frame) and, while it runs out of GPU memory and the tile can shrink,
    /// shrink it (`shrink_tile`, saying so through the warning sink) and run it again. A
    /// frame's pixels do not depend on its tiles, so the retried frame is the frame the first
    /// tile would have given.
    pub fn with_tile_fallback<R>(
        &self,
        mut attempt: impl FnMut() -> Result<R, GpuError>,
    ) -> Result<R, GpuError> {
        loop {
            match attempt() {
                Err(e @ GpuError::OutOfMemory { .. }) => match self.shrink_tile() {
                    Some((old, new)) => self.warn(&format!(
                        "warning: {e}\nwarning: rendering in {new}² tiles instead of {old}² from now on"
                    )),
                    None => return Err(e),
                },
                other => return other,
            }
        }
    }

    /// Whether the kernels' own time is measured (the adapter has timestamp queries).
    pub fn has_kernel_timer(&self) -> bool {
        self.timer.is_some()
    }

    /// The kernels' own time since the last call, summed over their dispatches (GPU
    /// timestamps, `KernelTimer`); `None` where the adapter has no timestamp queries.
    pub fn take_kernel_seconds(&self) -> Result<Option<f64>, GpuError> {
        self.timer
            .as_ref()
            .map(|t| t.lock().unwrap_or_else(|e| e.into_inner()).take(self))
            .transpose()
    }

    /// Whether the adapter is a software rasteriser (lavapipe, WARP, SwiftShader).
    pub fn is_software(&self) -> bool {
        self.adapter_info.device_type == wgpu::DeviceType::Cpu
    }

    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// Largest storage-buffer binding this device accepts.
    pub fn max_binding_bytes(&self) -> u64 {
        self.device.limits().max_storage_buffer_binding_size
    }

    /// `GpuError::TextureTooLarge` (naming `what`, with `fix`) if a `width` × `height`
    /// texture has a side over this device's largest.
    pub(crate) fn check_texture_side(
        &self,
        what: &'static str,
        width: u32,
        height: u32,
        fix: &'static str,
    ) -> Result<(), GpuError> {
        let side = self.device.limits().max_texture_dimension_2d;
        if width > side || height > side {
            return Err(GpuError::TextureTooLarge {
                what,
                width,
                height,
                side,
                fix,
            });
        }
        Ok(())
    }

    /// A 2D texture the kernels read with `textureLoad`, filled with `write_texture_rows`.
    pub(crate) fn load_texture(
        &self,
        label: &str,
        format: wgpu::TextureFormat,
        width: u32,
        height: u32,
    ) -> wgpu::Texture {
        self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        })
    }

    /// Write `rows` whole rows of `texture` from row `y0`: `data` from byte `offset`,
    /// `bytes_per_row` apart.
    pub(crate) fn write_texture_rows(
        &self,
        texture: &wgpu::Texture,
        y0: u32,
        rows: u32,
        data: &[u8],
        offset: u64,
        bytes_per_row: u32,
    ) {
        self.queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture,
                mip_level: 0,
                origin: wgpu::Origin3d { x: 0, y: y0, z: 0 },
                aspect: wgpu::TextureAspect::All,
            },
            data,
            wgpu::TexelCopyBufferLayout {
                offset,
                bytes_per_row: Some(bytes_per_row),
                rows_per_image: Some(rows),
            },
            wgpu::Extent3d {
                width: texture.width(),
                height: rows,
                depth_or_array_layers: 1,
            },
        );
    }

    /// The beauty schedule a render on this context takes by default.
    pub fn beauty_schedule(&self) -> BeautySchedule {
        self.beauty_schedule
    }

    /// Pixels each invocation of the wavefront's trace kernel serves.
    pub fn trace_pixels(&self) -> u32 {
        self.trace_pixels
    }

    /// The walk `render_aovs` takes on this context.
    pub fn aov_walk(&self) -> AovWalk {
        self.aov_walk
    }

    /// The AOV kernel of `walk`, compiled on first use; `Packet` needs subgroup operations.
    pub(crate) fn aov_kernel(&self, walk: AovWalk) -> Result<&wgpu::ComputePipeline, GpuError> {
        if walk == AovWalk::Packet && !self.device.features().contains(wgpu::Features::SUBGROUP) {
            return Err(GpuError::Unsupported(format!(
                "the packet walk (PRISMBAKE_GPU_WALK=packet) needs subgroup operations, which {} ({:?}) does not have; unset PRISMBAKE_GPU_WALK or set it to `ray`",
                self.adapter_info.name, self.adapter_info.backend
            )));
        }
        let build = || {
            let (source, entry) = match walk {
                AovWalk::Ray => (shaders::aov_module_source(), "render_aovs"),
                AovWalk::Packet => (shaders::aov_packet_module_source(), "render_aovs_packet"),
            };
            let [kernel] = pollster::block_on(build_pipelines(
                &self.device,
                &source,
                [entry],
                &[&self.scene_layout, &self.aov_layout, &self.cut_layout],
            ))?;
            Ok(kernel)
        };
        self.aov_kernels[walk as usize]
            .get_or_init(|| build().map_err(|e: GpuError| e.to_string()))
            .as_ref()
            .map_err(|e| GpuError::Shader(e.clone()))
    }

    /// Compile the beauty kernels of the context's schedule now rather than with the first
    /// beauty frame (so that a job's frame times do not include it).
    pub fn prepare_beauty(&self) -> Result<(), GpuError> {
        match self.beauty_schedule {
            BeautySchedule::Fused => self.beauty_fused().map(|_| ()),
            BeautySchedule::Wavefront => self.beauty_wavefront().map(|_| ()),
        }
    }

    /// The fused beauty kernel, compiled on first use (an AOV-only run never builds it).
    pub(crate) fn beauty_fused(&self) -> Result<&BeautyFused, GpuError> {
        let build = || {
            self.check_beauty_bindings(BeautySchedule::Fused)?;
            let [render, tonemap] = pollster::block_on(build_pipelines(
                &self.device,
                &shaders::beauty_module_source(),
                ["render_beauty", "tonemap_preview"],
                &[
                    &self.scene_layout,
                    &self.beauty_layout,
                    &self.lighting_layout,
                ],
            ))?;
            Ok(BeautyFused { render, tonemap })
        };
        self.beauty_fused
            .get_or_init(|| build().map_err(|e: GpuError| e.to_string()))
            .as_ref()
            .map_err(|e| GpuError::Shader(e.clone()))
    }

    /// The wavefront beauty kernels, compiled on first use.
    pub(crate) fn beauty_wavefront(&self) -> Result<&BeautyKernel, GpuError> {
        self.beauty_wavefront
            .get_or_init(|| pollster::block_on(self.build_wavefront()).map_err(|e| e.to_string()))
            .as_ref()
            .map_err(|e| GpuError::Shader(e.clone()))
    }

    /// Whether this device can run the beauty schedule it renders with (its storage buffers per
    /// shader stage), before anything is compiled or uploaded.
    pub fn check_beauty(&self) -> Result<(), GpuError> {
        self.check_beauty_bindings(self.beauty_schedule)
    }

    /// Whether the device binds the storage buffers `schedule` needs in one stage.
    fn check_beauty_bindings(&self, schedule: BeautySchedule) -> Result<(), GpuError> {
        let have = self.device.limits().max_storage_buffers_per_shader_stage;
        let need = schedule.storage_buffers();
        if have < need {
            return Err(GpuError::Unsupported(format!(
                "beauty ({schedule:?}) binds {need} storage buffers in one shader stage and {} allows {have}; render AOVs on it, or the beauty with --device auto (on the CPU where the GPU cannot) or --device cpu",
                self.adapter_info.name
            )));
        }
        Ok(())
    }

    async fn build_wavefront(&self) -> Result<BeautyKernel, GpuError> {
        self.check_beauty_bindings(BeautySchedule::Wavefront)?;
        let [start, trace, shade, tonemap] = build_pipelines(
            &self.device,
            &shaders::beauty_module_source(),
            [
                "beauty_start",
                "beauty_trace",
                "beauty_shade",
                "tonemap_preview",
            ],
            &[
                &self.scene_layout,
                &self.beauty_layout,
                &self.lighting_layout,
                &self.work_layout,
            ],
        )
        .await?;
        Ok(BeautyKernel {
            start,
            trace,
            shade,
            tonemap,
        })
    }

    /// Wait until the GPU has finished everything submitted so far (then `check`).
    pub(crate) fn wait(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Device(format!("waiting for the GPU: {e}")))?;
        self.check()
    }

    /// The error wgpu reported outside any error scope since the last call, if any (then
    /// cleared): a lost device or an allocation the driver refused becomes an error of the
    /// render that met it, not a panic.
    pub fn check(&self) -> Result<(), GpuError> {
        match self
            .driver_error
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take()
        {
            Some(e) if e.out_of_memory => Err(GpuError::OutOfMemory {
                adapter: self.adapter_info.name.clone(),
                detail: e.text,
            }),
            Some(e) => Err(GpuError::Device(format!(
                "{}: {}",
                self.adapter_info.name, e.text
            ))),
            None => Ok(()),
        }
    }

    /// Copy the first `size` bytes of `src` to the read-back buffer `readback` (of
    /// `TileBuffers`, grown to `size` if smaller), submit, wait, and hand the bytes to `f`.
    /// Shared by every kernel's read-back.
    pub(crate) fn read_back<R>(
        &self,
        readback: &mut Option<wgpu::Buffer>,
        encoder: wgpu::CommandEncoder,
        src: &wgpu::Buffer,
        size: u64,
        f: impl FnOnce(&[u8]) -> R,
    ) -> Result<R, GpuError> {
        if readback.as_ref().is_none_or(|b| b.size() < size) {
            *readback = None;
            *readback = Some(self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("tile readback"),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
            self.check()?;
        }
        let dst = readback.as_ref().expect("allocated above");
        self.read_back_into(encoder, src, dst, size, f)
    }

    /// The output buffer of `which` kernel (its slot of `TileBuffers::outputs`) and its
    /// group-1 bind group, holding at least `bytes` (reallocated, the old one dropped first,
    /// when smaller). The bytes the buffers hold now: `tile_buffer_bytes`.
    pub(crate) fn output<'b>(
        &self,
        outputs: &'b mut [Option<TileOutput>; 2],
        which: Output,
        bytes: u64,
    ) -> Result<&'b TileOutput, GpuError> {
        let (layout, label) = match which {
            Output::Aov => (&self.aov_layout, "aov tile"),
            Output::BeautySums => (&self.beauty_layout, "beauty sums tile"),
        };
        let usage = wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST;
        // Group 1: the frame uniform, then aov_out or beauty_sums.
        self.grown(
            &mut outputs[which as usize],
            bytes,
            label,
            layout,
            usage,
            true,
        )
    }

    /// The beauty kernels' path records (`TileBuffers::work`) and their group-3 bind group,
    /// holding at least `bytes` (reallocated, the old one dropped first, when smaller).
    pub(crate) fn work<'b>(
        &self,
        work: &'b mut Option<TileOutput>,
        bytes: u64,
    ) -> Result<&'b TileOutput, GpuError> {
        let usage = wgpu::BufferUsages::STORAGE;
        self.grown(work, bytes, "beauty paths", &self.work_layout, usage, false)
    }

    /// The buffer in `slot` and its bind group over `layout`, holding at least `bytes`
    /// (reallocated, the old one dropped first, when smaller): the buffer is the group's last
    /// binding, after the frame uniform at binding 0 when `with_frame`.
    fn grown<'b>(
        &self,
        slot: &'b mut Option<TileOutput>,
        bytes: u64,
        label: &str,
        layout: &wgpu::BindGroupLayout,
        usage: wgpu::BufferUsages,
        with_frame: bool,
    ) -> Result<&'b TileOutput, GpuError> {
        if slot.as_ref().is_none_or(|o| o.buffer.size() < bytes) {
            *slot = None;
            let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage,
                mapped_at_creation: false,
            });
            let mut entries = vec![];
            if with_frame {
                entries.push(self.frame_buffer.as_entire_binding());
            }
            entries.push(buffer.as_entire_binding());
            let entries: Vec<wgpu::BindGroupEntry> = entries
                .into_iter()
                .enumerate()
                .map(|(binding, resource)| wgpu::BindGroupEntry {
                    binding: binding as u32,
                    resource,
                })
                .collect();
            let group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(label),
                layout,
                entries: &entries,
            });
            // A refused allocation is this render's error (`check`), not a later one's.
            self.check()?;
            *slot = Some(TileOutput { buffer, group });
        }
        Ok(slot.as_ref().expect("allocated above"))
    }

    /// Bytes of GPU memory the output and read-back buffers hold now: those of the largest
    /// tile rendered so far by each kernel (none before the first frame).
    pub fn tile_buffer_bytes(&self) -> u64 {
        self.busy.lock().unwrap_or_else(|e| e.into_inner()).bytes()
    }

    /// `read_back` through the mappable buffer `dst` (`MAP_READ | COPY_DST`).
    pub(crate) fn read_back_into<R>(
        &self,
        encoder: wgpu::CommandEncoder,
        src: &wgpu::Buffer,
        dst: &wgpu::Buffer,
        size: u64,
        f: impl FnOnce(&[u8]) -> R,
    ) -> Result<R, GpuError> {
        let mut encoder = encoder;
        encoder.copy_buffer_to_buffer(src, 0, dst, 0, size);
        self.queue.submit([encoder.finish()]);
        let slice = dst.slice(0..size);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.wait()?;
        rx.recv()
            .map_err(|e| GpuError::Device(format!("read-back: {e}")))?
            .map_err(|e| GpuError::Device(format!("read-back: {e}")))?;
        let out = {
            let view = slice
                .get_mapped_range()
                .map_err(|e| GpuError::Device(format!("read-back: {e}")))?;
            f(&view)
        };
        dst.unmap();
        Ok(out)
    }
}

/// Compile `source` once and build the compute pipeline of each of its `entries` over one
/// layout of `layouts` (groups 0, 1, …); a WGSL or validation error becomes `GpuError::Shader`.
async fn build_pipelines<const N: usize>(
    device: &wgpu::Device,
    source: &str,
    entries: [&str; N],
    layouts: &[&wgpu::BindGroupLayout],
) -> Result<[wgpu::ComputePipeline; N], GpuError> {
    let label = entries.join(", ");
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(&label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let groups: Vec<Option<&wgpu::BindGroupLayout>> = layouts.iter().map(|l| Some(*l)).collect();
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(&label),
        bind_group_layouts: &groups,
        immediate_size: 0,
    });
    let pipelines = entries.map(|entry| {
        device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        })
    });
    if let Some(e) = scope.pop().await {
        return Err(GpuError::Shader(format!("{label}: {e}")));
    }
    Ok(pipelines)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_setting_takes_multiples_of_the_workgroup_and_names_the_fix() {
        assert_eq!(tile_setting(None).unwrap(), None);
        assert_eq!(tile_setting(Some(" ")).unwrap(), None);
        assert_eq!(tile_setting(Some("1024")).unwrap(), Some(1024));
        assert_eq!(tile_setting(Some("64")).unwrap(), Some(64));
        assert_eq!(tile_setting(Some("4096")).unwrap(), Some(4096));
        for bad in ["1020", "32", "8192", "-512", "big", "512px"] {
            let e = tile_setting(Some(bad)).unwrap_err().to_string();
            assert!(
                e.contains(&format!("PRISMBAKE_GPU_TILE={bad}")) && e.contains("multiple of 8"),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn memory_setting_takes_percentages_and_names_the_fix() {
        assert_eq!(memory_setting(None).unwrap(), None);
        assert_eq!(memory_setting(Some("")).unwrap(), None);
        assert_eq!(memory_setting(Some("50")).unwrap(), Some(50));
        assert_eq!(memory_setting(Some(" 80% ")).unwrap(), Some(80));
        assert_eq!(memory_setting(Some("100")).unwrap(), Some(100));
        for bad in ["0", "101", "-5", "half", "2GiB"] {
            let e = memory_setting(Some(bad)).unwrap_err().to_string();
            assert!(
                e.contains(&format!("PRISMBAKE_GPU_MEMORY={bad}")) && e.contains("unset it"),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn tiles_halve_to_workgroup_multiples_down_to_the_smallest() {
        let mut sides = vec![2048];
        while let Some(next) = smaller_tile(*sides.last().unwrap()) {
            sides.push(next);
        }
        assert_eq!(sides, [2048, 1024, 512, 256, 128, 64]);
        assert_eq!(smaller_tile(600), Some(296));
        assert_eq!(smaller_tile(136), Some(64));
        assert_eq!(smaller_tile(120), None);
    }

    #[test]
    fn driver_errors_say_whether_memory_ran_out_and_keep_their_causes() {
        #[derive(Debug)]
        struct Cause(&'static str);
        impl std::fmt::Display for Cause {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.0)
            }
        }
        impl std::error::Error for Cause {}
        let oom = DriverError::of(&wgpu::Error::OutOfMemory {
            source: Box::new(Cause("In Device::create_buffer: Not enough memory left.")),
        });
        assert!(oom.out_of_memory);
        assert_eq!(
            oom.text,
            "Out of Memory: In Device::create_buffer: Not enough memory left."
        );
        let invalid = DriverError::of(&wgpu::Error::Validation {
            source: Box::new(Cause("Buffer with 'tile' label is invalid")),
            description: "Validation Error\n\nCaused by:\n  Buffer with 'tile' label is invalid\n"
                .into(),
        });
        assert!(!invalid.out_of_memory);
        assert_eq!(
            invalid.text,
            "Validation Error Caused by: Buffer with 'tile' label is invalid"
        );
    }

    #[test]
    fn trace_pixels_setting_takes_whole_numbers_in_range_and_names_the_fix() {
        assert_eq!(trace_pixels_setting(None).unwrap(), None);
        assert_eq!(trace_pixels_setting(Some(" ")).unwrap(), None);
        assert_eq!(trace_pixels_setting(Some("1")).unwrap(), Some(1));
        assert_eq!(trace_pixels_setting(Some(" 64 ")).unwrap(), Some(64));
        for bad in ["0", "65", "-2", "four", "2.5"] {
            let e = trace_pixels_setting(Some(bad)).unwrap_err().to_string();
            assert!(
                e.contains(&format!("PRISMBAKE_GPU_TRACE_PIXELS={bad}")) && e.contains("unset it"),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn walk_setting_takes_the_two_walks_and_names_the_fix() {
        assert_eq!(walk_setting(None).unwrap(), None);
        assert_eq!(walk_setting(Some(" ")).unwrap(), None);
        assert_eq!(walk_setting(Some("ray")).unwrap(), Some(AovWalk::Ray));
        assert_eq!(
            walk_setting(Some(" packet")).unwrap(),
            Some(AovWalk::Packet)
        );
        for bad in ["Packet", "rays", "2"] {
            let e = walk_setting(Some(bad)).unwrap_err().to_string();
            assert!(
                e.contains(&format!("PRISMBAKE_GPU_WALK={bad}")) && e.contains("packet"),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn schedule_setting_takes_the_two_schedules_and_names_the_fix() {
        assert_eq!(schedule_setting(None).unwrap(), None);
        assert_eq!(schedule_setting(Some("")).unwrap(), None);
        assert_eq!(
            schedule_setting(Some("fused")).unwrap(),
            Some(BeautySchedule::Fused)
        );
        assert_eq!(
            schedule_setting(Some(" wavefront ")).unwrap(),
            Some(BeautySchedule::Wavefront)
        );
        for bad in ["Fused", "split", "1"] {
            let e = schedule_setting(Some(bad)).unwrap_err().to_string();
            assert!(
                e.contains(&format!("PRISMBAKE_GPU_BEAUTY={bad}")) && e.contains("wavefront"),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn tile_side_is_the_setting_or_the_default_within_the_binding_limit() {
        let big = u64::MAX / 2;
        assert_eq!(tile_side(None, true, big), MAX_TILE);
        assert_eq!(tile_side(None, false, big), HARDWARE_TILE);
        assert_eq!(tile_side(Some(1024), false, big), 1024);
        // WebGPU's default binding limit (128 MiB) holds 557² beauty path records of 432
        // bytes: cut to a multiple of the workgroup.
        let pixel = PATH_RECORD_BYTES;
        let t = tile_side(None, false, 128 << 20);
        assert_eq!(t % WORKGROUP, 0);
        assert!((t as u64).pow(2) * pixel <= 128 << 20);
        assert!(((t + WORKGROUP) as u64).pow(2) * pixel > 128 << 20);
    }
}
