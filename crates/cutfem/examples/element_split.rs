//! Where the cantilever's error comes from (`docs/simulation.md`, "Element"): the static tip
//! deflection of the beam of `tests/fem_cantilever.rs` (L = 2, 0.2 x 0.2, E = 1e5, nu = 0.3,
//! under gravity, clamped at x = 0 by Nitsche) for every element, with the faces on grid lines
//! and shifted off them (cut cells), and with the Nitsche box one or two cell columns wide;
//! then the model's geometry of the beam (volume, second moment of area, and how much of the
//! end face the clamp box `x <= 0` holds: the box's exact distance at the refined cells'
//! sub-nodes keeps its edges to a sub-cell; the spline of the node samples rounded them, and
//! the face receded from the box near them).
//!
//! `cargo run --release -p cutfem --example element_split [h ...]`

use cutfem::fem::element::Element;
use cutfem::fem::{Aabb, Grid, Model, NitscheQuadrature, Simulation};
use cutfem::shapes::Shape;
use gpumat::Vec3;

const L: f64 = 2.0;
const T: f64 = 0.2;
const E: f64 = 1.0e5;

/// The beam (a [`Shape::Box`]) on a grid of spacing `h`, nodes on multiples of `h`.
fn grid(center: [f64; 3], size: [f64; 3], h: f64) -> Grid {
    let sdf = Shape::Box { center, size }.to_sdf(1.0 / h, 2).expect("box sdf");
    Grid::new(sdf).expect("grid")
}

/// Tip deflection relative to Euler-Bernoulli of the free length: the material in
/// `x <= clamp_cells h` is held (`0`: the end face alone).
fn run(h: f64, element: Element, shift: f64, clamp_cells: f64, nu: f64) -> f64 {
    let model = Model {
        young: E,
        poisson: nu,
        density: 1.0,
        gravity: Vec3::new(0.0, -10.0, 0.0),
        corotation: false,
        element,
        nitsche_quadrature: NitscheQuadrature::Consistent,
        nitsche: NitscheQuadrature::Consistent.default_penalty(),
        dirichlet: vec![Aabb {
            min: [-1.0, -1.0, -1.0],
            max: [clamp_cells * h, 1.0, 1.0],
        }],
        ..Model::default()
    };
    // the beam from x = 0 to L; its sides shifted by `shift` cells off the grid lines
    let s = shift * h;
    let center = [0.5 * L, s, s];
    let mut sim = Simulation::new(grid(center, [L, T, T], h), model).expect("sim");
    sim.solver.direct = true;
    if let Err(e) = sim.solve_static() {
        eprintln!("{} h = {h}: {e}", element.name());
        return f64::NAN;
    }
    let (mut sum, mut n) = (0.0, 0);
    for (d, p) in sim.grid.positions.iter().enumerate() {
        if (p.x - L).abs() < 1e-9 && (p.y - s).abs() <= 0.5 * T + 1e-9 && (p.z - s).abs() <= 0.5 * T + 1e-9 {
            sum += sim.u.get(d, 0, 0).y;
            n += 1;
        }
    }
    let q = 10.0 * T * T;
    let free = L - clamp_cells * h;
    let exact = q * free.powi(4) / (8.0 * E * (T.powi(4) / 12.0));
    -sum / n as f64 / exact - 1.0
}

fn main() {
    let hs: Vec<f64> = std::env::args().skip(1).map(|a| a.parse().expect("h")).collect();
    let hs = if hs.is_empty() { vec![0.05, 0.025] } else { hs };
    println!("| h | element | faces on grid lines, end face held | held to x = h (free length L - h) | faces shifted 0.37 h (cut cells), end face held | the same, nu = 0.49 |");
    println!("|---|---|---|---|---|---|");
    for &h in &hs {
        for el in Element::ALL {
            let a = run(h, el, 0.0, 0.0, 0.3);
            let b = run(h, el, 0.0, 1.0, 0.3);
            let c = run(h, el, 0.37, 0.0, 0.3);
            let d = run(h, el, 0.37, 0.0, 0.49);
            println!(
                "| {h} | {} | {:+.2}% | {:+.2}% | {:+.2}% | {:+.2}% |",
                el.name(),
                100.0 * a,
                100.0 * b,
                100.0 * c,
                100.0 * d
            );
        }
    }
    println!();
    println!("| h | faces shifted | volume | I | end face held by the box x <= 0 |");
    println!("|---|---|---|---|---|");
    for &h in &hs {
        geometry(h, 0.0);
        geometry(h, 0.37);
    }
}

/// The model's geometry of the beam: volume, second moment of area `I_y` of the cut cells
/// (from their moments), and the share of the end face x = 0 that the clamp box `x <= 0`
/// holds (the clipped Nitsche surface).
fn geometry(h: f64, shift: f64) {
    let s = shift * h;
    let g = grid([0.5 * L, s, s], [L, T, T], h);
    let (mut vol, mut iy) = (0.0, 0.0);
    for c in &g.cells {
        let o = g.cell_origin(c).to_array();
        let m = &c.integrals.moments;
        let h3 = h * h * h;
        vol += m[0] * h3;
        // int (y - s)^2 = h3 * int (o_y + h eta - s)^2
        let a = o[1] - s;
        iy += h3 * (a * a * m[0] + 2.0 * a * h * m[3] + h * h * m[6]);
    }
    let model = Model {
        dirichlet: vec![Aabb {
            min: [-1.0, -1.0, -1.0],
            max: [0.0, 1.0, 1.0],
        }],
        ..Model::default()
    };
    let faces = cutfem::fem::sim::dirichlet_cells(&g, &model).expect("held surface");
    let held: f64 = faces
        .iter()
        .flatten()
        .map(|f| f.boundary.iter().sum::<f64>())
        .sum();
    println!(
        "| {h} | {shift} h | {:+.2}% | {:+.2}% | {:.1}% |",
        100.0 * (vol / (L * T * T) - 1.0),
        100.0 * (iy / (L * T.powi(4) / 12.0) - 1.0),
        100.0 * held / (T * T)
    );
}
