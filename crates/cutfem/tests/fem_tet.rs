//! The tetrahedral baseline (thesis sec. 4.6): mesh counts against Table 4.1, the linear
//! tetrahedron's patch test and exact strain energy, rigid rotations under corotation, hard
//! Dirichlet nodes, and the grid-versus-tetrahedra comparison of a clamped bar under gravity
//! (dynamic trajectory and static deflection), plus the assembly timing ratio.

mod fem_common;
use fem_common::*;

use cutfem::fem::collision::ContactScheme;
use cutfem::fem::element::lame;
use cutfem::fem::tet::{TetMesh, TetSimulation, KUHN};
use cutfem::fem::{Aabb, Ground, Model, Simulation};
use gpumat::{Mat3, Matrix, Vec3};

const CUBOID_CENTER: [f64; 3] = [0.0, 1.0, 0.0];
const CUBOID_SIZE: [f64; 3] = [1.29, 0.4, 0.8];

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

fn free_field(sim: &TetSimulation, f: impl Fn(Vec3<f64>) -> Vec3<f64>) -> Matrix<Vec3<f64>> {
    Matrix::from_fn(sim.mesh.dofs(), 1, 1, |d, _, _| {
        f(sim.mesh.positions[sim.mesh.free_nodes[d] as usize])
    })
}

/// The Kuhn tetrahedra tile the unit cube with positive orientation.
#[test]
fn kuhn_tetrahedra_tile_the_cell() {
    let corner = |c: usize| Vec3::new((c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64);
    let mut total = 0.0;
    for t in &KUHN {
        let (v, _) = cutfem::fem::tet::element_geometry(&t.map(corner));
        assert!((v - 1.0 / 6.0).abs() < 1e-15, "volume {v} of {t:?}");
        total += v;
    }
    assert!((total - 1.0).abs() < 1e-14);
}

/// Element and node counts of the thesis' cuboid against Table 4.1 ("resolution r" = cell
/// size 1/(2r)). The thesis' tet meshes are structured meshes of the cuboid; the centroid rule
/// on the SDF grid keeps within a few percent of their element count (at resolution 10, where
/// the faces lie on or a tenth of a cell from grid lines, all but the 52 tetrahedra along the
/// end faces' edges). The grid's own counts are printed for the record.
#[test]
fn cuboid_counts_match_table_4_1() {
    // Table 4.1: resolution, tet elements, tet free + fixed nodes, grid elements, grid nodes
    let table: [(usize, usize, usize, usize, usize); 16] = [
        (5, 2496, 630, 448, 675),
        (6, 4500, 1056, 960, 1309),
        (7, 7128, 1596, 1296, 1729),
        (8, 9828, 2156, 2464, 3105),
        (9, 13524, 2880, 3072, 3825),
        (10, 19968, 4131, 3328, 4131),
        (11, 27216, 5510, 5400, 6479),
        (12, 35340, 7040, 6400, 7623),
        (13, 42840, 8470, 8976, 10465),
        (14, 52272, 10212, 10368, 12025),
        (15, 67392, 13000, 11520, 13325),
        (16, 83148, 15876, 15288, 17415),
        (17, 99792, 18900, 17248, 19575),
        (18, 112056, 21150, 23040, 25823),
        (19, 132300, 24800, 25600, 28611),
        (20, 159744, 29733, 26624, 29733),
    ];
    for &(r, tets, nodes, cells, grid_nodes) in &table {
        let h = 1.0 / (2.0 * r as f64);
        let grid = box_grid(CUBOID_CENTER, CUBOID_SIZE, h);
        let mesh = TetMesh::from_grid(&grid, &Model::default()).expect("mesh");
        eprintln!(
            "resolution {r:2}: tets {:6} (thesis {tets:6}), tet nodes {:5} (thesis {nodes:5}), grid cells {:5} (thesis {cells:5}), grid nodes {:5} (thesis {grid_nodes:5}), volume {:.5}",
            mesh.tets.len(),
            mesh.nodes(),
            grid.cells.len(),
            grid.dofs(),
            mesh.volume()
        );
        let _ = (cells, grid_nodes);
        // the centroid rule keeps a cell's 6 tetrahedra or a subset, and no node outside them
        assert!(mesh.tets.len() <= 6 * grid.cells.len());
        assert!(mesh.nodes() <= grid.dofs());
        let rel = |a: usize, b: usize| (a as f64 - b as f64).abs() / b as f64;
        assert!(
            rel(mesh.tets.len(), tets) < 0.1,
            "tets {} vs thesis {tets}",
            mesh.tets.len()
        );
        assert!(
            rel(mesh.nodes(), nodes) < 0.15,
            "nodes {} vs thesis {nodes}",
            mesh.nodes()
        );
        if r == 10 {
            // y and z faces on grid lines, the end faces a tenth of a cell inside the end
            // cells: everything is kept except, in the end cells along the end faces' edges,
            // the tetrahedra whose centroid the trilinear interpolation puts outside
            assert_eq!(mesh.tets.len(), 19968 - 52);
            assert_eq!(mesh.nodes(), 4131 - 6);
        }
        assert!(mesh
            .volumes
            .iter()
            .all(|&v| (v - h * h * h / 6.0).abs() < 1e-12 * h * h * h));
    }
}

/// Patch test: a linear displacement gives zero force at every interior node and the forces
/// sum to zero; the strain energy is exactly `volume * W(eps)`.
#[test]
fn patch_test_and_exact_strain_energy() {
    let model = Model {
        corotation: false,
        young: 3000.0,
        poisson: 0.35,
        ..Model::default()
    };
    let grid = box_grid([0.013, 0.977, -0.021], [0.93, 0.41, 0.57], 0.05);
    let mut sim = TetSimulation::from_grid(&grid, model).expect("sim");
    let a = Mat3::from_rows([[0.01, 0.002, -0.003], [0.004, -0.02, 0.001], [0.0, 0.005, 0.015]]);
    sim.u = free_field(&sim, |x| a * x);
    let f = sim.elastic_force();
    let scale = 3000.0 * 0.05 * 0.05 * 0.02; // E h^2 |strain|: a typical nodal force
    let mut interior = 0;
    for d in 0..sim.mesh.dofs() {
        if !sim.mesh.surface[sim.mesh.free_nodes[d] as usize] {
            interior += 1;
            let r = f.get(d, 0, 0).norm();
            assert!(r < 1e-10 * scale, "node {d}: residual force {r}");
        }
    }
    assert!(interior > 100, "only {interior} interior nodes");
    assert!(f.ex().sum().norm() < 1e-9 * scale, "forces do not sum to zero");
    let energy = sim.elastic_energy();
    let expected = sim.mesh.volume() * strain_energy_density(a, 3000.0, 0.35);
    assert!(
        (energy - expected).abs() < 1e-10 * expected,
        "energy {energy} vs {expected}"
    );
}

/// A rigid rotation (30 degrees about a skew axis) produces no elastic force with corotation,
/// and a large spurious one without.
#[test]
fn rigid_rotation_has_no_elastic_force_with_corotation() {
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let rz = Mat3::from_rows([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]);
    let rx = Mat3::from_rows([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]);
    let r = rz * rx;
    let grid = box_grid(CUBOID_CENTER, CUBOID_SIZE, 0.1);
    let scale = 2000.0 * 0.1 * 0.1 * 0.5; // E h^2 |R - I|
    for corotation in [true, false] {
        let mut sim = TetSimulation::from_grid(
            &grid,
            Model {
                corotation,
                ..Model::default()
            },
        )
        .expect("sim");
        sim.u = free_field(&sim, |x| r * x - x);
        let f = sim.elastic_force();
        let worst = f.as_slice().iter().map(|v| v.norm()).fold(0.0, f64::max);
        eprintln!("corotation {corotation}: largest elastic force {worst:.3e} (scale {scale:.1})");
        if corotation {
            assert!(worst < 1e-9 * scale, "corotated rigid rotation: force {worst}");
        } else {
            assert!(
                worst > 0.01 * scale,
                "linear rigid rotation should be strained: {worst}"
            );
        }
    }
}

/// Hard Dirichlet: the nodes in the box are removed from the system and stay at zero; a box
/// holding no node is an error.
#[test]
fn dirichlet_nodes_are_fixed() {
    let h = 0.05;
    let grid = box_grid([0.5, 0.0, 0.0], [1.0, 0.2, 0.2], h);
    let model = Model {
        gravity: Vec3::new(0.0, -9.81, 0.0),
        dirichlet: vec![Aabb {
            min: [-1.0, -1.0, -1.0],
            max: [0.01 * h, 1.0, 1.0],
        }],
        ..Model::default()
    };
    let mut sim = TetSimulation::from_grid(&grid, model.clone()).expect("sim");
    assert_eq!(sim.mesh.fixed_nodes(), 25, "the 5x5 nodes of the end face x = 0");
    assert_eq!(sim.mesh.dofs() + 25, sim.mesh.nodes());
    for _ in 0..5 {
        sim.step().expect("step");
    }
    let u = sim.node_displacements();
    for (n, p) in sim.mesh.positions.iter().enumerate() {
        if p.x <= 0.0 {
            assert_eq!(u[n], Vec3::default());
        }
    }
    assert!(sim.max_displacement() > 0.0);
    let bad = Model {
        dirichlet: vec![Aabb {
            min: [5.0, 5.0, 5.0],
            max: [6.0, 6.0, 6.0],
        }],
        ..model
    };
    let err = TetMesh::from_grid(&grid, &bad).unwrap_err().to_string();
    assert!(err.starts_with("dirichlet[0]"), "{err}");
}

/// Mean displacement of the nodes on the plane `x = x_end` (the same nodes in both meshes).
fn tip(positions: &[Vec3<f64>], u: &[Vec3<f64>], x_end: f64) -> Vec3<f64> {
    let mut s = Vec3::default();
    let mut n = 0;
    for (p, d) in positions.iter().zip(u) {
        if (p.x - x_end).abs() < 1e-9 {
            s = s + *d;
            n += 1;
        }
    }
    assert!(n > 0);
    s * (1.0 / n as f64)
}

/// The clamped bar under gravity. The Dirichlet box reaches to `x_min + 1.001 h`, where `x_min`
/// is the smallest node coordinate: for the grid Nitsche acts on the surface inside it, the end
/// face and the lateral band up to `x_min + 1.001 h`; for the tetrahedra it fixes the two node
/// planes `x_min` and `x_min + h`. (A box to `x_min + 1.01 h` also holds a band 0.01 h wide in
/// the second layer of cells, which the penalty of 1e8 turns into a clamp of much of that
/// layer: the static tip then differs by 2% instead of 0.3%.)
/// Both thus clamp the same slab of material. (Fixing only the end plane makes the tet bar
/// about 20% softer.)
fn clamped(x_min: f64, h: f64, young: f64) -> Model {
    Model {
        young,
        poisson: 0.3,
        density: 1.0,
        gravity: Vec3::new(0.0, -9.81, 0.0),
        corotation: true,
        damping_mass: 0.2,
        damping_stiffness: 0.001,
        dirichlet: vec![Aabb {
            min: [-5.0, -5.0, -5.0],
            max: [x_min + 1.001 * h, 5.0, 5.0],
        }],
        dt: 0.01,
        theta: 0.6,
        // the thesis' comparison (sec. 4.6) is of its own grid element and nodal clamp (its
        // penalty 1e8 pins the slab, as the tetrahedra's fixed nodes do) with the tetrahedra
        element: cutfem::fem::element::Element::Trilinear,
        nitsche_quadrature: cutfem::fem::NitscheQuadrature::Thesis,
        nitsche: cutfem::fem::NitscheQuadrature::Thesis.default_penalty(),
        ..Model::default()
    }
}

struct Comparison {
    /// tip y per step, grid and tet
    grid: Vec<f64>,
    tet: Vec<f64>,
    /// static (linear) tip y, grid and tet
    grid_static: f64,
    tet_static: f64,
}

impl Comparison {
    fn run(center: [f64; 3], size: [f64; 3], h: f64, young: f64, steps: usize) -> Self {
        let grid = box_grid(center, size, h);
        let x_min = grid.positions.iter().map(|p| p.x).fold(f64::MAX, f64::min);
        let x_end = grid.positions.iter().map(|p| p.x).fold(f64::MIN, f64::max);
        let model = clamped(x_min, h, young);
        let mut tsim = TetSimulation::from_grid(&grid, model.clone()).expect("tet sim");
        let mut gsim = Simulation::new(grid, model).expect("grid sim");
        let (mut yg, mut yt) = (Vec::new(), Vec::new());
        for _ in 0..steps {
            let gi = gsim.step().expect("grid step");
            let ti = tsim.step().expect("tet step");
            assert!(!gi.fallback && !ti.fallback);
            yg.push(tip(&gsim.grid.positions, gsim.u.as_slice(), x_end).y);
            yt.push(tip(&tsim.mesh.positions, &tsim.node_displacements(), x_end).y);
        }
        gsim.solver.direct = true;
        tsim.solver.direct = true;
        gsim.solve_static().expect("grid static");
        tsim.solve_static().expect("tet static");
        let grid_static = tip(&gsim.grid.positions, gsim.u.as_slice(), x_end).y;
        let tet_static = tip(&tsim.mesh.positions, &tsim.node_displacements(), x_end).y;
        Self {
            grid: yg,
            tet: yt,
            grid_static,
            tet_static,
        }
    }

    /// Largest trajectory difference relative to the largest grid tip displacement.
    fn trajectory_error(&self) -> f64 {
        let max = self.grid.iter().map(|y| y.abs()).fold(0.0, f64::max);
        self.grid
            .iter()
            .zip(&self.tet)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
            / max
    }

    fn static_error(&self) -> f64 {
        (self.tet_static - self.grid_static).abs() / self.grid_static.abs()
    }

    fn print(&self, name: &str) {
        let max = self.grid.iter().map(|y| y.abs()).fold(0.0, f64::max);
        eprintln!(
            "{name}: max tip |u_y| {max:.5}, trajectory difference {:.2}%, static tip grid {:.6} tet {:.6} ({:+.2}%)",
            100.0 * self.trajectory_error(),
            self.grid_static,
            self.tet_static,
            100.0 * (self.tet_static - self.grid_static) / self.grid_static
        );
        for (s, (a, b)) in self
            .grid
            .iter()
            .zip(&self.tet)
            .enumerate()
            .filter(|(s, _)| s % 5 == 4)
        {
            eprintln!("  step {:2}: grid {a:+.6} tet {b:+.6}", s + 1);
        }
    }
}

/// The thesis' cuboid (sec. 4.6) at resolution 10 (cell size 1/20), clamped at one end,
/// swinging under gravity with corotation and Rayleigh damping for 30 steps: the tip
/// trajectories of the grid and the tetrahedra agree within 5% of the largest tip
/// displacement, and the linear static deflections within 1%.
#[test]
fn grid_and_tet_cuboid_agree() {
    let c = Comparison::run(CUBOID_CENTER, CUBOID_SIZE, 0.05, 2000.0, 30);
    c.print("cuboid h = 1/20");
    assert!(
        c.trajectory_error() < 0.05,
        "trajectory difference {}",
        c.trajectory_error()
    );
    assert!(c.static_error() < 0.01, "static difference {}", c.static_error());
}

/// A slender bar 1.0 x 0.2 x 0.2: the linear tetrahedra are stiffer in bending than the grid's
/// trilinear cells; at 4 cells across the tip deflections differ by about 3.1% (static) and
/// 6.5% (trajectory), at 8 cells across by about 2.6% and 4%: the two converge together.
/// (With the linear cut-cell integrals, which lose about 8% of the bar's volume at its edges at
/// 4 cells across, the differences were 6.7% / 9.4% and 3.5% / 5.2%; the refined integrals,
/// `cutcell::refined_cell_integrals`, lose 0.9%, so most of the coarse static difference was
/// that geometric error and the static difference now falls by a factor 0.82 rather than 0.5.)
#[test]
fn grid_and_tet_slender_bar_converge_together() {
    let coarse = Comparison::run([0.5, 0.0, 0.0], [1.0, 0.2, 0.2], 0.05, 2.0e4, 30);
    coarse.print("bar h = 1/20");
    let fine = Comparison::run([0.5, 0.0, 0.0], [1.0, 0.2, 0.2], 0.025, 2.0e4, 30);
    fine.print("bar h = 1/40");
    assert!(coarse.trajectory_error() < 0.15 && coarse.static_error() < 0.05);
    assert!(fine.trajectory_error() < 0.7 * coarse.trajectory_error());
    assert!(fine.static_error() < 0.9 * coarse.static_error() && fine.static_error() < 0.03);
}

/// Ground contact at the surface nodes: a cube dropped on the ground comes to rest on it,
/// penetrating less than half a cell, with the thesis' explicit contact (soft springs) and with
/// the implicit contact and springs 1000 times stiffer (the grid's test, fem_dynamics.rs).
#[test]
fn dropped_cube_rests_on_the_ground() {
    let h = 0.05;
    for (stiffness, scheme) in [(8.0, ContactScheme::Thesis), (1.0e4, ContactScheme::Implicit)] {
        let grid = box_grid([0.0, 0.35, 0.0], [0.4, 0.4, 0.4], h);
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
        let mut sim = TetSimulation::from_grid(&grid, model).expect("sim");
        let mut contacts = 0;
        for _ in 0..200 {
            contacts = sim.step().expect("step").contacts;
        }
        // (the soft spring already pushes at d > 0: a stiff one holds the cube just above)
        let u = sim.node_displacements();
        let lowest = sim
            .mesh
            .positions
            .iter()
            .zip(&u)
            .map(|(p, d)| p.y + d.y)
            .fold(f64::MAX, f64::min);
        let speed = sim.v.as_slice().iter().map(|v| v.norm()).fold(0.0, f64::max);
        eprintln!("{scheme:?} k = {stiffness}: lowest point {lowest:+.5}, max speed {speed:.2e}, contacts {contacts}");
        assert!(lowest > -0.5 * h, "penetration {lowest}");
        assert!(lowest < 0.5 * h, "the cube hovers at {lowest}");
        assert!(speed < 1e-2, "not at rest: {speed}");
    }
}
