//! The rules that turn an op-table entry into CUDA text, shared by the kernel generator
//! ([`crate::cuda_codegen`]) and by `build.rs` (which includes this file with `#[path]`, so it
//! must not use anything from the crate).
//!
//! An entry's text is a template over the operands `{0}` (and `{1}`). On a real element it is
//! pasted as is (`sqrt(x)`); on a block element (`Vec3`: 3 lanes, `Mat3`: 9 lanes) it becomes the
//! body of a lambda that `gpumat_map` / `gpumat_zip` (kernels/gpumat.cuh) apply lane by lane,
//! which is exactly what the CPU loop does with [`crate::Scalar::map`] / `zip`.

/// Fills a CUDA template with operand texts: `{i}` becomes `operands[i]`.
pub fn fill_cuda(template: &str, operands: &[&str]) -> String {
    let mut out = template.to_string();
    for (i, op) in operands.iter().enumerate() {
        out = out.replace(&format!("{{{i}}}"), op);
    }
    out
}

/// A unary entry applied to the text `a` of an element with `lanes` lanes.
pub fn unary_text(lanes: usize, template: &str, a: &str) -> String {
    if lanes == 1 {
        fill_cuda(template, &[a])
    } else {
        let body = fill_cuda(template, &["gm_x"]);
        format!("gpumat_map([](auto gm_x) {{ return {body}; }}, {a})")
    }
}

/// A binary entry applied to the texts `a`, `b` of elements with `lanes` lanes.
pub fn binary_text(lanes: usize, template: &str, a: &str, b: &str) -> String {
    if lanes == 1 {
        fill_cuda(template, &[a, b])
    } else {
        let body = fill_cuda(template, &["gm_x", "gm_y"]);
        format!("gpumat_zip([](auto gm_x, auto gm_y) {{ return {body}; }}, {a}, {b})")
    }
}
