//! `fem::forward::ForwardRun` (the run behind `softbody simulate`): the level-set update after
//! each frame leaves the simulation's state bit-for-bit as plain steps give it, the totals are
//! the sums of the frames' step infos, and the advected SDF of the cuboid that fell onto the
//! ground keeps its volume (sec. 4.4.5) and its centroid follows the nodes'.

use cutfem::fem::forward::ForwardRun;
use cutfem::scene::Scene;
use std::path::Path;

const SCENE: &str = r#"
[body]
shape = { kind = "box", center = [0.0, 1.0, 0.0], size = [1.2, 0.4, 0.8] }
resolution = 10
[material]
young = 2000.0
poisson = 0.3
[gravity]
acceleration = [0.0, -10.0, 0.0]
[ground]
height = 0.75
scheme = "penalty"
stiffness = 4.0e5
softness = 1.0e4
[time]
dt = 0.02
steps = 8
"#;

/// Volume and centroid height of the body of an SDF, with the smooth occupancy
/// `clamp(1/2 - phi/spacing, 0, 1)` per node (sub-cell accurate for a distance field).
fn volume_and_height(s: &cutfem::SdfGrid) -> (f64, f64) {
    let (mut v, mut vy) = (0.0, 0.0);
    for (i, &phi) in s.values.iter().enumerate() {
        let w = (0.5 - phi / s.spacing).clamp(0.0, 1.0);
        let y = s.origin[1] + ((i / s.dims[0]) % s.dims[1]) as f64 * s.spacing;
        v += w;
        vy += w * y;
    }
    (v * s.spacing.powi(3), vy / v)
}

/// The mass-weighted mean height of the deformed active nodes.
fn deformed_height(sim: &cutfem::fem::Simulation) -> f64 {
    let m = sim.mass.as_slice();
    let total: f64 = m.iter().sum();
    let moved: f64 = (sim.grid.positions.iter().zip(sim.u.as_slice()).zip(m))
        .map(|((p, u), &mi)| (p.y + u.y) * mi)
        .sum();
    moved / total
}

#[test]
fn advection_leaves_the_state_alone_and_the_totals_add_up() {
    let scene = Scene::parse(SCENE, Path::new("forward.toml")).unwrap();
    let mut plain = scene.build_simulation().unwrap();
    let mut sim = scene.build_simulation().unwrap();
    let mut run = ForwardRun::new(&sim, scene.numerics.diffusion).unwrap();
    let mut infos = Vec::new();
    for f in 1..=scene.time.steps {
        infos.push(plain.step().unwrap());
        run.frame(&mut sim, f).unwrap();
        assert_eq!(sim.u.as_slice(), plain.u.as_slice(), "frame {f}");
        assert_eq!(sim.v.as_slice(), plain.v.as_slice(), "frame {f}");
    }
    let t = &run.totals;
    let its: Vec<usize> = infos.iter().map(|i| i.iterations).collect();
    assert_eq!(t.iterations, its);
    assert_eq!(t.info.iterations, its.iter().sum::<usize>());
    let max_res = infos.iter().map(|i| i.residual).fold(0.0, f64::max);
    assert_eq!(t.info.residual, max_res);
    assert_eq!(t.fallbacks, infos.iter().filter(|i| i.fallback).count());
    assert_eq!(t.info.contacts, infos.last().unwrap().contacts);
    let contacts: Vec<usize> = infos.iter().map(|i| i.contacts).collect();
    assert!(
        contacts.iter().any(|&c| c > 0),
        "the cuboid reached the ground: {contacts:?}"
    );
    assert!(t.advection_s > 0.0);

    // the advected body keeps the rest volume (1.2 x 0.4 x 0.8 = 0.384) and follows the nodes
    let (v, y) = volume_and_height(run.advected.as_ref().unwrap());
    let want = deformed_height(&sim);
    eprintln!("advected volume {v}, height {y}, nodes' mean height {want}");
    assert!((v / 0.384 - 1.0).abs() < 0.05, "advected volume {v}");
    assert!(
        want < 1.0 - 0.03,
        "the body fell onto the ground: mean height {want}"
    );
    assert!(
        (y - want).abs() < 0.1 * (1.0 - want),
        "advected height {y} vs nodes' {want}"
    );
}
