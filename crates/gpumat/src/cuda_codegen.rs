//! CUDA text of a fused expression: the kernel the CUDA backend compiles (with NVRTC) for one
//! assignment. Built from the same op table as the CPU loop ([`crate::ops`]), so both
//! backends evaluate the same tree. Generating the text needs no GPU; [`crate::cuda`] collects
//! the kernels and (feature `cuda`) compiles them with NVRTC. Launching them is not built yet
//! ([`crate::backend`]).
//!
//! The kernel has one thread per output element `i`: it decodes
//! `(r, c, b) = (i mod R, (i / R) mod C, i / (R C))` from the linear index, evaluates the tree
//! at `(r, c, b)` and stores the result once. A leaf of shape `(R', C', B')` is read at
//! `r' + R' (c' + C' b')` with a coordinate replaced by 0 where its dimension is 1
//! (broadcasting). Lane-wise ops act on real elements directly (`sqrt(x)`) and on `Vec3` /
//! `Mat3` elements through `gpumat_map` / `gpumat_zip` of `kernels/gpumat.cuh`, with the op
//! table's text as the lambda body. A sparse product `y_r = sum_{k in row r} A_k x_{col_k}` is
//! a loop over the CSR row (an immediately invoked lambda, so the tree stays one expression).

use crate::expr::Expr;
use crate::matrix::Shape;
use crate::scalar::Scalar;

/// Collects the parameters and text of one generated kernel.
#[derive(Debug, Default)]
pub struct CudaGen {
    params: Vec<String>,
    rc: Vec<(String, String)>,
    constants: usize,
    names: usize,
}

impl CudaGen {
    /// The current (row, column) coordinate texts (`r`, `c` at the root; swapped under a
    /// transpose, the gathered column inside a sparse product).
    pub fn coords(&self) -> (String, String) {
        self.rc
            .last()
            .cloned()
            .unwrap_or_else(|| ("r".into(), "c".into()))
    }
    /// Registers an input buffer of the given element type and shape; returns the load text.
    pub fn load(&mut self, cuda_type: &str, s: Shape) -> String {
        let name = format!("in{}", self.params.len());
        self.params
            .push(format!("const {cuda_type}* __restrict__ {name}"));
        let (r, c) = self.coords();
        let r = if s.rows == 1 { "0".to_string() } else { r };
        let c = if s.cols == 1 { "0".to_string() } else { c };
        let b = if s.batches == 1 { "0" } else { "b" };
        format!("{name}[({r}) + {}ull * (({c}) + {}ull * ({b}))]", s.rows, s.cols)
    }
    /// A constant value (passed by value as a kernel parameter).
    pub fn constant(&mut self, cuda_type: &str, value: &str) -> String {
        let name = format!("k{}", self.constants);
        self.constants += 1;
        self.params
            .push(format!("const {cuda_type} {name} /* = {value} */"));
        name
    }
    /// The destination's current value (compound assignment).
    pub fn dst_load(&mut self) -> String {
        "dst[i]".into()
    }
    /// Registers a raw buffer parameter `const {cuda_type}* __restrict__ name`; returns `name`.
    pub fn buffer(&mut self, cuda_type: &str) -> String {
        let name = format!("in{}", self.params.len());
        self.params
            .push(format!("const {cuda_type}* __restrict__ {name}"));
        name
    }
    /// A fresh local variable name with the given prefix (unique within the kernel).
    pub fn fresh(&mut self, prefix: &str) -> String {
        self.names += 1;
        format!("{prefix}{}_", self.names)
    }
    /// Sets the coordinates the leaves below read at (undo with [`CudaGen::restore_rc`]).
    pub fn push_rc(&mut self, r: String, c: String) {
        self.rc.push((r, c));
    }
    /// Swaps the row and column coordinates (transpose).
    pub fn swap_rc(&mut self) {
        let (r, c) = self.coords();
        self.rc.push((c, r));
    }
    /// Reads a vector at the diagonal position.
    pub fn diag_rc(&mut self) {
        let (r, _) = self.coords();
        self.rc.push((r.clone(), r));
    }
    /// Undoes [`CudaGen::diag_rc`] or [`CudaGen::swap_rc`].
    pub fn restore_rc(&mut self) {
        self.rc.pop();
    }
}

/// The text of a lane-wise unary op-table entry applied to the element text `a` of type `T`
/// (see [`crate::cuda_text`]).
pub fn unary_text<T: Scalar>(template: &str, a: &str) -> String {
    crate::cuda_text::unary_text(T::LANES, template, a)
}

/// The text of a lane-wise binary op-table entry (see [`unary_text`]).
pub fn binary_text<T: Scalar>(template: &str, a: &str, b: &str) -> String {
    crate::cuda_text::binary_text(T::LANES, template, a, b)
}

/// The complete CUDA source of the kernel assigning `e` to a destination of element type `T`.
pub fn kernel_source<T: Scalar, E: Expr<Elem = T>>(e: &E, out: Shape, name: &str) -> String {
    let mut g = CudaGen::default();
    let body = e.cuda(&mut g);
    let mut params = vec![format!("{}* __restrict__ dst", T::CUDA_TYPE)];
    params.extend(g.params.iter().cloned());
    format!(
        "#include \"gpumat.cuh\"\nextern \"C\" __global__ void {name}({}) {{\n  \
         const unsigned long long i = blockIdx.x * (unsigned long long)blockDim.x + threadIdx.x;\n  \
         if (i >= {len}ull) return;\n  \
         const unsigned long long r = i % {rows}ull, c = (i / {rows}ull) % {cols}ull, b = i / ({rows}ull * {cols}ull);\n  \
         (void)r; (void)c; (void)b;\n  \
         dst[i] = {body};\n}}\n",
        params.join(", "),
        len = out.len(),
        rows = out.rows.max(1),
        cols = out.cols.max(1),
    )
}
