//! Block scalars against naive `f64` loops: `Vec3`/`Mat3` add, sub, neg, scale, `Mat3*Vec3`,
//! `Mat3*Mat3` (operators and the element product `smul`), transpose, dot, cross, outer,
//! determinant (Leibniz formula) and inverse (Gauss-Jordan), in `f32` and `f64`; and block
//! scalars as matrix elements: lane-wise unary operations (the padding lane stays zero),
//! `real .* Vec3`, `Mat3 .* Vec3`, `Mat3 .* Mat3`, block transpose, casts, identity/constant
//! nodes, and reductions (lane sums, Frobenius inner products and norms) over every axis set.

mod common;

use common::*;
use gpumat::{Axes, Mat3, Matrix, Real, Scalar, ScalarMul, Vec3};
use proptest::prelude::*;

type M = [[f64; 3]; 3];

fn mm(a: &M, b: &M) -> M {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}
fn mv(a: &M, v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| (0..3).map(|k| a[i][k] * v[k]).sum())
}
/// Determinant by the Leibniz formula (sum over the 6 permutations).
fn det(a: &M) -> f64 {
    const PERMS: [([usize; 3], f64); 6] = [
        ([0, 1, 2], 1.0),
        ([1, 2, 0], 1.0),
        ([2, 0, 1], 1.0),
        ([0, 2, 1], -1.0),
        ([2, 1, 0], -1.0),
        ([1, 0, 2], -1.0),
    ];
    PERMS
        .iter()
        .map(|(p, s)| s * a[0][p[0]] * a[1][p[1]] * a[2][p[2]])
        .sum()
}
/// Inverse by Gauss-Jordan elimination with partial pivoting.
fn inv(a: &M) -> M {
    let mut w = [[0.0; 6]; 3];
    for i in 0..3 {
        w[i][..3].copy_from_slice(&a[i]);
        w[i][3 + i] = 1.0;
    }
    for c in 0..3 {
        let p = (c..3)
            .max_by(|&x, &y| w[x][c].abs().total_cmp(&w[y][c].abs()))
            .unwrap();
        w.swap(c, p);
        let d = w[c][c];
        for v in w[c].iter_mut() {
            *v /= d;
        }
        for r in 0..3 {
            if r != c {
                let f = w[r][c];
                let row = w[c];
                for (v, x) in w[r].iter_mut().zip(row) {
                    *v -= f * x;
                }
            }
        }
    }
    std::array::from_fn(|i| std::array::from_fn(|j| w[i][3 + j]))
}

fn m3<R: Real>(a: &M) -> Mat3<R> {
    Mat3::from_rows(a.map(|r| r.map(R::of)))
}
fn back<R: Real>(m: Mat3<R>) -> M {
    m.m.map(|r| r.map(|x| x.as_f64()))
}
fn v3<R: Real>(v: [f64; 3]) -> Vec3<R> {
    Vec3::new(R::of(v[0]), R::of(v[1]), R::of(v[2]))
}
fn vback<R: Real>(v: Vec3<R>) -> [f64; 3] {
    assert_eq!(v.w, R::ZERO, "padding lane of {v:?} is not zero");
    [v.x.as_f64(), v.y.as_f64(), v.z.as_f64()]
}
/// The value as the block type stores it (rounded to `R`), back in `f64`.
fn round_m<R: Real>(a: &M) -> M {
    a.map(|r| r.map(|x| R::of(x).as_f64()))
}
fn round_v<R: Real>(v: [f64; 3]) -> [f64; 3] {
    v.map(|x| R::of(x).as_f64())
}

#[track_caller]
fn close_m(got: M, want: M, tol: f64, what: &str) {
    for i in 0..3 {
        for j in 0..3 {
            assert_close(got[i][j], want[i][j], tol, &format!("{what}[{i}][{j}]"));
        }
    }
}
#[track_caller]
fn close_v(got: [f64; 3], want: [f64; 3], tol: f64, what: &str) {
    for i in 0..3 {
        assert_close(got[i], want[i], tol, &format!("{what}[{i}]"));
    }
}

/// The block algebra in real type `R`, against `f64` on the inputs rounded to `R`. Entries
/// are in `[-2, 2]`, so `4 eps * 12` bounds the rounding of any 3-term product sum.
fn check_algebra<R>(seed: u64)
where
    Mat3<R>: Scalar<Real = R> + ScalarMul<Vec3<R>, Output = Vec3<R>> + ScalarMul<Output = Mat3<R>>,
    Vec3<R>: Scalar<Real = R> + ScalarMul<Output = Vec3<R>>,
    R: Real + ScalarMul<Vec3<R>, Output = Vec3<R>>,
{
    let mut rng = Rand::new(seed);
    let (a, b) = (
        round_m::<R>(&rng.mat3(-2.0, 2.0)),
        round_m::<R>(&rng.mat3(-2.0, 2.0)),
    );
    let u = round_v::<R>([
        rng.uniform(-2.0, 2.0),
        rng.uniform(-2.0, 2.0),
        rng.uniform(-2.0, 2.0),
    ]);
    let v = round_v::<R>([
        rng.uniform(-2.0, 2.0),
        rng.uniform(-2.0, 2.0),
        rng.uniform(-2.0, 2.0),
    ]);
    let s = R::of(rng.uniform(-3.0, 3.0));
    let (ma, mb, vu, vv) = (m3::<R>(&a), m3::<R>(&b), v3::<R>(u), v3::<R>(v));
    let e = eps::<R>();
    let tol = 4.0 * e * 12.0;
    let sf = s.as_f64();
    close_m(
        back(ma + mb),
        std::array::from_fn(|i| std::array::from_fn(|j| a[i][j] + b[i][j])),
        2.0 * e * 4.0,
        "add",
    );
    close_m(
        back(ma - mb),
        std::array::from_fn(|i| std::array::from_fn(|j| a[i][j] - b[i][j])),
        2.0 * e * 4.0,
        "sub",
    );
    close_m(back(-ma), a.map(|r| r.map(|x| -x)), 0.0, "neg");
    close_m(back(ma * s), a.map(|r| r.map(|x| x * sf)), e * 6.0, "scale");
    close_m(
        back(ma.scale(s)),
        a.map(|r| r.map(|x| x * sf)),
        e * 6.0,
        "Scalar::scale",
    );
    close_m(back(ma * mb), mm(&a, &b), tol, "Mat3 * Mat3");
    close_m(back(ma.smul(mb)), mm(&a, &b), tol, "Mat3 smul Mat3");
    close_m(
        back(ma.transpose()),
        std::array::from_fn(|i| std::array::from_fn(|j| a[j][i])),
        0.0,
        "transpose",
    );
    close_m(
        back(Scalar::transpose(ma)),
        back(ma.transpose()),
        0.0,
        "Scalar::transpose",
    );
    close_v(vback(ma * vu), mv(&a, u), tol, "Mat3 * Vec3");
    close_v(vback(ma.smul(vu)), mv(&a, u), tol, "Mat3 smul Vec3");
    close_v(
        vback(vu + vv),
        std::array::from_fn(|i| u[i] + v[i]),
        2.0 * e * 4.0,
        "Vec3 add",
    );
    close_v(
        vback(vu - vv),
        std::array::from_fn(|i| u[i] - v[i]),
        2.0 * e * 4.0,
        "Vec3 sub",
    );
    close_v(vback(-vu), u.map(|x| -x), 0.0, "Vec3 neg");
    close_v(vback(vu * s), u.map(|x| x * sf), e * 6.0, "Vec3 scale");
    close_v(
        vback(vu.smul(vv)),
        std::array::from_fn(|i| u[i] * v[i]),
        e * 4.0,
        "Vec3 lane product",
    );
    close_v(vback(s.smul(vu)), u.map(|x| x * sf), e * 6.0, "real smul Vec3");
    let dot: f64 = (0..3).map(|i| u[i] * v[i]).sum();
    assert_close(vu.dot(vv).as_f64(), dot, tol, "Vec3 dot");
    assert_close(Scalar::dot(vu, vv).as_f64(), dot, tol, "Scalar::dot Vec3");
    let fro: f64 = (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .map(|(i, j)| a[i][j] * b[i][j])
        .sum();
    assert_close(
        Scalar::dot(ma, mb).as_f64(),
        fro,
        4.0 * e * 36.0,
        "Scalar::dot Mat3 (Frobenius)",
    );
    let cross = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    close_v(vback(vu.cross(vv)), cross, tol, "cross");
    close_m(
        back(vu.outer(vv)),
        std::array::from_fn(|i| std::array::from_fn(|j| u[i] * v[j])),
        e * 4.0,
        "outer",
    );
    assert_close(
        vu.norm().as_f64(),
        (u.iter().map(|x| x * x).sum::<f64>()).sqrt(),
        tol,
        "norm",
    );
    assert_close(
        ma.trace().as_f64(),
        a[0][0] + a[1][1] + a[2][2],
        3.0 * e * 6.0,
        "trace",
    );
    assert_close(ma.determinant().as_f64(), det(&a), 8.0 * e * 48.0, "determinant");
    close_v(vback(ma.diagonal()), [a[0][0], a[1][1], a[2][2]], 0.0, "diagonal");
    close_v(vback(ma.row(1)), a[1], 0.0, "row");
    close_v(vback(ma.col(2)), [a[0][2], a[1][2], a[2][2]], 0.0, "col");
    assert_eq!(Mat3::from_cols(ma.col(0), ma.col(1), ma.col(2)), ma);
    // Inverse of a well-conditioned block (diagonally dominant: a + 7 I).
    let mut c = a;
    for (i, row) in c.iter_mut().enumerate() {
        row[i] += 7.0;
    }
    let mc = m3::<R>(&c);
    let got = back(mc.inverse().expect("invertible"));
    close_m(got, inv(&c), 64.0 * e, "inverse vs Gauss-Jordan");
    close_m(
        mm(&got, &c),
        back(Mat3::<R>::identity()),
        64.0 * e * 9.0,
        "inverse * A",
    );
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn block_algebra(seed in any::<u64>()) {
        check_algebra::<f32>(seed);
        check_algebra::<f64>(seed);
    }

    #[test]
    fn singular_blocks_have_no_inverse(seed in any::<u64>()) {
        // Small integers: the determinant of a matrix with a dependent row is exactly zero.
        let mut rng = Rand::new(seed);
        let r0: [f64; 3] = std::array::from_fn(|_| (rng.below(9) as f64) - 4.0);
        let r1: [f64; 3] = std::array::from_fn(|_| (rng.below(9) as f64) - 4.0);
        let k = (rng.below(5) as f64) - 2.0;
        let r2: [f64; 3] = std::array::from_fn(|j| r0[j] + k * r1[j]);
        let m = Mat3::<f64>::from_rows([r0, r1, r2]);
        prop_assert_eq!(m.determinant(), 0.0);
        prop_assert!(m.inverse().is_none());
        let m = Mat3::<f64>::from_rows([r0, r1, [f64::NAN, 0.0, 0.0]]);
        prop_assert!(m.inverse().is_none());
    }

    /// Block elements inside fused expressions, with broadcasting.
    #[test]
    fn blocks_in_expressions(seed in any::<u64>(), s in (1usize..5, 1usize..4, 1usize..4)) {
        let mut rng = Rand::new(seed);
        let vec3 = |rng: &mut Rand, lo: f64, hi: f64| Vec3::new(rng.uniform(lo, hi), rng.uniform(lo, hi), rng.uniform(lo, hi));
        let a = Matrix::from_fn(s.0, s.1, s.2, |_, _, _| vec3(&mut rng, -2.0, 2.0));
        let b = Matrix::from_fn(s.0, s.1, s.2, |_, _, _| vec3(&mut rng, 0.1, 4.0));
        let w = Matrix::from_fn(s.0, 1, 1, |_, _, _| rng.uniform(-2.0, 2.0)); // broadcast real
        let m = Matrix::from_fn(s.0, s.1, s.2, |_, _, _| Mat3::from_rows(rng.mat3(-2.0, 2.0)));
        let m2 = Matrix::from_fn(s.0, s.1, 1, |_, _, _| Mat3::from_rows(rng.mat3(-2.0, 2.0)));
        let tol = 4.0 * f64::EPSILON * 40.0;
        let d = Matrix::eval(a.ex() + b.ex().sqrt().scale(2.0) - w.ex().cwise_mul(a.ex()) + gpumat::scalar(Vec3::splat(0.5)));
        let mv_ = Matrix::eval(m.ex().cwise_mul(a.ex()));
        let mm_ = Matrix::eval(m.ex().cwise_mul(m2.ex()) + gpumat::identity::<Mat3<f64>>(s.0, s.1, 1));
        let tr = Matrix::eval(m.ex().transpose());
        let dots = Matrix::eval(a.ex().cwise_dot(b.ex()));
        let sqn = Matrix::eval(m.ex().cwise_squared_norm());
        let diag = Matrix::eval(a.ex().cast::<Mat3<f64>>() + w.ex().cast::<Mat3<f64>>());
        let spl = Matrix::eval(w.ex().cast::<Vec3<f64>>());
        let low = Matrix::<Vec3<f32>>::eval(a.ex().cast::<Vec3<f32>>().exp());
        for bb in 0..s.2 {
            for c in 0..s.1 {
                for r in 0..s.0 {
                    let (av, bv, wr) = (a.get(r, c, bb).to_array(), b.get(r, c, bb).to_array(), w.get(r, 0, 0));
                    let (mr, m2r) = (m.get(r, c, bb).m, m2.get(r, c, 0).m);
                    let want: [f64; 3] = std::array::from_fn(|i| av[i] + 2.0 * bv[i].sqrt() - wr * av[i] + 0.5);
                    close_v(vback(d.get(r, c, bb)), want, tol, "vec3 expression");
                    close_v(vback(mv_.get(r, c, bb)), mv(&mr, av), tol, "Mat3 .* Vec3");
                    let mut want = mm(&mr, &m2r);
                    if r == c {
                        for (i, row) in want.iter_mut().enumerate() {
                            row[i] += 1.0;
                        }
                    }
                    close_m(mm_.get(r, c, bb).m, want, tol, "Mat3 .* Mat3 + I");
                    close_m(tr.get(c, r, bb).m, std::array::from_fn(|i| std::array::from_fn(|j| mr[j][i])), 0.0, "block transpose");
                    assert_close(dots.get(r, c, bb), (0..3).map(|i| av[i] * bv[i]).sum(), tol, "cwise_dot");
                    let fro: f64 = mr.iter().flatten().map(|x| x * x).sum();
                    assert_close(sqn.get(r, c, bb), fro, tol, "cwise_squared_norm");
                    let want: M = std::array::from_fn(|i| std::array::from_fn(|j| if i == j { av[i] + wr } else { 0.0 }));
                    close_m(diag.get(r, c, bb).m, want, tol, "cast Vec3 -> Mat3 plus real -> Mat3");
                    close_v(vback(spl.get(r, 0, 0)), [wr; 3], 0.0, "cast real -> Vec3");
                    let le = low.get(r, c, bb);
                    prop_assert_eq!(le.w, 0.0f32);
                    close_v([le.x as f64, le.y as f64, le.z as f64], av.map(|x| (x as f32 as f64).exp()), 4.0 * f32::EPSILON as f64 * 8.0, "f32 exp");
                }
            }
        }
    }

    /// Reductions over block elements: lane-wise sums, Frobenius dots and norms.
    #[test]
    fn blocks_in_reductions(seed in any::<u64>(), s in (1usize..6, 1usize..5, 1usize..4)) {
        let mut rng = Rand::new(seed);
        let a = Matrix::from_fn(s.0, s.1, s.2, |_, _, _| Vec3::new(rng.uniform(-2.0, 2.0), rng.uniform(-2.0, 2.0), rng.uniform(-2.0, 2.0)));
        let b = Matrix::from_fn(s.0, s.1, s.2, |_, _, _| Vec3::new(rng.uniform(-2.0, 2.0), rng.uniform(-2.0, 2.0), rng.uniform(-2.0, 2.0)));
        let m = Matrix::from_fn(s.0, s.1, s.2, |_, _, _| Mat3::<f32>::from_rows(rng.mat3(-2.0, 2.0).map(|r| r.map(|x| x as f32))));
        let n = (s.0 * s.1 * s.2) as f64;
        for mask in 0..8u8 {
            let axes = Axes { rows: mask & 1 != 0, cols: mask & 2 != 0, batches: mask & 4 != 0 };
            let sum = a.ex().sum_over(axes);
            let dot = a.ex().dot_over(b.ex(), axes);
            let nrm = m.ex().norm_over(axes);
            let msum = m.ex().sum_over(axes);
            let out = sum.shape();
            for ob in 0..out.batches {
                for oc in 0..out.cols {
                    for or in 0..out.rows {
                        let mut lanes = [0.0; 3];
                        let mut d = 0.0;
                        let mut fro = 0.0;
                        let mut ms = [[0.0f64; 3]; 3];
                        for bb in 0..s.2 {
                            for c in 0..s.1 {
                                for r in 0..s.0 {
                                    let hit = (axes.rows || r == or) && (axes.cols || c == oc) && (axes.batches || bb == ob);
                                    if hit {
                                        let (av, bv) = (a.get(r, c, bb).to_array(), b.get(r, c, bb).to_array());
                                        let mm = back(m.get(r, c, bb));
                                        for i in 0..3 {
                                            lanes[i] += av[i];
                                            d += av[i] * bv[i];
                                            for j in 0..3 {
                                                fro += mm[i][j] * mm[i][j];
                                                ms[i][j] += mm[i][j];
                                            }
                                        }
                                    }
                                }
                            }
                        }
                        let tol = (3.0 * n + 3.0) * f64::EPSILON * 4.0 * n;
                        close_v(vback(sum.get(or, oc, ob)), lanes, tol, "Vec3 sum_over");
                        assert_close(dot.get(or, oc, ob), d, tol, "Vec3 dot_over");
                        let ftol = (9.0 * n + 3.0) * f32::EPSILON as f64;
                        assert_close(nrm.get(or, oc, ob) as f64, fro.sqrt(), ftol * fro.sqrt(), "Mat3 norm_over");
                        close_m(back(msum.get(or, oc, ob)), ms, ftol * 2.0 * n, "Mat3 sum_over");
                    }
                }
            }
        }
        let total = a.ex().sum();
        let lanes: [f64; 3] = std::array::from_fn(|i| a.as_slice().iter().map(|v| v.to_array()[i]).sum());
        close_v(vback(total), lanes, n * f64::EPSILON * 2.0 * n, "Vec3 sum()");
        let fro: f64 = a.as_slice().iter().map(|v| v.dot(*v)).sum();
        assert_close(a.ex().squared_norm(), fro, (3.0 * n + 1.0) * f64::EPSILON * fro, "Vec3 squared_norm()");
    }
}
