//! Intersector micro-benchmarks: PDM and the tessellated reference on one fixed batch of
//! primary rays of the example sphere (`examples/sphere`, its own glTF camera), single
//! threaded, so the figure is ns per ray per core. Criterion reports the time of the whole
//! batch; docs/benchmarks.md divides by the ray count printed at setup.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec2;
use prismbake::accel::Scene;
use prismbake::asset::{self, Overrides};
use prismbake::render::camera::Camera;
use prismbake::repair::RepairOptions;
use prismbake::trace::pdm::{Pdm, PdmOptions};
use prismbake::trace::reference::Reference;
use prismbake::trace::{Intersector, Ray, RayContext};
use std::hint::black_box;
use std::path::Path;

/// 128 × 128 pixel-centre rays through the scene camera.
const RES: u32 = 128;

fn primary_rays(cam: &Camera) -> Vec<Ray> {
    (0..RES)
        .flat_map(|y| {
            (0..RES).map(move |x| cam.ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), RES, RES))
        })
        .collect()
}

fn trace_batch(isect: &dyn Intersector, rays: &[Ray]) -> usize {
    rays.iter()
        .enumerate()
        .filter(|(i, r)| {
            isect
                .intersect(
                    r,
                    &RayContext {
                        pixel: *i as u32,
                        ..Default::default()
                    },
                )
                .is_some()
        })
        .count()
}

fn intersect(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/sphere/sphere.glb");
    let spec = asset::resolve(&root, &Overrides::default()).expect("examples/sphere resolves");
    let prepared = asset::prepare(&spec, &RepairOptions::default()).expect("examples/sphere bakes");
    let cam = match prepared.mesh.cameras.first().map(|c| &c.camera) {
        Some(c) => Camera::from_scene(c, 1.0),
        None => {
            let (lo, hi) = prepared.table.bounds();
            Camera::frame_bounds(
                lo,
                hi,
                prepared.mesh.up_axis.unwrap_or(prismbake::mesh::UpAxis::Y),
                40.0,
                1.0,
            )
        }
    };
    let rays = primary_rays(&cam);
    let scene = Scene::new(prepared.table, prepared.map);
    let pdm = Pdm::new(&scene, PdmOptions::default());
    let reference = Reference::new(scene.surface(), 2.0);
    let hits = trace_batch(&pdm, &rays);
    eprintln!(
        "sphere: {} prisms, {} rays, {} hit (pdm), {} hit (reference, {} micro-triangles)",
        scene.table.prisms.len(),
        rays.len(),
        hits,
        trace_batch(&reference, &rays),
        reference.triangle_count()
    );

    let mut g = c.benchmark_group("intersect_sphere_primary");
    g.throughput(Throughput::Elements(rays.len() as u64));
    g.sample_size(20);
    g.bench_function("pdm", |b| {
        b.iter(|| black_box(trace_batch(&pdm, black_box(&rays))))
    });
    g.bench_function("reference_k2", |b| {
        b.iter(|| black_box(trace_batch(&reference, black_box(&rays))))
    });
    g.finish();
}

criterion_group!(benches, intersect);
criterion_main!(benches);
