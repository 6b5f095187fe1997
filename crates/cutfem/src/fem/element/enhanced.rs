//! The grid element's stiffness (`[numerics] element`): the thesis' trilinear hexahedron (still
//! the default, `docs/simulation.md`, "Element"), and the trilinear hexahedron with incompatible modes (Wilson et al. 1973, in the
//! mean-free form of Taylor, Beresford & Wilson 1976, "QM6"), both with exact or corner-rule
//! integration over the cut part of the cell.
//!
//! # Why: locking
//!
//! The trilinear hexahedron cannot bend: under a pure bending moment its displacement
//! `u_x = xi eta` comes with a parasitic shear strain `gamma_xy = xi` that stores energy a real
//! beam does not have, so a beam four cells thick is 20-25% too stiff (shear locking; the
//! cantilever of `docs/simulation.md`), and near `nu = 1/2` its volume constraint locks too.
//! The incompatible modes add per cell and per axis `d` the bubble
//! `phi_d = 4 xi_d (1 - xi_d)` (`xi` the unit-cube coordinates) to each displacement
//! component: 9 internal degrees of freedom, condensed statically per cell. The bubble
//! `phi_x` in `u_y` cancels the parasitic shear of the bending mode exactly, so bending of
//! a parallelepiped is exact.
//!
//! # The maths
//!
//! With `a = grad N_I`, `b = grad N_J` for two modes `I, J` (8 corners, 3 bubbles), the
//! integrand block of eq. 4.4.5 is `lambda a_p b_q + mu a_q b_p + mu (a . b) delta_pq`. All
//! mode gradients are polynomials in the unit-cube coordinates in the span of the 7 monomials
//! `m = (1, xi, eta, zeta, xi eta, eta zeta, xi zeta)` (`d N_i / d xi` is bilinear in the other
//! two coordinates; `d phi_d / d xi_d = 4 - 8 xi_d`), so with the coefficient vectors
//! `c_{I,q}` of `d N_I / d xi_q` and the Gram matrix `G = int_{Omega_e} m m^T` of the cut part
//! (in unit-cube coordinates) every integral is a quadratic form:
//! `H_{IJ}[p][q] = int d_p N_I d_q N_J = c_{I,p}^T G c_{J,q}`, and
//!
//! ```text
//! K_IJ = h (lambda H_IJ + mu (H_IJ^T + tr(H_IJ) I))      (h: the unit-cube scaling h^3 / h^2)
//! ```
//!
//! `G` comes from the cut-cell moments (`CellIntegrals::moments`, exact to rounding for a
//! planar cut on each sub-cell: *exact* integration; its entries need the moments of degree
//! `<= 4` with each exponent `<= 2`), or from the thesis' corner rule
//! `G = sum_c w_v(c) / h^3 m(v_c) m(v_c)^T` (sec. 4.4.1.1: exact only for trilinear
//! integrands; it overweights the linear part of a strain 3x in a full cell).
//!
//! *Mean-free bubbles (QM6).* A constant stress does no work on a bubble only if
//! `int_{Omega_e} grad phi_d = 0`: true on a full cell, false on a cut one. Each bubble
//! gradient is therefore shifted by its mean over the cut part,
//! `grad phi_d <- grad phi_d - (1/|Omega_e|) int_{Omega_e} grad phi_d` (one change of the
//! constant coefficient, computed from `G`'s first row), so that the patch test holds on cut
//! cells too (`fem_statics::patch_test_uniform_strain`, `..._on_cut_cells`).
//!
//! *Static condensation.* With the corner (`u`) and bubble (`a`) parts of the 33 x 33 element
//! matrix, `K_c = K_uu - K_ua K_aa^+ K_au`, the bubble amplitudes `alpha = -T u` with
//! `T = K_aa^+ K_au`. `K_aa` is positive semidefinite; on a sliver of a cut cell a bubble can
//! be nearly constant there, so its mean-free gradient vanishes. The pseudo-inverse is a
//! Cholesky factorization that drops every pivot below `1e-10` of the largest diagonal entry
//! (the dropped bubble carries no energy: since the whole matrix is semidefinite, its coupling
//! `K_au` vanishes too). `K_c = K_uu - W^T W` with `W = L^{-1} K_au` is symmetric to the bit.
//!
//! *Corotation* rotates the condensed blocks, `R K_c R^T` (eq. 4.4.7): the bubbles live in the
//! unrotated frame of the cell.
//!
//! *Lame derivatives (adjoint, eq. 5.5.5).* `K_c = P^T K P` with `P = [I; -T]`, and since `T`
//! minimizes the energy, `dK_c = P^T dK P` (no term from `dT`). So for the cell's term
//! `S = l^T K_c b` the derivatives are those of the full element at the lifted vectors
//! `(l, -T l)`, `(b, -T b)`: with the gradient polynomials `Gl[p][q] = sum_I l_{I,p} c_{I,q}`,
//! `dS/dlambda = h tr(Gl)^T G tr(Gb)` and
//! `dS/dmu = h sum_pq (Gl[p][q]^T G Gb[q][p] + Gl[p][q]^T G Gb[p][q])`
//! ([`ElementSet::lame_derivatives`], checked against central differences in
//! `adjoint/tests/local.rs`).
//!
//! The Nitsche terms (eq. 4.4.15-4.4.17) use the traction of the corner field, its volumetric
//! part from the cell's mean dilatation ([`mean_gradients`]; `fem::sim::dirichlet`, "The
//! volumetric traction"): the bubbles are internal strain enhancements of the cell (the
//! enhanced-assumed-strain reading of the incompatible modes), not part of the displacement
//! the Dirichlet condition holds.

use super::CORNER_SIGNS;
use crate::cutcell::{moment_index, CellIntegrals};
use gpumat::{Mat3, Vec3};

/// The grid element (scene key `[numerics] element`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Element {
    /// the thesis' element: trilinear, corner rule (sec. 4.4.1.1)
    Trilinear,
    /// trilinear, exact integration over the cut part
    TrilinearExact,
    /// trilinear with incompatible modes, corner rule
    IncompatibleCorner,
    /// trilinear with incompatible modes, exact integration (the most accurate: see
    /// `docs/simulation.md`, "Element"; the default)
    #[default]
    Incompatible,
}

impl Element {
    /// Every element, in the order of the docs.
    pub const ALL: [Element; 4] = [
        Element::Trilinear,
        Element::TrilinearExact,
        Element::IncompatibleCorner,
        Element::Incompatible,
    ];
    /// The scene name.
    pub fn name(self) -> &'static str {
        match self {
            Element::Trilinear => "trilinear",
            Element::TrilinearExact => "trilinear_exact",
            Element::IncompatibleCorner => "incompatible_corner",
            Element::Incompatible => "incompatible",
        }
    }
    /// The element of a scene name.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.name() == name)
    }
    /// Whether it has the incompatible modes.
    pub fn has_modes(self) -> bool {
        matches!(self, Element::IncompatibleCorner | Element::Incompatible)
    }
    /// Whether it integrates exactly (else with the corner rule).
    pub fn exact(self) -> bool {
        matches!(self, Element::TrilinearExact | Element::Incompatible)
    }
}

/// Number of monomials of the gradient polynomials.
pub const MONOMIALS: usize = 7;
/// The exponents of the monomials `1, xi, eta, zeta, xi eta, eta zeta, xi zeta`.
const EXPONENTS: [[usize; 3]; MONOMIALS] = [
    [0, 0, 0],
    [1, 0, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 1, 0],
    [0, 1, 1],
    [1, 0, 1],
];
/// Modes of a cell: 8 corners and 3 bubbles.
const MODES: usize = 11;

/// A polynomial in the monomials.
type Poly = [f64; MONOMIALS];
/// The Gram matrix `int m m^T` of the monomials over the cut part (unit-cube coordinates).
pub type Gram = [[f64; MONOMIALS]; MONOMIALS];

/// The share of the material's stiffness given to the empty part of a cut cell by the exactly
/// integrated elements (the finite cell method's `alpha`): their Gram matrix is
/// `G_inside + alpha (G_cell - G_inside)`.
///
/// Why: a corner of a cut cell whose material sits near the opposite corner has almost no
/// stiffness under exact integration (its shape function's gradient nearly vanishes there) and
/// almost no mass. With corotation such corners drifted without bound: in the held bunny (12
/// cells across, E = 20, `alpha = 0`) the body's median displacement stayed 9e-3 while corners
/// with `int N_i < 1e-9 h^3` reached 0.8 in 10 steps and broke the level-set advection;
/// `alpha = 1e-8` still let them reach 0.2, `1e-6` keeps them with the body (largest
/// displacement 0.057, the thesis element's 0.062). The corner-rule elements need no such term:
/// their stiffness at a corner is proportional to its volume weight, like its lumped mass. The
/// cost in accuracy is the energy of `alpha` times the empty volume (1e-6 relative at most).
pub const FICTITIOUS_STIFFNESS: f64 = 1e-6;

/// The moments of the full unit cube, `int xi^a eta^b zeta^c = 1 / ((a + 1)(b + 1)(c + 1))`.
const FULL_MOMENTS: [f64; 27] = {
    let mut m = [0.0; 27];
    let mut k = 0;
    while k < 27 {
        let (a, b, c) = (k % 3, (k / 3) % 3, k / 9);
        m[k] = 1.0 / ((a + 1) * (b + 1) * (c + 1)) as f64;
        k += 1;
    }
    m
};

/// The Gram matrix of a cell's inside part for `element`: from the exact moments (with the
/// empty part at [`FICTITIOUS_STIFFNESS`]), or from the corner rule's weights (cell size `h`).
pub fn gram(integrals: &CellIntegrals, h: f64, element: Element) -> Gram {
    let mut g = [[0.0; MONOMIALS]; MONOMIALS];
    for (m, em) in EXPONENTS.iter().enumerate() {
        for (n, en) in EXPONENTS.iter().enumerate() {
            g[m][n] = if element.exact() {
                let k = moment_index(em[0] + en[0], em[1] + en[1], em[2] + en[2]);
                let inside = integrals.moments[k];
                inside + FICTITIOUS_STIFFNESS * (FULL_MOMENTS[k] - inside)
            } else {
                let h3 = h * h * h;
                (0..8)
                    .map(|c| {
                        let at = |e: &[usize; 3]| (0..3).all(|d| e[d] == 0 || (c >> d) & 1 == 1);
                        if at(em) && at(en) {
                            integrals.volume[c] / h3
                        } else {
                            0.0
                        }
                    })
                    .sum()
            };
        }
    }
    g
}

/// `x^T G y`.
#[inline]
fn form(g: &Gram, x: &Poly, y: &Poly) -> f64 {
    let mut s = 0.0;
    for m in 0..MONOMIALS {
        if x[m] != 0.0 {
            let gy: f64 = (0..MONOMIALS).map(|n| g[m][n] * y[n]).sum();
            s += x[m] * gy;
        }
    }
    s
}

/// The gradient polynomials `grads[I][q]` (`d / d xi_q` of mode `I`) on the unit cube: the 8
/// corners' trilinear `N_i`, then (with `modes`) the mean-free bubbles.
fn mode_gradients(g: &Gram, modes: bool) -> [[Poly; 3]; MODES] {
    let mut out = [[[0.0; MONOMIALS]; 3]; MODES];
    for (i, gi) in out.iter_mut().enumerate().take(8) {
        for (q, p) in gi.iter_mut().enumerate() {
            // d N_i / d xi_q = s_q f_a1 f_a2 with f = xi (bit set) or 1 - xi
            let s = if (i >> q) & 1 == 1 { 1.0 } else { -1.0 };
            let [a1, a2] = match q {
                0 => [1, 2],
                1 => [0, 2],
                _ => [0, 1],
            };
            let lin = |a: usize| {
                if (i >> a) & 1 == 1 {
                    (0.0, 1.0)
                } else {
                    (1.0, -1.0)
                }
            };
            let ((c1, d1), (c2, d2)) = (lin(a1), lin(a2));
            let pair = match (a1, a2) {
                (0, 1) => 4,
                (1, 2) => 5,
                _ => 6,
            };
            p[0] = s * c1 * c2;
            p[1 + a1] = s * d1 * c2;
            p[1 + a2] = s * c1 * d2;
            p[pair] = s * d1 * d2;
        }
    }
    if modes {
        let volume = g[0][0];
        for d in 0..3 {
            let p = &mut out[8 + d][d];
            p[0] = 4.0;
            p[1 + d] = -8.0;
            if volume > 0.0 {
                // the mean over the cut part: int p = p^T G e_0
                let mean = (0..MONOMIALS).map(|m| p[m] * g[m][0]).sum::<f64>() / volume;
                p[0] -= mean;
            }
        }
    }
    out
}

/// The `lambda` and `mu` parts (unit coefficients) of the blocks between all modes, world units.
fn mode_blocks(g: &Gram, grads: &[[Poly; 3]; MODES], h: f64, modes: usize) -> Vec<[Mat3<f64>; 2]> {
    let mut out = vec![[Mat3::default(); 2]; modes * modes];
    for i in 0..modes {
        for j in i..modes {
            let hm = Mat3::from_rows(std::array::from_fn(|p| {
                std::array::from_fn(|q| h * form(g, &grads[i][p], &grads[j][q]))
            }));
            let lam = hm;
            let mu = hm.transpose() + Mat3::from_scalar(hm.trace());
            out[i * modes + j] = [lam, mu];
            out[j * modes + i] = [lam.transpose(), mu.transpose()];
        }
    }
    out
}

/// `a_i = 4 / |Omega_e| int_{Omega_e} grad_xi N_i` from the Gram matrix's first column (the
/// integrals of the monomials); the corner signs for an empty part.
fn inside_gradient_weights(g: &Gram, grads: &[[Poly; 3]; MODES]) -> [Vec3<f64>; 8] {
    let volume = g[0][0];
    if volume.is_nan() || volume <= 0.0 {
        return CORNER_SIGNS;
    }
    std::array::from_fn(|i| {
        let mean = |q: usize| (0..MONOMIALS).map(|m| grads[i][q][m] * g[m][0]).sum::<f64>() / volume;
        Vec3::new(4.0 * mean(0), 4.0 * mean(1), 4.0 * mean(2))
    })
}

/// The mean world gradients `(1/|Omega_e|) int_{Omega_e} grad N_i` of the 8 corner functions
/// over a cell's inside part (Gram matrix `g` from [`gram`], cell size `h`): the cell's mean
/// dilatation is `sum_i gbar_i . u_i`. Zero for an empty part.
pub fn mean_gradients(g: &Gram, h: f64) -> [Vec3<f64>; 8] {
    let volume = g[0][0];
    if volume.is_nan() || volume <= 0.0 {
        return [Vec3::default(); 8];
    }
    let grads = mode_gradients(g, false);
    // a_i = 4 mean(grad_xi N_i); the world gradient is grad_xi / h
    inside_gradient_weights(g, &grads).map(|a| a * (0.25 / h))
}

/// Relative pivot below which a bubble is dropped from the condensation.
const PIVOT_REL: f64 = 1e-10;

/// The element of one cell geometry for one material: the condensed blocks and what the
/// adjoint needs to differentiate them.
#[derive(Clone, Debug)]
pub struct ElementSet {
    /// the condensed (for the trilinear element: plain) blocks `K_ij`, world units
    pub k: [[Mat3<f64>; 8]; 8],
    /// the Gram matrix of the cut part
    gram: Gram,
    /// the gradient polynomials of the modes (bubbles mean-free)
    grads: [[Poly; 3]; MODES],
    /// `T = K_aa^+ K_au` (9 x 24, bubble amplitudes `alpha = -T u`), with modes
    condense: Option<Box<[[f64; 24]; 9]>>,
    /// cell size
    h: f64,
    /// the corotation's gradient weights ([`ElementSet::gradient_weights`])
    weights: [Vec3<f64>; 8],
}

impl ElementSet {
    /// The element of a cell with Gram matrix `g` (see [`gram`]) and size `h`.
    pub fn new(g: Gram, h: f64, element: Element, lambda: f64, mu: f64) -> Self {
        let modes = element.has_modes();
        let grads = mode_gradients(&g, modes);
        let n = if modes { MODES } else { 8 };
        let parts = mode_blocks(&g, &grads, h, n);
        let block = |i: usize, j: usize| {
            let [l, m] = parts[i * n + j];
            l * lambda + m * mu
        };
        let mut k: [[Mat3<f64>; 8]; 8] = std::array::from_fn(|i| std::array::from_fn(|j| block(i, j)));
        let mut condense = None;
        if modes {
            // K_aa (9 x 9) and K_au (9 x 24) as scalars
            let kaa: [[f64; 9]; 9] =
                std::array::from_fn(|r| std::array::from_fn(|c| block(8 + r / 3, 8 + c / 3).m[r % 3][c % 3]));
            let kau: [[f64; 24]; 9] =
                std::array::from_fn(|r| std::array::from_fn(|c| block(8 + r / 3, c / 3).m[r % 3][c % 3]));
            let (l, keep) = semidefinite_cholesky(&kaa);
            // W = L^{-1} K_au (dropped rows zero)
            let mut w = [[0.0; 24]; 9];
            for r in 0..9 {
                if !keep[r] {
                    continue;
                }
                for c in 0..24 {
                    let s: f64 = (0..r).map(|t| l[r][t] * w[t][c]).sum();
                    w[r][c] = (kau[r][c] - s) / l[r][r];
                }
            }
            // K_c = K_uu - W^T W
            for i in 0..8 {
                for j in 0..8 {
                    let mut b = k[i][j];
                    for p in 0..3 {
                        for q in 0..3 {
                            let s: f64 = (0..9).map(|t| w[t][3 * i + p] * w[t][3 * j + q]).sum();
                            b.m[p][q] -= s;
                        }
                    }
                    k[i][j] = b;
                }
            }
            // T = L^{-T} W
            let mut t = Box::new([[0.0; 24]; 9]);
            for r in (0..9).rev() {
                if !keep[r] {
                    continue;
                }
                for c in 0..24 {
                    let s: f64 = (r + 1..9).map(|u| l[u][r] * t[u][c]).sum();
                    t[r][c] = (w[r][c] - s) / l[r][r];
                }
            }
            condense = Some(t);
        }
        let weights = if element.exact() {
            inside_gradient_weights(&g, &grads)
        } else {
            CORNER_SIGNS
        };
        Self {
            k,
            gram: g,
            grads,
            condense,
            h,
            weights,
        }
    }

    /// The weights `a_i` of the cell's average deformation gradient for corotation,
    /// `F = I + 1/(4h) sum_i u_i a_i^T` ([`super::deformation_gradient_with`]): for the
    /// corner-rule elements the thesis' gradient at the cell's centre (`a_i = s_i`, eq. 4.4.8);
    /// for the exactly integrated ones the average over the cell's *inside part*,
    /// `a_i = 4 / |Omega_e| int_{Omega_e} grad_xi N_i` (the same on a full cell). On a cut cell
    /// whose material sits in a corner the centre gradient is that of corners far outside the
    /// body, which only this cell holds: their free motion rotated the cell and fed back into
    /// the corotated forces, and a held bunny (12 cells across, E = 20) blew up in 6 steps with
    /// exact integration; the inside average follows the material.
    pub fn gradient_weights(&self) -> &[Vec3<f64>; 8] {
        &self.weights
    }

    /// The element of a cell's integrals.
    pub fn of_cell(integrals: &CellIntegrals, h: f64, element: Element, lambda: f64, mu: f64) -> Self {
        Self::new(gram(integrals, h, element), h, element, lambda, mu)
    }

    /// The bubble amplitudes `alpha = -T u` of corner values `u` (zero without modes).
    pub fn bubbles(&self, u: &[Vec3<f64>; 8]) -> [Vec3<f64>; 3] {
        let mut a = [Vec3::default(); 3];
        if let Some(t) = &self.condense {
            let flat: [f64; 24] = std::array::from_fn(|c| u[c / 3].to_array()[c % 3]);
            for (d, ad) in a.iter_mut().enumerate() {
                *ad = Vec3::from_array(std::array::from_fn(|p| {
                    -(0..24).map(|c| t[3 * d + p][c] * flat[c]).sum::<f64>()
                }));
            }
        }
        a
    }

    /// `(dS/dlambda, dS/dmu)` of `S = sum_ij l_i^T K_ij b_j` (module docs: the full element
    /// at the lifted vectors).
    pub fn lame_derivatives(&self, l: &[Vec3<f64>; 8], b: &[Vec3<f64>; 8]) -> (f64, f64) {
        let (al, ab) = (self.bubbles(l), self.bubbles(b));
        let modes = if self.condense.is_some() { MODES } else { 8 };
        // gradient polynomials: gp[p][q] = sum_I v_{I,p} c_{I,q}
        let grad_poly = |v: &[Vec3<f64>; 8], a: &[Vec3<f64>; 3]| {
            let mut gp = [[[0.0; MONOMIALS]; 3]; 3];
            for i in 0..modes {
                let vi = if i < 8 { v[i] } else { a[i - 8] }.to_array();
                for (p, row) in gp.iter_mut().enumerate() {
                    if vi[p] == 0.0 {
                        continue;
                    }
                    for (q, poly) in row.iter_mut().enumerate() {
                        for m in 0..MONOMIALS {
                            poly[m] += vi[p] * self.grads[i][q][m];
                        }
                    }
                }
            }
            gp
        };
        let (gl, gb) = (grad_poly(l, &al), grad_poly(b, &ab));
        let trace =
            |g: &[[Poly; 3]; 3]| -> Poly { std::array::from_fn(|m| g[0][0][m] + g[1][1][m] + g[2][2][m]) };
        let dl = self.h * form(&self.gram, &trace(&gl), &trace(&gb));
        let mut dm = 0.0;
        for p in 0..3 {
            for q in 0..3 {
                dm += form(&self.gram, &gl[p][q], &gb[q][p]) + form(&self.gram, &gl[p][q], &gb[p][q]);
            }
        }
        (dl, self.h * dm)
    }
}

/// Cholesky `A = L L^T` of a symmetric positive semidefinite 9 x 9 matrix, dropping (and
/// marking `false`) every pivot below [`PIVOT_REL`] of the largest diagonal entry together with
/// its row and column.
fn semidefinite_cholesky(a: &[[f64; 9]; 9]) -> ([[f64; 9]; 9], [bool; 9]) {
    let scale = (0..9).map(|i| a[i][i]).fold(0.0f64, f64::max);
    let mut l = [[0.0; 9]; 9];
    let mut keep = [false; 9];
    for j in 0..9 {
        let d = a[j][j] - (0..j).map(|t| l[j][t] * l[j][t]).sum::<f64>();
        // (NaN pivots are dropped too)
        if d.partial_cmp(&(PIVOT_REL * scale)) != Some(std::cmp::Ordering::Greater) {
            continue;
        }
        keep[j] = true;
        let ljj = d.sqrt();
        l[j][j] = ljj;
        for i in j + 1..9 {
            let s: f64 = (0..j).map(|t| l[i][t] * l[j][t]).sum();
            l[i][j] = (a[i][j] - s) / ljj;
        }
    }
    (l, keep)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The trilinear element with the corner rule is the thesis' element of
    /// [`super::super::StiffnessTables::block`].
    #[test]
    fn corner_rule_trilinear_is_the_thesis_element() {
        let h = 0.1;
        let t = super::super::StiffnessTables::new(h);
        let mut ci = CellIntegrals::full(h);
        ci.volume = [1.0, 0.5, 0.2, 0.0, 0.7, 0.1, 0.3, 0.05].map(|x| x * h * h * h / 8.0);
        let (lambda, mu) = (1.7, 0.9);
        let set = ElementSet::of_cell(&ci, h, Element::Trilinear, lambda, mu);
        for i in 0..8 {
            for j in 0..8 {
                let want = t.block(&ci.volume, i, j, lambda, mu);
                let d = set.k[i][j] - want;
                assert!(d.m.iter().flatten().all(|x| x.abs() < 1e-14), "({i}, {j}): {d:?}");
            }
        }
    }
}
