"""Physics for draw.py: the body (elasticity, clamps, loads), contact with a tilted plane,
St Venant-Kirchhoff forces, the Newmark run, and depth cameras.  Built on generate.py's
assembly, surfaces and solver (nothing shared with the Rust crates)."""

import time

import numpy as np
import scipy.sparse as sp
from skfem import Basis
from skfem.models.elasticity import lame_parameters

import generate as g
import hidden as hd
import drawmesh as dm


# ---------------------------------------------------------------------------
# The body
# ---------------------------------------------------------------------------
class DBody(g.Body):
    """generate.Body for a drawn scenario: its mesh (Q2 hexahedra or curved P2 tetrahedra),
    clamps (all nodes of the boundary facets inside a clamp box are fixed), gravity, wind and
    drag."""

    def __init__(self, sc, level):
        t0 = time.time()
        self.case = sc
        self.mesh, self.elem, self.mesh_info = make_mesh(sc, level)
        self.sb = Basis(self.mesh, self.elem)
        self.nS = self.sb.N
        self.N = 3 * self.nS
        self.doflocs = self.sb.doflocs.T.copy()
        t = sc["truth"]
        lam, mu = lame_parameters(t["young"], t["poisson"])
        self.lam, self.mu = lam, mu
        self.K, self.M = g.assemble_elasticity(self.sb, lam, mu, t["density"])
        self.F = self.M @ np.tile(np.asarray(sc["gravity"], float), self.nS)
        self.bfacets = self.mesh.boundary_facets()
        self._setup_facets()
        # clamps: the boundary facets lying inside a clamp box, all their nodes fixed
        self.facet_dofs = facet_dofs(self)
        X = self.doflocs[self.facet_dofs]                      # (nf, nfd, 3)
        depth = np.full(X.shape[:2], -np.inf)                  # how deep inside the nearest box
        for lo, hi in sc["clamp_boxes"]:
            d = np.minimum(X - np.asarray(lo), np.asarray(hi) - X).min(axis=2)
            depth = np.maximum(depth, d)
        self.clamped_facet = np.all(depth >= -CLAMP_TOL, axis=1)
        sd = np.unique(self.facet_dofs[self.clamped_facet])
        # the mesh conforms to the boxes: every boundary node inside a box is a node of a
        # facet inside it (the earlier rule "boundary nodes inside the box" fixes the same)
        inside = np.unique(self.facet_dofs[depth >= -CLAMP_TOL])
        assert np.array_equal(inside, sd), "the mesh does not conform to the clamp boxes"
        if sc["family"] == "hex" and sc["clamp_faces"]:      # exactly the faces' nodes
            assert np.any([np.abs(self.doflocs[sd, ax] - val) < 1e-9 for ax, val in sc["clamp_faces"]],
                          axis=0).all()
        self.clamp_area = float(hd.surface_mass(self, self.bfacets[self.clamped_facet]).sum() / 3) \
            if self.clamped_facet.any() else 0.0
        if self.mesh_info.get("clamp_area") is not None and sc["clamp_boxes"]:
            ca = self.mesh_info["clamp_area"]
            assert abs(self.clamp_area - ca) < 0.1 * ca, (self.clamp_area, ca)      # coarsest level: 5%
            assert self.clamped_facet.sum() == self.mesh_info["clamp_facets"]
        self.fixed = np.sort(np.concatenate([3 * sd + c for c in range(3)])) if len(sd) else np.zeros(0, int)
        self.free = np.setdiff1d(np.arange(self.N), self.fixed)
        # wind: uniform traction t on the whole surface, f_i = t int N_i dA; drag matrix c S
        self.wind_force = np.zeros(self.N)
        if sc["wind"] is not None:
            S = hd.surface_mass(self, self.bfacets)          # the whole surface
            self.wind_force = S @ np.tile(np.asarray(sc["wind"], float), self.nS)
            self.F = self.F + self.wind_force
        self.Cdrag = None
        if sc["drag"] is not None:
            self.Cdrag = sc["drag"] * hd.surface_mass(self, self.bfacets[~self.clamped_facet])
        self.h = self._edge_lengths()
        self.setup_seconds = time.time() - t0


CLAMP_TOL = 1e-6


def make_mesh(sc, level):
    spec = sc["mesh"][level]
    if sc["family"] == "hex":
        return dm.box_mesh(sc["shape"], spec["cells"], spec["grade"], spec.get("q", 1.5)) + ({},)
    return dm.gmsh_mesh(sc["shape"], spec["h"], sc["clamp_boxes"], spec.get("curvature_scale", 1.0))


def facet_dofs(body):
    """(n boundary facets, dofs per facet): the scalar dofs of each boundary facet (corner,
    mid-edge and, for Q2, face nodes): the element dofs whose reference location lies on
    the facet's reference plane."""
    R = np.asarray(body.elem.doflocs, float)                    # (Nbfun, 3)
    n = np.cross(body.f_e1, body.f_e2)
    on = np.abs(np.einsum("fd,ifd->fi", n, R[:, None, :] - body.f_orig[None])) < 1e-12
    per = on.sum(axis=1)
    assert np.all(per == per[0]), "facets with different dof counts"
    loc = np.nonzero(on)[1].reshape(len(on), per[0])
    return body.sb.element_dofs[loc, body.f_elem[:, None]]


def rigid_velocity(body, v0, w, c):
    return (np.asarray(v0, float) + np.cross(np.asarray(w, float), body.doflocs - c)).reshape(-1)


def center_of_mass(body):
    m = body.M[0::3, 0::3] @ np.ones(body.nS)
    return (m @ body.doflocs) / m.sum(), float(m.sum())


# ---------------------------------------------------------------------------
# Contact with the plane n . x = height (frictionless penalty, generate.Contact generalised)
# ---------------------------------------------------------------------------
class PlaneContact(g.Contact):
    """generate.Contact with any unit normal n: the gap is n . x - height, the contact
    problem is condensed onto the normal displacements n . u_i of the candidate nodes
    (P: rows n at the node's three free dofs), W = P A^-1 P'; the semismooth Newton on the
    condensed energy is generate.Contact.solve unchanged."""

    def __init__(self, body, ground, sub=6):
        self.k = ground["penalty"]
        self.height = ground["height"]
        n = np.asarray(ground["normal"], float)
        self.n = n / np.linalg.norm(n)
        mesh = body.mesh
        hmin = (body.doflocs @ self.n).min()
        fh = np.einsum("d,dvf->vf", self.n, mesh.p[:, mesh.facets[:, body.bfacets]])
        cand = np.nonzero(fh.max(axis=0) < hmin + ground["cap"])[0]
        self.cap_facets = cand
        E, self.w, X = g.cap_quadrature(body, cand, sub)
        self.y0 = X @ self.n - self.height
        sdofs = np.unique(E.indices)
        self.sdofs = sdofs
        self.E = E.tocsr()
        self.B = E[:, sdofs].tocsr()
        pos = -np.ones(body.N, int)
        pos[body.free] = np.arange(len(body.free))
        cols = np.stack([pos[3 * sdofs + c] for c in range(3)], axis=1)
        assert np.all(cols >= 0)
        nc = len(sdofs)
        self.P = sp.csr_matrix((np.tile(self.n, nc), cols.reshape(-1), 3 * np.arange(nc + 1)),
                               shape=(nc, len(body.free)))
        self.cdofs = np.arange(nc)           # only its length is used by Contact.prepare
        others = np.setdiff1d(np.arange(len(body.bfacets)), cand)
        od = body.sb.get_dofs(facets=body.bfacets[others]).all() if len(others) else []
        self.watch = np.setdiff1d(np.asarray(od, int), sdofs)
        self.area = float(self.w.sum())

    def _columns(self, cols):
        miss = cols[~self.have[cols]]
        PT = self.P.T.tocsc()
        for a in range(0, len(miss), 64):
            c = miss[a:a + 64]
            self.W[:, c] = self.P @ self.factor.solve(PT[:, c].toarray())
            self.have[c] = True
        return self.W[:, cols]


# ---------------------------------------------------------------------------
# St Venant-Kirchhoff internal force (hidden.svk_force with the body's own lam, mu and
# batched matrix products)
# ---------------------------------------------------------------------------
def svk_force(body):
    """f(u) = int P(F) grad N_i dV, P = F S, S = lam tr(E) I + 2 mu E, E = (F'F - I) / 2,
    F = I + grad u (vector dof order 3 i + a), with the scalar basis' quadrature; and its
    derivative along du (force.tangent).  3 x 3 tensors are kept as (3, 3, npoints) arrays."""
    lam, mu = body.lam, body.mu
    sb = body.sb
    G = np.array([sb.basis[i][0].grad for i in range(sb.Nbfun)])       # (nloc, 3, nel, nqp)
    nloc, _, nel, nq = G.shape
    Gt = np.ascontiguousarray(G.transpose(2, 0, 3, 1).reshape(nel, nloc, nq * 3))  # (e, i, q b)
    dx = sb.dx.reshape(-1)
    dofs = sb.element_dofs.T                                            # (nel, nloc)
    scatter = sp.csr_matrix((np.ones(nel * nloc), (dofs.reshape(-1), np.arange(nel * nloc))),
                            shape=(body.nS, nel * nloc))
    eye = np.eye(3)[:, :, None]

    def grad(u):
        ue = u.reshape(-1, 3)[dofs]                                     # (e, i, a)
        H = np.matmul(np.swapaxes(ue, 1, 2), Gt).reshape(nel, 3, nq, 3)  # (e, a, q, b)
        return H.transpose(1, 3, 0, 2).reshape(3, 3, -1)

    def mul(A, B):
        return np.einsum("akn,kbn->abn", A, B)

    def tr(A):
        return np.swapaxes(A, 0, 1)

    def stress(E):
        return 2.0 * mu * E + lam * (E[0, 0] + E[1, 1] + E[2, 2]) * eye

    def nodal(P):
        Pf = (P * dx).reshape(3, 3, nel, nq).transpose(2, 0, 3, 1).reshape(nel, 3, nq * 3)
        fe = np.matmul(Gt, np.swapaxes(Pf, 1, 2))                       # (e, i, a)
        return (scatter @ fe.reshape(-1, 3)).reshape(-1)

    def green(Fd):
        return 0.5 * (mul(tr(Fd), Fd) - eye)

    def force(u):
        Fd = eye + grad(u)
        return nodal(mul(Fd, stress(green(Fd))))

    def tangent(u, du):
        Fd, dF = eye + grad(u), grad(du)
        FtdF = mul(tr(Fd), dF)
        dE = 0.5 * (FtdF + tr(FtdF))
        return nodal(mul(dF, stress(green(Fd))) + mul(Fd, stress(dE)))
    gq = np.ascontiguousarray(G.transpose(2, 3, 0, 1))                 # (e, q, i, I)
    wq = sb.dx                                                          # (e, q)
    rows = (3 * dofs[:, :, None] + np.arange(3)).reshape(nel, 3 * nloc)
    R = np.broadcast_to(rows[:, :, None], (nel, 3 * nloc, 3 * nloc)).reshape(-1)
    Cc = np.broadcast_to(rows[:, None, :], (nel, 3 * nloc, 3 * nloc)).reshape(-1)
    I3 = np.eye(3)
    # the CSR pattern once; each assembly sums the element entries into it (bincount)
    pattern = sp.csr_matrix((np.arange(1, len(R) + 1, dtype=float), (R, Cc)), shape=(body.N, body.N))
    pattern.sum_duplicates()
    pattern.sort_indices()
    slot = np.empty(len(R), int)
    key = R.astype(np.int64) * body.N + Cc
    order = np.argsort(key, kind="stable")
    first = np.r_[True, key[order][1:] != key[order][:-1]]
    slot[order] = np.cumsum(first) - 1
    assert len(pattern.data) == slot.max() + 1

    def matrix(u):
        """The assembled tangent df/du (vector dofs 3 i + a).  With dP_aI / dF_bJ = delta_ab S_JI
        + lam F_aI F_bJ + mu (F_aJ F_bI + (F F')_ab delta_IJ) and v_ia = (g F')_ia (g: grad N_i):
        K_iajb = int delta_ab (g S g')_ij + lam v_ia v_jb + mu v_ib v_ja + mu (F F')_ab (g g')_ij,
        with the force's quadrature, one quadrature point at a time."""
        Fd = eye + grad(u)
        Fp = Fd.transpose(2, 0, 1).reshape(nel, nq, 3, 3)
        Sp = stress(green(Fd)).transpose(2, 0, 1).reshape(nel, nq, 3, 3)
        w = wq[:, :, None, None]
        v = np.matmul(gq, np.swapaxes(Fp, 2, 3))                        # (e, q, i, a)
        X = np.einsum("eqia,eqjb->eiajb", v * w, v)                     # int v_ia v_jb
        GG = np.matmul(gq * w, np.swapaxes(gq, 2, 3))                   # (e, q, i, j)
        C = np.matmul(Fp, np.swapaxes(Fp, 2, 3))                        # F F'
        Ke = np.einsum("eqij,eqab->eiajb", GG, mu * C)                 # int (F F')_ab (g g')_ij
        Ke += lam * X + mu * X.transpose(0, 1, 4, 3, 2)
        Y = np.einsum("eqiJ,eqjJ->eij", np.matmul(gq, Sp) * w, gq)      # int (g S g')_ij
        Ke += Y[:, :, None, :, None] * I3[None, None, :, None, :]
        return sp.csr_matrix((np.bincount(slot, Ke.reshape(-1), len(pattern.data)), pattern.indices,
                              pattern.indptr), shape=(body.N, body.N))
    force.tangent = tangent
    force.matrix = matrix
    return force


def check_svk(body, force):
    """f(u) = K u + O(|u|^2) and the tangent against central differences."""
    rng = np.random.default_rng(1)
    du = rng.normal(size=body.N)
    rel = [np.linalg.norm(force(e * du) - e * (body.K @ du)) / np.linalg.norm(e * (body.K @ du))
           for e in (1e-5, 1e-7)]
    assert 95 < rel[0] / rel[1] < 105, rel
    u1, d = 1e-2 * du, rng.normal(size=body.N)
    fd = (force(u1 + 1e-6 * d) - force(u1 - 1e-6 * d)) / 2e-6
    tan = force.tangent(u1, d)
    rt = float(np.linalg.norm(fd - tan) / np.linalg.norm(tan))
    assert rt < 1e-6, rt
    # the assembled tangent: K at u = 0, the tangent's action at u1
    K0 = force.matrix(np.zeros(body.N))
    rk = float(abs(K0 - body.K).max() / abs(body.K).max())
    assert rk < 1e-10, rk
    rm = float(np.linalg.norm(force.matrix(u1) @ d - tan) / np.linalg.norm(tan))
    assert rm < 1e-10, rm
    # the force against the linear K at a small displacement (max |u| 1e-3 of the nodes)
    us = 1e-3 * du / np.abs(du).max()
    small = float(np.linalg.norm(force(us) - body.K @ us) / np.linalg.norm(body.K @ us))
    return dict(linearisation_remainder_ratio=float(rel[0] / rel[1]), tangent_vs_fd=rt,
                force_vs_linear_small=small,
                assembled_tangent_at_zero_vs_K=rk, assembled_tangent_vs_tangent=rm)


# ---------------------------------------------------------------------------
# Newmark average acceleration
# ---------------------------------------------------------------------------
def simulate(body, sc, substeps, log=print, cap=None):
    t = sc["truth"]
    h = sc["dt"] / substeps
    I = body.free
    M = body.M[I][:, I].tocsr()
    K = body.K[I][:, I].tocsr()
    C = t["damping_mass"] * M + t["damping_stiffness"] * K
    if body.Cdrag is not None:
        C = C + body.Cdrag[I][:, I]
    C = sp.csr_matrix(C)
    F = body.F[I]
    c0, c1 = 4.0 / h ** 2, 2.0 / h
    t0 = time.time()
    fac = g.Factor(c0 * M + c1 * C + K)
    force = svk_force(body) if sc["svk"] else None
    f_int = (lambda u: K @ u) if force is None else (lambda u: force(g.u_full(body, u))[I])
    v = np.zeros(len(I))
    if sc["initial"] is not None:
        v = rigid_velocity(body, sc["initial"]["velocity"], sc["initial"]["angular_velocity"],
                           np.asarray(sc["initial"]["center"]))[I]
    a = g.Factor(M).solve(F - C @ v)
    contact = None
    if sc["ground"] is not None:
        gr = dict(sc["ground"], cap=cap if cap is not None else sc["ground"]["cap"])
        contact = PlaneContact(body, gr)
        if len(contact.cap_facets) == 0:
            # a coarse level's lowest facets reach above the cap: widen it (as for a node
            # outside it touching the ground)
            raise CapError("no boundary facet within the contact cap")
        contact.prepare(fac, len(I))
    u = np.zeros(len(I))
    frames = [np.zeros((body.nS, 3))]
    iterations, contact_steps, min_watch, depth = 0, 0, np.inf, []
    tfac, refactors = fac, 0
    energy = []
    for n in range(sc["steps"] * substeps):
        rhs = F + M @ (c0 * u + (4.0 / h) * v + a) + C @ (c1 * u + v)
        if force is None:
            un = fac.solve(rhs)
        else:       # modified Newton: the factor of the assembled tangent, refreshed when slow
            un = u + h * v + 0.5 * h * h * a                            # predictor
            r = c0 * (M @ un) + c1 * (C @ un) + f_int(un) - rhs
            rn, tol = np.linalg.norm(r), 1e-9 * np.linalg.norm(F)
            for k in range(60):
                if rn <= tol:
                    break
                un = un - tfac.solve(r)
                r = c0 * (M @ un) + c1 * (C @ un) + f_int(un) - rhs
                rn, rn_old = np.linalg.norm(r), rn
                iterations += 1
                if rn > 0.1 * rn_old and rn > tol:
                    KT = force.matrix(g.u_full(body, un))[I][:, I]
                    try:
                        tfac = g.Factor(c0 * M + c1 * C + KT)
                        refactors += 1
                    except ArithmeticError:
                        # the St Venant-Kirchhoff tangent is indefinite here (strong
                        # compression): modified Newton goes on with the last factor
                        pass
            else:
                raise RuntimeError(f"substep {n}: Newton did not converge")
        if contact is not None:
            f, it = contact.solve(contact.P @ un)
            if f is not None:
                un = un - fac.solve(contact.P.T @ f)
                iterations += it
                contact_steps += 1
        an = c0 * (un - u) - (4.0 / h) * v - a
        vn = v + 0.5 * h * (a + an)
        u, v, a = un, vn, an
        if contact is not None:
            full = g.u_full(body, u).reshape(-1, 3)
            if len(contact.watch):
                hw = (body.doflocs[contact.watch] + full[contact.watch]) @ contact.n - contact.height
                min_watch = min(min_watch, hw.min())
                if hw.min() <= 0:
                    raise CapError("a boundary node outside the contact cap reached the ground")
            gap = contact.y0 + contact.E @ (full @ contact.n)
            depth.append(max(0.0, -gap.min()))
        if (n + 1) % substeps == 0:
            frames.append(g.u_full(body, u).reshape(-1, 3))
            if force is None and contact is None:
                energy.append(0.5 * v @ (M @ v) + 0.5 * u @ (K @ u) - F @ u)
    info = dict(substeps=substeps, substep=h, seconds=round(time.time() - t0, 2),
                free_dofs=int(len(I)), newton_iterations=int(iterations))
    if force is not None:
        info["tangent_factorisations"] = refactors
    if energy and not (t["damping_mass"] or t["damping_stiffness"] or body.Cdrag is not None
                       or contact is not None):     # conservative: Newmark keeps the energy
        e0 = 0.5 * v0_energy(M, sc, body, I)
        info["energy_drift_rel"] = float(abs(energy[-1] - e0) / max(abs(e0), np.abs(energy).max(), 1e-30))
    if contact is not None:
        per_frame = np.array(depth).reshape(sc["steps"], substeps).max(axis=1)
        tail = max(1, sc["steps"] // 5)
        info.update(contact_substeps=contact_steps, contact_candidate_nodes=int(len(contact.sdofs)),
                    contact_cap=float(gr["cap"]), max_penetration=float(per_frame.max()),
                    final_frames_max_penetration=float(per_frame[-tail:].max()),
                    lowest_non_candidate_height=float(min_watch))
    log(f"    {sc['steps']}x{substeps} substeps in {info['seconds']:.1f}s"
        + (f", {iterations} Newton iterations" if iterations else "")
        + (f", {refactors} tangent factorisations" if force is not None else ""))
    return np.array(frames), info


def v0_energy(M, sc, body, I):
    if sc["initial"] is None:
        return 0.0
    v = rigid_velocity(body, sc["initial"]["velocity"], sc["initial"]["angular_velocity"],
                       np.asarray(sc["initial"]["center"]))[I]
    return float(v @ (M @ v))


class CapError(RuntimeError):
    pass


def run(body, sc, substeps, log=print):
    """simulate, widening the contact cap until no node outside it touches the ground."""
    cap = None
    while True:
        try:
            return simulate(body, sc, substeps, log, cap)
        except CapError:
            cap = 4 * (cap or sc["ground"]["cap"])
            log(f"    contact cap widened to {cap:.3f}")


# ---------------------------------------------------------------------------
# Depth cameras (hidden.py's convention, any camera; pixels found per triangle bounding box)
# ---------------------------------------------------------------------------
camera_frame = hd.camera_frame


def rays(cam, i, j):
    e, fwd, right, up, f = camera_frame(cam)
    cx, cy = cam["width"] / 2, cam["height"] / 2
    return fwd[None, :] + ((i + 0.5 - cx) / f)[:, None] * right - ((j + 0.5 - cy) / f)[:, None] * up


def depth_image(T, cam):
    """Depth (along the viewing axis) of the nearest triangle of T at every pixel centre, NaN
    where the ray misses: exact ray-triangle intersections (Moller-Trumbore) of every pixel
    whose centre lies in a triangle's projected bounding box."""
    e, fwd, right, up, f = camera_frame(cam)
    W, H = cam["width"], cam["height"]
    V = T.reshape(-1, 3) - e
    z = V @ fwd
    assert z.min() > 0, "the body is behind the camera"
    pi = (W / 2 + f * (V @ right) / z - 0.5).reshape(-1, 3)
    pj = (H / 2 - f * (V @ up) / z - 0.5).reshape(-1, 3)
    i0 = np.clip(np.floor(pi.min(axis=1)), 0, W).astype(int)
    i1 = np.clip(np.ceil(pi.max(axis=1)), -1, W - 1).astype(int)
    j0 = np.clip(np.floor(pj.min(axis=1)), 0, H).astype(int)
    j1 = np.clip(np.ceil(pj.max(axis=1)), -1, H - 1).astype(int)
    ni, nj = np.maximum(i1 - i0 + 1, 0), np.maximum(j1 - j0 + 1, 0)
    cnt = ni * nj
    tri = np.repeat(np.arange(len(T)), cnt)
    k = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    ii = i0[tri] + k % ni[tri]
    jj = j0[tri] + k // ni[tri]
    D = rays(cam, ii.astype(float), jj.astype(float))
    A, B, Cc = T[tri, 0], T[tri, 1], T[tri, 2]
    e1, e2 = B - A, Cc - A
    pv = np.cross(D, e2)
    det = np.einsum("nk,nk->n", e1, pv)
    ok = np.abs(det) > 1e-14
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = e - A
    bu = np.einsum("nk,nk->n", s, pv) * inv
    q = np.cross(s, e1)
    bv = np.einsum("nk,nk->n", D, q) * inv
    zz = np.einsum("nk,nk->n", e2, q) * inv
    hit = ok & (bu >= 0) & (bv >= 0) & (bu + bv <= 1) & (zz > 0)
    Z = np.full(H * W, np.inf)
    np.minimum.at(Z, (jj * W + ii)[hit], zz[hit])
    Z[~np.isfinite(Z)] = np.nan
    return Z.reshape(H, W)


def unproject(cam, i, j, z):
    e = np.array(cam["eye"], float)
    return e + z[:, None] * rays(cam, i.astype(float), j.astype(float))
