//! The SVG twin of a chart: the same size and layout as the raster picture, every element
//! balanced, lines and markers inside the plot, text escaped.

use super::canvas::svg_grid;
use super::*;

/// `(x, y)` pairs of every `points="..."` and `cx/cy` of the document.
fn coordinates(doc: &str) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for part in doc.split("points=\"").skip(1) {
        let list = &part[..part.find('"').unwrap()];
        for xy in list.split(' ') {
            let (x, y) = xy.split_once(',').unwrap();
            out.push((x.parse().unwrap(), y.parse().unwrap()));
        }
    }
    for part in doc.split("<circle cx=\"").skip(1) {
        let x: f64 = part[..part.find('"').unwrap()].parse().unwrap();
        let rest = &part[part.find("cy=\"").unwrap() + 4..];
        out.push((x, rest[..rest.find('"').unwrap()].parse().unwrap()));
    }
    out
}

fn balanced(doc: &str) {
    assert_eq!(doc.matches("<svg").count(), doc.matches("</svg>").count());
    assert_eq!(doc.matches("<text").count(), doc.matches("</text>").count());
    for tag in ["<rect", "<polyline", "<circle"] {
        for part in doc.split(tag).skip(1) {
            assert!(
                part.find("/>").unwrap() < part.find('<').unwrap_or(usize::MAX),
                "{tag}{part}"
            );
        }
    }
}

#[test]
fn svg_twin_has_the_raster_layout() {
    let mut chart = Chart {
        title: "rms <per> frame & fit".into(),
        x_label: "frame".into(),
        y_label: "rms distance".into(),
        series: vec![
            Series::new(
                "line",
                (0..30).map(|k| (k as f64, (k as f64 * 0.3).sin())).collect(),
                palette(0),
            ),
            Series::new("dots", (0..30).map(|k| (k as f64, 0.5)).collect(), palette(1))
                .with_style(Style::Markers),
            Series::new("dashes", vec![(0.0, -0.5), (29.0, 0.5)], palette(2)).with_style(Style::Dashed),
        ],
        hlines: vec![(0.25, "noise floor".into(), [150, 150, 150])],
        ..Chart::default()
    };
    // a fixed x range cuts the series: what lies outside the plot is clipped
    chart.x_range = Some((5.0, 20.0));
    let svg = chart.render_svg();
    let img = chart.render();
    assert_eq!((svg.width, svg.height), (img.width, img.height));
    let doc = svg.document();
    balanced(&doc);
    let ([x0, y0, x1, y1], [ya, xa]) = chart.plot_area();
    let pts = coordinates(&doc);
    assert!(pts.len() > 30, "{}", pts.len());
    for (x, y) in pts {
        let inside = (x0 as f64 - 1e-6..=x1 as f64 + 1e-6).contains(&x)
            && (y0 as f64 - 1e-6..=y1 as f64 + 1e-6).contains(&y);
        // the legend's samples lie inside the plot too (the legend is drawn in its corner)
        assert!(inside, "({x}, {y}) outside [{x0}, {x1}] x [{y0}, {y1}]");
    }
    // the markers in the range: 16 frames (5..=20), plus one in the legend
    assert_eq!(doc.matches("<circle").count(), 16 + 1);
    assert!(doc.contains("stroke-dasharray"));
    // every tick label and title is a text element; the y label is turned
    for (_, label) in ya.ticks.iter().chain(&xa.ticks) {
        assert!(doc.contains(&format!(">{label}</text>")), "{label}");
    }
    assert!(doc.contains(">rms &lt;per&gt; frame &amp; fit</text>"));
    assert!(doc.contains("rotate(-90)\" font-size") && doc.contains(">rms distance</text>"));
    for label in ["line", "dots", "dashes", "noise floor"] {
        assert!(doc.contains(&format!(">{label}</text>")), "{label}");
    }
}

#[test]
fn svg_grid_places_charts_as_the_raster_grid() {
    let small = Chart {
        width: 300,
        height: 200,
        ..Chart::default()
    };
    let big = Chart::default();
    let charts = [small.clone(), big.clone(), small];
    let img = grid_of(charts.iter().map(Chart::render).collect(), 2);
    let svg = svg_grid(charts.iter().map(Chart::render_svg).collect(), 2);
    assert_eq!((svg.width, svg.height), (img.width, img.height));
    let doc = svg.document();
    balanced(&doc);
    // cells of 640 x 400 at 8-pixel gaps; the small charts centred in theirs
    for at in ["x=\"178\" y=\"108\"", "x=\"656\" y=\"8\"", "x=\"178\" y=\"516\""] {
        assert!(doc.contains(&format!("<svg {at}")), "{at}\n{doc}");
    }
    let bars = BarChart {
        bars: vec![("a".into(), 1.0, palette(0)), ("b".into(), f64::NAN, palette(1))],
        ..BarChart::default()
    };
    let doc = bars.render_svg().document();
    balanced(&doc);
    assert!(doc.contains(">n/a</text>") && doc.contains(">a</text>"));
    // an empty chart is a white picture of its size
    let empty = Chart {
        width: 0,
        ..Chart::default()
    };
    assert_eq!(empty.render_svg().width, 0);
}
