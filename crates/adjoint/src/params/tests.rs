//! A parameter set before a problem resolved it (no stiffness-field basis yet) is consistent:
//! its labels, `to_x` and `apply` agree on the number of coordinates and nothing panics.

use super::*;

#[test]
fn unresolved_stiffness_field_has_no_coordinates_and_does_not_panic() {
    let set = ParamSet::parse(&["young,stiffness_field"]).unwrap();
    assert!(set.field.is_none());
    let mut model = Model::default();
    assert_eq!(set.labels(), vec!["young".to_string()]);
    assert_eq!(set.len(), 1);
    let x = set.to_x(&model);
    assert_eq!(x.len(), set.len());
    set.apply(&[3000f64.ln()], &mut model);
    assert!((model.young - 3000.0).abs() < 1e-9);
    assert!(model.stiffness_scale.is_none());
    let g = set.chain(&model, &PhysicalGradient::default());
    assert_eq!(g.len(), set.len());
    assert_eq!(set.x_scales(&model).len(), set.len());
    assert_eq!(set.bounds(&x).len(), set.len());
    assert_eq!(set.log_coordinates().len(), set.len());
}
