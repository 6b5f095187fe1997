//! Tests of the transactional outputs (`super`).

use super::*;

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("softbody-outdir-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn files_commit_together_or_restore_the_earlier_ones() {
    let d = scratch("files");
    let (a, b) = (d.join("a.csv"), d.join("a.cameras.json"));
    std::fs::write(&a, "old a").unwrap();
    let files = OutFiles::begin(&[a.clone(), b.clone()], &[]).unwrap();
    assert!(OutFiles::begin(std::slice::from_ref(&a), &[])
        .unwrap_err()
        .contains("is in use by process"));
    std::fs::write(files.path(&a), "new a").unwrap();
    std::fs::write(files.path(&b), "new b").unwrap();
    // the second target turns into a folder after the work began: the first is restored
    std::fs::create_dir(&b).unwrap();
    assert!(files.commit().unwrap_err().contains("a.cameras.json"));
    assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
    std::fs::remove_dir(&b).unwrap();
    let mut names: Vec<String> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["a.csv"], "no temporary, backup or lock file left");
}

#[test]
fn no_output_replaces_an_input() {
    let d = scratch("inputs");
    let scene = d.join("s.toml");
    std::fs::write(&scene, "scene").unwrap();
    let inputs = [scene.clone()];
    // the same file, by its own path, another spelling, a symbolic and a hard link
    let other = d.join(".").join("s.toml");
    let soft = d.join("soft.toml");
    let hard = d.join("hard.toml");
    std::os::unix::fs::symlink(&scene, &soft).unwrap();
    std::fs::hard_link(&scene, &hard).unwrap();
    for t in [&scene, &other, &soft, &hard] {
        let e = OutFiles::begin(std::slice::from_ref(t), &inputs).unwrap_err();
        assert!(e.contains("is an input of this run"), "{e}");
    }
    // a report folder that holds an input (here: one written by softbody before)
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join(MARKER), "").unwrap();
    let obs = out.join("obs.csv");
    std::fs::write(&obs, "frame,x,y,z\n").unwrap();
    let e = OutDir::begin(&out, &[scene.clone(), obs.clone()]).unwrap_err();
    assert!(e.contains("holds an input of this run"), "{e}");
    assert!(OutDir::begin(&out, std::slice::from_ref(&scene)).is_ok());
    assert_eq!(std::fs::read_to_string(&scene).unwrap(), "scene");
    assert_eq!(std::fs::read_to_string(&obs).unwrap(), "frame,x,y,z\n");
    // a new target holds nothing
    assert!(OutFiles::begin(&[d.join("new.csv")], &inputs).is_ok());
}

#[test]
fn a_dropped_dir_leaves_the_earlier_one_and_a_commit_replaces_it() {
    let d = scratch("dir");
    let t = d.join("out");
    let o = OutDir::begin(&t, &[]).unwrap();
    std::fs::write(o.path().join("summary.json"), "1").unwrap();
    let mut v = serde_json::json!({"f": o.path().join("x.png"), "n": [o.path()]});
    o.publish(&mut v);
    assert_eq!(v["f"], t.join("x.png").to_str().unwrap());
    assert_eq!(v["n"][0], t.to_str().unwrap());
    o.commit().unwrap();
    let o = OutDir::begin(&t, &[]).unwrap();
    std::fs::write(o.path().join("summary.json"), "2").unwrap();
    drop(o);
    assert_eq!(std::fs::read_to_string(t.join("summary.json")).unwrap(), "1");
    let o = OutDir::begin(&t, &[]).unwrap();
    std::fs::write(o.path().join("other.json"), "3").unwrap();
    o.commit().unwrap();
    assert!(
        !t.join("summary.json").exists(),
        "the earlier folder is replaced as a whole"
    );
    assert!(t.join(MARKER).exists());
    let names: Vec<_> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["out"]);
}

#[test]
fn a_nested_folder_moves_in_with_its_outer_one() {
    let d = scratch("nested");
    let t = d.join("out");
    let o = OutDir::begin(&t, &[]).unwrap();
    // a name that is not one plain folder name never leaves the outer folder
    for bad in ["..", ".", "a/b", "", "/abs"] {
        assert!(o.nested(bad).is_err(), "{bad:?}");
    }
    let kept = o.nested("kept").unwrap();
    std::fs::write(kept.path().join("diagnosis.json"), "1").unwrap();
    kept.commit().unwrap();
    // one that fails is removed with what it held
    let failed = o.nested("failed").unwrap();
    std::fs::write(failed.path().join("x"), "2").unwrap();
    drop(failed);
    // no lock or temporary name inside the outer folder, and a name is made once
    assert!(o.nested("kept").is_err());
    let inside: Vec<_> = std::fs::read_dir(o.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(inside, ["kept"]);
    o.commit().unwrap();
    assert!(t.join("kept").join(MARKER).is_file());
    assert_eq!(
        std::fs::read_to_string(t.join("kept").join("diagnosis.json")).unwrap(),
        "1"
    );
}
