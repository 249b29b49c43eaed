//! `bench` and `render --method` end to end for every method: the same rays, one row per
//! method and setting with time, error, leaks, memory and build time, and a plot per asset.

use crate::util::*;

#[test]
fn bench_runs_every_method_on_the_same_rays() {
    let out = temp_dir("bench-methods");
    run(&[
        "bench",
        s(&example("torus/torus.obj")),
        "--methods",
        "pdm,rmip,nonlinear",
        "--dt",
        "auto:1,auto:0.5",
        "--marching-scale",
        "2,8",
        "--precision",
        "f32,f64",
        "--res",
        "24x16",
        "--leak-rays",
        "3000",
        "--ref-density",
        "1",
        "--repeats",
        "1",
        "-o",
        s(&out),
    ])
    .assert_success();
    let rows: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("bench.json")).unwrap()).unwrap();
    let rows = rows.as_array().unwrap();
    let settings: Vec<(String, String)> = rows
        .iter()
        .map(|r| {
            (
                r["method"].as_str().unwrap().to_string(),
                r["setting"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    let count = |m: &str| settings.iter().filter(|(method, _)| method == m).count();
    // Each method's own knob is swept: two dt, two marching scales, two precisions.
    assert_eq!(
        (
            count("reference"),
            count("pdm"),
            count("rmip"),
            count("nonlinear")
        ),
        (1, 2, 2, 2),
        "{settings:?}"
    );
    for r in rows {
        let what = format!("{} {}", r["method"], r["setting"]);
        assert_eq!(r["rays"], 24 * 16, "{what}");
        assert_eq!(r["leak_rays"], 3000, "{what}");
        // The closed torus: nothing passes through, for any method.
        assert_eq!(r["through"], 0, "{what}");
        assert_eq!(r["leaks"], 0, "{what}");
        assert_eq!(r["leaks_inside"], 0, "{what}");
        // The local k = 8 check is on by default (nothing to confirm here).
        assert_eq!(r["leaks_confirmed"], 0, "{what}");
        assert!(r["mismatch_rate"].as_f64().unwrap() <= 0.01, "{what}");
        assert!(r["rays_per_s"].as_f64().unwrap() > 0.0, "{what}");
        assert!(r["memory_bytes"].as_u64().unwrap() > 0, "{what}");
        assert!(r["build_seconds"].as_f64().unwrap() > 0.0, "{what}");
    }
    let csv = std::fs::read_to_string(out.join("bench.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    assert!(header.ends_with(",build_seconds"), "{header}");
    assert!(
        header.contains(",leaks,leaks_inside,leaks_confirmed,through,"),
        "{header}"
    );
    assert_eq!(csv.lines().count(), 1 + rows.len());
    let plot = image::open(out.join("torus.png")).expect("time-vs-error plot");
    assert!(plot.width() > 100 && plot.height() > 100);
}

/// `bench` reads a baked table as `render` does: the same rays (the rock's table, baked into
/// another folder) give the same errors, steps and leaks as the mesh. `validate`, which
/// checks meshes, says a table is not one and how to get the mesh.
#[test]
fn bench_reads_a_baked_table_as_the_mesh() {
    let dir = temp_dir("bench-table");
    let table = dir.join("tables/rock.prisms");
    run(&["bake", s(&example("rock/rock.glb")), "-o", s(&table)]).assert_success();
    let bench = |input: &std::path::Path, name: &str| {
        let out = dir.join(name);
        let mut args = vec!["bench", s(input), "--methods", "pdm", "--res", "16x12"];
        args.extend(["--leak-rays", "500", "--ref-density", "1", "--repeats", "1"]);
        args.extend(["-o", s(&out)]);
        run(&args).assert_success();
        let rows: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("bench.json")).unwrap()).unwrap();
        rows.as_array().unwrap().clone()
    };
    let (mesh, baked) = (
        bench(&example("rock/rock.glb"), "mesh"),
        bench(&table, "table"),
    );
    assert!(!mesh.is_empty() && mesh.len() == baked.len(), "{mesh:?}");
    for (m, t) in mesh.iter().zip(&baked) {
        for key in [
            "method",
            "setting",
            "rays",
            "steps_per_ray",
            "mismatch_rate",
            "depth_err_median_texels",
            "depth_err_p99_texels",
            "normal_err_p99_deg",
            "leaks",
        ] {
            assert_eq!(m[key], t[key], "{key}: mesh {m}\ntable {t}");
        }
    }
    run(&["validate", s(&table)]).assert_code(1);
    let o = run(&["validate", s(&table)]);
    assert!(
        o.stdout.contains("is a baked prism table, not a mesh"),
        "{}",
        o.stdout
    );
}

#[test]
fn bench_refuses_reference_densities_out_of_range_before_writing() {
    let torus = example("torus/torus.obj");
    for (flag, value, range) in [
        ("--confirm-density", "-1", "(0, 64]"),
        ("--confirm-density", "1000", "(0, 64]"),
        ("--ref-density", "0", "(0, 64]"),
        ("--ref-density", "NaN", "(0, 64]"),
        ("--ref-memory", "0", "(0, 1e6]"),
        ("--ref-memory", "NaN", "(0, 1e6]"),
    ] {
        let out = temp_dir("bench-bad-density");
        let dir = out.join("results");
        // `--flag=value`: clap reads a bare `-1` as an option.
        let arg = format!("{flag}={value}");
        run(&["bench", s(&torus), &arg, "-o", s(&dir)])
            .assert_error(&[&format!("{flag} {value}"), range]);
        assert!(
            !dir.exists(),
            "{flag} {value}: the output folder was created"
        );
    }
}

/// A reference larger than its memory budget is refused before it takes the memory (the
/// machine would otherwise kill the process, or swap for minutes), naming the asset, its
/// size and a density that fits; that density renders, and the budget's bytes a
/// micro-triangle cover what the build took (VmHWM less a render with a tiny reference).
#[test]
fn a_reference_over_its_memory_budget_is_refused_with_a_density_that_fits() {
    let rock = example("rock/rock.glb");
    let dir = temp_dir("ref-budget");
    let render = |k: &str, gib: &str| {
        run(&[
            "render",
            s(&rock),
            "--method",
            "reference",
            "--ref-density",
            k,
            "--ref-memory",
            gib,
            "--aov",
            "depth",
            "--res",
            "16x16",
            "--json",
            "-o",
            s(&dir),
        ])
    };
    let refused = render("8", "0.5");
    refused.assert_error(&[
        "rock.glb",
        "the reference at --ref-density 8 is 3.88 M micro-triangles",
        "over the 0.50 GiB it may take (--ref-memory",
    ]);
    assert!(!dir.join("depth.exr").exists(), "{:?}", files_in(&dir));
    let after = |text: &str, key: &str| -> f64 {
        let tail = &text[text.find(key).unwrap_or_else(|| panic!("{key}: {text}")) + key.len()..];
        let end = tail
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap();
        tail[..end].parse().unwrap()
    };
    let fit = after(&refused.stderr, "; --ref-density ");
    assert!(fit > 2.0 && fit < 8.0, "{}", refused.stderr);
    let suggestion = &refused.stderr[refused.stderr.find("; --ref-density").unwrap()..];
    let predicted = after(suggestion, "M micro-triangles, about ") * (1u64 << 30) as f64;
    let peak = |out: &Output| out.json()["peak_memory_bytes"].as_u64().unwrap() as f64;
    let base = peak(render("0.01", "0.5").assert_success());
    let fits = render(&fit.to_string(), "0.5");
    let used = peak(fits.assert_success()) - base;
    assert!(dir.join("depth.exr").exists());
    assert!(
        used <= predicted && used >= predicted / 2.0,
        "k = {fit}: built in {used} bytes, predicted {predicted}"
    );
    // bench refuses the same way, before writing its tables.
    let bench_dir = temp_dir("ref-budget-bench");
    run(&[
        "bench",
        s(&rock),
        "--ref-density",
        "8",
        "--ref-memory",
        "0.5",
        "-o",
        s(&bench_dir),
    ])
    .assert_error(&["rock.glb", "--ref-density 8 is", "fits"]);
    assert!(!bench_dir.join("bench.csv").exists());
}

#[test]
fn every_method_renders_the_same_silhouette() {
    let sphere = example("sphere/sphere.glb");
    let mask = |method: &str| {
        let dir = temp_dir(&format!("render-{method}"));
        run(&[
            "render",
            s(&sphere),
            "--method",
            method,
            "--res",
            "40x40",
            "--aov",
            "mask,depth",
            "-o",
            s(&dir),
        ])
        .assert_success();
        let img = image::open(dir.join("mask.png")).unwrap().to_luma8();
        img.pixels().map(|p| p.0[0] > 127).collect::<Vec<bool>>()
    };
    let pdm = mask("pdm");
    let covered = pdm.iter().filter(|&&c| c).count();
    assert!(covered > 100 && covered < 1500, "coverage {covered}");
    for method in ["rmip", "nonlinear"] {
        let other = mask(method);
        let differ = pdm.iter().zip(&other).filter(|(a, b)| a != b).count();
        // Silhouette pixels may flip on a grazing sample; 0.5% of 1600 is 8.
        assert!(
            differ <= 8,
            "{method}: {differ} mask pixels differ from pdm"
        );
    }
}
