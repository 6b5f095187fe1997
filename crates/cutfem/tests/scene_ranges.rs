//! Issue 51: every numeric key of a scene has a declared range (`cutfem::scene::ranges`),
//! checked in one place with the file, the line and the key in the message. Two tests over the
//! whole class: every declared range refuses the values just outside each of its ends (and
//! accepts its ends where they are closed), and every numeric key that a complete scene can
//! hold (every core section written from a scene value, every shape, every effect section of
//! this crate, the example scenes) is declared.

use cutfem::scene::ranges::{numeric_keys, range_of, KeyRange, RANGES};
use cutfem::scene::Scene;
use std::path::{Path, PathBuf};

/// Keys whose values are integers.
const INTEGER: [&str; 6] = [
    "time.steps",
    "time.substeps",
    "model.stiffness_field.cells",
    "fit.iterations",
    "numerics.cg_max_iterations",
    "numerics.surface_subdivision",
];

/// TOML with `key` (dotted) set to the literal `value`: `[[dirichlet]]` for the boxes, an
/// inline table for a nested key.
fn text_with(key: &str, value: &str) -> String {
    let parts: Vec<&str> = key.split('.').collect();
    let header = match parts[0] {
        "dirichlet" => "[[dirichlet]]".to_string(),
        s => format!("[{s}]"),
    };
    let body = match parts.len() {
        2 => format!("{} = {value}", parts[1]),
        3 => format!("{} = {{ {} = {value} }}", parts[1], parts[2]),
        n => panic!("{key}: {n} parts"),
    };
    format!("# a scene\n{header}\n{body}\n")
}

fn literal(key: &str, v: f64) -> String {
    if INTEGER.contains(&key) {
        format!("{}", v as i64)
    } else {
        format!("{v:?}")
    }
}

/// Values just outside the range's finite ends.
fn outside(r: &KeyRange) -> Vec<f64> {
    let int = INTEGER.contains(&r.key);
    let mut out = Vec::new();
    let (lo, hi) = (r.min, r.max);
    if lo.value.is_finite() {
        out.push(match (lo.closed, int) {
            (false, _) => lo.value,
            (true, true) => lo.value - 1.0,
            (true, false) if lo.value == 0.0 => -1e-9,
            (true, false) => lo.value * (1.0 - 1e-6),
        });
    }
    if hi.value.is_finite() {
        out.push(match (hi.closed, int) {
            (false, _) => hi.value,
            (true, true) => hi.value + 1.0,
            (true, false) => hi.value * (1.0 + 1e-6),
        });
    }
    out
}

#[test]
fn every_declared_range_refuses_what_lies_outside_naming_file_line_and_key() {
    let path = Path::new("dir/s.toml");
    let mut checked = 0;
    for r in RANGES {
        for v in outside(r) {
            let text = text_with(r.key, &literal(r.key, v));
            let e = Scene::parse(&text, path).expect_err(&text).to_string();
            let says = format!("dir/s.toml: line 3: {}: must be", r.key);
            assert!(e.starts_with(&says), "{}: {e}", r.key);
            assert!(!r.contains(v), "{}: {v}", r.key);
            checked += 1;
        }
        // the closed ends belong to the range
        for end in [r.min, r.max].into_iter().filter(|e| e.closed) {
            assert!(r.contains(end.value), "{}", r.key);
        }
    }
    let bounded = RANGES
        .iter()
        .filter(|r| r.min.value.is_finite() || r.max.value.is_finite())
        .count();
    assert!(checked >= bounded, "{checked} of {bounded}");
    // the reported case: a tolerance that does no iteration
    let e = Scene::parse(&text_with("numerics.cg_tolerance", "1.0"), path)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("numerics.cg_tolerance: must be in [1e-16, 0.001]"),
        "{e}"
    );
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn every_numeric_key_a_scene_can_hold_is_declared() {
    let mut texts: Vec<String> = Vec::new();
    // every example scene
    let dir = root().join("examples/scenes");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.extend(
        std::fs::read_dir(dir.join("fit"))
            .unwrap()
            .map(|e| e.unwrap().path()),
    );
    for f in files
        .iter()
        .filter(|f| f.extension().is_some_and(|e| e == "toml"))
    {
        texts.push(std::fs::read_to_string(f).unwrap());
    }
    // every core section and key, written from a scene value with every option set
    let mut scene = Scene::load(&root().join("examples/scenes/cantilever.toml")).unwrap();
    scene.ground = Some(cutfem::scene::GroundSection {
        normal: [0.0, 1.0, 0.0],
        height: -1.0,
        stiffness: Some(1.0),
        softness: Some(1.0),
        scheme: Default::default(),
    });
    scene.initial = Some(Default::default());
    scene.body.origin = Some([0.0; 3]);
    scene.body.spacing = Some(0.1);
    scene.body.resolution = Some(10.0);
    scene.fit = Some(cutfem::scene::FitSection {
        iterations: Some(3),
        ..Default::default()
    });
    if let Some(m) = scene.model.as_mut() {
        m.stiffness_field = Some(cutfem::scene::StiffnessFieldSection { cells: [2, 2, 2] });
    }
    scene.numerics.nitsche_eta = Some(1.0);
    scene.numerics.nitsche_gamma = Some(1.0);
    texts.push(toml::to_string(&scene).unwrap());
    // every shape
    for shape in [
        "{ kind = \"box\", center = [0.0, 0.0, 0.0], size = [1.0, 1.0, 1.0] }",
        "{ kind = \"sphere\", center = [0.0, 0.0, 0.0], radius = 1.0 }",
        "{ kind = \"torus\", center = [0.0, 0.0, 0.0], axis = [0.0, 1.0, 0.0], major = 1.0, minor = 0.2 }",
        "{ kind = \"capsule\", a = [0.0, 0.0, 0.0], b = [1.0, 0.0, 0.0], radius = 0.2 }",
    ] {
        let shape: cutfem::shapes::Shape = toml::from_str::<toml::Table>(&format!("s = {shape}")).unwrap()
            ["s"]
            .clone()
            .try_into()
            .unwrap();
        texts.push(format!(
            "[body]\nshape = {}\n",
            toml::Value::try_from(shape).unwrap()
        ));
    }
    // every effect section of this crate, written from its type
    let sections = [
        (
            "drag",
            toml::Value::try_from(cutfem::scene::effects::drag::DragSection { coefficient: 1.0 }),
        ),
        (
            "clamp",
            toml::Value::try_from(cutfem::scene::effects::clamp::ClampSection { stiffness: 1.0 }),
        ),
        (
            "friction",
            toml::Value::try_from(cutfem::scene::effects::friction::FrictionSection { coefficient: 1.0 }),
        ),
        (
            "wind",
            toml::Value::try_from(cutfem::scene::effects::wind::WindSection { traction: [1.0; 3] }),
        ),
    ];
    for (name, v) in sections {
        let mut t = toml::Table::new();
        t.insert(name.into(), v.unwrap());
        texts.push(toml::to_string(&t).unwrap());
    }
    let mut keys: Vec<String> = texts.iter().flat_map(|t| numeric_keys(t)).collect();
    keys.sort();
    keys.dedup();
    let missing: Vec<&String> = keys.iter().filter(|k| range_of(k).is_none()).collect();
    assert!(
        missing.is_empty(),
        "numeric keys without a declared range: {missing:?}"
    );
    // and the table declares nothing a scene cannot hold
    let stale: Vec<&str> = RANGES
        .iter()
        .map(|r| r.key)
        .filter(|k| !keys.iter().any(|x| x == k))
        .collect();
    assert!(stale.is_empty(), "declared but never met: {stale:?}");
}
