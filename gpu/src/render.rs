//! `render_aovs` on the GPU: the mirror of `prismbake::render::render_aovs`, returning the same
//! `AovImage`. The image is dispatched in tiles of at most `MAX_TILE`² pixels; each tile
//! writes its uniform, dispatches `div_ceil(tile, WORKGROUP)` workgroups and reads back.

use crate::context::{GpuContext, MAX_TILE};
use crate::layout::{GpuAovPixel, GpuFrame, WORKGROUP};
use crate::scene::GpuScene;
use crate::GpuError;
use glam::{Vec2, Vec3};
use prismbake::render::camera::Camera;
use prismbake::render::{AovImage, RenderSettings};
use prismbake::trace::pdm::{Construction, PdmOptions, StepSize};
use prismbake::trace::NormalMode;

/// Orthonormal (right, up, back) of the view, computed exactly as `Camera::ray` computes it.
pub fn camera_basis(cam: &Camera) -> (Vec3, Vec3, Vec3) {
    let back = (cam.from - cam.to).normalize();
    let mut right = cam.up.cross(back);
    if right.length_squared() < 1e-12 {
        right = back.any_orthonormal_vector();
    }
    let right = right.normalize();
    (right, back.cross(right), back)
}

/// The per-dispatch uniform for a whole frame (the tile fields are set per tile).
pub fn frame_uniform(cam: &Camera, s: &RenderSettings, opts: &PdmOptions) -> GpuFrame {
    let (right, up, back) = camera_basis(cam);
    let (dt_auto, dt_value) = match opts.dt {
        StepSize::Auto(f) => (1, f),
        StepSize::World(w) => (0, w),
    };
    GpuFrame {
        cam_from: cam.from.to_array(),
        tan_half_fov: (cam.yfov_deg.to_radians() * 0.5).tan(),
        cam_right: right.to_array(),
        aspect: s.width as f32 / s.height as f32,
        cam_up: up.to_array(),
        width: s.width,
        cam_back: back.to_array(),
        height: s.height,
        tile_origin: [0, 0],
        tile_size: [s.width, s.height],
        spp: s.spp,
        seed: s.seed,
        dt_auto,
        dt_value,
        jitter: opts.jitter as u32,
        refine: opts.refine as u32,
        normal_mode: match opts.normal_mode {
            NormalMode::Smooth => 0,
            NormalMode::Geometric => 1,
        },
        sample_index: 0,
    }
}

/// Render one frame of AOVs with PDM on the GPU (the same image as the CPU's `render_aovs`
/// with `Pdm` up to float rounding; `opts.normal_mode` picks the shading normal).
/// `progress` is called with the number of rows finished so far.
pub fn render_aovs(
    ctx: &GpuContext,
    scene: &GpuScene,
    cam: &Camera,
    s: &RenderSettings,
    opts: &PdmOptions,
    progress: &dyn Fn(usize),
) -> Result<AovImage, GpuError> {
    check_render(s, opts)?;
    let _busy = ctx.busy.lock().unwrap_or_else(|e| e.into_inner());
    let (w, h) = (s.width, s.height);
    let n = (w * h) as usize;
    let mut pixels = vec![GpuAovPixel::default(); n];
    let base = frame_uniform(cam, s, opts);
    for ty in (0..h).step_by(MAX_TILE as usize) {
        for tx in (0..w).step_by(MAX_TILE as usize) {
            let (tw, th) = ((w - tx).min(MAX_TILE), (h - ty).min(MAX_TILE));
            let frame = GpuFrame {
                tile_origin: [tx, ty],
                tile_size: [tw, th],
                ..base
            };
            ctx.queue
                .write_buffer(&ctx.frame_buffer, 0, bytemuck::bytes_of(&frame));
            let mut encoder = ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("aov tile"),
                });
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("render_aovs"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&ctx.aov_pipeline);
                pass.set_bind_group(0, &scene.group, &[]);
                pass.set_bind_group(1, &ctx.aov_group, &[]);
                pass.dispatch_workgroups(tw.div_ceil(WORKGROUP), th.div_ceil(WORKGROUP), 1);
            }
            let bytes = (tw * th) as u64 * std::mem::size_of::<GpuAovPixel>() as u64;
            ctx.read_back(encoder, &ctx.aov_buffer, bytes, |data| {
                let tile: &[GpuAovPixel] = bytemuck::cast_slice(data);
                for row in 0..th {
                    let src = &tile[(row * tw) as usize..((row + 1) * tw) as usize];
                    let dst = ((ty + row) * w + tx) as usize;
                    pixels[dst..dst + tw as usize].copy_from_slice(src);
                }
            })?;
            progress(((ty + th) as usize).min(h as usize));
        }
    }
    Ok(to_image(&pixels, s))
}

/// What every GPU render refuses: the CPU-only PDM construction and an empty image.
pub(crate) fn check_render(s: &RenderSettings, opts: &PdmOptions) -> Result<(), GpuError> {
    if opts.construction != Construction::SharedWall {
        return Err(GpuError::Unsupported(
            "the parallel-offset PDM construction is a CPU-only measurement mode".into(),
        ));
    }
    if s.width == 0 || s.height == 0 || s.spp == 0 {
        return Err(GpuError::Unsupported(format!(
            "empty render {}x{} at {} spp",
            s.width, s.height, s.spp
        )));
    }
    Ok(())
}

/// Unpack kernel output into the CPU's `AovImage` (steps divided by spp as the CPU does).
fn to_image(pixels: &[GpuAovPixel], s: &RenderSettings) -> AovImage {
    let n = pixels.len();
    let mut img = AovImage {
        width: s.width,
        height: s.height,
        depth: Vec::with_capacity(n),
        normal: Vec::with_capacity(n),
        mask: Vec::with_capacity(n),
        uv: Vec::with_capacity(n),
        steps: Vec::with_capacity(n),
        prism: Vec::with_capacity(n),
        rays: n as u64 * s.spp as u64,
        total_steps: 0,
    };
    for p in pixels {
        img.depth.push(p.depth);
        img.normal.push(Vec3::from_array(p.normal));
        img.mask.push(p.mask);
        img.uv.push(Vec2::from_array(p.uv));
        img.steps.push(p.steps_sum / s.spp as f32);
        img.total_steps += p.steps_sum as u64;
        img.prism.push(p.prism as f32);
    }
    img
}
