//! The pattern and gather maps of the tetrahedral system and the per-step assembly of the
//! stiffness values, rotations, corotation forces and lumped mass (see [`super`] for the
//! maths).
//!
//! Like the grid's assembler, each stored block is the fixed-order sum of its element blocks
//! `R_t K_ij(t) R_t^T`, evaluated on the fly from the element's gradients and volume (a
//! general tetrahedral mesh has no shared element matrices to precompute). Not used, to keep
//! the thesis' formula: for an exactly orthogonal `R`, `R K_ij R^T` equals the unrotated block
//! of the rotated gradients `R g_i`, `R g_j`, which would save the two 3x3 products per block.

use super::TetMesh;
use crate::fem::assembly::Material;
use crate::fem::element::{polar_rotation, stiffness_block};
use crate::fem::grid::INACTIVE;
use gpumat::{Mat3, Matrix, SparseMatrix, SparsityPattern, Vec3};
use rayon::prelude::*;
use std::sync::Arc;

/// The BSR pattern of the free-node system and its gather maps, built once per mesh.
#[derive(Clone, Debug)]
pub struct TetAssembler {
    pattern: Arc<SparsityPattern>,
    /// free dof of each tetrahedron's vertices ([`INACTIVE`] for fixed ones)
    tet_dofs: Vec<[u32; 4]>,
    /// contributions of each stored block: `contrib[contrib_ptr[k]..contrib_ptr[k+1]]`
    contrib_ptr: Vec<u32>,
    /// `(tet, 4 i + j)`
    contrib: Vec<(u32, u8)>,
    /// tetrahedra touching each free dof: `node_tets[node_ptr[d]..node_ptr[d+1]]` as `(tet, vertex)`
    node_ptr: Vec<u32>,
    node_tets: Vec<(u32, u8)>,
}

/// Prefix sums of counts in `c[1..]`, in place.
fn prefix(c: &mut [u32]) {
    for k in 1..c.len() {
        c[k] += c[k - 1];
    }
}

impl TetAssembler {
    /// Builds the pattern (free node pairs sharing a tetrahedron) and the gather maps, in
    /// tetrahedron order (the fixed order of summation).
    pub fn new(mesh: &TetMesh) -> Self {
        let n = mesh.dofs();
        let tet_dofs: Vec<[u32; 4]> = mesh
            .tets
            .iter()
            .map(|t| t.map(|v| mesh.node_dofs[v as usize]))
            .collect();
        let entries = tet_dofs.iter().flat_map(|t| {
            t.iter().filter(|&&a| a != INACTIVE).flat_map(move |&a| {
                t.iter()
                    .filter(|&&b| b != INACTIVE)
                    .map(move |&b| (a as usize, b as usize))
            })
        });
        let pattern = SparsityPattern::from_entries(n, n, entries);
        let mut count = vec![0u32; pattern.nnz() + 1];
        let mut slots = Vec::with_capacity(tet_dofs.len() * 16);
        for (t, d) in tet_dofs.iter().enumerate() {
            for i in 0..4 {
                for j in 0..4 {
                    if d[i] == INACTIVE || d[j] == INACTIVE {
                        continue;
                    }
                    let k = pattern
                        .find(d[i] as usize, d[j] as usize)
                        .expect("pattern holds every tet pair");
                    count[k + 1] += 1;
                    slots.push((k as u32, t as u32, (4 * i + j) as u8));
                }
            }
        }
        prefix(&mut count);
        let contrib_ptr = count.clone();
        let mut next = count;
        let mut contrib = vec![(0u32, 0u8); slots.len()];
        for &(k, t, ij) in &slots {
            contrib[next[k as usize] as usize] = (t, ij);
            next[k as usize] += 1;
        }
        let mut ncount = vec![0u32; n + 1];
        for d in tet_dofs.iter().flatten().filter(|&&d| d != INACTIVE) {
            ncount[*d as usize + 1] += 1;
        }
        prefix(&mut ncount);
        let node_ptr = ncount.clone();
        let mut nnext = ncount;
        let mut node_tets = vec![(0u32, 0u8); node_ptr[n] as usize];
        for (t, d) in tet_dofs.iter().enumerate() {
            for (q, &d) in d.iter().enumerate().filter(|(_, &d)| d != INACTIVE) {
                node_tets[nnext[d as usize] as usize] = (t as u32, q as u8);
                nnext[d as usize] += 1;
            }
        }
        Self {
            pattern,
            tet_dofs,
            contrib_ptr,
            contrib,
            node_ptr,
            node_tets,
        }
    }

    /// The shared BSR pattern.
    pub fn pattern(&self) -> &Arc<SparsityPattern> {
        &self.pattern
    }
    /// The tetrahedra touching a free dof, as `(tet, vertex)`.
    pub fn tets_of(&self, dof: usize) -> &[(u32, u8)] {
        &self.node_tets[self.node_ptr[dof] as usize..self.node_ptr[dof + 1] as usize]
    }

    /// The unrotated element block `K_ij` of tetrahedron `t`.
    #[inline]
    fn element_block(mesh: &TetMesh, t: usize, i: usize, j: usize, m: &Material) -> Mat3<f64> {
        let g = &mesh.gradients[t];
        let v = mesh.volumes[t];
        stiffness_block(g[i], g[j], m.lambda * v, m.mu * v)
    }

    /// Writes the stiffness values (rotated `R_t K R_t^T` when `rotations` is given) into `k`,
    /// whose pattern must be [`TetAssembler::pattern`].
    pub fn assemble_stiffness(
        &self,
        mesh: &TetMesh,
        m: &Material,
        rotations: Option<&[Mat3<f64>]>,
        k: &mut SparseMatrix<Mat3<f64>>,
    ) {
        assert!(
            Arc::ptr_eq(k.pattern(), &self.pattern),
            "cutfem: stiffness matrix has a foreign pattern"
        );
        k.batch_values_mut(0)
            .par_iter_mut()
            .enumerate()
            .with_min_len(256)
            .for_each(|(kk, out)| {
                let mut acc = Mat3::default();
                for &(t, ij) in
                    &self.contrib[self.contrib_ptr[kk] as usize..self.contrib_ptr[kk + 1] as usize]
                {
                    let (t, i, j) = (t as usize, (ij / 4) as usize, (ij % 4) as usize);
                    let mut b = Self::element_block(mesh, t, i, j, m);
                    if let Some(r) = rotations {
                        b = r[t] * b * r[t].transpose();
                    }
                    acc = acc + b;
                }
                *out = acc;
            });
    }

    /// Per-tetrahedron rotations `polar(F)`, `F = I + sum_i u_i g_i^T` (eq. 2.7.3), from the
    /// free-dof displacement `u` (fixed vertices have `u = 0`).
    pub fn rotations(&self, mesh: &TetMesh, u: &Matrix<Vec3<f64>>, iterations: usize) -> Vec<Mat3<f64>> {
        let us = u.as_slice();
        self.tet_dofs
            .par_iter()
            .zip(mesh.gradients.par_iter())
            .map(|(d, g)| {
                let mut f = Mat3::identity();
                for i in 0..4 {
                    if d[i] != INACTIVE {
                        f = f + us[d[i] as usize].outer(g[i]);
                    }
                }
                polar_rotation(f, iterations)
            })
            .collect()
    }

    /// Adds the corotation forces `f_i -= sum_j R K_ij (R^T X_j - X_j)` to `f`.
    pub fn add_corotation_forces(
        &self,
        mesh: &TetMesh,
        m: &Material,
        rotations: &[Mat3<f64>],
        f: &mut Matrix<Vec3<f64>>,
    ) {
        let tet_forces: Vec<[Vec3<f64>; 4]> = mesh
            .tets
            .par_iter()
            .enumerate()
            .map(|(t, tet)| {
                let r = rotations[t];
                let rt = r.transpose();
                let x0 = mesh.positions[tet[0] as usize];
                let d: [Vec3<f64>; 4] = std::array::from_fn(|j| {
                    let x = mesh.positions[tet[j] as usize] - x0;
                    rt * x - x
                });
                std::array::from_fn(|i| {
                    let mut s = Vec3::default();
                    for j in 1..4 {
                        s = s + Self::element_block(mesh, t, i, j, m) * d[j];
                    }
                    -(r * s)
                })
            })
            .collect();
        f.as_mut_slice()
            .par_iter_mut()
            .enumerate()
            .for_each(|(dof, out)| {
                for &(t, q) in self.tets_of(dof) {
                    *out = *out + tet_forces[t as usize][q as usize];
                }
            });
    }

    /// Lumped mass per free dof: `density * sum_t V_t / 4`.
    pub fn lumped_mass(&self, mesh: &TetMesh, density: f64) -> Matrix<f64> {
        Matrix::from_fn(mesh.dofs(), 1, 1, |dof, _, _| {
            density
                * self
                    .tets_of(dof)
                    .iter()
                    .map(|&(t, _)| 0.25 * mesh.volumes[t as usize])
                    .sum::<f64>()
        })
    }
}
