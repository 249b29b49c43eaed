//! Where the leak rays of `prismbake bench` get through: for each leak (the reference hits clear
//! of the ray's end, `bench::LEAK_END_TOL_TEXELS`, the probed method — PDM, or RMIP /
//! nonlinear — nothing), the winding number of the ray's end with respect to the reference's
//! closed micro-mesh (1: inside the solid, so the ray went through the surface; 0: outside,
//! where the displaced surface folds over itself, and the method missed a pair of crossings),
//! the prism the reference hit (inserted crease prism or not, stitched or not), its
//! barycentrics, and what the other methods find on the ray lengthened by 4 texels.
//! With `CONFIRM_K`, a second reference at that density (8: within ~0.01 texel of the
//! canonical surface, against ~0.1 at 2) says whether it also hits before the ray's end: a
//! leak it does not confirm is a fold of the k = 2 tessellation's chords, not of the surface
//! (`bench::confirms_leak`, the bench's own check: only the prisms the ray crosses are
//! tessellated, so it works on any asset).
//! `cargo run --release -p prismbake-core --example leak_probe ASSET [N] [pdm|rmip|nonlinear] [SEED] [CONFIRM_K]`
//! (`bench --seed`, default 0, gives the bench's rays and jitter: the same leaks as the bench;
//! the tests use 0x1ea4)

use prismbake::accel::Scene;
use prismbake::asset::{self, Overrides};
use prismbake::bake::PRISM_INSERTED;
use prismbake::bench::{confirms_leak, leak_rays};
use prismbake::repair::RepairOptions;
use prismbake::trace::nonlinear::{Nonlinear, NonlinearOptions};
use prismbake::trace::pdm::{Pdm, PdmOptions, StepSize};
use prismbake::trace::reference::Reference;
use prismbake::trace::rmip::{Rmip, RmipOptions};
use prismbake::trace::{Intersector, RayContext};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = std::path::PathBuf::from(&args[1]);
    let n: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let spec = asset::resolve(&path, &Overrides::default()).expect("asset resolves");
    let prepared = asset::prepare(&spec, &RepairOptions::default()).expect("asset bakes");
    let scene = Scene::new(prepared.table, prepared.map);
    let reference = Reference::new(scene.surface(), 2.0);
    let pdm = Pdm::new(&scene, PdmOptions::default());
    let fine = Pdm::new(
        &scene,
        PdmOptions {
            dt: StepSize::Auto(0.05),
            jitter: false,
            ..Default::default()
        },
    );
    let rmip = Rmip::new(&scene, RmipOptions::default());
    let nl = Nonlinear::new(&scene, NonlinearOptions::default());
    let probed: &dyn Intersector = match args.get(3).map(String::as_str) {
        Some("rmip") => &rmip,
        Some("nonlinear") => &nl,
        _ => &pdm,
    };
    let seed = args.get(4).map_or(0, |s| {
        let s = s.trim_start_matches("0x");
        u32::from_str_radix(s, 16).expect("SEED in hex")
    });
    let confirm: Option<f32> = args.get(5).map(|k| k.parse().expect("CONFIRM_K a number"));
    let rays = leak_rays(&scene, n, seed);
    let mut confirmed = 0;
    let (mut leaks, mut inserted, mut stitched, mut near_edge, mut inside) = (0, 0, 0, 0, 0);
    for (i, r) in rays.iter().enumerate() {
        // The bench's context for leak ray i (pixel i, the seed).
        let ctx = RayContext {
            pixel: i as u32,
            seed,
            ..Default::default()
        };
        let Some(truth) = reference.intersect(r, &ctx) else {
            continue;
        };
        let p = &scene.table.prisms[truth.prism as usize];
        if truth.t > r.t_max - prismbake::bench::LEAK_END_TOL_TEXELS * p.texel_world
            || probed.intersect(r, &ctx).is_some()
        {
            continue;
        }
        leaks += 1;
        let fine_truth = confirm.map(|k| {
            let budget = prismbake::trace::reference::default_budget();
            confirms_leak(&scene, r, i as u32, k, budget).unwrap_or_else(|why| {
                eprintln!("ray {i}: {why}; not confirmed");
                false
            })
        });
        confirmed += fine_truth.unwrap_or(false) as usize;
        let winding = reference.winding_number(r.at(r.t_max));
        inside += (winding >= 0.5) as usize;
        let ins = p.flags & PRISM_INSERTED != 0;
        let st = scene.stitch().record_index(truth.prism).is_some();
        let edge = truth.bary.min_element() < 0.02;
        inserted += ins as usize;
        stitched += st as usize;
        near_edge += edge as usize;
        let mut longer = *r;
        longer.t_max += 4.0 * p.texel_world;
        let ext = probed.intersect(&longer, &ctx);
        if leaks <= 25 {
            println!(
                "ray {i}: winding {winding:.2} ref prism {} inserted {ins} stitched {st} bary {:.4?} (t_max - t)/texel {:.4} longer ray: probed prism {:?} (t - t_ref)/texel {:?}",
                truth.prism, truth.bary, (r.t_max - truth.t) / p.texel_world,
                ext.map(|h| h.prism), ext.map(|h| (h.t - truth.t) / p.texel_world)
            );
            let t_of =
                |h: Option<prismbake::trace::Hit>| h.map(|h| (h.t - truth.t) / p.texel_world);
            if let Some(hit) = fine_truth {
                println!("    reference k={}: hits before the end: {hit}", args[5]);
            }
            println!(
                "    fine pdm {:?}  rmip {:?}  nonlinear {:?}",
                t_of(fine.intersect(&longer, &ctx)),
                t_of(rmip.intersect(&longer, &ctx)),
                t_of(nl.intersect(&longer, &ctx))
            );
        }
    }
    println!("{leaks} leaks of {n}, {inside} ending inside: {inserted} in inserted prisms, {stitched} in stitched prisms, {near_edge} within 0.02 of an edge");
    if confirm.is_some() {
        println!(
            "{confirmed} of them hit clear of the ray's end by a reference at k = {} (bench::confirms_leak)",
            args[5]
        );
    }
}
