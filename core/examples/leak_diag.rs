//! Where an asset's leak rays go through: `leak_diag ASSET [N]` traces `N` leak rays
//! (`bench::leak_rays`, the bench's seed) with the reference and PDM (default settings), and
//! prints each leak (the reference hits clear of the ray's end, PDM nothing): the winding
//! number of the ray's end (1: inside the solid, so the ray went through the surface; 0: the
//! end is outside, where the displaced surface folds over itself, and PDM missed a pair of
//! crossings), the reference's prism, its flags, λ range and texel size, where it hits, and
//! whether PDM at a tenth of the step finds it.
//!
//! `cargo run --release -p prismbake-core --example leak_diag examples/rock/rock.glb 1000000`
use prismbake::accel::Scene;
use prismbake::asset::{self, Overrides};
use prismbake::bench::leak_rays;
use prismbake::repair::RepairOptions;
use prismbake::trace::pdm::{Pdm, PdmOptions, StepSize};
use prismbake::trace::reference::Reference;
use prismbake::trace::{Intersector, RayContext};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let Some(path) = args.get(1) else {
        eprintln!("usage: leak_diag ASSET [RAYS]");
        std::process::exit(2);
    };
    let spec = asset::resolve(std::path::Path::new(path), &Overrides::default())
        .unwrap_or_else(|e| panic!("{path}: {e}"));
    let n: usize = args
        .get(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000_000);
    let prepared =
        asset::prepare(&spec, &RepairOptions::default()).unwrap_or_else(|e| panic!("{path}: {e}"));
    let scene = Scene::new(prepared.table, prepared.map);
    let rays = leak_rays(&scene, n, 0x1ea4);
    let reference = Reference::new(scene.surface(), 2.0);
    let pdm = Pdm::new(&scene, PdmOptions::default());
    let fine = Pdm::new(
        &scene,
        PdmOptions {
            dt: StepSize::Auto(0.05),
            ..PdmOptions::default()
        },
    );
    let mut leaks = 0;
    for (i, r) in rays.iter().enumerate() {
        let ctx = RayContext {
            pixel: i as u32,
            ..Default::default()
        };
        let Some(truth) = reference.intersect(r, &ctx) else {
            continue;
        };
        let p = &scene.table.prisms[truth.prism as usize];
        if truth.t > r.t_max - prismbake::bench::LEAK_END_TOL_TEXELS * p.texel_world {
            continue;
        }
        if pdm.intersect(r, &ctx).is_some() {
            continue;
        }
        leaks += 1;
        let f = fine.intersect(r, &ctx);
        let cosang = r.dir.dot(truth.geometric_normal).abs();
        println!(
            "ray {i}: winding {:.2} ref prism {} flags {:#x} λ [{:.4},{:.4}] texel {:.4} bary {:.3?} t {:.4} (end {:.4}) |cos| {:.3} fine: {:?}",
            reference.winding_number(r.at(r.t_max)), truth.prism, p.flags, p.lambda_lo, p.lambda_hi, p.texel_world, truth.bary, truth.t, r.t_max, cosang,
            f.map(|h| (h.prism, h.t))
        );
    }
    println!("{leaks} leaks in {n} rays");
}
