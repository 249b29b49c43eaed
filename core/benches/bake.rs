//! Bake of a 4096² map over an 8064-triangle UV sphere whose UVs cover the whole map: the
//! footprint scan reads every texel about twice. Target (docs/benchmarks.md): ≤ 1 s on two
//! cores in release. Peak memory is measured separately (`examples/bake_memory.rs`), since
//! criterion's own allocations would blur a VmHWM reading.

mod common;

use criterion::{criterion_group, criterion_main, Criterion};
use glam::Vec2;
use prismbake::bake::{bake, footprint_range, BakeOptions};
use prismbake::heightmap::{DisplaceParams, HeightMap};
use std::hint::black_box;

/// The scan as it was before the row-slice rewrite (wrap applied per texel through
/// `HeightMap::texel_range`), kept here only as the baseline the numbers are compared with.
fn footprint_range_per_texel(map: &HeightMap, uv: &[Vec2; 3]) -> (f32, f32) {
    let p = uv.map(|t| map.texel_coords(t));
    let ymin = p.iter().map(|q| q.y).fold(f32::INFINITY, f32::min);
    let ymax = p.iter().map(|q| q.y).fold(f32::NEG_INFINITY, f32::max);
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for j in (ymin - 0.5).floor() as i64..=(ymax - 0.5).floor() as i64 + 1 {
        let (y0, y1) = (j as f32 - 0.5, j as f32 + 1.5);
        let (mut x0, mut x1) = (f32::INFINITY, f32::NEG_INFINITY);
        for i in 0..3 {
            let (a, b) = (p[i], p[(i + 1) % 3]);
            if a.y >= y0 && a.y <= y1 {
                (x0, x1) = (x0.min(a.x), x1.max(a.x));
            }
            for y in [y0, y1] {
                if (a.y - y) * (b.y - y) < 0.0 {
                    let x = a.x + (b.x - a.x) * (y - a.y) / (b.y - a.y);
                    (x0, x1) = (x0.min(x), x1.max(x));
                }
            }
        }
        if x0 <= x1 {
            let (a, b) = map.texel_range(
                (x0 - 0.5).floor() as i64,
                (x1 - 0.5).floor() as i64 + 1,
                j,
                j,
            );
            (lo, hi) = (lo.min(a), hi.max(b));
        }
    }
    (lo, hi)
}

fn bake_4096(c: &mut Criterion) {
    let mesh = common::uv_sphere(64, 64);
    let map = common::relief_map(4096);
    let opts = BakeOptions {
        params: DisplaceParams {
            scale: 0.05,
            midlevel: 0.5,
        },
    };
    let mut g = c.benchmark_group("bake");
    g.sample_size(10);
    g.bench_function(
        format!("4096x4096 map, {} triangles", mesh.triangle_count()),
        |b| b.iter(|| black_box(bake(black_box(&mesh), black_box(&map), &opts))),
    );
    // One large footprint (a pole triangle: 64 texels wide, 64 tall) without rayon.
    let t = mesh.triangle_count() / 2;
    let uv = mesh.corner_uvs(t);
    g.bench_function("footprint_range, one 64x64-texel triangle", |b| {
        b.iter(|| black_box(footprint_range(black_box(&map), black_box(&uv))))
    });
    g.bench_function(
        "footprint_range, one 64x64-texel triangle, per-texel baseline",
        |b| b.iter(|| black_box(footprint_range_per_texel(black_box(&map), black_box(&uv)))),
    );
    g.finish();
}

criterion_group!(benches, bake_4096);
criterion_main!(benches);
