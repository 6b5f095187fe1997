//! Small dense solves on row-major `n x n` slices (`n` up to a few dozen: the Gauss-Newton
//! systems of the optimizers and the covariances of a fit): a Cholesky factorization
//! `A = L L^T` reading only the lower triangle ([`SmallCholesky`]), and the inverse by
//! Gauss-Jordan elimination with partial pivoting ([`invert_small`]).

/// Lower-triangular Cholesky factor, row-major `n x n`.
#[derive(Clone, Debug)]
pub struct SmallCholesky {
    n: usize,
    l: Vec<f64>,
}

impl SmallCholesky {
    /// Factors the symmetric matrix `a` (row-major, lower triangle read). Returns `None`
    /// if a pivot is not positive or not finite (the matrix is not positive definite).
    pub fn factor(a: &[f64], n: usize) -> Option<Self> {
        debug_assert_eq!(a.len(), n * n);
        let mut l = vec![0.0; n * n];
        for j in 0..n {
            let mut d = a[j * n + j];
            for k in 0..j {
                d -= l[j * n + k] * l[j * n + k];
            }
            if !(d > 0.0 && d.is_finite()) {
                return None;
            }
            let d = d.sqrt();
            l[j * n + j] = d;
            for i in j + 1..n {
                let mut v = a[i * n + j];
                for k in 0..j {
                    v -= l[i * n + k] * l[j * n + k];
                }
                l[i * n + j] = v / d;
            }
        }
        Some(Self { n, l })
    }

    /// Solves `L L^T x = b`.
    pub fn solve(&self, b: &[f64]) -> Vec<f64> {
        let (n, l) = (self.n, &self.l);
        let mut x = b.to_vec();
        for i in 0..n {
            let mut v = x[i];
            for k in 0..i {
                v -= l[i * n + k] * x[k];
            }
            x[i] = v / l[i * n + i];
        }
        for i in (0..n).rev() {
            let mut v = x[i];
            for k in i + 1..n {
                v -= l[k * n + i] * x[k];
            }
            x[i] = v / l[i * n + i];
        }
        x
    }
}

/// Inverts a small symmetric positive definite matrix (`n x n`, row-major) by Gauss-Jordan
/// elimination with partial pivoting; `None` when it is singular.
pub fn invert_small(a: &[f64], n: usize) -> Option<Vec<f64>> {
    let mut m = a.to_vec();
    let mut inv = vec![0.0; n * n];
    for i in 0..n {
        inv[i * n + i] = 1.0;
    }
    let scale = a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    for col in 0..n {
        let piv = (col..n).max_by(|&x, &y| m[x * n + col].abs().total_cmp(&m[y * n + col].abs()))?;
        if m[piv * n + col].abs() <= 1e-14 * scale {
            return None;
        }
        for k in 0..n {
            m.swap(col * n + k, piv * n + k);
            inv.swap(col * n + k, piv * n + k);
        }
        let d = 1.0 / m[col * n + col];
        for k in 0..n {
            m[col * n + k] *= d;
            inv[col * n + k] *= d;
        }
        for r in 0..n {
            if r != col {
                let f = m[r * n + col];
                if f != 0.0 {
                    for k in 0..n {
                        m[r * n + k] -= f * m[col * n + k];
                        inv[r * n + k] -= f * inv[col * n + k];
                    }
                }
            }
        }
    }
    Some(inv)
}

#[cfg(test)]
mod tests {
    use super::{invert_small, SmallCholesky};

    #[test]
    fn solves_spd_system() {
        // A = [[4, 2, 0], [2, 5, 1], [0, 1, 3]], x = [1, -1, 2]
        let a = [4.0, 2.0, 0.0, 2.0, 5.0, 1.0, 0.0, 1.0, 3.0];
        let b = [2.0, -1.0, 5.0];
        let x = SmallCholesky::factor(&a, 3).unwrap().solve(&b);
        for (xi, ei) in x.iter().zip([1.0, -1.0, 2.0]) {
            assert!((xi - ei).abs() < 1e-14);
        }
    }

    #[test]
    fn rejects_indefinite() {
        assert!(SmallCholesky::factor(&[1.0, 2.0, 2.0, 1.0], 2).is_none());
    }

    #[test]
    fn inverts_and_refuses_singular() {
        let a = [4.0, 2.0, 0.0, 2.0, 5.0, 1.0, 0.0, 1.0, 3.0];
        let inv = invert_small(&a, 3).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let p: f64 = (0..3).map(|k| a[i * 3 + k] * inv[k * 3 + j]).sum();
                assert!((p - f64::from(u8::from(i == j))).abs() < 1e-14, "{i} {j} {p}");
            }
        }
        assert!(invert_small(&[1.0, 2.0, 2.0, 4.0], 2).is_none());
    }
}
