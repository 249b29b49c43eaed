//! A render job on the GPU: the counterpart of `prismbake::render::job::run`, sharing its
//! validation, loading, camera, frame list and output writing; only the frame render differs.

use crate::context::GpuContext;
use crate::render::render_aovs;
use crate::scene::GpuScene;
use prismbake::accel::Scene;
use prismbake::render::job::{
    base_camera, load_input, prepare_out_dir, FrameStats, Method, RenderJob, RenderSummary,
};
use prismbake::render::output;
use prismbake::trace::pdm::PdmOptions;
use prismbake::{Error, Result};
use std::time::Instant;

/// Run `job` on `ctx`'s adapter; `progress(frame_index, rows_done)` reports progress.
pub fn run(
    ctx: &GpuContext,
    job: &RenderJob,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<RenderSummary> {
    job.validate()?;
    if job.method.method != Method::Pdm {
        return Err(Error::Param(
            format!(
                "--method {:?}: the GPU renderer traces pdm only; use --device cpu for this method",
                job.method.method
            )
            .to_lowercase(),
        ));
    }
    prepare_out_dir(&job.out_dir)?;
    let t0 = Instant::now();
    let loaded = load_input(&job.input, &job.repair)?;
    let cam0 = base_camera(
        &loaded,
        &job.camera,
        job.settings.width as f32 / job.settings.height as f32,
    );
    let scene = Scene::new(loaded.table, loaded.map);
    let gpu_scene = GpuScene::upload(ctx, &scene).map_err(gpu_err)?;
    let opts = PdmOptions {
        normal_mode: job.method.normal_mode,
        ..job.method.pdm
    };
    let frames: Vec<Option<u32>> = match job.turntable {
        None => vec![None],
        Some(n) => {
            let (a, b) = job.frames.unwrap_or((0, n - 1));
            (a..=b).map(Some).collect()
        }
    };
    let mut summary = RenderSummary {
        method: job.method.method,
        device: format!("gpu ({})", ctx.adapter_description()),
        prisms: scene.table.prisms.len(),
        setup_seconds: t0.elapsed().as_secs_f64(),
        method_memory_bytes: gpu_scene.method_bytes() as usize,
        frames: vec![],
        files: vec![],
    };
    for (i, frame) in frames.iter().enumerate() {
        let cam = match (frame, job.turntable) {
            (Some(f), Some(n)) => cam0.turntable(*f, n),
            _ => cam0,
        };
        let t = Instant::now();
        let img = render_aovs(ctx, &gpu_scene, &cam, &job.settings, &opts, &|rows| {
            progress(i, rows)
        })
        .map_err(gpu_err)?;
        let seconds = t.elapsed().as_secs_f64();
        summary
            .files
            .extend(output::write_frame(&job.out_dir, &img, &job.aovs, *frame)?);
        summary.frames.push(FrameStats {
            frame: *frame,
            seconds,
            rays: img.rays,
            mrays_per_s: img.rays as f64 / seconds / 1e6,
            steps_per_ray: img.total_steps as f64 / img.rays.max(1) as f64,
            coverage: img.mask.iter().map(|&m| m as f64).sum::<f64>() / img.mask.len() as f64,
        });
    }
    Ok(summary)
}

fn gpu_err(e: crate::GpuError) -> Error {
    Error::Param(format!("gpu: {e}"))
}
