//! Issue 13, "Messages": an error repeats at most ~100 characters of a bad value, names each
//! key once, says "not a finite number" for every non-finite float of a scene (naming the key
//! and line), says that a path has no extension (listing the supported ones), and `observe`
//! refuses to write an observation file without a point.

use std::path::Path;
mod common;
use common::*;

const BODY: &str =
    "[body]\nshape = { kind = \"sphere\", center = [0.0, 1.0, 0.0], radius = 0.3 }\nresolution = 10\n";
const MATERIAL: &str = "[material]\nyoung = 1000.0\npoisson = 0.3\n";
const TIME: &str = "[time]\ndt = 0.01\nsteps = 2\n";

fn simulate(dir: &Path, text: &str) -> std::process::Output {
    let s = write(dir, "s.toml", text);
    run(&[
        "simulate",
        s.to_str().unwrap(),
        "--out",
        dir.join("out").to_str().unwrap(),
    ])
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn long_bad_values_are_quoted_up_to_100_characters() {
    let dir = tmp("messages", "long");
    let long = "x".repeat(5000);
    let cut = format!("{}…", "x".repeat(100));
    let o = simulate(
        &dir,
        &format!("{BODY}[material]\nyoung = \"{long}\"\npoisson = 0.3\n"),
    );
    one_line_error(
        &o,
        &format!("s.toml: line 5: invalid type: string \"{cut}\", expected f64"),
    );
    assert!(!stderr(&o).contains(&"x".repeat(101)));
    // a CSV field
    let s = write(&dir, "ok.toml", &format!("{BODY}{MATERIAL}{TIME}"));
    let csv = write(&dir, "long.csv", &format!("frame,x,y,z\n1,0,{long},0\n"));
    let o = run_on("fit", &s, &csv, &dir.join("fit"), &[]);
    one_line_error(&o, &format!("long.csv: line 2: y is not a number: \"{cut}\""));
    assert!(stderr(&o).len() < 300, "{}", stderr(&o));
    // a flag
    let o = run(&["observe", s.to_str().unwrap(), "--frames", &long]);
    one_line_error(&o, &format!("--frames: \"{cut}\" is not a frame number"));
    assert!(stderr(&o).len() < 300, "{}", stderr(&o));
}

#[test]
fn each_key_is_named_once() {
    let dir = tmp("messages", "once");
    let bad = "[body]\nshape = { kind = \"sphere\", center = [0.0, 1.0, 0.0], radius = -1.0 }\n";
    let o = simulate(&dir, &format!("{bad}{MATERIAL}"));
    // the declared range of the key (`cutfem::scene::ranges`), with its line
    one_line_error(
        &o,
        "s.toml: line 2: body.shape.radius: must be > 0 (a radius), got -1",
    );
    assert_eq!(stderr(&o).matches("body.shape").count(), 1, "{}", stderr(&o));
}

#[test]
fn non_finite_numbers_are_named_as_such() {
    let dir = tmp("messages", "finite");
    for (extra, needle) in [
        (
            "[ground]\nnormal = [nan, 1.0, 0.0]\n",
            "s.toml: line 8: ground.normal[0]: not a finite number (nan)",
        ),
        (
            "[[dirichlet]]\nmin = [-1.0, 0.0, -1.0]\nmax = [0.0, nan, 1.0]\n",
            "s.toml: line 9: dirichlet[0].max[1]: not a finite number (nan)",
        ),
        (
            "[ground]\nheight = -inf\n",
            "s.toml: line 8: ground.height: not a finite number (-inf)",
        ),
        (
            "[initial]\nvelocity = [0.0, inf, 0.0]\n",
            "s.toml: line 8: initial.velocity[1]: not a finite number (inf)",
        ),
    ] {
        let o = simulate(&dir, &format!("{BODY}{MATERIAL}{extra}"));
        one_line_error(&o, needle);
    }
    let o = simulate(&dir, &format!("{BODY}[material]\nyoung = nan\npoisson = 0.3\n"));
    one_line_error(&o, "s.toml: line 5: material.young: not a finite number (nan)");
}

#[test]
fn a_path_without_an_extension_is_called_so() {
    let dir = tmp("messages", "extension");
    let o = simulate(&dir, &format!("[body]\nsdf = \"body\"\n{MATERIAL}"));
    one_line_error(
        &o,
        "s.toml: body.sdf: `body` has no extension (supported: .sdf, .npy)",
    );
    let o = simulate(&dir, &format!("[body]\nmesh = \"body\"\n{MATERIAL}"));
    one_line_error(
        &o,
        "s.toml: body.mesh: `body` has no extension (supported: .obj, .stl, .ply)",
    );
    let o = simulate(&dir, &format!("[body]\nmesh = \"body.xyz\"\n{MATERIAL}"));
    one_line_error(
        &o,
        "s.toml: body.mesh: unsupported extension `.xyz` of `body.xyz` (supported: .obj, .stl, .ply)",
    );
}

#[test]
fn observe_refuses_to_write_no_point() {
    let dir = tmp("messages", "nothing");
    let s = write(&dir, "s.toml", &format!("{BODY}{MATERIAL}{TIME}"));
    let out = dir.join("o.csv");
    let observe = || {
        let (s, out) = (s.to_str().unwrap(), out.to_str().unwrap());
        run(&["observe", s, "--out", out, "--radius", "1000", "--pixels", "2"])
    };
    let o = observe();
    one_line_error(
        &o,
        "the 4 cameras saw no point of the body in the 2 frames observed",
    );
    assert!(!out.exists(), "a failed observe leaves no file");
    // an earlier file is left as it was
    std::fs::write(&out, "frame,x,y,z\n1,0,1,0\n").unwrap();
    let o = observe();
    one_line_error(&o, "saw no point");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "frame,x,y,z\n1,0,1,0\n");
}
