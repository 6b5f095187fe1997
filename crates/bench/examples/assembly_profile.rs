//! The grid assembly's cost inside a realistic step of Table B.5's cuboid (held at one end,
//! corotation on): each step followed by the level-set diffusion and advection, as in the
//! `tables` binary, so that the assembly finds the caches as the CG solve and the advection
//! left them. Prints per step the assembly (`StepInfo::assembly_s`), its cell and row sweeps
//! (`StepInfo::stiffness_s`), the step with the advection and the assembly's share, then the
//! time of `Simulation::assemble_system` (which also keeps `K`) repeated back to back.
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
    let (mut asm, mut sweeps, mut wall) = (0.0, 0.0, 0.0);
    for _ in 0..steps {
        let t = Instant::now();
        let info = sim.step().expect("step");
        let u_band = band.diffuse(&sim.u).expect("diffuse");
        let _ = advect(&sim.grid, &band, &u_band).expect("advect");
        wall += t.elapsed().as_secs_f64();
        asm += info.assembly_s;
        sweeps += info.stiffness_s;
    }
    let (mut again, mut again_sweeps) = (0.0, 0.0);
    for _ in 0..steps {
        let info = sim.assemble_system();
        again += info.assembly_s;
        again_sweeps += info.stiffness_s;
    }
    let ms = |s: f64| s / steps as f64 * 1e3;
    println!(
        "r={r} nodes={} blocks={} | in steps: asm {:.3} ms (sweeps {:.3} ms, last pass {:.3} ms) \
         step {:.2} ms asm/step {:.2}% | assemble_system back to back {:.3} ms (sweeps {:.3} ms)",
        sim.grid.dofs(),
        sim.assembler.pattern().nnz(),
        ms(asm),
        ms(sweeps),
        ms(asm - sweeps),
        ms(wall),
        100.0 * asm / wall,
        ms(again),
        ms(again_sweeps)
    );
}
