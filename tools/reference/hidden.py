#!/usr/bin/env python3
"""Hidden-effect reference cases for `softbody diagnose`, computed with scikit-fem.

"The real world" of a 1.05 x 0.22 x 0.22 cantilever (the accuracy issue's bar) in six
physical variants, each observed in three styles at several noise levels; every case pairs
one variant's observations with a scene that lacks one effect (or, for the controls, lacks
nothing that matters).  The physics is written down again here (nothing is shared with the
Rust crates); the elasticity, meshes, surfaces and linear solver are generate.py's.

Variants (all small-strain linear elasticity, Q2 hexahedra, Newmark average acceleration,
consistent mass, gravity (0, -10, 0), clamped at the x-min end face, Rayleigh mass damping
a1 = 0.8 unless said otherwise):

  base              the bar swinging down from rest
  stiffness_field   a soft band across the middle of the bar,
                    E(x) = E exp(-1.4 exp(-((x - 0.525) / 0.2)^2)) (0.25 E at x = 0.525)
  initial_velocity  starts with the rigid rotation about the clamped edge's axis z,
                    v = w e_z x (X - (0, 1, 0)), w = 1.5 rad/s (tip moving up at 1.6 m/s)
  drag              plus a linear air drag, a traction -c v on the whole surface
                    (consistent surface mass matrix c int N_i N_j dA), c = 0.2
  damped            Rayleigh mass damping a1 = 4 instead of 0.8
  clamp             the end face held by springs sigma n = -k u, k = 5e3 (consistent
                    surface mass matrix of the face), instead of fixed nodes
  inclusion         a stiff cube (5 E, side 0.05) in the middle of the bar: too small to see
  nonlinear         geometrically nonlinear: St. Venant-Kirchhoff, P = F S, S = lam tr(E) I
                    + 2 mu E, E = (F^T F - I) / 2 (the same lam, mu; the linear variants'
                    strain is its small-displacement limit). The bar's tip turns by ~25 degrees,
                    where linear elasticity stretches it along its tangent instead of letting it
                    swing on an arc: what `corotation` (large rotations, small strain) models.
                    Each substep's equation M a + C v + f(u) = F is solved by Newton's method
                    (the exact tangent by GMRES, preconditioned by the linear system's factor),
                    to |residual| <= 1e-9 |F|
                    or an update below 1e-12 (the residual's roundoff level)

The controls (nothing hidden): the base bar and the stiff inclusion at every style and level;
the complete model of the damped, drag, clamp and initial-velocity variants (the effect in
the scene at its true strength and fitted with E and nu); generate.py's landing sphere with
its ground.

Styles (noise: isotropic Gaussian sigma for the sampled styles, Gaussian depth noise sigma
for the camera):

  samples   points uniformly by deformed area on the surface (not the clamped face)
  partial   the same, on the surface facing one viewing direction only (one side seen)
  camera    one pinhole depth camera (cutfem's camera convention, camera file beside the
            CSV), a z-buffer of the deformed surface, depth + noise, unprojected pixels

Writes OUT/hidden/ (default tests/reference_values/independent/hidden):
  <variant>/<style>-<sigma>.csv [+ .cameras.json]   the observations
  scenes/<case>.toml                                the scene given to diagnose
  scenes/complete-<effect>.toml                     controls: the complete model, the
                                                    effect in the scene and fitted
  cases.json                                        every case: scene, observations,
                                                    hidden effect (null for controls),
                                                    true noise, truth

Usage:  python hidden.py [--out DIR] [--variant NAME ...]
"""

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse
import json
import sys
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from skfem import BilinearForm, FacetBasis, asm
from skfem.models.elasticity import lame_parameters

import generate as g

DEFAULT_OUT = os.path.join(g.DEFAULT_OUT, "hidden")

BAR = dict(kind="box", center=[0.525, 1.0, 0.0], size=[1.05, 0.22, 0.22])
LENGTH = 1.05
BASE = dict(
    body=BAR, young=2400.0, poisson=0.35, density=1.0,
    damping_mass=0.8, damping_stiffness=0.0,
    clamp=dict(axis=0, side="min"), ground=None,
    # 20 observed frames, 0.6 s: about one period of the first bending mode
    dt=0.03, steps=20, substeps=8,
    mesh=dict(reference=dict(cells=[16, 4, 4], grading=1.5)),
    resolution=20,
)
VARIANTS = {
    "base": dict(),
    "stiffness_field": dict(field=dict(kind="band", depth=1.4, center=0.525, width=0.2)),
    "initial_velocity": dict(omega=1.5),
    "drag": dict(drag=0.2),
    "damped": dict(damping_mass=4.0),
    "clamp": dict(springs=5.0e3),
    "inclusion": dict(field=dict(kind="inclusion", center=[0.525, 1.0, 0.0], side=0.05, factor=5.0)),
    "nonlinear": dict(nonlinear=True),
}
STYLES = ("samples", "partial", "camera")
SIGMAS = (0.0025, 0.005, 0.01, 0.02, 0.04)
# the partial and camera styles at two levels (repository size); the controls' variants at all
# five (the false-alarm rate is measured on them), the extra levels with seeds of their own
STYLE_SIGMAS = dict(samples=SIGMAS, partial=SIGMAS[2:4], camera=SIGMAS[2:4])
CONTROL_VARIANTS = ("base", "inclusion")
POINTS = 120                      # per frame, samples and partial styles
VIEW = np.array([0.2, 0.6, 1.0])  # the partial view looks from this direction
CAMERA = dict(eye=[0.525, 1.55, 1.9], target=[0.525, 0.9, 0.0], up=[0.0, 1.0, 0.0],
              fov_y=0.62, width=40, height=30)
SEED = 20261204
# the cases sliding.py writes into cases.json (kept when this script rewrites it)
FRICTION_CASES = ("friction", "complete-friction")

# The landing sphere of generate.py's `ground` case, its scene without the ground among the
# effects (the [ground] section's contact law kept: the diagnosis must find the plane)
GROUND = dict(case="ground/samples-0.01", scene="scenes/ground.toml",
              observations="../ground/observations.csv", hidden="ground", style="samples",
              sigma=0.01)

# The cases: (name, variant, effects of the scene, hidden effect or None)
CASES = [
    ("none", "base", ["gravity", "damping"], None),
    ("inclusion", "inclusion", ["gravity", "damping"], None),
    ("gravity", "base", ["damping"], "gravity"),
    ("damping", "damped", ["gravity"], "damping"),
    ("stiffness_field", "stiffness_field", ["gravity", "damping"], "stiffness_field"),
    ("initial_velocity", "initial_velocity", ["gravity", "damping"], "initial_velocity"),
    ("drag", "drag", ["gravity", "damping"], "drag"),
    ("clamp", "clamp", ["gravity", "damping"], "clamp"),
    ("corotation", "nonlinear", ["gravity", "damping"], "corotation"),
]

# Controls with the complete model: the variant's effect is in the scene at its true strength and
# fitted with the material (a user who added the effect the diagnosis named and diagnoses
# again), so nothing may be called missing. (name, variant, effects, sections, fitted).
# The initial rotation about the clamp's axis is our rigid motion about the centre of mass
# c = (0.525, 1, 0): v0 = w x (c - (0, 1, 0)) = (0, 1.5 * 0.525, 0).
FIT = ["young", "poisson"]
COMPLETE = [
    ("complete-damping", "damped", ["gravity", "damping"], [], FIT + ["damping_mass"]),
    ("complete-drag", "drag", ["gravity", "damping", "drag"], ["[drag]", "coefficient = 0.2"],
     FIT + ["drag"]),
    ("complete-clamp", "clamp", ["gravity", "damping", "clamp"], ["[clamp]", "stiffness = 5000.0"],
     FIT + ["clamp"]),
    ("complete-initial_velocity", "initial_velocity", ["gravity", "damping", "initial_velocity"],
     ["[initial]", "velocity = [0.0, 0.7875, 0.0]", "angular_velocity = [0.0, 0.0, 1.5]"],
     FIT + ["initial_velocity", "initial_angular_velocity"]),
    ("complete-corotation", "nonlinear", ["gravity", "damping", "corotation"], [], FIT),
]
# generate.py's landing sphere with its ground: a control with contact
GROUND_CONTROL = dict(case="complete-ground/samples-0.01", scene="../ground/scene.toml",
                      observations="../ground/observations.csv", hidden=None, style="samples",
                      sigma=0.01)


# ---------------------------------------------------------------------------
# Physics
# ---------------------------------------------------------------------------
def stiffness_scale(field):
    """Young's modulus factor as a function of the points x (3, ...), or None."""
    if field is None:
        return None
    if field["kind"] == "band":
        d, c, w = field["depth"], field["center"], field["width"]
        return lambda x: np.exp(-d * np.exp(-((x[0] - c) / w) ** 2))
    c, a, f = np.array(field["center"]), field["side"] / 2, field["factor"]

    def inside(x):
        return ((np.abs(x[0] - c[0]) <= a) & (np.abs(x[1] - c[1]) <= a)
                & (np.abs(x[2] - c[2]) <= a))
    return lambda x: np.where(inside(x), f, 1.0)


def scaled_stiffness(body, scale):
    """K of isotropic elasticity with (lambda, mu) scaled by scale(x) at the quadrature
    points (the generate.py assembly with a coefficient)."""
    lam, mu = lame_parameters(BASE["young"], BASE["poisson"])
    sb = body.sb
    S = [[None] * 3 for _ in range(3)]
    for a in range(3):
        for b in range(3):
            @BilinearForm
            def form(u, v, w, a=a, b=b):
                return scale(w.x) * v.grad[a] * u.grad[b]
            S[a][b] = asm(form, sb).tocsr()
    lap = S[0][0] + S[1][1] + S[2][2]
    blocks = [[lam * S[a][b] + mu * S[b][a] + (mu * lap if a == b else 0 * lap) for b in range(3)]
              for a in range(3)]
    Kb = sp.bmat(blocks).tocsr()
    n = sb.N
    perm = (3 * np.arange(n)[None, :] + np.arange(3)[:, None]).reshape(-1)
    P = sp.csr_matrix((np.ones(3 * n), (perm, np.arange(3 * n))), shape=(3 * n, 3 * n))
    return (P @ Kb @ P.T).tocsr()


def quadrature_share(body, scale):
    """Volume where the scale differs from 1 (quadrature estimate)."""
    sb = body.sb
    x = sb.mapping.F(sb.X)                                  # (3, nel, nqp)
    w = np.abs(sb.mapping.detDF(sb.X)) * sb.W[None, :]
    return float(np.sum(w * (np.abs(scale(x) - 1.0) > 1e-12)))


def surface_mass(body, facets):
    """c-free consistent surface mass int_G N_i N_j dA over `facets`, as a vector matrix."""
    fb = FacetBasis(body.mesh, body.elem, facets=facets)

    @BilinearForm
    def m(u, v, w):
        return u * v
    S = asm(m, fb).tocsr()
    return sp.kron(S, sp.identity(3), format="csr")


def build(variant):
    spec = VARIANTS[variant]
    body = g.Body(BASE, "reference")
    scale = stiffness_scale(spec.get("field"))
    extra = dict()
    if scale is not None:
        body.K = scaled_stiffness(body, scale)
        extra["field_volume"] = quadrature_share(body, scale)
    C = sp.csr_matrix((body.N, body.N))
    outer = body.bfacets
    if "drag" in spec:
        C = spec["drag"] * surface_mass(body, outer[~body.clamped_facet])
    if "springs" in spec:
        body.K = (body.K + spec["springs"] * surface_mass(body, outer[body.clamped_facet])).tocsr()
        body.fixed = np.zeros(0, int)
        body.free = np.arange(body.N)
    v0 = np.zeros((body.nS, 3))
    if "omega" in spec:
        X = body.doflocs - np.array([0.0, 1.0, 0.0])
        v0 = spec["omega"] * np.cross(np.array([0.0, 0.0, 1.0]), X)
    if spec.get("nonlinear"):
        extra["internal_force"] = svk_force(body)
    return body, C, v0.reshape(-1), spec.get("damping_mass", BASE["damping_mass"]), extra


def svk_force(body):
    """The St. Venant-Kirchhoff internal force f(u) = int P(F) grad(phi_i) dV (vector dof
    order 3 i + a), P = F (lam tr(E) I + 2 mu E), F = I + grad u, with the scalar basis'
    quadrature; its derivative at u = 0 is body.K (checked in run_variant)."""
    lam, mu = lame_parameters(BASE["young"], BASE["poisson"])
    sb = body.sb
    G = np.array([sb.basis[i][0].grad for i in range(sb.Nbfun)])   # (nloc, 3, nel, nqp)
    dx = sb.dx                                                      # (nel, nqp)
    dofs = sb.element_dofs                                          # (nloc, nel)
    eye = np.eye(3)

    def grad(u):
        return np.einsum("iea,ibeq->eqab", u.reshape(-1, 3)[dofs], G)   # (nel, nqp, 3, 3)

    def stress(E):
        return 2.0 * mu * E + lam * np.trace(E, axis1=2, axis2=3)[..., None, None] * eye

    def nodal(P):
        fe = np.einsum("eqab,ibeq,eq->iea", P, G, dx)
        f = np.zeros((body.nS, 3))
        np.add.at(f, dofs, fe)
        return f.reshape(-1)

    def force(u):
        Fd = eye + grad(u)
        E = 0.5 * (np.einsum("eqka,eqkb->eqab", Fd, Fd) - eye)
        return nodal(np.einsum("eqak,eqkb->eqab", Fd, stress(E)))

    def tangent(u, du):
        """The derivative of force at u along du: dP = dF S + F dS, dS = S(sym(F^T dF))."""
        Fd, dF = eye + grad(u), grad(du)
        E = 0.5 * (np.einsum("eqka,eqkb->eqab", Fd, Fd) - eye)
        FtdF = np.einsum("eqka,eqkb->eqab", Fd, dF)
        dE = 0.5 * (FtdF + np.swapaxes(FtdF, 2, 3))
        dP = np.einsum("eqak,eqkb->eqab", dF, stress(E)) + np.einsum("eqak,eqkb->eqab", Fd, stress(dE))
        return nodal(dP)
    force.tangent = tangent
    return force


def simulate(body, C_extra, v0, a1, internal_force=None):
    """Newmark average acceleration with substeps; frames 0..steps of the nodal
    displacements (nS, 3). With `internal_force` (a function of the full displacement
    vector) each substep's M a + C v + f(u) = F is solved by Newton iterations with the
    linear matrix (module docs)."""
    h = BASE["dt"] / BASE["substeps"]
    I = body.free
    M = body.M[I][:, I].tocsr()
    K = body.K[I][:, I].tocsr()
    C = (a1 * M + BASE["damping_stiffness"] * K + C_extra[I][:, I]).tocsr()
    F = body.F[I]
    c0, c1 = 4.0 / h ** 2, 2.0 / h
    fac = g.Factor(c0 * M + c1 * C + K)
    f_int = (lambda u: K @ u) if internal_force is None else \
        (lambda u: internal_force(g.u_full(body, u))[I])
    u = np.zeros(len(I))
    v = v0[I].copy()
    a = g.Factor(M).solve(F - C @ v)            # consistent initial acceleration, u0 = 0
    frames = [np.zeros((body.nS, 3))]
    iterations = 0
    for n in range(BASE["steps"] * BASE["substeps"]):
        rhs = F + M @ (c0 * u + (4.0 / h) * v + a) + C @ (c1 * u + v)
        un = fac.solve(rhs - f_int(u) + K @ u) if internal_force is not None else fac.solve(rhs)
        if internal_force is not None:
            for k in range(30):
                r = c0 * (M @ un) + c1 * (C @ un) + f_int(un) - rhs
                if np.linalg.norm(r) <= 1e-9 * np.linalg.norm(F):
                    break
                # Newton step: GMRES on the exact tangent, preconditioned by the linear factor
                T = spla.LinearOperator(
                    (len(I), len(I)), dtype=float,
                    matvec=lambda d: c0 * (M @ d) + c1 * (C @ d)
                    + internal_force.tangent(g.u_full(body, un), g.u_full(body, d))[I])
                P = spla.LinearOperator((len(I), len(I)), dtype=float, matvec=fac.solve)
                du, info = spla.gmres(T, r, M=P, rtol=1e-12, atol=0.0, restart=60, maxiter=10)
                un = un - du
                iterations += 1
                if np.abs(du).max() <= 1e-12:   # the residual's roundoff level reached
                    break
            else:
                raise RuntimeError(f"substep {n}: Newton did not converge ({np.linalg.norm(r):.3e})")
        an = c0 * (un - u) - (4.0 / h) * v - a
        v = v + 0.5 * h * (a + an)
        u, a = un, an
        if (n + 1) % BASE["substeps"] == 0:
            frames.append(g.u_full(body, u).reshape(-1, 3))
    simulate.newton_iterations = iterations
    return np.array(frames)


# ---------------------------------------------------------------------------
# Observation styles (noise-free geometry first, noise per level)
# ---------------------------------------------------------------------------
def outward_normals(T):
    n = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    n /= np.linalg.norm(n, axis=1)[:, None]
    # a box is convex: outward points away from the body's centre
    out = T.mean(axis=1) - T.reshape(-1, 3).mean(axis=0)
    return n * np.sign(np.einsum("ij,ij->i", n, out))[:, None]


def sample_points(body, surf, U, rng, partial, hide=None):
    """POINTS points uniformly by deformed area on the surface but the facets `hide` (default:
    the clamped face), on the side facing VIEW only with `partial`."""
    T = surf.triangles(U)
    A = g.tri_areas(T) * ~(body.clamped_facet if hide is None else hide)[surf.tf]
    if partial:
        A = A * (outward_normals(T) @ (VIEW / np.linalg.norm(VIEW)) > 0.1)
    k = rng.choice(len(A), size=POINTS, p=A / A.sum())
    r1, r2 = rng.random(POINTS), rng.random(POINTS)
    sq = np.sqrt(r1)
    bary = np.stack([1 - sq, sq * (1 - r2), sq * r2], axis=1)
    st = np.einsum("nk,nkd->nd", bary, surf.tst[k])
    return body.eval_matrix(surf.tf[k], st) @ (body.doflocs + U)


def camera_frame(cam=CAMERA):
    """Eye, viewing axis, right and up unit vectors, and the focal length in pixels of `cam`."""
    e, t, a = (np.array(cam[k], float) for k in ("eye", "target", "up"))
    fwd = (t - e) / np.linalg.norm(t - e)
    right = np.cross(fwd, a)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    f = (cam["height"] / 2) / np.tan(cam["fov_y"] / 2)
    return e, fwd, right, up, f


def depth_image(T):
    """Depth z (along the viewing axis) of the nearest surface at every pixel centre, NaN
    where the ray misses: exact ray-triangle intersections (Moller-Trumbore)."""
    e, fwd, right, up, f = camera_frame()
    W, H = CAMERA["width"], CAMERA["height"]
    cx, cy = W / 2, H / 2
    Z = np.full((H, W), np.nan)
    A, B, C = T[:, 0], T[:, 1], T[:, 2]
    e1, e2 = B - A, C - A
    for j in range(H):
        v = j + 0.5
        D = fwd[None, :] + ((np.arange(W) + 0.5 - cx) / f)[:, None] * right - ((v - cy) / f) * up
        pv = np.cross(D[:, None, :], e2[None])                    # (W, ntri, 3)
        det = np.einsum("tk,wtk->wt", e1, pv)
        ok = np.abs(det) > 1e-14
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = e - A                                                 # (ntri, 3)
        bu = np.einsum("tk,wtk->wt", s, pv) * inv
        q = np.cross(s, e1)                                       # (ntri, 3)
        bv = np.einsum("wk,tk->wt", D, q) * inv
        z = np.einsum("tk,tk->t", e2, q)[None, :] * inv           # ray parameter = depth
        hit = ok & (bu >= 0) & (bv >= 0) & (bu + bv <= 1) & (z > 0)
        z = np.where(hit, z, np.inf)
        zmin = z.min(axis=1)
        Z[j] = np.where(np.isfinite(zmin), zmin, np.nan)
    return Z


def unproject(i, j, z):
    e, fwd, right, up, f = camera_frame()
    cx, cy = CAMERA["width"] / 2, CAMERA["height"] / 2
    D = fwd[None, :] + ((i + 0.5 - cx) / f)[:, None] * right - ((j + 0.5 - cy) / f)[:, None] * up
    return e + z[:, None] * D


# ---------------------------------------------------------------------------
# Output
# ---------------------------------------------------------------------------
def fmt(v):
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def scene_toml(name, effects, hidden, variant=None, sections=(), fitted=None):
    b = BAR
    c, s = np.array(b["center"]), np.array(b["size"])
    lo, hi = c - s / 2 - 0.05, c + s / 2 + 0.05
    lo[0], hi[0] = -0.005, 0.005
    lines = [f"# Hidden-effect reference case '{name}' (tools/reference/hidden.py, scikit-fem).",
             "# " + (f"The complete model of variant '{variant}': a control." if fitted
                     else "Nothing of the catalogue is hidden (a control)." if hidden is None
                     else f"The observed bar has the effect '{hidden}'; this scene lacks it."),
             "[body]",
             f'shape = {{ kind = "box", center = {fmt(c)}, size = {fmt(s)} }}',
             f"resolution = {BASE['resolution']}", "",
             "[material]", f"young = {BASE['young']!r}", f"poisson = {BASE['poisson']!r}",
             f"density = {BASE['density']!r}", ""]
    if "damping" in effects:
        a1 = VARIANTS.get(variant, {}).get("damping_mass", BASE["damping_mass"]) if fitted else \
            BASE["damping_mass"]
        lines += ["[damping]", f"mass = {a1!r}",
                  f"stiffness = {BASE['damping_stiffness']!r}", ""]
    if "gravity" in effects:
        lines += ["[gravity]", f"acceleration = {fmt(g.GRAVITY)}", ""]
    if sections:
        lines += list(sections) + [""]
    lines += ["# holds the clamped end face", "[[dirichlet]]",
              f"min = {fmt(np.round(lo, 6))}", f"max = {fmt(np.round(hi, 6))}", "",
              "[time]", f"dt = {BASE['dt']!r}", f"steps = {BASE['steps']}", "theta = 0.5", ""]
    return "\n".join(lines + box_scene_tail(effects, fitted))


def box_scene_tail(effects, fitted):
    """A box scene's [model], [fit] (when `fitted`) and [numerics] lines."""
    lines = ["[model]", "effects = [" + ", ".join(f'"{e}"' for e in effects) + "]", ""]
    if fitted:
        lines += ["[fit]", "parameters = [" + ", ".join(f'"{p}"' for p in fitted) + "]", ""]
    # what a user of a box would set (docs/simulation.md, "Dual contouring"): marching cubes
    # bevels the bar's edges by up to a surface cell (the control seen by the depth camera at
    # sigma 0.0025 misfit by 1.75 sigma with it, 1.52 sigma without)
    return lines + ["# a box: its sharp edges kept in the simulated surface", "[numerics]",
                    'surface_method = "dual_contouring"', ""]


def write_csv(path, frames, pts, cams=None):
    with open(path, "w") as fh:
        fh.write("frame,x,y,z" + (",camera" if cams is not None else "") + "\n")
        for k, (f, p) in enumerate(zip(frames, pts)):
            tail = ",0" if cams is not None else ""
            fh.write(f"{f},{p[0]:.5f},{p[1]:.5f},{p[2]:.5f}{tail}\n")


def run_variant(variant, out, log):
    t0 = time.time()
    body, C, v0, a1, extra = build(variant)
    force = extra.pop("internal_force", None)
    if force is not None:
        # f(u) = K u + O(|u|^2): the nonlinear force's derivative at rest is the linear K, so
        # the relative remainder falls 100-fold when eps does
        rng = np.random.default_rng(1)
        du = rng.normal(size=body.N)
        rel = []
        for eps in (1e-4, 1e-6):
            rel.append(np.linalg.norm(force(eps * du) - eps * (body.K @ du))
                       / np.linalg.norm(eps * (body.K @ du)))
            log(f"  {variant}: |f(eps u) - K eps u| / |K eps u| = {rel[-1]:.3e} at eps {eps:g}")
        assert 95 < rel[0] / rel[1] < 105
        # the Newton tangent against central differences of the force, at a large displacement
        u1, d = 1e-2 * du, rng.normal(size=body.N)
        fd = (force(u1 + 1e-6 * d) - force(u1 - 1e-6 * d)) / 2e-6
        tan = force.tangent(u1, d)
        rel_t = np.linalg.norm(fd - tan) / np.linalg.norm(tan)
        log(f"  {variant}: tangent vs central differences {rel_t:.2e}")
        assert rel_t < 1e-6
    frames = simulate(body, C, v0, a1, force)
    if force is not None:
        extra["newton_iterations"] = int(simulate.newton_iterations)
        linear = simulate(body, C, v0, a1)
        extra["rms_difference_to_linear"] = float(np.sqrt(np.mean((frames - linear) ** 2)))
        log(f"  {variant}: {extra['newton_iterations']} Newton iterations; nodal rms difference "
            f"to the linear bar {extra['rms_difference_to_linear']:.4f}")
    log(f"  {variant}: {body.N} dofs, simulated in {time.time() - t0:.1f}s, "
        f"largest displacement {np.abs(frames).max():.3f}")
    surf = g.Surface(body, 4)
    fine = g.Surface(body, 8)
    d = os.path.join(out, variant)
    os.makedirs(d, exist_ok=True)
    vi = list(VARIANTS).index(variant)
    files = {}
    depth = [depth_image(surf.triangles(frames[f])) for f in range(1, BASE["steps"] + 1)]
    for si, style in enumerate(STYLES):
        levels = [(li, s) for li, s in enumerate(STYLE_SIGMAS[style])]
        if variant in CONTROL_VARIANTS:
            levels += [(10 + k, s) for k, s in enumerate(SIGMAS) if s not in STYLE_SIGMAS[style]]
        for li, sigma in levels:
            rng = np.random.default_rng([SEED, vi, si, li])
            fr, pts = [], []
            for f in range(1, BASE["steps"] + 1):
                if style == "camera":
                    Z = depth[f - 1]
                    jj, ii = np.nonzero(np.isfinite(Z))
                    z = Z[jj, ii] + sigma * rng.normal(size=len(ii))
                    P = unproject(ii, jj, z)
                else:
                    P = sample_points(body, surf, frames[f], rng, style == "partial")
                    P = P + sigma * rng.normal(size=P.shape)
                fr.append(np.full(len(P), f))
                pts.append(P)
            fr, pts = np.concatenate(fr), np.concatenate(pts)
            name = f"{style}-{sigma:g}"
            write_csv(os.path.join(d, name + ".csv"), fr, pts, None if style != "camera" else True)
            if style == "camera":
                with open(os.path.join(d, name + ".cameras.json"), "w") as fh:
                    json.dump(dict(cameras=[dict(id=0, **CAMERA)]), fh)
            dist = np.empty(len(pts))
            for f in np.unique(fr):
                sel = fr == f
                dist[sel] = g.distances_to_surface(pts[sel], fine.triangles(frames[f]))
            files[name] = dict(csv=f"{variant}/{name}.csv", style=style, sigma=sigma,
                               points=int(len(pts)), points_per_frame=round(len(pts) / BASE["steps"], 1),
                               rms_distance_to_true_surface=float(np.sqrt(np.mean(dist ** 2))))
    log(f"    observations written in {time.time() - t0:.1f}s")
    return dict(variant=variant, physics=VARIANTS[variant], dofs=int(body.N),
                max_displacement=float(np.linalg.norm(frames, axis=2).max()), files=files, **extra)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=DEFAULT_OUT)
    ap.add_argument("--variant", choices=sorted(VARIANTS), action="append")
    ap.add_argument("--index-only", action="store_true",
                    help="rewrite scenes and cases.json from the variants already generated")
    args = ap.parse_args()
    log = lambda *a: print(*a, flush=True)  # noqa: E731
    os.makedirs(os.path.join(args.out, "scenes"), exist_ok=True)
    index_path = os.path.join(args.out, "cases.json")
    variants = {}
    if os.path.exists(index_path):
        variants = json.load(open(index_path)).get("variants", {})
    for v in [] if args.index_only else args.variant or list(VARIANTS):
        variants[v] = run_variant(v, args.out, log)
    cases = []
    complete = [(name, variant, effects, None, sections, fitted)
                for name, variant, effects, sections, fitted in COMPLETE]
    for name, variant, effects, hidden, *more in [c + ((), None) for c in CASES] + complete:
        scene = f"scenes/{name}.toml"
        with open(os.path.join(args.out, scene), "w") as fh:
            fh.write(scene_toml(name, effects, hidden, variant, *more))
        for key, f in sorted(variants.get(variant, {}).get("files", {}).items(),
                             key=lambda kv: (STYLES.index(kv[1]["style"]), kv[1]["sigma"])):
            cases.append(dict(case=f"{name}/{key}", scene=scene, observations=f["csv"],
                              hidden=hidden, style=f["style"], sigma=f["sigma"]))
    text = open(os.path.join(args.out, "..", "ground", "scene.toml")).read()
    effects_line = 'effects = ["gravity", "damping", "ground"]'
    assert effects_line in text
    text = text.replace(effects_line, 'effects = ["gravity", "damping"]')
    text = ("# Hidden-effect case 'ground' (tools/reference/hidden.py): generate.py's landing sphere,\n"
            "# the ground switched off (its [ground] section, our contact law, kept).\n") + text
    with open(os.path.join(args.out, GROUND["scene"]), "w") as fh:
        fh.write(text)
    cases += [GROUND, GROUND_CONTROL]
    # sliding.py's friction cases, kept
    if os.path.exists(index_path):
        cases += [c for c in json.load(open(index_path))["cases"]
                  if c["case"].split("/")[0] in FRICTION_CASES]
    index = dict(
        generator="tools/reference/hidden.py (scikit-fem; physics notes in its docstring and "
                  "tools/reference/README.md)",
        base=dict(BASE, gravity=list(g.GRAVITY)), camera=CAMERA, view_direction=list(VIEW),
        points_per_frame=POINTS, variants=variants, cases=cases)
    with open(index_path, "w") as fh:
        fh.write(g.compact_json(index) + "\n")
    log(f"wrote {len(cases)} cases to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
