//! `render --denoise`: the beauty filtered by Intel Open Image Denoise, loaded at run time.
//!
//! The tests use the library Blender ships: `test.sh` installs the `bpy` wheel (for the add-on
//! tests) before the Rust tests, and its `lib` folder holds Open Image Denoise 2. A machine
//! without it fails these tests with a message saying how to get it, as the GPU tests fail
//! without an adapter.

use crate::util::*;
use std::path::{Path, PathBuf};

/// The folder holding `libOpenImageDenoise.so.2`: `PRISMBAKE_OIDN`, else the `bpy` wheel in
/// the repository's `.venv`.
fn oidn() -> String {
    if let Some(v) = std::env::var_os("PRISMBAKE_OIDN").filter(|v| !v.is_empty()) {
        return v.to_string_lossy().into_owned();
    }
    let lib = repo_root().join(".venv/lib");
    let found: Option<PathBuf> = std::fs::read_dir(&lib).ok().and_then(|r| {
        r.filter_map(|e| e.ok())
            .map(|e| e.path().join("site-packages/bpy/lib"))
            .find(|p| p.join("libOpenImageDenoise.so.2").exists())
    });
    match found {
        Some(p) => p.to_string_lossy().into_owned(),
        None => panic!(
            "no Open Image Denoise for the --denoise tests: run ./test.sh (it installs bpy, whose \
             lib folder holds one, into .venv) or set PRISMBAKE_OIDN to a libOpenImageDenoise.so.2"
        ),
    }
}

/// `render ASSET --aov beauty --res 64x64 --spp SPP -o OUT FLAGS` with the tests' library.
fn render_beauty(asset: &str, out: &Path, spp: &str, flags: &[&str]) -> Output {
    let asset = example(asset);
    let mut args = vec![
        "render",
        s(&asset),
        "--aov",
        "beauty",
        "--res",
        "64x64",
        "--spp",
        spp,
        "-o",
        s(out),
    ];
    args.extend_from_slice(flags);
    let o = run_in_env(&repo_root(), &args, &[("PRISMBAKE_OIDN", &oidn())]);
    o.assert_success();
    o
}

/// The sphere's beauty close up (a 20° field of view: the relief's cells span several
/// pixels, so noise and detail are told apart), on the CPU unless `extra` says otherwise;
/// the JSON summary.
fn render(out: &Path, spp: &str, extra: &[&str]) -> serde_json::Value {
    let flags = [&["--key-light", "40,50,2", "--fov", "20", "--json"], extra].concat();
    render_beauty("sphere/sphere.glb", out, spp, &flags).json()
}

/// RMS difference of the RGB of two beauty images over the pixels `reference` covers.
fn rms(a: &[[f32; 4]], reference: &[[f32; 4]]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for (p, r) in a.iter().zip(reference) {
        if r[3] > 0.0 {
            sum += (0..3).map(|k| ((p[k] - r[k]) as f64).powi(2)).sum::<f64>();
            n += 3;
        }
    }
    assert!(n > 300, "the sphere covers too few pixels ({})", n / 3);
    (sum / n as f64).sqrt()
}

/// At 4 samples the denoised beauty is much closer to the converged picture (256 samples)
/// than the noisy one (measured: RMS 0.112 → 0.048; a filter that did nothing would stay at
/// 1×), on the CPU and the GPU alike; alpha and the pixels the asset does not cover are left
/// as they were.
#[test]
fn denoised_beauty_is_closer_to_the_converged_picture() {
    let dir = temp_dir("denoise");
    let (noisy, denoised, gpu, converged) = (
        dir.join("noisy"),
        dir.join("denoised"),
        dir.join("gpu"),
        dir.join("converged"),
    );
    render(&converged, "256", &[]);
    let plain = render(&noisy, "4", &[]);
    assert!(plain.get("denoiser").is_none(), "{plain}");
    assert!(plain["frames"][0]["denoise_seconds"].is_null(), "{plain}");
    let summary = render(&denoised, "4", &["--denoise"]);
    let name = summary["denoiser"].as_str().unwrap();
    assert!(
        name.starts_with("Open Image Denoise 2.") && name.contains(", high quality ("),
        "{name}"
    );
    let secs = summary["frames"][0]["denoise_seconds"].as_f64().unwrap();
    assert!(secs > 0.0, "{summary}");

    let reference = read_rgba(&converged.join("beauty.exr"));
    let a = read_rgba(&noisy.join("beauty.exr"));
    let b = read_rgba(&denoised.join("beauty.exr"));
    let (e_noisy, e_denoised) = (rms(&a, &reference), rms(&b, &reference));
    eprintln!("RMS against 256 spp: 4 spp {e_noisy:.4}, 4 spp denoised {e_denoised:.4}");
    assert!(
        e_denoised < 0.6 * e_noisy,
        "denoising did not reduce the error enough: {e_noisy:.4} -> {e_denoised:.4}"
    );
    for (p, q) in a.iter().zip(&b) {
        assert_eq!(p[3], q[3], "alpha changed");
        if p[3] == 0.0 {
            assert_eq!(&q[..3], &[0.0; 3], "radiance where the asset is not");
        }
        assert!(q[..3].iter().all(|v| v.is_finite() && *v >= 0.0), "{q:?}");
    }
    // The fastest filter still halves the noise (measured: 0.112 -> 0.055).
    let fast_dir = dir.join("fast");
    let fast = render(&fast_dir, "4", &["--denoise", "fast"]);
    assert!(fast["denoiser"]
        .as_str()
        .unwrap()
        .contains(", fast quality ("));
    let e_fast = rms(&read_rgba(&fast_dir.join("beauty.exr")), &reference);
    eprintln!("RMS against 256 spp: 4 spp denoised fast {e_fast:.4}");
    assert!(e_fast < 0.6 * e_noisy, "{e_noisy:.4} -> {e_fast:.4}");
    // The preview shows the denoised radiance (it differs from the noisy preview).
    let png = |d: &Path| image::open(d.join("beauty.png")).unwrap().to_rgb8();
    assert_ne!(png(&noisy), png(&denoised));

    // The GPU's beauty and guides match the CPU's, so its denoised picture does too.
    let on_gpu = render(&gpu, "4", &["--denoise", "--device", "gpu"]);
    assert!(on_gpu["device"].as_str().unwrap().starts_with("gpu ("));
    let g = read_rgba(&gpu.join("beauty.exr"));
    let e_gpu = rms(&g, &b);
    eprintln!("GPU denoised against CPU denoised: RMS {e_gpu:.2e}");
    assert!(e_gpu < 0.1 * e_denoised, "{e_gpu} vs {e_denoised}");
    // Its PNG is the denoised picture too, not the preview the GPU tonemapped before the
    // filter (the noisy one, which the CPU's noisy preview all but equals).
    let gap = |a: &Path, b: &Path| {
        let (a, b) = (png(a), png(b));
        let sum: u64 = a
            .iter()
            .zip(b.iter())
            .map(|(p, q)| p.abs_diff(*q) as u64)
            .sum();
        sum as f64 / a.len() as f64
    };
    let (g_png, noisy_png) = (gap(&gpu, &denoised), gap(&noisy, &denoised));
    eprintln!(
        "PNG mean |Δ| against the CPU's denoised: GPU denoised {g_png:.3}, noisy {noisy_png:.3}"
    );
    assert!(g_png < 0.25 * noisy_png, "{g_png} vs {noisy_png}");
}

/// The shadow catcher's shadow (in alpha) is filtered too: at 4 samples its alpha is much
/// closer to the converged one over the ground (measured: RMS 0.232 -> 0.054), and never
/// falls below the asset's coverage.
#[test]
fn denoised_catcher_shadow_is_closer_to_the_converged_one() {
    let dir = temp_dir("denoise-catcher");
    let render = |name: &str, spp: &str, flags: &[&str]| {
        let out = dir.join(name);
        render_beauty("rock/rock.glb", &out, spp, flags);
        read_rgba(&out.join("beauty.exr"))
    };
    let reference = render("converged", "256", &["--ground"]);
    let noisy = render("noisy", "4", &["--ground"]);
    let denoised = render("denoised", "4", &["--ground", "--denoise"]);
    // Without a catcher alpha is the asset's coverage alone (the same samples).
    let coverage = render("bare", "4", &[]);
    // Pixels of the ground in the catcher's shadow: no radiance of the asset in any of the
    // three (none of their samples hit it), some shadow in the converged picture.
    let ground: Vec<usize> = (0..reference.len())
        .filter(|&i| {
            reference[i][3] > 0.001
                && [&reference, &noisy, &denoised]
                    .iter()
                    .all(|im| im[i][..3] == [0.0; 3])
        })
        .collect();
    assert!(
        ground.len() > 500,
        "{} shadowed ground pixels",
        ground.len()
    );
    let rms = |im: &[[f32; 4]]| {
        let sum: f64 = ground
            .iter()
            .map(|&i| ((im[i][3] - reference[i][3]) as f64).powi(2))
            .sum();
        (sum / ground.len() as f64).sqrt()
    };
    let (e_noisy, e_denoised) = (rms(&noisy), rms(&denoised));
    eprintln!("catcher alpha RMS against 256 spp: 4 spp {e_noisy:.4}, denoised {e_denoised:.4}");
    assert!(
        e_denoised < 0.5 * e_noisy,
        "{e_noisy:.4} -> {e_denoised:.4}"
    );
    // The filtered shadow only adds to the asset's coverage: alpha never falls below it, and
    // where the asset covers the whole pixel it stays 1.
    for (c, d) in coverage.iter().zip(&denoised) {
        assert!(d[3] >= c[3] - 1e-6 && d[3] <= 1.0 + 1e-6, "{c:?} -> {d:?}");
    }
}

/// A farm's slice of a denoised turntable (`--frames`) writes the same files as the whole
/// turntable: the filter is deterministic for the same frame.
#[test]
fn denoised_frame_ranges_match_the_whole_turntable() {
    let dir = temp_dir("denoise-frames");
    let (whole, part) = (dir.join("whole"), dir.join("part"));
    let flags = ["--ground", "--turntable", "3", "--denoise", "fast"];
    render_beauty("rock/rock.glb", &whole, "4", &flags);
    render_beauty(
        "rock/rock.glb",
        &part,
        "4",
        &[&flags[..], &["--frames", "2-2"]].concat(),
    );
    for f in ["beauty_0002.exr", "beauty_0002.png"] {
        let read = |d: &Path| std::fs::read(d.join(f)).unwrap();
        assert!(read(&whole) == read(&part), "{f} differs");
    }
    assert_eq!(
        files_in(&part),
        [
            "beauty_0002.exr",
            "beauty_0002.png",
            "beauty_contact_sheet.png"
        ]
    );
}

/// No library, a library that is not Open Image Denoise, or `--denoise` without beauty: a
/// clear error before anything is rendered, exit 2, and no files.
#[test]
fn denoise_without_the_library_or_the_beauty_is_an_error() {
    let dir = temp_dir("denoise-errors");
    let sphere = example("sphere/sphere.glb");
    let args = |out: &str, aov: &'static str| {
        vec![
            "render".to_string(),
            s(&sphere).to_string(),
            "--aov".into(),
            aov.into(),
            "--res".into(),
            "16x16".into(),
            "--denoise".into(),
            "-o".into(),
            out.to_string(),
        ]
    };
    let libm = [
        "/lib/x86_64-linux-gnu/libm.so.6",
        "/usr/lib/x86_64-linux-gnu/libm.so.6",
    ]
    .into_iter()
    .find(|p| Path::new(p).exists())
    .unwrap_or("libm.so.6");
    let missing = dir.join("no-such-folder");
    let cases: [(&str, &str, &'static str, &[&str]); 3] = [
        (
            "missing",
            s(&missing),
            "beauty",
            &["no-such-folder", "install.sh", "PRISMBAKE_OIDN"],
        ),
        (
            "libm",
            libm,
            "beauty",
            &["oidnNewDevice", "not Open Image Denoise 2"],
        ),
        ("aov", "", "normal", &["--denoise filters the beauty only"]),
    ];
    for (name, lib, aov, words) in cases {
        let out = dir.join(name);
        let a = args(s(&out), aov);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let lib = if lib.is_empty() {
            oidn()
        } else {
            lib.to_string()
        };
        let o = run_in_env(&repo_root(), &a, &[("PRISMBAKE_OIDN", &lib)]);
        assert_eq!(o.code, 2, "{name}: {}", o.stderr);
        for w in words {
            assert!(o.stderr.contains(w), "{name}: no '{w}' in: {}", o.stderr);
        }
        assert!(files_in(&out).is_empty(), "{name}: {:?}", files_in(&out));
    }
}
