//! The noise floor from the residuals at a fit (`adjoint::diagnosis::floor`) on unstructured surface
//! samples of a thin bar (the hard case: no cameras, 100-1000 points per frame), with a
//! smooth misfit of the model on top of the noise: within 20% of the true deviation, and the
//! model-free plane-fit floor on the same points for comparison.

use adjoint::diagnosis::floor::residual_floor;
use adjoint::diagnosis::residuals::{noise_floor, PointResidual};
use adjoint::observations::{Observations, ObservedPoint};
use adjoint::observe::rng::SplitMix64;

/// The bar 1.05 x 0.22 x 0.22 (x from 0).
const SIZE: [f64; 3] = [1.05, 0.22, 0.22];

/// A point uniform by area on the bar's surface and its outward normal.
fn surface_point(rng: &mut SplitMix64) -> ([f64; 3], [f64; 3]) {
    let areas = [SIZE[1] * SIZE[2], SIZE[0] * SIZE[2], SIZE[0] * SIZE[1]];
    let total: f64 = 2.0 * areas.iter().sum::<f64>();
    let mut t = rng.uniform() * total;
    for (axis, a) in areas.iter().enumerate() {
        for side in [0.0, 1.0] {
            if t < *a || (axis == 2 && side == 1.0) {
                let mut p = [0, 1, 2].map(|d| rng.uniform() * SIZE[d]);
                p[axis] = side * SIZE[axis];
                let mut n = [0.0; 3];
                n[axis] = 2.0 * side - 1.0;
                return (p, n);
            }
            t -= a;
        }
    }
    unreachable!()
}

/// The misfit of a model at surface point `q` (normal `n`, frame `frame`), of size `misfit`.
type Misfit = fn(q: [f64; 3], n: [f64; 3], frame: usize, misfit: f64) -> f64;

/// A smooth scalar field over the surface.
fn smooth(q: [f64; 3], _n: [f64; 3], frame: usize, misfit: f64) -> f64 {
    let phase = 0.4 * frame as f64;
    misfit * ((3.0 * q[0] + phase).sin() + 0.5 * (9.0 * q[1] - phase).cos())
}

/// A missing sag: the displacement `(0, -misfit x^2 t, 0)` (t = frame / 10) seen along the
/// normal, so the misfit jumps at the bar's edges.
fn sag(q: [f64; 3], n: [f64; 3], frame: usize, misfit: f64) -> f64 {
    -misfit * q[0] * q[0] * frame as f64 / 10.0 * n[1]
}

/// `frames` frames of `per_frame` points: residual = the misfit + sigma n; the observed point
/// is the surface point moved along the normal by its residual.
fn case(per_frame: usize, sigma: f64, misfit: f64, seed: u64) -> (Vec<PointResidual>, Observations) {
    case_with(smooth, per_frame, sigma, misfit, seed)
}

fn case_with(
    field: Misfit,
    per_frame: usize,
    sigma: f64,
    misfit: f64,
    seed: u64,
) -> (Vec<PointResidual>, Observations) {
    let mut rng = SplitMix64::new(seed);
    let (mut records, mut obs) = (Vec::new(), Observations::new());
    for frame in 1..=10 {
        for _ in 0..per_frame {
            let (q, n) = surface_point(&mut rng);
            let r = field(q, n, frame, misfit) + sigma * rng.gaussian();
            let p = [0, 1, 2].map(|d| q[d] + r * n[d]);
            records.push(PointResidual {
                frame,
                camera: None,
                position: p,
                residual: r,
                vector: n.map(|v| v * r),
                reference: q,
                outside: false,
            });
            obs.push(frame, ObservedPoint::new(p));
        }
    }
    (records, obs)
}

#[test]
fn difference_floor_is_within_20_percent_on_sparse_bar_samples() {
    for per_frame in [100, 300, 1000] {
        for sigma in [0.003, 0.01, 0.03] {
            // a misfit as large as the noise: what a missing effect or the grid leaves
            let (records, obs) = case(per_frame, sigma, 0.01, 7 + per_frame as u64);
            let f = residual_floor(&records).expect("enough pairs");
            let plane = noise_floor(&obs, &[], &[], 0.1).expect("enough planes");
            eprintln!(
                "{per_frame} points/frame, sigma {sigma}: residual floor {:.5} (+- {:.5}, {} points), \
                 plane fits {plane:.5}",
                f.sigma, f.std_error, f.points
            );
            let ratio = f.sigma / sigma;
            assert!((0.8..=1.2).contains(&ratio), "{per_frame} / {sigma}: {ratio}");
            // the standard error is what it says: the truth within 4 of them
            assert!((f.sigma - sigma).abs() < 4.0 * f.std_error + 0.1 * sigma, "{f:?}");
        }
    }
}

/// A missing effect (the model as given, before the diagnosis): a sag of 3, 6 and 15 times the
/// noise at the tip, which jumps at the bar's edges (seen along the normal): the model's rms
/// 1.2, 1.6 and 3.2 times the noise.
#[test]
fn difference_floor_holds_under_a_large_misfit() {
    for per_frame in [100, 300, 1000] {
        for amplitude in [0.03, 0.06, 0.15] {
            let sigma = 0.01;
            let (records, _) = case_with(sag, per_frame, sigma, amplitude, 11 + per_frame as u64);
            let rms =
                (records.iter().map(|r| r.residual * r.residual).sum::<f64>() / records.len() as f64).sqrt();
            let f = residual_floor(&records).expect("enough pairs");
            eprintln!(
                "sag {amplitude}, {per_frame} points/frame: rms {rms:.4} ({:.2}x the noise), floor {:.5}",
                rms / sigma,
                f.sigma
            );
            let ratio = f.sigma / sigma;
            if rms < 1.7 * sigma {
                // the subtle cases, where the floor decides: within 20%
                assert!((0.8..=1.2).contains(&ratio), "{per_frame} / {amplitude}: {ratio}");
            } else {
                // a large misfit leaks into the floor on sparse points (its jumps at the edges),
                // but the floor stays far below the rms: the verdict "fails" is not in doubt
                assert!(
                    ratio < 1.5 && f.sigma < 0.5 * rms,
                    "{per_frame} / {amplitude}: {ratio}"
                );
            }
        }
    }
}

#[test]
fn difference_floor_needs_pairs_and_skips_outside_points() {
    let (mut records, _) = case(5, 0.01, 0.0, 3);
    records.truncate(12);
    assert!(residual_floor(&records).is_none());
    // far outliers marked outside do not count
    let (mut records, _) = case(300, 0.01, 0.0, 4);
    let clean = residual_floor(&records).unwrap();
    for r in records.iter_mut().step_by(10) {
        r.residual = 5.0;
        r.outside = true;
    }
    let with = residual_floor(&records).unwrap();
    assert!(with.points < clean.points);
    assert!((with.sigma / clean.sigma - 1.0).abs() < 0.1, "{with:?} {clean:?}");
}
