//! Four-lane `f64` vectors for hot loops, written once and run either as plain lane loops
//! ([`Portable`], any CPU) or in 256-bit AVX2 registers ([`Avx2`], when the CPU has it).
//!
//! The default x86-64 target only has 128-bit SSE2 vectors; a kernel generic over [`Simd4`]
//! and started with [`dispatch`] runs in a function compiled with AVX2 where the CPU supports
//! it (detected once, then cached by std). Every lane does the same operations in the same
//! order on both backends, and Rust never contracts `a * b + c` into a fused multiply-add, so
//! the results are bitwise equal whichever runs (the fused expression loops of [`crate::expr`]
//! rely on the same fact).

use std::fmt::Debug;

/// A set of four-lane `f64` vector operations (lane-wise IEEE arithmetic).
pub trait Simd4: Copy + Debug + Send + Sync {
    /// The vector type.
    type V: Copy;
    /// All lanes `x`.
    fn splat(self, x: f64) -> Self::V;
    /// The lanes of `a` (from memory).
    fn load(self, a: &[f64; 4]) -> Self::V;
    /// A vector of the lanes `a` (values in registers: built without a round trip through
    /// memory, which would stall on store forwarding).
    fn set(self, a: [f64; 4]) -> Self::V;
    /// The lanes as an array.
    fn to_array(self, v: Self::V) -> [f64; 4];
    /// `a + b`, lane-wise.
    fn add(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a - b`, lane-wise.
    fn sub(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a * b`, lane-wise.
    fn mul(self, a: Self::V, b: Self::V) -> Self::V;
    /// `a / b`, lane-wise.
    fn div(self, a: Self::V, b: Self::V) -> Self::V;
    /// Runs `f` in a function compiled for this instruction set. Mark the closure
    /// `#[inline(always)]` so that its body is compiled with it.
    fn run<R>(self, f: impl FnOnce() -> R) -> R;
}

/// Plain lane loops: any CPU.
#[derive(Clone, Copy, Debug, Default)]
pub struct Portable;

impl Simd4 for Portable {
    type V = [f64; 4];
    #[inline(always)]
    fn splat(self, x: f64) -> [f64; 4] {
        [x; 4]
    }
    #[inline(always)]
    fn load(self, a: &[f64; 4]) -> [f64; 4] {
        *a
    }
    #[inline(always)]
    fn set(self, a: [f64; 4]) -> [f64; 4] {
        a
    }
    #[inline(always)]
    fn to_array(self, v: [f64; 4]) -> [f64; 4] {
        v
    }
    #[inline(always)]
    fn add(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        [a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3]]
    }
    #[inline(always)]
    fn sub(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]]
    }
    #[inline(always)]
    fn mul(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        [a[0] * b[0], a[1] * b[1], a[2] * b[2], a[3] * b[3]]
    }
    #[inline(always)]
    fn div(self, a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
        [a[0] / b[0], a[1] / b[1], a[2] / b[2], a[3] / b[3]]
    }
    #[inline(always)]
    fn run<R>(self, f: impl FnOnce() -> R) -> R {
        f()
    }
}

/// AVX2 registers. A value exists only on a CPU that has AVX2 ([`Avx2::detect`]), which makes
/// its operations safe to call.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug)]
pub struct Avx2(());

#[cfg(target_arch = "x86_64")]
impl Avx2 {
    /// `Some` when the CPU has AVX2.
    #[inline]
    pub fn detect() -> Option<Self> {
        std::arch::is_x86_feature_detected!("avx2").then_some(Avx2(()))
    }
}

#[cfg(target_arch = "x86_64")]
impl Simd4 for Avx2 {
    type V = std::arch::x86_64::__m256d;
    #[inline(always)]
    fn splat(self, x: f64) -> Self::V {
        // SAFETY: `self` exists only when the CPU has AVX2 (`Avx2::detect`).
        unsafe { std::arch::x86_64::_mm256_set1_pd(x) }
    }
    #[inline(always)]
    fn load(self, a: &[f64; 4]) -> Self::V {
        // SAFETY: the CPU has AVX2 (as above); `a` has four readable lanes (unaligned load).
        unsafe { std::arch::x86_64::_mm256_loadu_pd(a.as_ptr()) }
    }
    #[inline(always)]
    fn set(self, a: [f64; 4]) -> Self::V {
        // SAFETY: the CPU has AVX2 (as above).
        unsafe { std::arch::x86_64::_mm256_set_pd(a[3], a[2], a[1], a[0]) }
    }
    #[inline(always)]
    fn to_array(self, v: Self::V) -> [f64; 4] {
        let mut a = [0.0; 4];
        // SAFETY: the CPU has AVX2 (as above); `a` has four writable lanes (unaligned store).
        unsafe { std::arch::x86_64::_mm256_storeu_pd(a.as_mut_ptr(), v) };
        a
    }
    #[inline(always)]
    fn add(self, a: Self::V, b: Self::V) -> Self::V {
        // SAFETY: the CPU has AVX2 (as above).
        unsafe { std::arch::x86_64::_mm256_add_pd(a, b) }
    }
    #[inline(always)]
    fn sub(self, a: Self::V, b: Self::V) -> Self::V {
        // SAFETY: the CPU has AVX2 (as above).
        unsafe { std::arch::x86_64::_mm256_sub_pd(a, b) }
    }
    #[inline(always)]
    fn mul(self, a: Self::V, b: Self::V) -> Self::V {
        // SAFETY: the CPU has AVX2 (as above).
        unsafe { std::arch::x86_64::_mm256_mul_pd(a, b) }
    }
    #[inline(always)]
    fn div(self, a: Self::V, b: Self::V) -> Self::V {
        // SAFETY: the CPU has AVX2 (as above).
        unsafe { std::arch::x86_64::_mm256_div_pd(a, b) }
    }
    #[inline(always)]
    fn run<R>(self, f: impl FnOnce() -> R) -> R {
        // SAFETY: the CPU has AVX2 (as above), the only requirement of `run_avx2`.
        unsafe { run_avx2(f) }
    }
}

/// `f()` compiled with AVX2.
///
/// # Safety
/// The CPU supports AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn run_avx2<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// A computation written once for any [`Simd4`] backend.
pub trait Kernel {
    /// What it returns.
    type Output;
    /// Runs it with the operations of `s` (mark it `#[inline(always)]`).
    fn run<S: Simd4>(self, s: S) -> Self::Output;
}

/// Runs `k` with the best backend of this CPU: [`Avx2`] inside a function compiled for it
/// where the CPU has it, else [`Portable`]. The values are the same either way.
///
/// ```
/// use gpumat::simd::{dispatch, Kernel, Simd4};
/// struct Dot<'a>(&'a [[f64; 4]], &'a [[f64; 4]]);
/// impl Kernel for Dot<'_> {
///     type Output = [f64; 4];
///     #[inline(always)]
///     fn run<S: Simd4>(self, s: S) -> [f64; 4] {
///         let mut acc = s.splat(0.0);
///         for (a, b) in self.0.iter().zip(self.1) {
///             acc = s.add(acc, s.mul(s.load(a), s.load(b)));
///         }
///         s.to_array(acc)
///     }
/// }
/// let (a, b) = ([[1.0, 2.0, 3.0, 4.0]; 3], [[2.0; 4]; 3]);
/// assert_eq!(dispatch(Dot(&a, &b)), [6.0, 12.0, 18.0, 24.0]);
/// ```
#[inline(always)]
pub fn dispatch<K: Kernel>(k: K) -> K::Output {
    #[cfg(target_arch = "x86_64")]
    if let Some(s) = Avx2::detect() {
        return s.run(
            #[inline(always)]
            || k.run(s),
        );
    }
    k.run(Portable)
}

/// Runs `f` in a function compiled with AVX2 where the CPU has it (the same operations: the
/// values do not change). For code without explicit vectors that the compiler vectorizes.
///
/// ```
/// let x = [1.0f64, 2.0, 3.0, 4.0];
/// let s = gpumat::simd::with_avx2(#[inline(always)] || x.iter().map(|v| v * v).sum::<f64>());
/// assert_eq!(s, 30.0);
/// ```
#[inline(always)]
pub fn with_avx2<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if let Some(s) = Avx2::detect() {
        return s.run(f);
    }
    f()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both backends give the same bits on values with rounding in every operation.
    #[test]
    fn backends_agree_bitwise() {
        let a = [0.1, -1.0 / 3.0, 1e300, f64::MIN_POSITIVE];
        let b = [0.7, 2.0 / 7.0, 1e10, 0.5];
        fn f<S: Simd4>(s: S, a: &[f64; 4], b: &[f64; 4]) -> [f64; 4] {
            let (x, y) = (s.load(a), s.set(*b));
            s.to_array(s.div(s.sub(s.add(s.mul(x, y), s.splat(0.3)), x), y))
        }
        let p = f(Portable, &a, &b);
        #[cfg(target_arch = "x86_64")]
        if let Some(s) = Avx2::detect() {
            assert_eq!(p.map(f64::to_bits), f(s, &a, &b).map(f64::to_bits));
        }
        assert_eq!(p[0], (0.1 * 0.7 + 0.3 - 0.1) / 0.7);
    }
}
