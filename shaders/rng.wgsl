// rng.wgsl — counter-based random numbers, the exact mirror of core/src/rng.rs: PCG's output
// permutation chained over (seed, pixel, sample, bounce, purpose). u32 arithmetic wraps in
// WGSL as wrapping_mul/wrapping_add do in Rust, so both sides give the same bits.

// prismbake::rng::Purpose.
const PURPOSE_MARCH_JITTER: u32 = 1u;
const PURPOSE_PIXEL_JITTER: u32 = 2u;
const PURPOSE_BSDF: u32 = 3u;
const PURPOSE_LIGHT: u32 = 4u;
const PURPOSE_ALPHA: u32 = 6u;

fn pcg_hash(x: u32) -> u32 {
    let state = x * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

fn hash_counters(pixel: u32, sample: u32, bounce: u32, purpose: u32, seed: u32) -> u32 {
    var h = pcg_hash(seed ^ 0x9e3779b9u);
    h = pcg_hash(h ^ pixel);
    h = pcg_hash(h ^ sample);
    h = pcg_hash(h ^ bounce);
    return pcg_hash(h ^ purpose);
}

// Uniform float in [0, 1) from the 24 high bits (exact in f32, so bit-identical to the CPU).
fn to_unit_float(h: u32) -> f32 {
    return f32(h >> 8u) * (1.0 / 16777216.0);
}

fn random(pixel: u32, sample: u32, bounce: u32, purpose: u32, seed: u32) -> f32 {
    return to_unit_float(hash_counters(pixel, sample, bounce, purpose, seed));
}

// rng::random_keyed: `random` further keyed by `key` (a prism).
fn random_keyed(pixel: u32, sample: u32, bounce: u32, purpose: u32, seed: u32, key: u32) -> f32 {
    return to_unit_float(pcg_hash(hash_counters(pixel, sample, bounce, purpose, seed) ^ key));
}
