//! UV seams on the GPU: the stitched surface (`SeamMode::Stitch`, the default) and the raw one
//! (`Open`) traced as the CPU traces them. Fixture: a smooth-normal cube with one UV island
//! per face (every cube edge a seam) under a non-periodic clamp-wrapped map, so the islands
//! disagree at every seam and each seam band has its own stitched height, built from core's
//! public API (repair + bake).
//!
//! Breaks if the GPU evaluates the raw height where the CPU stitches (in the march or in the
//! surface normal), stitches under `Open`, or reads a stitch record wrongly (an edge, a band,
//! a chart out of place): each moves the pixels where stitched and open differ.

use crate::parity::{assert_parity, compare, report};
use crate::util::ctx;
use glam::{Vec2, Vec3};
use prismbake::accel::Scene;
use prismbake::bake::{bake, BakeOptions};
use prismbake::render::camera::Camera;
use prismbake::render::{self, AovImage, RenderSettings};
use prismbake::repair::{repair, RepairOptions};
use prismbake::seam::SeamMode;
use prismbake::trace::pdm::{Pdm, PdmOptions};
use prismbake::{BaseMesh, DisplaceParams, HeightMap, Wrap};
use prismbake_gpu::{render_aovs, GpuScene};
use std::sync::OnceLock;

/// The atlas: 3 × 2 islands of 32 × 32 texels.
const W: u32 = 96;
const H: u32 = 64;
const SCALE: f32 = 0.1;
const RES: u32 = 128;

/// UV of `(s, t) ∈ [0, 1]²` on island `face`, 2 texels inside its cell (v up the image).
fn island_uv(face: u32, s: f32, t: f32) -> Vec2 {
    let (x0, row0) = ((face % 3) as f32 * 32.0, (face / 3) as f32 * 32.0);
    let x = x0 + 2.0 + s * 28.0;
    let row = row0 + 2.0 + t * 28.0;
    Vec2::new(x / W as f32, 1.0 - row / H as f32)
}

/// The cube [-1, 1]³, `n × n` quads a face wound outwards, normals along the position (no hard
/// edge), one UV island per face: 12·n seam edges.
fn seamed_cube(n: u32) -> BaseMesh {
    let (mut positions, mut normals, mut uvs, mut triangles) = (vec![], vec![], vec![], vec![]);
    let axes = [Vec3::X, Vec3::Y, Vec3::Z];
    for face in 0..6u32 {
        let a = (face / 2) as usize;
        let sign = if face % 2 == 0 { 1.0 } else { -1.0 };
        let (t1, t2) = (axes[(a + 1) % 3], axes[(a + 2) % 3]);
        let base = positions.len() as u32;
        for j in 0..=n {
            for i in 0..=n {
                let (s, t) = (i as f32 / n as f32, j as f32 / n as f32);
                let p = axes[a] * sign + t1 * (2.0 * s - 1.0) + t2 * (2.0 * t - 1.0);
                positions.push(p);
                normals.push(p.normalize());
                uvs.push(island_uv(face, s, t));
            }
        }
        let at = |i: u32, j: u32| base + j * (n + 1) + i;
        for j in 0..n {
            for i in 0..n {
                let quad = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                for tri in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
                    // (t1, t2) is right-handed about +axis: flip on the negative faces.
                    triangles.push(if sign > 0.0 {
                        tri
                    } else {
                        [tri[0], tri[2], tri[1]]
                    });
                }
            }
        }
    }
    let faces = triangles.len();
    BaseMesh {
        positions,
        normals,
        uvs,
        triangles,
        face_group: vec![0; faces],
        groups: vec!["seamed cube".into()],
        face_flags: vec![0; faces],
        ..Default::default()
    }
}

/// A non-periodic relief with a little hashed noise, clamp-wrapped: no two islands agree on a
/// shared edge.
fn jump_map() -> HeightMap {
    let data = (0..W * H)
        .map(|i| {
            let (x, row) = ((i % W) as f32 + 0.5, (i / W) as f32 + 0.5);
            let relief = 0.35 * (0.37 * x + 0.11 * row).sin() * (0.23 * row - 0.05 * x).cos();
            let noise =
                ((prismbake::rng::pcg_hash(i ^ 0xcafe) >> 8) as f32 / 16_777_216.0 - 0.5) * 0.1;
            0.5 + relief + noise
        })
        .collect();
    HeightMap::new(W, H, data, Wrap::Clamp)
}

fn cube_scene(mode: SeamMode) -> Scene {
    let map = jump_map();
    let (mesh, _) = repair(seamed_cube(4), &RepairOptions::default());
    assert_eq!(mesh.seams.len(), 12 * 4, "every cube edge is a seam");
    let params = DisplaceParams {
        scale: SCALE,
        midlevel: 0.5,
    };
    Scene::new(bake(&mesh, &map, &BakeOptions { params }), map).with_seam_mode(mode)
}

/// One mode's CPU and GPU frames, and the stitched prisms the GPU scene was given.
struct Renders {
    cpu: AovImage,
    gpu: AovImage,
    /// Per prism: has a stitch record on the CPU.
    stitched: Vec<bool>,
    gpu_stitched_prisms: u32,
}

fn render_mode(mode: SeamMode) -> Renders {
    let scene = cube_scene(mode);
    // Three faces and their shared edges and corner in view.
    let cam = Camera::perspective(Vec3::new(2.6, 2.1, 3.3), Vec3::ZERO, Vec3::Y, 40.0);
    let settings = RenderSettings {
        width: RES,
        height: RES,
        spp: 1,
        seed: 7,
    };
    let opts = PdmOptions::default();
    let cpu = render::render_aovs(&Pdm::new(&scene, opts), &cam, &settings, &|_| {});
    let gpu_scene = GpuScene::upload(ctx(), &scene).expect("upload");
    let gpu = render_aovs(ctx(), &gpu_scene, &cam, &settings, &opts, &|_| {}).expect("render");
    let stitched = (0..scene.table.prisms.len() as u32)
        .map(|p| scene.stitch().get(p).is_some())
        .collect();
    Renders {
        cpu,
        gpu,
        stitched,
        gpu_stitched_prisms: gpu_scene.stitched_prisms(),
    }
}

/// Both modes, rendered once for the tests below.
fn renders() -> &'static (Renders, Renders) {
    static R: OnceLock<(Renders, Renders)> = OnceLock::new();
    R.get_or_init(|| (render_mode(SeamMode::Stitch), render_mode(SeamMode::Open)))
}

/// The prism id of a pixel from the `prism` AOV (id + 1, 0 = miss).
fn prism_of(img: &AovImage, i: usize) -> Option<usize> {
    (img.mask[i] > 0.5 && img.prism[i] >= 1.0).then(|| img.prism[i] as usize - 1)
}

#[test]
fn stitched_cube_matches_the_cpu_on_its_stitched_prisms() {
    let (s, _) = renders();
    let cpu_stitched = s.stitched.iter().filter(|&&x| x).count();
    assert!(cpu_stitched > 0, "the jump map stitches");
    assert_eq!(
        s.gpu_stitched_prisms as usize, cpu_stitched,
        "every CPU stitch record is uploaded"
    );
    let n = (RES * RES) as usize;
    let all = compare(&s.cpu, &s.gpu, |_| true);
    eprintln!("{}", report("cube 128², stitch", &all));
    assert_parity("cube, stitch", &all, n / 10);
    // Pixels where either device hit a prism with stitch data.
    let on_stitched = |i: usize| {
        [prism_of(&s.cpu, i), prism_of(&s.gpu, i)]
            .into_iter()
            .flatten()
            .any(|p| s.stitched[p])
    };
    let stitched = compare(&s.cpu, &s.gpu, on_stitched);
    eprintln!(
        "{}",
        report("cube 128², stitch, stitched prisms", &stitched)
    );
    assert_parity("cube, stitch, stitched prisms", &stitched, n / 20);
}

/// Per-pixel depth relative difference and normal angle (degrees) of two frames that both hit.
fn difference(a: &AovImage, b: &AovImage, i: usize) -> (f32, f32) {
    let depth = (a.depth[i] - b.depth[i]).abs() / a.depth[i].abs().max(1e-12);
    let angle = a.normal[i]
        .dot(b.normal[i])
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    (depth, angle)
}

#[test]
fn open_cube_matches_the_cpu_and_differs_from_stitched_where_the_cpu_does() {
    let (s, o) = renders();
    assert_eq!(o.gpu_stitched_prisms, 0, "open: no stitch record uploaded");
    let n = (RES * RES) as usize;
    let all = compare(&o.cpu, &o.gpu, |_| true);
    eprintln!("{}", report("cube 128², open", &all));
    assert_parity("cube, open", &all, n / 10);

    // Where the CPU's stitched and open surfaces differ (the seam bands), each GPU frame
    // must agree with the CPU frame of its own mode, far closer than the two modes are apart.
    let hit = |img: &AovImage, i: usize| img.mask[i] > 0.5;
    let bands: Vec<usize> = (0..n)
        .filter(|&i| hit(&s.cpu, i) && hit(&o.cpu, i))
        .filter(|&i| {
            let (depth, angle) = difference(&s.cpu, &o.cpu, i);
            depth > 1e-4 || angle > 1.0
        })
        .collect();
    let agree = |gpu: &AovImage, cpu: &AovImage| {
        bands
            .iter()
            .filter(|&&i| {
                hit(gpu, i) && {
                    let (depth, angle) = difference(cpu, gpu, i);
                    depth <= 1e-5 && angle <= 0.1
                }
            })
            .count()
    };
    let (stitch_agree, open_agree) = (agree(&s.gpu, &s.cpu), agree(&o.gpu, &o.cpu));
    let crossed = agree(&s.gpu, &o.cpu) + agree(&o.gpu, &s.cpu);
    eprintln!(
        "cube: {} px where the CPU's stitch and open differ; the GPU agrees with its own mode on {stitch_agree} (stitch) and {open_agree} (open), with the other mode on {crossed}",
        bands.len()
    );
    assert!(
        bands.len() >= n / 100,
        "the seam bands cover {} pixels",
        bands.len()
    );
    for (mode, agreed) in [("stitch", stitch_agree), ("open", open_agree)] {
        assert!(
            agreed as f64 >= 0.99 * bands.len() as f64,
            "{mode}: the GPU agrees with the CPU on {agreed} of {} seam-band pixels",
            bands.len()
        );
    }
}
