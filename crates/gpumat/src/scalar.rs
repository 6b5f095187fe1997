//! Scalar types: the real scalars `f32`/`f64` and the traits every matrix element obeys.
//!
//! cuMat (thesis ch. 3) treats small fixed-size blocks (`float4`, 3x3 matrices) as scalars, so
//! that a block-sparse matrix is "just" a sparse matrix whose entries are blocks. We do the
//! same: every element type is a bundle of `LANES` real lanes. Element-wise unary functions act
//! lane by lane, `+ - /` act lane by lane, and the element product `*` is the scalar's own
//! product ([`ScalarMul`]): lane-wise for `Vec3 * Vec3`, the matrix product for `Mat3 * Mat3`
//! and `Mat3 * Vec3`, scaling for `real * block`.

use std::fmt::Debug;

/// An element of a [`crate::Matrix`]: a real number or a small block of real lanes.
pub trait Scalar: Copy + Send + Sync + Debug + PartialEq + Default + 'static {
    /// The real type of the lanes (`f32` or `f64`).
    type Real: Real;
    /// Number of meaningful lanes (1 for reals, 3 for `Vec3`, 9 for `Mat3`).
    const LANES: usize;
    /// Name of the matching CUDA type (used by the kernel generator of the CUDA backend).
    const CUDA_TYPE: &'static str;

    /// All lanes zero.
    const ZERO: Self;
    /// The multiplicative identity (1, (1,1,1), the identity matrix).
    const ONE: Self;
    /// Lane `i` (`i < LANES`).
    fn lane(&self, i: usize) -> Self::Real;
    /// Builds a value lane by lane.
    fn from_lanes(f: impl FnMut(usize) -> Self::Real) -> Self;
    /// Applies `f` to every lane.
    fn map(self, f: impl Fn(Self::Real) -> Self::Real) -> Self;
    /// Combines two values lane by lane.
    fn zip(self, other: Self, f: impl Fn(Self::Real, Self::Real) -> Self::Real) -> Self;
    /// The block transpose (identity for reals and vectors).
    fn transpose(self) -> Self {
        self
    }

    /// `self + other`, lane-wise.
    #[inline(always)]
    fn add(self, other: Self) -> Self {
        self.zip(other, |a, b| a + b)
    }
    /// `self - other`, lane-wise.
    #[inline(always)]
    fn sub(self, other: Self) -> Self {
        self.zip(other, |a, b| a - b)
    }
    /// `s * self`.
    #[inline(always)]
    fn scale(self, s: Self::Real) -> Self {
        self.map(|a| a * s)
    }
    /// Sum over lanes of the lane products (the Euclidean / Frobenius inner product).
    #[inline(always)]
    fn dot(self, other: Self) -> Self::Real {
        let mut acc = <Self::Real as Scalar>::ZERO;
        for i in 0..Self::LANES {
            acc += self.lane(i) * other.lane(i);
        }
        acc
    }
    /// True when every lane is finite.
    fn is_finite(&self) -> bool {
        (0..Self::LANES).all(|i| num_traits::Float::is_finite(self.lane(i)))
    }
}

/// A real scalar: `f32` or `f64`.
pub trait Real:
    Scalar<Real = Self>
    + num_traits::Float
    + std::iter::Sum
    + bytemuck::Pod
    + faer::traits::RealField
    + std::fmt::Display
    + std::str::FromStr
{
    /// Converts from `f64` (rounding for `f32`).
    fn of(x: f64) -> Self;
    /// Converts to `f64` exactly.
    fn as_f64(self) -> f64;
    /// The value as a CUDA C++ literal of this type: `2.0f` for `f32`, `2.0` for `f64`
    /// (shortest round-trip digits); infinities and NaN as their bit patterns.
    fn cuda_literal(self) -> String;
}

macro_rules! impl_real {
    ($t:ty, $cuda:literal, |$v:ident| $literal:expr) => {
        impl Scalar for $t {
            type Real = $t;
            const LANES: usize = 1;
            const CUDA_TYPE: &'static str = $cuda;
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            #[inline(always)]
            fn lane(&self, _i: usize) -> $t {
                *self
            }
            #[inline(always)]
            fn from_lanes(mut f: impl FnMut(usize) -> $t) -> Self {
                f(0)
            }
            #[inline(always)]
            fn map(self, f: impl Fn($t) -> $t) -> Self {
                f(self)
            }
            #[inline(always)]
            fn zip(self, other: Self, f: impl Fn($t, $t) -> $t) -> Self {
                f(self, other)
            }
            #[inline(always)]
            fn add(self, other: Self) -> Self {
                self + other
            }
            #[inline(always)]
            fn sub(self, other: Self) -> Self {
                self - other
            }
            #[inline(always)]
            fn scale(self, s: $t) -> Self {
                self * s
            }
            #[inline(always)]
            fn dot(self, other: Self) -> $t {
                self * other
            }
            #[inline(always)]
            fn is_finite(&self) -> bool {
                <$t>::is_finite(*self)
            }
        }
        impl Real for $t {
            #[inline(always)]
            fn of(x: f64) -> Self {
                x as $t
            }
            #[inline(always)]
            fn as_f64(self) -> f64 {
                self as f64
            }
            fn cuda_literal(self) -> String {
                let $v = self;
                $literal
            }
        }
    };
}
impl_real!(f32, "float", |x| if x.is_finite() {
    format!("{x:?}f")
} else {
    format!("__int_as_float((int)0x{:08x}u)", x.to_bits())
});
impl_real!(f64, "double", |x| if x.is_finite() {
    format!("{x:?}")
} else {
    format!("__longlong_as_double(0x{:016x}ull)", x.to_bits())
});

/// The element product `self * rhs` of two scalars (see the module docs for its meaning on
/// blocks). Used by [`crate::Ex::cwise_mul`] and by sparse matrix-vector products.
pub trait ScalarMul<Rhs: Scalar = Self>: Scalar {
    /// The product's type.
    type Output: Scalar<Real = Self::Real>;
    /// The product.
    fn smul(self, rhs: Rhs) -> Self::Output;
    /// The CUDA text of the product of the operands `a` and `b`.
    fn cuda_mul(a: &str, b: &str) -> String {
        format!("({a} * {b})")
    }
}

impl ScalarMul for f32 {
    type Output = f32;
    #[inline(always)]
    fn smul(self, rhs: f32) -> f32 {
        self * rhs
    }
}
impl ScalarMul for f64 {
    type Output = f64;
    #[inline(always)]
    fn smul(self, rhs: f64) -> f64 {
        self * rhs
    }
}

/// Conversion between element types, used by [`crate::Ex::cast`].
pub trait CastFrom<T: Scalar>: Scalar {
    /// Converts one element.
    fn cast_from(x: T) -> Self;
}
impl CastFrom<f32> for f64 {
    #[inline(always)]
    fn cast_from(x: f32) -> f64 {
        x as f64
    }
}
impl CastFrom<f64> for f32 {
    #[inline(always)]
    fn cast_from(x: f64) -> f32 {
        x as f32
    }
}
impl CastFrom<f32> for f32 {
    #[inline(always)]
    fn cast_from(x: f32) -> f32 {
        x
    }
}
impl CastFrom<f64> for f64 {
    #[inline(always)]
    fn cast_from(x: f64) -> f64 {
        x
    }
}
