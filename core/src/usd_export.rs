//! Export a prepared (repaired and baked) asset as a USD text layer (`.usda`).
//!
//! The layer holds one `Mesh` (the repaired triangles, unit vertex normals, `primvars:st`), a
//! `UsdPreviewSurface` material whose `inputs:displacement` reads the height map through a
//! `UsdUVTexture` (`scale = S`, `bias = −M·S`, per DESIGN.md), and the baked per-face
//! displacement range as `uniform` primvars `primvars:prismbake:wmin` / `wmax` (world units
//! along the unit normal, one value per face), so a USD consumer can bound the displaced
//! surface without the prism table. Stage metadata: `upAxis`, `metersPerUnit`, `defaultPrim`.
//!
//! The text is written here rather than with openusd 0.6, whose `.usdc` writer produces files
//! Pixar USD cannot read; the file is written atomically (temp file + rename).

use crate::asset::Prepared;
use crate::error::Result;
use crate::heightmap::Wrap;
use crate::mesh::UpAxis;
use crate::prism_file;
use glam::Vec3;
use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

/// Write `prepared` as a `.usda` layer at `out`.
pub fn write_usda(prepared: &Prepared, out: &Path) -> Result<()> {
    prism_file::write_atomic(out, to_usda(prepared, out).as_bytes())
}

/// The `.usda` text for `prepared`, with the map's path written relative to `out`'s folder.
pub fn to_usda(prepared: &Prepared, out: &Path) -> String {
    let t = &prepared.table;
    let spec = &prepared.spec;
    let root = prim_name(&spec.mesh);
    let texture = spec
        .disp
        .as_deref()
        .map(|m| asset_path_from(out, m))
        .unwrap_or_default();
    let up = match prepared.mesh.up_axis.unwrap_or_default() {
        UpAxis::Y => "Y",
        UpAxis::Z => "Z",
    };
    // Extent of what renders: the base points and every prism's shell (displaced surface).
    let (mut lo, mut hi) = t.bounds();
    for &p in &t.positions {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let (s, m) = (t.params.scale, t.params.midlevel);
    let channel = match spec
        .channel
        .as_deref()
        .map(str::to_ascii_uppercase)
        .as_deref()
    {
        Some("G") => "g",
        Some("B") => "b",
        Some("A") => "a",
        _ => "r",
    };
    let wrap = match t.wrap {
        Wrap::Repeat => "repeat",
        Wrap::Clamp => "clamp",
    };
    let mat = format!("/{root}/Materials/Displaced");
    let mut o = String::with_capacity(64 * (t.positions.len() + t.prisms.len()) + 4096);
    let doc = format!("prismbake export of {}", file_name(&spec.mesh));
    let _ = write!(
        o,
        "#usda 1.0\n(\n    defaultPrim = \"{root}\"\n    doc = \"{}\"\n    metersPerUnit = 1\n    upAxis = \"{up}\"\n)\n\n",
        escape(&doc)
    );
    let _ = write!(
        o,
        "def Xform \"{root}\" (\n    kind = \"component\"\n)\n{{\n"
    );
    let _ = write!(o, "    def Mesh \"Mesh\" (\n        prepend apiSchemas = [\"MaterialBindingAPI\"]\n    )\n    {{\n");
    let _ = writeln!(o, "        float3[] extent = [{}, {}]", v3(lo), v3(hi));
    let _ = writeln!(
        o,
        "        int[] faceVertexCounts = [{}]",
        join(t.prisms.iter().map(|_| "3".to_string()))
    );
    let _ = writeln!(
        o,
        "        int[] faceVertexIndices = [{}]",
        join(t.prisms.iter().flat_map(|p| p.tri).map(|i| i.to_string()))
    );
    let _ = writeln!(o, "        rel material:binding = <{mat}>");
    let _ = writeln!(
        o,
        "        normal3f[] normals = [{}] (\n            interpolation = \"vertex\"\n        )",
        join(t.normals.iter().map(|&n| v3(n)))
    );
    let _ = writeln!(
        o,
        "        point3f[] points = [{}]",
        join(t.positions.iter().map(|&p| v3(p)))
    );
    let _ = writeln!(
        o,
        "        float[] primvars:prismbake:wmax = [{}] (\n            interpolation = \"uniform\"\n        )",
        join(t.prisms.iter().map(|p| f(p.d_max)))
    );
    let _ = writeln!(
        o,
        "        float[] primvars:prismbake:wmin = [{}] (\n            interpolation = \"uniform\"\n        )",
        join(t.prisms.iter().map(|p| f(p.d_min)))
    );
    let _ = writeln!(
        o,
        "        texCoord2f[] primvars:st = [{}] (\n            interpolation = \"vertex\"\n        )",
        join(t.uvs.iter().map(|uv| format!("({}, {})", f(uv.x), f(uv.y))))
    );
    let _ = writeln!(
        o,
        "        uniform token subdivisionScheme = \"none\"\n    }}\n"
    );
    let color = prepared
        .mesh
        .materials
        .first()
        .map_or([0.8, 0.8, 0.8, 1.0], |m| m.base_color);
    let _ = write!(
        o,
        r#"    def Scope "Materials"
    {{
        def Material "Displaced"
        {{
            token outputs:displacement.connect = <{mat}/PreviewSurface.outputs:displacement>
            token outputs:surface.connect = <{mat}/PreviewSurface.outputs:surface>

            def Shader "PreviewSurface"
            {{
                uniform token info:id = "UsdPreviewSurface"
                color3f inputs:diffuseColor = ({}, {}, {})
                float inputs:displacement.connect = <{mat}/HeightMap.outputs:{channel}>
                token outputs:displacement
                token outputs:surface
            }}

            def Shader "HeightMap"
            {{
                uniform token info:id = "UsdUVTexture"
                float4 inputs:bias = ({b}, {b}, {b}, 0)
                asset inputs:file = @{}@
                float4 inputs:scale = ({s}, {s}, {s}, 1)
                token inputs:sourceColorSpace = "raw"
                float2 inputs:st.connect = <{mat}/StReader.outputs:result>
                token inputs:wrapS = "{wrap}"
                token inputs:wrapT = "{wrap}"
                float outputs:{channel}
            }}

            def Shader "StReader"
            {{
                uniform token info:id = "UsdPrimvarReader_float2"
                string inputs:varname = "st"
                float2 outputs:result
            }}
        }}
    }}
}}
"#,
        f(color[0]),
        f(color[1]),
        f(color[2]),
        texture.replace('@', "%40"),
        b = f(-m * s),
        s = f(s),
    );
    o
}

/// Shortest text that reads back as the same f32 (Rust's `Display` round-trips).
fn f(x: f32) -> String {
    if x == 0.0 {
        "0".into()
    } else {
        format!("{x}")
    }
}

fn v3(p: Vec3) -> String {
    format!("({}, {}, {})", f(p.x), f(p.y), f(p.z))
}

fn join(items: impl Iterator<Item = String>) -> String {
    items.collect::<Vec<_>>().join(", ")
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

fn escape(s: &str) -> String {
    s.replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', " ")
}

/// A valid USD prim name from the mesh file's stem (`rock-01.glb` → `rock_01`).
pub fn prim_name(mesh: &Path) -> String {
    let stem = mesh
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut name: String = stem
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if name.is_empty() || name.starts_with(|c: char| c.is_ascii_digit()) {
        name.insert(0, '_');
    }
    name
}

/// The map's path as a USD asset path seen from the layer at `out`: `./rel/path` when a
/// relative path exists (same drive), else absolute; always with forward slashes.
pub fn asset_path_from(out: &Path, map: &Path) -> String {
    let abs = |p: &Path| -> PathBuf {
        std::fs::canonicalize(p).unwrap_or_else(|_| {
            std::env::current_dir()
                .map(|d| d.join(p))
                .unwrap_or_else(|_| p.to_path_buf())
        })
    };
    let dir = out
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let (map_abs, dir_abs) = (abs(map), abs(dir));
    let a: Vec<Component> = map_abs.components().collect();
    let b: Vec<Component> = dir_abs.components().collect();
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if common == 0 {
        return map_abs.to_string_lossy().replace('\\', "/");
    }
    let ups = b.len() - common;
    let mut parts: Vec<String> = vec![if ups == 0 { "." } else { ".." }.into()];
    parts.extend(std::iter::repeat_n("..".to_string(), ups.saturating_sub(1)));
    parts.extend(
        a[common..]
            .iter()
            .map(|c| c.as_os_str().to_string_lossy().into_owned()),
    );
    parts.join("/")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prim_names_are_usd_identifiers() {
        assert_eq!(prim_name(Path::new("a/rock-01.glb")), "rock_01");
        assert_eq!(prim_name(Path::new("3d.obj")), "_3d");
    }

    #[test]
    fn asset_paths_are_relative_to_the_layer() {
        let d = std::env::temp_dir().join(format!("pb_usd_export_{}", std::process::id()));
        std::fs::create_dir_all(d.join("maps")).unwrap();
        std::fs::create_dir_all(d.join("out")).unwrap();
        std::fs::write(d.join("maps/h.png"), b"x").unwrap();
        assert_eq!(
            asset_path_from(&d.join("out/a.usda"), &d.join("maps/h.png")),
            "../maps/h.png"
        );
        assert_eq!(
            asset_path_from(&d.join("a.usda"), &d.join("maps/h.png")),
            "./maps/h.png"
        );
        std::fs::remove_dir_all(&d).unwrap();
    }
}
