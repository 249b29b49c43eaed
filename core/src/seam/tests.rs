//! UV seams: detection, the stitched surface's continuity and bounds, leaks open vs stitched,
//! and seam-safe maps. Fixtures: a smooth-normal cube with one UV island per face (every cube
//! edge a seam, three islands at each corner) and a closed cylinder with smooth rims (a side
//! island whose two ends meet on a seam line, two cap islands meeting it along the rims).

use super::*;
use crate::accel::Scene;
use crate::bake::{bake, BakeOptions};
use crate::canonical::{surface_point, PrismGeom};
use crate::heightmap::HeightMap;
use crate::mesh::BaseMesh;
use crate::render::camera::Camera;
use crate::render::{render_aovs, RenderSettings};
use crate::repair::{repair, RepairOptions};
use crate::test_util::{leaks, Rng};
use crate::trace::nonlinear::{Nonlinear, NonlinearOptions};
use crate::trace::pdm::{Pdm, PdmOptions};
use crate::trace::reference::Reference;
use crate::trace::rmip::{Rmip, RmipOptions};
use crate::trace::Ray;

const W: u32 = 96;
const H: u32 = 64;
const SCALE: f32 = 0.1;

/// A UV island: texel rectangle `[x0, x1) × [row0, row1)` of the 96 × 64 atlas.
type Island = (f32, f32, f32, f32);

fn uv_in(island: Island, s: f32, t: f32) -> Vec2 {
    // 2 texels of padding inside the island's rectangle.
    let (x0, r0, x1, r1) = island;
    let x = x0 + 2.0 + s * (x1 - x0 - 4.0);
    let row = r0 + 2.0 + t * (r1 - r0 - 4.0);
    Vec2::new(x / W as f32, 1.0 - row / H as f32)
}

fn finish(
    mut positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    mut tris: Vec<[u32; 3]>,
) -> BaseMesh {
    // Convex shapes around the origin: wind every face outwards.
    for t in &mut tris {
        let p = t.map(|i| positions[i as usize]);
        if (p[1] - p[0]).cross(p[2] - p[0]).dot(p[0] + p[1] + p[2]) < 0.0 {
            t.swap(1, 2);
        }
    }
    positions.shrink_to_fit();
    crate::test_util::fixture_mesh(positions, normals, uvs, tris)
}

const CUBE_ISLANDS: [Island; 6] = [
    (0.0, 0.0, 32.0, 32.0),
    (32.0, 0.0, 64.0, 32.0),
    (64.0, 0.0, 96.0, 32.0),
    (0.0, 32.0, 32.0, 64.0),
    (32.0, 32.0, 64.0, 64.0),
    (64.0, 32.0, 96.0, 64.0),
];

/// The cube [-1, 1]³, `n × n` quads a face, normals `normalize(position)` (smooth: no hard
/// edge), one UV island per face: 12·n seam edges, three islands at every corner.
fn seamed_cube(n: u32) -> BaseMesh {
    let (mut pos, mut nrm, mut uvs, mut tris) = (vec![], vec![], vec![], vec![]);
    let e = [Vec3::X, Vec3::Y, Vec3::Z];
    for (face, &island) in CUBE_ISLANDS.iter().enumerate() {
        let (a, sign) = (face / 2, if face % 2 == 0 { 1.0 } else { -1.0 });
        let (t1, t2) = (e[(a + 1) % 3], e[(a + 2) % 3]);
        let base = pos.len() as u32;
        for j in 0..=n {
            for i in 0..=n {
                let (s, t) = (i as f32 / n as f32, j as f32 / n as f32);
                let p = e[a] * sign + t1 * (2.0 * s - 1.0) + t2 * (2.0 * t - 1.0);
                pos.push(p);
                nrm.push(p.normalize());
                uvs.push(uv_in(island, s, t));
            }
        }
        let at = |i: u32, j: u32| base + j * (n + 1) + i;
        for j in 0..n {
            for i in 0..n {
                tris.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                tris.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
    }
    finish(pos, nrm, uvs, tris)
}

const CYLINDER_ISLANDS: [Island; 3] = [
    (0.0, 0.0, 64.0, 32.0),
    (64.0, 0.0, 96.0, 32.0),
    (0.0, 32.0, 32.0, 64.0),
];

/// A closed cylinder (radius 1, y in [-1, 1]), `seg` segments, `rows` rows; rim normals are
/// shared by side and caps (smooth), so the rims and the side's `u` ends are UV seams:
/// `rows + 2·seg` seam edges.
fn seamed_cylinder(seg: u32, rows: u32) -> BaseMesh {
    let (mut pos, mut nrm, mut uvs, mut tris) = (vec![], vec![], vec![], vec![]);
    let radial = |j: u32| {
        let a = std::f32::consts::TAU * j as f32 / seg as f32;
        Vec3::new(a.cos(), 0.0, a.sin())
    };
    let rim_normal = |j: u32, y: f32| (radial(j) + Vec3::Y * y).normalize();
    for r in 0..=rows {
        for j in 0..=seg {
            let y = 2.0 * r as f32 / rows as f32 - 1.0;
            pos.push(radial(j % seg) + Vec3::Y * y);
            nrm.push(if r == 0 || r == rows {
                rim_normal(j % seg, y)
            } else {
                radial(j % seg)
            });
            uvs.push(uv_in(
                CYLINDER_ISLANDS[0],
                j as f32 / seg as f32,
                r as f32 / rows as f32,
            ));
        }
    }
    let at = |j: u32, r: u32| r * (seg + 1) + j;
    for r in 0..rows {
        for j in 0..seg {
            tris.push([at(j, r), at(j + 1, r), at(j + 1, r + 1)]);
            tris.push([at(j, r), at(j + 1, r + 1), at(j, r + 1)]);
        }
    }
    for (cap, y) in [(1usize, 1.0f32), (2, -1.0)] {
        let centre = pos.len() as u32;
        pos.push(Vec3::Y * y);
        nrm.push(Vec3::Y * y);
        uvs.push(uv_in(CYLINDER_ISLANDS[cap], 0.5, 0.5));
        let mid = pos.len() as u32;
        for j in 0..seg {
            let p = radial(j) * 0.5 + Vec3::Y * y;
            pos.push(p);
            nrm.push(Vec3::Y * y);
            uvs.push(uv_in(
                CYLINDER_ISLANDS[cap],
                0.5 + 0.25 * p.x,
                0.5 + 0.25 * p.z,
            ));
        }
        let ring = pos.len() as u32;
        for j in 0..seg {
            let p = radial(j) + Vec3::Y * y;
            pos.push(p);
            nrm.push(rim_normal(j, y));
            uvs.push(uv_in(
                CYLINDER_ISLANDS[cap],
                0.5 + 0.5 * p.x,
                0.5 + 0.5 * p.z,
            ));
        }
        for j in 0..seg {
            let k = (j + 1) % seg;
            tris.push([centre, mid + j, mid + k]);
            tris.push([mid + j, ring + j, ring + k]);
            tris.push([mid + j, ring + k, mid + k]);
        }
    }
    finish(pos, nrm, uvs, tris)
}

/// A 96 × 64 clamp-wrapped map: a non-periodic relief (so islands disagree at every seam),
/// or with `seam_safe` the same relief faded to the midlevel within 6 texels of each
/// island's border (equal on both sides of every seam, out to a few texels). `discs`: islands
/// whose border is the circle a cylinder cap's rim maps to.
fn island_map(islands: &[Island], discs: &[usize], seam_safe: bool) -> HeightMap {
    let data = (0..W * H)
        .map(|i| {
            let (x, row) = ((i % W) as f32 + 0.5, (i / W) as f32 + 0.5);
            let relief = 0.35 * (0.37 * x + 0.11 * row).sin() * (0.23 * row - 0.05 * x).cos();
            let noise = ((crate::rng::pcg_hash(i ^ 0xcafe) >> 8) as f32 / 16_777_216.0 - 0.5) * 0.1;
            let mut h = relief + noise;
            if seam_safe {
                let d = islands
                    .iter()
                    .enumerate()
                    .filter(|(_, &(x0, r0, x1, r1))| x >= x0 && x < x1 && row >= r0 && row < r1)
                    .map(|(k, &(x0, r0, x1, r1))| {
                        if discs.contains(&k) {
                            // The rim circle: half the padded island's width around its centre.
                            let c = Vec2::new(0.5 * (x0 + x1), 0.5 * (r0 + r1));
                            0.5 * (x1 - x0 - 4.0) - (Vec2::new(x, row) - c).length()
                        } else {
                            (x - x0).min(x1 - x).min(row - r0).min(r1 - row)
                        }
                    })
                    .fold(0.0f32, f32::max);
                h *= ((d - 6.0) / 4.0).clamp(0.0, 1.0);
            }
            0.5 + h
        })
        .collect();
    HeightMap::new(W, H, data, Wrap::Clamp)
}

fn scene_of(mesh: BaseMesh, map: HeightMap) -> Scene {
    let (mesh, _) = repair(mesh, &RepairOptions::default());
    let params = DisplaceParams {
        scale: SCALE,
        midlevel: 0.5,
    };
    Scene::new(bake(&mesh, &map, &BakeOptions { params }), map)
}

fn cube(seam_safe: bool) -> Scene {
    scene_of(seamed_cube(4), island_map(&CUBE_ISLANDS, &[], seam_safe))
}

fn cylinder(seam_safe: bool) -> Scene {
    scene_of(
        seamed_cylinder(24, 4),
        island_map(&CYLINDER_ISLANDS, &[1, 2], seam_safe),
    )
}

/// Barycentrics of prism `faces[side]` at fraction `s` along the seam (from side 0's first
/// corner).
fn seam_bary(seam: &SeamEdge, side: usize, s: f32) -> Vec3 {
    let mut b = [0.0; 3];
    let [i, j] = seam.corners(side);
    if side == 0 {
        (b[i], b[j]) = (1.0 - s, s);
    } else {
        (b[j], b[i]) = (1.0 - s, s);
    }
    Vec3::from(b)
}

fn position(scene: &Scene, prism: u32, b: Vec3) -> Vec3 {
    let g = PrismGeom::new(&scene.table, &scene.table.prisms[prism as usize]);
    surface_point(&g, &scene.prism_displacement(prism), b).position
}

/// Largest distance between the two sides' surface points along every seam edge (inside it:
/// at a vertex where seams of different jumps meet the stitched surface pinches, and the
/// vertex itself has no one height).
fn max_seam_gap(scene: &Scene) -> f32 {
    let mut gap = 0.0f32;
    for seam in &scene.table.seams {
        for k in 1..32 {
            let s = k as f32 / 32.0;
            let a = position(scene, seam.faces[0], seam_bary(seam, 0, s));
            let b = position(scene, seam.faces[1], seam_bary(seam, 1, s));
            gap = gap.max((a - b).length());
        }
    }
    gap
}

#[test]
fn seams_are_found_on_the_cube_and_the_cylinder() {
    // Breaks if repair stops pairing edges by position and normal (or pairs hard edges).
    for (mesh, want) in [
        (seamed_cube(4), 12 * 4),
        (seamed_cylinder(24, 4), 4 + 2 * 24),
    ] {
        let (out, report) = repair(mesh, &RepairOptions::default());
        assert_eq!(out.seams.len(), want, "{}", report.to_text());
        assert_eq!(report.uv_seam_edges, want);
        assert_eq!(report.seams.len(), want);
        assert!(
            report.stitched_edges.is_empty(),
            "smooth normals: no hard edge"
        );
        for seam in &out.seams {
            let [i0, j0] = seam.corners(0);
            let [i1, j1] = seam.corners(1);
            let (t0, t1) = (
                out.triangles[seam.faces[0] as usize],
                out.triangles[seam.faces[1] as usize],
            );
            // Same positions and normals bit for bit (twins snapped), other UVs.
            for (a, b) in [(t0[i0], t1[j1]), (t0[j0], t1[i1])] {
                assert_eq!(out.positions[a as usize], out.positions[b as usize]);
                assert_eq!(out.normals[a as usize], out.normals[b as usize]);
            }
            assert!(
                out.uvs[t0[i0] as usize] != out.uvs[t1[j1] as usize]
                    || out.uvs[t0[j0] as usize] != out.uvs[t1[i1] as usize]
            );
        }
    }
}

#[test]
fn stitched_surface_is_continuous_across_every_edge() {
    // Breaks if the two sides of a seam do not agree on one height, or if stitching changes
    // a face's height on an edge that is not its seam (a crack between neighbours of one
    // island): "continuous to 1e-5 of the object size", and the open surface really is torn.
    for (name, scene) in [("cube", cube(false)), ("cylinder", cylinder(false))] {
        let (lo, hi) = scene.table.bounds();
        let size = (hi - lo).length();
        assert!(!scene.stitch().is_empty(), "{name}: the jump map stitches");
        let stitched = max_seam_gap(&scene);
        assert!(
            stitched <= 1e-5 * size,
            "{name}: seam gap {stitched} of {size}"
        );
        let open = scene.table.clone();
        let open = Scene::new(open, scene.map.clone()).with_seam_mode(SeamMode::Open);
        assert!(
            max_seam_gap(&open) > 1e-2 * SCALE,
            "{name}: the open surface tears"
        );
        // Every edge shared by vertex index (no seam) must agree on both sides, stitched or not.
        let mut by_edge: std::collections::HashMap<(u32, u32), Vec<(u32, usize)>> =
            Default::default();
        for (i, p) in scene.table.prisms.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (p.tri[(k + 1) % 3], p.tri[(k + 2) % 3]);
                by_edge
                    .entry((a.min(b), a.max(b)))
                    .or_default()
                    .push((i as u32, k));
            }
        }
        let mut worst = 0.0f32;
        for ((a, b), faces) in &by_edge {
            if faces.len() != 2 {
                continue;
            }
            for step in 1..32 {
                let s = step as f32 / 32.0;
                let pts: Vec<Vec3> = faces
                    .iter()
                    .map(|&(f, _)| {
                        let tri = scene.table.prisms[f as usize].tri;
                        let bary = Vec3::from(tri.map(|v| {
                            if v == *a {
                                1.0 - s
                            } else if v == *b {
                                s
                            } else {
                                0.0
                            }
                        }));
                        position(&scene, f, bary)
                    })
                    .collect();
                worst = worst.max((pts[0] - pts[1]).length());
            }
        }
        assert!(worst <= 1e-5 * size, "{name}: inner edge gap {worst}");
    }
}

fn rays_to_inner_points(n: usize, seed: u32) -> Vec<(Ray, f32)> {
    let mut rng = Rng(seed);
    (0..n)
        .map(|_| {
            let o = rng.unit() * 4.0;
            let target = rng.unit() * 0.3 * rng.next();
            (Ray::new(o, (target - o).normalize()), (target - o).length())
        })
        .collect()
}

#[test]
fn open_seams_leak_and_stitched_seams_do_not() {
    // Breaks if stitching leaves a crack (a leak through the stitched surface), if a method
    // traces the raw height inside a seam band, or if the open surface were closed after all
    // (the test would then prove nothing). PDM on 10⁵ rays, the others on 2·10⁴.
    let rays = rays_to_inner_points(100_000, 7);
    let few = &rays[..20_000];
    for (name, scene) in [("cube", cube(false)), ("cylinder", cylinder(false))] {
        let open =
            Scene::new(scene.table.clone(), scene.map.clone()).with_seam_mode(SeamMode::Open);
        let pdm_open = leaks(&Pdm::new(&open, PdmOptions::default()), &rays);
        let pdm = leaks(&Pdm::new(&scene, PdmOptions::default()), &rays);
        assert!(pdm_open > 0, "{name}: open seams must let rays through");
        assert_eq!(
            pdm, 0,
            "{name}: PDM through the stitched surface ({pdm_open} when open)"
        );
        let reference = Reference::new(scene.surface(), 2.0);
        assert_eq!(leaks(&reference, few), 0, "{name}: reference");
        let ref_open = Reference::new(open.surface(), 2.0);
        assert!(
            leaks(&ref_open, few) > 0,
            "{name}: the open reference is torn too"
        );
        assert_eq!(
            leaks(&Rmip::new(&scene, RmipOptions::default()), few),
            0,
            "{name}: rmip"
        );
        assert_eq!(
            leaks(&Nonlinear::new(&scene, NonlinearOptions::default()), few),
            0,
            "{name}: nonlinear"
        );
    }
}

#[test]
fn seam_safe_map_renders_identically_open_and_stitched() {
    // Breaks if stitching changes the surface where both sides already agree (a bias of the
    // construction), so that a seam-safe asset would look different by default.
    for (name, scene) in [("cube", cube(true)), ("cylinder", cylinder(true))] {
        assert!(
            !scene.stitch().is_empty(),
            "{name}: the seams are stitched (not wrap seams)"
        );
        let open =
            Scene::new(scene.table.clone(), scene.map.clone()).with_seam_mode(SeamMode::Open);
        let cam = Camera::perspective(Vec3::new(2.6, 2.1, 3.3), Vec3::ZERO, Vec3::Y, 45.0);
        let settings = RenderSettings {
            width: 64,
            height: 64,
            spp: 1,
            seed: 0,
        };
        let a = render_aovs(
            &Pdm::new(&scene, PdmOptions::default()),
            &cam,
            &settings,
            &|_| {},
        );
        let b = render_aovs(
            &Pdm::new(&open, PdmOptions::default()),
            &cam,
            &settings,
            &|_| {},
        );
        assert!(
            a.mask.iter().filter(|&&m| m > 0.0).count() > 500,
            "{name}: the object is in view"
        );
        let differ = |x: &[f32], y: &[f32]| x.iter().zip(y).filter(|(p, q)| p != q).count();
        let normals_differ = a
            .normal
            .iter()
            .zip(&b.normal)
            .filter(|(p, q)| p != q)
            .count();
        assert_eq!(differ(&a.mask, &b.mask), 0, "{name}: mask pixels differ");
        assert_eq!(differ(&a.depth, &b.depth), 0, "{name}: depth pixels differ");
        assert_eq!(normals_differ, 0, "{name}: normal pixels differ");
    }
}

#[test]
fn stitched_prism_bounds_hold() {
    // Breaks if the bake's range for a prism next to a seam misses what stitching reads
    // across it: a stitched surface point outside its prism is a hole for every method.
    let mut rng = Rng(0x5ea);
    for (name, scene) in [("cube", cube(false)), ("cylinder", cylinder(false))] {
        let mut checked = 0;
        for (i, p) in scene.table.prisms.iter().enumerate() {
            let Some(_) = scene.stitch().get(i as u32) else {
                continue;
            };
            let disp = scene.prism_displacement(i as u32);
            let (_, n) = scene.table.prism_corners(p);
            for k in 0..400 {
                // Dense near the edges, where the bands are.
                let (mut a, mut c) = (rng.next(), rng.next());
                if k % 2 == 0 {
                    a *= 0.05;
                }
                if a + c > 1.0 {
                    (a, c) = (1.0 - a, 1.0 - c);
                }
                let b = [
                    Vec3::new(1.0 - a - c, a, c),
                    Vec3::new(a, 1.0 - a - c, c),
                    Vec3::new(c, a, 1.0 - a - c),
                ][k % 3];
                let d = disp.at(b);
                let tol = 1e-6;
                assert!(
                    d >= p.d_min - tol && d <= p.d_max + tol,
                    "{name} prism {i}: D* = {d} outside {p:?}"
                );
                let m = (n[0] * b.x + n[1] * b.y + n[2] * b.z).length();
                let l = d / m;
                assert!(
                    l >= p.lambda_lo - 1e-5 && l <= p.lambda_hi + 1e-5,
                    "{name} prism {i}: λ = {l}"
                );
                checked += 1;
            }
        }
        assert!(checked > 10_000, "{name}: {checked}");
    }
}

#[test]
fn stitched_gradient_matches_finite_differences() {
    // Breaks if `at_grad` (the shading normals' source) disagrees with `at` inside the bands.
    let scene = cube(false);
    let mut rng = Rng(3);
    let mut tested = 0;
    for i in 0..scene.table.prisms.len() as u32 {
        if scene.stitch().get(i).is_none() {
            continue;
        }
        let disp = scene.prism_displacement(i);
        for _ in 0..20 {
            let (b1, b2) = (0.02 + 0.3 * rng.next(), 0.02 + 0.3 * rng.next());
            let b = Vec3::new(1.0 - b1 - b2, b1, b2);
            let (d, g) = disp.at_grad(b);
            assert!((d - disp.at(b)).abs() <= 1e-6, "value");
            let e = 1e-4;
            let f = |x: f32, y: f32| disp.at(Vec3::new(1.0 - x - y, x, y));
            let fd = Vec2::new(
                (f(b1 + e, b2) - f(b1 - e, b2)) / (2.0 * e),
                (f(b1, b2 + e) - f(b1, b2 - e)) / (2.0 * e),
            );
            // Bilinear texels kink: compare where both one-sided slopes agree (no kink
            // within the step).
            let fwd = Vec2::new((f(b1 + e, b2) - d) / e, (f(b1, b2 + e) - d) / e);
            let bwd = Vec2::new((d - f(b1 - e, b2)) / e, (d - f(b1, b2 - e)) / e);
            if (fwd - bwd).abs().max_element() > 0.02 * fd.abs().max_element().max(0.01) {
                continue;
            }
            assert!(
                (g - fd).abs().max_element() <= 0.05 * fd.abs().max_element().max(0.01),
                "prism {i} at {b}: {g} vs {fd}"
            );
            tested += 1;
        }
    }
    assert!(tested > 100, "{tested}");
}

#[test]
fn band_weight_gradient_matches_finite_differences() {
    let mut rng = Rng(11);
    for _ in 0..2000 {
        let b = rng.barycentric().to_array();
        let k = (rng.next() * 3.0) as usize % 3;
        let band = 0.05 + 0.15 * rng.next();
        let (_, g) = band_weight(b, k, band);
        let e = 1e-4;
        if b.iter().any(|&x| x < 2.0 * e) {
            continue; // the clamp at b = 0 is not differentiable
        }
        for m in 0..3 {
            let (mut p, mut q) = (b, b);
            p[m] += e;
            q[m] -= e;
            let fd = (band_weight(p, k, band).0 - band_weight(q, k, band).0) / (2.0 * e);
            assert!(
                (g[m] - fd).abs() <= 2e-2 * fd.abs().max(1.0),
                "b {b:?} k {k} band {band}: d/db{m} {} vs {fd}",
                g[m]
            );
        }
    }
}

#[test]
fn band_weights_carry_each_edge_its_own_target() {
    // Breaks if a band's weight is not 1 on its own edge, or leaks onto the other two edges
    // (which would make neighbours of one island disagree there).
    for band in [0.05, 0.2] {
        for step in 1..20 {
            let s = step as f32 / 20.0;
            for k in 0..3 {
                let (i, j) = ((k + 1) % 3, (k + 2) % 3);
                let mut on = [0.0; 3];
                (on[i], on[j]) = (1.0 - s, s);
                assert_eq!(band_weight(on, k, band).0, 1.0);
                let mut other = [0.0; 3];
                (other[k], other[j]) = (1.0 - s, s);
                assert_eq!(band_weight(other, k, band).0, 0.0, "edge {i}");
                let mut inside = [1.0 / 3.0; 3];
                inside[k] = band * 1.01;
                inside[i] = (1.0 - inside[k]) / 2.0;
                inside[j] = inside[i];
                assert_eq!(band_weight(inside, k, band).0, 0.0, "beyond the band");
            }
        }
    }
}

#[test]
fn wrap_seams_are_not_stitched() {
    // Breaks if a u = 0/1 seam under repeat wrap (the same texels on both sides, as on the
    // torus and UV sphere examples) were stitched: it would slow the trace for nothing.
    let mut mesh = seamed_cylinder(24, 4);
    // Side island spanning the whole map in u, map repeated: its seam line is a wrap seam.
    for uv in mesh.uvs.iter_mut().take(5 * 25) {
        uv.x = (uv.x - 2.0 / W as f32) / (60.0 / W as f32);
    }
    let mut map = island_map(&CYLINDER_ISLANDS, &[1, 2], false);
    map.wrap = Wrap::Repeat;
    let scene = scene_of(mesh, map);
    let side_seams = scene
        .table
        .seams
        .iter()
        .filter(|s| is_wrap_seam(&scene.table, s))
        .count();
    assert_eq!(side_seams, 4, "the side's seam line");
    assert_eq!(scene.stitch().stitched_edges, 2 * 24, "only the rims");
}

#[test]
fn validate_measures_the_jump_of_each_map() {
    // Breaks if the seam-jump figures stop following the map: the jump map's max jump is a
    // good fraction of the scale, the seam-safe one's is zero.
    for (mesh, islands, discs) in [
        (seamed_cube(4), &CUBE_ISLANDS[..], &[][..]),
        (seamed_cylinder(24, 4), &CYLINDER_ISLANDS[..], &[1, 2][..]),
    ] {
        let (mesh, _) = repair(mesh, &RepairOptions::default());
        let params = DisplaceParams {
            scale: SCALE,
            midlevel: 0.5,
        };
        for (safe, want_rel) in [(false, 0.05f32), (true, 0.0)] {
            let map = island_map(islands, discs, safe);
            let r = measure_seams(
                &mesh.uvs,
                &mesh.triangles,
                &mesh.seams,
                &params,
                &map,
                map.wrap,
                5,
            );
            assert_eq!(r.seam_edges, mesh.seams.len());
            if safe {
                assert_eq!(r.max_jump, 0.0, "{r:?}");
                assert!(r.worst.is_empty());
            } else {
                assert!(r.max_jump_rel > want_rel, "{r:?}");
                assert!(r.rms_jump > 0.0 && r.rms_jump <= r.max_jump);
                assert_eq!(r.worst.len(), 5);
                assert!(r.worst[0].1 >= r.worst[4].1);
            }
        }
    }
}
