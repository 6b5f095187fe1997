//! Dynamics: energy conservation of the undamped theta = 1/2 scheme, monotone energy decay
//! with damping or theta > 1/2, and a cube dropped on the ground coming to rest on it.

mod fem_common;
use fem_common::*;

use cutfem::fem::collision::ContactScheme;
use cutfem::fem::{Aabb, Ground, Model};
use gpumat::Vec3;

fn swing(model: Model, steps: usize) -> Vec<f64> {
    let mut sim = box_sim([0.5, 0.0, 0.0], [1.0, 0.2, 0.2], 0.05, model);
    sim.solver.cg.tolerance = 1e-12;
    let mut e = vec![sim.kinetic_energy()];
    for _ in 0..steps {
        sim.step().expect("step");
        e.push(sim.kinetic_energy() + sim.elastic_energy());
    }
    e
}

fn beam_model(theta: f64, damping: f64) -> Model {
    Model {
        young: 1.0e4,
        corotation: false,
        theta,
        dt: 0.005,
        damping_mass: damping,
        initial_velocity: Vec3::new(0.0, -1.0, 0.3),
        dirichlet: vec![Aabb {
            min: [-1.0, -1.0, -1.0],
            max: [0.051, 1.0, 1.0],
        }],
        ..Model::default()
    }
}

/// Undamped, theta = 1/2: the discrete energy `1/2 v'Mv + 1/2 u'Ku` is conserved.
#[test]
fn undamped_swing_conserves_energy() {
    let e = swing(beam_model(0.5, 0.0), 40);
    // energy after the first step (the initial velocity field violates the clamp, the first
    // step settles it; from then on the scheme is exactly conservative)
    let e0 = e[1];
    let drift = e
        .iter()
        .skip(1)
        .map(|x| ((x - e0) / e0).abs())
        .fold(0.0, f64::max);
    eprintln!("energy {e0:.6e}, max relative drift {drift:.2e}");
    assert!(drift < 1e-6, "energy drifts by {drift}");
}

/// With Rayleigh damping, or with theta > 1/2, the energy falls monotonically.
#[test]
fn damped_swing_loses_energy_monotonically() {
    for (theta, damping) in [(0.5, 2.0), (0.6, 0.0)] {
        let e = swing(beam_model(theta, damping), 40);
        for w in e[1..].windows(2) {
            assert!(
                w[1] <= w[0] * (1.0 + 1e-9),
                "theta {theta}, damping {damping}: energy rises {w:?}"
            );
        }
        assert!(
            e[40] < 0.9 * e[1],
            "theta {theta}, damping {damping}: too little loss {} -> {}",
            e[1],
            e[40]
        );
    }
}

/// A cube dropped onto the ground comes to rest on it, penetrating less than half a cell:
/// with the thesis' explicit contact (soft enough springs: `k * crossings * dt^2 / mass < 1`,
/// here 81 crossings of `k = 8` carry a mass of 0.064) and with the implicit contact and
/// springs 1000 times stiffer.
#[test]
fn dropped_cube_rests_on_ground() {
    drop_cube(8.0, ContactScheme::Thesis);
    drop_cube(1.0e4, ContactScheme::Implicit);
}

fn drop_cube(stiffness: f64, scheme: ContactScheme) {
    let h = 0.05;
    let model = Model {
        young: 5.0e3,
        gravity: Vec3::new(0.0, -10.0, 0.0),
        damping_mass: 2.0,
        damping_stiffness: 0.01,
        dt: 0.01,
        ground: Some(Ground {
            normal: Vec3::new(0.0, 1.0, 0.0),
            height: 0.0,
            stiffness,
            softness: 1000.0,
            scheme,
        }),
        ..Model::default()
    };
    let mut sim = box_sim([0.0, 0.35, 0.0], [0.4, 0.4, 0.4], h, model);
    for _ in 0..200 {
        sim.step().expect("step");
    }
    // lowest surface point: crossings interpolated
    let mut lowest = f64::INFINITY;
    for c in &sim.crossings {
        let (a, b, t) = (c.a as usize, c.b as usize, c.t);
        let pa = sim.grid.positions[a] + sim.u.get(a, 0, 0);
        let pb = sim.grid.positions[b] + sim.u.get(b, 0, 0);
        lowest = lowest.min((pa * (1.0 - t) + pb * t).y);
    }
    let speed = sim.v.ex().cwise_squared_norm().max().sqrt();
    eprintln!("{scheme:?} k = {stiffness}: lowest surface point y = {lowest:.5}, max speed {speed:.2e}");
    assert!(lowest > -0.5 * h, "penetration {lowest}");
    assert!(lowest < 0.5 * h, "the cube hovers at {lowest}");
    assert!(speed < 1e-2, "not at rest: {speed}");
}

/// The element blocks of several materials are kept ([`cutfem::fem::element::BlockCache`]):
/// switching between more materials than are kept, every assembly and step equals, bit for bit,
/// that of a fresh simulation of the same model.
#[test]
fn switching_materials_assembles_what_a_fresh_simulation_does() {
    let model = |i: usize| Model {
        young: 1.0e4 * (1.0 + 0.1 * (i % 8) as f64),
        poisson: 0.25 + 0.02 * (i % 8) as f64,
        ..beam_model(0.6, 0.0)
    };
    let mut sim = box_sim([0.5, 0.0, 0.0], [1.0, 0.2, 0.2], 0.1, model(0));
    sim.step().expect("step");
    let (u, v) = (sim.u.clone(), sim.v.clone());
    // 0, 1, 0, 2, 0, 3, ...: the tangent's pattern, then every material again, then beyond
    let order: Vec<usize> = (1..8)
        .flat_map(|i| [0, i])
        .chain(0..8)
        .chain([7, 6, 1, 0])
        .collect();
    for i in order {
        sim.set_model(model(i)).expect("model");
        sim.u = u.clone();
        sim.v = v.clone();
        sim.assemble_system();
        let mut fresh = box_sim([0.5, 0.0, 0.0], [1.0, 0.2, 0.2], 0.1, model(i));
        fresh.u = u.clone();
        fresh.v = v.clone();
        fresh.assemble_system();
        assert!(
            sim.newmark_matrix().batch_values(0) == fresh.newmark_matrix().batch_values(0),
            "material {i}: the matrix differs from a fresh simulation's"
        );
        assert!(
            sim.newmark_rhs().as_slice() == fresh.newmark_rhs().as_slice(),
            "material {i}: rhs"
        );
        assert!(
            sim.stiffness().batch_values(0) == fresh.stiffness().batch_values(0),
            "material {i}: K"
        );
        sim.step().expect("step");
        fresh.step().expect("step");
        assert!(
            sim.u.as_slice() == fresh.u.as_slice(),
            "material {i}: the step differs"
        );
    }
}
