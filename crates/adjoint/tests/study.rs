//! Joint fits of a study (`adjoint::study::joint`): the joint cost, gradient and Gauss-Newton
//! matrix are the recordings' sums with the block structure of shared and per-recording
//! coordinates, the gradient is the finite-difference one, a study of one recording is its
//! single fit to the bit, and the result does not depend on the thread count.

mod common;

use adjoint::fit::FitObjective;
use adjoint::optim::{minimize, OptimParams, Optimizer};
use adjoint::params::ParamSet;
use adjoint::problem::Problem;
use adjoint::study::ensemble::Ensemble;
use adjoint::study::joint::{JointObjective, JointProblem};
use cutfem::fem::Model;
use gpumat::Vec3;
use std::ops::ControlFlow;
use std::rc::Rc;
use std::sync::{Arc, Barrier, Mutex};

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// The clamped bar of `common` without contact, launched with `v0` (it bends).
fn truth(v0: Vec3<f64>) -> Model {
    Model {
        ground: None,
        initial_velocity: v0,
        initial_angular_velocity: Vec3::default(),
        ..common::every_effect()
    }
}

/// Recording `r` (two different motions of one material), fitted from a wrong material and
/// a wrong launch.
fn recording(r: usize, params: &str) -> Problem {
    let v0 = [Vec3::new(0.4, 0.2, 0.0), Vec3::new(-0.1, 0.5, 0.3)][r];
    let t = truth(v0);
    let start = Model {
        young: t.young * 1.3,
        poisson: 0.25,
        initial_velocity: v0 * 0.8,
        ..t.clone()
    };
    common::problem(t, start, params)
}

fn study(params_own: bool) -> JointProblem {
    let p = if params_own {
        "young,poisson,initial_velocity"
    } else {
        "young,poisson"
    };
    JointProblem::new(
        vec!["a".into(), "b".into()],
        vec![recording(0, p), recording(1, p)],
        &ParamSet::parse(&["young,poisson"]).unwrap(),
    )
    .unwrap()
}

#[test]
fn joint_sums_have_the_block_structure() {
    let mut j = study(true);
    assert_eq!(j.len(), 2 + 3 + 3);
    assert_eq!(
        j.labels(),
        [
            "young",
            "poisson",
            "a:initial_velocity.x",
            "a:initial_velocity.y",
            "a:initial_velocity.z",
            "b:initial_velocity.x",
            "b:initial_velocity.y",
            "b:initial_velocity.z"
        ]
    );
    // a point away from the start in every coordinate
    let mut x = j.x0();
    x.iter_mut()
        .enumerate()
        .for_each(|(i, v)| *v += 0.01 * (i as f64 + 1.0));
    let (ev, g, h) = j.gauss_newton(&x).unwrap();
    let (mut a, mut b) = (
        recording(0, "young,poisson,initial_velocity"),
        recording(1, "young,poisson,initial_velocity"),
    );
    let (xa, xb) = (j.recording_x(&x, 0), j.recording_x(&x, 1));
    assert_eq!(xa, [&x[..2], &x[2..5]].concat());
    assert_eq!(xb, [&x[..2], &x[5..8]].concat());
    let (eva, ga, ha) = a.gauss_newton(&xa).unwrap();
    let (evb, gb, hb) = b.gauss_newton(&xb).unwrap();
    assert_eq!(ev.cost.to_bits(), (eva.cost + evb.cost).to_bits());
    for i in 0..2 {
        assert_eq!(g[i].to_bits(), (ga[i] + gb[i]).to_bits());
    }
    assert_eq!(bits(&g[2..5]), bits(&ga[2..]));
    assert_eq!(bits(&g[5..]), bits(&gb[2..]));
    let n = 8;
    let joint = |r: usize, i: usize| if i < 2 { i } else { 2 + 3 * r + i - 2 };
    for (r, hr) in [&ha, &hb].into_iter().enumerate() {
        for i in 0..5 {
            for k in 0..5 {
                let v = h[joint(r, i) * n + joint(r, k)];
                if i < 2 && k < 2 {
                    assert_eq!(v.to_bits(), (ha[i * 5 + k] + hb[i * 5 + k]).to_bits());
                } else {
                    assert_eq!(
                        v.to_bits(),
                        hr[i * 5 + k].to_bits(),
                        "H[{i}][{k}] of recording {r}"
                    );
                }
            }
        }
    }
    // the two recordings' own coordinates do not couple
    for i in 2..5 {
        for k in 5..8 {
            assert_eq!(h[i * n + k], 0.0);
            assert_eq!(h[k * n + i], 0.0);
        }
    }
    assert!(ev.recordings.len() == 2 && ev.gauss_newton.is_some());
}

#[test]
fn joint_gradient_is_the_finite_difference_gradient() {
    let mut j = study(true);
    let mut x = j.x0();
    x.iter_mut()
        .enumerate()
        .for_each(|(i, v)| *v -= 0.02 * (i as f64 + 1.0));
    let (ev, g) = j.gradient(&x).unwrap();
    assert!(ev.cost > 0.0);
    for k in 0..x.len() {
        let mut best = f64::INFINITY;
        for eps in [1e-3, 1e-4, 1e-5] {
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[k] += eps;
            xm[k] -= eps;
            let fd = (j.evaluate(&xp).unwrap().cost - j.evaluate(&xm).unwrap().cost) / (2.0 * eps);
            best = best.min((g[k] - fd).abs() / g[k].abs().max(fd.abs()));
        }
        assert!(best < 1e-5, "{}: rel {best:.2e}", j.labels()[k]);
    }
}

#[test]
fn a_study_of_one_recording_is_its_single_fit_to_the_bit() {
    let params = OptimParams {
        max_iterations: 4,
        ..OptimParams::default()
    };
    for optimizer in [Optimizer::Lbfgs, Optimizer::GaussNewton] {
        let mut single = recording(0, "young,poisson,initial_velocity");
        let x0 = single.x0();
        let (xs, infos) = minimize(
            optimizer,
            &mut FitObjective::new(&mut single),
            &x0,
            &params,
            &mut |_| ControlFlow::Continue(()),
        )
        .unwrap();
        let mut j = JointProblem::new(
            vec!["only".into()],
            vec![recording(0, "young,poisson,initial_velocity")],
            &ParamSet::parse(&["young,poisson"]).unwrap(),
        )
        .unwrap();
        assert_eq!(bits(&j.x0()), bits(&x0));
        let (xj, infoj) = minimize(
            optimizer,
            &mut JointObjective::new(&mut j),
            &x0,
            &params,
            &mut |_| ControlFlow::Continue(()),
        )
        .unwrap();
        assert_eq!(bits(&xj), bits(&xs), "{optimizer:?}");
        assert_eq!(infoj.evaluations, infos.evaluations);
        // and its standard errors are the single fit's
        let ev_single = single.gauss_newton(&xs).unwrap().0;
        let u_single = adjoint::fit::uncertainty(&mut single, &xs, &ev_single)
            .unwrap()
            .unwrap();
        let ev_joint = j.gauss_newton(&xj).unwrap().0;
        let u_joint = j.uncertainty(&xj, &ev_joint).unwrap().unwrap();
        assert_eq!(bits(&u_joint.std_errors), bits(&u_single.std_errors));
    }
}

#[test]
fn the_joint_result_does_not_depend_on_the_thread_count() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut j = study(true);
            let x = j.x0();
            let (ev, g, h) = j.gauss_newton(&x).unwrap();
            (ev.cost.to_bits(), bits(&g), bits(&h))
        })
    };
    assert_eq!(run(1), run(3));
}

/// Ranks as threads: an all-gather through shared slots and a barrier (what MPI's
/// all-gather does between processes).
struct ThreadRanks {
    rank: usize,
    size: usize,
    shared: Arc<(Mutex<Vec<Vec<u8>>>, Barrier)>,
}

impl Ensemble for ThreadRanks {
    fn rank(&self) -> usize {
        self.rank
    }
    fn size(&self) -> usize {
        self.size
    }
    fn all_gather(&self, mine: &[u8]) -> Vec<Vec<u8>> {
        let (slots, barrier) = &*self.shared;
        slots.lock().unwrap()[self.rank] = mine.to_vec();
        barrier.wait();
        let all = slots.lock().unwrap().clone();
        barrier.wait();
        all
    }
}

/// Runs `f` on `size` ranks (threads), each with its own copy of the study shared out over
/// them; every rank's result, in rank order.
fn on_ranks<T: Send>(size: usize, f: impl Fn(&mut JointProblem) -> T + Sync) -> Vec<T> {
    let shared = Arc::new((Mutex::new(vec![Vec::new(); size]), Barrier::new(size)));
    std::thread::scope(|s| {
        let handles: Vec<_> = (0..size)
            .map(|rank| {
                let (shared, f) = (shared.clone(), &f);
                s.spawn(move || {
                    let mut j = study(true);
                    j.distribute(Rc::new(ThreadRanks { rank, size, shared }));
                    f(&mut j)
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    })
}

#[test]
fn ranks_share_the_recordings_and_agree_with_one_process_to_the_bit() {
    let eval = |j: &mut JointProblem| {
        let x = j.x0();
        let (ev, g, h) = j.gauss_newton(&x).unwrap();
        let frames: Vec<_> = ev.recordings.iter().map(|e| e.frames.clone()).collect();
        (ev.cost.to_bits(), bits(&g), bits(&h), frames, j.owners().to_vec())
    };
    let (c1, g1, h1, f1, _) = eval(&mut study(true));
    for size in [2, 3] {
        for (rank, (c, g, h, f, owners)) in on_ranks(size, eval).into_iter().enumerate() {
            assert_eq!((c, &g, &h), (c1, &g1, &h1), "{size} ranks, rank {rank}");
            assert_eq!(f, f1);
            // the two recordings (same size) go to ranks 0 and 1; a third rank idles
            assert_eq!(owners, vec![0, 1]);
        }
    }
    // a short fit on two ranks takes the same steps as in one process
    let fit = |j: &mut JointProblem| {
        let x0 = j.x0();
        let mut obj = JointObjective::new(j);
        let params = OptimParams {
            max_iterations: 2,
            ..OptimParams::default()
        };
        let (x, _) = minimize(Optimizer::GaussNewton, &mut obj, &x0, &params, &mut |_| {
            ControlFlow::Continue(())
        })
        .unwrap();
        bits(&x)
    };
    let one = fit(&mut study(true));
    assert!(on_ranks(2, fit).iter().all(|x| *x == one));
}

#[test]
fn a_recording_that_fails_on_its_rank_stops_every_rank_with_its_message() {
    // recording `b` (rank 1) gets a non-finite launch velocity: its forward run fails there
    let results = on_ranks(2, |j| {
        let mut x = j.x0();
        let n = x.len();
        x[n - 1] = f64::NAN;
        j.gradient(&x).map(|_| ()).map_err(|e| e.to_string())
    });
    let local = {
        let mut j = study(true);
        let mut x = j.x0();
        let n = x.len();
        x[n - 1] = f64::NAN;
        j.gradient(&x).map(|_| ()).map_err(|e| e.to_string())
    };
    let msg = local.expect_err("a NaN launch velocity fails the forward run");
    assert!(msg.starts_with("recording `b`: "), "{msg}");
    for r in results {
        assert_eq!(r, Err(msg.clone()));
    }
}

#[test]
fn a_joint_fit_recovers_the_shared_material_from_two_motions() {
    let mut j = study(true);
    let x0 = j.x0();
    let params = OptimParams {
        max_iterations: 30,
        ..OptimParams::default()
    };
    let (x, _) = minimize(
        Optimizer::GaussNewton,
        &mut JointObjective::new(&mut j),
        &x0,
        &params,
        &mut |_| ControlFlow::Continue(()),
    )
    .unwrap();
    let v = j.values(&x);
    let get = |l: &str| v.iter().find(|(k, _)| k == l).unwrap().1;
    let t = common::every_effect();
    assert!(
        (get("young") / t.young - 1.0).abs() < 1e-4,
        "young {}",
        get("young")
    );
    assert!(
        (get("poisson") - t.poisson).abs() < 1e-4,
        "poisson {}",
        get("poisson")
    );
    assert!((get("b:initial_velocity.z") - 0.3).abs() < 1e-4, "{v:?}");
    // correlations are within [-1, 1] and symmetric
    let ev = j.gauss_newton(&x).unwrap().0;
    if let Some(u) = j.uncertainty(&x, &ev).unwrap() {
        assert!((u.correlation(0, 1) - u.correlation(1, 0)).abs() < 1e-12);
        assert!(u.correlation(0, 1).abs() <= 1.0 + 1e-12);
        assert!((u.correlation(0, 0) - 1.0).abs() < 1e-12);
    }
}
