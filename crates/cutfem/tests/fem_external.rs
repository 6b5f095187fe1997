//! The generic external force `sum_k c_k F_k` (`Model::external_force`): a field equal to
//! gravity's body force `M g` reproduces gravity's trajectory, and wrong sizes or non-finite
//! values are errors naming `model.external_force`.

mod fem_common;
use fem_common::*;

use cutfem::fem::{Aabb, ExternalForce, Model};
use gpumat::Vec3;
use std::sync::Arc;

fn held(gravity: Vec3<f64>) -> Model {
    Model {
        young: 5.0e3,
        gravity,
        dirichlet: vec![Aabb {
            min: [-1.0, -1.0, -1.0],
            max: [0.051, 1.0, 1.0],
        }],
        ..Model::default()
    }
}

#[test]
fn external_force_equal_to_m_g_reproduces_gravity() {
    let g = Vec3::new(0.0, -10.0, 2.0);
    let mut with_gravity = box_sim([0.5, 0.0, 0.0], [1.0, 0.2, 0.2], 0.05, held(g));
    let mass = with_gravity.mass.as_slice().to_vec();
    // two fields, m_i e_y and m_i e_z, with coefficients g_y, g_z
    let field = |e: Vec3<f64>| mass.iter().map(|&m| e * m).collect::<Vec<_>>();
    let mut model = held(Vec3::default());
    model.external_force = Some(ExternalForce {
        basis: Arc::new(vec![
            field(Vec3::new(0.0, 1.0, 0.0)),
            field(Vec3::new(0.0, 0.0, 1.0)),
        ]),
        coefficients: vec![-10.0, 2.0],
        labels: vec!["a".into(), "b".into()],
    });
    let mut with_external = box_sim([0.5, 0.0, 0.0], [1.0, 0.2, 0.2], 0.05, model);
    for sim in [&mut with_gravity, &mut with_external] {
        sim.solver.cg.tolerance = 1e-12;
    }
    for _ in 0..10 {
        with_gravity.step().unwrap();
        with_external.step().unwrap();
    }
    let scale = with_gravity.max_displacement();
    assert!(scale > 1e-4, "the beam bends: {scale}");
    let diff = (0..with_gravity.grid.dofs())
        .map(|i| (with_gravity.u.get(i, 0, 0) - with_external.u.get(i, 0, 0)).norm())
        .fold(0.0, f64::max);
    assert!(diff < 1e-9 * scale, "difference {diff} of {scale}");
    // the static solve sees it too
    with_gravity.solve_static().unwrap();
    with_external.solve_static().unwrap();
    let diff = (0..with_gravity.grid.dofs())
        .map(|i| (with_gravity.u.get(i, 0, 0) - with_external.u.get(i, 0, 0)).norm())
        .fold(0.0, f64::max);
    assert!(
        diff < 1e-9 * with_gravity.max_displacement(),
        "static difference {diff}"
    );
}

#[test]
fn external_force_errors_name_the_key() {
    let grid = box_grid([0.5, 0.0, 0.0], [1.0, 0.2, 0.2], 0.05);
    let n = grid.dofs();
    let bad = |basis: Vec<Vec<Vec3<f64>>>, coefficients: Vec<f64>| {
        let mut m = held(Vec3::default());
        m.external_force = Some(ExternalForce {
            labels: (0..coefficients.len()).map(|k| format!("f{k}")).collect(),
            basis: Arc::new(basis),
            coefficients,
        });
        cutfem::fem::Simulation::new(grid.clone(), m)
            .unwrap_err()
            .to_string()
    };
    let one = vec![Vec3::new(1.0, 0.0, 0.0); n];
    for msg in [
        bad(vec![one.clone()], vec![1.0, 2.0]),
        bad(vec![one.clone()], vec![f64::NAN]),
        bad(vec![vec![Vec3::new(1.0, 0.0, 0.0); n + 1]], vec![1.0]),
        bad(vec![one.clone(), one[1..].to_vec()], vec![1.0, 1.0]),
    ] {
        assert!(msg.contains("model.external_force"), "{msg}");
    }
}
