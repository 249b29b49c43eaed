// tonemap.wgsl — a beauty frame's PNG preview, made on the device from the sums the samples
// left: the mirror of prismbake::render::beauty::preview_pixel over PixelSums::resolve (the
// pixel's colour plus the background behind it), shading::tonemap_filmic and
// shading::linear_to_srgb. The host still resolves the sums for the linear EXR; the preview
// comes back in each pixel's `preview` word (red in its low byte), so the host writes the PNG
// without a pass of its own over the frame.

// Narkowicz's ACES-fitted filmic curve, per channel (shading::tonemap_filmic).
fn tonemap_filmic(c: vec3f) -> vec3f {
    let x = max(c, vec3f(0.0));
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), vec3f(0.0), vec3f(1.0));
}

// The sRGB transfer function of a linear value in [0, 1] (shading::linear_to_srgb).
fn linear_to_srgb(v: f32) -> f32 {
    let x = clamp(v, 0.0, 1.0);
    if (x <= 0.0031308) {
        return 12.92 * x;
    }
    return 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}

// A value in [0, 1] as an 8-bit code, rounded half away from zero as Rust's `f32::round`
// (WGSL's `round` takes halves to even). `x - floor(x)` is exact.
fn srgb_code(v: f32) -> u32 {
    let x = linear_to_srgb(v) * 255.0;
    let f = floor(x);
    return u32(select(f, f + 1.0, x - f >= 0.5));
}

// The catcher's shadow: the share of the light its samples lost to the asset
// (PixelSums::shadow).
fn sums_shadow(s: BeautySums) -> f32 {
    if (s.ground_unshadowed > 0.0) {
        return clamp(1.0 - s.ground_lit / s.ground_unshadowed, 0.0, 1.0);
    }
    return 0.0;
}

// preview_pixel of the pixel PixelSums::resolve makes of `s` after `spp` samples, packed.
fn preview_word(s: BeautySums, spp: u32) -> u32 {
    let k = 1.0 / f32(spp);
    let c = s.radiance * k;
    let bg = (s.background + s.ground_background * (1.0 - sums_shadow(s))) * k;
    let t = tonemap_filmic((c + bg) * lighting.exposure);
    return srgb_code(t.x) | (srgb_code(t.y) << 8u) | (srgb_code(t.z) << 16u);
}

// Dispatched once per tile, after its last sample.
@compute @workgroup_size(8, 8, 1)
fn tonemap_preview(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (!in_tile(gid)) {
        return;
    }
    let i = pixel_ref(gid).i;
    beauty_sums[i].preview = preview_word(beauty_sums[i], frame.spp);
}
