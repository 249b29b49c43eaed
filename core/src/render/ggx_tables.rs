//! Tables of the GGX lobe's directional albedo, for the multiple-scattering energy the
//! single-scattering lobe leaves out (Kulla & Conty 2017, "Revisiting Physically Based Shading
//! at Imageworks") and for how much the specular layer of a dielectric leaves its diffuse base
//! (the layering of Blender's Principled BSDF).
//!
//! Three tables, each on a regular grid whose end points are the axes' ends (roughness and
//! cos θo from 0 to 1), read by linear interpolation (`ggx_e`, `ggx_e_avg`, `ggx_s`):
//! * `GGX_E[μ][r]` (32 × 32): E(r, μ), the albedo of the lobe with F = 1 seen at cos θo = μ,
//!   roughness r (α = r²);
//! * `GGX_E_AVG[r]` (32): its cosine-weighted mean over μ, 2∫E(r, μ) μ dμ;
//! * `GGX_S[z][μ][r]` (16 × 16 × 16): for a dielectric of F0 = z⁴, the mean over the lobe's
//!   visible normals of s = (F(cos θh) − F0)/(1 − F0) (F the dielectric Fresnel; a sample
//!   below the horizon counts 0), so that `F0 + (1 − F0) s` is the lobe's mean Fresnel.
//!
//! The values are in `ggx_tables_data.rs`, written by `write_ggx_tables` (an ignored test:
//! `cargo test --release -p prismbake-core --lib write_ggx_tables -- --ignored`) from
//! `e_entry`, `e_avg_entry` and `s_entry` with stratified visible-normal samples; the
//! `stored_tables_match_their_definition` test recomputes entries and compares.

use super::shading::{
    fresnel_blend, fresnel_dielectric, ggx_alpha, ggx_sample, ior_from_f0, smith_g1, smith_g2,
};
use crate::rng::{random, Purpose};
use glam::{Vec2, Vec3};

pub use super::ggx_tables_data::{GGX_E, GGX_E_AVG, GGX_S};

/// Sides of the tables: `E_SIDE` for E and its mean, `S_SIDE` for s.
pub const E_SIDE: usize = 32;
pub const S_SIDE: usize = 16;

/// Grid index below `x` ∈ [0, 1] on `n` points, the one above, and the fraction between.
#[inline]
fn cell(x: f32, n: usize) -> (usize, usize, f32) {
    let x = x.clamp(0.0, 1.0) * (n - 1) as f32;
    let i = (x as usize).min(n - 1);
    (i, (i + 1).min(n - 1), x - i as f32)
}

#[inline]
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

/// E(r, μ) from `GGX_E`.
#[inline]
pub fn ggx_e(rough: f32, mu: f32) -> f32 {
    let (x0, x1, tx) = cell(rough, E_SIDE);
    let (y0, y1, ty) = cell(mu, E_SIDE);
    let at = |x: usize, y: usize| GGX_E[y * E_SIDE + x];
    lerp(
        lerp(at(x0, y0), at(x1, y0), tx),
        lerp(at(x0, y1), at(x1, y1), tx),
        ty,
    )
}

/// The cosine-weighted mean of E(r, ·), from `GGX_E_AVG`.
#[inline]
pub fn ggx_e_avg(rough: f32) -> f32 {
    let (x0, x1, tx) = cell(rough, E_SIDE);
    lerp(GGX_E_AVG[x0], GGX_E_AVG[x1], tx)
}

/// s(r, μ, z) from `GGX_S` (z = F0^¼).
#[inline]
pub fn ggx_s(rough: f32, mu: f32, z: f32) -> f32 {
    let (x0, x1, tx) = cell(rough, S_SIDE);
    let (y0, y1, ty) = cell(mu, S_SIDE);
    let (z0, z1, tz) = cell(z, S_SIDE);
    let at = |x: usize, y: usize, z: usize| GGX_S[(z * S_SIDE + y) * S_SIDE + x];
    let plane = |z: usize| {
        lerp(
            lerp(at(x0, y0, z), at(x1, y0, z), tx),
            lerp(at(x0, y1, z), at(x1, y1, z), tx),
            ty,
        )
    };
    lerp(plane(z0), plane(z1), tz)
}

/// The grid's value of an axis at point `i` of `n`, kept off the ends where a value is
/// degenerate (a horizontal view, an infinite index).
fn grid(i: usize, n: usize, lo: f32, hi: f32) -> f32 {
    (i as f32 / (n - 1) as f32).clamp(lo, hi)
}

/// `side`² stratified points of the unit square for table entry `entry`.
fn strata(entry: u32, side: u32) -> impl Iterator<Item = Vec2> {
    (0..side * side).map(move |k| {
        let (i, j) = (k % side, k / side);
        let jitter = |d: u32| random(entry, k, d, Purpose::Bench, 0x7ab1e5);
        Vec2::new(
            (i as f32 + jitter(0)) / side as f32,
            (j as f32 + jitter(1)) / side as f32,
        )
    })
}

fn view(mu: f32) -> Vec3 {
    Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu)
}

/// E(r, μ) by `side`² visible-normal samples: the mean of G2/G1 over those above the horizon.
pub fn e_entry(rough: f32, mu: f32, entry: u32, side: u32) -> f32 {
    let (alpha, wo) = (ggx_alpha(rough), view(mu));
    let sum: f64 = strata(entry, side)
        .map(|u| ggx_sample(wo, alpha, u))
        .filter(|wi| wi.z > 0.0)
        .map(|wi| (smith_g2(wo, wi, alpha) / smith_g1(wo, alpha)) as f64)
        .sum();
    (sum / (side * side) as f64) as f32
}

/// 2∫E(r, μ) μ dμ by the midpoint rule over `steps` values of μ, each `e_entry`.
pub fn e_avg_entry(rough: f32, entry: u32, steps: u32, side: u32) -> f32 {
    let sum: f64 = (0..steps)
        .map(|i| {
            let mu = (i as f32 + 0.5) / steps as f32;
            (2.0 * mu * e_entry(rough, mu, entry * steps + i, side)) as f64
        })
        .sum();
    (sum / steps as f64) as f32
}

/// s(r, μ, z) by `side`² visible-normal samples.
pub fn s_entry(rough: f32, mu: f32, z: f32, entry: u32, side: u32) -> f32 {
    let (alpha, wo) = (ggx_alpha(rough), view(mu));
    let f0 = (z * z) * (z * z);
    let eta = ior_from_f0(f0);
    let sum: f64 = strata(entry, side)
        .map(|u| ggx_sample(wo, alpha, u))
        .filter(|wi| wi.z > 0.0)
        .map(|wi| {
            let c = wo.dot((wo + wi).normalize());
            fresnel_blend(fresnel_dielectric(c, eta), f0) as f64
        })
        .sum();
    (sum / (side * side) as f64) as f32
}

/// The E table's axes at grid point (x, y): roughness and cos θo.
pub fn e_axes(x: usize, y: usize) -> (f32, f32) {
    (grid(x, E_SIDE, 1e-4, 1.0), grid(y, E_SIDE, 1e-4, 1.0))
}

/// The s table's axes at grid point (x, y, z): roughness, cos θo and F0^¼ (below 1, so that
/// the index stays finite).
pub fn s_axes(x: usize, y: usize, z: usize) -> (f32, f32, f32) {
    (
        grid(x, S_SIDE, 1e-4, 1.0),
        grid(y, S_SIDE, 1e-4, 1.0),
        grid(z, S_SIDE, 1e-4, 0.99),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Recomputes a spread of entries (fewer samples than the stored ones) and compares: the
    /// stored tables are what their definitions give, and the lookups read them the right way
    /// round.
    #[test]
    fn stored_tables_match_their_definition() {
        for (x, y) in [
            (0, 31),
            (3, 10),
            (12, 0),
            (16, 16),
            (31, 31),
            (31, 2),
            (25, 7),
        ] {
            let (r, mu) = e_axes(x, y);
            let want = e_entry(r, mu, 999, 48);
            assert!(
                (GGX_E[y * E_SIDE + x] - want).abs() < 4e-3 && (ggx_e(r, mu) - want).abs() < 4e-3,
                "E({r}, {mu}) = {} stored, {want} recomputed",
                GGX_E[y * E_SIDE + x]
            );
        }
        for x in [0, 9, 20, 31] {
            let r = e_axes(x, 0).0;
            let want = e_avg_entry(r, 5, 32, 24);
            assert!(
                (ggx_e_avg(r) - want).abs() < 4e-3,
                "E_avg({r}): {} vs {want}",
                ggx_e_avg(r)
            );
        }
        for (x, y, z) in [
            (0, 15, 3),
            (4, 2, 8),
            (8, 8, 8),
            (15, 0, 15),
            (15, 12, 5),
            (11, 5, 1),
        ] {
            let (r, mu, zz) = s_axes(x, y, z);
            let want = s_entry(r, mu, zz, 77, 48);
            assert!(
                (ggx_s(r, mu, zz) - want).abs() < 4e-3,
                "s({r}, {mu}, {zz}) = {} stored, {want} recomputed",
                ggx_s(r, mu, zz)
            );
        }
    }

    /// What the tables must be at their ends: a smooth lobe reflects everything (E = 1) with
    /// the Fresnel of its one normal; a rough one loses energy at grazing angles.
    #[test]
    fn the_tables_ends_are_the_known_values() {
        for mu in [0.05, 0.3, 0.7, 1.0] {
            assert!(
                (ggx_e(0.0, mu) - 1.0).abs() < 2e-3,
                "E(0, {mu}) = {}",
                ggx_e(0.0, mu)
            );
            let f0 = 0.04f32;
            let want = (fresnel_dielectric(mu, ior_from_f0(f0)) - f0) / (1.0 - f0);
            let got = ggx_s(0.0, mu, f0.sqrt().sqrt());
            assert!(
                (got - want).abs() < 0.01,
                "s(0, {mu}) = {got}, Fresnel gives {want}"
            );
        }
        // E by a quadrature of D G2 / (4 cos θo) over the hemisphere (1 500 × 3 000 points,
        // numpy), independent of the sampler: least at normal incidence for rough lobes.
        for (r, mu, want) in [
            (1.0, 1.0, 0.3069),
            (1.0, 0.3, 0.5601),
            (1.0, 0.05, 0.8478),
            (0.5, 0.3, 0.8379),
            (0.5, 0.9, 0.9074),
        ] {
            let got = ggx_e(r, mu);
            assert!(
                (got - want).abs() < 0.01,
                "E({r}, {mu}) = {got}, quadrature {want}"
            );
        }
        for r in 1..E_SIDE {
            assert!(GGX_E_AVG[r] < GGX_E_AVG[r - 1] + 1e-3, "{GGX_E_AVG:?}");
        }
    }

    /// Writes `ggx_tables_data.rs` (release build: about a minute on two cores).
    #[test]
    #[ignore]
    fn write_ggx_tables() {
        use rayon::prelude::*;
        use std::fmt::Write;
        let e: Vec<f32> = (0..E_SIDE * E_SIDE)
            .into_par_iter()
            .map(|i| {
                let (r, mu) = e_axes(i % E_SIDE, i / E_SIDE);
                e_entry(r, mu, i as u32, 256)
            })
            .collect();
        let e_avg: Vec<f32> = (0..E_SIDE)
            .into_par_iter()
            .map(|x| e_avg_entry(e_axes(x, 0).0, x as u32 + 5000, 256, 64))
            .collect();
        let s: Vec<f32> = (0..S_SIDE * S_SIDE * S_SIDE)
            .into_par_iter()
            .map(|i| {
                let (r, mu, z) = s_axes(i % S_SIDE, (i / S_SIDE) % S_SIDE, i / (S_SIDE * S_SIDE));
                s_entry(r, mu, z, i as u32 + 20_000, 128)
            })
            .collect();
        let mut out = String::from(
            "//! Written by `ggx_tables::tests::write_ggx_tables`; see `ggx_tables.rs`.\n\n",
        );
        for (name, v, rows) in [
            ("GGX_E", &e, E_SIDE),
            ("GGX_E_AVG", &e_avg, E_SIDE),
            ("GGX_S", &s, S_SIDE),
        ] {
            writeln!(
                out,
                "#[rustfmt::skip]\npub static {name}: [f32; {}] = [",
                v.len()
            )
            .unwrap();
            for row in v.chunks(rows) {
                let line: Vec<String> = row.iter().map(|x| format!("{x:.6}")).collect();
                writeln!(out, "    {},", line.join(", ")).unwrap();
            }
            out.push_str("];\n\n");
        }
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/render/ggx_tables_data.rs");
        std::fs::write(path, out.trim_end().to_string() + "\n").unwrap();
    }
}
