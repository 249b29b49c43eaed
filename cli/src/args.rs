//! Command-line flags (clap derive). Parsing only; validation turns them into core configs.

use clap::{Args, Parser, Subcommand, ValueEnum};
use prismbake::Wrap;
use std::path::PathBuf;

#[derive(Parser, Debug)]
#[command(
    name = "prismbake",
    version,
    about = "Displacement-mapped assets: repair, bake prisms, validate, ray trace without tessellation"
)]
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
    /// Ray trace AOV images (depth, normal, mask, uv, steps) and path-traced beauty of an asset,
    /// a baked table or every asset under a folder.
    Render(Box<RenderArgs>),
    /// Repair and bake an asset, then write it as USD: mesh, displacement material, per-face bounds.
    Export(ExportArgs),
    /// Time and error of every method on the same rays; table, CSV, JSON and a PNG plot.
    Bench(BenchArgs),
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Device {
    Cpu,
    Gpu,
    Auto,
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum NormalArg {
    Smooth,
    Geometric,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// A mesh (.gltf, .glb, .obj; with --disp or a sidecar) or a baked table (.prisms).
    pub input: PathBuf,
    #[command(flatten)]
    pub disp: DispArgs,
    #[command(flatten)]
    pub repair: RepairArgs,
    /// Intersection method: pdm, reference, rmip or nonlinear.
    #[arg(long, default_value = "pdm")]
    pub method: String,
    /// Where to render: cpu; gpu (any wgpu adapter, software Vulkan included; an error without
    /// one); auto (the GPU if an adapter exists and the job can run there, else the CPU).
    /// The GPU traces --method pdm, AOVs and beauty, stills, turntables and folders.
    #[arg(long, value_enum, default_value = "cpu")]
    pub device: Device,
    /// Image size WIDTHxHEIGHT.
    #[arg(long, default_value = "512x512", value_parser = parse_res)]
    pub res: (u32, u32),
    /// Samples per pixel (jittered inside the pixel when > 1).
    #[arg(long, default_value_t = 1)]
    pub spp: u32,
    /// Comma-separated AOVs: depth, normal, mask, uv, steps, prism, beauty (path traced).
    #[arg(long, default_value = "depth,normal,mask", value_delimiter = ',')]
    pub aov: Vec<String>,
    /// Render an N-frame turntable around the up axis.
    #[arg(long, value_name = "N")]
    pub turntable: Option<u32>,
    /// What turns in a turntable, about the asset's up axis: `asset` (the asset turns under
    /// lights that stay where the camera sees them, so every side passes through the key
    /// light), `camera` (the camera orbits a still scene: the lighting stays on the same side
    /// of the asset), `lights` (the camera and the asset stay, the environment and key light
    /// turn). AOVs depend only on the camera. Default: asset.
    #[arg(long, value_name = "MODE", value_parser = ["asset", "camera", "lights"])]
    pub turntable_mode: Option<String>,
    /// Only frames A-B (inclusive) of the turntable; identical to the same frames of a full run.
    #[arg(long, value_name = "A-B", value_parser = parse_range)]
    pub frames: Option<(u32, u32)>,
    /// Render through the scene file's camera of this name (a glTF camera node's or camera's
    /// name, `node #N`, a USD camera's prim path or name; default: the file's first camera).
    /// `--camera-from`, `--camera-to` and `--fov` still override its parts.
    #[arg(long, value_name = "NAME")]
    pub camera: Option<String>,
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub camera_from: Option<[f32; 3]>,
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub camera_to: Option<[f32; 3]>,
    /// Vertical field of view in degrees (a pinhole view, also through a file's orthographic
    /// camera).
    #[arg(long)]
    pub fov: Option<f32>,
    /// An orthographic view, HEIGHT scene units tall, from where the camera is; `fit`: as tall
    /// as the asset needs (its bounds with a 10% margin).
    #[arg(long, value_name = "HEIGHT|fit")]
    pub ortho: Option<String>,
    /// PDM step: `auto` (half a texel), `auto:F` (F texels) or a world-space length.
    #[arg(long, default_value = "auto", allow_hyphen_values = true)]
    pub dt: String,
    /// Turn off PDM's stochastic thin-feature jitter.
    #[arg(long)]
    pub no_jitter: bool,
    /// The shading normal (beauty and normal AOV): `geometric`, the displaced surface's own
    /// (what Cycles shades a displaced mesh with), or `smooth`, PDM's N′s = Ns − Ng + N′, which
    /// hides the base mesh's facets.
    #[arg(long, value_enum, default_value = "geometric")]
    pub normal: NormalArg,
    /// UV seams: `stitch` makes the displaced surface continuous across them (one agreed
    /// height on the edge, fading out over about a texel); `open` traces each face's own UVs,
    /// cracks and all.
    #[arg(long, default_value = "stitch", value_parser = ["stitch", "open"])]
    pub seams: String,
    /// Reference tessellation density, in micro-edges per texel.
    #[arg(long, default_value_t = 2.0)]
    pub ref_density: f32,
    /// Most memory, in GiB, the reference may take to build; a denser one is refused with
    /// the density that fits. Default: 80% of the memory available.
    #[arg(long, value_name = "GIB")]
    pub ref_memory: Option<f64>,
    /// Nonlinear rays (`--method nonlinear`): arithmetic of the per-prism work, f32 (with
    /// FMA) or f64.
    #[arg(long, default_value = "f32", value_parser = ["f32", "f64"])]
    pub precision: String,
    /// RMIP: march texels once a texture-space bound's longer side is at most this many texels.
    #[arg(long, default_value_t = 8.0)]
    pub marching_scale: f32,
    /// RMIP: pyramid resolution along the map's longer side (default: the N²-sized pyramid).
    #[arg(long, value_name = "N")]
    pub rmip_res: Option<u32>,
    #[arg(long, default_value_t = 0)]
    pub seed: u32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output folder.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print a JSON summary (timings, rays/s, files) on stdout.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub look: LookArgs,
    /// After rendering, re-render whenever the height map file changes (re-baking only the
    /// prisms whose bounds no longer hold); Ctrl-C to stop.
    #[arg(long)]
    pub watch: bool,
    /// With --watch: stop after N re-renders.
    #[arg(long, value_name = "N", requires = "watch")]
    pub watch_max: Option<u32>,
    /// Do not read or write the prism-table cache ($XDG_CACHE_HOME/prismbake).
    #[arg(long)]
    pub no_cache: bool,
}

/// Beauty settings: lights, material, bounces, ground.
#[derive(Args, Debug, Clone)]
pub struct LookArgs {
    /// Equirectangular HDR environment (.exr, or Radiance .hdr), oriented as Blender's world
    /// texture (the image's centre faces +X); default: a USD file's `DomeLight`, else a
    /// neutral built-in sky.
    #[arg(long, value_name = "MAP.exr|MAP.hdr")]
    pub env: Option<PathBuf>,
    /// Rotate the environment about the up axis (degrees, counter-clockwise seen from above;
    /// -90 gives OpenEXR's latitude-longitude orientation, that of a USD DomeLight).
    #[arg(
        long,
        value_name = "DEG",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub env_rotate: f32,
    /// Multiply the environment's radiance (0 = no environment light).
    #[arg(long, value_name = "K", default_value_t = 1.0)]
    pub env_intensity: f32,
    /// Directional key light with shadows: azimuth and elevation in degrees (azimuth 0 = the
    /// camera's side, 90 = +X), and its irradiance. Default: the scene file's directional
    /// light (a USD `DistantLight`, a glTF `KHR_lights_punctual` one), else none.
    #[arg(long, value_name = "AZ,EL,INTENSITY", value_parser = parse_vec3, allow_hyphen_values = true)]
    pub key_light: Option<[f32; 3]>,
    /// The key light's angular diameter in degrees (0 = point-like, hard shadows; the sun is
    /// about 0.5; a few degrees soften the displacement's self-shadowing as an overcast sun).
    /// Default: 0 for `--key-light`, the file's own for its light.
    #[arg(long, value_name = "DEG", default_value_t = 0.0)]
    pub key_angle: f32,
    /// The key light's colour (linear R,G,B), for `--key-light` or the file's light: a hue,
    /// divided by its luminance, so the light's irradiance stays what it was. Default: white
    /// for `--key-light`, the file's light's own colour.
    #[arg(long, value_name = "R,G,B", value_parser = parse_vec3)]
    pub key_color: Option<[f32; 3]>,
    /// Base colour (linear R,G,B in [0, 1]), in place of the glTF material's colour and
    /// base-colour texture; default: the material's, else 0.8 grey.
    #[arg(long, value_name = "R,G,B", value_parser = parse_vec3)]
    pub base_color: Option<[f32; 3]>,
    /// GGX roughness in [0, 1] (below 0.02: a perfect mirror); default: the glTF material's
    /// roughnessFactor, else 0.5.
    #[arg(long)]
    pub roughness: Option<f32>,
    /// Metallic in [0, 1]; default: the glTF material's metallicFactor, else 0.
    #[arg(long)]
    pub metallic: Option<f32>,
    /// Shade with the surface's own normals: do not bend them by the materials' tangent-space
    /// normal maps (glTF normalTexture, USD normal, .mtl norm / map_Bump).
    #[arg(long)]
    pub no_normal_maps: bool,
    /// Render the materials without their glow (glTF emissiveFactor / emissiveTexture, USD
    /// emissiveColor, .mtl Ke / map_Ke).
    #[arg(long)]
    pub no_emission: bool,
    /// Render every surface opaque: do not let the materials' alpha cut it away (glTF
    /// alphaMode MASK / BLEND with the base colour's alpha, USD opacity, .mtl d).
    #[arg(long)]
    pub no_alpha: bool,
    /// Light with the flags and defaults only, not the scene file's dome and directional
    /// lights (a standard lookdev rig for every asset).
    #[arg(long)]
    pub no_scene_lights: bool,
    /// Dielectric reflectance at normal incidence of every material (0.04 ≈ IOR 1.5; 0 = pure
    /// diffuse); default: each material's from its index of refraction (glTF KHR_materials_ior
    /// and KHR_materials_specular, USD ior, .mtl Ni), else 0.04.
    #[arg(long)]
    pub specular: Option<f32>,
    /// Specular tint of every material (linear R,G,B in [0, 1], Blender's Specular Tint: the
    /// dielectric's F0 times it, a metal's edge towards it); default: each material's (glTF
    /// KHR_materials_specular's colour), else white.
    #[arg(long, value_name = "R,G,B", value_parser = parse_vec3)]
    pub specular_tint: Option<[f32; 3]>,
    /// Clearcoat weight of every material, in [0, 1] (Blender's Coat Weight: a glossy
    /// dielectric layer over the rest, index 1.5); default: each material's (glTF
    /// KHR_materials_clearcoat, USD clearcoat, .mtl Pc), else none.
    #[arg(long, value_name = "W")]
    pub clearcoat: Option<f32>,
    /// Clearcoat roughness of every material, in [0, 1]; default: each material's, else 0.03.
    #[arg(long, value_name = "R")]
    pub clearcoat_roughness: Option<f32>,
    /// Surface bounces per path, 1..=4 (1 = direct light only).
    #[arg(long, default_value_t = 2)]
    pub bounces: u32,
    /// Shadow-catcher ground plane at the asset's lowest point (its shadow in the alpha).
    #[arg(long)]
    pub ground: bool,
    /// Exposure of the beauty's PNG previews and contact sheets, in stops: the radiance times
    /// 2^EV before the filmic curve (like a display exposure); the linear EXR is not scaled.
    #[arg(
        long,
        value_name = "EV",
        default_value_t = 0.0,
        allow_hyphen_values = true
    )]
    pub exposure: f32,
    /// Denoise the beauty (EXR, PNG, contact sheet) with Intel Open Image Denoise, guided by
    /// the first hits' albedo and normals: `high` (the default; final frames), `balanced`
    /// (~2.5x faster) or `fast` (~5x). Loaded at run time from PRISMBAKE_OIDN (the library or
    /// its folder), ~/.local/share/prismbake/oidn/lib (./install.sh puts it there), or the
    /// system's library path.
    #[arg(long, value_name = "QUALITY", num_args = 0..=1, default_missing_value = "high")]
    pub denoise: Option<DenoiseArg>,
}

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum DenoiseArg {
    High,
    Balanced,
    Fast,
}

fn parse_res(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}': expected WIDTHxHEIGHT, e.g. 512x512"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("'{s}': expected WIDTHxHEIGHT, e.g. 512x512"))
    };
    Ok((p(w)?, p(h)?))
}

fn parse_range(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("'{s}': expected A-B, e.g. 0-11");
    match s.split_once('-') {
        Some((a, b)) => Ok((
            a.trim().parse().map_err(|_| bad())?,
            b.trim().parse().map_err(|_| bad())?,
        )),
        None => s.trim().parse().map(|a| (a, a)).map_err(|_| bad()),
    }
}

fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|c| c.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{s}': expected X,Y,Z"))?;
    <[f32; 3]>::try_from(v).map_err(|_| format!("'{s}': expected three numbers X,Y,Z"))
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
    /// Largest height jump across a UV seam, as a fraction of |scale| (default 0.02);
    /// overrides the sidecar's `max_seam_jump`.
    #[arg(long, value_name = "FRACTION", allow_hyphen_values = true)]
    pub max_seam_jump: Option<f32>,
    /// Largest |displacement| allowed (world units); overrides the sidecar's `max_disp`.
    #[arg(long, value_name = "D")]
    pub max_disp: Option<f32>,
    #[arg(long, value_enum, default_value = "text")]
    pub format: ReportFormat,
    /// Write the report here instead of stdout.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Assets (meshes with sidecars or --disp flags, or folders of them).
    #[arg(required = true)]
    pub assets: Vec<PathBuf>,
    #[command(flatten)]
    pub disp: DispArgs,
    /// Methods to run (reference is always traced as the ground truth).
    #[arg(long, default_value = "pdm,reference", value_delimiter = ',')]
    pub methods: Vec<String>,
    /// PDM step sizes to sweep: auto, auto:F (F texels) or world lengths.
    #[arg(
        long,
        default_value = "auto:1,auto:0.5,auto:0.25",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub dt: Vec<String>,
    /// RMIP marching scales to sweep (texels below which a bound is texel-marched).
    #[arg(long, default_value = "2,8,32", value_delimiter = ',')]
    pub marching_scale: Vec<f32>,
    /// RMIP pyramid resolutions to sweep: auto (the N²-sized pyramid) or cells along the map's
    /// longer side.
    #[arg(long, default_value = "auto", value_delimiter = ',')]
    pub rmip_res: Vec<String>,
    /// Nonlinear-ray precisions to sweep: f32 (with FMA), f64.
    #[arg(long, default_value = "f32,f64", value_delimiter = ',')]
    pub precision: Vec<String>,
    /// Also run the paper-exact parallel-offset PDM (the before-fix watertightness numbers).
    #[arg(long)]
    pub paper_pdm: bool,
    /// Also run PDM over whole prisms, without its sub-prism cells, at every --dt (what the
    /// cells save, in one run).
    #[arg(long)]
    pub pdm_whole: bool,
    #[arg(long, default_value = "512x512", value_parser = parse_res)]
    pub res: (u32, u32),
    /// Random secondary rays leaving the reference's primary hits.
    #[arg(long, default_value_t = 0)]
    pub secondary: usize,
    /// Rays aimed from outside at points inside the object (leak test).
    #[arg(long, default_value_t = 100_000)]
    pub leak_rays: usize,
    /// UV seam treatments to bench, each on its own scene: stitch, open or both
    /// (`stitch,open` measures what stitching costs and what it closes, in one run).
    #[arg(long, default_value = "stitch", value_delimiter = ',')]
    pub seams: Vec<String>,
    #[arg(long, default_value_t = 2.0)]
    pub ref_density: f32,
    /// Most memory, in GiB, the reference may take to build; a denser one is refused with
    /// the density that fits. Default: 80% of the memory available.
    #[arg(long, value_name = "GIB")]
    pub ref_memory: Option<f64>,
    /// Density of the local reference that checks each leak (only the prisms the ray crosses
    /// are tessellated); a leak it does not hit is a fold of the coarser reference's chords.
    /// 0: no check.
    #[arg(long, default_value_t = 8.0)]
    pub confirm_density: f32,
    /// Timed repetitions per setting (the fastest counts).
    #[arg(long, default_value_t = 2)]
    pub repeats: u32,
    #[arg(long, default_value_t = 0)]
    pub seed: u32,
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output folder for bench.csv, bench.json and <asset>.png plots.
    #[arg(short, long, default_value = "bench-out")]
    pub output: PathBuf,
}

#[derive(Args, Debug)]
pub struct ExportArgs {
    /// A mesh (.gltf, .glb, .obj, .usda, .usdc; with --disp, a sidecar or a USD material).
    pub mesh: PathBuf,
    #[command(flatten)]
    pub disp: DispArgs,
    #[command(flatten)]
    pub repair: RepairArgs,
    /// Output USD text layer; the height map is referenced by a path relative to it.
    #[arg(long, value_name = "OUT.usda")]
    pub usd: PathBuf,
}
