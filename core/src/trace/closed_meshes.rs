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

#[test]
fn no_method_lets_a_ray_through_the_closed_example_meshes() {
    for name in ["sphere/sphere.glb", "torus/torus.obj"] {
        let (scene, reference) = crate::test_util::example_with_reference(name);
        let rays = leak_rays(scene, RAYS, 0x1ea4);
        assert_eq!(rays.len(), RAYS);
        let methods: Vec<(&str, Box<dyn Intersector + '_>)> = vec![
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
        ];
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
