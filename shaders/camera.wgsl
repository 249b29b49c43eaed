// camera.wgsl — primary rays, the mirror of prismbake::render::camera::Camera::ray. The basis
// (right, up, back), tan(fov/2) and the aspect ratio come from the host (gpu/src/render.rs),
// computed exactly as the CPU computes them.

@group(1) @binding(0) var<uniform> frame: Frame;

// The ray through image position `p` in pixels (origin top-left): from the camera through
// the image plane at unit distance, or, orthographic, from that position on the plane through
// the camera, along the view.
fn camera_ray(p: vec2f) -> Ray {
    let w = f32(frame.width);
    let h = f32(frame.height);
    let x = (2.0 * p.x / w - 1.0) * frame.tan_half_fov * frame.aspect;
    let y = (1.0 - 2.0 * p.y / h) * frame.tan_half_fov;
    let offset = frame.cam_right * x + frame.cam_up * y;
    if (frame.orthographic != 0u) {
        return Ray(frame.cam_from + offset, -frame.cam_back, 0.0, T_FAR);
    }
    return Ray(frame.cam_from, normalize(offset - frame.cam_back), 0.0, T_FAR);
}

// Sub-pixel position of sample `sample`: the centre for one sample, else the same hashed
// jitter as the CPU (bounce 0 for x, 1 for y).
fn pixel_jitter(pixel: u32, sample: u32) -> vec2f {
    if (frame.spp == 1u) {
        return vec2f(0.5);
    }
    return vec2f(
        random(pixel, sample, 0u, PURPOSE_PIXEL_JITTER, frame.seed),
        random(pixel, sample, 1u, PURPOSE_PIXEL_JITTER, frame.seed),
    );
}
