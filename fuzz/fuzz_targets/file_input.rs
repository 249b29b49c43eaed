//! The loaders take paths, not bytes: each input is written to one scratch file per
//! process (in /dev/shm when there is one, so the disk is not touched per run).

use std::path::PathBuf;

pub fn scratch_file(ext: &str, data: &[u8]) -> PathBuf {
    let dir = if std::path::Path::new("/dev/shm").is_dir() { PathBuf::from("/dev/shm") } else { std::env::temp_dir() };
    let path = dir.join(format!("prismbake-fuzz-{}.{ext}", std::process::id()));
    std::fs::write(&path, data).expect("scratch file is writable");
    path
}
