//! The scalar the nonlinear tracer is generic over (`f32` with explicit FMA, or `f64`), and
//! the three-component vector it needs. Kept minimal: glam has no generic vector type.

use std::fmt::Debug;
use std::ops::{Add, Div, Mul, Neg, Sub};

pub trait Real:
    Copy
    + Debug
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    const ZERO: Self;
    const ONE: Self;
    const HALF: Self;
    /// Machine epsilon (unit roundoff × 2).
    const EPS: Self;
    const INFINITY: Self;
    fn of(x: f64) -> Self;
    fn of32(x: f32) -> Self;
    fn to_f32(self) -> f32;
    fn to_f64(self) -> f64;
    /// `self * a + b` with one rounding.
    fn fma(self, a: Self, b: Self) -> Self;
    fn abs(self) -> Self;
    fn sqrt(self) -> Self;
    fn copysign(self, sign: Self) -> Self;
    fn is_finite(self) -> bool;
    #[inline]
    fn min(self, o: Self) -> Self {
        if o < self {
            o
        } else {
            self
        }
    }
    #[inline]
    fn max(self, o: Self) -> Self {
        if o > self {
            o
        } else {
            self
        }
    }
}

macro_rules! impl_real {
    ($t:ty) => {
        impl Real for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const HALF: Self = 0.5;
            const EPS: Self = <$t>::EPSILON;
            const INFINITY: Self = <$t>::INFINITY;
            #[inline]
            fn of(x: f64) -> Self {
                x as $t
            }
            #[inline]
            fn of32(x: f32) -> Self {
                x as $t
            }
            #[inline]
            fn to_f32(self) -> f32 {
                self as f32
            }
            #[inline]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline]
            fn fma(self, a: Self, b: Self) -> Self {
                self.mul_add(a, b)
            }
            #[inline]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline]
            fn copysign(self, sign: Self) -> Self {
                <$t>::copysign(self, sign)
            }
            #[inline]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
        }
    };
}
impl_real!(f32);
impl_real!(f64);

/// `a·b − c·d` with one rounding error less (Kahan's algorithm via FMA).
#[inline]
pub fn diff_of_products<T: Real>(a: T, b: T, c: T, d: T) -> T {
    let cd = c * d;
    let err = (-c).fma(d, cd);
    let dop = a.fma(b, -cd);
    dop + err
}

/// Polynomial `c[0] + c[1] x + c[2] x²` (low to high), Horner with FMA.
#[inline]
pub fn eval2<T: Real>(c: &[T; 3], x: T) -> T {
    c[2].fma(x, c[1]).fma(x, c[0])
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct V3<T>(pub T, pub T, pub T);

impl<T: Real> V3<T> {
    #[inline]
    pub fn of(v: glam::Vec3) -> Self {
        V3(T::of32(v.x), T::of32(v.y), T::of32(v.z))
    }
    #[inline]
    pub fn to_vec3(self) -> glam::Vec3 {
        glam::Vec3::new(self.0.to_f32(), self.1.to_f32(), self.2.to_f32())
    }
    #[inline]
    pub fn dot(self, o: Self) -> T {
        self.0.fma(o.0, self.1.fma(o.1, self.2 * o.2))
    }
    #[inline]
    pub fn cross(self, o: Self) -> Self {
        V3(
            diff_of_products(self.1, o.2, self.2, o.1),
            diff_of_products(self.2, o.0, self.0, o.2),
            diff_of_products(self.0, o.1, self.1, o.0),
        )
    }
    #[inline]
    pub fn length(self) -> T {
        self.dot(self).sqrt()
    }
    #[inline]
    pub fn scale(self, s: T) -> Self {
        V3(self.0 * s, self.1 * s, self.2 * s)
    }
}

impl<T: Real> Add for V3<T> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        V3(self.0 + o.0, self.1 + o.1, self.2 + o.2)
    }
}

impl<T: Real> Sub for V3<T> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        V3(self.0 - o.0, self.1 - o.1, self.2 - o.2)
    }
}
