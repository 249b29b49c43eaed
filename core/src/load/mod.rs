//! Stage 1: read a mesh file and a height map into `BaseMesh` + `HeightMap`.
//!
//! One UV convention for every loader (v up the image, see `mesh`); the glTF loader flips v.

pub mod gltf;
pub mod image;
pub mod obj;
#[cfg(test)]
mod tests;
pub mod usd;
mod usdc_check;

use crate::error::{Error, Result};
use crate::heightmap::{HeightMap, Wrap};
use crate::mesh::{BaseMesh, NamedCamera, Projection, SceneCamera};
use glam::{Mat4, Vec3};
use std::path::Path;

/// Options for mesh loading.
#[derive(Clone, Debug, Default)]
pub struct MeshOptions {
    /// Which TEXCOORD_n set to read (glTF); OBJ has one.
    pub uv_set: u32,
}

/// Options for height-map loading.
#[derive(Clone, Debug, Default)]
pub struct MapOptions {
    /// Channel name to read from an EXR (default: Y, else R, else the first channel).
    pub channel: Option<String>,
    pub wrap: Wrap,
}

/// Why a scene camera cannot be rendered through, if it cannot: a field of view outside what
/// `--fov` takes (0–179°; glTF requires `yfov` > 0, USD a positive focal length and aperture),
/// an orthographic view whose height is not a positive number, or a position or target that
/// is not finite.
fn camera_fault(c: &SceneCamera) -> Option<String> {
    use crate::render::camera::{usable_fov, MAX_FOV_DEG};
    match c.projection {
        Projection::Perspective { yfov_deg } if !usable_fov(yfov_deg) => {
            return Some(format!(
                "has a vertical field of view of {yfov_deg}° ({} rad), outside 0–{MAX_FOV_DEG}°",
                yfov_deg.to_radians()
            ));
        }
        Projection::Orthographic { height } if !(height.is_finite() && height > 0.0) => {
            return Some(format!(
                "is orthographic with a view {height} units tall (it must be a positive number)"
            ));
        }
        _ => {}
    }
    if !(c.from.is_finite() && c.to.is_finite() && c.up.is_finite()) {
        return Some("is placed at a position that is not finite".into());
    }
    None
}

/// Camera looking down its local -Z with local +Y up (glTF's and USD's convention); the target
/// is the mesh centre projected on the view axis, at least one unit ahead. An orthographic
/// view's height (in the camera's own units) is scaled as the transform scales its +Y, and its
/// film aspect as it scales its +X against its +Y.
fn scene_camera(
    mesh: &BaseMesh,
    world: Mat4,
    projection: Projection,
    film_aspect: Option<f32>,
    larger_side: bool,
) -> SceneCamera {
    let from = world.transform_point3(Vec3::ZERO);
    let forward = world
        .transform_vector3(Vec3::NEG_Z)
        .try_normalize()
        .unwrap_or(Vec3::NEG_Z);
    let local_up = world.transform_vector3(Vec3::Y);
    let up = local_up.try_normalize().unwrap_or(Vec3::Y);
    let (lo, hi) = mesh.bounds();
    let distance = ((lo + hi) * 0.5 - from).dot(forward).max(1.0);
    let orthographic = matches!(projection, Projection::Orthographic { .. });
    SceneCamera {
        from,
        to: from + forward * distance,
        up,
        projection: match projection {
            Projection::Orthographic { height } => Projection::Orthographic {
                height: height * local_up.length(),
            },
            perspective => perspective,
        },
        film_aspect: film_aspect.map(|a| match orthographic {
            true => a * world.transform_vector3(Vec3::X).length() / local_up.length(),
            false => a,
        }),
        larger_side: larger_side && orthographic,
    }
}

/// Add to `mesh`'s cameras the scene camera `names` at `world` with `projection` (an
/// orthographic height in the camera's own units), `film_aspect` and `larger_side`
/// (`SceneCamera`), once its geometry is loaded; one that cannot be rendered through is left
/// out with a warning.
pub(crate) fn attach_camera(
    mesh: &mut BaseMesh,
    mut names: Vec<String>,
    world: Mat4,
    projection: Projection,
    film_aspect: Option<f32>,
    larger_side: bool,
) {
    let camera = scene_camera(mesh, world, projection, film_aspect, larger_side);
    let mut seen = std::collections::HashSet::new();
    names.retain(|n| seen.insert(n.clone()));
    match camera_fault(&camera) {
        None => mesh.cameras.push(NamedCamera { names, camera }),
        // Such a camera renders a degenerate or flipped picture (a yfov of 0 sends every
        // ray one way, a negative one turns the image over): framed from the bounds instead.
        Some(fault) => eprintln!(
            "warning: {}: its camera '{}' {fault}: ignored (fix the camera; without another, the view is framed from the bounds, or set it with --camera-from, --camera-to and --fov)",
            mesh.source.display(),
            names[0]
        ),
    }
}

/// A mesh file may have at most `MAX_MATERIALS` materials (a prism keeps its material's index
/// in 24 bits of its flags).
pub(crate) fn check_material_count(path: &Path, count: usize) -> Result<()> {
    if count > crate::mesh::MAX_MATERIALS {
        return Err(Error::invalid(
            path,
            format!(
                "has {count} materials, more than the {} supported (merge materials)",
                crate::mesh::MAX_MATERIALS
            ),
        ));
    }
    Ok(())
}

/// The bytes of a file an asset names (a glTF buffer or image, an OBJ material library): a
/// regular file only, since a device (`/dev/zero`) would never finish reading.
pub(crate) fn read_named_file(file: &Path) -> std::io::Result<Vec<u8>> {
    if !file.is_file() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            "no such regular file",
        ));
    }
    std::fs::read(file)
}

/// Run `f`, turning a panic into `None`: for third-party readers that may panic on corrupt
/// input (openusd, a JPEG decoder). The panic is expected there, so it prints nothing; every
/// other panic still reaches the hook that was there before.
pub(crate) fn catch_quietly<T>(f: impl FnOnce() -> T) -> Option<T> {
    quiet_panics();
    let was = QUIET.with(|q| q.replace(true));
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    QUIET.with(|q| q.set(was));
    r.ok()
}

thread_local! {
    /// Set while `catch_quietly` runs: a panic on this thread is the reader's, and is caught.
    static QUIET: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Chain a panic hook, once, that stays silent for panics inside `catch_quietly` and hands
/// every other panic to the hook that was there before.
fn quiet_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET.with(|q| q.get()) {
                previous(info);
            }
        }));
    });
}

pub const MESH_EXTENSIONS: &str = ".gltf, .glb, .obj, .usda, .usdc or .usd";

/// Load a mesh by extension.
pub fn load_mesh(path: &Path, opts: &MeshOptions) -> Result<BaseMesh> {
    check_readable_file(path)?;
    let ext = extension(path);
    let mesh = match ext.as_str() {
        "gltf" | "glb" => gltf::load(path, opts)?,
        "obj" => obj::load(path, opts)?,
        "usda" | "usdc" | "usd" => usd::load(path, opts)?,
        "prisms" => {
            return Err(Error::invalid(
                path,
                "is a baked prism table, not a mesh: `render`, `bench` and `inspect` read \
                 tables; for \
                 this command give the mesh it was baked from (`inspect TABLE` names it)",
            ))
        }
        _ => {
            return Err(Error::UnsupportedFormat {
                path: path.into(),
                ext,
                expected: MESH_EXTENSIONS,
            })
        }
    };
    check_mesh(&mesh)?;
    Ok(mesh)
}

/// Load a height map by extension (.exr, .png, .tif/.tiff).
pub fn load_height_map(path: &Path, opts: &MapOptions) -> Result<HeightMap> {
    check_readable_file(path)?;
    image::load(path, opts)
}

pub fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

fn check_readable_file(path: &Path) -> Result<()> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        return Err(Error::invalid(
            path,
            "is a directory, expected a file (give the path of the file itself)",
        ));
    }
    Ok(())
}

/// Checks every loader's result the same way: no triangles, indices out of range, NaN.
pub fn check_mesh(mesh: &BaseMesh) -> Result<()> {
    let path = &mesh.source;
    if mesh.triangles.is_empty() {
        return Err(Error::invalid(
            path,
            "contains zero triangles (export the mesh with its faces, triangulated or as polygons)",
        ));
    }
    let n = mesh.positions.len();
    if mesh.normals.len() != n || mesh.uvs.len() != n {
        return Err(Error::invalid(
            path,
            "internal: attribute arrays differ in length",
        ));
    }
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&i) = tri.iter().find(|&&i| i as usize >= n) {
            return Err(Error::invalid(
                path,
                format!(
                    "{} references vertex {i} but there are only {n} vertices (re-export the mesh)",
                    mesh.face_name(t)
                ),
            ));
        }
    }
    for (what, bad) in [
        (
            "position",
            mesh.positions.iter().position(|p| !p.is_finite()),
        ),
        ("normal", mesh.normals.iter().position(|p| !p.is_finite())),
        ("UV", mesh.uvs.iter().position(|p| !p.is_finite())),
    ] {
        if let Some(v) = bad {
            return Err(Error::invalid(
                path,
                format!("vertex {v} has a NaN or infinite {what} (fix or delete that vertex)"),
            ));
        }
    }
    if let Some(v) = mesh.uvs.iter().position(|t| t.abs().max_element() > MAX_UV) {
        let t = mesh.uvs[v];
        return Err(Error::invalid(
            path,
            format!(
                "vertex {v} has the UV ({}, {}), past ±{MAX_UV}: single precision cannot address \
                 a texel that far out (the UVs are corrupt or wildly tiled; re-export them)",
                t.x, t.y
            ),
        ));
    }
    Ok(())
}

/// The largest |u| or |v| a mesh may have. Past it a 256² map's texel coordinates are
/// 1.7 × 10⁷ and up, where f32 no longer resolves a texel; real tiling stays far below
/// (UDIM tiles reach 10). A fuzzed UV of 2 × 10¹⁹ made the bake walk 10²⁰ texel rows.
pub const MAX_UV: f32 = 65536.0;
