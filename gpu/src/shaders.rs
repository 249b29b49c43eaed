//! The WGSL sources (`shaders/`, one file per stage), included at build time and concatenated
//! into one module: WGSL resolves names across the whole module, so the order only matters
//! for reading (shared declarations first, the entry point last).

/// Structs shared with the host, sentinels, the scene bind group, small helpers.
pub const COMMON: &str = include_str!("../../shaders/common.wgsl");
/// Counter-based random numbers (mirror of `prismbake::rng`).
pub const RNG: &str = include_str!("../../shaders/rng.wgsl");
/// Primary rays and pixel jitter (mirror of `prismbake::render::camera`).
pub const CAMERA: &str = include_str!("../../shaders/camera.wgsl");
/// Bilinear height-map sampling (mirror of `prismbake::heightmap`).
pub const HEIGHTMAP: &str = include_str!("../../shaders/heightmap.wgsl");
/// The stitched height next to UV seams (mirror of `prismbake::seam`).
pub const SEAM: &str = include_str!("../../shaders/seam.wgsl");
/// BVH2 closest-hit traversal (GPU counterpart of `prismbake::accel::Scene::closest_hit`).
pub const BVH: &str = include_str!("../../shaders/bvh.wgsl");
/// Ray vs prism interval (mirror of `prismbake::trace::prism_hit`).
pub const PRISM_HIT: &str = include_str!("../../shaders/prism_hit.wgsl");
/// Canonical surface and projection (mirror of `prismbake::canonical`).
pub const CANONICAL: &str = include_str!("../../shaders/canonical.wgsl");
/// The PDM march and refinement (mirror of `prismbake::trace::pdm`).
pub const PDM: &str = include_str!("../../shaders/pdm.wgsl");
/// The materials' records, their textures' sampling and their alpha (mirror of
/// `prismbake::texture` and `prismbake::render::cutout`).
pub const MATERIAL: &str = include_str!("../../shaders/material.wgsl");
/// The AOV kernel (mirror of `prismbake::render::render_aovs`).
pub const AOV: &str = include_str!("../../shaders/aov.wgsl");
/// The environment light (mirror of `prismbake::render::env`).
pub const ENV: &str = include_str!("../../shaders/env.wgsl");
/// Material, BSDF sampling, MIS weights (mirror of `prismbake::render::shading`).
pub const SHADING: &str = include_str!("../../shaders/shading.wgsl");
/// The materials as the beauty shades them (mirror of `BeautyScene::material_at`).
pub const TEXTURE: &str = include_str!("../../shaders/texture.wgsl");
/// The beauty kernel (mirror of `prismbake::render::beauty`).
pub const BEAUTY: &str = include_str!("../../shaders/beauty.wgsl");
/// The beauty's PNG preview (mirror of `prismbake::render::beauty::preview_pixel`).
pub const TONEMAP: &str = include_str!("../../shaders/tonemap.wgsl");

/// Every stage but the entry points and the lighting: what every kernel builds on.
pub const LIBRARY: [&str; 10] = [
    COMMON, RNG, CAMERA, HEIGHTMAP, SEAM, BVH, PRISM_HIT, CANONICAL, PDM, MATERIAL,
];

/// The AOV module: the library plus `aov.wgsl` (entry point `render_aovs`).
pub fn aov_module_source() -> String {
    let mut s = LIBRARY.join("\n");
    s.push('\n');
    s.push_str(AOV);
    s
}

/// BVH traversal by subgroup packets and its AOV kernel (needs the adapter's subgroups).
pub const PACKET: &str = include_str!("../../shaders/packet.wgsl");

/// The AOV module walked by subgroup packets: the AOV module and `packet.wgsl` (entry point
/// `render_aovs_packet`). Naga takes subgroup built-ins without WGSL's `enable subgroups;`
/// (which it rejects as not yet implemented) once the device has `Features::SUBGROUP`.
pub fn aov_packet_module_source() -> String {
    let mut s = aov_module_source();
    s.push('\n');
    s.push_str(PACKET);
    s
}

/// The beauty module: the library, the environment, the material, the texture,
/// `beauty.wgsl` (entry points `render_beauty`, `beauty_start`, `beauty_trace`,
/// `beauty_shade`) and `tonemap.wgsl` (entry point `tonemap_preview`).
pub fn beauty_module_source() -> String {
    let mut s = LIBRARY.join("\n");
    for part in [ENV, SHADING, TEXTURE, BEAUTY, TONEMAP] {
        s.push('\n');
        s.push_str(part);
    }
    s
}
