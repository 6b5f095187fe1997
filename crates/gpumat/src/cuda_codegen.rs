//! CUDA text of a fused expression: the kernel the CUDA backend compiles (with NVRTC) for one
//! assignment. Built from the same op table as the CPU loop ([`crate::ops`]), so both
//! backends evaluate the same tree. Compiling and launching it is the CUDA backend's job
//! (not built yet: [`crate::backend`]); generating the text needs no GPU and is tested here.
//!
//! The kernel has one thread per output element: it decodes `(r, c, b)` from the linear
//! index, evaluates the tree and stores the result once.

use crate::expr::Expr;
use crate::matrix::Shape;
use crate::scalar::Scalar;

/// Collects the parameters and text of one generated kernel.
#[derive(Debug, Default)]
pub struct CudaGen {
    params: Vec<String>,
    rc: Vec<(String, String)>,
    constants: usize,
}

impl CudaGen {
    fn coords(&self) -> (String, String) {
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
