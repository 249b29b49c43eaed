//! The GPU's way into a prism is the CPU's: for every pixel of the rock at 512² whose CPU ray
//! stops on a crease strip (a zero-area `PRISM_INSERTED` prism, the most degenerate prisms the
//! march meets), the adapter evaluates `camera_ray`, `clip_to_surface_bounds` and
//! `ray_prism_interval` on that prism, both on the CPU's ray and on its own, and each must
//! equal `Raster::ray`, `prism_hit::clip_to_surface_bounds` and `prism_hit::ray_prism_interval`.
//! Breaks if a driver's arithmetic (its division, square root, fused multiply-adds, or
//! assumptions about infinities) changes whether a ray enters such a prism.

use crate::util::{cpu_render, ctx};
use glam::{Vec2, Vec3};
use prismbake::bake::PRISM_INSERTED;
use prismbake::trace::prism_hit::{clip_to_surface_bounds, ray_prism_interval};
use prismbake_gpu::render::frame_uniform;
use prismbake_gpu::shaders;

/// pdm.rs's INTERVAL_PAD: the padding of the surface bounds' reach.
const INTERVAL_PAD: f32 = 1e-4;

/// vec4s per case: [0] pixel → GPU ray direction; [1] CPU ray origin (prism-local), t_min →
/// clip on the CPU ray; [2] CPU ray direction, t_max → interval on the CPU ray; [3..6] base
/// corners (w of [3]: reach) → [3] clip and [4] interval on the GPU ray; [6..9] lo corners,
/// [9..12] hi corners, [12] the prism's origin.
const CASE: usize = 13;

const PROBE: &str = r#"
@group(2) @binding(0) var<storage, read_write> io: array<vec4f>;

fn flag(ok: bool) -> f32 {
    return select(0.0, 1.0, ok);
}

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= arrayLength(&io) / 13u) {
        return;
    }
    let b = gid.x * 13u;
    let ro = io[b + 1u].xyz;
    let d = io[b + 2u].xyz;
    let t_min = io[b + 1u].w;
    let t_max = io[b + 2u].w;
    let reach = io[b + 3u].w;
    let v = array<vec3f, 3>(io[b + 3u].xyz, io[b + 4u].xyz, io[b + 5u].xyz);
    let lo = array<vec3f, 3>(io[b + 6u].xyz, io[b + 7u].xyz, io[b + 8u].xyz);
    let hi = array<vec3f, 3>(io[b + 9u].xyz, io[b + 10u].xyz, io[b + 11u].xyz);
    let ray = camera_ray(io[b].xy);
    let gro = ray.origin - io[b + 12u].xyz;

    let cl = clip_to_surface_bounds(ro, d, t_min, t_max, v, reach);
    let iv = ray_prism_interval(ro, d, cl.t_enter, cl.t_exit, lo, hi);
    let gcl = clip_to_surface_bounds(gro, ray.dir, ray.t_min, ray.t_max, v, reach);
    let giv = ray_prism_interval(gro, ray.dir, gcl.t_enter, gcl.t_exit, lo, hi);
    io[b] = vec4f(ray.dir, 0.0);
    io[b + 1u] = vec4f(flag(cl.ok), cl.t_enter, cl.t_exit, 0.0);
    io[b + 2u] = vec4f(flag(cl.ok && iv.ok), iv.t_enter, iv.t_exit, 0.0);
    io[b + 3u] = vec4f(flag(gcl.ok), gcl.t_enter, gcl.t_exit, 0.0);
    io[b + 4u] = vec4f(flag(gcl.ok && giv.ok), giv.t_enter, giv.t_exit, 0.0);
}
"#;

/// (ok, t_enter, t_exit) of a CPU clip or interval.
type Span = (bool, f32, f32);

fn same(cpu: Span, gpu: [f32; 4]) -> bool {
    let close = |a: f32, b: f32| (a - b).abs() <= 1e-5 * a.abs().max(b.abs()).max(1.0);
    (gpu[0] == 1.0) == cpu.0 && (!cpu.0 || (close(cpu.1, gpu[1]) && close(cpu.2, gpu[2])))
}

#[test]
fn rock_strip_rays_enter_their_prisms_as_on_the_cpu() {
    let size = 512;
    let (ex, settings, opts, cpu) = cpu_render("rock/rock.glb", size);
    let (scene, cam) = (&ex.scene, &ex.cam);
    let table = &scene.table;
    let raster = cam.raster(size, size);
    let mut io: Vec<[f32; 4]> = Vec::new();
    let mut cases = Vec::new();
    for i in 0..cpu.mask.len() {
        if cpu.mask[i] < 0.5 {
            continue;
        }
        let prism = cpu.prism[i] as usize - 1;
        let p = &table.prisms[prism];
        if p.flags & PRISM_INSERTED == 0 {
            continue;
        }
        let (x, y) = ((i as u32 % size) as f32, (i as u32 / size) as f32);
        let ray = raster.ray(Vec2::new(x, y) + 0.5);
        let origin = table.positions[p.tri[0] as usize];
        let v = p.tri.map(|k| table.positions[k as usize] - origin);
        let n = p.tri.map(|k| table.normals[k as usize]);
        let scale = (v[1].length())
            .max(v[2].length())
            .max((v[2] - v[1]).length())
            .max(f32::MIN_POSITIVE);
        let reach = p.d_min.abs().max(p.d_max.abs()) + INTERVAL_PAD * scale;
        let lo = [0, 1, 2].map(|k| v[k] + n[k] * p.lambda_lo);
        let hi = [0, 1, 2].map(|k| v[k] + n[k] * p.lambda_hi);
        let ro = ray.origin - origin;
        // The GPU's +∞ is T_FAR.
        let t_max = if ray.t_max.is_finite() {
            ray.t_max
        } else {
            prismbake_gpu::layout::T_FAR
        };
        let cl = clip_to_surface_bounds(ro, ray.dir, ray.t_min, ray.t_max, &v, reach);
        let iv = cl.and_then(|(t0, t1)| ray_prism_interval(ro, ray.dir, t0, t1, &lo, &hi));
        let span = |s: Option<(f32, f32)>| s.map_or((false, 0.0, 0.0), |(a, b)| (true, a, b));
        cases.push((
            i,
            ray.dir,
            span(cl),
            span(iv.map(|iv| (iv.t_enter, iv.t_exit))),
        ));
        let w = |a: Vec3, w: f32| [a.x, a.y, a.z, w];
        io.extend([
            [x + 0.5, y + 0.5, 0.0, 0.0],
            w(ro, ray.t_min),
            w(ray.dir, t_max),
            w(v[0], reach),
            w(v[1], 0.0),
            w(v[2], 0.0),
            w(lo[0], 0.0),
            w(lo[1], 0.0),
            w(lo[2], 0.0),
            w(hi[0], 0.0),
            w(hi[1], 0.0),
            w(hi[2], 0.0),
            w(origin, 0.0),
        ]);
    }
    assert!(cases.len() >= 300, "only {} strip pixels", cases.len());
    let frame = frame_uniform(cam, &settings, &opts);
    let src = format!(
        "{}\n{}\n{}\n{}\n{}",
        shaders::COMMON,
        shaders::RNG,
        shaders::CAMERA,
        shaders::PRISM_HIT,
        PROBE
    );
    let out = crate::util::run_probe(
        "prism entry probe",
        &src,
        (2, 0),
        &io,
        &[(
            1,
            0,
            bytemuck::bytes_of(&frame),
            wgpu::BufferUsages::UNIFORM,
        )],
    );
    let _ = ctx();
    let (mut dir_err, mut on_cpu_ray, mut on_gpu_ray) = (0f32, 0, 0);
    for (k, (pixel, dir, cl, iv)) in cases.iter().enumerate() {
        let o = &out[k * CASE..(k + 1) * CASE];
        dir_err = dir_err.max(
            (Vec3::new(o[0][0], o[0][1], o[0][2]) - *dir)
                .abs()
                .max_element(),
        );
        let cpu_ok = same(*cl, o[1]) && same(*iv, o[2]);
        let gpu_ok = same(*cl, o[3]) && same(*iv, o[4]);
        if !cpu_ok || !gpu_ok {
            if on_cpu_ray + on_gpu_ray < 8 {
                eprintln!(
                    "  pixel {pixel}: cpu clip {cl:?} interval {iv:?}; gpu on the cpu ray {:?} {:?}, on its own {:?} {:?}",
                    o[1], o[2], o[3], o[4]
                );
            }
            on_cpu_ray += !cpu_ok as usize;
            on_gpu_ray += !gpu_ok as usize;
        }
    }
    eprintln!(
        "rock strips: {} rays; prism entry differs on {on_cpu_ray} CPU rays, {on_gpu_ray} GPU rays; ray direction max error {dir_err:e}",
        cases.len()
    );
    assert!(dir_err <= 1e-6, "GPU camera rays differ by {dir_err:e}");
    assert_eq!(on_cpu_ray, 0, "prism entry differs on {on_cpu_ray} rays");
    assert_eq!(
        on_gpu_ray, 0,
        "prism entry differs on {on_gpu_ray} GPU rays"
    );
}
