//! One function per command: build the core config from the flags, call core, print.

use crate::args::{BakeArgs, ExportArgs, BenchArgs, Cli, Command, Device, DispArgs, InspectArgs, NormalArg, RenderArgs, RepairArgs, ReportFormat, ValidateArgs};
use crate::progress;
use prismbake::asset::{self, AssetSpec, Overrides};
use prismbake::repair::RepairOptions;
use prismbake::{prism_file, report, validate, Error, Result};
use glam::Vec3;
use prismbake::render::job::{self as render_job, CameraOverride, Input, Method, MethodConfig, RenderJob};
use prismbake::render::{Aov, RenderSettings};
use prismbake::bench::BenchConfig;
use prismbake::trace::nonlinear::NonlinearOptions;
use prismbake::trace::pdm::{Construction, PdmOptions, StepSize};
use prismbake::trace::rmip::RmipOptions;
use prismbake::trace::NormalMode;
use std::path::Path;
use std::process::ExitCode;

pub fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        Command::Inspect(a) => inspect(a),
        Command::Bake(a) => bake(a),
        Command::Validate(a) => validate(a),
        Command::Render(a) => render(a),
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
    }
}

pub fn repair_options(r: &RepairArgs) -> Result<RepairOptions> {
    let mut o = RepairOptions::default();
    if let Some(t) = r.crease_threshold {
        if !(0.0..1.0).contains(&t) {
            return Err(Error::Param(format!("--crease-threshold {t} must be in [0, 1) (a dot product of unit vectors)")));
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
        println!("{}", serde_json::to_string_pretty(&info).expect("serialises"));
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
            println!("{}", serde_json::to_string_pretty(&summary).expect("serialises"));
        } else {
            eprintln!("{}: up to date (same inputs), reused", a.output.display());
        }
        return Ok(ExitCode::SUCCESS);
    }
    let pb = progress::spinner("baking");
    let mut prepared = asset::prepare(&spec, &ropts)?;
    pb.finish_and_clear();
    prepared.table.map_path = asset::map_path_for_table(spec.require_disp()?, &a.output);
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
            a.paths.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
        )));
    }
    let pb = progress::bar(meshes.len() as u64, "validating");
    let flags = overrides(&a.disp, a.max_disp);
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
    Ok(if reports.iter().any(|r| r.failed()) { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

fn parse_dt(s: &str) -> Result<StepSize> {
    let bad = || Error::Param(format!("--dt {s}: expected auto, auto:F (F texels) or a positive world length"));
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
    match a.device {
        Device::Gpu => {
            return Err(Error::Param("--device gpu: the GPU renderer is not built yet; use --device cpu".into()));
        }
        Device::Auto => eprintln!("device: cpu (no GPU renderer in this build)"),
        Device::Cpu => {}
    }
    let aovs = a.aov.iter().map(|s| s.parse::<Aov>()).collect::<std::result::Result<Vec<_>, _>>().map_err(Error::Param)?;
    let input = if prismbake::load::extension(&a.input) == "prisms" {
        Input::Table { path: a.input.clone(), disp: a.disp.disp.clone(), channel: a.disp.channel.clone() }
    } else {
        Input::Asset(asset::resolve(&a.input, &overrides(&a.disp, None))?)
    };
    let normal_mode = match a.normal {
        NormalArg::Smooth => NormalMode::Smooth,
        NormalArg::Geometric => NormalMode::Geometric,
    };
    let job = RenderJob {
        input,
        method: MethodConfig {
            method,
            normal_mode,
            pdm: PdmOptions { dt: parse_dt(&a.dt)?, jitter: !a.no_jitter, ..PdmOptions::default() },
            nonlinear: NonlinearOptions { precision: a.precision.parse().map_err(Error::Param)?, ..NonlinearOptions::default() },
            ref_density: a.ref_density,
            rmip: RmipOptions { marching_scale: a.marching_scale, resolution: a.rmip_res, ..RmipOptions::default() },
        },
        settings: RenderSettings { width: a.res.0, height: a.res.1, spp: a.spp, seed: a.seed },
        aovs,
        turntable: a.turntable,
        frames: a.frames,
        camera: CameraOverride {
            from: a.camera_from.map(Vec3::from),
            to: a.camera_to.map(Vec3::from),
            fov_deg: a.fov,
        },
        out_dir: a.output.clone(),
        repair: repair_options(&a.repair)?,
    };
    job.validate()?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.unwrap_or(0))
        .build()
        .map_err(|e| Error::Param(format!("--threads: {e}")))?;
    let frames = job.turntable.map_or(1, |n| job.frames.map_or(n, |(x, y)| y - x + 1));
    let pb = progress::bar(frames as u64 * job.settings.height as u64, "rendering");
    let rows = job.settings.height as u64;
    let summary = pool.install(|| render_job::run(&job, &|frame, done| pb.set_position(frame as u64 * rows + done as u64)))?;
    pb.finish_and_clear();
    if a.json {
        println!("{}", serde_json::to_string_pretty(&summary).expect("serialises"));
    } else {
        for f in &summary.frames {
            eprintln!(
                "{}frame: {:.3} s, {:.2} Mrays/s, {:.1} steps/ray, coverage {:.1}%",
                f.frame.map(|i| format!("[{i:04}] ")).unwrap_or_default(),
                f.seconds,
                f.mrays_per_s,
                f.steps_per_ray,
                100.0 * f.coverage
            );
        }
        eprintln!("wrote {} files to {}", summary.files.len(), a.output.display());
    }
    Ok(ExitCode::SUCCESS)
}

fn bench(a: BenchArgs) -> Result<ExitCode> {
    let mut settings = Vec::new();
    for m in &a.methods {
        let method: Method = m.parse().map_err(Error::Param)?;
        match method {
            Method::Pdm => {
                for dt in &a.dt {
                    let pdm = PdmOptions { dt: parse_dt(dt)?, ..PdmOptions::default() };
                    settings.push((format!("dt={dt}"), MethodConfig { method, pdm, ..MethodConfig::default() }));
                }
            }
            _ => settings.push((m.clone(), MethodConfig { method, ..MethodConfig::default() })),
        }
    }
    if a.paper_pdm {
        let pdm = PdmOptions { construction: Construction::ParallelOffset, refine: false, ..PdmOptions::default() };
        settings.push(("paper".to_string(), MethodConfig { method: Method::Pdm, pdm, ..MethodConfig::default() }));
    }
    let cfg = BenchConfig {
        width: a.res.0,
        height: a.res.1,
        settings,
        ref_density: a.ref_density,
        secondary_rays: a.secondary,
        leak_rays: a.leak_rays,
        seed: a.seed,
        repeats: a.repeats,
    };
    if cfg.width == 0 || cfg.height == 0 || cfg.width > 8192 || cfg.height > 8192 {
        return Err(Error::Param(format!("--res {}x{}: each side must be 1..=8192", cfg.width, cfg.height)));
    }
    let meshes = asset::expand_paths(&a.assets)?;
    render_job::prepare_out_dir(&a.output)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.unwrap_or(0))
        .build()
        .map_err(|e| Error::Param(format!("--threads: {e}")))?;
    let mut rows = Vec::new();
    for mesh in &meshes {
        let spec = asset::resolve(mesh, &overrides(&a.disp, None))?;
        let input = Input::Asset(spec);
        let loaded = render_job::load_input(&input, &RepairOptions::default())?;
        let cam = render_job::base_camera(&loaded, &CameraOverride::default(), cfg.width as f32 / cfg.height as f32);
        let scene = prismbake::accel::Scene::new(loaded.table, loaded.map);
        let name = mesh.display().to_string();
        let asset_rows = pool.install(|| prismbake::bench::run_bench(&name, &scene, &cam, &cfg, &|m| eprintln!("{m}")));
        let stem = mesh.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        prismbake::bench::plot::write_plot(&a.output.join(format!("{stem}.png")), &format!("{stem}: time vs depth error"), &asset_rows)?;
        rows.extend(asset_rows);
    }
    print!("{}", prismbake::bench::to_table(&rows));
    prism_file::write_atomic(&a.output.join("bench.csv"), prismbake::bench::to_csv(&rows).as_bytes())?;
    let json = serde_json::to_string_pretty(&rows).expect("serialises");
    prism_file::write_atomic(&a.output.join("bench.json"), json.as_bytes())?;
    eprintln!("wrote bench.csv, bench.json and plots to {}", a.output.display());
    Ok(ExitCode::SUCCESS)
}

fn export(a: ExportArgs) -> Result<ExitCode> {
    if prismbake::load::extension(&a.usd) != "usda" {
        return Err(Error::Param(format!("--usd {}: only .usda (USD text) is written; name the output OUT.usda", a.usd.display())));
    }
    let spec = asset::resolve(&a.mesh, &overrides(&a.disp, None))?;
    let pb = progress::spinner("baking");
    let prepared = asset::prepare(&spec, &repair_options(&a.repair)?)?;
    pb.finish_and_clear();
    if !prepared.report.is_clean() {
        eprint!("{}", prepared.report.to_text());
    }
    prismbake::usd_export::write_usda(&prepared, &a.usd)?;
    eprintln!("{}: {} faces, {} points", a.usd.display(), prepared.table.prisms.len(), prepared.table.positions.len());
    Ok(ExitCode::SUCCESS)
}
