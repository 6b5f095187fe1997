//! Tests of the diagnosis pictures on a synthetic diagnosis of a sphere whose +x half is
//! observed outside the model (positive residuals) and whose -x half inside (negative).

use super::charts::*;
use super::*;
use adjoint::diagnosis::effects::Probe;
use adjoint::diagnosis::residuals::{PointResidual, Region};
use adjoint::diagnosis::score::Candidate;
use cutfem::fem::Model;
use cutfem::scene::Scene;

/// A UV sphere of radius `r` around `c`.
fn sphere(c: [f64; 3], r: f64, rings: usize, segments: usize) -> TriMesh {
    let mut vertices = vec![[c[0], c[1] + r, c[2]]];
    for i in 1..rings {
        let phi = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let th = std::f64::consts::TAU * j as f64 / segments as f64;
            vertices.push([
                c[0] + r * phi.sin() * th.cos(),
                c[1] + r * phi.cos(),
                c[2] + r * phi.sin() * th.sin(),
            ]);
        }
    }
    vertices.push([c[0], c[1] - r, c[2]]);
    let last = (vertices.len() - 1) as u32;
    let ring = |i: usize, j: usize| (1 + (i - 1) * segments + j % segments) as u32;
    let mut faces = Vec::new();
    for j in 0..segments {
        faces.push([0, ring(1, j + 1), ring(1, j)]);
        faces.push([last, ring(rings - 1, j), ring(rings - 1, j + 1)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            let (a, b, c2, d) = (ring(i, j), ring(i, j + 1), ring(i + 1, j), ring(i + 1, j + 1));
            faces.push([a, b, d]);
            faces.push([a, d, c2]);
        }
    }
    TriMesh { vertices, faces }
}

const CENTER: [f64; 3] = [0.0, 1.0, 0.0];

/// Points on the sphere over 6 frames: residual `+0.01` on the +x half, `-0.01` on the -x
/// half (growing a little over time), a few outside points.
fn records() -> Vec<PointResidual> {
    let mut out = Vec::new();
    for frame in 0..6 {
        let mut k = 0u64;
        for i in 1..30 {
            for j in 0..60 {
                let phi = std::f64::consts::PI * (i as f64 + 0.37) / 30.5;
                let th = std::f64::consts::TAU * (j as f64 + 0.21) / 60.0;
                let n = [phi.sin() * th.cos(), phi.cos(), phi.sin() * th.sin()];
                let q = [0, 1, 2].map(|d| CENTER[d] + 0.5 * n[d]);
                let size = (0.01 + 0.001 * frame as f64) * n[0].signum();
                let v = n.map(|x| x * size);
                k += 1;
                out.push(PointResidual {
                    frame,
                    camera: Some((k % 3) as u32),
                    position: [0, 1, 2].map(|d| q[d] + v[d]),
                    residual: size,
                    vector: v,
                    reference: q,
                    outside: k % 997 == 0,
                });
            }
        }
    }
    out
}

fn diagnosis() -> Diagnosis {
    let text = "[body]\nshape = { kind = \"sphere\", center = [0.0, 1.0, 0.0], radius = 0.5 }\n\
                resolution = 8\n[material]\nyoung = 1000.0\npoisson = 0.3\n";
    let scene = Scene::parse(text, Path::new("/tmp/diagnose-report-test.toml")).expect("scene");
    let records = records();
    let per_frame: Vec<(usize, f64, usize)> = (0..6)
        .map(|f| {
            let (r, n) = adjoint::diagnosis::residuals::rms(records.iter().filter(|r| r.frame == f));
            (f, r, n)
        })
        .collect();
    let direction = adjoint::diagnosis::residuals::direction(&records);
    let regions = vec![
        Region {
            id: 0,
            center: [0.45, 1.0, 0.1],
            points: 100,
            rms: 0.01,
            mean: 0.01,
            mean_vector: [0.01, 0.0, 0.0],
        },
        Region {
            id: 1,
            center: [-0.45, 1.0, 0.1],
            points: 100,
            rms: 0.01,
            mean: -0.01,
            mean_vector: [0.01, 0.0, 0.0],
        },
    ];
    let candidate = |effect: &str, predicted: f64, after: Option<f64>| Candidate {
        effect: effect.into(),
        probe: Probe::Score,
        params: vec![format!("{effect}.x")],
        score: 100.0,
        predicted_rms: predicted,
        rms_after: after,
        delta_bic: after.map(|_| -50.0),
        values: Vec::new(),
        suggestion: String::new(),
        error: None,
        model: None,
        scene: None,
        frees: Vec::new(),
        step: Vec::new(),
        x: Vec::new(),
    };
    let rms = adjoint::diagnosis::residuals::rms(records.iter()).0;
    Diagnosis {
        effects: vec!["corotation".into()],
        fitted: vec![("young".into(), 1000.0), ("poisson".into(), 0.3)],
        rms_start: 0.05,
        rms,
        noise_floor: Some(0.001),
        noise_floor_method: "depth images",
        noise_floor_std_error: None,
        on_bounds: Vec::new(),
        ground_push: None,
        per_frame,
        per_camera: vec![(0, rms, 1), (1, rms, 1), (2, rms, 1)],
        regions,
        direction,
        worst_frame: 5,
        records,
        unverified: None,
        candidates: vec![
            candidate("gravity", 0.004, Some(0.003)),
            candidate("damping", 0.008, None),
            candidate("initial_velocity", 0.0101, None),
        ],
        missing_effect: Some("gravity".into()),
        alternatives: Vec::new(),
        separation: None,
        plausibility: Vec::new(),
        verdict: "missing: gravity".into(),
        model: Model::default(),
        fitted_scene: scene,
        base_params: adjoint::params::ParamSet::parse(&["young", "poisson"]).expect("params"),
        base_x: vec![0.0, 0.0],
        base_x_start: vec![0.0, 0.0],
    }
}

fn history_entries() -> Vec<Entry> {
    let entry = |effects: &[&str], rms: f64, floor: Option<f64>| Entry {
        time: "2024-01-01T00:00:00Z".into(),
        command: "diagnose".into(),
        effects: effects.iter().map(|e| e.to_string()).collect(),
        parameters: vec![("young".into(), 1000.0)],
        rms,
        noise_floor: floor,
        missing_effect: None,
        observations: None,
    };
    vec![
        entry(&["corotation"], 0.05, None),
        entry(&["corotation"], 0.02, Some(0.001)),
        entry(&["corotation", "gravity"], 0.004, Some(0.001)),
        entry(&["corotation", "gravity", "damping"], 0.0012, Some(0.001)),
    ]
}

fn paths_all_history(dir: &Path) -> PathBuf {
    dir.join("history.png")
}

/// Width and height from a PNG file's header.
fn png_size(path: &Path) -> (usize, usize) {
    let bytes = std::fs::read(path).expect("png");
    assert_eq!(&bytes[1..4], b"PNG", "{}", path.display());
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]) as usize;
    (be(&bytes[16..20]), be(&bytes[20..24]))
}

fn is_red(c: [u8; 3]) -> bool {
    c[0] as i32 > c[2] as i32 + 50 && c[0] as i32 > c[1] as i32 + 20
}

fn is_blue(c: [u8; 3]) -> bool {
    c[2] as i32 > c[0] as i32 + 50
}

/// Count and mean x of the pixels of `img` in the rectangle that satisfy `f`.
fn census(img: &Image, x: (usize, usize), y: (usize, usize), f: fn([u8; 3]) -> bool) -> (usize, f64) {
    let mut n = 0;
    let mut sx = 0.0;
    for yy in y.0..y.1 {
        for xx in x.0..x.1 {
            if f(img.pixel(xx, yy)) {
                n += 1;
                sx += xx as f64;
            }
        }
    }
    (n, sx / n.max(1) as f64)
}

fn tmp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("softbody-diagnose-report-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn every_picture_is_written_with_its_size() {
    let d = diagnosis();
    let reference = sphere(CENTER, 0.5, 24, 48);
    let worst = sphere(CENTER, 0.49, 24, 48);
    let runs = history_entries();
    let inputs = PictureInputs {
        reference: &reference,
        worst: &worst,
        gravity: Some([0.0, -9.81, 0.0]),
        history: &runs,
    };
    let dir = tmp_dir("all");
    let paths = write_pictures(&dir, &d, &inputs).expect("pictures");
    let names: Vec<String> = paths
        .iter()
        .map(|p| p.file_name().unwrap_or_default().to_string_lossy().into_owned())
        .collect();
    let expected = [
        "rms_over_time.png",
        "surface_residual.png",
        "worst_frame.png",
        "residual_direction.png",
        "history.png",
        "candidates.png",
    ];
    assert_eq!(names, expected);
    let images = [
        rms_over_time(&d).render(),
        surface_residual(&d, &reference),
        worst_frame(&d, &worst),
        residual_direction(&d, inputs.gravity).png,
        history(&runs).png,
        candidates(&d).png,
    ];
    let widths = [800, 8 + 3 * (VIEW + 8), 8 + 2 * (VIEW + 8), 800, 800, 800];
    for ((path, img), w) in paths.iter().zip(&images).zip(widths) {
        let (pw, ph) = png_size(path);
        assert_eq!((pw, ph), (img.width, img.height), "{}", path.display());
        assert_eq!(pw, w, "{}", path.display());
        assert!((440..=700).contains(&ph), "{}: height {ph}", path.display());
    }
    // the charts have SVG twins of the same size; the surface renderings do not
    for (path, img) in paths.iter().zip(&images) {
        let svg = std::fs::read_to_string(path.with_extension("svg"));
        let name = path.file_name().unwrap_or_default().to_string_lossy();
        if name.starts_with("surface") || name.starts_with("worst") {
            assert!(svg.is_err(), "{name}");
            continue;
        }
        let svg = svg.expect("svg twin");
        let head = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\"",
            img.width, img.height
        );
        assert!(svg.starts_with(&head), "{name}: {}", &svg[..100]);
        assert!(
            svg.contains("<polyline") && svg.trim_end().ends_with("</svg>"),
            "{name}"
        );
        assert_eq!(
            svg.matches("<svg").count(),
            svg.matches("</svg>").count(),
            "{name}"
        );
    }
    let rms = std::fs::read_to_string(dir.join("rms_over_time.svg")).unwrap();
    assert!(rms.contains(">noise floor</text>"));
    let cands = std::fs::read_to_string(dir.join("candidates.svg")).unwrap();
    assert!(cands.contains(">after refit</text>") && cands.contains(">predicted</text>"));
    // without history there is no history picture
    let inputs = PictureInputs {
        history: &[],
        ..inputs
    };
    let dir2 = tmp_dir("nohistory");
    let paths = write_pictures(&dir2, &d, &inputs).expect("pictures");
    assert_eq!(paths.len(), 5);
    assert!(!dir2.join("history.png").exists());
    let alone = dir2.join("history_alone.png");
    write_history_picture(&alone, &runs).expect("history picture");
    assert_eq!(png_size(&alone), png_size(&paths_all_history(&dir)));
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&dir2);
}

#[test]
fn surface_is_red_where_outside_and_blue_where_inside() {
    let d = diagnosis();
    let reference = sphere(CENTER, 0.5, 24, 48);
    let img = surface_residual(&d, &reference);
    let title = text_block(img.width, SURFACE_TITLE, 2, true).png.height;
    // first view: azimuth 0.5 rad from +z, so +x is on the right of the picture
    let (xs, ys) = ((8, 8 + VIEW), (title + 8, title + 8 + VIEW));
    let (reds, red_x) = census(&img, xs, ys, is_red);
    let (blues, blue_x) = census(&img, xs, ys, is_blue);
    let mid = (8 + VIEW / 2) as f64;
    assert!(reds > 2000 && blues > 2000, "red {reds}, blue {blues}");
    assert!(red_x > mid + 20.0, "red at x {red_x}, centre {mid}");
    assert!(blue_x < mid - 20.0, "blue at x {blue_x}, centre {mid}");
    // the colour bar: blue on its left, red on its right
    let bar = (title + 8 + VIEW + 8, img.height);
    let (_, bar_red) = census(&img, (0, img.width), bar, is_red);
    let (_, bar_blue) = census(&img, (0, img.width), bar, is_blue);
    assert!(bar_red > bar_blue);
}

#[test]
fn worst_frame_dots_are_coloured_by_sign() {
    let d = diagnosis();
    let worst = sphere(CENTER, 0.49, 24, 48);
    let img = worst_frame(&d, &worst);
    let title = text_block(img.width, "worst frame", 2, true).png.height;
    let (xs, ys) = ((8, 8 + VIEW), (title + 8, title + 8 + VIEW));
    let (reds, red_x) = census(&img, xs, ys, is_red);
    let (blues, blue_x) = census(&img, xs, ys, is_blue);
    assert!(reds > 300 && blues > 300, "red {reds}, blue {blues}");
    assert!(red_x > blue_x);
}

#[test]
fn empty_meshes_and_diagnosis_still_draw() {
    let mut d = diagnosis();
    d.records.clear();
    d.per_frame.clear();
    d.candidates.clear();
    d.regions.clear();
    d.direction.per_frame.clear();
    let empty = TriMesh {
        vertices: Vec::new(),
        faces: Vec::new(),
    };
    let inputs = PictureInputs {
        reference: &empty,
        worst: &empty,
        gravity: None,
        history: &[],
    };
    let dir = tmp_dir("empty");
    let paths = write_pictures(&dir, &d, &inputs).expect("pictures");
    assert_eq!(paths.len(), 5);
    assert!(paths.iter().all(|p| p.exists()));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn unwritable_directory_names_the_path() {
    let d = diagnosis();
    let mesh = sphere(CENTER, 0.5, 6, 12);
    let file = tmp_dir("file");
    std::fs::write(&file, "not a folder").expect("file");
    let inputs = PictureInputs {
        reference: &mesh,
        worst: &mesh,
        gravity: None,
        history: &[],
    };
    let err = write_pictures(&file.join("sub"), &d, &inputs).expect_err("must fail");
    assert!(err.contains("softbody-diagnose-report-file"), "{err}");
    let _ = std::fs::remove_file(&file);
}

#[test]
fn spatial_hash_finds_the_nearest_vertex() {
    let mut seed = 12345u64;
    let mut rnd = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let points: Vec<[f64; 3]> = (0..500).map(|_| [rnd(), 2.0 * rnd(), 0.5 * rnd()]).collect();
    let hash = VertexHash::new(&points).expect("points");
    for _ in 0..300 {
        let p = [3.0 * rnd() - 1.0, 4.0 * rnd() - 1.0, 2.0 * rnd() - 0.75];
        let d2 = |q: &[f64; 3]| (0..3).map(|k| (q[k] - p[k]).powi(2)).sum::<f64>();
        let brute = (0..points.len()).min_by(|&a, &b| d2(&points[a]).total_cmp(&d2(&points[b])));
        let found = hash.nearest(p);
        assert_eq!(d2(&points[found]), d2(&points[brute.expect("some")]));
    }
}

#[test]
fn helpers() {
    assert_eq!(wrap("aa bb cc", 5), vec!["aa bb", "cc"]);
    assert_eq!(
        effect_list(&["initial_velocity".into(), "gravity".into()]),
        "initial_velocity + gravity"
    );
    assert_eq!(change(&["a".into()], &["b".into()]), "+b -a");
    assert_eq!(to_rgb(diverging(0.0)), [247, 247, 247]);
    assert!(diverging(1.0)[0] > diverging(1.0)[2] && diverging(-1.0)[2] > diverging(-1.0)[0]);
    assert!(spans_decade([0.001, 0.5].into_iter()) && !spans_decade([0.1, 0.5].into_iter()));
    assert_eq!(limit_of(&[f64::NAN, 0.0]), 1.0);
    let words = direction_words(&diagnosis(), Some([0.0, -1.0, 0.0]));
    assert!(
        words.starts_with("principal direction (") && words.contains("% of the residual; a uniform shift"),
        "{words}"
    );
    assert!(
        words.contains("rms grows ") && words.contains("angle to gravity "),
        "{words}"
    );
}

/// Writes the pictures of the synthetic diagnosis to look at:
/// `cargo test -p softbody diagnose_report::tests::write_examples -- --ignored`.
#[test]
#[ignore]
fn write_examples() {
    let d = diagnosis();
    let reference = sphere(CENTER, 0.5, 24, 48);
    let worst = sphere(CENTER, 0.49, 24, 48);
    let runs = history_entries();
    let inputs = PictureInputs {
        reference: &reference,
        worst: &worst,
        gravity: Some([0.0, -9.81, 0.0]),
        history: &runs,
    };
    let dir = std::env::temp_dir().join("softbody-diagnose-report-examples");
    let paths = write_pictures(&dir, &d, &inputs).expect("pictures");
    println!("{paths:#?}");
}

/// Failures in plain sight: a candidate whose probe or refit failed is in the printed table
/// with its error and in the JSON's `unchecked`; a discretisation guard that could not run
/// makes the verdict "unverified at 2r" in words and in the JSON's `unverified`.
#[test]
fn failed_candidates_and_guards_are_in_plain_sight() {
    let mut d = diagnosis();
    assert!(crate::diagnose::candidate_row(&d.candidates[1]).starts_with("damping"));
    d.candidates[1].error = Some("the simulation diverged at step 3".into());
    let row = crate::diagnose::candidate_row(&d.candidates[1]);
    assert!(
        row.starts_with("damping") && row.contains("could not be checked: the simulation diverged at step 3"),
        "{row}"
    );
    let v = crate::diagnose::summary_json(&d, &[], None, 1.0);
    assert_eq!(v["unchecked"][0]["effect"], "damping", "{v}");
    assert!(v["unverified"].is_null());

    adjoint::diagnosis::mark_unverified(&mut d, 16.0, "not enough memory for the finer grid");
    assert!(
        d.verdict.starts_with("unverified at 2r: gravity"),
        "{}",
        d.verdict
    );
    assert!(d.verdict.contains("resolution 16") && d.verdict.ends_with("missing: gravity"));
    let v = crate::diagnose::summary_json(&d, &[], None, 1.0);
    assert!(
        v["unverified"].as_str().unwrap().contains("not enough memory"),
        "{v}"
    );
    // what the named effect's values imply, and what each refit freed, are in the JSON
    d.plausibility = vec![adjoint::diagnosis::plausible::Plausibility {
        effect: "gravity".into(),
        implies: "g = 9.81".into(),
        implausible: Some("a test".into()),
    }];
    d.candidates[0].frees = vec![("poisson".into(), 0.28)];
    let v = crate::diagnose::summary_json(&d, &[], None, 1.0);
    assert_eq!(v["plausibility"][0]["implausible"], "a test", "{v}");
    assert_eq!(v["candidates"][0]["frees"]["poisson"], 0.28, "{v}");
    assert!(
        v["candidates"][1]["frees"]
            .as_object()
            .is_some_and(|o| o.is_empty()),
        "{v}"
    );
    // nothing named: nothing to verify
    let mut none = diagnosis();
    none.missing_effect = None;
    adjoint::diagnosis::mark_unverified(&mut none, 16.0, "x");
    assert_eq!(
        (none.verdict.as_str(), none.unverified),
        ("missing: gravity", None)
    );
}
