//! A lookdev job on the GPU: the CPU's own `lookdev::open` (validation, loading through the
//! prism-table cache, camera, environment) and `lookdev::render_all` (frames, turntables,
//! files, contact sheets), with `GpuFrames` rendering each frame.

use crate::beauty::{alpha_records, check_lighting_fits, render_beauty, GpuBeautyScene};
use crate::context::GpuContext;
use crate::render::render_aovs;
use crate::scene::GpuScene;
use crate::GpuError;
use prismbake::render::beauty::{BeautyImage, BeautyScene};
use prismbake::render::camera::Camera;
use prismbake::render::job::{Method, RenderJob};
use prismbake::render::lookdev::{
    self, FrameRenderer, LookdevOptions, LookdevSummary, Session, WatchEvent,
};
use prismbake::render::{Aov, AovImage, RenderSettings};
use prismbake::trace::pdm::PdmOptions;
use prismbake::{Error, Result};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

/// Frames of one job on one adapter: the uploaded scene, the PDM options, and the lighting
/// (uploaded with the first beauty frame, its environment kept for the following frames).
pub struct GpuFrames<'a> {
    ctx: &'a GpuContext,
    scene: &'a GpuScene,
    opts: PdmOptions,
    /// `--env`, for error messages about the environment.
    env_path: Option<PathBuf>,
    lighting: Mutex<Option<GpuBeautyScene>>,
}

impl<'a> GpuFrames<'a> {
    /// Frames of `scene`, with `lighting` uploaded before if any (a `watch`'s earlier render of
    /// the same session): kept where it serves the frames' `BeautyScene`, so that its
    /// environment and textures are not uploaded again.
    pub fn new(
        ctx: &'a GpuContext,
        scene: &'a GpuScene,
        opts: PdmOptions,
        env_path: Option<PathBuf>,
        lighting: Option<GpuBeautyScene>,
    ) -> Self {
        GpuFrames {
            ctx,
            scene,
            opts,
            env_path,
            lighting: Mutex::new(lighting),
        }
    }

    /// The lighting the frames uploaded (or were given), for the next render of the session.
    pub fn into_lighting(self) -> Option<GpuBeautyScene> {
        self.lighting
            .into_inner()
            .unwrap_or_else(|e| e.into_inner())
    }
}

impl FrameRenderer for GpuFrames<'_> {
    fn device(&self) -> String {
        format!("gpu ({})", self.ctx.adapter_description())
    }

    fn memory_bytes(&self) -> usize {
        self.scene.method_bytes() as usize
    }

    fn render_aovs(
        &self,
        cam: &Camera,
        settings: &RenderSettings,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Result<AovImage> {
        render_aovs(self.ctx, self.scene, cam, settings, &self.opts, &|r| {
            progress(r)
        })
        .map_err(gpu_err)
    }

    fn render_beauty(
        &self,
        cam: &Camera,
        settings: &RenderSettings,
        scene: &BeautyScene,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Result<BeautyImage> {
        let mut lighting = self.lighting.lock().unwrap_or_else(|e| e.into_inner());
        match lighting.as_ref() {
            Some(l) if l.serves(scene) => l.update(self.ctx, scene),
            _ => {
                let l =
                    GpuBeautyScene::upload(self.ctx, scene).map_err(|e| match &self.env_path {
                        Some(p) => Error::invalid(p, format!("gpu: {e}")),
                        None => gpu_err(e),
                    })?;
                *lighting = Some(l);
            }
        }
        let l = lighting.as_ref().expect("uploaded above");
        render_beauty(self.ctx, self.scene, l, cam, settings, &self.opts, &|r| {
            progress(r)
        })
        .map_err(gpu_err)
    }

    fn take_device_seconds(&self) -> Option<f64> {
        // A failed read of the timestamps loses the figure, not the frame.
        self.ctx.take_kernel_seconds().ok().flatten()
    }
}

/// Run a lookdev job (AOVs and/or beauty, stills or turntables) on `ctx`'s adapter;
/// `progress(frame_index, rows_done)` reports progress. The same outputs as
/// `lookdev::run` on the CPU, up to float rounding. A scene the adapter cannot hold is an
/// error (`GpuError::TooLarge`, `OutOfMemory`).
pub fn run(
    ctx: &GpuContext,
    job: &RenderJob,
    look: &LookdevOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<LookdevSummary> {
    run_on(ctx, job, look, progress, false)
}

/// `run`, except that a scene the adapter cannot hold (`GpuError::is_capacity`), or a beauty
/// it cannot run (too few storage buffers per shader stage, or a kernel its driver rejects),
/// all found before the first frame and so before any file is written, is rendered by the CPU
/// renderer from the same loaded session. The context's warning sink hears why, and the
/// summary keeps it (`gpu_fallback`). What `--device auto` does.
pub fn run_or_cpu(
    ctx: &GpuContext,
    job: &RenderJob,
    look: &LookdevOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<LookdevSummary> {
    run_on(ctx, job, look, progress, true)
}

fn run_on(
    ctx: &GpuContext,
    job: &RenderJob,
    look: &LookdevOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
    cpu_fallback: bool,
) -> Result<LookdevSummary> {
    check_method(job)?;
    let session = lookdev::open(job, look)?;
    let mut kept = Uploaded::default();
    render_session(ctx, job, look, &session, &mut kept, progress, cpu_fallback)
}

/// What a session keeps on the device between its renders (`watch`): the scene, and the
/// lighting a beauty uploaded.
#[derive(Default)]
struct Uploaded {
    scene: Option<GpuScene>,
    lighting: Option<GpuBeautyScene>,
}

/// Run a job as `run` (`run_or_cpu` with `cpu_fallback`, and once the CPU took over it keeps
/// the session), then re-render it whenever its height map file changes
/// (`lookdev::watch_with`). A change the re-bake answered without rebuilding
/// the BVH rewrites only the prism records, the stitch records and the map on the device
/// (`GpuScene::update_map`); the vertices, the BVH and the compiled kernels stay.
pub fn watch(
    ctx: &GpuContext,
    job: &RenderJob,
    look: &LookdevOptions,
    max_rerenders: Option<u32>,
    log: &dyn Fn(&str),
    on_event: &dyn Fn(&WatchEvent, &LookdevSummary),
    cpu_fallback: bool,
) -> Result<LookdevSummary> {
    check_method(job)?;
    let mut kept = Uploaded::default();
    // Why the CPU took over (`cpu_fallback`): the rest of the session stays there rather than
    // try the same upload again at every change.
    let mut on_cpu: Option<String> = None;
    lookdev::watch_with(
        job,
        look,
        max_rerenders,
        log,
        on_event,
        &mut |session, change| {
            if let Some(why) = &on_cpu {
                return render_on_cpu(job, look, session, &|_, _| {}, why.clone());
            }
            if let (Some(s), Some(bvh_kept)) =
                (kept.scene.as_mut(), change.map(|c| !c.bvh_rebuild_needed))
            {
                if bvh_kept && s.update_map(ctx, session.scene()) {
                    log("gpu: prisms, stitches and map rewritten in place (vertices, BVH and kernels kept)");
                } else {
                    log("gpu: scene uploaded anew");
                    kept.scene = None;
                }
            }
            let summary =
                render_session(ctx, job, look, session, &mut kept, &|_, _| {}, cpu_fallback)?;
            on_cpu.clone_from(&summary.render.gpu_fallback);
            Ok(summary)
        },
    )
}

fn check_method(job: &RenderJob) -> Result<()> {
    if job.method.method != Method::Pdm {
        return Err(Error::Param(
            format!(
                "--method {:?}: the GPU renderer traces pdm only; use --device cpu for this method",
                job.method.method
            )
            .to_lowercase(),
        ));
    }
    Ok(())
}

/// Render every frame of a loaded session on `ctx`, uploading its scene first unless `kept`
/// holds it already (and keeping the scene and the lighting there for the next render). With
/// `cpu_fallback`, a scene the adapter cannot hold, or a beauty it cannot run, is rendered by
/// the CPU renderer instead (`run_or_cpu`).
fn render_session(
    ctx: &GpuContext,
    job: &RenderJob,
    look: &LookdevOptions,
    session: &Session,
    kept: &mut Uploaded,
    progress: &(dyn Fn(usize, usize) + Sync),
    cpu_fallback: bool,
) -> Result<LookdevSummary> {
    let t = Instant::now();
    let want_beauty = job.aovs.contains(&Aov::Beauty);
    let scene = &mut kept.scene;
    // A failure names the environment's file where the lighting is what does not fit.
    let uploaded = match scene.take() {
        Some(s) => Ok(s),
        None => GpuScene::upload(ctx, session.scene()).map_err(|e| (e, None)),
    }
    .and_then(|scene| {
        if want_beauty {
            ctx.check_beauty().map_err(|e| (e, None))?;
            // Lighting kept from an earlier render of the session fits: its environment and
            // textures are the session's, unchanged.
            if kept.lighting.is_none() {
                check_lighting_fits(ctx, session.env(), session.textures())
                    .map_err(|e| (e, look.env.as_deref()))?;
            }
            // Compiled before the first frame too: a kernel the driver rejects is found here.
            ctx.prepare_beauty().map_err(|e| (e, None))?;
        }
        Ok(scene)
    });
    let uploaded = match uploaded {
        Ok(uploaded) => {
            let uploaded = scene.insert(uploaded);
            // The materials' alpha for the AOV kernels' traversal (the beauty's lighting
            // carries its own), or one opaque material where none cuts.
            let (records, texels) = match session.cuts_out() {
                true => alpha_records(&session.alpha_cuts(), session.textures(), session.epsilon()),
                false => (vec![Default::default()], vec![0.0]),
            };
            uploaded.cut_out(ctx, &records, &texels).map_err(gpu_err)?;
            uploaded
        }
        // Before the first frame only the beauty's storage-buffer check says `Unsupported`,
        // and only its kernel's compilation `Shader` (a driver that rejects it).
        Err((e, _))
            if cpu_fallback
                && (e.is_capacity()
                    || matches!(e, GpuError::Unsupported(_) | GpuError::Shader(_))) =>
        {
            let what = match e.is_capacity() {
                true => "cannot hold this scene",
                false => "cannot render this job",
            };
            ctx.warn(&format!(
                "device: cpu ({} {what}: {e}); --device gpu makes this an error",
                ctx.adapter_name()
            ));
            // The upload tried counts as set-up, as the GPU's own does.
            let tried = t.elapsed().as_secs_f64();
            let mut summary = render_on_cpu(job, look, session, progress, e.to_string())?;
            summary.render.setup_seconds += tried;
            return Ok(summary);
        }
        Err((e, Some(env))) => return Err(Error::invalid(env, format!("gpu: {e}"))),
        Err((e, None)) => return Err(gpu_err(e)),
    };
    // Upload and (for beauty) kernel compilation count as setup, as loading and baking do.
    let upload_seconds = t.elapsed().as_secs_f64();
    let opts = PdmOptions {
        normal_mode: job.method.normal_mode,
        ..job.method.pdm
    };
    let frames = GpuFrames::new(ctx, uploaded, opts, look.env.clone(), kept.lighting.take());
    let rendered = lookdev::render_all(job, look, session, &frames, progress);
    kept.lighting = frames.into_lighting();
    let mut summary = rendered?;
    summary.render.setup_seconds += upload_seconds;
    summary.render.gpu_tile = Some(ctx.tile());
    summary.render.gpu_walk = Some(ctx.aov_walk().name());
    summary.render.gpu_map_encoding = Some(uploaded.map_encoding().name());
    Ok(summary)
}

/// The session rendered by the CPU renderer because the GPU could not take it (`why`, kept in
/// the summary's `gpu_fallback`).
fn render_on_cpu(
    job: &RenderJob,
    look: &LookdevOptions,
    session: &Session,
    progress: &(dyn Fn(usize, usize) + Sync),
    why: String,
) -> Result<LookdevSummary> {
    let mut summary = lookdev::render_all_cpu(job, look, session, progress)?;
    summary.render.gpu_fallback = Some(why);
    Ok(summary)
}

fn gpu_err(e: GpuError) -> Error {
    Error::Param(format!("gpu: {e}"))
}
