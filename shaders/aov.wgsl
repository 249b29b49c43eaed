// aov.wgsl — the AOV kernel, the mirror of prismbake::render::render_aovs: one invocation per
// pixel of a tile, spp camera rays with the CPU's pixel jitter, PDM's closest hit, and the
// CPU's accumulation (mean depth/uv over hits, summed-then-normalised normal, coverage mask,
// summed steps, prism id + 1 of the first hit).

@group(1) @binding(1) var<storage, read_write> aov_out: array<AovPixel>;

// Workgroup edge = gpu::layout::WORKGROUP (the host dispatches div_ceil(tile, 8) groups).
@compute @workgroup_size(8, 8, 1)
fn render_aovs(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= frame.tile_size.x || gid.y >= frame.tile_size.y) {
        return;
    }
    let x = frame.tile_origin.x + gid.x;
    let y = frame.tile_origin.y + gid.y;
    let pixel = y * frame.width + x;
    var hits = 0u;
    var depth = 0.0;
    var normal = vec3f(0.0);
    var uv = vec2f(0.0);
    var steps = 0.0;
    var prism = 0u;
    for (var sample = 0u; sample < frame.spp; sample++) {
        let jitter = pixel_jitter(pixel, sample);
        let ray = camera_ray(vec2f(f32(x), f32(y)) + jitter);
        let ctx = RayContext(pixel, sample, 0u, frame.seed);
        let hit = intersect(ray, ctx);
        if (hit.prism != NO_PRISM) {
            hits += 1u;
            depth += hit.t;
            normal += hit.shading_normal;
            uv += hit.uv;
            steps += f32(hit.steps);
            if (hits == 1u) {
                prism = hit.prism + 1u;
            }
        }
    }
    let k = f32(max(hits, 1u));
    var out: AovPixel;
    out.normal = normalize_or_zero(normal);
    out.depth = select(0.0, depth / k, hits > 0u);
    out.uv = uv / k;
    out.mask = f32(hits) / f32(frame.spp);
    out.steps_sum = steps;
    out.prism = prism;
    aov_out[gid.y * frame.tile_size.x + gid.x] = out;
}
