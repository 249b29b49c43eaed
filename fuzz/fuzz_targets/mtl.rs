//! bytes → a .mtl file that a fixed .obj names (`mtllib`, a face under each of two material
//! names) → `load::load_mesh`, then each material's values as the render reads them: any input
//! is a clean `Err` or materials that passed; a panic, abort or runaway allocation is a bug.
#![no_main]

mod file_input;

use libfuzzer_sys::fuzz_target;
use prismbake::load::{self, MeshOptions};
use prismbake::render::lookdev;

fuzz_target!(|data: &[u8]| {
    let mtl = file_input::scratch_file("mtl", data);
    let name = mtl.file_name().and_then(|n| n.to_str()).expect("a UTF-8 scratch name");
    let obj = format!(
        "mtllib {name}\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n\
         usemtl a\nf 1/1 2/2 3/3\nusemtl b\nf 1/1 2/2 3/3\n"
    );
    let obj = file_input::scratch_file("obj", obj.as_bytes());
    if let Ok(mesh) = load::load_mesh(&obj, &MeshOptions::default()) {
        for m in &mesh.materials {
            let _ = lookdev::describe_alpha(m, None);
            let _ = lookdev::check_material_values(&mesh, m, &Default::default());
        }
    }
});
