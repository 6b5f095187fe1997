//! Tests of Table H's counting, curves and merge.
use super::*;
use serde_json::json;

#[test]
fn the_upper_bound_is_clopper_pearsons() {
    // no event in n: 1 - alpha^(1/n) (59 controls bound the rate by 5%)
    for n in [1, 18, 59, 100] {
        let want = 1.0 - 0.05f64.powf(1.0 / n as f64);
        assert!((super::upper_bound(0, n, 0.05) - want).abs() < 1e-12, "{n}");
    }
    assert!(super::upper_bound(0, 59, 0.05) < 0.05 && super::upper_bound(0, 58, 0.05) > 0.05);
    // one event in 10: P(X <= 1 | 10, p) = 0.05 at p = 0.39416 (tables of the binomial)
    assert!((super::upper_bound(1, 10, 0.05) - 0.39416).abs() < 1e-4);
    assert_eq!(super::upper_bound(3, 3, 0.05), 1.0);
}

#[test]
fn curves_count_detections_and_false_alarms_per_level() {
    let rows = vec![
        json!({"sigma": 0.01, "hidden": "drag", "missing": "drag", "right": true}),
        json!({"sigma": 0.01, "hidden": "drag", "missing": "damping", "right": false, "tied": true}),
        json!({"sigma": 0.01, "hidden": null, "missing": "clamp", "right": false}),
        json!({"sigma": 0.01, "hidden": null, "missing": null, "right": true}),
        json!({"sigma": 0.02, "hidden": "clamp", "missing": "clamp", "right": true}),
        json!({"sigma": 0.02, "hidden": null, "missing": null, "right": true}),
        // a case that did not run counts nowhere
        json!({"sigma": 0.02, "hidden": "clamp", "missing": null, "right": null}),
    ];
    let all = curves(&rows, None);
    assert_eq!(all.len(), 2);
    assert_eq!((all[0].detection, all[0].hidden_cases), (0.5, 2));
    assert_eq!(all[0].detection_or_tied, 1.0);
    assert_eq!((all[0].false_alarm, all[0].controls), (0.5, 2));
    assert_eq!((all[1].detection, all[1].hidden_cases), (1.0, 1));
    assert_eq!((all[1].false_alarm, all[1].controls), (0.0, 1));
    // an effect's curve has no point where it has no case
    let drag = curves(&rows, Some("drag"));
    assert_eq!(drag.len(), 1);
    assert_eq!(drag[0].sigma, 0.01);
    assert_eq!(effects(&rows), vec!["drag", "clamp"]);
    let pic = svg(&rows);
    assert!(pic.starts_with("<svg") && pic.contains("false alarms") && pic.ends_with("</svg>\n"));
}

#[test]
fn merge_replaces_rerun_cases_and_orders_as_cases_json() {
    let row = |case: &str, seconds: f64| -> Row {
        serde_json::from_value(json!({"case": case, "hidden": null, "style": "samples",
            "sigma": 0.01, "margin": null, "named_first": null, "missing": null, "right": null,
            "tied": null, "rms_after_ratio": null, "floor_ratio": null, "discretisation": null,
            "on_bounds": "", "seconds": seconds, "error": null}))
        .unwrap()
    };
    let earlier = vec![
        row("none/samples-0.01", 1.0),
        row("gone/samples-0.01", 2.0),
        row("gravity/samples-0.01", 3.0),
    ];
    let fresh = vec![
        row("gravity/samples-0.01", 4.0),
        row("inclusion/samples-0.01", 5.0),
    ];
    let merged = merge(earlier, fresh);
    let got: Vec<(&str, f64)> = merged.iter().map(|r| (r.case.as_str(), r.seconds)).collect();
    // cases.json lists none, inclusion, gravity in this order; `gone` is not listed
    assert_eq!(
        got,
        vec![
            ("none/samples-0.01", 1.0),
            ("inclusion/samples-0.01", 5.0),
            ("gravity/samples-0.01", 4.0),
            ("gone/samples-0.01", 2.0),
        ]
    );
}
