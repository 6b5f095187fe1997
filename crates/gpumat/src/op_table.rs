// The op table's entries, as visitor macros: `for_each_unary_op!(m)` calls `m! { .. }` with
// every unary entry `Type, "name", "cuda text", |x| rust body;` (binary: `|a, b|`).
//
// This file is the single list of lane-wise operations. `crate::ops` expands it into the op
// types and tables; `build.rs` `include!`s it to read the CUDA text of the build-time kernels;
// `crate::cuda` expands it into the kernel corpus (one kernel per op, type and broadcast).
// It contains only `macro_rules!` definitions, so `build.rs` can include it as is.

/// Calls `$m! { .. }` with every unary op entry.
macro_rules! for_each_unary_op {
    ($m:ident) => {
        $m! {
            /// `-x`
            Neg, "neg", "(-{0})", |x| -x;
            /// `sqrt(x)`
            Sqrt, "sqrt", "sqrt({0})", |x| x.sqrt();
            /// `1/sqrt(x)`
            Rsqrt, "rsqrt", "rsqrt({0})", |x| x.sqrt().recip();
            /// `|x|`
            Abs, "abs", "fabs({0})", |x| x.abs();
            /// `e^x`
            Exp, "exp", "exp({0})", |x| x.exp();
            /// `ln x`
            Log, "log", "log({0})", |x| x.ln();
            /// `ln(1 + x)`
            Log1p, "log1p", "log1p({0})", |x| x.ln_1p();
            /// `sin x`
            Sin, "sin", "sin({0})", |x| x.sin();
            /// `cos x`
            Cos, "cos", "cos({0})", |x| x.cos();
            /// `tan x`
            Tan, "tan", "tan({0})", |x| x.tan();
            /// `tanh x`
            Tanh, "tanh", "tanh({0})", |x| x.tanh();
            /// `x^2`
            Square, "square", "(({0}) * ({0}))", |x| x * x;
            /// `x^3`
            Cube, "cube", "(({0}) * ({0}) * ({0}))", |x| x * x * x;
            /// `1/x`
            Inverse, "inverse", "(1 / ({0}))", |x| x.recip();
            /// `floor x`
            Floor, "floor", "floor({0})", |x| x.floor();
            /// `ceil x`
            Ceil, "ceil", "ceil({0})", |x| x.ceil();
            /// sign of x (-1, 0, 1)
            Sign, "sign", "((({0}) > 0) - (({0}) < 0))", |x| if x > R::ZERO { R::ONE } else if x < R::ZERO { -R::ONE } else { R::ZERO };
        }
    };
}

/// Calls `$m! { .. }` with every binary op entry.
macro_rules! for_each_binary_op {
    ($m:ident) => {
        $m! {
            /// `a + b`
            AddOp, "add", "({0} + {1})", |a, b| a + b;
            /// `a - b`
            SubOp, "sub", "({0} - {1})", |a, b| a - b;
            /// `a / b`
            DivOp, "div", "({0} / {1})", |a, b| a / b;
            /// `min(a, b)`
            MinOp, "min", "fmin({0}, {1})", |a, b| a.min(b);
            /// `max(a, b)`
            MaxOp, "max", "fmax({0}, {1})", |a, b| a.max(b);
            /// `a^b`
            PowOp, "pow", "pow({0}, {1})", |a, b| a.powf(b);
        }
    };
}
