//! `bake` and `inspect` end to end on the bundled examples.

use crate::util::*;

#[test]
fn bake_writes_a_table_and_reuses_it_for_the_same_inputs() {
    let dir = temp_dir("bake");
    let out = dir.join("sphere.prisms");
    let sphere = example("sphere/sphere.glb");
    let first = run(&["bake", s(&sphere), "-o", s(&out), "--json"]);
    first.assert_success();
    let j = first.json();
    assert_eq!(j["reused"], false);
    let prisms = j["prisms"].as_u64().unwrap();
    assert!(prisms > 500, "{j}");
    // The documented budget: at most 64 bytes per triangle on disk.
    assert!(j["bytes_per_prism"].as_f64().unwrap() <= 64.0, "{j}");
    assert_eq!(
        std::fs::metadata(&out).unwrap().len(),
        j["bytes"].as_u64().unwrap()
    );

    let second = run(&["bake", s(&sphere), "-o", s(&out), "--json"]);
    second.assert_success();
    assert_eq!(second.json()["reused"], true);

    // A different scale is a different input: re-baked.
    let third = run(&[
        "bake",
        s(&sphere),
        "-o",
        s(&out),
        "--json",
        "--scale",
        "0.02",
    ]);
    third.assert_success();
    assert_eq!(third.json()["reused"], false);
    assert_eq!(files_in(&dir), vec!["sphere.prisms"]);

    // The table reads back through inspect.
    let info = run(&["inspect", s(&out), "--json"]);
    info.assert_success();
    assert_eq!(info.json()["prisms"].as_u64().unwrap(), prisms);
}

#[test]
fn bake_repairs_creases_of_the_rock() {
    let dir = temp_dir("bake-rock");
    let out = dir.join("rock.prisms");
    let r = run(&[
        "bake",
        s(&example("rock/rock.glb")),
        "-o",
        s(&out),
        "--json",
    ]);
    r.assert_success();
    let j = r.json();
    assert!(
        !j["repair"]["sharp_corners"].as_array().unwrap().is_empty(),
        "the rock example has creases: {j}"
    );
    assert!(j["inserted_prisms"].as_u64().unwrap() > 0, "{j}");
}

#[test]
fn inspect_reports_mesh_and_map() {
    let r = run(&["inspect", s(&example("sphere/sphere.glb")), "--json"]);
    r.assert_success();
    let j = r.json();
    assert!(j["triangles"].as_u64().unwrap() > 500);
    assert_eq!(j["has_uvs"], true);
    assert_eq!(
        j["camera"], true,
        "the sphere example carries a glTF camera"
    );
    assert_eq!(j["uv_sets"][0], 0);
    assert_eq!(j["map"]["width"], 1024);
    assert!(j["estimated_table_bytes"].as_u64().unwrap() > 0);
    let t = run(&["inspect", s(&example("torus/torus.obj"))]);
    t.assert_success();
    assert!(t.stdout.contains("triangles"));
    // No materials in the OBJ: every triangle the default.
    assert!(t.stdout.contains("material  'default': "), "{}", t.stdout);
    // The rock's one material with its texture, over all its triangles.
    let r = run(&["inspect", s(&example("rock/rock.glb")), "--json"]);
    let j = r.json();
    let m = &j["materials"];
    assert_eq!(m.as_array().unwrap().len(), 1, "{m}");
    assert_eq!(m[0]["name"], "rock_mat");
    assert_eq!(m[0]["texture"], "rock_albedo");
    assert_eq!(m[0]["triangles"], j["triangles"]);
    assert_eq!(m[0]["roughness"].as_f64().unwrap() as f32, 0.7);
}
