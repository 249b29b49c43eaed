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
use crate::mesh::BaseMesh;
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
    Ok(())
}
