//! Min-max mipmap of a height map: the nonlinear tracer's per-prism acceleration structure
//! (Ogaki 2023 §4.4, after Thonat et al. 2021). One pyramid per map, shared by every prism.
//!
//! Level 0 has one *cell* per texel: cell `(i, j)` spans the texel centres `i..i+1` and
//! `j..j+1` (in shifted texel coordinates `x = u W − 0.5`, `y = (1 − v) H − 0.5`), the square
//! where bilinear sampling reads exactly texels `(i, j)`, `(i+1, j)`, `(i, j+1)`, `(i+1, j+1)`
//! (wrap applied) — the two micro-triangles of the cell use the same four. Level `k` cell
//! `(i, j)` bounds level-0 cells `[i 2^k, (i+1) 2^k) × [j 2^k, (j+1) 2^k)`.
//!
//! Lookups take *unwrapped* cell indices (a UV footprint may straddle the repeat seam or lie
//! outside [0, 1]) and return a conservative range: for power-of-two maps exact, otherwise the
//! union of the ≤ 2 × 2 stored cells that cover the wrapped block.

use crate::heightmap::{HeightMap, Wrap};

struct Level {
    nx: usize,
    ny: usize,
    /// (min, max) of raw map values, row-major.
    cells: Vec<(f32, f32)>,
}

pub struct MinMaxMip {
    levels: Vec<Level>,
    width: i64,
    height: i64,
    wrap: Wrap,
}

impl MinMaxMip {
    pub fn new(map: &HeightMap) -> Self {
        let (w, h) = (map.width as usize, map.height as usize);
        let mut cells = Vec::with_capacity(w * h);
        for j in 0..h as i64 {
            for i in 0..w as i64 {
                let v = [
                    map.texel(i, j),
                    map.texel(i + 1, j),
                    map.texel(i, j + 1),
                    map.texel(i + 1, j + 1),
                ];
                cells.push((
                    v.iter().copied().fold(f32::INFINITY, f32::min),
                    v.iter().copied().fold(f32::NEG_INFINITY, f32::max),
                ));
            }
        }
        let mut levels = vec![Level {
            nx: w,
            ny: h,
            cells,
        }];
        while levels.last().is_some_and(|l| l.nx > 1 || l.ny > 1) {
            let prev = levels.last().unwrap();
            let (nx, ny) = (prev.nx.div_ceil(2), prev.ny.div_ceil(2));
            // A child index past the end (odd size) stands for wrapped or clamped cells: with
            // repeat they lie within the first two cells of the row, with clamp they repeat
            // the last one (see the module doc).
            let fold = |c: usize, n: usize, out: &mut [usize; 3]| -> usize {
                if c < n {
                    out[0] = c;
                    1
                } else if map.wrap == Wrap::Repeat {
                    out[0] = 0;
                    out[1] = 1.min(n - 1);
                    2
                } else {
                    out[0] = n - 1;
                    1
                }
            };
            let mut cells = Vec::with_capacity(nx * ny);
            for j in 0..ny {
                for i in 0..nx {
                    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                    for cj in [2 * j, 2 * j + 1] {
                        let mut ys = [0; 3];
                        let nys = fold(cj, prev.ny, &mut ys);
                        for ci in [2 * i, 2 * i + 1] {
                            let mut xs = [0; 3];
                            let nxs = fold(ci, prev.nx, &mut xs);
                            for &y in &ys[..nys] {
                                for &x in &xs[..nxs] {
                                    let (a, b) = prev.cells[y * prev.nx + x];
                                    lo = lo.min(a);
                                    hi = hi.max(b);
                                }
                            }
                        }
                    }
                    cells.push((lo, hi));
                }
            }
            levels.push(Level { nx, ny, cells });
        }
        MinMaxMip {
            levels,
            width: w as i64,
            height: h as i64,
            wrap: map.wrap,
        }
    }

    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    pub fn bytes(&self) -> usize {
        self.levels.iter().map(|l| l.cells.len() * 8).sum()
    }

    /// Stored cells (≤ 2) of level `k` covering the unwrapped block `[i 2^k, (i+1) 2^k)` of
    /// one axis of size `size`, with `n` stored cells.
    #[inline]
    fn axis_cells(&self, k: usize, i: i64, size: i64, n: usize) -> (usize, usize) {
        if n == 1 {
            return (0, 0);
        }
        let span = 1i64 << k;
        match self.wrap {
            Wrap::Repeat => {
                let start = (i * span).rem_euclid(size);
                let s0 = (start >> k) as usize;
                if start & (span - 1) == 0 {
                    (s0, s0)
                } else {
                    (s0, (s0 + 1) % n)
                }
            }
            Wrap::Clamp => {
                let a = (i * span).clamp(0, size - 1);
                let b = (i * span + span - 1).clamp(0, size - 1);
                ((a >> k) as usize, (b >> k) as usize)
            }
        }
    }

    /// Conservative (min, max) of the raw map over block `(ix, iy)` of level `k` (unwrapped
    /// indices; a level above the top reads the top).
    #[inline]
    pub fn range(&self, k: usize, ix: i64, iy: i64) -> (f32, f32) {
        let top = self.levels.len() - 1;
        let l = &self.levels[k.min(top)];
        if k > top {
            return l.cells[0];
        }
        let (x0, x1) = self.axis_cells(k, ix, self.width, l.nx);
        let (y0, y1) = self.axis_cells(k, iy, self.height, l.ny);
        let mut r = l.cells[y0 * l.nx + x0];
        for (x, y) in [(x1, y0), (x0, y1), (x1, y1)] {
            let c = l.cells[y * l.nx + x];
            r = (r.0.min(c.0), r.1.max(c.1));
        }
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{pcg_hash, to_unit_float};

    fn noise_map(w: u32, h: u32, wrap: Wrap) -> HeightMap {
        let mut s = 5u32;
        let data = (0..w * h)
            .map(|_| {
                s = pcg_hash(s);
                to_unit_float(s)
            })
            .collect();
        HeightMap::new(w, h, data, wrap)
    }

    /// Brute force over the level-0 cells of an unwrapped block.
    fn brute(map: &HeightMap, k: usize, ix: i64, iy: i64) -> (f32, f32) {
        let s = 1i64 << k;
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for j in iy * s..(iy + 1) * s {
            for i in ix * s..(ix + 1) * s {
                for (x, y) in [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)] {
                    lo = lo.min(map.texel(x, y));
                    hi = hi.max(map.texel(x, y));
                }
            }
        }
        (lo, hi)
    }

    #[test]
    fn ranges_bound_every_block_and_are_exact_for_power_of_two() {
        // Breaks if a block's stored range misses a texel its micro-triangles read (a hole in
        // the traversal), for blocks straddling the repeat seam, outside [0,1] and past the
        // clamped edge, at every level; power-of-two maps must be exact (no lost speed).
        for (w, h, wrap) in [
            (16, 16, Wrap::Repeat),
            (16, 8, Wrap::Clamp),
            (13, 7, Wrap::Repeat),
            (13, 7, Wrap::Clamp),
            (1, 1, Wrap::Repeat),
        ] {
            let map = noise_map(w, h, wrap);
            let mip = MinMaxMip::new(&map);
            let pot = w.is_power_of_two() && h.is_power_of_two();
            for k in 0..mip.level_count() + 1 {
                for iy in -3..4 {
                    for ix in -3..4 {
                        let (lo, hi) = mip.range(k, ix, iy);
                        let (blo, bhi) = brute(&map, k, ix, iy);
                        assert!(lo <= blo && hi >= bhi, "{w}x{h} {wrap:?} k{k} ({ix},{iy})");
                        if pot && wrap == Wrap::Repeat {
                            assert_eq!((lo, hi), (blo, bhi), "{w}x{h} k{k} ({ix},{iy})");
                        }
                    }
                }
            }
        }
    }
}
