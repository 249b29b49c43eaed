//! One GPU context for the whole test binary (building the pipelines compiles every shader),
//! and the example assets loaded, repaired, baked and framed as the parity tests need them.

use glam::Vec3;
use prismbake::accel::Scene;
use prismbake::asset::{self, Overrides};
use prismbake::mesh::UpAxis;
use prismbake::render::camera::Camera;
use prismbake::render::job::{load_input, Input};
use prismbake::repair::RepairOptions;
use prismbake_gpu::GpuContext;
use std::path::PathBuf;
use std::sync::OnceLock;

pub fn ctx() -> &'static GpuContext {
    static CTX: OnceLock<GpuContext> = OnceLock::new();
    CTX.get_or_init(|| {
        let ctx = GpuContext::new().unwrap_or_else(|e| {
            panic!("no usable wgpu adapter: {e}\n(install mesa-vulkan-drivers for lavapipe; a missing adapter fails these tests on purpose)")
        });
        eprintln!("adapter: {}", ctx.adapter_description());
        ctx
    })
}

/// An example asset rendered on the CPU with PDM's defaults at `size`² (one sample at the pixel
/// centre, seed 7): the scene, the settings and options used, and the image.
pub fn cpu_render(
    rel: &str,
    size: u32,
) -> (
    ExampleScene,
    prismbake::render::RenderSettings,
    prismbake::trace::pdm::PdmOptions,
    prismbake::render::AovImage,
) {
    use prismbake::render::{self, RenderSettings};
    use prismbake::trace::pdm::{Pdm, PdmOptions};
    let ex = example_scene(rel);
    let settings = RenderSettings {
        width: size,
        height: size,
        spp: 1,
        seed: 7,
    };
    let opts = PdmOptions::default();
    let cpu = render::render_aovs(&Pdm::new(&ex.scene, opts), &ex.cam, &settings, &|_| {});
    (ex, settings, opts, cpu)
}

pub fn example(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../examples")
        .join(rel)
}

/// An example asset as a scene, with a square camera framing it and its up axis.
pub struct ExampleScene {
    pub scene: Scene,
    pub cam: Camera,
    pub up_axis: UpAxis,
    /// Bounds of the base mesh.
    pub lo: Vec3,
    pub hi: Vec3,
}

pub fn example_scene(rel: &str) -> ExampleScene {
    let spec = asset::resolve(&example(rel), &Overrides::default()).expect("resolve");
    let loaded = load_input(&Input::Asset(spec), &RepairOptions::default()).expect("prepare");
    // Framed from the base mesh, not `table.bounds()`: a prism with nearly opposed corner
    // normals (flagged PRISM_DEGENERATE_NORMALS, λ range / 1e-3) can make the table's box
    // much larger than the asset (the rock's is), leaving it a few pixels wide.
    let (lo, hi) = loaded
        .table
        .positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let cam = Camera::frame_bounds(lo, hi, loaded.up_axis, 40.0, 1.0);
    ExampleScene {
        up_axis: loaded.up_axis,
        scene: Scene::new(loaded.table, loaded.map),
        cam,
        lo,
        hi,
    }
}

/// Run a probe kernel: entry point `probe` of the WGSL `src`, `@workgroup_size(64)`, one
/// invocation per element of `io` (a read-write storage array bound at `io_at` = (group,
/// binding)), with the read-only buffers `inputs` bound as (group, binding, contents). Returns
/// `io` as the kernel left it.
pub fn run_probe<T: bytemuck::Pod>(
    label: &str,
    src: &str,
    io_at: (u32, u32),
    io: &[T],
    inputs: &[(u32, u32, &[u8], wgpu::BufferUsages)],
) -> Vec<T> {
    run_probe_with_textures(label, src, io_at, io, inputs, &[])
}

/// `run_probe` with texture views bound too, at `(group, binding)`.
pub fn run_probe_with_textures<T: bytemuck::Pod>(
    label: &str,
    src: &str,
    io_at: (u32, u32),
    io: &[T],
    inputs: &[(u32, u32, &[u8], wgpu::BufferUsages)],
    textures: &[(u32, u32, &wgpu::TextureView)],
) -> Vec<T> {
    use wgpu::util::DeviceExt;
    let ctx = ctx();
    let device = ctx.device();
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: None,
        module: &module,
        entry_point: Some("probe"),
        compilation_options: Default::default(),
        cache: None,
    });
    let init = |label: &str, contents: &[u8], usage| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage,
        })
    };
    let bytes = std::mem::size_of_val(io) as u64;
    let io_buf = init(
        "io",
        bytemuck::cast_slice(io),
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
    );
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: bytes,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut bound: Vec<(u32, u32, wgpu::Buffer)> = inputs
        .iter()
        .map(|&(g, b, data, usage)| (g, b, init("input", data, usage)))
        .collect();
    bound.push((io_at.0, io_at.1, io_buf));
    let mut groups: Vec<u32> = bound
        .iter()
        .map(|&(g, _, _)| g)
        .chain(textures.iter().map(|&(g, _, _)| g))
        .collect();
    groups.sort_unstable();
    groups.dedup();
    let bind_groups: Vec<(u32, wgpu::BindGroup)> = groups
        .iter()
        .map(|&g| {
            let entries: Vec<wgpu::BindGroupEntry> =
                bound
                    .iter()
                    .filter(|(bg, _, _)| *bg == g)
                    .map(|(_, binding, buf)| wgpu::BindGroupEntry {
                        binding: *binding,
                        resource: buf.as_entire_binding(),
                    })
                    .chain(textures.iter().filter(|(tg, _, _)| *tg == g).map(
                        |&(_, binding, view)| wgpu::BindGroupEntry {
                            binding,
                            resource: wgpu::BindingResource::TextureView(view),
                        },
                    ))
                    .collect();
            let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout: &pipeline.get_bind_group_layout(g),
                entries: &entries,
            });
            (g, group)
        })
        .collect();
    let mut enc = device.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        for (g, group) in &bind_groups {
            pass.set_bind_group(*g, group, &[]);
        }
        pass.dispatch_workgroups((io.len() as u32).div_ceil(64), 1, 1);
    }
    let io_buf = &bound.last().expect("io is bound").2;
    enc.copy_buffer_to_buffer(io_buf, 0, &readback, 0, bytes);
    ctx.queue().submit([enc.finish()]);
    readback
        .slice(..)
        .map_async(wgpu::MapMode::Read, |r| r.expect("map"));
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .expect("poll");
    let view = readback.slice(..).get_mapped_range().expect("mapped");
    bytemuck::cast_slice(&view).to_vec()
}
