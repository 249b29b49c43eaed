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
