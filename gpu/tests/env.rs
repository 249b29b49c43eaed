//! The WGSL environment is the CPU's: on the adapter, `env_sample` draws the CPU's direction and
//! density from the same random numbers, and `env_radiance`, `env_radiance_smooth` and `env_pdf`
//! read the CPU's texels and tables, with the environment uploaded as `GpuBeautyScene::upload`
//! uploads it (`EnvTextures`: radiance and texel weights in one rgba32float texture, each row's
//! conditional cdf without its leading 0 in an r32float one, the marginal cdf without its
//! leading 0 and the row weights in an rg32float one). Breaks if a texel or a cdf entry is read
//! one off (a sampled direction a texel away, another texel's radiance or weight), which a
//! beauty parity render sees only as noise.

use crate::util;
use glam::{Vec2, Vec3};
use prismbake::render::env::{self, EnvFrame, EnvMap};
use prismbake::rng;
use prismbake_gpu::beauty::{check_lighting_fits, env_lighting, EnvTextures};
use prismbake_gpu::shaders;

const PROBE: &str = r#"
// Per case: in [0] = (u, _, _), [1] = (d, _); out [0] = env_sample(u) (dir, pdf),
// [1] = (env_radiance(d), env_pdf(d)), [2] = (env_radiance_smooth(d), _).
@group(3) @binding(1) var<storage, read_write> io: array<array<vec4f, 3>>;

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= arrayLength(&io)) {
        return;
    }
    let u = io[gid.x][0].xy;
    let d = io[gid.x][1].xyz;
    let s = env_sample(u);
    io[gid.x][0] = vec4f(s.dir, s.pdf);
    io[gid.x][1] = vec4f(env_radiance(d), env_pdf(d));
    io[gid.x][2] = vec4f(env_radiance_smooth(d), 0.0);
}
"#;

/// A non-square environment of distinct texels, lopsided (a bright patch, dark rows), so that
/// the tables are far from uniform and every texel's radiance and weight is its own.
fn lopsided_env(frame: EnvFrame) -> EnvMap {
    let (w, h) = (37u32, 19u32);
    let texels = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let noise = |k: u32| rng::pcg_hash(3 * i + k) as f32 / u32::MAX as f32;
            let base = Vec3::new(noise(1), noise(2), noise(3)) * 0.5;
            match (x, y) {
                (20..24, 4..7) => base + Vec3::new(80.0, 60.0, 40.0),
                (_, 12..15) => Vec3::ZERO,
                _ => base,
            }
        })
        .collect();
    EnvMap::new(w, h, texels, frame)
}

/// Densities agree to this relative error: the same texel's weights, over the GPU's sin θ of
/// its own acos (2·10⁻⁴ apart near a pole); another texel's weight differs by far more.
const PDF_TOL: f32 = 1e-3;

/// The bilinear background agrees to this share of its four texels' spread: the same texels,
/// weighted from the GPU's own atan2 and acos (uv ~10⁻⁵ apart, ~4·10⁻⁴ of a texel here); a
/// wrong texel moves it by a large share.
const SMOOTH_TOL: f32 = 1e-2;

/// The largest difference between the four texels `env_radiance_smooth` blends at `d` (the
/// CPU's indexing: u wraps, v clamps).
fn corner_range(e: &EnvMap, d: Vec3) -> f32 {
    let uv = env::env_dir_to_uv(env::world_to_env(d, e.frame));
    let p = uv * Vec2::new(e.width as f32, e.height as f32) - 0.5;
    let (w, h) = (e.width as i64, e.height as i64);
    let (x0, y0) = (p.x.floor() as i64, p.y.floor() as i64);
    let corners: Vec<Vec3> = [(0, 0), (1, 0), (0, 1), (1, 1)]
        .iter()
        .map(|&(dx, dy)| {
            let x = (x0 + dx).rem_euclid(w);
            let y = (y0 + dy).clamp(0, h - 1);
            e.texels[(y * w + x) as usize]
        })
        .collect();
    let lo = corners.iter().fold(Vec3::INFINITY, |a, &c| a.min(c));
    let hi = corners.iter().fold(Vec3::NEG_INFINITY, |a, &c| a.max(c));
    (hi - lo).max_element()
}

#[test]
fn environment_sampling_and_lookups_read_the_cpus_texels_and_tables() {
    let ctx = util::ctx();
    let src = format!("{}\n{}", shaders::beauty_module_source(), PROBE);
    for frame in [
        EnvFrame {
            z_up: false,
            rotation: 0.0,
        },
        EnvFrame {
            z_up: true,
            rotation: 1.3,
        },
    ] {
        let e = lopsided_env(frame);
        let (w, h) = (e.width, e.height);
        // Random numbers for the sampler, and directions through points inside each texel (a
        // fifth of a texel off its centre either way: far from an edge, where the GPU's atan2 and
        // acos may round to the neighbour).
        let mut state = 11u32;
        let mut next = || {
            state = rng::pcg_hash(state);
            state as f32 / u32::MAX as f32
        };
        let mut cases: Vec<(Vec2, Vec3)> = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let off = Vec2::new(next() - 0.5, next() - 0.5) * 0.4;
                let uv =
                    (Vec2::new(x as f32, y as f32) + 0.5 + off) / Vec2::new(w as f32, h as f32);
                let d = env::env_to_world(env::env_uv_to_dir(uv), frame);
                cases.push((Vec2::new(next(), next()), d));
            }
        }
        let io: Vec<[[f32; 4]; 3]> = cases
            .iter()
            .map(|(u, d)| [[u.x, u.y, 0.0, 0.0], [d.x, d.y, d.z, 0.0], [0.0; 4]])
            .collect();
        // Written two rows at a time, as an environment of millions of texels is: the bands
        // must meet (the last one short).
        let textures = EnvTextures::upload_in_bands(ctx, &e, 2 * w as usize);
        let view = |t: &wgpu::Texture| t.create_view(&Default::default());
        let (radiance, conditional, rows) = (
            view(&textures.radiance),
            view(&textures.conditional),
            view(&textures.rows),
        );
        let lighting = env_lighting(&e, e.frame);
        let gpu = util::run_probe_with_textures(
            "environment probe",
            &src,
            (3, 1),
            &io,
            &[(
                2,
                0,
                bytemuck::bytes_of(&lighting),
                wgpu::BufferUsages::UNIFORM,
            )],
            &[(2, 2, &rows), (2, 4, &radiance), (2, 5, &conditional)],
        );
        let mut pdf_flips = 0;
        for ((u, d), g) in cases.iter().zip(&gpu) {
            let want = env::env_sample(&e, e.frame, *u);
            let dir = Vec3::new(g[0][0], g[0][1], g[0][2]);
            // The same texel and the same place in it, up to the GPU's sin and cos.
            assert!(
                (dir - want.dir).abs().max_element() < 1e-5,
                "u {u}: sampled {dir} on the GPU, {} on the CPU ({frame:?})",
                want.dir
            );
            // The density of the texel the direction maps back to: the neighbour's where the
            // sample lies on an edge and the two round apart (rare).
            if (g[0][3] - want.pdf).abs() > PDF_TOL * want.pdf.abs().max(1e-3) {
                pdf_flips += 1;
            }
            let radiance = Vec3::new(g[1][0], g[1][1], g[1][2]);
            assert_eq!(
                radiance,
                env::env_radiance(&e, e.frame, *d),
                "radiance at {d}"
            );
            let pdf = env::env_pdf(&e, e.frame, *d);
            assert!(
                (g[1][3] - pdf).abs() <= PDF_TOL * pdf.abs().max(1e-3),
                "pdf at {d}: {} on the GPU, {pdf} on the CPU",
                g[1][3]
            );
            let smooth = Vec3::new(g[2][0], g[2][1], g[2][2]);
            let want_smooth = env::env_radiance_smooth(&e, e.frame, *d);
            let range = corner_range(&e, *d);
            assert!(
                (smooth - want_smooth).abs().max_element()
                    <= SMOOTH_TOL * range + 1e-5 * want_smooth.max_element().max(1.0),
                "smooth radiance at {d}: {smooth} on the GPU, {want_smooth} on the CPU"
            );
        }
        assert!(
            pdf_flips * 200 <= cases.len(),
            "{pdf_flips} of {} sampled densities differ ({frame:?})",
            cases.len()
        );
    }
}

/// An environment as wide as the device's largest texture fits; one texel wider is refused
/// before any upload, as a capacity error (so `--device auto` renders it on the CPU) naming the
/// sides, the device's side and the way out.
#[test]
fn an_environment_wider_than_the_devices_textures_is_refused_before_upload() {
    let ctx = util::ctx();
    let side = ctx.device().limits().max_texture_dimension_2d;
    let frame = EnvFrame {
        z_up: false,
        rotation: 0.0,
    };
    let env = |w: u32| EnvMap::new(w, 1, vec![Vec3::ONE; w as usize], frame);
    check_lighting_fits(ctx, Some(&env(side)), &[]).unwrap();
    let err = check_lighting_fits(ctx, Some(&env(side + 1)), &[]).unwrap_err();
    assert!(err.is_capacity(), "{err}");
    let msg = err.to_string();
    for part in [
        format!("{} × 1 texels", side + 1),
        format!("largest texture side of {side}"),
        "--device auto".to_string(),
    ] {
        assert!(msg.contains(&part), "{msg}");
    }
}
