//! One GPU context for the whole test binary (building the pipelines compiles every shader).

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
