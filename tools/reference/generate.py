#!/usr/bin/env python3
"""Independent reference data for the softbody fitter, computed with scikit-fem.

Nothing here is shared with the Rust crates: the physics is written down again
from the textbook (small-strain isotropic linear elasticity, consistent mass,
Rayleigh damping, Newmark average acceleration, clamped nodes, frictionless
penalty contact with the ground plane) and discretised with a fine conforming
quadratic mesh (Q2 hexahedra for boxes, isoparametric P2 tetrahedra for the
sphere).  For every case it writes, into OUT/<case>/:

  scene.toml        the case in softbody's scene format (analytic shape, true parameters)
  observations.csv  frame,x,y,z: points sampled uniformly by area on the deformed
                    surface of every observed frame, plus isotropic Gaussian noise
  truth.json        the true parameters, noise, discretisation, convergence numbers
                    and the noise floor (rms distance of the noisy points to the true
                    surface of their frame)

Usage:  python generate.py [--case NAME] [--out DIR] [--quick]

See README.md beside this file.
"""

import os

# One BLAS thread: with several threads OpenBLAS spins on a busy 2-core machine and a
# 200 x 200 Cholesky takes 0.3 s instead of 1 ms.  Must be set before numpy loads.
for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse
import json
import logging
import math
import platform
import sys
import time
from dataclasses import replace

import numpy as np
import scipy
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial import cKDTree

import skfem
from skfem import (Basis, BilinearForm, ElementHex2, ElementTetP2, ElementVector,
                   MeshHex, MeshTet1, MeshTet2, asm)
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity

logging.disable(logging.WARNING)  # skfem logs array-layout notices at INFO/WARNING

try:  # CHOLMOD (bundled with cvxopt) is ~50x faster than SuperLU on these matrices
    import cvxopt
    import cvxopt.cholmod
    HAVE_CHOLMOD = True
except ImportError:  # pragma: no cover - fallback keeps the script runnable
    HAVE_CHOLMOD = False

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
DEFAULT_OUT = os.path.join(REPO, "tests", "reference_values", "independent")

GRAVITY = np.array([0.0, -10.0, 0.0])

# ---------------------------------------------------------------------------
# The cases.  Every number that defines "the real world" is here.
# ---------------------------------------------------------------------------
# The cantilever's bar: body, material, damping, clamp and meshes (Q2 hexahedra: cells along
# x, y, z), shared by the cases "cantilever" and "twist".
BAR = dict(
    body=dict(kind="box", center=[0.525, 1.0, 0.0], size=[1.05, 0.22, 0.22]),
    young=2400.0, poisson=0.35, density=1.0,
    damping_mass=0.8, damping_stiffness=0.0,
    clamp=dict(axis=0, side="min"),
    ground=None,
    mesh=dict(reference=dict(cells=[40, 8, 8], grading=1.5),
              coarse=dict(cells=[20, 4, 4], grading=1.5)),
    substeps=8,
)

CASES = {
    "cantilever": dict(
        BAR,
        description="Box 1.05 x 0.22 x 0.22 clamped at its x-min end face, swinging "
                    "down under gravity from rest.",
        dt=0.02, steps=50, obs_every=2, points=300,
        sigma=0.01, seed=20261201,
    ),
    # The cantilever's swing under gravity is bending: it sees E (and the density), but
    # along nu the cost is flat (a fit's standard error on nu is 0.05).  The same bar,
    # given a spin about its own axis at t = 0, twists as well as swings: torsion sees
    # the shear modulus G = E / (2 (1 + nu)), bending sees E, so the motion sees nu.
    "twist": dict(
        BAR,
        description="The cantilever's bar (1.05 x 0.22 x 0.22, clamped at its x-min end face) "
                    "swinging down under gravity while it twists about its own axis: every "
                    "point that is not clamped starts with the velocity of a rigid spin "
                    "w x (X - c) about the bar's center c.",
        # first torsion mode ~41 rad/s (period 0.15 s), first bending mode ~10 rad/s:
        # 0.4 s are 2.6 twists and half a swing; tip twist amplitude ~0.3 rad
        angular_velocity=[10.0, 0.0, 0.0],
        dt=0.005, steps=80, obs_every=1, points=300,
        sigma=0.01, seed=20261204,
        # our lumped mass makes the bar's polar moment of inertia 10% too large at 4.4 cells
        # across (a fit then gives nu 0.22); the consistent mass is exact for it
        scene_numerics=dict(mass="consistent"),
        scene_numerics_note="our consistent mass: the lumped one's rotational inertia is "
                            "10% too large for this bar (docs/simulation.md, \"Mass\")",
    ),
    "block": dict(
        description="Thick block 0.5 x 0.6 x 0.5 clamped at its base face (y = 0), "
                    "bobbing and settling under its own weight from rest.",
        body=dict(kind="box", center=[0.0, 0.3, 0.0], size=[0.5, 0.6, 0.5]),
        young=100.0, poisson=0.3, density=1.0,
        damping_mass=0.5, damping_stiffness=0.002,
        clamp=dict(axis=1, side="min"),
        ground=None,
        dt=0.01, steps=60, obs_every=1, points=200,
        sigma=0.01, seed=20261202,
        mesh=dict(reference=dict(cells=[10, 12, 10], grading=1.5),
                  coarse=dict(cells=[5, 6, 5], grading=1.5)),
        substeps=8,
        # our surface for a body with sharp edges (marching cubes bevels them)
        scene_numerics=dict(surface_method="dual_contouring"),
        scene_numerics_note="our observed surface keeps the box's edges (docs/simulation.md, "
                            "\"The observed surface\")",
    ),
    "ground": dict(
        description="Sphere of radius 0.3 whose lowest point starts 0.05 above the ground "
                    "y = 0, dropped from rest; it lands, bounces and lands again.",
        body=dict(kind="sphere", center=[0.0, 0.35, 0.0], radius=0.3),
        young=2000.0, poisson=0.3, density=1.0,
        damping_mass=0.2, damping_stiffness=0.0005,
        clamp=None,
        # reference contact: frictionless penalty pressure p = k * penetration, k below
        ground=dict(normal=[0.0, 1.0, 0.0], height=0.0, penalty=4.0e6,
                    scene_stiffness=1.0e4, scene_softness=1000.0, cap=0.04),
        # our model integrates each frame in 2 steps: at one step per frame the rebounds
        # drift (rms at the truth 1.19x the noise floor, 1.015x with 2)
        scene_substeps=2,
        dt=0.01, steps=60, obs_every=1, points=200,
        sigma=0.01, seed=20261203,
        # isoparametric P2 tets: ball refined 3 times, then longest-edge bisection near
        # the contact point down to edge length hc (unit-ball units), graded by `grade`
        mesh=dict(reference=dict(nrefs=3, hc=0.03, grade=0.25),
                  coarse=dict(nrefs=3, hc=0.06, grade=0.5)),
        substeps=5,
    ),
}


# ---------------------------------------------------------------------------
# Linear solver
# ---------------------------------------------------------------------------
class Factor:
    """Factorisation of a symmetric positive definite sparse matrix."""

    def __init__(self, A):
        A = sp.csc_matrix(A)
        self.n = A.shape[0]
        if HAVE_CHOLMOD:
            L = sp.tril(A).tocoo()
            S = cvxopt.spmatrix(L.data, L.row.astype(int), L.col.astype(int), A.shape)
            cvxopt.cholmod.options["supernodal"] = 2
            self.F = cvxopt.cholmod.symbolic(S, uplo="L")
            cvxopt.cholmod.numeric(S, self.F)
            self.lu = None
        else:
            self.lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A")

    def solve(self, b):
        b = np.asarray(b, dtype=float)
        if self.lu is not None:
            return self.lu.solve(b)
        X = cvxopt.matrix(np.asfortranarray(b.reshape(self.n, -1)))
        cvxopt.cholmod.solve(self.F, X)
        return np.array(X).reshape(b.shape)


# ---------------------------------------------------------------------------
# Meshes
# ---------------------------------------------------------------------------
def graded(n, q, ends):
    """n cells on [0, 1]; with q > 1 power-graded towards the chosen ends
    ("lo", "hi" or "both": first cell (1/n)^q instead of 1/n)."""
    xi = np.linspace(0.0, 1.0, n + 1)
    if q == 1 or ends is None:
        return xi
    if ends == "lo":
        return xi ** q
    if ends == "hi":
        return 1 - (1 - xi) ** q
    return np.where(xi < 0.5, 0.5 * (2 * xi) ** q, 1 - 0.5 * (2 - 2 * xi) ** q)


def box_mesh(body, cells, clamp=None, grading=1.0):
    """Tensor mesh of Q2 hexahedra.  With a clamped face, cells are power-graded
    towards that face along its axis and towards both faces along the two other
    axes (the clamped edges carry the stress singularities)."""
    c = np.array(body["center"], float)
    s = np.array(body["size"], float)
    lo = c - s / 2
    axes = []
    for i in range(3):
        ends = None
        if clamp is not None:
            ends = ("lo" if clamp["side"] == "min" else "hi") if i == clamp["axis"] else "both"
        axes.append(lo[i] + s[i] * graded(cells[i], grading, ends))
    return MeshHex.init_tensor(*axes), ElementHex2()


def ball_mesh(body, nrefs, hc, grade):
    """Unit ball from skfem (octahedron refined nrefs times), bisected near the south
    pole (the contact point) until the longest edge is below hc + grade * distance,
    boundary vertices projected onto the sphere after every refinement; then made
    isoparametric P2 (edge midpoints of boundary edges projected onto the sphere),
    scaled and translated."""
    m = MeshTet1.init_ball(nrefs)
    south = np.array([0.0, -1.0, 0.0])
    pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    for _ in range(20):
        p, t = m.p, m.t
        L = np.max([np.linalg.norm(p[:, t[a]] - p[:, t[b]], axis=0) for a, b in pairs], axis=0)
        d = np.linalg.norm(p[:, t].mean(axis=1) - south[:, None], axis=0)
        marked = np.nonzero(L > (hc + grade * d) * 1.0001)[0]
        if len(marked) == 0:
            break
        m = m.refined(marked)
        D = m.boundary_nodes()
        P = m.p.copy()
        P[:, D] /= np.linalg.norm(P[:, D], axis=0)
        m = replace(m, doflocs=P)
    M = MeshTet2.from_mesh(m)
    D = M.dofs.get_facet_dofs(M.boundary_facets()).flatten()
    doflocs = M.doflocs.copy()
    doflocs[:, D] /= np.linalg.norm(doflocs[:, D], axis=0)
    doflocs = doflocs * body["radius"] + np.array(body["center"], float)[:, None]
    return replace(M, doflocs=doflocs), ElementTetP2()


def build_mesh(case, level):
    spec = case["mesh"][level]
    if case["body"]["kind"] == "box":
        return box_mesh(case["body"], spec["cells"], case["clamp"], spec.get("grading", 1.0))
    return ball_mesh(case["body"], **spec)


# ---------------------------------------------------------------------------
# The finite element model of one body
# ---------------------------------------------------------------------------
def assemble_elasticity(sb, lam, mu, rho):
    """Stiffness and consistent mass of isotropic linear elasticity for the vector
    space (scalar space)^3, dof 3*i + a = component a of scalar dof i.  Assembled from
    the nine scalar matrices S_ab[i, j] = int d_a phi_i d_b phi_j (much faster in skfem
    than the vector form; checked against skfem's linear_elasticity in --selftest):
        K[3i+a, 3j+b] = lam S_ab + mu (delta_ab sum_k S_kk + S_ba),
        M[3i+a, 3j+b] = delta_ab rho int phi_i phi_j."""
    S = [[None] * 3 for _ in range(3)]
    for a in range(3):
        for b in range(3):
            @BilinearForm
            def form(u, v, w, a=a, b=b):
                return v.grad[a] * u.grad[b]
            S[a][b] = asm(form, sb).tocsr()

    @BilinearForm
    def mass(u, v, w):
        return rho * u * v

    Ms = asm(mass, sb).tocsr()
    lap = S[0][0] + S[1][1] + S[2][2]
    blocks = [[lam * S[a][b] + mu * S[b][a] + (mu * lap if a == b else 0 * lap) for b in range(3)]
              for a in range(3)]
    Kb = sp.bmat(blocks).tocsr()                        # component-major ordering
    Mb = sp.block_diag([Ms, Ms, Ms]).tocsr()
    n = sb.N
    perm = (3 * np.arange(n)[None, :] + np.arange(3)[:, None]).reshape(-1)  # block row -> dof
    P = sp.csr_matrix((np.ones(3 * n), (perm, np.arange(3 * n))), shape=(3 * n, 3 * n))
    K = (P @ Kb @ P.T).tocsr()
    M = (P @ Mb @ P.T).tocsr()
    return K, M


class Body:
    def __init__(self, case, level):
        t0 = time.time()
        self.case = case
        self.mesh, self.elem = build_mesh(case, level)
        mesh, elem = self.mesh, self.elem
        self.sb = Basis(mesh, elem)                      # scalar basis
        self.vb = Basis(mesh, ElementVector(elem))      # displacement basis
        self.nS = self.sb.N
        self.N = self.vb.N
        # vector dof 3*s + c is component c of scalar dof s (checked, we rely on it)
        for c in range(3):
            assert np.array_equal(self.vb.element_dofs[c::3], 3 * self.sb.element_dofs + c)
        assert np.allclose(self.vb.doflocs[:, 0::3], self.sb.doflocs)
        self.doflocs = self.sb.doflocs.T.copy()          # (nS, 3): P2/Q2 node positions

        lam, mu = lame_parameters(case["young"], case["poisson"])
        rho = case["density"]

        self.K, self.M = assemble_elasticity(self.sb, lam, mu, rho)
        # body force: the gravity field is constant, hence exactly in the space
        G = np.tile(GRAVITY, self.nS)
        self.F = self.M @ G

        # boundary facets and their parametrisation
        self.bfacets = mesh.boundary_facets()
        self._setup_facets()

        # clamped face
        self.clamped_facet = np.zeros(len(self.bfacets), bool)
        fixed = np.zeros(0, int)
        if case["clamp"] is not None:
            ax, side = case["clamp"]["axis"], case["clamp"]["side"]
            c = np.array(case["body"]["center"], float)
            s = np.array(case["body"]["size"], float)
            face = c[ax] - s[ax] / 2 if side == "min" else c[ax] + s[ax] / 2
            fv = mesh.p[ax][mesh.facets[:, self.bfacets]]
            self.clamped_facet = np.all(np.abs(fv - face) < 1e-9, axis=0)
            sd = self.sb.get_dofs(facets=self.bfacets[self.clamped_facet]).all()
            assert np.all(np.abs(self.doflocs[sd, ax] - face) < 1e-9)
            fixed = np.concatenate([3 * sd + c for c in range(3)])
        self.fixed = np.unique(fixed)
        self.free = np.setdiff1d(np.arange(self.N), self.fixed)
        self.h = self._edge_lengths()
        self.setup_seconds = time.time() - t0

    # -- facets -------------------------------------------------------------
    def _setup_facets(self):
        mesh, elem = self.mesh, self.elem
        ref = np.asarray(elem.doflocs, float)              # (Nbfun, 3) reference dof locations
        nv = mesh.t.shape[0]
        self.tri = mesh.facets.shape[0] == 3
        nf = len(self.bfacets)
        self.f_elem = mesh.f2t[0, self.bfacets]
        self.f_orig = np.zeros((nf, 3))
        self.f_e1 = np.zeros((nf, 3))
        self.f_e2 = np.zeros((nf, 3))
        for k, f in enumerate(self.bfacets):
            t = self.f_elem[k]
            loc = [int(np.nonzero(mesh.t[:, t] == v)[0][0]) for v in mesh.facets[:, f]]
            assert max(loc) < nv
            R = ref[loc]
            if self.tri:
                self.f_orig[k], self.f_e1[k], self.f_e2[k] = R[0], R[1] - R[0], R[2] - R[0]
            else:
                const = [a for a in range(3) if np.ptp(R[:, a]) == 0]
                assert len(const) == 1
                a, b = [x for x in range(3) if x != const[0]]
                self.f_orig[k, const[0]] = R[0, const[0]]
                self.f_e1[k, a] = 1.0
                self.f_e2[k, b] = 1.0
        # sanity: the facet's corners interpolate to the mesh vertices
        corners = np.array([[0, 0], [1, 0], [0, 1]], float)
        for st in corners:
            fid = np.arange(nf)
            E = self.eval_matrix(fid, np.tile(st, (nf, 1)))
            X = E @ self.doflocs
            d = np.min(np.linalg.norm(
                mesh.p[:, mesh.facets[:, self.bfacets]].T - X[:, None, :], axis=2), axis=1)
            assert d.max() < 1e-12, d.max()

    def ref_coords(self, fid, st):
        return (self.f_orig[fid] + st[:, 0:1] * self.f_e1[fid]
                + st[:, 1:2] * self.f_e2[fid])

    def eval_matrix(self, fid, st, derivative=None):
        """Sparse matrix (npts x nS) evaluating a scalar field at facet points.
        fid: facet index (into self.bfacets) per point, st: (npts, 2) facet parameters.
        derivative=1 or 2: the derivative along the facet parameter s or t instead."""
        X = self.ref_coords(fid, st).T                      # (3, npts) reference coords
        tind = self.f_elem[fid]
        rows, cols, vals = [], [], []
        n = len(fid)
        for i in range(self.sb.element_dofs.shape[0]):
            phi, dphi = self.elem.lbasis(X, i)
            if derivative is None:
                v = phi
            else:
                e = self.f_e1[fid] if derivative == 1 else self.f_e2[fid]
                v = np.sum(dphi * e.T, axis=0)
            v = np.broadcast_to(v, (n,))
            keep = np.abs(v) > 1e-15
            rows.append(np.nonzero(keep)[0])
            cols.append(self.sb.element_dofs[i, tind[keep]])
            vals.append(v[keep])
        return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(n, self.nS))

    def facet_domain_clip(self, st):
        st = np.clip(st, 0.0, 1.0)
        if self.tri:
            s = st.sum(axis=1)
            over = s > 1
            st[over] /= s[over][:, None]
        return st

    def subdivision(self, s):
        """Parameters of a subdivision of every facet into small triangles:
        returns (vertex facet ids, vertex params, triangles (ntri, 3) into the vertices,
        triangle facet ids)."""
        if self.tri:
            P = [(i / s, j / s) for j in range(s + 1) for i in range(s + 1 - j)]
            idx = {}
            for k, (a, b) in enumerate(P):
                idx[(round(a * s), round(b * s))] = k
            T = []
            for j in range(s):
                for i in range(s - j):
                    T.append((idx[(i, j)], idx[(i + 1, j)], idx[(i, j + 1)]))
                    if i + j < s - 1:
                        T.append((idx[(i + 1, j)], idx[(i + 1, j + 1)], idx[(i, j + 1)]))
        else:
            P = [(i / s, j / s) for j in range(s + 1) for i in range(s + 1)]
            T = []
            for j in range(s):
                for i in range(s):
                    a = j * (s + 1) + i
                    T.append((a, a + 1, a + s + 2))
                    T.append((a, a + s + 2, a + s + 1))
        P = np.array(P)
        T = np.array(T)
        nf = len(self.bfacets)
        vf = np.repeat(np.arange(nf), len(P))
        vst = np.tile(P, (nf, 1))
        tris = (np.arange(nf)[:, None, None] * len(P) + T[None]).reshape(-1, 3)
        tf = np.repeat(np.arange(nf), len(T))
        return vf, vst, tris, tf

    def _edge_lengths(self):
        p, t = self.mesh.p, self.mesh.t
        if self.tri:
            pairs = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
        else:  # hex: take the shortest and longest vertex distances as bounds
            pairs = [(a, b) for a in range(8) for b in range(a + 1, 8)]
        L = np.array([np.linalg.norm(p[:, t[a]] - p[:, t[b]], axis=0) for a, b in pairs])
        if self.tri:
            return dict(min_edge=float(L.min()), max_edge=float(L.max()))
        Lmin = L.min(axis=0)
        return dict(min_edge=float(Lmin.min()), max_edge=float(Lmin.max()))


class Surface:
    """The boundary surface of a Body, subdivided into small flat triangles whose
    vertices lie on the exact (curved) quadratic surface."""

    def __init__(self, body, s):
        self.body = body
        self.vf, self.vst, self.tris, self.tf = body.subdivision(s)
        self.E = body.eval_matrix(self.vf, self.vst)
        self.X0 = self.E @ body.doflocs
        self.tst = self.vst[self.tris]                     # (ntri, 3, 2)

    def vertices(self, U):
        return self.X0 + self.E @ U

    def triangles(self, U):
        V = self.vertices(U)
        return V[self.tris]                                # (ntri, 3, 3)


def tri_areas(T):
    return 0.5 * np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1)


def point_triangle_distance(P, A, B, C):
    """Exact Euclidean distance from points P to triangles ABC (all (n, 3))."""
    ab, ac, ap = B - A, C - A, P - A
    n = np.cross(ab, ac)
    nn = np.einsum("ij,ij->i", n, n)
    # barycentric coordinates of the projection
    v = np.einsum("ij,ij->i", np.cross(ap, ac), n) / nn
    w = np.einsum("ij,ij->i", np.cross(ab, ap), n) / nn
    u = 1 - v - w
    inside = (u >= 0) & (v >= 0) & (w >= 0)
    d_plane = np.abs(np.einsum("ij,ij->i", ap, n)) / np.sqrt(nn)

    def seg(P, X, Y):
        d = Y - X
        t = np.clip(np.einsum("ij,ij->i", P - X, d) / np.einsum("ij,ij->i", d, d), 0, 1)
        return np.linalg.norm(P - (X + t[:, None] * d), axis=1)

    d_edge = np.minimum(np.minimum(seg(P, A, B), seg(P, B, C)), seg(P, C, A))
    return np.where(inside, d_plane, d_edge)


def distances_to_surface(points, T):
    """Distance of every point to the triangle soup T (ntri, 3, 3)."""
    cen = T.mean(axis=1)
    rmax = np.max(np.linalg.norm(T - cen[:, None, :], axis=2))
    tree = cKDTree(cen)
    d0, _ = tree.query(points)
    out = np.empty(len(points))
    for k, p in enumerate(points):
        cand = np.array(tree.query_ball_point(p, d0[k] + rmax + 1e-12))
        P = np.broadcast_to(p, (len(cand), 3))
        out[k] = point_triangle_distance(P, T[cand, 0], T[cand, 1], T[cand, 2]).min()
    return out


# ---------------------------------------------------------------------------
# Contact with the ground plane y = height (frictionless penalty)
# ---------------------------------------------------------------------------
def cap_quadrature(body, cand, sub):
    """A composite rule on the boundary facets `cand`: each facet split into sub x sub
    triangles, the 3-point degree-2 rule on each.  Returns the evaluation matrix of the
    quadrature points (points x scalar dofs), their reference area weights and positions."""
    vf, vst, tris, tf = body.subdivision(sub)
    Tp = vst[tris[: len(tris) // len(body.bfacets)]]     # sub-triangles of one facet
    bary = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])
    qst = np.einsum("qk,tkd->tqd", bary, Tp).reshape(-1, 2)       # points in one facet
    e1, e2 = Tp[:, 1] - Tp[:, 0], Tp[:, 2] - Tp[:, 0]
    sub_area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    qw = np.repeat(sub_area / 3, 3)
    fid = np.repeat(cand, len(qst))
    st = np.tile(qst, (len(cand), 1))
    E = body.eval_matrix(fid, st)
    E1 = body.eval_matrix(fid, st, derivative=1)
    E2 = body.eval_matrix(fid, st, derivative=2)
    X = E @ body.doflocs
    J = np.linalg.norm(np.cross(E1 @ body.doflocs, E2 @ body.doflocs), axis=1)
    return E, np.tile(qw, len(cand)) * J, X


class Contact:
    """Penalty energy  (k/2) * integral over the reference surface of min(0, gap)^2 dA,
    gap = height of the material point above the plane.  Integrated on the boundary
    facets near the lowest point (the candidate cap) with a composite rule: each facet
    split into sub x sub triangles, 3-point degree-2 rule on each."""

    def __init__(self, body, ground, sub=6):
        self.k = ground["penalty"]
        self.height = ground["height"]
        assert ground["normal"] == [0.0, 1.0, 0.0]
        mesh = body.mesh
        ymin = body.doflocs[:, 1].min()
        fy = mesh.p[1][mesh.facets[:, body.bfacets]]
        cand = np.nonzero(fy.max(axis=0) < ymin + ground["cap"])[0]
        self.cap_facets = cand
        E, self.w, X = cap_quadrature(body, cand, sub)       # reference area weights
        self.y0 = X[:, 1] - self.height                      # reference gap
        # candidate scalar dofs and the y-components among the free dofs
        sdofs = np.unique(E.indices)
        self.sdofs = sdofs
        self.E = E.tocsr()                                   # qp values from all scalar dofs
        self.B = E[:, sdofs].tocsr()                         # qp values from candidate dofs
        pos = -np.ones(body.N, int)
        pos[body.free] = np.arange(len(body.free))
        self.cdofs = pos[3 * sdofs + 1]
        assert np.all(self.cdofs >= 0)
        # the rest of the boundary must never reach the ground: watched every step
        others = np.setdiff1d(np.arange(len(body.bfacets)), cand)
        od = body.sb.get_dofs(facets=body.bfacets[others]).all() if len(others) else []
        self.watch = np.setdiff1d(np.asarray(od, int), sdofs)
        self.area = float(self.w.sum())

    def prepare(self, factor, nfree):
        """Columns of W = P A^-1 P' (P: the candidate y-dofs) are computed on demand."""
        nc = len(self.cdofs)
        self.factor, self.nfree = factor, nfree
        self.W = np.zeros((nc, nc))
        self.f_prev = None
        self.sizes = []
        self.have = np.zeros(nc, bool)
        nq = len(self.w) // len(self.cap_facets)
        self.qfacet = np.repeat(np.arange(len(self.cap_facets)), nq)
        B = self.B.tocsr()
        self.facet_dofs = [np.unique(B[k * nq:(k + 1) * nq].indices) for k in range(len(self.cap_facets))]
        self.facet_rows = [np.arange(k * nq, (k + 1) * nq) for k in range(len(self.cap_facets))]

    def _columns(self, cols):
        miss = cols[~self.have[cols]]
        for a in range(0, len(miss), 64):
            c = miss[a:a + 64]
            R = np.zeros((self.nfree, len(c)))
            R[self.cdofs[c], np.arange(len(c))] = 1.0
            self.W[:, c] = self.factor.solve(R)[self.cdofs]
            self.have[c] = True
        return self.W[:, cols]

    def solve(self, y_free):
        """The contact problem of one Newmark step, condensed onto the candidate
        y-displacements y = y_free - W f:  minimise 1/2 (y - y_free)' W^-1 (y - y_free)
        + contact energy(y).  Only the dofs S of facets in contact enter: on them it is
        minimise 1/2 d' W_SS^-1 d + contact energy, d = y_S - y_free_S (Schur complement),
        solved by Newton with a line search (exact once the active set settles); S grows
        until no quadrature point outside it penetrates.  Returns the contact force f
        (gradient of the contact energy; zero outside S) and the Newton iterations."""
        k, w, B, y0 = self.k, self.w, self.B, self.y0
        g = y0 + B @ y_free
        if g.min() >= 0:
            self.f_prev = None
            return None, 0
        if self.f_prev is not None:
            # start from the facets that penetrate under last substep's contact force
            # (y_free alone, without any support, penetrates over a much wider area)
            Sp = np.nonzero(self.f_prev)[0]
            g = y0 + B @ (y_free - self._columns(Sp) @ self.f_prev[Sp])
            if g.min() >= 0:
                g = y0 + B @ y_free
        facets = set(np.unique(self.qfacet[g < 0]).tolist())
        its = 0
        for _outer in range(50):
            fl = sorted(facets)
            S = np.unique(np.concatenate([self.facet_dofs[f] for f in fl]))
            rows = np.concatenate([self.facet_rows[f] for f in fl])
            BS = B[rows][:, S].tocsr()
            wS, y0S = w[rows], y0[rows]
            WS = self._columns(S)
            WSS = 0.5 * (WS[S] + WS[S].T)
            WSSi = sla.cho_solve(sla.cho_factor(WSS), np.eye(len(S)))
            yf = y_free[S]

            def phi(y):
                d = y - yf
                gm = np.minimum(y0S + BS @ y, 0)
                return 0.5 * d @ (WSSi @ d) + 0.5 * k * np.sum(wS * gm * gm)

            y = yf.copy()
            for _ in range(100):
                gS = y0S + BS @ y
                act = gS < 0
                grad = WSSi @ (y - yf) + k * (BS.T @ (wS * np.minimum(gS, 0)))
                Ba = BS[act]
                H = WSSi + k * (Ba.T @ sp.diags(wS[act]) @ Ba).toarray()
                step = -sla.cho_solve(sla.cho_factor(H), grad)
                its += 1
                # the energy is quadratic on each active set: a full step that keeps the
                # active set lands on the exact minimiser
                if np.array_equal(y0S + BS @ (y + step) < 0, act):
                    y = y + step
                    break
                f0, alpha = phi(y), 1.0
                while phi(y + alpha * step) > f0 + 1e-4 * alpha * (grad @ step) and alpha > 1e-10:
                    alpha *= 0.5
                y = y + alpha * step
            else:
                raise RuntimeError("contact Newton did not converge")
            gS = y0S + BS @ y
            fS = k * (BS.T @ (wS * np.minimum(gS, 0)))
            yall = y_free - WS @ fS
            g = y0 + B @ yall
            new = set(np.unique(self.qfacet[g < -1e-14]).tolist()) - facets
            if not new:
                f = np.zeros(len(y_free))
                f[S] = fS
                self.f_prev = f
                self.sizes.append(len(S))
                return f, its
            facets |= new
        raise RuntimeError("contact set did not settle")


# ---------------------------------------------------------------------------
# Time integration: Newmark average acceleration (beta = 1/4, gamma = 1/2)
# ---------------------------------------------------------------------------
def simulate(body, case, substeps, penalty=None, log=print):
    dt_frame, steps = case["dt"], case["steps"]
    h = dt_frame / substeps
    a_m, b_k = case["damping_mass"], case["damping_stiffness"]
    I = body.free
    M = body.M[I][:, I].tocsr()
    K = body.K[I][:, I].tocsr()
    C = (a_m * M + b_k * K).tocsr()
    F = body.F[I]
    c0, c1 = 4.0 / h ** 2, 2.0 / h
    t0 = time.time()
    fac = Factor(c0 * M + c1 * C + K)
    # initial velocity: a rigid spin w x (X - c) about the body's center c at every free
    # dof (clamped nodes are held: zero), or rest
    v = np.zeros(len(I))
    if case.get("angular_velocity") is not None:
        w = np.array(case["angular_velocity"], float)
        X = body.doflocs - np.array(case["body"]["center"], float)
        v = np.cross(w, X).reshape(-1)[I]
    # initial acceleration (u = 0): M a = F - C v (Jacobi-preconditioned CG, M is well
    # conditioned)
    r0 = F - C @ v
    dM = M.diagonal()
    a, cg_info = spla.cg(M, r0, rtol=1e-14, atol=0.0, maxiter=5000,
                         M=sp.diags(1.0 / dM))
    assert cg_info == 0 and np.linalg.norm(M @ a - r0) <= 1e-11 * np.linalg.norm(r0)
    contact = None
    if case["ground"] is not None:
        g = dict(case["ground"])
        if penalty is not None:
            g["penalty"] = penalty
        contact = Contact(body, g)
        contact.prepare(fac, len(I))
    t_setup = time.time() - t0
    u = np.zeros(len(I))
    frames = [np.zeros((body.nS, 3))]
    newton = 0
    contact_steps = 0
    min_watch = np.inf
    t0 = time.time()
    for n in range(steps * substeps):
        rhs = F + M @ (c0 * u + (4.0 / h) * v + a) + C @ (c1 * u + v)
        un = fac.solve(rhs)
        if contact is not None:
            f, it = contact.solve(un[contact.cdofs])
            if f is not None:
                r = np.zeros(len(I))
                r[contact.cdofs] = f
                un = un - fac.solve(r)
                newton += it
                contact_steps += 1
        an = c0 * (un - u) - (4.0 / h) * v - a
        vn = v + 0.5 * h * (a + an)
        u, v, a = un, vn, an
        if contact is not None and len(contact.watch):
            yw = body.doflocs[contact.watch, 1] + u_full(body, u).reshape(-1, 3)[contact.watch, 1]
            min_watch = min(min_watch, yw.min() - contact.height)
        if (n + 1) % substeps == 0:
            frames.append(u_full(body, u).reshape(-1, 3))
    info = dict(substeps=substeps, substep=h, setup_seconds=round(t_setup, 2),
                stepping_seconds=round(time.time() - t0, 2), free_dofs=int(len(I)))
    if contact is not None:
        info.update(contact_substeps=contact_steps, contact_newton_iterations=newton,
                    contact_candidate_dofs=int(len(contact.cdofs)),
                    contact_dofs_max=int(max(contact.sizes, default=0)),
                    contact_columns_computed=int(contact.have.sum()),
                    contact_penalty=contact.k,
                    lowest_non_candidate_boundary_node_height=float(min_watch))
        assert min_watch > 0, "a boundary node outside the contact cap reached the ground"
    log(f"    simulated {steps}x{substeps} substeps: setup {t_setup:.1f}s, "
        f"stepping {info['stepping_seconds']:.1f}s")
    return np.array(frames), info


def u_full(body, u_free):
    x = np.zeros(body.N)
    x[body.free] = u_free
    return x


# ---------------------------------------------------------------------------
# Comparison points: material points on the exact analytic surface
# ---------------------------------------------------------------------------
def analytic_surface_points(body_spec, n, rng):
    if body_spec["kind"] == "sphere":
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        return np.array(body_spec["center"]) + body_spec["radius"] * d
    c = np.array(body_spec["center"], float)
    s = np.array(body_spec["size"], float)
    areas = np.array([s[1] * s[2], s[1] * s[2], s[0] * s[2], s[0] * s[2], s[0] * s[1], s[0] * s[1]])
    face = rng.choice(6, size=n, p=areas / areas.sum())
    P = c + (rng.random((n, 3)) - 0.5) * s
    ax = face // 2
    P[np.arange(n), ax] = c[ax] + np.where(face % 2 == 0, -0.5, 0.5) * s[ax]
    return P


def locate(body, surf, points, candidates=8):
    """Facet and facet parameters of the reference-surface points nearest to `points`:
    Gauss-Newton on the exact facet map of each facet owning one of the `candidates`
    nearest sub-triangles (a point near a box edge may be closest to a sub-triangle of
    the other face), keeping the facet with the smallest residual."""
    T0 = surf.X0[surf.tris]
    cen = T0.mean(axis=1)
    _, kk = cKDTree(cen).query(points, k=candidates)
    best_r = np.full(len(points), np.inf)
    best_f = np.zeros(len(points), int)
    best_st = np.zeros((len(points), 2))
    for j in range(candidates):
        k = kk[:, j]
        fid = surf.tf[k]
        st = surf.tst[k].mean(axis=1)
        for _ in range(8):
            X = body.eval_matrix(fid, st) @ body.doflocs
            D1 = body.eval_matrix(fid, st, 1) @ body.doflocs
            D2 = body.eval_matrix(fid, st, 2) @ body.doflocs
            r = points - X
            J = np.stack([D1, D2], axis=2)                        # (n, 3, 2)
            JtJ = np.einsum("nia,nib->nab", J, J)
            Jtr = np.einsum("nia,ni->na", J, r)
            st = body.facet_domain_clip(st + np.linalg.solve(JtJ, Jtr[..., None])[..., 0])
        res = np.linalg.norm(body.eval_matrix(fid, st) @ body.doflocs - points, axis=1)
        better = res < best_r
        best_r[better], best_f[better], best_st[better] = res[better], fid[better], st[better]
    E = body.eval_matrix(best_f, best_st)
    return E, float(best_r.max())


def compare(runs, points):
    """Max and rms (over frames and points) of the displacement difference of two runs
    at the same material points."""
    (bA, fA), (bB, fB) = runs
    EA, rA = locate(bA, Surface(bA, 4), points)
    EB, rB = locate(bB, Surface(bB, 4), points)
    dmax, ss, cnt = 0.0, 0.0, 0
    umax = 0.0
    for UA, UB in zip(fA, fB):
        dA, dB = EA @ UA, EB @ UB
        d = np.linalg.norm(dA - dB, axis=1)
        dmax = max(dmax, d.max())
        ss += np.sum(d ** 2)
        cnt += len(d)
        umax = max(umax, np.linalg.norm(dA, axis=1).max())
    return dict(max_surface_point_difference=float(dmax),
                rms_surface_point_difference=float(math.sqrt(ss / cnt)),
                max_surface_displacement=float(umax),
                points=len(points), location_residual=max(rA, rB))


# ---------------------------------------------------------------------------
# Kinematic measures (is small-strain linear elasticity the right model?)
# ---------------------------------------------------------------------------
def kinematics(body, frames):
    """Largest displacement, infinitesimal rotation |skew(grad u)| and strain norm |eps|
    over all frames and quadrature points.  The maxima sit at the stress singularities
    (clamped edges, contact rim) and grow with mesh refinement there; the 99th
    percentiles (over quadrature points, worst frame) describe the body."""
    out = dict(max_displacement=0.0, max_rotation_rad=0.0, max_strain_norm=0.0,
               p99_rotation_rad=0.0, p99_strain_norm=0.0)
    for U in frames[1:]:
        out["max_displacement"] = max(out["max_displacement"], float(np.linalg.norm(U, axis=1).max()))
        G = np.stack([body.sb.interpolate(U[:, c]).grad for c in range(3)])  # (3, 3, nel, nqp)
        W = 0.5 * (G - G.transpose(1, 0, 2, 3))
        w = np.sqrt(W[0, 1] ** 2 + W[0, 2] ** 2 + W[1, 2] ** 2)
        E = 0.5 * (G + G.transpose(1, 0, 2, 3))
        e = np.sqrt(np.einsum("ijkl,ijkl->kl", E, E))
        out["max_rotation_rad"] = max(out["max_rotation_rad"], float(w.max()))
        out["max_strain_norm"] = max(out["max_strain_norm"], float(e.max()))
        out["p99_rotation_rad"] = max(out["p99_rotation_rad"], float(np.percentile(w, 99)))
        out["p99_strain_norm"] = max(out["p99_strain_norm"], float(np.percentile(e, 99)))
    return out


def max_displacement_per_frame(frames):
    return [float(np.linalg.norm(U, axis=1).max()) for U in frames]


# ---------------------------------------------------------------------------
# Observations
# ---------------------------------------------------------------------------
def observe(body, frames, case, rng, s=8):
    surf = Surface(body, s)
    visible = ~body.clamped_facet[surf.tf]       # a clamped face sits against its support
    noisy_all, frame_all = [], []
    for f in range(1, case["steps"] + 1):
        if f % case["obs_every"] != 0 and f != case["steps"]:
            continue
        U = frames[f]
        T = surf.triangles(U)
        A = tri_areas(T) * visible
        k = rng.choice(len(A), size=case["points"], p=A / A.sum())
        r1, r2 = rng.random(case["points"]), rng.random(case["points"])
        sq = np.sqrt(r1)
        bary = np.stack([1 - sq, sq * (1 - r2), sq * r2], axis=1)
        st = np.einsum("nk,nkd->nd", bary, surf.tst[k])
        E = body.eval_matrix(surf.tf[k], st)
        X = E @ (body.doflocs + U)                  # exactly on the deformed quadratic surface
        noisy = X + case["sigma"] * rng.normal(size=X.shape)
        noisy_all.append(noisy)
        frame_all.append(np.full(len(noisy), f))
    return np.concatenate(frame_all), np.concatenate(noisy_all)


def noise_floor(body, frames, fr, pts, s):
    surf = Surface(body, s)
    d = np.empty(len(pts))
    for f in np.unique(fr):
        sel = fr == f
        d[sel] = distances_to_surface(pts[sel], surf.triangles(frames[f]))
    return float(np.sqrt(np.mean(d ** 2))), d


# ---------------------------------------------------------------------------
# Output
# ---------------------------------------------------------------------------
def fmt(v):
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def scene_toml(name, case):
    b = case["body"]
    lines = [f"# Independent reference case '{name}' (tools/reference/generate.py, scikit-fem).",
             f"# {case['description']}",
             "# True parameters; observations.csv holds noisy surface points of the reference",
             "# solution, truth.json the discretisation and the noise floor.",
             "[body]"]
    if b["kind"] == "box":
        lines.append(f'shape = {{ kind = "box", center = {fmt(b["center"])}, size = {fmt(b["size"])} }}')
    else:
        lines.append(f'shape = {{ kind = "sphere", center = {fmt(b["center"])}, radius = {float(b["radius"])!r} }}')
    lines += ["", "[material]", f"young = {case['young']!r}", f"poisson = {case['poisson']!r}",
              f"density = {case['density']!r}", "",
              "[damping]", f"mass = {case['damping_mass']!r}", f"stiffness = {case['damping_stiffness']!r}", "",
              "[gravity]", f"acceleration = {fmt(GRAVITY)}", ""]
    effects = ["gravity", "damping"]
    if case["clamp"] is not None:
        ax = case["clamp"]["axis"]
        c = np.array(b["center"], float)
        s = np.array(b["size"], float)
        face = c[ax] - s[ax] / 2 if case["clamp"]["side"] == "min" else c[ax] + s[ax] / 2
        lo = c - s / 2 - 0.05
        hi = c + s / 2 + 0.05
        lo[ax], hi[ax] = face - 0.005, face + 0.005
        lines += ["# holds the clamped end face (the reference clamps every node on that face)",
                  "[[dirichlet]]", f"min = {fmt(np.round(lo, 6))}", f"max = {fmt(np.round(hi, 6))}", ""]
    if case["ground"] is not None:
        g = case["ground"]
        lines += ["# the reference uses a frictionless penalty p = k * penetration with",
                  f"# k = {g['penalty']:g} (converged in k, see truth.json); these are our model's springs",
                  "# per grid crossing (the thesis' law; ground/scene-penalty.toml has the reference's)",
                  "[ground]", 'scheme = "implicit"', f"normal = {fmt(g['normal'])}", f"height = {g['height']!r}",
                  f"stiffness = {g['scene_stiffness']!r}", f"softness = {g['scene_softness']!r}", ""]
        effects.append("ground")
    if case.get("angular_velocity") is not None:
        lines += ["# a rigid spin about the body's center of mass at t = 0 (the reference holds the",
                  "# clamped face's nodes at rest)",
                  "[initial]", f"angular_velocity = {fmt(case['angular_velocity'])}", ""]
        effects.append("initial_velocity")
    lines += ["[time]", f"dt = {case['dt']!r}", f"steps = {case['steps']}", "theta = 0.5"]
    if case.get("scene_substeps", 1) > 1:
        lines += ["# our integrator steps per frame (the contact is resolved in time)",
                  f"substeps = {case['scene_substeps']}"]
    lines += ["",
              "[model]", "effects = [" + ", ".join(f'"{e}"' for e in effects) + "]", ""]
    if case.get("scene_numerics"):
        lines += ["# " + case["scene_numerics_note"],
                  "[numerics]"] + [f'{k} = "{v}"' for k, v in case["scene_numerics"].items()] + [""]
    return "\n".join(lines)


def mesh_description(body, case, level):
    d = dict(level=level, element="P2 tetrahedra, isoparametric (curved boundary)" if body.tri
             else "Q2 (27-node triquadratic) hexahedra", cells=int(body.mesh.t.shape[1]),
             dofs=int(body.N), free_dofs=int(len(body.free)), **body.h)
    spec = case["mesh"][level]
    if body.tri:
        d["refinement"] = dict(spec, note="unit-ball units; radius scales them")
    else:
        d["cells_per_axis"] = list(spec["cells"])
        d["grading"] = dict(exponent=spec.get("grading", 1.0),
                            note="power grading x -> x^q towards the clamped face along its "
                                 "axis and towards both faces along the other axes")
    return d


def compact_json(obj):
    """Indented JSON with lists of numbers kept on one line."""
    import re
    text = json.dumps(obj, indent=2)
    return re.sub(r"\[\s*([-0-9.eE+,\s]*?)\s*\]",
                  lambda m: "[" + ", ".join(x.strip() for x in m.group(1).split(",")) + "]"
                  if m.group(1).strip() else "[]", text)


def run_case(name, out, quick=False, log=print):
    case = CASES[name]
    t_case = time.time()
    log(f"== {name}")
    sub = case["substeps"]
    log("  reference mesh")
    ref = Body(case, "reference")
    log(f"    {ref.N} dofs, {ref.mesh.t.shape[1]} cells")
    fr_ref, info_ref = simulate(ref, case, sub, log=log)

    rng_cmp = np.random.default_rng(case["seed"] + 7)
    cmp_pts = analytic_surface_points(case["body"], 1000 if quick else 2000, rng_cmp)
    convergence = {}
    if not quick:
        log("  coarse mesh")
        coarse = Body(case, "coarse")
        log(f"    {coarse.N} dofs")
        fr_c, info_c = simulate(coarse, case, sub, log=log)
        convergence["mesh"] = dict(compared="coarse mesh vs reference mesh, same substep",
                                   coarse=mesh_description(coarse, case, "coarse"),
                                   **compare([(ref, fr_ref), (coarse, fr_c)], cmp_pts))
        log(f"    mesh: max diff {convergence['mesh']['max_surface_point_difference']:.2e}")
        log("  half substep")
        fr_t, info_t = simulate(ref, case, 2 * sub, log=log)
        convergence["time"] = dict(compared=f"substep dt/{2 * sub} vs dt/{sub}, reference mesh",
                                   **compare([(ref, fr_ref), (ref, fr_t)], cmp_pts))
        log(f"    time: max diff {convergence['time']['max_surface_point_difference']:.2e}")
        if case["ground"] is not None:
            k4 = 4 * case["ground"]["penalty"]
            log("  4x penalty")
            fr_k, info_k = simulate(ref, case, sub, penalty=k4, log=log)
            convergence["contact"] = dict(compared=f"penalty {k4:g} vs {case['ground']['penalty']:g}, reference mesh",
                                          **compare([(ref, fr_ref), (ref, fr_k)], cmp_pts))
            log(f"    contact: max diff {convergence['contact']['max_surface_point_difference']:.2e}")

    log("  observations")
    rng = np.random.default_rng(case["seed"])
    fr_obs, pts = observe(ref, fr_ref, case, rng)
    nf, dist = noise_floor(ref, fr_ref, fr_obs, pts, 8)
    nf16, _ = noise_floor(ref, fr_ref, fr_obs, pts, 16) if not quick else (None, None)
    kin = kinematics(ref, fr_ref)
    log(f"    noise floor {nf:.6f} (subdivision 16: {nf16}), {kin}")

    d = os.path.join(out, name)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "scene.toml"), "w") as fh:
        fh.write(scene_toml(name, case))
    with open(os.path.join(d, "observations.csv"), "w") as fh:
        fh.write("frame,x,y,z\n")
        for f, p in zip(fr_obs, pts):
            fh.write(f"{f},{p[0]:.6g},{p[1]:.6g},{p[2]:.6g}\n")

    truth = dict(
        case=name, description=case["description"],
        body=case["body"],
        parameters=dict(young=case["young"], poisson=case["poisson"], density=case["density"],
                        damping_mass=case["damping_mass"], damping_stiffness=case["damping_stiffness"],
                        gravity=list(GRAVITY),
                        **({} if case.get("angular_velocity") is None else
                           dict(initial_angular_velocity=list(case["angular_velocity"]),
                                initial_angular_velocity_center=list(case["body"]["center"])))),
        clamp=None if case["clamp"] is None else dict(
            case["clamp"], note="every node of the body's face at this side of this axis "
                                "(0 = x, 1 = y) has zero displacement"),
        ground=None if case["ground"] is None else dict(
            normal=case["ground"]["normal"], height=case["ground"]["height"],
            reference_contact="frictionless penalty pressure p = k * penetration on the "
                              "reference surface, k = penalty (pressure per unit depth)",
            penalty=case["ground"]["penalty"],
            scene_stiffness=case["ground"]["scene_stiffness"],
            scene_softness=case["ground"]["scene_softness"]),
        time=dict(dt=case["dt"], steps=case["steps"], substeps=sub, substep=case["dt"] / sub,
                  scheme="Newmark average acceleration (beta 1/4, gamma 1/2), consistent mass, "
                         "Rayleigh damping, start in the undeformed configuration (frame 0) "
                         + ("at rest" if case.get("angular_velocity") is None else
                            "spinning rigidly (clamped nodes at rest)")
                         + " with the consistent initial acceleration"),
        noise=dict(sigma=case["sigma"], seed=case["seed"], rng="numpy.random.default_rng",
                   points_per_frame=case["points"],
                   frames=[int(f) for f in np.unique(fr_obs)],
                   sampling="uniform by deformed area on the boundary surface"
                            + (" except the clamped face" if case["clamp"] else "")),
        observed_points=int(len(pts)),
        noise_floor=nf,
        noise_floor_note="rms distance of the noisy observed points to the exact deformed "
                         "reference surface of their frame (quadratic facets subdivided 8x8; "
                         "16x16 gives noise_floor_subdivision_16)",
        noise_floor_subdivision_16=nf16,
        mesh=mesh_description(ref, case, "reference"),
        convergence=convergence,
        kinematics=kin,
        max_displacement_per_frame=max_displacement_per_frame(fr_ref),
        run=info_ref,
        generator=dict(script="tools/reference/generate.py", python=platform.python_version(),
                       scikit_fem=skfem.__version__, numpy=np.__version__, scipy=scipy.__version__,
                       solver="CHOLMOD (cvxopt)" if HAVE_CHOLMOD else "SuperLU",
                       quick=quick, seconds=round(time.time() - t_case, 1)),
    )
    with open(os.path.join(d, "truth.json"), "w") as fh:
        fh.write(compact_json(truth) + "\n")
    log(f"  wrote {d} in {time.time() - t_case:.0f}s")
    return truth


def selftest():
    """The fast assembly equals skfem's vector linear_elasticity / mass forms."""
    lam, mu = lame_parameters(1000.0, 0.3)
    meshes = [(MeshHex.init_tensor(np.linspace(0, 1, 3), np.linspace(0, 0.5, 2), np.linspace(0, 0.7, 3)),
               ElementHex2()),
              ball_mesh(dict(center=[0, 0.35, 0], radius=0.3), nrefs=1, hc=0.5, grade=0.5)]
    for mesh, elem in meshes:
        sb, vb = Basis(mesh, elem), Basis(mesh, ElementVector(elem))

        @BilinearForm
        def vmass(u, v, w):
            return 2.0 * dot(u, v)

        K0 = asm(linear_elasticity(lam, mu), vb)
        M0 = asm(vmass, vb)
        K, M = assemble_elasticity(sb, lam, mu, 2.0)
        ek = abs(K - K0).max() / abs(K0).max()
        em = abs(M - M0).max() / abs(M0).max()
        print(f"selftest {type(mesh).__name__}: K rel err {ek:.1e}, M rel err {em:.1e}")
        assert ek < 1e-12 and em < 1e-12


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--case", choices=sorted(CASES), action="append",
                    help="case to generate (repeatable; default: all)")
    ap.add_argument("--out", default=DEFAULT_OUT, help="output folder (default: %(default)s)")
    ap.add_argument("--quick", action="store_true",
                    help="reference run only, no convergence runs (for trying changes)")
    ap.add_argument("--selftest", action="store_true",
                    help="check the fast assembly against skfem's vector forms, then exit")
    args = ap.parse_args()
    if args.selftest:
        selftest()
        return 0
    for name in args.case or list(CASES):
        run_case(name, args.out, quick=args.quick, log=lambda *a: print(*a, flush=True))


if __name__ == "__main__":
    sys.exit(main())
