//! `validate` on files and folders: exit codes, formats, sidecars.

use crate::util::*;
use std::path::Path;

fn write(path: &Path, text: &str) {
    std::fs::write(path, text).unwrap();
}

/// A one-quad OBJ with UVs, and a copy with one inverted vertex normal.
fn quad_obj(normal_z: f32) -> String {
    format!(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nvn 0 0 {normal_z}\nf 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/2\n"
    )
}

#[test]
fn examples_fail_only_on_their_seam_jumps() {
    // The sphere's pole fans and the rock's box-projected islands sample different texels on
    // the two sides of their UV seams (the torus's seams are whole map periods apart): that
    // is the one problem validate reports on the examples; renders stitch it by default.
    let r = run(&["validate", s(&example("")), "--format", "json"]);
    r.assert_code(1);
    let j = r.json();
    assert_eq!(j["summary"]["assets"], 3, "{j}");
    assert_eq!(j["summary"]["failed"], 2, "{j}");
    for asset in j["assets"].as_array().unwrap() {
        let name = asset["asset"].as_str().unwrap();
        for check in asset["checks"].as_array().unwrap() {
            let failed = check["status"] == "fail";
            let seam = check["name"] == "seam-jump";
            let expect_fail = seam && !name.contains("torus");
            assert_eq!(failed, expect_fail, "{name}: {check}");
        }
    }
}

#[test]
fn problems_exit_one_and_name_faces_in_every_format() {
    let dir = temp_dir("validate");
    write(&dir.join("bad.obj"), &quad_obj(-1.0));
    write(
        &dir.join("bad.prismbake.toml"),
        "disp = \"h.png\"\nscale = 0.1\nwrap = \"clamp\"\n",
    );
    write(&dir.join("good.obj"), &quad_obj(1.0));
    write(
        &dir.join("good.prismbake.toml"),
        "disp = \"h.png\"\nscale = 0.1\n",
    );
    // A real 16-bit PNG written by hand-rolled code would be overkill: reuse an example map.
    std::fs::copy(example("maps/scales_256.png"), dir.join("h.png")).unwrap();

    let text = run(&["validate", s(&dir)]);
    text.assert_code(1);
    assert!(text.stdout.contains("inverted-normals"), "{}", text.stdout);
    assert!(text.stdout.contains("faces: 1"), "{}", text.stdout);

    let json = run(&["validate", s(&dir), "--format", "json"]);
    json.assert_code(1);
    let j = json.json();
    assert_eq!(j["summary"]["failed"], 1);

    let junit = run(&["validate", s(&dir), "--format", "junit"]);
    junit.assert_code(1);
    let doc = roxmltree::Document::parse(&junit.stdout).expect("JUnit output is well-formed XML");
    let cases: Vec<_> = doc
        .descendants()
        .filter(|n| n.has_tag_name("testcase"))
        .collect();
    assert_eq!(cases.len(), 2 * 11, "one test case per asset × check");
    let failures = doc
        .descendants()
        .filter(|n| n.has_tag_name("failure"))
        .count();
    assert_eq!(failures, 1);

    // --max-disp turns the displacement check on for both assets.
    let strict = run(&[
        "validate",
        s(&dir.join("good.obj")),
        "--max-disp",
        "0.001",
        "--format",
        "json",
    ]);
    strict.assert_code(1);
    let checks = &strict.json()["assets"][0]["checks"];
    let md = checks
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == "max-displacement")
        .unwrap();
    assert_eq!(md["status"], "fail");

    // The report can go to a file (written whole, atomically).
    let out = dir.join("report.xml");
    run(&["validate", s(&dir), "--format", "junit", "-o", s(&out)]).assert_code(1);
    assert!(std::fs::read_to_string(&out)
        .unwrap()
        .contains("<testsuites"));
}

#[test]
fn unreadable_map_and_missing_uvs_are_problems_not_crashes() {
    let dir = temp_dir("validate-map");
    write(&dir.join("a.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    write(
        &dir.join("a.prismbake.toml"),
        "disp = \"missing.png\"\nscale = 0.1\n",
    );
    let r = run(&["validate", s(&dir), "--format", "json"]);
    r.assert_code(1);
    let j = r.json();
    let checks = j["assets"][0]["checks"].as_array().unwrap();
    let status = |name: &str| checks.iter().find(|c| c["name"] == name).unwrap()["status"].clone();
    assert_eq!(status("uvs"), "fail");
    assert_eq!(status("map"), "fail");
}

#[test]
fn usage_errors_exit_two() {
    run(&["validate", "/nonexistent/path"]).assert_code(2);
    let dir = temp_dir("validate-empty");
    run(&["validate", s(&dir)])
        .assert_error(&["no mesh files"])
        .assert_code(2);
    run(&["validate"]).assert_code(2);
}

#[test]
fn a_base_colour_texture_that_does_not_decode_fails_the_textures_check() {
    // The examples pass it (the rock's texture decodes: examples_fail_only_on_their_seam_jumps);
    // a corrupt one fails it, naming the material and the image, and fails the asset.
    let dir = temp_dir("validate-texture");
    let rock = rock_with_a_corrupt_texture(&dir);
    let r = run(&["validate", s(&rock), "--format", "json"]);
    r.assert_code(1);
    let j = r.json();
    let checks = j["assets"][0]["checks"].as_array().unwrap();
    let t = checks
        .iter()
        .find(|c| c["name"] == "textures")
        .expect("a textures check");
    assert_eq!(t["status"], "fail", "{t}");
    let msg = t["message"].as_str().unwrap();
    for part in ["material 'rock_mat'", "'rock_albedo'", "cannot decode"] {
        assert!(msg.contains(part), "no '{part}' in {msg}");
    }
    let good = run(&["validate", s(&example("rock/rock.glb")), "--format", "json"]);
    let j = good.json();
    let t = j["assets"][0]["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == "textures")
        .cloned()
        .unwrap();
    assert_eq!(t["status"], "pass", "{t}");
    assert!(
        t["message"]
            .as_str()
            .unwrap()
            .contains("'rock_albedo' 256x256"),
        "{t}"
    );
}

/// A USD dome light lights the beauty, so its texture is checked with the materials': a
/// missing one fails the `textures` check naming the dome and the file, one that decodes
/// passes with its size.
#[test]
fn a_dome_lights_texture_is_in_the_textures_check() {
    let dir = temp_dir("validate-dome");
    let map = write_flat_map(&dir);
    write_constant_env(&dir.join("sky.exr"), 1.0);
    let textures = |texture: &str| {
        let usda = dir.join(format!("{texture}.usda"));
        let dome =
            format!("def DomeLight \"Sky\"\n{{\n    asset inputs:texture:file = @{texture}@\n}}\n");
        std::fs::write(&usda, quad_usda(&dome)).unwrap();
        let r = run(&["validate", s(&usda), "--disp", s(&map), "--format", "json"]);
        let j = r.json();
        let check = j["assets"][0]["checks"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["name"] == "textures")
            .cloned()
            .expect("a textures check");
        (r.code, check)
    };
    let (code, t) = textures("sky.exr");
    assert_eq!(t["status"], "pass", "{t}");
    assert!(
        t["message"]
            .as_str()
            .unwrap()
            .contains("dome light /Sky: '")
            && t["message"].as_str().unwrap().contains("sky.exr' 16x8"),
        "{t} (exit {code})"
    );
    let (code, t) = textures("gone.exr");
    assert_eq!((code, t["status"].as_str().unwrap()), (1, "fail"), "{t}");
    let msg = t["message"].as_str().unwrap();
    assert!(
        msg.contains("dome light /Sky: its texture") && msg.contains("gone.exr"),
        "{msg}"
    );
}
