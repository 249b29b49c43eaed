//! Tangent frames for normal maps: MikkTSpace tangents of a prism table's base triangles.
//!
//! A tangent-space normal map stores normals in the frame its baker computed from the mesh's
//! positions, normals and UVs. MikkTSpace is the frame Blender, Substance and xNormal bake in
//! (and the one glTF asks a viewer to compute when a file carries no tangents), so the beauty
//! computes it from the table it traces (`bake::PrismTable`: the repaired mesh, prisms numbered
//! as its triangles) rather than reading a file's own: one frame for glTF, OBJ, USD and baked
//! tables alike, and the one Cycles uses.
//!
//! The tangent of a corner is `xyz`, unit, along increasing `u`; `w` is the bitangent's sign:
//! the bitangent is `w · cross(n, xyz)`, along increasing `v` (up the image, the project's
//! convention: the green channel of an OpenGL-style normal map points up the image).

use crate::bake::PrismTable;
use glam::{Vec2, Vec3, Vec4};

/// Per prism, the tangent of each corner (`[xyz, sign]`), in the order of its `tri`.
pub fn corner_tangents(table: &PrismTable) -> Vec<[Vec4; 3]> {
    struct Geometry<'a> {
        table: &'a PrismTable,
        out: Vec<[Option<Vec4>; 3]>,
    }
    impl bevy_mikktspace::Geometry for Geometry<'_> {
        fn num_faces(&self) -> usize {
            self.table.prisms.len()
        }
        fn num_vertices_of_face(&self, _face: usize) -> usize {
            3
        }
        fn position(&self, face: usize, vert: usize) -> [f32; 3] {
            let i = self.table.prisms[face].tri[vert] as usize;
            self.table.positions[i].to_array()
        }
        fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
            let i = self.table.prisms[face].tri[vert] as usize;
            self.table.normals[i].to_array()
        }
        fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
            let i = self.table.prisms[face].tri[vert] as usize;
            self.table.uvs[i].to_array()
        }
        fn set_tangent(
            &mut self,
            tangent_space: Option<bevy_mikktspace::TangentSpace>,
            face: usize,
            vert: usize,
        ) {
            self.out[face][vert] = tangent_space.map(|t| Vec4::from_array(t.tangent_encoded()));
        }
    }
    let mut g = Geometry {
        table,
        out: vec![[None; 3]; table.prisms.len()],
    };
    // The error type has no variants: generation cannot fail.
    let _ = bevy_mikktspace::generate_tangents(&mut g);
    g.out
        .iter()
        .zip(&table.prisms)
        .map(|(corners, p)| {
            let pos = p.tri.map(|i| table.positions[i as usize]);
            let uv = p.tri.map(|i| table.uvs[i as usize]);
            let n = p.tri.map(|i| table.normals[i as usize]);
            std::array::from_fn(|k| {
                corners[k]
                    .filter(|t| t.is_finite() && t.truncate().length_squared() > 0.5)
                    .unwrap_or_else(|| face_tangent(pos, uv, n[k]))
            })
        })
        .collect()
}

/// A corner's tangent where MikkTSpace gives none (a triangle of no area in space or in UV,
/// alone): the triangle's own `dP/du` made perpendicular to the corner's normal, else any
/// direction perpendicular to it.
fn face_tangent(pos: [Vec3; 3], uv: [Vec2; 3], n: Vec3) -> Vec4 {
    let (e1, e2) = (pos[1] - pos[0], pos[2] - pos[0]);
    let (d1, d2) = (uv[1] - uv[0], uv[2] - uv[0]);
    let det = d1.x * d2.y - d2.x * d1.y;
    let dpdu = (e1 * d2.y - e2 * d1.y) / det;
    let dpdv = (e2 * d1.x - e1 * d2.x) / det;
    let t = (dpdu - n * n.dot(dpdu)).normalize_or_zero();
    if det.is_finite() && det != 0.0 && t != Vec3::ZERO {
        let sign = if n.cross(t).dot(dpdv) < 0.0 {
            -1.0
        } else {
            1.0
        };
        return t.extend(sign);
    }
    crate::render::shading::onb(n.normalize_or(Vec3::Z))
        .0
        .extend(1.0)
}

/// Per prism of `table`, its corners' normals on the base mesh (in `tri`'s order): what
/// `BeautyScene::bent_normal` interpolates, the undisplaced surface's normal.
pub fn corner_normals(table: &PrismTable) -> Vec<[Vec3; 3]> {
    (table.prisms.iter())
        .map(|p| p.tri.map(|i| table.normals[i as usize]))
        .collect()
}

/// The tangent frame at barycentrics `bary` of a prism whose corner tangents are `corners`,
/// about the unit normal `n` there: the interpolated tangent made perpendicular to `n`, and the
/// bitangent `sign · cross(n, t)`. `None` where the tangent is (nearly) along `n`.
#[inline]
pub fn frame_at(corners: &[Vec4; 3], bary: Vec3, n: Vec3) -> Option<(Vec3, Vec3)> {
    let t4 = corners[0] * bary.x + corners[1] * bary.y + corners[2] * bary.z;
    let t3 = t4.truncate();
    let t = (t3 - n * n.dot(t3)).normalize_or_zero();
    if t == Vec3::ZERO {
        return None;
    }
    let sign = if t4.w < 0.0 { -1.0 } else { 1.0 };
    Some((t, n.cross(t) * sign))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::Prism;

    /// A unit square in the xy plane facing +z, two triangles, with the UVs `uv` at its
    /// corners (0,0), (1,0), (1,1), (0,1).
    fn square(uv: [Vec2; 4]) -> PrismTable {
        PrismTable {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            normals: vec![Vec3::Z; 4],
            uvs: uv.to_vec(),
            prisms: [[0, 1, 2], [0, 2, 3]]
                .map(|tri| Prism {
                    tri,
                    d_min: 0.0,
                    d_max: 0.0,
                    lambda_lo: 0.0,
                    lambda_hi: 0.0,
                    texel_world: 0.0,
                    flags: 0,
                })
                .to_vec(),
            ..Default::default()
        }
    }

    fn corners_of(t: &[[Vec4; 3]]) -> Vec<Vec4> {
        t.iter().flatten().copied().collect()
    }

    #[test]
    fn a_square_mapped_as_it_lies_has_tangent_u_and_bitangent_v() {
        let uv = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)].map(Vec2::from);
        for t in corners_of(&corner_tangents(&square(uv))) {
            assert!(
                (t - Vec4::new(1.0, 0.0, 0.0, 1.0)).abs().max_element() < 1e-6,
                "{t}"
            );
        }
        let (t, b) = frame_at(
            &[Vec4::new(1.0, 0.0, 0.0, 1.0); 3],
            Vec3::ONE / 3.0,
            Vec3::Z,
        )
        .expect("a frame");
        assert_eq!((t, b), (Vec3::X, Vec3::Y));
    }

    #[test]
    fn a_mirrored_or_turned_map_turns_the_frame_with_it() {
        // u runs along -x: the tangent is -x and the bitangent still +y (v up), so the sign
        // is negative (cross(z, -x) = -y).
        let mirrored = [(1.0, 0.0), (0.0, 0.0), (0.0, 1.0), (1.0, 1.0)].map(Vec2::from);
        for t in corners_of(&corner_tangents(&square(mirrored))) {
            assert!(
                (t - Vec4::new(-1.0, 0.0, 0.0, -1.0)).abs().max_element() < 1e-6,
                "{t}"
            );
            let (tt, b) = frame_at(&[t; 3], Vec3::ONE / 3.0, Vec3::Z).expect("a frame");
            assert!((tt + Vec3::X).length() < 1e-6 && (b - Vec3::Y).length() < 1e-6);
        }
        // u runs along +y and v along -x (a quarter turn): tangent +y, bitangent -x.
        let turned = [(0.0, 1.0), (0.0, 0.0), (1.0, 0.0), (1.0, 1.0)].map(Vec2::from);
        for t in corners_of(&corner_tangents(&square(turned))) {
            assert!(
                (t - Vec4::new(0.0, 1.0, 0.0, 1.0)).abs().max_element() < 1e-6,
                "{t}"
            );
        }
    }

    #[test]
    fn a_triangle_without_uv_area_still_gets_a_unit_tangent_across_its_normal() {
        let flat = [Vec2::ZERO; 4];
        for t in corners_of(&corner_tangents(&square(flat))) {
            assert!((t.truncate().length() - 1.0).abs() < 1e-5, "{t}");
            assert!(t.truncate().dot(Vec3::Z).abs() < 1e-5, "{t}");
        }
    }

    #[test]
    fn the_frame_is_made_perpendicular_to_a_tilted_normal() {
        let n = Vec3::new(1.0, 0.0, 1.0).normalize();
        let (t, b) = frame_at(&[Vec4::new(1.0, 0.0, 0.0, 1.0); 3], Vec3::X, n).expect("a frame");
        assert!(t.dot(n).abs() < 1e-6 && b.dot(n).abs() < 1e-6 && (b - Vec3::Y).length() < 1e-6);
        assert!(frame_at(&[Vec4::new(0.0, 0.0, 1.0, 1.0); 3], Vec3::X, Vec3::Z).is_none());
    }
}
