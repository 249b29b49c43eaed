//! USD loader tests on small layers written here: what each one pins is in its name and its
//! assertion messages. Files from Blender and Pixar's usd-core are checked in tests/python.

use super::*;
use crate::load::{load_mesh, MeshOptions};

/// A fresh folder per test (tests run in parallel).
fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pb_usd_{}_{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn write(d: &Path, name: &str, text: &str) -> PathBuf {
    let p = d.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn layer(up: &str, body: &str) -> String {
    format!("#usda 1.0\n(\n    upAxis = \"{up}\"\n    metersPerUnit = 1\n)\n\n{body}\n")
}

/// A unit quad (z = 0, counter-clockwise seen from +z) plus a pentagon, with `st` given as
/// `st_decl` (type, name, value and metadata lines).
fn quad_and_pentagon(st_decl: &str) -> String {
    layer(
        "Y",
        &format!(
            r#"def Mesh "M"
{{
    int[] faceVertexCounts = [4, 5]
    int[] faceVertexIndices = [0, 1, 2, 3, 1, 4, 5, 6, 2]
    point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2.5, 0.5, 0), (2, 1, 0)]
    {st_decl}
}}"#
        ),
    )
}

fn area_sign_z(m: &BaseMesh, t: usize) -> f32 {
    m.face_cross(t).z
}

#[test]
fn polygons_are_fan_triangulated_counter_clockwise() {
    let d = dir("poly");
    let p = write(&d, "a.usda", &quad_and_pentagon(""));
    let m = load_mesh(&p, &MeshOptions::default()).unwrap();
    assert_eq!(
        m.triangle_count(),
        2 + 3,
        "a quad gives 2 triangles, a pentagon 3"
    );
    for t in 0..m.triangle_count() {
        assert!(
            area_sign_z(&m, t) > 0.0,
            "triangle {t} must keep the polygon's winding"
        );
    }
    assert!(
        m.missing_uvs,
        "no st primvar: the mesh is flagged as having no UVs"
    );
    assert_eq!(m.up_axis, Some(UpAxis::Y));
    assert_eq!(m.groups, vec!["/M".to_string()]);
    for n in &m.normals {
        assert!(
            (n.z - 1.0).abs() < 1e-5,
            "derived normals of a flat +z mesh point up, got {n}"
        );
    }
}

#[test]
fn indexed_face_varying_st_is_expanded_per_corner() {
    let d = dir("fv");
    // Corner k of the quad reads value indices[k]; the pentagon's corners all read value 0.
    let st = r#"texCoord2f[] primvars:st = [(0.5, 0.5), (0, 0), (1, 0), (1, 1), (0, 1)] (
        interpolation = "faceVarying"
    )
    int[] primvars:st:indices = [1, 2, 3, 4, 0, 0, 0, 0, 0]"#;
    let p = write(&d, "a.usda", &quad_and_pentagon(st));
    let m = load_mesh(&p, &MeshOptions::default()).unwrap();
    assert!(!m.missing_uvs);
    // The quad's UV at a position (the pentagon's corners all read (0.5, 0.5)).
    let uv_at = |pos: Vec3| {
        (0..m.vertex_count())
            .find(|&v| m.positions[v] == pos && m.uvs[v] != Vec2::splat(0.5))
            .map(|v| m.uvs[v])
            .unwrap()
    };
    assert_eq!(uv_at(Vec3::new(0.0, 0.0, 0.0)), Vec2::new(0.0, 0.0));
    assert_eq!(uv_at(Vec3::new(1.0, 1.0, 0.0)), Vec2::new(1.0, 1.0));
    assert_eq!(
        uv_at(Vec3::new(0.0, 1.0, 0.0)),
        Vec2::new(0.0, 1.0),
        "v points up: no flip"
    );
    // Point 1 and 2 carry different UVs in the two faces: they are split, so 4 + 5 vertices.
    assert_eq!(
        m.vertex_count(),
        9,
        "corners are shared only where point, normal and UV agree"
    );
}

#[test]
fn face_varying_st_split_on_shared_points_is_a_uv_seam() {
    // USD shares points between faces and splits only `st`: the quad and the pentagon share
    // points 1 and 2 (one edge), with other UVs on each side. Repair must find that edge as
    // a seam (same positions and derived normals, other UVs) and nothing else.
    let d = dir("fv_seam");
    let st = r#"texCoord2f[] primvars:st = [(0.5, 0.5), (0, 0), (1, 0), (1, 1), (0, 1)] (
        interpolation = "faceVarying"
    )
    int[] primvars:st:indices = [1, 2, 3, 4, 0, 0, 0, 0, 0]"#;
    let p = write(&d, "a.usda", &quad_and_pentagon(st));
    let m = load_mesh(&p, &MeshOptions::default()).unwrap();
    let (out, report) = crate::repair::repair(m, &Default::default());
    assert_eq!(out.seams.len(), 1, "{}", report.to_text());
    let seam = out.seams[0];
    let [i, j] = seam.corners(0);
    let tri = out.triangles[seam.faces[0] as usize];
    let ends = [
        out.positions[tri[i] as usize],
        out.positions[tri[j] as usize],
    ];
    assert!(ends.contains(&Vec3::new(1.0, 0.0, 0.0)) && ends.contains(&Vec3::new(1.0, 1.0, 0.0)));
}

#[test]
fn vertex_uniform_and_constant_st_interpolations() {
    let d = dir("interp");
    let cases = [
        (
            "vertex",
            r#"texCoord2f[] primvars:st = [(0, 0), (1, 0), (1, 1), (0, 1), (0.2, 0), (0.3, 0.5), (0.2, 1)] (
        interpolation = "vertex"
    )"#,
            7,
        ),
        (
            "uniform",
            r#"texCoord2f[] primvars:st = [(0.25, 0.25), (0.75, 0.75)] (
        interpolation = "uniform"
    )"#,
            4 + 5,
        ),
        (
            "constant",
            r#"texCoord2f[] primvars:st = [(0.5, 0.25)] (
        interpolation = "constant"
    )"#,
            7,
        ),
    ];
    for (name, st, verts) in cases {
        let p = write(&d, &format!("{name}.usda"), &quad_and_pentagon(st));
        let m = load_mesh(&p, &MeshOptions::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(m.vertex_count(), verts, "{name}: vertex count");
        match name {
            "vertex" => {
                let v = m
                    .positions
                    .iter()
                    .position(|p| *p == Vec3::new(2.5, 0.5, 0.0))
                    .unwrap();
                assert_eq!(m.uvs[v], Vec2::new(0.3, 0.5));
            }
            "uniform" => {
                let t_last = m.triangle_count() - 1;
                assert_eq!(m.corner_uvs(0), [Vec2::splat(0.25); 3]);
                assert_eq!(m.corner_uvs(t_last), [Vec2::splat(0.75); 3]);
            }
            _ => assert!(m.uvs.iter().all(|&u| u == Vec2::new(0.5, 0.25))),
        }
    }
}

#[test]
fn xform_ops_and_hierarchy_are_applied() {
    let d = dir("xform");
    let text = layer(
        "Z",
        r#"def Xform "Root"
{
    double3 xformOp:translate = (10, 0, 0)
    float xformOp:rotateZ = 90
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateZ"]

    def Xform "Child"
    {
        float3 xformOp:scale = (2, 2, 2)
        double3 xformOp:translate:pivot = (1, 0, 0)
        uniform token[] xformOpOrder = ["xformOp:translate:pivot", "xformOp:scale", "!invert!xformOp:translate:pivot"]

        def Mesh "Tri"
        {
            int[] faceVertexCounts = [3]
            int[] faceVertexIndices = [0, 1, 2]
            point3f[] points = [(1, 0, 0), (2, 0, 0), (1, 1, 0)]
        }
    }
    def Mesh "Moved"
    {
        matrix4d xformOp:transform = ( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 5, 1) )
        uniform token[] xformOpOrder = ["!resetXformStack!", "xformOp:transform"]
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    }
}"#,
    );
    let p = write(&d, "a.usda", &text);
    let m = load_mesh(&p, &MeshOptions::default()).unwrap();
    assert_eq!(m.up_axis, Some(UpAxis::Z));
    let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-5;
    // Child: scale 2 about the pivot (1,0,0): (1,0,0)→(1,0,0), (2,0,0)→(3,0,0), (1,1,0)→(1,2,0);
    // then Root: rotate 90° about z, then translate by 10 in x.
    let tri = m.corners(0);
    assert!(close(tri[0], Vec3::new(10.0, 1.0, 0.0)), "got {tri:?}");
    assert!(close(tri[1], Vec3::new(10.0, 3.0, 0.0)), "got {tri:?}");
    assert!(close(tri[2], Vec3::new(8.0, 1.0, 0.0)), "got {tri:?}");
    // Moved resets the stack: only its own matrix (row-vector translation (0,0,5)) applies.
    let moved = m.corners(1);
    assert!(close(moved[1], Vec3::new(1.0, 0.0, 5.0)), "got {moved:?}");
}

#[test]
fn rotate_xyz_applies_x_first() {
    let d = dir("rotxyz");
    let text = layer(
        "Y",
        r#"def Mesh "M"
{
    float3 xformOp:rotateXYZ = (90, 0, 90)
    uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    point3f[] points = [(0, 1, 0), (0, 0, 0), (1, 0, 0)]
}"#,
    );
    let m = load_mesh(&write(&d, "a.usda", &text), &MeshOptions::default()).unwrap();
    // (0,1,0): about x by 90° → (0,0,1); then about z → (0,0,1).
    // (1,0,0): about x → (1,0,0); then about z by 90° → (0,1,0).
    let c = m.corners(0);
    assert!((c[0] - Vec3::Z).length() < 1e-5, "got {c:?}");
    assert!((c[2] - Vec3::Y).length() < 1e-5, "got {c:?}");
}

#[test]
fn left_handed_and_mirrored_meshes_come_out_counter_clockwise() {
    let d = dir("orient");
    let tri = |extra: &str| {
        layer(
            "Y",
            &format!(
                r#"def Mesh "M"
{{
    {extra}
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    normal3f[] normals = [(0, 0, 1), (0, 0, 1), (0, 0, 1)] (
        interpolation = "vertex"
    )
}}"#
            ),
        )
    };
    for (name, extra, nz) in [
        ("plain", "", 1.0),
        ("left", r#"uniform token orientation = "leftHanded""#, 1.0),
        ("mirror", "float3 xformOp:scale = (1, 1, -1)\n    uniform token[] xformOpOrder = [\"xformOp:scale\"]", -1.0),
    ] {
        let m = load_mesh(&write(&d, &format!("{name}.usda"), &tri(extra)), &MeshOptions::default()).unwrap();
        let ng = m.face_cross(0).normalize();
        let n = m.normals[0];
        assert!((n.z - nz).abs() < 1e-5, "{name}: file normal transformed to world, got {n}");
        // The winding agrees with the normals whenever the file's winding did (plain,
        // mirror); a leftHanded mesh with +z normals is clockwise in USD terms, so flipped.
        let expect = if name == "left" { -nz } else { nz };
        assert!((ng.z - expect).abs() < 1e-5, "{name}: geometric normal {ng}");
    }
}

#[test]
fn face_varying_normals_and_primvars_normals_win() {
    let d = dir("normals");
    let text = layer(
        "Y",
        r#"def Mesh "M"
{
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    normal3f[] normals = [(1, 0, 0), (1, 0, 0), (1, 0, 0)] (
        interpolation = "vertex"
    )
    normal3f[] primvars:normals = [(0, 0, 2), (0, 0.6, 0.8)] (
        interpolation = "faceVarying"
    )
    int[] primvars:normals:indices = [0, 1, 0]
}"#,
    );
    let m = load_mesh(&write(&d, "a.usda", &text), &MeshOptions::default()).unwrap();
    let n = m.corner_normals(0);
    assert!(
        (n[0] - Vec3::Z).length() < 1e-6,
        "primvars:normals over normals, renormalised: {n:?}"
    );
    assert!(
        (n[1] - Vec3::new(0.0, 0.6, 0.8)).length() < 1e-6,
        "indexed: {n:?}"
    );
}

#[test]
fn displacement_material_gives_scale_and_midlevel() {
    let d = dir("disp");
    std::fs::create_dir_all(d.join("tex")).unwrap();
    let text = layer(
        "Z",
        r#"def Xform "Asset"
{
    def Mesh "M" (
        prepend apiSchemas = ["MaterialBindingAPI"]
    )
    {
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
        texCoord2f[] uvA = [(0, 0), (1, 0), (0, 1)]
        texCoord2f[] primvars:aaa = [(9, 9), (9, 9), (9, 9)] (
            interpolation = "vertex"
        )
        texCoord2f[] primvars:heightUV = [(0, 0), (1, 0), (0, 1)] (
            interpolation = "vertex"
        )
        rel material:binding = </Asset/Looks/Rock>
    }
    def Scope "Looks"
    {
        def Material "Rock"
        {
            token outputs:surface.connect = </Asset/Looks/Rock/Surf.outputs:surface>
            token outputs:displacement.connect = </Asset/Looks/Rock/Surf.outputs:displacement>
            def Shader "Surf"
            {
                uniform token info:id = "UsdPreviewSurface"
                float inputs:displacement.connect = </Asset/Looks/Rock/Height.outputs:g>
                token outputs:surface
                token outputs:displacement
            }
            def Shader "Height"
            {
                uniform token info:id = "UsdUVTexture"
                asset inputs:file = @./tex/h.exr@
                float4 inputs:scale = (1, 0.2, 1, 1)
                float4 inputs:bias = (0, -0.06, 0, 0)
                token inputs:wrapS = "clamp"
                token inputs:wrapT = "clamp"
                float2 inputs:st.connect = </Asset/Looks/Rock/Reader.outputs:result>
                float outputs:g
            }
            def Shader "Reader"
            {
                uniform token info:id = "UsdPrimvarReader_float2"
                string inputs:varname = "heightUV"
                float2 outputs:result
            }
        }
    }
}"#,
    );
    let p = write(&d, "a.usda", &text);
    let disp = displacement(&p)
        .unwrap()
        .expect("the bound material displaces");
    assert_eq!(
        disp.file,
        d.join("./tex/h.exr"),
        "relative to the authoring layer"
    );
    assert!((disp.scale - 0.2).abs() < 1e-6, "scale of channel g");
    assert!(
        (disp.midlevel - 0.3).abs() < 1e-6,
        "M = -bias/scale = 0.06/0.2"
    );
    assert_eq!(disp.wrap, Wrap::Clamp);
    assert_eq!(disp.channel, "G");
    assert_eq!(disp.uv_primvar.as_deref(), Some("heightUV"));
    // The mesh's UV set 0 is the primvar the texture reads, not the first by name.
    let m = load_mesh(&p, &MeshOptions::default()).unwrap();
    assert_eq!(m.corner_uvs(0)[1], Vec2::new(1.0, 0.0));
    let m1 = load_mesh(&p, &MeshOptions { uv_set: 1 }).unwrap();
    assert_eq!(
        m1.corner_uvs(0)[1],
        Vec2::splat(9.0),
        "uv_set 1 = the next primvar by name"
    );
    let e = load_mesh(&p, &MeshOptions { uv_set: 2 })
        .unwrap_err()
        .to_string();
    assert!(e.contains("/Asset/M") && e.contains("heightUV, aaa"), "{e}");
}

#[test]
fn preview_surface_materials_are_read_per_mesh() {
    // Two meshes share a textured material (read once), a third has a constant colour with
    // roughness and metallic, a fourth none; the texture reads the mesh's own UV primvar.
    let d = dir("materials");
    let mesh = |name: &str, material: Option<&str>| {
        let binding = material.map_or(String::new(), |m| {
            format!("rel material:binding = </A/Looks/{m}>")
        });
        format!(
            r#"    def Mesh "{name}" (
        prepend apiSchemas = ["MaterialBindingAPI"]
    )
    {{
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
        texCoord2f[] primvars:st = [(0, 0), (1, 0), (0, 1)] (
            interpolation = "vertex"
        )
        {binding}
    }}
"#
        )
    };
    let text = layer(
        "Y",
        &format!(
            r#"def Xform "A"
{{
{}{}{}{}    def Scope "Looks"
    {{
        def Material "Stone"
        {{
            token outputs:surface.connect = </A/Looks/Stone/Surf.outputs:surface>
            def Shader "Surf"
            {{
                uniform token info:id = "UsdPreviewSurface"
                color3f inputs:diffuseColor.connect = </A/Looks/Stone/Albedo.outputs:rgb>
                float inputs:roughness.connect = </A/Looks/Stone/Rough.outputs:g>
                float inputs:metallic.connect = </A/Looks/Stone/Albedo.outputs:r>
                normal3f inputs:normal.connect = </A/Looks/Stone/Bumps.outputs:rgb>
                token outputs:surface
            }}
            def Shader "Bumps"
            {{
                uniform token info:id = "UsdUVTexture"
                asset inputs:file = @./tex/normal.png@
                token inputs:sourceColorSpace = "raw"
                float4 inputs:scale = (2, 2, 2, 2)
                float4 inputs:bias = (-1, -1, -1, -1)
                float2 inputs:st.connect = </A/Looks/Stone/Reader.outputs:result>
                float3 outputs:rgb
            }}
            def Shader "Rough"
            {{
                uniform token info:id = "UsdUVTexture"
                asset inputs:file = @./tex/orm.png@
                token inputs:sourceColorSpace = "raw"
                float4 inputs:scale = (1, -1, 1, 1)
                float4 inputs:bias = (0, 1, 0, 0)
                float2 inputs:st.connect = </A/Looks/Stone/Turn.outputs:result>
                float outputs:g
            }}
            def Shader "Turn"
            {{
                uniform token info:id = "UsdTransform2d"
                float2 inputs:in.connect = </A/Looks/Stone/Tile.outputs:result>
                float inputs:rotation = 90
                float2 inputs:translation = (0.25, 0.5)
                float2 outputs:result
            }}
            def Shader "Tile"
            {{
                uniform token info:id = "UsdTransform2d"
                float2 inputs:in.connect = </A/Looks/Stone/Reader.outputs:result>
                float2 inputs:scale = (2, 3)
                float2 outputs:result
            }}
            def Shader "Albedo"
            {{
                uniform token info:id = "UsdUVTexture"
                asset inputs:file = @./tex/stone.png@
                token inputs:wrapS = "mirror"
                token inputs:wrapT = "clamp"
                float2 inputs:st.connect = </A/Looks/Stone/Reader.outputs:result>
                float3 outputs:rgb
                float outputs:r
            }}
            def Shader "Reader"
            {{
                uniform token info:id = "UsdPrimvarReader_float2"
                string inputs:varname = "st"
                float2 outputs:result
            }}
        }}
        def Material "Gold"
        {{
            token outputs:surface.connect = </A/Looks/Gold/Surf.outputs:surface>
            def Shader "Surf"
            {{
                uniform token info:id = "UsdPreviewSurface"
                color3f inputs:diffuseColor = (1, 0.75, 0.25)
                color3f inputs:emissiveColor = (2, 1, 0.5)
                float inputs:ior = 2
                float inputs:clearcoat = 0.5
                float inputs:clearcoatRoughness = 0.25
                float inputs:roughness = 0.2
                float inputs:metallic = 1
                token outputs:surface
            }}
        }}
    }}
}}"#,
            mesh("M1", Some("Stone")),
            mesh("M2", Some("Gold")),
            mesh("M3", Some("Stone")),
            mesh("M4", None)
        ),
    );
    let p = write(&d, "a.usda", &text);
    let m = load_mesh(&p, &MeshOptions::default()).unwrap();
    assert_eq!(m.materials.len(), 2);
    let per_face: Vec<u32> = (0..4).map(|t| m.face_material(t)).collect();
    assert_eq!(per_face, [0, 1, 0, 2], "Stone, Gold, Stone again, none");
    let (stone, gold) = (&m.materials[0], &m.materials[1]);
    assert_eq!(stone.name, "/A/Looks/Stone");
    assert_eq!(stone.base_color, [1.0; 4], "the texture alone");
    assert_eq!(
        (stone.roughness, stone.metallic),
        (1.0, 1.0),
        "the textures alone"
    );
    let t = stone.base_color_texture.as_ref().unwrap();
    assert_eq!(t.data, TextureData::File(d.join("./tex/stone.png")));
    assert_eq!(t.sampler.wrap, [TexWrap::Mirror, TexWrap::Clamp]);
    assert_eq!((t.name.as_str(), t.tex_coord), ("stone.png", 0));
    // No sourceColorSpace: USD's auto (decided by the image when it is decoded).
    assert_eq!(t.color_space, crate::texture::ColorSpace::Auto);
    // Roughness: the green of a raw texture; metallic: the red of the diffuse texture.
    let r = stone.roughness_texture.as_ref().unwrap();
    assert_eq!((r.texture.name.as_str(), r.channel), ("orm.png", 1));
    assert_eq!(r.texture.color_space, crate::texture::ColorSpace::Raw);
    // Its scale and bias (green inverted: a glossiness map read as roughness) are applied
    // when it is decoded; the albedo has none.
    assert_eq!(
        r.texture.scale_bias,
        Some(([1.0, -1.0, 1.0], [0.0, 1.0, 0.0]))
    );
    assert_eq!(t.scale_bias, None);
    // Read through two UsdTransform2d's, the one nearer the reader first.
    let tile = crate::texture::UvTransform::usd([2.0, 3.0], 0.0, [0.0; 2]);
    let turn = crate::texture::UvTransform::usd([1.0; 2], 90.0, [0.25, 0.5]);
    assert_eq!(r.texture.transform, turn.after(&tile));
    let uv = r.texture.transform.apply(glam::Vec2::new(1.0, 1.0));
    assert!((uv - glam::Vec2::new(-2.75, 2.5)).length() < 1e-6, "{uv}");
    let mt = stone.metallic_texture.as_ref().unwrap();
    assert_eq!((&mt.texture, mt.channel), (t, 0));
    // The normal map: its scale and bias as the texture gives them (exporters' 2 and -1).
    let n = stone.normal_texture.as_ref().unwrap();
    assert_eq!(n.texture.name, "normal.png");
    assert_eq!((n.scale, n.bias), ([2.0; 3], [-1.0; 3]));
    assert_eq!(n.describe_mapping(), "strength 1");
    assert_eq!(stone.texture_uses().len(), 3);
    assert_eq!(gold.normal_texture, None);
    assert_eq!((gold.emission, stone.emission), ([2.0, 1.0, 0.5], [0.0; 3]));
    // ior 2: F0 1/9.
    assert!((gold.specular.unwrap() - 1.0 / 9.0).abs() < 1e-7);
    // clearcoat and its roughness; UsdPreviewSurface's defaults (0, 0.01) where unauthored.
    assert_eq!((gold.clearcoat, gold.clearcoat_roughness), (0.5, 0.25));
    assert_eq!((stone.clearcoat, stone.clearcoat_roughness), (0.0, 0.01));
    assert_eq!(stone.specular, None);
    assert_eq!(gold.base_color, [1.0, 0.75, 0.25, 1.0]);
    assert_eq!((gold.roughness, gold.metallic), (0.2, 1.0));
    assert_eq!(gold.base_color_texture, None);
}

#[test]
fn material_subsets_bind_their_own_faces() {
    // Four quads: the mesh binds Red; a materialBind subset binds Blue to faces 0 and 3 (and
    // names a face 9 that is not there: ignored); a subset of another family, and one of
    // points, bind nothing.
    let d = dir("subsets");
    let material = |name: &str, rgb: &str| {
        format!(
            r#"        def Material "{name}"
        {{
            token outputs:surface.connect = </A/Looks/{name}/Surf.outputs:surface>
            def Shader "Surf"
            {{
                uniform token info:id = "UsdPreviewSurface"
                color3f inputs:diffuseColor = {rgb}
                token outputs:surface
            }}
        }}
"#
        )
    };
    let subset = |name: &str, family: &str, element: &str, indices: &str, m: &str| {
        format!(
            r#"        def GeomSubset "{name}" (
            prepend apiSchemas = ["MaterialBindingAPI"]
        )
        {{
            uniform token elementType = "{element}"
            uniform token familyName = "{family}"
            int[] indices = {indices}
            rel material:binding = </A/Looks/{m}>
        }}
"#
        )
    };
    let text = layer(
        "Y",
        &format!(
            r#"def Xform "A"
{{
    def Mesh "M" (
        prepend apiSchemas = ["MaterialBindingAPI"]
    )
    {{
        int[] faceVertexCounts = [4, 4, 4, 4]
        int[] faceVertexIndices = [0, 1, 4, 3, 1, 2, 5, 4, 3, 4, 7, 6, 4, 5, 8, 7]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (1, 1, 0), (2, 1, 0), (0, 2, 0), (1, 2, 0), (2, 2, 0)]
        rel material:binding = </A/Looks/Red>
{}{}{}    }}
    def Scope "Looks"
    {{
{}{}    }}
}}"#,
            subset("Blue", "materialBind", "face", "[0, 3, 9]", "Blue"),
            subset("Other", "partition", "face", "[1]", "Blue"),
            subset("Points", "materialBind", "point", "[2]", "Blue"),
            material("Red", "(1, 0, 0)"),
            material("Blue", "(0, 0, 1)"),
        ),
    );
    let p = write(&d, "a.usda", &text);
    let m = load_mesh(&p, &MeshOptions::default()).unwrap();
    let names: Vec<&str> = m.materials.iter().map(|x| x.name.as_str()).collect();
    assert_eq!(names, ["/A/Looks/Red", "/A/Looks/Blue"]);
    // Two triangles a quad, in face order.
    let per_face: Vec<u32> = (0..8).map(|t| m.face_material(t)).collect();
    assert_eq!(per_face, [1, 1, 0, 0, 0, 0, 1, 1]);
    assert_eq!(m.groups, ["/A/M", "/A/M/Blue"]);
}

#[test]
fn meshes_without_materials_have_no_displacement() {
    let d = dir("nodisp");
    let p = write(&d, "a.usda", &quad_and_pentagon(""));
    assert_eq!(displacement(&p).unwrap(), None);
}

/// Every error names the file and the prim (or property) and what to do; none panics.
#[test]
fn bad_files_are_errors_not_panics() {
    let d = dir("bad");
    let cases: Vec<(&str, String, &str)> = vec![
        ("garbage.usda", "this is not usd at all {{{".into(), "cannot be read as USD"),
        ("empty.usda", String::new(), "cannot be read as USD"),
        ("binary.usdc", "PXR-USDC\0\0\0\0garbage garbage".into(), "cannot be read as USD"),
        ("nomesh.usda", layer("Y", "def Xform \"X\"\n{\n}"), "zero triangles"),
        (
            "range.usda",
            layer("Y", "def Mesh \"M\"\n{\n    int[] faceVertexCounts = [3]\n    int[] faceVertexIndices = [0, 1, 7]\n    point3f[] points = [(0,0,0), (1,0,0), (0,1,0)]\n}"),
            "/M: faceVertexIndices[2] is 7",
        ),
        (
            "short.usda",
            layer("Y", "def Mesh \"M\"\n{\n    int[] faceVertexCounts = [3, 3]\n    int[] faceVertexIndices = [0, 1, 2]\n    point3f[] points = [(0,0,0), (1,0,0), (0,1,0)]\n}"),
            "face 1",
        ),
        (
            "negative.usda",
            layer("Y", "def Mesh \"M\"\n{\n    int[] faceVertexCounts = [-3]\n    int[] faceVertexIndices = [0, 1, 2]\n    point3f[] points = [(0,0,0), (1,0,0), (0,1,0)]\n}"),
            "negative",
        ),
        (
            "stcount.usda",
            layer("Y", "def Mesh \"M\"\n{\n    int[] faceVertexCounts = [3]\n    int[] faceVertexIndices = [0, 1, 2]\n    point3f[] points = [(0,0,0), (1,0,0), (0,1,0)]\n    texCoord2f[] primvars:st = [(0,0)] (\n        interpolation = \"faceVarying\"\n    )\n}"),
            "/M.primvars:st: has 1 values, expected one per face corner",
        ),
        (
            "stindex.usda",
            layer("Y", "def Mesh \"M\"\n{\n    int[] faceVertexCounts = [3]\n    int[] faceVertexIndices = [0, 1, 2]\n    point3f[] points = [(0,0,0), (1,0,0), (0,1,0)]\n    texCoord2f[] primvars:st = [(0,0)] (\n        interpolation = \"faceVarying\"\n    )\n    int[] primvars:st:indices = [0, 0, 5]\n}"),
            "primvars:st:indices[2] is 5",
        ),
        (
            "points.usda",
            layer("Y", "def Mesh \"M\"\n{\n    int[] faceVertexCounts = [3]\n    int[] faceVertexIndices = [0, 1, 2]\n    float[] points = [0, 1, 2]\n}"),
            "points is FloatVec",
        ),
        (
            "op.usda",
            layer("Y", "def Mesh \"M\"\n{\n    uniform token[] xformOpOrder = [\"xformOp:translate\"]\n    int[] faceVertexCounts = [3]\n    int[] faceVertexIndices = [0, 1, 2]\n    point3f[] points = [(0,0,0), (1,0,0), (0,1,0)]\n}"),
            "/M.xformOp:translate: is listed in xformOpOrder but has no value",
        ),
        (
            "nan.usda",
            layer("Y", "def Mesh \"M\"\n{\n    int[] faceVertexCounts = [3]\n    int[] faceVertexIndices = [0, 1, 2]\n    point3f[] points = [(nan,0,0), (1,0,0), (0,1,0)]\n}"),
            "NaN",
        ),
    ];
    for (name, text, want) in cases {
        let p = write(&d, name, &text);
        let r = std::panic::catch_unwind(|| load_mesh(&p, &MeshOptions::default()));
        let e = r
            .unwrap_or_else(|_| panic!("{name}: panicked"))
            .expect_err(name)
            .to_string();
        assert!(e.contains(name), "{name}: the error names the file: {e}");
        assert!(e.contains(want), "{name}: expected '{want}' in: {e}");
    }
}

/// Every truncated prefix of a valid binary layer fails cleanly (or loads), never panics.
#[test]
fn truncated_usdc_prefixes_fail_cleanly() {
    let d = dir("trunc");
    let text = quad_and_pentagon(
        "texCoord2f[] primvars:st = [(0, 0), (1, 0), (1, 1), (0, 1), (0.2, 0), (0.3, 0.5), (0.2, 1)] (\n        interpolation = \"vertex\"\n    )",
    );
    let data = openusd::usda::parse(&text).unwrap();
    let full = d.join("full.usdc");
    openusd::usdc::CrateWriter::write_to_file(&data, &full).unwrap();
    let m = load_mesh(&full, &MeshOptions::default()).expect("the whole binary layer loads");
    assert_eq!(m.triangle_count(), 5);
    let bytes = std::fs::read(&full).unwrap();
    let step = (bytes.len() / 97).max(1);
    for len in (0..bytes.len()).step_by(step) {
        let p = d.join(format!("cut{len}.usdc"));
        std::fs::write(&p, &bytes[..len]).unwrap();
        let r = std::panic::catch_unwind(|| load_mesh(&p, &MeshOptions::default()));
        assert!(r.is_ok(), "prefix of {len} bytes panicked");
    }
}

/// A text layer nested past `MAX_USDA_NESTING` is refused before the reader sees it (the
/// reader recurses per level; 50 000 nested prims overflowed the stack and aborted), while a
/// hierarchy at the limit loads, even on a 2 MiB thread (rayon's and std's default).
#[test]
fn deep_nesting_is_an_error_and_the_limit_loads_on_a_small_stack() {
    let d = dir("nesting");
    let nested = |levels: usize| {
        let mut body = String::new();
        for i in 0..levels - 1 {
            body += &format!("def Xform \"X{i}\" {{\n");
        }
        body += "def Mesh \"M\" {\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0, 1, 2]\n \
                 point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n texCoord2f[] primvars:st = \
                 [(0, 0), (1, 0), (0, 1)] (interpolation = \"vertex\")\n}\n";
        body += &"}\n".repeat(levels - 1);
        layer("Y", &body)
    };
    // The prims' braces, then the mesh's `[(0, 0), ...]` arrays: two levels more.
    let ok = write(&d, "ok.usda", &nested(MAX_USDA_NESTING - 2));
    let deep = write(&d, "deep.usda", &nested(20_000));
    let loaded = std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(move || load_mesh(&ok, &MeshOptions::default()).map(|m| m.triangles.len()))
        .unwrap()
        .join()
        .expect("no stack overflow at the limit");
    assert_eq!(loaded.unwrap(), 1);
    let e = load_mesh(&deep, &MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("deep.usda") && e.contains("levels deep") && e.contains("flatten"),
        "{e}"
    );
    // Brackets inside strings and comments do not count.
    let quoted = write(
        &d,
        "quoted.usda",
        &format!(
            "{}\n# {}\ndef Xform \"A\" ( doc = \"{}\" ) {{\n}}\n",
            layer("Y", ""),
            "{".repeat(500),
            "[".repeat(500)
        ),
    );
    assert!(check_nesting(&quoted).is_ok());
}

/// Square brackets nested inside square brackets, which openusd parses in time and memory
/// that double with every level (the fuzzed `dices = [0a [[[…` of 174 bytes held 24 GB), are
/// refused past `MAX_USDA_ARRAY_NESTING` wherever they are; list ops, arrays of tuples and
/// brackets closed before the next opens are not nesting.
#[test]
fn square_brackets_nested_in_square_brackets_are_an_error() {
    let d = dir("arrays");
    let nested = |k: usize| "[".repeat(k) + "1" + &"]".repeat(k);
    for (name, text) in [
        (
            "meta.usda",
            format!("#usda 1.0\n(\n    dices = {}\n)\n", nested(40)),
        ),
        (
            "attr.usda",
            layer(
                "Y",
                &format!("def Mesh \"M\"\n{{\n    int[] x = {}\n}}", nested(9)),
            ),
        ),
        // Past a comment a carriage return ends (the fuzzed layer that hung the reader:
        // `#us\ra normal[[[[…`), and past a block comment holding a quote.
        (
            "cr.usda",
            format!("#usda 1.0\n(\n    #x\rdices = {}\n)\n", nested(40)),
        ),
        (
            "block.usda",
            format!("#usda 1.0\n(\n    /* \" */ dices = {}\n)\n", nested(40)),
        ),
    ] {
        let e = check_nesting(&write(&d, name, &text))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(name) && e.contains("square brackets nested more than 8"),
            "{e}"
        );
    }
    let fine = layer(
        "Y",
        &format!(
            "def Mesh \"M\" (\n    prepend apiSchemas = [\"A\", \"B\"]\n)\n{{\n    \
             point3f[] points = [(0, 0, 0), (1, 0, 0)]\n    int[] y = {}\n    int[] z = {}\n    \
             /* {} \" */ string doc = \"a # and a [[[[[[[[[[ \\\" in a string\"\n}}",
            nested(MAX_USDA_ARRAY_NESTING),
            "[1] ".repeat(50),
            nested(20),
        ),
    );
    check_nesting(&write(&d, "fine.usda", &fine)).expect("comments and strings are skipped");
    // A string that runs past its line: openusd reads on to the next quote, so brackets after
    // it could hide from this scan.
    let text = "#usda 1.0\n(\n    doc = \"runs\n\" [[[[[[[[[[1]]]]]]]]]]\n)\n";
    let e = check_nesting(&write(&d, "string.usda", text))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("string.usda")
            && e.contains("line 3: a string's quotes are not closed on its line"),
        "{e}"
    );
}

/// Fuzzed binary layers that made the reader's allocation fail, which aborts the process: a
/// PATHS section stating a 4.4 TB compressed block, an array value of 1.5 × 10¹¹ elements, a
/// token vector of 4.5 × 10¹⁵ entries, a list op of 6.5 × 10¹⁷ items, an inlined token array,
/// a list op flagged as an array, a compressed array's block, a second list of references.
/// The pre-check refuses
/// them, naming the file and the section; every prefix of a valid layer, and the layer
/// itself, passes it (`truncated_usdc_prefixes_fail_cleanly` loads them).
#[test]
fn a_crate_count_larger_than_the_file_is_an_error_not_an_abort() {
    let d = dir("huge");
    let refused = |name: &str, bytes: &[u8], wants: &[&str]| {
        let p = d.join(name);
        std::fs::write(&p, bytes).unwrap();
        let e = load_mesh(&p, &MeshOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains(name), "{e}");
        for want in wants {
            assert!(e.contains(want), "{name}: expected '{want}' in: {e}");
        }
    };
    refused(
        "huge.usdc",
        include_bytes!("../../../fuzz/corpus/usdc/abort-huge-compressed-block"),
        &["PATHS section", "cannot hold"],
    );
    // An array value (read per attribute, after open) stating 1.5 × 10¹¹ elements.
    refused(
        "array.usdc",
        include_bytes!("../../../fuzz/corpus/usdc/abort-huge-array"),
        &["array value", "cannot hold"],
    );
    // A token vector value stating 4.5 × 10¹⁵ entries.
    refused(
        "tokens.usdc",
        include_bytes!("../../../fuzz/corpus/usdc/abort-huge-token-vector"),
        &["entries"],
    );
    // A string list op stating 6.5 × 10¹⁷ items.
    refused(
        "listop.usdc",
        include_bytes!("../../../fuzz/corpus/usdc/abort-huge-list-op"),
        &["list op"],
    );
    // A token array flagged inlined, whose payload (2) the reader still takes as an offset:
    // the count there (the file's magic) states 5.8 × 10¹⁷ tokens.
    refused(
        "inlined.usdc",
        include_bytes!("../../../fuzz/corpus/usdc/abort-huge-token-array"),
        &["array value", "cannot hold"],
    );
    // An int list op whose rep is flagged as an array: the reader reads it as a list op
    // anyway, its first list's count (2 × 10¹⁷) from the file's magic.
    refused(
        "arraylistop.usdc",
        include_bytes!("../../../fuzz/corpus/usdc/abort-list-op-flagged-array"),
        &["list op", "cannot hold"],
    );
    // A compressed int array whose LZ4 block states 1.8 × 10¹⁶ bytes (the count was fine).
    refused(
        "block.usdc",
        include_bytes!("../../../fuzz/corpus/usdc/abort-huge-compressed-array"),
        &["compressed array", "block states"],
    );
    // A reference list op whose second list states 2.8 × 10¹⁴ references (the pre-check
    // walks the first list's references, dictionaries included, to find it).
    refused(
        "references.usdc",
        include_bytes!("../../../fuzz/corpus/usdc/abort-huge-reference-list"),
        &["list op", "cannot hold"],
    );
    // A payload list op flagged inlined, which openusd 0.6 reads at its payload (0) anyway:
    // the count there states 1.9 × 10¹⁶ payloads.
    refused(
        "payloads.usdc",
        include_bytes!("../../../fuzz/corpus/usdc/abort-inlined-payload-list-op"),
        &["list op", "cannot hold"],
    );
    // Valid references pass: a binary layer whose prim references two others, with and
    // without customData.
    let refs = openusd::usda::parse(&layer(
        "Y",
        r#"def Mesh "A"
{
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
}
def Xform "B"
{
}
def Xform "C" (
    prepend references = [</A>, </B> (customData = { int k = 1 })]
    append references = </B>
)
{
}"#,
    ))
    .unwrap();
    let refs_path = d.join("refs.usdc");
    openusd::usdc::CrateWriter::write_to_file(&refs, &refs_path).unwrap();
    let refs_bytes = std::fs::read(&refs_path).unwrap();
    crate::load::usdc_check::check(&refs_path, &refs_bytes).expect("valid references pass");
    let data = openusd::usda::parse(&quad_and_pentagon("")).unwrap();
    let full = d.join("full.usdc");
    openusd::usdc::CrateWriter::write_to_file(&data, &full).unwrap();
    let bytes = std::fs::read(&full).unwrap();
    for len in 0..=bytes.len() {
        assert!(
            crate::load::usdc_check::check(&full, &bytes[..len]).is_ok(),
            "prefix of {len} bytes refused"
        );
    }
    // The same layer with one count blown up: refused, whichever section it is in.
    let mut refused = 0;
    for at in (32..bytes.len().saturating_sub(8)).step_by(8) {
        let mut b = bytes.clone();
        b[at..at + 8].copy_from_slice(&(1u64 << 42).to_le_bytes());
        if crate::load::usdc_check::check(&full, &b).is_err() {
            refused += 1;
        }
    }
    assert!(refused > 0, "no blown-up count refused");
}

/// The reader reads a dictionary's entries as values of their own and recurses into nested
/// dictionaries; an entry whose value is its own dictionary recursed until the stack
/// overflowed. A layer with nested `customData` loads; the same layer with the inner
/// dictionary's entry pointed back at the dictionary is an error naming the file.
#[test]
fn a_dictionary_that_holds_itself_is_an_error_not_a_stack_overflow() {
    let d = dir("dictloop");
    let text = layer(
        "Y",
        r#"def Mesh "M" (
    customData = {
        dictionary outer = {
            int inner = 7
        }
    }
)
{
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
}"#,
    );
    let data = openusd::usda::parse(&text).unwrap();
    let good = d.join("good.usdc");
    openusd::usdc::CrateWriter::write_to_file(&data, &good).unwrap();
    assert_eq!(
        load_mesh(&good, &MeshOptions::default())
            .unwrap()
            .triangle_count(),
        1
    );
    // The inner dictionary: a plain (not inlined) rep of type 31 stored in the file, pointing
    // at one entry whose jump leads to the int's rep.
    let mut b = std::fs::read(&good).unwrap();
    let u64_at = |b: &[u8], i: usize| u64::from_le_bytes(b[i..i + 8].try_into().unwrap());
    let (rep, payload) = (0..b.len() - 8)
        .map(|i| u64_at(&b, i))
        .filter(|v| v >> 56 == 0 && (v >> 48) & 0xFF == 31)
        .map(|v| (v, (v & ((1 << 48) - 1)) as usize))
        .find(|&(_, p)| p > 0 && p + 20 <= b.len() && u64_at(&b, p) == 1)
        .expect("the inner dictionary's rep");
    let jump_at = payload + 12;
    let int_rep_at = (jump_at as i64 + u64_at(&b, jump_at) as i64) as usize;
    assert_eq!(
        (u64_at(&b, int_rep_at) >> 48) & 0xFF,
        3,
        "the entry is the int"
    );
    b[int_rep_at..int_rep_at + 8].copy_from_slice(&rep.to_le_bytes());
    let looped = d.join("looped.usdc");
    std::fs::write(&looped, &b).unwrap();
    let e = load_mesh(&looped, &MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("looped.usdc") && e.contains("more than 32 deep, or in a loop"),
        "{e}"
    );
}

/// An attribute without a default is read at its first time sample, so time samples are read
/// too: their times array (a value of its own) states the count the reader allocates for. A
/// binary layer whose points are time samples loads; with the times' count blown up to 2⁴² it
/// is refused before the reader allocates 35 TB (which would abort).
#[test]
fn time_samples_with_a_huge_times_array_are_an_error_not_an_abort() {
    let d = dir("samples");
    let text = layer(
        "Y",
        "def Mesh \"M\" {\n    int[] faceVertexCounts = [3]\n    int[] faceVertexIndices = [0, 1, 2]\n    \
         point3f[] points.timeSamples = {\n        1.5: [(0, 0, 0), (1, 0, 0), (0, 1, 0)],\n        \
         2.5: [(0, 0, 0), (2, 0, 0), (0, 2, 0)],\n    }\n    texCoord2f[] primvars:st = [(0, 0), \
         (1, 0), (0, 1)] (interpolation = \"vertex\")\n}\n",
    );
    let data = openusd::usda::parse(&text).unwrap();
    let full = d.join("samples.usdc");
    openusd::usdc::CrateWriter::write_to_file(&data, &full).unwrap();
    let m = load_mesh(&full, &MeshOptions::default()).expect("the first sample loads");
    assert_eq!(m.triangle_count(), 1);
    assert_eq!(m.positions[1], glam::Vec3::X, "the first sample's points");
    let bytes = std::fs::read(&full).unwrap();
    for len in 0..=bytes.len() {
        assert!(
            crate::load::usdc_check::check(&full, &bytes[..len]).is_ok(),
            "prefix of {len} bytes refused"
        );
    }
    // The times [1.5, 2.5], stored after their count.
    let times: Vec<u8> = [1.5f64, 2.5].iter().flat_map(|t| t.to_le_bytes()).collect();
    let at = bytes
        .windows(16)
        .position(|w| w == times)
        .expect("the times array");
    let mut b = bytes.clone();
    if b[at - 8..at] == 2u64.to_le_bytes() {
        b[at - 8..at].copy_from_slice(&(1u64 << 42).to_le_bytes());
    } else {
        assert_eq!(b[at - 4..at], 2u32.to_le_bytes(), "the times' count");
        b[at - 4..at].copy_from_slice(&u32::MAX.to_le_bytes());
    }
    let p = d.join("huge-times.usdc");
    std::fs::write(&p, &b).unwrap();
    let e = load_mesh(&p, &MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("huge-times.usdc") && e.contains("array value") && e.contains("cannot hold"),
        "{e}"
    );
}

/// A panic inside the reader (fuzzed binary layer: a token index past the token table) is a
/// clean error naming the file.
#[test]
fn a_reader_panic_is_an_error() {
    let d = dir("panic");
    let p = d.join("crash.usdc");
    std::fs::write(
        &p,
        include_bytes!("../../../fuzz/corpus/usdc/crash-token-index"),
    )
    .unwrap();
    let e = load_mesh(&p, &MeshOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("crash.usdc") && e.contains("crashed on this file"),
        "{e}"
    );
}

/// Both prim walks (the mesh loader's and the displacement lookup's) refuse `p`, each with
/// an error holding every one of `wants`.
fn both_walks_refuse(p: &Path, wants: &[&str]) {
    for e in [
        load_mesh(p, &MeshOptions::default()).unwrap_err(),
        displacement(p).unwrap_err(),
    ] {
        let e = e.to_string();
        for want in wants {
            assert!(e.contains(want), "expected '{want}' in: {e}");
        }
    }
}

/// A fuzzed binary layer whose prim `/quad` is composed as its own child: both prim walks
/// recursed until the stack overflowed (23 000 levels, an abort). Prims deeper than
/// `MAX_PRIM_DEPTH` are an error naming the file (shown on a 300-deep binary layer); a
/// hierarchy 60 deep still loads. Input: `fuzz/corpus/usdc/overflow-prim-cycle`.
#[test]
fn a_prim_hierarchy_that_never_ends_is_an_error_not_a_stack_overflow() {
    let d = dir("primcycle");
    // The fuzzed file also names a prim `;-)`, refused first since binary prim names are
    // checked (`a_binary_prim_name_that_is_not_an_identifier_is_an_error`).
    let p = d.join("cycle.usdc");
    std::fs::write(
        &p,
        include_bytes!("../../../fuzz/corpus/usdc/overflow-prim-cycle"),
    )
    .unwrap();
    assert!(load_mesh(&p, &MeshOptions::default()).is_err());
    // A binary layer 300 prims deep (a text layer that deep is refused for its brackets):
    // refused by the depth guard, by both walks.
    let nest = |depth: usize| {
        let mut body = String::new();
        for k in 0..depth {
            body += &format!("def Xform \"X{k}\"\n{{\n");
        }
        body += "def Mesh \"M\"\n{\n    int[] faceVertexCounts = [3]\n    \
                 int[] faceVertexIndices = [0, 1, 2]\n    \
                 point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n}\n";
        body + &"}\n".repeat(depth)
    };
    let data = openusd::usda::parse(&layer("Y", &nest(300))).unwrap();
    let deep = d.join("deep.usdc");
    openusd::usdc::CrateWriter::write_to_file(&data, &deep).unwrap();
    both_walks_refuse(&deep, &["deep.usdc", "more than 256 levels deep"]);
    let deep = write(&d, "deep.usda", &layer("Y", &nest(60)));
    assert_eq!(
        load_mesh(&deep, &MeshOptions::default())
            .unwrap()
            .triangle_count(),
        1
    );
}

/// A fuzzed binary layer names a prim `;-)`: a binary layer's prim names are tokens, not
/// parsed, and that one sent openusd's instancing into endless recursion when the loader
/// asked whether the prim is active (a stack overflow). A child prim's name must be an
/// identifier, as a text layer's must (`check_prim_name`). Input:
/// `fuzz/corpus/usdc/overflow-prim-name`.
#[test]
fn a_binary_prim_name_that_is_not_an_identifier_is_an_error() {
    let d = dir("binname");
    // The second: a child of the root whose path has two levels ("/spuiA}/ad"): its last
    // part is an identifier, but the part between is not, and openusd's instancing recursed
    // on it too.
    for (file, bytes, shown) in [
        (
            "name.usdc",
            &include_bytes!("../../../fuzz/corpus/usdc/overflow-prim-name")[..],
            "\"/;-)\"",
        ),
        (
            "path.usdc",
            &include_bytes!("../../../fuzz/corpus/usdc/overflow-child-path")[..],
            "\"/spuiA}/ad\"",
        ),
    ] {
        let p = d.join(file);
        std::fs::write(&p, bytes).unwrap();
        both_walks_refuse(&p, &[file, shown, "not a USD identifier"]);
    }
}

/// A fuzzed binary layer lists a property named `nor}als` on its mesh. `Prim::attributes`
/// makes a path of every listed name, and openusd's ancestor walk over that path
/// (`Path::parent`) never ended: the loader hung. The mesh's primvars are now found by name,
/// and only `primvars:` names (identifier-checked) become paths. Input:
/// `fuzz/corpus/usdc/hang-property-name`. The load runs on a watchdog thread, so that a
/// regression fails here instead of hanging the suite.
#[test]
fn a_property_name_with_path_syntax_does_not_hang_the_loader() {
    let d = dir("hangname");
    let p = d.join("hang.usdc");
    std::fs::write(
        &p,
        include_bytes!("../../../fuzz/corpus/usdc/hang-property-name"),
    )
    .unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    let q = p.clone();
    std::thread::spawn(move || {
        let _ = tx.send(load_mesh(&q, &MeshOptions::default()).map(|m| m.triangles.len()));
    });
    let loaded = rx
        .recv_timeout(std::time::Duration::from_secs(300))
        .expect("the loader still runs after 300 s on a 1.2 kB file: it hangs");
    // The corrupt layer still holds its faces: three triangles once split.
    assert_eq!(loaded.expect("the layer loads"), 3);
}

/// Fuzzing found prim names with path syntax (`"hsq}ad"`) sending openusd's instancing into
/// endless recursion (a stack overflow, an abort): a text layer's prim names must be
/// identifiers. Both found files are in `fuzz/corpus/usda/overflow-prim-name-*`.
/// Property names become paths too, and `xformOpOrder` lists them as tokens from the file: a
/// fuzzed token with path syntax (`corpus/usda/overflow-xform-op-name`) sent openusd's
/// instancing into endless recursion (a stack overflow). A listed op must be a namespaced
/// identifier; suffixed ops (`xformOp:rotateXYZ:pivot`) and `!invert!` still load.
#[test]
fn an_xform_op_name_that_is_not_an_identifier_is_an_error() {
    let d = dir("opname");
    let fuzzed = d.join("fuzzed.usda");
    std::fs::write(
        &fuzzed,
        include_bytes!("../../../fuzz/corpus/usda/overflow-xform-op-name"),
    )
    .unwrap();
    let e = load_mesh(&fuzzed, &MeshOptions::default())
        .unwrap_err()
        .to_string();
    // Its op token's quotes also run past the line, which the scan now refuses first.
    assert!(
        e.contains("fuzzed.usda")
            && (e.contains("not a USD identifier") || e.contains("not closed on its line")),
        "{e}"
    );
    for (order, bad) in [
        ("\"xformOp:translate/(x)\"", true),
        ("\"xformOp:translate:\"", true),
        (
            "\"xformOp:translate\", \"!invert!xformOp:rotateXYZ:pivot\"",
            false,
        ),
    ] {
        let text = layer(
            "Y",
            &format!(
                "def Mesh \"M\" {{\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0, 1, 2]\n \
                 point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n texCoord2f[] primvars:st = \
                 [(0, 0), (1, 0), (0, 1)] (interpolation = \"vertex\")\n double3 xformOp:translate = \
                 (1, 2, 3)\n float3 xformOp:rotateXYZ:pivot = (0, 0, 90)\n uniform token[] xformOpOrder = \
                 [{order}]\n}}\n"
            ),
        );
        let p = write(&d, "op.usda", &text);
        let r = load_mesh(&p, &MeshOptions::default());
        if bad {
            let e = r.unwrap_err().to_string();
            assert!(
                e.contains("op.usda") && e.contains("not a USD identifier"),
                "{order}: {e}"
            );
        } else {
            let m = r.unwrap_or_else(|e| panic!("{order}: {e}"));
            assert_eq!(m.triangle_count(), 1);
        }
    }
}

#[test]
fn a_prim_name_that_is_not_an_identifier_is_an_error() {
    let d = dir("primname");
    for (name, bad) in [
        ("hsq}ad", true),
        ("a$b", true),
        ("1abc", true),
        ("Rock_01", false),
        ("Stein_ä", false),
    ] {
        let text = layer(
            "Y",
            &format!(
                "def Mesh \"{name}\" {{\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0, 1, 2]\n \
                 point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n}}\n"
            ),
        );
        let p = write(&d, "n.usda", &text);
        let r = load_mesh(&p, &MeshOptions::default());
        if bad {
            let e = r.unwrap_err().to_string();
            assert!(
                e.contains("n.usda") && e.contains("not a USD identifier"),
                "{name}: {e}"
            );
        } else {
            let e = r.err().map(|e| e.to_string()).unwrap_or_default();
            assert!(!e.contains("identifier"), "{name}: {e}");
        }
    }
}

/// A quoted prim name that runs past its line (the fuzzed `def Mh "qq⏎#…⏎}⏎…/icuad"`, whose
/// first line alone is an identifier) sent openusd into endless recursion (a stack overflow
/// with `/` in the rest) or a loop of minutes: it is refused, naming the line, before the
/// reader sees it. The name closed on its line still loads.
#[test]
fn a_prim_name_whose_quotes_run_past_its_line_is_an_error() {
    let d = dir("primname-lines");
    for (name, text) in [
        (
            "runs-on.usda",
            "#usda 1.0\n\ndef Mh \"qq\n#x\n}\n\nz/icuad\"  {\n}\n",
        ),
        ("unclosed.usda", "#usda 1.0\n\ndef Mesh \"quad"),
    ] {
        let e = load_mesh(&write(&d, name, text), &MeshOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(name) && e.contains("line 3") && e.contains("not closed on its line"),
            "{e}"
        );
    }
    let fine = write(&d, "fine.usda", &quad_with_cameras("Y", ""));
    assert_eq!(
        load_mesh(&fine, &MeshOptions::default())
            .unwrap()
            .triangle_count(),
        2
    );
}

#[test]
fn a_path_that_runs_past_its_line_is_an_error() {
    // Found by fuzzing a Blender export: a relationship target's `<` whose `>` came a dozen
    // lines later sent openusd's instancing into endless recursion, a stack overflow.
    let d = dir("path-lines");
    let overflow = include_str!("../../../fuzz/corpus/usda/stack-overflow-path-across-lines");
    for (name, text, line, why) in [
        (
            "overflow.usda",
            overflow,
            "line 30",
            "not closed on its line",
        ),
        (
            "spaces.usda",
            "#usda 1.0\n\ndef Mesh \"M\"\n{\n    rel material:binding = </A B>\n}\n",
            "line 5",
            "characters no path has",
        ),
        (
            "brace.usda",
            "#usda 1.0\n\ndef Mesh \"M\"\n{\n    rel material:binding = </A/Image_Text}re.outputs:rgb>\n}\n",
            "line 5",
            "unbalanced",
        ),
    ] {
        let e = load_mesh(&write(&d, name, text), &MeshOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(name) && e.contains(line) && e.contains(why),
            "{e}"
        );
    }
    // Paths with targets, variant selections and namespaces pass.
    let fine = quad_with_cameras("Y", "").replace(
        "def Mesh \"M\"\n{",
        "def Mesh \"M\"\n{\n    rel a:b = [</M.c[/d].e>, </M{v=x}>]",
    );
    assert!(fine.contains("rel a:b"), "{fine}");
    let m = load_mesh(&write(&d, "fine.usda", &fine), &MeshOptions::default()).unwrap();
    assert_eq!(m.triangle_count(), 2);
}

/// A quad in the z = 0 plane and the given camera prims after it.
fn quad_with_cameras(up: &str, cameras: &str) -> String {
    layer(
        up,
        &format!(
            r#"def Mesh "M"
{{
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 1, 2, 3]
    point3f[] points = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
}}
{cameras}"#
        ),
    )
}

/// A UsdGeomCamera becomes the scene camera: its transform places it (looking down its
/// local −Z, +Y up), `verticalAperture` over `focalLength` is its field of view; of two, the
/// first is the default and either is picked by its path or its name.
#[test]
fn a_usd_perspective_camera_becomes_the_scene_camera() {
    let d = dir("camera");
    let cameras = r#"def Xform "Rig"
{
    double3 xformOp:translate = (0, 0, 5)
    uniform token[] xformOpOrder = ["xformOp:translate"]
    def Camera "Shot"
    {
        float focalLength = 35
        float verticalAperture = 24
        float xformOp:rotateY = 90
        uniform token[] xformOpOrder = ["xformOp:rotateY"]
    }
}
def Camera "Second"
{
    double3 xformOp:translate = (0, 0, 9)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}"#;
    let p = write(&d, "shot.usda", &quad_with_cameras("Y", cameras));
    let m = load_mesh(&p, &MeshOptions::default()).unwrap();
    let cam = m.pick_camera(None).unwrap().expect("the first camera");
    for name in ["/Rig/Shot", "Shot"] {
        assert_eq!(m.pick_camera(Some(name)).unwrap(), Some(cam), "{name}");
    }
    for name in ["/Second", "Second"] {
        let second = m.pick_camera(Some(name)).unwrap().expect(name);
        assert_eq!(second.from, Vec3::new(0.0, 0.0, 9.0), "{name}");
    }
    let e = m.pick_camera(Some("Rig")).unwrap_err().to_string();
    assert!(
        e.contains("shot.usda") && e.contains("its cameras: '/Rig/Shot', '/Second'"),
        "{e}"
    );
    assert!(
        (cam.from - Vec3::new(0.0, 0.0, 5.0)).length() < 1e-5,
        "{}",
        cam.from
    );
    // Turned 90° about +Y, its −Z looks along −X.
    let dir = (cam.to - cam.from).normalize();
    assert!((dir - Vec3::NEG_X).length() < 1e-5, "{dir}");
    assert!((cam.up - Vec3::Y).length() < 1e-5, "{}", cam.up);
    let want = 2.0 * (12.0f32 / 35.0).atan().to_degrees();
    assert_yfov(&cam, want);
    // The film back: USD's default horizontal aperture over the authored vertical one.
    assert_eq!(cam.film_aspect, Some(20.955 / 24.0));

    // Not authored: USD's defaults (15.2908 over 50, 17.4°).
    let p = write(
        &d,
        "default.usda",
        &quad_with_cameras("Z", "def Camera \"C\"\n{\n}"),
    );
    let cam = load_mesh(&p, &MeshOptions::default())
        .unwrap()
        .pick_camera(None)
        .unwrap()
        .unwrap();
    assert_yfov(&cam, 2.0 * (15.2908f32 / 100.0).atan().to_degrees());
    assert_eq!(cam.film_aspect, Some((20.955f64 / 15.2908) as f32));
    // A square image of that camera keeps the film back's whole width: its vertical field of
    // view is the horizontal aperture's (23.9°); an image wider than the film back keeps the
    // vertical aperture's.
    let square = crate::render::camera::Camera::from_scene(&cam, 1.0);
    let wide = crate::render::camera::Camera::from_scene(&cam, 2.0);
    let yfov = |c: crate::render::camera::Camera| match c.projection {
        Projection::Perspective { yfov_deg } => yfov_deg,
        p => panic!("{p:?}"),
    };
    let horizontal = 2.0 * (20.955f32 / 100.0).atan().to_degrees();
    assert!((yfov(square) - horizontal).abs() < 1e-3, "{square:?}");
    assert!((yfov(wide) - 2.0 * (15.2908f32 / 100.0).atan().to_degrees()).abs() < 1e-4);

    // Orthographic: the view is verticalAperture tenths of a scene unit tall, scaled with
    // the prim (USD's default aperture where not authored).
    for (body, want) in [
        ("token projection = \"orthographic\"\n    float verticalAperture = 25", 2.5),
        ("token projection = \"orthographic\"\n    double3 xformOp:scale = (2, 2, 2)\n    uniform token[] xformOpOrder = [\"xformOp:scale\"]", 3.05816),
    ] {
        let cameras = format!("def Camera \"C\"\n{{\n    {body}\n}}");
        let p = write(&d, "ortho.usda", &quad_with_cameras("Y", &cameras));
        let m = load_mesh(&p, &MeshOptions::default()).unwrap();
        let cam = m.pick_camera(None).unwrap().expect(body);
        let Projection::Orthographic { height } = cam.projection else {
            panic!("{body}: {:?}", cam.projection);
        };
        assert!((height - want).abs() < 1e-4, "{body}: {height}");
    }
}

fn assert_yfov(cam: &crate::mesh::SceneCamera, want: f32) {
    match cam.projection {
        Projection::Perspective { yfov_deg } => {
            assert!((yfov_deg - want).abs() < 1e-3, "{yfov_deg} against {want}")
        }
        other => panic!("{other:?}"),
    }
}

/// A camera that cannot be rendered through is left out, the mesh still loads: one of a
/// projection USD does not define, one with a focal length of 0 (a field of view of 180°) or
/// a negative one (an image turned over), one whose focal length is not a number, and an
/// orthographic one with no height.
#[test]
fn a_usd_camera_that_cannot_be_rendered_through_is_left_out() {
    let d = dir("bad-camera");
    for (i, body) in [
        "token projection = \"fisheye\"",
        "token projection = \"orthographic\"\n    float verticalAperture = 0",
        "float focalLength = 0",
        "float focalLength = -35",
        "string focalLength = \"wide\"",
    ]
    .into_iter()
    .enumerate()
    {
        let cameras = format!("def Camera \"C\"\n{{\n    {body}\n}}");
        let p = write(&d, &format!("c{i}.usda"), &quad_with_cameras("Y", &cameras));
        let m = load_mesh(&p, &MeshOptions::default()).unwrap();
        assert!(m.cameras.is_empty(), "{body}: {:?}", m.cameras);
        assert_eq!(m.triangle_count(), 2, "{body}");
    }
}

#[test]
fn targets_must_be_paths_of_prim_and_property_names() {
    let at = sdf::Path::new("/M.rel").unwrap();
    let p = std::path::Path::new("a.usda");
    for good in ["/A/B", "/A/B.outputs:rgb", "/A{v=x}/B.c", "/A{v=}{w=y}"] {
        let t = sdf::Path::new(good).unwrap();
        assert!(super::checked_target(p, &at, t).is_ok(), "{good}");
    }
    // Those openusd's own parser lets through (as a mangled text layer's targets did).
    let mut refused = 0;
    for bad in ["/A/B}c", "/A/*x", "/A/B C", "/A{v}/B", "/A/B.c d"] {
        let Ok(t) = sdf::Path::new(bad) else { continue };
        let e = super::checked_target(p, &at, t).unwrap_err().to_string();
        assert!(
            e.contains("/M.rel") && e.contains("not a path of prim names"),
            "{e}"
        );
        refused += 1;
    }
    assert!(refused >= 2, "only {refused} of the bad paths parse");
    // A relative connection in a text layer is anchored where it is authored, and followed.
    let d = dir("relative-target");
    let text = layer(
        "Y",
        r#"def Mesh "M" (
    prepend apiSchemas = ["MaterialBindingAPI"]
)
{
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    rel material:binding = <../Looks/Red>
}
def Scope "Looks"
{
    def Material "Red"
    {
        token outputs:surface.connect = <Surf.outputs:surface>
        def Shader "Surf"
        {
            uniform token info:id = "UsdPreviewSurface"
            color3f inputs:diffuseColor = (1, 0, 0)
            token outputs:surface
        }
    }
}"#,
    );
    let m = load_mesh(&write(&d, "a.usda", &text), &MeshOptions::default()).unwrap();
    assert_eq!(m.materials.len(), 1, "{:?}", m.materials);
    assert_eq!(m.materials[0].base_color, [1.0, 0.0, 0.0, 1.0]);
}

/// A `DomeLight` becomes the scene's dome: its texture resolved against the layer, its colour
/// × intensity × 2^exposure, and its turn about the stage's up axis (+Y turned 30° about Y in a
/// Y-up stage; in a Z-up stage a `DomeLight_1`, whose pole follows the stage, turned about Z,
/// or a `DomeLight` lifted onto +Z by a quarter turn about X); the second dome is left out, a
/// dome of another parameterisation too, and a value that is not a number is an error.
#[test]
fn a_dome_light_becomes_the_scenes_environment() {
    let d = dir("dome");
    let dome = |ty: &str, body: &str| format!("def {ty} \"Sky\"\n{{\n    {body}\n}}\n");
    let rotate = |x: f32, y: f32, z: f32| {
        format!(
            "float3 xformOp:rotateXYZ = ({x}, {y}, {z})\n    \
             uniform token[] xformOpOrder = [\"xformOp:rotateXYZ\"]"
        )
    };
    let load = |name: &str, up: &str, domes: &str| {
        let p = write(&d, name, &quad_with_cameras(up, domes));
        load_mesh(&p, &MeshOptions::default()).map(|m| m.dome)
    };
    let body = format!(
        "asset inputs:texture:file = @maps/sky.exr@\n    float inputs:intensity = 2\n    \
         float inputs:exposure = 1\n    color3f inputs:color = (1, 0.5, 0.25)\n    {}",
        rotate(0.0, 30.0, 0.0)
    );
    let two = dome("DomeLight", &body) + &dome("DomeLight", "").replace("Sky", "Other");
    let got = load("y.usda", "Y", &two).unwrap().expect("a dome");
    assert_eq!(got.name, "/Sky");
    assert_eq!(got.texture, Some(d.join("maps/sky.exr")));
    assert_eq!(got.tint, [4.0, 2.0, 1.0]);
    assert!((got.turn_deg - 30.0).abs() < 1e-3, "{}", got.turn_deg);
    for (ty, xform) in [
        ("DomeLight_1", rotate(0.0, 0.0, 30.0)),
        ("DomeLight", rotate(90.0, 0.0, 30.0)),
    ] {
        let got = load("z.usda", "Z", &dome(ty, &xform)).unwrap().expect(ty);
        assert_eq!((got.texture, got.tint), (None, [1.0; 3]), "{ty}");
        assert!((got.turn_deg - 30.0).abs() < 1e-3, "{ty}: {}", got.turn_deg);
    }
    let mirrored = dome(
        "DomeLight",
        "token inputs:texture:format = \"mirroredBall\"",
    );
    assert_eq!(load("ball.usda", "Y", &mirrored).unwrap(), None);
    // A negative radiance, or one past f32's range, is no dome (a warning).
    for body in ["float inputs:intensity = -2", "float inputs:exposure = 200"] {
        let domes = dome("DomeLight", body);
        assert_eq!(load("dark.usda", "Y", &domes).unwrap(), None, "{body}");
    }
    let e = load(
        "bad.usda",
        "Y",
        &dome("DomeLight", "string inputs:intensity = \"hot\""),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("bad.usda") && e.contains("/Sky") && e.contains("inputs:intensity"),
        "{e}"
    );
}

/// `SphereLight`s light beside the key, as points or spheres of intensity (W/sr) UsdLux's
/// radiance times the sphere's disc, or normalized a quarter of the intensity (Blender writes
/// a 100 W lamp as 31.83, normalized: 7.96 W/sr); `treatAsPoint` makes a point;
/// `ShapingAPI`'s cone a spot down −Z; one of no radius that is not normalized casts nothing
/// and is left out; a second `DistantLight` lights beside the first, in the mesh's frame.
#[test]
fn sphere_lights_and_later_distant_lights_light_beside_the_key() {
    use crate::render::lights::LightShape;
    let d = dir("spheres");
    let lights = r#"def DistantLight "Sun"
{
}
def DistantLight "Rim"
{
    float inputs:intensity = 2
    bool inputs:normalize = 1
    float xformOp:rotateX = 90
    uniform token[] xformOpOrder = ["xformOp:rotateX"]
}
def SphereLight "Blender"
{
    float inputs:intensity = 31.830988
    bool inputs:normalize = 1
    float inputs:radius = 0.1
    double3 xformOp:translate = (0, 3, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def SphereLight "Ball"
{
    float inputs:intensity = 4
    color3f inputs:color = (1, 0, 0)
}
def SphereLight "Dot"
{
    float inputs:intensity = 4
    bool treatAsPoint = 1
}
def SphereLight "Spot" (
    prepend apiSchemas = ["ShapingAPI"]
)
{
    float inputs:intensity = 8
    bool inputs:normalize = 1
    float inputs:radius = 0
    float inputs:shaping:cone:angle = 30
    float inputs:shaping:cone:softness = 0.25
}
def SphereLight "Nothing"
{
    float inputs:radius = 0
}"#;
    let p = write(&d, "lights.usda", &quad_with_cameras("Y", lights));
    let m = load_mesh(&p, &MeshOptions::default()).unwrap();
    assert_eq!(m.sun.as_ref().map(|s| s.name.as_str()), Some("/Sun"));
    let names: Vec<&str> = m.lights.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, ["/Rim", "/Blender", "/Ball", "/Dot", "/Spot"]);
    let l = |i: usize| m.lights[i].light;
    // Turned 90° about +X, the rim's +Z is −Y.
    assert!(matches!(l(0).shape, LightShape::Distant { dir, cos_radius }
        if (dir - Vec3::NEG_Y).length() < 1e-6 && (cos_radius - 0.265f32.to_radians().cos()).abs() < 1e-6));
    assert_eq!(l(0).power, 2.0);
    assert!(
        matches!(l(1).shape, LightShape::Local { pos, radius, spot: None }
        if pos == Vec3::new(0.0, 3.0, 0.0) && (radius - 0.1).abs() < 1e-6)
    );
    assert!(
        (l(1).power - 100.0 / (4.0 * std::f32::consts::PI)).abs() < 1e-3,
        "{:?}",
        l(1)
    );
    // Red: its luminance 0.2126 of the radiance, times the disc, π × 0.5².
    let want = 4.0 * std::f32::consts::PI * 0.25 * 0.2126;
    assert!((l(2).power - want).abs() < 1e-5, "{:?}", l(2));
    assert!((l(2).color - Vec3::new(1.0 / 0.2126, 0.0, 0.0)).length() < 1e-4);
    assert!(matches!(l(3).shape, LightShape::Local { radius: 0.0, .. }));
    let LightShape::Local {
        spot: Some(spot), ..
    } = l(4).shape
    else {
        panic!("{:?}", l(4))
    };
    assert!((spot.axis - Vec3::NEG_Z).length() < 1e-6);
    assert!((spot.cos_outer - 30f32.to_radians().cos()).abs() < 1e-6);
    let cos30 = 30f32.to_radians().cos();
    assert!((spot.cos_inner - (cos30 + 0.25 * (1.0 - cos30))).abs() < 1e-6);
    assert_eq!(l(4).power, 2.0);
}

/// `RectLight`s and `DiskLight`s light as one-sided area lights down their −Z, of UsdLux's
/// radiance (over their area when normalized: Blender writes a 100 W area lamp as 31.83,
/// normalized, a radiance of 100 / (π × area)); a rect light's size is its width and height
/// along X and Y, a disk's its radius, both scaled with the prim.
#[test]
fn rect_and_disk_lights_are_area_lights() {
    use crate::render::lights::{area_and_normal, LightShape};
    let d = dir("areas");
    let lights = r#"def RectLight "Box"
{
    float inputs:intensity = 31.830988
    bool inputs:normalize = 1
    float inputs:width = 2
    float inputs:height = 0.5
    double3 xformOp:translate = (0, 0, 3)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def DiskLight "Round"
{
    float inputs:intensity = 31.830988
    bool inputs:normalize = 1
    double3 xformOp:scale = (2, 2, 2)
    uniform token[] xformOpOrder = ["xformOp:scale"]
}"#;
    let p = write(&d, "areas.usda", &quad_with_cameras("Y", lights));
    let m = load_mesh(&p, &MeshOptions::default()).unwrap();
    let [rect, disk] = [m.lights[0].light, m.lights[1].light];
    let LightShape::Area {
        pos,
        u,
        v,
        disk: false,
    } = rect.shape
    else {
        panic!("{rect:?}")
    };
    assert_eq!(
        (pos, u, v),
        (
            Vec3::new(0.0, 0.0, 3.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.25, 0.0)
        )
    );
    let (area, n) = area_and_normal(u, v, false);
    assert_eq!((area, n), (1.0, Vec3::NEG_Z));
    assert!(
        (rect.power - 100.0 / std::f32::consts::PI).abs() < 1e-3,
        "{rect:?}"
    );
    let LightShape::Area {
        u, v, disk: true, ..
    } = disk.shape
    else {
        panic!("{disk:?}")
    };
    // Radius 0.5 scaled by 2: an area of π.
    let (area, _) = area_and_normal(u, v, true);
    assert!((area - std::f32::consts::PI).abs() < 1e-5);
    assert!(
        (disk.power - 100.0 / std::f32::consts::PI / area).abs() < 1e-3,
        "{disk:?}"
    );
}

/// A `DistantLight` becomes the key light: towards its +Z as its transform turns it (45° up
/// and a quarter turn: azimuth 90°, +X), its irradiance `intensity × 2^exposure` (normalized)
/// or that times the disc's solid angle (UsdLux's fallbacks: 50 000 × 6.7 × 10⁻⁵ sr for a
/// 0.53° sun), times its colour's luminance, in that colour of unit luminance; its angle; in a
/// Z-up stage the same angles from the same light turned into Z-up. A negative colour, like
/// a negative intensity, leaves the light out.
#[test]
fn a_distant_light_becomes_the_key_light() {
    let d = dir("sun");
    let sun = |up: &str, rotate: &str| {
        let light = format!(
            "def DistantLight \"Sun\"\n{{\n    float inputs:intensity = 3\n    \
             float inputs:exposure = 1\n    float inputs:angle = 2\n    \
             bool inputs:normalize = 1\n    color3f inputs:color = (0.5, 1, 2)\n    \
             float3 xformOp:rotateXYZ = {rotate}\n    \
             uniform token[] xformOpOrder = [\"xformOp:rotateXYZ\"]\n}}\n"
        );
        let p = write(&d, &format!("{up}.usda"), &quad_with_cameras(up, &light));
        load_mesh(&p, &MeshOptions::default())
            .unwrap()
            .sun
            .expect("a sun")
    };
    for (up, rotate) in [("Y", "(-45, 90, 0)"), ("Z", "(45, 0, 90)")] {
        let got = sun(up, rotate);
        assert_eq!(got.name, "/Sun");
        let [az, el, irradiance] = got.key;
        assert!(
            (az - 90.0).abs() < 1e-3 && (el - 45.0).abs() < 1e-3,
            "{up}: {:?}",
            got.key
        );
        let luminance = 0.2126 * 0.5 + 0.7152 + 0.0722 * 2.0;
        assert!(
            (irradiance - 6.0 * luminance).abs() < 1e-5 && got.angle_deg == 2.0,
            "{up}: {got:?}"
        );
        let want = [0.5, 1.0, 2.0].map(|c| c / luminance);
        assert!(
            (0..3).all(|i| (got.color[i] - want[i]).abs() < 1e-5),
            "{up}: {got:?}"
        );
    }
    let p = write(
        &d,
        "fallback.usda",
        &quad_with_cameras("Y", "def DistantLight \"Sun\"\n{\n}\n"),
    );
    let got = load_mesh(&p, &MeshOptions::default())
        .unwrap()
        .sun
        .expect("a sun");
    let want = 50_000.0 * std::f64::consts::TAU * (1.0 - 0.265f64.to_radians().cos());
    let irradiance = got.key[2] as f64;
    assert!(
        (irradiance - want).abs() < 1e-5 * want && (want - 3.36).abs() < 0.01,
        "{got:?}"
    );
    assert_eq!(
        (got.key[1], got.angle_deg),
        (0.0, 0.53),
        "along −Z: on the horizon"
    );
    for (i, body) in [
        "float inputs:intensity = -2",
        "float inputs:exposure = 200",
        "color3f inputs:color = (1, -0.5, 1)",
    ]
    .into_iter()
    .enumerate()
    {
        let text = format!("def DistantLight \"Sun\"\n{{\n    {body}\n}}\n");
        let p = write(&d, &format!("bad{i}.usda"), &quad_with_cameras("Y", &text));
        let m = load_mesh(&p, &MeshOptions::default()).unwrap();
        assert_eq!(m.sun, None, "{body}");
    }
}
