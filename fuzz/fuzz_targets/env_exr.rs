//! bytes → an .exr file → `render::env::EnvMap::load_exr` (the `--env` HDRI): any input is a
//! clean `Err` or an environment whose sampling stays finite — every texel finite and
//! non-negative, a finite total weight, and `env_sample` / `env_pdf` / `env_radiance_smooth`
//! finite at any sample point; a panic, abort or runaway allocation is a bug.
#![no_main]

mod file_input;

use glam::{Vec2, Vec3};
use libfuzzer_sys::fuzz_target;
use prismbake::render::env::{env_pdf, env_radiance_smooth, env_sample, EnvFrame, EnvMap};

/// Sample points at the corners of the unit square, inside it and on its edges.
const US: [(f32, f32); 7] = [
    (0.0, 0.0),
    (0.999_999_9, 0.999_999_9),
    (0.5, 0.5),
    (0.123, 0.877),
    (1.0, 0.0),
    (0.0, 1.0),
    (0.75, 0.25),
];

fuzz_target!(|data: &[u8]| {
    let path = file_input::scratch_file("exr", data);
    let frame = EnvFrame {
        z_up: data.len() % 2 == 0,
        rotation: 0.7,
    };
    let Ok(env) = EnvMap::load_exr(&path, 1.0, frame) else {
        return;
    };
    assert_eq!(env.texels.len(), env.width as usize * env.height as usize);
    assert!(env.texels.iter().all(|t| t.is_finite() && t.min_element() >= 0.0));
    assert!(env.total_weight.is_finite() && env.total_weight >= 0.0);
    for (x, y) in US {
        let s = env_sample(&env, env.frame, Vec2::new(x, y));
        assert!(s.dir.is_finite() && s.pdf.is_finite() && s.pdf >= 0.0, "{x} {y}: {s:?}");
        assert!(env_radiance_smooth(&env, env.frame, s.dir).is_finite());
    }
    for d in [Vec3::X, Vec3::Y, -Vec3::Y, Vec3::new(0.3, -0.2, 0.9).normalize()] {
        let p = env_pdf(&env, env.frame, d);
        assert!(p.is_finite() && p >= 0.0, "{d}: {p}");
    }
});
