//! GPU vs CPU beauty: the same asset, camera, lighting, material and seed rendered by
//! `prismbake::render::beauty::render_beauty` (CPU, PDM) and `prismbake_gpu::render_beauty` in
//! both schedules (`BeautySchedule`: fused, wavefront)
//! must give the same picture. Both draw the same random numbers for every (pixel, sample,
//! bounce, purpose) and take the same decisions, so most pixels agree to float rounding; a
//! sample whose decision flips on a rounding difference (a texel boundary in environment
//! sampling, a lobe choice, a grazing or silhouette hit; the BVHs differ, BVH2 vs CWBVH, and
//! the GPU's transcendentals are not libm's) differs by up to its whole contribution / spp.
//!
//! Tolerances, in linear RGB relative to the CPU image's mean radiance over covered pixels
//! (`scale`): mean |Δ| over all pixels and channels ≤ 1e-3, the 99th percentile of the
//! per-pixel max-channel |Δ| ≤ 1e-2, alpha mean |Δ| ≤ 1e-3, the background (what shows
//! behind the asset: the bilinear environment, dimmed by the catcher's shadow) mean |Δ| ≤ 1e-3
//! of its own mean, the denoising guides (normals, coverage) mean |Δ| ≤ 1e-3, and ray counts
//! per kind within 1%. Measured on lavapipe (docs/gpu.md):
//! mean 3e-6..1e-5, p99 2e-5..5e-5, under 0.3% of pixels off by more than 1e-3, background
//! 4e-5..1.5e-4 (sharp texel edges of the sun, catcher shadows), identical ray counts — so
//! the bounds leave ~100× for other drivers and real GPUs, while a bug in any mirrored stage
//! (environment mapping or sampling tables, BSDF, MIS weights, random dimensions, shadow
//! catcher, accumulation) moves most pixels by far more than 1%.

use crate::util::{ctx, example_scene, ExampleScene};
use glam::Vec3;
use prismbake::mesh::UpAxis;
use prismbake::render::beauty::{
    beauty_preview, render_beauty, scene_epsilon, BeautyImage, BeautyScene, Ground, KeyLight,
    SurfaceMaterial,
};
use prismbake::render::camera::Camera;
use prismbake::render::env::{EnvFrame, EnvMap};
use prismbake::render::lights::{Light, LightSet, LightShape, Spot};
use prismbake::render::shading::{luminance, Material};
use prismbake::render::RenderSettings;
use prismbake::trace::pdm::{Pdm, PdmOptions};
use prismbake_gpu::{BeautySchedule, GpuBeautyScene, GpuScene};

struct Agreement {
    mean_rel: f64,
    p99_rel: f64,
    max_rel: f64,
    alpha_mean: f64,
    background_rel: f64,
    /// The denoising guides (`BeautyImage::guides`): mean |Δ| of the normal and the albedo
    /// (their largest component difference), the coverage, the ground's share and the catcher's shadow
    /// weighted by it, over all pixels.
    features_mean: f64,
    /// Pixels whose max-channel difference exceeds 1e-3 × scale.
    differing: f64,
    scale: f64,
}

fn compare(cpu: &BeautyImage, gpu: &BeautyImage) -> Agreement {
    let n = cpu.rgba.len();
    assert_eq!(gpu.rgba.len(), n);
    let covered: Vec<f64> = cpu
        .rgba
        .iter()
        .filter(|c| c[3] > 0.5)
        .map(|c| luminance(Vec3::new(c[0], c[1], c[2])) as f64)
        .collect();
    let scale = (covered.iter().sum::<f64>() / covered.len().max(1) as f64).max(1e-6);
    let bg_scale = cpu
        .background
        .iter()
        .map(|b| luminance(*b) as f64)
        .sum::<f64>()
        / n as f64;
    let (mut sum, mut alpha, mut bg, mut feat) = (0.0, 0.0, 0.0, 0.0);
    let mut per_pixel = Vec::with_capacity(n);
    for i in 0..n {
        let (c, g) = (cpu.rgba[i], gpu.rgba[i]);
        let d = (0..3).map(|k| (c[k] - g[k]).abs() as f64);
        sum += d.clone().sum::<f64>();
        per_pixel.push(d.fold(0.0, f64::max) / scale);
        alpha += (c[3] - g[3]).abs() as f64;
        bg += (cpu.background[i] - gpu.background[i]).abs().max_element() as f64;
        let (cf, gf) = (cpu.guides[i], gpu.guides[i]);
        feat += [
            (cf.normal - gf.normal).abs().max_element(),
            (cf.albedo - gf.albedo).abs().max_element(),
            (cf.coverage - gf.coverage).abs(),
            (cf.ground - gf.ground).abs(),
            (cf.ground * cf.shadow - gf.ground * gf.shadow).abs(),
        ]
        .iter()
        .map(|&d| d as f64)
        .sum::<f64>()
            / 5.0;
    }
    let differing = per_pixel.iter().filter(|&&d| d > 1e-3).count() as f64 / n as f64;
    per_pixel.sort_by(|a, b| a.total_cmp(b));
    Agreement {
        mean_rel: sum / (3 * n) as f64 / scale,
        p99_rel: per_pixel[n * 99 / 100],
        max_rel: per_pixel[n - 1],
        alpha_mean: alpha / n as f64,
        background_rel: bg / n as f64 / bg_scale.max(1e-6),
        features_mean: feat / n as f64,
        differing,
        scale,
    }
}

/// The shadow-catcher plane and ray offset as `lookdev` derives them: the base bounds grown
/// by the largest |D|, the plane at the lowest point along `up`.
fn ground_and_eps(ex: &ExampleScene, up: Vec3) -> (Ground, f32) {
    let d = ex
        .scene
        .table
        .prisms
        .iter()
        .map(|p| p.d_min.abs().max(p.d_max.abs()))
        .fold(0.0f32, f32::max);
    let (lo, hi) = (ex.lo - d, ex.hi + d);
    (
        Ground {
            up,
            height: lo.dot(up).min(hi.dot(up)),
        },
        scene_epsilon(lo, hi),
    )
}

/// A lopsided environment: a small bright sun above the horizon on a dim gradient, so that
/// importance sampling concentrates on a few texels (the CPU's tables must be the GPU's).
fn sun_env(frame: EnvFrame) -> EnvMap {
    let (w, h) = (64u32, 32u32);
    let texels = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if (40..43).contains(&x) && (9..11).contains(&y) {
                Vec3::new(60.0, 50.0, 40.0)
            } else {
                Vec3::new(0.2, 0.25, 0.3) * (1.0 - y as f32 / h as f32) + 0.05
            }
        })
        .collect();
    EnvMap::new(w, h, texels, frame)
}

fn check(
    rel: &str,
    ex: &ExampleScene,
    bscene: &BeautyScene,
    settings: &RenderSettings,
    label: &str,
) -> Agreement {
    let opts = PdmOptions::default();
    let cpu = render_beauty(
        &Pdm::new(&ex.scene, opts),
        &ex.cam,
        settings,
        bscene,
        &|_| {},
    );
    let gpu_scene = GpuScene::upload(ctx(), &ex.scene).expect("upload");
    let lighting = GpuBeautyScene::upload(ctx(), bscene).expect("lighting upload");
    // Both schedules, whichever this adapter takes by default.
    let mut agreement = None;
    for schedule in [BeautySchedule::Fused, BeautySchedule::Wavefront] {
        let gpu = prismbake_gpu::render_beauty_scheduled(
            ctx(),
            schedule,
            &gpu_scene,
            &lighting,
            &ex.cam,
            settings,
            &opts,
            &|_| {},
        )
        .expect("gpu beauty");
        let label = format!("{label} {schedule:?}");
        assert_eq!(
            gpu.exposure, cpu.exposure,
            "{rel} {label}: the previews' exposure"
        );
        agreement = Some(agree(rel, &label, settings, &cpu, &gpu));
    }
    agreement.expect("two schedules")
}

/// The GPU's beauty against the CPU's: the tolerances of the beauty parity tests.
fn agree(
    rel: &str,
    label: &str,
    settings: &RenderSettings,
    cpu: &BeautyImage,
    gpu: &BeautyImage,
) -> Agreement {
    let a = compare(cpu, gpu);
    eprintln!(
        "{rel} {label} {}² {} spp: mean |Δ| {:.2e} | p99 {:.2e} | max {:.2e} (× mean radiance {:.3}) | {:.2}% px > 1e-3 | alpha mean |Δ| {:.2e} | background {:.2e} | guides {:.2e} | rays cpu {:?} gpu {:?}",
        settings.width,
        settings.spp,
        a.mean_rel,
        a.p99_rel,
        a.max_rel,
        a.scale,
        100.0 * a.differing,
        a.alpha_mean,
        a.background_rel,
        a.features_mean,
        cpu.counters,
        gpu.counters
    );
    assert!(a.scale > 1e-3, "{rel}: the asset is black or missing");
    assert!(
        a.mean_rel <= 1e-3,
        "{rel} {label}: mean |Δ| {:.2e}",
        a.mean_rel
    );
    assert!(
        a.p99_rel <= 1e-2,
        "{rel} {label}: p99 |Δ| {:.2e}",
        a.p99_rel
    );
    assert!(
        a.alpha_mean <= 1e-3,
        "{rel} {label}: alpha {:.2e}",
        a.alpha_mean
    );
    assert!(
        a.background_rel <= 1e-3,
        "{rel} {label}: background {:.2e}",
        a.background_rel
    );
    // The guides are the camera hits' normals and coverage: the alpha's tolerance.
    assert!(
        a.features_mean <= 1e-3,
        "{rel} {label}: denoising guides {:.2e}",
        a.features_mean
    );
    let covered = cpu.guides.iter().filter(|g| g.coverage > 0.5).count();
    assert!(
        covered > 0
            && cpu
                .guides
                .iter()
                .filter(|g| g.coverage > 0.5)
                .all(|g| g.normal.length() > 0.1),
        "{rel} {label}: covered pixels without a normal guide"
    );
    preview_agrees(rel, label, gpu);
    let close = |c: u64, g: u64, what: &str| {
        assert!(
            (c as f64 - g as f64).abs() <= 0.01 * c as f64,
            "{rel} {label}: {what} cpu {c} gpu {g}"
        );
    };
    close(cpu.counters.rays, gpu.counters.rays, "rays");
    close(
        cpu.counters.key_shadow_rays,
        gpu.counters.key_shadow_rays,
        "key shadow rays",
    );
    close(
        cpu.counters.env_shadow_rays,
        gpu.counters.env_shadow_rays,
        "env shadow rays",
    );
    a
}

/// The GPU's preview (`tonemap.wgsl`, from its own sums) against the host's tonemap of the same
/// frame's pixels (`beauty_preview` of the resolved image): the filmic and sRGB curves and the
/// rounding are the same functions, so only a channel whose value falls within the GPU's
/// rounding (its `pow`, a fused multiply-add) of a code's edge may differ, by one code.
/// Measured on lavapipe: no channel differs in these scenes.
fn preview_agrees(rel: &str, label: &str, gpu: &BeautyImage) {
    let device = beauty_preview(gpu);
    let host = beauty_preview(&BeautyImage {
        preview: None,
        ..gpu.clone()
    });
    assert!(
        gpu.preview.is_some(),
        "{rel} {label}: no preview from the GPU"
    );
    assert_eq!(device.len(), host.len());
    let differ = device.iter().zip(&host).filter(|(d, h)| d != h).count();
    let worst = device
        .iter()
        .zip(&host)
        .map(|(d, h)| d.abs_diff(*h))
        .max()
        .unwrap_or(0);
    let bright = host.iter().filter(|&&v| v > 32).count();
    eprintln!(
        "{rel} {label}: preview channels differing from the host's tonemap {differ} of {} (worst {worst} codes)",
        host.len()
    );
    assert!(
        bright > host.len() / 4,
        "{rel} {label}: a dark preview tests little"
    );
    assert!(
        worst <= 1 && differ * 1000 <= host.len(),
        "{rel} {label}: {differ} preview channels differ, by up to {worst} codes"
    );
}

/// The lights of `sphere_under_the_sky`: one key light, or a rig, each light picked by what it
/// casts on the surface event's point.
enum Lights {
    One(KeyLight),
    Rig(Vec<Light>),
}

impl From<KeyLight> for Lights {
    fn from(k: KeyLight) -> Self {
        Lights::One(k)
    }
}

/// A rig of every kind of light about the sphere (radius about 1, at the origin): a warm sun
/// disc, a point above, a blue sphere light beside it, a spot aimed at it from the front, a
/// point-like rim light behind, a rectangle and a disk. Each shadow ray goes as far as its
/// light; BSDF samples meet the sun's disc, the sphere and the area lights.
#[test]
fn a_rig_of_every_kind_of_light_matches_the_cpu() {
    let spot = Spot {
        axis: Vec3::new(0.0, -0.3, -1.0).normalize(),
        cos_inner: 0.97,
        cos_outer: 0.9,
    };
    let local = |pos: Vec3, radius: f32, spot: Option<Spot>, power: f32, color: Vec3| Light {
        shape: LightShape::Local { pos, radius, spot },
        power,
        color,
    };
    sphere_under_the_sky(
        |ex| ex.cam,
        Lights::Rig(vec![
            KeyLight::from_angles(40.0, 50.0, 2.0, false)
                .with_angle(6.0)
                .with_color(Vec3::new(1.3, 0.95, 0.7))
                .into(),
            local(Vec3::new(0.0, 3.0, 0.5), 0.0, None, 12.0, Vec3::ONE),
            local(
                Vec3::new(2.5, 0.5, 1.0),
                0.3,
                None,
                6.0,
                Vec3::new(0.6, 0.9, 1.6),
            ),
            local(Vec3::new(0.0, 1.2, 4.0), 0.0, Some(spot), 30.0, Vec3::ONE),
            KeyLight::from_angles(200.0, 20.0, 1.5, false).into(),
            // A softbox above and in front, shining down and back; a disk low on the left,
            // shining right.
            Light {
                shape: LightShape::Area {
                    pos: Vec3::new(0.0, 2.5, 2.0),
                    u: Vec3::new(0.8, 0.0, 0.0),
                    v: Vec3::new(0.0, 0.3, -0.4),
                    disk: false,
                },
                power: 3.0,
                color: Vec3::new(1.0, 0.9, 0.8),
            },
            Light {
                shape: LightShape::Area {
                    pos: Vec3::new(-2.5, -0.5, 0.5),
                    u: Vec3::new(0.0, 0.0, 0.6),
                    v: Vec3::new(0.0, 0.6, 0.0),
                    disk: true,
                },
                power: 2.0,
                color: Vec3::ONE,
            },
        ]),
        1.0,
        RenderSettings {
            width: 64,
            height: 64,
            spp: 4,
            seed: 11,
        },
        "rig of seven lights",
    );
}

/// The sphere under the lookdev default: the built-in sky, `key` with its shadow rays, the
/// shadow catcher, Lambert + GGX (roughness 0.5), two bounces, seen through `view`'s camera
/// (given the example, framed through a pinhole).
fn sphere_under_the_sky(
    view: impl FnOnce(&ExampleScene) -> Camera,
    key: impl Into<Lights>,
    exposure: f32,
    settings: RenderSettings,
    label: &str,
) {
    let rel = "sphere/sphere.glb";
    let ex = example_scene(rel);
    assert_eq!(ex.up_axis, UpAxis::Y);
    let ex = ExampleScene {
        cam: view(&ex),
        ..ex
    };
    let env = EnvMap::default_sky(
        1.0,
        EnvFrame {
            z_up: false,
            rotation: 0.4,
        },
    );
    let (ground, eps) = ground_and_eps(&ex, Vec3::Y);
    let bscene = BeautyScene {
        env: &env,
        env_frame: env.frame,
        env_lights: true,
        lights: match key.into() {
            Lights::One(k) => LightSet::one(k),
            Lights::Rig(lights) => LightSet::new(&lights),
        },
        materials: &[SurfaceMaterial::from(Material::default())],
        textures: &[],
        tangents: &[],
        base_normals: &[],
        emissive: false,
        prisms: &ex.scene.table.prisms,
        ground: Some(ground),
        bounces: 2,
        eps,
        exposure,
    };
    check(rel, &ex, &bscene, &settings, label);
}

#[test]
fn sphere_with_sky_key_light_and_ground_matches_the_cpu() {
    sphere_under_the_sky(
        |ex| ex.cam,
        // A warm disc 6° across: its shadow rays draw their directions
        // (KeyLight::sample_dir), and BSDF samples meet it, both in its colour.
        KeyLight::from_angles(40.0, 50.0, 3.0, false)
            .with_angle(6.0)
            .with_color(Vec3::new(1.5, 0.9, 0.6)),
        // Half a stop up: the GPU's preview must take it as the host's does.
        1.5,
        RenderSettings {
            width: 64,
            height: 64,
            spp: 4,
            seed: 7,
        },
        "sky+key+ground",
    );
}

/// An orthographic view: every camera ray starts at its own place on the camera's plane
/// (the wavefront keeps it until the camera step's event), over the ground too.
#[test]
fn an_orthographic_view_matches_the_cpu() {
    sphere_under_the_sky(
        |ex| ex.cam.fit_orthographic(ex.lo, ex.hi, 1.0),
        KeyLight::from_angles(40.0, 50.0, 3.0, false),
        1.0,
        RenderSettings {
            width: 48,
            height: 48,
            spp: 2,
            seed: 3,
        },
        "orthographic",
    );
}

#[test]
fn materials_and_textures_per_prism_match_the_cpu() {
    // The rock's own base-colour texture (embedded in rock.glb: fish scales, a colour each)
    // with the file's sampler (repeat, bilinear) times a tinted factor, a red rough metal, the
    // texture again mirrored/clamped nearest with its red channel as the metallic, and a grey
    // metal whose roughness and metallic are the green and blue of one 8-bit data texture
    // (glTF's metallic-roughness), assigned to the prisms in turn (the fifth index is past the
    // end: the last material), read at every hit on the first and the second bounce. The red
    // metal has a normal map (8-bit data, its x and y scaled by 0.8, Normal Map Strength 1.3)
    // read in the rock's MikkTSpace tangents; the first material glows.
    use prismbake::bake::PRISM_MATERIAL_SHIFT;
    use prismbake::render::beauty::{NormalTex, TexChannel};
    use prismbake::texture::{raw8_table, ColorMap, Sampler, TexWrap, TextureSlot, UvTransform};
    let rel = "rock/rock.glb";
    let mut ex = example_scene(rel);
    for (i, p) in ex.scene.table.prisms.iter_mut().enumerate() {
        p.flags |= (i as u32 % 5) << PRISM_MATERIAL_SHIFT;
    }
    let path = crate::util::example(rel);
    let mesh = prismbake::load::load_mesh(&path, &Default::default()).expect("load");
    let tref = mesh.materials[0]
        .base_color_texture
        .clone()
        .expect("rock.glb has a base-colour texture");
    assert_eq!(
        tref.sampler,
        Sampler::default(),
        "rock.glb: repeat, bilinear"
    );
    let texture = ColorMap::load(&path, &tref, TextureSlot::BaseColor).expect("decode");
    let other = ColorMap {
        sampler: Sampler {
            wrap: [TexWrap::Mirror, TexWrap::Clamp],
            nearest: true,
        },
        ..texture.clone()
    };
    // 8 x 8 texels of raw 8-bit codes: roughness (green) and metallic (blue) in stripes across
    // u and v, red unused.
    let raw = raw8_table();
    let orm = ColorMap {
        width: 8,
        height: 8,
        texels: (0..64)
            .map(|i| Vec3::new(raw[7], raw[20 + 29 * (i % 8)], raw[255 - 30 * (i / 8)]))
            .collect(),
        sampler: Sampler::default(),
        // Turned, tiled and shifted (KHR_texture_transform).
        transform: UvTransform::gltf([0.1, -0.3], 0.6, [3.0, 2.0]),
        name: "orm".into(),
    };
    // 8 x 8 normals tilting up to about 35° every way, as 8-bit codes, tiled four times.
    let bumps = ColorMap {
        width: 8,
        height: 8,
        texels: (0..64)
            .map(|i| {
                let (x, y) = ((i % 8) as f32 / 7.0 - 0.5, (i / 8) as f32 / 7.0 - 0.5);
                let n = Vec3::new(1.4 * x, -1.2 * y, 1.0).normalize();
                (n * 0.5 + 0.5)
                    .to_array()
                    .map(|c| raw[(c * 255.0).round() as usize])
                    .into()
            })
            .collect(),
        sampler: Sampler::default(),
        transform: UvTransform::scale_offset([4.0, 4.0], [0.0, 0.0]),
        name: "bumps".into(),
    };
    let textures = [texture, other, orm, bumps];
    // 8-bit PNGs go up packed with the sRGB table, the data texture with the raw one
    // (`TextureLayout`).
    let layout = prismbake_gpu::beauty::texture_layout(&textures);
    assert_eq!(
        (layout.tables, layout.textures),
        (
            [0, 256],
            vec![
                (512, Some(0)),
                (512 + 256 * 256, Some(0)),
                (512 + 2 * 256 * 256, Some(1)),
                (512 + 2 * 256 * 256 + 64, Some(1))
            ]
        )
    );
    let channel = |texture, channel| Some(TexChannel { texture, channel });
    let materials = [
        SurfaceMaterial {
            material: Material {
                base_color: Vec3::new(1.0, 0.9, 0.8),
                specular_tint: Vec3::new(0.4, 1.0, 0.7),
                // Its glow dims under the clearcoat at grazing angles.
                clearcoat: 0.9,
                clearcoat_roughness: 0.25,
                ..Material::default()
            },
            texture: Some(0),
            // Both of the coat's channels from one texture (one lookup), and the coat's own
            // normal map (the glow's angle is the coat's).
            clearcoat_texture: channel(2, 0),
            clearcoat_roughness_texture: channel(2, 1),
            clearcoat_normal_texture: Some(NormalTex {
                texture: 3,
                scale: Vec3::new(1.0, 1.0, 2.0),
                bias: Vec3::new(-0.5, -0.5, -1.0),
                // Blended with the surface's normal (Blender's Normal Map Strength).
                strength: 0.6,
            }),
            // The diffuse under it bent by the bumps, steeply: shadowed about the unbent
            // normal (`shading::bump_shadowing`).
            normal_texture: Some(NormalTex {
                texture: 3,
                scale: Vec3::splat(2.0),
                bias: Vec3::splat(-1.0),
                strength: 2.0,
            }),
            // Glowing through the second texture (counted at every hit and, the scene being
            // emissive, by the last bounce's closest-hit ray).
            emission: Vec3::new(0.5, 0.4, 0.3),
            emission_texture: Some(1),
            ..Default::default()
        },
        SurfaceMaterial {
            material: Material {
                base_color: Vec3::new(0.9, 0.2, 0.1),
                roughness: 0.35,
                metallic: 1.0,
                specular: 0.04,
                specular_tint: Vec3::new(0.6, 0.9, 1.0),
                // A rough clearcoat over the bumps, about the normal before they bend it.
                clearcoat: 0.8,
                clearcoat_roughness: 0.15,
            },
            normal_texture: Some(NormalTex {
                texture: 3,
                scale: Vec3::new(1.6, 1.6, 2.0),
                bias: Vec3::new(-0.8, -0.8, -1.0),
                strength: 1.3,
            }),
            // The coat's roughness alone from a texture (another one than the weight's), its
            // own normal map the base's mirrored.
            clearcoat_roughness_texture: channel(1, 2),
            clearcoat_normal_texture: Some(NormalTex {
                texture: 3,
                scale: Vec3::new(-1.6, 1.6, 2.0),
                bias: Vec3::new(0.8, -0.8, -1.0),
                strength: 1.0,
            }),
            ..Default::default()
        },
        SurfaceMaterial {
            material: Material {
                metallic: 1.0,
                ..Material::default()
            },
            texture: Some(1),
            metallic_texture: channel(0, 0),
            ..Default::default()
        },
        SurfaceMaterial {
            material: Material {
                base_color: Vec3::splat(0.9),
                roughness: 1.0,
                metallic: 1.0,
                specular: 0.04,
                ..Material::default()
            },
            roughness_texture: channel(2, 1),
            metallic_texture: channel(2, 2),
            ..Default::default()
        },
    ];
    let env = sun_env(EnvFrame {
        z_up: false,
        rotation: 0.3,
    });
    let bscene = BeautyScene {
        env: &env,
        env_frame: env.frame,
        env_lights: true,
        lights: LightSet::one(KeyLight::from_angles(-30.0, 40.0, 2.0, false)),
        materials: &materials,
        textures: &textures,
        tangents: &prismbake::tangent::corner_tangents(&ex.scene.table),
        base_normals: &prismbake::tangent::corner_normals(&ex.scene.table),
        emissive: true,
        prisms: &ex.scene.table.prisms,
        ground: None,
        bounces: 2,
        eps: ground_and_eps(&ex, Vec3::Y).1,
        exposure: 1.0,
    };
    let settings = RenderSettings {
        width: 64,
        height: 64,
        spp: 3,
        seed: 5,
    };
    check(rel, &ex, &bscene, &settings, "4 materials, 4 textures");
}

#[test]
fn metal_and_mirror_under_a_sun_match_the_cpu() {
    // Importance sampling of a lopsided map in a rotated Z-up frame, a rough metal (GGX VNDF
    // and MIS on both lobes' pdfs) and a perfect mirror (the delta lobe, MIS weight 1), three
    // bounces, no key light, no ground; then each under a key disc alone, and glowing alone.
    let rel = "torus/torus.obj";
    let ex = example_scene(rel);
    let env = sun_env(EnvFrame {
        z_up: true,
        rotation: 1.1,
    });
    let eps = ground_and_eps(&ex, Vec3::Y).1;
    let settings = RenderSettings {
        width: 48,
        height: 48,
        spp: 3,
        seed: 11,
    };
    for (label, material) in [
        (
            "metal",
            Material {
                base_color: Vec3::new(0.9, 0.6, 0.3),
                roughness: 0.3,
                metallic: 1.0,
                specular: 0.04,
                specular_tint: Vec3::new(1.0, 0.7, 0.4),
                ..Material::default()
            },
        ),
        (
            "mirror",
            Material {
                base_color: Vec3::new(0.8, 0.8, 0.8),
                roughness: 0.0,
                metallic: 0.5,
                specular: 0.04,
                specular_tint: Vec3::new(0.5, 0.8, 1.0),
                ..Material::default()
            },
        ),
        (
            // A mirror clearcoat (a delta lobe) over a rough dark dielectric.
            "clearcoat",
            Material {
                base_color: Vec3::new(0.1, 0.05, 0.3),
                roughness: 0.6,
                clearcoat: 1.0,
                clearcoat_roughness: 0.0,
                ..Material::default()
            },
        ),
    ] {
        let bscene = BeautyScene {
            env: &env,
            env_frame: env.frame,
            env_lights: true,
            lights: LightSet::none(),
            materials: &[SurfaceMaterial::from(material)],
            textures: &[],
            tangents: &[],
            base_normals: &[],
            emissive: false,
            prisms: &ex.scene.table.prisms,
            ground: None,
            bounces: 3,
            eps,
            exposure: 1.0,
        };
        check(rel, &ex, &bscene, &settings, label);
        // The same surface lit by a wide key disc alone: its BSDF samples meet the disc (a
        // mirror's only way to see it), weighted against the shadow rays by MIS, and a last
        // bounce tests its escape towards the disc with a key shadow ray.
        // (A grey backdrop the camera sees, which lights nothing: `env_lights` false.)
        let backdrop = EnvMap::constant(Vec3::splat(0.6), env.frame);
        let keyed = BeautyScene {
            env: &backdrop,
            env_lights: false,
            // A bluish disc: the mirror's delta lobe sees it in its colour.
            lights: LightSet::one(
                KeyLight::from_angles(20.0, 35.0, 12.0, false)
                    .with_angle(40.0)
                    .with_color(Vec3::new(0.7, 1.0, 1.6)),
            ),
            bounces: 2,
            ..bscene
        };
        check(
            rel,
            &ex,
            &keyed,
            &settings,
            &format!("{label}, key disc alone"),
        );
        // The same surface under a softbox behind the camera, facing the asset, and a sphere
        // light above it: BSDF samples meet both (the mirror's only way to see them), weighted
        // against their shadow rays by MIS; the last bounce finds how far its surface is
        // wherever its ray meets one of them.
        let (lo, hi) = ex.scene.table.bounds();
        let centre = (lo + hi) * 0.5;
        let size = (hi - lo).length();
        let back = (ex.cam.from - centre).normalize();
        let side = back.cross(Vec3::Y).normalize();
        let rise = side.cross(back);
        let softbox = Light {
            shape: LightShape::Area {
                pos: centre + back * (1.5 * size),
                u: rise * (0.6 * size),
                v: side * (0.8 * size),
                disk: false,
            },
            power: 2.0,
            color: Vec3::new(1.0, 0.9, 0.8),
        };
        let sphere = Light {
            shape: LightShape::Local {
                pos: centre + rise * size + back * (0.3 * size),
                radius: 0.15 * size,
                spot: None,
            },
            power: 4.0 * size * size,
            color: Vec3::new(0.6, 0.9, 1.5),
        };
        let lamps = BeautyScene {
            env: &backdrop,
            env_lights: false,
            lights: LightSet::new(&[softbox, sphere]),
            bounces: 2,
            ..bscene
        };
        check(
            rel,
            &ex,
            &lamps,
            &settings,
            &format!("{label}, softbox and sphere light"),
        );
        // The same surface glowing before the backdrop: all its light is its own emission,
        // seen directly, at each bounce's hit, and by the last bounce's closest-hit ray (the
        // torus sees itself across its hole).
        let glowing = [SurfaceMaterial {
            emission: Vec3::new(1.5, 1.0, 0.5),
            ..SurfaceMaterial::from(material)
        }];
        let glow = BeautyScene {
            env: &backdrop,
            env_lights: false,
            materials: &glowing,
            emissive: true,
            // One bounce: its ray is the last, so the glow it finds is all the
            // interreflection.
            bounces: 1,
            ..bscene
        };
        check(rel, &ex, &glow, &settings, &format!("{label}, glowing"));
    }
}

#[test]
fn wavefront_path_records_are_sized_to_the_frame_and_fused_takes_none() {
    // The wavefront's path records (PATH_RECORD_BYTES per pixel) live beside the sums and the
    // read-back, sized to the largest frame rendered; the fused kernel allocates none.
    use prismbake_gpu::layout::{GpuBeautySums, PATH_RECORD_BYTES};
    let rel = "torus/torus.obj";
    let ex = example_scene(rel);
    let env = sun_env(EnvFrame {
        z_up: false,
        rotation: 0.0,
    });
    let bscene = BeautyScene {
        env: &env,
        env_frame: env.frame,
        env_lights: true,
        lights: LightSet::none(),
        materials: &[SurfaceMaterial::from(Material::default())],
        textures: &[],
        tangents: &[],
        base_normals: &[],
        emissive: false,
        prisms: &ex.scene.table.prisms,
        ground: None,
        bounces: 2,
        eps: ground_and_eps(&ex, Vec3::Y).1,
        exposure: 1.0,
    };
    let sums = std::mem::size_of::<GpuBeautySums>() as u64;
    for schedule in [BeautySchedule::Wavefront, BeautySchedule::Fused] {
        let own = prismbake_gpu::GpuContext::new().expect("a context of its own");
        let scene = GpuScene::upload(&own, &ex.scene).expect("upload");
        let lighting = GpuBeautyScene::upload(&own, &bscene).expect("lighting upload");
        let render = |w: u32, h: u32| {
            let s = RenderSettings {
                width: w,
                height: h,
                spp: 1,
                seed: 3,
            };
            prismbake_gpu::render_beauty_scheduled(
                &own,
                schedule,
                &scene,
                &lighting,
                &ex.cam,
                &s,
                &PdmOptions::default(),
                &|_| {},
            )
            .expect("gpu beauty")
        };
        let per_pixel = match schedule {
            BeautySchedule::Wavefront => 2 * sums + PATH_RECORD_BYTES,
            BeautySchedule::Fused => 2 * sums,
        };
        let small = render(40, 24);
        assert_eq!(own.tile_buffer_bytes(), 40 * 24 * per_pixel, "{schedule:?}");
        render(64, 48);
        assert_eq!(own.tile_buffer_bytes(), 64 * 48 * per_pixel, "{schedule:?}");
        let again = render(40, 24);
        assert_eq!(
            own.tile_buffer_bytes(),
            64 * 48 * per_pixel,
            "{schedule:?}: kept for the smaller frame"
        );
        assert_eq!(
            small.rgba, again.rgba,
            "{schedule:?}: a frame after a larger one"
        );
        assert!(small.counters.rays > 40 * 24, "{schedule:?}: no surface");
    }
}
