//! The one table of element-wise operations (architecture principle 1).
//!
//! Each entry gives the operation's name, its CUDA text (a format string over the operands
//! `{0}`, `{1}`) and its Rust function on one real lane. The CPU backend calls the Rust
//! function inside the fused assignment loop; the CUDA backend pastes the text into the one
//! generated kernel (see [`crate::cuda_codegen`]). Adding an operation means adding one line
//! here and one method on [`crate::Ex`].

use crate::scalar::Real;

/// A lane-wise unary operation.
pub trait UnaryOp: Copy + Send + Sync + std::fmt::Debug + 'static {
    /// Name of the operation.
    const NAME: &'static str;
    /// CUDA text, `{0}` is the operand.
    const CUDA: &'static str;
    /// The operation on one lane.
    fn apply<R: Real>(x: R) -> R;
}

/// A lane-wise binary operation (both operands of the same element type).
pub trait BinaryOp: Copy + Send + Sync + std::fmt::Debug + 'static {
    /// Name of the operation.
    const NAME: &'static str;
    /// CUDA text, `{0}` and `{1}` are the operands.
    const CUDA: &'static str;
    /// The operation on one lane.
    fn apply<R: Real>(a: R, b: R) -> R;
}

macro_rules! unary_ops {
    ($($(#[$doc:meta])* $ty:ident, $name:literal, $cuda:literal, |$x:ident| $body:expr;)*) => {
        $(
            $(#[$doc])*
            #[derive(Clone, Copy, Debug, Default)]
            pub struct $ty;
            impl UnaryOp for $ty {
                const NAME: &'static str = $name;
                const CUDA: &'static str = $cuda;
                #[inline(always)]
                fn apply<R: Real>($x: R) -> R { $body }
            }
        )*
        /// Every unary operation as `(name, CUDA text)`.
        pub const UNARY_TABLE: &[(&str, &str)] = &[$(($name, $cuda)),*];
        /// Evaluates the unary operation called `name` on `x` (for tests and tools).
        pub fn unary_by_name<R: Real>(name: &str, x: R) -> Option<R> {
            match name { $($name => Some(<$ty as UnaryOp>::apply(x)),)* _ => None }
        }
    };
}

macro_rules! binary_ops {
    ($($(#[$doc:meta])* $ty:ident, $name:literal, $cuda:literal, |$a:ident, $b:ident| $body:expr;)*) => {
        $(
            $(#[$doc])*
            #[derive(Clone, Copy, Debug, Default)]
            pub struct $ty;
            impl BinaryOp for $ty {
                const NAME: &'static str = $name;
                const CUDA: &'static str = $cuda;
                #[inline(always)]
                fn apply<R: Real>($a: R, $b: R) -> R { $body }
            }
        )*
        /// Every binary operation as `(name, CUDA text)`.
        pub const BINARY_TABLE: &[(&str, &str)] = &[$(($name, $cuda)),*];
    };
}

for_each_unary_op!(unary_ops);
for_each_binary_op!(binary_ops);

pub use crate::cuda_text::fill_cuda;
