//! The fuzzers' findings, replayed in every `cargo test` (docs/fuzzing.md): each crash ever
//! found frozen as a literal input, and the committed corpora (`fuzz/corpus/<target>/`) fed
//! to the same entry points the fuzz targets call. A panic here is a parser that trusts its
//! input again; every input must give `Ok` or a clean `Err`.

use prismbake::load::{self, MapOptions, MeshOptions};
use prismbake::prism_file;
use std::path::{Path, PathBuf};

fn scratch(name: &str, bytes: &[u8]) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("prismbake-fuzz-regressions-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// gltf-json 1.4 indexed the POSITION accessor before checking it during validation:
/// `"POSITION": 0` with no accessors panicked inside `Gltf::from_slice` (found by the `glb`
/// target in its first seconds, from a seed whose `"accessors"` key had two bits flipped).
#[test]
fn gltf_position_accessor_out_of_range_is_an_error() {
    let json =
        br#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}]}"#;
    let err =
        load::load_mesh(&scratch("position.gltf", json), &MeshOptions::default()).unwrap_err();
    assert!(
        err.to_string()
            .contains("POSITION names accessor 0 but there are 0"),
        "{err}"
    );
    // The same inside a .glb (the fuzzer's form): header, JSON chunk, no BIN chunk.
    let mut chunk = json.to_vec();
    chunk.resize(chunk.len().div_ceil(4) * 4, b' ');
    let mut glb = b"glTF".to_vec();
    glb.extend(2u32.to_le_bytes());
    glb.extend((20 + chunk.len() as u32).to_le_bytes());
    glb.extend((chunk.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&chunk);
    assert!(load::load_mesh(&scratch("position.glb", &glb), &MeshOptions::default()).is_err());
}

fn corpus(target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fuzz/corpus")
        .join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "{} is empty", dir.display());
    files
        .into_iter()
        .map(|p| (p.clone(), std::fs::read(&p).unwrap()))
        .collect()
}

#[test]
fn prism_table_corpus_decodes_or_fails_cleanly() {
    let mut ok = 0;
    for (_, bytes) in corpus("prism_table") {
        ok += prism_file::decode(&bytes).is_ok() as usize;
    }
    assert!(
        ok > 0,
        "the corpus keeps at least one valid table (the seeds)"
    );
}

#[test]
fn prism_table_every_truncation_of_a_baked_table_fails_cleanly() {
    // meshoptimizer's rule on a real table (the smallest valid one in the corpus).
    let (path, bytes) = corpus("prism_table")
        .into_iter()
        .filter(|(_, b)| prism_file::decode(b).is_ok())
        .min_by_key(|(_, b)| b.len())
        .unwrap();
    for n in 0..bytes.len() {
        assert!(
            prism_file::decode(&bytes[..n]).is_err(),
            "{}: prefix of {n} bytes decoded",
            path.display()
        );
    }
}

fn replay_files(target: &str, ext: &str, mut load: impl FnMut(&Path)) {
    for (i, (_, bytes)) in corpus(target).into_iter().enumerate() {
        load(&scratch(&format!("{target}-{i}.{ext}"), &bytes));
    }
}

#[test]
fn obj_corpus_loads_or_fails_cleanly() {
    replay_files("obj", "obj", |p| {
        drop(load::load_mesh(p, &MeshOptions::default()))
    });
}

/// The `mtl` target's corpus: each input the .mtl a fixed .obj names, its materials then
/// read as the render reads them.
#[test]
fn mtl_corpus_loads_or_fails_cleanly() {
    let mut loaded = 0;
    replay_files("mtl", "mtl", |mtl| {
        let name = mtl.file_name().unwrap().to_str().unwrap();
        let obj = format!(
            "mtllib {name}\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n\
             usemtl a\nf 1/1 2/2 3/3\nusemtl b\nf 1/1 2/2 3/3\n"
        );
        let obj = scratch(&format!("{name}.obj"), obj.as_bytes());
        if let Ok(mesh) = load::load_mesh(&obj, &MeshOptions::default()) {
            loaded += (mesh.materials.len() >= 2) as usize;
            for m in &mesh.materials {
                let _ = prismbake::render::lookdev::describe_alpha(m, None);
                let _ = prismbake::render::lookdev::check_material_values(
                    &mesh,
                    m,
                    &Default::default(),
                );
            }
        }
    });
    assert!(loaded > 0, "no input of the mtl corpus loads its materials");
}

/// The `pipeline` target's check (load, repair, bake, PDM and reference traces of a fuzzed
/// OBJ), over its corpus.
#[path = "../../fuzz/fuzz_targets/pipeline_check.rs"]
mod pipeline_check;

#[test]
fn pipeline_corpus_traces_true_hits() {
    let mut hits = Vec::new();
    replay_files("pipeline", "obj", |p| hits.push(pipeline_check::check(p)));
    // The hand-made seeds (a quad, a cube, slivers, a fold, huge and tiny triangles, a
    // tetrahedron) load and are hit: the replay traces, it does not only load.
    let seeds = corpus("pipeline")
        .iter()
        .zip(&hits)
        .filter(|((p, _), _)| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("seed-")
        })
        .map(|(_, &h)| h)
        .collect::<Vec<_>>();
    assert!(
        seeds.len() >= 6 && seeds.iter().filter(|&&h| h > 0).count() >= 5,
        "{seeds:?}"
    );
}

/// Found by the `pipeline` target, two ways to one 4096² grid (the segment cap) in the
/// reference's tessellation of a tiny mesh:
/// * three triangles whose UVs meet (two corners of one share a UV), folded, so that repair
///   inserts a crease strip whose rung turns the normal by 0.04°. Its texel size, a quarter
///   of that rung's arc, was 6 µm, and the strip's 1.4-long edge, whose UVs meet, was counted
///   at that rate: 50.9 M micro-triangles, a 1.8 GB allocation (an out-of-memory abort);
/// * a cube with a vertex pulled out to x = 71 and UVs to v = 8: a strip with one rung that
///   barely turns (a texel of 8 nm) and others at 90°, each counted at 10⁸ texels (a timeout
///   in the fuzzer, 11.7 GB and past two minutes for `render --method reference`; 0.8 s and
///   247 MB now).
///
/// An edge whose UVs meet is now counted by its normals' arc alone, at most 64 texels of it
/// (`tessellate::edge_segments_wanted`, `MAX_ARC_TEXELS`).
#[test]
fn an_edge_whose_uvs_meet_is_not_tessellated_at_a_rungs_texel_size() {
    for (name, bytes) in [
        (
            "oom-degenerate-uv",
            &include_bytes!("../../fuzz/corpus/pipeline/oom-degenerate-uv")[..],
        ),
        (
            "timeout-sliver-cube",
            &include_bytes!("../../fuzz/corpus/pipeline/timeout-sliver-cube")[..],
        ),
    ] {
        let path = scratch(&format!("{name}.obj"), bytes);
        let scene = pipeline_check::scene(&path).expect("the mesh loads");
        let mesh = prismbake::tessellate::tessellate(&scene.surface(), 2.0);
        let n = mesh.triangle_count();
        // 6 609 and 656 633 now (the sliver cube's UVs cross 64 texels); a capped grid alone
        // is 33.5 M.
        assert!(n < 2_000_000, "{name}: {n} micro-triangles");
        assert_eq!(mesh.capped_edges, 0, "{name}");
        assert!(pipeline_check::check(&path) > 0, "{name} is traced and hit");
    }
}

#[test]
fn glb_corpus_loads_or_fails_cleanly() {
    replay_files("glb", "glb", |p| {
        drop(load::load_mesh(p, &MeshOptions::default()))
    });
}

#[test]
fn height_png_corpus_loads_or_fails_cleanly() {
    replay_files("height_png", "png", |p| {
        drop(load::load_height_map(p, &MapOptions::default()))
    });
}

#[test]
fn height_exr_corpus_loads_or_fails_cleanly() {
    replay_files("height_exr", "exr", |p| {
        drop(load::load_height_map(p, &MapOptions::default()))
    });
}

/// Found by the `env_exr` target on its first seed (a `height_exr` corpus file): an EXR
/// whose channel list reads as empty made the environment loader index the missing first
/// channel and panic (the height-map loader already refused it, naming no channel).
#[test]
fn an_environment_without_channels_is_an_error() {
    use prismbake::render::env::{EnvFrame, EnvMap};
    let bytes = include_bytes!("../../fuzz/corpus/env_exr/regression-no-channels.exr");
    let path = scratch("no-channels.exr", bytes);
    let frame = EnvFrame {
        z_up: false,
        rotation: 0.0,
    };
    let e = EnvMap::load_exr(&path, 1.0, frame).unwrap_err().to_string();
    assert!(
        e.contains("no-channels.exr") && e.contains("has no channels"),
        "{e}"
    );
}

/// Replay an environment corpus through `EnvMap::load` under `frame`: each file a clean error,
/// or an environment whose sampling stays finite (the `env_exr` / `env_hdr` targets'
/// invariants). Returns how many loaded.
fn replay_environments(target: &str, ext: &str, frame: prismbake::render::env::EnvFrame) -> usize {
    use glam::Vec2;
    use prismbake::render::env::{env_pdf, env_sample, EnvMap};
    let loaded = std::cell::Cell::new(0);
    replay_files(target, ext, |p| {
        let Ok(env) = EnvMap::load(p, 1.0, frame) else {
            return;
        };
        loaded.set(loaded.get() + 1);
        assert!(env.total_weight.is_finite(), "{}", p.display());
        for u in [Vec2::ZERO, Vec2::splat(0.5), Vec2::new(0.123, 0.877)] {
            let s = env_sample(&env, env.frame, u);
            assert!(s.dir.is_finite() && s.pdf.is_finite(), "{}", p.display());
            assert!(env_pdf(&env, env.frame, s.dir).is_finite());
        }
    });
    loaded.get()
}

/// The `--env` EXR loader over its corpus.
#[test]
fn env_exr_corpus_loads_or_fails_cleanly() {
    use prismbake::render::env::EnvFrame;
    let frame = EnvFrame {
        z_up: false,
        rotation: 0.7,
    };
    let loaded = replay_environments("env_exr", "exr", frame);
    assert!(loaded > 0, "the corpus keeps environments that load");
}

/// Radiance `.hdr` environments over the `env_hdr` corpus.
#[test]
fn env_hdr_corpus_loads_or_fails_cleanly() {
    use prismbake::render::env::EnvFrame;
    let frame = EnvFrame {
        z_up: true,
        rotation: 0.0,
    };
    let loaded = replay_environments("env_hdr", "hdr", frame);
    assert!(loaded >= 4, "the corpus keeps its four seeds");
}

#[test]
fn height_tiff_corpus_loads_or_fails_cleanly() {
    replay_files("height_tiff", "tif", |p| {
        drop(load::load_height_map(p, &MapOptions::default()))
    });
}

#[test]
fn usda_corpus_loads_or_fails_cleanly() {
    replay_files("usda", "usda", |p| {
        drop(load::load_mesh(p, &MeshOptions::default()))
    });
}

#[test]
fn usdc_corpus_loads_or_fails_cleanly() {
    replay_files("usdc", "usdc", |p| {
        drop(load::load_mesh(p, &MeshOptions::default()))
    });
}

fn load_texture(bytes: &[u8]) -> prismbake::Result<prismbake::texture::ColorMap> {
    use prismbake::texture::{ColorMap, ColorSpace, Sampler, TextureData, TextureRef, TextureSlot};
    ColorMap::load(
        Path::new("fuzz.glb"),
        &TextureRef {
            name: "fuzz".into(),
            data: TextureData::Embedded(bytes.to_vec()),
            sampler: Sampler::default(),
            tex_coord: 0,
            transform: Default::default(),
            color_space: ColorSpace::Auto,
            scale_bias: None,
        },
        TextureSlot::BaseColor,
    )
}

/// zune-jpeg 0.5.15 (the JPEG decoder of `image`) panics in its AVX2 IDCT
/// (`idct/avx2.rs:246`, an `Option::unwrap`) on a 16×8 baseline JPEG whose third component
/// samples 2×3 against the luma's 1×1 (found by the `texture` target in its first seconds):
/// the texture's error, printed as such, not a crash.
#[test]
fn a_jpeg_decoder_panic_is_the_textures_error() {
    let bytes = include_bytes!("../../fuzz/corpus/texture/regression-zune-jpeg-idct-panic.jpg");
    let e = load_texture(bytes).unwrap_err().to_string();
    assert!(e.contains("'fuzz'") && e.contains("crashed"), "{e}");
}

/// The JPEG decoder fills in missing image data: 517 and 651 corrupt bytes declared 18960 ×
/// 32561 and 15632 × 9736 texels and decoded to them (7–30 GB on the way; found by the
/// `texture` target as out-of-memory inputs). Refused from the header, before decoding: the
/// first by the texel cap, the second by what 651 bytes can hold.
#[test]
fn a_jpeg_header_declaring_more_texels_than_its_bytes_hold_is_refused() {
    for bytes in [
        &include_bytes!("../../fuzz/corpus/texture/regression-huge-jpeg-header.jpg")[..],
        &include_bytes!("../../fuzz/corpus/texture/regression-huge-jpeg-header-2.jpg")[..],
    ] {
        let e = load_texture(bytes).unwrap_err().to_string();
        assert!(e.contains("x") && e.contains("texels, more than"), "{e}");
    }
    let e = load_texture(include_bytes!(
        "../../fuzz/corpus/texture/regression-huge-jpeg-header-2.jpg"
    ))
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("15632x9736") && e.contains("more than its 651 bytes"),
        "{e}"
    );
}

#[test]
fn texture_corpus_decodes_or_fails_cleanly() {
    let mut decoded = 0;
    for (_, bytes) in corpus("texture") {
        if let Ok(m) = load_texture(&bytes) {
            assert_eq!(m.texels.len(), m.width as usize * m.height as usize);
            decoded += 1;
        }
    }
    assert!(
        decoded >= 10,
        "the corpus keeps its seeds ({decoded} decode)"
    );
}
