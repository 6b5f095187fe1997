//! The held surface of the Dirichlet boxes (`[[dirichlet]]`): per cell, the Nitsche weights
//! of eq. 4.2.3 over the part of the body's surface inside a box, clipped exactly.

use crate::error::Error;
use crate::fem::grid::Grid;
use crate::fem::model::Model;

/// The part of a cell's surface held by the Dirichlet boxes: its Nitsche weights `w_b(e, i)`
/// (eq. 4.2.3 over the held part only) and mean outward normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NitscheFace {
    /// `int N_i` over the held surface in the cell, world units
    pub boundary: [f64; 8],
    /// the area-weighted mean unit outward normal of the held surface
    pub normal: [f64; 3],
}

/// The held surface of every cell: the part of the body's surface inside a Dirichlet box
/// (`[[dirichlet]]`: the material inside the box is held), clipped to the box exactly
/// ([`crate::cutcell::refined_boundary_in_box`]), so the held region does not depend on the
/// resolution. Overlapping boxes count their common surface once per box. Errors when a box
/// holds no part of the body's surface.
pub fn dirichlet_cells(grid: &Grid, model: &Model) -> Result<Vec<Option<NitscheFace>>, Error> {
    let h = grid.h();
    let mut faces: Vec<Option<NitscheFace>> = vec![None; grid.cells.len()];
    for (bi, bx) in model.dirichlet.iter().enumerate() {
        let mut any = false;
        for (e, c) in grid.cells.iter().enumerate() {
            if c.integrals.area <= 0.0 {
                continue;
            }
            let lo = grid.cell_origin(c).to_array();
            if (0..3).any(|d| lo[d] > bx.max[d] || lo[d] + h < bx.min[d]) {
                continue;
            }
            let part = crate::cutcell::refined_boundary_in_box(&grid.sdf, c.coord, bx.min, bx.max);
            if part.area <= 0.0 {
                continue;
            }
            any = true;
            let f = faces[e].get_or_insert(NitscheFace {
                boundary: [0.0; 8],
                normal: [0.0; 3],
            });
            for i in 0..8 {
                f.boundary[i] += part.boundary[i];
            }
            for d in 0..3 {
                // area-weighted sum for now, normalized below
                f.normal[d] += part.area * part.normal[d];
            }
        }
        if !any {
            return Err(Error::Invalid(format!(
                "dirichlet[{bi}]: the box {:?}..{:?} holds no part of the body's surface (no material is held)",
                bx.min, bx.max
            )));
        }
    }
    for f in faces.iter_mut().flatten() {
        let len = f.normal.iter().map(|x| x * x).sum::<f64>().sqrt();
        if len > 0.0 {
            f.normal = f.normal.map(|x| x / len);
        }
    }
    Ok(faces)
}
