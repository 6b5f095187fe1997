//! A parameter set is checked against a model once ([`ParamSet::layout`]): a set whose model
//! lacks what a parameter needs is refused with the scene key to add; a layout's labels,
//! `to_x`, `apply`, `chain` and `x_scales` agree on the number of coordinates, and writing `x`
//! into a model that lacks the ground or the external force puts the base's back.

use super::*;
use cutfem::fem::{ExternalForce, Ground};

#[test]
fn a_set_without_what_it_needs_is_refused_by_name() {
    let model = Model::default();
    let e = ParamSet::parse(&["young,stiffness_field"])
        .unwrap()
        .layout(&model)
        .unwrap_err();
    assert!(e.to_string().contains("[model].stiffness_field"), "{e}");
    let e = ParamSet::parse(&["ground"]).unwrap().layout(&model).unwrap_err();
    assert!(e.to_string().contains("[ground]"), "{e}");
    let e = ParamSet::parse(&["external_force"])
        .unwrap()
        .layout(&model)
        .unwrap_err();
    assert!(e.to_string().contains("wind"), "{e}");
}

/// A default model with a ground (non-default stiffness and softness) and a two-field external
/// force labelled `a`, `b`.
fn with_ground_and_force() -> Model {
    Model {
        ground: Some(Ground {
            normal: Vec3::new(0.0, 1.0, 0.0),
            height: -0.5,
            stiffness: 123.0,
            softness: 45.0,
            scheme: Default::default(),
        }),
        external_force: Some(ExternalForce {
            basis: std::sync::Arc::new(vec![vec![Vec3::new(1.0, 0.0, 0.0)]; 2]),
            coefficients: vec![0.5, -0.25],
            labels: vec!["a".into(), "b".into()],
        }),
        ..Model::default()
    }
}

#[test]
fn a_layout_agrees_with_itself_and_restores_the_base_parts() {
    let base = with_ground_and_force();
    let layout = ParamSet::parse(&["young,ground,external_force"])
        .unwrap()
        .layout(&base)
        .unwrap();
    assert_eq!(layout.params[2], Param::ExternalForce(2));
    let x = layout.to_x(&base);
    assert_eq!(x.len(), layout.len());
    assert_eq!(layout.labels().len(), 1 + 3 + 2);
    assert_eq!(layout.x_scales(&base).len(), layout.len());
    assert_eq!(
        layout.chain(&base, &PhysicalGradient::default()).len(),
        layout.len()
    );
    assert_eq!(layout.bounds(&x).len(), layout.len());
    assert_eq!(layout.log_coordinates().len(), layout.len());
    // a model without the ground and the force gets the base's back, moved by x
    let mut bare = Model::default();
    let mut moved = x.clone();
    moved[3] = 0.75; // ground height
    moved[5] = 2.0; // second force coefficient
    layout.apply(&moved, &mut bare);
    let g = bare.ground.unwrap();
    assert_eq!((g.height, g.stiffness, g.softness), (0.75, 123.0, 45.0));
    assert!((g.normal - Vec3::new(0.0, 1.0, 0.0)).norm() < 1e-15);
    let f = bare.external_force.as_ref().unwrap();
    assert_eq!(f.coefficients, vec![0.5, 2.0]);
    assert_eq!(f.labels, vec!["a".to_string(), "b".to_string()]);
    assert_eq!(layout.to_x(&bare), moved);
}

/// Issue 51: every parameter the fit accepts can be gradient-checked. `gradcheck` steps each
/// physical component by its label ([`crate::fit::get_physical`], [`crate::fit::set_physical`]);
/// over the whole vocabulary ([`ALL`], the stiffness field aside: it is stepped in its
/// coordinates), every label a layout reports is readable and writable there, and writing it
/// moves exactly that reported value.
#[test]
fn every_fitted_component_can_be_stepped_by_its_label() {
    use crate::fit::{get_physical, set_physical};
    let model = Model {
        drag: Some(cutfem::fem::NodalDamping {
            weights: std::sync::Arc::new(vec![1.0]),
            coefficient: 0.3,
        }),
        support: Some(40.0),
        friction: Some(0.2),
        dirichlet: vec![cutfem::fem::Aabb {
            min: [0.0; 3],
            max: [0.1; 3],
        }],
        damping_mass: 0.1,
        damping_stiffness: 0.01,
        initial_velocity: Vec3::new(0.1, 0.2, 0.3),
        ..with_ground_and_force()
    };
    for p in ALL.iter().filter(|p| **p != Param::StiffnessField) {
        let layout = ParamSet::parse(&[p.name()]).unwrap().layout(&model).unwrap();
        let physical = layout.physical(&model, &PhysicalGradient::default());
        assert!(!physical.is_empty(), "{p}");
        for (k, (label, _)) in physical.iter().enumerate() {
            let v = get_physical(&model, label).unwrap_or_else(|| panic!("{p}: `{label}` cannot be read"));
            let mut m = model.clone();
            assert!(
                set_physical(&mut m, label, v + 0.125),
                "{p}: `{label}` cannot be written"
            );
            assert_eq!(get_physical(&m, label), Some(v + 0.125), "{p}: `{label}`");
            // only that component moved, and the layout's values see it (the ground's normal
            // is reported as its unit vector: its components are compared as written)
            for (j, (other, _)) in physical.iter().enumerate() {
                let (a, b) = (get_physical(&model, other), get_physical(&m, other));
                assert_eq!(
                    a == b,
                    j != k,
                    "{p}: writing `{label}` moved `{other}`: {a:?} -> {b:?}"
                );
            }
        }
    }
}
