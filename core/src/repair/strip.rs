//! Step 5, the shape of what `stitch` inserts: normal arcs for wide hard edges and corners.
//!
//! A stitched hard edge's inserted triangles are zero-area: their displaced image is swept by
//! the normals they interpolate, `P + D m̂(b)` with `m(b) = Σ b_i n_i`. One quad between
//! normals `n1` and `n2` is fine while the two are not too far apart (a cube edge: 90°). Across
//! a knife edge (`n1 ≈ −n2`) `m(b)` passes through zero inside the quad's triangles: the bake's
//! `λ = D/|m|` range blows up (the `M_LO_FLOOR` clamp, `PRISM_DEGENERATE_NORMALS`) and the prism
//! is folded two-to-one, so no prism march has a well-defined sign there
//! (docs/watertightness.md). So a wide edge gets a *strip* of quads instead: at each end the
//! normal turns from `n1` to `n2` along a `NormalArc` in steps of at most
//! `RepairOptions::strip_step_angle` (60°), one inserted vertex (same position) per
//! intermediate normal, with the UV the two sides share; where the crease is also a UV seam,
//! each half of the strip keeps its side's UV and the halves meet at a seam
//! (`stitch::Ladders::ladder`). The displaced strip is then a rounded edge of radius `D`, and
//! every inserted triangle has normals within about one step of each other, so `|m|` stays
//! near 1.
//!
//! Which way to turn: the short great-circle arc, through `n1 + n2`, where that is well
//! defined (a convex edge rounds outwards, a concave one inwards). Near `n1 ≈ −n2` the short
//! arc is rounding noise; the arc then passes through the direction pointing away from the
//! solid, taken from the geometry of the faces along the edge (`edge_hint`): for a knife edge,
//! the bisector of the two faces' in-plane directions away from their interiors.
//!
//! Everything here is a function of the two normals and one hint per position, never of the
//! vertex records, so the copies of a position on two sides of a UV seam get equal normals
//! (the strips then meet as plain UV seams).

use glam::Vec3;

/// A hard edge whose sides' normals differ by at most this keeps a single quad (cube edges,
/// cylinder rims: 90°).
pub(super) const SINGLE_QUAD_MAX_ANGLE: f32 = std::f32::consts::FRAC_PI_2 * (1.0 + 1e-4);
/// `|n1 + n2|` below this (the normals more than ~151° apart): the short arc's midpoint is
/// taken from the geometry instead.
const ANTIPODAL_SUM: f32 = 0.5;

/// The turn from `from` to `to` through `mid` (equidistant from both), in `segments` equal
/// steps of at most `RepairOptions::strip_step_angle` (60°: the bake's bound `min n_i·ĉ` of
/// `|m|` over an inserted triangle then stays above ~0.75): two slerps of `half` radians.
#[derive(Clone, Copy, Debug)]
pub(super) struct NormalArc {
    from: Vec3,
    mid: Vec3,
    to: Vec3,
    half: f32,
    pub segments: u32,
}

/// `a` turned towards `b` by the fraction `t` of their angle `ang` (unit vectors).
fn slerp(a: Vec3, b: Vec3, ang: f32, t: f32) -> Vec3 {
    if ang < 1e-6 {
        return a.lerp(b, t).normalize();
    }
    let s = ang.sin();
    (a * (((1.0 - t) * ang).sin() / s) + b * ((t * ang).sin() / s)).normalize()
}

fn angle(a: Vec3, b: Vec3) -> f32 {
    // atan2 of |a × b| and a·b: accurate near 0 and near π, where acos is not.
    a.cross(b).length().atan2(a.dot(b))
}

impl NormalArc {
    /// The arc between unit normals `from` and `to` in steps of at most `step` radians (one
    /// step up to 90°, and whatever the angle if `step ≥ π`); `hint` points away from the solid
    /// at their position (only used when they are nearly opposite).
    pub fn new(from: Vec3, to: Vec3, hint: Vec3, step: f32) -> Self {
        let axis = (from - to).normalize_or_zero();
        let sum = from + to;
        let towards = if sum.length() >= ANTIPODAL_SUM {
            sum
        } else {
            hint
        };
        // Equidistant from both: remove the component along `from − to`.
        let mid = (towards - axis * axis.dot(towards))
            .try_normalize()
            .or_else(|| sum.try_normalize())
            .unwrap_or_else(|| axis.any_orthonormal_vector());
        let half = angle(from, mid);
        let total = 2.0 * half;
        let segments = if total <= SINGLE_QUAD_MAX_ANGLE || step >= std::f32::consts::PI {
            1
        } else {
            (total / step.max(1e-3)).ceil().clamp(1.0, 1024.0) as u32
        };
        NormalArc {
            from,
            mid,
            to,
            half,
            segments,
        }
    }

    /// Normal `j` of `0..=segments`: exactly `from` at 0 and `to` at `segments`.
    pub fn point(&self, j: u32) -> Vec3 {
        if j == 0 {
            return self.from;
        }
        if j >= self.segments {
            return self.to;
        }
        let s = 2.0 * j as f32 / self.segments as f32;
        if s <= 1.0 {
            slerp(self.from, self.mid, self.half, s)
        } else {
            slerp(self.mid, self.to, self.half, s - 1.0)
        }
    }
}

/// The direction away from the solid across the hard edge `pa → pb`, whose first face has
/// its third corner at `c1` and normal `ng1`, the second `c2` and `ng2`: the sum of the two
/// faces' in-plane directions perpendicular to the edge and away from their interiors, for a
/// convex edge (each face's third corner below the other face's plane), its negation for a
/// concave one (there the air is on the faces' side).
pub(super) fn edge_hint(pa: Vec3, pb: Vec3, c1: Vec3, ng1: Vec3, c2: Vec3, ng2: Vec3) -> Vec3 {
    let e = (pb - pa).normalize_or_zero();
    let away = |c: Vec3| {
        let w = c - pa;
        -(w - e * e.dot(w)).normalize_or_zero()
    };
    let convex = (c2 - pa).dot(ng1) + (c1 - pa).dot(ng2) < 0.0;
    let h = away(c1) + away(c2);
    if convex {
        h
    } else {
        -h
    }
}

/// Triangulate the strip between the ladders `a` (at the edge's first position, from the
/// first face's record to the second's) and `b` (at its second position, likewise): quads
/// `(b_i, a_j, a_j+1, b_i+1)` advanced on both ladders in proportion, so that the triangles
/// use the edge `b → a` of the first face and `a' → b'` of the second (both reversed), and
/// the zero-length edges `a_j → a_j+1` and `b_i+1 → b_i` are those of the neighbouring strips
/// reversed. A one-element ladder is a crease ending there: a fan.
pub(super) fn zip(a: &[u32], b: &[u32]) -> Vec<[u32; 3]> {
    let (ka, kb) = (a.len() - 1, b.len() - 1);
    let (mut i, mut j) = (0, 0);
    let mut out = Vec::with_capacity(ka + kb);
    while i < kb || j < ka {
        // Advance the ladder that is behind (ties: `a` first, the single quad's order).
        let advance_a = j < ka && (i == kb || (j + 1) * kb <= (i + 1) * ka);
        if advance_a {
            out.push([b[i], a[j], a[j + 1]]);
            j += 1;
        } else {
            out.push([b[i], a[j], b[i + 1]]);
            i += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const STEP_ANGLE: f32 = std::f32::consts::FRAC_PI_3;

    // Would break if the arc did not start and end on the sides' own normals (the strip
    // would not meet the faces) or took steps wider than STEP_ANGLE.
    #[test]
    fn arc_ends_on_its_normals_and_steps_evenly() {
        let from = Vec3::new(0.1, 0.99, 0.0).normalize();
        let to = Vec3::new(0.12, -0.99, 0.03).normalize();
        let arc = NormalArc::new(from, to, Vec3::X, STEP_ANGLE);
        assert_eq!(arc.segments, 3);
        assert_eq!(arc.point(0), from);
        assert_eq!(arc.point(3), to);
        for j in 0..3 {
            let step = angle(arc.point(j), arc.point(j + 1));
            assert!(step <= STEP_ANGLE && step > 0.9 * STEP_ANGLE, "{step}");
            // Through the outside (+x), not through the solid.
            assert!(arc.point(j + 1).x > 0.0 || j + 1 == 3);
        }
        // The cube's 90° edge keeps one segment.
        assert_eq!(
            NormalArc::new(Vec3::X, Vec3::Y, Vec3::ZERO, STEP_ANGLE).segments,
            1
        );
        // A step of π or more: one quad whatever the angle (the construction before strips).
        assert_eq!(
            NormalArc::new(from, to, Vec3::X, std::f32::consts::PI).segments,
            1
        );
    }

    // Would break if the knife-edge arc followed rounding noise instead of the hint: the
    // strip would round the edge through the solid.
    #[test]
    fn antipodal_normals_turn_towards_the_hint() {
        for hint in [Vec3::X, Vec3::NEG_X, Vec3::new(0.3, 0.2, 1.0)] {
            let arc = NormalArc::new(Vec3::Y, Vec3::NEG_Y, hint, STEP_ANGLE);
            let mid = arc.point(arc.segments / 2);
            let want = (hint - Vec3::Y * hint.y).normalize();
            assert!(mid.dot(want) > 0.8, "{hint} -> {mid}");
            assert_eq!(arc.segments, 3);
        }
    }

    // Would break if the knife edge's hint pointed into the fin.
    #[test]
    fn hint_points_out_of_a_knife_edge() {
        // Fin along z at x = 1: faces from the rim (x = 1) back to x = 0, 2° apart; the
        // first face (pa, pb, c1) on top, the second (pb, pa, c2) below.
        let (pa, pb) = (Vec3::new(1.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 0.0));
        let tilt = 1f32.to_radians().tan();
        let (c1, c2) = (Vec3::new(0.0, tilt, 0.5), Vec3::new(0.0, -tilt, 0.5));
        let ng1 = (pb - pa).cross(c1 - pa).normalize();
        let ng2 = (c2 - pa).cross(pb - pa).normalize();
        assert!(ng1.y > 0.9 && ng2.y < -0.9);
        let h = edge_hint(pa, pb, c1, ng1, c2, ng2);
        assert!(h.normalize().x > 0.99, "{h}");
    }

    // Would break if the zipper skipped a rung or wound a triangle the wrong way.
    #[test]
    fn zipper_uses_every_ladder_edge_once() {
        for (ka, kb) in [(1, 1), (3, 3), (3, 1), (0, 3), (2, 0), (2, 3)] {
            let a: Vec<u32> = (0..=ka).collect();
            let b: Vec<u32> = (100..=100 + kb).collect();
            let tris = zip(&a, &b);
            assert_eq!(tris.len() as u32, ka + kb);
            let mut directed = std::collections::HashSet::new();
            for t in &tris {
                for k in 0..3 {
                    assert!(
                        directed.insert((t[k], t[(k + 1) % 3])),
                        "{ka} {kb}: {tris:?}"
                    );
                }
            }
            // Boundary: b0 → a0, the ladders a_j → a_j+1 and b_i+1 → b_i, a_k → b_k.
            assert!(directed.contains(&(b[0], a[0])));
            assert!(directed.contains(&(a[ka as usize], b[kb as usize])));
            for j in 0..ka as usize {
                assert!(directed.contains(&(a[j], a[j + 1])));
            }
            for i in 0..kb as usize {
                assert!(directed.contains(&(b[i + 1], b[i])));
            }
        }
    }
}
