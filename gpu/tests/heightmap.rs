//! The WGSL height lookup is the CPU's: `sample_map` and `sample_grad` evaluated on the adapter
//! at UVs on and off the map (texel centres, texel edges, the map's borders, far outside it)
//! equal `HeightMap::sample` and `HeightMap::sample_grad` under both wrap modes. Breaks if the
//! GPU reads another texel than the CPU anywhere — a wrap at the border, say, which the parity
//! renders see only in the few pixels whose footprint crosses it.

use crate::util;
use glam::Vec2;
use prismbake::rng;
use prismbake::{HeightMap, Wrap};
use prismbake_gpu::layout::{encode_height_map, wrap_code, GpuSceneParams, MapEncoding};
use prismbake_gpu::scene::map_texture;
use prismbake_gpu::shaders;

const PROBE: &str = r#"
// Per case: in = (u, v, _, _), out = (sample_map, sample_grad's value, its gradient).
@group(1) @binding(0) var<storage, read_write> io: array<vec4f>;

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= arrayLength(&io)) {
        return;
    }
    let uv = io[gid.x].xy;
    let sg = sample_grad(uv);
    io[gid.x] = vec4f(sample_map(uv), sg.value, sg.grad);
}
"#;

/// Per case: in = a texel index (row-major), out = the bits of `map_texel` there.
const TEXEL_PROBE: &str = r#"
@group(1) @binding(0) var<storage, read_write> io: array<u32>;

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= arrayLength(&io)) {
        return;
    }
    let i = io[gid.x];
    io[gid.x] = bitcast<u32>(map_texel(i % scene.map_width, i / scene.map_width));
}
"#;

/// Run `probe` (one of the probes above) over `io` with `map` uploaded as `GpuScene::upload`
/// does (`encode_height_map`); returns the probe's output and the encoding.
fn run_map_probe<T: bytemuck::Pod>(
    probe: &str,
    map: &HeightMap,
    io: &[T],
) -> (Vec<T>, MapEncoding) {
    let encoded = encode_height_map(&map.data, map.width);
    let params = GpuSceneParams {
        map_width: map.width,
        map_height: map.height,
        wrap: wrap_code(map.wrap),
        map_encoding: encoded.encoding as u32,
        ..Default::default()
    };
    let src = format!("{}\n{}\n{}", shaders::COMMON, shaders::HEIGHTMAP, probe);
    let texture = map_texture(util::ctx(), &encoded);
    let view = texture.create_view(&Default::default());
    let out = util::run_probe_with_textures(
        "height map probe",
        &src,
        (1, 0),
        io,
        // scene, height_map (common.wgsl's bindings)
        &[(
            0,
            0,
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        )],
        &[(0, 5, &view)],
    );
    (out, encoded.encoding)
}

/// `[sample, sample_grad value, gradient u, gradient v]` per UV, on the adapter.
fn run_probe(map: &HeightMap, uvs: &[Vec2]) -> (Vec<[f32; 4]>, MapEncoding) {
    let io: Vec<[f32; 4]> = uvs.iter().map(|uv| [uv.x, uv.y, 0.0, 0.0]).collect();
    run_map_probe(PROBE, map, &io)
}

/// UVs where a wrong texel shows: every texel centre and texel edge of the map and of the
/// ring of texels around it (the borders, where the wrap modes differ), the corners, then
/// pseudo-random UVs far outside the map.
fn probe_uvs(w: u32, h: u32) -> Vec<Vec2> {
    let mut uvs = Vec::new();
    for j in -4..(2 * h as i32 + 4) {
        for i in -4..(2 * w as i32 + 4) {
            // Half-texel steps: centres ((k + 0.5) / n) and edges (k / n), a little off both.
            let u = i as f32 * 0.5 / w as f32;
            let v = j as f32 * 0.5 / h as f32;
            for off in [0.0, 0.013, -0.007] {
                uvs.push(Vec2::new(u + off / w as f32, v - off / h as f32));
            }
        }
    }
    uvs.extend([
        Vec2::ZERO,
        Vec2::ONE,
        Vec2::new(1.0, 0.0),
        Vec2::new(0.0, 1.0),
    ]);
    let mut s = 7u32;
    let mut next = || {
        s = rng::pcg_hash(s);
        s as f32 / u32::MAX as f32
    };
    for _ in 0..2048 {
        uvs.push(Vec2::new(next() * 40.0 - 20.0, next() * 40.0 - 20.0));
    }
    uvs
}

#[test]
fn height_lookups_read_the_cpus_texels_under_both_wraps() {
    // A non-square map of distinct values, so that any other texel gives another height.
    // Read as f32, and (its 16-bit quantisation) packed two to a word.
    let (w, h) = (7u32, 5u32);
    let data: Vec<f32> = (0..w * h)
        .map(|i| rng::pcg_hash(i + 1) as f32 / u32::MAX as f32)
        .collect();
    let data16: Vec<f32> = data
        .iter()
        .map(|v| (v * 65535.0).round() / 65535.0)
        .collect();
    for (data, encoding, wrap) in [
        (&data, MapEncoding::F32, Wrap::Repeat),
        (&data, MapEncoding::F32, Wrap::Clamp),
        (&data16, MapEncoding::Unorm16, Wrap::Repeat),
        (&data16, MapEncoding::Unorm16, Wrap::Clamp),
    ] {
        let map = HeightMap::new(w, h, data.clone(), wrap);
        let uvs = probe_uvs(w, h);
        let (gpu, got) = run_probe(&map, &uvs);
        assert_eq!(got, encoding);
        let mut worst = 0.0f32;
        for (uv, g) in uvs.iter().zip(&gpu) {
            let value = map.sample(*uv);
            let (value_g, grad) = map.sample_grad(*uv);
            let want = [value, value_g, grad.x, grad.y];
            for k in 0..4 {
                // The same arithmetic up to FMA contraction: ~1e-7 of the values and of the
                // gradient (texel differences × map size); a wrong texel moves them by ~0.1–1.
                let scale = if k < 2 { 1.0 } else { (w.max(h)) as f32 };
                let err = (g[k] - want[k]).abs() / scale;
                worst = worst.max(err);
                assert!(
                    err <= 1e-5,
                    "{wrap:?} uv {uv}: GPU {:?}, CPU {want:?} (component {k})",
                    g
                );
            }
        }
        eprintln!(
            "{wrap:?}, {encoding:?}: {} UVs, largest difference {worst:.1e}",
            uvs.len()
        );
    }
}

#[test]
fn packed_height_maps_give_back_the_cpus_texels_bit_for_bit() {
    // Every 16-bit code as the loader divides it (the shader's decode is exact for each), 8-bit
    // codes (the same quotients), half floats of both signs, and a map only f32 holds; odd
    // widths, so that each row's last word is half used.
    let unorm16: Vec<f32> = (0..=65535u32).map(|q| q as f32 / 65535.0).collect();
    let unorm8: Vec<f32> = (0..=254u32).map(|q| q as f32 / 255.0).collect();
    let halves: Vec<f32> = (0..4097u32)
        .map(|i| {
            let v = (i as f32 - 2048.0) * 0.37;
            f32::from_bits(v.to_bits() & !0x1fff)
        })
        .collect();
    let floats: Vec<f32> = (0..4097u32)
        .map(|i| rng::pcg_hash(i) as f32 / u32::MAX as f32 - 0.5)
        .collect();
    for (values, width, encoding) in [
        (unorm16, 255u32, MapEncoding::Unorm16),
        (unorm8, 17, MapEncoding::Unorm16),
        (halves, 17, MapEncoding::F16),
        (floats, 17, MapEncoding::F32),
    ] {
        // Rows of `width` texels, the values over and over until every one is in.
        let height = (values.len() as u32).div_ceil(width);
        let data: Vec<f32> = (0..(width * height) as usize)
            .map(|i| values[i % values.len()])
            .collect();
        let map = HeightMap::new(width, height, data.clone(), Wrap::Clamp);
        let io: Vec<u32> = (0..data.len() as u32).collect();
        let (gpu, got) = run_map_probe(TEXEL_PROBE, &map, &io);
        assert_eq!(got, encoding);
        let wrong: Vec<(usize, f32, f32)> = data
            .iter()
            .zip(&gpu)
            .enumerate()
            .filter(|(_, (v, g))| v.to_bits() != **g)
            .map(|(i, (v, g))| (i, *v, f32::from_bits(*g)))
            .collect();
        assert!(
            wrong.is_empty(),
            "{encoding:?}: {} of {} texels differ, first {:?}",
            wrong.len(),
            data.len(),
            &wrong[..wrong.len().min(5)]
        );
    }
}
