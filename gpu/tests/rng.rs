//! The WGSL hash is the CPU's bit for bit: `pcg_hash`, `hash_counters` and `random` evaluated
//! on the adapter for frozen and pseudo-random counters equal `prismbake::rng`. Breaks if either
//! side changes the hash (which would silently change every jittered image on one device only).

use crate::util;
use prismbake::rng::{self, Purpose};
use prismbake_gpu::shaders;

const PROBE: &str = r#"
// Per case: in = (x, pixel, sample, bounce, purpose, seed), out = (pcg, counters, random bits).
@group(0) @binding(0) var<storage, read_write> io: array<u32>;

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = arrayLength(&io) / 9u;
    if (gid.x >= n) {
        return;
    }
    let b = gid.x * 9u;
    io[b + 6u] = pcg_hash(io[b]);
    io[b + 7u] = hash_counters(io[b + 1u], io[b + 2u], io[b + 3u], io[b + 4u], io[b + 5u]);
    io[b + 8u] = bitcast<u32>(random(io[b + 1u], io[b + 2u], io[b + 3u], io[b + 4u], io[b + 5u]));
}
"#;

fn run_probe(cases: &[[u32; 6]]) -> Vec<[u32; 3]> {
    let data: Vec<u32> = cases
        .iter()
        .flat_map(|c| c.iter().copied().chain([0, 0, 0]))
        .collect();
    let src = format!("{}\n{}", shaders::RNG, PROBE);
    let out = util::run_probe("rng probe", &src, (0, 0), &data, &[]);
    out.chunks(9).map(|c| [c[6], c[7], c[8]]).collect()
}

fn purpose(p: u32) -> Purpose {
    [
        Purpose::MarchJitter,
        Purpose::PixelJitter,
        Purpose::Bsdf,
        Purpose::Light,
        Purpose::Bench,
    ][(p % 5) as usize]
}

#[test]
fn hashes_match_the_cpu_bit_for_bit() {
    // Frozen values first (the CPU's own frozen test), then 4096 pseudo-random counters
    // including the extremes of u32.
    let mut cases = vec![
        [0, 0, 0, 0, 1, 0],
        [1, 7, 3, 1, 2, 42],
        [u32::MAX, u32::MAX, u32::MAX, 1, 5, u32::MAX],
    ];
    let mut h = 99u32;
    for _ in 0..4096 {
        let mut next = || {
            h = rng::pcg_hash(h);
            h
        };
        cases.push([
            next(),
            next(),
            next() % 64,
            next() % 4,
            next() % 5 + 1,
            next(),
        ]);
    }
    let gpu = run_probe(&cases);
    assert_eq!(gpu[0][0], 129708002, "pcg_hash(0)");
    for (c, g) in cases.iter().zip(&gpu) {
        let p = purpose(c[4] - 1);
        assert_eq!(p as u32, c[4]);
        let want = [
            rng::pcg_hash(c[0]),
            rng::hash_counters(c[1], c[2], c[3], p, c[5]),
            rng::random(c[1], c[2], c[3], p, c[5]).to_bits(),
        ];
        assert_eq!(*g, want, "counters {c:?}");
    }
}
