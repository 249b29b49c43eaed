// aov.wgsl — the AOV kernel, the mirror of prismbake::render::render_aovs: one invocation per
// pixel of a tile renders ONE sample (`frame.sample_index`, with the CPU's pixel jitter),
// PDM's closest hit, and adds it to the pixel's sums (the CPU's `PixelAcc`: depth, normal,
// uv, steps, hit count, prism id + 1 of the first hit). Samples accumulate across dispatches
// in the CPU's order, so an invocation's loop iterations stay below lavapipe's cap at any
// spp (docs/gpu.md); the host divides and normalises the sums as the CPU does.

@group(1) @binding(1) var<storage, read_write> aov_out: array<AovPixel>;

// Workgroup edge = gpu::layout::WORKGROUP (the host dispatches div_ceil(tile, 8) groups).
@compute @workgroup_size(8, 8, 1)
fn render_aovs(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= frame.tile_size.x || gid.y >= frame.tile_size.y) {
        return;
    }
    let job = aov_ray(gid.xy);
    let hit = intersect(job.ray, job.ctx);
    if (hit.prism != NO_PRISM) {
        aov_add(gid.y * frame.tile_size.x + gid.x, hit);
    }
}

// The camera ray of tile pixel `gid` for the dispatch's sample, and its random-number context.
struct AovRay {
    ray: Ray,
    ctx: RayContext,
}

fn aov_ray(gid: vec2<u32>) -> AovRay {
    let x = frame.tile_origin.x + gid.x;
    let y = frame.tile_origin.y + gid.y;
    let pixel = y * frame.width + x;
    let sample = frame.sample_index;
    let jitter = pixel_jitter(pixel, sample);
    let ray = camera_ray(vec2f(f32(x), f32(y)) + jitter);
    return AovRay(ray, RayContext(pixel, sample, 0u, frame.seed));
}

// Add a hit to pixel `i`'s sums.
fn aov_add(i: u32, hit: Hit) {
    var acc = aov_out[i];
    acc.hits += 1.0;
    acc.depth_sum += hit.t;
    acc.normal_sum += hit.shading_normal;
    acc.uv_sum += hit.uv;
    acc.steps_sum += f32(hit.steps);
    if (acc.hits == 1.0) {
        acc.prism = hit.prism + 1u;
    }
    aov_out[i] = acc;
}
