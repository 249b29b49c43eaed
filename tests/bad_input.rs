//! Bad input: a clear one-line error naming the file and element, a non-zero exit, no panic,
//! and no output file left behind (half-written or otherwise).

use crate::util::*;
use std::path::{Path, PathBuf};

/// Bake `mesh` with `map` into a fresh folder; assert the error and that nothing was written.
fn bake_fails(name: &str, mesh: &Path, map: &Path, needles: &[&str]) {
    let dir = temp_dir(name);
    let out = dir.join("out.prisms");
    run(&[
        "bake",
        s(mesh),
        "--disp",
        s(map),
        "--scale",
        "0.1",
        "-o",
        s(&out),
    ])
    .assert_error(needles);
    assert!(
        files_in(&dir).is_empty(),
        "{name}: left files {:?}",
        files_in(&dir)
    );
}

fn map() -> PathBuf {
    example("maps/scales_256.png")
}

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// A minimal glTF: one triangle, positions only (no normals, no UVs), external buffer.
fn gltf_without_uvs(dir: &Path) -> PathBuf {
    let floats: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let bin: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    write(dir, "tri.bin", &bin);
    let json = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
      "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],
      "bufferViews":[{"buffer":0,"byteLength":36}],"buffers":[{"byteLength":36,"uri":"tri.bin"}]}"#;
    write(dir, "nouv.gltf", json)
}

#[test]
fn missing_and_unknown_files() {
    bake_fails(
        "missing",
        Path::new("/nonexistent/rock.glb"),
        &map(),
        &["/nonexistent/rock.glb"],
    );
    let dir = temp_dir("ext");
    let stl = write(&dir, "model.stl", "solid x\nendsolid x\n");
    bake_fails("unknown-ext", &stl, &map(), &["model.stl", ".glb"]);
    bake_fails(
        "missing-map",
        &example("sphere/sphere.glb"),
        Path::new("/nonexistent/h.png"),
        &["/nonexistent/h.png"],
    );
}

#[test]
fn truncated_glb() {
    let dir = temp_dir("trunc");
    let bytes = std::fs::read(example("sphere/sphere.glb")).unwrap();
    for n in [0, 11, 20, 100, bytes.len() / 2, bytes.len() - 1] {
        let p = write(&dir, &format!("cut{n}.glb"), &bytes[..n]);
        bake_fails(&format!("trunc{n}"), &p, &map(), &[&format!("cut{n}.glb")]);
    }
}

#[test]
fn gltf_without_uvs_is_refused_by_bake() {
    let dir = temp_dir("nouv");
    let p = gltf_without_uvs(&dir);
    bake_fails("nouv-bake", &p, &map(), &["nouv.gltf", "no UV"]);
}

#[test]
fn broken_obj_files() {
    let dir = temp_dir("obj");
    let nan = write(
        &dir,
        "nan.obj",
        "v nan 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n",
    );
    bake_fails("nan", &nan, &map(), &["nan.obj", "vertex 0"]);
    let oob = write(
        &dir,
        "oob.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 9/1\n",
    );
    bake_fails("oob", &oob, &map(), &["oob.obj"]);
    let empty = write(&dir, "empty.obj", "v 0 0 0\nv 1 0 0\n");
    bake_fails("empty", &empty, &map(), &["empty.obj", "zero triangles"]);
}

#[test]
fn broken_maps() {
    let dir = temp_dir("maps");
    let corrupt = write(&dir, "corrupt.png", b"\x89PNG\r\n\x1a\nthis is not a png");
    bake_fails(
        "corrupt-map",
        &example("sphere/sphere.glb"),
        &corrupt,
        &["corrupt.png"],
    );
    let folder = dir.join("folder.png");
    std::fs::create_dir_all(&folder).unwrap();
    bake_fails(
        "dir-map",
        &example("sphere/sphere.glb"),
        &folder,
        &["folder.png", "directory"],
    );
    let bad_ext = write(&dir, "h.bmp", b"BM");
    bake_fails(
        "bmp-map",
        &example("sphere/sphere.glb"),
        &bad_ext,
        &["h.bmp"],
    );
}

#[test]
fn bad_prism_tables() {
    let dir = temp_dir("tables");
    let good = dir.join("good.prisms");
    run(&["bake", s(&example("torus/torus.obj")), "-o", s(&good)]).assert_success();
    let bytes = std::fs::read(&good).unwrap();

    // A table from another format version (version 1 had no seam records).
    let mut v1 = bytes.clone();
    v1[8] = 1;
    let p = write(&dir, "v1.prisms", &v1);
    run(&["inspect", s(&p)]).assert_error(&["v1.prisms", "version 1", "re-bake"]);

    let p = write(&dir, "cut.prisms", &bytes[..bytes.len() - 7]);
    run(&["inspect", s(&p)]).assert_error(&["cut.prisms", "truncated"]);

    let mut huge = bytes.clone();
    huge[20..28].copy_from_slice(&1_000_000_000_000u64.to_le_bytes());
    let p = write(&dir, "huge.prisms", &huge);
    run(&["inspect", s(&p)]).assert_error(&["huge.prisms", "1000000000000 prisms"]);

    let mut flipped = bytes.clone();
    let mid = flipped.len() / 2;
    flipped[mid] ^= 0x40;
    let p = write(&dir, "flip.prisms", &flipped);
    run(&["inspect", s(&p)]).assert_error(&["flip.prisms", "checksum"]);
}

#[test]
fn bad_parameters() {
    let dir = temp_dir("params");
    let out = dir.join("o.prisms");
    run(&[
        "bake",
        s(&example("sphere/sphere.glb")),
        "--scale",
        "nan",
        "-o",
        s(&out),
    ])
    .assert_error(&["finite"]);
    run(&[
        "bake",
        s(&example("sphere/sphere.glb")),
        "--crease-threshold",
        "2",
        "-o",
        s(&out),
    ])
    .assert_error(&["--crease-threshold"]);
    run(&[
        "bake",
        s(&example("sphere/sphere.glb")),
        "--wrap",
        "mirror",
        "-o",
        s(&out),
    ])
    .assert_code(2);
    // No map anywhere: the message says how to give one.
    let obj = write(
        &dir,
        "m.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n",
    );
    run(&["bake", s(&obj), "-o", s(&out)]).assert_error(&["m.obj", "--disp", "m.prismbake.toml"]);
    assert!(files_in(&dir).iter().all(|f| f == "m.obj"));
}
