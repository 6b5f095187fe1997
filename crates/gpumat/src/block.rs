//! 3-lane vectors and 3x3 blocks used as scalars (cuMat's `real3 = float4` and 3x3 blocks).
//!
//! `Vec3<R>` stores three lanes in a 4-wide, 16-byte aligned slot (the fourth lane `w` is
//! padding and always zero), so a `Matrix<Vec3<f32>>` has the memory layout of CUDA's
//! `float4` arrays. `Mat3<R>` is a row-major 3x3 block; a `SparseMatrix<Mat3<R>>` is a 3x3
//! block-sparse (BSR) matrix and `Mat3 * Vec3` is the block product used by its SpMV.

use crate::scalar::{CastFrom, Real, Scalar, ScalarMul};
use std::ops::{Add, Mul, Neg, Sub};

/// `[[f(0, 0), f(0, 1), f(0, 2)], ..]`, row by row, as a plain array literal: it inlines
/// reliably, where `std::array::from_fn` and `map` go through generic adapters that the
/// optimizer does not always inline into large loops (same operations, same values).
#[inline(always)]
fn grid3<R>(mut f: impl FnMut(usize, usize) -> R) -> [[R; 3]; 3] {
    [
        [f(0, 0), f(0, 1), f(0, 2)],
        [f(1, 0), f(1, 1), f(1, 2)],
        [f(2, 0), f(2, 1), f(2, 2)],
    ]
}

/// A 3-vector stored in four lanes (`w` = 0), 16-byte aligned.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(16))]
pub struct Vec3<R> {
    /// x lane
    pub x: R,
    /// y lane
    pub y: R,
    /// z lane
    pub z: R,
    /// padding lane, always zero
    pub w: R,
}

// SAFETY: `Vec3<f32>` is `repr(C, align(16))` with four `f32` fields: 16 bytes, no padding
// bytes, every bit pattern valid.
unsafe impl bytemuck::Zeroable for Vec3<f32> {}
// SAFETY: see above; the type is `Copy` and `'static`.
unsafe impl bytemuck::Pod for Vec3<f32> {}
// SAFETY: `Vec3<f64>` is `repr(C, align(16))` with four `f64` fields: 32 bytes, no padding.
unsafe impl bytemuck::Zeroable for Vec3<f64> {}
// SAFETY: see above.
unsafe impl bytemuck::Pod for Vec3<f64> {}

/// A row-major 3x3 block.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct Mat3<R> {
    /// rows of the block: `m[row][col]`
    pub m: [[R; 3]; 3],
}

// SAFETY: `Mat3<R>` is `repr(C)` over `[[R; 3]; 3]` with `R` in {f32, f64}: no padding, every
// bit pattern valid.
unsafe impl bytemuck::Zeroable for Mat3<f32> {}
// SAFETY: see above.
unsafe impl bytemuck::Pod for Mat3<f32> {}
// SAFETY: see above.
unsafe impl bytemuck::Zeroable for Mat3<f64> {}
// SAFETY: see above.
unsafe impl bytemuck::Pod for Mat3<f64> {}

/// `Vec3<f32>`
pub type Vec3f = Vec3<f32>;
/// `Vec3<f64>`
pub type Vec3d = Vec3<f64>;
/// `Mat3<f32>`
pub type Mat3f = Mat3<f32>;
/// `Mat3<f64>`
pub type Mat3d = Mat3<f64>;

impl<R: Real> Vec3<R> {
    /// `(x, y, z)` with `w = 0`.
    #[inline(always)]
    pub fn new(x: R, y: R, z: R) -> Self {
        Self { x, y, z, w: R::ZERO }
    }
    /// All three lanes equal to `s`.
    #[inline(always)]
    pub fn splat(s: R) -> Self {
        Self::new(s, s, s)
    }
    /// The lanes as an array.
    #[inline(always)]
    pub fn to_array(self) -> [R; 3] {
        [self.x, self.y, self.z]
    }
    /// From an array.
    #[inline(always)]
    pub fn from_array(a: [R; 3]) -> Self {
        Self::new(a[0], a[1], a[2])
    }
    /// Euclidean inner product.
    #[inline(always)]
    pub fn dot(self, o: Self) -> R {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    /// Cross product.
    #[inline(always)]
    pub fn cross(self, o: Self) -> Self {
        Self::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }
    /// Euclidean norm.
    #[inline(always)]
    pub fn norm(self) -> R {
        self.dot(self).sqrt()
    }
    /// Outer product `self * o^T`.
    #[inline(always)]
    pub fn outer(self, o: Self) -> Mat3<R> {
        let a = self.to_array();
        let b = o.to_array();
        Mat3 {
            m: grid3(|i, j| a[i] * b[j]),
        }
    }
}

impl<R: Real> Mat3<R> {
    /// From rows.
    #[inline(always)]
    pub fn from_rows(m: [[R; 3]; 3]) -> Self {
        Self { m }
    }
    /// The identity block.
    #[inline(always)]
    pub fn identity() -> Self {
        Self::from_diagonal(Vec3::splat(R::ONE))
    }
    /// `s * I`.
    #[inline(always)]
    pub fn from_scalar(s: R) -> Self {
        Self::from_diagonal(Vec3::splat(s))
    }
    /// A diagonal block.
    #[inline(always)]
    pub fn from_diagonal(d: Vec3<R>) -> Self {
        let z = R::ZERO;
        Self {
            m: [[d.x, z, z], [z, d.y, z], [z, z, d.z]],
        }
    }
    /// The diagonal.
    #[inline(always)]
    pub fn diagonal(&self) -> Vec3<R> {
        Vec3::new(self.m[0][0], self.m[1][1], self.m[2][2])
    }
    /// Block transpose.
    #[inline(always)]
    pub fn transpose(&self) -> Self {
        Self {
            m: grid3(|i, j| self.m[j][i]),
        }
    }
    /// Determinant.
    #[inline(always)]
    pub fn determinant(&self) -> R {
        let m = &self.m;
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }
    /// Trace.
    #[inline(always)]
    pub fn trace(&self) -> R {
        self.m[0][0] + self.m[1][1] + self.m[2][2]
    }
    /// Inverse by the adjugate; `None` when the determinant is zero or not finite.
    pub fn inverse(&self) -> Option<Self> {
        let det = self.determinant();
        if det == R::ZERO || !det.is_finite() {
            return None;
        }
        let m = &self.m;
        let inv = R::ONE / det;
        let c = |a: usize, b: usize, c: usize, d: usize| m[a][b] * m[c][d];
        Some(Self {
            m: [
                [
                    (c(1, 1, 2, 2) - c(1, 2, 2, 1)) * inv,
                    (c(0, 2, 2, 1) - c(0, 1, 2, 2)) * inv,
                    (c(0, 1, 1, 2) - c(0, 2, 1, 1)) * inv,
                ],
                [
                    (c(1, 2, 2, 0) - c(1, 0, 2, 2)) * inv,
                    (c(0, 0, 2, 2) - c(0, 2, 2, 0)) * inv,
                    (c(0, 2, 1, 0) - c(0, 0, 1, 2)) * inv,
                ],
                [
                    (c(1, 0, 2, 1) - c(1, 1, 2, 0)) * inv,
                    (c(0, 1, 2, 0) - c(0, 0, 2, 1)) * inv,
                    (c(0, 0, 1, 1) - c(0, 1, 1, 0)) * inv,
                ],
            ],
        })
    }
    /// Row `i` as a vector.
    #[inline(always)]
    pub fn row(&self, i: usize) -> Vec3<R> {
        Vec3::from_array(self.m[i])
    }
    /// Column `j` as a vector.
    #[inline(always)]
    pub fn col(&self, j: usize) -> Vec3<R> {
        Vec3::new(self.m[0][j], self.m[1][j], self.m[2][j])
    }
    /// From columns.
    #[inline(always)]
    pub fn from_cols(a: Vec3<R>, b: Vec3<R>, c: Vec3<R>) -> Self {
        Self {
            m: [[a.x, b.x, c.x], [a.y, b.y, c.y], [a.z, b.z, c.z]],
        }
    }
}

macro_rules! impl_block_scalars {
    ($r:ty, $v:literal, $m:literal) => {
        impl Scalar for Vec3<$r> {
            type Real = $r;
            const LANES: usize = 3;
            const CUDA_TYPE: &'static str = $v;
            const ZERO: Self = Vec3 {
                x: 0.0,
                y: 0.0,
                z: 0.0,
                w: 0.0,
            };
            const ONE: Self = Vec3 {
                x: 1.0,
                y: 1.0,
                z: 1.0,
                w: 0.0,
            };
            #[inline(always)]
            fn lane(&self, i: usize) -> $r {
                match i {
                    0 => self.x,
                    1 => self.y,
                    _ => self.z,
                }
            }
            #[inline(always)]
            fn from_lanes(mut f: impl FnMut(usize) -> $r) -> Self {
                let x = f(0);
                let y = f(1);
                let z = f(2);
                Self::new(x, y, z)
            }
            #[inline(always)]
            fn map(self, f: impl Fn($r) -> $r) -> Self {
                Self::new(f(self.x), f(self.y), f(self.z))
            }
            #[inline(always)]
            fn zip(self, o: Self, f: impl Fn($r, $r) -> $r) -> Self {
                Self::new(f(self.x, o.x), f(self.y, o.y), f(self.z, o.z))
            }
            #[inline(always)]
            fn dot(self, o: Self) -> $r {
                Vec3::dot(self, o)
            }
        }
        impl Scalar for Mat3<$r> {
            type Real = $r;
            const LANES: usize = 9;
            const CUDA_TYPE: &'static str = $m;
            const ZERO: Self = Mat3 { m: [[0.0; 3]; 3] };
            const ONE: Self = Mat3 {
                m: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            };
            #[inline(always)]
            fn lane(&self, i: usize) -> $r {
                self.m[i / 3][i % 3]
            }
            #[inline(always)]
            fn from_lanes(mut f: impl FnMut(usize) -> $r) -> Self {
                Self {
                    m: grid3(|i, j| f(3 * i + j)),
                }
            }
            #[inline(always)]
            fn map(self, f: impl Fn($r) -> $r) -> Self {
                Self {
                    m: grid3(|i, j| f(self.m[i][j])),
                }
            }
            #[inline(always)]
            fn zip(self, o: Self, f: impl Fn($r, $r) -> $r) -> Self {
                Self {
                    m: grid3(|i, j| f(self.m[i][j], o.m[i][j])),
                }
            }
            #[inline(always)]
            fn transpose(self) -> Self {
                Mat3::transpose(&self)
            }
        }
        impl ScalarMul for Vec3<$r> {
            type Output = Vec3<$r>;
            #[inline(always)]
            fn smul(self, o: Self) -> Self {
                Self::new(self.x * o.x, self.y * o.y, self.z * o.z)
            }
        }
        impl ScalarMul<Vec3<$r>> for Mat3<$r> {
            type Output = Vec3<$r>;
            #[inline(always)]
            fn smul(self, v: Vec3<$r>) -> Vec3<$r> {
                let m = &self.m;
                Vec3::new(
                    m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
                    m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
                    m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
                )
            }
        }
        impl ScalarMul for Mat3<$r> {
            type Output = Mat3<$r>;
            #[inline(always)]
            fn smul(self, o: Self) -> Self {
                Self {
                    m: grid3(|i, j| {
                        self.m[i][0] * o.m[0][j] + self.m[i][1] * o.m[1][j] + self.m[i][2] * o.m[2][j]
                    }),
                }
            }
        }
        impl ScalarMul<Vec3<$r>> for $r {
            type Output = Vec3<$r>;
            #[inline(always)]
            fn smul(self, v: Vec3<$r>) -> Vec3<$r> {
                Scalar::scale(v, self)
            }
        }
        impl ScalarMul<Mat3<$r>> for $r {
            type Output = Mat3<$r>;
            #[inline(always)]
            fn smul(self, v: Mat3<$r>) -> Mat3<$r> {
                Scalar::scale(v, self)
            }
        }
        impl CastFrom<$r> for Mat3<$r> {
            /// A real `s` becomes the block `s * I`.
            #[inline(always)]
            fn cast_from(s: $r) -> Self {
                Mat3::from_scalar(s)
            }
        }
        impl CastFrom<$r> for Vec3<$r> {
            /// A real `s` becomes `(s, s, s)`.
            #[inline(always)]
            fn cast_from(s: $r) -> Self {
                Vec3::splat(s)
            }
        }
        impl CastFrom<Vec3<$r>> for Mat3<$r> {
            /// A vector becomes the diagonal block.
            #[inline(always)]
            fn cast_from(v: Vec3<$r>) -> Self {
                Mat3::from_diagonal(v)
            }
        }
    };
}
impl_block_scalars!(f32, "float4", "gpumat_mat3f");
impl_block_scalars!(f64, "double4", "gpumat_mat3d");

impl CastFrom<Vec3<f32>> for Vec3<f64> {
    #[inline(always)]
    fn cast_from(v: Vec3<f32>) -> Self {
        Vec3::new(v.x as f64, v.y as f64, v.z as f64)
    }
}
impl CastFrom<Vec3<f64>> for Vec3<f32> {
    #[inline(always)]
    fn cast_from(v: Vec3<f64>) -> Self {
        Vec3::new(v.x as f32, v.y as f32, v.z as f32)
    }
}
impl CastFrom<Mat3<f32>> for Mat3<f64> {
    #[inline(always)]
    fn cast_from(v: Mat3<f32>) -> Self {
        Mat3 {
            m: grid3(|i, j| v.m[i][j] as f64),
        }
    }
}
impl CastFrom<Mat3<f64>> for Mat3<f32> {
    #[inline(always)]
    fn cast_from(v: Mat3<f64>) -> Self {
        Mat3 {
            m: grid3(|i, j| v.m[i][j] as f32),
        }
    }
}

impl<R: Real> Add for Vec3<R> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl<R: Real> Sub for Vec3<R> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl<R: Real> Neg for Vec3<R> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y, -self.z)
    }
}
impl<R: Real> Mul<R> for Vec3<R> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, s: R) -> Self {
        Self::new(self.x * s, self.y * s, self.z * s)
    }
}
impl<R: Real> Add for Mat3<R> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self {
            m: grid3(|i, j| self.m[i][j] + o.m[i][j]),
        }
    }
}
impl<R: Real> Sub for Mat3<R> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self {
            m: grid3(|i, j| self.m[i][j] - o.m[i][j]),
        }
    }
}
impl<R: Real> Neg for Mat3<R> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self {
            m: grid3(|i, j| -self.m[i][j]),
        }
    }
}
impl<R: Real> Mul<R> for Mat3<R> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, s: R) -> Self {
        Self {
            m: grid3(|i, j| self.m[i][j] * s),
        }
    }
}
impl<R: Real> Mul<Vec3<R>> for Mat3<R> {
    type Output = Vec3<R>;
    #[inline(always)]
    fn mul(self, v: Vec3<R>) -> Vec3<R> {
        Vec3::new(self.row(0).dot(v), self.row(1).dot(v), self.row(2).dot(v))
    }
}
impl<R: Real> Mul for Mat3<R> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self {
            m: grid3(|i, j| self.row(i).dot(o.col(j))),
        }
    }
}
