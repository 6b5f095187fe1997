//! The coarse trilinear basis of the `stiffness_field` parameter (module docs of
//! [`crate::params`]).

use crate::Error;
use gpumat::Vec3;

/// The coarse trilinear basis of the `stiffness_field` parameter: `nodes` = `(cells+1)^3`
/// coefficients `c_k` on a grid spanning the active cells' centers, and per active cell the
/// trilinear weights of its center. The cell factors are `s_e = exp(sum_k w_ek c_k)`.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldBasis {
    /// coarse cells per axis
    pub cells: [usize; 3],
    /// lower corner of the coarse grid
    pub lo: [f64; 3],
    /// upper corner
    pub hi: [f64; 3],
    /// per active cell: `(coefficient, weight)` of the 8 coarse nodes around its center
    pub weights: Vec<[(u32, f64); 8]>,
}

impl FieldBasis {
    /// The basis with `cells` coarse cells per axis over `grid`'s active cells.
    pub fn new(grid: &cutfem::fem::Grid, cells: [usize; 3]) -> Result<Self, Error> {
        cutfem::scene::StiffnessFieldSection::check(cells).map_err(Error::Invalid)?;
        let h = grid.h();
        let centers: Vec<[f64; 3]> = grid
            .cells
            .iter()
            .map(|c| (grid.cell_origin(c) + Vec3::splat(0.5 * h)).to_array())
            .collect();
        if centers.is_empty() {
            return Err(Error::invalid(
                "model.stiffness_field: the body has no active cells",
            ));
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for c in &centers {
            for d in 0..3 {
                lo[d] = lo[d].min(c[d]);
                hi[d] = hi[d].max(c[d]);
            }
        }
        let (nx, ny) = (cells[0] + 1, cells[1] + 1);
        let weights = centers
            .iter()
            .map(|c| {
                let mut idx = [0usize; 3];
                let mut f = [0.0; 3];
                for d in 0..3 {
                    let span = (hi[d] - lo[d]).max(1e-12);
                    let t = ((c[d] - lo[d]) / span * cells[d] as f64).clamp(0.0, cells[d] as f64);
                    let i = (t.floor() as usize).min(cells[d] - 1);
                    idx[d] = i;
                    f[d] = t - i as f64;
                }
                std::array::from_fn(|k| {
                    let b = [k & 1, (k >> 1) & 1, k >> 2];
                    let node = (idx[0] + b[0]) + nx * ((idx[1] + b[1]) + ny * (idx[2] + b[2]));
                    let w: f64 = (0..3)
                        .map(|d| if b[d] == 1 { f[d] } else { 1.0 - f[d] })
                        .product();
                    (node as u32, w)
                })
            })
            .collect();
        Ok(Self {
            cells,
            lo,
            hi,
            weights,
        })
    }

    /// Number of coefficients.
    pub fn len(&self) -> usize {
        self.cells.iter().map(|c| c + 1).product()
    }
    /// Never empty.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The coefficient labels `stiffness_field[i,j,k]`.
    pub fn labels(&self) -> Vec<String> {
        let [nx, ny, nz] = self.cells.map(|c| c + 1);
        let mut out = Vec::with_capacity(nx * ny * nz);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    out.push(format!("stiffness_field[{i},{j},{k}]"));
                }
            }
        }
        out
    }

    /// The cell factors `s_e = exp(sum_k w_ek c_k)` of coefficients `c`.
    pub fn scales(&self, c: &[f64]) -> Vec<f64> {
        self.weights
            .iter()
            .map(|w| w.iter().map(|&(k, wk)| wk * c[k as usize]).sum::<f64>().exp())
            .collect()
    }

    /// The gradient with respect to the coefficients of a function with cell-factor gradient
    /// `g` at cell factors `s`.
    pub fn chain(&self, s: &[f64], g: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.len()];
        for ((w, &se), &ge) in self.weights.iter().zip(s).zip(g) {
            for &(k, wk) in w {
                out[k as usize] += ge * se * wk;
            }
        }
        out
    }
}
