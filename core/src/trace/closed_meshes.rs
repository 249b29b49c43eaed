//! Every method on the closed example meshes: the sphere (UV seams stitched, a pole fan) and
//! the torus (period seams on both axes), 10⁵ rays each from outside, aimed at points half a
//! texel below the lowest the surface can go (`bench::leak_rays`), which lie inside the solid.
//! A ray that reaches its end without a hit has passed through the displaced surface.
//!
//! The PDM, RMIP and nonlinear tests on the jittered icosphere cover the constructions one by
//! one; this covers the assets users see, with their seams, wrap and map resolutions, and holds
//! every method to the same count, so the speed comparison in `bench` is between methods that
//! are equally watertight.

use super::nonlinear::{Nonlinear, NonlinearOptions, Precision};
use super::pdm::{Pdm, PdmOptions};
use super::rmip::{Rmip, RmipOptions};
use super::{Intersector, RayContext};
use crate::bench::leak_rays;
use rayon::prelude::*;

/// Rays per asset (the stress size; the bench runs 10⁶).
const RAYS: usize = 100_000;

fn through(isect: &dyn Intersector, rays: &[super::Ray]) -> Vec<usize> {
    rays.par_iter()
        .enumerate()
        .filter(|(i, r)| {
            let ctx = RayContext {
                pixel: *i as u32,
                ..Default::default()
            };
            isect.intersect(r, &ctx).is_none()
        })
        .map(|(i, _)| i)
        .collect()
}

/// Every method, by name, on one scene.
fn methods(scene: &crate::accel::Scene) -> Vec<(&'static str, Box<dyn Intersector + '_>)> {
    vec![
        ("pdm", Box::new(Pdm::new(scene, PdmOptions::default()))),
        (
            "pdm whole prisms",
            Box::new(Pdm::new(
                scene,
                PdmOptions {
                    cells: false,
                    ..Default::default()
                },
            )),
        ),
        ("rmip", Box::new(Rmip::new(scene, RmipOptions::default()))),
        (
            "nonlinear f32",
            Box::new(Nonlinear::new(scene, NonlinearOptions::default())),
        ),
        (
            "nonlinear f64",
            Box::new(Nonlinear::new(
                scene,
                NonlinearOptions {
                    precision: Precision::F64,
                    ..Default::default()
                },
            )),
        ),
    ]
}

#[test]
fn no_method_lets_a_ray_through_the_closed_example_meshes() {
    for name in ["sphere/sphere.glb", "torus/torus.obj"] {
        let (scene, reference) = crate::test_util::example_with_reference(name);
        let rays = leak_rays(scene, RAYS, 0x1ea4);
        assert_eq!(rays.len(), RAYS);
        let methods = methods(scene);
        let all = std::iter::once(("reference", reference as &dyn Intersector))
            .chain(methods.iter().map(|(label, m)| (*label, m.as_ref())));
        for (label, isect) in all {
            let passed = through(isect, &rays);
            eprintln!("{name} {label}: {} of {RAYS} rays through", passed.len());
            assert!(
                passed.is_empty(),
                "{name} {label}: {} rays pass through the closed surface, first {:?}",
                passed.len(),
                &passed[..passed.len().min(8)]
            );
        }
    }
}

/// The rock: closed by position, but its displaced fin folds over itself (the flange is 0.02
/// thick at its root under a relief of ±0.025), so some leak rays end outside the solid and
/// the reference itself lets 3% of them through. A ray counts here only if its end is inside
/// the reference's closed surface (`Reference::winding_number`), the reference hits the
/// surface clear of the end (`bench::LEAK_END_TOL_TEXELS`, as the bench counts leaks) and the
/// method hits nothing before it.
///
/// Not yet 0. Ray 13140 grazes the surface (|cos| 0.1) and the reference hits it 0.45 texel
/// before its end, 0.045 texel from the surface along the normal, below the reference's own
/// chord error: every method agrees that it passes. RMIP and the nonlinear method also let
/// 29332 through, which crosses a crease strip's sliver below its base (λ < 0, where the
/// strips' level triangles fold over).
///
/// PDM is held to 1 (13140). It let 5 through before the strips' step followed their rung
/// width (`bake::inserted_texel_world`), and 2 (1281, 29332: the same slivers) until its march
/// interpolated the barycentrics homogeneously across the strips' `λ = 0` pole
/// (`pdm::inside_span`), looked for the inside between a sample just outside the triangle and
/// one far outside, and solved them from the level triangle's widest corner.
fn rock_through_bound(method: &str) -> usize {
    match method {
        "reference" => 0,
        "pdm" | "pdm whole prisms" => 1,
        _ => 2,
    }
}

#[test]
fn rays_into_the_rock_are_stopped() {
    let (scene, reference) = crate::test_util::example_with_reference("rock/rock.glb");
    let rays = leak_rays(scene, RAYS, 0x1ea4);
    let counted = |i: &usize| {
        let r = &rays[*i];
        let ctx = RayContext {
            pixel: *i as u32,
            ..Default::default()
        };
        reference.intersect(r, &ctx).is_some_and(|h| {
            let texel = scene.table.prisms[h.prism as usize].texel_world;
            h.t <= r.t_max - crate::bench::LEAK_END_TOL_TEXELS * texel
        }) && reference.winding_number(r.at(r.t_max)) >= 0.5
    };
    let methods = methods(scene);
    let all = std::iter::once(("reference", reference as &dyn Intersector))
        .chain(methods.iter().map(|(label, m)| (*label, m.as_ref())));
    for (label, isect) in all {
        let leaked: Vec<usize> = through(isect, &rays).into_iter().filter(counted).collect();
        eprintln!(
            "rock {label}: {} of {RAYS} rays into the solid go through: {leaked:?}",
            leaked.len()
        );
        assert!(
            leaked.len() <= rock_through_bound(label),
            "rock {label}: {} rays into the solid go through: {leaked:?}",
            leaked.len()
        );
    }
}
