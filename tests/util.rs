//! Test helpers: run the built binary in a temp dir and show everything on failure.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};

pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

pub fn example(rel: &str) -> PathBuf {
    repo_root().join("examples").join(rel)
}

/// A fresh, empty folder for one test.
pub fn temp_dir(name: &str) -> PathBuf {
    static N: AtomicU32 = AtomicU32::new(0);
    let dir = std::env::temp_dir().join(format!(
        "prismbake-it-{}-{}-{name}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

pub struct Output {
    pub code: i32,
    pub stdout: String,
    pub stderr: String,
    pub cmdline: String,
}

impl Output {
    fn describe(&self) -> String {
        format!(
            "command: {}\nexit: {}\n--- stdout\n{}\n--- stderr\n{}",
            self.cmdline, self.code, self.stdout, self.stderr
        )
    }
    pub fn assert_code(&self, code: i32) -> &Self {
        assert_eq!(self.code, code, "unexpected exit code\n{}", self.describe());
        self
    }
    pub fn assert_success(&self) -> &Self {
        self.assert_code(0)
    }
    /// An error: non-zero exit, one clear line on stderr containing every needle, no panic.
    pub fn assert_error(&self, needles: &[&str]) -> &Self {
        assert_ne!(self.code, 0, "expected failure\n{}", self.describe());
        assert!(
            !self.stderr.contains("panicked"),
            "panicked\n{}",
            self.describe()
        );
        for n in needles {
            assert!(
                self.stderr.contains(n),
                "stderr lacks {n:?}\n{}",
                self.describe()
            );
        }
        self
    }
    pub fn json(&self) -> serde_json::Value {
        serde_json::from_str(&self.stdout)
            .unwrap_or_else(|e| panic!("stdout is not JSON: {e}\n{}", self.describe()))
    }
}

/// A `render --json` summary's frame times hold together: each frame's trace time and file
/// time are > 0 and add up to its own time, the device's own clock (GPU timestamps) is
/// reported, inside the trace time, exactly when `device_clock` (`null` on the CPU), and the
/// job's wall time for its frames is at least all their traces, one after the other, and at
/// least all their files (a frame's files are written while the next one traces).
pub fn assert_frame_times(summary: &serde_json::Value, device_clock: bool) {
    let frames = summary["frames"].as_array().expect("frames");
    assert!(!frames.is_empty());
    let wall = summary["frames_seconds"]
        .as_f64()
        .unwrap_or_else(|| panic!("no frames_seconds: {summary}"));
    let total = |k: &str| frames.iter().map(|f| f[k].as_f64().unwrap()).sum::<f64>();
    assert!(wall >= total("trace_seconds"), "{summary}");
    assert!(wall >= total("write_seconds"), "{summary}");
    for f in frames {
        let get = |k: &str| {
            f[k].as_f64()
                .unwrap_or_else(|| panic!("frame lacks {k}: {f}"))
        };
        let (all, trace, write) = (get("seconds"), get("trace_seconds"), get("write_seconds"));
        assert!(trace > 0.0 && write > 0.0, "{f}");
        assert!((trace + write - all).abs() <= 1e-9 * all.max(1.0), "{f}");
        match f["device_seconds"].as_f64() {
            Some(d) => assert!(device_clock && d > 0.0 && d <= trace, "{f}"),
            None => assert!(!device_clock && f["device_seconds"].is_null(), "{f}"),
        }
    }
}

/// Run `prismbake ARGS` with `cwd` as working directory.
pub fn run_in(cwd: &Path, args: &[&str]) -> Output {
    run_in_env(cwd, args, &[])
}

/// `run_in` with environment variables `envs` set for the process.
pub fn run_in_env(cwd: &Path, args: &[&str], envs: &[(&str, &str)]) -> Output {
    let bin = env!("CARGO_BIN_EXE_prismbake");
    // Tables cached by `render` go to a folder of the test run, not the user's cache.
    let cache = std::env::temp_dir().join(format!("prismbake-it-cache-{}", std::process::id()));
    let out = Command::new(bin)
        .args(args)
        .current_dir(cwd)
        .env("XDG_CACHE_HOME", cache)
        .envs(envs.iter().copied())
        .output()
        .expect("binary runs");
    Output {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        cmdline: format!("prismbake {}", args.join(" ")),
    }
}

pub fn run(args: &[&str]) -> Output {
    run_in(&repo_root(), args)
}

pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Files in a folder (to check that nothing half-written was left).
pub fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map(|r| {
            r.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// A constant-radiance equirect EXR.
pub fn write_constant_env(path: &Path, radiance: f32) {
    let ch = |name| (name, vec![radiance; 16 * 8]);
    write_exr(path, 16, 8, vec![ch("R"), ch("G"), ch("B")], false);
}

/// `DIR/flat.exr`: a 4 × 4 height map at the midlevel everywhere (no displacement).
pub fn write_flat_map(dir: &Path) -> PathBuf {
    let map = dir.join("flat.exr");
    write_exr(&map, 4, 4, vec![("Y", vec![0.5; 16])], false);
    map
}

/// A Y-up USD text layer: a flat 2 × 2 quad (corners ±1 in x and y, UVs over the unit
/// square) and then `prims`.
pub fn quad_usda(prims: &str) -> String {
    format!(
        "#usda 1.0\n(\n    upAxis = \"Y\"\n)\n\
         def Mesh \"quad\"\n{{\n    int[] faceVertexCounts = [4]\n    \
         int[] faceVertexIndices = [0, 1, 2, 3]\n    \
         point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]\n    \
         texCoord2f[] primvars:st = [(0, 0), (1, 0), (1, 1), (0, 1)] (\n        \
         interpolation = \"vertex\"\n    )\n}}\n{prims}"
    )
}

/// Write a one-layer f32 EXR of `width` × `height` pixels: each channel by name, its pixels in
/// row order; `compressed` takes RLE (runs of equal values stay small on disk).
pub fn write_exr(
    path: &Path,
    width: usize,
    height: usize,
    channels: Vec<(&str, Vec<f32>)>,
    compressed: bool,
) {
    use exr::prelude::*;
    let channels = channels
        .into_iter()
        .map(|(name, plane)| AnyChannel::new(name, FlatSamples::F32(plane)))
        .collect::<Vec<_>>();
    let layer = Layer::new(
        (width, height),
        LayerAttributes::default(),
        match compressed {
            true => Encoding::FAST_LOSSLESS,
            false => Encoding::UNCOMPRESSED,
        },
        AnyChannels::sort(channels.into()),
    );
    Image::from_layer(layer).write().to_file(path).unwrap();
}

/// RGBA pixels of a beauty EXR.
pub fn read_rgba(path: &Path) -> Vec<[f32; 4]> {
    let [r, g, b, a] = read_channels(path, ["R", "G", "B", "A"]);
    (0..r.len()).map(|i| [r[i], g[i], b[i], a[i]]).collect()
}

/// The named channels of an EXR's first layer, each as its pixels in row order.
pub fn read_channels<const N: usize>(path: &Path, names: [&str; N]) -> [Vec<f32>; N] {
    let img = exr::prelude::read_all_flat_layers_from_file(path).unwrap();
    let layer = &img.layer_data[0];
    let n = layer.size.0 * layer.size.1;
    names.map(|name| {
        let channel = (layer.channel_data.list.iter())
            .find(|c| c.name.to_string() == name)
            .unwrap_or_else(|| panic!("{}: no channel {name}", path.display()));
        (0..n)
            .map(|i| channel.sample_data.value_by_flat_index(i).to_f32())
            .collect()
    })
}

/// A copy of the rock example in `dir` (with its sidecar and map) whose embedded base-colour
/// PNG has its image data overwritten: the GLB stays valid, the texture does not decode.
pub fn rock_with_a_corrupt_texture(dir: &Path) -> PathBuf {
    let mut glb = std::fs::read(example("rock/rock.glb")).unwrap();
    // After the PNG's signature and header chunk.
    let at = glb
        .windows(8)
        .position(|w| w == b"\x89PNG\r\n\x1a\n")
        .expect("rock.glb embeds a PNG");
    glb[at + 40..at + 400].fill(0x5a);
    let rock = dir.join("rock.glb");
    std::fs::write(&rock, glb).unwrap();
    let toml = std::fs::read_to_string(example("rock/rock.prismbake.toml")).unwrap();
    std::fs::write(
        dir.join("rock.prismbake.toml"),
        toml.replace("../maps/", "maps/"),
    )
    .unwrap();
    std::fs::create_dir_all(dir.join("maps")).unwrap();
    std::fs::copy(
        example("maps/scales_256.png"),
        dir.join("maps/scales_256.png"),
    )
    .unwrap();
    rock
}
