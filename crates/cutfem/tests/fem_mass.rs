//! The consistent mass matrix (`[numerics] mass`, `cutfem::fem::assembly::mass`): the full
//! cell's closed form, row sums equal to the lumped masses on cut cells, exact inertia of
//! linear fields (the moments of a body), and the rotational inertia of a thin bar that the
//! lumped mass overestimates by `2 h^2 / a^2`.

use cutfem::cutcell::{cell_integrals, CellIntegrals};
use cutfem::fem::assembly::mass::cell_mass;
use cutfem::fem::{Grid, MassMatrix, Model, Simulation};
use cutfem::shapes::Shape;
use gpumat::Vec3;

/// `int N_i N_j` of a full cell: `h^3 prod_k (1/3 or 1/6)` by whether corners `i`, `j` agree
/// along axis `k`.
#[test]
fn full_cell_is_the_tensor_product_of_the_1d_mass() {
    let h = 0.3;
    let m = cell_mass(&CellIntegrals::full(h), h);
    for (i, row) in m.iter().enumerate() {
        for (j, &mij) in row.iter().enumerate() {
            let want: f64 = (0..3)
                .map(|k| {
                    if (i >> k) & 1 == (j >> k) & 1 {
                        1.0 / 3.0
                    } else {
                        1.0 / 6.0
                    }
                })
                .product::<f64>()
                * h.powi(3);
            assert!((mij - want).abs() < 1e-15, "({i}, {j}): {mij} vs {want}");
        }
    }
}

/// On cut cells (planar and curved cuts) the rows sum to the lumped masses `int N_i`, the
/// matrix is symmetric and positive semi-definite on the corners, and a planar slab's
/// `x^T M x` for the linear field `x = xi` is its exact `int xi^2`.
#[test]
fn cut_cells_sum_to_the_lumped_mass_and_integrate_linear_fields_exactly() {
    let h = 0.2;
    let cuts: Vec<[f64; 8]> = vec![
        std::array::from_fn(|c| ((c & 1) as f64 - 0.37) * h),
        std::array::from_fn(|c| ((c & 1) + ((c >> 1) & 1) + ((c >> 2) & 1)) as f64 * h - 1.3 * h),
        std::array::from_fn(|c| {
            let p = [(c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64];
            (((p[0] - 0.9).powi(2) + (p[1] - 0.2).powi(2) + (p[2] - 0.6).powi(2)).sqrt() - 0.8) * h
        }),
    ];
    for (n, phi) in cuts.iter().enumerate() {
        let ci = cell_integrals(phi, h);
        let m = cell_mass(&ci, h);
        for i in 0..8 {
            let row: f64 = m[i].iter().sum();
            assert!(
                (row - ci.volume[i]).abs() < 1e-15,
                "cut {n} row {i}: {row} vs {}",
                ci.volume[i]
            );
            for j in 0..8 {
                assert_eq!(m[i][j], m[j][i]);
            }
        }
        // x^T M x >= 0 for a few fields, and = int (field)^2 for the linear field xi (corner
        // values 0 / h): int (h xi)^2 over the inside part = h^2 h^3 m_200
        let quad = |x: &[f64; 8]| {
            (0..8)
                .map(|i| (0..8).map(|j| x[i] * m[i][j] * x[j]).sum::<f64>())
                .sum::<f64>()
        };
        for s in 0..20u64 {
            let x: [f64; 8] =
                std::array::from_fn(|i| (((s * 8 + i as u64) * 2_654_435_761) % 1000) as f64 / 500.0 - 1.0);
            assert!(quad(&x) >= -1e-18, "cut {n}: not positive semi-definite");
        }
        let xi: [f64; 8] = std::array::from_fn(|c| (c & 1) as f64 * h);
        let want = h.powi(5) * ci.moments[cutfem::cutcell::moment_index(2, 0, 0)];
        assert!(
            (quad(&xi) - want).abs() < 1e-15 * want.max(1e-30) + 1e-20,
            "cut {n}: {} vs {want}",
            quad(&xi)
        );
    }
    // the planar slab x < 0.37 h: int xi^2 = 0.37^3 / 3 exactly
    let slab = cell_integrals(&cuts[0], h);
    assert!((slab.moments[cutfem::cutcell::moment_index(2, 0, 0)] - 0.37f64.powi(3) / 3.0).abs() < 1e-15);
}

/// The bar of the independent `twist` case (1.05 x 0.22 x 0.22, faces off the grid lines)
/// spinning about its axis at resolutions 20 and 30 (4.4 and 6.6 cells across): the consistent
/// mass' kinetic energy is `1/2 I w^2` with the polar moment of inertia `I` of the grid's own
/// body (its cut cells' exact moments) to rounding, the lumped mass' is about `2 h^2 / a^2`
/// (10%, 4.6%) larger; both carry the same total mass, the body's volume. (The grid's body is
/// the box up to a sub-cell chamfer of its edges: its volume is 0.04% below the box's at
/// resolution 20.)
#[test]
fn spinning_bar_has_the_exact_rotational_inertia_with_the_consistent_mass() {
    use cutfem::cutcell::moment_index;
    let (a, len) = (0.22, 1.05);
    let shape = Shape::Box {
        center: [0.525, 1.0, 0.0],
        size: [len, a, a],
    };
    let w = 10.0;
    let sim = |mass: MassMatrix, res: f64| {
        let grid = Grid::new(shape.to_sdf(res, 2).unwrap()).unwrap();
        let model = Model {
            mass,
            gravity: Vec3::new(0.0, 0.0, 0.0),
            initial_angular_velocity: Vec3::new(w, 0.0, 0.0),
            ..Model::default()
        };
        Simulation::new(grid, model).unwrap()
    };
    for res in [20.0, 30.0] {
        let (c, l) = (sim(MassMatrix::Consistent, res), sim(MassMatrix::Lumped, res));
        let h = c.grid.h();
        let center = c.center_of_mass();
        // on the axis to a small fraction of a cell: the sub-cells' Kuhn tetrahedra are not
        // mirror symmetric, so the edges' sub-cell chamfers differ slightly from side to side
        assert!(
            (center.y - 1.0).abs() < 1e-3 * h && center.z.abs() < 1e-3 * h,
            "center {center:?}"
        );
        // int ((y - cy)^2 + (z - cz)^2) over the grid's body, from each cell's moments
        let (mut volume, mut polar) = (0.0, 0.0);
        for cell in &c.grid.cells {
            let o = c.grid.positions[cell.dofs[0] as usize];
            let m = &cell.integrals.moments;
            let h3 = h * h * h;
            let second = |d: f64, k: [usize; 3], k2: [usize; 3]| {
                h3 * (d * d * m[0]
                    + 2.0 * d * h * m[moment_index(k[0], k[1], k[2])]
                    + h * h * m[moment_index(k2[0], k2[1], k2[2])])
            };
            volume += h3 * m[0];
            polar +=
                second(o.y - center.y, [0, 1, 0], [0, 2, 0]) + second(o.z - center.z, [0, 0, 1], [0, 0, 2]);
        }
        assert!(
            (c.total_mass() - volume).abs() < 1e-12,
            "mass {} vs {volume}",
            c.total_mass()
        );
        assert_eq!(c.total_mass(), l.total_mass(), "the same total mass");
        let exact = 0.5 * w * w * polar;
        let (rc, rl) = (c.kinetic_energy() / exact - 1.0, l.kinetic_energy() / exact - 1.0);
        let lumped_bias = 2.0 * h * h / (a * a);
        println!("res {res}: consistent {rc:+.2e}, lumped {rl:+.4} (2 h^2 / a^2 = {lumped_bias:.4}); volume {volume:.5} vs the box's {:.5}", len * a * a);
        assert!(rc.abs() < 1e-12, "res {res}: consistent {rc:+.3e}");
        assert!(
            (rl - lumped_bias).abs() < 0.3 * lumped_bias,
            "res {res}: lumped {rl:+.4} vs {lumped_bias:+.4}"
        );
    }
}
