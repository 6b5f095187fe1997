//! Diffusion of the displacements into the empty nodes and Direct Forward level-set advection
//! (thesis sec. 4.4.5, 2.5.2.5, Alg. A.2), on analytic SDFs sampled here.
//!
//! Run with `--nocapture` to see the measured errors.

use cutfem::fem::advect::{
    advect, advect_with, AdvectSettings, Diffusion, DisplacementExtension, DIFFUSION_DISTANCE,
};
use cutfem::fem::Grid;
use cutfem::SdfGrid;
use gpumat::{cg, Axes, CgParams, Mat3, Matrix, Vec3};

/// Samples `f` on the grid of spacing `h` (nodes on multiples of `h`) covering `[lo, hi]` plus
/// `pad` cells.
fn sample(lo: [f64; 3], hi: [f64; 3], h: f64, pad: i64, f: impl Fn([f64; 3]) -> f64) -> SdfGrid {
    let start: [i64; 3] = std::array::from_fn(|a| (lo[a] / h - 1e-9).floor() as i64 - pad);
    let end: [i64; 3] = std::array::from_fn(|a| (hi[a] / h + 1e-9).ceil() as i64 + pad);
    let dims: [usize; 3] = std::array::from_fn(|a| (end[a] - start[a] + 1) as usize);
    let origin: [f64; 3] = std::array::from_fn(|a| start[a] as f64 * h);
    let mut values = Vec::with_capacity(dims.iter().product());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                values.push(f([
                    origin[0] + h * i as f64,
                    origin[1] + h * j as f64,
                    origin[2] + h * k as f64,
                ]));
            }
        }
    }
    SdfGrid {
        exact: None,
        origin,
        spacing: h,
        dims,
        values,
    }
}

/// Exact SDF of an axis-aligned box.
fn box_sdf(center: [f64; 3], size: [f64; 3]) -> impl Fn([f64; 3]) -> f64 {
    move |p| {
        let q: [f64; 3] = std::array::from_fn(|a| (p[a] - center[a]).abs() - 0.5 * size[a]);
        let outside = q.iter().map(|v| v.max(0.0).powi(2)).sum::<f64>().sqrt();
        outside + q[0].max(q[1]).max(q[2]).min(0.0)
    }
}

fn box_grid(center: [f64; 3], size: [f64; 3], h: f64, pad: i64) -> Grid {
    let lo = std::array::from_fn(|a| center[a] - 0.5 * size[a]);
    let hi = std::array::from_fn(|a| center[a] + 0.5 * size[a]);
    Grid::new(sample(lo, hi, h, pad, box_sdf(center, size))).expect("valid box grid")
}

fn sphere_grid(center: [f64; 3], r: f64, h: f64, pad: i64) -> Grid {
    let f = move |p: [f64; 3]| {
        ((p[0] - center[0]).powi(2) + (p[1] - center[1]).powi(2) + (p[2] - center[2]).powi(2)).sqrt() - r
    };
    Grid::new(sample(center.map(|c| c - r), center.map(|c| c + r), h, pad, f)).expect("valid sphere grid")
}

/// World position of every band slot.
fn band_positions(grid: &Grid, band: &Diffusion) -> Vec<Vec3<f64>> {
    let [nx, ny, _] = grid.sdf.dims;
    band.nodes()
        .iter()
        .map(|&n| Vec3::from_array(grid.sdf.node_position(n % nx, (n / nx) % ny, n / (nx * ny))))
        .collect()
}

fn active_field(grid: &Grid, f: impl Fn(Vec3<f64>) -> Vec3<f64>) -> Matrix<Vec3<f64>> {
    Matrix::from_fn(grid.dofs(), 1, 1, |d, _, _| f(grid.positions[d]))
}

fn rot_z(deg: f64) -> Mat3<f64> {
    let (s, c) = deg.to_radians().sin_cos();
    Mat3::from_rows([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
}

fn rot_x(deg: f64) -> Mat3<f64> {
    let (s, c) = deg.to_radians().sin_cos();
    Mat3::from_rows([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
}

/// Volume as the count of inside nodes times `h^3`.
fn count_volume(s: &SdfGrid) -> f64 {
    s.inside_count() as f64 * s.spacing.powi(3)
}

/// Volume with a smoothed Heaviside, `sum clamp(1/2 - phi/h, 0, 1) h^3` (second order for an SDF).
fn smooth_volume(s: &SdfGrid) -> f64 {
    let h = s.spacing;
    s.values
        .iter()
        .map(|v| (0.5 - v / h).clamp(0.0, 1.0))
        .sum::<f64>()
        * h.powi(3)
}

/// `phi_adv(map(x)) - phi_0(x)` over the reference nodes `x` with `|phi_0(x)| < h` for which
/// `keep(x)` holds: (max, rms, count).
fn surface_error(
    grid: &Grid,
    adv: &SdfGrid,
    map: impl Fn(Vec3<f64>) -> Vec3<f64>,
    keep: impl Fn([f64; 3]) -> bool,
) -> (f64, f64, usize) {
    let s = &grid.sdf;
    let [nx, ny, nz] = s.dims;
    let (mut max, mut sq, mut n) = (0.0f64, 0.0, 0usize);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let v = s.value(i, j, k);
                let x = s.node_position(i, j, k);
                if v.abs() < s.spacing && keep(x) {
                    let p = map(Vec3::from_array(x));
                    let e = adv.sample(p.to_array()).expect("the output grid covers the body") - v;
                    max = max.max(e.abs());
                    sq += e * e;
                    n += 1;
                }
            }
        }
    }
    (max, (sq / n.max(1) as f64).sqrt(), n)
}

/// Table 4.1: the cuboid of the benchmarks, cells of size 1/20.
#[test]
fn empty_node_count_of_the_benchmark_cuboid() {
    let (center, size, h) = ([0.0, 1.0, 0.0], [1.29, 0.4, 0.8], 0.05);
    let grid = box_grid(center, size, h, 8);
    assert_eq!(grid.dofs(), 4131, "Table 4.1: grid free nodes");
    assert_eq!(grid.cells.len(), 3328, "Table 4.1: grid elements");
    let band = Diffusion::new(&grid).unwrap();
    assert_eq!(band.distance(), DIFFUSION_DISTANCE);
    // Lattice points at l1 distance 1..=5 from a 27 x 9 x 17 box of nodes:
    // 5 * 2 (ab + bc + ca) + 4 (a + b + c) (0 + 1 + 2 + 3 + 4) + 8 (0 + 0 + 1 + 3 + 6).
    assert_eq!(
        band.empty_count(),
        5 * 2 * (243 + 153 + 459) + 4 * 53 * 10 + 8 * 10
    );
    assert_eq!(band.len(), grid.dofs() + band.empty_count());
    let clipped = Diffusion::new(&box_grid(center, size, h, 2)).unwrap();
    println!(
        "cuboid: {} active nodes, {} cells, {} empty nodes (Table 4.1: 13365); on a grid padded by 2 cells: {}",
        grid.dofs(),
        grid.cells.len(),
        band.empty_count(),
        clipped.empty_count()
    );
    assert!(clipped.empty_count() < band.empty_count());
    let linear = Diffusion::with_distance(&grid, DIFFUSION_DISTANCE, DisplacementExtension::Linear).unwrap();
    assert_eq!(linear.nodes(), band.nodes());
}

/// The band is exactly the empty nodes within l1 distance 5 of an active node (brute force).
#[test]
fn band_is_the_l1_neighbourhood_of_the_active_nodes() {
    let grid = sphere_grid([0.02, -0.01, 0.03], 0.3, 0.1, 7);
    let band = Diffusion::with_distance(&grid, 4, DisplacementExtension::Harmonic).unwrap();
    let s = &grid.sdf;
    let [nx, ny, nz] = s.dims;
    let active: Vec<[i64; 3]> = grid
        .dof_nodes
        .iter()
        .map(|&n| [(n % nx) as i64, ((n / nx) % ny) as i64, (n / (nx * ny)) as i64])
        .collect();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let n = s.index(i, j, k);
                let d = active
                    .iter()
                    .map(|a| (a[0] - i as i64).abs() + (a[1] - j as i64).abs() + (a[2] - k as i64).abs())
                    .min()
                    .unwrap();
                match band.slot(n) {
                    Some(slot) if slot < band.dofs() => assert_eq!(d, 0),
                    Some(_) => assert!((1..=4).contains(&d), "node {n} at distance {d} is in the band"),
                    None => assert!(d > 4, "node {n} at distance {d} is missing"),
                }
            }
        }
    }
    for (slot, &n) in band.nodes().iter().enumerate() {
        assert_eq!(band.slot(n), Some(slot));
    }
}

#[test]
fn both_extensions_reproduce_constants() {
    let grid = sphere_grid([0.013, -0.021, 0.007], 0.3, 0.05, 7);
    let c = Vec3::new(0.3, -1.2, 0.05);
    for ext in [DisplacementExtension::Harmonic, DisplacementExtension::Linear] {
        let mut band = Diffusion::with_distance(&grid, DIFFUSION_DISTANCE, ext).unwrap();
        band.params.tolerance = 1e-12;
        let out = band.diffuse(&active_field(&grid, |_| c)).unwrap();
        assert_eq!(out.len(), band.len());
        let err = out.iter().map(|v| (*v - c).norm()).fold(0.0, f64::max);
        println!("{ext:?}: constant field, max error {err:.2e}");
        assert!(err < 1e-9 * c.norm(), "{ext:?}: {err}");
    }
}

/// A linear field `A x + c` on the active nodes: the linear extension gives `A x + c` on every
/// band node; the thesis' harmonic extension solves its discrete Laplace equation with Neumann
/// edges, obeys the maximum principle, and bends the field near the band's outer edge.
#[test]
fn linear_fields() {
    let grid = box_grid([0.013, 1.007, 0.021], [1.29, 0.4, 0.8], 0.05, 7);
    let a = Mat3::from_rows([[0.01, 0.002, -0.003], [0.004, -0.02, 0.001], [0.0, 0.005, 0.015]]);
    let c = Vec3::new(0.1, -0.2, 0.3);
    let lin = |x: Vec3<f64>| a * x + c;
    let u = active_field(&grid, lin);

    let mut band =
        Diffusion::with_distance(&grid, DIFFUSION_DISTANCE, DisplacementExtension::Linear).unwrap();
    band.params.tolerance = 1e-12;
    let (out, info) = band.diffuse_info(&u).unwrap();
    let pos = band_positions(&grid, &band);
    let err = out
        .iter()
        .zip(&pos)
        .map(|(v, p)| (*v - lin(*p)).norm())
        .fold(0.0, f64::max);
    println!(
        "linear extension: max error {err:.2e} ({:?} iterations)",
        info.iterations
    );
    assert!(err < 1e-9, "linear extension error {err}");

    let band = Diffusion::new(&grid).unwrap();
    let (out, info) = band.diffuse_info(&u).unwrap();
    let [nx, ny, nz] = grid.sdf.dims;
    let mut residual = 0.0f64;
    for (slot, &n) in band.nodes().iter().enumerate().skip(band.dofs()) {
        let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
        let nbrs = [
            (i > 0).then(|| n - 1),
            (i + 1 < nx).then(|| n + 1),
            (j > 0).then(|| n - nx),
            (j + 1 < ny).then(|| n + nx),
            (k > 0).then(|| n - nx * ny),
            (k + 1 < nz).then(|| n + nx * ny),
        ];
        let mut r = Vec3::default();
        for m in nbrs.into_iter().flatten() {
            if let Some(t) = band.slot(m) {
                r = r + (out[slot] - out[t]);
            }
        }
        residual = residual.max(r.norm());
    }
    let (lo, hi) = grid.positions.iter().map(|p| lin(*p)).fold(
        (Vec3::splat(f64::INFINITY), Vec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), v| {
            (
                Vec3::new(lo.x.min(v.x), lo.y.min(v.y), lo.z.min(v.z)),
                Vec3::new(hi.x.max(v.x), hi.y.max(v.y), hi.z.max(v.z)),
            )
        },
    );
    for v in &out {
        for (x, (l, h)) in v.to_array().iter().zip(lo.to_array().iter().zip(hi.to_array())) {
            assert!(
                *x >= l - 1e-9 && *x <= h + 1e-9,
                "maximum principle violated: {x} not in [{l}, {h}]"
            );
        }
    }
    let dev = out
        .iter()
        .zip(&pos)
        .map(|(v, p)| (*v - lin(*p)).norm())
        .fold(0.0, f64::max);
    println!(
        "harmonic extension: Laplace residual {residual:.2e}, deviation from the linear field {:.3} cells ({:?} iterations)",
        dev / 0.05,
        info.iterations
    );
    assert!(residual < 1e-7, "discrete Laplace residual {residual}");
    assert!(dev > 1e-4, "the harmonic extension is not expected to be linear");
}

/// One batched CG equals three single-coordinate CG solves, iteration counts included.
#[test]
fn batched_solve_equals_three_single_solves() {
    let grid = sphere_grid([0.013, -0.021, 0.007], 0.4, 0.05, 7);
    let field = |x: Vec3<f64>| Vec3::new(0.1 * (7.0 * x.x).sin(), x.y * x.y - 0.3 * x.z, 1e-3 * x.z);
    let u = active_field(&grid, field);
    for ext in [DisplacementExtension::Harmonic, DisplacementExtension::Linear] {
        let band = Diffusion::with_distance(&grid, DIFFUSION_DISTANCE, ext).unwrap();
        let (out, info) = band.diffuse_info(&u).unwrap();
        assert_eq!(band.last_info().as_ref(), Some(&info));
        let b = band.rhs(&u).unwrap();
        let m = band.empty_count();
        let bmax = b
            .ex()
            .norm_over(Axes::ROWS)
            .into_vec()
            .into_iter()
            .fold(0.0, f64::max);
        let params = CgParams {
            absolute_tolerance: band.params.tolerance * bmax,
            ..band.params
        };
        let mut diff = 0.0f64;
        let mut single = Vec::new();
        for c in 0..3 {
            let bc = Matrix::from_slice(m, 1, 1, b.batch(c));
            let mut x = Matrix::zeros(m, 1, 1);
            let ic = cg(
                band.matrix(),
                &bc,
                &mut x,
                band.preconditioner().unwrap(),
                &params,
            )
            .unwrap();
            single.push(ic.iterations[0]);
            for r in 0..m {
                diff = diff.max((x.get(r, 0, 0) - out[band.dofs() + r].to_array()[c]).abs());
            }
        }
        println!(
            "{ext:?}: batched iterations {:?}, single {single:?}, max difference {diff:.1e}",
            info.iterations
        );
        assert_eq!(info.iterations, single);
        assert!(info.converged.iter().all(|&c| c));
        assert!(
            diff <= 1e-14,
            "{ext:?}: batched and single solves differ by {diff}"
        );
    }
}

#[test]
fn warm_start_reuses_the_previous_solution() {
    let grid = sphere_grid([0.0, 0.0, 0.0], 0.4, 0.05, 7);
    let band = Diffusion::new(&grid).unwrap();
    let u = active_field(&grid, |x| Vec3::new(x.y * x.y, 0.1 * x.x, 0.0));
    let first = band.diffuse_info(&u).unwrap().1;
    let again = band.diffuse_info(&u).unwrap().1;
    let u2 = active_field(&grid, |x| Vec3::new(x.y * x.y + 0.01 * x.z, 0.1 * x.x, 0.0));
    let near = band.diffuse_info(&u2).unwrap().1;
    band.reset_warm_start();
    let cold = band.diffuse_info(&u2).unwrap().1;
    println!(
        "iterations: cold {:?}, same field again {:?}, perturbed field warm {:?} / cold {:?}",
        first.iterations, again.iterations, near.iterations, cold.iterations
    );
    assert_eq!(again.iterations, vec![0, 0, 0]);
    assert!(near.max_iterations() < cold.max_iterations());
}

fn check_translation(t_cells: [f64; 3]) -> (f64, f64) {
    let h = 0.05;
    let grid = sphere_grid([0.011, -0.023, 0.007], 0.5, h, 7);
    let band = Diffusion::new(&grid).unwrap();
    let t = Vec3::from_array(t_cells) * h;
    let u = band.diffuse(&active_field(&grid, |_| t)).unwrap();
    let adv = advect(&grid, &band, &u).unwrap();
    let (max, rms, n) = surface_error(&grid, &adv, |x| x + t, |_| true);
    let count = count_volume(&adv) / count_volume(&grid.sdf);
    let smooth = smooth_volume(&adv) / smooth_volume(&grid.sdf);
    println!(
        "sphere R = 10 h translated by {t_cells:?} h: surface error max {:.3} h, rms {:.3} h ({n} nodes); \
         volume ratio {count:.4} (count), {smooth:.4} (smoothed)",
        max / h,
        rms / h
    );
    assert!((count - 1.0).abs() < 0.03, "count volume ratio {count}");
    assert!((smooth - 1.0).abs() < 0.01, "smoothed volume ratio {smooth}");
    (max / h, rms / h)
}

#[test]
fn translation_by_whole_cells() {
    let (max, _) = check_translation([3.0, -2.0, 1.0]);
    assert!(max < 0.05, "{max} h");
    let (max0, _) = check_translation([0.0, 0.0, 0.0]);
    assert!(
        (max - max0).abs() < 1e-9,
        "a whole-cell translation must match the identity"
    );
}

#[test]
fn translation_by_fractions_of_a_cell() {
    for t in [
        [0.25, 0.0, 0.0],
        [0.5, 0.5, 0.5],
        [0.37, 0.5, -0.81],
        [2.63, -1.29, 0.44],
    ] {
        let (max, rms) = check_translation(t);
        assert!(max < 0.1 && rms < 0.06, "{t:?}: max {max} h, rms {rms} h");
    }
}

#[test]
fn rotation_by_30_degrees_preserves_the_volume() {
    let (center, size, h) = ([0.013, 1.007, 0.021], [1.29, 0.4, 0.8], 0.05);
    let grid = box_grid(center, size, h, 7);
    let c = Vec3::from_array(center);
    let (count0, smooth0) = (count_volume(&grid.sdf), smooth_volume(&grid.sdf));
    for ext in [DisplacementExtension::Harmonic, DisplacementExtension::Linear] {
        let band = Diffusion::with_distance(&grid, DIFFUSION_DISTANCE, ext).unwrap();
        for (name, r) in [
            ("z", rot_z(30.0)),
            ("x", rot_x(30.0)),
            ("z x", rot_z(30.0) * rot_x(30.0)),
        ] {
            let u = band
                .diffuse(&active_field(&grid, |x| r * (x - c) - (x - c)))
                .unwrap();
            let adv = advect(&grid, &band, &u).unwrap();
            // faces: nodes at least 2 cells from every edge of the box
            let face = |x: [f64; 3]| {
                let mut q: Vec<f64> = (0..3).map(|a| (x[a] - center[a]).abs() - 0.5 * size[a]).collect();
                q.sort_by(|a, b| b.total_cmp(a));
                q[1] < -2.0 * h
            };
            let map = |x: Vec3<f64>| r * (x - c) + c;
            let (fmax, frms, _) = surface_error(&grid, &adv, map, face);
            let (amax, arms, _) = surface_error(&grid, &adv, map, |_| true);
            let count = count_volume(&adv) / count0;
            let smooth = smooth_volume(&adv) / smooth0;
            println!(
                "{ext:?}, 30 deg about {name}: faces max {:.3} h rms {:.3} h; all near-surface nodes max {:.3} h \
                 rms {:.3} h; volume ratio {count:.4} (count), {smooth:.4} (smoothed)",
                fmax / h,
                frms / h,
                amax / h,
                arms / h
            );
            assert!(
                (count - 1.0).abs() < 0.04,
                "{ext:?} {name}: count volume ratio {count}"
            );
            assert!(
                (smooth - 1.0).abs() < 0.04,
                "{ext:?} {name}: smoothed volume ratio {smooth}"
            );
            if ext == DisplacementExtension::Linear {
                assert!(fmax < 0.1 * h, "{name}: face error {} h", fmax / h);
            }
        }
    }
}

#[test]
fn output_grid_follows_the_body() {
    let h = 0.05;
    let grid = sphere_grid([0.011, -0.023, 0.007], 0.3, h, 7);
    let band = Diffusion::new(&grid).unwrap();
    let at_rest = advect(&grid, &band, &vec![Vec3::default(); band.len()]).unwrap();
    for t in [Vec3::new(10.0, 0.0, 0.0), Vec3::new(10.013, -3.02, 0.5)] {
        let u = band.diffuse(&active_field(&grid, |_| t)).unwrap();
        let moved = advect(&grid, &band, &u).unwrap();
        println!(
            "moved by {:?}: origin {:?} -> {:?}, dims {:?} -> {:?}",
            t.to_array(),
            at_rest.origin,
            moved.origin,
            at_rest.dims,
            moved.dims
        );
        for a in 0..3 {
            let shift = moved.origin[a] - at_rest.origin[a];
            assert!(
                (shift - t.to_array()[a]).abs() <= h + 1e-9,
                "axis {a}: origin moved by {shift}"
            );
            assert!(
                moved.dims[a].abs_diff(at_rest.dims[a]) <= 1,
                "axis {a}: {:?} vs {:?}",
                moved.dims,
                at_rest.dims
            );
            // nodes on the reference lattice
            let off = (moved.origin[a] - grid.sdf.origin[a]) / h;
            assert!((off - off.round()).abs() < 1e-6);
        }
        if t.x == 10.0 {
            assert_eq!(moved.dims, at_rest.dims);
            let diff = moved
                .values
                .iter()
                .zip(&at_rest.values)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(diff < 1e-4 * h, "a whole-cell move changes the values by {diff}");
        }
        assert!(moved.values.iter().all(|v| v.is_finite()));
        let ratio = moved.inside_count() as f64 / at_rest.inside_count() as f64;
        assert!((ratio - 1.0).abs() < 0.03, "inside count ratio {ratio}");
        // the body stays inside: the output's outermost nodes are all outside
        let [nx, ny, nz] = moved.dims;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    if i == 0 || j == 0 || k == 0 || i + 1 == nx || j + 1 == ny || k + 1 == nz {
                        assert!(moved.value(i, j, k) > 0.0);
                    }
                }
            }
        }
    }
}

#[test]
fn advection_is_deterministic_and_the_fill_ring_is_harmless() {
    let grid = box_grid([0.013, 1.007, 0.021], [0.6, 0.4, 0.5], 0.05, 7);
    let band = Diffusion::new(&grid).unwrap();
    let c = Vec3::new(0.013, 1.007, 0.021);
    let r = rot_z(20.0) * rot_x(10.0);
    // a rotation plus a stretch along x by 1.8: gaps between the sources
    let f = |x: Vec3<f64>| r * (Mat3::from_diagonal(Vec3::new(1.8, 1.0, 1.0)) * (x - c)) - (x - c);
    let u = band.diffuse(&active_field(&grid, f)).unwrap();
    let many = advect(&grid, &band, &u).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let one = pool.install(|| advect(&grid, &band, &u).unwrap());
    assert_eq!(many, one, "the result depends on the thread count");
    let ring = AdvectSettings {
        fill_radius: 4.0,
        fill_weight: 1e-5,
        ..AdvectSettings::default()
    };
    let with_ring = advect_with(&grid, &band, &u, &ring).unwrap();
    assert_eq!(with_ring.dims, many.dims);
    let near = many
        .values
        .iter()
        .zip(&with_ring.values)
        .filter(|(a, _)| a.abs() < 0.05)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    println!(
        "stretched body: flood fill vs thesis-code fill ring differ by {:.2e} h near the surface",
        near / 0.05
    );
    assert!(near < 1e-3 * 0.05);
    assert!(many.values.iter().all(|v| v.is_finite()));
}

#[test]
fn errors_are_values() {
    let grid = sphere_grid([0.0, 0.0, 0.0], 0.2, 0.05, 7);
    let band = Diffusion::new(&grid).unwrap();
    let n = band.len();
    assert!(band.diffuse(&Matrix::zeros(grid.dofs() + 1, 1, 1)).is_err());
    assert!(advect(&grid, &band, &vec![Vec3::default(); n - 1]).is_err());
    let mut bad = vec![Vec3::default(); n];
    bad[n / 2] = Vec3::new(f64::NAN, 0.0, 0.0);
    assert!(advect(&grid, &band, &bad).is_err());
    bad[n / 2] = Vec3::new(1e9, 0.0, 0.0);
    let e = advect(&grid, &band, &bad).unwrap_err();
    println!("exploded displacement: {e}");
    let zero = vec![Vec3::default(); n];
    let s = AdvectSettings {
        kernel_radius: 0.0,
        ..AdvectSettings::default()
    };
    assert!(advect_with(&grid, &band, &zero, &s).is_err());
    let other = Diffusion::new(&sphere_grid([0.0, 0.0, 0.0], 0.25, 0.05, 7)).unwrap();
    assert!(advect(&grid, &other, &vec![Vec3::default(); other.len()]).is_err());
}
