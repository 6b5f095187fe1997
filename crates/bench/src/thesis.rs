//! The thesis' Appendix B figures (Tables B.1-B.4), in milliseconds, measured on an Intel
//! i7-6700 (4 cores, 3.4 GHz) with an NVIDIA GeForce GTX 1060 6GB, Windows 10, averages of
//! ten runs (thesis sec. 3.5). Reported next to our numbers for reference only.

/// Where the thesis' numbers come from.
pub const HARDWARE: &str = "thesis (Appendix B): Intel i7-6700 (4 cores, 3.4 GHz) CPU for Eigen/numpy, \
NVIDIA GeForce GTX 1060 6GB GPU for cuBLAS/cuSPARSE/cuMat, Windows 10; milliseconds, averages of 10 runs";

/// Table B.1 (k = 2): `(n, cuBLAS, cuMat, Eigen, numpy)` in ms.
pub const B1: &[(usize, f64, f64, f64, f64)] = &[
    (100, 0.0001488, 0.0037088, 0.0003004, 0.00495774),
    (1_000, 0.0001456, 0.00369664, 0.0004506, 0.00573897),
    (10_000, 0.0001504, 0.00368832, 0.0055286, 0.0202516),
    (100_000, 0.00015808, 0.0037232, 0.0484356, 0.160451),
    (1_000_000, 0.00020032, 0.00370272, 1.614, 6.66087),
    (10_000_000, 0.00022208, 0.00377824, 18.236, 73.0739),
    (50_000_000, 0.00022336, 0.00571136, 93.9108, 370.887),
];

/// Table B.2 (n = 10^6): `(k, cuBLAS, cuMat, Eigen, numpy)` in ms.
pub const B2: &[(usize, f64, f64, f64, f64)] = &[
    (1, 0.00014336, 0.00361568, 1.38066, 2.96753),
    (2, 0.00021216, 0.00368544, 1.58203, 6.78211),
    (3, 0.00194784, 0.00397888, 1.97174, 10.4266),
    (4, 0.166469, 0.00422528, 2.0635, 14.199),
    (5, 0.167558, 0.00430688, 2.40177, 19.0094),
    (6, 0.325902, 0.00459712, 2.65564, 21.729),
    (7, 0.330418, 0.0045984, 2.95554, 25.8566),
    (8, 0.488936, 0.00764864, 3.31724, 29.1512),
    (9, 0.48627, 0.00508224, 3.63084, 33.2603),
    (10, 0.643359, 0.00545568, 4.14723, 36.7435),
];

/// Table B.3 (SpMV, 2D Poisson, grid size g): `(g, cuSPARSE, cuMat, Eigen)` in ms.
pub const B3: &[(usize, f64, f64, f64)] = &[
    (10, 0.010252, 0.00955791, 0.0013821),
    (100, 0.0121149, 0.012815, 0.0651417),
    (1_000, 0.491989, 0.405348, 2.85587),
    (10_000, 49.2694, 37.1613, 302.804),
];

/// Table B.4 (CG, 2D diffusion, grid size g): `(g, cuMat, Eigen)` in ms.
pub const B4: &[(usize, f64, f64)] = &[
    (10, 0.350014, 0.0264716),
    (100, 3.79062, 17.7015),
    (1_000, 1160.36, 15700.8),
];

/// Caveat on the thesis' GPU columns of B.1/B.2, derived from the numbers themselves.
pub const GPU_TIMING_CAVEAT: &str =
    "the thesis' cuBLAS/cuMat times in B.1/B.2 stay near 0.004 ms up to n = 5e7, \
i.e. 600 MB in 0.0057 ms (~100 TB/s, 500x the GTX 1060's 192 GB/s): they time the asynchronous kernel \
launch, not its completion, so only the CPU columns (Eigen, numpy) are comparable with ours";

/// Row of B.1 for `n`.
pub fn b1(n: usize) -> Option<(f64, f64, f64, f64)> {
    B1.iter().find(|r| r.0 == n).map(|r| (r.1, r.2, r.3, r.4))
}
/// Row of B.2 for `k`.
pub fn b2(k: usize) -> Option<(f64, f64, f64, f64)> {
    B2.iter().find(|r| r.0 == k).map(|r| (r.1, r.2, r.3, r.4))
}
/// Row of B.3 for `g`.
pub fn b3(g: usize) -> Option<(f64, f64, f64)> {
    B3.iter().find(|r| r.0 == g).map(|r| (r.1, r.2, r.3))
}
/// Row of B.4 for `g`.
pub fn b4(g: usize) -> Option<(f64, f64)> {
    B4.iter().find(|r| r.0 == g).map(|r| (r.1, r.2))
}
