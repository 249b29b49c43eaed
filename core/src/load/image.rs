//! stub
use super::MapOptions;
use crate::{heightmap::HeightMap, Result};
pub fn load(_path: &std::path::Path, _opts: &MapOptions) -> Result<HeightMap> {
    todo!()
}
