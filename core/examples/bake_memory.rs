//! Peak memory of load → repair → bake for the 4096² benchmark asset (docs/benchmarks.md).
//!
//! `cargo run --release -p prismbake-core --example bake_memory [png16|png8|exr]` writes the
//! procedural UV sphere (OBJ), its 4096² relief (in the chosen format) and a sidecar to a
//! temp folder, then runs a fresh copy of itself that only loads, repairs and bakes, and
//! prints that process's VmHWM (peak resident set): writing the files must not count.

#[path = "../benches/common/mod.rs"]
mod common;

use prismbake::asset::{self, Overrides};
use prismbake::repair::RepairOptions;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.get(1).map(String::as_str) == Some("measure") {
        measure(Path::new(&args[2]));
        return;
    }
    let format = args.get(1).cloned().unwrap_or_else(|| "png16".into());
    let dir = std::env::temp_dir().join(format!("prismbake-bake-memory-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let obj = write_asset(&dir, &format);
    let status = std::process::Command::new(std::env::current_exe().unwrap())
        .arg("measure")
        .arg(&obj)
        .status()
        .unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    std::process::exit(status.code().unwrap_or(1));
}

fn write_asset(dir: &Path, format: &str) -> PathBuf {
    let mesh = common::uv_sphere(64, 64);
    let map = common::relief_map(4096);
    let mut obj = String::new();
    for (p, (n, t)) in mesh
        .positions
        .iter()
        .zip(mesh.normals.iter().zip(&mesh.uvs))
    {
        writeln!(
            obj,
            "v {} {} {}\nvn {} {} {}\nvt {} {}",
            p.x, p.y, p.z, n.x, n.y, n.z, t.x, t.y
        )
        .unwrap();
    }
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| i + 1);
        writeln!(obj, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}").unwrap();
    }
    let obj_path = dir.join("sphere.obj");
    std::fs::write(&obj_path, obj).unwrap();
    let (w, h) = (map.width, map.height);
    let map_name = match format {
        "png16" => {
            let px: Vec<u16> = map
                .data
                .iter()
                .map(|&v| (v * 65535.0).round() as u16)
                .collect();
            image::ImageBuffer::<image::Luma<u16>, _>::from_raw(w, h, px)
                .unwrap()
                .save(dir.join("relief.png"))
                .unwrap();
            "relief.png"
        }
        "png8" => {
            let px: Vec<u8> = map
                .data
                .iter()
                .map(|&v| (v * 255.0).round() as u8)
                .collect();
            image::ImageBuffer::<image::Luma<u8>, _>::from_raw(w, h, px)
                .unwrap()
                .save(dir.join("relief.png"))
                .unwrap();
            "relief.png"
        }
        "exr" => {
            prismbake::render::output::write_exr(&dir.join("relief.exr"), w, h, &["Y"], &map.data)
                .unwrap();
            "relief.exr"
        }
        other => panic!("unknown map format '{other}' (png16, png8 or exr)"),
    };
    std::fs::write(
        dir.join("sphere.prismbake.toml"),
        format!("disp = \"{map_name}\"\nscale = 0.05\n"),
    )
    .unwrap();
    obj_path
}

fn measure(obj: &Path) {
    let before = vm_hwm_kib();
    let start = Instant::now();
    let spec = asset::resolve(obj, &Overrides::default()).unwrap();
    let prepared = asset::prepare(&spec, &RepairOptions::default()).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    let peak = vm_hwm_kib();
    let map_mib = (prepared.map.data.len() * 4) as f64 / (1 << 20) as f64;
    let mib = |k: u64| k as f64 / 1024.0;
    println!(
        "map {}x{} ({}), {} triangles, {} prisms: load+repair+bake {:.3} s\n\
         VmHWM before {:.1} MiB, after {:.1} MiB (delta {:.1} MiB); map as f32 {:.1} MiB; \
         peak / map = {:.2} (delta / map = {:.2})",
        prepared.map.width,
        prepared.map.height,
        spec.disp
            .as_ref()
            .unwrap()
            .extension()
            .unwrap()
            .to_string_lossy(),
        prepared.mesh.triangle_count(),
        prepared.table.prisms.len(),
        seconds,
        mib(before),
        mib(peak),
        mib(peak - before),
        map_mib,
        mib(peak) / map_mib,
        mib(peak - before) / map_mib,
    );
}

/// Peak resident set size of this process so far (Linux `/proc/self/status`), in KiB.
fn vm_hwm_kib() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = status.lines().find(|l| l.starts_with("VmHWM:")).unwrap();
    line.split_whitespace().nth(1).unwrap().parse().unwrap()
}
