//! Every adjoint stage checked in isolation against central differences on random inputs, in
//! f64 (thesis sec. 5.2.5): polar decomposition, the cell elastic term, contact, and the whole
//! step Lagrangian `lam^T (b - A u')` of a small simulation with every effect on.

use adjoint::backward::{step_adjoint, step_lagrangian, PhysicalGradient};
use adjoint::local::*;
use cutfem::cutcell::{cell_integrals, CellIntegrals};
use cutfem::fem::collision::{ContactScheme, Ground};
use cutfem::fem::element::{corner_offsets, polar_rotation, Element, ElementSet};
use cutfem::fem::{Aabb, Grid, Model, Simulation};
use cutfem::shapes::Shape;
use gpumat::{Mat3, Matrix, Vec3};

/// A small deterministic generator (SplitMix64) for reproducible random inputs.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
    fn vec(&mut self) -> Vec3<f64> {
        Vec3::new(self.next(), self.next(), self.next())
    }
    fn mat(&mut self) -> Mat3<f64> {
        Mat3::from_rows(std::array::from_fn(|_| std::array::from_fn(|_| self.next())))
    }
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(1e-300)
}

/// Central difference of `f` at `t = 0`.
fn cd(eps: f64, f: impl Fn(f64) -> f64) -> f64 {
    (f(eps) - f(-eps)) / (2.0 * eps)
}

#[test]
fn polar_adjoint_matches_central_differences() {
    let mut rng = Rng(1);
    for trial in 0..20 {
        // F = rotation * stretch, moderately deformed
        let rot = polar_rotation(Mat3::identity() + rng.mat() * 0.8, 30);
        let f = rot * (Mat3::identity() + rng.mat() * 0.3);
        let w = rng.mat();
        let r_bar = w;
        let f_bar = polar_rotation_adjoint(f, 5, r_bar);
        let dir = rng.mat();
        let fd = cd(1e-6, |t| frobenius(&w, &polar_rotation(f + dir * t, 5)));
        let an = frobenius(&f_bar, &dir);
        assert!(rel(an, fd) < 1e-6, "trial {trial}: adjoint {an} fd {fd}");
    }
}

/// A cut cell of size 0.1 with random corner values (at least one inside), or a full one.
fn random_cell(rng: &mut Rng, full: bool) -> CellIntegrals {
    let h = 0.1;
    if full {
        return CellIntegrals::full(h);
    }
    let mut phi: [f64; 8] = std::array::from_fn(|_| (rng.next() - 0.3) * h);
    phi[0] = -0.5 * h;
    cell_integrals(&phi, h)
}

/// The elastic term's derivatives for every element (the condensed incompatible modes
/// included: `dK_c = P^T dK P`, module docs of `cutfem::fem::element`) on full and cut cells.
#[test]
fn cell_elastic_adjoint_matches_central_differences() {
    let mut rng = Rng(2);
    let h = 0.1;
    for element in Element::ALL {
        for trial in 0..8 {
            let ci = random_cell(&mut rng, trial == 0);
            let (lambda, mu) = (1500.0, 800.0);
            let set = |l: f64, m: f64| ElementSet::of_cell(&ci, h, element, l, m);
            let here = set(lambda, mu);
            let r = polar_rotation(Mat3::identity() + rng.mat() * 0.5, 30);
            let lam: [Vec3<f64>; 8] = std::array::from_fn(|_| rng.vec());
            let a: [Vec3<f64>; 8] = std::array::from_fn(|_| rng.vec() * 0.05);
            let x = corner_offsets(h);
            let dt = 0.01;
            let (r_bar, dl, dm) = cell_elastic_adjoint(&here, &r, &lam, &a, &x, dt);
            let dir = rng.mat();
            let fd = cd(1e-6, |t| {
                cell_elastic_value(&here.k, &(r + dir * t), &lam, &a, &x, dt)
            });
            let what = format!("{} trial {trial}", element.name());
            assert!(rel(frobenius(&r_bar, &dir), fd) < 1e-6, "{what} R");
            let fdl = cd(1e-2, |t| {
                cell_elastic_value(&set(lambda + t, mu).k, &r, &lam, &a, &x, dt)
            });
            let fdm = cd(1e-2, |t| {
                cell_elastic_value(&set(lambda, mu + t).k, &r, &lam, &a, &x, dt)
            });
            assert!(rel(dl, fdl) < 1e-6, "{what} lambda: {dl} vs {fdl}");
            assert!(rel(dm, fdm) < 1e-6, "{what} mu: {dm} vs {fdm}");
        }
    }
}

#[test]
fn contact_adjoint_matches_central_differences() {
    let mut rng = Rng(3);
    for scheme in [
        ContactScheme::Implicit,
        ContactScheme::Thesis,
        ContactScheme::Penalty,
        ContactScheme::Softmin,
    ] {
        for trial in 0..20 {
            let g = Ground {
                normal: (Vec3::new(0.0, 1.0, 0.0) + rng.vec() * 0.2),
                height: 0.1 * rng.next(),
                stiffness: 1e3,
                softness: 50.0,
                scheme,
            };
            // distances in the soft transition region (|alpha d| <~ 3)
            let x0 = Vec3::new(rng.next(), g.height + 0.03 * rng.next(), rng.next());
            let (u, un, v, lam) = (rng.vec() * 0.01, rng.vec() * 0.01, rng.vec(), rng.vec());
            let (dt, theta) = (0.01, 0.6);
            let adj = contact_adjoint(&g, dt, theta, x0, u, un, v, lam);
            let val = |g: &Ground, u, un, v, lam| contact_value(g, dt, theta, x0, u, un, v, lam);
            let d = rng.vec();
            let checks = [
                ("u", adj.u.dot(d), cd(1e-7, |t| val(&g, u + d * t, un, v, lam))),
                (
                    "u'",
                    adj.u_next.dot(d),
                    cd(1e-7, |t| val(&g, u, un + d * t, v, lam)),
                ),
                ("v", adj.v.dot(d), cd(1e-7, |t| val(&g, u, un, v + d * t, lam))),
                (
                    "lam",
                    adj.lam.dot(d),
                    cd(1e-7, |t| val(&g, u, un, v, lam + d * t)),
                ),
                (
                    "n",
                    adj.normal.dot(d),
                    cd(1e-7, |t| {
                        let mut g2 = g;
                        g2.normal = g.normal + d * t;
                        val(&g2, u, un, v, lam)
                    }),
                ),
                (
                    "height",
                    adj.height,
                    cd(1e-7, |t| {
                        let mut g2 = g;
                        g2.height = g.height + t;
                        val(&g2, u, un, v, lam)
                    }),
                ),
            ];
            for (name, an, fd) in checks {
                if an.abs().max(fd.abs()) < 1e-9 {
                    continue;
                }
                assert!(
                    rel(an, fd) < 1e-6,
                    "{scheme:?} trial {trial} {name}: {an} vs {fd}"
                );
            }
        }
    }
}

#[test]
fn friction_adjoint_matches_central_differences() {
    let mut rng = Rng(5);
    for scheme in [ContactScheme::Implicit, ContactScheme::Penalty] {
        for trial in 0..20 {
            let g = Ground {
                normal: (Vec3::new(0.0, 1.0, 0.0) + rng.vec() * 0.2),
                height: 0.1 * rng.next(),
                stiffness: 1e3,
                softness: 50.0,
                scheme,
            };
            // distances in the soft transition region, and in contact for the penalty law
            let x0 = Vec3::new(rng.next(), g.height + 0.03 * rng.next() - 0.01, rng.next());
            let (u, un, lam) = (rng.vec() * 0.01, rng.vec() * 0.01, rng.vec());
            let mu = 0.5 + rng.next().abs();
            let adj = friction_adjoint(&g, mu, x0, u, un, lam);
            let d = rng.vec();
            let checks = [
                (
                    "u",
                    adj.u.dot(d),
                    cd(1e-7, |t| friction_value(&g, mu, x0, u + d * t, un, lam)),
                ),
                (
                    "mu",
                    adj.mu,
                    cd(1e-3, |t| friction_value(&g, mu + t, x0, u, un, lam)),
                ),
                (
                    "n",
                    adj.normal.dot(d),
                    cd(1e-7, |t| {
                        let mut g2 = g;
                        g2.normal = g.normal + d * t;
                        friction_value(&g2, mu, x0, u, un, lam)
                    }),
                ),
                (
                    "height",
                    adj.height,
                    cd(1e-7, |t| {
                        let mut g2 = g;
                        g2.height = g.height + t;
                        friction_value(&g2, mu, x0, u, un, lam)
                    }),
                ),
            ];
            for (name, an, fd) in checks {
                if an.abs().max(fd.abs()) < 1e-9 {
                    continue;
                }
                assert!(
                    rel(an, fd) < 1e-6,
                    "{scheme:?} trial {trial} {name}: {an} vs {fd}"
                );
            }
        }
    }
}

/// A small bar with every effect on: corotation, Nitsche, gravity, damping and ground contact
/// with friction.
fn small_sim(scheme: ContactScheme) -> Simulation {
    let shape = Shape::Box {
        center: [0.0, 0.25, 0.0],
        size: [0.6, 0.2, 0.2],
    };
    let grid = Grid::new(shape.to_sdf(10.0, 2).unwrap()).unwrap();
    let model = Model {
        young: 3000.0,
        poisson: 0.3,
        density: 1.2,
        damping_mass: 0.1,
        damping_stiffness: 0.01,
        gravity: Vec3::new(0.5, -10.0, 0.2),
        ground: Some(Ground {
            normal: Vec3::new(0.05, 1.0, -0.03),
            height: 0.16,
            // per unit area for the penalty and softmin schemes (about 1e3 per crossing here)
            stiffness: if matches!(scheme, ContactScheme::Penalty | ContactScheme::Softmin) {
                3e5
            } else {
                1e3
            },
            softness: 60.0,
            scheme,
        }),
        dirichlet: vec![Aabb {
            min: [-0.4, 0.0, -0.2],
            max: [-0.22, 0.5, 0.2],
        }],
        friction: Some(0.7),
        ..Model::default()
    };
    let mut sim = Simulation::new(grid, model).unwrap();
    sim.solver.direct = true;
    sim
}

#[test]
fn step_adjoint_matches_central_differences() {
    for scheme in [
        ContactScheme::Implicit,
        ContactScheme::Thesis,
        ContactScheme::Penalty,
        ContactScheme::Softmin,
    ] {
        let mut sim = small_sim(scheme);
        let n = sim.grid.dofs();
        let mut rng = Rng(4);
        // a non-trivial state: random rotations-sized displacement field plus a few steps
        for _ in 0..3 {
            sim.step().unwrap();
        }
        let rv = |rng: &mut Rng, s: f64| Matrix::from_fn(n, 1, 1, |_, _, _| rng.vec() * s);
        sim.u = Matrix::eval(sim.u.ex() + rv(&mut rng, 0.02).ex());
        sim.v = Matrix::eval(sim.v.ex() + rv(&mut rng, 0.1).ex());
        let (u0, v0) = (sim.u.clone(), sim.v.clone());
        let u_next = Matrix::eval(u0.ex() + rv(&mut rng, 0.01).ex());
        let lam = rv(&mut rng, 1.0);
        let base = sim.model.clone();

        // the penalty scheme's adjoint linearizes at the converged u' (others ignore it)
        sim.linearize_contact_at(Some(u_next.clone()));
        sim.assemble_system();
        let mut ub = Matrix::zeros(n, 1, 1);
        let mut vb = Matrix::zeros(n, 1, 1);
        let mut g = PhysicalGradient::default();
        step_adjoint(&sim, &u_next, &lam, &mut ub, &mut vb, &mut g);

        let cell = std::cell::RefCell::new(sim);
        let eval = |model: &Model, u: &Matrix<Vec3<f64>>, v: &Matrix<Vec3<f64>>| {
            let mut sim = cell.borrow_mut();
            sim.reset(model.clone()).unwrap();
            sim.u = u.clone();
            sim.v = v.clone();
            sim.linearize_contact_at(Some(u_next.clone()));
            sim.assemble_system();
            step_lagrangian(&sim, &u_next, &lam)
        };
        let du = rv(&mut rng, 1.0);
        let dv = rv(&mut rng, 1.0);
        let fd_u = cd(1e-7, |t| eval(&base, &Matrix::eval(u0.ex() + du.ex() * t), &v0));
        let an_u = ub.ex().dot(du.ex());
        assert!(rel(an_u, fd_u) < 1e-6, "{scheme:?} u: {an_u} vs {fd_u}");
        // L is linear in v (both contact schemes), so a large step has no truncation error
        let fd_v = cd(1e-2, |t| eval(&base, &u0, &Matrix::eval(v0.ex() + dv.ex() * t)));
        let an_v = vb.ex().dot(dv.ex());
        assert!(rel(an_v, fd_v) < 1e-6, "{scheme:?} v: {an_v} vs {fd_v}");

        let (e, nu) = (base.young, base.poisson);
        let dlam_de = nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        let dmu_de = 1.0 / (2.0 * (1.0 + nu));
        let dlam_dnu = e * (1.0 + 2.0 * nu * nu) / ((1.0 + nu) * (1.0 - 2.0 * nu)).powi(2);
        let dmu_dnu = -e / (2.0 * (1.0 + nu) * (1.0 + nu));
        // L is linear in E, density, the damping coefficients and gravity: large steps there
        // avoid cancellation; the others are nonlinear and use small steps.
        type Edit = Box<dyn Fn(&mut Model, f64)>;
        let params: Vec<(&str, f64, f64, Edit)> = vec![
            (
                "young",
                g.lambda * dlam_de + g.mu * dmu_de,
                10.0,
                Box::new(|m, t| m.young += t),
            ),
            (
                "poisson",
                g.lambda * dlam_dnu + g.mu * dmu_dnu,
                1e-6,
                Box::new(|m, t| m.poisson += t),
            ),
            ("density", g.density, 0.1, Box::new(|m, t| m.density += t)),
            (
                "friction",
                g.friction,
                0.01,
                Box::new(|m, t| m.friction = m.friction.map(|f| f + t)),
            ),
            (
                "damping_mass",
                g.damping_mass,
                0.01,
                Box::new(|m, t| m.damping_mass += t),
            ),
            (
                "damping_stiffness",
                g.damping_stiffness,
                1e-3,
                Box::new(|m, t| m.damping_stiffness += t),
            ),
            (
                "gravity.x",
                g.gravity.to_array()[0],
                1.0,
                Box::new(|m, t| m.gravity = m.gravity + Vec3::new(t, 0.0, 0.0)),
            ),
            (
                "gravity.y",
                g.gravity.to_array()[1],
                1.0,
                Box::new(|m, t| m.gravity = m.gravity + Vec3::new(0.0, t, 0.0)),
            ),
            (
                "ground.height",
                g.ground_height,
                1e-7,
                Box::new(|m, t| m.ground.as_mut().unwrap().height += t),
            ),
            (
                "ground.normal.x",
                g.ground_normal.to_array()[0],
                1e-7,
                Box::new(|m, t| {
                    let gr = m.ground.as_mut().unwrap();
                    gr.normal = gr.normal + Vec3::new(t, 0.0, 0.0);
                }),
            ),
            (
                "ground.normal.y",
                g.ground_normal.to_array()[1],
                1e-5,
                Box::new(|m, t| {
                    let gr = m.ground.as_mut().unwrap();
                    gr.normal = gr.normal + Vec3::new(0.0, t, 0.0);
                }),
            ),
        ];
        for (name, an, eps, edit) in params {
            // the best of several steps: the whole assembly's rounding noise (about 1e-16 of
            // |L|) dominates small steps for the nonlinear parameters
            let fd = [eps, eps * 0.1, eps * 10.0]
                .into_iter()
                .map(|e| {
                    cd(e, |t| {
                        let mut m = base.clone();
                        edit(&mut m, t);
                        eval(&m, &u0, &v0)
                    })
                })
                .min_by(|a, b| (a - an).abs().total_cmp(&(b - an).abs()))
                .unwrap();
            assert!(rel(an, fd) < 1e-6, "{scheme:?} {name}: adjoint {an} vs fd {fd}");
        }
    }
}
