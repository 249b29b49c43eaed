//! One thread, one batch of primary rays through an example asset's camera (or a framing of
//! its bounds): ns per ray for PDM and the tessellated reference, from the same run. For the
//! figures in docs/benchmarks.md and for profiling (`valgrind --tool=callgrind` on a small
//! `RES`); benches/intersect.rs is the criterion version at 128².
//!
//! `cargo run --release -p prismbake-core --example trace_primary [ASSET] [RES] [pdm|whole|all|both|reference|rmip]`
//! (`PRISMBAKE_SPLIT=1` also times the rays each method hits and those it misses apart)

use glam::Vec2;
use prismbake::accel::Scene;
use prismbake::asset::{self, Overrides};
use prismbake::render::camera::Camera;
use prismbake::repair::RepairOptions;
use prismbake::trace::pdm::{Pdm, PdmOptions};
use prismbake::trace::reference::Reference;
use prismbake::trace::rmip::{Rmip, RmipOptions};
use prismbake::trace::{Intersector, Ray, RayContext};
use std::time::Instant;

/// Times `rays` (indexed by pixel) one after another; returns hits, steps, seconds.
fn trace_indexed(isect: &dyn Intersector, rays: &[(u32, Ray)]) -> (usize, u64, f64) {
    let t0 = Instant::now();
    let mut hits = 0;
    let mut steps = 0u64;
    for &(pixel, ref r) in rays {
        let ctx = RayContext {
            pixel,
            ..Default::default()
        };
        if let Some(h) = isect.intersect(r, &ctx) {
            hits += 1;
            steps += h.steps as u64;
        }
    }
    (hits, steps, t0.elapsed().as_secs_f64())
}

fn trace(isect: &dyn Intersector, rays: &[Ray]) -> (usize, u64, f64) {
    let indexed: Vec<(u32, Ray)> = rays
        .iter()
        .enumerate()
        .map(|(i, r)| (i as u32, *r))
        .collect();
    let result = trace_indexed(isect, &indexed);
    if std::env::var_os("PRISMBAKE_SPLIT").is_some() {
        // Where the time goes: the rays this method hits and those it misses, timed apart.
        let (hit, miss): (Vec<_>, Vec<_>) = indexed.into_iter().partition(|(pixel, r)| {
            let ctx = RayContext {
                pixel: *pixel,
                ..Default::default()
            };
            isect.intersect(r, &ctx).is_some()
        });
        let (_, _, hit_secs) = trace_indexed(isect, &hit);
        let (_, _, miss_secs) = trace_indexed(isect, &miss);
        println!(
            "  {}: {} hit rays {:.0} ns each, {} miss rays {:.0} ns each ({:.0} + {:.0} ns per ray of the batch)",
            isect.name(),
            hit.len(),
            hit_secs * 1e9 / hit.len().max(1) as f64,
            miss.len(),
            miss_secs * 1e9 / miss.len().max(1) as f64,
            hit_secs * 1e9 / rays.len() as f64,
            miss_secs * 1e9 / rays.len() as f64,
        );
    }
    result
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let asset_path = args
        .get(1)
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| root.join("examples/sphere/sphere.glb"));
    let res: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(512);
    let which = args.get(3).map(String::as_str).unwrap_or("both");
    let spec = asset::resolve(&asset_path, &Overrides::default()).expect("asset resolves");
    let prepared = asset::prepare(&spec, &RepairOptions::default()).expect("asset bakes");
    let cam = match prepared.mesh.cameras.first().map(|c| &c.camera) {
        Some(c) => Camera::from_scene(c, 1.0),
        None => {
            let (lo, hi) = prepared.table.bounds();
            let up = prepared.mesh.up_axis.unwrap_or(prismbake::mesh::UpAxis::Y);
            Camera::frame_bounds(lo, hi, up, 40.0, 1.0)
        }
    };
    let raster = cam.raster(res, res);
    let rays: Vec<Ray> = (0..res)
        .flat_map(|y| (0..res).map(move |x| (x, y)))
        .map(|(x, y)| raster.ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5)))
        .collect();
    let scene = Scene::new(prepared.table, prepared.map);
    let n = rays.len() as f64;
    let pdm_variants: &[(&str, bool)] = match which {
        "reference" | "rmip" => &[],
        "pdm" => &[("cells", true)],
        "whole" => &[("whole prisms", false)],
        _ => &[("cells", true), ("whole prisms", false)],
    };
    for &(label, cells) in pdm_variants {
        let t_build = Instant::now();
        let pdm = Pdm::new(
            &scene,
            PdmOptions {
                cells,
                ..PdmOptions::default()
            },
        );
        let build = t_build.elapsed().as_secs_f64();

        let (hits, steps, secs) = trace(&pdm, &rays);
        println!(
            "pdm ({label}, built in {:.0} ms, {} B/tri): {} rays, {hits} hit, {:.1} steps/hit, {:.0} ns/ray, {:.3} Mray/s (one thread)",
            build * 1e3,
            pdm.memory_bytes() / scene.table.prisms.len().max(1),
            rays.len(),
            steps as f64 / hits.max(1) as f64,
            secs * 1e9 / n,
            n / secs / 1e6
        );
    }
    if which == "rmip" {
        let t_build = Instant::now();
        let rmip = Rmip::new(&scene, RmipOptions::default());
        let build = t_build.elapsed().as_secs_f64();
        let (hits, steps, secs) = trace(&rmip, &rays);
        println!(
            "rmip (default, built in {:.0} ms): {hits} hit, {:.1} steps/hit, {:.0} ns/ray, {:.3} Mray/s (one thread)",
            build * 1e3,
            steps as f64 / hits.max(1) as f64,
            secs * 1e9 / n,
            n / secs / 1e6
        );
    }
    if which == "both" || which == "reference" {
        let reference = Reference::new(scene.surface(), 2.0);
        let (hits, _, secs) = trace(&reference, &rays);
        println!(
            "reference k=2 ({} micro-triangles): {hits} hit, {:.0} ns/ray, {:.3} Mray/s (one thread)",
            reference.triangle_count(),
            secs * 1e9 / n,
            n / secs / 1e6
        );
    }
}
