//! `render --device gpu|auto` end to end: a beauty turntable on the GPU (frames, contact sheet,
//! the same picture as the CPU run), `auto` picking the GPU for beauty, and the prism-table
//! cache shared by both paths. They need a wgpu adapter (lavapipe, Debian
//! `mesa-vulkan-drivers`, on a machine without a GPU); without one they fail, on purpose.

use crate::util::*;
use std::path::Path;
use std::process::Command;

fn luminance(p: &[f32; 4]) -> f64 {
    (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]) as f64
}

/// Mean |Δ| over RGB of two beauty EXRs, relative to the first one's mean covered radiance.
fn relative_difference(a: &Path, b: &Path) -> f64 {
    let (a, b) = (read_rgba(a), read_rgba(b));
    assert_eq!(a.len(), b.len());
    let covered: Vec<f64> = a.iter().filter(|p| p[3] > 0.5).map(luminance).collect();
    assert!(!covered.is_empty(), "the asset covers no pixel");
    let scale = covered.iter().sum::<f64>() / covered.len() as f64;
    let diff: f64 = a
        .iter()
        .zip(&b)
        .map(|(p, q)| (0..3).map(|k| (p[k] - q[k]).abs() as f64).sum::<f64>())
        .sum();
    diff / (3 * a.len()) as f64 / scale
}

#[test]
fn gpu_beauty_turntable_writes_every_frame_and_a_contact_sheet() {
    let dir = temp_dir("gpu-turntable");
    let sphere = example("sphere/sphere.glb");
    let render = |device: &str, out: &Path| {
        run(&[
            "render",
            s(&sphere),
            "--device",
            device,
            "--aov",
            "beauty",
            "--turntable",
            "4",
            "--res",
            "16x16",
            "--spp",
            "2",
            "--key-light",
            "30,40,2",
            "--ground",
            "--json",
            "-o",
            s(out),
        ])
        .assert_success()
        .json()
    };
    let (gpu_out, cpu_out) = (dir.join("gpu"), dir.join("cpu"));
    let gpu = render("gpu", &gpu_out);
    assert!(
        gpu["device"].as_str().unwrap().starts_with("gpu ("),
        "{}",
        gpu["device"]
    );
    let mut want: Vec<String> = (0..4)
        .flat_map(|f| [format!("beauty_{f:04}.exr"), format!("beauty_{f:04}.png")])
        .collect();
    want.push("beauty_contact_sheet.png".into());
    want.sort();
    assert_eq!(files_in(&gpu_out), want);
    let sheet = image::open(gpu_out.join("beauty_contact_sheet.png")).unwrap();
    assert_eq!(
        (sheet.width(), sheet.height()),
        (32, 32),
        "4 frames in a 2x2 grid"
    );
    assert_eq!(gpu["frames"].as_array().unwrap().len(), 4);
    // lavapipe (and every desktop Vulkan driver) has timestamp queries: each frame reports the
    // kernels' own time, inside its trace time.
    assert_frame_times(&gpu, true);
    assert!(gpu["beauty_rays"]["key_shadow_rays"].as_u64().unwrap() > 0);
    assert!(gpu["beauty_rays"]["env_shadow_rays"].as_u64().unwrap() > 0);

    // The CPU renders the same job: the same ray counts (within 1%: a sample whose decision
    // flips on rounding may trace other rays) and the same pictures up to float rounding
    // (gpu/tests/beauty.rs measures ~1e-5; 1e-3 leaves room, a real divergence is ≫ 1%).
    let cpu = render("cpu", &cpu_out);
    assert_eq!(files_in(&cpu_out), want);
    assert_frame_times(&cpu, false);
    for kind in ["rays", "key_shadow_rays", "env_shadow_rays"] {
        let (c, g) = (
            cpu["beauty_rays"][kind].as_u64().unwrap() as f64,
            gpu["beauty_rays"][kind].as_u64().unwrap() as f64,
        );
        assert!((c - g).abs() <= 0.01 * c, "{kind}: cpu {c} gpu {g}");
    }
    for f in 0..4 {
        let name = format!("beauty_{f:04}.exr");
        let d = relative_difference(&cpu_out.join(&name), &gpu_out.join(&name));
        assert!(d <= 1e-3, "{name}: GPU vs CPU mean |Δ| {d:.2e}");
    }
    // Frames of a turntable see the asset from different sides.
    assert!(
        relative_difference(
            &gpu_out.join("beauty_0000.exr"),
            &gpu_out.join("beauty_0001.exr")
        ) > 1e-3
    );
}

#[test]
fn auto_renders_beauty_on_the_gpu_from_the_cpu_table_cache() {
    let dir = temp_dir("gpu-cache");
    let cache = dir.join("cache");
    let torus = example("torus/torus.obj");
    let render = |device: &str, aov: &str| {
        let out = dir.join(device);
        let o = Command::new(env!("CARGO_BIN_EXE_prismbake"))
            .args([
                "render",
                s(&torus),
                "--device",
                device,
                "--aov",
                aov,
                "--res",
                "12x12",
                "--json",
                "-o",
                s(&out),
            ])
            .env("XDG_CACHE_HOME", &cache)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{stderr}");
        let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        (json, stderr)
    };
    let (cpu, _) = render("cpu", "mask");
    assert_eq!(cpu["table_cache"]["cache"], "stored", "{cpu}");
    assert!(cpu.get("gpu_tile").is_none(), "{cpu}");
    assert!(cpu.get("gpu_walk").is_none(), "{cpu}");
    let (auto, stderr) = render("auto", "beauty");
    assert!(
        stderr.contains("device: gpu ("),
        "auto takes the adapter for beauty: {stderr}"
    );
    assert!(auto["device"].as_str().unwrap().starts_with("gpu ("));
    // The tile side the frames were dispatched in: lavapipe's 512², a GPU's 2048² (either
    // cut to the device's binding limit).
    let tile = auto["gpu_tile"]
        .as_u64()
        .unwrap_or_else(|| panic!("{auto}"));
    assert!(tile % 8 == 0 && (64..=2048).contains(&tile), "{auto}");
    // The AOV kernel's walk (GpuContext::aov_walk) is reported.
    assert!(
        matches!(auto["gpu_walk"].as_str(), Some("ray" | "packet")),
        "{auto}"
    );
    // A software adapter (lavapipe in CI: "…, Cpu, …" in its description) says that the CPU
    // renderer is the faster device there; a GPU does not.
    let software = auto["device"].as_str().unwrap().contains(", Cpu,");
    assert_eq!(
        stderr.contains("is a software adapter") && stderr.contains("--device cpu"),
        software,
        "{stderr}"
    );
    assert_eq!(
        auto["table_cache"]["cache"], "reused",
        "the GPU path reuses the table the CPU path baked: {auto}"
    );
    assert_eq!(auto["table_cache"]["path"], cpu["table_cache"]["path"]);
    assert!(dir.join("auto").join("beauty.exr").is_file());
}

#[test]
fn gpu_render_traces_the_seam_mode_it_is_given() {
    // `--seams` reaches the GPU session: on a cube whose islands disagree at every seam, the
    // GPU's depth matches the CPU's of the same mode wherever the two modes differ. Breaks if
    // the GPU always traced one surface, or ignored `--seams`.
    let (jump, _, dir) = crate::seams::cube_assets();
    let render = |device: &str, seams: &str| -> Vec<f32> {
        let out = dir.join(format!("{device}-{seams}"));
        run(&[
            "render",
            s(&jump),
            "--device",
            device,
            "--res",
            "48x48",
            "--aov",
            "depth",
            "--camera-from",
            "2.6,2.1,3.3",
            "--camera-to",
            "0,0,0",
            "--seams",
            seams,
            "-o",
            s(&out),
        ])
        .assert_success();
        prismbake::render::output::read_exr(&out.join("depth.exr"))
            .unwrap()
            .3
    };
    let (cpu_stitch, cpu_open) = (render("cpu", "stitch"), render("cpu", "open"));
    let (gpu_stitch, gpu_open) = (render("gpu", "stitch"), render("gpu", "open"));
    let close = |a: f32, b: f32, tol: f32| (a - b).abs() <= tol * a.abs().max(1e-6);
    let bands: Vec<usize> = (0..cpu_stitch.len())
        .filter(|&i| !close(cpu_stitch[i], cpu_open[i], 1e-4))
        .collect();
    assert!(
        bands.len() >= 10,
        "stitch and open differ on {} px",
        bands.len()
    );
    for (mode, gpu, cpu) in [
        ("stitch", &gpu_stitch, &cpu_stitch),
        ("open", &gpu_open, &cpu_open),
    ] {
        let agree = bands
            .iter()
            .filter(|&&i| close(cpu[i], gpu[i], 1e-5))
            .count();
        eprintln!(
            "--seams {mode}: {agree} of {} seam-band px agree",
            bands.len()
        );
        assert!(
            agree as f64 >= 0.95 * bands.len() as f64,
            "--seams {mode}: the GPU's depth agrees with the CPU's on {agree} of {} seam-band px",
            bands.len()
        );
    }
}

/// A tile side the GPU path cannot use is refused before any frame, naming the variable and
/// the fix; `--device gpu` exits non-zero and writes nothing, `auto` says why it took the CPU.
#[test]
fn an_unusable_gpu_setting_is_an_error_naming_the_fix() {
    let dir = temp_dir("gpu-tile-setting");
    let out = dir.join("out");
    let torus = example("torus/torus.obj");
    let render = |device: &str, var: &str, value: &str| {
        run_in_env(
            &repo_root(),
            &[
                "render",
                s(&torus),
                "--device",
                device,
                "--res",
                "16x16",
                "--aov",
                "beauty",
                "-o",
                s(&out),
            ],
            &[(var, value)],
        )
    };
    // Each setting's bad value, and what its message must say besides "VAR=value".
    let bad: [(&str, &str, &[&str]); 4] = [
        ("PRISMBAKE_GPU_TILE", "1020", &["multiple of 8"]),
        ("PRISMBAKE_GPU_BEAUTY", "split", &["`fused`", "`wavefront`"]),
        ("PRISMBAKE_GPU_MEMORY", "0", &["percentage from 1 to 100"]),
        ("PRISMBAKE_GPU_TRACE_PIXELS", "0", &["from 1 to 64"]),
    ];
    for (var, value, says) in bad {
        let setting = format!("{var}={value}");
        let mut expected = vec![setting.as_str(), "unset it"];
        expected.extend(says);
        render("gpu", var, value).assert_error(&expected);
    }
    assert!(
        !out.exists() || files_in(&out).is_empty(),
        "files were written"
    );
    // Both schedules render when asked for by name, and the log says which ran.
    for schedule in ["fused", "wavefront"] {
        let r = render("gpu", "PRISMBAKE_GPU_BEAUTY", schedule);
        r.assert_success();
        assert!(
            r.stderr.contains(&format!("beauty schedule {schedule}")),
            "{schedule}: the log does not name the schedule:\n{}",
            r.stderr
        );
        assert!(
            out.join("beauty.png").is_file(),
            "{schedule}: no beauty.png"
        );
        std::fs::remove_dir_all(&out).unwrap();
    }
    let auto = render("auto", "PRISMBAKE_GPU_TILE", "huge");
    auto.assert_success();
    assert!(
        auto.stderr.contains("device: cpu (PRISMBAKE_GPU_TILE=huge"),
        "auto should say why it took the CPU:\n{}",
        auto.stderr
    );
}

/// A frame split over several GPU tiles (`PRISMBAKE_GPU_TILE=64` on a 96×80 frame: four tiles
/// of three sizes) is the one-tile frame: AOVs, and beauty in both schedules (the wavefront's
/// path records are indexed within a tile, its pixels' random numbers over the frame). Each
/// tile is resolved straight from the read-back into its rectangle of the frame, so a tile
/// written at the wrong row or column, or a missed one, changes the files.
#[test]
fn gpu_frames_split_over_tiles_are_the_one_tile_frame() {
    let dir = temp_dir("gpu-tiles");
    let sphere = example("sphere/sphere.glb");
    let render = |label: &str, aov: &str, schedule: &str, tile: Option<&str>| {
        let out = dir.join(format!("{label}-{}", tile.unwrap_or("whole")));
        let mut envs = vec![("PRISMBAKE_GPU_BEAUTY", schedule)];
        envs.extend(tile.map(|t| ("PRISMBAKE_GPU_TILE", t)));
        #[rustfmt::skip]
        let args = [
            "render", s(&sphere), "--device", "gpu", "--aov", aov, "--res", "96x80", "--spp", "2",
            "--key-light", "30,40,2", "--ground", "-o", s(&out),
        ];
        run_in_env(&repo_root(), &args, &envs).assert_success();
        out
    };
    let aovs = "depth,normal,mask,uv,steps";
    let whole = render("aovs", aovs, "wavefront", None);
    let [mask] = read_channels(&whole.join("mask.exr"), ["Y"]);
    assert!(
        mask.iter().any(|&m| m > 0.5) && mask.contains(&0.0),
        "the sphere does not cover part of the frame"
    );
    let tiled = render("aovs", aovs, "wavefront", Some("64"));
    for aov in aovs.split(',') {
        let file = format!("{aov}.exr");
        assert!(
            std::fs::read(whole.join(&file)).unwrap() == std::fs::read(tiled.join(&file)).unwrap(),
            "{file}: tiles change the AOV"
        );
    }
    for schedule in ["fused", "wavefront"] {
        let beauty =
            |tile| read_rgba(&render(schedule, "beauty", schedule, tile).join("beauty.exr"));
        let whole = beauty(None);
        assert!(
            whole.iter().any(|p| p[3] > 0.5),
            "{schedule}: the sphere is not in the frame"
        );
        assert_same_pixels(&beauty(Some("64")), &whole, &format!("{schedule}, tiles"));
        // Three pixels per trace invocation: tiles 64 and 32 wide take 3 and 2 invocations
        // across, the last of each row short of pixels.
        let across = dir.join(format!("{schedule}-across"));
        #[rustfmt::skip]
        let args = [
            "render", s(&sphere), "--device", "gpu", "--aov", "beauty", "--res", "96x80", "--spp", "2",
            "--key-light", "30,40,2", "--ground", "-o", s(&across),
        ];
        let envs = [
            ("PRISMBAKE_GPU_BEAUTY", schedule),
            ("PRISMBAKE_GPU_TILE", "64"),
            ("PRISMBAKE_GPU_TRACE_PIXELS", "3"),
        ];
        let r = run_in_env(&repo_root(), &args, &envs);
        r.assert_success();
        if schedule == "wavefront" {
            assert!(
                r.stderr.contains("(3 pixel(s) per trace invocation)"),
                "{}",
                r.stderr
            );
        }
        let across = read_rgba(&across.join("beauty.exr"));
        assert_same_pixels(
            &across,
            &whole,
            &format!("{schedule}, 3 pixels per trace invocation"),
        );
    }
}

/// `a` is `b` bit for bit; else how many pixels differ, and the first.
fn assert_same_pixels(a: &[[f32; 4]], b: &[[f32; 4]], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: pixel counts");
    let bits = |p: &[f32; 4]| p.map(f32::to_bits);
    let differ: Vec<usize> = (0..a.len())
        .filter(|&i| bits(&a[i]) != bits(&b[i]))
        .collect();
    assert!(
        differ.is_empty(),
        "{what}: {} of {} pixels differ, first {} ({:?} against {:?})",
        differ.len(),
        a.len(),
        differ[0],
        a[differ[0]],
        b[differ[0]]
    );
}

/// The summary of a `--device auto` render the CPU took over from the GPU, checked to say so:
/// the device, `gpu_fallback` naming `reason`, and the log's device line.
fn rendered_on_the_cpu_because(o: &Output, reason: &str) -> serde_json::Value {
    let json = o.assert_success().json();
    assert!(
        json["device"].as_str().unwrap().starts_with("cpu"),
        "{json}"
    );
    assert!(
        json["gpu_fallback"].as_str().unwrap().contains(reason),
        "{json}"
    );
    assert!(o.stderr.contains("device: cpu ("), "{}", o.stderr);
    json
}

/// The height map goes up as an r32uint texture, two 16-bit texels a word where that keeps
/// them exact (`layout::encode_height_map`): bounded by the device's largest texture side, not
/// by one storage binding. On a device held to WebGPU's default limits
/// (`PRISMBAKE_GPU_LIMITS=webgpu`: 8192 texels a side, 128 MiB a storage binding), so that a
/// hardware adapter runs the same test:
/// * an f32 map of 8192 × 4200 texels (138 MB, over the binding that used to hold the map)
///   renders on the device;
/// * a 16-bit map 16 384 texels wide (8192 words a row) renders there, and one two texels
///   wider does not fit, which is an error under `--device gpu` (no files) and a CPU render
///   under `--device auto`, saying why.
#[test]
fn maps_up_to_the_largest_texture_render_on_the_gpu_and_auto_renders_a_wider_one_on_the_cpu() {
    let dir = temp_dir("gpu-map-limit");
    let write_png = |name: &str, width: u32, height: u32| {
        let data: Vec<u16> = (0..width * height)
            .map(|i| (32768.0 + 12000.0 * ((i % width) as f32 * 0.01).sin()) as u16)
            .collect();
        let path = dir.join(name);
        image::ImageBuffer::<image::Luma<u16>, _>::from_raw(width, height, data)
            .unwrap()
            .save(&path)
            .unwrap();
        path
    };
    let sphere = example("sphere/sphere.glb");
    let render = |device: &str, map: &Path, out: &Path| {
        let args = [
            "render",
            s(&sphere),
            "--disp",
            s(map),
            "--device",
            device,
            "--aov",
            "mask",
            "--res",
            "16x16",
            "--json",
            "-o",
            s(out),
        ];
        run_in_env(&repo_root(), &args, &[("PRISMBAKE_GPU_LIMITS", "webgpu")])
    };
    let on_gpu = |o: Output, encoding: &str| {
        let json = o.assert_success().json();
        assert!(
            json["device"].as_str().unwrap().starts_with("gpu ("),
            "{json}"
        );
        assert_eq!(json["gpu_map_encoding"], encoding, "{json}");
        assert!(json.get("gpu_fallback").is_none(), "{json}");
    };

    // A gentle wave along the rows, in runs that RLE keeps small on disk.
    let (w, h) = (8192usize, 4200usize);
    assert!(w * h * 4 > 128 << 20);
    let f32_map = dir.join("f32.exr");
    let data: Vec<f32> = (0..w * h)
        .map(|i| 0.5 + 0.2 * ((i % w / 64) as f32 * 0.3).sin())
        .collect();
    write_exr(&f32_map, w, h, vec![("Y", data)], true);
    on_gpu(render("gpu", &f32_map, &dir.join("f32")), "f32");

    let fits = write_png("fits.png", 16384, 4);
    on_gpu(render("gpu", &fits, &dir.join("fits")), "unorm16");

    let over = write_png("over.png", 16386, 4);
    render("gpu", &over, &dir.join("refused"))
        .assert_code(2)
        .assert_error(&[
            "height map",
            "largest texture side of 8192",
            "--device auto",
        ]);
    assert!(files_in(&dir.join("refused")).is_empty());

    let auto = render("auto", &over, &dir.join("auto"));
    assert!(
        auto.stderr.contains("cannot hold this scene"),
        "{}",
        auto.stderr
    );
    let auto = rendered_on_the_cpu_because(&auto, "height map");
    assert!(auto.get("gpu_map_encoding").is_none(), "{auto}");
    assert!(dir.join("auto/mask.exr").is_file());
}

/// An environment is bounded on the GPU by the device's largest texture side, not by one storage
/// binding: 8192 × 1400 texels are 138 MB as f32 RGB, over the 128 MiB binding that lavapipe
/// (and WebGPU's defaults) allow, and the beauty lit by it renders on the device, not on the
/// CPU. (It used to be refused: 8K lookdev HDRIs went to the CPU.)
#[test]
fn an_environment_larger_than_a_storage_binding_lights_the_beauty_on_the_gpu() {
    let dir = temp_dir("gpu-env-large");
    let (w, h) = (8192usize, 1400usize);
    assert!(w * h * 12 > 128 << 20);
    // A sky graded by row with a sun, in runs that RLE keeps small on disk (~2 MB).
    let value = |k: usize| {
        move |i: usize| {
            let (x, y) = (i % w, i / w);
            let sun = if (5000..5040).contains(&x) && (300..330).contains(&y) {
                500.0
            } else {
                0.0
            };
            0.2 + 0.1 * k as f32 + 0.5 * (y as f32 / h as f32) + sun
        }
    };
    let ch = |name, k: usize| (name, (0..w * h).map(value(k)).collect());
    let env = dir.join("sky_8k.exr");
    write_exr(&env, w, h, vec![ch("R", 0), ch("G", 1), ch("B", 2)], true);
    let out = dir.join("out");
    let rock = example("rock/rock.glb");
    let json = run(&[
        "render",
        s(&rock),
        "--env",
        s(&env),
        "--device",
        "auto",
        "--aov",
        "beauty",
        "--res",
        "16x16",
        "--spp",
        "1",
        "--json",
        "-o",
        s(&out),
    ])
    .assert_success()
    .json();
    assert!(
        json["device"].as_str().unwrap().starts_with("gpu ("),
        "{json}"
    );
    assert!(json.get("gpu_fallback").is_none(), "{json}");
    assert!(out.join("beauty.exr").is_file());
}

/// A turntable whose lights turn (`--turntable-mode lights`) turns the environment on the GPU
/// as on the CPU: a sky bright on one side only, so a frame lit from another side differs.
#[test]
fn a_turntable_turns_the_environment_on_the_gpu_as_on_the_cpu() {
    let dir = temp_dir("gpu-turned-env");
    let (w, h) = (64usize, 32usize);
    let ch = |name| {
        let v = (0..w * h)
            .map(|i| if i % w < w / 4 { 4.0 } else { 0.05 })
            .collect();
        (name, v)
    };
    let env = dir.join("half_sky.exr");
    write_exr(&env, w, h, vec![ch("R"), ch("G"), ch("B")], false);
    let torus = example("torus/torus.obj");
    let render = |device: &str| {
        let out = dir.join(device);
        run(&[
            "render",
            s(&torus),
            "--env",
            s(&env),
            "--device",
            device,
            "--aov",
            "beauty",
            "--res",
            "16x16",
            "--spp",
            "2",
            "--turntable",
            "3",
            "--turntable-mode",
            "lights",
            "-o",
            s(&out),
        ])
        .assert_success();
        out
    };
    let (gpu, cpu) = (render("gpu"), render("cpu"));
    for f in 0..3 {
        let name = format!("beauty_{f:04}.exr");
        let d = relative_difference(&cpu.join(&name), &gpu.join(&name));
        assert!(d <= 1e-3, "{name}: GPU vs CPU mean |Δ| {d:.2e}");
    }
    let turned = relative_difference(&gpu.join("beauty_0000.exr"), &gpu.join("beauty_0001.exr"));
    assert!(turned > 0.1, "frames 0 and 1 differ by {turned:.2e} only");
}

/// `PRISMBAKE_GPU_LIMITS=webgpu` opens the device with WebGPU's default limits, 8 storage
/// buffers a shader stage among them: the AOV kernel (6) and the fused beauty (8) render there,
/// so the beauty runs on any adapter. The wavefront beauty binds 9: asked for
/// (`PRISMBAKE_GPU_BEAUTY=wavefront`) on such a device, it is an error under `--device gpu`
/// (exit 2, no files, the fix named) and a CPU render under `--device auto` that says why. A
/// setting it does not know is refused before any device is opened.
#[test]
fn under_webgpus_default_limits_the_beauty_renders_and_a_wavefront_that_cannot_falls_back() {
    let dir = temp_dir("gpu-webgpu-limits");
    let rock = example("rock/rock.glb");
    let render = |env: &[(&str, &str)], device: &str, aovs: &str, out: &str| {
        let out = dir.join(out);
        let args = [
            "render",
            s(&rock),
            "--device",
            device,
            "--aov",
            aovs,
            "--spp",
            "2",
            "--res",
            "24x24",
            "--json",
            "-o",
            s(&out),
        ];
        run_in_env(&repo_root(), &args, env)
    };
    let webgpu = [("PRISMBAKE_GPU_LIMITS", "webgpu")];
    let wavefront = [
        ("PRISMBAKE_GPU_LIMITS", "webgpu"),
        ("PRISMBAKE_GPU_BEAUTY", "wavefront"),
    ];

    let both = render(&webgpu, "gpu", "beauty,depth,normal,mask", "both")
        .assert_success()
        .json();
    let device = both["device"].as_str().unwrap();
    assert!(
        device.starts_with("gpu (") && device.contains("WebGPU's default limits"),
        "{both}"
    );
    assert!(both.get("gpu_fallback").is_none(), "{both}");
    assert!(dir.join("both/beauty.exr").is_file() && dir.join("both/mask.exr").is_file());

    render(&wavefront, "gpu", "beauty", "refused")
        .assert_code(2)
        .assert_error(&[
            "binds 9 storage buffers in one shader stage",
            "allows 8",
            "--device auto",
        ]);
    assert!(files_in(&dir.join("refused")).is_empty());

    let auto = render(&wavefront, "auto", "beauty,mask", "auto");
    rendered_on_the_cpu_because(&auto, "storage buffers");
    assert!(dir.join("auto/beauty.exr").is_file() && dir.join("auto/mask.exr").is_file());

    // The adapter's own limits take the wavefront (every adapter the GPU tests run on has 9).
    let full = render(
        &[("PRISMBAKE_GPU_BEAUTY", "wavefront")],
        "gpu",
        "beauty",
        "full",
    )
    .assert_success()
    .json();
    assert!(full.get("gpu_fallback").is_none(), "{full}");
    assert!(dir.join("full/beauty.exr").is_file());

    render(&[("PRISMBAKE_GPU_LIMITS", "tiny")], "gpu", "mask", "bad")
        .assert_code(2)
        .assert_error(&["PRISMBAKE_GPU_LIMITS=tiny", "`webgpu`"]);
    assert!(files_in(&dir.join("bad")).is_empty());
}
