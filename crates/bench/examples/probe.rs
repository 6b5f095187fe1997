use bench::problems::{poisson_matrix, random_vector};
use bench::timing::{measure, Policy};
use gpumat::{Axes, Jacobi, Matrix, Preconditioner};
use std::hint::black_box;

fn main() {
    let p = Policy {
        min_samples: 10,
        max_samples: 10,
        budget: std::time::Duration::from_millis(100),
        min_sample: std::time::Duration::from_millis(2),
    };
    let g = 1000usize;
    let n = g * g;
    let a = poisson_matrix(g);
    let pv = random_vector(1, n);
    let z = random_vector(4, n);
    let mut q = Matrix::<f32>::zeros(n, 1, 1);
    let mut x = random_vector(2, n);
    let mut r = random_vector(3, n);
    let mut pp = random_vector(5, n);
    let mut zz = Matrix::<f32>::zeros(n, 1, 1);
    let alpha = Matrix::<f32>::constant(1, 1, 1, 1e-7);
    let pre = Jacobi::new(&a).unwrap();
    let mut t = [1f64; 8];
    for _ in 0..5 {
        t[0] = t[0].min(measure(&p, || q.assign(&a * &pv)).seconds);
        t[1] = t[1].min(
            measure(&p, || {
                black_box(pv.ex().dot_over(q.ex(), Axes::ROWS));
            })
            .seconds,
        );
        t[2] = t[2].min(measure(&p, || x.assign_with(|x| x + alpha.ex().cwise_mul(pv.ex()))).seconds);
        t[3] = t[3].min(measure(&p, || r.assign_with(|r| r - alpha.ex().cwise_mul(q.ex()))).seconds);
        t[4] = t[4].min(measure(&p, || pre.apply(&r, &mut zz)).seconds);
        t[5] = t[5].min(
            measure(&p, || {
                black_box(r.ex().dot_over(zz.ex(), Axes::ROWS));
            })
            .seconds,
        );
        t[6] = t[6].min(
            measure(&p, || {
                black_box(r.ex().norm_over(Axes::ROWS));
            })
            .seconds,
        );
        t[7] = t[7].min(measure(&p, || pp.assign_with(|p| z.ex() + alpha.ex().cwise_mul(p))).seconds);
    }
    let names = [
        "spmv", "dot pq", "x upd", "r upd", "precond", "dot rz", "norm r", "p upd",
    ];
    for (nm, s) in names.iter().zip(t) {
        println!("{nm:8} {:.3} ms", s * 1e3);
    }
    println!("sum {:.3} ms", t.iter().sum::<f64>() * 1e3);
}
