//! Fusion really happens, measured with the `gpumat::stats` pass and allocation counters:
//! `d = a + 2b + sqrt(c)`, `d += expr`, `d -= expr`, `d *= s`, `assign_with`, the fused
//! `b = A u + c v` (SpMV inside the expression) and a sparse-view assignment are each one pass
//! with no allocation, on both the sequential and the parallel path; reductions of a whole tree
//! are one pass and allocate only their result. The unfused equivalents (separate
//! assignments through temporaries) make more passes and allocations, and give the same bits.

mod common;

use common::*;
use gpumat::{stats, Axes, Mat3, Matrix, SparseMatrix, SparsityPattern, Vec3};

/// Runs `f` with fresh counters and returns `(passes, allocations)`.
fn counted(f: impl FnOnce()) -> (usize, usize) {
    stats::reset();
    f();
    (stats::passes(), stats::allocations())
}

fn inputs(n: usize, nb: usize) -> [Matrix<f32>; 3] {
    let mut rng = Rand::new(n as u64);
    [
        random_matrix(&mut rng, (n, 1, nb), -10.0, 10.0),
        random_matrix(&mut rng, (n, 1, nb), -10.0, 10.0),
        random_matrix(&mut rng, (n, 1, nb), 0.0, 10.0),
    ]
}

#[test]
fn counters_count() {
    // The hooks themselves: an allocation and a pass are seen, and reset clears them.
    let (p, a) = counted(|| {
        let m = Matrix::<f64>::zeros(3, 1, 1);
        let _ = m.ex().sum();
    });
    assert_eq!((p, a), (1, 2)); // the zeros buffer and the 1x1x1 reduction result
    stats::reset();
    assert_eq!((stats::passes(), stats::allocations()), (0, 0));
}

#[test]
fn fused_assignment_is_one_pass_without_allocation() {
    for (n, nb) in [(10, 1), (1000, 3), (40_000, 2)] {
        let [a, b, c] = inputs(n, nb);
        let mut d = Matrix::<f32>::zeros(n, 1, nb);
        let (p, al) = counted(|| d.assign(a.ex() + b.ex() * 2.0 + c.ex().sqrt()));
        assert_eq!((p, al), (1, 0), "fused assign, n = {n}");

        // Unfused: the same value through temporaries costs more passes and allocations.
        let mut u = Matrix::<f32>::zeros(n, 1, nb);
        let (p, al) = counted(|| {
            let t1 = Matrix::eval(b.ex() * 2.0);
            let t2 = Matrix::eval(c.ex().sqrt());
            let mut t3 = Matrix::<f32>::zeros(n, 1, nb);
            t3.assign(a.ex() + t1.ex());
            u.assign(t3.ex() + t2.ex());
        });
        assert_eq!((p, al), (4, 3), "unfused, n = {n}");
        assert_eq!(u, d, "fused and unfused values differ");
    }
}

#[test]
fn compound_assignments_are_one_pass() {
    for n in [10, 50_000] {
        let [a, b, c] = inputs(n, 1);
        let mut d = a.clone();
        assert_eq!(counted(|| d += b.ex() * 0.5 + c.ex().sqrt()), (1, 0), "+= expr");
        assert_eq!(counted(|| d -= &b), (1, 0), "-= matrix");
        assert_eq!(counted(|| d *= 3.0f32), (1, 0), "*= s");
        assert_eq!(counted(|| d /= 2.0f32), (1, 0), "/= s");
        assert_eq!(
            counted(|| d.assign_with(|d| d.cwise_mul(a.ex()) + c.ex())),
            (1, 0),
            "assign_with"
        );
        // The same sequence by explicit temporaries takes a pass and a buffer per step.
        let mut e = a.clone();
        let (p, al) = counted(|| {
            let t = Matrix::eval(b.ex() * 0.5 + c.ex().sqrt());
            let s = Matrix::eval(e.ex() + t.ex());
            e.assign(s.ex());
        });
        assert_eq!((p, al), (3, 2));
        let mut f = a.clone();
        f += b.ex() * 0.5 + c.ex().sqrt();
        assert_eq!(f, e, "compound and explicit values differ");
    }
}

fn chain(n: usize, nb: usize) -> SparseMatrix<Mat3<f64>> {
    let mut rng = Rand::new(3);
    let p = SparsityPattern::from_entries(
        n,
        n,
        (0..n).flat_map(|i| [(i, i), (i, (i + 1) % n), ((i + 1) % n, i)]),
    );
    let vals = (0..p.nnz() * nb)
        .map(|_| Mat3::from_rows(rng.mat3(-1.0, 1.0)))
        .collect();
    SparseMatrix::from_values(p, nb, vals)
}

#[test]
fn spmv_fuses_with_its_surroundings() {
    for (n, nb) in [(5, 2), (20_000, 2)] {
        let a = chain(n, nb);
        let mut rng = Rand::new(4);
        let vec3s = |rng: &mut Rand| {
            Matrix::from_fn(n, 1, nb, |_, _, _| Vec3::new(rng.unit(), rng.unit(), rng.unit()))
        };
        let (u, v) = (vec3s(&mut rng), vec3s(&mut rng));
        let mut b = Matrix::<Vec3<f64>>::zeros(n, 1, nb);
        assert_eq!(
            counted(|| b.assign(&a * u.ex() + v.ex() * 0.25)),
            (1, 0),
            "b = A u + c v"
        );
        // Unfused: A u into a temporary first.
        let mut b2 = Matrix::<Vec3<f64>>::zeros(n, 1, nb);
        let (p, al) = counted(|| {
            let au = Matrix::eval(&a * &u);
            b2.assign(au.ex() + v.ex() * 0.25);
        });
        assert_eq!((p, al), (2, 1));
        assert_eq!(b, b2);
        // SpMV of an expression: the operand is evaluated inside the product, no temporary.
        assert_eq!(counted(|| b.assign(&a * (u.ex() - v.ex()))), (1, 0), "A (u - v)");
        assert_eq!(counted(|| b.assign(a.transpose_mul(u.ex()))), (1, 0), "A^T u");
    }
}

#[test]
fn sparse_view_assignment_is_one_pass() {
    for (n, nb) in [(6, 2), (40_000, 1)] {
        let k = chain(n, nb);
        let m = Matrix::<f64>::from_fn(n, 1, nb, |r, _, b| 1.0 + (r + b) as f64);
        let mut a = SparseMatrix::<Mat3<f64>>::zeros(k.pattern().clone(), nb);
        let (p, al) = counted(|| {
            a.assign((m.ex().cast::<Mat3<f64>>().as_diagonal() * 2.0 + k.ex() * 0.5).sparse_view(k.pattern()))
        });
        assert_eq!((p, al), (1, 0), "sparse view, n = {n}");
        let kd = k.pattern().find(n - 1, n - 1).unwrap();
        let want = Mat3::from_scalar(2.0 * m.get(n - 1, 0, nb - 1)) + k.batch_values(nb - 1)[kd] * 0.5;
        assert_eq!(a.batch_values(nb - 1)[kd], want);
    }
}

#[test]
fn reductions_of_trees_are_one_pass() {
    let [a, b, _] = inputs(100_000, 2);
    let (p, al) = counted(|| {
        let _ = (a.ex() - b.ex()).squared_norm();
    });
    assert_eq!((p, al), (1, 1)); // the 1x1x1 result
    let (p, al) = counted(|| {
        let _ = (a.ex() * 2.0).dot_over(b.ex().abs(), Axes::ROWS);
    });
    assert_eq!((p, al), (1, 1));
    let (p, al) = counted(|| {
        let _ = (a.ex() - b.ex()).norm_over(Axes::ROWS | Axes::BATCHES);
    });
    assert_eq!((p, al), (1, 1));
    // Unfused: the difference evaluated first.
    let (p, al) = counted(|| {
        let d = Matrix::eval(a.ex() - b.ex());
        let _ = d.ex().squared_norm();
    });
    assert_eq!((p, al), (2, 2));
}
