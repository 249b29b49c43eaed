//! Real roots of quadratics and cubics on an interval, after Yuksel 2022 ("High-Performance
//! Polynomial Root Finding for Graphics", HPG): the derivative's roots (a quadratic, solved in
//! closed form) split the interval into pieces where the cubic is monotonic; a piece whose
//! ends differ in sign holds exactly one root, found by Newton's method kept inside the
//! bracket (a step that leaves it is replaced by bisection). No closed-form cubic formula, so
//! no catastrophic cancellation near double roots or a vanishing leading coefficient.
//!
//! As in the paper's §5.3, every multiply-add is an explicit FMA (`Real::fma`), so the `f32`
//! build rounds once per Horner step. Departures from Yuksel's code: a critical point (or an
//! end) where the cubic is zero within its own evaluation error bound is reported as a root —
//! that is how double roots (a tangent ray grazing a micro-triangle) are found, since the
//! sign does not change there — and roots closer than the requested `x_err` are merged.

// `!(a < b)` is deliberate: it is also true for NaN, which must be rejected.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

use super::real::{diff_of_products, Real};

/// Real roots of `a x² + b x + c`, ascending, without the cancellation of the textbook
/// formula (pbrt-v4's `Quadratic`). `a == 0` falls back to the linear root.
#[inline]
pub fn quadratic<T: Real>(a: T, b: T, c: T, out: &mut [T; 2]) -> usize {
    if a == T::ZERO {
        if b == T::ZERO {
            return 0;
        }
        out[0] = -c / b;
        return out[0].is_finite() as usize;
    }
    let discrim = diff_of_products(b, b, T::of(4.0) * a, c);
    if discrim < T::ZERO {
        return 0;
    }
    let root = discrim.sqrt();
    let q = -T::HALF * (b + root.copysign(b));
    if q == T::ZERO {
        out[0] = T::ZERO;
        return 1;
    }
    let (r0, r1) = (q / a, c / q);
    let (r0, r1) = if r0 <= r1 { (r0, r1) } else { (r1, r0) };
    let mut n = 0;
    for r in [r0, r1] {
        if r.is_finite() {
            out[n] = r;
            n += 1;
        }
    }
    n
}

/// Cubic `c[0] + c[1] x + c[2] x² + c[3] x³` and its derivative at `x` (Horner, FMA).
#[inline]
pub fn eval3<T: Real>(c: &[T; 4], x: T) -> (T, T) {
    let p = c[3].fma(x, c[2]).fma(x, c[1]).fma(x, c[0]);
    let dp = (T::of(3.0) * c[3]).fma(x, T::of(2.0) * c[2]).fma(x, c[1]);
    (p, dp)
}

/// A running error bound of Horner's rule at `x` (Higham's γ_{2n} Σ|c_i||x|^i, with slack
/// for the rounding of the coefficients themselves).
#[inline]
fn eval_bound<T: Real>(c: &[T; 4], x: T) -> T {
    let ax = x.abs();
    let s = c[3]
        .abs()
        .fma(ax, c[2].abs())
        .fma(ax, c[1].abs())
        .fma(ax, c[0].abs());
    T::of(16.0) * T::EPS * s
}

/// Real roots of the cubic `c` (low to high) in `[x0, x1]`, ascending, in `out`; returns how
/// many. Roots are accurate to about `x_err` (absolute; Newton stops when a step is smaller).
pub fn cubic_roots<T: Real>(c: &[T; 4], x0: T, x1: T, x_err: T, out: &mut [T; 3]) -> usize {
    if !(x0 <= x1) {
        return 0;
    }
    // Ends and critical points, ascending.
    let mut pts = [x0; 4];
    let mut np = 1;
    let mut crit = [T::ZERO; 2];
    let nc = quadratic(T::of(3.0) * c[3], T::of(2.0) * c[2], c[1], &mut crit);
    for &x in &crit[..nc] {
        if x > x0 && x < x1 {
            pts[np] = x;
            np += 1;
        }
    }
    pts[np] = x1;
    np += 1;
    let mut val = [T::ZERO; 4];
    let mut zero = [false; 4];
    for i in 0..np {
        val[i] = eval3(c, pts[i]).0;
        zero[i] = val[i].abs() <= eval_bound(c, pts[i]);
    }
    let mut n = 0;
    let mut push = |r: T, out: &mut [T; 3]| {
        if n > 0 && (r - out[n - 1]).abs() <= x_err {
            return;
        }
        if n < 3 {
            out[n] = r;
            n += 1;
        }
    };
    for i in 0..np {
        if zero[i] {
            push(pts[i], out);
        }
        if i + 1 < np && !zero[i] && !zero[i + 1] && (val[i] < T::ZERO) != (val[i + 1] < T::ZERO) {
            let r = bracketed_newton(c, pts[i], val[i], pts[i + 1], val[i + 1], x_err);
            push(r, out);
        }
    }
    n
}

/// The one root of a monotonic piece `[a, b]` with `p(a)`, `p(b)` of opposite signs.
fn bracketed_newton<T: Real>(c: &[T; 4], a: T, pa: T, b: T, pb: T, x_err: T) -> T {
    // `neg` keeps the end where p < 0, `pos` the one where p > 0.
    let (mut neg, mut pos) = if pa < T::ZERO { (a, b) } else { (b, a) };
    // Start from the secant of the bracket (a good guess on a monotonic piece).
    let mut x = a - pa * (b - a) / (pb - pa);
    if !(x > a.min(b) && x < a.max(b)) {
        x = T::HALF * (a + b);
    }
    for _ in 0..80 {
        let (y, dy) = eval3(c, x);
        if y == T::ZERO {
            return x;
        }
        if y < T::ZERO {
            neg = x;
        } else {
            pos = x;
        }
        let mut next = x - y / dy;
        let (lo, hi) = (neg.min(pos), neg.max(pos));
        if !(next > lo && next < hi) {
            next = T::HALF * (lo + hi);
        }
        if (next - x).abs() <= x_err || hi - lo <= x_err {
            return next;
        }
        x = next;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{pcg_hash, to_unit_float};

    struct Rng(u32);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 = pcg_hash(self.0);
            to_unit_float(self.0) as f64
        }
        fn range(&mut self, a: f64, b: f64) -> f64 {
            a + (b - a) * self.next()
        }
    }

    /// `k (x − r0)(x − r1)(x − r2)` expanded, low to high.
    fn from_roots(k: f64, r: [f64; 3]) -> [f64; 4] {
        [
            -k * r[0] * r[1] * r[2],
            k * (r[0] * r[1] + r[1] * r[2] + r[0] * r[2]),
            -k * (r[0] + r[1] + r[2]),
            k,
        ]
    }

    fn roots<T: Real>(c: [f64; 4], lo: f64, hi: f64, x_err: f64) -> Vec<f64> {
        let c = c.map(T::of);
        let mut out = [T::ZERO; 3];
        let n = cubic_roots(&c, T::of(lo), T::of(hi), T::of(x_err), &mut out);
        out[..n].iter().map(|r| r.to_f64()).collect()
    }

    /// Every expected root in `[lo, hi]` (away from the ends) is found within `tol`, and
    /// nothing else is returned beyond `tol` of an expected root.
    fn check<T: Real>(c: [f64; 4], want: &[f64], lo: f64, hi: f64, tol: f64, what: &str) {
        let got = roots::<T>(c, lo, hi, tol * 1e-2);
        for w in want.iter().filter(|&&w| w > lo + tol && w < hi - tol) {
            assert!(
                got.iter().any(|g| (g - w).abs() <= tol),
                "{what}: root {w} not found in {got:?} ({c:?})"
            );
        }
        for g in &got {
            assert!(
                want.iter().any(|w| (g - w).abs() <= tol),
                "{what}: spurious root {g}, want {want:?} ({c:?})"
            );
        }
        assert!(
            got.windows(2).all(|p| p[0] <= p[1]),
            "{what}: not ascending {got:?}"
        );
    }

    fn random_cubics<T: Real>(tol_simple: f64, tol_double: f64) {
        let mut rng = Rng(0xC0B1C);
        for i in 0..4000 {
            let k = rng.range(0.2, 5.0) * if i % 2 == 0 { 1.0 } else { -1.0 };
            // Three simple roots at least 0.05 apart.
            let mut r = [
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ];
            r.sort_by(f64::total_cmp);
            if r[1] - r[0] > 0.05 && r[2] - r[1] > 0.05 {
                check::<T>(from_roots(k, r), &r, -1.2, 1.2, tol_simple, "simple");
            }
            // A double root and a simple one.
            let (d, s) = (rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
            if (d - s).abs() > 0.1 {
                check::<T>(
                    from_roots(k, [d, d, s]),
                    &[d, s],
                    -1.2,
                    1.2,
                    tol_double,
                    "double",
                );
            }
            // One real root and a complex pair.
            let (a, re, im) = (
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(0.1, 1.0),
            );
            let c = [
                -k * a * (re * re + im * im),
                k * (re * re + im * im + 2.0 * a * re),
                -k * (a + 2.0 * re),
                k,
            ];
            check::<T>(c, &[a], -1.2, 1.2, tol_simple, "complex pair");
            // Near-degenerate leading coefficient: k (x − r0)(x − r1)(ε x − 1), third root
            // at 1/ε far outside the interval.
            let eps = 10f64.powf(rng.range(-9.0, -4.0));
            let (r0, r1) = (rng.range(-1.0, -0.05), rng.range(0.05, 1.0));
            let (p, q) = (r0 + r1, r0 * r1);
            // (x² − p x + q)(ε x − 1) = ε x³ − (1 + ε p) x² + (p + ε q) x − q
            let c = [-k * q, k * (p + eps * q), -k * (1.0 + eps * p), k * eps];
            check::<T>(
                c,
                &[r0, r1, 1.0 / eps],
                -1.2,
                1.2,
                tol_simple,
                "tiny leading",
            );
            // Leading coefficient exactly zero: a plain quadratic.
            let c = [k * q, -k * p, k, 0.0];
            check::<T>(c, &[r0, r1], -1.2, 1.2, tol_simple, "quadratic");
        }
    }

    #[test]
    fn cubic_finds_every_root_f64() {
        // Breaks if a monotonic piece is skipped, a double root (no sign change) is lost, or a
        // tiny leading coefficient sends the derivative's roots astray.
        random_cubics::<f64>(1e-9, 1e-6);
    }

    #[test]
    fn cubic_finds_every_root_f32() {
        // The same cubics with f32 + FMA: simple roots to ~1e-4, double roots to ~√ε.
        random_cubics::<f32>(2e-4, 3e-3);
    }

    #[test]
    fn triple_root_and_constant() {
        let got = roots::<f64>(from_roots(1.0, [0.3, 0.3, 0.3]), -1.0, 1.0, 1e-12);
        assert!(
            !got.is_empty() && got.iter().all(|g| (g - 0.3).abs() < 1e-4),
            "{got:?}"
        );
        assert!(roots::<f32>([1.0, 0.0, 0.0, 0.0], -1.0, 1.0, 1e-6).is_empty());
        assert!(roots::<f32>([1.0, 1.0, 1.0, 1.0], 1.0, 0.0, 1e-6).is_empty());
    }

    #[test]
    fn quadratic_is_cancellation_free() {
        let mut out = [0.0f32; 2];
        assert_eq!(quadratic(1.0, -2e4, 1.0, &mut out), 2);
        assert!(
            (out[0] - 5e-5).abs() < 1e-9 && (out[1] - 2e4).abs() < 1.0,
            "{out:?}"
        );
        assert_eq!(quadratic(0.0, 2.0, -4.0, &mut out), 1);
        assert_eq!(out[0], 2.0);
        assert_eq!(quadratic(1.0, 0.0, 1.0, &mut out), 0);
    }
}
