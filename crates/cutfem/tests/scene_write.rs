//! The scene writer (`Scene::to_toml`, `Scene::write`): every scene file of the repository
//! reads back as the same scene, in its own folder and in another one (paths made absolute),
//! and a failed write leaves nothing behind.

use cutfem::scene::Scene;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Every `*.toml` below `dir` that is not a Cargo or rustfmt file.
fn scene_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            scene_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "toml") {
            out.push(p);
        }
    }
}

fn all_scenes() -> Vec<PathBuf> {
    let mut files = Vec::new();
    scene_files(&root().join("examples/scenes"), &mut files);
    scene_files(&root().join("tests/reference_values/independent"), &mut files);
    files
}

/// The scene as read from `text` at `path`, with the extensions' line numbers cleared.
fn read(text: &str, path: &Path) -> Scene {
    let mut s = Scene::parse(text, path).unwrap_or_else(|e| panic!("{e}\n{text}"));
    for x in s.extensions.values_mut() {
        x.line = 0;
    }
    s
}

#[test]
fn every_repository_scene_reads_back_the_same_in_its_own_folder() {
    let files = all_scenes();
    assert!(files.len() >= 15, "{files:?}");
    for f in files {
        let scene = read(&std::fs::read_to_string(&f).unwrap(), &f);
        let text = scene.to_toml(&f).unwrap();
        assert_eq!(read(&text, &f), scene, "{}:\n{text}", f.display());
        // a second round gives the same text (the writer is a fixed point)
        assert_eq!(read(&text, &f).to_toml(&f).unwrap(), text, "{}", f.display());
    }
}

#[test]
fn a_scene_written_elsewhere_keeps_its_body_file() {
    let dir = std::env::temp_dir().join(format!("scene-write-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut files = 0;
    for f in all_scenes() {
        let scene = read(&std::fs::read_to_string(&f).unwrap(), &f);
        let Some(original) = scene.body.sdf.clone().or(scene.body.mesh.clone()) else {
            continue;
        };
        let target = dir.join("moved.toml");
        scene.write(&target).unwrap();
        let moved = Scene::load(&target).unwrap();
        let now = moved.body.sdf.clone().or(moved.body.mesh.clone()).unwrap();
        assert!(now.is_absolute(), "{}", now.display());
        assert_eq!(
            now.canonicalize().unwrap(),
            scene.dir.join(&original).canonicalize().unwrap(),
            "{}",
            f.display()
        );
        assert_eq!(moved.material, scene.material);
        assert_eq!(
            moved.extensions.keys().collect::<Vec<_>>(),
            scene.extensions.keys().collect::<Vec<_>>()
        );
        files += 1;
    }
    assert!(files >= 5, "{files} scenes with a body file");
    // nothing but the written file is left in the folder (no temporary files)
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, vec![std::ffi::OsString::from("moved.toml")]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn changed_values_and_sections_are_written() {
    let f = root().join("examples/scenes/swinging_torus.toml");
    let mut scene = Scene::load(&f).unwrap();
    scene.material.young = 1234.5678901234567;
    scene.material.poisson = 0.123456789012345;
    scene.ground = Some(cutfem::scene::GroundSection {
        normal: [0.0, 1.0, 0.0],
        height: -0.25,
        stiffness: Some(3.0e4),
        softness: Some(50.0),
        scheme: cutfem::fem::collision::ContactScheme::Penalty,
    });
    scene.numerics.cg_tolerance = 1e-9;
    let text = scene.to_toml(&f).unwrap();
    let back = Scene::parse(&text, &f).unwrap();
    // bit-for-bit floats, the new section and the changed numerics
    assert_eq!(back.material.young.to_bits(), 1234.5678901234567f64.to_bits());
    assert_eq!(back.material.poisson.to_bits(), 0.123456789012345f64.to_bits());
    assert_eq!(back.ground, scene.ground);
    assert_eq!(back.numerics.cg_tolerance, 1e-9);
    assert!(text.contains("scheme = \"penalty\""), "{text}");
}

#[test]
fn a_write_into_a_missing_folder_fails_with_the_path_and_leaves_nothing() {
    let f = root().join("examples/scenes/swinging_torus.toml");
    let scene = Scene::load(&f).unwrap();
    let target = std::env::temp_dir()
        .join(format!("no-such-folder-{}", std::process::id()))
        .join("s.toml");
    let e = scene.write(&target).unwrap_err().to_string();
    assert!(e.contains("no-such-folder"), "{e}");
    assert!(!target.parent().unwrap().exists());
}

/// `[fit]` is a typed section: read with its values, refused on load (by every command, not
/// only `fit`) with an error naming the key, and written back.
#[test]
fn the_fit_section_is_typed_checked_on_load_and_written() {
    let base = "[body]\nshape = { kind = \"sphere\", center = [0.0, 1.0, 0.0], radius = 0.3 }\n\
                resolution = 10\n[material]\nyoung = 2000.0\npoisson = 0.3\ndensity = 1.0\n";
    let path = Path::new("fit_section.toml");
    let good = format!(
        "{base}[fit]\nparameters = [\"young\", \"poisson\"]\noptimizer = \"gauss-newton\"\niterations = 7\n"
    );
    let s = Scene::parse(&good, path).unwrap();
    let fit = s.fit.clone().unwrap();
    assert_eq!(
        fit.parameters.as_deref(),
        Some(&["young".to_string(), "poisson".to_string()][..])
    );
    assert_eq!(
        (fit.optimizer.as_deref(), fit.iterations),
        (Some("gauss-newton"), Some(7))
    );
    let text = s.to_toml(path).unwrap();
    assert!(
        text.contains("[fit]") && text.contains("iterations = 7"),
        "{text}"
    );
    assert_eq!(read(&text, path), read(&good, path));
    for (section, needle) in [
        (
            "[fit]\niteration = 7\n",
            "[fit].iteration: unknown key (known: parameters, optimizer, iterations)",
        ),
        (
            "[fit]\nparameters = [1]\n",
            "[fit].parameters must be a list of names",
        ),
        ("[fit]\noptimizer = 3\n", "[fit].optimizer must be a string"),
        (
            "[fit]\niterations = -1\n",
            // the declared range of every numeric key (`cutfem::scene::ranges`), with its line
            "line 9: fit.iterations: must be in [0, 1e6]",
        ),
        ("fit = 3\n", "[fit] must be a table"),
    ] {
        let text = if section.starts_with('[') {
            format!("{base}{section}")
        } else {
            format!("{section}{base}")
        };
        let e = Scene::parse(&text, path).unwrap_err().to_string();
        assert!(
            e.contains(needle) && e.contains("fit_section.toml") && !e.contains('\n'),
            "{e}"
        );
    }
}
