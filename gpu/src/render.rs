//! `render_aovs` on the GPU: the mirror of `prismbake::render::render_aovs`, returning the same
//! `AovImage`. Both kernels (AOVs, beauty) render one sample per submission into per-pixel
//! sums (`render_samples`): tiles of at most the context's tile² pixels, each cleared, its
//! stages dispatched `spp` times and read back.

use crate::context::{AovWalk, GpuContext, Output, TileBuffers};
use crate::layout::{GpuAovPixel, GpuFrame, PATH_RECORD_BYTES, WORKGROUP};
use crate::scene::GpuScene;
use crate::GpuError;
use glam::{Vec2, Vec3};
use prismbake::render::camera::Camera;
use prismbake::render::{AovImage, RenderSettings};
use prismbake::trace::pdm::{Construction, PdmOptions, StepSize};
use prismbake::trace::NormalMode;
use rayon::prelude::*;

/// The per-dispatch uniform for a whole frame (the tile fields are set per tile); the view's
/// basis and extent as `Camera::raster` computes them.
pub fn frame_uniform(cam: &Camera, s: &RenderSettings, opts: &PdmOptions) -> GpuFrame {
    let (right, up, back) = cam.basis();
    let (half, orthographic) = cam.half_extent();
    let (dt_auto, dt_value) = match opts.dt {
        StepSize::Auto(f) => (1, f),
        StepSize::World(w) => (0, w),
    };
    GpuFrame {
        cam_from: cam.from.to_array(),
        tan_half_fov: half,
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
        orthographic: orthographic as u32,
        _pad0: 0,
        _pad1: 0,
        _pad2: 0,
    }
}

/// One dispatch of a sample: a pipeline and its grid, `div_ceil(tile, WORKGROUP)` groups
/// across and `layers` times that down (the beauty trace's ray slots, `beauty_trace`).
#[derive(Clone, Copy)]
pub(crate) struct Stage<'a> {
    pub pipeline: &'a wgpu::ComputePipeline,
    pub layers: u32,
    /// Pixels of a row each invocation serves (`beauty_trace`); 1 elsewhere.
    pub across: u32,
}

/// A kernel over a frame: the stages one sample dispatches, in order (wgpu puts a barrier
/// between dispatches that write the same buffer), those dispatched once more after a tile's
/// last sample (`finish`: the beauty's preview), the output its group 1 writes (`T` per pixel
/// of a tile; group 0 is the scene), its bind groups 2..., and whether it takes the beauty
/// path records as its last group (`TileBuffers::work`).
pub(crate) struct Kernel<'a> {
    pub stages: &'a [Stage<'a>],
    pub finish: &'a [Stage<'a>],
    pub output: Output,
    pub groups: &'a [&'a wgpu::BindGroup],
    pub paths: bool,
    pub label: &'static str,
}

/// Render a frame with a sample-accumulating kernel: per tile of at most the context's tile²,
/// clear the output, dispatch `div_ceil(tile, WORKGROUP)` workgroups once per sample (the frame
/// uniform's `sample_index`; written before each submission, so each dispatch sees its own),
/// and hand the tile's pixels (row-major, `tile.width` per row) to `sink` straight from the
/// mapped read-back buffer, so that a frame's pixels are never copied whole before they are
/// resolved. `progress` gets rows finished, scaled over the samples of every tile.
pub(crate) fn render_samples<T: bytemuck::Pod>(
    ctx: &GpuContext,
    scene: &GpuScene,
    kernel: &Kernel,
    base: GpuFrame,
    sink: &mut dyn FnMut(TileRect, &[T]),
    progress: &dyn Fn(usize),
) -> Result<(), GpuError> {
    let (w, h, spp) = (base.width, base.height, base.spp);
    let side = ctx.tile();
    let tiles: Vec<(u32, u32)> = (0..h)
        .step_by(side as usize)
        .flat_map(|ty| (0..w).step_by(side as usize).map(move |tx| (tx, ty)))
        .collect();
    let passes = tiles.len() as u64 * spp as u64;
    let mut done = 0u64;
    let mut bufs = ctx.busy.lock().unwrap_or_else(|e| e.into_inner());
    let TileBuffers {
        outputs,
        readback,
        work,
    } = &mut *bufs;
    let largest_tile = (w.min(side) * h.min(side)) as u64;
    let largest = largest_tile * std::mem::size_of::<T>() as u64;
    let encoder = |label| {
        ctx.device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) })
    };
    let mut timer = ctx
        .timer
        .as_ref()
        .map(|t| t.lock().unwrap_or_else(|e| e.into_inner()));
    for &(tx, ty) in &tiles {
        let (tw, th) = ((w - tx).min(side), (h - ty).min(side));
        let bytes = (tw * th) as u64 * std::mem::size_of::<T>() as u64;
        let output = ctx.output(outputs, kernel.output, largest)?;
        let paths = match kernel.paths {
            true => Some(ctx.work(work, largest_tile * PATH_RECORD_BYTES)?),
            false => None,
        };
        let mut clear = encoder("clear tile");
        clear.clear_buffer(&output.buffer, 0, Some(bytes));
        ctx.queue.submit([clear.finish()]);
        for sample in 0..spp {
            let frame = GpuFrame {
                tile_origin: [tx, ty],
                tile_size: [tw, th],
                sample_index: sample,
                ..base
            };
            ctx.queue
                .write_buffer(&ctx.frame_buffer, 0, bytemuck::bytes_of(&frame));
            let mut enc = encoder(kernel.label);
            {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some(kernel.label),
                    timestamp_writes: timer.as_mut().map(|t| t.pass_writes()),
                });
                pass.set_bind_group(0, &scene.group, &[]);
                pass.set_bind_group(1, &output.group, &[]);
                let groups = kernel.groups.iter().copied();
                for (i, g) in groups.chain(paths.map(|p| &p.group)).enumerate() {
                    pass.set_bind_group(i as u32 + 2, g, &[]);
                }
                let last = sample + 1 == spp;
                let finish = kernel.finish.iter().filter(|_| last);
                for stage in kernel.stages.iter().chain(finish) {
                    pass.set_pipeline(stage.pipeline);
                    pass.dispatch_workgroups(
                        tw.div_ceil(WORKGROUP * stage.across),
                        th.div_ceil(WORKGROUP) * stage.layers,
                        1,
                    );
                }
            }
            ctx.queue.submit([enc.finish()]);
            ctx.wait()?;
            if let Some(t) = timer.as_mut() {
                t.flush_if_full(ctx)?;
            }
            done += 1;
            progress((done * h as u64 / passes) as usize);
        }
        ctx.read_back(
            readback,
            encoder("read-back"),
            &output.buffer,
            bytes,
            |data| {
                let rect = TileRect {
                    x: tx,
                    y: ty,
                    width: tw,
                    height: th,
                    frame_width: w,
                };
                sink(rect, bytemuck::cast_slice(data))
            },
        )?;
    }
    Ok(())
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
    render_aovs_walked(ctx, ctx.aov_walk(), scene, cam, s, opts, progress)
}

/// `render_aovs` with the BVH walk `walk` instead of the context's (`GpuContext::aov_walk`).
pub fn render_aovs_walked(
    ctx: &GpuContext,
    walk: AovWalk,
    scene: &GpuScene,
    cam: &Camera,
    s: &RenderSettings,
    opts: &PdmOptions,
    progress: &dyn Fn(usize),
) -> Result<AovImage, GpuError> {
    check_render(s, opts)?;
    let kernel = Kernel {
        stages: &[Stage {
            pipeline: ctx.aov_kernel(walk)?,
            layers: 1,
            across: 1,
        }],
        finish: &[],
        output: Output::Aov,
        groups: &[&scene.cut_group],
        paths: false,
        label: "render_aovs",
    };
    let blank = || AovImage {
        rays: s.width as u64 * s.height as u64 * s.spp as u64,
        ..AovImage::blank(s.width, s.height)
    };
    let frame = FrameJob {
        ctx,
        scene,
        kernel: &kernel,
        base: frame_uniform(cam, s, opts),
    };
    frame.render(blank, resolve_tile, progress)
}

/// One frame of a kernel, for `render`.
pub(crate) struct FrameJob<'a> {
    pub ctx: &'a GpuContext,
    pub scene: &'a GpuScene,
    pub kernel: &'a Kernel<'a>,
    pub base: GpuFrame,
}

impl FrameJob<'_> {
    /// Render the frame into the image `blank` makes, each tile resolved into it by `resolve`
    /// (image, tile rectangle, the tile's sums, spp), again from a new blank in smaller tiles
    /// while the GPU runs out of memory (`GpuContext::with_tile_fallback`). A retried frame's
    /// rows are reported only once they pass what the failed attempt had reported, so a
    /// progress bar holds still instead of running backwards.
    pub fn render<T: bytemuck::Pod, I>(
        &self,
        blank: impl Fn() -> I,
        resolve: fn(&mut I, TileRect, &[T], u32),
        progress: &dyn Fn(usize),
    ) -> Result<I, GpuError> {
        let spp = self.base.spp;
        let progress = forward_only(progress);
        let progress = &progress;
        self.ctx.with_tile_fallback(|| {
            let mut image = blank();
            render_samples(
                self.ctx,
                self.scene,
                self.kernel,
                self.base,
                &mut |rect, tile| resolve(&mut image, rect, tile, spp),
                progress,
            )?;
            Ok(image)
        })
    }
}

/// `progress`, called only with counts above every count it was called with before.
fn forward_only(progress: &dyn Fn(usize)) -> impl Fn(usize) + '_ {
    let shown = std::cell::Cell::new(None);
    move |done| {
        if shown.get().is_none_or(|s| done > s) {
            shown.set(Some(done));
            progress(done);
        }
    }
}

/// Where a tile lies in its frame (pixels), for the sink of `render_samples`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TileRect {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
    pub frame_width: u32,
}

impl TileRect {
    /// The tile's part of a frame row (`frame_width` long).
    pub fn span<'r, P>(&self, row: &'r mut [P]) -> &'r mut [P] {
        &mut row[self.x as usize..][..self.width as usize]
    }

    /// The tile's rows of a frame channel (row-major, `frame_width` per row), in parallel,
    /// whole: index them with `span`. Zip with `tile_rows` of the tile.
    pub fn frame_rows<'f, P: Send>(
        &self,
        frame: &'f mut [P],
    ) -> impl IndexedParallelIterator<Item = &'f mut [P]> {
        frame
            .par_chunks_mut(self.frame_width as usize)
            .skip(self.y as usize)
            .take(self.height as usize)
    }

    /// The tile's own rows, in parallel.
    pub fn tile_rows<'t, T: Sync>(
        &self,
        tile: &'t [T],
    ) -> impl IndexedParallelIterator<Item = &'t [T]> {
        tile.par_chunks(self.width as usize)
    }
}

/// Resolve a tile of the kernel's sums into `image` exactly as the CPU resolves its own (mean
/// depth and uv over hits, normalised normal sum, hits / spp, steps / spp), on all cores, in
/// one pass over the mapped read-back: at 2048² this is 4 M pixels, an order of magnitude more
/// host time than a real GPU's kernel.
fn resolve_tile(image: &mut AovImage, rect: TileRect, tile: &[GpuAovPixel], spp: u32) {
    let spp = spp as f32;
    let channels = (
        rect.frame_rows(&mut image.depth),
        rect.frame_rows(&mut image.normal),
        rect.frame_rows(&mut image.mask),
        rect.frame_rows(&mut image.uv),
        rect.frame_rows(&mut image.steps),
        rect.frame_rows(&mut image.prism),
    );
    let steps: u64 = channels
        .into_par_iter()
        .zip(rect.tile_rows(tile))
        .map(|((depth, normal, mask, uv, steps, prism), src)| {
            let rows = (rect.span(depth).iter_mut())
                .zip(rect.span(normal))
                .zip(rect.span(mask))
                .zip(rect.span(uv))
                .zip(rect.span(steps))
                .zip(rect.span(prism));
            let mut total = 0u64;
            for ((((((d, n), m), u), st), pr), p) in rows.zip(src) {
                let hits = p.hits.max(1.0);
                *d = if p.hits > 0.0 {
                    p.depth_sum / hits
                } else {
                    0.0
                };
                *n = Vec3::from_array(p.normal_sum).normalize_or_zero();
                *m = p.hits / spp;
                *u = Vec2::from_array(p.uv_sum) / hits;
                *st = p.steps_sum / spp;
                *pr = p.prism as f32;
                total += p.steps_sum as u64;
            }
            total
        })
        .sum();
    image.total_steps += steps;
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

#[cfg(test)]
mod tests {
    use std::cell::RefCell;

    #[test]
    fn a_retried_frame_does_not_move_the_progress_back() {
        let seen = RefCell::new(Vec::new());
        let record = |done| seen.borrow_mut().push(done);
        let progress = super::forward_only(&record);
        // An attempt reaches row 6 and runs out of memory; the retry starts over at 0.
        for done in [0, 3, 6, 0, 2, 6, 7, 9] {
            progress(done);
        }
        assert_eq!(*seen.borrow(), [0, 3, 6, 7, 9]);
    }
}
