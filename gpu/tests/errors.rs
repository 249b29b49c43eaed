//! wgpu's errors outside an error scope (a buffer the device refuses, a lost device after a
//! GPU watchdog's reset) come back as the render's error, not wgpu's default panic. A context
//! of its own, so that the shared one stays clean.

use crate::util::example_scene;
use prismbake::render::{AovImage, RenderSettings};
use prismbake::trace::pdm::PdmOptions;
use prismbake_gpu::{render_aovs, GpuContext, GpuError, GpuScene};

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
    let img = torus_aovs(&ctx, 16, 16)().expect("render after the error");
    assert!(img.mask.iter().any(|&m| m > 0.5));
}

/// A function rendering the torus example's AOVs at `width`×`height` on `ctx` (1 spp, seed 7).
fn torus_aovs(
    ctx: &GpuContext,
    width: u32,
    height: u32,
) -> impl Fn() -> Result<AovImage, GpuError> + '_ {
    let ex = example_scene("torus/torus.obj");
    let scene = GpuScene::upload(ctx, &ex.scene).expect("upload");
    let settings = RenderSettings {
        width,
        height,
        spp: 1,
        seed: 7,
    };
    move || {
        render_aovs(
            ctx,
            &scene,
            &ex.cam,
            &settings,
            &PdmOptions::default(),
            &|_| {},
        )
    }
}

/// A frame that runs out of GPU memory is rendered again in tiles half as wide, until one fits
/// (`GpuContext::with_tile_fallback`, around every frame of `render_aovs` and
/// `render_beauty`): the picture is the one the first tile gives, the tile stays smaller for
/// later frames, the buffers of the larger tile are freed, and below the smallest tile the
/// error stands. (The out-of-memory error is made here; that the driver's own is recognised as
/// one is `context::tests::driver_errors_say_whether_memory_ran_out_and_keep_their_causes`.)
#[test]
fn running_out_of_memory_shrinks_the_tile_and_keeps_the_picture() {
    let ctx = GpuContext::new().expect("an adapter");
    let render = torus_aovs(&ctx, 150, 130);
    let oom = || GpuError::OutOfMemory {
        adapter: ctx.adapter_name().to_string(),
        detail: "made by the test".into(),
    };
    let whole = render().expect("the first tile renders");
    let first = ctx.tile();
    assert!(first >= 256, "tile {first}");
    let warnings = std::sync::Arc::new(std::sync::Mutex::new(Vec::<String>::new()));
    let sink = warnings.clone();
    ctx.set_warning_sink(move |w| sink.lock().unwrap().push(w.to_string()));
    let mut attempts = 0;
    let shrunk = ctx
        .with_tile_fallback(|| {
            attempts += 1;
            match attempts {
                1 | 2 => Err(oom()),
                _ => render(),
            }
        })
        .expect("the third attempt renders");
    assert_eq!(attempts, 3);
    // Each shrink is one warning through the sink, naming the error and the new tile.
    let said = warnings.lock().unwrap().clone();
    assert_eq!(said.len(), 2, "{said:?}");
    let half = first / 2 / 8 * 8;
    for (w, (new, old)) in said.iter().zip([(half, first), (half / 2 / 8 * 8, half)]) {
        assert!(w.contains("made by the test"), "{w}");
        assert!(
            w.contains(&format!("{new}² tiles instead of {old}²")),
            "{w}"
        );
    }
    assert_eq!(ctx.tile(), first / 4 / 8 * 8);
    assert!(ctx.tile() < 150, "the frame is several tiles now");
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for (name, a, b) in [
        ("depth", &shrunk.depth, &whole.depth),
        ("mask", &shrunk.mask, &whole.mask),
    ] {
        assert!(bits(a) == bits(b), "{name} changed with the tile");
    }
    assert!(shrunk.normal == whole.normal && shrunk.uv == whole.uv);
    assert_eq!(shrunk.total_steps, whole.total_steps);
    assert!(
        whole.mask.iter().any(|&m| m > 0.0),
        "the torus is in the frame"
    );
    // Down to the smallest tile, then the error is the frame's.
    let e = ctx.with_tile_fallback(|| Err::<(), _>(oom())).unwrap_err();
    assert!(matches!(e, GpuError::OutOfMemory { .. }), "{e}");
    assert!(e.to_string().contains("out of GPU memory"), "{e}");
    assert_eq!(ctx.tile(), 64);
    assert_eq!(ctx.tile_buffer_bytes(), 0, "the tile buffers are freed");
    let smallest = render().expect("the smallest tile renders");
    assert!(bits(&smallest.depth) == bits(&whole.depth));
}
