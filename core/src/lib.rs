//! prismbake: displacement-mapped assets traced without tessellation.
//!
//! The pipeline is the module layout, one stage each, data flowing one way:
//! `load` (mesh + height map) → `repair` → `bake` (prism table) → `accel` → `trace` → `render`
//! → `report`. Each stage takes plain structs and returns plain structs.

pub mod accel;
pub mod asset;
pub mod bake;
pub mod bench;
pub mod canonical;
pub mod error;
pub mod heightmap;
pub mod load;
pub mod mesh;
pub mod prism_file;
pub mod render;
pub mod repair;
pub mod report;
pub mod rng;
pub mod seam;
pub mod sysmem;
pub mod table_cache;
pub mod tangent;
pub mod tessellate;
pub mod texture;
pub mod trace;
pub mod usd_export;
pub mod validate;

#[cfg(test)]
pub(crate) mod test_util;

pub use error::{Error, Result};
pub use heightmap::{DisplaceParams, HeightMap, Wrap};
pub use mesh::BaseMesh;
