//! Lookdev end to end: beauty renders (determinism, white furnace, shadow-ray accounting),
//! contact sheets, `render DIR` batches, `--watch` re-renders and the prism-table cache.

use crate::util::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn beauty_is_the_same_for_one_and_two_threads() {
    let (a, b) = (temp_dir("beauty-t1"), temp_dir("beauty-t2"));
    let rock = example("rock/rock.glb");
    for (dir, threads) in [(&a, "1"), (&b, "2")] {
        run(&[
            "render",
            s(&rock),
            "--res",
            "24x24",
            "--spp",
            "3",
            "--aov",
            "beauty",
            "--key-light",
            "40,50,2",
            "--ground",
            "--bounces",
            "2",
            "--threads",
            threads,
            "-o",
            s(dir),
        ])
        .assert_success();
    }
    assert!(
        read(&a.join("beauty.exr")) == read(&b.join("beauty.exr")),
        "beauty.exr differs between 1 and 2 threads"
    );
    assert!(read(&a.join("beauty.png")) == read(&b.join("beauty.png")));
    let img = image::open(a.join("beauty.png")).unwrap();
    assert_eq!((img.width(), img.height()), (24, 24));
}

/// White furnace: a convex object (the sphere without displacement) with a white Lambert
/// material in a constant environment of radiance 1, direct light only, must be 1 everywhere
/// it covers the pixel: ∫ (1/π) cos dω = 1. Tolerance: 3% on the mean (bias), 25% per pixel
/// (noise of 32 MIS samples; smooth shading normals also lose a little energy where sampled
/// directions dip under the geometric normal).
#[test]
fn white_furnace_converges_to_env_times_albedo() {
    let dir = temp_dir("furnace");
    let env = dir.join("white.exr");
    write_constant_env(&env, 1.0);
    let out = dir.join("out");
    run(&[
        "render",
        s(&example("sphere/sphere.glb")),
        "--scale",
        "0",
        "--res",
        "24x24",
        "--spp",
        "32",
        "--aov",
        "beauty",
        "--env",
        s(&env),
        "--base-color",
        "1,1,1",
        "--specular",
        "0",
        "--roughness",
        "1",
        "--bounces",
        "1",
        "-o",
        s(&out),
    ])
    .assert_success();
    let px: Vec<[f32; 4]> = read_rgba(&out.join("beauty.exr"))
        .into_iter()
        .filter(|p| p[3] >= 0.999)
        .collect();
    assert!(px.len() > 50, "the sphere covers the image");
    let mean = px
        .iter()
        .map(|p| (p[0] + p[1] + p[2]) as f64 / 3.0)
        .sum::<f64>()
        / px.len() as f64;
    assert!((mean - 1.0).abs() < 0.03, "furnace mean {mean}");
    for p in &px {
        assert!((p[0] - 1.0).abs() < 0.25, "furnace pixel {p:?}");
    }
    // Background pixels are transparent and black in the EXR (the env shows only in the PNG).
    assert!(read_rgba(&out.join("beauty.exr"))
        .iter()
        .any(|p| p[3] == 0.0 && p[0] == 0.0));
}

#[test]
fn shadow_rays_only_for_lights_that_exist() {
    let dir = temp_dir("shadow-rays");
    let sphere = example("sphere/sphere.glb");
    let json = |extra: &[&str], name: &str| {
        let mut args = vec![
            "render",
            s(&sphere),
            "--res",
            "16x16",
            "--spp",
            "2",
            "--json",
        ];
        args.extend_from_slice(extra);
        let out = dir.join(name);
        args.extend_from_slice(&["-o", s(&out)]);
        run(&args).assert_success().json()
    };
    let aov_only = json(&["--aov", "depth,normal"], "aov");
    assert_eq!(
        aov_only["beauty_rays"]["rays"], 0,
        "an AOV-only render does no shading"
    );
    assert_eq!(aov_only["shadow_rays"], 0);
    let env_only = json(&["--aov", "beauty"], "env");
    assert_eq!(
        env_only["beauty_rays"]["key_shadow_rays"], 0,
        "no key light, no key-light shadow rays"
    );
    assert!(env_only["beauty_rays"]["env_shadow_rays"].as_u64().unwrap() > 0);
    let dark = json(&["--aov", "beauty", "--env-intensity", "0"], "dark");
    assert_eq!(dark["shadow_rays"], 0, "no light at all: no shadow rays");
    let key = json(
        &[
            "--aov",
            "beauty",
            "--env-intensity",
            "0",
            "--key-light",
            "0,45,3",
        ],
        "key",
    );
    assert!(key["beauty_rays"]["key_shadow_rays"].as_u64().unwrap() > 0);
    assert_eq!(key["beauty_rays"]["env_shadow_rays"], 0);
}

#[test]
fn turntables_get_contact_sheets_of_the_frames_rendered() {
    let (full, part) = (temp_dir("sheet-full"), temp_dir("sheet-part"));
    let sphere = example("sphere/sphere.glb");
    run(&[
        "render",
        s(&sphere),
        "--res",
        "12x8",
        "--turntable",
        "5",
        "--aov",
        "mask,beauty",
        "-o",
        s(&full),
    ])
    .assert_success();
    for name in ["mask_contact_sheet.png", "beauty_contact_sheet.png"] {
        let img = image::open(full.join(name)).unwrap();
        assert_eq!(
            (img.width(), img.height()),
            (3 * 12, 2 * 8),
            "{name}: 5 frames in a 3x2 grid"
        );
    }
    run(&[
        "render",
        s(&sphere),
        "--res",
        "12x8",
        "--turntable",
        "5",
        "--frames",
        "1-2",
        "--aov",
        "mask",
        "-o",
        s(&part),
    ])
    .assert_success();
    let img = image::open(part.join("mask_contact_sheet.png")).unwrap();
    assert_eq!(
        (img.width(), img.height()),
        (2 * 12, 8),
        "2 frames side by side"
    );
    // The sheet's first tile is frame 1 of the full run.
    let tile = |dir: &Path, x0: u32| {
        let im = image::open(dir.join("mask_contact_sheet.png"))
            .unwrap()
            .to_rgb8();
        (0..8)
            .flat_map(|y| (0..12).map(move |x| (x, y)))
            .map(|(x, y)| im.get_pixel(x0 + x, y).0)
            .collect::<Vec<_>>()
    };
    assert_eq!(tile(&part, 0), tile(&full, 12));
}

/// A folder with the sphere (its own sidecar) and a broken OBJ.
/// `--turntable-mode`: what a frame's key light falls on. The sphere lit by a key light from
/// the camera's side (no environment), 4 frames: where the asset turns, every frame sees a
/// lit face; where the camera orbits a still scene, frame 2 looks at the side the light
/// does not reach; where the lights turn, so does the light, away from the still camera.
#[test]
fn a_turntable_turns_the_asset_the_camera_or_the_lights() {
    let dir = temp_dir("turntable-modes");
    let sphere = example("sphere/sphere.glb");
    let render = |mode: &str| {
        let out = dir.join(mode);
        run(&[
            "render",
            s(&sphere),
            "--res",
            "24x24",
            "--spp",
            "2",
            "--turntable",
            "4",
            "--turntable-mode",
            mode,
            "--aov",
            "mask,beauty",
            "--env-intensity",
            "0",
            "--key-light",
            "0,30,3",
            "--no-cache",
            "-o",
            s(&out),
        ])
        .assert_success();
        let frames: Vec<(f64, Vec<f32>)> = (0..4)
            .map(|f| {
                let rgba = read_rgba(&out.join(format!("beauty_{f:04}.exr")));
                let light = rgba.iter().map(|p| (p[0] + p[1] + p[2]) as f64).sum();
                let [mask] = read_channels(&out.join(format!("mask_{f:04}.exr")), ["Y"]);
                (light, mask)
            })
            .collect();
        frames
    };
    let (asset, camera, lights) = (render("asset"), render("camera"), render("lights"));
    let ratio = |frames: &[(f64, Vec<f32>)]| frames[2].0 / frames[0].0;
    let (a, c, l) = (ratio(&asset), ratio(&camera), ratio(&lights));
    assert!(
        (0.8..1.25).contains(&a),
        "asset: frame 2 / frame 0 light {a}"
    );
    assert!(c < 0.3, "camera: frame 2 / frame 0 light {c}");
    assert!(l < 0.3, "lights: frame 2 / frame 0 light {l}");
    // Frame 0 is the same picture in every mode; the camera moves only where it orbits.
    for (mode, frames) in [("camera", &camera), ("lights", &lights)] {
        assert!(
            (frames[0].0 - asset[0].0).abs() <= 1e-6 * asset[0].0,
            "{mode}: frame 0 light {} against {}",
            frames[0].0,
            asset[0].0
        );
    }
    assert_eq!(asset[1].1, camera[1].1, "the same orbit");
    assert_eq!(lights[1].1, lights[0].1, "a still camera");
    assert_ne!(asset[1].1, asset[0].1, "an orbit");
    // A mode needs a turntable; an unknown one is refused.
    let out = dir.join("none");
    run(&[
        "render",
        s(&sphere),
        "--turntable-mode",
        "lights",
        "-o",
        s(&out),
    ])
    .assert_error(&["--turntable-mode lights needs --turntable N"]);
    assert!(!out.exists() || files_in(&out).is_empty());
    run(&[
        "render",
        s(&sphere),
        "--turntable",
        "2",
        "--turntable-mode",
        "object",
        "-o",
        s(&out),
    ])
    .assert_code(2);
}

/// `--exposure EV` brightens the previews (PNG, contact sheet) by 2^EV before the filmic
/// curve and leaves the linear EXR as it was; a value out of range is refused.
#[test]
fn exposure_brightens_the_previews_and_leaves_the_exr_linear() {
    let dir = temp_dir("exposure");
    let torus = example("torus/torus.obj");
    let render = |ev: &str| {
        let out = dir.join(format!("ev{ev}"));
        run(&[
            "render",
            s(&torus),
            "--res",
            "16x16",
            "--aov",
            "beauty",
            "--exposure",
            ev,
            "--no-cache",
            "-o",
            s(&out),
        ])
        .assert_success();
        let png = image::open(out.join("beauty.png")).unwrap().to_rgb8();
        let mean = png.pixels().map(|p| p.0[1] as f64).sum::<f64>() / 256.0;
        (read_rgba(&out.join("beauty.exr")), mean)
    };
    let (plain, up, down) = (render("0"), render("1.5"), render("-2"));
    assert_eq!(
        plain.0, up.0,
        "the EXR is the radiance whatever the exposure"
    );
    assert_eq!(plain.0, down.0);
    assert!(up.1 > plain.1 + 10.0, "{} against {}", up.1, plain.1);
    assert!(down.1 < plain.1 - 10.0, "{} against {}", down.1, plain.1);
    for ev in ["40", "nan"] {
        run(&[
            "render",
            s(&torus),
            "--aov",
            "beauty",
            "--exposure",
            ev,
            "-o",
            s(&dir.join("bad")),
        ])
        .assert_error(&["--exposure", "stops"]);
    }
}

/// `--key-angle`: a key light with a size softens the shadows it casts (on the ground
/// catcher: more pixels partly shadowed; measured 110 against 47) and lights the asset with
/// the same irradiance (the lit sphere as bright within a few percent); it needs a key light
/// and a sane angle.
#[test]
fn a_key_light_with_an_angle_casts_soft_shadows_at_the_same_irradiance() {
    let dir = temp_dir("key-angle");
    let sphere = example("sphere/sphere.glb");
    let render = |angle: &str| {
        let out = dir.join(format!("angle{angle}"));
        run(&[
            "render",
            s(&sphere),
            "--res",
            "40x40",
            "--spp",
            "16",
            "--aov",
            "mask,beauty",
            "--env-intensity",
            "0",
            "--key-light",
            "100,25,3",
            "--key-angle",
            angle,
            "--ground",
            "--no-cache",
            "-o",
            s(&out),
        ])
        .assert_success();
        let rgba = read_rgba(&out.join("beauty.exr"));
        let [mask] = read_channels(&out.join("mask.exr"), ["Y"]);
        let lit: Vec<f64> = (rgba.iter().zip(&mask))
            .filter(|(_, m)| **m > 0.5)
            .map(|(p, _)| (p[0] + p[1] + p[2]) as f64)
            .collect();
        let penumbra = (rgba.iter().zip(&mask))
            .filter(|(p, m)| **m < 0.5 && p[3] > 0.1 && p[3] < 0.9)
            .count();
        (lit.iter().sum::<f64>() / lit.len() as f64, penumbra)
    };
    let (hard, soft) = (render("0"), render("30"));
    assert!(
        (soft.0 / hard.0 - 1.0).abs() < 0.05,
        "the asset's light: {} soft against {} hard",
        soft.0,
        hard.0
    );
    assert!(
        soft.1 * 5 > hard.1 * 8,
        "partly shadowed ground pixels: {} soft against {} hard",
        soft.1,
        hard.1
    );
    for (args, needle) in [
        (
            vec!["--key-angle", "5"],
            "--key-angle and --key-color need --key-light",
        ),
        (
            vec!["--key-color", "1,0.5,0"],
            "--key-angle and --key-color need --key-light",
        ),
        (
            vec!["--key-light", "0,30,1", "--key-color", "0,0,0"],
            "--key-color 0,0,0",
        ),
        (
            vec!["--key-light", "0,30,1", "--key-color", "1,-1,1"],
            "--key-color 1,-1,1",
        ),
        (
            vec!["--key-light", "0,30,1", "--key-angle", "120"],
            "--key-angle 120",
        ),
    ] {
        let mut all = vec!["render", s(&sphere), "--aov", "beauty"];
        all.extend(args);
        all.extend(["-o", s(&dir)]);
        run(&all).assert_error(&[needle]);
    }
}

fn batch_folder() -> PathBuf {
    let dir = temp_dir("batch-in");
    std::fs::copy(example("sphere/sphere.glb"), dir.join("sphere.glb")).unwrap();
    let map = example("maps/rock_1024.png");
    std::fs::write(
        dir.join("sphere.prismbake.toml"),
        format!("disp = {:?}\nscale = 0.05\n", s(&map)),
    )
    .unwrap();
    std::fs::write(
        dir.join("broken.obj"),
        "v 1 2\nf 1 2 9\nthis is not an obj\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("broken.prismbake.toml"),
        format!("disp = {:?}\n", s(&map)),
    )
    .unwrap();
    dir
}

#[test]
fn render_dir_continues_past_a_broken_asset() {
    let input = batch_folder();
    let out = temp_dir("batch-out");
    let r = run(&[
        "render",
        s(&input),
        "--res",
        "16x16",
        "--aov",
        "mask",
        "-o",
        s(&out),
    ]);
    r.assert_code(1);
    assert!(
        r.stderr.contains("broken.obj") && r.stderr.contains("1 failed"),
        "{}",
        r.stderr
    );
    assert!(r.stderr.contains("rendered 1 of 2 assets"), "{}", r.stderr);
    assert_eq!(files_in(&out.join("sphere")), vec!["mask.exr", "mask.png"]);
    assert!(!r.stderr.contains("panicked"));
}

#[test]
fn table_cache_is_reused_unless_disabled() {
    let dir = temp_dir("cache");
    let cache = dir.join("cache");
    let torus = example("torus/torus.obj");
    let render = |extra: &[&str]| {
        let mut args = vec!["render", s(&torus), "--res", "8x8", "--aov", "mask", "-o"];
        let out = dir.join("out");
        args.push(s(&out));
        args.extend_from_slice(extra);
        let o = Command::new(env!("CARGO_BIN_EXE_prismbake"))
            .args(&args)
            .env("XDG_CACHE_HOME", &cache)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let first = render(&[]);
    assert!(
        !first.contains("reused cached prism table") && first.contains("cached as"),
        "{first}"
    );
    let second = render(&[]);
    assert!(second.contains("reused cached prism table"), "{second}");
    let off = render(&["--no-cache"]);
    assert!(
        !off.contains("reused cached prism table") && !off.contains("cached as"),
        "{off}"
    );
}

/// A smooth 64² height map (68–188) with an optional line of 4 texels (x 8, y 20–23, in view of
/// the sphere's camera) set to `line`. A line one texel wide fills no prism's footprint, so
/// every prism it touches keeps texels of the smooth field: raising the line grows those
/// prisms' boxes (the BVH is rebuilt); lowering it again to a value above the field's keeps
/// them.
fn write_map(path: &Path, line: Option<u8>) {
    let img = image::GrayImage::from_fn(64, 64, |x, y| {
        let v = 128.0 + 60.0 * ((x as f32) * 0.3).sin() * ((y as f32) * 0.2).cos();
        match line {
            Some(l) if x == 8 && (20..24).contains(&y) => image::Luma([l]),
            _ => image::Luma([v as u8]),
        }
    });
    // Written next to the map and renamed over it, as editors save.
    let tmp = path.with_extension("tmp.png");
    img.save(&tmp).unwrap();
    std::fs::rename(&tmp, path).unwrap();
}

/// `render --watch` on `device`: a first render, an edit that raises a line of texels (a few
/// prisms re-baked, their boxes grown: the BVH is rebuilt), then one that lowers it part of the
/// way (the grown bounds still hold: the BVH is kept, and on the GPU the scene is rewritten in
/// place). Each re-render shows its map: both edits move the depth of some pixels. Returns the
/// watch's stderr, the final depth and the folder (its `ball.glb` now reads the final map).
fn watch_two_edits(device: &str) -> (String, Vec<f32>, PathBuf) {
    let dir = temp_dir(&format!("watch-{device}"));
    std::fs::copy(example("sphere/sphere.glb"), dir.join("ball.glb")).unwrap();
    let map = dir.join("h.png");
    write_map(&map, None);
    std::fs::write(
        dir.join("ball.prismbake.toml"),
        "disp = \"h.png\"\nscale = 0.05\n",
    )
    .unwrap();
    let out = dir.join("out");
    let mut child = Command::new(env!("CARGO_BIN_EXE_prismbake"))
        .args([
            "render",
            s(&dir.join("ball.glb")),
            "--device",
            device,
            "--res",
            "64x64",
            "--aov",
            "depth,mask",
            "--no-cache",
            "--watch",
            "--watch-max",
            "2",
            "-o",
            s(&out),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // stderr line by line, as the watch prints it.
    let lines = std::sync::Arc::new(std::sync::Mutex::new(Vec::<String>::new()));
    let reader = {
        let lines = lines.clone();
        let stderr = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            for l in std::io::BufRead::lines(std::io::BufReader::new(stderr)) {
                lines.lock().unwrap().push(l.unwrap());
            }
        })
    };
    let deadline = Instant::now() + Duration::from_secs(180);
    let wait_for = |what: &str, n: usize| {
        while lines
            .lock()
            .unwrap()
            .iter()
            .filter(|l| l.contains(what))
            .count()
            < n
        {
            if Instant::now() > deadline {
                let _ = Command::new("kill").arg(child.id().to_string()).status();
                panic!(
                    "{device}: no {n}× `{what}` in time:\n{}",
                    lines.lock().unwrap().join("\n")
                );
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    };
    let depth = || {
        let [y] = read_channels(&out.join("depth.exr"), ["Y"]);
        y
    };
    wait_for("watching", 1);
    let first = depth();
    std::thread::sleep(Duration::from_millis(300));
    write_map(&map, Some(255));
    wait_for("map changed", 1);
    let raised = depth();
    std::thread::sleep(Duration::from_millis(300));
    write_map(&map, Some(215));
    wait_for("map changed", 2);
    assert!(child.wait().unwrap().success());
    reader.join().unwrap();
    let stderr = lines.lock().unwrap().join("\n");
    let lowered = depth();
    // "re-baked K of N prisms": a 4x4-texel edit touches a few prisms, not the table.
    let events: Vec<&str> = stderr.lines().filter(|l| l.contains("re-baked")).collect();
    let nums: Vec<usize> = events[0]
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect();
    let (k, n) = (nums[0], nums[1]);
    assert!(k > 0 && k < n / 20, "re-baked {k} of {n}: {}", events[0]);
    assert!(
        events[0].contains("BVH rebuilt") && events[0].contains("re-rendered in"),
        "{stderr}"
    );
    assert!(
        events[1].contains("re-baked 0 of") && events[1].contains("BVH kept"),
        "{stderr}"
    );
    // Depth where both renders hit (0 elsewhere): each edit moves some pixels' depth by far
    // more than rounding.
    let moved = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .filter(|(x, y)| **x > 0.0 && **y > 0.0 && ((**x - **y) / **x).abs() > 1e-4)
            .count()
    };
    assert!(
        moved(&first, &raised) >= 2,
        "{device}: the raised line shows in no pixel"
    );
    assert!(
        moved(&raised, &lowered) >= 2,
        "{device}: the lowered line shows in no pixel"
    );
    (stderr, lowered, dir)
}

#[test]
fn watch_rerenders_after_a_map_edit_and_rebakes_few_prisms() {
    let (stderr, _, _) = watch_two_edits("cpu");
    assert!(!stderr.contains("gpu:"), "{stderr}");
}

#[test]
fn watch_on_the_gpu_rewrites_the_scene_in_place_when_the_bvh_is_kept() {
    let (stderr, lowered, dir) = watch_two_edits("gpu");
    // The scene rewritten in place renders the final map as a fresh CPU render of it does
    // (issue 4's parity bounds: depth within 1e-3 where both hit, masks within 0.5%).
    let out = dir.join("fresh");
    run(&[
        "render",
        s(&dir.join("ball.glb")),
        "--device",
        "cpu",
        "--res",
        "64x64",
        "--aov",
        "depth",
        "--no-cache",
        "-o",
        s(&out),
    ])
    .assert_success();
    let [fresh] = read_channels(&out.join("depth.exr"), ["Y"]);
    let (mut both, mut worse, mut one) = (0, 0, 0);
    for (g, c) in lowered.iter().zip(&fresh) {
        match (*g > 0.0, *c > 0.0) {
            (true, true) => {
                both += 1;
                worse += (((g - c) / c).abs() > 1e-3) as usize;
            }
            (false, false) => {}
            _ => one += 1,
        }
    }
    assert!(both > 500 && worse == 0, "{worse} of {both} pixels off");
    assert!(one * 200 <= fresh.len(), "{one} mask pixels differ");
    // The raise rebuilt the BVH (a new upload); the undo kept it (prisms and map rewritten).
    let gpu: Vec<&str> = stderr.lines().filter(|l| l.starts_with("gpu: ")).collect();
    assert_eq!(gpu.len(), 2, "{stderr}");
    assert!(gpu[0].contains("uploaded anew"), "{stderr}");
    assert!(gpu[1].contains("rewritten in place"), "{stderr}");
}

/// How much the colour (not the brightness) varies over the pixels the asset covers: the
/// standard deviation of each channel's share r / (r + g + b), summed over the channels.
fn colour_spread(path: &Path) -> f64 {
    let px: Vec<[f64; 3]> = read_rgba(path)
        .into_iter()
        .filter(|p| p[3] >= 0.999 && p[0] + p[1] + p[2] > 1e-3)
        .map(|p| {
            let sum = (p[0] + p[1] + p[2]) as f64;
            [p[0] as f64 / sum, p[1] as f64 / sum, p[2] as f64 / sum]
        })
        .collect();
    assert!(
        px.len() > 50,
        "{}: the asset covers too little",
        path.display()
    );
    (0..3)
        .map(|k| {
            let mean = px.iter().map(|p| p[k]).sum::<f64>() / px.len() as f64;
            (px.iter().map(|p| (p[k] - mean).powi(2)).sum::<f64>() / px.len() as f64).sqrt()
        })
        .sum()
}

fn render_rock_beauty(rock: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "render",
        s(rock),
        "--res",
        "40x40",
        "--spp",
        "2",
        "--aov",
        "beauty",
        "-o",
        s(out),
    ];
    args.extend_from_slice(extra);
    run(&args)
}

/// The rock's material has a base-colour texture (embedded in rock.glb, a colour per fish
/// scale): the beauty reads it without a word, its colours vary over the rock where a grey
/// material's do not, and `--base-color` replaces it.
#[test]
fn the_rocks_base_colour_texture_colours_its_beauty() {
    let dir = temp_dir("textured-rock");
    let rock = example("rock/rock.glb");
    let (textured, grey) = (dir.join("textured"), dir.join("grey"));
    let out = render_rock_beauty(&rock, &textured, &[]);
    out.assert_success();
    assert!(!out.stderr.contains("warning"), "{}", out.stderr);
    assert!(
        out.stderr
            .contains("beauty material 'rock_mat' (800 prisms): base colour (1, 1, 1) x texture rock_albedo, 256x256, repeat/repeat, bilinear, roughness 0.7, metallic 0,"),
        "{}",
        out.stderr
    );
    // --base-color replaces colour and texture; --roughness and --metallic the factors.
    let out = render_rock_beauty(
        &rock,
        &grey,
        &[
            "--base-color",
            "0.8,0.8,0.8",
            "--roughness",
            "0.25",
            "--metallic",
            "0.5",
        ],
    );
    out.assert_success();
    assert!(
        out.stderr.contains(
            "beauty material 'rock_mat' (800 prisms): base colour (0.8, 0.8, 0.8), roughness 0.25, metallic 0.5, specular 0.04"
        ),
        "{}",
        out.stderr
    );
    let (t, g) = (
        colour_spread(&textured.join("beauty.exr")),
        colour_spread(&grey.join("beauty.exr")),
    );
    eprintln!("colour spread: textured {t:.4}, grey {g:.4}");
    assert!(t > 0.05 && t > 4.0 * g, "textured {t:.4}, grey {g:.4}");
}

/// A base-colour texture that cannot be decoded fails a beauty render (naming the asset,
/// the image and the fix) before any file is written; renders that do not shade (AOVs) and
/// `--base-color` never read it.
#[test]
fn a_broken_base_colour_texture_fails_the_beauty_only() {
    let dir = temp_dir("broken-texture");
    let rock = rock_with_a_corrupt_texture(&dir);
    let out = dir.join("out");
    render_rock_beauty(&rock, &out, &[]).assert_error(&[
        "rock.glb",
        "base-colour texture 'rock_albedo'",
        "--base-color",
    ]);
    assert!(
        !out.exists() || files_in(&out).is_empty(),
        "{:?}",
        files_in(&out)
    );
    render_rock_beauty(&rock, &out, &["--base-color", "0.5,0.5,0.5"]).assert_success();
    run(&[
        "render",
        s(&rock),
        "--res",
        "16x16",
        "--aov",
        "depth",
        "-o",
        s(&dir.join("aov")),
    ])
    .assert_success();
}

/// A square facing +Z, its four vertices shared by two glTF primitives of one triangle each,
/// with UVs over it (`square.bin` beside it): the primitives take materials `materials[0]` and
/// `materials[1]`; `rest` gives the file's materials (and textures, samplers, images) as JSON
/// members.
fn square_gltf(dir: &Path, materials: [u32; 2], rest: &str) -> PathBuf {
    let positions: [f32; 12] = [-1., -1., 0., 1., -1., 0., 1., 1., 0., -1., 1., 0.];
    let normals: [f32; 12] = [0., 0., 1., 0., 0., 1., 0., 0., 1., 0., 0., 1.];
    let uvs: [f32; 8] = [0., 1., 1., 1., 1., 0., 0., 0.];
    let indices: [u16; 6] = [0, 1, 2, 0, 2, 3];
    let mut bin: Vec<u8> = positions
        .iter()
        .chain(&normals)
        .chain(&uvs)
        .flat_map(|f| f.to_le_bytes())
        .collect();
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    std::fs::write(dir.join("square.bin"), &bin).unwrap();
    let [m0, m1] = materials;
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
      "meshes":[{{"primitives":[
        {{"attributes":{{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2}},"indices":3,"material":{m0}}},
        {{"attributes":{{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2}},"indices":4,"material":{m1}}}]}}],
      {rest},
      "accessors":[
        {{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,-1,0],"max":[1,1,0]}},
        {{"bufferView":1,"componentType":5126,"count":4,"type":"VEC3"}},
        {{"bufferView":2,"componentType":5126,"count":4,"type":"VEC2"}},
        {{"bufferView":3,"byteOffset":0,"componentType":5123,"count":3,"type":"SCALAR"}},
        {{"bufferView":3,"byteOffset":6,"componentType":5123,"count":3,"type":"SCALAR"}}],
      "bufferViews":[
        {{"buffer":0,"byteOffset":0,"byteLength":48}},
        {{"buffer":0,"byteOffset":48,"byteLength":48}},
        {{"buffer":0,"byteOffset":96,"byteLength":32}},
        {{"buffer":0,"byteOffset":128,"byteLength":12}}],
      "buffers":[{{"byteLength":140,"uri":"square.bin"}}]}}"#
    );
    let path = dir.join("square.gltf");
    std::fs::write(&path, json).unwrap();
    path
}

/// `render SQUARE` head on (the camera 5 units along +Z, 30° across), a 32² beauty of `spp`
/// samples, displaced by the example fish scales times `scale`, `--json`, into `out`; then
/// `extra`.
fn render_square(square: &Path, scale: &str, spp: &str, out: &Path, extra: &[&str]) -> Output {
    let map = example("maps/scales_256.png");
    let mut args = vec![
        "render",
        s(square),
        "--disp",
        s(&map),
        "--scale",
        scale,
        "--res",
        "32x32",
        "--spp",
        spp,
        "--aov",
        "beauty",
        "--camera-from",
        "0,0,5",
        "--camera-to",
        "0,0,0",
        "--fov",
        "30",
        "--json",
        "-o",
        s(out),
    ];
    args.extend_from_slice(extra);
    run(&args)
}

/// The square (`square_gltf`) with a red material on its first triangle, a blue one on its
/// second.
fn two_material_square(dir: &Path) -> PathBuf {
    square_gltf(
        dir,
        [0, 1],
        r#""materials":[
        {"name":"red","pbrMetallicRoughness":{"baseColorFactor":[0.8,0.05,0.05,1],"metallicFactor":0,"roughnessFactor":0.6}},
        {"name":"blue","pbrMetallicRoughness":{"baseColorFactor":[0.05,0.05,0.8,1],"metallicFactor":0,"roughnessFactor":0.6}}]"#,
    )
}

/// Each primitive's material shades its own triangle: red below the square's diagonal, blue
/// above it, on the CPU and the GPU; the summary lists both with their prism counts.
#[test]
fn each_gltf_material_shades_its_own_triangles() {
    let dir = temp_dir("two-materials");
    let square = two_material_square(&dir);
    for device in ["cpu", "gpu"] {
        let out = dir.join(device);
        let o = render_square(&square, "0.02", "2", &out, &["--device", device]);
        o.assert_success();
        let names: Vec<(String, u64)> = o.json()["materials"]
            .as_array()
            .expect("materials in the summary")
            .iter()
            .map(|m| {
                (
                    m["name"].as_str().unwrap().to_string(),
                    m["prisms"].as_u64().unwrap(),
                )
            })
            .collect();
        assert_eq!(names, [("red".into(), 1), ("blue".into(), 1)], "{device}");
        // Row 0 of the image is the top (+Y): the blue triangle (0, 2, 3) holds the top-left
        // corner, the red one (0, 1, 2) the bottom-right.
        let px = read_rgba(&out.join("beauty.exr"));
        let at = |x: usize, y: usize| px[y * 32 + x];
        for (x, y, red) in [
            (7, 7, false),
            (24, 24, true),
            (12, 8, false),
            (26, 14, true),
        ] {
            let p = at(x, y);
            assert!(
                p[3] > 0.99,
                "{device}: pixel ({x}, {y}) is not on the square: {p:?}"
            );
            let (r, b) = (p[0], p[2]);
            assert!(
                if red { r > 4.0 * b } else { b > 4.0 * r },
                "{device}: pixel ({x}, {y}) should be {}: {p:?}",
                if red { "red" } else { "blue" }
            );
        }
    }
}

/// `--env` takes a Radiance `.hdr` as well as an EXR: the same radiance in either renders the
/// same beauty, byte for byte, on the CPU and on the GPU.
#[test]
fn a_radiance_hdr_environment_lights_as_its_exr_twin() {
    use image::codecs::hdr::{HdrDecoder, HdrEncoder};
    use image::ImageDecoder;
    let dir = temp_dir("env-hdr");
    let (w, h) = (32usize, 16usize);
    let sky: Vec<image::Rgb<f32>> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let sun = if (x, y) == (9, 4) { 400.0 } else { 0.0 };
            image::Rgb([
                0.3 + sun,
                0.4 + 0.05 * y as f32,
                0.9 - 0.04 * y as f32 + sun,
            ])
        })
        .collect();
    let hdr = dir.join("sky.hdr");
    let mut bytes = Vec::new();
    HdrEncoder::new(&mut bytes).encode(&sky, w, h).unwrap();
    std::fs::write(&hdr, &bytes).unwrap();
    // The texels the .hdr holds (RGBE-rounded), written as an EXR.
    let decoder = HdrDecoder::new(std::io::Cursor::new(&bytes)).unwrap();
    let mut raw = vec![0u8; decoder.total_bytes() as usize];
    decoder.read_image(&mut raw).unwrap();
    let floats: Vec<f32> = raw
        .chunks_exact(4)
        .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    let ch = |name, k: usize| (name, floats.iter().skip(k).step_by(3).copied().collect());
    let exr = dir.join("sky.exr");
    write_exr(&exr, w, h, vec![ch("R", 0), ch("G", 1), ch("B", 2)], false);

    let render = |env: &Path, device: &str| {
        let out = dir.join(format!(
            "{}-{device}",
            env.extension().unwrap().to_str().unwrap()
        ));
        run(&[
            "render",
            s(&example("sphere/sphere.glb")),
            "--res",
            "24x24",
            "--spp",
            "4",
            "--aov",
            "beauty",
            "--env",
            s(env),
            "--device",
            device,
            "-o",
            s(&out),
        ])
        .assert_success();
        read(&out.join("beauty.exr"))
    };
    for device in ["cpu", "gpu"] {
        let (from_hdr, from_exr) = (render(&hdr, device), render(&exr, device));
        assert!(
            from_hdr == from_exr,
            "{device}: the .hdr and its EXR twin differ"
        );
    }
    // The sun lights the sphere: the picture is not the sky's ambient alone.
    let lit = read_rgba(&dir.join("hdr-cpu/beauty.exr"));
    let peak = lit.iter().map(|p| p[0].max(p[2])).fold(0.0f32, f32::max);
    assert!(peak > 1.0, "brightest pixel {peak}");
}

/// A material whose values are not numbers (an `.mtl`'s `Kd nan 0.5 inf`, `Pr nan`, `Ke inf`) fails the
/// beauty before any frame, naming the file, the material and the flag that overrides it (it
/// rendered NaN pixels before); the flags that override those values render it, and AOVs
/// never read materials.
#[test]
fn a_material_with_nan_values_fails_the_beauty_naming_the_override() {
    let dir = temp_dir("nan-material");
    let obj = dir.join("quad.obj");
    std::fs::write(
        &obj,
        "mtllib quad.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
         vn 0 0 1\nusemtl bad\nf 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("quad.mtl"),
        "newmtl bad\nKd nan 0.5 inf\nPr nan\nKe 0 inf 0\n",
    )
    .unwrap();
    let map = example("maps/scales_256.png");
    let render = |out: &str, aovs: &str, extra: &[&str]| {
        let mut args = vec![
            "render",
            s(&obj),
            "--disp",
            s(&map),
            "--scale",
            "0.05",
            "--res",
            "16x16",
            "--spp",
            "2",
            "--aov",
            aovs,
            "-o",
        ];
        let out = dir.join(out);
        args.push(s(&out));
        args.extend_from_slice(extra);
        (run(&args), out)
    };
    let (failed, out) = render("nan", "beauty", &[]);
    failed.assert_error(&["quad.obj", "material 'bad'", "base colour", "--base-color"]);
    assert!(!out.exists() || files_in(&out).is_empty());
    let (failed, _) = render("nan-roughness", "beauty", &["--base-color", "0.5,0.5,0.5"]);
    failed.assert_error(&["material 'bad'", "roughness", "--roughness"]);
    let overrides = ["--base-color", "0.5,0.5,0.5", "--roughness", "0.4"];
    let (failed, _) = render("nan-emission", "beauty", &overrides);
    failed.assert_error(&["material 'bad'", "emission", "--no-emission"]);
    let overrides = [&overrides[..], &["--no-emission"]].concat();
    let (ok, out) = render("overridden", "beauty", &overrides);
    ok.assert_success();
    let px = read_rgba(&out.join("beauty.exr"));
    assert!(px.iter().all(|p| p.iter().all(|v| v.is_finite())));
    assert!(px.iter().any(|p| p[3] > 0.5), "the quad is in view");
    let (aovs, _) = render("aovs", "depth,mask", &[]);
    aovs.assert_success();
    // `validate` fails the asset's `textures` check (the materials) for it.
    let report = run(&["validate", s(&obj), "--disp", s(&map)]);
    assert_ne!(report.code, 0, "{}", report.stdout);
    assert!(
        report.stdout.contains("textures")
            && report
                .stdout
                .contains("material 'bad' has a NaN or infinite base colour"),
        "{}",
        report.stdout
    );
}

/// The square (`square_gltf`, one material) whose roughness and metallic come from a
/// metallic-roughness texture `orm.png` (glTF's: roughness in green, metallic in blue, factors
/// left out: 1), clamped: its left half a rough dielectric, its right half a smooth metal.
/// Red, which glTF leaves to occlusion, is the opposite of blue, so that reading the wrong
/// channel shows.
fn metallic_roughness_square(dir: &Path) -> PathBuf {
    image::RgbImage::from_fn(4, 4, |x, _| {
        if x < 2 {
            image::Rgb([255, 255, 0])
        } else {
            image::Rgb([0, 20, 255])
        }
    })
    .save(dir.join("orm.png"))
    .unwrap();
    square_gltf(
        dir,
        [0, 0],
        r#""materials":[{"name":"half metal","pbrMetallicRoughness":{"baseColorFactor":[0.9,0.9,0.9,1],
        "metallicRoughnessTexture":{"index":0}}}],
      "textures":[{"source":0,"sampler":0}],
      "samplers":[{"wrapS":33071,"wrapT":33071}],
      "images":[{"uri":"orm.png"}]"#,
    )
}

/// Mean luminance of the square's left and right thirds (away from the texture's seam) in a
/// 32² beauty EXR.
fn left_right_luminance(path: &Path) -> (f32, f32) {
    let px = read_rgba(path);
    let mean = |xs: std::ops::Range<usize>| {
        let mut sum = 0.0;
        let mut n = 0;
        for y in 10..22 {
            for x in xs.clone() {
                let p = px[y * 32 + x];
                assert!(p[3] > 0.99, "pixel ({x}, {y}) is not on the square");
                sum += 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
                n += 1;
            }
        }
        sum / n as f32
    };
    (mean(7..12), mean(20..25))
}

/// The metallic-roughness texture shades: under a key light off the mirror direction, its
/// rough dielectric half is lit and its smooth metal half dark, on the CPU and the GPU alike;
/// the summary names the texture and its channels; `--roughness`/`--metallic` replace it; and
/// one that cannot be decoded fails the beauty naming it and the flags.
#[test]
fn a_metallic_roughness_texture_sets_roughness_and_metallic_per_texel() {
    let dir = temp_dir("metallic-roughness");
    let square = metallic_roughness_square(&dir);
    let render = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let lights = ["--env-intensity", "0", "--key-light", "30,40,3"];
        let o = render_square(&square, "0.002", "4", &out, &[&lights[..], extra].concat());
        (o, out.join("beauty.exr"))
    };
    let mut lit = vec![];
    for device in ["cpu", "gpu"] {
        let (o, exr) = render(device, &["--device", device]);
        o.assert_success();
        let m = &o.json()["materials"][0];
        assert_eq!(
            (m["roughness"].as_f64(), m["metallic"].as_f64()),
            (Some(1.0), Some(1.0))
        );
        for (key, channel) in [
            ("roughness_texture", "channel g"),
            ("metallic_texture", "channel b"),
        ] {
            let t = m[key].as_str().unwrap_or_default();
            assert!(
                t.starts_with("orm.png, 4x4, clamp/clamp") && t.ends_with(channel),
                "{key}: {t}"
            );
        }
        let (left, right) = left_right_luminance(&exr);
        eprintln!("{device}: rough dielectric {left:.4}, smooth metal {right:.4}");
        assert!(
            left > 0.05 && left > 10.0 * right,
            "{device}: left {left}, right {right}"
        );
        lit.push((left, right));
    }
    let (cpu, gpu) = (lit[0], lit[1]);
    assert!(
        (cpu.0 - gpu.0).abs() < 0.05 * cpu.0,
        "CPU {cpu:?}, GPU {gpu:?}"
    );
    // The command line's values replace the texture: both halves the same dielectric.
    let (o, exr) = render("override", &["--roughness", "1", "--metallic", "0"]);
    o.assert_success();
    let m = &o.json()["materials"][0];
    assert!(
        m.get("roughness_texture").is_none() && m.get("metallic_texture").is_none(),
        "{m}"
    );
    let (left, right) = left_right_luminance(&exr);
    assert!(
        (left - right).abs() < 0.1 * left,
        "left {left}, right {right}"
    );
    // KHR_texture_transform mirroring u (offset 1, scale −1) swaps the halves.
    let gltf = std::fs::read_to_string(&square).unwrap();
    let mirrored = gltf.replace(
        r#""metallicRoughnessTexture":{"index":0}"#,
        r#""metallicRoughnessTexture":{"index":0,"extensions":{"KHR_texture_transform":{"offset":[1,0],"scale":[-1,1]}}}"#,
    );
    assert_ne!(mirrored, gltf);
    std::fs::write(
        &square,
        mirrored.replacen('{', r#"{"extensionsUsed":["KHR_texture_transform"],"#, 1),
    )
    .unwrap();
    let (o, exr) = render("mirrored", &[]);
    o.assert_success();
    assert!(!o.stderr.contains("warning"), "{}", o.stderr);
    let (left, right) = left_right_luminance(&exr);
    assert!(
        right > 0.05 && right > 10.0 * left,
        "mirrored: left {left}, right {right}"
    );
    // A texture that does not decode fails the beauty before any file is written.
    std::fs::write(dir.join("orm.png"), b"\x89PNG\r\n\x1a\n truncated").unwrap();
    let (o, exr) = render("broken", &[]);
    o.assert_error(&[
        "square.gltf",
        "roughness texture 'orm.png'",
        "--roughness R",
    ]);
    assert!(!exr.exists());
}

/// The square (`square_gltf`, one white matte material) with a tangent-space normal map
/// `tilt.png` (clamped) whose left half tilts the normal `deg` degrees towards -x, its right
/// half towards +x (u runs along +x, so +x is the map's red), and glTF `scale` `scale`; the
/// normals the 8-bit codes decode to, left and right.
fn normal_map_square(dir: &Path, deg: f32, scale: f32) -> (PathBuf, [[f32; 3]; 2]) {
    let (sin, cos) = deg.to_radians().sin_cos();
    let code = |v: f32| ((v + 1.0) * 0.5 * 255.0).round() as u8;
    let (left, right) = ([code(-sin), 128, code(cos)], [code(sin), 128, code(cos)]);
    image::RgbImage::from_fn(4, 4, |x, _| image::Rgb(if x < 2 { left } else { right }))
        .save(dir.join("tilt.png"))
        .unwrap();
    // The decoded normal M, blended with the square's (+z) by the strength as Cycles' Normal
    // Map node does: normalize(N + (M − N) · scale).
    let normal = |c: [u8; 3]| {
        let unit = |v: [f32; 3]| {
            let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            v.map(|x| x / len)
        };
        let m = unit(c.map(|c| c as f32 / 255.0 * 2.0 - 1.0));
        unit([m[0] * scale, m[1] * scale, 1.0 + (m[2] - 1.0) * scale])
    };
    let path = square_gltf(
        dir,
        [0, 0],
        &format!(
            r#""materials":[{{"name":"tilted","pbrMetallicRoughness":{{"baseColorFactor":[0.9,0.9,0.9,1],
        "metallicFactor":0,"roughnessFactor":1}},"normalTexture":{{"index":0,"scale":{scale}}}}}],
      "textures":[{{"source":0,"sampler":0}}],
      "samplers":[{{"wrapS":33071,"wrapT":33071}}],
      "images":[{{"uri":"tilt.png"}}]"#
        ),
    );
    (path, [normal(left), normal(right)])
}

/// A normal map bends the shading normal in the tangent frame: a matte square whose map tilts
/// its left half 20° away from a key light 60° off its normal and its right half 20° towards
/// it shows Lambert's cosine of the bent normals, 0.9/π · 3 · cos(80° and 40°), times the
/// diffuse's shadowing about the square's own normal (GGX's G1 at 60° for α² = tan²(20°)/8),
/// on the CPU and the GPU, within 1%; `--no-normal-maps` and a grey map (a bump map: not read,
/// a warning) give the flat cos 60° on both halves; glTF's `scale` is the Normal Map Strength,
/// which blends the map's normal with the square's (0.5: half the tilt; 2: 37.9°, where
/// scaling x and y would give 36.1°, and a shadowing of 0.949).
#[test]
fn a_normal_map_bends_the_shading_normal_in_its_tangent_frame() {
    let dir = temp_dir("normal-map");
    let map = example("maps/scales_256.png");
    let render = |square: &Path, name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let lights = [
            "--env-intensity",
            "0",
            "--key-light",
            "60,0,3",
            "--specular",
            "0",
            "--bounces",
            "1",
        ];
        let o = render_square(square, "0", "2", &out, &[&lights[..], extra].concat());
        o.assert_success();
        let (left, right) = left_right_luminance(&out.join("beauty.exr"));
        (o, left, right)
    };
    // The key light: azimuth 60° from the square's normal (+z) towards +x, on the horizon.
    let l = [60f32.to_radians().sin(), 0.0, 60f32.to_radians().cos()];
    // Lambert's cosine of the bent normal n, times the shadowing about the unbent +z:
    // 2 / (1 + √(1 + α² tan²θi)), θi the light's angle from +z, α² = tan²(bend) / 8.
    let lambert = |n: [f32; 3]| {
        let cos_d = n[2];
        let alpha2 = (0.125 * (1.0 / (cos_d * cos_d) - 1.0)).min(1.0);
        let tan2_i = 1.0 / (l[2] * l[2]) - 1.0;
        let shadowing = 2.0 / (1.0 + (1.0 + alpha2 * tan2_i).sqrt());
        0.9 / std::f32::consts::PI * 3.0 * (n[0] * l[0] + n[2] * l[2]).max(0.0) * shadowing
    };
    let close = |got: f32, want: f32, what: &str| {
        assert!(
            (got - want).abs() <= 0.01 * want + 1e-4,
            "{what}: {got}, want {want}"
        );
    };
    let (square, [nl, nr]) = normal_map_square(&dir, 20.0, 1.0);
    for device in ["cpu", "gpu"] {
        let (o, left, right) = render(&square, device, &["--device", device]);
        eprintln!("{device}: left {left:.4}, right {right:.4}");
        close(left, lambert(nl), &format!("{device} left"));
        close(right, lambert(nr), &format!("{device} right"));
        assert_eq!(
            o.json()["materials"][0]["normal_texture"].as_str(),
            Some("tilt.png, 4x4, clamp/clamp, bilinear, strength 1")
        );
    }
    let flat = lambert([0.0, 0.0, 1.0]);
    let (o, left, right) = render(&square, "off", &["--no-normal-maps"]);
    assert!(o.json()["materials"][0].get("normal_texture").is_none());
    close(left, flat, "--no-normal-maps left");
    close(right, flat, "--no-normal-maps right");
    // glTF's scale, the strength: the map's normal blended with the square's.
    let (square, [nl, nr]) = normal_map_square(&dir, 20.0, 0.5);
    let (_, left, right) = render(&square, "half", &[]);
    close(left, lambert(nl), "scale 0.5 left");
    close(right, lambert(nr), "scale 0.5 right");
    assert!(
        (nr[0].asin().to_degrees() - 10.0).abs() < 0.3,
        "half the tilt: {nr:?}"
    );
    let (square, [nl, nr]) = normal_map_square(&dir, 20.0, 2.0);
    assert!(
        (nr[0].atan2(nr[2]).to_degrees() - 37.9).abs() < 0.3,
        "{nr:?}"
    );
    for device in ["cpu", "gpu"] {
        let (_, left, right) = render(&square, &format!("double-{device}"), &["--device", device]);
        close(left, lambert(nl), &format!("{device} scale 2 left"));
        close(right, lambert(nr), &format!("{device} scale 2 right"));
    }
    // A negative strength is clamped to 0, as Blender clamps it: the flat square, and a
    // warning that says so.
    let (square, _) = normal_map_square(&dir, 20.0, -1.0);
    let (o, left, right) = render(&square, "negative", &[]);
    close(left, flat, "scale -1 left");
    close(right, flat, "scale -1 right");
    assert!(
        o.stderr
            .contains("normal texture (tilt.png) has strength -1")
            && o.stderr.contains("clamps to 0"),
        "{}",
        o.stderr
    );
    // A grey image is a bump map, not a normal map: not read, and said so.
    image::GrayImage::from_pixel(4, 4, image::Luma([200]))
        .save(dir.join("tilt.png"))
        .unwrap();
    let (o, left, right) = render(&square, "grey", &[]);
    assert!(
        o.stderr.contains("normal map 'tilt.png' is a grey image"),
        "{}",
        o.stderr
    );
    // `validate`'s textures check says the same.
    let report = run(&[
        "validate",
        s(&square),
        "--disp",
        s(&map),
        "--format",
        "json",
    ]);
    assert!(
        report.stdout.contains("textures") && report.stdout.contains("is a grey image"),
        "{}",
        report.stdout
    );
    close(left, flat, "grey left");
    close(right, flat, "grey right");
}

/// A black square that glows: glTF `emissiveFactor` (0.2, 0.4, 0.8) times its
/// `KHR_materials_emissive_strength` 2.5, times an `emissiveTexture` (`glow.png`, clamped)
/// white on its left half and sRGB code 128 on its right.
fn glowing_square(dir: &Path) -> PathBuf {
    image::RgbImage::from_fn(4, 4, |x, _| {
        image::Rgb(if x < 2 { [255; 3] } else { [128; 3] })
    })
    .save(dir.join("glow.png"))
    .unwrap();
    square_gltf(
        dir,
        [0, 0],
        r#""extensionsUsed":["KHR_materials_emissive_strength"],
      "materials":[{"name":"lamp","pbrMetallicRoughness":{"baseColorFactor":[0,0,0,1],"metallicFactor":0},
        "emissiveFactor":[0.2,0.4,0.8],"emissiveTexture":{"index":0},
        "extensions":{"KHR_materials_emissive_strength":{"emissiveStrength":2.5}}}],
      "textures":[{"source":0,"sampler":0}],
      "samplers":[{"wrapS":33071,"wrapT":33071}],
      "images":[{"uri":"glow.png"}]"#,
    )
}

/// An emissive material glows: in the dark, a black square shows its emission times its
/// texture exactly (the left half (0.5, 1, 2), the right half that times sRGB 128's 0.2158),
/// on the CPU and the GPU; the summary states it; `--no-emission` turns it off.
#[test]
fn an_emissive_material_glows_by_its_factor_strength_and_texture() {
    let dir = temp_dir("emission");
    let square = glowing_square(&dir);
    let render = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let dark = ["--env-intensity", "0"];
        let o = render_square(&square, "0.002", "2", &out, &[&dark[..], extra].concat());
        o.assert_success();
        (o, read_rgba(&out.join("beauty.exr")))
    };
    let glow = [0.5f32, 1.0, 2.0];
    let grey = ((128.0f32 / 255.0 + 0.055) / 1.055).powf(2.4);
    let mean = |px: &[[f32; 4]], xs: std::ops::Range<usize>| {
        let mut sum = [0f32; 3];
        for y in 10..22 {
            for x in xs.clone() {
                for c in 0..3 {
                    sum[c] += px[y * 32 + x][c] / (12 * xs.len()) as f32;
                }
            }
        }
        sum
    };
    for device in ["cpu", "gpu"] {
        let (o, px) = render(device, &["--device", device]);
        let m = &o.json()["materials"][0];
        assert_eq!(m["emission"], serde_json::json!([0.5, 1.0, 2.0]), "{m}");
        assert_eq!(
            m["emission_texture"].as_str(),
            Some("glow.png, 4x4, clamp/clamp, bilinear")
        );
        let (left, right) = (mean(&px, 7..12), mean(&px, 20..25));
        eprintln!("{device}: left {left:?}, right {right:?}");
        for c in 0..3 {
            assert!((left[c] - glow[c]).abs() < 1e-4, "{device} left {left:?}");
            assert!(
                (right[c] - glow[c] * grey).abs() < 1e-4,
                "{device} right {right:?}"
            );
        }
    }
    let (o, px) = render("off", &["--no-emission"]);
    assert!(o.json()["materials"][0].get("emission").is_none());
    assert!(
        mean(&px, 7..25).iter().all(|&c| c < 1e-6),
        "{:?}",
        mean(&px, 7..25)
    );
}

/// A material's index of refraction sets its dielectric reflectance: on the square of a red
/// material (no IOR: F0 0.04) and a blue one of glTF `KHR_materials_ior` 2.0 (F0 1/9), made
/// black mirrors under an even white sky, each half shows its F0 (the mirror's Fresnel at
/// near-normal incidence), on the CPU and the GPU; `--specular` sets every material's.
#[test]
fn a_materials_index_of_refraction_sets_its_reflectance() {
    let dir = temp_dir("ior");
    let gltf = std::fs::read_to_string(two_material_square(&dir)).unwrap();
    let square = dir.join("ior.gltf");
    let with_ior = gltf.replace(
        r#""roughnessFactor":0.6}},
        {"name":"blue","pbrMetallicRoughness":{"baseColorFactor":[0.05,0.05,0.8,1],"metallicFactor":0,"roughnessFactor":0.6}}"#,
        r#""roughnessFactor":0.6}},
        {"name":"blue","pbrMetallicRoughness":{"baseColorFactor":[0.05,0.05,0.8,1],"metallicFactor":0,"roughnessFactor":0.6},
         "extensions":{"KHR_materials_ior":{"ior":2.0}}}"#,
    );
    assert_ne!(with_ior, gltf);
    std::fs::write(&square, with_ior).unwrap();
    let sky = dir.join("sky.exr");
    write_constant_env(&sky, 1.0);
    let map = example("maps/scales_256.png");
    let render = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mirrors = [
            "--env",
            s(&sky),
            "--base-color",
            "0,0,0",
            "--roughness",
            "0",
            "--bounces",
            "1",
        ];
        let o = render_square(&square, "0", "2", &out, &[&mirrors[..], extra].concat());
        o.assert_success();
        let f0: Vec<f64> = o.json()["materials"]
            .as_array()
            .expect("materials")
            .iter()
            .map(|m| m["specular"].as_f64().unwrap())
            .collect();
        let px = read_rgba(&out.join("beauty.exr"));
        // The red triangle holds the bottom-right corner, the blue one the top-left.
        (f0, px[24 * 32 + 24][1], px[7 * 32 + 7][1])
    };
    for device in ["cpu", "gpu"] {
        let (f0, red, blue) = render(device, &["--device", device]);
        eprintln!("{device}: F0 {f0:?}, red half {red}, blue half {blue}");
        assert!(
            (f0[0] - 0.04).abs() < 1e-6 && (f0[1] - 1.0 / 9.0).abs() < 1e-6,
            "{f0:?}"
        );
        assert!((red - 0.04).abs() < 0.02 * 0.04, "{device}: red {red}");
        assert!(
            (blue - 1.0 / 9.0).abs() < 0.02 / 9.0,
            "{device}: blue {blue}"
        );
    }
    // `inspect` states each material's reflectance.
    let info = run(&["inspect", s(&square), "--disp", s(&map)]);
    info.assert_success();
    assert!(
        info.stdout.contains("metallic 0, specular 0.11111")
            && info.stdout.contains("metallic 0, specular 0.04"),
        "{}",
        info.stdout
    );
    let (f0, red, blue) = render("override", &["--specular", "0.2"]);
    assert_eq!(f0, [0.2; 2]);
    assert!(
        (red - 0.2).abs() < 0.004 && (blue - 0.2).abs() < 0.004,
        "{red} {blue}"
    );
}

/// The clearcoat (glTF `KHR_materials_clearcoat`): on the square of a red material without one
/// and a blue one with a mirror coat of weight 0.5, both bases black and without specular,
/// under an even white sky, the red half is black and the blue one shows half the coat's
/// Fresnel head on (index 1.5: 0.04); `--clearcoat 1` gives both halves 0.04, and a white
/// Lambert base under it keeps all the light (the coat takes from the base what it reflects):
/// 1. On the CPU and the GPU; the summary and `inspect` name the coat.
#[test]
fn a_clearcoat_reflects_its_fresnel_and_takes_it_from_the_base() {
    let dir = temp_dir("clearcoat");
    let gltf = std::fs::read_to_string(two_material_square(&dir)).unwrap();
    let square = dir.join("coat.gltf");
    let coated = gltf.replace(
        r#""roughnessFactor":0.6}},
        {"name":"blue","pbrMetallicRoughness":{"baseColorFactor":[0.05,0.05,0.8,1],"metallicFactor":0,"roughnessFactor":0.6}}"#,
        r#""roughnessFactor":0.6}},
        {"name":"blue","pbrMetallicRoughness":{"baseColorFactor":[0.05,0.05,0.8,1],"metallicFactor":0,"roughnessFactor":0.6},
         "extensions":{"KHR_materials_clearcoat":{"clearcoatFactor":0.5}}}"#,
    );
    assert_ne!(coated, gltf);
    std::fs::write(&square, coated).unwrap();
    let sky = dir.join("sky.exr");
    write_constant_env(&sky, 1.0);
    // A black base needs few samples: only the coat's delta lobe reflects.
    let render = |name: &str, base: &str, extra: &[&str]| {
        let out = dir.join(name);
        let spp = if base == "0,0,0" { "2" } else { "32" };
        let flags = [
            "--env",
            s(&sky),
            "--base-color",
            base,
            "--specular",
            "0",
            "--bounces",
            "1",
        ];
        let o = render_square(&square, "0", spp, &out, &[&flags[..], extra].concat());
        o.assert_success();
        let px = read_rgba(&out.join("beauty.exr"));
        // The red triangle holds the bottom-right corner, the blue one the top-left: the
        // mean green of each, away from the diagonal between them.
        let half = |inside: &dyn Fn(usize) -> bool| {
            let v: Vec<f64> = (0..32 * 32)
                .filter(|&i| inside(i % 32 + i / 32) && px[i][3] >= 0.999)
                .map(|i| px[i][1] as f64)
                .collect();
            assert!(v.len() > 100, "{name}: {} pixels", v.len());
            v.iter().sum::<f64>() / v.len() as f64
        };
        (o.json(), half(&|d| d > 34), half(&|d| d < 28))
    };
    for device in ["cpu", "gpu"] {
        let (summary, red, blue) = render(device, "0,0,0", &["--device", device]);
        eprintln!("{device}: red half {red}, blue half {blue}");
        assert_eq!(red, 0.0, "{device}: no coat over black");
        assert!((blue - 0.02).abs() < 0.02 * 0.02, "{device}: blue {blue}");
        let coats: Vec<_> = summary["materials"]
            .as_array()
            .expect("materials")
            .iter()
            .map(|m| m.get("clearcoat").cloned())
            .collect();
        assert_eq!(
            coats,
            [None, Some(serde_json::json!([0.5, 0.0]))],
            "{summary}"
        );
        let all = [
            "--clearcoat",
            "1",
            "--clearcoat-roughness",
            "0",
            "--device",
            device,
        ];
        let (_, red, blue) = render(&format!("{device}-all"), "0,0,0", &all);
        for v in [red, blue] {
            assert!((v - 0.04).abs() < 0.02 * 0.04, "{device}: {red} {blue}");
        }
        let (_, red, blue) = render(&format!("{device}-white"), "1,1,1", &all);
        for v in [red, blue] {
            assert!((v - 1.0).abs() < 0.01, "{device}: white base {red} {blue}");
        }
    }
    let info = run(&[
        "inspect",
        s(&square),
        "--disp",
        s(&example("maps/scales_256.png")),
    ]);
    info.assert_success();
    assert!(
        info.stdout.contains("clearcoat 0.5, clearcoat roughness 0"),
        "{}",
        info.stdout
    );
}

/// A key light with an angle is a disc of even radiance (its irradiance over its solid angle)
/// that BSDF samples meet as well as shadow rays, the two shared by MIS: a mirror square facing
/// it shows the disc at exactly that radiance (it showed nothing when only shadow rays found
/// the key), and a white Lambertian square facing a 90° disc converges to its analytic
/// radiance, the disc counted once, on the CPU and the GPU.
#[test]
fn a_key_disc_is_seen_in_a_mirror_and_counted_once() {
    let dir = temp_dir("key-disc");
    let square = two_material_square(&dir);
    let map = example("maps/scales_256.png");
    let render = |name: &str, device: &str, material: &[&str], angle: &str| {
        let out = dir.join(format!("{name}-{device}"));
        let mut args = vec![
            "render",
            s(&square),
            "--disp",
            s(&map),
            "--scale",
            "0",
            "--res",
            "24x24",
            "--spp",
            "16",
            "--aov",
            "beauty",
            "--camera-from",
            "0,0,5",
            "--camera-to",
            "0,0,0",
            "--fov",
            "20",
            "--env-intensity",
            "0",
            "--key-light",
            "0,0,2",
            "--key-angle",
            angle,
            "--bounces",
            "1",
            "--device",
            device,
            "-o",
            s(&out),
        ];
        args.extend_from_slice(material);
        run(&args).assert_success();
        let px: Vec<[f32; 4]> = read_rgba(&out.join("beauty.exr"))
            .into_iter()
            .filter(|p| p[3] >= 0.999)
            .collect();
        assert!(px.len() > 200, "{name}: the square fills the view");
        px
    };
    let lambert = [
        "--base-color",
        "1,1,1",
        "--specular",
        "0",
        "--roughness",
        "1",
    ];
    for device in ["cpu", "gpu"] {
        // Every reflected direction lies within 10° of the key's, inside its 30° radius.
        let want = 2.0 / (2.0 * std::f32::consts::PI * (1.0 - 30f32.to_radians().cos()));
        for p in render("mirror", device, &WHITE_MIRROR, "60") {
            assert!(
                (p[0] - want).abs() < 1e-3 * want,
                "{device}: mirror pixel {p:?}, the disc's radiance {want}"
            );
        }
        // E = L π sin²r over the disc facing the square, of radiance L = E₀ / (2π(1 − cos r)):
        // E₀ (1 + cos r) / 2; a white Lambertian surface's radiance is E / π.
        let px = render("lambert", device, &lambert, "90");
        let want = 2.0 * (1.0 + 45f32.to_radians().cos()) / 2.0 / std::f32::consts::PI;
        let mean = px.iter().map(|p| p[1] as f64).sum::<f64>() / px.len() as f64;
        eprintln!("{device}: Lambertian square under a 90° disc {mean:.4}, analytic {want:.4}");
        assert!(
            (mean - want as f64).abs() < 0.02 * want as f64,
            "{device}: mean {mean}, analytic {want}"
        );
    }
}

/// A white metal of no roughness: a perfect mirror of Fresnel 1.
const WHITE_MIRROR: [&str; 6] = [
    "--base-color",
    "1,1,1",
    "--metallic",
    "1",
    "--roughness",
    "0",
];

/// A white Lambertian of albedo 0.8 without specular (`lit_quad_centre`'s material).
const WHITE_LAMBERT: [&str; 6] = [
    "--base-color",
    "0.8,0.8,0.8",
    "--roughness",
    "1",
    "--specular",
    "0",
];

/// `usda` (a quad scene with its lights) written to `dir/NAME.usda` and its 9² beauty, head on
/// from 3 units through 10°, lit by its own lights alone (a black environment, one bounce), its
/// surface `material` (the overrides' arguments), `spp` samples a pixel: the centre pixel, and
/// the summary.
fn lit_quad_centre(
    dir: &Path,
    usda: &str,
    name: &str,
    spp: &str,
    material: &[&str],
) -> ([f32; 4], serde_json::Value) {
    let map = write_flat_map(dir);
    let black = dir.join("black.exr");
    write_constant_env(&black, 0.0);
    let path = dir.join(format!("{name}.usda"));
    std::fs::write(&path, usda).unwrap();
    let out = dir.join(name);
    let mut args = vec!["render", s(&path), "--disp", s(&map), "--scale", "0"];
    args.extend([
        "--aov",
        "beauty",
        "--res",
        "9x9",
        "--spp",
        spp,
        "--bounces",
        "1",
    ]);
    args.extend(material);
    args.extend([
        "--env",
        s(&black),
        "--camera-from",
        "0,0,3",
        "--camera-to",
        "0,0,0",
    ]);
    args.extend(["--fov", "10", "--json", "-o", s(&out)]);
    let summary = run(&args).assert_success().json();
    (read_rgba(&out.join("beauty.exr"))[4 * 9 + 4], summary)
}

/// A point light lights by the inverse square: a USD `SphereLight` marked `treatAsPoint`,
/// normalized, of intensity 16 (4 W/sr) two units above a white quad's centre casts 1 W/m²
/// there, and a Lambertian surface of albedo 0.8 under it sends 0.8 / π towards the camera
/// (no environment, no specular); a spot of the same intensity aimed away casts nothing; the
/// summary names the lights, and past sixteen a warning names those left out.
#[test]
fn a_point_light_lights_by_the_inverse_square() {
    let dir = temp_dir("point-light");
    let map = write_flat_map(&dir);
    let scene = |shaping: &str| {
        quad_usda(&format!(
            "def SphereLight \"Bulb\" (\n    prepend apiSchemas = [\"ShapingAPI\"]\n)\n{{\n    \
             float inputs:intensity = 16\n    bool inputs:normalize = 1\n    \
             bool treatAsPoint = 1\n    {shaping}\n    \
             double3 xformOp:translate = (0, 0, 2)\n    \
             uniform token[] xformOpOrder = [\"xformOp:translate\"]\n}}\n"
        ))
    };
    let centre = |usda: String, name: &str| lit_quad_centre(&dir, &usda, name, "4", &WHITE_LAMBERT);
    let (rgba, summary) = centre(scene(""), "point");
    let want = 0.8 / std::f32::consts::PI;
    assert!(
        (rgba[0] / want - 1.0).abs() < 0.01,
        "{rgba:?} against {want}"
    );
    assert_eq!(
        summary["lights"][0],
        "point '/Bulb' at (0.000, 0.000, 2.000), intensity 4"
    );
    // Aimed along +Z, away from the quad below it.
    let away = "float inputs:shaping:cone:angle = 30\n    \
                float xformOp:rotateX = 180\n    \
                uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:rotateX\"]";
    let (rgba, _) = centre(
        scene(away).replace(
            "    uniform token[] xformOpOrder = [\"xformOp:translate\"]\n",
            "",
        ),
        "spot",
    );
    assert_eq!(rgba[0], 0.0, "{rgba:?}");
    // A sun and seventeen bulbs: sixteen lights are rendered, and a warning names the two left
    // out.
    let many = (0..17)
        .map(|i| format!("def SphereLight \"B{i}\"\n{{\n    float inputs:radius = 0.1\n}}\n"))
        .collect::<String>();
    let path = dir.join("many.usda");
    std::fs::write(
        &path,
        quad_usda(&format!("def DistantLight \"Sun\"\n{{\n}}\n{many}")),
    )
    .unwrap();
    let mut args = vec!["render", s(&path), "--disp", s(&map), "--aov", "beauty"];
    let out = dir.join("many");
    args.extend(["--res", "4x4", "--json", "-o", s(&out)]);
    let o = run(&args);
    assert_eq!(
        o.assert_success().json()["lights"]
            .as_array()
            .unwrap()
            .len(),
        15
    );
    assert!(
        o.stderr.contains(
            "renders 16 lights, the key light and the first 15 others; left out: /B15, /B16"
        ),
        "{}",
        o.stderr
    );
}

/// An area light lights by its radiance over its solid angle: a USD `DiskLight` of radius 1 and
/// intensity 4 two units above a white quad, shining down, casts π L R² / (h² + R²) = 2.51
/// W/m² on the centre, and the albedo-0.8 Lambertian surface there sends 0.8 / π of that
/// towards the camera (within 3%: 64 samples a pixel of the disk); turned to face up, it
/// casts nothing.
#[test]
fn a_disk_light_lights_by_its_solid_angle() {
    let dir = temp_dir("disk-light");
    let centre = |turn: &str, name: &str| {
        let light = format!(
            "def DiskLight \"Panel\"\n{{\n    float inputs:intensity = 4\n    \
             float inputs:radius = 1\n    double3 xformOp:translate = (0, 0, 2)\n    \
             float xformOp:rotateX = {turn}\n    \
             uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:rotateX\"]\n}}\n"
        );
        lit_quad_centre(&dir, &quad_usda(&light), name, "64", &WHITE_LAMBERT)
    };
    let (rgba, summary) = centre("0", "down");
    let want = 0.8 / std::f32::consts::PI * (std::f32::consts::PI * 4.0 / 5.0);
    assert!(
        (rgba[0] / want - 1.0).abs() < 0.03,
        "{rgba:?} against {want}"
    );
    assert!(
        summary["lights"][0]
            .as_str()
            .unwrap()
            .starts_with("disk '/Panel' at (0.000, 0.000, 2.000), 2 × 2 across, shining along (0.000, 0.000, -1.000), radiance 4"),
        "{summary}"
    );
    let (rgba, _) = centre("180", "up");
    assert_eq!(rgba[0], 0.0, "{rgba:?}");
}

/// A mirror reflects a sphere and an area light: a white metal quad of no roughness under a
/// `DiskLight` of radiance 4 shining down on it shows the camera, whose reflected ray meets the
/// disk, radiance 4 (Fresnel 1 for a white metal; the camera's rays pass through the light); a
/// `SphereLight` of radius 0.5 and radiance 2 there shows 2, its spot's cone only where it
/// points at the quad; a point light, with no surface to meet, is not seen.
#[test]
fn a_mirror_reflects_spheres_and_area_lights() {
    let dir = temp_dir("mirror-lights");
    let lamp = |kind: &str, inputs: &str, schema: &str| {
        format!(
            "def {kind} \"Lamp\"{schema}\n{{\n    {inputs}\n    \
             double3 xformOp:translate = (0, 0, 2)\n    \
             uniform token[] xformOpOrder = [\"xformOp:translate\"]\n}}\n"
        )
    };
    let centre = |light: String, name: &str| {
        lit_quad_centre(&dir, &quad_usda(&light), name, "4", &WHITE_MIRROR).0
    };
    let near = |got: [f32; 4], want: f32, what: &str| {
        for c in &got[..3] {
            assert!(
                (c / want - 1.0).abs() < 0.01,
                "{what}: {got:?} against {want}"
            );
        }
    };
    let disk = "float inputs:intensity = 4\n    float inputs:radius = 1";
    near(centre(lamp("DiskLight", disk, ""), "disk"), 4.0, "disk");
    let sphere = "float inputs:intensity = 2\n    float inputs:radius = 0.5";
    near(
        centre(lamp("SphereLight", sphere, ""), "sphere"),
        2.0,
        "sphere",
    );
    let shaping = " (\n    prepend apiSchemas = [\"ShapingAPI\"]\n)";
    let spot = |angle: &str| format!("{sphere}\n    float inputs:shaping:cone:angle = {angle}");
    near(
        centre(lamp("SphereLight", &spot("30"), shaping), "spot"),
        2.0,
        "spot",
    );
    // A cone of 30° about −Z, turned to point along +X: the quad lies outside it.
    let aside = lamp("SphereLight", &spot("30"), shaping).replace(
        "uniform token[] xformOpOrder = [\"xformOp:translate\"]",
        "float xformOp:rotateY = 90\n    \
         uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:rotateY\"]",
    );
    assert_eq!(centre(aside, "spot-aside")[0], 0.0);
    let point = format!("{sphere}\n    bool treatAsPoint = 1");
    assert_eq!(centre(lamp("SphereLight", &point, ""), "point")[0], 0.0);
}

/// A USD file's `DomeLight` lights the beauty where `--env` is not given (`inspect` lists it,
/// and the directional light):
/// a red dome of intensity 3 (no texture) lights a white quad red, `--env` replaces it, and a
/// dome whose texture is missing fails naming the file, the dome and the texture. Its
/// `DistantLight` is the key light where `--key-light` is not given, in its colour;
/// `--no-scene-lights` leaves both out. Lights it does not render (cylinder, portal) are named
/// in a warning.
#[test]
fn a_usd_dome_light_is_the_environment_unless_env_is_given() {
    let dir = temp_dir("dome");
    let scene = |dome: &str| quad_usda(&format!("def DomeLight \"Sky\"\n{{\n    {dome}\n}}\n"));
    let red = dir.join("red.usda");
    std::fs::write(
        &red,
        scene("float inputs:intensity = 3\n    color3f inputs:color = (1, 0, 0)"),
    )
    .unwrap();
    let map = write_flat_map(&dir);
    let grey = dir.join("grey.exr");
    write_constant_env(&grey, 1.0);
    let render = |usda: &Path, name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut args = vec![
            "render",
            s(usda),
            "--disp",
            s(&map),
            "--aov",
            "beauty",
            "--res",
            "12x12",
            "--spp",
            "4",
            "--base-color",
            "1,1,1",
            "--camera-from",
            "0,0,3",
            "--camera-to",
            "0,0,0",
            "--json",
            "-o",
            s(&out),
        ];
        args.extend(extra);
        let o = run(&args);
        (o, out.join("beauty.exr"))
    };
    let info = run(&["inspect", s(&red), "--disp", s(&map), "--json"])
        .assert_success()
        .json();
    assert_eq!(info["dome_light"], "'/Sky' (no texture)");
    let (o, exr) = render(&red, "red", &[]);
    let said = o.assert_success().json()["environment"]
        .as_str()
        .unwrap()
        .to_string();
    assert_eq!(
        said,
        "the file's dome light '/Sky' (no texture, tint 3, 0, 0, turned 0°)"
    );
    let centre = read_rgba(&exr)[6 * 12 + 6];
    assert!(
        centre[0] > 0.5 && centre[1] == 0.0 && centre[2] == 0.0,
        "{centre:?}"
    );
    let (o, exr) = render(&red, "env", &["--env", s(&grey)]);
    let said = o.assert_success().json()["environment"]
        .as_str()
        .unwrap()
        .to_string();
    assert!(said.starts_with("--env "), "{said}");
    let centre = read_rgba(&exr)[6 * 12 + 6];
    assert!(
        centre[1] > 0.1 && (centre[0] - centre[1]).abs() < 1e-3,
        "{centre:?}"
    );
    // A distant light is the key light unless --key-light is given: its shadow rays are cast.
    let sunny = dir.join("sunny.usda");
    let sun = "def DistantLight \"Sun\"\n{\n    float inputs:intensity = 2\n    \
               bool inputs:normalize = 1\n    \
               float3 xformOp:rotateXYZ = (-60, 0, 0)\n    \
               uniform token[] xformOpOrder = [\"xformOp:rotateXYZ\"]\n}\n";
    std::fs::write(&sunny, scene("float inputs:intensity = 0.5") + sun).unwrap();
    let info = run(&["inspect", s(&sunny), "--disp", s(&map), "--json"])
        .assert_success()
        .json();
    assert_eq!(
        info["directional_light"],
        "'/Sun' (azimuth 0.0°, elevation 60.0°, irradiance 2, 0.53° across)"
    );
    let (o, _) = render(&sunny, "sun", &[]);
    let summary = o.assert_success().json();
    assert_eq!(
        summary["key_light"],
        "the file's directional light '/Sun' (azimuth 0.0°, elevation 60.0°, irradiance 2, 0.53° across)"
    );
    assert!(summary["beauty_rays"]["key_shadow_rays"].as_u64().unwrap() > 0);
    // A coloured sun lights in its colour: under a black sky the white quad takes its hue.
    let warm = dir.join("warm.usda");
    let warm_sun = sun.replace(
        "bool inputs:normalize = 1",
        "bool inputs:normalize = 1\n    color3f inputs:color = (1, 0.4, 0.1)",
    );
    std::fs::write(&warm, quad_usda(&warm_sun)).unwrap();
    let black = dir.join("black.exr");
    write_constant_env(&black, 0.0);
    let (o, exr) = render(&warm, "warm", &["--env", s(&black)]);
    let said = o.assert_success().json()["key_light"].to_string();
    assert!(
        said.contains("irradiance 1.0118, colour (1.977, 0.791, 0.198)"),
        "{said}"
    );
    let warm_rgba = read_rgba(&exr);
    let [r, g, b, _] = warm_rgba[6 * 12 + 6];
    assert!(
        r > 0.1 && (g / r - 0.4).abs() < 1e-3 && (b / r - 0.1).abs() < 1e-3,
        "{:?}",
        [r, g, b]
    );
    // --key-color gives the file's white sun that hue, keeping its irradiance (2, where the
    // warm sun's colour took it to 1.0118): the warm picture, brighter by 2 / 1.0118; and
    // --key-light one too.
    let (o, exr) = render(
        &sunny,
        "tinted",
        &["--env", s(&black), "--key-color", "1,0.4,0.1"],
    );
    o.assert_success();
    for (t, w) in read_rgba(&exr).iter().zip(&warm_rgba) {
        for c in 0..3 {
            let want = w[c] * 2.0 / 1.0118;
            assert!(
                (t[c] - want).abs() <= 1e-3 * want.max(1e-3),
                "{t:?} against {w:?}"
            );
        }
        assert_eq!(t[3], w[3]);
    }
    let (o, _) = render(
        &sunny,
        "own-tinted",
        &["--key-light", "0,30,1", "--key-color", "2,0.8,0.2"],
    );
    assert_eq!(
        o.assert_success().json()["key_light"],
        "--key-light, colour (1.977, 0.791, 0.198)"
    );
    // Cylinder and portal lights are not rendered: one warning names them all.
    let rig = dir.join("rig.usda");
    let lights = "def CylinderLight \"Key\"\n{\n}\ndef PortalLight \"Fill\"\n{\n}\n";
    std::fs::write(&rig, quad_usda(&format!("{sun}{lights}"))).unwrap();
    let o = run(&["inspect", s(&rig), "--disp", s(&map), "--json"]);
    o.assert_success();
    assert!(
        o.stderr
            .contains("2 lights are not read: /Key (CylinderLight), /Fill (PortalLight)"),
        "{}",
        o.stderr
    );
    assert_eq!(
        o.json()["directional_light"],
        info["directional_light"],
        "the distant light beside them is still read"
    );
    let (o, _) = render(&sunny, "own-key", &["--key-light", "0,30,1"]);
    assert_eq!(o.assert_success().json()["key_light"], "--key-light");
    // --no-scene-lights: the standard rig, neither of the file's lights.
    let (o, _) = render(&sunny, "rig", &["--no-scene-lights"]);
    let summary = o.assert_success().json();
    assert_eq!(summary["environment"], "the built-in sky");
    assert!(summary["key_light"].is_null(), "{summary}");
    let (o, _) = render(&sunny, "wider", &["--key-angle", "5"]);
    let said = o.assert_success().json()["key_light"].to_string();
    assert!(said.ends_with("irradiance 2, 5° across)\""), "{said}");
    // A dome whose radiance sums past f32's range fails, naming it, before anything is traced.
    let blinding = dir.join("blinding.usda");
    std::fs::write(&blinding, scene("float inputs:intensity = 1e38")).unwrap();
    let (o, exr) = render(&blinding, "blinding", &[]);
    o.assert_error(&["blinding.usda", "dome light /Sky", "past f32's range"]);
    assert!(!exr.exists());
    let missing = dir.join("missing.usda");
    std::fs::write(
        &missing,
        scene("asset inputs:texture:file = @nowhere/sky.exr@"),
    )
    .unwrap();
    let (o, exr) = render(&missing, "missing", &[]);
    o.assert_error(&["missing.usda", "dome light /Sky", "nowhere/sky.exr"]);
    assert!(!exr.exists());
}

/// The square (`square_gltf`) whose base-colour texture's alpha is 0 on its left half and 1 on
/// its right, under `alpha_mode` ("MASK" or "BLEND") with the factor's alpha `factor`.
fn cut_out_square(dir: &Path, alpha_mode: &str, factor: f32) -> PathBuf {
    image::RgbaImage::from_fn(4, 4, |x, _| match x < 2 {
        true => image::Rgba([255, 255, 255, 0]),
        false => image::Rgba([255, 255, 255, 255]),
    })
    .save(dir.join("leaf.png"))
    .unwrap();
    square_gltf(
        dir,
        [0, 0],
        &format!(
            r#""materials":[{{"name":"leaf","alphaMode":"{alpha_mode}","pbrMetallicRoughness":{{
        "baseColorFactor":[0.9,0.9,0.9,{factor}],"baseColorTexture":{{"index":0}}}}}}],
      "textures":[{{"source":0,"sampler":0}}],
      "samplers":[{{"wrapS":33071,"wrapT":33071,"magFilter":9728}}],
      "images":[{{"uri":"leaf.png"}}]"#
        ),
    )
}

/// A material's alpha cuts its surface away, in the beauty, its shadows' rays and the AOVs
/// alike (`render::cutout`): a MASK square whose texture's alpha is 0 on its left half shows
/// only its right half in the `mask` AOV and the beauty's alpha; a BLEND factor of 0.25 covers
/// a quarter of the samples; `--no-alpha` renders it whole; the GPU cuts the same (on
/// lavapipe here).
#[test]
fn a_materials_alpha_cuts_its_surface_away() {
    let dir = temp_dir("alpha");
    let render = |square: &Path, name: &str, spp: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut args = vec![
            "render",
            s(square),
            "--disp",
            "",
            "--scale",
            "0",
            "--res",
            "32x32",
            "--spp",
            spp,
            "--aov",
            "beauty,mask",
            "--camera-from",
            "0,0,5",
            "--camera-to",
            "0,0,0",
            "--fov",
            "30",
            "--json",
            "-o",
            s(&out),
        ];
        let map = write_flat_map(&dir);
        args[3] = s(&map);
        args.extend_from_slice(extra);
        let o = run(&args);
        let [mask] = read_channels(&out.join("mask.exr"), ["Y"]);
        let alpha: Vec<f32> = read_rgba(&out.join("beauty.exr"))
            .iter()
            .map(|p| p[3])
            .collect();
        (o, mask, alpha)
    };
    // Mean over the square's left and right thirds (away from the texture's seam).
    let halves = |v: &[f32]| {
        let mean = |xs: std::ops::Range<usize>| {
            let n = (xs.len() * 12) as f32;
            (10..22)
                .flat_map(|y| xs.clone().map(move |x| y * 32 + x))
                .map(|i| v[i])
                .sum::<f32>()
                / n
        };
        (mean(7..12), mean(20..25))
    };
    let mask_square = cut_out_square(&temp_dir("alpha-mask"), "MASK", 1.0);
    let (o, mask, alpha) = render(&mask_square, "mask", "4", &[]);
    o.assert_success();
    let m = &o.json()["materials"][0];
    assert_eq!(
        m["alpha"].as_str(),
        Some("mask at 0.5, alpha 1 x texture leaf.png, 4x4, clamp/clamp, nearest, alpha channel"),
        "{m}"
    );
    assert_eq!(halves(&mask), (0.0, 1.0));
    assert_eq!(halves(&alpha), (0.0, 1.0));
    let (o, whole, _) = render(&mask_square, "whole", "4", &["--no-alpha"]);
    o.assert_success();
    assert_eq!(halves(&whole), (1.0, 1.0));
    assert!(o.json()["materials"][0].get("alpha").is_none());
    // An alpha texture that keeps every texel (an opaque image under BLEND) cuts nothing: the
    // summary names no alpha.
    let opaque_dir = temp_dir("alpha-opaque");
    let opaque = cut_out_square(&opaque_dir, "BLEND", 1.0);
    image::RgbaImage::from_pixel(4, 4, image::Rgba([255, 255, 255, 255]))
        .save(opaque_dir.join("leaf.png"))
        .unwrap();
    let (o, whole, _) = render(&opaque, "opaque", "4", &[]);
    o.assert_success();
    assert!(
        o.json()["materials"][0].get("alpha").is_none(),
        "{}",
        o.stdout
    );
    assert_eq!(halves(&whole), (1.0, 1.0));
    // Blended: the right half is there with the factor's probability.
    let blend_square = cut_out_square(&temp_dir("alpha-blend"), "BLEND", 0.25);
    let (o, mask, alpha) = render(&blend_square, "blend", "64", &[]);
    o.assert_success();
    let (left, right) = halves(&mask);
    assert_eq!(left, 0.0);
    assert!((right - 0.25).abs() < 0.04, "{right}");
    assert_eq!(halves(&alpha), (left, right));
    // The GPU's traversal cuts the same surfaces away (lavapipe in CI): the same halves, and
    // the blended square's samples as the CPU's (the same random numbers).
    let (o, gpu_mask, gpu_alpha) = render(&mask_square, "gpu", "4", &["--device", "gpu"]);
    o.assert_success();
    assert!(o.json()["device"].as_str().unwrap().starts_with("gpu"));
    assert_eq!(
        (halves(&gpu_mask), halves(&gpu_alpha)),
        ((0.0, 1.0), (0.0, 1.0))
    );
    let (o, gpu_mask, _) = render(&blend_square, "blend-gpu", "64", &["--device", "gpu"]);
    o.assert_success();
    let differ = gpu_mask.iter().zip(&mask).filter(|(g, c)| g != c).count();
    assert!(differ <= 2, "{differ} mask pixels differ from the CPU's");
    let rgba = |name: &str| read_rgba(&dir.join(name).join("beauty.exr"));
    let (cpu, gpu) = (rgba("blend"), rgba("blend-gpu"));
    let diff = cpu
        .iter()
        .zip(&gpu)
        .flat_map(|(c, g)| (0..4).map(move |k| (c[k] - g[k]).abs()));
    let mean = diff.sum::<f32>() / (cpu.len() * 4) as f32;
    assert!(
        mean < 2e-3,
        "the GPU's beauty differs from the CPU's by {mean} on average"
    );
    // The AOV kernel's other walk (one ray an invocation, bvh.wgsl) cuts alike.
    let out = dir.join("ray-walk");
    let map = write_flat_map(&dir);
    let o = run_in_env(
        &dir,
        &[
            "render",
            s(&mask_square),
            "--disp",
            s(&map),
            "--scale",
            "0",
            "--res",
            "32x32",
            "--spp",
            "4",
            "--aov",
            "mask",
            "--camera-from",
            "0,0,5",
            "--camera-to",
            "0,0,0",
            "--fov",
            "30",
            "--device",
            "gpu",
            "-o",
            s(&out),
        ],
        &[("PRISMBAKE_GPU_WALK", "ray")],
    );
    o.assert_success();
    let [ray_mask] = read_channels(&out.join("mask.exr"), ["Y"]);
    assert_eq!(halves(&ray_mask), (0.0, 1.0));
}
