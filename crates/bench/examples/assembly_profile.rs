//! The grid assembly's cost inside a realistic step of Table B.5's cuboid (held at one end,
//! corotation on), after `warm-up` steps, in three settings of `steps` calls each:
//!
//! - `step+adv`: each step followed by the level-set diffusion and advection, as in the `tables`
//!   binary, so that the assembly finds the caches and the thread pool as the CG solve and the
//!   advection left them;
//! - `step`: the steps alone;
//! - `b2b`: `Simulation::assemble_system` (which also keeps `K`) back to back, warm caches.
//!
//! Each line gives the assembly (`StepInfo::assembly_s`), its pass over cells and rows
//! (`StepInfo::stiffness_s`), the whole call and the assembly's share of it.
//!
//! ```sh
//! cargo run --release -p bench --example assembly_profile -- [r] [steps] [warm-up steps]
//! ```

use cutfem::fem::advect::{advect, Diffusion};
use cutfem::fem::{Grid, Simulation};
use cutfem::shapes::Shape;
use std::time::Instant;

fn main() {
    let mut args = std::env::args().skip(1);
    let r: f64 = args.next().map_or(10.0, |s| s.parse().expect("r"));
    let steps: usize = args.next().map_or(100, |s| s.parse().expect("steps"));
    let warm_up: usize = args.next().map_or(10, |s| s.parse().expect("warm-up steps"));
    let shape = Shape::Box {
        center: [0.0, 1.0, 0.0],
        size: [1.29, 0.4, 0.8],
    };
    let grid = Grid::new(shape.to_sdf(2.0 * r, 6).expect("sdf")).expect("grid");
    let band = Diffusion::new(&grid).expect("band");
    let model = bench::table_cuboid::cuboid_model(false);
    let mut sim = Simulation::new(grid, model).expect("sim");
    sim.solver.cg.tolerance = bench::table_cuboid::CG_TOLERANCE;
    for _ in 0..warm_up {
        sim.step().expect("step");
    }
    println!(
        "r={r} nodes={} cells={} blocks={}",
        sim.grid.dofs(),
        sim.grid.cells.len(),
        sim.assembler.pattern().nnz()
    );
    let ms = |s: f64| s / steps as f64 * 1e3;
    for mode in ["step+adv", "step", "b2b"] {
        let (mut asm, mut pass, mut wall) = (0.0, 0.0, 0.0);
        for _ in 0..steps {
            let t = Instant::now();
            let info = if mode == "b2b" {
                sim.assemble_system()
            } else {
                sim.step().expect("step")
            };
            if mode == "step+adv" {
                let u_band = band.diffuse(&sim.u).expect("diffuse");
                let _ = advect(&sim.grid, &band, &u_band).expect("advect");
            }
            wall += t.elapsed().as_secs_f64();
            asm += info.assembly_s;
            pass += info.stiffness_s;
        }
        println!(
            "{mode:9} asm {:.3} ms (pass {:.3} ms, rest {:.3} ms) | call {:.2} ms | asm/call {:.2}%",
            ms(asm),
            ms(pass),
            ms(asm - pass),
            ms(wall),
            100.0 * asm / wall
        );
    }
}
