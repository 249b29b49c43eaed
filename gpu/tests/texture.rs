//! The WGSL base-colour texture is the CPU's: `texture_sample` evaluated on the adapter at UVs
//! on and off the texture (texel centres and edges, the borders, far outside) equals
//! `ColorMap::sample` for every wrap mode per axis and both filters, with the texels laid out
//! in one buffer as `GpuBeautyScene::upload` lays them out. Breaks
//! if the GPU reads another texel than the CPU anywhere (a wrap at a border, a mirrored
//! period, the nearest texel's rounding), which a parity render sees only in a few pixels.

use crate::util;
use glam::{Vec2, Vec3};
use prismbake::rng;
use prismbake::texture::{raw8_table, srgb8_table, ColorMap, Sampler, TexWrap, UvTransform};
use prismbake_gpu::beauty::{material_texture, texel_buffer, texture_layout, TEX_PACKED};
use prismbake_gpu::layout::{texture_sampler_code, GpuMaterial};
use prismbake_gpu::shaders;

const PROBE: &str = r#"
// Per case: in = (u, v, _, _), out = (texture_sample(uv), _).
@group(3) @binding(1) var<storage, read_write> io: array<vec4f>;

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= arrayLength(&io)) {
        return;
    }
    io[gid.x] = vec4f(texture_sample(materials[0].color_tex, io[gid.x].xy), 0.0);
}
"#;

/// UVs where a wrong texel shows: half-texel steps over the texture and two periods around it
/// (centres, edges, a little off both), then pseudo-random UVs far outside.
fn probe_uvs(w: u32, h: u32) -> Vec<Vec2> {
    let mut uvs = Vec::new();
    for j in -(2 * h as i32 + 3)..(4 * h as i32 + 3) {
        for i in -(2 * w as i32 + 3)..(4 * w as i32 + 3) {
            let (u, v) = (i as f32 * 0.5 / w as f32, j as f32 * 0.5 / h as f32);
            for off in [0.0, 0.013, -0.007] {
                uvs.push(Vec2::new(u + off / w as f32, v - off / h as f32));
            }
        }
    }
    let mut s = 3u32;
    let mut next = || {
        s = rng::pcg_hash(s);
        s as f32 / u32::MAX as f32
    };
    for _ in 0..2048 {
        uvs.push(Vec2::new(next() * 60.0 - 30.0, next() * 60.0 - 30.0));
    }
    uvs
}

#[test]
fn texture_lookups_read_the_cpus_texels_under_every_sampler() {
    // A non-square texture of distinct colours, so that any other texel, or an offset that
    // misses the texture's, gives another colour.
    let (w, h) = (5u32, 3u32);
    let colour = |i: u32| {
        Vec3::new(
            rng::pcg_hash(3 * i + 1) as f32 / u32::MAX as f32,
            rng::pcg_hash(3 * i + 2) as f32 / u32::MAX as f32,
            rng::pcg_hash(3 * i + 3) as f32 / u32::MAX as f32,
        )
    };
    // Laid out as `GpuBeautyScene::upload` does: an f32 texture (any colours), one of 8-bit
    // sRGB colours and one of 8-bit data, which go up packed (their codes and the tables), in
    // the same buffer.
    let codes = |table: [f32; 256], salt: u32| -> Vec<Vec3> {
        (0..w * h)
            .map(|i| {
                Vec3::from_array(std::array::from_fn(|k| {
                    table[(rng::pcg_hash(7 * i + k as u32 + salt) & 0xff) as usize]
                }))
            })
            .collect()
    };
    let tex: Vec<Vec3> = (0..w * h).map(colour).collect();
    let tex8 = codes(srgb8_table(), 0);
    let raw8 = codes(raw8_table(), 1000);
    let maps_with = |sampler: Sampler, transform: UvTransform| {
        [&tex, &tex8, &raw8].map(|texels| ColorMap {
            width: w,
            height: h,
            texels: texels.clone(),
            sampler,
            transform,
            name: "probe".into(),
        })
    };
    let maps = |sampler: Sampler| maps_with(sampler, UvTransform::IDENTITY);
    let layout = texture_layout(&maps(Sampler::default()));
    assert_eq!(
        layout.textures.iter().map(|t| t.1).collect::<Vec<_>>(),
        [None, Some(0), Some(1)]
    );
    assert_eq!(layout.len, 2 * 256 + 3 * 15 + 15 + 15);
    let texels = texel_buffer(&maps(Sampler::default()), &layout);
    let wraps = [TexWrap::Repeat, TexWrap::Clamp, TexWrap::Mirror];
    let uvs = probe_uvs(w, h);
    let io: Vec<[f32; 4]> = uvs.iter().map(|uv| [uv.x, uv.y, 0.0, 0.0]).collect();
    // The beauty module (its `env_texels` and `materials`), the probe beside its kernels.
    let src = format!("{}\n{}", shaders::beauty_module_source(), PROBE);
    let mut cases = 0;
    // A UV transform that swaps u and v, scales, flips and offsets, exactly in floats (powers
    // of two), so that the probe's texel boundaries stay boundaries on both sides.
    let swap = UvTransform([0.0, 2.0, 0.25, -1.0, 0.0, 0.5]);
    for (nearest, transform) in [
        (false, UvTransform::IDENTITY),
        (true, UvTransform::IDENTITY),
        (true, swap),
    ] {
        for wu in wraps {
            for wv in wraps {
                let sampler = Sampler {
                    wrap: [wu, wv],
                    nearest,
                };
                let maps = maps_with(sampler, transform);
                for (i, map) in maps.iter().enumerate() {
                    let tex = material_texture(&maps, &layout, i as u32, 0);
                    let packed = layout.textures[i].1.is_some();
                    assert_eq!(
                        tex.sampler,
                        texture_sampler_code(&sampler) | if packed { TEX_PACKED } else { 0 }
                    );
                    let material = GpuMaterial {
                        color_tex: tex,
                        ..Default::default()
                    };
                    let gpu = util::run_probe(
                        "texture probe",
                        &src,
                        (3, 1),
                        &io,
                        &[
                            // texture_texels and materials (texture.wgsl)
                            (
                                2,
                                3,
                                bytemuck::bytes_of(&material),
                                wgpu::BufferUsages::STORAGE,
                            ),
                            (
                                2,
                                1,
                                bytemuck::cast_slice(&texels),
                                wgpu::BufferUsages::STORAGE,
                            ),
                        ],
                    );
                    for (uv, g) in uvs.iter().zip(&gpu) {
                        let want = map.sample(*uv);
                        let err = (Vec3::new(g[0], g[1], g[2]) - want).abs().max_element();
                        // The same arithmetic up to FMA contraction (~1e-7); a wrong texel moves
                        // a channel by ~0.1–1.
                        assert!(
                        err <= 1e-5,
                        "{sampler:?} {transform:?} packed {packed} uv {uv}: GPU {g:?}, CPU {want} (|Δ| {err:.2e})"
                    );
                    }
                    cases += uvs.len();
                }
            }
        }
    }
    eprintln!("texture probe: {cases} lookups agree (18 samplers, 9 of them transformed; f32, sRGB and raw packed)");
}
