//! Readers never read an endless stream whole (`cutfem::input`): a scene, an `.sdf`, an
//! `.npy` or a mesh path that is a symlink to `/dev/zero` is refused at once (by the header, or
//! as text with a NUL byte), and an `.sdf` stream with a valid header followed by endless data
//! is read to one byte past what its header implies and refused as over-long.

use cutfem::scene::Scene;
use cutfem::{SdfGrid, TriMesh};
use std::io::Write;
use std::path::{Path, PathBuf};

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("cutfem-endless-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn zero_link(dir: &Path, name: &str) -> PathBuf {
    let p = dir.join(name);
    std::os::unix::fs::symlink("/dev/zero", &p).unwrap();
    p
}

fn message<T: std::fmt::Debug>(r: Result<T, cutfem::Error>) -> String {
    r.unwrap_err().to_string()
}

#[test]
fn symlinks_to_dev_zero_are_refused_at_once() {
    if !Path::new("/dev/zero").exists() {
        return;
    }
    let d = dir("zero");
    let e = message(SdfGrid::read_sdf(zero_link(&d, "z.sdf")));
    assert!(e.contains("z.sdf: resolution must be positive, found 0"), "{e}");
    let e = message(SdfGrid::read_npy(zero_link(&d, "z.npy"), [0.0; 3], 0.1));
    assert!(e.contains("not a .npy file"), "{e}");
    let e = message(TriMesh::load(zero_link(&d, "z.obj")));
    assert!(e.contains("NUL byte at byte 0"), "{e}");
    let e = message(TriMesh::load(zero_link(&d, "z.stl")));
    assert!(e.contains("neither binary STL"), "{e}");
    let e = message(TriMesh::load(zero_link(&d, "z.ply")));
    assert!(e.contains("no 'end_header'"), "{e}");
    let e = message(Scene::load(&zero_link(&d, "z.toml")));
    assert!(e.contains("z.toml: binary data"), "{e}");
}

#[test]
fn an_sdf_stream_is_read_to_its_header_size_only() {
    let d = dir("fifo");
    let fifo = d.join("endless.sdf");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        return; // no FIFOs here
    }
    let path = fifo.clone();
    // header: resolution 10, offset 0, 3 x 3 x 3 nodes (108 bytes of values); then zeros
    // until the reader goes away
    let writer = std::thread::spawn(move || {
        let mut f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
        let mut header = Vec::new();
        for v in [10i32, 0, 0, 0, 3, 3, 3] {
            header.extend_from_slice(&v.to_le_bytes());
        }
        f.write_all(&header).unwrap();
        let zeros = [0u8; 4096];
        let mut sent = 0usize;
        while f.write_all(&zeros).is_ok() {
            sent += zeros.len();
            assert!(sent < 1 << 30, "the reader read far more than the header implies");
        }
    });
    let e = message(SdfGrid::read_sdf(&fifo));
    writer.join().unwrap();
    assert!(
        e.contains("trailing data in .sdf file: size [3, 3, 3] needs 136 bytes, found more"),
        "{e}"
    );
}
