//! Height maps and the displacement convention.
//!
//! `D(u, v) = scale * (h(u, v) - midlevel)` (Blender's Displacement node; USD's UsdUVTexture
//! with `bias = -midlevel * scale`). `h` is in [0, 1] for integer formats and the raw value
//! for float formats. Sampling is bilinear with texel centres at `(i + 0.5) / N`; row 0 of
//! `data` is the *top* row of the image and `v` points up, so `v = 1 - (row + 0.5) / height`
//! at a texel centre.

use glam::Vec2;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Wrap {
    #[default]
    Repeat,
    Clamp,
}

impl std::str::FromStr for Wrap {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "repeat" => Ok(Wrap::Repeat),
            "clamp" => Ok(Wrap::Clamp),
            _ => Err(format!(
                "unknown wrap mode '{s}' (expected repeat or clamp)"
            )),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DisplaceParams {
    pub scale: f32,
    pub midlevel: f32,
}

impl Default for DisplaceParams {
    fn default() -> Self {
        DisplaceParams {
            scale: 1.0,
            midlevel: 0.5,
        }
    }
}

impl DisplaceParams {
    #[inline]
    pub fn displacement(&self, h: f32) -> f32 {
        self.scale * (h - self.midlevel)
    }
    /// The displacement range spanned by map values in `[hmin, hmax]` (scale may be negative).
    pub fn displacement_range(&self, hmin: f32, hmax: f32) -> (f32, f32) {
        let (a, b) = (self.displacement(hmin), self.displacement(hmax));
        (a.min(b), a.max(b))
    }
}

#[derive(Clone, Debug)]
pub struct HeightMap {
    pub width: u32,
    pub height: u32,
    /// Row-major, row 0 at the top of the image.
    pub data: Vec<f32>,
    pub wrap: Wrap,
    pub source: PathBuf,
    /// The channel that was read (`Y`, `R`, `L`, ...).
    pub channel: String,
}

impl HeightMap {
    pub fn new(width: u32, height: u32, data: Vec<f32>, wrap: Wrap) -> Self {
        assert_eq!(data.len(), width as usize * height as usize);
        HeightMap {
            width,
            height,
            data,
            wrap,
            source: PathBuf::new(),
            channel: String::new(),
        }
    }

    /// Texel (x, y) with the wrap mode applied; x, y may be any integers.
    #[inline]
    pub fn texel(&self, x: i64, y: i64) -> f32 {
        let (w, h) = (self.width as i64, self.height as i64);
        let (x, y) = match self.wrap {
            Wrap::Repeat => (wrap(x, w), wrap(y, h)),
            Wrap::Clamp => (x.clamp(0, w - 1), y.clamp(0, h - 1)),
        };
        self.data[(y * w + x) as usize]
    }

    /// Continuous texel coordinates of a UV: texel (i, j) has its centre at (i + 0.5, j + 0.5).
    #[inline]
    pub fn texel_coords(&self, uv: Vec2) -> Vec2 {
        Vec2::new(uv.x * self.width as f32, (1.0 - uv.y) * self.height as f32)
    }

    /// The four texels a bilinear sample at continuous texel position `p` (centres at
    /// integers) reads, `floor(p)` and the fraction. Fast path: all four inside the map, no
    /// wrap arithmetic and no libm `floor` call (`p ≥ 0`, so truncation is the floor; same
    /// texels, so bit-identical to the general path).
    #[inline(always)]
    fn bilinear_texels(&self, p: Vec2) -> ([f32; 4], f32, f32) {
        if p.x >= 0.0
            && p.y >= 0.0
            && p.x < self.width.saturating_sub(1) as f32
            && p.y < self.height.saturating_sub(1) as f32
        {
            // In range of `i32` (below the map's size): a 32-bit conversion, cheaper than a
            // saturating one to `usize`.
            let (x, y) = (p.x as i32, p.y as i32);
            let (tx, ty) = (p.x - x as f32, p.y - y as f32);
            let w = self.width as usize;
            let i = y as usize * w + x as usize;
            // One bounds check for the four texels.
            let q = &self.data[i..i + w + 2];
            return ([q[0], q[1], q[w], q[w + 1]], tx, ty);
        }
        let (fx, fy) = (floor(p.x), floor(p.y));
        let (tx, ty) = (p.x - fx, p.y - fy);
        // Far-off or NaN coordinates (a ray point far outside its prism) must not overflow
        // `x + 1`: clamp to a range where the wrap arithmetic is exact (NaN becomes 0).
        let (x, y) = (fx.clamp(-1e9, 1e9) as i64, fy.clamp(-1e9, 1e9) as i64);
        if self.wrap == Wrap::Repeat {
            // Tiled UVs (beyond [0, 1]): wrap the corner once per axis, not per texel; the
            // same texels and fractions as `texel`'s wrap.
            let (w, h) = (self.width as i64, self.height as i64);
            let (x0, y0) = (wrap(x, w), wrap(y, h));
            let x1 = if x0 + 1 == w { 0 } else { x0 + 1 };
            let y1 = if y0 + 1 == h { 0 } else { y0 + 1 };
            let at = |x: i64, y: i64| self.data[(y * w + x) as usize];
            return ([at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1)], tx, ty);
        }
        (
            [
                self.texel(x, y),
                self.texel(x + 1, y),
                self.texel(x, y + 1),
                self.texel(x + 1, y + 1),
            ],
            tx,
            ty,
        )
    }

    /// Bilinear sample of the raw map value at `uv`.
    #[inline]
    pub fn sample(&self, uv: Vec2) -> f32 {
        let p = self.texel_coords(uv) - Vec2::splat(0.5);
        let ([a, b, c, d], tx, ty) = self.bilinear_texels(p);
        let top = a + (b - a) * tx;
        let bottom = c + (d - c) * tx;
        top + (bottom - top) * ty
    }

    /// Bilinear sample and its gradient with respect to (u, v).
    pub fn sample_grad(&self, uv: Vec2) -> (f32, Vec2) {
        let p = self.texel_coords(uv) - Vec2::splat(0.5);
        let ([a, b, c, d], tx, ty) = self.bilinear_texels(p);
        let top = a + (b - a) * tx;
        let bottom = c + (d - c) * tx;
        let value = top + (bottom - top) * ty;
        let d_dx = (b - a) + ((d - c) - (b - a)) * ty;
        let d_dy = bottom - top;
        // x grows with u; y (rows) grows as v falls.
        let grad = Vec2::new(d_dx * self.width as f32, -d_dy * self.height as f32);
        (value, grad)
    }

    /// Min and max over every texel in the inclusive integer rectangle (wrap applied).
    pub fn texel_range(&self, x0: i64, x1: i64, y0: i64, y1: i64) -> (f32, f32) {
        let (w, h) = (self.width as i64, self.height as i64);
        // A rectangle wider than the map covers every column (likewise rows).
        let (x0, x1) = if x1 - x0 + 1 >= w && self.wrap == Wrap::Repeat {
            (0, w - 1)
        } else {
            (x0, x1)
        };
        let (y0, y1) = if y1 - y0 + 1 >= h && self.wrap == Wrap::Repeat {
            (0, h - 1)
        } else {
            (y0, y1)
        };
        let mut lo = f32::INFINITY;
        let mut hi = f32::NEG_INFINITY;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let v = self.texel(x, y);
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        (lo, hi)
    }

    pub fn value_range(&self) -> (f32, f32) {
        self.data
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            })
    }

    /// First texel that is NaN or infinite, as (x, y).
    pub fn first_non_finite(&self) -> Option<(u32, u32)> {
        self.data.iter().position(|v| !v.is_finite()).map(|i| {
            (
                (i % self.width as usize) as u32,
                (i / self.width as usize) as u32,
            )
        })
    }
}

/// `x.rem_euclid(n)` for `n > 0`: a mask where `n` is a power of two (two's complement makes
/// it the Euclidean remainder for negative `x` too), else the division.
#[inline]
fn wrap(x: i64, n: i64) -> i64 {
    if n & (n - 1) == 0 {
        x & (n - 1)
    } else {
        x.rem_euclid(n)
    }
}

/// `x.floor()` without the libm call (the x86-64 baseline has no rounding instruction):
/// truncation, one less for negative non-integers; `|x| ≥ 2²³` is already an integer, and
/// NaN stays NaN.
#[inline]
fn floor(x: f32) -> f32 {
    if x.abs() < 8_388_608.0 {
        let t = x as i32 as f32;
        if t > x {
            t - 1.0
        } else {
            t
        }
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texel_centres_sample_exactly() {
        // 2x2 map: top row 0, 1; bottom row 2, 3.
        let m = HeightMap::new(2, 2, vec![0.0, 1.0, 2.0, 3.0], Wrap::Clamp);
        assert_eq!(m.sample(Vec2::new(0.25, 0.75)), 0.0); // top-left texel centre
        assert_eq!(m.sample(Vec2::new(0.75, 0.75)), 1.0);
        assert_eq!(m.sample(Vec2::new(0.25, 0.25)), 2.0); // bottom-left: v up
        assert_eq!(m.sample(Vec2::new(0.5, 0.5)), 1.5);
    }

    #[test]
    fn fast_path_is_bit_identical_to_the_wrapped_texels() {
        // `sample`'s in-range fast path against the general `texel` path, over the whole map
        // and past its edges, both wrap modes.
        let data: Vec<f32> = (0..35)
            .map(|i| ((i * 13) % 7) as f32 * 0.37 + i as f32 * 1e-3)
            .collect();
        for wrap in [Wrap::Repeat, Wrap::Clamp] {
            let m = HeightMap::new(7, 5, data.clone(), wrap);
            for k in 0..4000 {
                let uv = Vec2::new((k % 63) as f32 / 41.0 - 0.3, (k / 63) as f32 / 47.0 - 0.2);
                let p = m.texel_coords(uv) - Vec2::splat(0.5);
                let (fx, fy) = (p.x.floor(), p.y.floor());
                let (tx, ty) = (p.x - fx, p.y - fy);
                let (x, y) = (fx as i64, fy as i64);
                let (a, b) = (m.texel(x, y), m.texel(x + 1, y));
                let (c, d) = (m.texel(x, y + 1), m.texel(x + 1, y + 1));
                let top = a + (b - a) * tx;
                let bottom = c + (d - c) * tx;
                let want = top + (bottom - top) * ty;
                assert_eq!(m.sample(uv).to_bits(), want.to_bits(), "{uv}");
            }
        }
    }

    #[test]
    fn wrap_is_the_euclidean_remainder() {
        for n in [1i64, 2, 3, 7, 8, 1024, 1000] {
            for x in (-5000i64..5000).chain([i64::MIN / 4, -1_000_000_007, 1_000_000_007]) {
                assert_eq!(wrap(x, n), x.rem_euclid(n), "{x} mod {n}");
            }
        }
    }

    #[test]
    fn floor_is_libm_floor() {
        let mut xs = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            8_388_607.5,
            -8_388_607.5,
            1e9,
            -1e9,
        ];
        xs.extend((0..20_000).map(|i| (i as f32 - 10_000.0) * 0.0173));
        for x in xs {
            assert_eq!(floor(x), x.floor(), "{x}");
        }
        assert!(floor(f32::NAN).is_nan());
        assert_eq!(floor(f32::INFINITY), f32::INFINITY);
        assert_eq!(floor(f32::NEG_INFINITY), f32::NEG_INFINITY);
    }

    #[test]
    fn repeat_wraps_between_edges() {
        let m = HeightMap::new(2, 1, vec![0.0, 1.0], Wrap::Repeat);
        // u = 0 sits halfway between the last and first texel centres.
        assert!((m.sample(Vec2::new(0.0, 0.5)) - 0.5).abs() < 1e-6);
        let c = HeightMap::new(2, 1, vec![0.0, 1.0], Wrap::Clamp);
        assert_eq!(c.sample(Vec2::new(0.0, 0.5)), 0.0);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let data: Vec<f32> = (0..16).map(|i| ((i * 7) % 5) as f32).collect();
        let m = HeightMap::new(4, 4, data, Wrap::Repeat);
        let uv = Vec2::new(0.37, 0.61);
        let (_, g) = m.sample_grad(uv);
        let e = 1e-3;
        let gx = (m.sample(uv + Vec2::new(e, 0.0)) - m.sample(uv - Vec2::new(e, 0.0))) / (2.0 * e);
        let gy = (m.sample(uv + Vec2::new(0.0, e)) - m.sample(uv - Vec2::new(0.0, e))) / (2.0 * e);
        assert!(
            (g.x - gx).abs() < 1e-2 * gx.abs().max(1.0),
            "{g} vs {gx},{gy}"
        );
        assert!(
            (g.y - gy).abs() < 1e-2 * gy.abs().max(1.0),
            "{g} vs {gx},{gy}"
        );
    }
}
