//! bytes → a .obj file → load, repair, bake, PDM and reference traces (`pipeline_check`): odd
//! geometry (slivers, collinear or coincident corners, folds, huge and tiny coordinates) must
//! give a clean load error or true hits; a panic, abort or non-finite hit is a bug.
#![no_main]

mod file_input;
mod pipeline_check;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let path = file_input::scratch_file("obj", data);
    let _ = pipeline_check::check(&path);
});
