//! Analytic shapes: distances, volumes, areas, grids and the serde form of `[body].shape`.

use super::*;
use cutfem::shapes::Shape;

// ---------------------------------------------------------------- analytic shapes

#[test]
fn sphere_sdf_is_exact_at_nodes() {
    let c = [0.1, 0.2, -0.3];
    let r = 0.7;
    let g = Shape::Sphere { center: c, radius: r }.to_sdf(10.0, 2).unwrap();
    let [nx, ny, nz] = g.dims;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = g.node_position(i, j, k);
                assert_eq!(g.value(i, j, k), norm(sub(p, c)) - r);
            }
        }
    }
    assert_eq!(g.dims, [19, 19, 19]); // x: floor(-6) - 2 .. ceil(8) + 2
    assert!((g.origin[0] + 0.8).abs() < 1e-12);
}

#[test]
fn box_grid_is_lattice_aligned() {
    // the box of the scene example, at resolution 20 with 2 padding cells
    let shape = Shape::Box {
        center: [0.0, 1.0, 0.0],
        size: [1.29, 0.4, 0.8],
    };
    let g = shape.to_sdf(20.0, 2).unwrap();
    let want = [-0.75, 0.7, -0.5];
    for a in 0..3 {
        assert!((g.origin[a] - want[a]).abs() < 1e-12, "{:?}", g.origin);
    }
    assert_eq!(g.dims, [31, 13, 21]);
    // nodes on the faces y = 0.8 and y = 1.2 have value 0 (the x faces fall between nodes)
    assert!(g.value(15, 2, 10).abs() < 1e-12 && g.value(15, 10, 10).abs() < 1e-12);
    assert!((g.inside_count() as f64 * 0.05f64.powi(3) / shape.volume() - 1.0).abs() < 0.2);
}

/// Checks `shape.distance` against the nearest of dense surface samples (`gap` bounds the
/// distance from any surface point to its nearest sample) and an inside predicate.
fn check_against_samples(shape: &Shape, surface: &[V], gap: f64, inside: impl Fn(V) -> bool) {
    let (lo, hi) = shape.bounding_box();
    let pad = 0.3;
    let mut rng = Rng(42);
    let mut worst = 0.0f64;
    for _ in 0..300 {
        let q = rng.in_box(lo.map(|x| x - pad), hi.map(|x| x + pad));
        let d = shape.distance(q);
        let reference = surface
            .iter()
            .map(|&s| norm(sub(q, s)))
            .fold(f64::INFINITY, f64::min);
        assert!(
            d.abs() <= reference + 1e-12,
            "{shape:?} at {q:?}: |{d}| > sampled {reference}"
        );
        assert!(
            reference - d.abs() <= gap,
            "{shape:?} at {q:?}: {d} vs sampled {reference}"
        );
        worst = worst.max(reference - d.abs());
        assert_eq!(d < 0.0, inside(q), "{shape:?} sign at {q:?}");
    }
    assert!(worst > 0.0 && worst <= gap);
}

#[test]
fn torus_capsule_box_distances_match_sampled_references() {
    use std::f64::consts::PI;
    // torus around a tilted axis
    let (c, axis, big, small) = ([0.2, -0.1, 0.3], [1.0, 2.0, 2.0], 0.8, 0.25);
    let n = axis.map(|x| x / 3.0);
    let e1 = [2.0 / 3.0, 1.0 / 3.0, -2.0 / 3.0]; // orthonormal to n
    let e2 = cross(n, e1);
    let (nu, nv) = (600, 150);
    let mut pts = Vec::new();
    for iu in 0..nu {
        let u = 2.0 * PI * iu as f64 / nu as f64;
        for iv in 0..nv {
            let v = 2.0 * PI * iv as f64 / nv as f64;
            let rad = big + small * v.cos();
            pts.push(std::array::from_fn(|a| {
                c[a] + rad * (u.cos() * e1[a] + u.sin() * e2[a]) + small * v.sin() * n[a]
            }));
        }
    }
    let gap = 0.5 * ((big + small) * 2.0 * PI / nu as f64).hypot(small * 2.0 * PI / nv as f64);
    let torus = Shape::Torus {
        center: c,
        axis,
        major: big,
        minor: small,
    };
    check_against_samples(&torus, &pts, gap, |q| {
        let d = sub(q, c);
        let z = dot(d, n);
        let rho = (dot(d, d) - z * z).sqrt();
        (rho - big).powi(2) + z * z < small * small
    });

    // capsule: cylinder side plus the two outer hemispheres
    let (a, b, r) = ([-0.4, 0.1, 0.0], [0.5, 0.6, -0.3], 0.3);
    let ab = sub(b, a);
    let len = norm(ab);
    let w = ab.map(|x| x / len);
    let f1 = {
        let t = cross(w, [0.0, 0.0, 1.0]);
        t.map(|x| x / norm(t))
    };
    let f2 = cross(w, f1);
    let (na, nl) = (300, 120);
    let mut pts = Vec::new();
    for ia in 0..na {
        let th = 2.0 * PI * ia as f64 / na as f64;
        let ring: V = std::array::from_fn(|k| r * (th.cos() * f1[k] + th.sin() * f2[k]));
        for il in 0..=nl {
            let s = il as f64 / nl as f64;
            pts.push(std::array::from_fn(|k| a[k] + s * ab[k] + ring[k]));
        }
        for ip in 1..=nl / 2 {
            let phi = 0.5 * PI * ip as f64 / (nl / 2) as f64;
            for (end, dir) in [(a, -1.0), (b, 1.0)] {
                pts.push(std::array::from_fn(|k| {
                    end[k] + phi.cos() * ring[k] + dir * r * phi.sin() * w[k]
                }));
            }
        }
    }
    let gap = 0.5 * (r * 2.0 * PI / na as f64).hypot((len / nl as f64).max(r * PI / nl as f64));
    let capsule = Shape::Capsule { a, b, radius: r };
    check_against_samples(&capsule, &pts, gap, |q| {
        let t = (dot(sub(q, a), ab) / (len * len)).clamp(0.0, 1.0);
        norm(sub(q, std::array::from_fn(|k| a[k] + t * ab[k]))) < r
    });

    // box: a grid on each face
    let (c, size) = ([0.1, -0.2, 0.3], [1.0, 0.5, 0.8]);
    let m = 200;
    let mut pts = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [-0.5, 0.5] {
            for iu in 0..=m {
                for iv in 0..=m {
                    let mut p = c;
                    p[axis] += side * size[axis];
                    p[u] += (iu as f64 / m as f64 - 0.5) * size[u];
                    p[v] += (iv as f64 / m as f64 - 0.5) * size[v];
                    pts.push(p);
                }
            }
        }
    }
    let gap = 0.5 * (1.0f64 / m as f64).hypot(0.8 / m as f64) + 1e-12;
    let cuboid = Shape::Box { center: c, size };
    check_against_samples(&cuboid, &pts, gap, |q| {
        (0..3).all(|k| (q[k] - c[k]).abs() < 0.5 * size[k])
    });
}

#[test]
fn volumes_and_areas_match_monte_carlo() {
    let shapes = [
        Shape::Box {
            center: [0.0, 1.0, 0.0],
            size: [1.29, 0.4, 0.8],
        },
        Shape::Sphere {
            center: [0.3, 0.0, -0.1],
            radius: 0.6,
        },
        Shape::Torus {
            center: [0.0; 3],
            axis: [0.0, 1.0, 1.0],
            major: 0.7,
            minor: 0.2,
        },
        Shape::Capsule {
            a: [0.0; 3],
            b: [0.6, 0.3, 0.2],
            radius: 0.25,
        },
    ];
    let mut rng = Rng(2024);
    for shape in &shapes {
        let (lo, hi) = shape.bounding_box();
        let (lo, hi) = (lo.map(|x| x - 0.05), hi.map(|x| x + 0.05));
        let box_vol: f64 = (0..3).map(|a| hi[a] - lo[a]).product();
        let eps = 0.01;
        let n = 400_000;
        let (mut inside, mut shell) = (0usize, 0usize);
        for _ in 0..n {
            let d = shape.distance(rng.in_box(lo, hi));
            inside += (d < 0.0) as usize;
            shell += (d.abs() < eps) as usize;
        }
        let vol = box_vol * inside as f64 / n as f64;
        let area = box_vol * shell as f64 / n as f64 / (2.0 * eps);
        eprintln!(
            "{shape:?}: volume {vol:.4} vs {:.4}, area {area:.4} vs {:.4}",
            shape.volume(),
            shape.area()
        );
        assert!(
            (vol / shape.volume() - 1.0).abs() < 0.02,
            "{shape:?} volume {vol}"
        );
        assert!((area / shape.area() - 1.0).abs() < 0.05, "{shape:?} area {area}");
    }
}

#[test]
fn shape_validation() {
    let bad = [
        Shape::Box {
            center: [0.0; 3],
            size: [1.0, 0.0, 1.0],
        },
        Shape::Sphere {
            center: [0.0; 3],
            radius: -1.0,
        },
        Shape::Torus {
            center: [0.0; 3],
            axis: [0.0; 3],
            major: 1.0,
            minor: 0.5,
        },
        Shape::Torus {
            center: [0.0; 3],
            axis: [0.0, 0.0, 1.0],
            major: 0.5,
            minor: 0.5,
        },
        Shape::Capsule {
            a: [0.0; 3],
            b: [f64::NAN, 0.0, 0.0],
            radius: 1.0,
        },
    ];
    for s in bad {
        assert!(s.validate().is_err() && s.to_sdf(10.0, 1).is_err(), "{s:?}");
    }
    let s = Shape::Sphere {
        center: [0.0; 3],
        radius: 1.0,
    };
    assert!(s.to_sdf(-1.0, 1).is_err());
    assert!(s.to_sdf(1e5, 0).unwrap_err().to_string().contains("nodes"));
}

// ---------------------------------------------------------------- serde form of [body].shape

/// A minimal self-describing deserializer standing in for a TOML inline table.
enum Val {
    S(&'static str),
    I(i64),
    F(f64),
    A(Vec<Val>),
    M(Vec<(&'static str, Val)>),
}

impl<'de> serde::Deserializer<'de> for Val {
    type Error = serde::de::value::Error;
    fn deserialize_any<W: serde::de::Visitor<'de>>(self, v: W) -> Result<W::Value, Self::Error> {
        use serde::de::value::{MapDeserializer, SeqDeserializer};
        match self {
            Val::S(s) => v.visit_borrowed_str(s),
            Val::I(i) => v.visit_i64(i),
            Val::F(x) => v.visit_f64(x),
            Val::A(xs) => v.visit_seq(SeqDeserializer::new(xs.into_iter())),
            Val::M(kv) => v.visit_map(MapDeserializer::new(kv.into_iter())),
        }
    }
    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf option
        unit unit_struct newtype_struct seq tuple tuple_struct map struct enum identifier ignored_any
    }
}

impl<'de> serde::de::IntoDeserializer<'de, serde::de::value::Error> for Val {
    type Deserializer = Val;
    fn into_deserializer(self) -> Val {
        self
    }
}

fn shape_from(kv: Vec<(&'static str, Val)>) -> Result<Shape, serde::de::value::Error> {
    serde::Deserialize::deserialize(Val::M(kv))
}

#[test]
fn shape_deserializes_from_the_scene_form() {
    use Val::*;
    // shape = { kind = "box", center = [0, 1, 0], size = [1.29, 0.4, 0.8] }
    let s = shape_from(vec![
        ("kind", S("box")),
        ("center", A(vec![I(0), I(1), I(0)])),
        ("size", A(vec![F(1.29), F(0.4), F(0.8)])),
    ])
    .unwrap();
    assert_eq!(
        s,
        Shape::Box {
            center: [0.0, 1.0, 0.0],
            size: [1.29, 0.4, 0.8]
        }
    );
    let s = shape_from(vec![
        ("kind", S("torus")),
        ("center", A(vec![I(0), I(0), I(0)])),
        ("axis", A(vec![I(0), I(1), I(0)])),
        ("major", F(1.0)),
        ("minor", F(0.25)),
    ])
    .unwrap();
    assert_eq!(
        s,
        Shape::Torus {
            center: [0.0; 3],
            axis: [0.0, 1.0, 0.0],
            major: 1.0,
            minor: 0.25
        }
    );
    let s = shape_from(vec![
        ("kind", S("sphere")),
        ("center", A(vec![I(0), I(0), I(0)])),
        ("radius", I(2)),
    ]);
    assert_eq!(
        s.unwrap(),
        Shape::Sphere {
            center: [0.0; 3],
            radius: 2.0
        }
    );
    let s = shape_from(vec![
        ("kind", S("capsule")),
        ("a", A(vec![I(0), I(0), I(0)])),
        ("b", A(vec![I(1), I(0), I(0)])),
        ("radius", F(0.5)),
    ]);
    assert!(s.is_ok());
    let e = shape_from(vec![("kind", S("cone")), ("radius", F(1.0))]).unwrap_err();
    assert!(e.to_string().contains("cone"), "{e}");
    let e = shape_from(vec![
        ("kind", S("sphere")),
        ("center", A(vec![I(0), I(0), I(0)])),
        ("radius", F(1.0)),
        ("size", F(1.0)),
    ]);
    assert!(e.unwrap_err().to_string().contains("size"));
    let e = shape_from(vec![
        ("kind", S("sphere")),
        ("center", A(vec![I(0), I(0)])),
        ("radius", F(1.0)),
    ]);
    assert!(e.is_err());
    let e = shape_from(vec![("kind", S("sphere")), ("radius", F(1.0))]).unwrap_err();
    assert!(e.to_string().contains("center"), "{e}");
}
