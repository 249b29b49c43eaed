//! bytes → a .tif file → `load::load_height_map`: any input is a clean `Err` or a value that passed
//! the loader's own checks; a panic, abort or runaway allocation is a bug.
#![no_main]

mod file_input;

use libfuzzer_sys::fuzz_target;
use prismbake::load::{self, MapOptions};

fuzz_target!(|data: &[u8]| {
    let path = file_input::scratch_file("tif", data);
    let _ = load::load_height_map(&path, &MapOptions::default());
});
