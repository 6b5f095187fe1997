//! adjoint: gradients and parameter reconstruction (thesis ch. 5). Not implemented yet: see issue 4.
