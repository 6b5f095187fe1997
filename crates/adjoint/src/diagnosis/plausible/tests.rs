use super::*;
use crate::observations::ObservedPoint;

fn motion<'a>(observations: &'a Observations, held: bool, surfaces: Vec<Vec<[f64; 3]>>) -> Motion<'a> {
    Motion {
        mass: 1.0,
        gravity: 10.0,
        duration: 0.4,
        held,
        fastest: 2.0,
        frequency: None,
        surfaces,
        spacing: 0.05,
        observations,
        floor: Some(0.01),
    }
}

/// A velocity force that holds up more than half the weight of a free body at its fastest
/// speed is implausible, one of a fraction of a percent is not; on a held body it is a decay
/// time, never judged by the weight.
#[test]
fn drag_that_carries_the_weight_is_implausible() {
    let obs = Observations::new();
    let free = motion(&obs, false, Vec::new());
    // m g = 10, fastest 2: 4 per unit speed holds up 80% at 2, terminal velocity 2.5
    let heavy = terminal("drag", 4.0, &free);
    assert!(heavy.implies.contains("terminal velocity of 2.5"), "{heavy:?}");
    assert!(heavy.implausible.as_deref().unwrap().contains("80%"), "{heavy:?}");
    let light = terminal("drag", 0.01, &free);
    assert!(light.implausible.is_none(), "{light:?}");
    assert!(light.implies.contains("terminal velocity of 1000"), "{light:?}");
    // just below and just above half the weight
    assert!(terminal("drag", 2.49, &free).implausible.is_none());
    assert!(terminal("drag", 2.51, &free).implausible.is_some());
    let held = terminal("drag", 4.0, &motion(&obs, true, Vec::new()));
    assert!(
        held.implausible.is_none() && held.implies.contains("decay time m / c = 0.25"),
        "{held:?}"
    );
    assert!(terminal("drag", 0.0, &free).implausible.is_none());
}

/// A plane the fitted body never comes near cannot stop it; one that observed points pass
/// through by more than the noise is not a ground; one the body touches, with the points on
/// it, is plausible.
#[test]
fn a_ground_never_reached_or_passed_through_is_implausible() {
    let mut obs = Observations::new();
    for i in 0..100 {
        obs.push(0, ObservedPoint::new([0.01 * i as f64, 0.002, 0.0]));
    }
    let body = |lowest: f64| vec![vec![[0.0, lowest + 0.2, 0.0], [0.0, lowest, 0.0]]; 3];
    let floor_y = [0.0, 1.0, 0.0];
    let touching = plane(floor_y, 0.0, &motion(&obs, false, body(0.001)));
    assert!(touching.implausible.is_none(), "{touching:?}");
    assert!(touching.implies.contains("within 0.001"), "{touching:?}");
    // reach: the larger of the spacing (0.05) and 3 noise floors (0.03)
    let far = plane(floor_y, 0.0, &motion(&obs, false, body(0.06)));
    assert!(
        far.implausible.as_deref().unwrap().contains("never touches"),
        "{far:?}"
    );
    assert!(plane(floor_y, 0.0, &motion(&obs, false, body(0.04)))
        .implausible
        .is_none());
    let pressed = plane(floor_y, 0.0, &motion(&obs, false, body(-0.004)));
    assert!(
        pressed.implausible.is_none() && pressed.implies.contains("0.004 into it"),
        "{pressed:?}"
    );
    // 2 of 102 points 0.2 below the plane (depth: 3 floors 0.03 > half the spacing 0.025)
    obs.push(1, ObservedPoint::new([0.0, -0.2, 0.0]));
    obs.push(1, ObservedPoint::new([0.1, -0.2, 0.0]));
    let through = plane(floor_y, 0.0, &motion(&obs, false, body(0.001)));
    let why = through.implausible.expect("passes through");
    assert!(
        why.starts_with("2 observed points (2.0%) lie more than 0.03 below"),
        "{why}"
    );
    // a tilted plane measures along its normal
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let tilted = plane([s, s, 0.0], -1.0, &motion(&Observations::new(), false, body(0.0)));
    assert!(
        tilted.implausible.as_deref().unwrap().contains("never touches"),
        "{tilted:?}"
    );
}

/// The stiffness field's contrast is stated and judged against [`MAX_CONTRAST`].
#[test]
fn a_thousandfold_stiffness_contrast_is_implausible() {
    let j = contrast(&[1.0, 2.0, 0.5]);
    assert!(
        j.implausible.is_none() && j.implies.contains("varies 4x"),
        "{j:?}"
    );
    assert!(contrast(&[1.0, 999.0]).implausible.is_none());
    assert!(contrast(&[0.5, 1000.0]).implausible.is_some());
}

/// A refitted drag candidate of a box falling under gravity: the simulation is run and a drag
/// that sinks it at its terminal velocity is judged implausible, air-like drag is not.
#[test]
fn judged_on_the_fitted_models_own_fall() {
    let candidate = |c: f64| {
        let text = format!(
            "[body]\nshape = {{ kind = \"box\", center = [0.0, 1.0, 0.0], size = [0.2, 0.2, 0.2] }}\nresolution = 8\n[material]\nyoung = 2000.0\npoisson = 0.3\ndensity = 1.0\n[gravity]\nacceleration = [0.0, -10.0, 0.0]\n[drag]\ncoefficient = {c:?}\n[time]\ndt = 0.02\nsteps = 20\n[model]\neffects = [\"gravity\", \"drag\"]\n"
        );
        let scene = Scene::parse(&text, std::path::Path::new("box.toml")).unwrap();
        let model = scene.build_simulation().unwrap().model;
        Candidate::refitted("drag", scene, model)
    };
    let obs = Observations::new();
    // m = 0.008, A = 0.24: c = 1 gives v_t = 0.33, reached within the 0.4 s
    let honey = judge(&candidate(1.0), &obs, Some(0.001)).unwrap().unwrap();
    assert_eq!(honey.effect, "drag");
    assert!(honey.implausible.is_some(), "{honey:?}");
    // c = 1e-4: v_t = 3333, the fall reaches 4
    let air = judge(&candidate(1e-4), &obs, Some(0.001)).unwrap().unwrap();
    assert!(air.implausible.is_none(), "{air:?}");
    assert!(
        air.implies.contains("its fastest speed here 3.") || air.implies.contains("its fastest speed here 4"),
        "{air:?}"
    );
}

/// A clamp whose held surface moves half as far as the body's farthest point or more does not
/// hold it; one whose held part barely moves does; its springs read as a layer of the body.
#[test]
fn a_clamp_that_lets_its_part_move_like_the_rest_is_implausible() {
    let obs = Observations::new();
    let boxes = [cutfem::fem::Aabb {
        min: [-0.1, -1.0, -1.0],
        max: [0.1, 1.0, 1.0],
    }];
    // a held vertex at x = 0 moving `root`, a free one at x = 1 moving 0.2
    let swing = |root: f64| {
        let rest = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        let bent = vec![[0.0, -root, 0.0], [1.0, -0.2, 0.0]];
        vec![rest.clone(), bent, rest]
    };
    let firm = held(&boxes, 1e4, 100.0, &motion(&obs, true, swing(0.01)));
    assert!(firm.implausible.is_none(), "{firm:?}");
    assert!(
        firm.implies.contains("a layer 0.01 thick") && firm.implies.contains("moves up to 0.01, 5%"),
        "{firm:?}"
    );
    // just below and at half of the largest displacement
    assert!(held(&boxes, 1e4, 100.0, &motion(&obs, true, swing(0.099)))
        .implausible
        .is_none());
    let loose = held(&boxes, 10.0, 100.0, &motion(&obs, true, swing(0.1)));
    assert!(
        loose
            .implausible
            .as_deref()
            .unwrap()
            .contains("50% as far as any point"),
        "{loose:?}"
    );
    // nothing moves: nothing to judge against
    let still = vec![vec![[0.0; 3], [1.0, 0.0, 0.0]]; 2];
    assert!(held(&boxes, 10.0, 100.0, &motion(&obs, true, still))
        .implausible
        .is_none());
}
