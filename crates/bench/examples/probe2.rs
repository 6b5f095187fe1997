use bench::lincomb::{fused, unfused};
use bench::problems::lincomb_inputs;
use bench::timing::{measure, Policy};
use gpumat::Matrix;
use std::hint::black_box;

fn main() {
    let p = Policy {
        min_samples: 20,
        max_samples: 20,
        budget: std::time::Duration::from_millis(100),
        min_sample: std::time::Duration::from_millis(2),
    };
    for (n, k) in [
        (100usize, 2usize),
        (1000, 2),
        (4096, 2),
        (20000, 2),
        (100000, 2),
        (1000000, 2),
        (1000000, 10),
    ] {
        let (vs, a) = lincomb_inputs(n, k);
        let mut d = Matrix::<f32>::zeros(n, 1, 1);
        let mut t = [1f64; 2];
        for _ in 0..5 {
            t[0] = t[0].min(measure(&p, || fused(black_box(&mut d), black_box(&vs), black_box(&a))).seconds);
            t[1] =
                t[1].min(measure(&p, || unfused(black_box(&mut d), black_box(&vs), black_box(&a))).seconds);
        }
        println!(
            "n={n} k={k} fused {:.1} ns ({:.1} GB/s)  unfused {:.1} ns  ratio {:.2}",
            t[0] * 1e9,
            (4 * (k + 1) * n) as f64 / t[0] / 1e9,
            t[1] * 1e9,
            t[1] / t[0]
        );
    }
}
