//! `render` end to end: files, determinism across threads, turntables and frame ranges, bad input.

use crate::util::*;
use std::path::Path;

fn read(path: &std::path::Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn writes_every_aov_as_exr_and_png() {
    let dir = temp_dir("render-aovs");
    run(&[
        "render",
        s(&example("torus/torus.obj")),
        "--res",
        "48x32",
        "--aov",
        "depth,normal,mask,uv,steps,prism",
        "-o",
        s(&dir),
    ])
    .assert_success();
    let mut want: Vec<String> = ["depth", "mask", "normal", "prism", "steps", "uv"]
        .iter()
        .flat_map(|a| [format!("{a}.exr"), format!("{a}.png")])
        .collect();
    want.sort();
    assert_eq!(files_in(&dir), want);
    // The mask is not empty and not full: the torus is framed inside the image.
    let img = image::open(dir.join("mask.png")).unwrap().to_luma8();
    assert_eq!(img.dimensions(), (48, 32));
    let covered = img.pixels().filter(|p| p.0[0] > 127).count();
    assert!(
        covered > 48 * 32 / 10 && covered < 48 * 32 * 9 / 10,
        "coverage {covered}"
    );
}

#[test]
fn same_image_for_one_and_many_threads() {
    let (a, b) = (temp_dir("threads1"), temp_dir("threads2"));
    let sphere = example("sphere/sphere.glb");
    for (dir, threads) in [(&a, "1"), (&b, "2")] {
        run(&[
            "render",
            s(&sphere),
            "--res",
            "40x40",
            "--spp",
            "2",
            "--aov",
            "depth,normal,steps",
            "--threads",
            threads,
            "-o",
            s(dir),
        ])
        .assert_success();
    }
    for f in ["depth.exr", "normal.exr", "steps.exr"] {
        assert!(
            read(&a.join(f)) == read(&b.join(f)),
            "{f} differs between 1 and 2 threads"
        );
    }
}

#[test]
fn turntable_frame_ranges_match_the_full_run() {
    let (full, part) = (temp_dir("tt-full"), temp_dir("tt-part"));
    let rock = example("rock/rock.glb");
    run(&[
        "render",
        s(&rock),
        "--res",
        "24x24",
        "--turntable",
        "4",
        "--aov",
        "depth",
        "-o",
        s(&full),
    ])
    .assert_success();
    assert_eq!(
        files_in(&full)
            .iter()
            .filter(|f| f.ends_with(".exr"))
            .count(),
        4
    );
    run(&[
        "render",
        s(&rock),
        "--res",
        "24x24",
        "--turntable",
        "4",
        "--frames",
        "2-3",
        "--aov",
        "depth",
        "-o",
        s(&part),
    ])
    .assert_success();
    assert_eq!(
        files_in(&part),
        vec![
            "depth_0002.exr",
            "depth_0002.png",
            "depth_0003.exr",
            "depth_0003.png",
            "depth_contact_sheet.png"
        ]
    );
    for f in ["depth_0002.exr", "depth_0003.exr"] {
        assert!(
            read(&full.join(f)) == read(&part.join(f)),
            "{f} differs from the full run"
        );
    }
    // Different frames see the asset from different sides.
    assert!(read(&full.join("depth_0000.exr")) != read(&full.join("depth_0001.exr")));
}

#[test]
fn renders_a_baked_table() {
    let dir = temp_dir("render-table");
    let table = dir.join("t.prisms");
    run(&["bake", s(&example("sphere/sphere.glb")), "-o", s(&table)]).assert_success();
    let out = dir.join("img");
    let summary = run(&[
        "render",
        s(&table),
        "--res",
        "32x32",
        "--aov",
        "mask",
        "-o",
        s(&out),
        "--json",
    ]);
    summary.assert_success();
    assert!(out.join("mask.exr").is_file());
    assert_frame_times(&summary.json(), false);
}

/// A USD camera's film back twice as wide as tall (apertures 40 × 20 tenths, focal length 50)
/// keeps its whole width in a square image, as USD's `expandAperture` and Blender's importer
/// (which fits it horizontally) have it: 5 units from the 2 × 2 quad, the view is 4 units
/// across both ways and the quad covers a quarter of the image (from the vertical aperture
/// alone it would fill it). An image twice as wide as tall sees the film back exactly, 4 × 2
/// units: the quad fills its height and half its width.
#[test]
fn a_usd_cameras_film_back_stays_whole_in_a_narrower_image() {
    let dir = temp_dir("render-film-back");
    let usda = dir.join("quad.usda");
    let camera = "def Camera \"Wide\"\n{\n    float focalLength = 50\n    \
                  float horizontalAperture = 40\n    float verticalAperture = 20\n    \
                  double3 xformOp:translate = (0, 0, 5)\n    \
                  uniform token[] xformOpOrder = [\"xformOp:translate\"]\n}\n";
    std::fs::write(&usda, quad_usda(camera)).unwrap();
    let map = write_flat_map(&dir);
    let coverage = |res: &str| {
        let out = dir.join(res);
        let mut args = vec!["render", s(&usda), "--disp", s(&map), "--scale", "0"];
        args.extend(["--res", res, "--aov", "mask", "--no-jitter", "-o", s(&out)]);
        run(&args).assert_success();
        let [mask] = read_channels(&out.join("mask.exr"), ["Y"]);
        mask.iter().sum::<f32>() / mask.len() as f32
    };
    let square = coverage("16x16");
    assert!((square - 0.25).abs() < 1e-6, "square: {square}");
    let wide = coverage("32x16");
    assert!((wide - 0.5).abs() < 1e-6, "wide: {wide}");
}

/// A table keeps the geometry; a render of it reads the rest from the mesh it was baked from
/// (found from the table's folder): the rock's table, baked into another folder, renders the
/// same beauty as the rock, its textured material included. Where the mesh has gone, or
/// changed, a warning says so and the default material shades it.
#[test]
fn a_baked_table_renders_with_its_meshs_materials() {
    let dir = temp_dir("render-table-materials");
    let rock = dir.join("rock.glb");
    std::fs::copy(example("rock/rock.glb"), &rock).unwrap();
    let map = example("maps/scales_256.png");
    let table = dir.join("tables/rock.prisms");
    run(&["bake", s(&rock), "--disp", s(&map), "-o", s(&table)]).assert_success();
    let info = run(&["inspect", s(&table), "--json"])
        .assert_success()
        .json();
    assert_eq!(info["mesh"], "../rock.glb", "{info}");
    assert!(
        info["mesh_scene"].as_str().unwrap().starts_with("read"),
        "{info}"
    );
    let beauty = |input: &Path, name: &str| {
        let out = dir.join(name);
        let mut args = vec!["render", s(input), "--res", "24x24", "--spp", "2"];
        args.extend(["--aov", "beauty", "--json", "-o", s(&out)]);
        if input == rock.as_path() {
            args.extend(["--disp", s(&map)]);
        }
        let o = run(&args);
        o.assert_success();
        (read_rgba(&out.join("beauty.exr")), o)
    };
    let (from_mesh, _) = beauty(&rock, "mesh");
    let (from_table, o) = beauty(&table, "table");
    assert_eq!(
        from_table, from_mesh,
        "the table's beauty differs from the mesh's"
    );
    assert_eq!(o.json()["materials"][0]["name"], "rock_mat", "{}", o.stdout);

    std::fs::write(&rock, b"glTF moved on").unwrap();
    let (changed, o) = beauty(&table, "changed");
    assert!(
        o.stderr
            .contains("rock.glb has changed since the table was baked"),
        "{}",
        o.stderr
    );
    assert_eq!(o.json()["materials"][0]["name"], "default", "{}", o.stdout);
    assert_ne!(
        changed, from_mesh,
        "the default material shades like the rock's"
    );
    std::fs::remove_file(&rock).unwrap();
    let (_, o) = beauty(&table, "gone");
    assert!(o.stderr.contains("rock.glb is not there"), "{}", o.stderr);
    let info = run(&["inspect", s(&table), "--json"])
        .assert_success()
        .json();
    assert!(
        info["mesh_scene"].as_str().unwrap().contains("not there"),
        "{info}"
    );
}

/// A Z-up USD asset's table stands Z up whether or not its mesh is still there: framed from
/// the bounds, its depth image is the mesh's (a Y-up copy of the same quad frames it another
/// way, so the comparison can fail).
#[test]
fn a_baked_table_keeps_its_up_axis() {
    let dir = temp_dir("render-table-up");
    let map = write_flat_map(&dir);
    let depth = |input: &Path, name: &str| {
        let out = dir.join(name);
        let mut args = vec!["render", s(input), "--disp", s(&map), "--scale", "0.1"];
        args.extend(["--res", "12x12", "--aov", "depth", "-o", s(&out)]);
        let o = run(&args);
        o.assert_success();
        let [d] = read_channels(&out.join("depth.exr"), ["Y"]);
        (d, o)
    };
    let y_up = dir.join("y.usda");
    std::fs::write(&y_up, quad_usda("")).unwrap();
    let z_up = dir.join("z.usda");
    std::fs::write(
        &z_up,
        quad_usda("").replace("upAxis = \"Y\"", "upAxis = \"Z\""),
    )
    .unwrap();
    let (want, _) = depth(&z_up, "mesh");
    assert_ne!(
        depth(&y_up, "y").0,
        want,
        "Y up and Z up frame the quad alike"
    );
    let table = dir.join("z.prisms");
    run(&[
        "bake",
        s(&z_up),
        "--disp",
        s(&map),
        "--scale",
        "0.1",
        "-o",
        s(&table),
    ])
    .assert_success();
    assert_eq!(
        run(&["inspect", s(&table), "--json"])
            .assert_success()
            .json()["up_axis"],
        "Z"
    );
    assert_eq!(depth(&table, "table").0, want);
    std::fs::remove_file(&z_up).unwrap();
    let (got, o) = depth(&table, "table-alone");
    assert!(o.stderr.contains("z.usda is not there"), "{}", o.stderr);
    assert_eq!(got, want, "without its mesh the table lost its up axis");
}

/// An OBJ box `w` wide (x), `h` tall (y) and `d` deep (z), centred on the origin, each face
/// with UVs over the unit square.
fn box_obj(path: &Path, [w, h, d]: [f32; 3]) {
    let (x, y, z) = (w / 2.0, h / 2.0, d / 2.0);
    let mut obj = String::from("vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n");
    for [sx, sy, sz] in [
        [-1., -1., -1.],
        [1., -1., -1.],
        [1., 1., -1.],
        [-1., 1., -1.],
    ]
    .into_iter()
    .chain([[-1., -1., 1.], [1., -1., 1.], [1., 1., 1.], [-1., 1., 1.]])
    {
        obj += &format!("v {} {} {}\n", sx * x, sy * y, sz * z);
    }
    for f in [
        [1, 4, 3, 2],
        [5, 6, 7, 8],
        [1, 2, 6, 5],
        [4, 8, 7, 3],
        [1, 5, 8, 4],
        [2, 3, 7, 6],
    ] {
        obj += &format!("f {}/1 {}/2 {}/3 {}/4\n", f[0], f[1], f[2], f[3]);
    }
    std::fs::write(path, obj).unwrap();
}

/// A turntable framed from the bounds holds the asset on every frame, not only the first: a
/// box long from front to back (seen end on in frame 0) covers no pixel on the image's edge
/// on any frame of the turn, and fills most of the width side on. The same holds for
/// `--ortho fit`.
#[test]
fn a_turntable_framed_from_the_bounds_keeps_the_asset_in_view() {
    let dir = temp_dir("render-turntable-framing");
    let obj = dir.join("plank.obj");
    box_obj(&obj, [0.4, 0.6, 4.0]);
    let map = write_flat_map(&dir);
    let n = 24;
    for (name, extra) in [("persp", None), ("ortho", Some("fit"))] {
        let out = dir.join(name);
        let mut args = vec!["render", s(&obj), "--disp", s(&map), "--scale", "0.02"];
        args.extend([
            "--res",
            "24x24",
            "--aov",
            "mask",
            "--turntable",
            "8",
            "-o",
            s(&out),
        ]);
        if let Some(fit) = extra {
            args.extend(["--ortho", fit]);
        }
        run(&args).assert_success();
        let mut widest = 0;
        for f in 0..8 {
            let [mask] = read_channels(&out.join(format!("mask_{f:04}.exr")), ["Y"]);
            let edge = (0..n * n)
                .filter(|&i| i % n == 0 || i % n == n - 1 || i / n == 0 || i / n == n - 1)
                .filter(|&i| mask[i] > 0.0)
                .count();
            assert_eq!(
                edge, 0,
                "{name}: frame {f} covers {edge} pixels on the image's edge"
            );
            let columns = (0..n)
                .filter(|&x| (0..n).any(|y| mask[y * n + x] > 0.0))
                .count();
            widest = widest.max(columns);
        }
        assert!(
            widest >= n / 2,
            "{name}: side on, the plank spans only {widest} of {n} columns"
        );
    }
}

#[test]
fn bad_render_input() {
    let dir = temp_dir("render-bad");
    let sphere = example("sphere/sphere.glb");
    let out = dir.join("out");
    run(&["render", s(&sphere), "--res", "0x0", "-o", s(&out)]).assert_error(&["--res 0x0"]);
    run(&["render", s(&sphere), "--res", "big", "-o", s(&out)]).assert_code(2);
    run(&["render", s(&sphere), "--spp", "0", "-o", s(&out)]).assert_error(&["--spp"]);
    run(&["render", s(&sphere), "--spp", "100000000", "-o", s(&out)]).assert_error(&["--spp"]);
    run(&["render", s(&sphere), "--aov", "shiny", "-o", s(&out)]).assert_error(&["shiny"]);
    run(&[
        "render",
        s(&sphere),
        "--aov",
        "beauty",
        "--bounces",
        "9",
        "-o",
        s(&out),
    ])
    .assert_error(&["--bounces"]);
    run(&[
        "render",
        s(&sphere),
        "--aov",
        "beauty",
        "--roughness",
        "2",
        "-o",
        s(&out),
    ])
    .assert_error(&["--roughness"]);
    for (flag, value) in [("--clearcoat", "1.5"), ("--clearcoat-roughness", "nan")] {
        run(&[
            "render",
            s(&sphere),
            "--aov",
            "beauty",
            flag,
            value,
            "-o",
            s(&out),
        ])
        .assert_error(&[flag, "[0, 1]"]);
    }
    run(&["render", s(&sphere), "--method", "magic", "-o", s(&out)]).assert_error(&["magic"]);
    run(&[
        "render",
        s(&sphere),
        "--camera-from",
        "nan,0,0",
        "-o",
        s(&out),
    ])
    .assert_error(&["finite"]);
    run(&["render", s(&sphere), "--frames", "0-3", "-o", s(&out)]).assert_error(&["--turntable"]);
    run(&[
        "render",
        s(&sphere),
        "--turntable",
        "4",
        "--frames",
        "2-9",
        "-o",
        s(&out),
    ])
    .assert_error(&["--frames"]);
    run(&["render", s(&sphere), "--dt", "-1", "-o", s(&out)]).assert_error(&["--dt"]);
    assert!(!out.exists(), "nothing is created for a rejected job");
    // An output folder that cannot be created (a file is in the way).
    let file = dir.join("file");
    std::fs::write(&file, "x").unwrap();
    run(&[
        "render",
        s(&sphere),
        "--res",
        "8x8",
        "-o",
        s(&file.join("sub")),
    ])
    .assert_error(&["file"]);
}

/// `--camera NAME` renders through that camera of the scene file: a flat quad seen head-on
/// from USD cameras 3 and 7 units away has those depths at the image centre, whichever is
/// picked by path or by name, the first being the default; the summary names the camera and
/// the flags that override it; a table baked from the file renders through them too. A name
/// the file lacks, or `--camera` on a prism table whose mesh is gone (a table keeps no
/// cameras), fails naming the choices, and writes nothing.
#[test]
fn camera_picks_one_of_the_scene_files_cameras_by_name() {
    let dir = temp_dir("render-camera");
    let usda = dir.join("quad.usda");
    let camera = |name: &str, z: f32| {
        format!(
            "def Camera \"{name}\"\n{{\n    double3 xformOp:translate = (0, 0, {z})\n    \
             uniform token[] xformOpOrder = [\"xformOp:translate\"]\n}}\n"
        )
    };
    std::fs::write(
        &usda,
        quad_usda(&(camera("Near", 3.0) + &camera("Far", 7.0))),
    )
    .unwrap();
    let map = write_flat_map(&dir);
    let centre_depth = |pick: Option<&str>| {
        let out = dir.join(format!(
            "out-{}",
            pick.unwrap_or("default").replace('/', "_")
        ));
        let mut args = vec![
            "render",
            s(&usda),
            "--disp",
            s(&map),
            "--scale",
            "0.1",
            "--midlevel",
            "0.5",
            "--res",
            "9x9",
            "--aov",
            "depth",
            "-o",
            s(&out),
        ];
        if let Some(name) = pick {
            args.extend(["--camera", name]);
        }
        args.push("--json");
        let summary = run(&args).assert_success().json();
        let [depth] = read_channels(&out.join("depth.exr"), ["Y"]);
        (
            depth[4 * 9 + 4],
            summary["camera"].as_str().unwrap().to_string(),
        )
    };
    for (pick, want, said) in [
        (None, 3.0, "the file's camera '/Near'"),
        (Some("Near"), 3.0, "the file's camera '/Near'"),
        (Some("/Far"), 7.0, "the file's camera '/Far'"),
        (Some("Far"), 7.0, "the file's camera '/Far'"),
    ] {
        let (got, camera) = centre_depth(pick);
        assert_eq!(camera, said, "--camera {pick:?}");
        assert!(
            (got - want).abs() < 1e-3,
            "--camera {pick:?}: depth {got}, want {want}"
        );
    }

    let summary = run(&[
        "render",
        s(&usda),
        "--disp",
        s(&map),
        "--res",
        "4x4",
        "--aov",
        "mask",
        "--fov",
        "30",
        "--json",
        "-o",
        s(&dir.join("fov")),
    ])
    .assert_success()
    .json();
    assert_eq!(summary["camera"], "the file's camera '/Near', with --fov");
    let out = dir.join("rejected");
    run(&[
        "render",
        s(&usda),
        "--disp",
        s(&map),
        "--camera",
        "Side",
        "-o",
        s(&out),
    ])
    .assert_error(&["quad.usda", "no camera named 'Side'", "'/Near', '/Far'"]);
    // A table renders through its mesh's cameras, while the mesh is there.
    let table = dir.join("quad.prisms");
    run(&["bake", s(&usda), "--disp", s(&map), "-o", s(&table)]).assert_success();
    let through_table = dir.join("table-far");
    let args = ["--res", "9x9", "--aov", "depth", "--camera", "Far", "-o"];
    run(&[&["render", s(&table)], &args[..], &[s(&through_table)]].concat()).assert_success();
    let [depth] = read_channels(&through_table.join("depth.exr"), ["Y"]);
    assert!(
        (depth[4 * 9 + 4] - 7.0).abs() < 1e-3,
        "{}",
        depth[4 * 9 + 4]
    );
    std::fs::remove_file(&usda).unwrap();
    run(&[&["render", s(&table)], &args[..], &[s(&out)]].concat()).assert_error(&[
        "quad.prisms",
        "--camera Far",
        "keeps no cameras",
        "quad.usda is not there",
    ]);
    assert_eq!(
        files_in(&out),
        Vec::<String>::new(),
        "nothing written for a rejected camera"
    );
}

/// Orthographic views: a USD camera with `projection = "orthographic"` (its view
/// `verticalAperture` tenths of a unit tall) sees the flat 2 × 2 quad head-on at one depth
/// across it and over exactly the pixels its square covers, whatever its distance; `--fov`
/// renders the same camera as a pinhole (then depth grows off the axis); `--ortho HEIGHT|fit`
/// makes any view orthographic; a height that is not a positive number, or with `--fov`,
/// fails before anything is written.
#[test]
fn orthographic_cameras_and_ortho_render_parallel_views() {
    let dir = temp_dir("render-ortho");
    let usda = dir.join("quad.usda");
    std::fs::write(
        &usda,
        quad_usda(
            "def Camera \"Top\"\n{\n    token projection = \"orthographic\"\n    \
             float verticalAperture = 40\n    double3 xformOp:translate = (0, 0, 3)\n    \
             uniform token[] xformOpOrder = [\"xformOp:translate\"]\n}\n",
        ),
    )
    .unwrap();
    let map = write_flat_map(&dir);
    let render = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut args = vec![
            "render",
            s(&usda),
            "--disp",
            s(&map),
            "--scale",
            "0.1",
            "--res",
            "20x20",
            "--aov",
            "mask,depth",
            "--json",
            "-o",
            s(&out),
        ];
        args.extend(extra);
        let summary = run(&args).assert_success().json();
        let [mask] = read_channels(&out.join("mask.exr"), ["Y"]);
        let [depth] = read_channels(&out.join("depth.exr"), ["Y"]);
        let hits: Vec<usize> = (0..400).filter(|&i| mask[i] > 0.5).collect();
        let camera = summary["camera"].as_str().unwrap().to_string();
        (camera, hits, depth)
    };
    // The view is 4 units tall and wide: the quad covers pixels 5..15 of 20 each way.
    let square: Vec<usize> = (5..15)
        .flat_map(|y| (5..15).map(move |x| y * 20 + x))
        .collect();
    let (camera, hits, depth) = render("file", &[]);
    assert_eq!(
        camera,
        "the file's orthographic camera '/Top' (4 units tall)"
    );
    assert_eq!(hits, square);
    for &i in &hits {
        assert!(
            (depth[i] - 3.0).abs() < 1e-4,
            "pixel {i}: depth {}",
            depth[i]
        );
    }
    let (camera, hits, depth) = render("fov", &["--fov", "60"]);
    assert_eq!(
        camera,
        "the file's orthographic camera '/Top' (4 units tall), with --fov"
    );
    let (centre, corner) = (depth[10 * 20 + 10], depth[hits[0]]);
    assert!(
        corner > centre + 0.05,
        "a pinhole: depth {corner} off the axis, {centre} on it"
    );
    // From 6 units further the parallel view is the same picture, 6 units deeper.
    let (camera, hits, depth) = render("moved", &["--camera-from", "0,0,9", "--ortho", "4"]);
    assert_eq!(
        camera,
        "the file's orthographic camera '/Top' (4 units tall), with --camera-from, --ortho"
    );
    assert_eq!(hits, square);
    assert!((depth[hits[0]] - 9.0).abs() < 1e-4, "{}", depth[hits[0]]);
    // `fit`: the quad and a 10% margin fill the view: 2 of 2.2 units, 18 of 20 pixels a side.
    let (camera, hits, _) = render("fit", &["--ortho", "fit"]);
    assert_eq!(
        camera,
        "the file's orthographic camera '/Top' (4 units tall), with --ortho"
    );
    assert_eq!(hits.len(), 18 * 18);
    for (value, needles) in [
        ("0", vec!["--ortho 0", "positive"]),
        ("-2", vec!["--ortho -2", "positive"]),
        ("wide", vec!["--ortho wide", "`fit`"]),
    ] {
        let out = dir.join("rejected");
        run(&[
            "render",
            s(&usda),
            "--disp",
            s(&map),
            &format!("--ortho={value}"),
            "-o",
            s(&out),
        ])
        .assert_error(&needles);
        assert!(!out.exists(), "--ortho {value}: the output folder was made");
    }
    run(&[
        "render",
        s(&usda),
        "--disp",
        s(&map),
        "--ortho",
        "2",
        "--fov",
        "30",
        "-o",
        s(&dir.join("both")),
    ])
    .assert_error(&["--ortho and --fov"]);
}
