//! Counter-based random numbers: every value is a hash of (pixel, sample, bounce, purpose,
//! seed), so CPU and GPU, one thread or many, draw the same numbers. The hash is PCG's
//! output permutation chained over the inputs (Jarzynski & Olano 2020, "Hash Functions for
//! GPU Rendering"); the WGSL mirror is `shaders/rng.wgsl`.

/// What a random number is used for; keeps streams of different purposes independent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum Purpose {
    /// Stochastic thin-feature jitter of PDM's first sample (paper §5.3).
    MarchJitter = 1,
    PixelJitter = 2,
    Bsdf = 3,
    Light = 4,
    Bench = 5,
    /// Whether a ray passes through a material's alpha (`render::cutout`).
    Alpha = 6,
}

#[inline]
pub fn pcg_hash(x: u32) -> u32 {
    let state = x.wrapping_mul(747796405).wrapping_add(2891336453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277803737);
    (word >> 22) ^ word
}

/// Hash of the counters; the same on every platform.
#[inline]
pub fn hash_counters(pixel: u32, sample: u32, bounce: u32, purpose: Purpose, seed: u32) -> u32 {
    let mut h = pcg_hash(seed ^ 0x9e37_79b9);
    h = pcg_hash(h ^ pixel);
    h = pcg_hash(h ^ sample);
    h = pcg_hash(h ^ bounce);
    pcg_hash(h ^ purpose as u32)
}

/// Uniform float in [0, 1) from a hash (24 high-quality bits).
#[inline]
pub fn to_unit_float(h: u32) -> f32 {
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

#[inline]
pub fn random(pixel: u32, sample: u32, bounce: u32, purpose: Purpose, seed: u32) -> f32 {
    to_unit_float(hash_counters(pixel, sample, bounce, purpose, seed))
}

/// `random` further keyed by `key` (a prism: one number per surface a ray meets).
#[inline]
pub fn random_keyed(
    pixel: u32,
    sample: u32,
    bounce: u32,
    purpose: Purpose,
    seed: u32,
    key: u32,
) -> f32 {
    to_unit_float(pcg_hash(
        hash_counters(pixel, sample, bounce, purpose, seed) ^ key,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frozen_values() {
        // Frozen so that a change to the hash (which would break CPU/GPU parity) is noticed.
        assert_eq!(pcg_hash(0), 129708002);
        assert_eq!(pcg_hash(1), 2831084092);
    }

    #[test]
    fn roughly_uniform() {
        let n = 100_000;
        let mean: f32 = (0..n)
            .map(|i| random(i, 0, 0, Purpose::Bench, 7))
            .sum::<f32>()
            / n as f32;
        assert!((mean - 0.5).abs() < 0.01, "{mean}");
    }
}
