//! scratch probe (to be removed)
use cutfem::fem::assembly::Material;
use cutfem::fem::tet::TetSimulation;
use cutfem::fem::{Aabb, Grid, Model, Simulation};
use cutfem::shapes::Shape;
use std::time::Instant;

fn best<F: FnMut()>(mut f: F) -> f64 {
    let mut b = f64::MAX;
    let flush = std::env::var("FLUSH").is_ok();
    let mut junk = vec![0u8; 64 << 20];
    for it in 0..30 {
        if flush {
            for x in junk.iter_mut().step_by(64) {
                *x = x.wrapping_add(it as u8);
            }
            std::hint::black_box(&junk);
        }
        let t = Instant::now();
        f();
        b = b.min(t.elapsed().as_secs_f64());
    }
    b * 1e3
}

fn main() {
    for r in [5.0, 10.0, 15.0] {
        let shape = Shape::Box {
            center: [0.0, 1.0, 0.0],
            size: [1.29, 0.4, 0.8],
        };
        let grid = Grid::new(shape.to_sdf(2.0 * r, 6).unwrap()).unwrap();
        let model = Model {
            young: 2000.0,
            poisson: 0.3,
            damping_mass: 0.1,
            damping_stiffness: 0.01,
            gravity: gpumat::Vec3::new(0.0, -10.0, 0.0),
            corotation: true,
            dirichlet: vec![Aabb {
                min: [-0.9, 0.6, -0.6],
                max: [-0.55, 1.4, 0.6],
            }],
            dt: 0.01,
            theta: 0.6,
            ..Model::default()
        };
        let mut tet = TetSimulation::from_grid(&grid, model.clone()).unwrap();
        let mut sim = Simulation::new(grid.clone(), model.clone()).unwrap();
        for _ in 0..3 {
            sim.step().unwrap();
            tet.step().unwrap();
        }
        let (lambda, mu) = model.lame();
        let m = Material {
            lambda,
            mu,
            eta: model.nitsche_eta,
        };
        let asm = &sim.assembler;
        let t_blocks = best(|| {
            std::hint::black_box(asm.element_blocks(&sim.grid, &m));
        });
        let blocks = asm.element_blocks(&sim.grid, &m);
        let t_rot = best(|| {
            std::hint::black_box(asm.rotations(&sim.grid, &sim.u, 5));
        });
        let rot = asm.rotations(&sim.grid, &sim.u, 5);
        let dir = cutfem::fem::sim::dirichlet_cells(&sim.grid, &model).unwrap();
        let mut k = sim.stiffness().clone();
        let t_k = best(|| asm.assemble_stiffness(&sim.grid, &m, &blocks, Some(&rot), &dir, None, &mut k));
        let nodir = vec![false; dir.len()];
        let t_k_nodir =
            best(|| asm.assemble_stiffness(&sim.grid, &m, &blocks, Some(&rot), &nodir, None, &mut k));
        let ta = &tet.assembler;
        let t_trot = best(|| {
            std::hint::black_box(ta.rotations(&tet.mesh, &tet.u, 5));
        });
        let trot = ta.rotations(&tet.mesh, &tet.u, 5);
        let mut tk = tet.stiffness().clone();
        let t_tk = best(|| ta.assemble_stiffness(&tet.mesh, &m, Some(&trot), &mut tk));
        let mut sim2 = Simulation::new(grid.clone(), model.clone()).unwrap();
        let mut tet2 = TetSimulation::from_grid(&grid, model.clone()).unwrap();
        let band = cutfem::fem::advect::Diffusion::new(&grid).unwrap();
        let (mut gk, mut gk_adv, mut tk_) = (vec![], vec![], vec![]);
        for _ in 0..30 {
            gk.push(sim2.step().unwrap().stiffness_s * 1e3);
        }
        let mut sim3 = Simulation::new(grid.clone(), model.clone()).unwrap();
        for _ in 0..30 {
            gk_adv.push(sim3.step().unwrap().stiffness_s * 1e3);
            let ub = band.diffuse(&sim3.u).unwrap();
            let _ = cutfem::fem::advect::advect(&sim3.grid, &band, &ub).unwrap();
        }
        for _ in 0..30 {
            tk_.push(tet2.step().unwrap().stiffness_s * 1e3);
        }
        let mean = |v: &Vec<f64>| v.iter().sum::<f64>() / v.len() as f64;
        let med = |v: &Vec<f64>| {
            let mut w = v.clone();
            w.sort_by(f64::total_cmp);
            w[w.len() / 2]
        };
        println!("in-sim means: grid {:.3} (median {:.3}, first {:.3}) grid+advect {:.3} (median {:.3}) tet {:.3} (median {:.3})",
            mean(&gk), med(&gk), gk[0], mean(&gk_adv), med(&gk_adv), mean(&tk_), med(&tk_));
        {
            let (mut gr, mut gkk, mut tr, mut tkk) = (vec![], vec![], vec![], vec![]);
            for _ in 0..20 {
                sim2.step().unwrap();
                let t = Instant::now();
                let rot = asm.rotations(&sim2.grid, &sim2.u, 5);
                gr.push(t.elapsed().as_secs_f64() * 1e3);
                let t = Instant::now();
                asm.assemble_stiffness(&sim2.grid, &m, &blocks, Some(&rot), &dir, None, &mut k);
                gkk.push(t.elapsed().as_secs_f64() * 1e3);
                tet2.step().unwrap();
                let t = Instant::now();
                let trot = ta.rotations(&tet2.mesh, &tet2.u, 5);
                tr.push(t.elapsed().as_secs_f64() * 1e3);
                let t = Instant::now();
                ta.assemble_stiffness(&tet2.mesh, &m, Some(&trot), &mut tk);
                tkk.push(t.elapsed().as_secs_f64() * 1e3);
            }
            println!(
                "after-step medians: grid rot {:.3} K {:.3} | tet rot {:.3} K {:.3} | ratio {:.2}",
                med(&gr),
                med(&gkk),
                med(&tr),
                med(&tkk),
                (med(&tr) + med(&tkk)) / (med(&gr) + med(&gkk))
            );
        }
        println!("r={r}: grid blocks {t_blocks:.3} ms, rot {t_rot:.3}, K {t_k:.3} (no nitsche {t_k_nodir:.3}) | tet rot {t_trot:.3}, K {t_tk:.3} | grid K+rot {:.3} tet {:.3} ratio {:.2}",
            t_rot + t_k, t_trot + t_tk, (t_trot + t_tk) / (t_rot + t_k));
    }
}
