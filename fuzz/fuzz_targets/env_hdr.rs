//! bytes → an .hdr file → `render::env::EnvMap::load` (a Radiance RGBE `--env` HDRI): any
//! input is a clean `Err` or an environment whose sampling stays finite; a panic, abort or
//! runaway allocation is a bug.
#![no_main]

mod file_input;

use glam::Vec2;
use libfuzzer_sys::fuzz_target;
use prismbake::render::env::{env_pdf, env_sample, EnvFrame, EnvMap};

fuzz_target!(|data: &[u8]| {
    let path = file_input::scratch_file("hdr", data);
    let frame = EnvFrame {
        z_up: false,
        rotation: 0.0,
    };
    let Ok(env) = EnvMap::load(&path, 1.0, frame) else {
        return;
    };
    assert_eq!(env.texels.len(), env.width as usize * env.height as usize);
    assert!(env.texels.iter().all(|t| t.is_finite() && t.min_element() >= 0.0));
    assert!(env.total_weight.is_finite());
    for u in [Vec2::ZERO, Vec2::splat(0.5), Vec2::new(0.999_999_9, 0.123)] {
        let s = env_sample(&env, env.frame, u);
        assert!(s.dir.is_finite() && s.pdf.is_finite() && s.pdf >= 0.0, "{s:?}");
        assert!(env_pdf(&env, env.frame, s.dir).is_finite());
    }
});
