//! Tests of the chart module; `write_examples` (ignored) writes pictures to look at.

use super::axis::*;
use super::*;

fn count_in(img: &Image, p: &Plot, c: [u8; 3]) -> usize {
    (p.y0..p.y1)
        .flat_map(|y| (p.x0..p.x1).map(move |x| (x, y)))
        .filter(|&(x, y)| img.pixel(x, y) == c)
        .count()
}

fn demo() -> Chart {
    let f = |k: f64| (k, 0.8f64.powf(k) + 1e-3);
    Chart {
        title: "Loss per iteration".into(),
        x_label: "iteration".into(),
        y_label: "loss".into(),
        log_y: true,
        series: vec![
            Series::new("Gauss-Newton", (0..40).map(|k| f(k as f64)).collect(), palette(0)),
            Series::new(
                "Adam lr=1e-2",
                (0..40).map(|k| (k as f64, 2.0 / (1.0 + k as f64))).collect(),
                palette(1),
            )
            .with_style(Style::LineMarkers),
            Series::new(
                "bad values",
                vec![(1.0, f64::NAN), (2.0, -1.0), (3.0, f64::INFINITY), (4.0, 0.3)],
                palette(2),
            )
            .with_style(Style::Markers),
        ],
        hlines: vec![(1e-3, "noise floor".into(), palette(3))],
        ..Chart::default()
    }
}

#[test]
fn ticks_are_nice() {
    assert_eq!(nice_step(1.0, 5), 0.2);
    assert_eq!(nice_step(137.0, 7), 20.0);
    assert_eq!(nice_step(0.03, 3), 0.01);
    assert!(nice_step(0.0, 5).is_nan() && nice_step(f64::NAN, 5).is_nan());
    assert_eq!(
        linear_ticks(0.0, 1.0, 5),
        vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]
    );
    assert_eq!(linear_ticks(-3.7, 12.2, 4), vec![0.0, 5.0, 10.0]);
    assert_eq!(linear_ticks(-0.1, 0.1, 2), vec![-0.1, 0.0, 0.1]);
    assert!(linear_ticks(1.0, 1.0, 5).is_empty() && linear_ticks(f64::MIN, f64::MAX, 5).len() <= 1001);
    let (lab, minor) = log_ticks(3e-5, 2e2, 10);
    assert_eq!(lab.len(), 7);
    assert!(lab.iter().all(|v| (v.log10() - v.log10().round()).abs() < 1e-12));
    assert!(!minor.is_empty());
    let (lab, _) = log_ticks(1e-12, 1e12, 5);
    assert!(lab.len() <= 6 && lab.iter().all(|v| (v.log10() - v.log10().round()).abs() < 1e-9));
    let (lab, _) = log_ticks(0.3, 0.8, 5);
    assert!(lab.len() >= 2, "{lab:?}");
    assert!(log_ticks(1.0, 1.0, 5).0.is_empty() && log_ticks(-1.0, 1.0, 5).0.is_empty());
}

#[test]
fn labels_are_compact() {
    let cases = [
        (0.0, "0"),
        (0.001, "1e-3"),
        (0.5, "0.5"),
        (2000.0, "2000"),
        (150000.0, "1.5e5"),
        (-0.25, "-0.25"),
    ];
    for (v, s) in cases {
        assert_eq!(fmt_compact(v), s);
    }
    assert_eq!(fmt_compact(0.123456), "0.123");
    let a = Axis::new(-0.05, 1.05, false, 6);
    let l: Vec<&str> = a.ticks.iter().map(|t| t.1.as_str()).collect();
    assert_eq!(l, ["0", "0.2", "0.4", "0.6", "0.8", "1.0"]);
    let a = Axis::new(1e-4, 1e2, true, 10);
    assert_eq!(
        a.ticks.iter().map(|t| t.1.as_str()).collect::<Vec<_>>(),
        ["1e-4", "1e-3", "0.01", "0.1", "1", "10", "100"]
    );
    let a = Axis::new(0.0, 3e5, false, 3);
    assert!(a.ticks.iter().any(|t| t.1 == "1e5"), "{:?}", a.ticks);
}

#[test]
fn chart_draws_series_inside_the_plot() {
    let c = demo();
    let img = c.render();
    assert_eq!((img.width, img.height), (640, 400));
    let (p, [ya, _]) = c.frame();
    for i in 0..4 {
        assert!(count_in(&img, &p, palette(i)) > 20, "series {i} missing");
    }
    assert!(ya
        .ticks
        .iter()
        .all(|t| (t.0.log10() - t.0.log10().round()).abs() < 1e-12));
    // data are clipped to the plot (the legend lies inside it too)
    let outside = (0..img.height)
        .flat_map(|y| (0..img.width).map(move |x| (x, y)))
        .filter(|&(x, y)| (x < p.x0 || x >= p.x1 || y < p.y0 || y >= p.y1) && img.pixel(x, y) == palette(0))
        .count();
    assert_eq!(outside, 0);
    assert_eq!(img, c.render(), "deterministic");
}

#[test]
fn axes_and_public_plot_area() {
    let c = Chart {
        log_x: true,
        log_y: true,
        series: vec![Series::new(
            "",
            (1..200).map(|k| (k as f64, 10f64.powi(-(k % 15)))).collect(),
            [0; 3],
        )],
        ..Chart::default()
    };
    let ([x0, y0, x1, y1], [ya, xa]) = c.plot_area();
    assert!(x0 < x1 && y0 < y1 && x1 <= 640 && y1 <= 400);
    for a in [&ya, &xa] {
        assert!(a.log && a.ticks.len() >= 2);
        assert!(
            a.ticks
                .iter()
                .all(|t| (t.0.log10() - t.0.log10().round()).abs() < 1e-9),
            "{:?}",
            a.ticks
        );
    }
    let big = Chart {
        series: vec![Series::new("", vec![(0.0, 0.0), (1.0, 4e6)], [0; 3])],
        ..Chart::default()
    };
    let (_, [ya, _]) = big.plot_area();
    assert!(
        ya.ticks.iter().any(|t| t.1 == "1e6" || t.1 == "2e6"),
        "{:?}",
        ya.ticks
    );
}

#[test]
fn degenerate_inputs_do_not_panic() {
    let nan = f64::NAN;
    let sets: Vec<Vec<(f64, f64)>> = vec![
        vec![],
        vec![(1.0, 2.0)],
        vec![(0.0, 5.0), (1.0, 5.0), (2.0, 5.0)],
        vec![(nan, nan), (f64::INFINITY, 1.0), (1.0, f64::NEG_INFINITY)],
        vec![(0.0, -1.0), (1.0, 0.0), (2.0, -3.0)],
        vec![(0.0, 1e300), (1.0, -1e300), (f64::MAX, f64::MIN)],
        vec![(0.0, 1e-300), (1e-9, 1e-299)],
    ];
    for (w, h) in [(640, 400), (200, 120), (30, 20), (1, 1), (0, 0)] {
        for log_y in [false, true] {
            for pts in &sets {
                for style in [Style::Line, Style::Markers, Style::LineMarkers, Style::Dashed] {
                    let c = Chart {
                        log_y,
                        title: "t".into(),
                        y_label: "y".into(),
                        series: vec![Series::new("s", pts.clone(), palette(0)).with_style(style)],
                        hlines: vec![(nan, "n".into(), palette(1)), (-1.0, "neg".into(), palette(2))],
                        width: w,
                        height: h,
                        ..Chart::default()
                    };
                    let img = c.render();
                    assert_eq!((img.width, img.height), (w, h));
                }
            }
            let b = BarChart {
                bars: vec![
                    ("a".into(), nan, palette(0)),
                    ("b".into(), -2.0, palette(1)),
                    ("c".into(), 0.0, palette(2)),
                ],
                log_y,
                width: w,
                height: h,
                ..BarChart::default()
            };
            assert_eq!(b.render().width, w);
            assert_eq!(
                BarChart {
                    width: w,
                    height: h,
                    ..BarChart::default()
                }
                .render()
                .height,
                h
            );
        }
    }
    let one = Chart {
        series: vec![Series::new("", vec![(3.0, 4.0)], palette(4))],
        ..Chart::default()
    };
    let (p, _) = one.frame();
    assert!(
        count_in(&one.render(), &p, palette(4)) > 0,
        "a single point is visible"
    );
    let fixed = Chart {
        x_range: Some((0.0, 1.0)),
        y_range: Some((0.0, 1.0)),
        ..demo()
    };
    assert_eq!(fixed.render().width, 640);
}

#[test]
fn bars_and_grid() {
    let b = BarChart {
        title: "rms per region".into(),
        y_label: "rms [m]".into(),
        bars: (0..5)
            .map(|i| (format!("region {i}"), 0.01 * (i + 1) as f64, palette(i)))
            .collect(),
        hlines: vec![(0.025, "noise".into(), [0, 0, 0])],
        ..BarChart::default()
    };
    let img = b.render();
    for i in 0..5 {
        assert!(
            img.rgb.chunks(3).filter(|c| *c == palette(i)).count() > 100,
            "bar {i}"
        );
    }
    let g = grid_of(vec![img.clone(), demo().render(), Image::new(10, 10, [0; 3])], 2);
    assert_eq!((g.width, g.height), (8 + 2 * 648, 8 + 2 * 408));
    assert_eq!(grid_of(Vec::new(), 3).width, 0);
}

/// Writes example pictures for a look: `cargo test -p softbody plot -- --ignored`.
#[test]
#[ignore]
fn write_examples() {
    let dir = std::path::Path::new("/tmp/plot_examples");
    std::fs::create_dir_all(dir).unwrap();
    demo().render().save_png(&dir.join("loss_log.png")).unwrap();
    demo().render_svg().save(&dir.join("loss_log.svg")).unwrap();
    let lin = Chart {
        title: "Young's modulus estimate".into(),
        x_label: "iteration".into(),
        y_label: "E [kPa]".into(),
        series: vec![
            Series::new(
                "estimate",
                (0..60)
                    .map(|k| {
                        (
                            k as f64,
                            2000.0 + 1500.0 * (-0.1 * k as f64).exp() * (0.7 * k as f64).cos(),
                        )
                    })
                    .collect(),
                palette(0),
            ),
            Series::new(
                "dashed",
                (0..60).map(|k| (k as f64, 1200.0 + 10.0 * k as f64)).collect(),
                palette(1),
            )
            .with_style(Style::Dashed),
        ],
        hlines: vec![(2000.0, "truth".into(), [0, 0, 0])],
        ..Chart::default()
    };
    lin.render().save_png(&dir.join("linear.png")).unwrap();
    let small = Chart {
        width: 320,
        height: 200,
        ..lin.clone()
    };
    small.render().save_png(&dir.join("small.png")).unwrap();
    let b = BarChart {
        title: "Candidates".into(),
        y_label: "loss".into(),
        log_y: true,
        bars: ["soft", "medium", "stiff", "very stiff", "n/a", "neg"]
            .iter()
            .zip([0.3, 2e-3, 5e-2, 4.0, f64::NAN, -1.0])
            .enumerate()
            .map(|(i, (l, v))| (l.to_string(), v, palette(i)))
            .collect(),
        hlines: vec![(1e-2, "threshold".into(), [200, 0, 0])],
        ..BarChart::default()
    };
    b.render().save_png(&dir.join("bars_log.png")).unwrap();
    let many = BarChart {
        title: "rms per region".into(),
        bars: (0..14)
            .map(|i| (format!("region_{i}"), (i as f64 - 4.0) * 0.013, palette(i)))
            .collect(),
        ..BarChart::default()
    };
    many.render().save_png(&dir.join("bars_many.png")).unwrap();
    let wide = Chart {
        title: "Gradient norm, log-log".into(),
        x_label: "step".into(),
        log_x: true,
        log_y: true,
        series: (0..6)
            .map(|j| {
                let pts = (1..200).map(|k| {
                    (
                        k as f64,
                        10f64.powf(2.0 - 0.07 * k as f64 * (1.0 + j as f64 / 5.0)),
                    )
                });
                Series::new(format!("run {j}"), pts.collect(), palette(j))
            })
            .collect(),
        ..Chart::default()
    };
    wide.render().save_png(&dir.join("many_decades.png")).unwrap();
    let odd = Chart {
        title: "Edge cases".into(),
        x_label: "x".into(),
        y_label: "y".into(),
        series: vec![
            Series::new("empty", vec![], palette(0)),
            Series::new("constant", vec![(0.0, 5.0), (1.0, 5.0), (2.0, 5.0)], palette(1)),
            Series::new("one point", vec![(1.5, 5.2)], palette(2)),
            Series::new(
                "NaN gap",
                vec![(0.0, 4.8), (0.5, 4.9), (1.0, f64::NAN), (1.5, 4.9), (2.0, 4.8)],
                palette(3),
            )
            .with_style(Style::LineMarkers),
        ],
        ..Chart::default()
    };
    odd.render().save_png(&dir.join("edge_cases.png")).unwrap();
    let pts: Vec<(f64, f64)> = (0..200_000)
        .map(|k| (k as f64, (k as f64 * 0.01).sin() * 1e3))
        .collect();
    let large = Chart {
        series: vec![
            Series::new("200k points", pts.clone(), palette(0)).with_style(Style::LineMarkers),
            Series::new("dashed", pts, palette(1)).with_style(Style::Dashed),
        ],
        x_range: Some((1000.0, 2000.0)),
        width: 1600,
        height: 1000,
        ..Chart::default()
    };
    large.render().save_png(&dir.join("large_zoomed.png")).unwrap();
    grid_of(vec![demo().render(), lin.render(), b.render(), many.render()], 2)
        .save_png(&dir.join("grid.png"))
        .unwrap();
}
