#!/usr/bin/env python3
"""Hidden ground friction: a soft box that lands on the ground while it moves sideways and
slides to a stop, computed with scikit-fem (the elasticity, mesh, surfaces and solver of
generate.py; nothing shared with the Rust crates).

The world (every number in CASE):

  a box 0.3 x 0.1 x 0.2 (E = 100, nu = 0.3, density 1; Rayleigh damping a1 = 0.2, a2 = 0.002),
  its bottom face 0.05 above the ground y = 0, every point starting with the velocity
  (1, 0, 0); gravity (0, -10, 0). It flies 0.1 s, lands flat (the impact sets it bobbing) and
  slides, slowed by ground friction.

  Contact: the normal pressure p = k max(0, -gap) at the points of the bottom face (penalty
  energy (k/2) int min(0, gap)^2 dA over the reference face, generate.py's contact
  quadrature: each Q2 facet split into 6 x 6 x 2 triangles, a 3-point rule on each); k = 1e5
  puts the contact oscillation of the bottom layer (period ~3.6 ms) within the time steps,
  so the landing converges in time (k = 4e6 did not: 2.4e-3 rms between 10 and 20 substeps
  per frame), and its penetration stays below 1e-4 (the weight presses with 1 Pa, the
  landing with ~10 Pa).
  Friction: the tangential traction t = -mu p_lag v_t with mu = 0.4 s/m, v_t the tangential
  (x, z) velocity of the material point at the end of the substep and p_lag its normal
  pressure at the substep's start: the viscous regularisation of Coulomb's law, the law our
  catalogue's `friction` states (docs/effects.md). With p lagged the friction is the
  gradient of the convex dissipation potential  sum_q w_q mu p_q |v_t,q|^2 / (2 c1)
  (c1 = 2 / h; Newmark: v' = c1 (u' - u) - v), so each substep minimises one convex,
  piecewise-quadratic energy (elastic + inertial + penalty + friction): Newton's method on
  the full system (CHOLMOD Cholesky of the tangent), exact once the contact set settles, a
  backtracking line search otherwise.

  Newmark average acceleration (beta = 1/4, gamma = 1/2), 10 substeps per 0.01 s frame, 50
  frames; Q2 hexahedra 8 x 3 x 6 (4 641 dofs).

Checks at every run (asserted):
  - horizontal momentum: its change over every substep equals the impulse of the damping
    and friction forces (trapezoidal, as Newmark integrates it), to 1e-9 of the momentum;
  - without friction the sliding box keeps its horizontal momentum but for the damping's
    share (the same balance with the friction's impulse zero);
  - the friction law: once the box rests on the ground and slides, its mean horizontal
    velocity falls as exp(-(mu N / m + a1) t) with N the measured total normal force
    (a rigid slide under a viscous law; fitted rate within 3%);
  - time convergence: the frames at 20 substeps per frame differ from those at 10 by less
    than a tenth of the smallest noise level (rms over the observed surface nodes).

Cases (written beside hidden.py's under OUT/hidden/friction and added to cases.json):
  friction/samples-<sigma>           the scene lacks `friction` (gravity, damping, ground and
                                     the initial velocity in it); 120 points per frame on the
                                     surface but the bottom face (unseen from above ground)
  complete-friction/samples-<sigma>  control: the same observations, `[friction] coefficient
                                     = 0.4` in the scene and fitted with E and nu

Usage:  python sliding.py [--out DIR]
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

import generate as g
import hidden as hd

CASE = dict(
    body=dict(kind="box", center=[0.0, 0.1, 0.0], size=[0.3, 0.1, 0.2]),
    young=100.0, poisson=0.3, density=1.0,
    damping_mass=0.2, damping_stiffness=0.002,
    clamp=None,
    ground=dict(normal=[0.0, 1.0, 0.0], height=0.0, penalty=1.0e5, cap=0.005,
                scene_scheme="penalty", scene_stiffness=1.0e5, scene_softness=1.0e6),
    velocity=[1.0, 0.0, 0.0], friction=0.4,
    dt=0.01, steps=50, substeps=10,
    mesh=dict(reference=dict(cells=[8, 3, 6])),
    resolution=60, scene_substeps=2,
)
SIGMAS = (0.0025, 0.005, 0.01, 0.02)
SEED = 20261205


def components(E, N):
    """The qp-value matrices of the x, y, z displacement components (full dof 3 s + c)."""
    E = E.tocsr()
    return [sp.csr_matrix((E.data, 3 * E.indices + c, E.indptr), shape=(E.shape[0], N))
            for c in range(3)]


def simulate(body, mu, substeps, log=print):
    """Frames 0..steps of the nodal displacements (nS, 3) and the run's measurements."""
    c = CASE
    h = c["dt"] / substeps
    M, K = body.M.tocsr(), body.K.tocsr()
    C = (c["damping_mass"] * M + c["damping_stiffness"] * K).tocsr()
    F = body.F
    c0, c1 = 4.0 / h ** 2, 2.0 / h
    A = (c0 * M + c1 * C + K).tocsc()
    fac = g.Factor(A)
    contact = g.Contact(body, c["ground"])
    k, w, y0 = contact.k, contact.w, contact.y0
    Ex, Ey, Ez = components(contact.E, body.N)
    others = contact.watch
    u = np.zeros(body.N)
    v = np.tile(np.array(c["velocity"], float), body.nS)
    a = g.Factor(M).solve(F - C @ v)
    ones_x = np.tile([1.0, 0.0, 0.0], body.nS)
    p_lag = np.zeros(len(w))
    f_fric_prev = np.zeros(body.N)
    frames = [np.zeros((body.nS, 3))]
    newton, worst_balance, normal_force, mean_vx = 0, 0.0, [], []
    for n in range(c["steps"] * substeps):
        rhs = F + M @ (c0 * u + (4.0 / h) * v + a) + C @ (c1 * u + v)
        wp = w * mu * p_lag
        Hf = c1 * (Ex.T @ sp.diags(wp) @ Ex + Ez.T @ sp.diags(wp) @ Ez)

        def parts(x):
            gq = y0 + Ey @ x
            vx = c1 * (Ex @ (x - u)) - Ex @ v
            vz = c1 * (Ez @ (x - u)) - Ez @ v
            return gq, vx, vz

        def decrease(x, step, alpha):
            """energy(x + alpha step) - energy(x), term by term (no cancellation of the
            large energies: a difference of 1e-12 stays visible)."""
            gq, vx, vz = parts(x)
            gn = gq + alpha * (Ey @ step)
            gm0, gm1 = np.minimum(gq, 0.0), np.minimum(gn, 0.0)
            dx, dz = alpha * c1 * (Ex @ step), alpha * c1 * (Ez @ step)
            return (alpha * step @ (A @ x - rhs) + 0.5 * alpha ** 2 * step @ (A @ step)
                    + 0.5 * k * np.sum(w * (gm1 - gm0) * (gm1 + gm0))
                    + np.sum(wp * (dx * (2 * vx + dx) + dz * (2 * vz + dz))) / (2 * c1))

        x = fac.solve(rhs)
        gq, _, _ = parts(x)
        if gq.min() < 0 or wp.any():
            for it in range(100):
                gq, vx, vz = parts(x)
                act = gq < 0
                grad = (A @ x - rhs + k * (Ey.T @ (w * np.minimum(gq, 0.0)))
                        + Ex.T @ (wp * vx) + Ez.T @ (wp * vz))
                # the energy is C1 and piecewise quadratic: where the contact set flickers
                # between nearly equal sets (a face at rest), the gradient decides
                if it and np.linalg.norm(grad) <= 1e-10 * np.linalg.norm(F):
                    break
                H = (A + k * (Ey.T @ sp.diags(w * act) @ Ey) + Hf).tocsc()
                step = -g.Factor(H).solve(grad)
                newton += 1
                # quadratic on each contact set: a full step that keeps the set is exact
                if np.array_equal(y0 + Ey @ (x + step) < 0, act):
                    x = x + step
                    break
                alpha = 1.0
                while decrease(x, step, alpha) > 1e-4 * alpha * (grad @ step) and alpha > 1e-10:
                    alpha *= 0.5
                x = x + alpha * step
            else:
                raise RuntimeError(f"substep {n}: contact Newton did not converge")
        gq, vx, vz = parts(x)
        f_fric = -(Ex.T @ (wp * vx) + Ez.T @ (wp * vz))       # the friction's nodal force
        an = c0 * (x - u) - (4.0 / h) * v - a
        vn = v + 0.5 * h * (a + an)
        # horizontal momentum: change = trapezoidal impulse of damping and friction
        dP = ones_x @ (M @ (vn - v))
        imp = 0.5 * h * ones_x @ (-(C @ (v + vn)) + f_fric + f_fric_prev)
        worst_balance = max(worst_balance, abs(dP - imp) / abs(ones_x @ (M @ v)))
        u, v, a, f_fric_prev = x, vn, an, f_fric
        p_lag = k * np.maximum(0.0, -gq)
        if len(others):
            assert (body.doflocs[others, 1] + u.reshape(-1, 3)[others, 1]).min() > 0, \
                "a boundary node outside the bottom face reached the ground"
        normal_force.append(float(np.sum(w * p_lag)))
        mean_vx.append(float(ones_x @ (M @ v)) / float(ones_x @ (M @ ones_x)))
        if (n + 1) % substeps == 0:
            frames.append(u.reshape(-1, 3).copy())
    log(f"    {c['steps']}x{substeps} substeps, mu {mu}: {newton} Newton iterations, "
        f"momentum balance {worst_balance:.1e}")
    assert worst_balance < 1e-9, worst_balance
    return np.array(frames), dict(newton=newton, momentum_balance=worst_balance, h=h,
                                  cap_facets=contact.cap_facets,
                                  normal_force=np.array(normal_force), mean_vx=np.array(mean_vx))


def decay_check(run, mu, mass, log):
    """The mean horizontal velocity's decay rate on the steady slide against mu N / m + a1."""
    t = run["h"] * (1 + np.arange(len(run["mean_vx"])))
    sel = t >= 0.25                       # after the landing and its bobbing
    rate = -np.polyfit(t[sel], np.log(run["mean_vx"][sel]), 1)[0]
    expect = mu * run["normal_force"][sel].mean() / mass + CASE["damping_mass"]
    log(f"    slide: velocity decay rate {rate:.3f}/s, mu N / m + a1 = {expect:.3f}/s")
    assert abs(rate / expect - 1) < 0.03, (rate, expect)
    return rate, expect


def scene_toml(name, effects, sections=(), fitted=None):
    c, gr = CASE, CASE["ground"]
    b = c["body"]
    lines = [f"# Hidden-effect reference case '{name}' (tools/reference/sliding.py, scikit-fem).",
             "# " + ("The complete model: friction in the scene at its true strength, fitted "
                     "(a control)." if fitted else
                     "The observed box slides with ground friction; this scene lacks it."),
             "[body]",
             f'shape = {{ kind = "box", center = {hd.fmt(b["center"])}, size = {hd.fmt(b["size"])} }}',
             f"resolution = {c['resolution']}", "",
             "[material]", f"young = {c['young']!r}", f"poisson = {c['poisson']!r}",
             f"density = {c['density']!r}", "",
             "[damping]", f"mass = {c['damping_mass']!r}", f"stiffness = {c['damping_stiffness']!r}", "",
             "[gravity]", f"acceleration = {hd.fmt(g.GRAVITY)}", "",
             f"# the reference's frictionless part is a penalty p = k * penetration, k = {gr['penalty']:g}",
             "# per unit area: the same law in our penalty scheme (smoothed over the first",
             "# 1 / softness of depth)",
             "[ground]", f"normal = {hd.fmt(gr['normal'])}", f"height = {gr['height']!r}",
             f"scheme = \"{gr['scene_scheme']}\"",
             f"stiffness = {gr['scene_stiffness']!r}", f"softness = {gr['scene_softness']!r}", "",
             "[initial]", f"velocity = {hd.fmt(c['velocity'])}", ""]
    if sections:
        lines += list(sections) + [""]
    lines += ["[time]", f"dt = {c['dt']!r}", f"steps = {c['steps']}", "theta = 0.5",
              "# our integrator steps per frame (the landing is resolved in time)",
              f"substeps = {c['scene_substeps']}", ""]
    return "\n".join(lines + hd.box_scene_tail(effects, fitted))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=hd.DEFAULT_OUT)
    args = ap.parse_args()
    log = lambda *a: print(*a, flush=True)  # noqa: E731
    t0 = time.time()
    c = CASE
    body = g.Body(c, "reference")
    mass = float(np.ones(body.nS) @ (body.M[0::3, 0::3] @ np.ones(body.nS)))
    mu = c["friction"]
    frames, run = simulate(body, mu, c["substeps"], log)
    rate, expect = decay_check(run, mu, mass, log)
    fine, _ = simulate(body, mu, 2 * c["substeps"], log)
    surf = g.Surface(body, 4)
    nodes = np.unique(surf.E.indices)
    time_error = float(np.sqrt(np.mean((fine[:, nodes] - frames[:, nodes]) ** 2)))
    log(f"    10 vs 20 substeps per frame: rms {time_error:.2e} over the surface nodes")
    assert time_error < 0.1 * min(SIGMAS), time_error
    frictionless, run0 = simulate(body, 0.0, c["substeps"], log)
    effect = float(np.sqrt(np.mean((frictionless[:, nodes] - frames[:, nodes]) ** 2)))
    log(f"    friction's effect: rms {effect:.4f} over the surface nodes; "
        f"slide {frames[-1][:, 0].mean():.3f} with, {frictionless[-1][:, 0].mean():.3f} without")
    bottom = np.zeros(len(body.bfacets), bool)
    bottom[run["cap_facets"]] = True
    d = os.path.join(args.out, "friction")
    os.makedirs(d, exist_ok=True)
    fine_surf = g.Surface(body, 8)
    files, cases = {}, []
    for li, sigma in enumerate(SIGMAS):
        rng = np.random.default_rng([SEED, li])
        fr, pts = [], []
        for f in range(1, c["steps"] + 1):
            P = hd.sample_points(body, surf, frames[f], rng, False, hide=bottom)
            fr.append(np.full(len(P), f))
            pts.append(P + sigma * rng.normal(size=P.shape))
        fr, pts = np.concatenate(fr), np.concatenate(pts)
        name = f"samples-{sigma:g}"
        hd.write_csv(os.path.join(d, name + ".csv"), fr, pts)
        dist = np.empty(len(pts))
        for f in np.unique(fr):
            sel = fr == f
            dist[sel] = g.distances_to_surface(pts[sel], fine_surf.triangles(frames[f]))
        files[name] = dict(csv=f"friction/{name}.csv", style="samples", sigma=sigma,
                           points=int(len(pts)),
                           rms_distance_to_true_surface=float(np.sqrt(np.mean(dist ** 2))))
        for case, hidden in (("friction", "friction"), ("complete-friction", None)):
            cases.append(dict(case=f"{case}/{name}", scene=f"scenes/{case}.toml",
                              observations=f"friction/{name}.csv", hidden=hidden,
                              style="samples", sigma=sigma))
    base = ["gravity", "damping", "ground", "initial_velocity"]
    with open(os.path.join(args.out, "scenes", "friction.toml"), "w") as fh:
        fh.write(scene_toml("friction", base))
    with open(os.path.join(args.out, "scenes", "complete-friction.toml"), "w") as fh:
        fh.write(scene_toml("complete-friction", base + ["friction"],
                            ["[friction]", f"coefficient = {mu!r}"], ["young", "poisson", "friction"]))
    index_path = os.path.join(args.out, "cases.json")
    index = json.load(open(index_path))
    index["cases"] = [x for x in index["cases"] if x["case"].split("/")[0] not in hd.FRICTION_CASES]
    index["cases"] += cases
    index["variants"]["friction"] = dict(
        variant="friction", physics=dict((k, c[k]) for k in (
            "body", "young", "poisson", "density", "damping_mass", "damping_stiffness", "ground",
            "velocity", "friction", "dt", "steps", "substeps", "mesh")),
        dofs=int(body.N), newton_iterations=run["newton"],
        momentum_balance=run["momentum_balance"], slide_decay_rate=rate,
        slide_decay_rate_expected=expect, time_error_10_vs_20_substeps=time_error,
        rms_effect_of_friction=effect, files=files)
    with open(index_path, "w") as fh:
        fh.write(g.compact_json(index) + "\n")
    log(f"wrote {len(cases)} friction cases in {time.time() - t0:.0f}s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
