//! The `validate` and `inspect` commands' logic: every check of an asset, as data.
//!
//! Checks (one JUnit test case each): `mesh` (readable, finite, in range), `uvs` (present),
//! `uv-range` (inside [0, 1] when the map is clamped), `degenerate-faces`, `inverted-normals`,
//! `sharp-creases`, `map` (readable), `finite-values` (no NaN/Inf texels), `max-displacement`,
//! `seam-jump` (the height map's jump across UV seams, which `--seams open` renders as cracks),
//! `textures` (the materials' values are numbers, their base-colour textures are there and
//! decode, and the beauty reads them).

use crate::asset::{self, AssetSpec, Overrides};
use crate::bake::PrismTable;
use crate::error::Result;
use crate::heightmap::{HeightMap, Wrap};
use crate::load;
use crate::mesh::BaseMesh;
use crate::prism_file;
use crate::render::env::{EnvFrame, EnvMap};
use crate::render::lookdev::{
    self, check_material_values, grey_normal_map, texture_notes, texture_readable, LookdevOptions,
    MaterialDescription,
};
use crate::repair::{self, RepairOptions, RepairReport};
use crate::report::{AssetReport, Check};
use crate::seam::{measure_seams, SeamReport};
use crate::texture::{ColorMap, TextureSlot};
use glam::{Vec2, Vec3};
use serde::Serialize;
use std::path::Path;

pub const CHECKS: [&str; 11] = [
    "mesh",
    "uvs",
    "uv-range",
    "degenerate-faces",
    "inverted-normals",
    "sharp-creases",
    "map",
    "finite-values",
    "max-displacement",
    "seam-jump",
    "textures",
];

/// `seam-jump` fails above this jump, as a fraction of `|scale|` (`max_seam_jump` in the
/// sidecar, `--max-seam-jump` on the command line): 2% of the scale is a step a lookdev
/// render shows as a line wherever seams are left open, and a map painted or baked with
/// seam-aware padding stays far below it.
pub const DEFAULT_MAX_SEAM_JUMP: f32 = 0.02;
/// Worst seam edges listed by the check.
const WORST_SEAMS: usize = 10;

fn skip_rest(checks: &mut Vec<Check>, why: &str) {
    for name in CHECKS.iter().skip(checks.len()) {
        checks.push(Check::skipped(name, why));
    }
}

fn faces_of(corners: &[repair::CornerFinding]) -> Vec<u32> {
    let mut f: Vec<u32> = corners.iter().map(|c| c.face).collect();
    f.dedup();
    f
}

/// Run every check on one asset; never fails (failures are checks).
pub fn validate_asset(mesh_path: &Path, flags: &Overrides, ropts: &RepairOptions) -> AssetReport {
    let mut checks = Vec::new();
    let name = mesh_path.display().to_string();
    let spec = match asset::resolve(mesh_path, flags) {
        Ok(s) => s,
        Err(e) => {
            checks.push(Check::fail("mesh", e.to_string()));
            skip_rest(&mut checks, "the asset's settings could not be read");
            return AssetReport {
                asset: name,
                checks,
            };
        }
    };
    let mesh = match load::load_mesh(&spec.mesh, &spec.mesh_options()) {
        Ok(m) => m,
        Err(e) => {
            checks.push(Check::fail("mesh", e.to_string()));
            skip_rest(&mut checks, "the mesh could not be read");
            return AssetReport {
                asset: name,
                checks,
            };
        }
    };
    checks.push(Check::pass(
        "mesh",
        format!(
            "{} triangles, {} vertices",
            mesh.triangle_count(),
            mesh.vertex_count()
        ),
    ));
    checks.push(if mesh.missing_uvs {
        Check::fail(
            "uvs",
            format!(
                "no UV coordinates (TEXCOORD_{}): unwrap the mesh and re-export",
                spec.uv_set
            ),
        )
    } else {
        Check::pass("uvs", "present")
    });
    checks.push(uv_range_check(&mesh, spec.wrap));
    let (repaired, report) = repair::repair(mesh.clone(), ropts);
    checks.extend(repair_checks(&report));
    let (map_results, map) = map_checks(&spec);
    checks.extend(map_results);
    checks.push(match &map {
        Some(map) => seam_check(&spec, &repaired, &report, map),
        None => Check::skipped("seam-jump", "no map"),
    });
    checks.push(texture_check(&mesh, spec.uv_set));
    AssetReport {
        asset: name,
        checks,
    }
}

/// The materials the beauty shades with: their values must be numbers (a NaN or infinite base
/// colour, roughness or metallic fails), and each texture the beauty reads must decode (a
/// missing file, a corrupt or unsupported image fails); one it does not read (another UV set,
/// a texture transform) is a warning. So must the USD dome light's texture, which lights the
/// beauty (a render without `--env` would fail on it).
fn texture_check(mesh: &BaseMesh, uv_set: u32) -> Check {
    let mut read = vec![];
    let mut failures = vec![];
    let mut warnings = vec![];
    for m in &mesh.materials {
        if let Err(e) = check_material_values(mesh, m, &LookdevOptions::default()) {
            failures.push(e.to_string());
        }
        warnings.extend(texture_notes(m, uv_set, &|_| true));
        for (slots, t) in m.texture_uses() {
            if !texture_readable(t, uv_set) {
                continue;
            }
            match ColorMap::load(&mesh.source, t, slots[0]) {
                Ok(c)
                    if (slots.contains(&TextureSlot::Normal)
                        || slots.contains(&TextureSlot::ClearcoatNormal))
                        && c.is_grey() =>
                {
                    warnings.push(format!("material '{}': {}", m.name, grey_normal_map(t)))
                }
                Ok(c) => {
                    let uses: Vec<&str> = slots.iter().map(|s| s.name()).collect();
                    read.push(format!(
                        "'{}' {}x{} ({})",
                        c.name,
                        c.width,
                        c.height,
                        uses.join(", ")
                    ))
                }
                Err(e) => failures.push(format!("material '{}': {e}", m.name)),
            }
        }
    }
    if let Some((dome, texture)) = mesh
        .dome
        .as_ref()
        .and_then(|d| Some((d, d.texture.as_ref()?)))
    {
        let frame = EnvFrame {
            z_up: false,
            rotation: 0.0,
        };
        match EnvMap::load(texture, 1.0, frame) {
            Ok(env) => read.push(format!(
                "dome light {}: '{}' {}x{}",
                dome.name,
                texture.display(),
                env.width,
                env.height
            )),
            Err(e) => failures.push(format!("dome light {}: its texture: {e}", dome.name)),
        }
    }
    if !failures.is_empty() {
        return Check::fail("textures", failures.join("; "));
    }
    if !warnings.is_empty() {
        return Check::warn("textures", warnings.join("; "));
    }
    match read.len() {
        0 => Check::pass("textures", "no textures"),
        n => Check::pass(
            "textures",
            format!("{n} texture(s) decode: {}", read.join(", ")),
        ),
    }
}

fn uv_range_check(mesh: &BaseMesh, wrap: Wrap) -> Check {
    if wrap == Wrap::Repeat || mesh.missing_uvs {
        return Check::pass("uv-range", "map repeats: any UV is valid");
    }
    let eps = 1e-6;
    let outside = |uv: Vec2| uv.x < -eps || uv.y < -eps || uv.x > 1.0 + eps || uv.y > 1.0 + eps;
    let faces: Vec<u32> = (0..mesh.triangle_count())
        .filter(|&t| mesh.corner_uvs(t).iter().any(|&uv| outside(uv)))
        .map(|t| t as u32)
        .collect();
    if faces.is_empty() {
        Check::pass("uv-range", "all UVs inside [0, 1]")
    } else {
        Check::fail(
            "uv-range",
            format!("{} faces have UVs outside [0, 1] while the map is clamped: use --wrap repeat or fix the UV layout", faces.len()),
        )
        .with_faces(faces)
    }
}

fn repair_checks(r: &RepairReport) -> Vec<Check> {
    let mut out = Vec::new();
    let mut bad: Vec<u32> = r
        .zero_area_faces
        .iter()
        .chain(&r.invalid_faces)
        .cloned()
        .collect();
    bad.sort_unstable();
    out.push(if !bad.is_empty() {
        Check::fail(
            "degenerate-faces",
            format!(
                "{} zero-area or invalid faces (dropped on bake; delete them or merge by distance)",
                bad.len()
            ),
        )
        .with_faces(bad)
    } else if !r.uv_degenerate_faces.is_empty() {
        Check::warn(
            "degenerate-faces",
            format!(
                "{} faces have zero UV area (the map is sampled along a line across them)",
                r.uv_degenerate_faces.len()
            ),
        )
        .with_faces(r.uv_degenerate_faces.clone())
    } else {
        Check::pass("degenerate-faces", "none")
    });
    out.push(if r.inverted_corners.is_empty() {
        Check::pass("inverted-normals", "every vertex normal faces the same side as its faces")
    } else {
        Check::fail(
            "inverted-normals",
            format!(
                "{} face corners have a vertex normal facing away from the face (n·N_g ≤ 0): recalculate normals outside",
                r.inverted_corners.len()
            ),
        )
        .with_faces(faces_of(&r.inverted_corners))
    });
    // Corners whose normal faces away are the inverted-normals check's; don't report them twice.
    let unresolved: Vec<repair::CornerFinding> = r
        .unresolved_crease_corners
        .iter()
        .filter(|c| c.dot > 0.0)
        .cloned()
        .collect();
    out.push(if !unresolved.is_empty() {
        Check::fail(
            "sharp-creases",
            format!(
                "{} sharp corners cannot be repaired (a crease ends inside the mesh): mark the whole edge loop sharp or bevel it",
                unresolved.len()
            ),
        )
        .with_faces(faces_of(&unresolved))
    } else if !r.sharp_corners.is_empty() {
        Check::warn(
            "sharp-creases",
            format!(
                "{} sharp corners on {} crease edges: bake splits {} vertices and inserts {} stitching triangles",
                r.sharp_corners.len(),
                r.crease_edges.len(),
                r.split_vertices.len(),
                r.inserted_triangles
            ),
        )
        .with_faces(faces_of(&r.sharp_corners))
    } else {
        Check::pass("sharp-creases", "none")
    });
    out
}

fn map_checks(spec: &AssetSpec) -> (Vec<Check>, Option<HeightMap>) {
    let disp = match spec.require_disp() {
        Ok(d) => d.to_path_buf(),
        Err(e) => {
            return (
                vec![
                    Check::fail("map", e.to_string()),
                    Check::skipped("finite-values", "no map"),
                    Check::skipped("max-displacement", "no map"),
                ],
                None,
            )
        }
    };
    let map = match load::load_height_map(&disp, &spec.map_options()) {
        Ok(m) => m,
        Err(e) => {
            return (
                vec![
                    Check::fail("map", e.to_string()),
                    Check::skipped("finite-values", "the map could not be read"),
                    Check::skipped("max-displacement", "the map could not be read"),
                ],
                None,
            )
        }
    };
    let mut out = vec![Check::pass(
        "map",
        format!("{}x{} channel {}", map.width, map.height, map.channel),
    )];
    out.push(match map.first_non_finite() {
        Some((x, y)) => {
            let n = map.data.iter().filter(|v| !v.is_finite()).count();
            Check::fail(
                "finite-values",
                format!(
                    "{}: {n} texels are NaN or infinite, the first at ({x}, {y}): fix the map",
                    disp.display()
                ),
            )
        }
        None => Check::pass("finite-values", "all texels finite"),
    });
    out.push(max_disp_check(spec, &map));
    (out, Some(map))
}

/// The height jump across every UV seam of the repaired mesh (`seam::measure_seams`).
fn seam_check(spec: &AssetSpec, mesh: &BaseMesh, report: &RepairReport, map: &HeightMap) -> Check {
    if mesh.seams.is_empty() {
        return Check::pass("seam-jump", "no UV seams");
    }
    let m = measure_seams(
        &mesh.uvs,
        &mesh.triangles,
        &mesh.seams,
        &spec.params,
        map,
        spec.wrap,
        WORST_SEAMS,
    );
    let limit = spec.max_seam_jump.unwrap_or(DEFAULT_MAX_SEAM_JUMP);
    let summary = format!(
        "{} seam edges ({} wrap seams), height jump max {:.6} ({:.2}% of |scale|), RMS {:.6}",
        m.seam_edges,
        m.wrap_seams,
        m.max_jump,
        100.0 * m.max_jump_rel,
        m.rms_jump
    );
    let worst: Vec<String> = m
        .worst
        .iter()
        .map(|&(i, j)| {
            let f = report.seams[i].faces;
            let name = |x: u32| {
                if x == u32::MAX {
                    "an inserted face".to_string()
                } else {
                    format!("face {x}")
                }
            };
            format!("{} | {}: {j:.6}", name(f[0]), name(f[1]))
        })
        .collect();
    // The input faces of the worst edges, for the add-on to select.
    let mut faces: Vec<u32> = m
        .worst
        .iter()
        .flat_map(|&(i, _)| report.seams[i].faces)
        .filter(|&f| f != u32::MAX)
        .collect();
    faces.sort_unstable();
    faces.dedup();
    let edges: Vec<[u32; 2]> = m
        .worst
        .iter()
        .map(|&(i, _)| report.seams[i].faces)
        .filter(|f| f[0] != u32::MAX && f[1] != u32::MAX)
        .collect();
    if m.max_jump_rel > limit {
        Check::fail(
            "seam-jump",
            format!(
                "{summary}, above the limit of {:.2}%: the map is not seam-safe (worst edges: {}); \
                 bake or paint the map with seam padding, or render with --seams stitch (the default)",
                100.0 * limit,
                worst.join(", ")
            ),
        )
        .with_faces(faces)
        .with_seam_edges(edges)
    } else {
        Check::pass("seam-jump", format!("{summary} ≤ {:.2}%", 100.0 * limit))
    }
}

fn max_disp_check(spec: &AssetSpec, map: &HeightMap) -> Check {
    let (lo, hi) = finite_range(map);
    let (dlo, dhi) = spec.params.displacement_range(lo, hi);
    let peak = dlo.abs().max(dhi.abs());
    match spec.max_disp {
        Some(limit) if peak > limit => Check::fail(
            "max-displacement",
            format!("|D| reaches {peak:.6} (range {dlo:.6} .. {dhi:.6}), above the limit {limit}: lower --scale or raise max_disp"),
        ),
        Some(limit) => Check::pass("max-displacement", format!("|D| ≤ {peak:.6} ≤ {limit}")),
        None => Check::pass("max-displacement", format!("D in {dlo:.6} .. {dhi:.6} (no limit set)")),
    }
}

fn finite_range(map: &HeightMap) -> (f32, f32) {
    map.data
        .iter()
        .filter(|v| v.is_finite())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        })
}

#[derive(Debug, Serialize)]
pub struct MapInfo {
    pub path: String,
    pub width: u32,
    pub height: u32,
    pub channel: String,
    pub value_min: f32,
    pub value_max: f32,
    pub displacement_min: f32,
    pub displacement_max: f32,
}

#[derive(Debug, Serialize)]
pub struct InspectInfo {
    pub mesh: String,
    pub triangles: usize,
    pub vertices: usize,
    pub groups: Vec<String>,
    pub uv_sets: Vec<u32>,
    pub has_uvs: bool,
    pub uv_min: [f32; 2],
    pub uv_max: [f32; 2],
    /// Fraction of UV area (sum over faces) inside the unit square's footprint of [0, 1]².
    pub uv_faces_inside_unit_square: f32,
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    pub camera: bool,
    /// The file's cameras, by the name messages show (the first is rendered unless
    /// `--camera` names another).
    pub cameras: Vec<String>,
    /// The file's dome light (USD) the beauty lights with unless `--env` is given: its prim
    /// path and texture.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dome_light: Option<String>,
    /// The file's directional light (a USD `DistantLight`, a glTF `KHR_lights_punctual` one),
    /// the key light unless `--key-light` is given: its name and `--key-light`'s terms.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub directional_light: Option<String>,
    /// The file's other lights the beauty renders beside the key (`SceneLight::describe`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub lights: Vec<String>,
    pub sharp_corners: usize,
    pub crease_edges: usize,
    pub inverted_corners: usize,
    pub zero_area_faces: usize,
    pub triangles_after_repair: usize,
    pub vertices_after_repair: usize,
    pub estimated_table_bytes: usize,
    pub map: Option<MapInfo>,
    /// UV seams of the repaired mesh and their height jump (with a map).
    pub seam_edges: usize,
    pub seams: Option<SeamReport>,
    /// The file's materials as the beauty reads them (docs/materials.md), with their triangle
    /// counts; triangles without one are `default` (listed when there are some).
    pub materials: Vec<MaterialInfo>,
}

#[derive(Debug, Serialize)]
pub struct MaterialInfo {
    pub name: String,
    pub triangles: usize,
    /// Textures by file name (not decoded here: `validate`'s `textures` check does).
    #[serde(flatten)]
    pub material: MaterialDescription,
}

/// "orm.png, channel g".
fn describe_channel_ref(c: &crate::texture::ChannelRef) -> String {
    format!("{}, channel {}", c.texture.name, c.channel_name())
}

/// The materials of `mesh` with their triangle counts, then `default` if some triangle has none.
fn material_infos(mesh: &BaseMesh) -> Vec<MaterialInfo> {
    let mut count = vec![0usize; mesh.materials.len() + 1];
    for t in 0..mesh.triangle_count() {
        count[mesh.face_material(t) as usize] += 1;
    }
    let mut out: Vec<MaterialInfo> = mesh
        .materials
        .iter()
        .zip(&count)
        .map(|(m, &triangles)| MaterialInfo {
            name: m.name.clone(),
            triangles,
            material: MaterialDescription {
                base_color: [m.base_color[0], m.base_color[1], m.base_color[2]],
                roughness: m.roughness,
                metallic: m.metallic,
                specular: m.specular.unwrap_or(lookdev::DEFAULT_SPECULAR),
                specular_tint: m.specular_tint,
                clearcoat: (m.clearcoat > 0.0).then_some([m.clearcoat, m.clearcoat_roughness]),
                clearcoat_texture: (m.clearcoat_texture.as_ref())
                    .filter(|_| m.clearcoat > 0.0)
                    .map(describe_channel_ref),
                clearcoat_roughness_texture: (m.clearcoat_roughness_texture.as_ref())
                    .filter(|_| m.clearcoat > 0.0)
                    .map(describe_channel_ref),
                clearcoat_normal_texture: (m.clearcoat_normal_texture.as_ref())
                    .filter(|_| m.clearcoat > 0.0)
                    .map(|n| format!("{}, {}", n.texture.name, n.describe_mapping())),
                texture: m.base_color_texture.as_ref().map(|t| t.name.clone()),
                roughness_texture: m.roughness_texture.as_ref().map(describe_channel_ref),
                metallic_texture: m.metallic_texture.as_ref().map(describe_channel_ref),
                normal_texture: m
                    .normal_texture
                    .as_ref()
                    .map(|n| format!("{}, {}", n.texture.name, n.describe_mapping())),
                emission: (m.emission != [0.0; 3]).then_some(m.emission),
                emission_texture: m
                    .emission_texture
                    .as_ref()
                    .filter(|_| m.emission != [0.0; 3])
                    .map(|t| t.name.clone()),
                alpha: lookdev::describe_alpha(
                    m,
                    m.alpha_texture.as_ref().map(|c| c.texture.name.clone()),
                ),
            },
        })
        .collect();
    let none = count[mesh.materials.len()];
    if none > 0 {
        out.push(MaterialInfo {
            name: "default".into(),
            triangles: none,
            material: MaterialDescription {
                base_color: lookdev::DEFAULT_BASE_COLOR.to_array(),
                roughness: lookdev::DEFAULT_ROUGHNESS,
                metallic: lookdev::DEFAULT_METALLIC,
                specular: lookdev::DEFAULT_SPECULAR,
                specular_tint: None,
                clearcoat: None,
                clearcoat_texture: None,
                clearcoat_roughness_texture: None,
                clearcoat_normal_texture: None,
                texture: None,
                roughness_texture: None,
                metallic_texture: None,
                normal_texture: None,
                emission: None,
                emission_texture: None,
                alpha: None,
            },
        });
    }
    out
}

impl InspectInfo {
    pub fn to_text(&self) -> String {
        let mut s = format!(
            "mesh      {}\nfaces     {} triangles, {} vertices, {} groups\nUVs       {} (sets {:?}), range ({:.3}, {:.3}) .. ({:.3}, {:.3}), {:.1}% of faces inside [0,1]²\nbounds    ({:.4}, {:.4}, {:.4}) .. ({:.4}, {:.4}, {:.4})\ncamera    {}\ncreases   {} sharp corners on {} crease edges; {} inverted corners; {} zero-area faces\nrepaired  {} triangles, {} vertices\ntable     ~{} bytes ({:.1} bytes/triangle)\n",
            self.mesh, self.triangles, self.vertices, self.groups.len(),
            if self.has_uvs { "present" } else { "MISSING" }, self.uv_sets,
            self.uv_min[0], self.uv_min[1], self.uv_max[0], self.uv_max[1], 100.0 * self.uv_faces_inside_unit_square,
            self.bounds_min[0], self.bounds_min[1], self.bounds_min[2], self.bounds_max[0], self.bounds_max[1], self.bounds_max[2],
            if self.cameras.is_empty() {
                "none (framing from bounds)".to_string()
            } else {
                let names: Vec<String> = self.cameras.iter().map(|n| format!("'{n}'")).collect();
                format!("{} (the first is rendered unless --camera names another)", names.join(", "))
            },
            self.sharp_corners, self.crease_edges, self.inverted_corners, self.zero_area_faces,
            self.triangles_after_repair, self.vertices_after_repair,
            self.estimated_table_bytes, self.estimated_table_bytes as f32 / self.triangles_after_repair.max(1) as f32,
        );
        if let Some(d) = &self.dome_light {
            s.push_str(&format!(
                "dome      {d} (lights the beauty unless --env is given)\n"
            ));
        }
        if let Some(d) = &self.directional_light {
            s.push_str(&format!(
                "key       {d} (the key light unless --key-light is given)\n"
            ));
        }
        for l in &self.lights {
            s.push_str(&format!("light     {l}\n"));
        }
        if let Some(m) = &self.map {
            s.push_str(&format!(
                "map       {} {}x{} channel {}, values {:.4} .. {:.4}, displacement {:.5} .. {:.5}\n",
                m.path, m.width, m.height, m.channel, m.value_min, m.value_max, m.displacement_min, m.displacement_max
            ));
        }
        match &self.seams {
            Some(j) => s.push_str(&format!(
                "seams     {} UV seam edges ({} wrap), height jump max {:.6} ({:.2}% of |scale|), RMS {:.6}\n",
                j.seam_edges, j.wrap_seams, j.max_jump, 100.0 * j.max_jump_rel, j.rms_jump
            )),
            None => s.push_str(&format!("seams     {} UV seam edges\n", self.seam_edges)),
        }
        for m in &self.materials {
            let what = m.material.describe();
            s.push_str(&format!(
                "material  '{}': {} triangles, {what}\n",
                m.name, m.triangles
            ));
        }
        s
    }
}

/// glTF TEXCOORD sets present on every triangle primitive (OBJ: [0] if it has vt).
fn uv_sets(mesh: &BaseMesh) -> Vec<u32> {
    if load::extension(&mesh.source) == "obj" {
        return if mesh.missing_uvs { vec![] } else { vec![0] };
    }
    let Ok(doc) = gltf::Gltf::open(&mesh.source) else {
        return vec![];
    };
    let mut sets: Vec<u32> = (0..8)
        .filter(|&n| {
            doc.meshes()
                .flat_map(|m| m.primitives().collect::<Vec<_>>())
                .all(|p| {
                    p.attributes()
                        .any(|(s, _)| s == gltf::Semantic::TexCoords(n))
                })
        })
        .collect();
    sets.dedup();
    sets
}

pub fn inspect(spec: &AssetSpec, ropts: &RepairOptions) -> Result<InspectInfo> {
    let mesh = load::load_mesh(&spec.mesh, &spec.mesh_options())?;
    let (lo, hi) = mesh.bounds();
    let (uv_lo, uv_hi) = mesh
        .uvs
        .iter()
        .fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(a, b), &u| {
            (a.min(u), b.max(u))
        });
    let inside = (0..mesh.triangle_count())
        .filter(|&t| {
            mesh.corner_uvs(t)
                .iter()
                .all(|u| u.x >= -1e-6 && u.y >= -1e-6 && u.x <= 1.0 + 1e-6 && u.y <= 1.0 + 1e-6)
        })
        .count();
    let (repaired, report) = repair::repair(mesh.clone(), ropts);
    let mut seams = None;
    let map = match &spec.disp {
        Some(d) => {
            let m = load::load_height_map(d, &spec.map_options())?;
            let (vmin, vmax) = finite_range(&m);
            let (dmin, dmax) = spec.params.displacement_range(vmin, vmax);
            seams = Some(measure_seams(
                &repaired.uvs,
                &repaired.triangles,
                &repaired.seams,
                &spec.params,
                &m,
                spec.wrap,
                WORST_SEAMS,
            ));
            Some(MapInfo {
                path: d.display().to_string(),
                width: m.width,
                height: m.height,
                channel: m.channel.clone(),
                value_min: vmin,
                value_max: vmax,
                displacement_min: dmin,
                displacement_max: dmax,
            })
        }
        None => None,
    };
    // The map's and the mesh's paths, as a table next to the mesh would hold them.
    let path_len = spec.disp.as_ref().map_or(0, |d| d.to_string_lossy().len())
        + spec.mesh.to_string_lossy().len();
    Ok(InspectInfo {
        mesh: spec.mesh.display().to_string(),
        triangles: mesh.triangle_count(),
        vertices: mesh.vertex_count(),
        groups: mesh.groups.clone(),
        uv_sets: uv_sets(&mesh),
        has_uvs: !mesh.missing_uvs,
        uv_min: uv_lo.to_array(),
        uv_max: uv_hi.to_array(),
        uv_faces_inside_unit_square: inside as f32 / mesh.triangle_count().max(1) as f32,
        bounds_min: lo.to_array(),
        bounds_max: hi.to_array(),
        camera: !mesh.cameras.is_empty(),
        cameras: mesh.cameras.iter().map(|c| c.names[0].clone()).collect(),
        directional_light: mesh.sun.as_ref().map(|l| l.describe(l.angle_deg)),
        lights: mesh.lights.iter().map(|l| l.describe()).collect(),
        dome_light: mesh.dome.as_ref().map(|d| match &d.texture {
            Some(t) => format!("'{}' ({})", d.name, t.display()),
            None => format!("'{}' (no texture)", d.name),
        }),
        sharp_corners: report.sharp_corners.len(),
        crease_edges: report.crease_edges.len(),
        inverted_corners: report.inverted_corners.len(),
        zero_area_faces: report.zero_area_faces.len(),
        triangles_after_repair: repaired.triangle_count(),
        vertices_after_repair: repaired.vertex_count(),
        estimated_table_bytes: prism_file::layout_len(
            repaired.vertex_count(),
            repaired.triangle_count(),
            repaired.seams.len(),
            path_len,
        ),
        map,
        seam_edges: repaired.seams.len(),
        seams,
        materials: material_infos(&mesh),
    })
}

#[derive(Debug, Serialize)]
pub struct TableSummary {
    pub table: String,
    pub reused: bool,
    pub prisms: usize,
    pub flat_prisms: usize,
    pub inserted_prisms: usize,
    /// UV seam edges recorded in the table (stitched by default when traced).
    pub seam_edges: usize,
    pub vertices: usize,
    pub bytes: usize,
    pub bytes_per_prism: f32,
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    pub displacement_min: f32,
    pub displacement_max: f32,
    pub map: String,
    pub map_size: [u32; 2],
    pub input_hash: String,
    /// The mesh file the table was baked from, as the table names it (`null`: a version-2
    /// table, which does not).
    pub mesh: Option<String>,
    /// Whether a render of the table reads that mesh's cameras, materials and lights, or
    /// why not.
    pub mesh_scene: String,
    pub up_axis: crate::mesh::UpAxis,
}

pub fn table_summary(t: &PrismTable, path: &Path, reused: bool) -> TableSummary {
    let bytes = prism_file::encoded_len(t);
    let (lo, hi) = t.bounds();
    let lo = if t.prisms.is_empty() { Vec3::ZERO } else { lo };
    let hi = if t.prisms.is_empty() { Vec3::ZERO } else { hi };
    TableSummary {
        table: path.display().to_string(),
        reused,
        prisms: t.prisms.len(),
        flat_prisms: t.flat_count(),
        inserted_prisms: t
            .prisms
            .iter()
            .filter(|p| p.flags & crate::bake::PRISM_INSERTED != 0)
            .count(),
        seam_edges: t.seams.len(),
        vertices: t.positions.len(),
        bytes,
        bytes_per_prism: bytes as f32 / t.prisms.len().max(1) as f32,
        bounds_min: lo.to_array(),
        bounds_max: hi.to_array(),
        displacement_min: t
            .prisms
            .iter()
            .map(|p| p.d_min)
            .fold(f32::INFINITY, f32::min),
        displacement_max: t
            .prisms
            .iter()
            .map(|p| p.d_max)
            .fold(f32::NEG_INFINITY, f32::max),
        map: t.map_path.clone(),
        map_size: [t.map_width, t.map_height],
        input_hash: t.input_hash.iter().map(|b| format!("{b:02x}")).collect(),
        mesh: (!t.source.mesh_path.is_empty()).then(|| t.source.mesh_path.clone()),
        mesh_scene: match crate::asset::table_mesh_path(t, path) {
            Ok(mesh) => format!(
                "read: a render uses {}'s cameras, materials and lights",
                mesh.display()
            ),
            Err(why) => format!("not read: {why}"),
        },
        up_axis: t.source.up_axis,
    }
}
