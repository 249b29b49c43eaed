//! The host structs and the WGSL agree byte for byte: naga (wgpu's own copy) parses the shader
//! modules and reports each struct's member offsets and size, which must equal `offset_of!` /
//! `size_of` on the Rust side; the sentinels and constants must have the same values on both
//! sides; and every module (AOV, its packet walk, beauty) must pass naga's validator. Breaks on
//! any one-sided edit of a shared struct or constant.

use prismbake_gpu::{layout, shaders};
use wgpu::naga;

fn parse(src: &str) -> naga::Module {
    naga::front::wgsl::parse_str(src).unwrap_or_else(|e| panic!("{}", e.emit_to_string(src)))
}

/// The AOV module (library + aov.wgsl).
fn module() -> naga::Module {
    parse(&shaders::aov_module_source())
}

/// The AOV module walked by packets (library + aov.wgsl + packet.wgsl).
fn packet_module() -> naga::Module {
    parse(&shaders::aov_packet_module_source())
}

/// The beauty module (library + env, shading, beauty).
fn beauty_module() -> naga::Module {
    parse(&shaders::beauty_module_source())
}

#[test]
fn shared_structs_have_the_same_offsets_and_sizes_in_wgsl() {
    // The beauty module holds every shared struct (common.wgsl is in both modules).
    let m = beauty_module();
    for (name, rust_size, rust_members) in layout::shared_layouts() {
        let (_, ty) = m
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("struct {name} not in the WGSL"));
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            panic!("{name} is not a struct in the WGSL");
        };
        assert_eq!(*span as usize, rust_size, "size of {name}");
        let wgsl: Vec<(&str, usize)> = members
            .iter()
            .map(|mb| (mb.name.as_deref().unwrap_or("?"), mb.offset as usize))
            .collect();
        assert_eq!(
            wgsl, rust_members,
            "members (name, offset) of {name}: WGSL vs Rust"
        );
    }
}

#[test]
fn the_beauty_path_record_is_the_size_the_host_allocates() {
    // GPU-only (no host struct mirrors it), but the host sizes the buffer: tile² records.
    let m = beauty_module();
    let (_, ty) = m
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some("PathRecord"))
        .expect("struct PathRecord in beauty.wgsl");
    let naga::TypeInner::Struct { span, .. } = &ty.inner else {
        panic!("PathRecord is not a struct");
    };
    assert_eq!(*span as u64, layout::PATH_RECORD_BYTES);
}

fn constant(m: &naga::Module, name: &str) -> naga::Literal {
    let (_, c) = m
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("const {name}"));
    match m.global_expressions[c.init] {
        naga::Expression::Literal(l) => l,
        ref e => panic!("const {name} is not a literal: {e:?}"),
    }
}

#[test]
fn sentinels_and_flags_are_mirrored() {
    let m = module();
    assert_eq!(
        constant(&m, "NO_PRISM"),
        naga::Literal::U32(layout::NO_PRISM)
    );
    assert_eq!(constant(&m, "T_FAR"), naga::Literal::F32(layout::T_FAR));
    assert_eq!(
        constant(&m, "NO_STITCH"),
        naga::Literal::U32(layout::NO_STITCH)
    );
    assert_eq!(
        constant(&m, "PRISM_FLAT"),
        naga::Literal::U32(prismbake::bake::PRISM_FLAT)
    );
    assert_eq!(
        constant(&m, "M_LO_FLOOR"),
        naga::Literal::F32(prismbake::bake::M_LO_FLOOR)
    );
    assert_eq!(
        constant(&m, "PURPOSE_MARCH_JITTER"),
        naga::Literal::U32(prismbake::rng::Purpose::MarchJitter as u32)
    );
    assert_eq!(
        constant(&m, "PURPOSE_PIXEL_JITTER"),
        naga::Literal::U32(prismbake::rng::Purpose::PixelJitter as u32)
    );
}

#[test]
fn beauty_constants_are_mirrored() {
    let m = beauty_module();
    use prismbake::render::{beauty, shading};
    for (name, purpose) in [
        ("PURPOSE_BSDF", prismbake::rng::Purpose::Bsdf),
        ("PURPOSE_LIGHT", prismbake::rng::Purpose::Light),
    ] {
        assert_eq!(
            constant(&m, name),
            naga::Literal::U32(purpose as u32),
            "{name}"
        );
    }
    assert_eq!(constant(&m, "DIMS"), naga::Literal::U32(beauty::DIMS));
    assert_eq!(constant(&m, "KEY_DIM"), naga::Literal::U32(beauty::KEY_DIM));
    assert_eq!(
        constant(&m, "TEX_PACKED"),
        naga::Literal::U32(prismbake_gpu::beauty::TEX_PACKED)
    );
    assert_eq!(
        constant(&m, "MIRROR_ROUGHNESS"),
        naga::Literal::F32(shading::MIRROR_ROUGHNESS)
    );
    assert_eq!(constant(&m, "PI"), naga::Literal::F32(shading::PI));
    assert_eq!(constant(&m, "INV_PI"), naga::Literal::F32(shading::INV_PI));
}

#[test]
fn modules_validate_and_state_the_host_workgroup_size() {
    let plain = naga::valid::Capabilities::default();
    // The packet walk's subgroup operations: what wgpu::Features::SUBGROUP grants.
    let subgroups = plain | naga::valid::Capabilities::SUBGROUP;
    for (m, entry, caps) in [
        (module(), "render_aovs", plain),
        (packet_module(), "render_aovs_packet", subgroups),
        (beauty_module(), "render_beauty", plain),
        (beauty_module(), "beauty_start", plain),
        (beauty_module(), "beauty_trace", plain),
        (beauty_module(), "beauty_shade", plain),
    ] {
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), caps)
            .validate(&m)
            .unwrap_or_else(|e| panic!("{entry}: {e:?}"));
        let ep = m
            .entry_points
            .iter()
            .find(|e| e.name == entry)
            .unwrap_or_else(|| panic!("entry point {entry}"));
        assert_eq!(ep.workgroup_size, [layout::WORKGROUP, layout::WORKGROUP, 1]);
    }
}

#[test]
fn beauty_binds_the_storage_buffers_the_device_is_asked_for() {
    // Breaks if a storage binding is added to a kernel without raising the limit the context
    // requests (pipeline creation would fail on adapters that only grant what was asked).
    let storage = |m: &naga::Module| {
        m.global_variables
            .iter()
            .filter(|(_, g)| matches!(g.space, naga::AddressSpace::Storage { .. }))
            .count() as u32
    };
    assert_eq!(
        storage(&beauty_module()),
        prismbake_gpu::context::BEAUTY_STORAGE_BUFFERS
    );
    assert!(storage(&module()) <= wgpu::Limits::defaults().max_storage_buffers_per_shader_stage);
    // The fused schedule (all but the wavefront's path records) fits WebGPU's defaults, so
    // the beauty runs on every adapter that has them.
    assert!(
        prismbake_gpu::context::BEAUTY_STORAGE_BUFFERS - 1
            <= wgpu::Limits::defaults().max_storage_buffers_per_shader_stage
    );
}
