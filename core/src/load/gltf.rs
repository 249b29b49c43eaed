//! stub
use super::MeshOptions;
use crate::{mesh::BaseMesh, Result};
pub fn load(_path: &std::path::Path, _opts: &MeshOptions) -> Result<BaseMesh> {
    todo!()
}
