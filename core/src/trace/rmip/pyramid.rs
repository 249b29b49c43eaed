//! The rectangular min-max image pyramid (RMIP, Thonat et al. 2023 §5): min/max of the height
//! map over any axis-aligned texel rectangle from four look-ups.
//!
//! Following Amir et al. 2007, a `w × h` range is the union of four (overlapping) ranges of
//! size `(2^p, 2^q)`, `p = ⌊log₂ w⌋`, `q = ⌊log₂ h⌋`, placed at its corners (eq. 5). Layer
//! `(p, q)` stores, for every top-left cell `(x, y)`, the min/max over
//! `[x, x+2^p) × [y, y+2^q)` *taken modulo the grid* (Fig. 6's orange queries), so a
//! rectangle that wraps around a repeat-mode map is still four look-ups.
//!
//! Compression (the paper's supplement reduces the `N²(1+log₂N)²` entries to `O(N²)`; its
//! exact scheme is not public): the pyramid is built over a coarser grid of *cells* of
//! `cell × cell` texels (each cell the min/max of its texels, like a min-max mip level), and
//! the resolution is chosen so that all layers together hold at most `width × height` entries.
//! A texel query is snapped outwards to whole cells, so it stays conservative, and it is exact
//! when `cell == 1` (`RmipOptions::resolution` = the map's size). As the paper notes, this loses
//! tightness only for rectangles smaller than a few cells, which texel marching covers.
//! Maps need not be square nor powers of two: the last cell of a row/column may be partial,
//! and cell indices still wrap consistently (cell `cw + j` is cell `j`).

use crate::heightmap::{HeightMap, Wrap};
use rayon::prelude::*;

#[derive(Clone, Debug)]
pub struct Pyramid {
    /// Map size in texels.
    width: u32,
    height: u32,
    /// Texels per cell side.
    cell: u32,
    /// Grid size in cells (the RMIP resolution).
    cw: u32,
    ch: u32,
    /// Layers along x: `p ∈ 0..levels_x` with `2^p ≤ cw` (likewise `q` with `ch`).
    levels_x: u32,
    wrap: Wrap,
    /// Layer `(p, q)` at `((q * levels_x + p) * cw * ch)`, row-major, `[min, max]`.
    data: Vec<[f32; 2]>,
}

/// `⌊log₂ n⌋ + 1` for `n ≥ 1`.
fn level_count(n: u32) -> u32 {
    32 - n.leading_zeros()
}

fn grid(n: u32, cell: u32) -> u32 {
    n.div_ceil(cell)
}

/// Entries of a pyramid with the given cell size.
pub fn entries_for_cell(width: u32, height: u32, cell: u32) -> u64 {
    let (cw, ch) = (grid(width, cell), grid(height, cell));
    cw as u64 * ch as u64 * level_count(cw) as u64 * level_count(ch) as u64
}

/// Smallest power-of-two cell whose pyramid holds at most `width × height` entries.
pub fn auto_cell(width: u32, height: u32) -> u32 {
    let budget = width as u64 * height as u64;
    let mut cell = 1;
    while entries_for_cell(width, height, cell) > budget && cell < width.max(height) {
        cell *= 2;
    }
    cell
}

#[inline]
fn merge(a: [f32; 2], b: [f32; 2]) -> [f32; 2] {
    [a[0].min(b[0]), a[1].max(b[1])]
}

impl Pyramid {
    /// Build over `map` with `cell × cell` texels per RMIP texel (`cell ≥ 1`).
    pub fn build(map: &HeightMap, cell: u32) -> Self {
        let cell = cell.clamp(1, map.width.max(map.height));
        let (w, h) = (map.width, map.height);
        let (cw, ch) = (grid(w, cell), grid(h, cell));
        let (lx, ly) = (level_count(cw), level_count(ch));
        let layer = (cw * ch) as usize;
        let mut data = vec![[0.0f32; 2]; layer * (lx * ly) as usize];
        // Layer (0, 0): min/max of each cell's texels.
        data[..layer]
            .par_chunks_mut(cw as usize)
            .enumerate()
            .for_each(|(cy, row)| {
                for (cx, out) in row.iter_mut().enumerate() {
                    let x0 = cx as u32 * cell;
                    let y0 = cy as u32 * cell;
                    let mut mm = [f32::INFINITY, f32::NEG_INFINITY];
                    for y in y0..(y0 + cell).min(h) {
                        for x in x0..(x0 + cell).min(w) {
                            let v = map.data[(y * w + x) as usize];
                            mm = merge(mm, [v, v]);
                        }
                    }
                    *out = mm;
                }
            });
        // Each layer doubles one side of its predecessor's windows: (p, q) from (p−1, q), or
        // (0, q) from (0, q−1).
        for q in 0..ly {
            for p in 0..lx {
                if p == 0 && q == 0 {
                    continue;
                }
                let (src, shift) = if p > 0 {
                    (
                        ((q * lx + p - 1) as usize) * layer,
                        (1usize << (p - 1), 0usize),
                    )
                } else {
                    (((q - 1) * lx) as usize * layer, (0, 1usize << (q - 1)))
                };
                let dst = ((q * lx + p) as usize) * layer;
                let (head, tail) = data.split_at_mut(dst);
                let prev = &head[src..src + layer];
                let (cwu, chu) = (cw as usize, ch as usize);
                tail[..layer]
                    .par_chunks_mut(cwu)
                    .enumerate()
                    .for_each(|(y, row)| {
                        let y2 = (y + shift.1) % chu;
                        for (x, out) in row.iter_mut().enumerate() {
                            let x2 = (x + shift.0) % cwu;
                            *out = merge(prev[y * cwu + x], prev[y2 * cwu + x2]);
                        }
                    });
            }
        }
        Pyramid {
            width: w,
            height: h,
            cell,
            cw,
            ch,
            levels_x: lx,
            wrap: map.wrap,
            data,
        }
    }

    pub fn cell(&self) -> u32 {
        self.cell
    }

    /// RMIP resolution (cells per side).
    pub fn resolution(&self) -> (u32, u32) {
        (self.cw, self.ch)
    }

    pub fn memory_bytes(&self) -> usize {
        self.data.len() * std::mem::size_of::<[f32; 2]>()
    }

    /// Cells `[start, start + count)` (start may exceed the grid: it wraps) covering the
    /// inclusive texel range `[t0, t1]` along an axis of `n` texels and `cn` cells.
    #[inline]
    fn axis(&self, t0: i64, t1: i64, n: u32, cn: u32) -> (u32, u32) {
        let (n, c) = (n as i64, self.cell as i64);
        match self.wrap {
            Wrap::Repeat => {
                if t1 - t0 + 1 >= n {
                    return (0, cn);
                }
                let s = t0.rem_euclid(n);
                let e = s + (t1 - t0);
                let cs = s / c;
                let ce = if e < n {
                    e / c
                } else {
                    cn as i64 + (e - n) / c
                };
                let count = ce - cs + 1;
                if count >= cn as i64 {
                    (0, cn)
                } else {
                    (cs as u32, count as u32)
                }
            }
            Wrap::Clamp => {
                let s = t0.clamp(0, n - 1) / c;
                let e = t1.clamp(0, n - 1) / c;
                (s as u32, (e - s + 1) as u32)
            }
        }
    }

    /// Raw map `(min, max)` over the inclusive texel rectangle `[x0, x1] × [y0, y1]` (any
    /// integers, `x0 ≤ x1`, `y0 ≤ y1`; the map's wrap mode applies). Conservative: exact
    /// over the rectangle grown to whole cells.
    #[inline]
    pub fn texel_range(&self, x0: i64, x1: i64, y0: i64, y1: i64) -> (f32, f32) {
        let (xs, xn) = self.axis(x0, x1, self.width, self.cw);
        let (ys, yn) = self.axis(y0, y1, self.height, self.ch);
        let p = level_count(xn) - 1;
        let q = level_count(yn) - 1;
        let base = ((q * self.levels_x + p) * self.cw * self.ch) as usize;
        let (xa, xb) = (xs % self.cw, (xs + xn - (1 << p)) % self.cw);
        let (ya, yb) = (ys % self.ch, (ys + yn - (1 << q)) % self.ch);
        let at = |x: u32, y: u32| self.data[base + (y * self.cw + x) as usize];
        let mm = merge(merge(at(xa, ya), at(xb, ya)), merge(at(xa, yb), at(xb, yb)));
        (mm[0], mm[1])
    }

    /// Raw map range that bilinear sampling can read anywhere in the continuous texel-space
    /// rectangle `[lo, hi]` (texel `i` has its centre at `i + 0.5`).
    #[inline]
    pub fn sample_range(&self, lo: glam::DVec2, hi: glam::DVec2) -> (f32, f32) {
        let x0 = (lo.x - 0.5).floor() as i64;
        let x1 = (hi.x - 0.5).floor() as i64 + 1;
        let y0 = (lo.y - 0.5).floor() as i64;
        let y1 = (hi.y - 0.5).floor() as i64 + 1;
        self.texel_range(x0, x1, y0, y1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{pcg_hash, to_unit_float};

    fn random_map(w: u32, h: u32, wrap: Wrap, seed: u32) -> HeightMap {
        let mut s = seed;
        let data = (0..w * h)
            .map(|_| {
                s = pcg_hash(s);
                to_unit_float(s)
            })
            .collect();
        HeightMap::new(w, h, data, wrap)
    }

    /// Brute force over the texels, with the rectangle first grown to whole cells.
    fn brute(map: &HeightMap, cell: i64, x0: i64, x1: i64, y0: i64, y1: i64) -> (f32, f32) {
        let grow = |a: i64, b: i64, n: i64| -> (i64, i64) {
            match map.wrap {
                Wrap::Repeat if b - a + 1 >= n => (0, n - 1),
                Wrap::Repeat => {
                    let s = a.rem_euclid(n);
                    let e = s + (b - a);
                    let s2 = s / cell * cell;
                    // The cell holding e (in the unwrapped frame), to its end (partial last).
                    let (ew, off) = if e < n { (e, 0) } else { (e - n, n) };
                    let e2 = ((ew / cell + 1) * cell).min(n) - 1 + off;
                    (s2, e2)
                }
                Wrap::Clamp => {
                    let s = a.clamp(0, n - 1) / cell * cell;
                    let e = (((b.clamp(0, n - 1)) / cell + 1) * cell).min(n) - 1;
                    (s, e)
                }
            }
        };
        let (a, b) = grow(x0, x1, map.width as i64);
        let (c, d) = grow(y0, y1, map.height as i64);
        map.texel_range(a, b, c, d)
    }

    /// Hundreds of random rectangles — inside the map, wrapping around its edges, larger than
    /// it, negative — on square, non-square and non-power-of-two maps, both wrap modes, exact
    /// (cell 1) and compressed pyramids: every query equals brute force over the same cells.
    /// Breaks if a layer is built with a wrong offset, the corner placement of eq. 5 is off
    /// by one, or wrapping cells are mis-numbered.
    #[test]
    fn range_queries_equal_brute_force() {
        let mut s = 99u32;
        let mut rnd = |n: i64| -> i64 {
            s = pcg_hash(s);
            (s as i64) % n
        };
        let mut checked = 0;
        for (w, h) in [(64, 64), (37, 20), (16, 48), (1, 9)] {
            for wrap in [Wrap::Repeat, Wrap::Clamp] {
                let map = random_map(w, h, wrap, w * 31 + h);
                for cell in [1, 2, 4, 8] {
                    let pyr = Pyramid::build(&map, cell);
                    for _ in 0..150 {
                        let (wi, hi) = (w as i64, h as i64);
                        let x0 = rnd(3 * wi) - wi;
                        let y0 = rnd(3 * hi) - hi;
                        let big = rnd(4) == 0;
                        let x1 = x0 + rnd(if big { 2 * wi + 2 } else { wi / 2 + 1 });
                        let big = rnd(4) == 0;
                        let y1 = y0 + rnd(if big { 2 * hi + 2 } else { hi / 2 + 1 });
                        let got = pyr.texel_range(x0, x1, y0, y1);
                        let want = brute(&map, pyr.cell() as i64, x0, x1, y0, y1);
                        assert_eq!(
                            got, want,
                            "{w}x{h} {wrap:?} cell {cell}: [{x0},{x1}]x[{y0},{y1}]"
                        );
                        if pyr.cell() == 1 {
                            assert_eq!(got, map.texel_range(x0, x1, y0, y1));
                        }
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked >= 4000);
    }

    #[test]
    fn compressed_pyramid_fits_the_n_squared_budget() {
        // The auto resolution holds at most width × height entries (the classic-mipmap order
        // of memory the paper's compression reaches), and cell 1 is the full N²(1+log₂N)².
        for (w, h) in [(256, 256), (1024, 1024), (512, 300), (1000, 1000)] {
            let cell = auto_cell(w, h);
            assert!(
                entries_for_cell(w, h, cell) <= w as u64 * h as u64,
                "{w}x{h}"
            );
            assert!(cell == 1 || entries_for_cell(w, h, cell / 2) > w as u64 * h as u64);
        }
        assert_eq!(entries_for_cell(256, 256, 1), 256 * 256 * 81);
        let map = random_map(256, 256, Wrap::Repeat, 3);
        let pyr = Pyramid::build(&map, auto_cell(256, 256));
        assert!(pyr.memory_bytes() <= 256 * 256 * 8);
        assert_eq!(pyr.texel_range(-5, 300, -9, 400), map.value_range());
    }
}
