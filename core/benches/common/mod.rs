//! Procedural fixtures shared by the benches: a UV sphere whose UVs cover the whole map
//! (so the bake reads every texel, as a real unwrapped asset does) and a 4096² relief.

#![allow(dead_code)]

use glam::{Vec2, Vec3};
use prismbake::heightmap::{HeightMap, Wrap};
use prismbake::mesh::BaseMesh;

/// UV sphere of radius 1: `segments` around, `rings` pole to pole, duplicated seam column,
/// `2 * segments * (rings - 1)` triangles (64 × 64 → 8064), UV = (longitude, latitude).
pub fn uv_sphere(segments: u32, rings: u32) -> BaseMesh {
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    for r in 0..=rings {
        let v = r as f32 / rings as f32;
        let theta = std::f32::consts::PI * (1.0 - v);
        for s in 0..=segments {
            let u = s as f32 / segments as f32;
            let phi = std::f32::consts::TAU * u;
            positions.push(Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                -theta.sin() * phi.sin(),
            ));
            uvs.push(Vec2::new(u, v));
        }
    }
    let row = segments + 1;
    let mut triangles = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let (a, b) = (r * row + s, r * row + s + 1);
            let (c, d) = (a + row, b + row);
            // The pole rows collapse one triangle of each quad: skip it.
            if r != 0 {
                triangles.push([a, b, d]);
            }
            if r != rings - 1 {
                triangles.push([a, d, c]);
            }
        }
    }
    let n = triangles.len();
    BaseMesh {
        normals: positions.clone(),
        positions,
        uvs,
        face_group: vec![0; n],
        face_flags: vec![0; n],
        triangles,
        groups: vec!["sphere".into()],
        ..Default::default()
    }
}

/// A `size`² repeat-wrapped relief in [0, 1]: smooth sinusoids plus texel-scale hash noise
/// (so footprint ranges are not trivially equal to their corners).
pub fn relief_map(size: u32) -> HeightMap {
    let tau = std::f32::consts::TAU;
    let n = size as f32;
    let data = (0..size * size)
        .map(|i| {
            let (x, y) = ((i % size) as f32 / n, (i / size) as f32 / n);
            let smooth = 0.5
                + 0.2 * (tau * 3.0 * x).sin() * (tau * 2.0 * y).cos()
                + 0.1 * (tau * 17.0 * (x + y)).sin();
            let noise = (prismbake::rng::pcg_hash(i) >> 8) as f32 / (1u32 << 24) as f32;
            (smooth + 0.1 * (noise - 0.5)).clamp(0.0, 1.0)
        })
        .collect();
    HeightMap::new(size, size, data, Wrap::Repeat)
}
