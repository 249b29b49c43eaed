//! UV seams end to end: a real OBJ cube (one UV island per face, smooth normals) with a 16-bit
//! PNG map that jumps across its seams and one that is seam-safe; `validate` flags the first
//! and passes the second, `render --seams` and `bench --seams` trace both surfaces.

use crate::util::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

const W: u32 = 96;
const H: u32 = 64;

/// Island `face` of the 3 × 2 atlas, as texel rectangle (x0, row0, x1, row1).
fn island(face: u32) -> (f32, f32, f32, f32) {
    let (cx, cy) = ((face % 3) as f32 * 32.0, (face / 3) as f32 * 32.0);
    (cx, cy, cx + 32.0, cy + 32.0)
}

/// The cube [-1, 1]³, 2 × 2 quads a face, normals along the position (no hard edge), each
/// face its own UV island 2 texels inside its atlas cell (OBJ: v up the image).
fn cube_obj() -> String {
    let mut s = String::from("o seamed_cube\n");
    let (mut v, mut vt) = (0, 0);
    let n = 2;
    let axes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut faces = String::new();
    for face in 0..6u32 {
        let a = (face / 2) as usize;
        let sign = if face % 2 == 0 { 1.0 } else { -1.0 };
        let (t1, t2) = (axes[(a + 1) % 3], axes[(a + 2) % 3]);
        let (x0, r0, x1, r1) = island(face);
        let base = v;
        for j in 0..=n {
            for i in 0..=n {
                let (u, w) = (i as f32 / n as f32, j as f32 / n as f32);
                let p: Vec<f32> = (0..3)
                    .map(|k| axes[a][k] * sign + t1[k] * (2.0 * u - 1.0) + t2[k] * (2.0 * w - 1.0))
                    .collect();
                let len = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                writeln!(s, "v {} {} {}", p[0], p[1], p[2]).unwrap();
                writeln!(s, "vn {} {} {}", p[0] / len, p[1] / len, p[2] / len).unwrap();
                let x = x0 + 2.0 + u * (x1 - x0 - 4.0);
                let row = r0 + 2.0 + w * (r1 - r0 - 4.0);
                writeln!(s, "vt {} {}", x / W as f32, 1.0 - row / H as f32).unwrap();
                v += 1;
                vt += 1;
            }
        }
        let _ = vt;
        let at = |i: u32, j: u32| base + j * (n + 1) + i + 1;
        // Wound outwards: (t1, t2) is right-handed about +axis; flip on the negative faces.
        for j in 0..n {
            for i in 0..n {
                let quad = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                for tri in [[quad[0], quad[1], quad[2]], [quad[0], quad[2], quad[3]]] {
                    let tri = if sign > 0.0 {
                        tri
                    } else {
                        [tri[0], tri[2], tri[1]]
                    };
                    writeln!(
                        faces,
                        "f {0}/{0}/{0} {1}/{1}/{1} {2}/{2}/{2}",
                        tri[0], tri[1], tri[2]
                    )
                    .unwrap();
                }
            }
        }
    }
    s + &faces
}

/// A 16-bit grey PNG: a non-periodic relief (the islands disagree at every seam), or faded to
/// mid-grey within 6 texels of each island's border (seam-safe).
fn write_map(path: &Path, seam_safe: bool) {
    let img = image::ImageBuffer::from_fn(W, H, |x, row| {
        let (x, row) = (x as f32 + 0.5, row as f32 + 0.5);
        let mut h = 0.35 * (0.37 * x + 0.11 * row).sin() * (0.23 * row - 0.05 * x).cos();
        if seam_safe {
            let (x0, r0, x1, r1) = island((x / 32.0) as u32 + 3 * (row / 32.0) as u32);
            let d = (x - x0).min(x1 - x).min(row - r0).min(r1 - row);
            h *= ((d - 6.0) / 4.0).clamp(0.0, 1.0);
        }
        image::Luma([((0.5 + h) * 65535.0).round() as u16])
    });
    img.save(path).unwrap();
}

pub(crate) fn cube_assets() -> (PathBuf, PathBuf, PathBuf) {
    let dir = temp_dir("seams");
    for (name, safe) in [("jump", false), ("safe", true)] {
        std::fs::write(dir.join(format!("{name}.obj")), cube_obj()).unwrap();
        write_map(&dir.join(format!("{name}.png")), safe);
        std::fs::write(
            dir.join(format!("{name}.prismbake.toml")),
            format!("disp = \"{name}.png\"\nscale = 0.1\nwrap = \"clamp\"\n"),
        )
        .unwrap();
    }
    (dir.join("jump.obj"), dir.join("safe.obj"), dir)
}

fn check<'a>(report: &'a serde_json::Value, name: &str) -> &'a serde_json::Value {
    report["assets"][0]["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == name)
        .unwrap_or_else(|| panic!("no {name} check in {report}"))
}

#[test]
fn validate_flags_a_map_that_jumps_across_seams_and_passes_a_seam_safe_one() {
    let (jump, safe, _) = cube_assets();
    let r = run(&["validate", s(&jump), "--format", "json"]);
    r.assert_code(1);
    let j = r.json();
    let c = check(&j, "seam-jump");
    assert_eq!(c["status"], "fail", "{c}");
    let msg = c["message"].as_str().unwrap();
    assert!(
        msg.contains("24 seam edges"),
        "12 cube edges × 2 segments: {msg}"
    );
    assert!(msg.contains("face "), "names the worst faces: {msg}");
    assert!(!c["faces"].as_array().unwrap().is_empty(), "{c}");

    let r = run(&["validate", s(&safe), "--format", "json"]);
    r.assert_success();
    assert_eq!(check(&r.json(), "seam-jump")["status"], "pass");

    // The limit is a knob: a huge one passes the jump map, a bad value is a usage error.
    let loose = run(&[
        "validate",
        s(&jump),
        "--max-seam-jump",
        "10",
        "--format",
        "json",
    ]);
    assert_eq!(check(&loose.json(), "seam-jump")["status"], "pass");
    run(&["validate", s(&jump), "--max-seam-jump", "-1"]).assert_error(&["--max-seam-jump"]);

    // inspect shows the totals.
    let i = run(&["inspect", s(&jump)]);
    i.assert_success();
    assert!(i.stdout.contains("24 UV seam edges"), "{}", i.stdout);
}

#[test]
fn bench_counts_rays_through_open_seams_and_none_through_stitched_ones() {
    let (jump, _, dir) = cube_assets();
    let out = dir.join("bench");
    let r = run(&[
        "bench",
        s(&jump),
        "--methods",
        "pdm",
        "--dt",
        "auto",
        "--res",
        "16x16",
        "--leak-rays",
        "20000",
        "--repeats",
        "1",
        "--seams",
        "stitch,open",
        "-o",
        s(&out),
    ]);
    r.assert_success();
    let rows: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("bench.json")).unwrap()).unwrap();
    let through = |method: &str, seams: &str| {
        rows.as_array()
            .unwrap()
            .iter()
            .find(|r| r["method"] == method && r["seams"] == seams)
            .unwrap_or_else(|| panic!("no {method}/{seams} row"))["through"]
            .as_u64()
            .unwrap()
    };
    assert_eq!(through("pdm", "stitch"), 0);
    assert_eq!(through("reference", "stitch"), 0);
    assert!(through("pdm", "open") > 0, "open seams let rays through");
    assert!(through("reference", "open") > 0);
}

#[test]
fn render_traces_the_stitched_or_the_open_surface() {
    let (jump, _, dir) = cube_assets();
    let render = |seams: &str| {
        let out = dir.join(format!("render-{seams}"));
        run(&[
            "render",
            s(&jump),
            "--res",
            "48x48",
            "--aov",
            "mask,depth",
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
        std::fs::read(out.join("depth.exr")).unwrap()
    };
    assert_ne!(render("stitch"), render("open"), "the seam bands differ");
    run(&[
        "render",
        s(&jump),
        "--seams",
        "closed",
        "-o",
        s(&dir.join("x")),
    ])
    .assert_error(&["--seams"]);
}
