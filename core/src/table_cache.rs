//! A cache of baked prism tables keyed by `asset::input_hash` (mesh bytes, map bytes,
//! parameters, repair options, format version, `asset::PIPELINE_REVISION`), so rendering the
//! same mesh + map again skips
//! repair and bake. Files are `<cache>/prismbake/<hash hex>.prisms`, written atomically; a
//! file that does not read back, or whose stored hash or map size disagree, is ignored (and
//! overwritten by the next bake). Nothing is ever evicted: delete the folder to reclaim space.

use crate::bake::PrismTable;
use crate::error::Result;
use crate::heightmap::HeightMap;
use crate::prism_file;
use std::path::{Path, PathBuf};

/// `$XDG_CACHE_HOME/prismbake`, else `$HOME/.cache/prismbake`; `None` without either.
pub fn default_dir() -> Option<PathBuf> {
    let nonempty = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    nonempty("XDG_CACHE_HOME")
        .or_else(|| nonempty("HOME").map(|h| h.join(".cache")))
        .map(|d| d.join("prismbake"))
}

pub fn path_for(dir: &Path, hash: &[u8; 32]) -> PathBuf {
    let hex: String = hash.iter().map(|b| format!("{b:02x}")).collect();
    dir.join(format!("{hex}.prisms"))
}

/// The cached table for `hash`, if there is a valid one made for a map of `map`'s size.
pub fn load(dir: &Path, hash: &[u8; 32], map: &HeightMap) -> Option<(PrismTable, PathBuf)> {
    let path = path_for(dir, hash);
    let table = prism_file::read(&path).ok()?;
    (table.input_hash == *hash && (table.map_width, table.map_height) == (map.width, map.height))
        .then_some((table, path))
}

/// Store `table` under its own input hash; returns the file written.
pub fn store(dir: &Path, table: &PrismTable) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).map_err(|e| crate::Error::io(dir, e))?;
    let path = path_for(dir, &table.input_hash);
    prism_file::write(&path, table)?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::fixtures::*;

    #[test]
    fn stores_and_reuses_only_the_same_inputs() {
        let dir = std::env::temp_dir().join(format!("prismbake-cache-test-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let map = relief_map(16);
        let mut t = table(&sphere_mesh(1, 0.1), &map, 0.05);
        t.input_hash = [7; 32];
        store(&dir, &t).unwrap();
        let (back, _) = load(&dir, &[7; 32], &map).expect("reused");
        assert_eq!(back.prisms, t.prisms);
        assert!(
            load(&dir, &[8; 32], &map).is_none(),
            "another hash is a miss"
        );
        assert!(
            load(&dir, &[7; 32], &relief_map(8)).is_none(),
            "another map size is a miss"
        );
        std::fs::write(path_for(&dir, &[7; 32]), b"garbage").unwrap();
        assert!(
            load(&dir, &[7; 32], &map).is_none(),
            "a broken file is a miss"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
