//! wgpu's errors outside an error scope (a buffer the device refuses, a lost device after a
//! GPU watchdog's reset) come back as the render's error, not wgpu's default panic. A context
//! of its own, so that the shared one stays clean.

use crate::util::example_scene;
use prismbake::render::RenderSettings;
use prismbake::trace::pdm::PdmOptions;
use prismbake_gpu::{render_aovs, GpuContext, GpuScene};

#[test]
fn driver_errors_are_errors_not_panics() {
    let ctx = GpuContext::new().expect("an adapter");
    let too_big = ctx.device().limits().max_buffer_size + 4;
    let _refused = ctx.device().create_buffer(&wgpu::BufferDescriptor {
        label: Some("larger than the device allows"),
        size: too_big,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let e = ctx.check().expect_err("the refused buffer is reported");
    assert!(
        e.to_string().contains("larger than the device allows"),
        "{e}"
    );
    ctx.check().expect("an error is reported once");
    // The context still renders.
    let ex = example_scene("torus/torus.obj");
    let scene = GpuScene::upload(&ctx, &ex.scene).expect("upload");
    let settings = RenderSettings {
        width: 16,
        height: 16,
        spp: 1,
        seed: 7,
    };
    let img = render_aovs(
        &ctx,
        &scene,
        &ex.cam,
        &settings,
        &PdmOptions::default(),
        &|_| {},
    )
    .expect("render after the error");
    assert!(img.mask.iter().any(|&m| m > 0.5));
}
