//! One function per command: build the core config from the flags, call core, print.

use crate::args::{
    BakeArgs, BenchArgs, Cli, Command, DenoiseArg, Device, DispArgs, ExportArgs, InspectArgs,
    NormalArg, RenderArgs, RepairArgs, ReportFormat, ValidateArgs,
};
use crate::progress;
use glam::Vec3;
use prismbake::asset::{self, AssetSpec, Overrides};
use prismbake::bench::BenchConfig;
use prismbake::render::denoise::Quality;
use prismbake::render::job::{
    self as render_job, check_reference_density, CameraOverride, Input, Method, MethodConfig,
    RenderJob, TurntableMode,
};
use prismbake::render::lookdev::{self, CacheUse, LookdevOptions, LookdevSummary, WatchEvent};
use prismbake::render::{Aov, RenderSettings};
use prismbake::repair::RepairOptions;
use prismbake::seam::SeamMode;
use prismbake::trace::nonlinear::NonlinearOptions;
use prismbake::trace::pdm::{Construction, PdmOptions, StepSize};
use prismbake::trace::rmip::RmipOptions;
use prismbake::trace::NormalMode;
use prismbake::{prism_file, report, validate, Error, Result};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

pub fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        Command::Inspect(a) => inspect(a),
        Command::Bake(a) => bake(a),
        Command::Validate(a) => validate(a),
        Command::Render(a) => render(*a),
        Command::Export(a) => export(a),
        Command::Bench(a) => bench(a),
    }
}

pub fn overrides(d: &DispArgs, max_disp: Option<f32>) -> Overrides {
    Overrides {
        disp: d.disp.clone(),
        scale: d.scale,
        midlevel: d.midlevel,
        wrap: d.wrap,
        channel: d.channel.clone(),
        uv_set: d.uv_set,
        max_disp,
        max_seam_jump: None,
    }
}

pub fn repair_options(r: &RepairArgs) -> Result<RepairOptions> {
    let mut o = RepairOptions::default();
    if let Some(t) = r.crease_threshold {
        if !(0.0..1.0).contains(&t) {
            return Err(Error::Param(format!(
                "--crease-threshold {t} must be in [0, 1) (a dot product of unit vectors)"
            )));
        }
        o.crease_threshold = t;
    }
    Ok(o)
}

fn print_or_write(text: &str, out: Option<&Path>) -> Result<()> {
    match out {
        Some(p) => prism_file::write_atomic(p, text.as_bytes()),
        None => {
            print!("{text}");
            Ok(())
        }
    }
}

fn inspect(a: InspectArgs) -> Result<ExitCode> {
    if prismbake::load::extension(&a.mesh) == "prisms" {
        let table = prism_file::read(&a.mesh)?;
        let summary = validate::table_summary(&table, &a.mesh, true);
        let v = serde_json::to_value(&summary).expect("serialises");
        if a.json {
            println!("{}", serde_json::to_string_pretty(&v).expect("serialises"));
        } else {
            for (k, val) in v.as_object().expect("object") {
                println!("{k:18} {val}");
            }
        }
        return Ok(ExitCode::SUCCESS);
    }
    let spec = asset::resolve(&a.mesh, &overrides(&a.disp, None))?;
    let info = validate::inspect(&spec, &repair_options(&a.repair)?)?;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&info).expect("serialises")
        );
    } else {
        print!("{}", info.to_text());
    }
    Ok(ExitCode::SUCCESS)
}

fn bake(a: BakeArgs) -> Result<ExitCode> {
    let spec: AssetSpec = asset::resolve(&a.mesh, &overrides(&a.disp, None))?;
    let ropts = repair_options(&a.repair)?;
    spec.require_disp()?;
    let hash = asset::input_hash(&spec, &ropts)?;
    if !a.force && a.output.is_file() && prism_file::read_input_hash(&a.output) == Some(hash) {
        let table = prism_file::read(&a.output)?;
        let summary = validate::table_summary(&table, &a.output, true);
        if a.json {
            println!(
                "{}",
                serde_json::to_string_pretty(&summary).expect("serialises")
            );
        } else {
            eprintln!("{}: up to date (same inputs), reused", a.output.display());
        }
        return Ok(ExitCode::SUCCESS);
    }
    let pb = progress::spinner("baking");
    let mut prepared = asset::prepare(&spec, &ropts)?;
    pb.finish_and_clear();
    prepared.table.map_path = asset::path_for_table(spec.require_disp()?, &a.output);
    prepared.table.source.mesh_path = asset::path_for_table(&spec.mesh, &a.output);
    // The table's folder is made when there is a table to put in it.
    if let Some(dir) = a.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    prism_file::write(&a.output, &prepared.table)?;
    let summary = validate::table_summary(&prepared.table, &a.output, false);
    if a.json {
        let mut v = serde_json::to_value(&summary).expect("serialises");
        v["repair"] = serde_json::to_value(&prepared.report).expect("serialises");
        println!("{}", serde_json::to_string_pretty(&v).expect("serialises"));
    } else {
        if !prepared.report.is_clean() {
            eprint!("{}", prepared.report.to_text());
        }
        eprintln!(
            "{}: {} prisms ({} flat), {} bytes ({:.1} bytes/prism)",
            a.output.display(),
            summary.prisms,
            summary.flat_prisms,
            summary.bytes,
            summary.bytes_per_prism
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn validate(a: ValidateArgs) -> Result<ExitCode> {
    let ropts = repair_options(&a.repair)?;
    let meshes = asset::expand_paths(&a.paths)?;
    if meshes.is_empty() {
        return Err(Error::Param(format!(
            "no mesh files (.gltf, .glb, .obj) found under {}",
            a.paths
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let pb = progress::bar(meshes.len() as u64, "validating");
    if let Some(j) = a.max_seam_jump {
        if !(j.is_finite() && j >= 0.0) {
            return Err(Error::Param(format!(
                "--max-seam-jump {j}: give a fraction of |scale| ≥ 0 (e.g. 0.02)"
            )));
        }
    }
    let flags = Overrides {
        max_seam_jump: a.max_seam_jump,
        ..overrides(&a.disp, a.max_disp)
    };
    let reports: Vec<report::AssetReport> = meshes
        .iter()
        .map(|m| {
            let r = validate::validate_asset(m, &flags, &ropts);
            pb.inc(1);
            r
        })
        .collect();
    pb.finish_and_clear();
    let text = match a.format {
        ReportFormat::Text => report::to_text(&reports),
        ReportFormat::Json => report::to_json(&reports),
        ReportFormat::Junit => report::to_junit(&reports),
    };
    print_or_write(&text, a.output.as_deref())?;
    Ok(if reports.iter().any(|r| r.failed()) {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

fn parse_dt(s: &str) -> Result<StepSize> {
    let bad = || {
        Error::Param(format!(
            "--dt {s}: expected auto, auto:F (F texels) or a positive world length"
        ))
    };
    let dt = if s == "auto" {
        StepSize::default()
    } else if let Some(f) = s.strip_prefix("auto:") {
        StepSize::Auto(f.parse().map_err(|_| bad())?)
    } else {
        StepSize::World(s.parse().map_err(|_| bad())?)
    };
    match dt {
        StepSize::Auto(v) | StepSize::World(v) if v > 0.0 && v.is_finite() => Ok(dt),
        _ => Err(bad()),
    }
}

fn render(a: RenderArgs) -> Result<ExitCode> {
    let method: Method = a.method.parse().map_err(Error::Param)?;
    let aovs = a
        .aov
        .iter()
        .map(|s| s.parse::<Aov>())
        .collect::<std::result::Result<Vec<_>, _>>()
        .map_err(Error::Param)?;
    // The GPU renders PDM (AOVs and beauty, stills, turntables, --watch); the other methods run
    // on the CPU (`auto` falls back to it, `gpu` says so).
    let gpu_able = method == Method::Pdm;
    // `auto` also renders on the CPU a scene the GPU cannot hold.
    let auto = a.device == Device::Auto;
    let gpu = match a.device {
        Device::Cpu => None,
        Device::Gpu if !gpu_able => {
            return Err(Error::Param(
                "--device gpu traces --method pdm; use --device cpu for the other methods".into(),
            ));
        }
        Device::Gpu => Some(
            prismbake_gpu::GpuContext::new()
                .map_err(|e| Error::Param(format!("--device gpu: {e}")))?,
        ),
        Device::Auto if !gpu_able => {
            eprintln!("device: cpu (this render needs the CPU renderer)");
            None
        }
        Device::Auto => prismbake_gpu::GpuContext::new()
            .map_err(|e| eprintln!("device: cpu ({e})"))
            .ok(),
    };
    if let Some(ctx) = &gpu {
        let walk = match aovs.iter().any(|a| *a != Aov::Beauty) {
            true => format!(", AOV walk {}", ctx.aov_walk().name()),
            false => String::new(),
        };
        let schedule = match (aovs.contains(&Aov::Beauty), ctx.beauty_schedule()) {
            (false, _) => String::new(),
            (true, s @ prismbake_gpu::BeautySchedule::Wavefront) => format!(
                ", beauty schedule {} ({} pixel(s) per trace invocation)",
                s.name(),
                ctx.trace_pixels()
            ),
            (true, s) => format!(", beauty schedule {}", s.name()),
        };
        eprintln!(
            "device: gpu ({}){walk}{schedule}",
            ctx.adapter_description()
        );
        if ctx.is_software() {
            eprintln!(
                "note: {} is a software adapter (its kernels run on this machine's CPU); --device cpu renders the same images faster here (1.4-4.3x on the example assets on the machines measured, docs/gpu.md)",
                ctx.adapter_name()
            );
        }
    }
    let look = lookdev_options(&a)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.unwrap_or(0))
        .build()
        .map_err(|e| Error::Param(format!("--threads: {e}")))?;
    if a.input.is_dir() {
        return render_batch(&a, method, &aovs, &look, &pool, gpu.as_ref(), auto);
    }
    let input = if prismbake::load::extension(&a.input) == "prisms" {
        Input::Table {
            path: a.input.clone(),
            disp: a.disp.disp.clone(),
            channel: a.disp.channel.clone(),
        }
    } else {
        Input::Asset(asset::resolve(&a.input, &overrides(&a.disp, None))?)
    };
    let job = render_job_for(&a, method, aovs, input, a.output.clone())?;
    job.validate()?;
    let frames = frame_count(&job);
    let rows = job.settings.height as u64;
    if a.watch {
        let on_event = |ev: &WatchEvent, s: &LookdevSummary| {
            eprintln!(
                "map changed: re-baked {} of {} prisms ({} records updated), BVH {}; re-rendered in {:.0} ms (change detected -> {} files written; re-bake {:.1} ms)",
                ev.rebake.prisms_rebaked, ev.rebake.prisms, ev.rebake.records_updated, ev.bvh, ev.latency_ms, s.render.files.len(), ev.rebake_ms
            );
        };
        let log = |m: &str| eprintln!("{m}");
        let summary = pool.install(|| match &gpu {
            Some(ctx) => {
                prismbake_gpu::job::watch(ctx, &job, &look, a.watch_max, &log, &on_event, auto)
            }
            None => lookdev::watch(&job, &look, a.watch_max, &log, &on_event, &|_, _| {}),
        })?;
        print_render_summary(&a, &summary);
        return Ok(ExitCode::SUCCESS);
    }
    let pb = progress::bar(frames * rows, "rendering");
    warn_between_redraws(gpu.as_ref(), &pb);
    let report = |frame: usize, done: usize| pb.set_position(frame as u64 * rows + done as u64);
    let summary =
        pool.install(|| run_lookdev(gpu.as_ref().map(|g| (g, auto)), &job, &look, &report))?;
    pb.finish_and_clear();
    print_render_summary(&a, &summary);
    Ok(ExitCode::SUCCESS)
}

/// The GPU's warnings (an out-of-memory fallback to smaller tiles) printed between the
/// progress bar's redraws, which would otherwise draw over them.
fn warn_between_redraws(gpu: Option<&prismbake_gpu::GpuContext>, pb: &indicatif::ProgressBar) {
    if let Some(ctx) = gpu {
        let pb = pb.clone();
        ctx.set_warning_sink(move |w| pb.suspend(|| eprintln!("{w}")));
    }
}

/// One lookdev job on the GPU if there is a context, else on the CPU; with `auto` (the
/// context's `bool`), on the CPU too where the GPU cannot hold the scene.
fn run_lookdev(
    gpu: Option<(&prismbake_gpu::GpuContext, bool)>,
    job: &RenderJob,
    look: &LookdevOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<LookdevSummary> {
    match gpu {
        Some((ctx, false)) => prismbake_gpu::job::run(ctx, job, look, progress),
        Some((ctx, true)) => prismbake_gpu::job::run_or_cpu(ctx, job, look, progress),
        None => lookdev::run(job, look, progress),
    }
}

fn lookdev_options(a: &RenderArgs) -> Result<LookdevOptions> {
    let l = &a.look;
    let opts = LookdevOptions {
        env: l.env.clone(),
        env_rotate_deg: l.env_rotate,
        env_intensity: l.env_intensity,
        key_light: l.key_light,
        key_angle_deg: l.key_angle,
        key_color: l.key_color.map(Vec3::from),
        base_color: l.base_color.map(Vec3::from),
        roughness: l.roughness,
        metallic: l.metallic,
        normal_maps: !l.no_normal_maps,
        emission: !l.no_emission,
        alpha: !l.no_alpha,
        scene_lights: !l.no_scene_lights,
        specular: l.specular,
        specular_tint: l.specular_tint.map(Vec3::from),
        clearcoat: l.clearcoat,
        clearcoat_roughness: l.clearcoat_roughness,
        bounces: l.bounces,
        ground: l.ground,
        exposure_ev: l.exposure,
        denoise: l.denoise.map(|d| match d {
            DenoiseArg::High => Quality::High,
            DenoiseArg::Balanced => Quality::Balanced,
            DenoiseArg::Fast => Quality::Fast,
        }),
        cache_dir: if a.no_cache {
            None
        } else {
            prismbake::table_cache::default_dir()
        },
    };
    opts.validate()?;
    Ok(opts)
}

fn render_job_for(
    a: &RenderArgs,
    method: Method,
    aovs: Vec<Aov>,
    input: Input,
    out_dir: PathBuf,
) -> Result<RenderJob> {
    let normal_mode = match a.normal {
        NormalArg::Smooth => NormalMode::Smooth,
        NormalArg::Geometric => NormalMode::Geometric,
    };
    Ok(RenderJob {
        input,
        method: MethodConfig {
            method,
            normal_mode,
            pdm: PdmOptions {
                dt: parse_dt(&a.dt)?,
                jitter: !a.no_jitter,
                ..PdmOptions::default()
            },
            nonlinear: NonlinearOptions {
                precision: a.precision.parse().map_err(Error::Param)?,
                ..NonlinearOptions::default()
            },
            ref_density: a.ref_density,
            ref_memory: ref_memory(a.ref_memory)?,
            rmip: RmipOptions {
                marching_scale: a.marching_scale,
                resolution: a.rmip_res,
                ..RmipOptions::default()
            },
            seams: a.seams.parse().map_err(Error::Param)?,
        },
        settings: RenderSettings {
            width: a.res.0,
            height: a.res.1,
            spp: a.spp,
            seed: a.seed,
        },
        aovs,
        turntable: a.turntable,
        turntable_mode: match (&a.turntable_mode, a.turntable) {
            (None, _) => TurntableMode::default(),
            (Some(m), Some(_)) => m.parse().map_err(Error::Param)?,
            (Some(m), None) => {
                return Err(Error::Param(format!(
                    "--turntable-mode {m} needs --turntable N"
                )))
            }
        },
        frames: a.frames,
        camera: CameraOverride {
            name: a.camera.clone(),
            from: a.camera_from.map(Vec3::from),
            to: a.camera_to.map(Vec3::from),
            fov_deg: a.fov,
            ortho: match a.ortho.as_deref() {
                None => None,
                Some("fit") => Some(None),
                Some(h) => Some(Some(h.parse::<f32>().map_err(|_| {
                    Error::Param(format!(
                        "--ortho {h}: give the view's height in scene units, or `fit` to fit \
                         the asset"
                    ))
                })?)),
            },
        },
        out_dir,
        repair: repair_options(&a.repair)?,
    })
}

fn frame_count(job: &RenderJob) -> u64 {
    job.turntable
        .map_or(1, |n| job.frames.map_or(n, |(x, y)| y - x + 1)) as u64
}

fn print_render_summary(a: &RenderArgs, summary: &LookdevSummary) {
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(summary).expect("serialises")
        );
        return;
    }
    match &summary.table_cache {
        CacheUse::Reused(p) => eprintln!("reused cached prism table {}", p.display()),
        CacheUse::Stored(p) => eprintln!(
            "baked {} prisms (cached as {})",
            summary.render.prisms,
            p.display()
        ),
        CacheUse::NotStored(e) => {
            eprintln!("baked {} prisms (not cached: {e})", summary.render.prisms)
        }
        CacheUse::Off => {}
    }
    eprintln!("camera: {}", summary.camera);
    if let Some(env) = &summary.environment {
        eprintln!("environment: {env}");
    }
    if let Some(key) = &summary.key_light {
        eprintln!("key light: {key}");
    }
    for l in &summary.lights {
        eprintln!("light: {l}");
    }
    for f in &summary.render.frames {
        eprintln!(
            "{}frame: {:.3} s (trace {:.3} s{}, {}files {:.3} s), {:.2} Mrays/s, {:.1} steps/ray, coverage {:.1}%",
            f.frame.map(|i| format!("[{i:04}] ")).unwrap_or_default(),
            f.seconds,
            f.trace_seconds,
            f.device_seconds
                .map(|d| format!(" of which kernels {d:.4} s"))
                .unwrap_or_default(),
            f.denoise_seconds
                .map(|d| format!("denoise {d:.3} s, "))
                .unwrap_or_default(),
            f.write_seconds,
            f.mrays_per_s,
            f.steps_per_ray,
            100.0 * f.coverage
        );
    }
    if summary.render.frames.len() > 1 {
        let own: f64 = summary.render.frames.iter().map(|f| f.seconds).sum();
        eprintln!(
            "{} frames in {:.3} s (their own {:.3} s: files are written while the next frame traces)",
            summary.render.frames.len(),
            summary.render.frames_seconds,
            own
        );
    }
    let b = &summary.beauty_rays;
    if b.rays > 0 {
        eprintln!(
            "beauty: {} rays, {} shadow rays ({} key light, {} environment)",
            b.rays, summary.shadow_rays, b.key_shadow_rays, b.env_shadow_rays
        );
    }
    for m in &summary.materials {
        let what = m.material.describe();
        eprintln!("beauty material '{}' ({} prisms): {what}", m.name, m.prisms);
    }
    if let Some(d) = &summary.denoiser {
        eprintln!("beauty denoised with {d}");
    }
    for p in &summary.contact_sheets {
        eprintln!("contact sheet: {}", p.display());
    }
    eprintln!(
        "wrote {} files to {}",
        summary.render.files.len() + summary.contact_sheets.len(),
        a.output.display()
    );
}

/// `render DIR`: every mesh under DIR into OUTPUT/<stem>/, past failures; exit 1 if any failed.
fn render_batch(
    a: &RenderArgs,
    method: Method,
    aovs: &[Aov],
    look: &LookdevOptions,
    pool: &rayon::ThreadPool,
    gpu: Option<&prismbake_gpu::GpuContext>,
    auto: bool,
) -> Result<ExitCode> {
    if a.watch {
        return Err(Error::Param(format!(
            "--watch follows one asset's height map; {} is a folder",
            a.input.display()
        )));
    }
    let meshes = asset::find_meshes(&a.input);
    if meshes.is_empty() {
        return Err(Error::Param(format!(
            "no mesh files (.gltf, .glb, .obj, .usd*) found under {}",
            a.input.display()
        )));
    }
    render_job::prepare_out_dir(&a.output)?;
    let probe = render_job_for(
        a,
        method,
        aovs.to_vec(),
        Input::Table {
            path: PathBuf::new(),
            disp: None,
            channel: None,
        },
        a.output.clone(),
    )?;
    probe.validate()?;
    let frames = frame_count(&probe);
    let pb = progress::bar(meshes.len() as u64 * frames, "rendering");
    warn_between_redraws(gpu, &pb);
    let mut used = std::collections::HashSet::new();
    let mut failures: Vec<(PathBuf, String)> = Vec::new();
    let mut results = Vec::new();
    for (k, mesh) in meshes.iter().enumerate() {
        let base = mesh
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "asset".into());
        let mut stem = base.clone();
        let mut n = 2;
        while !used.insert(stem.clone()) {
            stem = format!("{base}_{n}");
            n += 1;
        }
        pb.set_message(stem.clone());
        let out = a.output.join(&stem);
        let result = asset::resolve(mesh, &overrides(&a.disp, None))
            .and_then(|spec| {
                render_job_for(a, method, aovs.to_vec(), Input::Asset(spec), out.clone())
            })
            .and_then(|job| {
                pool.install(|| {
                    run_lookdev(gpu.map(|g| (g, auto)), &job, look, &|f, _| {
                        pb.set_position(k as u64 * frames + f as u64)
                    })
                })
            });
        pb.set_position((k as u64 + 1) * frames);
        match result {
            Ok(s) => {
                if !a.json {
                    let secs: f64 = s.render.frames.iter().map(|f| f.seconds).sum();
                    pb.suspend(|| {
                        eprintln!(
                            "{}: {} files in {}/ ({secs:.2} s)",
                            mesh.display(),
                            s.render.files.len() + s.contact_sheets.len(),
                            out.display()
                        )
                    });
                }
                results.push(
                    serde_json::json!({"mesh": mesh, "output": out, "ok": true, "summary": s}),
                );
            }
            Err(e) => {
                pb.suspend(|| eprintln!("{}: FAILED: {e}", mesh.display()));
                results.push(serde_json::json!({"mesh": mesh, "output": out, "ok": false, "error": e.to_string()}));
                failures.push((mesh.clone(), e.to_string()));
            }
        }
    }
    pb.finish_and_clear();
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({"assets": results}))
                .expect("serialises")
        );
    }
    eprintln!(
        "rendered {} of {} assets into {}",
        meshes.len() - failures.len(),
        meshes.len(),
        a.output.display()
    );
    if failures.is_empty() {
        return Ok(ExitCode::SUCCESS);
    }
    eprintln!("{} failed:", failures.len());
    for (mesh, e) in &failures {
        eprintln!("  {}: {e}", mesh.display());
    }
    Ok(ExitCode::from(1))
}

/// Every method × its own knob, as (label, config): dt for PDM, marching scale × RMIP
/// resolution for RMIP, f32/f64 for nonlinear; the paper-exact PDM when asked.
fn bench_settings(a: &BenchArgs) -> Result<Vec<(String, MethodConfig)>> {
    let mut settings = Vec::new();
    let with = |method: Method| MethodConfig {
        method,
        ..MethodConfig::default()
    };
    for m in &a.methods {
        let method: Method = m.parse().map_err(Error::Param)?;
        match method {
            Method::Pdm => {
                let variants: &[bool] = if a.pdm_whole { &[true, false] } else { &[true] };
                for &cells in variants {
                    for dt in &a.dt {
                        let pdm = PdmOptions {
                            dt: parse_dt(dt)?,
                            cells,
                            ..PdmOptions::default()
                        };
                        let label = if cells {
                            format!("dt={dt}")
                        } else {
                            format!("whole,dt={dt}")
                        };
                        settings.push((
                            label,
                            MethodConfig {
                                pdm,
                                ..with(method)
                            },
                        ));
                    }
                }
            }
            Method::Rmip => {
                for &ms in &a.marching_scale {
                    if !(ms.is_finite() && ms > 0.0) {
                        return Err(Error::Param(format!(
                            "--marching-scale {ms}: give texels > 0 (e.g. 2,8,32)"
                        )));
                    }
                    for res in &a.rmip_res {
                        let resolution = match res.as_str() {
                            "auto" => None,
                            r => Some(r.parse::<u32>().ok().filter(|&n| n > 0).ok_or_else(|| {
                                Error::Param(format!(
                                    "--rmip-res {r}: give auto or cells along the map's longer side (> 0)"
                                ))
                            })?),
                        };
                        let rmip = RmipOptions {
                            marching_scale: ms,
                            resolution,
                            ..RmipOptions::default()
                        };
                        settings.push((
                            format!("ms={ms},res={res}"),
                            MethodConfig {
                                rmip,
                                ..with(method)
                            },
                        ));
                    }
                }
            }
            Method::Nonlinear => {
                for p in &a.precision {
                    let nonlinear = NonlinearOptions {
                        precision: p
                            .parse()
                            .map_err(|e: String| Error::Param(format!("--precision: {e}")))?,
                        ..NonlinearOptions::default()
                    };
                    settings.push((
                        p.clone(),
                        MethodConfig {
                            nonlinear,
                            ..with(method)
                        },
                    ));
                }
            }
            Method::Reference => settings.push((m.clone(), with(method))),
        }
    }
    if a.paper_pdm {
        let pdm = PdmOptions {
            construction: Construction::ParallelOffset,
            refine: false,
            ..PdmOptions::default()
        };
        settings.push((
            "paper".to_string(),
            MethodConfig {
                pdm,
                ..with(Method::Pdm)
            },
        ));
    }
    Ok(settings)
}

/// `--ref-memory GIB` in bytes (`None`: the default budget).
fn ref_memory(gib: Option<f64>) -> Result<Option<u64>> {
    match gib {
        None => Ok(None),
        Some(g) if g > 0.0 && g <= 1e6 => Ok(Some((g * (1u64 << 30) as f64) as u64)),
        Some(g) => Err(Error::Param(format!(
            "--ref-memory {g}: give the GiB the reference may take to build, in (0, 1e6]"
        ))),
    }
}

fn bench(a: BenchArgs) -> Result<ExitCode> {
    let settings = bench_settings(&a)?;
    let cfg = BenchConfig {
        width: a.res.0,
        height: a.res.1,
        settings,
        ref_density: a.ref_density,
        ref_memory: ref_memory(a.ref_memory)?,
        confirm_density: a.confirm_density,
        secondary_rays: a.secondary,
        leak_rays: a.leak_rays,
        seed: a.seed,
        repeats: a.repeats,
    };
    if cfg.width == 0 || cfg.height == 0 || cfg.width > 8192 || cfg.height > 8192 {
        return Err(Error::Param(format!(
            "--res {}x{}: each side must be 1..=8192",
            cfg.width, cfg.height
        )));
    }
    check_reference_density("--ref-density", cfg.ref_density)?;
    if cfg.confirm_density != 0.0 {
        check_reference_density("--confirm-density", cfg.confirm_density).map_err(|_| {
            Error::Param(format!(
                "--confirm-density {}: must be 0 (no check) or in (0, 64]",
                cfg.confirm_density
            ))
        })?;
    }
    let seam_modes: Vec<SeamMode> = a
        .seams
        .iter()
        .map(|m| {
            m.parse()
                .map_err(|e: String| Error::Param(format!("--seams: {e}")))
        })
        .collect::<Result<_>>()?;
    let meshes = asset::expand_paths(&a.assets)?;
    render_job::prepare_out_dir(&a.output)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.unwrap_or(0))
        .build()
        .map_err(|e| Error::Param(format!("--threads: {e}")))?;
    let mut rows = Vec::new();
    for mesh in &meshes {
        let input = match prismbake::load::extension(mesh).as_str() {
            "prisms" => Input::Table {
                path: mesh.clone(),
                disp: a.disp.disp.clone(),
                channel: a.disp.channel.clone(),
            },
            _ => Input::Asset(asset::resolve(mesh, &overrides(&a.disp, None))?),
        };
        let loaded = render_job::load_input(&input, &RepairOptions::default())?;
        let cam = render_job::base_camera(
            &loaded,
            &CameraOverride::default(),
            cfg.width as f32 / cfg.height as f32,
            1,
        );
        let name = mesh.display().to_string();
        let mut asset_rows = Vec::new();
        for &mode in &seam_modes {
            let scene = prismbake::accel::Scene::new(loaded.table.clone(), loaded.map.clone())
                .with_seam_mode(mode);
            asset_rows.extend(
                pool.install(|| {
                    prismbake::bench::run_bench(&name, &scene, &cam, &cfg, &|m| eprintln!("{m}"))
                })
                .map_err(|e| Error::Param(format!("{name}: {e}")))?,
            );
        }
        let stem = mesh
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        prismbake::bench::plot::write_plot(
            &a.output.join(format!("{stem}.png")),
            &format!("{stem}: time vs depth error"),
            &asset_rows,
        )?;
        rows.extend(asset_rows);
    }
    print!("{}", prismbake::bench::to_table(&rows));
    prism_file::write_atomic(
        &a.output.join("bench.csv"),
        prismbake::bench::to_csv(&rows).as_bytes(),
    )?;
    let json = serde_json::to_string_pretty(&rows).expect("serialises");
    prism_file::write_atomic(&a.output.join("bench.json"), json.as_bytes())?;
    eprintln!(
        "wrote bench.csv, bench.json and plots to {}",
        a.output.display()
    );
    Ok(ExitCode::SUCCESS)
}

fn export(a: ExportArgs) -> Result<ExitCode> {
    if prismbake::load::extension(&a.usd) != "usda" {
        return Err(Error::Param(format!(
            "--usd {}: only .usda (USD text) is written; name the output OUT.usda",
            a.usd.display()
        )));
    }
    let spec = asset::resolve(&a.mesh, &overrides(&a.disp, None))?;
    let pb = progress::spinner("baking");
    let prepared = asset::prepare(&spec, &repair_options(&a.repair)?)?;
    pb.finish_and_clear();
    if !prepared.report.is_clean() {
        eprint!("{}", prepared.report.to_text());
    }
    prismbake::usd_export::write_usda(&prepared, &a.usd)?;
    eprintln!(
        "{}: {} faces, {} points",
        a.usd.display(),
        prepared.table.prisms.len(),
        prepared.table.positions.len()
    );
    Ok(ExitCode::SUCCESS)
}
