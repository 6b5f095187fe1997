//! cutfem: cut-cell FEM on SDF grids (thesis ch. 2 and 4). Not implemented yet: see issue 3.
