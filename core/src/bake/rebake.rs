//! Incremental re-bake for a changed height map (`render --watch`): same mesh and
//! parameters, new map values; only prisms whose stored bounds no longer hold are re-derived.

use super::{
    footprint_range, inserted_texel_world, prism_height_range, texel_world_size, with_height_range,
    Prism, PrismTable, PRISM_INSERTED,
};
use crate::heightmap::HeightMap;
use crate::seam::StitchField;
use rayon::prelude::*;
use serde::Serialize;

/// What `rebake_for_map` changed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct RebakeStats {
    pub prisms: usize,
    /// Prisms whose stored λ range no longer held the new displacement and was re-derived.
    pub prisms_rebaked: usize,
    /// Prisms whose displacement range or flat flag changed (bounds kept or not).
    pub records_updated: usize,
    /// Re-baked prisms whose box grew: the BVH no longer bounds them.
    pub boxes_grown: usize,
    pub bvh_rebuild_needed: bool,
}

/// Update a table for a new version of its height map (same mesh, same parameters) without a
/// full bake: every prism's footprint range is recomputed (`footprint_range`), its `d` range
/// and flat flag updated, but its extrusion range `[λlo, λhi]` is re-derived only when the new
/// `lambda_range(d_min, d_max, m_lo)` is not inside the stored one (the λ range, not the `d`
/// range, is what bounds the surface; `m_lo` comes from the unchanged normals). Kept ranges
/// may now be loose, never too small. A BVH built over the old boxes still bounds every prism
/// unless some re-derived box grew (`bvh_rebuild_needed`).
pub fn rebake_for_map(table: &mut PrismTable, map: &HeightMap) -> RebakeStats {
    let resized = (map.width, map.height) != (table.map_width, table.map_height);
    let params = table.params;
    let before = table.prisms.clone();
    if resized {
        // Texel sizes first: the stitch bands (one texel wide) follow them.
        for i in 0..table.prisms.len() {
            let p = table.prisms[i];
            let (pos, n) = table.prism_corners(&p);
            let uv = table.prism_uvs(&p);
            table.prisms[i].texel_world = if p.flags & PRISM_INSERTED != 0 {
                let (hmin, hmax) = footprint_range(map, &uv);
                let (d0, d1) = params.displacement_range(hmin, hmax);
                inserted_texel_world(map, &pos, &n, &uv, d0.abs().max(d1.abs()))
            } else {
                texel_world_size(map, &pos, &uv)
            };
        }
    }
    let view: &PrismTable = table;
    let field = StitchField::build(view, map);
    let updated: Vec<(Prism, bool, bool)> = view
        .prisms
        .par_iter()
        .enumerate()
        .map(|(i, p)| {
            let (_, n) = view.prism_corners(p);
            let (hmin, hmax) = prism_height_range(view, &field, map, i);
            let fresh = with_height_range(*p, &n, &params, hmin, hmax);
            let (lo, hi) = (fresh.lambda_lo, fresh.lambda_hi);
            let mut q = Prism {
                lambda_lo: p.lambda_lo,
                lambda_hi: p.lambda_hi,
                ..fresh
            };
            let holds = lo >= p.lambda_lo && hi <= p.lambda_hi;
            let mut grew = false;
            if !holds {
                q.lambda_lo = lo;
                q.lambda_hi = hi;
                let (a0, a1) = view.prism_aabb(p);
                let (b0, b1) = view.prism_aabb(&q);
                grew = b0.cmplt(a0).any() || b1.cmpgt(a1).any();
            }
            (q, !holds, grew)
        })
        .collect();
    let mut stats = RebakeStats {
        prisms: table.prisms.len(),
        ..RebakeStats::default()
    };
    for ((slot, old), (q, rebaked, grew)) in table.prisms.iter_mut().zip(&before).zip(updated) {
        stats.prisms_rebaked += rebaked as usize;
        stats.boxes_grown += grew as usize;
        stats.records_updated += (*old != q) as usize;
        *slot = q;
    }
    stats.bvh_rebuild_needed = stats.boxes_grown > 0;
    table.map_width = map.width;
    table.map_height = map.height;
    stats
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::fixtures::*;
    use crate::bake::{bake, BakeOptions};

    /// A local edit of the map re-bakes only the prisms over it; the result bounds the surface
    /// as a fresh bake does (fresh λ range inside the kept one, same d ranges and flags).
    #[test]
    fn local_edit_rebakes_only_the_prisms_over_it() {
        let mesh = sphere_mesh(2, 0.1);
        let map = relief_map(64);
        let mut table = table(&mesh, &map, 0.05);
        let n = table.prisms.len();
        assert_eq!(
            rebake_for_map(&mut table.clone(), &map).prisms_rebaked,
            0,
            "same map: nothing to do"
        );

        let mut edited = map.clone();
        for y in 20..24 {
            for x in 30..34 {
                edited.data[y * 64 + x] = 1.5; // above the old maximum: those bounds must grow
            }
        }
        let stats = rebake_for_map(&mut table, &edited);
        let fresh = bake(
            &mesh,
            &edited,
            &BakeOptions {
                params: table.params,
            },
        );
        assert!(
            stats.prisms_rebaked > 0 && stats.prisms_rebaked < n / 4,
            "{stats:?} of {n}"
        );
        assert!(stats.bvh_rebuild_needed && stats.boxes_grown > 0);
        for (got, want) in table.prisms.iter().zip(&fresh.prisms) {
            assert_eq!(
                (got.d_min, got.d_max, got.flags),
                (want.d_min, want.d_max, want.flags)
            );
            assert!(
                got.lambda_lo <= want.lambda_lo && got.lambda_hi >= want.lambda_hi,
                "{got:?} vs {want:?}"
            );
        }

        // The same map again: every bound holds, no BVH work.
        let again = rebake_for_map(&mut table, &edited);
        assert_eq!(
            (
                again.prisms_rebaked,
                again.records_updated,
                again.bvh_rebuild_needed
            ),
            (0, 0, false),
            "{again:?}"
        );
        // Back to the old map: only prisms under the patch can need new bounds (those whose
        // minimum was inside it now reach lower again); the others keep theirs, loose or not.
        let back = rebake_for_map(&mut table, &map);
        assert!(
            back.prisms_rebaked <= stats.prisms_rebaked && back.records_updated > 0,
            "{back:?}"
        );
    }
}
