//! The linear combination `d = sum_i alpha_i v_i` (thesis Tables B.1 and B.2), fused and
//! unfused.
//!
//! Fused: one [`Matrix::assign`] of the whole sum, one pass over memory. Expression types are
//! static, so the tree for each `k` is written out (as cuMat's benchmark does with a `switch`).
//! Unfused: one pass per term, as a sequence of BLAS calls would do (`d = a1 v1` (scal+copy),
//! then `d += a_i v_i` (axpy) for each further term).
//! faer: the sum written with faer's operators, as a faer user writes a sum of any length
//! (`d = Scale(a1) * &v1`, then `d += Scale(a_i) * &v_i`: each product is an owned temporary).

use gpumat::Matrix;

/// The largest `k` [`fused`] supports.
pub const MAX_TERMS: usize = 10;

/// `d = sum_i alphas[i] * vs[i]` in one fused pass (`1 <= k <= MAX_TERMS`).
#[track_caller]
pub fn fused(d: &mut Matrix<f32>, vs: &[Matrix<f32>], a: &[f32]) {
    assert_eq!(vs.len(), a.len(), "one factor per vector");
    let v = vs;
    match v.len() {
        1 => d.assign(v[0].ex() * a[0]),
        2 => d.assign(v[0].ex() * a[0] + v[1].ex() * a[1]),
        3 => d.assign(v[0].ex() * a[0] + v[1].ex() * a[1] + v[2].ex() * a[2]),
        4 => d.assign(v[0].ex() * a[0] + v[1].ex() * a[1] + v[2].ex() * a[2] + v[3].ex() * a[3]),
        5 => d.assign(
            v[0].ex() * a[0] + v[1].ex() * a[1] + v[2].ex() * a[2] + v[3].ex() * a[3] + v[4].ex() * a[4],
        ),
        6 => d.assign(
            v[0].ex() * a[0]
                + v[1].ex() * a[1]
                + v[2].ex() * a[2]
                + v[3].ex() * a[3]
                + v[4].ex() * a[4]
                + v[5].ex() * a[5],
        ),
        7 => d.assign(
            v[0].ex() * a[0]
                + v[1].ex() * a[1]
                + v[2].ex() * a[2]
                + v[3].ex() * a[3]
                + v[4].ex() * a[4]
                + v[5].ex() * a[5]
                + v[6].ex() * a[6],
        ),
        8 => d.assign(
            v[0].ex() * a[0]
                + v[1].ex() * a[1]
                + v[2].ex() * a[2]
                + v[3].ex() * a[3]
                + v[4].ex() * a[4]
                + v[5].ex() * a[5]
                + v[6].ex() * a[6]
                + v[7].ex() * a[7],
        ),
        9 => d.assign(
            v[0].ex() * a[0]
                + v[1].ex() * a[1]
                + v[2].ex() * a[2]
                + v[3].ex() * a[3]
                + v[4].ex() * a[4]
                + v[5].ex() * a[5]
                + v[6].ex() * a[6]
                + v[7].ex() * a[7]
                + v[8].ex() * a[8],
        ),
        10 => d.assign(
            v[0].ex() * a[0]
                + v[1].ex() * a[1]
                + v[2].ex() * a[2]
                + v[3].ex() * a[3]
                + v[4].ex() * a[4]
                + v[5].ex() * a[5]
                + v[6].ex() * a[6]
                + v[7].ex() * a[7]
                + v[8].ex() * a[8]
                + v[9].ex() * a[9],
        ),
        k => panic!("lincomb::fused supports 1..={MAX_TERMS} terms, got {k}"),
    }
}

/// `d = sum_i alphas[i] * vs[i]`, one pass per term (`k >= 1`).
#[track_caller]
pub fn unfused(d: &mut Matrix<f32>, vs: &[Matrix<f32>], a: &[f32]) {
    assert_eq!(vs.len(), a.len(), "one factor per vector");
    assert!(!vs.is_empty(), "at least one term");
    d.assign(vs[0].ex() * a[0]);
    for (v, &ai) in vs.iter().zip(a).skip(1) {
        *d += v.ex() * ai;
    }
}

/// `sum_i alphas[i] * vs[i]` with faer's operators (module docs), into a new column.
#[track_caller]
pub fn faer_ops(vs: &[faer::Col<f32>], a: &[f32]) -> faer::Col<f32> {
    assert_eq!(vs.len(), a.len(), "one factor per vector");
    assert!(!vs.is_empty(), "at least one term");
    let mut d = faer::Scale(a[0]) * &vs[0];
    for (v, &ai) in vs.iter().zip(a).skip(1) {
        d += faer::Scale(ai) * v;
    }
    d
}

/// The vectors as faer columns (the same numbers).
pub fn to_faer(vs: &[Matrix<f32>]) -> Vec<faer::Col<f32>> {
    vs.iter()
        .map(|v| {
            let s = v.as_slice();
            faer::Col::from_fn(s.len(), |i| s[i])
        })
        .collect()
}

/// Bytes a fused pass moves: `k` vectors read, one written (`4 (k + 1) n`).
pub fn fused_bytes(n: usize, k: usize) -> usize {
    4 * (k + 1) * n
}

/// Bytes the unfused passes move: `2n` for the first, `3n` (read d and v, write d) per
/// further term.
pub fn unfused_bytes(n: usize, k: usize) -> usize {
    4 * n * (2 + 3 * (k - 1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::lincomb_inputs;

    #[test]
    fn fused_unfused_and_faer_agree_for_every_k() {
        for k in 1..=MAX_TERMS {
            let (vs, a) = lincomb_inputs(37, k);
            let mut d1 = Matrix::zeros(37, 1, 1);
            let mut d2 = Matrix::zeros(37, 1, 1);
            fused(&mut d1, &vs, &a);
            unfused(&mut d2, &vs, &a);
            let d3 = faer_ops(&to_faer(&vs), &a);
            for i in 0..37 {
                let want: f32 = (0..k).map(|t| a[t] * vs[t].get(i, 0, 0)).sum();
                assert!((d1.get(i, 0, 0) - want).abs() < 1e-5);
                assert!((d2.get(i, 0, 0) - want).abs() < 1e-5);
                assert!((d3[i] - want).abs() < 1e-5);
            }
        }
    }
}
