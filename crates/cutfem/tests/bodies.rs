//! Bodies: SDF grids, the thesis `.sdf` and `.npy` formats, mesh readers, mesh -> SDF and
//! analytic shapes. Shared helpers live here; the tests are in `bodies/`.

#[path = "bodies/grids.rs"]
mod grids;
#[path = "bodies/meshes.rs"]
mod meshes;
#[path = "bodies/shapes.rs"]
mod shapes;

use cutfem::{Error, TriMesh};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

pub(crate) const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/data");
pub(crate) const SDF_FILES: [(&str, usize); 5] = [
    ("bunny_small", 1808),
    ("bunny_medium", 14403),
    ("dragon_small", 895),
    ("dragon_medium", 7031),
    ("dragon_large", 23552),
];

pub(crate) fn data(rel: &str) -> PathBuf {
    let p = PathBuf::from(DATA).join(rel);
    assert!(
        p.exists(),
        "shared data not found at {} (shared/ must sit beside the repo)",
        p.display()
    );
    p
}

/// A fresh path in the temp dir, unique per process and call.
pub(crate) fn tmp(name: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let n = N.fetch_add(1, Ordering::Relaxed);
    std::env::temp_dir().join(format!("cutfem_bodies_{}_{n}_{name}", std::process::id()))
}

pub(crate) fn write_tmp(name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = tmp(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// Asserts `r` is an error whose message mentions the file name and every piece of `needles`.
pub(crate) fn assert_err<T: std::fmt::Debug>(r: Result<T, Error>, path: &std::path::Path, needles: &[&str]) {
    let msg = r.expect_err("expected an error").to_string();
    let name = path.file_name().unwrap().to_str().unwrap();
    assert!(msg.contains(name), "message does not name the file: {msg}");
    assert!(!msg.contains('\n'), "message is not one line: {msg}");
    for n in needles {
        assert!(msg.contains(n), "message lacks '{n}': {msg}");
    }
}

/// SplitMix64, for seeded Monte Carlo.
pub(crate) struct Rng(u64);
impl Rng {
    pub(crate) fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    pub(crate) fn in_box(&mut self, lo: [f64; 3], hi: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|a| lo[a] + (hi[a] - lo[a]) * self.next())
    }
}

pub(crate) use cutfem::v3::{cross, dot, norm, sub, V3 as V};

/// Reference point-triangle distance, independent of the library's Ericson implementation:
/// projection onto the plane when it falls inside (same-side tests), else the nearest edge.
pub(crate) fn ref_tri_distance(p: V, t: [V; 3]) -> f64 {
    let seg = |a: V, b: V| {
        let ab = sub(b, a);
        let s = (dot(sub(p, a), ab) / dot(ab, ab)).clamp(0.0, 1.0);
        norm(sub(p, [a[0] + s * ab[0], a[1] + s * ab[1], a[2] + s * ab[2]]))
    };
    let edges = seg(t[0], t[1]).min(seg(t[1], t[2])).min(seg(t[2], t[0]));
    let n = cross(sub(t[1], t[0]), sub(t[2], t[0]));
    let nn = norm(n);
    if nn == 0.0 {
        return edges;
    }
    let n = n.map(|x| x / nn);
    let h = dot(sub(p, t[0]), n);
    let q = sub(p, n.map(|x| x * h));
    let inside = (0..3).all(|k| dot(cross(sub(t[(k + 1) % 3], t[k]), sub(q, t[k])), n) >= 0.0);
    if inside {
        h.abs()
    } else {
        edges
    }
}

/// Inside test by ray parity (Möller-Trumbore), majority over three skew directions.
pub(crate) fn ray_parity_inside(mesh: &TriMesh, p: V) -> bool {
    let dirs = [
        [0.5773, 0.6123, 0.5401],
        [-0.3123, 0.8412, -0.4412],
        [0.6912, -0.1234, -0.7120],
    ];
    let mut votes = 0;
    for d in dirs {
        let mut hits = 0;
        for f in 0..mesh.faces.len() {
            let [a, b, c] = mesh.triangle(f);
            let (e1, e2) = (sub(b, a), sub(c, a));
            let pv = cross(d, e2);
            let det = dot(e1, pv);
            if det.abs() < 1e-14 {
                continue;
            }
            let tv = sub(p, a);
            let u = dot(tv, pv) / det;
            let qv = cross(tv, e1);
            let v = dot(d, qv) / det;
            let t = dot(e2, qv) / det;
            if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 {
                hits += 1;
            }
        }
        votes += hits % 2;
    }
    votes >= 2
}
