"""scikit-fem + scipy peer of the `step-peer` table: Newmark steps of the thesis' cuboid held at
one end, as a scikit-fem user would write them.

The cuboid (center (0, 1, 0), size 1.29 x 0.4 x 0.8; crates/cutfem/src/fem/model.rs,
`thesis_cuboid`) on a structured mesh of trilinear hexahedra (ElementHex1, 2x2x2 Gauss points)
whose cells are at most 1/(2r) wide, r the thesis' resolution: at r = 10, 26 x 8 x 16 cells and
4131 nodes, the grid of Table B.5. Linear elasticity E = 2000, nu = 0.3, density 1, lumped mass,
gravity (0, -10, 0), Rayleigh damping a1 = 0.1, a2 = 0.01, the Newmark-1 scheme of the thesis
(eq. 2.6.2; crates/cutfem/src/fem/assembly/newmark.rs):

    A = cm M + ck K,  b = cm M u + cu K u + cv M v + dt f,
    cm = 1/(theta dt) + a1, ck = a2 + theta dt, cu = a2 - (1 - theta) dt, cv = 1/theta,

dt = 0.01, theta = 0.6. The nodes with x <= -0.55 (the hold box [-0.9, -0.55] in x) are held by
strong Dirichlet conditions (skfem's condense).

Timed apart (seconds per step but for the one-off costs):
  assembly_s  K assembled by skfem's asm, once (A linear model keeps it; a corotated or
              nonlinear one must assemble every step: its step is assembly_s + system_s + cg_s)
  system_s    A, b and the condensation to the free dofs, every step
  cg_s        scipy.sparse.linalg.cg with a Jacobi preconditioner, relative tolerance TOL,
              started at u + dt v (as ours, thesis 4.4.18); cg_iterations per step
  direct_s    a solve with scipy's SuperLU factor of A (splu, made once: A does not change for
              a linear model; direct_factor_s is its one-off cost)

usage: python3 step_peer.py R STEPS TOL
prints: time_s=... (system + cg per step: the linear step) and the fields above, nodes, dofs,
        max_u (the largest nodal displacement after the steps, CG's), versions
"""

import sys
import time

import numpy as np
import scipy
import scipy.sparse.linalg as spla
import skfem
from skfem import Basis, BilinearForm, ElementHex1, ElementVector, MeshHex, asm, condense
from skfem.models.elasticity import lame_parameters, linear_elasticity


def main():
    r, steps, tol = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
    h = 1.0 / (2 * r)
    lo, size = np.array([-0.645, 0.8, -0.4]), np.array([1.29, 0.4, 0.8])
    cells = np.ceil(size / h - 1e-9).astype(int)
    axes = [np.linspace(lo[d], lo[d] + size[d], cells[d] + 1) for d in range(3)]
    mesh = MeshHex.init_tensor(*axes)
    # 2x2x2 Gauss points, as ours (skfem's default for ElementHex1 is 4x4x4: 5x the assembly time)
    basis = Basis(mesh, ElementVector(ElementHex1()), intorder=2)

    young, poisson, density = 2000.0, 0.3, 1.0
    dt, theta, a1, a2 = 0.01, 0.6, 0.1, 0.01
    cm, ck = 1.0 / (theta * dt) + a1, a2 + theta * dt
    cu, cv = a2 - (1.0 - theta) * dt, 1.0 / theta
    lam, mu = lame_parameters(young, poisson)

    @BilinearForm
    def mass(u, v, w):
        return density * (u[0] * v[0] + u[1] * v[1] + u[2] * v[2])

    t0 = time.perf_counter()
    m = np.asarray(asm(mass, basis).sum(axis=1)).ravel()  # lumped
    mass_s = time.perf_counter() - t0
    M = scipy.sparse.diags(m)
    f = m * np.tile([0.0, -10.0, 0.0], mesh.p.shape[1])  # dofs interleaved per node
    held = basis.get_dofs(lambda x: x[0] <= -0.55 + 1e-9).all()
    free = np.setdiff1d(np.arange(basis.N), held)

    t0 = time.perf_counter()
    K = asm(linear_elasticity(lam, mu), basis)
    t_asm = time.perf_counter() - t0
    u, v = np.zeros(basis.N), np.zeros(basis.N)
    t_sys = t_cg = t_direct = 0.0
    iterations = 0
    lu = None
    direct_factor_s = 0.0
    for _ in range(steps):
        t1 = time.perf_counter()
        A = (cm * M + ck * K).tocsr()
        b = cm * (m * u) + cu * (K @ u) + cv * (m * v) + dt * f
        Af, bf, _, _ = condense(A, b, D=held)
        t2 = time.perf_counter()
        inv_diag = 1.0 / Af.diagonal()
        jacobi = spla.LinearOperator(Af.shape, matvec=lambda x: inv_diag * x)
        count = [0]

        def counter(_xk):
            count[0] += 1

        x0 = (u + dt * v)[free]
        try:
            xf, info = spla.cg(Af, bf, x0=x0, rtol=tol, atol=0.0, M=jacobi, callback=counter)
        except TypeError:  # scipy < 1.12
            xf, info = spla.cg(Af, bf, x0=x0, tol=tol, atol=0.0, M=jacobi, callback=counter)
        t3 = time.perf_counter()
        if info != 0:
            print(f"scipy cg did not converge (info {info})", file=sys.stderr)
            sys.exit(1)
        if lu is None:
            tf = time.perf_counter()
            lu = spla.splu(Af.tocsc())
            direct_factor_s = time.perf_counter() - tf
        t4 = time.perf_counter()
        xd = lu.solve(bf)
        t5 = time.perf_counter()
        t_sys += t2 - t1
        t_cg += t3 - t2
        t_direct += t5 - t4
        iterations += count[0]
        gap = np.linalg.norm(xd - xf) / max(np.linalg.norm(xd), 1e-300)
        if gap > 1e-3:
            print(f"cg and SuperLU differ by {gap:.2e}", file=sys.stderr)
            sys.exit(1)
        u_new = np.zeros(basis.N)
        u_new[free] = xf
        # velocity update u' = u + dt ((1 - theta) v + theta v')
        v = (u_new - u) / (theta * dt) - (1.0 - theta) / theta * v
        u = u_new
    n = float(steps)
    max_u = float(np.sqrt((u.reshape(-1, 3) ** 2).sum(axis=1)).max())
    print(
        f"time_s={(t_sys + t_cg) / n:.6e} assembly_s={t_asm:.6e} system_s={t_sys / n:.6e} "
        f"cg_s={t_cg / n:.6e} cg_iterations={iterations / n:.2f} direct_s={t_direct / n:.6e} "
        f"direct_factor_s={direct_factor_s:.6e} mass_s={mass_s:.6e} nodes={mesh.p.shape[1]} "
        f"cells={mesh.t.shape[1]} dofs={free.size} max_u={max_u:.6e} "
        f"skfem={skfem.__version__} scipy={scipy.__version__} numpy={np.__version__}"
    )


if __name__ == "__main__":
    main()
