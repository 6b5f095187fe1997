//! Static checks of the element and the assembly: patch test, exact strain energy of a linear
//! field, rigid motions under corotation, and element/derivative consistency.

mod fem_common;
use fem_common::*;

use cutfem::cutcell::{cell_integrals, CellIntegrals};
use cutfem::fem::element::{
    deformation_gradient, lame, polar_rotation, Element, ElementSet, StiffnessTables, FICTITIOUS_STIFFNESS,
};
use cutfem::fem::Model;
use gpumat::{Mat3, Matrix, Vec3};

fn linear_field(sim: &cutfem::fem::Simulation, a: Mat3<f64>) -> Matrix<Vec3<f64>> {
    Matrix::from_fn(sim.grid.dofs(), 1, 1, |i, _, _| a * sim.grid.positions[i])
}

fn strain_energy_density(a: Mat3<f64>, e: f64, nu: f64) -> f64 {
    let (lambda, mu) = lame(e, nu);
    let eps = (a + a.transpose()) * 0.5;
    let tr = eps.trace();
    let mut ee = 0.0;
    for p in 0..3 {
        for q in 0..3 {
            ee += eps.m[p][q] * eps.m[p][q];
        }
    }
    0.5 * lambda * tr * tr + mu * ee
}

/// A uniform strain is reproduced exactly: the elastic force vanishes at every node whose
/// surrounding cells are all full (patch test), and the forces sum to zero everywhere.
#[test]
fn patch_test_uniform_strain() {
    let mut rows = Vec::new();
    for element in Element::ALL {
        let worst = patch_test(element);
        eprintln!(
            "{:<20} worst interior residual / nodal force {worst:.2e}",
            element.name()
        );
        rows.push((element.name(), worst, 0.0, 1e-9));
    }
    reference::check(
        "patch_test",
        "largest residual force at the interior nodes of the cuboid (h = 0.05) under a uniform strain, relative to a typical nodal force E h |strain|; every element",
        "cargo test --release -p cutfem --test fem_statics patch_test",
        &rows,
    );
}

/// The worst interior residual of the patch test with `element`, relative to a nodal force.
fn patch_test(element: Element) -> f64 {
    let model = Model {
        corotation: false,
        element,
        ..Model::default()
    };
    let mut sim = box_sim([0.0, 1.0, 0.0], [1.29, 0.4, 0.8], 0.05, model);
    let a = Mat3::from_rows([[0.01, 0.002, -0.003], [0.004, -0.02, 0.001], [0.0, 0.005, 0.015]]);
    sim.u = linear_field(&sim, a);
    let f = sim.elastic_force();
    let scale: f64 = 2000.0 * 0.05 * 0.02; // E h |strain|: a typical nodal force
    let mut interior = 0;
    let mut worst: f64 = 0.0;
    for d in 0..sim.grid.dofs() {
        let full = sim.assembler.cells_of(d).len() == 8
            && sim
                .assembler
                .cells_of(d)
                .iter()
                .all(|&(e, _)| sim.grid.cells[e as usize].is_full());
        if full {
            interior += 1;
            let r = f.get(d, 0, 0).norm();
            worst = worst.max(r / scale);
            assert!(
                r < 1e-9 * scale,
                "{}: node {d}: residual force {r}",
                element.name()
            );
        }
    }
    assert!(interior > 100, "only {interior} interior nodes");
    let total = f.ex().sum();
    assert!(total.norm() < 1e-9, "forces do not sum to zero: {total:?}");
    worst
}

/// For a linear displacement every element is exact, also on cut cells:
/// `1/2 u^T K u = volume * W(eps)` with the discrete cut volume `sum w_v` (which itself is
/// within a few per mille of the exact one: the box's edges are chamfered by the piecewise
/// linear interface). For the incompatible modes this is the patch test on cut cells: the
/// mean-free bubbles stay at rest under a uniform strain (a bubble mean over the full cube
/// instead of the cut part would relax the energy below the exact one). The exactly integrated
/// elements add the empty part of the cut cells at the share `FICTITIOUS_STIFFNESS` (1e-6).
#[test]
fn strain_energy_of_linear_field_is_exact_on_cut_cells() {
    for element in Element::ALL {
        linear_field_energy(element);
    }
}

fn linear_field_energy(element: Element) {
    // a box whose faces do not align with the grid: every boundary cell is cut
    let model = Model {
        corotation: false,
        young: 3000.0,
        poisson: 0.35,
        element,
        ..Model::default()
    };
    let (size, h) = ([0.93, 0.41, 0.57], 0.05);
    let mut sim = box_sim([0.013, 0.977, -0.021], size, h, model);
    let a = Mat3::from_rows([[0.01, 0.002, -0.003], [0.004, -0.02, 0.001], [0.0, 0.005, 0.015]]);
    sim.u = linear_field(&sim, a);
    let _ = sim.elastic_force();
    let volume = sim.grid.volume();
    let exact_volume = size[0] * size[1] * size[2];
    assert!(
        (volume - exact_volume).abs() < 0.02 * exact_volume,
        "volume {volume} vs {exact_volume}"
    );
    let energy = sim.elastic_energy();
    // the exact elements give the empty part of the cut cells the stiffness share alpha
    let empty: f64 = sim
        .grid
        .cells
        .iter()
        .map(|c| h * h * h - c.integrals.volume.iter().sum::<f64>())
        .sum();
    let alpha = if element.exact() {
        FICTITIOUS_STIFFNESS
    } else {
        0.0
    };
    let expected = (volume + alpha * empty) * strain_energy_density(a, 3000.0, 0.35);
    assert!(
        (energy - expected).abs() < 1e-9 * expected,
        "{}: energy {energy} vs {expected}",
        element.name()
    );
}

/// A rigid rotation (30 degrees) produces no elastic force with corotation on, and a large
/// spurious force without it.
#[test]
fn rigid_rotation_has_no_elastic_force_with_corotation() {
    let angle: f64 = 30f64.to_radians();
    let (c, s) = (angle.cos(), angle.sin());
    let r = Mat3::from_rows([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]);
    let a = r - Mat3::identity();
    let mut with = box_sim(
        [0.0, 1.0, 0.0],
        [0.6, 0.4, 0.3],
        0.05,
        Model {
            corotation: true,
            ..Model::default()
        },
    );
    with.u = linear_field(&with, a);
    let f = with.elastic_force();
    let mut without = box_sim(
        [0.0, 1.0, 0.0],
        [0.6, 0.4, 0.3],
        0.05,
        Model {
            corotation: false,
            ..Model::default()
        },
    );
    without.u = linear_field(&without, a);
    let g = without.elastic_force();
    let fmax = f.ex().cwise_squared_norm().max().sqrt();
    let gmax = g.ex().cwise_squared_norm().max().sqrt();
    assert!(
        gmax > 1.0,
        "linear elasticity should see a large spurious force, got {gmax}"
    );
    assert!(fmax < 1e-9 * gmax, "corotated force {fmax} (linear: {gmax})");
}

#[test]
fn deformation_gradient_of_linear_field_and_polar_rotation() {
    let h = 0.1;
    let a = Mat3::from_rows([[0.1, 0.2, -0.05], [0.0, -0.1, 0.3], [0.02, 0.04, 0.05]]);
    let corners: [Vec3<f64>; 8] = std::array::from_fn(|c| {
        a * Vec3::new(
            (c & 1) as f64 * h,
            ((c >> 1) & 1) as f64 * h,
            ((c >> 2) & 1) as f64 * h,
        )
    });
    let f = deformation_gradient(&corners, h);
    let expect = Mat3::identity() + a;
    for p in 0..3 {
        for q in 0..3 {
            assert!((f.m[p][q] - expect.m[p][q]).abs() < 1e-12);
        }
    }
    // R is orthonormal with det 1 and R^T F symmetric (polar decomposition)
    let r = polar_rotation(f, 20);
    let rtr = r.transpose() * r;
    let s = r.transpose() * f;
    for p in 0..3 {
        for q in 0..3 {
            let id = if p == q { 1.0 } else { 0.0 };
            assert!((rtr.m[p][q] - id).abs() < 1e-10, "R^T R not identity");
            assert!((s.m[p][q] - s.m[q][p]).abs() < 1e-10, "R^T F not symmetric");
        }
    }
    assert!((r.determinant() - 1.0).abs() < 1e-10);
}

/// The element matrix of every element, on a full and on cut cells, is symmetric, has the 6
/// rigid modes in its null space, and is positive on the rest; the thesis' element is
/// [`StiffnessTables::block`] of the corner weights.
#[test]
fn element_matrices_are_symmetric_with_six_rigid_modes() {
    let h = 0.1;
    let (lambda, mu) = lame(1000.0, 0.3);
    let cells = [
        CellIntegrals::full(h),
        cell_integrals(&[-0.05, 0.02, -0.01, 0.04, -0.03, 0.01, 0.03, 0.06], h),
        cell_integrals(&[-0.004, 0.05, 0.05, 0.09, 0.05, 0.09, 0.09, 0.12], h),
    ];
    let t = StiffnessTables::new(h);
    for element in Element::ALL {
        for (n, ci) in cells.iter().enumerate() {
            let set = ElementSet::of_cell(ci, h, element, lambda, mu);
            let mut k = faer::Mat::<f64>::zeros(24, 24);
            for i in 0..8 {
                for j in 0..8 {
                    let b = set.k[i][j];
                    if element == Element::Trilinear {
                        let d = b - t.block(&ci.volume, i, j, lambda, mu);
                        assert!(
                            d.m.iter().flatten().all(|x| x.abs() < 1e-9 * lambda * h),
                            "thesis block"
                        );
                    }
                    for p in 0..3 {
                        for q in 0..3 {
                            k[(3 * i + p, 3 * j + q)] = b.m[p][q];
                        }
                    }
                }
            }
            let what = format!("{} cell {n}", element.name());
            let scale = (0..24).map(|i| k[(i, i)]).fold(0.0f64, f64::max);
            for i in 0..24 {
                for j in 0..24 {
                    assert!(
                        (k[(i, j)] - k[(j, i)]).abs() < 1e-12 * scale,
                        "{what}: not symmetric"
                    );
                }
            }
            let eig = k.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
            let zeros = eig.iter().filter(|&&e| e.abs() < 1e-9 * scale).count();
            assert!(eig.iter().all(|&e| e > -1e-9 * scale), "{what}: {eig:?}");
            // a full cell has exactly the rigid modes; a cut one at least them
            if n == 0 {
                assert_eq!(zeros, 6, "{what}: eigenvalues {eig:?}");
            } else {
                assert!(zeros >= 6, "{what}: eigenvalues {eig:?}");
            }
        }
    }
}

/// Cut cells with bit-identical integrals share one stored block set (the cuboid's flat
/// faces cut many cells alike), and every cell's blocks are exactly those of its own integrals.
#[test]
fn element_blocks_share_sets_of_cells_cut_alike() {
    use cutfem::fem::assembly::Material;
    use cutfem::fem::Simulation;
    let shape = cutfem::shapes::Shape::Box {
        center: [0.0, 1.0, 0.0],
        size: [1.29, 0.4, 0.8],
    };
    let grid = cutfem::fem::Grid::new(shape.to_sdf(16.0, 2).unwrap()).unwrap();
    let sim = Simulation::new(grid, Model::default()).unwrap();
    let (lambda, mu) = sim.model.lame();
    let (eta, eta_per_modulus) = sim.model.nitsche.terms(sim.grid.h());
    for element in Element::ALL {
        let m = Material {
            lambda,
            mu,
            eta,
            eta_per_modulus,
            element,
            support: None,
        };
        let blocks = sim.assembler.element_blocks(&sim.grid, &m);
        let cut = sim.grid.cut_cells();
        assert!(
            blocks.cut_sets() > 0 && 2 * blocks.cut_sets() < cut,
            "{} sets for {cut} cut cells",
            blocks.cut_sets()
        );
        let h = sim.grid.h();
        for (e, c) in sim.grid.cells.iter().enumerate() {
            let ci = if c.is_full() {
                CellIntegrals::full(h)
            } else {
                c.integrals
            };
            let want = ElementSet::of_cell(&ci, h, element, lambda, mu);
            assert_eq!(blocks.cell(e), &want.k, "{} cell {e}", element.name());
        }
    }
}
