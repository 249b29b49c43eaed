//! The whole CPU pipeline on a fuzzed mesh, shared by the `pipeline` fuzz target and the
//! corpus replay in `core/tests/fuzz_regressions.rs`: an OBJ that loads is repaired, baked over
//! a fixed 8 × 8 height map with a displacement of 5% of its bounds' diagonal, and traced by PDM
//! (with cells) and the tessellated reference along a 4 × 4 grid of camera rays framing it and
//! along the axes through its centre. Nothing may panic, and every hit must be a hit: a finite
//! distance within the ray, a finite point on it, unit normals, barycentrics that sum to 1, a
//! prism of the table.

use glam::{Vec2, Vec3};
use prismbake::accel::Scene;
use prismbake::bake::{self, BakeOptions};
use prismbake::heightmap::{DisplaceParams, HeightMap, Wrap};
use prismbake::load::{self, MeshOptions};
use prismbake::mesh::UpAxis;
use prismbake::render::camera::Camera;
use prismbake::repair::{self, RepairOptions};
use prismbake::trace::pdm::{Pdm, PdmOptions};
use prismbake::trace::reference::Reference;
use prismbake::trace::{Hit, Intersector, Ray, RayContext};
use std::path::Path;

/// Meshes above this many triangles are skipped: the fuzzer looks for odd geometry, not size.
pub const MAX_TRIANGLES: usize = 64;

/// The mesh at `path` loaded, repaired and baked as `check` traces it; `None` where it does
/// not load or is skipped.
pub fn scene(path: &Path) -> Option<Scene> {
    let mesh = load::load_mesh(path, &MeshOptions::default()).ok()?;
    if mesh.triangle_count() == 0 || mesh.triangle_count() > MAX_TRIANGLES {
        return None;
    }
    // UVs spanning more than 8 periods of the 8 × 8 map make the reference big by design
    // (each face, crease strips included, an n × n grid for n = 2 × its longest edge's
    // texels: 51 periods took 6 s and 1.4 GB for two triangles): size, not oddity.
    let (uv_lo, uv_hi) = mesh
        .uvs
        .iter()
        .fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(lo, hi), &t| {
            (lo.min(t), hi.max(t))
        });
    if (uv_hi - uv_lo).max_element() > 8.0 {
        return None;
    }
    let (mesh, _) = repair::repair(mesh, &RepairOptions::default());
    let (lo, hi) = mesh.bounds();
    let diagonal = (hi - lo).length();
    if !diagonal.is_finite() {
        return None;
    }
    let heights = (0..64).map(|i| ((i * 37) % 64) as f32 / 63.0).collect();
    let map = HeightMap::new(8, 8, heights, Wrap::Repeat);
    let params = DisplaceParams {
        scale: 0.05 * diagonal,
        midlevel: 0.5,
    };
    Some(Scene::new(
        bake::bake(&mesh, &map, &BakeOptions { params }),
        map,
    ))
}

/// The number of hits checked (0 where the mesh did not load or was skipped).
pub fn check(path: &Path) -> usize {
    let Some(scene) = scene(path) else {
        return 0;
    };
    let prisms = scene.table.prisms.len() as u32;
    let (lo, hi) = scene.table.bounds();
    let pdm = Pdm::new(&scene, PdmOptions::default());
    let reference = Reference::new(scene.surface(), 2.0);
    let mut rays = Vec::new();
    if (hi - lo).is_finite() {
        let raster = Camera::frame_bounds(lo, hi, UpAxis::Y, 40.0, 1.0).raster(4, 4);
        for y in 0..4 {
            for x in 0..4 {
                rays.push(raster.ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5)));
            }
        }
        let centre = (lo + hi) * 0.5;
        let reach = (hi - lo).length().max(1e-6);
        for axis in [
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            Vec3::NEG_X,
            Vec3::NEG_Y,
            Vec3::NEG_Z,
        ] {
            rays.push(Ray::new(centre - axis * reach, axis));
        }
    }
    let mut hits = 0;
    for (i, ray) in rays.iter().enumerate() {
        let ctx = RayContext {
            pixel: i as u32,
            ..Default::default()
        };
        for isect in [&pdm as &dyn Intersector, &reference] {
            if let Some(hit) = isect.intersect(ray, &ctx) {
                check_hit(isect.name(), ray, &hit, prisms);
                hits += 1;
            }
            let _ = isect.occluded(ray, &ctx);
        }
    }
    hits
}

fn check_hit(method: &str, ray: &Ray, hit: &Hit, prisms: u32) {
    let unit = |n: Vec3| (n.length() - 1.0).abs() < 1e-3;
    assert!(
        hit.t.is_finite() && hit.t >= ray.t_min && hit.t <= ray.t_max,
        "{method}: t {} outside the ray's [{}, {}]",
        hit.t,
        ray.t_min,
        ray.t_max
    );
    assert!(
        hit.position.is_finite(),
        "{method}: position {}",
        hit.position
    );
    assert!(
        unit(hit.geometric_normal),
        "{method}: geometric normal {}",
        hit.geometric_normal
    );
    assert!(
        unit(hit.shading_normal),
        "{method}: shading normal {}",
        hit.shading_normal
    );
    assert!(
        hit.bary.is_finite() && (hit.bary.element_sum() - 1.0).abs() < 1e-3,
        "{method}: barycentrics {}",
        hit.bary
    );
    assert!(
        hit.prism < prisms,
        "{method}: prism {} of {prisms}",
        hit.prism
    );
}
