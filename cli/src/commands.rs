//! One function per command: build the core config from the flags, call core, print.

use crate::args::{BakeArgs, Cli, Command, DispArgs, InspectArgs, RepairArgs, ReportFormat, ValidateArgs};
use crate::progress;
use prismbake::asset::{self, AssetSpec, Overrides};
use prismbake::repair::RepairOptions;
use prismbake::{prism_file, report, validate, Error, Result};
use std::path::Path;
use std::process::ExitCode;

pub fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        Command::Inspect(a) => inspect(a),
        Command::Bake(a) => bake(a),
        Command::Validate(a) => validate(a),
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
