//! Command-line flags (clap derive). Parsing only; validation turns them into core configs.

use clap::{Args, Parser, Subcommand, ValueEnum};
use prismbake::Wrap;
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(name = "prismbake", version, about = "Displacement-mapped assets: repair, bake prisms, validate, ray trace without tessellation")]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Describe a mesh (and map): faces, UVs, bounds, creases, estimated table size.
    Inspect(InspectArgs),
    /// Repair and bake a prism table (.prisms) for a mesh and height map.
    Bake(BakeArgs),
    /// Check assets (files or folders) for everything that breaks displacement.
    Validate(ValidateArgs),
}

/// Where the height map comes from and how it displaces; each flag overrides the sidecar.
#[derive(Args, Debug, Clone, Default)]
pub struct DispArgs {
    /// Height map (.exr, .png, .tif); default: the `disp` of the mesh's sidecar file.
    #[arg(long, value_name = "MAP")]
    pub disp: Option<PathBuf>,
    /// Displacement scale S in D = S·(h − M) (world units).
    #[arg(long, allow_negative_numbers = true)]
    pub scale: Option<f32>,
    /// Midlevel M in D = S·(h − M).
    #[arg(long, allow_negative_numbers = true)]
    pub midlevel: Option<f32>,
    /// Map wrap mode outside [0, 1].
    #[arg(long, value_parser = parse_wrap)]
    pub wrap: Option<Wrap>,
    /// EXR channel to read (default Y, else R, else the first).
    #[arg(long = "disp-channel", value_name = "NAME")]
    pub channel: Option<String>,
    /// glTF TEXCOORD set to use.
    #[arg(long = "uv-set", value_name = "N")]
    pub uv_set: Option<u32>,
}

fn parse_wrap(s: &str) -> Result<Wrap, String> {
    s.parse()
}

#[derive(Args, Debug, Clone)]
pub struct RepairArgs {
    /// Smallest allowed n·N_g at a triangle corner before a crease is repaired
    /// (default sin 2.5°, the paper's 5° interior angle).
    #[arg(long, value_name = "DOT")]
    pub crease_threshold: Option<f32>,
}

#[derive(Args, Debug)]
pub struct InspectArgs {
    pub mesh: PathBuf,
    #[command(flatten)]
    pub disp: DispArgs,
    #[command(flatten)]
    pub repair: RepairArgs,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args, Debug)]
pub struct BakeArgs {
    pub mesh: PathBuf,
    #[command(flatten)]
    pub disp: DispArgs,
    #[command(flatten)]
    pub repair: RepairArgs,
    /// Output prism table.
    #[arg(short, long, value_name = "OUT.prisms")]
    pub output: PathBuf,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    pub json: bool,
    /// Re-bake even when the existing table was made from the same inputs.
    #[arg(long)]
    pub force: bool,
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReportFormat {
    Text,
    Json,
    Junit,
}

#[derive(Args, Debug)]
pub struct ValidateArgs {
    /// Mesh files or folders (searched recursively for .gltf, .glb, .obj).
    #[arg(required = true)]
    pub paths: Vec<PathBuf>,
    #[command(flatten)]
    pub disp: DispArgs,
    #[command(flatten)]
    pub repair: RepairArgs,
    /// Largest |displacement| allowed (world units); overrides the sidecar's `max_disp`.
    #[arg(long, value_name = "D")]
    pub max_disp: Option<f32>,
    #[arg(long, value_enum, default_value = "text")]
    pub format: ReportFormat,
    /// Write the report here instead of stdout.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
}
