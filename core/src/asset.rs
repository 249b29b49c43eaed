//! An asset = a mesh file + its height map and displacement parameters, given by a sidecar
//! file next to the mesh (`rock.glb` → `rock.prismbake.toml`, documented in docs/sidecar.md)
//! and/or command-line flags (flags win). `prepare` runs load → repair → bake, and skips the
//! bake when an existing table was made from the same inputs (same input hash).

use crate::bake::{self, BakeOptions, PrismTable};
use crate::error::{Error, Result};
use crate::heightmap::{DisplaceParams, HeightMap, Wrap};
use crate::load::{self, MapOptions, MeshOptions};
use crate::mesh::BaseMesh;
use crate::prism_file;
use crate::repair::{self, RepairOptions, RepairReport};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

pub const SIDECAR_SUFFIX: &str = ".prismbake.toml";

/// The sidecar file, as written by people; paths relative to the sidecar's folder.
#[derive(Clone, Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Sidecar {
    pub disp: Option<PathBuf>,
    pub scale: Option<f32>,
    pub midlevel: Option<f32>,
    pub wrap: Option<Wrap>,
    pub channel: Option<String>,
    pub uv_set: Option<u32>,
    /// Largest |D| allowed by `validate` (world units).
    pub max_disp: Option<f32>,
    /// Largest height jump across a UV seam allowed by `validate`, as a fraction of the
    /// displacement scale.
    pub max_seam_jump: Option<f32>,
}

/// Settings given on the command line; `None` = take the sidecar's (or the default).
pub type Overrides = Sidecar;

/// Everything needed to load and bake one asset.
#[derive(Clone, Debug, Serialize)]
pub struct AssetSpec {
    pub mesh: PathBuf,
    pub disp: Option<PathBuf>,
    pub params: DisplaceParams,
    pub wrap: Wrap,
    pub channel: Option<String>,
    pub uv_set: u32,
    pub max_disp: Option<f32>,
    pub max_seam_jump: Option<f32>,
    /// The sidecar that was read, if any.
    pub sidecar: Option<PathBuf>,
}

impl AssetSpec {
    pub fn mesh_options(&self) -> MeshOptions {
        MeshOptions {
            uv_set: self.uv_set,
        }
    }
    pub fn map_options(&self) -> MapOptions {
        MapOptions {
            channel: self.channel.clone(),
            wrap: self.wrap,
        }
    }
    /// The height map path, or an error saying how to give one.
    pub fn require_disp(&self) -> Result<&Path> {
        self.disp.as_deref().ok_or_else(|| {
            Error::invalid(
                &self.mesh,
                format!(
                    "no height map given: pass --disp MAP or write `disp = \"map.png\"` in {}",
                    sidecar_path(&self.mesh).display()
                ),
            )
        })
    }
}

pub fn sidecar_path(mesh: &Path) -> PathBuf {
    let stem = mesh
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    mesh.with_file_name(format!("{stem}{SIDECAR_SUFFIX}"))
}

pub fn read_sidecar(path: &Path) -> Result<Sidecar> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut s: Sidecar = toml::from_str(&text).map_err(|e| {
        Error::invalid(
            path,
            format!("{} (see docs/sidecar.md for the fields)", e.message()),
        )
    })?;
    if let Some(d) = &s.disp {
        if d.is_relative() {
            s.disp = Some(path.parent().unwrap_or(Path::new("")).join(d));
        }
    }
    Ok(s)
}

/// Combine the mesh's sidecar (if present) with the command-line overrides.
pub fn resolve(mesh: &Path, flags: &Overrides) -> Result<AssetSpec> {
    let side_path = sidecar_path(mesh);
    let (side, sidecar) = if side_path.is_file() {
        (read_sidecar(&side_path)?, Some(side_path))
    } else {
        (Sidecar::default(), None)
    };
    let side = with_usd_material(mesh, side)?;
    let defaults = DisplaceParams::default();
    let spec = AssetSpec {
        mesh: mesh.to_path_buf(),
        disp: flags.disp.clone().or(side.disp),
        params: DisplaceParams {
            scale: flags.scale.or(side.scale).unwrap_or(defaults.scale),
            midlevel: flags
                .midlevel
                .or(side.midlevel)
                .unwrap_or(defaults.midlevel),
        },
        wrap: flags.wrap.or(side.wrap).unwrap_or_default(),
        channel: flags.channel.clone().or(side.channel),
        uv_set: flags.uv_set.or(side.uv_set).unwrap_or(0),
        max_disp: flags.max_disp.or(side.max_disp),
        max_seam_jump: flags.max_seam_jump.or(side.max_seam_jump),
        sidecar,
    };
    if !spec.params.scale.is_finite() || !spec.params.midlevel.is_finite() {
        return Err(Error::Param(format!(
            "{}: scale and midlevel must be finite numbers",
            mesh.display()
        )));
    }
    Ok(spec)
}

/// A USD mesh's own material is the weakest source of the displacement: it fills only what
/// the sidecar left unset (and the flags override both).
fn with_usd_material(mesh: &Path, mut side: Sidecar) -> Result<Sidecar> {
    if !matches!(load::extension(mesh).as_str(), "usda" | "usdc" | "usd") || !mesh.is_file() {
        return Ok(side);
    }
    let Some(usd) = load::usd::displacement(mesh)? else {
        return Ok(side);
    };
    if side.channel.is_none() && usd.channel != "R" && load::extension(&usd.file) == "exr" {
        side.channel = Some(usd.channel.clone());
    }
    side.disp = side.disp.or(Some(usd.file));
    side.scale = side.scale.or(Some(usd.scale));
    side.midlevel = side.midlevel.or(Some(usd.midlevel));
    side.wrap = side.wrap.or(Some(usd.wrap));
    Ok(side)
}

/// Every mesh file under `root` (sorted, so batch output order is stable).
pub fn find_meshes(root: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = walkdir::WalkDir::new(root)
        .follow_links(true)
        .into_iter()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_type().is_file())
        .map(|e| e.into_path())
        .filter(|p| {
            matches!(
                load::extension(p).as_str(),
                "gltf" | "glb" | "obj" | "usda" | "usdc" | "usd"
            )
        })
        .collect();
    found.sort();
    found
}

/// Expand files and folders into mesh paths.
pub fn expand_paths(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for p in paths {
        let meta = std::fs::metadata(p).map_err(|e| Error::io(p, e))?;
        if meta.is_dir() {
            out.extend(find_meshes(p));
        } else {
            out.push(p.clone());
        }
    }
    Ok(out)
}

/// Revision of what repair and bake make of the same inputs: bump it whenever a change to
/// either gives another table (the file format's `VERSION` only covers the layout), so that
/// tables cached by an older build (`table_cache`) are not served as this build's.
/// 2: crease strips on UV seams keep each side's UV.
/// 3: a crease strip's texel size is at most half its widest rung arc.
/// 4: a prism's flags carry its material (`bake::PRISM_MATERIAL_SHIFT`).
/// 5: normals within `weld::NORMAL_SNAP` at one position are unified before welding.
pub const PIPELINE_REVISION: u32 = 5;

/// blake3 of everything the table depends on.
pub fn input_hash(spec: &AssetSpec, repair: &RepairOptions) -> Result<[u8; 32]> {
    input_hash_at(spec, repair, PIPELINE_REVISION)
}

fn input_hash_at(spec: &AssetSpec, repair: &RepairOptions, revision: u32) -> Result<[u8; 32]> {
    let mut h = blake3::Hasher::new();
    h.update(b"prismbake-table");
    h.update(&prism_file::VERSION.to_le_bytes());
    h.update(&revision.to_le_bytes());
    hash_mesh_files(&mut h, &spec.mesh)?;
    // The map is streamed through the hasher, not read whole: next to the decoded map a
    // second copy of a large file was the load's peak memory.
    let disp = spec.require_disp()?;
    let file = std::fs::File::open(disp).map_err(|e| Error::io(disp, e))?;
    let len = file.metadata().map_err(|e| Error::io(disp, e))?.len();
    h.update(&len.to_le_bytes());
    h.update_reader(file).map_err(|e| Error::io(disp, e))?;
    h.update(&spec.params.scale.to_le_bytes());
    h.update(&spec.params.midlevel.to_le_bytes());
    h.update(&[spec.wrap as u8]);
    h.update(spec.channel.as_deref().unwrap_or("").as_bytes());
    h.update(&spec.uv_set.to_le_bytes());
    h.update(format!("{repair:?}").as_bytes());
    Ok(*h.finalize().as_bytes())
}

/// The mesh file's bytes, and those of every external buffer a glTF names (they change the
/// mesh too), through `h`.
fn hash_mesh_files(h: &mut blake3::Hasher, mesh: &Path) -> Result<()> {
    let mesh_bytes = std::fs::read(mesh).map_err(|e| Error::io(mesh, e))?;
    h.update(&(mesh_bytes.len() as u64).to_le_bytes());
    h.update(&mesh_bytes);
    if load::extension(mesh) == "gltf" {
        if let Ok(doc) = gltf::Gltf::from_slice(&mesh_bytes) {
            for b in doc.buffers() {
                if let gltf::buffer::Source::Uri(uri) = b.source() {
                    if !uri.starts_with("data:") {
                        let p = mesh.parent().unwrap_or(Path::new("")).join(uri);
                        if let Ok(bytes) = std::fs::read(&p) {
                            h.update(&bytes);
                        }
                    }
                }
            }
        }
    }
    Ok(())
}

/// blake3 of the mesh file and its external buffers: what a table keeps to know whether
/// the mesh it was baked from is still the same file (`TableSource::mesh_hash`).
pub fn mesh_hash(mesh: &Path) -> Result<[u8; 32]> {
    let mut h = blake3::Hasher::new();
    h.update(b"prismbake-mesh");
    hash_mesh_files(&mut h, mesh)?;
    Ok(*h.finalize().as_bytes())
}

/// A loaded, repaired and baked asset.
pub struct Prepared {
    pub spec: AssetSpec,
    pub mesh: BaseMesh,
    pub map: HeightMap,
    pub report: RepairReport,
    pub table: PrismTable,
}

/// Load the mesh (refusing meshes without UVs) and the map.
pub fn load(spec: &AssetSpec) -> Result<(BaseMesh, HeightMap)> {
    let mesh = load::load_mesh(&spec.mesh, &spec.mesh_options())?;
    if mesh.missing_uvs {
        return Err(Error::invalid(
            &spec.mesh,
            format!(
                "has no UV coordinates (TEXCOORD_{}); unwrap the mesh (e.g. Blender: UV ▸ Smart UV Project) and re-export",
                spec.uv_set
            ),
        ));
    }
    let map = load::load_height_map(spec.require_disp()?, &spec.map_options())?;
    if let Some((x, y)) = map.first_non_finite() {
        return Err(Error::invalid(
            &map.source,
            format!("texel ({x}, {y}) is NaN or infinite; fix the map (e.g. clamp it in your paint tool)"),
        ));
    }
    Ok((mesh, map))
}

/// load → repair → bake.
pub fn prepare(spec: &AssetSpec, repair_opts: &RepairOptions) -> Result<Prepared> {
    let (mesh, map) = load(spec)?;
    let (mesh, report) = repair::repair(mesh, repair_opts);
    let mut table = bake::bake(
        &mesh,
        &map,
        &BakeOptions {
            params: spec.params,
        },
    );
    table.input_hash = input_hash(spec, repair_opts)?;
    table.source.uv_set = spec.uv_set;
    table.source.mesh_hash = mesh_hash(&spec.mesh)?;
    Ok(Prepared {
        spec: spec.clone(),
        mesh,
        map,
        report,
        table,
    })
}

/// Path of a file (the map, the mesh) as stored in a table written to `table_path`: relative
/// to the table's folder (`../assets/rock.glb`), so that a tree moved whole keeps finding it,
/// unless the two share no folder but the root; then absolute.
pub fn path_for_table(file: &Path, table_path: &Path) -> String {
    let dir = table_path.parent().unwrap_or(Path::new(""));
    let abs = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    let (file_abs, dir_abs) = (
        abs(file),
        abs(if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        }),
    );
    let file_parts: Vec<_> = file_abs.components().collect();
    let dir_parts: Vec<_> = dir_abs.components().collect();
    let shared = file_parts
        .iter()
        .zip(&dir_parts)
        .take_while(|(a, b)| a == b)
        .count();
    let below_root = dir_parts
        .iter()
        .take(shared)
        .filter(|c| matches!(c, std::path::Component::Normal(_)))
        .count();
    if below_root == 0 {
        return file_abs.to_string_lossy().into_owned();
    }
    let mut rel = PathBuf::new();
    for _ in shared..dir_parts.len() {
        rel.push("..");
    }
    rel.extend(&file_parts[shared..]);
    rel.to_string_lossy().into_owned()
}

/// The height map a table was baked from, found from the table's folder.
pub fn table_map_path(table: &PrismTable, table_path: &Path) -> PathBuf {
    from_table(&table.map_path, table_path)
}

/// A path a table stores, found from the table's folder where it is relative.
fn from_table(stored: &str, table_path: &Path) -> PathBuf {
    let p = PathBuf::from(stored);
    match p.is_absolute() {
        true => p,
        false => table_path.parent().unwrap_or(Path::new("")).join(p),
    }
}

/// The mesh file `table` (read from `table_path`) was baked from, where it is still there and
/// unchanged; else why a render of the table goes without its cameras, materials and lights.
pub fn table_mesh_path(
    table: &PrismTable,
    table_path: &Path,
) -> std::result::Result<PathBuf, String> {
    let source = &table.source;
    if source.mesh_path.is_empty() {
        return Err(
            "the table does not name the mesh it was baked from (a version-2 table: \
             re-bake it to render with the mesh's cameras, materials and lights)"
                .into(),
        );
    }
    let mesh = from_table(&source.mesh_path, table_path);
    if !mesh.is_file() {
        return Err(format!(
            "its mesh {} is not there (moved or deleted: put it back, or re-bake the table \
             from where it is now)",
            mesh.display()
        ));
    }
    match mesh_hash(&mesh) {
        Ok(h) if h == source.mesh_hash => Ok(mesh),
        Ok(_) => Err(format!(
            "its mesh {} has changed since the table was baked (re-bake the table)",
            mesh.display()
        )),
        Err(e) => Err(e.to_string()),
    }
}

/// The mesh file `table` was baked from, loaded for what the table does not keep (its
/// cameras, materials, lights); `Err` says why not (`table_mesh_path`, or the file failing
/// to load).
pub fn table_mesh(table: &PrismTable, table_path: &Path) -> std::result::Result<BaseMesh, String> {
    let path = table_mesh_path(table, table_path)?;
    let options = MeshOptions {
        uv_set: table.source.uv_set,
    };
    load::load_mesh(&path, &options).map_err(|e| e.to_string())
}

/// Load a baked table and its height map (found relative to the table, or `disp` if given).
pub fn load_table(
    path: &Path,
    disp: Option<&Path>,
    channel: Option<String>,
) -> Result<(PrismTable, HeightMap)> {
    let table = prism_file::read(path)?;
    let map_path = match disp {
        Some(d) => d.to_path_buf(),
        None => table_map_path(&table, path),
    };
    let map = load::load_height_map(
        &map_path,
        &MapOptions {
            channel,
            wrap: table.wrap,
        },
    )?;
    if (map.width, map.height) != (table.map_width, table.map_height) {
        return Err(Error::invalid(
            path,
            format!(
                "was baked for a {}x{} map but {} is {}x{}; re-bake the table for this map",
                table.map_width,
                table.map_height,
                map_path.display(),
                map.width,
                map.height
            ),
        ));
    }
    Ok((table, map))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_paths_are_relative_below_a_shared_folder() {
        let dir = std::env::temp_dir().join(format!("pb-paths-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("assets/maps")).unwrap();
        std::fs::create_dir_all(dir.join("build")).unwrap();
        let map = dir.join("assets/maps/h.png");
        std::fs::write(&map, b"").unwrap();
        let at = |table: &str| path_for_table(&map, &dir.join(table));
        assert_eq!(at("t.prisms"), "assets/maps/h.png");
        assert_eq!(at("assets/maps/t.prisms"), "h.png");
        assert_eq!(at("build/t.prisms"), "../assets/maps/h.png");
        assert_eq!(at("build/x/t.prisms"), "../../assets/maps/h.png");
        // Sharing only the root: absolute.
        let root_only = path_for_table(Path::new("/"), &dir.join("t.prisms"));
        assert_eq!(root_only, "/");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    // Would break if the cache key lost the pipeline revision: a table baked by an older
    // build's repair would then be served as this build's.
    #[test]
    fn the_table_cache_key_changes_with_the_pipeline_revision() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/rock/rock.glb");
        let spec = resolve(&path, &Overrides::default()).unwrap();
        let opts = RepairOptions::default();
        let now = input_hash(&spec, &opts).unwrap();
        assert_eq!(now, input_hash_at(&spec, &opts, PIPELINE_REVISION).unwrap());
        assert_ne!(
            now,
            input_hash_at(&spec, &opts, PIPELINE_REVISION - 1).unwrap()
        );
    }
}
