//! SDF grids: accessors, interpolation, validation, the thesis `.sdf` and `.npy` formats.

use super::*;
use cutfem::sdf::NpyDtype;
use cutfem::shapes::Shape;
use cutfem::SdfGrid;

// ---------------------------------------------------------------- SdfGrid basics

#[test]
fn grid_accessors_and_trilinear_interpolation() {
    // a linear field is reproduced exactly by trilinear interpolation
    let f = |p: V| 0.3 * p[0] - 0.7 * p[1] + 1.1 * p[2] - 2.3;
    let g = SdfGrid::from_fn([-1.0, 0.5, 2.0], 0.25, [5, 4, 3], f);
    assert_eq!(g.node_count(), 60);
    assert_eq!(g.cell_count(), 4 * 3 * 2);
    assert_eq!(g.index(1, 2, 1), 1 + 5 * (2 + 4));
    assert_eq!(g.node_position(4, 3, 2), [0.0, 1.25, 2.5]);
    assert_eq!(g.value(1, 2, 1), f(g.node_position(1, 2, 1)));
    let mut rng = Rng(7);
    for _ in 0..200 {
        let p = rng.in_box([-1.0, 0.5, 2.0], [0.0, 1.25, 2.5]);
        assert!((g.sample(p).unwrap() - f(p)).abs() < 1e-12);
        let gr = g.gradient(p).unwrap();
        for (a, want) in [0.3, -0.7, 1.1].into_iter().enumerate() {
            assert!((gr[a] - want).abs() < 1e-12, "{gr:?}");
        }
    }
    // far faces are inside the box; anything beyond is not
    assert!((g.sample([0.0, 1.25, 2.5]).unwrap() - f([0.0, 1.25, 2.5])).abs() < 1e-12);
    assert_eq!(g.sample([0.01, 1.0, 2.2]), None);
    assert_eq!(g.sample([-1.01, 1.0, 2.2]), None);
    assert_eq!(g.gradient([-0.5, 2.0, 2.2]), None);
    // inside nodes: value < 0
    let inside = g.inside_nodes();
    assert_eq!(inside.len(), g.inside_count());
    assert!(inside.iter().all(|n| g.value(n[0], n[1], n[2]) < 0.0));
    let (lo, hi) = g.bounding_box_of_inside().unwrap();
    assert!(lo.iter().zip(&hi).all(|(l, h)| l <= h));
    g.validate().unwrap();
}

/// A body sampled without an inside node is explained: flat (no volume), thinner than two
/// cells (the resolution it needs), or enclosing nothing at a thickness the grid resolves.
#[test]
fn a_sampled_body_without_inside_nodes_says_why() {
    let outside = SdfGrid::from_fn([0.0; 3], 0.1, [4, 4, 4], |_| 1.0);
    let e = outside.check_sampled_body([0.0; 3], [0.3, 0.0, 0.3]).unwrap_err();
    assert!(e.contains("no volume"), "{e}");
    let e = outside
        .check_sampled_body([0.0; 3], [0.3, 0.05, 0.3])
        .unwrap_err();
    assert!(e.contains("raise [body] resolution to 4.000e1 or more"), "{e}");
    let e = outside.check_sampled_body([0.0; 3], [0.3, 0.3, 0.3]).unwrap_err();
    assert!(e.contains("encloses no volume"), "{e}");
    let inside = SdfGrid::from_fn([0.0; 3], 0.1, [4, 4, 4], |p| p[0] - 0.15);
    assert!(inside.check_sampled_body([0.0; 3], [0.3, 0.05, 0.3]).is_ok());
}

#[test]
fn grid_validation_errors() {
    let g = SdfGrid::from_fn([0.0; 3], 0.1, [3, 3, 3], |_| 1.0);
    assert_eq!(
        g.validate().unwrap_err().to_string(),
        "body: the SDF has no inside node (empty body)"
    );
    assert_eq!(g.bounding_box_of_inside(), None);
    let mut bad = SdfGrid::from_fn([0.0; 3], 0.1, [3, 3, 3], |_| -1.0);
    let at = bad.index(1, 2, 0);
    bad.values[at] = f64::NAN;
    assert!(bad.validate().unwrap_err().to_string().contains("(1, 2, 0)"));
    let thin = SdfGrid::from_fn([0.0; 3], 0.1, [1, 3, 3], |_| -1.0);
    assert!(thin.validate().is_err());
    let neg = SdfGrid {
        exact: None,
        spacing: -0.1,
        ..SdfGrid::from_fn([0.0; 3], 0.1, [2, 2, 2], |_| -1.0)
    };
    assert!(neg.validate().is_err());
    let short = SdfGrid {
        exact: None,
        values: vec![-1.0; 7],
        ..neg.clone()
    };
    assert!(short.validate().is_err());
}

// ---------------------------------------------------------------- thesis .sdf

#[test]
fn shared_sdf_files_load_with_readme_inside_counts() {
    for (name, count) in SDF_FILES {
        let g = SdfGrid::read_sdf(data(&format!("sdf/{name}.sdf"))).unwrap();
        g.validate().unwrap();
        assert_eq!(g.inside_count(), count, "{name}: inside nodes (value < 0)");
        // `<= 0` gives the same counts: no stored value is exactly zero
        assert_eq!(g.values.iter().filter(|&&v| v <= 0.0).count(), count, "{name}");
        let (lo, hi) = g.bounding_box_of_inside().unwrap();
        assert!((0..3).all(|a| lo[a] < hi[a]));
    }
    let g = SdfGrid::read_sdf(data("sdf/bunny_small.sdf")).unwrap();
    assert_eq!(g.dims, [27, 31, 22]);
    assert!((g.spacing - 0.2).abs() < 1e-15);
}

#[test]
fn sdf_roundtrip_is_bit_exact() {
    for (name, _) in SDF_FILES {
        let src = data(&format!("sdf/{name}.sdf"));
        let g = SdfGrid::read_sdf(&src).unwrap();
        let out = tmp(&format!("{name}.sdf"));
        g.write_sdf(&out).unwrap();
        assert_eq!(
            std::fs::read(&src).unwrap(),
            std::fs::read(&out).unwrap(),
            "{name}"
        );
        assert_eq!(SdfGrid::read_sdf(&out).unwrap(), g);
        std::fs::remove_file(out).ok();
    }
    // a generated grid on the 1/20 lattice
    let g = Shape::Sphere {
        center: [0.1, 0.2, -0.3],
        radius: 0.5,
    }
    .to_sdf(20.0, 2)
    .unwrap();
    let out = tmp("sphere.sdf");
    g.write_sdf(&out).unwrap();
    let back = SdfGrid::read_sdf(&out).unwrap();
    assert_eq!(back.dims, g.dims);
    assert!((0..3).all(|a| (back.origin[a] - g.origin[a]).abs() < 1e-12));
    let again = tmp("sphere2.sdf");
    back.write_sdf(&again).unwrap();
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&again).unwrap());
    for (a, b) in back.values.iter().zip(&g.values) {
        assert!((a - b).abs() <= 1e-7 * b.abs().max(1e-3));
    }
    std::fs::remove_file(out).ok();
    std::fs::remove_file(again).ok();
}

#[test]
fn sdf_read_errors_name_the_file() {
    let good = std::fs::read(data("sdf/bunny_small.sdf")).unwrap();
    let p = write_tmp("truncated.sdf", &good[..good.len() - 3]);
    assert_err(SdfGrid::read_sdf(&p), &p, &["truncated", "73684", "73681"]);
    let p = write_tmp("header.sdf", &good[..20]);
    assert_err(SdfGrid::read_sdf(&p), &p, &["truncated", "28", "20"]);
    let mut long = good.clone();
    long.extend_from_slice(&[0; 4]);
    let p = write_tmp("long.sdf", &long);
    assert_err(SdfGrid::read_sdf(&p), &p, &["73688"]);

    let mut nan = good.clone();
    let (i, j, k) = (3usize, 4usize, 5usize);
    let at = 28 + 4 * (i + 27 * (j + 31 * k));
    nan[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let p = write_tmp("nan.sdf", &nan);
    assert_err(SdfGrid::read_sdf(&p), &p, &["(3, 4, 5)", "NaN"]);
    let mut inf = good.clone();
    inf[28..32].copy_from_slice(&f32::INFINITY.to_le_bytes());
    let p = write_tmp("inf.sdf", &inf);
    assert_err(SdfGrid::read_sdf(&p), &p, &["(0, 0, 0)", "inf"]);

    let mut zero = good.clone();
    zero[0..4].copy_from_slice(&0i32.to_le_bytes());
    let p = write_tmp("zero_res.sdf", &zero);
    assert_err(SdfGrid::read_sdf(&p), &p, &["resolution"]);
    let mut negsize = good.clone();
    negsize[20..24].copy_from_slice(&(-31i32).to_le_bytes());
    let p = write_tmp("neg_size.sdf", &negsize);
    assert_err(SdfGrid::read_sdf(&p), &p, &["size"]);
    let mut absurd = good[..28].to_vec();
    for a in 0..3 {
        absurd[16 + 4 * a..20 + 4 * a].copy_from_slice(&i32::MAX.to_le_bytes());
    }
    let p = write_tmp("absurd.sdf", &absurd);
    assert_err(SdfGrid::read_sdf(&p), &p, &["absurd"]);
    let mut big = good[..28].to_vec();
    for a in 0..3 {
        big[16 + 4 * a..20 + 4 * a].copy_from_slice(&1000i32.to_le_bytes());
    }
    let p = write_tmp("big.sdf", &big);
    assert_err(SdfGrid::read_sdf(&p), &p, &["truncated", "4000000028"]);
    let missing = tmp("missing.sdf");
    assert_err(SdfGrid::read_sdf(&missing), &missing, &[]);
}

#[test]
fn sdf_write_refuses_grids_off_the_lattice() {
    let g = SdfGrid::from_fn([0.0; 3], 0.3, [2, 2, 2], |_| -1.0);
    let p = tmp("off.sdf");
    assert_err(g.write_sdf(&p), &p, &["spacing"]);
    let g = SdfGrid::from_fn([0.123, 0.0, 0.0], 0.1, [2, 2, 2], |_| -1.0);
    assert_err(g.write_sdf(&p), &p, &["origin"]);
    assert!(!p.exists());
}

// ---------------------------------------------------------------- .npy

#[test]
fn npy_roundtrip_f32_f64() {
    let g = SdfGrid::from_fn([0.5, -1.0, 2.0], 0.1, [7, 5, 3], |p| {
        p[0] - 2.0 * p[1] + 0.1 * p[2].sin()
    });
    let p64 = tmp("grid64.npy");
    g.write_npy(&p64, NpyDtype::F64).unwrap();
    let bytes = std::fs::read(&p64).unwrap();
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    assert_eq!((10 + header_len) % 64, 0);
    assert!(String::from_utf8_lossy(&bytes[10..10 + header_len]).contains("'shape': (3, 5, 7)"));
    assert_eq!(SdfGrid::read_npy(&p64, g.origin, g.spacing).unwrap(), g);
    let p32 = tmp("grid32.npy");
    g.write_npy(&p32, NpyDtype::F32).unwrap();
    let back = SdfGrid::read_npy(&p32, g.origin, g.spacing).unwrap();
    assert_eq!(back.dims, g.dims);
    for (a, b) in back.values.iter().zip(&g.values) {
        assert_eq!(*a, *b as f32 as f64);
    }
    // version 2.0 header (u32 length) is read too
    let mut v2 = b"\x93NUMPY\x02\x00".to_vec();
    let dict = "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2, 2)}\n";
    v2.extend_from_slice(&(dict.len() as u32).to_le_bytes());
    v2.extend_from_slice(dict.as_bytes());
    for n in 0..8 {
        v2.extend_from_slice(&(n as f64 - 3.5).to_le_bytes());
    }
    let p = write_tmp("v2.npy", &v2);
    let g2 = SdfGrid::read_npy(&p, [0.0; 3], 1.0).unwrap();
    assert_eq!(g2.value(1, 0, 1), 5.0 - 3.5);
}

fn npy_bytes(dict: &str, data: &[u8]) -> Vec<u8> {
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out.extend_from_slice(data);
    out
}

#[test]
fn npy_header_errors() {
    let data8 = [0u8; 64];
    let cases: [(&str, Vec<u8>, &str); 7] = [
        (
            "fortran.npy",
            npy_bytes(
                "{'descr': '<f8', 'fortran_order': True, 'shape': (2, 2, 2), }\n",
                &data8,
            ),
            "fortran_order",
        ),
        (
            "int.npy",
            npy_bytes(
                "{'descr': '<i4', 'fortran_order': False, 'shape': (2, 2, 2), }\n",
                &data8[..32],
            ),
            "'<i4'",
        ),
        (
            "big_endian.npy",
            npy_bytes(
                "{'descr': '>f8', 'fortran_order': False, 'shape': (2, 2, 2), }\n",
                &data8,
            ),
            "'>f8'",
        ),
        (
            "two_d.npy",
            npy_bytes(
                "{'descr': '<f8', 'fortran_order': False, 'shape': (4, 2), }\n",
                &data8,
            ),
            "3-D",
        ),
        (
            "short.npy",
            npy_bytes(
                "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2, 2), }\n",
                &data8[..63],
            ),
            "bytes",
        ),
        ("magic.npy", b"NUMPY\x01\x00 not really".to_vec(), "magic"),
        (
            "dict.npy",
            npy_bytes("{'descr': '<f8', 'shape': (2, 2, 2), }\n", &data8),
            "fortran_order",
        ),
    ];
    for (name, bytes, needle) in cases {
        let p = write_tmp(name, bytes);
        assert_err(SdfGrid::read_npy(&p, [0.0; 3], 0.1), &p, &[needle]);
    }
    let p = write_tmp(
        "ok.npy",
        npy_bytes(
            "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2, 2), }\n",
            &data8,
        ),
    );
    assert!(SdfGrid::read_npy(&p, [0.0; 3], 0.1).is_ok());
    assert_err(SdfGrid::read_npy(&p, [0.0; 3], 0.0), &p, &["spacing"]);
}
